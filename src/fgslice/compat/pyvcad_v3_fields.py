"""OpenVCAD 3's attribute arithmetic, served by :mod:`fgslice.compat.pyvcad_v3`'s attribute types.

* ``FloatAttribute``: ``+ - * / **`` with attributes or numbers (either side), ``-a``,
  ``abs(a)``; ``normalize(lo, hi)`` (lo -> 0, hi -> 1), ``map_range(in_lo, in_hi, out_lo,
  out_hi)`` (linear, not clamped), ``clamp(lo, hi)``; ``set_value``, ``set_expression``,
  ``set_function`` replace the definition in place.
* ``Vec3Attribute``: ``component(i)`` and ``.x .y .z`` (a channel as a FloatAttribute),
  ``magnitude()``, ``normalized()`` (unit length; zero vectors give NaN), ``dot(other)``.
* ``DerivedFloatAttribute(expression, inputs)``: an expression of named inputs
  (FloatAttributes or numbers).

Each step gives a new attribute and leaves its inputs as they were. The fields are
:class:`fgslice.design.derived_fields.DerivedField` callables, evaluated in the frame of
the node the result is attached to, like any field.
"""

from __future__ import annotations

import numbers
import operator

import numpy as np

from fgslice.compat import context
from fgslice.design.derived_fields import DerivedField, named_expression
from fgslice.errors import DesignError

_DOCS = "see the OpenVCAD 3 section of docs/language.md"


def _number(owner: str, what: str, value) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not np.isfinite(value):
        raise DesignError(f"{owner}: {what} must be a finite number, got {value!r}", hint=_DOCS)
    return float(value)


def _new_float(field):
    from fgslice.compat.pyvcad_v3 import FloatAttribute

    attribute = FloatAttribute.__new__(FloatAttribute)
    attribute.field = field
    return attribute


def _operand(owner: str, value):
    """The field of an arithmetic operand: a FloatAttribute's, or a number."""
    from fgslice.compat.pyvcad_v3 import FloatAttribute

    if isinstance(value, FloatAttribute):
        return value.field
    if isinstance(value, numbers.Real) and not isinstance(value, bool):
        return float(value)
    raise DesignError(f"{owner}: a FloatAttribute combines with FloatAttributes and numbers, got "
                      f"{type(value).__name__}", hint="take a vector's channel with .x / .component(i) first")


_SYMBOLS = {operator.add: "+", operator.sub: "-", operator.mul: "*", operator.truediv: "/", operator.pow: "**"}


def _binary(left, right, op, owner: str):
    a, b = _operand(owner, left), _operand(owner, right)
    return _new_float(DerivedField((a, b), lambda v: op(v[0], v[1]), f"({a!r} {_SYMBOLS[op]} {b!r})"))


class FloatOps:
    """The arithmetic and range methods of OpenVCAD 3's ``FloatAttribute``."""

    field: object

    def __add__(self, other):
        return _binary(self, other, operator.add, "FloatAttribute +")

    def __radd__(self, other):
        return _binary(other, self, operator.add, "FloatAttribute +")

    def __sub__(self, other):
        return _binary(self, other, operator.sub, "FloatAttribute -")

    def __rsub__(self, other):
        return _binary(other, self, operator.sub, "FloatAttribute -")

    def __mul__(self, other):
        return _binary(self, other, operator.mul, "FloatAttribute *")

    def __rmul__(self, other):
        return _binary(other, self, operator.mul, "FloatAttribute *")

    def __truediv__(self, other):
        return _binary(self, other, operator.truediv, "FloatAttribute /")

    def __rtruediv__(self, other):
        return _binary(other, self, operator.truediv, "FloatAttribute /")

    def __pow__(self, other):
        return _binary(self, other, operator.pow, "FloatAttribute **")

    def __rpow__(self, other):
        return _binary(other, self, operator.pow, "FloatAttribute **")

    def __neg__(self):
        return _new_float(DerivedField((self.field,), lambda v: -v[0], "-field"))

    def __abs__(self):
        return _new_float(DerivedField((self.field,), lambda v: np.abs(v[0]), "abs(field)"))

    def clamp(self, minimum, maximum):
        """The value held within ``[minimum, maximum]``."""
        lo, hi = _number("clamp", "minimum", minimum), _number("clamp", "maximum", maximum)
        if hi < lo:
            raise DesignError(f"FloatAttribute.clamp: maximum {hi:g} is below minimum {lo:g}")
        return _new_float(DerivedField((self.field,), lambda v: np.clip(v[0], lo, hi), "clamp"))

    def map_range(self, input_minimum, input_maximum, output_minimum, output_maximum):
        """``input_minimum`` -> ``output_minimum``, ``input_maximum`` -> ``output_maximum``,
        linear between and beyond (not clamped)."""
        a, b, c, e = (_number("map_range", n, v) for n, v in zip(
            ("input_minimum", "input_maximum", "output_minimum", "output_maximum"),
            (input_minimum, input_maximum, output_minimum, output_maximum)))
        if a == b:
            raise DesignError(f"FloatAttribute.map_range: the input range {a:g} .. {b:g} is empty",
                              hint="give two different input values")
        return _new_float(DerivedField((self.field,), lambda v: c + (v[0] - a) * (e - c) / (b - a), "map_range"))

    def normalize(self, minimum, maximum):
        """``minimum`` -> 0, ``maximum`` -> 1, linear (not clamped)."""
        return self.map_range(minimum, maximum, 0.0, 1.0)

    def set_value(self, value) -> None:
        """Make this attribute the constant ``value``."""
        self._define(_number("FloatAttribute.set_value", "value", value))

    def set_expression(self, expression) -> None:
        """Make this attribute the expression string ``expression``."""
        if not isinstance(expression, str):
            raise DesignError(f"FloatAttribute.set_expression takes a string, got {expression!r}", hint=_DOCS)
        self._define(expression)

    def set_function(self, function) -> None:
        """Make this attribute the ``@cfunc`` ``function`` of ``(x, y, z, d)``."""
        if isinstance(function, (str, numbers.Real)):
            raise DesignError("FloatAttribute.set_function takes a @cfunc", hint=_DOCS)
        self._define(function)

    def set_volume(self, volume) -> None:
        """Make this attribute the trilinear samples of the FloatVolume ``volume``."""
        from fgslice.compat.pyvcad_v3_leaves import FloatVolume

        if not isinstance(volume, FloatVolume):
            raise DesignError(f"FloatAttribute.set_volume takes a FloatVolume, got {type(volume).__name__}", hint=_DOCS)
        self._define(volume)

    def _define(self, definition) -> None:
        from fgslice.compat.pyvcad_v3 import _component

        self.field = _component("FloatAttribute", "the definition", definition)


