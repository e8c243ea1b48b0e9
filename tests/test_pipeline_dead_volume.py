"""Look-ahead end to end: every state change moves earlier by the set extruded length,
checked by walking the written G-code; strategy 1 with every dialect."""

from __future__ import annotations

import numpy as np
import pytest

from fgslice.design import api
from fgslice.machine.gcode_reader import read_gcode
from fgslice.machine.verify import verify_gcode
from fgslice.pipeline import slice_to_gcode
from fgslice.settings import load_settings

BAR = api.design(api.fgrade(["x/60 + 0.5", "0.5 - x/60"], ["blue", "yellow"], api.rectprism(60, 12, 1.2)))


def _state_positions(path) -> np.ndarray:
    """Extruded XY length printed before each ``;STATE:`` comment, mm."""
    program = read_gcode(path)
    printing = (program.e > 0) & (program.length > 0)
    cumulative = np.cumsum(np.where(printing, program.length, 0.0))
    state_lines = [n for n, line in enumerate(path.read_text().splitlines(), 1) if line.startswith(";STATE:")]
    before = np.searchsorted(program.line, state_lines)
    return np.where(before > 0, cumulative[np.maximum(before - 1, 0)], 0.0)


@pytest.mark.parametrize("distance", [25.0, 2500.0])
def test_every_change_is_issued_the_lookahead_distance_early(tmp_path, distance):
    settings = dict(colors="4", skirt_loops="0", strategy="2")
    plain, early = tmp_path / "plain.gcode", tmp_path / "early.gcode"
    slice_to_gcode(BAR, load_settings(None, settings), plain, jobs=1)
    slice_to_gcode(BAR, load_settings(None, {**settings, "lookahead_mm": str(distance)}), early, jobs=1)
    at, moved = _state_positions(plain), _state_positions(early)
    assert len(at) == len(moved) > 8  # several layers, several changes each; none dropped
    # within 0.05 mm: coordinates are written to 3 decimals and split points add vertices
    assert moved == pytest.approx(np.maximum(at - distance, 0.0), abs=0.05)
    if distance > 2100:  # longer than a layer's extrusion: changes move into earlier layers
        assert (_state_layers(early) < _state_layers(plain)).any()


def _state_layers(path) -> np.ndarray:
    """The layer (count of ``;LAYER_CHANGE`` before it, minus one) of each ``;STATE:``."""
    layer, out = -1, []
    for line in path.read_text().splitlines():
        if line.startswith(";LAYER_CHANGE"):
            layer += 1
        elif line.startswith(";STATE:"):
            out.append(layer)
    return np.array(out)


@pytest.mark.parametrize("profile", ["toolchanger", "foam-lwpla", "marlin-mixing-m163", "template-diw"])
def test_strategy1_purges_on_every_dialect_and_verifies(tmp_path, profile):
    settings = load_settings(profile, {"strategy": "1", "colors": "3", "walls": "2"})
    out = tmp_path / "bar.gcode"
    stats = slice_to_gcode(BAR, settings, out, jobs=1).stats
    assert verify_gcode(out, settings) == []
    program = read_gcode(out)
    assert "Wipe tower" in program.roles
    assert stats["purge_mm3"] > 0 and stats["state_changes"] >= 3
