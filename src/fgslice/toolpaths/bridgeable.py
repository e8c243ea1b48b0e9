"""Which overhangs a bridge spans: PrusaSlicer's ``dont_support_bridges``.

An overhang (an area of layer ``k`` with nothing of layer ``k - 1`` under it) is
*bridgeable* when, in some direction, straight lines across it land on the layer below
at both ends: a roof over a closed cavity, a span between two walls. Like PrusaSlicer's
bridge detector, directions every :data:`STEP_DEG` degrees are tried, lines :data:`LINES_PER_BEAD`
per bead width apart; a line is anchored when both its ends, carried ``reach + w`` mm on
beyond the overhang's edge, lie on the layer below. The overhang is bridgeable when the
lines anchored at both ends hold at least :data:`ANCHORED_SHARE` of the line length in
the best direction. A cantilever (a T's arm, anchored on one side only) is not. Bed
frame, mm.
"""

from __future__ import annotations

import numpy as np
import shapely
import shapely.affinity

STEP_DEG = 15.0
"""Directions tried, degrees apart."""

LINES_PER_BEAD = 1.0
"""Lines tried per bead width across the overhang."""

ANCHORED_SHARE = 0.9
"""Share of the line length that must be anchored at both ends."""


def bridgeable(piece: shapely.Geometry, lower: shapely.Geometry, reach: float, w: float) -> bool:
    """Whether lines across ``piece`` (one overhang polygon) land on ``lower`` (the outline
    of the layer below) at both ends, in some direction (see the module); ``reach``: how
    far the overhang's anchored edges lie from ``lower`` (mm)."""
    if piece.is_empty or lower.is_empty:
        return False
    carry = reach + w
    cx, cy = shapely.centroid(piece).coords[0]
    for angle in np.arange(0.0, 180.0, STEP_DEG):
        turned = shapely.affinity.rotate(piece, -angle, origin=(cx, cy))
        x0, y0, x1, y1 = turned.bounds
        ys = np.arange(y0 + w / 2, y1, w / LINES_PER_BEAD)
        if not len(ys):
            ys = np.array([(y0 + y1) / 2])
        lines = shapely.linestrings(np.stack([np.stack([np.full_like(ys, x0 - 1), ys], axis=1),
                                              np.stack([np.full_like(ys, x1 + 1), ys], axis=1)], axis=1))
        segments = shapely.get_parts(shapely.intersection(lines, turned))
        segments = segments[shapely.get_type_id(segments) == 1]
        if not len(segments):
            continue
        a = shapely.get_coordinates(shapely.get_point(segments, 0))
        b = shapely.get_coordinates(shapely.get_point(segments, -1))
        left, right, y = np.minimum(a[:, 0], b[:, 0]) - carry, np.maximum(a[:, 0], b[:, 0]) + carry, a[:, 1]
        ends = shapely.affinity.rotate(shapely.MultiPoint(np.concatenate([np.stack([left, y], 1), np.stack([right, y], 1)])),
                                       angle, origin=(cx, cy))
        xy = shapely.get_coordinates(ends)
        inside = shapely.contains_xy(lower, xy[:, 0], xy[:, 1])
        both = inside[: len(y)] & inside[len(y):]
        length = right - left - 2 * carry
        if length[both].sum() >= ANCHORED_SHARE * length.sum():
            return True
    return False
