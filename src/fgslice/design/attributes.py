"""Process attributes: fields of process parameters (fan, flow, speed, temperature,
infill density) attached to parts of the design tree.

``attribute(NAME, "EXPR") { ... }`` grades one process parameter over its children, as
``fgrade`` grades materials: the expression is evaluated in the node's own frame (``d``
is its children's signed distance), and at any point of the part the nearest enclosing
attribute of that name decides (the children of a union own their points as for
materials: the first child containing the point, else the nearest one; ``intersection``
and ``difference`` take their first child's; two bodies mixed by a weight,
:class:`fgslice.design.mix.Mix`, blend theirs). Geometry and materials pass through
unchanged. Where no attribute of a name encloses a point, the slice's settings decide.

Units: ``temperature`` degrees Celsius; ``flow`` percent of the nominal extrusion;
``fan`` percent; ``speed`` percent of each feature's speed; ``infill_density`` percent;
``fuzzy_skin_thickness`` and ``fuzzy_skin_point_distance`` mm (outer walls,
:mod:`fgslice.toolpaths.fuzzy_skin`); the feature speeds of :data:`ROLE_SPEEDS` mm/s.
``flow_rate`` (OpenVCAD's spelling) is read as ``flow``.

Attributes of any other name (OpenVCAD 3's design-intent fields such as ``modulus`` or
``density``, the channels of a colour) can be attached with ``any_name=True``: they drive
nothing, ``fgslice check`` lists them, and converters
(:mod:`fgslice.design.attribute_ops`) can derive machine attributes from them.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from fgslice.design import nodes
from fgslice.design.attribute_ops import AttributeCarrier, AttributeOperator
from fgslice.design.membership import owners
from fgslice.design.mix import Mix
from fgslice.design.tile import Tiled
from fgslice.errors import DesignError, did_you_mean

ROLE_SPEEDS = {
    "external_perimeter_speed": ("External perimeter",),
    "perimeter_speed": ("Perimeter",),
    "infill_speed": ("Internal infill",),
    "solid_infill_speed": ("Solid infill", "Bottom solid infill"),
    "top_solid_infill_speed": ("Top solid infill",),
}
"""Absolute speed attributes (mm/s, PrusaSlicer's and OpenVCAD's names) -> the path roles
(``;TYPE:`` names) whose feed rate they set per segment, instead of the feature's speed
times ``speed``."""

OPENVCAD_MACHINE_NAMES = {"temperature": ("temperature", 1.0), "flow_rate": ("flow", 100.0),
                          "infill_density": ("infill_density", 1.0),
                          "fuzzy_skin_thickness": ("fuzzy_skin_thickness", 1.0),
                          "fuzzy_skin_point_distance": ("fuzzy_skin_point_distance", 1.0),
                          **{name: (name, 1.0) for name in ROLE_SPEEDS}}
"""OpenVCAD attribute name -> (fgslice attribute, factor from OpenVCAD's unit to fgslice's)."""

UNITS = {"temperature": "C", "flow": "%", "fan": "%", "speed": "%", "infill_density": "%",
         "fuzzy_skin_thickness": "mm", "fuzzy_skin_point_distance": "mm", **dict.fromkeys(ROLE_SPEEDS, "mm/s")}
"""Every attribute name with the unit of its values."""

ALIASES = {"flow_rate": "flow"}
"""Other spellings accepted for attribute names."""

INSTANTANEOUS = ("fan", "flow", "speed", *ROLE_SPEEDS)
"""Attributes that take effect at once, written per extrusion segment."""


def canonical_name(name: str, where: nodes.Where = nodes.NOWHERE, any_name: bool = False) -> str:
    """The attribute name ``name`` stands for (case-insensitive; aliases resolved);
    unknown names are refused unless ``any_name``."""
    key = str(name).strip().lower()
    key = ALIASES.get(key, key)
    if any_name and key:
        return key
    if key not in UNITS:
        known = list(UNITS) + list(ALIASES)
        raise DesignError(
            f"unknown attribute '{name}'",
            hint=did_you_mean(key, known) or "attributes: " + ", ".join(known),
            **where.error_kwargs(),
        )
    return key


class Attribute(AttributeCarrier):
    """``attribute(name, field) { children }``: the process parameter ``name`` graded by
    ``field`` (this node's frame) over the children, which keep their geometry and
    materials (several children act as their union). ``any_name``: accept a name that
    drives nothing (see the module docstring)."""

    kind = "attribute"

    def __init__(self, name: str, field: nodes.Field, children: Sequence[nodes.Node], where: nodes.Where = nodes.NOWHERE,
                 any_name: bool = False) -> None:
        super().__init__(children, where)
        self.name = canonical_name(name, where, any_name)
        self.any_name = any_name
        self.field = field
        self._body = self.children[0] if len(self.children) == 1 else nodes.Union(self.children, where)

    def values(self, x, y, z) -> np.ndarray:
        """The field at points of this node's frame (1-D arrays), float64."""
        d = self._body.sdf(x, y, z) if self.field.uses_d else None
        return np.array(self.field(x, y, z, d), dtype=float)


class AttributeFields:
    """The attributes of a node tree, evaluated at points of the root's frame.

    ``names`` lists the attribute names the tree uses, in the order they first appear.
    :meth:`values` gives NaN where no attribute of the name encloses a point. ``ranges``
    and ``cover`` are filled by the slicer's check
    (:func:`fgslice.machine.grading.checked_attributes`): each attribute's
    ``(min, max)`` over the part and the share of the part it covers (0-1).
    """

    def __init__(self, root: nodes.Node) -> None:
        self.root = root
        self.ranges: dict[str, tuple[float, float]] = {}
        self.cover: dict[str, float] = {}
        self._below: dict[int, frozenset[str]] = {}
        names: list[str] = []
        for node, *_ in nodes.walk(root):
            names.extend(n for n in _produced(node) if n not in names)
        self.names = tuple(names)
        self._collect(root)

    def _collect(self, root: nodes.Node) -> None:
        """For every node, the attribute names used in its subtree (post-order, no recursion)."""
        order = [node for node, *_ in nodes.walk(root)]
        for node in reversed(order):
            own = set(_produced(node))
            for child in node.children:
                own |= self._below[id(child)]
            self._below[id(node)] = frozenset(own)

    def values(self, name: str, x, y, z) -> np.ndarray:
        """Attribute ``name`` at points ``x, y, z`` (root frame, mm; broadcast, any shape);
        NaN where no attribute of that name encloses the point."""
        x, y, z = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (x, y, z)))
        shape = x.shape
        x, y, z = x.ravel(), y.ravel(), z.ravel()
        out = np.empty(x.size)
        for s in nodes._chunks(x.size):
            out[s] = self._values(self.root, name, x[s], y[s], z[s], np.full(len(x[s]), np.nan))
        return out.reshape(shape)

    def _values(self, node: nodes.Node, name: str, x, y, z, ctx: np.ndarray) -> np.ndarray:
        """The values at 1-D points of ``node``'s frame; ``ctx``: the enclosing attribute's."""
        if isinstance(node, AttributeOperator) and name in node.outputs:
            return node.evaluate(self, name, x, y, z, ctx)
        if isinstance(node, Attribute) and node.name == name:
            ctx = node.values(x, y, z)
        if name not in self._below[id(node)] or not node.children:
            return ctx
        if isinstance(node, (nodes.Affine, Tiled)):
            return self._values(node._body, name, *node.local(x, y, z), ctx)
        children = node.children
        if isinstance(node, (nodes.Intersection, nodes.Difference)) or len(children) == 1:
            return self._values(children[0], name, x, y, z, ctx)
        if isinstance(node, Mix):
            first, second = (self._values(child, name, x, y, z, ctx) for child in children)
            both = node.mixed(first, second, x, y, z)
            return np.where(np.isnan(first), second, np.where(np.isnan(second), first, both))
        owner = owners(children, x, y, z)  # the union's rule for materials, the same here
        out = ctx.copy()
        for i, child in enumerate(children):
            sel = np.flatnonzero(owner == i)
            if sel.size:
                out[sel] = self._values(child, name, x[sel], y[sel], z[sel], ctx[sel])
        return out


