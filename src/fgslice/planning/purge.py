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
up to the last one with a change prints the perimeter and a sparse fill over the rows no
purge used (in the state the layer starts in), so the tower never stands on air; above
it, and in a print without any change, there is no tower.
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
from fgslice.planning.plan import (
    EXTRA,
    PACKED,
    ROLE_CODE,
    STATE,
    LayerPlan,
    PackedSteps,
    SetState,
    Step,
    polyline_lengths,
)
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

    @cached_property
    def _serpentine(self) -> tuple[np.ndarray, np.ndarray]:
        """One back-and-forth line over all the tower's rows, computed once per tower:
        points ``(2 * rows, 2)`` mm (row ``r`` from point ``2 r`` to ``2 r + 1``) and the
        arc length at each point, mm."""
        w = self.line_width
        xa, xb = self.x0 + w, self.x1 - w
        x = np.tile([xa, xb, xb, xa], (self.rows + 1) // 2)[: 2 * self.rows]
        points = np.c_[x, np.repeat(self.y0 + w + w * np.arange(self.rows), 2)]
        return points, np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(points, axis=0).T))])

    def row_start(self, row: int) -> float:
        """Arc length along :attr:`_serpentine` where ``row`` begins, mm."""
        return float(self._serpentine[1][2 * row]) if row < self.rows else float(self._serpentine[1][-1])

    def rows_used(self, length: float) -> int:
        """Rows the first ``length`` mm of the serpentine cover (a row begun counts, and so
        does the row of a turn the line ends in)."""
        if length <= 0:
            return 0
        _, arc = self._serpentine
        return min(int(np.searchsorted(arc, length - 1e-9, side="right")) - 1, len(arc) - 2) // 2 + 1

    def purge_path_at(self, start: float, length: float, color: int, height: float) -> Path:
        """``length`` mm of the serpentine from arc length ``start`` on: purges laid one
        after another (``purge_size = model``, or purge into infill), rather than each in
        its change's slot."""
        points, arc = self._serpentine
        end = start + length
        if end > arc[-1] + 1e-6:
            raise SliceError(
                f"a layer's purges need {end:.0f} mm of line; the tower holds {arc[-1]:.0f} mm per layer",
                hint="a looser purge_tolerance, a smaller palette (--set colors=...), or --set purge_size=full",
            )
        inside = (arc > start + 1e-9) & (arc < end - 1e-9)
        ends = np.column_stack([np.interp([start, end], arc, points[:, 0]), np.interp([start, end], arc, points[:, 1])])
        return Path(np.vstack([ends[:1], points[inside], ends[1:]]), Role.WIPE_TOWER, color, self.line_width, height)

    def base_paths(self, used_slots: int, color: int, height: float) -> list[Path]:
        """The tower's perimeter and a sparse fill over the rows the purges left empty
        (those of the slots after the first ``used_slots``)."""
        return self.base_paths_from(used_slots * self.rows_per_change, color, height)

    def base_paths_from(self, first_free: int, color: int, height: float) -> list[Path]:
        """The tower's perimeter and a sparse fill over the rows from ``first_free`` on."""
        w = self.line_width
        h2 = w / 2
        ring = np.array([[self.x0 + h2, self.y0 + h2], [self.x1 - h2, self.y0 + h2],
                         [self.x1 - h2, self.y1 - h2], [self.x0 + h2, self.y1 - h2]])
        paths = [Path(ring, Role.WIPE_TOWER, color, w, height, closed=True)]
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
    """Add the purge tower to the layers that need it, serially and streaming.

    Tracks the commanded state across layers. On each layer: skirt paths stay first;
    before the layer's first :class:`SetState` the tower's perimeter and sparse fill are
    printed in the state the layer starts in; after every SetState that changes the
    state, a purge of the new color (role WIPE_TOWER) on the tower, as long as ``sizer``
    says. With
    ``settings.purge_into_infill`` the new color's sparse infill of that layer is printed
    first and its volume counts against the purge: the tower gets only what is left (plus
    :func:`_unsettled_mm3`, never more than the full purge), the color's walls and skins
    come after it.

    The tower ends at the last layer with a tower purge after a change from a known state
    (the first SetState of the print starts from an unknown state and does not count): a
    layer without one is held back until a later layer needs the tower (then it gets the
    tower's perimeter and fill, so the tower never stands on air) or the print ends (then
    it is printed without tower, and a print that never changes state has none at all).
    Only runs of layers without such a purge are held, so a print that changes state on
    every layer streams one layer at a time. With ``settings.purge`` false or no tower the
    plans pass through unchanged.

    Args:
        plans: ordered layer plans (from :func:`fgslice.planning.order.order_layer`).
        tower: from :meth:`PurgeTower.plan`.
        settings: uses ``purge``, ``melt_volume_mm3``, ``bead_width``, ``purge_into_infill``.
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
    sizer = sizer or PurgeSizer.for_palette(settings, palette)
    state: int | None = None
    made: dict[tuple, tuple[Path, float]] = {}  # tower paths and volumes by what makes them: layers repeat them
    since = 0.0
    held: list[_LayerPurges] = []
    for plan in plans:
        if plan.index >= tower.n_layers:
            raise ValueError(f"layer {plan.index} is above the {tower.n_layers} layers the tower was planned for")
        layer = _LayerPurges.of(plan, state, since, tower, settings, sizer)
        if not tower.consecutive and layer.changes > tower.changes_per_layer:
            raise ValueError(
                f"layer {plan.index} has {layer.changes} state changes; the tower was sized for {tower.changes_per_layer}"
            )
        state, since = layer.end_state, layer.since
        held.append(layer)
        if layer.needs_tower:
            for waiting in held:
                yield waiting.with_tower(tower, made, stats)
            held.clear()
    for waiting in held:
        yield waiting.without_tower(stats)


@dataclass(frozen=True)
class _LayerPurges:
    """A layer's plan with what its state changes purge (see :func:`insert_purges`).

    Attributes:
        plan: the layer's plan.
        start_state: the state the layer starts in (None: unknown, before the first change).
        end_state: the state it ends in.
        since: volume extruded since its last change, tower purge included and tower
            base left out (which only lengthens the run), mm^3 (purge into infill only;
            0 otherwise).
        changes: its SetStates that change the state.
        marks, colors: index and color of each of its SetStates.
        groups: per SetState, the steps that follow it up to the next one, in printing
            order, as ``(before, after)``: index arrays of the steps printed before the
            tower purge and after it.
        lengths: per SetState, the purge left for the tower, mm (0 where the state does
            not change or the infill took it all).
        needs_tower: a tower purge follows a change from a known state.
        packed_rows: the tower purges are laid one after another from the tower's first
            row, each from the start of a row (purge into infill: they are shorter than a
            change's slot, and the sparse fill takes every row after the last one, so no row
            stays empty), rather than each in its change's slot; with a ``consecutive``
            tower (``purge_size = model``) each goes on where the one before ended.
    """

    plan: LayerPlan
    start_state: int | None
    end_state: int | None
    since: float
    changes: int
    marks: list[int]
    colors: list[int]
    groups: list[tuple[np.ndarray, np.ndarray]]
    lengths: list[float]
    needs_tower: bool
    packed_rows: bool = False

    @classmethod
    def of(cls, plan: LayerPlan, state: int | None, since: float, tower: PurgeTower, settings: Settings,
           sizer: PurgeSizer) -> "_LayerPurges":
        """What ``plan``'s changes purge (as long as ``sizer`` says), starting in ``state``
        with ``since`` mm^3 extruded since the last change (purge into infill only)."""
        packed = plan.packed
        if packed is not None:
            marks = np.flatnonzero(packed.kind == STATE).tolist()
            colors = packed.ref[marks].tolist()
            n_steps = len(packed.kind)
        else:
            marks = [i for i, step in enumerate(plan.steps) if isinstance(step, SetState)]
            colors = [plan.steps[i].color for i in marks]
            n_steps = len(plan.steps)
        start, changes = state, _count_changes(colors, state, sizer)
        ends = marks + [n_steps]
        if settings.purge_into_infill:
            roles, volumes = _step_roles_and_volumes(plan, np.arange(n_steps))
            since += float(volumes[: ends[0]].sum())
        area = bead_area(tower.line_width, plan.height)
        groups, lengths, needs = [], [], False
        for k, (i, color) in enumerate(zip(marks, colors)):
            steps = np.arange(i + 1, ends[k + 1])
            if color == state:
                groups.append((steps[:0], steps))
                lengths.append(0.0)
                if settings.purge_into_infill:
                    since += float(volumes[steps].sum())
                continue
            length = sizer.length(state, color, plan.height, plan.index)
            if settings.purge_into_infill:
                infill = roles[steps] == ROLE_CODE[Role.INTERNAL_INFILL]
                poured = float(volumes[steps][infill].sum())
                left = min(max(0.0, length * area + _unsettled_mm3(since, settings) - poured) / area, length)
                groups.append((steps[infill], steps[~infill]))
                lengths.append(left)
                since = left * area + float(volumes[steps].sum())
            else:
                groups.append((steps[:0], steps))
                lengths.append(length)
            needs |= state is not None and lengths[-1] > 0
            state = color
        return cls(plan, start, state, since, changes, marks, colors, groups, lengths, needs,
                   settings.purge_into_infill or tower.consecutive)

    def with_tower(self, tower: PurgeTower, made: dict, stats: PurgeStats) -> LayerPlan:
        """The plan with the tower's perimeter and fill and the purges; ``made`` caches
        tower paths by what makes them, ``stats`` is added to."""
        plan, state = self.plan, self.start_state
        if len(made) > MADE_PATHS:
            made.clear()
        purges: list[list[Path]] = []
        purge_volume, row, laid = 0.0, 0, 0.0  # first free row; mm of serpentine the packed purges used
        for color, length in zip(self.colors, self.lengths):
            if length <= 0:
                purges.append([])
                continue
            if self.packed_rows:
                start = laid if tower.consecutive else tower.row_start(row)
                key = ("at", start, length, color, plan.height)
                if key not in made:
                    path = tower.purge_path_at(*key[1:])
                    made[key] = (path, float(_volumes([path])[0]))
                path, volume = made[key]
                laid = start + length
                row = tower.rows_used(laid)
            else:
                key = (sum(map(len, purges)), length, color, plan.height)
                if key not in made:
                    path = tower.purge_path(*key)
                    made[key] = (path, float(_volumes([path])[0]))
                path, volume = made[key]
            purges.append([path])
            purge_volume += volume
        if not self.packed_rows:
            row = sum(map(len, purges)) * tower.rows_per_change
        base_key = ("base", row, CURRENT_STATE if state is None else state, plan.height)
        if base_key not in made:
            paths = tower.base_paths_from(*base_key[1:])
            made[base_key] = (paths, float(_volumes(paths).sum()))
        base, base_volume = made[base_key]
        stats.purge_mm3 += purge_volume
        stats.changes += self.changes
        stats.tower_base_mm3 += base_volume
        stats.extruded_mm3 += purge_volume + base_volume + _plan_volume(plan)
        return self._plan_with(base, purges)

    def without_tower(self, stats: PurgeStats) -> LayerPlan:
        """The plan in the purge order but without the tower (``stats`` is added to)."""
        stats.extruded_mm3 += _plan_volume(self.plan)
        if not any(len(before) for before, _ in self.groups):
            return self.plan
        return self._plan_with([], [[] for _ in self.marks])

    def _plan_with(self, base: list[Path], purges: list[list[Path]]) -> LayerPlan:
        """The plan's steps with ``base`` before its first SetState (after the others
        when it has none) and each change's purge between its two step groups."""
        plan = self.plan
        first = self.marks[0] if self.marks else (len(plan.packed.kind) if plan.packed is not None else len(plan.steps))
        pieces: list[tuple[int, int] | np.ndarray | list[Path]] = [(0, first), base]
        for i, (before, after), purge in zip(self.marks, self.groups, purges):
            pieces += [(i, i + 1), before, purge, after]
        packed = plan.packed
        if packed is not None:
            return LayerPlan.from_packed(plan.index, plan.z, plan.height, _packed_with(packed, pieces))
        steps: list[Step] = []
        for piece in pieces:
            if isinstance(piece, tuple):
                steps.extend(plan.steps[piece[0] : piece[1]])
            elif isinstance(piece, np.ndarray):
                steps.extend(plan.steps[j] for j in piece.tolist())
            else:
                steps.extend(piece)
        return LayerPlan(index=plan.index, z=plan.z, height=plan.height, steps=steps, prepared=plan.prepared)


