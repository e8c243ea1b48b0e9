"""The complete scripts of OpenVCAD 3's other guides (metamaterials: attribute-driven,
heterogeneous lattices, properties, conformal meshes and CAD; volumes; CadQuery; the
attribute resolver; moving from version 2), assembled as a reader would from each
guide's blocks (tests/openvcad3_guide_scripts/, README there): each slices, or is
refused on purpose with its reason; and the fields the lattice scripts read (cell
coordinates, ramps, mixes) against the guides' definitions."""

from __future__ import annotations

import importlib.util
import re
import textwrap
import shutil
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
import pytest

from fgslice.compat.script import load_script
from fgslice.design.attributes import attribute_fields
from fgslice.design.check import check_design
from fgslice.design.derived_fields import evaluate
from fgslice.errors import FgsliceError
from fgslice.machine.gcode_reader import read_gcode
from fgslice.pipeline import slice_to_gcode
from fgslice.settings import load_settings

SCRIPTS = Path(__file__).parent / "openvcad3_guide_scripts"
HAS_CADQUERY = importlib.util.find_spec("cadquery") is not None
HAS_OCP = importlib.util.find_spec("OCP") is not None

CONFORMAL = r"conformal cell maps .* rectangular cell maps only"
NO_CADQUERY = r"No module named 'cadquery'"
REFUSED = {
    "attribute_driven_03_graded_cell_spacing": r"warp_cell_map is not supported by fgslice: how OpenVCAD turns",
    "attribute_resolver_03_resolver_density_to_flow_rate": r"no chain .* reaches 'temperature' .*\(density\)",
    "attribute_resolver_04_foaming_tpu_tags": r"register_foaming_conversions .* does not publish",
    "attribute_resolver_05_j750_custom_table": r"generate_j750_modulus_toughness_lookup_table .* does not publish",
    "attribute_resolver_06_cross_compilation_shore_hardness": r"register_tpu_conversions .* does not publish",
    "conformal_cad_03_step_face_cubic": r"CADModel\.select_faces is not supported",
    "conformal_meshes_01_dome_gyroid": r"TriangleMeshSurface is not supported by fgslice: OpenVCAD.s conformal cell maps",
    "moving_from_v2_01_earlier_builder_style": r"gyroid: 'cell' is an argument of the earlier builders",
    "volumes_01_vdb_basic_density": r"vdb_loader is not supported by fgslice: .* OpenVDB",
    "volumes_04_vdb_fire": r"vdb_loader is not supported by fgslice: .* OpenVDB",
}
"""Scripts refused on purpose, and the reason their error gives."""

NOT_DESIGNS = {"properties_02_characterize_graph_cell": "prints a graph cell's report, builds no design"}

CADQUERY_REFUSED = {
    "conformal_cad_01_cylinder_gyroid", "conformal_cad_02_between_faces_octet", "conformal_cad_04_cone_bcc",
    "conformal_cad_05_spherical_band_schwarz_p", "conformal_cad_06_freeform_diamond",
}
"""CadQuery scripts that map cells onto CAD faces: refused at ``CADModel.faces``."""

CADQUERY_SLICES = {"cadquery_01_mounting_plate", "cadquery_02_cable_clamp", "cadquery_03_equipment_bracket"}

NAMES = sorted(p.stem for p in SCRIPTS.glob("[a-z]*.py"))
SLICES = [n for n in NAMES
          if n not in REFUSED and n not in NOT_DESIGNS and n not in CADQUERY_REFUSED and n not in CADQUERY_SLICES]


# ---------------------------------------------------------------- stand-ins for the guides' files


def _png(path: Path, pixels: np.ndarray) -> None:
    from PIL import Image

    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(pixels.astype(np.uint8), "RGBA").save(path)


LOGO = np.zeros((24, 40, 4))
LOGO[:, :20] = (255, 0, 0, 255)
LOGO[:, 20:] = (0, 0, 255, 128)
"""The logo stand-in: red left half, half-transparent blue right half (rows from the top)."""


