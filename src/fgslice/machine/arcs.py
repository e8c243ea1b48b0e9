"""Arc fitting: runs of short straight moves that lie on a circle become one ``G2``/``G3``.

:func:`fit_arcs` takes a layer's moves as the writer formats them (each path's first
point and the end of each of its moves, written coordinates) and replaces every run of at
least :data:`MIN_SEGMENTS` consecutive moves of one path that fits a circle by one arc
from the run's first point to its last, centre ``I J`` relative to its start, turning
clockwise (``G2``) or counter-clockwise (``G3``).

A run fits when the arc stays within ``tolerance`` mm of the moves it replaces: each
vertex lies within ``d_k`` of the circle and each move's chord leaves the circle by its
sagitta ``s_k``; the arc is kept when ``s_k + max(d_k, d_k+1) <= tolerance`` for every move
(the arc point farthest from a move is at most that far from it), the vertices go round
the centre in one direction, less than a full turn, and the radius is at most
:data:`MAX_RADIUS_MM` (flatter runs are straight lines in all but name). PrusaSlicer's
``arc_fitting`` uses its ``gcode_resolution`` the same way.

Runs are found with numpy (the turn direction at every vertex; only runs of one sign
are tried) and grown greedily from their first vertex: three moves, then the whole run
(up to :data:`MAX_SEGMENTS`), then bisecting between them. Every run grows at once: each
step of the greedy search is one vectorized check of one trial window per run still
growing (windows of unequal lengths, flattened), so a layer of tens of thousands of arcs
costs a few dozen numpy passes rather than a Python loop per arc.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

MIN_SEGMENTS = 3
"""Fewest straight moves an arc replaces (fewer do not make the file shorter)."""
MAX_SEGMENTS = 128
"""Most straight moves one arc replaces (a longer run becomes several arcs): bounds the
cost of each trial fit, while the file is already far shorter there."""
MAX_RADIUS_MM = 1000.0
"""Largest radius of a fitted arc, mm."""
ROUNDING_MM = 0.001
"""What the written centre offsets (3 decimals) may move the centre by, taken off the tolerance, mm."""


@dataclass(frozen=True)
class FittedMoves:
    """A layer's moves after arc fitting (``m`` moves, in the order of the input's).

    Attributes:
        ends: ``(m, 2)`` end of each move, mm.
        path: ``(m,)`` index of the path each move belongs to.
        length: ``(m,)`` XY length of each move (the arc's for arcs), mm.
        turn: ``(m,)`` 0 for a straight move, -1 for ``G2`` (clockwise), 1 for ``G3``.
        offset: ``(m, 2)`` centre minus start of each arc (``I J``), mm; 0 for straight moves.
    """

    ends: np.ndarray
    path: np.ndarray
    length: np.ndarray
    turn: np.ndarray
    offset: np.ndarray


def fit_arcs(starts: np.ndarray, ends: np.ndarray, path: np.ndarray, tolerance: float) -> FittedMoves:
    """Replace runs of ``ends`` (``(M, 2)`` mm, the moves of paths ``path`` ``(M,)``, paths in
    order, each path's moves consecutive, starting at ``starts[path]``) lying on circles by
    arcs deviating at most ``tolerance`` mm from them."""
    m = len(ends)
    first_move = np.flatnonzero(np.r_[True, path[1:] != path[:-1]]) if m else np.zeros(0, dtype=np.int64)
    vertices = np.empty((m + len(first_move), 2))
    # vertex of each move's start: the path's start before its first move, else the previous end
    vertex_of_end = np.arange(m) + np.searchsorted(first_move, np.arange(m), side="right")
    vertices[vertex_of_end] = ends
    vertices[vertex_of_end[first_move] - 1] = starts[path[first_move]]
    lines = FittedMoves(ends, path, np.hypot(*np.diff(vertices, axis=0)[vertex_of_end - 1].T), np.zeros(m, np.int8),
                        np.zeros((m, 2)))
    limit = tolerance - ROUNDING_MM
    if m < MIN_SEGMENTS or limit <= 0:
        return lines
    # whether moves k .. k + 2 fit (an arc may start at k), for every k at once
    k = np.arange(m - MIN_SEGMENTS + 1)
    windows = vertices[(vertex_of_end[k] - 1)[:, None] + np.arange(MIN_SEGMENTS + 1)]
    starts_fit = np.zeros(m, dtype=bool)
    starts_fit[k] = _fit_many(windows, limit)[0] & (path[k] == path[k + MIN_SEGMENTS - 1])
    runs = _candidate_runs(vertices, vertex_of_end, path)
    if not len(runs):
        return lines
    spans = _grow(vertices, vertex_of_end[runs[:, 0]] - runs[:, 0] - 1, runs[:, 0], runs[:, 1], limit, starts_fit)
    if not len(spans[0]):
        return lines
    return _replace(lines, vertices, vertex_of_end, spans)


def _candidate_runs(vertices: np.ndarray, vertex_of_end: np.ndarray, path: np.ndarray) -> np.ndarray:
    """Runs ``(first, last)`` (rows of an ``(r, 2)`` array) of move indices of one path, at
    least :data:`MIN_SEGMENTS` long, turning the same way at every vertex between them."""
    prev = vertices[vertex_of_end - 1]
    d = vertices[vertex_of_end] - prev  # each move's vector
    cross = d[:-1, 0] * d[1:, 1] - d[:-1, 1] * d[1:, 0]  # the turn between move k and k + 1
    sign = np.sign(cross) * (path[1:] == path[:-1])
    same = (sign[1:] == sign[:-1]) & (sign[1:] != 0)  # moves k, k+1, k+2 turn one way
    # runs of `same` of length L cover L + 2 moves
    edges = np.diff(np.r_[0, same.astype(np.int8), 0])
    begin, stop = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    keep = stop - begin + 2 >= MIN_SEGMENTS
    return np.column_stack([begin[keep], stop[keep] + 1]).astype(np.int64)


def _grow(vertices: np.ndarray, shift: np.ndarray, a: np.ndarray, b: np.ndarray, limit: float,
          starts_fit: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Arcs ``(first move, last move, centre, turn)`` (arrays) covering the moves
    ``a[r]..b[r]`` of each run ``r`` (one path's, whose move ``k`` starts at vertex
    ``k + shift[r]``) greedily from ``a[r]``: each as many moves as fit
    (``starts_fit[k]``: moves ``k .. k + 2`` fit), every run a step at a time together."""
    # the first move at or after each move that may start an arc (len(starts_fit) if none)
    fits = np.flatnonzero(starts_fit)
    next_fit = np.r_[fits, len(starts_fit)][np.searchsorted(fits, np.arange(len(starts_fit) + 1))]
    a, b, shift = a.copy(), b.copy(), shift.copy()
    firsts, lasts, centres, turns = [], [], [], []
    while True:
        a = next_fit[np.minimum(a, len(starts_fit))]
        live = b - a + 1 >= MIN_SEGMENTS
        a, b, shift = a[live], b[live], shift[live]
        if not len(a):
            break
        first = a + shift  # vertex where each arc starts
        low = np.full(len(a), MIN_SEGMENTS)
        _, centre, turn = _fit_windows(vertices, first, low, limit)
        high = np.minimum(b - a + 1, MAX_SEGMENTS)
        trial = np.flatnonzero(high > low)
        ok, c, t = _fit_windows(vertices, first[trial], high[trial], limit)
        whole = trial[ok]  # the whole run (up to the cap): the usual case on a smooth curve
        low[whole], centre[whole], turn[whole] = high[whole], c[ok], t[ok]
        while True:  # low fits, high does not
            trial = np.flatnonzero(high - low > 1)
            if not len(trial):
                break
            mid = (low[trial] + high[trial]) // 2
            ok, c, t = _fit_windows(vertices, first[trial], mid, limit)
            high[trial[~ok]] = mid[~ok]
            good = trial[ok]
            low[good], centre[good], turn[good] = mid[ok], c[ok], t[ok]
        firsts.append(a)
        lasts.append(a + low - 1)
        centres.append(centre)
        turns.append(turn)
        a = a + low
    if not firsts:
        return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 2)), np.zeros(0, np.int8)
    return np.concatenate(firsts), np.concatenate(lasts), np.concatenate(centres), np.concatenate(turns)


