"""OpenVCAD's intersection with ``intersect_distribution``: the children's materials mixed.

``Intersection(True, [a, b])`` keeps the region inside every child, as a plain
intersection does, but its material at each point is every child's there, summed and
normalized: the mean of the children's normalized fractions (two spheres of red and
blue intersect in a 50/50 purple lens). A plain intersection takes its first child's.
"""

from __future__ import annotations

import functools

from fgslice.design import nodes


class MixedIntersection(nodes.Intersection):
    """Intersection of the children whose fractions are the mean of theirs."""

    kind = "intersection"

    def raw(self, x, y, z, columns):
        total = sum(nodes.normalized(child.raw(x, y, z, columns)) for child in self.children)
        return total / len(self.children)

    @functools.cached_property
    def coordinate_free(self) -> bool:
        return all(child.coordinate_free for child in self.children)

    @functools.cached_property
    def can_be_void(self) -> bool:
        return any(child.can_be_void for child in self.children)
