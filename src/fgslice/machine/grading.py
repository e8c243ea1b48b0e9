"""Instantaneous process attributes (fan, flow, speed, feature speeds) along extrusion moves.

The paper's instantaneous parameters need no palette: the design's attribute fields
(:mod:`fgslice.design.attributes`) are sampled along every extrusion move of the part
and each move is cut into pieces over which no field changes by more than
``attribute_tolerance`` points of percent; each piece is commanded the fields' values at
its midpoint (``M106 S``, E scaled by flow, F scaled by speed; see ``docs/gcode.md``).
Nothing is planned ahead and no state change is made.

Conventions: bed-frame XY in mm; the fields are evaluated at the middle height of the
layer in the design frame (bed minus the placement offset); values in percent, clamped
to the machine's limits (:func:`fgslice.design.attributes.limits`). Paths that are not
part of the design (skirt, purge tower, custom) get the settings' values: fan
``fan_speed``, flow and speed 100%. On the first ``fan_off_layers`` layers the fan stays
off whatever the field says (first-layer adhesion), as PrusaSlicer's setting of that name.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fgslice.design.attributes import INSTANTANEOUS, ROLE_SPEEDS, AttributeFields, limits
from fgslice.errors import DesignError
from fgslice.planning.plan import ROLE_CODE
from fgslice.toolpaths.paths import Role

SAMPLE_MM = 0.2
"""Spacing of the field samples along a move, mm (half a 0.4 mm bead): variations of the
field shorter than that may be missed."""

GRADING_SETTINGS = ("attribute_tolerance",)
"""Settings only the grading uses: the header lists them only for designs it grades, so
that the G-code of other designs is what it was before the setting existed."""

CHECK_SAMPLES = 32
"""Grid points along the part's longest side when a slice checks its attributes."""

UNGRADED = np.array([ROLE_CODE[r] for r in (Role.SKIRT, Role.WIPE_TOWER, Role.CUSTOM, Role.SUPPORT,
                                             Role.SUPPORT_INTERFACE)])
"""Role codes of paths that are not part of the design."""


@dataclass(frozen=True)
class Pieces:
    """Moves cut where the fields change, in order.

    Attributes:
        parent: ``(K,)`` the move each piece belongs to.
        ends: ``(K, 2)`` end point of each piece (rounded to 0.001 mm), mm.
        values: attribute name -> ``(K,)`` value commanded over each piece, percent.
    """

    parent: np.ndarray
    ends: np.ndarray
    values: dict[str, np.ndarray]


