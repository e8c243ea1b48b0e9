"""Checks that a G-code file is safe to send to the machine a profile describes.

:func:`verify_gcode` reads any slicer's G-code (see :mod:`.gcode_reader`) and reports
:class:`~fgslice.machine.gcode_reader.Fault` s, each with its 1-based line:

* numbers that are not finite (NaN, inf, garbage);
* moves ending outside the build volume ``0..bed_x`` x ``0..bed_y`` x ``0..max_z``
  (tolerance ``BED_TOLERANCE_MM``), and arcs (``G2``/``G3``) sweeping outside its XY
  area anywhere along the way;
* extrusion per mm of XY travel ``E * filament_area / xy_length`` above
  ``max_cross_section_mm2`` (moves with XY length > 0; E as commanded, before M221);
  moves without XY motion (pure Z or pure E) extruding more than
  ``PRIME_ALLOWANCE_MM + retract_length`` of filament;
* extrusion while the active nozzle is colder than ``min_extrude_temperature``: a
  nozzle counts as heated to the last ``M109`` target (or a lower later ``M104``
  target: cooling is assumed immediate, heating only after a wait); skipped when
  ``min_extrude_temperature`` is 0;
* nozzle / bed targets above ``max_nozzle_temperature`` / ``max_bed_temperature``;
* ``M221`` outside ``[min_flow_percent, max_flow_percent]``;
* tool indices: ``T<n>`` with ``n >= tool_count`` on a toolchanger, ``n >= channels``
  on other dialects;
* mixes: ``M165`` factors outside [0, 1], not summing to 1 within ``MIX_SUM_TOLERANCE``,
  or set on a channel the machine lacks; ``M163`` factors outside [0, 1] or channels
  it lacks; any mixing command (``M163``/``M164``/``M165``) on a toolchanger or a
  temperature machine, which have no mixing hotend; ``M42`` values outside 0..255;
* ``M106`` fan values outside 0..255.

Consecutive faulty moves of one kind are reported once, at the first line, with the
number of moves and the last line (also when the run spans chunks of a streamed file).

Files are checked in chunks (bounded memory); :func:`verify_gcode_blocks` with
:func:`follow_file` checks a file while another process is still writing it, so the
slicer verifies its output alongside writing it.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Iterator

import numpy as np

from fgslice.machine.gcode_reader import CHUNK_LINES, MIX_LETTERS, Fault, GcodeProgram, iter_gcode, iter_gcode_blocks
from fgslice.settings import Settings

BED_TOLERANCE_MM = 0.1
PRIME_ALLOWANCE_MM = 10.0
MIX_SUM_TOLERANCE = 0.002
#: Bytes the slicer lets its file grow by before it tells its verifier to read them
#: (:func:`follow_file`, which also reads what follows the last size in such blocks).
#: What is left when the writer finishes is checked after it, so smaller blocks shorten
#: that wait, and each block costs a fixed part of the check (1 MiB: the vase's
#: verification ends about 0.05 s sooner than with 4 MiB, at the same total CPU).
FOLLOW_BLOCK_BYTES = 1 << 20


class _Runs:
    """Runs of consecutive bad moves of one kind, reported once each at the first line with
    the number of moves and the last line; a run open at the end of a chunk continues into
    the next."""

    def __init__(self) -> None:
        self.faults: list[Fault] = []
        self.open: list | None = None  # [first line, message, moves, last line]

    def add(self, program: GcodeProgram, bad: np.ndarray, describe: Callable[[int], str]) -> None:
        """Add a chunk's bad moves; ``describe(i)`` words the first move ``i`` of a run."""
        idx = np.flatnonzero(bad)
        if not len(idx):
            if len(bad):
                self._close()
            return
        breaks = np.flatnonzero(np.diff(idx) > 1)
        firsts = idx[np.concatenate([[0], breaks + 1])]
        lasts = idx[np.concatenate([breaks, [len(idx) - 1]])]
        for first, last in zip(firsts.tolist(), lasts.tolist()):
            if self.open is not None and first == 0:
                self.open[2] += last + 1
            else:
                self._close()
                self.open = [int(program.line[first]), describe(first), last - first + 1, 0]
            self.open[3] = int(program.line[last])
        if lasts[-1] < len(bad) - 1:
            self._close()

    def _close(self) -> None:
        if self.open is not None:
            line, message, count, last = self.open
            if count > 1:
                message += f" ({count} moves, to line {last})"
            self.faults.append(Fault(line, message))
            self.open = None

    def finish(self) -> list[Fault]:
        """All runs, the open one closed."""
        self._close()
        return self.faults


