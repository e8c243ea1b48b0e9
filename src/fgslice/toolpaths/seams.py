"""Seams: where every closed loop (walls, concentric fill loops, skirt and brim) starts.

``seam_position`` as in PrusaSlicer:

* ``nearest``: the planner enters each loop at its vertex nearest the nozzle (shortest
  travel; the seams wander). Loops are left as they are here.
* ``rear``: the loop's rearmost vertex (largest Y); on a flat rear edge, the vertex of
  it nearest the middle of the loop in X.
* ``aligned``: the loop's sharpest corner (largest turn between its two segments, where
  a seam hides best), ties broken as ``rear``; a loop without a corner sharper than
  :data:`CORNER_DEGREES` (a circle, an ellipse) starts at its rearmost vertex. The
  choice depends on the loop's shape only, so loops of the same shape on successive
  layers start at the same place and the seams line up.
* ``random``: a point uniformly distributed along the loop's length (inserted there as
  a vertex), drawn from a generator seeded by the layer index and the loop's place in
  the layer, so the output is the same on every run and with any number of workers.

With any mode but ``nearest`` the planner enters each closed path at its first point
(``order_layer(fixed_seams=True)``). Bed frame, mm.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from fgslice.toolpaths.paths import Path

SEAM_POSITIONS = ("nearest", "aligned", "rear", "random")

CORNER_DEGREES = 30.0
"""``aligned``: a turn sharper than this is a corner the seam goes to."""

TIE_MM = 0.01
"""Vertices whose Y (``rear``) lies this close to the largest count as equally rear."""

TIE_DEGREES = 1.0
"""``aligned``: corners whose turns differ by less than this count as equally sharp."""


def place_seams(paths: list[Path], mode: str, layer_index: int) -> list[Path]:
    """``paths`` with every closed path rotated to start at its seam (see the module);
    open paths and, for ``nearest``, all paths unchanged."""
    if mode == "nearest":
        return paths
    rng = np.random.default_rng([layer_index, 40]) if mode == "random" else None
    out = []
    for path in paths:
        if not path.closed or len(path.points) < 3:
            out.append(path)
        elif rng is not None:
            out.append(_at_random(path, rng))
        else:
            k = _aligned_vertex(path.points) if mode == "aligned" else _rear_vertex(path.points)
            out.append(path if k == 0 else replace(path, points=np.roll(path.points, -k, axis=0)))
    return out


def _rear_vertex(points: np.ndarray, among: np.ndarray | None = None) -> int:
    """The rearmost vertex (largest Y) of ``points`` (or of the vertices ``among``); ties
    within :data:`TIE_MM` go to the one nearest the loop's middle in X."""
    candidates = np.arange(len(points)) if among is None else among
    y = points[candidates, 1]
    rear = candidates[y >= y.max() - TIE_MM]
    middle = (points[:, 0].min() + points[:, 0].max()) / 2
    return int(rear[np.argmin(np.abs(points[rear, 0] - middle))])


def _aligned_vertex(points: np.ndarray) -> int:
    """The sharpest corner of the closed ring ``points`` (see the module)."""
    incoming = points - np.roll(points, 1, axis=0)
    outgoing = np.roll(points, -1, axis=0) - points
    cross = incoming[:, 0] * outgoing[:, 1] - incoming[:, 1] * outgoing[:, 0]
    dot = np.einsum("ij,ij->i", incoming, outgoing)
    turn = np.degrees(np.abs(np.arctan2(cross, dot)))
    if turn.max() < CORNER_DEGREES:
        return _rear_vertex(points)
    return _rear_vertex(points, np.flatnonzero(turn >= turn.max() - TIE_DEGREES))


def _at_random(path: Path, rng: np.random.Generator) -> Path:
    """``path`` starting at a point drawn uniformly along its length."""
    ring = path.vertices
    seg = np.hypot(*np.diff(ring, axis=0).T)
    arc = np.concatenate([[0.0], np.cumsum(seg)])
    t = rng.uniform(0.0, arc[-1])
    j = int(np.clip(np.searchsorted(arc, t, side="right") - 1, 0, len(seg) - 1))
    u = (t - arc[j]) / seg[j] if seg[j] > 0 else 0.0
    point = ring[j] + u * (ring[j + 1] - ring[j])
    points = path.points
    rest = np.vstack([points[j + 1 :], points[: j + 1]])
    if u <= 1e-9:
        rest = np.vstack([points[j:], points[:j]])
        return replace(path, points=rest)
    if np.hypot(*(rest[0] - point)) <= 1e-9:
        return replace(path, points=rest)
    return replace(path, points=np.vstack([point, rest]))
