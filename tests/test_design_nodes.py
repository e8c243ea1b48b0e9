"""Node tree: sdf, bounds, fractions and sections against hand-computed values."""

import math

import numpy as np
import pytest
import shapely

from fgslice.design import api, nodes
from fgslice.design.nodes import rotation_matrix


def sdf_at(node, *point):
    return float(api.design(node).sdf(*(np.array([c], dtype=float) for c in point))[0])


def fractions_at(design, *point):
    return design.fractions(*(np.array([c], dtype=float) for c in point))[0]


@pytest.mark.parametrize(
    "node, point, expected",
    [
        (api.sphere(2), (3, 4, 0), 3.0),
        (api.sphere(2), (0, 0, 0), -2.0),
        (api.cube(2), (2, 0, 0), 1.0),
        (api.cube(2), (0, 0, 0), -1.0),
        (api.cube(2), (2, 2, 2), math.sqrt(3)),
        (api.rectprism(2, 4, 6), (0, 0, 4), 1.0),
        (api.rectprism((2, 4, 6)), (0, 1.5, 0), -0.5),
        (api.cylinder(2, 4), (0, 0, 0), -2.0),
        (api.cylinder(2, 4), (3, 0, 0), 1.0),
        (api.cylinder(2, 4), (0, 0, 3), 1.0),
        (api.cylinder(2, 4), (3, 0, 3), math.sqrt(2)),
        (api.strut((0, 0, 0), (10, 0, 0), 1), (5, 2, 0), 1.0),
        (api.strut((0, 0, 0), (10, 0, 0), 1), (-2, 0, 0), 1.0),
        (api.strut((0, 0, 0), (10, 0, 0), 1), (12, 0, 1), math.sqrt(5) - 1),
        (api.function((-1, -1, -1), (1, 1, 1), lambda x, y, z: x + y), (0.5, 0.5, 0), 1.0),
        (api.function((-1, -1, -1), (1, 1, 1), lambda x, y, z: x + y), (-0.5, -0.25, 0), -0.5),
        (api.function((-1, -1, -1), (1, 1, 1), lambda x, y, z: x + y), (-0.5, -0.5, 3), 2.0),
    ],
)
def test_primitive_sdf(node, point, expected):
    assert sdf_at(node, *point) == pytest.approx(expected, abs=1e-12)


def test_booleans_follow_min_max():
    a, b = api.sphere(2), api.translate((3, 0, 0), api.sphere(2))
    p = (1.5, 0, 0)
    assert sdf_at(api.union(a, b), *p) == pytest.approx(-0.5)
    assert sdf_at(api.intersection(a, b), *p) == pytest.approx(-0.5)
    assert sdf_at(api.difference(a, b), *p) == pytest.approx(0.5)
    assert sdf_at(api.difference(a, b), -1, 0, 0) == pytest.approx(-1.0)
    assert sdf_at(api.union(a, b), 6, 0, 0) == pytest.approx(1.0)


def test_transforms_move_the_child():
    assert sdf_at(api.translate((1, 2, 3), api.sphere(1)), 1, 2, 3) == pytest.approx(-1)
    # right-hand rule about Z: +x goes to +y
    assert sdf_at(api.rotate((0, 0, 90), api.translate((5, 0, 0), api.sphere(1))), 0, 5, 0) == pytest.approx(-1)
    # pitch about X first (+y -> +z), then yaw about Y (+z -> +x)
    assert sdf_at(api.rotate((90, 90, 0), api.translate((0, 5, 0), api.sphere(1))), 5, 0, 0) == pytest.approx(-1)
    scaled = api.scale((2, 1, 1), api.sphere(1))
    assert sdf_at(scaled, 2, 0, 0) == pytest.approx(0, abs=1e-12)
    assert sdf_at(scaled, 1.9, 0, 0) < 0 < sdf_at(scaled, 0, 1.1, 0)
    assert sdf_at(api.scale(3, api.sphere(1)), 5, 0, 0) == pytest.approx(2)


