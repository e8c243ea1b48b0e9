"""Features narrower than a bead printed as one bead along their centre line.

Walls (strategy 1) and dense fills (strategy 2) run their outermost centre line half a
bead inside a region, so a part of the region narrower than a bead (``w``) gets no path:
a fin, a thin wall, a lattice strut's section, a band of one color between two others.
As PrusaSlicer's Arachne perimeter generator does, such a part is printed as a single
bead when it is at least ``min_feature_size`` wide, and dropped when narrower:

1. the *narrow pieces* of a region are the region minus its opening by ``w / 2`` (what
   the usual inset leaves out), computed only where the opening loses at least
   :data:`~fgslice.toolpaths.slivers.MIN_SLIVER_AREA` (a wide region gets nothing);
2. a piece's *cores* are its parts at least ``min_feature_size`` wide: the piece itself
   when its erosion by ``min_feature_size / 2`` is one polygon, the parts of its opening
   by that much when the erosion splits it. A piece without a core is dropped (counted
   as a dropped feature when it is at least :data:`MIN_DROPPED_AREA` and a bead long,
   not a corner's tip);
3. each core becomes a centre line: a core that fills most of its minimum rotated
   rectangle (a straight strip, a strut's elliptic section, a dot) gets the segment
   along the rectangle's long axis, ending half the rectangle's short side from its
   ends; any other core (a curved strip, a ring, a T) gets its medial axis, the edges
   of the Voronoi diagram of its densified boundary that lie inside it, with the spurs
   that run into corners pruned (a branch no longer than twice the clearance where it
   leaves the rest);
4. the bead's width makes it deposit the piece's volume (area x layer height) by the
   capsule model of :func:`~fgslice.toolpaths.paths.bead_area`, clamped to
   ``[min_bead_width, w]`` (a piece needing less than ``min_bead_width`` is over-filled,
   as PrusaSlicer does; a dot needing more than ``w`` gets a segment long enough).

Widths ``min_feature_size`` and ``min_bead_width`` are given as PrusaSlicer's are: mm, or
a percentage (``"25%"``) of ``nozzle_diameter``. Units mm, bed frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import networkx as nx
import numpy as np
import shapely
from scipy.spatial import QhullError, Voronoi

from fgslice.toolpaths.paths import Path, Role, bead_area
from fgslice.toolpaths.slivers import MIN_SLIVER_AREA
from fgslice.toolpaths.walls import offset

STRAIGHT_FILL = 0.7
"""A core filling at least this share of its minimum rotated rectangle is printed as one
segment along the rectangle's long axis (an ellipse fills pi / 4 of it)."""

MIN_DROPPED_AREA = MIN_SLIVER_AREA
"""Smallest piece (mm^2) narrower than ``min_feature_size`` reported as a dropped feature."""

SPUR_FACTOR = 2.0
"""A medial-axis branch ending free is pruned when no longer than this many times the
clearance (distance to the boundary) where it leaves the rest: a spur into a corner."""


@dataclass(frozen=True)
class ThinBeads:
    """Result of :func:`thin_beads`.

    Attributes:
        paths: the single beads, one or more per printed piece.
        printed_mm2: area of the narrow pieces these beads print, mm^2.
        dropped_mm2: area of the features narrower than ``min_feature_size``, left out, mm^2.
    """

    paths: list[Path]
    printed_mm2: float
    dropped_mm2: float


def feature_width(value: float | str, nozzle_diameter: float, name: str) -> float:
    """A width given as PrusaSlicer gives it (mm, or ``"N%"`` of the nozzle diameter), in mm.

    Raises:
        ValueError: neither a number nor a percentage, or not above 0.
    """
    text = str(value).strip()
    try:
        width = float(text[:-1]) / 100.0 * nozzle_diameter if text.endswith("%") else float(text)
    except ValueError:
        raise ValueError(f"{name} = {value!r} is neither a width in mm nor a percentage of nozzle_diameter "
                         "(e.g. 0.1 or '25%')") from None
    if not np.isfinite(width) or width <= 0:
        raise ValueError(f"{name} = {value!r} must be a width above 0 (mm, or a percentage of nozzle_diameter)")
    return width


