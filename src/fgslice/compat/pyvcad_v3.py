"""OpenVCAD 3 ("attribute modeling") names of the ``pyvcad`` module a design script imports.

OpenVCAD 3 geometry carries no material: every property is a typed field attached to a
node with ``node.set_attribute(name, attribute)``. This module holds the attribute types,
the attribute nodes and the conflict resolvers; :mod:`fgslice.compat.pyvcad` serves them
under ``pyvcad`` next to the geometry it shares with OpenVCAD 2, and calls :func:`dress`
for every node it converts, which wraps the node's fgslice tree in:

* its conflict resolvers (:class:`~fgslice.design.attribute_ops.ResolveConflicts`,
  :class:`~fgslice.design.attribute_ops.AverageFractions` for ``VOLUME_FRACTIONS``);
* its attributes, the ones an ancestor also sets left out (OpenVCAD's rule: a parent's
  attribute overrides its children's; a child without one inherits the parent's):
  ``VOLUME_FRACTIONS`` becomes an ``fgrade`` of the named materials; scalar attributes
  become :class:`~fgslice.design.attributes.Attribute` nodes, vector attributes one per
  channel (``color_rgb.r``, ``.g``, ``.b``; ``.a`` for RGBA; ``.x .y .z .w`` otherwise).

Units: OpenVCAD's ``FLOW_RATE`` is a multiplier (1.0 = nominal), fgslice's ``flow`` percent,
so ``flow_rate`` is multiplied by 100 (and divided back where a converter reads it);
``TEMPERATURE`` is in degrees C and ``INFILL_DENSITY`` in percent in both. Other names keep
their values and drive nothing (``fgslice check`` lists them).

Fields are evaluated in the frame of the node they are attached to, so they move with
its transforms; ``Identity(child)`` is a node of its own to attach world-frame fields
to. Numba ``@cfunc`` functions come from :mod:`fgslice.compat.numba_standin` and are
evaluated on numpy arrays.
"""

from __future__ import annotations

import copy
import enum
import numbers
from collections.abc import Callable, Sequence

import numpy as np

from fgslice import __version__
from fgslice.compat import context
from fgslice.compat import pyvcad as v2
from fgslice.compat import pyvcad_v3_leaves as leaves
from fgslice.compat.pyvcad_v3_leaves import (  # noqa: F401 - served under pyvcad (leaves.__all__)
    Cone, DICOMLoader, FloatVolume, MappedGraphLattice, MappedImplicitLattice, CellMap, GraphUnitCell, ImplicitUnitCell)
from fgslice.compat.numba_standin import CFunc
from fgslice.compat.pyvcad_cad import CADModel  # noqa: F401 - served as pyvcad.CADModel
from fgslice.compat.pyvcad_v3_fields import FloatOps, Vec3Ops, derived
from fgslice.compat.pyvcad_v3_samples import (TYPE_NAMES, AttributeSamples, ReturnType, convert_per_point,
                                              return_type_by_name)
from fgslice.design import api, lookup_tables, nodes
from fgslice.design.attribute_ops import AverageFractions, ConvertAttributes, Reducer, ResolveConflicts
from fgslice.design.attributes import OPENVCAD_MACHINE_NAMES as MACHINE_NAMES
from fgslice.design.attributes import Attribute as AttributeNode
from fgslice.design.derived_fields import evaluate, named_expression
from fgslice.design.expressions import compile_expression
from fgslice.design.lookup_tables import Grid
from fgslice.errors import DesignError

_DOCS = "see the OpenVCAD 3 section of docs/language.md"

__all__ = [
    "version", "DefaultAttributes", "FloatAttribute", "Vec3Attribute", "Vec4Attribute", "VolumeFractionsAttribute",
    "Identity", "BBoxUnion", "BBoxIntersection", "Torus", "AttributeModifier", "LookupTableEntry",
    "LookupTableConverter", "ExpressionConverter", "InterpolationMode", "resolvers", "Vec4", "CADModel",
    "DerivedFloatAttribute", "Attribute", "AttributeSamples", "AttributeConverterBase", *leaves.__all__,
]


def version() -> str:
    """The version of the modeling API, as OpenVCAD's ``pv.version()``: fgslice's, marked."""
    return f"3 (fgslice {__version__})"


# ---------------------------------------------------------------------------- names


class _Names:
    """``pv.DefaultAttributes``: OpenVCAD's canonical attribute names (lowercase strings)."""

    _NAMES = (
        "NONE", "MODULUS", "TOUGHNESS", "ELONGATION", "SHORE_HARDNESS", "TEMPERATURE", "HU", "VOLUME_FRACTIONS",
        "COLOR_RGBA", "COLOR_RGB", "DENSITY", "INFILL_DENSITY", "FUZZY_SKIN_POINT_DISTANCE", "FUZZY_SKIN_THICKNESS",
        "FLOW_RATE", "BRIDGE_SPEED", "EXTERNAL_PERIMETER_EXTRUSION_WIDTH", "EXTERNAL_PERIMETER_SPEED",
        "EXTRUSION_WIDTH", "GAP_FILL_SPEED", "INFILL_EXTRUSION_WIDTH", "INFILL_SPEED", "IRONING_FLOWRATE",
        "IRONING_SPEED", "LAYER_HEIGHT", "PERIMETER_EXTRUSION_WIDTH", "PERIMETER_SPEED", "PERIMETERS",
        "SMALL_PERIMETER_SPEED", "SOLID_INFILL_EXTRUSION_WIDTH", "SOLID_INFILL_SPEED",
        "SUPPORT_MATERIAL_EXTRUSION_WIDTH", "TOP_INFILL_EXTRUSION_WIDTH", "TOP_SOLID_INFILL_SPEED",
    )

    def __getattr__(self, name: str):
        if name in self._NAMES:
            return name.lower()
        if name in TYPE_NAMES:
            return return_type_by_name(TYPE_NAMES[name])
        if name.startswith("__"):
            raise AttributeError(name)
        raise v2._unsupported("DefaultAttributes", name)

    @staticmethod
    def get_return_type_by_name(name) -> ReturnType:
        """The ``Attribute.ReturnType`` of a default attribute name."""
        return return_type_by_name(name)


DefaultAttributes = _Names()

def _fgslice_name(name: str) -> tuple[str, float]:
    """The fgslice attribute an OpenVCAD scalar attribute is, with its unit factor."""
    return MACHINE_NAMES.get(name, (name, 1.0))


def _attribute_name(owner: str, name) -> str:
    if not isinstance(name, str) or not name.strip():
        raise DesignError(f"{owner}: an attribute name is a string such as pv.DefaultAttributes.TEMPERATURE, "
                          f"got {name!r}", hint=_DOCS)
    return name.strip().lower()


# ---------------------------------------------------------------------------- fields


