"""Design thumbnails: sizes, colors from the design's field, and the round trip through G-code."""

from __future__ import annotations

import base64
import io
import re

import numpy as np
import pytest
import shapely
from PIL import Image

from fgslice.design import api
from fgslice.errors import SettingsError
from fgslice.pipeline import slice_to_gcode
from fgslice.preview.thumbnails import parse_sizes, render_thumbnails, thumbnail_png
from fgslice.settings import load_settings

GRADIENT = api.design(api.fgrade(["x/40 + 0.5", "0.5 - x/40"], ["blue", "yellow"], api.rectprism(40, 20, 4)))


def _rgba(png: bytes) -> np.ndarray:
    return np.asarray(Image.open(io.BytesIO(png)).convert("RGBA"), dtype=float) / 255


def test_parse_sizes():
    assert parse_sizes("16x16, 220X124") == [(16, 16), (220, 124)]
    assert parse_sizes("") == []
    for bad in ("16x", "16*16", "0x10", "5000x10", "16x16,,abc"):
        with pytest.raises(SettingsError):
            parse_sizes(bad)


def test_thumbnails_have_the_requested_sizes_and_are_not_uniform():
    settings = load_settings(None, {"thumbnails": "16x16,220x124"})
    thumbs = render_thumbnails(GRADIENT, settings)
    assert [(w, h) for _, w, h in thumbs] == [(16, 16), (220, 124)]
    for png, w, h in thumbs:
        pixels = _rgba(png)
        assert pixels.shape == (h, w, 4)
        opaque = pixels[pixels[:, :, 3] > 0.99]
        assert 0.05 < len(opaque) / (w * h) < 0.95
        assert opaque[:, :3].std(axis=0).max() > 0.05
    assert np.all(_rgba(thumbs[1][0])[0, 0] == 0)


