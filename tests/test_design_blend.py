"""``blend()``: the child's geometry with its fractions averaged over a box."""

from __future__ import annotations

import numpy as np
import pytest

from fgslice.design import api, parse_design
from fgslice.design.blend import LATTICE_POINTS
from fgslice.errors import DesignError
from fgslice.machine.gcode_header import read_header
from fgslice.machine.gcode_reader import read_gcode
from fgslice.pipeline import slice_to_gcode
from fgslice.settings import load_settings
from fgslice.slicing.palette import Palette

TOUCHING = """blend({size}) {{ union() {{
    translate(-20, 0, 0) {{ rectprism((40, 40, 40), "red"); }}
    translate(20, 0, 0) {{ rectprism((40, 40, 40), "blue"); }}
}} }}"""


def _ramp(u, width):
    """Exact mean of a unit step at 0 over a window of ``width`` centred at ``u``."""
    return np.clip(0.5 - u / width, 0.0, 1.0)


def test_two_touching_boxes_cross_fade_as_the_analytic_ramp():
    design = parse_design(TOUCHING.format(size="10, 10, 10"))
    x = np.linspace(-8, 8, 33)
    f = design.fractions(x, np.full_like(x, 3.0), np.full_like(x, -2.0))
    np.testing.assert_allclose(f[:, 0], _ramp(x, 10), atol=1 / LATTICE_POINTS + 1e-9)
    np.testing.assert_allclose(f.sum(axis=1), 1.0)


def test_each_axis_has_its_own_width():
    rotated = """blend(2, 12, 4) { union() {
        translate(0, -20, 0) { rectprism((40, 40, 40), "red"); }
        translate(0, 20, 0) { rectprism((40, 40, 40), "blue"); }
    } }"""
    design = parse_design(rotated)
    y = np.linspace(-7, 7, 29)
    f = design.fractions(np.zeros_like(y), y, np.zeros_like(y))
    np.testing.assert_allclose(f[:, 0], _ramp(y, 12), atol=1 / LATTICE_POINTS + 1e-9)


def test_a_plane_at_an_angle_is_averaged_within_the_stated_accuracy():
    # the half-space n.p < 0 with n = (1, 1, 0)/sqrt(2): the mean over a cube of side s is
    # the convolution of two uniform windows of width s/sqrt(2), a piecewise quadratic
    design = api.design(api.blend(8, api.fgrade(["x + y < 0", "x + y >= 0"], ["red", "blue"],
                                                api.cube(60), mode="thresh")))
    u = np.linspace(-6, 6, 25)
    x = y = u / np.sqrt(2)
    f = design.fractions(x, y, np.zeros_like(u))[:, 0]
    a = 8 / np.sqrt(2)
    t = np.clip(u, -a, a)
    exact = np.where(t < 0, 1 - (a + t) ** 2 / (2 * a * a), (a - t) ** 2 / (2 * a * a))
    assert np.abs(f - exact).max() < 0.05


def test_a_linear_field_is_unchanged_and_the_geometry_is_the_childs():
    graded = api.fgrade(["x/40 + 0.5", "0.5 - x/40"], ["red", "blue"], api.rectprism(40, 20, 4))
    plain, blended = api.design(graded), api.design(api.blend((6, 6, 2), graded))
    x = np.linspace(-15, 15, 31)
    np.testing.assert_allclose(blended.fractions(x, 0.0, 0.0), plain.fractions(x, 0.0, 0.0), atol=1e-12)
    assert blended.section(0.5).equals(plain.section(0.5))
    assert blended.bounds() == plain.bounds()
    np.testing.assert_allclose(blended.sdf(x, 3.0, 0.0), plain.sdf(x, 3.0, 0.0))


def test_the_forms_of_the_sizes_agree_and_bad_sizes_are_refused():
    one = parse_design(TOUCHING.format(size="10"))
    three = parse_design(TOUCHING.format(size="10, 10, 10"))
    vector = parse_design(TOUCHING.format(size="(10, 10, 10)"))
    x = np.linspace(-6, 6, 7)
    for other in (three, vector):
        np.testing.assert_array_equal(one.fractions(x, 0.0, 0.0), other.fractions(x, 0.0, 0.0))
    with pytest.raises(DesignError, match="blend: sizes must be >= 0") as info:
        parse_design(TOUCHING.format(size="10, -1, 10"))
    assert info.value.line == 1
    with pytest.raises(DesignError, match="blend takes"):
        parse_design(TOUCHING.format(size="10, 10"))
    with pytest.raises(DesignError, match="blend: sizes"):
        api.blend(0, api.cube(1))


