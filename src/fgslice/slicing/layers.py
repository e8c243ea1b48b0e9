"""Plain data produced by slicing: where the part sits on the bed and each layer's regions.

Frames: the *design frame* is the one fields are evaluated in; the *bed frame* is the
printer's (mm, origin at the bed's front-left corner, z = 0 on the bed). The two differ
by a translation only: ``bed = design + offset``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely


@dataclass(frozen=True)
class Placement:
    """Translation from the design frame to the bed frame: ``bed = design + offset`` (mm)."""

    offset: tuple[float, float, float]

    def to_design(self, x: np.ndarray, y: np.ndarray, z: np.ndarray | float):
        """Bed-frame coordinates to design-frame coordinates (same shapes)."""
        ox, oy, oz = self.offset
        return np.asarray(x) - ox, np.asarray(y) - oy, np.asarray(z) - oz

    def to_bed(self, x: np.ndarray, y: np.ndarray, z: np.ndarray | float):
        """Design-frame coordinates to bed-frame coordinates (same shapes)."""
        ox, oy, oz = self.offset
        return np.asarray(x) + ox, np.asarray(y) + oy, np.asarray(z) + oz


@dataclass(frozen=True)
class LayerRegions:
    """One layer after slicing, in the bed frame.

    Attributes:
        index: 0-based layer number from the bed up.
        z: height of the top of this layer above the bed (the nozzle height), mm.
        height: layer thickness, mm; the slicing plane is at ``z - height / 2``.
        outline: the part's cross-section at the slicing plane.
        faces: one geometry per palette color (index = color), disjoint, together
            equal to ``outline``; an empty geometry where a color is absent.
    """

    index: int
    z: float
    height: float
    outline: shapely.MultiPolygon
    faces: tuple[shapely.Geometry, ...]

    @property
    def z_plane(self) -> float:
        """Bed-frame height of the slicing plane (mid-height of the layer), mm."""
        return self.z - self.height / 2
