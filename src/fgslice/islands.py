"""Set operations on layers of many separate islands, without overlaying the islands that
nothing touches.

GEOS overlays (a cascaded union, a difference of two multipolygons) cost seconds on a
layer of a hundred thousand small islands (a grid of cubes), although most of them touch
nothing: these functions hand GEOS only the islands that meet something, found through
an STRtree, and keep the others as they are. The results are the same regions as
:func:`shapely.union_all` and :func:`shapely.difference` give (the same vertices where
nothing is overlaid), as valid MultiPolygons. Coordinates in mm.
"""

from __future__ import annotations

import numpy as np
import shapely

MANY_ISLANDS = 64
"""Polygons from which :func:`difference_by_islands` works island by island."""


def _polygons(parts) -> np.ndarray:
    """The non-empty polygons of ``parts`` (geometries or arrays of them), flattened."""
    polys = shapely.get_parts(np.asarray(parts, dtype=object).ravel())
    if np.isin(shapely.get_type_id(polys), (4, 5, 6, 7)).any():  # collections inside collections
        polys = shapely.get_parts(polys)
    return polys[(shapely.get_type_id(polys) == 3) & ~shapely.is_empty(polys)]


def _multipolygon(polys: np.ndarray) -> shapely.MultiPolygon:
    polys = polys[(shapely.get_type_id(polys) == 3) & ~shapely.is_empty(polys)]
    polys = polys[shapely.area(polys) > 0]
    return shapely.multipolygons(polys) if len(polys) else shapely.MultiPolygon()


def union_polygons(parts, valid: bool = False) -> shapely.MultiPolygon:
    """The union of the polygonal parts of ``parts`` (polygons or multipolygons, as
    :func:`shapely.union_all` would give it): a valid MultiPolygon of polygons of positive
    area (an empty one without any), without overlaying the parts that touch nothing
    else: only groups of parts that intersect or touch one another are united, a valid
    part alone is kept as it is (a cascaded union of thousands of disjoint islands costs
    seconds). ``valid``: the parts are known to be valid polygons (not checked again)."""
    polys = _polygons(parts)
    n = len(polys)
    a, b = shapely.STRtree(polys).query(polys, predicate="intersects")
    other = a != b
    alone = np.ones(n, dtype=bool) if valid else shapely.is_valid(polys)
    merged = []
    if other.any():
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import connected_components

        edges = coo_matrix((np.ones(other.sum()), (a[other], b[other])), shape=(n, n))
        _, label = connected_components(edges, directed=False)
        alone &= np.bincount(label, minlength=n)[label] == 1
        grouped = np.flatnonzero(~alone)
        grouped = grouped[np.argsort(label[grouped], kind="stable")]
        splits = np.flatnonzero(np.diff(label[grouped])) + 1
        merged = [shapely.get_parts(shapely.union_all(polys[group])) for group in np.split(grouped, splits)]
    elif not alone.all():
        merged = [shapely.get_parts(shapely.union_all(polys[~alone]))]
    return _multipolygon(np.concatenate([polys[alone], *merged]) if merged else polys[alone])


def difference_by_islands(a, b) -> shapely.Geometry:
    """``a`` minus ``b`` (valid polygonal geometries): :func:`shapely.difference`, island by
    island when ``a`` has more than :data:`MANY_ISLANDS` polygons: an island of ``a`` that
    no part of ``b`` meets is kept, one they cover is dropped, the others lose the parts
    of ``b`` they meet."""
    islands = _polygons(a)
    if len(islands) <= MANY_ISLANDS:
        return shapely.difference(a, b)
    cutters = _polygons(b)
    cut, by = shapely.STRtree(cutters).query(islands, predicate="intersects")
    if not len(cut):
        return _multipolygon(islands)
    order = np.argsort(cut, kind="stable")
    cut, by = cut[order], by[order]
    first = np.flatnonzero(np.r_[True, np.diff(cut) != 0])
    count = np.diff(np.r_[first, len(cut)])
    tools = np.empty(len(first), dtype=object)
    single = count == 1
    tools[single] = cutters[by[first[single]]]
    for k in np.flatnonzero(~single):
        tools[k] = shapely.union_all(cutters[by[first[k] : first[k] + count[k]]])
    kept = np.ones(len(islands), dtype=bool)
    kept[cut[first]] = False
    met = islands[cut[first]]
    left = ~shapely.covers(tools, met)  # an island its cutters cover is gone without an overlay
    return _multipolygon(np.concatenate([islands[kept], _polygons(shapely.difference(met[left], tools[left]))]))
