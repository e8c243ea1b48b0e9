"""OpenVCAD's ``Offset`` and ``Shell``: a part grown, shrunk or hollowed.

``Offset(d, child)`` shifts the child's signed distance: ``sdf - d`` (mm; ``d > 0`` grows
the part by ``d``, ``d < 0`` shrinks it). ``Shell(t, child)`` is OpenVCAD's
``Difference(child, Offset(-t, child))``: the part hollowed to a closed wall ``t`` mm
thick. Both keep the child's materials and attributes (evaluated at the point, the
child's rules extending outward in a grown margin).

Sections are exact wherever they can be. A shift of the signed distance commutes with the
booleans (``min(a, b) - d = min(a - d, b - d)``; a difference shifts its cut the other
way), with transforms (scaled by their smallest stretch, as their distance is) and with
nodes that only set materials, so :func:`shifted` moves it down the tree onto the leaves:
a sphere or strut keeps its kind with the radius changed by ``d``; a prism (box,
cylinder, extrusion, text: a planar region ``S`` between two heights, with an exact
distance) has at height ``z`` the section ``buffer(S, sqrt(d^2 - t^2))`` when growing
(``t``: how far ``z`` lies above or below the prism, 0 beside it) and ``buffer(S, d)``
when shrinking, empty within ``|d|`` of its top and bottom; a mesh (also one moved by
a tilting transform) has its own section with the band of points within ``|d|`` of its
triangles added or cut away (:class:`TriangleBand`); any other leaf (functions,
lattices, smooth booleans, tilted primitives) is traced on its shifted distance. Arcs
are inscribed, vertices within ``spacing / 20`` of the true curve.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import shapely

from fgslice.design import nodes
from fgslice.design.extrusion import Extrusion
from fgslice.errors import DesignError

_EMPTY = shapely.MultiPolygon()


def shifted(node: nodes.Node, d: float) -> nodes.Node:
    """A node whose distance is ``node``'s minus ``d`` (mm), the shift moved onto the
    leaves; it gives geometry only (its materials are not meant to be read)."""
    from fgslice.design import smooth
    from fgslice.design.attribute_ops import AttributeCarrier

    if d == 0:
        return node
    if isinstance(node, Shifted):
        return shifted(node.children[0], node.d + d)
    if isinstance(node, nodes.Reshaped):  # Offset, Shell, a mesh moved under a map
        return shifted(node.shape, d)
    if isinstance(node, (nodes.MaterialNode, AttributeCarrier)):
        return shifted(node._body, d)
    if isinstance(node, nodes.Sphere):
        return nodes.Sphere(node.r + d, node.material, node.where) if node.r + d > 0 else Shifted(node, d)
    if isinstance(node, nodes.Strut):
        return nodes.Strut(node.a, node.b, node.r + d, node.material, node.where) if node.r + d > 0 else Shifted(node, d)
    if isinstance(node, (smooth.SmoothUnion, smooth.SmoothIntersection, smooth.SmoothDifference)):
        return Shifted(node, d)
    if isinstance(node, nodes.MeshShape):
        return MeshShifted(node, d)
    if isinstance(node, nodes.Affine) and node.moved_tree is not None:
        return shifted(node.moved_tree, d)
    if isinstance(node, nodes.Affine):
        stretch = float(node._stretch.min())
        return nodes.Affine(node.matrix, node.offset, shifted(node._body, d / stretch), node.where)
    if type(node) is nodes.Union or isinstance(node, nodes.Intersection):
        return type(node)([shifted(child, d) for child in node.children], node.where)
    if type(node) is nodes.Difference:
        first, *rest = node.children
        return nodes.Difference([shifted(first, d)] + [shifted(child, -d) for child in rest], node.where)
    return Shifted(node, d)


def prism(node: nodes.Node) -> tuple[float, float] | None:
    """``(z0, z1)`` when ``node`` is a planar region extruded from ``z0`` to ``z1`` mm with
    an exact signed distance (box, cylinder, extrusion); None otherwise."""
    if isinstance(node, nodes.Box):
        return -float(node.half[2]), float(node.half[2])
    if isinstance(node, nodes.Cylinder):
        return -node.h / 2, node.h / 2
    if isinstance(node, Extrusion):
        return node.z0, node.z1
    return None


def _quad_segments(radius: float, spacing: float) -> int:
    """Segments per quarter circle of a buffer of ``radius`` whose chords stay within
    ``spacing / 20`` of the arc."""
    return max(2, math.ceil(nodes._segments(abs(radius), spacing) / 4))


class Shifted(nodes.Node):
    """``child``'s distance minus ``d`` mm: exact sections of prisms (see the module
    docstring), traced on the distance otherwise."""

    kind = "offset"

    def __init__(self, child: nodes.Node, d: float) -> None:
        super().__init__((child,), child.where)
        self.d = float(d)
        self.extent = prism(child)
        self._regions: dict[float, shapely.Geometry] = {}

    def sdf(self, x, y, z):
        return self.children[0].sdf(x, y, z) - self.d

    def _bounds(self):
        lo, hi = self.children[0].bounds()
        child = self.children[0]
        if isinstance(child, (nodes.Sphere, nodes.Strut)) and child.r + self.d <= 0:
            return np.full(3, np.inf), np.full(3, -np.inf)
        return lo - self.d, hi + self.d  # shrunk: a distance <= d inside lies |d| within the box

    def _sections(self, zs, spacing):
        if self.extent is None:
            return [nodes.sampled_section(self, z, spacing) for z in zs]
        return [self._prism_section(z, spacing) for z in zs]

    def _prism_section(self, z: float, spacing: float) -> shapely.Geometry:
        z0, z1 = self.extent
        region = self._region(spacing)
        if self.d < 0:
            if min(z - z0, z1 - z) < -self.d:
                return _EMPTY
            return shapely.buffer(region, self.d, quad_segs=_quad_segments(self.d, spacing))
        t = max(z0 - z, z - z1, 0.0)
        if t >= self.d:
            return _EMPTY
        radius = math.sqrt(self.d * self.d - t * t)
        return shapely.buffer(region, radius, quad_segs=_quad_segments(radius, spacing))

    def _region(self, spacing: float) -> shapely.Geometry:
        """The prism's planar region, the same at every height it spans (kept per spacing)."""
        if spacing not in self._regions:
            z0, z1 = self.extent
            self._regions[spacing] = self.children[0].section((z0 + z1) / 2, spacing)
        return self._regions[spacing]