def _produced(node: nodes.Node) -> tuple[str, ...]:
    """The attribute names ``node`` itself sets."""
    if isinstance(node, Attribute):
        return (node.name,)
    return node.outputs if isinstance(node, AttributeOperator) else ()


def attribute_fields(design) -> AttributeFields | None:
    """The attributes of ``design`` (a node tree), or None when it has none."""
    root = getattr(design, "root", None)
    if not isinstance(root, nodes.Node):
        return None
    fields = AttributeFields(root)
    return fields if fields.names else None


def intent_temperature(root: nodes.Node, low: float, high: float, settings) -> str | None:
    """Why a ``temperature`` ranging ``low .. high`` C drives nothing on the machine of
    ``settings``, or None when it is the nozzle temperature there (and is checked
    against the machine's limits).

    Only OpenVCAD 3's attributes (attached by name, or derived by converters and
    resolvers) can be design intent: its ``TEMPERATURE`` is a field a design may carry
    for analysis or display (its functional-grading guide grades one over 0-10 C). On a
    profile without the temperature (foaming) dialect it drives nothing when the dialect
    commands no nozzle temperature (``template``) or when the whole range lies outside
    ``min_extrude_temperature .. max_nozzle_temperature``; a range reaching into the
    machine's is the nozzle temperature, and refused when it leaves it. On a foaming
    profile the temperature is what the machine grades: always driven, always checked."""
    if settings.dialect == "temperature" or not _openvcad3_only(root, "temperature"):
        return None
    if settings.dialect == "template":
        return "the template dialect commands no nozzle temperature, so the field stays design intent"
    lo, hi = limits(settings)["temperature"]
    if high < lo or low > hi:
        return (f"{low:.4g} .. {high:.4g} C is no nozzle temperature for this machine ({lo:.4g} .. {hi:.4g} C), so "
                "the field stays design intent (a foaming profile, dialect 'temperature', refuses it)")
    return None


