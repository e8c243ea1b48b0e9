"""End to end: designs sliced to G-code, checked against the design they came from."""

from __future__ import annotations

import numpy as np
import pytest
import shapely

from fgslice.design import api
from fgslice.machine.gcode_header import read_header
from fgslice.machine.gcode_reader import read_gcode
from fgslice.pipeline import slice_to_gcode
from fgslice.settings import load_settings
from fgslice.slicing.palette import Palette


def _slice(design, tmp_path, profile=None, jobs=1, **overrides):
    settings = load_settings(profile, {k: str(v) for k, v in overrides.items()})
    out = tmp_path / "part.gcode"
    result = slice_to_gcode(design, settings, out, jobs=jobs)
    return settings, read_gcode(out), result.stats, out


def _extruded_volume(program, settings) -> float:
    filament_area = np.pi * settings.filament_diameter**2 / 4
    printing = (program.e > 0) & (program.length > 0)
    return float(program.e[printing].sum() * filament_area)


def _offset(path) -> np.ndarray:
    return np.array(read_header(path).placement_offset)


GRADIENT_X = api.fgrade(["x/40 + 0.5", "0.5 - x/40"], ["blue", "yellow"], api.rectprism(40, 20, 2))


def test_strategy2_box_volume_matches_the_part(tmp_path):
    design = api.design(api.fgrade(["0.5", "0.5"], ["blue", "yellow"], api.rectprism(30, 20, 4)))
    settings, program, stats, _ = _slice(design, tmp_path, colors=2, skirt_loops=0)
    volume = _extruded_volume(program, settings)
    assert volume == pytest.approx(30 * 20 * 4, rel=0.03)
    assert stats["extruded_mm3"] == pytest.approx(volume, rel=1e-3)
    assert stats["layers"] == 20 and len(program.layer_z) == 20
    assert np.allclose(np.diff(program.layer_z), 0.2)


def test_strategy2_cylinder_with_hole_volume(tmp_path):
    ring = api.difference(api.cylinder(15, 3), api.cylinder(6, 3))
    design = api.design(api.fgrade(["rho/15", "1 - rho/15"], ["blue", "yellow"], ring))
    settings, program, _, _ = _slice(design, tmp_path, colors=3, skirt_loops=0)
    expected = np.pi * (15**2 - 6**2) * 3
    assert _extruded_volume(program, settings) == pytest.approx(expected, rel=0.03)


@pytest.mark.parametrize(
    "tree",
    [
        GRADIENT_X,
        api.fgrade(["rho/15", "1 - rho/15"], ["blue", "yellow"], api.difference(api.cylinder(15, 1), api.cylinder(4, 1))),
    ],
    ids=["linear", "radial"],
)
def test_commanded_color_matches_the_design_at_every_segment(tmp_path, tree):
    design = api.design(tree)
    settings, program, _, out = _slice(design, tmp_path, colors=4, skirt_loops=0)
    palette = Palette(2, 4)
    offset = _offset(out)
    moves = (program.e > 0) & (program.length > 0)
    start, end = program.start[moves], program.end[moves]
    mid = (start + end) / 2 - offset
    mid[:, 2] -= settings.layer_height / 2
    expected = palette.color_of(design.fractions(mid[:, 0], mid[:, 1], mid[:, 2]))
    at_start = palette.color_of(design.fractions(*(start - offset - [0, 0, 0.1]).T))
    at_end = palette.color_of(design.fractions(*(end - offset - [0, 0, 0.1]).T))
    inside_one_bin = at_start == at_end
    commanded = program.color_of_moves()[moves]
    assert inside_one_bin.mean() > 0.8
    assert np.array_equal(commanded[inside_one_bin], expected[inside_one_bin])
    assert set(np.unique(commanded)) == set(np.unique(expected))


def test_every_move_stays_on_the_bed(tmp_path):
    settings, program, stats, _ = _slice(api.design(GRADIENT_X), tmp_path, colors=3, strategy=1, walls=2)
    points = np.vstack([program.start, program.end])
    assert points[:, 0].min() >= 0 and points[:, 0].max() <= settings.bed_x
    assert points[:, 1].min() >= 0 and points[:, 1].max() <= settings.bed_y
    assert points[:, 2].min() >= 0 and points[:, 2].max() <= settings.max_z
    (x0, y0, _), (x1, y1, _) = stats["extrusion_bbox"]
    part = shapely.box(x0, y0, x1, y1)
    tower_paths = [r for r in program.roles if r == "Wipe tower"]
    assert tower_paths, "strategy 1 with 3 colors purges on a tower"
    assert part.area > 40 * 20


