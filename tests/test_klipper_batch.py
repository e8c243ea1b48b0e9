"""Klipper's batch mode runs fgslice's G-code for every built-in dialect.

Klipper's host (``klippy/klippy.py printer.cfg -i FILE.gcode -o OUT -d DICT``) reads the
file as a printer would, plans every move and writes the MCU commands to ``OUT``; it
rejects what its firmware would (moves outside the axes' limits, extrusion beyond
``max_extrude_cross_section`` or ``max_extrude_only_distance``, temperatures above
``max_temp``, tools and pins it does not have) and logs ``Unknown command`` for G-code it
does not implement. Needs, from the environment:

- ``FGSLICE_KLIPPER``: a Klipper source tree (``klippy/klippy.py``); the module is skipped
  when it is unset;
- ``FGSLICE_KLIPPER_PYTHON``: a Python with Klipper's ``scripts/klippy-requirements.txt``;
- ``FGSLICE_KLIPPER_DICT``: the data dictionary of a micro-controller build (default
  ``$FGSLICE_KLIPPER/out/klipper.dict``; an atmega2560 or a Linux-process build), whose
  pin names the printer configs use.

Each case's ``printer.cfg`` (:func:`fgslice.machine.klipper.printer_cfg`) is a cartesian
printer written from the fgslice profile, its motion limits included: axes
of ``bed_x`` x ``bed_y`` x ``max_z`` homed at 0, ``travel_speed`` and ``z_speed`` as the
velocity limits, the profile's nozzle and filament diameters (so Klipper's own defaults of
``max_extrude_cross_section`` = 4 d^2 and ``max_extrude_only_distance`` = 50 mm apply),
``max_nozzle_temperature`` and ``max_bed_temperature`` as the heaters' ``max_temp``, a
part-cooling ``[fan]``. A toolchanger gets one ``[extruder]``/``[extruderN]`` per tool and
``T0``..``Tn`` macros that ``ACTIVATE_EXTRUDER``. Klipper has no mixing extruder, so
``M165``, ``M163`` and ``M164`` are macros that check the mix as ``verify_gcode`` does
(each factor in 0..1 on a channel the profile has, the factors summing to 1 within 0.002)
and raise an error otherwise; Klipper has no ``M42`` either, so the template dialect's
``M42 P<n> S<v>`` is a macro setting a PWM ``[output_pin pN]``. In batch mode Klipper
reads no temperatures: it never refuses an extrusion as too cold and ``M109``/``M190``
return at once (``verify_gcode`` checks the heating order).

The print time Klipper plans for a file matches fgslice's estimate (the time model of
:mod:`fgslice.machine.timing`) within 3 %, with the profile's Marlin planner and with
Klipper's own.

Klipper's batch mode plans about 10,000 lines a second, so the larger examples are sliced
with settings that keep their files under 100,000 lines (palette.vcad's strategy 2 with
rectilinear fill, cylinder_z_gradient.vcad with strategy 1 at 0.3 mm layers). Checked with
Klipper v0.13.0; its development versions since September 2025 abort in batch mode on long
files (docs/gcode.md, "Checked against Klipper").
"""

from __future__ import annotations

import fcntl
import os
import re
import subprocess
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from fgslice.design import api
from fgslice.design.language import load_design
from fgslice.errors import FgsliceError
from fgslice.machine.gcode_reader import read_gcode
from fgslice.machine.klipper import MIX_LETTERS, KlipperBatch, mcu_pins, printer_cfg
from fgslice.pipeline import slice_to_gcode
from fgslice.settings import Settings, load_settings
from fgslice.slicing.palette import Palette

ROOT = Path(__file__).resolve().parents[1]
KLIPPER = os.environ.get("FGSLICE_KLIPPER", "")

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(not KLIPPER, reason="Klipper not available: set FGSLICE_KLIPPER (and FGSLICE_KLIPPER_PYTHON)"),
]

TIMEOUT_S = 300


@dataclass(frozen=True)
class Run:
    returncode: int
    problems: list[str]
    log: str
    serial_bytes: int


@pytest.fixture(scope="session")
def klipper(tmp_path_factory) -> KlipperBatch:
    """Klipper from the environment, its C helper built once for all test processes."""
    try:
        found = KlipperBatch.from_environment()
    except FgsliceError as exc:
        pytest.fail(str(exc))
    with open(tmp_path_factory.getbasetemp().parent / "klipper-chelper.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        built = subprocess.run([str(found.python), "-c", "import chelper; chelper.get_ffi()"],
                               cwd=found.klippy.parent, capture_output=True, text=True, timeout=TIMEOUT_S)
    if built.returncode:
        pytest.fail(f"Klipper's C helper does not build or load:\n{built.stderr}")
    return found


def run_klippy(klipper: KlipperBatch, settings: Settings, gcode: Path, folder: Path) -> Run:
    """Run ``gcode`` through Klipper's batch mode on the printer of ``settings``."""
    try:
        run = klipper.run(klipper.config(settings), gcode, folder)
    except subprocess.TimeoutExpired:
        log = folder / "klippy.log"
        text = log.read_text(errors="replace") if log.exists() else ""
        pytest.fail(f"klippy did not finish (a config error keeps it waiting); log:\n{text[-4000:]}")
    return Run(run.returncode, run.problems, run.log, run.serial.stat().st_size if run.serial.exists() else 0)


