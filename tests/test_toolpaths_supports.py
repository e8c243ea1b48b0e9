"""Supports: regions from consecutive outlines, and in the G-code, the share of the
extruded volume laid over nothing with supports off and on."""

from pathlib import Path

import numpy as np
import pytest
import shapely

from fgslice.analysis.overhang import SUPPORT_ROLES, unsupported_share
from fgslice.design.language import load_design, parse_design
from fgslice.errors import FgsliceError
from fgslice.machine.gcode_reader import read_gcode
from fgslice.pipeline import slice_to_gcode
from fgslice.settings import Settings, load_settings
from fgslice.toolpaths.paths import Role
from fgslice.toolpaths.supports import plan_supports, support_paths

GRADE = '["x/30+0.5", "0.5-x/30"], ["blue", "yellow"]'
PARTS = {
    "arch": "translate(0,0,5) { difference() { rectprism(20, 6, 10); "
            "translate(0,0,-5) { rotate(90,0,0) { cylinder(7, 8); } } } }",
    "T": "union() { translate(0,0,4) { rectprism(4, 6, 8); } translate(0,0,9) { rectprism(20, 6, 2); } }",
    "fan": "intersection() { union() { translate(-12,0,0) { rotate(0,45,0) { rectprism(3, 6, 30); } } "
           "rotate(0,60,0) { rectprism(3, 6, 30); } translate(12,0,0) { rotate(0,75,0) { rectprism(3, 6, 30); } } } "
           "translate(0,0,4) { rectprism(60, 30, 8); } }",
    "wing in a box": "union() { translate(0,0,6) { difference() { rectprism(24, 16, 12); rectprism(20, 12, 8); } } "
                     "translate(0,0,6) { scale(1, 1, 0.25) { rotate(90,0,0) { cylinder(6, 14); } } } }",
}


def _t_outlines(stem_layers=10, bar_layers=4):
    stem, bar = shapely.box(-2, -3, 2, 3), shapely.box(-10, -3, 10, 3)
    return [stem] * stem_layers + [bar] * bar_layers


def test_t_gets_support_under_its_arms_with_gaps_and_interface():
    settings = Settings(support=True, support_expansion=0)
    layers = plan_supports(_t_outlines(), settings)
    w = settings.bead_width
    regions = [shapely.union(layer.body, layer.interface) for layer in layers]
    # the bar starts on layer 10; one layer of top gap: support up to layer 8
    assert all(not r.is_empty for r in regions[:9])
    assert all(r.is_empty for r in regions[9:])
    stem = shapely.box(-2, -3, 2, 3)
    for r in regions[:9]:
        assert shapely.distance(r, stem) >= settings.support_xy_gap + w / 2 - 1e-6
        assert r.area > 0.8 * 2 * 8 * 6 * (1 - 0.2)  # most of the two arms' shadow
    assert [not layer.interface.is_empty for layer in layers[:9]] == [False] * 6 + [True] * 3
    wider = plan_supports(_t_outlines(), Settings(support=True, support_expansion=2.0))
    assert wider[3].body.area > layers[3].body.area + 2 * 2 * 6  # grown 2 mm around the arms' shadow
    lines = support_paths(layers[3], settings)
    assert lines and all(p.role is Role.SUPPORT and p.color == -1 for p in lines)
    directions = np.concatenate([np.diff(p.points, axis=0) for p in lines if not p.closed])  # lines, not the sheath
    along_x = np.abs(directions[:, 1]) < 1e-9
    assert np.abs(directions[along_x, 0]).sum() > 0.75 * np.hypot(*directions.T).sum()


def test_support_to_bed_drops_columns_that_stand_on_the_part():
    # a shelf (layers 6-7) over a low block (layers 0-2) that is wider than the shelf's stem
    stem, block, shelf = shapely.box(-2, -3, 2, 3), shapely.box(-8, -3, 2, 3), shapely.box(-8, -3, 8, 3)
    outlines = [block] * 3 + [stem] * 3 + [shelf] * 2
    bed = plan_supports(outlines, Settings(support=True, support_to="bed", support_expansion=0))
    part = plan_supports(outlines, Settings(support=True, support_to="part", support_expansion=0))
    right, left = shapely.box(3, -3, 9, 3), shapely.box(-9, -3, -3, 3)
    support = [shapely.union(layer.body, layer.interface) for layer in bed]
    assert all(s.intersection(right).area > 1 for s in support[:5])
    assert all(s.intersection(left).area == 0 for s in support)
    on_part = [shapely.union(layer.body, layer.interface) for layer in part]
    # on the block (top at layer 2): one layer of bottom gap, support from layer 4 to 4
    assert on_part[3].intersection(left).area == 0 and on_part[4].intersection(left).area > 1


