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
(up to :data:`MAX_SEGMENTS`), then bisecting between them; each trial is one vectorized
check, so an arc on a smooth curve costs two.
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
    spans = []  # (first move, last move, centre, turn) of each arc
    for a, b in _candidate_runs(vertices, vertex_of_end, path):
        spans += _grow(vertices, int(vertex_of_end[a]) - a - 1, a, b, limit, starts_fit)
    if not spans:
        return lines
    return _replace(lines, vertices, vertex_of_end, spans)


def _candidate_runs(vertices: np.ndarray, vertex_of_end: np.ndarray, path: np.ndarray) -> list[tuple[int, int]]:
    """Runs ``(first, last)`` of move indices of one path, at least :data:`MIN_SEGMENTS`
    long, turning the same way at every vertex between them."""
    prev = vertices[vertex_of_end - 1]
    d = vertices[vertex_of_end] - prev  # each move's vector
    cross = d[:-1, 0] * d[1:, 1] - d[:-1, 1] * d[1:, 0]  # the turn between move k and k + 1
    sign = np.sign(cross) * (path[1:] == path[:-1])
    same = (sign[1:] == sign[:-1]) & (sign[1:] != 0)  # moves k, k+1, k+2 turn one way
    # runs of `same` of length L cover L + 2 moves
    edges = np.diff(np.r_[0, same.astype(np.int8), 0])
    begin, stop = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    keep = stop - begin + 2 >= MIN_SEGMENTS
    return list(zip(begin[keep].tolist(), (stop[keep] + 1).tolist()))


def _grow(vertices: np.ndarray, shift: int, a: int, b: int, limit: float,
          starts_fit: np.ndarray) -> list[tuple[int, int, np.ndarray, int]]:
    """Arcs covering moves ``a..b`` (one run of one path, whose move ``k`` starts at vertex
    ``k + shift``) greedily from ``a``: each as many moves as fit (``starts_fit[k]``: moves
    ``k .. k + 2`` fit)."""
    found = []
    while b - a + 1 >= MIN_SEGMENTS:
        def fit(size: int):
            return _fit(vertices[a + shift : a + shift + size + 1], limit)

        if not starts_fit[a]:
            a += 1
            continue
        best = fit(MIN_SEGMENTS)
        low, high = MIN_SEGMENTS, min(b - a + 1, MAX_SEGMENTS)
        longest = fit(high) if high > low else best
        if longest is not None:  # the whole run (up to the cap): the usual case on a smooth curve
            low, best = high, longest
        while high - low > 1:  # low fits, high does not
            mid = (low + high) // 2
            trial = fit(mid)
            if trial is None:
                high = mid
            else:
                low, best = mid, trial
        centre, turn = best
        found.append((a, a + low - 1, centre, turn))
        a += low
    return found


def _fit(points: np.ndarray, limit: float) -> tuple[np.ndarray, int] | None:
    """The circle (centre, turn) through the first, middle and last of ``points`` (``(k, 2)``)
    if the arc along it stays within ``limit`` mm of the polyline (see the module notes)."""
    ok, centre, turn = _fit_many(points[None], limit)
    return (centre[0], int(turn[0])) if ok[0] else None


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


def _replace(lines: FittedMoves, vertices: np.ndarray, vertex_of_end: np.ndarray,
             spans: list[tuple[int, int, np.ndarray, int]]) -> FittedMoves:
    """``lines`` with the moves of each span replaced by its arc."""
    m = len(lines.ends)
    first = np.array([s[0] for s in spans], dtype=np.int64)
    last = np.array([s[1] for s in spans], dtype=np.int64)
    centre = np.array([s[2] for s in spans])
    turn = np.array([s[3] for s in spans], dtype=np.int8)
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
