"""Parts of color faces too narrow for a bead, given to a neighbouring color (strategy 2).

A face part narrower than a bead of width ``w`` (the face minus its opening by ``w / 2``)
gets no path when the face is filled: a steep gradient makes bands narrower than a bead
(a sigmoid grade), and a sharp ``thresh`` boundary sampled on a grid leaves thin bands
of the colors between its two sides. Such *slivers* are handed over before filling:

1. every face part is opened by ``w / 2`` (mitre joins, so corners stay); the part's
   *core* is what the opening keeps, its slivers are the rest (pieces smaller than
   :data:`MIN_SLIVER_AREA` are left alone: offset noise, corners a bead end fills);
2. in rounds, each sliver goes to a neighbouring color (one whose core, or a sliver
   placed there in an earlier round, shares more than a point of its boundary) that
   prints at least half of it once joined: the gain of a candidate is how much the
   area narrower than a bead within ``w`` of the sliver shrinks when the sliver joins
   it. Among the candidates within 1 % of the best gain, the one sharing the longest
   boundary wins: a ring between two wide faces goes to the one along its longer side,
   a stack of thin bands is eaten from both sides, and a spike no neighbour could
   print (a band's tip at the part surface) stays where it is;
3. slivers left over are grouped by contact; a group a bead fits in (a wall thinner
   than two beads cut into several thin bands) goes to the color with most of its area.

All in the bed frame, mm; faces are the exact faces of ``LayerRegions`` (before any
simplification), so neighbouring faces share their boundaries.
"""

from __future__ import annotations

import numpy as np
import shapely

from fgslice.slicing.regions import polygonal, polygonal_each
from fgslice.toolpaths.walls import opening

MIN_SLIVER_AREA = 1e-3
"""Smallest sliver (mm^2) handed over; smaller pieces of a face minus its opening are
offset noise or corners a bead's end covers (0.001 mm^2: 0.2 mm^3 over a thousand layers of 0.2 mm)."""

MERGE_GRID = 1e-6
"""Unions and clips of faces here are computed on this grid (mm), GEOS's fixed-precision
overlay: robust, and two pieces whose shared boundary was traced with different vertices
merge without the zero-area holes along it that a floating overlay leaves (an erosion
would widen them into gaps of a bead's width)."""

MIN_SLIVER_SHARE = 0.01
"""A layer whose faces lose at most this share of their area to their opening (and at
most :data:`MAX_KEPT_MM2`) keeps its slivers as they are: they are under 1 % of its volume (the 3DBenchy's band tips, about
1 mm^2 a layer; the palette object's, 0.5 mm^2 of 15,000), and handing them over costs
20-500 ms of overlays per layer."""

MAX_KEPT_MM2 = 2.0
"""A layer keeps its slivers only when they are also at most this area (mm^2): on a
large part, 1 % of a layer is hundreds of mm^2 (a 200 mm box graded by a curved field
kept 28 mm^2 of band tips along its surface on each layer, unprinted)."""

CONTACT_TOLERANCE = 1e-3
"""Two pieces closer than this (mm) touch; their shared boundary is measured within it."""


