"""A tilting transform moved down a node tree onto its meshes.

A rotation that tilts the Z axis (or any linear map that does) leaves no exact section
of its child to map in 2-D: the child would be traced on its signed distance, which
for a mesh is a 3-D distance to its triangles per sample. Instead the map is applied
once to the mesh's vertices (:meth:`fgslice.design.mesh.MeshGeometry.transformed`), so
the moved mesh sections exactly and as fast as an upright one, and its distance is exact.

:func:`moved` rebuilds the tree below the map with the map pushed down: unions,
intersections and differences keep their kind over moved children; transforms compose;
a node that sets materials (fgrade, blend, attribute) keeps them in its own frame
(:class:`Placed`: geometry from the moved children, fractions from the node under the
map); any other leaf stays under the map (sampled, as before).
"""

from __future__ import annotations

import functools

import numpy as np

from fgslice.design import nodes


def moved(node: nodes.Node, matrix: np.ndarray, offset: np.ndarray) -> nodes.Node:
    """``node`` under the map ``p = matrix @ q + offset``, the map pushed onto its meshes."""
    from fgslice.design.attributes import Attribute

    if isinstance(node, nodes.MeshShape):
        return nodes.MeshShape(node.geometry.transformed(matrix, offset), node.path, node.material, node.where)
    if isinstance(node, nodes.Affine):
        return moved(node._body, matrix @ node.matrix, matrix @ node.offset + offset)
    if type(node) in (nodes.Union, nodes.Intersection, nodes.Difference):
        return type(node)([moved(child, matrix, offset) for child in node.children], node.where)
    if isinstance(node, (nodes.MaterialNode, Attribute)):
        return Placed(Kept(matrix, offset, node, node.where), moved(node._body, matrix, offset))
    return Kept(matrix, offset, node, node.where)


def holds_mesh(node: nodes.Node) -> bool:
    """Whether a mesh lies anywhere below ``node``."""
    return any(isinstance(n, nodes.MeshShape) for n, *_ in nodes.walk(node))


class Kept(nodes.Affine):
    """A node left under the map: a material node's fractions, or a part without meshes
    (sampled where the map tilts)."""

    kind = "transform"
    moved_tree = None


class Placed(nodes.Reshaped):
    """A material node under a map: geometry (distance, bounds, sections) of ``shape``,
    the map already applied to its meshes; fractions of ``materials`` (the node under
    the map, evaluated in its own frame)."""

    def __init__(self, materials: Kept, shape: nodes.Node) -> None:
        super().__init__((shape,), materials.where)
        self.kind = materials.children[0].kind
        self.materials = materials
        self.shape = shape

    @property
    def valid_sections(self) -> bool:
        return self.shape.valid_sections

    def raw(self, x, y, z, columns):
        return self.materials.raw(x, y, z, columns)

    @functools.cached_property
    def coordinate_free(self) -> bool:
        return self.materials.coordinate_free

    @functools.cached_property
    def can_be_void(self) -> bool:
        return self.materials.can_be_void


def section_meshes(root: nodes.Node) -> list[nodes.MeshShape]:
    """The meshes ``root`` sections, each once: below a tilting map, the moved ones."""
    found: dict[int, nodes.MeshShape] = {}
    stack = [root]
    while stack:
        node = stack.pop()
        if isinstance(node, nodes.MeshShape):
            found.setdefault(id(node), node)
            continue
        tilted = node.moved_tree if isinstance(node, nodes.Affine) else None
        stack.extend((tilted,) if tilted is not None else reversed(node.children))
    return list(found.values())
