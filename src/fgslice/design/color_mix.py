"""Colour attributes printed as mixtures of the loaded filaments.

A design's ``color_rgb`` attribute (channels ``color_rgb.r``, ``.g``, ``.b``; else
``color_rgba``'s, alpha ignored: filaments are opaque) is an intended colour, linear RGB
in 0-1 as OpenVCAD defines it. The machine holds filaments of known colours (the
profile's ``filament_colors``, ``#rrggbb`` as sRGB); a mixture of fractions ``f`` is taken
to look like ``sum f_i c_i`` in linear sRGB (:func:`fgslice.colors.mix_linear`, the model
the rest of fgslice uses). Each point gets the mixture whose colour is nearest the
intended one in CIELAB (D65; Euclidean distance, CIE 1976 Delta E): the reachable colour
closest to the design's, chosen among the mixtures on a grid of the fraction simplex
(steps of 1/400 for two filaments, coarser for more, about 2000 candidates at most).

:func:`mix_colors` rebuilds a design so: its root wrapped in a :class:`ColorMix` whose
materials are the filaments (each named by the library material nearest its colour:
:func:`filament_names`). It does so only when the design has a
colour attribute, no materials of its own (its volume fractions decide otherwise) and
the settings name filament colours.
"""

from __future__ import annotations

import functools
import itertools
import math
import re

import numpy as np

from fgslice.colors import srgb_to_linear
from fgslice.design import nodes
from fgslice.errors import SettingsError

COLOR_ATTRIBUTES = ("color_rgb", "color_rgba")
"""Attribute names whose first three channels are an intended colour."""

MAX_CANDIDATES = 2000
"""The most mixtures compared per point."""


def parse_filament_colors(text: str) -> list[tuple[float, float, float]]:
    """``"#00ffff, #ff00ff"`` as sRGB triples in 0-1; an empty text gives none.

    Raises:
        SettingsError: an entry is not ``#rrggbb``.
    """
    colors = []
    for entry in (e.strip() for e in text.split(",") if e.strip()):
        if not re.fullmatch(r"#?[0-9a-fA-F]{6}", entry):
            raise SettingsError(f"filament_colors: '{entry}' is not a #rrggbb colour",
                                hint="write the loaded filaments' colours as '#00ffff,#ff00ff', one per channel")
        value = entry.lstrip("#")
        colors.append(tuple(int(value[i:i + 2], 16) / 255 for i in (0, 2, 4)))
    return colors


def color_channels(names) -> tuple[str, str, str] | None:
    """The three colour channels among attribute ``names`` (``color_rgb`` first), or None."""
    for base in COLOR_ATTRIBUTES:
        channels = tuple(f"{base}.{c}" for c in "rgb")
        if all(c in names for c in channels):
            return channels
    return None


def _lab(linear_rgb: np.ndarray) -> np.ndarray:
    import colour

    srgb = colour.RGB_COLOURSPACES["sRGB"]
    xyz = colour.RGB_to_XYZ(np.clip(linear_rgb, 0.0, 1.0), srgb, apply_cctf_decoding=False)
    return colour.XYZ_to_Lab(xyz, srgb.whitepoint)


@functools.lru_cache(maxsize=8)
def _candidates(filaments: tuple[tuple[float, float, float], ...]):
    """The mixtures compared, ``(K, n)`` (all fractions in steps of ``1/s``, the finest
    step giving at most :data:`MAX_CANDIDATES`, 400 at most), and a KD-tree of their
    CIELAB colours."""
    from scipy.spatial import cKDTree

    n = len(filaments)
    steps = max([1] + [s for s in range(1, 401) if math.comb(s + n - 1, n - 1) <= MAX_CANDIDATES])
    counts = np.array([np.bincount(c, minlength=n) for c in itertools.combinations_with_replacement(range(n), steps)])
    fractions = counts / steps
    linear = srgb_to_linear(np.asarray(filaments, dtype=float))
    return fractions, cKDTree(_lab(fractions @ linear))


def unmix(rgb: np.ndarray, filaments: tuple[tuple[float, float, float], ...]) -> np.ndarray:
    """Fractions ``(N, n)`` of the ``filaments`` (sRGB triples) whose mixture is nearest in
    CIELAB to each intended colour of ``rgb`` ``(N, 3)`` (linear RGB, clamped to 0-1)."""
    fractions, tree = _candidates(tuple(filaments))
    _, nearest = tree.query(_lab(np.asarray(rgb, dtype=float)))
    return fractions[nearest]


class ColorMix(nodes.Fgrade):
    """The child's colour attribute (``channels``, linear RGB) printed as the mixture of
    the filaments of sRGB colours ``filaments`` (the materials ``names``) nearest to it;
    the first filament where no colour attribute covers a point."""

    kind = "color_mix"

    def __init__(self, channels, names: list[str], filaments, child: nodes.Node) -> None:
        super().__init__([], names, (child,))
        self.channels = tuple(channels)
        self.filament_rgb = tuple(tuple(float(v) for v in rgb) for rgb in filaments)

    @functools.cached_property
    def _fields(self):
        from fgslice.design.attributes import AttributeFields

        return AttributeFields(self._body)

    _group = None

    def _values(self, x, y, z) -> list:
        shape = np.broadcast_shapes(*map(np.shape, (x, y, z)))
        rgb = np.stack([self._fields.values(c, x, y, z) for c in self.channels], axis=-1).reshape(-1, 3)
        out = np.zeros((rgb.shape[0], len(self.filament_rgb)))
        out[:, 0] = 1.0
        known = np.isfinite(rgb).all(axis=1)
        if known.any():
            out[known] = unmix(rgb[known], self.filament_rgb)
        return [out[:, i].reshape(shape) for i in range(out.shape[1])]


def mix_colors(design, settings):
    """``design`` with its colour attribute printed as filament mixtures (see the module
    notes), or ``design`` itself when that does not apply."""
    from fgslice.design.attributes import attribute_fields

    root = getattr(design, "root", None)
    fields = attribute_fields(design)
    text = getattr(settings, "filament_colors", "")
    if fields is None or not text or isinstance(root, ColorMix) or not colors_drive_mixture(design):
        return design
    channels = color_channels(fields.names)
    if channels is None:
        return design
    filaments = parse_filament_colors(text)
    names = filament_names(filaments, design.library)
    return nodes.NodeDesign(ColorMix(channels, names, filaments, root), design.library, hint_bounds=design.hint_bounds,
                            voxel_size=design.voxel_size, section_spacing=design.section_spacing, source=design.source)


def filament_names(filaments, library) -> list[str]:
    """A material of ``library`` standing for each filament colour (sRGB triples): the
    nearest (CIEDE2000) not taken by an earlier filament (``void`` excluded). The G-code
    names them in its header, so that previews and simulations find them."""
    candidates = [library.get(n) for n in library.names if n.lower() != nodes.VOID]
    import colour

    lab = _lab(srgb_to_linear(np.array([m.rgba[:3] for m in candidates], dtype=float)))
    names: list[str] = []
    for rgb in filaments:
        target = _lab(srgb_to_linear(np.asarray(rgb, dtype=float)))
        distance = np.asarray(colour.delta_E(lab, np.broadcast_to(target, lab.shape), method="CIE 2000"))
        for i in np.argsort(distance, kind="stable"):
            if candidates[i].name not in names:
                names.append(candidates[i].name)
                break
    return names


def colors_drive_mixture(design) -> bool:
    """Whether the design leaves the mixture to a colour attribute: it names no material."""
    return [m.name for m in design.materials] == [nodes.DEFAULT_MATERIAL.name]