class _ArrayFunction:
    """A Python function of numbers evaluated on numpy arrays: once on the whole arrays,
    or point by point when it only takes numbers (``if t < 0.0:``, ``max(a, b)``)."""

    def __init__(self, function: Callable, name: str) -> None:
        self.function = function
        self.__name__ = name
        self.per_point = False

    def __call__(self, *arrays) -> np.ndarray:
        shape = np.broadcast_shapes(*map(np.shape, arrays))
        if not self.per_point:
            try:
                with np.errstate(all="ignore"):
                    value = np.asarray(self.function(*arrays), dtype=float)
                return np.broadcast_to(value, shape)
            except (TypeError, ValueError):
                self.per_point = True
        return np.frompyfunc(self.function, len(arrays), 1)(*np.broadcast_arrays(*arrays)).astype(float)


class _PointField:
    """A ``@cfunc`` of ``(x, y, z, d)`` as a field: ``f(x, y, z, d=None)`` on arrays (mm);
    without ``d`` (the signed distance) the function sees NaN there."""

    def __init__(self, function: CFunc) -> None:
        self._array = _ArrayFunction(function.py_func, function.__name__)
        self.__name__ = function.__name__

    def __call__(self, x, y, z, d=None) -> np.ndarray:
        if d is None:
            d = np.full(np.broadcast_shapes(*map(np.shape, (x, y, z))), np.nan)
        return self._array(x, y, z, d)


def _component(owner: str, what: str, value):
    """One scalar component: a number, an expression string (checked now, so a bad one
    fails at the script's line) or a 4-argument ``@cfunc``."""
    if isinstance(value, bool):
        raise DesignError(f"{owner}: {what} must be a number, an expression string or a @cfunc, got {value!r}")
    if isinstance(value, numbers.Real):
        return float(value)
    if isinstance(value, str):
        where = context.site()
        compile_expression(value, file=where.file, line=where.line or 1)
        return value
    if isinstance(value, FloatVolume):
        return value.volume
    if isinstance(value, CFunc):
        if value.arity != 4:
            raise DesignError(f"{owner}: the @cfunc '{value.__name__}' takes {value.arity} arguments; an attribute "
                              "function takes (x, y, z, d)", hint=_DOCS)
        return _PointField(value)
    if callable(value):
        raise DesignError(f"{owner}: a Python function must be decorated with numba's @cfunc, as OpenVCAD requires",
                          hint="@cfunc(types.float64(types.float64, types.float64, types.float64, types.float64))")
    raise DesignError(f"{owner}: {what} must be a number, an expression string or a @cfunc, got {value!r}", hint=_DOCS)


def _node_field(field) -> str | Callable:
    """A component as a :class:`~fgslice.design.nodes.Field` source (numbers as text)."""
    return repr(field) if isinstance(field, float) else field


def _scaled(field, factor: float):
    """``field`` times ``factor``, as a field of the same kind."""
    if factor == 1.0:
        return field
    if isinstance(field, float):
        return field * factor
    if isinstance(field, str):
        return f"({field}) * {factor!r}"

    def scaled(x, y, z, d=None):
        return field(x, y, z, d) * factor

    scaled.__name__ = getattr(field, "__name__", "field")
    return scaled


class Attribute:
    """``pv.Attribute``, the base of the attribute types: fields kept as given, attached
    by ``set_attribute``; ``sample(x, y, z, d)`` evaluates one point (mm), ``clone()``
    copies, ``return_type()`` tells the kind of value."""

    ReturnType = ReturnType
    _type = ReturnType.dbl

    def __getattr__(self, name: str):
        if name.startswith("__"):
            raise AttributeError(name)
        raise v2._unsupported(type(self).__name__, name)

    def return_type(self) -> ReturnType:
        """``Attribute.ReturnType`` of the samples."""
        return self._type

    def clone(self):
        """An independent copy."""
        return copy.deepcopy(self)

    def is_volume_backed(self) -> bool:
        """Whether the attribute samples a volume (never, in fgslice)."""
        return False

    def sample(self, x, y, z, d=0.0):
        """The value at the point ``(x, y, z)`` with signed distance ``d`` (mm)."""
        point = [np.array([v2._number("sample", n, v)]) for n, v in zip("xyzd", (x, y, z, d))]
        return self._sample(point)


def _point(field, point) -> float:
    return float(evaluate(field, *point)[0])


class FloatAttribute(FloatOps, Attribute):
    """``FloatAttribute(value)``: a constant, an expression string of ``x, y, z, d`` (and
    ``rho, phic, r, theta, phis``) or a ``@cfunc`` of ``(x, y, z, d)``; ``FloatAttribute()``
    is the constant 0 until ``set_value`` / ``set_expression`` / ``set_function``. The
    arithmetic and range methods are :class:`~fgslice.compat.pyvcad_v3_fields.FloatOps`'."""

    def __init__(self, *args) -> None:
        v2._overload("FloatAttribute", args, {0: "", 1: "definition"})
        self.field = _component("FloatAttribute", "the definition", args[0]) if args else 0.0

    def to_field(self) -> float | str | Callable:
        """The field as fgslice's design nodes take it: a float (constant), an expression
        string, or a vectorized callable ``f(x, y, z, d=None) -> ndarray`` (mm; the
        function sees ``d`` NaN when it is not given)."""
        return self.field

    def _sample(self, point) -> float:
        return _point(self.field, point)


class _Vector(Attribute):
    """A vector attribute: one scalar field per channel (``set_value``,
    ``set_expression``, ``set_function`` replace them all)."""

    _owner = ""
    _channels: tuple[str, ...] = ()

    def __init__(self, *args) -> None:
        from fgslice.compat.png_loader import ColorVolume

        if len(args) == 1 and isinstance(args[0], ColorVolume):  # a PNGLoader's volume: its channels
            if args[0].channels != len(self._channels):
                raise DesignError(f"{self._owner} takes a volume of {len(self._channels)} channels, got "
                                  f"{args[0].channels}", hint="as_rgb_volume() for Vec3Attribute, as_rgba_volume() "
                                  "for Vec4Attribute")
            self.fields = tuple(args[0].field(i) for i in range(len(self._channels)))
            return
        v2._overload(self._owner, args, {0: "", len(self._channels): ", ".join(self._channels)})
        self.fields = tuple(_component(self._owner, c, a) for c, a in zip(self._channels, args)) if args else \
            (0.0,) * len(self._channels)

    def _set(self, method: str, kinds: tuple, args: tuple) -> None:
        owner = f"{self._owner}.{method}"
        v2._overload(owner, args, {len(self._channels): ", ".join(self._channels)})
        if not all(isinstance(a, kinds) and not isinstance(a, bool) for a in args):
            raise DesignError(f"{owner} takes {len(self._channels)} "
                              f"{'numbers' if numbers.Real in kinds else 'strings' if str in kinds else '@cfunc functions'}",
                              hint=_DOCS)
        self.fields = tuple(_component(self._owner, c, a) for c, a in zip(self._channels, args))

    def set_value(self, *values) -> None:
        """Constant channels."""
        self._set("set_value", (numbers.Real,), values)

    def set_expression(self, *expressions) -> None:
        """One expression string per channel."""
        self._set("set_expression", (str,), expressions)

    def set_function(self, *functions) -> None:
        """One ``@cfunc`` per channel."""
        self._set("set_function", (CFunc,), functions)

    def _sample(self, point):
        values = [_point(f, point) for f in self.fields]
        return v2.Vec3(*values) if len(values) == 3 else Vec4(*values)

    def to_fields(self) -> tuple:
        """Each channel's field, as :meth:`FloatAttribute.to_field`."""
        return self.fields


