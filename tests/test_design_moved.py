"""Meshes under tilting transforms: the map moved onto the vertices, exact sections."""

import numpy as np
import pytest
import shapely
import trimesh

from fgslice.design import nodes
from fgslice.design.language import parse_design
from fgslice.design.mesh import MeshGeometry
from fgslice.design.moved import Placed


def _mesh(tm: trimesh.Trimesh) -> nodes.MeshShape:
    return nodes.MeshShape(MeshGeometry(tm.vertices, tm.faces), "m.stl")


def test_box_on_its_side_sections_exactly():
    box = _mesh(trimesh.creation.box((10, 20, 30)))
    design = nodes.NodeDesign(nodes.Rotate((90, 0, 0), box))
    lo, hi = design.bounds()
    assert np.allclose(lo, (-5, -15, -10)) and np.allclose(hi, (5, 15, 10))
    for z in (-9.9, 0.0, 7.3):
        section = design.section(z)
        assert section.is_valid
        assert section.area == pytest.approx(10 * 30, rel=1e-12)
        assert np.allclose(section.bounds, (-5, -15, 5, 15))
    assert design.root.valid_sections
    assert [m.bounds() for m in design.meshes] == [design.root.bounds()]


@pytest.mark.parametrize("factors", [(1, 1, 1), (-1, 1, 1), (1.5, 0.5, 2.0), (1, -2, -1)])
def test_any_map_sections_like_the_moved_mesh(factors):
    """Rotation, non-uniform scale and mirrors: sections equal those of the mesh whose
    vertices trimesh moved (faces flipped by trimesh where the map mirrors)."""
    tm = trimesh.creation.cone(8, 20, sections=24)
    tm.apply_translation((3, -2, 1))
    root = nodes.Scale(factors, nodes.Rotate((37, 21, 5), _mesh(tm)))
    expected = tm.copy()
    expected.apply_transform(np.diag([*factors, 1.0]) @ np.vstack([np.hstack([nodes.rotation_matrix(37, 21, 5),
                                                                               np.zeros((3, 1))]), [0, 0, 0, 1]]))
    truth = MeshGeometry(expected.vertices, expected.faces)
    design = nodes.NodeDesign(root)
    lo, hi = np.array(design.bounds())
    assert np.allclose(lo, expected.bounds[0]) and np.allclose(hi, expected.bounds[1])
    zs = np.linspace(lo[2] + 0.05, hi[2] - 0.05, 9)
    for got, want in zip(design.sections(zs), truth.sections(zs)):
        assert got.is_valid and got.area > 0
        assert got.symmetric_difference(want).area < 1e-9 * want.area
    # the signed distance agrees in sign with the moved mesh's sections at the points
    rng = np.random.default_rng(3)
    points = lo + (hi - lo) * rng.random((300, 3))
    inside = [shapely.contains_xy(s, x, y) for s, (x, y, _) in zip(truth.sections(points[:, 2]), points)]
    assert np.array_equal(design.sdf(*points.T) <= 0, inside)


def test_fractions_stay_in_the_grading_frame(tmp_path):
    """An fgrade under a tilting rotation grades in its own frame: at a point p of the
    part the fraction is the field at R^-1 p, and the geometry is the moved mesh's."""
    trimesh.creation.box((20, 4, 4)).export(tmp_path / "bar.stl")
    design = parse_design(
        """rotate(0, 90, 0) { fgrade(["x/20 + 0.5", "0.5 - x/20"], ["red", "blue"]) { mesh("bar.stl"); } }""",
        file=tmp_path / "d.vcad",
    )
    assert isinstance(design.root.moved_tree, Placed)
    lo, hi = design.bounds()
    assert np.allclose(lo, (-2, -2, -10)) and np.allclose(hi, (2, 2, 10))  # the bar stands upright
    assert design.section(3.0).area == pytest.approx(16.0)
    z = np.array([-8.0, 0.0, 6.0])
    fractions = design.fractions(np.zeros(3), np.zeros(3), z)
    # rotate(0, 90, 0) takes x to -z: the child's x at height z is -z
    assert np.allclose(fractions[:, 0], -z / 20 + 0.5)


def test_a_traced_field_intersected_with_a_tilted_mesh_is_traced_only_where_the_mesh_is():
    """OpenVCAD's logo: a gyroid function intersected with a mesh under a tilting map. The
    function is traced only within the mesh section's box; the outlines are the same as
    the function's whole traced section intersected with the mesh's."""
    gyroid = nodes.Field("sin(x) * cos(y) + sin(y) * cos(z) + sin(z) * cos(x) + 0.5")
    field = nodes.FunctionShape((-60, -15, -6), (60, 15, 6), gyroid)
    blob = _mesh(trimesh.creation.icosphere(3, 8.0))
    root = nodes.Rotate((90, 180, 180), nodes.Intersection([blob, field]))
    design = nodes.NodeDesign(root)
    inner = design.root.moved_tree
    assert type(inner) is nodes.Intersection and [c.traced for c in inner.children] == [False, True]
    for z in (-5.0, 0.3, 4.0):
        got = design.section(z)
        mesh_part, traced = (c.section(z, nodes.DEFAULT_SECTION_SPACING) for c in inner.children)
        assert traced.bounds[2] - traced.bounds[0] > 100  # the function's whole section is wide
        want = shapely.intersection(mesh_part, traced)
        assert got.area > 10 and got.symmetric_difference(want).area < 1e-6 * want.area
