"""Mesh loading, exact sections and signed distance (fgslice.design.mesh)."""

from pathlib import Path

import numpy as np
import pytest
import shapely
import trimesh

from fgslice.design.mesh import MeshGeometry, load_mesh
from fgslice.errors import MeshError


def _reference_area(mesh: trimesh.Trimesh, z: float) -> float:
    """Even-odd area of trimesh's own plane cut: noded, polygonized segments, faces kept by ray parity."""
    segments = trimesh.intersections.mesh_plane(mesh, plane_normal=[0, 0, 1], plane_origin=[0, 0, z])[:, :, :2]
    noded = shapely.node(shapely.multilinestrings(shapely.linestrings(np.round(segments, 9))))
    faces = shapely.get_parts(shapely.polygonize(shapely.get_parts(noded)))
    probes = shapely.get_coordinates(shapely.point_on_surface(faces))
    a, b = segments[:, 0], segments[:, 1]
    px, py = probes[:, 0:1], probes[:, 1:2]
    straddle = (a[:, 1] > py) != (b[:, 1] > py)
    x_cross = a[:, 0] + (py - a[:, 1]) * (b[:, 0] - a[:, 0]) / np.where(b[:, 1] == a[:, 1], 1, b[:, 1] - a[:, 1])
    odd = (straddle & (x_cross > px)).sum(axis=1) % 2 == 1
    return float(shapely.area(faces[odd]).sum())


def _geometry(mesh: trimesh.Trimesh) -> MeshGeometry:
    return MeshGeometry(mesh.vertices, mesh.faces)


def _as_trimesh(geometry: MeshGeometry) -> trimesh.Trimesh:
    whole = geometry._whole  # the whole mesh's tables: vertices merged
    return trimesh.Trimesh(whole.vertices, whole.faces, process=False)


def _save(mesh: trimesh.Trimesh, path: Path, **kwargs) -> Path:
    mesh.export(path, **kwargs)
    return path


@pytest.fixture
def box_mesh() -> trimesh.Trimesh:
    return trimesh.creation.box(extents=(10.0, 20.0, 30.0))


@pytest.mark.parametrize("name, kwargs", [("box.stl", {}), ("box_ascii.stl", {"file_type": "stl_ascii"}), ("box.obj", {}), ("box.3mf", {})])
def test_load_formats_give_exact_box(tmp_path, box_mesh, name, kwargs):
    geometry = load_mesh(_save(box_mesh, tmp_path / name, **kwargs))
    assert geometry.path == tmp_path / name
    assert geometry.triangle_count == 12
    assert geometry.watertight
    np.testing.assert_allclose(geometry.bounds(), ((-5, -10, -15), (5, 10, 15)))
    section = geometry.section(3.0)
    assert isinstance(section, shapely.MultiPolygon)
    assert section.area == pytest.approx(200.0, rel=1e-12)
    assert section.equals(shapely.box(-5, -10, 5, 10))


def test_scene_bodies_are_concatenated(tmp_path):
    scene = trimesh.Scene([trimesh.creation.box(extents=(2, 2, 2)), trimesh.creation.box(extents=(2, 2, 2)).apply_translation((10, 0, 0))])
    geometry = load_mesh(_save(scene, tmp_path / "two.3mf"))
    section = geometry.section(0.5)
    assert len(section.geoms) == 2
    assert section.area == pytest.approx(8.0)


def test_cylinder_section_is_exact_polygon_and_matches_trimesh(tmp_path):
    mesh = trimesh.creation.cylinder(radius=7.0, height=10.0, sections=64)
    geometry = _geometry(mesh)
    for z in (-4.9, 0.0, 3.3):
        section = geometry.section(z)
        exact = 0.5 * 64 * 49.0 * np.sin(2 * np.pi / 64)
        assert section.area == pytest.approx(exact, rel=1e-12)
        assert section.area == pytest.approx(_reference_area(mesh, z), rel=1e-9)
        assert shapely.is_ccw(section.geoms[0].exterior)


def test_annulus_keeps_hole_with_cw_orientation():
    mesh = trimesh.creation.annulus(r_min=3.0, r_max=6.0, height=4.0, sections=48)
    section = _geometry(mesh).section(0.25)
    (polygon,) = section.geoms
    assert len(polygon.interiors) == 1
    assert not shapely.is_ccw(polygon.interiors[0])
    assert section.area == pytest.approx(_reference_area(mesh, 0.25), rel=1e-9)
    assert polygon.contains(shapely.Point(4.5, 0)) and not polygon.contains(shapely.Point(0, 0))


