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
path of a unit rotated (closed) or reversed (open) to start nearest the nozzle.
The other paths of a group are toured greedily: from the nozzle position, go to the
nearest path entry not printed yet. Entries are both ends of an open path (entering at
the far end reverses the path) and vertices of a closed path, one per
:data:`CLOSED_ENTRY_SPACING_MM` of arc (the path is then rotated to start at its exact
nearest vertex).

The layer's paths are sorted once so that every color group, and every unit in it, is a
contiguous run; their points, ends and entries are gathered into layer-wide arrays
(points as complex numbers ``x + iy``, so a distance is one ``abs``). A group with few
loose paths finds each nearest entry with one numpy pass over the group's entries
(printed ones set to infinity); a large group buckets its entries in a uniform grid
(:class:`_EntryGrid`) with each entry's nearest neighbours precomputed from it. The tours
record each step as a path index and a turn (as it is, reversed, or rotated to a vertex)
and the plan is packed from those records in numpy (:class:`PackedSteps` columns, no
:class:`Path` per step; they are built only if someone asks for ``plan.steps``).
Coordinates are bed-frame mm.
"""

from __future__ import annotations

from bisect import bisect_left
from collections.abc import Sequence
from operator import attrgetter

import numpy as np

from fgslice.errors import SettingsError
from fgslice.planning.plan import PACKED, ROLES, STATE, LayerPlan, PackedSteps, pack_arrays, role_codes
from fgslice.toolpaths.paths import LayerPaths, Path, Role

WALL_ROLES = frozenset({Role.EXTERNAL_PERIMETER, Role.PERIMETER})
_IS_WALL_CODE = np.array([role in WALL_ROLES for role in ROLES])
"""Whether each role code is a wall's (indexed by code: a lookup instead of ``np.isin`` per layer)."""
FEATURE_ORDERS = ("walls_first", "infill_first")
SKIRT_COLOR = -1

#: Closed paths are entered at any vertex, but the search holds one vertex per this much
#: arc length (mm); the exact nearest vertex is chosen once the path is picked.
CLOSED_ENTRY_SPACING_MM = 1.0
#: Groups with at least this many loose paths are toured with a grid of their entries;
#: smaller ones by one numpy pass over the group's entries per path.
GRID_MIN_PATHS = 128
#: Grid tours: entries per grid cell, on average over the entries' bounding box.
ENTRIES_PER_CELL = 2
#: Grid tours: the grid has at most this many cells per entry (bounds its memory).
MAX_CELLS_PER_ENTRY = 16
#: Grid tours: neighbours precomputed per entry (at most; those within one cell size).
NEIGHBOURS = 6
#: Grid tours: an entry whose 3x3 cells hold more entries than this gets no precomputed
#: neighbours (bounds the work on dense clusters).
NEIGHBOUR_CANDIDATES = 256
#: Grid tours: below this many unprinted entries, nearest-entry queries are one numpy pass.
BRUTE_FORCE_ENTRIES = 4096

_FAR = complex(np.inf, np.inf)


