"""The toolpath model: polylines with a role, a palette color, a width and a height.

A :class:`Path` holds its points as one ``(N, 2)`` float array in the bed frame (mm); no
Python object per point. ``closed`` paths return to their first point (the first point
is *not* repeated in ``points``).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from enum import Enum

import numpy as np


class Role(Enum):
    """What a path is, with PrusaSlicer's ``;TYPE:`` names as values."""

    EXTERNAL_PERIMETER = "External perimeter"
    PERIMETER = "Perimeter"
    INTERNAL_INFILL = "Internal infill"
    SOLID_INFILL = "Solid infill"
    TOP_SOLID_INFILL = "Top solid infill"
    BOTTOM_SOLID_INFILL = "Bottom solid infill"
    WIPE_TOWER = "Wipe tower"
    SKIRT = "Skirt/Brim"
    CUSTOM = "Custom"
    SUPPORT = "Support material"
    SUPPORT_INTERFACE = "Support material interface"
    BRIDGE_INFILL = "Bridge infill"


@dataclass(eq=False)
class Path:
    """One extrusion polyline.

    Treated as immutable: stages make new paths (``with_color``, the constructor) rather
    than assign to a path's fields. The class is not ``frozen`` only because a frozen
    dataclass's constructor costs about six times more, and a layer makes hundreds of
    thousands of paths when cutting into colors.

    Attributes:
        points: ``(N, 2)`` float64 array of XY positions in the bed frame, mm; N >= 2.
        role: what the path is.
        color: palette color index (0-based) the path is printed in.
        width: bead width, mm.
        height: bead height (layer height), mm.
        closed: True if the path returns from its last point to its first.
        group: -1, or the id of a unit of paths printed together in their list order
            (the walls of one island, holes included); planning keeps that order.
    """

    points: np.ndarray
    role: Role
    color: int
    width: float
    height: float
    closed: bool = False
    group: int = -1

    def with_color(self, color: int) -> "Path":
        """The same path in ``color`` (this path itself when it has that color already)."""
        return self if color == self.color else replace(self, color=color)

    @property
    def vertices(self) -> np.ndarray:
        """All vertices in printing order, the first repeated at the end if closed."""
        if self.closed:
            return np.vstack([self.points, self.points[:1]])
        return self.points

    @property
    def length(self) -> float:
        """Printed length, mm (including the closing segment of a closed path)."""
        return float(np.sum(np.hypot(*np.diff(self.vertices, axis=0).T)))

    @property
    def start(self) -> np.ndarray:
        """First point (where printing begins)."""
        return self.points[0]

    @property
    def end(self) -> np.ndarray:
        """Last point printed (the first point again for closed paths)."""
        return self.points[0] if self.closed else self.points[-1]


def bead_area(width: float, height: float) -> float:
    """Cross-section of a bead, mm², by the capsule model: ``h (w - h) + pi h^2 / 4``."""
    return height * (width - height) + np.pi * height * height / 4.0


@dataclass
class LayerPaths:
    """All toolpaths of one layer, unordered, in the bed frame.

    Attributes:
        index: 0-based layer number.
        z: nozzle height for this layer (top of the layer), mm.
        height: layer thickness, mm.
        paths: the layer's paths (any order; planning orders them).
        uncovered_mm2: area of the outline that no path covers because it is narrower
            than a bead (reported, never printed as garbage).
        reassigned_mm2: area of color faces too narrow for a bead given to a
            neighbouring color before filling (strategy 2), mm^2.
        thin_dropped_mm2: area of the features narrower than ``min_feature_size`` that
            no single bead prints (:mod:`~fgslice.toolpaths.thin_features`), mm^2.
        commanded: attribute name -> ``(min, max)`` of the values the layer's toolpaths
            were made for (strategy 1's ``infill_density``, percent); the writer reports
            the attributes it writes itself.
    """

    index: int
    z: float
    height: float
    paths: list[Path] = field(default_factory=list)
    uncovered_mm2: float = 0.0
    reassigned_mm2: float = 0.0
    thin_dropped_mm2: float = 0.0
    commanded: dict[str, tuple[float, float]] = field(default_factory=dict)
