"""Outlines of 2D signed fields: marching squares refined onto the zero level.

:func:`section_from_sdf` is the general fallback for sections of implicit designs. It
samples the field on a regular grid, traces the filled contour ``{f <= 0}`` with
contourpy (marching squares, holes included), then moves every vertex onto the zero
level with Newton steps along the numerical gradient and subdivides edges whose
midpoint strays from the zero level by more than ``tolerance``.

The grid is sampled coarse to fine: the field is first evaluated every
:data:`_COARSE` ``spacing``; a coarse cell is sampled at ``spacing`` only when one of its
corners is within ``L * coarse spacing`` of zero, ``L`` being 1.5 times the largest slope
seen between coarse neighbours (a Lipschitz estimate: a zero level crossing a cell
passes within ``coarse spacing / sqrt(2)`` of a corner, and differences along the axes
underestimate a diagonal slope by at most ``sqrt(2)``). Fields far steeper between the
coarse samples than at them may lose features thinner than the coarse step. Elsewhere the cell has one sign,
which is all marching squares needs there, so the fine grid is evaluated only in a band
around the outline.

Accuracy and limits (mm):

* Vertices lie within ``tolerance`` of the zero level wherever the field is smooth;
  chords between them deviate from it by at most ``tolerance`` at their midpoints.
* Features thinner than ``spacing`` (walls, gaps, islands) may be missed or merged:
  the topology is the grid's.
* Sharp corners are cut: marching squares places vertices on the two sides near a
  corner and Newton projection keeps them there, so the corner is replaced by a chamfer
  whose legs are at most about one ``spacing`` long (error at the corner point
  <= ``spacing / sqrt(2)``).
* The outline is clipped to ``bounds2d``: shapes touching or crossing the box are
  closed along its sides.
"""

from __future__ import annotations

from collections.abc import Callable

import contourpy
import numpy as np
import shapely

_NEWTON_STEPS = 4
_CONVERGED = 1e-6
"""Newton steps below this many ``spacing`` end a vertex's projection."""
_COARSE = 4
"""Coarse grid step, in fine steps."""
_MAX_SUBDIVISION_ROUNDS = 6


def section_from_sdf(
    sdf_xy: Callable[[np.ndarray, np.ndarray], np.ndarray],
    bounds2d: tuple[float, float, float, float],
    spacing: float,
    *,
    tolerance: float = 0.01,
) -> shapely.MultiPolygon:
    """The region ``{p : sdf_xy(p) <= 0}`` inside ``bounds2d``, as a valid MultiPolygon.

    Args:
        sdf_xy: the 2D signed field (negative inside), called with two equally shaped
            float arrays of x and y (mm), returning an array of that shape.
        bounds2d: ``(minx, miny, maxx, maxy)`` of the area to trace (mm).
        spacing: grid spacing (mm); sets the cost and the smallest feature kept.
        tolerance: largest distance (mm) between the outline and the zero level at
            vertices and edge midpoints.

    Returns:
        Polygons with counter-clockwise shells and clockwise holes; empty when the
        field is positive throughout the box.
    """
    minx, miny, maxx, maxy = (float(v) for v in bounds2d)
    box = _BoxClipped(sdf_xy, (minx, miny, maxx, maxy))
    xs = _axis(minx, maxx, spacing)
    ys = _axis(miny, maxy, spacing)
    values = _sample(box, xs, ys, spacing)
    if not (values <= 0).any():
        return shapely.MultiPolygon()
    generator = contourpy.contour_generator(xs, ys, values, fill_type=contourpy.FillType.OuterOffset)
    polygon_points, polygon_offsets = generator.filled(-np.inf, 0.0)
    if not polygon_points:
        return shapely.MultiPolygon()
    points, ring, ring_polygon = _flatten(polygon_points, polygon_offsets)
    step_limit = spacing
    points = _project(box, points, step_limit, spacing)
    points, ring = _subdivide(box, points, ring, tolerance, step_limit, spacing)
    return _polygons(points, ring, ring_polygon)


def _axis(lo: float, hi: float, spacing: float) -> np.ndarray:
    """Grid coordinates from ``lo - spacing`` past ``hi + spacing``, ``1 + k * _COARSE`` of them."""
    count = int(np.floor((hi - lo) / spacing + 1e-9)) + 3
    count += (1 - count) % _COARSE
    return lo - spacing + spacing * np.arange(count)


def _sample(field, xs: np.ndarray, ys: np.ndarray, spacing: float) -> np.ndarray:
    """The field on the grid ``ys x xs``: exact near the zero level, of the right sign elsewhere."""
    cx, cy = xs[::_COARSE], ys[::_COARSE]
    coarse = field(*np.meshgrid(cx, cy))
    step = _COARSE * spacing
    with np.errstate(invalid="ignore"):
        slopes = np.concatenate([np.abs(np.diff(coarse, axis=0)).ravel(), np.abs(np.diff(coarse, axis=1)).ravel()])
    slopes = slopes[np.isfinite(slopes)]
    lipschitz = 1.5 * (float(slopes.max()) / step if slopes.size else 1.0)
    near = ~(np.abs(coarse) > lipschitz * step)  # NaN counts as near
    cells = near[:-1, :-1] | near[1:, :-1] | near[:-1, 1:] | near[1:, 1:]
    fine = np.zeros((len(ys), len(xs)), dtype=bool)
    fine[:-1, :-1] = np.repeat(np.repeat(cells, _COARSE, axis=0), _COARSE, axis=1)
    fine[1:] |= fine[:-1].copy()
    fine[:, 1:] |= fine[:, :-1].copy()
    # outside refined cells every node takes the value of its cell's lower-left corner
    values = np.repeat(np.repeat(coarse, _COARSE, axis=0), _COARSE, axis=1)[: len(ys), : len(xs)]
    rows, cols = np.nonzero(fine)
    values[rows, cols] = field(xs[cols], ys[rows])
    return values


