"""Simplification: tolerance respected, closed paths stay closed, vertex count drops."""

import numpy as np
import shapely

from fgslice.toolpaths.paths import Path, Role
from fgslice.toolpaths.simplify import simplify_paths


def test_simplify_within_tolerance_and_keeps_closure():
    t = np.linspace(0, 2 * np.pi, 2000, endpoint=False)
    circle = np.column_stack([50 + 20 * np.cos(t), 50 + 20 * np.sin(t)])
    line = np.column_stack([np.linspace(0, 10, 500), 0.001 * np.sin(np.linspace(0, 30, 500))])
    paths = [Path(circle, Role.PERIMETER, 1, 0.4, 0.2, closed=True), Path(line, Role.SOLID_INFILL, 2, 0.4, 0.2)]
    out = simplify_paths(paths, 0.0125)
    assert out[0].closed and not out[1].closed
    assert out[0].color == 1 and out[1].role is Role.SOLID_INFILL
    assert len(out[0].points) < 200 and len(out[1].points) == 2
    assert not np.allclose(out[0].points[0], out[0].points[-1])
    for before, after in zip(paths, out):
        d = shapely.distance(shapely.points(before.vertices), shapely.LineString(after.vertices))
        assert d.max() <= 0.0125 + 1e-9
        assert abs(before.length - after.length) < 0.01 * before.length
