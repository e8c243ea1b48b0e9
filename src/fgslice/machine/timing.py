"""How long a G-code program takes on the machine: the firmware's motion planner, in numpy.

Every move runs a trapezoid: it accelerates from its entry speed at the move's
acceleration ``a``, cruises, and decelerates to its exit speed; a move of length ``L``
(mm) entered at ``v0``, cruising at ``vc`` and left at ``v1`` (mm/s) takes

    t = (vc - v0) / a + (L - (2 vc^2 - v0^2 - v1^2) / (2 a)) / vc + (vc - v1) / a    (s).

The speeds come from a look-ahead over all moves, as Klipper's ``toolhead.py`` and
Marlin's ``planner.cpp`` plan them: each junction between two moves has a largest speed
(below), every move's speed is at most its feed rate, and the speed changes by at most
``2 a L`` in v^2 over a move; the planned speed at each junction is the largest that
honours all of these, found with two cumulative minima (forward and backward) instead of
a loop. Junction speeds:

* ``klipper``: junction deviation ``square_corner_velocity^2 (sqrt 2 - 1) / a``, its
  "approximated centripetal velocity" limits (the corner's circle touches each move no
  further than its middle) and the extruder's ``instantaneous_corner_velocity`` (1 mm/s)
  over the change of E per mm; the peak of a move is further capped by Klipper's
  ``minimum_cruise_ratio`` (its planner's pseudo-acceleration ``a (1 - ratio)``: the
  highest speed of each accelerate-decelerate hill is the one reached at that gentler
  acceleration).
* ``marlin``: Marlin 2's junction deviation (``junction_deviation`` mm, 0.013 by default)
  with its limit for short moves on curves (``JD_HANDLE_SMALL_SEGMENTS``); or, with
  ``junction_deviation = 0``, classic jerk: the largest change of speed per axis at a
  junction is ``jerk`` mm/s for X and Y, 0.3 for Z and 5 for E (Marlin's defaults), and a
  move starts from rest at the speed at which no axis exceeds it.

Extrude-only moves (retractions) start and end at rest at ``retract_acceleration``
(Klipper's default: ``acceleration`` times its extrusion ratio ``4 d_nozzle^2 / (pi
d_filament^2 / 4)``, its speed capped at ``travel_speed`` times the same ratio; Marlin's:
``acceleration``). Moves with Z are capped at ``z_speed`` and ``z_acceleration`` along Z.
The firmware stops the head (the junction speed is 0) where it waits for the moves:
``M400``, ``G4`` (whose dwell is added), ``G28``, ``M109``/``M190``, ``M600``, a tool
change ``T<n>``, and on Klipper ``G92`` and the commands that flush its step generation
(``ACTIVATE_EXTRUDER``, ``SYNC_EXTRUDER_MOTION``, ``SET_EXTRUDER_ROTATION_DISTANCE``).
Heating and homing take no time here (they depend on the machine's state).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np

from fgslice.machine.gcode_reader import GcodeProgram, GcodeStream
from fgslice.settings import Settings

#: Klipper's ``instantaneous_corner_velocity`` default, mm/s.
KLIPPER_INSTANT_CORNER_V = 1.0
#: Marlin's classic-jerk defaults for Z and E (``DEFAULT_ZJERK``, ``DEFAULT_EJERK``), mm/s.
MARLIN_Z_JERK = 0.3
MARLIN_E_JERK = 5.0
#: Speed of moves before any ``F`` (Klipper's and Marlin's 25 mm/s), mm/s.
DEFAULT_SPEED = 25.0
#: Moves kept before planning them with a stop at the end (bounds memory; a stop is
#: planned every so many moves after the last real one, costing a fraction of a second
#: per stop).
MAX_PENDING = 1 << 18

_WAITS = {"M400", "G28", "M109", "M190", "M600", "G4"}
_KLIPPER_WAITS = {"G92", "ACTIVATE_EXTRUDER", "SYNC_EXTRUDER_MOTION", "SET_EXTRUDER_ROTATION_DISTANCE"}


@dataclass(frozen=True)
class MotionLimits:
    """What the planner needs of the machine (mm, mm/s, mm/s²); see the module docstring.

    Attributes:
        planner: ``klipper`` or ``marlin``.
        accel: XY(Z) acceleration; ``z_accel`` along Z; ``e_accel`` of extrude-only moves.
        z_velocity: largest speed along Z; ``e_velocity`` of extrude-only moves.
        junction_deviation: mm (0 with classic jerk on ``marlin``).
        jerk: ``(x, y, z, e)`` classic jerk, mm/s (``marlin`` with ``junction_deviation`` 0).
        cruise_ratio: Klipper's ``minimum_cruise_ratio`` (0 for Marlin).
        instant_corner_v: Klipper's extruder corner speed (inf for Marlin).
    """

    planner: str
    accel: float
    z_accel: float
    e_accel: float
    z_velocity: float
    e_velocity: float
    junction_deviation: float
    jerk: tuple[float, float, float, float]
    cruise_ratio: float
    instant_corner_v: float

    @classmethod
    def of(cls, settings: Settings) -> "MotionLimits":
        """The limits ``settings`` describe, with the firmware's defaults where they say 'auto'."""
        s = settings
        ratio = 4 * s.nozzle_diameter**2 / (math.pi * s.filament_diameter**2 / 4)
        klipper = s.motion_planner == "klipper"
        e_accel = s.retract_acceleration
        if e_accel == "auto":
            e_accel = s.acceleration * ratio if klipper else s.acceleration
        return cls(
            planner=s.motion_planner,
            accel=s.acceleration,
            z_accel=s.z_acceleration,
            e_accel=float(e_accel),
            z_velocity=s.z_speed,
            e_velocity=s.travel_speed * ratio if klipper else math.inf,
            junction_deviation=(s.square_corner_velocity**2 * (math.sqrt(2) - 1) / s.acceleration if klipper
                                else s.junction_deviation),
            jerk=(s.jerk, s.jerk, MARLIN_Z_JERK, MARLIN_E_JERK),
            cruise_ratio=s.minimum_cruise_ratio if klipper else 0.0,
            instant_corner_v=KLIPPER_INSTANT_CORNER_V if klipper else math.inf,
        )


