"""Parameter sweeps: slice one design for every combination of palette size, zipper width
and strategy, as the paper's experiments do (palette object at 4..48 colors, zipper on/off).

For each combination ``<stem>_c<colors>_z<zipper>_s<strategy>`` the sweep writes
``<name>.gcode`` and ``<name>.json`` (the slicer's statistics) into the output folder,
then ``summary.csv``: one row per combination with layers, extruded volume (cm^3), purge
volume (cm^3), state changes, estimated print time (s) and slicing time (s), then the
purge tolerance, tower volume (cm^3) and the share of the part the dead-volume model
predicts within half a palette bin (the last only for purges sized by the model).

A sweep over ``purge_tolerance`` (``tolerance``) slices every combination with
``purge_size = model`` at each tolerance, named ``..._t<tolerance>``: its table is the
tower's volume against the predicted fidelity.

Zipper widths apply to strategy 1 only (strategy 2 has no walls to zip), so strategy 2
combinations are sliced once per palette size with zipper 0.

Locally, combinations run one after another and each slices its layers in a process pool
(``jobs``). With a Dask ``scheduler``, every combination is one task on the cluster
(sliced there with one process); the workers write into ``out_dir``, which must be a
folder they can reach (a shared file system for a remote cluster). The submitter's
``SOURCE_DATE_EPOCH``, when set, stamps every combination's G-code, wherever it is sliced.
"""

from __future__ import annotations

import csv
import dataclasses
import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import Any

from fgslice.compat import open_design
from fgslice.compat.slicer_project import machine_settings, project_of
from fgslice.design.base import Design
from fgslice.errors import SettingsError
from fgslice.executor import map_ordered
from fgslice.output import atomic_output, check_writable
from fgslice.pipeline import build_time, slice_to_gcode
from fgslice.settings import Settings, load_settings

SUMMARY_COLUMNS = (
    "name", "strategy", "colors", "zipper", "layers", "extruded_cm3", "purge_cm3",
    "state_changes", "estimated_time_s", "slicing_s", "purge_tolerance", "tower_cm3", "within_half_bin",
)
"""Columns of ``summary.csv`` and of the dicts :func:`run_sweep` returns (volumes cm^3, times s)."""


@dataclass(frozen=True)
class Combination:
    """One point of the sweep: its file stem and its resolved settings."""

    name: str
    settings: Settings


@dataclass(frozen=True)
class _SweepJob:
    """What every combination's task needs (shipped once to each Dask worker).

    ``stamp`` is the submitter's :func:`~fgslice.pipeline.build_time`: a cluster's workers
    do not share the submitter's environment.
    """

    design: Design
    out_dir: Path
    jobs: int | None
    comments: dict[str, str]
    stamp: datetime | None


def combinations(
    stem: str,
    *,
    colors: Sequence[int],
    zipper: Sequence[float] = (0.0,),
    strategy: Sequence[int] | None = None,
    profile: str | None = None,
    overrides: dict[str, Any] | None = None,
    tolerance: Sequence[float] = (),
) -> list[Combination]:
    """Resolve every combination's settings (all are validated before anything is sliced).

    Arguments as :func:`run_sweep` (``zipper`` in percent); ``stem`` starts every
    combination's name.

    Raises:
        SettingsError: an empty list, a duplicate name, or a value the settings refuse.
    """
    if not colors:
        raise SettingsError("a sweep needs at least one palette size", hint="for example --colors 4,8,12,16")
    if not zipper:
        raise SettingsError("a sweep needs at least one zipper width", hint="use 0 for no zipper")
    base = load_settings(profile, overrides)
    strategies = list(strategy) if strategy else [base.strategy]
    result: list[Combination] = []
    for s in strategies:
        for n in colors:
            for z in zipper if s == 1 else (0.0,):
                values = {**(overrides or {}), "strategy": s, "colors": n, "zipper": z}
                for t in tolerance or (None,):
                    extra = {} if t is None else {"purge_size": "model", "purge_tolerance": t}
                    settings = load_settings(profile, {**values, **extra})
                    name = f"{stem}_c{settings.colors}_z{settings.zipper:g}_s{settings.strategy}"
                    result.append(Combination(name if t is None else f"{name}_t{t:g}", settings))
    names = [c.name for c in result]
    duplicates = sorted({n for n in names if names.count(n) > 1})
    if duplicates:
        raise SettingsError(f"the sweep lists the same combination twice: {', '.join(duplicates)}",
                            hint="remove repeated palette sizes, zipper widths or strategies")
    return result


