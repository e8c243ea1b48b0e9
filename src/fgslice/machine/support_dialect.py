"""A dialect that also writes the support's own state (:mod:`fgslice.toolpaths.support_state`).

:class:`SupportStateDialect` wraps the slice's dialect: palette colors are written by it,
the support's color (outside the palette) as ``;STATE:<color> support ...`` and

* a support tool: ``T<tool>``; the tool is heated with the others after the start G-code
  (``M104 T<tool> S<support_temperature>`` first, ``M109 T<tool> ...`` last), so that
  ``verify`` sees it hot before it extrudes;
* a support mix: the wrapped mixing dialect's command for that mix (``M165 A.. B..``,
  ``M163``/``M164``, Klipper's extruder steppers).
"""

from __future__ import annotations

import numpy as np

from fgslice.machine.dialects import Dialect, make_dialect
from fgslice.toolpaths.support_state import SupportState


class _MixPalette:
    """A palette of one color, the support mix (what a mixing dialect needs to write it)."""

    def __init__(self, fractions: np.ndarray) -> None:
        self.size, self.n_materials = 1, len(fractions)
        self.centers = np.asarray(fractions, dtype=float).reshape(1, -1)

    def label(self, color: int) -> str:
        return "support"


class SupportStateDialect(Dialect):
    """``inner`` for the palette's colors, and the support's own state."""

    def __init__(self, inner: Dialect, state: SupportState) -> None:
        self.inner, self.state = inner, state
        self.name = inner.name
        self.change_time_s = inner.change_time_s
        self.moves_head = inner.moves_head
        self._mix = (make_dialect(inner.settings, _MixPalette(state.fractions)) if state.fractions is not None
                     else None)
        super().__init__(inner.settings, inner.palette)

    def _own(self, color: int | None) -> bool:
        return color is not None and int(color) == self.state.color

    def _commands(self, color: int) -> list[str]:
        if self._own(color):
            return [f"T{self.state.tool}"] if self.state.tool is not None else self._mix._commands(0)
        return self.inner._commands(color)

    def _color(self, color: int) -> int:
        return int(color) if self._own(color) else self.inner._color(color)

    def state_commands(self, color: int) -> list[str]:
        if self._own(color):
            return [f";STATE:{self.state.color} {self.state.label}", *self._commands(color)]
        return self.inner.state_commands(color)

    def change_commands(self, previous: int | None, color: int) -> list[str]:
        if self._own(color):
            return self.state_commands(color)
        return self.inner.change_commands(None if self._own(previous) else previous, color)

    def change_time(self, previous: int | None, color: int) -> float:
        if self._own(color) or self._own(previous):
            return self.change_time_s
        return self.inner.change_time(previous, color)

    def start_commands(self) -> list[str]:
        """The wrapped dialect's, with the support tool heated first and waited for last."""
        lines = self.inner.start_commands()
        if self.state.tool is None:
            return lines
        t = f"{self.state.temperature:g}"
        return [f"M104 T{self.state.tool} S{t}", *lines, f"M109 T{self.state.tool} S{t}"]

    def extra_colors(self) -> dict[int, str]:
        return {self.state.color: self.state.label}


def with_support_state(dialect: Dialect, state: SupportState) -> Dialect:
    """``dialect``, wrapped when support has a state of its own."""
    return SupportStateDialect(dialect, state) if state.own else dialect
