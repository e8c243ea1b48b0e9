"""Parts narrower than a bead printed as single beads along their centre lines
(fgslice.toolpaths.thin_features): fins on a block measured in the G-code, centre lines
of rings, arcs and T-junctions against their geometry, the settings."""

from __future__ import annotations

import numpy as np
import pytest
import shapely

from fgslice.design.language import load_design
from fgslice.errors import SettingsError
from fgslice.machine.gcode_reader import read_gcode
from fgslice.pipeline import slice_to_gcode
from fgslice.settings import Settings, load_settings
from fgslice.slicing.layers import LayerRegions
from fgslice.toolpaths import strategy2
from fgslice.toolpaths.paths import Role, bead_area
from fgslice.toolpaths.thin_features import feature_limits, thin_beads
from fgslice.toolpaths.walls import offset

from conftest import EXAMPLES

H = 0.2
W = 0.4
FIN_LENGTH = 5.0
BLOCK_HEIGHT = 2.0


def fin_design(tmp_path, thickness: float):
    """A 10 x 10 x 2 mm block centred at the origin and a fin ``thickness`` mm thick, 5 mm
    long and as tall, from its right side (x = 5 .. 10) along y = 0."""
    path = tmp_path / "fin.vcad"
    path.write_text(f"union() {{ translate(0, 0, 1) {{ rectprism(10, 10, {BLOCK_HEIGHT}); }}\n"
                    f"  translate(7.5, 0, 1) {{ rectprism({FIN_LENGTH}, {thickness}, {BLOCK_HEIGHT}); }} }}\n")
    return load_design(path)


def slice_fin(tmp_path, thickness: float, **overrides):
    """``(program, stats, offset, settings)`` of the fin design sliced with ``overrides``."""
    settings = load_settings(None, {"skirt_loops": "0", "thumbnails": "", **{k: str(v) for k, v in overrides.items()}})
    out = tmp_path / "fin.gcode"
    stats = slice_to_gcode(fin_design(tmp_path, thickness), settings, out, jobs=1).stats
    return read_gcode(out), stats, np.array(stats["placement_offset"]), settings


def extruding(program) -> np.ndarray:
    return (program.e > 0) & (program.length > 0)


def beyond_block(program, offset_xyz, margin: float = 0.01) -> np.ndarray:
    """The extruding moves that run wholly right of the block's side (x = 5 in the design)."""
    edge = 5.0 + offset_xyz[0] + margin
    return extruding(program) & (program.start[:, 0] > edge) & (program.end[:, 0] > edge)


def assert_on_the_bed(program, settings):
    xy = np.vstack([program.start[extruding(program), :2], program.end[extruding(program), :2]])
    assert xy.min() >= 0 and xy[:, 0].max() <= settings.bed_x and xy[:, 1].max() <= settings.bed_y


@pytest.mark.parametrize("strategy", [1, 2])
@pytest.mark.parametrize("thickness", [0.25, 0.3])
def test_a_fin_thinner_than_a_bead_prints_one_bead_along_its_centre_line(tmp_path, strategy, thickness):
    program, stats, placed, settings = slice_fin(tmp_path, thickness, strategy=strategy, colors=1)
    fin = beyond_block(program, placed)
    layers = len(program.layer_z)
    assert layers == BLOCK_HEIGHT / H
    # one bead per layer, along y = 0 within 0.05 mm, spanning the fin
    assert sorted(program.layer[fin].tolist()) == list(range(layers))
    np.testing.assert_allclose(program.start[fin, 1], placed[1], atol=0.05)
    np.testing.assert_allclose(program.end[fin, 1], placed[1], atol=0.05)
    ends = np.concatenate([program.start[fin, 0], program.end[fin, 0]]) - placed[0]
    assert ends.min() < 5 + thickness and ends.max() > 10 - thickness and ends.max() < 10
    # its volume: the fin's, within 15 % (a 0.25 mm fin gets the 0.34 mm min_bead_width bead)
    extruded = float(program.e[fin].sum() * np.pi * settings.filament_diameter**2 / 4)
    assert extruded == pytest.approx(thickness * FIN_LENGTH * BLOCK_HEIGHT, rel=0.15)
    _, narrowest = feature_limits(settings)
    np.testing.assert_array_less(narrowest - 1e-3, program.width[fin])
    assert stats["thin_dropped_mm2"] == 0 and stats["uncovered_mm2"] < 0.01
    assert not [w for w in stats["warnings"] if "min_feature_size" in w or "narrower than a bead" in w]
    assert_on_the_bed(program, settings)


