"""A fast reader of any slicer's G-code, for the commands that matter to fgslice.

:func:`read_gcode` returns a :class:`GcodeProgram`: one row per move in numpy arrays
(start and end position in mm, filament length E in mm, feed rate in mm/min, line number,
layer, role, process state, bead width) plus the events ``verify`` needs (temperature
set points, tool selects, flow and mix commands, fan and PWM outputs, the commands at
which the head may stop with a ``G4``'s dwell).
:func:`iter_gcode` yields the same program in chunks of whole lines (global line
numbers, state carried from chunk to chunk) so that long files are processed in
bounded memory; :func:`read_gcode` joins its chunks.

Understood: ``G0``/``G1`` (X Y Z E F), ``G2``/``G3`` arcs (I J or R; their XY length is
the arc's), ``G28`` (homed axes go to 0), ``G90``/``G91`` (absolute/relative XYZ and
E), ``M82``/``M83`` (absolute/relative E), ``G92`` (set position, including ``G92 E0``),
``T<n>``, ``M165``, ``M163``/``M164``, ``M104``/``M109`` (S, R, T), ``M140``/``M190``,
``M221``, ``M106``/``M107``, ``M42``, and the comments ``;LAYER_CHANGE`` (or Cura's
``;LAYER:<n>``), ``;Z:``, ``;TYPE:``, ``;WIDTH:``, ``;STATE:<n>``. Other commands are
kept as line numbers only (Klipper's extended commands ``NAME KEY=VALUE`` among them).
A number that is not a finite number (``X1e999``, ``Ynan``, ``Eabc``) becomes a
:class:`Fault` and the word is ignored; the reader never raises on such content. A file that is not G-code text (binary, empty, no moves) is a
:class:`~fgslice.errors.GcodeError`.
"""

from __future__ import annotations

import io
import math
import os
import re
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import BinaryIO

import numpy as np

from fgslice.errors import GcodeError

MIX_LETTERS = "ABCDHI"

TEXT_COMMANDS = frozenset({"M16", "M23", "M28", "M30", "M32", "M33", "M117", "M118", "M928",
                           *(f"M{n}" for n in range(810, 820))})
"""Marlin commands whose argument is text (a message, a file name, a macro), not words."""

WAIT_COMMANDS = frozenset({"G4", "M400", "G28", "M109", "M190", "M600", "G92", "ACTIVATE_EXTRUDER",
                           "SYNC_EXTRUDER_MOTION", "SET_EXTRUDER_ROTATION_DISTANCE"})
"""Commands at which a firmware may stop the head (``T<n>`` too); :mod:`.timing` decides
which of them stop it on which firmware."""

ARC_SEGMENT_MM = 1.0
"""Length of the straight pieces a firmware cuts arcs into, mm (Marlin's
``MM_PER_ARC_SEGMENT``, Klipper's ``[gcode_arcs] resolution``)."""

_CODE = re.compile(r"[GMT]\d+(\.\d+)?$")
"""A command word the reader interprets the words of; others (Klipper's and hosts'
extended commands, ``SET_FAN_SPEED FAN=...``) are kept as line numbers only."""


@dataclass(frozen=True)
class Fault:
    """A problem found in a G-code file at 1-based ``line``."""

    line: int
    message: str


@dataclass(frozen=True)
class ArcExtent:
    """The XY box an arc (``G2``/``G3``) sweeps through, mm: ``lo = (x, y)``, ``hi = (x, y)``
    (a full circle reaches its whole diameter, wherever its ends are)."""

    line: int
    lo: tuple[float, float]
    hi: tuple[float, float]


@dataclass(frozen=True)
class MachineState:
    """The process state moves are printed in.

    Attributes:
        mix: mixing factors per channel (A B C D H I order, trailing unset channels
            dropped), or None if no mix was set.
        tool: active tool index.
        temperature: nozzle target of the active tool, degC, or None if never set.
        flow: M221 flow of the active tool, percent.
        color: palette color of the last ``;STATE:<n>`` comment, or None.
    """

    mix: tuple[float, ...] | None = None
    tool: int = 0
    temperature: float | None = None
    flow: float = 100.0
    color: int | None = None

    def mix_fractions(self, k: int) -> np.ndarray | None:
        """The mix as ``(k,)`` fractions summing to 1 (negative factors as 0, channels
        beyond ``k`` dropped, missing ones 0), or None without a mix or with nothing positive."""
        if self.mix is None:
            return None
        out = np.zeros(k)
        given = np.clip(np.asarray(self.mix[:k], dtype=float), 0.0, None)
        out[: len(given)] = given
        total = out.sum()
        return out / total if total > 0 else None


@dataclass(frozen=True)
class TemperatureEvent:
    """``M104``/``M109`` (nozzle) or ``M140``/``M190`` (bed) at ``line``; ``wait`` for M109/M190."""

    line: int
    command: str
    target: float
    tool: int
    wait: bool


@dataclass(frozen=True)
class ValueEvent:
    """A command at ``line`` with its numeric parameters (tool select, flow, mix, fan, PWM)."""

    line: int
    command: str
    values: dict[str, float]


