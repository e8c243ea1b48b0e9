"""Strategy 1, "preserving traditional toolpaths": walls, skins and infill on the
outline, then each path cut into palette colors along the material field.

Cutting needs no polygon clipping. Paths are simplified to ``gcode_resolution`` first,
then sampled in two levels (:func:`_sample`): the field is evaluated at the ends and
middle of pieces of at most ten bead widths, and densely (sub-segments of at most
``w / 2``, field at their midpoints) only on pieces where the color may change. Where
the color (or zipper color, see :mod:`fgslice.toolpaths.zipper`) changes between two
consecutive sub-segments, the cut is placed at the crossing by a vectorized search
along the path (:func:`_refine`). Pieces shorter
than a bead are merged into their longer neighbour. Units mm; bed frame.
"""

from __future__ import annotations

import heapq
from dataclasses import dataclass

import numpy as np
import shapely

from fgslice.settings import Settings
from fgslice.slicing.layers import LayerRegions
from fgslice.toolpaths.infill import uncovered_area
from fgslice.toolpaths.paths import LayerPaths, Path
from fgslice.toolpaths.simplify import simplify_paths
from fgslice.toolpaths.skins import fill_inner, split_inner
from fgslice.toolpaths.walls import make_walls
from fgslice.toolpaths.zipper import tooth_length, zipper_labels

SEARCH_SPLITS = 4
"""Parts each search interval is split into per round (see :func:`_refine`)."""

SEARCH_ROUNDS = 4
"""Search rounds placing each cut: the crossing is found to ``w / 2 / 4^4 = w / 512``."""

COARSE_STEP_WIDTHS = 10.0
"""Longest first-level sampling piece, in bead widths (see :func:`_sample`)."""

SAFETY = 4.0
"""Factor between the largest midpoint deviation from linear interpolation on a layer
and the margin from cell boundaries beyond which a piece keeps one color."""

MIN_MARGIN = 1e-9
"""Smallest margin from a cell boundary (fraction units), for linear fields."""

WARN_QUANTILE = 0.1
"""Share of the cut-bounded pieces allowed below ``min_segment_mm`` in the palette advice."""


def layer_paths(
    regions: LayerRegions,
    below: list[shapely.Geometry],
    above: list[shapely.Geometry],
    field,
    palette,
    settings: Settings,
) -> tuple[LayerPaths, "ShortPieces | None"]:
    """Toolpaths of one layer, cut into colors, and its short-piece record (or None).

    Args:
        regions: the layer (only ``outline`` is used for geometry).
        below, above: outlines of the ``bottom_layers`` layers below and ``top_layers``
            above, nearest first (fewer near the bottom/top of the part).
        field: object with ``fractions(xy (N,2), z) -> (N, k)`` in the bed frame.
        palette: object with ``color_of``, ``zipper_neighbor`` and ``size``.
        settings: bead width, layer height, walls, skins, infill, zipper, tolerance.
    """
    w, h = settings.bead_width, settings.layer_height
    walls = make_walls(regions.outline, settings.walls, w, h, outer_first=settings.wall_order == "outer_first")
    areas = split_inner(walls.inner, regions.outline, below, above, settings)
    raw = simplify_paths(walls.paths + fill_inner(areas, regions.index, settings), settings.gcode_resolution)
    cut = cut_by_color(raw, field, palette, regions.z_plane, regions.index, settings)
    out = LayerPaths(regions.index, regions.z, regions.height)
    out.paths = cut.paths
    out.uncovered_mm2 = uncovered_area(regions.outline, w)
    return out, short_pieces(cut.bounded_lengths, palette.size, settings.min_segment_mm, regions.index)


@dataclass(frozen=True)
class Cut:
    """Result of :func:`cut_by_color`.

    Attributes:
        paths: the colored pieces.
        bounded_lengths: lengths (mm) of the pieces cut at both ends (these shrink
            roughly as 1 / palette size; pieces ending at a path's end do not).
    """

    paths: list[Path]
    bounded_lengths: np.ndarray


