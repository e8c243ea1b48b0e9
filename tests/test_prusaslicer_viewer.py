"""PrusaSlicer's G-code viewer opens a toolchanger file with every tool in its color.

Needs ``prusa-gcodeviewer`` (Debian's prusa-slicer), ``Xvfb``, ImageMagick's ``import``
and glibc's ``localedef`` with the en_US locale source (the viewer refuses to start
without a locale of its language); skips otherwise. The viewer runs with a private home
folder and locale folder; the screenshot is kept in ``build/`` at the repository root.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest

from fgslice.design import api
from fgslice.pipeline import slice_to_gcode
from fgslice.settings import load_settings

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]
LOCALE_SOURCE = Path("/usr/share/i18n/locales/en_US")
WINDOW = (1024, 640)
TIMEOUT_S = 150


def _tools_missing() -> list[str]:
    missing = [tool for tool in ("prusa-gcodeviewer", "Xvfb", "import", "localedef") if shutil.which(tool) is None]
    return missing + ([] if LOCALE_SOURCE.exists() else [str(LOCALE_SOURCE)])


def _tool_colours(path: Path) -> list[tuple[int, int, int]]:
    line = next(line for line in path.read_text().splitlines() if line.startswith("; extruder_colour = "))
    return [tuple(int(c[i:i + 2], 16) for i in (1, 3, 5)) for c in line.split(" = ")[1].split(";")]


def _stop(process: subprocess.Popen) -> None:
    process.terminate()
    try:
        process.wait(timeout=10)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait()


def test_viewer_draws_each_tool_in_its_colour(tmp_path):
    missing = _tools_missing()
    if missing:
        pytest.skip(f"not available: {', '.join(missing)}")
    from PIL import Image

    design = api.design(api.fgrade(["z/4", "1-z/4"], ["blue", "yellow"], api.translate((0, 0, 2), api.cylinder(6, 4))))
    gcode = tmp_path / "cylinder.gcode"
    slice_to_gcode(design, load_settings("toolchanger", {"colors": "4", "thumbnails": ""}), gcode, jobs=1)
    colours = _tool_colours(gcode)
    assert len(colours) == 4

    locales = tmp_path / "locale"
    locales.mkdir()
    subprocess.run(["localedef", "-i", "en_US", "-f", "UTF-8", str(locales / "en_US.UTF-8")], check=True,
                   capture_output=True, timeout=120)
    config = tmp_path / "home" / ".config" / "PrusaSlicer"
    config.mkdir(parents=True)
    (config / "PrusaSlicerGcodeViewer.ini").write_text(
        f"show_splash_screen = 0\nshow_hints = 0\nrestore_win_position = 1\n"
        f"window_mainframe = 0; 0; {WINDOW[0]}; {WINDOW[1]}; 0\n"
    )
    read, write = os.pipe()
    xvfb = subprocess.Popen(["Xvfb", "-displayfd", str(write), "-screen", "0", f"{WINDOW[0]}x{WINDOW[1]}x24", "-nolisten", "tcp"],
                            pass_fds=(write,), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    os.close(write)
    with os.fdopen(read) as handle:
        display = ":" + handle.readline().strip()
    env = {**os.environ, "DISPLAY": display, "HOME": str(tmp_path / "home"), "LOCPATH": str(locales),
           "LANG": "en_US.UTF-8", "LC_ALL": "en_US.UTF-8", "XDG_CONFIG_HOME": str(tmp_path / "home" / ".config")}
    viewer = subprocess.Popen(["prusa-gcodeviewer", str(gcode)], env=env, stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL)
    shot = tmp_path / "viewer.png"
    found: dict[tuple[int, int, int], int] = {}
    try:
        deadline = time.monotonic() + TIMEOUT_S
        while time.monotonic() < deadline:
            time.sleep(3)
            assert viewer.poll() is None, "prusa-gcodeviewer exited"
            subprocess.run(["import", "-window", "root", str(shot)], env=env, check=True, capture_output=True, timeout=60)
            rgb = np.asarray(Image.open(shot).convert("RGB")).astype(int)
            found = {c: int((np.abs(rgb - c).max(axis=2) == 0).sum()) for c in colours}
            if min(found.values()) >= 100:  # the legend's swatch of each tool, 14 x 14 pixels
                break
    finally:
        _stop(viewer)
        _stop(xvfb)
    (ROOT / "build").mkdir(exist_ok=True)
    shutil.copy(shot, ROOT / "build" / "prusa-gcodeviewer.png")
    assert min(found.values()) >= 100, f"pixels of each tool's colour: {found}"