def test_vertex_on_plane_and_planes_outside(box_mesh):
    geometry = _geometry(box_mesh)
    sections = geometry.sections([15.0, -15.0, 0.0, 40.0, -40.0])
    # vertices on the plane count as above it: the top cut is the full face, the bottom one empty
    assert sections[0].area == pytest.approx(200.0)
    assert sections[1].is_empty
    assert sections[2].area == pytest.approx(200.0)
    assert sections[3].is_empty and sections[4].is_empty
    assert geometry.section(40.0).is_empty and geometry.section(-15.0).is_empty


def test_open_mesh_sections_are_closed(box_mesh):
    mesh = box_mesh.copy()
    side = np.flatnonzero(mesh.face_normals[:, 0] > 0.5)
    mesh.update_faces(np.setdiff1d(np.arange(len(mesh.faces)), side))
    geometry = _geometry(mesh)
    assert not geometry.watertight
    section = geometry.section(1.0)
    assert section.is_valid
    assert section.area == pytest.approx(200.0)


def test_sdf_of_box_and_of_open_box(box_mesh):
    x = np.array([0.0, 4.0, 7.0, 0.0, 0.0])
    y = np.array([0.0, 0.0, 0.0, 13.0, -9.5])
    z = np.array([0.0, 0.0, 0.0, 0.0, 14.0])
    expected = np.array([-5.0, -1.0, 2.0, 3.0, -0.5])
    np.testing.assert_allclose(_geometry(box_mesh).sdf(x, y, z), expected, atol=1e-12)
    mesh = box_mesh.copy()
    mesh.update_faces(np.arange(1, len(mesh.faces)))
    np.testing.assert_allclose(_geometry(mesh).sdf(x, y, z), expected, atol=1e-12)


def test_sdf_broadcasts(box_mesh):
    grid = np.linspace(-8, 8, 5)
    values = _geometry(box_mesh).sdf(grid[:, None], grid[None, :], 0.0)
    assert values.shape == (5, 5)
    assert values[2, 2] == pytest.approx(-5.0)


@pytest.mark.parametrize(
    "name, content, fragment",
    [
        ("missing.stl", None, "not found"),
        ("junk.stl", b"\x00\x01garbage" * 7, "too short"),
        ("junk.3mf", b"PK\x03\x04 not a zip", "cannot read"),
        ("empty.obj", b"", "no triangles"),
        ("model.ply", b"ply", "unsupported"),
        (
            "nan.stl",
            b"solid s\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex nan 1 0\nendloop\nendfacet\nendsolid s\n",
            "non-finite",
        ),
    ],
)
def test_bad_files_raise_mesh_error(tmp_path, name, content, fragment):
    path = tmp_path / name
    if content is not None:
        path.write_bytes(content)
    with pytest.raises(MeshError) as info:
        load_mesh(path)
    assert fragment in info.value.message
    assert info.value.file == str(path)
    assert info.value.hint


@pytest.mark.slow
def test_benchy_sections_match_trimesh(benchy_path):
    geometry = load_mesh(benchy_path)
    assert geometry.triangle_count == 225154
    assert not geometry.watertight
    (lo, hi) = geometry.bounds()
    zs = lo[2] + 0.1 + 0.2 * np.arange(240)
    sections = geometry.sections(zs)
    assert all(s.is_valid and isinstance(s, shapely.MultiPolygon) for s in sections)
    assert all(not s.is_empty for s in sections)
    for k in (3, 60, 130, 200):
        reference = _reference_area(_as_trimesh(geometry), zs[k])
        assert sections[k].area == pytest.approx(reference, rel=5e-3)
        assert geometry.section(zs[k]).equals_exact(sections[k], 0.0)
    volume = sum(s.area for s in sections) * 0.2
    assert volume == pytest.approx(abs(_as_trimesh(geometry).volume), rel=0.01)


def _shells(*meshes: trimesh.Trimesh) -> MeshGeometry:
    """One mesh holding all the given shells as they are (no boolean), like a multi-body STL."""
    return _geometry(trimesh.util.concatenate(list(meshes)))


