"""Fields of a rectangular cell map and the weights that mix two bodies.

A rectangular cell map is the box ``lo``..``hi`` (mm) split into ``cells`` equal cells per
axis; its logical coordinates run from 0 to ``cells`` along each axis. The fields here are
callables ``f(x, y, z, d=None)`` of numpy arrays (mm), as attribute nodes and graded
lattice lengths take them, evaluated in the frame of the node that uses them:

* :meth:`CellGrid.logical`: the position in cells across the whole map (0 at ``lo``,
  ``cells`` at ``hi``; continuous, not clamped);
* :meth:`CellGrid.phase`: the position inside the current cell, 0 where a cell begins and
  1 only at the map's far face;
* :meth:`CellGrid.index`: the current cell's number, 0 .. ``cells - 1``; a point on a face
  between two cells belongs to the next one, the far face to the last cell;
* :meth:`CellGrid.to_cells`: a vector field (mm) expressed in cells (divided by the cell
  size per axis: the Jacobian of a rectangular map).

:func:`ramp` is 0 up to ``start``, 1 from ``end``, linear (or smoothstep) between;
:func:`region_weight` is 0 inside a region more than ``half_width`` from its surface, 1
outside beyond it, a smoothstep across the band.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from fgslice.design.derived_fields import FieldSource, evaluate


class CellGrid:
    """The box ``lo``..``hi`` (mm) split into ``cells`` (3 counts) equal cells."""

    def __init__(self, lo, hi, cells) -> None:
        self.lo, self.hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
        self.cells = np.asarray(cells, dtype=int)
        self.size = (self.hi - self.lo) / self.cells

    def _coordinate(self, axis: int, x, y, z) -> np.ndarray:
        return (np.asarray((x, y, z)[axis], dtype=float) - self.lo[axis]) / self.size[axis]

    def logical(self, axis: int) -> Callable:
        """The position in cells along ``axis`` (0, 1, 2)."""

        def field(x, y, z, d=None):
            return self._coordinate(axis, x, y, z)

        return field

    def index(self, axis: int) -> Callable:
        """The number of the cell along ``axis``, clamped to the map's cells."""

        def field(x, y, z, d=None):
            return np.clip(np.floor(self._coordinate(axis, x, y, z)), 0, self.cells[axis] - 1)

        return field

    def phase(self, axis: int) -> Callable:
        """The position inside the cell along ``axis``, 0 .. 1."""

        def field(x, y, z, d=None):
            u = self._coordinate(axis, x, y, z)
            return u - np.clip(np.floor(u), 0, self.cells[axis] - 1)

        return field

    def to_cells(self, vector: tuple[FieldSource, FieldSource, FieldSource]) -> tuple[Callable, Callable, Callable]:
        """The vector field ``vector`` (mm per channel) in cells per channel."""

        def channel(axis: int) -> Callable:
            def field(x, y, z, d=None):
                return evaluate(vector[axis], x, y, z, d) / self.size[axis]

            return field

        return tuple(channel(axis) for axis in range(3))


def _step(t: np.ndarray, smooth: bool) -> np.ndarray:
    t = np.clip(t, 0.0, 1.0)
    return t * t * (3 - 2 * t) if smooth else t


def ramp(start: float, end: float, coordinate: FieldSource, smooth: bool = False) -> Callable:
    """0 where ``coordinate`` is at most ``start``, 1 from ``end`` on, linear between (a
    smoothstep with ``smooth``); ``start < end``."""

    def field(x, y, z, d=None):
        return _step((evaluate(coordinate, x, y, z, d) - start) / (end - start), smooth)

    return field


def region_weight(region_sdf: Callable, half_width: float) -> Callable:
    """0 inside the region deeper than ``half_width`` (mm), 1 outside it farther than
    that, a smoothstep of the region's signed distance ``region_sdf(x, y, z)`` between."""

    def field(x, y, z, d=None):
        return _step((region_sdf(x, y, z) + half_width) / (2 * half_width), True)

    return field
