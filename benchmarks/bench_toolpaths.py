"""Toolpath timings on the paper's vase cross-section (135 x 175 mm ellipse).

* strategy 2, 48 colors: faces = bands of the sin*cos gradient (contourpy filled
  contours intersected with the outline), concentric and rectilinear fills;
* strategy 1, 10 perimeters, no infill (the vase), 16 colors, zipper off and on;
* strategy 1, 3 perimeters and 100 % infill (the palette object), 16 colors;
* the real examples as the pipeline runs them: ``examples/vase.vcad`` layer 250
  (strategy 1, 10 walls, no infill or skins, 16 colors) and ``examples/palette.vcad``
  layer 5 (strategy 2, faces from ``slice_layer``, 12 and 48 colors).

Prints CPU ms per layer (``time.process_time``, median of repeats: the machine may be
shared, so wall time is not used), path counts and the volume ratio
``sum(length * bead_area) / (outline area * h)``.
Run: ``.venv/bin/python benchmarks/bench_toolpaths.py``.
"""

from __future__ import annotations

import time
from pathlib import Path

import contourpy
import numpy as np
import shapely

from fgslice.design import load_design
from fgslice.settings import Settings
from fgslice.slicing.field import BedField
from fgslice.slicing.layers import LayerRegions
from fgslice.slicing.palette import Palette
from fgslice.slicing.plan_layers import layer_heights, place_design
from fgslice.slicing.regions import polygonal, slice_layer
from fgslice.toolpaths import strategy1, strategy2
from fgslice.toolpaths.paths import bead_area

CENTER = (110.0, 110.0)


class SinCosField:
    """The paper's XY gradient, in design coordinates centred on the part."""

    def fractions(self, xy, z):
        x, y = xy[:, 0] - CENTER[0], xy[:, 1] - CENTER[1]
        f = (1 + np.sin(0.02 * x + 0.03 * y) * np.cos(0.03 * x - 0.02 * y)) / 2
        return np.column_stack([f, 1 - f])


def ellipse() -> shapely.MultiPolygon:
    circle = shapely.Point(CENTER).buffer(1.0, quad_segs=128)
    return shapely.MultiPolygon([shapely.affinity.scale(circle, 67.5, 87.5)])


def band_faces(outline, n: int, spacing: float = 0.25) -> tuple:
    """One face per color: filled contours of the first fraction, clipped to the outline."""
    minx, miny, maxx, maxy = outline.bounds
    xs = np.arange(minx - 1, maxx + 1, spacing)
    ys = np.arange(miny - 1, maxy + 1, spacing)
    gx, gy = np.meshgrid(xs, ys)
    f = SinCosField().fractions(np.column_stack([gx.ravel(), gy.ravel()]), 0)[:, 0].reshape(gx.shape)
    gen = contourpy.contour_generator(xs, ys, f, fill_type="OuterOffset")
    levels = np.linspace(0, 1, n + 1)
    levels[0], levels[-1] = -1, 2
    faces = []
    for lo, hi in zip(levels[:-1], levels[1:]):
        polys = []
        for pts, offs in zip(*gen.filled(lo, hi)):
            rings = [pts[a:b] for a, b in zip(offs[:-1], offs[1:])]
            polys.append(shapely.Polygon(rings[0], rings[1:]))
        band = shapely.union_all(polys) if polys else shapely.Polygon()
        faces.append(shapely.intersection(band.buffer(0), outline))
    return tuple(faces)


def timed(fn, repeats: int = 5) -> tuple[float, object]:
    """Median CPU time of ``fn`` in ms, and its last result."""
    out, times = None, []
    for _ in range(repeats):
        t = time.process_time()
        out = fn()
        times.append(time.process_time() - t)
    return 1e3 * float(np.median(times)), out


def volume_ratio(paths, outline, h) -> float:
    return sum(p.length * bead_area(p.width, p.height) for p in paths) / (outline.area * h)


def main() -> None:
    outline = ellipse()
    h = 0.2
    t0 = time.process_time()
    faces = band_faces(outline, 48)
    print(f"faces (48 colors, contourpy): {1e3 * (time.process_time() - t0):.0f} ms (setup, not toolpaths)")
    regions = LayerRegions(5, 6 * h, h, outline, faces)
    for pattern in ("concentric", "rectilinear"):
        settings = Settings(strategy=2, colors=48, fill_pattern=pattern)
        ms, lp = timed(lambda: strategy2.layer_paths(regions, settings), 3)
        print(
            f"strategy 2, 48 colors, {pattern:11s}: {ms:7.1f} ms/layer  paths {len(lp.paths):5d}  "
            f"volume ratio {volume_ratio(lp.paths, outline, h):.4f}  uncovered {lp.uncovered_mm2:.1f} mm2"
        )
    field, palette = SinCosField(), Palette(2, 16)
    bare = LayerRegions(5, 6 * h, h, outline, ())
    near = [outline] * 3
    cases = [
        ("vase: 10 walls, no infill", dict(walls=10, infill_density=0)),
        ("vase: 10 walls, zipper 10%", dict(walls=10, infill_density=0, zipper=10)),
        ("palette object: 3 walls, 100%", dict(walls=3, infill_density=100)),
    ]
    for name, extra in cases:
        settings = Settings(strategy=1, colors=16, min_segment_mm=0, **extra)
        ms, (lp, _) = timed(lambda: strategy1.layer_paths(bare, near, near, field, palette, settings))
        print(
            f"strategy 1, 16 colors, {name:30s}: {ms:7.1f} ms/layer  pieces {len(lp.paths):5d}  "
            f"volume ratio {volume_ratio(lp.paths, outline, h):.4f}"
        )

    examples()


def examples(root: Path = Path(__file__).resolve().parents[1] / "examples") -> None:
    """The vase and palette examples, one layer each, as ``pipeline._layer_task`` runs them."""
    settings = Settings(strategy=1, colors=16, walls=10, infill_density=0, top_layers=0, bottom_layers=0)
    design = load_design(root / "vase.vcad")
    placement = place_design(design, settings)
    index, z_top, height = layer_heights(design, settings)[250]
    ox, oy, oz = placement.offset
    section = design.section(z_top - height / 2 - oz)
    outline = polygonal(shapely.transform(section, lambda c: c + np.array([ox, oy])))
    regions = LayerRegions(index=index, z=z_top, height=height, outline=outline, faces=())
    field, palette = BedField(design, placement), Palette(2, 16)
    ms, (lp, _) = timed(lambda: strategy1.layer_paths(regions, [], [], field, palette, settings), 15)
    print(f"vase.vcad layer {index}, strategy 1, 10 walls, 16 colors: {ms:7.1f} ms/layer  pieces {len(lp.paths):5d}")
    design = load_design(root / "palette.vcad")
    for colors in (12, 48):
        for pattern in ("concentric", "rectilinear"):
            settings = Settings(strategy=2, colors=colors, fill_pattern=pattern)
            placement = place_design(design, settings)
            index, z_top, height = layer_heights(design, settings)[5]
            regions = slice_layer(design, placement, Palette(2, colors), index, z_top, height, settings)
            ms, lp = timed(lambda: strategy2.layer_paths(regions, settings), 5)
            print(
                f"palette.vcad layer {index}, strategy 2, {colors} colors, {pattern:11s}: {ms:7.1f} ms/layer  "
                f"paths {len(lp.paths):5d}  volume ratio {volume_ratio(lp.paths, regions.outline, height):.4f}"
            )


if __name__ == "__main__":
    main()