class Vec3Attribute(Vec3Ops, _Vector):
    """``Vec3Attribute(x, y, z)``: three channels (``COLOR_RGB``: red, green, blue in 0-1);
    the channel and vector methods are :class:`~fgslice.compat.pyvcad_v3_fields.Vec3Ops`'."""

    _owner, _channels, _type = "Vec3Attribute", ("x", "y", "z"), ReturnType.vec3


class Vec4Attribute(_Vector):
    """``Vec4Attribute(r, g, b, a)``: four channels (``COLOR_RGBA``: linear RGBA in 0-1)."""

    _owner, _channels, _type = "Vec4Attribute", ("r", "g", "b", "a"), ReturnType.vec4


class DerivedFloatAttribute(FloatAttribute):
    """``DerivedFloatAttribute(expression, inputs)``: the expression of the named inputs
    (``{"name": FloatAttribute or number}``) at each point; immutable, as in OpenVCAD."""

    def __init__(self, *args, **kwargs) -> None:
        expression, inputs = v2._bind("DerivedFloatAttribute", ("expression", "inputs"), args, kwargs, {})
        self.field = derived(expression, inputs)

    def _define(self, definition) -> None:
        raise DesignError("DerivedFloatAttribute is immutable: build a new one instead of setting its definition",
                          hint=_DOCS)


class VolumeFractionsAttribute(Attribute):
    """``VolumeFractionsAttribute([(field, material id), ...])``,
    ``VolumeFractionsAttribute([fields], [material ids])`` or ``VolumeFractionsAttribute()``
    and ``add_expression`` / ``add_function`` / ``add_value``: each field is the fraction
    of its material (ids from ``default_materials.id(name)``)."""

    _type = ReturnType.vfm_ptr

    def __init__(self, *args) -> None:
        v2._overload("VolumeFractionsAttribute", args, {0: "", 1: "[(field, material), ...]", 2: "fields, materials"})
        self.fields, self.materials, self.ids = [], [], []
        if not args:
            return
        if len(args) == 2:
            fields, materials = args
            if not isinstance(fields, Sequence) or not isinstance(materials, Sequence) or len(fields) != len(materials):
                raise DesignError("VolumeFractionsAttribute: give as many fields as materials, in two lists")
            pairs = list(zip(fields, materials))
        else:
            pairs = args[0]
            if isinstance(pairs, str) or not isinstance(pairs, Sequence) or not all(
                    isinstance(p, Sequence) and not isinstance(p, str) and len(p) == 2 for p in pairs):
                raise DesignError("VolumeFractionsAttribute takes a list of (field, material id) pairs", hint=_DOCS)
        if not pairs:
            raise DesignError("VolumeFractionsAttribute needs at least one (field, material id) pair")
        for field, material in pairs:
            self._add("VolumeFractionsAttribute", field, material)

    def _add(self, owner: str, field, material) -> None:
        if isinstance(material, numbers.Integral) and not isinstance(material, (bool, v2.MaterialId)):
            material = v2.default_materials.name_of(material)
        if not isinstance(material, v2.MaterialId):
            raise DesignError(f"{owner}: a material is an id from default_materials.id(name), got {material!r}",
                              hint=_DOCS)
        if material.name in self.materials:
            raise DesignError(f"{owner}: the material '{material.name}' appears twice")
        self.fields.append(_component(owner, "a fraction", field))
        self.materials.append(material.name)
        self.ids.append(material)

    def _pair(self, owner: str, kind: str, args: tuple) -> None:
        """Add ``(definition, material)`` given as two arguments or one pair; ``kind``:
        ``"number"``, ``"string"`` or ``"@cfunc"``."""
        v2._overload(owner, args, {1: "(definition, material)", 2: "definition, material"})
        pair = args if len(args) == 2 else args[0]
        if isinstance(pair, str) or not isinstance(pair, Sequence) or len(pair) != 2:
            raise DesignError(f"{owner} takes a {kind} and a material id, or one pair of them", hint=_DOCS)
        field, material = pair
        types = {"number": numbers.Real, "string": str, "@cfunc": CFunc}[kind]
        if not isinstance(field, types) or isinstance(field, bool):
            raise DesignError(f"{owner} takes a {kind} and a material id, got {field!r}", hint=_DOCS)
        self._add(owner, field, material)

    def add_expression(self, *args) -> None:
        """Add ``(expression, material)``."""
        self._pair("VolumeFractionsAttribute.add_expression", "string", args)

    def add_function(self, *args) -> None:
        """Add ``(@cfunc, material)``."""
        self._pair("VolumeFractionsAttribute.add_function", "@cfunc", args)

    def add_value(self, value, material) -> None:
        """Add a constant fraction of ``material``."""
        self._pair("VolumeFractionsAttribute.add_value", "number", (value, material))

    def _sample(self, point) -> dict:
        return {material: _point(field, point) for field, material in zip(self.fields, self.ids)}


def set_attribute(node: v2.Node, name, attribute) -> None:
    """``node.set_attribute(name, attribute)``: attach (or replace) the attribute ``name``."""
    key = _attribute_name("set_attribute", name)
    if isinstance(attribute, VolumeFractionsAttribute) != (key == "volume_fractions"):
        raise DesignError(f"set_attribute: '{key}' takes a "
                          f"{'VolumeFractionsAttribute' if key == 'volume_fractions' else 'Float, Vec3 or Vec4 attribute'}"
                          f", got {type(attribute).__name__}", hint=_DOCS)
    if not isinstance(attribute, Attribute):
        raise DesignError(f"set_attribute: an attribute is a pyvcad FloatAttribute, Vec3Attribute, Vec4Attribute or "
                          f"VolumeFractionsAttribute, got {type(attribute).__name__}", hint=_DOCS)
    if isinstance(attribute, VolumeFractionsAttribute) and not attribute.fields:
        raise DesignError("set_attribute: the VolumeFractionsAttribute has no materials yet",
                          hint="add them with add_expression(expression, material) or add_value(value, material)")
    if key in ("color_rgb", "color_rgba") and not isinstance(attribute, Vec3Attribute if key == "color_rgb" else Vec4Attribute):
        raise DesignError(f"set_attribute: '{key}' takes a {'Vec3' if key == 'color_rgb' else 'Vec4'}Attribute, "
                          f"got {type(attribute).__name__}", hint=_DOCS)
    vars(node).setdefault("_v3_attributes", {})[key] = attribute


