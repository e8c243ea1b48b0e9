"""Strategy 2: dense fills of color faces; volume, inset, uncovered area."""

import numpy as np
import pytest
import shapely

from fgslice.settings import Settings
from fgslice.slicing.layers import LayerRegions
from fgslice.toolpaths import strategy2
from fgslice.toolpaths.paths import Role, bead_area

W, H = 0.4, 0.2


def split_faces(outline, n):
    """n vertical bands of the outline as faces."""
    minx, miny, maxx, maxy = outline.bounds
    xs = np.linspace(minx - 1e-9, maxx + 1e-9, n + 1)
    return tuple(outline.intersection(shapely.box(a, miny - 1, b, maxy + 1)) for a, b in zip(xs[:-1], xs[1:]))


def box():
    return shapely.MultiPolygon([shapely.box(10, 10, 40, 30)])


def tube():
    outer = shapely.Point(60, 60).buffer(15, quad_segs=64)
    return shapely.MultiPolygon([outer.difference(shapely.Point(60, 60).buffer(6, quad_segs=64))])


def volume(paths):
    return sum(p.length * bead_area(p.width, p.height) for p in paths)


@pytest.mark.parametrize("pattern", ["concentric", "rectilinear"])
@pytest.mark.parametrize("shape", [box, tube])
@pytest.mark.parametrize("colors", [1, 3])
def test_volume_matches_part(pattern, shape, colors):
    outline = shape()
    regions = LayerRegions(0, H, H, outline, split_faces(outline, colors))
    lp = strategy2.layer_paths(regions, Settings(fill_pattern=pattern))
    error = volume(lp.paths) / (outline.area * H) - 1
    assert abs(error) < 0.03, error


@pytest.mark.parametrize("pattern", ["concentric", "rectilinear"])
def test_centerlines_half_a_bead_inside(pattern):
    outline = tube()
    regions = LayerRegions(1, 2 * H, H, outline, (outline,))
    lp = strategy2.layer_paths(regions, Settings(fill_pattern=pattern))
    full = [p for p in lp.paths if p.width == W]
    pts = np.vstack([p.points for p in full])
    d = shapely.distance(shapely.points(pts), outline.boundary)
    assert d.min() > W / 2 - 0.02
    outer = [p for p in full if p.role is Role.PERIMETER]
    assert len(outer) == 2  # the outside and the hole
    d_outer = shapely.distance(shapely.points(np.vstack([p.points for p in outer])), outline.boundary)
    assert np.allclose(d_outer, W / 2, atol=0.02)
    assert all(outline.contains(shapely.LineString(p.vertices)) for p in lp.paths)


def test_faces_keep_their_colors_and_stay_inside_them():
    outline = box()
    faces = split_faces(outline, 3)
    lp = strategy2.layer_paths(LayerRegions(0, H, H, outline, faces), Settings())
    assert {p.color for p in lp.paths} == {0, 1, 2}
    for p in lp.paths:
        face = faces[p.color]
        assert face.buffer(-p.width / 2 + 0.02).covers(shapely.LineString(p.vertices))


def test_narrow_parts_reported_uncovered():
    body = shapely.box(0, 0, 20, 20)
    sliver = shapely.box(20, 5, 30, 5.3)  # 0.3 mm wide: narrower than a bead
    outline = shapely.MultiPolygon([shapely.union_all([body, sliver])])
    lp = strategy2.layer_paths(LayerRegions(0, H, H, outline, (outline,)), Settings())
    assert lp.uncovered_mm2 == pytest.approx(3.0, rel=0.05)
    pts = np.vstack([p.points for p in lp.paths])
    assert not np.any(pts[:, 0] > 20.1)


def test_empty_faces():
    outline = box()
    faces = (outline, shapely.Polygon())
    lp = strategy2.layer_paths(LayerRegions(0, H, H, outline, faces), Settings())
    assert {p.color for p in lp.paths} == {0}