class _Verifier:
    """The checks, fed one chunk of a program at a time; carries the open fault runs and
    each nozzle's heated temperature (degC) and the active tool between chunks."""

    def __init__(self, settings: Settings) -> None:
        self.settings = settings
        self.read_faults: list[Fault] = []
        self.event_faults: list[Fault] = []
        self.volume, self.too_wide, self.blob, self.cold = _Runs(), _Runs(), _Runs(), _Runs()
        self.reached: dict[int, float] = {}
        self.tool = 0

    def add(self, program: GcodeProgram) -> None:
        """Check the next chunk (or a whole program)."""
        self.read_faults += program.faults
        self._check_volume(program)
        self._check_extrusion(program)
        self._check_heating(program)
        self.event_faults += _check_events(program, self.settings)

    def faults(self) -> list[Fault]:
        """All faults by line (at one line: reading, volume, extrusion, heating, events)."""
        faults = self.read_faults + self.volume.finish() + self.too_wide.finish() + self.blob.finish()
        faults += self.cold.finish() + self.event_faults
        return sorted(faults, key=lambda f: f.line)

    def _check_volume(self, program: GcodeProgram) -> None:
        settings = self.settings
        limits = np.array([settings.bed_x, settings.bed_y, settings.max_z])
        out = (program.end < -BED_TOLERANCE_MM) | (program.end > limits + BED_TOLERANCE_MM)
        bad = out[:, 0] | out[:, 1] | out[:, 2]

        def describe(i: int) -> str:
            x, y, z = program.end[i]
            return (f"move to X{x:.3f} Y{y:.3f} Z{z:.3f} leaves the build volume "
                    f"{settings.bed_x:g} x {settings.bed_y:g} x {settings.max_z:g} mm")

        self.volume.add(program, bad, describe)
        for arc in program.arcs:
            (x0, y0), (x1, y1) = arc.lo, arc.hi
            if min(x0, y0) < -BED_TOLERANCE_MM or x1 > limits[0] + BED_TOLERANCE_MM or y1 > limits[1] + BED_TOLERANCE_MM:
                self.event_faults.append(Fault(arc.line, (
                    f"arc sweeps through X{x0:.3f}..{x1:.3f} Y{y0:.3f}..{y1:.3f}, outside the build volume "
                    f"{settings.bed_x:g} x {settings.bed_y:g} mm")))

    def _check_extrusion(self, program: GcodeProgram) -> None:
        settings = self.settings
        area = np.pi * settings.filament_diameter**2 / 4.0
        moving = program.length > 0
        section = np.divide(program.e * area, program.length, out=np.zeros(len(program.e)), where=moving)
        too_wide = moving & (section > settings.max_cross_section_mm2)
        allowance = PRIME_ALLOWANCE_MM + settings.retract_length
        blob = ~moving & (program.e > allowance)
        self.too_wide.add(
            program, too_wide,
            lambda i: (f"extrudes {section[i]:.3f} mm^2 per mm of travel "
                       f"(max_cross_section_mm2 = {settings.max_cross_section_mm2:g})"),
        )
        self.blob.add(
            program, blob,
            lambda i: f"extrudes {program.e[i]:.3f} mm of filament without XY motion (allowance {allowance:g} mm)",
        )

    def _heated_timeline(self, program: GcodeProgram) -> tuple[np.ndarray, np.ndarray]:
        """Lines of the chunk where the active nozzle's heated temperature changes, and that
        temperature; advances the carried state to the chunk's end."""
        events = [(t.line, 0, t) for t in program.temperatures if t.tool >= 0]
        events += [(t.line, 1, t) for t in program.tools]
        events.sort(key=lambda item: (item[0], item[1]))
        reached = self.reached
        lines, values = [], []
        for line, kind, event in events:
            if kind == 1:
                self.tool = int(event.values["T"])
            elif event.wait:
                reached[event.tool] = event.target
            else:
                reached[event.tool] = min(reached.get(event.tool, 0.0), event.target)
            lines.append(line)
            values.append(reached.get(self.tool, 0.0))
        return np.array(lines, dtype=np.int64), np.array(values, dtype=float)

    def _check_heating(self, program: GcodeProgram) -> None:
        minimum = self.settings.min_extrude_temperature
        if minimum <= 0:
            return
        before = self.reached.get(self.tool, 0.0)
        lines, values = self._heated_timeline(program)
        at = np.searchsorted(lines, program.line, side="right") - 1
        heated = np.concatenate([[before], values])[at + 1]
        bad = (program.e > 0) & (heated < minimum)
        self.cold.add(
            program, bad,
            lambda i: (f"extrudes with the nozzle at {heated[i]:g} C, below min_extrude_temperature "
                       f"{minimum:g} C (heat with M109 first)"),
        )


