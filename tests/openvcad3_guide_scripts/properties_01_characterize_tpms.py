import pyvcad as pv
import pyvcad_metamaterials as mm

bounds = (
    pv.Vec3(-10.0, -10.0, -10.0),
    pv.Vec3(10.0, 10.0, 10.0),
)
cell_map = mm.rectangular_cell_map(bounds, cells=(2, 2, 2))
root = mm.gyroid(cell_map, wall_thickness=1.2)

report = mm.properties.characterize(
    root,
    voxel_size=0.4,
    bounds=bounds,
    periodic_axes="xyz",
)
print(report)

x_profile = report.cross_sections["x"]
print(x_profile.positions)
print(x_profile.solid_areas)
print(x_profile.area_fractions)
print(x_profile.coefficient_of_variation)