class _BoxClipped:
    """``max(f, box)``: the field intersected with the box's own signed distance."""

    def __init__(self, sdf_xy, bounds):
        self._sdf = sdf_xy
        self._lo = np.array(bounds[:2])
        self._hi = np.array(bounds[2:])

    def __call__(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        inside_box = np.maximum(np.maximum(self._lo[0] - x, x - self._hi[0]), np.maximum(self._lo[1] - y, y - self._hi[1]))
        return np.maximum(np.asarray(self._sdf(x, y), dtype=float), inside_box)


def _flatten(polygon_points, polygon_offsets):
    """contourpy OuterOffset output to flat (P, 2) points without closing or repeated points.

    Returns the points, the ring of each point, and the polygon of each ring (rings of
    a polygon are consecutive, its shell first).
    """
    counts = np.concatenate([np.diff(off) for off in polygon_offsets])
    ring_polygon = np.repeat(np.arange(len(polygon_offsets)), [len(off) - 1 for off in polygon_offsets])
    points = np.concatenate(polygon_points)
    ring = np.repeat(np.arange(len(counts)), counts)
    closing = np.cumsum(counts) - 1
    keep = np.ones(len(points), dtype=bool)
    keep[closing] = False
    same_ring = np.r_[False, ring[1:] == ring[:-1]]
    repeated = same_ring & np.r_[False, (points[1:] == points[:-1]).all(axis=1)]
    keep &= ~repeated
    return points[keep], ring[keep], ring_polygon


def _project(field, points: np.ndarray, step_limit: float, spacing: float) -> np.ndarray:
    """Newton steps ``p -= f(p) grad f / |grad f|^2`` (forward differences), each step at most ``step_limit``.

    A point stops once its step is below :data:`_CONVERGED` ``spacing`` (Newton converges
    quadratically: the next step would be smaller still).
    """
    h = spacing * 1e-4
    p = points.copy()
    active = np.arange(len(p))
    for _ in range(_NEWTON_STEPS):
        x, y = p[active, 0], p[active, 1]
        stacked_x = np.concatenate([x, x + h, x])
        stacked_y = np.concatenate([y, y, y + h])
        f0, fx, fy = field(stacked_x, stacked_y).reshape(3, -1)
        gx, gy = (fx - f0) / h, (fy - f0) / h
        norm2 = gx * gx + gy * gy
        with np.errstate(invalid="ignore", divide="ignore"):
            ratio = np.where(norm2 > 1e-12, f0 / norm2, 0.0)
        length = np.abs(ratio) * np.sqrt(norm2)
        scale = ratio * np.minimum(1.0, step_limit / np.maximum(length, 1e-300))
        p[active, 0] -= scale * gx
        p[active, 1] -= scale * gy
        active = active[~(length <= _CONVERGED * spacing)]
        if not active.size:
            break
    return p


def _subdivide(field, points, ring, tolerance, step_limit, spacing):
    """Insert projected midpoints into edges whose midpoint is off the zero level by > ``tolerance``."""
    for _ in range(_MAX_SUBDIVISION_ROUNDS):
        ring_start = np.r_[0, np.flatnonzero(ring[1:] != ring[:-1]) + 1]
        following = np.arange(1, len(points) + 1)
        ring_end = np.r_[ring_start[1:], len(points)]
        following[ring_end - 1] = ring_start
        mid = (points + points[following]) / 2
        projected = _project(field, mid, step_limit, spacing)
        far = np.linalg.norm(projected - mid, axis=1) > tolerance
        if not far.any():
            break
        position = np.arange(len(points), dtype=float)
        order = np.argsort(np.r_[position, position[far] + 0.5], kind="stable")
        points = np.concatenate([points, projected[far]])[order]
        ring = np.concatenate([ring, ring[far]])[order]
    return points, ring


def _polygons(points, ring, ring_polygon) -> shapely.MultiPolygon:
    """A valid, oriented MultiPolygon from rings (shell first within each polygon)."""
    sizes = np.bincount(ring, minlength=len(ring_polygon))
    first_ring = np.r_[True, ring_polygon[1:] != ring_polygon[:-1]]
    usable = sizes >= 3
    usable &= usable[first_ring][ring_polygon]
    keep = usable[ring]
    ring_index = (np.cumsum(usable) - 1)[ring[keep]]
    rings = shapely.linearrings(points[keep], indices=ring_index)
    ring_polygon = ring_polygon[usable]
    if len(ring_polygon) == 0:
        return shapely.MultiPolygon()
    polygon_index = np.cumsum(np.r_[True, ring_polygon[1:] != ring_polygon[:-1]]) - 1
    polygons = shapely.polygons(rings, indices=polygon_index)
    polygons = polygons[shapely.area(polygons) > 0]
    result = shapely.multipolygons(polygons)
    if not shapely.is_valid(result):
        fixed = shapely.make_valid(result)
        parts = shapely.get_parts(shapely.get_parts(fixed))
        result = shapely.multipolygons(parts[shapely.get_type_id(parts) == shapely.GeometryType.POLYGON])
        if not shapely.is_valid(result):
            result = shapely.multipolygons(shapely.get_parts(shapely.union_all(shapely.get_parts(result))))
    return shapely.orient_polygons(result)