def _channels(name: str, attribute) -> list[tuple[str, object]]:
    """The fgslice scalar attributes ``(name, field)`` an attribute becomes."""
    if isinstance(attribute, FloatAttribute):
        target, factor = _fgslice_name(name)
        return [(target, _scaled(attribute.field, factor))]
    letters = "rgba" if name.startswith("color") else "xyzw"
    return [(f"{name}.{letters[i]}", field) for i, field in enumerate(attribute.fields)]


def produced(node: v2.Node) -> frozenset[str]:
    """The fgslice attribute names ``node``'s own attributes set."""
    names = set()
    for name, attribute in vars(node).get("_v3_attributes", {}).items():
        names.update(["volume_fractions"] if name == "volume_fractions" else (n for n, _ in _channels(name, attribute)))
    return frozenset(names)


# ---------------------------------------------------------------------------- resolvers


class Vec4Mode(enum.Enum):
    """How min / max resolvers compare vectors: each channel apart, or whole by magnitude."""

    PerChannel = "per_channel"
    Magnitude = "magnitude"


class _Resolver:
    """Base of the conflict resolvers: how overlapping children's values combine."""

    reducer: Reducer

    def __getattr__(self, name: str):
        if name.startswith("__"):
            raise AttributeError(name)
        raise v2._unsupported(type(self).__name__, name)


class AverageConflictResolver(_Resolver):
    """The mean of the overlapping children's values (volume fractions: of their
    normalized fractions)."""

    def __init__(self) -> None:
        self.reducer = Reducer("average")


class _Extreme(_Resolver):
    _which = ""

    def __init__(self, mode: Vec4Mode = Vec4Mode.Magnitude) -> None:
        if not isinstance(mode, Vec4Mode):
            raise DesignError(f"{type(self).__name__}: the mode is pv.resolvers.Vec4Mode.PerChannel or .Magnitude, "
                              f"got {mode!r}")
        self.mode = mode

    def reducer_for(self, channels: int) -> Reducer:
        if channels > 1 and self.mode is Vec4Mode.Magnitude:
            return Reducer(f"{self._which}_magnitude")
        return Reducer(self._which)


class MinConflictResolver(_Extreme):
    """The least value; vectors: the one of least magnitude (default) or each channel's least."""

    _which = "min"


class MaxConflictResolver(_Extreme):
    """The greatest value; vectors: the one of greatest magnitude (default) or each channel's greatest."""

    _which = "max"


def _pairwise(owner: str, function) -> _ArrayFunction:
    if not isinstance(function, CFunc) or function.arity != 2:
        raise DesignError(f"{owner} takes @cfunc functions of (left, right)",
                          hint="@cfunc(types.float64(types.float64, types.float64))")
    return _ArrayFunction(function.py_func, function.__name__)


class CustomFloatConflictResolver(_Resolver):
    """``CustomFloatConflictResolver(f)``: ``f(left, right)`` reduced over the
    overlapping children in order."""

    def __init__(self, function) -> None:
        self.reducer = Reducer("pairwise", (_pairwise("CustomFloatConflictResolver", function),))
        self.channels = 1


class CustomVec3ConflictResolver(_Resolver):
    """``CustomVec3ConflictResolver(fx, fy, fz)``: one pairwise function per channel."""

    def __init__(self, *functions) -> None:
        v2._overload("CustomVec3ConflictResolver", functions, {3: "x, y, z"})
        self.reducer = Reducer("pairwise", tuple(_pairwise("CustomVec3ConflictResolver", f) for f in functions))
        self.channels = 3


class CustomVec4ConflictResolver(_Resolver):
    """``CustomVec4ConflictResolver(fr, fg, fb, fa)``: one pairwise function per channel."""

    def __init__(self, *functions) -> None:
        v2._overload("CustomVec4ConflictResolver", functions, {4: "r, g, b, a"})
        self.reducer = Reducer("pairwise", tuple(_pairwise("CustomVec4ConflictResolver", f) for f in functions))
        self.channels = 4


class _Resolvers:
    """``pv.resolvers``."""

    AverageConflictResolver = AverageConflictResolver
    MinConflictResolver = MinConflictResolver
    MaxConflictResolver = MaxConflictResolver
    CustomFloatConflictResolver = CustomFloatConflictResolver
    CustomVec3ConflictResolver = CustomVec3ConflictResolver
    CustomVec4ConflictResolver = CustomVec4ConflictResolver
    Vec4Mode = Vec4Mode
    Vec3Mode = Vec4Mode

    def __getattr__(self, name: str):
        if name.startswith("__"):
            raise AttributeError(name)
        raise v2._unsupported("resolvers", name)


resolvers = _Resolvers()


def set_attribute_conflict_resolver(node: v2.Node, name, resolver) -> None:
    """``node.set_attribute_conflict_resolver(name, resolver)`` on a union or intersection."""
    key = _attribute_name("set_attribute_conflict_resolver", name)
    if not isinstance(node, v2._Children):
        raise DesignError(f"{type(node).__name__}.set_attribute_conflict_resolver: only Union, BBoxUnion and "
                          "Intersection nodes have children whose attributes can conflict", hint=_DOCS)
    if not isinstance(resolver, _Resolver):
        raise DesignError(f"set_attribute_conflict_resolver: a resolver is one of pv.resolvers' classes, got {resolver!r}",
                          hint=_DOCS)
    if key == "volume_fractions" and not isinstance(resolver, AverageConflictResolver):
        raise DesignError(f"set_attribute_conflict_resolver: fgslice resolves 'volume_fractions' only with "
                          f"AverageConflictResolver, not {type(resolver).__name__}",
                          hint="fractions of several materials have no order to take a min or max of")
    vars(node).setdefault("_v3_resolvers", {})[key] = resolver


def _resolver_node(name: str, resolver: _Resolver, channels: list[str], built: nodes.Node) -> nodes.Node:
    if isinstance(resolver, (CustomFloatConflictResolver, CustomVec3ConflictResolver, CustomVec4ConflictResolver)):
        if resolver.channels != len(channels):
            raise DesignError(f"{type(resolver).__name__} resolves {resolver.channels} channel(s) but '{name}' has "
                              f"{len(channels)}", hint=_DOCS)
    reducer = resolver.reducer_for(len(channels)) if isinstance(resolver, _Extreme) else resolver.reducer
    return ResolveConflicts(channels, reducer, built)


# ---------------------------------------------------------------------------- dress


