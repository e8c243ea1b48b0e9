"""Outlines of 2D signed fields (fgslice.design.sampled.section_from_sdf)."""

import contourpy
import numpy as np
import pytest
import shapely

from fgslice.design.language import parse_design as load_source
from fgslice.design.sampled import section_from_sdf


def _circle(cx, cy, r):
    return lambda x, y: np.hypot(x - cx, y - cy) - r


def test_circle_area_and_vertices_on_the_circle():
    section = section_from_sdf(_circle(0.3, -0.2, 10.0), (-15, -15, 15, 15), 0.5)
    assert section.is_valid and len(section.geoms) == 1
    assert section.area == pytest.approx(np.pi * 100.0, rel=1e-3)
    xy = shapely.get_coordinates(section)
    assert np.abs(np.hypot(xy[:, 0] - 0.3, xy[:, 1] + 0.2) - 10.0).max() <= 0.01
    assert shapely.is_ccw(section.geoms[0].exterior)


def test_annulus_keeps_its_hole_clockwise():
    field = lambda x, y: np.abs(np.hypot(x, y) - 6.0) - 2.0  # noqa: E731
    section = section_from_sdf(field, (-10, -10, 10, 10), 0.4)
    (polygon,) = section.geoms
    assert len(polygon.interiors) == 1
    assert not shapely.is_ccw(polygon.interiors[0])
    assert section.area == pytest.approx(np.pi * (64.0 - 16.0), rel=1e-3)
    assert not section.contains(shapely.Point(0, 0))


def test_two_islands():
    a, b = _circle(-5, 0, 3), _circle(6, 1, 2)
    section = section_from_sdf(lambda x, y: np.minimum(a(x, y), b(x, y)), (-10, -10, 10, 10), 0.3)
    assert len(section.geoms) == 2
    # chords stay within the 0.01 mm tolerance of the outline: area error <= perimeter * 0.01
    assert section.area == pytest.approx(np.pi * 13.0, abs=2 * np.pi * 5.0 * 0.01)
    assert section.area < np.pi * 13.0


def test_square_corner_error_is_bounded_by_spacing():
    spacing = 0.5
    field = lambda x, y: np.maximum(np.abs(x), np.abs(y)) - 5.0  # noqa: E731
    section = section_from_sdf(field, (-8, -8, 8, 8), spacing)
    square = shapely.box(-5, -5, 5, 5)
    assert section.hausdorff_distance(square) <= spacing / np.sqrt(2)
    assert section.area == pytest.approx(100.0, abs=4 * spacing**2)
    xy = shapely.get_coordinates(section)
    assert np.abs(np.maximum(np.abs(xy[:, 0]), np.abs(xy[:, 1])) - 5.0).max() <= 0.01


def test_positive_field_gives_empty():
    section = section_from_sdf(lambda x, y: np.hypot(x, y) + 1.0, (-5, -5, 5, 5), 0.5)
    assert isinstance(section, shapely.MultiPolygon) and section.is_empty


def test_shape_crossing_the_box_is_clipped_to_it():
    section = section_from_sdf(_circle(0, 0, 10.0), (0, 0, 20, 20), 0.5)
    assert section.is_valid
    assert section.area == pytest.approx(np.pi * 100.0 / 4, rel=2e-3)
    assert shapely.box(0, 0, 20, 20).buffer(1e-9).contains(section)


def test_field_exactly_zero_on_a_grid_line():
    half = section_from_sdf(lambda x, y: y, (-4, -4, 4, 4), 0.5)
    assert half.is_valid
    assert half.area == pytest.approx(32.0, rel=1e-9)
    line = section_from_sdf(lambda x, y: x**2, (-4, -4, 4, 4), 0.5)
    assert line.is_valid and line.area == pytest.approx(0.0, abs=1e-6)


def test_only_a_narrow_band_is_evaluated_even_for_a_flat_field():
    evaluated = []

    def field(x, y):
        evaluated.append(np.column_stack([np.ravel(x), np.ravel(y)]))
        return 0.015 * (np.hypot(x, y) - 40.0)  # slope 0.015 per mm, as a function vase's

    cell = 0.5
    section = section_from_sdf(field, (-45, -45, 45, 45), cell, tolerance=0.005)
    coarse_grid, *fine = evaluated
    assert len(coarse_grid) <= (90 / (4 * cell) + 3) ** 2
    fine = np.concatenate(fine)
    # every later sample (fine nodes, Newton steps, midpoints) lies in a band of a few coarse cells around the outline
    assert np.abs(np.hypot(*fine.T) - 40.0).max() <= 4 * 4 * cell
    assert 0 <= np.pi * 1600.0 - section.area <= 0.005 * section.length
    small = section_from_sdf(_circle(3.3, -2.1, 0.6), (-10, -10, 10, 10), 0.5)
    assert len(small.geoms) == 1 and small.area == pytest.approx(np.pi * 0.36, rel=0.05)


@pytest.mark.parametrize("offset", [0.0, 0.13, 0.25, 0.37])
def test_islands_and_gaps_as_wide_as_the_cell_diagonal_are_kept(offset):
    cell = 0.4
    radius = 0.51 * cell * np.sqrt(2)
    centres = [(-6 + offset, 1.1), (0.2, -3 + offset), (5 + offset / 3, 4 - offset)]
    field = lambda x, y: np.min([np.hypot(x - cx, y - cy) - radius for cx, cy in centres], axis=0)  # noqa: E731
    islands = section_from_sdf(field, (-10, -10, 10, 10), cell)
    assert len(islands.geoms) == 3
    gap = section_from_sdf(lambda x, y: radius - np.abs(x - offset), (-5, -5, 5, 5), cell)  # a slot 2r wide
    assert len(gap.geoms) == 2