def _reach(cap: np.ndarray, delta: np.ndarray) -> np.ndarray:
    """The largest v² at each of ``n + 1`` junctions below ``cap`` (``(n + 1,)``, v²) such
    that v² changes by at most ``delta[i]`` over move ``i``: ``min_j (cap[j] + |C[i] - C[j]|)``
    with ``C`` the running sum of ``delta``, as a backward and a forward cumulative minimum."""
    c = np.concatenate([[0.0], np.cumsum(delta)])
    backward = np.minimum.accumulate((cap + c)[::-1])[::-1] - c
    forward = np.minimum.accumulate(cap - c) + c
    return np.minimum(backward, forward)


def _klipper_cruise(junction: np.ndarray, smooth: np.ndarray, delta: np.ndarray, smooth_delta: np.ndarray,
                    cruise2: np.ndarray) -> np.ndarray:
    """Klipper's cruise v² of each move under ``minimum_cruise_ratio`` (its look-ahead's
    ``flush``, without the loop). ``junction``: the planned junction v²; ``smooth``: the same
    at the pseudo-acceleration (``smooth_delta`` per move). A move that may accelerate (its
    smoothed start is not bound by the deceleration after it) cruises at most at its
    triangle's peak and at the smoothed peak of the hill's top: the first move from it on
    that does not end where the pseudo-acceleration would take it, or is followed by one
    that may not accelerate. A move that may not accelerate cruises at its start speed,
    at most at the cruise of the move before."""
    n = len(delta)
    accelerates = smooth[:-1] < smooth[1:] + smooth_delta
    follows = np.append(accelerates[1:], False)
    top = accelerates & ((smooth[:-1] + smooth_delta > smooth[1:]) | ~follows)
    index = np.arange(n)
    next_top = np.minimum.accumulate(np.where(top, index, n)[::-1])[::-1]
    peaks = np.append((smooth[:-1] + smooth[1:] + smooth_delta) / 2, 0.0)
    cruise = np.minimum(np.minimum(cruise2, (junction[:-1] + junction[1:] + delta) / 2), peaks[next_top])
    # the others: min(cruise of the last accelerating move, start v² of each move since then)
    group = np.cumsum(accelerates)
    values = np.where(accelerates, cruise, junction[:-1])
    big = float(values.max(initial=0.0)) + 1.0
    shifted = values - group * big
    return np.where(accelerates, cruise, np.minimum.accumulate(shifted) + group * big)