def _fitting_alternatives(part_footprint: shapely.Geometry, changes: int, n_layers: int, sizer: PurgeSizer) -> str:
    """What would make a model-sized tower fit the bed: the tightest ``purge_tolerance``
    (bisected between the current one and the whole composition range) and the largest
    palette at the current tolerance rule (bisected; a layer then spans at most as many
    changes as colors)."""
    from fgslice.slicing.palette import Palette, lattice_size, palette_size

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
    size_of = lattice_size if settings.palette == "ends" else palette_size
    sizes = sorted({size_of(k, m) for m in range(1, len(sizer.centers) + 1)} & set(range(2, len(sizer.centers))))
    low, high = -1, len(sizes)  # sizes[low] fits (or none), sizes[high] does not
    while high - low > 1:
        mid = (low + high) // 2
        smaller = msgspec.structs.replace(settings, colors=sizes[mid])
        if fits(smaller, Palette(k, sizes[mid], settings.palette).centers, min(changes, sizes[mid])):
            low = mid
        else:
            high = mid
    if low >= 0:
        rule = "a tenth of its bin" if settings.purge_tolerance == "auto" else f"{tol:.3g}"
        found.append(f"--set colors={sizes[low]} fits (tolerance {rule})")
    return " or ".join(found) if found else "no purge_tolerance or smaller palette fits"


