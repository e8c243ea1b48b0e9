"""OpenVCAD's evaluation methods of a node, computed on the fgslice tree the node builds.

* ``evaluate(x, y, z)``: the signed distance (mm, negative inside) at the point;
* ``gradient(x, y, z)`` or ``gradient(Vec3)``: the gradient of that distance by central
  differences of step :data:`GRADIENT_EPSILON` (OpenVCAD's ``m_gradient_epsilon``), a
  ``Vec3`` (unit length where the distance is exact);
* ``snap(Vec3)``: the nearest point on the surface, ``p - f(p) ∇f / |∇f|²`` repeated
  until ``|f|`` is below :data:`SNAP_TOLERANCE` (one step when the distance is exact);
* ``bounding_box()``: ``(Vec3 min, Vec3 max)``, the tight bounds of the node's shape (mm);
* ``prepare(voxel_size, bandwidth...)``: OpenVCAD's one-off sampling set-up before
  evaluation; fgslice needs none (it samples the design itself), so it only checks its
  arguments.

The node is converted at each call, so a node changed afterwards (``add_child``) answers
for what it is then.
"""

from __future__ import annotations

import numbers

import numpy as np

from fgslice.errors import DesignError

GRADIENT_EPSILON = 1e-4
"""Half the step of the central differences, mm (OpenVCAD's default gradient epsilon)."""

SNAP_TOLERANCE = 1e-7
"""``snap`` stops when the distance at the point is below this, mm."""

SNAP_STEPS = 50
"""Most Newton steps of ``snap``; a point that still misses the surface after them is an error."""


def _point(owner: str, args: tuple) -> np.ndarray:
    from fgslice.compat.pyvcad import Vec3

    if len(args) == 1 and isinstance(args[0], Vec3):
        return np.array(tuple(args[0]), dtype=float)
    if len(args) == 3 and all(isinstance(a, numbers.Real) and not isinstance(a, bool) for a in args):
        return np.array(args, dtype=float)
    raise DesignError(f"{owner} takes (x, y, z) numbers or a pyvcad.Vec3, got {args!r}")


def _sdf(node):
    from fgslice.compat.pyvcad import to_node

    tree = to_node(node)
    return lambda p: np.asarray(tree.sdf(p[..., 0], p[..., 1], p[..., 2]), dtype=float)


def _gradient(sdf, p: np.ndarray) -> np.ndarray:
    steps = np.eye(3) * GRADIENT_EPSILON
    return (sdf(p + steps) - sdf(p - steps)) / (2 * GRADIENT_EPSILON)


def evaluate(node, *args) -> float:
    """The signed distance of ``node`` at the point (mm)."""
    return float(_sdf(node)(_point(f"{type(node).__name__}.evaluate", args)))


def gradient(node, *args):
    """The gradient of the signed distance of ``node`` at the point, a ``Vec3``."""
    from fgslice.compat.pyvcad import Vec3

    return Vec3(*_gradient(_sdf(node), _point(f"{type(node).__name__}.gradient", args)))


def snap(node, *args):
    """The point of the surface of ``node`` nearest the given one, a ``Vec3``."""
    from fgslice.compat.pyvcad import Vec3

    owner = f"{type(node).__name__}.snap"
    sdf, p = _sdf(node), _point(owner, args)
    for _ in range(SNAP_STEPS):
        distance = float(sdf(p))
        if abs(distance) <= SNAP_TOLERANCE:
            return Vec3(*p)
        g = _gradient(sdf, p)
        norm2 = float(g @ g)
        if not np.isfinite(norm2) or norm2 == 0.0:
            break
        p = p - distance * g / norm2
    raise DesignError(f"{owner}: no surface point found from {tuple(_point(owner, args))} "
                      "(the distance has no slope there)", hint="snap a point nearer the surface")


def bounding_box(node):
    """``(min, max)`` corners of ``node``'s shape, two ``Vec3`` (mm)."""
    from fgslice.compat.pyvcad import Vec3, to_node

    lo, hi = to_node(node).bounds()
    if np.any(lo > hi):
        raise DesignError(f"{type(node).__name__}.bounding_box: the shape is empty")
    return Vec3(*lo), Vec3(*hi)


def prepare(node, voxel_size, *bandwidths) -> None:
    """OpenVCAD's ``prepare(voxel_size, bandwidth...)``: the arguments checked, nothing to do."""
    from fgslice.compat.pyvcad import Vec3

    owner = f"{type(node).__name__}.prepare"
    if not isinstance(voxel_size, Vec3) or not all(v > 0 for v in voxel_size):
        raise DesignError(f"{owner} takes a voxel size Vec3 of positive sizes first, got {voxel_size!r}")
    if not all(isinstance(b, numbers.Real) and not isinstance(b, bool) and b >= 0 for b in bandwidths):
        raise DesignError(f"{owner}: bandwidths are numbers >= 0, got {bandwidths!r}")
