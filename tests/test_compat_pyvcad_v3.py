"""OpenVCAD 3 (attribute modeling) scripts: the complete scripts of OpenVCAD 3's guides,
its hierarchy rules, conflict resolvers, converters and Numba functions, and the G-code
that its attributes drive."""

from __future__ import annotations

import re
import textwrap
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
import pytest

from fgslice.compat.script import load_script
from fgslice.design.attributes import attribute_fields
from fgslice.design.check import check_design, format_report
from fgslice.errors import FgsliceError
from fgslice.machine.gcode_reader import read_gcode
from fgslice.pipeline import slice_to_gcode
from fgslice.settings import load_settings

GUIDES = Path(__file__).parent / "fixtures" / "openvcad3_guides.md"
HEADER = "import pyvcad as pv\nimport pyvcad_rendering as viz\n"

NOT_DESIGNS = {
    "getting-started 1": "prints pv.version() only",
    "getting-started 3": "a fragment reading the 'cube' of the lesson before",
    "getting-started 20": "draws the tree with Render_Tree_Diagram (mermaid), no design",
    "gradients 1": "an f-string example, no design",
    "gradients 3": "a fragment without a root",
    "numba-attributes 1": "a template ('return ...')",
    "numba-attributes 3": "a template ('return ...')",
}


def _guide_scripts() -> list[tuple[str, str]]:
    """(``"<guide> <n>"``, script) for each Python block of the guides' text; fragments
    (no import of their own) get the guides' two import lines in front."""
    blocks = re.findall(r"^## ([\w-]+ \d+): .*?\n```python\n(.*?)\n```", GUIDES.read_text(), re.S | re.M)
    return [(name, code if code.startswith("import") else HEADER + code) for name, code in blocks]


SCRIPTS = _guide_scripts()


def _design(tmp_path, code: str):
    path = tmp_path / "design.py"
    path.write_text(textwrap.dedent(code))
    return load_script(path)


def _slice(design, tmp_path, **overrides):
    settings = load_settings(overrides.pop("profile", None), {k: str(v) for k, v in overrides.items()})
    out = tmp_path / "part.gcode"
    result = slice_to_gcode(design, settings, out, jobs=1, stamp=datetime(2026, 1, 1, tzinfo=timezone.utc))
    return settings, read_gcode(out), result.stats


def test_the_guides_fixture_holds_every_lesson():
    names = [name for name, _ in SCRIPTS]
    assert len(names) == 40 and names[0] == "getting-started 1" and names[-1] == "attribute-conflicts 6"
    assert set(NOT_DESIGNS) <= set(names)


@pytest.mark.parametrize("name,code", [s for s in SCRIPTS if s[0] not in NOT_DESIGNS], ids=[s[0] for s in SCRIPTS if s[0] not in NOT_DESIGNS])
def test_each_guide_script_slices_unchanged(name, code, tmp_path):
    design = _design(tmp_path, code)
    _, program, stats = _slice(design, tmp_path, layer_height=0.4, colors=2)
    lo, hi = (np.array(v) for v in design.bounds())
    roles = np.array(program.roles + [""])[program.role]
    printed = (program.e > 0) & (program.length > 0) & ~np.isin(roles, ["Skirt/Brim", "Wipe tower"])
    xy = program.end[printed, :2] - np.array(stats["placement_offset"][:2])
    assert (xy >= lo[:2] - 1.0).all() and (xy <= hi[:2] + 1.0).all()
    assert xy[:, 0].min() == pytest.approx(lo[0], abs=1.0)
    assert program.layer_z[-1] == pytest.approx(hi[2] - lo[2], abs=1.0)


def _values(design, name, *points):
    x, y, z = np.array(points, dtype=float).T
    return attribute_fields(design).values(name, x, y, z)


