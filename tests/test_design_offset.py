"""OpenVCAD's Offset and Shell: sections and sliced volumes against the analytic solids,
the shifted distance through booleans and transforms, materials and attributes kept, and
bad arguments named."""

from __future__ import annotations

import math
import textwrap

import numpy as np
import pytest
import shapely
import trimesh

from fgslice.compat.script import load_script
from fgslice.design import api, nodes, offset
from fgslice.design.attributes import attribute_fields
from fgslice.errors import DesignError
from fgslice.pipeline import slice_to_gcode
from fgslice.settings import load_settings

HEADER = "import pyvcad as pv\nimport pyvcad_rendering as viz\nmaterials = pv.default_materials\n"


def _script(tmp_path, body: str):
    path = tmp_path / "design.py"
    path.write_text(HEADER + textwrap.dedent("    " + body) + "\n", encoding="utf-8")
    return path


def _extruded_mm3(design, tmp_path) -> float:
    settings = load_settings(None, {"colors": "2", "strategy": "2", "layer_height": "0.2", "thumbnails": ""})
    return slice_to_gcode(design, settings, tmp_path / "part.gcode", jobs=1).stats["extruded_mm3"]


def _rounded_rectangle(a: float, b: float, r: float) -> float:
    """Area of an ``a`` x ``b`` rectangle grown by ``r`` with round corners."""
    return (a + 2 * r) * (b + 2 * r) - (4 - math.pi) * r * r


@pytest.mark.parametrize("z", [-9.7, -8.5, -3.0, 0.0, 6.0, 7.9, 8.1, 9.9])
def test_shell_of_a_cube_is_the_cube_less_the_shrunk_cube(z):
    shell = api.shell(2, api.cube(20))
    inner = 16 * 16 if abs(z) < 8 else 0.0
    assert shell.section(z, 0.1).area == pytest.approx(400 - inner, rel=1e-9)


@pytest.mark.parametrize("z", [-9.5, -7.0, -4.0, 0.0, 3.3, 7.99, 8.5])
def test_shell_of_a_sphere_is_an_annulus_at_every_height(z):
    shell = api.shell(2, api.sphere(10))
    expected = math.pi * (100 - z * z) - math.pi * max(64 - z * z, 0.0)
    assert shell.section(z, 0.1).area == pytest.approx(expected, rel=2e-3)


def test_shell_slices_to_the_volume_of_its_wall(tmp_path):
    cube = api.design(api.shell(2, api.cube(20)))
    assert _extruded_mm3(cube, tmp_path) == pytest.approx(20**3 - 16**3, rel=0.03)
    path = _script(tmp_path, """root = pv.Shell(1.5, pv.Sphere(pv.Vec3(0, 0, 0), 12, materials.id("red")))
    viz.Render(root, materials)""")
    ball = load_script(path)
    assert _extruded_mm3(ball, tmp_path) == pytest.approx(4 / 3 * math.pi * (12**3 - 10.5**3), rel=0.03)


@pytest.mark.parametrize("d", [0.5, 2.0, 3.0])
def test_offset_of_a_box_grows_each_dimension_by_twice_the_distance(d):
    grown = api.offset(d, api.rectprism(20, 10, 6))
    lo, hi = grown.bounds()
    np.testing.assert_allclose(np.subtract(hi, lo), (20 + 2 * d, 10 + 2 * d, 6 + 2 * d))
    for z in (0.0, 2.9, 3.0 + 0.6 * d, 3.0 + 0.95 * d):  # beside the box, then above its top
        t = max(z - 3.0, 0.0)
        radius = math.sqrt(d * d - t * t)
        assert grown.section(z, 0.1).area == pytest.approx(_rounded_rectangle(20, 10, radius), rel=1e-3)
    assert grown.section(3.0 + 1.01 * d, 0.1).is_empty


def test_negative_offset_shrinks_a_box_and_a_cylinder():
    shrunk = api.offset(-1.5, api.rectprism(20, 10, 6))
    lo, hi = shrunk.bounds()
    np.testing.assert_allclose(np.subtract(hi, lo), (17, 7, 3))
    assert shrunk.section(1.4, 0.1).area == pytest.approx(17 * 7)
    assert shrunk.section(1.6, 0.1).is_empty
    rod = api.offset(-1, api.cylinder(5, 10))
    assert rod.section(0.0, 0.1).area == pytest.approx(math.pi * 16, rel=2e-3)


def test_offset_shifts_the_distance_through_booleans_and_transforms():
    child = api.difference(
        api.union(api.translate((3, 0, 0), api.sphere(6)), api.rotate((0, 0, 30), api.rectprism(14, 4, 8))),
        api.scale((1, 2, 1), api.cylinder(1.5, 20)))
    rng = np.random.default_rng(3)
    x, y, z = (rng.uniform(-12, 12, 5000) for _ in range(3))
    for d in (1.25, -0.75):
        np.testing.assert_allclose(api.offset(d, child).sdf(x, y, z), child.sdf(x, y, z) - d, atol=1e-9)


