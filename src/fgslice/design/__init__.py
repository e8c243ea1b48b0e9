"""Design input: the .vcad language, expressions, geometry and material nodes, meshes.

Entry points: :func:`load_design` (a .vcad file), :func:`parse_design` (.vcad text),
:mod:`fgslice.design.api` (the same trees built in Python) and :func:`check_design`.
"""

from fgslice.design import api
from fgslice.design.check import CheckReport, check_design, format_report
from fgslice.design.language import load_design, parse_design
from fgslice.design.materials import MaterialLibrary, builtin_library, load_library
from fgslice.design.nodes import NodeDesign

__all__ = [
    "api",
    "load_design",
    "parse_design",
    "check_design",
    "format_report",
    "CheckReport",
    "MaterialLibrary",
    "builtin_library",
    "load_library",
    "NodeDesign",
]
