"""Layer outlines and color faces: coverage, disjointness, analytic areas, colors at points."""

import numpy as np
import pytest
import shapely

from fgslice.design.base import Design, Material
from fgslice.errors import FieldError
from fgslice.settings import Settings
from fgslice.slicing.field import BedField
from fgslice.slicing.layers import Placement
from fgslice.slicing.palette import Palette
from fgslice.slicing.plan_layers import layer_heights, place_design
from fgslice.slicing.regions import slice_layer


class Prism(Design):
    """A vertical prism of a 2D shape (``z`` in ``[0, height]``) with fractions from a callable."""

    def __init__(self, shape, height, fractions):
        self.shape, self.height, self._fractions = shape, height, fractions

    @property
    def materials(self):
        return [Material(f"m{i}", (0, 0, 0, 1)) for i in range(self._fractions(0.0, 0.0).shape[-1])]

    def sdf(self, x, y, z):
        x, y, z = np.broadcast_arrays(x, y, z)
        d = shapely.distance(self.shape.boundary, shapely.points(x, y))
        inside = shapely.contains_xy(self.shape, x, y)
        return np.maximum(np.where(inside, -d, d), np.maximum(-z, z - self.height))

    def fractions(self, x, y, z):
        x, y, _ = np.broadcast_arrays(x, y, z)
        raw = np.clip(self._fractions(x, y), 0, 1)
        return raw / raw.sum(axis=-1, keepdims=True)

    def bounds(self):
        x0, y0, x1, y1 = self.shape.bounds
        return (x0, y0, 0.0), (x1, y1, self.height)

    def section(self, z):
        if not 0 < z < self.height:
            return shapely.MultiPolygon()
        return shapely.MultiPolygon([self.shape])


def linear_x(x0, x1):
    def f(x, y):
        a = (np.asarray(x, float) - x0) / (x1 - x0)
        return np.stack(np.broadcast_arrays(a, 1 - a), axis=-1)

    return f


def radial(r0, r1):
    def f(x, y):
        a = (np.hypot(x, y) - r0) / (r1 - r0)
        return np.stack(np.broadcast_arrays(a, 1 - a), axis=-1)

    return f


def sincos(x, y):
    a = (1 + np.sin(0.025 * x + 0.0375 * y) * np.cos(0.0375 * x - 0.025 * y)) / 2
    return np.stack(np.broadcast_arrays(a, 1 - a), axis=-1)


def three_way(x, y):
    a = np.clip((x + 20) / 40, 0, 1)
    b = (1 - a) * np.clip((y + 20) / 40, 0, 1)
    return np.stack(np.broadcast_arrays(a, b, 1 - a - b), axis=-1)


SETTINGS = Settings(layer_height=0.2, bead_width=0.4, bed_x=300, bed_y=300)
SPACING = SETTINGS.bead_width  # the default grid spacing of the field samples
ANNULUS = shapely.Point(0, 0).buffer(30, quad_segs=512).difference(shapely.Point(0, 0).buffer(8, quad_segs=512))
ELLIPSE = shapely.affinity.scale(shapely.Point(0, 0).buffer(1.0, quad_segs=64), 67.5, 87.5, origin=(0, 0))


def first_layer(design, palette, **kw):
    placement = place_design(design, SETTINGS)
    index, z_top, h = layer_heights(design, SETTINGS)[0]
    return slice_layer(design, placement, palette, index, z_top, h, SETTINGS, **kw), placement


def assert_partition(regions, rel=0.005, n=4000, seed=2):
    """Faces lie in the outline, their areas add up to it, and sampled points are covered once."""
    faces = np.array(regions.faces, dtype=object)
    assert shapely.area(faces).sum() == pytest.approx(regions.outline.area, rel=rel)
    assert np.all(shapely.area(shapely.difference(faces, regions.outline)) < 1e-6 * regions.outline.area)
    x0, y0, x1, y1 = regions.outline.bounds
    rng = np.random.default_rng(seed)
    x, y = rng.uniform(x0, x1, n), rng.uniform(y0, y1, n)
    inside = shapely.contains_xy(regions.outline, x, y)
    covered = sum(shapely.contains_xy(f, x[inside], y[inside]).astype(int) for f in faces)
    assert np.all(covered == 1)


def assert_colors_at_points(regions, placement, design, palette, spacing, n=4000, seed=1):
    """Points inside a face farther than one grid spacing from its boundary have its color."""
    x0, y0, x1, y1 = regions.outline.bounds
    rng = np.random.default_rng(seed)
    xy = np.column_stack([rng.uniform(x0, x1, n), rng.uniform(y0, y1, n)])
    field = BedField(design, placement)
    expected = palette.color_of(field.fractions(xy, regions.z_plane))
    checked = 0
    for color, face in enumerate(regions.faces):
        inside = shapely.contains_xy(face, xy[:, 0], xy[:, 1])
        far = shapely.distance(face.boundary, shapely.points(xy[inside])) > spacing
        assert np.all(expected[inside][far] == color)
        checked += far.sum()
    assert checked > 0.2 * n * regions.outline.area / ((x1 - x0) * (y1 - y0))


