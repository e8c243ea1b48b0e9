"""The design node tree: geometry primitives, booleans, transforms and material grading.

Every node works in its own frame (millimetres). A node provides

* ``sdf(x, y, z)``: signed distance, negative inside (broadcasting numpy arrays);
* ``bounds()``: a tight axis-aligned box ``(lo, hi)`` (3-vectors, mm);
* ``section(z, spacing)``: the outline at height ``z`` as a shapely geometry. Exact
  (analytic polygons, vertices within ``spacing / 20`` of the true curve) for sphere,
  cube, rectprism, cylinder and strut; exact for meshes (delegated); booleans combine the
  sections of their children; translations, scalings and rotations that keep Z vertical
  transform the child's section; a tilting one moves the vertices of the meshes below
  it (:mod:`fgslice.design.moved`). Anything else (``function``, tilted primitives) is
  traced with :func:`fgslice.design.sampled.section_from_sdf` on cells of
  ``SAMPLED_CELL * spacing``, vertices within ``spacing / 20`` of the surface (a
  ``function`` on its expression, clipped to its box exactly).
  ``sections(zs, spacing)`` gives the same outlines at several heights, computed
  together where that is faster (a mesh sections many planes in one vectorized pass);
* ``raw(x, y, z, columns)``: raw (unclamped) material fractions, ``(N, k)`` for 1-D
  arrays.

Material rules (OpenVCAD's): an ``fgrade`` overrides everything below it, so the
outermost fgrade enclosing a point decides its fractions and the children of an fgrade
give only geometry; the materials named below an fgrade are hidden (never printed).
Outside every fgrade, a primitive naming a material has fraction 1 of it and one without
a name takes the design's first material. Where the children of a union overlap, the
first child that contains the point decides; outside all children, the nearest one.
``intersection`` and ``difference`` take their first child's materials.

:class:`NodeDesign` wraps a tree into a :class:`fgslice.design.base.Design`.
"""

from __future__ import annotations

import functools
import inspect
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import shapely

from fgslice.design.base import Design, Material
from fgslice.errors import DesignError, FieldError, FgsliceError

MAX_DEPTH = 200
"""Deepest nesting of nodes a design may have (deeper trees would exhaust the stack)."""

DEFAULT_SECTION_SPACING = 0.1
"""Default sampling step (mm) of sampled sections: a quarter of a 0.4 mm bead."""

DEFAULT_MATERIAL = Material("default", (0.5, 0.5, 0.5, 1.0))
"""The material of a design that names none."""

VOID = "void"
"""The name of empty space: where it has the largest fraction nothing is printed, elsewhere
its fraction is dropped. It is never one of a design's materials."""

_EMPTY = shapely.MultiPolygon()


@dataclass(frozen=True)
class Where:
    """Where a node was written: file, 1-based line and column, and that line's text."""

    file: str | None = None
    line: int | None = None
    column: int | None = None
    source_line: str | None = None

    def error_kwargs(self) -> dict:
        """Keyword arguments locating an :class:`FgsliceError` here."""
        return {"file": self.file, "line": self.line, "column": self.column, "source_line": self.source_line}


NOWHERE = Where()


class Field:
    """A scalar field over a node's frame: a compiled expression or a Python callable.

    Callables take numpy arrays ``(x, y, z)`` — or ``(x, y, z, d)`` when they accept a
    fourth argument, ``d`` being the signed distance of the fgrade's child — and return an
    array broadcastable to the points' shape (or a scalar). ``file_lines`` are the design
    file's lines from the string's own on, shown in its errors. ``expression`` is the compiled
    :class:`~fgslice.design.expressions.Expression` of a string field, None for a callable.
    """

    def __init__(self, source: str | Callable, where: Where = NOWHERE, file_lines: Sequence[str] | None = None) -> None:
        self.where = where
        if isinstance(source, str):
            from fgslice.design.expressions import compile_expression

            line = where.line if where.line is not None else 1
            column = where.column if where.column is not None else 1
            self._fn = compile_expression(source, file=where.file, line=line, column=column, file_lines=file_lines)
            self.uses_d = "d" in self._fn.variables
            self.text = source
            self._callable = False
            self.expression = self._fn
        elif callable(source):
            self._fn = source
            self.uses_d = _accepts_four(source)
            self.text = getattr(source, "__name__", "callable")
            self._callable = True
            self.expression = None
        else:
            raise DesignError(
                f"a material field must be an expression string or a callable, not {type(source).__name__}",
                **where.error_kwargs(),
            )

    def __call__(self, x: np.ndarray, y: np.ndarray, z: np.ndarray, d: np.ndarray | None = None) -> np.ndarray:
        """The field's values at the points, broadcast to the points' shape (float64)."""
        if not self._callable:
            value = self._fn(x, y, z, d) if self.uses_d else self._fn(x, y, z)
            return np.broadcast_to(np.asarray(value, dtype=float), np.broadcast_shapes(*map(np.shape, (x, y, z))))
        try:
            value = self._fn(x, y, z, d) if self.uses_d else self._fn(x, y, z)
            return np.broadcast_to(np.asarray(value, dtype=float), np.broadcast_shapes(*map(np.shape, (x, y, z))))
        except FgsliceError:
            raise
        except Exception as exc:
            raise FieldError(
                f"material field '{self.text}' failed: {type(exc).__name__}: {exc}",
                hint="a field callable takes numpy arrays x, y, z (and optionally d) and returns an array of their shape",
                **self.where.error_kwargs(),
            ) from None


def _accepts_four(fn: Callable) -> bool:
    """Whether ``fn`` can be called with four positional arguments."""
    try:
        inspect.signature(fn).bind(0, 0, 0, 0)
    except TypeError:
        return False
    except ValueError:
        return False
    return True


class Columns:
    """Maps material names (lower case) to fraction columns; ``k`` columns in all.

    ``void_only``: the fractions are wanted only to find where void wins (the void
    margin): a union's child that cannot give void any fraction (:attr:`Node.can_be_void`)
    then reads as the first material, without evaluating it.
    """

    def __init__(self, names: Sequence[str], void_only: bool = False) -> None:
        self.index = {name.lower(): i for i, name in enumerate(names)}
        self.k = len(names)
        self.void_only = void_only

    def one_hot(self, n: int, name: str | None) -> np.ndarray:
        """``(n, k)`` rows of fraction 1 of ``name`` (the first material when None)."""
        out = np.zeros((n, self.k))
        out[:, 0 if name is None else self.index[name.lower()]] = 1.0
        return out


