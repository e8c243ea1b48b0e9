"""Palette: cells of mixture space, centers, traversal order, zipper bands, errors."""

import numpy as np
import pytest
import shapely

from fgslice.errors import SettingsError
from fgslice.slicing.palette import Palette, palette_size


def _simplex_points(n: int, k: int, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).dirichlet(np.ones(k), size=n)


@pytest.mark.parametrize("n", [1, 2, 3, 4, 7, 16, 48])
def test_two_materials_bins(n):
    pal = Palette(2, n)
    f0 = np.linspace(0, 1, 1001)
    colors = pal.color_of(np.stack([f0, 1 - f0], axis=1))
    expected = np.minimum(np.floor(f0 * n), n - 1)
    # away from bin edges the color is the bin of f0
    off_edge = np.abs(f0 * n - np.rint(f0 * n)) > 1e-6
    assert np.array_equal(colors[off_edge], expected[off_edge])
    assert colors[0] == 0 and colors[-1] == n - 1
    assert np.allclose(pal.centers[:, 0], (np.arange(n) + 0.5) / n)
    assert np.allclose(pal.centers.sum(axis=1), 1.0)
    assert np.array_equal(pal.order, np.arange(n))


def test_bin_edges_belong_to_upper_bin():
    pal = Palette(2, 10)
    f0 = np.arange(11) / 10
    assert pal.color_of(np.stack([f0, 1 - f0], axis=1)).tolist() == [0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9]


@pytest.mark.parametrize("k,n", [(2, 5), (3, 9), (3, 16), (4, 15)])
def test_centers_lie_in_their_own_cell(k, n):
    pal = Palette(k, n)
    assert np.array_equal(pal.color_of(pal.centers), np.arange(n))
    assert np.allclose(pal.centers.sum(axis=1), 1.0)


@pytest.mark.parametrize("m", [1, 2, 3, 5])
def test_three_materials_equal_triangles(m):
    pal = Palette(3, m * m)
    pts = _simplex_points(40000, 3)
    colors = pal.color_of(pts)
    counts = np.bincount(colors, minlength=m * m)
    # m^2 cells of equal area: each gets about 1/m^2 of uniform samples
    assert counts.min() > 0
    assert np.allclose(counts / len(pts), 1 / m**2, atol=0.01)
    # each sample lies in the cell floor(f*m) of its color
    cells = pal.cells[colors]
    assert np.all((pts * m >= cells - 1e-12) & (pts * m <= cells + 1 + 1e-12))
    # the centroid of the samples of a color is its center
    for c in range(m * m):
        assert np.allclose(pts[colors == c].mean(axis=0), pal.centers[c], atol=0.02)


def _triangle(cell: np.ndarray, m: int) -> shapely.Polygon:
    """The cell of a 3-material palette drawn in the plane (barycentric to 2D)."""
    r = m - cell.sum()
    if r == 1:
        verts = [cell + np.eye(3, dtype=int)[i] for i in range(3)]
    else:
        verts = [cell + 1 - np.eye(3, dtype=int)[i] for i in range(3)]
    corners = np.array([[0.0, 0.0], [1.0, 0.0], [0.5, np.sqrt(3) / 2]])
    return shapely.Polygon(np.array(verts) / m @ corners)


@pytest.mark.parametrize("m", [2, 3, 4, 6])
def test_three_material_order_walks_edge_adjacent_cells_along_rows(m):
    pal = Palette(3, m * m)
    tris = [_triangle(c, m) for c in pal.cells]
    assert abs(sum(t.area for t in tris) - np.sqrt(3) / 4) < 1e-9
    row_changes = 0
    for a, b in zip(range(m * m - 1), range(1, m * m)):
        shared = tris[a].intersection(tris[b])
        if pal.cells[a][0] == pal.cells[b][0]:
            assert shared.length == pytest.approx(1 / m)  # a whole edge
        else:
            row_changes += 1
            assert shared.geom_type == "Point"  # a shared vertex between rows
    # the up/down triangles are a bipartite graph with m more up cells: m - 1 non-edge steps are unavoidable
    assert row_changes == m - 1


def test_two_material_order_adjacent_and_reversed_on_odd_layers():
    pal = Palette(2, 6)
    assert np.all(np.abs(np.diff(pal.centers[pal.order_for_layer(0), 0])) == pytest.approx(1 / 6))
    assert pal.order_for_layer(1).tolist() == [5, 4, 3, 2, 1, 0]
    assert pal.order_for_layer(2).tolist() == list(range(6))


