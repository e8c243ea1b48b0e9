"""A machine profile's tables from a design's attributes to machine attributes.

A design may carry attributes no machine drives (OpenVCAD's ``MODULUS``, ``DENSITY``,
``SHORE_HARDNESS``, or any name of its own). What they mean for a given filament is
measured for that filament, so the profile holds the conversion, in the setting
``attribute_tables``::

    attribute_tables = "density -> temperature: 0.40 250, 0.60 235, 1.20 205; shore_hardness -> flow_rate: 60 1.3, 95 0.9"

Each table, ``;``-separated, is ``source -> target: key value, key value, ...``: at least
two rows of two numbers, keys strictly increasing, read linearly between rows and held
flat beyond the ends (OpenVCAD's ``LookupTableConverter`` in ``LINEAR`` mode). The target
is one of fgslice's machine attributes (:data:`~fgslice.design.attributes.UNITS`:
temperature C, flow %, fan %, speed %, infill_density %, fuzzy skin mm, feature speeds
mm/s) or OpenVCAD's name for one (``flow_rate``, a multiplier: 1 is 100 %). Names are
case-insensitive.

:func:`apply_attribute_tables` wraps the design's root in one
:class:`~fgslice.design.attribute_ops.ConvertAttributes` per table whose source the
design sets and whose target it does not: a conversion in the design itself (an
``AttributeModifier``) wins over the profile's.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from fgslice.design import lookup_tables, nodes
from fgslice.design.attribute_ops import ConvertAttributes
from fgslice.design.attributes import OPENVCAD_MACHINE_NAMES, UNITS, attribute_fields
from fgslice.errors import SettingsError

_HINT = "for example --set attribute_tables='density -> temperature: 0.4 250, 1.2 205'"
_NAME = re.compile(r"[a-z_][a-z0-9_.]*")


@dataclass(frozen=True)
class AttributeTable:
    """``target`` (an fgslice machine attribute) from ``source`` by the rows ``keys`` ->
    ``values`` (``values`` already in the target's fgslice unit)."""

    source: str
    target: str
    keys: np.ndarray
    values: np.ndarray

    def __call__(self, inputs: list[np.ndarray]) -> list[np.ndarray]:
        """The target at the source values ``inputs[0]`` (NaN where the source is NaN)."""
        return lookup_tables.linear(self.keys, self.values[:, None], inputs[0])


def parse_attribute_tables(text: str) -> list[AttributeTable]:
    """The tables of an ``attribute_tables`` setting (see the module notes).

    Raises:
        SettingsError: a table that is not ``source -> target: key value, ...`` with two
            or more rows, increasing finite keys, finite values, a machine attribute as
            target, or two tables for one target.
    """
    tables: list[AttributeTable] = []
    for part in (p.strip() for p in text.split(";")):
        if not part:
            continue
        table = _table(part)
        if any(t.target == table.target for t in tables):
            raise SettingsError(f"attribute_tables: two tables give '{table.target}'", hint="keep one of them")
        tables.append(table)
    return tables


def _table(part: str) -> AttributeTable:
    head, colon, rows = part.partition(":")
    source, arrow, target = head.partition("->")
    source, target = source.strip().lower(), target.strip().lower()
    if not colon or not arrow or not _NAME.fullmatch(source) or not _NAME.fullmatch(target):
        raise SettingsError(f"attribute_tables: '{part}' is not 'source -> target: key value, key value, ...'",
                            hint=_HINT)
    name, factor = OPENVCAD_MACHINE_NAMES.get(target, (target, 1.0))
    if name not in UNITS:
        raise SettingsError(f"attribute_tables: '{target}' is no machine attribute",
                            hint=f"the target is one of {', '.join(sorted(UNITS))} or flow_rate")
    if source in (target, name):
        raise SettingsError(f"attribute_tables: '{part}' converts an attribute to itself", hint=_HINT)
    try:
        pairs = np.array([[float(v) for v in row.split()] for row in rows.split(",")], dtype=float)
    except ValueError:
        pairs = np.empty((0, 0))
    if pairs.ndim != 2 or pairs.shape[1:] != (2,) or len(pairs) < 2 or not np.isfinite(pairs).all():
        raise SettingsError(f"attribute_tables: the rows of '{source} -> {target}' are not two or more "
                            "'key value' pairs of numbers", hint=_HINT)
    if not (np.diff(pairs[:, 0]) > 0).all():
        raise SettingsError(f"attribute_tables: the keys of '{source} -> {target}' must increase", hint=_HINT)
    return AttributeTable(source, name, pairs[:, 0], pairs[:, 1] * factor)


def apply_attribute_tables(design, settings):
    """``design`` with the profile's ``attribute_tables`` applied (see the module notes),
    or ``design`` itself when none applies."""
    tables = parse_attribute_tables(getattr(settings, "attribute_tables", ""))
    fields = attribute_fields(design) if tables else None
    if fields is None:
        return design
    root = design.root
    for table in tables:
        if table.source in fields.names and table.target not in fields.names:
            root = ConvertAttributes([table.source], [table.target], table, root)
    if root is design.root:
        return design
    return nodes.NodeDesign(root, design.library, hint_bounds=design.hint_bounds, voxel_size=design.voxel_size,
                            section_spacing=design.section_spacing, source=design.source)


def profile_targets(design, source: str) -> list[str]:
    """The machine attributes the profile's tables give from ``source`` in ``design`` (as
    :func:`apply_attribute_tables` returned it)."""
    targets, node = [], getattr(design, "root", None)
    while isinstance(node, ConvertAttributes) and isinstance(node.function, AttributeTable):
        if node.function.source == source:
            targets.append(node.function.target)
        node = node._body
    return targets