# --------------------------------------------------------------------------- polygons


def _segments(radius: float, spacing: float) -> int:
    """Vertices of a circle of ``radius`` whose chords stay within ``spacing / 20``."""
    tol = spacing / 20.0
    if radius <= tol:
        return 96
    return int(min(4096, max(96, math.ceil(math.pi / math.acos(1.0 - tol / radius)))))


@functools.lru_cache(maxsize=64)
def _unit_circle(segments: int) -> tuple[np.ndarray, np.ndarray]:
    """Cosines and sines of ``segments`` angles evenly spaced from 0 (read-only): the
    sections of a sphere, cylinder or strut at many heights share them."""
    t = np.linspace(0.0, 2.0 * np.pi, segments, endpoint=False)
    cos, sin = np.cos(t), np.sin(t)
    cos.flags.writeable = sin.flags.writeable = False
    return cos, sin


def _circle(cx: float, cy: float, radius: float, spacing: float) -> shapely.Polygon:
    """A polygon inscribed in the circle (vertices on the circle)."""
    cos, sin = _unit_circle(_segments(radius, spacing))
    return shapely.Polygon(np.column_stack([cx + radius * cos, cy + radius * sin]))


def as_multipolygon(geom: shapely.Geometry) -> shapely.MultiPolygon:
    """The polygonal part of ``geom`` as a valid MultiPolygon."""
    if geom is None or geom.is_empty:
        return _EMPTY
    if not geom.is_valid:
        geom = shapely.make_valid(geom)
    parts = shapely.get_parts(shapely.get_parts(geom))
    polys = parts[(shapely.get_type_id(parts) == 3) & ~shapely.is_empty(parts)]
    polys = polys[shapely.area(polys) > 0]
    return shapely.multipolygons(polys) if len(polys) else _EMPTY


def _box_sdf(x, y, z, half) -> np.ndarray:
    """Exact signed distance to the box ``|x| <= half[0]``, ... centered at the origin."""
    qx = np.abs(x) - half[0]
    qy = np.abs(y) - half[1]
    qz = np.abs(z) - half[2]
    outside = np.sqrt(np.maximum(qx, 0) ** 2 + np.maximum(qy, 0) ** 2 + np.maximum(qz, 0) ** 2)
    return outside + np.minimum(np.maximum(np.maximum(qx, qy), qz), 0)


# ------------------------------------------------------------------------------ nodes


class Node:
    """Base of all nodes: children, source location, cached bounds, section dispatch."""

    kind = "node"
    valid_sections = False
    """True when :meth:`sections` gives valid MultiPolygons of polygons of positive area
    (a mesh's exact sections): a design's outlines then keep them as they are."""

    def __init__(self, children: Sequence[Node] = (), where: Where = NOWHERE) -> None:
        self.children = tuple(children)
        self.where = where

    def sdf(self, x, y, z) -> np.ndarray:
        """Signed distance (mm), negative inside."""
        raise NotImplementedError

    def _bounds(self) -> tuple[np.ndarray, np.ndarray]:
        raise NotImplementedError

    @functools.cached_property
    def _cached_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return self._bounds()

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """``(lo, hi)``: tight axis-aligned bounds (mm); ``lo > hi`` somewhere when empty."""
        return self._cached_bounds

    def section(self, z: float, spacing: float) -> shapely.Geometry:
        """Outline at height ``z`` (see the module docstring for exactness)."""
        return self.sections([z], spacing)[0]

    def sections(self, zs: Sequence[float], spacing: float) -> list[shapely.Geometry]:
        """Outlines at every height of ``zs``, in order: empty outside the node's bounds.
        The last :data:`KEPT_SECTIONS` outlines are kept and not computed again (a layer's
        outline is asked again for its materials, :mod:`fgslice.design.membership`)."""
        lo, hi = self.bounds()
        out = [_EMPTY] * len(zs)
        if np.any(lo > hi):
            return out
        kept = self.__dict__.setdefault("_kept_sections", {})
        inside = [i for i, z in enumerate(zs) if lo[2] <= z <= hi[2]]
        for i in inside:
            out[i] = kept.get((float(zs[i]), spacing))
        missing = [i for i in inside if out[i] is None]
        for i, outline in zip(missing, self._sections([float(zs[i]) for i in missing], spacing)):
            out[i] = outline
            kept[(float(zs[i]), spacing)] = outline
        for old in list(kept)[:-KEPT_SECTIONS]:
            del kept[old]
        return out

    def _sections(self, zs: list[float], spacing: float) -> list[shapely.Geometry]:
        """Outlines at heights within the bounds; one :meth:`_section` each unless overridden."""
        return [self._section(z, spacing) for z in zs]

    traced = False
    """True when the outlines are traced on a field over the node's whole box, so that
    tracing only a window of it (:meth:`sections_within`) saves work."""

    def sections_within(self, zs: Sequence[float], spacing: float, windows: np.ndarray) -> list[shapely.Geometry]:
        """Outlines at ``zs`` needed only inside the rectangles ``windows`` (``(n, 4)``
        xmin, ymin, xmax, ymax in mm; NaN: nothing needed), e.g. as one child of an
        intersection: a :attr:`traced` node traces only the windows (grown by two
        spacings); any other gives its whole outlines."""
        if not self.traced:
            return self.sections(zs, spacing)
        lo, hi = self.bounds()
        return [_EMPTY if np.any(lo > hi) or not lo[2] <= z <= hi[2] or np.isnan(w).any()
                else self._window_section(float(z), spacing, np.asarray(w, dtype=float))
                for z, w in zip(zs, windows)]

    def _window_section(self, z: float, spacing: float, window: np.ndarray) -> shapely.Geometry:
        return sampled_section(self, z, spacing, window)

    def _section(self, z: float, spacing: float) -> shapely.Geometry:
        return sampled_section(self, z, spacing)

    def raw(self, x, y, z, columns: Columns) -> np.ndarray:
        """Raw fractions ``(N, k)`` at 1-D points of this node's frame."""
        return self.children[0].raw(x, y, z, columns)

    @functools.cached_property
    def coordinate_free(self) -> bool:
        """Whether :meth:`raw` ignores the coordinates (then transforms need not map them)."""
        return self.children[0].coordinate_free

    @functools.cached_property
    def can_be_void(self) -> bool:
        """Whether :meth:`raw` can give the material ``void`` a fraction anywhere."""
        return bool(self.children) and self.children[0].can_be_void


