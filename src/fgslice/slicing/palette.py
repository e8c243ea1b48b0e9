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

from math import ceil, comb

import numpy as np

from fgslice.errors import SettingsError

LETTERS = "ABCDEFGHIJKLMNOPQRSTUVWXYZ"

KINDS = ("centers", "ends")
"""Palette kinds: cell centroids of equal cells (the paper's), or a lattice with the pure materials."""


def palette_bin_size(palette_size: int, n_materials: int, kind: str = "centers") -> float:
    """Width of one palette cell along a fraction axis: ``1/N`` for two materials,
    ``1/m`` for simplex palettes of ``m`` divisions per axis (``N = m^(k-1)`` cells or
    fewer); ``kind = "ends"``: the lattice spacing ``1/q`` (``1/(N-1)`` for two materials)."""
    if palette_size < 1:
        raise SettingsError(f"palette size must be >= 1, got {palette_size}")
    if kind == "ends" and n_materials >= 2 and palette_size >= 2:
        return 1.0 / _lattice_divisions(n_materials, palette_size)
    if n_materials <= 2:
        return 1.0 / palette_size
    divisions = ceil(palette_size ** (1.0 / (n_materials - 1)) - 1e-9)
    return 1.0 / divisions


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


def lattice_size(n_materials: int, q: int) -> int:
    """Number of points ``t / q`` of the simplex lattice of ``n_materials`` materials."""
    return comb(q + n_materials - 1, n_materials - 1)


def _lattice_divisions(n_materials: int, size: int) -> int:
    """``q`` such that ``lattice_size(n_materials, q) == size`` (``q >= 1``, two or more
    materials); SettingsError otherwise."""
    q = 1
    while lattice_size(n_materials, q) < size:
        q += 1
    if lattice_size(n_materials, q) == size:
        return q
    allowed = [lattice_size(n_materials, j) for j in range(1, 5)]
    near = [n for n in (lattice_size(n_materials, q - 1) if q > 1 else None, lattice_size(n_materials, q)) if n]
    rule = "any N >= 2" if n_materials == 2 else (
        f"N = C(q+{n_materials - 1}, {n_materials - 1}): " + ", ".join(map(str, allowed)) + ", ..."
    )
    raise SettingsError(
        f"palette = ends with {n_materials} materials puts the colors on a lattice that includes the pure "
        f"materials, which allows {rule}, not {size} color{'s' if size != 1 else ''}",
        hint=" or ".join(f"--set colors={n}" for n in near) + " (or --set palette=centers)",
    )


def _lattice(n_materials: int, q: int) -> np.ndarray:
    """All lattice tuples ``t`` (rows, int, ``t >= 0``, ``sum(t) = q``), unordered."""
    tuples = _tuples(n_materials, q + 1)
    return tuples[tuples.sum(axis=1) == q]


def _nearest_lattice(fractions: np.ndarray, q: int) -> np.ndarray:
    """Tuples ``t`` of the lattice points ``t / q`` nearest to ``fractions`` (..., k).

    Each ``q f_i`` is rounded (halves up), then the sum is brought back to ``q`` by
    raising the coordinates rounded down the most (or lowering those rounded up the
    most), ties broken by material order: the nearest point of the lattice ``A_{k-1}``
    (Conway and Sloane), which for points of the simplex lies in the simplex.
    """
    x = np.clip(np.asarray(fractions, dtype=float), 0.0, 1.0) * q
    t = np.floor(x + 0.5).astype(np.int64)
    excess = t.sum(axis=-1, keepdims=True) - q
    error = x - t  # > 0: rounded down
    k = x.shape[-1]
    rank = np.empty_like(t)
    np.put_along_axis(rank, np.argsort(-error, axis=-1, kind="stable"), np.arange(k), axis=-1)
    raise_ = (excess < 0) & (rank < -excess)
    lower = (excess > 0) & ((k - 1 - rank) < excess)
    return t + raise_ - lower


def _tuples(n_materials: int, top: int) -> np.ndarray:
    """Every integer tuple (rows) of ``n_materials`` entries in ``0 .. top - 1``."""
    grids = np.meshgrid(*([np.arange(top)] * n_materials), indexing="ij")
    return np.stack([g.ravel() for g in grids], axis=1)