@pytest.mark.parametrize(
    "k,n,allowed",
    [(3, 5, "colors=4 or --set colors=9"), (3, 10, "colors=9 or --set colors=16"), (4, 6, "colors=5 or --set colors=15")],
)
def test_invalid_sizes_name_the_nearest_allowed(k, n, allowed):
    with pytest.raises(SettingsError) as err:
        Palette(k, n)
    assert allowed in err.value.hint


def test_single_material_and_bad_sizes():
    pal = Palette(1, 1)
    assert pal.color_of(np.ones((5, 1))).tolist() == [0] * 5
    assert pal.label(0) == "A 100%"
    with pytest.raises(SettingsError):
        Palette(1, 3)
    with pytest.raises(SettingsError):
        Palette(2, 0)


def test_sizes_for_four_materials_count_nonempty_cells():
    assert [palette_size(4, m) for m in range(1, 5)] == [1, 5, 15, 34]
    pal = Palette(4, 15)
    colors = pal.color_of(_simplex_points(20000, 4, seed=3))
    assert set(np.unique(colors)) == set(range(15))


def test_zipper_neighbor_two_materials_hand_computed():
    pal = Palette(2, 4)  # boundaries at 0.25, 0.5, 0.75; beta 10% -> half band 0.05
    f0 = np.array([0.0, 0.03, 0.21, 0.24, 0.26, 0.29, 0.31, 0.5, 0.54, 0.76, 0.97, 1.0])
    got = pal.zipper_neighbor(np.stack([f0, 1 - f0], axis=1), 10.0)
    assert got.tolist() == [-1, -1, 1, 1, 0, 0, -1, 1, 1, 2, -1, -1]
    assert np.all(pal.zipper_neighbor(np.stack([f0, 1 - f0], axis=1), 0.0) == -1)


def test_zipper_neighbor_three_materials_hand_computed():
    pal = Palette(3, 4)  # m = 2: cells (0,0,1) (0,0,0) (0,1,0) (1,0,0)
    pts = np.array(
        [
            [0.48, 0.26, 0.26],  # centre cell (0,0,0), 0.02 below f0 = 1/2 -> cell (1,0,0)
            [0.52, 0.24, 0.24],  # cell (1,0,0), 0.02 above f0 = 1/2 -> cell (0,0,0)
            [0.9, 0.05, 0.05],  # deep in (1,0,0)
            [0.3, 0.3, 0.4],  # centre cell, 0.1 from every boundary
        ]
    )
    cells = pal.cells[pal.color_of(pts)].tolist()
    assert cells[:3] == [[0, 0, 0], [1, 0, 0], [1, 0, 0]]
    got = pal.zipper_neighbor(pts, 10.0)
    names = {tuple(c): i for i, c in enumerate(pal.cells.tolist())}
    assert got.tolist() == [names[(1, 0, 0)], names[(0, 0, 0)], -1, -1]


def test_labels():
    assert Palette(2, 4).label(1) == "A 37.5% / B 62.5%"
    assert Palette(3, 1).label(0) == "A 33.33% / B 33.33% / C 33.33%"
    with pytest.raises(SettingsError):
        Palette(2, 4).label(4)


@pytest.mark.parametrize("size", [1, 2, 3, 7, 16, 48])
def test_two_material_color_of_is_the_bin_of_the_first_fraction(size):
    palette = Palette(2, size)
    rng = np.random.default_rng(size)
    f0 = np.concatenate([rng.uniform(-0.1, 1.1, 5000), np.arange(size + 1) / size])
    fractions = np.stack([f0, 1 - f0], axis=-1)
    expected = palette._by_code[
        np.clip(np.searchsorted(palette._codes[palette._by_code], palette.cell_of(fractions) @ (palette.subdivisions ** np.arange(2))), 0, size - 1)
    ]
    colors = palette.color_of(fractions)
    assert np.array_equal(colors, expected)
    inside = (f0 >= 0) & (f0 < 1)
    assert np.all(colors[inside] == np.floor(f0[inside] * size))
    assert np.all(np.abs(palette.centers[colors[inside], 0] - f0[inside]) <= 0.5 / size + 1e-12)
