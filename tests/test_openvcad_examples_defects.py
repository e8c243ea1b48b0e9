"""Defects found by running OpenVCAD's examples, each on the input that found it."""

from __future__ import annotations

import textwrap

import numpy as np
import pytest

from fgslice.compat.script import load_script

HEADER = "import pyvcad as pv\nimport pyvcad_rendering as viz\nmaterials = pv.default_materials\n"


def _script(tmp_path, body: str, name: str = "design.py"):
    path = tmp_path / name
    path.write_text(HEADER + textwrap.dedent(body))
    return path


@pytest.mark.parametrize("mix, expected", [(True, (0.5, 0.5)), (False, (1.0, 0.0))])
def test_intersection_with_the_distribution_flag_mixes_the_materials(tmp_path, mix, expected):
    """5-3_multi_material_hello_world: a red and a blue sphere intersected with
    ``intersect_distribution`` print purple (half of each) in their lens; without, red."""
    path = _script(tmp_path, f"""
        radius = 5
        left_sphere  = pv.Sphere(pv.Vec3(-radius/2, 0, 0), radius, materials.id("red"))
        right_sphere = pv.Sphere(pv.Vec3(+radius/2, 0, 0), radius, materials.id("blue"))
        root = pv.Intersection({mix}, [left_sphere, right_sphere])
        viz.Render(root, materials)
        """)
    design = load_script(path)
    assert [m.name for m in design.materials] == ["red", "blue"]
    lo, hi = design.bounds()
    assert lo[0] == pytest.approx(-2.5) and hi[0] == pytest.approx(2.5)
    x = np.array([-2.0, 0.0, 1.5])
    fractions = design.fractions(x, np.zeros(3), np.zeros(3))
    assert np.allclose(fractions, np.tile(expected, (3, 1)))


def test_rings_that_shrink_below_three_points_are_dropped_before_building():
    """openvcad_logo_qr_code's sampled gyroid: a traced ring whose repeated points leave
    two distinct ones made every layer fail ("A linearring requires at least 4
    coordinates"); it is dropped and the other rings kept."""
    from fgslice.design.sampled import _polygons

    points = np.array([[0, 0], [10, 0], [10, 10], [0, 10], [5, 5], [5, 5], [6, 6.0], [20, 0], [20, 0], [20, 0]])
    ring = np.array([0, 0, 0, 0, 1, 1, 1, 2, 2, 2])
    result = _polygons(points, ring)
    assert result.is_valid and result.area == pytest.approx(100.0)
    assert _polygons(points[4:], ring[4:]).is_empty


TRI_MATERIAL_SHEET = """
def create_color_calibration_sheet(swatch_size, count_x, count_y, thickness, colors):
    union = pv.Union()
    for i in range(count_x):
        for j in range(count_y):
            c_frac = i / (count_x - 1)
            m_frac = j / (count_y - 1)
            fractions = [f"{c_frac:.3f}", f"{m_frac:.3f}", f"{1.0 - (c_frac + m_frac):.3f}"]
            center = pv.Vec3(-swatch_size * count_x / 2 + swatch_size / 2 + i * swatch_size,
                             -swatch_size * count_y / 2 + swatch_size / 2 + j * swatch_size, 0)
            base = pv.RectPrism(center, pv.Vec3(swatch_size, swatch_size, thickness), colors[2])
            union.add_child(pv.FGrade(fractions, colors, True, base))
    return union

mats = pv.default_materials
root = create_color_calibration_sheet(25, 12, 12, 10, [mats.id("cyan"), mats.id("magenta"), mats.id("white")])
viz.Render(root, mats)
"""


def test_check_reports_what_slice_refuses_before_any_layer(tmp_path):
    """tri_material_sheet: 300 x 300 mm of three materials. ``check`` called it usable,
    then ``slice`` refused it for the bed and the two-channel hotend; both are errors of
    ``check`` now, with the same words."""
    from fgslice.design.check import check_design
    from fgslice.errors import FgsliceError
    from fgslice.pipeline import slice_to_gcode
    from fgslice.settings import load_settings

    design = load_script(_script(tmp_path, TRI_MATERIAL_SHEET))
    settings = load_settings(None)
    report = check_design(design, settings=settings, samples=40)
    assert not report.usable
    assert any("3 materials but the mixing hotend has 2 channels" in e for e in report.errors)
    assert any("footprint 300.00 x 300.00 mm exceeds the bed" in e for e in report.errors)
    with pytest.raises(FgsliceError) as refused:
        slice_to_gcode(design, settings, tmp_path / "sheet.gcode", jobs=1)
    assert any(refused.value.message in e for e in report.errors)
    roomy = load_settings(None, {"channels": "3", "colors": "4", "bed_x": "320", "bed_y": "320"})
    assert check_design(design, settings=roomy, samples=40).usable


def test_a_git_lfs_pointer_is_named_with_the_fix(tmp_path):
    """An OpenVCAD checkout without ``git lfs pull`` holds pointers in place of meshes."""
    from fgslice.design.mesh import load_mesh
    from fgslice.errors import MeshError

    for name in ("gear.stl", "keychain_blank.3mf"):
        pointer = tmp_path / name
        pointer.write_text("version https://git-lfs.github.com/spec/v1\n"
                           "oid sha256:84cafc925771211edfddf4f7726c9a48d8f95e793598d8aac642188a9172b207\nsize 9116\n")
        with pytest.raises(MeshError) as error:
            load_mesh(pointer)
        assert "this is a Git LFS pointer" in error.value.message and "git lfs pull" in error.value.message


def test_legacy_designs_find_meshes_named_from_openvcads_resources_root(tmp_path):
    """OpenVCAD's legacy .vcad designs (studio/examples/legacy/...) name their meshes
    ``examples/data/3d_models/...``, relative to the folder holding ``examples``."""
    import trimesh

    from fgslice.design.language import parse_design

    models = tmp_path / "studio" / "examples" / "data" / "3d_models"
    models.mkdir(parents=True)
    trimesh.creation.cylinder(radius=5, height=10).export(models / "cylinder.stl")
    folder = tmp_path / "studio" / "examples" / "legacy" / "mechanical" / "compression"
    folder.mkdir(parents=True)
    design_path = folder / "cylinder_no_transition.vcad"
    design_path.write_text('mesh("examples/data/3d_models/cylinder.stl", "red");\n')
    design = parse_design(design_path.read_text(), file=design_path)
    lo, hi = design.bounds()
    assert np.allclose(lo, (-5, -5, -5), atol=1e-6) and np.allclose(hi, (5, 5, 5), atol=1e-6)
