"""A design scaled uniformly before it is placed on the bed (the ``scale`` setting).

As PrusaSlicer's ``--scale``: the whole design, geometry and material fields alike,
grows or shrinks by one factor about its own origin, so the fractions at a scaled point
are those at the point it came from.
"""

from __future__ import annotations

from fgslice.design import api
from fgslice.design.base import Design
from fgslice.design.nodes import NodeDesign


def scaled(design: Design, factor: float) -> Design:
    """``design`` scaled by ``factor`` about its origin (itself when the factor is 1)."""
    if factor == 1.0:
        return design
    hint = None
    if design.hint_bounds is not None:
        hint = tuple(tuple(factor * v for v in corner) for corner in design.hint_bounds)
    return NodeDesign(api.scale((factor,) * 3, design.root), design.library, hint_bounds=hint,
                      voxel_size=design.voxel_size, section_spacing=design.section_spacing, source=design.source)
