"""A union of many cubes listed one by one: the structure of the 114 548-cube design of
4.9 MB (a grid of ``translate(x, y, 0) { cube(0.6); }`` lines, 0.7 mm apart: 237 mm
square, three 0.2 mm layers).

Prints, for ``--cubes`` cubes: the design's size; parsing, one section and the field
(sdf and fractions at ``--points`` points) with long runs read as arrays
(``fgslice.design.statement_runs``, ``fgslice.design.copies``): their times, the field's
peak memory (tracemalloc), and the section's area checked against the cubes' area.
``--compare N`` does the same for N cubes both ways, runs read as arrays against one
node per statement (the parser's path), side by side with their ratios. ``--commands``
also runs ``fgslice check`` and ``fgslice slice`` on the design (wall and CPU seconds,
peak resident memory of the command and its workers, the extruded volume against the
cubes' volume).

    .venv/bin/python benchmarks/bench_union.py [--cubes 114548] [--points 32768] [--compare 2000] [--commands]
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np

import fgslice.design.statement_runs as statement_runs
from fgslice.design.language import parse_design

PITCH_MM = 0.7
SIZE_MM = 0.6


def cubes(n: int) -> str:
    """``n`` cubes of :data:`SIZE_MM` on a square grid :data:`PITCH_MM` apart, one line each."""
    side = int(np.ceil(np.sqrt(n)))
    lines = [f"translate({(i % side) * PITCH_MM:.1f}, {(i // side) * PITCH_MM:.1f}, 0) {{ cube({SIZE_MM}); }}"
             for i in range(n)]
    return "union() {\n" + "\n".join(lines) + "\n}\n"


def timed(fn):
    """``(result, CPU seconds)`` of ``fn()`` (one core's work: steadier than wall time on a
    shared machine)."""
    start = time.process_time()
    result = fn()
    return result, time.process_time() - start


def traced_peak(fn) -> float:
    """Peak MB of numpy's and Python's allocations during ``fn()`` (tracemalloc, which
    slows Python code down: timed apart)."""
    tracemalloc.start()
    fn()
    peak = tracemalloc.get_traced_memory()[1] / 1e6
    tracemalloc.stop()
    return peak


def figures(text: str, n: int, points: int) -> dict[str, tuple[float, float]]:
    """Seconds of parsing and of one section, seconds and peak MB of the field at
    ``points`` points (two sets of them, timed and traced); checks the section's area."""
    design, parse_s = timed(lambda: parse_design(text))
    section, section_s = timed(lambda: design.section(0.0))
    expected = n * SIZE_MM**2
    if abs(section.area - expected) > 1e-6 * expected:
        sys.exit(f"the section's area {section.area:.6f} mm2 is not the cubes' {expected:.6f} mm2")
    (x0, y0, z0), (x1, y1, z1) = design.bounds()
    timed_xyz, traced_xyz = np.random.default_rng(0).uniform([x0, y0, z0], [x1, y1, z1], (2, points, 3)).transpose(0, 2, 1)
    _, field_s = timed(lambda: (design.sdf(*timed_xyz), design.fractions(*timed_xyz)))
    field_mb = traced_peak(lambda: (design.sdf(*traced_xyz), design.fractions(*traced_xyz)))
    return {"parse": (parse_s, None), "section": (section_s, None), "field": (field_s, field_mb)}


def per_statement(text: str, n: int, points: int) -> dict[str, tuple[float, float]]:
    """:func:`figures` with one node per statement (no runs read as arrays)."""
    kept = statement_runs.MIN_RUN
    statement_runs.MIN_RUN = 10**12
    try:
        return figures(text, n, points)
    finally:
        statement_runs.MIN_RUN = kept


def command(args: list[str]) -> tuple[float, float, float, str]:
    """Wall s, CPU s (with its workers) and peak MB (the largest of the command and its
    workers, from ``wait4``) of ``fgslice ARGS``, and its output."""
    fgslice = Path(sys.executable).with_name("fgslice")
    start = time.perf_counter()
    proc = subprocess.Popen([str(fgslice), *args], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    out = proc.stdout.read()
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    return time.perf_counter() - start, usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024, out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cubes", type=int, default=114_548)
    parser.add_argument("--points", type=int, default=32_768)
    parser.add_argument("--compare", type=int, default=2000, help="cubes parsed both ways side by side (0: none)")
    parser.add_argument("--commands", action="store_true", help="also run fgslice check and fgslice slice")
    args = parser.parse_args()
    text = cubes(args.cubes)
    print(f"{args.cubes} cubes, {len(text) / 1e6:.2f} MB of design, {args.points} field points")
    fast = figures(text, args.cubes, args.points)
    print("  runs as arrays (CPU s): " + ", ".join(f"{k} {s:.2f} s" + (f" {mb:.0f} MB peak" if mb else "")
                                           for k, (s, mb) in fast.items()) + " (section area = the cubes')")
    if args.compare:
        small = cubes(args.compare)
        both = figures(small, args.compare, args.points), per_statement(small, args.compare, args.points)
        print(f"{args.compare} cubes, runs as arrays / a node per statement (CPU s):")
        for key in both[0]:
            (a, amb), (b, bmb) = both[0][key], both[1][key]
            peaks = f", peak {amb:.1f} / {bmb:.1f} MB" if amb else ""
            print(f"  {key:8s} {a:7.3f} s / {b:7.3f} s ({b / a:6.1f}x){peaks}")
    if args.commands:
        with tempfile.TemporaryDirectory() as folder:
            design = Path(folder) / "cubes.vcad"
            design.write_text(text)
            for name, extra in (("check", []), ("slice", ["-o", str(Path(folder) / "cubes.gcode")])):
                wall, cpu, peak, out = command([name, str(design), *extra])
                volume = re.search(r"([0-9.]+) cm3", out) if name == "slice" else None
                shown = f", {float(volume.group(1)):.2f} cm3 extruded for {args.cubes * SIZE_MM**3 / 1000:.2f} cm3 of cubes" \
                    if volume else ""
                print(f"fgslice {name}: {wall:.1f} s wall, {cpu:.1f} s CPU, peak {peak:.0f} MB{shown}")


if __name__ == "__main__":
    main()
