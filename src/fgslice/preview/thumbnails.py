"""Thumbnails of a design for the G-code header (printers' and hosts' file lists).

A thumbnail is an orthographic view of the design from the front-right, above
(azimuth :data:`AZIMUTH_DEG`, elevation :data:`ELEVATION_DEG`), colored by the design's
material field at the visible surface (mixtures blended as in
:mod:`fgslice.preview.colors`) and shaded by the surface's slope towards a light over the
viewer's shoulder; the background is transparent.

Rendering samples a signed distance once on a coarse grid over the design's bounds;
every pixel's ray is marched through that grid's trilinear interpolation
(:func:`_trilinear`) by sphere tracing, the first crossing is refined by bisection, and
the design's fractions are evaluated once per hit pixel. The grid comes from the
design's exact signed distance where that is cheap (about :data:`GRID_POINTS` points,
hits refined on it); for designs holding meshes, from what the slice already has when
it is given (:class:`LayerOutlines`: a strategy-1 slice's layer outlines, inside/outside
per cell from the nearest layer: no 3-D mesh distance, no whole-mesh tables), else from
the design's sections. Features
thinner than the grid spacing (a few mm on a 150 mm part) may be missed; at thumbnail
sizes they are below a pixel or two anyway.

Sizes come from ``settings.thumbnails`` (``"16x16,220x124"``): :func:`parse_sizes`.
The PNGs are embedded by :mod:`fgslice.machine.thumbnails`.
"""

from __future__ import annotations

import io
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import shapely

from fgslice.design.base import Design
from fgslice.errors import SettingsError
from fgslice.preview.colors import materials_rgba, mix_rgba

AZIMUTH_DEG = 35.0
ELEVATION_DEG = 30.0
GRID_POINTS = 60_000
SECTION_GRID_POINTS = 120_000
CHAMFER_PASSES = 4
MAX_STEPS = 96
BISECTIONS = 4
MAX_SIDE = 1024
AMBIENT = 0.35
_SIZE = re.compile(r"^\s*(\d+)\s*[xX]\s*(\d+)\s*$")


def parse_sizes(text: str) -> list[tuple[int, int]]:
    """Thumbnail sizes ``[(width, height), ...]`` from ``"16x16,220x124"`` (empty text: none).

    Raises:
        SettingsError: an entry is not ``WxH`` or a side is outside 1-1024 pixels.
    """
    sizes = []
    for entry in (e for e in text.split(",") if e.strip()) if text.strip() else ():
        match = _SIZE.match(entry)
        if not match:
            raise SettingsError(f"thumbnails: '{entry.strip()}' is not a size WxH",
                                hint="write sizes as WxH in pixels, comma separated, e.g. 16x16,220x124")
        w, h = int(match.group(1)), int(match.group(2))
        if not (1 <= w <= MAX_SIDE and 1 <= h <= MAX_SIDE):
            raise SettingsError(f"thumbnails: size {w}x{h} is out of range", hint=f"sides must be 1-{MAX_SIDE} pixels")
        sizes.append((w, h))
    return sizes


@dataclass(frozen=True)
class LayerOutlines:
    """A slice's layers as the thumbnails need them, all in the bed frame (mm).

    Attributes:
        mid: each layer's mid-height, ascending.
        height: each layer's thickness.
        outlines: each layer's outline (polygonal shapely geometry).
        offset: the placement offset ``(x, y, z)``: design frame = bed frame - offset.
    """

    mid: np.ndarray
    height: np.ndarray
    outlines: Sequence[shapely.Geometry]
    offset: tuple[float, float, float]


