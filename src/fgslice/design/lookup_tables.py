"""Lookup tables from attribute values to attribute values (OpenVCAD 3's
``LookupTableConverter``), on numpy arrays.

* :func:`step`: each point takes the row of the last key at or below its value (the
  first row below every key); NaN inputs give NaN.
* :func:`linear`: piecewise-linear between sorted keys, held flat beyond the ends.
* :func:`bilinear`: two inputs on a rectilinear grid (every pair of the two axes' values
  has a row), bilinear inside, each input clamped to its axis' range.

Rows are vectors of output channels (``(keys, channels)`` arrays); results are lists of
one array per channel.
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import RegularGridInterpolator

from fgslice.errors import DesignError


def step(keys: np.ndarray, rows: np.ndarray, t: np.ndarray) -> list[np.ndarray]:
    """Rows ``(n, channels)`` keyed by ascending ``keys`` ``(n,)`` at the values ``t``."""
    index = np.clip(np.searchsorted(keys, t, side="right") - 1, 0, len(keys) - 1)
    known = np.isfinite(t)
    return [np.where(known, rows[index, j], np.nan) for j in range(rows.shape[1])]


def linear(keys: np.ndarray, rows: np.ndarray, t: np.ndarray) -> list[np.ndarray]:
    """Rows ``(n, channels)`` at ascending ``keys`` interpolated at ``t`` (flat beyond)."""
    return [np.interp(t, keys, rows[:, j]) for j in range(rows.shape[1])]


class Grid:
    """A two-input table: ``points`` ``(n, 2)`` (each a pair of input values), ``rows``
    ``(n, channels)``; the points must fill the grid of their distinct values.
    ``owner`` names the table in messages."""

    def __init__(self, points: np.ndarray, rows: np.ndarray, owner: str) -> None:
        axes = [np.unique(points[:, i]) for i in range(2)]
        if any(len(a) < 2 for a in axes):
            raise DesignError(f"{owner}: a two-input LINEAR table needs at least two values of each input, got "
                              f"{len(axes[0])} x {len(axes[1])}", hint="give entries at the corners of a grid")
        grid = np.full((len(axes[0]), len(axes[1]), rows.shape[1]), np.nan)
        i, j = (np.searchsorted(axes[k], points[:, k]) for k in range(2))
        if len(set(zip(i.tolist(), j.tolist()))) != len(points):
            raise DesignError(f"{owner}: two entries have the same input point")
        grid[i, j] = rows
        missing = np.argwhere(np.isnan(grid[..., 0]))
        if missing.size:
            a, b = missing[0]
            raise DesignError(f"{owner}: a two-input LINEAR table is a rectilinear grid; the point "
                              f"({axes[0][a]:g}, {axes[1][b]:g}) has no entry",
                              hint="give an entry for every pair of the inputs' values")
        self.axes = axes
        self._interpolator = RegularGridInterpolator(axes, grid, method="linear")

    def __call__(self, a: np.ndarray, b: np.ndarray) -> list[np.ndarray]:
        """The channels at input values ``a``, ``b`` (clamped to the grid); NaN where an input is."""
        a, b = np.broadcast_arrays(np.asarray(a, dtype=float), np.asarray(b, dtype=float))
        known = np.isfinite(a) & np.isfinite(b)
        points = np.column_stack([np.clip(np.where(known, a, self.axes[0][0]), self.axes[0][0], self.axes[0][-1]).ravel(),
                                  np.clip(np.where(known, b, self.axes[1][0]), self.axes[1][0], self.axes[1][-1]).ravel()])
        out = self._interpolator(points).reshape(*a.shape, -1)
        return [np.where(known, out[..., c], np.nan) for c in range(out.shape[-1])]
