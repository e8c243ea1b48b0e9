"""The HTML report: one self-contained file holding every section."""

from __future__ import annotations

import base64
import io

import lxml.html
import numpy as np
import pytest
from PIL import Image

from fgslice.analysis.fidelity import fidelity, simulation_stats
from fgslice.analysis.simulate import simulate
from fgslice.design import api
from fgslice.errors import OutputError
from fgslice.machine.dialects import make_dialect
from fgslice.machine.gcode_reader import read_gcode
from fgslice.pipeline import slice_to_gcode
from fgslice.preview.report import write_report
from fgslice.settings import load_settings
from fgslice.slicing.palette import Palette

SECTIONS = ("design", "statistics", "warnings", "sheet", "palette", "fidelity", "settings")


@pytest.fixture(scope="module")
def sliced(tmp_path_factory):
    design = api.design(api.fgrade(["x/30 + 0.5", "0.5 - x/30"], ["blue", "yellow"], api.rectprism(30, 14, 1.2)))
    settings = load_settings(None, {"colors": "5", "skirt_loops": "0"})
    out = tmp_path_factory.mktemp("slice") / "part.gcode"
    result = slice_to_gcode(design, settings, out, jobs=1)
    return design, settings, out, result.stats


def test_report_is_one_self_contained_html_file(sliced, tmp_path):
    design, settings, out, stats = sliced
    palette = Palette(2, settings.colors)
    result = simulate(out, design, None, settings)
    fid = simulation_stats(result, fidelity(result))
    folder = tmp_path / "report"
    folder.mkdir()
    target = folder / "report.html"
    stats = dict(stats, warnings=["layer 3: a <tiny> segment"])
    write_report(target, stats=stats, settings=settings, palette=palette, dialect=make_dialect(settings, palette),
                 program=out, design=design, fidelity=fid)
    assert [p.name for p in folder.iterdir()] == ["report.html"]
    text = target.read_text(encoding="utf-8")
    tree = lxml.html.fromstring(text)
    assert {s.get("id") for s in tree.iter("section")} == set(SECTIONS)
    assert "http" not in " ".join(v for el in tree.iter() for k, v in el.attrib.items() if k in ("src", "href"))
    assert not tree.xpath("//link | //script")
    images = tree.xpath("//img")
    assert len(images) == 3
    for img in images:
        src = img.get("src")
        assert src.startswith("data:image/png;base64,")
        Image.open(io.BytesIO(base64.b64decode(src.split(",", 1)[1]))).verify()
    palette_rows = tree.xpath('//section[@id="palette"]//table//tr')
    assert len(palette_rows) == 1 + palette.size
    assert "M165 A" in tree.xpath('string(//section[@id="palette"])')
    swatches = tree.xpath('//section[@id="palette"]//p[@class="order"]/span')
    assert [int(s.get("title")) for s in swatches] == palette.order.tolist()
    assert "a <tiny> segment" in tree.xpath('string(//section[@id="warnings"])')
    statistics = tree.xpath('string(//section[@id="statistics"])')
    assert f"{stats['extruded_mm3'] / 1000:.2f}" in statistics
    assert f"{fid['mean_error']:.4g}" in tree.xpath('string(//section[@id="fidelity"])')
    assert "bead_width" in tree.xpath('string(//section[@id="settings"])')


def test_report_from_a_read_program_without_design(sliced, tmp_path):
    _, settings, out, stats = sliced
    palette = Palette(2, settings.colors)
    target = tmp_path / "r.html"
    write_report(target, stats=stats, settings=settings, palette=palette, dialect=None, program=read_gcode(out))
    tree = lxml.html.fromstring(target.read_text(encoding="utf-8"))
    assert {s.get("id") for s in tree.iter("section")} == set(SECTIONS) - {"design", "fidelity"}
    assert len(tree.xpath('//section[@id="palette"]//span[@class="swatch"]')) == 0
    assert np.all([img.get("src").startswith("data:") for img in tree.xpath("//img")])


def test_report_into_a_missing_folder_is_an_output_error(sliced, tmp_path):
    _, settings, out, stats = sliced
    with pytest.raises(OutputError):
        write_report(tmp_path / "no" / "r.html", stats=stats, settings=settings, palette=Palette(2, settings.colors),
                     dialect=None, program=out)
