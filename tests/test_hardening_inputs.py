"""Inputs that once crashed or printed the wrong thing, each sliced through the command
line or the pipeline as a user would: a clear error, or output that matches the design."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import traceback
import warnings

import numpy as np
import pytest
import trimesh
from click.testing import CliRunner

from fgslice.cli import main
from fgslice.design import check_design, load_design
from fgslice.design.language import parse_design
from fgslice.executor import Consumer
from fgslice.machine.gcode_reader import read_gcode
from fgslice.preview.thumbnails import render_thumbnails
from fgslice.settings import load_settings

FAR_APART = "union() { translate(-60,0,0) { cube(5); } translate(60,0,0) { cube(5); } }"
BAR = 'fgrade(["x/40 + 0.5", "0.5 - x/40"], ["red", "blue"]) { translate(0,0,1) { rectprism(40, 20, 2); } }'


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def write(tmp_path, text, name="part.vcad"):
    path = tmp_path / name
    path.write_text(text + "\n")
    return path


def extruded_mm3(path, filament_area=np.pi * 1.75**2 / 4):
    program = read_gcode(path)
    return float(program.e[(program.e > 0) & (program.length > 0)].sum() * filament_area)


def no_temporary_files(folder):
    return list(folder.glob(".*.part")) == []


@pytest.mark.parametrize("text", [FAR_APART, "union() { translate(-30,0,0) { cube(1); } translate(30,0,0) { cube(1); } }"],
                         ids=["5 mm cubes 120 mm apart", "1 mm cubes 60 mm apart"])
def test_small_parts_far_apart_slice_with_thumbnails_and_report(tmp_path, text):
    design = write(tmp_path, text)
    out = tmp_path / "far.gcode"
    result = run("slice", design, "-o", out, "--report", tmp_path / "far.png", "--set", "skirt_loops=0")
    assert result.exit_code == 0, result.output
    side = 5.0 if "cube(5)" in text else 1.0
    # a 1 mm square loses its corners to round beads (and the slice says so)
    assert extruded_mm3(out) == pytest.approx(2 * side**3, rel=0.05 if side == 5 else 0.2)
    assert "; thumbnail begin" in out.read_text()
    assert (tmp_path / "far.png").stat().st_size > 0


@pytest.mark.parametrize("expression", ["x < 5 ? -1 : 0/0", "x < 0 ? -1 : 1/0"])
def test_partly_nan_function_renders_thumbnails_without_warnings(expression):
    design = parse_design(f'function((-5,-5,0), (5,5,5), "{expression}");')
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        pngs = render_thumbnails(design, load_settings(None, {"thumbnails": "16x16,64x48"}))
    assert [(w, h) for _, w, h in pngs] == [(16, 16), (64, 48)]


@pytest.mark.parametrize("expression", ["0/0", "1/0"])
def test_function_nan_everywhere_is_refused_and_writes_nothing(tmp_path, expression):
    design = write(tmp_path, f'function((-5,-5,0), (5,5,5), "{expression}");')
    out = tmp_path / "nan.gcode"
    for thumbnails in ("16x16", ""):
        result = run("slice", design, "-o", out, "--set", f"thumbnails={thumbnails}")
        assert result.exit_code == 2, result.output
        assert "nothing to print: every layer's section of the part is empty" in result.output
        assert not out.exists() and no_temporary_files(tmp_path)
    assert not check_design(load_design(design)).usable


def test_pin_thinner_than_a_bead_is_refused(tmp_path):
    """A 0.3 mm pin prints as single beads with thin features (the default) and is refused
    without them; a 0.08 mm pin, under min_feature_size, is refused naming both settings."""
    design = write(tmp_path, "cylinder(0.15, 10);")
    result = run("slice", design, "-o", tmp_path / "pin.gcode", "--set", "thin_features=false")
    assert result.exit_code == 2 and "narrower than a bead" in result.output and "bead_width" in result.output
    assert not (tmp_path / "pin.gcode").exists()
    assert run("slice", design, "-o", tmp_path / "pin.gcode").exit_code == 0
    result = run("slice", write(tmp_path, "cylinder(0.04, 10);"), "-o", tmp_path / "needle.gcode")
    assert result.exit_code == 2 and "bead_width" in result.output and "min_feature_size" in result.output
    assert not (tmp_path / "needle.gcode").exists()


def test_mesh_of_zero_area_triangles_is_refused(tmp_path):
    v = np.array([[0, 0, 0], [10, 0, 0], [20, 0, 0], [0, 0, 5], [0, 0, 10], [0, 0, 15]], float)
    trimesh.Trimesh(v, [[0, 1, 2], [3, 4, 5], [0, 3, 5]], process=False).export(tmp_path / "flat.stl")
    result = run("slice", write(tmp_path, 'mesh("flat.stl");'), "-o", tmp_path / "flat.gcode")
    assert result.exit_code == 2 and "nothing to print" in result.output, result.output
    assert not (tmp_path / "flat.gcode").exists()


def test_box_with_missing_triangles_warns_when_sliced(tmp_path):
    box = trimesh.creation.box((20, 20, 10))
    box.apply_translation((0, 0, 5))
    trimesh.Trimesh(box.vertices, box.faces[2:], process=False).export(tmp_path / "holed.stl")
    stats = tmp_path / "holed.json"
    result = run("slice", write(tmp_path, 'mesh("holed.stl");'), "-o", tmp_path / "holed.gcode",
                 "--set", "thumbnails=", "--stats", stats)
    assert result.exit_code == 0, result.output
    assert any("not watertight" in w for w in json.loads(stats.read_text())["warnings"])
    assert "not watertight" in result.output


@pytest.mark.parametrize("colors", [125, 250, 500, 1000])
def test_large_palettes_neither_over_extrude_nor_collapse(tmp_path, colors):
    out, stats = tmp_path / "bar.gcode", tmp_path / "bar.json"
    result = run("slice", write(tmp_path, BAR), "-o", out, "--colors", colors, "--stats", stats,
                 "--set", "thumbnails=", "--set", "skirt_loops=0")
    assert result.exit_code == 0, result.output
    assert extruded_mm3(out) == pytest.approx(40 * 20 * 2, rel=0.03)
    used = json.loads(stats.read_text())["colors_used"]
    assert used >= 30  # 40 mm of bands at least 1.5 beads (0.6 mm) wide, about 66 at most


def test_infinite_grades_are_reported_as_clamped(tmp_path):
    report = check_design(parse_design('fgrade(["1/0", "0"], ["red", "blue"]) { cube(10); }'))
    assert any("infinite" in w and "+inf counts as 1" in w for w in report.warnings)
    assert report.fraction_ranges["red"] == (1.0, 1.0)
    assert not any("treated as 0" in w for w in report.warnings)


def _fails(messages):
    for _ in messages:
        pass
    raise ValueError("the consumer's own failure")


def test_a_consumer_failure_keeps_its_frames():
    with Consumer(_fails) as consumer:
        consumer.send(1)
        with pytest.raises(ValueError) as info:
            consumer.result()
    text = "".join(traceback.format_exception(info.value))
    assert "in _fails" in text and "the consumer's own failure" in text


def test_fgslice_traceback_shows_the_worker_frames(tmp_path, monkeypatch):
    """The crash that found this: the thumbnails, rendered by a process of their own."""
    design = write(tmp_path, FAR_APART)
    script = ("import sys, fgslice.preview.thumbnails as t\n"
              "def broken(*a, **k): raise ValueError('thumbnail failure')\n"
              "t.render_image = broken\n"
              "from fgslice.cli import main\n"
              "sys.argv = ['fgslice'] + sys.argv[1:]\n"
              "main()\n")
    done = subprocess.run([sys.executable, "-c", script, "slice", str(design), "-o", str(tmp_path / "o.gcode"),
                           "--jobs", "2"], capture_output=True, text=True, env={**os.environ, "FGSLICE_TRACEBACK": "1"},
                          timeout=120)
    assert done.returncode != 0
    assert "in broken" in done.stderr and "thumbnail failure" in done.stderr


@pytest.mark.parametrize("args", [["--measured-error", "nan"], ["--measured-error", "inf"],
                                  ["--melt-volume", "nan"], ["--melt-volume", "-inf"]])
def test_calibrate_refuses_non_finite_numbers(args):
    result = run("calibrate", "lookahead", *args)
    assert result.exit_code == 2 and "is not a finite number" in result.output
    assert "lookahead_mm=nan" not in result.output and "Traceback" not in result.output


def test_calibrate_refuses_an_error_larger_than_the_object():
    result = run("calibrate", "lookahead", "--measured-error", "1e300")
    assert result.exit_code == 2 and "larger than half the calibration object" in result.output


@pytest.mark.parametrize("value", ["nan", "inf"])
def test_set_refuses_non_finite_settings(tmp_path, value):
    result = run("slice", write(tmp_path, "cube(5);"), "-o", tmp_path / "o.gcode", "--set", f"lookahead_mm={value}")
    assert result.exit_code == 2 and "setting 'lookahead_mm'" in result.output and "finite number" in result.output
    assert not (tmp_path / "o.gcode").exists()


def test_deeply_nested_materials_and_profiles_are_refused(tmp_path):
    (tmp_path / "deep.json").write_text("[" * 100_000 + "]" * 100_000)
    result = run("slice", write(tmp_path, "cube(5);"), "-o", tmp_path / "o.gcode", "--materials", tmp_path / "deep.json")
    assert result.exit_code == 2 and "nests arrays or objects too deeply" in result.output
    (tmp_path / "deep.toml").write_text("bed_x = " + "[" * 100_000 + "]" * 100_000 + "\n")
    result = run("slice", write(tmp_path, "cube(5);"), "-o", tmp_path / "o.gcode", "--profile", tmp_path / "deep.toml")
    assert result.exit_code == 2 and "too deeply" in result.output


@pytest.fixture(scope="module")
def bar_gcode(tmp_path_factory):
    folder = tmp_path_factory.mktemp("bar")
    design = write(folder, BAR)
    result = run("slice", design, "-o", folder / "bar.gcode", "--colors", 8, "--set", "thumbnails=")
    assert result.exit_code == 0, result.output
    return folder / "bar.gcode", design


def test_simulate_refuses_zero_colors(bar_gcode):
    gcode, design = bar_gcode
    result = run("simulate", gcode, "--design", design, "--colors", 0)
    assert result.exit_code == 2 and "--colors" in result.output


@pytest.mark.parametrize("other", [
    'fgrade(["x/40 + 0.5", "0.5 - x/40"], ["red", "blue"]) { translate(0,0,1) { rectprism(20, 20, 2); } }',
    'fgrade(["x/40 + 0.5", "0.5 - x/40"], ["red", "blue"]) { cube(10); }',
    'fgrade(["x/40 + 0.5", "0.5 - x/40"], ["green", "blue"]) { translate(0,0,1) { rectprism(40, 20, 2); } }',
], ids=["half the bar", "a cube", "other materials"])
def test_simulate_refuses_a_design_the_gcode_was_not_sliced_from(bar_gcode, tmp_path, other):
    gcode, design = bar_gcode
    assert run("simulate", gcode, "--design", design).exit_code == 0
    result = run("simulate", gcode, "--design", write(tmp_path, other))
    assert result.exit_code == 2 and "pass the design the G-code was sliced from" in result.output, result.output
