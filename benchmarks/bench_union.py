"""A union of many cubes, as a design listing them one by one (the structure of a
114 548-cube design of 4.9 MB, at a size a benchmark can run): parsing, a section, and
the field at a chunk of points with the children located by bounding box
(``fgslice.design.union_index``) against every child evaluated, side by side.

    .venv/bin/python benchmarks/bench_union.py [--cubes 2000] [--points 8192]
"""

from __future__ import annotations

import argparse
import time
import tracemalloc

import numpy as np

import fgslice.design.union_index as union_index
from fgslice.design.language import parse_design


def cubes(n: int) -> str:
    side = int(np.ceil(np.sqrt(n)))
    lines = [f"  translate({(i % side) * 1.5:.2f}, {(i // side) * 1.5:.2f}, 0) {{ cube(0.6); }}" for i in range(n)]
    return "union() {\n" + "\n".join(lines) + "\n}\n"


def field_cost(text: str, many: int, points: np.ndarray) -> tuple[float, float]:
    """Seconds and peak MB (tracemalloc) of the sdf and the fractions at ``points``."""
    union_index.MANY_CHILDREN = many
    design = parse_design(text)
    tracemalloc.start()
    start = time.perf_counter()
    design.sdf(*points.T)
    design.fractions(*points.T)
    elapsed = time.perf_counter() - start
    peak = tracemalloc.get_traced_memory()[1] / 1e6
    tracemalloc.stop()
    return elapsed, peak


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--cubes", type=int, default=2000)
    parser.add_argument("--points", type=int, default=8192)
    args = parser.parse_args()
    text = cubes(args.cubes)
    start = time.perf_counter()
    design = parse_design(text)
    parsed = time.perf_counter() - start
    start = time.perf_counter()
    design.section(0.0)
    sectioned = time.perf_counter() - start
    print(f"{args.cubes} cubes, {len(text) / 1e6:.2f} MB of design: parse {parsed:.2f} s, one section {sectioned:.2f} s")
    (x0, y0, z0), (x1, y1, z1) = design.bounds()
    rng = np.random.default_rng(0)
    points = rng.uniform([x0, y0, z0], [x1, y1, z1], (args.points, 3))
    default = union_index.MANY_CHILDREN
    every_s, every_mb = field_cost(text, 10**9, points)
    index_s, index_mb = field_cost(text, default, points)
    print(f"sdf + fractions at {args.points} points: every child {every_s:.2f} s, {every_mb:.0f} MB peak; "
          f"by bounding box {index_s:.2f} s, {index_mb:.0f} MB peak; ratios {every_s / index_s:.2f}x time, "
          f"{every_mb / max(index_mb, 1e-9):.1f}x memory")


if __name__ == "__main__":
    main()