@pytest.mark.parametrize("strategy", [1, 2])
def test_a_fin_below_min_feature_size_is_dropped_with_a_warning(tmp_path, strategy):
    program, stats, placed, settings = slice_fin(tmp_path, 0.05, strategy=strategy, colors=1)
    assert not beyond_block(program, placed).any()
    layers = len(program.layer_z)
    assert stats["thin_dropped_mm2"] == pytest.approx(0.05 * FIN_LENGTH * layers, rel=0.05)
    warning = [w for w in stats["warnings"] if "min_feature_size" in w]
    assert len(warning) == 1 and f"on {layers} of {layers} layers" in warning[0] and "0.1 mm" in warning[0]
    assert_on_the_bed(program, settings)
    # a smaller min_feature_size prints it (at min_bead_width)
    program, stats, placed, _ = slice_fin(tmp_path, 0.05, strategy=strategy, colors=1, min_feature_size=0.04)
    assert beyond_block(program, placed).any() and stats["thin_dropped_mm2"] == 0


@pytest.mark.parametrize("strategy", [1, 2])
def test_without_thin_features_a_fin_is_left_unprinted(tmp_path, strategy):
    program, stats, placed, _ = slice_fin(tmp_path, 0.3, strategy=strategy, colors=1, thin_features="false")
    assert not beyond_block(program, placed).any()
    assert stats["uncovered_mm2"] == pytest.approx(0.3 * FIN_LENGTH * len(program.layer_z), rel=0.05)
    assert stats["thin_dropped_mm2"] == 0


@pytest.mark.parametrize("name, overrides", [("dogbone.vcad", {"strategy": 1, "colors": 3}),
                                             ("palette.vcad", {"colors": 1})])
def test_ordinary_parts_get_no_thin_beads(tmp_path, name, overrides):
    """Wide regions: the same moves with thin features on and off (with several colors,
    strategy 2 prints the tips of color bands narrower than a bead that no neighbour took)."""
    design = load_design(EXAMPLES / name)
    programs = []
    for thin in ("true", "false"):
        settings = load_settings(None, {"thumbnails": "", "thin_features": thin, **{k: str(v) for k, v in overrides.items()}})
        out = tmp_path / f"{thin}.gcode"
        slice_to_gcode(design, settings, out, jobs=1)
        programs.append(read_gcode(out))
    on, off = programs
    for name_ in ("start", "end", "e", "width"):
        np.testing.assert_array_equal(getattr(on, name_), getattr(off, name_))


def layer(geometry, settings=None):
    outline = shapely.MultiPolygon([geometry]) if geometry.geom_type == "Polygon" else geometry
    return strategy2.layer_paths(LayerRegions(0, H, H, outline, (outline,)), settings or Settings())


def volume(paths) -> float:
    return sum(bead_area(p.width, p.height) * p.length for p in paths)


def test_a_ring_thinner_than_a_bead_is_one_closed_bead_on_its_mid_circle():
    ring = shapely.Point(0, 0).buffer(5, 128).difference(shapely.Point(0, 0).buffer(4.7, 128))
    lp = layer(ring)
    assert len(lp.paths) == 1 and lp.paths[0].closed and lp.paths[0].role is Role.PERIMETER
    np.testing.assert_allclose(np.hypot(*lp.paths[0].points.T), 4.85, atol=0.01)
    assert volume(lp.paths) == pytest.approx(ring.area * H, rel=0.02)
    assert lp.uncovered_mm2 < 1e-6


