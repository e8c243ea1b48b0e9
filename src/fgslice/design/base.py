"""The interface every stage after design input relies on.

A :class:`Design` is geometry plus materials, both as fields over the design frame
(millimetres; OpenVCAD's frame: primitives centered at the origin). Everything
downstream — slicing, analysis, previews — uses only the members declared here.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import shapely


@dataclass(frozen=True)
class Material:
    """A base material: its name and display color (RGBA, each in [0, 1])."""

    name: str
    rgba: tuple[float, float, float, float]


class Design(ABC):
    """Geometry (signed distance, negative inside) and material volume fractions.

    Conventions: millimetres; arrays of coordinates are broadcast-compatible 1-D or
    N-D numpy float arrays; results have their broadcast shape.
    """

    @property
    @abstractmethod
    def materials(self) -> list[Material]:
        """The base materials, in the order of :meth:`fractions`' columns."""

    @abstractmethod
    def sdf(self, x: np.ndarray, y: np.ndarray, z: np.ndarray) -> np.ndarray:
        """Signed distance to the surface in mm (negative inside), shape of the broadcast."""

    @abstractmethod
    def fractions(self, x: np.ndarray, y: np.ndarray, z: np.ndarray) -> np.ndarray:
        """Normalized volume fractions, shape ``broadcast + (k,)``; each row sums to 1.

        Raw values are clamped to [0, 1] then divided by their sum. Where the raw values
        sum to 0 the first material is returned (and :meth:`check` reports it).
        """

    @abstractmethod
    def bounds(self) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
        """Axis-aligned bounding box ``((minx, miny, minz), (maxx, maxy, maxz))`` in mm."""

    @abstractmethod
    def section(self, z: float) -> shapely.MultiPolygon:
        """The outline of the part in the plane at height ``z`` (design frame), valid."""

    def sections(self, zs: Sequence[float]) -> list[shapely.MultiPolygon]:
        """The outlines at every height of ``zs`` (design frame), in order: :meth:`section`
        at each; designs that compute many planes faster together override it."""
        return [self.section(float(z)) for z in zs]

    def prepare_sections(self) -> None:
        """Build now, once, what :meth:`section` needs for any single plane, so that worker
        processes forked afterwards share it instead of each building it (a mesh's tables);
        designs that need nothing leave it alone."""
