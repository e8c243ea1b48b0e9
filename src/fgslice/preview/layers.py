"""Layer images of a G-code file: toolpaths at their real width, colored by process state.

Every extrusion move of a layer is drawn as a polyline of its ``;WIDTH:`` (mm) in the bed
frame: the axes are laid out so that one millimetre is the same number of pixels along
X and Y, and line widths are that many millimetres converted to points, with round caps
and joins (a bead's capsule ends). Colors are :mod:`fgslice.preview.colors`: mixtures
blended from the materials' colors, tools and ``;STATE`` colors as palette colors with a
legend, temperatures on a colormap with a colorbar. Travels can be shown as thin dashed
gray lines. With a design, its material field at the layer's mid-height is drawn beside
the toolpaths at the same scale (continuous, not quantized to the palette), masked
outside the part by the signed distance.

Images are PNG, rendered with matplotlib's Agg backend (no display needed), and written
atomically (:func:`fgslice.output.atomic_output`).
"""

from __future__ import annotations

import io
import math
from collections.abc import Sequence
from dataclasses import dataclass

import matplotlib

matplotlib.use("Agg")

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import LineCollection
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from fgslice.design.base import Design
from fgslice.errors import GcodeError
from fgslice.output import atomic_output, check_writable
from fgslice.preview.colors import (
    TEMPERATURE_CMAP,
    UNKNOWN_RGBA,
    Printout,
    StateColors,
    load_printout,
    materials_rgba,
    mix_rgba,
    state_colors,
)
from fgslice.slicing.layers import Placement

DPI = 100
BACKGROUND = "white"
FIGURE_COLOR = "#f2f2f2"
TRAVEL_COLOR = "#555555"
DEFAULT_WIDTH_MM = 0.4
MARGIN_PX = {"left": 60, "bottom": 46, "top": 36, "gap": 60}
LEGEND_PAD_PX = 10
COLORBAR_PX = 90
MAX_LEGEND = 40
MAX_FIELD_PX = 900


@dataclass(frozen=True)
class Layout:
    """Panels of equal scale: axes rectangles in pixels and millimetres per pixel.

    ``bounds`` is the bed-frame rectangle ``(x0, y0, x1, y1)`` (mm) every panel shows;
    ``px_per_mm`` the scale; ``panels`` the ``(left, bottom, width, height)`` pixel boxes.
    """

    bounds: tuple[float, float, float, float]
    px_per_mm: float
    panels: list[tuple[float, float, float, float]]


def layer_count(program) -> int:
    """Number of layers of a program (``;LAYER_CHANGE``/``;Z:`` comments)."""
    top = int(program.layer.max()) + 1 if len(program.layer) else 0
    return max(top, len(program.layer_z))


def check_layer(program, layer: int) -> None:
    """Raise :class:`GcodeError` unless ``layer`` is a layer of ``program``."""
    count = layer_count(program)
    if count == 0:
        raise GcodeError("the G-code has no layers", hint="previews need ';LAYER_CHANGE' comments")
    if not 0 <= layer < count:
        raise GcodeError(f"layer {layer} does not exist: the file has {count} layers (0-{count - 1})",
                         hint="pick a layer in range, or select one by height with --z")


def nearest_layer(program, z: float) -> int:
    """The layer whose top (``;Z:``, mm) is nearest ``z``; ties go to the lower layer.

    Raises:
        GcodeError: the file has no ``;Z:`` comments or ``z`` is not finite.
    """
    program = program.program if isinstance(program, Printout) else program
    if not math.isfinite(z):
        raise GcodeError(f"height {z} is not a number")
    if not program.layer_z:
        raise GcodeError("the G-code has no ';Z:' layer heights", hint="select the layer by number instead")
    return int(np.argmin(np.abs(np.asarray(program.layer_z) - z)))


def layer_z(program, layer: int) -> tuple[float, float]:
    """Top ``z`` and thickness of ``layer`` (mm) from the ``;Z:`` comments (NaN if absent)."""
    tops = np.asarray(program.layer_z, dtype=float)
    if layer >= len(tops):
        return math.nan, math.nan
    return float(tops[layer]), float(tops[layer] - (tops[layer - 1] if layer > 0 else 0.0))


def extrusion_bounds(program, margin_mm: float = 2.0) -> tuple[float, float, float, float]:
    """Bed-frame XY box of every extrusion move (all layers), grown by ``margin_mm``."""
    moves = (program.e > 0) & (program.length > 0)
    if not moves.any():
        raise GcodeError("the G-code extrudes nothing", hint="previews draw extrusion moves")
    pts = np.concatenate([program.start[moves, :2], program.end[moves, :2]])
    (x0, y0), (x1, y1) = pts.min(axis=0), pts.max(axis=0)
    return x0 - margin_mm, y0 - margin_mm, x1 + margin_mm, y1 + margin_mm


