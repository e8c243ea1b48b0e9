import pyvcad as pv
import pyvcad_metamaterials as mm
import pyvcad_rendering as viz

# Eight cells across the width (02_graded_cell_spacing.py)
base_map = mm.rectangular_cell_map(
    (pv.Vec3(-24.0, -6.0, -6.0), pv.Vec3(24.0, 6.0, 6.0)),
    cells=(8, 2, 2),
)

position_across_map = base_map.logical_position.x
u_spacing = position_across_map.map_range(0.0, 8.0, -0.8, 0.8)

warped_map = mm.warp_cell_map(
    base_map,
    u_scale=u_spacing,
    lock_u_bounds=True,
)
root = mm.gyroid(warped_map, wall_thickness=1.4)
viz.Render(root)
