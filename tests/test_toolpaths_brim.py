"""Brim: loops on the first layer only, hugging the part, covering brim_width."""

import numpy as np
import pytest
import shapely

from fgslice.design.language import parse_design
from fgslice.machine.gcode_header import read_header
from fgslice.machine.gcode_reader import read_gcode
from fgslice.pipeline import slice_to_gcode
from fgslice.settings import Settings, load_settings
from fgslice.toolpaths.brim import brim_loops, brim_paths
from fgslice.toolpaths.paths import Role
from fgslice.toolpaths.walls import bead_spacing

# a tall thin pin next to a ring: two islands, one with a hole
DESIGN = """
fgrade(["z/20", "1-z/20"], ["blue", "yellow"]) {
    union() {
        translate(0, 0, 10) { cylinder(2, 20); }
        translate(15, 0, 2) { difference() { cylinder(6, 4); cylinder(3, 5); } }
    }
}
"""


def test_brim_loops_hug_the_islands_and_not_their_holes():
    outline = shapely.MultiPolygon([shapely.box(0, 0, 10, 10), shapely.box(30, 0, 40, 10).difference(shapely.box(33, 3, 37, 7))])
    settings = Settings(brim_width=3.0)
    loops = brim_paths(outline, settings)
    n = brim_loops(settings)
    s = bead_spacing(settings.bead_width, settings.layer_height)
    assert n == round(3.0 / s) and len(loops) == 2 * n
    assert all(p.role is Role.SKIRT and p.color == -1 and p.closed for p in loops)
    distances = sorted({round(float(shapely.distance(shapely.LineString(p.vertices), outline)), 3) for p in loops})
    assert np.allclose(distances, settings.bead_width / 2 + s * np.arange(n), atol=0.01)
    hole = shapely.box(33, 3, 37, 7)
    assert not any(shapely.intersects(shapely.LineString(p.vertices), hole) for p in loops)
    assert brim_paths(outline, Settings()) == []


@pytest.mark.parametrize("width", [0.0, 4.0])
def test_brim_is_printed_on_layer_0_only_and_covers_its_width(tmp_path, width):
    settings = load_settings(None, {"strategy": "1", "colors": "2", "brim_width": str(width)})
    out = tmp_path / "pin.gcode"
    slice_to_gcode(parse_design(DESIGN), settings, out, jobs=1)
    program = read_gcode(out)
    offset = np.array(read_header(out).placement_offset)
    roles = np.array(program.roles + [""], dtype=object)[program.role]
    printing = (program.e > 0) & (program.length > 0)
    skirt = printing & (roles == "Skirt/Brim")
    part = printing & ~np.isin(roles, ["Skirt/Brim", "Wipe tower"]) & (program.layer == 0)
    footprint = shapely.MultiPoint(program.end[part][:, :2]).buffer(0.3)
    mid = (program.start[skirt][:, :2] + program.end[skirt][:, :2]) / 2
    near = shapely.distance(shapely.points(mid), footprint) < width + 1.0
    assert not (near & (program.layer[skirt] > 0)).any()
    brim = near & (program.layer[skirt] == 0)
    if width == 0:
        assert not brim.any()
        return
    # the brim's volume is that of the ring it covers: the islands' outside grown by the
    # loops' extent, the pin a 2 mm disc, the ring 6 mm without its hole
    pin = shapely.Point(offset[0], offset[1]).buffer(2.0, quad_segs=64)
    ring = shapely.Point(offset[0] + 15, offset[1]).buffer(6.0, quad_segs=64)
    islands = shapely.union(pin, ring)
    s = bead_spacing(settings.bead_width, settings.layer_height)
    n = brim_loops(settings)
    extent = n * s + (settings.bead_width - s) / 2
    ring_area = islands.buffer(extent, quad_segs=64).area - islands.area
    volume = program.e[skirt][brim].sum() * np.pi * settings.filament_diameter**2 / 4
    assert volume == pytest.approx(ring_area * settings.layer_height, rel=0.03)
    assert shapely.distance(shapely.points(mid[brim]), islands).max() <= extent


def test_brim_surrounds_the_support_standing_on_the_bed(tmp_path):
    # a T: its stem alone touches the bed, the support under its arms stands beside it
    t = "union() { translate(0,0,4) { rectprism(4, 6, 8); } translate(0,0,9) { rectprism(20, 6, 2); } }"
    settings = load_settings(None, {"colors": "1", "support": "true", "brim_width": "3", "skirt_loops": "0"})
    out = tmp_path / "t.gcode"
    slice_to_gcode(parse_design(t), settings, out, jobs=1)
    program = read_gcode(out)
    roles = np.array(program.roles + [""], dtype=object)[program.role]
    first = (program.e > 0) & (program.length > 0) & (program.layer == 0)
    brim = program.end[first & (roles == "Skirt/Brim")][:, :2]
    support = program.end[first & np.isin(roles, ["Support material", "Support material interface"])][:, :2]
    stem = program.end[first & ~np.isin(roles, ["Skirt/Brim", "Support material", "Support material interface"])][:, :2]
    assert len(support) and len(brim)
    assert np.ptp(support[:, 0]) > 2 * np.ptp(stem[:, 0])  # the support reaches far beyond the stem
    hull = shapely.MultiPoint(brim).convex_hull
    assert shapely.contains_xy(hull, support[:, 0], support[:, 1]).all()
    footprint = shapely.MultiPoint(support).buffer(settings.bead_width)
    assert shapely.distance(shapely.MultiPoint(brim), footprint) < settings.bead_width
    assert (program.layer[(program.e > 0) & (roles == "Skirt/Brim")] == 0).all()
