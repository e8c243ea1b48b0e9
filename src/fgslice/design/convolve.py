"""OpenVCAD 3's ``Blend`` and ``Convolve``: a child's attributes smoothed by a kernel.

At each point the targeted attributes (and the materials' fractions, when targeted) become
the weighted mean of the child's values at a fixed stencil of offsets around it,
counting only the offsets that fall inside the child (OpenVCAD's masked blur: outside
the part nothing pulls the values); a point whose stencil misses the part keeps its own
values. The geometry is the child's, unchanged.

Stencils (offsets in mm, weights):

* :func:`box_stencil`: OpenVCAD 3's ``Blend``, a box blur of half-widths ``(rx, ry, rz)``
  applied ``passes`` times, i.e. the sum of ``passes`` uniform offsets per axis; the
  box of :mod:`fgslice.design.blend`'s lattice rule with each axis mapped through the
  quantiles of that sum (the Irwin-Hall distribution), equal weights;
* :func:`kernel_stencil`: ``Convolve``'s kernel, a ``(2 rx + 1, 2 ry + 1, 2 rz + 1)``
  array of weights whose taps span ``physical_radius`` mm each side of the point. The
  weights are divided by their sum (a uniform kernel averages, a sharpening kernel keeps
  the level); a kernel whose weights sum to 0 (edge detection) gives differences, not a
  value a machine can be set to, and is refused.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence

import numpy as np

from fgslice.design import nodes
from fgslice.design.attribute_ops import AttributeOperator
from fgslice.design.blend import _unit_stencil
from fgslice.errors import DesignError


@functools.cache
def _irwin_hall_quantiles(passes: int) -> tuple[np.ndarray, np.ndarray]:
    """``(cdf, x)``: the distribution function of the sum of ``passes`` uniforms on [0, 1],
    tabulated on ``x`` in [0, passes]."""
    x = np.linspace(0.0, passes, 2048 * passes + 1)
    cdf = np.zeros_like(x)
    for k in range(passes + 1):
        cdf += (-1) ** k * math.comb(passes, k) * np.maximum(x - k, 0.0) ** passes
    return np.clip(cdf / math.factorial(passes), 0.0, 1.0), x


def box_stencil(radius: Sequence[float], passes: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Offsets ``(N, 3)`` (mm) and equal weights of a box blur of half-widths ``radius``
    (mm, >= 0) applied ``passes`` (>= 1) times."""
    cdf, x = _irwin_hall_quantiles(int(passes))
    u = _unit_stencil() + 0.5  # each axis: the N midpoints of (0, 1)
    offsets = 2.0 * (np.interp(u, cdf, x) - passes / 2.0) * np.asarray(radius, dtype=float)
    return offsets, np.full(len(offsets), 1.0 / len(offsets))


def kernel_stencil(weights: np.ndarray, physical_radius: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
    """Offsets ``(N, 3)`` (mm) and normalized weights of a kernel ``weights`` of shape
    ``(2 rx + 1, 2 ry + 1, 2 rz + 1)`` (indexed x, y, z) spanning ``physical_radius``."""
    weights = np.asarray(weights, dtype=float)
    total = float(weights.sum())
    if abs(total) <= 1e-12 * max(float(np.abs(weights).sum()), 1e-300):
        raise DesignError("Convolve: the kernel's weights sum to 0 (an edge-detecting kernel): the result is a field "
                          "of differences, not a value a printer can be set to",
                          hint="use weights with a positive sum (a blur or a sharpening kernel)")
    axes = []
    for size, reach in zip(weights.shape, physical_radius):
        r = (size - 1) // 2
        axes.append(np.arange(-r, r + 1) * (float(reach) / r if r else 0.0))
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    flat = weights.ravel() / total
    keep = flat != 0
    return grid[keep], flat[keep]


class Smoothed(AttributeOperator):
    """The child with its attributes ``names`` (fgslice channel names) and, when
    ``fractions``, its materials' fractions replaced by their masked weighted means over
    the stencil ``offsets`` (mm) with ``weights`` (summing to 1)."""

    kind = "convolve"

    def __init__(self, child: nodes.Node, offsets: np.ndarray, weights: np.ndarray, names: Sequence[str],
                 fractions: bool, where: nodes.Where = nodes.NOWHERE) -> None:
        super().__init__(child, where)
        self.offsets = np.asarray(offsets, dtype=float)
        self.weights = np.asarray(weights, dtype=float)
        self.outputs = tuple(names)
        self.fractions = bool(fractions)

    def _blocks(self, n: int):
        block = max(1, nodes.CHUNK // len(self.offsets))
        return [slice(s, min(s + block, n)) for s in range(0, n, block)]

    def _stencil(self, x, y, z, s: slice):
        """The stencil's points around the points ``s`` (flat, point-major) and which lie inside the child."""
        ox, oy, oz = self.offsets.T
        px, py, pz = ((v[s, None] + o).ravel() for v, o in ((x, ox), (y, oy), (z, oz)))
        inside = np.broadcast_to(self._body.sdf(px, py, pz), px.shape) <= 0
        return px, py, pz, inside.reshape(-1, len(self.offsets))

    def _mean(self, values: np.ndarray, inside: np.ndarray, own: np.ndarray) -> np.ndarray:
        """Masked weighted means of ``values`` ``(n, N[, k])``; ``own`` where no weight counts."""
        valid = inside if values.ndim == 2 else inside[..., None] & np.ones(values.shape, dtype=bool)
        valid = valid & np.isfinite(values)
        w = np.where(valid, self.weights[:, None] if values.ndim == 3 else self.weights, 0.0)
        total = w.sum(axis=1)
        summed = np.where(valid, values, 0.0) * w
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = summed.sum(axis=1) / total
        return np.where(total > 1e-12, mean, own)

    def raw(self, x, y, z, columns):
        own = self._body.raw(x, y, z, columns)
        if not self.fractions or self._body.coordinate_free:
            return own
        out = np.empty((np.shape(x)[0], columns.k))
        own = nodes.normalized(own)
        for s in self._blocks(np.shape(x)[0]):
            px, py, pz, inside = self._stencil(x, y, z, s)
            samples = nodes.normalized(self._body.raw(px, py, pz, columns)).reshape(inside.shape + (columns.k,))
            out[s] = self._mean(samples, inside, own[s])
        return out

    def evaluate(self, fields, name, x, y, z, ctx):
        own = fields._values(self._body, name, x, y, z, ctx)
        out = np.empty(len(x))
        n = len(self.offsets)
        for s in self._blocks(len(x)):
            px, py, pz, inside = self._stencil(x, y, z, s)
            samples = fields._values(self._body, name, px, py, pz, np.repeat(ctx[s], n)).reshape(inside.shape)
            out[s] = self._mean(samples, inside, own[s])
        return out
