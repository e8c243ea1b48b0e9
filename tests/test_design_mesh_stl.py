"""STL reading (binary and ASCII) without trimesh: parity with trimesh, errors for bad files, imports."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

from fgslice.design.mesh import load_mesh
from fgslice.errors import MeshError

RECORD = np.dtype([("normal", "<f4", 3), ("corners", "<f4", (3, 3)), ("attribute", "<u2")])


def _binary_stl(triangles: np.ndarray, *, header: bytes = b"", count: int | None = None) -> bytes:
    """A binary STL of (F, 3, 3) corners; ``count`` overrides the announced triangle count."""
    records = np.zeros(len(triangles), dtype=RECORD)
    records["corners"] = triangles
    announced = len(triangles) if count is None else count
    return header.ljust(80, b" ")[:80] + announced.to_bytes(4, "little") + records.tobytes()


def _ascii_facet(corners) -> str:
    vertices = "".join(f"      vertex {float(x)!r} {float(y)!r} {float(z)!r}\n" for x, y, z in corners)
    return f"  facet normal 0 0 1\n    outer loop\n{vertices}    endloop\n  endfacet\n"


def _ascii_stl(triangles, name: str = "part") -> str:
    return f"solid {name}\n" + "".join(_ascii_facet(t) for t in np.asarray(triangles, dtype=float)) + f"endsolid {name}\n"


@pytest.fixture
def sphere() -> trimesh.Trimesh:
    return trimesh.creation.icosphere(subdivisions=2, radius=4.0).apply_translation((1.0, -2.0, 3.0))


def _canonical(triangles: np.ndarray) -> np.ndarray:
    """(F, 9) rows of corners in lexicographic row order, for comparing triangle soups."""
    rows = np.asarray(triangles, dtype=float).reshape(-1, 9)
    return rows[np.lexsort(rows.T[::-1])]


def _trimesh_area(mesh: trimesh.Trimesh, z: float) -> float:
    """Area of trimesh's own section of a watertight mesh at height z."""
    return mesh.section(plane_origin=(0, 0, z), plane_normal=(0, 0, 1)).to_2D()[0].area


def test_binary_and_ascii_stl_read_like_trimesh(tmp_path, sphere):
    binary = tmp_path / "sphere.stl"
    ascii_ = tmp_path / "sphere_ascii.stl"
    sphere.export(binary)
    sphere.export(ascii_, file_type="stl_ascii")
    for path in (binary, ascii_):
        geometry = load_mesh(path)
        reference = trimesh.load(path, process=False)
        assert geometry.triangle_count == len(sphere.faces)
        whole = geometry._whole  # the whole mesh's tables
        assert len(whole.vertices) == len(sphere.vertices)  # shared corners merged
        assert geometry.watertight
        ours = _canonical(whole.vertices[whole.faces])
        np.testing.assert_array_equal(ours, _canonical(reference.triangles))
        assert geometry.section(3.0).area == pytest.approx(_trimesh_area(reference, 3.0), rel=1e-9)


def test_binary_header_starting_with_solid_is_binary(tmp_path, sphere):
    path = tmp_path / "solid_header.stl"
    path.write_bytes(_binary_stl(sphere.triangles, header=b"solid exported by a CAD program"))
    geometry = load_mesh(path)
    assert geometry.triangle_count == len(sphere.faces)
    assert geometry.section(3.0).area == pytest.approx(_trimesh_area(sphere, 3.0), rel=1e-6)


def test_ascii_variants_multiple_solids_case_and_exponents(tmp_path):
    text = _ascii_stl([[[0, 0, 0], [10, 0, 0], [0, 10, 0]]], "first") + _ascii_stl([[[0, 0, 5], [10, 0, 5], [0, 10, 5]]], "second")
    path = tmp_path / "two.stl"
    path.write_text(text.upper().replace("10.0", "1.0E+1").replace("5.0", "\t.5e1"))
    geometry = load_mesh(path)
    assert geometry.triangle_count == 2
    assert geometry.bounds() == ((0.0, 0.0, 0.0), (10.0, 10.0, 5.0))
    assert not geometry.watertight


