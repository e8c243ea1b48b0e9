import pyvcad as pv
import pyvcad_metamaterials as mm
import pyvcad_rendering as viz

# A BCC lattice across a block from x = -22 to 22 (03_graded_strut_radius.py)
cell_map = mm.rectangular_cell_map(
    (pv.Vec3(-22.0, -5.5, -5.5), pv.Vec3(22.0, 5.5, 5.5)),
    cells=(4, 1, 1),
)

beam_radius = pv.FloatAttribute("0.3 + (x + 22.0) / 44.0")
root = mm.bcc(cell_map, beam_radius=beam_radius)
viz.Render(root)