def test_hierarchy_first_child_owns_the_overlap_and_a_parent_overrides(tmp_path):
    lesson7 = dict(SCRIPTS)["getting-started 16"]
    design = _design(tmp_path, lesson7)
    # the cubes overlap for -2.5 <= x <= 2.5: the left (red) one owns it
    np.testing.assert_allclose(_values(design, "color_rgba.r", (-6, 0, 0), (0, 0, 0), (6, 0, 0)), [1, 1, 0])
    overridden = _design(tmp_path, lesson7.replace(
        "root = pv.Union(left_cube, right_cube)",
        'root = pv.Union(left_cube, right_cube)\nroot.set_attribute(pv.DefaultAttributes.COLOR_RGBA, '
        'pv.Vec4Attribute("0.25", "0.5", "0.75", "1.0"))'))
    np.testing.assert_allclose(_values(overridden, "color_rgba.g", (-6, 0, 0), (0, 0, 0), (6, 0, 0)), [0.5] * 3)


def test_a_child_inherits_its_parents_attribute_and_keeps_its_own_elsewhere(tmp_path):
    design = _design(tmp_path, HEADER + """
        a = pv.Sphere(pv.Vec3(-10, 0, 0), 4.0)
        b = pv.Sphere(pv.Vec3(10, 0, 0), 4.0)
        b.set_attribute("modulus", pv.FloatAttribute(7.0))
        inner = pv.Union(a, b)
        inner.set_attribute(pv.DefaultAttributes.DENSITY, pv.FloatAttribute("x"))
        root = pv.Translate(0, 0, 5, inner)
    """.replace("\n        ", "\n"))
    np.testing.assert_allclose(_values(design, "density", (-10, 0, 5), (10, 0, 5)), [-10, 10])
    np.testing.assert_allclose(_values(design, "modulus", (-10, 0, 5), (10, 0, 5)), [np.nan, 7])


def test_attributes_move_with_their_node_unless_attached_to_an_identity_above(tmp_path):
    rotated, world = (_design(tmp_path, dict(SCRIPTS)[n]) for n in ("getting-started 17", "getting-started 18"))
    # the prism lies along Y after the 90 degree roll; its gradient turned with it
    np.testing.assert_allclose(_values(rotated, "color_rgba.r", (0, -9, 0), (0, 9, 0)), [0.05, 0.95], atol=1e-9)
    np.testing.assert_allclose(_values(world, "color_rgba.r", (-1, 0, 0), (1, 0, 0)), [0.45, 0.55], atol=1e-9)


def test_resolvers_average_max_per_channel_fractions_and_custom_reductions(tmp_path):
    scripts = dict(SCRIPTS)
    lens = _design(tmp_path, scripts["attribute-conflicts 1"])
    np.testing.assert_allclose([_values(lens, f"color_rgba.{c}", (0, 0, 0))[0] for c in "rgba"], [0.5, 0, 0.5, 1])
    cross = _design(tmp_path, scripts["attribute-conflicts 2"])
    centre, arm = (0, 0, 0), (8, 0, 0)
    np.testing.assert_allclose([_values(cross, f"color_rgba.{c}", centre, arm) for c in "rgb"], [[1, 0], [1, 1], [1, 1]])
    fractions = _design(tmp_path, scripts["attribute-conflicts 3"])
    names = [m.name for m in fractions.materials]
    mix = fractions.fractions(np.array([0.0, 8.0]), np.array([0.0, 0.0]), np.array([0.0, 0.0]))
    np.testing.assert_allclose(mix[:, names.index("blue")], [0.5, 1.0])
    product = _design(tmp_path, scripts["attribute-conflicts 4"])
    np.testing.assert_allclose(_values(product, "density", (0, 0, 0)), [6.0])
    channels = _design(tmp_path, scripts["attribute-conflicts 5"])
    np.testing.assert_allclose([_values(channels, f"color_rgba.{c}", centre)[0] for c in "rgba"], [0.8, 0.8, 1.0, 1.0])
    grid = _design(tmp_path, scripts["attribute-conflicts 6"])
    np.testing.assert_allclose(_values(grid, "density", (0, 0, 0), (0, 8, 0), (8, 8, 0)), [4, 2, 1])


def test_numba_functions_with_branches_match_their_python_point_by_point(tmp_path):
    design = _design(tmp_path, dict(SCRIPTS)["numba-attributes 2"])
    x = np.linspace(-25, 25, 11)
    got = attribute_fields(design).values("modulus", x, 0 * x, 0 * x)
    np.testing.assert_allclose(got, 1 + 9 * np.clip((x + 20) / 40, 0, 1))