@pytest.mark.parametrize("d", [1.0, -1.0])
def test_sections_agree_with_the_shifted_distance(d):
    child = api.difference(api.union(api.sphere(6), api.translate((5, 0, 1), api.cube(7))),
                           api.translate((-2, 0, 0), api.cylinder(1.5, 20)))
    traced = api.offset(d, api.function((-8, -8, -3), (8, 8, 3), "sqrt((rho - 5)^2 + z^2) - 2.5"))
    rng = np.random.default_rng(5)
    for part in (api.offset(d, child), traced):
        for z in (-1.2, 0.0, 0.9):
            section = part.section(z, 0.05)
            x, y = rng.uniform(-13, 13, 4000), rng.uniform(-13, 13, 4000)
            distance = part.sdf(x, y, np.full_like(x, z))
            clear = np.abs(distance) > 0.05
            inside = shapely.contains_xy(section, x, y)
            assert inside.any()
            np.testing.assert_array_equal(inside[clear], distance[clear] < 0)


def test_offset_past_the_size_of_a_part_leaves_nothing():
    assert api.design(api.union(api.offset(-5, api.sphere(4)), api.sphere(1))).bounds() == (
        (-1.0, -1.0, -1.0), (1.0, 1.0, 1.0))
    assert api.offset(-2, api.cube(3)).section(0.0, 0.1).is_empty


def test_materials_and_attributes_are_the_childs(tmp_path):
    path = _script(tmp_path, """bar = pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(40, 10, 10), 1)
    grade = pv.FGrade(["x/40 + 0.5", "0.5 - x/40"], [materials.id("red"), materials.id("blue")], True, bar)
    root = pv.Union(False, [pv.Offset(2, grade), pv.Translate(0, 0, 30, pv.Shell(2, grade))])
    viz.Render(root, materials)""")
    design = load_script(path)
    x = np.array([-21.5, 0.0, 10.0, 21.5, 19.0])
    y, z = np.zeros(5), np.array([0.0, 0.0, 0.0, 0.0, 34.5])
    assert (design.sdf(x, y, z) < 0).all()  # 1.5 mm into the grown margin, and in the shell's top
    np.testing.assert_allclose(design.fractions(x, y, z)[:, 0], np.clip(x / 40 + 0.5, 0, 1))
    v3 = _script(tmp_path, """
    cube = pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(20, 20, 20))
    cube.set_attribute(pv.DefaultAttributes.TEMPERATURE, pv.FloatAttribute("220 + x"))
    root = pv.Shell(2.0, cube)""")
    shell = load_script(v3)
    points = np.array([[-9.0, 0, 0], [9.5, 3, 0], [0, 0, 0]])
    inside = shell.sdf(*points.T) < 0
    np.testing.assert_array_equal(inside, [True, True, False])
    values = attribute_fields(shell).values("temperature", *points[:2].T)
    np.testing.assert_allclose(values, 220 + points[:2, 0])


@pytest.mark.parametrize("body, message", [
    ("root = pv.Shell(-1.0, pv.Sphere(pv.Vec3(0, 0, 0), 5))", "Shell: thickness must be positive, got -1"),
    ("root = pv.Shell('thin', pv.Sphere(pv.Vec3(0, 0, 0), 5))", "Shell: thickness must be a number"),
    ("root = pv.Shell(pv.Sphere(pv.Vec3(0, 0, 0), 5))", r"Shell takes \(thickness\), then optionally the child"),
    ("root = pv.Offset(1.0, 2.0, pv.Sphere(pv.Vec3(0, 0, 0), 5))", r"Offset takes \(\) or \(offset\)"),
    ("root = pv.Offset(None)", "Offset: offset must be a number"),
    ("root = pv.Offset(1.0)", "Offset has no child"),
    ("root = pv.Shell(1.0, 'ball')", r"Shell takes \(thickness\)"),
])
def test_bad_arguments_name_the_class_and_argument(tmp_path, body, message):
    path = _script(tmp_path, body)
    with pytest.raises(DesignError, match=message) as caught:
        load_script(path)
    assert caught.value.line == 4


def test_api_refuses_bad_distances():
    with pytest.raises(DesignError, match="shell: thickness must be positive"):
        api.shell(0, api.sphere(1))
    with pytest.raises(DesignError, match="offset: the distance must be a number"):
        api.offset("far", api.sphere(1))
    with pytest.raises(DesignError, match="offset has no children"):
        api.offset(1.0)
    assert isinstance(api.offset(0.0, api.sphere(1)).section(0.0, 0.1), shapely.Polygon | shapely.MultiPolygon)
    assert nodes.NodeDesign(api.shell(1, api.sphere(3))).materials[0].name == "default"


