"""The box-averaged fractions of :mod:`fgslice.design.blend` from one grid, for children
holding meshes.

A mesh's materials at a point off a plane of sections cost a 3-D distance, and the
lattice rule asks for 512 such points per point. Here instead the child's normalized
fractions are sampled once, plane by plane (where a union's meshes are located by their
sections, :mod:`fgslice.design.membership`), at the centres of cells of ``size /``
:data:`CELLS` mm per axis covering the child's box grown by two cells and half the
blend's size (points farther out read the grid's edge); they are
box-averaged axis by axis (the cells taken as constant, a cumulative sum read
``CELLS / 2`` cells each side) and read at any point by trilinear interpolation.

Accuracy: a boundary between two materials moves by at most half a cell, so a sharp
boundary's ramp is within ``1 / CELLS`` (0.025) of the exact box average, checked against
the lattice rule at sample points (``tests/test_design_blend.py``); a field that varies
smoothly inside the child is averaged to within the same bound. Planes above and below
the child's box take the materials of the child's top and bottom planes (exact for
children whose sides are vertical, such as plates; elsewhere the nearest child in the
end plane stands for the nearest in 3-D).
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from fgslice.design.nodes import Columns, Node, normalized

CELLS = 40
"""Grid cells per blend size along each axis (even: the window spans whole cells)."""

MOST_CELLS = 6_000_000
"""Largest grid; a larger one is coarsened evenly (fewer cells per blend size, at least 8)."""


class BlendGrid:
    """Box means of ``child``'s fractions over ``size`` (mm per axis, all > 0) on a grid;
    along the ``whole`` axes (a size reaching the child's extent), the mean over the
    child's box on that axis, the same at every coordinate."""

    def __init__(self, child: Node, size: np.ndarray, columns: Columns, whole: np.ndarray) -> None:
        lo, hi = (np.asarray(b, dtype=float) for b in child.bounds())
        size = np.where(whole, np.maximum(hi - lo, 1e-3), np.asarray(size, dtype=float))
        cells = CELLS
        total = np.prod(np.ceil((hi - lo + size) / (size / cells)) + 5)
        if total > MOST_CELLS:
            cells = max(8, 2 * int(cells / 2 * (MOST_CELLS / total) ** (1 / 3)))
        self.step = size / cells
        span = hi - lo + size + 4 * self.step  # the queries' box (the child's grown by 2 cells) grown by half a size
        self.origin = lo - size / 2 - 2 * self.step + self.step / 2
        counts = np.ceil(span / self.step).astype(int) + 1
        axes = [self.origin[a] + self.step[a] * np.arange(counts[a]) for a in range(3)]
        values = self._sampled(child, axes, lo, hi, columns)
        for axis in range(3):
            if whole[axis]:
                inside = (axes[axis] >= lo[axis]) & (axes[axis] <= hi[axis])
                mean = np.compress(inside, values, axis=axis).mean(axis=axis, keepdims=True)
                values = np.repeat(mean, values.shape[axis], axis=axis)
            else:
                values = _box_mean(values, axis, cells // 2)
        self.values = values

    @staticmethod
    def _sampled(child: Node, axes, lo, hi, columns: Columns) -> np.ndarray:
        """The child's normalized fractions ``(nx, ny, nz, k)`` at the cell centres; planes
        outside its z range take those of its end planes."""
        gx, gy = (a.ravel() for a in np.meshgrid(axes[0], axes[1], indexing="ij"))
        margin = min(1e-6, (hi[2] - lo[2]) / 4)
        planes = np.clip(axes[2], lo[2] + margin, hi[2] - margin)
        out = np.empty((len(axes[0]), len(axes[1]), len(axes[2]), columns.k))
        done: dict[float, np.ndarray] = {}
        for i, z in enumerate(planes):
            if z not in done:
                done[z] = normalized(child.raw(gx, gy, np.full(gx.shape, z), columns)).reshape(out.shape[:2] + (-1,))
            out[:, :, i] = done[z]
        return out

    def __call__(self, x, y, z) -> np.ndarray:
        """Averaged fractions ``(N, k)`` at 1-D points (clamped into the grid)."""
        coords = np.stack([(np.asarray(v, dtype=float) - self.origin[a]) / self.step[a]
                           for a, v in enumerate((x, y, z))])
        return np.stack([ndimage.map_coordinates(self.values[..., c], coords, order=1, mode="nearest")
                         for c in range(self.values.shape[3])], axis=-1)


def _box_mean(values: np.ndarray, axis: int, half: int) -> np.ndarray:
    """Mean of cell-constant ``values`` over ``2 half`` cells centred on each cell centre
    along ``axis`` (the window clipped at the grid's ends)."""
    v = np.moveaxis(values, axis, 0)
    centres = np.cumsum(v, axis=0)
    centres -= v / 2  # the integral (in cells) from the grid's start to each cell centre
    out = np.empty_like(centres)
    n = len(v)
    upper = np.minimum(np.arange(n) + half, n - 1)
    lower = np.maximum(np.arange(n) - half, 0)
    np.subtract(centres[upper], centres[lower], out=out)
    out /= 2 * half
    return np.moveaxis(out, 0, axis)
