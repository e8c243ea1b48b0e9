"""The rectangular part of OpenVCAD 3's ``pyvcad_metamaterials`` module.

A design script imports this module as ``pyvcad_metamaterials`` (see
:mod:`fgslice.compat.script`). It builds :mod:`fgslice.design.lattice` nodes:

* ``rectangular_cell_map((lo, hi), cells=(nu, nv, nw))`` or ``cell_size=...`` (rounded up
  to whole cells, so the box stays exact): a box split into cells;
* ``tpms(cell_map, cell, mode="sheet", wall_thickness=1.0, level=0.0)`` and one builder per
  name of :data:`TPMS_NAMES` (``gyroid(cell_map, ...)``...): the TPMS sheet
  (``|d - level| <= wall_thickness / 2``) or solid (``d <= level``), ``d`` being the
  distance to the surface in mm, clipped to the map's box;
* ``graph_lattice(cell_map, cell, beam_radius=0.5, node_radius=None)`` and one builder
  per name of :data:`LATTICE_NAMES` (``octet(cell_map, ...)``...): struts of
  ``beam_radius`` along the cell's edges in every cell, balls of ``node_radius`` at its
  vertices when given, clipped to the map's box. ``curve_tolerance`` is accepted: a
  rectangular map keeps every beam straight;
* ``ImplicitUnitCell.standard(name)`` and ``GraphUnitCell(vertices, edges, ...)``: cells
  in the unit cube ``[0, 1]^3``.

Lengths are mm. ``wall_thickness``, ``level``, ``beam_radius`` and ``node_radius`` may be
graded: a number, an fgslice expression string, a Python function ``f(x, y, z)`` of numpy
arrays, or an OpenVCAD 3 attribute (anything with ``to_field()``), in the lattice's frame.
Names outside this subset (conformal maps, ``mix``, ``properties``...) fail by name.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Sequence

import numpy as np

from fgslice.compat.pyvcad import Vec3, _Leaf, _unsupported
from fgslice.design import lattice
from fgslice.errors import DesignError

_DOCS = "see the supported subset in docs/language.md (lattices and TPMS)"

TPMS_NAMES = tuple(lattice.TPMS_SURFACES)
"""The standard TPMS cells."""

LATTICE_NAMES = lattice.GRAPH_CELLS
"""The standard graph cells."""

__all__ = [
    "TPMS_NAMES", "LATTICE_NAMES", "CellMap", "rectangular_cell_map", "ImplicitUnitCell", "GraphUnitCell",
    "tpms", "graph_lattice", *TPMS_NAMES, *LATTICE_NAMES,
]


def __getattr__(name: str):
    if name.startswith("__"):
        raise AttributeError(name)
    raise _unsupported("pyvcad_metamaterials", name)


def _point(owner: str, what: str, value) -> np.ndarray:
    """A Vec3 or 3 numbers as an array (mm)."""
    if isinstance(value, Vec3):
        return np.array(tuple(value))
    if isinstance(value, Sequence) and len(value) == 3 and all(
            isinstance(v, numbers.Real) and not isinstance(v, bool) for v in value):
        return np.asarray(value, dtype=float)
    raise DesignError(f"{owner}: {what} must be a pyvcad.Vec3 or 3 numbers, got {value!r}", hint=_DOCS)


class CellMap:
    """A box ``lo``..``hi`` (mm) split into ``cells`` equal cells per axis."""

    def __init__(self, lo: np.ndarray, hi: np.ndarray, cells: tuple[int, int, int]) -> None:
        self.lo, self.hi, self.cells = lo, hi, cells

    @property
    def cell_size(self) -> np.ndarray:
        """The size of one cell (mm per axis)."""
        return (self.hi - self.lo) / np.asarray(self.cells)

    def __getattr__(self, name: str):
        if name.startswith("__"):
            raise AttributeError(name)
        raise _unsupported("CellMap", name)


def rectangular_cell_map(bounds, cells=None, cell_size=None) -> CellMap:
    """The box ``bounds = (lo, hi)`` split into ``cells = (nu, nv, nw)`` cells, or into
    cells of about ``cell_size`` (a number or 3; counts rounded up)."""
    owner = "rectangular_cell_map"
    if not isinstance(bounds, Sequence) or len(bounds) != 2:
        raise DesignError(f"{owner}: bounds must be a (min, max) pair of pyvcad.Vec3, got {bounds!r}", hint=_DOCS)
    lo, hi = (_point(owner, what, v) for what, v in zip(("the minimum corner", "the maximum corner"), bounds))
    if not np.all(hi > lo):
        raise DesignError(f"{owner}: the maximum corner must be above the minimum on every axis, got {bounds!r}")
    if (cells is None) == (cell_size is None):
        raise DesignError(f"{owner}: give either cells=(nu, nv, nw) or cell_size=...", hint=_DOCS)
    if cells is not None:
        if isinstance(cells, numbers.Integral) and not isinstance(cells, bool):
            cells = (cells,) * 3
        if (not isinstance(cells, Sequence) or len(cells) != 3
                or not all(isinstance(c, numbers.Integral) and not isinstance(c, bool) and c > 0 for c in cells)):
            raise DesignError(f"{owner}: cells must be 3 positive whole numbers, got {cells!r}")
        return CellMap(lo, hi, tuple(int(c) for c in cells))
    size = _point(owner, "cell_size", (cell_size,) * 3 if isinstance(cell_size, numbers.Real) else cell_size)
    if not np.all(size > 0):
        raise DesignError(f"{owner}: cell_size must be positive, got {cell_size!r}")
    return CellMap(lo, hi, tuple(max(1, math.ceil(round(float(n), 9))) for n in (hi - lo) / size))


def _cell_map(owner: str, cell_map) -> CellMap:
    if not isinstance(cell_map, CellMap):
        raise DesignError(f"{owner}: the first argument is a cell map (rectangular_cell_map(...)), "
                          f"got {type(cell_map).__name__}", hint=_DOCS)
    return cell_map


class ImplicitUnitCell:
    """A periodic scalar field over the unit cell; ``ImplicitUnitCell.standard(name)``."""

    def __init__(self, name: str) -> None:
        self.name = name

    @staticmethod
    def standard(name: str) -> ImplicitUnitCell:
        """The standard TPMS cell ``name`` (one of :data:`TPMS_NAMES`)."""
        key = name.lower().replace("-", "_") if isinstance(name, str) else name
        if key not in TPMS_NAMES:
            raise DesignError(f"ImplicitUnitCell.standard: unknown cell {name!r}", hint=f"the cells are {', '.join(TPMS_NAMES)}")
        return ImplicitUnitCell(key)

    def validate_periodicity(self) -> bool:
        """Whether the field repeats across opposite faces (the standard cells do)."""
        return True

    def __getattr__(self, name: str):
        if name.startswith("__"):
            raise AttributeError(name)
        raise _unsupported("ImplicitUnitCell", name)


class GraphUnitCell:
    """``GraphUnitCell(vertices, edges, vertex_tags=None, edge_tags=None, ...)``: vertices
    (Vec3 in the unit cube) joined by edges (pairs of vertex indices). Tags are accepted
    and carry no geometry."""

    def __init__(self, vertices, edges, **tags) -> None:
        unknown = sorted(set(tags) - {"vertex_tags", "edge_tags", "orientation_tags", "material_tags"})
        if unknown:
            raise DesignError(f"GraphUnitCell has no argument '{unknown[0]}'", hint=_DOCS)
        if isinstance(vertices, str) or not isinstance(vertices, Sequence) or not vertices:
            raise DesignError("GraphUnitCell: vertices must be a non-empty list of pyvcad.Vec3", hint=_DOCS)
        points = np.array([_point("GraphUnitCell", "a vertex", v) for v in vertices])
        pairs = []
        for edge in edges if isinstance(edges, Sequence) else [edges]:
            if (not isinstance(edge, Sequence) or len(edge) != 2
                    or not all(isinstance(i, numbers.Integral) and 0 <= i < len(points) for i in edge)):
                raise DesignError(f"GraphUnitCell: an edge is a pair of vertex indices below {len(points)}, got {edge!r}")
            pairs.append(tuple(edge))
        if not pairs:
            raise DesignError("GraphUnitCell needs at least one edge")
        self.vertices = points
        self.edges = points[np.array(pairs)]

    def __getattr__(self, name: str):
        if name.startswith("__"):
            raise AttributeError(name)
        raise _unsupported("GraphUnitCell", name)


class _Structure(_Leaf):
    """A lattice or TPMS node of this module."""


def tpms(cell_map, cell, mode: str = "sheet", wall_thickness=1.0, level=0.0) -> _Structure:
    """The TPMS ``cell`` (a name of :data:`TPMS_NAMES` or an ``ImplicitUnitCell``) over
    ``cell_map``: a ``"sheet"`` of ``wall_thickness`` around the surface shifted by
    ``level``, or the ``"solid"`` side ``d <= level`` (mm, may be graded)."""
    cell_map = _cell_map("tpms", cell_map)
    name = cell.name if isinstance(cell, ImplicitUnitCell) else ImplicitUnitCell.standard(cell).name
    if mode not in ("sheet", "solid"):
        raise DesignError(f'{name}: mode is "sheet" or "solid", got {mode!r}')
    thickness = lattice.Length(name, "wall_thickness", wall_thickness) if mode == "sheet" else None
    node = lattice.TPMS(lattice.tpms_surface(name), cell_map.cell_size, cell_map.lo, (cell_map.lo, cell_map.hi),
                        mode=mode, thickness=thickness, level=lattice.Length(name, "level", level, positive=False))
    return _Structure(node)


def graph_lattice(cell_map, cell, beam_radius=0.5, node_radius=None, curve_tolerance=None) -> _Structure:
    """Struts along the edges of ``cell`` (a name of :data:`LATTICE_NAMES` or a
    ``GraphUnitCell``) in every cell of ``cell_map``, of ``beam_radius``, with balls of
    ``node_radius`` at the cell's vertices when given (mm, may be graded)."""
    cell_map = _cell_map("graph_lattice", cell_map)
    if isinstance(cell, GraphUnitCell):
        name, edges, vertices = "graph_lattice", cell.edges, cell.vertices
    else:
        name = cell
        edges = lattice.graph_cell(cell)
        vertices = np.unique(edges.reshape(-1, 3), axis=0)
    if curve_tolerance is not None and not (isinstance(curve_tolerance, numbers.Real) and curve_tolerance > 0):
        raise DesignError(f"{name}: curve_tolerance must be a positive number, got {curve_tolerance!r}")
    size = cell_map.cell_size
    beam = lattice.Length(name, "beam_radius", beam_radius)
    joint = None if node_radius is None else lattice.Length(name, "node_radius", node_radius)
    node = lattice.StrutLattice(edges * size + cell_map.lo, beam, joints=vertices * size + cell_map.lo, joint=joint,
                                period=size, origin=cell_map.lo, window=(cell_map.lo, cell_map.hi))
    return _Structure(node)


def _tpms_builder(name: str):
    def build(cell_map, mode: str = "sheet", wall_thickness=1.0, level=0.0) -> _Structure:
        return tpms(cell_map, name, mode=mode, wall_thickness=wall_thickness, level=level)

    build.__name__ = build.__qualname__ = name
    build.__doc__ = f"``tpms(cell_map, '{name}', ...)``."
    return build


def _lattice_builder(name: str):
    def build(cell_map, beam_radius=0.5, node_radius=None, curve_tolerance=None) -> _Structure:
        return graph_lattice(cell_map, name, beam_radius=beam_radius, node_radius=node_radius,
                             curve_tolerance=curve_tolerance)

    build.__name__ = build.__qualname__ = name
    build.__doc__ = f"``graph_lattice(cell_map, '{name}', ...)``."
    return build


globals().update({name: _tpms_builder(name) for name in TPMS_NAMES})
globals().update({name: _lattice_builder(name) for name in LATTICE_NAMES})
