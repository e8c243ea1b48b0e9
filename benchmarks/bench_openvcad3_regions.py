"""OpenVCAD 3's foaming bar sliced by fgslice against 12 piecewise-constant regions.

The design is the attribute-resolver guide's Lesson 1 (a 180 mm bar, TEMPERATURE
220-256 C along x, FLOW_RATE from the LW-PLA lookup table). fgslice's G-code is read
back and, at the midpoint of every printed move of the part, the commanded temperature
(the state's M104) and flow (E per mm over the nominal bead) are compared with the
fields. OpenVCAD's slicer-project compiler would instead cut the temperature range into
12 equal bands, each printed at its mean temperature and flow; the same points are
compared with that. Prints the largest and mean deviations.

Usage: python benchmarks/bench_openvcad3_regions.py [temperature_step]   (default 5 C)
"""

from __future__ import annotations

import sys
import tempfile
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from fgslice.compat.script import load_script
from fgslice.design.attributes import attribute_fields
from fgslice.machine.gcode_reader import read_gcode
from fgslice.pipeline import slice_to_gcode
from fgslice.settings import load_settings
from fgslice.toolpaths.paths import bead_area

DESIGN = '''import pyvcad as pv
temperature_expr = "max(min((x/3 + 236), 256), 220)"
table = [(220, 1.42), (224, 1.23), (228, 1.08), (232, 0.98), (236, 0.86), (240, 0.76), (244, 0.72),
         (248, 0.69), (252, 0.67), (256, 0.66)]
converter = pv.LookupTableConverter(input_attributes=[pv.DefaultAttributes.TEMPERATURE],
                                    output_attributes=[pv.DefaultAttributes.FLOW_RATE],
                                    entries=[pv.LookupTableEntry(t, t, f) for t, f in table],
                                    mode=pv.InterpolationMode.LINEAR)
bar = pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(180.0, 12.0, 12.0))
bar.set_attribute(pv.DefaultAttributes.TEMPERATURE, pv.FloatAttribute(temperature_expr))
root = pv.AttributeModifier(converter, bar)
'''
REGIONS = 12


def main(step: str) -> None:
    folder = Path(tempfile.mkdtemp())
    (folder / "bar.py").write_text(DESIGN)
    design = load_script(folder / "bar.py")
    settings = load_settings("foam-lwpla", {"temperature_step": step})
    result = slice_to_gcode(design, settings, folder / "bar.gcode", jobs=1,
                            stamp=datetime(2026, 1, 1, tzinfo=timezone.utc))
    program = read_gcode(folder / "bar.gcode")
    roles = np.array(program.roles + [""])[program.role]
    part = (program.e > 0) & (program.length > 0) & (program.layer > 0) & ~np.isin(roles, ["Skirt/Brim", "Wipe tower"])
    mid = (program.start + program.end)[part] / 2 - np.array(result.stats["placement_offset"])
    fields = attribute_fields(design)
    flow, temperature = (fields.values(n, *mid.T) for n in ("flow", "temperature"))
    heights = np.diff([0.0, *program.layer_z])[program.layer[part]]
    nominal = bead_area(program.width[part], heights) / (np.pi * settings.filament_diameter**2 / 4)
    commanded_flow = 100 * program.e[part] / program.length[part] / nominal
    commanded_t = np.array([program.states[s].temperature for s in program.state[part]])
    band = np.clip(np.digitize(temperature, np.linspace(220, 256, REGIONS + 1)) - 1, 0, REGIONS - 1)
    region_t = np.array([temperature[band == b].mean() if (band == b).any() else 0.0 for b in range(REGIONS)])[band]
    region_flow = np.array([flow[band == b].mean() if (band == b).any() else 0.0 for b in range(REGIONS)])[band]
    print(f"{part.sum()} moves; temperature_step {step} C")
    for name, t, f in (("fgslice", commanded_t, commanded_flow), (f"{REGIONS} regions", region_t, region_flow)):
        print(f"{name:>11}: temperature off by max {np.abs(t - temperature).max():.2f} C, mean "
              f"{np.abs(t - temperature).mean():.2f} C; flow off by max {np.abs(f - flow).max():.2f}, mean "
              f"{np.abs(f - flow).mean():.2f} points of %")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "5")
