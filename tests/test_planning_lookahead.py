"""Look-ahead of state changes: exact distances, splits, order, layers, streaming."""

import numpy as np
import pytest
import shapely

from fgslice.errors import SettingsError
from fgslice.planning.lookahead import apply_lookahead, apply_time_lead, split_path
from fgslice.planning.plan import LayerPlan, SetState
from fgslice.toolpaths.paths import Path, Role


def synthetic_plans(n_layers, rng, colors=4, groups_per_layer=3, paths_per_group=(1, 5)):
    """Layers of color groups: SetState(c) then open zigzags and closed loops of random size."""
    plans = []
    color = 0
    for k in range(n_layers):
        steps = []
        if k == 0:
            steps.append(Path(rng.uniform(0, 50, (3, 2)), Role.SKIRT, -1, 0.4, 0.2))
        for _ in range(groups_per_layer):
            color = (color + 1) % colors
            steps.append(SetState(color))
            for _ in range(rng.integers(*paths_per_group)):
                pts = rng.uniform(0, 50, (rng.integers(2, 6), 2))
                closed = bool(rng.integers(2)) and len(pts) >= 3
                steps.append(Path(pts, Role.PERIMETER, color, 0.4, 0.2, closed=closed))
        plans.append(LayerPlan(index=k, z=0.2 * (k + 1), height=0.2, steps=steps))
    return plans


def walk(plans, measure=lambda p: p.length):
    """(position of each SetState, its layer, its color) and the paths with their starts."""
    changes, paths, total = [], [], 0.0
    for plan in plans:
        for step in plan.steps:
            if isinstance(step, SetState):
                changes.append((total, plan.index, step.color))
            else:
                paths.append((total, step))
                total += measure(step)
    return changes, paths, total


def assert_paths_split_exactly(inp_paths, out_paths):
    """Output paths are the input ones, in order, some cut into pieces along their polyline."""
    j = 0
    for _, original in inp_paths:
        line = shapely.LineString(original.vertices)
        pieces, length = [], 0.0
        while length < original.length - 1e-9:
            piece = out_paths[j][1]
            j += 1
            pieces.append(piece)
            length += piece.length
        assert length == pytest.approx(original.length, abs=1e-9)
        if len(pieces) == 1:
            assert pieces[0] is original
            continue
        assert np.allclose(pieces[0].points[0], original.points[0])
        assert np.allclose(pieces[-1].points[-1], original.vertices[-1])
        for a, b in zip(pieces, pieces[1:]):
            assert np.allclose(a.points[-1], b.points[0])
        for piece in pieces:
            assert not piece.closed
            assert (piece.role, piece.color, piece.width, piece.height) == (
                original.role, original.color, original.width, original.height)
            assert shapely.distance(line, shapely.MultiPoint(piece.points)) < 1e-9
    assert j == len(out_paths)


@pytest.mark.parametrize("distance", [0.0, 7.5, 60.0, 400.0, 2500.0])
def test_each_change_lands_exactly_the_distance_before_its_anchor(distance):
    rng = np.random.default_rng(11)
    plans = synthetic_plans(12, rng)
    out = list(apply_lookahead(iter(plans), distance))
    inp_changes, inp_paths, inp_total = walk(plans)
    out_changes, out_paths, out_total = walk(out)
    assert [len(out), [p.index for p in out]] == [len(plans), list(range(12))]
    assert out_total == pytest.approx(inp_total, abs=1e-9)
    assert [c for _, _, c in out_changes] == [c for _, _, c in inp_changes]  # none dropped or reordered
    for (anchor, _, color), (position, _, _) in zip(inp_changes, out_changes):
        assert position == pytest.approx(max(anchor - distance, 0.0), abs=1e-6)
        # The new color's first path still starts at the anchor.
        assert any(abs(start - anchor) < 1e-6 and p.color == color for start, p in out_paths)
    assert_paths_split_exactly(inp_paths, out_paths)
    if distance == 0:
        assert out == plans


