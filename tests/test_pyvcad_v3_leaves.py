"""OpenVCAD 3's leaf and composition constructors as its API reference gives them:
``Function(f, min, max)``, ``Mesh(path, center=..., compensate_slicer_ras=...)``, the
default constructors, ``Tile`` of any node, and ``pyvcad_rendering``'s modules."""

from __future__ import annotations

import math
import textwrap
from datetime import datetime, timezone

import numpy as np
import pytest
import shapely
import trimesh

from fgslice.compat.script import load_script
from fgslice.design.attributes import attribute_fields
from fgslice.errors import FgsliceError
from fgslice.machine.gcode_reader import read_gcode
from fgslice.pipeline import slice_to_gcode
from fgslice.settings import load_settings

HEADER = "import pyvcad as pv\n"


def _design(tmp_path, code: str):
    path = tmp_path / "design.py"
    path.write_text(HEADER + textwrap.dedent(code))
    return load_script(path)


def _bounds(design):
    lo, hi = design.bounds()
    return np.round(np.concatenate([lo, hi]), 3)


def _area(design, z: float) -> float:
    return design.root.section(z, 0.05).area


def _volume(design, step: float = 0.1) -> float:
    lo, hi = design.bounds()
    zs = np.arange(lo[2] + step / 2, hi[2], step)
    return float(sum(s.area for s in design.root.sections(list(zs), 0.05)) * step)


@pytest.mark.parametrize("function", [
    '"x^2 + y^2 + z^2 - 25"',
    "ball",
    "python_ball",
], ids=["expression", "cfunc of x y z", "python function of the eight coordinates"])
def test_function_takes_openvcad3s_function_min_max(tmp_path, function):
    design = _design(tmp_path, f"""
        import math
        from numba import cfunc, types

        @cfunc(types.float64(types.float64, types.float64, types.float64))
        def ball(x, y, z):
            return math.sqrt(x * x + y * y + z * z) - 5.0

        def python_ball(x, y, z, rho, phic, r, theta, phis):
            return r - 5.0

        root = pv.Function({function}, pv.Vec3(-6, -6, -6), pv.Vec3(6, 6, 6))
    """)
    assert _bounds(design) == pytest.approx([-5, -5, -5, 5, 5, 5], abs=0.05)
    assert _area(design, 0.0) == pytest.approx(25 * math.pi, rel=0.01)
    assert _area(design, 3.0) == pytest.approx(16 * math.pi, rel=0.01)


def test_a_cfunc_shape_of_the_wrong_arity_is_refused_by_name(tmp_path):
    with pytest.raises(FgsliceError, match=r"Function: a @cfunc takes \(x, y, z\), 'two' takes 2 arguments"):
        _design(tmp_path, """
            from numba import cfunc, types

            @cfunc(types.float64(types.float64, types.float64))
            def two(x, y):
                return x + y

            root = pv.Function(two, pv.Vec3(-1, -1, -1), pv.Vec3(1, 1, 1))
        """)


@pytest.fixture
def box_stl(tmp_path):
    """A 10 x 20 x 5 mm box from the origin into +X, +Y, +Z, as an STL file."""
    path = tmp_path / "box.stl"
    trimesh.creation.box(extents=(10, 20, 5), transform=trimesh.transformations.translation_matrix((5, 10, 2.5))
                         ).export(path)
    return path


@pytest.mark.parametrize("call, expected", [
    ("pv.Mesh(PATH)", [0, 0, 0, 10, 20, 5]),
    ("pv.Mesh(PATH, center=True)", [-5, -10, -2.5, 5, 10, 2.5]),
    ("pv.Mesh(PATH, True)", [-5, -10, -2.5, 5, 10, 2.5]),
    ("pv.Mesh(PATH, pv.Vec3(0.1, 0.1, 0.1), center=True)", [-5, -10, -2.5, 5, 10, 2.5]),
    ("pv.Mesh(PATH, center=False, disable_validation=True, override_voxel_size=0.1)", [0, 0, 0, 10, 20, 5]),
    ("pv.Mesh(PATH, compensate_slicer_ras=True)", [0, -20, 0, 10, 0, 5]),
    ("pv.Mesh(PATH, center=True, compensate_slicer_ras=True)", [-5, -10, -2.5, 5, 10, 2.5]),
])
def test_mesh_takes_openvcad3s_arguments(tmp_path, box_stl, call, expected):
    design = _design(tmp_path, f"root = {call.replace('PATH', repr(str(box_stl)))}\n")
    assert _bounds(design) == pytest.approx(expected, abs=1e-6)
    assert _volume(design) == pytest.approx(1000.0, rel=0.002)


