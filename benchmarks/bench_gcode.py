"""Speed of the G-code writer, reader and verifier on synthetic layers.

Two kinds of layers, 4 colors on the marlin-mixing profile:

* "loops": concentric closed loops of 400 vertices (strategy 2 fills, walls);
* "lines": rectilinear infill of 2-point lines (one travel + one move per path, the
  writer's worst case per move).

Prints moves/s written, lines/s read and verified (CPU time), and the output size per move.
Run: ``.venv/bin/python benchmarks/bench_gcode.py [--moves 1000000]``.
"""

from __future__ import annotations

import argparse
import io
import time

import numpy as np

from fgslice.machine.dialects import make_dialect
from fgslice.machine.gcode import GcodeWriter
from fgslice.machine.gcode_reader import read_gcode
from fgslice.machine.verify import verify_gcode
from fgslice.planning.plan import LayerPlan, SetState
from fgslice.settings import load_settings
from fgslice.slicing.palette import Palette
from fgslice.toolpaths.paths import Path, Role


def loop_layer(index: int, n_colors: int, vertices: int = 400, loops: int = 40) -> LayerPlan:
    """Concentric loops around the bed center, colored by ring."""
    t = np.linspace(0, 2 * np.pi, vertices, endpoint=False)
    steps = []
    for k in range(loops):
        r = 5.0 + 0.4 * k
        color = k * n_colors // loops
        if k == 0 or color != (k - 1) * n_colors // loops:
            steps.append(SetState(color))
        pts = np.column_stack([110 + r * np.cos(t), 110 + r * np.sin(t)])
        steps.append(Path(pts, Role.PERIMETER, color, 0.4, 0.2, closed=True))
    return LayerPlan(index, 0.2 * (index + 1), 0.2, steps)


def line_layer(index: int, n_colors: int, lines: int = 4000) -> LayerPlan:
    """Rectilinear 2-point infill lines over a 100 mm square, colored by X band."""
    steps = []
    xs = np.linspace(60, 160, lines)
    for k, x in enumerate(xs):
        color = k * n_colors // lines
        if k == 0 or color != (k - 1) * n_colors // lines:
            steps.append(SetState(color))
        y0, y1 = (60.0, 160.0) if k % 2 == 0 else (160.0, 60.0)
        steps.append(Path(np.array([[x, y0], [x, y1]]), Role.INTERNAL_INFILL, color, 0.4, 0.2))
    return LayerPlan(index, 0.2 * (index + 1), 0.2, steps)


def bench(kind: str, moves_wanted: int) -> None:
    settings = load_settings("marlin-mixing")
    palette = Palette(2, 4)
    make = loop_layer if kind == "loops" else line_layer
    per_layer = sum(len(p.vertices) - 1 for p in make(0, 4).paths)
    layers = [make(i, 4) for i in range(max(1, moves_wanted // per_layer))]
    moves = per_layer * len(layers)

    out = io.StringIO()
    writer = GcodeWriter(out, settings, palette, make_dialect(settings, palette), comments={})
    t0 = time.process_time()
    writer.write_header()
    for plan in layers:
        writer.write_layer(plan)
    stats = writer.finish()
    t_write = time.process_time() - t0
    text = out.getvalue()

    t0 = time.process_time()
    program = read_gcode(text)
    t_read = time.process_time() - t0
    t0 = time.process_time()
    faults = verify_gcode(program, settings)
    t_verify = time.process_time() - t0

    n_lines = text.count("\n")
    print(f"{kind}: {moves:,} moves, {n_lines:,} lines, {len(text) / 1e6:.1f} MB "
          f"({len(text) / moves:.1f} bytes/move), {stats['state_changes']} state changes")
    print(f"  write  {t_write:6.2f} s  {moves / t_write / 1e6:6.2f} M moves/s")
    print(f"  read   {t_read:6.2f} s  {n_lines / t_read / 1e6:6.2f} M lines/s  "
          f"({len(program.e):,} moves parsed)")
    print(f"  verify {t_verify:6.2f} s  {n_lines / t_verify / 1e6:6.2f} M lines/s  ({len(faults)} faults)")
    print(f"  read / write time ratio {t_read / t_write:.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--moves", type=int, default=1_000_000, help="moves per case")
    args = parser.parse_args()
    for kind in ("loops", "lines"):
        bench(kind, args.moves)


if __name__ == "__main__":
    main()
