"""Layer images: bead colors at known bed points against the design's palette bins."""

from __future__ import annotations

import io

import colour
import numpy as np
import pytest
from matplotlib.image import imread

from fgslice.design import api, builtin_library
from fgslice.errors import FgsliceError, GcodeError, OutputError
from fgslice.machine.gcode_reader import read_gcode
from fgslice.pipeline import slice_to_gcode
from fgslice.preview.colors import load_printout
from fgslice.preview.layers import layer_figure, layer_png, nearest_layer, render_layer, render_sheet
from fgslice.settings import load_settings
from fgslice.slicing.palette import Palette

SIZE = (1200, 900)
COLORS = 4


@pytest.fixture(scope="module")
def sliced(tmp_path_factory):
    """A 40 x 20 x 2 mm box graded blue -> yellow along x, strategy 2, 4 colors."""
    design = api.design(api.fgrade(["x/40 + 0.5", "0.5 - x/40"], ["blue", "yellow"], api.rectprism(40, 20, 2)))
    settings = load_settings(None, {"colors": str(COLORS), "skirt_loops": "0", "strategy": "2"})
    out = tmp_path_factory.mktemp("slice") / "box.gcode"
    slice_to_gcode(design, settings, out, jobs=1)
    return design, out


def _pixels(png: bytes) -> np.ndarray:
    return imread(io.BytesIO(png), format="png")


def _expected_rgb(fractions: np.ndarray) -> np.ndarray:
    """sRGB of a blue/yellow mixture mixed in linear light (colour-science's sRGB transfer)."""
    library = builtin_library()
    srgb = np.array([library.get("blue").rgba[:3], library.get("yellow").rgba[:3]])
    return colour.cctf_encoding(fractions @ colour.cctf_decoding(srgb, function="sRGB"), function="sRGB")


def test_bead_pixels_have_the_blended_color_of_their_design_bin(sliced):
    design, out = sliced
    printout = load_printout(out)
    program = printout.program
    layer = 3
    fig, ax = layer_figure(printout, layer, size=SIZE)
    image = _pixels(layer_png(printout, layer, size=SIZE))
    assert image.shape[:2] == (SIZE[1], SIZE[0])
    offset = np.array(printout.info.placement_offset)
    palette = Palette(2, COLORS)
    moves = np.flatnonzero((program.layer == layer) & (program.e > 0) & (program.length > 1.0))
    rng = np.random.default_rng(1)
    checked = 0
    for i in rng.choice(moves, size=min(40, len(moves)), replace=False):
        mid = (program.start[i, :2] + program.end[i, :2]) / 2
        f = design.fractions(np.array([mid[0] - offset[0]]), np.array([mid[1] - offset[1]]), np.array([0.7]))
        color = int(palette.color_of(f)[0])
        if color != program.color_of_moves()[i]:
            continue  # a bead straddling a bin boundary: its color is its face's, not its midpoint's
        px, py = ax.transData.transform(mid)
        rgb = image[int(SIZE[1] - py), int(px), :3]
        assert np.abs(rgb - _expected_rgb(palette.centers[color])).max() < 0.04
        checked += 1
    assert checked >= 20


def test_blank_areas_are_background_and_all_colors_appear(sliced):
    _, out = sliced
    printout = load_printout(out)
    fig, ax = layer_figure(printout, 0, size=SIZE)
    image = _pixels(layer_png(printout, 0, size=SIZE))
    x0, x1 = ax.get_xlim()
    y0, y1 = ax.get_ylim()
    px, py = ax.transData.transform((x0 + 0.5, y0 + 0.5))
    assert np.allclose(image[int(SIZE[1] - py), int(px), :3], 1.0)
    part = image[:, :, :3].reshape(-1, 3)
    for c in Palette(2, COLORS).centers:
        distance = np.abs(part - _expected_rgb(c)).max(axis=1)
        assert (distance < 0.02).sum() > 1000


def test_design_panel_shows_the_continuous_field_at_the_same_scale(sliced, tmp_path):
    design, out = sliced
    printout = load_printout(out)
    size = (1400, 700)
    fig, ax = layer_figure(printout, 2, design=design, show_travel=True, size=size)
    field_ax = fig.axes[1]
    assert field_ax.get_xlim() == ax.get_xlim() and field_ax.get_ylim() == ax.get_ylim()
    target = tmp_path / "layer.png"
    render_layer(printout, 2, target, design=design, show_travel=True, size=size)
    image = imread(target)
    assert image.shape[:2] == (700, 1400)
    offset = np.array(printout.info.placement_offset)
    for x in (-15.0, -3.0, 12.0):
        px, py = field_ax.transData.transform((x + offset[0], 4.0 + offset[1]))
        a = x / 40 + 0.5
        assert np.abs(image[int(size[1] - py), int(px), :3] - _expected_rgb(np.array([a, 1 - a]))).max() < 0.03
    px, py = field_ax.transData.transform((offset[0], 11.5 + offset[1]))
    assert np.allclose(image[int(size[1] - py), int(px), :3], 1.0)


