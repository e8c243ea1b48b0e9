"""Cost of OpenVCAD 3's ways to derive FLOW_RATE from TEMPERATURE, side by side.

The same conversion (LW-PLA's flow table, linear between 220, 236 and 256 C) written as
a LookupTableConverter, an ExpressionConverter, a DerivedFloatAttribute of the
temperature, and two Python AttributeConverterBase subclasses: one computing with numpy
(called once with whole arrays), one branching on the value (called once per point), each
over a bar whose temperature runs 220-256 C along x. Prints the time to evaluate the
flow at N points (the attribute evaluation that slicing and the check repeat), and each
one's ratio to the lookup table.

Usage: python benchmarks/bench_v3_converters.py [N]   (default 20000)
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from fgslice.compat.script import load_script
from fgslice.design.attributes import attribute_fields

BAR = '''import pyvcad as pv
bar = pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(180, 12, 12))
t = pv.FloatAttribute("236 + x / 5")
bar.set_attribute(pv.DefaultAttributes.TEMPERATURE, t)
'''
KINDS = {
    "LookupTableConverter": BAR + '''root = pv.AttributeModifier(pv.LookupTableConverter(["temperature"], ["flow_rate"],
    [pv.LookupTableEntry(a, b) for a, b in [(220, 1.42), (236, 0.86), (256, 0.66)]], pv.InterpolationMode.LINEAR), bar)
''',
    "ExpressionConverter": BAR + '''root = pv.AttributeModifier(pv.ExpressionConverter(["temperature"], ["flow_rate"],
    ["temperature < 236 ? 1.42 - (temperature - 220) * 0.035 : 0.86 - (temperature - 236) * 0.01"]), bar)
''',
    "DerivedFloatAttribute": BAR + '''bar.set_attribute(pv.DefaultAttributes.FLOW_RATE, pv.DerivedFloatAttribute(
    "t < 236 ? 1.42 - (t - 220) * 0.035 : 0.86 - (t - 236) * 0.01", {"t": t}))
root = bar
''',
    "AttributeConverterBase, numpy": BAR + '''import numpy as np


class Flow(pv.AttributeConverterBase):
    def required_attributes(self):
        return ["temperature"]

    def output_attributes(self):
        return ["flow_rate"]

    def convert(self, samples):
        out = pv.AttributeSamples()
        out.set_sample("flow_rate", np.interp(samples.get_sample("temperature"), [220, 236, 256], [1.42, 0.86, 0.66]))
        return out

root = pv.AttributeModifier(Flow(), bar)
''',
    "AttributeConverterBase, if/else": BAR + '''class Flow(pv.AttributeConverterBase):
    def required_attributes(self):
        return ["temperature"]

    def output_attributes(self):
        return ["flow_rate"]

    def convert(self, samples):
        t = samples.get_sample("temperature")
        out = pv.AttributeSamples()
        out.set_sample("flow_rate", 1.42 - (t - 220) * 0.035 if t < 236 else 0.86 - (t - 236) * 0.01)
        return out

root = pv.AttributeModifier(Flow(), bar)
''',
}


def main() -> None:
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 20_000
    rng = np.random.default_rng(0)
    x, y, z = rng.uniform(-80, 80, n), rng.uniform(-6, 6, n), rng.uniform(-6, 6, n)  # 220 .. 252 C
    expected = 100 * np.interp(236 + x / 5, [220, 236, 256], [1.42, 0.86, 0.66])
    times = {}
    with tempfile.TemporaryDirectory() as folder:
        for kind, code in KINDS.items():
            path = Path(folder) / "bar.py"
            path.write_text(code)
            fields = attribute_fields(load_script(path))
            start = time.perf_counter()
            flow = fields.values("flow", x, y, z)
            times[kind] = time.perf_counter() - start
            assert np.allclose(flow, expected, atol=1e-6), kind
    base = times["LookupTableConverter"]
    for kind, seconds in times.items():
        print(f"{kind:<32} {seconds * 1e3:9.1f} ms for {n} points   x{seconds / base:8.1f}")


if __name__ == "__main__":
    main()
