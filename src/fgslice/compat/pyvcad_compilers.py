"""OpenVCAD's ``pyvcad_compilers`` as fgslice runs a design script: a compiler names the design.

OpenVCAD's compilers turn a design into what a machine prints: bitmap stacks for inkjet
printers (``GrayscaleCompiler``, ``MaterialInkjetCompiler``, ``ColorInkjetCompiler``,
``DirectMaterialCompiler``, ``GCVFExporter``, ``MyersonCompiler``), meshes
(``MeshCompiler``), vat-printer images (``VatCompiler``), slicer projects
(``PrusaSlicerProjectCompiler``, ...). In a script that fgslice slices, the print is
fgslice's G-code, so a compiler keeps only the design it was given: ``compile()`` records
that root as the design to slice, as :func:`~fgslice.compat.pyvcad_rendering.Export`
does. Their machine arguments (voxel size, printer volume, output folder, material
table) are accepted and not used: the settings of the slice decide the print, except
what a slicer-project compiler says of the loaded filaments (their colours, the slot of
each material: :mod:`fgslice.compat.slicer_project`), which fgslice uses where the
settings say nothing else. ``set_progress_callback(f)`` is accepted; ``compile()`` calls
``f(1.0)`` once the design is recorded. A compiler whose output is not a print
(``InpWriter``: Abaqus meshes; ``CrossSectionSlicer``: section images) and every other
name raise a DesignError naming it.
"""

from __future__ import annotations

from fgslice.compat import context, slicer_project
from fgslice.compat.pyvcad import Node
from fgslice.errors import DesignError

COMPILERS = (
    "GrayscaleCompiler", "MaterialInkjetCompiler", "ColorInkjetCompiler", "DirectMaterialCompiler", "GCVFExporter",
    "MyersonCompiler", "MeshCompiler", "VatCompiler", "PrusaSlicerProjectCompiler", "SlicerProjectCompiler",
    "FullSpectrumSlicerProjectCompiler",
)
"""The compilers whose design fgslice slices instead."""

__all__ = list(COMPILERS)


def __getattr__(name: str):
    if name.startswith("__"):
        raise AttributeError(name)
    if name in COMPILERS:
        return type(name, (_Compiler,), {"__doc__": f"OpenVCAD's {name}: names the design to slice."})
    raise DesignError(f"pyvcad_compilers.{name} is not supported by fgslice",
                      hint="a compiler (GrayscaleCompiler, MaterialInkjetCompiler, ...) names the design that fgslice "
                           "slices; fgslice writes G-code, not other machines' files")


class _Compiler:
    """A compiler of the node among its arguments (``root``); ``compile()`` names it as the design."""

    def __init__(self, *args, **kwargs) -> None:
        roots = [a for a in (*args, *kwargs.values()) if isinstance(a, Node)]
        if len(roots) != 1:
            raise DesignError(f"pyvcad_compilers.{type(self).__name__} takes one pyvcad node (the design), "
                              f"got {len(roots)}")
        self._root, self._where = roots[0], context.site()
        name = type(self).__name__
        self._project = (slicer_project.parse(name, args, kwargs, self._where)
                         if name in slicer_project.PARAMETERS else None)
        self._progress = None

    def set_progress_callback(self, callback) -> None:
        """Keep ``callback``, called with the progress (0-1) as OpenVCAD's compilers do."""
        if not callable(callback):
            raise DesignError(f"{type(self).__name__}.set_progress_callback takes a function, got {callback!r}")
        self._progress = callback

    def compile(self, *args, **kwargs) -> None:
        """Record the root as the design to slice (OpenVCAD writes the machine's files here)."""
        run = context.current()
        if run is None:
            raise DesignError(f"{type(self).__name__}.compile records a design only in a script that fgslice runs",
                              hint="run the script with: fgslice slice design.py")
        run.exported.append((self._root, context.site()))
        run.projects[id(self._root)] = self._project
        if self._progress is not None:
            self._progress(1.0)

    def __getattr__(self, name: str):
        if name.startswith("__"):
            raise AttributeError(name)
        raise DesignError(f"pyvcad_compilers.{type(self).__name__}.{name} is not supported by fgslice",
                          hint="compile() names the design to slice; the slice's settings decide the print")
