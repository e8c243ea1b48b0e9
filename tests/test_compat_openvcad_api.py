"""The rest of OpenVCAD 2's example API: evaluation methods, unbounded functions, material
numbers, J750 resins, compilers, and the names refused with their reason."""

from __future__ import annotations

import math
import textwrap

import numpy as np
import pytest

from fgslice.compat.script import load_script
from fgslice.errors import DesignError

HEADER = "import pyvcad as pv\nimport pyvcad_rendering as viz\nmaterials = pv.default_materials\n"


def script(tmp_path, body: str, name: str = "design.py"):
    path = tmp_path / name
    path.write_text(HEADER + textwrap.dedent(body) + "\n", encoding="utf-8")
    return path


def printed(tmp_path, body: str) -> list[str]:
    """What the script prints (its values), run through fgslice's script loader."""
    out = tmp_path / "printed.txt"
    load_script(script(tmp_path, textwrap.dedent(body) + f"\nopen({str(out)!r}, 'w').write(repr(values))\nroot = pv.Sphere(1, 1, 1, 1)"))
    return eval(out.read_text())  # noqa: S307 - the test's own repr of floats


def test_evaluate_gradient_and_snap_follow_the_signed_distance(tmp_path):
    values = printed(tmp_path, """
        ball = pv.Sphere(pv.Vec3(0, 0, 0), 10, materials.id("red"))
        moved = pv.Translate(5, 0, 0, pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(2, 4, 6), 1))
        field = pv.Function('x^2 + y^2 + z^2 - 16', 1)
        p = pv.Vec3(15, 0, 0)
        g, s = ball.gradient(p), ball.snap(pv.Vec3(3, 4, 12))
        gf, sf = field.gradient(1, 2, 3), field.snap(pv.Vec3(0, 8, 0))
        values = [ball.evaluate(p.x, p.y, p.z), ball.evaluate(0, 0, 0), (g.x, g.y, g.z), (s.x, s.y, s.z),
                  moved.evaluate(5, 0, 0), moved.evaluate(9, 0, 0), (gf.x, gf.y, gf.z), (sf.x, sf.y, sf.z)]
    """)
    assert values[0] == pytest.approx(5.0) and values[1] == pytest.approx(-10.0)
    np.testing.assert_allclose(values[2], (1, 0, 0), atol=1e-6)
    np.testing.assert_allclose(values[3], np.array([3, 4, 12]) * 10 / 13, atol=1e-6)  # on the ray, radius 10
    assert values[4] == pytest.approx(-1.0) and values[5] == pytest.approx(3.0)  # half width 1 about x = 5
    np.testing.assert_allclose(values[6], (2, 4, 6), atol=1e-6)  # grad(x^2 + y^2 + z^2)
    np.testing.assert_allclose(values[7], (0, 4, 0), atol=1e-6)


def test_evaluation_methods_refuse_other_arguments(tmp_path):
    with pytest.raises(DesignError, match=r"Sphere.evaluate takes \(x, y, z\) numbers or a pyvcad.Vec3"):
        load_script(script(tmp_path, "root = pv.Sphere(pv.Vec3(0, 0, 0), 1, 1)\nroot.evaluate('x', 0, 0)"))


def test_a_function_without_its_box_takes_openvcads_box_and_lies_on_its_inside_region(tmp_path):
    design = load_script(script(tmp_path, "root = pv.Function('x^2 + y^2 + z^2 - 16', materials.id('blue'))"))
    lo, hi = design.bounds()
    np.testing.assert_allclose(lo, (-4, -4, -4), atol=0.01)
    np.testing.assert_allclose(hi, (4, 4, 4), atol=0.01)
    cut = design.section(0.0)
    assert cut.area == pytest.approx(math.pi * 16, rel=0.01)
    unbounded = load_script(script(tmp_path, "root = pv.Function('z - 3', 1)", "slab.py"))
    np.testing.assert_allclose(unbounded.bounds(), ((-10, -10, -10), (10, 10, 3)), atol=0.01)