@dataclass(frozen=True)
class _Dense:
    """Sub-segments of a set of paths (flat arrays, one row per sub-segment, in path order).

    ``uniform`` marks sub-segments proven to hold one color and no zipper band (see
    :func:`_sample`); the others are at most ``w / 2`` long.
    """

    pid: np.ndarray
    segment: np.ndarray
    p0: np.ndarray
    p1: np.ndarray
    length: np.ndarray
    arc_mid: np.ndarray
    mid: np.ndarray
    uniform: np.ndarray


def _split(pid, segment, a, b, arc0, count) -> _Dense:
    """Split segments ``a -> b`` (starting at arc position ``arc0`` on path ``pid``) into
    ``count`` equal sub-segments each."""
    src = np.repeat(np.arange(len(a)), count)
    j = np.arange(len(src)) - (np.cumsum(count) - count)[src]
    step = ((b - a) / count[:, None])[src]
    sub = (np.hypot(*(b - a).T) / count)[src]
    p0 = a[src] + step * j[:, None]
    return _Dense(
        pid=pid[src],
        segment=segment[src],
        p0=p0,
        p1=p0 + step,
        length=sub,
        arc_mid=arc0[src] + sub * (j + 0.5),
        mid=p0 + step / 2,
        uniform=np.zeros(len(src), dtype=bool),
    )


def _pieces_of(length: np.ndarray, step: float) -> np.ndarray:
    """How many equal sub-segments of at most ``step`` mm split segments of ``length`` mm."""
    return np.maximum(np.ceil(length / step), 1).astype(np.int64)


def _sample(verts, pid, arc, field, palette, z: float, w: float, beta: float):
    """Sub-segments of the paths with the field's color (and zipper neighbor) on each.

    Two levels, so that the field is evaluated densely only where colors may change:

    1. every segment is split into pieces of at most :data:`COARSE_STEP_WIDTHS` ``w``;
       the field is evaluated at both ends and the middle of each piece. Its deviation
       from linear interpolation at the middle, ``e``, bounds the field's curvature on
       the layer: ``margin = SAFETY * max(e)``. A piece whose three samples have one
       color and lie farther than ``margin`` (plus the zipper half-band) from every
       cell boundary keeps that color all along (cells are convex, so the linear
       interpolation between its ends stays ``min(d0, d1)`` inside, and the field
       departs from it by less than the margin); it stays one *uniform* sub-segment;
    2. the other pieces are split into sub-segments of at most ``w / 2`` and the
       field is evaluated at their midpoints.

    Returns ``(dense, color, neighbor)``; ``neighbor`` is -1 outside zipper bands.
    """
    seg = np.flatnonzero(pid[1:] == pid[:-1])
    first_vertex = np.searchsorted(pid, pid[seg])
    a, b = verts[seg], verts[seg + 1]
    count = _pieces_of(np.hypot(*(b - a).T), COARSE_STEP_WIDTHS * w)
    coarse = _split(pid[seg], seg - first_vertex, a, b, arc[seg], count)
    n = len(coarse.pid)
    last = np.flatnonzero(np.r_[coarse.pid[1:] != coarse.pid[:-1], True])
    f = field.fractions(np.vstack([coarse.p0, coarse.mid, coarse.p1[last]]), z)
    f0, fm = f[:n], f[n : 2 * n]
    f1 = np.empty_like(f0)
    f1[:-1] = f0[1:]
    f1[last] = f[2 * n :]
    margin = max(SAFETY * float(np.max(np.abs(fm - (f0 + f1) / 2), initial=0.0)), MIN_MARGIN)
    c = np.asarray(palette.color_of(f), dtype=np.int64)
    near = np.asarray(palette.zipper_neighbor(f, beta + 200.0 * margin)) >= 0
    c0, cm = c[:n], c[n : 2 * n]
    c1, near1 = np.empty_like(c0), np.empty_like(near[:n])
    c1[:-1], near1[:-1] = c0[1:], near[1:n]
    c1[last], near1[last] = c[2 * n :], near[2 * n :]
    uniform = (c0 == c1) & (c0 == cm) & ~(near[:n] | near[n : 2 * n] | near1)
    fine_count = np.where(uniform, 1, _pieces_of(coarse.length, w / 2))
    dense = _split(coarse.pid, coarse.segment, coarse.p0, coarse.p1, coarse.arc_mid - coarse.length / 2, fine_count)
    dense.uniform[:] = np.repeat(uniform, fine_count)
    sampled = ~dense.uniform
    fine_f = field.fractions(dense.mid[sampled], z)
    color = np.repeat(c0, fine_count)
    color[sampled] = palette.color_of(fine_f)
    neighbor = np.full(len(color), -1, dtype=np.int64)
    if beta > 0:
        neighbor[sampled] = palette.zipper_neighbor(fine_f, beta)
    return dense, color, neighbor


