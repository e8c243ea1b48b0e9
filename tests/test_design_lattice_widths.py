"""Lattices thinner than a bead: OpenVCAD's strut radius read as a radius (volume against
its analytic bounds) and a design made only of struts too thin to print (narrower than
min_feature_size, or than a bead without thin features) refused before slicing, with the
struts' width (fgslice.design.lattice_widths)."""

from __future__ import annotations

import itertools
import math
import textwrap

import numpy as np
import pytest

from fgslice.compat.script import load_script
from fgslice.design.lattice import StrutLattice
from fgslice.design.lattice_widths import thin_lattice
from fgslice.errors import SliceError
from fgslice.pipeline import slice_to_gcode
from fgslice.settings import load_settings

# OpenVCAD-Public's examples/lattices/2_unit_cell_custom.py: a 1 mm cell of 7 struts
# through its centre, its third argument (named strut_diameter there) the radius in
# OpenVCAD's API documentation ("radius (float) - The radius of the struts").
CUSTOM_CELL = """\
import pyvcad as pv
red = pv.default_materials.id("red")
edges = [
    [pv.Vec3(0,0,-0.5), pv.Vec3(0,0,0.5)],
    [pv.Vec3(0,-0.5,0), pv.Vec3(0,0.5,0)],
    [pv.Vec3(-0.5,0,0), pv.Vec3(0.5,0,0)],
    [pv.Vec3(-0.5,-0.5,-0.5), pv.Vec3(0.5,0.5,0.5)],
    [pv.Vec3(-0.5,0.5,-0.5), pv.Vec3(0.5,-0.5,0.5)],
    [pv.Vec3(0.5,-0.5,-0.5), pv.Vec3(-0.5,0.5,0.5)],
    [pv.Vec3(0.5,0.5,-0.5), pv.Vec3(-0.5,-0.5,0.5)],
]
root = pv.GraphLattice(edges, {radius}, red)
"""

# examples/lattices/5_openvcad_text_with_lattice.py with a box in place of the text mesh
TEXT_FILL = """\
import pyvcad as pv
red = pv.default_materials.id("red")
cell = pv.GraphLattice(pv.LatticeType.BodyCenteredCubic, pv.Vec3(1, 1, 1), {radius}, red)
part = pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(40, 20, 10), red)
root = {root}
"""


def script(tmp_path, text, name="part.py", **values):
    path = tmp_path / name
    path.write_text(textwrap.dedent(text.format(**values)))
    return load_script(path)


def layered_volume(design, dz):
    lo, hi = design.bounds()
    zs = np.arange(lo[2] + dz / 2, hi[2], dz)
    return sum(s.area for s in design.sections(list(zs), 0.02)) * dz


def test_the_custom_cell_reads_its_radius_as_a_radius(tmp_path):
    design = script(tmp_path, CUSTOM_CELL, radius=0.1)
    node = design.root
    assert isinstance(node, StrutLattice) and node.beam.constant == 0.1 and len(node.edges) == 7
    r = 0.1
    directions = [(b - a) / np.linalg.norm(b - a) for a, b in node.edges]
    capsules = sum(math.pi * r * r * np.linalg.norm(b - a) + 4 / 3 * math.pi * r**3 for a, b in node.edges)
    # Bonferroni: each pair overlaps within the Steinmetz solid of its two crossing lines
    pairs = sum(16 * r**3 / (3 * math.sqrt(1 - float(u @ v) ** 2)) for u, v in itertools.combinations(directions, 2))
    volume = layered_volume(design, 0.01)
    assert capsules - pairs < volume < capsules  # 0.213 < V < 0.341 mm^3: a diameter of 0.1 gives about 0.08
    np.testing.assert_allclose(design.bounds(), ((-0.6,) * 3, (0.6,) * 3))


def settings(**overrides):
    return load_settings(None, {"colors": "1", "strategy": "2", "thumbnails": "", **overrides})


