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

from fgslice.toolpaths.infill import scan_segments
from fgslice.toolpaths.walls import ring_groups

STEP_DEG = 15.0
"""Directions tried, degrees apart."""

LINES_PER_BEAD = 1.0
"""Lines tried per bead width across the overhang."""

ANCHORED_SHARE = 0.9
"""Share of the line length that must be anchored at both ends."""


def bridgeable(piece: shapely.Geometry, lower: shapely.Geometry, reach: float, w: float) -> bool:
    """Whether lines across ``piece`` (one overhang polygon) land on ``lower`` (the outline
    of the layer below) at both ends, in some direction (see the module); ``reach``: how
    far the overhang's anchored edges lie from ``lower`` (mm).

    In the frame turned by ``-angle`` about the piece's centroid, direction ``angle``'s
    lines run along X, one per ``w / LINES_PER_BEAD`` of the turned piece's height from
    half a spacing above its lowest point (one line through its middle when it is lower
    than that); the piece's rings cut them by a scanline pass
    (:func:`fgslice.toolpaths.infill.scan_segments`), and every line end is tested against
    ``lower`` (prepared in place) in one vectorized call."""
    if piece.is_empty or lower.is_empty:
        return False
    carry, spacing = reach + w, w / LINES_PER_BEAD
    c = np.array(shapely.centroid(piece).coords[0])
    coords, ring, _ = ring_groups(piece)
    coords = coords - c
    turns = np.radians(np.arange(0.0, 180.0, STEP_DEG))
    direction, left, right, offset = [], [], [], []
    for i, angle in enumerate(turns):
        u, n = np.array([np.cos(angle), np.sin(angle)]), np.array([-np.sin(angle), np.cos(angle)])
        across = coords @ n
        y0, y1 = across.min(), across.max()
        first = y0 + spacing / 2 if y0 + spacing / 2 < y1 else (y0 + y1) / 2
        shift = first - spacing / 2  # the lines at (j + 1/2) spacing of the shifted frame
        _, x0, x1, y, _, _ = scan_segments(np.stack([coords @ u, across - shift], axis=1), ring, spacing, 0.0)
        direction.append(np.full(len(y), i))
        left.append(x0 - carry)
        right.append(x1 + carry)
        offset.append(y + shift)
    direction, left, right, offset = map(np.concatenate, (direction, left, right, offset))
    if not len(direction):
        return False
    u = np.stack([np.cos(turns[direction]), np.sin(turns[direction])], axis=1)
    side = c + offset[:, None] * np.stack([-u[:, 1], u[:, 0]], axis=1)
    xy = np.concatenate([side + left[:, None] * u, side + right[:, None] * u])
    shapely.prepare(lower)
    inside = shapely.contains_xy(lower, xy[:, 0], xy[:, 1])
    both = inside[: len(direction)] & inside[len(direction):]
    length = right - left - 2 * carry
    count = len(turns)
    anchored = np.bincount(direction, weights=np.where(both, length, 0.0), minlength=count)
    total = np.bincount(direction, weights=length, minlength=count)
    tried = np.bincount(direction, minlength=count) > 0  # directions whose lines meet the piece
    return bool((anchored[tried] >= ANCHORED_SHARE * total[tried]).any())