def test_to_field_gives_a_number_an_expression_or_a_vectorized_callable(tmp_path):
    from fgslice.compat import numba_standin as numba
    from fgslice.compat import pyvcad as pv

    assert pv.FloatAttribute(2.5).to_field() == 2.5
    assert pv.FloatAttribute("0.1 * z + 1").to_field() == "0.1 * z + 1"

    @numba.cfunc(numba.types.float64(numba.types.float64, numba.types.float64, numba.types.float64,
                                     numba.types.float64))
    def thickness(x, y, z, d):
        return 0.5 if x < 0 else 1.0 + 0.01 * y

    field = pv.FloatAttribute(thickness).to_field()
    out = field(np.array([-1.0, 2.0]), np.array([0.0, 10.0]), np.zeros(2))
    np.testing.assert_allclose(out, [0.5, 1.1])


def test_lookup_and_expression_converters_derive_machine_attributes(tmp_path):
    code = HEADER + """
        table = [(220, 1.42), (236, 0.86), (256, 0.66)]
        converter = pv.LookupTableConverter(
            input_attributes=[pv.DefaultAttributes.TEMPERATURE],
            output_attributes=[pv.DefaultAttributes.FLOW_RATE],
            entries=[pv.LookupTableEntry(t, t, f) for t, f in table],
            mode=pv.InterpolationMode.LINEAR)
        bar = pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(180, 12, 12))
        bar.set_attribute(pv.DefaultAttributes.DENSITY, pv.FloatAttribute("0.5 + x / 360"))
        to_temperature = pv.ExpressionConverter(["density"], ["temperature"], ["256 - 36 * (density - 0.0) * 1"])
        root = pv.AttributeModifier(converter, pv.AttributeModifier(to_temperature, bar))
    """.replace("\n        ", "\n")
    design = _design(tmp_path, code)
    x = np.array([-90.0, 0.0, 90.0])
    t = attribute_fields(design).values("temperature", x, 0 * x, 0 * x)
    np.testing.assert_allclose(t, 256 - 36 * (0.5 + x / 360))
    flow = attribute_fields(design).values("flow", x, 0 * x, 0 * x)
    np.testing.assert_allclose(flow, 100 * np.interp(t, [220, 236, 256], [1.42, 0.86, 0.66]))


def test_smooth_union_fills_the_gap_between_its_children(tmp_path):
    design = _design(tmp_path, HEADER + "root = pv.Union(1.0, [pv.Sphere(pv.Vec3(-2.2, 0, 0), 2.0), "
                                        "pv.Sphere(pv.Vec3(2.2, 0, 0), 2.0)])\n")
    sharp = _design(tmp_path, HEADER + "root = pv.Union(pv.Sphere(pv.Vec3(-2.2, 0, 0), 2.0), "
                                       "pv.Sphere(pv.Vec3(2.2, 0, 0), 2.0))\n")
    gap = (np.zeros(1), np.zeros(1), np.zeros(1))
    assert sharp.sdf(*gap)[0] == pytest.approx(0.2) and design.sdf(*gap)[0] == pytest.approx(0.2 - 1.0 / 4)
    assert design.sections([0.0])[0].area > sharp.sections([0.0])[0].area


@pytest.mark.parametrize("code,message", [
    ("root = pv.Render_Tree_Diagram(pv.Sphere(pv.Vec3(0, 0, 0), 1.0))", "pyvcad.Render_Tree_Diagram is not supported"),
    ("def f(x, y, z, d):\n    return x\nroot = pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(1, 1, 1))\n"
     "root.set_attribute('modulus', pv.FloatAttribute(f))", "decorated with numba's @cfunc"),
    ("root = pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(1, 1, 1))\n"
     "root.set_attribute(pv.DefaultAttributes.VOLUME_FRACTIONS, pv.FloatAttribute(1.0))", "takes a VolumeFractions"),
    ("root = pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(1, 1, 1))\nroot.set_attribute_conflict_resolver('x', 1)",
     "RectPrism.set_attribute_conflict_resolver: only Union"),
    ("a = pv.FloatAttribute('x +')", "expression"),
    ("a = pv.DefaultAttributes.TEMPERATUR", "DefaultAttributes.TEMPERATUR is not supported"),
    ("from numba import njit", "numba.njit is not supported"),
])
def test_unsupported_names_and_bad_arguments_fail_at_the_scripts_line(tmp_path, code, message):
    with pytest.raises(FgsliceError, match=re.escape(message)) as caught:
        _design(tmp_path, HEADER + code + "\n")
    assert caught.value.line is not None and caught.value.line >= 3


