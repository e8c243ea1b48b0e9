"""Walls: count, spacing, holes, roles, nothing outside the outline, no sub-bead fragments."""

import numpy as np
import pytest
import shapely

from fgslice.settings import Settings
from fgslice.toolpaths.paths import Role
from fgslice.toolpaths.walls import bead_spacing, make_walls, offset, offset_polygons, simplify_outline

W, H = 0.4, 0.2
RESOLUTION = Settings().gcode_resolution
"""The tolerance strategy 1 simplifies its outlines to by default (mm)."""
OFFSET_TOLERANCE = 0.005
"""How far (mm) the walls' mitre offsets may lie from the reference offsets of a test."""


def plate_with_hole():
    return shapely.MultiPolygon([shapely.box(0, 0, 30, 20).difference(shapely.Point(15, 10).buffer(4, quad_segs=32))])


def distances_to_boundary(paths, outline):
    pts = np.vstack([p.points for p in paths])
    return shapely.distance(shapely.points(pts), outline.boundary)


@pytest.mark.parametrize("count", [1, 3, 5])
def test_wall_count_and_spacing(count):
    outline = plate_with_hole()
    walls = make_walls(outline, count, W, H)
    # one loop per island and per hole, per wall
    assert len(walls.paths) == 2 * count
    s = bead_spacing(W, H)
    for k in range(count):
        # loop k sits w/2 + k s inside the design surface
        d = distances_to_boundary(walls.paths, outline)
        assert np.any(np.isclose(d, W / 2 + k * s, atol=0.02))
    outer = [p for p in walls.paths if p.role is Role.EXTERNAL_PERIMETER]
    assert len(outer) == 2  # the island and the hole
    d = distances_to_boundary(outer, outline)
    assert np.allclose(d, W / 2, atol=0.02)


def test_hole_gets_walls_and_paths_stay_inside():
    outline = plate_with_hole()
    walls = make_walls(outline, 3, W, H)
    hole = shapely.Point(15, 10).buffer(4, quad_segs=32)
    around_hole = [p for p in walls.paths if shapely.Polygon(p.points).contains(shapely.Point(15, 10)) and p.length < 40]
    assert len(around_hole) == 3
    for p in walls.paths:
        # inside the outline by w/2, up to the difference of mitre and round joins on the hole
        line = shapely.LinearRing(p.points)
        assert outline.buffer(-W / 2 + OFFSET_TOLERANCE + 1e-6).covers(line)
        assert not line.intersects(hole)
    # inner area is the strip edge of the last loop: w/2 + 2 s + s/2 inside
    s = bead_spacing(W, H)
    expected = outline.buffer(-(W / 2 + 2.5 * s), join_style="mitre")
    assert walls.inner.symmetric_difference(expected).area < OFFSET_TOLERANCE * expected.length


def test_outer_first_order():
    walls = make_walls(plate_with_hole(), 3, W, H, outer_first=True)
    assert walls.paths[0].role is Role.EXTERNAL_PERIMETER
    walls = make_walls(plate_with_hole(), 3, W, H, outer_first=False)
    assert walls.paths[-1].role is Role.EXTERNAL_PERIMETER


def test_no_fragment_narrower_than_a_bead():
    # a plate with a thin tab (0.3 mm < w) and a slightly wider one (0.9 mm)
    body = shapely.box(0, 0, 20, 20)
    thin = shapely.box(20, 5, 30, 5.3)
    wide = shapely.box(20, 10, 30, 10.9)
    outline = shapely.MultiPolygon([shapely.union_all([body, thin, wide])])
    walls = make_walls(outline, 2, W, H)
    for p in walls.paths:
        # every bead fits inside the outline
        assert outline.buffer(1e-6).covers(shapely.LinearRing(p.points).buffer(W / 2 - 1e-3))
    pts = np.vstack([p.points for p in walls.paths])
    assert not np.any((pts[:, 0] > 20.5) & (pts[:, 1] > 4.9) & (pts[:, 1] < 5.4))
    assert np.any((pts[:, 0] > 25) & (pts[:, 1] > 10) & (pts[:, 1] < 11))


def test_no_walls_inner_is_half_bead_inside():
    outline = plate_with_hole()
    walls = make_walls(outline, 0, W, H)
    assert walls.paths == []
    expected = outline.buffer(-W / 2, join_style="mitre")
    assert walls.inner.symmetric_difference(expected).area < OFFSET_TOLERANCE * expected.length


def dumbbell():
    """Two plates joined by a 0.9 mm neck: the third loop's erosion splits there."""
    return shapely.MultiPolygon([shapely.union_all([shapely.box(0, 0, 10, 10), shapely.box(10, 4.55, 14, 5.45), shapely.box(14, 0, 24, 10)])])


def ellipse():
    return shapely.MultiPolygon([shapely.affinity.scale(shapely.Point(50, 50).buffer(1, quad_segs=64), 20, 30)])