@dataclass
class GcodeProgram:
    """The moves and events of a G-code file. Units mm, mm/min, degC, percent.

    Per move (length M): ``start``/``end`` (M, 3) positions; ``e`` (M,) filament mm
    (relative, as commanded, before M221); ``feed`` (M,) mm/min; ``length`` (M,) XY path
    length (arc length for G2/G3); ``line`` (M,) 1-based line numbers; ``layer`` (M,)
    0-based layer (-1 before the first layer change); ``role`` (M,) index into
    ``roles`` (-1 if none); ``state`` (M,) index into ``states``; ``width`` (M,) the last
    ``;WIDTH:`` (NaN if none). ``waits``: ``(line, command, dwell s)`` of each command at
    which the head may stop (:data:`WAIT_COMMANDS`; ``T<n>`` as ``T``; the dwell of a ``G4``).
    ``arc_centre`` (M, 2): the centre of each ``G2``/``G3`` move (NaN for straight moves);
    ``arc_turn`` (M,): -1 for ``G2`` (clockwise), 1 for ``G3``, 0 for straight moves; readers
    of the path's shape take :meth:`split_arcs`.
    """

    start: np.ndarray
    end: np.ndarray
    e: np.ndarray
    feed: np.ndarray
    length: np.ndarray
    line: np.ndarray
    layer: np.ndarray
    role: np.ndarray
    state: np.ndarray
    width: np.ndarray
    roles: list[str]
    states: list[MachineState]
    layer_z: list[float]
    temperatures: list[TemperatureEvent] = field(default_factory=list)
    tools: list[ValueEvent] = field(default_factory=list)
    flows: list[ValueEvent] = field(default_factory=list)
    mixes: list[ValueEvent] = field(default_factory=list)
    fans: list[ValueEvent] = field(default_factory=list)
    outputs: list[ValueEvent] = field(default_factory=list)
    faults: list[Fault] = field(default_factory=list)
    arcs: list[ArcExtent] = field(default_factory=list)
    waits: list[tuple[int, str, float]] = field(default_factory=list)
    unknown_lines: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    line_count: int = 0
    arc_centre: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    arc_turn: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int8))

    def split_arcs(self, segment_mm: float = ARC_SEGMENT_MM) -> "GcodeProgram":
        """This program with every ``G2``/``G3`` arc cut into the straight moves a firmware
        cuts it into (equal pieces of at most ``segment_mm`` along the arc; Z and E shared
        out by length); every other column repeated for the pieces. Itself without arcs."""
        arcs = np.flatnonzero(self.arc_turn)
        if not len(arcs):
            return self
        centre, start, end = self.arc_centre[arcs], self.start[arcs], self.end[arcs]
        radius = np.hypot(*(start[:, :2] - centre).T)
        usable = np.isfinite(radius) & (radius > 0) & np.isfinite(self.length[arcs])
        counts = np.ones(len(self.e), dtype=np.int64)
        counts[arcs] = np.where(usable, np.maximum(1, np.ceil(np.nan_to_num(self.length[arcs]) / segment_mm)), 1)
        index = np.repeat(np.arange(len(self.e)), counts)
        piece = np.arange(len(index)) - np.repeat(np.cumsum(counts) - counts, counts)
        share = (piece + 1) / counts[index]
        new_end = self.end[index]
        inner = np.flatnonzero(np.repeat(np.isin(np.arange(len(self.e)), arcs[usable]), counts) & (share < 1))
        if len(inner):
            which = np.searchsorted(arcs, index[inner])
            c, r = centre[which], radius[which]
            a0 = np.arctan2(start[which, 1] - c[:, 1], start[which, 0] - c[:, 0])
            angle = a0 + self.arc_turn[index[inner]] * share[inner] * self.length[index[inner]] / r
            new_end[inner, 0] = c[:, 0] + r * np.cos(angle)
            new_end[inner, 1] = c[:, 1] + r * np.sin(angle)
            new_end[inner, 2] = start[which, 2] + share[inner] * (end[which, 2] - start[which, 2])
        new_start = np.roll(new_end, 1, axis=0)
        firsts = piece == 0
        new_start[firsts] = self.start[index[firsts]]
        was_arc = self.arc_turn[index] != 0
        length = np.where(was_arc, np.hypot(*(new_end[:, :2] - new_start[:, :2]).T), self.length[index])
        return GcodeProgram(
            start=new_start, end=new_end, e=self.e[index] / counts[index], feed=self.feed[index], length=length,
            line=self.line[index], layer=self.layer[index], role=self.role[index], state=self.state[index],
            width=self.width[index], roles=self.roles, states=self.states, layer_z=self.layer_z,
            temperatures=self.temperatures, tools=self.tools, flows=self.flows, mixes=self.mixes, fans=self.fans,
            outputs=self.outputs, faults=self.faults, arcs=self.arcs, waits=self.waits,
            unknown_lines=self.unknown_lines, line_count=self.line_count,
            arc_centre=np.full((len(index), 2), np.nan), arc_turn=np.zeros(len(index), dtype=np.int8),
        )

    def flow_of_moves(self) -> np.ndarray:
        """(M,) M221 flow (percent) each move was printed with."""
        flows = np.array([s.flow for s in self.states], dtype=float)
        return flows[self.state]

    def fan_of_moves(self) -> np.ndarray:
        """(M,) part fan (percent, ``M106 S`` / 2.55; 0 before any fan command) each move
        was printed with."""
        lines = np.array([f.line for f in self.fans], dtype=np.int64)
        pwm = np.array([0.0] + [f.values.get("S", 255.0) for f in self.fans])
        return pwm[np.searchsorted(lines, self.line)] / 2.55

    def color_of_moves(self) -> np.ndarray:
        """(M,) palette color of each move from ``;STATE:`` comments (-1 if none)."""
        colors = np.array([-1 if s.color is None else s.color for s in self.states], dtype=np.int64)
        return colors[self.state]


CHUNK_LINES = 1 << 16
_BLOCK_BYTES = 8 << 20
_BINARY_PROBE = 65536


def _open(path_or_text: str | os.PathLike | bytes) -> tuple[BinaryIO, str | None]:
    """A binary stream over a file, bytes or a string holding G-code; and the file name if any."""
    if isinstance(path_or_text, os.PathLike) or (
        isinstance(path_or_text, str) and "\n" not in path_or_text and len(path_or_text) < 4096
        and os.path.isfile(path_or_text)
    ):
        name = str(path_or_text)
        try:
            return open(path_or_text, "rb"), name  # noqa: SIM115 - closed by iter_gcode
        except OSError as exc:
            raise GcodeError(f"cannot read G-code: {exc.strerror}", file=name) from None
    if isinstance(path_or_text, bytes):
        return io.BytesIO(path_or_text), None
    if "\n" not in path_or_text and Path(path_or_text).suffix.lower() in (".gcode", ".gco", ".g", ".nc"):
        raise GcodeError("G-code file not found", file=path_or_text)
    return io.BytesIO(str(path_or_text).encode("utf-8", errors="replace")), None


def _blocks(stream: BinaryIO, name: str | None) -> Iterator[bytes]:
    """The stream's bytes in blocks of ``_BLOCK_BYTES``.

    Raises:
        GcodeError: the stream cannot be read.
    """
    while True:
        try:
            block = stream.read(_BLOCK_BYTES)
        except OSError as exc:
            raise GcodeError(f"cannot read G-code: {exc.strerror}", file=name) from None
        if not block:
            return
        yield block


def _line_chunks(blocks: Iterable[bytes], name: str | None,
                 chunk_lines: int) -> Iterator[tuple[bytes, np.ndarray]]:
    """The text of ``blocks`` (bytes split anywhere) in pieces of whole lines: at most
    ``chunk_lines`` lines, and at most one block unless a single line is longer. Only the
    last piece may lack its final newline. Each piece comes with the offsets of its
    newlines.

    Raises:
        GcodeError: the text starts with binary data.
    """
    rest = b""
    probe = True
    for block in blocks:
        if not block:
            continue
        if probe and b"\x00" in block[:_BINARY_PROBE]:
            raise GcodeError("not G-code text: it holds binary data", file=name,
                             hint="binary G-code (.bgcode) is not supported; export plain G-code")
        probe = False
        data = rest + block if rest else block
        newlines = np.flatnonzero(np.frombuffer(data, dtype=np.uint8) == 10)
        if not len(newlines):
            rest = data
            continue
        last = list(range(chunk_lines - 1, len(newlines), chunk_lines))  # each piece's last newline
        if not last or last[-1] != len(newlines) - 1:
            last.append(len(newlines) - 1)
        a, k = 0, 0
        for j in last:
            b = int(newlines[j]) + 1
            yield data[a:b], newlines[k : j + 1] - a
            a, k = b, j + 1
        rest = data[a:]
    if rest:
        yield rest, np.zeros(0, dtype=np.int64)