def plan_layout(bounds: Sequence[float], box: tuple[float, float, float, float], n_panels: int, gap_px: float) -> Layout:
    """``n_panels`` side by side showing ``bounds`` at one common scale, centred in pixel ``box``."""
    x0, y0, x1, y1 = bounds
    left, bottom, width, height = box
    dx, dy = max(x1 - x0, 1e-6), max(y1 - y0, 1e-6)
    scale = max(min((width - gap_px * (n_panels - 1)) / (n_panels * dx), height / dy), 1e-6)
    pw, ph = dx * scale, dy * scale
    start = left + (width - (n_panels * pw + gap_px * (n_panels - 1))) / 2
    base = bottom + (height - ph) / 2
    panels = [(start + i * (pw + gap_px), base, pw, ph) for i in range(n_panels)]
    return Layout((x0, y0, x1, y1), scale, panels)


def _axes(fig: Figure, panel: tuple[float, float, float, float], bounds: Sequence[float], size: tuple[int, int]):
    w, h = size
    left, bottom, pw, ph = panel
    ax = fig.add_axes((left / w, bottom / h, pw / w, ph / h), facecolor=BACKGROUND)
    ax.set_xlim(bounds[0], bounds[2])
    ax.set_ylim(bounds[1], bounds[3])
    ax.tick_params(labelsize=8)
    return ax


def _runs(program, moves: np.ndarray) -> tuple[list[np.ndarray], np.ndarray]:
    """Polylines of consecutive moves ``moves`` (indices, ascending) with one state and width.

    Returns the ``(n_i + 1, 2)`` vertex arrays and the index of each run's first move.
    """
    if len(moves) == 0:
        return [], moves
    width = np.nan_to_num(program.width[moves], nan=-1.0)
    state = program.state[moves]
    breaks = np.flatnonzero((np.diff(moves) != 1) | (np.diff(state) != 0) | (np.diff(width) != 0)) + 1
    firsts = np.r_[0, breaks]
    starts = program.start[moves[firsts], :2]
    ends = np.split(program.end[moves, :2], breaks)
    return [np.vstack([s[None, :], e]) for s, e in zip(starts, ends)], moves[firsts]


def _extrusions(program, layer: int) -> np.ndarray:
    """Indices of the extrusion moves (E > 0, some XY length) of ``layer``."""
    return np.flatnonzero((program.layer == layer) & (program.e > 0) & (program.length > 0))


def layer_keys(program, colors: StateColors, layer: int) -> np.ndarray:
    """The legend keys (``colors.key``) of the states ``layer``'s extrusions are printed in."""
    return np.unique(colors.key[program.state[_extrusions(program, layer)]])


def draw_layer(ax, printout: Printout, colors: StateColors, layer: int, px_per_mm: float,
               *, show_travel: bool = False, default_width: float = DEFAULT_WIDTH_MM,
               values: np.ndarray | None = None, norm: Normalize | None = None) -> None:
    """Draw ``layer``'s extrusions (real width) on ``ax`` laid out at ``px_per_mm``
    (their states' legend keys: :func:`layer_keys`); with ``values`` (one per move,
    :func:`fgslice.preview.attributes.move_values`) each move is colored by its value on
    :data:`ATTRIBUTE_CMAP` scaled by ``norm`` instead of by its state.
    """
    program = printout.program
    on_layer = program.layer == layer
    moves = _extrusions(program, layer)
    if values is not None:
        from matplotlib import colormaps

        lines, firsts = list(np.stack([program.start[moves, :2], program.end[moves, :2]], axis=1)), moves
        rgba = colormaps[ATTRIBUTE_CMAP](norm(values[moves]))
        rgba[~np.isfinite(values[moves])] = UNKNOWN_RGBA
    else:
        lines, firsts = _runs(program, moves)
        rgba = colors.rgba[program.state[firsts]]
    widths_mm = np.nan_to_num(program.width[firsts], nan=default_width)
    if show_travel:
        travel = np.flatnonzero(on_layer & (program.e <= 0) & (program.length > 0))
        segments = np.stack([program.start[travel, :2], program.end[travel, :2]], axis=1)
        ax.add_collection(LineCollection(segments, colors=TRAVEL_COLOR, linewidths=0.4, linestyles=(0, (3, 3)),
                                         zorder=3))
    if lines:
        ax.add_collection(LineCollection(
            lines,
            colors=rgba,
            linewidths=widths_mm * px_per_mm * 72.0 / DPI,
            capstyle="round",
            joinstyle="round",
            antialiased=True,
            zorder=2,
        ))