def feature_limits(settings) -> tuple[float, float]:
    """``(min_feature_size, min_bead_width)`` of ``settings`` in mm, the bead width at most
    ``bead_width``."""
    nozzle = settings.nozzle_diameter
    smallest = feature_width(settings.min_feature_size, nozzle, "min_feature_size")
    return smallest, min(feature_width(settings.min_bead_width, nozzle, "min_bead_width"), settings.bead_width)


def thin_beads(regions, eroded, colors, settings, role: Role) -> ThinBeads:
    """Single beads along the parts of ``regions`` narrower than a bead (module docstring).

    Args:
        regions: polygonal geometries (array), bed frame.
        eroded: each region eroded by ``bead_width / 2`` (what the walls or fills start from).
        colors: the palette color of each region's beads (one value or one per region).
        settings: ``bead_width``, ``layer_height``, ``nozzle_diameter``, ``min_feature_size``,
            ``min_bead_width``, ``gcode_resolution``.
        role: the beads' role.
    """
    w, h = settings.bead_width, settings.layer_height
    regions = np.atleast_1d(np.asarray(regions, dtype=object))
    eroded = np.atleast_1d(np.asarray(eroded, dtype=object))
    colors = np.broadcast_to(np.asarray(colors, dtype=np.int64), regions.shape)
    if len(regions) == 0:
        return ThinBeads([], 0.0, 0.0)
    opened = offset(eroded, w / 2)
    lossy = np.flatnonzero(shapely.area(regions) - shapely.area(opened) >= MIN_SLIVER_AREA)
    if len(lossy) == 0:
        return ThinBeads([], 0.0, 0.0)
    pieces, of = shapely.get_parts(shapely.difference(regions[lossy], opened[lossy]), return_index=True)
    polygon = (shapely.get_type_id(pieces) == shapely.GeometryType.POLYGON) & (shapely.area(pieces) > 0)
    pieces, color = pieces[polygon], colors[lossy][of[polygon]]
    smallest, narrowest = feature_limits(settings)
    cores, core_of = _cores(pieces, smallest)
    printed = np.zeros(len(pieces), dtype=bool)
    printed[core_of] = True
    dropped = pieces[~printed]
    feature = (shapely.area(dropped) >= MIN_DROPPED_AREA) & (_rectangles(dropped)[2] >= w)
    # each core prints its share of its piece's area
    core_area = shapely.area(cores)
    share = core_area / np.bincount(core_of, core_area, minlength=len(pieces))[core_of]
    volume = share * shapely.area(pieces)[core_of] * h
    core_color = color[core_of]
    centre, direction, long, short = _rectangles(cores)
    straight = (core_area >= STRAIGHT_FILL * long * short) | (long <= 0)
    segments, widths = _long_axes(centre[straight], direction[straight], long[straight], short[straight],
                                  volume[straight], narrowest, w, h)
    paths = [Path(points, role, col, width, h)
             for points, width, col in zip(segments, widths, core_color[straight].tolist())]
    for k in np.flatnonzero(~straight).tolist():
        lines = _medial_axis(cores[k], smallest, settings.gcode_resolution)
        length = sum(line.length for line in lines)
        if length <= 0:
            segment, width = _long_axes(centre[k:k + 1], direction[k:k + 1], long[k:k + 1], short[k:k + 1],
                                           volume[k:k + 1], narrowest, w, h)
            paths.append(Path(segment[0], role, int(core_color[k]), width[0], h))
            continue
        width = float(_width_for(volume[k] / length, narrowest, w, h))
        for line in lines:
            points = shapely.get_coordinates(line)
            paths.append(Path(points[:-1] if line.is_ring else points, role, int(core_color[k]), width, h,
                              closed=line.is_ring))
    return ThinBeads(paths, float(shapely.area(pieces[printed]).sum()), float(shapely.area(dropped[feature]).sum()))


