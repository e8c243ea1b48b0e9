"""OpenVCAD Python scripts: each pyvcad class against the equivalent .vcad design, and
scripts that render nothing, use what is not supported, or fail."""

from __future__ import annotations

import math
import subprocess
import sys
import textwrap
import types

import numpy as np
import pytest
import trimesh
from click.testing import CliRunner

from fgslice.cli import main
from fgslice.compat import open_design
from fgslice.compat.script import load_script
from fgslice.compat import pyvcad_rendering
from fgslice.design import load_design
from fgslice.errors import DesignError, DesignSyntaxError, MeshError
from fgslice.pipeline import slice_to_gcode
from fgslice.settings import load_settings
from tests.conftest import EXAMPLES

HEADER = "import pyvcad as pv\nimport pyvcad_rendering as viz\nmaterials = pv.default_materials\n"
RED, BLUE = 'materials.id("red")', 'materials.id("blue")'

# (script body after HEADER, the same design in .vcad)
CASES = {
    "RectPrism": (
        f"root = pv.RectPrism(pv.Vec3(1, 2, 3), pv.Vec3(10, 8, 4), {RED})",
        'translate(1, 2, 3) { rectprism(10, 8, 4, "red"); }',
    ),
    "Sphere + Union(add_child)": (
        f"""root = pv.Union()
        root.add_child(pv.Sphere(pv.Vec3(-2, 0, 0), 4, {RED}))
        root.add_child(pv.Sphere(2, 0, 0, 4, {BLUE}))
        viz.Render(root, materials)""",
        'union() { translate(-2, 0, 0) { sphere(4, "red"); } translate(2, 0, 0) { sphere(4, "blue"); } }',
    ),
    "Cylinder + Union(flag, children)": (
        f"""viz.Render(pv.Union(False, [pv.Cylinder(pv.Vec3(0, 0, 1), 3, 6, {RED}),
                                   pv.Cylinder(pv.Vec3(4, 0, 0), 2, 4, {BLUE})]), materials)""",
        'union() { translate(0, 0, 1) { cylinder(3, 6, "red"); } translate(4, 0, 0) { cylinder(2, 4, "blue"); } }',
    ),
    "Intersection": (
        f"""root = pv.Intersection(False, [pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(8, 8, 8), {BLUE}),
                                       pv.Sphere(pv.Vec3(0, 0, 0), 5.5, {RED})])""",
        'intersection() { rectprism(8, 8, 8, "blue"); sphere(5.5, "red"); }',
    ),
    "Difference(a, b)": (
        f"root = pv.Difference(pv.Sphere(pv.Vec3(0, 0, 0), 5, {RED}), pv.Cylinder(pv.Vec3(0, 0, 0), 2, 12, {BLUE}))",
        'difference() { sphere(5, "red"); cylinder(2, 12, "blue"); }',
    ),
    "Difference + set_left/set_right": (
        f"""root = pv.Difference()
        root.set_left(pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(10, 10, 4), {BLUE}))
        root.set_right(pv.Sphere(pv.Vec3(5, 5, 0), 4, {RED}))""",
        'difference() { rectprism(10, 10, 4, "blue"); translate(5, 5, 0) { sphere(4, "red"); } }',
    ),
    "Translate": (
        f"""moved = pv.Translate(3, -2, 1)
        moved.set_child(pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(6, 4, 3), {RED}))
        root = pv.Union(False, [moved, pv.Translate(-4, 0, 0, pv.Sphere(pv.Vec3(0, 0, 0), 2, {BLUE}))])""",
        'union() { translate(3, -2, 1) { rectprism(6, 4, 3, "red"); } translate(-4, 0, 0) { sphere(2, "blue"); } }',
    ),
    "Rotate about a point, roll then yaw then pitch": (
        f"root = pv.Rotate(30, 20, 45, pv.Vec3(2, 1, 0), pv.RectPrism(pv.Vec3(2, 1, 0), pv.Vec3(10, 4, 3), {RED}))",
        'translate(2, 1, 0) { rotate(30, 0, 0) { rotate(0, 20, 0) { rotate(0, 0, 45) { translate(-2, -1, 0) {'
        ' translate(2, 1, 0) { rectprism(10, 4, 3, "red"); } } } } } }',
    ),
    "Rotate(angles) and Union of nodes (OpenVCAD 3)": (
        f"""rod = pv.Cylinder(pv.Vec3(0, 0, 0), 1, 8, {RED})
        root = pv.Union(rod, pv.Rotate(pv.Vec3(90, 0, 0), rod), pv.Rotate(0, 90, 0, rod))""",
        'union() { cylinder(1, 8, "red"); rotate(90, 0, 0) { cylinder(1, 8, "red"); }'
        ' rotate(0, 90, 0) { cylinder(1, 8, "red"); } }',
    ),
    "Scale": (
        f"root = pv.Union(0.0, [pv.Scale(2, 1, 0.5, pv.Sphere(pv.Vec3(0, 0, 0), 3, {BLUE})),"
        f" pv.Scale(1.5, pv.Sphere(pv.Vec3(0, 0, 5), 1, {RED}))])",
        'union() { scale(2, 1, 0.5) { sphere(3, "blue"); } scale(1.5) { translate(0, 0, 5) { sphere(1, "red"); } } }',
    ),
    "FGrade(set_child) over an ungraded child": (
        f"""bar = pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(20, 10, 4), 1)
        root = pv.FGrade(["x/20 + 0.5", "-x/20 + 0.5"], [{RED}, {BLUE}], False)
        root.set_child(bar)
        viz.Render(root, materials)""",
        'fgrade(["x/20 + 0.5", "-x/20 + 0.5"], ["red", "blue"]) { rectprism(20, 10, 4); }',
    ),
    "FGrade(child) over a child of one of its materials": (
        f"""ball = pv.Sphere(pv.Vec3(0, 0, 0), 5, {RED})
        root = pv.FGrade(["abs(d)/3", "1 - abs(d)/3"], [{RED}, {BLUE}], True, ball)""",
        'fgrade(["abs(d)/3", "1 - abs(d)/3"], ["red", "blue"]) { sphere(5, "red"); }',
    ),
    "FGrade with Python functions, on arrays and point by point": (
        f"""import math
        def along(x, y, z, rho, phic, r, theta, phis):
            return x / 20 + 0.5
        def around(x, y, z, rho, phic, r, theta, phis, d):
            return 0.5 + 0.5 * math.cos(theta) + abs(d) / 3
        materials = pv.default_materials()
        root = pv.FGrade([along, around], [{RED}, {BLUE}], True, pv.Cylinder(pv.Vec3(0, 0, 0), 6, 3, 1))""",
        'fgrade(["x/20 + 0.5", "0.5 + 0.5 cos(theta) + abs(d)/3"], ["red", "blue"]) { cylinder(6, 3); }',
    ),
    "Function": (
        f"root = pv.Function('x^2 + y^2 - 9', {BLUE}, pv.Vec3(-4, -4, 0), pv.Vec3(4, 4, 5))",
        'function((-4, -4, 0), (4, 4, 5), "x^2 + y^2 - 9", "blue");',
    ),
    "Function without its box, FGrade of material numbers": (
        """root = pv.FGrade(['x/8 + 0.5', '0.5 - x/8'], [1, 3], True, pv.Function('x^2 + y^2 + z^2 - 16'))""",
        'fgrade(["x/8 + 0.5", "0.5 - x/8"], ["red", "blue"]) { function((-10, -10, -10), (10, 10, 10), '
        '"x^2 + y^2 + z^2 - 16"); }',
    ),
    "Python function naming its coordinates": (
        f"""import math
        def wheel(theta, offset=0.0):
            return 0.5 + 0.5 * math.cos(theta - offset)
        root = pv.FGrade([wheel, lambda theta: 0.5 - 0.5 * math.cos(theta)], [{RED}, {BLUE}], True,
                         pv.Cylinder(pv.Vec3(0, 0, 0), 6, 3, 1))""",
        'fgrade(["0.5 + 0.5 cos(theta)", "0.5 - 0.5 cos(theta)"], ["red", "blue"]) { cylinder(6, 3); }',
    ),
    "Strut": (
        f"root = pv.Strut(pv.Vec3(-4, 0, 0), pv.Vec3(4, 2, 1), 1.5, {RED})",
        'strut((-4, 0, 0), (4, 2, 1), 1.5, "red");',
    ),
    "Mesh": (
        f"""root = pv.Union(False, [pv.Mesh("block.stl", {RED}),
                                   pv.Mesh("block.stl", pv.Vec3(0.1, 0.1, 0.1), {BLUE}, True)])""",
        'union() { mesh("block.stl", "red"); mesh("block.stl", "blue"); }',
    ),
}


