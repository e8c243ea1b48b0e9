"""OpenVCAD's ``pyvcad_rendering`` as fgslice runs a design script: no window, no wizard.

``Render(root, materials)`` and ``Export(root, materials)`` record ``root`` as the
design; the ``materials`` argument is accepted and not used (materials are resolved by
name through fgslice's library). Other names raise a DesignError naming them.
"""

from __future__ import annotations

from fgslice.compat import context
from fgslice.compat.pyvcad import Node
from fgslice.errors import DesignError

__all__ = ["Render", "Export", "render", "export"]


def __getattr__(name: str):
    if name.startswith("__"):
        raise AttributeError(name)
    raise DesignError(f"pyvcad_rendering.{name} is not supported by fgslice",
                      hint="only Render and Export are: they name the design to slice")


def _record(kind: str, vcad_object, into: str) -> None:
    run = context.current()
    if run is None:
        raise DesignError(f"pyvcad_rendering.{kind} records a design only in a script that fgslice runs",
                          hint="run the script with: fgslice slice design.py")
    if not isinstance(vcad_object, Node):
        raise DesignError(f"{kind} takes a pyvcad node, got {type(vcad_object).__name__}")
    getattr(run, into).append((vcad_object, context.site()))


def Render(vcad_object, materials=None) -> None:  # noqa: N802 (OpenVCAD's name)
    """Record ``vcad_object`` as the design (OpenVCAD opens a viewer window here)."""
    _record("Render", vcad_object, "rendered")


def Export(vcad_object, materials=None) -> None:  # noqa: N802 (OpenVCAD's name)
    """Record ``vcad_object`` as the design; an exported root wins over a rendered one."""
    _record("Export", vcad_object, "exported")


render = Render
export = Export
