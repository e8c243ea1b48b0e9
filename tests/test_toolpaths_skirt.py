"""Skirt: loop count, distance from the part, role and color."""

import numpy as np
import shapely

from fgslice.settings import Settings
from fgslice.toolpaths.paths import Role
from fgslice.toolpaths.skirt import skirt_paths
from fgslice.toolpaths.walls import bead_spacing


def test_skirt_loops_at_distance():
    outline = shapely.MultiPolygon([shapely.box(50, 50, 80, 70), shapely.Point(100, 60).buffer(5)])
    settings = Settings(skirt_loops=3, skirt_distance=4.0)
    loops = skirt_paths(outline, settings)
    assert len(loops) == 3
    assert all(p.role is Role.SKIRT and p.color == -1 and p.closed for p in loops)
    s = bead_spacing(settings.bead_width, settings.layer_height)
    for k, p in enumerate(sorted(loops, key=lambda p: p.length)):
        d = shapely.distance(shapely.points(p.points), shapely.convex_hull(outline))
        assert np.allclose(d, 4.0 + settings.bead_width / 2 + k * s, atol=0.02)
        assert not shapely.Polygon(p.points).boundary.intersects(outline.buffer(4.0))


def test_skirt_of_a_many_sided_outline_has_no_join_slivers_and_stays_within_resolution():
    outline = shapely.Point(110, 110).buffer(40, quad_segs=64)  # 256 corners of 1.4 degrees
    settings = Settings(skirt_loops=1, skirt_distance=3.0)
    (loop,) = skirt_paths(outline, settings)
    ring = np.vstack([loop.points, loop.points[:1]])
    segments = np.hypot(*np.diff(ring, axis=0).T)
    assert segments.min() > 0.2  # no round-join segment a few hundredths of a mm long
    middles = shapely.points((ring[1:] + ring[:-1]) / 2)
    gap = shapely.distance(middles, shapely.convex_hull(outline))
    expected = 3.0 + settings.bead_width / 2
    assert gap.min() >= expected - settings.gcode_resolution - 1e-9
    assert gap.max() <= expected + 0.02


def test_no_skirt():
    outline = shapely.box(0, 0, 10, 10)
    assert skirt_paths(outline, Settings(skirt_loops=0)) == []
