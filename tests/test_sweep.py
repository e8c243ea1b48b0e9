"""Sweeps: one G-code and one statistics file per combination, a summary that agrees with
them, and the same bytes whether combinations run locally or as Dask tasks."""

from __future__ import annotations

import csv
import json
import re

import pytest

from fgslice.errors import SettingsError
from fgslice.sweep import SUMMARY_COLUMNS, combinations, format_summary, run_sweep

DISC = """
fgrade(["x/24 + 0.5", "0.5 - x/24"], ["blue", "yellow"]) {
    translate(0, 0, 0.6) { cylinder(12, 1.2); }
}
"""
BASE = {"layer_height": "0.4", "walls": "2", "thumbnails": ""}


@pytest.fixture
def disc(tmp_path):
    path = tmp_path / "disc.vcad"
    path.write_text(DISC)
    return path


def _states(gcode: bytes) -> set[int]:
    return {int(m) for m in re.findall(rb";STATE:(\d+)", gcode)}


def test_local_sweep_writes_every_combination(tmp_path, disc, monkeypatch):
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1700000000")
    seen = []
    rows = run_sweep(disc, tmp_path / "out", colors=[2, 4], zipper=[0, 10], strategy=[1, 2],
                     overrides=BASE, jobs=2, progress=seen.append)
    names = [r["name"] for r in rows]
    assert names == ["disc_c2_z0_s1", "disc_c2_z10_s1", "disc_c4_z0_s1", "disc_c4_z10_s1",
                     "disc_c2_z0_s2", "disc_c4_z0_s2"]
    assert seen == rows
    with open(tmp_path / "out" / "summary.csv") as handle:
        table = list(csv.DictReader(handle))
    assert [t["name"] for t in table] == names
    assert tuple(table[0]) == SUMMARY_COLUMNS
    for row, line in zip(rows, table):
        gcode = (tmp_path / "out" / f"{row['name']}.gcode").read_bytes()
        stats = json.loads((tmp_path / "out" / f"{row['name']}.json").read_text())
        assert stats["layers"] == row["layers"] == int(line["layers"]) == 3
        assert gcode.count(b";LAYER_CHANGE") == 3
        assert stats["colors"] == row["colors"]
        assert _states(gcode) <= set(range(row["colors"]))
        assert float(line["extruded_cm3"]) == pytest.approx(stats["extruded_mm3"] / 1000, abs=1e-3)
        assert int(line["state_changes"]) == stats["state_changes"]
    by_name = {r["name"]: r for r in rows}
    # the gradient spans the whole range, so every color of the palette is printed
    assert _states((tmp_path / "out" / "disc_c4_z0_s2.gcode").read_bytes()) == {0, 1, 2, 3}
    assert by_name["disc_c4_z0_s1"]["state_changes"] > by_name["disc_c2_z0_s1"]["state_changes"]
    # a zipper overlaps neighbouring colors' walls: the same part, more pieces
    assert by_name["disc_c4_z10_s1"]["state_changes"] >= by_name["disc_c4_z0_s1"]["state_changes"]
    text = format_summary(rows)
    assert all(name in text for name in names)


def test_tolerance_sweep_trades_tower_volume_for_predicted_fidelity(tmp_path, disc):
    rows = run_sweep(disc, tmp_path / "out", colors=[4], strategy=[1], overrides=BASE, jobs=1,
                     tolerance=[0.0125, 0.1])
    assert [r["name"] for r in rows] == ["disc_c4_z0_s1_t0.0125", "disc_c4_z0_s1_t0.1"]
    tight, loose = rows
    assert (tight["purge_tolerance"], loose["purge_tolerance"]) == (0.0125, 0.1)
    assert tight["tower_cm3"] > loose["tower_cm3"] > 0
    assert 1 >= tight["within_half_bin"] >= loose["within_half_bin"] > 0
    stats = json.loads((tmp_path / "out" / "disc_c4_z0_s1_t0.1.json").read_text())
    assert stats["simulated_within_half_bin"] == loose["within_half_bin"]
    assert "in bin" in format_summary(rows) and "in bin" not in format_summary(
        run_sweep(disc, tmp_path / "plain", colors=[2], strategy=[1], overrides=BASE, jobs=1))


@pytest.mark.slow
def test_dask_sweep_matches_local(tmp_path, disc, monkeypatch, dask_scheduler):
    # set after the cluster started: its workers do not see it, the submitter's stamp is used
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1600000000")
    local = run_sweep(disc, tmp_path / "local", colors=[3], strategy=[1, 2], overrides=BASE, jobs=1)
    remote = run_sweep(disc, tmp_path / "dask", colors=[3], strategy=[1, 2], overrides=BASE, scheduler=dask_scheduler)
    assert [r["name"] for r in remote] == [r["name"] for r in local] == ["disc_c3_z0_s1", "disc_c3_z0_s2"]
    for row in local:
        a = (tmp_path / "local" / f"{row['name']}.gcode").read_bytes()
        b = (tmp_path / "dask" / f"{row['name']}.gcode").read_bytes()
        assert b.split(b"\n", 1)[0].endswith(b" on 2020-09-13 at 12:26:40 UTC")
        # only the sweep comment (the output folder's name) differs
        assert a.replace(b"sweep = local", b"sweep = dask") == b


def test_bad_sweeps_are_refused_before_slicing(tmp_path, disc):
    with pytest.raises(SettingsError, match="at least one palette size"):
        run_sweep(disc, tmp_path / "out", colors=[])
    with pytest.raises(SettingsError, match="same combination twice"):
        combinations("disc", colors=[4, 4])
    with pytest.raises(SettingsError, match="colors"):
        run_sweep(disc, tmp_path / "out", colors=[4, 0])
    assert not (tmp_path / "out").exists()


def test_a_sweep_runs_an_openvcad_script_with_its_compilers_filaments(tmp_path):
    """An OpenVCAD 3 colour bar compiled for PrusaSlicer with two filaments: each
    combination is sliced with those filaments' colours, red at one end, blue at the other."""
    script = tmp_path / "bar.py"
    script.write_text(
        "import pyvcad as pv\nimport pyvcad_compilers as pvc\n"
        "bar = pv.RectPrism(pv.Vec3(0, 0, 0.6), pv.Vec3(24, 8, 1.2))\n"
        "bar.set_attribute(pv.DefaultAttributes.COLOR_RGB, pv.Vec3Attribute('0.5 - x/24', '0', '0.5 + x/24'))\n"
        "pvc.PrusaSlicerProjectCompiler(bar, pv.Vec3(0.25, 0.25, 0.25), 'bar.3mf', num_regions=12,\n"
        "    color_mix_filaments=[{'slot': 1, 'color_hex': '#ff0000'}, {'slot': 2, 'color_hex': '#0000ff'}]).compile()\n")
    rows = run_sweep(script, tmp_path / "out", colors=[2, 4], strategy=[2], profile="marlin-mixing",
                     overrides=BASE, jobs=1)
    assert [r["name"] for r in rows] == ["bar_c2_z0_s2", "bar_c4_z0_s2"]
    for row in rows:
        gcode = (tmp_path / "out" / f"{row['name']}.gcode").read_bytes()
        assert b"filament_colors = #ff0000,#0000ff" in gcode
        assert _states(gcode) == set(range(row["colors"]))