def _cores(pieces: np.ndarray, smallest: float) -> tuple[np.ndarray, np.ndarray]:
    """The parts of ``pieces`` at least ``smallest`` wide and the piece of each: a piece
    whose erosion by ``smallest / 2`` is one polygon is its own core (its bits narrower
    than ``smallest``, a sharp tip, go with it); one eroded into several is opened."""
    eroded = offset(pieces, -smallest / 2)
    count = np.where(shapely.is_empty(eroded), 0, shapely.get_num_geometries(eroded))
    whole = np.flatnonzero(count == 1)
    split = np.flatnonzero(count > 1)
    parts, part_of = shapely.get_parts(offset(eroded[split], smallest / 2), return_index=True)
    keep = (shapely.get_type_id(parts) == shapely.GeometryType.POLYGON) & (shapely.area(parts) > 0)
    cores = np.concatenate([pieces[whole], parts[keep]])
    return cores, np.concatenate([whole, split[part_of[keep]]])


def _rectangles(geoms: np.ndarray):
    """``(centre (N, 2), direction (N, 2), long (N,), short (N,))`` of each geometry's
    minimum rotated rectangle: its centre, the unit vector along its longer side, and its
    sides' lengths, mm (0 for a degenerate one)."""
    n = len(geoms)
    centre, direction, sides = np.zeros((n, 2)), np.tile([1.0, 0.0], (n, 1)), np.zeros((n, 2))
    if n == 0:
        return centre, direction, sides[:, 0], sides[:, 1]
    rectangles = shapely.minimum_rotated_rectangle(geoms)
    box = (shapely.get_type_id(rectangles) == shapely.GeometryType.POLYGON) & (shapely.get_num_coordinates(rectangles) == 5)
    coords = shapely.get_coordinates(rectangles[box]).reshape(-1, 5, 2)
    a, b = coords[:, 1] - coords[:, 0], coords[:, 2] - coords[:, 1]
    la, lb = np.hypot(*a.T), np.hypot(*b.T)
    along = np.where((la >= lb)[:, None], a, b)
    centre[box] = coords[:, :4].mean(axis=1)
    sides[box] = np.column_stack([np.maximum(la, lb), np.minimum(la, lb)])
    direction[box] = along / np.maximum(sides[box, :1], 1e-300)
    flat = ~box  # a segment or a point: its extent
    if flat.any():
        bounds = shapely.bounds(geoms[flat])
        centre[flat] = (bounds[:, :2] + bounds[:, 2:]) / 2
        span = bounds[:, 2:] - bounds[:, :2]
        sides[flat, 0] = np.hypot(*span.T)
        direction[flat] = np.where(sides[flat, :1] > 0, span / np.maximum(sides[flat, :1], 1e-300), [1.0, 0.0])
    return centre, direction, sides[:, 0], sides[:, 1]


def _width_for(section, narrowest: float, w: float, h: float):
    """The bead width (mm) of cross-section ``section`` (mm^2) by the capsule model,
    clamped to ``[narrowest, w]``."""
    return np.clip(np.asarray(section) / h + h * (1 - np.pi / 4), narrowest, w)


def _long_axes(centre, direction, long, short, volume, narrowest: float, w: float, h: float):
    """``(segments (N, 2, 2), widths)`` (widths a list, mm): one segment along the long axis of
    each minimum rotated rectangle, centred in it, ending half its short side from its
    ends, and its width; a segment shorter than the short side (a dot) too short to hold
    ``volume`` even a bead wide is lengthened to hold it (at most the rectangle's length)."""
    length = np.maximum(long - short, 0.0)
    width = np.where(length > 0, _width_for(volume / np.maximum(length, 1e-300), narrowest, w, h), w)
    section = bead_area(width, h)
    dot = (length < short) & (volume > section * length)
    length = np.where(dot, np.minimum(volume / section, np.maximum(long, 1e-3)), length)
    half = direction * (length / 2)[:, None]
    return np.stack([centre - half, centre + half], axis=1), width.tolist()


