"""The ``fgslice`` command line: parse arguments, call the library, print results.

Every :class:`~fgslice.errors.FgsliceError` is printed in a few lines (what, where, how
to fix) and the process exits with status 2; an interruption exits with 130 and leaves
no partial output file.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import signal
import sys
import tempfile
import traceback
from pathlib import Path

import click

import fgslice
from fgslice.errors import FgsliceError
from fgslice.heap import retain_freed_memory


def _fail(error: FgsliceError) -> None:
    click.echo(error.format(), err=True)
    sys.exit(error.exit_code)


class _Finite(click.ParamType):
    """A float option that refuses NaN and infinities (which pass every range check)."""

    name = "float"

    def convert(self, value, param, ctx):
        number = click.FLOAT.convert(value, param, ctx)
        if not math.isfinite(number):
            self.fail(f"{value!r} is not a finite number", param, ctx)
        return number


FINITE = _Finite()

INTERNAL_ERROR_EXIT = 70
"""Exit status of an unexpected exception (``EX_SOFTWARE``): a bug, not bad input."""


class _Group(click.Group):
    """Turns fgslice errors, Ctrl-C and unexpected exceptions into short messages instead
    of tracebacks (``FGSLICE_TRACEBACK=1`` shows the traceback of an unexpected one)."""

    def invoke(self, ctx: click.Context):
        from fgslice.interrupts import Terminated, raise_on_termination

        try:
            with raise_on_termination():
                return super().invoke(ctx)
        except Terminated as stop:
            click.echo(f"terminated ({stop.args[0]}): no output file was written or changed", err=True)
            sys.exit(128 + stop.signum)
        except FgsliceError as error:
            if os.environ.get("FGSLICE_TRACEBACK") and error.__cause__ is not None:
                traceback.print_exception(error)  # an unexpected error reported as a refusal: its frames
            _fail(error)
        except KeyboardInterrupt:
            click.echo("interrupted: no output file was written or changed", err=True)
            sys.exit(130)
        except (click.ClickException, click.exceptions.Exit, click.exceptions.Abort):
            raise
        except BrokenPipeError:  # the reader of stdout left (`fgslice check x | head`): stop quietly, as cat does
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # no second error when Python flushes
            sys.exit(128 + signal.SIGPIPE)
        except Exception as error:
            if os.environ.get("FGSLICE_TRACEBACK"):
                raise
            click.echo(f"error: internal error in 'fgslice {ctx.invoked_subcommand}': {type(error).__name__}: {error}\n"
                       "  hint: this is a bug in fgslice, not in the input; "
                       "run again with FGSLICE_TRACEBACK=1 for the traceback to report", err=True)
            sys.exit(INTERNAL_ERROR_EXIT)


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(version=fgslice.__version__, prog_name="fgslice")
def main() -> None:
    """fgslice: slice functionally graded multi-material designs to G-code."""


def _settings(profile: str | None, sets: tuple[str, ...], extra: dict | None = None):
    """Settings of ``profile`` with ``--set`` overrides, then the options in ``extra`` that were given."""
    from fgslice.settings import load_settings, parse_overrides

    overrides = parse_overrides(sets)
    overrides.update({k: v for k, v in (extra or {}).items() if v is not None})
    return load_settings(profile, overrides)


def _write_json(path: Path, data: dict) -> None:
    """Write ``data`` as indented JSON, atomically."""
    from fgslice.output import atomic_output, check_writable

    check_writable(path)
    with atomic_output(path) as handle:
        json.dump(data, handle, indent=2, default=float)
        handle.write("\n")


@main.command("slice")
@click.argument("design", type=click.Path(dir_okay=False, path_type=Path))
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path), help="G-code file to write (default: DESIGN with .gcode; '-': standard output).")
@click.option("--profile", help="Built-in profile name (see 'fgslice profiles') or a TOML file.")
@click.option("--strategy", type=click.Choice(["1", "2"]), help="1: walls/skins/infill cut into colors; 2: faces filled densely.")
@click.option("--colors", type=int, help="Palette size N.")
@click.option("--layer-height", type=FINITE, help="Layer height h, mm.")
@click.option("--set", "sets", multiple=True, metavar="KEY=VALUE", help="Override any setting (repeatable).")
@click.option("--materials", type=click.Path(dir_okay=False, path_type=Path), help="Material library JSON.")
@click.option("--stats", "stats_path", type=click.Path(dir_okay=False, path_type=Path), help="Write statistics as JSON.")
@click.option("--report", "report_path", type=click.Path(dir_okay=False, path_type=Path), help="Write a self-contained HTML report.")
@click.option("--jobs", type=int, help="Worker processes (default: all cores).")
@click.option("--scheduler", help="Run layers on a Dask scheduler at this address.")
def slice_command(design, output, profile, strategy, colors, layer_height, sets, materials, stats_path, report_path, jobs, scheduler):
    """Slice DESIGN (.vcad, or an OpenVCAD .py script) to printer-ready G-code."""
    output = output or design.with_suffix(".gcode")
    settings = _settings(profile, sets, {"strategy": strategy, "colors": colors, "layer_height": layer_height})
    if output == Path("-"):  # sliced to a temporary file, verified, then copied to stdout
        with tempfile.TemporaryDirectory(prefix="fgslice-") as folder:
            gcode = Path(folder) / design.with_suffix(".gcode").name
            _slice(design, gcode, settings, materials, stats_path, report_path, jobs, scheduler, "<stdout>")
            with open(gcode, "rb") as handle:  # a reader that stops early (| head): see _Group.invoke
                shutil.copyfileobj(handle, sys.stdout.buffer)
            sys.stdout.buffer.flush()
        return
    _slice(design, output, settings, materials, stats_path, report_path, jobs, scheduler, str(output))


def _slice(design: Path, output: Path, settings, materials, stats_path, report_path, jobs, scheduler, shown: str) -> None:
    """:func:`slice_command` once the settings are loaded: slice to the file ``output``
    and print the summary (on stderr when the G-code goes to stdout)."""
    from fgslice.compat import open_design as load_design
    from fgslice.compat.slicer_project import machine_settings, project_of
    from fgslice.design.scaled import scaled
    from fgslice.output import check_writable
    from fgslice.pipeline import slice_to_gcode
    from fgslice.preview.thumbnails import parse_sizes, render_thumbnails

    check_writable(output, inputs=(design, materials))
    for extra in (stats_path, report_path):
        if extra:
            check_writable(extra, inputs=(design, output))
    loaded = load_design(design, materials)
    settings = machine_settings(project_of(loaded), loaded, settings)
    loaded = scaled(loaded, settings.scale)
    comments = {"design": str(design), "command": "fgslice " + " ".join(sys.argv[1:])}
    sizes = parse_sizes(settings.thumbnails)
    with _progress("slicing") as progress:
        result = slice_to_gcode(
            loaded, settings, output, jobs=jobs, scheduler=scheduler, comments=comments,
            thumbnails=(lambda layers: render_thumbnails(loaded, settings, sizes, layers)) if sizes else (),
            progress=progress,
        )
    s = result.stats
    if stats_path:
        _write_json(stats_path, s)
    if report_path:
        _write_report(report_path, result, settings, loaded, err=shown == "<stdout>")
    for warning in s["warnings"]:
        click.echo(f"warning: {warning}", err=True)
    tower = f", tower {s['tower_mm3'] / 1000:.2f} cm3 / {s['tower_g']:.1f} g" if s["tower_mm3"] else ""
    if s["simulated_within_half_bin"] is not None:
        tower += f" ({s['simulated_within_half_bin']:.1%} of the part simulated within half a bin)"
    click.echo(
        f"{shown}: {s['layers']} layers, {s['colors']} colors, {s['extruded_mm3'] / 1000:.2f} cm3, "
        f"{s['state_changes']} state changes{tower}, print {_duration(s['estimated_time_s'])}, "
        f"sliced in {s['elapsed_s']:.2f} s", err=shown == "<stdout>"
    )


def _write_report(path: Path, result, settings, design, err: bool = False) -> None:
    """The HTML report of a finished slice, with its simulated fidelity."""
    from fgslice.analysis.fidelity import fidelity, simulation_stats
    from fgslice.analysis.simulate import simulate
    from fgslice.design.machine_design import for_machine
    from fgslice.machine.state_dialect import dialect_for
    from fgslice.preview.report import write_report
    from fgslice.slicing.states import make_palette

    design = for_machine(design, settings)
    palette = make_palette(len(design.materials), settings.colors, settings.palette, result.stats.get("temperature_levels"))
    simulated = simulate(result.output, design, None, settings)
    write_report(
        path, stats=result.stats, settings=settings, palette=palette, dialect=dialect_for(settings, palette),
        program=result.output, design=design, fidelity=simulation_stats(simulated, fidelity(simulated)),
    )
    click.echo(f"{path}: report written", err=err)


def _duration(seconds: float) -> str:
    from fgslice.machine.gcode import format_duration

    return format_duration(seconds)


class _progress:
    """A rich progress bar on a terminal; nothing when output is redirected."""

    def __init__(self, label: str) -> None:
        self.label = label
        self.bar = None
        self.task = None

    def __enter__(self):
        if not sys.stderr.isatty():
            return None
        from rich.progress import BarColumn, MofNCompleteColumn, Progress, TimeElapsedColumn

        from rich.console import Console

        self.bar = Progress(
            f"[bold]{self.label}", BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
            console=Console(stderr=True), transient=True,
        )
        self.bar.__enter__()
        self.task = self.bar.add_task(self.label, total=None)
        return self.update

    def update(self, done: int, total: int) -> None:
        """Show ``done`` of ``total`` layers."""
        self.bar.update(self.task, completed=done, total=total)

    def __exit__(self, *exc) -> None:
        if self.bar is not None:
            self.bar.__exit__(*exc)


@main.command("check")
@click.argument("design", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--materials", type=click.Path(dir_okay=False, path_type=Path), help="Material library JSON.")
@click.option("--profile", default=None, help="Machine profile whose limits the attributes must fit.")
@click.option("--set", "sets", multiple=True, metavar="KEY=VALUE", help="Override any setting (repeatable).")
def check_command(design, materials, profile, sets):
    """Load DESIGN (.vcad or an OpenVCAD .py script) and report its materials, size, attribute ranges and problems."""
    from fgslice.compat import open_design as load_design
    from fgslice.design.scaled import scaled
    from fgslice.design import check_design, format_report
    from fgslice.compat.slicer_project import machine_settings, notes, project_of

    settings = _settings(profile, sets)
    loaded = load_design(design, materials)
    project = project_of(loaded)
    settings = machine_settings(project, loaded, settings)
    loaded = scaled(loaded, settings.scale)
    report = check_design(loaded, settings=settings)
    report.notes.extend(notes(project, loaded, settings))
    click.echo(format_report(report))
    if report.usable:
        from fgslice.executor import default_jobs
        from fgslice.resources import estimate_resources, format_estimate

        try:
            click.echo(format_estimate(estimate_resources(loaded, settings, jobs=default_jobs())))
        except FgsliceError as error:  # e.g. no layers: the slice says the same
            click.echo(f"estimate: none ({error})")
    if report.usable and "temperature" in report.attribute_cover:
        from fgslice.machine.grading import checked_attributes
        from fgslice.slicing.states import state_levels

        fields = checked_attributes(loaded, settings)  # the slicer's own check: the same levels
        levels = state_levels(fields.ranges, fields.cover, settings)
        if levels is not None:
            click.echo(f"temperature levels: {', '.join(f'{t:g}' for t in levels)} C (temperature_step "
                       f"{settings.temperature_step:g} C), each with every material color")
    sys.exit(0 if report.usable else 1)


@main.command("export-mesh")
@click.argument("design", type=click.Path(dir_okay=False, path_type=Path))
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False, path_type=Path), help="STL file to write.")
@click.option("--resolution", type=float, default=0.2, show_default=True, help="Grid step of marching cubes, mm.")
@click.option("--materials", type=click.Path(dir_okay=False, path_type=Path), help="Material library JSON.")
def export_mesh_command(design, output, resolution, materials):
    """Write DESIGN's surface as an STL mesh (marching cubes on its signed distance)."""
    from fgslice.compat import open_design as load_design
    from fgslice.design.export import export_mesh
    from fgslice.output import check_writable

    check_writable(output, inputs=(design,))
    vertices, triangles = export_mesh(load_design(design, materials), output, resolution)
    click.echo(f"{output}: {triangles:,} triangles, {vertices:,} vertices ({resolution:g} mm grid)")


