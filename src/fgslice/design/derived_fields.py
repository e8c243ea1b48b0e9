"""Fields computed from other fields point by point (OpenVCAD 3's attribute arithmetic,
``map_range``, ``clamp``, vector magnitudes, ``DerivedFloatAttribute``).

A *field* here is what an attribute node takes (:class:`fgslice.design.nodes.Field`
sources): a float (a constant), an expression string of ``x, y, z, d`` (and the other
coordinates of docs/expressions.md), or a callable ``f(x, y, z, d=None)`` on numpy
arrays. :class:`DerivedField` is such a callable: it evaluates its input fields at the
points and combines them with a function of arrays. ``d`` is the signed distance of the
node the field is attached to (mm); an input that needs it sees NaN when it is not given.
Values are float64; NaN means undefined and propagates.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence

import numpy as np

from fgslice.design.expressions import Expression, compile_expression
from fgslice.errors import DesignError

FieldSource = float | str | Callable
"""A constant, an expression string, or a callable ``f(x, y, z, d=None)``."""

SLOTS = ("x", "y", "z", "d")
"""The expression language's variables that carry named inputs (at most four inputs)."""

COORDINATES = frozenset({"x", "y", "z", "d", "rho", "phic", "r", "theta", "phis"})
"""Coordinate names of the expression language, which a named expression must not read."""


def evaluate(field: FieldSource, x, y, z, d=None) -> np.ndarray:
    """``field`` at the points (1-D arrays, mm), float64 of their shape."""
    shape = np.broadcast_shapes(*map(np.shape, (x, y, z)))
    if isinstance(field, float):
        return np.full(shape, field)
    if isinstance(field, str):
        field = _compiled(field)
    if isinstance(field, Expression):
        if "d" in field.variables:
            return np.broadcast_to(field(x, y, z, np.full(shape, np.nan) if d is None else d), shape).astype(float)
        return np.broadcast_to(field(x, y, z), shape).astype(float)
    return np.broadcast_to(np.asarray(field(x, y, z, d), dtype=float), shape)


_CACHE: dict[str, Expression] = {}


def _compiled(text: str) -> Expression:
    if text not in _CACHE:
        _CACHE[text] = compile_expression(text)
    return _CACHE[text]


class DerivedField:
    """``function(values)`` of the input fields' ``values`` (a list of arrays) at each
    point, as a field ``f(x, y, z, d=None)``; ``name`` is shown in messages."""

    def __init__(self, inputs: Sequence[FieldSource], function: Callable[[list[np.ndarray]], np.ndarray],
                 name: str) -> None:
        self.inputs = tuple(inputs)
        self.function = function
        self.__name__ = name

    def __call__(self, x, y, z, d=None) -> np.ndarray:
        values = [evaluate(f, x, y, z, d) for f in self.inputs]
        with np.errstate(all="ignore"):
            out = np.asarray(self.function(values), dtype=float)
        return np.broadcast_to(out, np.broadcast_shapes(*map(np.shape, (x, y, z))))


def named_expression(owner: str, text: str, names: Sequence[str], constants: dict[str, float] | None = None, *,
                     file: str | None = None, line: int = 1) -> Callable[[list[np.ndarray]], np.ndarray]:
    """The expression ``text`` over the named inputs ``names`` (at most four; case
    insensitive, as the expression language) and ``constants`` (name -> number), as a
    function of the inputs' value arrays, in the order of ``names``. Coordinates (``x``,
    ``z``, ``rho``...) that are not input names are refused: the expression reads its
    inputs only. ``owner`` names the API in messages; ``file``/``line``: the script's."""
    constants = dict(constants or {})
    if len(names) > len(SLOTS):
        raise DesignError(f"{owner}: fgslice evaluates at most {len(SLOTS)} attribute inputs in one expression, "
                          f"got {len(names)}", hint="split the expression into steps, each a derived attribute")
    known = [*names, *constants]
    used = set(re.findall(r"\b[A-Za-z_]\w*\b", text)) & (COORDINATES - {n.lower() for n in known})
    if used:
        raise DesignError(f"{owner}: '{sorted(used)[0]}' is not one of the inputs ({', '.join(known) or 'none'})",
                          hint="the expression reads its named inputs only")
    if not known:
        return _bound(compile_expression(text, file=file, line=line), 0)
    slots = {n.lower(): s for n, s in zip(names, SLOTS)}
    slots.update({n.lower(): f"({value!r})" for n, value in constants.items()})
    pattern = re.compile(r"\b(" + "|".join(re.escape(n) for n in sorted(slots, key=len, reverse=True)) + r")\b",
                         re.IGNORECASE)
    compiled = compile_expression(pattern.sub(lambda m: slots[m.group(1).lower()], text), file=file, line=line)
    return _bound(compiled, len(names))


def _bound(expression: Expression, count: int) -> Callable[[list[np.ndarray]], np.ndarray]:
    def function(values: list[np.ndarray]) -> np.ndarray:
        shape = np.broadcast_shapes(*map(np.shape, values)) if values else ()
        padded = list(values) + [np.zeros(shape)] * (len(SLOTS) - count)
        x, y, z, d = padded
        return expression(x, y, z, d) if "d" in expression.variables else expression(x, y, z)

    return function