class Offset(nodes.Reshaped):
    """``Offset(d, child)``: the child grown by ``d`` mm (shrunk when ``d < 0``)."""

    kind = "offset"

    def __init__(self, d: float, child: nodes.Node, where: nodes.Where = nodes.NOWHERE) -> None:
        super().__init__((child,), where)
        self.d = float(d)
        self.shape = shifted(child, self.d)


class Shell(nodes.Reshaped):
    """``Shell(t, child)``: the child hollowed, a closed wall ``t`` mm thick (``t > 0``)
    inside its surface."""

    kind = "shell"

    def __init__(self, thickness: float, child: nodes.Node, where: nodes.Where = nodes.NOWHERE) -> None:
        if not thickness > 0:
            raise DesignError(f"Shell: the thickness must be positive, got {thickness:g} mm", **where.error_kwargs())
        super().__init__((child,), where)
        self.thickness = float(thickness)
        self.shape = nodes.Difference([child, shifted(child, -self.thickness)], where)


class TriangleBand:
    """The band of points within ``d`` mm (> 0) of ``triangles`` ``(n, 3, 3)``, plane by
    plane (:meth:`section`). The mesh's features are gathered once: its non-degenerate
    triangles, their edges and corners, each edge and corner once (by coordinates)."""

    def __init__(self, triangles: np.ndarray, d: float) -> None:
        self.d = float(d)
        normal = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
        length = np.linalg.norm(normal, axis=1)
        keep = length > 0
        self.triangles, self.normals = triangles[keep], normal[keep] / length[keep, None]
        edges = np.stack([self.triangles, self.triangles[:, [1, 2, 0]]], axis=2).reshape(-1, 2, 3)
        sign = np.sign(edges[:, 0] - edges[:, 1])
        swap = sign[np.arange(len(sign)), np.argmax(sign != 0, axis=1)] > 0  # each edge once, its lower end first
        edges[swap] = edges[swap][:, ::-1]
        self.edges = np.unique(edges, axis=0)
        self.corners = np.unique(self.edges.reshape(-1, 3), axis=0)
        self.z_lo = self.triangles[..., 2].min(axis=1)
        self.z_hi = self.triangles[..., 2].max(axis=1)

    def section(self, z: float, spacing: float) -> shapely.Geometry:
        """The points of the plane at height ``z`` within ``d`` of any triangle: for each
        triangle, the section of its plate (the triangle swept ``d`` both ways along its
        normal: the points whose nearest point of the triangle is inside it), of the
        capsules of radius ``d`` around its edges (nearest point on an edge) and of the balls
        around its corners; their union."""
        return shapely.union_all(self.pieces(z, spacing))

    def pieces(self, z: float, spacing: float) -> np.ndarray:
        """The pieces whose union is :meth:`section` (an array of polygons, none empty)."""
        d = self.d
        near = (self.z_lo <= z + d) & (self.z_hi >= z - d)
        if not near.any():
            return np.empty(0, dtype=object)
        parts = [_plates(self.triangles[near], self.normals[near], z, d), _discs(self.corners, z, d, spacing)]
        edges = self.edges
        reach = (edges[..., 2].min(axis=1) - d <= z) & (edges[..., 2].max(axis=1) + d >= z)
        parts.append(_capsule_bodies(edges[reach], z, d, spacing))
        parts = np.concatenate(parts)
        return parts[~shapely.is_empty(parts)]


