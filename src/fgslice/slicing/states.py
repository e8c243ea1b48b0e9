"""Process states that combine a material color with a nozzle temperature.

A design with a ``temperature`` attribute (:mod:`fgslice.design.attributes`) prints on a
mixing hotend or a toolchanger with two non-instantaneous parameters at once: the mixture
(or tool) and the nozzle temperature. Its palette is the product of the material palette
(:class:`~fgslice.slicing.palette.Palette`) and a set of temperature *levels*
``T_j = (j0 + j) * temperature_step`` (degrees C, ``j = 0 .. L-1``) spanning the
attribute's range over the part: a point at temperature ``T`` takes the nearest level,
``j = floor((T - T_0) / step + 1/2)`` clipped to the levels, so the commanded temperature
is within half a step of the field wherever the field is inside the range.

Colors are numbered in traversal order: material color ``m`` holds the ``L`` colors
``m L .. m L + L - 1``, its levels walked upwards for even ``m`` and downwards for odd
``m``, so consecutive colors differ by one material bin or by one temperature level.

Fields handed to this palette carry one more column than the materials: the
temperature in degrees C (:class:`StateField`), the settings' ``nozzle_temperature``
where no attribute covers a point.
"""

from __future__ import annotations

import numpy as np

from fgslice.errors import SettingsError
from fgslice.slicing.field import BedField
from fgslice.slicing.palette import Palette

MAX_LEVELS = 64
"""The most temperature levels a slice may use (a palette of ``colors x levels`` states)."""


STATE_SETTINGS = ("temperature_step",)
"""Settings only temperature states use: the header lists them only for designs that
have them, so that the G-code of other designs is what it was before they existed."""


def temperature_levels(low: float, high: float, step: float, limits: tuple[float, float] | None = None) -> np.ndarray:
    """The multiples of ``step`` (degC) nearest to ``low`` and ``high`` and all between,
    without the ones outside the machine's ``limits`` (degC), if given."""
    first, last = (int(v) for v in np.floor(np.array([low, high]) / step + 0.5))
    if limits is not None:
        first = max(first, int(np.ceil(limits[0] / step - 1e-9)))
        last = max(first, min(last, int(np.floor(limits[1] / step + 1e-9))))
    if last - first + 1 > MAX_LEVELS:
        raise SettingsError(
            f"the temperature attribute ranges {low:.4g} .. {high:.4g} C: {last - first + 1} levels of "
            f"{step:g} C, more than {MAX_LEVELS}",
            hint=f"--set temperature_step={(high - low) / (MAX_LEVELS - 1):.3g} or more",
        )
    return np.arange(first, last + 1) * float(step)


class StatePalette:
    """The product of a material palette and temperature levels (see the module notes).

    Attributes:
        materials: the material palette.
        levels: ``(L,)`` the temperature levels, degC, increasing, ``step`` apart.
        size: ``materials.size * L`` colors.
        n_materials, kind: the material palette's.
        centers: ``(size, k)`` the mixture of each color (its material color's).
        temperatures: ``(size,)`` the nozzle temperature of each color, degC.
        material_of, level_of: ``(size,)`` each color's material color and level index.
        order: ``0 .. size - 1`` (colors are numbered in traversal order).
        band_counts, band_range: as :class:`Palette`'s, with the temperature as one more
            value cut into ``L`` bands.
    """

    def __init__(self, materials: Palette, levels: np.ndarray) -> None:
        self.materials = materials
        self.levels = np.asarray(levels, dtype=float)
        self.step = float(self.levels[1] - self.levels[0]) if len(self.levels) > 1 else 1.0
        n_levels = len(self.levels)
        self.size = materials.size * n_levels
        self.n_materials = materials.n_materials
        self.kind = materials.kind
        self.material_of = np.repeat(np.arange(materials.size), n_levels)
        rank = np.tile(np.arange(n_levels), materials.size)
        self.level_of = np.where(self.material_of % 2 == 0, rank, n_levels - 1 - rank)
        self._index = np.empty((materials.size, n_levels), dtype=np.int64)
        self._index[self.material_of, self.level_of] = np.arange(self.size)
        self.centers = materials.centers[self.material_of]
        self.temperatures = self.levels[self.level_of]
        self.order = np.arange(self.size)
        self.band_counts = np.append(materials.band_counts, n_levels)
        level_band = np.stack([self.level_of, self.level_of], axis=-1)[:, None, :]
        self.band_range = np.concatenate([materials.band_range[self.material_of], level_band], axis=1)

    def color(self, material: np.ndarray, level: np.ndarray) -> np.ndarray:
        """The color of material color ``material`` at level index ``level`` (arrays)."""
        return self._index[material, level]

    def level_index(self, temperature: np.ndarray) -> np.ndarray:
        """The nearest level of each temperature (degC), clipped to the levels."""
        j = np.floor((np.asarray(temperature, dtype=float) - self.levels[0]) / self.step + 0.5)
        return np.clip(j, 0, len(self.levels) - 1).astype(np.int64)

    def band_values(self, values: np.ndarray) -> np.ndarray:
        """The material palette's band values followed by the temperature's position among
        the levels, ``((T - T_0) / step + 1/2) / L`` in ``[0, 1]``."""
        v = np.asarray(values, dtype=float)
        position = ((v[..., -1] - self.levels[0]) / self.step + 0.5) / len(self.levels)
        return np.concatenate([self.materials.band_values(v[..., :-1]), np.clip(position, 0.0, 1.0)[..., None]], axis=-1)

    order_for_layer = Palette.order_for_layer

    def color_of(self, values: np.ndarray) -> np.ndarray:
        """Color index of fractions with a temperature column ``(..., k + 1)``."""
        v = np.asarray(values, dtype=float)
        return self.color(self.materials.color_of(v[..., :-1]), self.level_index(v[..., -1]))

    def zipper_neighbor(self, values: np.ndarray, beta_percent: float) -> np.ndarray:
        """The material palette's zipper neighbor at the point's own level, else -1: a
        temperature level boundary is no boundary between materials, and gets no zipper."""
        v = np.asarray(values, dtype=float)
        across = self.materials.zipper_neighbor(v[..., :-1], beta_percent)
        level = self.level_index(v[..., -1])
        return np.where(across >= 0, self.color(np.maximum(across, 0), level), -1)

    def label(self, color: int) -> str:
        """The material color's label and the temperature, e.g. ``"A 25% / B 75% @ 215 C"``."""
        if not 0 <= color < self.size:
            raise SettingsError(f"color {color} is not in the palette (0..{self.size - 1})")
        return f"{self.materials.label(int(self.material_of[color]))} @ {self.temperatures[color]:g} C"

    def __repr__(self) -> str:
        return f"StatePalette({self.materials!r}, levels={self.levels.tolist()})"


