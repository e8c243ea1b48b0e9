"""A temperature attribute end to end: the nozzle temperature commanded for every
extrusion move against the design's field at its midpoint, together with the material
grading, on a mixing hotend and on a toolchanger."""

from __future__ import annotations

from datetime import datetime, timezone

import numpy as np
import pytest

from fgslice.analysis.fidelity import predicted_within_half_bin
from fgslice.analysis.simulate import simulate
from fgslice.design import parse_design
from fgslice.errors import SettingsError
from fgslice.machine.gcode_header import read_header
from fgslice.machine.gcode_reader import read_gcode
from fgslice.pipeline import slice_to_gcode
from fgslice.preview.colors import load_printout, state_colors
from fgslice.settings import load_settings
from fgslice.slicing.states import header_palette
from tests.conftest import EXAMPLES

GRADED = (EXAMPLES / "temperature_gradient.vcad").read_text()
"""Yellow to blue along x (50 mm), 215 + 0.25 y degC over y = -20 .. 20."""


def _slice(text, tmp_path, profile=None, name="part.gcode", jobs=1, **overrides):
    settings = load_settings(profile, {k: str(v) for k, v in overrides.items()})
    out = tmp_path / name
    result = slice_to_gcode(parse_design(text), settings, out, jobs=jobs, stamp=datetime(2026, 1, 1, tzinfo=timezone.utc))
    return settings, read_gcode(out), result.stats, out


def _part_moves(program):
    roles = np.array(program.roles + [""])[program.role]
    return (program.e > 0) & (program.length > 0) & ~np.isin(roles, ["Skirt/Brim", "Wipe tower"])


def _commanded(program):
    """The active tool's nozzle target and the palette color of each move."""
    targets = np.array([np.nan if s.temperature is None else s.temperature for s in program.states])
    return targets[program.state], program.color_of_moves()


def _midpoints(program, stats):
    return (program.start + program.end) / 2 - np.array(stats["placement_offset"])


@pytest.mark.parametrize("strategy", [1, 2])
def test_mixing_hotend_commands_the_temperature_and_the_mixture_of_the_field(tmp_path, strategy):
    settings, program, stats, out = _slice(GRADED, tmp_path, strategy=strategy, colors=4)
    assert stats["temperature_levels"] == [210.0, 215.0, 220.0]
    assert stats["colors"] == 12
    assert stats["attributes"]["temperature"] == [210.0, 220.0]
    part = _part_moves(program)
    mid = _midpoints(program, stats)[part]
    temperature, color = (v[part] for v in _commanded(program))
    field = 215 + 0.25 * mid[:, 1]
    error = np.abs(temperature - field)
    # the level nearest the field: within half a step, but for beads on a level boundary
    assert np.mean(error <= settings.temperature_step / 2 + 0.25 * settings.bead_width) > 0.98
    assert error.max() <= settings.temperature_step
    header = read_header(out)
    palette = header_palette(2, header.colors, header.palette, header.settings.get("temperature_levels"))
    np.testing.assert_array_equal(palette.temperatures[color], temperature)
    first = palette.centers[color][:, 0]
    inner = np.abs(mid[:, 0]) < 24
    assert np.mean(np.abs(first - (mid[:, 0] / 50 + 0.5))[inner] <= 0.125 + 0.02) > 0.97
    # the mixture is commanded only when it changes: as many M165 as changes of material color
    text = out.read_text()
    mixes = [line for line in text.splitlines() if line.startswith("M165")]
    states = [int(line.split()[0][7:]) for line in text.splitlines() if line.startswith(";STATE:")]
    material = palette.material_of[states]
    assert len(mixes) == 1 + np.count_nonzero(np.diff(material))
    assert "; temperature_step = 5.0\n" in text