class Vec3Ops:
    """The channel and vector methods of OpenVCAD 3's ``Vec3Attribute``."""

    fields: tuple

    def component(self, index):
        """Channel ``index`` (0, 1 or 2) as a FloatAttribute."""
        if isinstance(index, bool) or not isinstance(index, numbers.Integral) or not 0 <= index <= 2:
            raise DesignError(f"Vec3Attribute.component: the index is 0, 1 or 2, got {index!r}")
        field = self.fields[int(index)]
        return _new_float(field)

    @property
    def x(self):
        """The first channel as a FloatAttribute."""
        return self.component(0)

    @property
    def y(self):
        """The second channel as a FloatAttribute."""
        return self.component(1)

    @property
    def z(self):
        """The third channel as a FloatAttribute."""
        return self.component(2)

    def magnitude(self):
        """The vector's Euclidean length as a FloatAttribute."""
        return _new_float(DerivedField(self.fields, lambda v: np.sqrt(v[0] ** 2 + v[1] ** 2 + v[2] ** 2), "magnitude"))

    def normalized(self):
        """The vector scaled to unit length (NaN where it is zero) as a Vec3Attribute."""
        from fgslice.compat.pyvcad_v3 import Vec3Attribute

        def channel(i):
            return DerivedField(self.fields, lambda v: v[i] / np.sqrt(v[0] ** 2 + v[1] ** 2 + v[2] ** 2), "normalized")

        out = Vec3Attribute.__new__(Vec3Attribute)
        out.fields = tuple(channel(i) for i in range(3))
        return out

    def dot(self, other):
        """The dot product with the Vec3Attribute ``other`` as a FloatAttribute."""
        if not isinstance(other, Vec3Ops):
            raise DesignError(f"Vec3Attribute.dot takes a Vec3Attribute, got {type(other).__name__}", hint=_DOCS)
        return _new_float(DerivedField(self.fields + other.fields,
                                       lambda v: v[0] * v[3] + v[1] * v[4] + v[2] * v[5], "dot"))


def derived(expression, inputs):
    """The field of ``DerivedFloatAttribute(expression, inputs)``: ``inputs`` maps names
    to FloatAttributes or numbers; the expression reads those names only."""
    from fgslice.compat.pyvcad_v3 import FloatAttribute

    owner = "DerivedFloatAttribute"
    if not isinstance(expression, str):
        raise DesignError(f"{owner}: the expression is a string, got {expression!r}", hint=_DOCS)
    if not isinstance(inputs, dict):
        raise DesignError(f"{owner}: inputs is a dict of name -> FloatAttribute or number, got "
                          f"{type(inputs).__name__}", hint=_DOCS)
    names, fields, constants = [], [], {}
    for name, value in inputs.items():
        if not isinstance(name, str) or not name.isidentifier():
            raise DesignError(f"{owner}: an input name is an identifier such as 'signal', got {name!r}")
        if isinstance(value, FloatAttribute):
            names.append(name)
            fields.append(value.field)
        elif isinstance(value, numbers.Real) and not isinstance(value, bool):
            constants[name] = float(value)
        else:
            raise DesignError(f"{owner}: input '{name}' must be a FloatAttribute or a number, got "
                              f"{type(value).__name__}", hint="OpenVCAD derives float attributes from float inputs")
    where = context.site()
    function = named_expression(owner, expression, names, constants, file=where.file, line=where.line or 1)
    return DerivedField(fields, function, expression)
