"""Fidelity metrics: how closely deposited compositions reproduce the design.

Per segment, the *composition error* is half the L1 distance between deposited and
designed fractions (for two materials this is ``|Δf|`` of the first material); the
*color difference* is CIEDE2000 between the two compositions rendered with the design's
material colors. Colors mix linearly in linear-sRGB by volume fraction, then go to CIE
XYZ and CIELAB (D65) with colour-science. Every statistic is weighted by the segment's
extruded volume and taken over the segments that build the part.

Reading them: the mean error is the average distance (0-1) of the printed composition
from the design; the 95th percentile shows the worst transitions (dead volume smears
them); the share within half a palette bin tells how much of the part lands in the
right color band; ΔE00 below about 1 is imperceptible, 2-10 noticeable at a glance.

colour-science takes about two seconds to import (it loads matplotlib and scipy), so it
is imported by the functions that compute colors, not with this module.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path
from collections.abc import Iterable, Sequence

import numpy as np

from fgslice.analysis.simulate import FEATURES, SimulationResult, mixing_deposit
from fgslice.colors import materials_rgba, srgb_to_linear
from fgslice.design.base import Material
from fgslice.errors import OutputError, SettingsError
from fgslice.slicing.palette import palette_bin_size


@dataclass(frozen=True)
class FidelityReport:
    """Volume-weighted fidelity of a print (fractions in 0-1, ΔE00 unitless).

    Attributes:
        segments: number of part segments measured.
        volume_mm3: their extruded volume, mm³.
        mean_error: mean composition error.
        p95_error: 95th percentile of the composition error.
        within_half_bin: share of the volume whose error is at most half a palette bin.
        bin_size: the palette bin used (fraction), ``None`` when unknown.
        mean_delta_e: mean CIEDE2000 difference.
        p95_delta_e: 95th percentile of CIEDE2000.
    """

    segments: int
    volume_mm3: float
    mean_error: float
    p95_error: float
    within_half_bin: float | None
    bin_size: float | None
    mean_delta_e: float
    p95_delta_e: float

    def as_dict(self) -> dict[str, float | int | None]:
        """Plain values for JSON statistics."""
        return asdict(self)


def composition_error(deposited: np.ndarray, designed: np.ndarray) -> np.ndarray:
    """Half the L1 distance between fraction rows, ``(..., k) -> (...)``, in [0, 1]."""
    return 0.5 * np.sum(np.abs(np.asarray(deposited) - np.asarray(designed)), axis=-1)


def within_half_bin(error: np.ndarray, weights: np.ndarray, bin_size: float) -> float:
    """Share of the total ``weights`` whose composition ``error`` is at most half of
    ``bin_size`` (0-1)."""
    return float(weights[error <= bin_size / 2 + 1e-12].sum() / weights.sum())


def predicted_within_half_bin(result: SimulationResult, palette_size: int) -> float:
    """Share of a simulation's part volume deposited within half a palette bin of the
    design (the ``within_half_bin`` of :func:`fidelity`, without computing colors)."""
    part = result.part
    if not part.any():
        raise SettingsError("no extrusion inside the part to measure", hint="check the design and the placement offset")
    error = composition_error(result.deposited[part], result.designed[part])
    bin_size = palette_bin_size(palette_size, len(result.materials), result.palette_kind)
    return within_half_bin(error, result.volume[part], bin_size)


def weighted_quantile(values: np.ndarray, weights: np.ndarray, q: float) -> float:
    """The value below which a share ``q`` (0-1) of the total weight lies."""
    order = np.argsort(values)
    cumulative = np.cumsum(weights[order])
    index = np.searchsorted(cumulative, q * cumulative[-1], side="left")
    return float(values[order][min(index, len(values) - 1)])


def mixture_lab(fractions: np.ndarray, materials: Sequence[Material]) -> np.ndarray:
    """CIELAB (D65) of compositions ``(..., k)`` mixed linearly in linear-sRGB, ``(..., 3)``."""
    import colour

    srgb = colour.RGB_COLOURSPACES["sRGB"]
    linear = srgb_to_linear(materials_rgba(materials)[:, :3])
    # linear-sRGB -> XYZ is a matrix, so mixing the materials' XYZ is fgslice.colors.mix_linear
    xyz_materials = colour.RGB_to_XYZ(linear, srgb, apply_cctf_decoding=False)
    return colour.XYZ_to_Lab(np.asarray(fractions, dtype=float) @ xyz_materials, srgb.whitepoint)


def delta_e_2000(lab_1: np.ndarray, lab_2: np.ndarray) -> np.ndarray:
    """CIEDE2000 difference between CIELAB arrays (colour-science's implementation)."""
    import colour

    return np.asarray(colour.delta_E(lab_1, lab_2, method="CIE 2000"))


#: Rows per block of color computations: blocks that stay in cache run 2-3x faster.
_COLOR_BLOCK = 1 << 16


def composition_delta_e(deposited: np.ndarray, designed: np.ndarray, materials: Sequence[Material]) -> np.ndarray:
    """CIEDE2000 between deposited and designed compositions ``(n, k)`` rendered with the
    materials' colors, ``(n,)``; computed in blocks of rows."""
    out = np.empty(len(deposited))
    for lo in range(0, len(deposited), _COLOR_BLOCK):
        hi = lo + _COLOR_BLOCK
        out[lo:hi] = delta_e_2000(mixture_lab(deposited[lo:hi], materials), mixture_lab(designed[lo:hi], materials))
    return out


def fidelity_of(
    deposited: np.ndarray,
    designed: np.ndarray,
    volume: np.ndarray,
    materials: Sequence[Material],
    palette_size: int | None = None,
    palette_kind: str = "centers",
) -> FidelityReport:
    """Fidelity of deposited against designed fractions ``(n, k)`` weighted by ``volume``
    (``palette_size`` colors of ``palette_kind`` give the half-bin share)."""
    if len(volume) == 0:
        raise SettingsError("no extrusion inside the part to measure", hint="check the design and the placement offset")
    error = composition_error(deposited, designed)
    weights = np.asarray(volume, dtype=float)
    total = float(weights.sum())
    delta_e = composition_delta_e(deposited, designed, materials)
    bin_size = palette_bin_size(palette_size, len(materials), palette_kind) if palette_size else None
    within = within_half_bin(error, weights, bin_size) if bin_size else None
    return FidelityReport(
        segments=len(weights),
        volume_mm3=total,
        mean_error=float(np.dot(error, weights) / total),
        p95_error=weighted_quantile(error, weights, 0.95),
        within_half_bin=within,
        bin_size=bin_size,
        mean_delta_e=float(np.dot(delta_e, weights) / total),
        p95_delta_e=weighted_quantile(delta_e, weights, 0.95),
    )


def fidelity(result: SimulationResult, palette_size: int | None = None) -> FidelityReport:
    """Fidelity of a simulation over its part segments.

    ``palette_size`` defaults to the G-code's ``; colors = N`` (``result.palette_size``);
    without either, ``within_half_bin`` is ``None``.
    """
    size = palette_size or result.palette_size
    part = result.part
    return fidelity_of(result.deposited[part], result.designed[part], result.volume[part], result.materials, size,
                       result.palette_kind)


def fidelity_by_palette(
    designed: np.ndarray,
    volume: np.ndarray,
    materials: Sequence[Material],
    sizes: Iterable[int],
    *,
    melt_volume_mm3: float = 0.0,
    mixing_share: float = 0.0,
) -> dict[int, FidelityReport]:
    """Fidelity of printing ``designed`` fractions quantized to palettes of each size.

    Each segment (in printing order) is commanded the center of its palette color
    (:class:`fgslice.slicing.palette.Palette`) and deposited through the melt-chamber
    model with ``melt_volume_mm3`` (0: an ideal printer, only quantization remains).

    Args:
        designed: ``(n, k)`` design fractions of the segments, printing order.
        volume: ``(n,)`` extruded volume of each segment, mm³.
        materials: the design's materials (colors).
        sizes: palette sizes N to compare.

    Returns:
        ``{N: FidelityReport}`` in the order of ``sizes``.
    """
    from fgslice.slicing.palette import Palette

    fractions = np.asarray(designed, dtype=float)
    out = {}
    for size in sizes:
        palette = Palette(fractions.shape[1], int(size))
        commanded = palette.centers[palette.color_of(fractions)]
        deposited = mixing_deposit(volume, commanded, (1 - mixing_share) * melt_volume_mm3, mixing_share * melt_volume_mm3)
        out[int(size)] = fidelity_of(deposited, fractions, volume, materials, int(size))
    return out


def transition_account(result: SimulationResult) -> dict[str, dict[str, float | None]]:
    """Where the transition material went, by feature (:data:`FEATURES`).

    ``off_color_mm3``: over every extruded segment (tower included), its volume times the
    composition error of what it deposits against the state commanded while it is
    printed: the material still on its way from an earlier state (mm³). A purge's first
    part, or the sparse infill that takes it with ``purge_into_infill``, holds most of it.
    ``mean_error``: the volume-weighted composition error against the design of the part
    segments of each feature (None where a feature has none). Empty without features.
    """
    if result.feature is None:
        return {}
    count = len(FEATURES)
    off = composition_error(result.deposited, result.commanded) * result.volume
    off_color = np.bincount(result.feature, weights=off, minlength=count)
    part = result.part
    weights = result.volume[part]
    error = composition_error(result.deposited[part], result.designed[part]) * weights
    sums = np.bincount(result.feature[part], weights=error, minlength=count)
    volumes = np.bincount(result.feature[part], weights=weights, minlength=count)
    return {
        "off_color_mm3": {name: float(v) for name, v in zip(FEATURES, off_color)},
        "mean_error": {name: float(e / v) if v > 0 else None for name, e, v in zip(FEATURES, sums, volumes)},
    }


def simulation_stats(result: SimulationResult, report: FidelityReport) -> dict:
    """Everything ``fgslice simulate --stats`` writes: the model, the print and the metrics.

    Adds ``worst_layer`` (highest volume-weighted mean error), ``layer_mean_error``
    (per layer index, part segments only; null for layers without any) and ``transition``
    (:func:`transition_account`).
    """
    model = result.model
    error = composition_error(result.deposited, result.designed)[result.part]
    layers = result.layer[result.part]
    weights = result.volume[result.part]
    count = int(result.layer.max()) + 1 if len(result.layer) else 0
    sums = np.bincount(layers, weights=error * weights, minlength=count)
    vols = np.bincount(layers, weights=weights, minlength=count)
    per_layer = [float(a / v) if v > 0 else None for a, v in zip(sums, vols)]
    known = [(e, i) for i, e in enumerate(per_layer) if e is not None]
    return {
        "model": model.kind,
        "melt_volume_mm3": model.melt_volume_mm3,
        "mixing_share": model.mixing_share,
        "tau_s": model.tau_s,
        "palette_size": result.palette_size,
        "extrusion_segments": int(len(result.volume)),
        "extruded_mm3": float(result.volume.sum()),
        **report.as_dict(),
        "worst_layer": max(known)[1] if known else None,
        "layer_mean_error": per_layer,
        **({"transition": account} if (account := transition_account(result)) else {}),
    }


def plot_layer_error(result: SimulationResult, path: str | Path, layer: int | None = None) -> int:
    """Write a PNG of one layer's segments colored by composition error, with a colorbar.

    ``layer`` defaults to the part layer with the largest volume-weighted mean error.
    Returns the layer drawn.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection

    error = composition_error(result.deposited, result.designed)
    part_layers = result.layer[result.part]
    if len(part_layers) == 0:
        raise SettingsError("no extrusion inside the part to plot")
    if layer is None:
        sums = np.bincount(part_layers, weights=(error * result.volume)[result.part])
        vols = np.bincount(part_layers, weights=result.volume[result.part])
        layer = int(np.argmax(np.where(vols > 0, sums / np.where(vols > 0, vols, 1.0), -1.0)))
    chosen = result.part & (result.layer == layer)
    if not chosen.any():
        raise SettingsError(f"layer {layer} has no part segments", hint=f"layers run 0..{int(part_layers.max())}")
    segments = np.stack([result.start[chosen, :2], result.end[chosen, :2]], axis=1)
    fig, ax = plt.subplots(figsize=(7, 6), dpi=120)
    lines = LineCollection(segments, cmap="magma", linewidths=1.5)
    lines.set_array(error[chosen])
    lines.set_clim(0.0, max(float(error[chosen].max()), 1e-6))
    ax.add_collection(lines)
    ax.autoscale()
    ax.set_aspect("equal")
    ax.set_xlabel("X (mm)")
    ax.set_ylabel("Y (mm)")
    ax.set_title(f"Composition error, layer {layer}")
    fig.colorbar(lines, ax=ax, label="|deposited - designed| (fraction)")
    fig.tight_layout()
    try:
        fig.savefig(path)
    except OSError as exc:
        raise OutputError(f"cannot write the figure: {exc.strerror}", file=path) from None
    finally:
        plt.close(fig)
    return layer
