"""Process attributes in the language and the API: parsing, nearest-enclosing rule, frames,
and check's ranges against the machine's limits."""

import numpy as np
import pytest

from fgslice.design import api, check_design, format_report, parse_design
from fgslice.design.attributes import AttributeFields, attribute_fields, limits
from fgslice.errors import DesignError, FgsliceError
from fgslice.settings import Settings, load_settings


def test_language_attribute_evaluates_in_its_frame_and_keeps_the_geometry():
    design = parse_design('translate(10, 0, 0) { attribute("fan", "50 + 0.6*x") { rectprism(100, 20, 2); } }')
    fields = attribute_fields(design)
    assert fields.names == ("fan",)
    x = np.array([-40.0, 10.0, 60.0])
    np.testing.assert_allclose(fields.values("fan", x, 0, 0), 50 + 0.6 * (x - 10))
    assert design.bounds() == ((-40.0, -10.0, -1.0), (60.0, 10.0, 1.0))
    assert design.section(0).area == pytest.approx(2000)
    np.testing.assert_array_equal(design.fractions(x, 0, 0), [[1], [1], [1]])


def test_nearest_enclosing_attribute_of_a_name_decides_and_others_pass_through():
    design = parse_design(
        """attribute("fan", 30) { attribute("flow", "100 + y") {
               union() { translate(-10, 0, 0) { attribute("fan", 70) { cube(10); } } translate(10, 0, 0) { cube(10); } }
           } }"""
    )
    fields = attribute_fields(design)
    assert fields.names == ("fan", "flow")
    x = np.array([-10.0, 10.0])
    np.testing.assert_allclose(fields.values("fan", x, 2, 0), [70, 30])
    np.testing.assert_allclose(fields.values("flow", x, 2, 0), [102, 102])
    assert np.isnan(fields.values("speed", x, 0, 0)).all()


def test_flow_rate_is_flow_and_union_children_own_their_points_first_wins():
    part = api.union(api.attribute("flow_rate", 80, api.cube(10)), api.attribute("flow", lambda x, y, z: 90 + x, api.cube(20)))
    fields = AttributeFields(part)
    assert fields.names == ("flow",)
    np.testing.assert_allclose(fields.values("flow", [0.0, 8.0, 30.0], 0, 0), [80, 98, 120])


def test_attribute_sees_d_and_fgrade_materials_pass_through_it():
    part = api.fgrade(["x > 0", "x <= 0"], ["red", "blue"], api.attribute("speed", "100 + 10*d", api.sphere(5)))
    design = api.design(part)
    np.testing.assert_allclose(attribute_fields(design).values("speed", [0.0, 3.0], 0, 0), [50, 80])
    np.testing.assert_allclose(design.fractions([2.0, -2.0], 0, 0), [[1, 0], [0, 1]])


def test_designs_without_attributes_have_none():
    assert attribute_fields(parse_design("sphere(3);")) is None


@pytest.mark.parametrize(
    "text, message",
    [
        ('attribute("fam", 3) { sphere(1); }', "unknown attribute 'fam'"),
        ('attribute("fan") { sphere(1); }', "attribute takes"),
        ('attribute("fan", 3);', "attribute has no children"),
        ('attribute("fan", "x +") { sphere(1); }', ""),
    ],
)
def test_language_errors_are_located(text, message):
    with pytest.raises(FgsliceError) as info:
        parse_design(text)
    assert message in info.value.message
    assert info.value.line == 1


def test_api_errors():
    with pytest.raises(DesignError, match="unknown attribute"):
        api.attribute("colour", 3, api.sphere(1))
    with pytest.raises(DesignError, match="no children"):
        api.attribute("fan", 3)


def test_check_reports_ranges_and_refuses_what_the_machine_cannot_do():
    design = parse_design('attribute("fan", "50 + 0.6*x") { attribute("temperature", "200 + z") { rectprism(100, 20, 2); } }')
    report = check_design(design, samples=40)
    assert report.usable, report.errors
    lo, hi = report.attribute_ranges["fan"]
    assert 20 <= lo < 22 and 78 < hi <= 80
    assert report.attribute_ranges["temperature"][0] >= 199 and report.attribute_ranges["temperature"][1] <= 201
    assert "attribute fan" in format_report(report)

    hot = parse_design('attribute("temperature", "260 + x") { rectprism(100, 20, 2); }')
    report = check_design(hot, samples=40)
    assert not report.usable
    assert "attribute 'temperature' ranges" in report.errors[0] and "300" in report.errors[0]
    assert check_design(hot, samples=40, settings=load_settings(None, {"max_nozzle_temperature": "320"})).usable


def test_limits_follow_the_settings():
    s = Settings()
    got = limits(s)
    assert got["flow"] == (s.min_flow_percent, s.max_flow_percent)
    assert got["speed"][1] == pytest.approx(100 * s.travel_speed / s.infill_speed)
    assert limits(Settings(max_cross_section_mm2=0.1))["flow"][1] == pytest.approx(100 * 0.1 / s.bead_area)


def test_cli_check_takes_the_machine_limits_from_the_profile(tmp_path):
    from click.testing import CliRunner

    from fgslice.cli import main

    path = tmp_path / "fast.vcad"
    path.write_text('attribute("speed", "220 + x") { rectprism(100, 20, 2); }')
    result = CliRunner().invoke(main, ["check", str(path)])
    assert result.exit_code == 1
    assert "attribute speed" in result.output and "attribute 'speed' ranges" in result.output
    result = CliRunner().invoke(main, ["check", str(path), "--set", "travel_speed=300"])
    assert result.exit_code == 0, result.output
