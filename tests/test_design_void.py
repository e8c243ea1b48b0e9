"""OpenVCAD's built-in materials, and ``void``: empty space, never a channel."""

from __future__ import annotations

import json

import numpy as np
import pytest

from fgslice.design import api, builtin_library, check_design, format_report, parse_design
from fgslice.errors import DesignError
from fgslice.machine.gcode_header import read_header
from fgslice.machine.gcode_reader import read_gcode
from fgslice.pipeline import slice_to_gcode
from fgslice.settings import load_settings
from tests.conftest import EXAMPLES

OPENVCAD_DEFAULTS = ["red", "green", "blue", "gray", "yellow", "cyan", "magenta", "white", "black", "pink",
                     "clear", "darkgray", "lightgray", "liquid", "support", "void"]

HOLE = 'fgrade(["0.5", "rho < 5"], ["red", "void"], "thresh") { rectprism(30, 30, 4, "blue"); }'


def _extruded_volume(out, settings) -> float:
    program = read_gcode(out)
    printing = (program.e > 0) & (program.length > 0)
    tower = [i for i, role in enumerate(program.roles) if "tower" in role.lower()]
    printing &= ~np.isin(program.role, tower)
    return float(program.e[printing].sum() * np.pi * settings.filament_diameter**2 / 4)


def test_every_openvcad_default_material_is_built_in():
    library = builtin_library()
    for name in OPENVCAD_DEFAULTS:
        assert library.get(name).name == name
    assert library.get("void").rgba[3] == 0
    design = parse_design('fgrade(["0.9 - x/800", "0.1 + x/800"], ["red", "liquid"]) { rectprism(160, 20, 8); }')
    assert [m.name for m in design.materials] == ["red", "liquid"]


def test_void_where_it_wins_is_a_hole_in_every_section():
    design = parse_design(HOLE)
    assert [m.name for m in design.materials] == ["red"]
    assert design.section(0.0).area == pytest.approx(900 - np.pi * 25, rel=2e-3)
    assert design.sdf(0.0, 0.0, 0.0) > 0 and design.sdf(10.0, 10.0, 0.0) < 0
    np.testing.assert_allclose(design.fractions(10.0, 10.0, 0.0), [1.0])
    report = check_design(design)
    assert "note: 'void' is empty space" in format_report(report)
    full = check_design(parse_design('rectprism(30, 30, 4, "red");'))
    assert report.inside_samples / full.inside_samples == pytest.approx((900 - np.pi * 25) / 900, abs=0.01)


def test_void_that_does_not_win_is_dropped_and_the_others_renormalized():
    design = parse_design('fgrade(["0.5", "0.3", "0.2 + x/100"], ["red", "blue", "void"]) { rectprism(20, 20, 2); }')
    assert [m.name for m in design.materials] == ["red", "blue"]
    np.testing.assert_allclose(design.fractions(np.array([-5.0, 5.0]), 0.0, 0.0), [[0.625, 0.375]] * 2)
    assert design.section(0.0).area == pytest.approx(400)


def test_a_void_grade_in_prob_mode_cuts_where_void_has_the_largest_fraction():
    design = parse_design('fgrade(["0.5 - x/20", "0.25", "0.5 + x/20"], ["red", "blue", "void"]) { rectprism(20, 10, 2); }')
    # void > red for x > 0 and void > blue for x > -5: the printed part is x < 0
    assert design.section(0.0).bounds == pytest.approx((-10, -5, 0, 5), abs=0.06)
    f = design.fractions(-5.0, 0.0, 0.0)
    np.testing.assert_allclose(f, [0.75 / 1.0, 0.25 / 1.0])


def test_the_extruded_volume_is_the_part_minus_the_void(tmp_path):
    design = parse_design(HOLE)
    settings = load_settings(None, {"colors": "1", "skirt_loops": "0", "strategy": "2"})
    out = tmp_path / "hole.gcode"
    slice_to_gcode(design, settings, out, jobs=1)
    assert _extruded_volume(out, settings) == pytest.approx((900 - np.pi * 25) * 4, rel=0.03)
    program = read_gcode(out)
    offset = np.array(read_header(out).placement_offset)
    mid = (program.start + program.end)[(program.e > 0) & (program.length > 0)] / 2 - offset
    assert np.hypot(mid[:, 0], mid[:, 1]).min() > 5 - 0.3