def test_mesh_mirrors_before_it_centres(tmp_path):
    """An L-shaped part: mirrored across Y, its long leg moves from +Y to -Y."""
    path = tmp_path / "l.stl"
    leg = trimesh.creation.box(extents=(2, 20, 2), transform=trimesh.transformations.translation_matrix((1, 10, 1)))
    foot = trimesh.creation.box(extents=(10, 2, 2), transform=trimesh.transformations.translation_matrix((5, 1, 1)))
    trimesh.util.concatenate([leg, foot]).export(path)
    plain = _design(tmp_path, f"root = pv.Mesh({str(path)!r}, center=True)\n")
    mirrored = _design(tmp_path, f"root = pv.Mesh({str(path)!r}, center=True, compensate_slicer_ras=True)\n")
    foot_y = [d.root.section(0.0, 0.05).intersection(shapely.box(4, -20, 6, 20)).centroid.y
              for d in (plain, mirrored)]
    assert foot_y == pytest.approx([-9.0, 9.0], abs=1e-6)


@pytest.mark.parametrize("code, bounds, z, area", [
    ("pv.Torus()", [-3, -3, -1, 3, 3, 1], 0.0, math.pi * (3**2 - 1**2)),
    ("pv.PolygonExtrude()", [0, 0, 0, 1, 1, 1], 0.5, 1.0),
    ("pv.RectPrism()", [-0.5, -0.5, -0.5, 0.5, 0.5, 0.5], 0.0, 1.0),
    ("pv.Sphere()", [-1, -1, -1, 1, 1, 1], 0.0, math.pi),
    ("pv.Cylinder()", [-1, -1, -0.5, 1, 1, 0.5], 0.0, math.pi),
])
def test_default_constructors_make_openvcad3s_default_shapes(tmp_path, code, bounds, z, area):
    design = _design(tmp_path, f"root = pv.Scale(10, {code})\n")
    assert _bounds(design) == pytest.approx(np.array(bounds) * 10, abs=0.05)
    assert _area(design, z * 10) == pytest.approx(area * 100, rel=0.01)


def test_tile_repeats_any_node_in_the_cells_of_its_bounds(tmp_path):
    """Balls of radius 2 every 5 mm, cut by a 20 x 20 x 10 box centred on a ball: 4 x 4 x 2
    balls' worth of volume (the halves on the box's faces count half)."""
    design = _design(tmp_path, """
        ball = pv.Sphere(pv.Vec3(0, 0, 0), 2)
        root = pv.Intersection(pv.Tile(5, 5, 5, ball), pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(20, 20, 10)))
    """)
    assert _bounds(design) == pytest.approx([-10, -10, -5, 10, 10, 5])
    assert _volume(design) == pytest.approx(32 * 4 / 3 * math.pi * 8, rel=0.01)
    layer = design.root.section(0.0, 0.05)
    assert len(shapely.get_parts(layer)) == 25 and layer.area == pytest.approx((9 + 12 / 2 + 4 / 4) * 4 * math.pi, rel=0.01)


def test_tile_without_sizes_repeats_the_childs_bounding_box(tmp_path):
    """A 4 x 4 x 4 cube with a 2 mm hole through it along Z tiles into a plate of 25 holes."""
    design = _design(tmp_path, """
        cell = pv.Difference(pv.RectPrism(pv.Vec3(1, 1, 1), pv.Vec3(4, 4, 4)), pv.Cylinder(pv.Vec3(1, 1, 1), 1, 6))
        root = pv.Intersection(pv.Tile(cell), pv.RectPrism(pv.Vec3(1, 1, 1), pv.Vec3(20, 20, 4)))
    """)
    layer = design.root.section(1.0, 0.05)
    assert layer.area == pytest.approx(400 - 25 * math.pi, rel=0.005)
    parts = shapely.get_parts(layer)
    assert len(parts) == 1 and len(parts[0].interiors) == 25


