"""palette = ends: colors on the simplex lattice with the pure materials, nearest color per
face; checked on the palette itself, on traced faces and on sliced G-code."""

from __future__ import annotations

from math import comb

import numpy as np
import pytest
import shapely

from fgslice.design import api
from fgslice.errors import SettingsError
from fgslice.machine.gcode_reader import read_gcode
from fgslice.pipeline import slice_to_gcode
from fgslice.settings import load_settings
from fgslice.slicing.palette import Palette
from fgslice.slicing.regions import color_faces


def _simplex_points(n: int, k: int, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).dirichlet(np.ones(k), size=n)


def _nearest(points: np.ndarray, centers: np.ndarray) -> np.ndarray:
    """Squared distance of each point to its nearest center, by brute force."""
    return ((points[:, None, :] - centers[None, :, :]) ** 2).sum(axis=-1).min(axis=1)


@pytest.mark.parametrize("n", [2, 3, 4, 5, 11])
def test_two_materials_color_k_of_n_is_k_over_n_minus_1(n):
    pal = Palette(2, n, "ends")
    assert np.allclose(pal.centers[:, 0], np.arange(n) / (n - 1))
    assert np.allclose(pal.centers.sum(axis=1), 1.0)
    f0 = np.linspace(0, 1, 2001)
    colors = pal.color_of(np.stack([f0, 1 - f0], axis=1))
    off_edge = np.abs(f0 * (n - 1) - np.floor(f0 * (n - 1)) - 0.5) > 1e-6
    assert np.array_equal(colors[off_edge], np.rint(f0 * (n - 1))[off_edge])
    assert colors[0] == 0 and colors[-1] == n - 1  # the pure materials


@pytest.mark.parametrize("k, n", [(3, 3), (3, 6), (3, 10), (3, 15), (4, 4), (4, 10), (4, 20)])
def test_lattice_with_vertices_and_nearest_color(k, n):
    pal = Palette(k, n, "ends")
    q = pal.subdivisions
    assert n == comb(q + k - 1, k - 1)
    assert np.allclose(pal.centers * q, np.rint(pal.centers * q)) and np.allclose(pal.centers.sum(axis=1), 1)
    for i in range(k):  # every pure material is a color
        assert any(np.allclose(c, np.eye(k)[i]) for c in pal.centers)
    pts = _simplex_points(20000, k)
    colors = pal.color_of(pts)
    own = ((pts - pal.centers[colors]) ** 2).sum(axis=1)
    assert np.allclose(own, _nearest(pts, pal.centers), atol=1e-12)
    assert np.array_equal(pal.color_of(pal.centers), np.arange(n))


@pytest.mark.parametrize("k, n", [(3, 6), (3, 10), (4, 10)])
def test_consecutive_colors_are_lattice_neighbours(k, n):
    pal = Palette(k, n, "ends")
    steps = np.abs(np.diff(pal.cells, axis=0)).sum(axis=1)
    assert np.all(steps == 2)  # t + e_i - e_j: their cells share a facet


@pytest.mark.parametrize("k, n, allowed", [(3, 4, "3, 6, 10, 15"), (3, 9, "3, 6, 10, 15"), (4, 5, "4, 10, 20, 35"),
                                          (2, 1, "any N >= 2")])
def test_other_sizes_are_refused_naming_the_allowed_ones(k, n, allowed):
    with pytest.raises(SettingsError) as err:
        Palette(k, n, "ends")
    assert allowed in str(err.value) and "--set colors=" in str(err.value)


def test_unknown_kind_is_refused():
    with pytest.raises(SettingsError, match="palette"):
        Palette(2, 4, "corners")
    with pytest.raises(Exception, match="palette"):
        load_settings(None, {"palette": "corners"})


@pytest.mark.parametrize("k, n", [(2, 4), (3, 6), (3, 10)])
def test_zipper_neighbour_is_the_color_across_the_nearest_facet(k, n):
    pal = Palette(k, n, "ends")
    pts = _simplex_points(20000, k, seed=1)
    colors = pal.color_of(pts)
    beta = 10.0
    neighbor = pal.zipper_neighbor(pts, beta)
    has = neighbor >= 0
    assert 0.02 < has.mean() < 0.8
    # a neighbour is an adjacent lattice point, and the point is nearly as close to it
    assert np.all(np.abs(pal.cells[neighbor[has]] - pal.cells[colors[has]]).sum(axis=1) == 2)
    d_own = np.sqrt(((pts[has] - pal.centers[colors[has]]) ** 2).sum(axis=1))
    d_other = np.sqrt(((pts[has] - pal.centers[neighbor[has]]) ** 2).sum(axis=1))
    half_step = np.sqrt(2) / pal.subdivisions  # distance between neighbouring lattice points
    assert np.all(d_other - d_own <= 2 * np.sqrt(2) * beta / 200 * half_step * pal.subdivisions + 1e-9)
    # the pure materials' own corners are no boundary
    assert np.all(pal.zipper_neighbor(np.eye(k), beta) == -1)


