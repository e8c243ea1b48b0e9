"""``blend(sx, sy, sz) { ... }``: the child's geometry with its fractions box-averaged.

At each point the normalized fractions (void included) are replaced by their mean over the
axis-aligned box of ``sx x sy x sz`` mm centred there: the cross-fade OpenVCAD makes
between two touching parts. The child's geometry is unchanged; samples of the box that
fall outside the child take its materials by the usual rules (outside a union, the
nearest child's), so near the surface the average runs over the field as it extends
outward.

The mean is a rank-1 lattice rule (Korobov, :data:`LATTICE_POINTS` points, generator
``(1, a, a^2 mod N)`` with ``a =`` :data:`LATTICE_GENERATOR`), one fixed stencil of
offsets for every point, evaluated in one vectorized call per block of points (skipped
when the children's fractions are the same everywhere, e.g. one primitive). Along each
axis the offsets are the midpoints of N equal cells, so the rule is exact for fractions
linear along each axis, and a sharp boundary perpendicular to an axis (two touching
boxes) gives the exact linear ramp within 1/N (0.002); for a planar boundary of any
orientation the error was below 0.05 (mean 0.003) over 1000 random planes.

A size at least the children's extent on an axis (their bounding box, e.g. ``blend(1e6)``)
averages over that whole extent: along that axis the samples span the children's box,
the same for every point, rather than reaching far beyond the part into the field as it
extends outward. When every axis is so, the fractions are one mean, computed once.

A child holding meshes (whose materials off a plane of sections cost a 3-D distance per
sample) with a blend size on every axis is averaged on a grid instead, once
(:mod:`fgslice.design.blend_grid`, within 0.025 of the lattice rule).
"""

from __future__ import annotations

import functools
from collections.abc import Sequence

import numpy as np

from fgslice.design.nodes import CHUNK, NOWHERE, Columns, MaterialNode, Node, Where, normalized

LATTICE_POINTS = 512
"""Samples of the box per point."""

LATTICE_GENERATOR = 119
"""Korobov parameter ``a``: odd, as is ``a^2 mod 512``, so every axis sees all N midpoints."""


@functools.cache
def _unit_stencil() -> np.ndarray:
    """``(N, 3)`` offsets in the unit cube centred at the origin."""
    i = np.arange(LATTICE_POINTS)
    generator = np.array([1, LATTICE_GENERATOR, LATTICE_GENERATOR**2 % LATTICE_POINTS])
    return ((i[:, None] * generator) % LATTICE_POINTS + 0.5) / LATTICE_POINTS - 0.5


class Blend(MaterialNode):
    """``blend(sx, sy, sz)``: fractions averaged over a box of those sizes (mm, >= 0; 0
    leaves that axis alone); geometry, bounds and sections are the children's (a union)."""

    kind = "blend"

    def __init__(self, size: Sequence[float], children: Sequence[Node], where: Where = NOWHERE) -> None:
        super().__init__(children, where)
        self.size = np.asarray(size, dtype=float)
        self._offsets = _unit_stencil() * self.size

    coordinate_free = False

    @functools.cached_property
    def _whole(self) -> tuple[np.ndarray, np.ndarray]:
        """``(axes, samples)``: the axes whose size reaches the children's extent, and the
        ``(N, 3)`` stencil over the children's box (the coordinates used on those axes)."""
        lo, hi = self._body.bounds()
        if np.any(lo > hi):
            return np.zeros(3, dtype=bool), self._offsets
        axes = (self.size > 0) & (self.size >= hi - lo)
        return axes, (lo + hi) / 2 + _unit_stencil() * (hi - lo)

    @functools.cached_property
    def _gridded(self) -> bool:
        """Whether the averages come from a grid (a child holding meshes, every size > 0)."""
        from fgslice.design.membership import uses_sections

        return bool(np.all(self.size > 0)) and uses_sections(self._body)

    def raw(self, x, y, z, columns: Columns) -> np.ndarray:
        if columns.void_only and not self.can_be_void:  # only where void wins is asked: nowhere here
            return columns.one_hot(np.shape(x)[0], None)
        if self._body.coordinate_free:  # the same fractions everywhere: their mean is themselves
            return normalized(self._body.raw(x, y, z, columns))
        n = np.shape(x)[0]
        whole, spanned = self._whole
        if whole.all():  # the box spans the children: one mean over their box for every point
            mean = normalized(self._body.raw(*spanned.T, columns)).mean(axis=0)
            return np.repeat(mean[None, :], n, axis=0)
        if self._gridded:
            key = (tuple(columns.index), columns.void_only)
            grids = self.__dict__.setdefault("_grids", {})
            if key not in grids:
                from fgslice.design.blend_grid import BlendGrid  # scipy, for blends over meshes only

                grids[key] = BlendGrid(self._body, self.size, columns, whole)
            return grids[key](x, y, z)
        out = np.empty((n, columns.k))
        ox, oy, oz = self._offsets.T
        block = max(1, CHUNK // LATTICE_POINTS)
        for start in range(0, n, block):
            s = slice(start, min(start + block, n))
            px, py, pz = (
                np.broadcast_to(spanned[:, a], (s.stop - s.start, LATTICE_POINTS)).ravel() if whole[a]
                else (v[s, None] + o).ravel()
                for a, (v, o) in enumerate(((x, ox), (y, oy), (z, oz)))
            )
            samples = normalized(self._body.raw(px, py, pz, columns))
            out[s] = samples.reshape(-1, LATTICE_POINTS, columns.k).mean(axis=1)
        return out
