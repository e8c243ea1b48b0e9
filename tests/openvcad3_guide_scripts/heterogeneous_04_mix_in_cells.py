import pyvcad as pv
import pyvcad_metamaterials as mm
import pyvcad_rendering as viz

cell_map = mm.rectangular_cell_map(
    (pv.Vec3(-24.0, -12.0, -8.0), pv.Vec3(24.0, 12.0, 8.0)),
    cells=(6, 3, 2),
)

gyroid = mm.gyroid(cell_map, wall_thickness=1.2)
schwarz_d = mm.schwarz_d(cell_map, wall_thickness=1.2)

left_region = pv.RectPrism.FromMinAndMax(
    pv.Vec3(-30.0, -18.0, -12.0), pv.Vec3(0.0, 18.0, 12.0)
)
right_region = pv.RectPrism.FromMinAndMax(
    pv.Vec3(0.0, -18.0, -12.0), pv.Vec3(30.0, 18.0, 12.0)
)

weight = mm.ramp(2.0, 4.0, axis="u", coordinates=cell_map.logical_position)
root = mm.mix(gyroid, schwarz_d, weight)
viz.Render(root)
