"""The streaming G-code writer: plans in, G-code text and statistics out.

:class:`GcodeWriter` writes a header, then one :class:`~fgslice.planning.plan.LayerPlan`
at a time (nothing of earlier layers is kept), then a footer. Conventions:

* relative extrusion (``M83``); for a segment of XY length ``L`` (mm) of a path of
  width ``w`` and height ``h``, ``E = L * bead_area(w, h) / (pi d^2 / 4)`` mm of filament
  (``d`` = ``filament_diameter``). E is rounded to 5 decimals by diffusing the rounding
  error along each path (each E is the difference of the path's rounded running total),
  so every path's written E equals its exact E to 5e-6 mm, whatever was printed before.
* coordinates have 3 decimals, trailing zeros dropped; moves that round to zero length
  are not written.
* PrusaSlicer's annotations: ``;BEFORE_LAYER_CHANGE`` and the layer's height (PrusaSlicer's
  default ``before_layer_gcode``, from which Moonraker reads the object's height),
  ``;LAYER_CHANGE``, ``;Z:``, ``;HEIGHT:``, ``;TYPE:<role>`` and ``;WIDTH:`` when they
  change; every state change starts with ``;STATE:<c> <label>``.
* feed rates: external perimeters ``outer_wall_speed``, sparse infill ``infill_speed``,
  every other extrusion ``print_speed``; everything on layer 0 ``first_layer_speed``;
  travels ``travel_speed`` (``G0``), Z moves ``z_speed``; all mm/s, written as mm/min.
* retraction ``G1 E-<retract_length>`` before travels longer than
  ``retract_min_travel`` and at layer changes, un-retraction after the travel; with
  ``z_hop`` > 0 retracted travels are lifted by ``z_hop``.

Moves are formatted in bulk: every number of a layer is split into groups of three
integer digits and its decimals, each looked up in a byte table, into one byte matrix whose
unprinted bytes are 0 and dropped at once (see :func:`format_lines`), so no Python object
is made per vertex.

A path's moves (its *body*) depend only on the path, so they are formatted where the
layer is planned, in the per-layer workers (:func:`prepare_bodies` attaches a
:class:`PathBodies` to the plan); the writer then only adds what depends on the print so
far — travels, retractions, annotations, feed rates, state changes — and joins the
texts. Paths without a prepared body (purge lines, paths split by look-ahead, plans
built elsewhere) are formatted by the writer the same way.

The statistics returned by :meth:`GcodeWriter.finish` are documented in ``docs/gcode.md``.
The time estimate is :class:`~fgslice.machine.timing.TimeModel`'s: the written text is
planned as the firmware plans it (acceleration, junction speeds), plus the dialect's fixed
``change_time_s`` per state change. The writer plans it itself, or, when another process
reads the file anyway (the slicer's verifier), that process plans it from what it reads
and the writer takes its figure before writing the footer.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from functools import cache
from operator import attrgetter
from datetime import datetime, timezone
from typing import TextIO

import numpy as np

import fgslice
from fgslice.errors import SettingsError
from fgslice.design.attributes import ROLE_SPEEDS
from fgslice.design.base import Material
from fgslice.machine.arcs import fit_arcs
from fgslice.machine.coasting import coast, wipe
from fgslice.machine.dialects import PLACEHOLDER, Dialect, PaletteLike
from fgslice.machine.grading import GRADING_SETTINGS, UNGRADED
from fgslice.machine.prusa_config import footer_block, tool_volumes
from fgslice.machine.thumbnails import thumbnail_block
from fgslice.machine.timing import TimeModel
from fgslice.planning.plan import EXTRA, ROLE_CODE, ROLES, STATE, LayerPlan, Prepared, SetState
from fgslice.settings import Settings
from fgslice.slicing.states import STATE_SETTINGS, StatePalette, material_colors
from fgslice.toolpaths.paths import Path, Role, bead_area

INT_DIGITS = 9
#: Bodies the writer keeps of paths it formatted itself, reused for equal geometry.
MADE_BODIES = 4096
TYPE_LINES = [f";TYPE:{role.value}\n" for role in ROLES] + [""]  # the last: no change


def fgslice_version() -> str:
    """The fgslice version (``fgslice.__version__``, which is also the package's
    metadata: no package metadata is read at run time)."""
    return fgslice.__version__


def fmt(value: float, decimals: int) -> str:
    """``value`` with at most ``decimals`` decimals, trailing zeros dropped (``-0`` as ``0``)."""
    text = f"{value:.{decimals}f}"
    if "." in text:
        text = text.rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


XY_DECIMALS = 3
"""Decimals of X, Y and Z in moves (trailing zeros dropped)."""
E_DECIMALS = 5
"""Decimals of E in moves (trailing zeros dropped)."""


@cache
def _digit_tables(decimals: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Byte tables of number pieces, 0 where nothing is printed, and their printed lengths.

    Returns ``full`` ``(3, 1000)``: the three digits of 0..999 (a column each);
    ``lead`` ``(3, 1000)``: the same without leading zeros (``0`` as "0", right-aligned)
    and ``lead_len``; ``frac`` ``(decimals + 1, 10**decimals)``: ``.`` and the decimals
    of 0..10**decimals - 1 without trailing zeros (nothing for 0) and ``frac_len``.
    """
    v = np.arange(1000)
    digits = np.stack([v // 100, v // 10 % 10, v % 10], axis=1)
    full = (digits + 48).astype(np.uint8)
    lead = np.where(v[:, None] >= [100, 10, 1], full, 0).astype(np.uint8)
    lead[0, 2] = 48
    # the decimals of 0..10**decimals - 1, most significant first, by tiling 0..9
    decimal = np.empty((10**decimals, decimals), dtype=np.uint8)
    for k in range(decimals):
        decimal[:, k] = np.repeat(np.tile(np.arange(10, dtype=np.uint8), 10**k), 10 ** (decimals - 1 - k))
    printed = np.logical_or.accumulate(decimal[:, ::-1] != 0, axis=1)[:, ::-1]  # not a trailing zero
    frac = np.zeros((10**decimals, decimals + 1), dtype=np.uint8)
    frac[:, 1:] = np.where(printed, decimal + 48, 0)
    if decimals:
        frac[:, 0] = np.where(printed[:, 0], 46, 0)
    return (np.ascontiguousarray(full.T), np.ascontiguousarray(lead.T), np.count_nonzero(lead, axis=1),
            np.ascontiguousarray(frac.T), np.count_nonzero(frac, axis=1))


def build_number_tables() -> None:
    """Build (once per process) the byte tables that coordinates (:data:`XY_DECIMALS`)
    and extrusions (:data:`E_DECIMALS`) are formatted with; called before worker
    processes are forked, so that they inherit the tables instead of each building them."""
    _digit_tables(XY_DECIMALS)
    _digit_tables(E_DECIMALS)


def _number_block(values: np.ndarray, decimals: int) -> tuple[list[np.ndarray], np.ndarray]:
    """ASCII bytes of ``values`` with at most ``decimals`` decimals, one column per value,
    as blocks of rows to be stacked, and the number of printed bytes of each value.

    The ``(w_i, n)`` uint8 blocks are sign, integer digits (most significant first) three
    at a time, point and decimals; bytes that are not printed (leading zeros, trailing zeros of the
    fraction, the point of whole numbers, the sign of non-negative values) are 0 and
    removed by the caller. Digits come from lookup tables, three integer digits at a time.
    """
    full, lead, lead_len, frac, frac_len = _digit_tables(decimals)
    q = np.rint(np.abs(values) * 10.0**decimals).astype(np.int64)
    whole, part = np.divmod(q, 10**decimals)
    top = int(whole.max()) if q.size else 0
    if top >= 10**INT_DIGITS:
        raise ValueError(f"cannot write a G-code number of more than {INT_DIGITS} integer digits")
    negative = (values < 0) & (q != 0)
    blocks = [np.where(negative, np.uint8(45), np.uint8(0))[None]]
    lengths = negative + np.take(frac_len, part)
    groups = 1
    while 1000**groups <= top:
        groups += 1
    for k in range(groups - 1, -1, -1):
        group = whole // 1000**k % 1000
        shown = np.take(lead, group, axis=1)
        size = np.take(lead_len, group)
        if k:
            size[whole < 1000**k] = 0  # a leading group of zeros
            shown[:, whole < 1000**k] = 0
        higher = whole >= 1000 ** (k + 1)
        if higher.any():
            shown[:, higher] = np.take(full, group[higher], axis=1)
            size[higher] = 3
        blocks.append(shown)
        lengths += size
    blocks.append(np.take(frac, part, axis=1))
    return blocks, lengths


def format_lines(fields: list[tuple[str, np.ndarray, int]], suffix: str = "\n") -> tuple[str, np.ndarray]:
    """One line per row: for each field its literal text then its number, then ``suffix``.

    ``fields`` are ``(text, values, decimals)`` with arrays of equal length; numbers are
    written with at most ``decimals`` decimals, trailing zeros dropped. Returns the text
    of all lines and the ``(n + 1,)`` character offsets of line starts (the last entry
    is the text length), so callers can slice runs of lines.
    """
    n = len(fields[0][1])
    if n == 0:
        return "", np.zeros(1, dtype=np.int64)
    blocks, lengths = _line_blocks(fields, suffix)
    return _assemble(blocks, n, lengths)


def _line_blocks(fields: list[tuple[str, np.ndarray, int]], suffix: str) -> tuple[list[np.ndarray], np.ndarray]:
    """The blocks of :func:`format_lines`' lines (for :func:`_stack`) and the printed
    length of each line. Numbers of the same decimals are formatted in one call."""
    n = len(fields[0][1])
    numbers: dict[int, list[np.ndarray]] = {}
    for _, values, decimals in fields:
        numbers.setdefault(decimals, []).append(values)
    columns = {}
    for decimals, arrays in numbers.items():
        values = np.concatenate(arrays) if len(arrays) > 1 else arrays[0]
        if not np.isfinite(values).all():
            raise ValueError("a toolpath has a non-finite coordinate")
        columns[decimals] = [_number_block(values, decimals), 0]
    blocks: list[np.ndarray] = []
    lengths = np.full(n, len(suffix), dtype=np.int64)
    for text, _, decimals in fields:
        (number, size), k = columns[decimals]
        columns[decimals][1] += 1
        blocks += [_literal(text), *(block[:, k * n : (k + 1) * n] for block in number)]
        lengths += len(text) + size[k * n : (k + 1) * n]
    blocks.append(_literal(suffix))
    return blocks, lengths


def _stack(blocks: list[np.ndarray], n: int) -> np.ndarray:
    """``(sum w_i, n)`` uint8: the ``(w_i, n)`` (or ``(w_i, 1)``, repeated) blocks one under another."""
    columns = np.empty((sum(len(b) for b in blocks), n), dtype=np.uint8)  # filled column-major: faster
    start = 0
    for block in blocks:
        columns[start : start + len(block)] = block
        start += len(block)
    return columns


def _assemble(blocks: list[np.ndarray], n: int, lengths: np.ndarray) -> tuple[str, np.ndarray]:
    """The text of the ``n`` columns of :func:`_stack` of ``blocks``, column after column,
    0 bytes dropped, and the ``(n + 1,)`` offsets of each column's text (``lengths``: the
    number of nonzero bytes of each column)."""
    offsets = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(lengths, out=offsets[1:])
    return _stack(blocks, n).T.tobytes().translate(None, b"\0").decode("ascii"), offsets


def _text_table(texts: list[str]) -> np.ndarray:
    """``(max_len, len(texts))`` uint8: the ASCII bytes of each text in a column, 0-padded,
    so that ``table[:, codes]`` is a block for :func:`_assemble` choosing a text per column."""
    width = max(map(len, texts), default=0)
    padded = "".join(text.ljust(width, "\0") for text in texts).encode("ascii")
    return np.frombuffer(padded, dtype=np.uint8).reshape(len(texts), width).T


def _literal(text: str) -> np.ndarray:
    """The bytes of ``text`` as a ``(len(text), 1)`` uint8 block (the same in every column)."""
    return np.frombuffer(text.encode("ascii"), dtype=np.uint8)[:, None]


def format_moves(x: np.ndarray, y: np.ndarray, e: np.ndarray) -> tuple[str, np.ndarray]:
    """``G1 X<x> Y<y> E<e>`` lines (3, 3 and 5 decimals); see :func:`format_lines`."""
    return format_lines([("G1 X", x, XY_DECIMALS), (" Y", y, XY_DECIMALS), (" E", e, E_DECIMALS)])


def format_arc_moves(x: np.ndarray, y: np.ndarray, turn: np.ndarray, offset: np.ndarray,
                     e: np.ndarray) -> tuple[str, np.ndarray]:
    """:func:`format_moves`, with ``G2`` (``turn`` -1) and ``G3`` (``turn`` 1) arcs, whose
    centre is ``offset`` ``(n, 2)`` from their start, as ``G2 X Y I J E`` lines."""
    n = len(x)
    if n == 0:
        return "", np.zeros(1, dtype=np.int64)
    arc = (turn != 0).astype(np.uint8)
    head, head_lengths = _line_blocks([("G1 X", x, XY_DECIMALS), (" Y", y, XY_DECIMALS)], "")
    head[0] = _text_table(["G1 X", "G2 X", "G3 X"])[:, np.where(arc, np.where(turn < 0, 1, 2), 0)]
    centre, centre_lengths = _line_blocks([(" I", offset[:, 0], XY_DECIMALS), (" J", offset[:, 1], XY_DECIMALS)], "")
    tail, tail_lengths = _line_blocks([(" E", e, E_DECIMALS)], "\n")
    return _assemble(head + [block * arc for block in centre] + tail, n,
                     head_lengths + centre_lengths * arc + tail_lengths)


@dataclass
class PathBodies:
    """The moves of a run of paths, formatted, with what the writer needs to know of them.

    Row ``i`` is path ``i``; a path whose moves all round to zero length has no moves
    (``length`` 0). Coordinates are the written ones (rounded to 0.001 mm).

    Attributes:
        text: the ``G1 X Y E`` lines of all paths, in row order.
        bounds: ``(n + 1,)`` character offsets of each path's lines in ``text``.
        start: ``(n, 2)`` first point of each path, mm.
        end: ``(n, 2)`` last point written, mm.
        low, high: ``(n, 2)`` corners of the box around the path's written points, mm.
        e: ``(n,)`` filament written, mm.
        length: ``(n,)`` XY length of the written moves, mm.
        fan: ``(n, 2)`` with a fan attribute: the ``M106 S`` value (0-255) a path starts
            with (the writer commands it when the fan is not there yet) and ends with;
            -1 where the path leaves the fan alone; else None.
        commanded: instantaneous attribute name -> ``(n, 2)`` smallest and largest value
            commanded over each path's moves (percent; NaN for a path without moves).
    """

    text: str
    bounds: np.ndarray
    start: np.ndarray
    end: np.ndarray
    low: np.ndarray
    high: np.ndarray
    e: np.ndarray
    length: np.ndarray
    fan: np.ndarray | None = None
    commanded: dict[str, np.ndarray] | None = None


@dataclass(frozen=True)
class LayerGrade:
    """What :func:`format_packed` needs to write a layer's instantaneous attributes.

    Attributes:
        grading: the design's attributes (:class:`~fgslice.machine.grading.SegmentGrading`).
        z: the layer's middle height, bed frame, mm.
        names: the attributes graded on this layer.
        roles: ``(n,)`` role code (:data:`ROLES`) of each path.
        feeds: ``(n,)`` feature speed of each path, mm/s.
    """

    grading: object
    z: float
    names: tuple[str, ...]
    roles: np.ndarray
    feeds: np.ndarray


def _graded_feeds(grade: LayerGrade, move_path: np.ndarray, values: dict[str, np.ndarray]) -> np.ndarray:
    """Feed rate (mm/s) of each piece: its path's feature speed times ``speed`` (percent),
    or the feature speed attribute of its path's role where that is defined."""
    feed = grade.feeds[move_path] * (values["speed"] / 100.0 if "speed" in values else 1.0)
    roles = grade.roles[move_path]
    for name, role_names in ROLE_SPEEDS.items():
        if name in values:
            own = np.isin(roles, [ROLE_CODE[Role(r)] for r in role_names]) & np.isfinite(values[name])
            feed = np.where(own, values[name], feed)
    return feed


def role_speeds(settings: Settings, first_layer: bool) -> np.ndarray:
    """Print speed (mm/s) of each role (:data:`ROLES`) on the first or any other layer."""
    s = settings
    by_role = np.full(len(ROLES), s.first_layer_speed if first_layer else s.print_speed)
    if not first_layer:
        by_role[ROLE_CODE[Role.EXTERNAL_PERIMETER]] = s.outer_wall_speed
        by_role[ROLE_CODE[Role.INTERNAL_INFILL]] = s.infill_speed
        by_role[ROLE_CODE[Role.BRIDGE_INFILL]] = s.bridge_speed
    return by_role


def layer_grade(grading, plan: LayerPlan, settings: Settings, roles: np.ndarray) -> LayerGrade | None:
    """The :class:`LayerGrade` of ``plan``'s paths of role codes ``roles`` (None without
    a grading or with nothing graded on this layer)."""
    if grading is None or not grading.active(plan.index):
        return None
    return LayerGrade(grading, plan.z - plan.height / 2, grading.active(plan.index), roles,
                      role_speeds(settings, plan.index == 0)[roles])


def format_bodies(paths: list[Path], filament_area: float, grade=None) -> PathBodies:
    """The moves of ``paths`` in bulk (E per segment from the bead area, rounding error
    diffused along each path; see the module notes). ``filament_area`` in mm^2;
    ``grade(roles)``: the :class:`LayerGrade` of paths of those role codes, or None."""
    arrays, closed, widths, heights = zip(*map(attrgetter("points", "closed", "width", "height"), paths))
    sizes = np.fromiter(map(len, arrays), dtype=np.int64, count=len(paths))
    graded = grade(np.array([ROLE_CODE[p.role] for p in paths], dtype=np.int64)) if grade else None
    return format_packed(np.concatenate(arrays), sizes, np.array(closed, dtype=bool), np.array(widths),
                         np.array(heights), filament_area, graded)


def format_packed(
    points: np.ndarray, sizes: np.ndarray, closed: np.ndarray, widths: np.ndarray, heights: np.ndarray,
    filament_area: float, grade: LayerGrade | None = None, arc_tolerance: float = 0.0,
) -> PathBodies:
    """:func:`format_bodies` of paths given as columns: ``points`` ``(P, 2)`` mm, one path
    after another, ``sizes`` ``(n,)`` points per path, ``closed``, ``widths`` and
    ``heights`` (mm) ``(n,)``; ``filament_area`` mm^2. With ``grade``, every move is cut
    where the instantaneous attributes change (:meth:`SegmentGrading.cut`) and written
    with its E scaled by flow, its own F (feature speed times speed) and an ``M106 S``
    before each piece whose fan differs from the previous piece's. With ``arc_tolerance``
    (mm) > 0 and no ``grade``, runs of moves on a circle become ``G2``/``G3`` arcs within
    that distance of them (:func:`~fgslice.machine.arcs.fit_arcs`), E following the arc's length."""
    n = len(sizes)
    counts = sizes + closed  # a closed path's vertices end at its first point again
    first = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(counts, out=first[1:])
    source = np.repeat(np.cumsum(sizes) - sizes - first[:-1], counts) + np.arange(first[-1])
    source[first[1:][closed] - 1] = source[first[:-1][closed]]
    pts = np.round(points[source], 3) + 0.0
    seg = np.hypot(*np.diff(pts, axis=0).T)
    inside = np.ones(len(seg), dtype=bool)
    inside[first[1:-1] - 1] = False
    moves = np.flatnonzero(inside & (seg > 0))
    move_path = np.repeat(np.arange(n), counts)[1:][moves]
    n_moves = np.bincount(move_path, minlength=n)
    row_start = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(n_moves, out=row_start[1:])

    lengths = seg[moves]
    ends = pts[moves + 1]
    scale = 1.0
    if grade is not None and len(moves):
        part = ~np.isin(grade.roles, UNGRADED)[move_path]
        pieces = grade.grading.cut(pts[moves], ends, part, grade.z, grade.names)
        froms = np.roll(pieces.ends, 1, axis=0)
        first_piece = np.concatenate([[True], pieces.parent[1:] != pieces.parent[:-1]])
        froms[first_piece] = pts[moves[pieces.parent[first_piece]]]
        keep = (pieces.ends != froms).any(axis=1)
        parent, ends = pieces.parent[keep], pieces.ends[keep]
        values = {name: v[keep] for name, v in pieces.values.items()}
        part = part[parent]
        lengths = np.hypot(*(ends - froms[keep]).T)
        move_path = move_path[parent]
        n_moves = np.bincount(move_path, minlength=n)
        np.cumsum(n_moves, out=row_start[1:])
        scale = values["flow"] / 100.0 if "flow" in values else 1.0
    fitted = None
    if arc_tolerance > 0 and grade is None and len(moves):
        fitted = fit_arcs(pts[first[:-1]], ends, move_path, arc_tolerance)
        ends, lengths, move_path = fitted.ends, fitted.length, fitted.path
        n_moves = np.bincount(move_path, minlength=n)
        np.cumsum(n_moves, out=row_start[1:])
    exact = np.cumsum(lengths * scale * (bead_area(widths, heights) / filament_area)[move_path])
    exact -= np.concatenate([[0.0], exact])[row_start[:-1]][move_path]
    rounded = np.round(exact, 5)
    e = np.diff(rounded, prepend=0.0)
    printed = n_moves > 0
    e[row_start[:-1][printed]] = rounded[row_start[:-1][printed]]
    fan = commanded = None
    if fitted is not None and fitted.turn.any():
        text, offsets = format_arc_moves(ends[:, 0], ends[:, 1], fitted.turn, fitted.offset, e)
    elif grade is None or not len(moves):
        text, offsets = format_moves(ends[:, 0], ends[:, 1], e)
    else:
        fields = [("G1 X", ends[:, 0], XY_DECIMALS), (" Y", ends[:, 1], XY_DECIMALS), (" E", e, E_DECIMALS)]
        if "speed" in values or not ROLE_SPEEDS.keys().isdisjoint(values):
            feed = _graded_feeds(grade, move_path, values)
            fields.append((" F", np.round(feed * 60.0, 1), 1))
        blocks, line_lengths = _line_blocks(fields, "\n")
        if "fan" in values:
            pwm = np.rint(values["fan"] * 2.55).astype(np.int64)
            firsts = row_start[:-1][printed]
            fan = np.full((n, 2), -1, dtype=np.int64)
            fan[printed, 0], fan[printed, 1] = pwm[firsts], pwm[row_start[1:][printed] - 1]
            changed = np.ones(len(pwm), dtype=bool)
            changed[1:] = pwm[1:] != pwm[:-1]
            changed[firsts] = False
            table, codes = _choices(pwm, changed, lambda v: f"M106 S{int(v)}\n")
            blocks.insert(0, table[:, codes])
            line_lengths = line_lengths + np.count_nonzero(table, axis=0)[codes]
        text, offsets = _assemble(blocks, len(ends), line_lengths)
        commanded = {}
        for name, v in values.items():
            commanded[name] = np.full((n, 2), np.nan)
            cuts = row_start[:-1][printed]
            v = np.where(part, v, np.nan)
            commanded[name][printed, 0] = np.fmin.reduceat(v, cuts)
            commanded[name][printed, 1] = np.fmax.reduceat(v, cuts)

    start = pts[first[:-1]]
    last = np.maximum(row_start[1:] - 1, 0)
    end = np.where(printed[:, None], ends[last] if len(ends) else start, start)
    low, high = start.copy(), start.copy()
    if len(ends):
        cuts = row_start[:-1][printed]
        low[printed] = np.minimum(start[printed], np.minimum.reduceat(ends, cuts, axis=0))
        high[printed] = np.maximum(start[printed], np.maximum.reduceat(ends, cuts, axis=0))
    return PathBodies(
        text=text,
        bounds=offsets[row_start],
        start=start,
        end=end,
        low=low,
        high=high,
        e=np.bincount(move_path, weights=e, minlength=n),
        length=np.bincount(move_path, weights=lengths, minlength=n),
        fan=fan,
        commanded=commanded,
    )


def prepare_bodies(plan: LayerPlan, settings: Settings, grading=None) -> None:
    """Format the moves of ``plan``'s paths now (in a per-layer worker) and attach them, so
    that :meth:`GcodeWriter.write_layer` only joins texts: the plan is packed into columns
    (:meth:`LayerPlan.pack`, as it would be to leave the worker) whose rows are its paths'
    :class:`PathBodies`; a plan that cannot be packed gets them as ``plan.prepared``.
    ``grading``: the design's instantaneous attributes
    (:class:`~fgslice.machine.grading.SegmentGrading`), None for none."""
    area = np.pi * settings.filament_diameter**2 / 4.0
    packed = plan.pack()
    if packed is None:
        paths = plan.paths
        if paths:
            grade = (lambda roles: layer_grade(grading, plan, settings, roles)) if grading else None
            plan.prepared = Prepared(dict(zip(paths, range(len(paths)))), format_bodies(paths, area, grade))
    elif len(packed.roles):
        grade = layer_grade(grading, plan, settings, packed.roles.astype(np.int64))
        packed.data = format_packed(packed.points, np.diff(packed.offsets).astype(np.int64), packed.closed,
                                    packed.widths, packed.heights, area, grade, arc_tolerance(settings))
        packed.rows = np.arange(len(packed.roles), dtype=np.int32)


def arc_tolerance(settings: Settings) -> float:
    """How far fitted arcs may leave the moves they replace, mm: ``gcode_resolution`` with
    ``arc_fitting = emit_center``, else 0 (no arcs)."""
    return settings.gcode_resolution if settings.arc_fitting == "emit_center" else 0.0


def fill_placeholders(text: str, values: dict[str, str], what: str) -> str:
    """Replace ``{name}`` in ``text`` by ``values[name]``; unknown names are a SettingsError."""

    def replace(match: re.Match[str]) -> str:
        name = match.group(1)
        if name not in values:
            raise SettingsError(
                f"unknown placeholder '{{{name}}}' in {what}",
                hint="placeholders: " + ", ".join(f"{{{k}}}" for k in values),
            )
        return values[name]

    return PLACEHOLDER.sub(replace, text)


def format_duration(seconds: float) -> str:
    """PrusaSlicer's time format: ``1d 2h 3m 4s``, leading zero units omitted."""
    total = int(round(seconds))
    days, rest = divmod(total, 86400)
    hours, rest = divmod(rest, 3600)
    minutes, secs = divmod(rest, 60)
    parts = [(days, "d"), (hours, "h"), (minutes, "m")]
    while parts and parts[0][0] == 0:
        parts.pop(0)
    return " ".join(f"{v}{u}" for v, u in parts + [(secs, "s")])


@dataclass
class _LayerPaths:
    """What the writer needs of a layer's steps, as arrays (from a plan's packed columns
    without making paths, else from its steps).

    Attributes:
        n: number of paths.
        codes, widths, colors: ``(n,)`` role code (:data:`ROLES`), bead width (mm) and
            design color of each path.
        states: the colors of the layer's SetStates in order; ``state_before`` the path
            each one precedes (``n``: after the last path).
        rows: ``(n,)`` each path's row of ``data`` (prepared bodies), -1 for none.
        data: the prepared :class:`PathBodies` (None if none).
        missing: the paths without a row, in order (every path when ``data`` is None).
    """

    n: int
    codes: np.ndarray
    widths: np.ndarray
    colors: np.ndarray
    states: np.ndarray
    state_before: np.ndarray
    rows: np.ndarray
    data: PathBodies | None
    missing: list[Path]

    @classmethod
    def of(cls, plan: LayerPlan) -> "_LayerPaths":
        packed = plan.packed
        if packed is not None and packed.data is not None and len(packed.roles) and (packed.rows >= 0).all():
            is_path = packed.kind != STATE
            kind, ref = packed.kind[is_path], packed.ref[is_path]
            extra = np.flatnonzero(kind == EXTRA)
            column = np.where(kind == EXTRA, 0, ref)
            codes = packed.roles[column].astype(np.int64)
            widths, colors = packed.widths[column], packed.colors[column].astype(np.int64)
            rows = packed.rows[column].astype(np.int64)
            missing = [packed.extras[r] for r in ref[extra].tolist()]
            if missing:
                roles, extra_widths, extra_colors = zip(*map(attrgetter("role", "width", "color"), missing))
                codes[extra] = [ROLE_CODE[r] for r in roles]
                widths[extra], colors[extra], rows[extra] = extra_widths, extra_colors, -1
            before = np.cumsum(is_path) - is_path
            return cls(len(ref), codes, widths, colors, packed.ref[~is_path], before[~is_path], rows, packed.data,
                       missing)
        steps = plan.steps
        is_path = np.fromiter((step.__class__ is not SetState for step in steps), dtype=bool, count=len(steps))
        paths = [step for step in steps if step.__class__ is not SetState]
        n = len(paths)
        roles, widths, colors = zip(*map(attrgetter("role", "width", "color"), paths)) if paths else ((), (), ())
        before = np.cumsum(is_path) - is_path
        states = np.array([step.color for step in steps if step.__class__ is SetState], dtype=np.int64)
        prepared = plan.prepared
        rows = np.full(n, -1, dtype=np.int64)
        missing = paths
        if prepared is not None and paths:
            get = prepared.rows.get
            rows[:] = [get(p, -1) for p in paths]
            missing = [paths[i] for i in np.flatnonzero(rows < 0).tolist()]
        return cls(n, np.fromiter(map(ROLE_CODE.__getitem__, roles), dtype=np.int64, count=n),
                   np.array(widths, dtype=np.float64), np.array(colors, dtype=np.int64), states,
                   before[~is_path], rows, prepared.data if prepared is not None and paths else None, missing)


def _choices(values: np.ndarray, shown: np.ndarray, line: Callable[[float], str]) -> tuple[np.ndarray, np.ndarray]:
    """A :func:`_text_table` of ``line(v)`` for the distinct ``values[shown]`` (and an
    empty last column) and the column of each row: its line where ``shown``, else empty."""
    distinct, which = np.unique(values[shown], return_inverse=True)
    codes = np.full(len(values), len(distinct), dtype=np.int64)
    codes[shown] = which
    return _text_table([line(v) for v in distinct.tolist()] + [""]), codes


class GcodeWriter:
    """Writes G-code to ``out`` layer by layer and gathers statistics.

    Args:
        out: text stream written to (nothing is kept in memory between layers).
        settings: the slice's settings (speeds, retraction, filament, G-code texts).
        palette: the palette (``size``, ``n_materials``, ``centers``, ``label``).
        dialect: turns state changes into commands (:func:`~.dialects.make_dialect`).
        comments: extra ``; key = value`` header lines (design file, command line...).
        thumbnails: ``(png_bytes, width, height)`` pictures embedded in the header.
        materials: the design's materials in channel order, for the colors of the
            settings block at the end (:mod:`.prusa_config`; default colors without them).
        now: the time stamp of the first line (default: the current UTC time).
        grading: the design's instantaneous attributes
            (:class:`~fgslice.machine.grading.SegmentGrading`) for the paths it formats
            itself; None for none.
        time_model: run the time model on the text written; False when another process
            reads the file anyway (the verifier) and plans its moves there, handing the
            time to :meth:`finish`.
    """

    def __init__(
        self,
        out: TextIO,
        settings: Settings,
        palette: PaletteLike,
        dialect: Dialect,
        *,
        comments: dict[str, str],
        thumbnails: Iterable[tuple[bytes, int, int]] = (),
        materials: Sequence[Material] = (),
        now: datetime | None = None,
        grading=None,
        time_model: bool = True,
    ) -> None:
        self.out = out
        self.grading = grading
        self._fan_pwm: int | None = None  # the last M106 S written (graded fan only)
        self._commanded: dict[str, list[float]] = {}
        self.settings = settings
        self.palette = palette
        self.dialect = dialect
        self.comments = dict(comments)
        self.thumbnails = tuple(thumbnails)
        self.materials = tuple(materials)
        self.now = now
        self.filament_area = np.pi * settings.filament_diameter**2 / 4.0
        self._state: int | None = None
        self._state_texts: dict[tuple, str] = {}  # by (previous state, state)
        self._pos: tuple[float, float] | None = None
        self._z = 0.0
        self._role: Role | None = None
        self._width: float | None = None
        self._feed: float | None = None
        self._retracted = False
        self._wipe_end: tuple[float, float] | None = None  # where the last wipe left the nozzle
        self._extruded = False
        self._fan_on = False
        self._e_written = 0.0
        self._stats_layers = 0
        self._travel_mm = 0.0
        self._timing = TimeModel(settings) if time_model else None
        self._change_s = 0.0  # the dialect's fixed time of the state changes, s
        self._ended = False
        self._state_changes = 0
        self._tool_changes = 0  # changes of the material color (of the tool on a toolchanger)
        self._retractions = 0
        self._volume_by_color: dict[int, float] = {}
        self._purge_mm3 = 0.0
        self._bbox_min = np.full(3, np.inf)
        self._bbox_max = np.full(3, -np.inf)
        self._skipped_paths = 0
        self._colors_used: set[int] = set()
        self._made: dict[tuple, tuple] = {}  # bodies formatted here, by geometry (purge lines repeat)
        self._made_paths: dict[Path, tuple] = {}  # the same, by path (purge towers reuse their paths)
        self._type_table = _text_table(TYPE_LINES)
        self._feed_tables: dict[bool, tuple[np.ndarray, np.ndarray]] = {}

    # -- header ---------------------------------------------------------------------
    def recorded_settings(self) -> dict[str, object]:
        """The settings the file records (header and settings block), by name: all of them
        but the attribute-grading ones when the design grades no instantaneous attribute,
        and ``filament_colors`` when it is empty; ``nozzle_temperature`` without a needless
        ``.0``."""
        unused = (() if self.grading is not None else GRADING_SETTINGS) + (
            () if isinstance(self.palette, StatePalette) else STATE_SETTINGS) + (
            () if self.settings.filament_colors else ("filament_colors",))
        recorded = {k: v for k, v in self.settings.as_dict().items() if k not in unused}
        # Moonraker reads the first '; nozzle_temperature' (the header's, in a file under 1 MiB) as integers
        recorded["nozzle_temperature"] = fmt(self.settings.nozzle_temperature, 1)
        return recorded

    def write_header(self) -> None:
        """The first line, thumbnails, comments, settings, palette and start G-code."""
        s = self.settings
        now = self.now or datetime.now(timezone.utc)
        lines = [f"; generated by fgslice {fgslice_version()} on {now:%Y-%m-%d} at {now:%H:%M:%S} UTC", ""]
        text = "\n".join(lines) + "\n"
        text += "".join(thumbnail_block(png, w, h) for png, w, h in self.thumbnails)
        lines = [""] + [f"; {k} = {one_line(v)}" for k, v in self.comments.items()]
        lines += [f"; {k} = {one_line(v)}" for k, v in self.recorded_settings().items()]
        lines.append(f"; palette = {self.palette.size} colors of {self.palette.n_materials} materials, dialect {self.dialect.name}")
        lines += [
            f"; color {c} = {self.palette.label(c)} : {self.dialect.describe(c)}" for c in range(self.palette.size)
        ]
        lines += [f"; color {c} = {label} : {self.dialect.describe(c)}" for c, label in self.dialect.extra_colors().items()]
        lines += ["", fill_placeholders(s.start_gcode, self._temperature_values(), "start_gcode")]
        lines += self.dialect.start_commands() + ["M83", "M107", ""]
        body = "\n".join(lines)
        if self._timing:
            self._timing.feed(body)
        self.out.write(text + body)

    def _temperature_values(self) -> dict[str, str]:
        return {
            "nozzle_temperature": fmt(self.settings.nozzle_temperature, 1),
            "bed_temperature": fmt(self.settings.bed_temperature, 1),
        }

    # -- layers ---------------------------------------------------------------------
    def write_layer(self, plan: LayerPlan) -> None:
        """Write one layer: layer annotations, Z move, fan, state changes and paths."""
        s = self.settings
        z = fmt(plan.z, 3)
        parts = [f";BEFORE_LAYER_CHANGE\n;{z}\n;LAYER_CHANGE\n;Z:{z}\n;HEIGHT:{fmt(plan.height, 3)}\n"]
        if self._extruded and not self._retracted and s.retract_length > 0:
            parts.append(self._retract_line())
            self._retracted = True
            self._retractions += 1
        parts.append(f"G1 Z{fmt(plan.z, 3)} F{fmt(s.z_speed * 60, 1)}\n")
        self._z = plan.z
        if not self._fan_on and plan.index >= s.fan_off_layers and s.fan_speed > 0:
            self._fan_on = True
            if self.grading is None or "fan" not in self.grading.active(plan.index):  # else the paths set it
                parts.append(f"M106 S{int(round(s.fan_speed * 2.55))}\n")
                self._fan_pwm = int(round(s.fan_speed * 2.55))

        layer = _LayerPaths.of(plan)
        if layer.n:
            at, texts, colors = self._state_changes_before(layer)
            trailing: list[str] = []
            parts.extend(self._write_paths(layer, at, texts, colors, plan, trailing))
            pending = "".join(trailing)
        else:
            pending = "".join(self._set_state(c) for c in layer.states)
        if pending:
            parts.append(pending)
            if self.dialect.moves_head:
                self._pos = None
        self._stats_layers += 1
        text = "".join(parts)
        if self._timing:
            self._timing.feed(text)
        self.out.write(text)

    def _state_changes_before(self, layer: "_LayerPaths") -> tuple[np.ndarray, list[str], np.ndarray]:
        """The state changes of the layer that change the state: the path each one is due
        before (``layer.n``: after the last path) and its text, in order; and the state each
        path is printed in (-1 for "unknown"). A path of a known color printed while the
        state is still unknown (no SetState yet in the print) sets that state first."""
        n = layer.n
        at = layer.state_before.tolist()  # the path each SetState precedes (n: none)
        changes = layer.states.tolist()
        if self._state is None:
            known = np.flatnonzero(layer.colors >= 0)
            if len(known) and (not at or known[0] < at[0]):
                at.insert(0, int(known[0]))
                changes.insert(0, int(layer.colors[known[0]]))
        due, texts, state_after = [], [], []
        start_state = -1 if self._state is None else self._state
        for j, color in zip(at, changes):
            text = self._set_state(color)
            if text:
                due.append(j)
                texts.append(text)
            state_after.append(self._state)
        colors = np.array([start_state, *state_after], dtype=np.int64)
        colors = colors[np.searchsorted(np.array(at, dtype=np.int64), np.arange(n), side="right")]
        return np.array(due, dtype=np.int64), texts, colors

    def _set_state(self, color: int) -> str:
        """The lines of a state change to ``color``, or "" if it is the current state."""
        if color == self._state:
            return ""
        previous, self._state = self._state, color
        self._state_changes += 1
        if previous is None or material_colors(self.palette, (previous,)) != material_colors(self.palette, (color,)):
            self._tool_changes += 1
        self._colors_used.add(color)
        self._change_s += self.dialect.change_time(previous, color)
        text = self._state_texts.get((previous, color))
        if text is None:
            text = self._state_texts[previous, color] = "\n".join(self.dialect.change_commands(previous, color)) + "\n"
        return text

    def _feeds(self, first_layer: bool) -> tuple[np.ndarray, np.ndarray]:
        """Print speed (mm/s) of each role (:data:`ROLES`) on the first or any other layer,
        and the :func:`_text_table` of their ``G1 F`` lines (last column empty)."""
        known = self._feed_tables.get(first_layer)
        if known is not None:
            return known
        by_role = role_speeds(self.settings, first_layer)
        known = self._feed_tables[first_layer] = (
            by_role, _text_table([f"G1 F{fmt(f * 60, 1)}\n" for f in by_role.tolist()] + [""]))
        return known

    def _retract_line(self, sign: int = -1) -> str:
        """``G1 E-<retract_length>`` (``sign`` -1) or the un-retraction (``sign`` 1)."""
        s = self.settings
        return f"G1 E{fmt(sign * s.retract_length, 5)} F{fmt(s.retract_speed * 60, 1)}\n"

    def _bodies(self, layer: "_LayerPaths", plan: LayerPlan) -> tuple[PathBodies, np.ndarray, str]:
        """The bodies of the layer's paths: the prepared ones, the others formatted now
        (all in bulk when none is prepared; else one by one, reused by path or by
        geometry: purge lines repeat from layer to layer); returns the bodies, each
        path's row in them and the text the rows' bounds index."""
        rows, data = layer.rows, layer.data
        graded = None
        if self.grading is not None and self.grading.active(plan.index):
            graded = lambda roles: layer_grade(self.grading, plan, self.settings, roles)  # noqa: E731
        if data is None:
            fresh = format_bodies(layer.missing, self.filament_area, graded)
            return fresh, np.arange(layer.n), fresh.text
        missing = np.flatnonzero(rows < 0)
        if not len(missing):
            return data, rows, data.text
        made, by_path = self._made, self._made_paths
        if len(made) > MADE_BODIES or len(by_path) > MADE_BODIES:
            made.clear()
            by_path.clear()
        todo = [p for p in layer.missing if p not in by_path]
        if todo:
            keys = [(p.points.tobytes(), p.closed, p.width, p.height) for p in todo]
            if graded:  # graded moves depend on the role and the height too
                keys = [(*key, p.role, plan.z) for key, p in zip(keys, todo)]
            new = {k: p for k, p in zip(keys, todo) if k not in made}
            if new:
                fresh = format_bodies(list(new.values()), self.filament_area, graded)
                cuts = fresh.bounds.tolist()
                columns = zip(fresh.start.tolist(), fresh.end.tolist(), fresh.low.tolist(), fresh.high.tolist(),
                              fresh.e.tolist(), fresh.length.tolist(), *(_graded_rows(fresh) if graded else ()))
                for key, a, b, row in zip(new, cuts[:-1], cuts[1:], columns):
                    made[key] = (fresh.text[a:b], *row)
            by_path.update(zip(todo, map(made.__getitem__, keys)))
        texts, start, end, low, high, e, length, *extra = zip(*map(by_path.__getitem__, layer.missing))
        sizes = np.fromiter(map(len, texts), dtype=np.int64, count=len(texts))
        old = data
        rows = rows.copy()
        rows[missing] = len(old.e) + np.arange(len(missing))
        joined = PathBodies(
            text="",
            bounds=np.concatenate([old.bounds, old.bounds[-1] + np.cumsum(sizes)]),
            start=np.concatenate([old.start, np.array(start).reshape(-1, 2)]),
            end=np.concatenate([old.end, np.array(end).reshape(-1, 2)]),
            low=np.concatenate([old.low, np.array(low).reshape(-1, 2)]),
            high=np.concatenate([old.high, np.array(high).reshape(-1, 2)]),
            e=np.concatenate([old.e, e]),
            length=np.concatenate([old.length, length]),
        )
        if graded:
            _join_graded(joined, old, extra)
        return joined, rows, old.text + "".join(texts)

    def _write_paths(
        self,
        layer: "_LayerPaths",
        at: np.ndarray,
        texts: list[str],
        colors: np.ndarray,
        plan: LayerPlan,
        trailing: list[str],
    ) -> list[str]:
        """The text of a layer's paths: their bodies (:meth:`_bodies`), travels,
        annotations, in bulk.

        ``texts[k]`` is a state change due before path ``at[k]`` (after the last path when
        ``at[k]`` is ``layer.n``); ``colors[i]`` is the state path ``i`` is printed in. A
        state change due before paths that print nothing goes before the next printed
        path, else to ``trailing``; with a dialect that moves the head, the next path's
        travel starts from an unknown position.
        """
        s = self.settings
        layer_index = plan.index
        bodies, rows, text = self._bodies(layer, plan)
        is_printed = bodies.length[rows] > 0
        printed = np.flatnonzero(is_printed)
        n = len(printed)
        self._skipped_paths += layer.n - n
        changes: dict[int, str] = {}
        for k, change in zip(np.searchsorted(printed, at).tolist(), texts):
            if k == n:
                trailing.append(change)
            else:
                changes[k] = changes.get(k, "") + change
        if not n:
            return []
        rows = rows[printed]
        widths = np.round(layer.widths[printed], 4)  # as ;WIDTH: writes them: a repeated line is left out
        starts, last = bodies.start[rows], bodies.end[rows]

        codes = layer.codes[printed]
        by_role, feed_table = self._feeds(layer_index == 0)
        feeds = by_role[codes]
        prev = np.vstack([[np.nan, np.nan] if self._pos is None else [self._pos], last[:-1]])
        unknown = np.isnan(prev[:, 0])
        if self.dialect.moves_head:
            unknown[list(changes)] = True
        travel = unknown | (starts != prev).any(axis=1)
        dist = np.where(unknown, 0.0, np.hypot(*(starts - np.nan_to_num(prev)).T))
        may_retract = np.ones(n, dtype=bool)
        may_retract[0] = self._extruded and not self._retracted
        retract = travel & ~unknown & (dist > s.retract_min_travel) & may_retract & (s.retract_length > 0)
        retracted = retract.copy()
        retracted[0] |= self._retracted
        hop = retracted & travel & (s.z_hop > 0)
        # paths ending before a retraction (or the layer change) coast and wipe there
        ends_retracting = np.append(retract[1:], s.retract_length > 0)
        wiped = ends_retracting if s.wipe_mm > 0 else np.zeros(n, dtype=bool)
        before_code = np.append(-1 if self._role is None else ROLE_CODE[self._role], codes[:-1])
        new_width = widths != np.append(np.nan if self._width is None else self._width, widths[:-1])
        new_feed = travel | (feeds != np.append(np.nan if self._feed is None else self._feed, feeds[:-1]))

        header, cuts = self._headers(
            starts, travel, retract & ~np.append(False, wiped[:-1]), hop, retracted,
            np.where(codes != before_code, codes, len(ROLES)),
            _choices(widths, new_width, lambda w: f";WIDTH:{fmt(w, 4)}\n"),
            (feed_table, np.where(new_feed, codes, len(ROLES))),
        )
        pieces = [""] * (2 * n)
        heads = cuts.tolist()
        pieces[0::2] = [header[a:b] for a, b in zip(heads[:-1], heads[1:])]
        pieces[1::2] = [text[a:b] for a, b in zip(bodies.bounds[rows].tolist(), bodies.bounds[rows + 1].tolist())]
        for k, change in changes.items():
            pieces[2 * k] = change + pieces[2 * k]
        filament = bodies.e[rows]
        if s.coast_mm > 0 or s.wipe_mm > 0:
            filament = filament.copy()
            self._coast_and_wipe(pieces, np.flatnonzero(ends_retracting), starts, filament, s.wipe_mm > 0)
        if bodies.fan is not None:
            self._command_fan(bodies.fan[rows], pieces)
        for name, ranges in (bodies.commanded or {}).items():
            low_high = self._commanded.setdefault(name, [np.inf, -np.inf])
            low_high[0] = min(low_high[0], float(np.nanmin(ranges[rows, 0], initial=np.inf)))
            low_high[1] = max(low_high[1], float(np.nanmax(ranges[rows, 1], initial=-np.inf)))

        self._retractions += int(retract.sum())
        self._travel_mm += float(dist.sum())
        self._e_written += float(filament.sum())
        volume = filament * self.filament_area
        used, which = np.unique(colors[printed], return_inverse=True)
        for color, v in zip(used.tolist(), np.bincount(which, weights=volume).tolist()):
            self._volume_by_color[color] = self._volume_by_color.get(color, 0.0) + v
        self._purge_mm3 += float(volume[codes == ROLE_CODE[Role.WIPE_TOWER]].sum())
        self._bbox_min = np.minimum(self._bbox_min, [*bodies.low[rows].min(axis=0), self._z])
        self._bbox_max = np.maximum(self._bbox_max, [*bodies.high[rows].max(axis=0), self._z])
        self._pos = (float(last[-1, 0]), float(last[-1, 1]))
        self._role, self._width, self._feed = ROLES[codes[-1]], float(widths[-1]), float(feeds[-1])
        self._retracted = False
        self._extruded = True
        if wiped[-1]:  # the layer's last path wiped and retracted already
            self._pos, self._retracted = self._wipe_end, True
            self._feed = None
            self._retractions += 1
        return pieces

    def _coast_and_wipe(self, pieces: list[str], paths: np.ndarray, starts: np.ndarray, filament: np.ndarray,
                        wiping: bool) -> None:
        """Coast the last ``coast_mm`` of each of ``paths`` (indices of printed paths) and,
        with ``wiping``, wipe back along it while retracting (:mod:`.coasting`); lowers
        ``filament`` (E per path) by what coasting no longer extrudes."""
        s = self.settings
        retract_feed, travel_feed = fmt(s.retract_speed * 60, 1), fmt(s.travel_speed * 60, 1)
        for k in paths.tolist():
            text, saved, points = coast(pieces[2 * k + 1], tuple(starts[k]), s.coast_mm)
            filament[k] -= saved
            if wiping:
                moves, length, self._wipe_end = wipe(points, s.wipe_mm, s.retract_length, retract_feed, travel_feed)
                text += moves
                self._travel_mm += length
            pieces[2 * k + 1] = text

    def _command_fan(self, fan: np.ndarray, pieces: list[str]) -> None:
        """Put an ``M106 S`` before the body of each printed path (``fan`` ``(n, 2)``, see
        :attr:`PathBodies.fan`) that starts at another fan than the print is at."""
        n = len(fan)
        sets = fan[:, 1] >= 0
        latest = np.maximum.accumulate(np.where(sets, np.arange(n), -1))
        current = -2 if self._fan_pwm is None else self._fan_pwm
        before = np.concatenate([[current], np.where(latest[:-1] >= 0, fan[np.maximum(latest[:-1], 0), 1], current)])
        for k in np.flatnonzero((fan[:, 0] >= 0) & (fan[:, 0] != before)).tolist():
            pieces[2 * k + 1] = f"M106 S{int(fan[k, 0])}\n" + pieces[2 * k + 1]
        if sets.any():
            self._fan_pwm = int(fan[latest[-1], 1])

    def _headers(
        self,
        starts: np.ndarray,
        travel: np.ndarray,
        retract: np.ndarray,
        hop: np.ndarray,
        retracted: np.ndarray,
        type_codes: np.ndarray,
        width_lines: tuple[np.ndarray, np.ndarray],
        feed_lines: tuple[np.ndarray, np.ndarray],
    ) -> tuple[str, np.ndarray]:
        """What goes before each of ``n`` paths, as one text and ``(n + 1,)`` offsets:
        retraction, lift, travel to ``starts`` (mm), lowering, un-retraction where the
        ``(n,)`` masks say, the ``;TYPE:`` line of ``type_codes`` (``len(ROLES)``: none),
        then the width and feed lines (``(table, codes)``, as :func:`_choices` gives)."""
        s = self.settings
        n = len(starts)
        lift = f"G1 Z{fmt(self._z + s.z_hop, 3)} F{fmt(s.z_speed * 60, 1)}\n"
        lower = f"G1 Z{fmt(self._z, 3)} F{fmt(s.z_speed * 60, 1)}\n"
        retract_line, unretract_line = self._retract_line(), self._retract_line(1)
        moves, move_lengths = _line_blocks([("G0 X", starts[:, 0], 3), (" Y", starts[:, 1], 3)],
                                           f" F{fmt(s.travel_speed * 60, 1)}\n")
        moves = _stack(moves, n)
        moves *= travel
        blocks = [_literal(retract_line) * retract, _literal(lift) * hop, moves, _literal(lower) * hop,
                  _literal(unretract_line) * retracted]
        lengths = (retract * len(retract_line) + hop * (len(lift) + len(lower)) + retracted * len(unretract_line)
                   + travel * move_lengths)
        for table, codes in ((self._type_table, type_codes), width_lines, feed_lines):
            blocks.append(table[:, codes])
            lengths += np.count_nonzero(table, axis=0)[codes]
        return _assemble(blocks, n, lengths)

    # -- footer ---------------------------------------------------------------------
    def write_end(self) -> None:
        """Write the end G-code (once; :meth:`finish` writes it if this was not called):
        the last of the file the machine executes, what follows is comments."""
        if self._ended:
            return
        self._ended = True
        end = fill_placeholders(self.settings.end_gcode, self._temperature_values(), "end_gcode")
        if self._timing:
            self._timing.feed(end)
        self.out.write("\n" + end)

    def finish(self, planned_s: float | None = None) -> dict:
        """Write the end G-code and the footer; return the statistics (see docs/gcode.md).

        Args:
            planned_s: seconds of the file's moves and dwells up to the end G-code as a
                :class:`~fgslice.machine.timing.TimeModel` read elsewhere plans them
                (with ``time_model=False``); None: this writer's own model's.
        """
        s = self.settings
        filament_mm = self._e_written
        extruded = filament_mm * self.filament_area
        grams_per_mm3 = s.filament_density / 1000.0
        self.write_end()
        if planned_s is None:
            if self._timing is None:
                raise ValueError("a writer without its time model needs the planned time")
            planned_s = self._timing.finish()
        time_s = planned_s + self._change_s
        footer = [
            "",
            "",
            f"; filament used [mm] = {filament_mm:.2f}",
            f"; filament used [cm3] = {extruded / 1000.0:.2f}",
            "; filament used [g] = " + ", ".join(
                f"{v * grams_per_mm3:.2f}" for v in tool_volumes(s, self.palette, self.materials, self._volume_by_color)),
            f"; total filament used [g] = {extruded * grams_per_mm3:.2f}",
            f"; state changes = {self._state_changes}",
            f"; estimated printing time (normal mode) = {format_duration(time_s)}",
            *footer_block(s, self.palette, self.materials, version=fgslice_version(),
                          tool_changes=self._tool_changes, colors_used=sorted(self._colors_used),
                          recorded=self.recorded_settings()),
            "",
        ]
        self.out.write("\n".join(footer))
        warnings = []
        if self._skipped_paths:
            warnings.append(f"{self._skipped_paths} paths shorter than 0.001 mm were not written")
        bbox = (
            [self._bbox_min.tolist(), self._bbox_max.tolist()] if np.isfinite(self._bbox_min).all() else None
        )
        commanded = {k: v for k, v in self._commanded.items() if v[0] <= v[1]}
        if isinstance(self.palette, StatePalette) and self._colors_used:
            temperatures = self.palette.temperatures[sorted(self._colors_used)]
            commanded["temperature"] = [float(temperatures.min()), float(temperatures.max())]
        return {
            "layers": self._stats_layers,
            "colors": self.palette.size,
            "colors_used": len(self._colors_used),
            "extruded_mm3": extruded,
            "extruded_mm3_by_color": dict(sorted(self._volume_by_color.items())),
            "travel_mm": self._travel_mm,
            "state_changes": self._state_changes,
            "retractions": self._retractions,
            "estimated_time_s": time_s,
            "extrusion_bbox": bbox,
            "purge_mm3": self._purge_mm3,
            "purge_g": self._purge_mm3 * grams_per_mm3,
            "filament_mm": filament_mm,
            "filament_g": extruded * grams_per_mm3,
            "warnings": warnings,
            **({"attributes": commanded} if commanded else {}),
        }


def _graded_rows(bodies: PathBodies) -> list[list]:
    """The graded columns of ``bodies`` as one list per column, a row per path: fan
    ``(start, end)``, then each commanded range (for the writer's cache)."""
    n = len(bodies.e)
    fan = np.full((n, 2), -1) if bodies.fan is None else bodies.fan
    return [fan.tolist(), [dict(zip(bodies.commanded or {}, r))
                           for r in zip(*(v.tolist() for v in (bodies.commanded or {}).values()))]
            if bodies.commanded else [{}] * n]


def _join_graded(joined: PathBodies, old: PathBodies, extra: list[tuple]) -> None:
    """Set the graded columns of ``joined``: ``old``'s rows, then the rows ``extra``
    (fans, commanded ranges: the columns of :func:`_graded_rows`)."""
    fan, commanded = extra
    n = len(old.e)
    joined.fan = np.concatenate([np.full((n, 2), -1) if old.fan is None else old.fan,
                                 np.array(fan, dtype=np.int64).reshape(-1, 2)])
    names = set(old.commanded or {}).union(*map(set, commanded))
    joined.commanded = {
        name: np.concatenate([(old.commanded or {}).get(name, np.full((n, 2), np.nan)),
                              np.array([r.get(name, [np.nan, np.nan]) for r in commanded]).reshape(-1, 2)])
        for name in names
    }


def one_line(value: object) -> str:
    """A settings value as one comment line (newlines written as ``\\n``)."""
    text = "" if value is None else str(value)
    return text.replace("\r", "").replace("\n", "\\n")
