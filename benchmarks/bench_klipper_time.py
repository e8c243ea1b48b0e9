"""fgslice's print-time estimate against Klipper's batch mode, on every profile's examples.

Each case is sliced with its profile; Klipper (batch mode, the printer.cfg that
:func:`fgslice.machine.klipper.printer_cfg` writes for the profile) plans the same file,
and its print time from the first layer to the end is set beside fgslice's estimate
(``estimated_time_s``). Prints each file's two times (s) and their ratio, then the
median and the largest deviation. The Marlin profiles are also run with
``motion_planner = klipper`` (Klipper's own junctions and minimum cruise ratio). Skips (exit 0) without Klipper: set ``FGSLICE_KLIPPER``,
``FGSLICE_KLIPPER_PYTHON`` and ``FGSLICE_KLIPPER_DICT`` as for
``tests/test_klipper_batch.py`` (docs/gcode.md, "Checked against Klipper").

Run: ``.venv/bin/python benchmarks/bench_klipper_time.py [--only PROFILE]`` (a few minutes:
Klipper plans about 10,000 lines a second).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
from pathlib import Path

from fgslice.design.language import load_design
from fgslice.machine.klipper import KlipperBatch
from fgslice.pipeline import slice_to_gcode
from fgslice.settings import load_settings

ROOT = Path(__file__).resolve().parents[1]

#: (example, profile, overrides): each profile's examples, sliced so that files stay under
#: about 100,000 lines.
CASES = [
    ("palette.vcad", "marlin-mixing", {"strategy": "2", "fill_pattern": "rectilinear"}),
    ("fan_gradient.vcad", "marlin-mixing", {}),
    ("ring_radial_gradient.vcad", "marlin-mixing", {"strategy": "1", "layer_height": "0.3"}),
    ("temperature_gradient.vcad", "marlin-mixing-m163", {}),
    ("temperature_gradient.vcad", "toolchanger", {"colors": "4"}),
    ("ring_radial_gradient.vcad", "toolchanger", {"strategy": "1", "colors": "4", "layer_height": "0.3"}),
    ("cylinder_z_gradient.vcad", "foam-tpu", {"strategy": "1", "layer_height": "0.3"}),
    ("plate_y_gradient.vcad", "foam-lwpla", {"strategy": "1"}),
    ("dogbone.vcad", "template-diw", {}),
    ("dogbone.vcad", "klipper-diw", {}),
    ("temperature_gradient.vcad", "klipper-mixing", {}),
    ("ring_radial_gradient.vcad", "klipper-mixing", {"strategy": "1", "layer_height": "0.3"}),
    ("fan_gradient.vcad", "marlin-mixing", {"motion_planner": "klipper"}),
    ("ring_radial_gradient.vcad", "marlin-mixing", {"strategy": "1", "layer_height": "0.3",
                                                    "motion_planner": "klipper"}),
    ("palette.vcad", "toolchanger", {"strategy": "1", "layer_height": "0.3", "motion_planner": "klipper"}),
]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", help="only the cases of this profile")
    args = parser.parse_args()
    klipper = KlipperBatch.from_environment()
    if klipper is None:
        print("skipped: Klipper not available (set FGSLICE_KLIPPER, FGSLICE_KLIPPER_PYTHON, FGSLICE_KLIPPER_DICT)")
        return 0
    ratios = []
    print(f"{'case':62s} {'fgslice':>11s} {'Klipper':>11s} {'ratio':>6s}")
    with tempfile.TemporaryDirectory() as tmp:
        for k, (example, profile, overrides) in enumerate(CASES):
            if args.only and profile != args.only:
                continue
            folder = Path(tmp) / str(k)
            folder.mkdir()
            settings = load_settings(profile, overrides)
            gcode = folder / "part.gcode"
            result = slice_to_gcode(load_design(ROOT / "examples" / example), settings, gcode, jobs=1)
            estimate = result.stats["estimated_time_s"]
            actual = klipper.print_time(klipper.config(settings), gcode, folder)
            ratios.append(estimate / actual)
            name = " ".join([example, profile, *(f"{key}={value}" for key, value in overrides.items())])
            print(f"{name:62s} {estimate:11.1f} {actual:11.1f} "
                  f"{estimate / actual:6.3f}", flush=True)
    deviations = [abs(r - 1) for r in ratios]
    print(f"median deviation {100 * statistics.median(deviations):.1f} %, largest {100 * max(deviations):.1f} %")
    return 0


if __name__ == "__main__":
    sys.exit(main())
