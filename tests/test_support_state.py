"""The support's own state, measured in the G-code: a toolchanger's support tool, a mixing
hotend's support mix, the cheapest palette color."""

import numpy as np
import pytest

from fgslice.analysis.overhang import SUPPORT_ROLES
from fgslice.design.language import parse_design
from fgslice.errors import FgsliceError
from fgslice.machine.gcode_header import read_footer, read_header
from fgslice.machine.gcode_reader import read_gcode
from fgslice.machine.verify import verify_gcode
from fgslice.pipeline import slice_to_gcode
from fgslice.preview.colors import load_printout, state_colors
from fgslice.settings import load_settings

# a T graded along X: two colors, support under both arms
T = ('fgrade(["x/30+0.5", "0.5-x/30"], ["blue", "yellow"]) { union() { translate(0,0,4) { rectprism(4, 6, 8); } '
     'translate(0,0,9) { rectprism(20, 6, 2); } } }')


def _slice(tmp_path, name, profile=None, **overrides):
    values = {"strategy": "1", "colors": "2", **{k: str(v) for k, v in overrides.items()}}
    settings = load_settings(profile, values)
    out = tmp_path / f"{name}.gcode"
    stats = slice_to_gcode(parse_design(T), settings, out, jobs=1).stats
    program = read_gcode(out)
    assert not verify_gcode(program, settings)
    program.labels = read_header(out).labels
    return program, stats


def _moves(program):
    """Masks of the support moves and the part moves that extrude, and each move's machine state."""
    roles = np.array(program.roles + [""], dtype=object)[program.role]
    printing = (program.e > 0) & (program.length > 0)
    support = np.isin(roles, SUPPORT_ROLES) & printing
    part = ~np.isin(roles, SUPPORT_ROLES + ("Wipe tower", "Skirt/Brim")) & printing
    states = np.array(program.states, dtype=object)[program.state]
    return support, part, states


def _tool_sequence(program):
    return [t.values["T"] for t in program.tools]


@pytest.mark.parametrize("strategy,lookahead", [(1, "0"), (1, "5"), (2, "0")])
def test_support_tool_prints_every_support_line_and_no_part_line(tmp_path, strategy, lookahead):
    program, stats = _slice(tmp_path, f"tool{strategy}_{lookahead}", "toolchanger", support="true", support_tool=3,
                            support_temperature=220, strategy=strategy, lookahead_mm=lookahead)
    support, part, states = _moves(program)
    tools = np.array([s.tool for s in states])
    assert support.any() and (tools[support] == 3).all()
    assert part.any() and (tools[part] != 3).all()
    assert (np.array([s.color for s in states])[support] == 3).all()
    # the support tool is heated before it extrudes (verify checks it) and named in the header
    assert program.labels[3].startswith("support")
    assert stats["extruded_mm3_by_color"][3] > 0
    # the preview's legend and the footer name the support tool
    out = tmp_path / f"tool{strategy}_{lookahead}.gcode"
    assert state_colors(load_printout(out)).labels[3] == "T3: support tool T3"
    assert read_footer(out)["referenced_tools"] == "0,1,3"
    text = out.read_text()
    names = text.split("\n; filament_settings_id = ")[1].split("\n")[0]
    assert names.endswith(";unused;support")
    # its own temperature, heated before the first layer, in PrusaSlicer's per-extruder list
    assert "\nM109 T3 S220\n" in text.split(";LAYER_CHANGE")[0] and "\n; temperature = 215,215,215,220\n" in text


def test_one_color_part_with_a_support_tool_gets_a_tower(tmp_path):
    program, stats = _slice(tmp_path, "one", "toolchanger", colors=1, support="true", support_tool=1)
    support, part, states = _moves(program)
    tools = np.array([s.tool for s in states])
    assert (tools[support] == 1).all() and (tools[part] == 0).all()
    assert stats["purge_mm3"] > 0 and "\n; wipe_tower = 1\n" in (tmp_path / "one.gcode").read_text()


def test_support_tool_adds_no_change_of_the_part_colors(tmp_path):
    plain, plain_stats = _slice(tmp_path, "plain", "toolchanger")
    program, stats = _slice(tmp_path, "tool", "toolchanger", support="true", support_tool=3)
    sequence = _tool_sequence(program)
    part = [t for t in sequence if t != 3]
    part_changes = sum(a != b for a, b in zip(part, part[1:]))
    plain_sequence = _tool_sequence(plain)
    assert part_changes == sum(a != b for a, b in zip(plain_sequence, plain_sequence[1:]))
    into_support = sum(b == 3 and a != 3 for a, b in zip(sequence, sequence[1:]))
    assert into_support > 0
    # the support tool primes on the tower when it comes in; going back to a part tool purges nothing
    melt = load_settings("toolchanger").melt_volume_mm3
    assert stats["purge_mm3"] == pytest.approx(plain_stats["purge_mm3"] + into_support * melt, rel=1e-3)


def test_support_mix_on_a_mixing_hotend(tmp_path):
    program, stats = _slice(tmp_path, "mix", support="true", support_mix="1,0")
    support, part, states = _moves(program)
    mixes = np.array([s.mix_fractions(2) for s in states[support]])
    assert support.any() and np.allclose(mixes, [1.0, 0.0])
    assert program.labels[2].startswith("support mix")
    part_mixes = np.array([s.mix_fractions(2) for s in states[part]])
    assert np.isin(np.round(part_mixes[:, 0], 4), [0.25, 0.75]).all()  # the part keeps its palette
    # the look-ahead moves the changes into and out of the support mix as any other
    program, _ = _slice(tmp_path, "mix_ahead", support="true", support_mix="1,0", lookahead_mm="auto")
    support, part, states = _moves(program)
    assert (np.array([s.color for s in states[support | part]]) == 2).any()


def test_cheapest_state_follows_the_filament_costs(tmp_path):
    for costs, cheap in (("20,45", 0.75), ("45,20", 0.25)):  # A cheaper: the color with more A
        program, _ = _slice(tmp_path, f"cost{cheap}", support="true", filament_costs=costs)
        support, _, states = _moves(program)
        mixes = np.array([s.mix_fractions(2) for s in states[support]])
        assert support.any() and np.allclose(mixes[:, 0], cheap)
    # without costs: the current state, which adds no change
    _, plain = _slice(tmp_path, "plain")
    _, current = _slice(tmp_path, "current", support="true")
    assert current["state_changes"] == plain["state_changes"]


@pytest.mark.parametrize("profile,overrides,message", [
    ("toolchanger", {"support_tool": 1}, "palette do not use"),
    ("toolchanger", {"support_tool": 5}, "palette do not use"),
    (None, {"support_tool": 3}, "needs a toolchanger"),
    ("toolchanger", {"support_mix": "1,0"}, "needs a mixing hotend"),
    (None, {"support_mix": "1,0,0"}, "2 fractions"),
    (None, {"support_mix": "a,b"}, "comma-separated"),
    (None, {"filament_costs": "20"}, "filament_costs"),
])
def test_support_state_settings_are_checked(tmp_path, profile, overrides, message):
    with pytest.raises(FgsliceError, match=message):
        _slice(tmp_path, "bad", profile, support="true", **overrides)