def _logo(folder: Path) -> None:
    _png(folder / "maclab_logo.png", LOGO)


def _pyramid(folder: Path) -> None:
    """Twelve 32 x 32 slices: an opaque square shrinking upward, its green rising with
    height, transparent around it."""
    for k in range(12):
        pixels = np.zeros((32, 32, 4))
        a, b = k, 32 - k
        pixels[a:b, a:b] = (255, round(255 * k / 11), 0, 255)
        _png(folder / "pyramid_stack" / f"slice_{k:03d}.png", pixels)


def _step_solid(path: Path, boxes) -> None:
    """A STEP file of the union of ``boxes`` ((x0, y0, z0), (x1, y1, z1)) mm."""
    from OCP.BRepAlgoAPI import BRepAlgoAPI_Fuse
    from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox
    from OCP.gp import gp_Pnt
    from OCP.STEPControl import STEPControl_AsIs, STEPControl_Writer

    shapes = [BRepPrimAPI_MakeBox(gp_Pnt(*lo), gp_Pnt(*hi)).Shape() for lo, hi in boxes]
    shape = shapes[0]
    for other in shapes[1:]:
        shape = BRepAlgoAPI_Fuse(shape, other).Shape()
    path.parent.mkdir(parents=True, exist_ok=True)
    writer = STEPControl_Writer()
    writer.Transfer(shape, STEPControl_AsIs)
    assert writer.Write(str(path)) == 1


BRACKET = [((-32, -18, 0), (32, 18, 5)), ((26, -18, 0), (32, 18, 32))]
"""The bracket stand-in: a base plate and an upright, 32 mm tall (mm)."""


def _bracket(folder: Path) -> None:
    _step_solid(folder / "bracket.step", BRACKET)


def _loft(folder: Path) -> None:
    _step_solid(folder.parents[1] / "data" / "3d_models" / "conformal_loft.step", [((0, 0, 0), (30, 20, 10))])


STAND_INS = {
    "volumes_02_png_single_image": (_logo, False),
    "volumes_03_png_image_stack": (_pyramid, False),
    "cadquery_04_bracket_import": (_bracket, True),
    "conformal_cad_03_step_face_cubic": (_loft, True),
}
"""What a reader has beside a script (the example's files, not public): how to make it,
and whether that needs Open CASCADE."""


def _placed(name: str, tmp_path: Path) -> Path:
    """The script copied to ``tmp_path/examples/guide/`` with its helper and stand-ins."""
    folder = tmp_path / "examples" / "guide"
    folder.mkdir(parents=True)
    for helper in SCRIPTS.glob("_*.py"):
        shutil.copy(helper, folder)
    shutil.copy(SCRIPTS / f"{name}.py", folder)
    make, needs_ocp = STAND_INS.get(name, (None, False))
    if needs_ocp and not HAS_OCP:
        pytest.skip("needs the CAD extra (cadquery-ocp-novtk)")
    if make is not None:
        make(folder)
    return folder / f"{name}.py"


def _slice(design, tmp_path, **overrides):
    settings = load_settings(None, {k: str(v) for k, v in overrides.items()})
    out = tmp_path / "part.gcode"
    result = slice_to_gcode(design, settings, out, jobs=1, stamp=datetime(2026, 1, 1, tzinfo=timezone.utc))
    return read_gcode(out), result.stats


def _values(design, name, *points):
    x, y, z = np.array(points, dtype=float).T
    return attribute_fields(design).values(name, x, y, z)


# ------------------------------------------------------------------------------------ each script


def test_every_script_is_classified():
    classified = set(SLICES) | set(REFUSED) | set(NOT_DESIGNS) | CADQUERY_REFUSED | CADQUERY_SLICES
    assert classified == set(NAMES) and len(NAMES) == 42