KEPT_SECTIONS = 4
"""Outlines each node keeps, the latest computed (see :meth:`Node.sections`)."""

SAMPLED_CELL = 4
"""Fine cell of sampled sections, in ``spacing``: 0.4 mm at the default spacing."""


def sampled_section(node: Node, z: float, spacing: float, window: np.ndarray | None = None) -> shapely.Geometry:
    """Outline of ``node`` at ``z`` traced on its sdf with cells of ``SAMPLED_CELL * spacing``
    mm, vertices within ``spacing / 20`` of the zero level; only within the rectangle
    ``window`` (xmin, ymin, xmax, ymax, grown by two spacings) when given."""
    from fgslice.design.sampled import section_from_sdf

    lo, hi = node.bounds()
    pad = 2.0 * spacing
    bounds2d = (lo[0] - pad, lo[1] - pad, hi[0] + pad, hi[1] + pad)
    if window is not None:
        bounds2d = _clipped(bounds2d, window, pad)
        if bounds2d is None:
            return _EMPTY
    return section_from_sdf(lambda x, y: node.sdf(x, y, np.full(np.shape(x), z)), bounds2d, SAMPLED_CELL * spacing,
                            tolerance=spacing / 20)


def _clipped(bounds2d, window: np.ndarray, pad: float) -> tuple[float, float, float, float] | None:
    """The rectangle ``bounds2d`` within ``window`` grown by ``pad``; None when they miss."""
    x0, y0 = max(bounds2d[0], window[0] - pad), max(bounds2d[1], window[1] - pad)
    x1, y1 = min(bounds2d[2], window[2] + pad), min(bounds2d[3], window[3] + pad)
    return (x0, y0, x1, y1) if x0 < x1 and y0 < y1 else None


class Primitive(Node):
    """A leaf shape centered at the origin, optionally made of a named material."""

    def __init__(self, material: str | None = None, where: Where = NOWHERE) -> None:
        super().__init__((), where)
        self.material = material

    coordinate_free = True

    @functools.cached_property
    def can_be_void(self) -> bool:
        return self.material is not None and self.material.lower() == VOID

    def raw(self, x, y, z, columns: Columns) -> np.ndarray:
        return columns.one_hot(np.shape(x)[0], self.material)


class Sphere(Primitive):
    """Ball of radius ``r`` centered at the origin."""

    kind = "sphere"

    def __init__(self, r: float, material: str | None = None, where: Where = NOWHERE) -> None:
        super().__init__(material, where)
        self.r = float(r)

    def sdf(self, x, y, z):
        return np.sqrt(x * x + y * y + z * z) - self.r

    def _bounds(self):
        return np.full(3, -self.r), np.full(3, self.r)

    def _section(self, z, spacing):
        rho2 = self.r**2 - z * z
        return _circle(0.0, 0.0, math.sqrt(rho2), spacing) if rho2 > 0 else _EMPTY


class Box(Primitive):
    """Rectangular prism of sizes ``(sx, sy, sz)`` centered at the origin (cube: equal sizes)."""

    kind = "rectprism"

    def __init__(self, size: Sequence[float], material: str | None = None, where: Where = NOWHERE) -> None:
        super().__init__(material, where)
        self.half = np.asarray(size, dtype=float) / 2.0

    def sdf(self, x, y, z):
        return _box_sdf(x, y, z, self.half)

    def _bounds(self):
        return -self.half, self.half.copy()

    def _section(self, z, spacing):
        hx, hy = self.half[:2]
        return shapely.box(-hx, -hy, hx, hy)


class Cylinder(Primitive):
    """Cylinder of radius ``r`` along Z from ``-h/2`` to ``h/2``."""

    kind = "cylinder"

    def __init__(self, r: float, h: float, material: str | None = None, where: Where = NOWHERE) -> None:
        super().__init__(material, where)
        self.r = float(r)
        self.h = float(h)

    def sdf(self, x, y, z):
        dr = np.sqrt(x * x + y * y) - self.r
        dz = np.abs(z) - self.h / 2.0
        return np.minimum(np.maximum(dr, dz), 0) + np.sqrt(np.maximum(dr, 0) ** 2 + np.maximum(dz, 0) ** 2)

    def _bounds(self):
        return np.array([-self.r, -self.r, -self.h / 2]), np.array([self.r, self.r, self.h / 2])

    def _section(self, z, spacing):
        return _circle(0.0, 0.0, self.r, spacing)