def state_levels(ranges: dict, cover: dict, settings) -> np.ndarray | None:
    """The temperature levels of a slice (:func:`temperature_levels`), None when the design
    grades no temperature; ``ranges`` and ``cover``: each attribute's ``(min, max)`` over
    the part and the share of the part it covers, as the check finds them
    (:class:`~fgslice.design.check.CheckReport`), by name.

    They span the attribute's range over the part, and ``nozzle_temperature`` when the
    attribute does not cover the whole part."""
    if "temperature" not in cover:
        return None
    default = float(settings.nozzle_temperature)
    low, high = ranges.get("temperature", (default, default))
    if cover["temperature"] < 1.0:
        low, high = min(low, default), max(high, default)
    limits = (settings.min_extrude_temperature, settings.max_nozzle_temperature)
    return temperature_levels(low, high, settings.temperature_step, limits)


def make_palette(n_materials: int, colors: int, kind: str, levels=None) -> Palette | StatePalette:
    """The palette of a slice: ``colors`` material colors (one for a single material),
    times the temperature ``levels`` (degC) when the design grades the temperature."""
    materials = Palette(n_materials, colors if n_materials > 1 else 1, kind)
    return materials if levels is None or len(levels) == 0 else StatePalette(materials, np.asarray(levels, dtype=float))


def header_palette(n_materials: int, colors: int, kind: str | None, levels_text: str | None) -> Palette | StatePalette:
    """The palette a G-code file was sliced with, from its header: ``colors`` and
    ``palette`` (the kind, None for ``centers``) and the ``temperature_levels`` comment
    (``"205,210,..."`` degC; None or empty without temperature states).

    Raises:
        SettingsError: the values make no palette.
    """
    levels = _evenly_spaced(levels_text) if levels_text else None
    if levels_text and levels is None:
        raise SettingsError(f"header 'temperature_levels' value '{levels_text}' is not evenly spaced temperatures",
                            hint="expected '; temperature_levels = 205,210,215' in degC")
    return make_palette(n_materials, colors, kind or "centers", levels)


def _evenly_spaced(text: str) -> np.ndarray | None:
    """The increasing, evenly spaced finite numbers of a comma-separated ``text``, or None."""
    try:
        values = np.array([float(v) for v in text.split(",")])
    except ValueError:
        return None
    steps = np.diff(values)
    if not np.isfinite(values).all() or (len(steps) and not (steps[0] > 0 and np.allclose(steps, steps[0]))):
        return None
    return values


class StateField(BedField):
    """A :class:`BedField` whose fractions carry the nozzle temperature (degC) as a last
    column: the design's ``temperature`` attribute, ``default`` where none covers a point."""

    def __init__(self, design, placement, default: float) -> None:
        super().__init__(design, placement)
        self.default = float(default)

    def _temperature(self, xy: np.ndarray, z: float) -> np.ndarray:
        t = self.attribute("temperature", xy, z)
        return np.where(np.isfinite(t), t, self.default)

    def fractions(self, xy: np.ndarray, z: float) -> np.ndarray:
        """Fractions ``(N, k)`` and the temperature: ``(N, k + 1)``."""
        return np.column_stack([super().fractions(xy, z), self._temperature(xy, z)])

    def fractions_grid(self, xs: np.ndarray, ys: np.ndarray, z: float) -> np.ndarray:
        """:meth:`BedField.fractions_grid` and the temperature: ``(len(ys), len(xs), k + 1)``."""
        gx, gy = np.meshgrid(np.asarray(xs, dtype=float), np.asarray(ys, dtype=float))
        t = self._temperature(np.column_stack([gx.ravel(), gy.ravel()]), z).reshape(gx.shape)
        return np.concatenate([super().fractions_grid(xs, ys, z), t[..., None]], axis=-1)


def field_for(design, placement, palette, settings) -> BedField:
    """The field the palette's colors are read from: with temperature states, a
    :class:`StateField`; else the plain :class:`BedField`."""
    if isinstance(palette, StatePalette):
        return StateField(design, placement, settings.nozzle_temperature)
    return BedField(design, placement)


def material_palette(palette: Palette | StatePalette) -> Palette:
    """The material palette of ``palette`` (itself for a :class:`Palette`)."""
    return palette.materials if isinstance(palette, StatePalette) else palette


def material_colors(palette: Palette | StatePalette, colors) -> list[int]:
    """The material color of each of ``colors`` (the colors themselves for a :class:`Palette`)."""
    if isinstance(palette, StatePalette):
        return [int(palette.material_of[c]) for c in colors]
    return [int(c) for c in colors]