@pytest.mark.slow
@pytest.mark.filterwarnings("error::RuntimeWarning")  # a numeric warning reaches the user as noise
@pytest.mark.parametrize("name", SLICES)
def test_each_guide_script_checks_and_slices_within_its_design(name, tmp_path):
    design = load_script(_placed(name, tmp_path))
    assert check_design(design).usable
    program, stats = _slice(design, tmp_path, layer_height=0.4, colors=2, thumbnails="")
    lo, hi = (np.array(v) for v in design.bounds())
    roles = np.array(program.roles + [""])[program.role]
    printed = (program.e > 0) & (program.length > 0) & ~np.isin(roles, ["Skirt/Brim", "Wipe tower"])
    xy = program.end[printed, :2] - np.array(stats["placement_offset"][:2])
    assert (xy >= lo[:2] - 1.0).all() and (xy <= hi[:2] + 1.0).all()
    assert program.layer_z[-1] == pytest.approx(hi[2] - lo[2], abs=0.8)


@pytest.mark.parametrize("name", sorted(REFUSED))
def test_refused_scripts_say_why_at_their_line(name, tmp_path):
    with pytest.raises(FgsliceError) as error:
        load_script(_placed(name, tmp_path))
    assert re.search(REFUSED[name], error.value.message), error.value.message
    assert error.value.line is not None


@pytest.mark.parametrize("name", sorted(CADQUERY_REFUSED | CADQUERY_SLICES))
def test_cadquery_scripts_need_cadquery_and_map_no_faces(name, tmp_path):
    if HAS_CADQUERY and name in CADQUERY_SLICES:
        design = load_script(_placed(name, tmp_path))
        assert check_design(design).usable
        return
    with pytest.raises(FgsliceError) as error:
        load_script(_placed(name, tmp_path))
    expected = r"CADModel\.faces is not supported" if HAS_CADQUERY else NO_CADQUERY
    assert re.search(expected, error.value.message), error.value.message
    if not HAS_CADQUERY:
        assert "pip install cadquery" in error.value.hint


# ------------------------------------------------------------------------- cell-map coordinates


def _field(attribute, x):
    x = np.asarray(x, dtype=float)
    return evaluate(attribute.field, x, 0 * x, 0 * x)


def test_cell_map_coordinates_follow_the_guide(tmp_path):
    from fgslice.compat import pyvcad as pv
    from fgslice.compat import pyvcad_metamaterials as mm

    # six 8 mm cells from x = -24 to 24
    cell_map = mm.rectangular_cell_map((pv.Vec3(-24, -12, -4), pv.Vec3(24, 12, 4)), cells=(6, 3, 1))
    x = [-24, -20, -16, 0, 23.9, 24]
    np.testing.assert_allclose(_field(cell_map.logical_position.x, x), [0, 0.5, 1, 3, 5.9875, 6])
    # a point on a face between cells is in the next cell; the far face stays in the last
    np.testing.assert_allclose(_field(cell_map.cell_index.x, x), [0, 0, 1, 3, 5, 5])
    np.testing.assert_allclose(_field(cell_map.unit_cell_phase.x, x), [0, 0.5, 0, 0, 0.9875, 1])
    # one millimetre along x crosses an eighth of a cell
    step = cell_map.to_cell_frame(pv.Vec3Attribute(1.0, 0.0, 0.0))
    np.testing.assert_allclose(_field(step.x, [0.0]), [0.125])
    np.testing.assert_allclose(_field(step.y, [0.0]), [0.0])


def test_cell_size_in_cell_units_sets_each_panels_beam_radius(tmp_path):
    design = load_script(_placed("attribute_driven_10_movement_in_cell_units", tmp_path))
    # 4 mm cells: 0.2 + 3.6 / 4 = 1.1; 8 mm cells: 0.2 + 3.6 / 8 = 0.65 (mm); sdf = distance - radius
    # (-12, 0, 0.5) is 0.5 mm from the x strut at y = z = 0; (10, 0, 3.5) 0.5 mm from the y strut at z = 4
    np.testing.assert_allclose(design.sdf(np.array([-12.0, 10.0]), np.zeros(2), np.array([0.5, 3.5])),
                               [0.5 - 1.1, 0.5 - 0.65], atol=1e-9)


