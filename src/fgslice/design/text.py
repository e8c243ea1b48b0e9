"""Text as an exact polygon section: glyph outlines from matplotlib's fonts, extruded.

:func:`text_region` lays out a string (lines split at ``\\n``) with matplotlib's
``TextPath`` in one of the DejaVu fonts matplotlib ships, flattens the glyphs' Bézier
curves to chords within a tolerance, and fills each line's contours by the even-odd rule
(a glyph's holes lie inside its outer contour). OpenVCAD's conventions
(``pyvcad.Text``): ``height`` is the whole block's height, bottom of the lowest glyph to
top of the highest (mm); lines are 1.2 font sizes apart (matplotlib's line spacing), each
aligned horizontally on X = 0 (left edge, centre or right edge), the block vertically on
Y = 0 (bottom, centre, top). :func:`text` extrudes the region by ``depth`` mm, centred on
Z = 0 as OpenVCAD's other leaves are.

Fonts: a family matplotlib finds is used; any other name takes the DejaVu font of its
kind (``Consolas``, ``Courier``... DejaVu Sans Mono; ``Times``, ``Georgia``... DejaVu
Serif; anything else DejaVu Sans).
"""

from __future__ import annotations

import functools

import numpy as np
import shapely

from fgslice.design import nodes
from fgslice.design.extrusion import Extrusion
from fgslice.errors import DesignError

LINE_SPACING = 1.2
"""Baseline to baseline, in font sizes."""

ASPECTS = {"regular": ("normal", "normal"), "bold": ("normal", "bold"), "italic": ("italic", "normal"),
           "bolditalic": ("italic", "bold")}
"""OpenVCAD's font aspects as matplotlib ``(style, weight)``."""

MONOSPACE = {"consolas", "courier", "courier new", "menlo", "monaco", "lucida console", "monospace", "mono"}
SERIF = {"times", "times new roman", "georgia", "garamond", "cambria", "serif"}


def font_properties(font: str, aspect: str):
    """matplotlib ``FontProperties`` of ``font`` (or its DejaVu stand-in) in ``aspect``."""
    from matplotlib import font_manager

    style, weight = ASPECTS[aspect]
    wanted = font_manager.FontProperties(family=font, style=style, weight=weight)
    try:
        font_manager.findfont(wanted, fallback_to_default=False)
        return wanted
    except ValueError:
        key = font.strip().lower()
        family = "DejaVu Sans Mono" if key in MONOSPACE else "DejaVu Serif" if key in SERIF else "DejaVu Sans"
        return font_manager.FontProperties(family=family, style=style, weight=weight)


def _rings(path, tolerance: float) -> list[np.ndarray]:
    """The closed contours of a matplotlib path, curves flattened to chords within ``tolerance``
    (in the path's units)."""
    rings, current = [], []
    for segment, code in path.iter_bezier():
        control = segment.control_points
        if code == path.MOVETO:
            if len(current) >= 3:
                rings.append(np.array(current))
            current = [control[0]]
            continue
        if code == path.CLOSEPOLY:
            if len(current) >= 3:
                rings.append(np.array(current))
            current = []
            continue
        reach = float(np.abs(np.diff(control, axis=0)).sum()) if len(control) > 1 else 0.0
        steps = 1 if len(control) <= 2 else max(2, int(np.ceil(np.sqrt(reach / max(tolerance, 1e-9)))))
        current.extend(segment(np.linspace(0, 1, steps + 1)[1:]))
    if len(current) >= 3:
        rings.append(np.array(current))
    return rings


def _line_region(line: str, prop, tolerance: float) -> shapely.Geometry:
    """One line of text at font size 1, baseline on Y = 0, contours filled even-odd."""
    from matplotlib.textpath import TextPath

    if not line.strip():
        return shapely.MultiPolygon()
    region = shapely.MultiPolygon()
    for ring in _rings(TextPath((0, 0), line, size=1.0, prop=prop), tolerance):
        polygon = shapely.make_valid(shapely.Polygon(ring))
        region = shapely.symmetric_difference(region, polygon)
    return nodes.as_multipolygon(region)


@functools.lru_cache(maxsize=64)
def text_region(content: str, height: float, font: str = "Consolas", aspect: str = "regular",
                h_align: str = "center", v_align: str = "center", tolerance: float = 0.005) -> shapely.MultiPolygon:
    """The filled outline of ``content`` (see the module notes), ``height`` mm tall, curve
    chords within ``tolerance`` mm."""
    if height <= 0:
        raise DesignError(f"text height must be positive, got {height:g} mm")
    prop = font_properties(font, aspect)
    lines = []
    for i, line in enumerate(content.split("\n")):
        region = _line_region(line, prop, tolerance / height)
        if region.is_empty:
            continue
        x0, _, x1, _ = region.bounds
        shift = {"left": -x0, "center": -(x0 + x1) / 2, "right": -x1}[h_align]
        lines.append(shapely.transform(region, lambda c, s=shift, i=i: c + np.array([s, -i * LINE_SPACING])))
    if not lines:
        raise DesignError(f"the text {content!r} has no visible glyph", hint="give it letters, digits or symbols")
    block = nodes.as_multipolygon(shapely.union_all(lines))
    _, y0, _, y1 = block.bounds
    scale = height / (y1 - y0)
    lift = {"bottom": -y0, "center": -(y0 + y1) / 2, "top": -y1}[v_align]
    region = shapely.transform(block, lambda c: (c + np.array([0.0, lift])) * scale)
    return nodes.as_multipolygon(region)


def text(content: str, height: float, depth: float, material: str | None = None, *, font: str = "Consolas",
         aspect: str = "regular", h_align: str = "center", v_align: str = "center",
         where: nodes.Where = nodes.NOWHERE) -> Extrusion:
    """``content`` as a solid: :func:`text_region` extruded ``depth`` mm, centred on Z = 0."""
    if depth <= 0:
        raise DesignError(f"text depth must be positive, got {depth:g} mm", **where.error_kwargs())
    region = text_region(content, float(height), font, aspect, h_align, v_align)
    shape = Extrusion(region, -depth / 2, depth / 2, material, where)
    shape.kind = "text"
    return shape
