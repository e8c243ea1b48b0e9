"""OpenVCAD 3's derived attributes (arithmetic, map_range, clamp, normalize, vector
methods, DerivedFloatAttribute), its Cone, and the volume-data names fgslice refuses."""

from __future__ import annotations

import math
import re
import textwrap
from datetime import datetime, timezone

import numpy as np
import pytest

from fgslice.compat.script import load_script
from fgslice.design.attributes import attribute_fields
from fgslice.errors import FgsliceError
from fgslice.machine.gcode_reader import read_gcode
from fgslice.pipeline import slice_to_gcode
from fgslice.settings import load_settings

HEADER = "import pyvcad as pv\n"


def _design(tmp_path, code: str):
    path = tmp_path / "design.py"
    path.write_text(HEADER + textwrap.dedent(code))
    return load_script(path)


def _slice(design, tmp_path, profile=None, **overrides):
    settings = load_settings(profile, {k: str(v) for k, v in overrides.items()})
    out = tmp_path / "part.gcode"
    result = slice_to_gcode(design, settings, out, jobs=1, stamp=datetime(2026, 1, 1, tzinfo=timezone.utc))
    return settings, read_gcode(out), result.stats


def _values(design, name, x, y, z):
    return attribute_fields(design).values(name, np.asarray(x, float), np.asarray(y, float), np.asarray(z, float))


def test_the_metamaterial_guides_attribute_steps_give_their_formulas(tmp_path):
    design = _design(tmp_path, """
        x_position = pv.FloatAttribute("x")
        position_01 = x_position.normalize(-24.0, 24.0)
        curved_position = position_01 ** 2
        thickness = curved_position.map_range(0.0, 1.0, 0.55, 1.65)
        bounded_thickness = thickness.clamp(0.55, 1.65)
        combined = pv.DerivedFloatAttribute("base + gain * signal", {"base": 0.4, "gain": 0.8, "signal": position_01})
        planar_position = pv.Vec3Attribute("x / 24", "0", "z / 24")
        radial_distance = planar_position.magnitude().clamp(0.0, 1.0)
        beam_radius = radial_distance.map_range(0.0, 1.0, 0.25, 1.25)
        root = pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(60, 10, 60))
        root.set_attribute(pv.DefaultAttributes.MODULUS, bounded_thickness)
        root.set_attribute(pv.DefaultAttributes.DENSITY, combined)
        root.set_attribute(pv.DefaultAttributes.HU, beam_radius)
        root.set_attribute(pv.DefaultAttributes.TOUGHNESS,
                           abs(1 - planar_position.normalized().x) + planar_position.dot(planar_position) / 2
                           - (-planar_position.z) * 3 + 1 / (1 + planar_position.component(1)))
    """)
    x = np.linspace(-30, 30, 13)
    z = np.linspace(-20, 28, 13)
    y = 0 * x
    p = (x + 24) / 48
    np.testing.assert_allclose(_values(design, "modulus", x, y, z), np.clip(0.55 + 1.1 * p * p, 0.55, 1.65))
    np.testing.assert_allclose(_values(design, "density", x, y, z), 0.4 + 0.8 * p)
    magnitude = np.hypot(x / 24, z / 24)
    np.testing.assert_allclose(_values(design, "hu", x, y, z), 0.25 + np.clip(magnitude, 0, 1))
    expected = np.abs(1 - (x / 24) / magnitude) + magnitude**2 / 2 + 3 * z / 24 + 1
    np.testing.assert_allclose(_values(design, "toughness", x, y, z), expected)


def test_setters_replace_the_definition_and_a_derived_attribute_is_immutable(tmp_path):
    design = _design(tmp_path, """
        a = pv.FloatAttribute()
        a.set_expression("2 * x")
        b = a + 1
        a.set_value(5.0)
        root = pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(10, 10, 10))
        root.set_attribute("modulus", b)
        root.set_attribute("density", a)
    """)
    np.testing.assert_allclose(_values(design, "modulus", [-4, 4], [0, 0], [0, 0]), [-7, 9])  # b kept the old a
    np.testing.assert_allclose(_values(design, "density", [-4, 4], [0, 0], [0, 0]), [5, 5])


