"""Outlines of 2D signed fields: an adaptive narrow band, marching squares, vertices on the zero level.

:func:`section_from_sdf` is the general section of implicit designs (``function`` shapes,
tilted rotations). It never samples a dense grid:

1. The field is evaluated on a coarse grid of ``_REFINE * cell`` (1.6 mm for the default
   0.4 mm cell). Each coarse cell gets its own slope bound ``L``: :data:`_SAFETY` times the
   largest difference quotient along the edges and diagonals of the cell and of its eight
   neighbours. A zero in the cell would lie within ``coarse / sqrt(2)`` of a corner, so a
   cell whose corners all have ``|f| > L * coarse / sqrt(2)`` holds no surface and is left
   alone; the others (and every cell with a sign change or a NaN) are refined.
2. Refined cells are sampled at ``cell``; marching squares runs on the fine cells whose
   corners change sign (saddles are split by the value at the cell's centre), giving
   directed segments with the inside (``f <= 0``) on their left. A segment leaving the
   refined cells marks the coarse cell it enters for refinement, until every contour is
   closed, so an underestimated slope costs time, not a broken outline.
3. Vertices are put on the zero level along their cell edges (regula falsi, so the rings
   keep marching squares' topology); edges whose midpoint is farther than ``tolerance``
   from the zero level (searched along the chord's perpendicular bisector, within half
   the chord) are split there, and only the new edges are checked again.
4. Rings are oriented by construction (counter-clockwise shells, clockwise holes); every
   hole goes to the smallest shell containing it. The result is clipped to ``bounds2d`` as
   an exact rectangle: a shape touching or crossing the box is closed along its sides
   (the grid's outer nodes are taken as outside, and the vertices next to them stay put:
   they lie beyond the box and are clipped away).

Accuracy and limits (mm):

* Vertices lie within ``tolerance`` of the zero level wherever the field is smooth, and so
  do chord midpoints.
* Features (walls, gaps, islands) at least ``cell * sqrt(2)`` wide are kept: such a disc
  or strip always holds a fine node. Thinner ones may be lost or merged, and so may
  features of a field far steeper between the coarse nodes than at them (the slope bound
  is an estimate, not a proof).
* Sharp corners of the field itself are cut: the corner is replaced by a chamfer whose
  legs are at most about one ``cell`` long (error at the corner <= ``cell / sqrt(2)``).
  Corners of ``bounds2d`` are exact.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import shapely

_REFINE = 4
"""Fine cells per coarse cell side."""
_SAFETY = 2.0
"""Factor on the largest local difference quotient making a cell's slope bound."""
_ROOT_STEPS = 12
"""Most regula falsi steps a vertex gets."""
_CONVERGED = 1e-6
"""Steps below this many ``cell`` end a vertex's root search."""
_MAX_SUBDIVISION_ROUNDS = 8
_OUTSIDE = 1e-9
"""Value given to outer-ring nodes where the field is not positive: outside, without a
slope of its own."""

# Marching squares. Corners: 0 (i, j), 1 (i+1, j), 2 (i+1, j+1), 3 (i, j+1); edges:
# 0 bottom (corners 0-1), 1 right (1-2), 2 top (3-2), 3 left (0-3). A case is the bit set
# of the inside corners; cases 16 and 17 are the saddles 5 and 10 with an inside centre.
_CORNER_EDGES = ((0, 3), (1, 0), (2, 1), (3, 2))
"""The two edges at each corner, ordered so that a segment from the first to the second
has that corner on its left."""


