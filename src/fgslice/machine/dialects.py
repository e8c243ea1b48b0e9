"""Dialects: how "set the process state to palette color c" is written in G-code.

A :class:`Dialect` turns a palette color into the G-code lines of its state. Every
state change starts with the comment ``;STATE:<color> <label>`` so that any reader can
recover the palette color whatever the commands are. One class per dialect:

* ``marlin-mixing``: ``M165 A<f1> B<f2> ...`` — Marlin's whole-mix command, factors with
  4 decimals in the design's material order; Marlin names the channels A B C D H I
  (E and F are taken by extrusion and feed rate).
* ``marlin-mixing-m163``: ``M163 S<i> P<f_i>`` for every channel, then ``M164 S0``
  (commit the mix to virtual tool 0).
* ``klipper-mixing``: a mixing hotend on stock Klipper, each channel an
  ``[extruder_stepper mix_a]``.. synced to the extruder's motion: a channel of fraction
  ``f > 0`` is synced (``SYNC_EXTRUDER_MOTION EXTRUDER=mix_a MOTION_QUEUE=extruder``) at
  the rotation distance ``mixing_rotation_distance / f`` (``SET_EXTRUDER_ROTATION_DISTANCE``),
  so it feeds ``f`` mm per mm of E; a channel of fraction 0 is unsynced
  (``MOTION_QUEUE=`` empty). Fractions are rounded to 4 decimals as ``M165``'s.
* ``toolchanger``: ``T<n>`` with ``n`` the color index; every tool the palette uses is
  heated (``M104 T<i>``, then ``M109 T<i>``) after the start G-code.
* ``temperature``: ``M104 S<t>`` then ``M221 S<flow>``; ``t`` is linear in the first
  material's fraction ``f_A``: ``t = temperature_a + (temperature_b - temperature_a)
  (1 - f_A)`` (100 % A prints at ``temperature_a``), ``flow`` from :mod:`.flow`. Both are
  whole numbers: Marlin keeps target temperatures and flow percentages as integers.
* ``template``: ``settings.state_template`` with ``{name}`` placeholders replaced by a
  restricted substitution (never ``str.format``): ``{color}``, ``{f0}``..``{f5}``
  (fractions 0-1, 4 decimals), ``{pct0}``..``{pct5}`` (0-100, 2 decimals),
  ``{pwm0}``..``{pwm5}`` (0-255, integers) and ``{temperature}`` (the temperature
  dialect's mapping). Materials the design does not have read as 0.

Mixing channels beyond the design's materials are set to 0; a design with more
materials than ``settings.channels`` is a :class:`~fgslice.errors.SettingsError`.
"""

from __future__ import annotations

import re
from abc import ABC, abstractmethod
from typing import Protocol

import numpy as np

from fgslice.errors import SettingsError
from fgslice.machine.flow import flow_percent
from fgslice.settings import Settings

MIX_LETTERS = "ABCDHI"
MAX_TEMPLATE_CHANNELS = 6
PLACEHOLDER = re.compile(r"\{([^{}\s]*)\}")
_INDEXED = re.compile(r"(f|pct|pwm)([0-9])")


class PaletteLike(Protocol):
    """What a dialect needs of a palette (see ``fgslice.slicing.palette.Palette``)."""

    size: int
    n_materials: int
    centers: np.ndarray

    def label(self, color: int) -> str: ...