def test_a_mesh_grows_shrinks_and_hollows_with_exact_sections(tmp_path):
    trimesh.creation.box((20, 10, 6)).export(tmp_path / "block.stl")
    block = api.mesh(tmp_path / "block.stl")
    grown = api.offset(2, block)
    for z in (0.0, 2.9, 4.2):
        radius = math.sqrt(4 - max(z - 3.0, 0.0) ** 2)
        assert grown.section(z, 0.1).area == pytest.approx(_rounded_rectangle(20, 10, radius), rel=1e-3)
    assert api.offset(-1.5, block).section(1.4, 0.1).area == pytest.approx(17 * 7, rel=1e-9)
    assert api.offset(-1.5, block).section(1.6, 0.1).is_empty
    shell = api.shell(1, block)
    assert shell.section(0.0, 0.1).area == pytest.approx(200 - 18 * 8, rel=1e-9)
    assert shell.section(2.5, 0.1).area == pytest.approx(200, rel=1e-9)
    standing = api.offset(1, api.rotate((90, 0, 0), block))  # the mesh tilted: its 20 x 6 face now horizontal
    assert standing.section(0.0, 0.1).area == pytest.approx(_rounded_rectangle(20, 6, 1), rel=1e-3)
    rng = np.random.default_rng(9)
    x, y, z = rng.uniform(-12, 12, 3000), rng.uniform(-7, 7, 3000), np.full(3000, 3.5)
    section, distance = grown.section(3.5, 0.05), grown.sdf(x, y, z)
    clear = np.abs(distance) > 0.05
    np.testing.assert_array_equal(shapely.contains_xy(section, x, y)[clear], distance[clear] < 0)


def _band_of_pieces(triangles: np.ndarray, z: float, d: float, spacing: float) -> shapely.Geometry:
    """The band within ``d`` of ``triangles`` at ``z``, one piece at a time: each edge's
    capsule body (a :class:`nodes.Strut`'s) and each corner's disc (``nodes._circle``),
    with the plates of :class:`offset.TriangleBand`."""
    band = offset.TriangleBand(triangles, d)
    parts = list(offset._plates(band.triangles, band.normals, z, d))
    for x, y, corner_z in band.corners:
        if d * d - (z - corner_z) ** 2 > 0:
            parts.append(nodes._circle(x, y, math.sqrt(d * d - (z - corner_z) ** 2), spacing))
    parts.extend(nodes.Strut(a, b, d)._body_section(z, spacing) for a, b in band.edges)
    return shapely.union_all([p for p in parts if not p.is_empty])


def test_the_band_of_a_meshs_triangles_is_its_pieces_built_together_and_the_exact_distance(tmp_path):
    ball = trimesh.creation.icosphere(subdivisions=2, radius=6)
    ball.apply_transform(trimesh.transformations.euler_matrix(0.3, 0.5, 0.2))
    block = trimesh.creation.box((8, 3, 5))
    block.apply_translation((2, 0, 4))
    triangles = np.concatenate([ball.triangles, block.triangles, [[[0, 0, 0], [1, 1, 1], [2, 2, 2]]]])  # and a degenerate one
    (tmp_path / "part.stl").write_bytes(trimesh.Trimesh(*trimesh.util.append_faces(
        [m.vertices for m in (ball, block)], [m.faces for m in (ball, block)])).export(file_type="stl"))
    mesh = api.mesh(tmp_path / "part.stl")
    rng = np.random.default_rng(11)
    for d in (0.8, 1.5):
        band = offset.TriangleBand(triangles, d)
        for z in (-5.6, -2.0, 0.0, 3.3, 6.2, 6.9):
            section = band.section(z, 0.05)
            assert section.symmetric_difference(_band_of_pieces(triangles, z, d, 0.05)).area < 1e-9
            x, y = rng.uniform(-9, 9, 4000), rng.uniform(-9, 9, 4000)
            distance = np.abs(mesh.sdf(x, y, np.full_like(x, z)))
            clear = np.abs(distance - d) > 0.02
            inside = shapely.contains_xy(section, x, y)
            assert inside.any()
            np.testing.assert_array_equal(inside[clear], distance[clear] < d)
        assert band.section(20.0, 0.05).is_empty
        own = mesh.section(0.5, 0.05)
        for grown, cut in ((api.offset(d, mesh), own.union(band.section(0.5, 0.05))),
                           (api.offset(-d, mesh), own.difference(band.section(0.5, 0.05)))):
            assert grown.section(0.5, 0.05).symmetric_difference(cut).area < 1e-5  # the section's own clean-up
