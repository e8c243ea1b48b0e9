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
- ``FGSLICE_KLIPPER_DICT``: the data dictionary of a Linux-process MCU build (default
  ``$FGSLICE_KLIPPER/out/klipper.dict``), whose pin names (``gpioN``, ``analogN``) the
  printer configs use.

Each case's ``printer.cfg`` is a cartesian printer written from the fgslice profile: axes
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

Klipper's batch mode plans about 10,000 lines a second, so the larger examples are sliced
with settings that keep their files under 100,000 lines (palette.vcad's strategy 2 with
rectilinear fill, cylinder_z_gradient.vcad with strategy 1 at 0.3 mm layers). Checked with
Klipper v0.13.0; its development versions since September 2025 abort in batch mode on long
files (docs/gcode.md, "Checked against Klipper").
"""

from __future__ import annotations

import fcntl
import itertools
import os
import re
import subprocess
from dataclasses import dataclass
from pathlib import Path

import pytest

from fgslice.design.language import load_design
from fgslice.pipeline import slice_to_gcode
from fgslice.settings import Settings, load_settings

ROOT = Path(__file__).resolve().parents[1]
KLIPPER = os.environ.get("FGSLICE_KLIPPER", "")

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(not KLIPPER, reason="Klipper not available: set FGSLICE_KLIPPER (and FGSLICE_KLIPPER_PYTHON)"),
]

TIMEOUT_S = 300
CONFIG_END = "======================="
PROBLEMS = re.compile(
    r"Unknown command|Move out of range|Extrude below minimum temp|Extrude only move too long"
    r"|Move exceeds maximum extrusion|error|shutdown|!!", re.IGNORECASE)
MIX_CHANNELS = "ABCDHI"


@dataclass(frozen=True)
class Klipper:
    python: Path
    klippy: Path
    dictionary: Path


@dataclass(frozen=True)
class Run:
    returncode: int
    problems: list[str]
    log: str
    serial_bytes: int


@pytest.fixture(scope="session")
def klipper(tmp_path_factory) -> Klipper:
    """Klipper from the environment, its C helper built once for all test processes."""
    root = Path(KLIPPER)
    found = Klipper(Path(os.environ.get("FGSLICE_KLIPPER_PYTHON", "")), root / "klippy" / "klippy.py",
                    Path(os.environ.get("FGSLICE_KLIPPER_DICT", root / "out" / "klipper.dict")))
    missing = [f"{name} '{path}'" for name, path in vars(found).items() if not path.is_file()]
    if missing:
        pytest.fail(f"FGSLICE_KLIPPER={KLIPPER}: no {', no '.join(missing)} (see docs/gcode.md)")
    with open(tmp_path_factory.getbasetemp().parent / "klipper-chelper.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        built = subprocess.run([str(found.python), "-c", "import chelper; chelper.get_ffi()"],
                               cwd=found.klippy.parent, capture_output=True, text=True, timeout=TIMEOUT_S)
    if built.returncode:
        pytest.fail(f"Klipper's C helper does not build or load:\n{built.stderr}")
    return found


def _mixing_macros(settings: Settings) -> str:
    channels = list(MIX_CHANNELS[:settings.channels])
    zeros = [0.0] * settings.channels
    return f"""
[gcode_macro M165]
gcode:
  {{% set mix = namespace(sum=0) %}}
  {{% for key, value in params.items() if key != "M" %}}
    {{% if key not in {channels} or value|float < 0 or value|float > 1 %}}
      {{action_raise_error("M165 %s%s: no such channel or factor" % (key, value))}}
    {{% endif %}}
    {{% set mix.sum = mix.sum + value|float %}}
  {{% endfor %}}
  {{% if (mix.sum - 1)|abs > 0.002 %}}
    {{action_raise_error("M165 %s: factors do not sum to 1" % rawparams)}}
  {{% endif %}}

[gcode_macro M163]
variable_mix: {zeros}
gcode:
  {{% set i = params.S|int %}}
  {{% set p = params.P|float %}}
  {{% if i < 0 or i >= mix|length or p < 0 or p > 1 %}}
    {{action_raise_error("M163 %s: no such channel or factor" % rawparams)}}
  {{% endif %}}
  SET_GCODE_VARIABLE MACRO=M163 VARIABLE=mix VALUE=[{{(mix[:i] + [p] + mix[i + 1:])|join(',')}}]

[gcode_macro M164]
gcode:
  {{% set mix = printer["gcode_macro M163"].mix %}}
  {{% if params.S|int != 0 or (mix|sum - 1)|abs > 0.002 %}}
    {{action_raise_error("M164 %s: mix %s" % (rawparams, mix))}}
  {{% endif %}}