def test_a_cell_smaller_than_the_child_cuts_it_to_the_cell(tmp_path):
    design = _design(tmp_path, """
        ball = pv.Sphere(pv.Vec3(0, 0, 0), 3)
        root = pv.Intersection(pv.Tile(4, 4, 4, ball), pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(8, 8, 4)))
    """)
    assert _area(design, 0.0) == pytest.approx(64.0, rel=1e-6)
    assert _area(design, 1.9) == pytest.approx(4 * _clipped_disc(math.sqrt(9 - 1.9**2), 2.0), rel=0.01)


def _clipped_disc(r: float, half: float) -> float:
    """Area of the disc of radius ``r`` inside the square ``|x|, |y| <= half`` (numerically)."""
    g = np.linspace(-half, half, 2001)
    x, y = np.meshgrid(g, g)
    return float(np.mean(x * x + y * y <= r * r) * (2 * half) ** 2)


def test_attributes_repeat_with_the_tiled_shape(tmp_path):
    design = _design(tmp_path, """
        ball = pv.Sphere(pv.Vec3(0, 0, 0), 2)
        ball.set_attribute(pv.DefaultAttributes.TEMPERATURE, pv.FloatAttribute("220 + 5 * x"))
        root = pv.Intersection(pv.Tile(5, 5, 5, ball), pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(20, 20, 10)))
    """)
    x = np.array([-1.5, 0.0, 1.5, 3.5, 5.0, 6.5, -5.0, -3.5])
    values = attribute_fields(design).values("temperature", x, np.zeros_like(x), np.zeros_like(x))
    assert values == pytest.approx([212.5, 220.0, 227.5, 212.5, 220.0, 227.5, 220.0, 227.5])


def test_a_tile_needs_a_bounded_shape_and_a_child(tmp_path):
    with pytest.raises(FgsliceError, match="repeats its cell without end"):
        _design(tmp_path, "root = pv.Tile(5, 5, 5, pv.Sphere(pv.Vec3(0, 0, 0), 2))\n").bounds()
    with pytest.raises(FgsliceError, match="Tile has no child"):
        _design(tmp_path, "root = pv.Intersection(pv.Tile(5, 5, 5), pv.Sphere(pv.Vec3(0, 0, 0), 2))\n")
    with pytest.raises(FgsliceError, match="Tile: a child must be a pyvcad node, got str"):
        _design(tmp_path, "t = pv.Tile()\nt.set_child('ball')\n")


def test_a_tiled_part_slices_within_its_box_and_to_its_volume(tmp_path):
    design = _design(tmp_path, """
        post = pv.Cylinder(pv.Vec3(0, 0, 0), 1.5, 6)
        root = pv.Intersection(pv.Tile(6, 6, 6, post), pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(24, 24, 6)))
    """)
    settings = load_settings(None, {"layer_height": "0.3"})
    out = tmp_path / "part.gcode"
    stats = slice_to_gcode(design, settings, out, jobs=1, stamp=datetime(2026, 1, 1, tzinfo=timezone.utc)).stats
    program = read_gcode(out)
    roles = np.array(program.roles + [""])[program.role]
    printed = (program.e > 0) & (program.length > 0) & ~np.isin(roles, ["Skirt/Brim", "Wipe tower"])
    xy = program.end[printed, :2] - np.array(stats["placement_offset"][:2])
    assert (xy >= -12 - 0.5).all() and (xy <= 12 + 0.5).all()
    posts = 4 * 4 * math.pi * 1.5**2 * 6  # 3 x 3 whole posts, 12 halves and 4 quarters on the box's sides
    filament_area = math.pi * settings.filament_diameter**2 / 4
    assert program.e[printed].sum() * filament_area == pytest.approx(posts, rel=0.1)