def test_outline_is_translated_to_bed_frame():
    design = Prism(shapely.box(-10, -5, 10, 5), 1.0, linear_x(-10, 10))
    regions, placement = first_layer(design, Palette(2, 4))
    assert regions.outline.bounds == pytest.approx((140, 145, 160, 155))
    assert regions.z == pytest.approx(0.2) and regions.z_plane == pytest.approx(0.1)
    assert placement.offset[2] == pytest.approx(0.0)


@pytest.mark.parametrize("n", [1, 4, 10])
def test_linear_gradient_gives_equal_strips(n):
    design = Prism(shapely.box(-20, -5, 20, 5), 1.0, linear_x(-20, 20))
    palette = Palette(2, n)
    regions, placement = first_layer(design, palette)
    assert len(regions.faces) == n
    assert_partition(regions)
    for j, face in enumerate(regions.faces):
        assert face.area == pytest.approx(400 / n, rel=1e-3)
        x0, _, x1, _ = face.bounds
        assert (x0, x1) == pytest.approx((130 + 40 * j / n, 130 + 40 * (j + 1) / n), abs=1e-6)
    assert_colors_at_points(regions, placement, design, palette, SPACING)


def test_radial_gradient_gives_annuli_with_holes():
    design = Prism(ANNULUS, 1.0, radial(8, 30))
    palette = Palette(2, 6)
    regions, placement = first_layer(design, palette)
    assert_partition(regions)
    radii = 8 + 22 * np.arange(7) / 6
    for j, face in enumerate(regions.faces):
        assert face.area == pytest.approx(np.pi * (radii[j + 1] ** 2 - radii[j] ** 2), rel=0.01)
        parts = shapely.get_parts(face)
        assert len(parts) == 1 and len(parts[0].interiors) == 1  # an annulus: one ring with a hole
    assert_colors_at_points(regions, placement, design, palette, SPACING)


def test_palette_plate_many_colors_is_a_partition():
    design = Prism(ELLIPSE, 0.4, sincos)
    palette = Palette(2, 48)
    regions, placement = first_layer(design, palette)
    assert_partition(regions)
    assert sum(not f.is_empty for f in regions.faces) > 40
    assert_colors_at_points(regions, placement, design, palette, SPACING, n=3000)


def test_steep_field_uses_exact_levels():
    """A field that crosses several bands between neighbouring samples still gives correct faces."""

    def steep(x, y):
        a = 0.5 + 0.5 * np.tanh(np.asarray(x, float) / 0.5)
        return np.stack(np.broadcast_arrays(a, 1 - a), axis=-1)

    design = Prism(shapely.box(-10, -10, 10, 10), 1.0, steep)
    palette = Palette(2, 8)
    regions, placement = first_layer(design, palette, spacing=0.1)
    assert_partition(regions)
    assert_colors_at_points(regions, placement, design, palette, 0.1)
    # color 4 is 1/2 <= f < 5/8, i.e. 0 <= x < 0.5 atanh(1/4) (design frame; bed x = design x + 150)
    x0, _, x1, _ = regions.faces[4].bounds
    assert (x0 - 150, x1 - 150) == pytest.approx((0.0, 0.5 * np.arctanh(0.25)), abs=0.01)


def test_constant_mixture_on_a_level_is_one_color():
    def half(x, y):
        a = np.full(np.shape(x), 0.5)
        return np.stack([a, 1 - a], axis=-1)

    design = Prism(shapely.box(-10, -10, 10, 10), 1.0, half)
    regions, _ = first_layer(design, Palette(2, 4))
    assert regions.faces[2].area == pytest.approx(400)
    assert all(regions.faces[c].is_empty for c in (0, 1, 3))


@pytest.mark.parametrize("n", [4, 9])
def test_three_material_faces(n):
    design = Prism(shapely.box(-20, -20, 20, 20).difference(shapely.Point(0, 0).buffer(5)), 1.0, three_way)
    palette = Palette(3, n)
    regions, placement = first_layer(design, palette)
    assert_partition(regions)
    assert_colors_at_points(regions, placement, design, palette, SPACING)
    # f_A alone decides the row: rows of cells have the analytic area of their f_A strip
    m = palette.subdivisions
    rows = np.bincount(palette.cells[:, 0], weights=[f.area for f in regions.faces], minlength=m)
    strip = shapely.box(-20, -20, 20, 20).difference(shapely.Point(0, 0).buffer(5, quad_segs=64))
    for a in range(m):
        band = shapely.box(-20 + 40 * a / m, -20, -20 + 40 * (a + 1) / m, 20)
        assert rows[a] == pytest.approx(strip.intersection(band).area, rel=0.01)


def test_empty_section_gives_empty_faces():
    design = Prism(shapely.box(-10, -10, 10, 10), 1.0, linear_x(-10, 10))
    regions = slice_layer(design, Placement((100, 100, 0)), Palette(2, 4), 9, 2.0, 0.2, SETTINGS)
    assert regions.outline.is_empty
    assert len(regions.faces) == 4 and all(f.is_empty for f in regions.faces)


def test_non_finite_fractions_are_reported():
    def broken(x, y):
        a = np.where(np.asarray(x) > 3, np.nan, 0.5)
        return np.stack(np.broadcast_arrays(a, 1 - a), axis=-1)

    design = Prism(shapely.box(-10, -10, 10, 10), 1.0, broken)
    with pytest.raises(FieldError, match="not finite"):
        first_layer(design, Palette(2, 4))
