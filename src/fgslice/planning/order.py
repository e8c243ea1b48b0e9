"""Order one layer's paths: color groups in palette order, then travel-minimizing tours.

A layer is printed as: the paths of color ``-1`` (the skirt, printed in whatever state
the printer is in), then one group per palette color in the layer's traversal order
(``Palette.order_for_layer``), each opened by a :class:`SetState`. Every color is printed
once per layer. Inside a color, walls (external perimeters and perimeters) come before
everything else for ``feature_order == "walls_first"`` and after it for
``"infill_first"``.

Paths with a ``group`` id (the walls of one island, holes included, as
``toolpaths.walls.make_walls`` gives them) form a *unit* printed in its list order, so the
wall order (outer-first or inner-first) survives cutting into colors: a color group
prints its units first, each entered at the unit whose first path is nearest, every
path of a unit rotated (closed) or reversed (open) to start nearest the nozzle. The
paths' end points are gathered once per layer, so orienting an open path is a comparison
of two distances and a closed path one vectorized nearest-vertex search; only paths that
change get a new :class:`Path`.
The other paths of a group are toured greedily: from the nozzle position, go to the
nearest path entry not printed yet. Entries are both ends of an open path (entering at
the far end reverses the path) and vertices of a closed path (entering there rotates
the path to start at that vertex). Nearest entries come from a :class:`scipy.spatial.cKDTree`;
each entry's nearest neighbours are precomputed in one batched query, so the tour
usually just scans a short list; a fresh query on a tree of the entries still alive
handles the rest. Coordinates are bed-frame mm.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from operator import attrgetter

import numpy as np
from scipy.spatial import cKDTree

from fgslice.errors import SettingsError
from fgslice.planning.plan import LayerPlan, SetState, Step
from fgslice.toolpaths.paths import LayerPaths, Path, Role

WALL_ROLES = frozenset({Role.EXTERNAL_PERIMETER, Role.PERIMETER})
FEATURE_ORDERS = ("walls_first", "infill_first")
SKIRT_COLOR = -1

#: Closed paths are entered at any vertex, but the search index holds one vertex per
#: this much arc length (mm); the exact nearest vertex is chosen once the path is picked.
CLOSED_ENTRY_SPACING_MM = 1.0
#: Neighbours precomputed per entry.
NEIGHBOURS = 6
#: Neighbours asked for first when the precomputed ones are all visited.
FALLBACK_K = 64
#: Below this many unvisited entries, nearest-entry queries are one numpy pass.
BRUTE_FORCE_ENTRIES = 256


def order_layer(
    paths: LayerPaths,
    color_sequence: np.ndarray,
    start_xy: np.ndarray,
    feature_order: str,
) -> LayerPlan:
    """The layer's paths as an ordered plan with one :class:`SetState` per color group.

    Args:
        paths: the layer's unordered paths (bed frame, mm).
        color_sequence: palette color indices in the order to print them on this layer;
            colors absent from the layer are skipped.
        start_xy: nozzle XY (mm) when the layer starts, e.g. the end of the previous layer.
        feature_order: ``"walls_first"`` or ``"infill_first"``.

    Returns:
        A :class:`LayerPlan`: color ``-1`` paths first (no state set), then for each color
        ``SetState(c)`` followed by its paths, each group toured nearest-neighbour.

    Raises:
        SettingsError: unknown ``feature_order``.
        ValueError: a path's color is neither ``-1`` nor in ``color_sequence``.
    """
    if feature_order not in FEATURE_ORDERS:
        raise SettingsError(
            f"feature_order '{feature_order}' is not one of {', '.join(FEATURE_ORDERS)}",
            hint="--set feature_order=walls_first",
        )
    plan = LayerPlan(index=paths.index, z=paths.z, height=paths.height)
    if not paths.paths:
        return plan
    sequence = np.asarray(color_sequence, dtype=np.int64).reshape(-1)
    colors = np.fromiter(map(attrgetter("color"), paths.paths), dtype=np.int64, count=len(paths.paths))
    roles = map(attrgetter("role"), paths.paths)
    walls = np.fromiter(map(WALL_ROLES.__contains__, roles), dtype=bool, count=len(paths.paths))
    stray = np.setdiff1d(colors, np.append(sequence, SKIRT_COLOR))
    if stray.size:
        raise ValueError(f"layer {paths.index}: path colors {stray.tolist()} are not in the color sequence")

    rank = np.full(max(int(colors.max()), int(sequence.max(initial=0))) + 2, -1, dtype=np.int64)
    rank[sequence[::-1]] = np.arange(sequence.size)[::-1]  # first occurrence wins
    feature_late = ~walls if feature_order == "walls_first" else walls
    group_key = np.where(colors == SKIRT_COLOR, -1, rank[colors] * 2 + feature_late)
    order = np.argsort(group_key, kind="stable")
    keys = group_key[order]
    bounds = np.flatnonzero(np.diff(keys)) + 1
    position = np.asarray(start_xy, dtype=np.float64).reshape(2)
    ends = _Ends(paths.paths)
    steps: list[Step] = []
    current = None
    for members in np.split(order, bounds):
        color = int(colors[members[0]])
        if color != SKIRT_COLOR and color != current:
            steps.append(SetState(color))
            current = color
        toured, position = _tour_units(paths.paths, members, ends, position)
        steps.extend(toured)
    plan.steps = steps
    return plan


class _Ends:
    """The first and last points of a layer's paths, gathered once per layer.

    Attributes:
        closed, group: each path's ``closed`` and ``group`` (Python lists).
        sx, sy, ex, ey: first and last point coordinates (Python lists of floats, mm).
    """

    def __init__(self, paths: Sequence[Path]) -> None:
        n = len(paths)
        arrays = list(map(attrgetter("points"), paths))
        offsets = np.zeros(n + 1, dtype=np.int64)
        np.cumsum(np.fromiter(map(len, arrays), dtype=np.int64, count=n), out=offsets[1:])
        points = np.concatenate(arrays)
        self.closed = list(map(attrgetter("closed"), paths))
        self.group = list(map(attrgetter("group"), paths))
        self.sx, self.sy = points[offsets[:-1]].T.tolist()
        self.ex, self.ey = points[offsets[1:] - 1].T.tolist()


def _tour_units(
    paths: Sequence[Path], members: np.ndarray, ends: _Ends, position: np.ndarray
) -> tuple[list[Path], np.ndarray]:
    """Print the units of grouped paths among ``paths[members]`` (nearest unit first, each
    in its list order), then tour the ungrouped ones greedily. Returns the oriented paths
    and the final XY."""
    units: dict[int, list[int]] = {}
    loose: list[int] = []
    group = ends.group
    for i in members.tolist():
        (units.setdefault(group[i], []) if group[i] >= 0 else loose).append(i)
    out: list[Path] = []
    x, y = float(position[0]), float(position[1])
    pending = list(units.values())
    while pending:
        gaps = [_entry_distance(paths, ends, unit[0], x, y) for unit in pending]
        x, y = _walk_unit(paths, pending.pop(int(np.argmin(gaps))), ends, x, y, out)
    position = np.array([x, y])
    if not loose:
        return out, position
    toured, position = travel_tour([paths[i] for i in loose], position)
    return out + toured, position


def _entry_distance(paths: Sequence[Path], ends: _Ends, i: int, x: float, y: float) -> float:
    """Distance (mm) from ``(x, y)`` to the nearest entry of path ``i`` (any vertex if
    closed, an end if open)."""
    if ends.closed[i]:
        d = paths[i].points - (x, y)
        return float(np.sqrt(np.min(np.einsum("ij,ij->i", d, d))))
    return min(math.hypot(ends.sx[i] - x, ends.sy[i] - y), math.hypot(ends.ex[i] - x, ends.ey[i] - y))


def _walk_unit(
    paths: Sequence[Path], unit: list[int], ends: _Ends, x: float, y: float, out: list[Path]
) -> tuple[float, float]:
    """Append the paths ``unit`` to ``out`` in order, each rotated (closed) or reversed
    (open) to start at its entry nearest the nozzle; returns the final nozzle XY (mm)."""
    sx, sy, ex, ey, closed = ends.sx, ends.sy, ends.ex, ends.ey, ends.closed
    for i in unit:
        path = paths[i]
        if closed[i]:
            points = path.points
            d = points - (x, y)
            vertex = int(np.argmin(np.einsum("ij,ij->i", d, d)))
            if vertex:
                path = _moved(path, np.concatenate((points[vertex:], points[:vertex])))
            x, y = float(points[vertex, 0]), float(points[vertex, 1])
        elif (ex[i] - x) ** 2 + (ey[i] - y) ** 2 < (sx[i] - x) ** 2 + (sy[i] - y) ** 2:
            path = _moved(path, path.points[::-1])
            x, y = sx[i], sy[i]
        else:
            x, y = ex[i], ey[i]
        out.append(path)
    return x, y


def _moved(path: Path, points: np.ndarray) -> Path:
    """``path`` with its points replaced (rotated or reversed); the constructor directly,
    as ``dataclasses.replace`` costs several times more per path."""
    return Path(points, path.role, path.color, path.width, path.height, path.closed, path.group)


def travel_distance(paths: Sequence[Path], start_xy: np.ndarray) -> float:
    """Total travel (mm) to print ``paths`` in order from ``start_xy``: start to the first
    path's start, then each path's end to the next path's start."""
    if not paths:
        return 0.0
    starts = np.array([p.start for p in paths])
    ends = np.array([np.asarray(start_xy, dtype=np.float64)] + [p.end for p in paths[:-1]])
    return float(np.sum(np.hypot(*(starts - ends).T)))


