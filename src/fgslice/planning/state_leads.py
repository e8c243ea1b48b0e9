"""Look-ahead of states that combine a mixture with a nozzle temperature.

A mixing hotend graded in composition and temperature (a
:class:`~fgslice.slicing.states.StatePalette`) has two lags: the melt chamber's volume,
compensated by ``lookahead_mm`` of extruded path, and the nozzle's heating, compensated by
``temperature_lead_s`` of printing time. Each :class:`SetState` is split into a
:class:`MixturePart` and a :class:`TemperaturePart`, each part moved by its own lead
(:func:`fgslice.planning.lookahead.shift_changes`), and the parts are then merged back
into absolute states in printing order: a mixture part sets the material color of the
current state, a temperature part its level (the print's first state, whose other part
is not known yet, is commanded whole where its earlier part goes). The writer thus sees
plain SetStates of existing colors, and its dialect writes only the part that changed
(:mod:`fgslice.machine.state_dialect`).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass

from fgslice.planning.lookahead import shift_changes
from fgslice.planning.plan import LayerPlan, SetState
from fgslice.slicing.states import StatePalette
from fgslice.toolpaths.paths import Path


@dataclass(frozen=True)
class MixturePart(SetState):
    """The material color of state ``color``, on its own."""


@dataclass(frozen=True)
class TemperaturePart(SetState):
    """The temperature level of state ``color``, on its own."""


def apply_state_leads(
    plans: Iterable[LayerPlan],
    palette: StatePalette,
    distance_mm: float,
    lead_s: float,
    speed_of: Callable[[Path], float],
) -> Iterator[LayerPlan]:
    """Issue the mixture part of every state change ``distance_mm`` of extruded path
    early and its temperature part ``lead_s`` seconds of printing early (``speed_of``:
    a path's printing speed, mm/s); with both leads 0 the plans pass unchanged."""
    if distance_mm <= 0 and lead_s <= 0:
        yield from plans
        return
    stream: Iterable[LayerPlan] = _split(plans)
    if lead_s > 0:
        stream = shift_changes(stream, float(lead_s), lambda path: 1.0 / speed_of(path),
                               moves=lambda step: step.__class__ is TemperaturePart)
    if distance_mm > 0:
        stream = shift_changes(stream, float(distance_mm), lambda path: 1.0,
                               moves=lambda step: step.__class__ is MixturePart)
    yield from _merge(stream, palette)


def _split(plans: Iterable[LayerPlan]) -> Iterator[LayerPlan]:
    for plan in plans:
        steps = []
        for step in plan.steps:
            if isinstance(step, SetState):
                steps += [MixturePart(step.color), TemperaturePart(step.color)]
            else:
                steps.append(step)
        yield LayerPlan(index=plan.index, z=plan.z, height=plan.height, steps=steps, prepared=plan.prepared)


def _merge(plans: Iterable[LayerPlan], palette: StatePalette) -> Iterator[LayerPlan]:
    """Parts to absolute states: each part changes its component of the current state
    (until both are known, the part's own color stands for the other one)."""
    material = level = None
    for plan in plans:
        steps = []
        for step in plan.steps:
            if not isinstance(step, SetState):
                steps.append(step)
                continue
            if step.__class__ is MixturePart or material is None:
                material = int(palette.material_of[step.color])
            if step.__class__ is TemperaturePart or level is None:
                level = int(palette.level_of[step.color])
            steps.append(SetState(int(palette.color(material, level))))
        yield LayerPlan(index=plan.index, z=plan.z, height=plan.height, steps=steps, prepared=plan.prepared)
