"""Process attributes of a G-code file's extrusion moves, as commanded, for previews.

Per move (the reader's :class:`~fgslice.machine.gcode_reader.GcodeProgram`):

* ``fan``: the last ``M106 S`` before it / 2.55, percent (0 before any);
* ``flow``: its extrusion over the nominal one of its bead, times its ``M221`` flow,
  percent: ``E * filament_area / (L * A(width, layer_height)) * M221``, from the
  header's ``filament_diameter``, ``layer_height`` and ``bead_width`` (for moves without
  ``;WIDTH:``);
* ``speed``: its feed rate over its feature's speed (``;TYPE:`` external perimeter
  ``outer_wall_speed``, internal infill ``infill_speed``, others ``print_speed``, layer
  0 ``first_layer_speed``), percent;
* ``temperature``: the nozzle target of its state, degrees C (NaN where none is known);
* ``infill_density``: the design's field at the move's midpoint (needs the design),
  percent; NaN where no attribute covers it.

Moves that do not extrude get NaN.
"""

from __future__ import annotations

import numpy as np

from fgslice.design.attributes import UNITS
from fgslice.errors import GcodeError
from fgslice.preview.colors import Printout
from fgslice.toolpaths.paths import bead_area

NAMES = tuple(UNITS)
"""The attributes a preview can color by (also ``flow_rate``, read as ``flow``)."""


def _setting(printout: Printout, key: str) -> float:
    value = printout.info.settings.get(key)
    try:
        return float(value)
    except (TypeError, ValueError):
        raise GcodeError(f"the G-code's header has no '; {key} = ...' setting to compute the commanded values from",
                         file=printout.name, hint="preview a file written by fgslice") from None


def move_values(printout: Printout, name: str, design=None, placement=None) -> np.ndarray:
    """``(M,)`` attribute ``name`` of each move of ``printout`` (see the module notes)."""
    from fgslice.design.attributes import canonical_name

    name = canonical_name(name)
    program = printout.program
    printing = (program.e > 0) & (program.length > 0)
    out = np.full(len(program.e), np.nan)
    if name == "fan":
        out[printing] = program.fan_of_moves()[printing]
    elif name == "flow":
        diameter, height = _setting(printout, "filament_diameter"), _setting(printout, "layer_height")
        width = np.where(np.isfinite(program.width), program.width, _setting(printout, "bead_width"))
        nominal = program.length * bead_area(width, height) / (np.pi * diameter**2 / 4)
        out[printing] = (program.e / np.where(printing, nominal, 1.0) * program.flow_of_moves())[printing]
    elif name == "speed":
        roles = np.array(program.roles + [""])[program.role]
        feature = np.where(roles == "External perimeter", _setting(printout, "outer_wall_speed"),
                           np.where(roles == "Internal infill", _setting(printout, "infill_speed"),
                                    _setting(printout, "print_speed")))
        feature = np.where(program.layer == 0, _setting(printout, "first_layer_speed"), feature)
        out[printing] = (program.feed / 60.0 / feature * 100.0)[printing]
    elif name == "temperature":
        targets = np.array([np.nan if s.temperature is None else s.temperature for s in program.states])
        out[printing] = targets[program.state][printing] if len(targets) else np.nan
    else:
        from fgslice.design.attributes import attribute_fields

        fields = attribute_fields(design) if design is not None else None
        if fields is None or name not in fields.names:
            raise GcodeError(f"'{name}' is not written per move: it is read from the design's attribute",
                             hint=f"pass the design (with an attribute(\"{name}\", ...) node) with --design")
        mid = (program.start[printing] + program.end[printing]) / 2
        x, y, z = placement.to_design(mid[:, 0], mid[:, 1], mid[:, 2] - _layer_heights(printout)[program.layer[printing]] / 2)
        out[printing] = fields.values(name, x, y, z)
    return out


def _layer_heights(printout: Printout) -> np.ndarray:
    """Each layer's thickness (mm): the difference of the layers' tops (the first from 0)."""
    tops = np.asarray(printout.program.layer_z, dtype=float)
    return np.diff(tops, prepend=0.0) if len(tops) else np.zeros(1)


def value_range(values: np.ndarray) -> tuple[float, float]:
    """Colormap limits of ``values``: their finite range (widened when flat)."""
    finite = values[np.isfinite(values)]
    if not len(finite):
        return 0.0, 1.0
    lo, hi = float(finite.min()), float(finite.max())
    return (lo, hi) if hi > lo else (lo - 0.5, hi + 0.5)
