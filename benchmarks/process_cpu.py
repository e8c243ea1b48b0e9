"""Where a slice's CPU goes, process by process: ``--jobs 1`` against ``--jobs N``.

Each run slices one row (default: the vase; the names ``compare_commits.py`` knows: the
rows of ``run_all.py``, the implicit parts, ``single_benchy`` and
``single_benchy_thumbnails``) in a fresh process that
times the pipeline's stages (:data:`STAGES`) wherever they run: in the command's own
process (``parent``), in the pool's workers (``worker``), in the process that verifies
the file while it is written (``verifier``) and in the one that renders thumbnails
(``thumbnails``). Every process reports at its exit its own CPU time (user + system,
``os.times``) and, per stage, the CPU time of the calls (``time.thread_time``), their
wall time, and when the first began and the last ended (seconds since the command's
interpreter reached this script, one monotonic clock for all processes). ``os.times``
counts in clock ticks (10 ms), so a process's CPU outside the stages can come out a few
ms below zero.

The two settings run in turns, ``--repeat`` times; each figure printed is the median
over the runs. The last lines say what ``--jobs N`` adds to the CPU time of
``--jobs 1``, per stage, and how long the command runs before the first layer task
starts (the serial start, which no number of workers shortens).

Run: ``.venv/bin/python benchmarks/process_cpu.py [--row vase] [--jobs 2] [--repeat 5]``.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

import compare_commits
import run_all

STAGES = (
    ("sections", "fgslice.pipeline", "_section_task"),
    ("layer tasks", "fgslice.pipeline", "_layer_task"),
    ("write", "fgslice.machine.gcode", "GcodeWriter.write_layer"),
    ("verify", "fgslice.pipeline", "verify_gcode"),
    ("verify", "fgslice.pipeline", "_verify_written"),
    ("thumbnails", "fgslice.preview.thumbnails", "render_thumbnails"),
)
"""Timed stages: (label, module, attribute); one label may name the same stage as it runs
with one process (``verify_gcode``) and with workers (``_verify_written``)."""

ROLES = {"_verify_written": "verifier", "_render_thumbnails": "thumbnails"}
"""Consumer processes by the function they run (``executor.Consumer``)."""

ROLE_ORDER = ("parent", "worker", "verifier", "thumbnails")
"""The order in which the roles of processes are printed."""


def child(record_path: str, argv: list[str]) -> None:
    """Run ``fgslice`` with ``argv``, its stages timed; each process appends one JSON line
    to ``record_path`` at its exit. The stages' modules, numpy with them, are imported
    before the command runs, as :func:`fgslice.cli.run` imports numpy."""
    started = time.perf_counter()
    import functools
    import importlib
    import multiprocessing.util

    from fgslice import cli, executor
    from fgslice.heap import retain_freed_memory

    stages: dict[str, list[float]] = defaultdict(lambda: [float("inf"), 0.0, 0.0, 0.0, 0])

    def timed(label, fn):
        @functools.wraps(fn)
        def call(*args, **kwargs):
            wall, cpu = time.perf_counter(), time.thread_time()
            try:
                return fn(*args, **kwargs)
            finally:
                end = time.perf_counter()
                entry = stages[label]
                entry[0] = min(entry[0], wall - started)
                entry[1] = max(entry[1], end - started)
                entry[2] += time.thread_time() - cpu
                entry[3] += end - wall
                entry[4] += 1
        return call

    for label, module_name, attribute in STAGES:
        owner = importlib.import_module(module_name)
        *path, name = attribute.split(".")
        for part in path:
            owner = getattr(owner, part)
        setattr(owner, name, timed(label, getattr(owner, name)))

    def report(role: str) -> None:
        times = os.times()
        line = json.dumps({"role": role, "cpu_s": times.user + times.system, "end_s": time.perf_counter() - started,
                           "stages": {k: dict(zip(("first_s", "last_s", "cpu_s", "wall_s", "calls"), v))
                                      for k, v in stages.items()}})
        with open(record_path, "a") as out:
            out.write(line + "\n")

    def record_this_process(role: str) -> None:
        """Drop the figures inherited from the parent; report this process's at its exit."""
        stages.clear()
        multiprocessing.util.Finalize(None, report, args=(role,), exitpriority=100)

    init_worker, consume = executor._init_worker, executor._consume

    def init_timed_worker(*args):
        record_this_process("worker")
        init_worker(*args)

    def consume_timed(fn, *args):
        record_this_process(ROLES.get(fn.__name__, fn.__name__))
        consume(fn, *args)

    executor._init_worker, executor._consume = init_timed_worker, consume_timed
    retain_freed_memory()
    try:
        cli.main(argv, prog_name="fgslice")
        code = 0
    except SystemExit as end:
        code = end.code if isinstance(end.code, int) else 1
    report("parent")
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


def run_once(name: str, design: Path, args: tuple[str, ...], jobs: int, workdir: Path) -> list[dict]:
    """One timed slice of row ``name`` (``design`` sliced with ``args``): the records of
    its processes."""
    records = workdir / f"records-{jobs}.jsonl"
    records.unlink(missing_ok=True)
    out = workdir / f"{name}-{jobs}.gcode"
    argv = run_all.fgslice_cmd(design, args, out, jobs)[3:]  # run_all.py's, after "python -m fgslice.cli"
    done = subprocess.run([sys.executable, __file__, "--child", str(records), "--", *argv],
                          cwd=run_all.ROOT, capture_output=True, text=True)
    if done.returncode != 0:
        sys.exit(f"fgslice {' '.join(argv)} failed:\n{done.stderr}")
    return [json.loads(line) for line in records.read_text().splitlines()]


