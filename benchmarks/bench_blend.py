"""CPU time of blend()'s box average against the same design without it.

The design is OpenVCAD's cross-fade: two touching 40 mm cubes of two materials, with and
without ``blend(10, 10, 10)``. The fractions are sampled on one layer's grid (80 x 40 mm
at 0.4 mm, 20,000 points) and on scattered points; every blended fraction costs
``LATTICE_POINTS`` (512) evaluations of the children. Prints CPU seconds per grid and
points per second, and the ratio blended / plain; then ``blend(1e6)``, whose box spans
the whole part (one mean for every point), against ``blend(10, 10, 10)`` on the grid.

Run: ``.venv/bin/python benchmarks/bench_blend.py [--repeat 3]``
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from fgslice.design import parse_design
from fgslice.design.blend import LATTICE_POINTS

BLOCKS = """union() {
    translate(-20, 0, 0) { rectprism((40, 40, 40), "red"); }
    translate(20, 0, 0) { rectprism((40, 40, 40), "blue"); }
}"""


def _cpu(fn, repeat: int) -> float:
    """Smallest CPU time (s) of ``repeat`` calls of ``fn``."""
    best = float("inf")
    for _ in range(repeat):
        start = time.process_time()
        fn()
        best = min(best, time.process_time() - start)
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    plain = parse_design(BLOCKS)
    blended = parse_design(f"blend(10, 10, 10) {{ {BLOCKS} }}")
    xs, ys = np.arange(-40, 40, 0.4), np.arange(-20, 20, 0.4)
    rng = np.random.default_rng(0)
    points = rng.uniform([-40, -20, -20], [40, 20, 20], size=(20_000, 3)).T
    print(f"stencil: {LATTICE_POINTS} samples per point")
    for label, call in (
        ("layer grid 200 x 100", lambda d: d.fractions(xs[None, :], ys[:, None], 0.0)),
        ("20,000 scattered points", lambda d: d.fractions(*points)),
    ):
        times = {name: _cpu(lambda: call(design), args.repeat) for name, design in (("plain", plain), ("blend", blended))}
        print(f"{label}: plain {times['plain'] * 1e3:.1f} ms, blend {times['blend'] * 1e3:.0f} ms "
              f"({20_000 / times['blend']:,.0f} points/s), ratio {times['blend'] / times['plain']:.0f}")
    huge = parse_design(f"blend(1e6) {{ {BLOCKS} }}")
    grid = lambda d: d.fractions(xs[None, :], ys[:, None], 0.0)  # noqa: E731
    big, ten = _cpu(lambda: grid(huge), args.repeat), _cpu(lambda: grid(blended), args.repeat)
    print(f"layer grid, blend(1e6) (spans the whole part: one mean): {big * 1e3:.1f} ms, "
          f"blend(10, 10, 10) {ten * 1e3:.0f} ms, ratio {big / ten:.3f}")


if __name__ == "__main__":
    main()
