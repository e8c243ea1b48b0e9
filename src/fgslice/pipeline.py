"""The slicing pipeline end to end: design + settings -> G-code file + statistics.

Stages (one module each; this file only wires them):

1. placement and layer heights (``slicing.plan_layers``), the palette
   (``slicing.palette``), the dialect (``machine.dialects``);
2. per layer, in parallel (``executor.map_ordered``): outline and color faces
   (``slicing.regions``), toolpaths (``toolpaths.strategy1`` / ``strategy2``), color and
   travel order (``planning.order``) and the G-code moves of every path
   (``machine.gcode.prepare_bodies``); strategy 1 first sections every layer so that each
   layer gets its neighbours' outlines for top and bottom skins;
3. serially, streaming: purge towers (``planning.purge``), look-ahead of state changes
   (``planning.lookahead``), the G-code writer (``machine.gcode``), which adds travels,
   retractions, annotations and state changes around the prepared moves (with workers,
   the header's thumbnails are rendered meanwhile by a process of their own);
4. the written file is verified (``machine.verify``) before it replaces the output; with
   worker processes, by one more process that reads the file while it is written.

Output is byte-identical whatever the number of workers: every per-layer result depends
only on the design, the settings and the layer index.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import importlib
import itertools
import os
import time
from datetime import datetime, timezone
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path as FilePath

import numpy as np
import shapely

from fgslice.coverage import check_coverage, mesh_warnings, part_volume
from fgslice.design.fingerprint import fingerprint
from fgslice.design.base import Design
from fgslice.design.machine_design import for_machine
from fgslice.design.lattice_widths import check_lattice_widths
from fgslice.design.support_bodies import split_support_bodies
from fgslice.errors import FgsliceError, SliceError
from fgslice.executor import Consumer, default_jobs, map_ordered
from fgslice.guards import check_resources
from fgslice.resources import check_budget, estimate_resources
from fgslice.interrupts import sigint_held
from fgslice.machine.state_dialect import dialect_for
from fgslice.machine.support_dialect import with_support_state
from fgslice.machine.gcode import GcodeWriter, build_number_tables, prepare_bodies
from fgslice.machine.grading import SegmentGrading, checked_attributes
from fgslice.machine.timing import TimeModel
from fgslice.machine.verify import FOLLOW_BLOCK_BYTES, follow_file, format_faults, verify_gcode, verify_gcode_blocks
from fgslice.output import atomic_output
from fgslice.planning.coasting import coasted_lengths
from fgslice.planning.lookahead import apply_lookahead, apply_time_lead
from fgslice.planning.order import order_layer
from fgslice.planning.plan import LayerPlan
from fgslice.planning.purge import PurgeStats, PurgeTower, insert_purges
from fgslice.planning.purge_size import PurgeSizer
from fgslice.planning.state_leads import apply_state_leads
from fgslice.planning.repeats import RepeatedLayers
from fgslice.preview.thumbnails import LayerOutlines
from fgslice.settings import Settings
from fgslice.slicing.field import BedField
from fgslice.slicing.layers import LayerRegions, Placement
from fgslice.slicing.palette import Palette
from fgslice.slicing.plan_layers import layer_heights, place_design
from fgslice.slicing.regions import polygonal, polygonal_each, slice_layer
from fgslice.slicing.states import StatePalette, field_for, make_palette, material_palette, state_levels
from fgslice.toolpaths import strategy1, strategy2
from fgslice.toolpaths.fuzzy_skin import FuzzySkin
from fgslice.toolpaths.paths import Path, Role
from fgslice.toolpaths.bridges import face_bridges
from fgslice.toolpaths.brim import brim_area, brim_paths
from fgslice.toolpaths.seams import place_seams
from fgslice.toolpaths.skirt import skirt_paths
from fgslice.toolpaths.support_state import SupportState, layer_sequence, pinned_changes, resolve_support_state
from fgslice.toolpaths.supports import SupportLayer, plan_supports, support_paths, support_volume
from fgslice.toolpaths.thin_features import dropped_warning
from fgslice.toolpaths.walls import simplify_outline


Thumbnails = Sequence[tuple[bytes, int, int]]
"""PNG thumbnails as ``(png bytes, width, height)``, pixels."""

COLOR_SAMPLE_MM = 2.0
"""Grid step of the field samples that bound how many colors a layer holds, mm."""


@dataclass
class SliceJob:
    """Everything a per-layer worker needs (read-only once built, but for ``repeats``).

    Attributes:
        layers: ``(layer index, top z, height)`` per layer, bed frame, mm.
        start_xy: where each layer's travel ordering starts, bed frame, mm.
        outlines: strategy 1 only: every layer's bed-frame outline, in layer order.
        sections: strategy 2, a design holding meshes: every layer's section (design
            frame), cut in batches once for the layers and the thumbnails.
        repeats: strategy 2: the layers this process has finished, for later layers whose
            regions repeat theirs (``planning.repeats``; the one part each process changes).
        grading: the design's fan, flow and speed attributes (``machine.grading``), if any.
        fuzzy: the design's fuzzy-skin attributes (``toolpaths.fuzzy_skin``), if any.
    """

    design: Design
    settings: Settings
    palette: Palette | StatePalette
    placement: Placement
    layers: list[tuple[int, float, float]]
    start_xy: np.ndarray
    outlines: list[shapely.Geometry] = field(default_factory=list)
    sections: list[shapely.Geometry] = field(default_factory=list)
    repeats: RepeatedLayers = field(default_factory=RepeatedLayers)
    grading: SegmentGrading | None = None
    fuzzy: FuzzySkin | None = None
    supports: list[SupportLayer] = field(default_factory=list)
    support_state: SupportState = field(default_factory=SupportState)


@dataclass
class LayerResult:
    """What one layer's worker returns.

    Attributes:
        short_pieces: strategy 1's count of pieces shorter than ``min_segment_mm`` (None for
            strategy 2 or a layer without cut pieces).
        uncovered_mm2: area narrower than a bead that no path covers, mm^2.
        reassigned_mm2: strategy 2's face area given to a neighbouring color, mm^2.
        thin_dropped_mm2: features narrower than ``min_feature_size`` left out, mm^2.
        colors: number of palette colors the layer's paths use.
        commanded: the toolpaths' attribute ranges (:attr:`LayerPaths.commanded`).
        outline_mm2: the area of the layer's outline, mm^2.
        part_mm3: the volume the layer's part paths deposit, mm^3 (:func:`part_volume`).
    """

    plan: LayerPlan
    short_pieces: strategy1.ShortPieces | None
    uncovered_mm2: float
    colors: int
    reassigned_mm2: float = 0.0
    thin_dropped_mm2: float = 0.0
    commanded: dict[str, tuple[float, float]] = field(default_factory=dict)
    support_mm3: float = 0.0
    outline_mm2: float = 0.0
    part_mm3: float = 0.0


@dataclass
class SliceResult:
    """A finished slice: where it went and its statistics.

    ``stats`` is JSON-ready: the G-code writer's keys (``docs/gcode.md``) plus the
    pipeline's (strategy, uncovered area, purge, placement, slicing time); volumes mm^3,
    areas mm^2, lengths mm, masses g, times s.
    """

    output: FilePath
    stats: dict


SECTION_BATCH = 16
"""Strategy 1 sections this many consecutive layers per task (:meth:`Design.sections`): a
mesh sections them in one vectorized pass. 3DBenchy, 240 layers, one process: 413 ms
of outlines one layer at a time, 238 ms in batches of 8 (236 ms in batches of 16). With
workers each batch is a pool task, and 8 of the vase's layers take 2-3 ms, about as much
as the task costs the pool: in batches of 16 its section pass took 151-175 ms instead of
175-240 ms (three runs each, ``--jobs 2``), and the palette's 10 layers are one batch,
sectioned without starting a pool. The first batch is timed in this process, and the
others go to the workers only when they would take longer than a pool saves
(``map_ordered(probe=True)``): the vase's take about 0.09 s in all."""


