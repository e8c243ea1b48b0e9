"""Regenerate the preview pictures of the README and docs/preview.md.

Run from the repository root: ``.venv/bin/python docs/images/make_images.py``. It slices
three examples into a temporary folder and renders:

* ``vase_layer.png``: a layer of the vase (walls only, strategy 1, 16 colors) with the
  design's field beside it;
* ``palette_s2_24.png``: the palette object, strategy 2, 24 colors;
* ``dogbone_s1_3.png``: the dogbone, strategy 1, 3 colors, travels shown;
* ``palette_sheet.png``: a contact sheet of the palette object.

Prints the render time and file size of each image.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from PIL import Image

from fgslice.design import load_design
from fgslice.pipeline import slice_to_gcode
from fgslice.preview.colors import load_printout
from fgslice.preview.layers import nearest_layer, render_layer, render_sheet
from fgslice.settings import load_settings

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "docs" / "images"


def _slice(name: str, folder: Path, **overrides: str):
    design = load_design(ROOT / "examples" / f"{name}.vcad")
    out = folder / f"{name}.gcode"
    started = time.perf_counter()
    slice_to_gcode(design, load_settings(None, overrides), out)
    print(f"sliced {name} in {time.perf_counter() - started:.1f} s")
    return design, load_printout(out)


def _report(path: Path, started: float) -> None:
    """Shrink ``path`` to a 64-color PNG (pictures for the docs must stay small) and print figures."""
    elapsed = time.perf_counter() - started
    Image.open(path).convert("RGB").quantize(64, method=Image.Quantize.MEDIANCUT).save(path, optimize=True)
    print(f"{path.name}: {elapsed:.2f} s to render, {path.stat().st_size / 1024:.0f} KB")


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        design, printout = _slice("vase", folder, strategy="1", colors="16", infill_density="0", layer_height="0.4",
                                  bead_width="0.6", top_layers="0")
        started = time.perf_counter()
        render_layer(printout, nearest_layer(printout, 60.0), OUT / "vase_layer.png", design=design, size=(1000, 540))
        _report(OUT / "vase_layer.png", started)

        _, printout = _slice("palette", folder, strategy="2", colors="24")
        started = time.perf_counter()
        render_layer(printout, 5, OUT / "palette_s2_24.png", size=(820, 700))
        _report(OUT / "palette_s2_24.png", started)
        started = time.perf_counter()
        render_sheet(printout, OUT / "palette_sheet.png", count=4, size=(720, 720))
        _report(OUT / "palette_sheet.png", started)

        _, printout = _slice("dogbone", folder, strategy="1", colors="3")
        started = time.perf_counter()
        render_layer(printout, 3, OUT / "dogbone_s1_3.png", show_travel=True, size=(1000, 330))
        _report(OUT / "dogbone_s1_3.png", started)


if __name__ == "__main__":
    main()
