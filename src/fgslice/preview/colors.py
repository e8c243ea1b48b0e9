"""Display colors of what a G-code commands, for previews.

Mixtures are drawn as the volume-weighted mix of their materials' colors in linear-light
sRGB (the same model as :mod:`fgslice.analysis.fidelity`): each material's sRGB is
decoded to linear light, mixed by the fractions, and encoded back. Alpha mixes linearly.

What a file's moves mean comes from its header comments, written by
:class:`fgslice.machine.gcode.GcodeWriter` (``; materials = blue,yellow``,
``; colors = N``, ``; dialect = ...``, ``; placement_offset = dx,dy,dz``,
``; temperature_a = ...``): :class:`PrintInfo`. A state is colored

* ``mix`` (marlin-mixing dialects, or any file with ``M165``/``M163``): by its mixing
  factors, normalized;
* ``tool`` (toolchanger): tool ``n`` as palette color ``n``'s center, blended;
* ``state`` (template dialect, or ``;STATE:<n>`` comments only): palette color ``n``;
* ``temperature``: by the nozzle target on a colormap (drawn with a colorbar);
* ``single``: one color, when nothing distinguishes the moves.

States that command nothing known (moves before the first state change) are gray.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass, field

import numpy as np

from fgslice.design.base import Material
from fgslice.design.materials import builtin_library
from fgslice.errors import DesignError, GcodeError
from fgslice.machine.gcode_reader import GcodeProgram, read_gcode
from fgslice.slicing.palette import Palette

UNKNOWN_RGBA = (0.62, 0.62, 0.62, 1.0)
SINGLE_RGBA = (0.93, 0.45, 0.10, 1.0)
TEMPERATURE_CMAP = "coolwarm"
DEFAULT_MATERIALS = ("cyan", "magenta", "yellow", "black", "red", "green")
_HEADER_LINE = re.compile(r"^;\s*([A-Za-z_][A-Za-z0-9_]*)\s*=\s*(.*?)\s*$")
_COLOR_LINE = re.compile(r"^;\s*color\s+(\d+)\s*=\s*(.*?)\s*(?::\s*(.*))?$")
_HEADER_BYTES = 1 << 20


def srgb_to_linear(c: np.ndarray) -> np.ndarray:
    """sRGB (0-1) to linear light (IEC 61966-2-1 transfer function)."""
    c = np.asarray(c, dtype=float)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(c: np.ndarray) -> np.ndarray:
    """Linear light (0-1) to sRGB (0-1), clipped to [0, 1]."""
    c = np.clip(np.asarray(c, dtype=float), 0.0, 1.0)
    return np.where(c <= 0.0031308, c * 12.92, 1.055 * c ** (1 / 2.4) - 0.055)


def mix_rgba(fractions: np.ndarray, rgba: np.ndarray) -> np.ndarray:
    """Display RGBA ``(..., 4)`` in [0, 1] of mixtures ``(..., k)`` of materials ``rgba`` ``(k, 4)``.

    RGB mixes in linear light, alpha linearly; fractions are used as given (callers
    normalize them).
    """
    rgba = np.asarray(rgba, dtype=float)
    f = np.asarray(fractions, dtype=float)
    rgb = linear_to_srgb(f @ srgb_to_linear(rgba[:, :3]))
    alpha = np.clip(f @ rgba[:, 3], 0.0, 1.0)
    return np.concatenate([rgb, alpha[..., None]], axis=-1)


def materials_rgba(materials: list[Material]) -> np.ndarray:
    """``(k, 4)`` RGBA of ``materials``."""
    return np.array([m.rgba for m in materials], dtype=float).reshape(-1, 4)


def fraction_label(fractions: np.ndarray, names: list[str]) -> str:
    """``"yellow 37.5% / blue 62.5%"`` for one composition (percent to 0.1, zeros left out)."""
    parts = [f"{n} {100 * f:.3g}%" for n, f in zip(names, np.asarray(fractions, dtype=float)) if f > 5e-4]
    return " / ".join(parts) or "none"


@dataclass(frozen=True)
class PrintInfo:
    """What a G-code file's header says about its colors (all optional).

    Attributes:
        materials: the design's materials, in the order of the mixing channels.
        colors: palette size N.
        dialect: the machine dialect name (``marlin-mixing``, ``toolchanger``, ...).
        placement_offset: ``bed = design + offset``, mm.
        temperature_a: nozzle target at 100 % of the first material, degC.
        temperature_b: nozzle target at 100 % of the second material, degC.
        labels: palette color index -> its label (``; color i = label : commands``).
        commands: palette color index -> the commands that set it.
        settings: every ``; key = value`` comment, as text.
    """

    materials: list[Material] | None = None
    colors: int | None = None
    dialect: str | None = None
    placement_offset: tuple[float, float, float] | None = None
    temperature_a: float | None = None
    temperature_b: float | None = None
    labels: dict[int, str] = field(default_factory=dict)
    commands: dict[int, str] = field(default_factory=dict)
    settings: dict[str, str] = field(default_factory=dict)


def _number(values: dict[str, tuple[str, int]], key: str, file: str | None) -> float | None:
    if key not in values:
        return None
    text, line = values[key]
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not np.isfinite(value):
        raise GcodeError(f"header '{key}' value '{text}' is not a number", file=file, line=line)
    return value


def parse_header(text: str, file: str | None = None) -> PrintInfo:
    """The :class:`PrintInfo` of G-code ``text`` (its comments before the first layer change).

    Raises:
        GcodeError: a header value fgslice wrote is malformed (line given), or names an
            unknown material.
    """
    head = text.split(";LAYER_CHANGE", 1)[0]
    values: dict[str, tuple[str, int]] = {}
    labels: dict[int, str] = {}
    commands: dict[int, str] = {}
    for number, line in enumerate(head.splitlines(), 1):
        match = _COLOR_LINE.match(line)
        if match:
            labels.setdefault(int(match.group(1)), match.group(2))
            commands.setdefault(int(match.group(1)), match.group(3) or "")
            continue
        match = _HEADER_LINE.match(line)
        if match:
            values.setdefault(match.group(1), (match.group(2), number))
    materials = None
    if values.get("materials", ("", 0))[0]:
        names, line = values["materials"]
        library = builtin_library()
        try:
            materials = [library.get(n.strip()) for n in names.split(",")]
        except DesignError as exc:
            raise GcodeError(f"header 'materials': {exc.message}", file=file, line=line, hint=exc.hint) from None
    colors = None
    if "colors" in values:
        text_value, line = values["colors"]
        if not text_value.isdigit() or int(text_value) < 1:
            raise GcodeError(f"header 'colors' value '{text_value}' is not a palette size", file=file, line=line)
        colors = int(text_value)
    offset = None
    if "placement_offset" in values:
        text_value, line = values["placement_offset"]
        try:
            parts = tuple(float(p) for p in text_value.split(","))
        except ValueError:
            parts = ()
        if len(parts) != 3 or not np.all(np.isfinite(parts)):
            raise GcodeError(f"header 'placement_offset' value '{text_value}' is not three numbers", file=file,
                             line=line, hint="expected '; placement_offset = dx,dy,dz' in mm")
        offset = parts
    return PrintInfo(
        materials=materials,
        colors=colors,
        dialect=values["dialect"][0] if "dialect" in values else None,
        placement_offset=offset,
        temperature_a=_number(values, "temperature_a", file),
        temperature_b=_number(values, "temperature_b", file),
        labels=labels,
        commands=commands,
        settings={k: v for k, (v, _) in values.items()},
    )


@dataclass(frozen=True)
class Printout:
    """A read G-code file: its moves and what its header says."""

    program: GcodeProgram
    info: PrintInfo
    name: str | None = None


def load_printout(source: str | os.PathLike | bytes | GcodeProgram | Printout, info: PrintInfo | None = None) -> Printout:
    """A :class:`Printout` from a G-code path, its bytes or text, a read program or a printout.

    ``info`` replaces the header's (needed for a bare :class:`GcodeProgram`, which has
    no header; without it such a program is drawn without material colors).

    Raises:
        GcodeError: not readable G-code, or a malformed header.
    """
    if isinstance(source, Printout):
        return source if info is None else Printout(source.program, info, source.name)
    if isinstance(source, GcodeProgram):
        return Printout(source, info or PrintInfo())
    name = None
    if isinstance(source, bytes):
        head = source[:_HEADER_BYTES].decode("utf-8", errors="replace")
    elif isinstance(source, os.PathLike) or ("\n" not in source and os.path.isfile(source)):
        name = str(source)
        try:
            with open(source, "rb") as handle:
                head = handle.read(_HEADER_BYTES).decode("utf-8", errors="replace")
        except OSError as exc:
            raise GcodeError(f"cannot read G-code: {exc.strerror}", file=name) from None
    elif "\n" not in source:
        raise GcodeError(f"G-code file not found: {source}", file=source)
    else:
        head = source[:_HEADER_BYTES]
    program = read_gcode(source)
    return Printout(program, info or parse_header(head, name), name)


@dataclass(frozen=True)
class StateColors:
    """Display colors of a program's states.

    Attributes:
        mode: ``mix``, ``tool``, ``state``, ``temperature`` or ``single``.
        rgba: ``(len(program.states), 4)`` color of each state.
        key: ``(len(program.states),)`` legend key of each state (-1: unknown state);
            for ``temperature``, the index of the state itself.
        labels: legend key -> label.
        value: ``(len(program.states),)`` nozzle target per state (``temperature`` mode), degC.
        value_range: colormap limits of ``temperature`` mode, degC.
    """

    mode: str
    rgba: np.ndarray
    key: np.ndarray
    labels: dict[int, str]
    value: np.ndarray | None = None
    value_range: tuple[float, float] | None = None


def _mode(printout: Printout) -> str:
    dialect = printout.info.dialect or ""
    states = printout.program.states
    if dialect.startswith("marlin-mixing"):
        return "mix"
    if dialect in ("toolchanger", "temperature"):
        return "tool" if dialect == "toolchanger" else "temperature"
    if dialect == "template":
        return "state"
    if any(s.mix is not None for s in states):
        return "mix"
    if any(s.color is not None for s in states):
        return "state"
    if len({s.tool for s in states}) > 1:
        return "tool"
    if len({s.temperature for s in states if s.temperature is not None}) > 1:
        return "temperature"
    return "single"


def _materials(printout: Printout, k: int) -> list[Material]:
    """The header's materials, else ``k`` default ones (cyan, magenta, yellow, ...)."""
    if printout.info.materials:
        return printout.info.materials
    library = builtin_library()
    return [library.get(DEFAULT_MATERIALS[i % len(DEFAULT_MATERIALS)]) for i in range(k)]


