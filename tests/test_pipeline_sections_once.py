"""Strategy 2 cuts a mesh design's layers once: the layers and the thumbnails share them."""

import trimesh

from fgslice.design import api
from fgslice.design.mesh import MeshGeometry
from fgslice.machine.gcode_reader import read_gcode
from fgslice.pipeline import slice_to_gcode
from fgslice.preview.thumbnails import render_thumbnails
from fgslice.resources import PROBES
from fgslice.settings import load_settings


def test_strategy2_thumbnails_take_the_layers_sections(tmp_path, monkeypatch):
    planes = []
    sections = MeshGeometry.sections
    monkeypatch.setattr(MeshGeometry, "sections", lambda self, zs: planes.extend(zs) or sections(self, zs))
    box = trimesh.creation.box((20, 10, 4))
    box.apply_transform(trimesh.transformations.rotation_matrix(0.5, (1, 0, 0)))
    box.export(tmp_path / "box.stl")
    design = api.design(api.rotate((90, 0, 0), api.mesh(tmp_path / "box.stl")))
    settings = load_settings(None, {"strategy": "2", "colors": "1", "thumbnails": "16x16"})
    out = tmp_path / "box.gcode"
    slice_to_gcode(design, settings, out, jobs=1, thumbnails=lambda layers: render_thumbnails(design, settings, layers=layers))
    layers = len(read_gcode(out).layer_z)
    assert layers > 20
    # every layer cut once, none again for the thumbnails; the resource estimate cuts PROBES planes first
    assert len(planes) == layers + PROBES
    assert b"thumbnail begin 16x16" in out.read_bytes()
