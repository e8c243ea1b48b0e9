"""The time model against trapezoids worked out by hand (fgslice.machine.timing)."""

from __future__ import annotations

import math

import pytest

from fgslice.machine.gcode import format_duration
from fgslice.machine.gcode_header import read_footer
from fgslice.machine.timing import TimeModel, estimate_time
from fgslice.settings import load_settings

A = 3000.0  # the profiles' acceleration, mm/s^2


def trapezoid(length: float, cruise: float, accel: float, v0: float = 0.0, v1: float = 0.0) -> float:
    """Seconds of a move of ``length`` mm entered at ``v0``, left at ``v1``, cruising at
    ``cruise`` if it can reach it (else a triangle), accelerating at ``accel``."""
    peak = min(cruise, math.sqrt((2 * accel * length + v0**2 + v1**2) / 2))
    ramps = (2 * peak**2 - v0**2 - v1**2) / (2 * accel)
    return (peak - v0) / accel + (peak - v1) / accel + (length - ramps) / peak


def klipper(**overrides):
    return load_settings("marlin-mixing", {"motion_planner": "klipper", "minimum_cruise_ratio": "0", **overrides})


@pytest.mark.parametrize("settings", [klipper(), load_settings("marlin-mixing")], ids=["klipper", "marlin"])
@pytest.mark.parametrize("length, feed", [(100.0, 100.0), (1.0, 100.0), (20.0, 40.0)])
def test_a_move_from_rest_to_rest_is_a_trapezoid(settings, length, feed):
    text = f"G1 X{length} F{feed * 60}\n"
    assert estimate_time(text, settings) == pytest.approx(trapezoid(length, feed, A), rel=1e-9)


def test_moves_straight_on_are_planned_as_one():
    settings = klipper()
    pieces = "".join(f"G1 X{x} F6000\n" for x in range(10, 101, 10))
    assert estimate_time(pieces, settings) == pytest.approx(trapezoid(100, 100, A), rel=1e-9)


def test_a_square_corner_is_taken_at_the_square_corner_velocity():
    settings = klipper(square_corner_velocity="5")
    both = 2 * trapezoid(50, 100, A, v1=5.0)
    assert estimate_time("G1 X50 F6000\nG1 Y50\n", settings) == pytest.approx(both, rel=1e-9)


def test_marlin_junction_deviation_of_a_square_corner():
    settings = load_settings("marlin-mixing", {"junction_deviation": "0.02"})
    corner = math.sqrt(0.02 * A * math.sin(math.pi / 4) / (1 - math.sin(math.pi / 4)))
    both = 2 * trapezoid(50, 100, A, v1=corner)
    assert estimate_time("G1 X50 F6000\nG1 Y50\n", settings) == pytest.approx(both, rel=1e-9)


def test_marlin_classic_jerk_starts_at_the_jerk():
    settings = load_settings("marlin-mixing", {"junction_deviation": "0", "jerk": "10"})
    expected = trapezoid(100, 100, A, v0=10.0)  # and stops at rest, as Marlin's last block
    assert estimate_time("G1 X100 F6000\n", settings) == pytest.approx(expected, rel=1e-9)


def test_klipper_minimum_cruise_ratio_caps_a_short_move():
    settings = klipper(minimum_cruise_ratio="0.5")
    length = 2.0  # too short to reach 100 mm/s: the peak is that of half the acceleration
    peak = math.sqrt(length * A / 2)
    expected = 2 * peak / A + (length - peak**2 / A) / peak
    assert estimate_time("G1 X2 F6000\n", settings) == pytest.approx(expected, rel=1e-9)


def test_retractions_use_the_firmware_extrusion_acceleration():
    settings = klipper()
    ratio = 4 * 0.4**2 / (math.pi * 1.75**2 / 4)  # Klipper: max_accel x max_extrude_ratio
    text = "M83\nG1 E-0.8 F2100\nG1 E0.8 F2100\n"
    assert estimate_time(text, settings) == pytest.approx(2 * trapezoid(0.8, 35, A * ratio), rel=1e-9)
    marlin = load_settings("marlin-mixing", {"retract_acceleration": "1000"})
    assert estimate_time(text, marlin) == pytest.approx(2 * trapezoid(0.8, 35, 1000), rel=1e-9)


