"""The part volume each layer reports: bead cross-section x printed length, summed over
the part's paths in one pass, against each path's own length."""

from __future__ import annotations

import numpy as np

from fgslice.coverage import part_volume
from fgslice.toolpaths.paths import Path, Role, bead_area


def test_part_volume_is_each_paths_bead_times_its_length():
    rng = np.random.default_rng(7)
    paths = [Path(rng.random((int(rng.integers(2, 9)), 2)) * 20, Role.INTERNAL_INFILL, i % 3,
                  0.4 + 0.05 * (i % 4), 0.2 + 0.05 * (i % 2), closed=bool(i % 2)) for i in range(300)]
    skirt = Path(np.array([[0.0, 0.0], [50.0, 0.0]]), Role.SKIRT, 0, 0.4, 0.2)
    expected = sum(bead_area(p.width, p.height) * p.length for p in paths)
    assert abs(part_volume(paths + [skirt]) - expected) < 1e-9 * expected


def test_a_closed_square_counts_its_closing_side():
    square = Path(np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]]), Role.EXTERNAL_PERIMETER, 0, 0.4, 0.2,
                  closed=True)
    assert abs(part_volume([square]) - 40.0 * bead_area(0.4, 0.2)) < 1e-12
    assert part_volume([]) == 0.0
