"""Resource estimates before slicing (fgslice.resources): how they scale, the refusal
when the G-code or the memory cannot fit, the warning above the thresholds, the line
``fgslice check`` prints, and the G-code estimate against the real file."""

from __future__ import annotations

import pytest
from click.testing import CliRunner

from fgslice import resources
from fgslice.cli import main
from fgslice.design.language import parse_design
from fgslice.errors import ResourceError
from fgslice.pipeline import slice_to_gcode
from fgslice.resources import GCODE_FACTOR, check_budget, estimate_resources
from fgslice.settings import load_settings

GRADED_BOX = 'fgrade(["x/{w} + 0.5", "0.5 - x/{w}"], ["blue", "yellow"]) {{ rectprism({w}, {d}, {h}); }}'
GRADED_CYLINDER = 'fgrade(["z/{h}", "1 - z/{h}"], ["blue", "yellow"]) {{ cylinder({r}, {h}); }}'


def settings(**overrides):
    return load_settings("marlin-mixing", {"skirt_loops": 0, **overrides})


def box(w, d, h):
    return parse_design(GRADED_BOX.format(w=w, d=d, h=h))


def curved(w, d, h):
    """A box graded by a field whose color boundaries curve every few mm."""
    return parse_design('fgrade(["0.5 + 0.5*sin(x/5)*cos(y/7)", "0.5 - 0.5*sin(x/5)*cos(y/7)"], '
                        f'["blue", "yellow"]) {{ rectprism({w}, {d}, {h}); }}')


def test_a_huge_box_scales_with_its_area_and_height():
    s = settings(strategy=2, colors=16)
    base = estimate_resources(curved(100, 100, 10), s)
    wide = estimate_resources(curved(200, 200, 10), s)
    tall = estimate_resources(curved(100, 100, 20), s)
    assert base.layers == 50 and tall.layers == 100
    assert 3.5 < wide.gcode_mb / base.gcode_mb < 4.5  # four times the area per layer
    assert 1.8 < tall.gcode_mb / base.gcode_mb < 2.2  # twice the layers
    assert wide.slice_s > base.slice_s and wide.print_s == pytest.approx(4 * base.print_s, rel=0.05)
    # a box graded along x: its color faces are rectangles, four moves a loop, and a box
    # twice as wide has twice the loops of twice the length
    assert 1.8 < estimate_resources(box(200, 200, 10), s).gcode_mb / estimate_resources(box(100, 100, 10), s).gcode_mb < 2.2
    # the 200 x 200 x 150 mm box at 16 colors: gigabytes (the same field on a 60 x 60 x 6 mm
    # box wrote 14.9 MB for an estimate of 13.8 MB)
    assert estimate_resources(curved(200, 200, 150), s).gcode_mb > 1000


def test_fewer_colors_and_thicker_layers_lower_the_estimate():
    part = curved(60, 60, 6)
    many = estimate_resources(part, settings(strategy=2, colors=16))
    assert estimate_resources(part, settings(strategy=2, colors=2)).gcode_mb < many.gcode_mb
    assert estimate_resources(part, settings(strategy=2, colors=16, layer_height=0.4)).gcode_mb < many.gcode_mb
    assert estimate_resources(part, settings(strategy=1, colors=16)).gcode_mb < many.gcode_mb


def test_a_full_disk_is_refused_before_anything_is_written(tmp_path, monkeypatch):
    monkeypatch.setattr(resources, "free_disk_mb", lambda output: 0.01)
    out = tmp_path / "part.gcode"
    with pytest.raises(ResourceError) as info:
        slice_to_gcode(box(20, 20, 2), settings(strategy=2, colors=8), out, jobs=1)
    assert "MB are free" in str(info.value) and "--set colors=" in info.value.hint
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_too_little_memory_is_refused_naming_jobs():
    est = estimate_resources(box(20, 20, 2), settings(strategy=2, colors=8), jobs=2)
    with pytest.raises(ResourceError) as info:
        check_budget(est, settings(strategy=2, colors=8), memory_mb=1.0, disk_mb=1e9)
    assert "memory" in str(info.value) and "--jobs 1" in info.value.hint


def test_a_large_job_is_warned_about_with_the_settings_that_help():
    s = settings(strategy=2, colors=16)
    est = estimate_resources(curved(200, 200, 150), s, jobs=1)
    warnings = check_budget(est, s, memory_mb=1e9, disk_mb=1e9)
    assert any("G-code is estimated" in w and "colors=" in w and "layer_height" in w for w in warnings)
    assert any("minutes" in w or "min:" in w for w in warnings)
    assert check_budget(estimate_resources(box(20, 20, 2), s), s, memory_mb=1e9, disk_mb=1e9) == []


@pytest.mark.parametrize("text, overrides", [
    (GRADED_BOX.format(w=30, d=20, h=2), {"strategy": 2, "colors": 8}),
    (GRADED_BOX.format(w=30, d=20, h=2), {"strategy": 1, "colors": 4}),
    (GRADED_CYLINDER.format(r=8, h=3), {"strategy": 2, "colors": 4}),
    ('fgrade(["0.5 + 0.5*sin(x/5)*cos(y/7)", "0.5 - 0.5*sin(x/5)*cos(y/7)"], ["blue", "yellow"]) '
     '{ rectprism(30, 30, 1); }', {"strategy": 2, "colors": 16}),
])
def test_the_gcode_estimate_is_within_its_stated_factor(text, overrides, tmp_path):
    part, s = parse_design(text), settings(**overrides)
    out = tmp_path / "part.gcode"
    slice_to_gcode(part, s, out, jobs=1)
    real = out.stat().st_size / 1e6
    est = estimate_resources(part, s).gcode_mb
    assert 1 / GCODE_FACTOR < real / est < GCODE_FACTOR


def test_check_prints_the_estimate(tmp_path):
    design = tmp_path / "box.vcad"
    design.write_text(GRADED_BOX.format(w=30, d=20, h=2))
    result = CliRunner().invoke(main, ["check", str(design)])
    assert result.exit_code == 0, result.output
    line = next(line for line in result.output.splitlines() if line.startswith("estimate"))
    assert "10 layers" in line and "G-code ~" in line and "memory ~" in line and "slicing ~" in line
