"""OpenVCAD 3's point-wise attribute API: return types, ``AttributeSamples`` and the
Python converters (``AttributeConverterBase`` subclasses) built on them.

* ``Attribute.ReturnType`` (``dbl``, ``vec3``, ``vec4``, ``vfm_ptr``),
  ``DefaultAttributes.NAME_TYPE`` and ``DefaultAttributes.get_return_type_by_name(name)``;
* ``AttributeSamples``: attribute name -> value at one point (a float, a ``Vec3``, a
  ``Vec4``), what a converter's ``convert(samples)`` reads and returns;
* :func:`convert_per_point`: a converter's ``convert(samples)`` run at every point of
  arrays, for converters written in Python (slow: one call per point).
"""

from __future__ import annotations

import enum
import numbers
from collections.abc import Callable, Sequence

import numpy as np

from fgslice.errors import DesignError

_DOCS = "see the OpenVCAD 3 section of docs/language.md"


class ReturnType(enum.Enum):
    """``Attribute.ReturnType``: what an attribute's samples are."""

    dbl = 0
    vec3 = 1
    vec4 = 2
    vfm_ptr = 3


TYPES = {"color_rgba": ReturnType.vec4, "color_rgb": ReturnType.vec3, "volume_fractions": ReturnType.vfm_ptr}
"""Return types of the default names that are not ``dbl``."""

TYPE_NAMES = {"MODULUS_TYPE": "modulus", "TOUGHNSS_TYPE": "toughness", "TOUGHNESS_TYPE": "toughness",
              "ELONGATION_TYPE": "elongation", "SHORE_HARDNESS_TYPE": "shore_hardness", "TEMPERATURE_TYPE": "temperature",
              "HU_TYPE": "hu", "VOLUME_FRACTIONS_TYPE": "volume_fractions", "COLOR_RGBA_TYPE": "color_rgba",
              "COLOR_RGB_TYPE": "color_rgb", "DENSITY_TYPE": "density", "INFILL_DENSITY_TYPE": "infill_density",
              "FUZZY_SKIN_POINT_DISTANCE_TYPE": "fuzzy_skin_point_distance",
              "FUZZY_SKIN_THICKNESS_TYPE": "fuzzy_skin_thickness", "FLOW_RATE_TYPE": "flow_rate"}
"""``DefaultAttributes.*_TYPE`` -> the name whose type it is (``TOUGHNSS_TYPE``: OpenVCAD's spelling)."""


def return_type_by_name(name) -> ReturnType:
    """``DefaultAttributes.get_return_type_by_name(name)``: the type of a default name."""
    from fgslice.compat.pyvcad_v3 import DefaultAttributes

    if not isinstance(name, str) or name.upper() not in DefaultAttributes._NAMES:
        raise DesignError(f"get_return_type_by_name: '{name}' is not one of pv.DefaultAttributes' names", hint=_DOCS)
    return TYPES.get(name.lower(), ReturnType.dbl)


class AttributeSamples:
    """``AttributeSamples()``: attribute values at one point, by name."""

    def __init__(self) -> None:
        self._values: dict[str, object] = {}

    def set_sample(self, name, value) -> None:
        """Set ``name`` to a number, ``Vec3`` or ``Vec4``."""
        self._values[_key(name)] = _sample_value(name, value)

    def get_sample(self, name):
        """The value of ``name``."""
        key = _key(name)
        if key not in self._values:
            raise DesignError(f"AttributeSamples has no sample '{key}'",
                              hint="check has_sample(name); a converter sees its required attributes only")
        return self._values[key]

    def has_sample(self, name) -> bool:
        """Whether ``name`` has a value."""
        return _key(name) in self._values

    def get_type(self, name) -> ReturnType:
        """The type of ``name``'s value."""
        from fgslice.compat.pyvcad import Vec3

        value = self.get_sample(name)
        return ReturnType.vec3 if isinstance(value, Vec3) else ReturnType.dbl if isinstance(value, float) else ReturnType.vec4