ATTRIBUTE_CMAP = "viridis"
"""Colormap of layers colored by a process attribute."""


def _colorbar(fig: Figure, norm: Normalize, cmap: str, label: str, size: tuple[int, int],
              rows: tuple[float, float]) -> float:
    """A colorbar of ``cmap`` over ``norm`` at the right edge of the picture, in the pixel
    rows ``(bottom, height)``; returns its width in pixels with its label."""
    from matplotlib import colormaps
    from matplotlib.cm import ScalarMappable

    w, h = size
    bottom, height = rows
    cax = fig.add_axes(((w - COLORBAR_PX) / w, (bottom + 0.1 * height) / h, 18 / w, 0.8 * height / h))
    fig.colorbar(ScalarMappable(norm, colormaps[cmap]), cax=cax, label=label)
    return w - cax.get_tightbbox(FigureCanvasAgg(fig).get_renderer()).x0 + LEGEND_PAD_PX


def _attribute_image(design: Design, placement: Placement, name: str, norm: Normalize, bounds: Sequence[float],
                     z: float, shape: tuple[int, int]) -> np.ndarray:
    """``(ny, nx, 4)`` RGBA of the design's attribute ``name`` at bed height ``z``
    (transparent outside the part and where no attribute covers it)."""
    from matplotlib import colormaps

    from fgslice.design.attributes import attribute_fields

    x0, y0, x1, y1 = bounds
    ny, nx = shape
    xs = x0 + (np.arange(nx) + 0.5) * (x1 - x0) / nx
    ys = y0 + (np.arange(ny) + 0.5) * (y1 - y0) / ny
    dx, dy, dz = placement.to_design(xs[None, :], ys[:, None], z)
    fields = attribute_fields(design)
    values = (fields.values(name, dx, dy, dz) if fields is not None and name in fields.names
              else np.full((ny, nx), np.nan))
    values = np.broadcast_to(values, (ny, nx))
    shown = np.broadcast_to(np.asarray(design.sdf(dx, dy, dz)) <= 0, (ny, nx)) & np.isfinite(values)
    image = np.zeros((ny, nx, 4))
    image[shown] = colormaps[ATTRIBUTE_CMAP](norm(values[shown]))
    return image


def _legend(fig: Figure, colors: StateColors, keys: np.ndarray, size: tuple[int, int], rows: tuple[float, float]) -> float:
    """The key of the colors drawn, at the right edge of the picture, in the pixel rows
    ``(bottom, height)``; returns its width in pixels, for the panels to leave room for it.
    A list wider than half the picture is set in a smaller font (down to 5 pt)."""
    w, h = size
    bottom, height = rows
    renderer = FigureCanvasAgg(fig).get_renderer()
    if colors.mode == "temperature":
        return _colorbar(fig, Normalize(*colors.value_range), TEMPERATURE_CMAP, "nozzle target (degC)", size, rows)
    known = [int(k) for k in keys if k >= 0 and int(k) in colors.labels]
    if len(known) > MAX_LEGEND:
        known = [known[i] for i in np.linspace(0, len(known) - 1, MAX_LEGEND).round().astype(int)]
    first_state = {int(k): int(np.flatnonzero(colors.key == k)[0]) for k in known}
    handles = [Patch(facecolor=colors.rgba[first_state[k]], edgecolor="#333333", linewidth=0.4, label=colors.labels[k])
               for k in known]
    if (keys < 0).any():
        handles.append(Patch(facecolor=UNKNOWN_RGBA, edgecolor="#333333", linewidth=0.4, label="no state set"))
    if not handles:
        return 0.0
    fontsize = 7 if len(handles) > 16 else 8
    while True:
        legend = fig.legend(handles=handles, loc="upper right", bbox_to_anchor=((w - LEGEND_PAD_PX) / w, (bottom + height) / h),
                            fontsize=fontsize, frameon=False, title=colors.mode, title_fontsize=8,
                            handlelength=1.4, labelspacing=0.3)
        width = legend.get_window_extent(renderer).width
        if width <= w / 2 or fontsize <= 5:
            return width + 2 * LEGEND_PAD_PX
        legend.remove()
        fontsize -= 1