def test_rotation_order_is_x_then_y_then_z():
    r = rotation_matrix(30, 40, 50)
    a, b, c = np.radians([30, 40, 50])
    rx = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
    ry = np.array([[np.cos(b), 0, np.sin(b)], [0, 1, 0], [-np.sin(b), 0, np.cos(b)]])
    rz = np.array([[np.cos(c), -np.sin(c), 0], [np.sin(c), np.cos(c), 0], [0, 0, 1]])
    v = np.array([0.3, -1.2, 2.0])
    np.testing.assert_allclose(r @ v, rz @ (ry @ (rx @ v)))


def test_bounds_are_tight_for_boxes_and_transforms():
    d = api.design(api.translate((1, 2, 3), api.cylinder(2, 4)))
    assert d.bounds() == ((-1, 0, 1), (3, 4, 5))
    lo, hi = api.design(api.rotate((0, 0, 45), api.cube(2))).bounds()
    np.testing.assert_allclose(hi, (math.sqrt(2), math.sqrt(2), 1))
    lo, hi = api.design(api.intersection(api.cube(4), api.translate((1, 0, 0), api.cube(4)))).bounds()
    np.testing.assert_allclose(lo, (-1, -2, -2))
    np.testing.assert_allclose(hi, (2, 2, 2))
    lo, hi = api.design(api.scale((2, -3, 1), api.sphere(1))).bounds()
    np.testing.assert_allclose(lo, (-2, -3, -1))
    lo, hi = api.design(api.function((0, 1, 2), (3, 4, 5), lambda x, y, z: x - 5)).bounds()
    np.testing.assert_allclose(lo, (0, 1, 2))
    np.testing.assert_allclose(hi, (3, 4, 5))
    lo, hi = api.design(api.function((0, 1, 2), (3, 4, 5), lambda x, y, z: x - 1.5)).bounds()
    np.testing.assert_allclose(lo, (0, 1, 2))  # a function's bounds: its inside region within the box
    np.testing.assert_allclose(hi, (1.5, 4, 5), atol=1e-3)
    assert hi[0] >= 1.5


def test_fgrade_fields_see_their_own_frame_through_nested_transforms():
    inner = api.rotate((0, 0, 90), api.translate((5, 0, 0), api.sphere(3)))
    graded = api.fgrade([lambda x, y, z: y / 10, lambda x, y, z: 1 - y / 10], ["blue", "yellow"], inner)
    design = api.design(api.translate((100, 0, 0), graded))
    # the sphere's center lands at (0, 5, 0) in the fgrade frame, (100, 5, 0) in the design
    assert sdf_at(api.translate((100, 0, 0), graded), 100, 5, 0) == pytest.approx(-3)
    np.testing.assert_allclose(fractions_at(design, 100, 5, 0), [0.5, 0.5])
    np.testing.assert_allclose(fractions_at(design, 100, 7, 0), [0.7, 0.3])
    np.testing.assert_allclose(fractions_at(design, 101, 3, 1), [0.3, 0.7])


def test_fgrade_d_is_the_signed_distance_of_its_child():
    graded = api.fgrade([lambda x, y, z, d: -d / 5, lambda x, y, z, d: 1 + d / 5], ["red", "blue"], api.sphere(5))
    design = api.design(api.translate((0, 0, 10), graded))
    np.testing.assert_allclose(fractions_at(design, 0, 0, 10), [1, 0])
    np.testing.assert_allclose(fractions_at(design, 2.5, 0, 10), [0.5, 0.5])


def test_union_overlap_takes_the_first_childs_material():
    design = api.design(api.union(api.sphere(2, "red"), api.translate((1, 0, 0), api.sphere(2, "blue"))))
    assert [m.name for m in design.materials] == ["red", "blue"]
    np.testing.assert_allclose(fractions_at(design, 0.5, 0, 0), [1, 0])
    np.testing.assert_allclose(fractions_at(design, 2.5, 0, 0), [0, 1])
    np.testing.assert_allclose(fractions_at(design, -3, 0, 0), [1, 0])
    np.testing.assert_allclose(fractions_at(design, 4, 0, 0), [0, 1])