def dress(node: v2.Node, built: nodes.Node, above: frozenset[str]) -> nodes.Node:
    """``built`` (the fgslice tree of ``node``) wrapped in ``node``'s conflict resolvers,
    then in its attributes that no ancestor sets (``above``: the names ancestors set)."""
    own = vars(node).get("_v3_attributes", {})
    for name, resolver in vars(node).get("_v3_resolvers", {}).items():
        if name == "volume_fractions":
            if "volume_fractions" not in above and name not in own:
                built = AverageFractions(built)
            continue
        channels = _resolver_channels(name, built)
        if channels and not (set(channels) & (above | produced(node))):
            built = _resolver_node(name, resolver, channels, built)
    for name, attribute in own.items():
        if name == "volume_fractions":
            if "volume_fractions" not in above:
                built = api.fgrade([_node_field(f) for f in attribute.fields], attribute.materials, built)
            continue
        for channel, field in reversed(_channels(name, attribute)):
            if channel not in above:
                built = AttributeNode(channel, nodes.Field(_node_field(field)), (built,), any_name=True)
    return built


def attribute_list(node: v2.Node) -> list[str]:
    """``node.attribute_list()``: the OpenVCAD attribute names ``node``'s design has
    (its own, its descendants', what its converters derive), in order of appearance."""
    from fgslice.design.attributes import AttributeFields

    built = v2.to_node(node)
    back = {target: name for name, (target, _) in MACHINE_NAMES.items()}
    names = [back.get(n, n.partition(".")[0]) for n in AttributeFields(built).names]
    if any(isinstance(n, nodes.Fgrade) for n, *_ in nodes.walk(built)):
        names.append("volume_fractions")
    return list(dict.fromkeys(names))


def _resolver_channels(name: str, built: nodes.Node) -> list[str]:
    """The fgslice attribute names below ``built`` that the OpenVCAD attribute ``name`` became."""
    from fgslice.design.attributes import AttributeFields

    present = AttributeFields(built).names
    target = _fgslice_name(name)[0]
    if target in present:
        return [target]
    letters = "rgba" if name.startswith("color") else "xyzw"
    return [f"{name}.{c}" for c in letters if f"{name}.{c}" in present]


# ---------------------------------------------------------------------------- nodes


class Identity(v2._Unary):
    """``Identity(child)``: the child unchanged, a node of its own to attach attributes to
    in the frame it is in (e.g. world-aligned fields over a rotated part)."""

    def __init__(self, *args) -> None:
        super().__init__("Identity", args, {0: ""})

    def _apply(self, child: nodes.Node) -> nodes.Node:
        return child


class BBoxUnion(v2.Union):
    """``BBoxUnion([children])`` or ``BBoxUnion(k)`` + ``add_child``: OpenVCAD's n-ary
    union (bounding boxes speed it up there); the same union here."""


class BBoxIntersection(v2.Intersection):
    """``BBoxIntersection([children])``: the intersection of the children."""


class Torus(v2._Leaf):
    """``Torus(r1, r2)``: a ring about the Z axis, centred at the origin: ``r1`` from the
    axis to the tube's centre, tube radius ``r2`` (mm); ``Torus()`` is ``Torus(2, 1)``."""

    def __init__(self, *args, **kwargs) -> None:
        bound = v2._bind("Torus", ("r1", "r2"), args, kwargs, {} if args or kwargs else {"r1": 2.0, "r2": 1.0})
        r1, r2 = (v2._number("Torus", n, v) for n, v in zip(("r1", "r2"), bound))
        if not 0 < r2 < r1:
            raise DesignError(f"Torus needs 0 < r2 < r1, got r1 = {r1:g}, r2 = {r2:g}")
        reach = r1 + r2
        super().__init__(api.function((-reach, -reach, -r2), (reach, reach, r2),
                                      f"sqrt((rho - {r1!r})^2 + z^2) - {r2!r}"))


class Vec4:
    """``Vec4(x, y, z, w)``: four numbers (lookup-table outputs)."""

    def __init__(self, x=0.0, y=0.0, z=0.0, w=0.0) -> None:
        self.values = tuple(v2._number("Vec4", a, v) for a, v in zip("xyzw", (x, y, z, w)))


# ---------------------------------------------------------------------------- converters


class InterpolationMode(enum.Enum):
    """Lookup-table interpolation: STEP (each entry's value over its range) or LINEAR."""

    STEP = 0
    LINEAR = 1


class LookupTableEntry:
    """One row of a lookup table:

    * ``LookupTableEntry(input, output)``: a point (LINEAR, or STEP from ``input`` on);
    * ``LookupTableEntry(input_low, input_high, output)``: a range of one input;
    * ``LookupTableEntry([a, b], output)``: a point of a two-input LINEAR grid;
    * ``LookupTableEntry([(low, high), ...], [value, ...])``: one range per input of a
      multi-input STEP table, with the value each input's match gives.

    An output is a number, a ``Vec3`` / ``Vec4``, or (single input) a list of them, one
    per output attribute. ``is_valid`` (default True) can be set False to leave the row out.
    """

    def __init__(self, *args) -> None:
        owner = "LookupTableEntry"
        v2._overload(owner, args, {2: "input, output", 3: "input_low, input_high, output"})
        first = args[0]
        if len(args) == 2 and isinstance(first, Sequence) and not isinstance(first, str):
            if not first:
                raise DesignError(f"{owner}: the list of inputs is empty")
            if all(isinstance(k, Sequence) and not isinstance(k, str) for k in first):
                if any(len(k) != 2 for k in first):
                    raise DesignError(f"{owner}: each input range is a (low, high) pair", hint=_DOCS)
                self.keys = tuple(_range(owner, *k) for k in first)
                self.ranged = True
            else:
                self.keys = tuple((v, v) for v in (v2._number(owner, "input point", k) for k in first))
                self.ranged = False
        else:
            low = v2._number(owner, "input", first)
            self.keys = (_range(owner, low, args[1]) if len(args) == 3 else (low, low),)
            self.ranged = len(args) == 3
        output = args[-1]
        listed = isinstance(output, Sequence) and not isinstance(output, str)
        self.values = tuple(_output_value(owner, o) for o in (output if listed else [output]))
        if not self.values:
            raise DesignError(f"{owner}: the list of outputs is empty")
        self.is_valid = True

    @property
    def low(self) -> float:
        """The (first) input's value or low end."""
        return self.keys[0][0]


def _range(owner: str, low, high) -> tuple[float, float]:
    low, high = v2._number(owner, "input_low", low), v2._number(owner, "input_high", high)
    if high < low:
        raise DesignError(f"{owner}: input_high {high:g} is below input_low {low:g}")
    return low, high