def test_toolchanger_sets_each_tool_before_it_is_picked_up(tmp_path):
    settings, program, stats, out = _slice(GRADED, tmp_path, profile="toolchanger", colors=4, strategy=1,
                                           temperature_lead_s=2)
    assert any(w.startswith("temperature_lead_s is not used on a toolchanger") for w in stats["warnings"])
    lines = out.read_text().splitlines()
    picks = [i for i, line in enumerate(lines) if line[:1] == "T" and line[1:].isdigit()]
    assert picks
    for i in picks:
        assert lines[i - 1].startswith(f"M104 {lines[i]} S")
    part = _part_moves(program)
    temperature, _ = (v[part] for v in _commanded(program))
    mid = _midpoints(program, stats)[part]
    assert np.mean(np.abs(temperature - (215 + 0.25 * mid[:, 1])) <= settings.temperature_step / 2 + 0.1) > 0.98
    tools = np.array([s.tool for s in program.states])[program.state][part]
    np.testing.assert_array_equal(np.unique(tools), [0, 1, 2, 3])
    # PrusaSlicer's and Moonraker's view: four tools, as many tool changes as T commands
    assert f"; total toolchanges = {len(picks)}" in lines and "; referenced_tools = 0,1,2,3" in lines
    colours = next(line for line in lines if line.startswith("; extruder_colour = "))
    assert colours.count("#") == 4


def test_a_single_material_part_graded_by_temperature_alone(tmp_path):
    settings, program, stats, out = _slice('attribute("temperature", "200 + 0.4*x") { rectprism(50, 20, 2); }',
                                           tmp_path, strategy=2)
    assert stats["temperature_levels"] == [190.0, 195.0, 200.0, 205.0, 210.0]
    assert stats["purge_mm3"] == 0 or stats["tower_mm3"] == 0
    part = _part_moves(program)
    temperature, _ = (v[part] for v in _commanded(program))
    mid = _midpoints(program, stats)[part]
    assert np.mean(np.abs(temperature - (200 + 0.4 * mid[:, 0])) <= 2.5 + 0.2) > 0.98


def test_uncovered_parts_print_at_the_profile_temperature(tmp_path):
    text = 'union() { attribute("temperature", 230) { translate(-15, 0, 0) { cube(10); } } translate(15, 0, 0) { cube(10); } }'
    settings, program, stats, _ = _slice(text, tmp_path, strategy=2)
    assert stats["temperature_levels"][0] == settings.nozzle_temperature
    assert stats["temperature_levels"][-1] == 230
    part = _part_moves(program)
    temperature, _ = (v[part] for v in _commanded(program))
    x = _midpoints(program, stats)[part][:, 0]
    assert (temperature[x < -10] == 230).all() and (temperature[x > 10] == settings.nozzle_temperature).all()


def test_temperature_changes_alone_purge_nothing(tmp_path):
    _, _, stats, out = _slice(GRADED, tmp_path, strategy=1, colors=2)
    plain = GRADED.replace('attribute("temperature", "215 + 0.25*y")', "union()")
    _, _, alone, _ = _slice(plain, tmp_path, name="plain.gcode", strategy=1, colors=2)
    lines = out.read_text().splitlines()
    alone_only = [i for i, line in enumerate(lines)
                  if line.startswith(";STATE:") and lines[i + 1].startswith("M104") and not lines[i + 2].startswith("M165")]
    assert len(alone_only) > 10
    for i in alone_only:  # printing goes on in the part, not in the tower
        assert not any(";TYPE:Wipe tower" in text for text in lines[i + 2 : i + 12])
    assert stats["state_changes"] > alone["state_changes"]
    assert stats["purge_mm3"] == alone["purge_mm3"] > 0  # the material changes purge as without the attribute


def test_the_leads_move_the_temperature_by_time_and_the_mixture_by_length(tmp_path):
    *_, plain_out = _slice(GRADED, tmp_path, strategy=2, colors=4, purge="false")
    *_, led_out = _slice(GRADED, tmp_path, name="led.gcode", strategy=2, colors=4, purge="false",
                                temperature_lead_s=3, lookahead_mm=8)

    def commands(path):
        """Each M104 / M165 line with the printing time and extruded length before it."""
        out = []
        program = read_gcode(path)
        extruding = (program.e > 0) & (program.length > 0)
        lines = path.read_text().splitlines()
        at = np.array(program.line)
        for number, line in enumerate(lines, 1):
            if line.startswith(("M104", "M165")) and line != "M104 S0":  # not the end G-code's
                before = extruding & (at < number)
                seconds = program.length[before] / (program.feed[before] / 60)
                out.append((line, float(seconds.sum()), float(program.length[before].sum())))
        return out

    a, b = commands(plain_out), commands(led_out)
    assert [c for c, *_ in a] == [c for c, *_ in b]
    moved_t = [ta - tb for (c, ta, _), (_, tb, _) in zip(a, b) if c.startswith("M104") and ta > 10]
    # the print's first state is commanded whole, where its earlier part (temperature) goes
    moved_l = [la - lb for (c, _, la), (_, _, lb) in zip(a, b) if c.startswith("M165")][1:]
    assert moved_t and min(moved_t) >= 3 - 0.05  # at the profile's speeds: longer on the slower first layer
    assert moved_l and min(moved_l) == pytest.approx(8, abs=0.05) and max(moved_l) == pytest.approx(8, abs=0.05)


