"""Does a slice print the part it was given? Checked from per-layer totals, after slicing.

Each layer reports its outline's area (mm^2) and the volume of its part's paths (mm^3,
skirt and purge tower left out: :func:`part_volume`); :func:`check_coverage` then refuses
a slice that prints nothing and warns about one whose part is partly missing:

* every section empty (a mesh of zero-area triangles, a field that is NaN everywhere):
  refused, nothing is written;
* sections that no bead fits in anywhere (a pin thinner than ``bead_width``): refused;
* strategy 2 (every face filled densely), an extruded volume more than
  :data:`VOLUME_TOLERANCE` away from the sections' volume (``area x layer height``):
  a warning with both volumes;
* an area left unprinted because it is narrower than a bead over more than
  :data:`UNCOVERED_SHARE` of the sections' area, or more than
  :data:`UNCOVERED_MM2_PER_LAYER` a layer on average: a warning naming ``bead_width``.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from fgslice.errors import SliceError
from fgslice.toolpaths.paths import Path, Role, bead_area

VOLUME_TOLERANCE = 0.03
"""Strategy 2 warns when the part's extruded volume is further than this share from its sections'."""

UNCOVERED_SHARE = 0.01
"""Warn when more than this share of the sections' area is narrower than a bead and not printed."""

UNCOVERED_MM2_PER_LAYER = 2.0
"""... or more than this area per layer on average (mm^2): on a large part 1 % is
hundreds of mm^2 a layer. As much as a layer may keep of its slivers
(:data:`fgslice.toolpaths.slivers.MAX_KEPT_MM2`)."""


def part_volume(paths: Iterable[Path]) -> float:
    """Volume (mm^3) the part's paths deposit: bead cross-section x length (closing
    segments of closed paths included), skirt and purge tower left out. One pass over
    all the paths' points: a layer holds up to thousands of paths."""
    kept = [p for p in paths if p.role not in (Role.SKIRT, Role.WIPE_TOWER)]
    if not kept:
        return 0.0
    counts = np.fromiter((len(p.points) for p in kept), np.int64, len(kept))
    points = np.concatenate([p.points for p in kept])
    lasts = np.cumsum(counts) - 1
    firsts = lasts - counts + 1
    segments = np.hypot(*np.diff(points, axis=0).T)
    segments[lasts[:-1]] = 0.0  # from one path's end to the next path's start: no bead
    areas = bead_area(np.fromiter((p.width for p in kept), float, len(kept)),
                      np.fromiter((p.height for p in kept), float, len(kept)))
    closed = np.fromiter((p.closed for p in kept), bool, len(kept))
    closing = np.where(closed, np.hypot(*(points[lasts] - points[firsts]).T), 0.0)
    owner = np.repeat(np.arange(len(kept)), counts)[:-1]
    return float(np.dot(segments, areas[owner]) + np.dot(closing, areas))


def check_coverage(section_mm3: float, section_mm2: float, part_mm3: float, uncovered_mm2: float,
                   strategy: int, bead_width: float, layers: int | None = None) -> list[str]:
    """Warnings about a slice whose part is partly missing (see the module docstring).

    Args:
        section_mm3: the sections' volume, sum of area x layer height, mm^3.
        section_mm2: the sections' area summed over the layers, mm^2.
        part_mm3: what the part's paths deposit, mm^3 (:func:`part_volume`).
        uncovered_mm2: area narrower than a bead that no path covers, all layers, mm^2.
        strategy: 1 or 2.
        bead_width: mm.
        layers: the layer count (None: the share of the area alone decides).

    Raises:
        SliceError: the slice prints nothing of the part.
    """
    if section_mm3 <= 0:
        raise SliceError(
            "nothing to print: every layer's section of the part is empty",
            hint="run 'fgslice check' on the design: a mesh of flat or zero-area triangles, or a shape "
                 "whose distance is NaN or infinite everywhere, has no inside",
        )
    if part_mm3 <= 0:
        raise SliceError(
            f"nothing to print: the part ({section_mm3:.3g} mm^3) is narrower than a bead "
            f"(bead_width = {bead_width:g} mm) everywhere",
            hint="lower bead_width (with a smaller nozzle), or scale the part up; with thin_features on, "
                 "parts at least min_feature_size wide print as single beads (lower min_feature_size)",
        )
    warnings = []
    if strategy == 2 and abs(part_mm3 - section_mm3) > VOLUME_TOLERANCE * section_mm3:
        warnings.append(
            f"the part's toolpaths extrude {part_mm3 / 1000:.3f} cm3 for sections of {section_mm3 / 1000:.3f} cm3 "
            f"({100 * (part_mm3 / section_mm3 - 1):+.1f} %): the print will be "
            f"{'over' if part_mm3 > section_mm3 else 'under'}-filled (features a few beads wide lose their "
            "corners: a smaller bead_width fits them better)"
        )
    limit = UNCOVERED_SHARE * section_mm2
    if layers:
        limit = min(limit, UNCOVERED_MM2_PER_LAYER * layers)
    if uncovered_mm2 > limit:
        warnings.append(
            f"{uncovered_mm2:.1f} mm^2 of the sections ({100 * uncovered_mm2 / section_mm2:.1f} %) are narrower "
            f"than a bead (bead_width = {bead_width:g} mm) and are not printed; lower bead_width to print them"
        )
    return warnings


def mesh_warnings(design) -> list[str]:
    """A warning per mesh of ``design`` that is not watertight (what ``fgslice check``
    says too): its sections are closed by stitching, and near its holes a part of the
    solid may be missing."""
    return [f"mesh {mesh.path} is not watertight: its sections are closed by stitching and may lose part "
            "of the solid near its holes (check the preview, or repair the mesh)"
            for mesh in getattr(design, "meshes", ()) if not mesh.geometry.watertight]
