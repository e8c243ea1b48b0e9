"""Designs in the style of OpenVCAD's 15 legacy examples (compression cylinders, liquid
grades, a gyroid, dogbones, soft actuators, the vtp states), written for these tests.

Their meshes are stand-ins of similar size built here with numpy and trimesh. Every
design passes ``check``; every graded one slices to the same G-code as the same design
with the child's material deleted (the enclosing fgrade overrides it), and the hidden
material is not one of the design's materials.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
import trimesh

from fgslice.design import check_design, format_report, load_design
from fgslice.pipeline import slice_to_gcode
from fgslice.settings import load_settings

MESHES = "examples/data/3d_models"

GYROID = """sin(2*pi*x/4) * cos(2*pi*y/4) +
            sin(2*pi*y/4) * cos(2*pi*z/4) +
            sin(2*pi*z/4) * cos(2*pi*x/4)"""

ACTUATOR = "2.8 * sqrt(x^2 + y^2) + sin(4 * z) - sin(2.8 * sqrt(x^2 + y^2) + 3.2) - 0.2 - 3.3"

CHANNEL = "3.5 * sqrt(x^2 + y^2) + sin(4 * z) - sin(2.8 * sqrt(x^2 + y^2) + 3.2) - 0.2 - 3.3"

# name -> (text with {m} where the child's material goes, the child's material, materials file?)
DESIGNS = {
    "compression_graded": (
        'union() { fgrade(["0.5 + z/8.4", "0.5 - z/8.4"], ["white", "black"], "prob") {\n'
        f'  mesh("{MESHES}/cylinder.stl"{{m}}); }} }}',
        "blue", False,
    ),
    "compression_sharp": (
        'union() { fgrade(["z < 0", "z > 0"], ["red", "blue"], "thresh") {\n'
        f'  mesh("{MESHES}/cylinder.stl"{{m}}); }} }}',
        "red", False,
    ),
    "compression_plain": (f'union() {{ mesh("{MESHES}/cylinder.stl", "red"); }}', None, False),
    "liquid_ramp": (
        'union() { fgrade(["0.9 - x/800", "0.1 + x/800"], ["red", "liquid"], "prob") {\n'
        "  rectprism((160, 20, 8){m}); } }",
        "red", False,
    ),
    "liquid_spheres": (
        "union() {\n"
        + "".join(
            f'  translate({x}, 0, 0) {{ fgrade(["{a}", "{b}"], ["red", "liquid"], "prob") {{ sphere(7.5{{m}}); }} }}\n'
            for x, a, b in ((-40, 0.9, 0.2), (-24, 0.85, 0.1), (-8, 0.9, 0.1), (8, 0.95, 0.05))
        )
        + '  translate(24, 0, 0) { sphere(7.5, "red"); }\n}',
        "red", False,
    ),
    "gyroid": (
        f'union() {{ fgrade(["{GYROID}", "0.5"], ["red", "blue"], "prob") {{\n'
        f'  function((-5, -5, -5), (5, 5, 5), "{GYROID}"{{m}}); }} }}',
        "red", False,
    ),
    "dogbone": (
        'union() { fgrade(["(x > -1) and (x < 1)", "0.5"], ["blue", "red"], "thresh") {\n'
        f'  mesh("{MESHES}/dogbone.stl"{{m}}); }} }}',
        "red", False,
    ),
    "dogbone_large": (
        'union() { fgrade(["1 / (1 + exp(x))", "1 - 1 / (1 + exp(x))"], ["cyan", "yellow"], "prob") {\n'
        f'  mesh("{MESHES}/dogbone_large.stl"{{m}}); }} }}',
        "cyan", False,
    ),
    "actuator": (
        'union() { intersection() { rectprism((3.75, 3.75, 10), "green");\n'
        f'  function((-3.75, -3.75, -5.25), (3.75, 3.75, 5.25), "{ACTUATOR}", "green"); }} }}',
        None, False,
    ),
    "actuator_thresh": (
        'union() { fgrade(["0.2", "sin(4.5 * z + 1.57) - 0.1",\n'
        '  "100 * (sin(atan(50 * sin(4.5 * z - 1.57) - 60)) + 1) - rho * sin(phic) + 0.1"],\n'
        '  ["blue", "cyan", "yellow"], "thresh") {\n'
        '  function((-2, -2, -3.1415), (2, 2, 3.1415), "(0.5 * (rho * sin(phic) - 0.5)^4 + '
        "(rho * sin(phic + 0.5 * pi))^4 + 0.5 * (sin(atan(100 * sin(4.5 * z - 1.57) - 60)) + 1) * "
        '(sin(atan(20 * sin(phic))) + 1) - 1)"{m}); } }',
        "red", False,
    ),
    "actuator_core": (
        'union() { fgrade(["1/(1+exp(10*rho - 4.25))", "1 - 1/(1+exp(10*rho - 4.25))"], ["red", "blue"]) {\n'
        "  intersection() { rectprism((3.75, 3.75, 10){m});\n"
        f'  function((-3.75, -3.75, -5.25), (3.75, 3.75, 5.25), "{ACTUATOR}"{{m}}); }} }} }}',
        "green", False,
    ),
    "actuator_channel": (
        f'union() {{ fgrade(["({CHANNEL} <= 0) ? 1 : 0", "({CHANNEL} > 0) ? 1 : 0"], ["red", "blue"], "thresh") {{\n'
        "  intersection() { rectprism((3.75, 3.75, 10){m});\n"
        f'  function((-3.75, -3.75, -5.25), (3.75, 0, 5.25), "{ACTUATOR}"{{m}}); }} }} }}',
        "green", False,
    ),
    "vtp_blending": (
        "union() { blend(10, 10, 10) { union() {\n"
        '  translate(-20, 0, 0) { rectprism((40, 40, 40), "state_a"); }\n'
        '  translate(20, 0, 0) { rectprism((40, 40, 40), "state_b"); } } } }',
        None, True,
    ),
    "vtp_gear": (
        'union() { fgrade(["1 / (1 + exp(-4.5(rho - 4)))", "(-1 / (1 + exp(-4.5(rho - 4)))) + 1"],\n'
        '  ["state_a", "state_b"], "prob") {\n'
        f'  mesh("{MESHES}/gear.stl"{{m}}); }} }}',
        "state_a", True,
    ),
    "vtp_static": (
        'union() { translate(-20, 0, 0) { rectprism((40, 40, 40), "state_a"); }\n'
        '  translate(20, 0, 0) { rectprism((40, 40, 40), "state_b"); } }',
        None, True,
    ),
}


def _prism(lower: np.ndarray, upper: np.ndarray, z0: float, z1: float, closed: bool) -> trimesh.Trimesh:
    """A watertight prism from z0 to z1 over the planform between two curves matched point
    by point (``lower`` to the right of ``upper`` when walked in order); ``closed`` joins
    the last points to the first (a ring), else the ends are closed by straight walls."""
    n = len(lower)
    plan = np.vstack([lower, upper])
    vertices = np.vstack([np.column_stack([plan, np.full(2 * n, z)]) for z in (z0, z1)])

    def low(i, top):
        return i % n + (2 * n if top else 0)

    def up(i, top):
        return n + i % n + (2 * n if top else 0)

    faces = []
    for i in range(n if closed else n - 1):
        j = i + 1
        faces += [[low(i, 1), low(j, 1), up(j, 1)], [low(i, 1), up(j, 1), up(i, 1)]]
        faces += [[low(i, 0), up(j, 0), low(j, 0)], [low(i, 0), up(i, 0), up(j, 0)]]
        faces += [[low(i, 0), low(j, 0), low(j, 1)], [low(i, 0), low(j, 1), low(i, 1)]]
        faces += [[up(j, 0), up(i, 0), up(i, 1)], [up(j, 0), up(i, 1), up(j, 1)]]
    if not closed:
        for a, b in ((up(0, 0), low(0, 0)), (low(n - 1, 0), up(n - 1, 0))):
            faces += [[a, b, b + 2 * n], [a, b + 2 * n, a + 2 * n]]
    mesh = trimesh.Trimesh(vertices, np.array(faces), process=True)
    assert mesh.is_watertight and mesh.volume > 0
    return mesh


def _dogbone(length, grip, neck, gauge, thickness, fillet) -> trimesh.Trimesh:
    """A flat tensile bar along X centred at the origin: grips ``grip`` wide, a neck
    ``neck`` wide and ``gauge`` long, circular fillets of radius ``fillet`` (mm)."""
    x = np.linspace(-length / 2, length / 2, 801)
    ax = np.abs(x)
    half = np.full_like(x, grip / 2)
    half[ax <= gauge / 2] = neck / 2
    bend = (ax > gauge / 2) & (ax < gauge / 2 + fillet)
    rise = fillet - np.sqrt(np.maximum(fillet**2 - (ax[bend] - gauge / 2) ** 2, 0))
    half[bend] = np.minimum(grip / 2, neck / 2 + rise)
    return _prism(np.column_stack([x, -half]), np.column_stack([x, half]), -thickness / 2, thickness / 2, False)


def _gear() -> trimesh.Trimesh:
    """A 24-tooth gear about 18 mm across and 6 mm thick with a 5 mm bore, centred at the origin."""
    t = np.linspace(0, 2 * np.pi, 384, endpoint=False)
    radius = 8 + 1.2 * np.clip(3 * np.sin(24 * t), -1, 1)
    outer = np.column_stack([radius * np.cos(t), radius * np.sin(t)])
    bore = np.column_stack([2.5 * np.cos(t), 2.5 * np.sin(t)])
    return _prism(outer, bore, -3, 3, True)


@pytest.fixture(scope="module")
def legacy(tmp_path_factory):
    """A folder holding the stand-in meshes, the vtp materials file and a function writing
    one design (with or without its child's material) there, returning its path."""
    root = tmp_path_factory.mktemp("legacy")
    (root / MESHES).mkdir(parents=True)
    trimesh.creation.cylinder(radius=6.35, height=12.7, sections=96).export(root / MESHES / "cylinder.stl")
    _dogbone(115, 19, 6, 33, 3.2, 14).export(root / MESHES / "dogbone.stl")
    _dogbone(165, 19, 13, 57, 3.2, 76).export(root / MESHES / "dogbone_large.stl")
    _gear().export(root / MESHES / "gear.stl")
    vtp = root / "vtp.json"
    vtp.write_text(json.dumps({"scale": 255, "materials": [
        {"name": "state_a", "r": 220, "g": 40, "b": 40}, {"name": "state_b", "r": 40, "g": 40, "b": 220}]}))

    def write(name: str, with_material: bool = True, folder: str = "with"):
        text, material, needs_vtp = DESIGNS[name]
        (root / folder).mkdir(exist_ok=True)
        path = root / folder / f"{name}.vcad"
        path.write_text(text.replace("{m}", f', "{material}"' if with_material and material else ""))
        (root / folder / MESHES).mkdir(parents=True, exist_ok=True)
        for mesh in (root / MESHES).iterdir():
            target = root / folder / MESHES / mesh.name
            if not target.exists():
                target.symlink_to(mesh)
        return path, (vtp if needs_vtp else None)

    return write


def test_there_are_fifteen_designs_eleven_graded():
    assert len(DESIGNS) == 15
    assert sum(material is not None for _, material, _ in DESIGNS.values()) == 11


@pytest.mark.parametrize("name", sorted(DESIGNS))
def test_every_legacy_design_passes_check(legacy, name):
    path, vtp = legacy(name)
    design = load_design(path, vtp)
    report = check_design(design, samples=24)
    assert report.usable, format_report(report)
    hidden = DESIGNS[name][1]
    names = [m.name for m in design.materials]
    if hidden is not None and hidden not in _grade_materials(DESIGNS[name][0]):
        assert hidden not in names
        assert any(f"material '{hidden}'" in note and "overridden" in note for note in report.notes)
    assert set(report.fraction_ranges) == set(names)


def _grade_materials(text: str) -> set[str]:
    """The material names of the fgrade lists in ``text``."""
    import re

    return {m for group in re.findall(r'\]\s*,\s*\[([^\]]*)\]', text) for m in re.findall(r'"(\w+)"', group)}


GRADED = sorted(name for name, (_, material, _) in DESIGNS.items() if material is not None)


@pytest.mark.parametrize("name", GRADED)
def test_a_graded_design_slices_as_if_its_child_had_no_material(legacy, name, tmp_path):
    outputs = []
    for folder, with_material in (("with", True), ("without", False)):
        path, vtp = legacy(name, with_material, folder)
        design = load_design(path, vtp)
        overrides = {"colors": "4", "skirt_loops": "0", "layer_height": "0.4", "channels": str(len(design.materials))}
        settings = load_settings(None, overrides)
        out = tmp_path / f"{folder}.gcode"
        result = slice_to_gcode(design, settings, out, jobs=1)
        outputs.append((out.read_text(), result.stats))
    (with_text, with_stats), (without_text, without_stats) = outputs
    assert with_stats["state_changes"] == without_stats["state_changes"]
    body = [line for line in with_text.splitlines() if not line.startswith(";")]
    assert body == [line for line in without_text.splitlines() if not line.startswith(";")]
