"""What it costs a local pool to hand layer results back to the parent.

The vase's layers 240-246 (strategy 1, 16 colors, 10 walls) are sliced once, before the
pool forks; every task then returns that run of 7 results again, 72 tasks (500 layers,
as the vase's pool gets them), with the same window of runs in flight. Each way of
returning them runs in a fresh process, ``--repeat`` times in turns:

* ``nothing``: the tasks return a list of None (what forking, tasks and futures cost);
* ``pipe``: the results travel through the pool's pipe, pickled by ``concurrent.futures``;
* ``slots``: fgslice's executor, results pickled into shared memory (``executor._ResultSlots``).

Prints the median wall time and CPU time (parent incl. its threads, and the workers),
and what moving the results costs over ``nothing``.
Run: ``.venv/bin/python benchmarks/bench_executor.py [--repeat 5]``.
"""

from __future__ import annotations

import argparse
import json
import resource
import statistics
import subprocess
import sys
import time
from collections import deque
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
TASKS = 72
RUN = 7
WINDOW = 64
MODES = ("nothing", "pipe", "slots")


def vase_run() -> list:
    """The vase's layers 240-246 as the pool's workers return them."""
    from fgslice import pipeline
    from fgslice.design.language import load_design
    from fgslice.settings import load_settings
    from fgslice.slicing.palette import Palette
    from fgslice.slicing.plan_layers import layer_heights, place_design

    design = load_design(ROOT / "examples" / "vase.vcad")
    settings = load_settings(None, {"strategy": 1, "colors": 16, "layer_height": 0.2, "walls": 10,
                                    "infill_density": 0, "top_layers": 0, "bottom_layers": 0})
    layers = layer_heights(design, settings)
    job = pipeline.SliceJob(design, settings, Palette(2, 16), place_design(design, settings), layers,
                            np.array([settings.bed_x / 2, settings.bed_y / 2]))
    job.outlines = [o for batch in range(0, len(layers), 8)
                    for o in pipeline._section_task(job, range(batch, min(batch + 8, len(layers))))]
    return [pipeline._layer_task(job, i) for i in range(240, 240 + RUN)]


RESULTS: list = []


def _nothing(_: int) -> list:
    return [None] * RUN


def _pipe(_: int) -> list:
    return RESULTS


def _slot_item(state: list, item: int) -> object:
    return state[item % RUN]


def measure(mode: str) -> dict:
    """One way of returning the results, in this process."""
    import multiprocessing

    from fgslice import executor

    global RESULTS
    RESULTS = vase_run()
    start, before = time.perf_counter(), resource.getrusage(resource.RUSAGE_SELF)
    if mode == "slots":
        received = sum(1 for _ in executor.map_ordered(_slot_item, RESULTS, range(TASKS * RUN), jobs=2, window=WINDOW))
    else:
        context = multiprocessing.get_context("fork")
        with ProcessPoolExecutor(2, mp_context=context) as pool:
            task = _pipe if mode == "pipe" else _nothing
            pending: deque = deque(pool.submit(task, k) for k in range(WINDOW // RUN))
            submitted, received = len(pending), 0
            while pending:
                received += len(pending.popleft().result())
                if submitted < TASKS:
                    pending.append(pool.submit(task, submitted))
                    submitted += 1
    wall = time.perf_counter() - start
    after, workers = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    parent = (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)
    return {"wall": wall, "parent": parent, "workers": workers.ru_utime + workers.ru_stime, "received": received,
            "switches": after.ru_nvcsw - before.ru_nvcsw}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--mode", choices=MODES, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.mode:
        print(json.dumps(measure(args.mode)))
        return
    runs: dict[str, list[dict]] = {mode: [] for mode in MODES}
    for _ in range(args.repeat):
        for mode in MODES:
            out = subprocess.run([sys.executable, __file__, "--mode", mode], capture_output=True, text=True, check=True)
            runs[mode].append(json.loads(out.stdout))
    med = {mode: {key: statistics.median(r[key] for r in rs) for key in ("wall", "parent", "workers", "switches")}
           for mode, rs in runs.items()}
    print(f"{TASKS} tasks of {RUN} vase layers, 2 workers, median of {args.repeat} runs each")
    print(f"{'mode':8} {'wall s':>7} {'parent cpu s':>13} {'workers cpu s':>14} {'switches':>9} {'moving cpu s':>13}")
    base = med["nothing"]["parent"] + med["nothing"]["workers"]
    for mode, m in med.items():
        moving = m["parent"] + m["workers"] - base
        print(f"{mode:8} {m['wall']:7.3f} {m['parent']:13.3f} {m['workers']:14.3f} {m['switches']:9.0f} {moving:13.3f}")
    pipe, slots = (med[m]["parent"] + med[m]["workers"] - base for m in ("pipe", "slots"))
    print(f"slots / pipe, CPU to move the results: {slots / pipe:.2f}")


if __name__ == "__main__":
    main()
