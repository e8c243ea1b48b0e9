"""The paper's runtime table (Table "Slicing times"), side by side with PrusaSlicer and CuraEngine.

Every row is sliced by ``fgslice slice ... --stats`` in its own process, so each figure
covers one whole command (start-up, import, slicing, writing, verification):

* wall: elapsed seconds of the command;
* cpu: user + system seconds of the command and its worker processes (on a shared,
  loaded machine this is the steadier figure);
* peak: largest resident set of the command or any of its workers, MB (``wait4``, from a
  small launcher process so that this script's own size does not count);
* ratios: our wall time over the paper's (1271 s vase ... 424 s palette) and over our
  target (vase 8 s, Benchy 5 s, palette rows 1.5 s), and our CPU time over the target
  (what the wall time would be on an idle machine with one core); below 1 is better.

Then ``speedup``: the vase with ``--jobs 1`` and ``--jobs 2`` (target >= 1.6), with the
machine's own ceilings for two processes (two ``--jobs 1`` slices of the vase at once,
and a fixed pure-Python loop alone and as two copies at once), and
``compare``: a single-material 3DBenchy (0.2 mm layers, 2 walls, 15 % infill) with
fgslice, ``prusa-slicer`` and ``CuraEngine`` (each skipped with a note when not installed),
and ``implicit``: parts without exact sections against the exact vase of the same run (a
function vase of the vase's size and settings, a gyroid block, three meshes side by side),
taken in turns, with their ratio to the exact vase and their targets.

Before timing, the installed ``fgslice`` package is byte-compiled (``compileall``), as
``pip install`` does for a regular install: an editable checkout run with
``PYTHONDONTWRITEBYTECODE`` set would otherwise recompile every module in every process
of every row.

``--profile`` instead slices each selected row in one process under cProfile and prints
its top functions by own time (where the time goes).

``--repeat N`` runs every command N times and reports the run of median wall time (its
CPU time and peak memory with it): on a shared machine one run can be 30 % off.

Run: ``.venv/bin/python benchmarks/run_all.py [--rows vase,benchy,...] [--jobs N] [--repeat N] [--quick] [--profile]``.
Row names: see ``--list``.
"""

from __future__ import annotations

import argparse
import compileall
import glob
import importlib.util
import json
import os
import pstats
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
BENCHY_STL = ROOT.parent / "shared" / "data" / "meshes" / "3DBenchy.stl"

VASE_TARGET_S = 8.0
BENCHY_TARGET_S = 5.0
PALETTE_TARGET_S = 1.5
SPEEDUP_TARGET = 1.6

VASE_ARGS = ("--strategy", "1", "--colors", "16", "--layer-height", "0.2",
             "--set", "walls=10", "--set", "infill_density=0", "--set", "top_layers=0", "--set", "bottom_layers=0")
PALETTE_S1 = ("--strategy", "1", "--layer-height", "0.2", "--set", "walls=3", "--set", "infill_density=100")
PALETTE_S2 = ("--strategy", "2", "--layer-height", "0.2")


@dataclass(frozen=True)
class Row:
    """One line of the paper's table: the design, the fgslice options, the paper's time (s)."""

    name: str
    design: Path
    args: tuple[str, ...]
    paper_s: float
    target_s: float
    quick: bool = False


