"""Strategy 1 end to end on the dogbone example: colors, zippers, skins, purge tower."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import shapely

from fgslice.design import load_design
from fgslice.machine.gcode_header import read_header
from fgslice.machine.gcode_reader import read_gcode
from fgslice.pipeline import slice_to_gcode
from fgslice.settings import load_settings
from fgslice.slicing.palette import Palette

DOGBONE = Path(__file__).resolve().parents[1] / "examples" / "dogbone.vcad"


def _slice(tmp_path, **overrides):
    settings = load_settings(None, {"strategy": "1", "colors": "3", **{k: str(v) for k, v in overrides.items()}})
    design = load_design(DOGBONE)
    out = tmp_path / "dogbone.gcode"
    result = slice_to_gcode(design, settings, out, jobs=1)
    program = read_gcode(out)
    offset = np.array(read_header(out).placement_offset)
    return design, settings, program, result.stats, offset


def _part_moves(program):
    roles = np.array(program.roles + [""], dtype=object)[program.role]
    printing = (program.e > 0) & (program.length > 0)
    return printing & ~np.isin(roles, ["Wipe tower", "Skirt/Brim"]), roles


@pytest.mark.parametrize("zipper", [0, 10])
def test_dogbone_colors_follow_the_gradient(tmp_path, zipper):
    design, settings, program, stats, offset = _slice(tmp_path, zipper=zipper)
    part, _ = _part_moves(program)
    palette = Palette(2, 3)
    mid = (program.start[part] + program.end[part]) / 2 - offset
    mid[:, 2] -= settings.layer_height / 2
    fractions = design.fractions(mid[:, 0], mid[:, 1], mid[:, 2])
    expected = palette.color_of(fractions)
    commanded = program.color_of_moves()[part]
    neighbor = palette.zipper_neighbor(fractions, zipper)
    ok = (commanded == expected) | ((neighbor >= 0) & (commanded == neighbor))
    # segments whose two ends lie in different bins straddle a cut: judged by their midpoint
    assert ok.mean() > 0.995, f"{(~ok).sum()} of {len(ok)} segments in the wrong color"
    in_band = neighbor >= 0
    if zipper:
        assert in_band.any()
        assert (commanded[in_band] == neighbor[in_band]).any(), "zipper bands use both colors"
        assert (commanded[in_band] == expected[in_band]).any()
    else:
        assert not in_band.any()
    assert stats["layers"] == 8  # 1.5 mm at 0.2 mm: mid-planes inside the part


def test_dogbone_tower_is_beside_the_part_on_every_layer(tmp_path):
    _, settings, program, stats, _ = _slice(tmp_path, walls=2, top_layers=2, bottom_layers=2)
    part, roles = _part_moves(program)
    tower = (roles == "Wipe tower") & (program.e > 0) & (program.length > 0)
    tower_pts = np.vstack([program.start[tower][:, :2], program.end[tower][:, :2]])
    part_pts = np.vstack([program.start[part][:, :2], program.end[part][:, :2]])
    tower_box = shapely.box(*tower_pts.min(axis=0), *tower_pts.max(axis=0))
    part_hull = shapely.MultiPoint(part_pts).convex_hull
    assert not tower_box.intersects(part_hull)
    assert tower_pts.min() >= 0 and tower_pts[:, 0].max() <= settings.bed_x and tower_pts[:, 1].max() <= settings.bed_y
    assert set(program.layer[tower]) == set(range(stats["layers"]))
    assert stats["purge_mm3"] > 0 and 0 < stats["purge_waste_share"] < 1


def test_dogbone_skins_and_walls(tmp_path):
    _, _, program, stats, _ = _slice(tmp_path, walls=2, top_layers=2, bottom_layers=2, infill_density=20)
    part, roles = _part_moves(program)
    layers = program.layer[part]
    solid = np.isin(roles[part], ["Solid infill", "Top solid infill"])
    sparse = roles[part] == "Internal infill"
    solid_layers = set(layers[solid])
    assert {0, 1, 6, 7} <= solid_layers  # two bottom and two top layers are solid
    assert not (set(layers[sparse]) & {0, 1, 6, 7})
    assert set(layers[sparse]) == {2, 3, 4, 5}
    external = roles[part] == "External perimeter"
    assert set(layers[external]) == set(range(8))


@pytest.mark.parametrize("colors", [3, 48])
def test_purge_tower_bound_is_the_largest_color_count_of_any_layer(tmp_path, colors):
    """The tower is sized by the most colors any layer spans: the full pass gives that
    maximum; at 3 colors the ball (fractions 0.42-0.58) lies in the middle color only."""
    from fgslice.pipeline import SliceJob, _colors_in_outline, _max_colors_per_layer, _section_task
    from fgslice.slicing.plan_layers import layer_heights, place_design

    path = tmp_path / "ball.vcad"
    path.write_text('fgrade(["(x+60)/120", "1-(x+60)/120"], ["blue", "yellow"]) { translate(0, 0, 10) { sphere(10); } }\n')
    design = load_design(path)
    settings = load_settings(None, {"strategy": "1", "colors": str(colors)})
    job = SliceJob(design, settings, Palette(2, colors), place_design(design, settings), layer_heights(design, settings),
                   np.zeros(2))
    job.outlines = _section_task(job, range(len(job.layers)))
    each = [_colors_in_outline(job, i) for i in range(len(job.layers))]
    assert len(set(each)) > 1 or colors == 3
    assert _max_colors_per_layer(job, 1, None) == max(each)
    palette = Palette(2, colors)
    for i, outline in enumerate(job.outlines):  # no layer holds more colors than its bound
        xy = shapely.get_coordinates(outline) - np.array(job.placement.offset[:2])
        f0 = (xy[:, 0] + 60) / 120
        held = palette.color_of(np.c_[f0, 1 - f0])
        assert held.max() - held.min() + 1 <= each[i]
    assert max(each) < colors
    if colors == 3:
        assert max(each) == 1


def _slice_text(tmp_path, text, **overrides):
    path = tmp_path / "part.vcad"
    path.write_text(text)
    settings = load_settings(None, {"strategy": "1", "colors": "4", **{k: str(v) for k, v in overrides.items()}})
    design = load_design(path)
    out = tmp_path / "part.gcode"
    result = slice_to_gcode(design, settings, out, jobs=1)
    program = read_gcode(out)
    roles = np.array(program.roles + [""], dtype=object)[program.role]
    printing = (program.e > 0) & (program.length > 0)
    return program, roles, printing, result.stats


def test_the_tower_of_a_grade_that_ends_at_half_height_ends_with_it(tmp_path):
    """Graded in z up to z = 5 of a 10 mm cylinder: the last state change is below 5 mm,
    so the tower stops there and is sized for one change per layer."""
    program, roles, printing, stats = _slice_text(
        tmp_path, 'fgrade(["min(z/5, 1)", "1 - min(z/5, 1)"], ["blue", "yellow"]) '
        '{ translate(0, 0, 5) { cylinder(8, 10); } }\n')
    tower = printing & (roles == "Wipe tower")
    state = program.state[printing]
    last_change_z = program.end[printing, 2][np.flatnonzero(state[1:] != state[:-1])[-1] + 1]
    assert 3.0 < last_change_z <= 5.0
    assert program.end[tower, 2].max() == pytest.approx(last_change_z)
    assert program.end[printing & (roles != "Wipe tower"), 2].max() == pytest.approx(10.0)
    x, y = program.end[tower, 0], program.end[tower, 1]
    from fgslice.planning.purge import _tower_size, purge_length

    width, depth, _, _ = _tower_size(purge_length(68.5, 0.4, 0.2), 1, 0.4, 1.0)  # one change per layer
    assert x.max() - x.min() < width and y.max() - y.min() < depth


@pytest.mark.parametrize("materials", [2, 3])
def test_a_part_that_never_changes_color_has_no_tower(tmp_path, materials):
    """A uniform mixture (two or three materials, --colors 4): one state for the whole
    print, no state change, no tower."""
    names = ["blue", "yellow", "red"][:materials]
    fractions = ", ".join(f'"{1 / materials}"' for _ in names)
    program, roles, printing, stats = _slice_text(
        tmp_path, f'fgrade([{fractions}], [{", ".join(f"{chr(34)}{n}{chr(34)}" for n in names)}]) '
        '{ translate(0, 0, 2) { rectprism(20, 10, 4); } }\n', colors=4, channels=max(2, materials))
    assert not np.any(printing & (roles == "Wipe tower"))
    assert stats["purge_mm3"] == 0.0 and stats["purge_waste_share"] == 0.0
    assert len(set(program.state[printing & (roles != "Skirt/Brim")].tolist())) == 1


SLAB_WITH_RIM = (
    'fgrade(["0.5", "0.5"], ["blue", "yellow"]) { union() {\n'
    '    translate(0, 0, 2.5) { rectprism(40, 20, 5); }\n'
    '    translate(0, 0, 7.5) { difference() { rectprism(40, 20, 5); rectprism(36, 16, 6); } }\n'
    '} }\n'
)


@pytest.mark.parametrize("anchored", [True, False])
def test_the_band_under_the_rim_is_solid_on_the_slabs_top_layers(tmp_path, anchored):
    """40 x 20 x 5 mm slab with a 2 mm rim from z 5 to 10: on the slab's top 3 layers the
    band inside the walls under the rim (0.74-2 mm from the edge) is covered by the
    layers above and below, yet too narrow for sparse lines; anchored skins fill it."""
    overrides = {} if anchored else {"skin_margin": 0, "sparse_min_width": 0}
    program, roles, printing, _ = _slice_text(tmp_path, SLAB_WITH_RIM, **overrides)
    offset = np.array(read_header(tmp_path / "part.gcode").placement_offset)
    box = shapely.box(-20 + offset[0], -10 + offset[1], 20 + offset[0], 10 + offset[1])
    w = 0.4
    inner_edge = w / 2 + (w - 0.2 * (1 - np.pi / 4)) * 1.5  # inside the 2 walls' strips
    band = box.buffer(-inner_edge, join_style="mitre").difference(box.buffer(-2.0, join_style="mitre"))
    area = np.pi * 1.75**2 / 4
    for z in (4.6, 4.8, 5.0):
        layer = printing & np.isclose(program.end[:, 2], z) & np.isin(roles, ["Solid infill", "Top solid infill", "Internal infill"])
        mid = (program.start[layer, :2] + program.end[layer, :2]) / 2
        in_band = shapely.contains_xy(band.buffer(1e-6), mid[:, 0], mid[:, 1])
        filled = program.e[layer][in_band].sum() * area / (band.area * 0.2)  # share of the band's volume
        lines = shapely.multilinestrings([shapely.LineString([a[:2], b[:2]]) for a, b in zip(program.start[layer], program.end[layer])])
        covered = shapely.buffer(lines, 0.3).intersection(band).area / band.area  # nothing wider than a bead left
        if anchored:
            assert covered > 0.99 and filled > 0.85, (z, covered, filled)
            assert not np.any(layer & (roles == "Internal infill"))
        else:
            assert covered < 0.6 and filled < 0.4, (z, covered, filled)
    # the layer's extruded volume against its volume (outline area x h), anchored
    if anchored:
        layer = printing & np.isclose(program.end[:, 2], 5.0) & (roles != "Skirt/Brim") & (roles != "Wipe tower")
        assert program.e[layer].sum() * area == pytest.approx(box.area * 0.2, rel=0.03)


def test_zipper_teeth_across_a_boundary_the_field_only_approaches_fit_the_tower(tmp_path):
    """A uniform 0.49 mixture lies in one color bin, but within the zipper band of the
    boundary at 0.5: the teeth print the color across it, so the tower is sized for the
    two colors of a layer."""
    program, roles, printing, stats = _slice_text(
        tmp_path, 'fgrade(["0.49", "0.51"], ["blue", "yellow"]) { translate(0, 0, 1) { rectprism(20, 10, 2); } }\n',
        zipper=10)
    part = printing & (roles != "Skirt/Brim") & (roles != "Wipe tower")
    assert len(set(program.state[part].tolist())) == 2
    assert stats["purge_mm3"] > 0


@pytest.mark.parametrize("resolution", [0.002, 0.05])
def test_the_outline_is_simplified_to_gcode_resolution(tmp_path, resolution):
    """Strategy 1 simplifies each layer's outline to ``gcode_resolution`` before its walls
    and fills: the solid fill's line ends, which lie on the inner area's boundary (and are
    not simplified again), stay within it of the inner circle, and a coarser resolution
    leaves fewer wall vertices."""
    program, roles, printing, _ = _slice_text(
        tmp_path, 'function((-11, -11, 0), (11, 11, 1), "sqrt(x^2 + y^2) - 10", "blue");\n',
        colors=1, walls=1, infill_density=100, top_layers=0, bottom_layers=0, skirt_loops=0,
        gcode_resolution=resolution)
    offset = np.array(read_header(tmp_path / "part.gcode").placement_offset)
    fill = printing & (roles == "Solid infill")
    ends = np.vstack([program.start[fill, :2], program.end[fill, :2]]) - offset[:2]
    along_lines = np.isclose(program.start[fill, 0] - program.end[fill, 0],
                             program.start[fill, 1] - program.end[fill, 1])  # the 45 degree lines, not links
    radius = np.hypot(*ends[np.r_[along_lines, along_lines]].T)
    settings = load_settings(None, {"walls": "1"})
    s = settings.bead_width - settings.layer_height * (1 - np.pi / 4)
    inner = 10 - settings.bead_width / 2 - s / 2
    section_tolerance = 0.005
    assert np.abs(radius - inner).max() <= resolution + section_tolerance + 1e-6
    walls = printing & (roles == "External perimeter")
    per_layer = walls.sum() / len(program.layer_z)
    if resolution > 0.01:
        assert np.abs(radius - inner).max() > 0.01  # the coarse outline is not the fine one
        assert per_layer < 100
    else:
        assert per_layer > 150
