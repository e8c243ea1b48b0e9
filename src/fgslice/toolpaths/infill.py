"""Infill: rectilinear lines linked into serpentines, and concentric loops.

Units mm and degrees. Densities are fractions of a solid fill in percent (0-100).
A fill at density ``d`` lays lines whose total length times the bead cross-section
``A`` equals ``region area x h x d / 100`` (see ``docs/toolpaths.md``): the nominal
line spacing is ``s * 100 / d`` with ``s = A / h`` (:func:`~fgslice.toolpaths.walls.bead_spacing`),
corrected once for the length of the links between lines.

Rectilinear lines are anchored on a global grid (line ``i`` at ``(i + 1/2) * spacing``
across the fill direction), so sparse infill stacks from layer to layer. Line ``i`` of
a serpentine runs left to right in the rotated frame when ``i`` is even, right to left
when odd; consecutive lines are joined at alternating ends by a straight link when the
link lies inside the region and is at most :data:`MAX_LINK_SPACINGS` spacings long.
In the returned paths, segment ``2 j`` is the ``j``-th line and segment ``2 j + 1`` the
link after it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import shapely

from fgslice.toolpaths.paths import Path, Role
from fgslice.toolpaths.walls import (
    bead_spacing,
    offset,
    offset_polygons,
    opening,
    ring_groups,
    ring_starts,
    split_rings,
)

MAX_LINK_SPACINGS = 3.0
"""Longest link between two neighbouring lines, in line spacings."""

VOLUME_TOLERANCE = 0.01
"""Relative volume error of a rectilinear fill above which its spacing is corrected."""

SPACING_CANDIDATES = (0.96, 0.98, 1.0, 1.02, 1.04)
"""Factors around the corrected spacing tried when a fill misses its volume."""

SLIVER_MIN_AREA_PER_MM = 0.05
"""A part's opening is searched for slivers only when it loses more than this many bead
widths of area per mm of the part's boundary (less is the rounding of mitre corners)."""

SLIVER_MIN_THICKNESS = 1e-3
"""Gap fills are made only for slivers at least this thick on average (mm); thinner ones
are numerical residue of offsetting."""

MAX_WIDTH_FACTOR = 1.5
"""Widest dense bead, in nominal bead widths (a loop or a solid fill may be widened to
balance volume)."""

INSIDE_TOLERANCE = 1e-4
"""Slack (mm) when testing that a link lies inside the region: its ends are moved this far
inward along their lines, so a link along a straight boundary edge counts as inside."""


def _rotate(xy: np.ndarray, angle_deg: float) -> np.ndarray:
    """Rotate ``(N, 2)`` points about the origin by ``angle_deg`` (counter-clockwise)."""
    a = np.deg2rad(angle_deg)
    c, s = np.cos(a), np.sin(a)
    return xy @ np.array([[c, s], [-s, c]])