def _check_events(program: GcodeProgram, settings: Settings) -> list[Fault]:
    faults = []
    for t in program.temperatures:
        bed = t.tool < 0
        limit = settings.max_bed_temperature if bed else settings.max_nozzle_temperature
        if t.target > limit or t.target < 0:
            what = "bed" if bed else "nozzle"
            faults.append(Fault(t.line, f"{t.command}: {what} temperature {t.target:g} C is outside 0..{limit:g} C"))
    for f in program.flows:
        s = f.values.get("S")
        if s is not None and not settings.min_flow_percent <= s <= settings.max_flow_percent:
            faults.append(Fault(f.line, f"M221: flow {s:g}% is outside {settings.min_flow_percent:g}.."
                                        f"{settings.max_flow_percent:g}%"))
    toolchanger = settings.dialect == "toolchanger"
    tool_limit = settings.tool_count if toolchanger else settings.channels
    for t in program.tools:
        n = int(t.values["T"])
        if n >= tool_limit:
            what = f"tool_count = {tool_limit}" if toolchanger else f"channels = {tool_limit}"
            faults.append(Fault(t.line, f"T{n}: no such tool ({what})"))
    for m in program.mixes:
        if settings.dialect in ("toolchanger", "temperature"):
            faults.append(Fault(m.line, f"{m.command}: a mixing command, but the {settings.dialect} machine has "
                                        "no mixing hotend (wrong profile, or a file for another machine)"))
            continue
        faults += _mix_faults(m.line, m.command, m.values, settings.channels)
    for o in program.outputs:
        s = o.values.get("S")
        if s is not None and not 0 <= s <= 255:
            faults.append(Fault(o.line, f"M42: value {s:g} is outside 0..255"))
    for f in program.fans:
        s = f.values.get("S")
        if s is not None and not 0 <= s <= 255:
            faults.append(Fault(f.line, f"M106: fan {s:g} is outside 0..255"))
    return faults


