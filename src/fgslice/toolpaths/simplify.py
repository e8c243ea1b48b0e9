"""Simplify paths to a tolerance (mm) before output, in one vectorized shapely call.

Closed paths stay closed: they are simplified as rings (the closing vertex is taken
into account, then dropped again, so ``Path.points`` keeps not repeating it).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import shapely

from fgslice.toolpaths.paths import Path


def simplify_paths(paths: list[Path], tolerance: float) -> list[Path]:
    """Every path simplified (Douglas-Peucker) so no point moves more than ``tolerance``.

    Paths that would degenerate (fewer than 2 points, or 3 for closed ones) keep their
    original points.
    """
    if not paths or tolerance <= 0:
        return list(paths)
    verts = [p.vertices for p in paths]
    counts = np.array([len(v) for v in verts])
    lines = shapely.linestrings(np.vstack(verts), indices=np.repeat(np.arange(len(paths)), counts))
    simple = shapely.simplify(lines, tolerance, preserve_topology=False)
    coords, index = shapely.get_coordinates(simple, return_index=True)
    bounds = np.searchsorted(index, np.arange(len(paths) + 1))
    out = []
    for p, a, b in zip(paths, bounds[:-1].tolist(), bounds[1:].tolist()):
        pts = coords[a : b - 1] if p.closed else coords[a:b]
        out.append(replace(p, points=pts) if len(pts) >= (3 if p.closed else 2) else p)
    return out
