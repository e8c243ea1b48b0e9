"""Simulating a single-material foaming print (temperature states on the temperature
dialect): fgslice simulate and slice --report follow the commanded nozzle temperature."""

from __future__ import annotations

import json
import textwrap
from datetime import datetime, timezone

import numpy as np
import pytest
from click.testing import CliRunner

from fgslice.analysis.fidelity import fidelity
from fgslice.analysis.simulate import simulate
from fgslice.cli import main
from fgslice.compat.script import load_script
from fgslice.errors import SettingsError
from fgslice.machine.gcode_header import read_header
from fgslice.pipeline import slice_to_gcode
from fgslice.settings import load_settings

BAR = """
import pyvcad as pv
bar = pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(60, 12, 3))
{attribute}
root = bar
"""
GRADED = 'bar.set_attribute(pv.DefaultAttributes.TEMPERATURE, pv.FloatAttribute("max(min(0.6 * x + 208, 225), 190)"))'


def _sliced(tmp_path, attribute=GRADED, **overrides):
    script = tmp_path / "bar.py"
    script.write_text(textwrap.dedent(BAR.format(attribute=attribute)))
    design = load_script(script)
    settings = load_settings("foam-lwpla", {"layer_height": "0.3", **overrides})
    out = tmp_path / "bar.gcode"
    slice_to_gcode(design, settings, out, jobs=1, stamp=datetime(2026, 1, 1, tzinfo=timezone.utc))
    return script, design, settings, out


def _temperatures(result, which):
    """A result's fractions as nozzle temperatures (the mapping over the print's levels)."""
    hot, cold = result.model.temperature_a, result.model.temperature_b
    return cold + getattr(result, which)[:, 0] * (hot - cold)


def test_simulation_follows_the_commanded_temperature_and_the_thermal_lag(tmp_path):
    _, design, settings, out = _sliced(tmp_path)
    quick = simulate(out, design, None, load_settings("foam-lwpla", {"tau_s": "0.001"}))
    part = quick.part
    assert part.mean() > 0.9 and quick.model.kind == "thermal"
    assert (quick.model.temperature_a, quick.model.temperature_b) == (225, 190)  # the print's levels
    designed = _temperatures(quick, "designed")[part]
    x = ((quick.start + quick.end) / 2)[part, 0] - read_header(out).placement_offset[0]
    np.testing.assert_allclose(designed, np.clip(0.6 * x + 208, 190, 225), atol=1e-6)
    commanded = _temperatures(quick, "commanded")[part]
    assert set(np.round(commanded)) <= set(np.arange(190, 226, settings.temperature_step))
    volume = quick.volume[part]
    close = np.abs(commanded - designed) <= settings.temperature_step / 2 + 0.1
    assert volume[close].sum() / volume.sum() > 0.95
    # an instant nozzle deposits what was commanded; a slow one lags behind it
    np.testing.assert_allclose(_temperatures(quick, "deposited"), _temperatures(quick, "commanded"), atol=0.05)
    slow = simulate(out, design, None, load_settings("foam-lwpla", {"tau_s": "20"}))
    lag = np.abs(_temperatures(slow, "deposited") - _temperatures(slow, "commanded"))
    assert lag.max() > 2.0
    assert fidelity(slow).mean_error > fidelity(quick).mean_error
    assert fidelity(quick).within_half_bin > 0.9 and quick.palette_size == 8  # 190 .. 225 C by 5 C


def test_simulate_and_slice_report_work_from_the_command_line(tmp_path):
    script, _, _, out = _sliced(tmp_path)
    runner = CliRunner()
    stats = tmp_path / "sim.json"
    done = runner.invoke(main, ["simulate", str(out), "--design", str(script), "--stats", str(stats)])
    assert done.exit_code == 0, done.output
    assert "thermal model" in done.output and json.loads(stats.read_text())["palette_size"] == 8
    report = tmp_path / "bar.html"
    sliced = runner.invoke(main, ["slice", str(script), "-o", str(tmp_path / "again.gcode"), "--profile", "foam-lwpla",
                                  "--report", str(report)])
    assert sliced.exit_code == 0, sliced.output
    html = report.read_text()
    assert '<section id="fidelity"><h2>Simulated fidelity</h2>' in html and "thermal" in html


def test_a_single_material_foaming_print_without_a_temperature_grades_nothing_to_simulate(tmp_path):
    _, design, settings, out = _sliced(tmp_path, attribute="")
    with pytest.raises(SettingsError, match="nothing to simulate"):
        simulate(out, design, None, settings)