@main.command("profiles")
@click.option("--keys", is_flag=True, help="List every setting with its value in the profile and its meaning.")
@click.option("--profile", help="The profile --keys shows: a built-in name or a TOML file (default: marlin-mixing).")
def profiles_command(keys, profile):
    """List the built-in printer profiles (or every setting of one with --keys)."""
    from fgslice.settings import builtin_profiles, describe_settings, load_settings

    if keys or profile:
        settings = load_settings(profile)
        for name, default, description in describe_settings():
            value = getattr(settings, name)
            note = "" if value == default else f" (default {default!r})"
            click.echo(f"{name} = {value!r}  # {description}{note}")
        return
    for name, description in builtin_profiles().items():
        click.echo(f"{name:20s} {description}")


@main.command("verify")
@click.argument("gcode", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--profile", help="Machine profile whose limits apply.")
@click.option("--set", "sets", multiple=True, metavar="KEY=VALUE", help="Override any setting.")
def verify_command(gcode, profile, sets):
    """Check GCODE (from any slicer) against the machine's limits."""
    from fgslice.machine.verify import format_faults, verify_gcode

    faults = verify_gcode(gcode, _settings(profile, sets))
    if faults:
        click.echo(format_faults(faults))
        click.echo(f"{gcode}: {len(faults)} fault(s)", err=True)
        sys.exit(1)
    click.echo(f"{gcode}: ok")


@main.command("simulate")
@click.argument("gcode", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--design", "design_path", required=True, type=click.Path(dir_okay=False, path_type=Path), help="The design the G-code was sliced from.")
@click.option("--materials", type=click.Path(dir_okay=False, path_type=Path), help="Material library JSON.")
@click.option("--profile", help="Machine profile (default: the settings recorded in the G-code).")
@click.option("--set", "sets", multiple=True, metavar="KEY=VALUE", help="Override any setting (e.g. tau_s, mixing_share).")
@click.option("--melt-volume", type=FINITE, help="Melt chamber volume V_melt, mm^3 (default: the profile's).")
@click.option("--colors", type=click.IntRange(min=1), help="Palette size for the half-bin metric (default: from the G-code).")
@click.option("--stats", "stats_path", type=click.Path(dir_okay=False, path_type=Path), help="Write the results as JSON.")
@click.option("--png", "png_path", type=click.Path(dir_okay=False, path_type=Path), help="Draw the composition error over one layer.")
@click.option("--layer", type=int, help="Layer for --png (default: the worst).")
def simulate_command(gcode, design_path, materials, profile, sets, melt_volume, colors, stats_path, png_path, layer):
    """Predict the composition GCODE really deposits and compare it with DESIGN."""
    from fgslice.analysis.fidelity import fidelity, plot_layer_error, simulation_stats
    from fgslice.analysis.simulate import simulate, simulation_settings
    from fgslice.compat import open_design as load_design
    from fgslice.design.scaled import scaled
    from fgslice.output import check_writable
    from fgslice.settings import parse_overrides

    for path in (stats_path, png_path):
        if path:
            check_writable(path, inputs=(gcode, design_path))
    settings = simulation_settings(gcode, profile, parse_overrides(sets))
    design = scaled(load_design(design_path, materials), settings.scale)
    result = simulate(gcode, design, None, settings, melt_volume_mm3=melt_volume, palette_size=colors)
    report = fidelity(result, colors)
    stats = simulation_stats(result, report)
    if stats_path:
        _write_json(stats_path, stats)
    half_bin = "n/a" if report.within_half_bin is None else f"{100 * report.within_half_bin:.1f}%"
    click.echo(
        f"{gcode}: {stats['model']} model, V_melt {stats['melt_volume_mm3']:g} mm3; composition error mean "
        f"{report.mean_error:.4f}, p95 {report.p95_error:.4f}; within half a bin {half_bin}; "
        f"CIEDE2000 mean {report.mean_delta_e:.2f}, p95 {report.p95_delta_e:.2f}"
    )
    if "transition" in stats:
        off = ", ".join(f"{k} {v:.1f}" for k, v in stats["transition"]["off_color_mm3"].items() if v >= 0.05)
        click.echo(f"transition material (off-color volume, mm3): {off or 'none'}")
    if png_path:
        drawn = plot_layer_error(result, png_path, layer)
        click.echo(f"{png_path}: composition error of layer {drawn}")


@main.group("calibrate")
def calibrate_group():
    """Calibration prints and calculators."""


@calibrate_group.command("lookahead")
@click.option("--profile", help="Machine profile.")
@click.option("--set", "sets", multiple=True, metavar="KEY=VALUE", help="Override any setting.")
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path), help="Write the calibration object's G-code here.")
@click.option("--measured-error", type=FINITE, help="Distance e_x (mm) between the object's midpoint and where the color change appeared.")
@click.option("--segment-length", type=FINITE, default=20.0, show_default=True, help="Length L_y of one serpentine line, mm.")
@click.option("--bead-width", type=FINITE, help="Bead width w, mm (default: the profile's).")
@click.option("--melt-volume", type=FINITE, help="Known melt chamber volume V_melt, mm^3.")
def calibrate_lookahead(profile, sets, output, measured_error, segment_length, bead_width, melt_volume):
    """Print Appendix A's calibration object (-o) or compute the look-ahead distance."""
    from fgslice.analysis.calibrate import lookahead_advice, write_calibration
    from fgslice.output import check_writable

    settings = _settings(profile, sets, {"bead_width": bead_width})
    if output:
        check_writable(output)
        stats = write_calibration(output, settings, length_y=segment_length)
        click.echo(
            f"{output}: calibration object, {stats['layers']} layers, the state changes at the midpoint of "
            f"each layer; measure e_x and run: fgslice calibrate lookahead --measured-error E_X "
            f"--segment-length {segment_length:g}"
        )
        return
    _, text = lookahead_advice(
        settings, measured_error_mm=measured_error, melt_volume_mm3=melt_volume, line_length_mm=segment_length
    )
    click.echo(text)


