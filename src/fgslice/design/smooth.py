"""Smooth union: the children's union with a fillet of radius about ``k`` where they meet.

The signed distance is the polynomial smooth minimum of the children's, reduced pairwise
in order (``smin(a, b) = min(a, b) - h^2 k / 4`` with ``h = max(k - |a - b|, 0) / k``, as
OpenVCAD's ``Union(k, ...)`` and ``BBoxUnion(k)``); it adds material only where two
surfaces come within ``k`` mm of each other, by at most ``k / 4`` mm. Sections are traced
on that distance (:func:`fgslice.design.nodes.sampled_section`). Materials and attributes
follow the union's rule: the first child containing a point, else the nearest one (the
fillet takes the nearest child's).
"""

from __future__ import annotations

import functools
from collections.abc import Sequence

import numpy as np

from fgslice.design import nodes
from fgslice.errors import DesignError


def smooth_min(a: np.ndarray, b: np.ndarray, k: float) -> np.ndarray:
    """Polynomial smooth minimum of two distances (mm) with blend radius ``k`` > 0 (mm)."""
    h = np.maximum(k - np.abs(a - b), 0.0) / k
    return np.minimum(a, b) - h * h * k / 4.0


class SmoothUnion(nodes.Union):
    """Union of the children blended with radius ``k`` (mm, > 0)."""

    kind = "smooth_union"

    def __init__(self, k: float, children: Sequence[nodes.Node], where: nodes.Where = nodes.NOWHERE) -> None:
        if not k > 0:
            raise DesignError(f"a smooth union's blend radius must be positive, got {k:g}", **where.error_kwargs())
        super().__init__(children, where)
        self.k = float(k)

    def sdf(self, x, y, z):
        return functools.reduce(lambda a, b: smooth_min(a, b, self.k), (c.sdf(x, y, z) for c in self.children))

    def _bounds(self):
        lo, hi = super()._bounds()
        return lo - self.k / 4.0, hi + self.k / 4.0

    def _sections(self, zs, spacing):
        return [nodes.sampled_section(self, z, spacing) for z in zs]
