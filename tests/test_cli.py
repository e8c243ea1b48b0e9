"""The command line: a usable summary on success, one clear message and no file on error."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from fgslice.cli import main

BOX = 'fgrade(["x/40 + 0.5", "0.5 - x/40"], ["blue", "yellow"]) { rectprism(40, 20, 1); }\n'


@pytest.fixture
def design(tmp_path):
    path = tmp_path / "box.vcad"
    path.write_text(BOX, encoding="utf-8")
    return path


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def test_slice_writes_gcode_stats_and_a_summary(design, tmp_path):
    out, stats = tmp_path / "box.gcode", tmp_path / "box.json"
    result = run("slice", design, "-o", out, "--colors", "3", "--stats", stats, "--jobs", "1")
    assert result.exit_code == 0, result.output
    assert "5 layers, 3 colors" in result.output
    data = json.loads(stats.read_text())
    for key in ("layers", "colors", "extruded_mm3", "extruded_mm3_by_color", "travel_mm", "state_changes",
                "estimated_time_s", "extrusion_bbox", "warnings", "elapsed_s"):
        assert key in data
    assert data["layers"] == 5 and data["colors"] == 3
    assert sum(float(v) for v in data["extruded_mm3_by_color"].values()) == pytest.approx(data["extruded_mm3"], rel=0.02)


def test_slice_summary_gives_the_tower_and_with_model_purges_the_simulated_share(design, tmp_path):
    out, stats = tmp_path / "box.gcode", tmp_path / "box.json"
    result = run("slice", design, "-o", out, "--strategy", "1", "--colors", "3", "--set", "purge_size=model",
                 "--stats", stats, "--jobs", "1")
    assert result.exit_code == 0, result.output
    data = json.loads(stats.read_text())
    summary = result.output.strip().splitlines()[-1]
    assert f"tower {data['tower_mm3'] / 1000:.2f} cm3 / {data['tower_g']:.1f} g" in summary
    assert f"({data['simulated_within_half_bin']:.1%} of the part simulated within half a bin)" in summary
    assert data["tower_mm3"] > data["purge_mm3"] > 0


@pytest.mark.parametrize(
    "args, words",
    [
        (["--profile", "nonesuch"], "unknown profile"),
        (["--set", "wals=2"], "did you mean 'walls'"),
        (["--set", "layer_height=-1"], "layer_height"),
        (["--profile", "toolchanger", "--colors", "8"], "tool"),
        (["--set", "bed_x=30"], "bed"),
        (["--layer-height", "1.5", "--set", "bead_width=2"], "max_cross_section_mm2"),
    ],
)
def test_bad_input_fails_cleanly_without_output(design, tmp_path, args, words):
    out = tmp_path / "out.gcode"
    result = run("slice", design, "-o", out, "--jobs", "1", *args)
    assert result.exit_code == 2, result.output
    assert words in result.output
    assert "Traceback" not in result.output
    assert not out.exists()
    assert not list(tmp_path.glob(".out.gcode*")), "no temporary file is left behind"


def test_a_design_thinner_than_half_a_layer_has_no_layers(tmp_path):
    path = tmp_path / "thin.vcad"
    path.write_text('rectprism(20, 20, 0.08, "red")\n', encoding="utf-8")
    out = tmp_path / "thin.gcode"
    result = run("slice", path, "-o", out)
    assert result.exit_code == 2 and "no layers" in result.output
    assert not out.exists()


def test_unwritable_output_and_input_overwrite_are_refused(design, tmp_path):
    result = run("slice", design, "-o", tmp_path / "missing" / "x.gcode")
    assert result.exit_code == 2 and "does not exist" in result.output
    result = run("slice", design, "-o", design)
    assert result.exit_code == 2 and "input" in result.output
    assert design.read_text() == BOX


def test_existing_output_survives_a_failed_slice(design, tmp_path):
    out = tmp_path / "keep.gcode"
    out.write_text("old", encoding="utf-8")
    result = run("slice", design, "-o", out, "--set", "bed_x=10")
    assert result.exit_code == 2
    assert out.read_text() == "old"


def test_syntax_error_shows_file_line_column_and_caret(tmp_path):
    path = tmp_path / "bad.vcad"
    path.write_text('union() {\n  sphere(1;\n}\n', encoding="utf-8")
    result = run("slice", path, "-o", tmp_path / "bad.gcode")
    assert result.exit_code == 2
    assert f"{path}:2:" in result.output and "^" in result.output


def test_profiles_and_check(design):
    result = run("profiles")
    assert result.exit_code == 0
    for name in ("marlin-mixing", "marlin-mixing-m163", "toolchanger", "foam-lwpla", "foam-tpu", "template-diw"):
        assert name in result.output
    result = run("check", design)
    assert result.exit_code == 0, result.output
    assert "blue" in result.output and "yellow" in result.output


def test_profile_keys_show_the_values_the_profile_slices_with(tmp_path):
    from fgslice.settings import load_settings

    def shown(*args):
        result = run("profiles", "--keys", *args)
        assert result.exit_code == 0, result.output
        return dict(line.split("  # ")[0].split(" = ", 1) for line in result.output.splitlines())

    assert shown()["bed_x"] == repr(load_settings("marlin-mixing").bed_x) == "255.0"
    toolchanger = shown("--profile", "toolchanger")
    assert toolchanger["dialect"] == "'toolchanger'" and toolchanger["bed_x"] == "360.0"
    assert "bed width, mm (default 220.0)" in run("profiles", "--keys", "--profile", "toolchanger").output
    mine = tmp_path / "mine.toml"
    mine.write_text('inherits = "toolchanger"\ntool_count = 3\n', encoding="utf-8")
    values = shown("--profile", mine)
    settings = load_settings(str(mine))
    assert values == {name: repr(value) for name, value in settings.as_dict().items()}
    assert values["tool_count"] == "3" and values["bed_y"] == "360.0" and values["profile_name"] == "'mine'"
    result = run("profiles", "--keys", "--profile", "nonesuch")
    assert result.exit_code == 2 and "unknown profile 'nonesuch'" in result.output


def test_verify_passes_our_output_and_flags_a_broken_file(design, tmp_path):
    out = tmp_path / "box.gcode"
    assert run("slice", design, "-o", out, "--jobs", "1").exit_code == 0
    assert run("verify", out).exit_code == 0
    broken = tmp_path / "broken.gcode"
    broken.write_text(out.read_text() + "G1 X999 Y10 E1\n", encoding="utf-8")
    result = run("verify", broken)
    assert result.exit_code == 1 and "line" in result.output


def test_simulate_reports_fidelity_and_writes_stats_and_png(design, tmp_path):
    out = tmp_path / "box.gcode"
    assert run("slice", design, "-o", out, "--colors", "4", "--jobs", "1").exit_code == 0
    stats, png = tmp_path / "sim.json", tmp_path / "sim.png"
    result = run("simulate", out, "--design", design, "--stats", stats, "--png", png)
    assert result.exit_code == 0, result.output
    data = json.loads(stats.read_text())
    assert 0 <= data["mean_error"] <= data["p95_error"] <= 1
    assert data["palette_size"] == 4
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    off = data["transition"]["off_color_mm3"]
    line = next(x for x in result.output.splitlines() if x.startswith("transition material"))
    assert all(f"{k} {v:.1f}" in line for k, v in off.items() if v >= 0.05)


def test_calibrate_lookahead_from_measurement_and_volume(tmp_path):
    result = run("calibrate", "lookahead", "--measured-error", "19", "--segment-length", "20")
    assert result.exit_code == 0
    assert result.output.strip().splitlines()[-1] == "--set lookahead_mm=960.0"  # ceil(19 / 0.4) * 20
    result = run("calibrate", "lookahead", "--melt-volume", "68.5")
    assert "--set lookahead_mm=959.2" in result.output  # 68.5 / (0.2 * 0.2 + pi 0.2^2 / 4)
    out = tmp_path / "cal.gcode"
    result = run("calibrate", "lookahead", "-o", out)
    assert result.exit_code == 0 and out.exists()
    assert run("verify", out).exit_code == 0


def test_slice_embeds_thumbnails_and_writes_a_report(design, tmp_path):
    out, report = tmp_path / "box.gcode", tmp_path / "box.html"
    result = run("slice", design, "-o", out, "--colors", "3", "--jobs", "1", "--report", report)
    assert result.exit_code == 0, result.output
    text = out.read_text()
    assert "; thumbnail begin 16x16" in text and "; thumbnail begin 220x124" in text
    html = report.read_text()
    assert "<html" in html.lower() and "data:image/png;base64," in html


def test_slice_without_thumbnails_starts_no_thumbnail_process(design, tmp_path, monkeypatch):
    import fgslice.pipeline

    started = []
    monkeypatch.setattr(fgslice.pipeline, "_start_thumbnails", lambda *args: started.append(args))
    out = tmp_path / "box.gcode"
    result = run("slice", design, "-o", out, "--colors", "3", "--jobs", "2", "--set", "thumbnails=")
    assert result.exit_code == 0, result.output
    assert started == [] and "; thumbnail begin" not in out.read_text()


def test_preview_draws_a_layer_a_sheet_and_refuses_a_missing_layer(design, tmp_path):
    out = tmp_path / "box.gcode"
    assert run("slice", design, "-o", out, "--colors", "3", "--jobs", "1").exit_code == 0
    png = tmp_path / "layer.png"
    result = run("preview", out, "-o", png, "--z", "0.6", "--design", design)
    assert result.exit_code == 0 and "layer 2" in result.output
    assert png.read_bytes()[:4] == b"\x89PNG"
    result = run("preview", out, "-o", tmp_path / "sheet.png", "--sheet", "4")
    assert result.exit_code == 0
    result = run("preview", out, "-o", tmp_path / "x.png", "--layer", "99")
    assert result.exit_code == 2 and "does not exist" in result.output
    result = run("preview", design, "-o", tmp_path / "y.png")
    assert result.exit_code == 2 and "Traceback" not in result.output


def test_sweep_writes_one_slice_per_combination_and_a_summary(design, tmp_path):
    out = tmp_path / "sweep"
    result = run("sweep", design, "-o", out, "--colors", "2,3", "--zipper", "0,10", "--strategy", "1", "--jobs", "1")
    assert result.exit_code == 0, result.output
    names = sorted(p.name for p in out.glob("*.gcode"))
    assert names == ["box_c2_z0_s1.gcode", "box_c2_z10_s1.gcode", "box_c3_z0_s1.gcode", "box_c3_z10_s1.gcode"]
    rows = (out / "summary.csv").read_text().splitlines()
    assert len(rows) == 5
    stats = json.loads((out / "box_c3_z10_s1.json").read_text())
    assert stats["colors"] == 3
    result = run("sweep", design, "-o", out, "--colors", "4,x")
    assert result.exit_code == 2 and "comma-separated" in result.output


def _program(*args, python_options=()):
    """The real program (``python -m fgslice.cli``, as the console script runs it), with
    stdout and stderr piped, so that only what was flushed before it exited arrives;
    ``python_options`` go to the interpreter."""
    import subprocess
    import sys

    return subprocess.run([sys.executable, *python_options, "-m", "fgslice.cli", *map(str, args)],
                          capture_output=True, text=True, timeout=120)


def test_program_exits_with_everything_written_and_flushed(design, tmp_path):
    """The program skips the interpreter's teardown: the G-code, the statistics, the
    summary on stdout and the warnings on stderr must all be complete before it does."""
    from fgslice.machine.verify import verify_gcode
    from fgslice.settings import load_settings

    out, stats = tmp_path / "box.gcode", tmp_path / "box.json"
    done = _program("slice", design, "-o", out, "--colors", "3", "--stats", stats, "--jobs", "2",
                    "--strategy", "1", "--set", "min_segment_mm=50")
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith(f"{out}: ") and done.stdout.endswith("\n")
    assert "warning:" in done.stderr and "min_segment_mm = 50" in done.stderr
    assert json.loads(stats.read_text())["layers"] == 5
    text = out.read_text()
    assert text.rstrip().splitlines()[-1].startswith("; ") and "; filament used [mm] = " in text
    assert verify_gcode(out, load_settings(None, {})) == []
    assert sorted(p.name for p in tmp_path.iterdir()) == ["box.gcode", "box.json", "box.vcad"]


def test_program_exit_status_of_errors_and_of_click_usage(design, tmp_path):
    bad = _program("slice", design, "-o", tmp_path / "box.gcode", "--set", "walls=-1")
    assert bad.returncode == 2 and "walls" in bad.stderr and not (tmp_path / "box.gcode").exists()
    usage = _program("slice")
    assert usage.returncode == 2 and "Missing argument" in usage.stderr
    assert _program("--version").returncode == 0


_THREADS_AFTER_NUMPY = """
import os, sys
from fgslice import cli

