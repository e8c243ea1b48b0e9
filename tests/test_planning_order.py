"""Layer ordering: color groups, feature order, and the greedy travel tour."""

import itertools

import numpy as np
import pytest

from fgslice.errors import SettingsError
from fgslice.planning.order import order_layer, travel_distance, travel_tour
from fgslice.planning.plan import SetState
from fgslice.toolpaths.paths import LayerPaths, Path, Role


def segment(x0, y0, x1, y1, color=0, role=Role.INTERNAL_INFILL):
    return Path(np.array([[x0, y0], [x1, y1]], dtype=float), role, color, 0.4, 0.2)


def loop(cx, cy, r, color=0, role=Role.PERIMETER, n=32):
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    return Path(np.c_[cx + r * np.cos(t), cy + r * np.sin(t)], role, color, 0.4, 0.2, closed=True)


def shuffled_grid(n, rng, colors=1):
    m = int(np.ceil(np.sqrt(n)))
    paths = [
        segment((i % m) * 2.0, (i // m) * 2.0, (i % m) * 2.0 + 1.5, (i // m) * 2.0, int(rng.integers(colors)))
        for i in range(n)
    ]
    rng.shuffle(paths)
    return paths


def same_geometry(a: Path, b: Path) -> bool:
    """Same set of printed segments (direction and starting vertex free)."""
    def edges(p):
        v = p.vertices
        pairs = np.sort(np.stack([v[:-1], v[1:]], axis=1).view([("x", float), ("y", float)]), axis=1)
        return sorted(map(tuple, pairs.view(float).reshape(-1, 4).round(9).tolist()))
    return edges(a) == edges(b)


def test_color_groups_follow_the_sequence_with_skirt_first_and_walls_first():
    rng = np.random.default_rng(1)
    paths = [segment(*rng.uniform(0, 50, 4), color=c, role=r)
             for c in (0, 2, 3) for r in (Role.INTERNAL_INFILL, Role.EXTERNAL_PERIMETER, Role.PERIMETER)
             for _ in range(3)]
    paths.append(loop(25, 25, 30, color=-1, role=Role.SKIRT))
    rng.shuffle(paths)
    plan = order_layer(LayerPaths(4, 1.0, 0.2, paths), np.array([3, 1, 0, 2]), np.zeros(2), "walls_first")
    assert (plan.index, plan.z, plan.height) == (4, 1.0, 0.2)
    assert plan.steps[0].role is Role.SKIRT
    states = [s.color for s in plan.steps if isinstance(s, SetState)]
    assert states == [3, 0, 2]  # color 1 is absent and skipped; each color once
    current = None
    kinds = []
    for step in plan.steps[1:]:
        if isinstance(step, SetState):
            current = step.color
            kinds.append([])
        else:
            assert step.color == current
            kinds[-1].append(step.role in (Role.EXTERNAL_PERIMETER, Role.PERIMETER))
    for group in kinds:
        assert group == sorted(group, reverse=True)  # walls, then the rest
    assert len(plan.paths) == len(paths)

    later = order_layer(LayerPaths(4, 1.0, 0.2, paths), np.array([3, 1, 0, 2]), np.zeros(2), "infill_first")
    first_of_groups = [later.steps[i + 1] for i, s in enumerate(later.steps) if isinstance(s, SetState)]
    assert all(p.role is Role.INTERNAL_INFILL for p in first_of_groups)


def test_every_path_is_printed_once_with_its_geometry():
    rng = np.random.default_rng(2)
    paths = shuffled_grid(60, rng, colors=3) + [loop(5, 5, 3, color=1), loop(40, 7, 2, color=2)]
    plan = order_layer(LayerPaths(0, 0.2, 0.2, paths), np.arange(3), np.array([100.0, 100.0]), "walls_first")
    out = plan.paths
    assert len(out) == len(paths)
    remaining = list(paths)
    for p in out:
        match = next(q for q in remaining if q.color == p.color and q.closed == p.closed and same_geometry(p, q))
        remaining.remove(match)
    assert not remaining


def brute_force_travel(paths, start):
    best = np.inf
    for perm in itertools.permutations(range(len(paths))):
        for flips in itertools.product((False, True), repeat=len(paths)):
            seq = [paths[i].points[::-1] if f else paths[i].points for i, f in zip(perm, flips)]
            starts = np.array([s[0] for s in seq])
            ends = np.array([start] + [s[-1] for s in seq[:-1]])
            best = min(best, np.hypot(*(starts - ends).T).sum())
    return best


def test_greedy_tour_is_close_to_the_brute_force_optimum_on_tiny_cases():
    rng = np.random.default_rng(3)
    ratios = []
    for _ in range(12):
        paths = [segment(*rng.uniform(0, 20, 4)) for _ in range(5)]
        start = rng.uniform(0, 20, 2)
        toured, _ = travel_tour(paths, start)
        ratios.append(travel_distance(toured, start) / brute_force_travel(paths, start))
    assert min(ratios) >= 1.0 - 1e-9
    assert max(ratios) < 2.0
    assert np.mean(ratios) < 1.35


def test_greedy_tour_is_much_shorter_than_a_shuffled_grid_order():
    rng = np.random.default_rng(4)
    paths = shuffled_grid(1000, rng)
    toured, end = travel_tour(paths, np.zeros(2))
    ordered, shuffled = travel_distance(toured, np.zeros(2)), travel_distance(paths, np.zeros(2))
    assert ordered < 0.05 * shuffled
    # Grid of 32 columns, gaps 0.5 mm in a row, 2 mm between rows: a tour near 1000 * 0.5 mm.
    assert ordered < 1000 * 0.5 * 2.0
    assert np.allclose(end, toured[-1].end)


def test_closed_paths_start_at_the_vertex_nearest_to_the_nozzle_and_open_ones_at_the_nearer_end():
    square = Path(np.array([[0, 0], [10, 0], [10, 10], [0, 10]], float), Role.PERIMETER, 0, 0.4, 0.2, closed=True)
    toured, end = travel_tour([square], np.array([11.0, 9.0]))
    assert np.allclose(toured[0].points[0], [10, 10])
    assert np.allclose(end, [10, 10])
    assert np.isclose(toured[0].length, square.length)
    toured, end = travel_tour([segment(0, 0, 10, 0)], np.array([12.0, 1.0]))
    assert np.allclose(toured[0].points, [[10, 0], [0, 0]])
    assert np.allclose(end, [0, 0])


def test_concentric_loops_are_toured_inside_out_without_long_jumps():
    loops = [loop(50, 50, r, n=200) for r in np.arange(1.0, 20.0, 0.4)]
    rng = np.random.default_rng(5)
    rng.shuffle(loops)
    toured, _ = travel_tour(loops, np.array([50.0, 50.0]))
    radii = [np.hypot(*(p.points[0] - 50)) for p in toured]
    assert np.all(np.diff(radii) > 0)
    assert travel_distance(toured, np.array([50.0, 50.0])) < 25.0


def test_bad_input_is_reported():
    paths = LayerPaths(0, 0.2, 0.2, [segment(0, 0, 1, 0, color=5)])
    with pytest.raises(ValueError, match="not in the color sequence"):
        order_layer(paths, np.arange(3), np.zeros(2), "walls_first")
    with pytest.raises(SettingsError, match="feature_order"):
        order_layer(paths, np.arange(6), np.zeros(2), "sideways")
    empty = order_layer(LayerPaths(1, 0.4, 0.2, []), np.arange(3), np.zeros(2), "walls_first")
    assert empty.steps == [] and empty.index == 1


def _wall_order(wall_order, start):
    """Printed wall loops of two islands (a square with a hole and a small square), one
    color, strategy 1 with 3 walls: (island index, distance of the loop to the surface)."""
    import shapely

    from fgslice.settings import Settings
    from fgslice.slicing.layers import LayerRegions
    from fgslice.slicing.palette import Palette
    from fgslice.toolpaths import strategy1

    class Uniform:
        def fractions(self, xy, z):
            return np.column_stack([np.full(len(xy), 0.3), np.full(len(xy), 0.7)])

    holed = shapely.box(0, 0, 30, 30).difference(shapely.box(10, 10, 20, 20))
    outline = shapely.MultiPolygon([holed, shapely.box(40, 0, 50, 10)])
    settings = Settings(strategy=1, walls=3, infill_density=20, wall_order=wall_order, top_layers=0, bottom_layers=0)
    lp, _ = strategy1.layer_paths(LayerRegions(2, 0.6, 0.2, outline, ()), [], [], Uniform(), Palette(2, 4), settings)
    plan = order_layer(lp, np.arange(4), np.asarray(start, dtype=float), "walls_first")
    walls = [s for s in plan.steps if isinstance(s, Path) and s.role in (Role.EXTERNAL_PERIMETER, Role.PERIMETER)]
    assert len(walls) == 9  # 3 loops around the square, 3 around its hole, 3 around the small square
    island = [int(shapely.box(-1, -1, 31, 31).contains(shapely.Point(p.points[0])) is False) for p in walls]
    depth = [shapely.LinearRing(p.points).distance(outline.boundary) for p in walls]
    return np.array(island), np.array(depth)


@pytest.mark.parametrize("start", [(0.0, 0.0), (60.0, 0.0)])
def test_wall_order_is_kept_per_island(start):
    for wall_order, sign in (("outer_first", 1), ("inner_first", -1)):
        island, depth = _wall_order(wall_order, start)
        # each island's loops are printed together, the nearer island first
        assert np.count_nonzero(np.diff(island)) == 1
        assert island[0] == (0 if start[0] < 30 else 1)
        for i in (0, 1):
            d = depth[island == i]
            assert np.all(sign * np.diff(d) >= -1e-6)  # outer -> inner, or inner -> outer
            assert d.max() - d.min() > 0.6  # three loops, 0.2 .. 0.91 mm deep


def test_large_mixed_group_tours_every_path_once_and_short():
    """Above the tree threshold and with more entries than one numpy pass handles: open
    segments and closed loops of one color, all printed once, with a short tour."""
    rng = np.random.default_rng(6)
    segments = shuffled_grid(2500, rng)
    loops = [loop(x, y, 0.4, n=12) for x, y in rng.uniform(0, 100, (300, 2))]
    paths = segments + loops
    rng.shuffle(paths)
    plan = order_layer(LayerPaths(0, 0.2, 0.2, paths), np.arange(1), np.zeros(2), "infill_first")
    out = plan.paths
    assert len(out) == len(paths)
    assert sum(p.closed for p in out) == len(loops)
    key = lambda p: (p.closed, *np.sort(p.points, axis=0).round(9).ravel().tolist())
    assert sorted(map(key, out)) == sorted(map(key, paths))
    travel = travel_distance(out, np.zeros(2))
    assert travel < 0.02 * travel_distance(paths, np.zeros(2))
    for p in out:
        if p.closed:
            continue
        # each open segment is printed from one end to the other of its original
        assert np.isclose(np.hypot(*(p.points[-1] - p.points[0])), 1.5)


@pytest.mark.parametrize("layout", ["curves", "cluster"])
def test_grid_tour_is_the_exact_nearest_entry_tour(layout, monkeypatch):
    """Large groups (grid of entries, precomputed neighbours, live block search) pick the
    same next path as one numpy pass over all entries does at every step: entries along
    thin curves across a wide box, and a dense cluster with far outliers and loops."""
    from fgslice.planning import order

    rng = np.random.default_rng(7)
    if layout == "curves":
        # Pieces of infill between two wavy boundaries, in several bands over 150 mm.
        x = rng.uniform(0, 150, 3000)
        band = rng.integers(0, 5, x.size) * 30.0
        y0 = band + 3 * np.sin(x / 9)
        paths = [segment(a, b, a + 0.3, b + 4 + rng.uniform(0, 0.5)) for a, b in zip(x, y0)]
    else:
        centre = rng.normal(0, 0.5, (2500, 4)) + 50
        paths = [segment(*row) for row in centre] + [segment(*rng.uniform(0, 400, 4)) for _ in range(40)]
        paths += [loop(x, y, 0.6, n=9) for x, y in rng.uniform(45, 55, (60, 2))]
    rng.shuffle(paths)
    layer = LayerPaths(0, 0.2, 0.2, paths)
    grid = order_layer(layer, np.arange(1), np.array([-20.0, 10.0]), "infill_first").paths
    monkeypatch.setattr(order, "GRID_MIN_PATHS", len(paths) + 1)
    scan = order_layer(layer, np.arange(1), np.array([-20.0, 10.0]), "infill_first").paths
    assert len(grid) == len(scan) == len(paths)
    assert all(np.array_equal(g.points, s.points) for g, s in zip(grid, scan))
    assert np.isclose(travel_distance(grid, np.zeros(2)), travel_distance(scan, np.zeros(2)))


def test_packed_plan_holds_each_input_path_turned_and_its_attributes():
    """The plan is packed straight from the tour's records: every step's points are an
    input path's points as they are, reversed (open) or rotated (closed), with that
    path's attributes, and the columns equal those of packing the built steps."""
    from fgslice.planning.plan import pack_steps

    rng = np.random.default_rng(7)
    paths = shuffled_grid(300, rng, colors=3) + [loop(20, 20, 5, color=c, n=9) for c in range(3)]
    paths += [Path(np.array([[0.0, 40], [5, 41], [9, 40]]), Role.EXTERNAL_PERIMETER, 1, 0.45, 0.2, group=4)]
    plan = order_layer(LayerPaths(0, 0.2, 0.2, paths), np.array([2, 0, 1]), np.array([30.0, -5.0]), "walls_first")
    packed = plan.packed
    assert packed is not None
    again = pack_steps(plan.steps, None)
    for name in ("kind", "ref", "points", "offsets", "roles", "colors", "widths", "heights", "closed", "groups",
                 "lengths", "rows"):
        assert np.array_equal(getattr(packed, name), getattr(again, name)), name
    printed = [s for s in plan.steps if isinstance(s, Path)]
    assert len(printed) == len(paths)
    for step in printed:
        source = [p for p in paths if p.color == step.color and same_geometry(p, step)
                  and (p.role, p.width, p.group, p.closed) == (step.role, step.width, step.group, step.closed)]
        assert source, "every printed path is an input path"
        p = source[0]
        if p.closed:
            k = int(np.flatnonzero((p.points == step.points[0]).all(axis=1))[0])
            assert np.array_equal(step.points, np.roll(p.points, -k, axis=0))
        else:
            assert np.array_equal(step.points, p.points) or np.array_equal(step.points, p.points[::-1])
