"""What a slice will cost before it starts: slicing time, peak memory and G-code size.

:func:`estimate_resources` looks at the part at a few heights only (:data:`PROBES`
sections and a coarse grid of field samples in each, nothing else is sliced) and scales
to every layer; :func:`check_budget` refuses a job whose G-code would not fit on the
output's disk or whose memory would exceed what the machine has available, and warns
above :data:`WARN_SLICE_S`, :data:`WARN_GCODE_MB` or half the available memory. Each
message names the settings that help.

The model (mm; per probed layer, averaged, times the layer count; ``A`` the section's
area, ``P`` its outline's length and ``V`` its vertices (in strategy 2 with colors:
those of its color faces), ``s`` the bead spacing, ``k`` the colors a grid of field
samples finds in it):

* path length: ``A / s`` for a dense layer (strategy 2, strategy 1's
  ``top_layers + bottom_layers``), ``A / s`` at ``infill_density`` plus ``walls`` loops
  of ``P`` for the others;
* moves: concentric loops, the path length over the mean move length ``P / V`` (held
  within :data:`MOVE_MM`: a box's loops are four moves, a circle's are chords);
  rectilinear fill (strategy 1, ``fill_pattern = rectilinear``), two moves per line
  across the section (mean line ``A sqrt 2 / (W + D)``, ``W x D`` its bounding box);
  strategy 1 times ``1 +`` :data:`COLOR_MOVES` ``(k - 1)`` for the pieces the colors cut;
* G-code: :data:`BYTES_PER_MOVE` per move, plus :data:`BYTES_PER_LAYER`;
* slicing time: :data:`SECONDS_PER_MOVE` per move, :data:`SECONDS_PER_LAYER` per layer
  and :data:`SECONDS_PER_SAMPLE` per field sample of the color faces, over
  ``min(jobs, layers)`` workers, plus :data:`START_S`;
* memory: :data:`BASE_MB` for the command and again per worker, plus the moves and
  samples of the layers a worker holds at once (:data:`BYTES_PER_MOVE_HELD`,
  :data:`BYTES_PER_SAMPLE_HELD`).

Fitted to real slices (``benchmarks/bench_estimates.py`` prints the ratios): on boxes and
cylinders, strategies 1 and 2, 1 to 16 colors, the real G-code size was 1.1 to 1.6
times the estimate (:data:`GCODE_FACTOR` is the stated bound; 1.07 and 1.28 on 60 mm boxes
graded by a curved and a planar field) and the peak memory 0.9 to 1.5 times. The time
constants are fitted (least squares on relative error) to those six parts and the 500-layer
vase of ``examples/`` (93 s of CPU) on an idle 2-core machine: real time 0.9 to 1.1 times
the estimate there; a slower or busier machine takes proportionally longer.
"""

from __future__ import annotations

import math
import os
import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import shapely

from fgslice.design.base import Design
from fgslice.errors import ResourceError
from fgslice.guards import estimate as path_estimate
from fgslice.settings import Settings
from fgslice.slicing.states import make_palette
from fgslice.toolpaths.walls import bead_spacing

PROBES = 3
"""Heights the part is sectioned at: the middles of equal thirds of its height."""

GRID = 40
"""Field samples per side of the probe grid over the footprint."""

MOVE_MM = (0.5, 100.0)
"""The mean move length is held within these bounds, mm."""

COLOR_MOVES = 0.5
"""Strategy 1: extra moves per move and per color of a layer beyond the first (its
paths are cut into colors, each piece with its own travel and state change)."""

BYTES_PER_MOVE = 28.0
"""G-code bytes per move (a ``G1 X.. Y.. E..`` line)."""

BYTES_PER_LAYER = 400.0
"""G-code bytes per layer: its change, annotations, travels and state changes."""

SECONDS_PER_MOVE = 6.5e-6
"""Slicing time per move on one core: toolpaths, planning, writing and verifying."""

