"""OpenVCAD 3's ``pyvcad_attribute_resolver`` module, as a design script imports it.

A registry of conversions (edges from a source attribute to a target attribute, each
with a factory of a fresh converter) and :func:`adapt`, which wraps a design in the
``AttributeModifier`` chain that gives it the attributes a machine needs:

* the chain for each target is a shortest one (fewest conversions) from the attributes
  the design already has; an edge applies once its ``required_inputs`` (default: its
  source) are present and its target is not; ``tags`` keep the edges sharing at least
  one tag, ``allowed_conversions`` the edges of those names; ``max_depth`` bounds the
  chain;
* among shortest chains the one of highest total ``priority`` wins; a tie is an
  :class:`AmbiguousPathError` naming the chains; no chain is a :class:`NoPathError`;
* targets are taken in order, each seeing what the earlier ones added.

OpenVCAD's bundled modules (foaming TPU / LW-PLA, J750 tables) register measured
tables that its documentation does not publish; they are refused by name, except
:func:`register_pla_conversions`, which registers the one table the documentation prints
(LW-PLA temperature -> flow rate, tag ``foaming_pla``) and leaves out its unpublished
density -> temperature table. Register the tables of your own filament with
:func:`register_conversion`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from collections.abc import Callable

from fgslice.compat import pyvcad as v2
from fgslice.errors import DesignError

_DOCS = "see the OpenVCAD 3 section of docs/language.md"

__all__ = [
    "register_conversion", "unregister_conversion", "list_conversions", "clear_conversions", "adapt", "list_modules",
    "ConversionEntry", "ResolverError", "NoPathError", "AmbiguousPathError", "register_pla_conversions",
]

PLA_FLOW_COMPENSATION = ((220, 1.42), (224, 1.23), (228, 1.08), (232, 0.98), (236, 0.86),
                         (240, 0.76), (244, 0.72), (248, 0.69), (252, 0.67), (256, 0.66))
"""LW-PLA's flow compensation, (temperature C, flow-rate factor), as OpenVCAD's attribute
modifier guide prints it."""

_BUNDLED = ("register_foaming_conversions", "register_tpu_conversions",
            "register_j750_shore_hardness_conversions", "register_j750_modulus_toughness_conversions",
            "generate_j750_modulus_toughness_lookup_table", "generate_j750_modulus_toughness_reachable_region_plot")


def __getattr__(name: str):
    if name.startswith("__"):
        raise AttributeError(name)
    if name in _BUNDLED:
        raise DesignError(f"pyvcad_attribute_resolver.{name} is not supported by fgslice: it registers OpenVCAD's "
                          "measured tables, which its documentation does not publish",
                          hint="register your filament's table with register_conversion(source, target, "
                               "lambda: pv.LookupTableConverter(...))")
    raise v2._unsupported("pyvcad_attribute_resolver", name)


class ResolverError(DesignError):
    """Base error of the attribute resolver."""


class NoPathError(ResolverError):
    """No chain of conversions reaches a target attribute."""


class AmbiguousPathError(ResolverError):
    """Several shortest chains of equal priority reach a target; ``paths`` lists them."""

    def __init__(self, message: str, paths=None) -> None:
        super().__init__(message, hint="give the preferred conversions a higher priority, or pass "
                                       "allowed_conversions / tags to adapt()")
        self.paths = list(paths or [])


@dataclass
class ConversionEntry:
    """One conversion: ``source`` -> ``target`` attribute names, ``converter_factory``
    (no arguments, returns a converter), ``name`` (default ``"source_to_target"``),
    ``priority`` (higher wins ties), ``tags``, ``required_inputs`` (default ``[source]``)."""

    source: str
    target: str
    converter_factory: Callable
    name: str | None = None
    priority: float = 0
    tags: list[str] = field(default_factory=list)
    required_inputs: list[str] | None = None

    def __post_init__(self) -> None:
        self.source, self.target = _name("source", self.source), _name("target", self.target)
        if not callable(self.converter_factory):
            raise ResolverError(f"register_conversion: converter_factory must be a callable returning a converter, "
                                f"got {self.converter_factory!r}", hint="e.g. lambda: pv.ExpressionConverter(...)")
        self.name = self.name or f"{self.source}_to_{self.target}"
        self.tags = list(self.tags or [])
        self.required_inputs = [_name("required_inputs", n) for n in (self.required_inputs or [self.source])]


def _name(what: str, value) -> str:
    if not isinstance(value, str) or not value.strip():
        raise ResolverError(f"register_conversion: {what} is an attribute name, got {value!r}")
    return value.strip().lower()


_REGISTRY: dict[str, ConversionEntry] = {}


def register_conversion(source, target, converter_factory, name=None, priority=0, tags=None,
                        required_inputs=None) -> str:
    """Register a conversion (replacing one of the same name); returns its name."""
    entry = ConversionEntry(source, target, converter_factory, name, priority, tags or [], required_inputs)
    _REGISTRY[entry.name] = entry
    return entry.name


def unregister_conversion(name) -> None:
    """Remove the conversion ``name``."""
    if name not in _REGISTRY:
        raise KeyError(name)
    del _REGISTRY[name]


def list_conversions() -> list[ConversionEntry]:
    """The registered conversions, in registration order."""
    return list(_REGISTRY.values())


def clear_conversions() -> None:
    """Remove every conversion."""
    _REGISTRY.clear()


def list_modules() -> list[str]:
    """The bundled conversion modules installed: none in fgslice (see the module notes)."""
    return []


def register_pla_conversions() -> None:
    """Register LW-PLA's temperature -> flow_rate conversion (:data:`PLA_FLOW_COMPENSATION`,
    linear, tag ``foaming_pla``). OpenVCAD's density -> temperature table for LW-PLA is not
    published, so no conversion reaches temperature from density."""
    from fgslice.compat import pyvcad_v3 as pv

    def converter():
        entries = [pv.LookupTableEntry(t, t, flow) for t, flow in PLA_FLOW_COMPENSATION]
        return pv.LookupTableConverter([pv.DefaultAttributes.TEMPERATURE], [pv.DefaultAttributes.FLOW_RATE], entries,
                                       pv.InterpolationMode.LINEAR)

    register_conversion("temperature", "flow_rate", converter, name="foaming_pla_temperature_to_flow_rate",
                        tags=["foaming_pla"])


def _chains(available: frozenset[str], target: str, edges: list[ConversionEntry], max_depth: int):
    """Every shortest chain of ``edges`` from ``available`` to ``target`` (breadth first,
    one chain length at a time; the same edges in another order count once)."""
    level = [(available, ())]
    for _ in range(max_depth):
        found, following = {}, []
        for have, chain in level:
            for edge in edges:
                if edge.target in have or not set(edge.required_inputs) <= have:
                    continue
                if edge.target == target:
                    found.setdefault(frozenset(e.name for e in chain + (edge,)), chain + (edge,))
                else:
                    following.append((have | {edge.target}, chain + (edge,)))
        if found or not following:
            return list(found.values())
        level = following
    return []


def adapt(design, target_attributes, allowed_conversions=None, tags=None, max_depth=10):
    """``design`` wrapped in the ``AttributeModifier`` chains that give it
    ``target_attributes`` (see the module notes); the design itself when it has them."""
    from fgslice.compat.pyvcad_v3 import AttributeModifier, attribute_list

    if not isinstance(design, v2.Node):
        raise ResolverError(f"adapt: the design is a pyvcad node, got {type(design).__name__}")
    if isinstance(target_attributes, str):
        target_attributes = [target_attributes]
    edges = [e for e in _REGISTRY.values()
             if (allowed_conversions is None or e.name in allowed_conversions)
             and (not tags or set(tags) & set(e.tags))]
    result = design
    for target in (_name("target_attributes", t) for t in target_attributes):
        available = frozenset(attribute_list(result))
        if target in available:
            continue
        chains = _chains(available, target, edges, int(max_depth))
        if not chains:
            raise NoPathError(f"adapt: no chain of registered conversions reaches '{target}' from the design's "
                              f"attributes ({', '.join(sorted(available)) or 'none'})",
                              hint="register_conversion(...) one that does (fgslice registers none of OpenVCAD's "
                                   "unpublished tables, such as LW-PLA's density -> temperature)")
        best = max(sum(e.priority for e in chain) for chain in chains)
        top = [chain for chain in chains if sum(e.priority for e in chain) == best]
        if len(top) > 1:
            described = "; ".join(" -> ".join(e.name for e in chain) for chain in top)
            raise AmbiguousPathError(f"adapt: {len(top)} chains of equal priority reach '{target}': {described}",
                                     paths=top)
        for entry in top[0]:
            result = AttributeModifier(entry.converter_factory(), result)
    return result
