"""Broken and extreme geometry: each case slices sensibly (checked on the G-code: volume,
extent, layer count, colors) or is refused with a clear FgsliceError."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from fgslice.design import api
from fgslice.design import check_design
from fgslice.errors import FgsliceError, SliceError
from fgslice.machine.gcode_reader import read_gcode
from fgslice.pipeline import slice_to_gcode
from fgslice.settings import load_settings

H, W = 0.2, 0.45


def run(design, tmp_path, **overrides):
    """Slice with strategy 2, no skirt; return the program and statistics."""
    settings = load_settings("marlin-mixing", {"strategy": 2, "skirt_loops": 0, "layer_height": H,
                                               "bead_width": W, "colors": 2, **overrides})
    out = tmp_path / "part.gcode"
    result = slice_to_gcode(design, settings, out, jobs=1)
    return read_gcode(out), result.stats


def graded(node, axis="x", span=40.0):
    return api.design(api.fgrade([f"{axis}/{span} + 0.5", f"0.5 - {axis}/{span}"], ["blue", "yellow"], node))


def extruded_mm3(program, filament_area=np.pi * 1.75**2 / 4):
    """Volume of the moves that extrude while moving in XY, mm^3 (retraction and its
    recovery are left out)."""
    return float(program.e[(program.e > 0) & (program.length > 0)].sum() * filament_area)


def part_bbox(program):
    ext = (program.e > 0) & (program.length > 0)
    pts = np.vstack([program.start[ext], program.end[ext]])
    return pts.min(axis=0), pts.max(axis=0)


def test_non_watertight_benchy_slab_slices(benchy_path, tmp_path):
    slab = api.intersection(api.mesh(benchy_path), api.translate((0, 0, 10.5), api.rectprism(100, 100, 1.0)))
    design = graded(slab, span=60.0)
    program, stats = run(design, tmp_path)
    assert not trimesh.load(benchy_path, force="mesh").is_watertight
    assert stats["layers"] == 5
    section = api.design(api.mesh(benchy_path)).section(10.5)
    x0, y0, x1, y1 = section.bounds
    lo, hi = part_bbox(program)
    assert abs((hi[0] - lo[0]) - (x1 - x0)) < 2 * W and abs((hi[1] - lo[1]) - (y1 - y0)) < 2 * W
    assert extruded_mm3(program) == pytest.approx(section.area * 1.0, rel=0.1)


def test_self_intersecting_mesh_slices_as_the_union(tmp_path):
    a = trimesh.creation.box((20, 10, 2))
    b = trimesh.creation.box((10, 20, 2))
    path = tmp_path / "cross.stl"
    trimesh.util.concatenate([a, b]).export(path)
    program, stats = run(graded(api.mesh(path)), tmp_path)
    union_area = 20 * 10 + 10 * 20 - 10 * 10
    assert stats["layers"] == 10
    assert extruded_mm3(program) == pytest.approx(union_area * 2.0, rel=0.06)
    lo, hi = part_bbox(program)
    assert hi[0] - lo[0] == pytest.approx(20 - W, abs=0.1) and hi[1] - lo[1] == pytest.approx(20 - W, abs=0.1)


@pytest.mark.parametrize("node", [
    lambda tmp: api.rectprism(10, 10, 0.0),
    lambda tmp: api.rectprism(10, 10, 0.05),
    lambda tmp: api.mesh(_flat_mesh(tmp)),
], ids=["zero-height prism", "thinner than half a layer", "flat mesh"])
def test_zero_thickness_parts_are_refused_clearly(node, tmp_path):
    with pytest.raises(FgsliceError) as info:
        run(graded(node(tmp_path)), tmp_path)
    assert list(tmp_path.glob("*.gcode")) == [] and list(tmp_path.glob(".*.part")) == []
    text = info.value.format()
    assert any(word in text for word in ("no layers", "empty", "must be positive", "flat")), text


def _flat_mesh(tmp_path):
    path = tmp_path / "flat.stl"
    trimesh.Trimesh(vertices=[[0, 0, 0], [10, 0, 0], [10, 10, 0], [0, 10, 0]], faces=[[0, 1, 2], [0, 2, 3]]).export(path)
    return path


def test_gap_between_parts_gives_layers_without_area(tmp_path):
    lower = api.translate((0, 0, 0.5), api.rectprism(10, 10, 1))
    upper = api.translate((0, 0, 3.5), api.rectprism(10, 10, 1))
    program, stats = run(graded(api.union(lower, upper)), tmp_path)
    assert stats["layers"] == 20
    z = program.end[program.e > 0][:, 2]
    printed = np.unique(np.round(z, 3))
    np.testing.assert_allclose(printed, [0.2, 0.4, 0.6, 0.8, 1.0, 3.2, 3.4, 3.6, 3.8, 4.0])
    assert extruded_mm3(program) == pytest.approx(2 * 100 * 1.0, rel=0.06)


def test_color_band_narrower_than_a_bead_still_fills_the_part(tmp_path):
    # Blue only in |x| < 0.1 mm: a band a fifth of a bead wide across a 20 mm plate.
    design = api.design(api.fgrade(["abs(x) < 0.1 ? 1 : 0", "abs(x) < 0.1 ? 0 : 1"], ["blue", "yellow"],
                                   api.rectprism(20, 10, 1)))
    program, stats = run(design, tmp_path)
    assert stats["layers"] == 5
    assert extruded_mm3(program) == pytest.approx(200 * 1.0, rel=0.06)
    by_color = {int(k): float(v) for k, v in stats["extruded_mm3_by_color"].items()}
    assert by_color.get(1, 0.0) < 0.05 * 200 and by_color.get(0, 0.0) > 0.9 * 200  # color 1: mostly blue


@pytest.mark.parametrize("field", ["log(x)", "1/x"])
def test_nan_and_infinite_fields_slice_as_documented_and_are_reported(field, tmp_path):
    # NaN counts as 0 and inf is clamped to 1: where x < 0 both fields give blue 0 -> color 0;
    # where they exceed 0.2 (x > 1.22 for log, x < 5 for 1/x) blue is over half -> color 1.
    design = api.design(api.fgrade([field, "0.2"], ["blue", "yellow"], api.rectprism(20, 10, 1)))
    program, stats = run(design, tmp_path)
    assert stats["layers"] == 5 and np.all(np.isfinite(program.end))
    ext = (program.e > 0) & (program.length > 0)
    colors = np.array([s.color for s in program.states])[program.state[ext]]
    left = program.end[ext][:, 0] < load_settings("marlin-mixing").bed_x / 2 - W
    assert set(colors[left]) == {0} and 1 in set(colors[~left])
    warnings = check_design(design).warnings
    if field == "log(x)":
        assert any("NaN over" in w and "treated as 0" in w for w in warnings), warnings


def test_a_jump_in_the_field_splits_colors_at_the_jump(tmp_path):
    design = api.design(api.fgrade(["z < 0 ? 1 : 0", "z < 0 ? 0 : 1"], ["blue", "yellow"], api.cube(4)))
    program, stats = run(design, tmp_path)
    assert stats["layers"] == 20
    ext = program.e > 0
    z = program.end[ext][:, 2]
    colors = np.array([s.color for s in program.states])[program.state[ext]]
    assert set(colors[z < 1.95]) == {1} and set(colors[z > 2.05]) == {0}


def test_a_part_far_from_the_origin_is_centered_on_the_bed(tmp_path):
    design = graded(api.translate((1e6, -1e6, 0), api.rectprism(10, 10, 1)), span=1e7)
    program, stats = run(design, tmp_path)
    lo, hi = part_bbox(program)
    bed = load_settings("marlin-mixing")
    np.testing.assert_allclose((lo[:2] + hi[:2]) / 2, [bed.bed_x / 2, bed.bed_y / 2], atol=0.05)
    np.testing.assert_allclose(hi[:2] - lo[:2], [10 - W, 10 - W], atol=0.05)
    assert stats["layers"] == 5


def test_a_tiny_part_is_sliced_or_refused(tmp_path):
    try:
        program, stats = run(graded(api.cube(0.1), span=0.1), tmp_path, bead_width=0.2, layer_height=0.05)
    except SliceError as err:
        assert err.hint
    else:
        assert stats["layers"] == 2
        assert extruded_mm3(program) < 50 * 0.1**3


def test_a_ten_metre_part_is_refused_with_its_size(tmp_path):
    with pytest.raises(SliceError) as info:
        run(graded(api.rectprism(10_000, 100, 10), span=1e4), tmp_path)
    assert "10000.00 x 100.00 mm exceeds the bed" in info.value.message and "--profile" in info.value.hint
