"""Simulating a single-material foaming print: the nozzle temperature is what is graded.

A foaming filament graded by temperature alone (one material, a ``temperature``
attribute, the ``temperature`` dialect) commands temperature states, not mixtures. The
thermal-lag model of :mod:`fgslice.analysis.simulate` already follows the nozzle
temperature and reads it as the share of "material A" of the linear mapping
``T = T_b + f_A (T_a - T_b)``. Here that mapping spans the print's temperature levels:
``T_a`` the hottest, ``T_b`` the coolest; the design is seen through
:class:`TemperatureStates`, whose two "materials" are the filament at those two
temperatures and whose fractions are the design's temperature at each point on the
same mapping (the profile's ``nozzle_temperature`` where no attribute covers it). The
composition error of a segment is then ``|T_deposited - T_designed| / (T_a - T_b)``,
and half a palette bin is half a temperature level (``temperature_step``).

Units: degC, mm.
"""

from __future__ import annotations

from collections.abc import Sequence

import msgspec
import numpy as np
import shapely

from fgslice.design.base import Design, Material
from fgslice.errors import SettingsError


class TemperatureStates(Design):
    """``design`` (one material, graded by its ``temperature`` attribute) as two
    materials: the filament at ``hot`` and at ``cold`` degC, in the proportions that put
    the design's temperature between them (clamped); ``default`` degC where no attribute
    covers a point."""

    def __init__(self, design: Design, hot: float, cold: float, default: float) -> None:
        from fgslice.design.attributes import attribute_fields
        from fgslice.preview.colors import TEMPERATURE_CMAP

        from matplotlib import colormaps

        if not hot > cold:
            raise SettingsError(f"temperature levels {cold:g} .. {hot:g} C span no range to simulate",
                                hint="the design's temperature attribute grades nothing on this profile")
        self.design, self.hot, self.cold, self.default = design, float(hot), float(cold), float(default)
        self._fields = attribute_fields(design)
        cmap = colormaps[TEMPERATURE_CMAP]
        name = design.materials[0].name
        self._materials = [Material(f"{name} {self.hot:g} C", tuple(float(c) for c in cmap(1.0))),
                           Material(f"{name} {self.cold:g} C", tuple(float(c) for c in cmap(0.0)))]

    @property
    def materials(self) -> list[Material]:
        return self._materials

    def temperature(self, x, y, z) -> np.ndarray:
        """The designed nozzle temperature at the points, degC."""
        t = self._fields.values("temperature", x, y, z) if self._fields is not None else np.full(np.shape(x), np.nan)
        return np.where(np.isfinite(t), t, self.default)

    def fractions(self, x, y, z) -> np.ndarray:
        share = np.clip((self.temperature(x, y, z) - self.cold) / (self.hot - self.cold), 0.0, 1.0)
        return np.stack([share, 1.0 - share], axis=-1)

    def sdf(self, x, y, z) -> np.ndarray:
        return self.design.sdf(x, y, z)

    def bounds(self):
        return self.design.bounds()

    def section(self, z: float) -> shapely.MultiPolygon:
        return self.design.section(z)

    def sections(self, zs: Sequence[float]) -> list[shapely.MultiPolygon]:
        return self.design.sections(zs)


def thermal_states(design: Design, settings, levels: Sequence[float] | None):
    """``(design, settings, palette size)`` to simulate a single-material foaming print
    with: the design as :class:`TemperatureStates` over ``levels`` (the print's
    temperature levels, degC, from its header or the design's check), the settings'
    ``temperature_a`` / ``temperature_b`` set to their ends, one palette color per level.

    Raises:
        SettingsError: no levels (the design grades no temperature: nothing to simulate).
    """
    if levels is None or len(levels) == 0:
        raise SettingsError(
            "a single-material design on the temperature dialect grades the nozzle temperature, and this one has "
            "no temperature attribute: every segment prints in the same state, there is nothing to simulate",
            hint="grade the temperature (an attribute named temperature), or simulate a two-material design")
    levels = np.sort(np.asarray(levels, dtype=float))
    cold = float(levels[0])
    hot = float(levels[-1]) if len(levels) > 1 else cold + settings.temperature_step  # one level: one step wide
    wrapped = TemperatureStates(design, hot, cold, settings.nozzle_temperature)
    return wrapped, msgspec.structs.replace(settings, temperature_a=hot, temperature_b=cold), max(len(levels), 2)


def print_levels(design: Design, settings, levels_text: str | None) -> np.ndarray | None:
    """The temperature levels of a print: its header's ``temperature_levels`` (degC,
    comma-separated), else those the slicer gives the design under ``settings``; None
    when it grades no temperature."""
    from fgslice.machine.grading import checked_attributes
    from fgslice.slicing.states import header_palette, state_levels

    if levels_text:
        return header_palette(1, 1, None, levels_text).levels
    fields = checked_attributes(design, settings)
    return None if fields is None else state_levels(fields.ranges, fields.cover, settings)
