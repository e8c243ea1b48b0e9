"""Which ends of a layer's paths the G-code writer coasts (:mod:`fgslice.machine.coasting`),
for the look-ahead, which counts extruded length only."""

from __future__ import annotations

import numpy as np

from fgslice.planning.lookahead import path_lengths
from fgslice.settings import Settings
from fgslice.toolpaths.paths import Path


def coasted_lengths(paths: list[Path], settings: Settings) -> np.ndarray:
    """Per path of a layer in printing order, the length (mm) coasted at its end:
    ``coast_mm`` (at most the path's length) where a retraction follows, i.e. the next
    path starts farther than ``retract_min_travel`` from its end, or the layer ends."""
    n = len(paths)
    if settings.coast_mm <= 0 or settings.retract_length <= 0 or not n:
        return np.zeros(n)
    ends = np.array([p.end for p in paths])
    starts = np.array([p.start for p in paths])
    retracts = np.append(np.hypot(*(starts[1:] - ends[:-1]).T) > settings.retract_min_travel, True)
    return np.where(retracts, np.minimum(settings.coast_mm, path_lengths(paths)), 0.0)
