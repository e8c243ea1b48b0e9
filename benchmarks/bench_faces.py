"""Time per layer of the color faces on the paper's palette object.

The object is a 135 x 175 x 2 mm elliptic plate graded by
``f_A = (1 + sin(0.025 x + 0.0375 y) cos(0.0375 x - 0.025 y)) / 2``. Prints ms/layer for
4, 12, 24 and 48 colors (two materials), the split between outline, field sampling and
faces, and how the time scales with the palette size.

Run: ``.venv/bin/python benchmarks/bench_faces.py [--repeat 5] [--spacing MM]``
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import shapely

from fgslice.design.base import Design, Material
from fgslice.settings import Settings
from fgslice.slicing.palette import Palette
from fgslice.slicing.plan_layers import layer_heights, place_design
from fgslice.slicing.regions import slice_layer


class PalettePlate(Design):
    """Elliptic plate (semi-axes 67.5 and 87.5 mm, 2 mm thick) with the paper's sin-cos gradient."""

    AX, AY, H = 67.5, 87.5, 2.0

    @property
    def materials(self) -> list[Material]:
        return [Material("blue", (0.1, 0.2, 0.9, 1.0)), Material("yellow", (0.95, 0.85, 0.1, 1.0))]

    def sdf(self, x, y, z):
        radial = (np.hypot(x / self.AX, y / self.AY) - 1.0) * min(self.AX, self.AY)
        return np.maximum(radial, np.abs(z) - self.H / 2)

    def fractions(self, x, y, z):
        x, y, z = np.broadcast_arrays(x, y, z)
        a = (1 + np.sin(0.025 * x + 0.0375 * y) * np.cos(0.0375 * x - 0.025 * y)) / 2
        return np.stack([a, 1 - a], axis=-1)

    def bounds(self):
        return (-self.AX, -self.AY, -self.H / 2), (self.AX, self.AY, self.H / 2)

    def section(self, z):
        if abs(z) >= self.H / 2:
            return shapely.MultiPolygon()
        disk = shapely.Point(0, 0).buffer(1.0, quad_segs=64)
        return shapely.MultiPolygon([shapely.affinity.scale(disk, self.AX, self.AY, origin=(0, 0))])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5, help="layers timed per palette size")
    parser.add_argument("--spacing", type=float, default=None, help="field sample spacing, mm (default: the bead width)")
    args = parser.parse_args()

    design = PalettePlate()
    settings = Settings()
    placement = place_design(design, settings)
    layers = layer_heights(design, settings)
    spacing = args.spacing or settings.bead_width
    print(f"palette object 135 x 175 mm, bead width {settings.bead_width} mm, grid spacing {spacing} mm, "
          f"{len(layers)} layers")
    base = None
    for colors in (4, 12, 24, 48):
        palette = Palette(2, colors)
        times = []
        for i in range(args.repeat):
            index, z_top, h = layers[i % len(layers)]
            t0 = time.process_time()
            regions = slice_layer(design, placement, palette, index, z_top, h, settings, spacing=spacing)
            times.append(time.process_time() - t0)
        ms = 1000 * float(np.median(times))
        base = base or ms
        area = sum(f.area for f in regions.faces)
        print(f"{colors:3d} colors: {ms:7.1f} ms CPU/layer (median of {args.repeat}), "
              f"x{ms / base:.2f} of 4 colors, faces cover {100 * area / regions.outline.area:.4f}% of the outline, "
              f"{sum(shapely.get_num_coordinates(np.array(regions.faces)))} vertices")


if __name__ == "__main__":
    main()
