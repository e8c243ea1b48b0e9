"""CAD models (STEP, IGES, BREP, CadQuery shapes) through Open CASCADE: parts built with
OCP's primitives, written to files here, sliced through OpenVCAD 2's ``CAD``, OpenVCAD 3's
``CADModel`` and the .vcad ``mesh(...)``, against the analytic solids; bad files and the
missing extra."""

from __future__ import annotations

import importlib.util
import math
import sys
import textwrap
import types
from datetime import datetime, timezone

import numpy as np
import pytest
from click.testing import CliRunner

from fgslice.cli import main
from fgslice.compat.pyvcad_cad import CADModel
from fgslice.compat.script import load_script
from fgslice.design import api, cad, load_design
from fgslice.errors import DesignError, FgsliceError, MeshError
from fgslice.pipeline import slice_to_gcode
from fgslice.settings import load_settings

needs_ocp = pytest.mark.skipif(importlib.util.find_spec("OCP") is None,
                               reason="needs Open CASCADE: pip install 'fgslice[cad]'")

HEADER = "import pyvcad as pv\nimport pyvcad_rendering as viz\nmaterials = pv.default_materials\n"
CUBE = 20.0
"""Edge of the test cube (mm), from (-10, -10, 0) to (10, 10, 20)."""
RADIUS, HEIGHT = 8.0, 6.0
"""The test cylinder (mm): along Z from z = 0, centred on the axis."""


def cube_shape():
    from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox
    from OCP.gp import gp_Pnt

    return BRepPrimAPI_MakeBox(gp_Pnt(-CUBE / 2, -CUBE / 2, 0), CUBE, CUBE, CUBE).Shape()


def cylinder_shape():
    from OCP.BRepPrimAPI import BRepPrimAPI_MakeCylinder

    return BRepPrimAPI_MakeCylinder(RADIUS, HEIGHT).Shape()


def write_step(shape, path):
    from OCP.IFSelect import IFSelect_RetDone
    from OCP.STEPControl import STEPControl_AsIs, STEPControl_Writer

    cad._occ()  # quiets Open CASCADE's messages
    writer = STEPControl_Writer()
    writer.Transfer(shape, STEPControl_AsIs)
    assert writer.Write(str(path)) == IFSelect_RetDone
    return path


def write_iges(shape, path, *, solids: bool):
    """An IGES file of ``shape``: its faces only (what most CAD programs export), or solids."""
    from OCP.IGESControl import IGESControl_Writer

    cad._occ()
    writer = IGESControl_Writer("MM", 1 if solids else 0)
    writer.AddShape(shape)
    writer.ComputeModel()
    assert writer.Write(str(path))
    return path


def script(tmp_path, body: str):
    path = tmp_path / "design.py"
    path.write_text(HEADER + textwrap.dedent("        " + body), encoding="utf-8")
    return path


def extruded_mm3(design, tmp_path) -> float:
    settings = load_settings(None, {"colors": "3", "strategy": "2", "layer_height": "0.3", "thumbnails": ""})
    result = slice_to_gcode(design, settings, tmp_path / "part.gcode", jobs=1,
                            stamp=datetime(2026, 1, 1, tzinfo=timezone.utc))
    return result.stats["extruded_mm3"]


def assert_cube_sections(design, centre=(0.0, 0.0)):
    lo, hi = design.bounds()
    np.testing.assert_allclose(lo, (centre[0] - 10, centre[1] - 10, 0), atol=1e-6)
    np.testing.assert_allclose(hi, (centre[0] + 10, centre[1] + 10, CUBE), atol=1e-6)
    for section in design.sections([0.15, 7.3, 19.85]):
        assert section.area == pytest.approx(CUBE * CUBE, rel=1e-9)
        np.testing.assert_allclose(section.bounds, (centre[0] - 10, centre[1] - 10, centre[0] + 10, centre[1] + 10),
                                   atol=1e-6)


def assert_cylinder_sections(design):
    lo, hi = design.bounds()
    np.testing.assert_allclose(lo, (-RADIUS, -RADIUS, 0), atol=0.02)
    np.testing.assert_allclose(hi, (RADIUS, RADIUS, HEIGHT), atol=0.02)
    for section in design.sections([0.15, 3.0, 5.85]):
        # the inscribed polygon is at most the linear deflection inside the circle
        assert math.pi * (RADIUS - cad.LINEAR_DEFLECTION_MM) ** 2 <= section.area <= math.pi * RADIUS**2
        np.testing.assert_allclose(section.bounds, (-RADIUS, -RADIUS, RADIUS, RADIUS), atol=cad.LINEAR_DEFLECTION_MM)


@needs_ocp
def test_a_v2_script_slices_a_step_cube_to_its_volume(tmp_path):
    write_step(cube_shape(), tmp_path / "cube.step")
    design = load_script(script(tmp_path, 'root = pv.CAD("cube.step", True, materials.id("red"))\n'))
    assert [m.name for m in design.materials] == ["red"]
    assert_cube_sections(design)
    assert extruded_mm3(design, tmp_path) == pytest.approx(CUBE**3, rel=0.03)


