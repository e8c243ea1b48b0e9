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
triangles added or cut away (:func:`triangle_band`); any other leaf (functions,
lattices, smooth booleans, tilted primitives) is traced on its shifted distance. Arcs
are inscribed, vertices within ``spacing / 20`` of the true curve.
"""

from __future__ import annotations

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


def triangle_band(triangles: np.ndarray, z: float, d: float, spacing: float) -> shapely.Geometry:
    """The points of the plane at height ``z`` within ``d`` mm (> 0) of any of the
    ``triangles`` ``(n, 3, 3)``: for each triangle, the section of its plate (the triangle
    swept ``d`` both ways along its normal: the points whose nearest point of the triangle
    is inside it) and of the capsules of radius ``d`` around its edges (nearest point on
    an edge or a corner)."""
    zs = triangles[..., 2]
    triangles = triangles[(zs.min(axis=1) <= z + d) & (zs.max(axis=1) >= z - d)]
    if not len(triangles):
        return _EMPTY
    normal = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    length = np.linalg.norm(normal, axis=1)
    keep = length > 0
    triangles, normal = triangles[keep], normal[keep] / length[keep, None]
    shift = d * normal[:, None, :]
    corners = np.concatenate([triangles - shift, triangles + shift], axis=1)  # (n, 6, 3): the plate's corners
    pairs = np.array([(0, 1), (1, 2), (2, 0), (3, 4), (4, 5), (5, 3), (0, 3), (1, 4), (2, 5)])
    a, b = corners[:, pairs[:, 0]], corners[:, pairs[:, 1]]  # (n, 9, 3): the plate's edges
    dz = b[..., 2] - a[..., 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (z - a[..., 2]) / dz
    crossing = (dz != 0) & (t >= 0) & (t <= 1)
    points = a + np.where(crossing, t, 0.0)[..., None] * (b - a)
    owner, edge = np.nonzero(crossing)
    if owner.size:
        _, index = np.unique(owner, return_inverse=True)
        plates = shapely.convex_hull(shapely.multipoints(points[owner, edge, :2], indices=index))
    else:
        plates = []
    parts = [p for p in plates if p.geom_type == "Polygon"]
    edges = np.stack([triangles, triangles[:, [1, 2, 0]]], axis=2).reshape(-1, 2, 3)
    sign = np.sign(edges[:, 0] - edges[:, 1])
    swap = sign[np.arange(len(sign)), np.argmax(sign != 0, axis=1)] > 0  # each edge once, its lower end first
    edges[swap] = edges[swap][:, ::-1]
    edges = np.unique(edges, axis=0)
    ends = np.unique(edges.reshape(-1, 3), axis=0)
    rho2 = d * d - (z - ends[:, 2]) ** 2
    parts.extend(nodes._circle(x, y, math.sqrt(r2), spacing) for (x, y, _), r2 in zip(ends, rho2) if r2 > 0)
    reach = (edges[..., 2].min(axis=1) - d <= z) & (edges[..., 2].max(axis=1) + d >= z)
    parts.extend(nodes.Strut(start, end, d)._body_section(z, spacing) for start, end in edges[reach])
    return shapely.union_all([p for p in parts if not p.is_empty])


class MeshShifted(Shifted):
    """A mesh's distance minus ``d`` mm, its sections exact: the mesh's own section with
    the band of points within ``|d|`` of its triangles added (growing) or cut away
    (shrinking), :func:`triangle_band`."""

    def _sections(self, zs, spacing):
        geometry = self.children[0].geometry
        triangles = geometry._vertices[geometry._faces]
        out = []
        for z, own in zip(zs, geometry.sections(zs)):
            band = triangle_band(triangles, z, abs(self.d), spacing)
            out.append(shapely.union(own, band) if self.d > 0 else shapely.difference(own, band))
        return out
