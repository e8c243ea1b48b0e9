"""Arc fitting (fgslice.machine.arcs) and G2/G3 through the writer, the reader and the time model."""

from __future__ import annotations

import numpy as np
import pytest
import shapely

from fgslice.design import api
from fgslice.errors import SettingsError
from fgslice.machine.arcs import fit_arcs
from fgslice.machine.gcode_reader import read_gcode
from fgslice.machine.timing import estimate_time
from fgslice.pipeline import slice_to_gcode
from fgslice.settings import load_settings

TOLERANCE = 0.0125


def _paths(rng):
    """A noisy circle, a square, an S curve and a spiral, as written (3 decimals)."""
    t = np.linspace(0, 2 * np.pi, 301)
    circle = np.column_stack([100 + 20 * np.cos(t), 100 + 20 * np.sin(t)]) + rng.normal(0, 0.002, (301, 2))
    square = np.array([[0, 0], [10, 0], [10, 10], [0, 10], [0, 0]], dtype=float)
    a = np.linspace(0, np.pi, 60)
    s_curve = np.vstack([np.column_stack([50 + 10 * np.cos(a), 50 + 10 * np.sin(a)]),
                         np.column_stack([30 + 10 * np.cos(a[::-1]), 50 - 10 * np.sin(a[::-1])])[1:]])
    w = np.linspace(0, 6 * np.pi, 400)
    spiral = np.column_stack([120 + (5 + w) * np.cos(w), 60 + (5 + w) * np.sin(w)])
    return [np.round(p, 3) for p in (circle, square, s_curve, spiral)]


def _arc_points(start, end, offset, turn, samples=50):
    """Points along an arc from ``start`` to ``end`` around ``start + offset``."""
    centre = start + offset
    r = np.hypot(*(start - centre))
    a0 = np.arctan2(*(start - centre)[::-1])
    a1 = np.arctan2(*(end - centre)[::-1])
    sweep = np.mod((a1 - a0) * turn, 2 * np.pi)
    angles = a0 + turn * np.linspace(0, sweep, samples)
    return centre + r * np.column_stack([np.cos(angles), np.sin(angles)])


def test_fitted_arcs_stay_within_the_tolerance_and_keep_the_length():
    paths = _paths(np.random.default_rng(3))
    starts = np.array([p[0] for p in paths])
    ends = np.vstack([p[1:] for p in paths])
    owner = np.repeat(np.arange(len(paths)), [len(p) - 1 for p in paths])
    fitted = fit_arcs(starts, ends, owner, TOLERANCE)
    assert (fitted.turn != 0).sum() >= 4 and len(fitted.ends) < len(ends) / 10
    assert not (fitted.turn[fitted.path == 1]).any()  # the square's corners stay corners
    polylines = [shapely.LineString(p) for p in paths]
    position = starts[fitted.path[0]]
    for k in range(len(fitted.ends)):
        if k and fitted.path[k] != fitted.path[k - 1]:
            position = starts[fitted.path[k]]
        if fitted.turn[k]:
            samples = _arc_points(position, fitted.ends[k], np.round(fitted.offset[k], 3), fitted.turn[k])
            distance = shapely.distance(shapely.points(samples), polylines[fitted.path[k]])
            assert distance.max() <= TOLERANCE
        position = fitted.ends[k]
    for index, path in enumerate(paths):
        length = np.hypot(*np.diff(path, axis=0).T).sum()
        assert fitted.length[fitted.path == index].sum() == pytest.approx(length, rel=1e-3)


def _slice(tmp_path, name, **overrides):
    design = api.design(api.fgrade(["clamp(0, rho/20, 1)", "1 - clamp(0, rho/20, 1)"], ["blue", "yellow"],
                                   api.cylinder(20, 0.6)))
    settings = load_settings(None, {"strategy": "2", "colors": "4", "thumbnails": "",
                                    **{k: str(v) for k, v in overrides.items()}})
    out = tmp_path / f"{name}.gcode"
    stats = slice_to_gcode(design, settings, out, jobs=1).stats
    return settings, out, stats


def test_a_slice_with_arcs_extrudes_the_same_volume_in_a_shorter_file(tmp_path):
    settings, lines, plain = _slice(tmp_path, "lines")
    _, arcs, fitted = _slice(tmp_path, "arcs", arc_fitting="emit_center")
    text = arcs.read_text()
    assert "\nG2 X" in text or "\nG3 X" in text
    assert "\nG2 " not in lines.read_text() and "\nG3 " not in lines.read_text()
    assert arcs.stat().st_size < 0.6 * lines.stat().st_size
    assert fitted["extruded_mm3"] == pytest.approx(plain["extruded_mm3"], rel=1e-3)
    program = read_gcode(arcs)
    area = np.pi * settings.filament_diameter**2 / 4
    assert program.e.sum() * area == pytest.approx(fitted["extruded_mm3"], rel=1e-4)
    # the time model plans arcs as the firmware's 1 mm pieces: close to the straight moves' time
    assert fitted["estimated_time_s"] == pytest.approx(plain["estimated_time_s"], rel=0.05)
    # every piece of the arcs, as the firmware prints them, lies on the part's printed area
    split = program.split_arcs()
    printing = (split.e > 0) & (program.split_arcs().length > 0)
    straight = read_gcode(lines)
    reference = shapely.union_all(shapely.buffer(shapely.linestrings(np.stack(
        [straight.start[straight.e > 0, :2], straight.end[straight.e > 0, :2]], axis=1)), TOLERANCE + 1e-3))
    assert shapely.contains_xy(reference, *split.end[printing, :2].T).mean() > 0.999


