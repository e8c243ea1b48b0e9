"""Zippers on the paper's sin*cos XY gradient over a 150 x 150 mm plate."""

import numpy as np
import pytest
import shapely

from fgslice.settings import Settings
from fgslice.slicing.layers import LayerRegions
from fgslice.slicing.palette import Palette
from fgslice.toolpaths import strategy1
from fgslice.toolpaths.paths import Role

W, H = 0.4, 0.2
BETA = 12.0


class SinCosField:
    """The paper's gradient: f = (1 + sin(0.02x + 0.03y) cos(0.03x - 0.02y)) / 2."""

    def fractions(self, xy, z):
        x, y = xy[:, 0], xy[:, 1]
        f = (1 + np.sin(0.02 * x + 0.03 * y) * np.cos(0.03 * x - 0.02 * y)) / 2
        return np.column_stack([f, 1 - f])


PLATE = shapely.MultiPolygon([shapely.box(0, 0, 150, 150)])
FIELD = SinCosField()
PALETTE = Palette(2, 6)


def layer(index, zipper=BETA, walls=3, density=0):
    settings = Settings(strategy=1, walls=walls, infill_density=density, zipper=zipper, top_layers=0,
                        bottom_layers=0, min_segment_mm=3, infill_angle=0)
    regions = LayerRegions(index, (index + 1) * H, H, PLATE, ())
    lp, _ = strategy1.layer_paths(regions, [PLATE], [PLATE], FIELD, PALETTE, settings)
    return lp.paths


def midpoints(paths):
    return np.array([shapely.LineString(p.vertices).interpolate(0.5, normalized=True).coords[0] for p in paths])


@pytest.fixture(scope="module")
def walls_k():
    return layer(4)


@pytest.fixture(scope="module")
def walls_k1():
    return layer(5)


def test_colors_outside_and_inside_bands(walls_k):
    pieces = [p for p in walls_k if p.length >= 2 * W]
    f = FIELD.fractions(midpoints(pieces), 0)
    color = PALETTE.color_of(f)
    neighbor = PALETTE.zipper_neighbor(f, BETA)
    got = np.array([p.color for p in pieces])
    out = neighbor < 0
    assert out.sum() > 20 and (~out).sum() > 20
    assert np.all(got[out] == color[out])
    assert np.all((got[~out] == color[~out]) | (got[~out] == neighbor[~out]))
    # both colors of each boundary are used inside its band
    assert np.mean(got[~out] == neighbor[~out]) > 0.3
    assert np.mean(got[~out] == color[~out]) > 0.3


def test_in_band_pieces_alternate_along_walls(walls_k):
    outer = [p for p in walls_k if p.role is Role.EXTERNAL_PERIMETER]
    # walk the outer wall: pieces in order of where they start along the wall
    ring = shapely.LinearRing(shapely.box(0, 0, 150, 150).buffer(-W / 2, join_style="mitre").exterior)
    start = np.array([ring.project(shapely.Point(p.points[0])) for p in outer])
    pieces = [outer[i] for i in np.argsort(start)]
    f = FIELD.fractions(midpoints(pieces), 0)
    in_band = PALETTE.zipper_neighbor(f, BETA) >= 0
    colors = np.array([p.color for p in pieces])
    pairs = in_band[1:] & in_band[:-1]
    assert pairs.sum() >= 5
    assert np.all(colors[1:][pairs] != colors[:-1][pairs])


def test_alternation_flips_between_layers(walls_k, walls_k1):
    def in_band_colors(paths):
        pieces = [p for p in paths if p.role is Role.EXTERNAL_PERIMETER and p.length >= 2 * W]
        mids = midpoints(pieces)
        band = PALETTE.zipper_neighbor(FIELD.fractions(mids, 0), BETA) >= 0
        return mids[band], np.array([p.color for p in pieces])[band]

    m0, c0 = in_band_colors(walls_k)
    m1, c1 = in_band_colors(walls_k1)
    # match pieces of the two layers by position
    d = np.hypot(*(m0[:, None, :] - m1[None, :, :]).transpose(2, 0, 1))
    j = d.argmin(axis=1)
    close = d[np.arange(len(m0)), j] < 0.5
    assert close.sum() >= 5
    assert np.all(c0[close] != c1[j[close]])


def test_infill_lines_alternate_in_bands():
    paths = layer(4, walls=1, density=15)
    lines = [p for p in paths if p.role is Role.INTERNAL_INFILL]
    # in-band pieces of x-parallel lines (angle 0): consecutive lines in y alternate color
    segs = [p for p in lines if np.ptp(p.points[:, 1]) < 1e-6 and p.length > 2 * W]
    mids = midpoints(segs)
    f = FIELD.fractions(mids, 0)
    band = PALETTE.zipper_neighbor(f, BETA) >= 0
    pair = np.sort(np.column_stack([PALETTE.color_of(f), PALETTE.zipper_neighbor(f, BETA)]), axis=1)
    colors = np.array([p.color for p in segs])
    checked = 0
    spacing = np.diff(np.unique(np.round(mids[:, 1], 6))).min()
    for lo, hi in {tuple(x) for x in pair[band]}:
        sel = np.flatnonzero(band & (pair[:, 0] == lo) & (pair[:, 1] == hi))
        for a in sel:
            # the in-band piece of the same boundary on the next line up, nearby in x
            b = sel[np.isclose(mids[sel, 1], mids[a, 1] + spacing, atol=1e-6) & (np.abs(mids[sel, 0] - mids[a, 0]) < 3)]
            for j in b:
                checked += 1
                assert colors[a] != colors[j]
    assert checked >= 5


def test_zipper_off_matches_field_everywhere():
    paths = layer(4, zipper=0)
    pieces = [p for p in paths if p.length >= 2 * W]
    color = PALETTE.color_of(FIELD.fractions(midpoints(pieces), 0))
    assert np.all(color == [p.color for p in pieces])
