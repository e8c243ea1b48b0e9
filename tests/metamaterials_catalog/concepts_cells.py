import pyvcad as pv
import pyvcad_metamaterials as mm
import pyvcad_rendering as viz

gyroid_cell = pv.ImplicitUnitCell.standard("gyroid")
assert gyroid_cell.validate_periodicity()

cell = pv.GraphUnitCell(
    [pv.Vec3(0.0, 0.0, 0.0), pv.Vec3(1.0, 1.0, 1.0)],
    [(0, 1)],
    edge_tags=[10],
)

cell_map = mm.rectangular_cell_map(
    (pv.Vec3(-20.0, -15.0, -10.0), pv.Vec3(20.0, 15.0, 10.0)),
    cells=(4, 3, 2),
)
gyroid = mm.tpms(cell_map, gyroid_cell, wall_thickness=1.2)
diagonals = mm.graph_lattice(cell_map, cell, beam_radius=0.7)
octet = mm.octet(cell_map, beam_radius=0.7)

part = pv.Intersection(
    pv.Union(gyroid, diagonals),
    pv.Sphere(pv.Vec3(0.0, 0.0, 0.0), 12.0),
)
viz.Render(part)
