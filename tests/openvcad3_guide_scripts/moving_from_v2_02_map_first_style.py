import pyvcad as pv
import pyvcad_metamaterials as mm

# Version 3 map-first style
cell_map = mm.rectangular_cell_map(
    (pv.Vec3(-15.0, -15.0, -15.0), pv.Vec3(15.0, 15.0, 15.0)),
    cells=(3, 3, 3),
)
root = mm.gyroid(cell_map, wall_thickness=1.2)