ROWS = (
    Row("vase", EXAMPLES / "vase.vcad", VASE_ARGS, 1271, VASE_TARGET_S),
    Row("benchy", EXAMPLES / "benchy.vcad", ("--strategy", "2", "--colors", "5", "--layer-height", "0.2"), 754, BENCHY_TARGET_S),
    Row("palette_s1_c4", EXAMPLES / "palette.vcad", PALETTE_S1 + ("--colors", "4"), 33, PALETTE_TARGET_S, quick=True),
    Row("palette_s1_c8", EXAMPLES / "palette.vcad", PALETTE_S1 + ("--colors", "8"), 54, PALETTE_TARGET_S),
    Row("palette_s1_c12", EXAMPLES / "palette.vcad", PALETTE_S1 + ("--colors", "12"), 76, PALETTE_TARGET_S),
    Row("palette_s1_c16", EXAMPLES / "palette.vcad", PALETTE_S1 + ("--colors", "16"), 99, PALETTE_TARGET_S, quick=True),
    Row("palette_s1_c16_z10", EXAMPLES / "palette.vcad", PALETTE_S1 + ("--colors", "16", "--set", "zipper=10"), 219,
        PALETTE_TARGET_S, quick=True),
    Row("palette_s2_c12", EXAMPLES / "palette.vcad", PALETTE_S2 + ("--colors", "12"), 86, PALETTE_TARGET_S, quick=True),
    Row("palette_s2_c24", EXAMPLES / "palette.vcad", PALETTE_S2 + ("--colors", "24"), 174, PALETTE_TARGET_S),
    Row("palette_s2_c36", EXAMPLES / "palette.vcad", PALETTE_S2 + ("--colors", "36"), 285, PALETTE_TARGET_S),
    Row("palette_s2_c48", EXAMPLES / "palette.vcad", PALETTE_S2 + ("--colors", "48"), 424, PALETTE_TARGET_S, quick=True),
)
EXTRA = ("speedup", "compare", "implicit")
STAGES = (
    ("load design", ("language.py", "load_design")),
    ("thumbnails", ("thumbnails.py", "render_thumbnails")),
    ("outlines", ("pipeline.py", "_section_task")),
    ("regions", ("regions.py", "slice_layer")),
    ("strategy 1", ("strategy1.py", "layer_paths")),
    ("  walls", ("walls.py", "make_walls")),
    ("  cut", ("strategy1.py", "cut_by_color")),
    ("strategy 2", ("strategy2.py", "layer_paths")),
    ("order", ("order.py", "order_layer")),
    ("format", ("gcode.py", "prepare_bodies")),
    ("write", ("gcode.py", "write_layer")),
    ("verify", ("verify.py", "verify_gcode")),
)
"""Pipeline stages whose cumulative time ``--profile`` reports: (label, (file, function)).
Indented labels are parts of the stage above. The streamed stages after ordering (purge,
look-ahead) are left out: their cumulative time includes the layer generator they pull from."""


def byte_compile() -> None:
    """Write the byte code of every module of the fgslice package that the rows import."""
    spec = importlib.util.find_spec("fgslice")
    for location in spec.submodule_search_locations or ():
        compileall.compile_dir(location, quiet=1)


def stage_seconds(stats: pstats.Stats) -> dict[str, float]:
    """Cumulative profiled seconds of each :data:`STAGES` entry present in ``stats``."""
    cumulative = {(Path(file).name, func): v[3] for (file, _, func), v in stats.stats.items()}
    return {label: cumulative[key] for label, key in STAGES if key in cumulative}


@dataclass
class Run:
    """Measured cost of one command."""

    wall_s: float
    cpu_s: float
    peak_mb: float
    returncode: int
    stderr: str


LAUNCHER = """\
import os, sys, time
report = int(sys.argv[1])
start = time.perf_counter()
pid = os.fork()
if pid == 0:
    os.close(report)
    try:
        os.execvp(sys.argv[2], sys.argv[2:])
    except OSError as error:
        print(f"cannot run {sys.argv[2]}: {error}", file=sys.stderr)
        os._exit(127)
_, status, usage = os.wait4(pid, 0)
wall = time.perf_counter() - start
os.write(report, f"{wall} {usage.ru_utime + usage.ru_stime} {usage.ru_maxrss} {status}".encode())
"""
"""Runs a measured command from a small process of its own (``python -S``, about 8 MB):
Linux counts in a child's ``ru_maxrss`` the resident set it had before ``exec``, a copy of
its parent's, so a command started straight from this script (which imports trimesh for
the implicit rows, about 110 MB) would report this script's size as its peak whenever
its own is smaller. The launcher forks, execs the command, waits for it and writes its
wall time, CPU time, peak RSS (kB) and wait status to the file descriptor it is given."""


