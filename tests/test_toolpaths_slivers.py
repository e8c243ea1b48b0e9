"""Strategy 2: face parts narrower than a bead are given to a neighbouring color."""

import numpy as np
import pytest
import shapely

from fgslice.settings import Settings
from fgslice.slicing.layers import LayerRegions
from fgslice.toolpaths import strategy2
from fgslice.toolpaths.paths import bead_area
from fgslice.toolpaths.slivers import MAX_KEPT_MM2, MIN_SLIVER_SHARE, give_slivers

W, H = 0.4, 0.2


def disc(r):
    return shapely.Point(0, 0).buffer(r, quad_segs=128)


def ring_faces():
    """Hub (color 0, r < 4), a 0.25 mm ring (color 1), the rest of a 10 mm disc (color 2)."""
    return (shapely.MultiPolygon([disc(4)]), shapely.MultiPolygon([disc(4.25).difference(disc(4))]),
            shapely.MultiPolygon([disc(10).difference(disc(4.25))]))


def strips(widths, colors, height=10.0):
    """Vertical strips side by side from x = 0, one face per color (a color may get several)."""
    edges = np.concatenate([[0.0], np.cumsum(widths)])
    faces = [[] for _ in range(max(colors) + 1)]
    for a, b, c in zip(edges[:-1], edges[1:], colors):
        faces[c].append(shapely.box(a, 0, b, height))
    return tuple(shapely.MultiPolygon(shapely.get_parts(shapely.union_all(f))) if f else shapely.MultiPolygon()
                 for f in faces)


def volume(paths):
    return sum(p.length * bead_area(p.width, p.height) for p in paths)


def test_a_ring_goes_to_the_neighbour_along_its_longer_side():
    faces = ring_faces()
    given, area = give_slivers(faces, W)
    assert area == pytest.approx(faces[1].area, rel=1e-6)  # on the 1e-6 mm grid
    assert given[1].is_empty
    assert given[0] is faces[0]  # untouched faces are kept as they are
    assert given[2].area == pytest.approx(faces[1].area + faces[2].area, rel=1e-6)
    assert given[2].covers(faces[1].buffer(-1e-6))
    assert shapely.union_all(given).symmetric_difference(disc(10)).area < 1e-4  # snapped to 1e-6 mm


@pytest.mark.parametrize("pattern", ["concentric", "rectilinear"])
def test_the_ring_is_printed_in_the_outer_color(pattern):
    faces = ring_faces()
    outline = shapely.MultiPolygon([disc(10)])
    lp = strategy2.layer_paths(LayerRegions(0, H, H, outline, faces), Settings(fill_pattern=pattern, colors=3))
    assert lp.reassigned_mm2 == pytest.approx(faces[1].area, rel=1e-6)
    assert lp.uncovered_mm2 < 1e-3
    assert abs(volume(lp.paths) / (outline.area * H) - 1) < 0.03
    assert {p.color for p in lp.paths} == {0, 2}
    # the path nearest the middle of the ring is the outer color's
    middle = shapely.Point(4.125, 0)
    nearest = min(lp.paths, key=lambda p: middle.distance(shapely.LineString(p.vertices)))
    assert nearest.color == 2


def test_slivers_between_slivers_take_the_color_of_the_side_they_touch():
    # wide 0 | 0.2 mm of 1 | 0.2 mm of 2 | 0.2 mm of 3 | wide 4
    faces = strips([5, 0.2, 0.2, 0.2, 5], [0, 1, 2, 3, 4])
    given, area = give_slivers(faces, W)
    assert area == pytest.approx(0.6 * 10, rel=1e-6)
    assert given[1].is_empty and given[2].is_empty and given[3].is_empty
    assert given[0].area == pytest.approx(5.4 * 10, rel=1e-6)  # 1 next to it, then 2 (ties go to the lower color)
    assert given[4].area == pytest.approx(5.2 * 10, rel=1e-6)  # 3 next to it
    assert given[0].covers(shapely.box(5, 0, 5.4, 10).buffer(-1e-6))
    assert given[4].covers(shapely.box(5.4, 0, 5.6, 10).buffer(-1e-6))


