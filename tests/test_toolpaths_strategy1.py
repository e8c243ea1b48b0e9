"""Strategy 1: walls/skins/infill on the outline, cut into colors along the field."""

import numpy as np
import pytest
import shapely

from fgslice.settings import Settings
from fgslice.slicing.layers import LayerRegions
from fgslice.slicing.palette import Palette
from fgslice.toolpaths import strategy1
from fgslice.toolpaths.infill import uncovered_area
from fgslice.toolpaths.strategy1 import summarize_short_pieces
from fgslice.toolpaths.paths import Role, bead_area

W, H = 0.4, 0.2


class LinearField:
    """First material's fraction rises linearly from x0 to x1 (bed frame)."""

    def __init__(self, x0=0.0, x1=60.0):
        self.x0, self.x1 = x0, x1

    def fractions(self, xy, z):
        f = np.clip((xy[:, 0] - self.x0) / (self.x1 - self.x0), 0, 1)
        return np.column_stack([f, 1 - f])


def plate():
    body = shapely.box(0, 0, 60, 40).difference(shapely.Point(30, 20).buffer(6, quad_segs=32))
    return shapely.MultiPolygon([body])


def run(settings, index=3, below=None, above=None, field=None, colors=4, outline=None):
    outline = outline or plate()
    below = [outline] * 3 if below is None else below
    above = [outline] * 3 if above is None else above
    regions = LayerRegions(index, (index + 1) * H, H, outline, ())
    palette = Palette(2, colors)
    return strategy1.layer_paths(regions, below, above, field or LinearField(), palette, settings), palette


def point_at(path, fraction):
    line = shapely.LineString(path.vertices)
    return np.array(line.interpolate(fraction, normalized=True).coords[0])


def test_piece_colors_match_field_and_cuts_sit_on_crossings():
    settings = Settings(strategy=1, walls=3, infill_density=20, min_segment_mm=0)
    (lp, short), palette = run(settings, colors=6)
    field = LinearField()
    assert short is None
    long = [p for p in lp.paths if p.length >= 2 * W]
    mids = np.array([point_at(p, 0.5) for p in long])
    colors = palette.color_of(field.fractions(mids, 0))
    assert np.all(colors == [p.color for p in long])
    # both ends of each piece lie in the piece's color (cut at the crossing, +-0.01 mm)
    for p in long:
        line = shapely.LineString(p.vertices)
        ends = np.array([line.interpolate(0.01).coords[0], line.interpolate(line.length - 0.01).coords[0]])
        assert np.all(palette.color_of(field.fractions(ends, 0)) == p.color)
    assert {p.color for p in lp.paths} == set(range(6))


def test_cutting_keeps_length_and_stays_inside():
    one = Settings(strategy=1, walls=2, infill_density=30, colors=1)
    many = Settings(strategy=1, walls=2, infill_density=30, min_segment_mm=0)
    (lp1, _), _ = run(one, colors=1)
    (lp4, _), _ = run(many, colors=4)
    l1, l4 = sum(p.length for p in lp1.paths), sum(p.length for p in lp4.paths)
    assert l4 == pytest.approx(l1, rel=1e-3)
    outline = plate()
    for p in lp4.paths:
        assert outline.covers(shapely.LineString(p.vertices))
    assert all(p.length >= W - 1e-6 for p in lp4.paths)


def test_walls_and_holes():
    settings = Settings(strategy=1, walls=3, infill_density=0, colors=1)
    (lp, _), _ = run(settings, colors=1)
    walls = [p for p in lp.paths if p.role in (Role.EXTERNAL_PERIMETER, Role.PERIMETER)]
    assert len(walls) == 6  # 3 around the plate, 3 around the hole
    assert sum(p.role is Role.EXTERNAL_PERIMETER for p in walls) == 2
    d = shapely.distance(shapely.points(np.vstack([p.points for p in walls if p.role is Role.EXTERNAL_PERIMETER])), plate().boundary)
    assert np.allclose(d, W / 2, atol=0.02)


