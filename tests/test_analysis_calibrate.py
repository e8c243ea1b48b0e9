"""Calibration object, Appendix A formulas, and the simulated transition with and without look-ahead."""

import math

import numpy as np
import pytest
import shapely

from fgslice.analysis.calibrate import (
    calibration_midpoint,
    calibration_plan,
    format_lookahead,
    lookahead_advice,
    lookahead_from_measurement,
    lookahead_from_volume,
    predicted_offsets,
    transition_offsets,
)
from fgslice.analysis.simulate import MeltModel, simulate_trace, trace_from_plans
from fgslice.design.base import Design, Material
from fgslice.errors import SettingsError
from fgslice.planning.lookahead import apply_lookahead
from fgslice.planning.plan import SetState
from fgslice.settings import Settings

CENTERS = np.array([[0.0, 1.0], [1.0, 0.0]])   # color 1 = pure A, color 0 = pure B


class StepBox(Design):
    """A box centered at the origin: material A for x < 0, B for x > 0."""

    def __init__(self, size=(60.0, 20.0, 0.6)):
        self.half = np.array(size) / 2

    @property
    def materials(self):
        return [Material("white", (1.0, 1.0, 1.0, 1.0)), Material("blue", (0.1, 0.2, 0.9, 1.0))]

    def sdf(self, x, y, z):
        q = np.abs(np.stack(np.broadcast_arrays(x, y, z), axis=-1)) - self.half
        return np.linalg.norm(np.maximum(q, 0.0), axis=-1) + np.minimum(q.max(axis=-1), 0.0)

    def fractions(self, x, y, z):
        a = (np.asarray(x) < 0).astype(float)
        a = np.broadcast_to(a, np.broadcast(x, y, z).shape)
        return np.stack([a, 1.0 - a], axis=-1)

    def bounds(self):
        return tuple(-self.half), tuple(self.half)

    def section(self, z):
        return shapely.MultiPolygon([shapely.box(-self.half[0], -self.half[1], self.half[0], self.half[1])])


def _offsets(settings, plans, share):
    trace = trace_from_plans(plans, CENTERS, settings)
    offset = (settings.bed_x / 2, settings.bed_y / 2, 0.3)   # lowest point of the box on the bed
    model = MeltModel("mixing", settings.melt_volume_mm3, share)
    result = simulate_trace(trace, StepBox(), offset, model)
    offsets = transition_offsets(result, calibration_midpoint(settings))
    assert len(offsets) == 3
    return offsets


def test_calibration_object_geometry():
    settings = Settings()
    plans = calibration_plan(settings, CENTERS)
    assert len(plans) == 3
    for plan in plans:
        states = [s.color for s in plan.steps if isinstance(s, SetState)]
        assert states == ([1, 0] if plan.index == 0 else [plan.index % 2])   # one change per layer
        first, second = plan.paths
        # the change happens exactly at the midpoint in X, at the end of the first half
        assert first.points[-1][0] == pytest.approx(settings.bed_x / 2)
        assert np.array_equal(first.points[-1], second.points[0])
        pts = np.vstack([first.points, second.points])
        assert pts[:, 0].max() - pts[:, 0].min() == pytest.approx(60.0 - settings.bead_width)
        assert pts[:, 1].max() - pts[:, 1].min() == pytest.approx(20.0)
    even, odd = plans[0], plans[1]
    assert even.paths[0].color == 1 and odd.paths[0].color == 0      # A first, then B first
    # A is printed on x < midpoint on every layer
    for plan in plans:
        for path in plan.paths:
            side = np.mean(path.points[:, 0]) < settings.bed_x / 2
            assert side == (path.color == 1)
    trace = trace_from_plans(plans, CENTERS, settings)
    printed = sum(p.length for plan in plans for p in plan.paths)
    assert trace.volume.sum() == pytest.approx(printed * settings.bead_area)


def test_transition_without_lookahead_lags_by_melt_volume():
    settings = Settings(melt_volume_mm3=68.5)
    length = lookahead_from_volume(68.5, settings.bead_width, settings.layer_height)
    offsets = _offsets(settings, calibration_plan(settings, CENTERS), share=0.0)
    beads = offsets / settings.bead_width
    assert np.all(np.abs(beads - length / 20.0) <= 1.0)   # about L / L_y lines late


def test_transition_with_lookahead_l_lands_on_the_midpoint():
    settings = Settings(melt_volume_mm3=68.5)
    length = lookahead_from_volume(68.5, settings.bead_width, settings.layer_height)
    plans = list(apply_lookahead(calibration_plan(settings, CENTERS), length))
    offsets = _offsets(settings, plans, share=0.0)
    assert np.all(np.abs(offsets) <= settings.bead_width)


def test_well_mixed_share_moves_the_half_way_point_to_the_median_delay():
    settings = Settings(melt_volume_mm3=68.5)
    share = 0.3
    length = lookahead_from_volume(68.5, settings.bead_width, settings.layer_height)
    line = 20.0 + settings.bead_width                 # path per hatch line, join included
    median = (1 - share + share * math.log(2)) * length
    plain = _offsets(settings, calibration_plan(settings, CENTERS), share)
    assert np.all(np.abs(plain / settings.bead_width - median / line) <= 1.0)
    shifted = _offsets(settings, list(apply_lookahead(calibration_plan(settings, CENTERS), length)), share)
    assert np.all(np.abs(shifted / settings.bead_width - (median - length) / line) <= 1.0)


def test_appendix_a_formulas():
    assert lookahead_from_volume(68.5, 0.4, 0.2) == pytest.approx(68.5 / (0.2 * 0.2 + math.pi * 0.01))
    assert lookahead_from_measurement(19.0, 20.0, 0.4) == 960.0      # 48 lines of 20 mm
    assert lookahead_from_measurement(-0.4, 20.0, 0.4) == 20.0
    assert lookahead_from_measurement(0.0, 20.0, 0.4) == 0.0
    assert format_lookahead(959.44) == "--set lookahead_mm=959.4"
    with pytest.raises(SettingsError):
        lookahead_from_measurement(3.0, 0.0, 0.4)
    with pytest.raises(SettingsError):
        lookahead_from_volume(68.5, 0.2, 0.4)


def test_lookahead_advice_gives_the_option_line():
    settings = Settings(melt_volume_mm3=68.5)
    distance, text = lookahead_advice(settings)
    assert distance == pytest.approx(959.17, abs=0.01)
    assert text.splitlines()[-1] == "--set lookahead_mm=959.2"
    distance, text = lookahead_advice(settings, measured_error_mm=19.0)
    assert distance == 960.0 and "48 lines" in text and text.endswith("--set lookahead_mm=960.0")


@pytest.mark.parametrize(
    ("profile", "overrides", "expected_beads"),
    [
        ("marlin-mixing", {"mixing_share": "0"}, [68.5 / 0.0714 / 20.4] * 3),           # L / (L_y + w) lines late
        ("marlin-mixing", {"mixing_share": "0", "lookahead_mm": "auto"}, [0.0] * 3),    # compensated
        ("foam-lwpla", {}, [8 * math.log(2) * v / 20.4 for v in (20.0, 40.0, 40.0)]),   # tau ln 2 of printing
    ],
)
def test_predicted_calibration_offsets(profile, overrides, expected_beads):
    from fgslice.settings import load_settings

    settings = load_settings(profile, overrides)
    beads = predicted_offsets(settings) / settings.bead_width
    assert np.all(np.abs(beads - np.array(expected_beads)) <= 1.0)
