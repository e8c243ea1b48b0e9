"""Previews colored by process attributes: the values read back from the G-code."""

from datetime import datetime, timezone

import numpy as np
import pytest

from fgslice.design import parse_design
from fgslice.errors import GcodeError
from fgslice.pipeline import slice_to_gcode
from fgslice.preview.attributes import move_values
from fgslice.preview.colors import load_printout
from fgslice.preview.layers import layer_figure, render_layer
from fgslice.settings import load_settings
from fgslice.slicing.layers import Placement

TEXT = """attribute("fan", "50 + 0.6*x") { attribute("flow", "90 + 0.2*x") { attribute("speed", "80 + y") {
              attribute("infill_density", "30 + 0.4*x") { rectprism(60, 20, 2, "red"); } } } }"""


@pytest.fixture(scope="module")
def sliced(tmp_path_factory):
    out = tmp_path_factory.mktemp("attr") / "part.gcode"
    design = parse_design(TEXT)
    result = slice_to_gcode(design, load_settings(None, {"strategy": "1"}), out, jobs=1,
                            stamp=datetime(2026, 1, 1, tzinfo=timezone.utc))
    return design, out, result.stats


@pytest.mark.parametrize("name, field", [("fan", lambda x, y: 50 + 0.6 * x), ("flow_rate", lambda x, y: 90 + 0.2 * x),
                                         ("speed", lambda x, y: 80 + y)])
def test_move_values_are_the_commanded_field(sliced, name, field):
    design, out, stats = sliced
    printout = load_printout(out)
    program = printout.program
    values = move_values(printout, name)
    roles = np.array(program.roles + [""])[program.role]
    part = np.isfinite(values) & (roles != "Skirt/Brim") & (program.layer >= 1) & (program.length > 1)
    mid = (program.start[part] + program.end[part]) / 2 - np.array(stats["placement_offset"])
    np.testing.assert_allclose(values[part], field(mid[:, 0], mid[:, 1]), atol=1.6)
    low, high = stats["attributes"]["flow" if name == "flow_rate" else name]
    assert low - 0.5 <= values[part].min() and values[part].max() <= high + 0.5


def test_infill_density_is_read_from_the_design(sliced, tmp_path):
    design, out, _ = sliced
    printout = load_printout(out)
    with pytest.raises(GcodeError, match="--design"):
        move_values(printout, "infill_density")
    fig, ax = layer_figure(printout, 4, design=design, attribute="infill_density")
    assert "infill_density" in ax.get_title()
    values = move_values(printout, "infill_density", design, Placement(tuple(printout.info.placement_offset)))
    program = printout.program
    roles = np.array(program.roles + [""])[program.role]
    part = np.isfinite(values) & (roles != "Skirt/Brim")
    mid = (program.start[part] + program.end[part]) / 2 - np.array(printout.info.placement_offset)
    np.testing.assert_allclose(values[part], 30 + 0.4 * mid[:, 0], atol=1e-6)


def test_render_layer_by_attribute_colors_by_value(sliced, tmp_path):
    _, out, _ = sliced
    png = tmp_path / "fan.png"
    render_layer(out, 4, png, attribute="fan")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    fig, ax = layer_figure(out, 4, attribute="fan")
    colors = ax.collections[-1].get_colors()
    assert len(np.unique(np.round(colors, 3), axis=0)) > 10


def test_cli_preview_by_attribute(sliced, tmp_path):
    from click.testing import CliRunner

    from fgslice.cli import main

    _, out, _ = sliced
    png = tmp_path / "speed.png"
    result = CliRunner().invoke(main, ["preview", str(out), "--layer", "3", "--attribute", "speed", "-o", str(png)])
    assert result.exit_code == 0, result.output
    assert png.stat().st_size > 1000
    result = CliRunner().invoke(main, ["preview", str(out), "--attribute", "colour", "-o", str(tmp_path / "x.png")])
    assert result.exit_code != 0 and "unknown attribute 'colour'" in result.output
    assert not (tmp_path / "x.png").exists()