def give_slivers(faces, width: float) -> tuple[tuple[shapely.Geometry, ...], float]:
    """``faces`` (one MultiPolygon per color) with their slivers handed to a neighbour.

    Args:
        faces: the color faces of one layer, disjoint, bed frame.
        width: bead width ``w``, mm.

    Returns:
        ``(faces, reassigned_mm2)``: the new faces (a face that neither gave nor received
        anything is the same object as before) and the area that changed color, mm^2.
    """
    faces = np.asarray(faces, dtype=object)
    if np.count_nonzero(~shapely.is_empty(faces)) < 2:  # no neighbouring color to give to
        return tuple(faces), 0.0
    parts, owner = shapely.get_parts(faces, return_index=True)
    polygon = shapely.get_type_id(parts) == shapely.GeometryType.POLYGON
    parts, owner = parts[polygon], owner[polygon]
    opened = opening(parts, width / 2)
    lost = shapely.area(parts) - shapely.area(opened)  # at least the slivers' area: a cheap bound first
    if lost.sum() <= min(MIN_SLIVER_SHARE * shapely.area(parts).sum(), MAX_KEPT_MM2):
        return tuple(faces), 0.0
    thin = np.flatnonzero(lost >= MIN_SLIVER_AREA)
    rest, rest_of = shapely.get_parts(shapely.difference(parts[thin], opened[thin]), return_index=True)
    rest_of = thin[rest_of]
    big = (shapely.get_type_id(rest) == shapely.GeometryType.POLYGON) & (shapely.area(rest) >= MIN_SLIVER_AREA)
    if not big.any():
        return tuple(faces), 0.0
    slivers, own = rest[big], owner[rest_of[big]]
    cut = np.array([shapely.MultiPolygon() for _ in parts], dtype=object)
    shapely.multipolygons(slivers, indices=rest_of[big], out=cut)
    cores, core_of = _valid_polygons(shapely.difference(parts, cut))
    # on the grid of the overlays below, so that they are exact there
    slivers, cores = shapely.set_precision(slivers, MERGE_GRID), shapely.set_precision(cores, MERGE_GRID)
    core_color = owner[core_of]
    color = _by_contact(slivers, own, cores, core_color, len(faces), width)
    lone = color < 0
    if lone.any():
        color[lone] = _by_group(slivers[lone], own[lone], len(faces), width)
    moved = color != own
    out = faces.copy()
    for c in np.unique(np.concatenate([own[moved], color[moved]])):
        pieces = np.concatenate([cores[core_color == c], slivers[color == c]])
        out[c] = polygonal(shapely.union_all(pieces, grid_size=MERGE_GRID))
    return tuple(out), float(shapely.area(slivers[moved]).sum())


def _by_contact(slivers, own, cores, core_color, n_colors: int, width: float) -> np.ndarray:
    """The color each sliver joins, -1 where no neighbour prints most of it.

    In rounds, the candidates of a sliver are the colors of the cores and of the slivers
    placed in earlier rounds that share more than a point of its boundary (after the
    first round only the slivers touching one placed in the last round are looked at
    again: the others' candidates have not changed). A candidate's
    gain is how much the uncovered area within ``w`` of the sliver shrinks when the
    sliver joins it (:func:`_uncovered_near`); candidates printing at least half of the
    sliver qualify, and among those within 1 % of the best gain the one sharing the
    longest boundary wins (then the lowest color).
    """
    color = np.full(len(slivers), -1, dtype=np.int64)
    area = shapely.area(slivers)
    grown = shapely.buffer(slivers, CONTACT_TOLERANCE)
    inner, window = shapely.buffer(slivers, width), shapely.set_precision(shapely.buffer(slivers, 2 * width), MERGE_GRID)
    receivers, receiver_color = cores, core_color
    pending = check = np.arange(len(slivers))
    while len(check):
        tree = shapely.STRtree(receivers)
        i, j = tree.query(slivers[check], predicate="dwithin", distance=CONTACT_TOLERANCE)
        shared = shapely.length(shapely.intersection(shapely.boundary(receivers[j]), grown[check[i]]))
        cand, shared = _sums(check[i] * n_colors + receiver_color[j], shared)
        cand, shared = cand[shared > 4 * CONTACT_TOLERANCE], shared[shared > 4 * CONTACT_TOLERANCE]  # more than a corner
        sliver, candidate = cand // n_colors, cand % n_colors
        # the candidate colors' receivers near each sliver, merged
        wi, wj = tree.query(window[sliver], predicate="intersects")
        same = receiver_color[wj] == candidate[wi]
        wi, wj = wi[same], wj[same]
        # the polygonal part: a receiver that only touches the window clips to a line or a point
        clipped = polygonal_each(shapely.intersection(receivers[wj], window[sliver[wi]], grid_size=MERGE_GRID))
        local = np.array([shapely.union_all(clipped[wi == c], grid_size=MERGE_GRID) for c in range(len(cand))],
                         dtype=object)
        joined = shapely.union(local, slivers[sliver], grid_size=MERGE_GRID)
        gain = area[sliver] + _uncovered_near(local, inner[sliver], width) - _uncovered_near(joined, inner[sliver], width)
        ok = gain >= 0.5 * area[sliver]
        if not ok.any():
            break
        sliver, candidate, gain, shared = sliver[ok], candidate[ok], gain[ok], shared[ok]
        best = np.zeros(len(slivers))
        np.maximum.at(best, sliver, gain)
        near_best = gain >= best[sliver] - 0.01 * area[sliver]
        sliver, candidate, shared = sliver[near_best], candidate[near_best], shared[near_best]
        order = np.lexsort((candidate, -shared, sliver))
        first = order[np.r_[True, np.diff(sliver[order]) != 0]]
        placed = sliver[first]
        color[placed] = candidate[first]
        receivers = np.concatenate([receivers, slivers[placed]])
        receiver_color = np.concatenate([receiver_color, color[placed]])
        pending = np.setdiff1d(pending, placed)
        # only a sliver touching one just placed can have a new candidate
        touching = shapely.STRtree(slivers[placed]).query(slivers[pending], predicate="dwithin", distance=CONTACT_TOLERANCE)[0]
        check = pending[np.unique(touching)]
    return color


