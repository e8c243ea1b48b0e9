"""A planar region extruded along Z: exact sections (the region itself) and distance.

The region is a shapely (Multi)Polygon in the XY plane (mm); the solid spans
``z0 <= z <= z1``. Text and OpenVCAD's polygon extrusions are built on it.
"""

from __future__ import annotations

import numpy as np
import shapely

from fgslice.design import nodes
from fgslice.errors import DesignError


class Extrusion(nodes.Primitive):
    """``region`` (valid, non-empty) extruded from ``z0`` to ``z1`` mm (``z0 < z1``)."""

    kind = "extrusion"
    valid_sections = True

    def __init__(self, region: shapely.Geometry, z0: float, z1: float, material: str | None = None,
                 where: nodes.Where = nodes.NOWHERE) -> None:
        super().__init__(material, where)
        region = nodes.as_multipolygon(region)
        if region.is_empty:
            raise DesignError("the extruded region is empty (no polygon of positive area)", **where.error_kwargs())
        if not z1 > z0:
            raise DesignError(f"an extrusion needs a positive depth, got {z1 - z0:g} mm", **where.error_kwargs())
        shapely.prepare(region)
        self.region = region
        self._boundary = region.boundary
        self.z0, self.z1 = float(z0), float(z1)

    def sdf(self, x, y, z):
        x, y, z = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (x, y, z)))
        edge = shapely.distance(self._boundary, shapely.points(x.ravel(), y.ravel())).reshape(x.shape)
        planar = np.where(shapely.contains_xy(self.region, x, y), -edge, edge)
        half = (self.z1 - self.z0) / 2
        dz = np.abs(z - (self.z0 + half)) - half
        return np.minimum(np.maximum(planar, dz), 0) + np.hypot(np.maximum(planar, 0), np.maximum(dz, 0))

    def _bounds(self):
        x0, y0, x1, y1 = self.region.bounds
        return np.array([x0, y0, self.z0]), np.array([x1, y1, self.z1])

    def _section(self, z, spacing):
        return self.region