def test_thumbnail_colors_follow_the_gradient():
    pixels = _rgba(thumbnail_png(GRADIENT, 220, 124))
    opaque = pixels[:, :, 3] > 0.99
    cols = np.flatnonzero(opaque.any(axis=0))
    left = pixels[:, cols[0] : cols[0] + len(cols) // 4][opaque[:, cols[0] : cols[0] + len(cols) // 4]]
    right = pixels[:, cols[-1] - len(cols) // 4 : cols[-1]][opaque[:, cols[-1] - len(cols) // 4 : cols[-1]]]
    # seen from the front right, +x (blue: its fraction is x/40 + 0.5) is on the right of the picture
    blueness = lambda p: float(np.mean(p[:, 2] - p[:, 0]))  # noqa: E731
    assert blueness(right) > blueness(left) + 0.2


def test_thumbnails_embedded_in_gcode_decode_to_pngs(tmp_path):
    settings = load_settings(None, {"colors": "2", "skirt_loops": "0", "thumbnails": "32x24,120x90"})
    design = api.design(api.fgrade(["x/20 + 0.5", "0.5 - x/20"], ["blue", "yellow"], api.rectprism(20, 10, 0.6)))
    out = tmp_path / "part.gcode"
    slice_to_gcode(design, settings, out, jobs=1, thumbnails=tuple(render_thumbnails(design, settings)))
    text = out.read_text()
    blocks = re.findall(r"; thumbnail begin (\d+)x(\d+) (\d+)\n(.*?)\n; thumbnail end", text, re.S)
    assert [(int(w), int(h)) for w, h, _, _ in blocks] == [(32, 24), (120, 90)]
    for w, h, length, body in blocks:
        data = "".join(line[2:] for line in body.splitlines())
        assert len(data) == int(length)
        image = Image.open(io.BytesIO(base64.b64decode(data)))
        assert image.size == (int(w), int(h))
        assert np.asarray(image.convert("RGBA"))[:, :, 3].max() == 255


def test_trilinear_matches_scipy_map_coordinates_with_edges_clamped():
    from scipy.ndimage import map_coordinates

    from fgslice.preview.thumbnails import _trilinear

    rng = np.random.default_rng(3)
    volume = rng.normal(size=(4, 6, 9))
    index = rng.uniform(-3.0, 11.0, size=(3, 2000))
    expected = map_coordinates(volume, index, order=1, mode="nearest")
    assert np.allclose(_trilinear(volume, index), expected, atol=1e-12)


@pytest.mark.parametrize("step", [(1.0, 1.0, 1.0), (1.0, 1.3, 0.7)])
def test_chamfer_distance_bounds_the_euclidean_distance(step):
    from scipy.ndimage import distance_transform_edt

    from fgslice.preview.thumbnails import _chamfer_distance

    step = np.asarray(step)
    mask = np.random.default_rng(5).random((40, 30, 25)) < 0.003
    passes, reach = 4, 15
    chamfer = _chamfer_distance(mask, step, passes)
    exact = distance_transform_edt(~mask, sampling=step)
    assert np.all(chamfer[mask] == 0)
    # never below the true distance (capped at the reach), never more than 25 % above it
    assert np.all(chamfer >= np.minimum(exact, reach * step.min()) - 1e-9)
    assert np.all(chamfer <= 1.25 * exact + 1e-9)
    # a cell `reach` cells from a lone mask cell along an axis gets its exact distance
    lone = np.zeros((2 * reach + 1, 3, 3), dtype=bool)
    lone[0, 1, 1] = True
    assert _chamfer_distance(lone, step, passes)[reach, 1, 1] == pytest.approx(reach * step[0])


def test_thumbnail_from_sections_matches_the_exact_signed_distance_render():
    from fgslice.preview.thumbnails import _Scene, render_image

    holed = api.design(api.fgrade(["x/40 + 0.5", "0.5 - x/40"], ["blue", "yellow"],
                                  api.difference(api.rectprism(40, 20, 12), api.cylinder(6, 20))))
    exact = render_image(holed, 220, 124)
    scene = _Scene(holed)
    scene._exact = False
    from_sections = render_image(holed, 220, 124, scene)
    a, b = exact[..., 3] > 0.5, from_sections[..., 3] > 0.5
    assert a.sum() > 5000
    assert (a == b).mean() > 0.97


def test_thumbnails_do_not_depend_on_how_fast_the_design_evaluates():
    """The same design gives the same PNG bytes however long its signed distance takes
    (a loaded machine, or the thumbnail process running beside the slicing workers)."""
    import time

    class Slow:
        """GRADIENT with a signed distance that takes 10 ms a call."""

        def __getattr__(self, name):
            return getattr(GRADIENT, name)

        def sdf(self, x, y, z):
            time.sleep(0.01)
            return GRADIENT.sdf(x, y, z)

    assert thumbnail_png(Slow(), 48, 32) == thumbnail_png(GRADIENT, 48, 32)


@pytest.mark.parametrize("strategy", ["1", "2"])
def test_thumbnails_of_meshes_drawn_from_the_slice_layers(tmp_path, strategy):
    """The thumbnails get the layer outlines (strategy 1's own; strategy 2 sections a mesh
    design for them): three meshes of one material each are drawn from them with the
    silhouette and the colors of a render from the design's own sections, each body in
    its material's color, without building any mesh's 3-D distance or whole tables."""
    import trimesh

    from fgslice.design.language import parse_design
    from fgslice.preview.thumbnails import _Scene, render_image

    for k, name in enumerate("abc"):
        box = trimesh.creation.box((40, 20, 4))
        box.apply_translation((0, 25 * k, 2))
        box.export(tmp_path / f"mesh_{name}.stl")
    text = 'union() { mesh("mesh_a.stl", "red"); mesh("mesh_b.stl", "green"); mesh("mesh_c.stl", "blue"); }'
    design = parse_design(text, file=tmp_path / "part.vcad")
    settings = load_settings(None, {"strategy": strategy, "channels": "3", "skirt_loops": "0", "thumbnails": "220x124"})
    seen = {}

    def render(layers):
        seen["image"] = render_image(design, 220, 124, _Scene(design, layers))
        return render_thumbnails(design, settings, layers=layers)

    out = tmp_path / "part.gcode"
    slice_to_gcode(design, settings, out, jobs=1, thumbnails=render)
    # (strategy 2's own sections build the whole-mesh tables, before the workers fork)
    tables = ("_distance", "_ray_counters") + (("_whole",) if strategy == "1" else ())
    built = [n for m in design.meshes for n in tables if n in vars(m.geometry)]
    assert built == []
    assert "; thumbnail begin 220x124" in out.read_text()

    drawn = seen["image"]
    reference = render_image(parse_design(text, file=tmp_path / "part.vcad"), 220, 124)  # from sections, exact bodies
    a, b = drawn[..., 3] > 0.5, reference[..., 3] > 0.5
    assert a.sum() > 3000
    assert (a == b).mean() > 0.98
    both = a & b
    assert np.abs(drawn[both][:, :3] - reference[both][:, :3]).max(axis=1).mean() < 0.05
    # every body shows in its own color: the pixel's strongest channel is its material's
    strongest = np.argmax(drawn[a][:, :3], axis=1)
    assert all((strongest == channel).mean() > 0.2 for channel in range(3))


def test_the_view_drawn_from_layers_matches_the_exact_render():
    """Drawn from layer outlines (each pixel shows the highest layer holding its ray), a
    graded ring with a post standing in its hole (an island drawn after the hole it sits
    in) has the silhouette, shading and colors of the render from the exact signed
    distance, the post included."""
    from fgslice.preview.thumbnails import LayerOutlines, _Scene, render_image

    ring = api.union(api.difference(api.cylinder(15, 10), api.cylinder(10, 10)), api.cylinder(4, 10))
    design = api.design(api.fgrade(["x/30 + 0.5", "0.5 - x/30"], ["blue", "yellow"], ring))
    (_, _, z0), (_, _, z1) = design.bounds()
    mid = np.arange(z0 + 0.1, z1, 0.2)
    layers = LayerOutlines(mid=mid + 5.0, height=np.full(len(mid), 0.2), outlines=[
        shapely.affinity.translate(section, 100.0, 50.0) for section in design.sections(list(mid))],
        offset=(100.0, 50.0, 5.0))
    drawn = render_image(design, 220, 124, _Scene(design, layers))
    exact = render_image(design, 220, 124)
    a, b = drawn[..., 3] > 0.5, exact[..., 3] > 0.5
    assert a.sum() > 5000
    assert (a == b).mean() > 0.985
    both = a & b
    assert np.abs(drawn[both][:, :3] - exact[both][:, :3]).max(axis=1).mean() < 0.05
    # the post shows where the ring alone lets the background through, as in the exact render
    hollow = api.design(api.fgrade(["x/30 + 0.5", "0.5 - x/30"], ["blue", "yellow"],
                                   api.difference(api.cylinder(15, 10), api.cylinder(10, 10))))
    post = b & ~(render_image(hollow, 220, 124)[..., 3] > 0.5)
    assert post.sum() > 100
    assert a[post].mean() > 0.97


def test_layers_without_outlines_draw_a_transparent_view():
    """Layers whose outlines are all empty (or the empty parts of some) leave the
    background transparent, with no error; a layer with an outline still shows."""
    from fgslice.preview.thumbnails import LayerOutlines, _Scene, render_image

    def layers(outlines):
        return LayerOutlines(mid=0.1 + 0.2 * np.arange(len(outlines)), height=np.full(len(outlines), 0.2),
                             outlines=outlines, offset=(0.0, 0.0, 0.0))

    empty = [shapely.Polygon(), shapely.MultiPolygon(), shapely.Polygon()]
    assert not render_image(GRADIENT, 40, 30, _Scene(GRADIENT, layers(empty)))[..., 3].any()
    one = [shapely.box(-20, -10, 20, 10), shapely.Polygon(), shapely.MultiPolygon()]
    assert render_image(GRADIENT, 40, 30, _Scene(GRADIENT, layers(one)))[..., 3].sum() > 100