_TOKEN_WIDTH = 16
_AXES = "XYZEFIJR"


def _table(chars: str) -> np.ndarray:
    table = np.zeros(256, dtype=bool)
    table[np.frombuffer(chars.encode(), dtype=np.uint8)] = True
    return table


_AXIS_TABLE = _table(_AXES + _AXES.lower())
_UPPER_AXIS_TABLE = _table(_AXES)
_END_TABLE = _table(" \t\r\n;\x00")
_MOVE_END_TABLE = _table(" \t\r\n;")
_COMMENT_KEYS = _table("TWLZS")
_AXIS_COLUMN = np.zeros(256, dtype=np.int64)
_AXIS_COLUMN[np.frombuffer(_AXES.encode(), dtype=np.uint8)] = np.arange(len(_AXES))
_POW10_INT = 10 ** np.arange(17, dtype=np.int64)
_POW10 = 10.0 ** np.arange(17)
_LIVE_BYTES = np.array([[(1 << 8 * min(k, 8)) - 1, (1 << 8 * max(k - 8, 0)) - 1] for k in range(17)], dtype=np.uint64)
_CHUNK = 1 << 16


def _ffill(values: np.ndarray, initial: float) -> np.ndarray:
    """Forward-fill NaNs of ``values``; leading NaNs become ``initial``."""
    idx = np.where(np.isnan(values), -1, np.arange(len(values)))
    np.maximum.accumulate(idx, out=idx)
    return np.where(idx >= 0, values[np.maximum(idx, 0)], initial)


def _arc_lengths(start: np.ndarray, end: np.ndarray, i: np.ndarray, j: np.ndarray, r: np.ndarray,
                 clockwise: np.ndarray) -> np.ndarray:
    """XY lengths of G2 (clockwise) / G3 arcs given by centre offsets I J or radius R, mm."""
    chord = np.hypot(end[:, 0] - start[:, 0], end[:, 1] - start[:, 1])
    with np.errstate(invalid="ignore", divide="ignore"):
        cx, cy = start[:, 0] + np.nan_to_num(i), start[:, 1] + np.nan_to_num(j)
        radius = np.hypot(start[:, 0] - cx, start[:, 1] - cy)
        a0 = np.arctan2(start[:, 1] - cy, start[:, 0] - cx)
        a1 = np.arctan2(end[:, 1] - cy, end[:, 0] - cx)
        sweep = np.mod(np.where(clockwise, a0 - a1, a1 - a0), 2 * np.pi)
        sweep = np.where(sweep == 0, 2 * np.pi, sweep)
        by_center = radius * sweep
        rr = np.abs(r)
        half = 2 * np.arcsin(np.clip(chord / (2 * rr), 0, 1))
        by_radius = rr * np.where(r < 0, 2 * np.pi - half, half)
    return np.where(np.isnan(r), by_center, np.where(rr > 0, by_radius, chord))


