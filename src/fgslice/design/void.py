"""Void: empty space named as a material, cut out of a design's sections.

Where the normalized fraction of ``void`` is larger than every other material's (one-hot
``thresh`` grades included), nothing is printed. :func:`void_region` traces that region
in one plane: the margin ``f_void - max(f_others)`` is sampled on a regular grid and its
``> 0`` region is taken from contourpy's filled contours (linear interpolation between
samples). Boundaries of continuous fractions are placed within about
``spacing^2 |f''| / (8 |grad f|)``; a jump (``thresh``) is placed midway between the two
samples around it, within ``spacing / 2``. Ties (margin exactly 0) are printed. The
spacing is widened where needed to keep the grid within :data:`MAX_GRID_POINTS`. The
margin is evaluated with :class:`~fgslice.design.nodes.Columns` ``void_only``: parts of
the tree that cannot give void a fraction read as another material without evaluation.
"""

from __future__ import annotations

import math

import contourpy
import numpy as np
import shapely

from fgslice.design.nodes import as_multipolygon

MAX_GRID_POINTS = 4_000_000
"""Most samples of one plane (a 200 x 200 mm outline at 0.1 mm)."""


def void_region(margin_xy, bounds2d: tuple[float, float, float, float], spacing: float) -> shapely.MultiPolygon:
    """The region ``{margin_xy > 0}`` within ``bounds2d`` (mm), traced at ``spacing`` mm.

    ``margin_xy(x, y)`` takes broadcast arrays of x ``(1, nx)`` and y ``(ny, 1)`` and
    returns the ``(ny, nx)`` margin; the grid reaches one spacing past the bounds and has
    at most about :data:`MAX_GRID_POINTS` samples.
    """
    x0, y0, x1, y1 = bounds2d
    spacing = max(spacing, math.sqrt((x1 - x0) * (y1 - y0) / MAX_GRID_POINTS))
    nx = math.ceil((x1 - x0) / spacing) + 3
    ny = math.ceil((y1 - y0) / spacing) + 3
    xs = x0 - spacing + spacing * np.arange(nx)
    ys = y0 - spacing + spacing * np.arange(ny)
    margin = np.broadcast_to(np.asarray(margin_xy(xs[None, :], ys[:, None]), dtype=float), (ny, nx))
    if not (margin > 0).any():
        return shapely.MultiPolygon()
    generator = contourpy.contour_generator(xs, ys, margin, fill_type=contourpy.FillType.OuterOffset)
    points, offsets = generator.filled(0.0, 2.0)  # the margin lies in [-1, 1]
    polygons = [
        shapely.Polygon(ring[bounds[0] : bounds[1]], [ring[a:b] for a, b in zip(bounds[1:-1], bounds[2:])])
        for ring, bounds in zip(points, offsets)
    ]
    return as_multipolygon(shapely.union_all(polygons))


def without_void(design, outline: shapely.MultiPolygon, z: float, spacing: float) -> shapely.MultiPolygon:
    """``outline`` (design frame, height ``z`` mm) minus the region where void wins."""
    if outline.is_empty:
        return outline
    hole = void_region(lambda x, y: design.void_margin(x, y, z), outline.bounds, spacing)
    return outline if hole.is_empty else as_multipolygon(outline.difference(hole))