SECONDS_PER_LAYER = {1: 0.0125, 2: 0.0107}
"""Slicing time per layer on one core, by strategy (strategy 1 cuts its paths along the
field, plans the purge tower and looks at neighbouring layers)."""

SECONDS_PER_SAMPLE = 2e-7
"""Slicing time per field sample of a layer's color faces, one core."""

START_S = 1.1
"""Start-up: imports, the design, the thumbnails, the verifier's last block."""

BASE_MB = 70.0
"""Resident memory of the command (or of a worker) before any layer, MB."""

BYTES_PER_MOVE_HELD = 400.0
"""Memory per move of the layers a worker holds (points, paths, prepared text), bytes."""

BYTES_PER_SAMPLE_HELD = 120.0
"""Memory per field sample of a layer's faces (coordinates, fractions, contours), bytes."""

GCODE_FACTOR = 3.0
"""The stated accuracy of the G-code estimate: the real size was within this factor."""

WARN_SLICE_S = 600.0
"""Warn when the slice is estimated to take longer than this, s."""

WARN_GCODE_MB = 500.0
"""Warn when the G-code is estimated larger than this, MB."""


@dataclass(frozen=True)
class ResourceEstimate:
    """What slicing a part will need (see the module docstring for the model).

    Attributes:
        layers: layer count.
        moves: G-code moves of the print.
        slice_s: slicing wall time with the given workers, s.
        memory_mb: peak resident memory of the command and its workers together, MB.
        gcode_mb: size of the G-code file, MB (10^6 bytes).
        print_s: printing time at ``print_speed`` (no acceleration), s.
    """

    layers: int
    moves: float
    slice_s: float
    memory_mb: float
    gcode_mb: float
    print_s: float


@dataclass(frozen=True)
class _Probe:
    area: float  # mm^2
    length: float  # outline, mm
    extent: float  # width + depth of the section's bounding box, mm
    vertices: int
    colors: int


def _probes(design: Design, settings: Settings) -> list[_Probe]:
    """The part at :data:`PROBES` heights: section area, outline, vertices and the
    colors a :data:`GRID` x :data:`GRID` grid of field samples finds in it. In strategy 2
    with colors, the outline and vertices are those of the layer's color faces (traced
    and simplified as the slice does), whose concentric loops the moves follow."""
    from fgslice.slicing.plan_layers import place_design
    from fgslice.slicing.regions import slice_layer
    from fgslice.toolpaths.simplify import simplify_polygons
    from fgslice.toolpaths.strategy2 import simplify_tolerance

    (x0, y0, z0), (x1, y1, z1) = design.bounds()
    palette = make_palette(len(design.materials), settings.colors, settings.palette)
    faces_traced = settings.strategy == 2 and palette.size > 1
    offset = place_design(design, settings).offset if faces_traced else None
    gx, gy = np.meshgrid(np.linspace(x0, x1, GRID + 2)[1:-1], np.linspace(y0, y1, GRID + 2)[1:-1])
    gx, gy = gx.ravel(), gy.ravel()
    out = []
    for z in z0 + (z1 - z0) * (np.arange(PROBES) + 0.5) / PROBES:
        section = design.section(float(z))
        outline = section
        colors = 1
        if faces_traced and not section.is_empty:
            h = settings.layer_height
            regions = slice_layer(design, place_design(design, settings), palette, 0, float(z + offset[2] + h / 2),
                                  h, settings, section=section)
            outline = shapely.multipolygons(list(shapely.get_parts(
                simplify_polygons(np.asarray(regions.faces, dtype=object), simplify_tolerance(settings)))))
        elif palette.size > 1 and not section.is_empty:
            inside = shapely.contains_xy(section, gx, gy)
            if inside.any():
                fractions = design.fractions(gx[inside], gy[inside], np.full(int(inside.sum()), z))
                colors = len(np.unique(palette.color_of(fractions)))
        bx0, by0, bx1, by1 = section.bounds if not section.is_empty else (0.0, 0.0, 0.0, 0.0)
        out.append(_Probe(float(section.area), float(outline.length), bx1 - bx0 + by1 - by0,
                          int(shapely.get_num_coordinates(outline)), colors))
    return out


