"""Strategy 1's sparse infill graded by the design's ``infill_density`` attribute.

The sparse area of a layer is cut into regions by density band: the attribute (percent,
``infill_density`` setting where no attribute covers a point) is sampled on a grid of
:data:`SAMPLE_MM` over the area at the layer's middle height, each sample is given the
band ``round(value / DENSITY_BAND)``, contourpy traces the filled contours of the bands
(boundaries halfway between samples of neighbouring bands) and shapely clips them to the
area. Each region is filled at the mean of its samples' values, so a constant attribute
gives exactly its value and a gradient steps by about :data:`DENSITY_BAND` points.
Bed frame, mm.
"""

from __future__ import annotations

import contourpy
import numpy as np
import shapely

from fgslice.design.nodes import as_multipolygon

DENSITY_BAND = 5.0
"""Width of a density band, points of percent."""

SAMPLE_MM = 1.0
"""Grid step of the density samples, mm."""


def density_regions(sparse, field, z: float, default: float) -> list[tuple[shapely.Geometry, float]] | None:
    """The ``(region, density percent)`` pieces of the sparse area ``sparse`` (shapely,
    bed frame) under ``field``'s ``infill_density`` attribute at bed height ``z``, or
    None when the design has no such attribute. ``field``: a
    :class:`~fgslice.slicing.field.BedField` (or any object without ``attributes``: no
    grading); ``default``: the setting, percent."""
    attributes = getattr(field, "attributes", None)
    if attributes is None or "infill_density" not in attributes.names or sparse.is_empty:
        return None
    x0, y0, x1, y1 = sparse.bounds
    xs = np.arange(x0 - SAMPLE_MM, x1 + 2 * SAMPLE_MM, SAMPLE_MM)
    ys = np.arange(y0 - SAMPLE_MM, y1 + 2 * SAMPLE_MM, SAMPLE_MM)
    gx, gy = np.meshgrid(xs, ys)
    values = field.attribute("infill_density", np.column_stack([gx.ravel(), gy.ravel()]), z).reshape(gx.shape)
    values = np.clip(np.where(np.isfinite(values), values, default), 0.0, 100.0)
    bands = np.rint(values / DENSITY_BAND)
    inside = shapely.contains_xy(sparse, gx, gy)
    levels = np.unique(bands)
    if len(levels) == 1:
        return [(sparse, float(values[inside].mean() if inside.any() else values.mean()))]
    gen = contourpy.contour_generator(xs, ys, bands, fill_type="OuterOffset")
    out = []
    for k in levels.tolist():
        points, offsets = gen.filled(k - 0.5, k + 0.5)
        polygons = [shapely.Polygon(p[o[0]:o[1]], [p[a:b] for a, b in zip(o[1:-1], o[2:])]) for p, o in zip(points, offsets)]
        region = as_multipolygon(shapely.intersection(sparse, shapely.make_valid(shapely.union_all(polygons))))
        if region.is_empty or region.area <= 0:
            continue
        own = (bands == k) & inside
        out.append((region, float(values[own].mean() if own.any() else values[bands == k].mean())))
    return out
