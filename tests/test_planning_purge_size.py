"""Purges sized by the dead-volume model: the inverted melt-chamber and thermal models,
the tower they need, and slices whose regions start within the tolerance."""

import math

import numpy as np
import pytest
import shapely

from fgslice.analysis.fidelity import composition_error, fidelity
from fgslice.analysis.simulate import lag_average, mixing_deposit, simulate
from fgslice.design import api
from fgslice.errors import SettingsError, SliceError
from fgslice.pipeline import slice_to_gcode
from fgslice.planning.plan import SetState
from fgslice.planning.purge import PurgeStats, PurgeTower, insert_purges
from fgslice.planning.purge_size import PurgeSizer, purge_volume
from fgslice.settings import Settings, load_settings
from fgslice.slicing.palette import Palette
from fgslice.toolpaths.paths import Path, Role, bead_area
from test_planning_purge import FOOTPRINT, layer_plans, purges_per_change

PALETTE = Palette(2, 4)
BAR = api.design(api.fgrade(["x/60 + 0.5", "0.5 - x/60"], ["blue", "yellow"], api.rectprism(60, 12, 1.2)))


def _output_after(volume: float, old: np.ndarray, new: np.ndarray, v_plug: float, v_mix: float) -> np.ndarray:
    """What the simulator's melt chamber deposits on a tiny segment ``volume`` mm^3 after a
    step from ``old`` (the chamber full of it) to ``new``."""
    tiny = 1e-4
    volumes = np.array([500.0, volume, tiny])
    commanded = np.array([old, new, new])
    return mixing_deposit(volumes, commanded, v_plug, v_mix)[2]


@pytest.mark.parametrize("d", [1 / 16, 0.25, 0.9])
@pytest.mark.parametrize("share", [0.3, 0.6])
def test_purge_of_a_change_of_size_d_matches_the_closed_form(d, share):
    v_melt, tol = 68.5, 0.1 / 16
    v_plug, v_mix = (1 - share) * v_melt, share * v_melt
    volume = purge_volume(d, tol, v_plug, v_mix)
    assert volume == pytest.approx(v_plug + v_mix * math.log(d / tol), rel=1e-12)
    # the simulator agrees: the composition leaving the nozzle after that volume is tol away
    old, new = np.array([0.5 + d / 2, 0.5 - d / 2]), np.array([0.5 - d / 2, 0.5 + d / 2])
    assert composition_error(_output_after(volume, old, new, v_plug, v_mix), new) == pytest.approx(tol, rel=1e-3)
    assert composition_error(_output_after(0.97 * volume, old, new, v_plug, v_mix), new) > 1.01 * tol
    # the sizer turns it into mm of bead of the layer's cross-section
    settings = Settings(purge_size="model", mixing_share=share, colors=4)
    sizer = PurgeSizer.of(settings, np.array([old, new]))
    assert sizer.tolerance == pytest.approx(0.1 / 2)  # a tenth of the bin of a 2-color palette
    expected = purge_volume(d, 0.05, v_plug, v_mix, residual=0.05) / bead_area(0.4, 0.2)
    assert sizer.length(0, 1, 0.2, 3) == pytest.approx(expected, rel=1e-12)


def test_residual_of_an_earlier_state_is_purged_too():
    v_plug, v_mix, tol, d = 40.0, 20.0, 0.01, 0.2
    volume = purge_volume(d, tol, v_plug, v_mix, residual=tol)
    assert volume == pytest.approx(v_plug + v_mix * math.log((d + tol * math.exp(-v_plug / v_mix)) / tol))
    # the old state's own purge left the chamber tol away from it, on the far side from
    # the new state; the next purge still ends within tol (and only just)
    older, old, new = np.array([1.0, 0.0]), np.array([0.6, 0.4]), np.array([0.4, 0.6])
    before = purge_volume(composition_error(older, old), tol, v_plug, v_mix)
    volumes = np.array([v_mix * 50, before, volume, 1e-4])
    out = mixing_deposit(volumes, np.array([older, old, new, new]), v_plug, v_mix)
    assert tol * 0.999 <= composition_error(out[3], new) <= tol * (1 + 1e-6)
    assert composition_error(out[3], new) > composition_error(_output_after(volume, old, new, v_plug, v_mix), new)
    # no purge when the change and the residual are within the tolerance; the plug alone
    # when the well-mixed share is zero
    assert purge_volume(0.004, tol, v_plug, v_mix, residual=0.005) == 0.0
    assert purge_volume(d, tol, 68.5, 0.0) == 68.5


