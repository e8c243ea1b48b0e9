"""G-code size of a large part: fgslice against PrusaSlicer for the same 200 x 200 mm box.

The box (``--height`` mm high, default 150) is sliced single material with 0.2 mm layers,
2 walls, 100 % rectilinear infill and one skirt loop, centred on the bed, by ``fgslice``
(strategy 1: walls and infill as PrusaSlicer lays them; and strategy 2: every face
filled densely, the same box in one color) and by ``prusa-slicer --export-gcode``
(skipped with a note when it is not installed). Each line gives the file's size, its
lines, bytes per layer and the ratio to PrusaSlicer's file (target: at most 1.2).

``--graded`` adds the box graded in 3-D (``compare_commits.box200_design``: 16 colors,
strategy 2, spherical bands), whose curved faces make many short segments, with
``arc_fitting = disabled`` and ``emit_center`` side by side.

Run: ``.venv/bin/python benchmarks/bench_gcode_size.py [--height 150] [--jobs 2] [--graded]``.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import trimesh

import compare_commits
import run_all

TARGET_RATIO = 1.2
LAYER_MM = 0.2
SINGLE = ("--layer-height", "0.2", "--set", "walls=2", "--set", "infill_density=100",
          "--set", "infill_pattern=rectilinear", "--set", "skirt_loops=1")
"""fgslice's settings for the single-material box (PrusaSlicer's below match them)."""


def prusa_command(stl: Path, out: Path) -> list[str] | None:
    """PrusaSlicer's command for the single-material box, or None when not installed."""
    prusa = shutil.which("prusa-slicer")
    if not prusa:
        return None
    return [prusa, "--export-gcode", "--layer-height", "0.2", "--first-layer-height", "0.2", "--perimeters", "2",
            "--fill-density", "100%", "--fill-pattern", "rectilinear", "--top-fill-pattern", "rectilinear",
            "--bottom-fill-pattern", "rectilinear", "--skirts", "1", "--center", "125,105", "-o", str(out), str(stl)]


def run(cmd: list[str]) -> float:
    """Run ``cmd`` (its output hidden unless it fails); seconds of wall time."""
    start = time.perf_counter()
    done = subprocess.run(cmd, cwd=run_all.ROOT, capture_output=True, text=True,
                          env={**os.environ, "SOURCE_DATE_EPOCH": "0"})
    if done.returncode != 0:
        sys.exit(f"{' '.join(map(str, cmd))} failed:\n{done.stderr[-2000:]}")
    return time.perf_counter() - start


def describe(name: str, out: Path, layers: int, seconds: float, reference: int | None) -> None:
    """One line of figures for the G-code file ``out``."""
    size = out.stat().st_size
    with open(out, "rb") as handle:
        lines = sum(block.count(b"\n") for block in iter(lambda: handle.read(1 << 20), b""))
    ratio = f"{size / reference:6.3f}" if reference else "   n/a"
    print(f"{name:34s} {size / 1e6:9.2f} MB {lines:11,d} lines {size / layers / 1e3:8.1f} kB/layer"
          f"  ratio {ratio}  ({seconds:.0f} s)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--height", type=float, default=150.0, help="box height, mm (150: the full box)")
    parser.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="fgslice worker processes")
    parser.add_argument("--graded", action="store_true", help="also the box graded in 3-D, arcs off and on")
    args = parser.parse_args()
    layers = max(1, round(args.height / LAYER_MM))
    run_all.byte_compile()
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        stl = work / "box.stl"
        box = trimesh.creation.box((200.0, 200.0, args.height))
        box.apply_translation((0.0, 0.0, args.height / 2))
        box.export(stl)
        plain = work / "box.vcad"
        plain.write_text(f"rectprism(200, 200, {args.height:g});\n")
        print(f"200 x 200 x {args.height:g} mm box, {layers} layers of {LAYER_MM} mm, single material, 100 % infill")
        reference = None
        prusa_out = work / "prusa.gcode"
        command = prusa_command(stl, prusa_out)
        if command is None:
            print("prusa-slicer: not installed (Debian package prusa-slicer); no ratio")
        else:
            seconds = run(command)
            reference = prusa_out.stat().st_size
            describe("prusa-slicer", prusa_out, layers, seconds, reference)
            prusa_out.unlink()
        for name, extra in (("fgslice strategy 1", ("--strategy", "1")), ("fgslice strategy 2", ("--strategy", "2"))):
            out = work / "fgslice.gcode"
            seconds = run(run_all.fgslice_cmd(plain, SINGLE + extra, out, args.jobs))
            describe(name, out, layers, seconds, reference)
            out.unlink()
        if args.graded:
            graded = work / "graded.vcad"
            graded.write_text(compare_commits.box200_design(args.height))
            for arcs in ("disabled", "emit_center"):
                out = work / "graded.gcode"
                seconds = run(run_all.fgslice_cmd(graded, compare_commits.BOX200_ARGS + ("--set", f"arc_fitting={arcs}"),
                                                  out, args.jobs))
                describe(f"graded, 16 colors, arcs {arcs}", out, layers, seconds, reference)
                out.unlink()
    print(f"target: fgslice's file at most {TARGET_RATIO}x PrusaSlicer's")


if __name__ == "__main__":
    main()
