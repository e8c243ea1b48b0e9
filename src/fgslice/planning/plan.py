"""The ordered plan of a print, before any G-code is written.

A :class:`LayerPlan` is a sequence of steps: :class:`SetState` (switch the process state
to a palette color) and :class:`~fgslice.toolpaths.paths.Path` (travel to its start, then
extrude along it). The writer turns steps into G-code in order; travel moves between
paths are implied. ``Path.color`` is the color the design asks for there; the state the
printer is commanded is the latest :class:`SetState` before the path — the two differ
only where look-ahead issues a change early.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Union

from fgslice.toolpaths.paths import Path


@dataclass(frozen=True)
class SetState:
    """Command the process state of palette color ``color`` (0-based index)."""

    color: int


Step = Union[SetState, Path]


@dataclass
class LayerPlan:
    """The ordered steps of one layer.

    Attributes:
        index: 0-based layer number.
        z: nozzle height (top of the layer) above the bed, mm.
        height: layer thickness, mm.
        steps: ordered :class:`SetState` and :class:`Path` steps.
    """

    index: int
    z: float
    height: float
    steps: list[Step] = field(default_factory=list)

    @property
    def paths(self) -> list[Path]:
        """The extrusion paths of this layer, in printing order."""
        return [s for s in self.steps if isinstance(s, Path)]