def _design_image(design: Design, placement: Placement, bounds: Sequence[float], z: float, shape: tuple[int, int]) -> np.ndarray:
    """``(ny, nx, 4)`` RGBA of the design's field at bed height ``z`` on pixel centres (transparent outside)."""
    x0, y0, x1, y1 = bounds
    ny, nx = shape
    xs = x0 + (np.arange(nx) + 0.5) * (x1 - x0) / nx
    ys = y0 + (np.arange(ny) + 0.5) * (y1 - y0) / ny
    dx, dy, dz = placement.to_design(xs[None, :], ys[:, None], z)
    inside = np.broadcast_to(np.asarray(design.sdf(dx, dy, dz)) <= 0, (ny, nx))
    image = np.zeros((ny, nx, 4))
    if inside.any():
        fractions = np.asarray(design.fractions(dx, dy, dz), dtype=float)
        fractions = np.broadcast_to(fractions, (ny, nx, fractions.shape[-1]))
        image[inside] = mix_rgba(fractions[inside], materials_rgba(design.materials))
    return image


def _placement(printout: Printout, placement: Placement | None) -> Placement:
    if placement is not None:
        return placement
    if printout.info.placement_offset is None:
        raise GcodeError("the G-code has no '; placement_offset = dx,dy,dz' comment to place the design",
                         file=printout.name, hint="pass the placement used to slice it")
    return Placement(printout.info.placement_offset)


def _png(fig: Figure) -> bytes:
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=DPI, facecolor=fig.get_facecolor())
    return buffer.getvalue()


def _check_size(size: tuple[int, int]) -> tuple[int, int]:
    w, h = (int(v) for v in size)
    if not (200 <= w <= 8000 and 150 <= h <= 8000):
        raise GcodeError(f"image size {w}x{h} is out of range", hint="use 200-8000 x 150-8000 pixels")
    return w, h


def layer_figure(source, layer: int, *, design: Design | None = None, placement: Placement | None = None,
                 show_travel: bool = False, size: tuple[int, int] = (1200, 900), attribute: str | None = None):
    """The figure of one layer and its toolpath axes (bed mm to pixels: ``ax.transData``).

    See :func:`render_layer` for the arguments.
    """
    if attribute is not None:
        from fgslice.design.attributes import canonical_name

        attribute = canonical_name(attribute)
    printout = load_printout(source)
    program = printout.program
    check_layer(program, layer)
    size = _check_size(size)
    w, h = size
    bounds = extrusion_bounds(program)
    colors = state_colors(printout)
    m = MARGIN_PX
    fig = Figure(figsize=(w / DPI, h / DPI), dpi=DPI, facecolor=FIGURE_COLOR)
    rows = (m["bottom"], h - m["bottom"] - m["top"])
    values = norm = None
    if attribute is None:
        legend_px = _legend(fig, colors, layer_keys(program, colors, layer), size, rows)
    else:
        from fgslice.design.attributes import UNITS
        from fgslice.preview.attributes import move_values, value_range

        located = _placement(printout, placement) if design is not None else None
        values = move_values(printout, attribute, design, located)
        norm = Normalize(*value_range(values))
        legend_px = _colorbar(fig, norm, ATTRIBUTE_CMAP, f"{attribute} ({UNITS[attribute]})", size, rows)
    box = (m["left"], m["bottom"], w - m["left"] - legend_px - LEGEND_PAD_PX, rows[1])
    layout = plan_layout(bounds, box, 2 if design is not None else 1, m["gap"])
    ax = _axes(fig, layout.panels[0], bounds, size)
    default_width = float(printout.info.settings.get("bead_width", DEFAULT_WIDTH_MM))
    draw_layer(ax, printout, colors, layer, layout.px_per_mm, show_travel=show_travel,
               default_width=default_width, values=values, norm=norm)
    ax.set_xlabel("X (mm)", fontsize=8)
    ax.set_ylabel("Y (mm)", fontsize=8)
    z_top, height = layer_z(program, layer)
    where = f"z = {z_top:g} mm" if math.isfinite(z_top) else "z unknown"
    ax.set_title(f"layer {layer} of {layer_count(program)}, {where}: toolpaths", fontsize=10)
    if design is not None:
        dax = _axes(fig, layout.panels[1], bounds, size)
        z_mid = z_top - height / 2 if math.isfinite(z_top) else 0.0
        _, _, pw, ph = layout.panels[1]
        shape = (max(1, min(int(ph), MAX_FIELD_PX)), max(1, min(int(pw), MAX_FIELD_PX)))
        if attribute is None:
            image = _design_image(design, _placement(printout, placement), bounds, z_mid, shape)
        else:
            image = _attribute_image(design, _placement(printout, placement), attribute, norm, bounds, z_mid, shape)
        dax.imshow(image, origin="lower", extent=(bounds[0], bounds[2], bounds[1], bounds[3]),
                   interpolation="nearest", aspect="auto")
        dax.set_xlabel("X (mm)", fontsize=8)
        dax.set_title(f"design {attribute or 'field'} at z = {z_mid:g} mm", fontsize=10)
    if attribute is not None:
        ax.set_title(f"layer {layer} of {layer_count(program)}, {where}: {attribute} as commanded", fontsize=10)
    return fig, ax