def _refine(dense, k, nxt, predicate) -> np.ndarray:
    """Distance past the midpoint of ``k`` where ``predicate(points)`` turns False.

    The search runs between the two midpoints, or from the shared end when a side is
    uniform (its color is known all along it), so it spans at most ``w / 2``. Each of
    :data:`SEARCH_ROUNDS` rounds evaluates :data:`SEARCH_SPLITS` - 1 inner points of
    every interval at once and keeps the part where the predicate turns False. The
    path between the midpoints runs from the midpoint of ``k`` to its end, then from
    the start of ``nxt`` to its midpoint.
    """
    half_k, half_n = dense.length[k] / 2, dense.length[nxt] / 2
    mid_k, end_k, start_n = dense.mid[k][:, None], dense.p1[k][:, None], dense.p0[nxt][:, None]
    along_k, along_n = end_k - mid_k, dense.mid[nxt][:, None] - start_n
    lo = np.where(dense.uniform[k], half_k, 0.0)
    hi = half_k + np.where(dense.uniform[nxt], 0.0, half_n)
    j = np.arange(1, SEARCH_SPLITS)
    for _ in range(SEARCH_ROUNDS):
        step = (hi - lo) / SEARCH_SPLITS
        u = lo[:, None] + step[:, None] * j
        first = u <= half_k[:, None]
        on_k = mid_k + along_k * np.where(first, u / half_k[:, None], 1.0)[..., None]
        on_n = start_n + along_n * np.where(first, 0.0, (u - half_k[:, None]) / half_n[:, None])[..., None]
        same = predicate(np.where(first[..., None], on_k, on_n).reshape(-1, 2), len(j))
        passed = np.cumprod(same.reshape(-1, len(j)), axis=1).sum(axis=1)
        lo, hi = lo + step * passed, lo + step * (passed + 1)
    return (lo + hi) / 2


