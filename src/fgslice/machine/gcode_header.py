"""Reading back the comments :class:`fgslice.machine.gcode.GcodeWriter` puts around the moves.

The header is everything before the first ``;LAYER_CHANGE``: ``; key = value`` comments
(the job's comments such as ``placement_offset`` and ``materials``, then every setting)
and one ``; color i = label : commands`` line per palette color. The footer is what
follows the last ``;LAYER_CHANGE``: ``; filament used [mm] = ...``, ``; estimated
printing time (normal mode) = ...`` and the like, then the PrusaSlicer-style settings
block (:mod:`fgslice.machine.prusa_config`), which is not part of the footer read here.

The first occurrence of a key wins. Values fgslice interprets (offset, palette size,
temperatures) are validated here; a malformed one is a :class:`GcodeError` naming the
file and the 1-based line. Files of other slicers simply lack these keys.
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass, field

from fgslice.errors import GcodeError

LAYER_CHANGE = ";LAYER_CHANGE"
SETTINGS_BLOCK = "; prusaslicer_config = begin"
_KEY_VALUE = re.compile(r"^;[ \t]*([A-Za-z_][A-Za-z0-9_]*)[ \t]*=[ \t]*(.*?)[ \t\r]*$", re.MULTILINE)
_COLOR_LINE = re.compile(r"^;[ \t]*color[ \t]+(\d+)[ \t]*=[ \t]*([^:\r\n]*?)[ \t]*(?::[ \t]*([^\r\n]*?))?[ \t\r]*$",
                         re.MULTILINE)
_FOOTER_LINE = re.compile(r"^;[ \t]*([^=\n;]+?)[ \t]*=[ \t]*([^\r\n]*?)[ \t\r]*$", re.MULTILINE)
_CHUNK_BYTES = 1 << 20
_FOOTER_BYTES = 1 << 16


@dataclass(frozen=True)
class GcodeHeader:
    """What a G-code file's header comments say (every field optional).

    Attributes:
        placement_offset: ``bed = design + offset``, mm (three finite numbers).
        colors: palette size N.
        palette: the palette kind (``centers`` or ``ends``; None when the file does not say).
        materials: the design's material names, in the order of the mixing channels.
        dialect: the machine dialect name (``marlin-mixing``, ``toolchanger``, ...).
        temperature_a: nozzle target at 100 % of the first material, degC.
        temperature_b: nozzle target at 100 % of the second material, degC.
        labels: palette color index -> its label (``; color i = label : commands``).
        commands: palette color index -> the commands that set it.
        settings: every ``; key = value`` comment, as text.
        lines: key of ``settings`` -> its 1-based line number.
    """

    placement_offset: tuple[float, float, float] | None = None
    colors: int | None = None
    palette: str | None = None
    materials: tuple[str, ...] = ()
    dialect: str | None = None
    temperature_a: float | None = None
    temperature_b: float | None = None
    labels: dict[int, str] = field(default_factory=dict)
    commands: dict[int, str] = field(default_factory=dict)
    settings: dict[str, str] = field(default_factory=dict)
    lines: dict[str, int] = field(default_factory=dict)


def _line_numbers(text: str, positions: list[int]) -> list[int]:
    """1-based line numbers of increasing character ``positions`` in ``text``."""
    out, line, previous = [], 1, 0
    for position in positions:
        line += text.count("\n", previous, position)
        previous = position
        out.append(line)
    return out


def _temperature(values: dict[str, str], lines: dict[str, int], key: str, file: str | None) -> float | None:
    if key not in values:
        return None
    try:
        value = float(values[key])
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise GcodeError(f"header '{key}' value '{values[key]}' is not a number", file=file, line=lines[key])
    return value


def parse_header(text: str, file: str | None = None) -> GcodeHeader:
    """The :class:`GcodeHeader` of G-code ``text`` (its comments before the first ``;LAYER_CHANGE``).

    Args:
        text: the file's text, or its beginning up to at least the first layer change.
        file: the file name errors report.

    Raises:
        GcodeError: ``placement_offset``, ``colors`` or a temperature is malformed.
    """
    end = text.find(LAYER_CHANGE)
    head = text if end < 0 else text[:end]
    matches = list(_KEY_VALUE.finditer(head))
    values: dict[str, str] = {}
    lines: dict[str, int] = {}
    for match, line in zip(matches, _line_numbers(head, [m.start() for m in matches])):
        values.setdefault(match.group(1), match.group(2))
        lines.setdefault(match.group(1), line)
    labels: dict[int, str] = {}
    commands: dict[int, str] = {}
    for match in _COLOR_LINE.finditer(head):
        labels.setdefault(int(match.group(1)), match.group(2))
        commands.setdefault(int(match.group(1)), match.group(3) or "")
    offset = None
    if "placement_offset" in values:
        try:
            parts = tuple(float(p) for p in values["placement_offset"].split(","))
        except ValueError:
            parts = ()
        if len(parts) != 3 or not all(math.isfinite(p) for p in parts):
            raise GcodeError(f"header 'placement_offset' value '{values['placement_offset']}' is not three numbers",
                             file=file, line=lines["placement_offset"], hint="expected '; placement_offset = dx,dy,dz' in mm")
        offset = parts
    colors = None
    if "colors" in values:
        if not values["colors"].isdigit() or int(values["colors"]) < 1:
            raise GcodeError(f"header 'colors' value '{values['colors']}' is not a palette size", file=file,
                             line=lines["colors"], hint="expected '; colors = N'")
        colors = int(values["colors"])
    return GcodeHeader(
        placement_offset=offset,
        colors=colors,
        palette=values.get("palette"),
        materials=tuple(n.strip() for n in values.get("materials", "").split(",") if n.strip()),
        dialect=values.get("dialect"),
        temperature_a=_temperature(values, lines, "temperature_a", file),
        temperature_b=_temperature(values, lines, "temperature_b", file),
        labels=labels,
        commands=commands,
        settings=values,
        lines=lines,
    )


def read_header(path: str | os.PathLike) -> GcodeHeader:
    """The :class:`GcodeHeader` of a G-code file, reading it only up to the first ``;LAYER_CHANGE``.

    Raises:
        GcodeError: the file cannot be read, or a header value is malformed.
    """
    chunks: list[bytes] = []
    marker = LAYER_CHANGE.encode()
    try:
        with open(path, "rb") as handle:
            while chunk := handle.read(_CHUNK_BYTES):
                chunks.append(chunk)
                if marker in b"".join(chunks[-2:]):
                    break
    except OSError as exc:
        raise GcodeError(f"cannot read G-code: {exc.strerror}", file=str(path)) from None
    return parse_header(b"".join(chunks).decode("utf-8", errors="replace"), str(path))


def read_footer(path: str | os.PathLike) -> dict[str, str]:
    """``; key = value`` comments after the last ``;LAYER_CHANGE`` of a G-code file:
    ``filament used [mm]``, ``estimated printing time (normal mode)``, ..., up to the
    PrusaSlicer-style settings block (``; prusaslicer_config = begin``). Only the last
    64 KiB are read (all of them when the last layer is longer); a file that small without
    a layer change has no footer.

    Raises:
        GcodeError: the file cannot be read.
    """
    try:
        with open(path, "rb") as handle:
            size = handle.seek(0, os.SEEK_END)
            handle.seek(max(0, size - _FOOTER_BYTES))
            tail = handle.read().decode("utf-8", errors="replace")
    except OSError as exc:
        raise GcodeError(f"cannot read G-code: {exc.strerror}", file=str(path)) from None
    last = tail.rfind(LAYER_CHANGE)
    if last < 0 and size <= _FOOTER_BYTES:
        return {}
    block = tail.find(SETTINGS_BLOCK, max(last, 0))
    out: dict[str, str] = {}
    for key, value in _FOOTER_LINE.findall(tail, max(last, 0), len(tail) if block < 0 else block):
        out.setdefault(key, value)
    return out
