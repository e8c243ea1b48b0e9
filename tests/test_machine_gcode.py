"""The G-code writer: E math, travel and retraction, annotations, footer, statistics."""

import io
import re
from datetime import datetime, timezone

import numpy as np
import pytest

from fgslice.machine.dialects import make_dialect
from fgslice.machine.gcode import GcodeWriter, fmt, format_duration, format_lines, format_moves
from fgslice.machine.gcode_reader import read_gcode
from fgslice.machine.thumbnails import thumbnail_block
from fgslice.machine.verify import verify_gcode
from fgslice.planning.plan import LayerPlan, SetState
from fgslice.settings import load_settings
from fgslice.slicing.palette import Palette
from fgslice.toolpaths.paths import Path, Role, bead_area

PNG = b"\x89PNG\r\n\x1a\n" + bytes(range(256)) * 3
NOW = datetime(2025, 3, 4, 5, 6, 7, tzinfo=timezone.utc)


def ring(cx, cy, r, n=60):
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    return np.column_stack([cx + r * np.cos(t), cy + r * np.sin(t)])


def layer(index, h=0.2):
    """Two colors of loops, an infill zigzag in the current state and a purge line."""
    rng = np.random.default_rng(index)
    zig = np.column_stack([np.linspace(90, 130, 41), 100 + 5 * (np.arange(41) % 2)])
    steps = [
        SetState(index % 2),
        Path(ring(110, 110, 20), Role.EXTERNAL_PERIMETER, index % 2, 0.45, h, closed=True),
        Path(ring(110, 110, 19.55) + rng.normal(0, 1e-5, (60, 2)), Role.PERIMETER, index % 2, 0.4, h, closed=True),
        SetState(2),
        Path(zig, Role.INTERNAL_INFILL, -1, 0.4, h),
        Path(np.array([[20.0, 20.0], [40.0, 20.0]]), Role.WIPE_TOWER, 2, 0.5, h),
    ]
    return LayerPlan(index, h * (index + 1), h, steps)


def write(plans, profile="marlin-mixing", palette=None, **overrides):
    settings = load_settings(profile, {k: str(v) for k, v in overrides.items()})
    palette = palette or Palette(2, 4)
    out = io.StringIO()
    writer = GcodeWriter(out, settings, palette, make_dialect(settings, palette), comments={"design": "ring.vcad"},
                         thumbnails=[(PNG, 16, 16)], now=NOW)
    writer.write_header()
    for plan in plans:
        writer.write_layer(plan)
    stats = writer.finish()
    return out.getvalue(), stats, settings


def expected_volume(plans):
    return sum(p.length * bead_area(p.width, p.height) for plan in plans for p in plan.paths)


def test_extruded_volume_equals_length_times_bead_area():
    plans = [layer(i) for i in range(3)]
    text, stats, settings = write(plans)
    program = read_gcode(text)
    area = np.pi * settings.filament_diameter**2 / 4
    printed = program.length > 0
    volume = program.e[printed & (program.e > 0)].sum() * area
    assert volume == pytest.approx(expected_volume(plans), rel=1e-3)
    assert stats["extruded_mm3"] == pytest.approx(expected_volume(plans), rel=1e-3)
    # each segment carries its own bead: E per mm of XY equals bead_area / filament area
    widths = program.width[printed & (program.e > 0)]
    per_mm = program.e[printed & (program.e > 0)] / program.length[printed & (program.e > 0)]
    expected = np.array([bead_area(w, 0.2) for w in widths]) / area
    assert np.allclose(per_mm, expected, rtol=0.02, atol=2e-4)