def test_arcs_are_refused_on_the_template_dialect_and_off_by_default():
    assert load_settings(None, {}).arc_fitting == "disabled"
    with pytest.raises(SettingsError, match="arc_fitting"):
        load_settings("template-diw", {"arc_fitting": "emit_center"})


def test_the_reader_splits_arcs_as_the_firmware_does():
    text = "G90\nM83\nG1 X30 Y20 Z0.2 F1200\nG2 X10 Y20 I-10 J0 E2\nG3 X0 Y30 R10 E1\n"
    program = read_gcode(text.encode())
    split = program.split_arcs()
    assert program.length[1:].sum() == pytest.approx(15 * np.pi)
    assert len(split.e) == 1 + 32 + 16
    first = split.line == 4
    assert np.hypot(split.end[first, 0] - 20, split.end[first, 1] - 20) == pytest.approx(10)
    assert (split.end[first, 1] <= 20 + 1e-9).all()  # clockwise from the east: through the south
    assert split.e.sum() == pytest.approx(3) and split.length.sum() == pytest.approx(np.hypot(30, 20) + 15 * np.pi, rel=1e-3)
    assert estimate_time(text, load_settings(None, {})) > estimate_time("G1 X30 Y20 Z0.2 F1200\n",
                                                                          load_settings(None, {}))


def _greedy_arcs(starts, ends, owner, tolerance):
    """The arcs one path at a time, one trial at a time (the greedy search the module
    describes, with its own single-window check): ``{(path, first point, last point): (centre, turn)}``."""
    from fgslice.machine.arcs import MAX_SEGMENTS, MIN_SEGMENTS, ROUNDING_MM, _fit_many

    limit = tolerance - ROUNDING_MM
    found = {}
    for index in np.unique(owner):
        points = np.vstack([starts[index], ends[owner == index]])
        d = np.diff(points, axis=0)
        sign = np.sign(d[:-1, 0] * d[1:, 1] - d[:-1, 1] * d[1:, 0])

        def fit(a, size):
            ok, centre, turn = _fit_many(points[a : a + size + 1][None], limit)
            return (tuple(centre[0]), int(turn[0])) if ok[0] else None

        # moves k, k + 1, k + 2 turn one way: runs of such k cover their moves and two more
        same = [bool(sign[k] == sign[k + 1] != 0) for k in range(len(sign) - 1)] + [False]
        runs, begin = [], None
        for k, flag in enumerate(same):
            if flag and begin is None:
                begin = k
            if not flag and begin is not None:
                runs.append((begin, k + 1))
                begin = None
        for a, run_end in runs:
            while run_end - a + 1 >= MIN_SEGMENTS:
                best = fit(a, MIN_SEGMENTS)
                if best is None:
                    a += 1
                    continue
                low, high = MIN_SEGMENTS, min(run_end - a + 1, MAX_SEGMENTS)
                longest = fit(a, high) if high > low else best
                if longest is not None:
                    low, best = high, longest
                while high - low > 1:
                    mid = (low + high) // 2
                    trial = fit(a, mid)
                    if trial is None:
                        high = mid
                    else:
                        low, best = mid, trial
                found[(int(index), a, a + low)] = best
                a += low
    return found


def test_every_path_grown_together_gives_the_arcs_of_one_path_at_a_time(monkeypatch):
    from fgslice.machine import arcs as module

    rng = np.random.default_rng(8)
    paths = _paths(rng)
    for _ in range(40):  # arcs of ellipses of every size, clean and noisy
        t = np.sort(rng.uniform(0, 2 * np.pi * rng.uniform(0.2, 1.5), rng.integers(5, 300)))
        r = rng.uniform(0.5, 60)
        p = np.column_stack([r * np.cos(t), r * rng.uniform(0.5, 1) * np.sin(t)]) + rng.uniform(0, 200, 2)
        paths.append(np.round(p + rng.normal(0, rng.choice([0, 0.001, 0.01]), p.shape), 3))
    starts = np.array([p[0] for p in paths])
    ends = np.vstack([p[1:] for p in paths])
    owner = np.repeat(np.arange(len(paths)), [len(p) - 1 for p in paths])
    spans = []
    monkeypatch.setattr(module, "_replace", lambda lines, vertices, vertex_of_end, found: spans.append(found) or lines)
    fit_arcs(starts, ends, owner, TOLERANCE)
    first, last, centre, turn = spans[0]
    path_start = np.searchsorted(owner, np.arange(len(paths)))
    arcs = {(int(owner[f]), int(f - path_start[owner[f]]), int(l + 1 - path_start[owner[f]])): (c, int(t))
            for f, l, c, t in zip(first, last, centre, turn)}
    expected = _greedy_arcs(starts, ends, owner, TOLERANCE)
    assert len(expected) > 100
    assert arcs.keys() == expected.keys()
    for key, (c, t) in expected.items():
        assert arcs[key][1] == t
        assert tuple(arcs[key][0]) == pytest.approx(c, abs=1e-9)