def _key(name) -> str:
    if type(name) is str and name.islower() and name.strip() == name and name:
        return name
    if not isinstance(name, str) or not name.strip():
        raise DesignError(f"AttributeSamples: an attribute name is a string, got {name!r}")
    return name.strip().lower()


def _sample_value(name, value):
    if type(value) is float:  # the common case first: one call per point
        return value
    from fgslice.compat.pyvcad import Vec3
    from fgslice.compat.pyvcad_v3 import Vec4

    if isinstance(value, (Vec3, Vec4)):
        return value
    if isinstance(value, numbers.Real) and not isinstance(value, bool):
        return float(value)
    if isinstance(value, np.ndarray) and value.dtype.kind == "f":  # a whole-array call (convert_per_point)
        return value
    raise DesignError(f"AttributeSamples.set_sample('{name}'): a sample is a number, Vec3 or Vec4, got "
                      f"{type(value).__name__}", hint="fgslice converts to float and colour attributes")


def _channels(value) -> tuple[float, ...]:
    if type(value) is float:
        return (value,)
    from fgslice.compat.pyvcad import Vec3

    return tuple(value) if isinstance(value, Vec3) else value.values


def convert_per_point(convert: Callable, inputs: Sequence[str], outputs: Sequence[str], widths: Sequence[int],
                      owner: str) -> Callable[[list[np.ndarray]], list[np.ndarray]]:
    """A function of the inputs' arrays giving the outputs' channel arrays, calling
    ``convert(samples) -> AttributeSamples`` (``widths``: channels per output): once with
    whole float arrays as the samples when it computes with them (arithmetic, numpy),
    else (a branch on a value, ``math`` functions) at each point. Points where an input
    is NaN give NaN."""
    state = {"per_point": False}

    def whole(columns: list[np.ndarray]) -> list[np.ndarray] | None:
        samples = AttributeSamples()
        samples._values.update(zip(inputs, columns))
        try:
            with np.errstate(all="ignore"):
                result = convert(samples)
            if not isinstance(result, AttributeSamples) or any(w != 1 for w in widths):
                return None
            out = [np.broadcast_to(np.asarray(result.get_sample(name), dtype=float), columns[0].shape)
                   for name in outputs]
        except (TypeError, ValueError, DesignError):
            return None
        known = np.all([np.isfinite(c) for c in columns], axis=0)
        return [np.where(known, o, np.nan) for o in out]

    def function(values: list[np.ndarray]) -> list[np.ndarray]:
        shape = np.broadcast_shapes(*map(np.shape, values))
        columns = [np.broadcast_to(v, shape).ravel() for v in values]
        if not state["per_point"]:
            out = whole([np.array(c, dtype=float) for c in columns])
            if out is not None:
                return [o.reshape(shape) for o in out]
            state["per_point"] = True
        out = np.full((int(np.prod(shape)), sum(widths)), np.nan)
        known = np.flatnonzero(np.all([np.isfinite(c) for c in columns], axis=0))
        points = np.column_stack(columns)[known].tolist()
        for i, point in zip(known.tolist(), points):
            samples = AttributeSamples()
            samples._values.update(zip(inputs, point))
            result = convert(samples)
            if not isinstance(result, AttributeSamples):
                raise DesignError(f"{owner}.convert must return a pv.AttributeSamples, got {type(result).__name__}",
                                  hint=_DOCS)
            row = [c for name in outputs for c in _channels(result.get_sample(name))]
            if len(row) != out.shape[1]:
                raise DesignError(f"{owner}.convert gives {len(row)} channel(s) for the outputs "
                                  f"{', '.join(outputs)} ({' + '.join(map(str, widths))} channels)", hint=_DOCS)
            out[i] = row
        return [out[:, j].reshape(shape) for j in range(out.shape[1])]

    return function