def _slice_combination(job: _SweepJob, combination: Combination) -> dict:
    """Slice one combination into ``out_dir``; returns its summary row."""
    gcode = job.out_dir / f"{combination.name}.gcode"
    result = slice_to_gcode(job.design, combination.settings, gcode, jobs=job.jobs, comments=job.comments,
                            stamp=job.stamp)
    with atomic_output(gcode.with_suffix(".json")) as handle:
        json.dump(result.stats, handle, indent=2, default=float)
        handle.write("\n")
    s = result.stats
    return {
        "name": combination.name,
        "strategy": combination.settings.strategy,
        "colors": combination.settings.colors,
        "zipper": combination.settings.zipper,
        "layers": s["layers"],
        "extruded_cm3": round(s["extruded_mm3"] / 1000, 3),
        "purge_cm3": round(s["purge_mm3"] / 1000, 3),
        "state_changes": s["state_changes"],
        "estimated_time_s": round(s["estimated_time_s"], 1),
        "slicing_s": s["elapsed_s"],
        "purge_tolerance": s["purge_tolerance"],
        "tower_cm3": round(s["tower_mm3"] / 1000, 3),
        "within_half_bin": s["simulated_within_half_bin"],
    }


def run_sweep(
    design_path: str | Path,
    out_dir: str | Path,
    *,
    colors: Sequence[int],
    zipper: Sequence[float] = (0.0,),
    strategy: Sequence[int] | None = None,
    profile: str | None = None,
    overrides: dict[str, Any] | None = None,
    materials: str | Path | None = None,
    jobs: int | None = None,
    scheduler: str | None = None,
    progress: Callable[[dict], None] | None = None,
    tolerance: Sequence[float] = (),
) -> list[dict]:
    """Slice ``design_path`` for every combination and write the G-code, statistics and
    ``summary.csv`` into ``out_dir`` (created if missing).

    Args:
        design_path: the design: ``.vcad`` text or an OpenVCAD ``.py`` script (whose
            slicer-project compiler's filaments apply as ``fgslice slice`` applies them).
        out_dir: output folder.
        colors: palette sizes N.
        zipper: zipper widths beta, percent (strategy 1 only).
        strategy: strategies to run; None keeps the profile's / overrides' strategy.
        profile: built-in profile name or TOML file (None: the default profile).
        overrides: other settings, as ``--set`` would give them (``{"walls": "3"}``).
        materials: material library JSON for the design.
        jobs: worker processes per combination when running locally (default: all cores).
        scheduler: a Dask scheduler address; each combination becomes one task there.
        progress: called with each combination's summary row as it finishes.
        tolerance: ``purge_tolerance`` values to slice each combination at with
            ``purge_size = model`` (empty: the settings' purges).

    Returns:
        One dict per combination, keys :data:`SUMMARY_COLUMNS`, in sweep order
        (strategy, then colors, then zipper, then tolerance).

    Raises:
        FgsliceError: bad settings or design, an unwritable output, any slicing refusal.
    """
    design_path = Path(design_path)
    out_dir = Path(out_dir)
    todo = combinations(design_path.stem, colors=colors, zipper=zipper, strategy=strategy,
                        profile=profile, overrides=overrides, tolerance=tolerance)
    out_dir.mkdir(parents=True, exist_ok=True)
    for combination in todo:
        for suffix in (".gcode", ".json"):
            check_writable(out_dir / f"{combination.name}{suffix}", inputs=(design_path,))
    summary = check_writable(out_dir / "summary.csv", inputs=(design_path,))
    design = open_design(design_path, materials)
    project = project_of(design)
    todo = [dataclasses.replace(c, settings=machine_settings(project, design, c.settings)) for c in todo]
    job = _SweepJob(
        design=design,
        out_dir=out_dir.resolve(),
        jobs=1 if scheduler else jobs,
        comments={"design": str(design_path), "sweep": out_dir.name},
        stamp=build_time(),
    )
    rows = []
    for row in map_ordered(_slice_combination, job, todo, jobs=1, scheduler=scheduler, window=len(todo)):
        rows.append(row)
        if progress:
            progress(row)
    with atomic_output(summary) as handle:
        writer = csv.DictWriter(handle, fieldnames=SUMMARY_COLUMNS, lineterminator="\n")
        writer.writeheader()
        writer.writerows(rows)
    return rows


def format_summary(rows: Sequence[dict]) -> str:
    """The summary rows as an aligned text table (cm^3, s); with the tower's volume and the
    predicted share within half a bin when some purges were sized by the model."""
    modelled = any(r["within_half_bin"] is not None for r in rows)
    header = (f"{'combination':32s} {'layers':>6s} {'cm3':>9s} {'purge cm3':>9s} {'changes':>7s} "
              f"{'print h':>8s} {'slice s':>8s}" + (f" {'tower cm3':>9s} {'in bin':>7s}" if modelled else ""))
    lines = [header, "-" * len(header)]
    for r in rows:
        share = "" if r["within_half_bin"] is None else f"{r['within_half_bin']:.1%}"
        lines.append(
            f"{r['name']:32s} {r['layers']:6d} {r['extruded_cm3']:9.2f} {r['purge_cm3']:9.2f} "
            f"{r['state_changes']:7d} {r['estimated_time_s'] / 3600:8.2f} {r['slicing_s']:8.2f}"
            + (f" {r['tower_cm3']:9.2f} {share:>7s}" if modelled else "")
        )
    return "\n".join(lines)
