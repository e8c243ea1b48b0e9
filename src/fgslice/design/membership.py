"""Which child of a union (or fgrade) a point belongs to, for its materials.

The rule (see :mod:`fgslice.design.nodes`): the first child containing the point decides;
outside all children, the nearest one. Deciding it with the children's signed distances
costs a 3-D distance per point and child, which for a mesh is the whole cost of finding
materials. Points of one plane (all at the same ``z``, as the toolpath stages sample them
layer by layer) are instead tested against the child's own section there (point in
polygon), for every child whose distance is costly (it contains a mesh; parts of it
that are sampled, such as a ``function``, give their traced outline). Outside every
child, such a child's distance is the in-plane distance to its section (at least the
3-D distance, equal where the surface is vertical); a child the plane misses is farther
than any child the plane cuts, and only where the plane misses every child are the
3-D distances compared.

Sections are computed at the default spacing and kept for the last few planes of each
child (the stages ask for one layer many times, at a few heights, then move on).
"""

from __future__ import annotations

import weakref
from collections.abc import Sequence

import numpy as np
import shapely

_PLANE_SECTIONS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
"""Child node -> {z: prepared section at z}: the last planes each child was cut at."""
_KEPT_PLANES = 4
"""Planes kept per child: a layer's stages ask at its bottom, middle and top in turns."""
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
        if np.isinf(d).all():  # the plane misses every child
            d = np.stack([np.broadcast_to(c.sdf(x[outside], y[outside], z[outside]), outside.shape) for c in children])
        owner[outside] = np.argmin(d, axis=0)
    return owner


def _outside_distance(child, distance, index, x, y, z, by_section: bool) -> np.ndarray:
    """Distance (mm) from the points ``index`` to ``child`` (none of them inside it)."""
    if not by_section:
        return distance[index]
    section = _plane_section(child, float(z[0]))
    if section.is_empty:
        return np.full(index.shape, np.inf)
    return shapely.distance(section, shapely.points(x[index], y[index]))


def uses_sections(node) -> bool:
    """Whether ``node``'s points are located by its sections: it contains a mesh."""
    known = _USES_SECTIONS.get(node)
    if known is None:
        from fgslice.design.nodes import walk

        known = any(n.kind == "mesh" for n, *_ in walk(node))
        _USES_SECTIONS[node] = known
    return known


def _plane_section(child, z: float) -> shapely.Geometry:
    """``child``'s section at ``z`` (default spacing), prepared for point queries."""
    kept = _PLANE_SECTIONS.setdefault(child, {})
    if z in kept:
        return kept[z]
    from fgslice.design.nodes import DEFAULT_SECTION_SPACING

    section = child.section(z, DEFAULT_SECTION_SPACING)
    shapely.prepare(section)
    kept[z] = section
    for old in list(kept)[:-_KEPT_PLANES]:
        del kept[old]
    return section