"""


def printer_cfg(settings: Settings) -> str:
    """A Klipper config for the machine of ``settings`` on the Linux-process MCU's pins."""
    gpio = (f"gpio{n}" for n in itertools.count())
    pin = gpio.__next__
    sections = [
        "[mcu]\nserial: /tmp/klipper_host_mcu\n",
        f"[printer]\nkinematics: cartesian\nmax_velocity: {settings.travel_speed}\nmax_accel: 3000\n"
        f"max_z_velocity: {settings.z_speed}\nmax_z_accel: 100\n",
    ]
    for axis, length, rotation in (("x", settings.bed_x, 40), ("y", settings.bed_y, 40), ("z", settings.max_z, 8)):
        sections.append(
            f"[stepper_{axis}]\nstep_pin: {pin()}\ndir_pin: {pin()}\nenable_pin: !{pin()}\nmicrosteps: 16\n"
            f"rotation_distance: {rotation}\nendstop_pin: ^{pin()}\nposition_endstop: 0\nposition_max: {length}\n"
            "homing_speed: 50\n")
    tools = settings.tool_count if settings.dialect == "toolchanger" else 1
    for tool in range(tools):
        sections.append(
            f"[extruder{tool or ''}]\nstep_pin: {pin()}\ndir_pin: {pin()}\nenable_pin: !{pin()}\nmicrosteps: 16\n"
            f"rotation_distance: 33.5\nnozzle_diameter: {settings.nozzle_diameter}\n"
            f"filament_diameter: {settings.filament_diameter}\nheater_pin: {pin()}\n"
            f"sensor_type: EPCOS 100K B57560G104F\nsensor_pin: analog{tool + 1}\ncontrol: pid\npid_Kp: 22.2\n"
            f"pid_Ki: 1.08\npid_Kd: 114\nmin_temp: 0\nmax_temp: {settings.max_nozzle_temperature}\n"
            f"min_extrude_temp: {settings.min_extrude_temperature}\n")
    if settings.dialect == "toolchanger":
        sections += [f"[gcode_macro T{tool}]\ngcode: ACTIVATE_EXTRUDER EXTRUDER=extruder{tool or ''}\n"
                     for tool in range(tools)]
    sections += [
        f"[heater_bed]\nheater_pin: {pin()}\nsensor_type: EPCOS 100K B57560G104F\nsensor_pin: analog0\n"
        f"control: watermark\nmin_temp: 0\nmax_temp: {settings.max_bed_temperature}\n",
        f"[fan]\npin: {pin()}\n",
    ]
    if settings.dialect in ("marlin-mixing", "marlin-mixing-m163"):
        sections.append(_mixing_macros(settings))
    outputs = sorted(set(re.findall(r"M42 P(\d+)", "\n".join((settings.state_template, settings.start_gcode,
                                                               settings.end_gcode)))), key=int)
    sections += [f"[output_pin p{n}]\npin: {pin()}\npwm: True\n" for n in outputs]
    if outputs:
        sections.append("[gcode_macro M42]\ngcode: SET_PIN PIN=p{params.P|int} VALUE={params.S|float / 255}\n")
    return "\n".join(sections)


def run_klippy(klipper: Klipper, settings: Settings, gcode: Path, folder: Path) -> Run:
    """Run ``gcode`` through Klipper's batch mode on the printer of ``settings``."""
    config, log, serial = folder / "printer.cfg", folder / "klippy.log", folder / "out.serial"
    config.write_text(printer_cfg(settings), encoding="utf-8")
    try:
        done = subprocess.run(
            [str(klipper.python), str(klipper.klippy), str(config), "-i", str(gcode), "-o", str(serial),
             "-d", str(klipper.dictionary), "-l", str(log)],
            capture_output=True, text=True, timeout=TIMEOUT_S)
    except subprocess.TimeoutExpired:
        text = log.read_text(errors="replace") if log.exists() else ""
        pytest.fail(f"klippy did not finish in {TIMEOUT_S} s (a config error keeps it waiting); log:\n{text[-4000:]}")
    after_config = log.read_text(errors="replace").rpartition(CONFIG_END)[2] + done.stdout + done.stderr
    problems = [line for line in after_config.splitlines() if PROBLEMS.search(line)]
    return Run(done.returncode, problems, after_config, serial.stat().st_size if serial.exists() else 0)


CASES = [
    ("palette.vcad", "marlin-mixing", {"strategy": "1"}),
    ("palette.vcad", "marlin-mixing", {"strategy": "2", "fill_pattern": "rectilinear"}),
    ("fan_gradient.vcad", "marlin-mixing", {}),
    ("temperature_gradient.vcad", "marlin-mixing", {}),
    ("temperature_gradient.vcad", "marlin-mixing-m163", {}),
    ("temperature_gradient.vcad", "toolchanger", {"colors": "4"}),
    ("cylinder_z_gradient.vcad", "foam-tpu", {"strategy": "1", "layer_height": "0.3"}),
    ("dogbone.vcad", "template-diw", {}),
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