def _medial_axis(core, smallest: float, tolerance: float) -> list[shapely.LineString]:
    """The medial axis of polygon ``core`` as merged lines (module docstring, 3): Voronoi
    edges of its boundary densified to a third of its mean width, inside it and at least
    ``smallest / 4`` from its boundary, spurs pruned, simplified to ``tolerance``."""
    mean_width = 2 * core.area / max(core.length, 1e-12)
    boundary = core.boundary
    points = np.unique(shapely.get_coordinates(shapely.segmentize(boundary, max(mean_width / 3, 1e-3))), axis=0)
    try:
        diagram = Voronoi(points)
    except QhullError:  # too few points, or all on one line
        return []
    vertex = diagram.vertices
    ridges = np.array([r for r in diagram.ridge_vertices if min(r) >= 0], dtype=np.int64).reshape(-1, 2)
    clearance = shapely.distance(boundary, shapely.points(vertex))
    kept = shapely.contains_xy(core, vertex[:, 0], vertex[:, 1]) & (clearance >= smallest / 4)
    ridges = ridges[kept[ridges].all(axis=1) & (ridges[:, 0] != ridges[:, 1])]
    graph = nx.Graph()
    graph.add_nodes_from((int(n), {"clearance": float(clearance[n])}) for n in np.unique(ridges))
    lengths = np.hypot(*(vertex[ridges[:, 1]] - vertex[ridges[:, 0]]).T)
    graph.add_edges_from((int(p), int(q), {"length": float(d)}) for (p, q), d in zip(ridges, lengths))
    _prune_spurs(graph)
    if graph.number_of_edges() == 0:
        return []
    segments = shapely.linestrings(vertex[np.array(graph.edges, dtype=np.int64)])
    merged = shapely.line_merge(shapely.multilinestrings(segments))
    return [shapely.simplify(line, tolerance) for line in shapely.get_parts(merged)]


def _prune_spurs(graph: nx.Graph) -> None:
    """Remove, in rounds, the branches from a free end to a junction (a node of degree 3 or
    more) no longer than :data:`SPUR_FACTOR` times the junction's clearance; all of a
    round's spurs at once, so that the two spurs into the corners at a strip's end both go
    and the centre line ends where they met."""
    while True:
        doomed = []
        for leaf in [n for n, d in graph.degree() if d == 1]:
            branch, length, previous, node = [leaf], 0.0, None, leaf
            while True:
                nxt = next(m for m in graph.neighbors(node) if m != previous)
                length += graph.edges[node, nxt]["length"]
                if graph.degree(nxt) != 2 or nxt == leaf:
                    break
                branch.append(nxt)
                previous, node = node, nxt
            if graph.degree(nxt) >= 3 and length <= SPUR_FACTOR * graph.nodes[nxt]["clearance"]:
                doomed += branch
        if not doomed:
            return
        graph.remove_nodes_from(doomed)


def layer_thin_beads(out, regions, eroded, colors, settings, role: Role) -> list[Path]:
    """:func:`thin_beads` for one layer's ``LayerPaths`` ``out`` (its ``uncovered_mm2``
    already set): the area the beads print leaves ``uncovered_mm2``, the features dropped
    go to ``thin_dropped_mm2``. No beads when ``settings.thin_features`` is off."""
    if not settings.thin_features or out.uncovered_mm2 < MIN_SLIVER_AREA:
        return []
    thin = thin_beads(regions, eroded, colors, settings, role)
    out.uncovered_mm2 = max(0.0, out.uncovered_mm2 - thin.printed_mm2)
    out.thin_dropped_mm2 = thin.dropped_mm2
    return thin.paths


def dropped_warning(dropped: list[tuple[int, float]], layers: int, settings) -> list[str]:
    """One warning line for the features narrower than ``min_feature_size`` a slice left
    out, ``dropped`` holding ``(layer, mm^2)`` of each layer that left some (none if none)."""
    if not dropped:
        return []
    total = sum(area for _, area in dropped)
    smallest, _ = feature_limits(settings)
    return [f"{total:.2f} mm^2 of features on {len(dropped)} of {layers} layers (first on layer {dropped[0][0]}) are "
            f"narrower than min_feature_size = {settings.min_feature_size} ({smallest:g} mm) and are not printed; "
            "lower min_feature_size to print them as single beads"]
