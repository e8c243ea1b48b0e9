"""The resource estimate (``fgslice.resources``) against real slices of small parts.

Slices a few graded boxes and a cylinder (strategies 1 and 2, 1 to 16 colors) with
``--jobs 1``, each as its own process, and prints for each the estimated and the real
slicing time, peak memory (the command's largest resident set) and G-code size, with
their ratios (real / estimate). Run from the repository root::

    .venv/bin/python benchmarks/bench_estimates.py
"""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from fgslice.compat import open_design
from fgslice.resources import estimate_resources
from fgslice.settings import load_settings

BOX = 'fgrade(["x/{w} + 0.5", "0.5 - x/{w}"], ["blue", "yellow"]) {{ rectprism({w}, {d}, {h}); }}\n'
CYLINDER = 'fgrade(["z/{h}", "1 - z/{h}"], ["blue", "yellow"]) {{ cylinder({h}, {r}); }}\n'

CASES = [
    ("box 20x20x2 s2 c8", BOX.format(w=20, d=20, h=2), {"strategy": 2, "colors": 8}),
    ("box 40x40x4 s2 c16", BOX.format(w=40, d=40, h=4), {"strategy": 2, "colors": 16}),
    ("box 60x30x3 s2 c1", BOX.format(w=60, d=30, h=3), {"strategy": 2, "colors": 1}),
    ("box 40x40x4 s1 c4", BOX.format(w=40, d=40, h=4), {"strategy": 1, "colors": 4}),
    ("box 80x40x2 s1 c2", BOX.format(w=80, d=40, h=2), {"strategy": 1, "colors": 2}),
    ("cylinder r15 h10 s2 c8", CYLINDER.format(h=10, r=15), {"strategy": 2, "colors": 8}),
]


def _run(design: Path, output: Path, sets: dict) -> tuple[float, float]:
    """Wall time (s) and peak resident set (MB) of one ``fgslice slice`` process."""
    args = [sys.executable, "-c", "from fgslice.cli import main; main()", "slice", str(design), "-o", str(output),
            "--jobs", "1"]
    for key, value in sets.items():
        args += ["--set", f"{key}={value}"]
    start = time.perf_counter()
    proc = subprocess.Popen(args, stdout=subprocess.DEVNULL)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - start
    if status:
        raise SystemExit(f"{design} failed: status {status}")
    return wall, usage.ru_maxrss / 1024


def main() -> None:
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name, text, sets in CASES:
            design = Path(tmp, "part.vcad")
            design.write_text(text)
            output = Path(tmp, "part.gcode")
            settings = load_settings(None, {k: str(v) for k, v in sets.items()})
            est = estimate_resources(open_design(design), settings, jobs=1)
            wall, peak = _run(design, output, sets)
            size = output.stat().st_size / 1e6
            rows.append((name, est.slice_s, wall, est.memory_mb, peak, est.gcode_mb, size))
    print(f"{'part':26s} {'time est/real s':>17s} {'ratio':>6s} {'memory est/real MB':>20s} {'ratio':>6s} "
          f"{'G-code est/real MB':>19s} {'ratio':>6s}")
    for name, ts, tr, ms, mr, gs, gr in rows:
        print(f"{name:26s} {ts:8.2f} {tr:8.2f} {tr / ts:6.2f} {ms:10.0f} {mr:9.0f} {mr / ms:6.2f} "
              f"{gs:9.2f} {gr:9.2f} {gr / gs:6.2f}")
    print(json.dumps({"ratios_gcode": [round(r[6] / r[5], 3) for r in rows],
                      "ratios_time": [round(r[2] / r[1], 3) for r in rows],
                      "ratios_memory": [round(r[4] / r[3], 3) for r in rows]}))


if __name__ == "__main__":
    resource.setrlimit(resource.RLIMIT_CORE, (0, 0))
    main()