def measure(cmd: list[str], cwd: Path, env: dict[str, str] | None = None) -> Run:
    """Run ``cmd`` (in environment ``env``, default this one) and return its wall time,
    CPU time and peak RSS: its own or any waited-for descendant's, as ``wait4`` reports
    them on Linux (ru_maxrss, kB), through :data:`LAUNCHER` so that this script's own size
    does not count (a peak below the launcher's, about 8 MB, reads as the launcher's)."""
    read, write = os.pipe()
    with tempfile.TemporaryFile(mode="w+") as err:
        try:
            subprocess.run([sys.executable, "-S", "-c", LAUNCHER, str(write), *cmd], cwd=cwd, env=env,
                           stdout=subprocess.DEVNULL, stderr=err, pass_fds=(write,), check=True)
        finally:
            os.close(write)
            with os.fdopen(read, "rb") as figures:
                reported = figures.read().decode()
        wall, cpu, peak_kb, status = reported.split()
        err.seek(0)
        stderr = err.read()
    return Run(float(wall), float(cpu), int(peak_kb) / 1024, os.waitstatus_to_exitcode(int(status)), stderr)


def fgslice_cmd(design: Path, args: tuple[str, ...], out: Path, jobs: int) -> list[str]:
    """The ``fgslice slice`` command line of one row, writing ``out`` and ``out``.json."""
    return [sys.executable, "-m", "fgslice.cli", "slice", str(design), "-o", str(out),
            "--stats", str(out.with_suffix(".json")), "--jobs", str(jobs), *args]


