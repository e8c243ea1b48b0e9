"""The ``scale`` setting: a part larger than the bed is refused with the factor that fits,
and sliced at that factor when the user sets it."""

from __future__ import annotations

import json
import math
import re

import pytest
from click.testing import CliRunner

from fgslice.cli import main
from fgslice.settings import load_settings

SHEET = (300.0, 20.0, 2.0)


def test_a_part_larger_than_the_bed_is_refused_with_the_scale_that_fits_and_slices_at_it(tmp_path):
    design = tmp_path / "sheet.vcad"
    design.write_text(f'rectprism({SHEET[0]:g}, {SHEET[1]:g}, {SHEET[2]:g}, "red");', encoding="utf-8")
    out, stats = tmp_path / "sheet.gcode", tmp_path / "stats.json"
    refused = CliRunner().invoke(main, ["slice", str(design), "-o", str(out)])
    assert refused.exit_code != 0 and not out.exists()
    factor = float(re.search(r"--set scale=([0-9.]+)", refused.output).group(1))
    s = load_settings(None)
    margin = s.skirt_distance + s.skirt_loops * s.bead_width + s.brim_width
    assert factor == math.floor(100 * (s.bed_x - 2 * margin) / SHEET[0]) / 100
    checked = CliRunner().invoke(main, ["check", str(design)])
    assert f"--set scale={factor:g}" in checked.output and "usable: no" in checked.output

    sliced = CliRunner().invoke(main, ["slice", str(design), "-o", str(out), "--set", f"scale={factor:g}",
                                       "--set", "layer_height=0.3", "--set", "skirt_loops=0", "--stats", str(stats)])
    assert sliced.exit_code == 0, sliced.output
    result = json.loads(stats.read_text())
    (x0, y0, _), (x1, y1, _) = result["extrusion_bbox"]
    w = s.bead_width
    assert x1 - x0 == pytest.approx(SHEET[0] * factor - w, abs=0.05)  # bead centres half a bead inside
    assert y1 - y0 == pytest.approx(SHEET[1] * factor - w, abs=0.05)
    printed_height = round(SHEET[2] * factor / 0.3) * 0.3
    assert result["extruded_mm3"] == pytest.approx(SHEET[0] * SHEET[1] * factor**2 * printed_height, rel=0.03)
    checked = CliRunner().invoke(main, ["check", str(design), "--set", f"scale={factor:g}"])
    assert "usable: yes" in checked.output and f"{SHEET[0] * factor:.2f} x {SHEET[1] * factor:.2f}" in checked.output