def scan_segments(coords: np.ndarray, ring: np.ndarray, spacing, min_length: float, group=None):
    """Scanline clip of the global grid of horizontal lines against polygon rings.

    ``coords``/``ring`` are the ring vertices of one region or of many disjoint ones
    (already rotated, no repeated closing vertex). Each edge crossing line
    ``y_i = (i + 1/2) spacing`` (half-open in y, so a vertex on a line counts once) gives
    an x; sorted per line, crossings pair up into inside intervals by the even-odd rule
    (which holds for the union of disjoint regions too). ``spacing`` is one value or one
    per ring; ``group``, when given (one value per ring), clips each group of rings on
    its own (groups may overlap, e.g. one region at several spacings).

    Returns ``(line, x0, x1, y, src, ends)`` arrays sorted by group, line then x, one row
    per segment at least ``min_length`` long; ``src`` is the ring whose edge the segment
    starts on (a segment lies in the region that ring bounds); ``ends`` ``(n, 2)`` the
    edges (index of their first vertex) its two ends lie on.
    """
    first = ring_starts(ring)
    nxt = np.arange(1, len(coords) + 1)
    nxt[np.append(first[1:], len(coords)) - 1] = first
    p, q = coords, coords[nxt]
    per_ring = np.ndim(spacing) > 0
    step = np.asarray(spacing)[ring] if per_ring else spacing
    lo_y, hi_y = np.minimum(p[:, 1], q[:, 1]), np.maximum(p[:, 1], q[:, 1])
    i0 = np.ceil(lo_y / step - 0.5).astype(np.int64)
    i1 = np.ceil(hi_y / step - 0.5).astype(np.int64)
    counts = np.maximum(i1 - i0, 0)
    edge = np.repeat(np.arange(len(p)), counts)
    line = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts) + i0[edge]
    y = (line + 0.5) * (step[edge] if per_ring else step)
    t = (y - p[edge, 1]) / (q[edge, 1] - p[edge, 1])
    x = p[edge, 0] + t * (q[edge, 0] - p[edge, 0])
    order = np.lexsort((x, line) if group is None else (x, line, np.asarray(group)[ring[edge]]))
    line, x, y, edge = line[order], x[order], y[order], edge[order]
    line, x0, x1, y, src = line[0::2], x[0::2], x[1::2], y[0::2], ring[edge[0::2]]
    keep = x1 - x0 >= min_length
    return line[keep], x0[keep], x1[keep], y[keep], src[keep], edge.reshape(-1, 2)[keep]


def _links(containers, owner, line, x0, x1, y, ends, spacing, angle_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """Accepted links ``(a, b)``: segment ``a`` on line ``i`` to segment ``b`` on ``i + 1``.

    The link joins the right ends when ``i`` is even, the left ends when odd; both
    segments must belong to the same region (``owner``), the link must be at most
    :data:`MAX_LINK_SPACINGS` times the region's ``spacing`` (one value, or one per
    region) long and lie in the region's entry of ``containers`` (bed frame). Each end
    is used once (shortest candidate wins).

    A link whose two ends lie on one boundary edge (``ends``, from
    :func:`scan_segments`) runs along that edge, :data:`INSIDE_TOLERANCE` inside it:
    it is taken without a test, like a link along an edge that ``covers`` accepts
    thanks to that slack (on 3DBenchy's fills, 70 % of the candidates; of their 62,000,
    one passes within 1e-4 mm of the tip of a hole touching the edge, which ``covers``
    refuses). The others are tested with ``covers``.
    """
    n = len(line)
    if n < 2:
        return np.empty(0, int), np.empty(0, int)
    # segments grouped by region, then line: candidates are the next line's group
    key = owner * (line.max() - line.min() + 2) + (line - line.min())
    by_key = np.lexsort((x0, key))
    sorted_key = key[by_key]
    next_start = np.searchsorted(sorted_key, key + 1, side="left")
    next_end = np.searchsorted(sorted_key, key + 1, side="right")
    counts = next_end - next_start
    a = np.repeat(np.arange(n), counts)
    if len(a) == 0:
        return a, a
    b = by_key[np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts) + np.repeat(next_start, counts)]
    right = line[a] % 2 == 0
    xa = np.where(right, x1[a], x0[a])
    xb = np.where(right, x1[b], x0[b])
    length = np.hypot(xb - xa, y[b] - y[a])
    ok = length <= MAX_LINK_SPACINGS * (np.asarray(spacing)[owner[a]] if np.ndim(spacing) else spacing)
    a, b, xa, xb, length, right = a[ok], b[ok], xa[ok], xb[ok], length[ok], right[ok]
    side = right.astype(np.int64)
    inside = ends[a, side] == ends[b, side]
    test = np.flatnonzero(~inside)
    if len(test):
        inward = np.where(right[test], -INSIDE_TOLERANCE, INSIDE_TOLERANCE)
        xy = np.column_stack([xa[test] + inward, y[a[test]], xb[test] + inward, y[b[test]]])
        links = shapely.linestrings(_rotate(xy.reshape(-1, 2), angle_deg).reshape(-1, 2, 2))
        shapely.prepare(containers)
        inside[test] = shapely.covers(containers[owner[a[test]]], links)
    a, b, length = a[inside], b[inside], length[inside]
    order = np.argsort(length, kind="stable")
    a, b = a[order], b[order]
    _, first_a = np.unique(a, return_index=True)
    a, b = a[np.sort(first_a)], b[np.sort(first_a)]
    _, first_b = np.unique(b, return_index=True)
    return a[np.sort(first_b)], b[np.sort(first_b)]