def test_a_custom_cell_thinner_than_a_bead_is_refused_with_its_width(tmp_path):
    """Without thin features, 0.2 mm struts are narrower than a bead: nothing prints."""
    design = script(tmp_path, CUSTOM_CELL, radius=0.1)
    with pytest.raises(SliceError) as refused:
        slice_to_gcode(design, settings(thin_features="false"), tmp_path / "cell.gcode", jobs=1)
    assert "struts are 0.2 mm across (radius 0.1 mm)" in refused.value.message
    assert "bead_width = 0.4 mm" in refused.value.message
    assert "radius of at least 0.2 mm" in refused.value.hint and "thin_features" in refused.value.hint
    assert not (tmp_path / "cell.gcode").exists()


def test_a_custom_cell_below_min_feature_size_is_refused_naming_it(tmp_path):
    """With thin features (the default), struts narrower than min_feature_size (25 % of
    the 0.4 mm nozzle: 0.1 mm) are refused, naming the setting."""
    design = script(tmp_path, CUSTOM_CELL, radius=0.02)
    with pytest.raises(SliceError) as refused:
        slice_to_gcode(design, settings(), tmp_path / "cell.gcode", jobs=1)
    assert "struts are 0.04 mm across (radius 0.02 mm)" in refused.value.message
    assert "min_feature_size = 25% (0.1 mm)" in refused.value.message
    assert "radius of at least 0.05 mm" in refused.value.hint and "lower min_feature_size" in refused.value.hint
    assert not (tmp_path / "cell.gcode").exists()


def test_a_thin_tiled_fill_is_refused_before_it_is_sliced(tmp_path, monkeypatch):
    design = script(tmp_path, TEXT_FILL, radius=0.1, root="pv.Intersection(False, [pv.Tile(cell), part])")
    monkeypatch.setattr("fgslice.pipeline._prepare_for_workers", lambda: pytest.fail("the fill went on to be sliced"))
    with pytest.raises(SliceError, match=r"struts are 0\.2 mm across"):
        slice_to_gcode(design, settings(thin_features="false"), tmp_path / "fill.gcode", jobs=1)
    assert thin_lattice(design.root, 0.1, dots=True) is None  # at least min_feature_size: it prints


@pytest.mark.parametrize("radius, root, thin", [
    (0.1, "pv.Scale(2, 2, 2, pv.Intersection(False, [pv.Tile(cell), part]))", False),  # 0.4 mm struts once scaled
    (0.1, "pv.Scale(1.5, 1.5, 1.5, pv.Intersection(False, [pv.Tile(cell), part]))", True),
    (0.1, "pv.Union(False, [pv.Intersection(False, [pv.Tile(cell), part]), pv.Sphere(pv.Vec3(0, 0, 0), 3, red)])",
     False),
    (0.2, "pv.Intersection(False, [pv.Tile(cell), part])", False),
])
def test_only_designs_made_of_thin_struts_are_thin(tmp_path, radius, root, thin):
    design = script(tmp_path, TEXT_FILL, radius=radius, root=root)
    found = thin_lattice(design.root, 0.4)
    assert (found is not None) == thin
    if thin:
        assert found.width == pytest.approx(0.3) and found.radius == pytest.approx(0.15)


def test_the_check_agrees_with_what_the_slicer_prints(tmp_path, monkeypatch):
    """Struts of radius 0.19 mm (0.38 mm across) meet in junctions just over a bead wide:
    without thin features the check calls them thin, and sliced anyway no toolpath
    covers any of them."""
    small = "pv.Intersection(False, [pv.Tile(cell), pv.RectPrism(pv.Vec3(0, 0, 0), pv.Vec3(6, 6, 3), red)])"
    design = script(tmp_path, TEXT_FILL, radius=0.19, root=small)
    assert thin_lattice(design.root, 0.4).width == pytest.approx(0.38)
    monkeypatch.setattr("fgslice.pipeline.check_lattice_widths", lambda *args: None)
    with pytest.raises(SliceError, match="narrower than a bead"):
        slice_to_gcode(design, settings(thin_features="false"), tmp_path / "small.gcode", jobs=1)
