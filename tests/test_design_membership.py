"""Which body of a union a point belongs to, from the bodies' sections (fgslice.design.membership)."""

import numpy as np
import pytest
import trimesh

from fgslice.design import membership
from fgslice.design.language import parse_design
from fgslice.design.mesh import MeshGeometry


@pytest.fixture
def three_meshes(tmp_path):
    """Three 40 x 20 x 2 mm boxes side by side, the middle one overlapping the first, and
    a 10 mm tall one whose lower part is cut by a sphere."""
    for name, size, offset in (("a", (40, 20, 2), (0, 0, 1)), ("b", (40, 20, 2), (0, 15, 1)),
                               ("c", (40, 20, 10), (0, 50, 5))):
        box = trimesh.creation.box(size)
        box.apply_translation(offset)
        box.export(tmp_path / f"{name}.stl")
    text = """union() {
        mesh("a.stl", "red");
        mesh("b.stl", "green");
        difference() { mesh("c.stl", "blue"); translate(0, 50, 0) { sphere(6); } }
    }"""
    return parse_design(text, file=tmp_path / "part.vcad")


def _expected_owner(design, x, y, z):
    """The rule on 3-D signed distances: first child containing the point, else the nearest."""
    d = np.stack([c.sdf(x, y, z) for c in design.root.children])
    inside = d <= 0
    return np.where(inside.any(axis=0), np.argmax(inside, axis=0), np.argmin(d, axis=0))


@pytest.mark.parametrize("z", [0.5, 1.0, 1.9])
def test_materials_of_a_plane_follow_the_first_containing_body(three_meshes, z):
    rng = np.random.default_rng(3)
    x = rng.uniform(-25, 25, 4000)
    y = rng.uniform(-15, 65, 4000)
    zz = np.full_like(x, z)
    expected = _expected_owner(three_meshes, x, y, zz)
    owner = membership.owners(three_meshes.root.children, x, y, zz)
    d = np.stack([c.sdf(x, y, zz) for c in three_meshes.root.children])
    clear = (np.abs(d) > 1e-6).all(axis=0)  # off every surface
    inside = (d <= 0).any(axis=0)
    assert np.array_equal(owner[clear & inside], expected[clear & inside])
    # outside all bodies the in-plane distance picks the nearest body, as the 3-D one does here
    # (vertical sides), wherever the nearest is not a tie
    nearest_two = np.sort(d, axis=0)[:2]
    distinct = clear & ~inside & (nearest_two[1] - nearest_two[0] > 1e-6)
    assert distinct.sum() > 1000
    assert np.array_equal(owner[distinct], expected[distinct])
    colors = three_meshes.fractions(x, y, zz).argmax(axis=1)
    names = [m.name.lower() for m in three_meshes.materials]
    decided = clear & (inside | distinct)
    assert np.array_equal(colors[decided], np.array([names.index(n) for n in ("red", "green", "blue")])[expected[decided]])


def test_a_plane_needs_no_3d_mesh_distance(three_meshes, monkeypatch):
    def no_distance(*args):
        raise AssertionError("3-D mesh distance evaluated")

    monkeypatch.setattr(MeshGeometry, "sdf", no_distance)
    x, y = np.meshgrid(np.linspace(-19, 19, 40), np.linspace(-9, 59, 60))
    x, y = x.ravel(), y.ravel()
    fractions = three_meshes.fractions(x, y, np.full_like(x, 1.0))  # the sphere's hole in body c at z = 1
    in_hole = np.hypot(x, y - 50) < np.sqrt(36 - 1) + 1e-6
    blue = [m.name.lower() for m in three_meshes.materials].index("blue")
    in_c = (np.abs(x) < 20) & (np.abs(y - 50) < 10)
    assert (fractions[in_c & ~in_hole].argmax(axis=1) == blue).all()
    in_b_only = (np.abs(x) < 20) & (y > 10) & (y < 25)
    green = [m.name.lower() for m in three_meshes.materials].index("green")
    assert (fractions[in_b_only].argmax(axis=1) == green).all()


def test_points_at_several_heights_use_the_distances(three_meshes):
    x = np.array([0.0, 0.0, 0.0, 0.0])
    y = np.array([5.0, 12.0, 50.0, 58.0])
    z = np.array([1.0, 1.5, 8.0, 0.2])
    assert list(membership.owners(three_meshes.root.children, x, y, z)) == [0, 1, 2, 2]
    assert list(_expected_owner(three_meshes, x, y, z)) == [0, 1, 2, 2]


def test_mesh_subtrees_use_sections(tmp_path):
    trimesh.creation.box((4, 4, 4)).export(tmp_path / "m.stl")
    design = parse_design(
        """union() {
            mesh("m.stl");
            sphere(3);
            union() { function((-1,-1,-1),(1,1,1), "x"); mesh("m.stl"); }
            rotate(0, 0, 30) { mesh("m.stl"); }
            rotate(30, 0, 0) { mesh("m.stl"); }
            rotate(30, 0, 0) { union() { mesh("m.stl"); sphere(1); } }
        }""",
        file=tmp_path / "d.vcad",
    )
    # every child holding a mesh (also beside a sampled function or a tilted sphere)
    assert [membership.uses_sections(c) for c in design.root.children] == [True, False, True, True, True, True]


def test_a_gyroid_filled_mesh_decides_a_plane_without_3d_mesh_distances(tmp_path, monkeypatch):
    """A mesh intersected with a sampled gyroid function, then a plain mesh (OpenVCAD's
    keychain): points of a plane follow the sections, and agree with the distance rule."""
    trimesh.creation.box((30, 20, 4)).export(tmp_path / "m.stl")
    design = parse_design(
        """union() {
            intersection() {
                mesh("m.stl", "red");
                function((-20,-20,-5),(20,20,5), "sin(x)*cos(y)+sin(y)*cos(z)+sin(z)*cos(x)+0.5");
            }
            mesh("m.stl", "blue");
        }""",
        file=tmp_path / "d.vcad",
    )
    rng = np.random.default_rng(5)
    x, y = rng.uniform(-14, 14, 3000), rng.uniform(-9, 9, 3000)
    z = np.full_like(x, 0.7)
    expected = _expected_owner(design, x, y, z)
    d = design.root.children[0].sdf(x, y, z)
    with monkeypatch.context() as patch:
        patch.setattr(MeshGeometry, "sdf", lambda *args: (_ for _ in ()).throw(AssertionError("3-D mesh distance")))
        owner = membership.owners(design.root.children, x, y, z)
    clear = np.abs(d) > 0.05  # the gyroid's traced outline is within 0.005 mm of its level set
    assert {0, 1} <= set(owner[clear])
    assert np.array_equal(owner[clear], expected[clear])


def test_a_child_the_plane_misses_owns_no_point_of_it(three_meshes, monkeypatch):
    """At z = 6 only the tall body is cut: every point of the plane is its own, found
    without a 3-D mesh distance to the two flat bodies below."""
    monkeypatch.setattr(MeshGeometry, "sdf", lambda *args: pytest.fail("3-D mesh distance evaluated"))
    x, y = np.meshgrid(np.linspace(-30, 30, 25), np.linspace(-20, 70, 30))
    x, y = x.ravel(), y.ravel()
    assert (membership.owners(three_meshes.root.children, x, y, np.full_like(x, 6.0)) == 2).all()