class Dialect(ABC):
    """Writes the commands of a palette color's process state.

    Attributes:
        name: the dialect's settings name.
        change_time_s: fixed time a state change takes on the machine, s (for the
            writer's time estimate; moves are counted separately).
        moves_head: True if a state change moves the print head (the position after it
            is unknown, so the next path always starts with a travel).
    """

    name: str = ""
    change_time_s: float = 0.0
    moves_head: bool = False

    def __init__(self, settings: Settings, palette: PaletteLike) -> None:
        self.settings = settings
        self.palette = palette
        self._check()

    def _check(self) -> None:
        """Raise SettingsError if this dialect cannot print ``palette`` with ``settings``."""

    def _color(self, color: int) -> int:
        color = int(color)
        if not 0 <= color < self.palette.size:
            raise ValueError(f"color {color} is not in the palette of {self.palette.size} colors")
        return color

    def state_commands(self, color: int) -> list[str]:
        """G-code lines setting the state of ``color``: ``;STATE:<c> <label>`` then the commands."""
        color = self._color(color)
        return [f";STATE:{color} {self.palette.label(color)}", *self._commands(color)]

    def change_commands(self, previous: int | None, color: int) -> list[str]:
        """The lines of a change from state ``previous`` (None: unknown) to ``color``:
        :meth:`state_commands` (a state's commands do not depend on the one before)."""
        return self.state_commands(color)

    def change_time(self, previous: int | None, color: int) -> float:
        """Fixed time of a change from ``previous`` to ``color``, s: :attr:`change_time_s`."""
        return self.change_time_s

    @abstractmethod
    def _commands(self, color: int) -> list[str]:
        """The machine commands (no comment) of ``color``'s state."""

    def start_commands(self) -> list[str]:
        """Lines the writer adds after the start G-code (e.g. heating every tool)."""
        return []

    def describe(self, color: int) -> str:
        """The commands of ``color``'s state on one line, e.g. ``M165 A0.1250 B0.8750``."""
        return " | ".join(self._commands(self._color(color)))

    def extra_colors(self) -> dict[int, str]:
        """Colors outside the palette this dialect writes, with their labels (the
        support's own state: :mod:`.support_dialect`)."""
        return {}


class MarlinMixing(Dialect):
    """``M165 A.. B..``: the whole mix in one command."""

    name = "marlin-mixing"

    def _check(self) -> None:
        _check_channels(self.settings, self.palette)

    def _commands(self, color: int) -> list[str]:
        factors = _channel_factors(self.palette.centers[color], self.settings.channels)
        return ["M165 " + " ".join(f"{MIX_LETTERS[i]}{f:.4f}" for i, f in enumerate(factors))]


class MarlinMixingM163(Dialect):
    """``M163 S<i> P<f_i>`` per channel, then ``M164 S0``."""

    name = "marlin-mixing-m163"

    def _check(self) -> None:
        _check_channels(self.settings, self.palette)

    def _commands(self, color: int) -> list[str]:
        factors = _channel_factors(self.palette.centers[color], self.settings.channels)
        return [f"M163 S{i} P{f:.4f}" for i, f in enumerate(factors)] + ["M164 S0"]


class KlipperMixing(Dialect):
    """Klipper's extruder steppers, synced to the extruder and scaled to the mix."""

    name = "klipper-mixing"

    def _check(self) -> None:
        _check_channels(self.settings, self.palette)

    def _commands(self, color: int) -> list[str]:
        factors = np.round(_channel_factors(self.palette.centers[color], self.settings.channels), 4)
        lines = []
        for i, f in enumerate(factors.tolist()):
            stepper = f"EXTRUDER=mix_{MIX_LETTERS[i].lower()}"
            if f <= 0:
                lines.append(f"SYNC_EXTRUDER_MOTION {stepper} MOTION_QUEUE=")
                continue
            distance = f"{self.settings.mixing_rotation_distance / f:.6f}".rstrip("0").rstrip(".")
            lines += [f"SYNC_EXTRUDER_MOTION {stepper} MOTION_QUEUE=extruder",
                      f"SET_EXTRUDER_ROTATION_DISTANCE {stepper} DISTANCE={distance}"]
        return lines


class Toolchanger(Dialect):
    """``T<n>``: one tool per color."""

    name = "toolchanger"
    change_time_s = 10.0
    moves_head = True

    def _check(self) -> None:
        n, tools = self.palette.size, self.settings.tool_count
        if n > tools:
            raise SettingsError(
                f"{n} colors need {n} tools; this profile has {tools}",
                hint=f"--set tool_count={n} or --colors {tools}",
            )

    def start_commands(self) -> list[str]:
        """Heat every tool the palette uses to ``nozzle_temperature`` and wait for each."""
        t = f"{self.settings.nozzle_temperature:g}"
        tools = range(self.palette.size)
        return [f"M104 T{i} S{t}" for i in tools] + [f"M109 T{i} S{t}" for i in tools]

    def _commands(self, color: int) -> list[str]:
        return [f"T{color}"]


