"""OpenVCAD's Blend (2 and 3), Convolve and Sum: mixtures and attributes at points against
the documented formulas, the sum's solid against its analytic shape, and bad arguments
named."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fgslice.compat.script import load_script
from fgslice.design.attributes import attribute_fields
from fgslice.design.blend import LATTICE_POINTS
from fgslice.design.convolve import box_stencil, kernel_stencil
from fgslice.errors import DesignError
from fgslice.machine.gcode_reader import read_gcode
from fgslice.pipeline import slice_to_gcode
from fgslice.settings import load_settings

HEADER = "import pyvcad as pv\nimport pyvcad_rendering as viz\nmaterials = pv.default_materials\n"
BLOCKS = """a = pv.RectPrism(pv.Vec3(-20, 0, 0), pv.Vec3(40, 20, 20), materials.id("red"))
b = pv.RectPrism(pv.Vec3(20, 0, 0), pv.Vec3(40, 20, 20), materials.id("blue"))
pair = pv.Union(False, [a, b])
"""
STEP_BAR = """bar = pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(60, 10, 10))
bar.set_attribute(pv.DefaultAttributes.TEMPERATURE, pv.FloatAttribute("x > 0 ? 240 : 200"))
"""


def _load(tmp_path, body: str):
    path = tmp_path / "design.py"
    path.write_text(HEADER + "\n".join(line.strip() for line in body.splitlines()) + "\n", encoding="utf-8")
    return load_script(path)


def _box_mean_of_step(x, r):
    """Share of a box ``[x - r, x + r]`` below 0: OpenVCAD's blend of two touching blocks."""
    return np.clip(0.5 - x / (2 * r), 0.0, 1.0)


def _triangle_mean_of_step(x, r):
    """Share below 0 of the sum of two uniform offsets on [-r, r] around ``x`` (two box passes)."""
    s = -np.asarray(x, dtype=float)  # P(offset < -x)
    t = (s + 2 * r) / (2 * r)  # the sum of two U(0, 1) below t
    return np.where(t <= 0, 0.0, np.where(t >= 2, 1.0, np.where(t <= 1, t * t / 2, 1 - (2 - t) ** 2 / 2)))


def test_openvcad2_blend_mixes_two_blocks_as_the_box_mean(tmp_path):
    design = _load(tmp_path, BLOCKS + "root = pv.Blend(5, pair)")
    x = np.linspace(-7, 7, 29)
    red = design.fractions(x, np.full_like(x, 2.0), np.full_like(x, -3.0))[:, 0]
    np.testing.assert_allclose(red, _box_mean_of_step(x, 5), atol=1 / LATTICE_POINTS + 1e-9)
    lo, hi = design.bounds()
    np.testing.assert_allclose((lo, hi), ((-40, -10, -10), (40, 10, 10)))


def test_openvcad3_blend_blurs_an_attribute_and_the_materials(tmp_path):
    design = _load(tmp_path, STEP_BAR + "root = pv.Blend(bar, [pv.DefaultAttributes.TEMPERATURE], [4.0, 0.0, 0.0], 2)")
    x = np.linspace(-10, 10, 41)
    t = attribute_fields(design).values("temperature", x, 0 * x, 0 * x)
    np.testing.assert_allclose(t, 240 - 40 * _triangle_mean_of_step(x, 4.0), atol=40 * 2 / LATTICE_POINTS)
    mixed = _load(tmp_path, BLOCKS + "root = pv.Blend(pair, [pv.DefaultAttributes.VOLUME_FRACTIONS], [3.0, 3.0, 3.0])")
    red = mixed.fractions(x, 0 * x, 0 * x)[:, 0]
    np.testing.assert_allclose(red, _box_mean_of_step(x, 3.0), atol=1 / LATTICE_POINTS + 1e-9)


def test_blend_counts_only_the_inside_of_the_part(tmp_path):
    design = _load(tmp_path, """bar = pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(60, 10, 10))
    bar.set_attribute(pv.DefaultAttributes.TEMPERATURE, pv.FloatAttribute("200 + x"))
    root = pv.Blend(bar, [], [6.0, 0.0, 0.0])""")
    x = np.array([-29.0, 0.0, 10.0, 27.0])
    t = attribute_fields(design).values("temperature", x, 0 * x, 0 * x)
    # a linear field keeps its value where the box lies inside; at an end, the mean of the part's half-box
    expected = 200 + np.array([(-30 + (-23)) / 2, 0.0, 10.0, (21 + 30) / 2])
    np.testing.assert_allclose(t, expected, atol=0.05)