@contextlib.contextmanager
def _failures_of(job: SliceJob, indices: Sequence[int]) -> Iterator[None]:
    """Report an unexpected exception of the work on layers ``indices`` as a
    :class:`SliceError` naming them (fgslice's own errors pass as they are)."""
    try:
        yield
    except FgsliceError:
        raise
    except Exception as exc:
        first, last = job.layers[indices[0]], job.layers[indices[-1]]
        where = (f"layer {first[0]} (z = {first[1]:.3f} mm)" if len(indices) == 1 else
                 f"layers {first[0]}-{last[0]} (z = {first[1]:.3f}-{last[1]:.3f} mm)")
        raise SliceError(
            f"{where} could not be sliced: {type(exc).__name__}: {exc}",
            hint="a geometry operation failed there; a slightly different layer_height or bead_width often "
                 "avoids it (and the design is worth reporting as a bug in fgslice)",
        ) from exc


def _section_task(job: SliceJob, indices: Sequence[int]) -> list[shapely.Geometry]:
    """Strategy 1, pass 1: the bed-frame outlines of some layers, each simplified once for
    the walls and skins of its layer and its neighbours (:func:`simplify_outline`)."""
    ox, oy, oz = job.placement.offset
    with _failures_of(job, indices):
        sections = job.design.sections([job.layers[i][1] - job.layers[i][2] / 2 - oz for i in indices])
        shifted = shapely.transform(np.array(sections, dtype=object), lambda c: c + np.array([ox, oy]))
        return list(polygonal_each(simplify_outline(polygonal_each(shifted), job.settings.gcode_resolution)))


