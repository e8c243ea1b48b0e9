"""Solid skins from neighbouring layers, and the split of a layer's inner area.

Top skin of a layer = its outline minus the intersection of the outlines of the
``top_layers`` layers above it; when fewer than ``top_layers`` layers exist above (the
top of the part), that intersection is empty and the whole layer is top skin. Bottom
skins likewise with the layers below (so the first layer is entirely solid). Only the
inner area (inside the walls) is split, so the skins are computed within it directly:
the neighbours (outlines simplified like the layer's own,
:func:`~fgslice.toolpaths.walls.simplify_outline`) are intersected with the inner area
(nothing to compute where they cover it, the usual case inside a part). Geometry is
shapely in the bed frame, mm.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import shapely

from fgslice.settings import Settings
from fgslice.toolpaths.infill import concentric, rectilinear_many
from fgslice.toolpaths.paths import Path, Role

_EMPTY = shapely.Polygon()
"""The empty area (geometries are immutable; shapely parses WKT to make a new one)."""

NARROW_MIN_AREA = 1e-3
"""Smallest narrow sparse piece made solid by :func:`anchor`, mm^2 (smaller ones are the
floating-point residue of the opening)."""

OPENED_TOLERANCE = 1e-9
"""How far (mm) the vertices of an opening that changes nothing may lie from the sparse
area's: the pieces between them are far below :data:`NARROW_MIN_AREA`. A smooth part's
sparse area (every layer of the vases) is its own opening to about 1e-12 mm, and the
comparison costs a fiftieth of the overlay it saves."""


def covered(region, neighbours: Sequence, count: int):
    """Part of ``region`` covered by all of the ``count`` nearest ``neighbours``.

    ``neighbours`` are the outlines of the adjacent layers, nearest first; missing
    layers count as empty, so nothing is covered when fewer than ``count`` are given.
    ``count = 0`` covers everything (``region`` itself is returned). Neighbours that
    cover ``region`` are recognised by a predicate, without any overlay: when all do,
    ``region`` itself is returned (as for an empty ``region``); otherwise ``region`` is
    intersected with the others only, ``region`` first, so that every intermediate
    result lies within it (3DBenchy, 480 calls: 111 -> 67 ms).
    """
    if count == 0 or region.is_empty:
        return region
    if len(neighbours) < count:
        return _EMPTY
    near = np.asarray(list(neighbours[:count]), dtype=object)
    cover = shapely.covers(near, region)
    if np.all(cover):
        return region
    return shapely.intersection_all(np.r_[np.asarray([region], dtype=object), near[~cover]])


def _minus(region, part):
    """``region`` minus ``part`` where ``part`` is :func:`covered`'s result for ``region``."""
    if part is region:
        return _EMPTY
    if part.is_empty:
        return region
    return shapely.difference(region, part)


@dataclass(frozen=True)
class InnerAreas:
    """The inner area of a layer split by fill kind (MultiPolygons, mm).

    Attributes:
        top: top solid skin (role TOP_SOLID_INFILL).
        solid: bottom and internal solid skin (role SOLID_INFILL).
        sparse: the rest, filled at the requested density (role INTERNAL_INFILL).
    """

    top: shapely.Geometry
    solid: shapely.Geometry
    sparse: shapely.Geometry


def split_inner(inner, outline, below: Sequence, above: Sequence, settings: Settings) -> InnerAreas:
    """Split ``inner`` (the area inside the walls of ``outline``) into top skin, solid
    skin and sparse.

    With ``A`` the part of ``inner`` covered by the ``top_layers`` outlines above and
    ``B`` the part of ``A`` covered by the ``bottom_layers`` below (:func:`covered`):
    top = ``inner - A``, solid = ``A - B``, sparse = ``B`` (``inner`` lies within
    ``outline``, so this equals the outline's exposed parts intersected with ``inner``).
    A density of 100 % makes everything solid (role SOLID_INFILL where not top skin).
    """
    under_above = covered(inner, above, settings.top_layers)
    top = _minus(inner, under_above)
    if settings.infill_density >= 100.0:
        return InnerAreas(top, under_above, _EMPTY)
    sparse = covered(under_above, below, settings.bottom_layers)
    areas = InnerAreas(top, _minus(under_above, sparse), sparse)
    return anchor(areas, under_above, settings.skin_margin, settings.sparse_min_width)


