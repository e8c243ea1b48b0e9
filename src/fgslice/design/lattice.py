"""Strut lattices and triply periodic minimal surfaces (TPMS) as exact implicit nodes.

Both are periodic: one cell of size ``period`` (mm, per axis) repeats from the corner
``origin``. Nothing is meshed; the nodes give their signed distance pointwise and their
sections from a 2-D field sampled on a grid (:mod:`fgslice.design.lattice_sections`).

* :class:`StrutLattice`: capsules of radius ``beam`` around segments (and balls of radius
  ``joint`` at given points). Without a period the segments are taken as they are (one
  unit cell); with one they repeat in every cell. The distance to the struts is exact;
  a graded radius is evaluated at the query point (the region is ``distance <= r(p)``).
* :class:`TPMS`: the level set of a periodic field ``g`` over phases ``X = 2 pi u`` (``u``
  the position in cells). ``d = g / |grad g|`` (mm, the first-order distance to the
  surface ``g = 0``) defines the body: a sheet ``|d - level| <= thickness / 2`` or a solid
  ``d <= level``. Thickness and level may be graded. :class:`MixedTPMS` changes from one
  cell to another along a graded weight.

A node is confined to its ``window`` box (``lo``, ``hi``; the geometry is clipped to it).
A tiled lattice made without one (OpenVCAD 2's ``Tile``) has no bounds until an
intersection with bounded shapes gives it theirs (:func:`confine`).

Graded lengths (:class:`Length`) are numbers, fgslice expression strings, callables
``f(x, y, z)`` of numpy arrays, or objects with a ``to_field()`` method returning one of
those (OpenVCAD 3 attributes), evaluated in the node's own frame.
"""

from __future__ import annotations

import functools
import itertools
import math
import numbers
from collections.abc import Callable, Sequence

import numpy as np

from fgslice.design.nodes import NOWHERE, Affine, Field, Node, Primitive, Where, _box_sdf, walk
from fgslice.errors import DesignError


class Length:
    """A length (mm), constant or graded over a node's frame.

    ``value``: a number, an expression string, a callable ``f(x, y, z)`` or an object with
    ``to_field()`` returning one of those. ``positive``: a constant must be > 0.
    """

    def __init__(self, owner: str, what: str, value, *, positive: bool = True) -> None:
        self.owner, self.what = owner, what
        converter = getattr(value, "to_field", None)
        if callable(converter) and not isinstance(value, (str, numbers.Number)):
            value = converter()
        self.constant: float | None = None
        self.field: Field | None = None
        if isinstance(value, bool):
            raise DesignError(f"{owner}: {what} must be a length in mm, got {value!r}")
        if isinstance(value, numbers.Real):
            value = float(value)
            if not math.isfinite(value) or (positive and value <= 0):
                raise DesignError(f"{owner}: {what} must be {'positive' if positive else 'finite'}, got {value:g}",
                                  hint="give it in mm")
            self.constant = value
        elif isinstance(value, str) or callable(value):
            self.field = Field(value)
        else:
            raise DesignError(f"{owner}: {what} must be a number, an expression string, a function of "
                              f"(x, y, z) or an attribute, got {type(value).__name__}")

    def __call__(self, x, y, z) -> np.ndarray | float:
        """The length at the points (broadcast), or the constant."""
        if self.constant is not None:
            return self.constant
        return np.nan_to_num(self.field(x, y, z), nan=0.0)

    def range_over(self, lo, hi) -> tuple[float, float]:
        """``(least, largest)`` over the box lo..hi: exact for a constant, else sampled on
        a 9 x 9 x 9 grid with a quarter of the spread added on both sides."""
        if self.constant is not None:
            return self.constant, self.constant
        axes = [np.linspace(a, b, 9) if b > a else np.array([a]) for a, b in zip(lo, hi)]
        grid = np.meshgrid(*axes, indexing="ij")
        values = np.asarray(self(*grid), dtype=float)
        least, largest = float(values.min()), float(values.max())
        spread = (largest - least) / 4
        return least - spread, largest + spread


# ----------------------------------------------------------------------------- catalog


def _graph_from_vertices(vertices: np.ndarray, length: float) -> np.ndarray:
    """Edges ``(n, 2, 3)`` joining the vertices that lie ``length`` apart."""
    i, j = np.triu_indices(len(vertices), 1)
    close = np.isclose(np.linalg.norm(vertices[i] - vertices[j], axis=1), length)
    return np.stack([vertices[i[close]], vertices[j[close]]], axis=1)


