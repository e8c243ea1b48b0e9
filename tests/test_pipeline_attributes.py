"""Instantaneous attributes end to end: the fan, flow and speed commanded for every
extrusion move against the design's field at its midpoint."""

from __future__ import annotations

from datetime import datetime, timezone

import numpy as np
import pytest

from fgslice.design import parse_design
from fgslice.errors import DesignError
from fgslice.machine.gcode_reader import read_gcode
from fgslice.pipeline import slice_to_gcode
from fgslice.settings import load_settings
from fgslice.toolpaths.paths import bead_area

PLATE = "rectprism(100, 20, 2);"


def _slice(text, tmp_path, jobs=1, name="part.gcode", **overrides):
    settings = load_settings(None, {k: str(v) for k, v in overrides.items()})
    out = tmp_path / name
    result = slice_to_gcode(parse_design(text), settings, out, jobs=jobs, stamp=datetime(2026, 1, 1, tzinfo=timezone.utc))
    return settings, read_gcode(out), result.stats, out


def _printing(program):
    return (program.e > 0) & (program.length > 0)


def _design_midpoints(program, stats):
    offset = np.array(stats["placement_offset"])
    mid = (program.start + program.end) / 2 - offset
    return mid


def _roles(program, names):
    return np.isin(np.array(program.roles + [""])[program.role], names)


@pytest.mark.parametrize("strategy", [1, 2])
def test_fan_follows_the_field_along_every_segment(tmp_path, strategy):
    settings, program, stats, _ = _slice(f'attribute("fan", "50 + 0.6*x") {{ {PLATE} }}', tmp_path, strategy=strategy)
    fan = program.fan_of_moves()
    part = _printing(program) & ~_roles(program, ["Skirt/Brim", "Wipe tower"]) & (program.layer >= settings.fan_off_layers)
    offset = np.array(stats["placement_offset"])
    mid = _design_midpoints(program, stats)[part]
    field = 50 + 0.6 * mid[:, 0]
    np.testing.assert_allclose(fan[part], field, atol=settings.attribute_tolerance / 2 + 0.5)
    for end in (program.start[part], program.end[part]):
        assert np.abs(fan[part] - (50 + 0.6 * (end[:, 0] - offset[0]))).max() <= 5
    left, right = mid[:, 0] < -49, mid[:, 0] > 49
    assert np.abs(fan[part][left] - 20).max() < 2 and np.abs(fan[part][right] - 80).max() < 2
    # the first layers print with the fan off, the skirt with the profile's fan
    assert (fan[_printing(program) & (program.layer < settings.fan_off_layers)] == 0).all()
    skirt = _printing(program) & _roles(program, ["Skirt/Brim"]) & (program.layer >= settings.fan_off_layers)
    np.testing.assert_allclose(fan[skirt], settings.fan_speed, atol=0.5)
    low, high = stats["attributes"]["fan"]
    assert 19.5 < low < 21 and 79 < high < 80.5


def test_flow_scales_each_segment_and_the_volume(tmp_path):
    field = "75 + 0.25*(x + 50)"
    settings, program, stats, _ = _slice(f'attribute("flow_rate", "{field}") {{ {PLATE} }}', tmp_path)
    _, _, plain, _ = _slice(PLATE, tmp_path, name="plain.gcode")
    part = _printing(program) & ~_roles(program, ["Skirt/Brim"])
    area = np.pi * settings.filament_diameter**2 / 4
    nominal = program.length * bead_area(program.width, settings.layer_height) / area
    mid = _design_midpoints(program, stats)[part]
    # E is rounded to 5 decimals: compare on moves long enough for that not to matter
    long = program.length[part] > 1.0
    ratio = (program.e[part] / nominal[part])[long] * 100
    np.testing.assert_allclose(ratio, (75 + 0.25 * (mid[:, 0] + 50))[long], atol=settings.attribute_tolerance / 2 + 0.1)
    skirt = _printing(program) & _roles(program, ["Skirt/Brim"])
    np.testing.assert_allclose(program.e[skirt].sum(), nominal[skirt].sum(), rtol=1e-4)
    # the plate is uniform in x: the part's volume scales by the mean flow, 87.5%
    skirt_mm3 = nominal[skirt].sum() * area
    assert (stats["extruded_mm3"] - skirt_mm3) / (plain["extruded_mm3"] - skirt_mm3) == pytest.approx(0.875, abs=0.01)


def test_speed_scales_each_feature_speed(tmp_path):
    settings, program, stats, _ = _slice(f'attribute("speed", "75 + 0.5*x") {{ {PLATE} }}', tmp_path, strategy=1)
    _, _, plain, _ = _slice(PLATE, tmp_path, name="plain.gcode", strategy=1)
    part = _printing(program) & ~_roles(program, ["Skirt/Brim"]) & (program.layer > 0)
    feature = np.where(_roles(program, ["External perimeter"]), settings.outer_wall_speed,
                       np.where(_roles(program, ["Internal infill"]), settings.infill_speed, settings.print_speed))
    mid = _design_midpoints(program, stats)[part]
    share = program.feed[part] / 60 / feature[part] * 100
    np.testing.assert_allclose(share, 75 + 0.5 * mid[:, 0], atol=settings.attribute_tolerance / 2 + 0.2)
    first = _printing(program) & (program.layer == 0) & ~_roles(program, ["Skirt/Brim"])
    mid0 = _design_midpoints(program, stats)[first]
    np.testing.assert_allclose(program.feed[first] / 60 / settings.first_layer_speed * 100, 75 + 0.5 * mid0[:, 0],
                               atol=settings.attribute_tolerance / 2 + 0.2)
    assert stats["estimated_time_s"] > plain["estimated_time_s"] * 1.1