def order_layer(
    paths: LayerPaths,
    color_sequence: np.ndarray,
    start_xy: np.ndarray,
    feature_order: str,
    fixed_seams: bool = False,
) -> LayerPlan:
    """The layer's paths as an ordered plan with one :class:`SetState` per color group.

    Args:
        paths: the layer's unordered paths (bed frame, mm).
        color_sequence: palette color indices in the order to print them on this layer;
            colors absent from the layer are skipped.
        start_xy: nozzle XY (mm) when the layer starts, e.g. the end of the previous layer.
        feature_order: ``"walls_first"`` or ``"infill_first"``.
        fixed_seams: enter every closed path at its first point (its seam, placed by
            :func:`fgslice.toolpaths.seams.place_seams`) instead of its vertex nearest
            the nozzle.

    Returns:
        A :class:`LayerPlan`: color ``-1`` paths first (no state set), then for each color
        ``SetState(c)`` followed by its paths, each group toured nearest-neighbour; held as
        :class:`PackedSteps` columns (:meth:`LayerPlan.from_packed`).

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
    items = paths.paths
    if not items:
        return plan
    n = len(items)
    sequence = np.asarray(color_sequence, dtype=np.int64).reshape(-1)
    roles, colors, widths, heights, unit = _path_columns(items)
    walls = _IS_WALL_CODE[roles]
    rank = np.full(max(int(colors.max()), int(sequence.max(initial=0))) + 2, -1, dtype=np.int64)
    rank[sequence[::-1]] = np.arange(sequence.size)[::-1]  # first occurrence wins
    stray = (colors != SKIRT_COLOR) & ((colors < 0) | (rank[np.maximum(colors, 0)] < 0))
    if stray.any():
        bad = np.unique(colors[stray]).tolist()
        raise ValueError(f"layer {paths.index}: path colors {bad} are not in the color sequence")

    feature_late = ~walls if feature_order == "walls_first" else walls
    group_key = np.where(colors == SKIRT_COLOR, -1, rank[colors] * 2 + feature_late)
    loose = unit < 0
    _, first_seen, inverse = np.unique(unit, return_index=True, return_inverse=True)
    unit_rank = first_seen[inverse]
    # Color groups in order; in each, its units (by first appearance, paths in list
    # order) and then its loose paths.
    order = np.lexsort((unit_rank, loose, group_key))
    keys, loose, unit_rank = group_key[order], loose[order], unit_rank[order]
    new_group = np.ones(n, dtype=bool)
    np.not_equal(keys[1:], keys[:-1], out=new_group[1:])
    group_start = np.flatnonzero(new_group)
    unit_paths = np.add.reduceat(~loose, group_start)
    new_unit = new_group.copy()
    new_unit[1:] |= unit_rank[1:] != unit_rank[:-1]
    layer = _Layer([items[i] for i in order.tolist()], loose, fixed_seams)
    chains = _Chains(layer, new_unit) if not loose.all() else None
    all_unit_starts = np.flatnonzero(new_unit & ~loose).tolist()

    x, y = (float(v) for v in np.asarray(start_xy, dtype=np.float64).reshape(2))
    steps = _Steps()
    current = None
    group_colors = colors[order[group_start]].tolist()
    group_stop = group_start.tolist()[1:] + [n]
    bounds = zip(group_start.tolist(), group_stop, unit_paths.tolist())
    for color, (a, c, units) in zip(group_colors, bounds):
        if color != SKIRT_COLOR and color != current:
            steps.state(color)
            current = color
        if units:
            unit_starts = all_unit_starts[bisect_left(all_unit_starts, a) : bisect_left(all_unit_starts, a + units)]
            x, y = _walk_units(layer, chains, unit_starts, a + units, x, y, steps)
        if a + units < c:
            x, y = _tour(layer, a + units, c, x, y, steps)
    columns = (roles[order], colors[order], widths[order], heights[order], layer.closed_mask, unit[order])
    return LayerPlan.from_packed(paths.index, paths.z, paths.height, layer.pack(steps, *columns))


def _path_columns(items: list[Path]) -> tuple[np.ndarray, ...]:
    """Role codes, colors, widths (mm), heights (mm) and groups of ``items``, one array each."""
    n = len(items)
    return (
        role_codes(map(attrgetter("role"), items)),
        np.fromiter(map(attrgetter("color"), items), dtype=np.int64, count=n),
        np.fromiter(map(attrgetter("width"), items), dtype=np.float64, count=n),
        np.fromiter(map(attrgetter("height"), items), dtype=np.float64, count=n),
        np.fromiter(map(attrgetter("group"), items), dtype=np.int64, count=n),
    )


class _Steps:
    """A plan as it is built: per step, ``path`` is a layer path index (-1 for a
    :class:`SetState`) and ``value`` how the path is turned (:data:`AS_IS`,
    :data:`REVERSED`, or ``k > 0``: closed, rotated to start at its vertex ``k``) or the
    SetState's color."""

    def __init__(self) -> None:
        self.path: list[int] = []
        self.value: list[int] = []

    def state(self, color: int) -> None:
        self.path.append(-1)
        self.value.append(color)