class Strut(Primitive):
    """Capsule: all points within ``r`` of the segment from ``a`` to ``b``."""

    kind = "strut"

    def __init__(self, a, b, r: float, material: str | None = None, where: Where = NOWHERE) -> None:
        super().__init__(material, where)
        self.a = np.asarray(a, dtype=float)
        self.b = np.asarray(b, dtype=float)
        self.r = float(r)

    def sdf(self, x, y, z):
        ba = self.b - self.a
        px, py, pz = x - self.a[0], y - self.a[1], z - self.a[2]
        length2 = float(ba @ ba)
        t = 0.0 if length2 == 0 else np.clip((px * ba[0] + py * ba[1] + pz * ba[2]) / length2, 0.0, 1.0)
        return np.sqrt((px - t * ba[0]) ** 2 + (py - t * ba[1]) ** 2 + (pz - t * ba[2]) ** 2) - self.r

    def _bounds(self):
        return np.minimum(self.a, self.b) - self.r, np.maximum(self.a, self.b) + self.r

    def _section(self, z, spacing):
        parts = []
        for end in (self.a, self.b):
            rho2 = self.r**2 - (z - end[2]) ** 2
            if rho2 > 0:
                parts.append(_circle(end[0], end[1], math.sqrt(rho2), spacing))
        parts.append(self._body_section(z, spacing))
        return shapely.union_all([p for p in parts if not p.is_empty])

    def _body_section(self, z: float, spacing: float) -> shapely.Geometry:
        """Section of the capsule's cylindrical body (between the end planes).

        With u the unit axis, rho = |u_xy|, s and n the in-plane coordinates along and
        across u_xy measured from a, and w = z - a_z: the squared distance to the axis is
        ``n^2 + (s uz - w rho)^2`` and the axial coordinate is ``s rho + w uz``.
        """
        ba = self.b - self.a
        length = float(np.linalg.norm(ba))
        if length == 0:
            return _EMPTY
        u = ba / length
        w = z - self.a[2]
        rho = math.hypot(u[0], u[1])
        if rho < 1e-12:
            axial = w * u[2]
            return _circle(self.a[0], self.a[1], self.r, spacing) if 0 <= axial <= length else _EMPTY
        s_lo, s_hi = sorted(((0 - w * u[2]) / rho, (length - w * u[2]) / rho))
        if abs(u[2]) > 1e-12:
            e_lo, e_hi = sorted(((w * rho - self.r) / u[2], (w * rho + self.r) / u[2]))
            s_lo, s_hi = max(s_lo, e_lo), min(s_hi, e_hi)
        elif abs(w) >= self.r:
            return _EMPTY
        if s_hi <= s_lo:
            return _EMPTY
        n_samples = max(2, _segments(self.r, spacing) // 2)
        s = s_lo + (s_hi - s_lo) * (1 - np.cos(np.linspace(0, np.pi, n_samples))) / 2
        n = np.sqrt(np.maximum(self.r**2 - (s * u[2] - w * rho) ** 2, 0))
        along = np.array([u[0], u[1]]) / rho
        across = np.array([-along[1], along[0]])
        ss = np.concatenate([s, s[::-1]])
        nn = np.concatenate([n, -n[::-1]])
        pts = self.a[:2] + ss[:, None] * along + nn[:, None] * across
        poly = shapely.Polygon(pts)
        return poly if poly.is_valid else shapely.make_valid(poly)


class FunctionShape(Primitive):
    """``function(lo, hi, expr)``: inside where the field is <= 0, within the box lo..hi."""

    kind = "function"

    def __init__(self, lo, hi, field: Field, material: str | None = None, where: Where = NOWHERE) -> None:
        super().__init__(material, where)
        self.lo = np.asarray(lo, dtype=float)
        self.hi = np.asarray(hi, dtype=float)
        self.field = field
        if field.uses_d:
            raise DesignError(
                "'d' is only defined in fgrade expressions, not in function(...) shapes",
                **field.where.error_kwargs(),
            )

    def sdf(self, x, y, z):
        center = (self.lo + self.hi) / 2
        box = _box_sdf(x - center[0], y - center[1], z - center[2], (self.hi - self.lo) / 2)
        return np.maximum(self.field(x, y, z), box)

    def _bounds(self):
        """The box tightened to where the field is <= 0 (:mod:`fgslice.design.function_bounds`)."""
        from fgslice.design.function_bounds import tight_box

        return tight_box(self.field, self.lo, self.hi)

    traced = True

    def _section(self, z, spacing):
        """The expression's region traced on its own values (not the box-clamped sdf),
        clipped to the box's rectangle exactly."""
        return self._window_section(z, spacing, None)

    def _window_section(self, z, spacing, window):
        from fgslice.design.sampled import section_from_sdf

        height = np.float64(z)
        rectangle = (self.lo[0], self.lo[1], self.hi[0], self.hi[1])
        if window is not None:
            rectangle = _clipped(rectangle, window, 2.0 * spacing)
            if rectangle is None:
                return _EMPTY
        return section_from_sdf(lambda x, y: self.field(x, y, height), rectangle, SAMPLED_CELL * spacing,
                                tolerance=spacing / 20)


class MeshShape(Primitive):
    """A triangle mesh in its own coordinates (see :mod:`fgslice.design.mesh`)."""

    kind = "mesh"
    valid_sections = True

    def __init__(self, geometry, path: str, material: str | None = None, where: Where = NOWHERE) -> None:
        super().__init__(material, where)
        self.geometry = geometry
        self.path = path

    def sdf(self, x, y, z):
        x, y, z = np.broadcast_arrays(x, y, z)
        return self.geometry.sdf(x, y, z)

    def _bounds(self):
        lo, hi = self.geometry.bounds()
        return np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)

    def _sections(self, zs, spacing):
        return self.geometry.sections(zs)


def _union_raw(children: Sequence[Node], x, y, z, columns: Columns, index=None) -> np.ndarray:
    """Fractions of a union: first child containing the point, else the nearest child
    (located through ``index``, a :class:`~fgslice.design.union_index.ChildIndex`, when given)."""
    if len(children) == 1:
        return children[0].raw(x, y, z, columns)
    from fgslice.design.membership import owners

    owner = index.owners(x, y, z) if index is not None else owners(children, x, y, z)
    out = np.empty((np.shape(x)[0], columns.k))
    for i, child in enumerate(children):
        sel = np.flatnonzero(owner == i)
        if not sel.size:
            continue
        if columns.void_only and not child.can_be_void:
            out[sel] = columns.one_hot(sel.size, None)
        else:
            out[sel] = child.raw(x[sel], y[sel], z[sel], columns)
    return out