def test_statistics_by_commanded_color_and_purge():
    plans = [layer(i) for i in range(2)]
    _, stats, _ = write(plans)
    by_color = stats["extruded_mm3_by_color"]
    loops0 = sum(p.length * bead_area(p.width, 0.2) for p in plans[0].paths[:2])
    assert by_color[0] == pytest.approx(loops0, rel=1e-3)
    zig_and_purge = sum(p.length * bead_area(p.width, 0.2) for plan in plans for p in plan.paths[2:])
    assert by_color[2] == pytest.approx(zig_and_purge, rel=1e-3)
    assert stats["purge_mm3"] == pytest.approx(2 * 20 * bead_area(0.5, 0.2), rel=1e-3)
    assert stats["purge_g"] == pytest.approx(stats["purge_mm3"] * 1.24e-3)
    assert stats["layers"] == 2 and stats["colors"] == 4 and stats["state_changes"] == 4
    (x0, y0, z0), (x1, y1, z1) = stats["extrusion_bbox"]
    assert (x0, y0, z0) == pytest.approx((20, 20, 0.2)) and (x1, y1, z1) == pytest.approx((130, 130, 0.4))
    assert stats["filament_mm"] * np.pi * 1.75**2 / 4 == pytest.approx(stats["extruded_mm3"])
    assert stats["estimated_time_s"] > stats["travel_mm"] / 150


def test_travel_retraction_and_z_hop():
    plans = [layer(0), layer(1)]
    text, stats, settings = write(plans, z_hop=0.3)
    lines = text.splitlines()
    travels = [i for i, line in enumerate(lines) if line.startswith("G0 ")]
    long_travels = 0
    for i in travels:
        before = lines[i - 2 : i]
        after = lines[i + 1 : i + 3]
        if before == ["G1 E-0.8 F2100", f"G1 Z{before[1][4:].split()[0]} F600"] or lines[i - 1].startswith("G1 Z"):
            long_travels += 1
            assert after[1] == "G1 E0.8 F2100"
    assert long_travels >= 3
    program = read_gcode(text)
    e = program.e
    assert e[e < 0].sum() == pytest.approx(-0.8 * stats["retractions"])
    assert e[(e > 0) & (program.length == 0) & (program.start[:, 2] == program.end[:, 2])].sum() == pytest.approx(
        0.8 * stats["retractions"])
    # retracted travels are lifted by z_hop and come back down before printing
    hops = program.end[:, 2] - program.start[:, 2]
    assert np.isclose(hops, 0.3).sum() >= 3 and np.isclose(hops, -0.3).sum() == np.isclose(hops, 0.3).sum()
    # short travels (the 0.45 mm step between the two rings) do not retract
    second_ring = next(i for i, line in enumerate(lines) if line == ";TYPE:Perimeter")
    assert not any(line.startswith("G1 E-") for line in lines[second_ring - 3 : second_ring])


def test_annotations_and_header():
    text, stats, settings = write([layer(0), layer(1)])
    lines = text.splitlines()
    assert lines[0] == "; generated by fgslice 0.1.0 on 2025-03-04 at 05:06:07 UTC" or re.fullmatch(
        r"; generated by fgslice \S+ on 2025-03-04 at 05:06:07 UTC", lines[0])
    assert thumbnail_block(PNG, 16, 16) in text
    assert "; design = ring.vcad" in lines and "; layer_height = 0.2" in lines
    assert "; color 0 = A 12.5% / B 87.5% : M165 A0.1250 B0.8750" in lines
    assert "M140 S60" in lines and "M109 S210" in lines
    assert lines.index("M83") < lines.index(";LAYER_CHANGE")
    program = read_gcode(text)
    assert program.layer_z == [0.2, 0.4]
    assert set(program.roles) == {"External perimeter", "Perimeter", "Internal infill", "Wipe tower"}
    assert sorted(set(program.layer.tolist()) - {-1}) == [0, 1]
    colors = program.color_of_moves()[program.e > 0]
    roles = np.array(program.roles)[program.role[program.e > 0]]
    assert set(colors[roles == "Internal infill"]) == {2}
    layer_of = program.layer[program.e > 0]
    assert set(colors[(roles == "External perimeter") & (layer_of == 1)]) == {1}
    widths = set(program.width[program.e > 0].round(3))
    assert widths == {0.45, 0.4, 0.5}
    assert text.count(";STATE:") == stats["state_changes"]
    assert "M106 S255" in lines and lines.index("M106 S255") > [i for i, l in enumerate(lines) if l == ";LAYER_CHANGE"][1]


def test_footer():
    text, stats, _ = write([layer(0)])
    tail = text.partition("; generated by PrusaSlicer")[0].splitlines()[-6:]
    assert f"; filament used [mm] = {stats['filament_mm']:.2f}" in tail
    assert f"; filament used [cm3] = {stats['extruded_mm3'] / 1000:.2f}" in tail
    assert f"; estimated printing time (normal mode) = {format_duration(stats['estimated_time_s'])}" in tail
    assert format_duration(3723) == "1h 2m 3s" and format_duration(59.6) == "1m 0s" and format_duration(90061) == "1d 1h 1m 1s"