def travel_tour(paths: Sequence[Path], start_xy: np.ndarray) -> tuple[list[Path], np.ndarray]:
    """Greedy nearest-neighbour tour of ``paths`` from ``start_xy`` (mm).

    Open paths may be reversed, closed paths rotated, to start at the entry nearest to
    the nozzle. Returns the oriented paths in printing order and the final nozzle XY.
    """
    n = len(paths)
    if n == 0:
        return [], np.asarray(start_xy, dtype=np.float64)
    entries = _Entries(paths)
    tour = _GreedyTour(entries)
    out: list[Path] = []
    position = np.asarray(start_xy, dtype=np.float64).reshape(2)
    at_entry = -1
    for _ in range(n):
        chosen = tour.nearest_from_entry(at_entry) if at_entry >= 0 else -1
        if chosen < 0:
            chosen = tour.nearest_from_point(position)
        index = entries.path_of[chosen]
        tour.visit(index)
        path = paths[index]
        if path.closed:
            points = path.points
            vertex = int(np.argmin(np.einsum("ij,ij->i", points - position, points - position)))
            if vertex:
                path = _moved(path, np.roll(points, -vertex, axis=0))
            position = path.points[0]
            at_entry = -1
        else:
            if entries.reverses[chosen]:
                path = _moved(path, path.points[::-1])
            at_entry = entries.partner[chosen]
            position = path.points[-1]
        out.append(path)
    return out, position


