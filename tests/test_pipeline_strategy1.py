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
    """The tower is sized by the most colors any layer spans: the shortcut through the
    widest layer (capped at 3 colors) and the full pass (48 colors) give that maximum."""
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
    assert (max(each) == colors) == (colors == 3)