def test_fractions_are_clamped_then_normalized():
    def graded(a, b):
        return api.design(api.fgrade([lambda x, y, z: a + 0 * x, lambda x, y, z: b + 0 * x], ["red", "blue"], api.sphere(1)))

    np.testing.assert_allclose(fractions_at(graded(2.0, 0.5), 0, 0, 0), [2 / 3, 1 / 3])
    np.testing.assert_allclose(fractions_at(graded(-1.0, 0.3), 0, 0, 0), [0, 1])
    np.testing.assert_allclose(fractions_at(graded(0.0, 0.0), 0, 0, 0), [1, 0])
    np.testing.assert_allclose(fractions_at(graded(np.nan, 0.25), 0, 0, 0), [0, 1])
    np.testing.assert_allclose(graded(2.0, 0.5).raw_fractions(np.zeros(1), np.zeros(1), np.zeros(1))[0], [2, 0.5])


def test_an_fgrade_overrides_the_materials_of_its_children():
    part = api.union(
        api.sphere(1, "green"),
        api.fgrade(
            [lambda x, y, z: 0.25 + 0 * x, lambda x, y, z: 0.75 + 0 * x],
            ["blue", "green"],
            api.translate((5, 0, 0), api.sphere(1)),
            api.translate((10, 0, 0), api.sphere(1, "red")),
        ),
    )
    design = api.design(part)
    assert [m.name for m in design.materials] == ["green", "blue"]
    assert [name for name, _ in design.overridden] == ["red"]
    np.testing.assert_allclose(fractions_at(design, 0, 0, 0), [1, 0])
    np.testing.assert_allclose(fractions_at(design, 5, 0, 0), [0.75, 0.25])
    np.testing.assert_allclose(fractions_at(design, 10, 0, 0), [0.75, 0.25])


def test_the_outermost_fgrade_decides_over_nested_ones():
    inner = api.fgrade(["1", "0"], ["red", "cyan"], api.cube(2))
    outer = api.fgrade(["x / 4 + 0.5", "0.5 - x / 4"], ["blue", "yellow"], inner)
    design = api.design(api.union(outer, api.translate((5, 0, 0), api.cube(2, "cyan"))))
    assert [m.name for m in design.materials] == ["blue", "yellow", "cyan"]
    assert [name for name, _ in design.overridden] == ["red"]
    x = np.array([-0.5, 0.0, 0.5])
    f = design.fractions(x, np.zeros(3), np.zeros(3))
    np.testing.assert_allclose(f, np.column_stack([x / 4 + 0.5, 0.5 - x / 4, np.zeros(3)]))
    np.testing.assert_allclose(fractions_at(design, 5, 0, 0), [0, 0, 1])


def test_thresh_mode_gives_the_largest_fraction_outright():
    fields = [lambda x, y, z: x, lambda x, y, z: 1 - x]
    design = api.design(api.fgrade(fields, ["red", "blue"], api.cube(4), mode="thresh"))
    f = design.fractions(np.array([0.3, 0.7]), np.zeros(2), np.zeros(2))
    np.testing.assert_allclose(f, [[0, 1], [1, 0]])


def test_uncolored_primitive_outside_fgrade_takes_the_first_material():
    design = api.design(api.union(api.sphere(1, "cyan"), api.translate((5, 0, 0), api.sphere(1))))
    np.testing.assert_allclose(fractions_at(design, 5, 0, 0), [1])
    assert [m.name for m in api.design(api.sphere(1)).materials] == ["default"]


def test_fractions_keep_the_broadcast_shape():
    design = api.design(api.fgrade([lambda x, y, z: x, lambda x, y, z: 1 - x], ["red", "blue"], api.cube(4)))
    f = design.fractions(np.zeros((3, 1)), np.zeros((1, 4)), 0.0)
    assert f.shape == (3, 4, 2)
    assert design.sdf(np.zeros((3, 1)), np.zeros((1, 4)), 0.0).shape == (3, 4)