def test_a_blended_part_prints_the_averaged_mixture(tmp_path):
    text = """blend(8, 8, 8) { union() {
        translate(-10, 0, 1) { rectprism((20, 10, 2), "red"); }
        translate(10, 0, 1) { rectprism((20, 10, 2), "blue"); }
    } }"""
    design = parse_design(text)
    settings = load_settings(None, {"colors": "4", "skirt_loops": "0"})
    out = tmp_path / "blend.gcode"
    slice_to_gcode(design, settings, out, jobs=1)
    program = read_gcode(out)
    offset = np.array(read_header(out).placement_offset)
    moves = (program.e > 0) & (program.length > 0)
    mid = (program.start[moves] + program.end[moves]) / 2 - offset
    mid[:, 2] -= settings.layer_height / 2
    expected = Palette(2, 4).color_of(np.column_stack([_ramp(mid[:, 0], 8), 1 - _ramp(mid[:, 0], 8)]))
    commanded = program.color_of_moves()[moves]
    assert np.mean(commanded == expected) > 0.9
    assert set(np.unique(commanded)) == {0, 1, 2, 3}
    filament = np.pi * settings.filament_diameter**2 / 4
    assert program.e[moves].sum() * filament == pytest.approx(40 * 10 * 2, rel=0.03)


def test_a_child_of_one_material_is_left_as_it_is():
    design = parse_design('blend(5) { translate(1, 0, 0) { sphere(3, "red"); } }')
    np.testing.assert_array_equal(design.fractions(np.array([0.0, 3.9]), 0.0, 0.0), [[1.0], [1.0]])
    assert design.section(0.0).area == pytest.approx(np.pi * 9, rel=1e-3)


def test_the_stencil_averages_planar_steps_within_the_stated_accuracy():
    from fgslice.design.blend import _unit_stencil

    stencil = _unit_stencil()
    t = (np.arange(96) + 0.5) / 96 - 0.5
    reference = np.stack(np.meshgrid(t, t, t, indexing="ij"), -1).reshape(-1, 3)
    rng = np.random.default_rng(3)
    normals = rng.normal(size=(40, 3))
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    offsets = rng.uniform(-0.4, 0.4, 40)
    errors = [abs((stencil @ n < c).mean() - (reference @ n < c).mean()) for n, c in zip(normals, offsets)]
    assert max(errors) < 0.05 and np.mean(errors) < 0.01
    for axis in range(3):  # each axis sees the midpoints of 512 equal cells
        np.testing.assert_allclose(np.sort(stencil[:, axis]), (np.arange(LATTICE_POINTS) + 0.5) / LATTICE_POINTS - 0.5)


def test_a_size_beyond_the_part_averages_over_the_parts_whole_extent():
    """blend(1e6) on parts 80 x 40 x 40 mm: every axis spans the children's box, so every
    point gets the box's mean (the red part fills 3/4 of it), the same as a blend of
    exactly the extent; one axis beyond the extent averages over it alone."""
    uneven = """blend({size}) {{ union() {{
        translate(-10, 0, 0) {{ rectprism((60, 40, 40), "red"); }}
        translate(30, 0, 0) {{ rectprism((20, 40, 40), "blue"); }}
    }} }}"""
    huge = parse_design(uneven.format(size="1e6"))
    exact = parse_design(uneven.format(size="80, 40, 40"))
    rng = np.random.default_rng(4)
    points = rng.uniform([-60, -30, -30], [60, 30, 30], (500, 3)).T
    red = huge.fractions(*points)[:, 0]
    assert np.allclose(red, 0.75, atol=1e-12)
    assert np.array_equal(huge.fractions(*points), exact.fractions(*points))
    along_x = parse_design(uneven.format(size="1e6, 0, 0"))
    assert np.allclose(along_x.fractions(*points)[:, 0], 0.75, atol=1e-12)
    below = parse_design(uneven.format(size="79, 40, 40"))  # not the whole extent: a ramp
    x = np.array([-38.0, 18.0])
    assert np.ptp(below.fractions(x, 0.0, 0.0)[:, 0]) > 0.2


def test_a_child_of_meshes_is_averaged_on_a_grid_within_its_accuracy_of_the_lattice_rule(tmp_path):
    import trimesh

    from fgslice.design.blend_grid import CELLS

    for name, x0 in (("left", -10.0), ("right", 10.0)):
        trimesh.creation.box((20, 10, 2), trimesh.transformations.translation_matrix((x0, 0, 1))).export(
            tmp_path / f"{name}.stl")
    meshes = api.blend(8, api.union(api.mesh(tmp_path / "left.stl", "red"), api.mesh(tmp_path / "right.stl", "blue")))
    boxes = api.blend(8, api.union(api.translate((-10, 0, 1), api.rectprism(20, 10, 2, "red")),
                                   api.translate((10, 0, 1), api.rectprism(20, 10, 2, "blue"))))
    assert meshes._gridded and not boxes._gridded
    gridded, exact = api.design(meshes), api.design(boxes)
    rng = np.random.default_rng(3)
    x, y, z = rng.uniform((-20, -5, 0), (20, 5, 2), (400, 3)).T
    x[:100] = rng.uniform(-5, 5, 100)  # across the ramp
    np.testing.assert_allclose(gridded.fractions(x, y, z), exact.fractions(x, y, z), atol=1 / CELLS)
    plane = np.full(x.shape, 1.0)  # a layer's points, as the slicer asks
    np.testing.assert_allclose(gridded.fractions(x, y, plane)[:, 0], _ramp(x, 8), atol=1 / CELLS)
