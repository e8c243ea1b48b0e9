"""Skins: the inner area split into top, solid and sparse by the neighbouring outlines."""

import numpy as np
import pytest
import shapely

from fgslice.settings import Settings
from fgslice.toolpaths.skins import covered, split_inner
from fgslice.toolpaths.walls import make_walls

W, H = 0.4, 0.2


def plate():
    return shapely.MultiPolygon([shapely.box(0, 0, 60, 40).difference(shapely.Point(30, 20).buffer(6, quad_segs=32))])


def split(below, above, density=20.0, **anchoring):
    outline = plate()
    inner = make_walls(outline, 2, W, H).inner
    settings = Settings(strategy=1, walls=2, infill_density=density, top_layers=2, bottom_layers=2, **anchoring)
    return inner, split_inner(inner, outline, below, above, settings)


def areas(split_areas):
    return np.array([split_areas.top.area, split_areas.solid.area, split_areas.sparse.area])


def test_inside_a_part_everything_is_sparse():
    inner, got = split([plate()] * 2, [plate()] * 2)
    assert got.top.is_empty and got.solid.is_empty
    assert got.sparse.equals(inner)


def test_parts_partition_the_inner_area_by_the_neighbours():
    small = shapely.box(15, 5, 45, 35)  # smaller layers above: a top ring
    shifted = shapely.box(-5, -5, 40, 45)  # shifted layers below: a bottom strip
    inner, got = split([plate(), shifted], [small, small], skin_margin=0.0, sparse_min_width=0.0)
    top, solid, sparse = areas(got)
    assert top + solid + sparse == pytest.approx(inner.area, rel=1e-9)
    assert shapely.union_all([got.top, got.solid, got.sparse]).symmetric_difference(inner).area < 1e-6
    assert top == pytest.approx(inner.difference(small).area, rel=1e-6)
    assert sparse == pytest.approx(inner.intersection(small).intersection(shifted).area, rel=1e-6)
    assert solid == pytest.approx(inner.intersection(small).difference(shifted).area, rel=1e-6)
    assert solid > 10 and top > 10 and sparse > 10


def test_missing_layers_make_everything_skin():
    inner, got = split([], [plate()] * 2)  # first layer: all bottom skin
    assert got.solid.equals(inner) and got.top.is_empty and got.sparse.is_empty
    inner, got = split([plate()] * 2, [plate()])  # one layer below the top: all top skin
    assert got.top.equals(inner) and got.solid.is_empty and got.sparse.is_empty


def test_full_density_is_solid_below_the_top_skin():
    small = shapely.box(15, 5, 45, 35)
    inner, got = split([], [small, small], density=100.0)
    assert got.sparse.is_empty
    assert got.top.area == pytest.approx(inner.difference(small).area, rel=1e-6)
    assert got.solid.area == pytest.approx(inner.intersection(small).area, rel=1e-6)


def test_covered_counts_only_the_nearest_layers():
    region = shapely.box(0, 0, 10, 10)
    assert covered(region, [shapely.box(0, 0, 5, 10), shapely.Polygon()], 1).area == pytest.approx(50)
    assert covered(region, [region, shapely.box(0, 0, 5, 10)], 1) is region
    assert covered(region, [region], 0) is region
    assert covered(region, [region], 2).is_empty


def test_covered_is_the_region_within_every_neighbour_that_does_not_cover_it():
    region = shapely.box(0, 0, 10, 10)
    wide, left, lower = shapely.box(-5, -5, 15, 15), shapely.box(-1, -1, 6, 11), shapely.box(-1, -1, 11, 4)
    part = covered(region, [wide, left, lower], 3)
    assert part.equals(shapely.box(0, 0, 6, 4))
    assert covered(region, [wide, left], 2).equals(shapely.box(0, 0, 6, 10))
    assert covered(region, [wide, wide], 2) is region


def test_skins_extend_into_the_sparse_area_by_the_margin():
    small = shapely.box(15, 5, 45, 35)  # smaller layers above: a top ring around it
    inner, plain = split([plate()] * 2, [small, small], skin_margin=0.0, sparse_min_width=0.0)
    _, got = split([plate()] * 2, [small, small], skin_margin=1.5, sparse_min_width=0.0)
    assert got.top.equals(plain.top)  # the exposed skin stays top skin
    grown = plain.sparse.intersection(plain.top.buffer(1.5))
    assert got.solid.area == pytest.approx(plain.solid.area + grown.area, rel=1e-6)
    assert got.sparse.area == pytest.approx(plain.sparse.area - grown.area, rel=1e-6)
    # no sparse point within the margin of the top skin
    assert shapely.distance(got.sparse, plain.top) == pytest.approx(1.5, abs=1e-3)
    assert shapely.union_all([got.top, got.solid, got.sparse]).symmetric_difference(inner).area < 1e-6


def test_sparse_strips_too_narrow_for_infill_become_solid():
    # the layers above leave a 1.5 mm slot open (top skin) 2.8 mm inside the walls
    above = shapely.box(-1, -1, 61, 41).difference(shapely.box(3.5, 5, 5.0, 35))
    inner, slot = split([plate()] * 2, [above] * 2, skin_margin=0.0, sparse_min_width=2.0)
    strip = inner.intersection(shapely.box(3.5, 5, 5.0, 35))
    assert slot.top.symmetric_difference(strip).area < 1e-6
    _, got = split([plate()] * 2, [above] * 2, skin_margin=0.0, sparse_min_width=4.0)
    # the sparse strip between the slot and the walls (x 0.74-3.5, 2.8 mm wide) is
    # narrower than 4 mm and becomes solid; the wide rest stays sparse
    assert slot.solid.is_empty  # 2 mm: wide enough
    left = inner.intersection(shapely.box(-1, 7, 3.5, 33))
    assert got.solid.covers(left)
    assert got.sparse.area == pytest.approx(inner.area - strip.area - got.solid.area, rel=1e-6)
    assert got.sparse.area > 0.8 * inner.area


def test_a_layer_without_skins_and_without_narrow_parts_is_unchanged():
    inner, got = split([plate()] * 2, [plate()] * 2)
    assert got.sparse.equals(inner) and got.top.is_empty and got.solid.is_empty