def _output_value(owner: str, value) -> tuple[float, ...]:
    """An output as its channels: a number (1), a Vec3 (3) or a Vec4 (4)."""
    if isinstance(value, v2.Vec3):
        return tuple(value)
    if isinstance(value, Vec4):
        return value.values
    if isinstance(value, dict):
        raise DesignError(f"{owner}: lookup tables to volume fractions are not supported by fgslice",
                          hint="give the fractions as a VolumeFractionsAttribute of expressions of x, y, z")
    return (v2._number(owner, "output", value),)


_WIDTHS = {"color_rgb": 3, "color_rgba": 4}
"""Channels of the vector attributes a lookup table can give (other outputs: 1)."""


def _output_channels(names: Sequence[str]) -> list[tuple[str, float]]:
    """The fgslice attributes ``(name, unit factor)`` that converter outputs ``names`` fill, channel by channel."""
    out = []
    for name in names:
        if name in _WIDTHS:
            out.extend((f"{name}.{c}", 1.0) for c in "rgba"[:_WIDTHS[name]])
        else:
            out.append(_fgslice_name(name))
    return out


def _names(owner: str, what: str, names, vectors: bool = False) -> tuple[str, ...]:
    """Attribute names of a converter: float attributes (and colours, when ``vectors``)."""
    if isinstance(names, str) or not isinstance(names, Sequence) or not names:
        raise DesignError(f"{owner}: {what} is a list of attribute names", hint=_DOCS)
    out = tuple(_attribute_name(owner, n) for n in names)
    refused = ("volume_fractions",) if vectors else ("volume_fractions", *_WIDTHS)
    vector = [n for n in out if n in refused]
    if vector:
        kinds = "float attributes and colours" if vectors else "float attributes"
        raise DesignError(f"{owner}: fgslice converts to {kinds}, not '{vector[0]}'", hint=_DOCS)
    return out


class _Converter:
    """Base of the converters: input and output attribute names, :meth:`_arrays` (a
    function of the inputs' arrays giving the outputs' channel arrays), and OpenVCAD's
    point-wise API (``required_attributes()``, ``output_attributes()``,
    ``convert(samples)``, ``clone()``)."""

    inputs: tuple[str, ...]
    outputs: tuple[str, ...]

    def __getattr__(self, name: str):
        if name.startswith("__"):
            raise AttributeError(name)
        raise v2._unsupported(type(self).__name__, name)

    def _io(self) -> tuple[tuple[str, ...], tuple[str, ...]]:
        """The input and output attribute names."""
        return self.inputs, self.outputs

    def _arrays(self, values: list[np.ndarray]) -> list[np.ndarray]:
        raise NotImplementedError

    def required_attributes(self) -> list[str]:
        """The input attribute names."""
        return list(self.inputs)

    def output_attributes(self) -> list[str]:
        """The output attribute names."""
        return list(self.outputs)

    def clone(self):
        """An independent copy."""
        return copy.deepcopy(self)

    def convert(self, samples):
        """The outputs at one point, from the inputs in ``samples`` (``AttributeSamples``)."""
        if not isinstance(samples, AttributeSamples):
            raise DesignError(f"{type(self).__name__}.convert takes a pv.AttributeSamples", hint=_DOCS)
        values = [np.array([float(samples.get_sample(name))]) for name in self.inputs]
        channels = [float(c[0]) for c in self._arrays(values)]
        out = AttributeSamples()
        for name in self.outputs:
            width = _WIDTHS.get(name, 1)
            part, channels = channels[:width], channels[width:]
            out.set_sample(name, part[0] if width == 1 else v2.Vec3(*part) if width == 3 else Vec4(*part))
        return out


class AttributeConverterBase(_Converter):
    """``pv.AttributeConverterBase``: subclass it in Python with
    ``required_attributes()``, ``output_attributes()`` (lists of names: float attributes,
    ``color_rgb``, ``color_rgba``) and ``convert(samples) -> AttributeSamples``, and pass
    an instance to ``AttributeModifier``. fgslice calls ``convert`` once per point it
    evaluates (slow: prefer a LookupTableConverter or ExpressionConverter)."""

    def __init__(self) -> None:
        pass

    def required_attributes(self) -> list[str]:
        raise DesignError(f"{type(self).__name__} must define required_attributes()", hint=_DOCS)

    def output_attributes(self) -> list[str]:
        raise DesignError(f"{type(self).__name__} must define output_attributes()", hint=_DOCS)

    def convert(self, samples):
        raise DesignError(f"{type(self).__name__} must define convert(samples)", hint=_DOCS)

    def _io(self):
        owner = type(self).__name__
        return (_names(owner, "required_attributes()", self.required_attributes()),
                _names(owner, "output_attributes()", self.output_attributes(), vectors=True))

    def _arrays(self, values):
        inputs, outputs = self._io()
        return convert_per_point(self.convert, inputs, outputs, [_WIDTHS.get(n, 1) for n in outputs],
                                 type(self).__name__)(values)


