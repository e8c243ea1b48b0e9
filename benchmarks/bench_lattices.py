"""Lattice rows against PrusaSlicer: the same geometry sliced by fgslice from the design
and by PrusaSlicer from an STL that ``fgslice export-mesh`` writes of it.

Rows:

* ``bcc_bar``: OpenVCAD's ``4_graded_lattice_bar.py`` (160 x 40 x 20 mm, body-centred
  cubic cells of 10 mm, struts of radius 1.5 mm under a red-blue grade);
* ``gyroid_cube``: a 60 mm gyroid sheet cube (``pyvcad_metamaterials``, 6 x 6 x 6 cells,
  1.2 mm walls).

Both slicers get the same single-material settings (0.2 mm layers, 2 walls, 15 % infill,
3 top and 3 bottom layers, one skirt loop, centred on a 220 x 220 mm bed, no
thumbnails). Each round slices with fgslice and then with PrusaSlicer, so that a machine
whose speed drifts slows both alike; each run's wall and CPU seconds are printed as it
ends, then the ratios fgslice / PrusaSlicer of each round and their median (target: at
most 2). ``--graded`` also slices the bar as designed (graded, default settings) in each
round, for reference. The STL export is timed on its own (it is not part of either
slice); the STL's distance from the design's exact surface is printed with its triangle
count. PrusaSlicer's rows are skipped when ``prusa-slicer`` is not installed.

Run: ``.venv/bin/python benchmarks/bench_lattices.py [--rows bcc_bar,gyroid_cube]
[--resolution 0.6] [--repeat 3] [--jobs 2] [--graded]``. At 0.6 mm the STL keeps the
struts and walls within a few hundredths of a millimetre (printed by the run) and
PrusaSlicer finishes; at 0.2-0.3 mm (1.8-4 million triangles) it had not finished after
7-13 minutes of CPU.
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from run_all import SINGLE_BENCHY_ARGS, byte_compile, fgslice_cmd, measure  # noqa: E402

OPENVCAD_BAR = Path(os.environ.get("FGSLICE_OPENVCAD", "OpenVCAD-Public")) / "examples" / "lattices" / "4_graded_lattice_bar.py"
"""OpenVCAD's own bar, from the checkout ``$FGSLICE_OPENVCAD`` names; else the copy below."""

BAR = """import pyvcad as pv
import pyvcad_rendering as viz

materials = pv.default_materials
red = materials.id("red")
blue = materials.id("blue")
cell = pv.GraphLattice(pv.LatticeType.BodyCenteredCubic, pv.Vec3(10, 10, 10), 1.5, red)
bar = pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(160, 40, 20), red)
filled_bar = pv.Intersection(False, [pv.Tile(cell), bar])
fgrade = pv.FGrade(["x/150 + 0.5", "-x/150 + 0.5"], [red, blue], False)
fgrade.set_child(filled_bar)
viz.Render(fgrade, materials)
"""
"""OpenVCAD's ``4_graded_lattice_bar.py`` as it runs (used when the checkout is absent)."""

GYROID = """import pyvcad as pv
import pyvcad_metamaterials as mm
import pyvcad_rendering as viz

cell_map = mm.rectangular_cell_map((pv.Vec3(-30, -30, -30), pv.Vec3(30, 30, 30)), cells=(6, 6, 6))
viz.Render(mm.gyroid(cell_map, mode="sheet", wall_thickness=1.2))
"""

ROWS = {"bcc_bar": BAR, "gyroid_cube": GYROID}

PRUSA_ARGS = ("--export-gcode", "--layer-height", "0.2", "--first-layer-height", "0.2", "--perimeters", "2",
              "--fill-density", "15%", "--top-solid-layers", "3", "--bottom-solid-layers", "3", "--skirts", "1",
              "--center", "110,110")


