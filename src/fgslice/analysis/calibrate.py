"""Look-ahead calibration (Appendix A of the paper).

Two ways to find the look-ahead distance ``L`` (mm of extruded path) that compensates a
hotend's dead volume:

* known melt-chamber volume: ``L = V_melt / A`` with the capsule bead area
  ``A = h (w - h) + pi h^2 / 4`` (:func:`lookahead_from_volume`);
* unknown volume: print the calibration object (:func:`calibration_plan`,
  :func:`write_calibration`) — a serpentine rectangle hatched along Y whose state
  changes from material A to material B exactly at its midpoint in X — measure how far
  the visible transition lies from the midpoint (``e_x``) and take
  ``L = ceil(e_x / w) x L_y`` (:func:`lookahead_from_measurement`); repeat with the new
  look-ahead until ``e_x`` vanishes.

Units: mm, mm³.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from fgslice.analysis.simulate import MeltModel, SimulationResult, deposit, trace_from_plans
from fgslice.errors import SettingsError
from fgslice.planning.plan import LayerPlan, SetState
from fgslice.settings import Settings
from fgslice.toolpaths.paths import Path as ToolPath
from fgslice.toolpaths.paths import Role, bead_area

#: Default calibration object: extent along X (mm), line length along Y (mm), layers.
LENGTH_X = 60.0
LENGTH_Y = 20.0
LAYERS = 3


def lookahead_from_volume(melt_volume_mm3: float, bead_width_mm: float, layer_height_mm: float) -> float:
    """Look-ahead ``L = V_melt / A`` (mm) for a known melt-chamber volume (capsule area A)."""
    if melt_volume_mm3 < 0:
        raise SettingsError(f"melt volume must be >= 0 mm^3, got {melt_volume_mm3}")
    if not 0 < layer_height_mm <= bead_width_mm:
        raise SettingsError(
            f"need 0 < layer height ({layer_height_mm} mm) <= bead width ({bead_width_mm} mm)",
            hint="check --set layer_height=... bead_width=...",
        )
    return melt_volume_mm3 / bead_area(bead_width_mm, layer_height_mm)


def lookahead_from_measurement(measured_error_mm: float, segment_length_mm: float, bead_width_mm: float) -> float:
    """Look-ahead ``L = ceil(e_x / w) x L_y`` (mm) from a calibration print.

    Args:
        measured_error_mm: ``e_x``, distance along X between the object's midpoint and
            where the printed transition is seen, mm (its sign is ignored).
        segment_length_mm: ``L_y``, extruded length of one hatch line along Y, mm.
        bead_width_mm: ``w``, hatch spacing, mm.
    """
    if segment_length_mm <= 0 or bead_width_mm <= 0:
        raise SettingsError(
            f"segment length ({segment_length_mm} mm) and bead width ({bead_width_mm} mm) must be > 0"
        )
    # a measurement a hair above a whole number of beads (float noise) does not add a bead
    segments = math.ceil(round(abs(measured_error_mm) / bead_width_mm, 9))
    return segments * segment_length_mm


def format_lookahead(distance_mm: float) -> str:
    """The option line that applies a look-ahead, e.g. ``--set lookahead_mm=959.4``."""
    return f"--set lookahead_mm={distance_mm:.1f}"


def lookahead_advice(
    settings: Settings,
    *,
    measured_error_mm: float | None = None,
    melt_volume_mm3: float | None = None,
    line_length_mm: float = LENGTH_Y,
) -> tuple[float, str]:
    """The look-ahead to use and the lines to print about it.

    With ``measured_error_mm`` (``e_x`` from a calibration print): Appendix A's unknown-
    volume method with ``L_y = line_length_mm``; otherwise the known-volume method with
    ``melt_volume_mm3`` (default ``settings.melt_volume_mm3``) and the settings' bead.

    Returns:
        ``(distance_mm, text)``; the text's last line is the ``--set lookahead_mm=...`` option.
    """
    w, h = settings.bead_width, settings.layer_height
    if measured_error_mm is not None:
        if abs(measured_error_mm) > LENGTH_X / 2:
            raise SettingsError(
                f"measured error e_x = {measured_error_mm:g} mm is larger than half the calibration object "
                f"({LENGTH_X:g} mm wide)",
                hint="measure e_x on the printed object, from its midpoint to where the color changes, in mm",
            )
        distance = lookahead_from_measurement(measured_error_mm, line_length_mm, w)
        lines = round(distance / line_length_mm)
        how = (f"e_x = {abs(measured_error_mm):g} mm: ceil(e_x / w = {w:g} mm) = {lines} lines "
               f"x L_y = {line_length_mm:g} mm = {distance:.1f} mm")
    else:
        volume = settings.melt_volume_mm3 if melt_volume_mm3 is None else melt_volume_mm3
        distance = lookahead_from_volume(volume, w, h)
        how = (f"V_melt = {volume:g} mm^3 / A = {bead_area(w, h):.4f} mm^2 (w = {w:g} mm, h = {h:g} mm) "
               f"= {distance:.1f} mm")
    return distance, f"{how}\n{format_lookahead(distance)}"


def _extreme_colors(centers: np.ndarray) -> tuple[int, int]:
    """Palette colors richest and poorest in the first material (A and B)."""
    return int(np.argmax(centers[:, 0])), int(np.argmin(centers[:, 0]))


def calibration_plan(
    settings: Settings,
    centers: np.ndarray,
    *,
    length_x: float = LENGTH_X,
    length_y: float = LENGTH_Y,
    layers: int = LAYERS,
) -> list[LayerPlan]:
    """Layer plans of Appendix A's calibration object, centered on the bed.

    Each layer is one serpentine of an even number ``n = 2 round(length_x / 2w)`` of
    lines along Y (centerline length ``length_y``, spacing ``w = bead_width``), joined
    by short moves along X. The state is A (the palette color richest in the first
    material) on the half ``x < x_mid`` and B on the other half, changed exactly at
    ``x_mid`` — in the middle of the join between lines ``n/2 - 1`` and ``n/2``. Even
    layers run from -X to +X (A then B), odd layers back (B then A), so every layer has
    exactly one change, at the midpoint.

    Args:
        settings: bead width, layer height, bed size.
        centers: ``(N, k)`` palette centers (:attr:`Palette.centers`).
        length_x: extent of the hatch along X, mm.
        length_y: length of one hatch line along Y (``L_y``), mm.
        layers: number of layers.

    Returns:
        One :class:`LayerPlan` per layer: path, ``SetState``, path (the first layer
        starts with a ``SetState`` of A).
    """
    w, h = settings.bead_width, settings.layer_height
    lines = 2 * max(1, round(length_x / (2 * w)))
    if length_y <= 0 or layers < 1:
        raise SettingsError(f"calibration object needs length_y > 0 and layers >= 1, got {length_y}, {layers}")
    width_x = lines * w
    x0 = settings.bed_x / 2 - width_x / 2
    y0 = settings.bed_y / 2 - length_y / 2
    if x0 < 0 or y0 < 0 or layers * h > settings.max_z:
        raise SettingsError(f"the calibration object ({width_x:g} x {length_y:g} mm) does not fit the bed")
    x = x0 + w / 2 + w * np.arange(lines)
    up = np.arange(lines) % 2 == 0
    y_first = np.where(up, y0, y0 + length_y)
    y_last = np.where(up, y0 + length_y, y0)
    points = np.column_stack([np.repeat(x, 2), np.column_stack([y_first, y_last]).ravel()])
    half = lines  # points of the first half: lines 0 .. n/2 - 1, two points each
    x_mid = x0 + width_x / 2
    cut = np.array([[x_mid, points[half - 1, 1]]])
    first = np.vstack([points[:half], cut])
    second = np.vstack([cut, points[half:]])
    color_a, color_b = _extreme_colors(np.asarray(centers, dtype=float))
    plans = []
    for k in range(layers):
        halves = [(first, color_a), (second, color_b)]
        if k % 2:
            halves = [(second[::-1].copy(), color_b), (first[::-1].copy(), color_a)]
        (pts_1, color_1), (pts_2, color_2) = halves
        steps = [SetState(color_1)] if k == 0 else []
        steps += [
            ToolPath(points=pts_1, role=Role.SOLID_INFILL, color=color_1, width=w, height=h),
            SetState(color_2),
            ToolPath(points=pts_2, role=Role.SOLID_INFILL, color=color_2, width=w, height=h),
        ]
        plans.append(LayerPlan(index=k, z=(k + 1) * h, height=h, steps=steps))
    return plans


def calibration_midpoint(settings: Settings) -> float:
    """Bed X of the calibration object's midpoint (where the state changes), mm."""
    return settings.bed_x / 2


