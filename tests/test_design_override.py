"""An enclosing fgrade overrides its children's materials (OpenVCAD's rule), in the
language and in the Python API; hidden materials are not design materials."""

from __future__ import annotations

import numpy as np
import pytest

from fgslice.design import api, check_design, format_report, parse_design
from fgslice.machine.gcode_header import read_header
from fgslice.machine.gcode_reader import read_gcode
from fgslice.pipeline import slice_to_gcode
from fgslice.settings import load_settings
from fgslice.slicing.palette import Palette

COUPON = """union() {
    fgrade(["0.5 + z/8.4", "0.5 - z/8.4"], ["white", "black"], "prob") {
        cylinder(6, 8.4, "blue");
    }
}"""


def test_the_grade_decides_and_the_child_material_is_hidden():
    design = parse_design(COUPON)
    assert [m.name for m in design.materials] == ["white", "black"]
    z = np.linspace(-4, 4, 9)
    f = design.fractions(np.zeros(9), np.ones(9), z)
    np.testing.assert_allclose(f, np.column_stack([0.5 + z / 8.4, 0.5 - z / 8.4]))
    report = check_design(design)
    assert report.fraction_ranges["white"][0] < 0.05 and report.fraction_ranges["white"][1] > 0.95
    text = format_report(report)
    assert "note: material 'blue' (line 3) is overridden by an enclosing fgrade" in text
    assert "usable: yes" in text


def test_the_api_follows_the_same_rule():
    part = api.fgrade(["0.5 + z/8.4", "0.5 - z/8.4"], ["white", "black"], api.cylinder(6, 8.4, "blue"))
    design = api.design(api.union(part))
    assert [m.name for m in design.materials] == ["white", "black"]
    assert [name for name, _ in design.overridden] == ["blue"]
    np.testing.assert_allclose(design.fractions(0.0, 0.0, 2.1), [0.75, 0.25])


def test_materials_under_booleans_and_transforms_below_a_grade_are_hidden_too():
    text = """union() {
        fgrade(["x/20 + 0.5", "0.5 - x/20"], ["red", "blue"]) {
            difference() {
                translate(0, 0, 0) { rectprism(20, 20, 4, "green"); }
                intersection() { cylinder(3, 10, "cyan"); sphere(4, "magenta"); }
            }
        }
        translate(0, 30, 0) { cube(5, "cyan"); }
    }"""
    design = parse_design(text)
    assert [m.name for m in design.materials] == ["red", "blue", "cyan"]
    assert sorted(name for name, _ in design.overridden) == ["green", "magenta"]
    np.testing.assert_allclose(design.fractions(5.0, 5.0, 0.0), [0.75, 0.25, 0])
    np.testing.assert_allclose(design.fractions(0.0, 30.0, 0.0), [0, 0, 1])


def test_the_outermost_of_nested_grades_decides():
    text = """fgrade(["0.25", "0.75"], ["white", "black"]) {
        union() { fgrade(["1", "0"], ["red", "blue"]) { cube(4, "green"); } sphere(1); }
    }"""
    design = parse_design(text)
    assert [m.name for m in design.materials] == ["white", "black"]
    assert sorted(name for name, _ in design.overridden) == ["blue", "green", "red"]
    np.testing.assert_allclose(design.fractions(1.0, 1.0, 1.0), [0.25, 0.75])


def test_a_hidden_material_does_not_make_a_two_material_grade_a_three_material_design(tmp_path):
    design = parse_design(COUPON)
    settings = load_settings("marlin-mixing", {"colors": "4", "skirt_loops": "0"})
    out = tmp_path / "coupon.gcode"
    result = slice_to_gcode(design, settings, out, jobs=1)
    assert read_header(out).materials == ("white", "black")
    assert result.stats["state_changes"] >= 3
    program = read_gcode(out)
    offset = np.array(read_header(out).placement_offset)
    tower = [i for i, role in enumerate(program.roles) if "tower" in role.lower()]
    moves = (program.e > 0) & (program.length > 0) & ~np.isin(program.role, tower)
    mid = (program.start[moves] + program.end[moves]) / 2 - offset
    mid[:, 2] -= settings.layer_height / 2
    expected = Palette(2, 4).color_of(design.fractions(mid[:, 0], mid[:, 1], mid[:, 2]))
    commanded = program.color_of_moves()[moves]
    assert np.mean(commanded == expected) > 0.95
    assert set(np.unique(commanded)) == {0, 1, 2, 3}


@pytest.mark.parametrize("mode", ["prob", "thresh"])
def test_a_primitive_outside_every_grade_keeps_its_material(mode):
    text = f"""union() {{
        fgrade(["x > 0", "x <= 0"], ["red", "blue"], "{mode}") {{ rectprism(10, 10, 2, "yellow"); }}
        translate(20, 0, 0) {{ rectprism(10, 10, 2, "yellow"); }}
    }}"""
    design = parse_design(text)
    assert [m.name for m in design.materials] == ["red", "blue", "yellow"]
    assert design.overridden == []
    np.testing.assert_allclose(design.fractions(np.array([2.0, -2.0, 20.0]), 0.0, 0.0),
                               [[1, 0, 0], [0, 1, 0], [0, 0, 1]])
