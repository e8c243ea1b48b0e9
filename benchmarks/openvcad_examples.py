"""Every Python example of an OpenVCAD-Public checkout through `fgslice check` and `fgslice slice`.

The examples are copied with their Git LFS meshes replaced by stand-ins of about the same
size (`openvcad_standins.py`). Each script is checked, then sliced as a user following
fgslice's hints would: a refusal whose hint names settings (`--set channels=3`, `--set
colors=4`...) is retried with the first one added, up to three times. Each row ends:

* ok: G-code written;
* refused: fgslice stopped with an error naming what it does not do or what does not fit
  (the reason is its first line);
* crash: an internal error or a traceback;
* timeout: the command ran longer than `--timeout` seconds.

Run: .venv/bin/python benchmarks/openvcad_examples.py /path/to/OpenVCAD-Public
     [--timeout 300] [--jobs 2] [--only substring]
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from openvcad_standins import examples_with_standins  # noqa: E402

FGSLICE = Path(sys.executable).with_name("fgslice")
ERROR = re.compile(r"(^|: )error: ")
HINTED = re.compile(r"--set ([a-z_]+=[^\s,)]+)")
RETRIES = 3


def run(args: list[str], timeout: float, cwd: Path) -> tuple[str, str, float]:
    """``(outcome, first error line, seconds)`` of one fgslice command."""
    start = time.perf_counter()
    try:
        done = subprocess.run([str(FGSLICE), *args], cwd=cwd, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return "timeout", f"over {timeout:g} s", time.perf_counter() - start
    seconds = time.perf_counter() - start
    text = done.stderr + done.stdout
    errors = [line.split("error: ", 1)[1] for line in text.splitlines() if ERROR.search(line)]
    if done.returncode == 0:
        return "ok", "", seconds
    if "Traceback" in text or any("internal error" in e for e in errors) or not errors:
        return "crash", (errors or text.strip().splitlines() or ["no output"])[-1][:200], seconds
    hints = [line for line in text.splitlines() if line.strip().startswith("hint:")]
    return "refused", errors[0][:200] + ("".join(f" | {h.strip()}" for h in hints[:1])), seconds


def slice_as_a_user(script: Path, timeout: float, jobs: int) -> tuple[str, str, float, list[str]]:
    """Slice ``script``, following settings its refusals suggest; the last outcome and the settings used."""
    sets: list[str] = []
    for _ in range(RETRIES + 1):
        args = ["slice", script.name, "-o", str(script.with_suffix(".gcode")), "--jobs", str(jobs)]
        outcome, reason, seconds = run(args + [a for s in sets for a in ("--set", s)], timeout, script.parent)
        suggested = HINTED.findall(reason) if outcome == "refused" else []
        new = [s for s in suggested if s.split("=")[0] not in {t.split("=")[0] for t in sets}]
        if not new:
            return outcome, reason, seconds, sets
        sets.append(new[-1])  # of "colors=1 or colors=5", the palette nearer the one asked for
    return outcome, reason, seconds, sets


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("checkout", type=Path, help="an OpenVCAD-Public checkout")
    parser.add_argument("--timeout", type=float, default=300.0, help="seconds per command")
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--only", default="", help="run only the scripts whose path contains this")
    args = parser.parse_args()
    counts: Counter = Counter()
    with tempfile.TemporaryDirectory() as tmp:
        examples = examples_with_standins(args.checkout, Path(tmp))
        scripts = sorted(p for p in examples.rglob("*.py") if args.only in str(p.relative_to(examples)))
        print(f"{'example':60} {'check':8} {'slice':8} {'s':>7}  settings / reason")
        for script in scripts:
            check, _, _ = run(["check", script.name], args.timeout, script.parent)
            outcome, reason, seconds, sets = slice_as_a_user(script, args.timeout, args.jobs)
            counts[outcome] += 1
            note = " ".join(f"--set {s}" for s in sets) + (f"  {reason}" if reason else "")
            print(f"{str(script.relative_to(examples)):60} {check:8} {outcome:8} {seconds:7.1f}  {note}", flush=True)
    print(f"\n{len(scripts)} examples: " + ", ".join(f"{counts[k]} {k}" for k in ("ok", "refused", "crash", "timeout")))


if __name__ == "__main__":
    main()