CASES = [
    ("palette.vcad", "marlin-mixing", {"strategy": "1"}),
    ("palette.vcad", "marlin-mixing", {"strategy": "2", "fill_pattern": "rectilinear"}),
    ("fan_gradient.vcad", "marlin-mixing", {}),
    ("temperature_gradient.vcad", "marlin-mixing", {}),
    ("temperature_gradient.vcad", "marlin-mixing-m163", {}),
    ("temperature_gradient.vcad", "toolchanger", {"colors": "4"}),
    ("cylinder_z_gradient.vcad", "foam-tpu", {"strategy": "1", "layer_height": "0.3"}),
    ("dogbone.vcad", "template-diw", {}),
    ("dogbone.vcad", "klipper-diw", {}),
    ("temperature_gradient.vcad", "klipper-mixing", {}),
    ("palette.vcad", "klipper-mixing", {"strategy": "2", "fill_pattern": "rectilinear", "channels": "3"}),
]


@pytest.mark.parametrize("example, profile, overrides", CASES,
                         ids=["-".join([e.removesuffix(".vcad"), p, *(f"{k}={v}" for k, v in o.items())])
                              for e, p, o in CASES])
def test_klipper_runs_the_sliced_example(klipper, tmp_path, example, profile, overrides):
    settings = load_settings(profile, overrides)
    gcode = tmp_path / "part.gcode"
    slice_to_gcode(load_design(ROOT / "examples" / example), settings, gcode, jobs=1)
    run = run_klippy(klipper, settings, gcode, tmp_path)
    assert run.returncode == 0 and not run.problems, f"klippy exit {run.returncode}:\n{run.log}"
    assert run.serial_bytes > 0


@pytest.mark.parametrize("lines, message", [
    ("G1 X{x} Y10 F3000", "Move out of range"),
    ("M999", 'Unknown command:"M999"'),
    ("M165 A0.5 B0.6", "factors do not sum to 1"),
    ("M165 A0.5 C0.5", "no such channel or factor"),
    ("M163 S0 P0.4\nM163 S1 P0.4\nM164 S0", "M164 S0: mix"),
    ("G1 E60 F600", "Extrude only move too long"),
    ("G1 X20 Y20 E60 F600", "Move exceeds maximum extrusion"),
])
def test_klipper_reports_what_it_rejects(klipper, tmp_path, lines, message):
    settings = load_settings("marlin-mixing")
    gcode = tmp_path / "bad.gcode"
    gcode.write_text(f"G28\nG90\nM83\nG1 Z1 F600\n{lines.format(x=settings.bed_x + 1)}\n", encoding="utf-8")
    run = run_klippy(klipper, settings, gcode, tmp_path)
    assert any(message in line for line in run.problems), run.log


@pytest.mark.parametrize("planner", ["marlin", "klipper"])
def test_klipper_plans_the_estimated_time(klipper, tmp_path, planner):
    settings = load_settings("marlin-mixing", {"motion_planner": planner})
    gcode = tmp_path / "part.gcode"
    stats = slice_to_gcode(load_design(ROOT / "examples" / "fan_gradient.vcad"), settings, gcode, jobs=1).stats
    planned = klipper.print_time(klipper.config(settings), gcode, tmp_path)
    assert abs(stats["estimated_time_s"] / planned - 1) < 0.03, (stats["estimated_time_s"], planned)


def test_klipper_mixing_feeds_every_channel_its_share(klipper, tmp_path):
    """Each channel's steps in Klipper's output, times its rotation distance, are the
    filament the mixture asks of it: the sum over moves of E times the channel's fraction
    in the move's state (a third channel the design leaves empty, and the pure colors of
    an 'ends' palette, unsync channels). The design: a cylinder graded blue to yellow
    along z."""
    settings = load_settings("klipper-mixing", {"channels": "3", "palette": "ends", "colors": "5"})
    gcode = tmp_path / "part.gcode"
    design = api.design(api.fgrade(["z/6", "1-z/6"], ["blue", "yellow"], api.translate((0, 0, 3), api.cylinder(10, 6))))
    slice_to_gcode(design, settings, gcode, jobs=1)
    assert "MOTION_QUEUE=\n" in gcode.read_text(encoding="utf-8")
    digital, analog = mcu_pins(klipper.dictionary)
    config = printer_cfg(settings, digital, analog)
    run = klipper.run(config, gcode, tmp_path)
    assert run.returncode == 0 and not run.problems, run.log
    steps = klipper.step_counts(run.serial)
    program = read_gcode(gcode)
    palette = Palette(2, settings.colors, settings.palette)
    colors = program.color_of_moves()
    share = np.ones((len(colors), settings.channels))  # before any state: every channel as configured
    known = colors >= 0
    share[known] = 0.0
    share[known, :2] = palette.centers[colors[known]].round(4)
    expected = share.T @ program.e
    per_step = settings.mixing_rotation_distance / 3200  # 200 full steps x 16 microsteps
    for i, want in enumerate(expected.tolist()):
        pin = re.search(rf"\[extruder_stepper mix_{MIX_LETTERS[i].lower()}\]\nextruder: extruder\nstep_pin: (\w+)",
                        config).group(1)
        got = abs(steps.get(pin, 0)) * per_step
        assert got == pytest.approx(want, rel=0.01, abs=0.05), (MIX_LETTERS[i], got, want)
    # the empty channel moved only before the first state (as configured), both others much more
    assert expected[2] == pytest.approx(program.e[~known].sum()) and min(expected[:2]) > 10 * abs(expected[2])