def script(tmp_path, body: str, name: str = "design.py"):
    path = tmp_path / name
    path.write_text(HEADER + textwrap.dedent("        " + body) + "\n", encoding="utf-8")
    return path


def extruded_mm3(design, tmp_path, name):
    settings = load_settings(None, {"colors": "3", "strategy": "2", "layer_height": "0.3", "thumbnails": ""})
    return slice_to_gcode(design, settings, tmp_path / f"{name}.gcode", jobs=1).stats["extruded_mm3"]


@pytest.mark.parametrize("case", CASES)
def test_each_class_matches_the_vcad_design(case, tmp_path):
    body, vcad = CASES[case]
    trimesh.creation.box((6, 4, 3)).apply_translation((1, 0, 0)).export(tmp_path / "block.stl")
    python = load_script(script(tmp_path, body))
    (tmp_path / "design.vcad").write_text(vcad, encoding="utf-8")
    text = load_design(tmp_path / "design.vcad")
    assert [m.name for m in python.materials] == [m.name for m in text.materials]
    np.testing.assert_allclose(python.bounds(), text.bounds(), atol=1e-9)
    (lo, hi), rng = text.bounds(), np.random.default_rng(25)
    x, y, z = (rng.uniform(a - 1, b + 1, 3000) for a, b in zip(lo, hi))
    np.testing.assert_allclose(python.sdf(x, y, z), text.sdf(x, y, z), atol=1e-9)
    inside = text.sdf(x, y, z) < 0
    assert inside.sum() > 100
    np.testing.assert_allclose(python.fractions(x[inside], y[inside], z[inside]),
                               text.fractions(x[inside], y[inside], z[inside]), atol=1e-12)
    assert extruded_mm3(python, tmp_path, "py") == pytest.approx(extruded_mm3(text, tmp_path, "vcad"), rel=1e-12)