@functools.cache
def _graph_cells() -> dict[str, np.ndarray]:
    """The named graph cells: edges ``(n, 2, 3)`` in the unit cube ``[0, 1]^3``."""
    corners = np.array(list(itertools.product((0.0, 1.0), repeat=3)))
    faces = np.array([(0, .5, .5), (1, .5, .5), (.5, 0, .5), (.5, 1, .5), (.5, .5, 0), (.5, .5, 1)])
    cubic = _graph_from_vertices(corners, 1.0)
    bcc = np.stack([np.full(corners.shape, 0.5), corners], axis=1)
    fcc = _graph_from_vertices(corners, math.sqrt(2))
    octahedron = _graph_from_vertices(faces, math.sqrt(0.5))
    signs = list(itertools.product((-1.0, 1.0), repeat=2))
    truncated_octahedron = {tuple(np.array((0.0, a, 2 * b))[list(p)]) for a, b in signs
                            for p in itertools.permutations(range(3))}
    kelvin = _graph_from_vertices(np.array(sorted(truncated_octahedron)) / 4 + 0.5, math.sqrt(2) / 4)
    tetra = np.array([(0.25, 0.25, 0.25), (0.75, 0.75, 0.25), (0.75, 0.25, 0.75), (0.25, 0.75, 0.75)])
    sites = np.vstack([corners, faces])
    diamond = np.array([(t, s) for t in tetra for s in sites if np.isclose(np.linalg.norm(t - s), math.sqrt(3) / 4)])
    return {"cubic": cubic, "bcc": bcc, "fcc": fcc, "kelvin": kelvin, "octet": np.vstack([fcc, octahedron]),
            "diamond": diamond}


def graph_cell(name: str) -> np.ndarray:
    """Edges ``(n, 2, 3)`` of the named graph cell in the unit cube (see :data:`GRAPH_CELLS`)."""
    cells = _graph_cells()
    if name not in cells:
        raise DesignError(f"unknown graph lattice '{name}'", hint=f"the lattices are {', '.join(GRAPH_CELLS)}")
    return cells[name]


GRAPH_CELLS = ("cubic", "bcc", "fcc", "kelvin", "octet", "diamond")
"""Named graph cells: cube edges; body diagonals (centre to corners); face diagonals;
truncated octahedron (Kelvin cell); octet truss (face diagonals and the octahedron joining
the face centres); diamond (each tetrahedral site to its four face-centred cubic neighbours)."""


def _gyroid(sx, cx, sy, cy, sz, cz):
    return sx * cy + sy * cz + sz * cx


def _schwarz_p(sx, cx, sy, cy, sz, cz):
    return cx + cy + cz


def _schwarz_d(sx, cx, sy, cy, sz, cz):
    return sx * sy * sz + sx * cy * cz + cx * sy * cz + cx * cy * sz


def _neovius(sx, cx, sy, cy, sz, cz):
    return 3 * (cx + cy + cz) + 4 * cx * cy * cz


def _doubled(sx, cx, sy, cy, sz, cz):
    """Sines and cosines of the doubled phases."""
    return 2 * sx * cx, 2 * sy * cy, 2 * sz * cz, 2 * cx * cx - 1, 2 * cy * cy - 1, 2 * cz * cz - 1


def _iwp(sx, cx, sy, cy, sz, cz):
    _, _, _, c2x, c2y, c2z = _doubled(sx, cx, sy, cy, sz, cz)
    return 2 * (cx * cy + cy * cz + cz * cx) - (c2x + c2y + c2z)


def _lidinoid(sx, cx, sy, cy, sz, cz):
    s2x, s2y, s2z, c2x, c2y, c2z = _doubled(sx, cx, sy, cy, sz, cz)
    return (0.5 * (s2x * cy * sz + s2y * cz * sx + s2z * cx * sy)
            - 0.5 * (c2x * c2y + c2y * c2z + c2z * c2x) + 0.15)


def _split_p(sx, cx, sy, cy, sz, cz):
    s2x, s2y, s2z, c2x, c2y, c2z = _doubled(sx, cx, sy, cy, sz, cz)
    return (1.1 * (s2x * sz * cy + s2y * sx * cz + s2z * sy * cx)
            - 0.2 * (c2x * c2y + c2y * c2z + c2z * c2x) - 0.4 * (c2x + c2y + c2z))


TPMS_SURFACES: dict[str, Callable] = {
    "gyroid": _gyroid, "iwp": _iwp, "lidinoid": _lidinoid, "neovius": _neovius,
    "schwarz_d": _schwarz_d, "schwarz_p": _schwarz_p, "split_p": _split_p,
}
"""The standard TPMS fields ``g``, as functions of the sines and cosines of the phases
``X, Y, Z`` (radians; one cell is ``2 pi``): ``g(sin X, cos X, sin Y, cos Y, sin Z, cos Z)``."""