def test_a_shared_control_drives_the_wall_and_is_attached(tmp_path):
    design = load_script(_placed("attribute_driven_11_shared_control_attribute", tmp_path))
    x = np.array([-24.0, 0.0, 12.0, 24.0])
    expected = 0.55 + 1.1 * ((x + 24) / 48) ** 2
    np.testing.assert_allclose(_values(design, "wall_thickness_control", *[(v, 0, 0) for v in x]), expected)


# --------------------------------------------------------------------------------- mixed bodies


def _variant(name, tmp_path, old, new):
    """The script ``name`` with its line ``old`` replaced by ``new``."""
    text = (SCRIPTS / f"{name}.py").read_text()
    assert old in text
    path = tmp_path / f"{name}_{abs(hash(new))}.py"
    path.write_text(text.replace(old, new))
    return load_script(path)


def _points(n=3000, seed=5):
    rng = np.random.default_rng(seed)
    return rng.uniform((-24, -12, -8), (24, 12, 8), (n, 3)).T


def test_mix_across_a_region_keeps_each_body_beyond_the_band_and_averages_on_its_surface(tmp_path):
    name = "heterogeneous_02_mix_across_a_region"
    mixed = load_script(_placed(name, tmp_path))
    old = "root = mm.mix(\n    gyroid,\n    schwarz_d,\n    region=left_region,\n    half_width=4.0,\n)"
    gyroid = _variant(name, tmp_path, old, "root = gyroid")
    schwarz_d = _variant(name, tmp_path, old, "root = schwarz_d")
    x, y, z = _points()
    got, a, b = mixed.sdf(x, y, z), gyroid.sdf(x, y, z), schwarz_d.sdf(x, y, z)
    np.testing.assert_allclose(got[x < -4], a[x < -4])
    np.testing.assert_allclose(got[x > 4], b[x > 4])
    zero = np.zeros_like(y)
    np.testing.assert_allclose(mixed.sdf(zero, y, z), (gyroid.sdf(zero, y, z) + schwarz_d.sdf(zero, y, z)) / 2)
    assert np.mean(np.isclose(got[np.abs(x) < 3], a[np.abs(x) < 3])) < 0.1


def test_a_smooth_ramp_weights_the_mix_by_smoothstep(tmp_path):
    name = "heterogeneous_03_mix_along_x"
    mixed = load_script(_placed(name, tmp_path))
    old = "root = mm.mix(gyroid, schwarz_d, weight)"
    gyroid, schwarz_d = (_variant(name, tmp_path, old, f"root = {b}") for b in ("gyroid", "schwarz_d"))
    _, y, z = _points(400)
    for x, w in ((-8.0, 0.0), (-4.0, 0.15625), (0.0, 0.5), (4.0, 0.84375), (8.0, 1.0)):
        xs = np.full_like(y, x)
        np.testing.assert_allclose(mixed.sdf(xs, y, z), (1 - w) * gyroid.sdf(xs, y, z) + w * schwarz_d.sdf(xs, y, z),
                                   atol=1e-12)


def test_a_mixed_cell_is_the_first_cell_before_the_ramp_and_the_second_after(tmp_path):
    name = "attribute_driven_12_mixed_unit_cells"
    mixed = load_script(_placed(name, tmp_path))
    old = "root = mm.tpms(cell_map, mixed_cell, wall_thickness=1.2)"
    gyroid = _variant(name, tmp_path, old, "root = mm.gyroid(cell_map, wall_thickness=1.2)")
    schwarz_d = _variant(name, tmp_path, old, "root = mm.schwarz_d(cell_map, wall_thickness=1.2)")
    x, y, z = _points()
    got = mixed.sdf(x, y, z)
    # logical 2.5 .. 3.5 of 8 mm cells from -24: x = -4 .. 4
    np.testing.assert_allclose(got[x <= -4], gyroid.sdf(x, y, z)[x <= -4])
    np.testing.assert_allclose(got[x >= 4], schwarz_d.sdf(x, y, z)[x >= 4])
    middle = np.abs(x) < 3
    assert not np.allclose(got[middle], gyroid.sdf(x, y, z)[middle])
    assert not np.allclose(got[middle], schwarz_d.sdf(x, y, z)[middle])