def _arc_centres(start: np.ndarray, end: np.ndarray, i: np.ndarray, j: np.ndarray, r: np.ndarray,
                 clockwise: np.ndarray) -> np.ndarray:
    """``(n, 2)`` centres of G2 (clockwise) / G3 arcs given by centre offsets I J or radius
    R (negative: the longer arc), mm (an R arc whose chord is longer than its diameter:
    the chord's middle)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        dx, dy = end[:, 0] - start[:, 0], end[:, 1] - start[:, 1]
        chord = np.hypot(dx, dy)
        rise = np.sqrt(np.maximum(np.abs(r)**2 - chord**2 / 4, 0.0))
        side = np.where(clockwise, -1.0, 1.0) * np.where(r < 0, -1.0, 1.0)  # centre left of the chord: +1
        by_radius = ~np.isnan(r)
        cx = np.where(by_radius, (start[:, 0] + end[:, 0]) / 2 - side * rise * dy / chord,
                      start[:, 0] + np.nan_to_num(i))
        cy = np.where(by_radius, (start[:, 1] + end[:, 1]) / 2 + side * rise * dx / chord,
                      start[:, 1] + np.nan_to_num(j))
    return np.column_stack([cx, cy])


def _arc_extents(start: np.ndarray, end: np.ndarray, i: np.ndarray, j: np.ndarray, r: np.ndarray,
                 clockwise: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """XY boxes ``(lo, hi)`` ``(n, 2)`` swept by G2 (clockwise) / G3 arcs given by centre
    offsets I J or radius R (negative: the longer arc), mm: the ends and the circle's
    points at 0, 90, 180 and 270 degrees that lie on the arc. I J arcs whose ends meet are
    full circles; an R arc whose chord is longer than its diameter is the chord."""
    with np.errstate(invalid="ignore", divide="ignore"):
        rr = np.abs(r)
        by_radius = ~np.isnan(r)
        cx, cy = _arc_centres(start, end, i, j, r, clockwise).T
        radius = np.hypot(start[:, 0] - cx, start[:, 1] - cy)
        a0 = np.arctan2(start[:, 1] - cy, start[:, 0] - cx)
        a1 = np.arctan2(end[:, 1] - cy, end[:, 0] - cx)
        sweep = np.mod(np.where(clockwise, a0 - a1, a1 - a0), 2 * np.pi)
        sweep = np.where((sweep == 0) & ~by_radius, 2 * np.pi, sweep)
        quarter = np.arange(4) * (np.pi / 2)
        along = np.mod(np.where(clockwise[:, None], a0[:, None] - quarter, quarter - a0[:, None]), 2 * np.pi)
        on_arc = (along <= sweep[:, None]) & np.isfinite(radius)[:, None] & ~(by_radius & ~(rr > 0))[:, None]
        px = np.where(on_arc, cx[:, None] + radius[:, None] * np.cos(quarter), np.nan)
        py = np.where(on_arc, cy[:, None] + radius[:, None] * np.sin(quarter), np.nan)
    xs = np.column_stack([start[:, 0], end[:, 0], px])
    ys = np.column_stack([start[:, 1], end[:, 1], py])
    return (np.column_stack([np.nanmin(xs, axis=1), np.nanmin(ys, axis=1)]),
            np.column_stack([np.nanmax(xs, axis=1), np.nanmax(ys, axis=1)]))


class _Events:
    """The sequential part of reading: every line that is not a G0-G3 move.

    ``after[0]`` is the state at the start of the current chunk, ``after[k]`` the one in
    force after line ``lines[k - 1]``.
    """

    def __init__(self) -> None:
        self.roles: list[str] = []
        self.role_index: dict[str, int] = {}
        self.layer_z: list[float] = []
        self.states: list[MachineState] = []
        self.state_index: dict[tuple, int] = {}  # MachineState fields -> index
        self.layer = -1
        self.role = -1
        self.width = math.nan
        self.tool = 0
        self.temps: dict[int, float] = {}
        self.flow: dict[int, float] = {}
        self.mix: tuple[float, ...] | None = None
        self.pending_mix: dict[int, float] = {}
        self.color: int | None = None
        self.state = self._state()
        self.begin_chunk()

    def begin_chunk(self) -> None:
        """Start new event lists; the interpreter state (layer, role, state, ...) carries on."""
        self.faults: list[Fault] = []
        self.unknown: list[int] = []
        self.temperatures: list[TemperatureEvent] = []
        self.tools: list[ValueEvent] = []
        self.flows: list[ValueEvent] = []
        self.mixes: list[ValueEvent] = []
        self.fans: list[ValueEvent] = []
        self.outputs: list[ValueEvent] = []
        self.waits: list[tuple[int, str, float]] = []
        self.positional: list[tuple[int, str, dict[str, float], set[str]]] = []
        self.lines: list[int] = []
        self.after: list[tuple[int, int, int, float]] = [(self.layer, self.role, self.state, self.width)]

    def _state(self) -> int:
        key = (self.mix, self.tool, self.temps.get(self.tool), self.flow.get(self.tool, 100.0), self.color)
        idx = self.state_index.get(key)
        if idx is None:
            idx = self.state_index[key] = len(self.states)
            self.states.append(MachineState(*key))
        return idx

    def _params(self, words: list[str], num: int) -> dict[str, float]:
        out = {}
        for w in words[1:]:
            key = w[0].upper()
            try:
                v = float(w[1:])
            except ValueError:
                v = math.nan
            if not math.isfinite(v):
                if w[1:]:
                    self.faults.append(Fault(num, f"{words[0]}: {key} value '{w[1:]}' is not a finite number"))
                continue
            out[key] = v
        return out

    def comment(self, raw: str, num: int) -> None:
        if raw.startswith(";TYPE:"):
            name = raw[6:].strip()
            role = self.role_index.get(name)
            if role is None:
                role = self.role_index[name] = len(self.roles)
                self.roles.append(name)
            self.role = role
        elif raw.startswith(";WIDTH:"):
            try:
                self.width = float(raw[7:])
            except ValueError:
                self.faults.append(Fault(num, f"';WIDTH:' value '{raw[7:].strip()}' is not a number"))
        elif raw.startswith(";LAYER_CHANGE"):
            self.layer += 1
        elif raw.startswith(";Z:"):
            try:
                self.layer_z.append(float(raw[3:]))
            except ValueError:
                self.faults.append(Fault(num, f"';Z:' value '{raw[3:].strip()}' is not a number"))
        elif raw.startswith(";STATE:"):
            head = raw[7:].split(maxsplit=1)
            if head and head[0].lstrip("-").isdecimal():
                self.color = int(head[0])
                self.state = self._state()
        elif raw.startswith(";LAYER:"):
            value = raw[7:].strip()
            if value.lstrip("-").isdecimal():
                self.layer = int(value)

    def command(self, raw: str, num: int) -> None:
        semi = raw.find(";")
        words = (raw[:semi] if semi >= 0 else raw).split()
        if not words:
            return
        cmd = words[0].upper()
        if cmd in TEXT_COMMANDS or not _CODE.match(cmd):  # a message, a file name, a host macro, NAME KEY=VALUE
            self.unknown.append(num)
            if cmd in WAIT_COMMANDS:
                self.waits.append((num, cmd, 0.0))
            return
        p = self._params(words, num)
        if cmd in WAIT_COMMANDS or (cmd[0] == "T" and cmd[1:].isdecimal()):
            self.waits.append((num, "T" if cmd[0] == "T" else cmd, _dwell(p) if cmd == "G4" else 0.0))
        if cmd[0] == "T" and cmd[1:].isdecimal():
            self.tool = int(cmd[1:])
            self.tools.append(ValueEvent(num, "T", {"T": float(self.tool)}))
            self.state = self._state()
        elif cmd in ("M104", "M109"):
            target = p.get("S", p.get("R"))
            which = int(p.get("T", self.tool))
            if target is not None:
                self.temperatures.append(TemperatureEvent(num, cmd, target, which, cmd == "M109"))
                self.temps[which] = target
                self.state = self._state()
            elif cmd == "M109":
                self.temperatures.append(TemperatureEvent(num, cmd, self.temps.get(which, 0.0), which, True))
        elif cmd in ("M140", "M190"):
            if "S" in p or "R" in p:
                self.temperatures.append(TemperatureEvent(num, cmd, p.get("S", p.get("R", 0.0)), -1, cmd == "M190"))
        elif cmd == "M221":
            self.flows.append(ValueEvent(num, cmd, p))
            if "S" in p:
                self.flow[int(p.get("T", self.tool))] = p["S"]
                self.state = self._state()
        elif cmd == "M165":
            self.mixes.append(ValueEvent(num, cmd, p))
            given = {MIX_LETTERS.index(k): v for k, v in p.items() if k in MIX_LETTERS}
            if given:
                self.mix = tuple(given.get(i, 0.0) for i in range(max(given) + 1))
                self.state = self._state()
        elif cmd == "M163":
            self.mixes.append(ValueEvent(num, cmd, p))
            if "S" in p and "P" in p:
                self.pending_mix[int(p["S"])] = p["P"]
        elif cmd == "M164":
            self.mixes.append(ValueEvent(num, cmd, p))
            channels = [i for i in self.pending_mix if i >= 0]
            if channels:
                self.mix = tuple(self.pending_mix.get(i, 0.0) for i in range(max(channels) + 1))
                self.state = self._state()
        elif cmd in ("G90", "G91", "M82", "M83", "G92", "G28"):
            self.positional.append((num, cmd, p, {w[0].upper() for w in words[1:]}))
        elif cmd == "M106":
            self.fans.append(ValueEvent(num, cmd, p))
        elif cmd == "M107":
            self.fans.append(ValueEvent(num, cmd, {"S": 0.0}))
        elif cmd == "M42":
            self.outputs.append(ValueEvent(num, cmd, p))
        else:
            self.unknown.append(num)

    def record(self, num: int) -> None:
        """Remember the layer, role, state and width in force after line ``num`` if they
        changed there."""
        now = (self.layer, self.role, self.state, self.width)
        if now != self.after[-1]:
            self.lines.append(num)
            self.after.append(now)


def _dwell(params: dict[str, float]) -> float:
    """Seconds a ``G4`` waits: its first positive ``P`` (ms) or ``S`` (s); 0 for none."""
    for key, value in params.items():
        if key in ("P", "S") and value > 0:
            return value / 1000.0 if key == "P" else value
    return 0.0


def _eight_digits(v: np.ndarray) -> np.ndarray:
    """The 8-digit integers held by uint64 words of digit values 0-9, first byte most significant."""
    v = (v * 10 + (v >> 8)) & 0x00FF00FF00FF00FF
    v = (v * 100 + (v >> 16)) & 0x0000FFFF0000FFFF
    return (v * 10000 + (v >> 32)) & 0xFFFFFFFF


def _first_byte(v: np.ndarray) -> np.ndarray:
    """Column of the first nonzero byte of each row of 16 bytes held as (n, 2) uint64; 16 if none."""
    lo = (np.bitwise_count((v[:, 0] & (~v[:, 0] + 1)) - 1) >> 3).astype(np.int64)
    hi = np.bitwise_count((v[:, 1] & (~v[:, 1] + 1)) - 1) >> 3
    return lo + np.where(lo == 8, hi, 0)


def _classify(chars: np.ndarray) -> tuple[np.ndarray, ...]:
    """Per-byte classes of number candidates ``(n, w)`` (uint8, one number per row):
    digit values, digit mask, point mask, first byte, leading sign, and the bytes that
    end a number (anything else, the leading sign excepted)."""
    digits = chars - np.uint8(48)
    is_digit = digits < 10
    is_point = chars == 46
    c0 = chars[:, 0]
    signed = (c0 == 45) | (c0 == 43)
    foreign = ~(is_digit | is_point)
    foreign[:, 0] &= ~signed
    return digits, is_digit, is_point, c0, signed, foreign


def _parse_chunk(padded: np.ndarray, words: np.ndarray, begin: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_parse_numbers` on one chunk; ``words[i]`` is the little-endian uint64 at byte ``i``."""
    raw = np.empty((len(begin), 2), dtype=np.uint64)
    raw[:, 0] = words[begin]
    raw[:, 1] = words[begin + 8]
    chars = raw.view(np.uint8)
    digits, is_digit, is_point, c0, signed, foreign = _classify(chars)
    length = _first_byte(foreign.view(np.uint64))
    points = is_point.view(np.uint64)
    point = np.minimum(_first_byte(points), length)
    second = _first_byte(points & (points - 1))
    n_digits = length - (point < length) - signed
    bad = ~_END_TABLE[padded[begin + length]] | (second < length) | (n_digits <= 0) | (n_digits > 15)
    digits *= is_digit
    live = digits.view(np.uint64) & _LIVE_BYTES[length]
    number = (_eight_digits(live[:, 0]) * 100_000_000 + _eight_digits(live[:, 1])).view(np.int64)
    scale = _POW10_INT[16 - point]
    whole = number // scale
    fraction = (number - whole * scale) // _POW10_INT[16 - length]
    decimals = np.maximum(length - 1 - point, 0)
    values = (whole * _POW10_INT[decimals] + fraction) / _POW10[decimals]
    return np.where(c0 == 45, -values, values), ~bad