def test_the_issue_example_slices_to_its_volume_with_the_grade(tmp_path):
    path = script(tmp_path, f"""bar = pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(40, 20, 3), 1)
        root = pv.FGrade(["x/40 + 0.5", "-x/40 + 0.5"], [{RED}, {BLUE}], False)
        root.set_child(bar)
        viz.Render(root, materials)""")
    design = load_script(path)
    assert [m.name for m in design.materials] == ["red", "blue"]
    one = np.array([1.0])
    np.testing.assert_allclose(design.fractions(10 * one, 0 * one, 0 * one), [[0.75, 0.25]])
    np.testing.assert_allclose(design.fractions(-20 * one, 0 * one, 0 * one), [[0.0, 1.0]])
    assert extruded_mm3(design, tmp_path, "bar") == pytest.approx(40 * 20 * 3, rel=0.05)


def test_the_example_script_is_the_example_design():
    python = open_design(EXAMPLES / "cylinder_z_gradient.py")
    text = open_design(EXAMPLES / "cylinder_z_gradient.vcad")
    rng = np.random.default_rng(7)
    x, y, z = rng.uniform(-16, 16, 2000), rng.uniform(-16, 16, 2000), rng.uniform(-1, 71, 2000)
    np.testing.assert_allclose(python.sdf(x, y, z), text.sdf(x, y, z), atol=1e-9)
    np.testing.assert_allclose(python.fractions(x, y, z), text.fractions(x, y, z), atol=1e-12)
    assert [m.name for m in python.materials] == ["blue", "yellow"]


