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


def polygon_extrude(vertices, height: float, symmetric: bool = False, material: str | None = None,
                    where: nodes.Where = nodes.NOWHERE) -> nodes.Node:
    """OpenVCAD's ``PolygonExtrude``: the planar polygon through ``vertices`` ((N, 3) mm,
    N >= 3, coplanar) extruded along its normal (right-hand rule over the vertex order)
    by ``height`` mm (negative: against the normal), or ``height / 2`` each side of its
    plane when ``symmetric``. A polygon in a horizontal plane gives an exact extrusion;
    in a tilted plane, the extrusion placed by a rotation."""
    points = np.asarray(vertices, dtype=float)
    if points.ndim != 2 or points.shape[1] != 3 or len(points) < 3:
        raise DesignError("PolygonExtrude needs at least 3 vertices (x, y, z)", **where.error_kwargs())
    centre = points.mean(axis=0)
    following = np.roll(points, -1, axis=0)
    normal = np.cross(points - centre, following - centre).sum(axis=0)  # twice the vector area
    size = float(np.ptp(points, axis=0).max())
    if np.linalg.norm(normal) <= 1e-12 * max(size, 1e-9) ** 2:
        raise DesignError("PolygonExtrude: the vertices are collinear (the polygon has no area)", **where.error_kwargs())
    normal /= np.linalg.norm(normal)
    off_plane = np.abs((points - centre) @ normal).max()
    if off_plane > 1e-6 * max(size, 1.0):
        raise DesignError(f"PolygonExtrude: the vertices are not coplanar (one lies {off_plane:.3g} mm off their plane)",
                          **where.error_kwargs())
    if height == 0:
        raise DesignError("PolygonExtrude: the height must not be 0", **where.error_kwargs())
    seed = np.array([1.0, 0, 0]) if abs(normal[0]) < 0.9 else np.array([0, 1.0, 0])
    u = seed - (seed @ normal) * normal
    u /= np.linalg.norm(u)
    v = np.cross(normal, u)
    frame = np.column_stack([u, v, normal])
    local = (points - centre) @ frame  # (u, v, ~0) of each vertex
    polygon = shapely.make_valid(shapely.Polygon(local[:, :2]))
    z0, z1 = ((-abs(height) / 2, abs(height) / 2) if symmetric else sorted((0.0, float(height))))
    shape = Extrusion(polygon, z0, z1, material, where)
    shape.kind = "polygon_extrude"
    return nodes.Affine(frame, centre, shape, where)
