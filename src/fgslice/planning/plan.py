"""The ordered plan of a print, before any G-code is written.

A :class:`LayerPlan` is a sequence of steps: :class:`SetState` (switch the process state
to a palette color) and :class:`~fgslice.toolpaths.paths.Path` (travel to its start, then
extrude along it). The writer turns steps into G-code in order; travel moves between
paths are implied. ``Path.color`` is the color the design asks for there; the state the
printer is commanded is the latest :class:`SetState` before the path — the two differ
only where look-ahead issues a change early.

Plans cross process boundaries (per-layer workers): a plan pickles its paths as a few
flat arrays (all points in one ``(N, 2)`` array, one row of attributes per path, each
path's length computed by the sender) rather than one array per path. The receiver keeps
them as :class:`PackedSteps` columns: stages that understand columns (purge towers, the
G-code writer) work on them without making a :class:`Path` per step; the first access to
``steps`` or ``prepared`` of such a plan builds the paths (as views of the one points
array) and drops the columns.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from operator import attrgetter
from typing import Any, Union

import numpy as np

from fgslice.toolpaths.paths import Path, Role


@dataclass(frozen=True)
class SetState:
    """Command the process state of palette color ``color`` (0-based index)."""

    color: int


Step = Union[SetState, Path]

ROLES = tuple(Role)
ROLE_CODE = {role: k for k, role in enumerate(ROLES)}
_ROLE_CODE_BY_ID = {id(role): k for role, k in ROLE_CODE.items()}  # hashing an Enum member runs Python code

#: :attr:`PackedSteps.kind` of a step: a path of the columns, a SetState, an extra path.
PACKED, STATE, EXTRA = 0, 1, 2


def polyline_lengths(arrays: Sequence[np.ndarray], closed: np.ndarray) -> np.ndarray:
    """Length (mm) of each ``(N_i, 2)`` polyline of ``arrays`` (N_i >= 1), with the
    segment from its last point back to its first where ``closed`` is True."""
    sizes = np.fromiter(map(len, arrays), dtype=np.int64, count=len(arrays))
    return _packed_lengths(np.concatenate(arrays), sizes, closed)


def _packed_lengths(points: np.ndarray, sizes: np.ndarray, closed: np.ndarray) -> np.ndarray:
    """:func:`polyline_lengths` of polylines stored one after another in ``points``."""
    first = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    last = first + sizes - 1
    seg = np.hypot(*np.diff(points, axis=0, append=points[-1:]).T)
    seg[last] = 0.0
    closing = np.where(closed, np.hypot(*(points[first] - points[last]).T), 0.0)
    return np.add.reduceat(seg, first) + closing


@dataclass
class Prepared:
    """Per-path data computed where a plan was made, for a consumer further down (the
    G-code writer's formatted moves, :class:`fgslice.machine.gcode.PathBodies`).

    Attributes:
        rows: row of ``data`` for each path it covers, looked up by path identity; paths
            added or replaced later (purges, look-ahead splits) have no row.
        data: the consumer's per-row data.
    """

    rows: dict[Path, int]
    data: Any


@dataclass
class PackedSteps:
    """A layer's steps as columns (see the module notes). Units mm.

    Attributes:
        kind: ``(S,)`` int8 per step: :data:`PACKED` (path ``ref`` of the columns),
            :data:`STATE` (a SetState of color ``ref``), :data:`EXTRA` (``extras[ref]``).
        ref: ``(S,)`` int32, see ``kind``.
        points: ``(P, 2)`` the column paths' points, one path after another.
        offsets: ``(n + 1,)`` where each column path's points start in ``points``.
        roles: ``(n,)`` int8 index into :data:`ROLES`.
        colors, groups: ``(n,)`` int32.
        widths, heights, lengths: ``(n,)`` float64 (``lengths`` with the closing segment).
        closed: ``(n,)`` bool.
        rows: ``(n,)`` row of ``data`` of each column path, -1 for none.
        data: the :class:`Prepared` data the rows index (None if none).
        extras: paths added after packing (purges, tower bases).
    """

    kind: np.ndarray
    ref: np.ndarray
    points: np.ndarray
    offsets: np.ndarray
    roles: np.ndarray
    colors: np.ndarray
    widths: np.ndarray
    heights: np.ndarray
    closed: np.ndarray
    groups: np.ndarray
    lengths: np.ndarray
    rows: np.ndarray
    data: Any = None
    extras: list[Path] = field(default_factory=list)

    def with_steps(self, kind: np.ndarray, ref: np.ndarray, extras: list[Path]) -> "PackedSteps":
        """The same columns in another step sequence."""
        return PackedSteps(kind, ref, self.points, self.offsets, self.roles, self.colors, self.widths,
                           self.heights, self.closed, self.groups, self.lengths, self.rows, self.data, extras)

    def build(self) -> tuple[list[Step], Prepared | None]:
        """The steps as :class:`SetState` and :class:`Path` objects (points are views of
        ``points``) and the :class:`Prepared` rows keyed by those paths."""
        paths: list[Path] = []
        cuts = self.offsets.tolist()
        new = object.__new__
        points = self.points
        for a, b, role, color, width, h, shut, group in zip(
            cuts[:-1], cuts[1:], self.roles.tolist(), self.colors.tolist(), self.widths.tolist(),
            self.heights.tolist(), self.closed.tolist(), self.groups.tolist(),
        ):
            path = new(Path)
            path.__dict__.update(points=points[a:b], role=ROLES[role], color=color, width=width, height=h,
                                 closed=shut, group=group)
            paths.append(path)
        extras = self.extras
        steps = [paths[r] if k == PACKED else SetState(r) if k == STATE else extras[r]
                 for k, r in zip(self.kind.tolist(), self.ref.tolist())]
        prepared = None
        if self.data is not None:
            prepared = Prepared({p: r for p, r in zip(paths, self.rows.tolist()) if r >= 0}, self.data)
        return steps, prepared


@dataclass
class LayerPlan:
    """The ordered steps of one layer.

    Attributes:
        index: 0-based layer number.
        z: nozzle height (top of the layer) above the bed, mm.
        height: layer thickness, mm.
        steps: ordered :class:`SetState` and :class:`Path` steps.
        prepared: optional per-path data for a later stage (:class:`Prepared`).
        packed: the steps as columns while no one has asked for ``steps``
            (:meth:`from_packed`); None once they are built or for a plan built from steps.
    """

    index: int
    z: float
    height: float
    steps: list[Step] = field(default_factory=list)
    prepared: Prepared | None = None
    packed: PackedSteps | None = field(default=None, repr=False, compare=False)

    @classmethod
    def from_packed(cls, index: int, z: float, height: float, packed: PackedSteps) -> "LayerPlan":
        """A plan held as columns; ``steps`` and ``prepared`` are built on first access."""
        plan = object.__new__(cls)
        plan.__dict__.update(index=index, z=z, height=height, packed=packed)
        return plan

    def __getattr__(self, name: str) -> Any:
        """Build ``steps`` and ``prepared`` of a packed plan when first asked for."""
        packed = self.__dict__.get("packed")
        if name not in ("steps", "prepared") or packed is None:
            raise AttributeError(name)
        self.steps, self.prepared = packed.build()
        self.packed = None
        return self.__dict__[name]

    def pack(self) -> PackedSteps | None:
        """Hold the steps as columns from now on, as a plan received from a worker does
        (``steps`` and ``prepared`` are dropped and rebuilt on access); returns the columns,
        or None (plan unchanged) when a step is neither a :class:`Path` nor a :class:`SetState`."""
        if self.packed is not None:
            return self.packed
        if not {s.__class__ for s in self.steps} <= {Path, SetState}:
            return None
        self.packed = pack_steps(self.steps, self.prepared)
        del self.steps, self.prepared
        return self.packed

    @property
    def paths(self) -> list[Path]:
        """The extrusion paths of this layer, in printing order."""
        return [s for s in self.steps if isinstance(s, Path)]

    def __reduce__(self):
        """Pickle the paths as flat arrays (see the module notes)."""
        if self.packed is not None:
            return (_unpack, (self.index, self.z, self.height, self.packed))
        steps = self.steps
        if not {s.__class__ for s in steps} <= {Path, SetState}:
            return (LayerPlan, (self.index, self.z, self.height, steps, self.prepared))
        return (_unpack, (self.index, self.z, self.height, pack_steps(steps, self.prepared)))


def role_codes(roles) -> np.ndarray:
    """``(n,)`` int8 :attr:`PackedSteps.roles` codes of an iterable of :class:`Role` members."""
    roles = list(roles)
    return np.fromiter(map(_ROLE_CODE_BY_ID.__getitem__, map(id, roles)), dtype=np.int8, count=len(roles))


def pack_arrays(kind: np.ndarray, ref: np.ndarray, points: np.ndarray, sizes: np.ndarray, roles: np.ndarray,
                colors, widths, heights, closed, groups) -> PackedSteps:
    """:class:`PackedSteps` (no prepared data) from per-step ``kind``/``ref`` and per-path
    columns: ``points`` ``(P, 2)`` mm, one path after another, ``sizes`` points per path,
    ``roles`` codes (:func:`role_codes`); each path's length is computed here."""
    n = len(sizes)
    closed = np.asarray(closed, dtype=bool)
    return PackedSteps(
        np.asarray(kind, dtype=np.int8),
        np.asarray(ref, dtype=np.int32),
        points,
        np.concatenate([[0], np.cumsum(sizes)]).astype(np.int32),
        np.asarray(roles, dtype=np.int8),
        np.asarray(colors, dtype=np.int32),
        np.asarray(widths, dtype=np.float64),
        np.asarray(heights, dtype=np.float64),
        closed,
        np.asarray(groups, dtype=np.int32),
        _packed_lengths(points, sizes, closed) if n else np.zeros(0),
        np.full(n, -1, dtype=np.int32),
    )


def pack_steps(steps: list[Step], prepared: Prepared | None) -> PackedSteps:
    """The columns of ``steps`` (SetState and Path only), path lengths computed here."""
    is_path = np.fromiter((s.__class__ is Path for s in steps), dtype=bool, count=len(steps))
    paths = [s for s in steps if s.__class__ is Path]
    n = len(paths)
    kind = np.where(is_path, PACKED, STATE)
    ref = np.zeros(len(steps), dtype=np.int32)
    ref[is_path] = np.arange(n)
    ref[~is_path] = [s.color for s in steps if s.__class__ is SetState]
    if paths:
        points, roles, colors, widths, heights, closed, groups = zip(
            *map(attrgetter("points", "role", "color", "width", "height", "closed", "group"), paths)
        )
        sizes = np.fromiter(map(len, points), dtype=np.int64, count=n)
        packed = pack_arrays(kind, ref, np.concatenate(points).astype(np.float64, copy=False), sizes,
                             role_codes(roles), colors, widths, heights, closed, groups)
    else:
        packed = pack_arrays(kind, ref, np.zeros((0, 2)), np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int8),
                             (), (), (), (), ())
    if prepared is not None:
        get = prepared.rows.get
        packed.rows = np.array([get(p, -1) for p in paths], dtype=np.int32)
        packed.data = prepared.data
    return packed


def _unpack(index: int, z: float, height: float, packed: PackedSteps) -> LayerPlan:
    """The plan :meth:`LayerPlan.__reduce__` packed, kept as columns."""
    return LayerPlan.from_packed(index, z, height, packed)
