"""Strategy 2's layers whose regions repeat an earlier layer's reuse its plan: only when the
regions are identical and the parity is the same, and the reused plan is the one the layer
would have got afresh."""

from __future__ import annotations

import numpy as np
import pytest
import shapely

from conftest import same_steps
from fgslice.design.language import parse_design
from fgslice.pipeline import SliceJob, _layer_task
from fgslice.planning.plan import LayerPlan, PackedSteps, SetState
from fgslice.planning.repeats import RepeatedLayers
from fgslice.settings import load_settings
from fgslice.slicing.layers import LayerRegions
from fgslice.slicing.palette import Palette
from fgslice.slicing.plan_layers import layer_heights, place_design

PRISM = """
fgrade(["x/24 + 0.5", "0.5 - x/24"], ["blue", "yellow"]) {
    translate(0, 0, 1.2) { cylinder(12, 2.4); }
}
"""
GRADED_IN_Z = PRISM.replace('"x/24 + 0.5", "0.5 - x/24"', '"0.25 + x/48 + z/12", "0.75 - x/48 - z/12"')


def _regions(index, height=0.2, shift=0.0):
    square = shapely.box(0, 0, 10, 10)
    left, right = shapely.box(0, 0, 5 + shift, 10), shapely.box(5 + shift, 0, 10, 10)
    return LayerRegions(index=index, z=0.2 * (index + 1), height=height, outline=shapely.MultiPolygon([square]),
                        faces=(shapely.MultiPolygon([left]), shapely.MultiPolygon([right])))


def _plan(index):
    columns = PackedSteps(np.zeros(1, np.int8), np.zeros(1, np.int32), np.zeros((2, 2)), np.array([0, 2]),
                          np.zeros(1, np.int8), np.zeros(1, np.int32), np.full(1, 0.4), np.full(1, 0.2),
                          np.zeros(1, bool), np.zeros(1, np.int32), np.zeros(1), np.zeros(1, np.int32))
    return LayerPlan.from_packed(index, 0.2 * (index + 1), 0.2, columns)


def test_only_identical_regions_of_the_same_parity_are_found():
    repeats = RepeatedLayers()
    plan = _plan(1)
    repeats.keep(_regions(1), plan, "layer 1")
    plan_3, result = repeats.find(_regions(3))
    assert result == "layer 1" and (plan_3.index, plan_3.z) == (3, 0.8) and plan_3.packed is plan.packed
    assert repeats.find(_regions(2)) is None  # the other parity: palette reversed
    assert repeats.find(_regions(3, height=0.3)) is None
    assert repeats.find(_regions(3, shift=1e-9)) is None
    assert not plan.packed.points.flags.writeable  # shared by every layer that reuses it


def _job(text, overrides):
    design = parse_design(text)
    settings = load_settings(None, {"strategy": "2", "colors": "6", "layer_height": "0.2", **overrides})
    palette = Palette(2, settings.colors)
    return SliceJob(design, settings, palette, place_design(design, settings), layer_heights(design, settings),
                    np.array([settings.bed_x / 2, settings.bed_y / 2]))


@pytest.mark.parametrize("pattern", ["concentric", "rectilinear"])
def test_a_reused_plan_is_the_plan_computed_afresh(pattern):
    """Layers 0-5 of a prism graded along x, in one job (layers 3-5 reuse 1 and 2; layer 2
    cannot reuse layer 0, which holds the skirt) and each in a job of its own: same steps,
    same moves, same statistics; only index and z differ."""
    job = _job(PRISM, {"fill_pattern": pattern})
    assert len(job.layers) == 12
    reused = [_layer_task(job, index) for index in range(6)]
    points = [result.plan.packed.points for result in reused]
    assert [np.shares_memory(p, points[2 - k % 2]) for k, p in enumerate(points)] == [False] + [True] * 5
    assert not np.shares_memory(points[1], points[2])
    for index, result in enumerate(reused):
        fresh = _layer_task(_job(PRISM, {"fill_pattern": pattern}), index)
        assert (result.plan.index, result.plan.z) == (fresh.plan.index, fresh.plan.z) == job.layers[index][:2]
        assert (result.colors, result.uncovered_mm2) == (fresh.colors, fresh.uncovered_mm2)
        assert result.plan.packed.data.text == fresh.plan.packed.data.text
        same_steps(result.plan, fresh.plan)
    odd, even = ([step.color for step in result.plan.steps if isinstance(step, SetState)] for result in reused[1:3])
    assert odd == even[::-1] and odd != even


def test_layers_of_a_field_graded_in_z_are_not_reused():
    """Its color faces move from one layer to the next."""
    job = _job(GRADED_IN_Z, {})
    results = [_layer_task(job, index) for index in range(1, 6)]
    for a, b in zip(results, results[2:]):
        assert not np.shares_memory(a.plan.packed.points, b.plan.packed.points)


@pytest.mark.parametrize("overrides", [{}, {"lookahead_mm": "25"}, {"fill_pattern": "rectilinear"}],
                         ids=["plain", "lookahead", "rectilinear"])
def test_a_whole_slice_is_byte_identical_with_and_without_reuse(tmp_path, monkeypatch, overrides):
    """One process (every repeated layer reused), its plans unpacked again by the look-ahead,
    against the same slice with reuse turned off."""
    from fgslice.pipeline import slice_to_gcode

    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1700000000")
    settings = load_settings(None, {"strategy": "2", "colors": "6", "layer_height": "0.2", "thumbnails": "", **overrides})
    slice_to_gcode(parse_design(PRISM), settings, tmp_path / "reused.gcode", jobs=1)
    monkeypatch.setattr(RepeatedLayers, "find", lambda self, regions: None)
    slice_to_gcode(parse_design(PRISM), settings, tmp_path / "fresh.gcode", jobs=1)
    reused, fresh = (tmp_path / "reused.gcode").read_bytes(), (tmp_path / "fresh.gcode").read_bytes()
    assert reused.count(b";LAYER_CHANGE") == 12
    assert reused == fresh