def transition_offsets(result: SimulationResult, midpoint_x: float) -> np.ndarray:
    """Per layer, where the deposited first-material fraction first crosses 0.5, mm.

    Returns ``(layers,)`` distances along the printing direction from the midpoint to
    the middle of the first segment past the crossing (positive: late, as dead volume
    makes it; negative: early, as too much look-ahead makes it); NaN for a layer that
    never crosses. Only segments of the part count.
    """
    part = result.part
    return _crossings(result.deposited[part, 0], result.start[part], result.end[part], result.layer[part], midpoint_x)


def _crossings(fraction_a: np.ndarray, start: np.ndarray, end: np.ndarray, layer: np.ndarray, midpoint_x: float) -> np.ndarray:
    """:func:`transition_offsets` on plain arrays of extrusion segments in printing order."""
    layers = np.unique(layer)
    out = np.full(len(layers), np.nan)
    for i, number in enumerate(layers):
        idx = np.flatnonzero(layer == number)
        f = fraction_a[idx]
        crossed = np.flatnonzero((f >= 0.5) != (f[0] >= 0.5))
        if len(crossed) == 0:
            continue
        direction = np.sign(end[idx[-1], 0] - start[idx[0], 0])
        j = idx[crossed[0]]
        out[i] = direction * ((start[j, 0] + end[j, 0]) / 2 - midpoint_x)
    return out