def _ellipse_distance(xy, a, b):
    """First-order distance to the ellipse (x/a)^2 + (y/b)^2 = 1 (exact to O(d^2 / radius))."""
    f = np.hypot(xy[:, 0] / a, xy[:, 1] / b) - 1.0
    r = np.hypot(xy[:, 0] / a, xy[:, 1] / b)
    gradient = np.hypot(xy[:, 0] / (a * a * r), xy[:, 1] / (b * b * r))
    return np.abs(f) / gradient


def _edges(polygon_ring):
    xy = np.asarray(polygon_ring.coords)
    return xy[:-1], xy[1:]


def test_function_vase_outline_is_within_5_microns_of_the_analytic_ellipse():
    design = load_source(
        'function((-68,-88,-50),(68,88,50), "sqrt((x/67.5)^2 + (y/87.5)^2) - (0.8 + 0.2*cos(z/16))");'
    )
    for z in (-49.9, -20.0, 0.0, 13.3, 49.9):
        k = 0.8 + 0.2 * np.cos(z / 16)
        section = design.section(z)
        (polygon,) = section.geoms
        assert not polygon.interiors
        start, end = _edges(polygon.exterior)
        assert _ellipse_distance(start, 67.5 * k, 87.5 * k).max() <= 1e-6
        assert _ellipse_distance((start + end) / 2, 67.5 * k, 87.5 * k).max() <= 0.005
        deficit = np.pi * 67.5 * 87.5 * k * k - polygon.area  # chords inside the convex outline
        assert 0 <= deficit <= 0.005 * polygon.length


def test_torus_section_is_an_annulus_within_5_microns():
    big, small = 20.0, 6.0
    design = load_source(f'function((-27,-27,-7),(27,27,7), "(sqrt(x^2+y^2) - {big})^2 + z^2 - {small}^2");')
    for z in (0.0, 3.0, -5.5):
        half = np.sqrt(small**2 - z * z)
        (polygon,) = design.section(z).geoms
        assert len(polygon.interiors) == 1
        for ring, radius in ((polygon.exterior, big + half), (polygon.interiors[0], big - half)):
            start, end = _edges(ring)
            assert np.abs(np.hypot(*start.T) - radius).max() <= 1e-6
            assert np.abs(np.hypot(*((start + end) / 2).T) - radius).max() <= 0.005
        assert polygon.area == pytest.approx(4 * np.pi * big * half, rel=1e-5)


def _gyroid(z):
    return lambda x, y: np.sin(x) * np.cos(y) + np.sin(y) * np.cos(z) + np.sin(z) * np.cos(x)


def _reference(field, box, step=0.02):
    """The region from a dense grid of ``step`` (contourpy), clipped to ``box``."""
    xs = np.arange(box[0] - 2 * step, box[2] + 3 * step, step)
    ys = np.arange(box[1] - 2 * step, box[3] + 3 * step, step)
    values = field(*np.meshgrid(xs, ys))
    generator = contourpy.contour_generator(xs, ys, values, fill_type=contourpy.FillType.OuterCode)
    points, codes = generator.filled(-np.inf, 0.0)
    polygons = [shapely.from_ragged_array(shapely.GeometryType.POLYGON, *_ragged(p, c)) for p, c in zip(points, codes)]
    region = shapely.make_valid(shapely.union_all(np.concatenate(polygons)))
    return shapely.intersection(region, shapely.box(*box))


def _ragged(points, codes):
    starts = np.flatnonzero(codes == 1)
    ring_offsets = np.r_[starts, len(points)]
    return points, (ring_offsets, np.array([0, len(starts)]))


@pytest.mark.parametrize("z", [0.0, 1.3, 2.9, -7.1])
def test_gyroid_matches_a_fine_grid_reference_and_the_box_exactly(z):
    box = (-12.0, -12.0, 12.0, 12.0)
    design = load_source('function((-12,-12,-10),(12,12,10), "sin(x)*cos(y)+sin(y)*cos(z)+sin(z)*cos(x)");')
    section = design.section(z)
    assert section.is_valid
    reference = _reference(_gyroid(z), box)
    assert len(section.geoms) == len(shapely.get_parts(reference))
    assert sum(len(p.interiors) for p in section.geoms) == sum(len(p.interiors) for p in shapely.get_parts(reference))
    # the outlines agree to the reference's own accuracy: area between them below 5 um per mm of outline
    assert shapely.symmetric_difference(section, reference).area <= 0.005 * section.length
    xy = shapely.get_coordinates(section)
    assert (np.abs(xy) <= 12.0).all()
    on_box = np.isclose(np.abs(xy), 12.0, rtol=0, atol=1e-12).any(axis=1)
    assert np.abs(_gyroid(z)(*xy[~on_box].T)).max() <= 1e-6  # inner vertices on the surface
    assert shapely.box(*box).covers(section)
    corners = shapely.points([(-12, -12), (12, -12), (12, 12), (-12, 12)])
    inside_corners = _gyroid(z)(*shapely.get_coordinates(corners).T) < 0
    assert np.array_equal(shapely.intersects(section, corners), inside_corners)


def test_a_crossing_through_infinity_is_found_by_bisection():
    design = load_source('function((-5,-5,-1),(5,5,1), "1/x");')  # inside where x < 0; 1/0 = inf on a node
    section = design.section(0.0)
    assert section.is_valid
    assert section.area == pytest.approx(10 * 5.0, abs=10 * 0.005)  # the 10 mm line within 5 um