class _Entries:
    """Where each path can be entered: both ends of open paths, spaced vertices of closed ones.

    Attributes:
        xy: ``(M, 2)`` entry positions, mm.
        path_of: path index of each entry (Python list).
        reverses: for open-path entries, True at the path's last point (Python list).
        partner: for open-path entries, the entry at the other end; -1 for closed paths.
        count: entries per path (Python list).
    """

    def __init__(self, paths: Sequence[Path]) -> None:
        n = len(paths)
        closed = np.fromiter((p.closed for p in paths), dtype=bool, count=n)
        sizes = np.fromiter((len(p.points) for p in paths), dtype=np.int64, count=n)
        allpts = np.concatenate([p.points for p in paths])
        first = np.concatenate([[0], np.cumsum(sizes)[:-1]])
        last = first + sizes - 1

        open_idx = np.flatnonzero(~closed)
        ends = np.empty((2 * open_idx.size, 2))
        ends[0::2] = allpts[first[open_idx]]
        ends[1::2] = allpts[last[open_idx]]
        open_path = np.repeat(open_idx, 2)
        open_reverse = np.tile([False, True], open_idx.size)
        partner = np.arange(2 * open_idx.size) ^ 1

        # Closed paths: keep a vertex each time the arc length enters a new bucket.
        owner = np.repeat(np.arange(n), sizes)
        steps = np.hypot(*np.diff(allpts, axis=0, prepend=allpts[:1]).T)
        steps[first] = 0.0
        arc = np.cumsum(steps)
        arc -= np.repeat(arc[first], sizes)
        bucket = np.floor(arc / CLOSED_ENTRY_SPACING_MM).astype(np.int64)
        keep = closed[owner]
        keep[1:] &= (bucket[1:] != bucket[:-1]) | (owner[1:] != owner[:-1])
        closed_xy, closed_path = allpts[keep], owner[keep]

        self.xy = np.concatenate([ends, closed_xy])
        path_of = np.concatenate([open_path, closed_path])
        self.path_of = path_of.tolist()
        self.path_of_array = path_of
        self.reverses = np.concatenate([open_reverse, np.zeros(closed_path.size, dtype=bool)]).tolist()
        self.partner = np.concatenate([partner, np.full(closed_path.size, -1)]).tolist()
        self.count = np.bincount(path_of, minlength=n).tolist()