@pytest.mark.parametrize("strategy", ["1", "2"])
def test_parallel_output_is_byte_identical(tmp_path, monkeypatch, strategy):
    """With workers the thumbnails are rendered in a process of their own: the file,
    thumbnails included, is the same as with one process."""
    from fgslice.preview.thumbnails import render_thumbnails

    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1700000000")
    design = api.design(GRADIENT_X)
    settings = load_settings(None, {"colors": "4", "strategy": strategy, "walls": "2", "thumbnails": "16x16,60x40"})
    one, two = tmp_path / "one.gcode", tmp_path / "two.gcode"
    slice_to_gcode(design, settings, one, jobs=1, thumbnails=lambda layers: render_thumbnails(design, settings, layers=layers))
    slice_to_gcode(design, settings, two, jobs=2, thumbnails=lambda layers: render_thumbnails(design, settings, layers=layers))
    assert b"; thumbnail begin 60x40" in two.read_bytes()
    assert one.read_bytes() == two.read_bytes()


@pytest.mark.parametrize("strategy, suffix", [("1", ".stl"), ("1", ".obj"), ("2", ".stl")])
def test_parallel_output_of_a_mesh_is_byte_identical(tmp_path, monkeypatch, strategy, suffix):
    """A mesh's layers are sectioned in batches (strategy 1, tables of the triangles each
    batch spans), in this process or by the workers, as the probe finds them cheap or
    costly (made to, with ``SERIAL_WORK_S``); or one by one from the whole mesh's tables
    (strategy 2). The file is the same as with one process."""
    import trimesh

    from fgslice import executor
    from fgslice.preview.thumbnails import render_thumbnails

    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1700000000")
    pooled = []
    map_pool = executor._map_pool
    monkeypatch.setattr(executor, "_map_pool", lambda fn, *a: pooled.append(fn.__name__) or map_pool(fn, *a))
    torus = trimesh.creation.torus(major_radius=12.0, minor_radius=4.0, major_sections=40, minor_sections=20)
    torus.apply_transform(trimesh.transformations.rotation_matrix(0.4, (1, 0, 0)))
    path = tmp_path / f"torus{suffix}"
    torus.export(path)
    settings = load_settings(None, {"colors": "4", "strategy": strategy, "walls": "2", "thumbnails": "16x16"})
    one, two = tmp_path / "one.gcode", tmp_path / "two.gcode"
    # a design loaded afresh for each slice: neither finds tables the other built
    three = tmp_path / "three.gcode"
    for out, jobs, serial_work_s in ((one, 1, 60.0), (two, 2, 60.0), (three, 2, 0.0)):
        monkeypatch.setattr(executor, "SERIAL_WORK_S", serial_work_s)
        design = api.design(api.fgrade(["x/40 + 0.5", "0.5 - x/40"], ["blue", "yellow"], api.mesh(path)))
        thumbnails = lambda layers, d=design: render_thumbnails(d, settings, layers=layers)  # noqa: E731
        slice_to_gcode(design, settings, out, jobs=jobs, thumbnails=thumbnails)
    program = read_gcode(two)
    assert len(program.layer_z) > 30
    assert one.read_bytes() == two.read_bytes() == three.read_bytes()
    assert pooled.count("_section_task") == (1 if strategy == "1" else 0)


@pytest.mark.parametrize("jobs", [1, 2])
def test_failing_thumbnails_stop_the_slice_and_write_nothing(tmp_path, jobs):
    """An error while rendering thumbnails (in its own process with workers) reaches the
    caller as itself, and no file is left behind."""
    from fgslice.errors import FieldError

    def render(layers):
        raise FieldError("the field is NaN at (1, 2, 3)", hint="check the expression")

    design = api.design(GRADIENT_X)
    settings = load_settings(None, {"colors": "2"})
    out = tmp_path / "part.gcode"
    with pytest.raises(FieldError, match="NaN at"):
        slice_to_gcode(design, settings, out, jobs=jobs, thumbnails=render)
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize(
    "profile, expected",
    [
        ("marlin-mixing", ["M165 A0.1250 B0.8750", "M165 A0.8750 B0.1250"]),
        ("marlin-mixing-m163", ["M163 S0 P0.1250", "M163 S1 P0.8750", "M164 S0"]),
        ("toolchanger", ["T0", "T3"]),
        ("template-diw", ["M400", "M42 P4 S32", "M42 P4 S223"]),
    ],
)
def test_each_dialect_writes_its_state_commands(tmp_path, profile, expected):
    _, _, _, out = _slice(api.design(GRADIENT_X), tmp_path, profile=profile, colors=4)
    lines = set(out.read_text().splitlines())
    for command in expected:
        assert command in lines, command


