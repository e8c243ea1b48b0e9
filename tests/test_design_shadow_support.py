"""Inkjet-style support (OpenVCAD's ``SupportAnalyzer``): the model's vertical shadow."""

from __future__ import annotations

import math
import textwrap

import numpy as np
import pytest

from fgslice.compat.script import load_script
from fgslice.design import api
from fgslice.design.shadow_support import ShadowSupport
from fgslice.design.support_bodies import split_support_bodies
from fgslice.errors import DesignError
from fgslice.machine.gcode_header import read_header
from fgslice.machine.gcode_reader import read_gcode
from fgslice.pipeline import slice_to_gcode
from fgslice.settings import load_settings
from fgslice.slicing.palette import Palette


def test_a_spheres_support_is_the_cylinder_below_its_equator_minus_the_lower_hemisphere():
    r = 10.0
    support = ShadowSupport(api.sphere(r, "blue"), 0.027, "support")
    lo, hi = support.bounds()
    np.testing.assert_allclose(lo, (-r, -r, -r), atol=0.01)
    np.testing.assert_allclose(hi, (r, r, 0.0), atol=0.11)
    for z in (-9.0, -5.0, -1.0):
        section = support.section(z, 0.1)
        assert section.area == pytest.approx(math.pi * z * z, rel=0.01)  # annulus from sqrt(r^2 - z^2) to r
        assert section.convex_hull.area == pytest.approx(math.pi * r * r, rel=0.01)
    assert support.section(0.5, 0.1).is_empty and support.section(5.0, 0.1).is_empty
    dz = 0.1
    heights = np.arange(-r + dz / 2, 0.0, dz)
    volume = sum(s.area for s in support.sections(list(heights), 0.1)) * dz
    assert volume == pytest.approx(math.pi * r**3 / 3, rel=0.01)  # cylinder r^2 h minus the hemisphere


def test_its_distance_has_the_sign_of_the_analytic_shadow():
    r = 10.0
    support = ShadowSupport(api.sphere(r, "blue"), 0.2, "support")
    x, y, z = np.random.default_rng(7).uniform(-12, 12, (3, 4000))
    truth = (np.hypot(x, y) <= r) & (z >= -r) & (z <= 0) & (np.sqrt(x * x + y * y + z * z) > r)
    near = np.abs(np.sqrt(x * x + y * y + z * z) - r) < 0.2
    near |= np.abs(np.hypot(x, y) - r) < 0.2
    near |= np.abs(z) < 0.2
    assert np.array_equal((support.sdf(x, y, z) <= 0)[~near], truth[~near])
    plane = np.full(x.shape, -4.0)  # a plane's points, from the section
    truth = (np.hypot(x, y) <= r) & (np.hypot(x, y) > math.sqrt(r * r - 16))
    assert np.mean((support.sdf(x, y, plane) <= 0) != truth) < 0.005


def test_an_overhanging_top_is_supported_down_to_the_models_lowest_point():
    post = api.translate((0, 0, 4), api.cylinder(2, 8, "blue"))
    top = api.translate((6, 0, 9), api.rectprism(20, 10, 2, "blue"))
    support = ShadowSupport(api.union(post, top), 0.2, "support")
    lo, hi = support.bounds()
    np.testing.assert_allclose(lo, (-4, -5, 0), atol=0.01)
    np.testing.assert_allclose(hi, (16, 5, 8), atol=0.11)
    for z in (0.5, 4.0, 7.5):
        assert support.section(z, 0.1).area == pytest.approx(200 - math.pi * 4, rel=0.005)
    assert support.section(9.0, 0.1).is_empty


HEADER = "import pyvcad as pv\nimport pyvcad_rendering as viz\nmaterials = pv.default_materials\n"


def _script(tmp_path, body: str):
    path = tmp_path / "design.py"
    path.write_text(HEADER + textwrap.dedent(body) + "\n", encoding="utf-8")
    return path


ANALYZED = """
    blue, support = materials.id("blue"), materials.id("{material}")
    ball = pv.Sphere(pv.Vec3(0, 0, 0), {r}, blue)
    shadow = pv.SupportAnalyzerParallel(ball, pv.Vec3(0.0423, 0.0846, 0.027), support).analyze()
    viz.Render(pv.Union(False, [ball, shadow]), materials)
"""


def test_in_a_part_material_the_support_prints_as_that_material_under_the_overhang(tmp_path):
    r = 6.0
    design = load_script(_script(tmp_path, ANALYZED.format(material="green", r=r)))
    assert [m.name for m in design.materials] == ["blue", "green"]
    settings = load_settings(None, {"colors": "2", "skirt_loops": "0"})
    out = tmp_path / "support.gcode"
    slice_to_gcode(design, settings, out, jobs=1)
    program = read_gcode(out)
    moves = (program.e > 0) & (program.length > 0)
    mid = (program.start[moves] + program.end[moves]) / 2 - np.array(read_header(out).placement_offset)
    mid[:, 2] -= settings.layer_height / 2
    colors = program.color_of_moves()[moves]
    blue, green = Palette(2, 2).color_of(np.eye(2))
    rho, z = np.hypot(mid[:, 0], mid[:, 1]), mid[:, 2]
    surface = np.sqrt(np.maximum(r * r - z * z, 0.0))
    in_support = (z < -0.5) & (rho > surface + 0.6) & (rho < r - 0.6)
    in_ball = rho < surface - 0.6
    assert in_support.sum() > 50 and in_ball.sum() > 50
    assert np.mean(colors[in_support] == green) > 0.95
    assert np.mean(colors[in_ball] == blue) > 0.95
    assert z[colors == green].max() < 0.5  # no support above the equator
    assert rho[colors == green].max() < r + 0.1  # nor beside the ball


def test_in_openvcads_support_material_it_is_a_support_body(tmp_path):
    design = load_script(_script(tmp_path, ANALYZED.format(material="support", r=6.0)))
    bodies = split_support_bodies(design)
    assert [m.name for m in bodies.part.materials] == ["blue"]
    lo, hi = bodies.enforcers.bounds()
    np.testing.assert_allclose(lo, (-6, -6, -6), atol=0.01)
    np.testing.assert_allclose(hi, (6, 6, 0), atol=0.11)
    assert bodies.enforcers.section(-4.0).area == pytest.approx(math.pi * 16, rel=0.01)


@pytest.mark.parametrize("arguments, message", [
    ("ball, pv.Vec3(0, 0.1, 0.1), 1", r"SupportAnalyzer: voxel_size must be positive"),
    ("ball, 0.1, 1", r"SupportAnalyzer: voxel_size must be a pyvcad.Vec3"),
    ("42, pv.Vec3(0.1, 0.1, 0.1)", r"SupportAnalyzer: a child must be a pyvcad node"),
])
def test_bad_arguments_are_refused_by_name(tmp_path, arguments, message):
    path = _script(tmp_path, f"""
        ball = pv.Sphere(pv.Vec3(0, 0, 0), 5, 1)
        pv.SupportAnalyzer({arguments})
        viz.Render(ball, materials)
    """)
    with pytest.raises(DesignError, match=message):
        load_script(path)