def _uncovered_near(regions: np.ndarray, near: np.ndarray, width: float) -> np.ndarray:
    """Area of each region narrower than a bead (minus its opening by ``w / 2``) inside ``near``.
    A region whose rings touch themselves (a union of strut sections), on which GEOS's
    overlay fails, is repaired first."""
    try:
        narrow = shapely.difference(regions, opening(regions, width / 2))
    except shapely.errors.GEOSException:
        regions = polygonal_each(shapely.make_valid(regions))
        narrow = shapely.difference(regions, opening(regions, width / 2))
    return shapely.area(shapely.intersection(narrow, near))


def _by_group(slivers: np.ndarray, own: np.ndarray, n_colors: int, width: float) -> np.ndarray:
    """Slivers no neighbour prints, grouped by contact: a group that a bead fits in as a
    whole (its opening by ``w / 2`` keeps at least half of it) goes to the color holding
    most of its area; the others keep their colors."""
    groups = shapely.get_parts(shapely.union_all(slivers, grid_size=MERGE_GRID))
    printable = shapely.area(opening(groups, width / 2)) >= 0.5 * shapely.area(groups)
    inside, group = shapely.STRtree(groups).query(shapely.point_on_surface(slivers), predicate="dwithin",
                                                  distance=CONTACT_TOLERANCE)
    cand, total = _sums(group * n_colors + own[inside], shapely.area(slivers[inside]))
    order = np.lexsort((cand % n_colors, -total, cand // n_colors))
    first = order[np.r_[True, np.diff(cand[order] // n_colors) != 0]]
    winner = np.full(len(groups), -1, dtype=np.int64)
    winner[cand[first] // n_colors] = cand[first] % n_colors
    out = np.array(own)
    take = printable[group]
    out[inside[take]] = winner[group[take]]
    return out


def _valid_polygons(geometries: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The polygons of ``geometries`` (repaired where an overlay returned an invalid one)
    and the index of the geometry each comes from."""
    parts, index = shapely.get_parts(shapely.make_valid(geometries), return_index=True)
    keep = (shapely.get_type_id(parts) == shapely.GeometryType.POLYGON) & (shapely.area(parts) > 0)
    return parts[keep], index[keep]


def _sums(key: np.ndarray, value: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The distinct keys (sorted) and the sum of ``value`` over each."""
    unique, inverse = np.unique(key, return_inverse=True)
    return unique, np.bincount(inverse, value, minlength=len(unique))