def test_check_lists_each_attribute_its_range_and_what_it_drives(tmp_path):
    design = _design(tmp_path, dict(SCRIPTS)["gradients 2"])
    report = check_design(design, settings=load_settings("foam-lwpla", {}))
    text = format_report(report)
    assert re.search(r"attribute modulus\s+1\.\d+ \.\. 9\.\d+ -> drives nothing on this machine: .*AttributeModifier", text)
    assert report.usable
    # lesson 2's 0-10 C Gaussian TEMPERATURE: design intent on the mixing hotend, refused when foaming
    lesson2 = _design(tmp_path, dict(SCRIPTS)["gradients 4"])
    intent = check_design(lesson2)
    assert intent.usable and intent.design_intent == ["temperature"]
    assert intent.attribute_drives["temperature"].startswith("nothing on this machine: ")
    refused = check_design(lesson2, settings=load_settings("foam-lwpla", {}))
    assert not refused.usable and "outside this machine's 170 .. 300 C" in refused.errors[0]


# ---------------------------------------------------------------- G-code follows the field


def test_volume_fractions_bar_mixture_follows_x(tmp_path):
    design = _design(tmp_path, dict(SCRIPTS)["getting-started 15"])
    names = [m.name for m in design.materials]
    _, program, stats = _slice(design, tmp_path, colors=8, strategy=1)
    mid = (program.start + program.end)[:, :2] / 2 - np.array(stats["placement_offset"][:2])
    printed = (program.e > 0) & (program.length > 0) & (program.layer == 5) & (np.abs(mid) <= [25, 5]).all(axis=1)
    x = mid[printed, 0]
    blue = np.array([program.states[s].mix_fractions(2)[names.index("blue")] for s in program.state[printed]])
    # eight palette bins of 1/8: the commanded share of blue is the field's within a bin
    assert np.abs(blue - (x / 50 + 0.5)).max() <= 1 / 8 + 0.02
    assert np.corrcoef(x, blue)[0, 1] > 0.95


FOAM = HEADER + """
bar = pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(60, 12, 4))
bar.set_attribute(pv.DefaultAttributes.TEMPERATURE, pv.FloatAttribute("{temperature}"))
{flow}
"""
FLOW = """converter = pv.LookupTableConverter([pv.DefaultAttributes.TEMPERATURE], [pv.DefaultAttributes.FLOW_RATE],
    [pv.LookupTableEntry(t, t, f) for t, f in [(220, 1.42), (236, 0.86), (256, 0.66)]], pv.InterpolationMode.LINEAR)
root = pv.AttributeModifier(converter, bar)"""


def _foam(tmp_path, temperature: str, flow: str):
    design = _design(tmp_path, FOAM.format(temperature=temperature, flow=flow))
    _, program, stats = _slice(design, tmp_path, profile="foam-lwpla")
    printed = (program.e > 0) & (program.length > 0) & (program.layer > 0)
    temperature = np.array([program.states[s].temperature for s in program.state[printed]])
    return program, printed, temperature


def test_temperature_bar_on_a_foaming_profile_m104_spans_the_field_and_m221_falls(tmp_path):
    # the paper's LW-PLA range, where its flow polynomial holds
    program, printed, temperature = _foam(tmp_path, "max(min(0.6 * x + 208, 225), 190)", "root = bar")
    assert temperature.min() == 190 and temperature.max() == 225  # 5 C levels over 190 .. 225
    heats = [(e.line, e.target) for e in program.temperatures if e.target > 0 and not e.wait]
    lines = np.array([line for line, _ in heats])
    # each M221 with the temperature of the M104 before it
    pairs = [(heats[np.searchsorted(lines, f.line) - 1][1], f.values["S"]) for f in program.flows if f.line > lines[0]]
    assert len(pairs) > 5
    t, flow = np.array(pairs).T
    assert len(np.unique(t)) == 8 and all(np.diff(flow[np.argsort(t)]) <= 0) and flow.max() > flow.min()


