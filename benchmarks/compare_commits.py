"""Two versions of fgslice on the same rows, run alternately: before/after figures that a
machine whose speed drifts over minutes cannot skew.

The base revision is checked out into a temporary git worktree and byte-compiled like
the working tree (``run_all.byte_compile``); each row then runs base, current, base,
current... ``--repeat`` times, both with this venv's Python and the same arguments
(``PYTHONPATH`` selects the source tree). Prints the median wall and CPU seconds of each
version and the ratio current / base (below 1 is faster).

Run: ``.venv/bin/python benchmarks/compare_commits.py BASE [--rows vase,palette_s1_c16] [--repeat 3] [--jobs 2]``
(rows as in ``run_all.py --list``, plus ``single_benchy``: the single-material Benchy of
the ``compare`` row, ``single_benchy_thumbnails``: the same with the default thumbnails,
and the ``implicit`` rows by name: ``function_vase``, ``gyroid``, ``three_meshes``).
"""

from __future__ import annotations

import argparse
import compileall
import json
import os
import statistics
import subprocess
import tempfile
from pathlib import Path

import run_all

DEFAULT_ROWS = "vase,benchy,palette_s1_c12,palette_s1_c16,palette_s1_c16_z10,palette_s2_c12,palette_s2_c48,single_benchy"


def rows_by_name(workdir: Path) -> dict[str, tuple[Path, tuple[str, ...]]]:
    """Design and arguments of every row name."""
    rows = {r.name: (r.design, r.args) for r in run_all.ROWS}
    rows.update({name: (design, args) for name, design, args, *_ in run_all.implicit_rows(workdir)[1:]})
    design = workdir / "benchy_single.vcad"
    design.write_text(f"mesh({json.dumps(str(run_all.BENCHY_STL))});\n")
    rows["single_benchy"] = (design, run_all.SINGLE_BENCHY_ARGS)
    rows["single_benchy_thumbnails"] = (design, run_all.SINGLE_BENCHY_ARGS + run_all.WITH_THUMBNAILS)
    for name, height in (("box200", 150.0), ("box200_thin", 4.0)):
        design = workdir / f"{name}.vcad"
        design.write_text(box200_design(height))
        rows[name] = (design, BOX200_ARGS)
    return rows


BOX200_ARGS = ("--strategy", "2", "--colors", "16", "--layer-height", "0.2")
"""The large part's slice: strategy 2, 16 colors, 0.2 mm layers."""


def box200_design(height: float) -> str:
    """A 200 x 200 mm box ``height`` mm high graded in 3-D: blue to yellow with the distance
    from its centre (spherical bands, so every face boundary is curved)."""
    return (f'fgrade(["clamp(0, r/250, 1)", "1 - clamp(0, r/250, 1)"], ["blue", "yellow"]) {{\n'
            f"    rectprism(200, 200, {height:g});\n}}\n")


def run_once(source: Path, design: Path, args: tuple[str, ...], out: Path, jobs: int) -> run_all.Run:
    """One slice with the fgslice sources under ``source`` first on the import path."""
    env = {**os.environ, "PYTHONPATH": str(source)}
    return run_all.measure(run_all.fgslice_cmd(design, args, out, jobs), out.parent, env)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("base", help="git revision to compare the working tree with")
    parser.add_argument("--rows", default=DEFAULT_ROWS, help=f"comma-separated rows (default: {DEFAULT_ROWS})")
    parser.add_argument("--repeat", type=int, default=3, help="runs of each version per row")
    parser.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="worker processes per slice")
    args = parser.parse_args(argv)
    if args.repeat < 1:
        parser.error(f"--repeat must be at least 1, not {args.repeat}")
    with tempfile.TemporaryDirectory() as tmp:
        workdir = Path(tmp)
        rows = rows_by_name(workdir)
        wanted = [n.strip() for n in args.rows.split(",") if n.strip()]
        unknown = sorted(set(wanted) - set(rows))
        if unknown:
            parser.error(f"unknown rows {', '.join(unknown)}; choose from {', '.join(rows)}")
        base_tree = workdir / "base"
        added = subprocess.run(["git", "-C", str(run_all.ROOT), "worktree", "add", "--detach", str(base_tree), args.base],
                               capture_output=True, text=True)
        if added.returncode != 0:
            parser.error(f"cannot check out {args.base}: {added.stderr.strip()}")
        try:
            compare(rows, wanted, base_tree / "src", workdir, args.repeat, args.jobs, args.base)
        finally:
            subprocess.run(["git", "-C", str(run_all.ROOT), "worktree", "remove", "--force", str(base_tree)],
                           capture_output=True)


def compare(rows, wanted: list[str], base_src: Path, workdir: Path, repeat: int, jobs: int, base: str) -> None:
    """Alternate the two versions on each row and print medians and ratios."""
    current_src = run_all.ROOT / "src"
    for source in (base_src, current_src):
        compileall.compile_dir(str(source / "fgslice"), quiet=1)
    print(f"base {base} against the working tree, --jobs {jobs}, median of {repeat} alternating runs")
    print(f"{'row':20s} {'base wall':>10s} {'base cpu':>9s} {'now wall':>9s} {'now cpu':>8s} {'wall x':>7s} {'cpu x':>6s}")
    for name in wanted:
        design, args = rows[name]
        runs: dict[str, list[run_all.Run]] = {"base": [], "now": []}
        for _ in range(repeat):
            for label, source in (("base", base_src), ("now", current_src)):
                runs[label].append(run_once(source, design, args, workdir / f"{name}_{label}.gcode", jobs))
        failed = [r for rs in runs.values() for r in rs if r.returncode != 0]
        if failed:
            print(f"{name:20s} failed (exit {failed[0].returncode}): {failed[0].stderr.strip().splitlines()[-1:]}")
            continue
        b_wall, b_cpu = (statistics.median(getattr(r, k) for r in runs["base"]) for k in ("wall_s", "cpu_s"))
        n_wall, n_cpu = (statistics.median(getattr(r, k) for r in runs["now"]) for k in ("wall_s", "cpu_s"))
        print(f"{name:20s} {b_wall:10.2f} {b_cpu:9.2f} {n_wall:9.2f} {n_cpu:8.2f} {n_wall / b_wall:7.2f} {n_cpu / b_cpu:6.2f}",
              flush=True)


if __name__ == "__main__":
    main()
