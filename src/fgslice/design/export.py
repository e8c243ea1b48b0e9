"""A design's surface as a triangle mesh (STL): marching cubes on its signed distance.

The signed distance is sampled on a regular grid of ``resolution`` mm over the design's
box (one sample beyond it on every side, so every surface closes), one XY plane at a
time, and scikit-image's marching cubes runs on slabs of planes. Vertices lie on the zero
level by linear interpolation along the grid edges: features thinner than about one
``resolution`` may be lost or merged. Materials are not exported (an STL has none).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from fgslice.design.base import Design
from fgslice.errors import DesignError

MAX_SAMPLES = 2_000_000_000
"""Most grid samples an export may take (about 8 GB of float32 at once if kept whole)."""

_SLAB_SAMPLES = 8_000_000
"""Samples per slab of planes handed to marching cubes at once."""


def mesh_arrays(design: Design, resolution: float) -> tuple[np.ndarray, np.ndarray]:
    """``(vertices (n, 3) mm, faces (m, 3) indices)`` of the design's surface, triangles
    wound counter-clockwise seen from outside. Slabs repeat the vertices of the planes
    they share (equal coordinates): merge them for a closed mesh."""
    from skimage.measure import marching_cubes

    if not resolution > 0:
        raise DesignError(f"the mesh resolution must be positive, got {resolution:g} mm")
    lo, hi = (np.asarray(v, dtype=float) for v in design.bounds())
    if np.any(lo > hi):
        raise DesignError("the design is empty: there is no surface to export")
    counts = [int(math.ceil((h - l) / resolution)) + 3 for l, h in zip(lo, hi)]
    if math.prod(counts) > MAX_SAMPLES:
        raise DesignError(
            f"a {resolution:g} mm grid over the design takes {math.prod(counts):,} samples (at most {MAX_SAMPLES:,})",
            hint="export at a coarser --resolution",
        )
    axes = [l - resolution + resolution * np.arange(n) for l, n in zip(lo, counts)]
    x, y = axes[0][:, None], axes[1][None, :]
    per_slab = max(2, _SLAB_SAMPLES // (counts[0] * counts[1]))
    vertices, faces, offset = [], [], 0
    start = 0
    previous = None
    while start < counts[2] - 1:
        stop = min(counts[2], start + per_slab)
        planes = [previous] if previous is not None else []
        planes += [_plane(design, x, y, axes[2][k], k, counts) for k in range(start + (previous is not None), stop)]
        volume = np.stack(planes, axis=2)
        previous = volume[:, :, -1]
        if volume.min() < 0 < volume.max():
            v, f, _, _ = marching_cubes(volume, 0.0, gradient_direction="descent")
            v[:, 2] += start  # grid indices: a plane shared by two slabs gives both the same vertices
            vertices.append(v)
            faces.append(f + offset)
            offset += len(v)
        start = stop - 1
    if not vertices:
        raise DesignError("the design has no surface on the export grid", hint="export at a finer --resolution")
    origin = np.array([a[0] for a in axes])
    return origin + np.vstack(vertices) * resolution, np.vstack(faces)


def _plane(design: Design, x: np.ndarray, y: np.ndarray, z: float, k: int, counts: list[int]) -> np.ndarray:
    """The signed distance on plane ``k`` (float32), positive on the grid's outer ring."""
    values = np.asarray(design.sdf(x, y, np.float64(z)), dtype=np.float32)
    values = np.nan_to_num(values, nan=1.0, posinf=1.0, neginf=-1.0)
    if k in (0, counts[2] - 1):
        values[...] = np.maximum(values, 1e-6)
    values[[0, -1], :] = np.maximum(values[[0, -1], :], 1e-6)
    values[:, [0, -1]] = np.maximum(values[:, [0, -1]], 1e-6)
    return values


def surface_mesh(design: Design, resolution: float):
    """The design's surface as a closed :class:`trimesh.Trimesh` (the slabs' shared
    vertices merged, the zero-area triangles of samples exactly on the surface dropped)."""
    import trimesh

    vertices, faces = mesh_arrays(design, resolution)
    mesh = trimesh.Trimesh(vertices, faces)
    mesh.update_faces(mesh.nondegenerate_faces())
    mesh.remove_unreferenced_vertices()
    return mesh


def export_mesh(design: Design, path: str | Path, resolution: float) -> tuple[int, int]:
    """Write the design's surface to ``path`` as a binary STL (atomically); returns the
    vertex and triangle counts."""
    import trimesh

    from fgslice.output import atomic_output

    mesh = surface_mesh(design, resolution)
    with atomic_output(path, "wb") as out:
        out.write(trimesh.exchange.stl.export_stl(mesh))
    return len(mesh.vertices), len(mesh.faces)
