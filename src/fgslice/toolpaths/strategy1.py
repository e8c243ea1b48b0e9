"""Strategy 1, "preserving traditional toolpaths": walls, skins and infill on the
outline, then each path cut into palette colors along the material field.

Cutting needs no polygon clipping. Paths are simplified to ``gcode_resolution`` first,
then sampled in two levels (:func:`_sample`): the field is evaluated at the ends and
middle of pieces of at most ten bead widths, and densely (sub-segments of at most
``w / 2``, field at their midpoints) only on pieces where the color may change. Where
the color (or zipper color, see :mod:`fgslice.toolpaths.zipper`) changes between two
consecutive sub-segments, the cut is placed at the crossing by a vectorized search
along the path (:func:`_refine`). Pieces shorter
than a bead are merged into their longer neighbour. Units mm; bed frame. Inside,
points are complex numbers ``x + iy`` in 1-D arrays (cheap to gather, unlike rows of
``(N, 2)`` arrays) and only the sub-segments at cuts or in zipper bands are looked up.
"""

from __future__ import annotations

import heapq
from dataclasses import dataclass

import numpy as np
import shapely

from fgslice.settings import Settings
from fgslice.slicing.layers import LayerRegions
from fgslice.toolpaths.bridges import bridge_paths, split_bridges
from fgslice.toolpaths.graded_infill import density_regions
from fgslice.toolpaths.infill import uncovered_area
from fgslice.toolpaths.paths import LayerPaths, Path, Role
from fgslice.toolpaths.simplify import simplify_paths
from fgslice.toolpaths.skins import fill_inner, split_inner
from fgslice.toolpaths.thin_features import layer_thin_beads
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