def move_times(start: np.ndarray, end: np.ndarray, e: np.ndarray, feed: np.ndarray, limits: MotionLimits,
               stop_before: np.ndarray | None = None) -> np.ndarray:
    """Seconds each of ``n`` moves takes, planned from rest to rest.

    Args:
        start, end: ``(n, 3)`` XYZ positions, mm.
        e: ``(n,)`` filament, mm (negative: retraction).
        feed: ``(n,)`` commanded speed, mm/s (along XYZ; along E for extrude-only moves).
        limits: the machine's :class:`MotionLimits`.
        stop_before: ``(n,)`` True where the head stops before the move (a wait).
    """
    n = len(e)
    if not n:
        return np.zeros(0)
    d = end - start
    length = np.sqrt(np.einsum("ij,ij->i", d, d))
    kinematic = length >= 1e-9
    move_d = np.where(kinematic, length, np.abs(e))
    safe_d = np.where(move_d > 0, move_d, 1.0)
    unit = d / np.where(kinematic, length, 1.0)[:, None]
    e_ratio = e / safe_d
    velocity = np.where(feed > 0, feed, DEFAULT_SPEED)
    accel = np.full(n, limits.accel)
    accel[~kinematic] = limits.e_accel
    dz = np.abs(unit[:, 2])
    z_moves = kinematic & (dz > 0)
    velocity[z_moves] = np.minimum(velocity[z_moves], limits.z_velocity / dz[z_moves])
    accel[z_moves] = np.minimum(accel[z_moves], limits.z_accel / dz[z_moves])
    limited_e = ~kinematic | (e_ratio < 0)
    if limited_e.any():
        inverse = 1.0 / np.maximum(np.abs(e_ratio[limited_e]), 1e-12)
        velocity[limited_e] = np.minimum(velocity[limited_e], limits.e_velocity * inverse)
        accel[limited_e] = np.minimum(accel[limited_e], limits.e_accel * inverse)
    cruise2 = velocity**2
    delta = 2.0 * move_d * accel

    axes = np.column_stack([unit, np.where(kinematic, e_ratio, np.sign(e))])  # X Y Z E per mm/s of speed

    # Junction caps (v², junction i is before move i; n is after the last move).
    cap = np.zeros(n + 1)
    jerk = limits.planner == "marlin" and limits.junction_deviation <= 0
    if n > 1:
        if jerk:
            cap[1:-1] = _jerk_junction2(axes, velocity, limits)
        else:
            joint = kinematic[1:] & kinematic[:-1]
            cap[1:-1] = np.where(joint, _junction_caps(unit, e_ratio, velocity, accel, move_d, delta, limits), 0.0)
    if stop_before is not None:
        cap[:-1][stop_before] = 0.0
    if jerk:  # from rest a move starts at the speed at which no axis exceeds its jerk
        from_rest = cap[:-1] == 0
        cap[:-1][from_rest] = _safe_speed2(axes[from_rest], velocity[from_rest], limits)
    junction = _reach(cap, delta)
    cruise = np.minimum(cruise2, (junction[:-1] + junction[1:] + delta) / 2)
    if limits.cruise_ratio > 0:
        smooth_delta = np.minimum(2.0 * move_d * limits.accel * (1 - limits.cruise_ratio), delta)
        cruise = _klipper_cruise(junction, _reach(cap, smooth_delta), delta, smooth_delta, cruise2)
    v0 = np.sqrt(np.minimum(junction[:-1], cruise))
    v1 = np.sqrt(np.minimum(junction[1:], cruise))
    vc = np.sqrt(cruise)
    cruise_d = np.maximum(move_d - (2 * cruise - v0**2 - v1**2) / (2 * accel), 0.0)
    return np.where(move_d > 0, (2 * vc - v0 - v1) / accel + cruise_d / np.maximum(vc, 1e-12), 0.0)


