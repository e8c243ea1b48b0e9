"""One layer's outline and its per-color faces, in the bed frame (mm).

The outline is the design's exact section at the layer's mid-plane, translated to the
bed and simplified to :data:`SECTION_TOLERANCE` (mesh sections carry many vertices a
few microns apart, which make the clipping below slow).
Faces are computed without a polygon arrangement:

1. the normalized fractions are sampled on a regular grid (``spacing`` mm, default one
   bead width: a band narrower than a bead cannot be filled anyway) covering the
   outline's bounds;
2. contourpy traces *filled* contours of each fraction between the palette's levels,
   so every band is a set of polygons with holes whose boundaries are the iso-lines,
   open or closed alike. Two materials: bands of ``f_0`` at ``j / N``. Three or more:
   bands of each ``f_i`` at ``j / m``; a cell's face is the intersection of the bands
   of its tuple ``t``. With ``palette = ends`` the bands are those of
   :meth:`Palette.band_values` (``f_0`` shifted by half a step for two materials, the
   pairwise differences ``f_i - f_j`` for more, a color taking two bands of each).
   Bands follow :meth:`Palette.cell_of`'s convention
   ``j/m <= f < (j+1)/m`` (the field is negated, since contourpy's bands are
   ``lower < z <= upper``), and the outermost bands are open-ended so the bands tile the
   whole grid;
3. each face is intersected with the outline (vectorized shapely; only its polygons
   crossing the outline's boundary go through the overlay); whatever part of the
   outline is left over (slivers from numerical noise, points where several iso-lines
   meet) goes to the color found at its representative point, so the faces are
   disjoint and their union is the outline.

Accuracy: contourpy places iso-lines by linear interpolation between grid samples, so
an iso-line is exact where the field is linear and off by at most about
``spacing^2 |f''| / (8 |grad f|)`` elsewhere: about 1 micrometre for the paper's sin-cos
gradient at 0.4 mm, 0.2 mm on a circle of radius r is ``spacing^2 / (8 r)``. The outline
itself is exact. Bands are traced by one contour level for all colors when neighbouring
samples differ by less than about half a band (:func:`_bands_by_parity`), else by one
contour per band; both give the same faces. ``benchmarks/bench_faces.py`` times it.
"""

from __future__ import annotations

import contourpy
import numpy as np
import shapely

from fgslice.design.base import Design
from fgslice.errors import FieldError, ResourceError
from fgslice.settings import Settings
from fgslice.slicing.field import BedField
from fgslice.slicing.layers import LayerRegions, Placement
from fgslice.slicing.palette import Palette
from fgslice.slicing.states import field_for

MAX_GRID_POINTS = 40_000_000

SECTION_TOLERANCE = 0.005
"""How far (mm) the outline's boundary may move when simplified (Douglas-Peucker)
before the faces are clipped to it (3DBenchy: 1150 vertices per layer on average, 180
after; clipping 0.68 -> 0.38 s CPU over 240 layers)."""


def _group_polygons(parts: np.ndarray, index: np.ndarray, n: int) -> np.ndarray:
    """One MultiPolygon per ``0..n-1`` of the non-empty polygons among ``parts``, grouped by ``index``."""
    keep = shapely.get_type_id(parts) == shapely.GeometryType.POLYGON
    keep &= ~shapely.is_empty(parts)
    out = np.array([shapely.MultiPolygon() for _ in range(n)], dtype=object)
    if keep.any():
        shapely.multipolygons(parts[keep], indices=index[keep], out=out)
    return out


def polygonal_each(geometries: np.ndarray) -> np.ndarray:
    """Keep the polygonal parts of each geometry, as one MultiPolygon per input (empty if none)."""
    parts, index = shapely.get_parts(geometries, return_index=True)
    return _group_polygons(parts, index, len(geometries))


def _clipped(faces: np.ndarray, outline: shapely.Geometry) -> np.ndarray:
    """Each face intersected with ``outline``, as MultiPolygons.

    Only the face polygons crossing the outline's boundary go through the overlay;
    those strictly inside it are kept as they are and those outside dropped.
    """
    parts, index = shapely.get_parts(faces, return_index=True)
    shapely.prepare(outline)
    inside = shapely.contains_properly(outline, parts)
    crossing = ~inside & shapely.intersects(outline, parts)
    parts[crossing] = shapely.intersection(parts[crossing], outline)
    keep = inside | crossing
    pieces, piece = shapely.get_parts(parts[keep], return_index=True)
    return _group_polygons(pieces, index[keep][piece], len(faces))


