"""Outlines of 2D signed fields (fgslice.design.sampled.section_from_sdf)."""

import numpy as np
import pytest
import shapely

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


def test_fine_grid_is_sampled_only_near_the_outline():
    evaluated = []

    def field(x, y):
        evaluated.append(np.size(x))
        return np.hypot(x, y) - 40.0

    section = section_from_sdf(field, (-45, -45, 45, 45), 0.5)
    full_grid = (90 / 0.5 + 3) ** 2
    assert evaluated[0] + evaluated[1] < 0.35 * full_grid  # coarse grid, then the band around the outline
    assert section.area == pytest.approx(np.pi * 1600.0, rel=1e-4)
    small = section_from_sdf(_circle(3.3, -2.1, 0.6), (-10, -10, 10, 10), 0.5)
    assert len(small.geoms) == 1 and small.area == pytest.approx(np.pi * 0.36, rel=0.05)