def deviation(design: Path, stl: Path, samples: int = 200_000) -> str:
    """How far the STL lies from the design's exact surface: the design's signed distance
    (mm) at the vertices and at the centroids of up to ``samples`` triangles."""
    import numpy as np
    import trimesh

    from fgslice.compat.script import load_script

    exact = load_script(design)
    mesh = trimesh.load(stl)
    rng = np.random.default_rng(1)
    faces = rng.choice(len(mesh.faces), min(samples, len(mesh.faces)), replace=False)
    vertices = mesh.vertices[rng.choice(len(mesh.vertices), min(samples, len(mesh.vertices)), replace=False)]
    at = {"vertices": vertices, "centroids": mesh.triangles_center[faces]}
    figures = {name: np.abs(exact.sdf(*points.T)) for name, points in at.items()}
    return ", ".join(f"{name} off the exact surface: mean {d.mean():.3f} mm, max {d.max():.3f} mm"
                     for name, d in figures.items())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", default=",".join(ROWS))
    parser.add_argument("--resolution", type=float, default=0.6, help="STL grid step, mm")
    parser.add_argument("--repeat", type=int, default=3, help="rounds of fgslice then PrusaSlicer")
    parser.add_argument("--graded", action="store_true", help="also slice the bar as designed (graded), for reference")
    parser.add_argument("--jobs", type=int, default=2)
    args = parser.parse_args()
    byte_compile()
    prusa = shutil.which("prusa-slicer")
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        for row in args.rows.split(","):
            design = work / f"{row}.py"
            text = OPENVCAD_BAR.read_text() if row == "bcc_bar" and OPENVCAD_BAR.exists() else ROWS[row]
            design.write_text(text)
            stl = work / f"{row}.stl"
            export = measure([sys.executable, "-m", "fgslice.cli", "export-mesh", str(design), "-o", str(stl),
                              "--resolution", str(args.resolution)], work)
            if export.returncode != 0:
                print(f"{row}: export-mesh failed: {export.stderr.strip()[-300:]}")
                continue
            size_mb = stl.stat().st_size / 1e6
            print(f"\n{row}: STL at {args.resolution:g} mm, {(stl.stat().st_size - 84) // 50:,} triangles "
                  f"({size_mb:.0f} MB), exported in {export.wall_s:.1f} s; {deviation(design, stl)}")
            commands = {"fgslice": fgslice_cmd(design, SINGLE_BENCHY_ARGS, work / f"{row}_fg.gcode", args.jobs)}
            if prusa:
                commands["prusa-slicer"] = [prusa, *PRUSA_ARGS, "-o", str(work / f"{row}_prusa.gcode"), str(stl)]
            else:
                print("  prusa-slicer  skipped: not installed (Debian package prusa-slicer)")
            if args.graded and row == "bcc_bar":
                commands["fgslice graded"] = fgslice_cmd(design, ("--set", "thumbnails="), work / f"{row}_graded.gcode",
                                                         args.jobs)
            rounds = []
            for turn in range(1, args.repeat + 1):
                rounds.append({})
                for name, cmd in commands.items():
                    run = rounds[-1][name] = measure(cmd, work)
                    state = "" if run.returncode == 0 else f"  failed (exit {run.returncode}): {run.stderr.strip()[-300:]}"
                    print(f"  round {turn} {name:14s} wall {run.wall_s:7.2f} s  cpu {run.cpu_s:7.2f} s  "
                          f"peak {run.peak_mb:6.0f} MB{state}", flush=True)
            print_ratios(row, rounds)


def print_ratios(row: str, rounds: list[dict]) -> None:
    """fgslice / PrusaSlicer, wall and CPU, of each round where both finished, and the
    median over those rounds."""
    pairs = [(r["fgslice"], r["prusa-slicer"]) for r in rounds
             if "prusa-slicer" in r and r["fgslice"].returncode == 0 and r["prusa-slicer"].returncode == 0]
    if not pairs:
        return
    wall = [fg.wall_s / prusa.wall_s for fg, prusa in pairs]
    cpu = [fg.cpu_s / prusa.cpu_s for fg, prusa in pairs]
    print(f"  {row} fgslice/prusa-slicer, median of {len(pairs)} rounds: wall {statistics.median(wall):.2f} "
          f"(rounds {', '.join(f'{w:.2f}' for w in wall)}), cpu {statistics.median(cpu):.2f} "
          f"(rounds {', '.join(f'{c:.2f}' for c in cpu)})", flush=True)

if __name__ == "__main__":
    main()