@main.command("preview")
@click.argument("gcode", type=click.Path(dir_okay=False, path_type=Path))
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False, path_type=Path), help="PNG file to write.")
@click.option("--layer", type=int, help="Layer number (0-based; default: the middle layer).")
@click.option("--z", "z", type=FINITE, help="Draw the layer nearest this height, mm.")
@click.option("--design", "design_path", type=click.Path(dir_okay=False, path_type=Path), help="Draw the design's field at that height beside it.")
@click.option("--materials", type=click.Path(dir_okay=False, path_type=Path), help="Material library JSON (for the header's materials and --design).")
@click.option("--travel", is_flag=True, help="Draw travel moves too.")
@click.option("--sheet", type=int, metavar="N", help="A contact sheet of N evenly spaced layers instead.")
@click.option("--attribute", metavar="NAME", help="Color by a process attribute as commanded: fan, flow, speed, temperature, infill_density.")
def preview_command(gcode, output, layer, z, design_path, materials, travel, sheet, attribute):
    """Draw a layer of GCODE (or a contact sheet) at real bead width, colored by state."""
    from fgslice.output import check_writable
    from fgslice.preview.colors import load_printout
    from fgslice.preview.layers import layer_count, nearest_layer, render_layer, render_sheet

    check_writable(output, inputs=(gcode,))
    library = None
    if materials:
        from fgslice.design.materials import load_library

        library = load_library(materials)
    printout = load_printout(gcode, library=library)
    if sheet:
        drawn = render_sheet(printout, output, count=sheet)
        click.echo(f"{output}: layers {', '.join(map(str, drawn))}")
        return
    design = None
    if design_path:
        from fgslice.compat import open_design as load_design

        design = load_design(design_path, materials)
    if z is not None:
        layer = nearest_layer(printout, z)
    elif layer is None:
        layer = layer_count(printout.program) // 2
    render_layer(printout, layer, output, design=design, show_travel=travel, attribute=attribute)
    click.echo(f"{output}: layer {layer}")