@pytest.mark.parametrize("code,message", [
    ("a = pv.DerivedFloatAttribute('s + x', {'s': pv.FloatAttribute('z')})", "'x' is not one of the inputs (s)"),
    ("a = pv.DerivedFloatAttribute('s', [1])", "inputs is a dict"),
    ("a = pv.DerivedFloatAttribute('s', {'s': pv.Vec3Attribute(1, 2, 3)})", "input 's' must be a FloatAttribute"),
    ("a = pv.DerivedFloatAttribute('s', {'s': 1.0})\na.set_value(2.0)", "DerivedFloatAttribute is immutable"),
    ("a = pv.DerivedFloatAttribute('a+b+c+e+f', {n: pv.FloatAttribute(1.0) for n in 'abcef'})", "at most 4"),
    ("a = pv.FloatAttribute('x').map_range(1, 1, 0, 2)", "input range 1 .. 1 is empty"),
    ("a = pv.FloatAttribute('x') + pv.Vec3Attribute(1, 2, 3)", "combines with FloatAttributes and numbers"),
    ("a = pv.Vec3Attribute(1, 2, 3).component(3)", "index is 0, 1 or 2"),
    ("root = pv.Cone(30.0, 10.0)", "aperture half-angle in radians"),
    ("root = pv.Cone(0.5, -1)", "height must be positive"),
    ("root = pv.SignedDistanceField('part.vdb')", "pyvcad.SignedDistanceField is not supported by fgslice: its data "
                                                  "is an OpenVDB grid"),
    ("v = pv.vdb_loader.load_float_volume('model.vdb', 'density')", "pyvcad.vdb_loader is not supported"),
    ("v = pv.DICOMLoader('scans')", "DICOMLoader: 'scans' is not a folder"),
    ("v = pv.Vec3sVolume()", "pyvcad.Vec3sVolume is not supported by fgslice: its data is an OpenVDB grid"),
])
def test_bad_derived_attributes_cones_and_volume_data_fail_at_the_scripts_line(tmp_path, code, message):
    with pytest.raises(FgsliceError, match=re.escape(message)) as caught:
        _design(tmp_path, code + "\n")
    assert caught.value.line is not None and caught.value.line >= 2


def test_derived_temperature_and_flow_drive_m104_and_extrusion_along_the_bar(tmp_path):
    design = _design(tmp_path, """
        t = pv.FloatAttribute("x").normalize(-30, 30)
        bar = pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(60, 12, 4))
        bar.set_attribute(pv.DefaultAttributes.TEMPERATURE, t.map_range(0, 1, 190, 225))
        bar.set_attribute(pv.DefaultAttributes.FLOW_RATE, pv.DerivedFloatAttribute("hi - span * t",
                                                                                  {"hi": 1.2, "span": 0.4, "t": t}))
        root = bar
    """)
    settings, program, stats = _slice(design, tmp_path, profile="foam-lwpla")
    printed = (program.e > 0) & (program.length > 0) & (program.layer > 0)
    x = ((program.start + program.end) / 2)[printed, 0] - stats["placement_offset"][0]
    temperature = np.array([program.states[s].temperature for s in program.state[printed]])
    assert temperature.min() == 190 and temperature.max() == 225
    # a state per level of temperature_step: within a level of the field at the move
    assert np.abs(temperature - (190 + 35 * (x + 30) / 60)).max() <= settings.temperature_step + 1e-9
    per_mm = program.e[printed] / program.length[printed]
    ends = [np.median(per_mm[band]) for band in (x < -25, x > 25)]
    assert ends[1] / ends[0] == pytest.approx((1.2 - 0.4 * 55 / 60) / (1.2 - 0.4 * 5 / 60), rel=0.05)


def test_cone_sections_are_the_analytic_circles(tmp_path):
    design = _design(tmp_path, "root = pv.Translate(5, -3, 0, pv.Cone(math.radians(20), 30.0))\n".replace(
        "math.radians(20)", repr(math.radians(20))))
    lo, hi = (np.array(b) for b in design.bounds())
    r = 30 * math.tan(math.radians(20))
    np.testing.assert_allclose(lo, [5 - r, -3 - r, -30], atol=1e-9)
    np.testing.assert_allclose(hi, [5 + r, -3 + r, 0], atol=1e-9)
    zs = [-29.0, -20.0, -7.5, -1.0]
    for z, section in zip(zs, design.sections(zs)):
        radius = -z * math.tan(math.radians(20))
        assert section.area == pytest.approx(math.pi * radius**2, rel=2e-3)
        assert section.centroid.x == pytest.approx(5) and section.centroid.y == pytest.approx(-3)
    # the signed distance: exact to the side and to the base
    d = design.sdf(np.array([5.0, 5.0, 5.0 + r + 2]), np.array([-3.0, -3.0, -3.0]), np.array([-10.0, -31.0, -30.0]))
    np.testing.assert_allclose(d, [-10 * math.sin(math.radians(20)), 1.0, 2.0], atol=1e-9)