def test_convolve_takes_the_kernels_weighted_mean(tmp_path):
    design = _load(tmp_path, """bar = pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(60, 10, 10))
    bar.set_attribute(pv.DefaultAttributes.TEMPERATURE, pv.FloatAttribute("200 + x + 2 * y"))
    skewed = pv.Convolve(bar, [pv.DefaultAttributes.TEMPERATURE], pv.CustomKernel([1, 0, 3], 1, 0, 0), [2.0, 0, 0])
    box = pv.Convolve(bar, [], pv.BoxKernel(1), [1.0, 1.0, 1.0])
    root = pv.Union(False, [pv.Translate(0, 30, 0, skewed), pv.Translate(0, -30, 0, box)])""")
    fields = attribute_fields(design)
    x = np.array([-10.0, 0.0, 10.0])
    # weights 1 at -2 mm and 3 at +2 mm along x: the mean is the field 1 mm further along x
    np.testing.assert_allclose(fields.values("temperature", x, 30 + 0 * x, 0 * x), 200 + x + 1)
    np.testing.assert_allclose(fields.values("temperature", x, -30 + 0 * x, 0 * x), 200 + x)  # linear: unchanged
    offsets, weights = kernel_stencil(np.ones((3, 1, 5)), (1.0, 7.0, 2.0))
    assert offsets.shape == (15, 3) and weights.sum() == pytest.approx(1.0)
    np.testing.assert_allclose((offsets.min(axis=0), offsets.max(axis=0)), ((-1, 0, -2), (1, 0, 2)))


def test_box_stencil_is_the_sum_of_passes_uniform_offsets():
    for passes in (1, 3):
        offsets, weights = box_stencil((2.0, 0.0, 5.0), passes)
        assert np.abs(offsets[:, 0]).max() <= 2.0 * passes and not offsets[:, 1].any()
        assert np.var(offsets[:, 2]) == pytest.approx(passes * 10.0**2 / 12, rel=0.01)  # n U(-5, 5): n * 100 / 12
        assert weights.sum() == pytest.approx(1.0)


def test_sum_is_the_solid_where_the_distances_add_up_to_the_iso_value(tmp_path):
    design = _load(tmp_path, """left = pv.Sphere(pv.Vec3(-4, 0, 0), 5, materials.id("red"))
    right = pv.Sphere(pv.Vec3(4, 0, 0), 5, materials.id("blue"))
    root = pv.Sum(2.0, [left, right])""")
    # |p - c1| + |p - c2| <= 12: an ellipsoid with foci at x = +-4, semi-axes 6 and sqrt(36 - 16)
    a, b = 6.0, math.sqrt(20.0)
    for z in (0.0, 2.5):
        shrink = math.sqrt(1 - z * z / (b * b))
        assert design.section(z).area == pytest.approx(math.pi * a * b * shrink**2, rel=3e-3)
    lo, hi = design.bounds()
    assert lo[0] <= -a and hi[0] >= a and lo[1] <= -b and hi[1] >= b
    red = design.fractions(np.array([-3.0, 3.0]), np.zeros(2), np.zeros(2))[:, 0]
    np.testing.assert_allclose(red, [1.0, 0.0])  # each point to the child containing it, as a union's


