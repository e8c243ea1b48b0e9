"""Planning speed: order_layer on 5000 paths, apply_lookahead over 500 layers x 40 paths,
and order / purge / G-code writing per layer of a vase-like print (10 wall loops cut into
16 colors, ~600 open pieces per layer, one wall unit, a purge per color).

Prints wall and CPU times (best of several runs) and the travel ratio of the greedy tour
against the input order. Run: ``.venv/bin/python benchmarks/bench_planning.py``.
"""

from __future__ import annotations

import io
import time

import numpy as np
import shapely

from fgslice.machine.dialects import make_dialect
from fgslice.machine.gcode import GcodeWriter
from fgslice.planning.lookahead import apply_lookahead
from fgslice.planning.order import order_layer, travel_distance
from fgslice.planning.plan import LayerPlan, SetState
from fgslice.planning.purge import PurgeStats, PurgeTower, insert_purges
from fgslice.settings import Settings
from fgslice.slicing.palette import Palette
from fgslice.toolpaths.paths import LayerPaths, Path, Role


def best_of(fn, runs=5):
    """(best wall s, best CPU s) over ``runs`` calls of ``fn``."""
    wall, cpu = [], []
    for _ in range(runs):
        w0, c0 = time.perf_counter(), time.process_time()
        fn()
        wall.append(time.perf_counter() - w0)
        cpu.append(time.process_time() - c0)
    return min(wall), min(cpu)


def layer_of_segments(n, colors, rng):
    """``n`` shuffled infill segments on a grid, a tenth of them closed wall loops."""
    m = int(np.ceil(np.sqrt(n)))
    paths = []
    for i in range(n):
        x, y = (i % m) * 2.0, (i // m) * 2.0
        color = int(rng.integers(colors))
        if i % 10 == 0:
            t = np.linspace(0, 2 * np.pi, 24, endpoint=False)
            paths.append(Path(np.c_[x + 0.7 * np.cos(t), y + 0.7 * np.sin(t)], Role.PERIMETER, color, 0.4, 0.2, True))
        else:
            paths.append(Path(np.array([[x, y], [x + 1.5, y]]), Role.INTERNAL_INFILL, color, 0.4, 0.2))
    rng.shuffle(paths)
    return LayerPaths(0, 0.2, 0.2, paths)


def lookahead_plans(n_layers, paths_per_layer, rng):
    plans = []
    for k in range(n_layers):
        steps = []
        for g in range(4):
            steps.append(SetState((k + g) % 8))
            for _ in range(paths_per_layer // 4):
                steps.append(Path(rng.uniform(0, 100, (4, 2)), Role.SOLID_INFILL, (k + g) % 8, 0.4, 0.2))
        plans.append(LayerPlan(k, 0.2 * (k + 1), 0.2, steps))
    return plans


def vase_layers(n_layers, colors=16, walls=10, pieces_per_loop=64):
    """Wall loops of an ellipse (67 x 87 mm semi-axes) cut into ``pieces_per_loop`` open
    pieces whose color follows a sin*cos field quantized to ``colors`` bins."""
    t = np.linspace(0, 2 * np.pi, pieces_per_loop * 6 + 1)
    layers = []
    for k in range(n_layers):
        paths = []
        for wall in range(walls):
            a, b = 67.0 - 0.45 * wall, 87.0 - 0.45 * wall
            ring = np.c_[150 + a * np.cos(t + 0.01 * k), 130 + b * np.sin(t + 0.01 * k)]
            for piece in np.array_split(np.arange(t.size), pieces_per_loop):
                points = ring[piece[0] : piece[-1] + 2]
                f = (1 + np.sin(0.025 * points[0, 0] + 0.0375 * points[0, 1]) * np.cos(0.0375 * points[0, 0])) / 2
                role = Role.EXTERNAL_PERIMETER if wall == 0 else Role.PERIMETER
                paths.append(Path(points, role, min(int(f * colors), colors - 1), 0.45, 0.2, group=0))
        layers.append(LayerPaths(k, 0.2 * (k + 1), 0.2, paths))
    return layers


def vase_stages(n_layers=40, colors=16):
    """CPU ms per layer of order_layer, insert_purges and GcodeWriter.write_layer."""
    settings = Settings(strategy=1, colors=colors, walls=10, infill_density=0)
    palette = Palette(2, colors)
    layers = vase_layers(n_layers, colors)
    tower = PurgeTower.plan(shapely.box(80, 40, 220, 220), settings, colors, n_layers)
    best = {}
    for _ in range(3):
        c0 = time.process_time()
        plans = [order_layer(lp, palette.order_for_layer(lp.index), np.zeros(2), "walls_first") for lp in layers]
        c1 = time.process_time()
        purged = list(insert_purges(iter(plans), tower, settings, palette, PurgeStats()))
        c2 = time.process_time()
        writer = GcodeWriter(io.StringIO(), settings, palette, make_dialect(settings, palette), comments={})
        writer.write_header()
        for plan in purged:
            writer.write_layer(plan)
        c3 = time.process_time()
        for name, cpu in (("order", c1 - c0), ("purge", c2 - c1), ("write", c3 - c2)):
            best[name] = min(best.get(name, np.inf), cpu / n_layers * 1e3)
    return best, np.mean([len(lp.paths) for lp in layers])


def main() -> None:
    rng = np.random.default_rng(0)
    ref_wall, _ = best_of(lambda: np.sort(rng.random(1_000_000)), runs=3)
    print(f"machine reference: sorting 1e6 floats takes {ref_wall * 1e3:.1f} ms")
    for colors in (1, 4):
        layer = layer_of_segments(5000, colors, rng)
        wall, cpu = best_of(lambda: order_layer(layer, np.arange(colors), np.zeros(2), "walls_first"))
        plan = order_layer(layer, np.arange(colors), np.zeros(2), "walls_first")
        ratio = travel_distance(plan.paths, np.zeros(2)) / travel_distance(layer.paths, np.zeros(2))
        print(f"order_layer, 5000 paths, {colors} color(s): {wall * 1e3:.1f} ms wall, {cpu * 1e3:.1f} ms CPU; "
              f"travel {ratio:.3f} x the input order's")
    stages, paths_per_layer = vase_stages()
    print(f"vase-like layer ({paths_per_layer:.0f} paths, 16 colors), CPU ms per layer: "
          + ", ".join(f"{name} {ms:.2f}" for name, ms in stages.items()))
    plans = lookahead_plans(500, 40, rng)
    layer_mm = np.mean([sum(p.length for p in plan.paths) for plan in plans])
    for distance in (450.0, 960.0):
        wall, cpu = best_of(lambda: sum(1 for _ in apply_lookahead(iter(plans), distance)), runs=3)
        print(f"apply_lookahead, 500 layers x 40 paths, {distance:.0f} mm (= {distance / layer_mm:.2f} layers): "
              f"{wall * 1e3:.0f} ms wall, {cpu * 1e3:.0f} ms CPU ({wall / 500 * 1e3:.2f} ms per layer)")


if __name__ == "__main__":
    main()