def cut_by_color(paths: list[Path], field, palette, z: float, layer_index: int, settings: Settings) -> Cut:
    """Cut ``paths`` into pieces of one color each (see the module docstring), listed in
    the order of ``paths`` and along each path."""
    if not paths:
        return Cut([], np.empty(0))
    w = settings.bead_width
    beta = settings.zipper
    verts_list = [p.vertices for p in paths]
    counts = np.array([len(v) for v in verts_list])
    verts = np.vstack(verts_list)
    pid = np.repeat(np.arange(len(paths)), counts)
    closed = np.array([p.closed for p in paths])
    step = np.r_[0.0, np.hypot(*np.diff(verts, axis=0).T)]
    step[np.r_[False, pid[1:] != pid[:-1]]] = 0.0
    cum = np.cumsum(step)
    first_vertex = np.r_[0, np.cumsum(counts)[:-1]]
    arc = cum - cum[first_vertex][pid]
    total = arc[np.cumsum(counts) - 1]

    dense, color, neighbor = _sample(verts, pid, arc, field, palette, z, w, beta)
    label = zipper_labels(
        color, neighbor, dense.pid, dense.segment, dense.arc_mid, dense.length, closed, layer_index,
        tooth_length(w, settings.min_segment_mm),
    )

    # cuts between consecutive sub-segments (and across the start of closed paths)
    first_sub = np.searchsorted(dense.pid, np.arange(len(paths)))
    last_sub = np.r_[first_sub[1:], len(dense.pid)] - 1
    inner = np.flatnonzero((dense.pid[1:] == dense.pid[:-1]) & (label[1:] != label[:-1]))
    wrap = np.flatnonzero(closed & (label[last_sub] != label[first_sub]))
    k = np.r_[inner, last_sub[wrap]]
    nxt = np.r_[inner + 1, first_sub[wrap]]
    u = dense.length[k] / 2
    band_k, band_n = neighbor[k] >= 0, neighbor[nxt] >= 0
    field_cut = ~band_k & ~band_n
    band_cut = band_k != band_n
    if field_cut.any():
        ks, ns = k[field_cut], nxt[field_cut]
        want = color[ks]
        u[field_cut] = _refine(dense, ks, ns, lambda xy, r: palette.color_of(field.fractions(xy, z)) == np.repeat(want, r))
    if band_cut.any():
        ks, ns = k[band_cut], nxt[band_cut]
        want = band_k[band_cut]
        u[band_cut] = _refine(
            dense, ks, ns, lambda xy, r: (palette.zipper_neighbor(field.fractions(xy, z), beta) >= 0) == np.repeat(want, r)
        )
    cpid = dense.pid[k]
    carc = np.mod(dense.arc_mid[k] + u, total[cpid])
    order = np.lexsort((carc, cpid))
    cpid, carc, clab = cpid[order], carc[order], label[nxt][order]
    bounds = np.searchsorted(cpid, np.arange(len(paths) + 1))

    whole: list[Path] = []
    whole_src: list[int] = []
    rows: list[tuple[int, float, float, int]] = []
    for i, path in enumerate(paths):
        a, b = bounds[i], bounds[i + 1]
        first_label = int(label[first_sub[i]])
        if a == b:
            whole.append(path.with_color(first_label))
            whole_src.append(i)
            continue
        cuts, labs = carc[a:b], clab[a:b].tolist()
        length = float(total[i])
        if path.closed:
            starts, ends = cuts.tolist(), np.r_[cuts[1:], cuts[0] + length].tolist()
        else:
            starts, ends, labs = [0.0] + cuts.tolist(), cuts.tolist() + [length], [first_label] + labs
        starts, ends, labs = _merge_short(starts, ends, labs, w, path.closed, length)
        if len(labs) == 1 and path.closed:
            whole.append(path.with_color(labs[0]))
            whole_src.append(i)
            continue
        rows += [(i, s0, s1, lab) for s0, s1, lab in zip(starts, ends, labs)]
    # pieces in the order of their source paths (and along each path)
    unordered = whole + _pieces(paths, verts, pid, arc, total, rows)
    order = np.argsort(np.r_[whole_src, [r[0] for r in rows]].astype(np.int64), kind="stable")
    pieces = [unordered[j] for j in order.tolist()]
    runs = _color_runs(color, dense.pid, dense.length, closed)
    return Cut(pieces, runs)


def _pieces(paths, verts, pid, arc, total, rows) -> list[Path]:
    """Build the pieces ``rows = [(path, start arc, end arc, color)]`` in bulk.

    A piece whose end passes its (closed) path's length wraps over the path's start.
    """
    if not rows:
        return []
    rpid = np.array([r[0] for r in rows])
    s0 = np.array([r[1] for r in rows])
    s1 = np.array([r[2] for r in rows])
    wraps = s1 > total[rpid]
    # wrapped pieces become two parts: [s0, total] and [0, s1 - total]
    part_pid = np.r_[rpid, rpid[wraps]]
    part_s0 = np.r_[s0, np.zeros(wraps.sum())]
    part_s1 = np.r_[np.minimum(s1, total[rpid]), s1[wraps] - total[rpid[wraps]]]
    gap = np.r_[0.0, np.cumsum(total + 1.0)[:-1]]
    g_arc = arc + gap[pid]
    g0, g1 = part_s0 + gap[part_pid], part_s1 + gap[part_pid]
    first = np.searchsorted(pid, part_pid)
    last = np.searchsorted(pid, part_pid, side="right") - 1
    head, tail = _points_at(verts, g_arc, g0, first, last), _points_at(verts, g_arc, g1, first, last)
    i0 = np.searchsorted(g_arc, g0, side="right")
    i1 = np.maximum(np.searchsorted(g_arc, g1, side="left"), i0)
    inner = i1 - i0
    size = inner + 2
    offsets = np.r_[0, np.cumsum(size)]
    out = np.empty((offsets[-1], 2))
    out[offsets[:-1]] = head
    out[offsets[1:] - 1] = tail
    slot = np.ones(offsets[-1], dtype=bool)
    slot[offsets[:-1]] = slot[offsets[1:] - 1] = False
    src = np.arange(inner.sum()) - np.repeat(np.cumsum(inner) - inner, inner) + np.repeat(i0, inner)
    out[slot] = verts[src]
    n_rows = len(rows)
    extra = dict(zip(np.flatnonzero(wraps).tolist(), range(n_rows, n_rows + int(wraps.sum()))))
    pieces = []
    for r, (i, _, _, lab) in enumerate(rows):
        pts = out[offsets[r] : offsets[r + 1]]
        if r in extra:
            e = extra[r]
            pts = np.vstack([pts, out[offsets[e] + 1 : offsets[e + 1]]])
        p = paths[i]
        pieces.append(Path(pts, p.role, lab, p.width, p.height, False, p.group))
    return pieces


