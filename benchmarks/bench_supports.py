"""Support planning (``plan_supports``) on the full 3DBenchy: time and support volume,
optionally against a git revision, run alternately.

The Benchy's strategy-1 layer outlines (0.2 mm layers, as the slicer simplifies them) are
cut once with the working tree; each version then plans the support of those outlines
with ``support_to = bed`` and ``part`` (the defaults otherwise) in a process of its own
(``PYTHONPATH`` selects the source tree), ``--repeat`` times in turns. Prints the median
seconds of each, the ratio now / base, and each version's support volume (the regions'
area times the layer height, mm³: the same output gives the same volume).

Run: ``.venv/bin/python benchmarks/bench_supports.py [--base REV] [--repeat 3]``.
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
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BENCHY_STL = Path(os.environ.get("FGSLICE_SHARED_DATA", ROOT.parent / "shared" / "data")) / "meshes" / "3DBenchy.stl"
MODES = ("bed", "part")


def cut_outlines(path: Path) -> int:
    """The Benchy's layer outlines, as the slicer's strategy 1 makes them, to ``path`` (WKB)."""
    import numpy as np
    import shapely

    from fgslice.design.language import parse_design
    from fgslice.pipeline import polygonal_each, simplify_outline
    from fgslice.settings import load_settings
    from fgslice.slicing.plan_layers import layer_heights

    settings = load_settings(None, {"strategy": "1", "colors": "1", "support": "true"})
    design = parse_design(f"mesh({json.dumps(str(BENCHY_STL))});")
    zs = [top - height / 2 for _, top, height in layer_heights(design, settings)]
    sections = np.array(design.sections(zs), dtype=object)
    outlines = polygonal_each(simplify_outline(polygonal_each(sections), settings.gcode_resolution))
    path.write_bytes(json.dumps([g.hex() for g in shapely.to_wkb(list(outlines))]).encode())
    return len(zs)


def worker(path: Path) -> None:
    """Plan the support of the outlines in ``path`` once per mode; print seconds and volume."""
    import shapely

    from fgslice.settings import Settings
    from fgslice.toolpaths.supports import plan_supports

    outlines = list(shapely.from_wkb([bytes.fromhex(h) for h in json.loads(path.read_text())]))
    out = {}
    for mode in MODES:
        settings = Settings(support=True, support_to=mode)
        start = time.process_time()
        layers = plan_supports(outlines, settings)
        seconds = time.process_time() - start
        volume = sum(layer.body.area + layer.interface.area for layer in layers) * settings.layer_height
        out[mode] = (seconds, volume)
    print(json.dumps(out))


def run(source: Path, path: Path) -> dict[str, tuple[float, float]]:
    env = {**os.environ, "PYTHONPATH": str(source)}
    done = subprocess.run([sys.executable, __file__, "--worker", str(path)], env=env, capture_output=True, text=True,
                          check=True)
    return json.loads(done.stdout.splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--base", help="git revision to compare the working tree with")
    parser.add_argument("--repeat", type=int, default=3, help="runs of each version")
    parser.add_argument("--worker", type=Path, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        worker(args.worker)
        return
    with tempfile.TemporaryDirectory() as tmp:
        workdir = Path(tmp)
        path = workdir / "outlines.json"
        layers = cut_outlines(path)
        versions = {"now": ROOT / "src"}
        if args.base:
            base = workdir / "base"
            subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", str(base), args.base], check=True,
                           capture_output=True)
            versions = {"base": base / "src", **versions}
        try:
            runs = {label: [] for label in versions}
            for _ in range(args.repeat):
                for label, source in versions.items():
                    runs[label].append(run(source, path))
        finally:
            if args.base:
                subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(base)], capture_output=True)
    print(f"3DBenchy, {layers} layers, plan_supports CPU seconds (median of {args.repeat}) and support volume")
    for mode in MODES:
        row = {label: (statistics.median(r[mode][0] for r in rs), rs[0][mode][1]) for label, rs in runs.items()}
        text = "  ".join(f"{label} {s:6.2f} s {v:9.1f} mm3" for label, (s, v) in row.items())
        ratio = f"  now/base {row['now'][0] / row['base'][0]:.2f}" if "base" in row else ""
        print(f"support_to = {mode:4s}  {text}{ratio}")


if __name__ == "__main__":
    main()
