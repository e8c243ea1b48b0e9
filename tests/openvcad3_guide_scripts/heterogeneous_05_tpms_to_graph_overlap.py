import pyvcad as pv
import pyvcad_metamaterials as mm
import pyvcad_rendering as viz

# 03_tpms_to_graph_overlap.py: one 8 mm cell of overlap on the shared map
cell_map = mm.rectangular_cell_map(
    (pv.Vec3(-24.0, -12.0, -8.0), pv.Vec3(24.0, 12.0, 8.0)),
    cells=(6, 3, 2),
)
schwarz_p = mm.schwarz_p(cell_map, wall_thickness=1.2)
octet = mm.octet(cell_map, beam_radius=0.8)

OVERLAP_HALF_WIDTH = 4.0

tpms_region = pv.RectPrism.FromMinAndMax(
    pv.Vec3(-30.0, -18.0, -12.0),
    pv.Vec3(OVERLAP_HALF_WIDTH, 18.0, 12.0),
)
graph_region = pv.RectPrism.FromMinAndMax(
    pv.Vec3(-OVERLAP_HALF_WIDTH, -18.0, -12.0),
    pv.Vec3(30.0, 18.0, 12.0),
)
root = pv.Union(
    pv.Intersection(schwarz_p, tpms_region),
    pv.Intersection(octet, graph_region),
)
viz.Render(root)
