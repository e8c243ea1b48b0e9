"""The ordered plan of a print, before any G-code is written.

A :class:`LayerPlan` is a sequence of steps: :class:`SetState` (switch the process state
to a palette color) and :class:`~fgslice.toolpaths.paths.Path` (travel to its start, then
extrude along it). The writer turns steps into G-code in order; travel moves between
paths are implied. ``Path.color`` is the color the design asks for there; the state the
printer is commanded is the latest :class:`SetState` before the path — the two differ
only where look-ahead issues a change early.

Plans cross process boundaries (per-layer workers): a plan pickles its paths as a few
flat arrays (all points in one ``(N, 2)`` array, one row of attributes per path) rather
than one array per path, and unpickles them as views of that array, so sending a layer
of thousands of paths costs a handful of buffers.
"""

from __future__ import annotations

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

_ROLES = tuple(Role)
_ROLE_CODE = {role: k for k, role in enumerate(_ROLES)}


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
class LayerPlan:
    """The ordered steps of one layer.

    Attributes:
        index: 0-based layer number.
        z: nozzle height (top of the layer) above the bed, mm.
        height: layer thickness, mm.
        steps: ordered :class:`SetState` and :class:`Path` steps.
        prepared: optional per-path data for a later stage (:class:`Prepared`).
    """

    index: int
    z: float
    height: float
    steps: list[Step] = field(default_factory=list)
    prepared: Prepared | None = None

    @property
    def paths(self) -> list[Path]:
        """The extrusion paths of this layer, in printing order."""
        return [s for s in self.steps if isinstance(s, Path)]

    def __reduce__(self):
        """Pickle the paths as flat arrays (see the module notes)."""
        steps = self.steps
        kinds = {s.__class__ for s in steps}
        if not kinds <= {Path, SetState}:
            return (LayerPlan, (self.index, self.z, self.height, steps, self.prepared))
        is_path = np.fromiter((s.__class__ is Path for s in steps), dtype=bool, count=len(steps))
        paths = [s for s in steps if s.__class__ is Path]
        states = np.array([s.color for s in steps if s.__class__ is SetState], dtype=np.int64)
        columns = None
        if paths:
            points, roles, colors, widths, heights, closed, groups = zip(
                *map(attrgetter("points", "role", "color", "width", "height", "closed", "group"), paths)
            )
            columns = (
                np.concatenate(points).astype(np.float64, copy=False),
                np.fromiter(map(len, points), dtype=np.int64, count=len(paths)),
                np.fromiter(map(_ROLE_CODE.__getitem__, roles), dtype=np.int8, count=len(paths)),
                np.array(colors, dtype=np.int64),
                np.array(widths, dtype=np.float64),
                np.array(heights, dtype=np.float64),
                np.array(closed, dtype=bool),
                np.array(groups, dtype=np.int64),
            )
        prepared = None
        if self.prepared is not None:
            get = self.prepared.rows.get
            prepared = (np.array([get(p, -1) for p in paths], dtype=np.int64), self.prepared.data)
        return (_unpack, (self.index, self.z, self.height, is_path, states, columns, prepared))


def _unpack(index, z, height, is_path, states, columns, prepared) -> LayerPlan:
    """The plan :meth:`LayerPlan.__reduce__` packed: paths rebuilt as views of one array."""
    paths: list[Path] = []
    if columns is not None:
        points, sizes, roles, colors, widths, heights, closed, groups = columns
        cuts = np.cumsum(sizes).tolist()
        new = object.__new__
        for a, b, role, color, width, h, shut, group in zip(
            [0, *cuts[:-1]], cuts, roles.tolist(), colors.tolist(), widths.tolist(), heights.tolist(),
            closed.tolist(), groups.tolist(),
        ):
            path = new(Path)
            path.__dict__.update(points=points[a:b], role=_ROLES[role], color=color, width=width, height=h,
                                 closed=shut, group=group)
            paths.append(path)
    path_iter, state_iter = iter(paths), iter(states.tolist())
    steps = [next(path_iter) if kind else SetState(next(state_iter)) for kind in is_path.tolist()]
    plan = LayerPlan(index, z, height, steps)
    if prepared is not None:
        rows, data = prepared
        plan.prepared = Prepared({p: r for p, r in zip(paths, rows.tolist()) if r >= 0}, data)
    return plan