class LookupTableConverter(_Converter):
    """``LookupTableConverter(input_attributes, output_attributes, entries, mode=STEP)``.

    One input: LINEAR interpolates between the entries' inputs (held flat beyond the
    first and last), STEP gives the row of the last entry whose input (low end) is at most
    the point's (the first entry below every one). Two inputs, LINEAR: bilinear on the
    rectilinear grid of the entries' points (each input clamped to the grid). Several
    inputs, STEP: each input is matched on its own range column (as one input) and gives
    its own value; one output attribute takes the values end to end (``Vec3`` + number
    -> ``color_rgba``), else output ``i`` takes input ``i``'s value. Outputs are float
    attributes, ``color_rgb`` or ``color_rgba`` (:mod:`fgslice.design.lookup_tables`).
    """

    def __init__(self, input_attributes, output_attributes, entries, mode=InterpolationMode.STEP) -> None:
        owner = "LookupTableConverter"
        self.inputs = _names(owner, "input_attributes", input_attributes)
        self.outputs = _names(owner, "output_attributes", output_attributes, vectors=True)
        if not isinstance(mode, InterpolationMode):
            raise DesignError(f"{owner}: mode is pv.InterpolationMode.STEP or .LINEAR, got {mode!r}")
        if isinstance(entries, str) or not isinstance(entries, Sequence) or not entries or not all(
                isinstance(e, LookupTableEntry) for e in entries):
            raise DesignError(f"{owner}: entries is a list of pv.LookupTableEntry", hint=_DOCS)
        entries = [e for e in entries if e.is_valid]
        if not entries:
            raise DesignError(f"{owner}: every entry is marked is_valid = False")
        n = len(self.inputs)
        if n > 2 and mode is InterpolationMode.LINEAR:
            raise DesignError(f"{owner}: LINEAR interpolates one input or a two-input grid, got {n} inputs",
                              hint="use STEP, or chain converters")
        bad = [e for e in entries if len(e.keys) != n or (n > 1 and e.ranged != (mode is InterpolationMode.STEP))]
        if bad:
            form = "a list of (low, high) ranges" if mode is InterpolationMode.STEP else "a list of input points"
            raise DesignError(f"{owner}: an entry has {len(bad[0].keys)} input(s) for {n} input attribute(s)"
                              + (f"; with several inputs in {mode.name} mode each entry gives {form}" if n > 1 else ""),
                              hint=_DOCS)
        widths = [_WIDTHS.get(name, 1) for name in self.outputs]
        self.mode = mode
        if n > 1 and mode is InterpolationMode.STEP:
            self._columns = [self._column(owner, entries, i, widths) for i in range(n)]
            return
        rows = np.array([self._row(owner, e, widths) for e in entries])
        if n == 2:
            self._grid = Grid(np.array([[k[0] for k in e.keys] for e in entries]), rows, owner)
            return
        order = np.argsort([e.low for e in entries], kind="stable")
        ordered = [entries[i] for i in order]
        rows = rows[order]
        if mode is InterpolationMode.LINEAR:
            self._x = np.array([v for e in ordered for v in ((e.low,) if e.keys[0][0] == e.keys[0][1]
                                                              else e.keys[0])])
            self._y = np.array([r for e, r in zip(ordered, rows) for r in ([r] if e.keys[0][0] == e.keys[0][1]
                                                                           else [r, r])])
        else:
            self._x = np.array([e.low for e in ordered])
            self._y = rows

    def _row(self, owner: str, entry: LookupTableEntry, widths: list[int]) -> list[float]:
        """The entry's output channels, end to end: one value per output, or one value for all."""
        values = entry.values
        if len(values) == 1 and len(values[0]) == sum(widths):
            return list(values[0])
        if [len(v) for v in values] != widths:
            raise DesignError(f"{owner}: an entry gives {_shape(values)} for the output attribute(s) "
                              f"{', '.join(self.outputs)} ({' + '.join(map(str, widths))} channels)", hint=_DOCS)
        return [c for v in values for c in v]

    def _column(self, owner: str, entries, i: int, widths: list[int]):
        """Input ``i``'s STEP table: its range lows (ascending) and the values it gives."""
        values = [e.values for e in entries]
        if any(len(v) != len(self.inputs) for v in values):
            raise DesignError(f"{owner}: with several inputs in STEP mode each entry gives one value per input "
                              f"({len(self.inputs)})", hint=_DOCS)
        mine = [len(v[i]) for v in values]
        if len(set(mine)) != 1:
            raise DesignError(f"{owner}: the entries give input {self.inputs[i]!r} values of different sizes")
        joined = sum(len(v) for v in values[0])
        if not ((len(widths) == 1 and joined == widths[0]) or
                (len(widths) == len(self.inputs) and all(len(v) == w for v, w in zip(values[0], widths)))):
            raise DesignError(f"{owner}: the entries give {_shape(values[0])} for the output attribute(s) "
                              f"{', '.join(self.outputs)} ({' + '.join(map(str, widths))} channels)", hint=_DOCS)
        order = np.argsort([e.keys[i][0] for e in entries], kind="stable")
        return (np.array([entries[j].keys[i][0] for j in order]), np.array([entries[j].values[i] for j in order]))

    def _arrays(self, values):
        if self.mode is InterpolationMode.STEP and len(self.inputs) > 1:
            return [c for (keys, rows), t in zip(self._columns, values) for c in lookup_tables.step(keys, rows, t)]
        if len(self.inputs) == 2:
            return self._grid(values[0], values[1])
        if self.mode is InterpolationMode.LINEAR:
            return lookup_tables.linear(self._x, self._y, values[0])
        return lookup_tables.step(self._x, self._y, values[0])


def _shape(values) -> str:
    return " + ".join(f"{len(v)}" for v in values) + " channel(s)"


class ExpressionConverter(_Converter):
    """``ExpressionConverter(input_attributes, output_attributes, expressions)``: each
    output is an expression of the input attributes' names (at most four inputs)."""

    def __init__(self, input_attributes, output_attributes, expressions) -> None:
        owner = "ExpressionConverter"
        self.inputs = _names(owner, "input_attributes", input_attributes)
        self.outputs = _names(owner, "output_attributes", output_attributes)
        if isinstance(expressions, str) or not isinstance(expressions, Sequence) or len(expressions) != len(self.outputs):
            raise DesignError(f"{owner}: give one expression string per output attribute", hint=_DOCS)
        where = context.site()
        self._expressions = []
        for text in expressions:
            if not isinstance(text, str):
                raise DesignError(f"{owner}: an expression is a string, got {text!r}")
            self._expressions.append(named_expression(owner, text, self.inputs, file=where.file, line=where.line or 1))

    def _arrays(self, values):
        return [e(list(values)) for e in self._expressions]


class AttributeModifier(v2.Node):
    """``AttributeModifier(converter, child)``: the converter's output attributes, computed
    from the child's input attributes at each point, over the child."""

    def __init__(self, converter, child=None) -> None:
        super().__init__()
        if not isinstance(converter, _Converter):
            raise DesignError(f"AttributeModifier: the converter is a pv.LookupTableConverter, pv.ExpressionConverter "
                              f"or a pv.AttributeConverterBase subclass, got {type(converter).__name__}", hint=_DOCS)
        self._converter = converter
        self._child = None if child is None else v2._child("AttributeModifier", child)

    def set_child(self, child) -> None:
        """The node whose attributes are converted."""
        self._child = v2._child("AttributeModifier", child)

    def _build(self, convert) -> nodes.Node:
        if self._child is None:
            raise DesignError("AttributeModifier has no child", hint="give it with set_child(node)")
        conv = self._converter
        names_in, names_out = conv._io()
        inputs = [_fgslice_name(n) for n in names_in]
        outputs = _output_channels(names_out)

        def function(values):
            converted = conv._arrays([v / factor for v, (_, factor) in zip(values, inputs)])
            return [np.asarray(c, dtype=float) * factor for c, (_, factor) in zip(converted, outputs)]

        return ConvertAttributes([n for n, _ in inputs], [n for n, _ in outputs], function, convert(self._child))



# ---------------------------------------------------------------------------- smoothing


def _radius(owner: str, value) -> tuple[float, float, float]:
    """``physical_radius``: ``[rx, ry, rz]`` (or one number) in mm, >= 0, one positive."""
    values = value if isinstance(value, Sequence) and not isinstance(value, str) else [value]
    radius = tuple(v2._number(owner, "physical_radius", v) for v in values)
    if len(radius) == 1:
        radius *= 3
    if len(radius) != 3 or min(radius) < 0 or max(radius) <= 0:
        raise DesignError(f"{owner}: physical_radius is [rx, ry, rz] in mm, >= 0 with one positive, got {value!r}",
                          hint=_DOCS)
    return radius


