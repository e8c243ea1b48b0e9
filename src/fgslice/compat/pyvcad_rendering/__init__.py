"""OpenVCAD's ``pyvcad_rendering`` as fgslice runs a design script: no window, no files.

OpenVCAD's viewer (``Render``), its off-screen images and animations
(``Render_Image``, ``Render_Sweep_Animation``, ``Render_Turntable_Animation``), its
exports (``Export``, ``vtk_export.export_iso_surface_vtk``, ``export_volume_vtk``) all
take the design's root: here they record it as the design to slice and write nothing.
An exported root wins over a rendered one. Their other arguments (materials, sizes, file
paths) are accepted and not used. The names are importable from the package and from
its modules, as in OpenVCAD (``pyvcad_rendering.render.Render``). Other names raise a
DesignError naming them.
"""

from __future__ import annotations

from fgslice.compat.pyvcad_rendering import export, render, vtk_export
from fgslice.compat.pyvcad_rendering.export import Export
from fgslice.compat.pyvcad_rendering.render import (
    Render,
    Render_Image,
    Render_Sweep_Animation,
    Render_Turntable_Animation,
    refuse,
)

__all__ = ["Render", "Render_Image", "Render_Sweep_Animation", "Render_Turntable_Animation", "Export", "render",
           "export", "vtk_export"]

MODULES = {"render": render, "export": export, "vtk_export": vtk_export}
"""The package's modules, by the name a script imports them under (``pyvcad_rendering.<name>``)."""


def __getattr__(name: str):
    return refuse("pyvcad_rendering", name)