def test_cli_slices_and_checks_a_script(tmp_path):
    path = script(tmp_path, f"""root = pv.FGrade(["x/8 + 0.5", "0.5 - x/8"], [{RED}, {BLUE}], True)
        root.set_child(pv.Sphere(pv.Vec3(0, 0, 0), 4, 1))""")
    out = tmp_path / "ball.gcode"
    result = CliRunner().invoke(main, ["slice", str(path), "-o", str(out), "--jobs", "1"])
    assert result.exit_code == 0, result.output
    assert out.read_text().count("\n") > 100
    result = CliRunner().invoke(main, ["check", str(path)])
    assert result.exit_code == 0 and "red" in result.output
    result = CliRunner().invoke(main, ["simulate", str(out), "--design", str(path)])
    assert result.exit_code == 0 and "composition error mean" in result.output, result.output
    png = tmp_path / "layer.png"
    result = CliRunner().invoke(main, ["preview", str(out), "-o", str(png), "--design", str(path)])
    assert result.exit_code == 0 and png.stat().st_size > 1000, result.output
    assert "pyvcad" not in sys.modules and "pyvcad_rendering" not in sys.modules


def test_rotate_applies_roll_then_yaw_then_pitch(tmp_path):
    # yaw 90 about Y leaves a point on +y where it is, then pitch 90 about X takes +y to +z
    path = script(tmp_path, f"root = pv.Rotate(90, 90, 0, pv.Vec3(0, 0, 0), pv.Sphere(pv.Vec3(0, 5, 0), 1, {RED}))")
    lo, hi = load_script(path).bounds()
    np.testing.assert_allclose((np.add(lo, hi) / 2), (0, 0, 5), atol=1e-9)


def test_export_wins_over_render_and_the_last_call_counts(tmp_path):
    path = script(tmp_path, f"""a = pv.Sphere(pv.Vec3(0, 0, 0), 1, {RED})
        b = pv.Sphere(pv.Vec3(0, 0, 0), 2, {RED})
        c = pv.Sphere(pv.Vec3(0, 0, 0), 3, {RED})
        root = a
        viz.Render(b, materials)
        viz.Export(c, materials)
        viz.Render(a, materials)""")
    assert load_script(path).bounds()[1] == pytest.approx((3, 3, 3))


def test_script_without_a_rendered_root_is_refused(tmp_path):
    path = script(tmp_path, f"ball = pv.Sphere(pv.Vec3(0, 0, 0), 1, {RED})")
    out = tmp_path / "design.gcode"
    result = CliRunner().invoke(main, ["slice", str(path), "-o", str(out)])
    assert result.exit_code == 2
    assert "the script renders no design" in result.output and "Render(root, materials)" in result.output
    assert not out.exists()
    not_a_node = script(tmp_path, "root = 42", "number.py")
    with pytest.raises(DesignError, match="'root' is a int, not a pyvcad node"):
        load_script(not_a_node)