def test_earlier_builder_arguments_name_their_replacement(tmp_path):
    from fgslice.compat import pyvcad_metamaterials as mm
    from fgslice.errors import DesignError

    with pytest.raises(DesignError, match=r"octet: 'radius' .* \(use beam_radius\)"):
        mm.octet(radius=0.8)
    with pytest.raises(DesignError, match=r"tpms has no argument 'wall'"):
        mm.tpms(None, "gyroid", wall=1.0)
    body = mm.gyroid(mm.rectangular_cell_map(((0, 0, 0), (8, 8, 8)), cells=1))
    with pytest.raises(DesignError, match=r"mix: give either a weight or region"):
        mm.mix(body, body)
    with pytest.raises(DesignError, match=r"mix: half_width goes with region"):
        mm.mix(body, body, 0.5, half_width=2.0)
    with pytest.raises(DesignError, match=r'ramp: axis "u" is a logical axis'):
        mm.ramp(0.0, 1.0, axis="u")


# ------------------------------------------------------------------- the resolver and volumes


def test_the_published_lw_pla_table_gives_flow_rate_from_temperature(tmp_path):
    design = load_script(_placed("attribute_resolver_02_resolver_temperature_to_flow_rate", tmp_path))
    # temperature = x / 3 + 236: 228, 230, 236, 250 C; the guide's table, linear between its points
    points = [(-24, 0, 0), (-18, 0, 0), (0, 0, 0), (42, 0, 0)]
    np.testing.assert_allclose(_values(design, "temperature", *points), [228, 230, 236, 250])
    np.testing.assert_allclose(_values(design, "flow", *points), [108, 103, 86, 68], atol=1e-9)


def test_png_volumes_colour_their_carrier_pixel_by_pixel(tmp_path):
    logo = load_script(_placed("volumes_02_png_single_image", tmp_path / "logo"))
    # 40 x 24 pixels of 0.25 mm, 10 mm deep, centred: x -5 .. 5, y -3 .. 3, z -5 .. 5
    np.testing.assert_allclose(np.array(logo.bounds()), [(-5, -3, -5), (5, 3, 5)], atol=1e-9)
    left, right = (-2.5, 0, 0), (2.5, 0, 0)
    np.testing.assert_allclose([_values(logo, f"color_rgba.{c}", left, right) for c in "rgba"],
                               [[1, 0], [0, 0], [0, 1], [1, 128 / 255]], atol=1e-9)
    pyramid = load_script(_placed("volumes_03_png_image_stack", tmp_path / "pyramid"))
    lo, hi = pyramid.bounds()
    np.testing.assert_allclose(np.array(hi) - np.array(lo), [11.2, 11.2, 4.2], atol=1e-9)
    # the centre column: green rises slice by slice (k / 11 in slice k, from the bottom)
    zs = lo[2] + 0.35 * (np.arange(12) + 0.5)
    green = _values(pyramid, "color_rgba.g", *[(0, 0, z) for z in zs])
    np.testing.assert_allclose(green, np.round(255 * np.arange(12) / 11) / 255, atol=1e-9)


@pytest.mark.skipif(not HAS_OCP, reason="needs the CAD extra (cadquery-ocp-novtk)")
def test_the_imported_bracket_carries_its_modulus_ramp(tmp_path):
    design = load_script(_placed("cadquery_04_bracket_import", tmp_path))
    np.testing.assert_allclose(np.array(design.bounds()), [(-32, -18, 0), (32, 18, 32)], atol=0.05)
    z = np.array([2.0, 16.0, 30.0])
    np.testing.assert_allclose(_values(design, "modulus", *[(29, 0, v) for v in z]), 900 + 1700 * z / 32)


