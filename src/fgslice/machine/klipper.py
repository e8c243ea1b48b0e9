"""Klipper's side of a profile: the printer.cfg of its machine, and Klipper's batch mode.

:func:`printer_cfg` writes a Klipper config for the machine of a profile: a cartesian
printer with the bed, speeds and motion limits of the settings (``max_accel`` =
``acceleration``, ``max_z_accel`` = ``z_acceleration``, the square corner velocity and
minimum cruise ratio, or for a Marlin profile their equivalents: the square corner
velocity of its junction deviation, ``sqrt(junction_deviation x acceleration / (sqrt 2 -
1))``, no cruise ratio and ``max_extrude_only_accel`` = ``acceleration``), an
``[extruder]`` per tool, the channels of a ``klipper-mixing`` hotend
(:func:`mixing_sections`), ``[output_pin]`` sections for the pins the G-code sets, and
macros for what Klipper lacks (Marlin's mixing commands, which are checked as
``verify_gcode`` does; ``M42``; tool changes, which dwell the dialect's change time). Pins are taken from the micro-controller's data dictionary, so any build
serves (Klipper's Linux process, an atmega2560...).

:class:`KlipperBatch` runs ``klippy.py printer.cfg -i FILE -o OUT -d DICT`` (Klipper's
``docs/Debugging.md``): Klipper reads the file as a printer would and writes the commands
it would send to the micro-controller. The print time is the one Klipper logs as it exits
(``Exiting (print time T s)``, the toolhead's time of the last move) less the time at which
the first layer starts, taken from a second run of the file's start alone.
"""

from __future__ import annotations

import json
import math
import os
import re
import subprocess
from dataclasses import dataclass
from pathlib import Path

from fgslice.errors import FgsliceError
from fgslice.machine.dialects import Toolchanger
from fgslice.settings import Settings

MIX_LETTERS = "ABCDHI"
#: Log lines after the config that mean Klipper refused or did not know something.
PROBLEMS = re.compile(
    r"Unknown command|Move out of range|Extrude below minimum temp|Extrude only move too long"
    r"|Move exceeds maximum extrusion|error|shutdown|!!", re.IGNORECASE)
CONFIG_END = "======================="
_PRINT_TIME = re.compile(r"Exiting \(print time ([0-9.]+)s\)")


def mcu_pins(dictionary: Path) -> tuple[list[str], list[str]]:
    """The digital and the analog pin names of the micro-controller whose data dictionary
    (``out/klipper.dict`` of a build) is ``dictionary``, without the pins its serial port
    and buses reserve: a Linux process has ``gpioN`` and ``analogN``; an AVR ports
    ``PA0``..``PL7`` with the analog inputs on ports F and K."""
    data = json.loads(Path(dictionary).read_text(encoding="utf-8"))
    reserved = {pin for key, value in data.get("config", {}).items()
                if key.startswith(("RESERVE_PINS_", "BUS_PINS_")) for pin in str(value).split(",")}
    names = []
    for first, (number, count) in data["enumerations"]["pin"].items():
        base = first.rstrip("0123456789")
        start = int(first[len(base):])
        names += [f"{base}{start + k}" for k in range(count)]
    avr = str(data.get("config", {}).get("MCU", "")).startswith("atmega")
    analog = [n for n in names if n.startswith("analog") or (avr and n[:2] in ("PF", "PK"))]
    digital = [n for n in names if n not in reserved and n not in analog]
    return digital, analog


def junction_velocity(settings: Settings) -> float:
    """Klipper's square corner velocity for the machine of ``settings``, mm/s: its own on a
    Klipper profile; on a Marlin profile the one of the same junction deviation (the
    classic jerk when that is 0)."""
    if settings.motion_planner == "klipper":
        return settings.square_corner_velocity
    if settings.junction_deviation <= 0:
        return settings.jerk
    return math.sqrt(settings.junction_deviation * settings.acceleration / (math.sqrt(2) - 1))


def mixing_sections(settings: Settings, pins: list[tuple[str, str, str]] | None = None) -> str:
    """The printer.cfg sections of a ``klipper-mixing`` hotend's channels: an
    ``[extruder_stepper mix_a]``.. each, synced to ``[extruder]`` (which keeps the heater and
    has no stepper of its own) at ``mixing_rotation_distance``. ``pins``: each channel's
    (step, dir, enable) pins; named placeholders without."""
    out = []
    for i in range(settings.channels):
        name = MIX_LETTERS[i].lower()
        step, direction, enable = pins[i] if pins else (f"<step pin {name}>", f"<dir pin {name}>",
                                                        f"<enable pin {name}>")
        out.append(f"[extruder_stepper mix_{name}]\nextruder: extruder\nstep_pin: {step}\ndir_pin: {direction}\n"
                   f"enable_pin: !{enable}\nmicrosteps: 16\nrotation_distance: {settings.mixing_rotation_distance}\n")
    return "\n".join(out)