class Union(Node):
    """Union of the children (min of their sdfs)."""

    kind = "union"

    def sdf(self, x, y, z):
        if self._index is not None:
            return self._index.sdf(x, y, z)
        return functools.reduce(np.minimum, (c.sdf(x, y, z) for c in self.children))

    @functools.cached_property
    def _index(self):
        """The children by bounding box (:mod:`fgslice.design.union_index`) when there are
        many and none is located by its sections (meshes); None otherwise."""
        from fgslice.design.membership import uses_sections
        from fgslice.design.union_index import MANY_CHILDREN, ChildIndex

        if len(self.children) <= MANY_CHILDREN or any(uses_sections(c) for c in self.children):
            return None
        index = ChildIndex(self.children)
        return index if index.usable else None

    def _bounds(self):
        boxes = [c.bounds() for c in self.children]
        boxes = [b for b in boxes if not np.any(b[0] > b[1])] or boxes
        return np.min([b[0] for b in boxes], axis=0), np.max([b[1] for b in boxes], axis=0)

    @functools.cached_property
    def valid_sections(self) -> bool:
        """Many children or copies (:mod:`fgslice.design.copies`): their sections are joined
        by :func:`~fgslice.islands.union_polygons`, which keeps islands apart as
        they are and gives valid MultiPolygons."""
        return len(self.children) > 64 or any(c.kind == "copies" for c in self.children)

    def _sections(self, zs, spacing):
        if len(self.children) == 1 and self.children[0].kind == "copies":
            return self.children[0].sections(zs, spacing)
        parts = np.array([c.sections(zs, spacing) for c in self.children], dtype=object)
        if self.valid_sections:
            from fgslice.islands import union_polygons

            return [union_polygons(parts[:, i]) for i in range(len(zs))]
        return list(shapely.union_all(parts, axis=0))

    def raw(self, x, y, z, columns):
        return _union_raw(self.children, x, y, z, columns, self._index)

    @functools.cached_property
    def coordinate_free(self) -> bool:
        return len(self.children) == 1 and self.children[0].coordinate_free

    @functools.cached_property
    def can_be_void(self) -> bool:
        return any(child.can_be_void for child in self.children)


class Intersection(Node):
    """Intersection of the children (max of their sdfs); materials of the first child."""

    kind = "intersection"

    def sdf(self, x, y, z):
        return functools.reduce(np.maximum, (c.sdf(x, y, z) for c in self.children))

    def _bounds(self):
        boxes = [c.bounds() for c in self.children]
        return np.max([b[0] for b in boxes], axis=0), np.min([b[1] for b in boxes], axis=0)

    def _sections(self, zs, spacing):
        """The children's outlines intersected; a :attr:`~Node.traced` child beside others
        is traced only within the box of what the others leave at each height."""
        exact = [c for c in self.children if not c.traced]
        if not exact or len(exact) == len(self.children):
            parts = [np.array(c.sections(zs, spacing), dtype=object) for c in self.children]
            return list(functools.reduce(shapely.intersection, parts))
        out = functools.reduce(shapely.intersection, [np.array(c.sections(zs, spacing), dtype=object) for c in exact])
        for child in self.children:
            if child.traced:
                traced = child.sections_within(zs, spacing, shapely.bounds(out))
                out = shapely.intersection(out, np.array(traced, dtype=object))
        return list(out)


class Difference(Node):
    """First child minus the others: ``max(a, -min(others))``; materials of the first child."""

    kind = "difference"

    def sdf(self, x, y, z):
        first = self.children[0].sdf(x, y, z)
        if len(self.children) == 1:
            return first
        rest = functools.reduce(np.minimum, (c.sdf(x, y, z) for c in self.children[1:]))
        return np.maximum(first, -rest)

    def _bounds(self):
        return self.children[0].bounds()

    def _sections(self, zs, spacing):
        firsts = self.children[0].sections(zs, spacing)
        if len(self.children) == 1:
            return firsts
        cut = [i for i, first in enumerate(firsts) if not first.is_empty]  # the others only where there is a first
        others = zip(*(c.sections([zs[i] for i in cut], spacing) for c in self.children[1:]))
        for i, parts in zip(cut, others):
            firsts[i] = shapely.difference(firsts[i], shapely.union_all(parts))
        return firsts


class MappedBody:
    """A node whose materials are those of its one child ``_body`` at mapped points
    (:meth:`local`): whether they ignore the coordinates, or can be void, is the child's."""

    _body: Node

    @functools.cached_property
    def coordinate_free(self) -> bool:
        return self._body.coordinate_free

    @functools.cached_property
    def can_be_void(self) -> bool:
        return self._body.can_be_void

    def raw(self, x, y, z, columns):
        if self._body.coordinate_free:
            return self._body.raw(x, y, z, columns)
        return self._body.raw(*self.local(x, y, z), columns)


class Affine(MappedBody, Node):
    """A linear map ``p = M q + t`` from the child's frame ``q`` to this node's frame ``p``.

    Sections are exact when ``M`` keeps the Z axis vertical (no tilt): the child's
    section at the corresponding height, mapped in 2D. Otherwise, below a map holding a
    mesh, the map is moved onto the meshes' vertices (:attr:`moved_tree`), whose
    sections are exact; anything else is sampled.
    """

    def __init__(self, matrix, offset, child: Node | Sequence[Node], where: Where = NOWHERE) -> None:
        children = (child,) if isinstance(child, Node) else tuple(child)
        super().__init__(children, where)
        self.matrix = np.asarray(matrix, dtype=float)
        self.offset = np.asarray(offset, dtype=float)
        self._inverse = np.linalg.inv(self.matrix)
        self._stretch = np.linalg.svd(self.matrix, compute_uv=False)
        # the inverse's nonzero terms per row: translations and scalings skip the zeros
        self._rows = [[(j, float(c)) for j, c in enumerate(row) if c != 0] for row in self._inverse]
        self._body = children[0] if len(children) == 1 else Union(children, where)

    def local(self, x, y, z):
        """This node's coordinates mapped into the child's frame."""
        p = [v - o if o != 0 else v for v, o in zip((x, y, z), self.offset)]
        mapped = []
        for row in self._rows:
            terms = [p[j] if c == 1 else p[j] * c for j, c in row]
            mapped.append(functools.reduce(np.add, terms))
        return tuple(mapped)

    @functools.cached_property
    def moved_tree(self) -> Node | None:
        """The child with this map moved onto its meshes (:func:`fgslice.design.moved.moved`)
        when the map tilts the Z axis and a mesh lies below; None otherwise."""
        from fgslice.design.moved import holds_mesh, moved

        if self.keeps_z_vertical or not holds_mesh(self._body):
            return None
        return moved(self._body, self.matrix, self.offset)

    @property
    def valid_sections(self) -> bool:
        return self.moved_tree is not None and self.moved_tree.valid_sections

    @property
    def traced(self) -> bool:
        """A tilting map without a mesh below: traced on its distance."""
        return self.moved_tree is None and not self.keeps_z_vertical

    def sdf(self, x, y, z):
        if self.moved_tree is not None:
            return self.moved_tree.sdf(x, y, z)
        # scaled by the map's smallest stretch so the result stays a lower bound on distance
        stretch = float(self._stretch.min())
        distance = self._body.sdf(*self.local(x, y, z))
        return distance if stretch == 1 else distance * stretch

    def _bounds(self):
        if self.moved_tree is not None:
            return self.moved_tree.bounds()
        lo, hi = self._body.bounds()
        if np.any(lo > hi):
            return lo + self.offset, hi + self.offset
        corners = np.array([[(lo, hi)[(i >> j) & 1][j] for j in range(3)] for i in range(8)])
        mapped = corners @ self.matrix.T + self.offset
        return mapped.min(axis=0), mapped.max(axis=0)

    @functools.cached_property
    def keeps_z_vertical(self) -> bool:
        """Whether the map keeps the Z axis vertical (then sections are the child's, mapped in 2D)."""
        m = np.where(np.abs(self.matrix) < 1e-12, 0.0, self.matrix)
        return m[0, 2] == 0 and m[1, 2] == 0 and m[2, 0] == 0 and m[2, 1] == 0

    def _sections(self, zs, spacing):
        if self.moved_tree is not None:
            return self.moved_tree.sections(zs, spacing)
        if not self.keeps_z_vertical:
            return [sampled_section(self, z, spacing) for z in zs]
        m = np.where(np.abs(self.matrix) < 1e-12, 0.0, self.matrix)
        children = self._body.sections([(z - self.offset[2]) / m[2, 2] for z in zs], spacing / float(self._stretch.max()))
        (a, b), (d, e) = m[:2, :2]
        xoff, yoff = self.offset[:2]

        def plane_map(q: np.ndarray) -> np.ndarray:  # shapely.affinity.affine_transform's arithmetic
            x, y = q.T
            return np.stack([a * x + b * y + xoff, d * x + e * y + yoff]).T

        return list(shapely.transform(np.array(children, dtype=object), plane_map))

    def raw(self, x, y, z, columns):
        if self.moved_tree is not None and not self._body.coordinate_free:
            return self.moved_tree.raw(x, y, z, columns)
        return super().raw(x, y, z, columns)


