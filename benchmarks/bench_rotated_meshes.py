"""Meshes under a tilting rotation against the same meshes upright: `fgslice slice` wall
and CPU time of each, side by side in one run, and their ratio (target: at most 2).

Rows: the 3DBenchy upright and lying on its side (`rotate(90, 0, 0)`); OpenVCAD's
`flexy_keychain` and `solid_keychain` examples as written (`Rotate(90, 180, 180)`, the
keychain stood on its edge) against the same scripts with `Rotate(0, 180, 180)` (flat,
the Z axis kept vertical), their LFS meshes replaced by stand-ins
(`openvcad_standins.py`). The keychains stand 2x taller than they lie, so the rotated
rows have twice the layers.

Run: .venv/bin/python benchmarks/bench_rotated_meshes.py [OpenVCAD-Public checkout]
     [--jobs N] [--repeat N]
"""

from __future__ import annotations

import argparse
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


def timed(design: Path, extra: list[str], jobs: int) -> tuple[float, float]:
    """Wall and CPU seconds (user + system, with workers) of one `fgslice slice` run."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    subprocess.run([str(FGSLICE), "slice", str(design), "-o", str(design.with_suffix(".gcode")), "--jobs", str(jobs),
                    *extra], check=True, stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def pairs(checkout: Path | None, work: Path) -> list[tuple[str, Path, Path, list[str]]]:
    """``(row, upright design, rotated design, extra arguments)`` for each row."""
    rows = []
    if BENCHY.is_file():
        upright, rotated = work / "benchy_upright.vcad", work / "benchy_rotated.vcad"
        upright.write_text(f'mesh("{BENCHY}");\n')
        rotated.write_text(f'rotate(90, 0, 0) {{ mesh("{BENCHY}"); }}\n')
        rows.append(("3DBenchy rotate(90,0,0)", upright, rotated, []))
    if checkout is not None:
        meshes = examples_with_standins(checkout, work) / "meshes"
        for name, extra in KEYCHAIN_SETTINGS.items():
            rotated = meshes / f"{name}.py"
            upright = meshes / f"{name}_flat.py"
            upright.write_text(rotated.read_text().replace("pv.Rotate(90,180,180", "pv.Rotate(0,180,180"))
            rows.append((f"{name} Rotate(90,180,180)", upright, rotated, extra))
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("checkout", nargs="?", type=Path, help="an OpenVCAD-Public checkout (keychain rows)")
    parser.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--repeat", type=int, default=1, help="runs of each design, alternating; medians reported")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        print(f"{'row':40} {'upright s':>10} {'rotated s':>10} {'wall ratio':>10} {'cpu ratio':>10}")
        for row, upright, rotated, extra in pairs(args.checkout, Path(tmp)):
            runs = {upright: [], rotated: []}
            for _ in range(args.repeat):
                for design in (upright, rotated):
                    runs[design].append(timed(design, extra, args.jobs))
            (uw, uc), (rw, rc) = ((statistics.median(r[0] for r in runs[d]), statistics.median(r[1] for r in runs[d]))
                                  for d in (upright, rotated))
            print(f"{row:40} {uw:10.2f} {rw:10.2f} {rw / uw:10.2f} {rc / uc:10.2f}", flush=True)


if __name__ == "__main__":
    main()