def estimate_resources(design: Design, settings: Settings, layers: int | None = None,
                       jobs: int = 1) -> ResourceEstimate:
    """The resources slicing ``design`` with ``settings`` on ``jobs`` workers will need.

    ``layers`` defaults to :func:`fgslice.slicing.plan_layers.layer_heights`'s count.
    """
    if layers is None:
        from fgslice.slicing.plan_layers import layer_heights

        layers = len(layer_heights(design, settings))
    s = bead_spacing(settings.bead_width, settings.layer_height)
    dense_mm = sparse_mm = dense_moves = sparse_moves = 0.0
    probes = _probes(design, settings)
    rectilinear = settings.strategy == 1 or settings.fill_pattern == "rectilinear"
    for p in probes:
        step = float(np.clip(p.length / max(p.vertices, 1), *MOVE_MM))
        # rectilinear fill: two moves (a line and its link) per line across the section
        line = float(np.clip(p.area * math.sqrt(2.0) / max(p.extent, 1e-9), *MOVE_MM)) / 2.0
        fill = line if rectilinear else step
        cut = 1.0 + COLOR_MOVES * (p.colors - 1)
        walls = settings.walls * p.length if settings.strategy == 1 else 0.0
        dense_mm += p.area / s + walls
        sparse_mm += p.area / s * settings.infill_density / 100.0 + walls
        dense_moves += (p.area / s / fill + walls / step) * cut
        sparse_moves += (p.area / s * settings.infill_density / 100.0 / fill + walls / step) * cut
    n = len(probes)
    dense_mm, sparse_mm, dense_moves, sparse_moves = (v / n for v in (dense_mm, sparse_mm, dense_moves, sparse_moves))
    solid = layers if settings.strategy == 2 else min(layers, settings.top_layers + settings.bottom_layers)
    moves = dense_moves * solid + sparse_moves * (layers - solid)
    path_mm = dense_mm * solid + sparse_mm * (layers - solid)
    samples = path_estimate(design, settings, layers).face_samples
    gcode_bytes = BYTES_PER_MOVE * moves + BYTES_PER_LAYER * layers + 20_000
    workers = max(1, min(jobs, layers))
    cpu = SECONDS_PER_MOVE * moves + SECONDS_PER_LAYER[settings.strategy] * layers + SECONDS_PER_SAMPLE * samples * layers
    held = max(1, math.ceil(layers / (32 * workers))) if workers > 1 else 1
    per_worker = held * (BYTES_PER_MOVE_HELD * max(dense_moves, sparse_moves) + BYTES_PER_SAMPLE_HELD * samples) / 1e6
    memory = BASE_MB * (1 + (workers if workers > 1 else 0)) + workers * per_worker
    return ResourceEstimate(layers, moves, START_S + cpu / workers, memory, gcode_bytes / 1e6,
                            path_mm / settings.print_speed)


def available_memory_mb() -> float | None:
    """Memory the machine can give a new job without swapping, MB (Linux's
    ``MemAvailable``; None where it cannot be read)."""
    try:
        with open("/proc/meminfo") as handle:
            for line in handle:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        return None
    return None


def free_disk_mb(output: str | os.PathLike) -> float | None:
    """Free space of the file system the output goes to, MB (None where unknown,
    e.g. a directory that does not exist yet: the output's own check names it)."""
    folder = Path(output).resolve().parent
    try:
        return shutil.disk_usage(folder).free / 1e6
    except OSError:
        return None