def test_a_sliced_cone_s_outer_wall_follows_its_radius_at_each_layer(tmp_path):
    design = _design(tmp_path, "root = pv.Cone(0.6, 12.0)\n")
    settings, program, stats = _slice(design, tmp_path, layer_height=0.3)
    offset = np.array(stats["placement_offset"])
    roles = np.array(program.roles + [""])[program.role]
    outer = (program.e > 0) & (roles == "External perimeter")
    assert outer.any()
    for layer in np.unique(program.layer[outer])[::5]:
        here = outer & (program.layer == layer)
        z_design = program.layer_z[layer] - settings.layer_height / 2 - offset[2]
        xy = program.end[here, :2] - offset[:2]
        radius = -z_design * math.tan(0.6) - settings.bead_width / 2
        np.testing.assert_allclose(np.hypot(*xy.T), radius, atol=0.05)


def test_lookup_tables_of_the_api_reference_single_multi_input_step_and_a_two_input_grid(tmp_path):
    design = _design(tmp_path, """
        part = pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(40, 40, 10))
        part.set_attribute(pv.DefaultAttributes.HU, pv.FloatAttribute("x * 50"))
        part.set_attribute(pv.DefaultAttributes.TEMPERATURE, pv.FloatAttribute("x / 2"))
        part.set_attribute(pv.DefaultAttributes.DENSITY, pv.FloatAttribute("(y + 20) / 80"))
        hu = pv.LookupTableConverter(['hu'], ['color_rgba'], [
            pv.LookupTableEntry(-1000, -500, pv.Vec4(0, 0, 0, 0)),
            pv.LookupTableEntry(-500, 0, pv.Vec4(1, 0, 0, 0.5)),
            pv.LookupTableEntry(0, 1000, pv.Vec4(0, 1, 0, 1)),
        ], pv.InterpolationMode.STEP)
        rgb = pv.LookupTableConverter(['temperature', 'density'], ['color_rgb', 'modulus'], [
            pv.LookupTableEntry([(0, 1), (0, 0.01)], [pv.Vec3(1, 1, 1), 0.0]),
            pv.LookupTableEntry([(1, 10), (0.01, 0.5)], [pv.Vec3(1, 0, 0), 0.5]),
        ], pv.InterpolationMode.STEP)
        corners = [([t, d], f) for t, d, f in [(-10, 0, 1.0), (10, 0, 2.0), (-10, 0.5, 3.0), (10, 0.5, 5.0)]]
        grid = pv.LookupTableConverter(['temperature', 'density'], ['toughness'],
                                       [pv.LookupTableEntry(p, f) for p, f in corners], pv.InterpolationMode.LINEAR)
        root = pv.AttributeModifier(grid, pv.AttributeModifier(rgb, pv.AttributeModifier(hu, part)))
    """)
    x = np.array([-15.0, -5.0, 5.0, 15.0, 4.0])
    y = np.array([-20.0, -10.0, 0.0, 19.0, -19.9])
    z = 0 * x
    rgba = np.array([_values(design, f"color_rgba.{c}", x, y, z) for c in "rgba"]).T
    np.testing.assert_allclose(rgba, [[0, 0, 0, 0], [1, 0, 0, 0.5], [0, 1, 0, 1], [0, 1, 0, 1], [0, 1, 0, 1]])
    t, d = x / 2, (y + 20) / 80
    # each input matched on its own column: temperature -> the colour, density -> modulus
    red_only = t >= 1
    np.testing.assert_allclose(_values(design, "color_rgb.g", x, y, z), np.where(red_only, 0, 1))
    np.testing.assert_allclose(_values(design, "modulus", x, y, z), np.where(d >= 0.01, 0.5, 0))
    u, v = (np.clip(t, -10, 10) + 10) / 20, np.clip(d, 0, 0.5) / 0.5
    expected = 1 * (1 - u) * (1 - v) + 2 * u * (1 - v) + 3 * (1 - u) * v + 5 * u * v
    np.testing.assert_allclose(_values(design, "toughness", x, y, z), expected)


