"""Triangle meshes as geometry: loading, exact planar sections and signed distance.

Everything is in millimetres in the mesh file's own frame (no re-centering here; a
design node places the mesh).

Sections are exact: every triangle crossing the plane contributes the segment between
the two points where the plane cuts its edges. Conventions and robustness rules:

* A vertex lying exactly on the plane counts as *above* it. This is a symbolic
  perturbation (the plane moved down by an infinitesimal), applied identically to every
  triangle sharing the vertex, so no segment is lost or doubled.
* Segment ends are identified by the unique mesh edge they lie on; segments are stitched
  into loops through those ids (two segments per edge on a manifold mesh; at an edge
  of two consistently wound faces the next segment is found directly from the face
  across, a table built for the whole mesh or for the triangles a batch of planes
  spans, see :class:`MeshGeometry`). At a
  non-manifold edge (more than two faces) a segment's end is paired with another
  segment's start (in order of index), so loops keep the triangles' winding. Ends left
  open (holes in a non-watertight mesh) are joined to the nearest other open end of
  the same plane when both are each other's nearest and closer than
  ``gap_tolerance``; chains still open after that are closed directly.
* Segments are directed by their triangle's winding, so each loop has an orientation:
  counter-clockwise around solid for an outward-wound shell. Loops with fewer than
  three points or (almost) zero area are dropped. The region is filled with the
  nonzero winding rule, as slicers do: overlapping shells (separate bodies exported
  into one file) give their union, an inward-wound inner shell (a hollow part) a hole.
  A loop whose orientation cannot be trusted (an open chain closed directly, or one
  mixing directions) falls back to even-odd: it toggles between solid and empty.
  Planes with touching or crossing loops are filled from the faces of the noded
  loops; a remaining invalid result (a self-intersecting loop) goes through
  ``shapely.make_valid``'s ``structure`` method (the faces enclosed by its outer rings
  minus those enclosed by its holes) and is reduced to its polygons.
* Outer rings are counter-clockwise, holes clockwise.

The signed distance (negative inside) is the exact distance to the nearest triangle
with a sign from an inside test that tolerates holes: the parity of crossings of three
rays (+x, +y, +z) from the point, decided by majority. On a watertight mesh the three
agree; a hole smaller than the part fools at most the rays that pass through it.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from functools import cached_property
from pathlib import Path

import numpy as np
import shapely
from fgslice.errors import MeshError

SUPPORTED_FORMATS = {".stl": "stl", ".3mf": "3mf", ".obj": "obj"}

_EMPTY = shapely.MultiPolygon()
"""The empty section (geometries are immutable, so one instance serves every plane)."""

_MIN_LOOP_AREA = 1e-10
"""Loops with an absolute area below this (mm^2) are degenerate and dropped."""

_MAX_PAIRS_PER_BATCH = 2_000_000
"""Upper bound on (plane, triangle) pairs processed at once by :meth:`sections`."""

_SDF_CHUNK = 8192
"""Query points processed at once by :meth:`MeshGeometry.sdf` (bounds memory)."""

_REEXPORT_HINT = "the file may be truncated or not a mesh; re-export it from your CAD program"


def load_mesh(path: str | Path, *, gap_tolerance: float = 0.25) -> MeshGeometry:
    """Read an STL (binary or ASCII), 3MF or OBJ file into a :class:`MeshGeometry`.

    STL files are read directly with numpy; 3MF and OBJ files through trimesh (imported
    only for them). All bodies of a 3MF or OBJ scene (all solids of an ASCII STL) are
    concatenated into one mesh; coincident vertices are merged. ``gap_tolerance`` (mm)
    is the largest hole gap a section bridges (see the module notes).

    Raises:
        MeshError: the file is missing, of an unsupported type, unreadable or corrupt,
            holds no triangles, or has non-finite vertex coordinates.
    """
    path = Path(path)
    file_type = SUPPORTED_FORMATS.get(path.suffix.lower())
    if file_type is None:
        raise MeshError(
            f"unsupported mesh file type '{path.suffix or path.name}'",
            file=path,
            hint="use an .stl, .3mf or .obj file",
        )
    if not path.is_file():
        raise MeshError("mesh file not found", file=path, hint="check the path (relative paths start at the design file's folder)")
    refuse_lfs_pointer(path)
    if file_type == "stl":  # the corners of each triangle in turn: faces are (0, 1, 2), (3, 4, 5), ...
        vertices, faces, element = _read_stl(path).reshape(-1, 3), None, "triangle"
    else:
        vertices, faces = _read_with_trimesh(path, file_type)
        element = "vertex"
    if len(vertices) == 0 or (faces is not None and len(faces) == 0):
        raise MeshError(
            "the mesh holds no triangles",
            file=path,
            hint="export the bodies as a triangle mesh (not only points, lines or an empty scene)",
        )
    if not np.isfinite(vertices).all():  # all at once first: 10x faster than row by row
        bad = int(np.flatnonzero(~np.isfinite(vertices).all(axis=1))[0]) // (3 if element == "triangle" else 1)
        raise MeshError(
            f"{element} {bad} has a non-finite coordinate (NaN or infinity)",
            file=path,
            hint="repair the mesh (e.g. with your CAD program's mesh repair) and export it again",
        )
    return MeshGeometry(vertices, faces, merge=True, path=path, gap_tolerance=gap_tolerance)


LFS_POINTER = b"version https://git-lfs.github.com/spec/v1"
"""How a Git LFS pointer file starts (what a clone holds in place of a large file until
``git lfs pull`` fetches it)."""


def refuse_lfs_pointer(path: Path) -> None:
    """Raise a MeshError naming the fix when ``path`` is a Git LFS pointer, not the file."""
    with path.open("rb") as stream:
        if stream.read(len(LFS_POINTER)) == LFS_POINTER:
            raise MeshError(
                "this is a Git LFS pointer, not the file itself: run git lfs pull",
                file=path,
                hint="in the repository's folder: git lfs install && git lfs pull (it fetches the large files)",
            )


def _read_with_trimesh(path: Path, file_type: str) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (V, 3) mm and faces (F, 3) of a 3MF or OBJ file, all bodies concatenated."""
    import trimesh

    try:
        with path.open("rb") as stream:
            loaded = trimesh.load(stream, file_type=file_type, process=False)
            if isinstance(loaded, trimesh.Scene):
                loaded = loaded.to_mesh()
    except Exception as exc:  # trimesh raises many unrelated types for corrupt input
        raise MeshError(f"cannot read the {file_type.upper()} mesh: {exc}", file=path, hint=_REEXPORT_HINT) from exc
    if not isinstance(loaded, trimesh.Trimesh):
        return np.empty((0, 3)), np.empty((0, 3), dtype=np.int64)
    return np.asarray(loaded.vertices, dtype=float), np.asarray(loaded.faces, dtype=np.int64)


_STL_HEADER_BYTES = 84
"""A binary STL starts with an 80-byte header and the uint32 triangle count."""

_STL_RECORD = np.dtype([("normal", "<f4", 3), ("corners", "<f4", (3, 3)), ("attribute", "<u2")])
"""One 50-byte binary STL triangle record (little endian)."""