def _points_at(verts, g_arc, g, first, last) -> np.ndarray:
    """Points at global arc positions ``g`` on paths spanning vertices ``first..last``."""
    idx = np.clip(np.searchsorted(g_arc, g, side="right") - 1, first, last - 1)
    span = g_arc[idx + 1] - g_arc[idx]
    t = np.clip(np.divide(g - g_arc[idx], span, out=np.zeros_like(g), where=span > 0), 0.0, 1.0)
    return verts[idx] + (verts[idx + 1] - verts[idx]) * t[:, None]


def _color_runs(color, pid, length, closed) -> np.ndarray:
    """Lengths of field-color runs bounded by color changes at both ends, mm.

    Computed on the densified sub-segments (accurate to a sub-segment), with runs
    of closed paths joined over the path start.
    """
    start = np.r_[True, (pid[1:] != pid[:-1]) | (color[1:] != color[:-1])]
    run = np.cumsum(start) - 1
    run_len = np.bincount(run, weights=length)
    run_pid = pid[start]
    run_color = color[start]
    first_run = np.searchsorted(run_pid, run_pid, side="left")
    last_run = np.searchsorted(run_pid, run_pid, side="right") - 1
    idx = np.arange(len(run_len))
    single = first_run == last_run
    c = closed[run_pid]
    joined = c & ~single & (run_color[first_run] == run_color[last_run])
    length_out = run_len.copy()
    at_first = joined & (idx == first_run)
    length_out[at_first] += run_len[last_run[at_first]]
    keep = ~single & ~(joined & (idx == last_run))
    keep &= c | ((idx != first_run) & (idx != last_run))
    return length_out[keep]


def _merge_short(starts: list, ends: list, labels: list, min_length: float, closed: bool, total: float):
    """Give each piece shorter than ``min_length`` its longer neighbour's color and
    join neighbours of equal color (cyclically for closed paths).

    Pieces are merged shortest first (the first of equal lengths in path order),
    each into its longer neighbour (the previous one on a tie). After the first
    merge all equal neighbours are joined; from then on each merge joins a piece
    with its neighbours of the new color, kept in a doubly linked list (pieces keep
    their list position as id; a piece joined over a closed path's start becomes
    the last one) with a heap of ``(length, id)`` checked lazily, so a path of ``n``
    pieces takes ``O(n log n)``.
    """
    if len(labels) < 2:
        return starts, ends, labels
    lengths = np.subtract(ends, starts)
    i = int(np.argmin(lengths))
    if lengths[i] >= min_length:
        return starts, ends, labels
    n = len(labels)
    options = [j for j in ((i - 1) % n if (closed or i > 0) else None, (i + 1) % n if (closed or i < n - 1) else None) if j is not None]
    labels = list(labels)
    labels[i] = labels[max(options, key=lambda j: lengths[j])]
    s, e, lab = _join_equal(starts, ends, labels, closed, total)
    n = len(lab)
    if n < 2:
        return s, e, lab
    nxt = list(range(1, n)) + [0 if closed else -1]
    prv = [n - 1 if closed else -1] + list(range(n - 1))
    alive = [True] * n
    heap = [(e[k] - s[k], k) for k in range(n)]
    heapq.heapify(heap)
    head, count = 0, n
    while count > 1:
        length, i = heap[0]
        if not alive[i] or length != e[i] - s[i]:
            heapq.heappop(heap)
            continue
        if length >= min_length:
            break
        has_prev = closed or i != head
        has_next = closed or nxt[i] != -1
        if has_prev and has_next:
            p, q = prv[i], nxt[i]
            j = p if e[p] - s[p] >= e[q] - s[q] else q
        else:
            j = prv[i] if has_prev else nxt[i]
        lab[i] = lab[j]
        # linear join: i with its previous and next pieces of the same color
        first = i
        if first != head and lab[prv[first]] == lab[first]:
            first = prv[first]
        last = first
        while nxt[last] != -1 and nxt[last] != head and lab[nxt[last]] == lab[first]:
            last = nxt[last]
        if first != last:
            e[first] = e[last]
            k = nxt[first]
            while True:
                alive[k] = False
                count -= 1
                if k == last:
                    break
                k = nxt[k]
            nxt[first] = nxt[last]
            if nxt[last] != -1:
                prv[nxt[last]] = first
            heapq.heappush(heap, (e[first] - s[first], first))
        # wrap join: the last piece continues into the first
        tail = prv[head]
        if closed and count > 1 and lab[head] == lab[tail]:
            e[tail] = e[head] + total
            alive[head] = False
            count -= 1
            nxt[tail], prv[nxt[head]] = nxt[head], tail
            head = nxt[head]
            heapq.heappush(heap, (e[tail] - s[tail], tail))
    keep = [k for k in range(n) if alive[k]]
    if closed and count > 1:
        # list order: from head around the cycle (a piece joined over the start is last)
        keep, k = [], head
        for _ in range(count):
            keep.append(k)
            k = nxt[k]
    return [s[k] for k in keep], [e[k] for k in keep], [lab[k] for k in keep]