def test_a_temperature_to_colour_table_drives_the_mixture_on_a_two_filament_hotend(tmp_path):
    design = _design(tmp_path, """
        bar = pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(60, 10, 2))
        bar.set_attribute(pv.DefaultAttributes.DENSITY, pv.FloatAttribute("x / 30"))
        to_colour = pv.LookupTableConverter(['density'], ['color_rgb'], [
            pv.LookupTableEntry(-1, pv.Vec3(1, 0, 0)), pv.LookupTableEntry(1, pv.Vec3(0, 0, 1))],
            pv.InterpolationMode.LINEAR)
        root = pv.AttributeModifier(to_colour, bar)
    """)
    _, program, stats = _slice(design, tmp_path, profile="marlin-mixing", colors=8, strategy=1,
                               filament_colors="#ff0000,#0000ff")
    mid = (program.start + program.end)[:, :2] / 2 - np.array(stats["placement_offset"][:2])
    printed = (program.e > 0) & (program.length > 0) & (program.layer == 2) & (np.abs(mid) <= [30, 5]).all(axis=1)
    x = mid[printed, 0]
    blue = np.array([program.states[s].mix_fractions(2)[1] for s in program.state[printed]])
    # the table gives red (1, 0, 0) .. blue (0, 0, 1) linearly: the blue share is (x + 30) / 60
    assert np.abs(blue - (0.5 + x / 60)).max() <= 1 / 8 + 0.02
    assert blue.min() < 0.15 and blue.max() > 0.85


@pytest.mark.parametrize("code,message", [
    ("pv.LookupTableConverter(['hu'], ['volume_fractions'], [pv.LookupTableEntry(0, 1)])", "not 'volume_fractions'"),
    ("pv.LookupTableEntry([1.0, 2.0], {1: 0.7, 2: 0.3})", "lookup tables to volume fractions are not supported"),
    ("pv.LookupTableConverter(['hu', 'density'], ['modulus'], [pv.LookupTableEntry([0, 0], 1.0), "
     "pv.LookupTableEntry([1, 0], 1.0), pv.LookupTableEntry([0, 1], 1.0)], pv.InterpolationMode.LINEAR)",
     "the point (1, 1) has no entry"),
    ("pv.LookupTableConverter(['hu', 'density', 'modulus'], ['toughness'], [pv.LookupTableEntry([0, 0, 0], 1.0)], "
     "pv.InterpolationMode.LINEAR)", "LINEAR interpolates one input or a two-input grid"),
    ("pv.LookupTableConverter(['hu'], ['color_rgba'], [pv.LookupTableEntry(0, pv.Vec3(1, 0, 0))])",
     "an entry gives 3 channel(s) for the output attribute(s) color_rgba (4 channels)"),
])
def test_bad_lookup_tables_fail_with_their_reason(tmp_path, code, message):
    with pytest.raises(FgsliceError, match=re.escape(message)):
        _design(tmp_path, code + "\n")


GAUSSIAN = """
    prism = pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(50, 10, 4))
    prism.set_attribute(pv.DefaultAttributes.TEMPERATURE, pv.FloatAttribute("{expression}"))
    root = prism
"""


def test_a_temperature_that_is_no_nozzle_temperature_is_design_intent_on_a_mixing_hotend(tmp_path):
    # the functional-grading guide's 0-10 C Gaussian: no temperature state, the profile's nozzle temperature
    design = _design(tmp_path, GAUSSIAN.format(expression="10 * exp(-(x^2) / (2 * 10^2))"))
    settings, program, stats = _slice(design, tmp_path, layer_height=0.4)
    heats = {e.target for e in program.temperatures if e.target > 0 and e.command in ("M104", "M109")}
    assert heats == {settings.nozzle_temperature} and "temperature_levels" not in stats
    printed = (program.e > 0) & (program.length > 0)
    assert len({program.states[s].temperature for s in program.state[printed]}) <= 1
    with pytest.raises(FgsliceError, match=re.escape("outside this machine's 170 .. 300 C")):
        _slice(design, tmp_path, profile="foam-lwpla")


