"""Simplification: tolerance respected, closed paths stay closed, vertex count drops,
polygons stay valid."""

import numpy as np
import shapely

from fgslice.toolpaths.paths import Path, Role
from fgslice.toolpaths.simplify import simplify_paths, simplify_polygons


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


def test_simplify_polygons_within_tolerance_and_valid():
    # a dense, slightly noisy plate with a hole, like a mesh section
    rng = np.random.default_rng(1)
    t = np.linspace(0, 2 * np.pi, 4000, endpoint=False)
    outer = np.column_stack([30 + 20 * np.cos(t), 30 + 15 * np.sin(t)]) + rng.normal(0, 5e-4, (len(t), 2))
    hole = np.column_stack([30 + 4 * np.cos(t), 30 + 4 * np.sin(t)])[::-1]
    plate = shapely.Polygon(outer, [hole])
    notch = shapely.box(0, 0, 10, 10).difference(shapely.box(4, -1, 6, 5))
    out = simplify_polygons(np.array([plate, notch]), 0.01)
    assert shapely.is_valid(out).all()
    assert shapely.get_num_coordinates(out[0]) < shapely.get_num_coordinates(plate) / 10
    assert shapely.hausdorff_distance(out[0], plate) <= 0.01 + 1e-9
    assert abs(out[0].area - plate.area) < 0.01 * plate.length
    # corners survive exactly
    assert out[1].equals(notch)
    assert simplify_polygons(plate, 0.01).equals(out[0])
