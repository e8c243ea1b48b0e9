"""Temperature states: the product palette, its levels, the header round trip, the
state dialect's commands and the split leads."""

from __future__ import annotations

import numpy as np
import pytest

from fgslice.errors import SettingsError
from fgslice.machine.dialects import Toolchanger
from fgslice.machine.flow import flow_percent
from fgslice.machine.state_dialect import dialect_for
from fgslice.planning.plan import LayerPlan, SetState
from fgslice.planning.state_leads import apply_state_leads
from fgslice.settings import load_settings
from fgslice.slicing.palette import Palette
from fgslice.slicing.states import StatePalette, header_palette, make_palette, temperature_levels
from fgslice.toolpaths.paths import Path, Role


def _palette(colors=4, levels=(210.0, 215.0, 220.0)):
    return StatePalette(Palette(2, colors), np.array(levels))


def test_levels_are_the_nearest_multiples_within_the_machine():
    np.testing.assert_array_equal(temperature_levels(211, 219, 5), [210, 215, 220])
    np.testing.assert_array_equal(temperature_levels(212.6, 212.6, 5), [215])
    np.testing.assert_array_equal(temperature_levels(168, 302, 10, (170, 300)), np.arange(170, 301, 10))
    with pytest.raises(SettingsError, match="more than 64"):
        temperature_levels(170, 300, 1)


def test_colors_walk_each_material_colors_levels_in_turn():
    p = _palette()
    assert p.size == 12
    np.testing.assert_array_equal(p.material_of, np.repeat(np.arange(4), 3))
    np.testing.assert_array_equal(p.temperatures, [210, 215, 220, 220, 215, 210] * 2)
    steps = np.abs(np.diff(p.material_of)) + np.abs(np.diff(p.level_of))
    assert (steps == 1).all()
    np.testing.assert_array_equal(p.centers[:3], np.repeat(Palette(2, 4).centers[:1], 3, axis=0))
    assert p.label(4) == "A 37.5% / B 62.5% @ 215 C"


def test_color_of_takes_the_bin_and_the_nearest_level():
    p = _palette()
    f = np.array([[0.1, 0.9, 207.0], [0.1, 0.9, 212.6], [0.3, 0.7, 217.4], [0.9, 0.1, 240.0], [0.6, 0.4, 190.0]])
    colors = p.color_of(f)
    np.testing.assert_array_equal(p.material_of[colors], [0, 0, 1, 3, 2])
    np.testing.assert_array_equal(p.temperatures[colors], [210, 215, 215, 220, 210])


def test_band_layout_cuts_the_temperature_into_one_band_per_level():
    p = _palette()
    np.testing.assert_array_equal(p.band_counts, [4, 3])
    values = p.band_values(np.array([[0.3, 0.7, 212.4], [0.3, 0.7, 212.6]]))
    bands = np.floor(values * p.band_counts).astype(int)
    for color, band in zip(p.color_of(np.array([[0.3, 0.7, 212.4], [0.3, 0.7, 212.6]])), bands):
        np.testing.assert_array_equal(p.band_range[color, :, 0], band)


def test_zippers_cross_material_boundaries_only():
    p = _palette()
    near_bin = np.array([[0.249, 0.751, 215.0]])
    assert p.material_of[p.zipper_neighbor(near_bin, 2.0)[0]] == 1
    assert p.temperatures[p.zipper_neighbor(near_bin, 2.0)[0]] == 215
    near_level = np.array([[0.1, 0.9, 212.49]])
    assert p.zipper_neighbor(near_level, 2.0)[0] == -1


def test_header_palette_round_trip_and_errors():
    assert isinstance(header_palette(2, 4, None, None), Palette)
    p = header_palette(2, 4, "centers", "210,215,220")
    np.testing.assert_array_equal(p.temperatures, _palette().temperatures)
    assert header_palette(1, 4, None, "200,205").size == 2
    with pytest.raises(SettingsError, match="temperature_levels"):
        header_palette(2, 4, None, "210,hot")
    with pytest.raises(SettingsError, match="evenly spaced"):
        header_palette(2, 4, None, "210,215,225")
    assert isinstance(make_palette(2, 4, "centers", None), Palette)


def test_mixing_changes_write_only_what_changes():
    settings = load_settings(None, {})
    d = dialect_for(settings, _palette())
    assert d.change_commands(None, 4) == [";STATE:4 A 37.5% / B 62.5% @ 215 C", "M104 S215", "M165 A0.3750 B0.6250"]
    assert d.change_commands(4, 5) == [";STATE:5 A 37.5% / B 62.5% @ 210 C", "M104 S210"]
    assert d.change_commands(5, 6) == [";STATE:6 A 62.5% / B 37.5% @ 210 C", "M165 A0.6250 B0.3750"]
    assert d.describe(2) == "M104 S220 | M165 A0.1250 B0.8750"
    foaming = dialect_for(load_settings(None, {"flow_model": "pla"}), _palette())
    assert foaming.change_commands(4, 5)[1:] == ["M104 S210", f"M221 S{round(float(flow_percent('pla', 210.0)))}"]
    tools = dialect_for(load_settings("toolchanger", {"flow_model": "tpu"}), _palette())
    assert tools.change_commands(3, 4)[1:] == ["M104 T1 S215", f"M221 S{round(float(flow_percent('tpu', 215.0)))}"]
    assert tools.change_commands(2, 3)[1:] == ["M104 T1 S220", "T1", f"M221 S{round(float(flow_percent('tpu', 220.0)))}"]


def test_toolchanger_sets_the_tool_before_picking_it():
    settings = load_settings("toolchanger", {})
    d = dialect_for(settings, _palette())
    assert d.change_commands(2, 3)[1:] == ["M104 T1 S220", "T1"]
    assert d.change_commands(3, 4)[1:] == ["M104 T1 S215"]
    assert d.change_time(3, 4) == 0 and d.change_time(2, 3) == Toolchanger.change_time_s > 0
    with pytest.raises(SettingsError, match="6 colors need 6 tools"):
        dialect_for(settings, _palette(colors=6))


def _line(x0, x1, color):
    return Path(points=np.array([[x0, 0.0], [x1, 0.0]]), role=Role.PERIMETER, color=color, width=0.4, height=0.2)


def test_leads_move_each_part_by_its_own_measure():
    p = _palette()
    # 100 mm in color 0 (bin 0, 210 C), then color 4 (bin 1, 215 C): both parts change
    plan = LayerPlan(index=0, z=0.2, height=0.2, steps=[SetState(0), _line(0, 100, 0), SetState(4), _line(100, 200, 4)])
    out = list(apply_state_leads([plan], p, 20.0, 3.0, lambda path: 10.0))
    steps = out[0].steps
    ends = [float(s.points[-1, 0]) for s in steps if isinstance(s, Path)]
    # the temperature part 3 s x 10 mm/s = 30 mm early, the mixture 20 mm early
    assert ends == [70.0, 80.0, 100.0, 200.0]
    # whole states: (bin 0, 210 C) twice (the first change's two parts), (bin 0, 215 C), (bin 1, 215 C)
    assert [s.color for s in steps if isinstance(s, SetState)] == [0, 0, int(p.color(0, 1)), 4]
    assert [s.__class__ for s in steps if not isinstance(s, Path)] == [SetState] * 4
    assert list(apply_state_leads([plan], p, 0.0, 0.0, lambda path: 10.0))[0].steps == plan.steps