# ------------------------------------------------------------------ geometric characterization


def _characterize(root, voxel=0.5, axes=""):
    """The report of the pyvcad node ``root`` within -10 .. 10 mm on every axis."""
    from fgslice.compat import pyvcad as pv
    from fgslice.compat import pyvcad_metamaterials as mm

    return mm.properties.characterize(root, voxel_size=voxel, bounds=(pv.Vec3(-10, -10, -10), pv.Vec3(10, 10, 10)),
                                      periodic_axes=axes)


def test_characterize_measures_a_box_exactly_where_the_grid_allows(tmp_path):
    from fgslice.compat import pyvcad as pv

    side = 10.25
    box = _characterize(pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(side, side, side)))
    assert box.envelope_volume == pytest.approx(8000)
    # 20 of the 40 voxel centres per axis lie inside (|c| < 5.125): 10 mm of solid per axis
    assert box.solid_volume == pytest.approx(1000)
    assert box.relative_density + box.porosity == pytest.approx(1)
    # the faces sit between grid nodes, where the planar distance is interpolated exactly;
    # marching cubes cuts a chamfer along the 12 edges (under 2 %)
    assert 6 * side ** 2 * 0.98 < box.surface_area < 6 * side ** 2
    assert box.interface_area == pytest.approx(box.surface_area)
    assert box.hydraulic_diameter == pytest.approx(4 * box.void_volume / box.interface_area)
    assert (box.solid_component_count, box.euler_characteristic, box.genus) == (1, 2, 0)
    np.testing.assert_allclose(box.centroid, (0, 0, 0), atol=1e-9)
    profile = box.cross_sections["x"]
    inside = np.abs(np.array(profile.positions)) < side / 2
    np.testing.assert_allclose(np.array(profile.solid_areas)[inside], 100)
    np.testing.assert_allclose(np.array(profile.solid_areas)[~inside], 0)
    assert profile.coefficient_of_variation == pytest.approx(1.0)


def test_characterize_counts_handles_and_joins_periodic_faces(tmp_path):
    from fgslice.compat import pyvcad as pv

    torus = _characterize(pv.Torus(6.0, 2.0), voxel=0.4)
    assert (torus.euler_characteristic, torus.genus, torus.solid_component_count) == (0, 1, 1)
    slabs = pv.Union(pv.RectPrism.FromMinAndMax(pv.Vec3(-10, -10, -10), pv.Vec3(-8, 10, 10)),
                     pv.RectPrism.FromMinAndMax(pv.Vec3(8, -10, -10), pv.Vec3(10, 10, 10)))
    assert _characterize(slabs).solid_component_count == 2
    wrapped = _characterize(slabs, axes="x")
    assert wrapped.solid_component_count == 1
    # only the slabs' inner faces are material-void interface; the rest lie on the envelope
    assert wrapped.interface_area == pytest.approx(2 * 20 * 20, rel=0.02)


def test_the_gyroid_report_agrees_with_the_design(tmp_path):
    design = load_script(_placed("properties_01_characterize_tpms", tmp_path))
    from fgslice.compat import pyvcad as pv
    from fgslice.compat import pyvcad_metamaterials as mm

    cell_map = mm.rectangular_cell_map((pv.Vec3(-10, -10, -10), pv.Vec3(10, 10, 10)), cells=(2, 2, 2))
    report = _characterize(mm.gyroid(cell_map, wall_thickness=1.2), voxel=0.4, axes="xyz")
    points = np.random.default_rng(2).uniform(-10, 10, (200000, 3)).T
    assert report.relative_density == pytest.approx(np.mean(design.sdf(*points) < 0), rel=0.02)
    assert report.solid_component_count == 1
    # the sheet's two faces: about twice the gyroid's area, 3.09 a^2 per cell of side a
    assert report.interface_area == pytest.approx(2 * 8 * 3.09 * 10 ** 2, rel=0.05)
    for axis in "xyz":
        profile = report.cross_sections[axis]
        np.testing.assert_allclose(np.mean(profile.area_fractions), report.relative_density, rtol=1e-9)