def _error(path: Path, content: bytes) -> MeshError:
    path.write_bytes(content)
    with pytest.raises(MeshError) as info:
        load_mesh(path)
    assert info.value.file == str(path)
    assert info.value.hint
    return info.value


def test_truncated_and_mismatched_binary_stl(tmp_path, sphere):
    data = _binary_stl(sphere.triangles)
    error = _error(tmp_path / "cut.stl", data[:-30])
    assert f"announcing {len(sphere.faces)} triangles" in error.message and "truncated" in error.message
    error = _error(tmp_path / "count.stl", _binary_stl(sphere.triangles, count=len(sphere.faces) - 1))
    assert f"announcing {len(sphere.faces) - 1} triangles" in error.message and "truncated" not in error.message


@pytest.mark.parametrize(
    "content, fragment",
    [
        (b"", "too short"),
        (b"\x89PNG\r\n\x1a\n" + bytes(range(256)) * 4, "not a valid STL"),
        (b"solid empty\nendsolid empty\n", "no triangles"),
        (bytes(80) + (0).to_bytes(4, "little"), "no triangles"),
    ],
    ids=["empty file", "not an STL", "ascii without facets", "binary without triangles"],
)
def test_files_that_are_not_usable_stl(tmp_path, content, fragment):
    assert fragment in _error(tmp_path / "bad.stl", content).message


def test_nan_coordinates_name_the_triangle(tmp_path, sphere):
    triangles = sphere.triangles.copy()
    triangles[7, 2, 0] = np.nan
    assert "triangle 7 has a non-finite coordinate" in _error(tmp_path / "nan.stl", _binary_stl(triangles)).message
    text = _ascii_stl(triangles[:9]).replace("nan", "-inf")
    assert "triangle 7 has a non-finite coordinate" in _error(tmp_path / "inf.stl", text.encode()).message


def test_malformed_ascii_facet_points_at_its_line(tmp_path):
    good = [[[0, 0, 0], [1, 0, 0], [0, 1, 0]]]
    lines = _ascii_stl(good * 3).splitlines()
    lines[12] = "      vertex 1 0 zero"  # a vertex of the second facet
    error = _error(tmp_path / "malformed.stl", "\n".join(lines).encode())
    assert "malformed ASCII STL facet" in error.message
    assert (error.line, error.column) == (9, 3)
    cut = _ascii_stl(good * 2).rsplit("endsolid", 1)[0]
    assert "ends without 'endsolid'" in _error(tmp_path / "cut.stl", cut.encode()).message


def test_benchy_binary_reads_exactly_like_trimesh(benchy_path):
    geometry = load_mesh(benchy_path)
    reference = trimesh.load(benchy_path, process=False)
    assert geometry.triangle_count == len(reference.faces)
    distinct = np.unique(np.ascontiguousarray(reference.vertices).view(np.dtype((np.void, 24))))
    whole = geometry._whole  # the whole mesh's tables
    assert len(whole.vertices) == len(distinct)
    np.testing.assert_array_equal(_canonical(whole.vertices[whole.faces]), _canonical(reference.triangles))


def _modules_after(code: str) -> set[str]:
    out = subprocess.run([sys.executable, "-c", code + "\nimport sys; print(' '.join(sys.modules))"], capture_output=True, text=True, check=True)
    return set(out.stdout.split())


def test_designs_import_only_what_they_need(tmp_path, sphere):
    plain = tmp_path / "plain.vcad"
    plain.write_text('fgrade(["z/10", "1-z/10"], ["red", "blue"]) { cylinder(5, 10); }')
    modules = _modules_after(f"from fgslice.design import load_design; load_design({str(plain)!r}).section(0.0)")
    assert "fgslice.design.mesh" not in modules and "trimesh" not in modules
    sphere.export(tmp_path / "sphere.stl")
    meshed = tmp_path / "meshed.vcad"
    meshed.write_text('mesh("sphere.stl");')
    modules = _modules_after(f"from fgslice.design import load_design; d = load_design({str(meshed)!r}); d.section(3.0)")
    assert "fgslice.design.mesh" in modules
    assert "trimesh" not in modules and "scipy" not in modules
