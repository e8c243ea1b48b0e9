"""Offset and Shell sections of a mesh: exact (the mesh's section with the band of its
triangles, ``fgslice.design.offset.TriangleBand``) against tracing the shifted 3-D
distance (``nodes.sampled_section``), side by side in one run, with the area they differ by.

    .venv/bin/python benchmarks/bench_offset.py [--subdivisions 3]
    .venv/bin/python benchmarks/bench_offset.py --mesh ../shared/data/meshes/3DBenchy.stl --planes 4 --exact-only

``--mesh`` takes any mesh file (e.g. the 225,154-triangle 3DBenchy) instead of the
icosphere; its sections are taken at ``--planes`` heights spread over its middle, and
``--exact-only`` leaves out tracing (on a mesh that large, minutes a plane). Prints CPU
seconds per plane.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import trimesh

from fgslice.design import api, nodes


def _timed(function):
    start = time.process_time()
    result = function()
    return result, time.process_time() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--subdivisions", type=int, default=3, help="icosphere subdivisions (3: 1280 triangles)")
    parser.add_argument("--mesh", type=Path, help="a mesh file to offset instead of the icosphere")
    parser.add_argument("--planes", type=int, default=1, help="section heights (the icosphere's: z = 3 mm and up)")
    parser.add_argument("--exact-only", action="store_true", help="leave out tracing the shifted distance")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        if args.mesh is None:
            path = Path(folder) / "ball.stl"
            ball = trimesh.creation.icosphere(subdivisions=args.subdivisions, radius=15)
            ball.export(path)
            heights = 3.0 + np.arange(args.planes) * 2.0
            label = f"icosphere r = 15 mm, {len(ball.faces)} triangles"
        else:
            path = args.mesh
            loaded = trimesh.load(path, force="mesh")
            lo, hi = loaded.bounds[:, 2]
            heights = lo + (hi - lo) * (np.arange(args.planes) + 1) / (args.planes + 1)
            label = f"{path.name}, {len(loaded.faces)} triangles"
        mesh = api.mesh(path)
        print(f"{label}, planes at z = {', '.join(f'{z:.1f}' for z in heights)} mm, spacing 0.1 mm "
              f"(CPU s per plane)")
        for name, part in (("Offset(+1)", api.offset(1, mesh)), ("Offset(-1.5)", api.offset(-1.5, mesh)),
                           ("Shell(2)", api.shell(2, mesh))):
            exact, t_exact = _timed(lambda: [part.section(float(z), 0.1) for z in heights])
            line = f"{name:13s} exact {t_exact / len(heights):7.2f} s"
            if not args.exact_only:
                shape = part.shape
                traced, t_traced = _timed(lambda: [nodes.sampled_section(shape, float(z), 0.1) for z in heights])
                differ = sum(e.symmetric_difference(t).area for e, t in zip(exact, traced))
                line += (f"  traced {t_traced / len(heights):7.2f} s  ratio {t_traced / t_exact:5.1f}  areas "
                         f"{sum(e.area for e in exact):8.2f} / {sum(t.area for t in traced):8.2f} mm2, "
                         f"differ by {differ:.3f} mm2")
            else:
                line += f"  area {sum(e.area for e in exact):9.2f} mm2"
            print(line, flush=True)


if __name__ == "__main__":
    main()
