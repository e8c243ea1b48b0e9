"""The tight box of a ``function`` shape: where its field is <= 0 within its given box.

A function's box only bounds where it may be inside (OpenVCAD's default box is 20 mm about
the origin whatever the function); the part lies on the bed by its lowest inside point,
so its bounds must be those of the inside region. Each side of the box is moved inward
plane by plane (planes :func:`step` mm apart, each sampled on a grid of that step) to
the first plane holding an inside sample, then bisected against the last empty plane to
:data:`TOLERANCE`; the bound kept is the empty side, so the region lies within it. A
feature thinner than the step between two sampled planes or points can be missed; a
function no sample finds inside keeps its box.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

TOLERANCE = 1e-3
"""How far outside the inside region a tight bound may lie, mm."""

FINEST_STEP = 0.2
"""Finest sampling step, mm (half a 0.4 mm bead)."""

PLANES = 128
"""Most sampled planes (and samples per row) across the box on each axis."""


def step(extent: float) -> float:
    """Sampling step (mm) across a box side of ``extent`` mm."""
    return max(FINEST_STEP, extent / PLANES)


def tight_box(field: Callable, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(lo, hi)`` of where ``field(x, y, z) <= 0`` inside the box ``lo..hi`` (mm); the
    box itself when no sample is inside (the sections then show what, if anything, is)."""
    box = np.array(lo, dtype=float), np.array(hi, dtype=float)
    lo, hi = box[0].copy(), box[1].copy()
    for axis in (2, 0, 1):
        others = [a for a in range(3) if a != axis]
        grids = [np.arange(lo[a], hi[a] + step(hi[a] - lo[a]) / 2, step(hi[a] - lo[a])) for a in others]
        u, v = (g.ravel() for g in np.meshgrid(*grids, indexing="ij"))

        def holds(t: float, axis=axis, others=others, u=u, v=v) -> bool:
            point = [None, None, None]
            point[axis], point[others[0]], point[others[1]] = np.full(u.shape, t), u, v
            return bool(np.any(np.asarray(field(*point)) <= 0))

        planes = np.append(np.arange(lo[axis], hi[axis], step(hi[axis] - lo[axis])), hi[axis])
        inside = next((i for i, t in enumerate(planes) if holds(t)), None)
        if inside is None:
            return box
        last = next(i for i in range(len(planes) - 1, -1, -1) if holds(planes[i]))
        lo[axis] = planes[0] if inside == 0 else _bisect(holds, planes[inside - 1], planes[inside])
        hi[axis] = planes[-1] if last == len(planes) - 1 else _bisect(holds, planes[last + 1], planes[last])
    return lo, hi


def _bisect(holds: Callable[[float], bool], empty: float, full: float) -> float:
    """A plane position within :data:`TOLERANCE` of the first holding one, on the empty side."""
    while abs(full - empty) > TOLERANCE:
        middle = (empty + full) / 2
        if holds(middle):
            full = middle
        else:
            empty = middle
    return empty
