"""Seams: where closed loops start, measured in the G-code for each seam_position."""

import numpy as np
import pytest

from fgslice.design.language import parse_design
from fgslice.machine.gcode_reader import read_gcode
from fgslice.pipeline import slice_to_gcode
from fgslice.settings import load_settings

# a round back (smooth: no corner) and a square nose at the front (sharp corners)
DESIGN = """
fgrade(["0.5", "0.5"], ["blue", "yellow"]) {
    translate(0, 0, 2) { difference() {
        union() { cylinder(8, 4); translate(0, -8, 0) { rectprism(6, 8, 4); } }
        cylinder(2, 6);
    } }
}
"""


def _loops(path, roles_wanted):
    """Closed loops of the wanted roles: (layer, role, (k, 3) points, first move index)."""
    program = read_gcode(path)
    roles = np.array(program.roles + [""], dtype=object)[program.role]
    printing = (program.e > 0) & (program.length > 0)
    loops, current = [], None
    for i in range(len(program.e)):
        joined = current is not None and printing[i] and roles[i] == current[1] and np.allclose(
            program.start[i], current[2][-1], atol=1e-6)
        if joined:
            current[2].append(program.end[i])
            continue
        if current is not None and np.allclose(current[2][0], current[2][-1], atol=2e-3) and len(current[2]) > 3:
            loops.append(current)
        current = [int(program.layer[i]), roles[i], [program.start[i], program.end[i]]] if printing[i] else None
    if current is not None and np.allclose(current[2][0], current[2][-1], atol=2e-3):
        loops.append(current)
    return [(layer, role, np.array(points)) for layer, role, points in loops if role in roles_wanted]


def _slice(tmp_path, strategy, seam):
    settings = load_settings(None, {"strategy": str(strategy), "colors": "1", "seam_position": seam, "walls": "3"})
    out = tmp_path / f"seam_{strategy}_{seam}.gcode"
    slice_to_gcode(parse_design(DESIGN), settings, out, jobs=1)
    return out


@pytest.mark.parametrize("strategy", [1, 2])
def test_rear_seams_start_every_loop_at_its_rearmost_point(tmp_path, strategy):
    roles = {"External perimeter", "Perimeter", "Solid infill", "Skirt/Brim"}
    loops = _loops(_slice(tmp_path, strategy, "rear"), roles)
    assert len(loops) > 40
    for _, _, points in loops:
        assert points[0, 1] >= points[:, 1].max() - 0.011


def test_nearest_seams_do_not_all_sit_at_the_rear(tmp_path):
    loops = _loops(_slice(tmp_path, 1, "nearest"), {"External perimeter", "Perimeter"})
    at_rear = [points[0, 1] >= points[:, 1].max() - 0.011 for _, _, points in loops]
    assert np.mean(at_rear) < 0.5


def _outer_seams(loops):
    """Per layer, the start of the outer island's external perimeter (the longest loop)."""
    seams = {}
    for layer, _, points in loops:
        length = np.hypot(*np.diff(points[:, :2], axis=0).T).sum()
        if layer not in seams or length > seams[layer][0]:
            seams[layer] = (length, points[0, :2], points)
    return seams


def test_aligned_seams_line_up_at_a_corner(tmp_path):
    seams = _outer_seams(_loops(_slice(tmp_path, 1, "aligned"), {"External perimeter"}))
    starts = np.array([start for _, start, _ in seams.values()])
    assert len(starts) == 20
    assert np.ptp(starts, axis=0).max() < 0.01  # one place on every layer
    _, start, points = next(iter(seams.values()))
    assert start[1] < points[:, 1].min() + 0.01  # at the nose's corners, not the round back


def test_random_seams_scatter(tmp_path):
    seams = _outer_seams(_loops(_slice(tmp_path, 1, "random"), {"External perimeter"}))
    starts = np.array([start for _, start, _ in seams.values()])
    assert len(np.unique(np.round(starts, 1), axis=0)) >= 15
    again = _outer_seams(_loops(_slice(tmp_path, 1, "random"), {"External perimeter"}))
    assert np.array_equal(starts, np.array([start for _, start, _ in again.values()]))