def test_a_thin_wall_of_thin_bands_goes_to_its_largest_color_and_is_printed():
    # a 0.7 mm wall cut into bands of 0.2 / 0.3 / 0.2 mm: no band holds a bead, the wall does
    faces = strips([0.2, 0.3, 0.2], [0, 1, 2], height=20)
    given, area = give_slivers(faces, W)
    assert given[0].is_empty and given[2].is_empty
    assert given[1].area == pytest.approx(0.7 * 20, rel=1e-6)
    assert area == pytest.approx(0.4 * 20, rel=1e-6)
    outline = shapely.MultiPolygon([shapely.box(0, 0, 0.7, 20)])
    lp = strategy2.layer_paths(LayerRegions(0, H, H, outline, faces), Settings(colors=3))
    assert {p.color for p in lp.paths} == {1}
    assert abs(volume(lp.paths) / (outline.area * H) - 1) < 0.03


def test_faces_wide_enough_are_left_alone():
    faces = strips([5, 2, 5], [0, 1, 2])
    given, area = give_slivers(faces, W)
    assert area == 0.0
    assert all(a is b for a, b in zip(given, faces))


def test_a_tail_hanging_from_its_own_face_only_stays_with_it():
    # a 0.3 mm tail of color 0 on the part surface: nothing else touches it, nothing to give
    body = shapely.box(0, 0, 20, 20).union(shapely.box(20, 5, 30, 5.3))
    other = shapely.box(-5, 0, 0, 20)
    faces = (shapely.MultiPolygon([body]), shapely.MultiPolygon([other]))
    given, area = give_slivers(faces, W)
    assert area == 0.0 and given[0] is faces[0]
    outline = shapely.MultiPolygon([body.union(other)])
    lp = strategy2.layer_paths(LayerRegions(0, H, H, outline, faces), Settings(colors=2, thin_features=False))
    assert lp.uncovered_mm2 == pytest.approx(3.0, rel=0.05)
    # with thin features, one bead of its own color along it
    lp = strategy2.layer_paths(LayerRegions(0, H, H, outline, faces), Settings(colors=2))
    tail = [p for p in lp.paths if p.points[:, 0].min() > 20]
    assert lp.uncovered_mm2 < 1e-6 and len(tail) == 1 and tail[0].color == 0
    np.testing.assert_allclose(tail[0].points[:, 1], 5.15, atol=1e-6)


def test_a_layer_whose_slivers_are_under_the_share_keeps_them():
    """A 0.25 mm ring of color 1 between a 0.8 mm hub and a disc of 60 mm: 1.4 mm^2, under
    MIN_SLIVER_SHARE and MAX_KEPT_MM2, so no overlay runs and every face stays as it was;
    the same ring on a 10 mm disc (2 % of it) is handed over, and so is a ring of 6.5 mm^2
    around a 4 mm hub on the 60 mm disc (0.1 %, but more than MAX_KEPT_MM2: on a large
    part 1 % of a layer is too much to leave unprinted)."""
    def faces_around(r):
        hub, ring, rest = shapely.MultiPolygon([disc(r)]), disc(r + 0.25).difference(disc(r)), disc(60).difference(disc(r + 0.25))
        return (hub, shapely.MultiPolygon([ring]), shapely.MultiPolygon([rest])), ring.area

    faces, ring = faces_around(0.8)
    assert ring < min(MIN_SLIVER_SHARE * disc(60).area, MAX_KEPT_MM2)
    given, area = give_slivers(faces, W)
    assert area == 0.0 and all(a is b for a, b in zip(given, faces))
    small = ring_faces()
    assert small[1].area > MIN_SLIVER_SHARE * disc(10).area
    assert give_slivers(small, W)[1] > 0
    faces, ring = faces_around(4.0)
    assert MAX_KEPT_MM2 < ring < MIN_SLIVER_SHARE * disc(60).area
    assert give_slivers(faces, W)[1] > 0.9 * ring


def test_a_receiver_touching_the_window_only_along_a_line():
    """A 0.2 mm strip of color 1 between color 0 and a 0.8 mm strip of color 2, with
    color 0 again right behind that strip: color 0's second piece meets the sliver's 2 w
    window only along its edge (the clip is a line, which the overlays must not see)."""
    box = shapely.box
    faces = (shapely.MultiPolygon([box(0, 0, 5, 10), box(6.0, 0, 11, 10)]), shapely.MultiPolygon([box(5, 0, 5.2, 10)]),
             shapely.MultiPolygon([box(5.2, 0, 6.0, 10)]))
    given, area = give_slivers(faces, W)
    assert area == pytest.approx(2.0, rel=1e-6)
    assert given[1].is_empty
    assert shapely.union_all(given).symmetric_difference(box(0, 0, 11, 10)).area < 1e-4