@pytest.mark.parametrize("code", [
    "import pyvcad_rendering.render as r\nr.Render_Image(BALL, 'x.png', width=10)",
    "from pyvcad_rendering.render import Render\nRender(BALL)",
    "import pyvcad_rendering\npyvcad_rendering.Render_Turntable_Animation(BALL, 'frames')",
    "from pyvcad_rendering import render\nrender.Render_Sweep_Animation(BALL, 'frames', axis='x')",
    "from pyvcad_rendering.export import Export\nExport(BALL)",
    "from pyvcad_rendering.vtk_export import export_volume_vtk\nexport_volume_vtk(BALL, 'x.vtk')",
    "import pyvcad_rendering.vtk_export\npyvcad_rendering.vtk_export.export_iso_surface_vtk(BALL, 'x.vtk')",
])
def test_pyvcad_renderings_modules_name_the_design(tmp_path, code):
    design = _design(tmp_path, "BALL = pv.Sphere(pv.Vec3(0, 0, 0), 7)\n" + code + "\n")
    assert _bounds(design) == pytest.approx([-7, -7, -7, 7, 7, 7])


def test_an_unknown_rendering_name_is_refused_by_name(tmp_path):
    with pytest.raises(FgsliceError, match="pyvcad_rendering.render.Render_Movie is not supported by fgslice"):
        _design(tmp_path, "import pyvcad_rendering.render as r\nr.Render_Movie(pv.Sphere(pv.Vec3(0, 0, 0), 1))\n")


def test_volume_fractions_take_plain_material_numbers_as_fgrade_does(tmp_path):
    """1 and 3 are red and blue in the material table, as ``default_materials.id`` gives them."""
    numbered, named = (_design(tmp_path, f"""
        bar = pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(40, 10, 10))
        bar.set_attribute(pv.DefaultAttributes.VOLUME_FRACTIONS,
                          pv.VolumeFractionsAttribute([("0.5 + x / 40", {a}), ("0.5 - x / 40", {b})]))
        root = bar
    """) for a, b in (("1", "3"), ('pv.default_materials.id("red")', 'pv.default_materials.id("blue")')))
    x = np.linspace(-19, 19, 9)
    zeros = np.zeros_like(x)
    for design in (numbered, named):
        names = [m.name.lower() for m in design.materials]
        fractions = design.fractions(x, zeros, zeros)
        assert fractions[:, names.index("red")] == pytest.approx(0.5 + x / 40)
        assert fractions[:, names.index("blue")] == pytest.approx(0.5 - x / 40)
    with pytest.raises(FgsliceError, match="material id 99 is not in the material table"):
        _design(tmp_path, 'pv.VolumeFractionsAttribute([("1", 99)])\n')


def test_rotate_with_only_a_child_turns_nothing(tmp_path):
    design = _design(tmp_path, "root = pv.Rotate(pv.RectPrism(pv.Vec3(1, 2, 3), pv.Vec3(2, 4, 6)))\n")
    assert _bounds(design) == pytest.approx([0, 0, 0, 2, 4, 6])


def test_bounding_box_gives_the_shapes_corners_after_prepare(tmp_path):
    design = _design(tmp_path, """
        shape = pv.Union(pv.Sphere(pv.Vec3(1, 2, 3), 10), pv.RectPrism(pv.Vec3(1, 2, 20), pv.Vec3(4, 4, 30)))
        shape.prepare(pv.Vec3(0.5, 0.5, 0.5), 1.0, 1.0)
        lo, hi = shape.bounding_box()
        root = pv.RectPrism.FromMinAndMax(lo, hi)
    """)
    assert _bounds(design) == pytest.approx([-9, -8, -7, 11, 12, 35], abs=1e-6)


@pytest.mark.parametrize("code, message", [
    ("pv.Sphere(pv.Vec3(0, 0, 0), 1).prepare(0.5, 1.0)", "prepare takes a voxel size Vec3 of positive sizes first"),
    ("pv.Sphere(pv.Vec3(0, 0, 0), 1).prepare(pv.Vec3(0.5, 0.5, 0.5), -1)", "bandwidths are numbers >= 0"),
    ("pv.TriangleMeshSurface([], [])", "TriangleMeshSurface is not supported by fgslice: OpenVCAD's conformal cell maps"),
    ("pv.TrimMode.CLIP", "TrimMode is not supported by fgslice: OpenVCAD's conformal cell maps"),
    ("pv.vdb_loader.load_float_volume('a.vdb', 'density')", "vdb_loader is not supported by fgslice: its data is an "
                                                            "OpenVDB grid"),
])
def test_refusals_and_bad_arguments_name_what_and_why(tmp_path, code, message):
    with pytest.raises(FgsliceError, match=message):
        _design(tmp_path, code + "\n")