def test_streaming_writes_each_layer_as_it_comes():
    settings = load_settings("marlin-mixing")
    palette = Palette(2, 4)
    out = io.StringIO()
    writer = GcodeWriter(out, settings, palette, make_dialect(settings, palette), comments={}, now=NOW)
    writer.write_header()
    writer.write_layer(layer(0))
    first = out.getvalue()
    assert first.count(";LAYER_CHANGE") == 1 and "filament used" not in first
    writer.write_layer(layer(1))
    assert out.getvalue().startswith(first) and out.getvalue().count(";LAYER_CHANGE") == 2
    stats = writer.finish()
    assert stats["layers"] == 2 and out.getvalue().endswith("; prusaslicer_config = end\n")
    assert f"; estimated printing time (normal mode) = {format_duration(stats['estimated_time_s'])}\n" in out.getvalue()


def test_toolchanger_state_is_a_tool_and_forces_a_travel():
    plans = [LayerPlan(0, 0.2, 0.2, [SetState(1), Path(ring(50, 50, 5), Role.PERIMETER, 1, 0.4, 0.2, True),
                                     SetState(3), Path(ring(50, 50, 5), Role.PERIMETER, 3, 0.4, 0.2, True)])]
    text, stats, settings = write(plans, "toolchanger", Palette(2, 5))
    lines = text.splitlines()
    t3 = lines.index("T3")
    assert lines[t3 - 1].startswith(";STATE:3 ") and lines[t3 + 1].startswith("G0 X55 Y50")
    assert verify_gcode(text, settings) == []


def test_zero_length_moves_are_suppressed_and_numbers_are_compact():
    pts = np.array([[10.0, 10.0], [10.0002, 10.0], [12.5, 10.0], [12.5, 10.0], [12.5, 11.25]])
    text, _, _ = write([LayerPlan(0, 0.2, 0.2, [SetState(0), Path(pts, Role.PERIMETER, 0, 0.4, 0.2)])])
    moves = [line for line in text.splitlines() if line.startswith("G1 X")]
    assert [m.split(" E")[0] for m in moves] == ["G1 X12.5 Y10", "G1 X12.5 Y11.25"]


def test_format_moves_matches_python_formatting():
    rng = np.random.default_rng(3)
    x, y, e = rng.uniform(-5, 400, 500), rng.uniform(0, 400, 500).round(2), rng.uniform(0, 2, 500)
    text, offsets = format_moves(x, y, e)
    for k, line in enumerate(text.splitlines()):
        words = line.split()
        assert float(words[1][1:]) == float(f"{x[k]:.3f}") and float(words[3][1:]) == float(f"{e[k]:.5f}")
        assert float(words[2][1:]) == float(f"{y[k]:.3f}")
        assert not words[1].endswith("0") or "." not in words[1]
    assert offsets[-1] == len(text)


@pytest.mark.parametrize("decimals", [0, 1, 2, 3, 4, 5])
def test_format_lines_writes_every_number_as_python_does(decimals):
    rng = np.random.default_rng(decimals)
    special = [0.0, -0.0, -1e-9, 1e-9, 0.5, -0.5, 1000.0, 999.9999999, 1000000.0, 123456789.0, -12345.6789,
               100.1, 0.00001, 0.000049, 2.00000, 10.0, -7.25]
    values = np.concatenate([special, rng.uniform(-2000, 2000, 300), 10.0 ** rng.uniform(-6, 8, 300)])
    text, offsets = format_lines([("V", values, decimals)])
    assert text.splitlines() == [f"V{fmt(v, decimals)}" for v in values]
    assert offsets[-1] == len(text) and np.all(np.diff(offsets) > 1)