def _voxel_size(owner: str, value) -> None:
    """``override_voxel_size``: accepted (fgslice samples the child itself, without a grid)."""
    if value is None:
        return
    sizes = value if isinstance(value, Sequence) and not isinstance(value, str) else [value]
    if len(sizes) not in (1, 3) or any(v2._number(owner, "override_voxel_size", v) <= 0 for v in sizes):
        raise DesignError(f"{owner}: override_voxel_size is [x, y, z] in mm, positive, got {value!r}", hint=_DOCS)


def _targets(owner: str, attributes, built: nodes.Node) -> tuple[list[str], bool]:
    """The fgslice channels of the child's attributes named by ``attributes`` (all of them
    when empty) and whether its materials' fractions are smoothed."""
    from fgslice.design.attributes import AttributeFields

    if isinstance(attributes, str) or not isinstance(attributes, Sequence):
        raise DesignError(f"{owner}: attributes is a list of attribute names (empty: all), got {attributes!r}",
                          hint=_DOCS)
    names = [_attribute_name(owner, a) for a in attributes]
    if not names:
        return list(AttributeFields(built).names), True
    channels = [c for n in names if n != "volume_fractions" for c in _resolver_channels(n, built)]
    if not channels and "volume_fractions" not in names:
        raise DesignError(f"{owner}: the child has none of the attributes {', '.join(names)}",
                          hint="set them on the child with set_attribute, or name the ones it has")
    return channels, "volume_fractions" in names


class AttributeBlend(v2.Node):
    """OpenVCAD 3's ``Blend(child, attributes, physical_radius, num_passes=1,
    override_voxel_size=None)``: the named attributes (all when the list is empty;
    ``VOLUME_FRACTIONS``: the materials) box-blurred ``num_passes`` times over
    ``physical_radius`` mm each side, inside the child (:mod:`fgslice.design.convolve`)."""

    def __init__(self, *args, **kwargs) -> None:
        super().__init__()
        child, self._attributes, radius, passes, voxel = v2._bind(
            "Blend", ("child", "attributes", "physical_radius", "num_passes", "override_voxel_size"), args, kwargs,
            {"num_passes": 1, "override_voxel_size": None})
        self._child = v2._child("Blend", child)
        self._radius = _radius("Blend", radius)
        if isinstance(passes, bool) or not isinstance(passes, numbers.Integral) or not 1 <= passes <= 8:
            raise DesignError(f"Blend: num_passes is a whole number from 1 to 8, got {passes!r}", hint=_DOCS)
        self._passes = int(passes)
        _voxel_size("Blend", voxel)

    def _build(self, convert) -> nodes.Node:
        from fgslice.design.convolve import Smoothed, box_stencil

        built = convert(self._child)
        channels, fractions = _targets("Blend", self._attributes, built)
        return Smoothed(built, *box_stencil(self._radius, self._passes), channels, fractions)


class ConvolveKernel:
    """Base of the convolution kernels: weights ``(2 rx + 1, 2 ry + 1, 2 rz + 1)``, indexed x, y, z."""

    weights: np.ndarray

    def get_radius_x(self) -> int:
        return (self.weights.shape[0] - 1) // 2

    def get_radius_y(self) -> int:
        return (self.weights.shape[1] - 1) // 2

    def get_radius_z(self) -> int:
        return (self.weights.shape[2] - 1) // 2


def _kernel_radii(owner: str, radii) -> tuple[int, int, int]:
    out = []
    for axis, r in zip(("rx", "ry", "rz"), radii):
        if isinstance(r, bool) or not isinstance(r, numbers.Integral) or not 0 <= r <= 10:
            raise DesignError(f"{owner}: {axis} is a whole number of taps from 0 to 10, got {r!r}", hint=_DOCS)
        out.append(int(r))
    return tuple(out)


class BoxKernel(ConvolveKernel):
    """``BoxKernel(radius)`` or ``BoxKernel(rx, ry, rz)``: equal weights on a
    ``(2 rx + 1) x (2 ry + 1) x (2 rz + 1)`` grid of taps (a uniform average)."""

    def __init__(self, *args) -> None:
        v2._overload("BoxKernel", args, {1: "radius", 3: "rx, ry, rz"})
        rx, ry, rz = _kernel_radii("BoxKernel", args * 3 if len(args) == 1 else args)
        self.weights = np.ones((2 * rx + 1, 2 * ry + 1, 2 * rz + 1))


class CustomKernel(ConvolveKernel):
    """``CustomKernel(weights, rx, ry, rz)``: explicit weights, a flat list of
    ``(2 rx + 1)(2 ry + 1)(2 rz + 1)`` numbers, x varying fastest, then y, then z."""

    def __init__(self, weights, rx, ry, rz) -> None:
        rx, ry, rz = _kernel_radii("CustomKernel", (rx, ry, rz))
        if isinstance(weights, str) or not isinstance(weights, Sequence):
            raise DesignError(f"CustomKernel: weights is a flat list of numbers, got {weights!r}", hint=_DOCS)
        values = [v2._number("CustomKernel", "a weight", w) for w in weights]
        shape = (2 * rz + 1, 2 * ry + 1, 2 * rx + 1)
        if len(values) != shape[0] * shape[1] * shape[2]:
            raise DesignError(f"CustomKernel: {len(values)} weights for a {shape[2]} x {shape[1]} x {shape[0]} kernel "
                              f"(rx = {rx}, ry = {ry}, rz = {rz}) that needs {shape[0] * shape[1] * shape[2]}")
        self.weights = np.asarray(values).reshape(shape).transpose(2, 1, 0)


class Convolve(v2.Node):
    """``Convolve(child, attributes, kernel, physical_radius, override_voxel_size=None)``:
    the named attributes (all when the list is empty; ``VOLUME_FRACTIONS``: the
    materials) replaced by the kernel's weighted mean, its taps spanning
    ``physical_radius`` mm each side, inside the child (:mod:`fgslice.design.convolve`)."""

    def __init__(self, *args, **kwargs) -> None:
        super().__init__()
        child, self._attributes, kernel, radius, voxel = v2._bind(
            "Convolve", ("child", "attributes", "kernel", "physical_radius", "override_voxel_size"), args, kwargs,
            {"override_voxel_size": None})
        self._child = v2._child("Convolve", child)
        if not isinstance(kernel, ConvolveKernel):
            raise DesignError(f"Convolve: kernel is a pv.BoxKernel or pv.CustomKernel, got {kernel!r}", hint=_DOCS)
        from fgslice.design.convolve import kernel_stencil

        self._stencil = kernel_stencil(kernel.weights, _radius("Convolve", radius))
        _voxel_size("Convolve", voxel)

    def _build(self, convert) -> nodes.Node:
        from fgslice.design.convolve import Smoothed

        built = convert(self._child)
        channels, fractions = _targets("Convolve", self._attributes, built)
        return Smoothed(built, *self._stencil, channels, fractions)


__all__ += ["AttributeBlend", "ConvolveKernel", "BoxKernel", "CustomKernel", "Convolve"]