def test_grid_fractions_match_pointwise_fractions():
    fields = ["(1+sin(0.1*x+0.2*y)*cos(0.2*x-0.1*y))/2", "1-(1+sin(0.1*x+0.2*y)*cos(0.2*x-0.1*y))/2"]
    part = api.translate((1, 2, 3), api.fgrade(fields, ["red", "blue"], api.translate((0, 0, 1), api.sphere(40))))
    for node in (part.children[0], part):
        design = api.design(node)
        xs = np.linspace(-40, 40, 410)[None, :]
        ys = np.linspace(-30, 30, 190)[:, None]
        grid = design.fractions(xs, ys, 5.0)
        gx, gy = np.broadcast_arrays(xs, ys)
        flat = design.fractions(gx.ravel(), gy.ravel(), np.full(gx.size, 5.0))
        assert grid.shape == (190, 410, 2)
        np.testing.assert_allclose(grid.reshape(-1, 2), flat, rtol=0, atol=1e-15)
        assert np.ptp(grid[..., 0]) > 0.5


def area(node, z):
    geom = api.design(node).section(z)
    assert isinstance(geom, shapely.MultiPolygon) and geom.is_valid
    return geom.area


@pytest.mark.parametrize("r", [0.5, 1.0, 10.0, 87.5])
def test_circle_sections_are_within_a_thousandth_of_the_analytic_area(r):
    assert area(api.cylinder(r, 2), 0.3) == pytest.approx(math.pi * r * r, rel=1e-3)
    assert area(api.sphere(r), 0.6 * r) == pytest.approx(math.pi * 0.64 * r * r, rel=1e-3)


def test_box_and_boolean_sections_are_exact():
    assert area(api.rectprism(3, 4, 5), 2.4) == pytest.approx(12)
    assert area(api.rectprism(3, 4, 5), 2.6) == 0
    assert area(api.cube(2), 0) == pytest.approx(4)
    ring = api.difference(api.cylinder(50, 10), api.cylinder(15, 10))
    assert area(ring, 1) == pytest.approx(math.pi * (50**2 - 15**2), rel=1e-3)
    both = api.union(api.cube(2), api.translate((1, 0, 0), api.cube(2)))
    assert area(both, 0) == pytest.approx(6)
    assert area(api.intersection(api.cube(2), api.translate((1, 0, 0), api.cube(2))), 0) == pytest.approx(2)


def test_transformed_sections_are_exact():
    moved = api.design(api.translate((3, 4, 5), api.cylinder(2, 2))).section(5.5)
    assert moved.area == pytest.approx(4 * math.pi, rel=1e-3)
    assert (moved.centroid.x, moved.centroid.y) == pytest.approx((3, 4), abs=1e-9)
    turned = api.design(api.rotate((0, 0, 30), api.rectprism(10, 2, 2))).section(0)
    assert turned.area == pytest.approx(20)
    assert turned.bounds[2] == pytest.approx(5 * math.cos(math.radians(30)) + math.sin(math.radians(30)))
    assert area(api.scale((2, 3, 4), api.cylinder(1, 2)), 3.9) == pytest.approx(6 * math.pi, rel=1e-3)
    assert area(api.scale((2, 3, 4), api.cylinder(1, 2)), 4.1) == 0
    # a half turn about X keeps Z vertical: exact, mirrored
    flipped = api.design(api.rotate((180, 0, 0), api.translate((0, 2, 1), api.cube(1)))).section(-1)
    assert flipped.area == pytest.approx(1)
    assert flipped.centroid.y == pytest.approx(-2)


def test_strut_sections_match_the_capsule():
    horizontal = api.strut((-10, 0, 0), (10, 0, 0), 2)
    assert area(horizontal, 0) == pytest.approx(80 + 4 * math.pi, rel=1e-3)
    assert area(horizontal, 1) == pytest.approx(20 * 2 * math.sqrt(3) + 3 * math.pi, rel=1e-3)
    vertical = api.strut((1, 1, -5), (1, 1, 5), 2)
    assert area(vertical, 3) == pytest.approx(4 * math.pi, rel=1e-3)
    assert area(vertical, 6) == pytest.approx(3 * math.pi, rel=1e-3)
    tilted = api.strut((-6, -2, -4), (5, 3, 6), 2.5)
    design = api.design(tilted)
    for z in (-5.0, -1.0, 0.5, 6.5):
        step = 0.02
        xs, ys = np.meshgrid(np.arange(-12, 12, step) + step / 2, np.arange(-12, 12, step) + step / 2)
        counted = np.count_nonzero(design.sdf(xs, ys, np.full(xs.shape, z)) <= 0) * step * step
        assert design.section(z).area == pytest.approx(counted, rel=0.01)


