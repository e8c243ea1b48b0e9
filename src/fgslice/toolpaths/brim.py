"""Brim: loops hugging the part's outside on the first layer, to hold it to the bed.

As PrusaSlicer's outer brim: loop ``k`` has its centerline ``w / 2 + k s`` outside the
first layer's islands (holes filled: no brim inside a hole), ``s = A / h`` the bead
spacing, so the innermost bead touches the part and neighbouring beads are spaced as
walls are; ``round(brim_width / s)`` loops (at least one) cover ``brim_width`` mm.
Loops of neighbouring islands that would overlap merge into one. Role SKIRT
(PrusaSlicer's ``Skirt/Brim``), color -1: printed in whatever state is current, never
changing state for it. Bed frame, mm.
"""

from __future__ import annotations

import numpy as np
import shapely

from fgslice.islands import MANY_ISLANDS, union_polygons
from fgslice.settings import Settings
from fgslice.toolpaths.paths import Path, Role
from fgslice.toolpaths.simplify import simplify_polygons
from fgslice.toolpaths.skirt import CURRENT_STATE
from fgslice.toolpaths.walls import MITRE_LIMIT, bead_spacing, ring_groups, split_rings


def brim_loops(settings: Settings) -> int:
    """How many loops ``brim_width`` asks for (0 without a brim)."""
    if settings.brim_width <= 0:
        return 0
    s = bead_spacing(settings.bead_width, settings.layer_height)
    return max(1, int(round(settings.brim_width / s)))


def _filled(outline):
    """The islands of ``outline`` with their holes filled, as one geometry (many islands
    apart are kept as they are: :func:`fgslice.islands.union_polygons`)."""
    islands = shapely.polygons(shapely.get_exterior_ring(shapely.get_parts(outline)))
    return union_polygons(islands) if len(islands) > MANY_ISLANDS else shapely.union_all(islands)


def brim_area(first_layer_outline, settings: Settings):
    """The first layer's islands with their brim (holes filled), the area a skirt goes around."""
    solid = _filled(first_layer_outline)
    n = brim_loops(settings)
    if n == 0:
        return solid
    width = settings.bead_width + (n - 1) * bead_spacing(settings.bead_width, settings.layer_height)
    return shapely.buffer(solid, width, join_style="mitre", mitre_limit=MITRE_LIMIT)


def brim_paths(first_layer_outline, settings: Settings) -> list[Path]:
    """:func:`brim_loops` closed loops (role SKIRT, color -1) around the first layer's
    islands, innermost first; holes of a loop (around a gap between islands) are loops too."""
    n = brim_loops(settings)
    if n == 0 or first_layer_outline.is_empty:
        return []
    w, h = settings.bead_width, settings.layer_height
    solid = _filled(first_layer_outline)
    dist = w / 2 + bead_spacing(w, h) * np.arange(n)
    loops = shapely.buffer(solid, dist, join_style="mitre", mitre_limit=MITRE_LIMIT)
    loops = simplify_polygons(loops, settings.gcode_resolution)
    coords, ring, _ = ring_groups(loops)
    return split_rings(coords, ring, Role.SKIRT, CURRENT_STATE, w, h)
