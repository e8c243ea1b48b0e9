"""Purge into infill end to end: the 100 x 50 x 10 mm bar graded in x, 4 colors, 20 %
infill, and where the simulator finds the transition material."""

from __future__ import annotations

import numpy as np
import pytest

from fgslice.analysis.fidelity import composition_error, transition_account
from fgslice.analysis.simulate import FEATURES, feature_of_roles, simulate, simulation_settings
from fgslice.design import load_design
from fgslice.pipeline import slice_to_gcode
from fgslice.settings import load_settings

BAR = 'fgrade(["x/100 + 0.5", "0.5 - x/100"], ["blue", "yellow"]) { rectprism(100, 50, 10); }\n'


@pytest.fixture(scope="module")
def bar(tmp_path_factory):
    folder = tmp_path_factory.mktemp("bar")
    path = folder / "bar.vcad"
    path.write_text(BAR)
    design = load_design(path)
    out = {}
    for into in (False, True):
        settings = load_settings(None, {"strategy": "1", "colors": "4", "infill_density": "20",
                                        "purge_into_infill": str(into).lower()})
        gcode = folder / f"bar_{into}.gcode"
        stats = slice_to_gcode(design, settings, gcode, jobs=1).stats
        tower_mm3 = stats["purge_waste_share"] * stats["extruded_mm3"]
        result = simulate(gcode, design, None, simulation_settings(gcode))
        out[into] = (stats, tower_mm3, result)
    return out


def test_the_bar_tower_shrinks_and_its_walls_are_no_worse(bar):
    (plain, plain_tower, plain_sim), (into, into_tower, into_sim) = bar[False], bar[True]
    assert plain_tower == pytest.approx(11_700, rel=0.02)  # the tower of 11.7 cm^3
    assert into_tower <= 0.6 * plain_tower
    # the part itself is the same: same volume outside the tower
    assert plain["extruded_mm3"] - plain_tower == pytest.approx(into["extruded_mm3"] - into_tower, rel=2e-4)  # share rounded
    walls = [transition_account(sim)["mean_error"]["walls"] for sim in (plain_sim, into_sim)]
    assert walls[1] <= walls[0]
    off = [transition_account(sim)["off_color_mm3"] for sim in (plain_sim, into_sim)]
    assert off[1]["walls"] <= off[0]["walls"]
    # the transition goes into the infill instead of the tower
    assert off[1]["infill"] > 5 * off[0]["infill"] and off[1]["tower"] < 0.5 * off[0]["tower"]


def test_the_transition_account_adds_up_by_feature(bar):
    _, _, sim = bar[True]
    account = transition_account(sim)
    assert set(account["off_color_mm3"]) == set(FEATURES)
    total = float(np.sum(composition_error(sim.deposited, sim.commanded) * sim.volume))
    assert sum(account["off_color_mm3"].values()) == pytest.approx(total, rel=1e-9)
    walls = sim.part & (sim.feature == FEATURES.index("walls"))
    expected = np.average(composition_error(sim.deposited[walls], sim.designed[walls]), weights=sim.volume[walls])
    assert account["mean_error"]["walls"] == pytest.approx(expected, rel=1e-9)
    assert account["mean_error"]["tower"] is None  # the tower is not part of the part
    assert account["off_color_mm3"]["tower"] > 0


def test_roles_of_fgslice_prusaslicer_and_cura_map_to_features():
    names = ["External perimeter", "Perimeter", "Overhang perimeter", "Gap fill", "WALL-OUTER", "WALL-INNER",
             "Solid infill", "Top solid infill", "Bridge infill", "SKIN", "Internal infill", "FILL",
             "Wipe tower", "PRIME-TOWER", "Skirt/Brim", "SKIRT", "Custom"]
    features = [FEATURES[i] for i in feature_of_roles(names)]
    assert features == ["walls"] * 6 + ["skins"] * 4 + ["infill"] * 2 + ["tower"] * 2 + ["other"] * 3


@pytest.mark.parametrize("into", [False, True])
def test_held_back_layers_give_the_same_gcode_with_workers(tmp_path, monkeypatch, into):
    """Graded in z up to half height: the upper layers are held back until the print
    ends; one process and two workers write the same bytes."""
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1700000000")
    path = tmp_path / "half.vcad"
    path.write_text('fgrade(["min(z/3, 1)", "1 - min(z/3, 1)"], ["blue", "yellow"]) '
                    '{ translate(0, 0, 3) { cylinder(6, 6); } }\n')
    design = load_design(path)
    settings = load_settings(None, {"strategy": "1", "colors": "4", "thumbnails": "",
                                    "purge_into_infill": str(into).lower()})
    outputs = []
    for jobs in (1, 2):
        out = tmp_path / f"half_{jobs}.gcode"
        slice_to_gcode(design, settings, out, jobs=jobs)
        outputs.append(out.read_bytes())
    assert outputs[0] == outputs[1]
    text = outputs[0].decode()
    layers = text.split(";LAYER_CHANGE")
    with_tower = [i for i, layer in enumerate(layers) if ";TYPE:Wipe tower" in layer]
    assert with_tower and max(with_tower) < len(layers) / 2 + 1  # no tower over the upper, ungraded half
