"""Look-ahead: issue each state change early, by extruded length or by printing time.

A mixing hotend holds a melt volume ``V_melt`` of the old mixture; a foaming nozzle needs
time to reach a new temperature. Commanding a change ``d`` mm of extrusion (or ``t``
seconds of printing) before the path that needs the new state makes the transition land
where the design puts it (paper, "Dead volume" and Appendix A: ``d = V_melt / A``).

Semantics, with the *anchor* of a :class:`SetState` being the cumulative extruded length
(or printing time) at its place in the input:

- the change is emitted where the cumulative measure equals ``anchor - lead``; travel
  moves count nothing, every :class:`Path` (purge tower lines included) counts, across
  layer boundaries — a change may move into earlier layers;
- if that point falls inside a path, the path is split there into two open paths (same
  role, color, width, height), the interpolated point shared;
- at a path boundary the change goes right before the next path, so it stays in the
  layer of the path it precedes;
- changes keep their order (anchors never decrease) and none is dropped; a change that
  would move before the first extrusion of the print is clamped there (kept first);
- ``Path.color`` is unchanged: it is still the color the design asks for there.

Streaming: a layer is yielded once no later change can move into it, i.e. once the input
read so far extends more than ``lead`` past the layer's end. Memory holds about ``lead``
worth of paths plus one layer.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, field, replace
from operator import attrgetter, itemgetter

import numpy as np

from fgslice.errors import SettingsError
from fgslice.planning.plan import LayerPlan, SetState, Step, polyline_lengths
from fgslice.toolpaths.paths import Path

#: Positions closer than this (mm, or s) count as the same point.
EPS = 1e-9


def apply_lookahead(plans: Iterable[LayerPlan], distance_mm: float,
                    coasted: Callable[[list[Path]], np.ndarray] | None = None,
                    moves: Callable[[SetState], bool] | None = None) -> Iterator[LayerPlan]:
    """Move every :class:`SetState` ``distance_mm`` of extruded path length earlier.

    Args:
        plans: the print's layer plans in order (consumed lazily).
        distance_mm: look-ahead distance, mm of extruded path (``Settings.lookahead_distance``).
        coasted: per layer, the length (mm) at the end of each of its paths that the writer
            will coast (:func:`fgslice.planning.coasting.coasted_lengths`): it extrudes
            nothing, so it does not count.
        moves: which changes move (called once per change, in order; None: all); the
            others keep their places, e.g. a toolchanger's changes into and out of its
            support tool (:func:`fgslice.toolpaths.support_state.pinned_changes`).

    Yields:
        The same layers with state changes moved (and paths split where they land).

    Raises:
        SettingsError: a negative or non-finite distance.
    """
    _check_lead(distance_mm, "lookahead_mm", "mm")
    if distance_mm == 0:
        yield from plans
        return
    yield from shift_changes(plans, float(distance_mm), lambda path: 1.0, moves=moves, coasted=coasted,
                             barrier=True)


def apply_time_lead(
    plans: Iterable[LayerPlan], lead_s: float, speed_of: Callable[[Path], float]
) -> Iterator[LayerPlan]:
    """Move every :class:`SetState` ``lead_s`` seconds of printing time earlier.

    Printing time is ``length / speed_of(path)`` summed over paths (mm / (mm/s)); travel
    time is not counted, so the real lead is at least ``lead_s``. Used by the temperature
    dialect: a nozzle needs time, not volume, to settle.

    Args:
        plans: the print's layer plans in order (consumed lazily).
        lead_s: lead time, s (``Settings.temperature_lead_s``).
        speed_of: printing speed of a path, mm/s (> 0), as the G-code writer will use it.

    Raises:
        SettingsError: a negative or non-finite lead.
    """
    _check_lead(lead_s, "temperature_lead_s", "s")
    if lead_s == 0:
        yield from plans
        return
    yield from shift_changes(plans, float(lead_s), lambda path: 1.0 / speed_of(path))


def split_path(path: Path, offsets_mm: Sequence[float]) -> list[Path]:
    """Cut ``path`` at the given arc lengths (mm, increasing, strictly inside the path).

    Returns ``len(offsets_mm) + 1`` open paths with the path's role, color, width and
    height; consecutive pieces share the interpolated cut point. A closed path is cut
    along its vertices including the closing segment.
    """
    v = path.vertices
    seg = np.hypot(*np.diff(v, axis=0).T)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    offs = np.asarray(offsets_mm, dtype=np.float64)
    idx = np.clip(np.searchsorted(cum, offs, side="right") - 1, 0, seg.size - 1)
    t = (offs - cum[idx]) / np.where(seg[idx] > 0, seg[idx], 1.0)
    inside = t > 0  # a cut exactly on a vertex reuses the vertex
    cuts = v[idx[inside]] + t[inside, None] * (v[idx[inside] + 1] - v[idx[inside]])
    points = np.insert(v, idx[inside] + 1, cuts, axis=0)
    at = (idx + np.cumsum(inside)).tolist()  # where each cut point sits in ``points``
    bounds = zip([0] + at, at + [len(points) - 1])
    return [replace(path, points=points[a : b + 1], closed=False) for a, b in bounds]


def path_lengths(paths: Sequence[Path]) -> np.ndarray:
    """Printed length of each path (closing segment included), mm, in one numpy pass."""
    if not paths:
        return np.zeros(0)
    arrays, closed = zip(*map(attrgetter("points", "closed"), paths))
    return polyline_lengths(arrays, np.array(closed, dtype=bool))


def _check_lead(value: float, key: str, unit: str) -> None:
    if not math.isfinite(value) or value < 0:
        raise SettingsError(f"{key} must be a finite value >= 0 {unit}, got {value}", hint=f"--set {key}=0 disables it")


@dataclass
class _PendingLayer:
    """A layer read from the input whose state changes are not all placed yet.

    ``starts``/``ends`` are the cumulative measure (mm or s) at each path's ends; ``rates``
    the measure per mm of each path; ``changes`` the (position, SetState) to place
    (placed in order of position, equal positions in the order they were added).
    """

    plan: LayerPlan
    end: float
    paths: list[Path] = field(default_factory=list)
    starts: list[float] = field(default_factory=list)
    ends: list[float] = field(default_factory=list)
    rates: list[float] = field(default_factory=list)
    changes: list[tuple[float, SetState]] = field(default_factory=list)

    def build(self) -> LayerPlan:
        """The layer's steps: paths in order with the changes placed (paths split)."""
        steps: list[Step] = []
        changes, j = sorted(self.changes, key=itemgetter(0)), 0
        for path, c0, c1, rate in zip(self.paths, self.starts, self.ends, self.rates):
            cuts: list[tuple[float, list[SetState]]] = []
            while j < len(changes) and changes[j][0] < c1 - EPS:
                position, change = changes[j]
                j += 1
                if position <= c0 + EPS:
                    steps.append(change)
                elif cuts and position - cuts[-1][0] <= EPS:
                    cuts[-1][1].append(change)
                else:
                    cuts.append((position, [change]))
            if not cuts:
                steps.append(path)
                continue
            pieces = split_path(path, [(position - c0) / rate for position, _ in cuts])
            steps.append(pieces[0])
            for (_, placed), piece in zip(cuts, pieces[1:]):
                steps.extend(placed)
                steps.append(piece)
        steps.extend(change for _, change in changes[j:])
        plan = self.plan
        return LayerPlan(index=plan.index, z=plan.z, height=plan.height, steps=steps, prepared=plan.prepared)


