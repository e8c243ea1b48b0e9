"""A short fingerprint of a design's geometry and field, recorded in the G-code header.

``fgslice simulate`` (and the report) compare a G-code file against a design; a design
that is not the one the file was sliced from gives a meaningless comparison. The
fingerprint tells them apart without the design's file (designs built in Python have
none) and whatever the file's name, spacing or comments: it hashes the material names,
the bounding box (to 1 um) and, at :data:`POINTS` fixed points spread over that box,
whether each is inside and its normalized fractions (to 1e-4); a design with meshes,
its meshes' vertices and triangles instead of the samples.
"""

from __future__ import annotations

import functools
import hashlib

import numpy as np

from fgslice.design.base import Design

POINTS = 256
"""Sample points of the fingerprint (fixed, in the unit cube scaled to the bounding box)."""


@functools.cache
def _unit_points() -> np.ndarray:
    return np.random.default_rng(20240541).random((POINTS, 3))


def fingerprint(design: Design) -> str:
    """16 hexadecimal digits naming ``design``'s materials, bounds, inside and fractions.

    A design holding meshes is named by its meshes' vertices and triangles instead of
    samples: a mesh's distance at arbitrary points needs tables the slice never builds.
    """
    lo, hi = (np.asarray(b, dtype=float) for b in design.bounds())
    digest = hashlib.sha256()
    digest.update("\0".join(m.name for m in design.materials).encode())
    digest.update(np.round(np.concatenate([lo, hi]) * 1000).astype(np.int64).tobytes())
    meshes = getattr(design, "meshes", ())
    for mesh in meshes:
        digest.update(np.round(mesh.geometry._vertices * 1000).astype(np.int64).tobytes())
        digest.update(np.asarray(mesh.geometry._faces, dtype=np.int64).tobytes())
    if not meshes:
        x, y, z = (lo + (hi - lo) * _unit_points()).T
        digest.update((np.asarray(design.sdf(x, y, z)) <= 0).tobytes())
        fractions = np.nan_to_num(np.asarray(design.fractions(x, y, z), dtype=float))
        digest.update(np.round(fractions * 1e4).astype(np.int64).tobytes())
    return digest.hexdigest()[:16]
