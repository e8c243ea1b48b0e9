"""How much of a print is laid over nothing: the measure supports are judged by.

Read from any slicer's G-code (:func:`~fgslice.machine.gcode_reader.read_gcode`): a
point of an extruding move on layer ``k >= 1`` is *over nothing* when no material lies
within half a bead of it below, the material below being

* every extrusion of the layers whose top lies at or above the bottom of layer ``k``
  (its top ``;Z:`` minus the nominal ``layer_height``): layer ``k - 1``, and the support
  layers PrusaSlicer prints at heights of their own in between (part, support, tower,
  skirt), each bead its centerline grown by ``w / 2``, closed by ``close_mm`` (sparse
  infill's gaps and the gaps between support lines count as material: the beads above
  bridge them as they are meant to), and
* the support (``;TYPE:Support material`` and ``Support material interface``) whose
  layer top lies within ``gap_mm`` below that, because the surface a support holds is
  printed the top z gap above the support's top by design; for a support move, every
  extrusion there (support standing on the part keeps the bottom z gap above it).

Layer 0 lies on the bed. The share is the extruded volume (E) of the moves' points over
nothing divided by all extruded volume. The layers are rasterized on a grid of ``cell``
mm; distances come from scipy's Euclidean distance transform.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage
from scipy.spatial import cKDTree

TILE_MM = 8.0
"""Side of the tiles the closing is rasterized in, mm."""

SUPPORT_ROLES = ("Support material", "Support material interface")


def _samples(start: np.ndarray, end: np.ndarray, step: float) -> tuple[np.ndarray, np.ndarray]:
    """Points every ``step`` mm (at least the two ends) along each segment, and the
    segment of each point."""
    length = np.hypot(*(end - start).T)
    count = np.maximum(np.ceil(length / step).astype(np.int64), 1) + 1
    owner = np.repeat(np.arange(len(start)), count)
    first = np.cumsum(count) - count
    t = (np.arange(count.sum()) - first[owner]) / (count[owner] - 1)
    return start[owner] + t[:, None] * (end - start)[owner], owner


def unsupported_share(program, bead_width: float, layer_height: float = 0.2, gap_mm: float = 0.2,
                      close_mm: float = 1.5, cell: float = 0.1) -> float:
    """Share (0-1) of the extruded volume laid over nothing (see the module); mm."""
    printing = np.flatnonzero((program.e > 0) & (program.length > 0) & (program.layer >= 0))
    if not len(printing):
        return 0.0
    roles = np.array(list(program.roles) + [""], dtype=object)[program.role[printing]]
    is_support = np.isin(roles, SUPPORT_ROLES)
    layer = program.layer[printing]
    e = program.e[printing]
    order = np.argsort(layer, kind="stable")
    start, end = program.start[printing[order], :2], program.end[printing[order], :2]
    layer, is_support, e = layer[order], is_support[order], e[order]
    points, owner = _samples(start, end, cell)  # the material below: centerlines every cell
    point_layer, point_support = layer[owner], is_support[owner]
    bounds = np.searchsorted(point_layer, np.arange(int(layer.max()) + 2))
    judged, judged_owner = _samples(start, end, 2 * cell)  # the points judged
    weight = (e / np.bincount(judged_owner, minlength=len(e)))[judged_owner]
    judged_bounds = np.searchsorted(layer[judged_owner], np.arange(int(layer.max()) + 2))
    judged_support = is_support[judged_owner]
    over_nothing = 0.0
    reach = bead_width + cell  # centerlines this close: the beads overlap by half a bead at least
    tops = np.asarray(program.layer_z, dtype=float)
    eps = 1e-3
    for k in range(1, int(layer.max()) + 1):
        mine = slice(judged_bounds[k], judged_bounds[k + 1])
        if mine.start == mine.stop:
            continue
        here, here_weight = judged[mine], weight[mine]
        bottom = tops[k] - layer_height
        first_all = min(int(np.searchsorted(tops, bottom - eps)), k - 1)
        first_support = min(int(np.searchsorted(tops, bottom - gap_mm - eps)), first_all)
        lo = bounds[first_support]
        candidates = points[lo : bounds[k]]
        near_layer = point_layer[lo : bounds[k]] >= first_all
        mine_support = judged_support[mine]
        for kind, below in ((~mine_support, candidates[near_layer | point_support[lo : bounds[k]]]),
                            (mine_support, candidates)):
            if not kind.any():
                continue
            pts, wts = here[kind], here_weight[kind]
            if not len(below):
                over_nothing += float(wts.sum())
                continue
            tree = cKDTree(below)
            near, _ = tree.query(pts, distance_upper_bound=reach)
            doubt = ~np.isfinite(near)
            if doubt.any():
                far = _far_after_closing(pts[doubt], below, tree, bead_width, close_mm, cell)
                over_nothing += float(wts[doubt][far].sum())
    return over_nothing / float(e.sum())


def _far_after_closing(points: np.ndarray, below: np.ndarray, tree, bead_width: float, close_mm: float,
                       cell: float) -> np.ndarray:
    """Which ``points`` lie more than half a bead from the beads ``below`` (centerline
    samples) once those are closed by ``close_mm``; rasterized in tiles of
    :data:`TILE_MM` around the points, so empty space between islands costs nothing."""
    far = np.zeros(len(points), dtype=bool)
    margin = bead_width + 2 * close_mm + 2 * cell
    tiles, tile_of = np.unique(np.floor(points / TILE_MM).astype(np.int64), axis=0, return_inverse=True)
    for t, corner in enumerate(tiles):
        mine = np.flatnonzero(tile_of.ravel() == t)
        low = corner * TILE_MM - margin
        high = (corner + 1) * TILE_MM + margin
        near = below[tree.query_ball_point((low + high) / 2, float(np.hypot(*(high - low)) / 2))]
        near = near[((near >= low) & (near <= high)).all(axis=1)]
        if not len(near):
            far[mine] = True
            continue
        shape = np.ceil((high - low) / cell).astype(np.int64) + 1
        grid = np.ones(shape, dtype=bool)
        idx = np.rint((near - low) / cell).astype(np.int64)
        grid[idx[:, 0], idx[:, 1]] = False
        dilated = ndimage.distance_transform_edt(grid, sampling=cell) <= bead_width / 2 + close_mm
        closed = ndimage.distance_transform_edt(dilated, sampling=cell) > close_mm
        distance = ndimage.distance_transform_edt(~closed, sampling=cell)
        at = np.rint((points[mine] - low) / cell).astype(np.int64)
        far[mine] = distance[at[:, 0], at[:, 1]] > bead_width / 2 + cell
    return far
