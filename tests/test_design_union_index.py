"""A union of many primitives locates its children by bounding box
(fgslice.design.union_index): the same distances, inside/outside and owning children as
evaluating every child, on a union of cubes, spheres and cylinders, two materials."""

from __future__ import annotations

import functools

import numpy as np

from fgslice.design.language import parse_design
from fgslice.design.membership import owners
from fgslice.design.union_index import MANY_CHILDREN


EXACT = ["cube(1.5)", "sphere(1)", "cylinder(0.8, 2)", "rotate(30, 0, 45) { rectprism(1, 2, 0.5); }"]


def scattered_union(n: int, seed: int = 1, shapes=EXACT):
    rng = np.random.default_rng(seed)
    lines = []
    for i in range(n):
        x, y, z = rng.uniform(-30, 30, 3)
        material = ["blue", "yellow"][i % 2]
        shape = shapes[i % len(shapes)]
        shape = shape if "{" in shape else shape + ";"
        lines.append(f'translate({x:.2f}, {y:.2f}, {z / 10:.2f}) {{ fgrade(["1"], ["{material}"]) {{ {shape} }} }}')
    design = parse_design("union() {\n" + "\n".join(lines) + "\n}")
    node = design.root
    while node.kind != "union":
        node = node.children[0]
    return design, node


def test_the_index_gives_every_childs_minimum_and_owner():
    design, union = scattered_union(4 * MANY_CHILDREN)
    assert union._index is not None
    rng = np.random.default_rng(2)
    x, y, z = rng.uniform(-35, 35, (3, 4000)) * np.array([[1], [1], [0.15]])
    full = functools.reduce(np.minimum, (c.sdf(x, y, z) for c in union.children))
    assert np.allclose(union.sdf(x, y, z), full, atol=1e-12)
    assert (union.sdf(x, y, z) <= 0).sum() > 50  # some points are inside
    assert np.array_equal(union._index.owners(x, y, z), owners(union.children, x, y, z))
    # the fractions follow the owning child's material
    fractions = design.fractions(x, y, z)
    assert set(np.unique(np.round(fractions, 9), axis=0).ravel()) <= {0.0, 1.0}


def test_children_whose_distance_is_a_bound_keep_inside_and_outside():
    """A scaled sphere's distance is scaled down (a lower bound, not exact): a child
    farther than the nearest box's value may be left out, which can only raise the
    union's value where it is positive, never change its sign."""
    _, union = scattered_union(4 * MANY_CHILDREN, shapes=EXACT + ["scale(3, 1, 1) { sphere(0.7); }"])
    rng = np.random.default_rng(3)
    x, y, z = rng.uniform(-35, 35, (3, 4000)) * np.array([[1], [1], [0.15]])
    full = functools.reduce(np.minimum, (c.sdf(x, y, z) for c in union.children))
    indexed = union.sdf(x, y, z)
    assert np.array_equal(indexed <= 0, full <= 0)
    assert np.all(indexed >= full - 1e-12)
    assert np.array_equal(indexed[full <= 0], full[full <= 0])


def test_a_small_union_evaluates_every_child():
    assert scattered_union(MANY_CHILDREN)[1]._index is None
