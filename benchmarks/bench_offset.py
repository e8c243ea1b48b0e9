"""Offset and Shell sections of a mesh: exact (the mesh's section with the band of its
triangles, ``fgslice.design.offset.triangle_band``) against tracing the shifted 3-D
distance (``nodes.sampled_section``), side by side in one run, with the area they differ by.

    .venv/bin/python benchmarks/bench_offset.py [--subdivisions 3]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import trimesh

from fgslice.design import api, nodes


def _timed(function):
    start = time.process_time()
    result = function()
    return result, time.process_time() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--subdivisions", type=int, default=3, help="icosphere subdivisions (3: 1280 triangles)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "ball.stl"
        ball = trimesh.creation.icosphere(subdivisions=args.subdivisions, radius=15)
        ball.export(path)
        mesh = api.mesh(path)
        print(f"icosphere r = 15 mm, {len(ball.faces)} triangles, one plane at z = 3 mm, spacing 0.1 mm (CPU s)")
        for name, part in (("Offset(+1)", api.offset(1, mesh)), ("Offset(-1.5)", api.offset(-1.5, mesh)),
                           ("Shell(2)", api.shell(2, mesh))):
            exact, t_exact = _timed(lambda: part.section(3.0, 0.1))
            shape = part.shape
            traced, t_traced = _timed(lambda: nodes.sampled_section(shape, 3.0, 0.1))
            differ = exact.symmetric_difference(traced).area
            print(f"{name:13s} exact {t_exact:6.2f} s  traced {t_traced:6.2f} s  ratio {t_traced / t_exact:5.1f}  "
                  f"areas {exact.area:8.2f} / {traced.area:8.2f} mm2, differ by {differ:.3f} mm2")


if __name__ == "__main__":
    main()