def _mix_faults(line: int, command: str, values: dict[str, float], channels: int) -> list[Fault]:
    faults = []
    if command == "M165":
        factors = {k: v for k, v in values.items() if k in MIX_LETTERS}
        for k, v in factors.items():
            if not 0 <= v <= 1:
                faults.append(Fault(line, f"M165: factor {k}{v:g} is outside [0, 1]"))
            elif MIX_LETTERS.index(k) >= channels and v > 0:
                faults.append(Fault(line, f"M165: channel {k} does not exist (channels = {channels})"))
        total = sum(factors.values())
        if factors and abs(total - 1.0) > MIX_SUM_TOLERANCE:
            faults.append(Fault(line, f"M165: factors sum to {total:.4f}, not 1"))
    elif command == "M163":
        p, s = values.get("P"), values.get("S")
        if p is not None and not 0 <= p <= 1:
            faults.append(Fault(line, f"M163: factor P{p:g} is outside [0, 1]"))
        if s is not None and not 0 <= s < channels:
            faults.append(Fault(line, f"M163: channel S{s:g} does not exist (channels = {channels})"))
    return faults


def verify_gcode(program_or_path: GcodeProgram | str | os.PathLike, settings: Settings, *,
                 chunk_lines: int = CHUNK_LINES) -> list[Fault]:
    """All faults of a G-code program (or file, or text) against ``settings``, by line.

    A file or text is read and checked in chunks of ``chunk_lines`` lines
    (:func:`.gcode_reader.iter_gcode`), so memory stays bounded whatever its length; the
    faults are the same as for the whole program.

    Raises:
        GcodeError: the file cannot be read as G-code.
    """
    verifier = _Verifier(settings)
    if isinstance(program_or_path, GcodeProgram):
        verifier.add(program_or_path)
    else:
        for chunk in iter_gcode(program_or_path, chunk_lines=chunk_lines):
            verifier.add(chunk)
    return verifier.faults()


def verify_gcode_blocks(blocks: Iterable[bytes], settings: Settings, *, name: str | None = None,
                        chunk_lines: int = CHUNK_LINES,
                        also: Callable[[GcodeProgram], None] | None = None) -> list[Fault]:
    """:func:`verify_gcode` of G-code arriving as byte blocks split anywhere (see
    :func:`follow_file`); ``name`` is the file named in errors; ``also`` is called with
    every chunk read, in order (a time model planning the same program, say).

    Raises:
        GcodeError: the text is not readable G-code.
    """
    verifier = _Verifier(settings)
    for chunk in iter_gcode_blocks(blocks, chunk_lines=chunk_lines, name=name):
        verifier.add(chunk)
        if also:
            also(chunk)
    return verifier.faults()


def follow_file(path: str | os.PathLike, sizes: Iterable[int]) -> Iterator[bytes]:
    """The bytes of a file that another process is writing: each size in ``sizes`` says
    the file holds at least that many bytes (flushed), and what it grew by is read as one
    block (the writer decides how often to tell); the rest is read once ``sizes`` ends,
    in blocks of at most :data:`FOLLOW_BLOCK_BYTES`.

    Each block read is handed to the kernel to be written to disk now (``posix_fadvise``
    ``DONTNEED`` starts the write-back of its pages without waiting for it; pages already
    written are dropped from the cache), so the writer's final ``fsync`` has little left
    to wait for (75 MB read back in blocks of 1 MiB as written: 31-33 ms -> about 1 ms).
    """
    with open(path, "rb") as handle:
        done = 0

        def read(limit: int) -> bytes:
            nonlocal done
            block = handle.read(limit)
            if block and hasattr(os, "posix_fadvise"):
                os.posix_fadvise(handle.fileno(), done, len(block), os.POSIX_FADV_DONTNEED)
            done += len(block)
            return block

        for size in sizes:
            if size > done:
                yield read(size - done)
        while block := read(FOLLOW_BLOCK_BYTES):
            yield block


def format_faults(faults: list[Fault], limit: int = 50) -> str:
    """Faults as text, one per line (``line 12: message``), the first ``limit`` of them."""
    if not faults:
        return "no faults"
    lines = [f"{len(faults)} fault{'s' if len(faults) != 1 else ''}:"]
    lines += [f"  line {f.line}: {f.message}" for f in faults[:limit]]
    if len(faults) > limit:
        lines.append(f"  ... and {len(faults) - limit} more")
    return "\n".join(lines)
