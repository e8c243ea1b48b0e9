"""OpenVCAD 3's leaves and volume data that :mod:`fgslice.compat.pyvcad_v3` serves under ``pyvcad``.

* ``Cone(angle, height)`` (:class:`fgslice.design.cone.Cone`);
* ``MappedImplicitLattice``, ``MappedGraphLattice`` (the metamaterial module's TPMS and
  graph lattices on rectangular cell maps) and ``CellMap``, ``ImplicitUnitCell``,
  ``GraphUnitCell``;
* ``DICOMLoader(folder).as_volume()`` -> ``FloatVolume`` (:mod:`fgslice.design.volumes`);
* the OpenVDB names (``SignedDistanceField``, ``Vec2sVolume``, ``Vec3sVolume``,
  ``Vec4sVolume``, ``vdb_loader``), refused with the reason as soon as a script uses them.
"""

from __future__ import annotations

from os import PathLike
from pathlib import Path

import numpy as np

from fgslice.compat import context
from fgslice.compat import pyvcad as v2
from fgslice.compat import pyvcad_metamaterials as mm
from fgslice.design.cone import Cone as _ConeNode
from fgslice.design.volumes import ScalarVolume, load_dicom_series
from fgslice.errors import DesignError

_DOCS = "see the OpenVCAD 3 section of docs/language.md"

__all__ = ["Cone", "MappedImplicitLattice", "MappedGraphLattice", "CellMap", "ImplicitUnitCell", "GraphUnitCell",
           "FloatVolume", "DICOMLoader"]


class Cone(v2._Leaf):
    """``Cone(angle, height)`` or ``Cone()`` (0.5 rad, 1 mm): a solid cone, aperture
    half-angle ``angle`` (radians), apex at the origin, base disc at ``z = -height``
    (:class:`fgslice.design.cone.Cone`)."""

    def __init__(self, *args, **kwargs) -> None:
        angle, height = v2._bind("Cone", ("angle", "height"), args, kwargs, {"angle": 0.5, "height": 1.0})
        angle, height = v2._number("Cone", "angle", angle), v2._number("Cone", "height", height)
        if not 0 < angle < np.pi / 2:
            raise DesignError(f"Cone: the angle is the aperture half-angle in radians, in (0, pi/2), got {angle:g}",
                              hint="convert degrees with math.radians")
        if height <= 0:
            raise DesignError(f"Cone: the height must be positive, got {height:g}")
        super().__init__(_ConeNode(angle, height))


class MappedImplicitLattice(v2._Leaf):
    """``MappedImplicitLattice(cell_map, unit_cell, mode="sheet", wall_thickness=None,
    level=None)``: ``pyvcad_metamaterials.tpms`` (rectangular maps; ``None``: its
    defaults, 1 mm and 0)."""

    def __init__(self, cell_map, unit_cell, mode="sheet", wall_thickness=None, level=None) -> None:
        if not isinstance(unit_cell, mm.ImplicitUnitCell):
            raise DesignError(f"MappedImplicitLattice: unit_cell is a pv.ImplicitUnitCell, got {unit_cell!r}",
                              hint="pv.ImplicitUnitCell.standard('gyroid')")
        built = mm.tpms(cell_map, unit_cell, mode, 1.0 if wall_thickness is None else wall_thickness,
                        0.0 if level is None else level)
        super().__init__(built._node)


class MappedGraphLattice(v2._Leaf):
    """``MappedGraphLattice(cell_map, unit_cell, beam_radius, node_radius=None,
    curve_tolerance=0.05)``: ``pyvcad_metamaterials.graph_lattice`` (rectangular maps)."""

    def __init__(self, cell_map, unit_cell, beam_radius, node_radius=None, curve_tolerance=0.05) -> None:
        if not isinstance(unit_cell, mm.GraphUnitCell):
            raise DesignError(f"MappedGraphLattice: unit_cell is a pv.GraphUnitCell, got {unit_cell!r}", hint=_DOCS)
        built = mm.graph_lattice(cell_map, unit_cell, beam_radius, node_radius, curve_tolerance)
        super().__init__(built._node)


CellMap, ImplicitUnitCell, GraphUnitCell = mm.CellMap, mm.ImplicitUnitCell, mm.GraphUnitCell
"""The metamaterial module's cell maps and unit cells, under ``pyvcad`` as in OpenVCAD."""


class FloatVolume:
    """A scalar volume (from ``DICOMLoader(folder).as_volume()``): ``sample(x, y, z)``
    (trilinear, mm), ``bounding_box()`` (the voxels' outer corners, two Vec3), ``clone()``;
    ``FloatAttribute(volume)`` makes it a field (:class:`fgslice.design.volumes.ScalarVolume`)."""

    def __init__(self, volume: ScalarVolume) -> None:
        self.volume = volume

    def __getattr__(self, name: str):
        if name.startswith("__"):
            raise AttributeError(name)
        raise v2._unsupported("FloatVolume", name)

    def sample(self, x, y, z) -> float:
        """The value at ``(x, y, z)`` (mm)."""
        return float(self.volume(*(np.array([v2._number("FloatVolume.sample", n, v)]) for n, v in zip("xyz", (x, y, z))))[0])

    def bounding_box(self) -> tuple:
        """``(min, max)`` corners of the voxels (Vec3, mm)."""
        lo, hi = self.volume.bounds()
        return v2.Vec3(*lo), v2.Vec3(*hi)

    def clone(self) -> FloatVolume:
        """The same volume (volumes are read-only)."""
        return FloatVolume(self.volume)


class DICOMLoader:
    """``DICOMLoader(folder)``: the DICOM series in ``folder`` (pydicom;
    :func:`fgslice.design.volumes.load_dicom_series`); ``as_volume()`` gives its
    FloatVolume (rescaled values, commonly HU)."""

    def __init__(self, folder) -> None:
        if not isinstance(folder, (str, PathLike)):
            raise DesignError(f"DICOMLoader: the folder is a path, got {folder!r}")
        path, run = Path(folder), context.current()
        if not path.is_absolute() and run is not None and (run.path.resolve().parent / path).is_dir():
            path = run.path.resolve().parent / path  # the script's folder, then the cwd, as for meshes
        self._volume = FloatVolume(load_dicom_series(path))

    def __getattr__(self, name: str):
        if name.startswith("__"):
            raise AttributeError(name)
        raise v2._unsupported("DICOMLoader", name)

    def as_volume(self) -> FloatVolume:
        """The series' FloatVolume."""
        return self._volume