def _number_list(kind, text: str) -> list:
    """``"4,8,12"`` -> ``[4, 8, 12]`` (``kind`` int or float), with a clear error."""
    from fgslice.errors import SettingsError

    try:
        return [kind(part) for part in text.split(",") if part.strip()]
    except ValueError:
        raise SettingsError(f"expected comma-separated numbers, got '{text}'", hint="for example --colors 4,8,12,16") from None


@main.command("sweep")
@click.argument("design", type=click.Path(dir_okay=False, path_type=Path))
@click.option("-o", "--output", "out_dir", required=True, type=click.Path(file_okay=False, path_type=Path), help="Folder for the G-code, statistics and summary.csv.")
@click.option("--colors", "colors", required=True, help="Palette sizes, e.g. 4,8,12,16.")
@click.option("--zipper", "zipper", default="0", show_default=True, help="Zipper widths beta (percent), e.g. 0,5.")
@click.option("--strategy", "strategy", help="Strategies, e.g. 1,2 (default: the profile's).")
@click.option("--profile", help="Built-in profile name or a TOML file.")
@click.option("--set", "sets", multiple=True, metavar="KEY=VALUE", help="Override any setting for every combination.")
@click.option("--materials", type=click.Path(dir_okay=False, path_type=Path), help="Material library JSON.")
@click.option("--jobs", type=int, help="Worker processes per slice (default: all cores).")
@click.option("--scheduler", help="Run each combination as a task on this Dask scheduler.")
@click.option("--tolerance", "tolerance", help="purge_tolerance values, each sliced with purge_size=model, e.g. 0.00625,0.025.")
def sweep_command(design, out_dir, colors, zipper, strategy, profile, sets, materials, jobs, scheduler, tolerance):
    """Slice DESIGN for every combination of palette size, zipper width and strategy."""
    from fgslice.settings import parse_overrides
    from fgslice.sweep import format_summary, run_sweep

    rows = run_sweep(
        design, out_dir, colors=_number_list(int, colors), zipper=_number_list(float, zipper),
        strategy=_number_list(int, strategy) if strategy else None, profile=profile,
        overrides=parse_overrides(sets), materials=materials, jobs=jobs, scheduler=scheduler,
        tolerance=_number_list(float, tolerance) if tolerance else (),
    )
    click.echo(format_summary(rows))
    click.echo(f"{out_dir}: {len(rows)} slices and summary.csv")