def test_temperature_and_flow_rate_bar_extrudes_less_as_the_temperature_rises(tmp_path):
    # OpenVCAD's foaming example: 220 .. 256 C, its flow table
    program, printed, temperature = _foam(tmp_path, "max(min(0.6 * x + 238, 256), 220)", FLOW)
    assert temperature.min() == 220 and temperature.max() == 255
    assert not program.flows  # the design's flow replaces the profile's flow model
    per_mm = program.e[printed] / program.length[printed]
    by_level = [np.median(per_mm[temperature == t]) for t in np.unique(temperature)]
    assert all(np.diff(by_level) < 0)
    expected = np.interp(np.unique(temperature), [220, 236, 256], [1.42, 0.86, 0.66])
    np.testing.assert_allclose(np.array(by_level) / by_level[0], expected / expected[0], rtol=0.08)


def test_infill_density_bar_sparse_volume_per_length_rises(tmp_path):
    design = _design(tmp_path, HEADER + """
bar = pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(80, 20, 4))
bar.set_attribute(pv.DefaultAttributes.INFILL_DENSITY, pv.FloatAttribute("clamp(10, 40 + x/2, 70)"))
root = bar
""")
    settings, program, stats = _slice(design, tmp_path, strategy=1)
    roles = np.array(program.roles + [""])[program.role]
    infill = (program.e > 0) & (program.length > 0) & (roles == "Internal infill") & (program.layer == 6)
    x = ((program.start + program.end) / 2)[infill, 0] - stats["placement_offset"][0]
    bands = [(x >= lo) & (x < lo + 20) for lo in (-40, -20, 0, 20)]
    per_mm = [program.e[infill][b].sum() / 20 for b in bands]
    assert all(np.diff(per_mm) > 0)
    # band centres at x = -30 .. 30: densities 25, 35, 45, 55 %
    assert per_mm[-1] / per_mm[0] == pytest.approx(55 / 25, rel=0.25)


def test_color_rgb_bar_on_a_two_filament_mixing_hotend_follows_the_colour(tmp_path):
    design = _design(tmp_path, HEADER + """
bar = pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(60, 10, 4))
bar.set_attribute(pv.DefaultAttributes.COLOR_RGB,
                  pv.Vec3Attribute("clamp(0, 0.5 - x/60, 1)", "0.0", "clamp(0, 0.5 + x/60, 1)"))
root = bar
""")
    _, program, stats = _slice(design, tmp_path, profile="marlin-mixing", colors=8, strategy=1,
                               filament_colors="#ff0000,#0000ff")
    mid = (program.start + program.end)[:, :2] / 2 - np.array(stats["placement_offset"][:2])
    printed = (program.e > 0) & (program.length > 0) & (program.layer == 5) & (np.abs(mid) <= [30, 5]).all(axis=1)
    x = mid[printed, 0]
    blue = np.array([program.states[s].mix_fractions(2)[1] for s in program.state[printed]])
    # red + blue light in linear RGB is the mixture itself: the blue share is the blue channel
    assert np.abs(blue - (0.5 + x / 60)).max() <= 1 / 8 + 0.02
    report = format_report(check_design(design, settings=load_settings("marlin-mixing", {
        "filament_colors": "#ff0000,#0000ff"})))
    assert "color_rgb.r" in report and "-> drives the mixture of the filaments #ff0000,#0000ff" in report
    # the filaments are named by the library colours nearest them, which previews know
    assert report.startswith("materials:\n  red ") and report.count(" alpha ") == 2


def test_a_colour_without_filament_colours_drives_nothing_and_says_how_to(tmp_path):
    design = _design(tmp_path, dict(SCRIPTS)["getting-started 14"])
    report = check_design(design, settings=load_settings("marlin-mixing", {}))
    assert "filament_colors" in report.attribute_drives["color_rgba.r"]
    assert [m.name for m in report.materials] == ["default"]


