"""OpenVCAD 3's ``CADModel``: a CAD model read once and turned into a ``CAD`` node.

``CADModel.from_step(path)``, ``from_iges(path)``, ``from_brep(path)``,
``from_brep_bytes(data)`` and ``from_cadquery(value)`` (a CadQuery ``Workplane``, ``Shape``
or a selection of them, taken by duck typing: any object whose ``.wrapped`` is an Open
CASCADE ``TopoDS_Shape``, or such a shape itself) keep the model;
``to_node(use_fast_mode=False)`` tessellates its closed solids
(:mod:`fgslice.design.cad`) into a node that ``pyvcad.CAD`` would give for the same file.
Its faces (``faces``, ``face``, ``select_faces``) feed OpenVCAD's conformal cell maps,
which fgslice does not implement; they are refused by name. Relative paths: the script's
folder, then the cwd.
"""

from __future__ import annotations

from pathlib import Path

from fgslice.compat import context
from fgslice.compat import pyvcad as v2
from fgslice.design import api, cad
from fgslice.errors import DesignError, MeshError

_DOCS = "see the OpenVCAD 3 section of docs/language.md"


class CAD(v2.CAD):
    """What ``CADModel.to_node()`` returns: a ``pyvcad.CAD`` leaf of a model already read."""

    def __init__(self, node) -> None:
        v2._Leaf.__init__(self, node)


def _read(path, kind: str):
    if not isinstance(path, (str, Path)):
        raise DesignError(f"CADModel.from_{kind}: path must be a file name, got {path!r}", hint=_DOCS)
    run = context.current()
    try:
        found = v2.resolve_mesh_path(str(path), run.path.resolve().parent if run else None)
    except MeshError as error:
        raise MeshError(f"CAD file not found: '{path}'", hint=error.hint) from None
    try:
        return cad.read_shape(found, kind), f"CAD file '{found}'"
    except MeshError as error:
        raise MeshError(f"CAD file '{found}': {error.message}", hint=error.hint) from None


class CADModel:
    """``pv.CADModel``: made by its ``from_*`` methods, turned into a node by :meth:`to_node`."""

    def __init__(self, *args, **kwargs) -> None:
        raise DesignError("CADModel is made by CADModel.from_step(path), from_iges(path), from_brep(path), "
                          "from_brep_bytes(data) or from_cadquery(part)", hint=_DOCS)

    @classmethod
    def _of(cls, shape, name: str) -> CADModel:
        model = object.__new__(cls)
        model._shape, model._name = shape, name
        return model

    @staticmethod
    def from_step(path) -> CADModel:
        """A STEP (.step, .stp) file's model."""
        return CADModel._of(*_read(path, "step"))

    @staticmethod
    def from_iges(path) -> CADModel:
        """An IGES (.iges, .igs) file's model."""
        return CADModel._of(*_read(path, "iges"))

    @staticmethod
    def from_brep(path) -> CADModel:
        """An ASCII BREP file's model (mm)."""
        return CADModel._of(*_read(path, "brep"))

    @staticmethod
    def from_brep_bytes(data) -> CADModel:
        """The model of an ASCII BREP stream held in memory (mm)."""
        return CADModel._of(cad.brep_shape(data, "CADModel.from_brep_bytes: the data"), "the BREP data")

    @staticmethod
    def from_cadquery(value) -> CADModel:
        """A CadQuery ``Workplane``, ``Shape`` or selection (mm), or an Open CASCADE shape."""
        return CADModel._of(cad.occ_shape(value, "CADModel.from_cadquery"), "the CadQuery model")

    def to_node(self, use_fast_mode: bool = False) -> CAD:
        """The model's closed solids as a ``CAD`` node; both modes slice the same tessellation."""
        try:
            return CAD(api.cad_shape(self._shape, name=self._name))
        except MeshError as error:
            error.file = None
            raise

    def __getattr__(self, name: str):
        if name.startswith("__") or name in ("_shape", "_name"):
            raise AttributeError(name)
        raise DesignError(f"CADModel.{name} is not supported by fgslice's pyvcad",
                          hint="CAD faces drive OpenVCAD's conformal cell maps, which fgslice does not implement; "
                               "to_node() slices the model")