def test_strategy_1_prints_a_void_hole_like_the_same_hole_cut_by_difference(tmp_path):
    settings = load_settings(None, {"colors": "1", "skirt_loops": "0", "strategy": "1"})
    volumes = []
    for name, text in (("void", HOLE), ("cut", 'difference() { rectprism(30, 30, 4, "red"); cylinder(5, 4); }')):
        out = tmp_path / f"{name}.gcode"
        slice_to_gcode(parse_design(text), settings, out, jobs=1)
        volumes.append(_extruded_volume(out, settings))
    assert volumes[0] == pytest.approx(volumes[1], rel=0.02)


def test_a_void_primitive_in_a_union_is_a_hole():
    design = api.design(api.union(api.sphere(3, "void"), api.cube(10, "red")))
    assert [m.name for m in design.materials] == ["red"]
    assert design.section(0.0).area == pytest.approx(100 - np.pi * 9, rel=2e-3)


def test_void_in_a_materials_file_is_still_empty_space(tmp_path):
    library = tmp_path / "vtp.json"
    library.write_text(json.dumps({"materials": [{"name": "state_a", "r": 255, "g": 0, "b": 0},
                                                 {"name": "void", "r": 0, "g": 0, "b": 255}]}))
    text = 'fgrade(["x < 0", "x >= 0"], ["state_a", "void"], "thresh") { rectprism(20, 10, 2); }'
    design = parse_design(text, materials=library)
    assert [m.name for m in design.materials] == ["state_a"]
    settings = load_settings(None, {"colors": "1", "skirt_loops": "0"})
    out = tmp_path / "half.gcode"
    slice_to_gcode(design, settings, out, jobs=1)
    assert read_header(out).materials == ("state_a",)
    assert _extruded_volume(out, settings) == pytest.approx(10 * 10 * 2, rel=0.03)


def test_a_design_of_void_only_is_refused():
    with pytest.raises(DesignError, match="void only"):
        parse_design('sphere(5, "void");')


def test_a_void_hole_in_a_part_without_material_names_keeps_the_default_material():
    design = parse_design('union() { sphere(3, "void"); cube(10); }')
    assert [m.name for m in design.materials] == ["default"]
    assert design.section(0.0).area == pytest.approx(100 - np.pi * 9, rel=2e-3)


def test_the_void_grid_of_a_large_part_stays_bounded():
    from fgslice.design import void

    calls = []

    def margin(x, y):
        calls.append(np.broadcast_shapes(x.shape, y.shape))
        return np.where(np.hypot(x, y) < 100, 1.0, -1.0)

    region = void.void_region(margin, (-500, -500, 500, 500), 0.1)
    assert np.prod(calls[0]) <= void.MAX_GRID_POINTS * 1.01
    assert region.area == pytest.approx(np.pi * 100**2, rel=0.01)


def test_where_void_wins_is_found_without_evaluating_parts_that_cannot_be_void(monkeypatch):
    from fgslice.design.blend import Blend

    text = (EXAMPLES / "blended_blocks.vcad").read_text()
    design = parse_design(text)
    xs, ys = np.meshgrid(np.linspace(-19, 19, 77), np.linspace(-9, 9, 37))
    full = design.fractions(xs, ys, np.zeros_like(xs))  # (the blended fractions, void dropped)
    calls = []
    blend_raw = Blend.raw
    monkeypatch.setattr(Blend, "raw", lambda self, *a: calls.append(1) or blend_raw(self, *a))
    margin = design.void_margin(xs, ys, np.zeros_like(xs))
    assert not calls
    inside = np.hypot(xs, ys) <= 3 + 1e-9
    np.testing.assert_array_equal(margin > 0, inside)
    assert (margin[~inside] == -1).all() and np.allclose(full.sum(axis=-1), 1)
    # the section: the blocks minus the 6 mm hole
    assert design.section(0.0).area == pytest.approx(40 * 20 - np.pi * 9, rel=2e-3)
