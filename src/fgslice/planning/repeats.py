"""Strategy 2's layers whose regions repeat an earlier layer's reuse its finished plan.

A prismatic part whose material field does not vary with height (a bar graded along x,
the paper's color palette object) has the same outline and the same color faces on many
layers. Strategy 2's toolpaths, their order and their G-code moves depend on the layer's
regions, its thickness and the parity of its index only (odd layers traverse the palette
in reverse, rectilinear fill turns by 90 degrees; the layer's height above the bed is in
the plan, not in its moves). So a layer whose regions are identical to those of an
earlier layer of the same parity (same vertices in the same order,
``shapely.equals_identical``, and the same thickness) takes that layer's plan instead of
computing it again: the G-code is byte-identical either way. (The job's settings are the
same for every layer; the pipeline neither keeps nor reuses the first layer, which also
holds the skirt.)

Each process keeps its own :class:`RepeatedLayers` (with workers, each worker reuses only
the layers it computed itself), holding one layer per parity, so memory stays bounded.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import shapely

from fgslice.planning.plan import LayerPlan, PackedSteps
from fgslice.slicing.layers import LayerRegions


@dataclass
class RepeatedLayers:
    """The last layer kept of each index parity: its regions, its plan's columns and the
    result the caller keeps with them (the pipeline's per-layer result)."""

    kept: dict[int, tuple[LayerRegions, PackedSteps, Any]] = field(default_factory=dict)

    def find(self, regions: LayerRegions) -> tuple[LayerPlan, Any] | None:
        """For a layer whose regions equal exactly those kept for its parity: that layer's
        plan re-labelled as this layer's (its columns shared, not copied) and the result
        kept with it; else None."""
        entry = self.kept.get(regions.index % 2)
        if entry is None or not _same_regions(entry[0], regions):
            return None
        _, columns, result = entry
        return LayerPlan.from_packed(regions.index, regions.z, regions.height, columns), result

    def keep(self, regions: LayerRegions, plan: LayerPlan, result: Any) -> None:
        """Keep ``plan`` (built from ``regions``) and ``result`` for later layers of the same
        parity, in place of the layer kept before. Only a packed plan is kept, its columns
        made read-only: every layer that reuses them shares them (whoever unpacks the plan
        later gets paths whose points are views of them)."""
        if plan.packed is None:
            return
        _read_only(plan.packed)
        self.kept[regions.index % 2] = (regions, plan.packed, result)


def _read_only(columns: Any) -> None:
    """Make every array of a dataclass (and of the dataclasses it holds) read-only."""
    for item in dataclasses.fields(columns):
        value = getattr(columns, item.name)
        if isinstance(value, np.ndarray):
            value.flags.writeable = False
        elif dataclasses.is_dataclass(value):
            _read_only(value)


def _same_regions(a: LayerRegions, b: LayerRegions) -> bool:
    """Whether two layers have the same thickness, outline and faces, vertex for vertex."""
    if a.height != b.height or len(a.faces) != len(b.faces):
        return False
    if not shapely.equals_identical(a.outline, b.outline):
        return False
    faces_a = np.asarray(a.faces, dtype=object)
    faces_b = np.asarray(b.faces, dtype=object)
    return bool(shapely.equals_identical(faces_a, faces_b).all())