def test_temperature_changes_purge_for_the_thermal_lag_at_the_tower_speed():
    settings = load_settings("foam-lwpla", {"purge_size": "model", "colors": "4", "purge_tolerance": "0.5"})
    sizer = PurgeSizer.of(settings, PALETTE.centers)
    span = abs(settings.temperature_a - settings.temperature_b)
    d = 0.25 * span
    seconds = settings.tau_s * math.log((d + 0.5) / 0.5)
    assert sizer.length(1, 2, 0.2, 5) == pytest.approx(seconds * settings.print_speed, rel=1e-12)
    assert sizer.length(1, 2, 0.2, 0) == pytest.approx(seconds * settings.first_layer_speed, rel=1e-12)
    # the simulator's thermal lag: after that time on the tower the nozzle is 0.5 degC off
    t0, t1 = settings.temperature_b + 0.375 * span, settings.temperature_b + 0.625 * span
    residual_start = t0 - 0.5  # the chamber carries the tolerance of the change before
    mean = lag_average(np.array([seconds, 1e-6]), np.array([t1, t1]), settings.tau_s, np.array(residual_start))
    assert abs(mean[1] - t1) <= 0.5 + 1e-6


def test_model_purges_follow_one_another_on_the_tower():
    settings = Settings(purge_size="model", melt_volume_mm3=20.0)
    sizer = PurgeSizer.of(settings, PALETTE.centers)
    tower = PurgeTower.plan(FOOTPRINT, settings, changes_per_layer=4, n_layers=4, sizer=sizer)
    assert tower.consecutive
    stats = PurgeStats()
    out = list(insert_purges(iter(layer_plans(4)), tower, settings, PALETTE, stats, sizer))
    records = purges_per_change(out)
    for layer, old, new, length in records:
        expected = 0.0 if old == new else sizer.length(old, new, 0.2, layer)
        assert length == pytest.approx(expected, rel=1e-9)
    first = [r for r in records if r[1] is None][0]
    assert first[3] > max(r[3] for r in records if r[1] is not None)  # the unknown start purges most
    # each layer's purges: one line through its rows, inside the tower, never overlapping
    box = tower.footprint.buffer(1e-6)
    for plan in out:
        steps = plan.steps
        lines = [steps[i + 1] for i, step in enumerate(steps[:-1]) if isinstance(step, SetState)
                 and isinstance(steps[i + 1], Path) and steps[i + 1].role is Role.WIPE_TOWER]
        for a, b in zip(lines, lines[1:]):
            assert np.allclose(a.vertices[-1], b.vertices[0])
        printed = [shapely.LineString(p.vertices) for p in lines]
        assert all(shapely.within(line, box) for line in printed)
        assert sum(line.length for line in printed) == pytest.approx(shapely.union_all(printed).length, rel=1e-9)


def test_looser_tolerance_gives_a_smaller_tower_and_full_stays_the_melt_volume():
    lengths = []
    for tol in ("auto", "0.05", "0.1"):
        settings = load_settings(None, {"purge_size": "model", "colors": "4", "purge_tolerance": tol})
        tower = PurgeTower.plan(FOOTPRINT, settings, 4, 10, PurgeSizer.of(settings, PALETTE.centers))
        lengths.append((tower.purge_mm, tower.footprint.area))
    assert lengths[0] > lengths[1] > lengths[2]
    full = PurgeTower.plan(FOOTPRINT, Settings(), 4, 10, PurgeSizer.of(Settings(), PALETTE.centers))
    assert full.purge_mm == pytest.approx(68.5 / Settings().bead_area) and not full.consecutive


