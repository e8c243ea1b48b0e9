"""Translated copies of one kind of primitive, evaluated together.

A design listing thousands of ``translate(x, y, z) { cube(s); }`` statements in one union
would otherwise hold two nodes per statement and call each one for its distance and its
section. :class:`Copies` holds them as arrays: the centres ``(n, 3)`` and the sizes of
each copy (mm), all of one primitive kind and one material. Its distance is the union's
(the smallest copy's distance), computed for all the pairs of points and nearby copies
in one vectorized call (:class:`~fgslice.design.union_index.BoxIndex`); its section at a
height is every cut copy's outline, made in one call per kind and joined by
:func:`fgslice.islands.union_polygons`. Distances, bounds and outlines are the same
numbers as those of ``Translate`` nodes over the primitives (the same arithmetic, vectorized).

Copies of consecutive statements of one union only, with one material: a union's
materials go to the first child containing a point, else the nearest, and every copy
here gives the same material, so the group decides a point as its copies would.
"""

from __future__ import annotations

import functools

import numpy as np
import shapely
from fgslice.design import nodes
from fgslice.islands import union_polygons

SHAPES = ("box", "sphere", "cylinder")
"""Primitive kinds :class:`Copies` holds: ``box`` sizes ``(sx, sy, sz)``, ``sphere``
``(r,)``, ``cylinder`` ``(r, h)`` (along Z, centred), all in mm."""


class Copies(nodes.Primitive):
    """``n`` copies of one primitive kind (:data:`SHAPES`), of one material, each centred
    at a row of ``centers`` ``(n, 3)`` with its row of ``sizes`` (mm)."""

    kind = "copies"
    valid_sections = True

    def __init__(self, shape: str, centers, sizes, material: str | None = None,
                 where: nodes.Where = nodes.NOWHERE) -> None:
        super().__init__(material, where)
        if shape not in SHAPES:
            raise ValueError(f"unknown shape {shape!r}")
        self.shape = shape
        self.centers = np.asarray(centers, dtype=float).reshape(-1, 3)
        self.sizes = np.asarray(sizes, dtype=float).reshape(len(self.centers), -1)
        if shape == "box":
            self.half = self.sizes / 2.0
            self._extent = self.half
        elif shape == "sphere":
            self._extent = np.repeat(self.sizes[:, :1], 3, axis=1)
        else:
            r, h = self.sizes[:, 0], self.sizes[:, 1]
            self._extent = np.column_stack([r, r, h / 2])

    @property
    def count(self) -> int:
        """Number of copies."""
        return len(self.centers)

    @property
    def statements(self) -> int:
        """Nodes the copies stand for: a translation and a primitive each."""
        return 2 * self.count

    def item_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """``(lo, hi)`` of every copy, ``(n, 3)`` each (mm)."""
        return self.centers + -self._extent, self.centers + self._extent

    def _bounds(self):
        lo, hi = self.item_bounds()
        return lo.min(axis=0), hi.max(axis=0)

    def distance(self, item: np.ndarray, x, y, z) -> np.ndarray:
        """Distance of copy ``item[i]`` at the point ``(x[i], y[i], z[i])`` (1-D arrays)."""
        c = self.centers[item]
        lx, ly, lz = x - c[:, 0], y - c[:, 1], z - c[:, 2]
        if self.shape == "box":
            return nodes._box_sdf(lx, ly, lz, self.half[item].T)
        r = self.sizes[item, 0]
        if self.shape == "sphere":
            return np.sqrt(lx * lx + ly * ly + lz * lz) - r
        dr = np.sqrt(lx * lx + ly * ly) - r
        dz = np.abs(lz) - self.sizes[item, 1] / 2.0
        return np.minimum(np.maximum(dr, dz), 0) + np.sqrt(np.maximum(dr, 0) ** 2 + np.maximum(dz, 0) ** 2)

    @functools.cached_property
    def _index(self):
        from fgslice.design.union_index import BoxIndex

        return BoxIndex(*self.item_bounds(), self.distance)

    def sdf(self, x, y, z):
        return self._index.sdf(x, y, z)

    def _sections(self, zs, spacing):
        return [self._section(z, spacing) for z in zs]

    def _section(self, z, spacing):
        local = z - self.centers[:, 2]
        half_height = self._extent[:, 2]
        cut = np.flatnonzero((-half_height <= local) & (local <= half_height))
        cx, cy = self.centers[cut, 0], self.centers[cut, 1]
        if self.shape == "box":
            hx, hy = self.half[cut, 0], self.half[cut, 1]
            outlines = shapely.box(cx + -hx, cy + -hy, cx + hx, cy + hy)
        elif self.shape == "sphere":
            r = self.sizes[cut, 0]
            rho2 = r**2 - local[cut] * local[cut]
            keep = rho2 > 0
            outlines = _circles(cx[keep], cy[keep], np.sqrt(rho2[keep]), spacing)
        else:
            outlines = _circles(cx, cy, self.sizes[cut, 0], spacing)
        return union_polygons(outlines, valid=True)


def _circles(cx: np.ndarray, cy: np.ndarray, radius: np.ndarray, spacing: float) -> np.ndarray:
    """:func:`fgslice.design.nodes._circle` at ``(cx, cy)`` of every ``radius``, moved as a
    ``Translate`` moves it (vertices ``radius * cos + cx``), one call per vertex count."""
    segments = np.array([nodes._segments(float(r), spacing) for r in radius], dtype=np.int64)
    out = np.empty(len(radius), dtype=object)
    for count in np.unique(segments):
        rows = np.flatnonzero(segments == count)
        cos, sin = nodes._unit_circle(int(count))
        coords = np.stack([radius[rows, None] * cos + cx[rows, None], radius[rows, None] * sin + cy[rows, None]], axis=-1)
        out[rows] = shapely.polygons(coords)
    return out