def _marlin_mixing_macros(settings: Settings) -> str:
    channels = list(MIX_LETTERS[:settings.channels])
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


def printer_cfg(settings: Settings, digital: list[str], analog: list[str]) -> str:
    """A Klipper config for the machine of ``settings`` on the given micro-controller pins
    (:func:`mcu_pins`)."""
    pins = iter(digital)
    pin = pins.__next__
    s = settings
    klipper = s.motion_planner == "klipper"
    sections = [
        "[mcu]\nserial: /tmp/klipper_host_mcu\n",
        f"[printer]\nkinematics: cartesian\nmax_velocity: {s.travel_speed}\nmax_accel: {s.acceleration}\n"
        f"max_z_velocity: {s.z_speed}\nmax_z_accel: {s.z_acceleration}\n"
        f"square_corner_velocity: {junction_velocity(s):.4f}\n"
        f"minimum_cruise_ratio: {s.minimum_cruise_ratio if klipper else 0}\n",
    ]
    for axis, length, rotation in (("x", s.bed_x, 40), ("y", s.bed_y, 40), ("z", s.max_z, 8)):
        sections.append(
            f"[stepper_{axis}]\nstep_pin: {pin()}\ndir_pin: {pin()}\nenable_pin: !{pin()}\nmicrosteps: 16\n"
            f"rotation_distance: {rotation}\nendstop_pin: ^{pin()}\nposition_endstop: 0\nposition_max: {length}\n"
            "homing_speed: 50\n")
    tools = s.tool_count if s.dialect == "toolchanger" else 1
    e_accel = s.retract_acceleration if s.retract_acceleration != "auto" else (None if klipper else s.acceleration)
    mixing = s.dialect == "klipper-mixing"
    for tool in range(tools):
        stepper = "" if mixing else (f"step_pin: {pin()}\ndir_pin: {pin()}\nenable_pin: !{pin()}\nmicrosteps: 16\n"
                                     "rotation_distance: 33.5\n")
        sections.append(
            f"[extruder{tool or ''}]\n{stepper}nozzle_diameter: {s.nozzle_diameter}\n"
            f"filament_diameter: {s.filament_diameter}\nheater_pin: {pin()}\n"
            f"sensor_type: EPCOS 100K B57560G104F\nsensor_pin: {analog[tool + 1]}\ncontrol: pid\npid_Kp: 22.2\n"
            f"pid_Ki: 1.08\npid_Kd: 114\nmin_temp: 0\nmax_temp: {s.max_nozzle_temperature}\n"
            f"min_extrude_temp: {s.min_extrude_temperature}\n"
            + (f"max_extrude_only_accel: {e_accel}\n" if e_accel else ""))
    if mixing:
        sections.append(mixing_sections(s, [(pin(), pin(), pin()) for _ in range(s.channels)]))
    if s.dialect == "toolchanger":
        dwell = f"\n  G4 P{Toolchanger.change_time_s * 1000:.0f}" if Toolchanger.change_time_s else ""
        sections += [f"[gcode_macro T{tool}]\ngcode:\n  ACTIVATE_EXTRUDER EXTRUDER=extruder{tool or ''}{dwell}\n"
                     for tool in range(tools)]
    sections += [
        f"[heater_bed]\nheater_pin: {pin()}\nsensor_type: EPCOS 100K B57560G104F\nsensor_pin: {analog[0]}\n"
        f"control: watermark\nmin_temp: 0\nmax_temp: {s.max_bed_temperature}\n",
        f"[fan]\npin: {pin()}\n",
    ]
    if s.dialect in ("marlin-mixing", "marlin-mixing-m163"):
        sections.append(_marlin_mixing_macros(s))
    texts = "\n".join((s.state_template, s.start_gcode, s.end_gcode))
    outputs = sorted(set(re.findall(r"M42 P(\d+)", texts)), key=int)
    sections += [f"[output_pin p{n}]\npin: {pin()}\npwm: True\n" for n in outputs]
    if outputs:
        sections.append("[gcode_macro M42]\ngcode: SET_PIN PIN=p{params.P|int} VALUE={params.S|float / 255}\n")
    sections += [f"[output_pin {name}]\npin: {pin()}\npwm: True\n"
                 for name in sorted(set(re.findall(r"SET_PIN PIN=(\w+)", texts)))]
    return "\n".join(sections)


@dataclass(frozen=True)
class BatchRun:
    """What a batch-mode run left: exit code, the log after the config, the lines of it
    that report a problem (:data:`PROBLEMS`), Klipper's print time at exit (s; None if it
    did not log one) and the micro-controller commands it wrote."""

    returncode: int
    log: str
    problems: list[str]
    print_time_s: float | None
    serial: Path


