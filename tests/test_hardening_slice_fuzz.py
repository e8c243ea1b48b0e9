"""Property-based slicing of generated designs: every run ends in a clean FgsliceError, or
in G-code that passed verification and whose extruded volume is within 3 % of the part's
sections (strategy 2, which fills every section) or that says why it is not.

The designs mix every node type (primitives, booleans, transforms, grades, blends, meshes
including degenerate ones), small and far-apart parts, fields that are NaN or infinite in
places, and extreme settings (thin and thick beads and layers, palettes of 1-16 colors:
large palettes are covered on a graded bar in ``test_hardening_inputs.py``, since the
handover of slivers can take minutes on some generated layers with hundreds of colors).
Parts are a few millimetres to a few centimetres, so each slice takes well under a
second; the example count keeps the whole test to a few tens of seconds.
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fgslice.design import api
from fgslice.errors import FgsliceError
from fgslice.machine.gcode_reader import read_gcode
from fgslice.pipeline import slice_to_gcode
from fgslice.preview.thumbnails import render_thumbnails
from fgslice.settings import load_settings
from fgslice.slicing.plan_layers import layer_heights, place_design

SLICES = settings(max_examples=8, deadline=None, derandomize=True,
                  suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
VOLUME_SHARE = 0.03

size = st.floats(2.0, 15.0)
position = st.floats(-60.0, 60.0)
angle = st.floats(-180.0, 180.0)
FIELDS = ["x/40 + 0.5", "0.5 + 0.5*sin(x/3)*cos(y/4)", "z/10", "x < 0 ? 1 : 0", "log(x)", "1/x", "y*y/100"]


def _mesh(kind: str, folder) -> api.nodes.Node:
    """A box, a box missing two triangles, a flat mesh, or a mesh of zero-area triangles."""
    box = trimesh.creation.box((8, 6, 4))
    box.apply_translation((0, 0, 2))
    if kind == "box":
        shape = box
    elif kind == "holed":
        shape = trimesh.Trimesh(box.vertices, box.faces[2:], process=False)
    elif kind == "flat":
        shape = trimesh.Trimesh([[0, 0, 0], [10, 0, 0], [0, 10, 0], [10, 10, 0]], [[0, 1, 2], [1, 3, 2]], process=False)
    else:
        shape = trimesh.Trimesh([[0, 0, 0], [5, 0, 0], [10, 0, 0], [0, 0, 3]], [[0, 1, 2], [0, 2, 1], [0, 1, 3]],
                                process=False)
    path = folder / f"{kind}.stl"
    shape.export(path)
    return api.mesh(path)


@st.composite
def shapes(draw, folder, depth=0):
    kinds = ["cube", "rectprism", "sphere", "cylinder", "strut", "function", "mesh"]
    if depth < 1:
        kinds += ["union", "difference", "intersection", "translate", "rotate", "scale", "blend"]
    kind = draw(st.sampled_from(kinds))
    if kind == "cube":
        return api.cube(draw(size))
    if kind == "rectprism":
        return api.rectprism(draw(size), draw(size), draw(st.floats(0.3, 10.0)))
    if kind == "sphere":
        return api.sphere(draw(size) / 2)
    if kind == "cylinder":
        return api.cylinder(draw(st.floats(0.1, 12.0)), draw(size))
    if kind == "strut":
        return api.strut((0, 0, 0), (draw(size), draw(size) / 2, draw(size) / 3), draw(st.floats(0.5, 4.0)))
    if kind == "function":
        r = draw(size) / 2
        expression = draw(st.sampled_from(["x*x + y*y + z*z - {r}", "abs(x) + abs(y) - {r}", "x < 0 ? -1 : 0/0",
                                           "0/0", "max(abs(x), abs(z)) - {r}"]))
        return api.function((-r, -r, -r), (r, r, r), expression.format(r=r * r if "x*x" in expression else r))
    if kind == "mesh":
        return _mesh(draw(st.sampled_from(["box", "holed", "flat", "zero-area"])), folder)
    children = [draw(shapes(folder, depth + 1)) for _ in range(draw(st.integers(1, 3)))]
    if kind in ("union", "intersection"):
        return getattr(api, kind)(*children)
    if kind == "difference":
        return api.difference(*children)
    if kind == "translate":
        return api.translate((draw(position), draw(position), draw(st.floats(-20, 20))), *children)
    if kind == "rotate":
        return api.rotate((draw(angle), draw(angle), draw(angle)), *children)
    if kind == "scale":
        return api.scale((draw(st.floats(0.2, 3)), draw(st.floats(0.2, 3)), draw(st.floats(0.2, 3))), *children)
    return api.blend(draw(st.sampled_from([0.5, 3.0])), *children)


@st.composite
def designs(draw, folder):
    parts = [draw(shapes(folder)) for _ in range(draw(st.integers(1, 2)))]
    if len(parts) > 1 and draw(st.booleans()):  # far apart
        parts = [api.translate((120 * i / (len(parts) - 1) - 60, 0, 0), p) for i, p in enumerate(parts)]
    root = api.union(*parts) if len(parts) > 1 else parts[0]
    if draw(st.booleans()):
        field = draw(st.sampled_from(FIELDS))
        root = api.fgrade([field, f"1 - ({field})"], ["blue", "yellow"], root)
    return api.design(root)


def section_volume(design, settings) -> float:
    """The sections' volume at the layers' mid-planes, mm^3 (what strategy 2 fills)."""
    oz = place_design(design, settings).offset[2]
    layers = layer_heights(design, settings)
    mids = [z - h / 2 - oz for _, z, h in layers]
    return float(sum(s.area * h for s, (_, _, h) in zip(design.sections(mids), layers)))


def extruded_mm3(path, filament_area=np.pi * 1.75**2 / 4) -> float:
    program = read_gcode(path)
    return float(program.e[(program.e > 0) & (program.length > 0)].sum() * filament_area)


@pytest.mark.slow
@given(data=st.data())
@SLICES
def test_generated_designs_slice_to_verified_gcode_or_a_clean_error(tmp_path_factory, data):
    folder = tmp_path_factory.mktemp("fuzz")
    overrides = {
        "strategy": 2, "skirt_loops": 0, "thumbnails": "16x16",
        "colors": data.draw(st.sampled_from([1, 2, 16])),
        "layer_height": data.draw(st.sampled_from([0.1, 0.2, 0.3])),
        "bead_width": data.draw(st.sampled_from([0.3, 0.45, 0.8])),
    }
    out = folder / "part.gcode"
    try:
        design = data.draw(designs(folder))
        settings = load_settings("marlin-mixing", overrides)
        result = slice_to_gcode(design, settings, out, jobs=1,
                                thumbnails=lambda layers: render_thumbnails(design, settings, layers=layers))
    except FgsliceError as error:
        text = error.format()
        assert text.startswith(("error:", design_file_prefix(error))) and "fails verification" not in text, text
        assert not out.exists() and list(folder.glob(".*.part")) == []
        return
    sections = section_volume(design, settings)
    extruded = extruded_mm3(out)
    said = [w for w in result.stats["warnings"] if "-filled" in w or "not printed" in w]
    assert abs(extruded - sections) <= VOLUME_SHARE * sections or said, (extruded, sections, result.stats["warnings"])


def design_file_prefix(error: FgsliceError) -> str:
    return f"{error.location}: error:" if error.location else "error:"