@pytest.mark.parametrize("shape", [ellipse, dumbbell, plate_with_hole])
def test_loops_are_the_opened_erosions(shape):
    # loop k is the boundary of the outline eroded by w/2 + k s and opened by s/2, whether
    # the opening is skipped (no event between levels) or computed (the neck); the
    # outline comes simplified (as strategy 1 slices it), within the tolerance of the shape
    simple, count = simplify_outline(shape(), RESOLUTION), 6
    assert shapely.hausdorff_distance(simple, shape()) <= RESOLUTION
    s = bead_spacing(W, H)
    walls = make_walls(simple, count, W, H, outer_first=True)
    dist = W / 2 + s * np.arange(count)
    opened = shapely.buffer(shapely.buffer(simple, -(dist + s / 2), join_style="mitre", mitre_limit=3), s / 2,
                            join_style="mitre", mitre_limit=3)
    expected = shapely.union_all(shapely.boundary(opened))
    got = shapely.union_all([shapely.LinearRing(p.points) for p in walls.paths])
    assert shapely.hausdorff_distance(got, expected) < 1e-6


def test_offset_polygons_equal_geos_offsets():
    """Vertex-by-vertex erosions are GEOS's mitre erosions; events go to GEOS."""
    smooth = shapely.Point(0, 0).buffer(10, quad_segs=32).difference(shapely.Point(2, 1).buffer(3, quad_segs=16))
    short_edge = shapely.Polygon([(0, 0), (20, 0), (20, 10), (10.025, 14), (9.975, 14), (0, 10)])  # the 0.05 mm edge collapses
    dumbbell = shapely.union_all([shapely.box(0, 0, 10, 10), shapely.box(10, 4.85, 20, 5.15), shapely.box(20, 0, 30, 10)])
    sliver = shapely.box(0, 0, 20, 0.3)
    notch = shapely.Polygon([(0, 0), (10, 0), (1, 3), (10, 6), (0, 6)])  # reflex corner sharper than the mitre limit
    polygons = np.array([smooth, short_edge, dumbbell, sliver, notch], dtype=object)
    for d in (-0.2, -0.5):
        got, exact = offset_polygons(polygons, d)
        want = offset(polygons, d)
        assert exact[:2].all() and not exact[2:].any()
        assert np.all(shapely.area(shapely.symmetric_difference(got, want)) < 1e-8)
        assert np.all(shapely.is_valid(got))
        assert shapely.get_num_coordinates(got[1]) == shapely.get_num_coordinates(short_edge) - 1


def test_offset_polygons_one_distance_per_polygon():
    """Each polygon is eroded by its own distance; clockwise rings bevel sharp reflex corners too."""
    smooth = shapely.Point(0, 0).buffer(10, quad_segs=32)
    notch = shapely.Polygon([(0, 0), (10, 0), (10, 4), (2, 5), (10, 6), (10, 10), (0, 10)])  # 14 degree reflex corner
    polygons = np.array([smooth, smooth, smooth, notch, notch.reverse()], dtype=object)
    d = np.array([-0.2, -1.0, -4.0, -0.5, -0.5])
    got, exact = offset_polygons(polygons, d)
    want = offset(polygons, d)
    assert exact[:3].all() and not exact[3:].any()
    assert np.all(shapely.area(shapely.symmetric_difference(got, want)) < 1e-8)
    assert np.allclose(shapely.area(got[:3]), shapely.area(want[:3]), rtol=0, atol=1e-9)


@pytest.mark.parametrize("reverse", [False, True])
def test_convex_walls_are_geos_offsets_vertex_for_vertex(reverse):
    """Smooth convex outlines (the vase's ellipses) are eroded in numpy to every level at once;
    the loops are GEOS's mitre erosions, same vertices from the same start, whichever the
    outline's orientation, also where an edge collapses before the innermost level."""
    oval = shapely.affinity.scale(shapely.Point(50, 50).buffer(1, quad_segs=64), 20, 30)
    chamfered = shapely.Polygon([(0, 0), (20, 0), (20, 9.3), (19.3, 10), (0, 10)])  # 1 mm edge, gone at 1.2 mm
    s, count = bead_spacing(W, H), 6
    for shape in (oval, chamfered):
        simple = simplify_outline(shape.reverse() if reverse else shape, RESOLUTION)
        walls = make_walls(simple, count, W, H, outer_first=True)
        want = offset(simple, -(W / 2 + s * np.arange(count)))
        assert len(walls.paths) == count
        for path, loop in zip(walls.paths, want):
            ring = shapely.get_coordinates(shapely.get_exterior_ring(loop))[:-1]
            assert path.points.shape == ring.shape
            assert np.abs(path.points - ring).max() < 1e-9


@pytest.mark.parametrize("outline", [shapely.box(0, 0, 10, 0.3), shapely.MultiPolygon([shapely.box(0, 0, 0.35, 0.35)])],
                         ids=["strip", "speck"])
def test_outline_narrower_than_a_bead_gets_no_walls(outline):
    # the tip of a tilted torus, a sliver of a mesh: no loop fits, nothing is left inside
    walls = make_walls(outline, 2, 0.4, 0.2)
    assert walls.paths == []
    assert walls.inner.is_empty and walls.eroded.is_empty
