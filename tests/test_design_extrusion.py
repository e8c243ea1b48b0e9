"""OpenVCAD's PolygonExtrude: planar polygons extruded along their normal."""

import math
import textwrap

import numpy as np
import pytest

from fgslice.compat.script import load_script
from fgslice.design.extrusion import polygon_extrude
from fgslice.design.nodes import NodeDesign
from fgslice.errors import DesignError

HEADER = "import pyvcad as pv\nimport pyvcad_rendering as viz\nimport math\nmaterials = pv.default_materials\n"


def test_the_hexagon_demo_is_a_prism_of_the_hexagons_area(tmp_path):
    """polygon_extrude_demo: a regular hexagon of radius 10 extruded 10 mm up."""
    path = tmp_path / "hexagon.py"
    path.write_text(HEADER + textwrap.dedent("""
        vertices = [pv.Vec3(10 * math.cos(2 * math.pi * i / 6), 10 * math.sin(2 * math.pi * i / 6), 0) for i in range(6)]
        root = pv.PolygonExtrude(vertices, 10.0, False, materials.id("blue"))
        viz.Render(root, materials)
        """))
    design = load_script(path)
    lo, hi = design.bounds()
    assert lo[2] == pytest.approx(0.0) and hi[2] == pytest.approx(10.0)
    assert hi[0] - lo[0] == pytest.approx(20.0)
    section = design.section(5.0)
    assert section.area == pytest.approx(1.5 * math.sqrt(3) * 100, rel=1e-9)
    assert design.sdf(np.array([0.0]), np.array([0.0]), np.array([5.0]))[0] == pytest.approx(-5.0)


def test_the_two_triangles_form_a_tilted_slab_of_their_area(tmp_path):
    """polygon_extrude_two_triangles: triangles with a corner 1 mm below the others lie in
    tilted planes; each extrusion's volume is its area times the height."""
    tri = [(0, 0, -1), (10, 0, 0), (0, 10, 0)]
    shape = NodeDesign(polygon_extrude(tri, 2.0, False, "red"))
    a, b, c = (np.array(p, dtype=float) for p in tri)
    area = np.linalg.norm(np.cross(b - a, c - a)) / 2
    lo, hi = np.array(shape.bounds())
    zs = np.arange(lo[2] + 0.025, hi[2], 0.05)
    volume = sum(s.area for s in shape.sections(zs, 0.05)) * 0.05
    assert volume == pytest.approx(area * 2.0, rel=0.02)


def test_bad_polygons_are_refused_by_name():
    with pytest.raises(DesignError, match="collinear"):
        polygon_extrude([(0, 0, 0), (1, 0, 0), (2, 0, 0)], 1.0)
    with pytest.raises(DesignError, match="not coplanar"):
        polygon_extrude([(0, 0, 0), (10, 0, 0), (10, 10, 0), (0, 10, 3)], 1.0)
