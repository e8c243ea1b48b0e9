"""Infill: density as extruded volume, line directions, links inside the region."""

import numpy as np
import pytest
import shapely

from fgslice.toolpaths.infill import concentric, line_fill, rectilinear, rectilinear_many, solid_fill
from fgslice.toolpaths.paths import Role, bead_area

W, H = 0.4, 0.2


def region():
    plate = shapely.box(0, 0, 60, 50).difference(shapely.Point(30, 25).buffer(8, quad_segs=32))
    return plate.difference(shapely.box(45, -1, 50, 20))


def volume(paths):
    return sum(p.length * bead_area(p.width, p.height) for p in paths)


@pytest.mark.parametrize("density", [10, 20, 35, 60, 100])
@pytest.mark.parametrize("angle", [0, 45, 90, 30])
def test_rectilinear_density_is_volume(density, angle):
    area = region()
    paths = rectilinear(area, density, angle, W, H, Role.INTERNAL_INFILL)
    error = volume(paths) / (area.area * H * density / 100) - 1
    assert abs(error) < 0.05, error


@pytest.mark.parametrize("density", [20, 100])
def test_concentric_density_is_volume(density):
    area = region()
    paths = concentric(area, density, W, H, Role.INTERNAL_INFILL)
    error = volume(paths) / (area.area * H * density / 100) - 1
    assert abs(error) < 0.05, error


def test_paths_inside_and_serpentine_links_short():
    area = region()
    paths = rectilinear(area, 30, 45, W, H, Role.INTERNAL_INFILL)
    grown = area.buffer(1e-6)
    for p in paths:
        assert grown.covers(shapely.LineString(p.points))
    # linked: far fewer paths than lines
    n_lines = sum(len(p.points) // 2 for p in paths)
    assert len(paths) < n_lines / 4
    # lines (even segments) run at 45 degrees; links are the odd segments
    for p in paths:
        d = np.diff(p.points, axis=0)
        lines = d[0::2]
        assert np.allclose(np.abs(lines[:, 0]), np.abs(lines[:, 1]), atol=1e-6)
        assert np.all(np.hypot(*lines.T) >= W)


def test_direction_follows_angle():
    area = shapely.box(0, 0, 20, 20)
    for angle, axis in ((0, 1), (90, 0)):
        paths = rectilinear(area, 50, angle, W, H, Role.SOLID_INFILL)
        lines = np.diff(paths[0].points, axis=0)[0::2]
        assert np.allclose(lines[:, axis], 0, atol=1e-9)


def test_short_lines_dropped():
    # a thin triangle: lines near the tip are shorter than a bead
    tri = shapely.Polygon([(0, 0), (20, 0), (0, 4)])
    paths = rectilinear(tri, 100, 90, W, H, Role.SOLID_INFILL, link=False)
    assert all(p.length >= W for p in paths)
    assert max(p.points[:, 0].max() for p in paths) < 20 - 1.0


def test_zero_density_and_empty_region():
    assert rectilinear(region(), 0, 0, W, H, Role.INTERNAL_INFILL) == []
    assert rectilinear(shapely.Polygon(), 20, 0, W, H, Role.INTERNAL_INFILL) == []
    assert concentric(shapely.Polygon(), 20, W, H, Role.INTERNAL_INFILL) == []


def test_solid_fill_of_many_regions_keeps_each_region_and_its_volume():
    # three disjoint regions filled in one pass: each path stays in its own region (no
    # link crosses between them) and each region gets its volume
    regions = [
        shapely.box(0, 0, 20, 3),
        shapely.Point(40, 10).buffer(8, quad_segs=32).difference(shapely.Point(40, 10).buffer(3, quad_segs=32)),
        shapely.Polygon([(0, 6), (30, 6), (0, 20)]),
    ]
    paths = solid_fill(regions, 30.0, W, H, Role.SOLID_INFILL, [7, 8, 9])
    assert {p.color for p in paths} == {7, 8, 9}
    for color, area in zip([7, 8, 9], regions):
        mine = [p for p in paths if p.color == color]
        assert all(area.buffer(1e-3).covers(shapely.LineString(p.points)) for p in mine)
        assert volume(mine) / (area.area * H) == pytest.approx(1.0, abs=0.03)


def test_line_fill_with_one_spacing_per_region_fills_each_on_its_own():
    # overlapping copies of one region at several spacings, in one pass, give each
    # spacing's own lines; every line lies inside the region
    area = region()
    spacings = np.array([0.9, 1.3, 2.0])
    pts, chain, owner = line_fill(np.full(3, area, dtype=object), spacings, 30.0, W)
    assert set(owner.tolist()) == {0, 1, 2}
    for k, spacing in enumerate(spacings):
        alone, alone_chain, _ = line_fill(area, spacing, 30.0, W)
        mine = owner[chain] == k
        assert np.array_equal(pts[mine], alone)
        assert len(np.unique(alone_chain)) == len(np.unique(chain[mine]))
    lines = shapely.linestrings(pts.reshape(-1, 2, 2))  # vertices 2j, 2j + 1: line j
    assert shapely.covers(area.buffer(1e-6), lines).all()


def test_rectilinear_many_equals_separate_fills():
    # several regions (overlapping, each its own density and role) in one pass give
    # each region's own fill
    area, box = region(), shapely.box(10, 10, 40, 30)
    many = rectilinear_many([area, box, shapely.Polygon()], [20, 100, 50], 30, W, H,
                            [Role.INTERNAL_INFILL, Role.SOLID_INFILL, Role.TOP_SOLID_INFILL])
    alone = rectilinear(area, 20, 30, W, H, Role.INTERNAL_INFILL) + rectilinear(box, 100, 30, W, H, Role.SOLID_INFILL)
    assert [p.role for p in many] == [p.role for p in alone]
    assert all(np.allclose(a.points, b.points, atol=1e-9) for a, b in zip(many, alone))
    assert volume([p for p in many if p.role is Role.SOLID_INFILL]) == pytest.approx(box.area * H, rel=0.05)


@pytest.mark.parametrize("angle", [0, 30, 90])
def test_lines_between_two_slanted_edges_make_one_serpentine(angle):
    """Every link of a fill between two long straight edges runs along one of them (both
    of its ends lie on that edge): all are taken, and the fill is one serpentine."""
    band = shapely.affinity.rotate(shapely.Polygon([(0, 0), (30, 0), (42, 40), (12, 40)]), angle, origin=(0, 0))
    points, chain, _ = line_fill([band], 0.5, angle, W)
    assert len(np.unique(chain)) == 1
    assert len(points) > 150
    grown = band.buffer(1e-6)
    assert grown.covers(shapely.LineString(points))


def test_a_link_across_a_notch_is_refused():
    """Line ends on two different edges with the boundary between them bulging inward
    (a notch) are not linked across it."""
    notched = shapely.box(0, 0, 20, 10).difference(shapely.Polygon([(20, 4.6), (17, 5.1), (20, 5.6)]))
    points, chain, _ = line_fill([notched], 0.4, 0, W)
    notch = shapely.Polygon([(20, 4.6), (17, 5.1), (20, 5.6)]).buffer(-1e-6)
    paths = [shapely.LineString(points[chain == c]) for c in np.unique(chain) if (chain == c).sum() > 1]
    assert not any(path.intersects(notch) for path in paths)
    assert len(paths) == 2  # the lines above the notch and those below it
