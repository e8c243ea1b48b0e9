import pyvcad as pv
import pyvcad_metamaterials as mm
import pyvcad_rendering as viz

cell_map = mm.rectangular_cell_map(
    (pv.Vec3(-15.0, -15.0, -15.0), pv.Vec3(15.0, 15.0, 15.0)),
    cells=(3, 3, 3),
)
lattice = mm.octet(
    cell_map,
    beam_radius=0.8,
    node_radius=0.9,
    curve_tolerance=0.05,
)
viz.Render(lattice)
