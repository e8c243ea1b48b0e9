"""Sections of lattices and TPMS: the 2-D field of a layer on a grid, filled contours.

A layer's field is sampled on a regular grid over the node's window (one node beyond it
on every side) and its region ``field <= 0`` traced by contourpy's filled contours (linear
interpolation along grid edges), and the region is clipped to the window exactly. A TPMS's
vertices are then moved along their grid edges onto the zero level of the field itself
(its distance ``g / |grad g|`` bends more than the grid step assumes).

The grid step ``h`` keeps the chord error ``h^2 / (8 R)`` of a contour of curvature radius
``R`` within ``spacing / 20``: ``R`` is the smallest strut radius over ``sqrt(3)`` (the
tightest end of the ellipse a strut leaning 55 degrees cuts), or for a TPMS an eighth of
the smallest cell; a sheet's wall is also sampled at least twice across; ``h`` is never
above ``2 * spacing``. With a period, the step divides the cell exactly, so the distance to
the struts is computed for one cell (folded height, the struts that reach the layer) and
repeated over the window by index; graded radii are evaluated on the whole grid.
"""

from __future__ import annotations

import math

import contourpy
import numpy as np
import shapely

from fgslice.design.lattice import TPMS, Periodic, StrutLattice

_BIG = 1e9
"""Field value standing for "no strut near" (contourpy needs finite values)."""


def _step(node: Periodic, spacing: float) -> float:
    tolerance = spacing / 20
    if isinstance(node, StrutLattice):
        least = max(node.radius_range()[0], spacing)
        return min(2 * spacing, math.sqrt(8 * least / math.sqrt(3) * tolerance))
    lo, hi = node.bounds()
    radius = float(node.period.min()) / (8 * node.harmonic)
    step = min(2 * spacing, math.sqrt(8 * radius * tolerance))
    if node.mode == "sheet":
        step = min(step, max(node.thickness.range_over(lo, hi)[0], spacing) / 2)
    return step


class _Axis:
    """Grid coordinates along one axis over lo..hi (one node beyond each end); with a
    period, the step divides it and ``cell`` gives each node's index within the cell."""

    def __init__(self, lo: float, hi: float, step: float, period: float | None, origin: float) -> None:
        if period is None:
            n = max(2, math.ceil((hi - lo) / step)) + 1
            h = (hi - lo) / (n - 1)
            self.values = lo - h + h * np.arange(n + 2)
            self.cell = None
            return
        self.per_cell = max(1, math.ceil(period / step))
        h = period / self.per_cell
        first, last = math.floor((lo - origin) / h) - 1, math.ceil((hi - origin) / h) + 1
        index = np.arange(first, last + 1)
        self.values = origin + h * index
        self.cell = np.mod(index, self.per_cell)
        self.cell_values = origin + h * np.arange(self.per_cell)


def sections(node: Periodic, zs: list[float], spacing: float) -> list[shapely.Geometry]:
    """The node's outlines at heights within its bounds (see the module docstring)."""
    lo, hi = node.bounds()
    step = _step(node, spacing)
    periodic = isinstance(node, StrutLattice) and node.period is not None
    axes = [_Axis(lo[i], hi[i], step, node.period[i] if periodic else None, node.origin[i]) for i in range(2)]
    x, y = axes[0].values[None, :], axes[1].values[:, None]
    out = []
    for z in zs:
        height = np.float64(z)
        if isinstance(node, TPMS):
            field = node.body(node.distance(x, y, height), x, y, height)

            def at(px, py, height=height):
                return node.body(node.distance(px, py, height), px, py, height)
        else:
            field, at = _strut_field(node, axes, x, y, z), None
        out.append(_region(axes[0].values, axes[1].values, field, at, lo, hi))
    return out


def _strut_field(node: StrutLattice, axes: list[_Axis], x: np.ndarray, y: np.ndarray, z: float) -> np.ndarray:
    """The lattice's signed field on the grid at height ``z``."""
    reach = node.reach
    edges, joints = node.copies
    height = z if node.period is None else node.origin[2] + math.fmod(z - node.origin[2], node.period[2]) % node.period[2]
    zlo, zhi = edges[:, :, 2].min(axis=1), edges[:, :, 2].max(axis=1)
    edges = edges[(zlo - reach <= height) & (zhi + reach >= height)]
    joints = joints[np.abs(joints[:, 2] - height) <= reach]
    if node.period is None:
        edge_d, joint_d = node.distances(x, y, np.float64(height), edges, joints)
    else:
        cx, cy = axes[0].cell_values[None, :], axes[1].cell_values[:, None]
        cell_edge, cell_joint = node.distances(cx, cy, np.float64(height), edges, joints)
        rows, columns = np.ix_(axes[1].cell, axes[0].cell)
        edge_d, joint_d = cell_edge[rows, columns], cell_joint[rows, columns]
    field = node.combine(edge_d, joint_d, x, y, np.float64(z))
    return np.nan_to_num(np.asarray(field, dtype=float), nan=_BIG, posinf=_BIG, neginf=-_BIG)


