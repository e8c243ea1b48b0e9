"""Solid skins from neighbouring layers, and the split of a layer's inner area.

Top skin of a layer = its outline minus the intersection of the outlines of the
``top_layers`` layers above it; when fewer than ``top_layers`` layers exist above (the
top of the part), that intersection is empty and the whole layer is top skin. Bottom
skins likewise with the layers below (so the first layer is entirely solid). Geometry
is shapely in the bed frame, mm.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import shapely

from fgslice.settings import Settings
from fgslice.toolpaths.infill import concentric, rectilinear
from fgslice.toolpaths.paths import Path, Role


def exposed(outline, neighbours: Sequence, count: int):
    """Part of ``outline`` not covered by all of the ``count`` nearest ``neighbours``.

    ``neighbours`` are the outlines of the adjacent layers, nearest first; missing
    layers count as empty, so the whole outline is exposed when fewer than ``count``
    are given. ``count = 0`` exposes nothing. Neighbours that cover the outline (the
    usual case inside a part) are recognised by a predicate, without any overlay.
    """
    if count == 0:
        return shapely.Polygon()
    if len(neighbours) < count:
        return outline
    near = np.asarray(list(neighbours[:count]), dtype=object)
    if np.all(shapely.covers(near, outline)):
        return shapely.Polygon()
    return shapely.difference(outline, shapely.intersection_all(near))


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
    """Split ``inner`` (the area inside the walls) into top skin, solid skin and sparse.

    A density of 100 % makes everything solid (role SOLID_INFILL where not top skin).
    """
    empty = shapely.Polygon()
    top = exposed(outline, above, settings.top_layers)
    bottom = exposed(outline, below, settings.bottom_layers)
    top = empty if top.is_empty else shapely.intersection(inner, top)
    if settings.infill_density >= 100.0:
        return InnerAreas(top, shapely.difference(inner, top) if not top.is_empty else inner, empty)
    bottom = empty if bottom.is_empty else shapely.intersection(inner, bottom)
    if top.is_empty and bottom.is_empty:
        return InnerAreas(empty, empty, inner)
    solid = shapely.difference(bottom, top)
    return InnerAreas(top, solid, shapely.difference(inner, shapely.union(top, bottom)))


def fill_inner(areas: InnerAreas, layer_index: int, settings: Settings) -> list[Path]:
    """Fill skins with 100 % rectilinear and the sparse area with the chosen pattern.

    Lines run at ``infill_angle`` on even layers and ``infill_angle + 90`` on odd ones.
    """
    w, h = settings.bead_width, settings.layer_height
    angle = settings.infill_angle + 90.0 * (layer_index % 2)
    paths = rectilinear(areas.top, 100.0, angle, w, h, Role.TOP_SOLID_INFILL)
    paths += rectilinear(areas.solid, 100.0, angle, w, h, Role.SOLID_INFILL)
    if settings.infill_pattern == "concentric":
        paths += concentric(areas.sparse, settings.infill_density, w, h, Role.INTERNAL_INFILL)
    else:
        paths += rectilinear(areas.sparse, settings.infill_density, angle, w, h, Role.INTERNAL_INFILL)
    return paths
