"""Design fields sampled in bed coordinates.

Toolpath stages work in the bed frame (mm); the design's fields live in the design frame.
:class:`BedField` translates bed points with the layer's :class:`Placement` and evaluates
the design there, so every stage samples the same field the same way.
"""

from __future__ import annotations

import functools

import numpy as np

from fgslice.design.base import Design
from fgslice.slicing.layers import Placement


class BedField:
    """The material and distance fields of ``design`` placed on the bed by ``placement``."""

    def __init__(self, design: Design, placement: Placement) -> None:
        self.design = design
        self.placement = placement

    def _design_xyz(self, xy: np.ndarray, z: float):
        pts = np.asarray(xy, dtype=float).reshape(-1, 2)
        return self.placement.to_design(pts[:, 0], pts[:, 1], np.full(len(pts), float(z)))

    def fractions(self, xy: np.ndarray, z: float) -> np.ndarray:
        """Normalized volume fractions ``(N, k)`` at bed points ``xy`` ``(N, 2)`` (mm), height ``z`` (mm)."""
        x, y, zz = self._design_xyz(xy, z)
        return np.asarray(self.design.fractions(x, y, zz), dtype=float).reshape(len(x), len(self.design.materials))

    def fractions_grid(self, xs: np.ndarray, ys: np.ndarray, z: float) -> np.ndarray:
        """Fractions ``(len(ys), len(xs), k)`` on the grid of bed coordinates ``xs`` x ``ys`` (mm) at height ``z``.

        Row ``i``, column ``j`` is the point ``(xs[j], ys[i])``; the design is evaluated
        on broadcast coordinate arrays, without materializing the grid's coordinates.
        """
        x, y, zz = self.placement.to_design(np.asarray(xs, dtype=float)[None, :], np.asarray(ys, dtype=float)[:, None], float(z))
        values = np.asarray(self.design.fractions(x, y, zz), dtype=float)
        return np.broadcast_to(values, (len(ys), len(xs), values.shape[-1]))

    def sdf(self, xy: np.ndarray, z: float) -> np.ndarray:
        """Signed distance (mm, negative inside) ``(N,)`` at bed points ``xy`` ``(N, 2)``, height ``z``."""
        x, y, zz = self._design_xyz(xy, z)
        return np.asarray(self.design.sdf(x, y, zz), dtype=float).reshape(len(x))

    @functools.cached_property
    def attributes(self):
        """The design's process attributes
        (:class:`~fgslice.design.attributes.AttributeFields`), None when it has none."""
        from fgslice.design.attributes import attribute_fields

        return attribute_fields(self.design)

    def attribute(self, name: str, xy: np.ndarray, z: float) -> np.ndarray:
        """Attribute ``name`` ``(N,)`` at bed points ``xy`` ``(N, 2)``, height ``z`` (mm);
        NaN where no attribute of that name covers a point."""
        x, y, zz = self._design_xyz(xy, z)
        return self.attributes.values(name, x, y, zz)