def predicted_offsets(
    settings: Settings,
    *,
    melt_volume_mm3: float | None = None,
    length_x: float = LENGTH_X,
    length_y: float = LENGTH_Y,
    layers: int = LAYERS,
) -> np.ndarray:
    """Where the calibration print's transition should appear, per layer, mm from the midpoint.

    Simulates the calibration object (with the settings' look-ahead applied) through the
    dialect's model (:mod:`fgslice.analysis.simulate`) without writing G-code; positive
    values lie past the midpoint in the printing direction. A value near 0 means the
    look-ahead compensates ``melt_volume_mm3`` (default ``settings.melt_volume_mm3``).
    """
    from fgslice.planning.lookahead import apply_lookahead

    palette = calibration_palette(settings)
    plans = calibration_plan(settings, palette.centers, length_x=length_x, length_y=length_y, layers=layers)
    distance = settings.lookahead_distance
    trace = trace_from_plans(apply_lookahead(plans, distance) if distance > 0 else plans, palette.centers, settings)
    deposited = deposit(trace, MeltModel.from_settings(settings, melt_volume_mm3))
    extruding = trace.volume > 0
    return _crossings(deposited[:, 0], trace.start[extruding], trace.end[extruding], trace.layer[extruding], calibration_midpoint(settings))


def write_calibration(out_path: str | Path, settings: Settings, *, length_x: float = LENGTH_X, length_y: float = LENGTH_Y, layers: int = LAYERS) -> dict:
    """Write the calibration object's G-code with the machine writer; return its statistics.

    The settings' look-ahead (``lookahead_mm``, ``auto`` included) is applied, so a
    print after :func:`lookahead_from_measurement` shows the remaining error. The
    palette is the one a slice would use (``colors``, or ``tool_count`` for a
    toolchanger); A and B are its colors richest and poorest in the first material.
    """
    from fgslice.machine.dialects import make_dialect
    from fgslice.machine.gcode import GcodeWriter
    from fgslice.output import atomic_output, check_writable
    from fgslice.planning.lookahead import apply_lookahead

    target = check_writable(out_path)
    palette = calibration_palette(settings)
    plans = calibration_plan(settings, palette.centers, length_x=length_x, length_y=length_y, layers=layers)
    distance = settings.lookahead_distance
    planned = apply_lookahead(plans, distance) if distance > 0 else iter(plans)
    comments = {
        "calibration": "look-ahead (Appendix A): state change at the midpoint in X",
        "calibration_line_length_y": f"{length_y:g}",
        "calibration_midpoint_x": f"{calibration_midpoint(settings):g}",
        "lookahead_applied_mm": f"{distance:g}",
    }
    with atomic_output(target) as handle:
        writer = GcodeWriter(handle, settings, palette, make_dialect(settings, palette), comments=comments)
        writer.write_header()
        for plan in planned:
            writer.write_layer(plan)
        return writer.finish()


def calibration_palette(settings: Settings):
    """The palette a slice with these settings uses (materials = channels for mixing)."""
    from fgslice.slicing.palette import Palette

    materials = settings.channels if settings.dialect.endswith(("-mixing", "-mixing-m163")) else 2
    size = settings.tool_count if settings.dialect == "toolchanger" else settings.colors
    return Palette(materials, size, settings.palette)