@needs_ocp
@pytest.mark.parametrize("solids", [False, True], ids=["iges-faces", "iges-solids"])
def test_a_v2_script_slices_an_iges_cylinder_to_its_volume(tmp_path, solids):
    write_iges(cylinder_shape(), tmp_path / "cylinder.igs", solids=solids)
    design = load_script(script(tmp_path, """root = pv.FGrade(["x/16 + 0.5", "0.5 - x/16"],
                                             [materials.id("red"), materials.id("blue")], False)
        root.set_child(pv.CAD("cylinder.igs", use_fast_mode=False))
        """))
    assert_cylinder_sections(design)
    one = np.ones(1)
    np.testing.assert_allclose(design.fractions(4 * one, 0 * one, 3 * one), [[0.75, 0.25]])
    assert extruded_mm3(design, tmp_path) == pytest.approx(math.pi * RADIUS**2 * HEIGHT, rel=0.03)


@needs_ocp
def test_a_v3_script_slices_a_cadmodel_with_its_attribute(tmp_path):
    write_step(cube_shape(), tmp_path / "cube.stp")
    design = load_script(script(tmp_path, """root = pv.CADModel.from_step("cube.stp").to_node(use_fast_mode=True)
        root.set_attribute(pv.DefaultAttributes.VOLUME_FRACTIONS,
                           pv.VolumeFractionsAttribute(["z/20", "1 - z/20"], [materials.id("red"), materials.id("blue")]))
        viz.Render(root)
        """))
    assert [m.name for m in design.materials] == ["red", "blue"]
    assert_cube_sections(design)
    one = np.ones(1)
    np.testing.assert_allclose(design.fractions(0 * one, 0 * one, 5 * one), [[0.25, 0.75]])
    assert extruded_mm3(design, tmp_path) == pytest.approx(CUBE**3, rel=0.03)


@needs_ocp
def test_v3_cad_models_from_iges_brep_and_v3_cad(tmp_path):
    from OCP.BRepTools import BRepTools

    write_iges(cylinder_shape(), tmp_path / "cylinder.iges", solids=False)
    BRepTools.Write_s(cylinder_shape(), str(tmp_path / "cylinder.brep"))
    for line in ('pv.CADModel.from_iges("cylinder.iges").to_node()',
                 'pv.CADModel.from_brep("cylinder.brep").to_node()',
                 f'pv.CADModel.from_brep_bytes(open({str(tmp_path / "cylinder.brep")!r}, "rb").read()).to_node()',
                 'pv.CAD("cylinder.iges", True)'):
        design = load_script(script(tmp_path, f"root = {line}\n"))
        assert_cylinder_sections(design)


@needs_ocp
def test_cadquery_parts_are_taken_by_duck_typing(tmp_path):
    """A CadQuery ``Shape`` wraps its OCP shape in ``.wrapped``; a ``Workplane`` gives its
    stack with ``.vals()``: stand-ins of both (no cadquery needed), and a raw TopoDS_Shape."""
    from OCP.BRepAlgoAPI import BRepAlgoAPI_Cut
    from OCP.BRepPrimAPI import BRepPrimAPI_MakeCylinder
    from OCP.gp import gp_Ax2, gp_Dir, gp_Pnt

    hole = BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(0, 0, -1), gp_Dir(0, 0, 1)), 3.0, CUBE + 2).Shape()
    plate = BRepAlgoAPI_Cut(cube_shape(), hole).Shape()
    shape = types.SimpleNamespace(wrapped=plate)
    workplane = types.SimpleNamespace(vals=lambda: [shape])
    for value in (plate, shape, workplane, [shape]):
        design = api.design(CADModel.from_cadquery(value).to_node(use_fast_mode=True)._build(None))
        section = design.section(10.0)
        # the hole's inscribed polygon is at most the linear deflection inside its circle
        assert CUBE**2 - math.pi * 3**2 <= section.area <= CUBE**2 - math.pi * (3 - cad.LINEAR_DEFLECTION_MM) ** 2
        assert len(section.geoms) == 1 and len(section.geoms[0].interiors) == 1
    with pytest.raises(DesignError, match="expected a CadQuery Workplane or Shape"):
        CADModel.from_cadquery(42)


@needs_ocp
def test_two_step_parts_move_and_union_like_meshes(tmp_path):
    write_step(cube_shape(), tmp_path / "cube.step")
    write_step(cylinder_shape(), tmp_path / "cylinder.step")
    design = load_script(script(tmp_path, """root = pv.Union(False, [
            pv.CAD("cube.step", True, materials.id("red")),
            pv.Rotate(90, 0, 0, pv.Vec3(0, 0, 0), pv.CAD("cylinder.step", True, materials.id("blue")))])
        """))
    lo, hi = design.bounds()  # the cylinder's axis turned from +z to -y
    np.testing.assert_allclose(lo, (-10, -10, -RADIUS), atol=0.02)
    np.testing.assert_allclose(hi, (10, 10, CUBE), atol=0.02)
    section = design.section(-RADIUS / 2)  # below the cube: the lying cylinder's rectangle
    assert section.area == pytest.approx(2 * RADIUS * math.sqrt(3) / 2 * HEIGHT, rel=2e-3)