def test_contact_sheet_renders_evenly_spaced_layers(sliced, tmp_path):
    _, out = sliced
    target = tmp_path / "sheet.png"
    layers = render_sheet(out, target, count=4, size=(800, 800))
    assert layers == [0, 3, 6, 9]
    image = imread(target)
    assert image.shape[:2] == (800, 800)
    assert len(np.unique(image[:, :, :3].reshape(-1, 3).round(2), axis=0)) > 10


def test_nearest_layer_by_height(sliced):
    _, out = sliced
    program = read_gcode(out)
    assert nearest_layer(program, 0.79) == 3
    assert nearest_layer(program, 100.0) == 9


def test_missing_layer_is_a_gcode_error(sliced, tmp_path):
    _, out = sliced
    with pytest.raises(GcodeError, match=r"layer 600 does not exist: the file has 10 layers \(0-9\)"):
        render_layer(out, 600, tmp_path / "x.png")
    assert not (tmp_path / "x.png").exists()


def test_missing_output_folder_is_an_output_error(sliced, tmp_path):
    _, out = sliced
    with pytest.raises(OutputError, match="does not exist"):
        render_layer(out, 0, tmp_path / "nowhere" / "x.png")


def test_text_that_is_not_gcode_is_refused(tmp_path):
    source = tmp_path / "part.vcad"
    source.write_text("fgrade([\"x\"], [\"blue\"]) { sphere(5); }\n")
    with pytest.raises(FgsliceError):
        render_layer(source, 0, tmp_path / "x.png")
    binary = tmp_path / "part.bgcode"
    binary.write_bytes(b"GCDE\x00\x01\x02")
    with pytest.raises(GcodeError, match="binary"):
        render_layer(binary, 0, tmp_path / "x.png")


@pytest.mark.parametrize("size", [(1200, 900), (640, 480)])
@pytest.mark.parametrize("profile", ["marlin-mixing", "foam-lwpla"])
def test_the_key_fits_in_the_picture_beside_the_panels(tmp_path, profile, size):
    """Long mixture labels ("red 16.7% / green 16.7% / blue 66.7%") and the colorbar stay
    inside the image, right of the toolpath and design panels."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    if profile == "foam-lwpla":
        grade, materials, sets = ["x/40 + 0.5", "0.5 - x/40"], ["pla", "lwpla"], {"colors": "6"}
    else:
        grade, materials = ["x/80 + 0.25", "0.25", "0.5 - x/80"], ["red", "green", "blue"]
        sets = {"channels": "3", "colors": "9"}
    design = api.design(api.fgrade(grade, materials, api.rectprism(40, 20, 1)))
    out = tmp_path / "long.gcode"
    slice_to_gcode(design, load_settings(profile, {"skirt_loops": "0", "thumbnails": "", **sets}), out, jobs=1)
    fig, ax = layer_figure(out, 2, design=design, size=size)
    renderer = FigureCanvasAgg(fig).get_renderer()
    keys = [legend.get_window_extent(renderer) for legend in fig.legends]
    colorbars = [a for a in fig.axes if a.get_ylabel() == "nozzle target (degC)"]
    keys += [a.get_tightbbox(renderer) for a in colorbars]
    assert len(keys) == 1
    panels_right = max(a.get_window_extent(renderer).x1 for a in fig.axes if a not in colorbars)
    assert panels_right <= keys[0].x0 and keys[0].x1 <= size[0]
    assert 0 <= keys[0].y0 and keys[0].y1 <= size[1]


def test_a_design_without_material_names_previews_in_its_default_gray(tmp_path):
    """A design that names no material has the one material ``default`` (gray); its G-code
    previews without a materials file, its beads in that gray."""
    out = tmp_path / "plain.gcode"
    settings = load_settings(None, {"skirt_loops": "0"})
    slice_to_gcode(api.design(api.rectprism(20, 20, 2)), settings, out, jobs=1)
    pixels = _pixels(layer_png(out, 1, size=SIZE))[..., :3]
    gray = np.all(np.abs(pixels - 0.5) < 0.02, axis=-1)
    fig, ax = layer_figure(out, 1, size=SIZE)
    (x0, y0), (x1, y1) = ax.transData.transform([(0.0, 0.0), (20.0, 20.0)])  # the part's size in pixels
    assert gray.sum() > 0.3 * (x1 - x0) * (y1 - y0)
