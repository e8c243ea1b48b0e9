"""Purge towers (strategy 1): flush the old state out of the nozzle after every change.

After a state change the melt chamber still holds ``V_melt`` of the old mixture (a mixing
hotend), the previous tool's ooze (a toolchanger: one purge per tool change), or a nozzle
that has not reached its new temperature yet (the temperature dialect: ``M104`` does not
wait, so the purge is also the time the temperature gets to settle). Before printing a
color group whose :class:`SetState` changes the state, the nozzle lays ``L`` mm of bead
on a tower beside the part, with the capsule model of Appendix A::

    L = V_melt / (h (w - h) + pi h^2 / 4)

With ``purge_size = model`` each change purges what the dead-volume model says it needs
(:mod:`fgslice.planning.purge_size`).

The tower is a rectangle sized so the layer with the most changes fits: each change owns
``rows_per_change`` back-and-forth rows at spacing ``w`` inside a perimeter (``model``:
the purges of a layer follow one another along its rows, whatever their lengths). Every layer
prints the perimeter and a sparse fill over the rows no purge used (in the state the
layer starts in), so the tower never stands on air, from the bed up to the part's top.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from functools import cached_property
from operator import attrgetter

import msgspec
import numpy as np
import shapely

from fgslice.errors import SettingsError, SliceError
from fgslice.planning.plan import EXTRA, PACKED, STATE, LayerPlan, PackedSteps, SetState, Step, polyline_lengths
from fgslice.planning.purge_size import PurgeSizer, purge_length
from fgslice.settings import Settings
from fgslice.toolpaths.paths import Path, Role, bead_area

#: Filament density used for purge mass, g/cm^3 (PLA; TPU is about 1.2, LW-PLA unfoamed 1.2).
PLA_DENSITY_G_CM3 = 1.24
#: Gap kept between the tower and the part's footprint (skirt included), mm.
TOWER_CLEARANCE_MM = 3.0
#: Smallest tower side, mm, so a tall tower stays standing.
MIN_TOWER_SIDE_MM = 10.0
#: Spacing of the sparse fill lines printed where no purge happened on a layer, mm.
SPARSE_SPACING_MM = 2.0
#: Width/depth ratios tried for the tower, squarest first.
ASPECTS = (1.0, 2.0, 0.5, 4.0, 0.25)
#: Color of paths printed in "whatever state the printer is in".
CURRENT_STATE = -1
#: Tower paths :func:`insert_purges` keeps for reuse on later layers (the same slot, length,
#: color and height make the same path).
MADE_PATHS = 4096


@dataclass(frozen=True)
class PurgeTower:
    """A rectangular purge tower on the bed.

    Attributes:
        x0, y0, x1, y1: outer edges of the tower in the bed frame, mm.
        line_width: bead width of its lines, mm.
        purge_mm: purge length per change the tower is sized for at the nominal layer height, mm.
        rows_per_change: back-and-forth rows each change owns on a layer.
        rows: rows per layer (at least ``changes_per_layer * rows_per_change``).
        changes_per_layer: most changes a layer may hold.
        n_layers: layers the tower is printed on (the part's layers).
        consecutive: a layer's purges follow one another along its rows (``purge_size =
            model``) instead of each filling the rows of its own slot.
    """

    x0: float
    y0: float
    x1: float
    y1: float
    line_width: float
    purge_mm: float
    rows_per_change: int
    rows: int
    changes_per_layer: int
    n_layers: int
    consecutive: bool = False

    @classmethod
    def plan(
        cls, part_footprint: shapely.Geometry, settings: Settings, changes_per_layer: int, n_layers: int,
        sizer: PurgeSizer | None = None, *, explain: bool = True,
    ) -> "PurgeTower":
        """Size and place the tower clear of ``part_footprint`` (bed frame, skirt included).

        The position is ``(purge_tower_x, purge_tower_y)`` (the tower's center) when set,
        else the first free spot right of the part, left, behind, in front, then anywhere
        on the bed nearest the part; squarer shapes are tried first. ``sizer`` gives the
        length each change needs (default: the melt volume's, ``purge_size = full``);
        ``explain`` false leaves the search for settings that would fit out of the error.

        Raises:
            SettingsError: only one of purge_tower_x / purge_tower_y is set.
            SliceError: the chosen spot overlaps the part or leaves the bed, or no spot fits
                (with ``purge_size = model``: saying which tolerance or palette would fit).
        """
        w = settings.bead_width
        changes = max(1, int(changes_per_layer))
        length = sizer.tower_length(changes) if sizer else purge_length(settings.melt_volume_mm3, w, settings.layer_height)
        sizes = [_tower_size(length, changes, w, aspect) for aspect in ASPECTS]
        keepout = shapely.buffer(part_footprint, TOWER_CLEARANCE_MM)
        shapely.prepare(keepout)
        bed = (settings.bed_x, settings.bed_y)
        fixed = (settings.purge_tower_x, settings.purge_tower_y)
        if (fixed[0] is None) != (fixed[1] is None):
            raise SettingsError(
                "purge_tower_x and purge_tower_y must be set together",
                hint="--set purge_tower_x=<mm> --set purge_tower_y=<mm>, or both 'auto'",
            )
        for width, depth, rows_per_change, rows in sizes:
            if fixed[0] is not None:
                centers = np.array([fixed], dtype=np.float64)
            else:
                centers = _candidate_centers(keepout.bounds, width, depth, bed)
            ok = _fits(centers, width, depth, keepout, bed)
            if ok.any():
                cx, cy = (float(v) for v in centers[np.argmax(ok)])
                return cls(cx - width / 2, cy - depth / 2, cx + width / 2, cy + depth / 2, w, length,
                           rows_per_change, rows, changes, n_layers, bool(sizer and sizer.model))
        width, depth = sizes[0][:2]
        what = f"{width:.0f} x {depth:.0f} mm purge tower ({changes} changes per layer x {length:.0f} mm of purge)"
        if fixed[0] is not None:
            raise SliceError(
                f"a {what} centered at ({fixed[0]:g}, {fixed[1]:g}) overlaps the part or its skirt "
                f"(clearance {TOWER_CLEARANCE_MM:g} mm) or leaves the {bed[0]:g} x {bed[1]:g} mm bed",
                hint="move it (purge_tower_x/purge_tower_y), or --set purge_tower_x=auto --set purge_tower_y=auto",
            )
        hint = "--set purge=false, a smaller palette (--set colors=...), or a smaller melt_volume_mm3"
        if sizer and sizer.model and explain:
            hint = _fitting_alternatives(part_footprint, changes, n_layers, sizer) + "; or --set purge=false"
        raise SliceError(f"no room on the {bed[0]:g} x {bed[1]:g} mm bed for a {what} beside the part", hint=hint)

    @property
    def footprint(self) -> shapely.Polygon:
        """The tower's rectangle in the bed frame."""
        return shapely.box(self.x0, self.y0, self.x1, self.y1)

    @cached_property
    def _slots(self) -> tuple[np.ndarray, np.ndarray]:
        """The back-and-forth line of every change slot, computed once per tower: points
        ``(changes_per_layer, 2 * rows_per_change, 2)`` mm and the arc length at each
        point, same shape without the last axis, mm."""
        w, per = self.line_width, self.rows_per_change
        y = (self.y0 + w + w * np.arange(self.changes_per_layer * per)).reshape(-1, per)
        xa, xb = self.x0 + w, self.x1 - w
        x = np.tile([xa, xb, xb, xa], (per + 1) // 2)[: 2 * per]
        points = np.stack(np.broadcast_arrays(x, np.repeat(y, 2, axis=1)), axis=-1)
        seg = np.hypot(*np.moveaxis(np.diff(points, axis=1), -1, 0))
        arc = np.concatenate([np.zeros((len(points), 1)), np.cumsum(seg, axis=1)], axis=1)
        return points, arc

    @cached_property
    def _rows(self) -> tuple[np.ndarray, np.ndarray]:
        """All purge rows of a layer as one back-and-forth line (``consecutive``): points
        ``(2 * changes_per_layer * rows_per_change, 2)`` mm and the arc length at each."""
        w, n = self.line_width, self.changes_per_layer * self.rows_per_change
        y = self.y0 + w + w * np.arange(n)
        x = np.tile([self.x0 + w, self.x1 - w, self.x1 - w, self.x0 + w], (n + 1) // 2)[: 2 * n]
        points = np.column_stack([x, np.repeat(y, 2)])
        arc = np.r_[0.0, np.cumsum(np.hypot(*np.diff(points, axis=0).T))]
        return points, arc

    def rows_used(self, length: float) -> int:
        """Rows the first ``length`` mm of a layer's consecutive purges cover."""
        _, arc = self._rows
        return int(np.searchsorted(arc[1::2], length - 1e-9)) + 1 if length > 0 else 0

    def purge_path_at(self, start: float, length: float, color: int, height: float) -> Path:
        """``length`` mm of the layer's rows from arc length ``start`` (``consecutive``)."""
        points, arc = self._rows
        end = start + length
        if end > arc[-1] + 1e-6:
            raise SliceError(
                f"a layer's purges need {end:.0f} mm of line; the tower holds {arc[-1]:.0f} mm per layer",
                hint="a looser purge_tolerance, a smaller palette (--set colors=...), or --set purge_size=full",
            )
        inside = (arc > start + 1e-9) & (arc < end - 1e-9)
        ends = np.column_stack([np.interp([start, end], arc, points[:, 0]), np.interp([start, end], arc, points[:, 1])])
        return Path(np.vstack([ends[:1], points[inside], ends[1:]]), Role.WIPE_TOWER, color, self.line_width, height)

    def purge_path(self, slot: int, length: float, color: int, height: float) -> Path:
        """Back-and-forth lines of ``length`` mm over the rows of change ``slot`` on a layer
        (``0 <= slot < changes_per_layer``): the slot's line cut at that arc length."""
        points, arc = self._slots
        points, arc = points[slot], arc[slot]
        if length > arc[-1] + 1e-6:
            raise ValueError(f"purge of {length:.1f} mm exceeds the tower's {arc[-1]:.1f} mm per change")
        if length < arc[-1] - 1e-9:
            i = min(max(int(np.searchsorted(arc, length, side="right")) - 1, 0), len(arc) - 2)
            t = (length - arc[i]) / (arc[i + 1] - arc[i])
            cut = [points[i] + t * (points[i + 1] - points[i])] if t > 0 else []
            points = np.concatenate([points[: i + 1], cut]) if cut else points[: i + 1]
        return Path(points, Role.WIPE_TOWER, color, self.line_width, height)

    def base_paths(self, used_slots: int, color: int, height: float) -> list[Path]:
        """The tower's perimeter and a sparse fill over the rows the purges left empty."""
        w = self.line_width
        h2 = w / 2
        ring = np.array([[self.x0 + h2, self.y0 + h2], [self.x1 - h2, self.y0 + h2],
                         [self.x1 - h2, self.y1 - h2], [self.x0 + h2, self.y1 - h2]])
        paths = [Path(ring, Role.WIPE_TOWER, color, w, height, closed=True)]
        first_free = used_slots * self.rows_per_change
        if first_free >= self.rows:
            return paths
        ya, yb = self.y0 + w + w * first_free, self.y0 + w * self.rows
        xa, xb = self.x0 + w, self.x1 - w
        if yb - ya < w:
            paths.append(Path(np.array([[xa, ya], [xb, ya]]), Role.WIPE_TOWER, color, w, height))
            return paths
        x = np.linspace(xa, xb, max(2, int(np.ceil((xb - xa) / SPARSE_SPACING_MM)) + 1))
        y = np.tile([ya, yb, yb, ya], (x.size + 1) // 2)[: 2 * x.size]
        paths.append(Path(np.c_[np.repeat(x, 2), y], Role.WIPE_TOWER, color, w, height))
        return paths


@dataclass
class PurgeStats:
    """What the purges cost; filled while :func:`insert_purges` runs.

    Attributes:
        density_g_cm3: filament density used for masses, g/cm^3.
        changes: purged state changes.
        purge_mm3: volume of the purge lines, mm^3.
        tower_base_mm3: volume of the tower's perimeters and sparse fill, mm^3.
        extruded_mm3: everything the plans extrude, tower included, mm^3.
    """

    density_g_cm3: float = PLA_DENSITY_G_CM3
    changes: int = 0
    purge_mm3: float = 0.0
    tower_base_mm3: float = 0.0
    extruded_mm3: float = 0.0

    @property
    def purge_g(self) -> float:
        """Mass of the purge lines, g."""
        return self.purge_mm3 * self.density_g_cm3 / 1000.0

    @property
    def tower_mm3(self) -> float:
        """Volume of the whole tower (purges and base), mm^3."""
        return self.purge_mm3 + self.tower_base_mm3

    @property
    def tower_g(self) -> float:
        """Mass of the whole tower, g."""
        return self.tower_mm3 * self.density_g_cm3 / 1000.0

    @property
    def waste_share(self) -> float:
        """Share of all extruded filament that goes into the tower (0..1)."""
        return self.tower_mm3 / self.extruded_mm3 if self.extruded_mm3 > 0 else 0.0


def insert_purges(
    plans: Iterable[LayerPlan],
    tower: PurgeTower | None,
    settings: Settings,
    palette,
    stats: PurgeStats | None = None,
    sizer: PurgeSizer | None = None,
) -> Iterator[LayerPlan]:
    """Add the purge tower to each layer, serially and streaming.

    Tracks the commanded state across layers. On each layer: skirt paths stay first;
    before the layer's first :class:`SetState` the tower's perimeter and sparse fill are
    printed in the state the layer starts in; after every SetState that changes the
    state, a purge of the new color (role WIPE_TOWER) on the tower, as long as ``sizer``
    says. With ``settings.purge`` false or no tower the plans pass through unchanged.

    Args:
        plans: ordered layer plans (from :func:`fgslice.planning.order.order_layer`).
        tower: from :meth:`PurgeTower.plan`.
        settings: uses ``purge``, ``melt_volume_mm3``, ``bead_width``.
        palette: its ``centers`` ((N, k) fractions) size model purges.
        stats: filled with volumes as layers go by; read it once the iterator is exhausted.
        sizer: purge lengths; default :meth:`PurgeSizer.of` ``settings`` and ``palette``.

    Raises:
        ValueError: a layer holds more changes, or lies higher, than the tower was planned for.
        SliceError: a layer's model purges are longer than the tower holds.
    """
    stats = stats if stats is not None else PurgeStats()
    if not settings.purge or tower is None:
        for plan in plans:
            stats.extruded_mm3 += _plan_volume(plan)
            yield plan
        return
    sizer = sizer or PurgeSizer.of(settings, palette.centers)
    state: int | None = None
    made: dict[tuple, tuple[Path, float]] = {}  # tower paths and volumes by what makes them: layers repeat them
    for plan in plans:
        if plan.index >= tower.n_layers:
            raise ValueError(f"layer {plan.index} is above the {tower.n_layers} layers the tower was planned for")
        packed = plan.packed
        if packed is not None:
            marks = np.flatnonzero(packed.kind == STATE).tolist()
            colors = packed.ref[marks].tolist()
            n_steps = len(packed.kind)
        else:
            marks = [i for i, step in enumerate(plan.steps) if isinstance(step, SetState)]
            colors = [plan.steps[i].color for i in marks]
            n_steps = len(plan.steps)
        changes = _count_changes(colors, state)
        lengths = _purge_lengths(colors, state, sizer, plan)
        used_slots = changes
        if tower.consecutive:
            used_slots = math.ceil(tower.rows_used(sum(lengths)) / tower.rows_per_change)
        elif changes > tower.changes_per_layer:
            raise ValueError(
                f"layer {plan.index} has {changes} state changes; the tower was sized for {tower.changes_per_layer}"
            )
        if len(made) > MADE_PATHS:
            made.clear()
        base_key = ("base", used_slots, CURRENT_STATE if state is None else state, plan.height)
        if base_key not in made:
            paths = tower.base_paths(*base_key[1:])
            made[base_key] = (paths, float(_volumes(paths).sum()))
        base, base_volume = made[base_key]
        # the new order: ranges (a, b) of the plan's steps and lists of tower paths
        ends = marks + [n_steps]
        pieces: list[tuple[int, int] | list[Path]] = [(0, ends[0])]
        if not marks:
            pieces.append(base)
        purges: list[Path] = []
        purge_volumes: list[float] = []
        laid = 0.0  # mm of the layer's rows the consecutive purges have used
        for k, (i, color, length) in enumerate(zip(marks, colors, lengths)):
            if k == 0:
                pieces.append(base)
            pieces.append((i, i + 1))
            if color != state and length > 0:
                key = (laid if tower.consecutive else len(purges), length, color, plan.height)
                laid += length
                if key not in made:
                    path = tower.purge_path_at(*key) if tower.consecutive else tower.purge_path(*key)
                    made[key] = (path, float(_volumes([path])[0]))
                path, volume = made[key]
                purges.append(path)
                purge_volumes.append(volume)
                pieces.append([path])
            state = color
            pieces.append((i + 1, ends[k + 1]))
        purge_volume = float(np.sum(purge_volumes))
        stats.purge_mm3 += purge_volume
        stats.changes += len(purges)
        stats.tower_base_mm3 += base_volume
        stats.extruded_mm3 += purge_volume + base_volume + _plan_volume(plan)
        if packed is not None:
            yield LayerPlan.from_packed(plan.index, plan.z, plan.height, _packed_with(packed, pieces))
        else:
            steps: list[Step] = []
            for piece in pieces:
                steps.extend(plan.steps[piece[0] : piece[1]] if isinstance(piece, tuple) else piece)
            yield LayerPlan(index=plan.index, z=plan.z, height=plan.height, steps=steps, prepared=plan.prepared)


def _packed_with(packed: PackedSteps, pieces: list[tuple[int, int] | list[Path]]) -> PackedSteps:
    """``packed`` with its steps reordered as ``pieces``: ranges ``(a, b)`` of its steps and
    lists of new paths (added to its extras)."""
    extras = list(packed.extras)
    kinds, refs = [], []
    for piece in pieces:
        if isinstance(piece, tuple):
            kinds.append(packed.kind[piece[0] : piece[1]])
            refs.append(packed.ref[piece[0] : piece[1]])
        else:
            kinds.append(np.full(len(piece), EXTRA, dtype=np.int8))
            refs.append(np.arange(len(extras), len(extras) + len(piece), dtype=np.int32))
            extras.extend(piece)
    return packed.with_steps(np.concatenate(kinds), np.concatenate(refs), extras)


def _plan_volume(plan: LayerPlan) -> float:
    """Everything ``plan`` extrudes by the capsule model, mm^3 (from the packed lengths when
    the plan is packed)."""
    packed = plan.packed
    if packed is None:
        return float(_volumes(plan.paths).sum())
    ref = packed.ref[packed.kind == PACKED]
    area = bead_area(packed.widths[ref], packed.heights[ref])
    return float(np.dot(packed.lengths[ref], area)) + float(_volumes(packed.extras).sum())


def _purge_lengths(colors: list[int], state: int | None, sizer: PurgeSizer, plan: LayerPlan) -> list[float]:
    """Purge length after each of a layer's SetStates (their ``colors`` in order), starting
    from ``state``: 0 where the state does not change, mm."""
    lengths = []
    for color in colors:
        lengths.append(0.0 if color == state else sizer.length(state, color, plan.height, plan.index))
        state = color
    return lengths


def _count_changes(colors: list[int], state: int | None) -> int:
    """How many of the layer's SetStates (their ``colors`` in order) change the state,
    starting from ``state``."""
    return sum(a != b for a, b in zip([state] + colors[:-1], colors))


def _volumes(paths: list[Path]) -> np.ndarray:
    """Extruded volume of each path by the capsule model, mm^3, from one attribute pass."""
    if not paths:
        return np.zeros(0)
    arrays, closed, widths, heights = zip(*map(attrgetter("points", "closed", "width", "height"), paths))
    lengths = polyline_lengths(arrays, np.array(closed, dtype=bool))
    return lengths * bead_area(np.array(widths), np.array(heights))


def _fitting_alternatives(part_footprint: shapely.Geometry, changes: int, n_layers: int, sizer: PurgeSizer) -> str:
    """What would make a model-sized tower fit the bed: the tightest ``purge_tolerance``
    (bisected between the current one and the whole composition range) and the largest
    palette at the current tolerance rule (bisected; a layer then spans at most as many
    changes as colors)."""
    from fgslice.slicing.palette import Palette, palette_size

    settings = sizer.settings

    def fits(s: Settings, centers: np.ndarray, n_changes: int) -> bool:
        try:
            PurgeTower.plan(part_footprint, s, n_changes, n_layers, PurgeSizer.of(s, centers), explain=False)
        except SliceError:
            return False
        return True

    def tolerant(t: float) -> Settings:
        return msgspec.structs.replace(settings, purge_tolerance=t)

    found = []
    tol, top = sizer.tolerance, sizer.full_range
    if top > tol and fits(tolerant(top), sizer.centers, changes):
        low, high = tol, top
        for _ in range(40):
            mid = math.sqrt(low * high)
            low, high = (low, mid) if fits(tolerant(mid), sizer.centers, changes) else (mid, high)
        unit = 10.0 ** (math.floor(math.log10(high)) - 1)
        fitting = math.ceil(high / unit - 1e-9) * unit
        bin_ = sizer.bin_size * sizer.full_range
        found.append(f"--set purge_tolerance={fitting:.2g} fits ({fitting / bin_:.2g} of a palette bin; "
                     f"the current {tol:.3g} is {tol / bin_:.2g}, and fidelity falls as it grows)")
    k = sizer.centers.shape[1]
    sizes = sorted({palette_size(k, m) for m in range(1, len(sizer.centers) + 1)} & set(range(2, len(sizer.centers))))
    low, high = -1, len(sizes)  # sizes[low] fits (or none), sizes[high] does not
    while high - low > 1:
        mid = (low + high) // 2
        smaller = msgspec.structs.replace(settings, colors=sizes[mid])
        if fits(smaller, Palette(k, sizes[mid]).centers, min(changes, sizes[mid])):
            low = mid
        else:
            high = mid
    if low >= 0:
        rule = "a tenth of its bin" if settings.purge_tolerance == "auto" else f"{tol:.3g}"
        found.append(f"--set colors={sizes[low]} fits (tolerance {rule})")
    return " or ".join(found) if found else "no purge_tolerance or smaller palette fits"


def _tower_size(length: float, changes: int, w: float, aspect: float) -> tuple[float, float, int, int]:
    """(width, depth, rows per change, rows) of a tower with ``width / depth >= aspect``.

    Rows run along X at spacing ``w`` inside a one-bead perimeter; a change owns enough
    rows for ``length`` mm of back-and-forth line (row length plus ``w`` per turn).
    """
    run = max(math.sqrt(changes * length * w * aspect) - 2 * w, MIN_TOWER_SIDE_MM - 2 * w)
    while True:
        per_change = math.ceil((length + w) / (run + w))
        rows = max(changes * per_change, math.ceil(MIN_TOWER_SIDE_MM / w) - 1)
        width, depth = run + 2 * w, (rows + 1) * w
        if width >= aspect * depth:
            return width, depth, per_change, rows
        run += w


def _candidate_centers(bounds, width: float, depth: float, bed: tuple[float, float]) -> np.ndarray:
    """Tower centers to try: beside the keep-out box (right, left, behind, front), then a
    grid over the bed ordered by distance to the part."""
    minx, miny, maxx, maxy = bounds
    cx, cy = (minx + maxx) / 2, (miny + maxy) / 2
    gap = 1e-3  # touching the keep-out counts as overlapping
    sides = [(maxx + width / 2 + gap, cy), (minx - width / 2 - gap, cy),
             (cx, maxy + depth / 2 + gap), (cx, miny - depth / 2 - gap)]
    step = max(2.0, min(width, depth) / 4)
    gx, gy = np.meshgrid(np.arange(width / 2, bed[0] - width / 2 + 1e-9, step),
                         np.arange(depth / 2, bed[1] - depth / 2 + 1e-9, step))
    grid = np.c_[gx.ravel(), gy.ravel()]
    grid = grid[np.argsort(np.hypot(grid[:, 0] - cx, grid[:, 1] - cy), kind="stable")]
    return np.vstack([np.array(sides), grid])


def _fits(centers: np.ndarray, width: float, depth: float, keepout: shapely.Geometry, bed) -> np.ndarray:
    """Which candidate towers lie on the bed and clear of ``keepout``."""
    x0, y0 = centers[:, 0] - width / 2, centers[:, 1] - depth / 2
    x1, y1 = x0 + width, y0 + depth
    on_bed = (x0 >= 0) & (y0 >= 0) & (x1 <= bed[0]) & (y1 <= bed[1])
    ok = on_bed.copy()
    ok[on_bed] = ~shapely.intersects(shapely.box(x0[on_bed], y0[on_bed], x1[on_bed], y1[on_bed]), keepout)
    return ok