def _palette_colors(printout: Printout, index: np.ndarray) -> tuple[np.ndarray, dict[int, str]]:
    """RGBA and labels of palette colors ``index`` (``-1`` unknown), from the header's palette."""
    info = printout.info
    known = index >= 0
    out = np.tile(UNKNOWN_RGBA, (len(index), 1))
    labels: dict[int, str] = {}
    if info.materials and info.colors:
        palette = Palette(len(info.materials), info.colors)
        names = [m.name for m in info.materials]
        valid = known & (index < palette.size)
        out[valid] = mix_rgba(palette.centers[index[valid]], materials_rgba(info.materials))
        labels = {int(c): fraction_label(palette.centers[c], names) for c in np.unique(index[valid])}
    else:
        from matplotlib import colormaps

        cmap = colormaps["tab20"]
        out[known] = cmap(index[known] % cmap.N)
        labels = {int(c): info.labels.get(int(c), f"color {c}") for c in np.unique(index[known])}
    return out, labels


def state_colors(printout: Printout) -> StateColors:
    """The display color of every state of ``printout.program`` (see the module docstring)."""
    states = printout.program.states
    n = len(states)
    mode = _mode(printout)
    if mode == "mix":
        k = max([len(printout.info.materials or ())] + [len(s.mix) for s in states if s.mix is not None])
        materials = _materials(printout, k)
        k = len(materials)
        fractions = np.zeros((n, k))
        has = np.zeros(n, dtype=bool)
        for i, s in enumerate(states):
            if s.mix is not None:
                fractions[i, : min(k, len(s.mix))] = np.clip(s.mix[:k], 0.0, None)
                has[i] = fractions[i].sum() > 0
        fractions[has] /= fractions[has].sum(axis=1, keepdims=True)
        rgba = np.tile(UNKNOWN_RGBA, (n, 1))
        rgba[has] = mix_rgba(fractions[has], materials_rgba(materials))
        _, first, key = np.unique(np.round(fractions, 4), axis=0, return_index=True, return_inverse=True)
        key = np.where(has, key.reshape(-1), -1)
        names = [m.name for m in materials]
        labels = {int(key[i]): fraction_label(fractions[i], names) for i in first if has[i]}
        return StateColors(mode, rgba, key, labels)
    if mode in ("tool", "state"):
        index = np.array([s.tool if mode == "tool" else (-1 if s.color is None else s.color) for s in states])
        rgba, labels = _palette_colors(printout, index)
        if mode == "tool":
            labels = {c: f"T{c}: {text}" for c, text in labels.items()}
        return StateColors(mode, rgba, index, labels)
    if mode == "temperature":
        from matplotlib import colormaps

        value = np.array([np.nan if s.temperature is None else s.temperature for s in states])
        info = printout.info
        if info.temperature_a is not None and info.temperature_b is not None and info.temperature_a != info.temperature_b:
            lo, hi = sorted((info.temperature_a, info.temperature_b))
        else:
            finite = value[np.isfinite(value)]
            lo, hi = (float(finite.min()), float(finite.max())) if len(finite) else (0.0, 1.0)
            hi = hi if hi > lo else lo + 1.0
        rgba = np.tile(UNKNOWN_RGBA, (n, 1))
        known = np.isfinite(value)
        rgba[known] = colormaps[TEMPERATURE_CMAP]((value[known] - lo) / (hi - lo))
        return StateColors(mode, rgba, np.where(known, np.arange(n), -1), {}, value, (lo, hi))
    return StateColors(mode, np.tile(SINGLE_RGBA, (n, 1)), np.zeros(n, dtype=np.int64), {0: "extrusion"})
