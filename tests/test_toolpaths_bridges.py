"""Bridges: lines across the shortest span over air, at the bridge speed, measured in the G-code."""

import numpy as np
import pytest
import shapely

from fgslice.design.language import parse_design
from fgslice.machine.gcode_reader import read_gcode
from fgslice.pipeline import slice_to_gcode
from fgslice.settings import Settings, load_settings
from fgslice.toolpaths.bridges import bridge_paths, span_angle, split_bridges
from fgslice.toolpaths.skins import InnerAreas

# a 24 x 12 x 4 mm block with a 6 mm wide channel through it along its length (z 0..2),
# turned 30 degrees: its roof spans 6 mm across the channel, 24 mm along it
DESIGN = """
fgrade(["x/40+0.5", "0.5-x/40"], ["blue", "yellow"]) {
    rotate(0, 0, 30) { translate(0, 0, 2) { difference() {
        rectprism(24, 12, 4);
        translate(0, 0, -1) { rectprism(30, 6, 2); }
    } } }
}
"""


def test_span_angle_is_across_the_short_side():
    strip = shapely.affinity.rotate(shapely.box(0, 0, 20, 5), 30, origin=(0, 0))
    assert span_angle(strip) == pytest.approx(120.0, abs=1e-6)


def test_split_bridges_takes_the_skin_over_air_and_anchors_it():
    outline = shapely.box(0, 0, 20, 10)
    below = shapely.union(shapely.box(0, 0, 20, 2), shapely.box(0, 8, 20, 10))  # two walls, air between
    areas = InnerAreas(shapely.Polygon(), shapely.box(1, 1, 19, 9), shapely.Polygon())
    settings = Settings(strategy=1)
    rest, bridges = split_bridges(areas, below, settings)
    assert bridges.covers(shapely.box(1, 2, 19, 8))
    assert bridges.area == pytest.approx(18 * (6 + 2 * 2 * 0.4), rel=1e-6)
    assert rest.solid.area == pytest.approx(areas.solid.area - bridges.area)
    lines = bridge_paths(bridges, settings)
    moves = np.concatenate([np.diff(p.points, axis=0) for p in lines])
    along_y = np.abs(moves[:, 0]) < 1e-9
    assert np.abs(moves[along_y, 1]).sum() > 0.8 * np.hypot(*moves.T).sum()
    assert split_bridges(areas, None, settings)[1].is_empty
    assert split_bridges(areas, outline, settings)[1].is_empty


def _bridge_lines(tmp_path, strategy: str):
    """The sliced channel block's program and its extruding bridge moves, after asserting
    what both strategies share: bridges on the layer over the channel only, at
    ``bridge_speed``, the long ones across the channel (turned 30 degrees) and anchored two
    beads each side."""
    settings = load_settings(None, {"strategy": strategy, "colors": "2", "bridge_speed": "17"})
    out = tmp_path / f"channel{strategy}.gcode"
    slice_to_gcode(parse_design(DESIGN), settings, out, jobs=1)
    program = read_gcode(out)
    roles = np.array(program.roles + [""], dtype=object)[program.role]
    bridge = (roles == "Bridge infill") & (program.e > 0) & (program.length > 0)
    assert set(np.round(program.end[bridge, 2], 3)) == {2.2}  # the layer over the channel only
    assert (program.feed[bridge] == 17 * 60).all()
    d = (program.end[bridge] - program.start[bridge])[:, :2]
    angle = np.degrees(np.arctan2(d[:, 1], d[:, 0])) % 180.0
    long = program.length[bridge] > 3.0
    assert long.sum() > 10
    assert np.allclose(angle[long], 120.0, atol=0.5)  # across the channel, turned 30 degrees
    assert 6.0 < program.length[bridge][long].max() < 6.0 + 2 * 2 * 0.4 + 0.05  # anchored two beads each side
    return program, bridge


def test_bridge_lines_cross_the_channel_at_bridge_speed(tmp_path):
    _bridge_lines(tmp_path, "1")


def test_strategy_2_bridges_cross_the_channel_in_the_faces_colors(tmp_path):
    program, bridge = _bridge_lines(tmp_path, "2")
    assert len(set(program.color_of_moves()[bridge])) == 2  # the graded roof keeps both colors
