"""Strategy 2, "continuous printing against the gradient": every color face filled densely.

Each face (one per palette color, bed frame, mm) is first simplified to half the
``gcode_resolution`` (faces traced on a grid carry far more vertices than offsets
need), then inset so that its outermost
centerline lies exactly ``w / 2`` inside the face, then filled:

* ``concentric``: successive inward offsets ``s = A / h`` apart until nothing is left
  (loop 0 has role PERIMETER, the others SOLID_INFILL);
* ``rectilinear``: one loop (PERIMETER), then lines at 100 % density (spacing ``s``),
  direction ``infill_angle`` on even layers and ``infill_angle + 90`` on odd ones,
  linked into serpentines (SOLID_INFILL).

Slivers thinner than a spacing left between loops are printed as narrower gap-fill
loops (:func:`~fgslice.toolpaths.infill.concentric_levels`). Paths are simplified to
``gcode_resolution`` before they are returned. Parts of a face narrower than a bead
are not printed; their area is reported in ``LayerPaths.uncovered_mm2``.
"""

from __future__ import annotations

import numpy as np
import shapely

from fgslice.settings import Settings
from fgslice.slicing.layers import LayerRegions
from fgslice.toolpaths.infill import concentric_levels, rectilinear, uncovered_area
from fgslice.toolpaths.paths import LayerPaths, Role
from fgslice.toolpaths.simplify import simplify_paths
from fgslice.toolpaths.walls import bead_spacing, offset, opening


def layer_paths(regions: LayerRegions, settings: Settings) -> LayerPaths:
    """Dense toolpaths of every color face of one layer (colors = face indices)."""
    w, h = settings.bead_width, settings.layer_height
    s = bead_spacing(w, h)
    faces = shapely.simplify(np.asarray(regions.faces, dtype=object), settings.gcode_resolution / 2, preserve_topology=False)
    out = LayerPaths(regions.index, regions.z, regions.height)
    if len(faces) == 0:
        return out
    if settings.fill_pattern == "concentric":
        loops = concentric_levels(faces, w / 2, s, w, h)
        out.paths = loops.paths(np.where(loops.level == 0, Role.PERIMETER, Role.SOLID_INFILL), loops.region, h)
    else:
        loops = concentric_levels(faces, w / 2, s, w, h, max_levels=1)
        out.paths = loops.paths(np.where(loops.level == 0, Role.PERIMETER, Role.SOLID_INFILL), loops.region, h)
        inner = offset(opening(offset(faces, -w / 2), s / 2), -s / 2)
        angle = settings.infill_angle + 90.0 * (regions.index % 2)
        for color, area in enumerate(inner):
            out.paths += rectilinear(area, 100.0, angle, w, h, Role.SOLID_INFILL, color=color)
    out.paths = simplify_paths(out.paths, settings.gcode_resolution)
    out.uncovered_mm2 = uncovered_area(faces, w)
    return out
