"""A one-file HTML report of a slice: settings, statistics, contact sheet, palette, warnings, fidelity.

The page is self-contained: images are inlined as base64 PNG ``data:`` URIs, the style
sheet is inline, and there are no links to anything outside the file, so it can be
mailed or archived next to the G-code. It is written atomically
(:func:`fgslice.output.atomic_output`).
"""

from __future__ import annotations

import base64
import html
import io
import math
from collections.abc import Mapping
from datetime import datetime, timezone

import numpy as np

from fgslice.design.base import Design
from fgslice.machine.gcode import fgslice_version, format_duration
from fgslice.machine.gcode_header import GcodeHeader
from fgslice.machine.gcode_reader import GcodeProgram
from fgslice.output import atomic_output, check_writable
from fgslice.preview.colors import load_printout, materials_rgba, mix_rgba
from fgslice.preview.layers import sheet_png
from fgslice.preview.thumbnails import thumbnail_png
from fgslice.slicing.palette import Palette
from fgslice.slicing.states import StatePalette

STYLE = """
body { font-family: system-ui, sans-serif; margin: 2em auto; max-width: 1100px; color: #222; }
h1 { font-size: 1.5em; } h2 { font-size: 1.2em; border-bottom: 1px solid #ccc; padding-bottom: .2em; margin-top: 1.6em; }
table { border-collapse: collapse; font-size: .9em; }
td, th { border: 1px solid #ddd; padding: .2em .6em; text-align: left; vertical-align: top; }
th { background: #f3f3f3; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
.swatch { display: inline-block; width: 1.4em; height: 1.4em; border: 1px solid #555; vertical-align: middle; }
.order .swatch { width: 1.1em; height: 1.1em; margin: 0 1px; }
img { max-width: 100%; height: auto; border: 1px solid #ddd; }
.warn { color: #8a4b00; }
.settings { columns: 2; }
"""

STAT_ROWS = (
    ("layers", "layers", "{:d}"),
    ("colors", "palette colors", "{:d}"),
    ("colors_used", "colors used", "{:d}"),
    ("strategy", "strategy", "{}"),
    ("extruded_mm3", "extruded volume (cm³)", "mm3_to_cm3"),
    ("filament_mm", "filament (m)", "mm_to_m"),
    ("filament_g", "filament (g)", "{:.1f}"),
    ("travel_mm", "travel (m)", "mm_to_m"),
    ("state_changes", "state changes", "{:d}"),
    ("retractions", "retractions", "{:d}"),
    ("estimated_time_s", "estimated printing time", "duration"),
    ("purge_mm3", "purge volume (cm³)", "mm3_to_cm3"),
    ("purge_g", "purge (g)", "{:.2f}"),
    ("purge_waste_share", "purge share of material", "percent"),
    ("tower_mm3", "purge tower volume (cm³)", "mm3_to_cm3"),
    ("tower_g", "purge tower (g)", "{:.2f}"),
    ("purge_tolerance", "purge tolerance (model)", "{:g}"),
    ("uncovered_mm2", "area left unfilled (mm², all layers)", "{:.2f}"),
    ("reassigned_mm2", "narrow area given to a neighbouring color (mm², all layers)", "{:.2f}"),
    ("lookahead_mm", "look-ahead (mm)", "{:g}"),
    ("elapsed_s", "slicing time (s)", "{:.1f}"),
)


def _format(value, how: str) -> str:
    if how == "mm3_to_cm3":
        return f"{value / 1000:.2f}"
    if how == "mm_to_m":
        return f"{value / 1000:.2f}"
    if how == "duration":
        return format_duration(float(value))
    if how == "percent":
        return f"{100 * value:.1f} %"
    try:
        return how.format(value)
    except (ValueError, TypeError):
        return str(value)


def _png_tag(png: bytes, alt: str) -> str:
    return f'<img alt="{html.escape(alt)}" src="data:image/png;base64,{base64.b64encode(png).decode("ascii")}">'


def _hex(rgba: np.ndarray) -> str:
    r, g, b = (int(round(255 * c)) for c in rgba[:3])
    return f"#{r:02x}{g:02x}{b:02x}"