def test_the_mug_of_the_examples_lies_on_its_cup(tmp_path):
    design = load_script(script(tmp_path, """
        cup = pv.Intersection(False, [pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(2.1, 2.1, 2.9), materials.id('blue')),
                                      pv.Function('x^2 + y^2 - 1^2', materials.id('blue'))])
        handle = pv.Translate(1, 0, 0, pv.Rotate(90, 0, 0, pv.Vec3(0, 0, 0), pv.Scale(0.85, 0.85, 0.85,
                 pv.Function('(x^2 + y^2 + z^2 + 1.15^2 - 0.5^2)^2 - 4 * (1.15) * (x^2 + y^2)', materials.id('green')))))
        root = pv.Union(False, [cup, handle])
    """))
    lo, hi = design.bounds()
    assert lo[2] == pytest.approx(-1.45) and hi[2] == pytest.approx(1.45)  # the cup's bottom and rim
    assert lo[0] == pytest.approx(-1.0, abs=0.01) and hi[0] == pytest.approx(2.148, abs=0.02)  # the handle's reach
    assert design.section(lo[2] + 0.1).area == pytest.approx(math.pi, rel=0.02)


def test_material_numbers_in_an_fgrade_are_the_tables_ids(tmp_path):
    design = load_script(script(tmp_path, """
        wheel = [f"0.5 + 0.5 * cos(theta - 2 * pi * {k} / 5)" for k in range(5)]
        root = pv.FGrade(wheel, [1, 2, 3, 4, 5], True, pv.Cylinder(pv.Vec3(0, 0, 0), 25, 3, 1))
        assert materials.id("blue") == 3 and materials.id("magenta") == 6
    """))
    assert [m.name for m in design.materials] == ["red", "green", "blue", "yellow", "cyan"]
    one = np.array([1.0])
    raw = np.array([0.5 + 0.5 * math.cos(0 - 2 * math.pi * k / 5) for k in range(5)])
    np.testing.assert_allclose(design.fractions(20 * one, 0 * one, 0 * one)[0], raw / raw.sum(), atol=1e-12)


def test_j750_resins_print_as_the_filaments_of_their_colours(tmp_path):
    design = load_script(script(tmp_path, """
        j750 = pv.j750_materials
        ids = [j750.id(n) for n in ("VeroYellow", "Agilus30Mgn", "Agilus30Blk", "M.Cleanser")]
        root = pv.FGrade(["0.4", "0.3", "0.2", "0.1"], ids, True, pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(9, 9, 9)))
    """))
    assert [m.name for m in design.materials] == ["yellow", "magenta", "black", "liquid"]
    with pytest.raises(DesignError, match="'Agilus30Yl' and 'veroyellow' would both print as 'yellow'"):
        load_script(script(tmp_path, "a = pv.j750_materials.id('VeroYellow')\nb = pv.j750_materials.id('Agilus30Yl')",
                           "same.py"))
    alone = load_script(script(tmp_path, "root = pv.Sphere(0, 0, 0, 1, pv.j750_materials.id('Agilus30Yl'))",
                               "alone.py"))  # another script's resins do not count
    assert [m.name for m in alone.materials] == ["yellow"]
    with pytest.raises(DesignError, match="no filament stands for the resin 'Tango'"):
        load_script(script(tmp_path, "a = pv.j750_materials.id('Tango')", "tango.py"))


def test_a_compiler_names_the_design_it_compiles(tmp_path):
    design = load_script(script(tmp_path, """
        import pyvcad_compilers as pvc
        bar = pv.RectPrism(pv.Vec3(0, 0, 5), pv.Vec3(40, 20, 10), materials.id("black"))
        viz.Render(pv.Sphere(pv.Vec3(0, 0, 0), 3, 1), materials)
        compiler = pvc.GrayscaleCompiler(bar, pv.Vec3(1, 1, 1), pv.Vec3(60, 40, 20), 1, 2, "out", "slice_")
        compiler.compile()
    """))
    (lo, hi) = design.bounds()
    np.testing.assert_allclose(np.subtract(hi, lo), (40, 20, 10))
    assert [m.name for m in design.materials] == ["black"]
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("body, message", [
    ("import pyvcad_compilers as pvc\npvc.InpWriter()", r"pyvcad_compilers.InpWriter is not supported by fgslice"),
    ("import pyvcad_compilers as pvc\npvc.MeshCompiler(pv.Sphere(1, 1, 1, 1), 1, 'o', 'p', 3).write()",
     r"MeshCompiler.write is not supported"),
    ("pv.ConformalMap(pv.Sphere(0, 0, 0, 5), pv.Sphere(0, 0, 5, 1))",
     r"pyvcad.ConformalMap is not supported by fgslice: OpenVCAD's experimental wrapping"),
    ("pv.Map('a.off', 'b.off')", r"pyvcad.Map is not supported by fgslice: OpenVCAD's experimental surface"),
    ("pv.PointMap('a.stl', 'b.inp', 'c.csv', ['1'], [1], True)", r"pyvcad.PointMap is not supported by fgslice: "
                                                                  r"it needs the simulation's tetrahedral mesh"),
])
def test_names_a_filament_printer_cannot_honour_are_refused_with_the_reason(tmp_path, body, message):
    path = script(tmp_path, body)
    with pytest.raises(DesignError, match=message) as caught:
        load_script(path)
    assert caught.value.file == str(path) and caught.value.hint


