import pyvcad as pv
import pyvcad_metamaterials as mm
import pyvcad_rendering as viz

# A shallow cubic lattice, six cells across X (06_position_across_lattice.py)
cell_map = mm.rectangular_cell_map(
    (pv.Vec3(-24.0, -12.0, -4.0), pv.Vec3(24.0, 12.0, 4.0)),
    cells=(6, 3, 1),
)

position_across_lattice = cell_map.logical_position.x
beam_radius = position_across_lattice.map_range(0.0, 6.0, 0.35, 1.25)

root = mm.cubic(cell_map, beam_radius=beam_radius)
viz.Render(root)
