"""Strategy 2, "continuous printing against the gradient": every color face filled densely.

Each face (one per palette color, bed frame, mm) is first simplified to
:func:`simplify_tolerance` (faces traced on a grid carry far more vertices than offsets
need), then filled by :func:`~fgslice.toolpaths.infill.dense_levels`, whose outermost
centerline lies exactly ``w / 2`` inside the face:

* ``concentric``: successive inward offsets ``s = A / h`` apart until nothing is left;
* ``rectilinear``: one loop, then lines at 100 % density (spacing ``s``), direction
  ``infill_angle`` on even layers and ``infill_angle + 90`` on odd ones, linked into
  serpentines (SOLID_INFILL), inside the face eroded by ``w / 2 + s / 2``.

Each loop's width makes it deposit its own territory's volume (no gap fill needed,
thin tapering band ends included). Roles: the outermost loop of a face is
EXTERNAL_PERIMETER when it runs along the part surface (within
``w / 2 +`` :data:`SURFACE_TOLERANCE` of the outline's boundary), PERIMETER otherwise;
inner loops are SOLID_INFILL. Paths are simplified to ``gcode_resolution`` before they
are returned. Parts of a face narrower than a bead are first given to a neighbouring
color (:func:`~fgslice.toolpaths.slivers.give_slivers`, area in
``LayerPaths.reassigned_mm2``); what is still narrower than a bead after that (a part
of the outline itself thinner than a bead) is printed as single beads in its face's color
(:mod:`~fgslice.toolpaths.thin_features`, with ``thin_features`` on), or not printed, its
area reported in ``LayerPaths.uncovered_mm2``. Areas over air are cut out of the faces first and filled
with bridge lines across their short span (:mod:`~fgslice.toolpaths.bridges`).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import shapely

from fgslice.settings import Settings
from fgslice.slicing.layers import LayerRegions
from fgslice.slicing.regions import SECTION_TOLERANCE
from fgslice.toolpaths.bridges import bridge_paths, bridge_pieces
from fgslice.toolpaths.infill import dense_levels, solid_fill, uncovered_area
from fgslice.toolpaths.paths import LayerPaths, Path, Role
from fgslice.toolpaths.simplify import simplify_paths, simplify_polygons
from fgslice.toolpaths.slivers import MIN_SLIVER_AREA, give_slivers
from fgslice.toolpaths.thin_features import layer_thin_beads
from fgslice.toolpaths.walls import bead_spacing, offset_polygons


SURFACE_TOLERANCE = 0.05
"""A face's outermost loop coming this close (mm) to ``w / 2`` from the outline's
boundary lies along the part surface (role EXTERNAL_PERIMETER)."""


def layer_paths(regions: LayerRegions, settings: Settings, bridges=None) -> LayerPaths:
    """Dense toolpaths of every color face of one layer (colors = face indices);
    ``bridges``: the layer's area over air (:func:`~fgslice.toolpaths.bridges.face_bridges`),
    filled with bridge lines, or None."""
    w, h = settings.bead_width, settings.layer_height
    s = bead_spacing(w, h)
    out = LayerPaths(regions.index, regions.z, regions.height)
    if len(regions.faces) == 0:
        return out
    bridged: list[Path] = []
    if bridges is not None and not bridges.is_empty:
        pieces = bridge_pieces(bridges, w, regions.faces)
        bridged = bridge_paths(bridges, settings, pieces=pieces)
        shares = [shapely.union_all([p for _, c, p in pieces if c == color]) for color in range(len(regions.faces))]
        regions = dataclasses.replace(
            regions, faces=tuple(shapely.difference(np.asarray(regions.faces, dtype=object),
                                                    np.asarray(shares, dtype=object))))
    faces, parts, owner, eroded, exact = _eroded_faces(regions.faces, settings)
    # a polygon offset vertex by vertex comes back whole when dilated: nothing uncovered
    uncovered = uncovered_area(parts[~exact], w, eroded=eroded[~exact])
    if uncovered >= MIN_SLIVER_AREA:
        given, out.reassigned_mm2 = give_slivers(regions.faces, w)
        if out.reassigned_mm2 > 0:
            faces, parts, owner, eroded, exact = _eroded_faces(given, settings)
            uncovered = uncovered_area(parts[~exact], w, eroded=eroded[~exact])
    out.uncovered_mm2 = uncovered
    thin = layer_thin_beads(out, parts[~exact], eroded[~exact], owner[~exact], settings, Role.PERIMETER)
    levels = None if settings.fill_pattern == "concentric" else 1
    loops = dense_levels(faces, w / 2, s, w, h, max_levels=levels, eroded=(eroded, owner))
    out.paths = simplify_paths(loops.paths(_roles(loops, regions.outline, w), loops.region, h), settings.gcode_resolution)
    if settings.fill_pattern == "rectilinear":
        angle = settings.infill_angle + 90.0 * (regions.index % 2)
        out.paths += solid_fill(loops.rest, angle, w, h, Role.SOLID_INFILL, loops.rest_region)
    out.paths += bridged + thin
    return out


def _eroded_faces(faces, settings: Settings):
    """``(faces, parts, owner, eroded, exact)``: the faces simplified to
    :func:`simplify_tolerance`, their polygons and the face of each, and those eroded by
    half a bead (``exact``: offset vertex by vertex)."""
    faces = simplify_polygons(np.asarray(faces, dtype=object), simplify_tolerance(settings))
    parts, owner = shapely.get_parts(faces, return_index=True)
    eroded, exact = offset_polygons(parts, -settings.bead_width / 2)
    return faces, parts, owner, eroded, exact


def simplify_tolerance(settings: Settings) -> float:
    """How far (mm) face boundaries may move before offsetting: ``max(gcode_resolution / 2, w / 40)``."""
    return max(settings.gcode_resolution / 2, settings.bead_width / 40)


def _roles(loops, outline, width: float) -> np.ndarray:
    """Per loop: EXTERNAL_PERIMETER for outermost loops along the outline's boundary
    (simplified like the layer's outline, to
    :data:`~fgslice.slicing.regions.SECTION_TOLERANCE`), PERIMETER for the other
    outermost loops, SOLID_INFILL inside."""
    roles = np.where(loops.level == 0, Role.PERIMETER, Role.SOLID_INFILL)
    first = np.flatnonzero(loops.level == 0)
    if len(first) == 0:
        return roles
    outer = (loops.level == 0)[loops.ring]
    rings = shapely.linestrings(loops.coords[outer], indices=np.searchsorted(first, loops.ring[outer]))
    boundary = shapely.boundary(simplify_polygons(outline, SECTION_TOLERANCE))
    shapely.prepare(boundary)
    surface = shapely.dwithin(boundary, rings, width / 2 + SURFACE_TOLERANCE)
    roles[first[surface]] = Role.EXTERNAL_PERIMETER
    return roles