def test_temperature_dialect_sets_temperature_and_flow(tmp_path):
    settings, program, _, out = _slice(api.design(GRADIENT_X), tmp_path, profile="foam-lwpla", colors=2)
    text = out.read_text()
    # color 0 holds 25% blue (material A) -> 190 + 35 * 0.75 = 216.25 C, sent in whole degrees
    t = 190 + 35 * 0.75
    assert "M104 S216" in text.splitlines()
    flow = 100 * (8.35479e-6 * t**3 - 5.37075e-3 * t**2 + 1.13374 * t - 77.814)
    flows = [ev.values.get("S") for ev in program.flows]
    assert any(abs(f - flow) <= 0.5 for f in flows)


@pytest.mark.parametrize("jobs", [1, 2])
def test_output_failing_verification_is_refused_and_not_written(tmp_path, jobs):
    """The written file is verified (in a second process that follows it when there are
    workers): a profile whose limits contradict its settings leaves no output."""
    from fgslice.errors import SliceError

    design = api.design(GRADIENT_X)
    settings = load_settings(None, {"colors": "2", "max_bed_temperature": "40", "min_extrude_temperature": "250"})
    out = tmp_path / "part.gcode"
    with pytest.raises(SliceError, match="fails verification") as info:
        slice_to_gcode(design, settings, out, jobs=jobs)
    message = str(info.value)
    assert "M140: bed temperature 60 C is outside 0..40 C" in message
    assert "below min_extrude_temperature 250 C" in message
    assert not out.exists() and not list(tmp_path.iterdir())


def test_a_fault_in_the_last_line_is_found_by_the_process_that_follows_the_file(tmp_path):
    """The verifier reads the file while it is written and what is left at the end: a
    command past the machine's limits in the end G-code (the file's last line) is found."""
    from fgslice.errors import SliceError

    settings = load_settings(None, {"colors": "2", "end_gcode": "M104 S0\nM84\nM104 S999"})
    out = tmp_path / "part.gcode"
    with pytest.raises(SliceError, match="fails verification") as info:
        slice_to_gcode(api.design(GRADIENT_X), settings, out, jobs=2)
    assert "999" in str(info.value) and not out.exists() and not list(tmp_path.iterdir())


def test_thumbnails_of_a_mesh_are_drawn_from_the_layer_outlines(tmp_path):
    """Strategy 1 draws a mesh's thumbnails from the layers it sliced: neither the mesh's
    whole section tables nor its 3-D signed distance are ever built, in the thumbnail
    process (workers) or here, and the file is the one ``--jobs 1`` writes."""
    from datetime import datetime, timezone

    import trimesh

    from fgslice.design.language import parse_design
    from fgslice.errors import FieldError
    from fgslice.preview.thumbnails import render_thumbnails

    box = trimesh.creation.box((20, 10, 3))
    box.apply_translation((0, 0, 1.5))
    box.export(tmp_path / "box.stl")
    outputs = []
    for jobs in (2, 1):
        design = parse_design('mesh("box.stl");', file=tmp_path / "part.vcad")
        settings = load_settings(None, {"strategy": "1", "colors": "1"})
        geometry = design.meshes[0].geometry

        def render(layers):
            thumbs = render_thumbnails(design, settings, [(16, 16)], layers)
            built = {"_whole", "_distance", "_ray_counters"} & set(vars(geometry))
            if built:
                raise FieldError(f"the thumbnails built the mesh's {sorted(built)}")
            return thumbs

        out = tmp_path / f"part{jobs}.gcode"
        slice_to_gcode(design, settings, out, jobs=jobs, thumbnails=render, stamp=datetime(2026, 1, 1, tzinfo=timezone.utc))
        outputs.append(out.read_bytes())
        assert not {"_whole", "_distance", "_ray_counters"} & set(vars(geometry))
    assert outputs[0] == outputs[1]


def test_a_width_is_written_once_while_it_stays_the_same(tmp_path):
    """Strategy 2's concentric loops share one bead width: ``;WIDTH:`` is written when the
    written value changes, not before every loop."""
    _, _, _, out = _slice(api.design(api.rectprism(30, 30, 0.6)), tmp_path, strategy=2)
    widths = [line for line in out.read_text().splitlines() if line.startswith(";WIDTH:")]
    assert widths and all(a != b for a, b in zip(widths, widths[1:]))
    loops = sum(1 for line in out.read_text().splitlines() if line.startswith("G0 "))
    assert loops > 3 * len(widths)
