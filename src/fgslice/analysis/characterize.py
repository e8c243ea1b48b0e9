"""Geometric characterization of architected materials (OpenVCAD 3's
``pyvcad_metamaterials.properties``).

:func:`characterize` samples a signed distance (negative inside, mm) at the centres of
cubic-ish voxels filling an envelope box exactly (``ceil(extent / voxel_size)`` voxels per
axis) and reports:

* ``envelope_volume`` ``V_e``; ``solid_volume`` ``V_s`` (fraction of inside samples times
  ``V_e``); ``void_volume``; ``relative_density`` ``V_s / V_e``; ``porosity``;
* ``surface_area``: every triangle of the surface extracted by marching cubes on the
  distance clipped to the envelope (nodes of the same grid, scikit-image);
  ``interface_area``: without the triangles lying on an envelope face; the ratios
  ``surface_area_to_solid_volume``, ``interface_area_to_solid_volume``,
  ``specific_surface_area`` (``interface / V_e``), ``normalized_interface_area``
  (``interface / V_e^(2/3)``) and ``hydraulic_diameter`` (``4 V_void / interface``);
* ``centroid`` of the inside samples; ``solid_component_count`` (26-connected inside
  voxels, joined across opposite envelope faces along ``periodic_axes``);
  ``euler_characteristic`` ``V - E + F`` of the mesh and ``genus`` ``(2 C - chi) / 2``
  (``C`` the mesh's connected surfaces) when the mesh is closed, else None;
* ``cross_sections[axis]``: per voxel layer along the axis, its ``positions`` (mm),
  ``solid_areas`` (mm^2), ``area_fractions`` and their ``coefficient_of_variation``
  (population standard deviation over mean).

:func:`characterize_graph_cell` measures a graph unit cell's struts exactly: counts,
connected components, cycle rank ``E - V + C``, degrees, lengths, ``aspect_ratio = L / 2r``
and ``slenderness_ratio = 2 L / r``; a strut passing through a vertex of the cell is cut
there. Ratios with a zero denominator are None.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field, fields

import numpy as np
from scipy import ndimage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from fgslice.errors import DesignError

MAX_VOXELS = 50_000_000
"""Most voxels one characterization samples."""


def _ratio(a: float, b: float) -> float | None:
    return a / b if b > 0 else None


@dataclass
class CrossSectionProfile:
    """The solid area of each voxel layer along one axis."""

    positions: list[float]
    solid_areas: list[float]
    area_fractions: list[float]
    coefficient_of_variation: float | None


@dataclass
class Characterization:
    """See the module notes; lengths mm, areas mm^2, volumes mm^3."""

    voxel_size: float
    envelope_volume: float
    solid_volume: float
    void_volume: float
    relative_density: float
    porosity: float
    surface_area: float
    interface_area: float
    surface_area_to_solid_volume: float | None
    interface_area_to_solid_volume: float | None
    specific_surface_area: float
    normalized_interface_area: float
    hydraulic_diameter: float | None
    centroid: tuple[float, float, float] | None
    solid_component_count: int
    euler_characteristic: int
    genus: int | None
    cross_sections: dict[str, CrossSectionProfile] = field(repr=False)

    def __str__(self) -> str:
        lines = ["Characterization"]
        for f in fields(self):
            if f.name != "cross_sections":
                value = getattr(self, f.name)
                lines.append(f"  {f.name}: {value:.6g}" if isinstance(value, float) else f"  {f.name}: {value}")
        for axis, profile in self.cross_sections.items():
            cv = profile.coefficient_of_variation
            lines.append(f"  cross_sections[{axis!r}]: {len(profile.positions)} layers, "
                         f"coefficient of variation {'None' if cv is None else f'{cv:.4g}'}")
        return "\n".join(lines)


def _grid(lo: np.ndarray, hi: np.ndarray, voxel_size: float) -> tuple[np.ndarray, np.ndarray]:
    counts = np.maximum(1, np.ceil(np.round((hi - lo) / voxel_size, 9)).astype(int))
    if np.prod(counts.astype(float)) > MAX_VOXELS:
        raise DesignError(f"characterize: {' x '.join(map(str, counts))} voxels of {voxel_size:g} mm is more than "
                          f"{MAX_VOXELS:,}", hint="give a larger voxel_size or smaller bounds")
    return counts, (hi - lo) / counts


def _sample(sdf: Callable, axes: list[np.ndarray]) -> np.ndarray:
    """``sdf`` on the grid of ``axes`` (x, y, z arrays), plane by plane in z."""
    x, y = np.meshgrid(axes[0], axes[1], indexing="ij")
    out = np.empty((len(axes[0]), len(axes[1]), len(axes[2])))
    for k, z in enumerate(axes[2]):
        out[:, :, k] = np.asarray(sdf(x.ravel(), y.ravel(), np.full(x.size, z)), dtype=float).reshape(x.shape)
    return out


def _components(inside: np.ndarray, periodic: set[int]) -> int:
    labels, count = ndimage.label(inside, structure=np.ones((3, 3, 3), dtype=bool))
    if count == 0 or not periodic:
        return int(count)
    pairs = []
    for axis in periodic:
        first, last = np.take(labels, 0, axis=axis), np.take(labels, -1, axis=axis)
        for du in (-1, 0, 1):
            for dv in (-1, 0, 1):
                shifted = np.roll(np.roll(last, du, axis=0), dv, axis=1)
                both = (first > 0) & (shifted > 0)
                pairs.append(np.stack([first[both], shifted[both]], axis=1))
    pairs = np.concatenate(pairs) - 1
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(count, count))
    return int(connected_components(graph, directed=False)[0])


def _mesh(distance: np.ndarray, step: np.ndarray, lo: np.ndarray):
    """Vertices (mm) and faces of the zero level of ``distance`` on grid nodes from ``lo``."""
    from skimage.measure import marching_cubes

    if not (distance.min() < 0 < distance.max()):
        return np.zeros((0, 3)), np.zeros((0, 3), dtype=int)
    vertices, faces, _, _ = marching_cubes(distance, 0.0, spacing=tuple(step))
    return vertices + lo, faces


def _areas(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    a, b, c = (vertices[faces[:, i]] for i in range(3))
    return np.linalg.norm(np.cross(b - a, c - a), axis=1) / 2


def _topology(faces: np.ndarray, n_vertices: int) -> tuple[int, int | None]:
    """Euler characteristic and genus (None unless every edge has two faces)."""
    if not len(faces):
        return 0, None
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    unique, uses = np.unique(edges, axis=0, return_counts=True)
    used = np.unique(faces)
    chi = len(used) - len(unique) + len(faces)
    if not np.all(uses == 2):
        return int(chi), None
    graph = coo_matrix((np.ones(len(unique)), (unique[:, 0], unique[:, 1])), shape=(n_vertices, n_vertices))
    labels = connected_components(graph, directed=False)[1]
    surfaces = len(np.unique(labels[used]))
    twice = 2 * surfaces - chi
    return int(chi), twice // 2 if twice % 2 == 0 else None


def characterize(sdf: Callable, lo, hi, voxel_size: float, periodic_axes: str = "") -> Characterization:
    """Measure the body ``sdf(x, y, z) < 0`` within the box ``lo``..``hi`` (mm) on voxels
    of about ``voxel_size`` mm; ``periodic_axes``: the axes (``"xyz"``...) whose opposite
    envelope faces join components."""
    lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    if not np.all(hi > lo):
        raise DesignError(f"characterize: the bounds must have a positive extent on every axis, got {lo} .. {hi}")
    if not (isinstance(voxel_size, (int, float)) and math.isfinite(voxel_size) and voxel_size > 0):
        raise DesignError(f"characterize: voxel_size must be a positive number (mm), got {voxel_size!r}")
    if not isinstance(periodic_axes, str) or set(periodic_axes) - set("xyz"):
        raise DesignError(f'characterize: periodic_axes is a string of x, y, z (e.g. "xyz"), got {periodic_axes!r}')
    counts, step = _grid(lo, hi, float(voxel_size))
    centres = [lo[a] + (np.arange(counts[a]) + 0.5) * step[a] for a in range(3)]
    inside = _sample(sdf, centres) < 0
    envelope = float(np.prod(hi - lo))
    density = float(inside.mean())
    solid = density * envelope

    nodes = [lo[a] + np.arange(-1, counts[a] + 2) * step[a] for a in range(3)]
    distance = _sample(sdf, nodes)
    grid = np.meshgrid(*nodes, indexing="ij")
    box = np.max([np.maximum(lo[a] - grid[a], grid[a] - hi[a]) for a in range(3)], axis=0)
    vertices, faces = _mesh(np.maximum(distance, box), step, lo - step)
    areas = _areas(vertices, faces)
    tolerance = 1e-6 * float(step.min())
    on_face = np.zeros(len(faces), dtype=bool)
    for a in range(3):
        coordinate = vertices[faces][:, :, a]
        on_face |= np.all(np.abs(coordinate - lo[a]) < tolerance, axis=1)
        on_face |= np.all(np.abs(coordinate - hi[a]) < tolerance, axis=1)
    surface, interface = float(areas.sum()), float(areas[~on_face].sum())
    chi, genus = _topology(faces, len(vertices))

    where = np.nonzero(inside)
    centroid = tuple(float(np.mean(centres[a][where[a]])) for a in range(3)) if where[0].size else None
    sections = {}
    for a, name in enumerate("xyz"):
        others = [b for b in range(3) if b != a]
        cell_area = float(step[others[0]] * step[others[1]])
        full = float((hi - lo)[others[0]] * (hi - lo)[others[1]])
        areas_a = inside.sum(axis=tuple(others)) * cell_area
        mean = float(areas_a.mean())
        sections[name] = CrossSectionProfile(centres[a].tolist(), areas_a.tolist(), (areas_a / full).tolist(),
                                             _ratio(float(areas_a.std()), mean))
    return Characterization(
        voxel_size=float(voxel_size), envelope_volume=envelope, solid_volume=solid, void_volume=envelope - solid,
        relative_density=density, porosity=1 - density, surface_area=surface, interface_area=interface,
        surface_area_to_solid_volume=_ratio(surface, solid), interface_area_to_solid_volume=_ratio(interface, solid),
        specific_surface_area=interface / envelope, normalized_interface_area=interface / envelope ** (2 / 3),
        hydraulic_diameter=_ratio(4 * (envelope - solid), interface), centroid=centroid,
        solid_component_count=_components(inside, {"xyz".index(c) for c in periodic_axes}),
        euler_characteristic=chi, genus=genus, cross_sections=sections)


@dataclass
class GraphCellReport:
    """A graph unit cell's struts at a size and radius (mm)."""

    cell_size: tuple[float, float, float]
    beam_radius: float
    node_count: int
    strut_count: int
    component_count: int
    cycle_rank: int
    degree_histogram: dict[int, int]
    mean_degree: float
    total_length: float
    strut_lengths: list[float] = field(repr=False)
    mean_strut_length: float
    mean_aspect_ratio: float
    mean_slenderness_ratio: float


