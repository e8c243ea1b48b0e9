"""OpenVCAD's ``Sum``: the children's signed distances added, cut at an iso value.

The part is where ``sdf_1 + sdf_2 + ... <= iso`` (mm): a blobby merge of the children
(two balls that overlap fill the waist between them; with ``iso > 0`` the sum reaches
beyond them). The distance is ``sum - iso``, not a true distance; sections are traced
on it. Materials and attributes follow the union's rules (the first child containing
the point, else the nearest).

Bounds: inside a child ``i`` its distance is at least ``-R_i`` (``R_i`` half the
smallest side of its box), and a point ``delta`` outside a child's box is at least
``delta`` from it, so the part lies within ``iso + sum of the other R_i`` of every
child's box; the bounds are the intersection of those boxes (empty children, whose
distance is positive everywhere, left out; children whose distance
underestimates the true distance outside them, such as non-uniform scalings, may reach
past it).
"""

from __future__ import annotations

import functools

import numpy as np

from fgslice.design import nodes


class Sum(nodes.Union):
    """The children's distances summed; inside where the sum is at most ``iso`` mm."""

    kind = "sum"

    def __init__(self, iso: float, children, where: nodes.Where = nodes.NOWHERE) -> None:
        super().__init__(children, where)
        self.iso = float(iso)

    def sdf(self, x, y, z):
        return functools.reduce(np.add, (c.sdf(x, y, z) for c in self.children)) - self.iso

    def _bounds(self):
        boxes = [(lo, hi) for lo, hi in (c.bounds() for c in self.children) if not np.any(lo > hi)]
        if not boxes:  # an empty child only adds a positive distance
            return np.full(3, np.inf), np.full(3, -np.inf)
        depth = [float(np.min(hi - lo)) / 2 for lo, hi in boxes]
        reach = [self.iso + sum(depth) - own for own in depth]
        lo = np.max([b[0] - r for b, r in zip(boxes, reach)], axis=0)
        hi = np.min([b[1] + r for b, r in zip(boxes, reach)], axis=0)
        return lo, hi

    def _sections(self, zs, spacing):
        return [nodes.sampled_section(self, z, spacing) for z in zs]
