"""The palette: a finite set of process states ("colors") subdividing mixture space.

A design with ``k`` materials has volume fractions ``f`` on the simplex
``f_i >= 0, sum f_i = 1``. The palette cuts the simplex with the hyperplanes
``f_i = j / m`` (``j = 1 .. m-1``) for every material ``i``. Each nonempty cell of that
arrangement is one color; a cell is named by the integer tuple ``t = floor(f * m)``
(each entry clipped to ``m - 1``), and the nonempty tuples are exactly those with
``m - k + 1 <= sum(t) <= m - 1``. Their number is

    N(k, m) = C(m + k - 1, k) - C(m, k)

so ``N = m`` for two materials (equal bins of the first fraction), ``N = m^2`` for three
(equal triangles), ``1, 5, 15, 34, 65, ...`` for four; one material has ``N = 1``.

The state sent to the printer for a color is its cell's centroid ``(t + r / k) / m`` with
``r = m - sum(t)``; for two materials the bin middle. Colors are numbered in traversal
order (see :func:`_snake_keys`), so :attr:`Palette.order` is ``0 .. N-1`` on even layers
and reversed on odd ones. ``docs/palette.md`` explains the choices.
"""

from __future__ import annotations

from math import comb

import numpy as np

from fgslice.errors import SettingsError

LETTERS = "ABCDEFGHIJKLMNOPQRSTUVWXYZ"


def palette_size(n_materials: int, m: int) -> int:
    """Number of colors of a palette cutting each fraction into ``m`` equal intervals."""
    if n_materials == 1:
        return 1
    return comb(m + n_materials - 1, n_materials) - comb(m, n_materials)


def allowed_sizes_near(n_materials: int, size: int) -> list[int]:
    """The valid palette sizes just below and just above ``size`` (one or two values)."""
    if n_materials == 1:
        return [1]
    m = 1
    while palette_size(n_materials, m + 1) <= size:
        m += 1
    lower, upper = palette_size(n_materials, m), palette_size(n_materials, m + 1)
    return [lower] if lower == size else [lower, upper]


def _subdivisions(n_materials: int, size: int) -> int:
    """``m`` such that ``palette_size(n_materials, m) == size``; SettingsError otherwise."""
    if n_materials < 1:
        raise SettingsError(f"a palette needs at least one material, got {n_materials}")
    if size < 1:
        raise SettingsError(f"the palette size must be at least 1, got {size}", hint="--set colors=4")
    if n_materials == 1:
        if size != 1:
            raise SettingsError(
                f"a single-material design has exactly one color, but colors = {size}",
                hint="--set colors=1",
            )
        return 1
    near = allowed_sizes_near(n_materials, size)
    if near == [size]:
        m = 1
        while palette_size(n_materials, m) < size:
            m += 1
        return m
    rule = {2: "any N >= 1", 3: "N = m^2 (1, 4, 9, 16, 25, ...)"}.get(
        n_materials, f"N = C(m+{n_materials - 1}, {n_materials}) - C(m, {n_materials}) for m = 1, 2, ..."
    )
    raise SettingsError(
        f"a palette of {size} colors does not match a subdivision of the mixture space of {n_materials} materials "
        f"({rule})",
        hint=f"use --set colors={near[0]} or --set colors={near[1]}",
    )


def _cells(n_materials: int, m: int) -> np.ndarray:
    """All nonempty cell tuples ``t`` (rows, int) of the arrangement, unordered."""
    grids = np.meshgrid(*([np.arange(m)] * n_materials), indexing="ij")
    tuples = np.stack([g.ravel() for g in grids], axis=1)
    sums = tuples.sum(axis=1)
    return tuples[(sums >= m - n_materials + 1) & (sums <= m - 1)]


def _snake_keys(cells: np.ndarray) -> list[np.ndarray]:
    """Sort keys (most significant first) of the boustrophedon traversal of the cells.

    Rows are cells of equal ``t_0``, visited in increasing ``t_0``. Inside a row, each
    further coordinate ``t_i`` runs up or down depending on the parity of
    ``t_0 + ... + t_{i-1}``; the last two coordinates are walked together along
    ``t_{k-2} - t_{k-1}`` (then their sum), which for three materials walks the strip of
    alternating up/down triangles of the row from one end to the other.
    """
    k = cells.shape[1]
    keys = [cells[:, 0]]
    prefix = cells[:, 0].copy()
    for i in range(1, k - 2):
        keys.append(np.where(prefix % 2 == 0, cells[:, i], -cells[:, i]))
        prefix = prefix + cells[:, i]
    sign = np.where(prefix % 2 == 0, 1, -1) if k > 2 else np.ones(len(cells), dtype=int)
    keys.append(sign * (cells[:, k - 2] - cells[:, k - 1]))
    keys.append(sign * (cells[:, k - 2] + cells[:, k - 1]))
    return keys