def tpms_surface(name: str) -> Callable:
    """The named TPMS field of :data:`TPMS_SURFACES`."""
    if name not in TPMS_SURFACES:
        raise DesignError(f"unknown TPMS '{name}'", hint=f"the TPMS are {', '.join(TPMS_SURFACES)}")
    return TPMS_SURFACES[name]


# ------------------------------------------------------------------------------- nodes


def _as_box(lo, hi) -> tuple[np.ndarray, np.ndarray]:
    return np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)


class Periodic(Primitive):
    """Base of the periodic nodes: ``period`` (mm per axis, or None), ``origin`` (a cell
    corner) and the ``window`` box the body is clipped to (None: not yet confined)."""

    def __init__(self, period, origin, window, material, where: Where) -> None:
        super().__init__(material, where)
        self.period = None if period is None else np.asarray(period, dtype=float)
        if self.period is not None and not np.all(self.period > 0):
            raise DesignError(f"{self.kind}: the cell size must be positive on every axis, got {tuple(self.period)}")
        self.origin = np.zeros(3) if origin is None else np.asarray(origin, dtype=float)
        self.window = None if window is None else _as_box(*window)

    @property
    def unbounded(self) -> bool:
        """Whether the node repeats without end (no window yet)."""
        return self.window is None

    def confine(self, lo, hi) -> None:
        """Grow the window to cover the box lo..hi (an intersection's bounds)."""
        lo, hi = _as_box(lo, hi)
        self.window = (lo, hi) if self.window is None else (np.minimum(self.window[0], lo), np.maximum(self.window[1], hi))
        self.__dict__.pop("_cached_bounds", None)
        self.__dict__.pop("_kept_sections", None)

    def _window(self) -> tuple[np.ndarray, np.ndarray]:
        if self.window is None:
            raise DesignError(
                f"{self.kind} repeats its cell without end: it has no bounds of its own",
                hint="intersect it with a bounded shape, e.g. Intersection(False, [Tile(cell), RectPrism(...)])",
                **self.where.error_kwargs(),
            )
        return self.window

    def _bounds(self):
        lo, hi = self._window()
        return lo.copy(), hi.copy()

    def fold(self, x, y, z):
        """The points moved into the cell at ``origin`` (unchanged without a period)."""
        if self.period is None:
            return x, y, z
        return tuple(o + np.mod(v - o, p) for v, o, p in zip((x, y, z), self.origin, self.period))

    def _clip(self, distance, x, y, z):
        lo, hi = self._window()
        centre, half = (lo + hi) / 2, (hi - lo) / 2
        return np.maximum(distance, _box_sdf(x - centre[0], y - centre[1], z - centre[2], half))

    def _sections(self, zs, spacing):
        from fgslice.design.lattice_sections import sections

        return sections(self, zs, spacing)


