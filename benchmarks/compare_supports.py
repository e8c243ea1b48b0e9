"""Support volume of fgslice next to PrusaSlicer 2.5's, on the overhang test parts.

Parts: an arch, a T, a 45/60/75° overhang fan, a wing in a box (the designs of
``tests/test_toolpaths_supports.py``) and the single-material 3DBenchy
(``../shared/data/meshes/3DBenchy.stl``). fgslice slices each with ``support = true``
(strategy 1, one color, 0.2 mm layers, support also on the part as PrusaSlicer's default);
PrusaSlicer gets an STL of the same part: the 3DBenchy's own, else the layer outlines
fgslice slices, each extruded over its layer (a stack of prisms; PrusaSlicer's planes at
the layers' middles cut exactly those outlines) and runs
``prusa-slicer --export-gcode --support-material`` with 0.2 mm layers. Both G-codes are
read by fgslice's reader: the support volume (``;TYPE:Support material`` and ``Support
material interface`` moves, mm³) and the share of all extruded volume laid over nothing
(:func:`fgslice.analysis.overhang.unsupported_share`; PrusaSlicer's support ends
:data:`PRUSA_GAP_MM` below the layer it holds).

Run: ``.venv/bin/python benchmarks/compare_supports.py [--jobs 2] [--parts arch,T]``.
Prints one row per part and the ratio fgslice / PrusaSlicer (the target: within 1.5x).
"""

from __future__ import annotations

import argparse
import shutil
import struct
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import shapely

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from test_toolpaths_supports import GRADE, PARTS  # noqa: E402

from fgslice.analysis.overhang import SUPPORT_ROLES, unsupported_share  # noqa: E402
from fgslice.design.language import parse_design  # noqa: E402
from fgslice.machine.gcode_reader import read_gcode  # noqa: E402
from fgslice.pipeline import slice_to_gcode  # noqa: E402
from fgslice.settings import load_settings  # noqa: E402
from fgslice.slicing.plan_layers import layer_heights  # noqa: E402

BENCHY_STL = ROOT.parent / "shared" / "data" / "meshes" / "3DBenchy.stl"
FILAMENT_MM = 1.75
PRUSA_GAP_MM = 0.4
"""PrusaSlicer's support top below the bottom of the layer it holds: its 0.2 mm contact
distance, and the first layer over support printed as a bridge of nozzle height."""
SETTINGS = {"strategy": "1", "colors": "1", "layer_height": "0.2", "support": "true", "support_to": "part"}


def prism_stl(design, settings, path: Path) -> None:
    """A binary STL of ``design``'s layer outlines, each extruded over its layer."""
    triangles = []
    for _, top, height in layer_heights(design, settings):
        section = shapely.orient_polygons(design.sections([top - height / 2])[0])  # holes clockwise
        z0, z1 = top - height, top
        for tri in shapely.get_parts(shapely.constrained_delaunay_triangles(section)):
            a, b, c = np.asarray(tri.exterior.coords)[:3]
            triangles += [[(*a, z1), (*b, z1), (*c, z1)], [(*a, z0), (*c, z0), (*b, z0)]]
        for ring in shapely.get_rings(shapely.get_parts(section)):
            xy = np.asarray(ring.coords)
            for p, q in zip(xy[:-1], xy[1:]):
                triangles += [[(*p, z0), (*q, z0), (*q, z1)], [(*p, z0), (*q, z1), (*p, z1)]]
    tri = np.asarray(triangles, dtype=np.float32)
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
    record = np.zeros(len(tri), dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
    record["n"], record["v"] = normals, tri
    path.write_bytes(b"\0" * 80 + struct.pack("<I", len(tri)) + record.tobytes())


def measured(gcode: Path, gap_mm: float) -> tuple[float, float]:
    """Support volume (mm³) and share of extruded volume over nothing of a G-code file
    (``gap_mm``: the support's top z gap below the bottom of the layer it holds)."""
    program = read_gcode(gcode)
    roles = np.array(list(program.roles) + [""], dtype=object)[program.role]
    support = np.isin(roles, SUPPORT_ROLES) & (program.e > 0) & (program.length > 0)
    volume = float(program.e[support].sum() * np.pi * FILAMENT_MM**2 / 4)
    return volume, unsupported_share(program, 0.4, gap_mm=gap_mm)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--jobs", type=int, default=2, help="fgslice worker processes")
    parser.add_argument("--parts", default=",".join([*PARTS, "benchy"]), help="comma-separated part names")
    parser.add_argument("--benchy", type=Path, default=BENCHY_STL, help="the 3DBenchy STL")
    args = parser.parse_args()
    prusa = shutil.which("prusa-slicer")
    settings = load_settings(None, SETTINGS)
    print(f"{'part':<14} {'fgslice mm3':>12} {'prusa mm3':>10} {'ratio':>6} {'fg over nothing':>16} {'prusa over nothing':>19}")
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        for name in args.parts.split(","):
            if name == "benchy":
                if not args.benchy.exists():
                    print(f"{name:<14} skipped: {args.benchy} not found")
                    continue
                design = parse_design(f'mesh("{args.benchy}");')
                stl = args.benchy
            else:
                design = parse_design(f"fgrade({GRADE}) {{ {PARTS[name]} }}")
                stl = work / f"{name.replace(' ', '_')}.stl"
                prism_stl(design, settings, stl)
            ours = work / f"{name.replace(' ', '_')}_fgslice.gcode"
            slice_to_gcode(design, settings, ours, jobs=args.jobs)
            fg_volume, fg_share = measured(ours, settings.support_top_z_gap)
            if not prusa:
                print(f"{name:<14} {fg_volume:>12.0f} {'-':>10} {'-':>6} {fg_share * 100:>15.3f}% prusa-slicer not installed")
                continue
            theirs = work / f"{name.replace(' ', '_')}_prusa.gcode"
            subprocess.run([prusa, "--export-gcode", "--support-material", "--layer-height", "0.2",
                            "--first-layer-height", "0.2", "--center", "110,110", "-o", str(theirs), str(stl)],
                           check=True, capture_output=True)
            pr_volume, pr_share = measured(theirs, PRUSA_GAP_MM)
            ratio = fg_volume / pr_volume if pr_volume > 0 else float("inf")
            print(f"{name:<14} {fg_volume:>12.0f} {pr_volume:>10.0f} {ratio:>6.2f} {fg_share * 100:>15.3f}% "
                  f"{pr_share * 100:>18.3f}%", flush=True)


if __name__ == "__main__":
    main()
