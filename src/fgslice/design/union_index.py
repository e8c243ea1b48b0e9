"""The children of a large union located by their bounding boxes, so that a point is
evaluated against the few children near it instead of all of them.

A union of thousands of primitives (a design listing 100 000 cubes) would otherwise
evaluate every child's distance at every point: ``children x points`` work and, for the
membership of each point, a ``children x points`` table. :class:`ChildIndex` keeps the
children's XY boxes in a shapely STRtree (their centres in a k-d tree) and, for a batch
of points:

1. evaluates the child whose box centre is nearest each point (in XY; scipy's k-d tree,
   far cheaper than the nearest box itself and, in a grid of boxes, the box holding the
   point): ``v``, an upper estimate of the union's distance there, as any child's is;
2. evaluates the children whose boxes lie within ``max(v, 0)`` of the point (in 3-D;
   those holding it where ``v <= 0``);
   the others are farther than ``v`` from it, and, since every node's distance is at
   most the true distance (:class:`~fgslice.design.nodes.Affine` scales it down by its
   smallest stretch), their distance cannot be the union's when they are exact, and the
   union's value stays a valid lower bound of the true distance when they are not.

A point inside a child lies in its box, so inside/outside and the first child containing
a point are exact. Used by :class:`~fgslice.design.nodes.Union` above
:data:`MANY_CHILDREN` children, and by :class:`~fgslice.design.copies.Copies` (copies of
one primitive, whose distances at all pairs are one vectorized call).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import shapely
from scipy.spatial import cKDTree

MANY_CHILDREN = 64
"""A union of more children than this locates them by their boxes."""


class BoxIndex:
    """Items by their bounding boxes ``lo``, ``hi`` (``(n, 3)``, design frame, mm); an item
    with ``lo > hi`` on some axis is empty and never evaluated. ``evaluate(item, x, y, z)``
    gives item ``item[i]``'s distance at the point ``(x[i], y[i], z[i])`` for 1-D arrays."""

    def __init__(self, lo: np.ndarray, hi: np.ndarray, evaluate) -> None:
        lo = np.asarray(lo, dtype=float).reshape(-1, 3)
        hi = np.asarray(hi, dtype=float).reshape(-1, 3)
        self.evaluate = evaluate
        self.kept = np.flatnonzero(~np.any(lo > hi, axis=1))
        self.lo, self.hi = lo[self.kept], hi[self.kept]
        self.tree = shapely.STRtree(shapely.box(self.lo[:, 0], self.lo[:, 1], self.hi[:, 0], self.hi[:, 1]))
        self.centres = cKDTree((self.lo[:, :2] + self.hi[:, :2]) / 2) if len(self.kept) else None

    @property
    def usable(self) -> bool:
        """Whether any item is non-empty (otherwise every child is evaluated as usual)."""
        return len(self.kept) > 0

    def pairs(self, x: np.ndarray, y: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(point, item, distance)``: every item that can decide each 1-D point, with
        its distance there (a point may appear with the same item twice)."""
        p0 = np.arange(len(x))
        t0 = self.centres.query(np.c_[x, y])[1] if len(x) else np.zeros(0, dtype=np.int64)
        v0 = self._evaluate(p0, t0, x, y, z)
        reach = np.maximum(v0, 0.0)
        points = shapely.points(x, y)
        held = np.flatnonzero(reach == 0)
        away = np.flatnonzero(reach > 0)
        ph, th = self.tree.query(points[held], predicate="intersects")
        pa, ta = self.tree.query(points[away], predicate="dwithin", distance=reach[away])
        p1, t1 = np.concatenate([held[ph], away[pa]]), np.concatenate([th, ta])
        gap = np.maximum(np.maximum(self.lo[t1] - np.c_[x[p1], y[p1], z[p1]], np.c_[x[p1], y[p1], z[p1]] - self.hi[t1]), 0)
        near = np.sqrt((gap**2).sum(axis=1)) <= reach[p1]
        nearest = np.full(len(x), -1)
        nearest[p0] = t0
        near &= t1 != nearest[p1]  # the nearest box's item is evaluated already
        p1, t1 = p1[near], t1[near]
        v1 = self._evaluate(p1, t1, x, y, z)
        return np.concatenate([p0, p1]), self.kept[np.concatenate([t0, t1])], np.concatenate([v0, v1])

    def sdf(self, x, y, z) -> np.ndarray:
        """The union's distance at the points (broadcast together), see the module docstring."""
        x, y, z = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (x, y, z)))
        shape = x.shape
        point, _, distance = self.pairs(x.ravel(), y.ravel(), z.ravel())
        out = np.full(x.size, np.inf)
        np.minimum.at(out, point, distance)
        return out.reshape(shape)

    def owners(self, x: np.ndarray, y: np.ndarray, z: np.ndarray) -> np.ndarray:
        """Index of the item deciding each 1-D point: the first containing it, else the nearest."""
        point, child, distance = self.pairs(x, y, z)
        inside = distance <= 0
        # inside first, then by item index (the first containing); outside by distance
        order = np.lexsort((child, np.where(inside, 0.0, distance), ~inside, point))
        first = order[np.r_[True, np.diff(point[order]) != 0]]
        owner = np.zeros(len(x), dtype=np.int64)
        owner[point[first]] = child[first]
        return owner

    def _evaluate(self, point: np.ndarray, tree_index: np.ndarray, x, y, z) -> np.ndarray:
        """Each pair's item's distance at its point."""
        if not len(point):
            return np.empty(0)
        return np.asarray(self.evaluate(self.kept[tree_index], x[point], y[point], z[point]), dtype=float)


class ChildIndex(BoxIndex):
    """The non-empty children of a union, by bounding box (design frame, mm)."""

    def __init__(self, children: Sequence) -> None:
        self.children = list(children)
        bounds = [c.bounds() for c in self.children]
        lo = np.array([b[0] for b in bounds], dtype=float).reshape(-1, 3)
        hi = np.array([b[1] for b in bounds], dtype=float).reshape(-1, 3)
        super().__init__(lo, hi, self._children_at)

    def _children_at(self, child: np.ndarray, x, y, z) -> np.ndarray:
        """Each pair's child's distance at its point, one call per child."""
        out = np.empty(len(child))
        order = np.argsort(child, kind="stable")
        starts = np.flatnonzero(np.r_[True, np.diff(child[order]) != 0])
        ends = np.r_[starts[1:], len(order)]
        for start, end in zip(starts, ends):
            rows = order[start:end]
            out[rows] = np.broadcast_to(self.children[child[rows[0]]].sdf(x[rows], y[rows], z[rows]), rows.shape)
        return out
