"""A shape repeated in a grid without end: OpenVCAD's ``Tile`` of any node.

:class:`Tiled` evaluates its child at every point folded into one cell: the cell of size
``period`` (mm per axis) with its least corner at ``origin``, so what of the child lies
in that cell repeats in every cell and what lies outside it is cut off. Like the
periodic lattices (:mod:`fgslice.design.lattice`) it has no bounds of its own until an
intersection with bounded shapes confines it to a window. Materials and attributes
below it repeat with the shape: they are evaluated at the folded point too.

Sections are exact: the child's outline at the folded height, clipped to the cell's
rectangle, copied to every cell that meets the window.
"""

from __future__ import annotations

import math

import numpy as np
import shapely

from fgslice.design.lattice import Periodic
from fgslice.design.nodes import NOWHERE, MappedBody, Node, Where, as_multipolygon
from fgslice.errors import DesignError

MAX_CELLS = 250_000
"""Most cells one layer of a tiling may cover (each is one copy of the child's outline)."""


class Tiled(MappedBody, Periodic):
    """``child`` repeated every ``period`` (mm, per axis) from the cell corner ``origin``."""

    kind = "tile"

    def __init__(self, child: Node, period, origin, where: Where = NOWHERE) -> None:
        super().__init__(period, origin, None, None, where)
        self.children = (child,)
        self._body = child

    def local(self, x, y, z):
        """Points of this node's frame folded into the cell, in the child's frame."""
        return self.fold(x, y, z)

    def sdf(self, x, y, z):
        x, y, z = np.broadcast_arrays(x, y, z)
        return self._clip(self._body.sdf(*self.fold(x, y, z)), x, y, z)

    def _sections(self, zs, spacing):
        lo, hi = self._window()
        folded = [float(self.origin[2] + np.mod(z - self.origin[2], self.period[2])) for z in zs]
        cell = shapely.box(self.origin[0], self.origin[1], self.origin[0] + self.period[0],
                           self.origin[1] + self.period[1])
        shifts = self._shifts(lo, hi)
        out = []
        for outline in self._body.sections(folded, spacing):
            piece = as_multipolygon(shapely.intersection(outline, cell))
            if piece.is_empty:
                out.append(piece)
                continue
            count = shapely.get_num_coordinates(piece)
            copies = shapely.transform(np.full(len(shifts), piece, dtype=object),
                                       lambda q: q + np.repeat(shifts, count, axis=0))
            inner = shapely.contains_properly(cell, piece)  # then the copies are apart: no union needed
            parts = shapely.get_parts(copies)
            tiled = shapely.multipolygons(parts) if inner else shapely.union_all(copies)
            out.append(as_multipolygon(shapely.clip_by_rect(tiled, lo[0], lo[1], hi[0], hi[1])))
        return out

    def _shifts(self, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """``(n, 2)`` offsets (mm) of the cells that meet the window lo..hi in X and Y."""
        first = np.floor((lo[:2] - self.origin[:2]) / self.period[:2]).astype(int)
        last = np.ceil((hi[:2] - self.origin[:2]) / self.period[:2]).astype(int)
        counts = last - first
        if math.prod(int(c) for c in counts) > MAX_CELLS:
            raise DesignError(f"tile: {counts[0]} x {counts[1]} cells in one layer is more than fgslice repeats "
                              f"({MAX_CELLS})", hint="use larger cells or a smaller bounding shape",
                              **self.where.error_kwargs())
        ix, iy = np.meshgrid(np.arange(first[0], last[0]), np.arange(first[1], last[1]), indexing="ij")
        return np.column_stack([ix.ravel(), iy.ravel()]) * self.period[:2]


def tile(child: Node, period=None, where: Where = NOWHERE) -> Tiled:
    """``child`` tiled without end, every ``period`` (mm per axis; None: the child's
    bounding box), the cell centred on the child's bounding box."""
    lo, hi = child.bounds()
    if np.any(lo > hi):
        raise DesignError("tile: the shape to repeat is empty", **where.error_kwargs())
    period = hi - lo if period is None else np.asarray(period, dtype=float)
    return Tiled(child, period, (lo + hi) / 2 - period / 2, where)