def test_skins_from_neighbours():
    settings = Settings(strategy=1, walls=2, infill_density=20, colors=1, top_layers=2, bottom_layers=2)
    outline = plate()
    (middle, _), _ = run(settings, colors=1)
    roles = {p.role for p in middle.paths}
    assert Role.TOP_SOLID_INFILL not in roles and Role.SOLID_INFILL not in roles
    (first, _), _ = run(settings, index=0, below=[], colors=1)
    solid = sum(p.length for p in first.paths if p.role is Role.SOLID_INFILL)
    assert {p.role for p in first.paths} >= {Role.SOLID_INFILL}
    assert Role.INTERNAL_INFILL not in {p.role for p in first.paths}
    (top, _), _ = run(settings, above=[outline], colors=1)
    assert Role.TOP_SOLID_INFILL in {p.role for p in top.paths}
    # a smaller layer above: only the exposed ring is top skin
    small = shapely.box(15, 10, 45, 30)
    (partial, _), _ = run(settings, above=[small, small], colors=1)
    skin = [p for p in partial.paths if p.role is Role.TOP_SOLID_INFILL]
    skin_area = sum(p.length for p in skin) * bead_area(W, H) / H
    inner = outline.buffer(-(W / 2 + 1.5 * (bead_area(W, H) / H)), join_style="mitre")
    expected = inner.difference(small).area
    assert skin_area == pytest.approx(expected, rel=0.05)
    assert solid > 0


def test_sparse_infill_density():
    settings = Settings(strategy=1, walls=2, infill_density=25, colors=1, top_layers=0, bottom_layers=0)
    (lp, _), _ = run(settings, colors=1)
    sparse = [p for p in lp.paths if p.role is Role.INTERNAL_INFILL]
    s = bead_area(W, H) / H
    region = plate().buffer(-(W / 2 + 1.5 * s), join_style="mitre")
    error = sum(p.length for p in sparse) * bead_area(W, H) / (region.area * H * 0.25) - 1
    assert abs(error) < 0.05


def test_short_piece_warning_suggests_a_smaller_palette():
    settings = Settings(strategy=1, walls=2, infill_density=0, min_segment_mm=5)
    (_, short), _ = run(settings, colors=4)
    assert short is None
    (_, short), _ = run(settings, colors=32)
    assert short is not None and short.shortest_mm < 5 and 0 < short.short <= short.total
    # bands of 60/N mm; pieces along x-running walls are ~60/N long: N <= 12 keeps 5 mm
    assert 6 <= short.suggestion <= 12
    (message,) = summarize_short_pieces([short, short], 10, 5, 32)
    assert f"at most {short.suggestion} colors" in message and "on 2 of 10 layers" in message
    assert short.by_kind[0] == short.short  # no infill: all in walls
    assert f"{2 * short.short} in walls" in message
    (_, fewer), _ = run(settings, colors=short.suggestion)
    if fewer:  # only a few grazing pieces (around the hole) may stay short
        assert fewer.short - fewer.grazing <= 0.15 * fewer.total
    # advice that would not help is not given: a palette no smaller than the one in use
    (message,) = summarize_short_pieces([short], 10, 5, short.suggestion)
    assert "palette of at most" not in message


def test_short_pieces_that_graze_a_boundary_get_no_palette_advice():
    """A bar graded along x, 4 colors: the short pieces are infill lines turning next to a
    band edge (the same color on both sides), whatever the palette size."""
    settings = Settings(strategy=1, walls=2, infill_density=20, min_segment_mm=5, top_layers=0, bottom_layers=0)
    for colors in (4, 8):
        (_, short), _ = run(settings, colors=colors)
        assert short is not None and short.grazing > 0
        (message,) = summarize_short_pieces([short], 1, 5, colors)
        if short.grazing == short.short:
            assert "palette of at most" not in message
        assert f"{short.grazing} only graze a color boundary" in message