def test_changes_move_into_previous_layers_and_several_are_in_flight():
    rng = np.random.default_rng(12)
    plans = synthetic_plans(10, rng)
    layer_lengths = [sum(p.length for p in plan.paths) for plan in plans]
    distance = 1.5 * max(layer_lengths)
    out = list(apply_lookahead(iter(plans), distance))
    inp_changes, _, _ = walk(plans)
    out_changes, _, _ = walk(out)
    moved_layers = [o[1] for i, o in zip(inp_changes, out_changes) if i[0] > distance]
    original_layers = [i[1] for i in inp_changes if i[0] > distance]
    assert moved_layers and all(m < o for m, o in zip(moved_layers, original_layers))
    assert all(o - m >= 1 for m, o in zip(moved_layers, original_layers))
    # In flight: a change is issued while earlier ones have not reached their anchors yet.
    positions = np.array([o[0] for o in out_changes])
    anchors = np.array([i[0] for i in inp_changes])
    in_flight = [(anchors[:i] > positions[i]).sum() for i in range(len(positions))]
    assert max(in_flight) >= 3


def test_changes_before_the_start_are_clamped_at_the_first_extrusion():
    rng = np.random.default_rng(13)
    plans = synthetic_plans(3, rng)
    plans[0].steps = [s for s in plans[0].steps if not isinstance(s, Path) or s.role is not Role.SKIRT]
    out = list(apply_lookahead(iter(plans), 1e6))
    states = [s for s in out[0].steps[:9] if isinstance(s, SetState)]
    assert len(states) == 9  # every change is issued before the first path
    assert [s.color for s in states] == [s.color for p in plans for s in p.steps if isinstance(s, SetState)]
    assert isinstance(out[0].steps[9], Path)


def test_split_path_cuts_open_and_closed_paths_at_exact_lengths():
    square = Path(np.array([[0, 0], [10, 0], [10, 10], [0, 10]], float), Role.PERIMETER, 3, 0.5, 0.25, closed=True)
    pieces = split_path(square, [5.0, 10.0, 37.5])
    assert [p.length for p in pieces] == pytest.approx([5.0, 5.0, 27.5, 2.5])
    assert np.allclose(pieces[0].points, [[0, 0], [5, 0]])
    assert np.allclose(pieces[1].points, [[5, 0], [10, 0]])
    assert np.allclose(pieces[3].points, [[0, 2.5], [0, 0]])
    assert all(not p.closed and p.color == 3 and p.width == 0.5 for p in pieces)


def test_time_lead_measures_printing_time():
    rng = np.random.default_rng(14)
    plans = synthetic_plans(8, rng)
    speeds = {Role.PERIMETER: 20.0, Role.SKIRT: 50.0}
    speed_of = lambda p: speeds[p.role]  # noqa: E731
    seconds = lambda p: p.length / speed_of(p)  # noqa: E731
    out = list(apply_time_lead(iter(plans), 3.0, speed_of))
    inp_changes, inp_paths, _ = walk(plans, seconds)
    out_changes, out_paths, _ = walk(out, seconds)
    for (anchor, _, _), (position, _, _) in zip(inp_changes, out_changes, strict=True):
        assert position == pytest.approx(max(anchor - 3.0, 0.0), abs=1e-6)
    assert_paths_split_exactly(walk(plans)[1], walk(out)[1])


def test_streaming_holds_only_a_window_of_layers():
    """500 layers x 40 paths: output layer k is produced before input layer k + 3 is read."""
    rng = np.random.default_rng(15)
    template = synthetic_plans(4, rng, groups_per_layer=4, paths_per_group=(10, 11))
    layer_length = min(sum(p.length for p in plan.paths) for plan in template)
    read = []

    def source():
        for k in range(500):
            plan = template[k % 4]
            read.append(k)
            yield LayerPlan(index=k, z=0.2 * (k + 1), height=0.2, steps=plan.steps)

    lag = []
    count = 0
    for plan in apply_lookahead(source(), 1.5 * layer_length):
        lag.append(len(read) - 1 - plan.index)
        count += 1
    assert count == 500
    assert max(lag) <= 3


def test_negative_or_nan_leads_are_refused():
    with pytest.raises(SettingsError, match="lookahead_mm"):
        list(apply_lookahead(iter([]), -1.0))
    with pytest.raises(SettingsError, match="temperature_lead_s"):
        list(apply_time_lead(iter([]), float("nan"), lambda p: 1.0))