PIXELS = np.array([[[1.0, 0.0, 0.0, 1.0], [0.0, 1.0, 0.0, 0.5], [0.0, 0.0, 1.0, 1.0]],
                   [[1.0, 1.0, 1.0, 1.0], [0.0, 0.0, 0.0, 0.25], [0.5, 0.5, 0.5, 1.0]]])
"""A 3 x 2 pixel RGBA image: row 0 is its top."""


def test_a_png_image_is_a_colour_volume_with_a_pixel_per_voxel(tmp_path):
    from matplotlib import image

    image.imsave(tmp_path / "logo.png", PIXELS)
    design = load_script(script(tmp_path, """
        loader = pv.PNGLoader.FromImage("logo.png", pv.Vec3(2, 1, 0.5), 3.0, pv.PNGColorMode.COLOR_RGBA, center=True)
        volume = loader.as_rgba_volume()
        lo, hi = volume.bounding_box()
        carrier = pv.RectPrism.FromMinAndMax(lo, hi)
        carrier.set_attribute(pv.DefaultAttributes.COLOR_RGBA, pv.Vec4Attribute(volume))
        root = carrier
    """))
    from fgslice.design.attributes import attribute_fields

    np.testing.assert_allclose(design.bounds(), ((-3, -1, -1.5), (3, 1, 1.5)))
    fields = attribute_fields(design)
    columns, rows = np.meshgrid(np.arange(3), np.arange(2))
    x, y = -3 + 2 * columns.ravel() + 1, 1 - rows.ravel() - 0.5  # pixel centres: row 0 at the top
    for z in (-1.25, 0.0, 1.25):  # the image repeats through the depth
        got = np.stack([fields.values(f"color_rgba.{c}", x, y, np.full(x.shape, z)) for c in "rgba"], axis=1)
        np.testing.assert_allclose(got, PIXELS.reshape(-1, 4), atol=1 / 255)
    between = fields.values("color_rgba.g", np.array([-1.0]), np.array([0.5]), np.array([0.0]))
    assert between[0] == pytest.approx(0.5, abs=1 / 255)  # halfway from red (g 0) to green (g 1)


def test_a_png_stack_is_stacked_from_the_bottom_and_rgb_drops_alpha(tmp_path):
    from matplotlib import image

    (tmp_path / "stack").mkdir()
    for i, value in enumerate((0.0, 1.0)):
        image.imsave(tmp_path / "stack" / f"slice_{i:02d}.png", np.full((2, 2, 3), value))
    design = load_script(script(tmp_path, """
        volume = pv.PNGLoader.FromStack("stack", pv.Vec3(1, 1, 2), pv.PNGColorMode.COLOR_RGB).as_rgb_volume()
        lo, hi = volume.bounding_box()
        root = pv.RectPrism.FromMinAndMax(lo, hi)
        root.set_attribute(pv.DefaultAttributes.COLOR_RGB, pv.Vec3Attribute(volume))
    """))
    from fgslice.design.attributes import attribute_fields

    np.testing.assert_allclose(design.bounds(), ((0, 0, 0), (2, 2, 4)))
    red = attribute_fields(design).values("color_rgb.r", np.array([1.0, 1.0]), np.array([1.0, 1.0]),
                                          np.array([0.5, 3.5]))
    np.testing.assert_allclose(red, (0.0, 1.0), atol=1 / 255)
    with pytest.raises(DesignError, match="made with PNGColorMode.COLOR_RGB"):
        load_script(script(tmp_path, 'pv.PNGLoader.FromStack("stack", pv.Vec3(1, 1, 1), '
                                     'pv.PNGColorMode.COLOR_RGB).as_rgba_volume()', "rgba.py"))
    with pytest.raises(DesignError, match="'nothere.png' not found"):
        load_script(script(tmp_path, 'pv.PNGLoader.FromImage("nothere.png", pv.Vec3(1, 1, 1), 1, '
                                     'pv.PNGColorMode.COLOR_RGB)', "missing.py"))