def test_sparse_sampling_keeps_every_piece_in_its_color_on_a_curved_field():
    """The field is evaluated densely only where colors may change: check that no piece
    of a 10-wall ellipse on the sin*cos field holds another color anywhere inside."""

    class SinCos:
        def fractions(self, xy, z):
            x, y = xy[:, 0] - 70, xy[:, 1] - 90
            f = (1 + np.sin(0.025 * x + 0.0375 * y) * np.cos(0.0375 * x - 0.025 * y)) / 2
            return np.column_stack([f, 1 - f])

    outline = shapely.MultiPolygon([shapely.affinity.scale(shapely.Point(70, 90).buffer(1, quad_segs=64), 60, 80)])
    settings = Settings(strategy=1, walls=10, infill_density=0, top_layers=0, bottom_layers=0, min_segment_mm=0)
    (lp, _), palette = run(settings, outline=outline, field=SinCos(), colors=16, below=[], above=[])
    lines = np.array([shapely.LineString(p.vertices) for p in lp.paths])
    lengths = shapely.length(lines)
    # samples every 0.1 mm, 0.01 mm clear of the ends
    count = np.maximum((lengths / 0.1).astype(int), 2)
    piece = np.repeat(np.arange(len(lines)), count)
    j = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
    along = 0.01 + (lengths[piece] - 0.02) * j / (count[piece] - 1)
    pts = shapely.get_coordinates(shapely.line_interpolate_point(lines[piece], along))
    wrong = palette.color_of(SinCos().fractions(pts, 0)) != np.array([p.color for p in lp.paths])[piece]
    assert len(lp.paths) > 200
    # only stretches shorter than a bead (merged into their neighbour) may hold another color
    assert np.bincount(piece[wrong], minlength=len(lines)).max() * 0.1 < W
    assert wrong.mean() < 1e-3


def test_short_piece_quantile_equals_numpy_quantile():
    """The partial-sort quantile behind the palette suggestion is numpy's default
    (linear) quantile, to the last bit or two, for any count of pieces."""
    from fgslice.toolpaths.strategy1 import _quantile

    rng = np.random.default_rng(5)
    for n in (1, 2, 3, 9, 10, 11, 257, 5000):
        for q in (0.0, 0.1, 0.5, 0.99, 1.0):
            values = rng.exponential(4.0, n)
            assert _quantile(values, q) == pytest.approx(np.quantile(values, q), rel=1e-14, abs=0)


def test_uncovered_area_is_what_no_bead_fits_in():
    """Without thin features, a fin narrower than a bead is left unprinted and reported."""
    fin = shapely.box(60, 10, 70, 10.3)  # 10 mm long, 0.3 mm thick: narrower than a bead
    outline = shapely.MultiPolygon([plate().geoms[0].union(fin)])
    (lp, _), _ = run(Settings(strategy=1, walls=2, infill_density=20, thin_features=False), outline=outline)
    assert lp.uncovered_mm2 == pytest.approx(uncovered_area(outline, W), rel=1e-9)
    assert lp.uncovered_mm2 == pytest.approx(10 * 0.3, rel=0.05)


def test_one_color_palette_keeps_every_path_whole_in_color_0():
    """With one color nothing is cut: each path comes back whole in color 0 (the very
    same path when it has color 0 already), in order."""
    from fgslice.toolpaths.paths import Path

    square = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]])
    paths = [Path(square, Role.PERIMETER, 0, 0.4, 0.2, closed=True), Path(square[:2] + 1, Role.SOLID_INFILL, 3, 0.4, 0.2)]
    cut = strategy1.cut_by_color(paths, None, Palette(1, 1), 0.1, 0, Settings())
    assert cut.paths[0] is paths[0]
    assert cut.paths[1].color == 0 and paths[1].color == 3
    assert np.array_equal(cut.paths[1].points, paths[1].points) and cut.paths[1].role is Role.SOLID_INFILL
