"""Strategy 1 next to PrusaSlicer and CuraEngine: solid and sparse volume per layer.

Slices the single-material 3DBenchy (``../shared/data/meshes/3DBenchy.stl``; 0.2 mm
layers, 2 walls, 15 % infill, 3 top / 3 bottom layers, one skirt loop, the commands of
``run_all.py``'s comparison) with fgslice and, when installed, ``prusa-slicer`` and
``CuraEngine`` (printer definitions of Debian's ``cura`` package, with the values of
:data:`CURA_VALUES`), reads each G-code with
fgslice's reader and sums the extruded volume (mm³, ``E`` x filament area) of every move
by feature of its ``;TYPE:`` (``analysis.simulate.feature_of_roles``): walls, solid
(top, bottom, internal solid and bridge infill, Cura's SKIN) and sparse infill.

Prints a table of the layers by height (every ``--every``-th layer, and each layer of
the deck's underside, z 8.2-8.6 mm), the totals, and the solid volume under the deck
against CuraEngine's (the target: within 10 %). Layers are matched by their ``;Z:``
height (Cura's by the height of its moves), rounded to 0.01 mm.

Run: ``.venv/bin/python benchmarks/compare_volumes.py [--every 10] [--jobs 2]``.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from run_all import BENCHY_STL, comparison_commands  # noqa: E402

from fgslice.analysis.simulate import FEATURES, feature_of_roles  # noqa: E402
from fgslice.machine.gcode_reader import read_gcode  # noqa: E402

CURA_VALUES = {
    "infill_sparse_thickness": 0.2, "infill_line_distance": 2 * 0.4 * 100 / 15,
    "top_skin_expand_distance": 0.8, "bottom_skin_expand_distance": 0.8,
    "top_skin_preshrink": 0.8, "bottom_skin_preshrink": 0.8,
}
"""Settings CuraEngine takes from ``fdmprinter.def.json`` as bare default values: the Cura
front end derives them by formula, the engine alone does not (it would print infill every
0.1 mm layer with 2 mm line spacing). These are the front end's values for the run:
the layer height, the grid's line distance ``2 w 100 / density``, and the skin expand
and preshrink distances ``wall_line_width_0 + (wall_line_count - 1) wall_line_width_x``."""
CURA_EXTRUDER = ("-e0", "-s", "material_diameter=1.75")
"""The filament diameter is an extruder setting: without it Cura's E is for 2.85 mm."""
FILAMENT_MM = 1.75
DECK_Z = (8.2, 8.6)
"""Layer tops (mm) of the deck's underside, where the skins used to stop short."""
SLICERS = ("fgslice", "prusa-slicer", "CuraEngine")
COLUMNS = ("walls", "solid", "sparse")


def layer_volumes(gcode: Path) -> dict[float, np.ndarray]:
    """Per layer top z (mm, rounded to 0.01): extruded volume of walls, solid and sparse, mm³."""
    program = read_gcode(gcode)
    feature = np.r_[feature_of_roles(program.roles), len(FEATURES) - 1][program.role]
    printing = (program.e > 0) & (program.length > 0)
    volume = program.e * np.pi * FILAMENT_MM**2 / 4
    z = np.round(program.end[:, 2], 2)
    out: dict[float, np.ndarray] = {}
    for column, name in enumerate(("walls", "skins", "infill")):
        chosen = printing & (feature == FEATURES.index(name))
        for top in np.unique(z[chosen]).tolist():
            out.setdefault(top, np.zeros(len(COLUMNS)))[column] = float(volume[chosen & (z == top)].sum())
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--every", type=int, default=10, help="print every n-th layer (and the deck's)")
    parser.add_argument("--jobs", type=int, default=2, help="fgslice worker processes")
    args = parser.parse_args()
    if not BENCHY_STL.exists():
        print(f"skipped: {BENCHY_STL} not found")
        return
    with tempfile.TemporaryDirectory() as tmp:
        workdir = Path(tmp)
        commands = comparison_commands(BENCHY_STL, workdir, args.jobs)
        volumes: dict[str, dict[float, np.ndarray]] = {}
        for name in SLICERS:
            command = commands[name]
            if isinstance(command, str):
                print(f"{name}: {command}")
                continue
            if name == "CuraEngine":
                at = command.index("-l")
                extra = [a for k, v in CURA_VALUES.items() for a in ("-s", f"{k}={v:g}")]
                command = command[:at] + extra + list(CURA_EXTRUDER) + command[at:]
            out = Path(command[command.index("-o") + 1])
            run = subprocess.run(command, capture_output=True, text=True)
            if run.returncode != 0 or not out.exists():
                print(f"{name}: failed ({run.returncode}): {run.stderr.strip().splitlines()[-1:] }")
                continue
            volumes[name] = layer_volumes(out)
    names = list(volumes)
    heights = sorted(set().union(*volumes.values()))
    head = "   z mm " + "".join(f"| {n:^29} " for n in names)
    sub = "        " + "".join("| " + " ".join(f"{c:>9}" for c in COLUMNS) + " " for _ in names)
    print(f"\nvolume per layer, mm3 (3DBenchy, 0.2 mm, 2 walls, 15 % infill)\n{head}\n{sub}")
    for i, z in enumerate(heights):
        if i % args.every and not (DECK_Z[0] - 1e-6 <= z <= DECK_Z[1] + 1e-6):
            continue
        cells = [volumes[n].get(z, np.zeros(len(COLUMNS))) for n in names]
        print(f"{z:7.2f} " + "".join("| " + " ".join(f"{v:9.1f}" for v in c) + " " for c in cells))
    totals = {n: np.sum(list(volumes[n].values()), axis=0) for n in names}
    print("  total " + "".join("| " + " ".join(f"{v:9.0f}" for v in totals[n]) + " " for n in names))
    deck = {n: sum(v[1] for z, v in volumes[n].items() if DECK_Z[0] - 1e-6 <= z <= DECK_Z[1] + 1e-6) for n in names}
    print(f"\nsolid volume under the deck (layer tops z {DECK_Z[0]}-{DECK_Z[1]} mm), mm3:")
    for n in names:
        ratio = f"  ratio to CuraEngine {deck[n] / deck['CuraEngine']:.3f}" if deck.get("CuraEngine") else ""
        print(f"  {n:13} {deck[n]:8.1f}{ratio}")
    for n in names:
        if n != "fgslice":
            ratios = ", ".join(f"{c} {totals['fgslice'][k] / totals[n][k]:.3f}" for k, c in enumerate(COLUMNS) if totals[n][k])
            print(f"totals fgslice / {n}: {ratios}")


if __name__ == "__main__":
    main()