def _helps(settings: Settings, what: str) -> str:
    """The settings that lower ``what`` (gcode, memory or time), for a hint."""
    tips = []
    if settings.colors > 1:
        tips.append(f"fewer colors (--set colors=..., now {settings.colors})")
    tips.append(f"a thicker layer_height (now {settings.layer_height:g} mm) or bead_width "
                f"(now {settings.bead_width:g} mm)")
    if settings.strategy == 2:
        tips.append("strategy 1 (--strategy 1: sparse infill)")
    elif settings.infill_density > 20:
        tips.append(f"a lower infill_density (now {settings.infill_density:g} %)")
    if what == "memory":
        tips.append("fewer workers (--jobs 1)")
    if what == "time":
        tips.append("more workers (--jobs N)")
    return "; ".join(tips)


def _duration(seconds: float) -> str:
    """``12 s``, ``4.5 min``, ``2.1 h`` (two significant digits)."""
    for unit, size in (("h", 3600.0), ("min", 60.0)):
        if seconds >= size:
            return f"{float(f'{seconds / size:.2g}'):g} {unit}"
    return f"{float(f'{seconds:.2g}'):g} s"


def _megabytes(mb: float) -> str:
    """``0.098 MB``, ``587 MB``, ``3.1 GB`` (two or three significant digits)."""
    return f"{float(f'{mb / 1000:.2g}'):g} GB" if mb >= 1000 else f"{float(f'{mb:.3g}'):g} MB"


def format_estimate(est: ResourceEstimate) -> str:
    """One line: ``estimate (10 layers, scaled from 3 of them): slicing ~12 s, memory ~300 MB, G-code ~40 MB, print ~2.1 h``."""
    return (f"estimate ({est.layers} layers, scaled from {PROBES} of them): slicing ~{_duration(est.slice_s)}, "
            f"memory ~{_megabytes(est.memory_mb)}, G-code ~{_megabytes(est.gcode_mb)}, print ~{_duration(est.print_s)}")


def check_budget(est: ResourceEstimate, settings: Settings, output: str | os.PathLike | None = None,
                 *, memory_mb: float | None = None, disk_mb: float | None = None) -> list[str]:
    """Refuse a job that cannot fit, return warnings for one that is very large.

    Args:
        est: :func:`estimate_resources`'s estimate.
        settings: the job's settings (named in the hints).
        output: the G-code path; its directory's free space is the disk budget.
        memory_mb: the memory budget (default :func:`available_memory_mb`).
        disk_mb: the disk budget (default :func:`free_disk_mb` of ``output``).

    Raises:
        ResourceError: the G-code estimate exceeds the free disk space, or the memory
            estimate the available memory.
    """
    memory_mb = available_memory_mb() if memory_mb is None else memory_mb
    if disk_mb is None and output is not None:
        disk_mb = free_disk_mb(output)
    if disk_mb is not None and est.gcode_mb > disk_mb:
        raise ResourceError(
            f"the G-code would be about {est.gcode_mb:.3g} MB but only {disk_mb:.3g} MB are free where it goes"
            + (f" ({Path(output).resolve().parent})" if output is not None else ""),
            hint=f"write it to a disk with more space (-o), or slice with {_helps(settings, 'gcode')}",
        )
    if memory_mb is not None and est.memory_mb > memory_mb:
        raise ResourceError(
            f"slicing would need about {est.memory_mb:.3g} MB of memory but {memory_mb:.3g} MB are available",
            hint=f"slice with {_helps(settings, 'memory')}",
        )
    warnings = []
    if est.gcode_mb > WARN_GCODE_MB:
        warnings.append(f"the G-code is estimated at {est.gcode_mb:.3g} MB: a smaller file needs "
                        + _helps(settings, "gcode"))
    if memory_mb is not None and est.memory_mb > memory_mb / 2:
        warnings.append(f"slicing is estimated to need {est.memory_mb:.3g} MB of the {memory_mb:.3g} MB available: "
                        "less needs " + _helps(settings, "memory"))
    if est.slice_s > WARN_SLICE_S:
        warnings.append(f"slicing is estimated to take {est.slice_s / 60:.3g} min: faster needs "
                        + _helps(settings, "time"))
    return warnings
