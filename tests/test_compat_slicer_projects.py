"""OpenVCAD 3's slicer-project scripts (``PrusaSlicerProjectCompiler``,
``FullSpectrumSlicerProjectCompiler``): the guide's seven examples slice unchanged with
``fgslice slice``, and the G-code follows each field continuously where OpenVCAD would cut
it into regions."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from fgslice.cli import main
from fgslice.machine.gcode_reader import read_gcode

GUIDE = Path(__file__).parent / "fixtures" / "openvcad3_slicer_projects.md"
SCRIPTS = dict(re.findall(r"^## (\S+\.py)\n```python\n(.*?)\n```", GUIDE.read_text(), re.S | re.M))


def _cli(*args) -> str:
    result = CliRunner().invoke(main, [str(a) for a in args])
    assert result.exit_code == 0, result.output
    return result.output


def _script(tmp_path: Path, name: str, code: str | None = None) -> Path:
    path = tmp_path / name
    path.write_text((SCRIPTS[name] if code is None else code) + "\n")
    return path


def _slice(tmp_path: Path, name: str, *options, code: str | None = None):
    """The G-code program of ``fgslice slice`` on the guide's script ``name``, the moves'
    midpoints in the design's frame (mm) and the slice's statistics."""
    script = _script(tmp_path, name, code)
    gcode, stats = tmp_path / "part.gcode", tmp_path / "stats.json"
    _cli("slice", script, "-o", gcode, "--stats", stats, *options)
    program, stats = read_gcode(gcode), json.loads(stats.read_text())
    mid = (program.start + program.end) / 2 - np.array(stats["placement_offset"])
    return program, mid, stats


def _roles(program) -> np.ndarray:
    return np.array(program.roles + [""])[program.role]


def test_the_fixture_holds_the_guides_seven_examples():
    assert sorted(SCRIPTS) == [
        "01_fuzzy_skin_cylinder.py", "02_infill_density_bar.py", "03_temperature_compensation_demo.py",
        "04_full_spectrum_color_gradient.py", "05_full_spectrum_volume_fractions.py",
        "06_prusa_colormix_color_gradient.py", "07_prusa_colormix_volume_fractions.py"]
    assert all("compiler.compile()" in code for code in SCRIPTS.values())


def test_fuzzy_skin_point_distance_sets_the_texture_along_the_height(tmp_path):
    program, mid, stats = _slice(tmp_path, "01_fuzzy_skin_cylinder.py", "--layer-height", "0.4")
    outer = (program.e > 0) & (program.length > 0) & (_roles(program) == "External perimeter")
    layers = np.unique(program.layer[outer])
    points = np.array([np.count_nonzero(outer & (program.layer == k)) for k in layers])
    z = np.array(program.layer_z)[layers] - 0.2 - stats["placement_offset"][2]  # mid-layer, design frame
    distance = 0.3 + 1.2 * np.clip((z + 10) / 20, 0, 1)
    # the points along the wall, 2 pi (r - w/2) long, are the field's distance apart on every layer
    np.testing.assert_allclose(points * distance, 2 * np.pi * (10 - 0.2), rtol=0.05)
    assert points[0] > 3 * points[-1]
    # moved across the wall by PrusaSlicer's default 0.3 mm at most
    radius = np.hypot(*(program.end[outer, :2] - np.array(stats["placement_offset"][:2])).T)
    assert np.abs(radius - 9.8).max() == pytest.approx(0.3, abs=0.02)


def test_infill_density_bar_sparse_infill_per_mm_rises_with_the_field(tmp_path):
    program, mid, _ = _slice(tmp_path, "02_infill_density_bar.py", "--strategy", "1")
    infill = (program.e > 0) & (program.length > 0) & (_roles(program) == "Internal infill") & (program.layer == 6)
    x = mid[infill, 0]
    edges = np.linspace(-36, 36, 5)  # four bands within the walls
    per_mm = np.array([program.e[infill][(x >= a) & (x < b)].sum() / (b - a) for a, b in zip(edges, edges[1:])])
    assert all(np.diff(per_mm) > 0)
    density = 10 + 60 * ((edges[1:] + edges[:-1]) / 2 + 40) / 80  # at the bands' centres: 19 .. 60 %
    ratio = per_mm / density
    np.testing.assert_allclose(ratio, ratio.mean(), rtol=0.2)  # sparse infill in proportion to the field


def test_temperature_bar_m104_follows_the_field_and_extrusion_follows_the_flow_table(tmp_path):
    program, mid, _ = _slice(tmp_path, "03_temperature_compensation_demo.py", "--profile", "foam-lwpla")
    printed = (program.e > 0) & (program.length > 0) & (program.layer > 0) & (np.abs(mid[:, 0]) < 69)
    commanded = np.array([program.states[s].temperature for s in program.state[printed]])
    field = np.clip(mid[printed, 0] / 3 + 236, 216, 256)
    # 5 C states: each move at the level of its own field within half a step (and look-ahead)
    assert np.median(np.abs(commanded - field)) <= 2.5
    assert np.corrcoef(field, commanded)[0, 1] > 0.98
    first = program.line[np.flatnonzero(printed)[0]]
    heats = {e.target for e in program.temperatures if e.line > first and e.target > 0}
    assert set(np.unique(commanded)) <= heats and min(heats) == 215 and max(heats) == 255  # the 5 C levels
    per_mm = program.e[printed] / program.length[printed]
    levels = np.unique(commanded)
    by_level = np.array([np.median(per_mm[commanded == t]) for t in levels])
    expected = np.interp(levels, [216, 236, 256], [1.50, 0.86, 0.66])
    np.testing.assert_allclose(by_level / by_level[0], expected / expected[0], rtol=0.08)


def _blue_share(program, mid, channels: int, blue: int) -> tuple[np.ndarray, np.ndarray]:
    """x (mm) and the commanded share of channel ``blue`` on the printed moves of layer 5
    inside the 60 x 10 mm bar."""
    printed = (program.e > 0) & (program.length > 0) & (program.layer == 5) & (np.abs(mid[:, :2]) <= [30, 5]).all(axis=1)
    share = np.array([program.states[s].mix_fractions(channels)[blue] for s in program.state[printed]])
    return mid[printed, 0], share


@pytest.mark.parametrize("name", ["05_full_spectrum_volume_fractions.py", "07_prusa_colormix_volume_fractions.py"])
def test_volume_fractions_bar_mixture_follows_the_fractions(tmp_path, name):
    program, mid, _ = _slice(tmp_path, name, "--colors", "8", "--strategy", "1")
    x, blue = _blue_share(program, mid, 2, 1)
    # eight palette bins of 1/8: the commanded share is the field's within a bin
    assert np.abs(blue - (x + 30) / 60).max() <= 1 / 8 + 0.02
    assert np.corrcoef(x, blue)[0, 1] > 0.95


def test_volume_fraction_materials_put_each_material_on_its_slot(tmp_path):
    code = SCRIPTS["05_full_spectrum_volume_fractions.py"].replace(
        'volume_fraction_materials={"red": 1, "blue": 2}', 'volume_fraction_materials={"red": 2, "blue": 1}')
    program, mid, _ = _slice(tmp_path, "05_full_spectrum_volume_fractions.py", "--colors", "8", "--strategy", "1",
                             code=code)
    assert "; materials = blue,red" in (tmp_path / "part.gcode").read_text()
    x, blue = _blue_share(program, mid, 2, 0)  # blue on slot 1: channel A
    assert np.abs(blue - (x + 30) / 60).max() <= 1 / 8 + 0.02


def _header(tmp_path: Path, key: str) -> str:
    return re.search(rf"^; {key} = (.*)$", (tmp_path / "part.gcode").read_text(), re.M).group(1)


def test_prusa_colormix_colour_bar_is_printed_as_mixtures_of_prusas_cmykw_filaments(tmp_path):
    from fgslice.design.color_mix import parse_filament_colors, unmix

    cmykw = "#0082ad,#d10f4f,#efd00b,#3d3e3d,#e6eaef"  # the compiler's documented defaults
    program, mid, _ = _slice(tmp_path, "06_prusa_colormix_color_gradient.py", "--colors", "56", "--strategy", "1",
                             "--set", "channels=5")
    assert _header(tmp_path, "filament_colors") == cmykw
    printed = (program.e > 0) & (program.length > 0) & (program.layer == 5) & (np.abs(mid[:, :2]) <= [30, 5]).all(axis=1)
    commanded = np.array([program.states[s].mix_fractions(5) for s in program.state[printed]])
    x = mid[printed, 0]
    target = unmix(np.column_stack([(x + 30) / 60, (30 - x) / 60, np.ones_like(x)]), tuple(parse_filament_colors(cmykw)))
    # 56 colours of 5 materials are fractions in steps of 1/4: the nearest mixture within a step
    assert np.abs(commanded - target).max() <= 0.25
    assert np.corrcoef(x, commanded[:, 1])[0, 1] > 0.85  # magenta rises along the bar


def test_full_spectrum_colour_bar_on_a_toolchanger_takes_the_nearest_filament(tmp_path):
    program, mid, _ = _slice(tmp_path, "04_full_spectrum_color_gradient.py", "--profile", "toolchanger",
                             "--colors", "5", "--set", "palette=ends", "--strategy", "1")
    text = (tmp_path / "part.gcode").read_text()
    assert _header(tmp_path, "filament_colors") == "#00ffff,#ff00ff,#ffff00,#000000,#ffffff"
    # each tool's palette colour, from the header: '; color 4 = A 100% / B 0% / ... : T4'
    holds = {int(tool): [float(v) for v in re.findall(r"([\d.]+)%", label)]
             for label, tool in re.findall(r"^; color \d+ = (.*?) : T(\d+)$", text, re.M)}
    printed = (program.e > 0) & (program.length > 0) & (program.layer == 5) & (np.abs(mid[:, :2]) <= [30, 5]).all(axis=1)
    filament = np.array([np.argmax(holds[program.states[s].tool]) for s in program.state[printed]])
    x = mid[printed, 0]
    # cyan (slot 1) where the intended colour is nearer cyan, magenta (slot 2) where nearer magenta
    assert (filament[x < -3] == 0).all() and (filament[x > 3] == 1).all()
    assert (x < -3).sum() > 10 and (x > 3).sum() > 10


def test_an_explicit_filament_colors_setting_wins_over_the_compilers_filaments(tmp_path):
    _slice(tmp_path, "06_prusa_colormix_color_gradient.py", "--colors", "8", "--strategy", "1",
           "--set", "filament_colors=#00ffff,#ff00ff")
    assert _header(tmp_path, "filament_colors") == "#00ffff,#ff00ff"
    assert _header(tmp_path, "materials") == "cyan,magenta"
    out = _cli("check", tmp_path / "06_prusa_colormix_color_gradient.py", "--set", "filament_colors=#00ffff,#ff00ff")
    assert ("note: filament colours #00ffff,#ff00ff from the profile or --set, not PrusaSlicerProjectCompiler's "
            "default filaments") in out


def test_the_filaments_given_to_the_compiler_are_the_loaded_colours(tmp_path):
    code = SCRIPTS["06_prusa_colormix_color_gradient.py"].replace(
        "    enable_color_mix=True,\n",
        '    enable_color_mix=True,\n    color_mix_filaments=[{"slot": 2, "color_hex": "#FF00FF"}, '
        '{"slot": 1, "color_hex": "#00FFFF"}],\n')
    program, mid, _ = _slice(tmp_path, "06_prusa_colormix_color_gradient.py", "--colors", "8", "--strategy", "1",
                             code=code)
    assert _header(tmp_path, "filament_colors") == "#00ffff,#ff00ff"  # in slot order
    x, magenta = _blue_share(program, mid, 2, 1)
    # cyan + magenta light in linear RGB is the mixture itself: the magenta share is the red channel
    assert np.abs(magenta - (x + 30) / 60).max() <= 1 / 8 + 0.02


def test_check_says_the_compilers_regions_are_not_used(tmp_path):
    out = _cli("check", _script(tmp_path, "02_infill_density_bar.py"), "--set", "strategy=1")
    assert ("note: PrusaSlicerProjectCompiler (line 18): its stepwise regions (num_regions=12) are not used: "
            "fgslice grades every attribute continuously") in out
    out = _cli("check", _script(tmp_path, "04_full_spectrum_color_gradient.py"), "--set", "channels=5",
               "--set", "colors=21")
    assert "(max_palette_size=10) are not used" in out
    assert "note: filament colours #00ffff,#ff00ff,#ffff00,#000000,#ffffff from " \
           "FullSpectrumSlicerProjectCompiler's default filaments" in out


@pytest.mark.parametrize("change,message", [
    (("num_regions=12", "num_region=12"), "PrusaSlicerProjectCompiler has no argument 'num_region'"),
    (("num_regions=12", 'color_mix_filaments=[{"slot": 1, "color_hex": "#FF0000"}, {"slot": 3, "color_hex": "#0000FF"}]'),
     "color_mix_filaments fills slots 1, 3"),
    (("num_regions=12", 'volume_fraction_materials={"green": 1}'), "volume_fraction_materials names 'green'"),
])
def test_bad_compiler_arguments_fail_at_the_compilers_line(tmp_path, change, message):
    code = SCRIPTS["02_infill_density_bar.py"].replace(*change)
    result = CliRunner().invoke(main, ["check", str(_script(tmp_path, "bar.py", code))])
    assert result.exit_code != 0 and message in result.output
    assert "bar.py:18:" in result.output


def test_a_progress_callback_hears_the_compile_finish(tmp_path):
    from fgslice.compat.script import load_script

    code = SCRIPTS["02_infill_density_bar.py"].replace(
        "compiler.compile()", "heard = []\ncompiler.set_progress_callback(heard.append)\ncompiler.compile()\n"
                              "assert heard == [1.0], heard")
    design = load_script(_script(tmp_path, "bar.py", code))
    assert design.bounds()[1] == pytest.approx((40, 10, 2))
