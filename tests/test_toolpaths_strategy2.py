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
    pts = np.vstack([p.points for p in lp.paths])
    d = shapely.distance(shapely.points(pts), outline.boundary)
    assert d.min() > W / 2 - 0.02
    outer = [p for p in lp.paths if p.role is Role.EXTERNAL_PERIMETER]
    assert len(outer) == 2  # the outside and the hole
    d_outer = shapely.distance(shapely.points(np.vstack([p.points for p in outer])), outline.boundary)
    assert np.allclose(d_outer, W / 2, atol=0.02)
    assert all(outline.contains(shapely.LineString(p.vertices)) for p in lp.paths)


def test_outermost_loops_on_the_surface_are_external_perimeters():
    outline = box()
    faces = split_faces(outline, 3)
    lp = strategy2.layer_paths(LayerRegions(0, H, H, outline, faces), Settings())
    outer = [p for p in lp.paths if p.role in (Role.EXTERNAL_PERIMETER, Role.PERIMETER)]
    assert len(outer) == 3  # one outermost loop per face, all touching the part surface
    assert all(p.role is Role.EXTERNAL_PERIMETER for p in outer)
    # a face entirely inside the part: its outermost loop is an ordinary perimeter
    inner_face = shapely.box(20, 15, 30, 25)
    ring = shapely.box(10, 10, 40, 30).difference(inner_face)
    lp = strategy2.layer_paths(LayerRegions(0, H, H, outline, (ring, inner_face)), Settings())
    roles = sorted((p.color, p.role.value) for p in lp.paths if p.role in (Role.EXTERNAL_PERIMETER, Role.PERIMETER))
    # the ring's outside runs along the surface, its hole and the inner face do not
    assert roles == [(0, Role.EXTERNAL_PERIMETER.value), (0, Role.PERIMETER.value), (1, Role.PERIMETER.value)]


def gradient_plate(colors):
    """A 60 x 40 mm plate whose faces are the bands of a sin*cos gradient (as slicing makes
    them); at 48 colors the narrowest bands are about 0.8 mm wide and taper to points."""
    from fgslice.slicing.palette import Palette
    from fgslice.slicing.regions import color_faces

    class Field:
        def fractions_grid(self, xs, ys, z):
            x, y = np.meshgrid(xs, ys)
            f = (1 + np.sin(0.04 * x + 0.06 * y) * np.cos(0.06 * x - 0.04 * y)) / 2
            return np.stack([f, 1 - f], axis=-1)

    outline = shapely.MultiPolygon([shapely.box(10, 10, 70, 50)])
    return outline, color_faces(outline, Field(), Palette(2, colors), H / 2, W)


@pytest.mark.parametrize("pattern", ["concentric", "rectilinear"])
@pytest.mark.parametrize("colors", [12, 48])
def test_volume_matches_part_on_gradient_bands(pattern, colors):
    outline, faces = gradient_plate(colors)
    assert sum(1 for f in faces if not f.is_empty) > colors // 2  # many thin, tapering bands
    lp = strategy2.layer_paths(LayerRegions(0, H, H, outline, faces), Settings(fill_pattern=pattern, colors=colors))
    error = volume(lp.paths) / (outline.area * H) - 1
    assert abs(error) < 0.03, error


def test_faces_keep_their_colors_and_stay_inside_them():
    outline = box()
    faces = split_faces(outline, 3)
    lp = strategy2.layer_paths(LayerRegions(0, H, H, outline, faces), Settings())
    assert {p.color for p in lp.paths} == {0, 1, 2}
    for p in lp.paths:
        face = faces[p.color]
        assert face.buffer(-p.width / 2 + 0.02).covers(shapely.LineString(p.vertices))


def test_narrow_parts_reported_uncovered():
    """Without thin features, a part narrower than a bead is left unprinted and reported."""
    body = shapely.box(0, 0, 20, 20)
    sliver = shapely.box(20, 5, 30, 5.3)  # 0.3 mm wide: narrower than a bead
    outline = shapely.MultiPolygon([shapely.union_all([body, sliver])])
    lp = strategy2.layer_paths(LayerRegions(0, H, H, outline, (outline,)), Settings(thin_features=False))
    assert lp.uncovered_mm2 == pytest.approx(3.0, rel=0.05)
    pts = np.vstack([p.points for p in lp.paths])
    assert not np.any(pts[:, 0] > 20.1)


def test_empty_faces():
    outline = box()
    faces = (outline, shapely.Polygon())
    lp = strategy2.layer_paths(LayerRegions(0, H, H, outline, faces), Settings())
    assert {p.color for p in lp.paths} == {0}
