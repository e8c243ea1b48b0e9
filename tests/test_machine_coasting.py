"""Coasting and wipe, measured in the G-code; the look-ahead leaves coasted length out."""

import numpy as np
import pytest

from fgslice.design.language import parse_design
from fgslice.machine.gcode_reader import read_gcode
from fgslice.pipeline import slice_to_gcode
from fgslice.planning.lookahead import apply_lookahead
from fgslice.planning.plan import LayerPlan, SetState
from fgslice.settings import load_settings
from fgslice.toolpaths.paths import Path, Role

DESIGN = 'fgrade(["x/20+0.5", "0.5-x/20"], ["blue", "yellow"]) { translate(0,0,1) { union() { rectprism(12, 8, 2); translate(15,0,0) { cylinder(3, 2); } } } }'


def _slice(tmp_path, **overrides):
    values = {"strategy": "1", "colors": "2", "purge": "false", **{k: str(v) for k, v in overrides.items()}}
    settings = load_settings(None, values)
    out = tmp_path / (("_".join(f"{k}{v}" for k, v in overrides.items()) or "plain") + ".gcode")
    stats = slice_to_gcode(parse_design(DESIGN), settings, out, jobs=1).stats
    return settings, read_gcode(out), stats


def _runs(program, settings):
    """Per retraction: the XY length moved without extrusion at a print feed just before it
    (coasting), and the XY length and filament of the retracting moves (wipe)."""
    travel_feed = settings.travel_speed * 60
    out = []
    i = 0
    e, length, feed = program.e, program.length, program.feed
    n = len(e)
    while i < n:
        if e[i] < 0:  # a retraction starts: look back for coasting, forward for the wipe
            j = i - 1
            coasted = 0.0
            while j >= 0 and e[j] == 0 and length[j] > 0 and feed[j] != travel_feed:
                coasted += length[j]
                j -= 1
            printed_before = j >= 0 and e[j] > 0 and length[j] > 0
            k, wiped, retracted = i, 0.0, 0.0
            while k < n and e[k] < 0:
                wiped += length[k]
                retracted -= e[k]
                k += 1
            if printed_before:
                out.append((coasted, wiped, retracted))
            i = k
        else:
            i += 1
    return np.array(out)


def test_coasting_and_wipe_lengths_in_the_gcode(tmp_path):
    settings, plain, plain_stats = _slice(tmp_path)
    _, program, stats = _slice(tmp_path, coast_mm=0.6, wipe_mm=1.5)
    runs = _runs(program, settings)
    assert len(runs) > 20
    coasted, wiped, retracted = runs.T
    assert np.allclose(retracted, settings.retract_length, atol=1e-4)
    long_enough = coasted > 0
    assert long_enough.mean() > 0.9
    assert np.median(coasted) == pytest.approx(0.6, abs=0.002)
    assert (coasted <= 0.6 + 0.002).all()
    assert np.median(wiped) == pytest.approx(1.5, abs=0.002) and (wiped <= 1.5 + 0.002).all()
    # coasting leaves out the coasted length's volume and nothing else
    assert plain_stats["extruded_mm3"] - stats["extruded_mm3"] == pytest.approx(
        coasted.sum() * settings.bead_area, rel=0.05)
    assert not _runs(plain, settings)[:, :2].any()


def test_lookahead_leaves_coasted_length_out():
    a = Path(np.array([[0.0, 0.0], [10.0, 0.0]]), Role.PERIMETER, 0, 0.4, 0.2)
    b = Path(np.array([[20.0, 0.0], [30.0, 0.0]]), Role.PERIMETER, 1, 0.4, 0.2)
    plan = LayerPlan(index=0, z=0.2, height=0.2, steps=[SetState(0), a, SetState(1), b])
    (plain,) = apply_lookahead([plan], 5.0)
    (coasting,) = apply_lookahead([plan], 5.0, lambda paths: np.array([2.0, 2.0]))
    cut = [s for s in plain.steps if isinstance(s, Path)][0]
    assert cut.points[-1, 0] == pytest.approx(5.0)
    cut = [s for s in coasting.steps if isinstance(s, Path)][0]
    assert cut.points[-1, 0] == pytest.approx(3.0)  # 8 mm of A extrude, the change 5 mm before its end