def _body_outlines(job: SliceJob, body) -> list[shapely.Geometry] | None:
    """Every layer's section of a support body (bed frame), or None without one."""
    if body is None:
        return None
    ox, oy, oz = job.placement.offset
    sections = body.sections([z_top - height / 2 - oz for _, z_top, height in job.layers])
    return list(shapely.transform(np.array(sections, dtype=object), lambda c: c + np.array([ox, oy])))


def _below_outline(job: SliceJob, index: int) -> shapely.Geometry | None:
    """Strategy 2: the bed-frame outline of the layer under layer ``index`` (None for the first)."""
    if index == 0:
        return None
    if job.outlines:
        return job.outlines[index - 1]
    ox, oy, oz = job.placement.offset
    _, z_top, height = job.layers[index - 1]
    section = job.sections[index - 1] if job.sections else job.design.section(z_top - height / 2 - oz)
    below = shapely.transform(section, lambda c: c + np.array([ox, oy]))
    # rings a hair apart in the design's frame (two bodies cut by one plane) can meet once
    # moved onto the bed, where coordinates are coarser: such an outline is repaired
    return below if shapely.is_valid(below) else polygonal(shapely.make_valid(below))


def _plane_task(job: SliceJob, indices: Sequence[int]) -> list[shapely.Geometry]:
    """Strategy 2, a design holding meshes: the sections of some layers (design frame)."""
    oz = job.placement.offset[2]
    with _failures_of(job, indices):
        return job.design.sections([job.layers[i][1] - job.layers[i][2] / 2 - oz for i in indices])


def _layer_task(job: SliceJob, index: int) -> LayerResult:
    """Regions, toolpaths and order of one layer, and its paths' G-code moves."""
    with _failures_of(job, [index]):
        return _layer_result(job, index)


def _layer_result(job: SliceJob, index: int) -> LayerResult:
    """:func:`_layer_task`'s work."""
    s = job.settings
    i, z_top, height = job.layers[index]
    # the first layer holds the skirt; fuzzy skins, random seams and supports differ from layer to layer
    repeats = (job.repeats if s.strategy == 2 and index > 0 and job.fuzzy is None
               and s.seam_position != "random" and not s.support else None)
    if s.strategy == 2:
        regions = slice_layer(job.design, job.placement, job.palette, i, z_top, height, s,
                              section=job.sections[index] if job.sections else None)
        bridges = face_bridges(regions.outline, _below_outline(job, index), s)
        if not bridges.is_empty:  # the repeated layers' plans hold no bridges
            repeats = None
        repeated = repeats.find(regions) if repeats is not None else None
        if repeated is not None:
            plan, result = repeated
            return dataclasses.replace(result, plan=plan)
        paths = strategy2.layer_paths(regions, s, bridges)
        short = None
    else:
        outline = job.outlines[index]
        regions = LayerRegions(index=i, z=z_top, height=height, outline=outline, faces=())
        below = job.outlines[max(0, index - s.bottom_layers) : index][::-1]
        above = job.outlines[index + 1 : index + 1 + s.top_layers]
        field_ = field_for(job.design, job.placement, job.palette, s)
        paths, short = strategy1.layer_paths(regions, below, above, field_, job.palette, s)
    if job.fuzzy is not None:
        paths.paths = job.fuzzy.apply(paths.paths, i, z_top - height / 2)
    part_mm3 = part_volume(paths.paths)
    support = support_paths(job.supports[index], s, job.support_state.color) if job.supports else []
    paths.paths += support
    if index == 0:
        footprint = regions.outline  # the brim goes around the part and the support standing on the bed
        if support:
            footprint = shapely.union_all([footprint, job.supports[0].body, job.supports[0].interface])
        paths.paths = skirt_paths(brim_area(footprint, s), s) + brim_paths(footprint, s) + paths.paths
    colors = len({p.color for p in paths.paths if p.color >= 0})
    paths.paths = place_seams(paths.paths, s.seam_position, i)
    sequence = layer_sequence(job.palette.order_for_layer(i), job.support_state, i)  # the support's own state too
    plan = order_layer(paths, sequence, job.start_xy, s.feature_order,
                       fixed_seams=s.seam_position != "nearest")
    prepare_bodies(plan, s, job.grading)
    result = LayerResult(plan=plan, short_pieces=short, uncovered_mm2=paths.uncovered_mm2, colors=colors,
                         reassigned_mm2=paths.reassigned_mm2, thin_dropped_mm2=paths.thin_dropped_mm2,
                         commanded=paths.commanded,
                         support_mm3=support_volume(support),
                         outline_mm2=float(regions.outline.area), part_mm3=part_mm3)
    if repeats is not None:
        repeats.keep(regions, plan, result)
    return result