def _segment_table() -> list[list[tuple[int, int]]]:
    """Directed segments (from edge, to edge) of each case, inside on the left."""
    corner_xy = np.array([(0, 0), (1, 0), (1, 1), (0, 1)], dtype=float)
    edge_xy = np.array([(0.5, 0), (1, 0.5), (0.5, 1), (0, 0.5)])
    table: list[list[tuple[int, int]]] = []
    for case in range(18):
        bits = {16: 5, 17: 10}.get(case, case)
        inside = [(bits >> k) & 1 for k in range(4)]
        if case in (5, 10):  # saddle, outside centre: the inside corners cut off one by one
            table.append([_CORNER_EDGES[k] for k in range(4) if inside[k]])
        elif case >= 16:  # saddle, inside centre: the outside corners cut off one by one
            table.append([_CORNER_EDGES[k][::-1] for k in range(4) if not inside[k]])
        elif 0 < case < 15:
            a, b = (e for e in range(4) if inside[e] != inside[(e + 1) % 4])
            k = inside.index(1)
            direction, to_corner = edge_xy[b] - edge_xy[a], corner_xy[k] - edge_xy[a]
            left = direction[0] * to_corner[1] - direction[1] * to_corner[0] > 0
            table.append([(a, b) if left else (b, a)])
        else:
            table.append([])
    return table


_SEGMENTS = _segment_table()
_SEGMENT_COUNTS = np.array([len(s) for s in _SEGMENTS])
_SEGMENT_FIRST = np.r_[0, np.cumsum(_SEGMENT_COUNTS)[:-1]]
_SEGMENT_PAIRS = np.array([pair for s in _SEGMENTS for pair in s], dtype=np.int64)


def section_from_sdf(
    sdf_xy: Callable[[np.ndarray, np.ndarray], np.ndarray],
    bounds2d: tuple[float, float, float, float],
    cell: float,
    *,
    tolerance: float = 0.005,
) -> shapely.MultiPolygon:
    """The region ``{p : sdf_xy(p) <= 0}`` inside the rectangle ``bounds2d``, as a valid MultiPolygon.

    Args:
        sdf_xy: the 2D signed field (negative inside), called with two equally shaped
            float arrays of x and y (mm), returning an array of that shape. It need not
            be a distance, only continuous (a sign change through an infinite value is
            located by bisection); NaN counts as outside.
        bounds2d: ``(minx, miny, maxx, maxy)``: the rectangle the region is clipped to (mm).
        cell: fine cell size (mm); sets the smallest feature kept (``cell * sqrt(2)``).
        tolerance: largest distance (mm) between the outline and the zero level at
            vertices and edge midpoints.

    Returns:
        Polygons with counter-clockwise shells and clockwise holes; empty when the
        field is positive throughout the box.
    """
    grid = _Grid(sdf_xy, bounds2d, cell)
    starts, ends = grid.contours(grid.coarse_band())
    if not starts.size:
        return shapely.MultiPolygon()
    order, ring = _rings(starts, ends)
    edges = starts[order]
    fixed = grid.fixed(edges)
    p0, p1, f0, f1 = grid.edge_ends(edges)
    points = np.column_stack(_falsi(p0[:, 0], p0[:, 1], p1[:, 0], p1[:, 1], f0, f1))
    points[~fixed] = _root_on_edges(sdf_xy, p0[~fixed], p1[~fixed], f0[~fixed], f1[~fixed], cell)
    points, ring = _subdivide(sdf_xy, points, fixed, ring, tolerance, cell)
    result = _polygons(points, ring)
    return _clip(result, bounds2d)