class Translate(Affine):
    """``translate(dx, dy, dz)``: moves the children by the offset (mm)."""

    kind = "translate"

    def __init__(self, offset, child, where: Where = NOWHERE) -> None:
        super().__init__(np.eye(3), offset, child, where)


def rotation_matrix(pitch: float, yaw: float, roll: float) -> np.ndarray:
    """``Rz(roll) @ Ry(yaw) @ Rx(pitch)`` (degrees, right-hand rule about fixed X, Y, Z).

    Applied to a child, it turns it first by ``pitch`` about X, then by ``yaw`` about Y,
    then by ``roll`` about Z, all about the axes of the parent frame.
    """
    (ca, sa), (cb, sb), (cc, sc) = (_cos_sin(angle) for angle in (pitch, yaw, roll))
    rx = np.array([[1, 0, 0], [0, ca, -sa], [0, sa, ca]])
    ry = np.array([[cb, 0, sb], [0, 1, 0], [-sb, 0, cb]])
    rz = np.array([[cc, -sc, 0], [sc, cc, 0], [0, 0, 1]])
    return rz @ ry @ rx


def _cos_sin(degrees: float) -> tuple[float, float]:
    """Cosine and sine of an angle in degrees, exactly 0 and +-1 at multiples of 90
    degrees (so that quarter turns map axes onto axes without 1e-16 residues, which
    would make a plane's points leave their plane)."""
    quarters = float(degrees) / 90.0
    if quarters == round(quarters):
        return ((1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0))[int(round(quarters)) % 4]
    radians = math.radians(degrees)
    return math.cos(radians), math.sin(radians)


class Rotate(Affine):
    """``rotate(pitch, yaw, roll)`` in degrees; see :func:`rotation_matrix` for the order."""

    kind = "rotate"

    def __init__(self, angles, child, where: Where = NOWHERE) -> None:
        super().__init__(rotation_matrix(*angles), np.zeros(3), child, where)


class Scale(Affine):
    """``scale(sx, sy, sz)``: stretches the children along X, Y, Z (factors non-zero).

    The sdf is ``child_sdf(p / s) * min|s|``: exact for uniform scaling, a lower bound on
    the distance otherwise (the zero level set is exact).
    """

    kind = "scale"

    def __init__(self, factors, child, where: Where = NOWHERE) -> None:
        super().__init__(np.diag(np.asarray(factors, dtype=float)), np.zeros(3), child, where)


class MaterialNode(Node):
    """A node that keeps its children's geometry (their union) and sets the materials."""

    def __init__(self, children: Sequence[Node], where: Where = NOWHERE) -> None:
        super().__init__(children, where)
        self._body = children[0] if len(children) == 1 else Union(children, where)

    def sdf(self, x, y, z):
        return self._body.sdf(x, y, z)

    def _bounds(self):
        return self._body.bounds()

    def _sections(self, zs, spacing):
        return self._body.sections(zs, spacing)

    @functools.cached_property
    def can_be_void(self) -> bool:
        return self._body.can_be_void


