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

import enum
import numbers
import re
from collections.abc import Callable, Sequence

import numpy as np

from fgslice import __version__
from fgslice.compat import context
from fgslice.compat import pyvcad as v2
from fgslice.compat.numba_standin import CFunc
from fgslice.design import api, nodes
from fgslice.design.attribute_ops import AverageFractions, ConvertAttributes, Reducer, ResolveConflicts
from fgslice.design.attributes import ROLE_SPEEDS, Attribute
from fgslice.design.expressions import compile_expression
from fgslice.errors import DesignError

_DOCS = "see the OpenVCAD 3 section of docs/language.md"

__all__ = [
    "version", "DefaultAttributes", "FloatAttribute", "Vec3Attribute", "Vec4Attribute", "VolumeFractionsAttribute",
    "Identity", "BBoxUnion", "BBoxIntersection", "Torus", "AttributeModifier", "LookupTableEntry",
    "LookupTableConverter", "ExpressionConverter", "InterpolationMode", "resolvers", "Vec4",
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

    def __getattr__(self, name: str) -> str:
        if name in self._NAMES:
            return name.lower()
        if name.startswith("__"):
            raise AttributeError(name)
        raise v2._unsupported("DefaultAttributes", name)


DefaultAttributes = _Names()

MACHINE_NAMES = {"temperature": ("temperature", 1.0), "flow_rate": ("flow", 100.0),
                 "infill_density": ("infill_density", 1.0),
                 "fuzzy_skin_thickness": ("fuzzy_skin_thickness", 1.0),
                 "fuzzy_skin_point_distance": ("fuzzy_skin_point_distance", 1.0),
                 **{name: (name, 1.0) for name in ROLE_SPEEDS}}
"""OpenVCAD attribute name -> (fgslice attribute, factor from OpenVCAD's unit to fgslice's)."""


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


class _Attribute:
    """Base of the attribute types: fields kept as given, attached by ``set_attribute``."""

    def __getattr__(self, name: str):
        if name.startswith("__"):
            raise AttributeError(name)
        raise v2._unsupported(type(self).__name__, name)


class FloatAttribute(_Attribute):
    """``FloatAttribute(value)``: a constant, an expression string of ``x, y, z, d`` (and
    ``rho, phic, r, theta, phis``) or a ``@cfunc`` of ``(x, y, z, d)``."""

    def __init__(self, *args) -> None:
        v2._overload("FloatAttribute", args, {1: "definition"})
        self.field = _component("FloatAttribute", "the definition", args[0])

    def to_field(self) -> float | str | Callable:
        """The field as fgslice's design nodes take it: a float (constant), an expression
        string, or a vectorized callable ``f(x, y, z, d=None) -> ndarray`` (mm; the
        function sees ``d`` NaN when it is not given)."""
        return self.field


class _Vector(_Attribute):
    """A vector attribute: one scalar field per channel."""

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
        v2._overload(self._owner, args, {len(self._channels): ", ".join(self._channels)})
        self.fields = tuple(_component(self._owner, c, a) for c, a in zip(self._channels, args))

    def to_fields(self) -> tuple:
        """Each channel's field, as :meth:`FloatAttribute.to_field`."""
        return self.fields


class Vec3Attribute(_Vector):
    """``Vec3Attribute(x, y, z)``: three channels (``COLOR_RGB``: red, green, blue in 0-1)."""

    _owner, _channels = "Vec3Attribute", ("x", "y", "z")


class Vec4Attribute(_Vector):
    """``Vec4Attribute(r, g, b, a)``: four channels (``COLOR_RGBA``: linear RGBA in 0-1)."""

    _owner, _channels = "Vec4Attribute", ("r", "g", "b", "a")


class VolumeFractionsAttribute(_Attribute):
    """``VolumeFractionsAttribute([(field, material id), ...])`` or
    ``VolumeFractionsAttribute([fields], [material ids])``: each field is the fraction of
    its material (ids from ``default_materials.id(name)``)."""

    def __init__(self, *args) -> None:
        v2._overload("VolumeFractionsAttribute", args, {1: "[(field, material), ...]", 2: "fields, materials"})
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
        self.fields, self.materials = [], []
        for field, material in pairs:
            if not isinstance(material, v2.MaterialId):
                raise DesignError("VolumeFractionsAttribute: a material is an id from default_materials.id(name), "
                                  f"got {material!r}", hint=_DOCS)
            self.fields.append(_component("VolumeFractionsAttribute", "a fraction", field))
            self.materials.append(material.name)
        if len(set(self.materials)) != len(self.materials):
            raise DesignError("VolumeFractionsAttribute: a material appears twice")


def set_attribute(node: v2.Node, name, attribute) -> None:
    """``node.set_attribute(name, attribute)``: attach (or replace) the attribute ``name``."""
    key = _attribute_name("set_attribute", name)
    if isinstance(attribute, VolumeFractionsAttribute) != (key == "volume_fractions"):
        raise DesignError(f"set_attribute: '{key}' takes a "
                          f"{'VolumeFractionsAttribute' if key == 'volume_fractions' else 'Float, Vec3 or Vec4 attribute'}"
                          f", got {type(attribute).__name__}", hint=_DOCS)
    if not isinstance(attribute, _Attribute):
        raise DesignError(f"set_attribute: an attribute is a pyvcad FloatAttribute, Vec3Attribute, Vec4Attribute or "
                          f"VolumeFractionsAttribute, got {type(attribute).__name__}", hint=_DOCS)
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
                built = Attribute(channel, nodes.Field(_node_field(field)), (built,), any_name=True)
    return built


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
    axis to the tube's centre, tube radius ``r2`` (mm)."""

    def __init__(self, *args, **kwargs) -> None:
        r1, r2 = (v2._number("Torus", n, v) for n, v in zip(("r1", "r2"), v2._bind("Torus", ("r1", "r2"), args, kwargs, {})))
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
    """``LookupTableEntry(input, output)`` or ``LookupTableEntry(input_low, input_high,
    output)``: one input value or range and its output value(s) (a number, or a list of
    numbers, one per output attribute)."""

    def __init__(self, *args) -> None:
        v2._overload("LookupTableEntry", args, {2: "input, output", 3: "input_low, input_high, output"})
        if any(isinstance(a, Sequence) and not isinstance(a, str) for a in args[:-1]):
            raise DesignError("LookupTableEntry with several inputs is not supported by fgslice", hint=_DOCS)
        low = v2._number("LookupTableEntry", "input", args[0])
        high = v2._number("LookupTableEntry", "input_high", args[1]) if len(args) == 3 else low
        if high < low:
            raise DesignError(f"LookupTableEntry: input_high {high:g} is below input_low {low:g}")
        output = args[-1]
        outputs = output if isinstance(output, Sequence) and not isinstance(output, str) else [output]
        if any(isinstance(o, (v2.Vec3, Vec4, dict)) for o in outputs):
            raise DesignError("LookupTableEntry: fgslice's lookup tables give numbers (float attributes), not vectors "
                              "or volume fractions", hint=_DOCS)
        self.low, self.high = low, high
        self.outputs = tuple(v2._number("LookupTableEntry", "output", o) for o in outputs)


def _names(owner: str, what: str, names) -> tuple[str, ...]:
    if isinstance(names, str) or not isinstance(names, Sequence) or not names:
        raise DesignError(f"{owner}: {what} is a list of attribute names", hint=_DOCS)
    out = tuple(_attribute_name(owner, n) for n in names)
    vector = [n for n in out if n in ("volume_fractions", "color_rgb", "color_rgba")]
    if vector:
        raise DesignError(f"{owner}: '{vector[0]}' is not a float attribute; fgslice converts float attributes only",
                          hint=_DOCS)
    return out


class _Converter:
    """Base of the converters: input and output attribute names, a function of arrays."""

    inputs: tuple[str, ...]
    outputs: tuple[str, ...]

    def __getattr__(self, name: str):
        if name.startswith("__"):
            raise AttributeError(name)
        raise v2._unsupported(type(self).__name__, name)

    def convert(self, values: list[np.ndarray]) -> list[np.ndarray]:
        raise NotImplementedError


class LookupTableConverter(_Converter):
    """``LookupTableConverter(input_attributes, output_attributes, entries, mode=STEP)``:
    one input attribute; LINEAR interpolates between the entries' inputs (held flat beyond
    the first and last), STEP gives the value of the last entry whose input (low end) is
    at most the point's (the first entry below it)."""

    def __init__(self, input_attributes, output_attributes, entries, mode=InterpolationMode.STEP) -> None:
        owner = "LookupTableConverter"
        self.inputs = _names(owner, "input_attributes", input_attributes)
        self.outputs = _names(owner, "output_attributes", output_attributes)
        if len(self.inputs) != 1:
            raise DesignError(f"{owner} with {len(self.inputs)} input attributes is not supported by fgslice",
                              hint="use one input attribute, or an ExpressionConverter")
        if not isinstance(mode, InterpolationMode):
            raise DesignError(f"{owner}: mode is pv.InterpolationMode.STEP or .LINEAR, got {mode!r}")
        if isinstance(entries, str) or not isinstance(entries, Sequence) or not entries or not all(
                isinstance(e, LookupTableEntry) for e in entries):
            raise DesignError(f"{owner}: entries is a list of pv.LookupTableEntry", hint=_DOCS)
        bad = [e for e in entries if len(e.outputs) != len(self.outputs)]
        if bad:
            raise DesignError(f"{owner}: an entry gives {len(bad[0].outputs)} value(s) for "
                              f"{len(self.outputs)} output attribute(s)")
        ordered = sorted(entries, key=lambda e: e.low)
        if mode is InterpolationMode.LINEAR:
            self._x = np.array([v for e in ordered for v in ((e.low,) if e.low == e.high else (e.low, e.high))])
            self._y = np.array([o for e in ordered for o in ([e.outputs] if e.low == e.high else [e.outputs] * 2)])
        else:
            self._x = np.array([e.low for e in ordered])
            self._y = np.array([e.outputs for e in ordered])
        self.mode = mode

    def convert(self, values):
        t = values[0]
        if self.mode is InterpolationMode.LINEAR:
            return [np.interp(t, self._x, self._y[:, j]) for j in range(len(self.outputs))]
        index = np.clip(np.searchsorted(self._x, t, side="right") - 1, 0, len(self._x) - 1)
        return [np.where(np.isfinite(t), self._y[index, j], np.nan) for j in range(len(self.outputs))]


class ExpressionConverter(_Converter):
    """``ExpressionConverter(input_attributes, output_attributes, expressions)``: each
    output is an expression of the input attributes' names (at most four inputs)."""

    _SLOTS = ("x", "y", "z", "d")

    def __init__(self, input_attributes, output_attributes, expressions) -> None:
        owner = "ExpressionConverter"
        self.inputs = _names(owner, "input_attributes", input_attributes)
        self.outputs = _names(owner, "output_attributes", output_attributes)
        if len(self.inputs) > len(self._SLOTS):
            raise DesignError(f"{owner}: fgslice converts at most {len(self._SLOTS)} input attributes at once")
        if isinstance(expressions, str) or not isinstance(expressions, Sequence) or len(expressions) != len(self.outputs):
            raise DesignError(f"{owner}: give one expression string per output attribute", hint=_DOCS)
        where = context.site()
        pattern = re.compile(r"\b(" + "|".join(re.escape(n) for n in self.inputs) + r")\b")
        slots = dict(zip(self.inputs, self._SLOTS))
        self._expressions = []
        for text in expressions:
            if not isinstance(text, str):
                raise DesignError(f"{owner}: an expression is a string, got {text!r}")
            self._check_names(text)
            compiled = compile_expression(pattern.sub(lambda m: slots[m.group(1)], text),
                                          file=where.file, line=where.line or 1)
            self._expressions.append(compiled)

    def _check_names(self, text: str) -> None:
        coordinates = {"x", "y", "z", "d", "rho", "phic", "r", "theta", "phis"} - set(self.inputs)
        used = set(re.findall(r"\b[A-Za-z_]\w*\b", text)) & coordinates
        if used:
            raise DesignError(f"ExpressionConverter: '{sorted(used)[0]}' is not one of the input attributes "
                              f"({', '.join(self.inputs)})", hint="a converter's expressions read its inputs only")

    def convert(self, values):
        padded = list(values) + [np.zeros_like(values[0])] * (len(self._SLOTS) - len(values))
        return [e(*padded[:3], padded[3]) if "d" in e.variables else e(*padded[:3]) for e in self._expressions]


class AttributeModifier(v2.Node):
    """``AttributeModifier(converter, child)``: the converter's output attributes, computed
    from the child's input attributes at each point, over the child."""

    def __init__(self, converter, child=None) -> None:
        super().__init__()
        if not isinstance(converter, _Converter):
            raise DesignError(f"AttributeModifier: the converter is a pv.LookupTableConverter or pv.ExpressionConverter, "
                              f"got {type(converter).__name__}", hint=_DOCS)
        self._converter = converter
        self._child = None if child is None else v2._child("AttributeModifier", child)

    def set_child(self, child) -> None:
        """The node whose attributes are converted."""
        self._child = v2._child("AttributeModifier", child)

    def _build(self, convert) -> nodes.Node:
        if self._child is None:
            raise DesignError("AttributeModifier has no child", hint="give it with set_child(node)")
        conv = self._converter
        inputs = [_fgslice_name(n) for n in conv.inputs]
        outputs = [_fgslice_name(n) for n in conv.outputs]

        def function(values):
            converted = conv.convert([v / factor for v, (_, factor) in zip(values, inputs)])
            return [np.asarray(c, dtype=float) * factor for c, (_, factor) in zip(converted, outputs)]

        return ConvertAttributes([n for n, _ in inputs], [n for n, _ in outputs], function, convert(self._child))