class Probe:
    commands = cli.main.commands

    def __call__(self):
        import numpy  # noqa: F401
        print(os.environ.get("OPENBLAS_NUM_THREADS", "unset"), len(os.listdir("/proc/self/task")))
        sys.exit(0)

cli.main = Probe()
sys.argv = ["fgslice", "slice"]
cli.run()
"""


@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="threads are counted in /proc")
def test_program_runs_numpy_single_threaded_unless_told_otherwise():
    """numpy's BLAS would start a thread pool competing with the worker processes; the
    program limits it to one thread, and an explicit OPENBLAS_NUM_THREADS wins."""
    import os
    import subprocess
    import sys

    def threads(env):
        done = subprocess.run([sys.executable, "-c", _THREADS_AFTER_NUMPY], capture_output=True, text=True,
                              timeout=60, env=env)
        assert done.returncode == 0, done.stderr
        return done.stdout.split()

    env = {k: v for k, v in os.environ.items() if k not in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS")}
    assert threads(env) == ["1", "1"]
    if (os.cpu_count() or 1) >= 2:
        assert threads({**env, "OPENBLAS_NUM_THREADS": "2"}) == ["2", "2"]


def test_program_under_a_profiler_exits_normally_so_it_saves_its_data(design, tmp_path):
    import subprocess
    import sys

    prof = tmp_path / "slice.prof"
    done = subprocess.run([sys.executable, "-m", "cProfile", "-o", str(prof), "-m", "fgslice.cli", "slice", str(design),
                           "-o", str(tmp_path / "box.gcode"), "--jobs", "1"], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert prof.stat().st_size > 0


def test_the_version_printed_and_written_in_headers_is_the_installed_packages(design, tmp_path):
    from importlib import metadata

    installed = metadata.version("fgslice")
    assert _program("--version").stdout.strip() == f"fgslice, version {installed}"
    out = tmp_path / "box.gcode"
    assert _program("slice", design, "-o", out).returncode == 0
    assert out.read_text().splitlines()[0].startswith(f"; generated by fgslice {installed} on ")


def _imports_of_program(*args) -> list[tuple[int, str]]:
    """``(nesting depth, module)`` of every import the program makes, in the order they
    finish (``python -X importtime``: depth 0 is an import made by the program's own code
    rather than by another module's import)."""
    done = _program(*args, python_options=("-X", "importtime"))
    assert done.returncode == 0, done.stderr
    imports = []
    for line in done.stderr.splitlines():
        if line.startswith("import time:") and not line.rstrip().endswith("imported package"):
            name = line.rsplit("|", 1)[1]
            imports.append(((len(name) - len(name.lstrip()) - 1) // 2, name.strip()))
    return imports


def test_commands_import_numpy_first_and_help_does_without_it(design):
    """numpy's own import makes thousands of short nested calls: imported from deep in a
    command it crossed one of CPython's frame-chunk boundaries again and again (one
    mmap/munmap pair each time, 35-45 ms per command), so the program imports it at the
    bottom of the stack before the command runs. Help and version need none of it."""
    for args in (("--version",), ("--help",)):
        assert not [name for _, name in _imports_of_program(*args) if name.split(".")[0] == "numpy"]
    imports = _imports_of_program("check", design)
    assert [depth for depth, name in imports if name == "numpy"] == [0]
    names = [name for _, name in imports]
    assert names.index("numpy") < names.index("fgslice.design")


def test_preview_reads_the_header_materials_from_the_materials_file(tmp_path):
    library = tmp_path / "vtp.json"
    library.write_text(json.dumps({"materials": [{"name": "state_a", "r": 255, "g": 0, "b": 0},
                                                 {"name": "state_b", "r": 0, "g": 0, "b": 255}]}))
    design = tmp_path / "states.vcad"
    design.write_text('union() { translate(-5, 0, 0) { rectprism(10, 10, 1, "state_a"); }\n'
                      '  translate(5, 0, 0) { rectprism(10, 10, 1, "state_b"); } }\n')
    out, png = tmp_path / "states.gcode", tmp_path / "states.png"
    assert run("slice", design, "-o", out, "--materials", library, "--colors", "2", "--jobs", "1").exit_code == 0
    result = run("preview", out, "-o", png)
    assert result.exit_code == 2 and "unknown material 'state_a'" in result.output and "--materials" in result.output
    assert not png.exists()
    result = run("preview", out, "-o", png, "--materials", library)
    assert result.exit_code == 0, result.output
    assert png.read_bytes()[:4] == b"\x89PNG"
    result = run("preview", out, "-o", tmp_path / "sheet.png", "--sheet", "2", "--materials", library)
    assert result.exit_code == 0, result.output
