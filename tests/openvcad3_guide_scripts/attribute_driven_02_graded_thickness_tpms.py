import pyvcad as pv
import pyvcad_metamaterials as mm
import pyvcad_rendering as viz

# The map spans X from -24 to 24 (01_graded_thickness_tpms.py)
cell_map = mm.rectangular_cell_map(
    (pv.Vec3(-24.0, -8.0, -8.0), pv.Vec3(24.0, 8.0, 8.0)),
    cells=(6, 2, 2),
)

wall_thickness = pv.FloatAttribute("0.6 + 2.0 * (x + 24.0) / 48.0")
root = mm.gyroid(cell_map, wall_thickness=wall_thickness)
viz.Render(root)