def _part_footprint(job: SliceJob) -> shapely.Geometry:
    """The bed area the part and its skirt cover (bounding box of the part, grown by the skirt)."""
    (x0, y0, _), (x1, y1, _) = job.design.bounds()
    ox, oy, _ = job.placement.offset
    s = job.settings
    grow = s.skirt_distance + s.skirt_loops * s.bead_width if s.skirt_loops else 0.0
    grow += s.brim_width + s.bead_width if s.brim_width > 0 else 0.0
    grow += s.support_expansion + s.bead_width if s.support else 0.0  # support may reach past the part
    return shapely.box(x0 + ox, y0 + oy, x1 + ox, y1 + oy).buffer(grow, join_style="mitre")


def _max_colors_per_layer(job: SliceJob, jobs: int, scheduler: str | None) -> int:
    """An upper bound of the material colors a layer holds, hence of its purged state
    changes (sizes the purge tower).

    The bound cannot exceed the palette size, so the layer of largest outline area
    (likeliest to span the most colors) is tried first: when it reaches the palette size,
    the other layers need no sampling.
    """
    if not job.layers:
        return 1
    widest = int(np.argmax(shapely.area(job.outlines)))
    if _colors_in_outline(job, widest) >= material_palette(job.palette).size:
        return material_palette(job.palette).size
    return max(map_ordered(_colors_in_outline, job, range(len(job.layers)), jobs=jobs, scheduler=scheduler), default=1)


def _colors_in_outline(job: SliceJob, index: int) -> int:
    """Colors a layer's outline spans, from the field sampled on a :data:`COLOR_SAMPLE_MM`
    grid inside it and at its vertices.

    What the samples miss is bounded by ``delta``, twice the largest difference of a
    fraction between neighbouring samples (grid neighbours inside the outline, consecutive
    vertices), plus the zipper band (``zipper`` percent of the range: its teeth take the
    color across a boundary the field only approaches). Two materials: every bin that
    ``[min - delta, max + delta]`` of the first fraction meets. More materials: one color
    when no fraction varies (``delta = 0``, e.g. a part of one material), else the
    palette size. With temperature states only the material colors count: a change of
    temperature alone purges nothing (:meth:`PurgeSizer.length`).
    """
    outline = job.outlines[index]
    if outline.is_empty:
        return 0
    x0, y0, x1, y1 = outline.bounds
    xs, ys = np.meshgrid(np.arange(x0, x1 + COLOR_SAMPLE_MM, COLOR_SAMPLE_MM), np.arange(y0, y1 + COLOR_SAMPLE_MM, COLOR_SAMPLE_MM))
    inside = shapely.contains_xy(outline, xs, ys)
    vertices = shapely.get_coordinates(outline)
    z = job.layers[index][1] - job.layers[index][2] / 2
    f = BedField(job.design, job.placement).fractions(np.vstack([np.c_[xs[inside], ys[inside]], vertices]), z)
    grid = np.full(xs.shape + (f.shape[1],), np.nan)
    grid[inside] = f[: int(inside.sum())]
    steps = [np.diff(grid, axis=0).reshape(-1, f.shape[1]), np.diff(grid, axis=1).reshape(-1, f.shape[1]),
             np.diff(f[int(inside.sum()) :], axis=0)]
    delta = 2.0 * max(float(np.abs(d[np.isfinite(d)]).max(initial=0.0)) for d in steps) + job.settings.zipper / 100
    palette = material_palette(job.palette)
    if palette.n_materials != 2:
        return 1 if delta == 0.0 else palette.size
    first = np.clip([f[:, 0].min() - delta, f[:, 0].max() + delta], 0.0, 1.0)
    lo, hi = palette.color_of(np.c_[first, 1.0 - first])
    return int(abs(hi - lo) + 1)


