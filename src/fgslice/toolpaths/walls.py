"""Perimeters (walls) by inward offsets of a layer outline, and the offset and ring functions
the other toolpath modules share.

Spacing model (see ``docs/toolpaths.md``): a bead of width ``w`` and height ``h`` has the
capsule cross-section ``A = h (w - h) + pi h^2 / 4`` (mm²). Neighbouring beads are laid
at the centerline spacing ``s = A / h = w - h (1 - pi/4)`` (PrusaSlicer's perimeter
spacing), so that a region of area ``R`` filled with lines of total length ``L ~ R / s``
receives exactly ``R h`` of material. The outermost centerline sits exactly ``w / 2``
inside the outline; loop ``k`` sits ``w / 2 + k s`` inside.

All geometry is shapely 2 in the bed frame, mm. Offsets use mitre joins with
:data:`MITRE_LIMIT` and are vectorized over arrays of geometries and distances. Walls
are offsets of the outline as given: strategy 1 simplifies each layer's outline once,
when it is sliced, to its ``gcode_resolution`` setting (:func:`simplify_outline`), and
its walls and skins take it so.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely

from fgslice.toolpaths.paths import Path, Role, bead_area
from fgslice.toolpaths.simplify import simplify_polygons

MITRE_LIMIT = 3.0
"""Mitre limit of every offset (ratio of the mitre length to the offset distance)."""


def simplify_outline(outline, tolerance: float):
    """``outline`` (polygonal, mm) simplified to ``tolerance`` (mm), as walls and skins take
    it. Strategy 1 takes the ``gcode_resolution`` setting, as PrusaSlicer simplifies a
    layer's slices before its perimeters: mesh sections carry many vertices a few
    microns apart, which make mitre offsets slow (3DBenchy layers: 1150 vertices on
    average, 127 at 0.0125 mm)."""
    return simplify_polygons(outline, tolerance)


def bead_spacing(width: float, height: float) -> float:
    """Centerline spacing of neighbouring beads, mm: ``A / h = w - h (1 - pi/4)``."""
    return bead_area(width, height) / height


def offset(geoms, distance) -> np.ndarray:
    """Offset polygons by ``distance`` (mm, negative = inward), mitre joins, vectorized.

    ``geoms`` and ``distance`` broadcast against each other (scalars or arrays). GEOS's
    mitre joins divide by the sine of the turn, zero at a straight vertex; the result is
    right and the floating-point flag is not a warning.
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        return shapely.buffer(geoms, distance, join_style="mitre", mitre_limit=MITRE_LIMIT)


def offset_polygons(polygons, distance) -> tuple[np.ndarray, np.ndarray]:
    """Offset every Polygon of an array inward by ``-distance`` (mm, ``distance < 0``),
    mitre joins; ``distance`` is one value or one per polygon (so that one call offsets
    a polygon to several distances when it is repeated).

    Where nothing happens to a polygon's topology the mitre offset is each vertex moved
    along its corner's bisector, ``v = p + d (o_a + o_b) / (1 + o_a . o_b)`` with
    ``o_a``, ``o_b`` the outward unit normals of the corner's edges; that is done in
    numpy for all rings at once (GEOS spends ~1.5 us per vertex on the same result).
    A polygon keeps this result when every corner's mitre stays within
    :data:`MITRE_LIMIT`, every edge keeps its direction (none collapses), every ring its
    orientation, and the result is a valid polygon (no two parts of its boundary cross,
    so no part splits, merges or vanishes); the others go through :func:`offset`.
    Convex rings skip the validity test: when no edge reverses, their offset keeps every
    edge's direction in the same order and is convex, hence simple.

    Returns:
        ``(result, exact)``: one geometry per input (a Polygon where ``exact``, else
        GEOS's result, possibly a MultiPolygon or empty); ``exact`` marks the polygons
        offset vertex by vertex, whose offset by ``-distance`` gives the input back.
    """
    polygons = np.atleast_1d(np.asarray(polygons, dtype=object))
    distance = np.broadcast_to(np.asarray(distance, dtype=float), polygons.shape)
    if not np.all(distance < 0):
        raise ValueError(f"offset_polygons erodes (distance < 0), got {distance.max()}")
    simple = (shapely.get_type_id(polygons) == shapely.GeometryType.POLYGON) & ~shapely.is_empty(polygons)
    out = np.empty(len(polygons), dtype=object)
    exact = np.zeros(len(polygons), dtype=bool)
    todo = np.flatnonzero(simple)
    if len(todo):
        moved, good = _mitre_offset(polygons[todo], distance[todo])
        exact[todo] = good
        out[todo[good]] = moved[good]
    rest = np.flatnonzero(~exact)
    if len(rest):
        out[rest] = offset(polygons[rest], distance[rest])
    return out, exact