def shift_changes(
    plans: Iterable[LayerPlan],
    lead: float,
    rate_of: Callable[[Path], float],
    moves: Callable[[SetState], bool] | None = None,
    coasted: Callable[[list[Path]], np.ndarray] | None = None,
    barrier: bool = False,
) -> Iterator[LayerPlan]:
    """Place each SetState ``lead`` earlier in the cumulative measure ``sum(length * rate)``
    (``rate_of(path)`` per mm); with ``moves``, only the changes it accepts move, the
    others keep their places (with ``barrier``, no later change moves before them); with
    ``coasted``, each path's measure leaves out the length the writer coasts at its end
    (``coasted(paths)``, mm per path of a layer)."""
    pending: deque[_PendingLayer] = deque()
    waiting: list[SetState] = []  # clamped at the start of the print: before the next path
    total = 0.0
    floor = 0.0  # where the last change that keeps its place is
    for plan in plans:
        layer = _PendingLayer(plan, end=total)
        pending.append(layer)
        layer_paths = [s for s in plan.steps if isinstance(s, Path)]
        measured = path_lengths(layer_paths)
        if coasted is not None and layer_paths:
            measured = np.maximum(measured - coasted(layer_paths), 0.0)
        lengths = iter(measured.tolist())
        for step in plan.steps:
            if isinstance(step, SetState) and moves is not None and not moves(step):
                layer.changes.extend((total, change) for change in [*waiting, step])
                waiting = []
                floor = total if barrier else floor
                continue
            if isinstance(step, SetState):
                position = max(total - lead, floor)
                if position < total - EPS:
                    target = next(p for p in pending if p.end > position + EPS)
                    target.changes.append((position, step))
                else:
                    waiting.append(step)
                continue
            rate = rate_of(step)
            if waiting:
                layer.changes.extend((total, change) for change in waiting)
                waiting = []
            layer.paths.append(step)
            layer.starts.append(total)
            total += next(lengths) * rate
            layer.ends.append(total)
            layer.rates.append(rate)
            layer.end = total
        while pending and pending[0].end <= total - lead + EPS:
            yield pending.popleft().build()
    if waiting and pending:
        pending[-1].changes.extend((math.inf, change) for change in waiting)
    while pending:
        yield pending.popleft().build()
