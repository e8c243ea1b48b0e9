"""Absurd jobs are refused up front, with the numbers and the setting to change, fast."""

import time
import tracemalloc

import pytest

from fgslice.design import api
from fgslice.errors import ResourceError
from fgslice.guards import MAX_LAYER_PATH_MM, check_resources, estimate
from fgslice.pipeline import slice_to_gcode
from fgslice.settings import load_settings

BIG_BED = {"bed_x": 5000, "bed_y": 5000, "max_z": 5000}


def graded_box(sx, sy, sz):
    return api.design(api.fgrade(["x/%g + 0.5" % sx, "0.5 - x/%g" % sx], ["blue", "yellow"], api.rectprism(sx, sy, sz)))


def refused(design, overrides, tmp_path):
    """Slice through the public entry point; return the error, its time (s) and peak memory (bytes)."""
    settings = load_settings("marlin-mixing", {**BIG_BED, **overrides})
    out = tmp_path / "out.gcode"
    tracemalloc.start()
    started = time.perf_counter()
    with pytest.raises(ResourceError) as info:
        slice_to_gcode(design, settings, out, jobs=1)
    elapsed = time.perf_counter() - started
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert not out.exists() and list(tmp_path.iterdir()) == []
    return info.value, elapsed, peak


def test_absurd_layer_count_is_refused_before_anything_is_built(tmp_path):
    error, elapsed, peak = refused(graded_box(10, 10, 5000), {"layer_height": 0.011}, tmp_path)
    assert "454545 layers" in error.message and "100000" in error.message
    assert "layer_height" in error.hint
    assert elapsed < 1.0 and peak < 50e6


def test_billions_of_face_samples_are_refused(tmp_path):
    error, elapsed, peak = refused(graded_box(4000, 4000, 1), {"strategy": 2, "bead_width": 0.06, "layer_height": 0.05}, tmp_path)
    assert "field samples" in error.message and "4.44e+09" in error.message
    assert "bead_width" in error.hint and "--colors" in error.hint
    assert elapsed < 1.0 and peak < 50e6


def test_kilometres_of_paths_per_layer_are_refused(tmp_path):
    error, elapsed, peak = refused(
        graded_box(5000, 5000, 1), {"strategy": 1, "infill_density": 100, "bead_width": 0.06, "layer_height": 0.05}, tmp_path
    )
    assert "417 km of toolpaths" in error.message and "the limit is 10 km" in error.message
    assert "bead_width 0.06 mm" in error.message and "infill_density" in error.hint
    assert elapsed < 1.0 and peak < 50e6


def test_a_print_of_years_is_refused_by_its_total_length(tmp_path):
    # 600 x 600 mm solid, 0.4 mm beads: 900 m a layer (allowed), 5000 layers: 4500 km in all.
    error, _, _ = refused(graded_box(600, 600, 1000), {"strategy": 2, "layer_height": 0.2}, tmp_path)
    assert "over 5000 layers" in error.message and "4.5e+03 km" in error.message
    assert "layer_height" in error.hint


def test_estimates_of_an_ordinary_part_match_its_geometry():
    settings = load_settings("marlin-mixing", {"strategy": 2, "bead_width": 0.5})
    est = check_resources(graded_box(100, 50, 10), settings, 50)
    assert est.face_samples == (200 + 3) * (100 + 3)
    assert est.layer_path_mm == pytest.approx(100 * 50 / 0.5)
    assert est.total_path_mm == pytest.approx(50 * 100 * 50 / 0.5)
    s1 = load_settings("marlin-mixing", {"strategy": 1, "bead_width": 0.5, "walls": 2, "infill_density": 20,
                                         "top_layers": 3, "bottom_layers": 3})
    est1 = estimate(graded_box(100, 50, 10), s1, 50)
    walls = 2 * 2 * 150
    assert est1.face_samples == 0
    assert est1.total_path_mm == pytest.approx(50 * walls + 6 * 10_000 + 44 * 2_000)
    assert est1.layer_path_mm < MAX_LAYER_PATH_MM


def test_one_color_needs_no_face_samples():
    settings = load_settings("marlin-mixing", {**BIG_BED, "strategy": 2, "colors": 1, "bead_width": 2.0})
    assert check_resources(graded_box(4000, 4000, 1), settings, 5).face_samples == 0