#: :class:`_Steps` turns of a path: printed as it is, or reversed (open paths).
AS_IS, REVERSED = 0, -1


class _Layer:
    """A layer's paths (already in group order) gathered into flat arrays.

    Attributes:
        paths: the paths.
        points: every path's points, concatenated, ``(P, 2)`` float (mm).
        xy: the same points as complex ``x + iy`` (mm).
        offsets: ``(n + 1,)`` path ``i`` owns ``xy[offsets[i]:offsets[i + 1]]`` (Python list).
        closed, closed_mask: each path's ``closed`` (Python list, numpy array).
        start, end: first and last point of each path (Python lists of complex, mm);
            ``start_xy``, ``end_xy`` the same as numpy arrays.
        entry_xy: entries of the loose paths (complex, mm), path by path, in point order.
        entry_path: path index of each entry.
        entry_reverses: True for the last point of an open path (entering there reverses it).
        entry_partner: the other entry of the same open path, -1 for a closed path's entries.
        entry_offsets: ``(n + 1,)`` path ``i`` owns entries ``entry_offsets[i]:entry_offsets[i + 1]``.
    """

    def __init__(self, paths: list[Path], loose: np.ndarray, fixed_seams: bool = False) -> None:
        n = len(paths)
        self.fixed_seams = fixed_seams
        self.paths = paths
        arrays = list(map(attrgetter("points"), paths))
        sizes = np.fromiter(map(len, arrays), dtype=np.int64, count=n)
        offsets = np.zeros(n + 1, dtype=np.int64)
        np.cumsum(sizes, out=offsets[1:])
        self.points = np.ascontiguousarray(np.concatenate(arrays), dtype=np.float64)
        xy = self.points.view(np.complex128).ravel()
        closed = np.fromiter(map(attrgetter("closed"), paths), dtype=bool, count=n)
        first, last = offsets[:-1], offsets[1:] - 1
        self.xy = xy
        self.offsets = offsets.tolist()
        self.closed_mask = closed
        self.closed = closed.tolist()
        self.start_xy, self.end_xy = xy[first], xy[last]
        self.start = self.start_xy.tolist()
        self.end = self.end_xy.tolist()

        keep = np.zeros(xy.size, dtype=bool)
        open_loose = loose & ~closed
        keep[first[open_loose]] = True
        keep[last[open_loose]] = True
        ring = np.flatnonzero(loose & closed)
        if fixed_seams:
            keep[first[ring]] = True
        elif ring.size:
            # Closed paths: keep a vertex each time the arc length enters a new bucket.
            ring_sizes = sizes[ring]
            ring_first = np.zeros(ring.size, dtype=np.int64)
            np.cumsum(ring_sizes[:-1], out=ring_first[1:])
            vertex = np.arange(int(ring_sizes.sum())) + np.repeat(first[ring] - ring_first, ring_sizes)
            steps = np.abs(np.diff(xy[vertex], prepend=xy[vertex[:1]]))
            steps[ring_first] = 0.0
            arc = np.cumsum(steps)
            arc -= np.repeat(arc[ring_first], ring_sizes)
            bucket = np.floor(arc / CLOSED_ENTRY_SPACING_MM)
            new_bucket = np.ones(bucket.size, dtype=bool)
            np.not_equal(bucket[1:], bucket[:-1], out=new_bucket[1:])
            new_bucket[ring_first] = True
            keep[vertex[new_bucket]] = True
        entry_vertex = np.flatnonzero(keep)
        entry_path = np.searchsorted(offsets, entry_vertex, side="right") - 1
        self.entry_xy = xy[entry_vertex]
        self.entry_path = entry_path
        self.entry_reverses = (entry_vertex == last[entry_path]) & ~closed[entry_path]
        # an open path's two entries are consecutive: each one's partner is the other
        entry_index = np.arange(entry_vertex.size)
        self.entry_partner = np.where(
            closed[entry_path], -1, np.where(self.entry_reverses, entry_index - 1, entry_index + 1)
        )
        self.entry_offsets = np.searchsorted(entry_path, np.arange(n + 1)).tolist()

    def enter_closed(self, i: int, at: complex) -> tuple[int, complex]:
        """The vertex of closed path ``i`` nearest ``at`` (its index on the path, the
        path's turn in :class:`_Steps`), and that vertex's position; its first vertex
        with fixed seams."""
        if self.fixed_seams:
            return 0, self.start[i]
        ring = self.xy[self.offsets[i] : self.offsets[i + 1]]
        vertex = int(np.abs(ring - at).argmin())
        return vertex, complex(ring[vertex])

    def pack(self, steps: _Steps, roles, colors, widths, heights, closed, groups) -> PackedSteps:
        """The recorded ``steps`` as columns: each path's points taken from
        :attr:`points` as it is, reversed or rotated, with its attributes (per layer path,
        in layer order) gathered."""
        index = np.asarray(steps.path, dtype=np.int64)
        value = np.asarray(steps.value, dtype=np.int64)
        is_path = index >= 0
        kind = np.where(is_path, PACKED, STATE)
        ref = np.where(is_path, np.cumsum(is_path) - 1, value)
        path, turn = index[is_path], value[is_path]
        offsets = np.asarray(self.offsets, dtype=np.int64)
        first, sizes = offsets[path], offsets[path + 1] - offsets[path]
        owner = np.repeat(np.arange(path.size), sizes)
        t = np.arange(int(sizes.sum())) - np.repeat(np.cumsum(sizes) - sizes, sizes)
        size, shift = sizes[owner], turn[owner]
        t = np.where(shift == REVERSED, size - 1 - t, np.where(shift > 0, (t + shift) % size, t))
        return pack_arrays(kind, ref, self.points[first[owner] + t], sizes, roles[path], colors[path], widths[path],
                           heights[path], closed[path], groups[path])

    def entry_distances(self, indices: np.ndarray, at: complex) -> np.ndarray:
        """Distance (mm) from ``at`` to the nearest entry of each path in ``indices`` (any
        vertex if closed, an end if open)."""
        start = np.array([self.start[i] for i in indices.tolist()])
        end = np.array([self.end[i] for i in indices.tolist()])
        dist = np.minimum(np.abs(start - at), np.abs(end - at))
        closed = np.array([self.closed[i] for i in indices.tolist()], dtype=bool)
        ring = indices[closed]
        if self.fixed_seams:
            dist[closed] = np.abs(start[closed] - at)
        elif ring.size:
            offsets = np.asarray(self.offsets)
            sizes = offsets[ring + 1] - offsets[ring]
            ring_first = np.zeros(ring.size, dtype=np.int64)
            np.cumsum(sizes[:-1], out=ring_first[1:])
            vertex = np.arange(int(sizes.sum())) + np.repeat(offsets[ring] - ring_first, sizes)
            dist[closed] = np.minimum.reduceat(np.abs(self.xy[vertex] - at), ring_first)
        return dist