VERTEX_TOLERANCE = 1e-9
"""Arc distance (mm) under which a path vertex counts as lying on a piece's end."""

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
        regions: the layer (only ``outline`` is used for geometry, simplified by
            :func:`~fgslice.toolpaths.walls.simplify_outline`).
        below, above: outlines of the ``bottom_layers`` layers below and ``top_layers``
            above, nearest first (fewer near the bottom/top of the part), simplified alike.
        field: object with ``fractions(xy (N,2), z) -> (N, k)`` in the bed frame (and,
            to grade the infill density, ``attributes`` and ``attribute(name, xy, z)``).
        palette: object with ``color_of``, ``zipper_neighbor`` and ``size``.
        settings: bead width, layer height, walls, skins, infill, zipper, tolerance.
    """
    w, h = settings.bead_width, settings.layer_height
    walls = make_walls(regions.outline, settings.walls, w, h, outer_first=settings.wall_order == "outer_first")
    areas = split_inner(walls.inner, regions.outline, below, above, settings)
    areas, bridges = split_bridges(areas, below[0] if below and settings.bottom_layers else None, settings)
    sparse = density_regions(areas.sparse, field, regions.z_plane, settings.infill_density)
    raw = simplify_paths(walls.paths, settings.gcode_resolution) + fill_inner(areas, regions.index, settings, sparse)
    raw += bridge_paths(bridges, settings)
    out = LayerPaths(regions.index, regions.z, regions.height)
    out.uncovered_mm2 = uncovered_area(regions.outline, w, eroded=walls.eroded)
    raw += layer_thin_beads(out, regions.outline, walls.eroded, 0, settings, Role.EXTERNAL_PERIMETER)
    cut = cut_by_color(raw, field, palette, regions.z_plane, regions.index, settings)
    out.paths = cut.paths
    if sparse:
        densities = [density for _, density in sparse]
        out.commanded["infill_density"] = (min(densities), max(densities))
    kinds = _piece_kinds([raw[i].role for i in cut.bounded_paths.tolist()])
    return out, short_pieces(cut.bounded_lengths, palette.size, settings.min_segment_mm, regions.index, kinds,
                             cut.bounded_crossing)


@dataclass(frozen=True)
class Cut:
    """Result of :func:`cut_by_color`.

    Attributes:
        paths: the colored pieces.
        bounded_lengths: lengths (mm) of the pieces cut at both ends (these shrink
            roughly as 1 / palette size; pieces ending at a path's end do not).
        bounded_paths: index of the input path of each of them.
        bounded_crossing: whether each of them crosses a color band (the colors before
            and after it differ) rather than grazing a boundary (the same color on both
            sides).
    """

    paths: list[Path]
    bounded_lengths: np.ndarray
    bounded_paths: np.ndarray
    bounded_crossing: np.ndarray


def _no_runs() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The bounded-run arrays of a :class:`Cut` without any cut."""
    return np.empty(0), np.empty(0, dtype=np.int64), np.empty(0, dtype=bool)


def _complex(xy: np.ndarray) -> np.ndarray:
    """``(N, 2)`` float points as ``(N,)`` complex numbers ``x + iy`` (a view when possible)."""
    return np.ascontiguousarray(xy, dtype=np.float64).view(np.complex128)[:, 0]


def _xy(points: np.ndarray) -> np.ndarray:
    """``(N,)`` complex points as an ``(N, 2)`` float view (x, y)."""
    return np.ascontiguousarray(points).view(np.float64).reshape(-1, 2)


@dataclass(frozen=True)
class _Lines:
    """The vertices of a list of paths, flat (closed paths repeat their first vertex).

    Points are complex ``x + iy`` (mm): indexing a 1-D complex array is much cheaper
    than gathering rows of an ``(N, 2)`` array.
    """

    vertex: np.ndarray
    pid: np.ndarray
    arc: np.ndarray
    first: np.ndarray
    total: np.ndarray
    closed: np.ndarray

    @classmethod
    def of(cls, paths: list[Path]) -> "_Lines":
        verts = [p.vertices for p in paths]
        counts = np.array([len(v) for v in verts])
        vertex = _complex(np.concatenate(verts))
        pid = np.repeat(np.arange(len(paths)), counts)
        step = np.concatenate(([0.0], np.abs(np.diff(vertex))))
        first = np.concatenate(([0], np.cumsum(counts)[:-1]))
        step[first] = 0.0
        cum = np.cumsum(step)
        arc = cum - np.repeat(cum[first], counts)
        total = arc[first + counts - 1]
        return cls(vertex, pid, arc, first, total, np.array([p.closed for p in paths]))


@dataclass(frozen=True)
class _Sub:
    """Attributes of a set of sub-segments (see :meth:`_Dense.locate`); lengths and arc
    positions in mm, points complex."""

    pid: np.ndarray
    length: np.ndarray
    arc_start: np.ndarray
    start: np.ndarray
    step: np.ndarray
    uniform: np.ndarray


@dataclass(frozen=True)
class _Dense:
    """Sub-segments of a set of paths, in path order, stored per sampling piece.

    Piece ``p`` (of path ``pid[p]``, on its segment ``segment[p]``) is split into
    ``count[p]`` equal sub-segments, numbered from ``offset[p]``: each ``length[p]``
    long (mm), the ``j``-th one running from ``origin[p] + j * step[p]`` (complex) at arc
    position ``arc0[p] + j * length[p]``. ``uniform`` pieces are proven to hold one
    color and no zipper band (see :func:`_sample`); the other sub-segments are at most
    ``w / 2`` long. Only the few sub-segments that matter (cuts, bands) are ever
    looked at one by one (:meth:`locate`).
    """

    offset: np.ndarray
    count: np.ndarray
    pid: np.ndarray
    segment: np.ndarray
    origin: np.ndarray
    step: np.ndarray
    length: np.ndarray
    arc0: np.ndarray
    uniform: np.ndarray

    @property
    def size(self) -> int:
        """Number of sub-segments."""
        return int(self.offset[-1] + self.count[-1])

    def locate(self, i: np.ndarray) -> _Sub:
        """Attributes of sub-segments ``i``."""
        p = np.searchsorted(self.offset, i, side="right") - 1
        j = i - self.offset[p]
        length = self.length[p]
        return _Sub(
            pid=self.pid[p],
            length=length,
            arc_start=self.arc0[p] + length * j,
            start=self.origin[p] + self.step[p] * j,
            step=self.step[p],
            uniform=self.uniform[p],
        )


def _repeat_index(count: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For items repeated ``count`` times each: the item of every copy and its rank."""
    item = np.repeat(np.arange(len(count)), count)
    return item, np.arange(len(item)) - np.repeat(np.cumsum(count) - count, count)


def _pieces_of(length: np.ndarray, step: float) -> np.ndarray:
    """How many equal sub-segments of at most ``step`` mm split segments of ``length`` mm."""
    return np.maximum(np.ceil(length / step), 1).astype(np.int64)


def _sample(lines: _Lines, field, palette, z: float, w: float, beta: float):
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

    Returns ``(dense, color, neighbor)``: per sub-segment, the color and the zipper
    neighbor (-1 outside bands; None without zipper).
    """
    pid, vertex = lines.pid, lines.vertex
    seg = np.flatnonzero(pid[1:] == pid[:-1])
    a = vertex[seg]
    d = vertex[seg + 1] - a
    length = np.abs(d)
    count = _pieces_of(length, COARSE_STEP_WIDTHS * w)
    src, j = _repeat_index(count)
    step = (d / count)[src]
    sub = (length / count)[src]
    p0 = a[src] + step * j
    cpid = pid[seg][src]
    n = len(src)
    last = np.flatnonzero(np.concatenate((cpid[1:] != cpid[:-1], [True])))
    f = field.fractions(_xy(np.concatenate([p0, p0 + step / 2, p0[last] + step[last]])), z)
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
    fine_count = np.where(uniform, 1, _pieces_of(sub, w / 2))
    dense = _Dense(
        offset=np.cumsum(fine_count) - fine_count,
        count=fine_count,
        pid=cpid,
        segment=(seg - lines.first[pid[seg]])[src],
        origin=p0,
        step=step / fine_count,
        length=sub / fine_count,
        arc0=lines.arc[seg][src] + sub * j,
        uniform=uniform,
    )
    color = np.repeat(c0, fine_count)
    neighbor = np.full(len(color), -1, dtype=np.int64) if beta > 0 else None
    split = np.flatnonzero(~uniform)
    if len(split):
        piece, rank = _repeat_index(fine_count[split])
        piece = split[piece]
        sampled = dense.offset[piece] + rank
        fine_f = field.fractions(_xy(p0[piece] + dense.step[piece] * (rank + 0.5)), z)
        color[sampled] = palette.color_of(fine_f)
        if beta > 0:
            neighbor[sampled] = palette.zipper_neighbor(fine_f, beta)
    return dense, color, neighbor


def _refine(k: _Sub, nxt: _Sub, same_side) -> np.ndarray:
    """Distance past the midpoint of sub-segments ``k`` where ``same_side(points)``
    turns False on the way to the midpoints of the following sub-segments ``nxt``.

    The search runs between the two midpoints, or from the shared end when a side is
    uniform (its color is known all along it), so it spans at most ``w / 2``. Each of
    :data:`SEARCH_ROUNDS` rounds evaluates :data:`SEARCH_SPLITS` - 1 inner points of
    every interval at once (``same_side`` gets them as ``(len(k) * (SEARCH_SPLITS - 1), 2)``
    rows, interval by interval) and keeps the part where the predicate turns False.
    The path between the midpoints runs from the midpoint of ``k`` to its end, then
    from the start of ``nxt`` to its midpoint.
    """
    half_k, half_n = k.length / 2, nxt.length / 2
    dir_k = np.divide(k.step, k.length, out=np.zeros_like(k.step), where=half_k > 0)[:, None]
    dir_n = np.divide(nxt.step, nxt.length, out=np.zeros_like(nxt.step), where=half_n > 0)[:, None]
    mid_k = (k.start + k.step / 2)[:, None]
    start_n = nxt.start[:, None]
    lo = np.where(k.uniform, half_k, 0.0)
    hi = half_k + np.where(nxt.uniform, 0.0, half_n)
    j = np.arange(1, SEARCH_SPLITS)
    for _ in range(SEARCH_ROUNDS):
        step = (hi - lo) / SEARCH_SPLITS
        u = lo[:, None] + step[:, None] * j
        past = u - half_k[:, None]
        points = np.where(past <= 0, mid_k + dir_k * u, start_n + dir_n * past)
        same = same_side(_xy(points.ravel())).reshape(-1, len(j))
        passed = np.cumprod(same, axis=1).sum(axis=1)
        lo, hi = lo + step * passed, lo + step * (passed + 1)
    return (lo + hi) / 2


def _changes(values: np.ndarray, path_start: np.ndarray) -> np.ndarray:
    """Sub-segments (not starting a path) whose value differs from the previous one's."""
    i = np.flatnonzero(values[1:] != values[:-1]) + 1
    at = np.minimum(np.searchsorted(path_start, i), len(path_start) - 1)
    return i[path_start[at] != i]


def cut_by_color(paths: list[Path], field, palette, z: float, layer_index: int, settings: Settings) -> Cut:
    """Cut ``paths`` into pieces of one color each (see the module docstring), listed in
    the order of ``paths`` and along each path."""
    if not paths:
        return Cut([], *_no_runs())
    if palette.size == 1:
        return Cut([p.with_color(0) for p in paths], *_no_runs())
    w = settings.bead_width
    beta = settings.zipper
    lines = _Lines.of(paths)
    dense, color, neighbor = _sample(lines, field, palette, z, w, beta)
    first_sub = dense.offset[np.searchsorted(dense.pid, np.arange(len(paths)))]
    last_sub = np.concatenate((first_sub[1:], [dense.size])) - 1
    color_change = _changes(color, first_sub)
    label, label_change = color, color_change
    if beta > 0 and (neighbor >= 0).any():
        in_band = neighbor >= 0
        loop = np.flatnonzero(in_band & np.repeat(lines.closed[dense.pid], dense.count))
        at = np.minimum(np.searchsorted(first_sub, loop), len(paths) - 1)
        run_start = (loop == 0) | ~in_band[loop - 1] | (first_sub[at] == loop)
        piece = np.searchsorted(dense.offset, loop, side="right") - 1
        length = dense.length[piece]
        arc_mid = dense.arc0[piece] + length * (loop - dense.offset[piece] + 0.5)
        label = zipper_labels(
            color, neighbor, np.repeat(dense.segment, dense.count), loop, run_start, arc_mid, length,
            layer_index, tooth_length(w, settings.min_segment_mm),
        )
        label_change = _changes(label, first_sub)

    # cuts between consecutive sub-segments (and across the start of closed paths)
    wrap = np.flatnonzero(lines.closed & (label[last_sub] != label[first_sub]))
    k = np.concatenate((label_change - 1, last_sub[wrap]))
    nxt = np.concatenate((label_change, first_sub[wrap]))
    sk = dense.locate(k)
    u = sk.length / 2
    if beta > 0:
        band_k, band_n = neighbor[k] >= 0, neighbor[nxt] >= 0
    else:
        band_k = band_n = np.zeros(len(nxt), dtype=bool)
    # cuts searched on the color (neither side in a band), then on the band edge
    by_color, by_band = np.flatnonzero(~band_k & ~band_n), np.flatnonzero(band_k != band_n)
    searched = np.concatenate((by_color, by_band))
    if len(searched):
        split = len(by_color) * (SEARCH_SPLITS - 1)
        want_color = np.repeat(color[k[by_color]], SEARCH_SPLITS - 1)
        want_band = np.repeat(band_k[by_band], SEARCH_SPLITS - 1)

        def same_side(xy: np.ndarray) -> np.ndarray:
            f = field.fractions(xy, z)
            same = np.empty(len(xy), dtype=bool)
            if split:
                same[:split] = palette.color_of(f[:split]) == want_color
            if split < len(xy):
                same[split:] = (palette.zipper_neighbor(f[split:], beta) >= 0) == want_band
            return same

        u[searched] = _refine(dense.locate(k[searched]), dense.locate(nxt[searched]), same_side)
    cpid = sk.pid
    carc = np.mod(sk.arc_start + sk.length / 2 + u, lines.total[cpid])
    pieces = _pieces(paths, lines, cpid, carc, label[nxt], label[first_sub], w)
    run_first = np.sort(np.concatenate((first_sub, color_change)))
    runs = dense.locate(run_first)
    return Cut(pieces, *_color_runs(runs.pid, color[run_first], runs.arc_start, lines.total, lines.closed))


def _pieces(paths, lines: _Lines, cpid, carc, clab, first_label, min_length: float) -> list[Path]:
    """The colored pieces of ``paths`` from their cuts (path, arc position, color after
    the cut), in the order of ``paths`` and along each path.

    An open path starts in ``first_label``; a closed path's last piece runs over its
    start. Pieces shorter than ``min_length`` are merged (:func:`_merge_short`, run
    only on the paths that have some). A path left in one piece keeps its points.
    """
    n_paths = len(paths)
    total, closed = lines.total, lines.closed
    has_cuts = np.bincount(cpid, minlength=n_paths) > 0
    # an open path's first piece starts at arc 0, in the path's first color
    opening = np.flatnonzero(has_cuts & ~closed)
    rpid = np.concatenate((opening, cpid))
    start = np.concatenate((np.zeros(len(opening)), carc))
    order = np.lexsort((start, rpid))
    rpid, start, lab = rpid[order], start[order], np.concatenate((first_label[opening], clab))[order]
    bounds = np.searchsorted(rpid, np.arange(n_paths + 1))
    end = np.empty_like(start)
    end[:-1] = start[1:]
    last = bounds[1:][has_cuts] - 1
    cut_paths = np.flatnonzero(has_cuts)
    end[last] = np.where(closed[cut_paths], start[bounds[:-1][has_cuts]] + total[cut_paths], total[cut_paths])

    rpid, start, end, lab = _merge_windows(rpid, start, end, lab, bounds, min_length, closed, total)
    # a path left in one piece (no cuts, or all merged into one) keeps its points
    count = np.bincount(rpid, minlength=n_paths)
    whole_label = first_label.copy()
    one = count[rpid] == 1
    whole_label[rpid[one]] = lab[one]
    rpid, start, end, lab = rpid[~one], start[~one], end[~one], lab[~one]
    whole = np.flatnonzero(count <= 1)
    xy, offsets = _piece_points(lines, rpid, start, end)
    item_pid = np.concatenate((whole, rpid))
    order = np.argsort(item_pid, kind="stable")
    item_piece = np.concatenate((np.full(len(whole), -1), np.arange(len(rpid))))[order]
    labels, whole_labels = lab.tolist(), whole_label.tolist()
    starts, ends = offsets[:-1].tolist(), offsets[1:].tolist()
    out = []
    for i, r in zip(item_pid[order].tolist(), item_piece.tolist()):
        p = paths[i]
        if r < 0:
            out.append(Path(p.points, p.role, whole_labels[i], p.width, p.height, p.closed, p.group))
        else:
            out.append(Path(xy[starts[r] : ends[r]], p.role, labels[r], p.width, p.height, False, p.group))
    return out


def _merge_windows(rpid, start, end, lab, bounds, min_length: float, closed, total):
    """Pieces (path, start, end, label; sorted by path and along it, ``bounds`` the
    path offsets) after merging those shorter than ``min_length`` (:func:`_merge_short`).

    A closed path with a short piece is merged whole. On open paths only windows are:
    runs of short pieces with their neighbours, chained through a single long piece
    between two runs. A long piece keeps its color and its outer neighbour has another
    color, so windows do not interact and give the same pieces as merging the whole
    path (a long serpentine with a few short pieces costs a few short merges).
    """
    is_short = end - start < min_length
    if not is_short.any():
        return rpid, start, end, lab
    same_path = rpid[1:] == rpid[:-1]
    open_piece = ~closed[rpid]
    touched = is_short.copy()
    touched[1:] |= is_short[:-1] & same_path
    touched[:-1] |= is_short[1:] & same_path
    touched &= open_piece
    # windows: consecutive touched pieces of a path, broken between two long pieces
    joined = same_path & touched[1:] & touched[:-1] & (is_short[1:] | is_short[:-1])
    first = np.flatnonzero(touched & ~np.concatenate(([False], joined)))
    last = np.flatnonzero(touched & ~np.concatenate((joined, [False])))
    whole = np.flatnonzero(np.bincount(rpid[is_short & ~open_piece], minlength=len(closed)) > 0)
    keep = ~touched & ~np.isin(rpid, whole)
    rows = [(rpid[keep], start[keep], end[keep], lab[keep])]
    spans = [(a, b + 1, False, 0.0) for a, b in zip(first.tolist(), last.tolist())]
    spans += [(bounds[i], bounds[i + 1], True, float(total[i])) for i in whole.tolist()]
    for a, b, is_closed, length in spans:
        merged = _merge_short(start[a:b].tolist(), end[a:b].tolist(), lab[a:b].tolist(), min_length, is_closed, length)
        rows.append((np.full(len(merged[2]), rpid[a]), *(np.array(c) for c in merged)))
    rpid, start, end, lab = (np.concatenate(c) for c in zip(*rows))
    order = np.lexsort((start, rpid))
    return rpid[order], start[order], end[order], lab[order]


def _piece_points(lines: _Lines, rpid, s0, s1) -> tuple[np.ndarray, np.ndarray]:
    """Points of the pieces ``[s0, s1]`` (arc positions, mm) of paths ``rpid``: all of
    them as one ``(M, 2)`` array and each piece's row offsets into it.

    A piece ending past its closed path's length runs over the path's start: closed
    paths are walked twice (vertices repeated with arc positions shifted by the length).
    Vertices within :data:`VERTEX_TOLERANCE` of a piece's ends are left out (a cut on a
    vertex, e.g. at a zipper tooth boundary, gives no repeated point).
    """
    counts = np.diff(np.concatenate((lines.first, [len(lines.vertex)])))
    ext = counts + np.where(lines.closed, counts - 1, 0)
    owner, rank = _repeat_index(ext)
    again = rank >= counts[owner]
    src = lines.first[owner] + np.where(again, rank - counts[owner] + 1, rank)
    vertex = lines.vertex[src]
    gap = np.concatenate(([0.0], np.cumsum(2 * lines.total + 1.0)[:-1]))
    g_arc = lines.arc[src] + np.where(again, lines.total[owner], 0.0) + gap[owner]
    ext_first = np.concatenate(([0], np.cumsum(ext)[:-1]))
    g0, g1 = s0 + gap[rpid], s1 + gap[rpid]
    first, last = ext_first[rpid], ext_first[rpid] + ext[rpid] - 1
    i0 = np.searchsorted(g_arc, g0 + VERTEX_TOLERANCE, side="right")
    i1 = np.maximum(np.searchsorted(g_arc, g1 - VERTEX_TOLERANCE, side="left"), i0)
    inner = i1 - i0
    offsets = np.concatenate(([0], np.cumsum(inner + 2)))
    out = np.empty(offsets[-1], dtype=np.complex128)
    out[offsets[:-1]] = _points_at(vertex, g_arc, g0, np.searchsorted(g_arc, g0, side="right"), first, last)
    out[offsets[1:] - 1] = _points_at(vertex, g_arc, g1, np.searchsorted(g_arc, g1, side="right"), first, last)
    piece, j = _repeat_index(inner)
    out[offsets[:-1][piece] + 1 + j] = vertex[i0[piece] + j]
    return _xy(out), offsets


def _points_at(vertex, g_arc, g, after, first, last) -> np.ndarray:
    """Complex points at global arc positions ``g`` on paths spanning vertices
    ``first..last``; ``after`` is the index of the first vertex past each position."""
    idx = np.clip(after - 1, first, last - 1)
    span = g_arc[idx + 1] - g_arc[idx]
    t = np.clip(np.divide(g - g_arc[idx], span, out=np.zeros_like(g), where=span > 0), 0.0, 1.0)
    return vertex[idx] + (vertex[idx + 1] - vertex[idx]) * t


def _color_runs(pid, color, arc, total, closed) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Lengths of field-color runs bounded by color changes at both ends, mm, the path of
    each, and whether the runs before and after it have different colors (it crosses a
    band) rather than the same (it grazes a boundary).

    Runs are given by where they start (path ``pid``, ``color``, arc position ``arc``,
    in path order); computed on the sub-segments (accurate to a sub-segment), with
    runs of closed paths (lengths ``total``) joined over the path start.
    """
    same_path = pid[1:] == pid[:-1]
    end = total[pid]
    end[:-1] = np.where(same_path, arc[1:], end[:-1])
    run_len = end - arc
    first_run = np.searchsorted(pid, pid, side="left")
    last_run = np.searchsorted(pid, pid, side="right") - 1
    idx = np.arange(len(run_len))
    single = first_run == last_run
    c = closed[pid]
    joined = c & ~single & (color[first_run] == color[last_run])
    length_out = run_len.copy()
    at_first = joined & (idx == first_run)
    length_out[at_first] += run_len[last_run[at_first]]
    keep = ~single & ~(joined & (idx == last_run))
    keep &= c | ((idx != first_run) & (idx != last_run))
    before = np.where(idx == first_run, np.where(joined, last_run - 1, last_run), idx - 1)
    after = np.where(idx == last_run, first_run, idx + 1)
    return length_out[keep], pid[keep], (color[before] != color[after])[keep]


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


PIECE_KINDS = ("walls", "skins", "sparse infill")
"""What a color piece belongs to, for the short-piece warning (:func:`_piece_kinds`)."""


def _piece_kinds(roles: list[Role]) -> np.ndarray:
    """Index into :data:`PIECE_KINDS` of each role: perimeters, solid fills, sparse infill."""
    kind = {Role.EXTERNAL_PERIMETER: 0, Role.PERIMETER: 0, Role.INTERNAL_INFILL: 2}
    return np.array([kind.get(r, 1) for r in roles], dtype=np.int64)


@dataclass(frozen=True)
class ShortPieces:
    """Color pieces of one layer shorter than ``min_segment_mm``.

    Attributes:
        layer: layer index.
        short: how many pieces cut at both ends are shorter than ``min_segment_mm``.
        total: how many pieces are cut at both ends.
        shortest_mm: the shortest of them, mm.
        suggestion: the largest palette size expected to keep the short pieces that
            cross a color band long enough (None when no short piece crosses one).
        by_kind: how many of the short ones are in walls, skins and sparse infill
            (:data:`PIECE_KINDS`).
        grazing: how many of the short ones only graze a color boundary.
    """

    layer: int
    short: int
    total: int
    shortest_mm: float
    suggestion: int | None
    by_kind: tuple[int, int, int] = (0, 0, 0)
    grazing: int = 0


def short_pieces(bounded: np.ndarray, palette_size: int, min_segment_mm: float, layer_index: int,
                 kinds: np.ndarray | None = None, crossing: np.ndarray | None = None) -> ShortPieces | None:
    """The layer's short-piece record, or None when every piece is long enough.

    A piece that crosses a color band (``crossing``: other colors before and after it) is
    as long as the band is wide along the path, and bands widen as ``1 / N`` with the
    palette size ``N``: a palette of ``N * L_q / min_segment_mm`` colors keeps all but the
    shortest :data:`WARN_QUANTILE` of those long enough (``L_q`` that quantile of their
    lengths). A piece that grazes a boundary (the same color on both sides: an infill
    line turning next to it, a wall running along it) does not depend on ``N``.
    ``kinds`` (:data:`PIECE_KINDS` index of each piece) gives ``by_kind``; without
    ``crossing`` every piece counts as crossing.
    """
    if len(bounded) == 0 or min_segment_mm <= 0 or bounded.min() >= min_segment_mm:
        return None
    short = bounded < min_segment_mm
    crossing = np.ones(len(bounded), dtype=bool) if crossing is None else crossing
    across = bounded[crossing]
    suggestion = None
    if np.any(short & crossing):
        suggestion = max(1, int(palette_size * _quantile(across, WARN_QUANTILE) / min_segment_mm))
    by_kind = (0, 0, 0) if kinds is None else tuple(np.bincount(kinds[short], minlength=len(PIECE_KINDS)).tolist())
    return ShortPieces(layer_index, int(np.sum(short)), len(bounded), float(bounded.min()), suggestion, by_kind,
                       int(np.sum(short & ~crossing)))


def _quantile(values: np.ndarray, q: float) -> float:
    """The ``q`` quantile of ``values``, interpolated linearly between the two order
    statistics around ``(n - 1) q`` (``np.quantile``'s default method). Two partial
    sorts: ``np.quantile`` would import ``numpy.ma`` on first use, about 30 ms in every
    worker process."""
    position = (len(values) - 1) * q
    below = int(position)
    above = min(below + 1, len(values) - 1)
    low, high = np.partition(values, (below, above))[[below, above]]
    return float(low + (high - low) * (position - below))


def summarize_short_pieces(records: list[ShortPieces], layers: int, min_segment_mm: float, palette_size: int) -> list[str]:
    """One warning for the whole print from the layers' short-piece records (none if empty).

    It says where the short pieces are (walls, skins, sparse infill) and what would help:
    for those crossing color bands narrower than ``min_segment_mm``, a palette of at most
    the suggested size when that is smaller than ``palette_size``; those only grazing a
    boundary are named as such, since no palette size lengthens them.
    """
    if not records:
        return []
    short = sum(r.short for r in records)
    total = sum(r.total for r in records)
    worst = min(records, key=lambda r: r.shortest_mm)
    grazing = sum(r.grazing for r in records)
    kinds = np.sum([r.by_kind for r in records], axis=0).tolist()
    where = ", ".join(f"{n} in {kind}" for n, kind in sorted(zip(kinds, PIECE_KINDS), reverse=True) if n)
    parts = [f"{short} of {total} color pieces on {len(records)} of {layers} layers are shorter than "
             f"min_segment_mm = {min_segment_mm:g} mm (shortest {worst.shortest_mm:.2f} mm, layer {worst.layer})"
             + (f": {where}" if where else "")]
    suggestions = [r.suggestion for r in records if r.suggestion is not None]
    if suggestions and min(suggestions) < palette_size:
        parts.append(f"{short - grazing} cross color bands narrower than that: a palette of at most "
                     f"{min(suggestions)} colors would keep them long enough")
    if grazing:
        parts.append(f"{grazing} only graze a color boundary (an infill line turning or a wall running next to it), "
                     "which no palette size lengthens")
    return ["; ".join(parts)]