class _Field:
    """Three-material fractions varying linearly across a 60 x 60 mm plate (bed frame)."""

    def fractions_grid(self, xs, ys, z):
        x, y = np.meshgrid(xs, ys)
        return self.at(x, y)

    def fractions(self, points, z):
        return self.at(points[:, 0], points[:, 1])

    @staticmethod
    def at(x, y):
        a = np.clip(x / 60, 0, 1) * np.clip(1 - y / 60, 0, 1)
        b = np.clip(1 - x / 60, 0, 1) * np.clip(1 - y / 60, 0, 1)
        return np.stack([a, b, 1 - a - b], axis=-1)


@pytest.mark.parametrize("n", [6, 10])
def test_three_material_faces_are_the_nearest_colors(n):
    pal = Palette(3, n, "ends")
    outline = shapely.MultiPolygon([shapely.box(0, 0, 60, 60)])
    faces = color_faces(outline, _Field(), pal, 0.1, 0.4)
    assert sum(f.area for f in faces) == pytest.approx(3600, rel=1e-9)
    assert shapely.union_all(faces).symmetric_difference(outline).area < 1e-6
    xs, ys = np.meshgrid(np.arange(0.5, 60, 0.7), np.arange(0.5, 60, 0.7))
    pts = np.column_stack([xs.ravel(), ys.ravel()])
    expected = pal.color_of(_Field.at(pts[:, 0], pts[:, 1]))
    points = shapely.points(pts)
    checked = 0
    for c, face in enumerate(faces):
        inside = shapely.contains(face.buffer(-0.4), points)  # a spacing away from its boundary
        assert np.all(expected[inside] == c)
        checked += inside.sum()
    assert checked > 0.8 * len(pts)


def _slice(design, tmp_path, **overrides):
    settings = load_settings(None, {"skirt_loops": "0", "palette": "ends", **{k: str(v) for k, v in overrides.items()}})
    out = tmp_path / "part.gcode"
    slice_to_gcode(design, settings, out, jobs=1)
    return settings, read_gcode(out)


def _commanded(program, k):
    """Per printing move of the part: the mixture the G-code's mixing command sets, and the
    move's midpoint (purge tower moves left out: they flush the previous state)."""
    mixes = np.array([s.mix_fractions(k) if s.mix else np.full(k, np.nan) for s in program.states])
    tower = np.array([name == "Wipe tower" for name in program.roles] + [False])[program.role]
    moves = (program.e > 0) & (program.length > 0) & ~tower
    assert not np.isnan(mixes[program.state[moves]]).any()
    return mixes[program.state[moves]], (program.start[moves] + program.end[moves]) / 2


@pytest.mark.parametrize("strategy", [1, 2])
def test_two_pure_boxes_print_pure(tmp_path, strategy):
    boxes = api.union(api.translate((-8, 0, 0), api.rectprism(10, 10, 2, material="red")),
                      api.translate((8, 0, 0), api.rectprism(10, 10, 2, material="blue")))
    settings, program = _slice(api.design(boxes), tmp_path, colors=4, strategy=strategy)
    mix, _ = _commanded(program, 2)
    assert len(mix) > 100
    pure = np.isclose(mix, 0, atol=1e-4) | np.isclose(mix, 1, atol=1e-4)
    assert pure.all()  # 100/0 and 0/100, no 93.75/6.25 mixes
    assert {tuple(np.rint(m)) for m in mix} == {(1.0, 0.0), (0.0, 1.0)}


def test_three_materials_get_three_pure_colors(tmp_path):
    part = api.union(api.translate((-12, 0, 0), api.cylinder(5, 2, material="red")),
                     api.cylinder(5, 2, material="green"),
                     api.translate((12, 0, 0), api.cylinder(5, 2, material="blue")))
    settings, program = _slice(api.design(part), tmp_path, colors=3, channels=3)
    mix, mid = _commanded(program, 3)
    offset_x = mid[:, 0] - settings.bed_x / 2
    for x, material in ((-12, 0), (0, 1), (12, 2)):
        near = np.abs(offset_x - x) < 4
        assert near.sum() > 10 and np.allclose(mix[near], np.eye(3)[material], atol=1e-4)