def _walk_units(
    layer: _Layer, chains: _Chains, unit_starts: list[int], stop: int, x: float, y: float, out: _Steps
) -> tuple[float, float]:
    """Print the units starting at ``unit_starts`` (the last ends at ``stop``), nearest
    first unit first, each in its list order, every path rotated (closed) or reversed
    (open) to start nearest the nozzle. Appends to ``out``; returns the final XY (mm)."""
    at = complex(x, y)
    pending = list(zip(unit_starts, unit_starts[1:] + [stop]))
    while pending:
        pick = 0
        if len(pending) > 1:
            firsts = np.array([u[0] for u in pending])
            pick = int(layer.entry_distances(firsts, at).argmin())
        a, b = pending.pop(pick)
        at = chains.walk(a, b, at, out)
    return at.real, at.imag


class _Chains:
    """Orientation of a unit's paths, decided ahead for runs of open paths.

    Walking a unit, an open path is reversed when its last point is nearer the nozzle
    than its first, and the nozzle then stands at the end it finished. Inside a *chain*
    (a run of open paths of one unit) that decision depends only on whether the previous
    path was reversed, so it is computed for the whole layer at once: ``flips[0][i]`` /
    ``flips[1][i]`` say whether path ``i`` is reversed when its chain's first path is
    not / is. Only a chain's first path (after a unit start or a closed path) is decided
    against the actual nozzle position; closed paths are rotated one by one.
    """

    def __init__(self, layer: _Layer, new_unit: np.ndarray) -> None:
        self.layer = layer
        closed, start, end = layer.closed_mask, layer.start_xy, layer.end_xy
        head = new_unit | closed
        head[1:] |= closed[:-1]
        # Reverse path i when the previous one finished at its end (a) / at its start (b);
        # the first path is a chain head, decided at run time.
        rev_a = np.zeros(head.size, dtype=bool)
        rev_b = np.zeros(head.size, dtype=bool)
        np.less(np.abs(end[1:] - end[:-1]), np.abs(start[1:] - end[:-1]), out=rev_a[1:])
        np.less(np.abs(end[1:] - start[:-1]), np.abs(start[1:] - start[:-1]), out=rev_b[1:])
        index = np.arange(head.size)
        fixed_at = np.maximum.accumulate(np.where((rev_a == rev_b) & ~head, index, -1))
        negations = np.cumsum(rev_a & ~rev_b & ~head)
        chain_head = np.maximum.accumulate(np.where(head, index, 0))
        fixed = fixed_at >= chain_head
        anchor = np.where(fixed, fixed_at, chain_head)
        flip = (negations - negations[anchor]) % 2 == 1
        flip ^= np.where(fixed, rev_a[anchor], False)
        self.flips = (flip.tolist(), (flip ^ ~fixed).tolist())
        self.heads = np.flatnonzero(head).tolist()

    def walk(self, a: int, b: int, at: complex, out: _Steps) -> complex:
        """Append paths ``a..b-1`` (one unit) in order, oriented from the nozzle position
        ``at``; returns the final nozzle position."""
        layer = self.layer
        closed, start, end = layer.closed, layer.start, layer.end
        heads = self.heads[bisect_left(self.heads, a) : bisect_left(self.heads, b)]
        for c0, c1 in zip(heads, heads[1:] + [b]):
            if closed[c0]:
                vertex, at = layer.enter_closed(c0, at)
                out.path.append(c0)
                out.value.append(vertex)
                continue
            flips = self.flips[abs(end[c0] - at) < abs(start[c0] - at)][c0:c1]
            out.path.extend(range(c0, c1))
            out.value.extend([REVERSED if f else AS_IS for f in flips])
            at = start[c1 - 1] if flips[-1] else end[c1 - 1]
        return at


