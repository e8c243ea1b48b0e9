"""CPU time of strategy 2's sliver hand-over, against the layer's whole strategy 2 toolpaths.

Three layers with bands narrower than a bead: a gear graded by a sigmoid of rho (a
0.5 mm ring at rho = 4, 4 colors), a plate with a ``thresh`` boundary along a diagonal
(16 colors) and a plate graded by ``sin(3x)`` (8 colors, most bands narrower than a bead).
For each prints the CPU ms of ``give_slivers`` and of ``strategy2.layer_paths`` (which
includes it), their ratio, and the area handed over.

Run: ``.venv/bin/python benchmarks/bench_slivers.py [--repeat 5]``
"""

from __future__ import annotations

import argparse
import time

from fgslice.design import api
from fgslice.settings import load_settings
from fgslice.slicing.palette import Palette
from fgslice.slicing.plan_layers import place_design
from fgslice.slicing.regions import slice_layer
from fgslice.toolpaths import strategy2
from fgslice.toolpaths.slivers import give_slivers

SIGMOID = "1/(1+exp(-4.5(rho-4)))"


def _gear():
    teeth = [api.rotate((0, 0, 30 * i), api.translate((8.5, 0, 0), api.rectprism(3, 2.4, 2))) for i in range(12)]
    return api.fgrade([SIGMOID, f"1-{SIGMOID}"], ["red", "blue"], api.union(api.cylinder(7.5, 2), *teeth))


CASES = {
    "gear, sigmoid ring, 4 colors": (_gear, 4),
    "plate, thresh diagonal, 16 colors": (
        lambda: api.fgrade(["0.5+(x+y)/10", "0.5-(x+y)/10"], ["red", "blue"], api.rectprism(20, 12, 2), mode="thresh"),
        16,
    ),
    "plate, sin(3x), 8 colors": (
        lambda: api.fgrade(["0.5+0.5*sin(3x)", "0.5-0.5*sin(3x)"], ["red", "blue"], api.rectprism(20, 12, 2)),
        8,
    ),
}


def _cpu_ms(fn, repeat: int) -> float:
    """Smallest CPU time of ``repeat`` calls, ms."""
    best = float("inf")
    for _ in range(repeat):
        start = time.process_time()
        fn()
        best = min(best, time.process_time() - start)
    return best * 1000


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    print(f"{'layer':36s} {'slivers ms':>10s} {'layer ms':>9s} {'share':>6s} {'handed mm2':>10s}")
    for name, (tree, colors) in CASES.items():
        design = api.design(tree())
        settings = load_settings(None, {"colors": str(colors)})
        palette = Palette(2, colors)
        regions = slice_layer(design, place_design(design, settings), palette, 3, 0.8, 0.2, settings)
        handed = give_slivers(regions.faces, settings.bead_width)[1]
        slivers = _cpu_ms(lambda: give_slivers(regions.faces, settings.bead_width), args.repeat)
        layer = _cpu_ms(lambda: strategy2.layer_paths(regions, settings), args.repeat)
        print(f"{name:36s} {slivers:10.1f} {layer:9.1f} {slivers / layer:6.2f} {handed:10.2f}")


if __name__ == "__main__":
    main()