def _cells(n_materials: int, m: int) -> np.ndarray:
    """All nonempty cell tuples ``t`` (rows, int) of the arrangement, unordered."""
    tuples = _tuples(n_materials, m)
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
    """The colors of a print: cells of mixture space, their states and their order.

    Attributes:
        n_materials: number of base materials ``k``.
        size: number of colors ``N``.
        kind: ``"centers"`` (equal cells, the state of a color is its cell's centroid) or
            ``"ends"`` (the states are the simplex lattice points ``t / q``, pure
            materials included; each mixture takes the nearest).
        subdivisions: ``m``, the number of equal intervals each fraction is cut into
            (``"centers"``), or the lattice's denominator ``q`` (``"ends"``).
        cells: ``(N, k)`` int tuples naming each color: its cell ``floor(f * m)``
            (``"centers"``) or its lattice point ``q * f`` (``"ends"``).
        centers: ``(N, k)`` float fractions sent to the printer (cell centroids, or the
            lattice points).
        order: ``(N,)`` traversal order of colors for even layers (``0 .. N-1``: colors
            are numbered in traversal order).
        n_bands, band_range: how the colors' cells are cut out of mixture space for
            tracing faces: :meth:`band_values` gives ``L`` values in ``[0, 1]``, each cut
            into ``n_bands`` equal bands ``[b, b + 1) / n_bands``; color ``c`` is the
            intersection over ``l`` of the bands ``band_range[c, l, 0] ..
            band_range[c, l, 1]`` of value ``l``.
        band_counts: ``(L,)`` the number of bands of each value (``n_bands`` each).
    """

    def __init__(self, n_materials: int, size: int, kind: str = "centers") -> None:
        self.n_materials = int(n_materials)
        self.size = int(size)
        if kind not in KINDS:
            raise SettingsError(f"unknown palette kind {kind!r}", hint="--set palette=centers or --set palette=ends")
        self.kind = kind if self.n_materials > 1 else "centers"
        k = self.n_materials
        if self.kind == "ends":
            self.subdivisions = q = _lattice_divisions(k, self.size)
            cells = _lattice(k, q)
            self.cells = cells[np.lexsort(_snake_keys(cells)[::-1])]
            self.centers = self.cells / q
        else:
            self.subdivisions = _subdivisions(k, self.size)
            m = self.subdivisions
            if k == 1:
                self.cells = np.zeros((1, 1), dtype=np.int64)
                self.centers = np.ones((1, 1))
            else:
                cells = _cells(k, m)
                self.cells = cells[np.lexsort(_snake_keys(cells)[::-1])]
                rest = m - self.cells.sum(axis=1, keepdims=True)
                self.centers = (self.cells + rest / k) / m
        self.order = np.arange(self.size)
        base = self.subdivisions + 1
        self._codes = self.cells @ (base ** np.arange(k))
        self._by_code = np.argsort(self._codes)
        #: Two materials with color c = bin c of the first fraction: color_of is one floor.
        self._two_material_bins = (
            self.kind == "centers" and k == 2 and bool(np.array_equal(self.cells[:, 0], np.arange(self.size)))
        )
        self._pairs = np.array([(i, j) for i in range(k) for j in range(i + 1, k)], dtype=np.int64).reshape(-1, 2)
        self.n_bands, self.band_range = self._band_layout()
        self.band_counts = np.full(self.band_range.shape[1], self.n_bands)

    def _band_layout(self) -> tuple[int, np.ndarray]:
        """``(n_bands, band_range)`` (see the class docstring)."""
        k, m = self.n_materials, self.subdivisions
        if self.kind == "centers" or k == 1:
            t = self.cells[:, :1] if k <= 2 else self.cells
            return max(m, 1), np.stack([t, t], axis=-1)
        if k == 2:
            c = self.cells[:, :1]
            return m + 1, np.stack([c, c], axis=-1)
        i, j = self._pairs.T
        d = self.cells[:, i] - self.cells[:, j] + m  # the point's band pair: [d - 1, d] of 2q
        return 2 * m, np.stack([np.maximum(d - 1, 0), np.minimum(d, 2 * m - 1)], axis=-1)

    def band_values(self, fractions: np.ndarray) -> np.ndarray:
        """The ``L`` values ``(..., L)`` whose bands cut out the colors (see :attr:`band_range`).

        ``"centers"``: the fractions themselves (``f_0`` alone for two materials), cut at
        ``j / m``. ``"ends"``, two materials: ``(q f_0 + 1/2) / (q + 1)``, whose ``q + 1``
        bands are the nearest lattice points. ``"ends"``, three or more: for each pair
        ``i < j``, ``(f_i - f_j + 1) / 2`` cut into ``2 q`` bands; the nearest lattice
        point ``p`` is where ``|q (f_i - f_j) - q (p_i - p_j)| <= 1`` for every pair (the
        Voronoi cell of the lattice ``A_{k-1}``), two bands of each pair.
        """
        f = np.asarray(fractions, dtype=float)
        k, q = self.n_materials, self.subdivisions
        if self.kind == "centers" or k == 1:
            return f[..., :1] if k <= 2 else f
        if k == 2:
            return ((q * f[..., 0] + 0.5) / (q + 1))[..., None]
        i, j = self._pairs.T
        return (f[..., i] - f[..., j] + 1.0) / 2.0

    def order_for_layer(self, layer_index: int) -> np.ndarray:
        """Colors in traversal order for layer ``layer_index``: reversed on odd layers."""
        return self.order[::-1].copy() if layer_index % 2 else self.order.copy()

    def cell_of(self, fractions: np.ndarray) -> np.ndarray:
        """Cell tuples ``(..., k)`` of normalized fractions ``(..., k)``.

        Two materials: bins of the first fraction, ``[j/N, (j+1)/N)`` with the last bin
        closed. Three or more: ``floor(f * m)`` clipped to ``m - 1``; on a point where
        several boundaries meet (the floors sum to ``m`` or more) the coordinates with
        the smallest fractional part, the last material first, are lowered so that the
        tuple names an existing cell. ``"ends"``: the tuple ``t`` of the nearest lattice
        point ``t / q`` (:func:`_nearest_lattice`).
        """
        f = np.asarray(fractions, dtype=float)
        k, m = self.n_materials, self.subdivisions
        if k == 1:
            return np.zeros(f.shape, dtype=np.int64)
        if self.kind == "ends":
            return _nearest_lattice(f, m)
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
        return self._color_of_cells(self.cell_of(fractions))

    def _color_of_cells(self, cells: np.ndarray) -> np.ndarray:
        """Color index of cell tuples ``(..., k)`` (existing ones)."""
        codes = cells @ ((self.subdivisions + 1) ** np.arange(self.n_materials))
        pos = np.searchsorted(self._codes[self._by_code], codes)
        return self._by_code[np.clip(pos, 0, self.size - 1)]

    def zipper_neighbor(self, fractions: np.ndarray, beta_percent: float) -> np.ndarray:
        """The color across the nearest cell boundary for points in a zipper band, else -1.

        The band around each interior boundary is ``beta_percent`` % of the fraction
        range wide in total, centred on the boundary: a point qualifies when its distance
        to the boundary, in fraction units, is below ``beta_percent / 200``. The edges of
        mixture space (a fraction at 0 or 1) have no neighbor. For three or more
        materials the candidate boundaries are the facets ``f_i = const`` of the point's
        own cell that are shared with another cell. ``"ends"``: the boundaries are the
        facets ``q (f_i - f_j) - (t_i - t_j) = 1`` of the point's lattice cell towards
        the existing point ``t + e_i - e_j``, at the distance ``(1 - q (f_i - f_j) +
        (t_i - t_j)) / (2 q)`` (how far ``f_i`` and ``f_j`` each have to move).
        """
        f = np.asarray(fractions, dtype=float)
        half = float(beta_percent) / 200.0
        k, m = self.n_materials, self.subdivisions
        if k == 1 or self.size == 1:
            return np.full(f.shape[:-1], -1, dtype=np.int64)
        if self.kind == "ends":
            return self._lattice_zipper(f, half)
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
        neighbor = self._color_of_cells(moved)
        return np.where(np.isfinite(dist) & (np.abs(dist) < half), neighbor, -1)

    def _lattice_zipper(self, f: np.ndarray, half: float) -> np.ndarray:
        """:meth:`zipper_neighbor` of an ``"ends"`` palette (``half`` in fraction units)."""
        k, q = self.n_materials, self.subdivisions
        t = self.cell_of(f)
        x = np.clip(f, 0.0, 1.0) * q - t
        i, j = np.array([(a, b) for a in range(k) for b in range(k) if a != b]).T
        dist = np.where(t[..., j] >= 1, (1.0 - (x[..., i] - x[..., j])) / (2 * q), np.inf)
        best = np.argmin(dist, axis=-1)
        nearest = np.take_along_axis(dist, best[..., None], axis=-1)[..., 0]
        moved = t + (np.arange(k) == i[best][..., None]) - (np.arange(k) == j[best][..., None])
        return np.where(nearest < half, self._color_of_cells(moved), -1)

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
        kind = "" if self.kind == "centers" else f", kind={self.kind!r}"
        return f"Palette(n_materials={self.n_materials}, size={self.size}{kind})"