@needs_ocp
def test_vcad_mesh_reads_step_files(tmp_path):
    write_step(cube_shape(), tmp_path / "cube.step")
    (tmp_path / "part.vcad").write_text('translate(5, 0, 0) { mesh("cube.step", "blue"); }\n')
    design = load_design(tmp_path / "part.vcad")
    assert [m.name for m in design.materials] == ["blue"]
    assert_cube_sections(design, centre=(5.0, 0.0))


@needs_ocp
def test_file_units_become_millimetres(tmp_path):
    from OCP.Interface import Interface_Static
    from OCP.STEPControl import STEPControl_Writer

    STEPControl_Writer()  # sets up the STEP statics first
    Interface_Static.SetCVal_s("write.step.unit", "INCH")
    try:
        write_step(cube_shape(), tmp_path / "cube_inch.step")
    finally:
        Interface_Static.SetCVal_s("write.step.unit", "MM")
    text = (tmp_path / "cube_inch.step").read_text()
    assert "CONVERSION_BASED_UNIT('INCH'" in text and "(0.393700787" in text  # 10 mm written as inches
    assert_cube_sections(api.design(api.cad(tmp_path / "cube_inch.step")))


@needs_ocp
def test_bad_cad_files_are_named_with_their_path(tmp_path):
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeEdge, BRepBuilderAPI_MakeFace
    from OCP.gp import gp_Pln, gp_Pnt

    write = {
        "missing.step": None,
        "text.step": "this is not STEP\n",
        "lfs.step": "version https://git-lfs.github.com/spec/v1\noid sha256:00\nsize 31219\n",
    }
    for name, text in write.items():
        if text is not None:
            (tmp_path / name).write_text(text)
    write_step(BRepBuilderAPI_MakeEdge(gp_Pnt(0, 0, 0), gp_Pnt(10, 0, 0)).Edge(), tmp_path / "edge.step")
    write_step(BRepBuilderAPI_MakeFace(gp_Pln(), 0, 10, 0, 10).Face(), tmp_path / "face.step")
    write_iges(BRepBuilderAPI_MakeFace(gp_Pln(), 0, 10, 0, 10).Face(), tmp_path / "face.igs", solids=False)
    expected = {
        "missing.step": "CAD file not found",
        "text.step": "not a readable STEP file",
        "lfs.step": "Git LFS pointer",
        "edge.step": "holds no solid",
        "face.step": "do not close into a solid: 4 free edges",
        "face.igs": "do not close into a solid",
    }
    for name, message in expected.items():
        with pytest.raises(MeshError, match=message) as raised:
            load_script(script(tmp_path, f'root = pv.CAD("{name}", True, 1)\n'))
        assert name in raised.value.message, raised.value.message
        assert raised.value.file.endswith("design.py") and raised.value.line == 4
    result = CliRunner().invoke(main, ["check", str(tmp_path / "design.py")])
    assert result.exit_code != 0 and "face.igs" in result.output and "Traceback" not in result.output
    with pytest.raises(MeshError, match="edge.step.*holds no solid"):
        load_script(script(tmp_path, 'root = pv.CADModel.from_step("edge.step").to_node()\n'))
    with pytest.raises(DesignError, match=r"CADModel.select_faces is not supported"):
        load_script(script(tmp_path, 'pv.CADModel.from_step("face.step").select_faces()\n'))


def test_a_missing_extra_names_it(tmp_path, monkeypatch):
    (tmp_path / "part.step").write_text("ISO-10303-21;\n")
    monkeypatch.setitem(sys.modules, "OCP", None)  # `import OCP` now fails as if not installed
    path = script(tmp_path, 'root = pv.CAD("part.step", True, materials.id("red"))\n')
    with pytest.raises(DesignError, match="need Open CASCADE") as raised:
        load_script(path)
    assert "pip install 'fgslice[cad]'" in raised.value.hint and raised.value.line == 4
    result = CliRunner().invoke(main, ["check", str(path)])
    assert result.exit_code != 0 and "pip install 'fgslice[cad]'" in result.output
    with pytest.raises(FgsliceError, match="need Open CASCADE"):
        load_script(script(tmp_path, "root = pv.CADModel.from_cadquery(object()).to_node()\n"))
    (tmp_path / "part.vcad").write_text('mesh("part.step", "red");\n')
    with pytest.raises(DesignError, match="mesh 'part.step': CAD models .* need Open CASCADE") as raised:
        load_design(tmp_path / "part.vcad")
    assert "pip install 'fgslice[cad]'" in raised.value.hint and raised.value.line == 1