class StrutLattice(Periodic):
    """Capsules of radius ``beam`` around the segments ``edges`` ``(n, 2, 3)`` (mm, this
    node's frame), and balls of radius ``joint`` at ``joints`` ``(m, 3)`` (optional),
    repeated every ``period`` from ``origin`` when a period is given, clipped to ``window``."""

    kind = "lattice"

    def __init__(self, edges, beam: Length, *, joints=None, joint: Length | None = None, period=None, origin=None,
                 window=None, material: str | None = None, where: Where = NOWHERE) -> None:
        super().__init__(period, origin, window, material, where)
        self.edges = np.asarray(edges, dtype=float).reshape(-1, 2, 3)
        self.joints = np.zeros((0, 3)) if joints is None or joint is None else np.asarray(joints, dtype=float).reshape(-1, 3)
        if not len(self.edges) and not len(self.joints):
            raise DesignError("a lattice needs at least one strut", **where.error_kwargs())
        self.beam = beam
        self.joint = joint

    def radius_range(self) -> tuple[float, float]:
        """Least and largest radius (beam and joint) over the window (mm)."""
        lo, hi = self._extent() if self.period is None and self.window is None else self._window()
        ranges = [self.beam.range_over(lo, hi)] + ([self.joint.range_over(lo, hi)] if len(self.joints) else [])
        return min(r[0] for r in ranges), max(r[1] for r in ranges)

    @functools.cached_property
    def reach(self) -> float:
        """The largest radius (mm), at least 0: how far a strut reaches from its segment."""
        return max(self.radius_range()[1], 0.0)

    @functools.cached_property
    def copies(self) -> tuple[np.ndarray, np.ndarray]:
        """Segments ``(n, 2, 3)`` and joints ``(m, 3)`` that can reach into the cell at
        ``origin``: the cell's own and those of its 26 neighbours within :attr:`reach`."""
        if self.period is None:
            return self.edges, self.joints
        shifts = np.array(list(itertools.product((-1, 0, 1), repeat=3)), dtype=float) * self.period
        lo, hi = self.origin - self.reach, self.origin + self.period + self.reach
        edges = (self.edges[None] + shifts[:, None, None, :]).reshape(-1, 2, 3)
        near = np.all((edges.min(axis=1) <= hi) & (edges.max(axis=1) >= lo), axis=1)
        joints = (self.joints[None] + shifts[:, None, :]).reshape(-1, 3)
        close = np.all((joints <= hi) & (joints >= lo), axis=1)
        return edges[near], joints[close]

    def _bounds(self):
        if self.period is None and self.window is None:
            lo, hi = self._extent()
            self.window = (lo - self.reach, hi + self.reach)
        return super()._bounds()

    def _extent(self) -> tuple[np.ndarray, np.ndarray]:
        """The box of the segments and joints."""
        points = np.vstack([self.edges.reshape(-1, 3), self.joints])
        return points.min(axis=0), points.max(axis=0)

    def distances(self, x, y, z, edges: np.ndarray, joints: np.ndarray):
        """Distances (mm) from the points to the nearest segment and the nearest joint
        (``inf`` when there are none)."""
        nearest_edge = np.full(np.broadcast_shapes(*map(np.shape, (x, y, z))), np.inf)
        for a, b in edges:
            ba = b - a
            px, py, pz = x - a[0], y - a[1], z - a[2]
            length2 = float(ba @ ba)
            t = 0.0 if length2 == 0 else np.clip((px * ba[0] + py * ba[1] + pz * ba[2]) / length2, 0.0, 1.0)
            np.minimum(nearest_edge, (px - t * ba[0]) ** 2 + (py - t * ba[1]) ** 2 + (pz - t * ba[2]) ** 2,
                       out=nearest_edge)
        nearest_joint = np.full(nearest_edge.shape, np.inf)
        for c in joints:
            np.minimum(nearest_joint, (x - c[0]) ** 2 + (y - c[1]) ** 2 + (z - c[2]) ** 2, out=nearest_joint)
        return np.sqrt(nearest_edge), np.sqrt(nearest_joint)

    def combine(self, edge_distance, joint_distance, x, y, z):
        """The signed distance from the distances to the segments and joints at the points."""
        out = edge_distance - self.beam(x, y, z)
        if len(self.joints):
            out = np.minimum(out, joint_distance - self.joint(x, y, z))
        return out

    def sdf(self, x, y, z):
        """Exact up to :attr:`band` mm from the struts; beyond, ``band`` (a lower bound):
        only the struts within ``reach + band`` of the points' heights are measured."""
        fx, fy, fz = self.fold(x, y, z)
        edges, joints = self.copies
        if not np.size(fz):
            return self._clip(self.combine(*self.distances(fx, fy, fz, edges, joints), x, y, z), x, y, z)
        margin = self.reach + self.band
        zmin, zmax = float(np.min(fz)) - margin, float(np.max(fz)) + margin
        edges = edges[(edges[:, :, 2].min(axis=1) <= zmax) & (edges[:, :, 2].max(axis=1) >= zmin)]
        joints = joints[(joints[:, 2] <= zmax) & (joints[:, 2] >= zmin)]
        distance = np.minimum(self.combine(*self.distances(fx, fy, fz, edges, joints), x, y, z), self.band)
        return self._clip(distance, x, y, z)

    @functools.cached_property
    def band(self) -> float:
        """How far from the struts (mm) :meth:`sdf` is exact: the largest radius, at least 1 mm."""
        return max(self.reach, 1.0)


_SECOND_HARMONIC = (_iwp, _lidinoid, _split_p)


