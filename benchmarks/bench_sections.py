"""Section speed: the Benchy at 240 layer heights, and section_from_sdf on a superellipse.

Prints times (s or ms) and their ratio to the targets (ratio <= 1 meets the target).
Run: .venv/bin/python benchmarks/bench_sections.py
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import shapely

from fgslice.design.mesh import load_mesh
from fgslice.design.sampled import section_from_sdf

BENCHY = Path(__file__).resolve().parents[2] / "shared" / "data" / "meshes" / "3DBenchy.stl"
MESH_TARGET_S = 2.0
SDF_TARGET_MS = 5.0
SDF_POINTS = 10_000


def bench_mesh() -> None:
    """Time 240 mid-layer sections (0.2 mm layers) and a 10^4-point signed distance query."""
    if not BENCHY.exists():
        print(f"skipped mesh sections: {BENCHY} not found")
        return
    start = time.perf_counter()
    mesh = load_mesh(BENCHY)
    print(f"load {mesh.triangle_count} triangles: {time.perf_counter() - start:.2f} s")
    (lo, hi) = mesh.bounds()
    zs = lo[2] + 0.1 + 0.2 * np.arange(240)
    start, cpu = time.perf_counter(), time.process_time()
    sections = mesh.sections(zs)
    elapsed, cpu = time.perf_counter() - start, time.process_time() - cpu
    print(
        f"240 sections: {elapsed:.3f} s wall, {cpu:.3f} s CPU (target {MESH_TARGET_S} s, ratio {elapsed / MESH_TARGET_S:.2f}); "
        f"total area {sum(s.area for s in sections):.1f} mm2"
    )
    rng = np.random.default_rng(0)
    points = np.asarray(lo) + (np.asarray(hi) - np.asarray(lo)) * rng.random((SDF_POINTS, 3))
    start = time.perf_counter()
    mesh.sdf(points[:10, 0], points[:10, 1], points[:10, 2])
    print(f"sdf structures (first call): {time.perf_counter() - start:.2f} s")
    start = time.perf_counter()
    mesh.sdf(points[:, 0], points[:, 1], points[:, 2])
    print(f"sdf of {SDF_POINTS} points uniform in the bounding box: {time.perf_counter() - start:.2f} s")


def bench_sampled() -> None:
    """Time section_from_sdf on a 135 x 175 mm superellipse (exponent 4) at several cell sizes
    (0.4 mm is what a function gets at the default 0.1 mm section spacing)."""
    a, b = 67.5, 87.5

    def superellipse(x, y):
        return (((np.abs(x) / a) ** 4 + (np.abs(y) / b) ** 4) ** 0.25 - 1.0) * a

    box = (-70.0, -90.0, 70.0, 90.0)
    for cell in (0.4, 1.0, 2.0):
        section_from_sdf(superellipse, box, cell)
        repeats = 20
        start = time.perf_counter()
        for _ in range(repeats):
            section = section_from_sdf(superellipse, box, cell)
        per_call = (time.perf_counter() - start) / repeats * 1e3
        print(
            f"section_from_sdf cell {cell} mm: {per_call:.2f} ms/call "
            f"(target {SDF_TARGET_MS} ms, ratio {per_call / SDF_TARGET_MS:.2f}); "
            f"{len(shapely.get_coordinates(section))} vertices"
        )


if __name__ == "__main__":
    bench_mesh()
    bench_sampled()