class _GreedyTour:
    """Nearest-unvisited-entry queries for a greedy tour over :class:`_Entries`."""

    def __init__(self, entries: _Entries) -> None:
        self.entries = entries
        self.visited = [False] * len(entries.count)
        self.visited_array = np.zeros(len(entries.count), dtype=bool)
        self.alive = sum(entries.count)
        self.tree = cKDTree(entries.xy)
        self.tree_ids = np.arange(entries.xy.shape[0])
        k = min(NEIGHBOURS, entries.xy.shape[0])
        _, nearest = self.tree.query(entries.xy, k=k)
        self.neighbours = nearest.reshape(entries.xy.shape[0], k).tolist()

    def visit(self, path_index: int) -> None:
        self.visited[path_index] = True
        self.visited_array[path_index] = True
        self.alive -= self.entries.count[path_index]

    def nearest_from_entry(self, entry: int) -> int:
        """The nearest unvisited entry among ``entry``'s precomputed neighbours, or -1."""
        path_of, visited = self.entries.path_of, self.visited
        for candidate in self.neighbours[entry]:
            if not visited[path_of[candidate]]:
                return candidate
        return -1

    def nearest_from_point(self, xy: np.ndarray) -> int:
        """The nearest unvisited entry to ``xy``.

        Few entries left: one vectorized distance computation over them. Otherwise a
        tree query, growing ``k`` past visited entries; the tree is rebuilt over the
        unvisited entries once it holds twice as many entries as are left.
        """
        if self.tree_ids.size > 2 * self.alive or self.alive <= BRUTE_FORCE_ENTRIES:
            self._drop_visited()
        if self.alive <= BRUTE_FORCE_ENTRIES:
            d = self.entries.xy[self.tree_ids] - xy
            return int(self.tree_ids[np.argmin(np.einsum("ij,ij->i", d, d))])
        size = self.tree_ids.size
        visited = self.visited_array
        k = min(FALLBACK_K, size)
        while True:
            _, found = self.tree.query(xy, k=k)
            ids = self.tree_ids[np.atleast_1d(found)]
            alive = np.flatnonzero(~visited[self.entries.path_of_array[ids]])
            if alive.size:
                return int(ids[alive[0]])
            k = min(8 * k, size)

    def _drop_visited(self) -> None:
        """Keep only unvisited entries in the tree (and in ``tree_ids``)."""
        if self.tree_ids.size == self.alive:
            return
        alive = ~self.visited_array[self.entries.path_of_array[self.tree_ids]]
        self.tree_ids = self.tree_ids[alive]
        if self.alive > BRUTE_FORCE_ENTRIES:
            self.tree = cKDTree(self.entries.xy[self.tree_ids])
