"""How long each purge is: the melt volume (``purge_size = full``) or what the change
needs by the dead-volume model (``purge_size = model``).

``full`` purges ``L = V_melt / A`` mm of bead on every change (Appendix A), whatever the
change. ``model`` inverts the models of :mod:`fgslice.analysis.simulate`: a purge is the
shortest extrusion after which the composition leaving the nozzle is within
``purge_tolerance`` of the new state.

Melt chamber (plug flow through ``V_plug = (1 - s) V_melt``, then a well-mixed
``V_mix = s V_melt``): after a change of size ``d`` (half the L1 distance between the two
palette centers, the fidelity metrics' composition error) from a chamber that holds the
old state, the output is the old state until ``V_plug`` has been extruded, then
approaches the new one as ``d exp(-(V - V_plug) / V_mix)``, so the purge volume is::

    V = V_plug + V_mix ln(d / tol)        (0 when d <= tol)

Every change is purged to the tolerance, so the chamber may still carry up to ``tol`` of
the state before the old one (``r``); the output is bounded by ``d + r`` before the new
state arrives and by ``(d + r exp(-V_plug / V_mix)) exp(-(V - V_plug) / V_mix)`` after,
and the purge is the shortest volume that brings that bound within ``tol`` (see
:func:`purge_volume`). The first change of a print (the nozzle may hold anything) is
sized for a change across the whole composition range (``d = 1``, or ``|T_a - T_b|``),
with ``r = 0``.

Thermal lag (temperature dialect, ``dT/dt = (T_cmd - T) / tau``): the same with no plug,
``d`` and ``tol`` in degC and the result in seconds, turned into mm at the tower's print
speed (``first_layer_speed`` on layer 0, else ``print_speed``).

Units: mm, mm^3, s, degC; compositions are fractions 0-1.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from fgslice.settings import Settings
from fgslice.slicing.palette import palette_bin_size
from fgslice.slicing.states import StatePalette, material_palette
from fgslice.toolpaths.paths import bead_area


def purge_length(melt_volume_mm3: float, bead_width: float, layer_height: float) -> float:
    """``L = V_melt / (h (w - h) + pi h^2 / 4)``, mm of bead that extrudes ``V_melt``."""
    return melt_volume_mm3 / bead_area(bead_width, layer_height)


def purge_volume(distance: float, tolerance: float, v_plug: float, v_mix: float, residual: float = 0.0) -> float:
    """Shortest extrusion after which the output of the melt-chamber model is within
    ``tolerance`` of the new state, and stays so.

    Args:
        distance: size of the change (same unit as ``tolerance``).
        tolerance: allowed distance from the new state (> 0).
        v_plug: plug-flow volume (delay), mm^3 (or s).
        v_mix: well-mixed volume (exponential constant), mm^3 (or s; tau for the thermal lag).
        residual: what the chamber may still hold of earlier states beyond the old one.

    Returns:
        The volume (or time, with ``v_plug = 0`` and ``v_mix = tau``), >= 0.
    """
    if distance + residual <= tolerance:
        return 0.0
    if v_mix <= 0:
        return v_plug if distance > tolerance else 0.0
    carried = residual * math.exp(-v_plug / v_mix)
    if distance + carried <= tolerance:  # within tolerance before the new state arrives
        return v_mix * math.log(residual / (tolerance - distance))
    return v_plug + v_mix * math.log((distance + carried) / tolerance)


def default_tolerance(settings: Settings, bin_size: float) -> float:
    """``purge_tolerance`` with ``'auto'`` resolved: a tenth of a palette bin
    (``bin_size``, a fraction), in degC of the temperature mapping for that dialect."""
    if settings.purge_tolerance != "auto":
        return float(settings.purge_tolerance)
    scale = abs(settings.temperature_a - settings.temperature_b) if settings.dialect == "temperature" else 1.0
    return 0.1 * bin_size * scale


@dataclass
class PurgeSizer:
    """The purge length of every change of a slice.

    Attributes:
        settings: the slice's settings (``purge_size``, ``purge_tolerance``,
            ``melt_volume_mm3``, ``mixing_share``, ``tau_s``, speeds, bead).
        centers: ``(N, k)`` palette centers (compositions of the material colors).
        bin_size: the palette bin (fraction) the default tolerance is a tenth of.
        material_of: with temperature states, the material color (row of ``centers``) of
            each state the plans name; None when the plans name material colors.
        support_tool: the color of a toolchanger's support tool (no row of ``centers``):
            a change to it purges as one across the whole range (its own prime), a change
            from it back to a part tool purges nothing (that nozzle holds its own filament,
            the part's state did not change); None without one. A support mix is a row of
            ``centers`` instead (:meth:`with_support`).
    """

    settings: Settings
    centers: np.ndarray
    bin_size: float
    material_of: np.ndarray | None = None
    support_tool: int | None = None
    _made: dict = field(default_factory=dict, repr=False)

    @classmethod
    def of(cls, settings: Settings, centers: np.ndarray, material_of: np.ndarray | None = None) -> "PurgeSizer":
        """The purge lengths of a slice with ``settings`` on a palette of ``centers``
        (``(N, k)`` fractions of the material colors); ``material_of``: see the class."""
        centers = np.asarray(centers, dtype=np.float64)
        return cls(settings, centers, palette_bin_size(len(centers), centers.shape[1], settings.palette), material_of)

    @classmethod
    def for_palette(cls, settings: Settings, palette) -> "PurgeSizer":
        """:meth:`of` the material colors of ``palette`` (a
        :class:`~fgslice.slicing.palette.Palette` or a
        :class:`~fgslice.slicing.states.StatePalette`, whose states it maps to them)."""
        states = isinstance(palette, StatePalette)
        return cls.of(settings, material_palette(palette).centers, palette.material_of if states else None)

    def with_support(self, state) -> "PurgeSizer":
        """This sizer knowing the support's own state (a
        :class:`~fgslice.toolpaths.support_state.SupportState`): its mix as the row of its
        color, or its tool (see ``support_tool``)."""
        if not state.own:
            return self
        if state.tool is not None:
            return replace(self, support_tool=state.color, _made={})
        return replace(self, centers=np.vstack([self.centers, state.fractions]), _made={})

    def material(self, color: int | None) -> int | None:
        """The material color (row of :attr:`centers`) of a state the plans name."""
        return color if color is None or self.material_of is None else int(self.material_of[color])

    @property
    def model(self) -> bool:
        """True when purges follow the dead-volume model (``purge_size = model``)."""
        return self.settings.purge_size == "model"

    @property
    def thermal(self) -> bool:
        """True for the temperature dialect (the thermal lag sizes the purges)."""
        return self.settings.dialect == "temperature"

    @property
    def tolerance(self) -> float:
        """The tolerance: composition fraction, or degC for the temperature dialect."""
        return default_tolerance(self.settings, self.bin_size)

    @property
    def full_range(self) -> float:
        """The largest change there is: a composition distance of 1 in the unit of the
        tolerance (degC of the mapping for the temperature dialect)."""
        return abs(self.settings.temperature_a - self.settings.temperature_b) if self.thermal else 1.0

    def distance(self, old: int | None, new: int) -> float:
        """Size of a change between two colors: half the L1 distance of their centers, or
        the difference of their temperatures (degC) for the temperature dialect; from
        ``old = None`` (unknown), the whole range."""
        if old is None or self.support_tool in (old, new):
            return self.full_range
        return 0.5 * float(np.abs(self.centers[new] - self.centers[old]).sum()) * self.full_range

    def per_step(self) -> float:
        """Longest purge per palette step of change at the nominal layer height, mm: the
        most that ``j`` steps cost divided by ``j``, over every ``j`` (with two materials a
        layer's colors change monotonically, so its purges add up to at most this per
        step it spans; a one-step change is the costliest for tolerances below about half
        a step). Palettes of three or more materials count every change as the whole range."""
        s = self.settings
        if len(self.centers) < 2 or self.centers.shape[1] != 2:
            return self._of(self.full_range, self.tolerance, s.layer_height, False)
        step = self.distance(0, 1)
        return max(self._of(j * step, self.tolerance, s.layer_height, False) / j for j in range(1, len(self.centers)))

    def _of(self, distance: float, residual: float, height: float, first_layer: bool) -> float:
        """Purge length, mm of bead, for a change of ``distance`` (see the module)."""
        s = self.settings
        if self.thermal:
            seconds = purge_volume(distance, self.tolerance, 0.0, s.tau_s, residual)
            return seconds * (s.first_layer_speed if first_layer else s.print_speed)
        v_mix = s.mixing_share * s.melt_volume_mm3
        volume = purge_volume(distance, self.tolerance, s.melt_volume_mm3 - v_mix, v_mix, residual)
        return volume / bead_area(s.bead_width, height)

    def length(self, old: int | None, new: int, height: float, layer_index: int) -> float:
        """Purge length, mm of bead of ``height``, for the change from color ``old``
        (None: unknown, the first change of a print) to ``new`` on layer ``layer_index``;
        0 between states of the same material color (a change of temperature alone,
        :class:`~fgslice.slicing.states.StatePalette`)."""
        s = self.settings
        old, new = self.material(old), self.material(new)
        if old == new or (old is not None and old == self.support_tool):
            return 0.0
        if not self.model:
            return purge_length(s.melt_volume_mm3, s.bead_width, height)
        key = (old, new, height, layer_index == 0)
        if key not in self._made:
            residual = 0.0 if old is None else self.tolerance
            self._made[key] = self._of(self.distance(old, new), residual, height, layer_index == 0)
        return self._made[key]

    def tower_length(self, changes: int) -> float:
        """Length of bead per change the tower is sized for (nominal layer height), mm.

        ``full``: the melt volume's. ``model``: a layer's purges are laid one after
        another, so the tower holds ``changes - 1`` steps of :meth:`per_step` and one
        purge across the whole range (the first of the layer, from the state the layer
        before ended in, may be any), averaged over the ``changes``.
        """
        s = self.settings
        if not self.model:
            return purge_length(s.melt_volume_mm3, s.bead_width, s.layer_height)
        step = self.per_step()
        largest = self._of(self.full_range, self.tolerance, s.layer_height, False)
        changes = max(1, int(changes))
        return ((changes - 1) * step + largest) / changes