def test_graph_cell_report_of_the_octet(tmp_path, capsys):
    with pytest.raises(FgsliceError, match="renders no design"):
        load_script(_placed("properties_02_characterize_graph_cell", tmp_path))
    printed = capsys.readouterr().out.split("\n")
    # 8 corners (3 half face diagonals each), 6 face centres (4 half diagonals + 4 octahedron edges)
    assert printed[:3] == ["14", "36", "{3: 8, 8: 6}"]
    strut = 16.0 / np.sqrt(2)  # half a face diagonal = an octahedron edge
    assert float(printed[3]) == pytest.approx(strut / 1.6)
    assert float(printed[4]) == pytest.approx(2 * strut / 0.8)


def test_mixed_bodies_blend_their_attributes_and_materials_with_the_weight(tmp_path):
    path = tmp_path / "mixed.py"
    path.write_text(textwrap.dedent("""
        import pyvcad as pv
        import pyvcad_metamaterials as mm

        materials = pv.default_materials
        left = pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(20, 10, 10))
        left.set_attribute(pv.DefaultAttributes.DENSITY, pv.FloatAttribute(1.0))
        left.set_attribute(pv.DefaultAttributes.VOLUME_FRACTIONS,
                           pv.VolumeFractionsAttribute([("1.0", materials.id("red"))]))
        right = pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(20, 10, 10))
        right.set_attribute(pv.DefaultAttributes.DENSITY, pv.FloatAttribute("3 + 0 * x"))
        right.set_attribute(pv.DefaultAttributes.VOLUME_FRACTIONS,
                            pv.VolumeFractionsAttribute([("1.0", materials.id("blue"))]))
        root = mm.mix(left, right, mm.ramp(-5.0, 5.0, axis="x"))
    """))
    design = load_script(path)
    points = [(-8, 0, 0), (-2.5, 0, 0), (0, 0, 0), (8, 0, 0)]
    np.testing.assert_allclose(_values(design, "density", *points), [1, 1.5, 2, 3])
    x, y, z = np.array(points, dtype=float).T
    mix = design.fractions(x, y, z)
    names = [m.name for m in design.materials]
    np.testing.assert_allclose(mix[:, names.index("blue")], [0, 0.25, 0.5, 1])
    np.testing.assert_allclose(mix[:, names.index("red")], [1, 0.75, 0.5, 0])


@pytest.mark.parametrize("name", ["attribute_driven_12_mixed_unit_cells", "heterogeneous_02_mix_across_a_region",
                                  "attribute_driven_09_alternating_cell_thickness"])
def test_the_sections_of_mixed_and_cell_graded_lattices_hold_the_design_volume(name, tmp_path):
    design = load_script(_placed(name, tmp_path))
    lo, hi = (np.asarray(v) for v in design.bounds())
    dz = 0.5
    zs = np.arange(lo[2] + dz / 2, hi[2], dz)
    layered = sum(s.area for s in design.sections(list(zs))) * dz
    points = np.random.default_rng(11).uniform(lo, hi, (60000, 3))
    sampled = np.mean(design.sdf(*points.T) < 0) * np.prod(hi - lo)
    assert layered == pytest.approx(sampled, rel=0.03)


def test_whole_cells_alternate_thin_and_thick_walls(tmp_path):
    design = load_script(_placed("attribute_driven_09_alternating_cell_thickness", tmp_path))
    rng = np.random.default_rng(4)
    solid = []
    for cell in range(6):  # 8 mm cells from x = -24
        points = rng.uniform((-24 + 8 * cell, -4, -4), (-16 + 8 * cell, 4, 4), (20000, 3))
        solid.append(np.mean(design.sdf(*points.T) < 0))
    even, odd = np.array(solid[0::2]), np.array(solid[1::2])
    # walls of 0.3 mm in even cells, 1.8 mm in odd ones: about six times the solid
    np.testing.assert_allclose(odd / even, 6.0, rtol=0.2)
