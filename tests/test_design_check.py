"""check_design: reports on the examples and on designs with known problems."""

import numpy as np
import pytest

from fgslice.design import api, check_design, format_report, load_design
from tests.conftest import EXAMPLES

EXAMPLE_FILES = sorted(p for p in EXAMPLES.glob("*.vcad") if p.name != "benchy.vcad")


@pytest.mark.parametrize("path", EXAMPLE_FILES, ids=lambda p: p.name)
def test_examples_load_and_check_without_problems(path):
    design = load_design(path)
    report = check_design(design, samples=40)
    assert report.usable, report.errors
    assert report.warnings == []
    assert path.read_text().startswith("//")
    for lo, hi in report.fraction_ranges.values():
        assert 0 <= lo <= hi <= 1


@pytest.mark.slow
def test_benchy_example_loads(benchy_path):
    design = load_design(EXAMPLES / "benchy.vcad")
    report = check_design(design, samples=12)
    assert report.usable
    assert [m.name for m in report.materials] == ["blue", "yellow"]
    (x0, y0, z0), (x1, y1, z1) = report.bounds
    assert 40 < z1 - z0 < 60


def test_example_dimensions():
    vase = load_design(EXAMPLES / "vase.vcad")
    np.testing.assert_allclose(vase.bounds(), ((-67.5, -87.5, 0), (67.5, 87.5, 100)))
    top = vase.section(99.99)
    assert top.bounds[2] - top.bounds[0] == pytest.approx(135, abs=0.1)
    palette = load_design(EXAMPLES / "palette.vcad")
    np.testing.assert_allclose(palette.bounds(), ((-67.5, -87.5, 0), (67.5, 87.5, 2)))
    assert palette.section(1).area == pytest.approx(np.pi * 67.5 * 87.5, rel=1e-3)
    dogbone = load_design(EXAMPLES / "dogbone.vcad")
    (x0, y0, z0), (x1, y1, z1) = dogbone.bounds()
    assert (x1 - x0, y1 - y0, z1 - z0) == pytest.approx((165, 19, 1.5), abs=0.02)
    outline = dogbone.section(0.75)
    assert len(outline.geoms) == 1
    widths = [outline.intersection(api_line(x)).length for x in (0.0, 28.0, 40.0, 60.0, -60.0)]
    assert widths[0] == pytest.approx(13) and widths[1] == pytest.approx(13, abs=0.01)
    assert 13 < widths[2] < 19 and widths[3] == pytest.approx(19) and widths[4] == pytest.approx(19)
    f = dogbone.fractions(np.array([-82.0, 0.0, 82.0]), np.zeros(3), np.zeros(3))
    np.testing.assert_allclose(f[:, 0], [0.5 / 165, 0.5, 164.5 / 165])
    cylinder = load_design(EXAMPLES / "cylinder_z_gradient.vcad")
    np.testing.assert_allclose(cylinder.fractions(np.zeros(2), np.zeros(2), np.array([0.0, 70.0])), [[0, 1], [1, 0]])


def api_line(x):
    import shapely

    return shapely.LineString([(x, -20), (x, 20)])


def test_raw_fractions_outside_unit_range_are_reported_with_their_share():
    # the paper's cylinder without the shift: z/70 runs from -0.5 to 0.5, negative on half
    design = api.design(api.fgrade(["z/70", "1-z/70"], ["blue", "yellow"], api.cylinder(15, 70)))
    report = check_design(design, samples=40)
    assert report.usable
    text = " ".join(report.warnings)
    assert "'blue' leaves [0, 1] over 50.0%" in text
    assert "'yellow' leaves [0, 1] over 50.0%" in text


def test_zero_sums_nan_and_empty_designs_are_reported():
    zero = api.design(api.fgrade([lambda x, y, z: 0 * x, lambda x, y, z: x], ["red", "blue"], api.cube(10)))
    assert any("sum to 0 over 50.0%" in w for w in check_design(zero, samples=20).warnings)
    nan = api.design(api.fgrade([lambda x, y, z: np.sqrt(x), "1"], ["red", "blue"], api.cube(10)))
    with np.errstate(invalid="ignore"):
        report = check_design(nan, samples=20)
    assert any("NaN over 50.0%" in w and "treated as 0" in w for w in report.warnings)
    empty = api.design(api.intersection(api.cube(1), api.translate((5, 0, 0), api.cube(1))))
    report = check_design(empty)
    assert not report.usable and "usable: no" in format_report(report)


def test_format_report_lists_materials_box_and_nodes():
    report = check_design(load_design(EXAMPLES / "three_materials.vcad"), samples=30)
    text = format_report(report)
    for words in ("red", "green", "blue", "white", "bounding box", "nodes: 8", "usable: yes"):
        assert words in text
    lo, hi = report.fraction_ranges["white"]
    assert hi == 1.0