def _join_equal(starts: list, ends: list, labels: list, closed: bool, total: float):
    """Merge consecutive pieces of the same color (for a closed path of length
    ``total``, the last piece continues into the first one)."""
    s, e, lab = [starts[0]], [ends[0]], [labels[0]]
    for s0, e0, l0 in zip(starts[1:], ends[1:], labels[1:]):
        if l0 == lab[-1]:
            e[-1] = e0
        else:
            s.append(s0), e.append(e0), lab.append(l0)
    if closed and len(lab) > 1 and lab[0] == lab[-1]:
        e[-1] = e[0] + total
        s, e, lab = s[1:], e[1:], lab[1:]
    return s, e, lab


@dataclass(frozen=True)
class ShortPieces:
    """Color pieces of one layer shorter than ``min_segment_mm``.

    Attributes:
        layer: layer index.
        short: how many pieces cut at both ends are shorter than ``min_segment_mm``.
        total: how many pieces are cut at both ends.
        shortest_mm: the shortest of them, mm.
        suggestion: the largest palette size expected to keep them long enough.
    """

    layer: int
    short: int
    total: int
    shortest_mm: float
    suggestion: int


def short_pieces(bounded: np.ndarray, palette_size: int, min_segment_mm: float, layer_index: int) -> ShortPieces | None:
    """The layer's short-piece record, or None when every piece is long enough.

    Pieces cut at both ends shrink roughly as ``1 / N`` with the palette size ``N``, so
    a palette of ``N * L_q / min_segment_mm`` colors keeps all but the shortest
    :data:`WARN_QUANTILE` of them long enough (``L_q`` that quantile of their lengths).
    """
    if len(bounded) == 0 or min_segment_mm <= 0 or bounded.min() >= min_segment_mm:
        return None
    suggestion = max(1, int(palette_size * np.quantile(bounded, WARN_QUANTILE) / min_segment_mm))
    return ShortPieces(layer_index, int(np.sum(bounded < min_segment_mm)), len(bounded), float(bounded.min()), suggestion)


def summarize_short_pieces(records: list[ShortPieces], layers: int, min_segment_mm: float) -> list[str]:
    """One warning for the whole print from the layers' short-piece records (none if empty)."""
    if not records:
        return []
    short = sum(r.short for r in records)
    total = sum(r.total for r in records)
    worst = min(records, key=lambda r: r.shortest_mm)
    suggestion = min(r.suggestion for r in records)
    return [
        f"{short} of {total} color pieces on {len(records)} of {layers} layers are shorter than "
        f"min_segment_mm = {min_segment_mm:g} mm (shortest {worst.shortest_mm:.2f} mm, layer {worst.layer}); "
        f"a palette of at most {suggestion} colors would keep them long enough"
    ]