@dataclass(frozen=True)
class KlipperBatch:
    """A Klipper to run in batch mode: the Python with Klipper's requirements, its
    ``klippy/klippy.py`` and a micro-controller data dictionary.

    :meth:`from_environment` reads ``FGSLICE_KLIPPER`` (the source tree),
    ``FGSLICE_KLIPPER_PYTHON`` and ``FGSLICE_KLIPPER_DICT`` (default
    ``$FGSLICE_KLIPPER/out/klipper.dict``)."""

    python: Path
    klippy: Path
    dictionary: Path
    timeout_s: float = 600.0

    @classmethod
    def from_environment(cls) -> "KlipperBatch | None":
        """The Klipper the environment names; None when ``FGSLICE_KLIPPER`` is unset.

        Raises:
            FgsliceError: a named file is missing.
        """
        root = os.environ.get("FGSLICE_KLIPPER", "")
        if not root:
            return None
        found = cls(Path(os.environ.get("FGSLICE_KLIPPER_PYTHON", "")), Path(root) / "klippy" / "klippy.py",
                    Path(os.environ.get("FGSLICE_KLIPPER_DICT", Path(root) / "out" / "klipper.dict")))
        missing = [f"{name} '{path}'" for name, path in vars(found).items()
                   if isinstance(path, Path) and not path.is_file()]
        if missing:
            raise FgsliceError(f"FGSLICE_KLIPPER={root}: no {', no '.join(missing)}",
                               hint="see docs/gcode.md, 'Checked against Klipper'")
        return found

    def config(self, settings: Settings) -> str:
        """:func:`printer_cfg` on this Klipper's micro-controller pins."""
        return printer_cfg(settings, *mcu_pins(self.dictionary))

    def run(self, config: str, gcode: Path, folder: Path) -> BatchRun:
        """Run ``gcode`` through batch mode with the printer.cfg text ``config``; files go
        to ``folder``.

        Raises:
            subprocess.TimeoutExpired: Klipper did not finish within ``timeout_s``.
        """
        folder.mkdir(parents=True, exist_ok=True)
        cfg, log, serial = folder / "printer.cfg", folder / "klippy.log", folder / "out.serial"
        cfg.write_text(config, encoding="utf-8")
        log.unlink(missing_ok=True)
        done = subprocess.run(
            [str(self.python), str(self.klippy), str(cfg), "-i", str(gcode), "-o", str(serial),
             "-d", str(self.dictionary), "-l", str(log)],
            capture_output=True, text=True, timeout=self.timeout_s)
        text = log.read_text(errors="replace") if log.exists() else ""
        after = text.rpartition(CONFIG_END)[2] + done.stdout + done.stderr
        times = _PRINT_TIME.findall(text)
        return BatchRun(done.returncode, after, [line for line in after.splitlines() if PROBLEMS.search(line)],
                        float(times[-1]) if times else None, serial)

    def print_time(self, config: str, gcode: Path, folder: Path) -> float:
        """Seconds Klipper plans for the layers of the fgslice file ``gcode`` (from its first
        ``;LAYER_CHANGE`` to the end): the print time at exit of the whole file less that of
        the file's start alone.

        Raises:
            FgsliceError: Klipper reported a problem or no print time.
        """
        text = gcode.read_text(encoding="utf-8")
        start = folder / "start.gcode"
        start.write_text(text[: text.find(";LAYER_CHANGE")], encoding="utf-8")
        times = []
        for name, path in (("whole", gcode), ("start", start)):
            run = self.run(config, path, folder / name)
            if run.returncode or run.problems or run.print_time_s is None:
                raise FgsliceError(f"Klipper's batch mode failed on {path} (exit {run.returncode}): "
                                   + "; ".join(run.problems[:5] or [run.log[-2000:]]))
            times.append(run.print_time_s)
        return times[0] - times[1]

    def step_counts(self, serial: Path) -> dict[str, int]:
        """Net steps (forward minus backward) each stepper made in the micro-controller
        commands ``serial`` (read with Klipper's ``klippy/parsedump.py``), by step pin."""
        dump = subprocess.run([str(self.python), str(self.klippy.parent / "parsedump.py"), str(self.dictionary),
                               str(serial)], capture_output=True, text=True, timeout=self.timeout_s, check=True)
        pins: dict[int, str] = {}
        direction: dict[int, int] = {}
        counts: dict[str, int] = {}
        for line in dump.stdout.splitlines():
            name, _, rest = line.partition(" ")
            words = dict(w.split("=", 1) for w in rest.split() if "=" in w)
            if name == "config_stepper":
                pins[int(words["oid"])] = words["step_pin"]
            elif name == "set_next_step_dir":
                direction[int(words["oid"])] = 1 if int(words["dir"]) else -1
            elif name == "queue_step":
                oid = int(words["oid"])
                pin = pins.get(oid, str(oid))
                counts[pin] = counts.get(pin, 0) + direction.get(oid, 1) * int(words["count"])
        return counts