def test_unmixing_finds_the_nearest_reachable_colour_in_cielab():
    from fgslice.design.color_mix import unmix

    cyan_magenta_yellow = ((0.0, 1.0, 1.0), (1.0, 0.0, 1.0), (1.0, 1.0, 0.0))
    f = unmix(np.array([[0.0, 1.0, 1.0], [1.0, 0.5, 0.5], [0.5, 0.5, 0.5]]), cyan_magenta_yellow)
    np.testing.assert_allclose(f.sum(axis=1), 1.0)
    assert f[0, 0] == pytest.approx(1.0) and f[1, 0] < 0.05  # pure cyan; a pink has no cyan
    np.testing.assert_allclose(f[2], [1 / 3] * 3, atol=0.05)  # grey: equal shares


def test_fuzzy_skin_cylinder_outer_wall_deviation_grows_with_the_field(tmp_path):
    design = _design(tmp_path, HEADER + """
cylinder = pv.Cylinder(pv.Vec3(0, 0, 0), 10.0, 10.0)
cylinder.set_attribute(pv.DefaultAttributes.FUZZY_SKIN_THICKNESS, pv.FloatAttribute("0.035 * (z + 5)"))
cylinder.set_attribute(pv.DefaultAttributes.FUZZY_SKIN_POINT_DISTANCE, pv.FloatAttribute(0.6))
root = cylinder
""")
    _, program, stats = _slice(design, tmp_path, layer_height=0.5, bead_width=0.5)
    roles = np.array(program.roles + [""])[program.role]
    outer = (program.e > 0) & (program.length > 0) & (roles == "External perimeter")
    centre = np.array(stats["placement_offset"][:2])
    radius = np.hypot(*(program.end[outer, :2] - centre).T)
    layers = np.unique(program.layer[outer])
    spread = np.array([np.abs(radius[program.layer[outer] == k] - 9.75).max() for k in layers])
    expected = 0.035 * (np.array(program.layer_z)[layers] - 0.25)  # the field at mid-layer
    assert np.corrcoef(expected, spread)[0, 1] > 0.95
    assert (spread <= expected + 0.1).all() and (spread[-3:] >= 0.5 * expected[-3:]).all()
    again = _slice(design, tmp_path, layer_height=0.5, bead_width=0.5)[1]
    np.testing.assert_array_equal(again.end, program.end)  # seeded: the same texture every time


def test_feature_speed_attributes_set_each_segments_feed_rate(tmp_path):
    design = _design(tmp_path, HEADER + """
bar = pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(60, 20, 2))
bar.set_attribute(pv.DefaultAttributes.EXTERNAL_PERIMETER_SPEED, pv.FloatAttribute("40 + x/2"))
half = pv.RectPrism(pv.Vec3(15, 0, 0), pv.Vec3(30, 20, 2))
half.set_attribute(pv.DefaultAttributes.INFILL_SPEED, pv.FloatAttribute(90.0))
root = pv.Union(half, bar)
""")
    settings, program, stats = _slice(design, tmp_path, strategy=1)
    roles = np.array(program.roles + [""])[program.role]
    mid = (program.start + program.end)[:, :2] / 2 - np.array(stats["placement_offset"][:2])
    printed = (program.e > 0) & (program.length > 0) & (program.layer == 3)
    outer = printed & (roles == "External perimeter") & (np.abs(mid[:, 0]) < 29.5)
    # the half owns its points: the bar's outer wall speed holds where the half is not
    left = outer & (mid[:, 0] < 0)
    np.testing.assert_allclose(program.feed[left] / 60, 40 + mid[left, 0] / 2, atol=0.6)
    infill = printed & (roles == "Internal infill")
    inside_half = infill & (mid[:, 0] > 1)
    assert np.allclose(program.feed[inside_half] / 60, 90) and inside_half.sum() > 10
    assert np.allclose(program.feed[infill & (mid[:, 0] < -1)] / 60, settings.infill_speed)
    inner = printed & (roles == "Perimeter")
    assert np.allclose(program.feed[inner] / 60, settings.print_speed)