def _openvcad3_only(root: nodes.Node, name: str) -> bool:
    """Whether every node of ``root``'s tree that sets attribute ``name`` is an OpenVCAD 3
    attribute (attached by name) or an attribute operator (converters, resolvers)."""
    setters = [n for n, *_ in nodes.walk(root) if name in _produced(n)]
    return bool(setters) and all(isinstance(n, AttributeOperator) or (isinstance(n, Attribute) and n.any_name)
                                 for n in setters)


def limits(settings) -> dict[str, tuple[float, float]]:
    """The machine's range of each attribute under ``settings``
    (:class:`fgslice.settings.Settings`): temperature from ``min_extrude_temperature`` to
    ``max_nozzle_temperature``; flow within ``min_flow_percent`` .. ``max_flow_percent``
    and no more than ``max_cross_section_mm2`` allows for the bead; fan 0-100; speed from
    1% to the share that brings the fastest feature to ``travel_speed``; infill density
    0-100; fuzzy skin thickness 0 to the bead width, point distance 0.1-100 mm; the
    speeds of :data:`ROLE_SPEEDS` 1 mm/s to ``travel_speed``."""
    fastest = max(settings.print_speed, settings.outer_wall_speed, settings.infill_speed, settings.first_layer_speed)
    return {
        "temperature": (settings.min_extrude_temperature, settings.max_nozzle_temperature),
        "flow": (settings.min_flow_percent,
                 min(settings.max_flow_percent, 100.0 * settings.max_cross_section_mm2 / settings.bead_area)),
        "fan": (0.0, 100.0),
        "speed": (1.0, 100.0 * settings.travel_speed / fastest),
        "infill_density": (0.0, 100.0),
        "fuzzy_skin_thickness": (0.0, settings.bead_width),
        "fuzzy_skin_point_distance": (0.1, 100.0),
        **dict.fromkeys(ROLE_SPEEDS, (1.0, settings.travel_speed)),
    }


def out_of_limits(name: str, low: float, high: float, settings) -> str | None:
    """Why attribute ``name`` ranging ``low .. high`` exceeds the machine's limits
    (:func:`limits`), with what to change; None when it fits."""
    lo, hi = limits(settings)[name]
    if low >= lo - 1e-9 and high <= hi + 1e-9:
        return None
    return (f"attribute '{name}' ranges {low:.4g} .. {high:.4g} {UNITS[name]} over the part, outside this "
            f"machine's {lo:.4g} .. {hi:.4g} {UNITS[name]}: change the attribute's expression or the profile's limits")


def drives(name: str, settings) -> str | None:
    """What attribute ``name`` commands on the machine of ``settings``
    (:class:`fgslice.settings.Settings`), None when it has no machine meaning."""
    if name not in UNITS:
        return None
    if name == "temperature":
        flow = f", with M221 from the '{settings.flow_model}' flow model" if settings.flow_model != "none" else ""
        return f"nozzle temperature states (M104, levels of {settings.temperature_step:g} C){flow}"
    if name == "infill_density":
        if settings.strategy == 2:
            return "nothing with strategy 2 (every face is filled densely); use strategy 1"
        return "the sparse infill's density (strategy 1)"
    if name in ROLE_SPEEDS:
        return f"the feed rate per segment of {' and '.join(ROLE_SPEEDS[name]).lower()} paths (F)"
    if name == "fuzzy_skin_thickness":
        return "fuzzy skin on outer walls: each point moved across the wall by up to this"
    if name == "fuzzy_skin_point_distance":
        return "fuzzy skin on outer walls: the distance between its points"
    return {"flow": "the extrusion per segment (E scaled)", "fan": "the part fan per segment (M106)",
            "speed": "the feed rate per segment (F scaled)"}[name]


INTENT_HINT = ("derive a machine attribute from it: wrap the part in pv.AttributeModifier with a "
               "LookupTableConverter or ExpressionConverter to temperature, flow_rate or infill_density")
"""What turns an attribute without machine meaning into one, for ``fgslice check``."""