def _mitre_offset(polygons: np.ndarray, distance: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Vertex-by-vertex mitre offsets of non-empty Polygons by one distance each, and per
    polygon whether it is the true offset (see :func:`offset_polygons`).

    An edge that the offset reverses between two edges that keep their direction
    collapses: its two vertices become the meeting point of its neighbours' offset lines
    (GEOS gives the same corner after removing the reversed edge's loop).
    """
    rings, ring_poly = shapely.get_rings(polygons, return_index=True)
    coords, ring = shapely.get_coordinates(rings, return_index=True)
    sizes = np.bincount(ring, minlength=len(rings)) - 1
    opened = np.ones(len(coords), dtype=bool)
    opened[np.cumsum(sizes + 1) - 1] = False
    p, ring = coords[opened], ring[opened]
    d = distance[ring_poly[ring]]
    first = np.cumsum(sizes) - sizes
    nxt = np.arange(1, len(p) + 1)
    nxt[first + sizes - 1] = first
    prv = np.empty_like(nxt)
    prv[nxt] = np.arange(len(p))
    edge = p[nxt] - p
    length = np.sqrt(np.einsum("ij,ij->i", edge, edge))
    area = np.bincount(ring, p[:, 0] * p[nxt, 1] - p[nxt, 0] * p[:, 1], minlength=len(rings))
    hole = np.r_[False, ring_poly[1:] == ring_poly[:-1]]
    side = (np.where(hole, -1.0, 1.0) * np.sign(area))[ring]  # +1: interior left of the edges
    with np.errstate(divide="ignore", invalid="ignore"):
        normal = np.column_stack([edge[:, 1], -edge[:, 0]]) * (side / length)[:, None]
        level = np.einsum("ij,ij->i", normal, p) + d  # offset line k: normal_k . q = level_k
        o_a = normal[prv]
        v = p + d[:, None] * (o_a + normal) / (1.0 + np.einsum("ij,ij->i", o_a, normal))[:, None]
        turn = (o_a[:, 0] * normal[:, 1] - o_a[:, 1] * normal[:, 0]) * side  # > 0: convex corner
        bad = _cut_mitre(o_a, normal, d * side) | ~(length > 0)
        rev = np.einsum("ij,ij->i", v[nxt] - v, edge) <= 0
        collapse = rev & ~rev[prv] & ~rev[nxt]
        bad |= rev & ~collapse
        i = np.flatnonzero(collapse)
        v[i] = _meet(normal[prv[i]], level[prv[i]], normal[nxt[i]], level[nxt[i]])
        bad[i] |= _cut_mitre(normal[prv[i]], normal[nxt[i]], d[i] * side[i])
        kept = np.ones(len(p), dtype=bool)
        kept[nxt[i]] = False
        # each kept vertex starts the original edge after the one it swallowed, if any
        start_edge = np.where(collapse, nxt, np.arange(len(p)))
        nxt_kept = np.where(kept[nxt], nxt, nxt[nxt])
        bad |= kept & ~(np.einsum("ij,ij->i", v[nxt_kept] - v, edge[start_edge]) > 0)
        bad |= ~np.isfinite(v).all(axis=1)
        cross = (v[:, 0] * v[nxt_kept, 1] - v[nxt_kept, 0] * v[:, 1])[kept]
    new_sizes = np.bincount(ring[kept], minlength=len(rings))
    new_area = np.bincount(ring[kept], cross, minlength=len(rings))
    bad_ring = np.bincount(ring, bad, minlength=len(rings)) > 0
    bad_ring |= (new_sizes < 3) | (area == 0) | (np.sign(new_area) != np.sign(area))
    good = np.bincount(ring_poly, bad_ring, minlength=len(polygons)) == 0
    convex_ring = np.bincount(ring, turn <= 0, minlength=len(rings)) == 0
    convex = good & (np.bincount(ring_poly, ~convex_ring | hole, minlength=len(polygons)) == 0) & ~np.bincount(
        ring_poly[ring[i]], minlength=len(polygons)
    ).astype(bool)
    # the good polygons' rings, each closed by repeating its first vertex
    good_ring = good[ring_poly]
    kept &= good_ring[ring]
    renumber = np.cumsum(good_ring) - 1
    sizes = new_sizes[good_ring]
    ring_at = np.r_[0, np.cumsum(sizes + 1)]
    out = np.empty((ring_at[-1], 2))
    out[np.arange(kept.sum()) + renumber[ring[kept]]] = v[kept]
    out[ring_at[1:] - 1] = out[ring_at[:-1]]
    poly_at = np.r_[0, np.cumsum(np.bincount(ring_poly, minlength=len(polygons))[good])]
    result = np.empty(len(polygons), dtype=object)
    result[good] = shapely.from_ragged_array(shapely.GeometryType.POLYGON, out, (ring_at, poly_at))
    check = good & ~convex
    good[check] = shapely.is_valid(result[check])
    return result, good


def _meet(normal_a: np.ndarray, level_a: np.ndarray, normal_b: np.ndarray, level_b: np.ndarray) -> np.ndarray:
    """Meeting points of the lines ``normal_a . q = level_a`` and ``normal_b . q = level_b``
    (non-finite for parallel lines)."""
    det = normal_a[:, 0] * normal_b[:, 1] - normal_a[:, 1] * normal_b[:, 0]
    x = (level_a * normal_b[:, 1] - level_b * normal_a[:, 1]) / det
    y = (normal_a[:, 0] * level_b - normal_b[:, 0] * level_a) / det
    return np.column_stack([x, y])


def _cut_mitre(normal_a: np.ndarray, normal_b: np.ndarray, distance) -> np.ndarray:
    """Corners between edges of outward normals ``normal_a`` then ``normal_b`` whose mitre
    the offset by ``distance`` would bevel, ``distance`` (one value or one per corner)
    being multiplied by -1 on rings whose interior lies right of their edges: where the
    offset edges part (convex corners when growing, reflex ones when shrinking) and the mitre is longer than
    :data:`MITRE_LIMIT` times the distance."""
    turn = (normal_a[:, 0] * normal_b[:, 1] - normal_a[:, 1] * normal_b[:, 0]) * np.sign(distance)
    denom = 1.0 + np.einsum("ij,ij->i", normal_a, normal_b)
    return (turn > 0) & ~(denom >= 2.0 / MITRE_LIMIT**2)


def opening(geoms, radius) -> np.ndarray:
    """Morphological opening: erode by ``radius`` then dilate back (mm), vectorized.

    Removes every part narrower than ``2 * radius`` and keeps the rest unchanged
    (sharp corners included, thanks to mitre joins).
    """
    return offset(offset(geoms, -np.asarray(radius)), radius)


def ring_groups(geoms) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every ring (exteriors and holes) of an array of polygonal geometries, flattened.

    Returns:
        ``(coords, ring_index, ring_source)``: the ``(M, 2)`` vertices of all rings
        without the repeated closing vertex; for each vertex the index (0..R-1) of its
        ring; for each ring the index into ``geoms`` of the geometry it belongs to.
        Rings with fewer than 3 distinct vertices are left out. Within a polygon the
        exterior comes first.
    """
    geoms = np.atleast_1d(np.asarray(geoms, dtype=object))
    parts, part_src = shapely.get_parts(geoms, return_index=True)
    keep = ~shapely.is_empty(parts)
    parts, part_src = parts[keep], part_src[keep]
    rings, ring_part = shapely.get_rings(parts, return_index=True)
    big = shapely.get_num_coordinates(rings) >= 4
    rings, ring_part = rings[big], ring_part[big]
    coords, index = shapely.get_coordinates(rings, return_index=True)
    last = np.ones(len(index), dtype=bool)  # each ring's repeated closing vertex
    last[:-1] = index[1:] != index[:-1]
    return coords[~last], index[~last], part_src[ring_part]


def ring_starts(index: np.ndarray) -> np.ndarray:
    """Where each ring begins in flat vertices (``index`` per vertex, as :func:`ring_groups`
    gives); empty when there are no vertices."""
    starts = np.ones(len(index), dtype=bool)
    starts[1:] = index[1:] != index[:-1]
    return np.flatnonzero(starts)


def split_rings(coords: np.ndarray, index: np.ndarray, roles, colors, width, height: float, groups=-1) -> list[Path]:
    """Closed :class:`Path` objects from flat ring vertices (as :func:`ring_groups` gives).

    ``roles`` is one :class:`Role` or one per ring; ``colors``, ``width`` (mm) and
    ``groups`` one value or one per ring.
    """
    if len(coords) == 0:
        return []
    starts = ring_starts(index)
    ends = np.append(starts[1:], len(coords))
    n = len(starts)
    roles = [roles] * n if isinstance(roles, Role) else list(roles)
    colors = np.broadcast_to(np.asarray(colors, dtype=int), (n,)).tolist()
    groups = np.broadcast_to(np.asarray(groups, dtype=int), (n,)).tolist()
    widths = np.broadcast_to(np.asarray(width, dtype=float), (n,)).tolist()
    return [
        Path(coords[a:b], role, color, w, height, closed=True, group=group)
        for a, b, role, color, w, group in zip(starts.tolist(), ends.tolist(), roles, colors, widths, groups)
    ]


def island_of(outline, coords: np.ndarray, ring_index: np.ndarray) -> np.ndarray:
    """For each ring (flat vertices as :func:`ring_groups` gives), the index of the part
    of ``outline`` that holds its first vertex (-1 if none)."""
    first = ring_starts(ring_index)
    islands = shapely.get_parts(outline)
    ring, island = shapely.STRtree(islands).query(shapely.points(coords[first]), predicate="intersects")
    out = np.full(len(first), -1, dtype=np.int64)
    out[ring[::-1]] = island[::-1]
    return out


SHARPEST_EXACT_CORNER = 45.0
"""Corners (degrees, convex or reflex) at least this open are offset as exact mitres
(their mitre stays within :data:`MITRE_LIMIT`, which allows down to about 39 degrees)."""


def _mitres_exact(outline) -> bool:
    """True when no corner of ``outline`` is sharper than :data:`SHARPEST_EXACT_CORNER`,
    so that every offset of it keeps plain mitre corners (no bevels)."""
    coords, ring, _ = ring_groups(outline)
    if len(coords) == 0:
        return True
    first = ring_starts(ring)
    last = np.append(first[1:], len(coords)) - 1
    nxt, prv = np.arange(1, len(coords) + 1), np.arange(-1, len(coords) - 1)
    nxt[last], prv[first] = first, last
    u, v = coords[prv] - coords, coords[nxt] - coords
    cos = np.sum(u * v, axis=1) / np.maximum(np.hypot(*u.T) * np.hypot(*v.T), 1e-300)
    return bool(np.all(cos <= np.cos(np.deg2rad(SHARPEST_EXACT_CORNER))))


def _erosions(outline, distances: np.ndarray) -> np.ndarray:
    """``offset(outline, -distances)``: one geometry per distance (mm). A convex outline
    of one polygon without holes (the vase's ellipses) is eroded to every distance at once
    by :func:`_convex_erosions`; other outlines by one GEOS call (numpy offsets of
    concave mesh sections meet an event at most levels, and GEOS then redoes them)."""
    parts = shapely.get_parts(outline)
    if len(parts) == 1:
        convex = _convex_erosions(parts[0], distances)
        if convex is not None:
            return convex
    return offset(outline, -distances)


def _convex_erosions(polygon, distances: np.ndarray) -> np.ndarray | None:
    """Exact mitre erosions of a convex Polygon without holes to several distances (mm,
    > 0), exteriors clockwise from the input's first vertex like GEOS's; None when the
    polygon has holes or a corner that is not strictly convex, or an edge would reverse.

    Every vertex moves along its corner's mitre vector ``m = (o_a + o_b) / (1 + o_a . o_b)``
    (see :func:`offset_polygons`), the same at every distance, so all levels cost one
    product. An edge's direction changes linearly with the distance: kept at the largest
    one, it is kept at all. A convex polygon's offset that keeps every edge's direction is
    convex, hence valid, and GEOS's has the same vertices (convex corners are neither
    bevelled nor simplified when eroding).
    """
    if shapely.get_num_interior_rings(polygon):
        return None
    p = shapely.get_coordinates(polygon)[:-1]
    if not shapely.is_ccw(shapely.get_exterior_ring(polygon)):
        p = np.roll(p[::-1], 1, axis=0)
    edge = np.roll(p, -1, axis=0) - p
    with np.errstate(divide="ignore", invalid="ignore"):
        normal = np.column_stack([edge[:, 1], -edge[:, 0]]) / np.hypot(*edge.T)[:, None]
        o_a = np.roll(normal, 1, axis=0)
        if not np.all(o_a[:, 0] * normal[:, 1] - o_a[:, 1] * normal[:, 0] > 0):
            return None
        mitre = (o_a + normal) / (1.0 + np.einsum("ij,ij->i", o_a, normal))[:, None]
    shifted = edge - distances.max() * (np.roll(mitre, -1, axis=0) - mitre)
    if not np.all(np.einsum("ij,ij->i", shifted, edge) > 0):
        return None
    n, levels = len(p), len(distances)
    ring = np.arange(n, -1, -1) % n  # clockwise, closed
    coords = (p[ring] - distances[:, None, None] * mitre[ring]).reshape(-1, 2)
    offsets = (np.arange(levels + 1) * (n + 1), np.arange(levels + 1))
    return shapely.from_ragged_array(shapely.GeometryType.POLYGON, coords, offsets)


def _same_combinatorics(a, b) -> np.ndarray:
    """Per pair, whether two inward offsets of one outline have the same parts, holes and
    vertex count: no edge vanished and no part split or vanished between their distances."""
    return (
        (shapely.get_num_geometries(a) == shapely.get_num_geometries(b))
        & (_holes(a) == _holes(b))
        & (shapely.get_num_coordinates(a) == shapely.get_num_coordinates(b))
        & ~shapely.is_empty(b)
    )


def _holes(geoms) -> np.ndarray:
    """Number of holes of each polygonal geometry of an array."""
    parts, src = shapely.get_parts(geoms, return_index=True)
    return np.bincount(src, shapely.get_num_interior_rings(parts), minlength=len(geoms))


def _erode_more(half: np.ndarray, have: np.ndarray, loops: np.ndarray, outline, distances: np.ndarray) -> None:
    """Fill ``half[k] = offset(outline, -distances[k])`` (in place) for the ``loops`` not
    marked in ``have`` yet, in one vectorized offset, and mark them."""
    need = loops[~have[loops]]
    if len(need):
        half[need] = offset(outline, -distances[need])
        have[need] = True


@dataclass(frozen=True)
class Walls:
    """Result of :func:`make_walls`.

    Attributes:
        paths: the perimeters, ordered by loop index (outermost loops first when
            outer-first, innermost first otherwise); each carries as ``group`` the
            index of its island in ``outline`` (holes belong to their island).
        inner: area left for skins and infill (the inner edge of the innermost loop's
            nominal strip, i.e. ``s / 2`` inside its centerline), a MultiPolygon.
        eroded: the outline eroded by ``w / 2`` (where the outermost centerline may run;
            with ``uncovered_area`` it gives the area no bead fits in).
    """

    paths: list[Path]
    inner: shapely.Geometry
    eroded: shapely.Geometry


def make_walls(outline, count: int, width: float, height: float, *, outer_first: bool = False, color: int = 0) -> Walls:
    """Perimeters of ``outline``: ``count`` loops per island and per hole.

    Loop ``k`` is the boundary of the outline (already simplified,
    :func:`simplify_outline`) eroded by ``w / 2 + k s`` (``s`` from :func:`bead_spacing`), opened by ``s / 2`` so that no loop is printed around a
    sliver narrower than the bead spacing (its two sides would overlap). The loop
    centers and the inner area (erosion by ``w / 2 + (count - 1) s + s / 2``) come from
    one vectorized offset. Where a loop's erosion and the next level (the inner area for
    the last loop), or failing that its erosion by ``s / 2`` more (one more vectorized
    offset), have the same combinatorics and the outline has no corner sharper than
    :data:`SHARPEST_EXACT_CORNER`, nothing thinner than a spacing exists in between and
    the opening equals the erosion; elsewhere the opening is computed (that erosion by
    ``w / 2 + k s + s / 2``, dilated by ``s / 2``). Loop 0 of
    each island and of each hole has role EXTERNAL_PERIMETER, the others PERIMETER.
    Every loop's ``group`` is the index of the outline island it lies in, so that
    planning prints one island's loops together in this order.

    Args:
        outline: the layer's cross-section (Polygon or MultiPolygon), mm.
        count: number of loops (0 = none; the inner area is then the outline eroded by
            ``w / 2``, so fills keep their centerlines half a bead inside).
        width, height: bead width and layer height, mm.
        outer_first: print order of the loops of each island.
        color: color given to every loop.
    """
    s = bead_spacing(width, height)
    if count == 0 or outline.is_empty:
        eroded = offset(outline, -width / 2)
        return Walls([], eroded, eroded)
    dist = width / 2 + s * np.arange(count)
    levels = _erosions(outline, np.append(dist, dist[-1] + s / 2))
    centers, inner, eroded = levels[:count], levels[count], levels[0]
    # each loop's erosion by s / 2 more (the inner area for the last loop; others on demand)
    half = np.empty(count, dtype=object)
    half[-1] = inner
    have = np.arange(count) == count - 1
    unchanged = _same_combinatorics(centers, levels[1:])
    check = np.flatnonzero(~unchanged[:-1])
    _erode_more(half, have, check, outline, dist + s / 2)
    unchanged[check] = _same_combinatorics(centers[check], half[check])
    if not (unchanged.any() and _mitres_exact(outline)):
        unchanged[:] = False
    redo = np.flatnonzero(~unchanged)
    _erode_more(half, have, redo, outline, dist + s / 2)
    centers[redo] = offset(half[redo], s / 2)
    coords, ring_idx, loop = ring_groups(centers)
    roles = np.where(loop == 0, Role.EXTERNAL_PERIMETER, Role.PERIMETER)
    paths = split_rings(coords, ring_idx, roles, color, width, height, island_of(outline, coords, ring_idx))
    order = np.argsort(loop if outer_first else -loop, kind="stable")
    return Walls([paths[i] for i in order], inner, eroded)
