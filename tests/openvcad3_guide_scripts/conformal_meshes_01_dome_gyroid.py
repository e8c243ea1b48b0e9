import math

import pyvcad as pv
import pyvcad_metamaterials as mm
import pyvcad_rendering as viz

from _triangle_surface_examples import disk_surface

RADIUS = 15.0

def spherical_cap(x, y):
    r2 = (x * x + y * y) / (RADIUS * RADIUS)
    return 8.0 * math.sqrt(max(0.0, 1.0 - 0.75 * r2))

surface = disk_surface(RADIUS, 10, 36, spherical_cap)
cell_map = mm.cell_map_from_surface(surface, cells=(12, 12, 1), height=4.0)
root = mm.gyroid(cell_map, wall_thickness=0.7)

viz.Render(root)