def _region(xs: np.ndarray, ys: np.ndarray, field: np.ndarray, at, lo: np.ndarray, hi: np.ndarray) -> shapely.Geometry:
    """``field <= 0`` on the grid as polygons, vertices moved onto the zero level of
    ``at(x, y)`` (the field at points) unless it is None, clipped to the box lo..hi in XY."""
    field = np.broadcast_to(field, (ys.size, xs.size))
    least = float(field.min())
    if least > 0:
        return shapely.MultiPolygon()
    generator = contourpy.contour_generator(xs, ys, field, fill_type=contourpy.FillType.ChunkCombinedOffsetOffset)
    points, offsets, outers = generator.filled(least - 1.0, 0.0)
    if points[0] is None:
        return shapely.MultiPolygon()
    coords = points[0] if at is None else _onto_level(points[0], field, at, xs, ys)
    polygons = shapely.from_ragged_array(shapely.GeometryType.POLYGON, coords, (offsets[0], outers[0]))
    region = shapely.MultiPolygon(list(polygons)) if len(polygons) > 1 else polygons[0]
    return shapely.clip_by_rect(region, lo[0], lo[1], hi[0], hi[1])


_FALSI_STEPS = 3


def _onto_level(points: np.ndarray, field: np.ndarray, at, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
    """The contour's vertices moved along their grid edges onto the zero level of ``at``
    (Illinois regula falsi between the edge's ends, :data:`_FALSI_STEPS` evaluations), so
    that they keep the contour's topology. Vertices on grid nodes and on the grid's border
    (where the region is closed along it, outside the clipping box) stay."""
    hx, hy = xs[1] - xs[0], ys[1] - ys[0]
    ix, iy = (points[:, 0] - xs[0]) / hx, (points[:, 1] - ys[0]) / hy
    on_row = np.abs(iy - np.rint(iy)) < 1e-6
    row = np.where(on_row, np.rint(iy), np.clip(np.floor(iy), 0, ys.size - 2)).astype(np.intp)
    column = np.where(on_row, np.clip(np.floor(ix), 0, xs.size - 2), np.rint(ix)).astype(np.intp)
    row2, column2 = row + ~on_row, column + on_row
    row2, column2 = np.minimum(row2, ys.size - 1), np.minimum(column2, xs.size - 1)
    f0, f1 = field[row, column], field[row2, column2]
    at_node = on_row & (np.abs(ix - np.rint(ix)) < 1e-6)
    border = np.where(on_row, (row == 0) | (row == ys.size - 1), (column == 0) | (column == xs.size - 1))
    move = (f0 * f1 < 0) & np.isfinite(f0) & np.isfinite(f1) & ~at_node & ~border
    if not move.any():
        return points
    p0 = np.column_stack([xs[column[move]], ys[row[move]]])
    p1 = np.column_stack([xs[column2[move]], ys[row2[move]]])
    fa, fb = f0[move], f1[move]
    a, b = np.zeros(fa.size), np.ones(fa.size)
    side = np.zeros(fa.size)
    for _ in range(_FALSI_STEPS):
        t = a + (b - a) * fa / (fa - fb)
        p = p0 + t[:, None] * (p1 - p0)
        ft = np.asarray(at(p[:, 0], p[:, 1]), dtype=float)
        left = np.sign(ft) == np.sign(fa)
        a, fa = np.where(left, t, a), np.where(left, ft, fa)
        b, fb = np.where(left, b, t), np.where(left, fb, ft)
        fb = np.where(left & (side > 0), fb / 2, fb)  # Illinois: halve the end kept twice
        fa = np.where(~left & (side < 0), fa / 2, fa)
        side = np.where(left, 1.0, -1.0)
    t = a + (b - a) * fa / (fa - fb)
    out = points.copy()
    out[move] = p0 + np.nan_to_num(t, nan=0.5)[:, None] * (p1 - p0)
    return out