@pytest.mark.parametrize("body, line, message", [
    ("lattice = pv.GraphLattice(pv.LatticeType.BCC, pv.Vec3(1, 1, 1), 0.1, 1)", 4,
     "pyvcad.LatticeType.BCC is not supported"),
    (f"ball = pv.Sphere(pv.Vec3(0, 0, 0), 1, {RED}, sample=2)", 4, "Sphere has no argument 'sample'"),
    (f"box = pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(1, 1, 1), {RED}, 2)", 4, r"RectPrism takes at most 3 arguments"),
    ("rod = pv.Strut(pv.Vec3(0, 0, 0), radius=1)", 4, "Strut is missing its argument 'end'"),
    ("rod = pv.Cylinder(pv.Vec3(0, 0, 0), 1, 2, 1, center=pv.Vec3(0, 0, 0))", 4, "Cylinder got 'center' twice"),
    (f"ball = pv.Sphere(pv.Vec3(0, 0, 0), 1, {RED})\n        size = ball.volume()", 5,
     "Sphere.volume is not supported"),
    (f"root = pv.Union(-2.0, False, [pv.Sphere(pv.Vec3(0, 0, 0), 1, {RED})])", 4, r"k must be >= 0, got -2"),
    ("import pyvcad_rendering as viz\n        viz.RenderFrame()", 5, "pyvcad_rendering.RenderFrame is not supported"),
    ("root = pv.Translate(1, 2)", 4, r"Translate takes \(\) or \(x, y, z\), then optionally the child, got 2"),
    ("root = pv.Rotate(pv.Vec3(0, 0, 0), 5)", 4, r"Rotate takes .* \(angles: Vec3\) .*, got 2"),
    ("root = pv.FGrade(['x', '1-x'], ['red', 2], False, pv.Sphere(pv.Vec3(0, 0, 0), 1))", 4,
     "materials must be a list of ids"),
    ("root = pv.FGrade(['x', '1-x'], [1, 200], False, pv.Sphere(pv.Vec3(0, 0, 0), 1))", 4,
     "material id 200 is not in the material table"),
    ("root = pv.Sphere(pv.Vec3(0, 0, 0), -1)", 4, "r must be positive"),
    ("root = pv.Union()", 4, "Union has no children"),
    (f"root = pv.Union(False, [pv.Sphere(pv.Vec3(0, 0, 0), 1, {RED})], 3)", 4, r"Union takes \(\[k\]"),
])
def test_what_is_outside_the_subset_is_named_at_its_line(tmp_path, body, line, message):
    path = script(tmp_path, body)
    with pytest.raises(DesignError, match=message) as caught:
        load_script(path)
    assert (caught.value.file, caught.value.line) == (str(path), line)


def test_unknown_material_is_reported_at_the_primitive(tmp_path):
    path = script(tmp_path, """ball = pv.Sphere(pv.Vec3(0, 0, 0), 1, materials.id("nosuch"))
        viz.Render(pv.Union(False, [ball]), materials)""")
    with pytest.raises(DesignError, match="unknown material 'nosuch'") as caught:
        load_script(path)
    assert caught.value.line == 4 and "materials.id(\"nosuch\")" in caught.value.source_line


def test_a_bad_expression_is_shown_at_the_fgrade_line(tmp_path):
    path = script(tmp_path, f"""ball = pv.Sphere(pv.Vec3(0, 0, 0), 1, 1)
        grade = pv.FGrade(["x +* 2", "1"], [{RED}, {BLUE}], True, ball)
        viz.Render(grade, materials)""")
    with pytest.raises(DesignSyntaxError, match="unexpected") as caught:
        load_script(path)
    assert (caught.value.file, caught.value.line, caught.value.source_line) == (str(path), 5, "x +* 2")


def test_a_missing_mesh_names_the_script_line(tmp_path):
    path = script(tmp_path, f'part = pv.Mesh("../data/nothere.stl", {RED})')
    with pytest.raises(MeshError, match="mesh file not found") as caught:
        load_script(path)
    assert (caught.value.file, caught.value.line) == (str(path), 4)


