import pyvcad as pv
import pyvcad_metamaterials as mm
import pyvcad_rendering as viz

# Two 24 mm panels side by side: six 4 mm cells and three 8 mm cells
# (09_movement_in_cell_units.py)
small_cells = mm.rectangular_cell_map(
    (pv.Vec3(-26.0, -4.0, -4.0), pv.Vec3(-2.0, 4.0, 4.0)),
    cells=(6, 2, 2),
)
large_cells = mm.rectangular_cell_map(
    (pv.Vec3(2.0, -4.0, -4.0), pv.Vec3(26.0, 4.0, 4.0)),
    cells=(3, 1, 1),
)

one_mm_x_step = pv.Vec3Attribute(1.0, 0.0, 0.0)

def radius_for(cell_map):
    step_in_cell_units = cell_map.to_cell_frame(one_mm_x_step)
    fraction_of_cell_crossed = abs(step_in_cell_units.x)
    return (0.2 + 3.6 * fraction_of_cell_crossed).clamp(0.4, 1.1)

root = pv.Union(
    mm.cubic(small_cells, beam_radius=radius_for(small_cells)),
    mm.cubic(large_cells, beam_radius=radius_for(large_cells)),
)
viz.Render(root)
