"""The viewer page in a real headless Chromium: layers, slider, colors, pixels.

Needs the playwright package and a system Chromium at /usr/bin/chromium (nothing is
downloaded). Without them the test skips, except when ``CI=true``, where it fails: CI
installs Chromium (``.ci/run``). The screenshot is kept in ``build/`` at the repository root.
"""

from __future__ import annotations

import io
import os
from pathlib import Path

import numpy as np
import pytest

from fgslice.design import api
from fgslice.machine.gcode_reader import read_gcode
from fgslice.pipeline import slice_to_gcode
from fgslice.preview.viewer import ViewerServer
from fgslice.settings import load_settings

pytestmark = [pytest.mark.browser, pytest.mark.slow]

ROOT = Path(__file__).resolve().parents[1]
CHROMIUM = Path("/usr/bin/chromium")
CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync",
                 "--use-gl=angle", "--use-angle=swiftshader", "--enable-unsafe-swiftshader"]


def _require(available: bool, reason: str) -> None:
    """Skip when something is missing, but fail in CI, which provides everything."""
    if not available:
        if os.environ.get("CI", "").lower() == "true":
            pytest.fail(f"{reason} (CI=true: .ci/run must provide it)")
        pytest.skip(reason)


def _colored_pixels(png: bytes) -> int:
    """Pixels with chroma (max - min channel) over 40: toolpaths, not the gray background or bed."""
    from PIL import Image

    rgb = np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).astype(int)
    return int(((rgb.max(axis=2) - rgb.min(axis=2)) > 40).sum())


@pytest.fixture(scope="module")
def sliced(tmp_path_factory):
    """A 12 mm cylinder, 4 mm tall, graded blue to yellow along z, in 4 colors."""
    design = api.design(api.fgrade(["z/4", "1-z/4"], ["blue", "yellow"], api.translate((0, 0, 2), api.cylinder(6, 4))))
    out = tmp_path_factory.mktemp("viewer") / "cylinder.gcode"
    slice_to_gcode(design, load_settings(None, {"colors": "4", "skirt_loops": "0"}), out, jobs=1)
    return out


def test_page_draws_the_layers_and_follows_the_slider(sliced):
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        sync_playwright = None
    _require(sync_playwright is not None, "the playwright package is not installed (pip install -e '.[test]')")
    _require(CHROMIUM.exists(), f"no Chromium at {CHROMIUM} (apt-get install chromium)")

    program = read_gcode(sliced)
    n_layers = len(program.layer_z)
    printing = np.any(program.end != program.start, axis=1) & (program.e > 0)
    layer = np.maximum(program.layer, 0)
    roles_used = {program.roles[r] for r in np.unique(program.role[printing]) if r >= 0}
    assert n_layers == 20

    build = ROOT / "build"
    build.mkdir(exist_ok=True)
    errors: list[str] = []
    with ViewerServer(sliced) as server, sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
        try:
            page = browser.new_page(viewport={"width": 1100, "height": 700})
            page.on("pageerror", lambda error: errors.append(str(error)))
            page.goto(server.url)
            page.wait_for_selector("#layer-info[data-ready='1'], #layer-info[data-error]", timeout=60_000)
            info = page.locator("#layer-info")
            assert info.get_attribute("data-error") is None, info.inner_text()
            assert info.get_attribute("data-layer-count") == str(n_layers)
            assert info.get_attribute("data-layer-max") == str(n_layers - 1)
            assert info.inner_text().startswith(f"layers 0-{n_layers - 1} of {n_layers}")
            assert info.get_attribute("data-segments-drawn") == str(int(printing.sum()))
            canvas = page.locator("#view canvas")
            full = _colored_pixels(canvas.screenshot())
            box = canvas.bounding_box()
            assert full > 0.005 * box["width"] * box["height"], "the canvas shows no toolpaths"
            page.screenshot(path=str(build / "viewer_browser.png"))

            top = 4
            page.fill("#layer-max", str(top))
            assert info.get_attribute("data-layer-max") == str(top)
            assert info.inner_text().startswith(f"layers 0-{top} of {n_layers}")
            assert info.get_attribute("data-segments-drawn") == str(int((printing & (layer <= top)).sum()))
            assert 0 < _colored_pixels(canvas.screenshot()) < full

            page.fill("#layer-min", str(n_layers - 1))
            assert info.get_attribute("data-layer-min") == str(n_layers - 1)
            assert info.get_attribute("data-layer-max") == str(n_layers - 1)

            page.select_option("#color-mode", "role")
            legend = set(page.locator("#legend li").all_inner_texts())
            assert legend == roles_used
            stats = dict(zip(*[iter(page.locator("#stats td").all_inner_texts())] * 2))
            assert stats["layers"] == str(n_layers) and stats["materials"] == "blue,yellow"
        finally:
            browser.close()
    assert not errors, errors
