"""Fidelity metrics: CIEDE2000 against published pairs, palette-size curve, figures."""

import json

import numpy as np
import pytest

from fgslice.analysis.fidelity import (
    composition_error,
    delta_e_2000,
    fidelity,
    fidelity_by_palette,
    mixture_lab,
    plot_layer_error,
    simulation_stats,
    weighted_quantile,
)
from fgslice.analysis.simulate import MeltModel, SimulationResult
from fgslice.design.base import Material

BLUE_YELLOW = [Material("blue", (0.1, 0.2, 0.8, 1.0)), Material("yellow", (0.95, 0.85, 0.1, 1.0))]


@pytest.mark.parametrize(
    ("lab_1", "lab_2", "expected"),
    [  # Sharma, Wu & Dalal (2005) test data, pairs 1, 7, 17; and colour-science's docstring example
        ((50.0, 2.6772, -79.7751), (50.0, 0.0, -82.7485), 2.0425),
        ((50.0, 0.0, 0.0), (50.0, -1.0, 2.0), 2.3669),
        ((50.0, 2.5, 0.0), (73.0, 25.0, -18.0), 27.1492),
        ((100.0, 21.57210357, 272.22819350), (100.0, 426.67945353, 72.39590835), 94.0356490),
    ],
)
def test_ciede2000_known_pairs(lab_1, lab_2, expected):
    assert float(delta_e_2000(np.array(lab_1), np.array(lab_2))) == pytest.approx(expected, abs=1e-4)


def test_mixture_colors_are_srgb_primaries_at_the_ends():
    materials = [Material("white", (1.0, 1.0, 1.0, 1.0)), Material("blue", (0.0, 0.0, 1.0, 1.0))]
    lab = mixture_lab(np.array([[1.0, 0.0], [0.0, 1.0], [0.5, 0.5]]), materials)
    assert lab[0] == pytest.approx([100.0, 0.0, 0.0], abs=0.02)
    assert lab[1] == pytest.approx([32.30, 79.19, -107.86], abs=0.02)   # sRGB blue in CIELAB D65
    assert lab[1, 0] < lab[2, 0] < lab[0, 0]


def test_quantization_error_and_delta_e_fall_with_palette_size():
    f = np.linspace(0.0, 1.0, 6001)
    designed = np.stack([f, 1.0 - f], axis=1)
    volume = np.full(len(f), 0.05)
    sizes = [2, 4, 8, 16, 32, 48]
    reports = fidelity_by_palette(designed, volume, BLUE_YELLOW, sizes)
    delta_e = np.array([reports[n].mean_delta_e for n in sizes])
    for n in sizes:   # uniform gradient, cell centers: mean |f - center| = bin / 4
        assert reports[n].mean_error == pytest.approx(1.0 / (4 * n), rel=0.01)
        assert reports[n].within_half_bin == pytest.approx(1.0)
    assert np.all(np.diff(delta_e) < 0)
    drop_to_16 = delta_e[0] - delta_e[3]
    drop_after = delta_e[3] - delta_e[-1]
    assert drop_to_16 > 5 * drop_after        # steep, then diminishing returns (the paper's curve)
    assert delta_e[-1] < 1.0                  # 48 colors: imperceptible on average


def test_dead_volume_degrades_fidelity():
    f = np.linspace(0.0, 1.0, 6001)
    designed = np.stack([f, 1.0 - f], axis=1)
    volume = np.full(len(f), 0.05)
    ideal = fidelity_by_palette(designed, volume, BLUE_YELLOW, [16])[16]
    smeared = fidelity_by_palette(designed, volume, BLUE_YELLOW, [16], melt_volume_mm3=20.0, mixing_share=0.3)[16]
    # 20 mm^3 of lag on a 300 mm^3 ramp shifts the composition by about 20/300
    assert smeared.mean_error == pytest.approx(20.0 / 300.0, abs=0.01)
    assert smeared.within_half_bin < 0.5 * ideal.within_half_bin
    assert smeared.mean_delta_e > 3 * ideal.mean_delta_e


def test_weighted_quantile_and_error():
    values = np.array([0.0, 1.0, 2.0, 3.0])
    assert weighted_quantile(values, np.array([1.0, 1.0, 1.0, 97.0]), 0.95) == 3.0
    assert weighted_quantile(values, np.array([97.0, 1.0, 1.0, 1.0]), 0.95) == 0.0
    assert composition_error(np.array([0.2, 0.3, 0.5]), np.array([0.5, 0.3, 0.2])) == pytest.approx(0.3)


def _layer_result():
    x = np.linspace(0.0, 40.0, 401)
    start = np.stack([x[:-1], np.zeros(400), np.full(400, 0.2)], axis=1)
    end = np.stack([x[1:], np.zeros(400), np.full(400, 0.2)], axis=1)
    designed_a = (start[:, 0] + end[:, 0]) / 80.0
    deposited_a = np.clip(designed_a - 0.1, 0.0, 1.0)
    two = lambda a: np.stack([a, 1.0 - a], axis=1)  # noqa: E731
    return SimulationResult(
        deposited=two(deposited_a), commanded=two(deposited_a), designed=two(designed_a),
        volume=np.full(400, 0.007), start=start, end=end, layer=np.zeros(400, dtype=int),
        line=np.arange(400), part=np.ones(400, dtype=bool), materials=BLUE_YELLOW, palette_size=8,
        model=MeltModel("mixing", 20.0, 0.3),
    )


def test_fidelity_of_a_result_uses_its_palette_size():
    report = fidelity(_layer_result())
    assert report.bin_size == pytest.approx(1 / 8)
    assert report.mean_error == pytest.approx(0.1, abs=0.01)
    # 0.1 > half of 1/8 except where the clamp at 0 leaves the error below 1/16
    assert report.within_half_bin == pytest.approx(1 / 16, abs=0.005)
    assert set(report.as_dict()) >= {"mean_error", "p95_error", "within_half_bin", "mean_delta_e"}


def test_error_figure_is_written(tmp_path):
    out = tmp_path / "error.png"
    assert plot_layer_error(_layer_result(), out) == 0
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and out.stat().st_size > 5000


def test_simulation_stats_name_the_worst_layer():
    result = _layer_result()
    result.layer[200:] = 2                      # layer 1 empty, layer 2 = the second half
    stats = simulation_stats(result, fidelity(result))
    assert stats["layer_mean_error"][1] is None
    # the first half starts at designed 0, where the clamp at 0 keeps the error below 0.1
    assert stats["worst_layer"] == 2
    assert stats["layer_mean_error"][2] == pytest.approx(0.1)
    assert stats["layer_mean_error"][0] < 0.1
    assert stats["extruded_mm3"] == pytest.approx(400 * 0.007)
    assert json.loads(json.dumps(stats)) == stats