def layer_png(source, layer: int, *, design: Design | None = None, placement: Placement | None = None,
              show_travel: bool = False, size: tuple[int, int] = (1200, 900), attribute: str | None = None) -> bytes:
    """PNG bytes of one layer (see :func:`render_layer`)."""
    fig, _ = layer_figure(source, layer, design=design, placement=placement, show_travel=show_travel, size=size,
                          attribute=attribute)
    return _png(fig)


def _write(path, data: bytes) -> None:
    with atomic_output(path, "wb") as handle:
        handle.write(data)


def render_layer(program, layer: int, out_png, *, design: Design | None = None, placement: Placement | None = None,
                 show_travel: bool = False, size: tuple[int, int] = (1200, 900), attribute: str | None = None) -> None:
    """Write a PNG of one layer's toolpaths at real bead width, colored by state.

    Args:
        program: a G-code path, its text or bytes, a :class:`~fgslice.preview.colors.Printout`
            or a read :class:`~fgslice.machine.gcode_reader.GcodeProgram` (then without
            header: no material colors or placement).
        layer: 0-based layer (:func:`nearest_layer` picks one by height).
        out_png: the image file.
        design: draw the design's field at the layer's mid-height beside the toolpaths.
        placement: design-to-bed translation; default the file's ``; placement_offset``.
        show_travel: draw travel moves as thin dashed lines.
        size: image ``(width, height)`` in pixels.
        attribute: color the moves by this process attribute as commanded (fan, flow,
            speed, temperature; infill_density from ``design``) on a colormap over its
            range in the file, and draw the design's attribute field beside them.

    Raises:
        GcodeError: not G-code, no such layer, no extrusion, no placement for ``design``.
        OutputError: the output folder does not exist or cannot be written.
    """
    check_writable(out_png)
    _write(out_png, layer_png(program, layer, design=design, placement=placement, show_travel=show_travel, size=size,
                              attribute=attribute))


def sheet_layers(program, count: int) -> list[int]:
    """``count`` evenly spaced layers from the first to the last (fewer if the file has fewer)."""
    total = layer_count(program)
    if count < 1:
        raise GcodeError(f"a contact sheet needs at least one layer, got {count}")
    if total == 0:
        raise GcodeError("the G-code has no layers", hint="previews need ';LAYER_CHANGE' comments")
    return sorted({int(v) for v in np.linspace(0, total - 1, min(count, total)).round()})


def sheet_png(source, *, count: int = 9, size: tuple[int, int] = (1200, 1200)) -> bytes:
    """PNG bytes of a contact sheet (see :func:`render_sheet`)."""
    printout = load_printout(source)
    program = printout.program
    layers = sheet_layers(program, count)
    w, h = _check_size(size)
    cols = math.ceil(math.sqrt(len(layers)))
    rows = math.ceil(len(layers) / cols)
    bounds = extrusion_bounds(program)
    colors = state_colors(printout)
    default_width = float(printout.info.settings.get("bead_width", DEFAULT_WIDTH_MM))
    fig = Figure(figsize=(w / DPI, h / DPI), dpi=DPI, facecolor=FIGURE_COLOR)
    cell_w, cell_h = w / cols, (h - 10) / rows
    for i, layer in enumerate(layers):
        r, c = divmod(i, cols)
        box = (c * cell_w + 8, h - 10 - (r + 1) * cell_h + 8, cell_w - 16, cell_h - 30)
        layout = plan_layout(bounds, box, 1, 0)
        ax = _axes(fig, layout.panels[0], bounds, (w, h))
        ax.set_xticks([])
        ax.set_yticks([])
        draw_layer(ax, printout, colors, layer, layout.px_per_mm, default_width=default_width)
        z_top, _ = layer_z(program, layer)
        ax.set_title(f"layer {layer}" + (f", z = {z_top:g} mm" if math.isfinite(z_top) else ""), fontsize=9)
    return _png(fig)


def render_sheet(program, out_png, *, count: int = 9, size: tuple[int, int] = (1200, 1200)) -> list[int]:
    """Write a contact sheet: ``count`` evenly spaced layers on one PNG, all at one scale.

    Returns the layers drawn. Raises like :func:`render_layer`.
    """
    check_writable(out_png)
    printout = load_printout(program)
    _write(out_png, sheet_png(printout, count=count, size=size))
    return sheet_layers(printout.program, count)