@main.command("view")
@click.argument("gcode", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--port", type=int, help="Port on 127.0.0.1 (default: a free one).")
@click.option("--open", "open_browser", is_flag=True, help="Open the page in the default browser.")
def view_command(gcode, port, open_browser):
    """Show GCODE's toolpaths in 3D in a local browser page (Ctrl-C stops the server)."""
    from fgslice.preview.viewer import serve

    serve(gcode, port=port, open_browser=open_browser)


def run() -> None:
    """The ``fgslice`` program: :func:`main`, then exit at once with its status.

    Everything a command writes is closed by the time it returns (output files by
    their context managers, worker processes by their pools), so after flushing stdout
    and stderr the process skips the interpreter's teardown of numpy, shapely, msgspec
    and the design's objects, about 0.1 s on every command. It exits normally instead
    (running ``atexit`` handlers) when a profiler or tracer is active (``python -m
    cProfile``, coverage), so that it can save its data. An unexpected exception is a
    short message and exit status :data:`INTERNAL_ERROR_EXIT` (``_Group.invoke``). The process keeps the memory it
    frees for reuse (:func:`fgslice.heap.retain_freed_memory`), as its workers do.

    When a command is named, numpy is imported first, here at the bottom of the call
    stack (``fgslice --help`` and ``--version`` alone do without it: 45 ms instead of
    85 ms). CPython keeps the frames of Python calls in chunks of 16 KiB, mapping one
    when a call does not fit in the current chunk and unmapping it when that call
    returns. numpy's import builds its typing aliases (``numpy._typing``) in thousands
    of short nested calls; imported from within a command, some thirty frames deeper,
    they crossed a chunk boundary again and again: 800-1800 mmap/munmap pairs and
    35-45 ms on every command (``strace``). From here they stay in the first chunk,
    which is never unmapped: slicing the vase, the palette or the Benchy makes 12-15
    munmaps in all. (Newer CPython releases keep a spare chunk instead,
    python/cpython#142183.)

    Before that import, numpy's OpenBLAS is limited to one thread
    (``OPENBLAS_NUM_THREADS=1`` unless the environment sets it): fgslice runs its layers
    in worker processes and calls BLAS only on tiny matrices, and OpenBLAS's thread
    pool, started at import, costs every command about 60 ms of its serial start-up and
    130 ms of CPU on the other core (2-core machine).
    """
    retain_freed_memory()
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    if any(arg in main.commands for arg in sys.argv[1:]):
        import numpy  # noqa: F401 - imported here for where it happens (see above)
    if sys.getprofile() is not None or sys.gettrace() is not None:
        main()
        return
    try:
        main()
    except SystemExit as end:
        code = end.code
    else:
        code = 0
    if isinstance(code, str):
        print(code, file=sys.stderr)
        code = 1
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code or 0)


if __name__ == "__main__":
    run()