def test_a_tower_that_does_not_fit_names_a_tolerance_that_does():
    part = shapely.box(45, 45, 175, 175)
    settings = Settings(purge_size="model", colors=16, bed_x=220, bed_y=220)
    palette = Palette(2, 16)
    with pytest.raises(SliceError, match="no room") as err:
        PurgeTower.plan(part, settings, 16, 100, PurgeSizer.of(settings, palette.centers))
    hint = err.value.hint
    assert "--set purge_tolerance=" in hint
    value = float(hint.split("--set purge_tolerance=")[1].split()[0])
    looser = load_settings(None, {"purge_size": "model", "colors": "16", "bed_x": "220", "bed_y": "220",
                                  "purge_tolerance": str(value)})
    PurgeTower.plan(part, looser, 16, 100, PurgeSizer.of(looser, palette.centers))  # fits
    tighter = load_settings(None, {"purge_size": "model", "colors": "16", "bed_x": "220", "bed_y": "220",
                                   "purge_tolerance": str(value * 0.8)})
    with pytest.raises(SliceError):
        PurgeTower.plan(part, tighter, 16, 100, PurgeSizer.of(tighter, palette.centers))
    colors = int(hint.split("--set colors=")[1].split()[0])
    assert 2 <= colors < 16
    fewer = Settings(purge_size="model", colors=colors, bed_x=220, bed_y=220)
    PurgeTower.plan(part, fewer, colors, 100, PurgeSizer.of(fewer, Palette(2, colors).centers))


@pytest.mark.parametrize("profile", ["marlin-mixing", "foam-lwpla", "toolchanger"])
def test_a_slice_with_model_purges_starts_every_region_within_its_tolerance(tmp_path, profile):
    settings = load_settings(profile, {"strategy": "1", "colors": "4", "walls": "2", "purge_size": "model"})
    out = tmp_path / "bar.gcode"
    stats = slice_to_gcode(BAR, settings, out, jobs=1).stats
    result = simulate(out, BAR, None, settings)
    error = composition_error(result.deposited, result.commanded)
    # a region's first segment: a part segment right after the tower (or the skirt)
    first = np.flatnonzero(result.part[1:] & ~result.part[:-1]) + 1
    assert len(first) >= stats["layers"]
    tolerance = 0.1 / 4  # composition; in degC for the temperature dialect
    scale = abs(settings.temperature_a - settings.temperature_b) if settings.dialect == "temperature" else 1.0
    assert stats["purge_tolerance"] == pytest.approx(tolerance * scale)
    assert error[first].max() <= tolerance


def test_stats_give_the_tower_and_the_simulated_share_with_model_purges(tmp_path):
    settings = load_settings(None, {"strategy": "1", "colors": "4", "walls": "2", "purge_size": "model"})
    stats = slice_to_gcode(BAR, settings, tmp_path / "bar.gcode", jobs=1).stats
    # the share `fgslice simulate` reports for the same file
    reported = fidelity(simulate(tmp_path / "bar.gcode", BAR, None, settings)).within_half_bin
    assert stats["simulated_within_half_bin"] == pytest.approx(reported, abs=1e-4)
    assert 0 < reported <= 1
    full = slice_to_gcode(BAR, load_settings(None, {**settings.as_dict(), "purge_size": "full"}), tmp_path / "f.gcode",
                          jobs=1).stats
    assert full["simulated_within_half_bin"] is None
    assert stats["tower_mm3"] > full["tower_mm3"] > 0
    assert stats["tower_g"] == pytest.approx(stats["tower_mm3"] * 1.24 / 1000, rel=1e-3)


def test_tolerance_must_be_positive_and_the_scaled_purge_is_gone():
    with pytest.raises(SettingsError, match="purge_tolerance"):
        load_settings(None, {"purge_tolerance": "0"})
    with pytest.raises(SettingsError, match="unknown setting") as err:
        load_settings(None, {"purge_scale_by_change": "true"})
    assert "purge_size=model" in err.value.hint