def _bytes(value: int) -> np.uint64:
    """``value`` in every byte of a uint64 word."""
    return np.uint64(value * 0x0101010101010101)


_HIGH_BITS, _LOW_BITS = _bytes(0x80), _bytes(0x7F)
_ZERO_CHARS, _DIGIT_LIMIT, _POINT_XOR = _bytes(0x30), _bytes(0x76), _bytes(0x1E)
_ONE, _SEVEN, _EIGHT, _BYTE = np.uint64(1), np.uint64(7), np.uint64(8), np.uint64(0xFF)


def _parse_short(words: np.ndarray, begin: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Numbers of at most 7 characters (all coordinates and extrusions a slicer writes)
    starting at ``begin``, each from the one uint64 word ``words[begin]`` (little endian:
    the first character in the low byte): values, validity and length in characters (the
    first character that is not a digit, a point or a leading sign; 8 when all eight are).

    Valid: at most 7 characters, at most one point, at least one digit; the caller checks
    what follows. All byte classes are found at once in the word (SWAR): ``d = byte ^ '0'``
    is a digit below 10, a point is ``d == 0x1E``; the high bit of each byte flags a class.
    The point's byte is shifted out, leaving the digits (a sign as a leading 0)
    left-aligned; their 8-digit integer is ``mantissa * 10**(8 - digits)``, so one division
    by ``10**(8 - point)`` (both exact in float64) gives the correctly rounded value, the
    same as ``float(text)``."""
    word = words[begin]
    d = word ^ _ZERO_CHARS  # the operations below work in place to keep few temporaries
    non_digit = d & _LOW_BITS
    non_digit += _DIGIT_LIMIT
    non_digit |= d
    non_digit &= _HIGH_BITS
    scratch = d ^ _POINT_XOR
    point = scratch & _LOW_BITS
    point += _LOW_BITS
    point |= scratch
    np.invert(point, out=point)
    point &= _HIGH_BITS
    word &= _BYTE
    negative = word == 45
    sign = (word == 43) | negative
    sign = sign.view(np.uint8).astype(np.uint64)
    sign *= _BYTE
    end = non_digit | point
    end ^= point  # the bytes that are neither digits nor a point
    np.bitwise_and(sign, _HIGH_BITS, out=scratch)
    end |= scratch
    end ^= scratch  # ... nor a leading sign
    below_end = end - _ONE
    np.invert(end, out=end)
    below_end &= end
    length = np.bitwise_count(below_end)
    length >>= 3
    live = below_end >> _SEVEN
    point &= live
    below_point = point - _ONE
    valid = (below_point & point) == 0  # at most one point
    np.invert(point, out=scratch)
    below_point &= scratch
    below_point >>= _SEVEN
    at = np.bitwise_count(below_point)
    at >>= 3
    np.minimum(at, length, out=at)
    np.invert(sign, out=sign)
    live &= sign
    d &= live
    shifted = d >> _EIGHT
    d &= below_point
    np.invert(below_point, out=below_point)
    shifted &= below_point
    d |= shifted
    valid &= length < 8
    np.invert(non_digit, out=non_digit)
    non_digit &= live
    non_digit &= _HIGH_BITS
    valid &= non_digit != 0  # at least one digit
    values = _eight_digits(d) / _POW10[8 - at.astype(np.int64)]
    np.negative(values, out=values, where=negative)
    return values, valid, length.astype(np.int64)


def _parse_numbers(padded: np.ndarray, begin: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Values of the plain decimal numbers starting at ``padded[begin]``.

    A number runs to the next blank, ``;``, line end or NUL; it is an optional sign,
    digits with at most one point, at least one digit and at most 15 digits in all, at
    most ``_TOKEN_WIDTH`` characters; ``padded`` has at least 16 bytes after the last
    ``begin``. The 16 bytes at each start are read as two uint64 words; the digits are
    combined eight at a time with integer multiply-shift steps into one integer, split at
    the point into integer and fraction digits, and the mantissa (integer, < 10^15) is
    divided by a power of ten: both are exact in float64, so the result is the correctly
    rounded value, the same as ``float(text)``. Chunks keep the temporaries in cache.
    Returns the values and a validity mask.
    """
    values, valid, length = _short_numbers(padded, begin)
    valid &= _END_TABLE[padded[begin + length]]
    longer = length == 8
    if longer.any():
        values[longer], valid[longer] = _parse_chunk(padded, _byte_words(padded), begin[longer])
    return values, valid


def _short_numbers(padded: np.ndarray, begin: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`_parse_short` of the numbers at ``padded[begin]``, in pieces of :data:`_CHUNK`
    that keep the temporaries in cache: values, validity and lengths."""
    words = _byte_words(padded)
    values = np.empty(len(begin))
    valid = np.empty(len(begin), dtype=bool)
    length = np.empty(len(begin), dtype=np.int64)
    for s in range(0, len(begin), _CHUNK):
        piece = slice(s, s + _CHUNK)
        values[piece], valid[piece], length[piece] = _parse_short(words, begin[piece])
    return values, valid, length


def _byte_words(padded: np.ndarray) -> np.ndarray:
    """The little-endian uint64 starting at each byte of ``padded`` (a view)."""
    return np.ndarray(buffer=padded, dtype="<u8", shape=(len(padded) - 7,), strides=(1,))


def _plain_words(padded: np.ndarray, size: int, row_of_line: np.ndarray,
                 n_rows: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Axis words of the move lines (``row_of_line >= 0``, giving each line's row) of the
    text ``padded[:size]`` written in the plain shape every slicer writes most: ``G<n>`` at
    the line's start, then words of an upper-case axis letter and a valid number of at most
    7 characters, each after one blank, and nothing else.

    All words of all lines are read at once from the blanks and line ends in text order
    (a blank's line is the count of line ends before it): the letter after each blank, the
    number after it (:func:`_parse_short`, which also gives its length), which must end at
    the next blank or line end; a line's first blank must be its fourth character. Returns
    (row, letter, value) per word of the rows of that shape, and the other rows (for
    :func:`_general_words`).
    """
    is_separator = (padded == 32) | (padded == 10)
    is_separator[size] = True  # ends the last line when the text does not
    separator = np.flatnonzero(is_separator)
    newline = np.concatenate([[True], padded[separator] != 32])
    separator = np.concatenate([[-1], separator])  # the end of the line before the text
    blank = np.flatnonzero(~newline)
    row = row_of_line[(np.cumsum(newline) - 1)[blank]]
    moving = row >= 0
    blank, row = blank[moving], row[moving]
    at = separator[blank]
    letter = padded[at + 1]
    values, valid = _parse_plain(padded, at + 2, separator[blank + 1])
    valid &= _UPPER_AXIS_TABLE[letter] & (~newline[blank - 1] | (at == separator[blank - 1] + 3))
    plain = np.zeros(n_rows, dtype=bool)
    plain[row] = True
    plain[row[~valid]] = False
    keep = plain[row]
    return row[keep], letter[keep], values[keep], np.flatnonzero(~plain)


def _parse_plain(padded: np.ndarray, begin: np.ndarray, end: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Values of the numbers of at most 7 characters at ``padded[begin:end]``
    (:func:`_short_numbers`) and whether each is valid and ends exactly at ``end``."""
    values, valid, length = _short_numbers(padded, begin)
    valid &= begin + length == end
    return values, valid


def _general_words(padded: np.ndarray, starts: np.ndarray, ends: np.ndarray, first: np.ndarray,
                   lines: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Axis words of any move ``lines``: (index into ``lines``, upper-case letter, value,
    valid) per word.

    A word is an axis letter right after a blank, before the line's comment. The lines'
    bytes are first gathered into one buffer (when they are a small part of the chunk),
    then a word's line is the count of newlines before it, from one pass over blanks and
    newlines together.
    """
    if not len(lines):
        empty = np.zeros(0, dtype=np.int64)
        return empty, empty.astype(np.uint8), empty.astype(float), empty.astype(bool)
    sizes = ends[lines] - starts[lines] + 1
    offsets = np.zeros(len(lines) + 1, dtype=np.int64)
    np.cumsum(sizes, out=offsets[1:])
    n_bytes = int(offsets[-1])
    text = np.zeros(n_bytes + _TOKEN_WIDTH + 2, dtype=np.uint8)
    text[:n_bytes] = padded[np.repeat(starts[lines] - offsets[:-1], sizes) + np.arange(n_bytes)]
    text[offsets[1:] - 1] = 10
    line_end = offsets[1:] - 1
    comment_start = line_end.copy()
    semis = np.flatnonzero(text[:n_bytes] == ord(";"))
    if len(semis):
        uniq, at = np.unique(np.searchsorted(offsets, semis, side="right") - 1, return_index=True)
        comment_start[uniq] = semis[at]
    buf = text[:n_bytes]
    separators = np.flatnonzero((buf == 32) | (buf == 9) | (buf == 10))
    newline = buf[separators] == 10
    line_of = np.cumsum(newline) - newline
    word = _AXIS_TABLE[text[separators + 1]] & ~newline
    pos, lid = separators[word] + 1, line_of[word]
    keep = (pos < comment_start[lid]) & (pos > first[lines][lid] - starts[lines][lid] + offsets[lid] + 1)
    pos, lid = pos[keep], lid[keep]
    values, valid = _parse_numbers(text, pos + 1)
    return lid, text[pos] & 0xDF, values, valid


def _long_number(line: str, letter: str) -> float | None:
    """The finite value of the first word of axis ``letter`` of a move ``line`` (its code
    part), or None when it is not a finite number."""
    for word in line.split()[1:]:
        if word[:1].upper() == letter:
            if not _DECIMAL.match(word[1:]):
                return None
            value = float(word[1:])
            return value if math.isfinite(value) else None
    return None


MAX_COORDINATE = 1e9
"""Largest magnitude of a coordinate, extrusion or feed the reader takes (1000 km): a larger
one is a fault (a sum of them would overflow)."""

_DECIMAL = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$", re.ASCII)
"""A decimal number as firmware reads it, with an exponent (ASCII digits only)."""


def _cleaned(data: bytes, newlines: np.ndarray) -> bytes | None:
    """``data`` with line numbers and checksums (``N12 G1 X10*35``: what a host adds when
    it streams a file) removed and the words of a G command written without blanks
    separated (``G1X10Y10`` -> ``G1 X10 Y10``, what firmware accepts), lines kept; None
    when no line needs it. Lines are picked by their first bytes (and a ``*``), with
    numpy, so that the usual file costs a few passes over its bytes."""
    buf = np.frombuffer(data, dtype=np.uint8)
    starts = np.concatenate([[0], newlines + 1])
    starts = starts[starts < len(buf)]
    padded = np.concatenate([buf, np.zeros(4, dtype=np.uint8)])
    c0, c1, c2, c3 = (padded[starts + k] for k in range(4))
    digit = [(c >= 48) & (c <= 57) for c in (c1, c2)]
    upper = [(c >= 65) & (c <= 90) for c in (c2, c3)]
    dirty = ((c0 | 0x20) == ord("n")) & digit[0]
    dirty |= ((c0 | 0x20) == ord("g")) & digit[0] & (upper[0] | (digit[1] & upper[1]))
    if b"*" in data:
        dirty[np.searchsorted(newlines, np.flatnonzero(buf == ord("*")))] = True
    if not dirty.any():
        return None
    ends = np.append(newlines, len(buf))[: len(starts)]
    pieces, done = [], 0
    for a, b in zip(starts[dirty].tolist(), ends[dirty].tolist()):
        code, semi, comment = data[a:b].partition(b";")
        code = re.sub(rb"^[Nn]\d+", lambda m: b" " * len(m.group(0)), code)  # blanked: no line ends up empty
        code = re.sub(rb"\*\d+(?=[ \t\r]*$)", lambda m: b" " * len(m.group(0)), code)
        if code.lstrip()[:1] in (b"G", b"g"):
            code = re.sub(rb"(?<=[0-9.])(?=[A-Z])", b" ", code)
        pieces += [data[done:a], code, semi, comment]
        done = b
    pieces.append(data[done:])
    return b"".join(pieces)


class _Reader:
    """Reads G-code chunk by chunk, carrying the machine's state from one chunk to the next:
    position (mm), E (mm) and its G92 offset, absolute/relative modes, feed rate, line
    count, and (in :class:`_Events`) layer, role, width, tool, temperatures, flow, mix."""

    def __init__(self) -> None:
        self.events = _Events()
        self.pos = np.zeros(3)
        self.e_pos = 0.0
        self.rel_xyz = self.rel_e = False
        self.feed = 0.0
        self.line_count = 0

    def _integrate(self, axis: dict[str, np.ndarray], move_numbers: np.ndarray,
                   start: np.ndarray, end: np.ndarray, de: np.ndarray) -> None:
        """Fill ``start``/``end``/``de`` of the chunk's moves, stepping through the
        positional commands (G90/G91/M82/M83/G92/G28) between them."""
        positional = self.events.positional
        n_rows = len(move_numbers)
        bounds = np.searchsorted(move_numbers, [ev[0] for ev in positional]).tolist() + [n_rows]
        begin = 0
        for k, stop in enumerate(bounds):
            if stop > begin:
                for a, letter in enumerate("XYZ"):
                    v = axis[letter][begin:stop]
                    end[begin:stop, a] = (self.pos[a] + np.cumsum(np.nan_to_num(v)) if self.rel_xyz
                                          else _ffill(v, self.pos[a]))
                start[begin] = self.pos
                start[begin + 1 : stop] = end[begin : stop - 1]
                ve = axis["E"][begin:stop]
                if self.rel_e:
                    de[begin:stop] = np.nan_to_num(ve)
                else:
                    absolute = _ffill(ve, self.e_pos)
                    de[begin:stop] = np.diff(absolute, prepend=self.e_pos)
                    self.e_pos = float(absolute[-1])
                self.pos = end[stop - 1].copy()
                begin = stop
            if k == len(positional):
                break
            _, cmd, p, words = positional[k]
            if cmd == "G90":
                self.rel_xyz = self.rel_e = False
            elif cmd == "G91":
                self.rel_xyz = self.rel_e = True
            elif cmd == "M82":
                self.rel_e = False
            elif cmd == "M83":
                self.rel_e = True
            elif cmd == "G92":
                self.pos = np.array([p.get("X", self.pos[0]), p.get("Y", self.pos[1]), p.get("Z", self.pos[2])])
                self.e_pos = p.get("E", self.e_pos)
            else:
                homed = words & set("XYZ") or set("XYZ")
                self.pos = np.array([0.0 if a in homed else self.pos[i] for i, a in enumerate("XYZ")])

    def chunk(self, data: bytes, newlines: np.ndarray) -> GcodeProgram:
        """The moves and events of ``data`` (whole lines following the previous chunk),
        whose newlines are at ``newlines``."""
        offset = self.line_count
        cleaned = _cleaned(data, newlines)
        if cleaned is not None:
            data = cleaned
            newlines = np.flatnonzero(np.frombuffer(data, dtype=np.uint8) == 10)
        buf = np.frombuffer(data, dtype=np.uint8)
        ends = newlines if buf[-1] == 10 else np.append(newlines, len(buf))
        starts = np.concatenate([[0], newlines + 1])[: len(ends)]
        n_lines = len(ends)
        self.line_count += n_lines
        padded = np.concatenate([buf, np.zeros(_TOKEN_WIDTH + 2, dtype=np.uint8)])

        first = starts.copy()
        for i in np.flatnonzero((padded[starts] == 32) | (padded[starts] == 9)).tolist():
            line = data[starts[i] : ends[i]]
            first[i] += len(line) - len(line.lstrip())
        c0, c1, c2 = padded[first], padded[first + 1], padded[first + 2]
        is_move = ((c0 == ord("G")) | (c0 == ord("g"))) & (c1 >= ord("0")) & (c1 <= ord("3")) & (
            _MOVE_END_TABLE[c2] | (first + 2 >= ends)
        )
        empty = first >= ends
        plain_comment = (c0 == ord(";")) & ~_COMMENT_KEYS[c1]

        events = self.events
        events.begin_chunk()
        interpreted = np.flatnonzero(~(is_move | empty | plain_comment))
        for i, a, b in zip((interpreted + (offset + 1)).tolist(), first[interpreted].tolist(),
                           ends[interpreted].tolist()):
            raw = data[a:b].decode("utf-8", errors="replace").rstrip()
            if raw.startswith(";"):
                events.comment(raw, i)
            else:
                events.command(raw, i)
            events.record(i)

        move_lines = np.flatnonzero(is_move)
        n_rows = len(move_lines)
        row_of_line = np.full(n_lines, -1, dtype=np.int64)
        row_of_line[move_lines] = np.arange(n_rows)
        rows, letters, values, rest = _plain_words(padded, len(buf), row_of_line, n_rows)
        rest_index, rest_letters, rest_values, valid = _general_words(padded, starts, ends, first, move_lines[rest])
        rest_rows = rest[rest_index]
        faults = list(events.faults)
        for i in np.flatnonzero(~valid).tolist():
            line = int(move_lines[rest_rows[i]])
            word = data[starts[line] : ends[line]].decode("utf-8", errors="replace").split(";")[0].strip()
            value = _long_number(word, chr(rest_letters[i]))
            if value is not None and abs(value) <= MAX_COORDINATE:  # a number the fast parser leaves out
                rest_values[i], valid[i] = value, True
                continue
            what = "is not a finite number" if value is None else f"{value:g} is out of range (|value| > {MAX_COORDINATE:g})"
            faults.append(Fault(offset + line + 1, f"{word}: {chr(rest_letters[i])} value {what}"))
        rows = np.concatenate([rows, rest_rows[valid]])
        letters = np.concatenate([letters, rest_letters[valid]])
        values = np.concatenate([values, rest_values[valid]])
        table = np.full((len(_AXES), n_rows), np.nan)
        table.reshape(-1)[_AXIS_COLUMN[letters] * n_rows + rows] = values
        axis = dict(zip(_AXES, table))

        move_numbers = move_lines + (offset + 1)
        end = np.empty((n_rows, 3))
        start = np.empty((n_rows, 3))
        de = np.zeros(n_rows)
        self._integrate(axis, move_numbers, start, end, de)
        feed = _ffill(axis["F"], self.feed)
        if n_rows:
            self.feed = float(feed[-1])
        code = (padded[first[move_lines] + 1] - ord("0")).astype(np.int64)
        length = np.hypot(end[:, 0] - start[:, 0], end[:, 1] - start[:, 1])
        arcs = code >= 2
        arc_extents = []
        arc_centre = np.full((n_rows, 2), np.nan)
        arc_turn = np.zeros(n_rows, dtype=np.int8)
        if arcs.any():
            arc_centre[arcs] = _arc_centres(start[arcs], end[arcs], axis["I"][arcs], axis["J"][arcs], axis["R"][arcs],
                                            code[arcs] == 2)
            arc_turn[arcs] = np.where(code[arcs] == 2, -1, 1)
            length[arcs] = _arc_lengths(start[arcs], end[arcs], axis["I"][arcs], axis["J"][arcs], axis["R"][arcs],
                                        code[arcs] == 2)
            lo, hi = _arc_extents(start[arcs], end[arcs], axis["I"][arcs], axis["J"][arcs], axis["R"][arcs],
                                  code[arcs] == 2)
            arc_extents = [ArcExtent(n, (x0, y0), (x1, y1)) for n, (x0, y0), (x1, y1)
                           in zip(move_numbers[arcs].tolist(), lo.tolist(), hi.tolist())]
        moved = np.flatnonzero(~np.isnan(table[:4]).all(axis=0))  # rows with X, Y, Z or E
        changed = np.zeros(n_lines, dtype=np.int64)
        changed[np.array(events.lines, dtype=np.int64) - (offset + 1)] = 1
        recorded = np.cumsum(changed)[move_lines[moved]]  # index into events.after of each move
        layer, role, state, width = np.array(events.after, dtype=float).T
        return GcodeProgram(
            start=start.take(moved, axis=0),
            end=end.take(moved, axis=0),
            e=de[moved],
            feed=feed[moved],
            length=length[moved],
            line=move_numbers[moved],
            layer=layer.astype(np.int64)[recorded],
            role=role.astype(np.int64)[recorded],
            state=state.astype(np.int64)[recorded],
            width=width[recorded],
            roles=events.roles,
            states=events.states,
            layer_z=events.layer_z,
            temperatures=events.temperatures,
            tools=events.tools,
            flows=events.flows,
            mixes=events.mixes,
            fans=events.fans,
            outputs=events.outputs,
            faults=sorted(faults, key=lambda f: f.line),
            arcs=arc_extents,
            waits=events.waits,
            unknown_lines=np.array(events.unknown, dtype=np.int64),
            line_count=self.line_count,
            arc_centre=arc_centre[moved],
            arc_turn=arc_turn[moved],
        )


def iter_gcode(path_or_text: str | os.PathLike | bytes, *, chunk_lines: int = CHUNK_LINES) -> Iterator[GcodeProgram]:
    """Read G-code (a file path, bytes or a string holding the text) in chunks of whole lines.

    Each chunk is a :class:`GcodeProgram` of at most ``chunk_lines`` lines (and about
    8 MB): its moves and events with global (whole-file) line numbers, read with the
    state the previous chunks left (positions, modes, E, layer, role, width, process
    state). ``roles``, ``states`` and ``layer_z`` are the same lists in every chunk and
    grow as the file is read, so indices stay valid; ``line_count`` counts the lines read
    so far. Memory stays bounded by the chunk size whatever the file's length.

    Moves (G0-G3) are parsed in bulk with numpy; every other line goes through a small
    sequential interpreter. In moves, words are separated by blanks (``G1 X1 Y2``, as
    every slicer writes them) and axis values are plain decimal numbers (``X-1.25``);
    exponents, NaN, inf and other text are faults.

    Raises:
        GcodeError: the input is not readable G-code text; or, after the last chunk, it
            was empty or had no moves.
    """
    stream, name = _open(path_or_text)
    with stream:
        yield from iter_gcode_blocks(_blocks(stream, name), chunk_lines=chunk_lines, name=name)


def iter_gcode_blocks(blocks: Iterable[bytes], *, chunk_lines: int = CHUNK_LINES,
                      name: str | None = None) -> Iterator[GcodeProgram]:
    """:func:`iter_gcode` over G-code that arrives as byte blocks split anywhere (a file
    read while it is written, say); ``name`` is the file named in errors.

    Raises:
        GcodeError: as :func:`iter_gcode`.
    """
    if chunk_lines < 1:
        raise ValueError("chunk_lines must be at least 1")
    reader = _Reader()
    blank = True
    moves = 0
    for data, newlines in _line_chunks(blocks, name, chunk_lines):
        blank = blank and data.isspace()
        program = reader.chunk(data, newlines)
        moves += len(program.e)
        yield program
    if blank:
        raise GcodeError("the G-code is empty", file=name)
    if not moves:
        raise GcodeError(
            "no moves found: this is not G-code, or it only sets up the machine",
            file=name,
            hint="expected G0/G1 lines such as 'G1 X10 Y10 E0.5'",
        )


_ARRAY_FIELDS = ("start", "end", "e", "feed", "length", "line", "layer", "role", "state", "width", "unknown_lines",
                 "arc_centre", "arc_turn")
_EVENT_FIELDS = ("temperatures", "tools", "flows", "mixes", "fans", "outputs", "faults", "arcs", "waits")


def read_gcode(path_or_text: str | os.PathLike | bytes, *, chunk_lines: int = CHUNK_LINES) -> GcodeProgram:
    """The whole program of a G-code file, bytes or string: the chunks of
    :func:`iter_gcode` joined (each array is joined and the chunks' copies dropped in
    turn, so the peak is about the result plus one array).

    Raises:
        GcodeError: the input is not readable G-code text, is empty or has no moves.
    """
    parts: dict[str, list] = {name: [] for name in _ARRAY_FIELDS}
    events: dict[str, list] = {name: [] for name in _EVENT_FIELDS}
    last = None
    for last in iter_gcode(path_or_text, chunk_lines=chunk_lines):
        for name, arrays in parts.items():
            arrays.append(getattr(last, name))
        for name, items in events.items():
            items.extend(getattr(last, name))
    joined = {name: np.concatenate(parts.pop(name)) for name in _ARRAY_FIELDS}
    return GcodeProgram(**joined, **events, roles=last.roles, states=last.states, layer_z=last.layer_z,
                        line_count=last.line_count)


class GcodeStream:
    """Reads G-code handed over piece by piece, each piece whole lines (the writer's text
    as it is written, say): :meth:`read` returns the piece's moves and events as a
    :class:`GcodeProgram`, with line numbers and machine state carried over from the
    pieces before, as :func:`iter_gcode` does for the chunks of a file."""

    def __init__(self) -> None:
        self._reader = _Reader()

    @property
    def line_count(self) -> int:
        """Lines read so far."""
        return self._reader.line_count

    def read(self, text: str | bytes) -> GcodeProgram:
        """The moves and events of ``text``: whole lines, at least one (a missing last
        newline is taken as there)."""
        data = text.encode("utf-8") if isinstance(text, str) else text
        if not data.endswith(b"\n"):
            data += b"\n"
        return self._reader.chunk(data, np.flatnonzero(np.frombuffer(data, dtype=np.uint8) == 10))