def _unsettled_mm3(since: float, settings: Settings) -> float:
    """Extra purge (mm^3) after a change made ``since`` mm^3 after the previous one, when
    the sparse infill takes the purge.

    In the melt-chamber model (plug flow ``V_plug = (1 - s) V_melt``, then a well-mixed
    ``V_mix = s V_melt``, ``s`` = ``mixing_share``) the share of a change still unsettled
    after ``v`` mm^3 is ``rho = exp(-(v - V_plug) / V_mix)`` (1 before ``V_plug``). The
    infill taken in front of the tower shortens the previous color's run, so the old
    state still holds ``rho`` of the color before it; after ``V_melt + V_mix ln(1 + rho)``
    the first wall sees no more of older colors than after a full purge from a settled
    state (both changes in the same direction, the worst case). 0 without mixing.
    """
    v_mix = settings.mixing_share * settings.melt_volume_mm3
    if v_mix <= 0:
        return 0.0
    v_plug = settings.melt_volume_mm3 - v_mix
    rho = math.exp(-max(since - v_plug, 0.0) / v_mix)
    return v_mix * math.log1p(rho)


def _step_roles_and_volumes(plan: LayerPlan, steps: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Role code (:data:`~fgslice.planning.plan.ROLE_CODE`, -1 for a SetState) and extruded
    volume (mm^3) of the plan's ``steps``."""
    packed = plan.packed
    roles = np.full(len(steps), -1, dtype=np.int64)
    volumes = np.zeros(len(steps))
    if packed is not None:
        kind, ref = packed.kind[steps], packed.ref[steps]
        own = kind == PACKED
        rows = ref[own]
        roles[own] = packed.roles[rows]
        volumes[own] = packed.lengths[rows] * bead_area(packed.widths[rows], packed.heights[rows])
        extra = np.flatnonzero(kind == EXTRA)
        paths = [packed.extras[r] for r in ref[extra].tolist()]
    else:
        extra = np.array([j for j, s in enumerate(steps.tolist()) if isinstance(plan.steps[s], Path)], dtype=np.int64)
        paths = [plan.steps[s] for s in steps[extra].tolist()]
    if paths:
        roles[extra] = [ROLE_CODE[p.role] for p in paths]
        volumes[extra] = _volumes(paths)
    return roles, volumes


def _packed_with(packed: PackedSteps, pieces: list[tuple[int, int] | np.ndarray | list[Path]]) -> PackedSteps:
    """``packed`` with its steps reordered as ``pieces``: ranges ``(a, b)`` and index
    arrays of its steps, and lists of new paths (added to its extras)."""
    extras = list(packed.extras)
    kinds, refs = [], []
    for piece in pieces:
        if isinstance(piece, tuple):
            kinds.append(packed.kind[piece[0] : piece[1]])
            refs.append(packed.ref[piece[0] : piece[1]])
        elif isinstance(piece, np.ndarray):
            kinds.append(packed.kind[piece])
            refs.append(packed.ref[piece])
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


def _count_changes(colors: list[int], state: int | None, sizer: PurgeSizer) -> int:
    """How many of the layer's SetStates (their ``colors`` in order) change the material
    color (:meth:`PurgeSizer.material`), starting from ``state``: a change of temperature
    alone purges nothing."""
    materials = [sizer.material(c) for c in [state] + colors]
    return sum(a != b for a, b in zip(materials[:-1], materials[1:]))


def _volumes(paths: list[Path]) -> np.ndarray:
    """Extruded volume of each path by the capsule model, mm^3, from one attribute pass."""
    if not paths:
        return np.zeros(0)
    arrays, closed, widths, heights = zip(*map(attrgetter("points", "closed", "width", "height"), paths))
    lengths = polyline_lengths(arrays, np.array(closed, dtype=bool))
    return lengths * bead_area(np.array(widths), np.array(heights))


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
