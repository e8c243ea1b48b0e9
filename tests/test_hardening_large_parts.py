"""Large parts: a 200 mm box graded by a curved field prints its band tips along the
surface (they are handed to a neighbouring color instead of being left out because they
are under 1 % of a large layer), and the coverage warning counts absolute area too."""

from __future__ import annotations

from fgslice.coverage import UNCOVERED_MM2_PER_LAYER, check_coverage
from fgslice.design.language import parse_design
from fgslice.machine.gcode_reader import read_gcode
from fgslice.pipeline import slice_to_gcode
from fgslice.settings import load_settings

CURVED_BOX = ('fgrade(["0.5 + 0.5*sin(x/5)*cos(y/7)*cos(z/9)", "0.5 - 0.5*sin(x/5)*cos(y/7)*cos(z/9)"], '
              '["blue", "yellow"]) { rectprism(200, 200, 0.2); }')


def test_a_200_mm_box_leaves_no_band_tips_unprinted(tmp_path):
    settings = load_settings("marlin-mixing", {"strategy": 2, "colors": 16, "skirt_loops": 0, "thumbnails": ""})
    out = tmp_path / "box.gcode"
    stats = slice_to_gcode(parse_design(CURVED_BOX), settings, out, jobs=1).stats
    # before: 28 mm^2 of the layer's 40 000 (0.07 %) stayed unprinted along the surface
    assert stats["layers"] == 1 and stats["uncovered_mm2"] < 1.0
    assert stats["reassigned_mm2"] > 10.0
    program = read_gcode(out)
    extruded = float(program.e[(program.e > 0) & (program.length > 0)].sum()) * 3.14159265 * 1.75**2 / 4
    assert abs(extruded - 200 * 200 * 0.2) < 0.03 * 200 * 200 * 0.2
    assert not [w for w in stats["warnings"] if "are not printed" in w]


def test_uncovered_area_is_warned_about_per_layer_on_a_large_part():
    layers, area = 750, 40_000.0
    # 3 mm^2 a layer: 0.0075 % of each layer, far under 1 %, but a visible gap on every layer
    uncovered = 3.0 * layers
    warnings = check_coverage(area * layers * 0.2, area * layers, area * layers * 0.2, uncovered, 2, 0.4, layers)
    assert any("narrower than a bead" in w for w in warnings)
    below = check_coverage(area * layers * 0.2, area * layers, area * layers * 0.2,
                           0.5 * UNCOVERED_MM2_PER_LAYER * layers, 2, 0.4, layers)
    assert below == []
    # without the layer count, the share alone decides (as before)
    assert check_coverage(area * layers * 0.2, area * layers, area * layers * 0.2, uncovered, 2, 0.4) == []