def test_a_temperature_reaching_into_the_nozzle_range_drives_m104_and_is_refused_beyond_it(tmp_path):
    within = _design(tmp_path, GAUSSIAN.format(expression="200 + x / 2"))
    _, program, _ = _slice(within, tmp_path, layer_height=0.4)
    targets = {e.target for e in program.temperatures if e.target > 0 and e.command == "M104"}
    assert min(targets) <= 190 and max(targets) >= 210
    straddling = _design(tmp_path, GAUSSIAN.format(expression="150 + x"))
    with pytest.raises(FgsliceError, match=re.escape("outside this machine's 170 .. 300 C")):
        _slice(straddling, tmp_path, layer_height=0.4)


def test_attributes_sample_clone_and_tell_their_types(tmp_path):
    from fgslice.compat import pyvcad as pv

    a = pv.FloatAttribute("2 * x + d")
    assert a.sample(1.5, 0, 0, -0.5) == pytest.approx(2.5) and a.return_type() is pv.Attribute.ReturnType.dbl
    b = a.clone()
    a.set_value(7.0)
    assert (a.sample(1, 1, 1, 0), b.sample(1, 1, 1, 0)) == (7.0, 2.0)
    colour = pv.Vec4Attribute()
    colour.set_expression("x", "y", "z", "1")
    rgba = colour.sample(0.1, 0.2, 0.3, 0)
    assert isinstance(rgba, pv.Vec4) and rgba.values == pytest.approx((0.1, 0.2, 0.3, 1.0))
    v = pv.Vec3Attribute(1, 2, 3)
    v.set_value(3, 0, 4)
    assert tuple(v.sample(0, 0, 0, 0)) == (3, 0, 4) and v.magnitude().sample(0, 0, 0, 0) == 5
    assert not v.is_volume_backed() and v.return_type() is pv.Attribute.ReturnType.vec3
    mats = pv.default_materials
    fractions = pv.VolumeFractionsAttribute()
    fractions.add_expression("x", mats.id("blue"))
    fractions.add_value(0.25, mats.id("red"))
    assert {m.name: f for m, f in fractions.sample(0.5, 0, 0, 0).items()} == {"blue": 0.5, "red": 0.25}
    assert isinstance(fractions, pv.Attribute) and fractions.return_type() is pv.Attribute.ReturnType.vfm_ptr
    assert pv.DefaultAttributes.COLOR_RGBA_TYPE is pv.Attribute.ReturnType.vec4
    assert pv.DefaultAttributes.TOUGHNSS_TYPE is pv.DefaultAttributes.get_return_type_by_name("modulus")
    assert pv.DefaultAttributes.get_return_type_by_name("volume_fractions") is pv.Attribute.ReturnType.vfm_ptr


def test_converters_convert_one_point_of_samples():
    from fgslice.compat import pyvcad as pv

    table = pv.LookupTableConverter(["temperature"], ["flow_rate", "color_rgb"], [
        pv.LookupTableEntry(220, [1.4, pv.Vec3(0, 0, 1)]), pv.LookupTableEntry(240, [0.8, pv.Vec3(1, 0, 0)])],
        pv.InterpolationMode.LINEAR)
    samples = pv.AttributeSamples()
    samples.set_sample(pv.DefaultAttributes.TEMPERATURE, 235)
    out = table.convert(samples)
    assert out.get_sample("flow_rate") == pytest.approx(0.95) and tuple(out.get_sample("color_rgb")) == pytest.approx(
        (0.75, 0, 0.25))
    assert out.get_type("color_rgb") is pv.Attribute.ReturnType.vec3 and not out.has_sample("temperature")
    assert table.required_attributes() == ["temperature"] and table.clone().output_attributes() == ["flow_rate", "color_rgb"]
    expression = pv.ExpressionConverter(["hu"], ["modulus", "toughness"], ["hu * 1000 + 500", "0.5 * hu + 10"])
    samples.set_sample("hu", 2.0)
    assert expression.convert(samples).get_sample("toughness") == 11.0


PYTHON_CONVERTER = """
    class FoamFlow(pv.AttributeConverterBase):
        def __init__(self):
            super().__init__()

        def required_attributes(self):
            return [pv.DefaultAttributes.TEMPERATURE]

        def output_attributes(self):
            return [pv.DefaultAttributes.FLOW_RATE]

        def convert(self, samples):
            t = samples.get_sample(pv.DefaultAttributes.TEMPERATURE)
            out = pv.AttributeSamples()
            out.set_sample(pv.DefaultAttributes.FLOW_RATE, 1.3 if t < 205 else 0.9)
            return out

    bar = pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(40, 10, 2))
    bar.set_attribute(pv.DefaultAttributes.TEMPERATURE, pv.FloatAttribute("200 + x / 2"))
    root = pv.AttributeModifier(FoamFlow(), bar)
"""