def test_z_moves_use_the_z_acceleration():
    settings = klipper(z_acceleration="100")
    assert estimate_time("G1 Z5 F600\n", settings) == pytest.approx(trapezoid(5, 10, 100), rel=1e-9)


def test_waits_stop_the_head_and_dwells_add_their_time():
    settings = klipper()
    text = "G1 X50 F6000\nM400\nG1 X100\nG4 P1500\nG1 X150\nT1\nG1 X200\n"
    assert estimate_time(text, settings) == pytest.approx(4 * trapezoid(50, 100, A) + 1.5, rel=1e-9)


def test_pieces_fed_one_by_one_give_the_time_of_the_whole():
    settings = klipper(minimum_cruise_ratio="0.5")
    lines = [f"G1 X{100 + 30 * math.cos(k / 7):.3f} Y{100 + 30 * math.sin(k / 5):.3f} E0.05 F{1200 + 60 * (k % 40)}"
             for k in range(400)]
    lines[150:150] = ["M400", "G1 E-0.8 F2100"]
    text = "M83\n" + "\n".join(lines) + "\n"
    model = TimeModel(settings)
    for k in range(0, len(lines), 37):
        model.feed("\n".join(lines[k:k + 37]) + "\n" if k else "M83\n" + "\n".join(lines[:37]) + "\n")
    assert model.finish() == pytest.approx(estimate_time(text, settings), rel=1e-12)


def test_the_footer_and_statistics_carry_the_model_time(tmp_path):
    from fgslice.design.language import load_design
    from fgslice.pipeline import slice_to_gcode
    from pathlib import Path

    settings = load_settings("toolchanger", {"colors": "3"})
    out = tmp_path / "part.gcode"
    design = load_design(Path(__file__).resolve().parents[1] / "examples" / "temperature_gradient.vcad")
    stats = slice_to_gcode(design, settings, out, jobs=1).stats
    text = out.read_text(encoding="utf-8")
    changes = sum(1 for line in text.splitlines() if line[:1] == "T" and line[1:].isdigit())  # 10 s each
    assert stats["estimated_time_s"] == pytest.approx(estimate_time(text, settings) + 10.0 * changes, rel=1e-9)
    assert read_footer(out)["estimated printing time (normal mode)"] == format_duration(stats["estimated_time_s"])
    # acceleration makes the print slower than its lengths at their feed rates
    assert stats["estimated_time_s"] > _no_acceleration(text, settings) + 10.0 * changes


def _no_acceleration(text: str, settings) -> float:
    from fgslice.machine.gcode_reader import read_gcode
    import numpy as np

    program = read_gcode(text.encode())
    d = np.linalg.norm(program.end - program.start, axis=1)
    d = np.where(d > 0, d, np.abs(program.e))
    return float(np.sum(d / (program.feed / 60.0)))


def test_chunks_read_elsewhere_give_the_time_of_the_text(monkeypatch):
    """The verifier's chunks (any size) planned with :meth:`TimeModel.read` give the time
    the writer's pieces give, also where a long run of moves is cut without a real stop."""
    from fgslice.machine import timing
    from fgslice.machine.gcode_reader import iter_gcode

    monkeypatch.setattr(timing, "MAX_PENDING", 64)
    settings = klipper(minimum_cruise_ratio="0.5")
    lines = [f"G1 X{100 + 30 * math.cos(k / 7):.3f} Y{100 + 30 * math.sin(k / 5):.3f} E0.05 F{1200 + 60 * (k % 40)}"
             for k in range(400)]
    lines[150:150] = ["M400", "G1 E-0.8 F2100", "G4 P250"]
    text = "M83\n" + "\n".join(lines) + "\n"
    whole = estimate_time(text, settings)
    for size in (7, 100, 1000):
        model = TimeModel(settings)
        for chunk in iter_gcode(text.encode(), chunk_lines=size):
            model.read(chunk)
        assert model.finish() == pytest.approx(whole, rel=1e-12)
    assert whole > 0.25 + estimate_time("M83\n" + "\n".join(lines[153:]) + "\n", settings)
