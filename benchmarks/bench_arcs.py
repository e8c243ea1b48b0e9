"""Arc fitting (``arc_fitting = emit_center``, ``fgslice.machine.arcs.fit_arcs``) on one
layer's worth of moves: curves of every radius and eccentricity, some noisy, as written
(3 decimals). Prints the moves, the arcs and lines they become, the CPU time and moves
per second.

    .venv/bin/python benchmarks/bench_arcs.py [--paths 3000] [--tolerance 0.0125] [--repeat 3]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from fgslice.machine.arcs import fit_arcs


def layer(paths: int, seed: int = 1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(starts, ends, path)`` of ``paths`` arcs of ellipses, 5-400 moves each."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(paths):
        n = rng.integers(5, 400)
        t = np.sort(rng.uniform(0, 2 * np.pi * rng.uniform(0.2, 1.5), n))
        r, c = rng.uniform(0.5, 60), rng.uniform(0, 200, 2)
        p = c + np.column_stack([r * np.cos(t), r * rng.uniform(0.5, 1) * np.sin(t)])
        out.append(np.round(p + rng.normal(0, rng.choice([0, 0.001, 0.01]), (n, 2)), 3))
    starts = np.array([p[0] for p in out])
    ends = np.vstack([p[1:] for p in out])
    return starts, ends, np.repeat(np.arange(len(out)), [len(p) - 1 for p in out])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--paths", type=int, default=3000)
    parser.add_argument("--tolerance", type=float, default=0.0125)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    starts, ends, path = layer(args.paths)
    best = np.inf
    for _ in range(args.repeat):
        start = time.process_time()
        fitted = fit_arcs(starts, ends, path, args.tolerance)
        best = min(best, time.process_time() - start)
    arcs = int((fitted.turn != 0).sum())
    print(f"{len(ends):,} moves of {args.paths} paths -> {arcs:,} arcs and {len(fitted.ends) - arcs:,} lines "
          f"(tolerance {args.tolerance} mm): {best:.2f} s CPU, {len(ends) / best:,.0f} moves/s")


if __name__ == "__main__":
    main()