def _view_basis() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit vectors: view direction (camera to scene), screen right, screen up."""
    az, el = math.radians(AZIMUTH_DEG), math.radians(ELEVATION_DEG)
    camera = np.array([math.sin(az) * math.cos(el), -math.cos(az) * math.cos(el), math.sin(el)])
    view = -camera
    right = np.cross(view, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    return view, right, np.cross(right, view)


class _Grid:
    """The design's signed distance sampled on a regular grid over its (padded) bounds.

    :meth:`from_sdf` samples the design's signed distance; :meth:`from_sections`, for
    designs whose signed distance is slow (meshes), fills the grid from the design's
    sections (inside/outside per cell), :meth:`from_layers` from a slice's layer outlines;
    both convert that to a distance (:meth:`from_inside`).
    """

    def __init__(self, lo: np.ndarray, step: np.ndarray, sdf: np.ndarray, planes: np.ndarray | None = None) -> None:
        self.lo = lo
        self.step = step
        self.sdf = sdf
        self.gradient = np.gradient(sdf, *step)
        self.planes = planes
        """From layers: the design-frame height (mm) of the layer each grid plane was drawn
        from (grid planes outside the layers take the nearest drawn one's); else None."""

    @staticmethod
    def _axes(lo: np.ndarray, hi: np.ndarray, points: int) -> tuple[list[np.ndarray], np.ndarray]:
        extent = hi - lo
        spacing = float(np.prod(extent) / points) ** (1 / 3)
        shape = np.clip(np.ceil(extent / spacing).astype(int) + 1, 4, 160)
        step = extent / (shape - 1)
        return [lo[i] + np.arange(shape[i]) * step[i] for i in range(3)], step

    @classmethod
    def from_sdf(cls, design: Design, lo: np.ndarray, hi: np.ndarray, points: int) -> _Grid:
        axes, step = cls._axes(lo, hi, points)
        values = np.asarray(design.sdf(axes[0][:, None, None], axes[1][None, :, None], axes[2][None, None, :]), float)
        return cls(lo, step, np.ascontiguousarray(np.broadcast_to(values, tuple(len(a) for a in axes))))

    @classmethod
    def from_sections(cls, design: Design, lo: np.ndarray, hi: np.ndarray, points: int) -> _Grid:
        axes, step = cls._axes(lo, hi, points)
        xx, yy = np.meshgrid(axes[0], axes[1], indexing="ij")
        inside = np.stack([shapely.contains_xy(section, xx, yy) for section in design.sections(axes[2])], axis=2)
        return cls.from_inside(lo, step, inside)

    @classmethod
    def from_layers(cls, layers: LayerOutlines, lo: np.ndarray, hi: np.ndarray, points: int) -> _Grid:
        """Each grid plane takes the outline of the layer nearest to it (empty above the top
        layer and below the bottom one); ``lo``, ``hi`` in the design frame."""
        axes, step = cls._axes(lo, hi, points)
        ox, oy, oz = layers.offset
        xx, yy = np.meshgrid(axes[0] + ox, axes[1] + oy, indexing="ij")
        mid, half = np.asarray(layers.mid, float), np.asarray(layers.height, float) / 2
        z = axes[2] + oz
        after = np.clip(np.searchsorted(mid, z), 1, len(mid) - 1) if len(mid) > 1 else np.zeros(len(z), int)
        nearest = np.where(np.abs(z - mid[after - 1]) <= np.abs(z - mid[after]), after - 1, after)
        within = np.abs(z - mid[nearest]) <= half[nearest]
        inside = np.zeros(xx.shape + (len(z),), dtype=bool)
        drawn = np.flatnonzero(within)
        for k in drawn:
            inside[:, :, k] = shapely.contains_xy(layers.outlines[nearest[k]], xx, yy)
        grid = cls.from_inside(lo, step, inside)
        if len(drawn):
            closest = drawn[np.abs(np.arange(len(z))[:, None] - drawn[None, :]).argmin(axis=1)]
            grid.planes = mid[nearest[closest]] - oz
        return grid

    def plane_heights(self, points: np.ndarray) -> np.ndarray:
        """Each of ``(n, 3)`` points' height snapped to the layer its grid plane was drawn
        from (needs :attr:`planes`)."""
        k = np.clip(np.rint((points[:, 2] - self.lo[2]) / self.step[2]).astype(int), 0, len(self.planes) - 1)
        return self.planes[k]

    @classmethod
    def from_inside(cls, lo: np.ndarray, step: np.ndarray, inside: np.ndarray) -> _Grid:
        """A distance from inside/outside per cell, by chamfer propagation
        (:func:`_chamfer_distance`), smoothed over one cell (:func:`_smooth`)."""
        sdf = _chamfer_distance(inside, step, CHAMFER_PASSES) - _chamfer_distance(~inside, step, CHAMFER_PASSES)
        return cls(lo, step, _smooth(sdf))

    def _index(self, points: np.ndarray) -> np.ndarray:
        return ((points - self.lo) / self.step).T

    def value(self, points: np.ndarray) -> np.ndarray:
        """Trilinear interpolation of the sampled distance at ``(n, 3)`` points (mm)."""
        return _trilinear(self.sdf, self._index(points))

    def normal(self, points: np.ndarray) -> np.ndarray:
        """Unit outward normals ``(n, 3)`` from the sampled distance's gradient."""
        index = self._index(points)
        g = np.stack([_trilinear(c, index) for c in self.gradient], axis=1)
        return g / np.maximum(np.linalg.norm(g, axis=1, keepdims=True), 1e-12)


def _shifted(offset: int, size: int) -> tuple[slice, slice]:
    """Slices ``(to, from)`` of an axis of ``size`` such that ``a[to]`` and
    ``a[from]`` are neighbours ``offset`` cells apart (``to = from + offset``)."""
    return slice(max(offset, 0), size + min(offset, 0)), slice(max(-offset, 0), size + min(-offset, 0))


def _chamfer_distance(mask: np.ndarray, step: np.ndarray, passes: int) -> np.ndarray:
    """Distance (mm) from every cell to the nearest cell of ``mask`` (0 on it).

    ``passes`` passes of 26-neighbour chamfer propagation by jumps of ``2**(passes - 1)``,
    ..., 2, 1 cells (as in jump flooding), each jump of the Euclidean length it spans
    (``step`` mm per axis). One jump per pass reaches every cell up to
    ``reach = 2**passes - 1`` cells away along each axis; a path of jumps is never shorter
    than the straight line between the cell centres, so a reached cell's value is at least
    its Euclidean distance (and, on cubic cells, at most 13 % more, as with one-cell
    steps); a cell not reached lies more than ``reach`` cells away and gets that lower
    bound, ``reach * min(step)``. A lower bound where it matters is what sphere tracing
    needs: it never steps past a surface. Four passes (reach 15) cost a third of twelve
    one-cell passes (reach 12): 3DBenchy's thumbnails take 0.14 s instead of 0.24 s, with
    the same PNG bytes.
    """
    distance = np.where(mask, 0.0, np.inf)
    shape = mask.shape
    neighbours = [(i, j, k) for i in (-1, 0, 1) for j in (-1, 0, 1) for k in (-1, 0, 1) if (i, j, k) != (0, 0, 0)]
    for jump in 2 ** np.arange(passes - 1, -1, -1):
        for direction in neighbours:
            offset = np.asarray(direction) * jump
            if np.any(np.abs(offset) >= shape):  # no cell has a neighbour that far
                continue
            to = tuple(_shifted(o, n)[0] for o, n in zip(offset, shape))
            source = tuple(_shifted(o, n)[1] for o, n in zip(offset, shape))
            np.minimum(distance[to], distance[source] + float(np.linalg.norm(offset * step)), out=distance[to])
    distance[np.isinf(distance)] = (2**passes - 1) * float(np.min(step))
    return distance


def _smooth(volume: np.ndarray) -> np.ndarray:
    """``volume`` blurred by the binomial kernel (1 4 6 4 1)/16 along each axis (a Gaussian
    of one cell's standard deviation), edges repeated."""
    out = volume
    for axis in range(volume.ndim):
        v = np.moveaxis(out, axis, 0)
        n = v.shape[0]
        padded = np.concatenate([v[:1], v[:1], v, v[-1:], v[-1:]])
        v = (padded[:n] + 4 * padded[1 : n + 1] + 6 * padded[2 : n + 2] + 4 * padded[3 : n + 3] + padded[4 : n + 4]) / 16
        out = np.moveaxis(v, 0, axis)
    return out


def _trilinear(volume: np.ndarray, index: np.ndarray) -> np.ndarray:
    """Trilinear interpolation of ``volume`` at fractional grid indices ``index`` ``(3, n)``;
    indices outside the grid are clamped to its edge (what ``scipy.ndimage.map_coordinates``
    does with ``order=1, mode="nearest"``, without importing scipy for every slice).

    The eight corners of each point's cell are read from the flattened volume at one
    offset each from the cell's first corner (a 1-D ``take`` is several times faster
    than indexing the 3-D array eight times).
    """
    volume = np.ascontiguousarray(volume)
    shape = np.array(volume.shape)
    at = np.clip(index.T, 0, shape - 1)
    base = np.minimum(at.astype(np.intp), shape - 2)
    fx, fy, fz = (at - base).T
    sx, sy, sz = (stride // volume.itemsize for stride in volume.strides)
    first = base @ np.array([sx, sy, sz])
    flat = volume.ravel()

    def corner(offset: int) -> np.ndarray:
        return np.take(flat, first + offset)

    c00 = corner(0) * (1 - fx) + corner(sx) * fx
    c10 = corner(sy) * (1 - fx) + corner(sx + sy) * fx
    c01 = corner(sz) * (1 - fx) + corner(sx + sz) * fx
    c11 = corner(sy + sz) * (1 - fx) + corner(sx + sy + sz) * fx
    return (c00 * (1 - fy) + c10 * fy) * (1 - fz) + (c01 * (1 - fy) + c11 * fy) * fz


def _sdf_is_fast(design: Design) -> bool:
    """Whether the design's exact signed distance is cheap enough to sample a grid with:
    a design holding meshes (``design.meshes`` non-empty) is not (a mesh's signed
    distance needs search structures that take about a second to build), every other
    one is. Decided from the design alone, never by timing, so that the thumbnails, and
    the G-code holding them, are the same on every run and machine."""
    return not getattr(design, "meshes", None)


def _ray_box(origins: np.ndarray, view: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Entry and exit ray parameters of the box (slab method); entry > exit means a miss."""
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / view
        t0, t1 = (lo - origins) * inv, (hi - origins) * inv
    near, far = np.minimum(t0, t1), np.maximum(t0, t1)
    return np.nanmax(near, axis=1), np.nanmin(far, axis=1)


class _Scene:
    """What every view of one design shares: its padded bounds (mm), whether its exact
    signed distance is used, and the sampled-distance :class:`_Grid` (from ``layers`` when
    given); built once for all thumbnail sizes."""

    def __init__(self, design: Design, layers: LayerOutlines | None = None) -> None:
        (x0, y0, z0), (x1, y1, z1) = design.bounds()
        lo, hi = np.array([x0, y0, z0], float), np.array([x1, y1, z1], float)
        pad = 0.02 * float(np.linalg.norm(hi - lo)) + 1e-3
        self.design = design
        self.layers = layers
        self.lo, self.hi = lo - pad, hi + pad
        self._grid: _Grid | None = None
        self._exact: bool | None = None

    @property
    def exact(self) -> bool:
        """Whether hits are refined on the design's exact signed distance."""
        if self._exact is None:
            self._exact = _sdf_is_fast(self.design)
        return self._exact

    @property
    def grid(self) -> _Grid:
        """The sampled distance: from the signed distance when exact, else from the layers
        when given, else from the design's sections."""
        if self._grid is None:
            if self.exact:
                self._grid = _Grid.from_sdf(self.design, self.lo, self.hi, GRID_POINTS)
            elif self.layers is not None:
                self._grid = _Grid.from_layers(self.layers, self.lo, self.hi, SECTION_GRID_POINTS)
            else:
                self._grid = _Grid.from_sections(self.design, self.lo, self.hi, SECTION_GRID_POINTS)
        return self._grid


def render_image(design: Design, width: int, height: int, scene: _Scene | None = None) -> np.ndarray:
    """``(height, width, 4)`` RGBA floats (0-1) of the design's view (row 0 at the top).

    ``scene`` shares the sampled grid between several sizes of the same design.
    """
    scene = scene or _Scene(design)
    lo, hi = scene.lo, scene.hi
    view, right, up = _view_basis()
    corners = np.array(np.meshgrid(*zip(lo, hi), indexing="ij")).reshape(3, -1).T
    u, v = corners @ right, corners @ up
    pixel = max((u.max() - u.min()) / width, (v.max() - v.min()) / height)
    uc, vc = (u.max() + u.min()) / 2, (v.max() + v.min()) / 2
    us = uc + (np.arange(width) - (width - 1) / 2) * pixel
    vs = vc - (np.arange(height) - (height - 1) / 2) * pixel
    uu, vv = np.meshgrid(us, vs)
    center = (lo + hi) / 2
    reach = float(np.linalg.norm(hi - lo))
    origins = (center + (uu.ravel() - center @ right)[:, None] * right + (vv.ravel() - center @ up)[:, None] * up
               - reach * view)
    t_in, t_out = _ray_box(origins, view, lo, hi)
    image = np.zeros((height * width, 4))
    rays = np.flatnonzero(t_in < t_out)
    if len(rays) == 0:
        return image.reshape(height, width, 4)
    exact, grid = scene.exact, scene.grid
    min_step = 0.5 * float(grid.step.min())
    t = t_in[rays].copy()
    t_prev = t.copy()
    hit = np.zeros(len(rays), dtype=bool)
    active = np.ones(len(rays), dtype=bool)
    for _ in range(MAX_STEPS):
        idx = np.flatnonzero(active)
        if len(idx) == 0:
            break
        d = grid.value(origins[rays[idx]] + t[idx, None] * view)
        inside = d <= 0
        hit[idx[inside]] = True
        active[idx[inside]] = False
        moving = idx[~inside]
        t_prev[moving] = t[moving]
        t[moving] += np.maximum(0.6 * d[~inside], min_step)
        active[moving[t[moving] > t_out[rays[moving]]]] = False
    found = np.flatnonzero(hit)
    a, b = t_prev[found], t[found]
    o = origins[rays[found]]
    for _ in range(BISECTIONS):
        mid = (a + b) / 2
        p = o + mid[:, None] * view
        inside = (np.asarray(design.sdf(p[:, 0], p[:, 1], p[:, 2])) if exact else grid.value(p)) <= 0
        b = np.where(inside, mid, b)
        a = np.where(inside, a, mid)
    p = o + b[:, None] * view
    fractions = _fractions(design, p, grid.plane_heights(p) if grid.planes is not None else None)
    color = mix_rgba(fractions, materials_rgba(design.materials))
    light = -view + 0.6 * up + 0.3 * right
    light /= np.linalg.norm(light)
    shade = AMBIENT + (1 - AMBIENT) * np.clip(grid.normal(p) @ light, 0.0, 1.0)
    color[:, :3] *= shade[:, None]
    image[rays[found]] = color
    return image.reshape(height, width, 4)


def _fractions(design: Design, points: np.ndarray, planes: np.ndarray | None) -> np.ndarray:
    """The design's fractions ``(n, k)`` at ``(n, 3)`` points (mm); with ``planes`` (a
    height per point), at the points moved to those heights, one call per height: points
    of one plane find the body they belong to from its section, not a 3-D distance
    (:mod:`fgslice.design.membership`)."""
    if planes is None:
        return np.asarray(design.fractions(points[:, 0], points[:, 1], points[:, 2]), dtype=float).reshape(len(points), -1)
    heights, which = np.unique(planes, return_inverse=True)
    out = np.empty((len(points), len(design.materials)))
    for k, z in enumerate(heights):
        at = np.flatnonzero(which == k)
        values = design.fractions(points[at, 0], points[at, 1], np.full(len(at), z))
        out[at] = np.asarray(values, dtype=float).reshape(len(at), -1)
    return out


def thumbnail_png(design: Design, width: int, height: int, scene: _Scene | None = None) -> bytes:
    """PNG bytes of the design's view, ``width`` x ``height`` pixels, transparent background."""
    from PIL import Image

    pixels = np.round(render_image(design, width, height, scene) * 255).astype(np.uint8)
    buffer = io.BytesIO()
    Image.fromarray(pixels, "RGBA").save(buffer, format="PNG")
    return buffer.getvalue()


def render_thumbnails(
    design: Design, settings, sizes: list[tuple[int, int]] | None = None, layers: LayerOutlines | None = None,
) -> list[tuple[bytes, int, int]]:
    """Thumbnails ``[(png, width, height), ...]`` for ``GcodeWriter(..., thumbnails=...)``.

    ``sizes`` defaults to :func:`parse_sizes` of ``settings.thumbnails`` (SettingsError
    when malformed); an empty list means no thumbnails. ``layers``: the slice's layer
    outlines to draw the part from (what :func:`fgslice.pipeline.slice_to_gcode` passes
    to its ``thumbnails`` function in strategy 1); None: the design itself.
    """
    chosen = parse_sizes(settings.thumbnails) if sizes is None else sizes
    scene = _Scene(design, layers)
    return [(thumbnail_png(design, w, h, scene), w, h) for w, h in chosen]