def _speed_of(settings: Settings) -> Callable[[Path], float]:
    """Printing speed (mm/s) of a path by role, for time-based look-ahead."""

    def speed(path: Path) -> float:
        if path.role is Role.EXTERNAL_PERIMETER:
            return settings.outer_wall_speed
        if path.role is Role.INTERNAL_INFILL:
            return settings.infill_speed
        return settings.print_speed

    return speed


def slice_to_gcode(
    design: Design,
    settings: Settings,
    output: str | FilePath,
    *,
    jobs: int | None = None,
    scheduler: str | None = None,
    comments: dict[str, str] | None = None,
    thumbnails: Thumbnails | Callable[[LayerOutlines | None], Thumbnails] = (),
    progress: Callable[[int, int], None] | None = None,
    verify: bool = True,
    stamp: datetime | None = None,
) -> SliceResult:
    """Slice ``design`` with ``settings`` and write printer-ready G-code to ``output``.

    Args:
        design: the part (any :class:`~fgslice.design.base.Design`).
        settings: resolved settings (:func:`fgslice.settings.load_settings`).
        output: G-code path; written atomically (temporary file, verified, renamed).
        jobs: worker processes for per-layer stages (default: all cores).
        scheduler: a Dask scheduler address to run per-layer stages on instead.
        comments: extra ``; key = value`` header lines.
        thumbnails: PNG thumbnails ``(png, width, height)`` to embed, or a function that
            renders them from the slice's layer outlines (None: from the design itself, in
            strategy 2 for a design without meshes; :func:`_thumbnail_render`),
            e.g. ``lambda layers: render_thumbnails(design, settings, layers=layers)``:
            called once the outlines exist, with workers in a process of its own alongside
            the first layers (serial work the other cores would wait for), else here.
        progress: called as ``progress(done_layers, total_layers)``.
        verify: check the written file against the machine's limits before keeping it.
        stamp: the time stamp of the G-code's first line (UTC); None: :func:`build_time`.

    Returns:
        The output path and the statistics (see :class:`SliceResult`).

    Raises:
        FgsliceError: any refusal (settings, design, bed size, verification, output).
    """
    started = time.perf_counter()
    jobs = default_jobs() if jobs is None else max(1, jobs)
    design_fingerprint = fingerprint(design)  # of the design as given: simulate compares it
    bodies = split_support_bodies(design)
    design = for_machine(bodies.part, settings)
    attributes = checked_attributes(design, settings)
    levels = state_levels(attributes.ranges, attributes.cover, settings) if attributes is not None else None
    palette = make_palette(len(design.materials), settings.colors, settings.palette, levels)
    dialect = dialect_for(settings, palette, attributes is not None and "flow" in attributes.names)
    support_state = resolve_support_state(settings, palette)
    dialect = with_support_state(dialect, support_state)
    placement = place_design(design, settings)
    layers = layer_heights(design, settings)
    check_resources(design, settings, len(layers))
    check_lattice_widths(design, settings)
    budget = check_budget(estimate_resources(design, settings, len(layers), jobs), settings, output)
    bed_center = np.array([settings.bed_x / 2, settings.bed_y / 2])
    job = SliceJob(design, settings, palette, placement, layers, bed_center,
                   grading=SegmentGrading.of(attributes, placement.offset, settings),
                   fuzzy=FuzzySkin.of(attributes, placement.offset), support_state=support_state)
    if settings.strategy == 2:
        # one plane per layer task (strategy 1 sections batches of layers); a thumbnail
        # process forked later shares the tables too
        design.prepare_sections()
    _prepare_for_workers()

    with contextlib.ExitStack() as cleanup:
        tower = None
        sizer = PurgeSizer.for_palette(settings, palette).with_support(support_state)
        batches = [range(i, min(i + SECTION_BATCH, len(layers))) for i in range(0, len(layers), SECTION_BATCH)]
        if settings.strategy == 1 or settings.support:
            job.outlines = list(itertools.chain.from_iterable(
                map_ordered(_section_task, job, batches, jobs=jobs, scheduler=scheduler, probe=True)))
        elif getattr(design, "meshes", ()):
            job.sections = list(itertools.chain.from_iterable(
                map_ordered(_plane_task, job, batches, jobs=jobs, scheduler=scheduler, probe=True)))
        if settings.support:
            job.supports = plan_supports(job.outlines, settings, _body_outlines(job, bodies.enforcers),
                                         _body_outlines(job, bodies.blockers))
        if callable(thumbnails):
            render = _thumbnail_render(job, thumbnails)
            thumbnails = _start_thumbnails(render, cleanup) if jobs > 1 or scheduler else tuple(render())
        if settings.strategy == 1:
            own = support_state.own and any(not layer.empty for layer in job.supports)  # one change more a layer
            if settings.purge and (palette.size > 1 or own):
                changes = _max_colors_per_layer(job, jobs, scheduler) + own
                tower = PurgeTower.plan(_part_footprint(job), settings, max(changes, 1), len(layers), sizer)
                job.start_xy = np.array([(tower.x0 + tower.x1) / 2, (tower.y0 + tower.y1) / 2])

        short_records: list[strategy1.ShortPieces] = []
        uncovered = [0.0]
        supported = [0.0]  # support volume, mm^3
        covered = [0.0, 0.0, 0.0]  # the sections' volume and area, the part paths' volume
        reassigned = []  # (layer, mm^2) of the layers that gave slivers away
        thin_dropped = []  # (layer, mm^2) of the layers that left thin features out
        commanded: dict[str, list[float]] = {}  # the toolpaths' attribute ranges
        total = len(layers)

        def plans():
            for done, result in enumerate(map_ordered(_layer_task, job, range(total), jobs=jobs, scheduler=scheduler), 1):
                if result.short_pieces:
                    short_records.append(result.short_pieces)
                uncovered[0] += result.uncovered_mm2
                supported[0] += result.support_mm3
                covered[0] += result.outline_mm2 * job.layers[done - 1][2]
                covered[1] += result.outline_mm2
                covered[2] += result.part_mm3
                if result.reassigned_mm2 > 0:
                    reassigned.append((done - 1, result.reassigned_mm2))
                if result.thin_dropped_mm2 > 0:
                    thin_dropped.append((done - 1, result.thin_dropped_mm2))
                for name, (low, high) in result.commanded.items():
                    seen = commanded.setdefault(name, [low, high])
                    seen[0], seen[1] = min(seen[0], low), max(seen[1], high)
                if progress:
                    progress(done, total)
                yield result.plan

        purge_stats = PurgeStats()
        stream = insert_purges(plans(), tower, settings, palette, purge_stats, sizer) if tower else plans()
        if isinstance(palette, StatePalette) and settings.dialect != "toolchanger":
            stream = apply_state_leads(stream, palette, settings.lookahead_distance, settings.temperature_lead_s,
                                       _speed_of(settings))
        elif settings.dialect == "temperature" and settings.temperature_lead_s > 0:
            stream = apply_time_lead(stream, settings.temperature_lead_s, _speed_of(settings))
        elif settings.lookahead_distance > 0:
            stream = apply_lookahead(stream, settings.lookahead_distance,
                                     functools.partial(coasted_lengths, settings=settings) if settings.coast_mm else None,
                                     pinned_changes(support_state))

        header = {
            "placement_offset": ",".join(f"{v:.4f}" for v in placement.offset),
            "materials": ",".join(m.name for m in design.materials),
            "design_fingerprint": design_fingerprint,
            **({"temperature_levels": ",".join(f"{t:g}" for t in palette.levels)}
               if isinstance(palette, StatePalette) else {}),
            **(comments or {}),
        }
        # with workers, a process verifies the file while it is written; forked before the
        # output is opened, it holds none of its buffers
        follower = Consumer(_verify_written, settings) if verify and (jobs > 1 or scheduler) else None
        if follower:
            cleanup.enter_context(follower)
        with sigint_held():  # a Ctrl-C lands after the temporary file's cleanup is registered
            handle = cleanup.enter_context(atomic_output(output))
        cleanup.callback(stream.close)  # on an error, stop the workers here and now
        if follower:
            follower.send(handle.name)
        first = list(itertools.islice(stream, 1))  # the workers start before the header waits for thumbnails
        if callable(thumbnails):
            thumbnails = thumbnails()
        writer = GcodeWriter(
            handle, settings, palette, dialect, comments=header, thumbnails=thumbnails, materials=design.materials,
            now=stamp or build_time(), grading=job.grading, time_model=follower is None,
        )
        writer.write_header()
        told = 0  # the file size the verifier was last told
        for written, plan in enumerate(itertools.chain(first, stream), 1):
            writer.write_layer(plan)
            if follower:
                handle.flush()
                size = os.fstat(handle.fileno()).st_size
                # it reads what it is told: blocks of FOLLOW_BLOCK_BYTES, a quarter of that once
                # the rest is estimated shorter, so that its last block, after the writer's, is short
                untold, rest = size - told, size * (total - written) / written
                if untold >= FOLLOW_BLOCK_BYTES or (untold >= FOLLOW_BLOCK_BYTES / 4 and rest < FOLLOW_BLOCK_BYTES):
                    follower.send(size)
                    told = size
        writer.write_end()
        planned_s = None
        if follower:
            handle.flush()
            os.fsync(handle.fileno())  # what is left of the disk write overlaps the verifier's last block
            # the verifier reads up to the end G-code (the footer is comments), planning its moves
            faults, planned_s = follower.result()
        stats = writer.finish(planned_s)
        coverage = check_coverage(covered[0], covered[1], covered[2], uncovered[0], settings.strategy,
                                  settings.bead_width, total)
        handle.flush()
        if verify:
            if not follower:
                faults = verify_gcode(FilePath(handle.name), settings)
            if faults:
                raise SliceError(
                    "the G-code fails verification against the machine profile; nothing was written:\n"
                    + format_faults(faults),
                    hint="this is a bug in fgslice or a profile whose limits contradict its settings",
                )

    stats.setdefault("warnings", [])
    stats["warnings"] = list(stats["warnings"]) + strategy1.summarize_short_pieces(
        short_records, total, settings.min_segment_mm, palette.size
    ) + _sliver_warning(reassigned, total, settings) + dropped_warning(thin_dropped, total, settings) + coverage + budget
    if settings.strategy == 2:  # whose sectioning built the whole meshes' tables already
        stats["warnings"] += mesh_warnings(design)
    if settings.strategy == 2 and attributes is not None and "infill_density" in attributes.names:
        stats["warnings"].append("strategy 2 fills every face densely: the infill_density attribute is ignored")
    if isinstance(palette, StatePalette) and settings.dialect == "toolchanger" and settings.temperature_lead_s > 0:
        stats["warnings"].append("temperature_lead_s is not used on a toolchanger: each tool is set to its "
                                 "temperature when it is picked up (M104 T<n> before T<n>)")
    stats.update(
        {
            "layers": total,
            "colors": palette.size,
            "strategy": settings.strategy,
            "uncovered_mm2": round(uncovered[0], 3),
            "support_mm3": round(supported[0], 3),
            "reassigned_mm2": round(sum(area for _, area in reassigned), 3),
            "thin_dropped_mm2": round(sum(area for _, area in thin_dropped), 3),
            "purge_mm3": round(purge_stats.purge_mm3, 3) if tower else 0.0,
            "purge_g": round(purge_stats.purge_g, 4) if tower else 0.0,
            "purge_waste_share": round(purge_stats.waste_share, 4) if tower else 0.0,
            "tower_mm3": round(purge_stats.tower_mm3, 3) if tower else 0.0,
            "tower_g": round(purge_stats.tower_g, 4) if tower else 0.0,
            "purge_tolerance": round(sizer.tolerance, 6) if tower and sizer.model else None,
            "lookahead_mm": round(settings.lookahead_distance, 3),
            "placement_offset": list(placement.offset),
            "elapsed_s": round(time.perf_counter() - started, 3),
        }
    )
    if commanded:
        stats["attributes"] = {**stats.get("attributes", {}), **commanded}
    if isinstance(palette, StatePalette):
        stats["temperature_levels"] = palette.levels.tolist()
    stats["simulated_within_half_bin"] = (
        _simulated_share(output, design, placement, settings, palette) if tower and sizer.model else None
    )
    return SliceResult(output=FilePath(output), stats=stats)