def _table(rows: list[tuple[str, str]], numeric: bool = True) -> str:
    cls = ' class="num"' if numeric else ""
    body = "".join(f"<tr><th>{html.escape(k)}</th><td{cls}>{html.escape(v)}</td></tr>" for k, v in rows)
    return f"<table>{body}</table>"


def _settings_section(settings) -> str:
    values = settings.as_dict() if hasattr(settings, "as_dict") else dict(settings)
    rows = [(k, str(v).replace("\n", " | ")) for k, v in values.items()]
    return f'<section id="settings"><h2>Settings</h2><div class="settings">{_table(rows, numeric=False)}</div></section>'


def _stats_section(stats: Mapping) -> str:
    rows = [(label, _format(stats[key], how)) for key, label, how in STAT_ROWS if stats.get(key) is not None]
    bbox = stats.get("extrusion_bbox")
    if bbox:
        (x0, y0, z0), (x1, y1, z1) = bbox
        rows.append(("extrusion box (mm)", f"X {x0:g}-{x1:g}, Y {y0:g}-{y1:g}, Z {z0:g}-{z1:g}"))
    by_color = stats.get("extruded_mm3_by_color") or {}
    extra = ""
    if by_color:
        cells = "".join(f"<tr><td>{html.escape(str(c))}</td><td class=\"num\">{v / 1000:.3f}</td></tr>"
                        for c, v in sorted(by_color.items(), key=lambda kv: int(kv[0])))
        extra = f"<h3>Volume by color</h3><table><tr><th>color</th><th>cm³</th></tr>{cells}</table>"
    return f'<section id="statistics"><h2>Statistics</h2>{_table(rows)}{extra}</section>'


def _palette_section(palette: Palette | StatePalette, materials, dialect) -> str:
    names = [m.name for m in materials] if materials else [chr(65 + i) for i in range(palette.n_materials)]
    rgba = mix_rgba(palette.centers, materials_rgba(materials)) if materials else None
    rows = []
    for c in range(palette.size):
        swatch = f'<span class="swatch" style="background:{_hex(rgba[c])}"></span>' if rgba is not None else ""
        label = " / ".join(f"{n} {100 * f:.3g}%" for n, f in zip(names, palette.centers[c]))
        if isinstance(palette, StatePalette):
            label += f" @ {palette.temperatures[c]:g} C"
        commands = html.escape(dialect.describe(c)) if dialect is not None else ""
        rows.append(f"<tr><td class=\"num\">{c}</td><td>{swatch}</td><td>{html.escape(label)}</td><td><code>{commands}</code></td></tr>")
    head = "<tr><th>color</th><th></th><th>composition</th><th>commands</th></tr>"
    order = "".join(
        f'<span class="swatch" title="{c}" style="background:{_hex(rgba[c])}"></span>' if rgba is not None else f"{c} "
        for c in palette.order.tolist()
    )
    return (f'<section id="palette"><h2>Palette</h2><p>{palette.size} colors of {palette.n_materials} materials'
            f'{", dialect " + html.escape(dialect.name) if dialect is not None else ""}.</p>'
            f"<table>{head}{''.join(rows)}</table>"
            f'<h3>Traversal order</h3><p class="order">{order}</p>'
            f"<p>Even layers print colors in this order ({' &rarr; '.join(map(str, palette.order.tolist()))}); "
            f"odd layers reverse it, so each layer starts with the color the previous one ended with.</p></section>")


def _warnings_section(stats: Mapping) -> str:
    warnings = list(stats.get("warnings") or [])
    if not warnings:
        return '<section id="warnings"><h2>Warnings</h2><p>None.</p></section>'
    items = "".join(f'<li class="warn">{html.escape(str(w))}</li>' for w in warnings)
    return f'<section id="warnings"><h2>Warnings</h2><ul>{items}</ul></section>'


def _layer_error_png(per_layer: list) -> bytes:
    from matplotlib.figure import Figure

    values = np.array([math.nan if v is None else v for v in per_layer], dtype=float)
    fig = Figure(figsize=(7, 2.4), dpi=100)
    ax = fig.add_axes((0.09, 0.2, 0.88, 0.7))
    ax.plot(np.arange(len(values)), values, color="#b03a2e", linewidth=1.2)
    ax.set_xlabel("layer", fontsize=8)
    ax.set_ylabel("mean error", fontsize=8)
    ax.tick_params(labelsize=7)
    ax.grid(alpha=0.3)
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png")
    return buffer.getvalue()


