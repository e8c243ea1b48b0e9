"""Coasting and wipe: what the writer does to a path's moves before a retraction.

* **Coasting** (``coast_mm``): the last ``coast_mm`` of the path are moved without
  extrusion (the melt still under pressure fills them), as PrusaSlicer's and Cura's
  coasting; the move in which coasting starts is split there. A path shorter than
  ``coast_mm`` is coasted whole.
* **Wipe** (``wipe_mm``): after the path, the nozzle moves back along it for ``wipe_mm``
  at travel speed while it retracts (``retract_length`` spread over the wipe in
  proportion to its moves; what a path shorter than the wipe leaves is retracted at its
  end), as PrusaSlicer's wipe on retraction. The writer then omits the retraction before
  the travel.

Both apply to a path followed by a retracting travel, or by the layer change. The moves
are the writer's ``G1 X Y E`` lines (:func:`~fgslice.machine.gcode.format_moves`; an
``F`` word or ``M106`` lines of graded attributes are kept). Units mm.
"""

from __future__ import annotations

import re

import numpy as np

_MOVE = re.compile(r"G1 X(-?[\d.]+) Y(-?[\d.]+) E(-?[\d.]+)(.*)")


def _number(value: float, decimals: int) -> str:
    text = f"{value:.{decimals}f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


def coast(text: str, start: tuple[float, float], distance: float) -> tuple[str, float, np.ndarray]:
    """The moves ``text`` of a path starting at ``start`` with its last ``distance`` mm
    coasted; returns the new text, the filament (mm of E) no longer extruded, and the
    path's points as written (``(k, 2)``, start first), for a wipe."""
    lines = text.splitlines(keepends=True)
    found = [(i, _MOVE.match(line)) for i, line in enumerate(lines)]
    found = [(i, m) for i, m in found if m]
    points = np.array([start] + [(float(m[1]), float(m[2])) for _, m in found])
    if not found or distance <= 0:
        return text, 0.0, points
    seg = np.hypot(*np.diff(points, axis=0).T)
    from_end = np.cumsum(seg[::-1])[::-1]  # length from each move's start to the path's end
    saved = 0.0
    for k, (i, m) in enumerate(found):
        if from_end[k] <= distance:  # the whole move coasts
            saved += float(m[3])
            lines[i] = f"G1 X{m[1]} Y{m[2]}{m[4]}\n"
        elif from_end[k] - seg[k] < distance:  # coasting starts inside this move
            keep = (from_end[k] - distance) / seg[k]
            at = points[k] + keep * (points[k + 1] - points[k])
            e = float(m[3])
            printed = round(e * keep, 5)
            saved += e - printed
            lines[i] = (f"G1 X{_number(at[0], 3)} Y{_number(at[1], 3)} E{_number(printed, 5)}{m[4]}\n"
                        f"G1 X{m[1]} Y{m[2]}{m[4]}\n")
    return "".join(lines), saved, points


def wipe(points: np.ndarray, distance: float, retract_mm: float, retract_feed: str,
         travel_feed: str) -> tuple[str, float, tuple[float, float]]:
    """Moves back along the path ``points`` (``(k, 2)``, printing order) for ``distance`` mm
    while retracting ``retract_mm`` of filament; returns the text, the length wiped and
    where the nozzle stops.
    ``retract_feed`` and ``travel_feed`` are the ``F`` values (mm/min) as written."""
    back = points[::-1]
    seg = np.hypot(*np.diff(back, axis=0).T)
    done = np.concatenate([[0.0], np.cumsum(seg)])
    lines, left, wiped, at = [], retract_mm, 0.0, back[0]
    for k in range(len(seg)):
        if done[k] >= distance or seg[k] == 0:
            continue
        length = min(seg[k], distance - done[k])
        to = np.round(back[k] + (length / seg[k]) * (back[k + 1] - back[k]), 3)
        share = round(retract_mm * length / distance, 5)
        left -= share
        wiped += length
        lines.append(f"G1 X{_number(to[0], 3)} Y{_number(to[1], 3)} E-{_number(share, 5)} F{travel_feed}\n")
        at = to
    if round(left, 5) > 0:
        lines.append(f"G1 E-{_number(left, 5)} F{retract_feed}\n")
    return "".join(lines), wiped, (float(at[0]), float(at[1]))
