"""Strategy 2 prints the whole part: bands narrower than a bead go to a neighbouring color,
so the extruded volume matches the part's on steep and sharp gradients and on the examples."""

from __future__ import annotations

import numpy as np
import pytest

from fgslice.design import api
from fgslice.design.language import load_design
from fgslice.machine.gcode_reader import read_gcode
from fgslice.pipeline import slice_to_gcode
from fgslice.settings import load_settings

from conftest import EXAMPLES

SIGMOID = "1/(1+exp(-4.5(rho-4)))"


def gear_vcad(teeth: int = 12) -> str:
    """A 5 mm thick gear: a 7.5 mm disc and ``teeth`` 3 x 2.4 mm teeth, graded by a sigmoid of
    rho whose 0.25..0.75 band is 0.5 mm wide at rho = 4 (narrower than two beads)."""
    tooth = "rotate(0, 0, {a}) {{ translate(8.5, 0, 2.5) {{ rectprism(3, 2.4, 5); }} }}"
    body = "\n".join(tooth.format(a=360 * i / teeth) for i in range(teeth))
    return (f'fgrade(["{SIGMOID}", "1-{SIGMOID}"], ["red", "blue"]) {{\n'
            f"  union() {{\n    translate(0, 0, 2.5) {{ cylinder(7.5, 5); }}\n{body}\n  }}\n}}\n")


def _slice(design, tmp_path, **overrides):
    settings = load_settings(None, {"skirt_loops": "0", **{k: str(v) for k, v in overrides.items()}})
    out = tmp_path / "part.gcode"
    stats = slice_to_gcode(design, settings, out, jobs=1).stats
    return settings, read_gcode(out), stats


def _extruded_volume(program, settings) -> float:
    printing = (program.e > 0) & (program.length > 0)
    return float(program.e[printing].sum() * np.pi * settings.filament_diameter**2 / 4)


def _part_volume(design, settings, program) -> float:
    """Sum of the exact sections at the layers' mid-planes times the layer height (mm^3)."""
    (_, _, z0), _ = design.bounds()
    h = settings.layer_height
    return sum(design.section(z0 + h * (i + 0.5)).area * h for i in range(len(program.layer_z)))


@pytest.mark.parametrize("colors", [4, 8])
def test_gear_with_a_steep_grade_is_printed_whole(tmp_path, colors):
    path = tmp_path / "gear.vcad"
    path.write_text(gear_vcad())
    design = load_design(path)
    settings, program, stats = _slice(design, tmp_path, colors=colors)
    part = _part_volume(design, settings, program)
    assert part == pytest.approx(1248, rel=0.01)
    assert _extruded_volume(program, settings) == pytest.approx(part, rel=0.03)
    assert stats["reassigned_mm2"] > 10 * len(program.layer_z)  # the ring at rho = 4, every layer
    assert stats["uncovered_mm2"] < 0.01 * stats["reassigned_mm2"]
    warnings = [w for w in stats["warnings"] if "neighbouring color" in w]
    assert len(warnings) == 1 and f"{stats['reassigned_mm2']:.2f} mm^2" in warnings[0]
    # the ring went to the hub's or the teeth's color: nothing printed in the colors between
    used = set(np.unique(program.color_of_moves()[(program.e > 0) & (program.length > 0)]))
    assert used == {0, colors - 1}


def test_sharp_thresh_boundary_is_printed_in_its_two_materials(tmp_path):
    # a thresh grade is pure red for x < 0 and pure blue for x > 0; the sampled field ramps
    # over one grid spacing there, which makes bands of the colors between, far narrower than a bead
    tree = api.fgrade(["0.5 - x/10", "0.5 + x/10"], ["red", "blue"], api.rectprism(20, 12, 2), mode="thresh")
    design = api.design(tree)
    settings, program, stats = _slice(design, tmp_path, colors=6)
    assert _extruded_volume(program, settings) == pytest.approx(20 * 12 * 2, rel=0.03)
    assert stats["reassigned_mm2"] > 0
    moves = (program.e > 0) & (program.length > 0)
    assert set(np.unique(program.color_of_moves()[moves])) == {0, 5}


@pytest.mark.parametrize("name, overrides", [
    ("palette", {"colors": 12, "layer_height": 0.4}), ("ring_radial_gradient", {"colors": 8}), ("dogbone", {}),
    ("plate_y_gradient", {"colors": 16}), ("three_materials", {"colors": 5, "channels": 4}),
])
def test_examples_extrude_their_volume(tmp_path, name, overrides):
    design = load_design(EXAMPLES / f"{name}.vcad")
    settings, program, _ = _slice(design, tmp_path, **overrides)
    assert _extruded_volume(program, settings) == pytest.approx(_part_volume(design, settings, program), rel=0.03)


@pytest.mark.parametrize("palette, colors", [("centers", 9), ("ends", 6)])
def test_three_material_thresh_boundaries_are_printed_whole(tmp_path, palette, colors):
    # sharp boundaries of a three-material palette: the bands' intersections hold lines
    # along them too, which the faces must survive (GEOS failed on them)
    tree = api.fgrade(["rho/8", "1-rho/8", "abs(x)/10"], ["red", "green", "blue"], api.cylinder(10, 2), mode="thresh")
    design = api.design(tree)
    settings, program, stats = _slice(design, tmp_path, colors=colors, channels=3, palette=palette)
    assert _extruded_volume(program, settings) == pytest.approx(_part_volume(design, settings, program), rel=0.03)
    assert stats["uncovered_mm2"] + stats["reassigned_mm2"] > 0  # there were bands narrower than a bead
