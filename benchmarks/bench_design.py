"""Design evaluation speed on the example vase.

Prints the time to evaluate the signed distance and the material fractions at 10^6
points (target: 0.2 s together) and the time of 500 sections (one per 0.2 mm layer),
each with its ratio to the target (below 1 is better than the target).

Run: .venv/bin/python benchmarks/bench_design.py
"""

import time
from pathlib import Path

import numpy as np

from fgslice.design import load_design

VASE = Path(__file__).resolve().parents[1] / "examples" / "vase.vcad"
TARGET_FIELDS_S = 0.2
N_POINTS = 1_000_000
N_SECTIONS = 500


def best_of(repeats, fn):
    """Least wall and least CPU time (s) of ``repeats`` calls (CPU time is steadier on a shared machine)."""
    walls, cpus = [], []
    for _ in range(repeats):
        start, cpu = time.perf_counter(), time.process_time()
        fn()
        walls.append(time.perf_counter() - start)
        cpus.append(time.process_time() - cpu)
    return min(walls), min(cpus)


def main() -> None:
    design = load_design(VASE)
    (x0, y0, z0), (x1, y1, z1) = design.bounds()
    rng = np.random.default_rng(0)
    x = rng.uniform(x0, x1, N_POINTS)
    y = rng.uniform(y0, y1, N_POINTS)
    z = rng.uniform(z0, z1, N_POINTS)
    t_sdf, c_sdf = best_of(3, lambda: design.sdf(x, y, z))
    t_frac, c_frac = best_of(3, lambda: design.fractions(x, y, z))
    xs, ys = np.linspace(x0, x1, 1000)[None, :], np.linspace(y0, y1, 1000)[:, None]
    t_grid, c_grid = best_of(3, lambda: design.fractions(xs, ys, (z0 + z1) / 2))
    total = t_sdf + t_frac
    print(f"vase sdf at {N_POINTS:,} points:       {t_sdf:.3f} s ({c_sdf:.3f} s CPU)")
    print(f"vase fractions at {N_POINTS:,} points: {t_frac:.3f} s ({c_frac:.3f} s CPU)")
    print(f"vase fractions on a 1000 x 1000 grid:  {t_grid:.3f} s ({c_grid:.3f} s CPU)")
    print(
        f"total {total:.3f} s ({c_sdf + c_frac:.3f} s CPU), target {TARGET_FIELDS_S} s, "
        f"ratio {total / TARGET_FIELDS_S:.2f} ({(c_sdf + c_frac) / TARGET_FIELDS_S:.2f} CPU)"
    )
    heights = np.linspace(z0, z1, N_SECTIONS + 2)[1:-1]
    start = time.perf_counter()
    vertices = sum(len(p.exterior.coords) for h in heights for p in design.section(h).geoms)
    t_sections = time.perf_counter() - start
    print(
        f"{N_SECTIONS} vase sections: {t_sections:.3f} s ({1000 * t_sections / N_SECTIONS:.2f} ms each, "
        f"{vertices / N_SECTIONS:.0f} vertices each)"
    )


if __name__ == "__main__":
    main()
