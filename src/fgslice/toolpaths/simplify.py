"""Simplify paths (before output) and polygons (before offsetting) to a tolerance (mm),
in vectorized shapely calls.

Closed paths stay closed: they are simplified as rings (the closing vertex is taken
into account, then dropped again, so ``Path.points`` keeps not repeating it).
"""

from __future__ import annotations

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
    points = np.concatenate([p.points for p in paths])
    counts = np.array([len(p.points) for p in paths])
    closed = np.array([p.closed for p in paths], dtype=np.int64)
    # every path's vertices, closed ones with their first point repeated at the end
    sizes = counts + closed
    ends = np.cumsum(sizes)
    verts = np.empty((ends[-1], 2))
    keep = np.ones(ends[-1], dtype=bool)
    keep[(ends - 1)[closed == 1]] = False
    verts[keep] = points
    verts[(ends - 1)[closed == 1]] = points[(np.cumsum(counts) - counts)[closed == 1]]
    lines = shapely.linestrings(verts, indices=np.repeat(np.arange(len(paths)), sizes))
    simple = shapely.simplify(lines, tolerance, preserve_topology=False)
    coords, index = shapely.get_coordinates(simple, return_index=True)
    bounds = np.searchsorted(index, np.arange(len(paths) + 1))
    out = []
    for p, a, b in zip(paths, bounds[:-1].tolist(), bounds[1:].tolist()):
        pts = coords[a : b - 1] if p.closed else coords[a:b]
        if len(pts) >= (3 if p.closed else 2):
            p = Path(pts, p.role, p.color, p.width, p.height, p.closed, p.group)
        out.append(p)
    return out


def simplify_polygons(geoms, tolerance: float):
    """Polygonal geometries (one or an array) simplified (Douglas-Peucker) so that their
    boundaries move by about ``tolerance`` (mm) at most.

    Mesh sections and traced faces carry many vertices closer together than any offset
    or printer resolves; offsets of the simplified geometry are many times faster.
    Topology is not preserved vertex by vertex: GEOS repairs the result instead, so
    it stays valid, and rings closer than ``tolerance`` to each other may merge
    (material thinner than the tolerance vanishes, far below a bead width).
    """
    return shapely.simplify(geoms, tolerance, preserve_topology=False)