class Fgrade(MaterialNode):
    """Material grading: fractions ``fields`` of ``materials`` over the children.

    The fractions override the children's materials (the children give the geometry
    only). Fields see this node's own frame. ``d`` is the children's (union) signed distance.
    ``mode``: ``"prob"`` (default) keeps the continuous fractions; ``"thresh"`` gives
    each point entirely to the material with the largest clamped fraction (first on ties).
    """

    kind = "fgrade"

    def __init__(
        self,
        fields: Sequence[Field],
        materials: Sequence[str],
        children: Sequence[Node],
        mode: str = "prob",
        where: Where = NOWHERE,
    ) -> None:
        super().__init__(children, where)
        self.fields = tuple(fields)
        self.materials = tuple(materials)
        self.mode = mode

    @functools.cached_property
    def _group(self):
        """All fields compiled together (shared subexpressions once), or None with callables."""
        from fgslice.design.expressions import combine_expressions

        expressions = [f.expression for f in self.fields]
        return None if any(e is None for e in expressions) else combine_expressions(expressions)

    def _values(self, x, y, z) -> list:
        """The fields' raw values at broadcast points of this node's frame, in material order."""
        d = self._body.sdf(x, y, z) if any(f.uses_d for f in self.fields) else None
        if self._group is not None:
            return self._group(x, y, z, d)
        return [field(x, y, z, d) for field in self.fields]

    def own_fractions(self, x, y, z, columns: Columns) -> np.ndarray:
        """This node's raw fractions ``shape + (k,)`` at broadcast points of its frame."""
        shape = np.broadcast_shapes(*map(np.shape, (x, y, z)))
        values = self._values(x, y, z)
        out = np.zeros(shape + (columns.k,))
        cols = [columns.index[name.lower()] for name in self.materials]
        for value, col in zip(values, cols):
            out[..., col] = value
        if self.mode == "thresh":
            clamped = np.clip(np.nan_to_num(out[..., cols], nan=0.0), 0.0, 1.0)
            winner = np.asarray(cols)[np.argmax(clamped, axis=-1)]
            out[...] = 0.0
            np.put_along_axis(out, winner[..., None], 1.0, axis=-1)
        return out

    def own_normalized(self, x, y, z, columns: Columns) -> np.ndarray:
        """``normalized(own_fractions(...))``, the same values computed on contiguous
        columns (clamped, summed and divided one material at a time) before they are
        packed into the ``shape + (k,)`` result."""
        if self.mode == "thresh":
            return normalized(self.own_fractions(x, y, z, columns))
        shape = np.broadcast_shapes(*map(np.shape, (x, y, z)))
        by_column = dict(zip((columns.index[name.lower()] for name in self.materials), self._values(x, y, z)))
        f = []
        for col in range(columns.k):
            value = np.fmax(by_column.get(col, 0.0), 0.0, dtype=float)
            if value.shape != shape:
                value = np.array(np.broadcast_to(value, shape))
            f.append(np.fmin(value, 1.0, out=value))
        total = f[0].copy()
        for value in f[1:]:
            total += value
        empty = total <= 0
        if empty.any():
            f[0][empty] = 1.0
            total[empty] = 1.0
        out = np.empty(shape + (columns.k,))
        for col, value in enumerate(f):
            np.divide(value, total, out=out[..., col])
        return out

    coordinate_free = False

    @functools.cached_property
    def can_be_void(self) -> bool:
        return any(name.lower() == VOID for name in self.materials)

    def raw(self, x, y, z, columns):
        return self.own_fractions(x, y, z, columns)


# ----------------------------------------------------------------------------- design


def walk(root: Node):
    """Nodes in document order (pre-order), without recursion, with their depth and whether
    an fgrade above them overrides their materials."""
    stack = [(root, 1, False)]
    while stack:
        node, depth, overridden = stack.pop()
        yield node, depth, overridden
        below = overridden or isinstance(node, Fgrade)
        stack.extend((c, depth + 1, below) for c in reversed(node.children))


def normalized(raw: np.ndarray) -> np.ndarray:
    """Fractions from raw values ``(..., k)``: NaN -> 0, clamp to [0, 1], divide by the sum.

    Rows summing to 0 become the first material. Returns a new array.
    """
    f = np.fmax(raw, 0.0)  # fmax ignores NaN: NaN -> 0, -inf -> 0
    np.fmin(f, 1.0, out=f)  # +inf -> 1
    total = f[..., 0].copy()
    for j in range(1, f.shape[-1]):  # column sums: faster than a reduction over a short axis
        total += f[..., j]
    empty = total <= 0
    if empty.any():
        f[empty, 0] = 1.0
        total[empty] = 1.0
    f /= total[..., None]
    return f


CHUNK = 1 << 15
"""Points evaluated at once: keeps numpy temporaries in cache instead of fresh pages."""


def _chunks(n: int):
    """Slices covering ``range(n)`` in blocks of :data:`CHUNK`."""
    return [slice(i, min(i + CHUNK, n)) for i in range(0, n, CHUNK)]


