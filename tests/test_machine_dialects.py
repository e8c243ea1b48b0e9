"""Dialects: exact state-change commands per machine, and the foaming flow polynomials."""

import numpy as np
import pytest

from fgslice.errors import SettingsError
from fgslice.machine.dialects import make_dialect, state_temperature
from fgslice.machine.flow import f_pla, f_tpu, flow_percent
from fgslice.settings import load_settings
from fgslice.slicing.palette import Palette


def commands(profile, palette, color, **overrides):
    dialect = make_dialect(load_settings(profile, {k: str(v) for k, v in overrides.items()}), palette)
    lines = dialect.state_commands(color)
    assert lines[0] == f";STATE:{color} {palette.label(color)}"
    return lines[1:]


def test_marlin_mixing_m165_four_decimals_in_material_order():
    assert commands("marlin-mixing", Palette(2, 4), 0) == ["M165 A0.1250 B0.8750"]
    assert commands("marlin-mixing", Palette(2, 4), 3) == ["M165 A0.8750 B0.1250"]


def test_marlin_mixing_pads_unused_channels_and_rejects_too_many_materials():
    assert commands("marlin-mixing", Palette(2, 4), 1, channels=3) == ["M165 A0.3750 B0.6250 C0.0000"]
    with pytest.raises(SettingsError, match="3 materials but the mixing hotend has 2 channels"):
        make_dialect(load_settings("marlin-mixing"), Palette(3, 4))


def test_marlin_mixing_m163_every_channel_then_commit():
    palette = Palette(3, 4)
    lines = commands("marlin-mixing-m163", palette, 1, channels=4)
    f = palette.centers[1]
    assert lines == [f"M163 S0 P{f[0]:.4f}", f"M163 S1 P{f[1]:.4f}", f"M163 S2 P{f[2]:.4f}", "M163 S3 P0.0000", "M164 S0"]
    assert sum(float(line.split("P")[1]) for line in lines[:-1]) == pytest.approx(1.0, abs=2e-4)


def test_toolchanger_tool_per_color_and_too_many_colors():
    assert commands("toolchanger", Palette(2, 5), 3) == ["T3"]
    with pytest.raises(SettingsError) as info:
        make_dialect(load_settings("toolchanger"), Palette(2, 7))
    assert "7 colors need 7 tools; this profile has 5" in info.value.message
    assert info.value.hint == "--set tool_count=7 or --colors 5"


@pytest.mark.parametrize("profile,poly", [("foam-lwpla", f_pla), ("foam-tpu", f_tpu)])
def test_temperature_linear_in_first_material_with_flow(profile, poly):
    palette = Palette(2, 4)
    settings = load_settings(profile)
    for color in range(4):
        f_a = palette.centers[color][0]
        t = round(190 + 35 * (1 - f_a))
        assert commands(profile, palette, color) == [f"M104 S{t}", f"M221 S{round(poly(t))}"]
    assert state_temperature(settings, np.array([1.0, 0.0])) == 190.0
    assert state_temperature(settings, np.array([0.0, 1.0])) == 225.0


def test_temperature_without_flow_model_keeps_100_percent():
    lines = commands("foam-lwpla", Palette(2, 2), 0, flow_model="none")
    assert lines == [f"M104 S{round(190 + 35 * 0.75)}", "M221 S100"]


def test_flow_polynomials_match_the_paper_and_are_plausible():
    t = np.arange(190.0, 225.1, 1.0)
    assert f_pla(200.0) == pytest.approx(100 * (8.35479e-6 * 200**3 - 5.37075e-3 * 200**2 + 1.13374 * 200 - 77.814))
    assert f_tpu(200.0) == pytest.approx(100 * (3.09637e-4 * 200**2 - 1.38401e-1 * 200 + 15.9560))
    for poly in (f_pla, f_tpu):
        values = poly(t)
        assert np.all((values > 40) & (values < 110))
        # hotter foams more, so less flow; F_TPU's parabola bottoms out at 223.5 C
        assert np.all(np.diff(values) < 0.1)
        assert values[0] - values[-1] > 30
    assert f_pla(190.0) == pytest.approx(101.85, abs=0.1) and f_pla(225.0) == pytest.approx(55.0, abs=0.2)
    assert f_tpu(190.0) == pytest.approx(83.8, abs=0.1) and f_tpu(225.0) == pytest.approx(49.1, abs=0.1)
    assert flow_percent("none", 210.0) == 100.0


def test_template_fills_every_placeholder():
    template = "M400\nM42 P4 S{pwm0}\n; c={color} f={f0},{f1},{f2} pct={pct0},{pct1} pwm1={pwm1} t={temperature}"
    palette = Palette(2, 4)
    lines = commands("template-diw", palette, 1, state_template=template)
    t = 190 + 35 * (1 - 0.375)
    assert lines == [
        "M400",
        "M42 P4 S96",
        f"; c=1 f=0.3750,0.6250,0.0000 pct=37.50,62.50 pwm1=159 t={t:.1f}",
    ]


@pytest.mark.parametrize("bad", ["{f6}", "{speed}", "{}", "{pwm0:x}"])
def test_template_unknown_placeholder_is_named(bad):
    with pytest.raises(SettingsError, match="unknown placeholder") as info:
        make_dialect(load_settings("template-diw", {"state_template": f"M42 P4 S{bad}"}), Palette(2, 4))
    assert bad in info.value.message


def test_template_attribute_access_is_rejected_not_evaluated():
    with pytest.raises(SettingsError, match=r"\{0\.__class__\}"):
        make_dialect(load_settings("template-diw", {"state_template": "M117 {0.__class__}"}), Palette(2, 4))


def test_template_requires_a_template():
    with pytest.raises(SettingsError, match="needs a state_template"):
        make_dialect(load_settings("template-diw", {"state_template": " "}), Palette(2, 4))


def test_describe_is_the_commands_on_one_line():
    dialect = make_dialect(load_settings("foam-lwpla"), Palette(2, 2))
    assert dialect.describe(1) == f"M104 S{round(190 + 35 * 0.25)} | M221 S{round(f_pla(round(190 + 35 * 0.25)))}"