def test_support_only_under_walls_leaning_further_than_the_angle():
    outlines = [shapely.box(0, 0, 10, 10).buffer(0.6 * k, join_style="mitre") for k in range(10)]  # 71.6 degrees
    assert all(layer.empty for layer in plan_supports(outlines, Settings(support=True, support_angle=75)))
    leaning = plan_supports(outlines, Settings(support=True, support_angle=45))
    assert not leaning[0].empty and leaning[-1].empty


def _share(tmp_path, text, name, strategy=1, **overrides):
    design = load_design(text) if isinstance(text, Path) else parse_design(f"fgrade({GRADE}) {{ {text} }}")
    # no purge tower: its volume would dilute the share
    values = {"strategy": str(strategy), "colors": "2", "purge": "false", **{k: str(v) for k, v in overrides.items()}}
    settings = load_settings(None, values)
    out = tmp_path / f"{name.replace(' ', '_')}_{overrides.get('support', False)}.gcode"
    stats = slice_to_gcode(design, settings, out, jobs=1).stats
    program = read_gcode(out)
    return unsupported_share(program, settings.bead_width), stats, program


@pytest.mark.parametrize("name", list(PARTS))
def test_supports_leave_under_half_a_percent_over_nothing(tmp_path, name):
    to = "part" if name == "wing in a box" else "bed"
    off, _, _ = _share(tmp_path, PARTS[name], name)
    # bridges are left over air on purpose (dont_support_bridges): measured with support under them too
    on, stats, program = _share(tmp_path, PARTS[name], name, support="true", support_to=to, dont_support_bridges="false")
    assert on < 0.005
    assert off > 2 * on
    roles = np.array(program.roles + [""], dtype=object)[program.role]
    support = np.isin(roles, SUPPORT_ROLES) & (program.e > 0) & (program.length > 0)
    volume = program.e[support].sum() * np.pi * 1.75**2 / 4
    assert volume == pytest.approx(stats["support_mm3"], rel=1e-3)


def test_strategy_2_supports_a_t(tmp_path):
    off, _, _ = _share(tmp_path, PARTS["T"], "T2", strategy=2)
    on, _, _ = _share(tmp_path, PARTS["T"], "T2", strategy=2, support="true")
    assert on < 0.005 < off


def test_benchy_supports(tmp_path, benchy_path):
    # at half size: the same overhangs (angles keep under a uniform scaling; its cabin roof
    # stands on the deck), a quarter of the area and half the layers
    design = tmp_path / "benchy.vcad"
    design.write_text(f'scale(0.5, 0.5, 0.5) {{ mesh("{benchy_path}"); }}')
    off, _, _ = _share(tmp_path, design, "benchy", colors=1)
    on, stats, _ = _share(tmp_path, design, "benchy", colors=1, support="true", support_to="part",
                          dont_support_bridges="false")
    assert on < 0.005 and off > 2 * on
    assert stats["support_mm3"] > 0


def test_support_prints_in_the_current_state_or_its_own(tmp_path):
    t = PARTS["T"]
    _, plain, _ = _share(tmp_path, t, "Tstate")
    _, current, program = _share(tmp_path, t, "Tstate", support="true")
    assert current["state_changes"] == plain["state_changes"]
    _, own, program = _share(tmp_path, t, "Tstate", support="true", support_state=1, purge="false")
    roles = np.array(program.roles + [""], dtype=object)[program.role]
    support = np.isin(roles, SUPPORT_ROLES) & (program.e > 0) & (program.length > 0)
    assert support.any() and (program.color_of_moves()[support] == 1).all()
    with pytest.raises(FgsliceError, match="support_state"):
        _share(tmp_path, t, "Tstate", support="true", support_state=5)


def _support_moves(program):
    roles = np.array(program.roles + [""], dtype=object)[program.role]
    printing = (program.e > 0) & (program.length > 0)
    support = np.isin(roles, SUPPORT_ROLES) & printing
    return program.end[support], program.end[~support & printing & (program.layer >= 1)]  # part: above the skirt