def _simulated_share(output, design: Design, placement, settings: Settings, palette: Palette | StatePalette) -> float:
    """Share of the part the dead-volume model predicts within half a palette bin of the
    design, simulating the written G-code (:mod:`fgslice.analysis.simulate`)."""
    from fgslice.analysis.fidelity import predicted_within_half_bin
    from fgslice.analysis.simulate import simulate

    size = material_palette(palette).size
    result = simulate(FilePath(output), design, placement, settings, palette_size=size)
    return round(predicted_within_half_bin(result, result.palette_size or size), 6)


def _sliver_warning(reassigned: list[tuple[int, float]], layers: int, settings: Settings) -> list[str]:
    """One warning line for the face area strategy 2 gave to neighbouring colors (none if none)."""
    if not reassigned:
        return []
    total = sum(area for _, area in reassigned)
    worst, most = max(reassigned, key=lambda item: item[1])
    return [
        f"{total:.2f} mm^2 of color faces on {len(reassigned)} of {layers} layers were narrower than a bead "
        f"(bead_width = {settings.bead_width:g} mm) and were printed in a neighbouring color "
        f"(most on layer {worst}: {most:.2f} mm^2); fewer colors make the bands wider"
    ]


def _prepare_for_workers() -> None:
    """Build, before the worker processes fork, what each of them would otherwise build
    on its own: the G-code number tables, and ``numpy.ma``, which numpy 2's ``np.unique``
    imports on first use (about 30 ms per process)."""
    build_number_tables()
    importlib.import_module("numpy.ma")