def _plates(triangles: np.ndarray, normals: np.ndarray, z: float, d: float) -> np.ndarray:
    """Sections at ``z`` of the triangles swept ``d`` both ways along their unit
    ``normals``: convex polygons (an array, the ones that are not polygons left out)."""
    shift = d * normals[:, None, :]
    corners = np.concatenate([triangles - shift, triangles + shift], axis=1)  # (n, 6, 3): the plate's corners
    pairs = np.array([(0, 1), (1, 2), (2, 0), (3, 4), (4, 5), (5, 3), (0, 3), (1, 4), (2, 5)])
    a, b = corners[:, pairs[:, 0]], corners[:, pairs[:, 1]]  # (n, 9, 3): the plate's edges
    dz = b[..., 2] - a[..., 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (z - a[..., 2]) / dz
    crossing = (dz != 0) & (t >= 0) & (t <= 1)
    points = a + np.where(crossing, t, 0.0)[..., None] * (b - a)
    owner, edge = np.nonzero(crossing)
    if not owner.size:
        return np.empty(0, dtype=object)
    _, index = np.unique(owner, return_inverse=True)
    plates = shapely.convex_hull(shapely.multipoints(points[owner, edge, :2], indices=index))
    return plates[shapely.get_type_id(plates) == shapely.GeometryType.POLYGON]


def _discs(corners: np.ndarray, z: float, d: float, spacing: float) -> np.ndarray:
    """Sections at ``z`` of the balls of radius ``d`` around ``corners`` ``(k, 3)``: the
    polygons of :func:`fgslice.design.nodes._circle`, built together."""
    rho2 = d * d - (z - corners[:, 2]) ** 2
    inside = rho2 > 0
    centres, radii = corners[inside, :2], np.sqrt(rho2[inside])
    counts = np.array([nodes._segments(r, spacing) for r in radii], dtype=np.int64)
    out = []
    for count in np.unique(counts):
        pick = counts == count
        cos, sin = nodes._unit_circle(int(count))
        r = radii[pick, None]
        rings = np.stack([centres[pick, 0, None] + r * cos, centres[pick, 1, None] + r * sin], axis=-1)
        out.append(shapely.polygons(rings))
    return np.concatenate(out) if out else np.empty(0, dtype=object)


def _capsule_bodies(edges: np.ndarray, z: float, r: float, spacing: float) -> np.ndarray:
    """Sections at ``z`` of the cylindrical bodies (between the end planes) of the
    capsules of radius ``r`` around ``edges`` ``(m, 2, 3)``: the polygons of
    :meth:`fgslice.design.nodes.Strut._body_section`, built together."""
    a = edges[:, 0]
    ba = edges[:, 1] - a
    length = np.sqrt(np.sum(ba * ba, axis=1))
    edges, a, ba, length = edges[length > 0], a[length > 0], ba[length > 0], length[length > 0]
    u = ba / length[:, None]
    w = z - a[:, 2]
    rho = np.hypot(u[:, 0], u[:, 1])
    upright = rho < 1e-12
    axial = w[upright] * u[upright, 2]
    standing = a[upright][(axial >= 0) & (axial <= length[upright])]
    count = nodes._segments(r, spacing)
    cos, sin = nodes._unit_circle(count)
    out = [shapely.polygons(np.stack([standing[:, 0, None] + r * cos, standing[:, 1, None] + r * sin], axis=-1))]
    slanted = ~upright
    a, u, w, rho, length = a[slanted], u[slanted], w[slanted], rho[slanted], length[slanted]
    uz = u[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        s_lo = np.minimum(-w * uz / rho, (length - w * uz) / rho)
        s_hi = np.maximum(-w * uz / rho, (length - w * uz) / rho)
        e_lo = np.minimum((w * rho - r) / uz, (w * rho + r) / uz)
        e_hi = np.maximum((w * rho - r) / uz, (w * rho + r) / uz)
    tilted = np.abs(uz) > 1e-12
    s_lo = np.where(tilted, np.maximum(s_lo, e_lo), s_lo)
    s_hi = np.where(tilted, np.minimum(s_hi, e_hi), s_hi)
    keep = (tilted | (np.abs(w) < r)) & (s_hi > s_lo)
    a, u, w, rho, uz, s_lo, s_hi = (v[keep] for v in (a, u, w, rho, uz, s_lo, s_hi))
    n_samples = max(2, count // 2)
    ease = (1 - np.cos(np.linspace(0, np.pi, n_samples))) / 2
    s = s_lo[:, None] + (s_hi - s_lo)[:, None] * ease
    n = np.sqrt(np.maximum(r**2 - (s * uz[:, None] - (w * rho)[:, None]) ** 2, 0))
    along = u[:, :2] / rho[:, None]
    across = np.stack([-along[:, 1], along[:, 0]], axis=1)
    ss = np.concatenate([s, s[:, ::-1]], axis=1)
    nn = np.concatenate([n, -n[:, ::-1]], axis=1)
    rings = a[:, None, :2] + ss[..., None] * along[:, None, :] + nn[..., None] * across[:, None, :]
    bodies = shapely.polygons(rings)
    invalid = ~shapely.is_valid(bodies)
    bodies[invalid] = shapely.make_valid(bodies[invalid])
    out.append(bodies)
    return np.concatenate(out)


class MeshShifted(Shifted):
    """A mesh's distance minus ``d`` mm, its sections exact: the mesh's own section with
    the band of points within ``|d|`` of its triangles added (growing) or cut away
    (shrinking), :class:`TriangleBand`; the band's pieces that cannot change the section
    (inside it when growing, outside it when shrinking) are left out of the union."""

    def _sections(self, zs, spacing):
        geometry = self.children[0].geometry
        band = self._band
        out = []
        for z, own in zip(zs, geometry.sections(zs)):
            pieces = band.pieces(z, spacing)
            shapely.prepare(own)
            if self.d > 0:  # a piece inside the section adds nothing to it
                out.append(shapely.union(own, shapely.union_all(pieces[~shapely.contains_properly(own, pieces)])))
            else:  # nor cuts anything away from it when it lies outside
                out.append(shapely.difference(own, shapely.union_all(pieces[shapely.intersects(own, pieces)])))
        return out

    @functools.cached_property
    def _band(self) -> TriangleBand:
        geometry = self.children[0].geometry
        return TriangleBand(geometry._vertices[geometry._faces], abs(self.d))