class Palette:
    """The colors of a print: equal cells of mixture space, their states and their order.

    Attributes:
        n_materials: number of base materials ``k``.
        size: number of colors ``N``.
        subdivisions: ``m``, the number of equal intervals each fraction is cut into.
        cells: ``(N, k)`` int tuples ``floor(f * m)`` naming each color's cell.
        centers: ``(N, k)`` float fractions sent to the printer (cell centroids).
        order: ``(N,)`` traversal order of colors for even layers (``0 .. N-1``: colors
            are numbered in traversal order).
    """

    def __init__(self, n_materials: int, size: int) -> None:
        self.n_materials = int(n_materials)
        self.size = int(size)
        self.subdivisions = _subdivisions(self.n_materials, self.size)
        k, m = self.n_materials, self.subdivisions
        if k == 1:
            self.cells = np.zeros((1, 1), dtype=np.int64)
            self.centers = np.ones((1, 1))
        else:
            cells = _cells(k, m)
            self.cells = cells[np.lexsort(_snake_keys(cells)[::-1])]
            rest = m - self.cells.sum(axis=1, keepdims=True)
            self.centers = (self.cells + rest / k) / m
        self.order = np.arange(self.size)
        self._codes = self.cells @ (m ** np.arange(k))
        self._by_code = np.argsort(self._codes)
        #: Two materials with color c = bin c of the first fraction: color_of is one floor.
        self._two_material_bins = k == 2 and bool(np.array_equal(self.cells[:, 0], np.arange(self.size)))

    def order_for_layer(self, layer_index: int) -> np.ndarray:
        """Colors in traversal order for layer ``layer_index``: reversed on odd layers."""
        return self.order[::-1].copy() if layer_index % 2 else self.order.copy()

    def cell_of(self, fractions: np.ndarray) -> np.ndarray:
        """Cell tuples ``(..., k)`` of normalized fractions ``(..., k)``.

        Two materials: bins of the first fraction, ``[j/N, (j+1)/N)`` with the last bin
        closed. Three or more: ``floor(f * m)`` clipped to ``m - 1``; on a point where
        several boundaries meet (the floors sum to ``m`` or more) the coordinates with
        the smallest fractional part, the last material first, are lowered so that the
        tuple names an existing cell.
        """
        f = np.asarray(fractions, dtype=float)
        k, m = self.n_materials, self.subdivisions
        if k == 1:
            return np.zeros(f.shape, dtype=np.int64)
        if k == 2:
            t0 = np.clip(np.floor(f[..., 0] * m), 0, m - 1).astype(np.int64)
            return np.stack([t0, m - 1 - t0], axis=-1)
        scaled = np.clip(f, 0.0, 1.0) * m
        t = np.clip(np.floor(scaled), 0, m - 1).astype(np.int64)
        excess = np.maximum(t.sum(axis=-1) - (m - 1), 0)
        frac = np.where(t > 0, scaled - t, np.inf)
        # stable argsort of the reversed columns: ties lower the last material first
        rank = np.empty_like(t)
        by_frac = np.argsort(frac[..., ::-1], axis=-1, kind="stable")
        np.put_along_axis(rank, (k - 1) - by_frac, np.arange(k), axis=-1)
        return t - (rank < excess[..., None])

    def color_of(self, fractions: np.ndarray) -> np.ndarray:
        """Color index (``...``) of normalized fractions ``(..., k)``."""
        if self._two_material_bins:
            f0 = np.asarray(fractions, dtype=float)[..., 0]
            return np.clip(np.floor(f0 * self.subdivisions), 0, self.subdivisions - 1).astype(np.int64)
        t = self.cell_of(fractions)
        codes = t @ (self.subdivisions ** np.arange(self.n_materials))
        pos = np.searchsorted(self._codes[self._by_code], codes)
        return self._by_code[np.clip(pos, 0, self.size - 1)]

    def zipper_neighbor(self, fractions: np.ndarray, beta_percent: float) -> np.ndarray:
        """The color across the nearest cell boundary for points in a zipper band, else -1.

        The band around each interior boundary is ``beta_percent`` % of the fraction
        range wide in total, centred on the boundary: a point qualifies when its distance
        to the boundary, in fraction units, is below ``beta_percent / 200``. The edges of
        mixture space (a fraction at 0 or 1) have no neighbor. For three or more
        materials the candidate boundaries are the facets ``f_i = const`` of the point's
        own cell that are shared with another cell.
        """
        f = np.asarray(fractions, dtype=float)
        half = float(beta_percent) / 200.0
        k, m = self.n_materials, self.subdivisions
        if k == 1 or self.size == 1:
            return np.full(f.shape[:-1], -1, dtype=np.int64)
        if k == 2:
            boundary = np.clip(np.rint(f[..., 0] * m), 1, m - 1)
            across = np.where(f[..., 0] * m < boundary, boundary, boundary - 1).astype(np.int64)
            dist = np.abs(f[..., 0] - boundary / m)
            return np.where(dist < half, across, -1)
        t = self.cell_of(f)
        total = t.sum(axis=-1, keepdims=True)
        lower_ok = (t >= 1) & (total - 1 >= m - k + 1)
        upper_ok = (t + 1 <= m - 1) & (total + 1 <= m - 1)
        d_lower = np.where(lower_ok, f - t / m, np.inf)
        d_upper = np.where(upper_ok, (t + 1) / m - f, np.inf)
        both = np.concatenate([d_lower, d_upper], axis=-1)
        best = np.argmin(both, axis=-1)
        dist = np.take_along_axis(both, best[..., None], axis=-1)[..., 0]
        step = np.where(best < k, -1, 1)
        axis = best % k
        moved = t + step[..., None] * (np.arange(k) == axis[..., None])
        codes = moved @ (m ** np.arange(k))
        pos = np.clip(np.searchsorted(self._codes[self._by_code], codes), 0, self.size - 1)
        neighbor = self._by_code[pos]
        return np.where(np.isfinite(dist) & (np.abs(dist) < half), neighbor, -1)

    def label(self, color: int) -> str:
        """Human-readable state of a color, e.g. ``"A 37.5% / B 62.5%"``."""
        if not 0 <= color < self.size:
            raise SettingsError(f"color {color} is not in the palette (0..{self.size - 1})")
        parts = []
        for i, value in enumerate(self.centers[color]):
            pct = f"{100.0 * value:.2f}".rstrip("0").rstrip(".")
            parts.append(f"{LETTERS[i]} {pct}%")
        return " / ".join(parts)

    def __repr__(self) -> str:
        return f"Palette(n_materials={self.n_materials}, size={self.size})"
