"""Zippers: interleave the two neighbouring colors inside the band around each boundary.

``palette.zipper_neighbor(fractions, beta)`` tells, for each point, the color across
the nearest palette boundary when the point lies inside the zipper band (total width
``beta`` percent of the gradient range, centred on the boundary), else -1. Inside a
band the two colors of the boundary, ``(lo, hi)``, alternate *tooth by tooth*:

* closed paths (walls, concentric loops): each in-band stretch of the path is cut into
  teeth of about :func:`tooth_length` along the path; tooth ``j`` gets ``lo`` when
  ``j + layer`` is even, ``hi`` otherwise;
* open paths (rectilinear serpentines): one tooth per line, so consecutive lines
  alternate (tooth ``j`` = line ``j`` and the link after it).

Adding the layer index shifts the alternation by one from layer to layer, so the
interface also interlocks in Z. Outside bands a sub-segment keeps its field color.
"""

from __future__ import annotations

import numpy as np


def tooth_length(width: float, min_segment_mm: float) -> float:
    """Length of a zipper tooth along a wall, mm: ``max(min_segment_mm, 2 w)``."""
    return max(min_segment_mm, 2.0 * width)


def zipper_labels(
    color: np.ndarray,
    neighbor: np.ndarray,
    segment: np.ndarray,
    loop: np.ndarray,
    loop_run_start: np.ndarray,
    loop_arc_mid: np.ndarray,
    loop_length: np.ndarray,
    layer_index: int,
    tooth: float,
) -> np.ndarray:
    """Colors of a layer's densified sub-segments (in path order) with zippers applied:
    the field color outside bands, the alternating tooth colors inside.

    Args:
        color: field color at each sub-segment's midpoint.
        neighbor: ``palette.zipper_neighbor`` there (-1 outside every band).
        segment: index of the original path segment each sub-segment comes from.
        loop: the in-band sub-segments that lie on closed paths (ascending indices).
        loop_run_start: for each of ``loop``, True where a stretch of consecutive in-band
            sub-segments of a path begins (at the path's start or after a sub-segment
            outside every band).
        loop_arc_mid: for each of ``loop``, arc length of its midpoint along its path, mm.
        loop_length: for each of ``loop``, its length, mm.
        layer_index: the layer's index (parity shifts the alternation).
        tooth: tooth length along closed paths, mm.
    """
    parity = (segment >> 1) + layer_index
    if len(loop):
        run = np.cumsum(loop_run_start) - 1
        run_start_arc = (loop_arc_mid - loop_length / 2)[loop_run_start]
        run_length = np.bincount(run, weights=loop_length)
        teeth = np.maximum(np.round(run_length / tooth), 1.0)
        along = np.floor((loop_arc_mid - run_start_arc[run]) / (run_length / teeth)[run]).astype(np.int64)
        parity[loop] = along + layer_index
    lo = np.minimum(color, neighbor)
    return np.where(neighbor >= 0, np.where(parity & 1, color + neighbor - lo, lo), color)
