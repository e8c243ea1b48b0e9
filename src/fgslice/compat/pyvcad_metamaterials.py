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

* a map's ``logical_position`` (position in cells across the map), ``unit_cell_phase``
  (0..1 inside each cell), ``cell_index`` (the cell's number) as ``Vec3Attribute``, and
  ``to_cell_frame(vector)`` (a ``Vec3Attribute`` in mm expressed in cells), from
  :class:`fgslice.design.cell_fields.CellGrid`;
* ``ramp(start, end, axis="x", smooth=False, coordinates=None)``: a weight, 0 up to
  ``start`` and 1 from ``end`` along ``x``/``y``/``z`` (mm) or ``u``/``v``/``w`` of
  ``coordinates`` (e.g. ``cell_map.logical_position``);
* ``ImplicitUnitCell.mixed(first, second, weight)``: a TPMS cell changing from ``first``
  to ``second`` (:class:`fgslice.design.lattice.MixedTPMS`);
* ``mix(first, second, weight)`` or ``mix(first, second, region=node, half_width=h)``:
  two bodies mixed by a weight (:mod:`fgslice.design.mix`); with a region, the first
  body inside it and the second outside, mixed across a band of ``2 h`` mm.

Lengths are mm. ``wall_thickness``, ``level``, ``beam_radius`` and ``node_radius`` may be
graded: a number, an fgslice expression string, a Python function ``f(x, y, z)`` of numpy
arrays, or an OpenVCAD 3 attribute (anything with ``to_field()``), in the lattice's frame.
* ``properties.characterize(node, voxel_size, bounds=None, periodic_axes="")`` and
  ``properties.characterize_graph_cell(cell, cell_size, beam_radius)``: the reports of
  :mod:`fgslice.analysis.characterize`.

Names outside this subset fail by name, with the reason for conformal maps
(``cell_map_from_surface``...), ``warp_cell_map``, ``mix_many`` and ``idw_weight``.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Sequence

import numpy as np

from fgslice.compat.pyvcad import Node, Vec3, _Leaf, _unsupported
from fgslice.design import lattice
from fgslice.design.cell_fields import CellGrid, ramp as _ramp, region_weight
from fgslice.design.mix import Mix
from fgslice.errors import DesignError

_DOCS = "see the supported subset in docs/language.md (lattices and TPMS)"

TPMS_NAMES = tuple(lattice.TPMS_SURFACES)
"""The standard TPMS cells."""

LATTICE_NAMES = lattice.GRAPH_CELLS
"""The standard graph cells."""

__all__ = [
    "TPMS_NAMES", "LATTICE_NAMES", "CellMap", "rectangular_cell_map", "ImplicitUnitCell", "GraphUnitCell",
    "tpms", "graph_lattice", "ramp", "mix", "properties", *TPMS_NAMES, *LATTICE_NAMES,
]

CONFORMAL_REASON = ("OpenVCAD's conformal cell maps flatten a surface into a chart and fill the offset volume with "
              "curved cells; fgslice implements rectangular cell maps only",
              "fill the part with a rectangular_cell_map(...) lattice clipped by Intersection, or export the "
              "conformal lattice from OpenVCAD as a mesh and slice the mesh")
_REFUSED = {
    "cell_map_from_surface": CONFORMAL_REASON, "cell_map_between_surfaces": CONFORMAL_REASON,
    "cell_map_from_cad_face": CONFORMAL_REASON, "cell_map_between_cad_faces": CONFORMAL_REASON,
    "warp_cell_map": ("how OpenVCAD turns its spacing weights (u_scale, which may be negative) into cell "
                      "boundaries is not documented, so fgslice cannot place the cells where OpenVCAD does",
                      "use rectangular maps of the cell sizes you want side by side, or grade wall_thickness / "
                      "beam_radius instead"),
    "mix_many": ("OpenVCAD does not document how it weights more than two bodies",
                 "nest mix(first, second, weight) calls"),
    "idw_weight": ("OpenVCAD does not document its inverse-distance weighting (power, cut-off)",
                   "give the weight as a FloatAttribute expression of the distance to your seed points"),
}
"""Names of OpenVCAD's module that fgslice refuses, with the reason and what to do instead."""

_REMOVED = {"cell": "the map's cells", "size": "the map's bounds", "bounds": "the map's bounds",
            "center": "the map's bounds", "thickness": "wall_thickness", "radius": "beam_radius"}
"""Arguments of the earlier builders, removed in OpenVCAD 3, and what replaces them."""


def __getattr__(name: str):
    if name.startswith("__"):
        raise AttributeError(name)
    if name in _REFUSED:
        reason, hint = _REFUSED[name]
        raise DesignError(f"pyvcad_metamaterials.{name} is not supported by fgslice: {reason}", hint=hint)
    raise _unsupported("pyvcad_metamaterials", name)


def _no_removed_arguments(owner: str, extra: dict) -> None:
    """A DesignError naming the first keyword of ``extra`` (earlier builder style or unknown)."""
    if not extra:
        return
    name = next(iter(extra))
    if name in _REMOVED:
        raise DesignError(f"{owner}: '{name}' is an argument of the earlier builders, removed in OpenVCAD 3 "
                          f"(use {_REMOVED[name]})",
                          hint="build the map first: cell_map = rectangular_cell_map((lo, hi), cells=(nu, nv, nw)), "
                               f"then {owner}(cell_map, ...)")
    raise DesignError(f"{owner} has no argument '{name}'", hint=_DOCS)


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

    @property
    def logical_position(self):
        """The position in cells across the map (0 .. cells per axis), a Vec3Attribute."""
        grid = CellGrid(self.lo, self.hi, self.cells)
        return _vector(tuple(grid.logical(axis) for axis in range(3)))

    @property
    def unit_cell_phase(self):
        """The position inside the current cell (0 .. 1 per axis), a Vec3Attribute."""
        grid = CellGrid(self.lo, self.hi, self.cells)
        return _vector(tuple(grid.phase(axis) for axis in range(3)))

    @property
    def cell_index(self):
        """The current cell's number per axis (0 .. cells - 1), a Vec3Attribute."""
        grid = CellGrid(self.lo, self.hi, self.cells)
        return _vector(tuple(grid.index(axis) for axis in range(3)))

    def to_cell_frame(self, vector):
        """The Vec3Attribute ``vector`` (mm) expressed in cells of this map."""
        return _vector(CellGrid(self.lo, self.hi, self.cells).to_cells(_vector_fields("CellMap.to_cell_frame", vector)))

    def __getattr__(self, name: str):
        if name.startswith("__"):
            raise AttributeError(name)
        raise _unsupported("CellMap", name)


def _vector(fields):
    from fgslice.compat.pyvcad_v3 import Vec3Attribute

    attribute = Vec3Attribute.__new__(Vec3Attribute)
    attribute.fields = fields
    return attribute


def _vector_fields(owner: str, value) -> tuple:
    from fgslice.compat.pyvcad_v3 import Vec3Attribute

    if not isinstance(value, Vec3Attribute):
        raise DesignError(f"{owner} takes a pyvcad.Vec3Attribute, got {type(value).__name__}", hint=_DOCS)
    return value.fields


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

    def __init__(self, name: str, mixed: tuple | None = None) -> None:
        self.name = name
        self.mixed_from = mixed
        """``(first, second, weight)`` of a mixed cell, else None."""

    @staticmethod
    def mixed(first, second, weight) -> ImplicitUnitCell:
        """A cell changing from the standard cell ``first`` (weight 0) to ``second``
        (weight 1); ``weight`` a number, expression or FloatAttribute, clamped to 0..1."""
        cells = []
        for what, cell in (("first", first), ("second", second)):
            if not isinstance(cell, ImplicitUnitCell) or cell.mixed_from is not None:
                raise DesignError(f"ImplicitUnitCell.mixed: the {what} cell must be ImplicitUnitCell.standard(name), "
                                  f"got {cell!r}", hint=_DOCS)
            cells.append(cell)
        weight = lattice.Length("ImplicitUnitCell.mixed", "weight", weight, positive=False)
        return ImplicitUnitCell(f"{cells[0].name}-{cells[1].name}", (cells[0].name, cells[1].name, weight))

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


def tpms(cell_map=None, cell=None, mode: str = "sheet", wall_thickness=1.0, level=0.0, **extra) -> _Structure:
    """The TPMS ``cell`` (a name of :data:`TPMS_NAMES` or an ``ImplicitUnitCell``) over
    ``cell_map``: a ``"sheet"`` of ``wall_thickness`` around the surface shifted by
    ``level``, or the ``"solid"`` side ``d <= level`` (mm, may be graded)."""
    _no_removed_arguments("tpms", extra)
    cell_map = _cell_map("tpms", cell_map)
    name = cell.name if isinstance(cell, ImplicitUnitCell) else ImplicitUnitCell.standard(cell).name
    if mode not in ("sheet", "solid"):
        raise DesignError(f'{name}: mode is "sheet" or "solid", got {mode!r}')
    thickness = lattice.Length(name, "wall_thickness", wall_thickness) if mode == "sheet" else None
    options = dict(mode=mode, thickness=thickness, level=lattice.Length(name, "level", level, positive=False))
    box = (cell_map.lo, cell_map.hi)
    if isinstance(cell, ImplicitUnitCell) and cell.mixed_from is not None:
        first, second, weight = cell.mixed_from
        node = lattice.MixedTPMS((lattice.tpms_surface(first), lattice.tpms_surface(second)), weight,
                                 cell_map.cell_size, cell_map.lo, box, **options)
    else:
        node = lattice.TPMS(lattice.tpms_surface(name), cell_map.cell_size, cell_map.lo, box, **options)
    return _Structure(node)


def graph_lattice(cell_map=None, cell=None, beam_radius=0.5, node_radius=None, curve_tolerance=None,
                  **extra) -> _Structure:
    """Struts along the edges of ``cell`` (a name of :data:`LATTICE_NAMES` or a
    ``GraphUnitCell``) in every cell of ``cell_map``, of ``beam_radius``, with balls of
    ``node_radius`` at the cell's vertices when given (mm, may be graded)."""
    _no_removed_arguments("graph_lattice", extra)
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


_AXES = {"x": 0, "y": 1, "z": 2, "u": 0, "v": 1, "w": 2}


def ramp(start, end, axis: str = "x", smooth: bool = False, coordinates=None):
    """A FloatAttribute weight: 0 up to ``start``, 1 from ``end``, linear between (a
    smoothstep with ``smooth``), along ``x``/``y``/``z`` (mm, the consuming node's frame)
    or ``u``/``v``/``w``, the channels of ``coordinates`` (a Vec3Attribute such as
    ``cell_map.logical_position``)."""
    from fgslice.compat.pyvcad_v3_fields import _new_float

    owner = "ramp"
    if axis not in _AXES:
        raise DesignError(f'{owner}: axis is one of "x", "y", "z", "u", "v", "w", got {axis!r}', hint=_DOCS)
    lo, hi = (_number(owner, what, v) for what, v in (("start", start), ("end", end)))
    if not hi > lo:
        raise DesignError(f"{owner}: end must be above start, got start={lo:g}, end={hi:g}")
    if coordinates is None:
        if axis in "uvw":
            raise DesignError(f'{owner}: axis "{axis}" is a logical axis: give coordinates=cell_map.logical_position',
                              hint=_DOCS)
        coordinate = ("x", "y", "z")[_AXES[axis]]
    else:
        coordinate = _vector_fields(f"{owner}: coordinates", coordinates)[_AXES[axis]]
    return _new_float(_ramp(lo, hi, coordinate, smooth=bool(smooth)))


def _number(owner: str, what: str, value) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(value):
        raise DesignError(f"{owner}: {what} must be a finite number, got {value!r}", hint=_DOCS)
    return float(value)


class _Mixed(Node):
    """What :func:`mix` returns: two bodies mixed by a weight (:class:`fgslice.design.mix.Mix`)."""

    def __init__(self, first: Node, second: Node, weight, region: Node | None, half_width: float | None) -> None:
        super().__init__()
        self._first, self._second, self._weight = first, second, weight
        self._region, self._half_width = region, half_width

    def _build(self, convert):
        weight = self._weight
        if self._region is not None:
            weight = region_weight(convert(self._region).sdf, self._half_width)
        return Mix(convert(self._first), convert(self._second), lattice.Length("mix", "weight", weight, positive=False))


def mix(first, second, weight=None, region=None, half_width=None) -> Node:
    """``first`` where ``weight`` is 0, ``second`` where it is 1, their shapes mixed
    between; or, with ``region`` (a node) and ``half_width`` (mm), ``first`` inside the
    region and ``second`` outside, mixed across the band within ``half_width`` of its
    surface."""
    for what, body in (("first", first), ("second", second)):
        if not isinstance(body, Node):
            raise DesignError(f"mix: the {what} body must be a pyvcad node, got {type(body).__name__}", hint=_DOCS)
    if (weight is None) == (region is None):
        raise DesignError("mix: give either a weight or region=... with half_width=...", hint=_DOCS)
    if region is not None:
        if not isinstance(region, Node):
            raise DesignError(f"mix: region must be a pyvcad node, got {type(region).__name__}", hint=_DOCS)
        half_width = _number("mix", "half_width", half_width)
        if half_width <= 0:
            raise DesignError(f"mix: half_width must be positive, got {half_width:g}")
        return _Mixed(first, second, None, region, half_width)
    if half_width is not None:
        raise DesignError("mix: half_width goes with region=...; a weight field sets the blend itself", hint=_DOCS)
    lattice.Length("mix", "weight", weight, positive=False)
    return _Mixed(first, second, weight, None, None)


def _tpms_builder(name: str):
    def build(cell_map=None, mode: str = "sheet", wall_thickness=1.0, level=0.0, **extra) -> _Structure:
        _no_removed_arguments(name, extra)
        return tpms(cell_map, name, mode=mode, wall_thickness=wall_thickness, level=level)

    build.__name__ = build.__qualname__ = name
    build.__doc__ = f"``tpms(cell_map, '{name}', ...)``."
    return build


def _lattice_builder(name: str):
    def build(cell_map=None, beam_radius=0.5, node_radius=None, curve_tolerance=None, **extra) -> _Structure:
        _no_removed_arguments(name, extra)
        return graph_lattice(cell_map, name, beam_radius=beam_radius, node_radius=node_radius,
                             curve_tolerance=curve_tolerance)

    build.__name__ = build.__qualname__ = name
    build.__doc__ = f"``graph_lattice(cell_map, '{name}', ...)``."
    return build


globals().update({name: _tpms_builder(name) for name in TPMS_NAMES})
globals().update({name: _lattice_builder(name) for name in LATTICE_NAMES})


class _Properties:
    """``pyvcad_metamaterials.properties``: geometric characterization
    (:mod:`fgslice.analysis.characterize`)."""

    @staticmethod
    def characterize(node, voxel_size, bounds=None, periodic_axes: str = ""):
        """The report of ``node`` within ``bounds`` (a ``(min, max)`` pair of Vec3; the
        node's bounding box when None) on voxels of ``voxel_size`` mm."""
        from fgslice.analysis.characterize import characterize
        from fgslice.compat.pyvcad import to_node
        from fgslice.design import api

        owner = "properties.characterize"
        if not isinstance(node, Node):
            raise DesignError(f"{owner}: the first argument is a pyvcad node, got {type(node).__name__}", hint=_DOCS)
        design = api.design(to_node(node))
        if bounds is None:
            lo, hi = (np.asarray(v, dtype=float) for v in design.bounds())
        elif isinstance(bounds, Sequence) and len(bounds) == 2:
            lo, hi = (_point(owner, what, v) for what, v in zip(("the minimum corner", "the maximum corner"), bounds))
        else:
            raise DesignError(f"{owner}: bounds is a (min, max) pair of pyvcad.Vec3, got {bounds!r}", hint=_DOCS)
        return characterize(design.sdf, lo, hi, _number(owner, "voxel_size", voxel_size), periodic_axes)

    @staticmethod
    def characterize_graph_cell(cell, cell_size, beam_radius):
        """The exact strut report of ``cell`` (a name of :data:`LATTICE_NAMES` or a
        ``GraphUnitCell``) at ``cell_size`` (mm, a number or 3) and ``beam_radius`` (mm)."""
        from fgslice.analysis.characterize import characterize_graph_cell

        edges = cell.edges if isinstance(cell, GraphUnitCell) else lattice.graph_cell(cell)
        size = cell_size if isinstance(cell_size, numbers.Real) else _point("characterize_graph_cell", "cell_size",
                                                                           cell_size)
        return characterize_graph_cell(edges, size, _number("characterize_graph_cell", "beam_radius", beam_radius))

    def __getattr__(self, name: str):
        if name.startswith("__"):
            raise AttributeError(name)
        raise _unsupported("pyvcad_metamaterials.properties", name)


properties = _Properties()
