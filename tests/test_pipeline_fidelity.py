"""Simulated fidelity of real slices: the shape of the paper's Delta-E against palette size."""

from __future__ import annotations

import pytest

from fgslice.analysis.fidelity import fidelity
from fgslice.analysis.simulate import simulate
from fgslice.design import parse_design
from fgslice.pipeline import slice_to_gcode
from fgslice.settings import load_settings

# A small palette object: an ellipse with the vase's sin*cos field, its frequencies scaled
# up 3x so the 45 x 58 mm part spans the same range of the gradient as the paper's.
SMALL_PALETTE = """
fgrade(["(1+sin(0.075*x+0.1125*y)*cos(0.1125*x-0.075*y))/2",
        "1-(1+sin(0.075*x+0.1125*y)*cos(0.1125*x-0.075*y))/2"], ["yellow", "blue"]) {
    translate(0, 0, 0.2) { scale(22.5, 29.2, 1) { cylinder(1, 0.4); } }
}
"""


@pytest.mark.slow
def test_strategy2_fidelity_improves_steeply_then_levels_off(tmp_path):
    design = parse_design(SMALL_PALETTE)
    delta_e = {}
    for n in (2, 4, 8, 16, 32):
        settings = load_settings(None, {"colors": str(n), "melt_volume_mm3": "2", "lookahead_mm": "auto"})
        out = tmp_path / f"p{n}.gcode"
        slice_to_gcode(design, settings, out, jobs=1)
        delta_e[n] = fidelity(simulate(out, design, None, settings)).mean_delta_e
    assert delta_e[2] > delta_e[4] > delta_e[8] > delta_e[16]
    steep = delta_e[2] - delta_e[16]
    flat = abs(delta_e[16] - delta_e[32])
    assert steep > 4 * flat, delta_e
