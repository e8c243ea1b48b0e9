"""Writing states that combine a material color with a nozzle temperature.

A :class:`~fgslice.slicing.states.StatePalette` color is a material color and a
temperature level. :class:`StateDialect` writes a change between two such colors as the
commands of the parts that change, after the ``;STATE:<color> <label>`` comment:

* mixing hotends (``marlin-mixing``, ``marlin-mixing-m163``): ``M104 S<t>`` when the
  level changes, then the mixture's own commands when the material color changes;
* toolchangers: ``M104 T<n> S<t>`` then ``T<n>`` when the tool changes (the new tool
  is set to the level before it is picked up), ``M104 T<n> S<t>`` for the active tool
  when only the level changes.

With a ``flow_model`` (foaming filament, :mod:`fgslice.machine.flow`) the change ends
with ``M221 S<flow>``, the flow of the temperature sent, as the temperature dialect
writes it (after the tool change: it applies to the active tool in Marlin and Klipper).
Temperatures and flows are whole numbers (Marlin keeps integer targets and percentages).
``M104`` does not wait: the nozzle follows while printing; ``temperature_lead_s`` issues
the mixing hotend's temperature changes ahead of the mixture's
(:mod:`fgslice.planning.state_leads`).
The temperature (foaming) dialect takes a temperature attribute on a single material:
its states are then the temperature levels alone (``M104 S<t>``, and ``M221`` from the
flow model). When the design grades the flow itself (a ``flow`` attribute: its E scaling
per segment already compensates), the flow model's ``M221`` is left out so the flow is
not compensated twice. The template dialect gives the temperature no meaning and refuses
these palettes; so does the temperature dialect with several materials (their mixture
is its temperature already).
"""

from __future__ import annotations

from fgslice.errors import SettingsError
from fgslice.machine.dialects import Dialect, make_dialect
from fgslice.machine.flow import flow_percent
from fgslice.settings import Settings
from fgslice.slicing.states import StatePalette

DIALECTS = ("marlin-mixing", "marlin-mixing-m163", "klipper-mixing", "toolchanger")
"""The dialects that can command the temperature as a state of its own."""


class StateDialect(Dialect):
    """The dialect of ``settings`` for the material part of each color, with the
    temperature commands added (see the module notes)."""

    def __init__(self, settings: Settings, palette: StatePalette, design_flow: bool = False) -> None:
        self.foaming = settings.dialect == "temperature" and palette.materials.size == 1
        self.model_flow = settings.flow_model != "none" and not design_flow
        if settings.dialect not in DIALECTS and not self.foaming:
            raise SettingsError(
                f"the temperature attribute grades the nozzle temperature, which the {settings.dialect} dialect "
                "does not command as a state of its own",
                hint="slice with a mixing hotend or toolchanger profile (--profile marlin-mixing, "
                     "--profile toolchanger), or remove the temperature attribute",
            )
        self.base = make_dialect(settings, palette.materials)
        self.name = self.base.name
        self.change_time_s = self.base.change_time_s
        self.moves_head = self.base.moves_head
        super().__init__(settings, palette)

    def _tool(self) -> bool:
        return self.base.name == "toolchanger"

    def _commands(self, color: int) -> list[str]:
        return self._change(None, color)

    def change_commands(self, previous: int | None, color: int) -> list[str]:
        """``;STATE:`` and the commands of the parts that differ from ``previous``."""
        color = self._color(color)
        return [f";STATE:{color} {self.palette.label(color)}", *self._change(previous, color)]

    def change_time(self, previous: int | None, color: int) -> float:
        """The material change's fixed time, s, when the material color changes; else 0."""
        if previous is not None and self.palette.material_of[previous] == self.palette.material_of[color]:
            return 0.0
        return self.change_time_s

    def _change(self, previous: int | None, color: int) -> list[str]:
        p = self.palette
        material = int(p.material_of[color])
        new_level = previous is None or p.level_of[previous] != p.level_of[color]
        new_material = previous is None or p.material_of[previous] != material
        heat = new_level or (new_material and self._tool())
        target = round(float(p.temperatures[color]))
        tool = f"T{material} " if self._tool() else ""
        lines = [f"M104 {tool}S{target}"] if heat else []
        lines += self.base._commands(material) if new_material and not self.foaming else []
        if heat and self.model_flow:
            lines.append(f"M221 S{round(float(flow_percent(self.settings.flow_model, float(target))))}")
        return lines

    def start_commands(self) -> list[str]:
        """The material dialect's (a toolchanger heats every tool the palette uses)."""
        return self.base.start_commands()


def dialect_for(settings: Settings, palette, design_flow: bool = False) -> Dialect:
    """The dialect of ``settings`` for ``palette``: :class:`StateDialect` for temperature
    states (``design_flow``: the design grades the flow itself), else
    :func:`~fgslice.machine.dialects.make_dialect`."""
    if isinstance(palette, StatePalette):
        return StateDialect(settings, palette, design_flow)
    return make_dialect(settings, palette)