class TPMS(Periodic):
    """A sheet or solid of the periodic field ``surface`` (see :data:`TPMS_SURFACES`) with
    cells of ``period`` from ``origin``, clipped to ``window``; see the module docstring."""

    kind = "tpms"

    def __init__(self, surface: Callable, period, origin, window, *, mode: str = "sheet", thickness: Length | None = None,
                 level: Length | None = None, material: str | None = None, where: Where = NOWHERE) -> None:
        super().__init__(period, origin, window, material, where)
        if mode not in ("sheet", "solid"):
            raise DesignError(f'a TPMS mode is "sheet" or "solid", got {mode!r}', **where.error_kwargs())
        if mode == "sheet" and thickness is None:
            raise DesignError("a TPMS sheet needs a wall thickness", **where.error_kwargs())
        self.surface = surface
        self.harmonic = 2 if surface in _SECOND_HARMONIC else 1
        """The highest multiple of the phases in the field (curvature scale, 1 or 2)."""
        self.mode = mode
        self.thickness = thickness
        self.level = level

    _STEP = 1e-3
    """Phase step (radians) of the central differences giving ``grad g``."""

    def distance(self, x, y, z):
        """``g / |grad g|`` (mm) at the points (broadcast): negative on the solid side. The
        gradient is a central difference of :data:`_STEP` radians, the shifted sines and
        cosines taken from the point's own by the angle-sum formulas."""
        return self.field_distance(self.surface, x, y, z)

    def field_distance(self, surface: Callable, x, y, z):
        """:meth:`distance` of the periodic field ``surface`` on this node's cells."""
        k = 2 * np.pi / self.period
        trig = []
        for v, o, kk in zip((x, y, z), self.origin, k):
            phase = (v - o) * kk
            trig += [np.sin(phase), np.cos(phase)]
        g = surface(*trig)
        ch, sh = math.cos(self._STEP), math.sin(self._STEP)
        slope2 = 0.0
        for axis in range(3):
            s, c = trig[2 * axis], trig[2 * axis + 1]
            ahead, behind = list(trig), list(trig)
            ahead[2 * axis: 2 * axis + 2] = s * ch + c * sh, c * ch - s * sh
            behind[2 * axis: 2 * axis + 2] = s * ch - c * sh, c * ch + s * sh
            slope = (surface(*ahead) - surface(*behind)) * (k[axis] / (2 * self._STEP))
            slope2 = slope2 + slope * slope
        return g / np.maximum(np.sqrt(slope2), 1e-6 * float(k.min()))

    def body(self, distance, x, y, z):
        """The body's field from :meth:`distance` (negative inside)."""
        level = 0.0 if self.level is None else self.level(x, y, z)
        if self.mode == "solid":
            return distance - level
        return np.abs(distance - level) - self.thickness(x, y, z) / 2

    def sdf(self, x, y, z):
        return self._clip(self.body(self.distance(x, y, z), x, y, z), x, y, z)


class MixedTPMS(TPMS):
    """A TPMS whose cell changes from ``surfaces[0]`` (``weight`` 0) to ``surfaces[1]``
    (``weight`` 1): the distance is ``(1 - w) d0 + w d1`` of the two cells' distances
    (mm), the weight clamped to 0..1, so the wall keeps its thickness through the blend."""

    kind = "tpms"

    def __init__(self, surfaces: tuple[Callable, Callable], weight: Length, period, origin, window, **options) -> None:
        super().__init__(surfaces[0], period, origin, window, **options)
        self.surfaces, self.weight = surfaces, weight
        self.harmonic = max(2 if s in _SECOND_HARMONIC else 1 for s in surfaces)

    def distance(self, x, y, z):
        w = np.clip(self.weight(x, y, z), 0.0, 1.0)
        return (1 - w) * self.field_distance(self.surfaces[0], x, y, z) + w * self.field_distance(self.surfaces[1], x, y, z)


# ---------------------------------------------------------------------------- confining


def _periodic_below(node: Node) -> list[Periodic]:
    return [n for n, _, _ in walk(node) if isinstance(n, Periodic) and n.unbounded]


def confine(children: Sequence[Node]) -> None:
    """Give the unbounded periodic nodes below ``children`` (an intersection's) the bounds
    of the bounded children, mapped through the transforms in between.

    Raises a DesignError when no child is bounded."""
    open_children = [c for c in children if _periodic_below(c)]
    if not open_children:
        return
    closed = [c for c in children if not _periodic_below(c)]
    if not closed:
        raise DesignError(
            "an intersection of lattices that repeat without end has no bounds",
            hint="add a bounded shape to the intersection, e.g. a RectPrism",
        )
    boxes = [c.bounds() for c in closed]
    lo, hi = np.max([b[0] for b in boxes], axis=0), np.min([b[1] for b in boxes], axis=0)
    for child in open_children:
        _confine(child, lo, hi)


def _confine(node: Node, lo: np.ndarray, hi: np.ndarray) -> None:
    if isinstance(node, Periodic):
        if node.unbounded:
            node.confine(lo, hi)
        return
    if isinstance(node, Affine):
        corners = np.array([[(lo, hi)[(i >> j) & 1][j] for j in range(3)] for i in range(8)])
        local = (corners - node.offset) @ node._inverse.T
        lo, hi = local.min(axis=0), local.max(axis=0)
    for child in node.children:
        _confine(child, lo, hi)