def test_support_bodies_of_the_design_enforce_and_block_support(tmp_path):
    settings = load_settings(None, {"colors": "1", "support": "true"})
    cx, cy = settings.bed_x / 2, settings.bed_y / 2
    column = 'translate(0,0,4) { rectprism(4, 6, 8, "blue"); }'
    # a vertical column overhangs nowhere; a support body beside it asks for support there
    plain = tmp_path / "column.gcode"
    slice_to_gcode(parse_design(f"union() {{ {column} }}"), settings, plain, jobs=1)
    assert not len(_support_moves(read_gcode(plain))[0])
    enforced = tmp_path / "enforced.gcode"
    design = parse_design(f'union() {{ {column} translate(6,0,4) {{ rectprism(4, 6, 8, "support"); }} }}')
    result = slice_to_gcode(design, settings, enforced, jobs=1)
    assert result.stats["support_mm3"] > 0
    support, part = _support_moves(read_gcode(enforced))
    x = support[:, 0] - cx
    assert len(x) and (x > 2 + settings.support_xy_gap).all() and (x < 8 + settings.bead_width).all()
    assert np.abs(support[:, 1] - cy).max() < 3 + settings.bead_width
    assert (np.abs(part[:, 0] - cx) < 2 + settings.bead_width).all()  # the body itself is not printed as part
    # a blocker over the T's right arm: support under the left arm only
    blocked = tmp_path / "blocked.gcode"
    t = 'union() { translate(0,0,4) { rectprism(4, 6, 8, "blue"); } translate(0,0,9) { rectprism(20, 6, 2, "blue"); } }'
    design = parse_design(f'union() {{ {t} translate(7,0,5) {{ rectprism(10, 10, 12, "support_blocker"); }} }}')
    slice_to_gcode(design, settings, blocked, jobs=1)
    support, _ = _support_moves(read_gcode(blocked))
    assert len(support) and (support[:, 0] - cx < 2).all()  # the right arm spans x 2..10
    with pytest.raises(FgsliceError, match="only support bodies"):
        slice_to_gcode(parse_design('rectprism(4, 4, 4, "support");'), settings, tmp_path / "none.gcode", jobs=1)


def test_bridges_get_no_support_unless_asked(tmp_path):
    # a block with a 6 mm channel through it: its roof is a bridge anchored on both walls
    channel = ('translate(0, 0, 2) { difference() { rectprism(24, 12, 4, "blue"); '
               'translate(0, 0, -1) { rectprism(30, 6, 2, "blue"); } } }')
    volumes = {}
    for flag in ("true", "false"):
        settings = load_settings(None, {"colors": "1", "support": "true", "dont_support_bridges": flag})
        out = tmp_path / f"channel_{flag}.gcode"
        volumes[flag] = slice_to_gcode(parse_design(channel), settings, out, jobs=1).stats["support_mm3"]
        support, _ = _support_moves(read_gcode(out))
        # under the roof's middle, away from the channel's open ends where its walls overhang
        middle = (np.abs(support[:, 0] - settings.bed_x / 2) < 8) & (np.abs(support[:, 1] - settings.bed_y / 2) < 3)
        assert middle.any() == (flag == "false")
    assert volumes["true"] < 0.8 * volumes["false"]
    # a cantilever is no bridge: the T's arms keep their support
    t = plan_supports(_t_outlines(), Settings(support=True, dont_support_bridges=True))
    assert not t[5].empty


def test_interface_is_what_a_layer_above_lacks():
    # columns that change from layer to layer: a cone-like shelf standing partly on a block (support on the part)
    block = shapely.box(-8, -3, 0, 3)
    outlines = [block] * 4 + [shapely.box(-1, -3, 1, 3)] * 4 + [shapely.box(-2 - k, -3 - k / 2, 2 + k, 3) for k in range(6)]
    settings = Settings(support=True, support_to="part", support_interface_layers=2, support_expansion=1.0)
    layers = plan_supports(outlines, settings)
    regions = [shapely.union(layer.body, layer.interface) for layer in layers]
    assert sum(not layer.interface.is_empty for layer in layers) >= 3
    for j, layer in enumerate(layers):
        above = regions[j + 1 : j + 3]
        covered = shapely.intersection_all(above) if len(above) == 2 else shapely.Polygon()
        assert layer.body.symmetric_difference(regions[j].intersection(covered)).area < 1e-6
        assert layer.interface.symmetric_difference(regions[j].difference(covered)).area < 1e-6
