"""Smooth booleans (OpenVCAD's ``Union(k, ...)``, ``Intersection(k, ...)``, ``Difference(k, ...)``).

With a smoothing radius ``k > 0`` (mm) the children's distances are combined by the
polynomial smooth minimum ``smin(a, b) = min(a, b) - h^2 k / 4`` with
``h = max(k - |a - b|, 0) / k``: a fillet of about ``k`` where the surfaces meet, the sharp
boolean where they are farther apart than ``k``. Intersection uses ``smax(a, b) =
-smin(-a, -b)``, difference ``smax(a, -b)``. The fillets have no closed-form section:
sections are traced on the combined distance (:func:`fgslice.design.nodes.sampled_section`);
materials follow the sharp booleans' rules.
"""

from __future__ import annotations

import functools

import numpy as np

from fgslice.design import nodes


def smooth_min(a, b, k: float):
    """Polynomial smooth minimum of ``a`` and ``b`` with radius ``k`` (mm)."""
    h = np.maximum(k - np.abs(a - b), 0.0) / k
    return np.minimum(a, b) - h * h * k / 4.0


class _Smoothed:
    """What the smooth booleans share: the radius ``k`` (mm) before the children, and
    sections traced on the combined distance."""

    def __init__(self, k: float, children, where: nodes.Where = nodes.NOWHERE) -> None:
        super().__init__(children, where)
        self.k = float(k)

    def _sections(self, zs, spacing):
        return [nodes.sampled_section(self, z, spacing) for z in zs]


class SmoothUnion(_Smoothed, nodes.Union):
    """Union whose children blend into each other within ``k`` mm."""

    kind = "smooth_union"

    def sdf(self, x, y, z):
        return functools.reduce(lambda a, b: smooth_min(a, b, self.k), (c.sdf(x, y, z) for c in self.children))

    def _bounds(self):
        lo, hi = super()._bounds()
        return lo - self.k / 4, hi + self.k / 4  # the fillet reaches at most k / 4 beyond the children


class SmoothIntersection(_Smoothed, nodes.Intersection):
    """Intersection whose edges are rounded within ``k`` mm."""

    kind = "smooth_intersection"

    def sdf(self, x, y, z):
        return functools.reduce(lambda a, b: -smooth_min(-a, -b, self.k), (c.sdf(x, y, z) for c in self.children))


class SmoothDifference(_Smoothed, nodes.Difference):
    """First child minus the others, the cut's edges rounded within ``k`` mm."""

    kind = "smooth_difference"

    def sdf(self, x, y, z):
        first = self.children[0].sdf(x, y, z)
        rest = functools.reduce(np.minimum, (c.sdf(x, y, z) for c in self.children[1:]))
        return -smooth_min(-first, rest, self.k)
