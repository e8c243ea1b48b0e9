"""OpenVCAD's ``j750_materials``: the Stratasys J750 inkjet resins as filament colours.

A J750 design names resins (``VeroYellow``, ``Agilus30Mgn``, ``M.Cleanser``...); a
filament printer has filaments instead, so each resin is printed as the fgslice material
of its colour: the colour word of its name (``Cyan``/``Cyn``, ``Magenta``/``Mgn``,
``Yellow``/``Yl``, ``Black``/``Blk``, ``White``/``Wht``, ``Clear``/``Clr``, ``Gray``/``Gry``)
for the Vero (rigid) and Agilus (flexible) families, ``liquid`` for the cleanser (a
non-curing fluid) and ``support`` for the support resins (``SUP705``, ``SUP706``). Two
resins of one colour would print as one filament, so the second is an error naming both.
"""

from __future__ import annotations

import re

from fgslice.errors import DesignError

_COLOURS = (
    ("cyan", r"cyan|cyn"), ("magenta", r"magenta|mgn"), ("yellow", r"yellow|yl"), ("black", r"black|blk"),
    ("white", r"white|wht"), ("clear", r"clear|clr"), ("gray", r"gr[ae]y|gry"),
)
_FAMILY = re.compile(r"^(vero|agilus30)(?P<colour>[a-z]+?)(plus|-v)?$")


def filament_of(resin: str) -> str:
    """The fgslice material printing the J750 resin ``resin``; DesignError when unknown."""
    key = resin.strip().lower()
    if "cleanser" in key:
        return "liquid"
    if re.fullmatch(r"sup\d+", key):
        return "support"
    found = _FAMILY.match(key.replace(" ", ""))
    if found:
        for name, pattern in _COLOURS:
            if re.fullmatch(pattern, found["colour"].removeprefix("pure").removeprefix("ultra")):
                return name
    raise DesignError(f"j750_materials: no filament stands for the resin '{resin}'",
                      hint="the Vero and Agilus30 colours, M.Cleanser and SUP705/706 are known; "
                           "name fgslice materials with default_materials.id(name) instead")


def check_distinct(chosen: dict[str, str], resin: str, filament: str) -> None:
    """Refuse a second resin that would print as the filament of an earlier one."""
    for other, used in chosen.items():
        if used == filament and other != resin.lower():
            raise DesignError(f"j750_materials: '{resin}' and '{other}' would both print as '{filament}'",
                              hint="a filament printer has one filament per colour: use one of the two resins")
