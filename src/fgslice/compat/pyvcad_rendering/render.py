"""``pyvcad_rendering.render``: OpenVCAD's viewer and off-screen renders, each naming the
design to slice (see :mod:`fgslice.compat.pyvcad_rendering`)."""

from __future__ import annotations

from fgslice.compat import context
from fgslice.compat.pyvcad import Node
from fgslice.errors import DesignError

__all__ = ["Render", "Render_Image", "Render_Sweep_Animation", "Render_Turntable_Animation"]


def refuse(module: str, name: str):
    """A module ``__getattr__``'s answer for ``name``: AttributeError for dunders, else a DesignError."""
    if name.startswith("__"):
        raise AttributeError(name)
    raise DesignError(f"{module}.{name} is not supported by fgslice",
                      hint="Render, Render_Image, the animations and the exports name the design to slice")


def record(kind: str, vcad_object, into: str) -> None:
    """Record ``vcad_object`` in the running script's ``into`` list (``rendered`` or ``exported``)."""
    run = context.current()
    if run is None:
        raise DesignError(f"pyvcad_rendering.{kind} records a design only in a script that fgslice runs",
                          hint="run the script with: fgslice slice design.py")
    if not isinstance(vcad_object, Node):
        raise DesignError(f"{kind} takes a pyvcad node, got {type(vcad_object).__name__}")
    getattr(run, into).append((vcad_object, context.site()))


def Render(vcad_object, materials=None) -> None:  # noqa: N802 (OpenVCAD's name)
    """Record ``vcad_object`` as the design (OpenVCAD opens a viewer window here)."""
    record("Render", vcad_object, "rendered")


def Render_Image(vcad_object, *args, **kwargs) -> None:  # noqa: N802 (OpenVCAD's name)
    """Record ``vcad_object`` as the design (OpenVCAD writes an image here)."""
    record("Render_Image", vcad_object, "rendered")


def Render_Sweep_Animation(vcad_object, *args, **kwargs) -> None:  # noqa: N802 (OpenVCAD's name)
    """Record ``vcad_object`` as the design (OpenVCAD writes a sweep animation here)."""
    record("Render_Sweep_Animation", vcad_object, "rendered")


def Render_Turntable_Animation(vcad_object, *args, **kwargs) -> None:  # noqa: N802 (OpenVCAD's name)
    """Record ``vcad_object`` as the design (OpenVCAD writes a turntable animation here)."""
    record("Render_Turntable_Animation", vcad_object, "rendered")


def __getattr__(name: str):
    return refuse("pyvcad_rendering.render", name)