def _tour(layer: _Layer, a: int, b: int, x: float, y: float, out: _Steps) -> tuple[float, float]:
    """Greedy nearest-entry tour of the loose paths ``a..b-1``; appends the oriented paths
    to ``out`` and returns the final XY (mm).

    The walk records which entry each path is entered at and orients the paths
    afterwards. After an open path the nozzle stands on the path's other entry, whose
    precomputed neighbour list (:class:`_GridSearch`) usually holds the next entry (the
    first unprinted one in it); otherwise the search is asked (a live query)."""
    e0, e1 = layer.entry_offsets[a], layer.entry_offsets[b]
    search = (_GridSearch if b - a >= GRID_MIN_PATHS else _ScanSearch)(layer, e0, e1)
    entry_path = layer.entry_path[e0:e1]
    path_of = entry_path.tolist()
    partner_of = np.where(layer.entry_partner[e0:e1] >= 0, layer.entry_partner[e0:e1] - e0, -1).tolist()
    entry_offsets = layer.entry_offsets
    neighbours, neighbour_offsets = search.neighbours, search.neighbour_offsets
    printed = search.printed
    rotated: list[tuple[int, int]] = []
    chosen_entries: list[int] = []
    at = complex(x, y)
    at_entry = -1
    left = e1 - e0
    for step in range(b - a):
        chosen = -1
        if at_entry >= 0:
            for candidate in neighbours[neighbour_offsets[at_entry] : neighbour_offsets[at_entry + 1]]:
                if not printed[candidate]:
                    chosen = candidate
                    break
        if chosen < 0:
            if at_entry >= 0:
                at = complex(layer.entry_xy[e0 + at_entry])
            chosen = search.nearest(at, left)
        chosen_entries.append(chosen)
        at_entry = partner_of[chosen]
        if at_entry >= 0:
            printed[chosen] = printed[at_entry] = 1
            left -= 2
        else:
            i = path_of[chosen]
            lo, hi = entry_offsets[i] - e0, entry_offsets[i + 1] - e0
            printed[lo:hi] = b"\x01" * (hi - lo)
            left -= hi - lo
            vertex, at = layer.enter_closed(i, at)
            rotated.append((step, vertex))
    chosen = np.array(chosen_entries, dtype=np.int64)
    turns = np.where(layer.entry_reverses[e0:e1][chosen], REVERSED, AS_IS)
    for k, vertex in rotated:
        turns[k] = vertex
    out.path.extend(entry_path[chosen].tolist())
    out.value.extend(turns.tolist())
    if at_entry >= 0:
        at = complex(layer.entry_xy[e0 + at_entry])
    return at.real, at.imag