class SegmentGrading:
    """The instantaneous attributes of a design, ready to cut a layer's moves.

    Args:
        fields: the design's attributes.
        offset: the placement offset (design point = bed point - offset), mm.
        settings: the slice's :class:`~fgslice.settings.Settings` (tolerance, fan, limits).
    """

    def __init__(self, fields: AttributeFields, offset, settings) -> None:
        self.fields = fields
        self.names = tuple(n for n in INSTANTANEOUS if n in fields.names)
        self.offset = tuple(float(v) for v in offset)
        self.tolerance = float(settings.attribute_tolerance)
        # a feature speed attribute undefined at a point leaves the feature's own speed (NaN)
        self.defaults = {"fan": float(settings.fan_speed), "flow": 100.0, "speed": 100.0,
                         **dict.fromkeys(ROLE_SPEEDS, np.nan)}
        bounds = limits(settings)
        self.limits = {name: bounds[name] for name in self.names}
        self.fan_off_layers = settings.fan_off_layers

    @classmethod
    def of(cls, fields: AttributeFields | None, offset, settings) -> "SegmentGrading | None":
        """The grading of ``fields``, or None when they hold no instantaneous attribute."""
        if fields is None or not any(n in fields.names for n in INSTANTANEOUS):
            return None
        return cls(fields, offset, settings)

    def active(self, layer_index: int) -> tuple[str, ...]:
        """The attributes graded on layer ``layer_index`` (no fan on fan-off layers)."""
        return tuple(n for n in self.names if n != "fan" or layer_index >= self.fan_off_layers)

    def values(self, name: str, xy: np.ndarray, z: float) -> np.ndarray:
        """Attribute ``name`` at bed points ``xy`` ``(N, 2)`` of height ``z`` (mm): the
        field, the default where it is not defined, clamped to the machine's limits."""
        ox, oy, oz = self.offset
        raw = self.fields.values(name, xy[:, 0] - ox, xy[:, 1] - oy, z - oz)
        lo, hi = self.limits[name]
        return np.clip(np.where(np.isfinite(raw), raw, self.defaults[name]), lo, hi)

    def cut(self, a: np.ndarray, b: np.ndarray, graded: np.ndarray, z: float, names: tuple[str, ...]) -> Pieces:
        """The moves from ``a`` to ``b`` (``(M, 2)`` rounded points, mm) cut into pieces:
        moves where ``graded`` is False are one piece at the default values; the others
        are sampled every :data:`SAMPLE_MM` and cut so that no field of ``names`` varies
        by more than the tolerance over a piece (the field taken as linear between
        samples), each piece valued at its midpoint."""
        m = len(a)
        delta = b - a
        length = np.hypot(*delta.T)
        steps = np.where(graded, np.maximum(1, np.ceil(length / SAMPLE_MM)), 1).astype(np.int64)
        # samples k / steps, k = 0..steps, of the graded moves
        move = np.repeat(np.arange(m), steps + 1)
        first = np.concatenate([[0], np.cumsum(steps + 1)[:-1]])
        k = np.arange(len(move)) - first[move]
        t = k / steps[move]
        sampled = graded[move]
        points = a[move[sampled]] + t[sampled, None] * delta[move[sampled]]
        change = np.zeros(len(move))
        for name in names:
            v = np.zeros(len(move))
            v[sampled] = np.nan_to_num(self.values(name, points, z), nan=0.0)  # undefined: a change too
            change = np.maximum(change, np.abs(np.diff(v, append=0.0)))
        # interval j runs from sample j to j + 1 of the same move
        interval = np.flatnonzero(k < steps[move])
        dv = change[interval]
        # sub-intervals change by at most an eighth of the tolerance, pieces by seven
        # eighths from their first sub-interval's end: by the tolerance at most in all
        eighth = self.tolerance / 8.0
        parts = np.maximum(1, np.ceil(dv / eighth - 1e-9)).astype(np.int64)
        sub_interval = np.repeat(np.arange(len(interval)), parts)
        sub_first = np.concatenate([[0], np.cumsum(parts)[:-1]])
        i = np.arange(len(sub_interval)) - sub_first[sub_interval] + 1  # 1..parts
        sub_move = move[interval][sub_interval]
        sub_t = (k[interval][sub_interval] + i / parts[sub_interval]) / steps[sub_move]
        step_change = (dv / parts)[sub_interval]
        cum = np.cumsum(step_change)
        move_start = np.concatenate([[0], np.flatnonzero(np.diff(sub_move)) + 1])
        cum -= np.repeat(cum[move_start] - step_change[move_start], np.diff(np.append(move_start, len(sub_move))))
        level = np.floor(cum / (7 * eighth) - 1e-9)
        last = np.ones(len(sub_move), dtype=bool)  # the last sub-interval of each piece
        last[:-1] = (sub_move[1:] != sub_move[:-1]) | (level[1:] != level[:-1])
        parent = sub_move[last]
        t_end = sub_t[last]
        t_end[np.append(parent[1:] != parent[:-1], True)] = 1.0
        t_start = np.concatenate([[0.0], t_end[:-1]])
        t_start[np.concatenate([[True], parent[1:] != parent[:-1]])] = 0.0
        ends = np.round(a[parent] + t_end[:, None] * delta[parent], 3) + 0.0
        ends[t_end == 1.0] = b[parent[t_end == 1.0]]
        middle = a[parent] + ((t_start + t_end) / 2)[:, None] * delta[parent]
        on = graded[parent]
        values = {}
        for name in names:
            v = np.full(len(parent), np.clip(self.defaults[name], *self.limits[name]))
            v[on] = self.values(name, middle[on], z)
            values[name] = v
        return Pieces(parent, ends, values)


def checked_attributes(design, settings) -> AttributeFields | None:
    """The attributes of ``design``, or None when it has none, after the check that
    ``fgslice check`` makes of them (:func:`fgslice.design.check.check_design`).

    Raises:
        DesignError: an attribute leaves the machine's limits under ``settings``.
    """
    from fgslice.design.attributes import attribute_fields
    from fgslice.design.check import check_design

    fields = attribute_fields(design)
    if fields is None:
        return None
    report = check_design(design, samples=CHECK_SAMPLES, settings=settings)
    problems = [e for e in report.errors if e.startswith("attribute '")]
    if problems:
        raise DesignError("; ".join(problems), hint="run 'fgslice check' on the design with the same profile")
    fields.ranges, fields.cover = dict(report.attribute_ranges), dict(report.attribute_cover)
    for name in report.design_intent:  # drives nothing on this machine
        fields.ranges.pop(name, None)
        fields.cover.pop(name, None)
    return fields