def test_state_change_before_a_degenerate_path_is_kept():
    dot = np.array([[30.0, 30.0], [30.0001, 30.0]])
    line = np.array([[30.0, 40.0], [50.0, 40.0]])
    plan = LayerPlan(0, 0.2, 0.2, [SetState(0), Path(line, Role.PERIMETER, 0, 0.4, 0.2), SetState(1),
                                   Path(dot, Role.PERIMETER, 1, 0.4, 0.2), Path(line[::-1], Role.PERIMETER, -1, 0.4, 0.2),
                                   SetState(3)])
    text, stats, _ = write([plan])
    lines = text.splitlines()
    m1, m3 = lines.index("M165 A0.3750 B0.6250"), lines.index("M165 A0.8750 B0.1250")
    second = [i for i, l in enumerate(lines) if l.startswith("G1 X30 Y40")]
    assert m1 < second[0] < m3
    assert stats["state_changes"] == 3 and stats["warnings"] == ["1 paths shorter than 0.001 mm were not written"]
    assert stats["extruded_mm3_by_color"][1] == pytest.approx(20 * bead_area(0.4, 0.2), rel=1e-4)


def test_thumbnail_block_prusaslicer_format():
    import base64

    block = thumbnail_block(PNG, 16, 16).splitlines()
    encoded = base64.b64encode(PNG).decode()
    assert block[0] == f"; thumbnail begin 16x16 {len(encoded)}" and block[-1] == "; thumbnail end"
    body = block[1:-1]
    assert all(line.startswith("; ") and len(line) <= 80 for line in body)
    assert "".join(line[2:] for line in body) == encoded
    with pytest.raises(ValueError, match="not a PNG"):
        thumbnail_block(b"GIF89a", 16, 16)


def test_prepared_bodies_write_the_same_text_as_the_writer():
    import copy
    import pickle

    from fgslice.machine.gcode import prepare_bodies
    from fgslice.planning.lookahead import apply_lookahead

    settings = load_settings("marlin-mixing")
    plain = [layer(i) for i in range(3)]
    prepared = pickle.loads(pickle.dumps(copy.deepcopy(plain)))
    for plan in prepared:
        prepare_bodies(plan, settings)
    prepared = pickle.loads(pickle.dumps(prepared))  # as a worker sends them
    # an extra path no body was prepared for
    prepared[1].steps.insert(2, Path(ring(60, 60, 3), Role.SKIRT, -1, 0.4, 0.2, closed=True))
    plain[1].steps.insert(2, Path(ring(60, 60, 3), Role.SKIRT, -1, 0.4, 0.2, closed=True))
    assert write(plain)[0] == write(prepared)[0]
    # look-ahead splits prepared paths: the pieces are written from their points
    shifted_plain = list(apply_lookahead(plain, 7.0))
    shifted = list(apply_lookahead(prepared, 7.0))
    assert any(plan.prepared and any(p not in plan.prepared.rows for p in plan.paths) for plan in shifted)
    assert write(shifted_plain)[0] == write(shifted)[0]


def test_bodies_prepared_in_this_process_write_the_same_text():
    from fgslice.machine.gcode import prepare_bodies

    settings = load_settings("marlin-mixing")
    plain, prepared = [layer(i) for i in range(3)], [layer(i) for i in range(3)]
    for plan in prepared:
        prepare_bodies(plan, settings)  # with --jobs 1 plans never leave the process
    assert all(plan.packed is not None and len(plan.packed.data.e) == 4 for plan in prepared)
    text, stats, _ = write(prepared)
    assert (text, stats) == write(plain)[:2]
    assert stats["extruded_mm3"] == pytest.approx(expected_volume(plain), rel=1e-5)


def test_each_path_writes_its_exact_filament():
    plans = [layer(i) for i in range(2)]
    text, stats, settings = write(plans)
    program = read_gcode(text)
    area = np.pi * settings.filament_diameter**2 / 4
    lines = text.splitlines()
    # sum E of each run of extruding moves between non-move lines = one path
    paths = [p for plan in plans for p in plan.paths]
    written = [np.round(p.vertices, 3) for p in paths]  # the coordinates as written
    exact = [np.hypot(*np.diff(v, axis=0).T).sum() * bead_area(p.width, p.height) / area for v, p in zip(written, paths)]
    extruding = (program.length > 0) & (program.e > 0)
    runs = np.split(program.e[extruding], np.flatnonzero(np.diff(program.line[extruding]) > 1) + 1)
    assert len(runs) == len(paths) and len(lines) > len(paths)
    assert np.allclose([r.sum() for r in runs], exact, rtol=0, atol=6e-6)