def _fidelity_section(fidelity: Mapping) -> str:
    rows = []
    for key, value in fidelity.items():
        if isinstance(value, (list, tuple, dict)):
            continue
        if isinstance(value, float):
            text = f"{value:.4g}"
        else:
            text = "n/a" if value is None else str(value)
        rows.append((key.replace("_", " "), text))
    plot = ""
    per_layer = fidelity.get("layer_mean_error")
    if per_layer and any(v is not None for v in per_layer):
        plot = "<h3>Mean composition error per layer</h3>" + _png_tag(_layer_error_png(per_layer), "error per layer")
    return (f'<section id="fidelity"><h2>Simulated fidelity</h2><p>What the dead-volume model predicts the printer '
            f"deposits, compared with the design (errors are fractions 0-1, ΔE00 color differences).</p>"
            f"{_table(rows)}{plot}</section>")


def report_html(*, stats: Mapping, settings, palette: Palette, dialect, program, design: Design | None = None,
                fidelity: Mapping | None = None, title: str | None = None) -> str:
    """The report's HTML text (see :func:`write_report`)."""
    info = None
    design_materials = list(design.materials) if design is not None else None
    if isinstance(program, GcodeProgram):
        info = GcodeHeader(colors=palette.size, dialect=getattr(settings, "dialect", None))
    printout = load_printout(program, info, design_materials if info is not None else None)
    materials = printout.materials or design_materials
    title = title or (f"fgslice report: {printout.name}" if printout.name else "fgslice report")
    now = datetime.now(timezone.utc)
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        f"<title>{html.escape(title)}</title><style>{STYLE}</style></head><body>",
        f"<h1>{html.escape(title)}</h1>",
        f"<p>fgslice {html.escape(fgslice_version())}, {now:%Y-%m-%d %H:%M} UTC.</p>",
    ]
    if design is not None:
        parts.append('<section id="design"><h2>Design</h2>' + _png_tag(thumbnail_png(design, 440, 248), "design view")
                     + "</section>")
    parts += [
        _stats_section(stats),
        _warnings_section(stats),
        '<section id="sheet"><h2>Layers</h2><p>Toolpaths at their real width, colored by the commanded state.</p>'
        + _png_tag(sheet_png(printout, count=9, size=(1100, 1100)), "contact sheet") + "</section>",
        _palette_section(palette, materials, dialect),
    ]
    if fidelity is not None:
        parts.append(_fidelity_section(fidelity))
    parts += [_settings_section(settings), "</body></html>"]
    return "\n".join(parts)


def write_report(path, *, stats: Mapping, settings, palette: Palette, dialect, program, design: Design | None = None,
                 fidelity: Mapping | None = None) -> None:
    """Write the HTML report of a slice to ``path`` (one self-contained file).

    Args:
        path: the ``.html`` file to write (atomically).
        stats: the slice statistics (``SliceResult.stats``).
        settings: the :class:`~fgslice.settings.Settings` used.
        palette: the :class:`~fgslice.slicing.palette.Palette` used.
        dialect: the :class:`~fgslice.machine.dialects.Dialect` (its commands per color), or None.
        program: the G-code: a path (its header supplies materials and placement), a
            :class:`~fgslice.preview.colors.Printout`, or a read ``GcodeProgram``.
        design: adds a view of the design and supplies material colors.
        fidelity: simulated fidelity, e.g. ``fgslice.analysis.fidelity.simulation_stats(...)``
            or ``FidelityReport.as_dict()``.

    Raises:
        OutputError: the folder does not exist or cannot be written.
        GcodeError: the G-code cannot be read.
    """
    check_writable(path)
    text = report_html(stats=stats, settings=settings, palette=palette, dialect=dialect, program=program,
                       design=design, fidelity=fidelity)
    with atomic_output(path) as handle:
        handle.write(text)
