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
    path_id: np.ndarray,
    segment: np.ndarray,
    arc_mid: np.ndarray,
    sub_length: np.ndarray,
    closed: np.ndarray,
    layer_index: int,
    tooth: float,
) -> np.ndarray:
    """Color of each densified sub-segment with zippers applied.

    Args:
        color: field color at each sub-segment midpoint.
        neighbor: ``palette.zipper_neighbor`` there (-1 outside every band).
        path_id: index of the path each sub-segment belongs to (contiguous, in order).
        segment: index of the original path segment each sub-segment comes from.
        arc_mid: arc length of the sub-segment midpoint along its path, mm.
        sub_length: length of each sub-segment, mm.
        closed: per path, whether it is closed.
        layer_index: the layer's index (parity shifts the alternation).
        tooth: tooth length along closed paths, mm.
    """
    band = neighbor >= 0
    if not band.any():
        return color
    lo, hi = np.minimum(color, neighbor), np.maximum(color, neighbor)
    start = np.r_[True, (path_id[1:] != path_id[:-1]) | (band[1:] != band[:-1])]
    run = np.cumsum(start) - 1
    run_first = np.flatnonzero(start)
    run_start_arc = arc_mid[run_first] - sub_length[run_first] / 2
    run_length = np.bincount(run, weights=sub_length)
    teeth = np.maximum(np.round(run_length / tooth), 1.0)
    rel = arc_mid - run_start_arc[run]
    along = np.floor(rel / (run_length[run] / teeth[run])).astype(np.int64)
    index = np.where(closed[path_id], along, segment // 2)
    return np.where(band, np.where((index + layer_index) % 2 == 0, lo, hi), color)