def _split(pairs: np.ndarray, nodes: np.ndarray) -> np.ndarray:
    """The edges ``pairs`` (node indices) cut at every node lying inside them (within
    1e-9 cells), as in an octet's face diagonals through the face centres."""
    out = []
    for a, b in pairs:
        d = nodes[b] - nodes[a]
        t = (nodes - nodes[a]) @ d / float(d @ d)
        off = np.linalg.norm(nodes - nodes[a] - t[:, None] * d, axis=1)
        inner = np.flatnonzero((off < 1e-9) & (t > 1e-9) & (t < 1 - 1e-9))
        chain = [a, *inner[np.argsort(t[inner])].tolist(), b]
        out += list(zip(chain[:-1], chain[1:]))
    return np.array(out, dtype=np.int64).reshape(-1, 2)


def characterize_graph_cell(edges: np.ndarray, cell_size, beam_radius: float) -> GraphCellReport:
    """The struts ``edges`` ``(n, 2, 3)`` (unit cube) scaled by ``cell_size`` (mm, a number
    or 3) with radius ``beam_radius`` (mm); vertices closer than 1e-9 cells are one node,
    and a strut through a node is two struts."""
    size = np.broadcast_to(np.asarray(cell_size, dtype=float), (3,)).copy()
    if not np.all(size > 0) or not (isinstance(beam_radius, (int, float)) and beam_radius > 0):
        raise DesignError(f"characterize_graph_cell: cell_size and beam_radius must be positive (mm), got "
                          f"{cell_size!r}, {beam_radius!r}")
    points = np.asarray(edges, dtype=float).reshape(-1, 3)
    _, first, index = np.unique(np.round(points / 1e-9).astype(np.int64), axis=0, return_index=True,
                                return_inverse=True)
    index = index.ravel()
    unit = points[first]
    pairs = np.unique(np.sort(_split(index.reshape(-1, 2), unit), axis=1), axis=0)
    pairs = pairs[pairs[:, 0] != pairs[:, 1]]
    n = int(index.max()) + 1
    degrees = np.bincount(pairs.ravel(), minlength=n)
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    components = int(connected_components(graph, directed=False)[0])
    nodes = unit * size
    lengths = np.linalg.norm(nodes[pairs[:, 1]] - nodes[pairs[:, 0]], axis=1)
    r = float(beam_radius)
    return GraphCellReport(
        cell_size=tuple(size.tolist()), beam_radius=r, node_count=n, strut_count=len(pairs),
        component_count=components, cycle_rank=len(pairs) - n + components,
        degree_histogram=dict(sorted(Counter(degrees.tolist()).items())), mean_degree=float(degrees.mean()),
        total_length=float(lengths.sum()), strut_lengths=lengths.tolist(), mean_strut_length=float(lengths.mean()),
        mean_aspect_ratio=float(np.mean(lengths / (2 * r))), mean_slenderness_ratio=float(np.mean(2 * lengths / r)))
