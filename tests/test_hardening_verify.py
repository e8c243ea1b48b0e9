"""``fgslice verify`` passes every example's output and flags deliberately broken files.

The examples are cut to their bottom millimetre (a few layers) to keep this fast. Each
fault kind of the verifier has its own unit test in ``test_machine_verify.py``; here the
faults are injected into real sliced output and checked through the command line: exit
status, the ``line N: message`` listing on stdout and the count on stderr.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from conftest import SHARED_DATA
from fgslice.cli import main
from fgslice.design import api, load_design
from fgslice.pipeline import slice_to_gcode
from fgslice.settings import load_settings

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
SHARED_BENCHY = SHARED_DATA / "meshes" / "3DBenchy.stl"
SLAB_MM = 1.0

NATURAL = {
    "dogbone": {"strategy": 1, "colors": 3},
    "palette": {"strategy": 2, "colors": 8},
    "three_materials": {"strategy": 2, "colors": 5, "channels": 4},
    "vase": {"strategy": 1, "colors": 4, "infill_density": 0},
    "ring_angular_gradient": {"strategy": 1, "colors": 4},
}


def bottom_slab(path: Path):
    """The example cut to its lowest ``SLAB_MM`` millimetre (same fields, same frame); the
    bounding box may reach below the part (a difference keeps its first body's box)."""
    design = load_design(path)
    (x0, y0, z0), (x1, y1, z1) = design.bounds()
    z0 = next(z for z in np.arange(z0, z1, 0.05) if design.section(z + 0.05).area > 0)
    slab = api.translate(((x0 + x1) / 2, (y0 + y1) / 2, z0 + SLAB_MM / 2),
                         api.rectprism(x1 - x0 + 2, y1 - y0 + 2, SLAB_MM))
    return api.design(api.intersection(design.root, slab))


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def example_paths():
    for path in sorted(EXAMPLES.glob("*.vcad")):
        marks = [pytest.mark.skipif(not SHARED_BENCHY.exists(), reason="shared Benchy mesh absent")] \
            if path.stem == "benchy" else []
        yield pytest.param(path, id=path.stem, marks=marks)


@pytest.fixture(scope="module")
def sliced(tmp_path_factory):
    """A small real output to break."""
    out = tmp_path_factory.mktemp("verify") / "dogbone.gcode"
    slice_to_gcode(bottom_slab(EXAMPLES / "dogbone.vcad"), load_settings("marlin-mixing", NATURAL["dogbone"]), out,
                   jobs=1)
    return out


@pytest.mark.slow
@pytest.mark.parametrize("path", list(example_paths()))
def test_verify_passes_every_example(path, tmp_path):
    overrides = NATURAL.get(path.stem, {"strategy": 2, "colors": 4})
    out = tmp_path / f"{path.stem}.gcode"
    stats = slice_to_gcode(bottom_slab(path), load_settings("marlin-mixing", overrides), out, jobs=1,
                           verify=False).stats
    assert stats["layers"] == round(SLAB_MM / 0.2)
    sets = [a for k, v in overrides.items() if k == "channels" for a in ("--set", f"{k}={v}")]
    result = run("verify", out, *sets)
    assert result.exit_code == 0, result.stdout + result.stderr
    assert result.stdout == f"{out}: ok\n"


BREAKS = {
    "outside the bed": ("G1 X500 Y10 E0.1", "leaves the build volume"),
    "not a number": ("G1 X10 Ynan E0.1", "not a finite number"),
    "blob": ("G1 E20", "without XY motion"),
    "too hot": ("M104 S450", "nozzle temperature 450 C is outside"),
    "bad mix": ("M165 A0.9 B0.9", "factors sum to 1.8000"),
    "no such channel": ("M165 A0.5 B0.25 C0.25", "channel C does not exist"),
    "no such tool": ("T7", "T7: no such tool"),
}


@pytest.mark.parametrize("name", BREAKS)
def test_verify_flags_a_broken_line_with_its_number(name, sliced, tmp_path):
    bad, words = BREAKS[name]
    lines = sliced.read_text().splitlines()
    at = next(i for i, line in enumerate(lines) if line.startswith(";LAYER_CHANGE")) + 3
    broken = tmp_path / "broken.gcode"
    broken.write_text("\n".join(lines[:at] + [bad] + lines[at:]) + "\n")
    result = run("verify", broken)
    assert result.exit_code == 1, result.stdout + result.stderr
    listed = re.findall(r"^  line (\d+): (.*)$", result.stdout, flags=re.M)
    assert (str(at + 1), ) in [(n,) for n, m in listed if words in m], result.stdout
    assert re.fullmatch(rf"{re.escape(str(broken))}: \d+ fault\(s\)\n", result.stderr)


def test_cold_extrusion_is_flagged(sliced, tmp_path):
    text = sliced.read_text()
    broken = tmp_path / "cold.gcode"
    broken.write_text(re.sub(r"^M109 S\d+.*$", "M104 S0", text, flags=re.M))
    result = run("verify", broken)
    assert result.exit_code == 1 and "below min_extrude_temperature" in result.stdout


def test_verify_refuses_what_is_not_gcode(tmp_path):
    binary = tmp_path / "part.bgcode"
    binary.write_bytes(b"GCDE\x01\x00\x00\x00" + bytes(range(256)))
    for path, words in ((binary, "binary"), (tmp_path / "missing.gcode", "No such file")):
        result = run("verify", path)
        assert result.exit_code == 2 and words in result.stderr and "Traceback" not in result.stderr


MISSED = {
    "words without blanks": ("G1X500Y500E0.1", "leaves the build volume"),
    "full circle off the bed": ("G2 X{x} Y{y} I-200 J0 E1", "arc sweeps through X-"),
    "longer arc by radius": ("G2 X{x2} Y{y} R-150 E1", "arc sweeps through"),
    "absurd E": ("G1 X{x2} Y{y} E1e308", "E value 1e+308 is out of range"),
}


@pytest.mark.parametrize("name", MISSED)
def test_verify_catches_moves_written_unusually(name, sliced, tmp_path):
    bad, words = MISSED[name]
    lines = sliced.read_text().splitlines()
    at = next(i for i, line in enumerate(lines) if line.startswith(";LAYER_CHANGE")) + 3
    x, y = next((float(m[1]), float(m[2])) for line in lines[at:] if (m := re.match(r"G1 X(\S+) Y(\S+)", line)))
    bad = bad.format(x=x, y=y, x2=x + 20)
    broken = tmp_path / "broken.gcode"
    broken.write_text("\n".join(lines[:at] + [bad] + lines[at:]) + "\n")
    result = run("verify", broken)
    assert result.exit_code == 1, result.stdout + result.stderr
    listed = re.findall(r"^  line (\d+): (.*)$", result.stdout, flags=re.M)
    assert any(n == str(at + 1) and words in m for n, m in listed), result.stdout
    assert "not a finite number" not in result.stdout  # each is a number, if an absurd one


FINE = ["M117 Printing... 50%", "M118 E1 X1000 hello", "M23 /X500E5.gco", "N1 G1 X10 Y10*35",
        "N2 G1 X10 Y10 ; moved*12", "SET_FAN_SPEED FAN=nozzle SPEED=0.5", "G2 X{x} Y{y} I5 J0",
        "G1X{x}Y{y}"]


@pytest.mark.parametrize("line", FINE)
def test_verify_accepts_messages_checksums_and_sound_arcs(line, sliced, tmp_path):
    lines = sliced.read_text().splitlines()
    at = next(i for i, text in enumerate(lines) if text.startswith(";LAYER_CHANGE")) + 3
    x, y = next((float(m[1]), float(m[2])) for text in lines[at:] if (m := re.match(r"G1 X(\S+) Y(\S+)", text)))
    edited = tmp_path / "edited.gcode"
    edited.write_text("\n".join(lines[:at] + [line.format(x=x, y=y)] + lines[at:]) + "\n")
    result = run("verify", edited)
    assert result.exit_code == 0, result.stdout + result.stderr


def test_verify_toolchanger_flags_mixing_commands(sliced):
    """The dogbone is sliced for the mixing hotend: its M165 lines have no place on a toolchanger."""
    result = run("verify", sliced, "--profile", "toolchanger")
    assert result.exit_code == 1
    assert "M165: a mixing command, but the toolchanger machine has no mixing hotend" in result.stdout
    assert run("verify", sliced).exit_code == 0