def anchor(areas: InnerAreas, under_above, margin: float, min_width: float) -> InnerAreas:
    """Anchored skins: the sparse area within ``margin`` mm of the top or solid skin, and
    every part of the sparse area narrower than ``min_width`` mm, become solid skin.

    As PrusaSlicer's external infill margin and Cura's skin expand distance: a skin that
    ends exactly where the layers above or below stop would rest on (or carry) sparse
    lines only at its edge, and the strip left between it and the walls would be too
    narrow for sparse lines to reach. Narrow means removed by an opening of the sparse area
    by ``min_width / 2`` (mitre joins, so a rectangle is its own opening); pieces smaller
    than ``NARROW_MIN_AREA`` are floating-point residue and stay sparse (when the opening
    has the sparse area's own vertices, to :data:`OPENED_TOLERANCE`, nothing is narrow and
    the overlay is skipped). ``under_above``
    is the solid and sparse areas together (the inner area less the top skin): the new
    solid is it less the new sparse area. Areas that nothing changes are returned as they
    are (the same geometry objects).
    """
    top, solid, sparse = areas.top, areas.solid, areas.sparse
    if sparse.is_empty:
        return areas
    changed = False
    if margin > 0 and not (top.is_empty and solid.is_empty):
        skins = shapely.union(top, solid) if not (top.is_empty or solid.is_empty) else (solid if top.is_empty else top)
        near = shapely.buffer(skins, margin)
        if shapely.intersects(near, sparse):
            sparse, changed = shapely.difference(sparse, near), True
    if min_width > 0 and not sparse.is_empty:
        opened = shapely.buffer(shapely.buffer(sparse, -min_width / 2, join_style="mitre"), min_width / 2, join_style="mitre")
        if shapely.equals_exact(shapely.normalize(opened), shapely.normalize(sparse), tolerance=OPENED_TOLERANCE):
            return InnerAreas(top, shapely.difference(under_above, sparse), sparse) if changed else areas
        parts = shapely.get_parts(sparse if opened.is_empty else shapely.difference(sparse, opened))
        narrow = parts[shapely.area(parts) >= NARROW_MIN_AREA]
        if opened.is_empty and len(narrow) == len(parts):
            sparse, changed = _EMPTY, True  # all of it is narrow
        elif len(narrow):
            sparse, changed = shapely.difference(sparse, shapely.multipolygons(narrow)), True  # parts of one overlay: disjoint
    if not changed:
        return areas
    return InnerAreas(top, shapely.difference(under_above, sparse), sparse)


def fill_inner(areas: InnerAreas, layer_index: int, settings: Settings, sparse=None) -> list[Path]:
    """Fill skins with 100 % rectilinear and the sparse area with the chosen pattern.

    Lines run at ``infill_angle`` on even layers and ``infill_angle + 90`` on odd ones;
    the rectilinear fills of a layer are computed together (:func:`rectilinear_many`).
    ``sparse``: the sparse area as ``(region, density percent)`` pieces (a graded
    density, :mod:`fgslice.toolpaths.graded_infill`); None: all at ``infill_density``.
    """
    w, h = settings.bead_width, settings.layer_height
    angle = settings.infill_angle + 90.0 * (layer_index % 2)
    sparse = [(areas.sparse, settings.infill_density)] if sparse is None else sparse
    fills = [(areas.top, 100.0, Role.TOP_SOLID_INFILL), (areas.solid, 100.0, Role.SOLID_INFILL)]
    if settings.infill_pattern != "concentric":
        fills += [(region, density, Role.INTERNAL_INFILL) for region, density in sparse]
    regions, densities, roles = zip(*fills)
    paths = rectilinear_many(regions, densities, angle, w, h, roles)
    if settings.infill_pattern == "concentric":
        for region, density in sparse:
            paths += concentric(region, density, w, h, Role.INTERNAL_INFILL)
    return paths