def _serpentines(line, x0, x1, y, owner, a, b) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Order linked segments into chains: ``(points (2n, 2), chain id per point, owner
    per chain)``.

    Each segment has at most one link to the next line and one from the previous, so
    chains are simple paths; each segment finds its chain's first segment (the lowest
    index: segments are sorted by line) by pointer jumping, and chains are numbered in
    the order of their first segments.
    """
    n = len(line)
    head = np.arange(n)
    head[b] = a
    while True:
        jumped = head[head]
        if np.array_equal(jumped, head):
            break
        head = jumped
    roots, chain = np.unique(head, return_inverse=True)
    n_chains = len(roots)
    order = np.lexsort((line, chain))
    forward = line[order] % 2 == 0
    start = np.where(forward, x0[order], x1[order])
    end = np.where(forward, x1[order], x0[order])
    pts = np.empty((2 * n, 2))
    pts[0::2, 0], pts[1::2, 0] = start, end
    pts[0::2, 1] = pts[1::2, 1] = y[order]
    chain_owner = np.empty(n_chains, dtype=np.int64)
    chain_owner[chain] = owner
    return pts, np.repeat(chain[order], 2), chain_owner


def line_fill(regions, spacing, angle_deg: float, width: float, *, link: bool = True):
    """Parallel lines across one region or many disjoint ones at ``spacing`` and
    ``angle_deg``, as polylines (one scanline pass for all regions).

    ``spacing`` is one value, or one per region: each region is then clipped on its
    own, so the regions may overlap (e.g. one region at several candidate spacings).
    ``link`` is one flag, or one per region.

    Returns:
        ``(points, chain, owner)``: the ``(M, 2)`` vertices of every polyline in the bed
        frame; per vertex, the index of its polyline (vertices of one polyline
        contiguous); per polyline, the index of the region it fills. Lines shorter than
        ``width`` are dropped; links never join two regions.
    """
    regions = np.atleast_1d(np.asarray(regions, dtype=object))
    empty = (np.empty((0, 2)), np.empty(0, int), np.empty(0, int))
    if np.any(np.asarray(spacing) <= 0):
        return empty
    coords, ring, ring_owner = ring_groups(regions)
    if len(coords) == 0:
        return empty
    if np.ndim(spacing):
        step, group = np.asarray(spacing, dtype=float)[ring_owner], ring_owner
    else:
        step, group = spacing, None
    line, x0, x1, y, src, ends = scan_segments(_rotate(coords, -angle_deg), ring, step, width, group)
    if len(line) == 0:
        return empty
    owner = ring_owner[src]
    if np.any(link):
        a, b = _links(regions, owner, line, x0, x1, y, ends, spacing, angle_deg)
        if np.ndim(link):
            linked = np.asarray(link, dtype=bool)[owner[a]]
            a, b = a[linked], b[linked]
    else:
        a = b = np.empty(0, int)
    pts, chain, chain_owner = _serpentines(line, x0, x1, y, owner, a, b)
    return _rotate(pts, angle_deg), chain, chain_owner


def _lengths(points: np.ndarray, chain: np.ndarray, owner: np.ndarray, count: int) -> tuple[np.ndarray, np.ndarray]:
    """Total length of lines and of links of :func:`line_fill` polylines per region
    (``owner`` per polyline, ``count`` regions), mm.

    Every polyline starts at an even vertex index and alternates line, link, line...,
    so segment ``i`` is a line exactly when ``i`` is even.
    """
    seg = np.hypot(*np.diff(points, axis=0).T)
    same = chain[1:] == chain[:-1]
    even = np.arange(len(seg)) % 2 == 0
    region = owner[chain[:-1]]
    lines = np.bincount(region[same & even], seg[same & even], minlength=count)
    links = np.bincount(region[same & ~even], seg[same & ~even], minlength=count)
    return lines, links


def rectilinear(
    region,
    density: float,
    angle_deg: float,
    width: float,
    height: float,
    role: Role,
    *,
    color: int = 0,
    link: bool = True,
) -> list[Path]:
    """Rectilinear fill of ``region`` at ``density`` percent (lines linked into serpentines);
    see :func:`rectilinear_many`."""
    return rectilinear_many([region], [density], angle_deg, width, height, [role], color=color, link=link)


def rectilinear_many(
    regions,
    densities,
    angle_deg: float,
    width: float,
    height: float,
    roles,
    *,
    color: int = 0,
    link: bool = True,
) -> list[Path]:
    """Rectilinear fills of several regions (each at its density, percent, with its
    role), lines linked into serpentines; the paths of region 0 first, then region 1...

    Each region is filled on its own (regions may overlap) but all in one
    :func:`line_fill` pass. The spacing starts at ``s * 100 / density``; when lines plus
    links then miss ``area * h * density / 100`` of volume by more than
    :data:`VOLUME_TOLERANCE`, the spacing is corrected for the measured link length
    (links are dropped if they would take more than half of the length) and the
    candidate spacings around it (:data:`SPACING_CANDIDATES`, for all such regions in
    a second pass) are tried, keeping the one closest in volume: with few lines, whole
    lines appear or vanish as the grid shifts.
    """
    regions = np.asarray(regions, dtype=object)
    densities = np.asarray(densities, dtype=float)
    keep = np.flatnonzero((densities > 0) & ~shapely.is_empty(regions))
    if len(keep) == 0:
        return []
    regions, densities, roles = regions[keep], densities[keep], [roles[i] for i in keep.tolist()]
    n, s = len(keep), bead_spacing(width, height)
    spacing = s * 100.0 / densities
    points, chain, owner = line_fill(regions, spacing, angle_deg, width, link=link)
    lines, links = _lengths(points, chain, owner, n)
    target = shapely.area(regions) * densities / 100.0 / s
    error = np.abs(lines + links - target)
    retry = np.flatnonzero((lines > 0) & (error > VOLUME_TOLERANCE * target))
    fills = [(points, chain, owner == r) for r in range(n)]
    if len(retry):
        linked = link & (target[retry] - links[retry] > 0.5 * target[retry])
        corrected = lines[retry] * spacing[retry] / np.where(linked, target[retry] - links[retry], target[retry])
        k = len(SPACING_CANDIDATES)
        pts, ch, own = line_fill(
            np.repeat(regions[retry], k), np.outer(corrected, SPACING_CANDIDATES).ravel(), angle_deg, width,
            link=np.repeat(linked, k),
        )
        tried = np.abs(np.sum(_lengths(pts, ch, own, len(retry) * k), axis=0).reshape(-1, k) - target[retry, None])
        best = np.argmin(tried, axis=1)
        for j, r in enumerate(retry.tolist()):
            if tried[j, best[j]] < error[r]:
                fills[r] = (pts, ch, own == j * k + best[j])
    paths = []
    for (pts, ch, mine), role in zip(fills, roles):
        chosen = mine[ch]
        paths += open_paths(pts[chosen], ch[chosen], role, color, width, height)
    return paths


def solid_fill(regions, angle_deg: float, width: float, height: float, role: Role, colors) -> list[Path]:
    """100 % rectilinear fill of many disjoint regions in one scanline pass.

    Lines are ``s`` apart (:func:`~fgslice.toolpaths.walls.bead_spacing`) and linked
    into serpentines within each region; the paths of region ``r`` get ``colors[r]``.
    Instead of trying other spacings, each region's beads get the width that deposits
    exactly its volume: with ``L`` its lines plus links, ``s' = area / L`` and
    ``w' = s' + h (1 - pi/4)``, clipped to ``[h, MAX_WIDTH_FACTOR w]`` (links add a few
    percent of length on narrow regions, so ``w'`` is slightly below ``w`` there).
    """
    regions = np.atleast_1d(np.asarray(regions, dtype=object))
    points, chain, owner = line_fill(regions, bead_spacing(width, height), angle_deg, width)
    if len(points) == 0:
        return []
    seg = np.hypot(*np.diff(points, axis=0).T) * (chain[1:] == chain[:-1])
    length = np.bincount(owner[chain[:-1]], seg, minlength=len(regions))
    share = np.divide(shapely.area(regions), length, out=np.zeros(len(regions)), where=length > 0)
    widths = np.clip(share + height * (1 - np.pi / 4), height, MAX_WIDTH_FACTOR * width)
    return open_paths(points, chain, role, np.asarray(colors, dtype=np.int64)[owner], widths[owner], height)


def open_paths(points: np.ndarray, chain: np.ndarray, role: Role, color, width, height: float) -> list[Path]:
    """Open :class:`Path` objects from flat polyline vertices grouped by ``chain``
    (``color`` and ``width``: one value, or one per polyline)."""
    if len(points) == 0:
        return []
    starts = np.flatnonzero(np.r_[True, chain[1:] != chain[:-1]])
    ends = np.r_[starts[1:], len(points)]
    colors = np.broadcast_to(np.asarray(color, dtype=np.int64), starts.shape).tolist()
    widths = np.broadcast_to(np.asarray(width, dtype=float), starts.shape).tolist()
    return [
        Path(points[s:e], role, c, w, height)
        for s, e, c, w in zip(starts.tolist(), ends.tolist(), colors, widths)
        if e - s >= 2
    ]


@dataclass(frozen=True)
class Loops:
    """Closed loop centerlines of many regions, flattened (see :func:`concentric_levels`).

    Attributes:
        coords: ``(M, 2)`` ring vertices, bed frame, mm (closing vertex not repeated).
        ring: ring index (0..R-1) of each vertex.
        region: per ring, the index of the region it fills.
        level: per ring, its offset level (0 = outermost); -1 for gap fills.
        width: per ring, its bead width, mm (narrower than nominal for gap fills).
        rest: what :func:`dense_levels` leaves to another fill when it stops at
            ``max_levels`` (parts of the last level eroded by ``s / 2``), else empty.
        rest_region: per ``rest`` entry, the index of its region.
    """

    coords: np.ndarray
    ring: np.ndarray
    region: np.ndarray
    level: np.ndarray
    width: np.ndarray
    rest: np.ndarray = field(default_factory=lambda: np.empty(0, dtype=object))
    rest_region: np.ndarray = field(default_factory=lambda: np.empty(0, dtype=np.int64))

    def paths(self, roles, colors, height: float) -> list[Path]:
        """The loops as closed paths (``roles``/``colors``: one value or one per ring)."""
        return split_rings(self.coords, self.ring, roles, colors, self.width, height)


def concentric_levels(regions, first: float, spacing: float, width: float, height: float, *,
                      gap_fill: bool = True, max_levels: int | None = None) -> Loops:
    """Concentric loop centerlines of many regions at once.

    Loop ``k`` of region ``r`` is the boundary of ``regions[r]`` eroded by
    ``first + k * spacing`` and opened by ``spacing / 2`` (no loop around a sliver
    narrower than the spacing). Erosion proceeds level by level over the connected
    parts of all regions still non-empty (one vectorized offset per step), at most
    ``max_levels`` levels.

    With ``gap_fill``, each sliver the opening removes (a part thinner than a spacing,
    e.g. the middle of a face or a tapering end) is printed as its own boundary loop with
    a reduced width ``w'`` chosen so that the loop deposits the sliver's share of
    material: with sliver area ``a`` and perimeter ``p`` (mean thickness ``2 a / p``),
    ``w' = a / p + s / 2 + h (1 - pi/4)``, clipped to ``[h, w]``. Slivers shorter than
    a bead (``p / 2 < w``) or thinner than :data:`SLIVER_MIN_THICKNESS` are dropped.
    Slivers are cut out (an overlay) only from parts whose opening lost a noticeable
    area (:data:`SLIVER_MIN_AREA_PER_MM`).
    """
    regions = np.atleast_1d(np.asarray(regions, dtype=object))
    parts, owner = shapely.get_parts(offset(regions, -first), return_index=True)
    geoms, owners, levels, widths = [], [], [], []
    level = 0
    while len(parts) and (max_levels is None or level < max_levels):
        half = offset(parts, -spacing / 2)
        alive = ~shapely.is_empty(half)
        opened = offset(half, spacing / 2)
        if gap_fill:
            # slivers: whole parts the opening removes, and parts of the rest whose
            # opening lost more than a thin rim's worth of area
            lost = shapely.area(parts) - shapely.area(opened)
            cut = alive & (lost > SLIVER_MIN_AREA_PER_MM * width * shapely.length(parts))
            pieces = np.concatenate([parts[~alive], shapely.difference(parts[cut], opened[cut])])
            thin, src_thin = shapely.get_parts(pieces, return_index=True)
            thin_owner = np.concatenate([owner[~alive], owner[cut]])[src_thin]
            area, perimeter = shapely.area(thin), shapely.length(thin)
            keep = (perimeter / 2 >= width) & (2 * area >= SLIVER_MIN_THICKNESS * perimeter)
            geoms.append(thin[keep])
            owners.append(thin_owner[keep])
            levels.append(np.full(keep.sum(), -1))
            widths.append(np.clip(area[keep] / perimeter[keep] + spacing / 2 + height * (1 - np.pi / 4), height, width))
        half, owner, opened = half[alive], owner[alive], opened[alive]
        geoms.append(opened)
        owners.append(owner)
        levels.append(np.full(len(owner), level))
        widths.append(np.full(len(owner), width))
        parts, src = shapely.get_parts(offset(half, -spacing / 2), return_index=True)
        owner = owner[src]
        level += 1
    if not geoms:
        empty = np.empty(0, int)
        return Loops(np.empty((0, 2)), empty, empty, empty, np.empty(0))
    coords, ring, src = ring_groups(np.concatenate(geoms))
    return Loops(coords, ring, np.concatenate(owners)[src], np.concatenate(levels)[src], np.concatenate(widths)[src])


def dense_levels(regions, first: float, spacing: float, width: float, height: float, *,
                 max_levels: int | None = None, eroded=None) -> Loops:
    """Concentric loops filling many regions densely, each deposits its own strip's volume.

    Loop ``k`` of region ``r`` is the boundary of a part ``P`` of ``regions[r]`` eroded by
    ``first + k * spacing`` (one vectorized offset per level over all parts still
    non-empty, at most ``max_levels`` levels). There is no opening and no gap fill:
    each loop's width is chosen so that it deposits the area of its own territory,
    ``P`` grown by ``g`` (``first`` for level 0: up to the region's edge; ``s / 2``
    otherwise) minus its children at the next level grown by ``s / 2``:
    ``s' = (area(P) + g perimeter(P) - area(C) - s/2 perimeter(C)) / perimeter(P)``,
    ``w' = s' + h (1 - pi/4)``, clipped to ``[h, MAX_WIDTH_FACTOR w]``. On a uniform
    band this is ``w`` inside and ``first + s/2 + h (1 - pi/4)`` (0.42 mm for w = 0.4,
    h = 0.2) for the outermost loop; where a part tapers or is thinner than a spacing the
    loop is narrowed or widened so that its part still gets the right volume. With
    ``max_levels`` reached, the rest is filled otherwise: the last loops' territory ends
    at their part eroded by ``s / 2``, where the other fill starts. Parts whose
    perimeter is shorter than two bead widths are dropped. ``eroded``, when given, is
    ``(polygons, region)``: the polygons of ``regions`` eroded by ``first`` (an offset
    the caller shares) and the region index of each. What is left for the other fill is
    returned as ``Loops.rest``.
    """
    regions = np.atleast_1d(np.asarray(regions, dtype=object))
    trim = height * (1 - np.pi / 4)
    if eroded is None:
        parts, owner = shapely.get_parts(regions, return_index=True)
        eroded = (offset_polygons(parts, -first)[0], owner)
    parts, src = shapely.get_parts(eroded[0], return_index=True)
    parts, owner, perimeter = _printable(parts, np.asarray(eroded[1])[src], width)
    area = shapely.area(parts)
    geoms, owners, levels, widths = [], [], [], []
    rest, rest_owner = np.empty(0, dtype=object), np.empty(0, dtype=np.int64)
    level = 0
    while len(parts):
        grow = first if level == 0 else spacing / 2
        if max_levels is not None and level + 1 >= max_levels:
            rest, rest_owner = offset(parts, -spacing / 2), owner
            share = (area + grow * perimeter - shapely.area(rest)) / perimeter
            nxt, src = np.empty(0, dtype=object), np.empty(0, dtype=np.int64)
            nxt_area = nxt_perimeter = np.empty(0)
        else:
            nxt, src = shapely.get_parts(offset(parts, -spacing), return_index=True)
            nxt, src, nxt_perimeter = _printable(nxt, src, width)
            nxt_area = shapely.area(nxt)
            child_area = np.bincount(src, nxt_area, minlength=len(parts))
            child_perimeter = np.bincount(src, nxt_perimeter, minlength=len(parts))
            share = (area + grow * perimeter - child_area - spacing / 2 * child_perimeter) / perimeter
        geoms.append(parts)
        owners.append(owner)
        levels.append(np.full(len(parts), level))
        widths.append(np.clip(share + trim, height, MAX_WIDTH_FACTOR * width))
        parts, owner, area, perimeter = nxt, owner[src], nxt_area, nxt_perimeter
        level += 1
    if not geoms:
        empty = np.empty(0, int)
        return Loops(np.empty((0, 2)), empty, empty, empty, np.empty(0))
    coords, ring, src = ring_groups(np.concatenate(geoms))
    return Loops(
        coords, ring, np.concatenate(owners)[src], np.concatenate(levels)[src], np.concatenate(widths)[src],
        rest, rest_owner,
    )


def _printable(parts: np.ndarray, owner: np.ndarray, width: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The non-empty parts whose perimeter is at least two bead widths, their owners and
    their perimeters (mm)."""
    perimeter = shapely.length(parts)
    keep = ~shapely.is_empty(parts) & (perimeter >= 2 * width)
    return parts[keep], owner[keep], perimeter[keep]


def concentric(region, density: float, width: float, height: float, role: Role, *, color: int = 0) -> list[Path]:
    """Concentric fill of ``region`` at ``density`` percent: loops ``spacing`` apart.

    The first loop is half a spacing inside ``region`` (``region`` is the area to fill,
    e.g. the inner edge of the innermost wall's strip); spacing is ``s * 100 / density``.
    """
    if density <= 0 or region.is_empty:
        return []
    spacing = bead_spacing(width, height) * 100.0 / density
    loops = concentric_levels([region], spacing / 2, spacing, width, height, gap_fill=density >= 100.0)
    return loops.paths(role, color, height)


def uncovered_area(regions, width: float, eroded=None) -> float:
    """Total area (mm²) of the parts of ``regions`` narrower than a bead.

    That is each region minus its opening by ``w / 2`` (erode by half a bead, dilate
    back): what no bead of width ``w`` fits in. ``eroded``, when given, is ``regions``
    already eroded by ``w / 2`` (``regions`` may then be separate polygons: their
    openings do not overlap); otherwise ``regions`` are opened as given.
    """
    regions = np.atleast_1d(np.asarray(regions, dtype=object))
    opened = opening(regions, width / 2) if eroded is None else offset(eroded, width / 2)
    # never below 0: an erosion dilated back with mitre joins can exceed the region
    # (overshoot at corners, or ~1e-12 mm^2 of rounding after an exact numpy erosion)
    return max(0.0, float(np.sum(shapely.area(regions)) - np.sum(shapely.area(opened))))
