"""``simulate`` against a design that is not the one the G-code was sliced from: the
G-code header's design fingerprint tells them apart even when the shape and the
materials are the same and only the field differs."""

from __future__ import annotations

import pytest
from click.testing import CliRunner

from fgslice.analysis.simulate import simulate
from fgslice.cli import main
from fgslice.design.fingerprint import fingerprint
from fgslice.design.language import parse_design
from fgslice.errors import DesignError
from fgslice.machine.gcode_header import read_header
from fgslice.pipeline import slice_to_gcode
from fgslice.settings import load_settings

ALONG_X = 'fgrade(["x/30 + 0.5", "0.5 - x/30"], ["blue", "yellow"]) { rectprism(30, 20, 1); }'
ALONG_Y = 'fgrade(["y/20 + 0.5", "0.5 - y/20"], ["blue", "yellow"]) { rectprism(30, 20, 1); }'


@pytest.fixture
def sliced(tmp_path):
    settings = load_settings("marlin-mixing", {"strategy": 2, "colors": 4, "thumbnails": ""})
    out = tmp_path / "part.gcode"
    slice_to_gcode(parse_design(ALONG_X), settings, out, jobs=1)
    return out, settings


def test_the_header_records_the_design_fingerprint(sliced):
    out, _ = sliced
    recorded = read_header(out).settings["design_fingerprint"]
    assert recorded == fingerprint(parse_design(ALONG_X))
    # whitespace and comments do not change it; the field does
    assert fingerprint(parse_design("// the same part\n" + ALONG_X.replace("; }", ";\n}"))) == recorded
    assert fingerprint(parse_design(ALONG_Y)) != recorded


def test_simulate_refuses_another_field_on_the_same_shape(sliced):
    out, settings = sliced
    assert simulate(out, parse_design(ALONG_X), None, settings).volume.sum() > 0
    with pytest.raises(DesignError) as info:
        simulate(out, parse_design(ALONG_Y), None, settings)
    assert "sliced from another design" in str(info.value) and "--design" in info.value.hint


def test_the_simulate_command_names_the_mismatch(sliced, tmp_path):
    out, _ = sliced
    other = tmp_path / "other.vcad"
    other.write_text(ALONG_Y)
    result = CliRunner().invoke(main, ["simulate", str(out), "--design", str(other)])
    assert result.exit_code == 2 and "sliced from another design" in result.output
    same = tmp_path / "same.vcad"
    same.write_text(ALONG_X)
    assert CliRunner().invoke(main, ["simulate", str(out), "--design", str(same)]).exit_code == 0