class _ScanSearch:
    """Nearest unprinted entry by one numpy pass over a group's entries.

    Attributes:
        printed: one flag byte per entry (set by the tour).
        neighbours, neighbour_offsets: empty neighbour lists (every query is live).
    """

    def __init__(self, layer: _Layer, e0: int, e1: int) -> None:
        self.xy = layer.entry_xy[e0:e1]
        self.printed = bytearray(self.xy.size)
        self.printed_mask = np.frombuffer(self.printed, dtype=bool)
        self.neighbours: list[int] = []
        self.neighbour_offsets = [0] * (self.xy.size + 1)

    def nearest(self, at: complex, alive: int) -> int:
        """Index (in the group) of the unprinted entry nearest ``at`` (``alive`` of them)."""
        distance = np.abs(self.xy - at)
        distance[self.printed_mask] = np.inf
        return int(distance.argmin())


class _GridSearch:
    """Nearest unprinted entry of a large group, from a uniform grid of its entries.

    Each entry's nearest neighbours within one grid cell size are precomputed in one
    vectorized pass (:func:`_neighbour_lists`): after an open path the nozzle stands on an
    entry, and the next entry is usually the first unprinted one in that short list (all
    entries nearer than it are in the list, so it is the nearest). Otherwise (after a
    closed path, or all those printed) a live query: one numpy pass when few entries are
    left, else the grid's cell blocks searched outward from the nozzle
    (:meth:`_EntryGrid.nearest`); the grid is rebuilt over the unprinted entries once it
    holds twice as many as are left.
    """

    def __init__(self, layer: _Layer, e0: int, e1: int) -> None:
        self.xy = layer.entry_xy[e0:e1]
        # One flag byte per entry, set by the tour per item and read here as a numpy view.
        self.printed = bytearray(self.xy.size)
        self.printed_mask = np.frombuffer(self.printed, dtype=bool)
        self.ids = np.arange(self.xy.size)
        self.grid = _EntryGrid(self.xy, self.ids)
        self.neighbours, self.neighbour_offsets = self.grid.neighbour_lists(NEIGHBOURS)

    def nearest(self, at: complex, alive: int) -> int:
        """Index (in the group) of the unprinted entry nearest ``at`` (``alive`` of them)."""
        if self.ids.size > 2 * alive:
            self.ids = self.ids[~self.printed_mask[self.ids]]
            if alive > BRUTE_FORCE_ENTRIES:
                self.grid = _EntryGrid(self.xy, self.ids)
        if alive <= BRUTE_FORCE_ENTRIES:
            ids = self.ids[~self.printed_mask[self.ids]]
            self.ids = ids
            return int(ids[np.abs(self.xy[ids] - at).argmin()])
        return self.grid.nearest(at, self.printed_mask)