WINDOW_POINTS = 1 << 18
"""Points checked at once by :func:`_fit_windows` (bounds its temporary arrays)."""


def _fit_windows(vertices: np.ndarray, first: np.ndarray, size: np.ndarray,
                 limit: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`_fit_many` of the windows ``vertices[first[w] : first[w] + size[w] + 1]`` of
    unequal lengths: whether each fits, its centre ``(w, 2)`` and turn ``(w,)``."""
    ok = np.zeros(len(first), dtype=bool)
    centre = np.zeros((len(first), 2))
    turn = np.zeros(len(first), dtype=np.int64)
    bounds = np.searchsorted(np.cumsum(size + 1), np.arange(1, 1 + int((size + 1).sum()) // WINDOW_POINTS) * WINDOW_POINTS)
    for rows in np.split(np.arange(len(first)), np.unique(bounds)):
        if len(rows):
            ok[rows], centre[rows], turn[rows] = _fit_ragged(vertices, first[rows], size[rows], limit)
    return ok, centre, turn


def _fit_ragged(vertices: np.ndarray, first: np.ndarray, size: np.ndarray,
                limit: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`_fit_windows` of one batch: the windows' points flattened, the checks of
    :func:`_fit_many` reduced per window."""
    count = size + 1
    start = np.cumsum(count) - count  # each window's first row in the flat arrays
    window = np.repeat(np.arange(len(first)), count)
    points = vertices[np.arange(int(count.sum())) - np.repeat(start, count) + np.repeat(first, count)]
    p0, p1, p2 = vertices[first], vertices[first + count // 2], vertices[first + size]
    u, v = p1 - p0, p2 - p0
    det = 2.0 * (u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0])
    safe = np.where(np.abs(det) < 1e-12, 1.0, det)
    uu, vv = (u * u).sum(axis=1), (v * v).sum(axis=1)
    centre = p0 + np.column_stack([(v[:, 1] * uu - u[:, 1] * vv) / safe, (u[:, 0] * vv - v[:, 0] * uu) / safe])
    rel = points - centre[window]
    radius = np.hypot(*(p0 - centre).T)
    off = np.abs(np.hypot(rel[:, 0], rel[:, 1]) - radius[window])
    pair = np.ones(len(points), dtype=bool)
    pair[start + size] = False  # a window's last point starts no pair
    pair = np.flatnonzero(pair)
    pa, pb = rel[pair], rel[pair + 1]
    step = np.arctan2(pa[:, 0] * pb[:, 1] - pa[:, 1] * pb[:, 0], (pa * pb).sum(axis=1))  # signed, radians
    pair_start = start - np.arange(len(first))  # each window's first pair
    turn = np.where(step[pair_start] > 0, 1, -1)
    pair_window = window[pair]
    sagitta = radius[pair_window] * (1.0 - np.cos(step / 2))
    ok = ((np.abs(det) >= 1e-12) & (radius <= MAX_RADIUS_MM) & (np.maximum.reduceat(off, start) <= limit)
          & (np.minimum.reduceat(step * turn[pair_window], pair_start) > 0)
          & (np.abs(np.add.reduceat(step, pair_start)) < 2 * np.pi - 1e-6)
          & (np.maximum.reduceat(sagitta + np.maximum(off[pair], off[pair + 1]), pair_start) <= limit))
    return ok, centre, turn


def _fit_many(windows: np.ndarray, limit: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`_fit` of ``(w, k, 2)`` windows of ``k`` points at once: whether each fits, its
    centre ``(w, 2)`` and turn ``(w,)`` (1 counter-clockwise, -1 clockwise)."""
    p0, p1, p2 = windows[:, 0], windows[:, windows.shape[1] // 2], windows[:, -1]
    u, v = p1 - p0, p2 - p0
    det = 2.0 * (u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0])
    safe = np.where(np.abs(det) < 1e-12, 1.0, det)
    uu, vv = (u * u).sum(axis=1), (v * v).sum(axis=1)
    centre = p0 + np.column_stack([(v[:, 1] * uu - u[:, 1] * vv) / safe, (u[:, 0] * vv - v[:, 0] * uu) / safe])
    rel = windows - centre[:, None]
    radius = np.hypot(*(p0 - centre).T)
    off = np.abs(np.hypot(rel[..., 0], rel[..., 1]) - radius[:, None])
    a, b = rel[:, :-1], rel[:, 1:]
    step = np.arctan2(a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0], (a * b).sum(axis=2))  # signed, radians
    turn = np.where(step[:, 0] > 0, 1, -1)
    sagitta = radius[:, None] * (1.0 - np.cos(step / 2))
    ok = ((np.abs(det) >= 1e-12) & (radius <= MAX_RADIUS_MM) & (off.max(axis=1) <= limit)
          & (step * turn[:, None] > 0).all(axis=1) & (np.abs(step.sum(axis=1)) < 2 * np.pi - 1e-6)
          & (sagitta + np.maximum(off[:, :-1], off[:, 1:]) <= limit).all(axis=1))
    return ok, centre, turn


def _replace(lines: FittedMoves, vertices: np.ndarray, vertex_of_end: np.ndarray, spans) -> FittedMoves:
    """``lines`` with the moves of each span (``(first, last, centre, turn)`` arrays, see
    :func:`_grow`) replaced by its arc."""
    m = len(lines.ends)
    first, last, centre, turn = spans
    turn = turn.astype(np.int8)
    covered = np.zeros(m + 1, dtype=np.int64)
    np.add.at(covered, first, 1)
    np.add.at(covered, last, -1)
    keep = np.cumsum(covered[:-1]) == 0  # the moves of no arc, and the last of each (which becomes it)
    start = vertices[vertex_of_end[first] - 1]
    a0 = np.arctan2(*(start - centre).T[::-1])
    a1 = np.arctan2(*(lines.ends[last] - centre).T[::-1])
    sweep = np.mod((a1 - a0) * turn, 2 * np.pi)
    radius = np.hypot(*(start - centre).T)
    length, turns, offset = lines.length.copy(), lines.turn.copy(), lines.offset.copy()
    length[last], turns[last], offset[last] = radius * sweep, turn, centre - start
    return FittedMoves(lines.ends[keep], lines.path[keep], length[keep], turns[keep], offset[keep])