def test_a_python_converter_derives_the_flow_that_scales_each_segment_s_extrusion(tmp_path):
    design = _design(tmp_path, PYTHON_CONVERTER)
    np.testing.assert_allclose(_values(design, "flow", [-15, 9, 11, 15], [0] * 4, [0] * 4), [130, 130, 90, 90])
    settings, program, stats = _slice(design, tmp_path, profile="foam-lwpla", layer_height=0.4)
    printed = (program.e > 0) & (program.length > 2) & (program.layer > 0)
    x = ((program.start + program.end) / 2)[printed, 0] - stats["placement_offset"][0]
    per_mm = program.e[printed] / program.length[printed]
    cool, hot = np.median(per_mm[x < 5]), np.median(per_mm[x > 15])  # 205 C at x = 10
    assert cool / hot == pytest.approx(1.3 / 0.9, rel=0.03)


RESOLVED = """
    import pyvcad_attribute_resolver as resolver
    resolver.clear_conversions()
    table = [(0.3, 240), (0.6, 220), (1.0, 200)]
    resolver.register_conversion("density", "temperature", lambda: pv.LookupTableConverter(
        ["density"], ["temperature"], [pv.LookupTableEntry(d, t) for d, t in table], pv.InterpolationMode.LINEAR),
        tags=["lw_pla"])
    resolver.register_conversion("temperature", "flow_rate", lambda: pv.ExpressionConverter(
        ["temperature"], ["flow_rate"], ["1 - (temperature - 200) / 100"]), tags=["lw_pla"])
    resolver.register_conversion("density", "flow_rate", lambda: pv.ExpressionConverter(
        ["density"], ["flow_rate"], ["density"]), name="direct", tags=["other"])
    bar = pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(60, 12, 3))
    bar.set_attribute(pv.DefaultAttributes.DENSITY, pv.FloatAttribute("0.65 + x / 85.7"))
    root = resolver.adapt(bar, [pv.DefaultAttributes.TEMPERATURE, pv.DefaultAttributes.FLOW_RATE], tags=["lw_pla"])
    assert bar.attribute_list() == ["density"]
    assert sorted(root.attribute_list()) == ["density", "flow_rate", "temperature"]
"""


def test_the_attribute_resolver_chains_registered_conversions_to_what_the_machine_needs(tmp_path):
    design = _design(tmp_path, RESOLVED)
    x = np.array([-25.0, 0.0, 25.0])
    density = 0.65 + x / 85.7
    t = np.interp(density, [0.3, 0.6, 1.0], [240, 220, 200])
    np.testing.assert_allclose(_values(design, "temperature", x, 0 * x, 0 * x), t)
    np.testing.assert_allclose(_values(design, "flow", x, 0 * x, 0 * x), 100 * (1 - (t - 200) / 100))
    _, program, _ = _slice(design, tmp_path, profile="foam-lwpla", layer_height=0.3)
    targets = [e.target for e in program.temperatures if e.command == "M104" and e.target > 0]
    assert min(targets) <= 212 and max(targets) >= 220  # 209 .. 222 C over the bar, 5 C levels


AMBIGUOUS = """
    import pyvcad_attribute_resolver as resolver
    resolver.clear_conversions()
    for name, factor in [("fast", 1.0), ("slow", 0.5)]:
        resolver.register_conversion("density", "flow_rate", lambda f=factor: pv.ExpressionConverter(
            ["density"], ["flow_rate"], [str(f) + " * density"]), name=name{priority})
    bar = pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(20, 10, 2))
    bar.set_attribute(pv.DefaultAttributes.DENSITY, pv.FloatAttribute(0.8))
    root = resolver.adapt(bar, ["{target}"])
"""


@pytest.mark.parametrize("code,message", [
    (AMBIGUOUS.format(priority="", target="flow_rate"), "2 chains of equal priority reach 'flow_rate': fast; slow"),
    (AMBIGUOUS.format(priority="", target="infill_density"), "no chain of registered conversions reaches "
                                                             "'infill_density' from the design's attributes (density)"),
    ("import pyvcad_attribute_resolver as r\nr.register_foaming_conversions()", "its documentation does not publish"),
])
def test_the_attribute_resolver_refuses_ambiguous_missing_and_bundled_conversions(tmp_path, code, message):
    with pytest.raises(FgsliceError, match=re.escape(message)):
        _design(tmp_path, code)