_NUMBER = rb"[-+]?(?:(?:\d+\.?\d*|\.\d+)(?:e[-+]?\d+)?|nan|inf(?:inity)?)"


def _facet_body(number: bytes) -> bytes:
    """Regex of an ASCII STL facet after its ``facet`` keyword, vertex coordinates matched by ``number``."""
    vertex = rb"\s+vertex\s+" + number + rb"\s+" + number + rb"\s+" + number
    return rb"\s+normal\s+\S+\s+\S+\s+\S+\s+outer\s+loop" + vertex * 3 + rb"\s+endloop\s+endfacet(?!\S)"


_FACET_KEYWORD = rb"(?<!\S)facet(?!\S)"
_ASCII_FACET = _FACET_KEYWORD + _facet_body(b"(" + _NUMBER + b")")
_ASCII_BAD_FACET = _FACET_KEYWORD + b"(?!" + _facet_body(_NUMBER) + b")"
"""Patterns of a well-formed facet (capturing its nine coordinates) and of a malformed one;
compiled (and cached) by :mod:`re` on first use, so binary STL files never pay for them."""


def _read_stl(path: Path) -> np.ndarray:
    """The (F, 3, 3) triangle corners (mm, float64) of a binary or ASCII STL file.

    A file is binary when its size is exactly the header plus 50 bytes per announced
    triangle, ASCII when it starts with ``solid`` and holds text; anything else is an
    error naming what does not fit.
    """
    data = path.read_bytes()
    count = int.from_bytes(data[80:84], "little") if len(data) >= _STL_HEADER_BYTES else None
    if count is not None and len(data) == _STL_HEADER_BYTES + count * _STL_RECORD.itemsize:
        records = np.frombuffer(data, dtype=_STL_RECORD, offset=_STL_HEADER_BYTES)
        return records["corners"].astype(np.float64)
    if data.lstrip()[:5].lower() == b"solid" and b"\0" not in data[:1024]:
        return _read_ascii_stl(data.lower(), path)
    if count is None:
        raise MeshError(
            f"the file is too short to be an STL ({len(data)} bytes; a binary STL has at least {_STL_HEADER_BYTES})",
            file=path,
            hint=_REEXPORT_HINT,
        )
    expected = _STL_HEADER_BYTES + count * _STL_RECORD.itemsize
    raise MeshError(
        f"not a valid STL: a binary STL announcing {count} triangles has {expected} bytes, this file has {len(data)}"
        + (" (truncated?)" if len(data) < expected else ""),
        file=path,
        hint=_REEXPORT_HINT,
    )


def _read_ascii_stl(text: bytes, path: Path) -> np.ndarray:
    """The (F, 3, 3) corners of an ASCII STL given as lower-cased bytes (the facets of every solid).

    Each facet must read ``facet normal nx ny nz``, ``outer loop``, three ``vertex x y z``,
    ``endloop``, ``endfacet`` (any whitespace between words); the first one that does
    not is reported with its line and column.
    """
    numbers = re.findall(_ASCII_FACET, text)
    if len(numbers) != len(re.findall(_FACET_KEYWORD, text)):
        bad = re.search(_ASCII_BAD_FACET, text).start()
        raise MeshError(
            "malformed ASCII STL facet: expected 'facet normal nx ny nz', 'outer loop', "
            "three 'vertex x y z' lines, 'endloop', 'endfacet'",
            file=path,
            line=text.count(b"\n", 0, bad) + 1,
            column=bad - text.rfind(b"\n", 0, bad),
            hint=_REEXPORT_HINT,
        )
    if text.rfind(b"endsolid") < text.rfind(b"endfacet"):
        raise MeshError("the ASCII STL ends without 'endsolid'", file=path, line=text.count(b"\n") + 1, hint=_REEXPORT_HINT)
    return np.array(numbers, dtype=bytes).reshape(-1, 9).astype(np.float64).reshape(-1, 3, 3)


_MERGE_DIGITS = 8
"""Vertices equal after rounding to this many decimals (mm) are merged (trimesh's default)."""

_HASH = np.array([0x9E3779B97F4A7C15, 0xC2B2AE3D27D4EB4F, 0x165667B19E3779F9], dtype=np.uint64)