class _Grid:
    """The node lattice ``origin + cell * (i, j)``, evaluated only where it is needed.

    Fine indices run over ``0..nx`` and ``0..ny`` (multiples of :data:`_REFINE`); nodes on
    the outer ring are taken as outside (value at least :data:`_OUTSIDE`). Every node is evaluated
    at most once, so the cells on either side of an edge see the same values: coarse nodes
    are kept in a coarse array, a refined coarse cell keeps the ``_REFINE x _REFINE``
    nodes whose lower-left coarse cell it is, and the few other nodes refined cells need
    (along the band's upper and right sides) are kept sorted by key.
    """

    def __init__(self, field, bounds2d, cell: float) -> None:
        minx, miny, maxx, maxy = (float(v) for v in bounds2d)
        self.field = field
        self.cell = float(cell)
        pad = 2
        self.nx = _multiple(int(np.ceil((maxx - minx) / cell - 1e-9)) + 2 * pad)
        self.ny = _multiple(int(np.ceil((maxy - miny) / cell - 1e-9)) + 2 * pad)
        self.x0 = (minx + maxx) / 2 - self.nx * cell / 2
        self.y0 = (miny + maxy) / 2 - self.ny * cell / 2
        ci = np.arange(0, self.nx + 1, _REFINE)
        cj = np.arange(0, self.ny + 1, _REFINE)
        jj, ii = np.meshgrid(cj, ci, indexing="ij")
        self.coarse = self._evaluate(ii, jj)
        self.slot = np.full(self.coarse.shape, -1)
        self.owned = np.empty((0, _REFINE, _REFINE))
        self.other_keys = np.empty(0, dtype=np.int64)
        self.other_values = np.empty(0)

    def _evaluate(self, i: np.ndarray, j: np.ndarray) -> np.ndarray:
        value = np.asarray(self.field(self.x0 + self.cell * i, self.y0 + self.cell * j), dtype=float)
        value = np.broadcast_to(value, np.shape(i)).copy()
        border = self._border(i, j)
        value[border] = np.fmax(value[border], _OUTSIDE)
        return value

    def _border(self, i: np.ndarray, j: np.ndarray) -> np.ndarray:
        """Whether fine nodes are on the outer ring."""
        return (i == 0) | (j == 0) | (i == self.nx) | (j == self.ny)

    def _others(self, keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Positions of ``keys`` among the other nodes, and whether each is there."""
        position = np.searchsorted(self.other_keys, keys)
        found = position < self.other_keys.size
        found[found] = self.other_keys[position[found]] == keys[found]
        return position, found

    def _key(self, i: np.ndarray, j: np.ndarray) -> np.ndarray:
        return j * (self.nx + 1) + i

    def at(self, i: np.ndarray, j: np.ndarray) -> np.ndarray:
        """Values at fine nodes ``(i, j)`` already evaluated (coarse, owned or other)."""
        ci, cj = i // _REFINE, j // _REFINE
        a, b = i % _REFINE, j % _REFINE
        slot = self.slot[cj, ci]
        coarse = (a == 0) & (b == 0)
        out = np.where(coarse, self.coarse[cj, ci], np.nan)
        owned = ~coarse & (slot >= 0)
        out[owned] = self.owned[slot[owned], b[owned], a[owned]]
        rest = ~coarse & ~owned
        if rest.any():
            position, _ = self._others(self._key(i[rest], j[rest]))
            out[rest] = self.other_values[position]
        return out

    def refine(self, cells: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Evaluate the fine nodes of the coarse cells ``cells`` (boolean, not refined
        yet); returns their coarse indices ``(ci, cj)``."""
        cj, ci = np.nonzero(cells)
        offset = np.arange(_REFINE)
        i = np.broadcast_to(ci[:, None, None] * _REFINE + offset[None, None, :], (ci.size, _REFINE, _REFINE))
        j = np.broadcast_to(cj[:, None, None] * _REFINE + offset[None, :, None], (ci.size, _REFINE, _REFINE))
        values = self._evaluate(i, j)
        values[:, 0, 0] = self.coarse[cj, ci]
        if self.other_keys.size:  # nodes evaluated before as others keep their values
            position, found = self._others(self._key(i, j))
            values[found] = self.other_values[position[found]]
        self.slot[cj, ci] = self.owned.shape[0] + np.arange(ci.size)
        self.owned = np.concatenate([self.owned, values])
        # nodes on the cells' upper and right sides whose own coarse cell is not refined
        top = np.arange(_REFINE + 1)
        edge_i = np.concatenate([np.broadcast_to(top, (ci.size, _REFINE + 1)),
                                 np.full((ci.size, _REFINE), _REFINE)], axis=1) + ci[:, None] * _REFINE
        edge_j = np.concatenate([np.full((ci.size, _REFINE + 1), _REFINE),
                                 np.broadcast_to(offset, (ci.size, _REFINE))], axis=1) + cj[:, None] * _REFINE
        edge_i, edge_j = edge_i.ravel(), edge_j.ravel()
        outside = (self.slot[edge_j // _REFINE, edge_i // _REFINE] < 0) & ((edge_i % _REFINE != 0) | (edge_j % _REFINE != 0))
        keys = np.unique(self._key(edge_i[outside], edge_j[outside]))
        _, found = self._others(keys)
        keys = keys[~found]
        if keys.size:
            value = self._evaluate(keys % (self.nx + 1), keys // (self.nx + 1))
            merged = np.concatenate([self.other_keys, keys])
            order = np.argsort(merged, kind="stable")
            self.other_keys = merged[order]
            self.other_values = np.concatenate([self.other_values, value])[order]
        return ci, cj

    def blocks(self, ci: np.ndarray, cj: np.ndarray) -> np.ndarray:
        """Values ``(n, _REFINE + 1, _REFINE + 1)`` (rows by y) at all fine nodes of the
        refined coarse cells ``(ci, cj)``, their upper and right sides included."""
        r = _REFINE
        out = np.empty((ci.size, r + 1, r + 1))
        out[:, :r, :r] = self.owned[self.slot[cj, ci]]
        out[:, r, r] = self.coarse[cj + 1, ci + 1]
        offset = np.arange(r)
        for side, (ni, nj) in enumerate(((ci + 1, cj), (ci, cj + 1))):
            neighbour = self.slot[nj, ni]
            done = neighbour >= 0
            target = (slice(None), slice(None, r), r) if side == 0 else (slice(None), r, slice(None, r))
            values = np.empty((ci.size, r))
            values[done] = self.owned[neighbour[done], :, 0] if side == 0 else self.owned[neighbour[done], 0, :]
            rest = np.flatnonzero(~done)
            if rest.size:
                fi = np.broadcast_to(ni[rest, None] * r + (0 if side == 0 else offset), (rest.size, r))
                fj = np.broadcast_to(nj[rest, None] * r + (offset if side == 0 else 0), (rest.size, r))
                values[rest] = self.at(fi.ravel(), fj.ravel()).reshape(rest.size, r)
            out[target] = values
        return out

    def coarse_band(self) -> np.ndarray:
        """Boolean array of the coarse cells (rows by y) that may hold the zero level."""
        values = self.coarse
        step = _REFINE * self.cell
        with np.errstate(invalid="ignore"):
            horizontal = np.abs(np.diff(values, axis=1)) / step
            vertical = np.abs(np.diff(values, axis=0)) / step
            diagonal = np.fmax(np.abs(values[1:, 1:] - values[:-1, :-1]), np.abs(values[1:, :-1] - values[:-1, 1:]))
            slope = np.fmax.reduce([horizontal[1:], horizontal[:-1], vertical[:, 1:], vertical[:, :-1],
                                    diagonal / (step * np.sqrt(2))])
            local = _neighbourhood_max(slope)
            corners = np.stack([values[:-1, :-1], values[:-1, 1:], values[1:, :-1], values[1:, 1:]])
            nearest = np.abs(corners).min(axis=0)
            inside = corners <= 0
            near = ~(nearest > _SAFETY * local * step / np.sqrt(2))
        return near | (inside.any(axis=0) & ~inside.all(axis=0))

    def contours(self, band: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Closed directed contour segments of the refined cells.

        Returns ``(start, end)`` sorted by ``start``: for every segment the id of the edge
        it starts on and of the one it ends on (each crossed edge starts one segment and
        ends one). Edge ids:
        ``2 * key(i, j)`` for the edge from node (i, j) to (i+1, j), plus 1 for the one
        from (i, j) to (i, j+1).
        """
        refined = np.zeros_like(band)
        new = band
        starts, ends = [], []
        start = end = np.zeros(0, dtype=np.int64)  # no cell crossed: no segment
        while new.any():
            start, end = self._segments(*self.refine(new))
            starts.append(start)
            ends.append(end)
            refined |= new
            start, end = np.concatenate(starts), np.concatenate(ends)
            new = self._cells_beside(np.setxor1d(start, end), band.shape) & ~refined
        order = np.argsort(start)
        return start[order], end[order]

    def _cells_beside(self, edges: np.ndarray, shape) -> np.ndarray:
        """Coarse cells on either side of the fine ``edges``."""
        node, vertical = edges // 2, edges % 2
        i, j = node % (self.nx + 1), node // (self.nx + 1)
        marks = np.zeros(shape, dtype=bool)
        for ci, cj in ((i, j), (np.where(vertical == 1, i - 1, i), np.where(vertical == 1, j, j - 1))):
            ok = (ci >= 0) & (cj >= 0) & (ci < self.nx) & (cj < self.ny)
            marks[cj[ok] // _REFINE, ci[ok] // _REFINE] = True
        return marks

    def _segments(self, ci: np.ndarray, cj: np.ndarray):
        """Marching-squares segments of the fine cells of the refined coarse cells
        ``(ci, cj)``: start edges and end edges."""
        r = _REFINE
        inside = self.blocks(ci, cj) <= 0
        code = (inside[:, :-1, :-1] | (inside[:, :-1, 1:] << 1) | (inside[:, 1:, 1:] << 2) | (inside[:, 1:, :-1] << 3))
        cell_of, b, a = np.nonzero((code > 0) & (code < 15))
        case = code[cell_of, b, a].astype(np.int64)
        i, j = ci[cell_of] * r + a, cj[cell_of] * r + b
        saddle = np.flatnonzero((case == 5) | (case == 10))
        if saddle.size:
            centre = self.field(self.x0 + self.cell * (i[saddle] + 0.5), self.y0 + self.cell * (j[saddle] + 0.5))
            joined = saddle[np.asarray(centre, dtype=float) <= 0]
            case[joined] = np.where(case[joined] == 5, 16, 17)
        row = self.nx + 1
        base = j * row + i
        edge_ids = np.stack([2 * base, 2 * (base + 1) + 1, 2 * (base + row), 2 * base + 1])
        n = _SEGMENT_COUNTS[case]
        owner = np.repeat(np.arange(case.size), n)
        rank = np.arange(owner.size) - np.repeat(np.cumsum(n) - n, n)
        first, last = _SEGMENT_PAIRS[_SEGMENT_FIRST[case][owner] + rank].T
        return edge_ids[first, owner], edge_ids[last, owner]

    def fixed(self, edges: np.ndarray) -> np.ndarray:
        """Whether each edge touches an outer node (its crossing is outside the box)."""
        node, vertical = edges // 2, edges % 2
        i, j = node % (self.nx + 1), node // (self.nx + 1)
        return self._border(i, j) | self._border(i + 1 - vertical, j + vertical)

    def edge_ends(self, edges: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Both nodes of each edge and their values: ``(p0, p1, f0, f1)``, points ``(E, 2)``."""
        node, vertical = edges // 2, edges % 2
        i, j = node % (self.nx + 1), node // (self.nx + 1)
        i1, j1 = i + 1 - vertical, j + vertical
        p0 = np.column_stack([self.x0 + self.cell * i, self.y0 + self.cell * j])
        p1 = np.column_stack([self.x0 + self.cell * i1, self.y0 + self.cell * j1])
        return p0, p1, self.at(i, j), self.at(i1, j1)


def _neighbourhood_max(values: np.ndarray) -> np.ndarray:
    """The largest value (NaN ignored) of each cell and its eight neighbours."""
    out = values.copy()
    for axis in (0, 1):
        grown = out.copy()
        lower = [slice(None)] * 2
        upper = [slice(None)] * 2
        lower[axis], upper[axis] = slice(None, -1), slice(1, None)
        np.fmax(grown[tuple(lower)], out[tuple(upper)], out=grown[tuple(lower)])
        np.fmax(grown[tuple(upper)], out[tuple(lower)], out=grown[tuple(upper)])
        out = grown
    return out


def _multiple(n: int) -> int:
    """``n`` rounded up to a multiple of :data:`_REFINE`."""
    return n + (-n) % _REFINE


def _rings(starts: np.ndarray, ends: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Segments (sorted by start edge) chained into rings: each segment's successor
    starts where it ends.

    Returns the segments in ring order (each stands for its start vertex) and the ring
    of each.
    """
    successor = np.searchsorted(starts, ends).tolist()
    seen = bytearray(len(successor))
    order: list[int] = []
    ring_sizes: list[int] = []
    for first in range(len(successor)):
        if seen[first]:
            continue
        size = len(order)
        s = first
        while not seen[s]:
            seen[s] = 1
            order.append(s)
            s = successor[s]
        ring_sizes.append(len(order) - size)
    return np.array(order, dtype=np.int64), np.repeat(np.arange(len(ring_sizes)), ring_sizes)


def _root_on_edges(field, p0, p1, f0, f1, cell: float) -> np.ndarray:
    """Where the field crosses zero on each segment ``p0 -> p1`` (values ``f0``, ``f1`` of
    opposite sides of zero): regula falsi with the Illinois rule, ending once a step is
    below :data:`_CONVERGED` ``cell``. The root stays on its cell edge, so the rings keep
    the topology marching squares gave them."""
    first_inside = f0 <= 0
    lo_x, lo_y = (np.where(first_inside, p0[:, k], p1[:, k]) for k in (0, 1))  # the f <= 0 end
    hi_x, hi_y = (np.where(first_inside, p1[:, k], p0[:, k]) for k in (0, 1))
    f_lo, f_hi = np.where(first_inside, f0, f1), np.where(first_inside, f1, f0)
    x, y = _falsi(lo_x, lo_y, hi_x, hi_y, f_lo, f_hi)
    out = np.column_stack([x, y])
    index = np.flatnonzero(~np.isnan(f_lo) & ~np.isnan(f_hi))
    lo_x, lo_y, hi_x, hi_y, f_lo, f_hi, x, y = (v[index] for v in (lo_x, lo_y, hi_x, hi_y, f_lo, f_hi, x, y))
    kept = np.zeros(index.size, dtype=np.int8)  # the end kept at the last step: -1 low, 1 high
    for _ in range(_ROOT_STEPS):
        if not index.size:
            break
        value = np.asarray(field(x, y), dtype=float)
        inside = ~(value > 0)
        lo_x, lo_y, f_lo = np.where(inside, x, lo_x), np.where(inside, y, lo_y), np.where(inside, value, f_lo)
        hi_x, hi_y, f_hi = np.where(inside, hi_x, x), np.where(inside, hi_y, y), np.where(inside, f_hi, value)
        f_hi = np.where(inside & (kept == 1), f_hi / 2, f_hi)  # Illinois: an end kept twice weighs half
        f_lo = np.where(~inside & (kept == -1), f_lo / 2, f_lo)
        kept = np.where(inside, 1, -1).astype(np.int8)
        new_x, new_y = _falsi(lo_x, lo_y, hi_x, hi_y, f_lo, f_hi)
        moving = (np.maximum(np.abs(new_x - x), np.abs(new_y - y)) > _CONVERGED * cell) & (value != 0)
        out[index, 0], out[index, 1] = new_x, new_y
        index = index[moving]
        lo_x, lo_y, hi_x, hi_y, f_lo, f_hi, kept = (v[moving] for v in (lo_x, lo_y, hi_x, hi_y, f_lo, f_hi, kept))
        x, y = new_x[moving], new_y[moving]
    return out


def _falsi(lo_x, lo_y, hi_x, hi_y, f_lo, f_hi):
    """The point where the line through the ends' values crosses zero (the middle when
    an end's value is infinite or NaN: bisection)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.where(np.isfinite(f_lo) & np.isfinite(f_hi), f_lo / (f_lo - f_hi), 0.5)
        t = np.clip(np.nan_to_num(t, nan=0.5), 0.0, 1.0)
    return lo_x + t * (hi_x - lo_x), lo_y + t * (hi_y - lo_y)


def _midpoints(field, pa: np.ndarray, pb: np.ndarray, cell: float) -> tuple[np.ndarray, np.ndarray]:
    """The zero of the field on the perpendicular bisector of each chord ``pa -> pb``,
    within half the chord's length of its midpoint (so that split edges stay near their
    chord and rings do not cross), and whether one was found there."""
    mid = (pa + pb) / 2
    chord = pb - pa
    reach = np.column_stack([-chord[:, 1], chord[:, 0]]) / 2
    ends = np.concatenate([mid + reach, mid - reach])
    values = np.asarray(field(np.concatenate([mid[:, 0], ends[:, 0]]), np.concatenate([mid[:, 1], ends[:, 1]])), dtype=float)
    fm, f_plus, f_minus = values.reshape(3, -1)
    inside = fm <= 0
    crosses_plus = inside != (f_plus <= 0)
    crosses_minus = inside != (f_minus <= 0)
    use_plus = crosses_plus & (~crosses_minus | (np.abs(f_plus) <= np.abs(f_minus)))
    found = (crosses_plus | crosses_minus) & np.isfinite(fm)
    out = mid.copy()
    pick = np.flatnonzero(found)
    if pick.size:
        end = np.where(use_plus[pick, None], mid[pick] + reach[pick], mid[pick] - reach[pick])
        f_end = np.where(use_plus[pick], f_plus[pick], f_minus[pick])
        out[pick] = _root_on_edges(field, mid[pick], end, fm[pick], f_end, cell)
    return out, found


def _subdivide(field, points, fixed, ring, tolerance, cell):
    """Split edges whose midpoint is farther than ``tolerance`` from the zero level at
    the projected midpoint; only the edges made by a split are checked again.

    Vertices are ordered by a key: ring positions are integers, a point inserted between
    keys ``a`` and ``b`` gets ``(a + b) / 2`` (before the next integer on a ring's
    closing edge). Edges with a fixed end are left alone.
    """
    n = len(points)
    ring_start = np.r_[0, np.flatnonzero(ring[1:] != ring[:-1]) + 1]
    following = np.arange(1, n + 1)
    following[np.r_[ring_start[1:], n] - 1] = ring_start
    keys = np.arange(n, dtype=float)
    check = np.flatnonzero(~fixed & ~fixed[following])
    a, b = check, following[check]
    all_points, all_keys, all_rings = [points], [keys], [ring]
    for _ in range(_MAX_SUBDIVISION_ROUNDS):
        if not a.size:
            break
        projected, found = _midpoints(field, _take(all_points, a), _take(all_points, b), cell)
        far = found & (np.linalg.norm(projected - (_take(all_points, a) + _take(all_points, b)) / 2, axis=1) > tolerance)
        if not far.any():
            break
        a, b = a[far], b[far]
        ka, kb = _take(all_keys, a), _take(all_keys, b)
        new_keys = np.where(kb > ka, (ka + kb) / 2, ka + (np.floor(ka) + 1 - ka) / 2)
        first_new = sum(len(k) for k in all_keys)
        new = first_new + np.arange(a.size)
        all_points.append(projected[far])
        all_keys.append(new_keys)
        all_rings.append(_take(all_rings, a))
        a, b = np.concatenate([a, new]), np.concatenate([new, b])
    keys = np.concatenate(all_keys)
    order = np.argsort(keys, kind="stable")
    return np.concatenate(all_points)[order], np.concatenate(all_rings)[order]


def _take(parts: list[np.ndarray], index: np.ndarray) -> np.ndarray:
    """``np.concatenate(parts)[index]`` without copying when there is one part."""
    return (parts[0] if len(parts) == 1 else np.concatenate(parts))[index]


def _polygons(points: np.ndarray, ring: np.ndarray) -> shapely.MultiPolygon:
    """A valid, oriented MultiPolygon from oriented rings: counter-clockwise ones are
    shells, clockwise ones holes of the smallest shell containing them."""
    ring_start = np.r_[0, np.flatnonzero(ring[1:] != ring[:-1]) + 1]
    n = len(points)
    following = np.arange(1, n + 1)
    following[np.r_[ring_start[1:], n] - 1] = ring_start
    keep = (points != points[following]).any(axis=1)
    points, ring = points[keep], ring[keep]
    if not points.size:
        return shapely.MultiPolygon()
    ring_start = np.r_[0, np.flatnonzero(ring[1:] != ring[:-1]) + 1]
    sizes = np.diff(np.r_[ring_start, len(points)])
    following = np.arange(1, len(points) + 1)
    following[np.r_[ring_start[1:], len(points)] - 1] = ring_start
    cross = points[:, 0] * points[following, 1] - points[following, 0] * points[:, 1]
    area = np.add.reduceat(cross, ring_start) / 2
    usable = (sizes >= 3) & (area != 0)
    if not usable.any():
        return shapely.MultiPolygon()
    rings = np.empty(len(sizes), dtype=object)  # rings shrunk below 3 points are never built
    rings[usable] = shapely.linearrings(points[np.repeat(usable, sizes)],
                                        indices=np.repeat(np.arange(np.count_nonzero(usable)), sizes[usable]))
    shells = np.flatnonzero(usable & (area > 0))
    holes = np.flatnonzero(usable & (area < 0))
    if not shells.size:
        return shapely.MultiPolygon()
    shell_polygons = shapely.polygons(rings[shells])
    owner = np.full(len(sizes), -1)
    owner[shells] = np.arange(shells.size)
    if holes.size:
        probe, container = shapely.STRtree(shell_polygons).query(shapely.points(points[ring_start[holes]]), predicate="within")
        best = np.full(holes.size, -1)
        order = np.argsort(-area[shells][container], kind="stable")  # larger first: the smallest wins
        best[probe[order]] = container[order]
        owner[holes] = best
    listed = np.flatnonzero(owner >= 0)
    listed = listed[np.lexsort((area[listed] < 0, owner[listed]))]
    polygons = shapely.polygons(rings[listed], indices=owner[listed]) if holes.size else shell_polygons
    result = shapely.multipolygons(polygons)
    if not shapely.is_valid(result):
        fixed = shapely.make_valid(result)
        parts = shapely.get_parts(shapely.get_parts(fixed))
        result = shapely.multipolygons(parts[shapely.get_type_id(parts) == shapely.GeometryType.POLYGON])
        if not shapely.is_valid(result):
            result = shapely.multipolygons(shapely.get_parts(shapely.union_all(shapely.get_parts(result))))
    return result


def _clip(region: shapely.MultiPolygon, bounds2d) -> shapely.MultiPolygon:
    """``region`` within the rectangle ``bounds2d`` (exact), oriented."""
    minx, miny, maxx, maxy = (float(v) for v in bounds2d)
    lo_x, lo_y, hi_x, hi_y = shapely.bounds(region)
    if lo_x < minx or lo_y < miny or hi_x > maxx or hi_y > maxy:
        clipped = shapely.intersection(region, shapely.box(minx, miny, maxx, maxy))
        parts = shapely.get_parts(shapely.get_parts(clipped))
        region = shapely.multipolygons(parts[(shapely.get_type_id(parts) == shapely.GeometryType.POLYGON) & (shapely.area(parts) > 0)])
    return shapely.orient_polygons(region)