def test_the_attribute_resolver_prefers_the_higher_priority(tmp_path):
    design = _design(tmp_path, AMBIGUOUS.format(priority=", priority=1 if name == 'slow' else 0", target="flow_rate"))
    np.testing.assert_allclose(_values(design, "flow", [0.0], [0.0], [0.0]), [40.0])


def test_mapped_lattices_are_the_metamaterial_builders_and_from_min_and_max_spans_its_corners(tmp_path):
    mapped = _design(tmp_path, """
        import pyvcad_metamaterials as mm
        box = pv.RectPrism.FromMinAndMax(pv.Vec3(-12, -12, 0), pv.Vec3(12, 12, 8))
        cells = mm.rectangular_cell_map((pv.Vec3(-12, -12, 0), pv.Vec3(12, 12, 8)), cells=(3, 3, 1))
        sheet = pv.MappedImplicitLattice(cells, pv.ImplicitUnitCell.standard("gyroid"), "sheet", 1.2)
        root = pv.Union(sheet, pv.Translate(40, 0, 0, box))
    """)
    built = _design(tmp_path, """
        import pyvcad_metamaterials as mm
        cells = mm.rectangular_cell_map((pv.Vec3(-12, -12, 0), pv.Vec3(12, 12, 8)), cells=(3, 3, 1))
        root = pv.Union(mm.gyroid(cells, wall_thickness=1.2), pv.RectPrism(pv.Vec3(40, 0, 4), pv.Vec3(24, 24, 8)))
    """)
    for a, b in zip(mapped.sections([1.0, 4.5]), built.sections([1.0, 4.5])):
        assert a.area == pytest.approx(b.area, rel=1e-9) and a.area > 24 * 24 + 24 * 24 * 0.2
    np.testing.assert_allclose(mapped.bounds(), built.bounds())


def test_a_mapped_graph_lattice_is_the_graph_lattice_of_its_cell(tmp_path):
    cell = textwrap.dedent("""
        import pyvcad_metamaterials as mm
        cells = mm.rectangular_cell_map((pv.Vec3(0, 0, 0), pv.Vec3(20, 20, 10)), cells=(2, 2, 1))
        cell = pv.GraphUnitCell([pv.Vec3(0, 0, 0), pv.Vec3(1, 1, 1), pv.Vec3(1, 0, 0)], [(0, 1), (0, 2)])
    """)
    mapped = _design(tmp_path, cell + "root = pv.MappedGraphLattice(cells, cell, 0.8)\n")
    built = _design(tmp_path, cell + "root = mm.graph_lattice(cells, cell, beam_radius=0.8)\n")
    for a, b in zip(mapped.sections([2.0, 7.0]), built.sections([2.0, 7.0])):
        assert a.area == pytest.approx(b.area, rel=1e-9) and a.area > 0
    with pytest.raises(FgsliceError, match="unit_cell is a pv.GraphUnitCell"):
        _design(tmp_path, cell + "root = pv.MappedGraphLattice(cells, 'octet', 0.8)\n")


def test_a_python_converter_computing_with_arrays_is_called_once_and_a_branching_one_per_point():
    from fgslice.compat import pyvcad as pv
    from fgslice.compat.pyvcad_v3_samples import convert_per_point

    calls = []

    def with_numpy(samples):
        calls.append("numpy")
        out = pv.AttributeSamples()
        out.set_sample("modulus", np.sqrt(samples.get_sample("density")) * 10)
        return out

    def branching(samples):
        calls.append("branch")
        out = pv.AttributeSamples()
        out.set_sample("modulus", 1.0 if samples.get_sample("density") < 0.5 else 2.0)
        return out

    density = np.array([0.1, 0.4, np.nan, 0.6, 0.9])
    (modulus,) = convert_per_point(with_numpy, ["density"], ["modulus"], [1], "Numpy")([density])
    np.testing.assert_allclose(modulus, 10 * np.sqrt(density))
    (step,) = convert_per_point(branching, ["density"], ["modulus"], [1], "Branch")([density])
    np.testing.assert_allclose(step, [1, 1, np.nan, 2, 2])
    # numpy: one call on the arrays; branching: a failed array call, then one per defined point
    assert calls == ["numpy", "branch"] + ["branch"] * 4