def _sorted_groups(keys: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Equal keys grouped by one argsort: the sorting order (the keys of a group in no
    particular order: :func:`_group_firsts` gives each group's first in input order), a
    mask over the sorted keys marking each group's start, and each key's group index
    (groups numbered in key order).

    numpy's quicksort is vectorized (AVX2, AVX-512) and sorts 64-bit keys 3-4x faster
    than its stable sort, a timsort (3DBenchy's 675 k vertex keys: 16 against 70 ms)."""
    order = np.argsort(keys, kind="quicksort")
    sorted_keys = keys[order]
    new = np.concatenate(([True], sorted_keys[1:] != sorted_keys[:-1]))
    inverse = np.empty(len(keys), dtype=np.int64)
    inverse[order] = np.cumsum(new) - 1
    return order, new, inverse


def _group_firsts(order: np.ndarray, new: np.ndarray) -> np.ndarray:
    """Each group of :func:`_sorted_groups` by its first key in input order (the smallest
    index among its keys), in group order."""
    return np.minimum.reduceat(order, np.flatnonzero(new))


def _stable_order(keys: np.ndarray) -> np.ndarray:
    """``np.argsort(keys, kind="stable")`` of integer keys, as the quicksort of the
    distinct keys ``key * n + index`` (``n`` keys): 2-3x faster than numpy's stable sort
    on 64-bit keys (see :func:`_sorted_groups`). Keys that could overflow that product,
    or negative ones, take the stable sort."""
    n = len(keys)
    if n == 0:
        return np.empty(0, dtype=np.intp)
    if int(keys.min()) < 0 or int(keys.max()) >= (np.iinfo(np.int64).max - n) // n:
        return np.argsort(keys, kind="stable")
    return np.argsort(keys.astype(np.int64) * n + np.arange(n), kind="quicksort")


def _merge_vertices(vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Coincident vertices merged: the kept vertices and, for each input row, its kept index.

    Rows are rounded to :data:`_MERGE_DIGITS` decimals, hashed to one 64-bit key and
    sorted once; a hash collision between different rows (checked against the kept
    rows) falls back to ``np.unique(axis=0)``.
    """
    scaled = vertices * 10.0**_MERGE_DIGITS
    q = np.rint(scaled, out=scaled).astype(np.int64)  # rounded in place: one temporary fewer
    del scaled
    with np.errstate(over="ignore"):
        key = q.view(np.uint64) @ _HASH
    order, new, inverse = _sorted_groups(key)
    first = _group_firsts(order, new)
    if not np.array_equal(np.take(np.take(q, first, axis=0), inverse, axis=0), q):
        _, first, inverse = np.unique(q, axis=0, return_index=True, return_inverse=True)
        inverse = inverse.reshape(-1)
    return np.take(vertices, first, axis=0), inverse


def _column_extremes(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Smallest and largest value of each column of ``points`` (N, 3), one column at a
    time: a reduction along the rows of an (N, 3) array runs three values at a time,
    about 8x slower (3DBenchy: 58 -> 7 ms)."""
    return (np.array([points[:, k].min() for k in range(points.shape[1])]),
            np.array([points[:, k].max() for k in range(points.shape[1])]))


class MeshGeometry:
    """A triangle mesh with exact sections and a signed distance (mm, file frame).

    Sections need tables of the triangles (vertices merged and ordered by height, edges,
    the face across each edge, triangles binned by height: :class:`_Tables`). Those of
    the whole mesh are built when asked for (:meth:`prepare_sections`, :attr:`watertight`)
    and kept. Until then, every call of :meth:`sections` (and :meth:`section`) builds
    tables of only the triangles its planes can cross: a triangle that a plane crosses
    through an edge shares that edge with another crossed triangle, so the subset
    sections exactly like the whole mesh. A slice's batches of layers are then sectioned in the worker
    processes, each with its own small tables, while the parent only reads the file.
    3DBenchy, 240 layers in 15 batches: the subsets hold 0.98x its triangles in all and
    cost 171-210 ms more CPU than sectioning with the whole tables, which took the
    parent 260-330 ms on one core; a single-material slice with two workers went from
    1.98 to 1.80 s (medians of 12 alternating runs) and its peak from 145 to 86 MB.

    Attributes:
        path: the file the mesh was read from (None when built in memory).
        gap_tolerance: the largest gap (mm) between open chain ends a section bridges.
    """

    def __init__(self, vertices: np.ndarray, faces: np.ndarray | None = None, *, merge: bool = False,
                 path: str | Path | None = None, gap_tolerance: float = 0.25):
        """Build from ``vertices`` (V, 3) in mm and ``faces`` (F, 3) vertex indices (wound
        counter-clockwise seen from outside), or ``faces=None``: every three consecutive
        vertices are one triangle's corners. With ``merge``, coincident vertices (equal
        after rounding to :data:`_MERGE_DIGITS` decimals) are merged before any table is
        built; without, vertices are used as given."""
        self.path = Path(path) if path is not None else None
        self.gap_tolerance = float(gap_tolerance)
        self._vertices = np.asarray(vertices, dtype=float)
        self._faces = np.arange(len(self._vertices)).reshape(-1, 3) if faces is None else np.asarray(faces, dtype=np.int64)
        self._merge = merge
        self._lo, self._hi = _column_extremes(self._vertices)  # before any merge

    @property
    def triangle_count(self) -> int:
        """Number of triangles."""
        return len(self._faces)

    @cached_property
    def watertight(self) -> bool:
        """True when every edge is shared by exactly two faces."""
        if len(self._faces) == 0:
            return False
        whole = self._whole
        return bool((np.bincount(whole.face_edges.ravel(), minlength=len(whole.edges)) == 2).all())

    def bounds(self) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
        """Axis-aligned bounding box ``((minx, miny, minz), (maxx, maxy, maxz))`` in mm."""
        return (tuple(float(v) for v in self._lo), tuple(float(v) for v in self._hi))

    def prepare_sections(self) -> None:
        """Build the whole mesh's tables now (before worker processes fork, so that they
        share them: one plane per task needs them, a subset per plane would cost more)."""
        self._whole  # a cached property: built here, then kept

    def section(self, z: float) -> shapely.MultiPolygon:
        """The cross-section at height ``z`` (mm), valid; empty outside the mesh."""
        return self.sections([z])[0]

    def sections(self, zs: Sequence[float] | np.ndarray) -> list[shapely.MultiPolygon]:
        """Cross-sections at every height of ``zs`` (any order), computed together: with
        the whole mesh's tables once they exist, else with tables of the triangles that
        span the heights' range."""
        zs = np.asarray(zs, dtype=float).ravel()
        if len(zs) == 0:
            return []
        tables = self.__dict__.get("_whole")
        if tables is None:
            zmin, zmax = self._face_spans
            spanned = self._faces[(zmin < zs.max()) & (zmax >= zs.min())]
            if len(spanned) == 0:
                return [_EMPTY] * len(zs)
            tables = self._tables(spanned)
        return tables.sections(zs, self.gap_tolerance)

    def transformed(self, matrix: np.ndarray, offset: np.ndarray) -> MeshGeometry:
        """This mesh with every vertex ``v`` moved to ``matrix @ v + offset`` (mm): a new
        geometry whose sections and distance are exact in the new frame, whatever the map
        (rotation, scaling, mirror). A map that mirrors (negative determinant) reverses
        each triangle's corners so that the faces still wind counter-clockwise seen from
        outside."""
        matrix = np.asarray(matrix, dtype=float)
        faces = self._faces[:, ::-1] if np.linalg.det(matrix) < 0 else self._faces
        return MeshGeometry(self._vertices @ matrix.T + np.asarray(offset, dtype=float), np.ascontiguousarray(faces),
                            merge=self._merge, path=self.path, gap_tolerance=self.gap_tolerance)

    @cached_property
    def _whole(self) -> "_Tables":
        if self._merge:  # from here on the merged vertices stand for the file's (one copy fewer)
            self._vertices, inverse = _merge_vertices(self._vertices)
            self._faces, self._merge = inverse[self._faces], False
            self.__dict__.pop("_face_spans", None)
        return _Tables(self._vertices, self._faces)

    @cached_property
    def _face_spans(self) -> tuple[np.ndarray, np.ndarray]:
        """Lowest and highest corner height of each face, mm."""
        z0, z1, z2 = np.ascontiguousarray(self._vertices[:, 2])[self._faces].T
        return np.minimum(np.minimum(z0, z1), z2), np.maximum(np.maximum(z0, z1), z2)

    def _tables(self, faces: np.ndarray) -> "_Tables":
        """Tables of the triangles ``faces`` (rows of the mesh's faces)."""
        if self._merge:
            vertices, inverse = _merge_vertices(self._vertices[faces.ravel()])
            return _Tables(vertices, inverse.reshape(-1, 3))
        used, inverse = np.unique(faces, return_inverse=True)
        return _Tables(self._vertices[used], inverse.reshape(-1, 3))

    def sdf(self, x: np.ndarray, y: np.ndarray, z: np.ndarray) -> np.ndarray:
        """Signed distance (mm) to the surface, negative inside; shape of the broadcast."""
        x, y, z = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float), np.asarray(z, float))
        points = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
        out = np.empty(len(points))
        for start in range(0, len(points), _SDF_CHUNK):
            chunk = points[start : start + _SDF_CHUNK]
            distance = self._distance.query(chunk)
            inside = sum(counter.odd_crossings(chunk) for counter in self._ray_counters) >= 2
            out[start : start + _SDF_CHUNK] = np.where(inside, -distance, distance)
        return out.reshape(x.shape)

    @cached_property
    def _distance(self) -> _TriangleDistance:
        return _TriangleDistance(self._vertices[self._faces])

    @cached_property
    def _ray_counters(self) -> tuple[_RayCrossings, ...]:
        triangles = self._vertices[self._faces]
        return tuple(_RayCrossings(triangles, axis) for axis in range(3))


class _Tables:
    """What sections need of a set of triangles: vertices ordered by height and faces by
    lowest vertex (:func:`_sorted_by_height`), unique edges, each face's edges and the
    face across each of them (:func:`_edge_tables`), corner heights, edge end points and
    the faces binned by height (:class:`_SlabIndex`)."""

    def __init__(self, vertices: np.ndarray, faces: np.ndarray):
        self.vertices, self.faces = _sorted_by_height(vertices, faces)
        self.edges, self.face_edges, self.across = _edge_tables(self.faces, len(self.vertices))
        self.face_z = np.ascontiguousarray(self.vertices[:, 2])[self.faces]
        self.edge_ends = np.take(self.vertices, self.edges, axis=0)
        z0, z1, z2 = self.face_z.T
        self.slabs = _SlabIndex(np.minimum(np.minimum(z0, z1), z2), np.maximum(np.maximum(z0, z1), z2))

    def sections(self, zs: np.ndarray, gap_tolerance: float) -> list[shapely.MultiPolygon]:
        """Sections at the heights ``zs``, in batches of at most :data:`_MAX_PAIRS_PER_BATCH`
        (plane, triangle) pairs."""
        candidates = self.slabs.candidate_counts(zs)
        result = np.empty(len(zs), dtype=object)
        begin = 0
        while begin < len(zs):
            end = begin + 1
            total = int(candidates[begin])
            while end < len(zs) and total + candidates[end] <= _MAX_PAIRS_PER_BATCH:
                total += int(candidates[end])
                end += 1
            result[begin:end] = self._section_batch(zs[begin:end], gap_tolerance)
            begin = end
        return list(result)

    def _section_batch(self, zs: np.ndarray, gap_tolerance: float) -> np.ndarray:
        """Sections (MultiPolygons) at the heights ``zs``."""
        plane, face = self.slabs.crossings(zs)
        if len(face) == 0:
            return np.full(len(zs), _EMPTY, dtype=object)
        node_ids, points, next_face = _plane_segments(self.face_z, self.edge_ends, self.face_edges, self.across, face, zs[plane])
        node_ids = node_ids + plane[:, None] * len(self.edges)
        key = plane * len(self.faces) + face  # ascending: crossings() lists planes, then faces, in order
        successor = np.where(next_face >= 0, np.searchsorted(key, plane * len(self.faces) + next_face), -1)
        rings, ring_plane, ring_direction = _stitch(node_ids, points, plane, successor, gap_tolerance)
        return _assemble(rings, ring_plane, ring_direction, len(zs))


def _sorted_by_height(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Vertices renumbered by height and faces by lowest vertex (both stable), so that the
    triangles and edges a plane crosses lie close together in memory. The heights are
    ranked first (equal heights, -0.0 and 0.0 too, share a rank), so that both sorts are
    :func:`_stable_order`'s."""
    _, height_rank = np.unique(vertices[:, 2], return_inverse=True)
    order = _stable_order(height_rank.reshape(-1))
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    faces = rank[faces]
    lowest = np.minimum(np.minimum(faces[:, 0], faces[:, 1]), faces[:, 2])
    return np.take(vertices, order, axis=0), np.take(faces, _stable_order(lowest), axis=0)


def _edge_tables(faces: np.ndarray, n_vertices: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The unique edges ``(E, 2)`` (lower vertex index first, sorted), each face's edges
    ``(F, 3)`` and the face across each of them ``(F, 3)``, or -1.

    A face's edges are (v0, v1), (v1, v2), (v2, v0), in that order. Only edges of
    exactly two faces wound consistently (one runs the edge upwards in vertex index,
    the other downwards) have a face across; at the others (boundary, non-manifold or
    flipped) sections pair segment ends by edge id.
    """
    following = np.roll(faces, -1, axis=1)
    upwards = (faces < following).ravel()
    keys = (np.minimum(faces, following) * np.int64(n_vertices) + np.maximum(faces, following)).ravel()
    order, new, inverse = _sorted_groups(keys)
    unique = keys[order[new]]
    two_faces = np.flatnonzero(~new[1:] & np.r_[new[2:], True] & new[:-1])
    a, b = order[two_faces], order[two_faces + 1]
    consistent = upwards[a] != upwards[b]
    a, b = a[consistent], b[consistent]
    across = np.full(keys.size, -1, dtype=np.int64)
    across[a] = b // 3
    across[b] = a // 3
    return np.column_stack([unique // n_vertices, unique % n_vertices]), inverse.reshape(-1, 3), across.reshape(-1, 3)


class _SlabIndex:
    """Triangles binned by the horizontal slabs (height ``step``, mm) their z-extent overlaps.

    A plane at height ``z`` is crossed by a triangle when ``zmin < z <= zmax`` (a vertex
    on the plane counts as above it); every such triangle is binned in the plane's slab,
    so a plane's candidates are one slab's list instead of the whole mesh. ``step``
    starts at the median triangle height and doubles until the bins hold at most
    four entries per triangle.
    """

    _ENTRIES_PER_TRIANGLE = 4

    def __init__(self, zmin: np.ndarray, zmax: np.ndarray):
        self._zmin, self._zmax = zmin, zmax
        self._z0 = float(zmin.min())
        span = float(zmax.max()) - self._z0
        self._step = max(float(np.median(zmax - zmin)), span / 65536, 1e-9)
        while True:
            lo = self._slab(zmin)
            counts = self._slab(zmax) - lo + 1
            if counts.sum() <= self._ENTRIES_PER_TRIANGLE * len(zmin):
                break
            self._step *= 2
        slab = np.repeat(lo, counts) + _ranks_within_runs(counts)
        order = np.argsort(slab.astype(np.min_scalar_type(int(slab.max()))), kind="stable")  # radix sort when small
        self._faces = np.repeat(np.arange(len(zmin)), counts)[order]
        self._start = np.searchsorted(slab[order], np.arange(int(slab.max()) + 2))

    def _slab(self, z: np.ndarray) -> np.ndarray:
        return np.floor((z - self._z0) / self._step).astype(np.int64)

    def _bins(self, zs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """First entry and entry count of each height's slab (count 0 outside the mesh)."""
        slab = self._slab(np.clip(zs, self._z0 - self._step, self._z0 + self._step * len(self._start)))
        inside = (slab >= 0) & (slab < len(self._start) - 1)
        slab = np.where(inside, slab, 0)
        first = self._start[slab]
        return first, np.where(inside, self._start[slab + 1] - first, 0)

    def candidate_counts(self, zs: np.ndarray) -> np.ndarray:
        """Upper bound on the triangles crossing each plane of ``zs``."""
        return self._bins(zs)[1]

    def crossings(self, zs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(plane, face)``: each triangle crossing each plane of ``zs``; planes ascending, then faces."""
        first, counts = self._bins(zs)
        plane = np.repeat(np.arange(len(zs)), counts)
        face = self._faces[np.repeat(first, counts) + _ranks_within_runs(counts)]
        z = zs[plane]
        crossing = (self._zmin[face] < z) & (z <= self._zmax[face])
        return plane[crossing], face[crossing]


def _ranks_within_runs(counts: np.ndarray) -> np.ndarray:
    """0, 1, ..., counts[i]-1 for each i, concatenated."""
    total = int(counts.sum())
    starts = np.cumsum(counts) - counts
    return np.arange(total) - np.repeat(starts, counts)


def _crossed_edges() -> np.ndarray:
    """(8, 2): for each pattern ``sum(above_j << j)`` of a triangle's vertices above the
    plane, the slot (0..2, edge j joins v_j and v_j+1) of the edge where its segment
    starts (v_j above, v_j+1 below) and of the one where it ends (the opposite)."""
    above = (np.arange(8)[:, None] >> np.arange(3)) & 1 == 1
    above_next = np.roll(above, -1, axis=1)
    return np.column_stack([np.argmax(above & ~above_next, axis=1), np.argmax(above_next & ~above, axis=1)])


_CROSSED_EDGES = _crossed_edges()
_VERTEX_BITS = np.array([1, 2, 4])


def _plane_segments(face_z, edge_ends, face_edges, across, face, z):
    """Segments cut by planes at heights ``z`` from triangles ``face`` (one plane each).

    ``face_z`` (F, 3) are the triangles' vertex heights, ``edge_ends`` (E, 2, 3) the
    end points of each unique edge, ``face_edges`` (F, 3) each triangle's edges,
    ``across`` (F, 3) the face across each of them (:func:`_edge_tables`).

    Returns ``(edge_ids, points, next_face)``: shapes (M, 2), (M, 2, 2) and (M,) — for
    both ends of each segment, the unique edge it lies on and its XY position; and the
    face whose segment starts where this one ends, when the edge has a face across
    (else -1). The position is computed from the edge's canonical vertex order, so
    both faces of an edge agree bit for bit.

    Segments are directed by the triangle's winding: they start on the edge the winding
    crosses downwards (v_j above, v_j+1 below) and end on the one it crosses upwards.
    That is the direction ``z x n`` for the triangle normal ``n``, so an outward-wound
    shell gives counter-clockwise loops (seen from +z) around solid and clockwise ones
    around holes.
    """
    pattern = (face_z[face] >= z[:, None]) @ _VERTEX_BITS
    slots = _CROSSED_EDGES[pattern]
    edge_ids = face_edges[face[:, None], slots]
    ends = edge_ends[edge_ids]
    a, b = ends[:, :, 0], ends[:, :, 1]
    t = (z[:, None] - a[..., 2]) / (b[..., 2] - a[..., 2])
    points = a[..., :2] + t[..., None] * (b[..., :2] - a[..., :2])
    return edge_ids, points, across[face, slots[:, 1]]


def _stitch(node_ids: np.ndarray, points: np.ndarray, plane: np.ndarray, successor: np.ndarray, gap_tolerance: float):
    """Order segments into rings.

    ``node_ids`` (M, 2) identify each segment end (equal ids = same point), ``points``
    (M, 2, 2) are their positions, ``plane`` (M,) their plane; ``successor`` (M,) is
    the segment starting where each one ends when that is known from the mesh's
    adjacency (else -1: the ends are paired by node id). Ends are handled as
    half-ends ``h = 2 * segment + end``; a walk enters a segment at ``h``, leaves at
    ``h ^ 1`` and continues at that end's mate. Returns ``(rings, ring_plane, ring_direction)`` where
    ``rings = (ring_index, coords, ring_size)``: the ring of each point (ascending),
    the (P, 2) points in ring order and the number of points of each ring.

    Every loop and open chain is walked twice, once per direction, over disjoint
    half-ends; the walk whose smallest half-end is even is kept. A loop's points start
    at its smallest half-end, a chain's at its free end and close with the point where
    it leaves its last segment. Rings are ordered by smallest half-end.

    ``ring_direction`` (one per ring) tells whether a ring's point order follows its
    segments' directions (+1), runs against all of them (-1) or cannot be trusted (0):
    the ring is an open chain closed directly, or it mixes both (non-manifold pairing,
    or open ends joined across a gap with opposite directions).
    """
    xy = points.reshape(-1, 2)
    half_plane = np.repeat(plane, 2)
    mate = _mates(node_ids.ravel(), successor)
    _pair_open_ends(mate, xy, half_plane, gap_tolerance)
    half = np.arange(node_ids.size)
    if ((mate ^ half)[mate >= 0] & 1).all():
        # every mate joins a segment's end to a start: the walks along the segments'
        # directions use only the starts (even half-ends), the reversed ones only the ends
        succ = mate[1::2] // 2  # the segment whose start is this segment's end's mate (-1 stays -1)
        walk, first = _walks(succ)
        walk = walk * 2
        succ = mate[half ^ 1]
    else:
        succ = mate[half ^ 1]
        walk, first = _walks(succ)
    label = np.minimum.reduceat(walk, first)
    last = np.r_[first[1:], len(walk)] - 1
    is_open = succ[walk[last]] < 0
    keep = np.flatnonzero(label % 2 == 0)
    keep = keep[_stable_order(label[keep])]
    label, is_open = label[keep], is_open[keep]
    entered = (last - first + 1)[keep]
    backward = np.add.reduceat(walk % 2, first)[keep]
    starts = np.repeat(first[keep], entered) + _ranks_within_runs(entered)
    halves = walk[starts]
    extra = np.zeros(len(halves), dtype=np.int64)
    extra[np.cumsum(entered)[is_open] - 1] = 1
    ring_size = entered + is_open
    repeated = np.repeat(halves, extra + 1)
    leaving = np.zeros(len(repeated), dtype=np.int64)
    leaving[np.cumsum(ring_size)[is_open] - 1] = 1
    coords = xy[repeated ^ leaving]
    ring_index = np.repeat(np.arange(len(keep)), ring_size)
    ring_direction = np.where(backward == 0, 1, np.where(backward == entered, -1, 0)).astype(np.int8)
    ring_direction[is_open] = 0
    return (ring_index, coords, ring_size), half_plane[label], ring_direction


def _walks(succ: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every element once, in walks along ``succ`` (-1 = stop; at most one predecessor each).

    Returns the elements in walk order and the position where each walk starts. Chains
    are walked from their first element (the one without predecessor), in order of it;
    then loops from their smallest element, in order of it.

    Pointer doubling backwards: each element keeps the smallest key among the ``2^k``
    elements before it (a chain's first element, keyed below every index, stops the
    walk) and how many steps back it lies. Once a round lowers no key, every element
    holds its walk's start and its rank in the walk.
    """
    n = len(succ)
    linked = np.flatnonzero(succ >= 0)
    has_pred = np.zeros(n, dtype=bool)
    has_pred[succ[linked]] = True
    back = np.arange(n)
    back[succ[linked]] = linked
    low = np.arange(n) - np.where(has_pred, 0, n)
    steps = np.zeros(n, dtype=np.int64)
    span = 1
    while True:
        earlier = low[back]
        lower = earlier < low
        if not lower.any():
            break
        steps = np.where(lower, steps[back] + span, steps)
        low = np.minimum(low, earlier)
        back = back[back]
        span *= 2
    order = np.argsort((low + n) * n + steps)
    low = low[order]
    return order, np.flatnonzero(np.r_[True, low[1:] != low[:-1]])


def _mates(nodes: np.ndarray, successor: np.ndarray) -> np.ndarray:
    """Mate of each half-end: a segment's end and the start of its known ``successor``,
    the other half-ends by :func:`_pair_equal` (none of them shares a node with those)."""
    mate = np.full(len(nodes), -1)
    known = np.flatnonzero(successor >= 0)
    mate[2 * known + 1] = 2 * successor[known]
    mate[2 * successor[known]] = 2 * known + 1
    rest = np.flatnonzero(mate < 0)
    if len(rest):
        partner = _pair_equal(nodes[rest], rest % 2)
        paired = partner >= 0
        mate[rest[paired]] = rest[partner[paired]]
    return mate


def _pair_equal(nodes: np.ndarray, is_end: np.ndarray) -> np.ndarray:
    """Mate of each half-end (by position in ``nodes``): another one with the same node id, or -1.

    ``is_end`` (0 or 1 each) tells segment ends from starts. At each node the
    starts are paired with the ends first (both in order of index), so that a walk
    keeps following the segments' directions at non-manifold edges; starts or ends
    left over are paired among themselves in order of index, an odd one out stays
    unpaired.
    """
    n = len(nodes)
    position = np.arange(n)
    order = _stable_order(nodes * 2 + is_end)
    sorted_nodes = nodes[order]
    run_start = np.r_[True, sorted_nodes[1:] != sorted_nodes[:-1]]
    first = np.maximum.accumulate(np.where(run_start, position, 0))
    rank = position - first
    run = np.cumsum(run_start) - 1
    starts = np.bincount(run, weights=1 - is_end[order]).astype(np.int64)[run]
    ends = np.bincount(run)[run] - starts
    mixed = np.minimum(starts, ends)
    start_side = rank < starts
    within = np.where(start_side, rank, rank - starts)
    partner = np.where(start_side, starts + rank, rank - starts)
    left = within - mixed
    left_count = np.where(start_side, starts, ends) - mixed
    left_partner = rank + np.where(left % 2 == 0, 1, -1)
    partner = np.where(within < mixed, partner, np.where((left ^ 1) < left_count, left_partner, -1))
    paired = partner >= 0
    mate = np.full(n, -1)
    mate[order[paired]] = order[first[paired] + partner[paired]]
    return mate


def _pair_open_ends(mate: np.ndarray, xy: np.ndarray, plane: np.ndarray, tolerance: float) -> None:
    """Mate (in place) open half-ends of the same plane that are each other's nearest within ``tolerance``."""
    open_ends = np.flatnonzero(mate < 0)
    if len(open_ends) < 2 or tolerance <= 0:
        return
    from scipy.spatial import cKDTree

    pts = xy[open_ends]
    span = np.ptp(pts, axis=0).max() + 4 * tolerance + 1.0
    keyed = np.column_stack([pts, plane[open_ends] * span])
    dist, idx = cKDTree(keyed).query(keyed, k=min(3, len(open_ends)), distance_upper_bound=tolerance)
    own = np.arange(len(open_ends))[:, None]
    candidate = np.where((idx != own) & np.isfinite(dist), idx, len(open_ends))
    nearest = np.take_along_axis(candidate, np.argmin(candidate == len(open_ends), axis=1)[:, None], axis=1)[:, 0]
    found = nearest < len(open_ends)
    mutual = np.zeros(len(open_ends), dtype=bool)
    mutual[found] = nearest[nearest[found]] == own[found, 0]
    mate[open_ends[mutual]] = open_ends[nearest[mutual]]


def _assemble(rings, ring_plane: np.ndarray, ring_direction: np.ndarray, n_planes: int) -> np.ndarray:
    """Nonzero-winding regions of each plane's rings: an object array of MultiPolygons.

    A ring counts +1 around the points it encloses when its mesh direction is
    counter-clockwise, -1 when clockwise; a point is solid where the sum is not zero.
    An untrusted ring (direction 0) falls back to even-odd: it toggles between solid
    and empty. Planes whose rings never touch are filled from the nesting tree of the
    rings; planes with touching or crossing rings (overlapping shells) from the faces of
    their noded rings (:func:`_fill_crossing`).

    A plane whose rings together form a simple line (each ring simple, no two touching)
    is filled from the nesting tree and is valid by construction; only the other planes
    are searched for touching pairs and have their result validated.
    """
    ring_index, coords, ring_size = rings
    out = np.full(n_planes, _EMPTY, dtype=object)
    usable = ring_size >= 3
    if not usable.any():
        return out
    keep_point = usable[ring_index]
    new_index = np.cumsum(usable) - 1
    ring_index = new_index[ring_index[keep_point]]
    coords = coords[keep_point]
    ring_plane, ring_direction = ring_plane[usable], ring_direction[usable]
    polygons = shapely.polygons(shapely.linearrings(coords, indices=ring_index))
    solid = np.abs(shapely.area(polygons)) > _MIN_LOOP_AREA
    polygons, ring_plane, ring_direction = polygons[solid], ring_plane[solid], ring_direction[solid]
    if len(polygons) == 0:
        return out
    exteriors = shapely.get_exterior_ring(polygons)
    winding = np.where(shapely.is_ccw(exteriors), ring_direction, -ring_direction)
    planes, local_plane = np.unique(ring_plane, return_inverse=True)
    suspect = planes[~shapely.is_simple(shapely.multilinestrings(exteriors, indices=local_plane))]
    shifted, offsets = _side_by_side(polygons, ring_plane)
    crossing = np.zeros(n_planes, dtype=bool)
    if len(suspect):
        ids = np.flatnonzero(np.isin(ring_plane, suspect))
        crossing = _planes_with_touching_rings(shifted[ids], ring_plane[ids], n_planes)
    nested = ~crossing[ring_plane]
    if nested.any():
        ids = np.flatnonzero(nested)
        _fill_nested(out, polygons[ids], shifted[ids], offsets[ids], ring_plane[ids], winding[ids])
    for plane in np.flatnonzero(crossing):
        ids = np.flatnonzero(ring_plane == plane)
        out[plane] = _fill_crossing(exteriors[ids], polygons[ids], winding[ids])
    for i in suspect[~shapely.is_valid(out[suspect])]:
        out[i] = _polygonal(shapely.make_valid(out[i], method="structure", keep_collapsed=False))
    return shapely.orient_polygons(out)


def _side_by_side(polygons: np.ndarray, plane: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Polygons moved along x by their plane times a width, so planes never overlap; and the (N, 2) offsets."""
    offsets = np.zeros((len(plane), 2))
    if not plane.any():
        return polygons, offsets
    bounds = shapely.total_bounds(polygons)
    offsets[:, 0] = plane * ((bounds[2] - bounds[0]) * 2 + 1.0)
    per_coordinate = np.repeat(offsets, shapely.get_num_coordinates(polygons), axis=0)
    return shapely.transform(polygons, lambda xy: xy + per_coordinate), offsets


def _planes_with_touching_rings(shifted: np.ndarray, plane: np.ndarray, n_planes: int) -> np.ndarray:
    """(n_planes,) bool: the plane holds two rings that touch or cross (``shifted`` from :func:`_side_by_side`)."""
    boundaries = shapely.get_exterior_ring(shifted)
    first, second = shapely.STRtree(boundaries).query(boundaries, predicate="intersects")
    touching = np.zeros(n_planes, dtype=bool)
    touching[plane[first[first != second]]] = True
    return touching


def _fill_nested(out, polygons, shifted, offsets, plane, winding) -> None:
    """Fill ``out`` with the regions of planes whose rings are disjoint (so properly nested).

    Walking the nesting tree from the outside in, the winding number just outside a
    ring is the one just inside its parent. A ring bounds the region where exactly one
    side of it is solid: an outer ring when its inside is solid, else a hole of the
    nearest enclosing outer ring.
    """
    parent, depth = _nesting(polygons, shifted, offsets)
    n = len(polygons)
    w_out = np.zeros(n, dtype=np.int64)
    w_in = np.zeros(n, dtype=np.int64)
    outer = np.zeros(n, dtype=bool)
    owner = np.full(n, -1)
    for level in np.unique(depth):
        ids = np.flatnonzero(depth == level)
        up = parent[ids]
        has_parent = up >= 0
        w_out[ids] = np.where(has_parent, w_in[up], 0)
        toggle = np.where(w_out[ids] == 0, 1, -w_out[ids])
        w_in[ids] = w_out[ids] + np.where(winding[ids] != 0, winding[ids], toggle)
        outer[ids] = (w_in[ids] != 0) & (w_out[ids] == 0)
        owner[ids] = np.where(has_parent, np.where(outer[up], up, owner[up]), -1)
    hole = (w_in == 0) & (w_out != 0)
    kept = np.flatnonzero(outer | hole)
    if len(kept) == 0:
        return
    is_hole = hole[kept]
    group = np.where(is_hole, owner[kept], kept)
    order = np.lexsort((is_hole, group, plane[kept]))
    kept, group = kept[order], group[order]
    new_group = np.r_[True, group[1:] != group[:-1]]
    group_index = np.cumsum(new_group) - 1
    regions = shapely.polygons(shapely.get_exterior_ring(polygons[kept]), indices=group_index)
    region_plane = plane[kept][new_group]
    planes = np.unique(region_plane)
    out[planes] = shapely.multipolygons(regions, indices=np.searchsorted(planes, region_plane))


def _nesting(polygons: np.ndarray, shifted: np.ndarray, offsets: np.ndarray):
    """Innermost enclosing ring (or -1) and enclosure depth of each ring, within its plane.

    ``shifted`` and ``offsets`` come from :func:`_side_by_side`, so one spatial index
    serves all planes; a ring is inside another when its first vertex lies in the
    other's interior.
    """
    first = shapely.get_point(shapely.get_exterior_ring(polygons), 0)
    probe = shapely.points(shapely.get_coordinates(first) + offsets)
    inner, outer = shapely.STRtree(shifted).query(probe, predicate="within")
    depth = np.bincount(inner, minlength=len(polygons))
    parent = np.full(len(polygons), -1)
    order = np.lexsort((depth[outer], inner))
    inner, outer = inner[order], outer[order]
    last = np.r_[inner[1:] != inner[:-1], True][: len(inner)]
    parent[inner[last]] = outer[last]
    return parent, depth


def _fill_crossing(rings: np.ndarray, polygons: np.ndarray, winding: np.ndarray) -> shapely.MultiPolygon:
    """The solid region of one plane whose rings touch or cross.

    The rings are noded and polygonized into faces; a face is solid when the winding
    number of an interior point over the trusted rings is not zero, XOR the point lies
    in an odd number of untrusted rings. Solid faces are merged (they form a coverage).
    """
    faces = shapely.get_parts(shapely.polygonize(shapely.get_parts(shapely.node(shapely.multilinestrings(rings)))))
    if len(faces) == 0:
        return shapely.MultiPolygon()
    probes = shapely.point_on_surface(faces)
    face, ring = shapely.STRtree(polygons).query(probes, predicate="within")
    number = np.bincount(face, weights=winding[ring], minlength=len(faces))
    untrusted = np.bincount(face, weights=winding[ring] == 0, minlength=len(faces))
    solid = (number != 0) ^ (untrusted % 2 == 1)
    return _polygonal(shapely.coverage_union_all(faces[solid]))


def _polygonal(geometry: shapely.Geometry) -> shapely.MultiPolygon:
    """The polygons of a valid geometry (collection), as one valid MultiPolygon."""
    parts = shapely.get_parts(shapely.get_parts(geometry))
    polys = parts[shapely.get_type_id(parts) == shapely.GeometryType.POLYGON]
    result = shapely.multipolygons(polys)
    if not shapely.is_valid(result):
        result = shapely.multipolygons(shapely.get_parts(shapely.union_all(polys)))
    return result


class _TriangleDistance:
    """Exact unsigned distance from points to a triangle soup (mm).

    Bounds: a set of points lying within ``t`` of a plane (unit normal ``n``) and within
    ``R`` of a centre ``c`` is at least ``sqrt(max(0, |h| - t)^2 + max(0, l - R)^2)`` from
    ``p``, with ``h = (p - c).n`` and ``l`` the in-plane distance from ``p`` to ``c``. A
    triangle is such a set with ``t = 0``; so is a *cluster* of 16 triangles consecutive
    in Morton order of their centroids (``t`` = its thickness about its mean plane).

    Search: ``best`` starts at the distance to the nearest vertex. Clusters are grouped
    by ``R`` (factors of 4), each group with a k-d tree of centres searched within
    ``best + R``, widening ``k`` until the bound, not ``k``, limits the search. Clusters
    whose bound beats ``best`` are opened, their triangles bounded the same way, and the
    survivors measured exactly with ``trimesh.triangles.closest_point``.
    """

    _CLUSTER = 16

    def __init__(self, triangles: np.ndarray):
        from scipy.spatial import cKDTree
        from trimesh.triangles import closest_point

        self._closest_point = closest_point
        centroids = triangles.mean(axis=1)
        order = np.argsort(_morton_codes(centroids), kind="stable")
        self._triangles = triangles[order]
        pad = (-len(order)) % self._CLUSTER
        members = np.r_[np.arange(len(order)), np.full(pad, len(order) - 1)].reshape(-1, self._CLUSTER)
        self._members = members
        normal = np.cross(self._triangles[:, 1] - self._triangles[:, 0], self._triangles[:, 2] - self._triangles[:, 0])
        self._tri = _bounding_slabs(self._triangles, normal)
        cluster_vertices = self._triangles[members].reshape(len(members), -1, 3)
        self._cluster = _bounding_slabs(cluster_vertices, normal[members].sum(axis=1))
        size_class = np.floor(np.log2(np.maximum(self._cluster[1], 1e-9)) / 2).astype(int)
        self._groups = []
        for cls in np.unique(size_class):
            ids = np.flatnonzero(size_class == cls)
            self._groups.append((ids, float(self._cluster[1][ids].max()), cKDTree(self._cluster[0][ids])))
        self._vertex_tree = cKDTree(np.unique(triangles.reshape(-1, 3), axis=0))

    def query(self, points: np.ndarray) -> np.ndarray:
        """Distance (mm) from each (N, 3) point to the nearest triangle."""
        best = self._vertex_tree.query(points)[0]
        for ids, radius, tree in self._groups:
            pending = np.arange(len(points))
            done = 0
            k = 8
            while len(pending):
                k_eff = min(k, len(ids))
                bound = best[pending] + radius
                dist, idx = tree.query(points[pending], k=k_eff, distance_upper_bound=float(bound.max()))
                dist = dist.reshape(len(pending), k_eff)[:, done:]
                idx = idx.reshape(len(pending), k_eff)[:, done:]
                within = dist <= bound[:, None]
                rows, cols = np.nonzero(within)
                self._open_clusters(best, pending[rows], ids[idx[rows, cols]], points)
                if k_eff == len(ids):
                    break
                pending = pending[within[:, -1]]
                done = k_eff
                k *= 4
        return best

    def _open_clusters(self, best, point, cluster, points) -> None:
        """Lower ``best[point]`` with the triangles of ``cluster`` that may beat it."""
        close = _lower_bound(points[point], self._cluster, cluster) < best[point]
        point = np.repeat(point[close], self._CLUSTER)
        tri = self._members[cluster[close]].ravel()
        close = _lower_bound(points[point], self._tri, tri) < best[point]
        point, tri = point[close], tri[close]
        nearest = self._closest_point(self._triangles[tri], points[point])
        np.minimum.at(best, point, np.linalg.norm(nearest - points[point], axis=1))


def _bounding_slabs(vertices: np.ndarray, normal: np.ndarray):
    """(centre, radius, unit normal, thickness) of each (K, 3) vertex set (see _TriangleDistance)."""
    centre = vertices.mean(axis=1)
    offset = vertices - centre[:, None, :]
    radius = np.linalg.norm(offset, axis=2).max(axis=1)
    length = np.linalg.norm(normal, axis=1, keepdims=True)
    unit = np.divide(normal, length, out=np.zeros_like(normal), where=length > 0)
    thickness = np.abs(np.einsum("ikj,ij->ik", offset, unit)).max(axis=1)
    thickness[length[:, 0] == 0] = np.inf
    return centre, radius, unit, thickness


def _lower_bound(p: np.ndarray, slabs, index: np.ndarray) -> np.ndarray:
    """Lower bound on the distance from points ``p`` to the vertex sets ``index`` of ``slabs``."""
    centre, radius, unit, thickness = (a[index] for a in slabs)
    offset = p - centre
    height = np.einsum("ij,ij->i", offset, unit)
    lateral = np.linalg.norm(offset - height[:, None] * unit, axis=1)
    across = np.maximum(np.abs(height) - thickness, 0.0)
    across = np.where(np.isfinite(thickness), across, 0.0)
    along = np.maximum(lateral - radius, 0.0)
    return np.sqrt(across**2 + along**2)


def _morton_codes(points: np.ndarray) -> np.ndarray:
    """30-bit Morton (Z-order) codes of (N, 3) points quantized to 1024 levels per axis."""
    lo = points.min(axis=0)
    span = np.maximum(points.max(axis=0) - lo, 1e-12)
    q = np.minimum((points - lo) / span * 1024, 1023).astype(np.int64)
    for shift, mask in ((16, 0x030000FF), (8, 0x0300F00F), (4, 0x030C30C3), (2, 0x09249249)):
        q = (q | (q << shift)) & mask
    return q[:, 0] | (q[:, 1] << 1) | (q[:, 2] << 2)


class _RayCrossings:
    """Parity of crossings between triangles and rays cast from points along +axis.

    Triangles are projected on the plane normal to ``axis`` and binned in a uniform
    grid. A point exactly on a projected edge or vertex is decided by simulation of
    simplicity: it is moved by an infinitesimal along a fixed irrational direction, so
    a ray through a shared edge hits exactly one of its two triangles.
    """

    _PERTURBATION = np.array([1.0, 0.6180339887498949])

    def __init__(self, triangles: np.ndarray, axis: int):
        self._axis = axis
        self._uv = [a for a in range(3) if a != axis]
        flat = triangles[:, :, self._uv]
        self._flat = flat
        self._height = triangles[:, :, axis]
        lo = flat.min(axis=1)
        hi = flat.max(axis=1)
        extent = np.maximum(hi - lo, 0).max(axis=1)
        self._origin = lo.min(axis=0)
        span = hi.max(axis=0) - self._origin
        self._cell = max(float(np.median(extent)) * 2, float(span.max()) / 2048, 1e-9)
        self._shape = np.floor(span / self._cell).astype(np.int64) + 1
        i0 = np.floor((lo - self._origin) / self._cell).astype(np.int64)
        i1 = np.floor((hi - self._origin) / self._cell).astype(np.int64)
        nu = i1[:, 0] - i0[:, 0] + 1
        nv = i1[:, 1] - i0[:, 1] + 1
        counts = nu * nv
        tri = np.repeat(np.arange(len(triangles)), counts)
        local = _ranks_within_runs(counts)
        cu = i0[tri, 0] + local % nu[tri]
        cv = i0[tri, 1] + local // nu[tri]
        cell = cu * self._shape[1] + cv
        order = np.argsort(cell, kind="stable")
        self._cell_triangles = tri[order]
        self._cell_start = np.searchsorted(cell[order], np.arange(self._shape.prod() + 1))

    def odd_crossings(self, points: np.ndarray) -> np.ndarray:
        """True where the ray from each (N, 3) point crosses the surface an odd number of times."""
        q = points[:, self._uv]
        cell_uv = np.floor((q - self._origin) / self._cell).astype(np.int64)
        in_grid = ((cell_uv >= 0) & (cell_uv < self._shape)).all(axis=1)
        cell = np.where(in_grid, cell_uv[:, 0] * self._shape[1] + cell_uv[:, 1], 0)
        start = self._cell_start[cell]
        counts = np.where(in_grid, self._cell_start[cell + 1] - start, 0)
        point = np.repeat(np.arange(len(points)), counts)
        tri = self._cell_triangles[np.repeat(start, counts) + _ranks_within_runs(counts)]
        corners = self._flat[tri]
        qp = q[point]
        nxt = np.roll(corners, -1, axis=1)
        edge = nxt - corners
        rel = qp[:, None, :] - corners
        w = edge[..., 0] * rel[..., 1] - edge[..., 1] * rel[..., 0]
        tie = edge[..., 0] * self._PERTURBATION[1] - edge[..., 1] * self._PERTURBATION[0]
        side = np.where(w == 0, tie, w)
        hit = (side > 0).all(axis=1) | (side < 0).all(axis=1)
        # w[:, j] belongs to edge j -> j+1, i.e. it is the barycentric weight of corner j+2
        weights = np.roll(w[hit], -1, axis=1)
        height = (weights * self._height[tri[hit]]).sum(axis=1) / weights.sum(axis=1)
        above = height > points[point[hit], self._axis]
        return np.bincount(point[hit][above], minlength=len(points)) % 2 == 1
