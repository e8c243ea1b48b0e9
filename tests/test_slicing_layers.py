"""Placement on the bed and layer heights."""

import numpy as np
import pytest
import shapely

from fgslice.design.base import Design, Material
from fgslice.errors import ResourceError, SliceError
from fgslice.settings import Settings
from fgslice.slicing.field import BedField
from fgslice.slicing.plan_layers import layer_heights, place_design


class Box(Design):
    """Axis-aligned box between ``lo`` and ``hi`` (mm) with f_A = x-fraction of its width."""

    def __init__(self, lo, hi):
        self.lo, self.hi = np.array(lo, float), np.array(hi, float)

    @property
    def materials(self):
        return [Material("a", (1, 0, 0, 1)), Material("b", (0, 0, 1, 1))]

    def sdf(self, x, y, z):
        c, h = (self.lo + self.hi) / 2, (self.hi - self.lo) / 2
        q = np.stack(np.broadcast_arrays(np.abs(x - c[0]) - h[0], np.abs(y - c[1]) - h[1], np.abs(z - c[2]) - h[2]))
        return np.linalg.norm(np.maximum(q, 0), axis=0) + np.minimum(q.max(axis=0), 0)

    def fractions(self, x, y, z):
        x, y, z = np.broadcast_arrays(x, y, z)
        a = np.clip((x - self.lo[0]) / (self.hi[0] - self.lo[0]), 0, 1)
        return np.stack([a, 1 - a], axis=-1)

    def bounds(self):
        return tuple(self.lo), tuple(self.hi)

    def section(self, z):
        if not self.lo[2] < z < self.hi[2]:
            return shapely.MultiPolygon()
        return shapely.MultiPolygon([shapely.box(self.lo[0], self.lo[1], self.hi[0], self.hi[1])])


def test_centered_placement_puts_lowest_point_on_bed():
    design = Box((-5, 10, 3), (15, 20, 7))
    settings = Settings(bed_x=200, bed_y=180)
    placement = place_design(design, settings)
    (x0, y0, z0), (x1, y1, z1) = design.bounds()
    bx, by, bz = placement.to_bed(np.array([x0, x1]), np.array([y0, y1]), np.array([z0, z1]))
    assert bz[0] == pytest.approx(0.0)
    assert bz[1] == pytest.approx(4.0)
    assert (bx.mean(), by.mean()) == pytest.approx((100.0, 90.0))


def test_position_when_not_centered():
    design = Box((-5, -5, -1), (5, 5, 1))
    placement = place_design(design, Settings(center=False, position_x=30, position_y=40))
    assert placement.offset == pytest.approx((30, 40, 1))


def test_bed_field_evaluates_in_design_frame():
    design = Box((0, 0, 0), (10, 10, 10))
    placement = place_design(design, Settings())
    field = BedField(design, placement)
    xy = np.array([[105.0, 110.0], [112.5, 110.0]])  # design x = 0 and 7.5
    assert field.fractions(xy, 5.0)[:, 0] == pytest.approx([0.0, 0.75])
    assert field.sdf(xy, 5.0) == pytest.approx([0.0, -2.5])
    grid = field.fractions_grid(np.array([105.0, 112.5]), np.array([110.0, 111.0, 112.0]), 5.0)
    assert grid.shape == (3, 2, 2) and grid[:, 1, 0] == pytest.approx([0.75] * 3)


@pytest.mark.parametrize(
    "height,expected",
    [(2.0, 10), (2.05, 10), (2.11, 11), (0.25, 1), (0.31, 2), (0.11, 1)],
)
def test_layer_count_rounds_to_nearest_layer(height, expected):
    design = Box((0, 0, 0), (10, 10, height))
    layers = layer_heights(design, Settings(layer_height=0.2))
    assert len(layers) == expected
    assert [i for i, _, _ in layers] == list(range(expected))
    assert [z for _, z, _ in layers] == pytest.approx([(i + 1) * 0.2 for i in range(expected)])
    # every slicing plane (mid-layer) lies inside the part
    assert all(0 < z - h / 2 < height for _, z, h in layers)
    # and the printed height is within half a layer of the part's
    assert abs(layers[-1][1] - height) <= 0.1 + 1e-9


def test_too_thin_part_has_no_layers():
    with pytest.raises(SliceError, match="less than half the layer height"):
        layer_heights(Box((0, 0, 0), (10, 10, 0.05)), Settings(layer_height=0.2))


def test_too_many_layers_is_a_resource_error():
    with pytest.raises(ResourceError, match="layers"):
        layer_heights(Box((0, 0, 0), (10, 10, 4000)), Settings(layer_height=0.02, bead_width=0.4, max_z=5000))


def test_part_larger_than_bed_is_refused_with_numbers():
    with pytest.raises(SliceError) as err:
        place_design(Box((0, 0, 0), (300, 10, 10)), Settings(bed_x=220, bed_y=220))
    assert "300.00 x 10.00" in err.value.message and "220" in err.value.message
    assert "scale" in err.value.hint
    with pytest.raises(SliceError, match="build height"):
        place_design(Box((0, 0, 0), (10, 10, 300)), Settings(max_z=250))


def test_off_bed_position_hints_centering():
    with pytest.raises(SliceError) as err:
        place_design(Box((-20, -20, 0), (20, 20, 5)), Settings(center=False, position_x=5, position_y=100))
    assert "--set center=true" in err.value.hint


def test_bed_field_of_no_points_is_an_empty_table():
    from fgslice.design import api
    from fgslice.slicing.field import BedField
    from fgslice.slicing.layers import Placement

    design = api.design(api.fgrade(["x", "1-x"], ["blue", "yellow"], api.cube(2)))
    field = BedField(design, Placement((0.0, 0.0, 0.0)))
    assert field.fractions(np.zeros((0, 2)), 1.0).shape == (0, 2)
    assert field.fractions(np.array([[0.25, 0.0]]), 0.0) == pytest.approx(np.array([[0.25, 0.75]]))
