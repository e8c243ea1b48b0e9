"""Fuzzy skin: outer walls roughened point by point, graded by the design's attributes.

As PrusaSlicer's fuzzy skin (outside walls): each external perimeter is replaced by
points placed along it about ``fuzzy_skin_point_distance`` mm apart (each gap drawn
uniformly within 3/4 to 5/4 of it), each moved across the wall by a distance drawn
uniformly within ``-fuzzy_skin_thickness .. +fuzzy_skin_thickness`` mm. Here both are
the design's attributes of those names (:mod:`fgslice.design.attributes`), evaluated
along the wall, so the texture is graded along it: the gaps follow the local distance
(points are equally spaced in ``integral dL / distance``), the displacement the local
thickness. Where only one of the two attributes covers a point the other takes
PrusaSlicer's default (0.8 mm between points, 0.3 mm thick); where neither does, the wall
is left as it is. An open piece (strategy 1 cuts walls into colours) keeps its two ends,
so the pieces still join.

The random draws are seeded by the layer index and the path's position in the layer, so
a slice is reproducible and the same for any number of workers. Bed-frame mm; the fields
are evaluated at the middle height of the layer in the design frame.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from fgslice.toolpaths.paths import Path, Role

THICKNESS, DISTANCE = "fuzzy_skin_thickness", "fuzzy_skin_point_distance"
DEFAULT_THICKNESS_MM = 0.3
DEFAULT_DISTANCE_MM = 0.8
SEED = 20_260_101
"""Base of every layer's random draws."""


class FuzzySkin:
    """The fuzzy-skin attributes of a design, ready to roughen a layer's outer walls.

    Args:
        fields: the design's :class:`~fgslice.design.attributes.AttributeFields`.
        offset: the placement offset (design point = bed point - offset), mm.
    """

    def __init__(self, fields, offset) -> None:
        self.fields = fields
        self.offset = np.asarray(offset, dtype=float)

    @classmethod
    def of(cls, fields, offset) -> "FuzzySkin | None":
        """The fuzzy skin of ``fields``, or None when they hold neither attribute."""
        if fields is None or not ({THICKNESS, DISTANCE} & set(fields.names)):
            return None
        return cls(fields, offset)

    def _values(self, xy: np.ndarray, z: float) -> tuple[np.ndarray, np.ndarray]:
        """Thickness and point distance (mm) at bed points ``xy``; thickness 0 where
        neither attribute covers a point."""
        x, y, zz = xy[:, 0] - self.offset[0], xy[:, 1] - self.offset[1], np.full(len(xy), z - self.offset[2])
        names = self.fields.names
        nan = np.full(len(xy), np.nan)
        thickness = self.fields.values(THICKNESS, x, y, zz) if THICKNESS in names else nan
        distance = self.fields.values(DISTANCE, x, y, zz) if DISTANCE in names else nan
        covered = np.isfinite(thickness) | np.isfinite(distance)
        thickness = np.where(np.isfinite(thickness), thickness, np.where(covered, DEFAULT_THICKNESS_MM, 0.0))
        distance = np.where(np.isfinite(distance), distance, DEFAULT_DISTANCE_MM)
        return np.maximum(thickness, 0.0), np.maximum(distance, 0.05)

    def apply(self, paths: list[Path], layer_index: int, z: float) -> list[Path]:
        """``paths`` with every external perimeter roughened (layer ``layer_index``, bed
        height ``z`` mm: the middle of the layer)."""
        out = []
        for k, path in enumerate(paths):
            if path.role is Role.EXTERNAL_PERIMETER:
                rng = np.random.default_rng([SEED, layer_index, k])
                path = self._roughen(path, z, rng)
            out.append(path)
        return out

    def _roughen(self, path: Path, z: float, rng: np.random.Generator) -> Path:
        points = path.points
        line = np.vstack([points, points[:1]]) if path.closed else points
        step = np.hypot(*np.diff(line, axis=0).T)
        total = float(step.sum())
        if total <= 0:
            return path
        length = np.concatenate([[0.0], np.cumsum(step)])
        # the fields along the path, every 0.1 mm or finer than the smallest distance
        fine = np.linspace(0.0, total, max(2, int(np.ceil(total / 0.1)) + 1))
        fine_xy = np.column_stack([np.interp(fine, length, line[:, 0]), np.interp(fine, length, line[:, 1])])
        thickness, distance = self._values(fine_xy, z)
        if not np.any(thickness > 0):
            return path
        # stations equally spaced in u = integral dL / distance, each jittered by a quarter gap
        u = np.concatenate([[0.0], np.cumsum(np.diff(fine) * 2.0 / (distance[1:] + distance[:-1]))])
        start = rng.uniform(0.0, 0.5)
        k = np.arange(start, u[-1], 1.0)
        if path.closed and len(k) < 3:
            return path
        k = np.clip(k + rng.uniform(-0.25, 0.25, len(k)), 0.0, u[-1])
        at = np.sort(np.interp(k, u, fine))
        if not len(at):
            return path
        xy = np.column_stack([np.interp(at, length, line[:, 0]), np.interp(at, length, line[:, 1])])
        segment = np.clip(np.searchsorted(length, at, side="right") - 1, 0, len(step) - 1)
        direction = np.diff(line, axis=0)[segment] / np.maximum(step[segment], 1e-12)[:, None]
        normal = np.column_stack([-direction[:, 1], direction[:, 0]])
        shift = np.interp(at, fine, thickness) * rng.uniform(-1.0, 1.0, len(at))
        moved = xy + normal * shift[:, None]
        if not path.closed:
            moved = np.vstack([line[:1], moved, line[-1:]])
        return replace(path, points=moved)