class _EntryGrid:
    """Entries (complex ``x + iy``, mm) bucketed in square cells, with an empty border.

    The cell size gives about :data:`ENTRIES_PER_CELL` entries per occupied cell
    (:func:`_cell_size`). Entries are sorted by cell (row-major), so a row of adjacent cells
    is one contiguous run of ``ids``: ``ids[start[c]:start[c + 1]]`` are the entries of
    cell ``c``.
    """

    def __init__(self, xy: np.ndarray, ids: np.ndarray) -> None:
        pts = xy[ids]
        x, y = pts.real, pts.imag
        self.x0, self.y0 = float(x.min()), float(y.min())
        self.cell = _cell_size(x - self.x0, y - self.y0)
        self.nx = int((float(x.max()) - self.x0) / self.cell) + 1
        self.ny = int((float(y.max()) - self.y0) / self.cell) + 1
        self.stride = self.nx + 2
        column = np.minimum(((x - self.x0) / self.cell).astype(np.int64), self.nx - 1) + 1
        row = np.minimum(((y - self.y0) / self.cell).astype(np.int64), self.ny - 1) + 1
        self.cell_of = row * self.stride + column
        by_cell = np.argsort(self.cell_of, kind="stable")
        self.xy = xy
        self.ids = ids[by_cell]
        self.start = np.zeros(self.stride * (self.ny + 2) + 1, dtype=np.int64)
        np.cumsum(np.bincount(self.cell_of, minlength=self.start.size - 1), out=self.start[1:])

    def neighbour_lists(self, k: int) -> tuple[list[int], list[int]]:
        """Up to ``k`` nearest other entries of each entry among those its 3x3 cells are
        sure to hold, nearest first, as a flat list of entry indices and per-entry offsets
        into it (entry ``e``'s list is ``flat[offsets[e]:offsets[e + 1]]``). Those cells
        hold every entry within one cell size plus the entry's distance to its own cell's
        sides, so each list is the exact start of the entry's sorted neighbours. Entries whose 3x3 cells hold more than :data:`NEIGHBOUR_CANDIDATES`
        entries get an empty list (the live query serves them). Only for a grid of all the
        entries (``ids`` = ``0..n-1``)."""
        n = self.ids.size
        block = self.cell_of[:, None] + np.array([-self.stride - 1, -1, self.stride - 1])
        lo, hi = self.start[block], self.start[block + 3]
        lengths = hi - lo
        lengths[lengths.sum(axis=1) > NEIGHBOUR_CANDIDATES] = 0
        lengths, lo = lengths.ravel(), lo.ravel()
        run_start = np.cumsum(lengths) - lengths
        total = int(lengths.sum())
        query = np.repeat(np.arange(n).repeat(3), lengths)
        candidate = self.ids[np.arange(total) + np.repeat(lo - run_start, lengths)]
        distance = np.abs(self.xy[candidate] - self.xy[query])
        # The 3x3 cells hold every entry within one cell size plus the entry's distance
        # to its own cell's sides.
        u = (self.xy.real - self.x0) / self.cell - (self.cell_of % self.stride - 1)
        v = (self.xy.imag - self.y0) / self.cell - (self.cell_of // self.stride - 1)
        reach = self.cell * (1.0 + np.minimum(np.minimum(u, 1.0 - u), np.minimum(v, 1.0 - v)))
        keep = (distance <= reach[query]) & (candidate != query)
        query, candidate, distance = query[keep], candidate[keep], distance[keep]
        # Sort by entry, then distance: distance / (4 cell) is in [0, 0.375].
        by = np.argsort(query + distance / (4.0 * self.cell), kind="stable")
        query, candidate = query[by], candidate[by]
        first = np.searchsorted(query, np.arange(n + 1))
        rank = np.arange(query.size) - first[query]
        keep = rank < k
        offsets = np.searchsorted(query[keep], np.arange(n + 1))
        return candidate[keep].tolist(), offsets.tolist()

    def nearest(self, at: complex, printed: np.ndarray) -> int:
        """The unprinted entry nearest ``at``: blocks of cells around ``at``'s cell, twice
        as wide each time, until the nearest unprinted entry found is nearer than any
        entry outside the block can be."""
        column = int(np.floor((at.real - self.x0) / self.cell))
        row = int(np.floor((at.imag - self.y0) / self.cell))
        # Start with a block that reaches the grid.
        reach = max(1, -column, column - self.nx + 1, -row, row - self.ny + 1)
        while True:
            c0, c1 = max(column - reach, 0), min(column + reach, self.nx - 1)
            r0, r1 = max(row - reach, 0), min(row + reach, self.ny - 1)
            rows = (np.arange(r0, r1 + 1) + 1) * self.stride
            lo, hi = self.start[rows + c0 + 1], self.start[rows + c1 + 2]
            lengths = hi - lo
            run_start = np.cumsum(lengths) - lengths
            ids = self.ids[np.arange(int(lengths.sum())) + np.repeat(lo - run_start, lengths)]
            ids = ids[~printed[ids]]
            whole = c0 == 0 and r0 == 0 and c1 == self.nx - 1 and r1 == self.ny - 1
            if ids.size:
                distance = np.abs(self.xy[ids] - at)
                best = int(distance.argmin())
                # Distance from ``at`` to the block's sides that have cells beyond them.
                x, y = at.real - self.x0, at.imag - self.y0
                safe = min(
                    x - c0 * self.cell if c0 > 0 else np.inf,
                    (c1 + 1) * self.cell - x if c1 < self.nx - 1 else np.inf,
                    y - r0 * self.cell if r0 > 0 else np.inf,
                    (r1 + 1) * self.cell - y if r1 < self.ny - 1 else np.inf,
                )
                if whole or distance[best] <= safe:
                    return int(ids[best])
            reach *= 2


def _cell_size(x: np.ndarray, y: np.ndarray) -> float:
    """Grid cell size (mm) giving about :data:`ENTRIES_PER_CELL` points per occupied cell,
    for points ``x, y >= 0`` (mm) that may fill an area or lie along curves (infill ends on
    color boundaries).

    Starts from the size that would suit points spread evenly over their bounding box,
    then twice scales it by ``(target / occupancy) ** (1 / d)``, where ``d`` (1 for curves,
    2 for areas) is estimated from how occupancy changed with the previous step. Never
    smaller than gives :data:`MAX_CELLS_PER_ENTRY` cells per point over the box.
    """
    n = x.size
    width, height = float(x.max()), float(y.max())
    smallest = np.sqrt(width * height / (MAX_CELLS_PER_ENTRY * n))
    cell = max(np.sqrt(width * height * ENTRIES_PER_CELL / n), max(width, height) * ENTRIES_PER_CELL / n)
    if cell <= 0.0:
        return 1.0
    dimension = 2.0
    previous = None
    for _ in range(2):
        columns = int(width / cell) + 1
        occupied = np.unique((y / cell).astype(np.int64) * columns + (x / cell).astype(np.int64)).size
        occupancy = n / occupied
        if previous is not None and previous[0] != cell and previous[1] != occupancy:
            dimension = float(np.clip(np.log(previous[1] / occupancy) / np.log(previous[0] / cell), 1.0, 2.0))
        previous = (cell, occupancy)
        cell = max(cell * (ENTRIES_PER_CELL / occupancy) ** (1.0 / dimension), smallest)
    return cell


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
    position = np.asarray(start_xy, dtype=np.float64).reshape(2)
    if not paths:
        return [], position
    items = list(paths)
    out = _Steps()
    layer = _Layer(items, np.ones(len(items), dtype=bool))
    x, y = _tour(layer, 0, len(items), float(position[0]), float(position[1]), out)
    roles, colors, widths, heights, groups = _path_columns(items)
    steps, _ = layer.pack(out, roles, colors, widths, heights, layer.closed_mask, groups).build()
    return steps, np.array([x, y])
