"""``pyvcad_rendering.vtk_export``: OpenVCAD's VTK exports name the design to slice (see
:mod:`fgslice.compat.pyvcad_rendering`)."""

from __future__ import annotations

from fgslice.compat.pyvcad_rendering.render import record, refuse

__all__ = ["export_iso_surface_vtk", "export_volume_vtk"]


def export_iso_surface_vtk(vcad_object, *args, **kwargs) -> None:
    """Record ``vcad_object`` as the design (OpenVCAD writes its surface as VTK here)."""
    record("export_iso_surface_vtk", vcad_object, "exported")


def export_volume_vtk(vcad_object, *args, **kwargs) -> None:
    """Record ``vcad_object`` as the design (OpenVCAD writes its sampled volume as VTK here)."""
    record("export_volume_vtk", vcad_object, "exported")


def __getattr__(name: str):
    return refuse("pyvcad_rendering.vtk_export", name)
