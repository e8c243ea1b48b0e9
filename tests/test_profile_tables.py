"""The profile's ``attribute_tables``: a design's attribute without machine meaning
(OpenVCAD's MODULUS, SHORE_HARDNESS, ...) converted to a machine attribute by a table
measured for the filament, checked from the G-code."""

from __future__ import annotations

import textwrap
from datetime import datetime, timezone

import numpy as np
import pytest

from fgslice.compat.script import load_script
from fgslice.design.check import check_design, format_report
from fgslice.design.profile_tables import apply_attribute_tables, parse_attribute_tables
from fgslice.errors import SettingsError
from fgslice.machine.gcode_reader import read_gcode
from fgslice.pipeline import slice_to_gcode
from fgslice.settings import load_settings

BAR = """
import pyvcad as pv
bar = pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(60, 12, 4))
bar.set_attribute(pv.DefaultAttributes.MODULUS, pv.FloatAttribute("1000 + 20 * x"))
bar.set_attribute(pv.DefaultAttributes.SHORE_HARDNESS, pv.FloatAttribute("80 + x / 6"))
root = bar
"""
TABLES = "modulus -> temperature: 400 250, 1000 230, 1600 210; Shore_Hardness -> FLOW_RATE: 75 1.2, 85 0.8"


def _design(tmp_path, code: str = BAR):
    path = tmp_path / "design.py"
    path.write_text(textwrap.dedent(code))
    return load_script(path)


def _settings(tables: str = TABLES, profile: str | None = "foam-lwpla"):
    return load_settings(profile, {"attribute_tables": tables})


def test_the_tables_read_linearly_and_flat_beyond_their_ends():
    temperature, flow = parse_attribute_tables(TABLES)
    assert (temperature.source, temperature.target, flow.source, flow.target) == (
        "modulus", "temperature", "shore_hardness", "flow")
    (t,) = temperature([np.array([0.0, 400, 700, 1000, 1300, 1600, 2000, np.nan])])
    np.testing.assert_allclose(t[:-1], [250, 250, 240, 230, 220, 210, 210])
    assert np.isnan(t[-1])
    (f,) = flow([np.array([80.0])])  # OpenVCAD's flow_rate multiplier, as fgslice's flow percent
    assert f[0] == pytest.approx(100.0)


def test_the_design_gets_the_targets_and_check_says_where_they_come_from(tmp_path):
    design = apply_attribute_tables(_design(tmp_path), _settings())
    report = format_report(check_design(_design(tmp_path), settings=_settings()))
    assert "modulus" in report and "drives temperature through the profile's attribute_tables" in report
    assert "drives flow through the profile's attribute_tables" in report
    from fgslice.design.attributes import attribute_fields

    fields = attribute_fields(design)
    x = np.array([-30.0, 0.0, 30.0])
    np.testing.assert_allclose(fields.values("temperature", x, 0 * x, 0 * x), [250, 230, 210])
    np.testing.assert_allclose(fields.values("flow", x, 0 * x, 0 * x), [120, 100, 80])


def test_without_a_table_check_names_the_profile_route(tmp_path):
    report = format_report(check_design(_design(tmp_path), settings=_settings("")))
    assert "attribute_tables = 'modulus -> temperature: key value, key value, ...'" in report


def test_the_designs_own_conversion_wins_over_the_profiles(tmp_path):
    design = _design(tmp_path, BAR + textwrap.dedent("""
        bar.set_attribute(pv.DefaultAttributes.TEMPERATURE, pv.FloatAttribute("222"))
    """))
    converted = apply_attribute_tables(design, _settings("modulus -> temperature: 400 250, 1600 210"))
    assert converted is design


def test_the_foaming_printer_grades_temperature_from_the_modulus(tmp_path):
    settings = _settings()
    out = tmp_path / "bar.gcode"
    stats = slice_to_gcode(_design(tmp_path), settings, out, jobs=1,
                           stamp=datetime(2026, 1, 1, tzinfo=timezone.utc)).stats
    program = read_gcode(out)
    printed = (program.e > 0) & (program.length > 0) & (program.layer > 0)
    x = ((program.start + program.end) / 2)[printed, 0] - stats["placement_offset"][0]
    commanded = np.array([program.states[s].temperature for s in program.state[printed]])
    designed = np.interp(1000 + 20 * x, [400, 1000, 1600], [250, 230, 210])
    assert commanded.min() == 210 and commanded.max() == 250
    # temperature states of 5 C: the commanded one is the design's within half a level, give or take a bead
    assert np.abs(commanded - designed).max() <= 2.5 + 0.7
    assert np.corrcoef(x, commanded)[0, 1] < -0.95


@pytest.mark.parametrize("text, message", [
    ("modulus temperature: 1 2, 3 4", "is not 'source -> target: key value"),
    ("modulus -> stiffness: 1 2, 3 4", "'stiffness' is no machine attribute"),
    ("modulus -> temperature: 1 2", "are not two or more 'key value' pairs"),
    ("modulus -> temperature: 1 2, 3", "are not two or more 'key value' pairs"),
    ("modulus -> temperature: 1 2, x 4", "are not two or more 'key value' pairs"),
    ("modulus -> temperature: 1 2, nan 4", "are not two or more 'key value' pairs"),
    ("modulus -> temperature: 3 2, 1 4", "must increase"),
    ("modulus -> temperature: 1 2, 3 4; density -> temperature: 1 2, 3 4", "two tables give 'temperature'"),
    ("flow -> flow_rate: 1 2, 3 4", "converts an attribute to itself"),
])
def test_a_malformed_table_is_refused_before_anything_is_written(tmp_path, text, message):
    with pytest.raises(SettingsError, match=message):
        parse_attribute_tables(text)
    out = tmp_path / "bar.gcode"
    with pytest.raises(SettingsError, match=message):
        slice_to_gcode(_design(tmp_path), _settings(text), out, jobs=1)
    plain = _design(tmp_path, "import pyvcad as pv\nroot = pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(10, 10, 2))\n")
    with pytest.raises(SettingsError, match=message):  # also for a design without attributes
        slice_to_gcode(plain, _settings(text), out, jobs=1)
    assert not out.exists()