def _inverted(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """The same shell with every triangle wound the other way (normals pointing inwards)."""
    return trimesh.Trimesh(mesh.vertices, mesh.faces[:, ::-1], process=False)


def _box(size, centre=(0.0, 0.0, 0.0)) -> trimesh.Trimesh:
    return trimesh.creation.box(extents=size).apply_translation(centre)


@pytest.mark.parametrize(
    "a, b",
    [
        (((20, 10, 2), (0, 0, 0)), ((10, 20, 2), (0, 0, 0))),  # a cross: no corner of one inside the other
        (((10, 10, 2), (0, 0, 0)), ((10, 10, 2), (5, 5, 0))),  # a corner of each inside the other
    ],
    ids=["cross", "offset squares"],
)
def test_overlapping_shells_slice_as_their_union(a, b):
    geometry = _shells(_box(*a), _box(*b))
    expected = shapely.union(*(shapely.box(c[0] - s[0] / 2, c[1] - s[1] / 2, c[0] + s[0] / 2, c[1] + s[1] / 2) for s, c in (a, b)))
    sections = geometry.sections([-0.5, 0.3])
    for section in sections:
        assert section.is_valid
        assert section.area == pytest.approx(expected.area, rel=1e-12)
        assert shapely.symmetric_difference(section, expected).area < 1e-9
        assert all(shapely.is_ccw(p.exterior) for p in section.geoms)
    assert geometry.section(0.3).equals_exact(sections[1], 0.0)


def test_shell_inside_a_shell_fills_and_inverted_shell_is_solid():
    outer, inner = _box((10, 10, 10)), _box((4, 4, 4))
    assert _shells(outer, inner).section(0.5).area == pytest.approx(100.0)
    assert _geometry(_inverted(outer)).section(0.5).area == pytest.approx(100.0)


@pytest.mark.parametrize("kind", ["box", "sphere"])
def test_inward_facing_inner_shell_stays_a_hole(kind):
    if kind == "box":
        outer, inner = _box((10, 10, 10)), _box((4, 6, 4), (1, 0, 0))
    else:
        outer, inner = trimesh.creation.icosphere(3, radius=5.0), trimesh.creation.icosphere(3, radius=3.0)
    mesh = trimesh.util.concatenate([outer, _inverted(inner)])
    geometry = _geometry(mesh)
    for z in (-1.3, 0.2, 1.7):
        section = geometry.section(z)
        (polygon,) = section.geoms
        assert len(polygon.interiors) == 1
        assert section.area == pytest.approx(_reference_area(mesh, z), rel=1e-9)
    assert geometry.section(4.0).area == pytest.approx(_reference_area(mesh, 4.0), rel=1e-9)


def test_tube_crossed_by_a_bar_keeps_the_rest_of_its_hole():
    tube = trimesh.creation.annulus(r_min=3.0, r_max=6.0, height=4.0, sections=48)
    section = _shells(tube, _box((14, 2, 2))).section(0.25)
    expected = shapely.union(_geometry(tube).section(0.25), shapely.box(-7, -1, 7, 1))
    assert section.is_valid
    assert shapely.symmetric_difference(section, expected).area < 1e-9
    assert sum(len(p.interiors) for p in section.geoms) == 2
    assert section.contains(shapely.Point(0, 0)) and not section.intersects(shapely.Point(0, 2))


def test_inner_shell_with_a_missing_face_falls_back_to_even_odd():
    inner = _inverted(_box((4, 4, 4)))
    inner.update_faces(np.flatnonzero(inner.face_normals[:, 0] < 0.5))
    geometry = _shells(_box((10, 10, 10)), inner)
    section = geometry.section(0.5)
    assert section.area == pytest.approx(100.0 - 16.0)


@pytest.mark.parametrize("centres", [[(-5, 0, 0), (5, 0, 0)], [(-5, -5, 0), (5, 5, 0)], [(-5, 0, 0), (5, 0, 0), (5, 10, 0)]], ids=["face", "edge", "L"])
def test_bodies_touching_along_shared_edges_slice_as_their_union(tmp_path, centres):
    # merged vertices make the shared edges non-manifold (four faces); the face order must not matter
    path = _save(trimesh.util.concatenate([_box((10, 10, 2), c) for c in centres]), tmp_path / "touching.stl")
    merged = _as_trimesh(load_mesh(path))
    rng = np.random.default_rng(7)
    for _ in range(20):
        shuffled = trimesh.Trimesh(merged.vertices, merged.faces[rng.permutation(len(merged.faces))], process=False)
        section = _geometry(shuffled).section(0.3)
        assert section.is_valid
        assert section.area == pytest.approx(100.0 * len(centres), rel=1e-12)


@pytest.mark.parametrize("name, kwargs", [("torus.stl", {}), ("torus_ascii.stl", {"file_type": "stl_ascii"}), ("torus.obj", {}), ("torus.3mf", {})])
def test_batches_section_like_the_whole_mesh(tmp_path, name, kwargs):
    # without the whole mesh's tables, each call builds tables of the triangles its planes
    # span; the outlines must be those of the whole tables, to the byte
    torus = trimesh.creation.torus(major_radius=10.0, minor_radius=3.0, major_sections=48, minor_sections=24)
    torus.apply_transform(trimesh.transformations.rotation_matrix(0.3, (1, 0, 0)))
    path = _save(torus, tmp_path / name, **kwargs)
    zs = np.linspace(-7.0, 7.0, 71)
    batched = load_mesh(path)
    by_batch = [s for start in range(0, len(zs), 16) for s in batched.sections(zs[start : start + 16])]
    assert "_whole" not in vars(batched)  # no whole tables were built for them
    whole = load_mesh(path)
    whole.prepare_sections()
    assert [s.wkb for s in by_batch] == [s.wkb for s in whole.sections(zs)]
    assert sum(not s.is_empty for s in by_batch) > 50
    assert batched.section(float(zs[0])).is_empty and batched.sections([]) == []


def test_benchy_batches_section_like_the_whole_mesh(benchy_path):
    zs = 0.1 + 0.2 * np.arange(240)
    batched = load_mesh(benchy_path)
    by_batch = [s for start in range(0, len(zs), 16) for s in batched.sections(zs[start : start + 16])]
    assert "_whole" not in vars(batched)
    whole = load_mesh(benchy_path)
    whole.prepare_sections()
    assert [s.wkb for s in by_batch] == [s.wkb for s in whole.sections(zs)]


def test_stable_order_is_numpys_stable_argsort_with_ties_and_overflow():
    """The quicksort of ``key * n + index`` orders like numpy's stable sort, ties in input
    order; keys too large for that product, or negative, take the stable sort itself."""
    from fgslice.design.mesh import _stable_order

    rng = np.random.default_rng(3)
    for keys in (rng.integers(0, 50, 10_000), rng.integers(0, 2**40, 5_000), np.array([2**62, 1, 2**62, 0]),
                 np.array([-3, 5, -3, 0]), np.zeros(7, dtype=np.int64), np.array([], dtype=np.int64)):
        assert np.array_equal(_stable_order(keys), np.argsort(keys, kind="stable"))


def test_merged_vertices_keep_each_groups_first_vertex_in_input_order():
    """Vertices equal after rounding merge into the first of them in input order (its
    coordinates exactly), whatever order the unstable sort leaves within the group."""
    from fgslice.design.mesh import _merge_vertices

    rng = np.random.default_rng(5)
    base = np.rint(rng.random((300, 3)) * 50e8) / 1e8  # on the rounding grid
    copies = rng.integers(0, 300, 3000)
    vertices = base[copies] + rng.uniform(-2e-10, 2e-10, (3000, 3))  # equal after rounding to 1e-8 mm
    kept, inverse = _merge_vertices(vertices)
    firsts = np.array([np.flatnonzero(copies == c)[0] for c in np.unique(copies)])
    assert len(kept) == len(firsts)
    assert len(np.unique(inverse[firsts])) == len(firsts)  # each first is a kept row of its own
    assert np.array_equal(kept[inverse[firsts]], vertices[firsts])
    assert np.allclose(kept[inverse], vertices, atol=1e-9)


def test_vertices_by_height_keep_ties_in_input_order():
    """Vertices at equal heights (-0.0 and 0.0 among them) stay in input order, and faces
    with the same lowest vertex too: the numbering the stable sorts give."""
    from fgslice.design.mesh import _sorted_by_height

    rng = np.random.default_rng(8)
    vertices = rng.random((2000, 3))
    vertices[:, 2] = rng.choice([-0.0, 0.0, 0.2, 0.4, 1.0], 2000)
    faces = rng.integers(0, 2000, (3000, 3))
    got_vertices, got_faces = _sorted_by_height(vertices, faces)
    order = np.argsort(vertices[:, 2], kind="stable")
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    renumbered = rank[faces]
    lowest = renumbered.min(axis=1)
    assert np.array_equal(got_vertices, vertices[order])
    assert np.array_equal(got_faces, renumbered[np.argsort(lowest, kind="stable")])