def _junction_caps(unit, e_ratio, velocity, accel, move_d, delta, limits: MotionLimits) -> np.ndarray:
    """The largest v² at the ``n - 1`` junctions between consecutive moves (both moving
    the head), before the look-ahead: both moves' speeds and the planner's corner rule."""
    prev, this = unit[:-1], unit[1:]
    cos_theta = -np.einsum("ij,ij->i", prev, this)  # the corner's angle: -1 straight on, 1 reversal
    cap = np.minimum(velocity[:-1], velocity[1:]) ** 2
    sin_d2 = np.sqrt(np.maximum(0.5 * (1.0 - cos_theta), 0.0))
    cos_d2 = np.sqrt(np.maximum(0.5 * (1.0 + cos_theta), 0.0))
    bent = (sin_d2 < 1.0) & (cos_d2 > 0.0)  # not straight on
    r = sin_d2 / np.where(bent, 1.0 - sin_d2, 1.0)
    slower = np.minimum(accel[1:], accel[:-1])
    cap = np.where(bent, np.minimum(cap, r * limits.junction_deviation * slower), cap)
    if limits.planner == "klipper":
        quarter_tan = 0.25 * sin_d2 / np.where(bent, cos_d2, 1.0)
        cap = np.where(bent, np.minimum(cap, np.minimum(delta[1:], delta[:-1]) * quarter_tan), cap)
        diff = np.abs(e_ratio[1:] - e_ratio[:-1])
        cap = np.where(diff > 0, np.minimum(cap, (limits.instant_corner_v / np.where(diff > 0, diff, 1.0)) ** 2), cap)
    else:
        theta = np.arccos(np.clip(-cos_theta, -1.0, 1.0))  # the change of direction, radians
        small = (move_d[1:] < 1.0) & (cos_theta < -math.sqrt(0.5)) & (theta > 0)
        cap = np.where(small, np.minimum(cap, move_d[1:] * accel[1:] / np.where(small, theta, 1.0)), cap)
    return cap


def _jerk_junction2(axes: np.ndarray, velocity: np.ndarray, limits: MotionLimits) -> np.ndarray:
    """Marlin's classic jerk at each junction of moves with axis velocities ``axes``
    (``(n, 4)`` per mm/s of speed): both moves' velocities scaled to the slower move's
    speed, each axis's jump (the larger speed where an axis reverses) at most its jerk; v²."""
    nominal = np.minimum(velocity[:-1], velocity[1:])
    v_exit, v_entry = axes[:-1] * nominal[:, None], axes[1:] * nominal[:, None]
    same_sign = (v_exit * v_entry) >= 0
    jump = np.where(same_sign, np.abs(v_exit - v_entry), np.maximum(np.abs(v_exit), np.abs(v_entry)))
    jerk = np.array(limits.jerk)
    factor = np.min(np.where(jump > jerk, jerk / np.where(jump > 0, jump, 1.0), 1.0), axis=1)
    return (nominal * factor) ** 2


def _safe_speed2(axes: np.ndarray, velocity: np.ndarray, limits: MotionLimits) -> np.ndarray:
    """Marlin's classic-jerk speed a move may start at from rest: its speed scaled so that
    no axis exceeds its jerk; v²."""
    speeds = np.abs(axes) * velocity[:, None]
    jerk = np.array(limits.jerk)
    factor = np.min(np.where(speeds > jerk, jerk / np.where(speeds > 0, speeds, 1.0), 1.0), axis=1)
    return (velocity * factor) ** 2


