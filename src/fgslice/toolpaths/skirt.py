"""Skirt: loops around the first layer, printed in whatever state is current.

The first loop's centerline lies ``skirt_distance + w / 2`` outside the convex hull of
the first layer's outline (so the gap between skirt and part is ``skirt_distance``,
mm); further loops are one bead spacing ``s = A / h`` apart, outward. The round joins of
that offset are simplified to ``gcode_resolution`` like every other path (a join at each
hull vertex would otherwise add a segment a few hundredths of a mm long).
"""

from __future__ import annotations

import numpy as np
import shapely

from fgslice.settings import Settings
from fgslice.toolpaths.paths import Path, Role
from fgslice.toolpaths.simplify import simplify_polygons
from fgslice.toolpaths.walls import bead_spacing, ring_groups, split_rings

CURRENT_STATE = -1
"""Color of skirt paths: print in the state that is current, never change state for it."""


def skirt_paths(first_layer_outline, settings: Settings) -> list[Path]:
    """``settings.skirt_loops`` closed loops (role SKIRT, color -1) around the part."""
    if settings.skirt_loops == 0 or first_layer_outline.is_empty:
        return []
    w, h = settings.bead_width, settings.layer_height
    hull = shapely.convex_hull(first_layer_outline)
    dist = settings.skirt_distance + w / 2 + bead_spacing(w, h) * np.arange(settings.skirt_loops)
    loops = simplify_polygons(shapely.buffer(hull, dist, quad_segs=16), settings.gcode_resolution)
    coords, ring, _ = ring_groups(loops)
    return split_rings(coords, ring, Role.SKIRT, CURRENT_STATE, w, h)
