"""Meshes under a rotation, a mirror or a scaling against the same meshes upright:
`fgslice slice` wall and CPU time of each, side by side in one run, and their ratio
(target: at most 2).

Rows on the 3DBenchy (60 x 31 x 48 mm, 225,154 triangles), each against the Benchy
upright: `rotate(90, 0, 0)` (about X, on its side), `rotate(0, 90, 0)` (about Y, on its
stern), `rotate(0, 0, 90)` (about Z), `rotate(37, 23, 71)` (oblique) and
`scale(-1.2, 1.2, 1.2)` (mirrored and 1.2x larger). With an OpenVCAD-Public checkout,
also OpenVCAD's `flexy_keychain` and `solid_keychain` examples as written
(`Rotate(90, 180, 180)`, the keychain stood on its edge) against the same scripts with
`Rotate(0, 180, 180)` (flat, the Z axis kept vertical), their LFS meshes replaced by
stand-ins (`openvcad_standins.py`).

A turned part is sliced in as many layers as it is tall, so each row prints the layer
counts and the ratio of CPU time per layer beside the ratios of wall and CPU time. Every
round slices the upright mesh and then each of its variants, in turns; the ratios are
taken within a round and the median over the rounds is printed.

Run: .venv/bin/python benchmarks/bench_rotated_meshes.py [OpenVCAD-Public checkout]
     [--jobs N] [--repeat N] [--rows x,y,z,oblique,mirror]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from openvcad_standins import BENCHY, examples_with_standins  # noqa: E402

FGSLICE = Path(sys.executable).with_name("fgslice")
KEYCHAIN_SETTINGS = {"flexy_keychain": ["--set", "colors=5", "--set", "channels=4"],
                     "solid_keychain": ["--set", "channels=3"]}
BENCHY_VARIANTS = {"x": "rotate(90, 0, 0)", "y": "rotate(0, 90, 0)", "z": "rotate(0, 0, 90)",
                   "oblique": "rotate(37, 23, 71)", "mirror": "scale(-1.2, 1.2, 1.2)"}
"""Row name: the transform the Benchy is sliced under."""


def timed(design: Path, extra: list[str], jobs: int) -> tuple[float, float, int]:
    """Wall and CPU seconds (user + system, with workers) of one `fgslice slice` run, and
    its number of layers (its warnings, such as the Benchy's holes, are not shown)."""
    stats = design.with_suffix(".json")
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    run = subprocess.run([str(FGSLICE), "slice", str(design), "-o", str(design.with_suffix(".gcode")), "--jobs",
                          str(jobs), "--stats", str(stats), *extra], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                         text=True)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if run.returncode != 0:
        sys.exit(f"{design.name}: fgslice slice failed (exit {run.returncode}): {run.stderr.strip()[-500:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu, json.loads(stats.read_text())["layers"]


def groups(checkout: Path | None, work: Path, names: list[str]) -> list[tuple[Path, list[tuple[str, Path]], list[str]]]:
    """``(upright design, [(row, transformed design), ...], extra arguments)`` per mesh."""
    found = []
    if BENCHY.is_file():
        upright = work / "benchy_upright.vcad"
        upright.write_text(f'mesh("{BENCHY}");\n')
        variants = []
        for name in names:
            design = work / f"benchy_{name}.vcad"
            design.write_text(f'{BENCHY_VARIANTS[name]} {{ mesh("{BENCHY}"); }}\n')
            variants.append((f"3DBenchy {BENCHY_VARIANTS[name]}", design))
        found.append((upright, variants, []))
    else:
        print(f"3DBenchy rows skipped: {BENCHY} not found (set BENCHY)")
    if checkout is not None:
        meshes = examples_with_standins(checkout, work) / "meshes"
        for name, extra in KEYCHAIN_SETTINGS.items():
            rotated = meshes / f"{name}.py"
            upright = meshes / f"{name}_flat.py"
            upright.write_text(rotated.read_text().replace("pv.Rotate(90,180,180", "pv.Rotate(0,180,180"))
            found.append((upright, [(f"{name} Rotate(90,180,180)", rotated)], extra))
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("checkout", nargs="?", type=Path, help="an OpenVCAD-Public checkout (keychain rows)")
    parser.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--repeat", type=int, default=3, help="rounds; median ratios reported")
    parser.add_argument("--rows", default=",".join(BENCHY_VARIANTS), help="3DBenchy variants, comma-separated")
    args = parser.parse_args()
    names = [name for name in args.rows.split(",") if name]
    unknown = sorted(set(names) - set(BENCHY_VARIANTS))
    if unknown:
        parser.error(f"unknown rows {unknown}; choose from {', '.join(BENCHY_VARIANTS)}")
    with tempfile.TemporaryDirectory() as tmp:
        print(f"{'row':40} {'upright s':>10} {'moved s':>10} {'layers':>9} {'wall ratio':>10} {'cpu ratio':>10} "
              f"{'cpu/layer':>10}   (medians over {args.repeat} rounds)")
        for upright, variants, extra in groups(args.checkout, Path(tmp), names):
            rounds = []
            for _ in range(args.repeat):
                base = timed(upright, extra, args.jobs)
                rounds.append([(base, timed(design, extra, args.jobs)) for _, design in variants])
            for index, (row, _) in enumerate(variants):
                pairs = [r[index] for r in rounds]
                (uw, uc, ul), (mw, mc, ml) = ((statistics.median(p[i][0] for p in pairs),
                                               statistics.median(p[i][1] for p in pairs), pairs[0][i][2])
                                              for i in (0, 1))
                wall = statistics.median(m[0] / u[0] for u, m in pairs)
                cpu = statistics.median(m[1] / u[1] for u, m in pairs)
                print(f"{row:40} {uw:10.2f} {mw:10.2f} {f'{ul}/{ml}':>9} {wall:10.2f} {cpu:10.2f} "
                      f"{cpu * ul / ml:10.2f}", flush=True)


if __name__ == "__main__":
    main()