class NodeDesign(Design):
    """A :class:`Design` evaluated from a node tree.

    Args:
        root: the tree.
        library: resolves material names (:class:`fgslice.design.materials.MaterialLibrary`);
            the built-in library when None.
        hint_bounds: ``root(...)``'s box hint ``((minx, miny, minz), (maxx, maxy, maxz))``.
        voxel_size: ``root(...)``'s voxel size hint (mm); not used for evaluation.
        section_spacing: step (mm) of sampled sections; default a quarter of a 0.4 mm bead.
    """

    def __init__(
        self,
        root: Node,
        library=None,
        *,
        hint_bounds=None,
        voxel_size=None,
        section_spacing: float = DEFAULT_SECTION_SPACING,
        source: str | None = None,
    ) -> None:
        from fgslice.design.materials import builtin_library

        library = library or builtin_library()
        self.library = library
        self.root = root
        self.hint_bounds = hint_bounds
        self.voxel_size = voxel_size
        self.section_spacing = float(section_spacing)
        self.source = source
        names: list[str] = []
        materials: list[Material] = []
        hidden: dict[str, tuple[str, Where]] = {}
        self.has_void = False
        unnamed = False
        self.node_count = 0
        for node, depth, overridden in walk(root):
            self.node_count += getattr(node, "statements", 1)
            if depth > MAX_DEPTH:
                raise DesignError(
                    f"the design nests more than {MAX_DEPTH} levels deep",
                    hint="flatten the tree: a union takes any number of children",
                    **node.where.error_kwargs(),
                )
            used = node.materials if isinstance(node, Fgrade) else ()
            if isinstance(node, Primitive) and node.material is not None:
                used = (node.material,)
            unnamed |= isinstance(node, Primitive) and node.material is None and not overridden
            for name in used:
                material = library.get(name, **node.where.error_kwargs())
                key = material.name.lower()
                if overridden:
                    hidden.setdefault(key, (material.name, node.where))
                elif key == VOID:
                    self.has_void = True
                elif key not in (n.lower() for n in names):
                    names.append(material.name)
                    materials.append(material)
        if not materials:
            if self.has_void and not unnamed:
                raise DesignError(
                    "the design is made of void only: nothing would be printed",
                    hint="give the part a material besides 'void'",
                    **root.where.error_kwargs(),
                )
            names, materials = [DEFAULT_MATERIAL.name], [DEFAULT_MATERIAL]
        visible = {n.lower() for n in names} | ({VOID} if self.has_void else set())
        self.overridden = [(name, where) for key, (name, where) in hidden.items() if key not in visible]
        """Materials named only below an fgrade, which overrides them: ``(name, where)`` of
        each one's first mention. They are not among :attr:`materials`."""
        self._materials = materials
        from fgslice.design.moved import section_meshes

        self.meshes: list[MeshShape] = section_meshes(root)
        """The meshes the design sections (below a tilting transform, the moved ones)."""
        self.columns = Columns(names + ([VOID] if self.has_void else []))

    @property
    def materials(self) -> list[Material]:
        return list(self._materials)

    def sdf(self, x, y, z) -> np.ndarray:
        """Signed distance (mm, negative inside). With void: ``max(sdf, void_margin * 1 mm)``,
        of the right sign (void regions are outside) but not a distance near them."""
        x, y, z = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (x, y, z)))
        shape = x.shape
        x, y, z = x.ravel(), y.ravel(), z.ravel()
        out = np.empty(x.size)
        for s in _chunks(x.size):
            out[s] = self.root.sdf(x[s], y[s], z[s])
        if self.has_void:
            np.maximum(out, self.void_margin(x, y, z), out=out)
        return out.reshape(shape)

    def void_margin(self, x, y, z) -> np.ndarray:
        """Normalized void fraction minus the largest other fraction (broadcast shape):
        positive exactly where void wins and nothing is printed. Only for designs with void."""
        f = self._per_chunk(x, y, z, normalize=True, columns=self._void_columns)
        return f[..., -1] - f[..., :-1].max(axis=-1)

    @functools.cached_property
    def _void_columns(self) -> Columns:
        """:attr:`columns` for :meth:`void_margin`: parts that cannot be void are not evaluated."""
        return Columns(list(self.columns.index), void_only=True)

    def _per_chunk(self, x, y, z, normalize: bool, columns: Columns | None = None) -> np.ndarray:
        columns = columns or self.columns
        x, y, z = (np.asarray(v, dtype=float) for v in (x, y, z))
        shape = np.broadcast_shapes(x.shape, y.shape, z.shape)
        root = self.root
        if isinstance(root, Fgrade):
            return self._broadcast_fractions(root, x, y, z, shape, normalize)
        x, y, z = np.broadcast_arrays(x, y, z)
        x, y, z = x.ravel(), y.ravel(), z.ravel()
        out = np.empty((x.size, columns.k))
        for s in _chunks(x.size):
            raw = self.root.raw(x[s], y[s], z[s], columns)
            out[s] = normalized(raw) if normalize else raw
        return out.reshape(shape + (columns.k,))

    def _broadcast_fractions(self, root: Fgrade, x, y, z, shape, normalize: bool) -> np.ndarray:
        """Fractions of a root fgrade (its own fractions, without walking the children), on
        broadcast inputs.

        Inputs are never expanded: blocks of whole rows are evaluated, and an input constant
        along the first axis (a grid's row of x, a single z) is passed as it is. Inputs
        fitting one block are evaluated at once, without copying the result.
        """
        ndim = max(len(shape), 1)
        x, y, z = (v.reshape((1,) * (ndim - v.ndim) + v.shape) for v in (x, y, z))
        full = shape or (1,)
        rows = max(1, CHUNK // max(1, math.prod(full[1:])))
        own = root.own_normalized if normalize else root.own_fractions
        if full[0] <= rows:
            return own(x, y, z, self.columns).reshape(shape + (self.columns.k,))
        out = np.empty(full + (self.columns.k,))
        for start in range(0, full[0], rows):
            block = slice(start, start + rows)
            out[block] = own(*(v[block] if v.shape[0] > 1 else v for v in (x, y, z)), self.columns)
        return out.reshape(shape + (self.columns.k,))

    def raw_fractions(self, x, y, z) -> np.ndarray:
        """Raw (unclamped, unnormalized) fractions, shape ``broadcast + (k,)`` (void left out)."""
        raw = self._per_chunk(x, y, z, normalize=False)
        return raw[..., : len(self._materials)] if self.has_void else raw

    def fractions(self, x, y, z) -> np.ndarray:
        """Normalized fractions; with void, its fraction is dropped and the others divided
        by their sum (the first material where they sum to 0)."""
        f = self._per_chunk(x, y, z, normalize=True)
        return normalized(f[..., :-1]) if self.has_void else f

    def bounds(self):
        lo, hi = self.root.bounds()
        return tuple(float(v) for v in lo), tuple(float(v) for v in hi)

    def section(self, z: float, spacing: float | None = None) -> shapely.MultiPolygon:
        """Outline at height ``z``; ``spacing`` (mm) for sampled parts, default ``section_spacing``."""
        return self.sections([z], spacing)[0]

    def sections(self, zs: Sequence[float], spacing: float | None = None) -> list[shapely.MultiPolygon]:
        """Outlines at every height of ``zs``, like :meth:`section` at each, computed together.

        With void, each outline loses the region where void wins, traced on a grid of
        ``spacing`` mm (:func:`fgslice.design.void.void_region`)."""
        spacing = spacing or self.section_spacing
        outlines = self.root.sections([float(z) for z in zs], spacing)
        if not self.root.valid_sections:
            outlines = [as_multipolygon(g) for g in outlines]
        if self.has_void:
            from fgslice.design.void import without_void

            outlines = [without_void(self, outline, float(z), spacing) for outline, z in zip(outlines, zs)]
        return outlines

    def prepare_sections(self) -> None:
        """Build every mesh's whole tables now (:meth:`fgslice.design.mesh.MeshGeometry.prepare_sections`)."""
        for mesh in self.meshes:
            mesh.geometry.prepare_sections()


class Reshaped(Node):
    """A node with the geometry (distance, bounds, sections) of :attr:`shape`, another
    node; its subclasses say where its materials and attributes come from."""

    shape: Node

    def sdf(self, x, y, z):
        return self.shape.sdf(x, y, z)

    def _bounds(self):
        return self.shape.bounds()

    def _sections(self, zs, spacing):
        return self.shape.sections(zs, spacing)