def test_a_curved_strip_is_one_open_bead_on_its_centre_line():
    arc = shapely.LineString([(10 * np.cos(a), 10 * np.sin(a)) for a in np.linspace(0, 2, 100)])
    strip = arc.buffer(0.15, cap_style="flat")
    lp = layer(strip)
    assert len(lp.paths) == 1 and not lp.paths[0].closed
    np.testing.assert_allclose(np.hypot(*lp.paths[0].points.T), 10, atol=0.02)
    assert lp.paths[0].length == pytest.approx(arc.length - 0.3, abs=0.1)  # ends half the width in
    assert volume(lp.paths) == pytest.approx(strip.area * H, rel=0.02)


def test_a_t_junction_of_thin_walls_is_three_beads_meeting_without_spurs():
    tee = shapely.union_all([shapely.box(0, 0, 10, 0.3), shapely.box(4.85, 0, 5.15, 8)])
    lp = layer(tee)
    assert len(lp.paths) == 3
    points = np.vstack([p.points for p in lp.paths])
    on_bar = np.abs(points[:, 1] - 0.15) < 0.05
    on_stem = np.abs(points[:, 0] - 5.0) < 0.05
    assert np.all(on_bar | on_stem)  # every vertex on a centre line: no spur into a corner
    assert points[:, 0].min() == pytest.approx(0.15, abs=0.05) and points[:, 0].max() == pytest.approx(9.85, abs=0.05)
    assert points[:, 1].max() == pytest.approx(7.85, abs=0.05)
    assert volume(lp.paths) == pytest.approx(tee.area * H, rel=0.05)


def test_a_pin_is_a_dot_holding_its_volume():
    """A 0.3 mm disc (a thin pin's section) is a short segment a bead wide at its centre."""
    pin = shapely.Point(3, 4).buffer(0.15, 32)
    lp = layer(pin)
    assert len(lp.paths) == 1 and lp.paths[0].width == pytest.approx(W)
    np.testing.assert_allclose(lp.paths[0].points.mean(axis=0), (3, 4), atol=1e-6)
    # the face is simplified to 0.01 mm before filling: its area is within 3 % of the disc's
    assert lp.paths[0].length < 0.3 and volume(lp.paths) == pytest.approx(pin.area * H, rel=0.03)


def test_beads_take_the_color_of_their_face():
    """A wide region gets no bead; a fin's bead takes the color of the region it lies in."""
    settings = Settings(colors=2)
    body = shapely.box(0, 0, 20, 20)
    eroded = offset(np.array([body], dtype=object), -W / 2)
    assert thin_beads([body], eroded, [1], settings, Role.PERIMETER).paths == []
    fin = shapely.box(20, 5, 30, 5.3)
    eroded = offset(np.array([body.union(fin)], dtype=object), -W / 2)
    beads = thin_beads([body.union(fin)], eroded, [1], settings, Role.PERIMETER)
    assert [p.color for p in beads.paths] == [1] and beads.printed_mm2 == pytest.approx(3.0, rel=1e-6)


@pytest.mark.parametrize("value, mm", [("25%", 0.1), ("0.15", 0.15), (0.2, 0.2), ("50 %", 0.2)])
def test_min_feature_size_is_mm_or_a_percentage_of_the_nozzle(value, mm):
    settings = load_settings(None, {"min_feature_size": value})
    assert feature_limits(settings) == pytest.approx((mm, 0.34))


@pytest.mark.parametrize("key, value", [("min_feature_size", "wide"), ("min_bead_width", "-5%"),
                                        ("min_feature_size", "0")])
def test_a_bad_width_names_its_setting(key, value):
    with pytest.raises(SettingsError, match=key):
        load_settings(None, {key: value})


def test_min_bead_width_is_at_most_a_bead():
    assert feature_limits(load_settings(None, {"min_bead_width": "150%"}))[1] == pytest.approx(W)