def test_readers_rebuild_the_palette_from_the_header(tmp_path):
    _, program, stats, out = _slice(GRADED, tmp_path, strategy=2, colors=4)
    design = parse_design(GRADED)
    result = simulate(out, design, None, load_settings(None, {"colors": "4"}))
    assert result.palette_size == 4  # the material colors, from the header
    # the states' mixtures: what was commanded is the material color of each move's state
    palette = header_palette(2, 4, None, "210,215,220")
    assert 0 < predicted_within_half_bin(result, 4) <= 1  # (strategy 2 has no purges: the melt lags)
    part = result.part
    np.testing.assert_allclose(np.unique(result.commanded[part], axis=0), np.unique(palette.materials.centers, axis=0))
    colors = state_colors(load_printout(out))
    assert len(colors.rgba) == len(program.states) and (colors.key[program.state[_part_moves(program)]] >= 0).all()


@pytest.mark.parametrize("profile", ["foam-tpu", "template-diw"])
def test_dialects_without_a_temperature_state_refuse_it(tmp_path, profile):
    with pytest.raises(SettingsError, match="does not command as a state of its own"):
        _slice(GRADED, tmp_path, profile=profile)
    assert not (tmp_path / "part.gcode").exists()


def test_too_many_levels_are_refused_with_a_step_that_fits(tmp_path):
    with pytest.raises(SettingsError, match="levels of 0.5 C") as info:
        _slice('attribute("temperature", "210 + 0.8*x") { rectprism(50, 20, 2); }', tmp_path, temperature_step=0.5)
    assert "temperature_step=" in info.value.hint


def test_designs_without_a_temperature_attribute_record_no_levels(tmp_path):
    *_, out = _slice('attribute("fan", 40) { rectprism(20, 20, 2); }', tmp_path, strategy=2)
    text = out.read_text()
    assert "temperature_levels" not in text and "temperature_step" not in text
    assert "@" not in "".join(line for line in text.splitlines() if line.startswith(";STATE:"))


def test_check_names_the_levels_the_slice_uses(tmp_path):
    from click.testing import CliRunner

    from fgslice.cli import main

    result = CliRunner().invoke(main, ["check", str(EXAMPLES / "temperature_gradient.vcad"), "--set", "temperature_step=2"])
    assert result.exit_code == 0, result.output
    line = next(text for text in result.output.splitlines() if text.startswith("temperature levels: "))
    _, _, stats, _ = _slice(GRADED, tmp_path, strategy=2, temperature_step=2)
    assert line.startswith("temperature levels: " + ", ".join(f"{t:g}" for t in stats["temperature_levels"]) + " C")
    assert stats["temperature_levels"] == [210.0, 212.0, 214.0, 216.0, 218.0, 220.0]


def test_modelled_purges_are_those_of_the_material_changes(tmp_path):
    plain = GRADED.replace('attribute("temperature", "215 + 0.25*y")', "union()")
    assert plain != GRADED
    _, _, graded, _ = _slice(GRADED, tmp_path, strategy=1, purge_size="model")
    _, _, alone, _ = _slice(plain, tmp_path, name="plain.gcode", strategy=1, purge_size="model")
    assert graded["state_changes"] > alone["state_changes"]
    for key in ("purge_tolerance", "purge_mm3", "tower_mm3"):
        assert graded[key] == alone[key], key
    assert graded["purge_tolerance"] == pytest.approx(0.1 / 4)  # a tenth of the 4-color palette's bin