@pytest.mark.parametrize("strategy", [1, 2])
@pytest.mark.parametrize("k, n", [(2, 5), (3, 6)])
def test_commanded_mixture_is_the_nearest_lattice_color_of_the_field(tmp_path, strategy, k, n):
    if k == 2:
        tree = api.fgrade(["x/40 + 0.5", "0.5 - x/40"], ["red", "blue"], api.rectprism(40, 20, 1))
    else:
        tree = api.fgrade(["(x+20)/40 * (10-y)/20", "(20-x)/40 * (10-y)/20", "(y+10)/20"], ["red", "green", "blue"],
                          api.rectprism(40, 20, 1))
    design = api.design(tree)
    settings, program = _slice(design, tmp_path, colors=n, channels=k, strategy=strategy)
    pal = Palette(k, n, "ends")
    mix, mid = _commanded(program, k)
    (x0, y0, z0), (x1, y1, _) = design.bounds()
    local = mid - [settings.bed_x / 2 - (x0 + x1) / 2, settings.bed_y / 2 - (y0 + y1) / 2, -z0]
    local[:, 2] -= settings.layer_height / 2
    field = design.fractions(local[:, 0], local[:, 1], local[:, 2])
    expected = pal.centers[pal.color_of(field)]
    # away from the boundaries between colors (where a move may straddle two), exactly the nearest color
    step = 1 / pal.subdivisions
    d = np.sqrt(((field[:, None, :] - pal.centers[None]) ** 2).sum(-1))
    d.sort(axis=1)
    clear = d[:, 1] - d[:, 0] > 0.3 * step
    assert clear.mean() > 0.3
    assert np.allclose(mix[clear], expected[clear], atol=1e-4)
    assert {tuple(np.round(m, 3)) for m in mix} <= {tuple(np.round(c, 3)) for c in pal.centers}


def test_header_records_the_palette_for_the_simulator_and_viewer(tmp_path):
    from fgslice.analysis.simulate import simulate
    from fgslice.machine.gcode_header import read_header
    from fgslice.preview.viewer import _palette_centers

    boxes = api.union(api.translate((-8, 0, 0), api.rectprism(10, 10, 1, material="red")),
                      api.translate((8, 0, 0), api.rectprism(10, 10, 1, material="blue")))
    design = api.design(boxes)
    settings = load_settings("toolchanger", {"skirt_loops": "0", "palette": "ends", "colors": "4", "tool_count": "4"})
    out = tmp_path / "part.gcode"
    slice_to_gcode(design, settings, out, jobs=1)
    header = read_header(out)
    assert header.palette == "ends"
    assert np.allclose(_palette_centers(header, 2), Palette(2, 4, "ends").centers)
    # simulated with the profile's default (centers), the file's palette is what counts
    result = simulate(out, design, None, load_settings("toolchanger"))
    assert {tuple(np.rint(c)) for c in result.commanded} == {(1.0, 0.0), (0.0, 1.0)}
    assert np.allclose(result.commanded, np.rint(result.commanded))


def test_thresh_grade_of_three_materials_prints_only_pure_materials(tmp_path):
    tree = api.fgrade(["rho/8", "1-rho/8", "y/6"], ["red", "green", "blue"], api.cylinder(10, 1), mode="thresh")
    design = api.design(tree)
    settings, program = _slice(design, tmp_path, colors=6, channels=3)
    mix, _ = _commanded(program, 3)
    assert len(mix) > 100
    # the bands between the materials' regions went to a neighbour: every move is pure
    assert np.allclose(mix.max(axis=1), 1.0, atol=1e-4)
    assert {int(np.argmax(m)) for m in mix} == {0, 1, 2}


@pytest.mark.parametrize(("k", "n", "q"), [(2, 2, 1), (2, 5, 4), (2, 11, 10), (3, 6, 2), (3, 10, 3), (4, 10, 2)])
def test_the_bin_of_an_ends_palette_is_its_lattice_spacing(k, n, q):
    from fgslice.slicing.palette import palette_bin_size

    palette = Palette(k, n, "ends")
    assert palette.subdivisions == q
    assert palette_bin_size(n, k, "ends") == pytest.approx(1 / q)
    # the nearest lattice point is within half a spacing along every fraction of a pair
    points = _simplex_points(2000, k, seed=k * n)
    worst = np.abs(points - palette.centers[palette.color_of(points)]).max()
    assert worst <= 1 / q + 1e-9 and worst > 0.4 / q


def test_modelled_purges_take_a_tenth_of_the_lattice_spacing(tmp_path):
    design = api.design(api.fgrade(["x/40 + 0.5", "0.5 - x/40"], ["blue", "yellow"], api.rectprism(40, 20, 1)))
    settings = load_settings(None, {"palette": "ends", "colors": "5", "strategy": "1", "purge_size": "model"})
    stats = slice_to_gcode(design, settings, tmp_path / "ends.gcode", jobs=1).stats
    assert stats["purge_tolerance"] == pytest.approx(0.1 / 4)
    assert 0 < stats["simulated_within_half_bin"] <= 1
