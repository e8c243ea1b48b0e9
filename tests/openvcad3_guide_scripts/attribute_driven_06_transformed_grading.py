import pyvcad as pv
import pyvcad_metamaterials as mm
import pyvcad_rendering as viz

# 05_transformed_grading.py
cell_map = mm.rectangular_cell_map(
    (pv.Vec3(-24.0, -8.0, -8.0), pv.Vec3(24.0, 8.0, 8.0)),
    cells=(6, 2, 2),
)

thickness = pv.FloatAttribute("0.55 + 1.35 * (x + 24) / 48")
lattice = mm.gyroid(cell_map, wall_thickness=thickness)
root = pv.Rotate(0.0, 0.0, 35.0, lattice)
viz.Render(root)
