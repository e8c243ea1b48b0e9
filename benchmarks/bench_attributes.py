"""Cost of grading fan, flow and speed per extrusion segment.

Slices a 100 x 20 x 2 mm plate (one process, verification on) plain, with a fan
attribute and with fan, flow and speed attributes, each strategy, the variants
interleaved ``--repeat`` times, and prints the best CPU time of each, its ratio to the
plain slice, and the G-code moves written per move of the plain slice.
Run: ``.venv/bin/python benchmarks/bench_attributes.py [--repeat 3]``.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from fgslice.design import parse_design
from fgslice.machine.gcode_reader import read_gcode
from fgslice.pipeline import slice_to_gcode
from fgslice.settings import load_settings

PLATE = "rectprism(100, 20, 2);"
VARIANTS = {
    "plain": PLATE,
    "fan": f'attribute("fan", "50 + 0.6*x") {{ {PLATE} }}',
    "fan+flow+speed": f'attribute("fan", "50 + 0.6*x") {{ attribute("flow", "90 + 0.2*x") {{ '
                      f'attribute("speed", "80 + y") {{ {PLATE} }} }} }}',
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        for strategy in (2, 1):
            settings = load_settings(None, {"strategy": str(strategy)})
            best = {name: float("inf") for name in VARIANTS}
            moves = {}
            for _ in range(args.repeat):
                for name, text in VARIANTS.items():
                    out = Path(folder) / f"{name}.gcode"
                    design = parse_design(text)
                    start = time.process_time()
                    slice_to_gcode(design, settings, out, jobs=1)
                    best[name] = min(best[name], time.process_time() - start)
                    moves[name] = len(read_gcode(out).e)
            for name in VARIANTS:
                print(f"strategy {strategy} {name:<15} {best[name]:6.2f} s CPU  x{best[name] / best['plain']:.2f}  "
                      f"moves x{moves[name] / moves['plain']:.2f}")


if __name__ == "__main__":
    main()