def test_empty_sections_outside_the_bounds():
    assert api.design(api.sphere(1)).section(1.5).is_empty
    assert api.design(api.intersection(api.cube(1), api.translate((5, 0, 0), api.cube(1)))).section(0).is_empty


def test_sections_of_many_heights_equal_one_section_each_and_mesh_planes_are_cut_together(tmp_path, monkeypatch):
    """``sections`` gives, height by height, exactly what ``section`` gives (booleans,
    transforms, a sampled tilted shape, heights outside the bounds and out of order), and
    a mesh inside the tree is cut at all its heights in one batch."""
    import trimesh

    from fgslice.design.mesh import _Tables

    torus = trimesh.creation.torus(major_radius=8, minor_radius=3, major_sections=48, minor_sections=24)
    torus.export(tmp_path / "torus.stl")
    tree = api.fgrade(
        ["x / 20 + 0.5", "0.5 - x / 20"], ["blue", "yellow"],
        api.difference(
            api.union(api.translate((1, 2, 0), api.mesh(tmp_path / "torus.stl")), api.scale((2, 1, 1), api.cube(6))),
            api.rotate((20, 0, 0), api.cylinder(1.5, 30)),
            api.intersection(api.cube(4), api.sphere(2.5)),
        ),
    )
    design = api.design(tree)
    zs = [2.9, -1.0, 0.0, 0.5, 7.0, -2.95, 1.7, 3.5]
    one_each = [design.section(z) for z in zs]
    for node, *_ in nodes.walk(tree):  # each node keeps its last outlines: start afresh
        node.__dict__.pop("_kept_sections", None)
    batches = []
    original = _Tables._section_batch
    monkeypatch.setattr(_Tables, "_section_batch", lambda self, planes, gap: batches.append(len(planes)) or original(self, planes, gap))
    together = design.sections(zs)
    assert batches == [6]  # z = 3.5 and 7 lie above the torus: the other six in one batch
    assert [g.wkb for g in together] == [g.wkb for g in one_each]
    assert together[4].is_empty and not together[0].is_empty
    assert all(isinstance(g, shapely.MultiPolygon) and g.is_valid for g in together)
    again = design.sections(zs[-nodes.KEPT_SECTIONS:])  # the last outlines are kept, not cut again
    assert batches == [6] and [g.wkb for g in again] == [g.wkb for g in one_each[-nodes.KEPT_SECTIONS:]]


def test_transforms_map_all_heights_at_once_as_shapely_maps_each_section():
    """An affine node maps its child's sections in one call, with the arithmetic of
    ``shapely.affinity.affine_transform`` (bit for bit)."""
    child = api.intersection(api.sphere(10), api.union(api.cube(12), api.translate((4, 0, 0), api.cylinder(3, 30))))
    for node in (api.rotate((0, 0, 33), child), api.scale((1.3, 0.7, 2), child), api.translate((3.1, -2.7, 5), child)):
        zs = [-24.0, -9.3, 0.0, 4.99, 5.0, 12.2, 14.9, 40.0]
        m, offset = node.matrix, node.offset
        plane_map = [m[0, 0], m[0, 1], m[1, 0], m[1, 1], offset[0], offset[1]]
        inner = api.design(child).sections([(z - offset[2]) / m[2, 2] for z in zs], 0.3 / max(np.abs(np.linalg.eigvals(m))))
        expected = [g if g.is_empty else shapely.affinity.affine_transform(g, plane_map) for g in inner]
        mapped = api.design(node).sections(zs, 0.3)
        assert sum(not g.is_empty for g in mapped) >= 3
        assert [g.wkb for g in mapped] == [g.wkb for g in expected]