def median_run(runs: list[tuple[Run, dict]]) -> tuple[Run, dict]:
    """The run of median wall time (the lower middle one of an even count); the first
    failed run if any failed."""
    failed = [r for r in runs if r[0].returncode != 0]
    if failed:
        return failed[0]
    return sorted(runs, key=lambda r: r[0].wall_s)[(len(runs) - 1) // 2]


def run_fgslice(design: Path, args: tuple[str, ...], out: Path, jobs: int, repeat: int = 1) -> tuple[Run, dict]:
    """Slice one row ``repeat`` times; returns the measurements and the statistics JSON
    (empty on failure) of the run of median wall time."""
    runs = []
    stats_path = out.with_suffix(".json")
    for _ in range(repeat):
        run = measure(fgslice_cmd(design, args, out, jobs), ROOT)
        stats = json.loads(stats_path.read_text()) if run.returncode == 0 and stats_path.exists() else {}
        runs.append((run, stats))
    return median_run(runs)


def print_table(rows: list[Row], jobs: int, workdir: Path, repeat: int) -> None:
    head = (f"{'row':20s} {'layers':>6s} {'colors':>6s} {'wall s':>8s} {'cpu s':>8s} {'slice s':>8s} "
            f"{'peak MB':>8s} {'paper s':>8s} {'/paper':>8s} {'target s':>8s} {'/target':>8s} {'cpu/tgt':>8s}")
    print(f"fgslice, --jobs {jobs}{_median_note(repeat)}\n{head}\n{'-' * len(head)}")
    for row in rows:
        run, stats = run_fgslice(row.design, row.args, workdir / f"{row.name}.gcode", jobs, repeat)
        if run.returncode != 0:
            print(f"{row.name:20s} failed (exit {run.returncode}): {run.stderr.strip().splitlines()[-1:]}")
            continue
        print(f"{row.name:20s} {stats['layers']:6d} {stats['colors']:6d} {run.wall_s:8.2f} {run.cpu_s:8.2f} "
              f"{stats['elapsed_s']:8.2f} {run.peak_mb:8.0f} {row.paper_s:8.0f} {run.wall_s / row.paper_s:8.4f} "
              f"{row.target_s:8.1f} {run.wall_s / row.target_s:8.2f} {run.cpu_s / row.target_s:8.2f}", flush=True)


def print_profiles(rows: list[Row], workdir: Path, top: int) -> None:
    """Each row with ``--jobs 1`` under cProfile: total and the ``top`` functions by own time."""
    for row in rows:
        out = workdir / f"{row.name}.gcode"
        prof = workdir / f"{row.name}.prof"
        cmd = fgslice_cmd(row.design, row.args, out, 1)
        run = measure([cmd[0], "-m", "cProfile", "-o", str(prof), *cmd[1:]], ROOT)
        if run.returncode != 0:
            print(f"{row.name}: failed (exit {run.returncode}): {run.stderr.strip().splitlines()[-1:]}")
            continue
        stats = pstats.Stats(str(prof))
        total = stats.total_tt
        print(f"\n{row.name}: {total:.1f} s profiled wall (cpu {run.cpu_s:.1f} s)")
        parts = [f"{label.strip()} {seconds:.2f} s ({100 * seconds / total:.0f}%)" for label, seconds in stage_seconds(stats).items()]
        print("  stages (cumulative): " + ", ".join(parts))
        entries = sorted(stats.stats.items(), key=lambda kv: kv[1][2], reverse=True)[:top]
        for (file, line, func), (_, calls, tottime, cumtime, _) in entries:
            where = f"{Path(file).name}:{line}" if line else file
            print(f"  {tottime:7.2f} s {100 * tottime / total:5.1f}%  cum {cumtime:7.2f} s  {calls:>9d} calls  {func} ({where})")


def print_speedup(workdir: Path, repeat: int) -> None:
    """Vase with 1 and 2 worker processes, and two ``--jobs 1`` slices of it at once,
    taken in turns (``repeat`` rounds).

    Prints the speed-up as the ratio of the median wall times and as the median of each
    round's ratio (steadier when the machine's speed drifts between rounds), then the
    *workload ceiling*: what two processes slicing the vase get done on this machine,
    against one alone (``2 * solo / pair``). On 2 vCPUs that share a physical core or a
    loaded host, two busy processes each run slower than one alone, and no ``--jobs 2``
    speed-up can exceed that ceiling; the speed-up over the ceiling is the parallel
    efficiency of the pipeline itself.
    """
    vase = ROWS[0]
    rounds = []
    for _ in range(repeat):
        one = run_fgslice(vase.design, vase.args, workdir / "vase_j1.gcode", 1)
        two = run_fgslice(vase.design, vase.args, workdir / "vase_j2.gcode", 2)
        rounds.append((one, two, concurrent_wall([fgslice_cmd(vase.design, vase.args, workdir / f"vase_pair{k}.gcode", 1)
                                                  for k in range(2)])))
    one, _ = median_run([r[0] for r in rounds])
    two, _ = median_run([r[1] for r in rounds])
    if one.returncode or two.returncode:
        print(f"\nspeed-up: vase failed ({one.stderr or two.stderr})")
        return
    speedups = [r[0][0].wall_s / r[1][0].wall_s for r in rounds]
    ceilings = [2 * r[0][0].wall_s / r[2] for r in rounds]
    print(f"\nvase{_median_note(repeat)} --jobs 1: wall {one.wall_s:.2f} s, cpu {one.cpu_s:.2f} s, peak {one.peak_mb:.0f} MB; --jobs 2: "
          f"wall {two.wall_s:.2f} s, cpu {two.cpu_s:.2f} s, peak {two.peak_mb:.0f} MB; "
          f"speed-up {one.wall_s / two.wall_s:.2f} (target >= {SPEEDUP_TARGET})")
    if repeat > 1:
        print(f"speed-up of each round: {', '.join(f'{v:.2f}' for v in speedups)}; median {_median(speedups):.2f}")
    print(f"workload ceiling: two --jobs 1 slices of the vase at once take {_median([r[2] for r in rounds]):.2f} s, "
          f"so two processes do {', '.join(f'{v:.2f}' for v in ceilings)}x the work of one here "
          f"(median {_median(ceilings):.2f}); --jobs 2 reaches {_median([a / b for a, b in zip(speedups, ceilings)]):.0%} of it")
    solo, pair = parallel_ceiling(repeat)
    print(f"machine ceiling: a pure-Python loop takes {solo:.2f} s alone and {pair:.2f} s as two copies at once, "
          f"so two processes do at most {2 * solo / pair:.2f}x the work of one here")


def _median(values: list[float]) -> float:
    """The lower middle value, as :func:`median_run` picks runs."""
    return sorted(values)[(len(values) - 1) // 2]


def concurrent_wall(cmds: list[list[str]]) -> float:
    """Wall seconds from starting every command of ``cmds`` at once until the last ends."""
    start = time.perf_counter()
    procs = [subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL) for cmd in cmds]
    for proc in procs:
        proc.wait()
    return time.perf_counter() - start


SPIN = "s = 0\nfor i in range(6_000_000):\n    s += i * i % 7\n"
"""A fixed CPU-bound loop (about 1 s) for :func:`parallel_ceiling`."""


def parallel_ceiling(repeat: int) -> tuple[float, float]:
    """Wall seconds of :data:`SPIN` run alone and of two copies run at once (median of
    ``repeat``): on 2 vCPUs that share a physical core or a loaded host, two processes
    each run slower than one alone, which caps any ``--jobs 2`` speed-up at
    ``2 * solo / pair``."""
    cmd = [sys.executable, "-c", SPIN]
    solos, pairs = [], []
    for _ in range(repeat):
        solos.append(measure(cmd, ROOT).wall_s)
        pairs.append(concurrent_wall([cmd, cmd]))
    return _median(solos), _median(pairs)


def machine_reference() -> float:
    """Wall seconds of :data:`SPIN` alone, printed before and after the rows: this machine's
    speed drifts by tens of percent from one hour to the next, and two runs' figures
    compare fairly only at a similar reference."""
    return measure([sys.executable, "-c", SPIN], ROOT).wall_s


def _median_note(repeat: int) -> str:
    return f", median of {repeat} runs" if repeat > 1 else ""


def cura_definition() -> Path | None:
    """Cura's ``fdmprinter.def.json`` (Debian package ``cura``), or None."""
    candidates = [os.environ.get("CURA_FDMPRINTER", "")]
    candidates += glob.glob("/usr/share/cura/resources/definitions/fdmprinter.def.json")
    candidates += glob.glob("/usr/share/**/definitions/fdmprinter.def.json", recursive=True)
    return next((Path(c) for c in candidates if c and Path(c).is_file()), None)


SINGLE_BENCHY_ARGS = ("--strategy", "1", "--colors", "1", "--layer-height", "0.2",
                      "--set", "walls=2", "--set", "infill_density=15", "--set", "thumbnails=")
"""fgslice's arguments for the single-material Benchy: like the other slicers' commands,
no thumbnails in the G-code (neither PrusaSlicer's nor CuraEngine's command line renders
any)."""

WITH_THUMBNAILS = ("--set", "thumbnails=16x16,220x124")
"""The default profile's thumbnails, for the comparison row that shows what they cost."""


def comparison_commands(stl: Path, workdir: Path, jobs: int) -> dict[str, list[str] | str]:
    """Single-material Benchy: 0.2 mm layers, 2 walls, 15 % infill, 3 top / 3 bottom layers,
    one skirt loop, centred on a 220 x 220 mm bed; fgslice also once with its default
    thumbnails. A string value says why a slicer is skipped."""
    design = workdir / "benchy_single.vcad"
    design.write_text(f"mesh({json.dumps(str(stl))});\n")
    commands: dict[str, list[str] | str] = {
        "fgslice": fgslice_cmd(design, SINGLE_BENCHY_ARGS, workdir / "single_fgslice.gcode", jobs),
        "+ thumbnails": fgslice_cmd(design, SINGLE_BENCHY_ARGS + WITH_THUMBNAILS, workdir / "single_thumbs.gcode", jobs),
    }
    prusa = shutil.which("prusa-slicer")
    commands["prusa-slicer"] = [
        prusa, "--export-gcode", "--layer-height", "0.2", "--first-layer-height", "0.2", "--perimeters", "2",
        "--fill-density", "15%", "--top-solid-layers", "3", "--bottom-solid-layers", "3", "--skirts", "1",
        "--center", "110,110", "-o", str(workdir / "single_prusa.gcode"), str(stl),
    ] if prusa else "not installed (Debian package prusa-slicer)"
    cura, definition = shutil.which("CuraEngine"), cura_definition()
    if not cura:
        commands["CuraEngine"] = "not installed (Debian package cura-engine)"
    elif not definition:
        commands["CuraEngine"] = "fdmprinter.def.json not found (Debian package cura, or set CURA_FDMPRINTER)"
    else:
        sets = {
            "machine_width": 220, "machine_depth": 220, "machine_height": 250, "center_object": "true",
            "layer_height": 0.2, "layer_height_0": 0.2, "wall_line_count": 2, "infill_sparse_density": 15,
            "top_layers": 3, "bottom_layers": 3, "adhesion_type": "skirt", "skirt_line_count": 1,
            "material_diameter": 1.75,
        }
        commands["CuraEngine"] = [cura, "slice", "-j", str(definition),
                                  *[a for k, v in sets.items() for a in ("-s", f"{k}={v}")],
                                  "-l", str(stl), "-o", str(workdir / "single_cura.gcode")]
    return commands


def print_comparison(workdir: Path, jobs: int, repeat: int) -> None:
    """Single-material Benchy with every installed slicer, taken in turns (one run of each
    per round, ``repeat`` rounds), so that a change of the machine's speed during the
    series weighs on every slicer alike; medians per slicer."""
    if not BENCHY_STL.exists():
        print(f"\ncomparison skipped: {BENCHY_STL} not found")
        return
    print(f"\nsingle-material 3DBenchy (0.2 mm, 2 walls, 15 % infill){_median_note(repeat)}, slicers taken in turns")
    commands = {}
    for name, cmd in comparison_commands(BENCHY_STL, workdir, jobs).items():
        if isinstance(cmd, str):
            print(f"  {name:13s} skipped: {cmd}")
        else:
            commands[name] = cmd
    rounds = [{name: measure(cmd, workdir) for name, cmd in commands.items()} for _ in range(repeat)]
    runs: dict[str, Run] = {}
    for name in commands:
        run = median_run([(r[name], {}) for r in rounds])[0]
        if run.returncode != 0:
            print(f"  {name:13s} failed (exit {run.returncode}): {run.stderr.strip().splitlines()[-1:]}")
            continue
        runs[name] = run
        ratio = "" if name in ("fgslice", "+ thumbnails") or "fgslice" not in runs else \
            f"  fgslice/{name}: wall {runs['fgslice'].wall_s / run.wall_s:.2f}, cpu {runs['fgslice'].cpu_s / run.cpu_s:.2f}"
        if ratio and "+ thumbnails" in runs:
            thumbs = runs["+ thumbnails"]
            ratio += f"; with thumbnails: wall {thumbs.wall_s / run.wall_s:.2f}, cpu {thumbs.cpu_s / run.cpu_s:.2f}"
        print(f"  {name:13s} wall {run.wall_s:7.2f} s  cpu {run.cpu_s:7.2f} s  peak {run.peak_mb:6.0f} MB{ratio}", flush=True)


FUNCTION_VASE = """fgrade(["(1+sin(0.025*x+0.0375*y)*cos(0.0375*x-0.025*y))/2",
        "1-(1+sin(0.025*x+0.0375*y)*cos(0.0375*x-0.025*y))/2"], ["yellow", "blue"]) {
    function((-68,-88,-50), (68,88,50), "sqrt((x/67.5)^2 + (y/87.5)^2) - (0.8 + 0.2*cos(z/16))");
}
"""
"""The vase's size and gradient as a ``function`` (no exact section): 500 layers."""

GYROID = """fgrade(["(z+10)/20", "1-(z+10)/20"], ["red", "blue"]) {
    function((-20,-20,-10), (20,20,10), "sin(x)*cos(y)+sin(y)*cos(z)+sin(z)*cos(x)");
}
"""
"""A gyroid block 40 x 40 x 20 mm graded along z."""

THREE_MESHES = """union() {
    mesh("mesh_a.stl", "red");
    mesh("mesh_b.stl", "green");
    mesh("mesh_c.stl", "blue");
}
"""
"""Three 40 x 20 x 2 mm boxes side by side (written by :func:`implicit_rows`), one material each."""


@dataclass(frozen=True)
class Implicit:
    """One ``implicit`` row: the design's text, fgslice options, and targets (wall s, and
    ratio to the exact vase of the same run; None: no ratio target)."""

    name: str
    text: str
    args: tuple[str, ...]
    target_s: float
    target_ratio: float | None = None


IMPLICIT = (
    Implicit("function_vase", FUNCTION_VASE, VASE_ARGS, VASE_TARGET_S, 1.5),
    Implicit("gyroid", GYROID, ("--strategy", "2", "--colors", "8", "--layer-height", "0.2"), 3.0),
    Implicit("three_meshes", THREE_MESHES, ("--strategy", "1", "--layer-height", "0.2", "--set", "channels=3"), 1.0),
)


def implicit_rows(workdir: Path) -> list[tuple[str, Path, tuple[str, ...], float, float | None]]:
    """The exact vase, then every :data:`IMPLICIT` design written to ``workdir`` (with its
    meshes): ``(name, design, args, target s, target ratio)``."""
    import trimesh

    for k, name in enumerate("abc"):
        box = trimesh.creation.box((40, 20, 2))
        box.apply_translation((0, 25 * k, 1))
        box.export(workdir / f"mesh_{name}.stl")
    rows = [("vase", ROWS[0].design, ROWS[0].args, ROWS[0].target_s, None)]
    for row in IMPLICIT:
        design = workdir / f"{row.name}.vcad"
        design.write_text(row.text)
        rows.append((row.name, design, row.args, row.target_s, row.target_ratio))
    return rows


def print_implicit(workdir: Path, jobs: int, repeat: int) -> None:
    """The :func:`implicit_rows` taken in turns (``repeat`` rounds); medians, and each
    row's wall and CPU time over the exact vase's of the same rounds."""
    rows = implicit_rows(workdir)
    rounds = [[measure(fgslice_cmd(design, args, workdir / f"{name}.gcode", jobs), ROOT) for name, design, args, *_ in rows]
              for _ in range(repeat)]
    print(f"\nparts without exact sections, --jobs {jobs}{_median_note(repeat)}, taken in turns with the exact vase")
    vase = median_run([(r[0], {}) for r in rounds])[0]
    for i, (name, _, _, target_s, target_ratio) in enumerate(rows):
        run = median_run([(r[i], {}) for r in rounds])[0]
        if run.returncode != 0:
            print(f"  {name:14s} failed (exit {run.returncode}): {run.stderr.strip().splitlines()[-1:]}")
            continue
        ratio = f"  /vase: wall {run.wall_s / vase.wall_s:5.2f}, cpu {run.cpu_s / vase.cpu_s:5.2f}" if i else ""
        target = f"  target {target_s:.1f} s" + (f", <= {target_ratio}x the vase" if target_ratio else "")
        print(f"  {name:14s} wall {run.wall_s:7.2f} s  cpu {run.cpu_s:7.2f} s  peak {run.peak_mb:6.0f} MB{ratio}{target}",
              flush=True)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", help="comma-separated row names (default: all); see --list")
    parser.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="worker processes per slice")
    parser.add_argument("--quick", action="store_true", help="only the palette rows marked quick, no vase/Benchy")
    parser.add_argument("--profile", action="store_true", help="profile the selected rows instead of timing them")
    parser.add_argument("--top", type=int, default=5, help="functions per row with --profile")
    parser.add_argument("--list", action="store_true", help="print the row names and exit")
    parser.add_argument("--repeat", type=int, default=1,
                        help="run each command this many times and report the run of median wall time")
    parser.add_argument("--keep", type=Path, help="write G-code and statistics here instead of a temporary folder")
    args = parser.parse_args(argv)
    if args.repeat < 1:
        parser.error(f"--repeat must be at least 1, not {args.repeat}")
    names = [r.name for r in ROWS] + list(EXTRA)
    if args.list:
        print("\n".join(names))
        return
    if args.rows:
        wanted = [n.strip() for n in args.rows.split(",") if n.strip()]
        unknown = sorted(set(wanted) - set(names))
        if unknown:
            parser.error(f"unknown rows {', '.join(unknown)}; choose from {', '.join(names)}")
    elif args.quick:
        wanted = [r.name for r in ROWS if r.quick]
    else:
        wanted = names
    print(f"{time.strftime('%Y-%m-%d %H:%M')}, load average {', '.join(f'{v:.2f}' for v in os.getloadavg())}, "
          f"{os.cpu_count()} cores, machine reference {machine_reference():.2f} s (a fixed Python loop)")
    byte_compile()
    with tempfile.TemporaryDirectory() as tmp:
        workdir = args.keep or Path(tmp)
        workdir.mkdir(parents=True, exist_ok=True)
        rows = [r for r in ROWS if r.name in wanted]
        if args.profile:
            print_profiles(rows, workdir, args.top)
            return
        if rows:
            print_table(rows, args.jobs, workdir, args.repeat)
        if "speedup" in wanted:
            print_speedup(workdir, args.repeat)
        if "compare" in wanted:
            print_comparison(workdir, args.jobs, args.repeat)
        if "implicit" in wanted:
            print_implicit(workdir, args.jobs, args.repeat)
    print(f"\nmachine reference at the end: {machine_reference():.2f} s")


if __name__ == "__main__":
    main()
