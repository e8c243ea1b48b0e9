"""Which child of a union (or fgrade) a point belongs to, for its materials.

The rule (see :mod:`fgslice.design.nodes`): the first child containing the point decides;
outside all children, the nearest one. Deciding it with the children's signed distances
costs a 3-D distance per point and child, which for a mesh is the whole cost of finding
materials. Points of one plane (all at the same ``z``, as the toolpath stages sample them
layer by layer) are instead tested against the child's own section there (point in
polygon), for every child whose section is exact and whose distance is costly (it
contains a mesh). Outside every child, such a child's distance is the in-plane distance
to its section (at least the 3-D distance, equal where the surface is vertical), or its
3-D distance where the plane misses it.

Sections are computed at the default spacing and kept for the last plane of each child
(the stages ask for one layer many times, then move on).
"""

from __future__ import annotations

import weakref
from collections.abc import Sequence

import numpy as np
import shapely

_PLANE_SECTIONS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
"""Child node -> (z, prepared section at z): the last plane each child was cut at."""
_USES_SECTIONS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def owners(children: Sequence, x: np.ndarray, y: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Index of the child deciding each point's materials (1-D points of the union's frame)."""
    plane = np.size(z) > 0 and float(np.min(z)) == float(np.max(z))
    by_section = [plane and uses_sections(c) for c in children]
    inside = np.empty((len(children), np.size(x)), dtype=bool)
    distance: list[np.ndarray | None] = [None] * len(children)
    for i, child in enumerate(children):
        if by_section[i]:
            inside[i] = shapely.intersects_xy(_plane_section(child, float(z[0])), x, y)
        else:
            distance[i] = np.broadcast_to(child.sdf(x, y, z), np.shape(x))
            inside[i] = distance[i] <= 0
    contained = inside.any(axis=0)
    owner = np.argmax(inside, axis=0)
    outside = np.flatnonzero(~contained)
    if outside.size:
        d = np.stack([_outside_distance(c, distance[i], outside, x, y, z, by_section[i]) for i, c in enumerate(children)])
        owner[outside] = np.argmin(d, axis=0)
    return owner


def _outside_distance(child, distance, index, x, y, z, by_section: bool) -> np.ndarray:
    """Distance (mm) from the points ``index`` to ``child`` (none of them inside it)."""
    if not by_section:
        return distance[index]
    section = _plane_section(child, float(z[0]))
    if section.is_empty:
        return np.broadcast_to(child.sdf(x[index], y[index], z[index]), index.shape)
    return shapely.distance(section, shapely.points(x[index], y[index]))


def uses_sections(node) -> bool:
    """Whether ``node``'s points are located by its sections: all of its sections are
    exact (no sampled part) and it contains a mesh."""
    known = _USES_SECTIONS.get(node)
    if known is None:
        from fgslice.design.nodes import walk

        kinds = [n for n, *_ in walk(node)]
        known = any(n.kind == "mesh" for n in kinds) and all(_exact(n) for n in kinds)
        _USES_SECTIONS[node] = known
    return known


def _exact(node) -> bool:
    """Whether ``node`` itself computes its section without sampling its field."""
    from fgslice.design.nodes import Affine, FunctionShape, Node, walk

    if isinstance(node, FunctionShape):
        return False
    if isinstance(node, Affine):
        tilted = node.moved_tree
        return node.keeps_z_vertical or (tilted is not None and all(_exact(n) for n, *_ in walk(tilted)))
    return type(node)._section is not Node._section or type(node)._sections is not Node._sections


def _plane_section(child, z: float) -> shapely.Geometry:
    """``child``'s section at ``z`` (default spacing), prepared for point queries."""
    cached = _PLANE_SECTIONS.get(child)
    if cached is not None and cached[0] == z:
        return cached[1]
    from fgslice.design.nodes import DEFAULT_SECTION_SPACING

    section = child.section(z, DEFAULT_SECTION_SPACING)
    shapely.prepare(section)
    _PLANE_SECTIONS[child] = (z, section)
    return section