class Temperature(Dialect):
    """``M104 S<t>`` then ``M221 S<flow>``: temperature-graded foaming filament."""

    name = "temperature"

    def _commands(self, color: int) -> list[str]:
        t = round(state_temperature(self.settings, self.palette.centers[color]))
        flow = round(float(flow_percent(self.settings.flow_model, float(t))))
        return [f"M104 S{t}", f"M221 S{flow}"]


class Template(Dialect):
    """``settings.state_template`` with its placeholders filled in."""

    name = "template"

    def _check(self) -> None:
        if not self.settings.state_template.strip():
            raise SettingsError(
                "the template dialect needs a state_template",
                hint="for example --set 'state_template=M400\\nM42 P4 S{pwm0}'",
            )
        for match in PLACEHOLDER.finditer(self.settings.state_template):
            if not _known_placeholder(match.group(1)):
                raise SettingsError(
                    f"unknown placeholder '{{{match.group(1)}}}' in state_template",
                    hint="placeholders: {color}, {f0}..{f5}, {pct0}..{pct5}, {pwm0}..{pwm5}, {temperature}",
                )

    def _commands(self, color: int) -> list[str]:
        values = template_values(self.settings, self.palette, color)
        text = PLACEHOLDER.sub(lambda m: values[m.group(1)], self.settings.state_template)
        return [line.strip() for line in text.splitlines() if line.strip()]


DIALECTS: dict[str, type[Dialect]] = {
    cls.name: cls for cls in (MarlinMixing, MarlinMixingM163, KlipperMixing, Toolchanger, Temperature, Template)
}


def make_dialect(settings: Settings, palette: PaletteLike) -> Dialect:
    """The dialect ``settings.dialect`` for ``palette``.

    Raises:
        SettingsError: the palette does not fit the machine (more materials than mixing
            channels, more colors than tools, a missing or malformed state template).
    """
    return DIALECTS[settings.dialect](settings, palette)


def state_temperature(settings: Settings, fractions: np.ndarray) -> float:
    """Nozzle temperature of a mix, degC: ``temperature_a`` at 100 % of the first material."""
    f_a = float(fractions[0])
    return settings.temperature_a + (settings.temperature_b - settings.temperature_a) * (1.0 - f_a)


def template_values(settings: Settings, palette: PaletteLike, color: int) -> dict[str, str]:
    """The text of every template placeholder (name without braces) for ``color``."""
    factors = _channel_factors(palette.centers[color], MAX_TEMPLATE_CHANNELS)
    values = {"color": str(color), "temperature": f"{state_temperature(settings, palette.centers[color]):.1f}"}
    for i, f in enumerate(factors):
        values[f"f{i}"] = f"{f:.4f}"
        values[f"pct{i}"] = f"{100.0 * f:.2f}"
        values[f"pwm{i}"] = str(int(round(255.0 * f)))
    return values


def _known_placeholder(name: str) -> bool:
    if name in ("color", "temperature"):
        return True
    match = _INDEXED.fullmatch(name)
    return match is not None and int(match.group(2)) < MAX_TEMPLATE_CHANNELS


def _channel_factors(center: np.ndarray, channels: int) -> np.ndarray:
    """The mix of a color over ``channels`` channels; channels beyond the materials are 0."""
    factors = np.zeros(channels)
    n = min(len(center), channels)
    factors[:n] = center[:n]
    return factors


def _check_channels(settings: Settings, palette: PaletteLike) -> None:
    if palette.n_materials > settings.channels:
        raise SettingsError(
            f"the design has {palette.n_materials} materials but the mixing hotend has {settings.channels} channels",
            hint=f"--set channels={palette.n_materials} if the machine has them",
        )
