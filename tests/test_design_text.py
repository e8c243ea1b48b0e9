"""Text: glyph outlines extruded, extents against the font's own metrics (FreeType)."""

import numpy as np
import pytest
from matplotlib import font_manager
from matplotlib.ft2font import FT2Font, LoadFlags

from fgslice.compat.script import load_script
from fgslice.design.text import LINE_SPACING, font_properties, text, text_region
from fgslice.errors import DesignError


def _glyph_box(char: str, font: str = "Consolas", aspect: str = "regular"):
    """``(xmin, ymin, xmax, ymax)`` of a glyph in em, from FreeType's metrics."""
    face = FT2Font(font_manager.findfont(font_properties(font, aspect)))
    face.set_size(1000, 72)  # 1000 pixels per em
    glyph = face.load_char(ord(char), flags=LoadFlags.NO_HINTING)
    return np.array(glyph.bbox) / 64 / 1000


@pytest.mark.parametrize("char, aspect", [("H", "regular"), ("W", "bold"), ("g", "italic")])
def test_a_glyph_has_the_fonts_proportions(char, aspect):
    x0, y0, x1, y1 = _glyph_box(char, aspect=aspect)
    region = text_region(char, 10.0, "Consolas", aspect)
    bx0, by0, bx1, by1 = region.bounds
    assert by1 - by0 == pytest.approx(10.0, rel=1e-9)
    assert (bx1 - bx0) / (by1 - by0) == pytest.approx((x1 - x0) / (y1 - y0), rel=0.01)
    assert (bx0 + bx1) / 2 == pytest.approx(0.0, abs=1e-9) and (by0 + by1) / 2 == pytest.approx(0.0, abs=1e-9)


def test_lines_stack_at_the_line_spacing_and_the_block_takes_the_height():
    x0, y0, x1, y1 = _glyph_box("H")
    cap = y1 - y0
    region = text_region("H\nH", 20.0, h_align="left", v_align="bottom")
    assert region.bounds[1] == pytest.approx(0.0, abs=1e-9) and region.bounds[3] == pytest.approx(20.0)
    scale = 20.0 / (LINE_SPACING + cap)
    assert len(region.geoms) == 2
    heights = sorted(g.bounds[3] - g.bounds[1] for g in region.geoms)
    assert heights == pytest.approx([cap * scale] * 2, rel=0.01)
    assert region.bounds[0] == pytest.approx(0.0, abs=1e-9)  # left alignment: the ink starts on X = 0


def test_text_is_an_exact_extrusion_with_holes():
    shape = text("O", 10.0, 2.0, "red")
    lo, hi = shape.bounds()
    assert lo[2] == -1.0 and hi[2] == 1.0
    section = shape.section(0.5, 0.1)
    assert section.is_valid and len(section.geoms[0].interiors) == 1
    assert shape.sections([1.5], 0.1)[0].is_empty
    inside = section.representative_point()
    d = shape.sdf(np.array([inside.x, 0.0]), np.array([inside.y, 0.0]), np.array([0.0, 0.0]))
    assert d[0] < 0 < d[1]  # the ring is solid, its centre is the hole


def test_pyvcad_text_as_in_openvcads_custom_text_example(tmp_path):
    path = tmp_path / "custom_text.py"
    path.write_text(
        "import pyvcad as pv\nimport pyvcad_rendering as viz\nmaterials = pv.default_materials\n"
        "text = pv.Text('Welcome to OpenVCAD\\nMAC Lab', 20, 5, materials.id('blue'), pv.FontAspect.Italic, 'Consolas',"
        " pv.HorizontalAlignment.Center, pv.VerticalAlignment.Center)\nviz.Render(text, materials)\n")
    design = load_script(path)
    lo, hi = design.bounds()
    assert hi[1] - lo[1] == pytest.approx(20.0) and hi[2] - lo[2] == pytest.approx(5.0)
    assert [m.name for m in design.materials] == ["blue"]
    assert design.section(0.0).area > 0


def test_text_without_glyphs_is_refused():
    with pytest.raises(DesignError, match="no visible glyph"):
        text_region("  \n ", 5.0)