def polygonal(geometry: shapely.Geometry) -> shapely.MultiPolygon:
    """The polygonal part of ``geometry`` as one MultiPolygon (lines and points dropped)."""
    return polygonal_each(np.array([geometry], dtype=object))[0]


def _grid(bounds: tuple[float, float, float, float], spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """Sample coordinates covering ``bounds`` with one spacing of margin on each side."""
    x0, y0, x1, y1 = bounds
    nx = int(np.ceil((x1 - x0) / spacing)) + 3
    ny = int(np.ceil((y1 - y0) / spacing)) + 3
    if nx * ny > MAX_GRID_POINTS:
        raise ResourceError(
            f"sampling a {x1 - x0:.1f} x {y1 - y0:.1f} mm layer at {spacing:g} mm needs {nx * ny} points "
            f"(limit {MAX_GRID_POINTS})",
            hint="raise bead_width or the face sampling spacing",
        )
    xs = x0 - spacing + spacing * np.arange(nx)
    ys = y0 - spacing + spacing * np.arange(ny)
    return xs, ys


def _ragged_polygons(points: np.ndarray | None, offsets: np.ndarray, outer: np.ndarray) -> np.ndarray:
    """Polygons (outer ring + holes) from one chunk of contourpy's ChunkCombinedOffsetOffset output."""
    if points is None:
        return np.empty(0, dtype=object)
    return shapely.from_ragged_array(
        shapely.GeometryType.POLYGON, points, (offsets.astype(np.int64), outer.astype(np.int64))
    )


def _bands_by_level(xs: np.ndarray, ys: np.ndarray, scaled: np.ndarray, n_bands: int) -> np.ndarray:
    """Bands ``j <= scaled < j + 1`` (first and last open-ended) by one filled contour per band.

    Filled contours of ``-scaled`` are used so the lower level of each band is the
    inclusive one (contourpy's bands are ``lower < z <= upper``).
    """
    levels = -np.arange(n_bands + 1, dtype=float)[::-1]
    levels[0], levels[-1] = -2.0 * n_bands - 1.0, 1.0
    gen = contourpy.contour_generator(xs, ys, -scaled, fill_type="ChunkCombinedOffsetOffset", chunk_size=0)
    out = np.empty(n_bands, dtype=object)
    for i, (points, offsets, outer) in enumerate(gen.multi_filled(levels)):
        out[n_bands - 1 - i] = shapely.multipolygons(_ragged_polygons(points[0], offsets[0], outer[0]))
    # a band narrower than the grid spacing comes back with rings touching or crossing
    # themselves, which GEOS's overlays then get wrong (an intersection returning the
    # whole layer): such bands are repaired first
    invalid = ~shapely.is_valid(out)
    if invalid.any():
        out[invalid] = polygonal_each(shapely.make_valid(out[invalid]))
    return out


def _bands_by_parity(xs: np.ndarray, ys: np.ndarray, scaled: np.ndarray, n_bands: int) -> np.ndarray:
    """The same bands as :func:`_bands_by_level` from a single contour level.

    ``p = 1/2 + (-1)^(c+1) d`` (``c`` = band index, ``d`` = distance of ``scaled`` to the
    nearest integer) is above 1/2 exactly in odd bands and is linear in ``scaled``
    within half a band of every boundary, so its 1/2 iso-line traced by linear
    interpolation is every band boundary at once. Each connected piece of
    ``{p > 1/2}`` / ``{p <= 1/2}`` is one piece of one band; its index is read at the
    piece's representative point. Valid when neighbouring samples differ by less than
    half a band (checked by the caller).
    """
    band = np.clip(np.floor(scaled), 0, n_bands - 1)
    rest = scaled - band
    dist = np.maximum(np.minimum(rest, 1.0 - rest), 1e-9)
    p = 0.5 + np.where(band % 2 == 1, dist, -dist)
    gen = contourpy.contour_generator(xs, ys, p, fill_type="ChunkCombinedOffsetOffset", chunk_size=0)
    pieces, parity = [], []
    for lower, upper, odd in ((-1.0, 0.5, 0), (0.5, 2.0, 1)):
        points, offsets, outer = gen.filled(lower, upper)
        polys = _ragged_polygons(points[0], offsets[0], outer[0])
        pieces.append(polys)
        parity.append(np.full(len(polys), odd))
    pieces, parity = np.concatenate(pieces), np.concatenate(parity)
    inside = shapely.get_coordinates(shapely.point_on_surface(pieces))
    iy = np.clip(np.rint((inside[:, 1] - ys[0]) / (ys[1] - ys[0])).astype(np.int64), 0, len(ys) - 1)
    ix = np.clip(np.rint((inside[:, 0] - xs[0]) / (xs[1] - xs[0])).astype(np.int64), 0, len(xs) - 1)
    value = scaled[iy, ix]
    index = np.clip(np.floor(value), 0, n_bands - 1)
    wrong = index % 2 != parity
    nearer_up = value - index >= 0.5
    index = np.where(wrong & nearer_up & (index < n_bands - 1), index + 1, np.where(wrong, index - 1, index))
    index = np.clip(index, 0, n_bands - 1).astype(np.int64)
    order = np.argsort(index, kind="stable")
    out = np.array([shapely.MultiPolygon() for _ in range(n_bands)], dtype=object)
    shapely.multipolygons(pieces[order], indices=index[order], out=out)
    return out


def _bands(xs: np.ndarray, ys: np.ndarray, values: np.ndarray, n_bands: int) -> np.ndarray:
    """MultiPolygons ``b_j = {j/n <= v < (j+1)/n}`` (first and last open-ended), j = 0..n-1.

    ``values`` is a ``(len(ys), len(xs))`` grid. The single-level parity method is used
    when every pair of neighbouring samples differs by less than 0.45 of a band (bands
    at least about two grid spacings wide); otherwise one contour per band.
    """
    scaled = values * n_bands
    steepest = max(np.abs(np.diff(scaled, axis=0)).max(initial=0.0), np.abs(np.diff(scaled, axis=1)).max(initial=0.0))
    if steepest < 0.45:
        return _bands_by_parity(xs, ys, scaled, n_bands)
    return _bands_by_level(xs, ys, scaled, n_bands)


COARSEN_WIDTH = 1.5
"""Bands narrower than a sample spacing on most of a layer are grouped into runs at least
this many spacings wide (:func:`_palette_bands`)."""


def _palette_bands(xs: np.ndarray, ys: np.ndarray, values: np.ndarray, n_bands: int) -> np.ndarray:
    """:func:`_bands` of ``values``, or, where the palette is finer than the samples can
    hold, bands grouped in runs (the others left empty).

    The sample spacing is the bead width: a band narrower than that has no bead of its
    own, and a layer of such bands would be handed, sliver by sliver, to one color (the
    gradient lost). When the median change of the scaled value between neighbouring
    samples exceeds one band, runs of ``k = ceil(COARSEN_WIDTH x that change)``
    consecutive bands are traced as one band, given to the run's middle band: the layer
    prints about ``n_bands / k`` colors, each about ``COARSEN_WIDTH`` beads wide or more,
    each at most ``k / 2`` bands from the field (the median, not the maximum, so that a
    sharp step in an otherwise gentle field is left to the slivers' handover).
    """
    change = np.median(np.hypot(*np.gradient(values * n_bands))) if min(values.shape) > 1 else 0.0
    if not change > 1.0:
        return _bands(xs, ys, values, n_bands)
    k = int(np.ceil(COARSEN_WIDTH * change))
    runs = -(-n_bands // k)
    out = np.array([shapely.MultiPolygon() for _ in range(n_bands)], dtype=object)
    out[np.minimum(np.arange(runs) * k + k // 2, n_bands - 1)] = _bands(xs, ys, values * n_bands / (k * runs), runs)
    return out


def _sampled_fractions(field: BedField, xs: np.ndarray, ys: np.ndarray, z: float) -> np.ndarray:
    """Fractions ``(len(ys), len(xs), k)`` on the grid; FieldError where they are not finite."""
    values = field.fractions_grid(xs, ys, z)
    finite = np.isfinite(values).all(axis=-1)
    if not finite.all():
        iy, ix = np.unravel_index(int(np.argmin(finite)), finite.shape)
        raise FieldError(
            f"the material fractions are not finite at bed point ({xs[ix]:.3f}, {ys[iy]:.3f}, {z:.3f}) mm",
            hint="check the material expressions for divisions by zero or logarithms of non-positive values",
        )
    return values


def color_faces(
    outline: shapely.Geometry, field: BedField, palette: Palette, z: float, spacing: float
) -> tuple[shapely.Geometry, ...]:
    """One MultiPolygon per palette color: disjoint, together equal to ``outline`` (bed frame).

    Args:
        outline: the layer's cross-section, bed frame, mm.
        field: the design's fields in bed coordinates.
        palette: the colors.
        z: bed height of the slicing plane, mm.
        spacing: grid spacing of the field samples, mm.
    """
    outline = polygonal(outline)
    empty = shapely.MultiPolygon()
    if outline.is_empty:
        return tuple(empty for _ in range(palette.size))
    if palette.size == 1:
        return (outline,)
    xs, ys = _grid(outline.bounds, spacing)
    fractions = _sampled_fractions(field, xs, ys, z)
    values = palette.band_values(fractions)
    lo, hi = palette.band_range[..., 0], palette.band_range[..., 1]
    faces = None
    for i in range(values.shape[-1]):
        bands = _palette_bands(xs, ys, values[:, :, i], int(palette.band_counts[i]))
        strip = bands[lo[:, i]]
        for extra in range(1, int((hi[:, i] - lo[:, i]).max()) + 1):
            wide = hi[:, i] - lo[:, i] >= extra
            strip[wide] = shapely.union(strip[wide], bands[lo[wide, i] + extra])
        faces = strip if faces is None else _intersection(faces, strip)
    faces = _clipped(faces, outline)
    covered = shapely.area(faces).sum()
    if outline.area - covered > 1e-9 * max(outline.area, 1.0):
        faces = _fill_remainder(outline, faces, field, palette, z)
    return tuple(faces)


def _intersection(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``shapely.intersection(a, b)`` of bands. Along a step of the field (a
    three-material ``thresh`` grade) an intersection can also hold lines and points,
    which GEOS then fails to intersect with an empty band; the polygonal parts are kept
    and intersected again in that case."""
    try:
        return shapely.intersection(a, b)
    except shapely.errors.GEOSException:
        return shapely.intersection(polygonal_each(a), polygonal_each(b))


def _fill_remainder(
    outline: shapely.Geometry, faces: np.ndarray, field: BedField, palette: Palette, z: float
) -> np.ndarray:
    """Give every piece of ``outline`` not covered by ``faces`` to the color at its representative point."""
    rest = shapely.get_parts(shapely.difference(outline, shapely.union_all(faces)))
    rest = rest[(shapely.get_type_id(rest) == shapely.GeometryType.POLYGON) & (shapely.area(rest) > 0)]
    if len(rest) == 0:
        return faces
    points = shapely.get_coordinates(shapely.point_on_surface(rest))
    colors = palette.color_of(field.fractions(points, z))
    faces = faces.copy()
    for color in np.unique(colors):
        faces[color] = shapely.union_all(np.append(rest[colors == color], faces[color]))
    return polygonal_each(faces)


def face_spacing(settings: Settings) -> float:
    """Default grid spacing of the field samples: the bead width, mm."""
    return settings.bead_width


def slice_layer(
    design: Design,
    placement: Placement,
    palette: Palette,
    index: int,
    z_top: float,
    height: float,
    settings: Settings,
    *,
    spacing: float | None = None,
    section: shapely.Geometry | None = None,
) -> LayerRegions:
    """The outline and color faces of layer ``index`` (top at ``z_top``, thickness ``height``, mm).

    The design is cut at the mid-plane ``z_top - height / 2`` (bed frame), i.e. at
    ``z_top - height / 2 - offset_z`` in its own frame; the outline is translated by the
    placement's XY offset and simplified to :data:`SECTION_TOLERANCE`. ``spacing`` (mm)
    overrides :func:`face_spacing`; ``section``, the design's section at that plane when
    it was cut already (design frame), saves cutting it again.
    """
    z_plane = z_top - height / 2
    ox, oy, oz = placement.offset
    if section is None:
        section = design.section(z_plane - oz)
    outline = shapely.transform(section, lambda c: c + np.array([ox, oy]))
    outline = polygonal(shapely.simplify(polygonal(outline), SECTION_TOLERANCE, preserve_topology=False))
    field = field_for(design, placement, palette, settings)
    faces = color_faces(outline, field, palette, z_plane, spacing or face_spacing(settings))
    return LayerRegions(index=index, z=z_top, height=height, outline=outline, faces=faces)
