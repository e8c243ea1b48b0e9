"""Display colors of what a G-code commands, for previews.

Mixtures are drawn as the volume-weighted mix of their materials' colors in linear-light
sRGB (:mod:`fgslice.colors`, the same model as :mod:`fgslice.analysis.fidelity`).

What a file's moves mean comes from its header comments, written by
:class:`fgslice.machine.gcode.GcodeWriter` (``; materials = blue,yellow``,
``; colors = N``, ``; dialect = ...``, ``; placement_offset = dx,dy,dz``,
``; temperature_a = ...``), read by :mod:`fgslice.machine.gcode_header`. A state is colored

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
from dataclasses import dataclass

import numpy as np

from fgslice.colors import materials_rgba, mix_rgba
from fgslice.design.base import Material
from fgslice.design.materials import MaterialLibrary, builtin_library
from fgslice.design.nodes import DEFAULT_MATERIAL
from fgslice.errors import DesignError, GcodeError
from fgslice.machine.gcode_header import GcodeHeader, parse_header, read_header
from fgslice.machine.gcode_reader import GcodeProgram, read_gcode
from fgslice.slicing.states import header_palette, material_palette

UNKNOWN_RGBA = (0.62, 0.62, 0.62, 1.0)
SINGLE_RGBA = (0.93, 0.45, 0.10, 1.0)
TEMPERATURE_CMAP = "coolwarm"
DEFAULT_MATERIALS = ("cyan", "magenta", "yellow", "black", "red", "green")
_HEADER_BYTES = 1 << 20


def fraction_label(fractions: np.ndarray, names: list[str]) -> str:
    """``"yellow 37.5% / blue 62.5%"`` for one composition (percent to 0.1, zeros left out)."""
    parts = [f"{n} {100 * f:.3g}%" for n, f in zip(names, np.asarray(fractions, dtype=float)) if f > 5e-4]
    return " / ".join(parts) or "none"


@dataclass(frozen=True)
class Printout:
    """A read G-code file: its moves, what its header says and the materials it prints.

    Attributes:
        program: the moves.
        info: the header comments (empty for a bare program).
        name: the file name, if read from a file.
        materials: the header's materials looked up in the built-in library, or the
            design's; None when unknown.
    """

    program: GcodeProgram
    info: GcodeHeader
    name: str | None = None
    materials: list[Material] | None = None


def header_materials(info: GcodeHeader, file: str | None = None,
                     library: MaterialLibrary | None = None) -> list[Material] | None:
    """The materials named by the header's ``; materials = a,b``, or None without it, looked
    up in ``library`` (default the built-in one; a materials file's for its own names);
    ``default`` is the material of a design that names none.

    Raises:
        GcodeError: a name the library does not know (with the header line).
    """
    if not info.materials:
        return None
    library = library or builtin_library()
    try:
        return [DEFAULT_MATERIAL if name == DEFAULT_MATERIAL.name else library.get(name) for name in info.materials]
    except DesignError as exc:
        raise GcodeError(f"header 'materials': {exc.message}", file=file, line=info.lines.get("materials"),
                         hint="give the materials file the design was sliced with (--materials FILE)") from None


def _read_source_header(source: str | os.PathLike | bytes) -> tuple[str | None, GcodeHeader]:
    """The file name (None for bytes or text) and header of G-code given as a path, bytes or text."""
    if isinstance(source, bytes):
        return None, parse_header(source[:_HEADER_BYTES].decode("utf-8", errors="replace"))
    if isinstance(source, os.PathLike) or ("\n" not in source and os.path.isfile(source)):
        return str(source), read_header(source)
    if "\n" not in source:
        raise GcodeError(f"G-code file not found: {source}", file=source)
    return None, parse_header(source)


def load_printout(source: str | os.PathLike | bytes | GcodeProgram | Printout, info: GcodeHeader | None = None,
                  materials: list[Material] | None = None, library: MaterialLibrary | None = None) -> Printout:
    """A :class:`Printout` from a G-code path, its bytes or text, a read program or a printout.

    ``info`` replaces the header's (needed for a bare :class:`GcodeProgram`, which has
    no header; without it such a program is drawn without material colors);
    ``materials`` replaces the header's materials (e.g. the design's own); ``library``
    resolves the header's material names (default the built-in library).

    Raises:
        GcodeError: not readable G-code, or a malformed header.
    """
    if isinstance(source, Printout):
        if info is None:
            return Printout(source.program, source.info, source.name, materials or source.materials)
        program, name, header = source.program, source.name, info
    elif isinstance(source, GcodeProgram):
        program, name, header = source.split_arcs(), None, GcodeHeader()
    else:
        name, header = _read_source_header(source)
        program = read_gcode(source).split_arcs()  # arcs as the straight pieces the firmware prints
    info = info or header
    return Printout(program, info, name, materials or header_materials(info, name, library))


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
    if printout.materials:
        return printout.materials
    library = builtin_library()
    return [library.get(DEFAULT_MATERIALS[i % len(DEFAULT_MATERIALS)]) for i in range(k)]


def _palette_colors(printout: Printout, index: np.ndarray, tools: bool = False) -> tuple[np.ndarray, dict[int, str]]:
    """RGBA and labels of palette colors ``index`` (``-1`` unknown), from the header's
    palette; with ``tools``, of tools (a toolchanger's tool n prints material color n)."""
    info = printout.info
    known = index >= 0
    out = np.tile(UNKNOWN_RGBA, (len(index), 1))
    labels: dict[int, str] = {}
    if printout.materials and info.colors:
        palette = header_palette(len(printout.materials), info.colors, info.palette, info.settings.get("temperature_levels"))
        palette = material_palette(palette) if tools else palette
        names = [m.name for m in printout.materials]
        valid = known & (index < palette.size)
        out[valid] = mix_rgba(palette.centers[index[valid]], materials_rgba(printout.materials))
        labels = {int(c): fraction_label(palette.centers[c], names) for c in np.unique(index[valid])}
        # states outside the palette the header names (the support's tool): gray, with their label
        labels.update({int(c): info.labels[int(c)] for c in np.unique(index[known & ~valid]) if int(c) in info.labels})
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
        k = max([len(printout.materials or ())] + [len(s.mix) for s in states if s.mix is not None])
        materials = _materials(printout, k)
        k = len(materials)
        fractions = np.zeros((n, k))
        has = np.zeros(n, dtype=bool)
        for i, s in enumerate(states):
            mix = s.mix_fractions(k)
            if mix is not None:
                fractions[i], has[i] = mix, True
        rgba = np.tile(UNKNOWN_RGBA, (n, 1))
        rgba[has] = mix_rgba(fractions[has], materials_rgba(materials))
        _, first, key = np.unique(np.round(fractions, 4), axis=0, return_index=True, return_inverse=True)
        key = np.where(has, key.reshape(-1), -1)
        names = [m.name for m in materials]
        labels = {int(key[i]): fraction_label(fractions[i], names) for i in first if has[i]}
        return StateColors(mode, rgba, key, labels)
    if mode in ("tool", "state"):
        index = np.array([s.tool if mode == "tool" else (-1 if s.color is None else s.color) for s in states])
        rgba, labels = _palette_colors(printout, index, tools=mode == "tool")
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
