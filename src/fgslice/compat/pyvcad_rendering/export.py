"""``pyvcad_rendering.export``: OpenVCAD's export names the design to slice (see
:mod:`fgslice.compat.pyvcad_rendering`)."""

from __future__ import annotations

from fgslice.compat.pyvcad_rendering.render import record, refuse

__all__ = ["Export"]


def Export(vcad_object, *args, **kwargs) -> None:  # noqa: N802 (OpenVCAD's name)
    """Record ``vcad_object`` as the design; an exported root wins over a rendered one."""
    record("Export", vcad_object, "exported")


def __getattr__(name: str):
    return refuse("pyvcad_rendering.export", name)