def _thumbnail_render(job: SliceJob, thumbnails: Callable[[LayerOutlines | None], Thumbnails]) -> Callable[[], Thumbnails]:
    """``thumbnails`` bound to what it draws the part from: strategy 1's layer outlines;
    in strategy 2, a mesh design's sections, those the layers take (exact and batched
    for meshes, a fraction of the 3-D distances the design itself would need);
    else the design itself (None)."""
    if job.settings.strategy == 1:
        return functools.partial(thumbnails, _thumbnail_layers(job, job.outlines))
    if job.sections:
        ox, oy, _ = job.placement.offset
        shifted = shapely.transform(np.array(job.sections, dtype=object), lambda c: c + np.array([ox, oy]))
        return functools.partial(thumbnails, _thumbnail_layers(job, list(polygonal_each(shifted))))
    return functools.partial(thumbnails, None)


def _thumbnail_layers(job: SliceJob, outlines: Sequence[shapely.Geometry]) -> LayerOutlines:
    """The layer ``outlines`` of ``job`` (bed frame, one per layer) for the thumbnails."""
    _, tops, heights = np.asarray(job.layers, dtype=float).T
    return LayerOutlines(mid=tops - heights / 2, height=heights, outlines=outlines, offset=tuple(job.placement.offset))


def _start_thumbnails(render: Callable[[], Thumbnails], cleanup: contextlib.ExitStack) -> Callable[[], tuple]:
    """Run ``render`` in a forked process (closed by ``cleanup``); returns the function
    that waits for its thumbnails (and raises what rendering raised)."""
    return cleanup.enter_context(Consumer(_render_thumbnails, render)).result


def _render_thumbnails(messages: Iterator, render: Callable[[], Thumbnails]) -> tuple:
    """The thumbnail process: ``render()`` (``messages`` only ends the wait)."""
    return tuple(render())


def _verify_written(messages: Iterator, settings: Settings) -> tuple[list, float]:
    """Faults of the file being written, and the seconds its moves and dwells take
    (:class:`~fgslice.machine.timing.TimeModel`, planned from the same reading, so the
    writer does not read its text a second time): ``messages`` is its name, then its size
    after each flush (see :func:`fgslice.machine.verify.follow_file`)."""
    name = next(messages)
    model = TimeModel(settings)
    faults = verify_gcode_blocks(follow_file(name, messages), settings, name=name, also=model.read)
    return faults, model.finish()


def build_time() -> datetime | None:
    """The time stamp for the G-code's first line: ``SOURCE_DATE_EPOCH`` of this process's
    environment when set (for reproducible output), else None (the writer uses the
    current time)."""
    epoch = os.environ.get("SOURCE_DATE_EPOCH", "").strip()
    return datetime.fromtimestamp(int(epoch), tz=timezone.utc) if epoch.isdecimal() else None