def summarize(runs: list[list[dict]]) -> dict:
    """Medians over ``runs``: CPU per role (in all, and outside the timed stages), and per
    stage (over all processes) CPU, wall, calls, first start and last end."""
    def median(values):
        return statistics.median(values) if values else 0.0

    def per_run(run):
        roles, outside, stages = defaultdict(float), defaultdict(float), defaultdict(lambda: defaultdict(list))
        for record in run:
            roles[record["role"]] += record["cpu_s"]
            outside[record["role"]] += record["cpu_s"] - sum(f["cpu_s"] for f in record["stages"].values())
            for label, figures in record["stages"].items():
                for key, value in figures.items():
                    stages[label][key].append(value)
        return roles, outside, stages

    parsed = [per_run(run) for run in runs]
    roles = sorted({role for r, _, _ in parsed for role in r},
                   key=lambda role: ROLE_ORDER.index(role) if role in ROLE_ORDER else len(ROLE_ORDER))
    labels = sorted({label for _, _, s in parsed for label in s}, key=[s[0] for s in STAGES].index)
    return {
        "roles": {role: median([r.get(role, 0.0) for r, _, _ in parsed]) for role in roles},
        "outside": {role: median([o.get(role, 0.0) for _, o, _ in parsed]) for role in roles},
        "processes": {role: median([sum(1 for rec in run if rec["role"] == role) for run in runs]) for role in roles},
        "stages": {label: {
            "cpu_s": median([sum(s[label]["cpu_s"]) for _, _, s in parsed if label in s]),
            "wall_s": median([sum(s[label]["wall_s"]) for _, _, s in parsed if label in s]),
            "calls": median([sum(s[label]["calls"]) for _, _, s in parsed if label in s]),
            "first_s": median([min(s[label]["first_s"]) for _, _, s in parsed if label in s]),
            "last_s": median([max(s[label]["last_s"]) for _, _, s in parsed if label in s]),
        } for label in labels},
        "end_s": median([max(rec["end_s"] for rec in run) for run in runs]),
        "cpu_s": median([sum(rec["cpu_s"] for rec in run) for run in runs]),
    }


def print_summary(jobs: int, summary: dict) -> None:
    print(f"--jobs {jobs}: CPU {summary['cpu_s']:.2f} s in all, last process ends at {summary['end_s']:.2f} s")
    for role, cpu in summary["roles"].items():
        print(f"  {role:11s} {summary['processes'][role]:3.0f} process(es)  CPU {cpu:6.3f} s,"
              f" {summary['outside'][role]:6.3f} s of it outside the stages")
    print(f"  {'stage':12s} {'calls':>6s} {'CPU s':>7s} {'wall s':>7s} {'first s':>8s} {'last s':>7s}")
    for label, figures in summary["stages"].items():
        print(f"  {label:12s} {figures['calls']:6.0f} {figures['cpu_s']:7.3f} {figures['wall_s']:7.3f}"
              f" {figures['first_s']:8.3f} {figures['last_s']:7.3f}")


def main() -> None:
    if len(sys.argv) > 2 and sys.argv[1] == "--child":
        child(sys.argv[2], sys.argv[4:])
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--row", default="vase", help="a row of run_all.py (see run_all.py --list), an implicit "
                        "part, single_benchy or single_benchy_thumbnails")
    parser.add_argument("--jobs", type=int, default=2, help="workers to compare with one process")
    parser.add_argument("--repeat", type=int, default=5, help="runs of each setting, taken in turns")
    args = parser.parse_args()
    if args.jobs < 2 or args.repeat < 1:
        parser.error("--jobs must be at least 2 and --repeat at least 1")
    runs: dict[int, list] = {1: [], args.jobs: []}
    with tempfile.TemporaryDirectory() as tmp:
        rows = compare_commits.rows_by_name(Path(tmp))
        if args.row not in rows:
            parser.error(f"unknown row {args.row}; choose from {', '.join(rows)}")
        run_all.byte_compile()
        for _ in range(args.repeat):
            for jobs in runs:
                runs[jobs].append(run_once(args.row, *rows[args.row], jobs, Path(tmp)))
    one, many = summarize(runs[1]), summarize(runs[args.jobs])
    print(f"{args.row}, median of {args.repeat} runs each, taken in turns")
    print_summary(1, one)
    print_summary(args.jobs, many)
    added = {label: many["stages"][label]["cpu_s"] - figures["cpu_s"]
             for label, figures in one["stages"].items() if label in many["stages"]}
    outside = {role: value - one["outside"].get(role, 0.0) for role, value in many["outside"].items()}
    print(f"CPU that --jobs {args.jobs} adds: {many['cpu_s'] - one['cpu_s']:+.3f} s; in the stages: "
          + ", ".join(f"{label} {value:+.3f}" for label, value in added.items())
          + "; outside them: " + ", ".join(f"{role} {value:+.3f}" for role, value in outside.items()))
    for jobs, summary in ((1, one), (args.jobs, many)):
        start = summary["stages"].get("layer tasks", {}).get("first_s")
        if start is not None:
            print(f"--jobs {jobs}: the first layer task starts at {start:.3f} s")


if __name__ == "__main__":
    main()