def test_nested_attributes_several_workers_and_lookahead_splits(tmp_path):
    text = """fgrade(["x/100 + 0.5", "0.5 - x/100"], ["red", "blue"]) { attribute("fan", "40 + 0.5*y") {
                  union() { attribute("fan", 90) { translate(-30, 0, 0) { cube(10); } } rectprism(100, 20, 2); } } }"""
    settings, program, stats, out = _slice(text, tmp_path, jobs=2, strategy=1, lookahead_mm=5, colors=3)
    _, _, _, serial = _slice(text, tmp_path, jobs=1, name="serial.gcode", strategy=1, lookahead_mm=5, colors=3)
    assert out.read_bytes() == serial.read_bytes()
    part = _printing(program) & ~_roles(program, ["Skirt/Brim", "Wipe tower"]) & (program.layer >= settings.fan_off_layers)
    mid = _design_midpoints(program, stats)[part]
    in_cube = (np.abs(mid[:, 0] + 30) < 4.5) & (np.abs(mid[:, 1]) < 4.5) & (np.abs(mid[:, 2]) < 4.5)
    outside = (np.abs(mid[:, 0] + 30) > 5.5) | (np.abs(mid[:, 1]) > 5.5)
    fan = program.fan_of_moves()[part]
    np.testing.assert_allclose(fan[in_cube], 90, atol=0.5)
    np.testing.assert_allclose(fan[outside], 40 + 0.5 * mid[outside, 1], atol=settings.attribute_tolerance / 2 + 0.5)
    tower = _printing(program) & _roles(program, ["Wipe tower"]) & (program.layer >= settings.fan_off_layers)
    assert tower.any()
    np.testing.assert_allclose(program.fan_of_moves()[tower], settings.fan_speed, atol=0.5)


def test_slice_refuses_attributes_outside_the_limits(tmp_path):
    with pytest.raises(DesignError, match="attribute 'flow' ranges"):
        _slice(f'attribute("flow", 300) {{ {PLATE} }}', tmp_path)
    assert not (tmp_path / "part.gcode").exists()


def _infill(program, layer):
    return _printing(program) & _roles(program, ["Internal infill"]) & (program.layer == layer)


def test_infill_density_grades_the_sparse_infill_across_the_layer(tmp_path):
    settings, program, stats, _ = _slice('attribute("infill_density", "30 + 0.5*x") { rectprism(100, 20, 4); }',
                                         tmp_path, strategy=1)
    area = np.pi * settings.filament_diameter**2 / 4
    layer = 10
    infill = _infill(program, layer)
    mid = _design_midpoints(program, stats)[infill]
    volume = program.e[infill] * area
    # the sparse area: inside the walls, about 97.5 x 17.5 mm
    inner_y = 20 - 2 * settings.walls * settings.bead_width
    for lo, hi in ((-40, -20), (-10, 10), (20, 40)):
        band = (mid[:, 0] >= lo) & (mid[:, 0] < hi)
        density = volume[band].sum() / ((hi - lo) * inner_y * settings.layer_height) * 100
        assert density == pytest.approx(30 + 0.5 * (lo + hi) / 2, rel=0.2, abs=2)
    total = volume.sum() / ((100 - 2 * settings.walls * settings.bead_width) * inner_y * settings.layer_height) * 100
    assert total == pytest.approx(30, rel=0.1)
    # as commanded: the density regions' values, the field over x = -49.2 .. 49.2 in 5-point bands
    low, high = stats["attributes"]["infill_density"]
    assert 5 <= low <= 8 and 52 <= high <= 55


def test_a_constant_infill_density_attribute_prints_as_the_setting(tmp_path):
    _, graded, _, _ = _slice('attribute("infill_density", 40) { rectprism(30, 20, 3); }', tmp_path, strategy=1)
    _, plain, _, _ = _slice("rectprism(30, 20, 3);", tmp_path, name="plain.gcode", strategy=1, infill_density=40)
    np.testing.assert_array_equal(graded.end, plain.end)
    np.testing.assert_array_equal(graded.e, plain.e)


def test_strategy_2_warns_that_it_ignores_infill_density(tmp_path):
    _, _, stats, _ = _slice('attribute("infill_density", 30) { cube(5); }', tmp_path)
    assert any("infill_density attribute is ignored" in w for w in stats["warnings"])


@pytest.mark.parametrize("tolerance", [0.5, 5.0])
def test_no_piece_spans_more_than_the_tolerance(tmp_path, tolerance):
    settings, program, stats, _ = _slice('attribute("speed", "60 + 0.004*x*x*x/10") { rectprism(100, 20, 2); }',
                                         tmp_path, attribute_tolerance=tolerance)
    part = _printing(program) & ~_roles(program, ["Skirt/Brim"]) & (program.layer > 0)
    feature = np.where(_roles(program, ["External perimeter"]), settings.outer_wall_speed, settings.print_speed)[part]
    commanded = program.feed[part] / 60 / feature * 100
    offset = np.array(stats["placement_offset"])
    for end in (program.start[part], program.end[part]):
        x = end[:, 0] - offset[0]
        assert np.abs(commanded - (60 + 0.004 * x**3 / 10)).max() <= tolerance + 0.1
    assert len(commanded) > 5 * 100 / 5 / tolerance


def test_the_tolerance_is_recorded_only_where_it_applies(tmp_path):
    *_, graded = _slice(f'attribute("fan", 40) {{ {PLATE} }}', tmp_path)
    *_, plain = _slice(PLATE, tmp_path, name="plain.gcode")
    assert "; attribute_tolerance = 2.0\n" in graded.read_text()
    assert "attribute_tolerance" not in plain.read_text()
