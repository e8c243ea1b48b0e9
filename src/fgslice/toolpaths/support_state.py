"""The state support is printed in: the current one, a palette color, or a state of its own.

:func:`resolve_support_state` reads the settings once per slice, in this precedence:

* ``support_tool = t`` (toolchanger): support is printed with tool ``t`` (e.g. soluble
  PVA), a tool the palette's colors do not use (``colors <= t < tool_count``); its paths
  carry color ``t``, outside the palette, written ``T<t>`` and heated to
  ``support_temperature`` (``nozzle_temperature`` when 0) with the other tools.
* ``support_mix = "f0,f1,..."`` (mixing hotends): support is printed in that mix of the
  design's materials (normalized to sum 1), a state of its own with color ``N`` (the
  palette's size).
* ``support_state = k``: palette color ``k``, printed with that color's paths.
* ``support_state = cheapest`` (default): the palette color whose filament costs least per
  volume, from ``filament_costs`` (cost per kg of each channel or tool, as PrusaSlicer's
  ``filament_cost``; a mix costs the sum of its fractions times its channels' costs, every
  filament having ``filament_density``); without costs (or on a one-filament machine)
  the cheapest is ``current``: a state that is already in the nozzle costs no purge at all.
* ``support_state = current``: color ``-1``, printed first on each layer in whatever
  state the nozzle is in (the state the layer starts in).

A state of its own is printed as one block per layer, last on even layers and first on
odd ones (:func:`layer_sequence`), so that consecutive layers share it and the order of
the part's colors, hence their changes, is the same as without support.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from fgslice.errors import SettingsError
from fgslice.settings import Settings
from fgslice.slicing.states import StatePalette, material_colors, material_palette

CURRENT_STATE = -1
"""Support color with ``support_state = current``: printed in whatever state is current."""

MIXING_DIALECTS = ("marlin-mixing", "marlin-mixing-m163", "klipper-mixing")


@dataclass(frozen=True)
class SupportState:
    """The state support is printed in.

    Attributes:
        color: the color support paths carry: :data:`CURRENT_STATE`, a palette color, or
            the color of a state of its own (``support_tool``, or the palette's size for
            ``support_mix``).
        own: True for a state outside the palette (``support_tool`` or ``support_mix``).
        tool: the support tool (toolchanger), else None.
        fractions: the support mix (fractions of the design's materials, sum 1), else None.
        temperature: the support tool's nozzle temperature, C (0 without a support tool).
    """

    color: int = CURRENT_STATE
    own: bool = False
    tool: int | None = None
    fractions: np.ndarray | None = None
    temperature: float = 0.0

    @property
    def label(self) -> str:
        """The own state's name in the G-code header, e.g. ``support tool T3``."""
        if self.tool is not None:
            return f"support tool T{self.tool}"
        mix = " / ".join(f"{chr(65 + i)} {100 * f:.4g}%" for i, f in enumerate(self.fractions))
        return f"support mix {mix}"


def resolve_support_state(settings: Settings, palette) -> SupportState:
    """The support's state for ``palette`` (a Palette or StatePalette) with ``settings``
    (see the module); the default state when support is off.

    Raises:
        SettingsError: a support tool on another dialect, inside the palette or beyond the
            tools; a support mix on another dialect, of the wrong length or not a mix; a
            ``support_state`` the palette lacks; malformed ``filament_costs``; a state of
            its own with temperature states (an attribute grading the nozzle temperature).
    """
    s = settings
    if not s.support:
        return SupportState()
    own = s.support_tool >= 0 or s.support_mix.strip()
    if own and isinstance(palette, StatePalette):
        raise SettingsError("support_tool and support_mix need a palette of mixes: a temperature attribute makes "
                            "states of their own", hint="--set support_state=current, or a palette color")
    if s.support_tool >= 0:
        return _tool_state(s, palette.size)
    if s.support_mix.strip():
        return _mix_state(s, palette)
    state = s.support_state
    if state == "current":
        return SupportState()
    if state == "cheapest":
        color = cheapest_color(s, palette)
        return SupportState() if color is None else SupportState(color=color)
    if not 0 <= state < palette.size:
        raise SettingsError(
            f"support_state = {state} is not a color of this {palette.size}-color palette",
            hint=f"--set support_state=current, or a color from 0 to {palette.size - 1}",
        )
    return SupportState(color=int(state))


def _tool_state(s: Settings, colors: int) -> SupportState:
    tool = s.support_tool
    if s.dialect != "toolchanger":
        raise SettingsError(f"support_tool = {tool} needs a toolchanger; this profile's dialect is {s.dialect}",
                            hint="--profile toolchanger, or --set support_mix=... on a mixing hotend")
    if not colors <= tool < s.tool_count:
        raise SettingsError(
            f"support_tool = {tool} must be a tool the {colors} colors of the palette do not use "
            f"(T{colors}..T{s.tool_count - 1})",
            hint=(f"--set support_tool={colors}" if colors < s.tool_count
                  else f"--colors {s.tool_count - 1} or --set tool_count={colors + 1}"),
        )
    return SupportState(color=tool, own=True, tool=tool,
                        temperature=s.support_temperature or s.nozzle_temperature)


def _mix_state(s: Settings, palette) -> SupportState:
    if s.dialect not in MIXING_DIALECTS:
        raise SettingsError(f"support_mix needs a mixing hotend; this profile's dialect is {s.dialect}",
                            hint="--set support_tool=N on a toolchanger, or support_state")
    return SupportState(color=palette.size, own=True, fractions=support_mix(s, palette.n_materials))


def support_mix(settings: Settings, materials: int) -> np.ndarray:
    """``support_mix`` as ``materials`` fractions summing to 1.

    Raises:
        SettingsError: not that many numbers >= 0, or all 0.
    """
    text, k = settings.support_mix, materials
    try:
        values = np.array([float(v) for v in text.split(",")])
    except ValueError:
        raise SettingsError(f"support_mix = {text!r} is not comma-separated numbers",
                            hint="for example --set support_mix=1,0") from None
    if len(values) != k or not np.isfinite(values).all() or (values < 0).any() or values.sum() <= 0:
        raise SettingsError(f"support_mix = {text!r} must be {k} fractions >= 0, one per material of the design, "
                            "not all 0", hint="for example --set support_mix=" + ",".join(["1"] + ["0"] * (k - 1)))
    return values / values.sum()


def filament_costs(settings: Settings) -> np.ndarray | None:
    """``filament_costs`` as numbers (per kg), or None when empty.

    Raises:
        SettingsError: not comma-separated numbers >= 0.
    """
    text = settings.filament_costs.strip()
    if not text:
        return None
    try:
        costs = np.array([float(v) for v in text.split(",")])
    except ValueError:
        costs = np.array([-1.0])
    if not np.isfinite(costs).all() or (costs < 0).any():
        raise SettingsError(f"filament_costs = {text!r} is not comma-separated costs >= 0",
                            hint="one cost per kg for each channel or tool, e.g. --set filament_costs=20,45")
    return costs


def cheapest_color(settings: Settings, palette) -> int | None:
    """The palette color of the lowest filament cost per volume (the first of equal
    ones), or None without ``filament_costs`` or on a machine of one filament.

    Raises:
        SettingsError: fewer costs than the filaments the palette uses.
    """
    costs = filament_costs(settings)
    if costs is None:
        return None
    materials = material_palette(palette)
    per_material = np.asarray(material_colors(palette, range(palette.size)))
    tools = settings.dialect == "toolchanger"
    if not tools and settings.dialect not in MIXING_DIALECTS:
        return None
    needed = materials.size if tools else materials.n_materials  # tools, or channels
    if len(costs) < needed:
        raise SettingsError(f"filament_costs has {len(costs)} costs; the palette uses {needed} filaments",
                            hint="one cost per kg for each channel or tool, comma-separated")
    per_volume = costs[per_material] if tools else materials.centers[per_material] @ costs[:needed]
    return int(np.argmin(per_volume))


def layer_sequence(order: np.ndarray, state: SupportState, layer_index: int) -> np.ndarray:
    """The colors of layer ``layer_index`` in print order: the palette's ``order`` for that
    layer, with a state of its own last on even layers and first on odd ones."""
    if not state.own:
        return order
    return np.append(order, state.color) if layer_index % 2 == 0 else np.insert(order, 0, state.color)


def pinned_changes(state: SupportState) -> Callable[[object], bool] | None:
    """For the look-ahead on a toolchanger: a predicate that is False for the changes into
    and out of the support tool (they keep their places: a tool change issued early would
    print part lines with the support tool, or support with a part tool); None otherwise.
    Called once per change, in print order."""
    if state.tool is None:
        return None
    last = [None]

    def moves(change) -> bool:
        previous, last[0] = last[0], change.color
        return state.color not in (previous, change.color)

    return moves