@pytest.mark.parametrize("body, message", [
    ("root = pv.Blend(-2, pv.Sphere(pv.Vec3(0, 0, 0), 5))", "Blend: radius must be positive, got -2"),
    ("root = pv.Blend(pv.Sphere(pv.Vec3(0, 0, 0), 5), [], [1, 2])", r"Blend: physical_radius is \[rx, ry, rz\]"),
    ("root = pv.Blend(pv.Sphere(pv.Vec3(0, 0, 0), 5), [], 2.0, 0)", "Blend: num_passes is a whole number"),
    ("root = pv.Blend(pv.Sphere(pv.Vec3(0, 0, 0), 5), ['temperature'], 2.0)", "Blend: the child has none of the "
     "attributes temperature"),
    ("root = pv.Convolve(pv.Sphere(pv.Vec3(0, 0, 0), 5), [], [[1]], 2.0)", "Convolve: kernel is a pv.BoxKernel"),
    ("root = pv.Convolve(pv.Sphere(pv.Vec3(0, 0, 0), 5), [], pv.CustomKernel([-1, 0, 1], 1, 0, 0), 2.0)",
     "Convolve: the kernel's weights sum to 0"),
    ("k = pv.CustomKernel([1, 2], 1, 0, 0)", "CustomKernel: 2 weights for a 3 x 1 x 1 kernel"),
    ("k = pv.BoxKernel(1.5)", "BoxKernel: rx is a whole number"),
    ("root = pv.Convolution(pv.Convolution.BlendKernel(3, 3, 3), pv.Sphere(pv.Vec3(0, 0, 0), 5))",
     "Convolution is not supported by fgslice: its kernel is counted in voxels"),
    ("root = pv.Sum('iso', [])", "Sum: iso_value must be a number"),
    ("root = pv.Sum(0.0, [1, 2])", "Sum: a child must be a pyvcad node"),
    ("root = pv.Sum(1.0)", "Sum has no children"),
])
def test_bad_arguments_name_the_class_and_argument(tmp_path, body, message):
    path = tmp_path / "design.py"
    path.write_text(HEADER + body + "\n", encoding="utf-8")
    with pytest.raises(DesignError, match=message) as caught:
        load_script(path)
    assert caught.value.line == 4


def test_a_blended_temperature_step_is_commanded_along_the_bar(tmp_path):
    design = _load(tmp_path, """bar = pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(60, 12, 4))
    bar.set_attribute(pv.DefaultAttributes.TEMPERATURE, pv.FloatAttribute("x > 0 ? 250 : 220"))
    root = pv.Blend(bar, [pv.DefaultAttributes.TEMPERATURE], [6.0, 0.0, 0.0])""")
    out = tmp_path / "bar.gcode"
    settings = load_settings("foam-lwpla", {})
    slice_to_gcode(design, settings, out, jobs=1)
    program = read_gcode(out)
    printed = (program.e > 0) & (program.length > 0) & (program.layer > 0)
    start, end = program.start[printed, 0], program.end[printed, 0]
    centre = (min(start.min(), end.min()) + max(start.max(), end.max())) / 2
    lo, hi = np.minimum(start, end) - centre, np.maximum(start, end) - centre
    temperature = np.array([program.states[s].temperature for s in program.state[printed]])
    assert set(temperature[hi < -6.5]) == {220} and set(temperature[lo > 6.5]) == {250}
    ramp = (lo > -6) & (hi < 6)
    field = 220 + 30 * np.clip(0.5 + (lo + hi)[ramp] / 2 / 12, 0, 1)  # the box mean over +-6 mm
    assert len(np.unique(temperature[ramp])) >= 5
    assert np.abs(temperature[ramp] - field).max() <= settings.temperature_step + 0.5


def test_blurring_an_attribute_leaves_the_materials_where_they_are(tmp_path):
    design = _load(tmp_path, """bar = pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(60, 10, 10))
    bar.set_attribute(pv.DefaultAttributes.VOLUME_FRACTIONS, pv.VolumeFractionsAttribute(
    [("0.5 + x / 60", materials.id("red")), ("0.5 - x / 60", materials.id("blue"))]))
    bar.set_attribute(pv.DefaultAttributes.TEMPERATURE, pv.FloatAttribute("200 + x"))
    root = pv.Translate(10, 0, 0, pv.Blend(bar, [pv.DefaultAttributes.TEMPERATURE], [5.0, 0.0, 0.0]))""")
    x = np.array([-15.0, 10.0, 30.0])
    red = design.fractions(x, 0 * x, 0 * x)[:, 0]
    np.testing.assert_allclose(red, 0.5 + (x - 10) / 60)
    np.testing.assert_allclose(attribute_fields(design).values("temperature", x, 0 * x, 0 * x), 200 + x - 10)
