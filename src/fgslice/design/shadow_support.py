"""Inkjet-style support: the vertical shadow of a model under its overhangs.

A point belongs to the support when it lies outside the model, has model material above
it in the same ``(x, y)`` column, and is no lower than the model's lowest ``z`` (the
support stands on the bed the model stands on). This is what OpenVCAD's
``SupportAnalyzer`` fills with a support resin, voxel by voxel.

The section at height ``z`` is ``cover(z) - model(z)``, where ``cover(z)``, the union of
the model's sections at every height above ``z``, is built once from the model's
sections at the midpoints of equal slabs of at most :attr:`ShadowSupport.step` mm
(top down, each level's cover the union of its section and the cover above). The
sections are as exact as the model's in ``x`` and ``y``; in ``z`` the support reaches
the overhang within one step (material above ``z`` but below the next level is
missed when it also lies outside ``model(z)``).

The distance is the in-plane signed distance to the section for points of a few planes
(the slicer asks layer by layer), else ``max(cover distance, -model distance, floor)``:
its sign is exact to the step, its size a distance in the plane, not in 3-D, measured to
points every :data:`EDGE_STEP` mm along the boundary (a k-d tree: within 0.025 mm).
"""

from __future__ import annotations

import functools

import numpy as np
import shapely
from scipy.spatial import cKDTree

from fgslice.design import nodes

MIN_STEP = 0.1
"""Finest height step (mm) of the cover's levels: a quarter of a 0.2 mm layer."""

PLANES = 16
"""Distance queries over at most this many heights are answered from the sections."""

EDGE_STEP = 0.05
"""Spacing (mm) of the boundary points in-plane distances are measured to."""


class ShadowSupport(nodes.Primitive):
    """The support under ``model`` (a node, not a child: its materials stay its own) in
    ``material``, its levels every ``step`` mm at most (raised to :data:`MIN_STEP`)."""

    kind = "shadow_support"

    def __init__(self, model: nodes.Node, step: float, material: str | None = None,
                 where: nodes.Where = nodes.NOWHERE) -> None:
        super().__init__(material, where)
        self.model = model
        self.step = max(float(step), MIN_STEP)

    @functools.cached_property
    def _levels(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(heights, covers, shadows)``: the level heights (mm, ascending), the cover at
        each (model material at or above it) and the support between it and the level above."""
        lo, hi = self.model.bounds()
        if np.any(lo > hi):
            return np.empty(0), np.empty(0, dtype=object), np.empty(0, dtype=object)
        count = max(1, int(np.ceil((hi[2] - lo[2]) / self.step)))
        heights = lo[2] + (np.arange(count) + 0.5) * (hi[2] - lo[2]) / count
        sections = np.array(self.model.sections(list(heights), nodes.DEFAULT_SECTION_SPACING), dtype=object)
        covers = np.empty(count, dtype=object)
        above = shapely.Polygon()
        for i in range(count - 1, -1, -1):
            above = shapely.simplify(shapely.union(sections[i], above), nodes.DEFAULT_SECTION_SPACING / 20)
            covers[i] = above
        shadows = np.empty(count, dtype=object)
        shadows[:-1] = shapely.difference(covers[1:], sections[:-1])
        shadows[-1] = shapely.Polygon()
        shapely.prepare(covers)
        return heights, covers, shadows

    def _bounds(self):
        heights, _, shadows = self._levels
        kept = [i for i, s in enumerate(shadows) if s.area > nodes.DEFAULT_SECTION_SPACING**2]
        if not kept:
            return np.full(3, np.inf), np.full(3, -np.inf)
        boxes = shapely.bounds(shadows[kept])
        lo_z = self.model.bounds()[0][2]
        top = heights[kept[-1] + 1]
        return (np.array([boxes[:, 0].min(), boxes[:, 1].min(), lo_z]),
                np.array([boxes[:, 2].max(), boxes[:, 3].max(), top]))

    def _sections(self, zs, spacing):
        heights, covers, _ = self._levels
        above = np.searchsorted(heights, zs, side="left")
        out = [nodes._EMPTY] * len(zs)
        inside = [i for i, k in enumerate(above) if k < len(heights)]
        models = self.model.sections([zs[i] for i in inside], spacing)
        for i, model in zip(inside, models):
            out[i] = nodes.as_multipolygon(shapely.difference(covers[above[i]], model))
        return out

    def sdf(self, x, y, z):
        x, y, z = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (x, y, z)))
        out = np.empty(x.shape)
        planes = np.unique(z)
        if planes.size <= PLANES:
            for plane in planes:
                at = z == plane
                out[at] = _planar(self.section(float(plane), nodes.DEFAULT_SECTION_SPACING), x[at], y[at],
                                  self._far(x[at], y[at], z[at]))
            return out
        heights, covers, _ = self._levels
        above = np.searchsorted(heights, z, side="left")
        for k in np.unique(above):
            at = above == k
            far = self._far(x[at], y[at], z[at])
            out[at] = far if k == len(heights) else _planar(covers[k], x[at], y[at], far)
        floor = self.model.bounds()[0][2] - z
        return np.maximum(np.maximum(out, floor), -np.broadcast_to(self.model.sdf(x, y, z), x.shape))

    def _far(self, x, y, z) -> np.ndarray:
        """A positive distance for points of a plane without support: to the node's box, at least one step."""
        lo, hi = self.bounds()
        if np.any(lo > hi):
            return np.full(x.shape, np.inf)
        centre, half = (lo + hi) / 2, (hi - lo) / 2
        box = nodes._box_sdf(x - centre[0], y - centre[1], z - centre[2], half)
        return np.maximum(box, self.step)


def _planar(region: shapely.Geometry, x: np.ndarray, y: np.ndarray, far: np.ndarray) -> np.ndarray:
    """Signed distance (mm) in the plane from ``(x, y)`` to ``region``'s boundary,
    negative inside (the sign exact, the size to the nearest of the boundary's points
    every :data:`EDGE_STEP` mm, within half a step); ``far`` where the region is empty."""
    if region.is_empty:
        return far
    edge = shapely.get_coordinates(shapely.segmentize(region.boundary, EDGE_STEP))
    distance = cKDTree(edge).query(np.column_stack([x, y]))[0]
    return np.where(shapely.contains_xy(region, x, y), -distance, distance)