def test_an_exception_of_the_script_is_reported_at_its_own_frame(tmp_path):
    path = script(tmp_path, """def size(n):
            return 10 / n
        root = pv.Sphere(pv.Vec3(0, 0, 0), size(0))""")
    result = CliRunner().invoke(main, ["check", str(path)])
    assert result.exit_code == 2
    assert f"{path}:5:" in result.output
    assert "the script raised ZeroDivisionError: division by zero" in result.output
    assert "return 10 / n" in result.output and "Traceback" not in result.output
    assert "pyvcad" not in sys.modules


def test_syntax_and_import_errors_of_the_script(tmp_path):
    broken = script(tmp_path, "root = pv.Sphere(pv.Vec3(0, 0, 0), 1", "broken.py")
    with pytest.raises(DesignSyntaxError, match="not valid Python") as caught:
        load_script(broken)
    assert caught.value.file == str(broken) and caught.value.line == 4
    binary = tmp_path / "binary.py"
    binary.write_bytes(b"root = 1\n\xff\xfe")
    with pytest.raises(DesignSyntaxError, match="not a text file") as caught:
        load_script(binary)
    assert "UTF-8 Python source" in caught.value.hint
    missing = script(tmp_path, "import pyvcad_voxels", "voxels.py")
    with pytest.raises(DesignError, match="ModuleNotFoundError: No module named 'pyvcad_voxels'") as caught:
        load_script(missing)
    assert caught.value.line == 4


def test_vcad_files_are_never_run_as_python(tmp_path):
    marker = tmp_path / "ran"
    path = tmp_path / "design.vcad"
    path.write_text(f"open({str(marker)!r}, 'w').write('x')\n", encoding="utf-8")
    with pytest.raises(DesignSyntaxError):
        open_design(path)
    assert not marker.exists()
    good = tmp_path / "ball.vcad"
    good.write_text('sphere(2, "red");', encoding="utf-8")
    probe = ("import sys; from fgslice.compat import open_design; d = open_design(sys.argv[1]); "
             "print(d.materials[0].name, 'fgslice.compat.pyvcad' in sys.modules)")
    done = subprocess.run([sys.executable, "-c", probe, str(good)], capture_output=True, text=True, check=True)
    assert done.stdout.split() == ["red", "False"]


def test_sibling_modules_import_and_resources_path_finds_the_checkout(tmp_path):
    folder = tmp_path / "checkout" / "examples" / "meshes"
    folder.mkdir(parents=True)
    (folder / "sizes.py").write_text("RADIUS = 3\n", encoding="utf-8")
    trimesh.creation.icosphere(3, 5).export(tmp_path / "checkout" / "ball.stl")
    path = script(folder, f"""import sizes
        root = pv.Union(False, [pv.Mesh(pv.resources_path() + "ball.stl", {RED}),
                                pv.Sphere(pv.Vec3(4, 0, 0), sizes.RADIUS, {BLUE})])""")
    design = load_script(path)
    assert design.bounds()[1][0] == pytest.approx(7)
    assert "sizes" in sys.modules and str(folder) not in sys.path
    sys.modules.pop("sizes")


def test_a_pyvcad_module_already_imported_is_put_back(tmp_path, monkeypatch):
    real = types.ModuleType("pyvcad")
    monkeypatch.setitem(sys.modules, "pyvcad", real)
    path = script(tmp_path, f"root = pv.Sphere(pv.Vec3(0, 0, 0), 2, {RED})")
    assert load_script(path).bounds()[1] == pytest.approx((2, 2, 2))
    assert sys.modules["pyvcad"] is real and "pyvcad_rendering" not in sys.modules


def test_render_outside_a_script_run_says_how_to_run_it():
    from fgslice.compat import pyvcad as pv

    ball = pv.Sphere(pv.Vec3(0, 0, 0), 1)
    with pytest.raises(DesignError, match="only in a script that fgslice runs"):
        pyvcad_rendering.Render(ball, pv.default_materials)
    assert math.isclose(pv.Vec3(1, 2, 3).y, 2)