class TimeModel:
    """The print time of G-code handed over piece by piece (the writer's text as it is
    written): moves are planned from one stop of the head to the next, so a piece may end
    anywhere; :meth:`finish` plans the rest (ending at rest) and returns the total.

    Args:
        settings: the machine (:meth:`MotionLimits.of`).
    """

    def __init__(self, settings: Settings) -> None:
        self.limits = MotionLimits.of(settings)
        self._stream = GcodeStream()
        self._pending: list[tuple[np.ndarray, ...]] = []
        self._pending_moves = 0
        self._waits = _WAITS | {"T"} | (_KLIPPER_WAITS if self.limits.planner == "klipper" else set())
        self.motion_s = 0.0
        self.fixed_s = 0.0

    @property
    def total_s(self) -> float:
        """Seconds planned so far (moves up to the last stop, dwells, fixed times)."""
        return self.motion_s + self.fixed_s

    def add(self, seconds: float) -> None:
        """Add a fixed time (a tool change's, say), s."""
        self.fixed_s += seconds

    def feed(self, text: str) -> None:
        """Read the next piece of G-code (whole lines)."""
        if text:
            self.read(self._stream.read(text))

    def read(self, program: GcodeProgram) -> None:
        """Take the next chunk of a program read elsewhere (:func:`~.gcode_reader.iter_gcode`'s
        chunks, say, in order): the same total as :meth:`feed` of its text. Arcs are
        planned as the straight pieces the firmware cuts them into."""
        program = program.split_arcs()
        waits = [(line, dwell) for line, command, dwell in program.waits if command in self._waits]
        for _, dwell in waits:
            self.fixed_s += dwell
        self._queue(program, np.array([line for line, _ in waits], dtype=np.int64))

    def finish(self) -> float:
        """Plan the moves still pending (ending at rest); the total time, s."""
        self._plan_pending()
        return self.total_s

    def _queue(self, program: GcodeProgram, wait_lines: np.ndarray) -> None:
        """Queue ``program``'s moves; plan everything before its last wait."""
        stop = np.zeros(len(program.e), dtype=bool)
        if len(wait_lines):
            after = np.searchsorted(program.line, wait_lines)
            stop[after[after < len(stop)]] = True
        d = program.end - program.start
        keep = (np.abs(d).sum(axis=1) > 1e-9) | (np.abs(program.e) > 1e-9)
        columns = (program.start[keep], program.end[keep], program.e[keep], program.feed[keep] / 60.0, stop[keep])
        if len(wait_lines) and (not len(program.line) or wait_lines[-1] > program.line[-1]):
            # a wait after the last move: everything so far ends at rest
            self._push(columns)
            self._plan_pending()
            return
        stops = np.flatnonzero(columns[4])
        if len(stops):
            cut = int(stops[-1])
            self._push(tuple(c[:cut] for c in columns))
            self._plan_pending()
            columns = tuple(c[cut:] for c in columns)
        self._push(columns)

    def _push(self, columns: tuple[np.ndarray, ...]) -> None:
        """Keep moves (start, end, e, speed, stop-before columns) for planning; plan each
        :data:`MAX_PENDING` moves after the last stop as if the head stopped there, so
        the total does not depend on how the program was cut into pieces."""
        if not len(columns[2]):
            return
        self._pending.append(columns)
        self._pending_moves += len(columns[2])
        while self._pending_moves >= MAX_PENDING:
            joined = tuple(np.concatenate(c) for c in zip(*self._pending))
            self._pending = [tuple(c[MAX_PENDING:] for c in joined)] if len(joined[2]) > MAX_PENDING else []
            self._pending_moves -= MAX_PENDING
            self._plan(tuple(c[:MAX_PENDING] for c in joined))

    def _plan_pending(self) -> None:
        """Plan the kept moves from rest to rest and add their time."""
        if not self._pending:
            return
        columns = tuple(np.concatenate(c) for c in zip(*self._pending))
        self._pending.clear()
        self._pending_moves = 0
        self._plan(columns)

    def _plan(self, columns: tuple[np.ndarray, ...]) -> None:
        """Plan moves (start, end, e, speed, stop-before columns) from rest to rest; add their time."""
        self.motion_s += float(move_times(*columns[:4], self.limits, columns[4]).sum())


def estimate_time(text: str, settings: Settings) -> float:
    """Seconds the G-code ``text`` takes on the machine of ``settings`` (:class:`TimeModel`)."""
    model = TimeModel(settings)
    model.feed(text)
    return model.finish()
