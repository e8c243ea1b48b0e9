"""CAD models (STEP, IGES, BREP files; Open CASCADE shapes) as triangle meshes.

Boundary-representation models are read with Open CASCADE through its Python wheel
(``cadquery-ocp-novtk``, the optional extra ``fgslice[cad]``; imported only here and only
when a CAD model is loaded), tessellated once, and handed on as a
:class:`~fgslice.design.mesh.MeshGeometry`, so a CAD part sections, moves and takes
attributes exactly as a mesh file does.

Conventions:

* Lengths are millimetres. Open CASCADE converts a STEP or IGES file's own length unit
  (inch, metre, ...) to millimetres when it reads the file, so a part drawn in inches
  comes in at its true size; a BREP file has no unit and is taken as millimetres, as are
  the shapes handed over from CadQuery.
* Tessellation: linear deflection :data:`LINEAR_DEFLECTION_MM` (no point of a face is
  farther than that from its triangles) and angular deflection
  :data:`ANGULAR_DEFLECTION_RAD`, in absolute terms whatever the part's size. That is the
  distance fgslice's own outline simplification may move a layer's outline (the default
  ``gcode_resolution``), far below a layer height or a line width, so sections of the
  mesh are the CAD part's sections to within what the printer can reproduce. OpenVCAD's
  exact and fast modes therefore both slice this one mesh.
* Solids only: a model is its closed solids. A file (typically IGES) holding faces
  without a solid has its faces sewn (to :data:`SEWING_TOLERANCE_MM`) into shells, each
  of which must close; a face, a wire or an open shell has no inside and is refused.
"""

from __future__ import annotations

import io
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from fgslice.design.mesh import MeshGeometry, refuse_lfs_pointer
from fgslice.errors import DesignError, MeshError

CAD_FORMATS = {".step": "step", ".stp": "step", ".iges": "iges", ".igs": "iges", ".brep": "brep"}
"""File suffixes (lower case) read as CAD models, and their format."""

INSTALL_HINT = "install the CAD extra: pip install 'fgslice[cad]' (Open CASCADE's wheel, cadquery-ocp-novtk)"

LINEAR_DEFLECTION_MM = 0.0125
"""Largest distance (mm) between a CAD face and its triangles."""

ANGULAR_DEFLECTION_RAD = 0.5
"""Largest angle (radians) between the normals of neighbouring triangles along a curved
face (Open CASCADE's default); on small fillets and holes the linear deflection is finer."""

SEWING_TOLERANCE_MM = 0.01
"""Largest gap (mm) between face edges that sewing closes (IGES faces without a solid)."""

_EXPORT_HINT = "export the part from your CAD program as a closed solid (STEP AP214/AP242 or IGES with solids)"


def is_cad_file(path: str | Path) -> bool:
    """True when ``path`` names a file :func:`load_cad` reads (by its suffix)."""
    return Path(path).suffix.lower() in CAD_FORMATS


def _occ():
    """The OCP modules used here, or a DesignError naming the extra to install."""
    try:
        from OCP import BRepBuilderAPI, BRepLib, BRepMesh, Message
    except ImportError as error:
        raise DesignError(
            f"CAD models (STEP, IGES) need Open CASCADE, which is not installed ({error})",
            hint=INSTALL_HINT,
        ) from None
    for printer in Message.Message.DefaultMessenger_s().Printers():  # the readers print statistics to stdout
        printer.SetTraceLevel(Message.Message_Gravity.Message_Fail)
    return BRepBuilderAPI, BRepLib, BRepMesh


def load_cad(path: str | Path) -> MeshGeometry:
    """The solids of a STEP (.step, .stp), IGES (.iges, .igs) or BREP (.brep) file as a mesh (mm).

    Raises:
        DesignError: Open CASCADE (the ``cad`` extra) is not installed.
        MeshError: the file is missing, a Git LFS pointer, not a readable file of its
            type, or holds no closed solid.
    """
    return tessellate(read_shape(path), "the file", path=Path(path))


def read_shape(path: str | Path, kind: str | None = None):
    """The Open CASCADE shape a CAD file holds, read as ``kind`` (``"step"``, ``"iges"``
    or ``"brep"``; by default from the file's suffix, :data:`CAD_FORMATS`).

    Raises:
        DesignError: Open CASCADE (the ``cad`` extra) is not installed.
        MeshError: the file is missing, a Git LFS pointer or not a readable file of its type.
    """
    path = Path(path)
    kind = kind or CAD_FORMATS.get(path.suffix.lower())
    if kind is None:
        raise MeshError(f"unsupported CAD file type '{path.suffix or path.name}'", file=path,
                        hint="use a .step/.stp, .iges/.igs or .brep file")
    if not path.is_file():
        raise MeshError("CAD file not found", file=path, hint="check the path")
    refuse_lfs_pointer(path)
    _occ()
    return {"step": _read_step, "iges": _read_iges, "brep": _read_brep}[kind](path)


def _read_step(path: Path):
    from OCP.STEPControl import STEPControl_Reader

    return _read_with(STEPControl_Reader(), path, "STEP")


def _read_iges(path: Path):
    from OCP.IGESControl import IGESControl_Reader

    return _read_with(IGESControl_Reader(), path, "IGES")


def _read_with(reader, path: Path, kind: str):
    """The shape an Open CASCADE exchange ``reader`` (STEP, IGES) reads from ``path``."""
    from OCP.IFSelect import IFSelect_RetDone

    if reader.ReadFile(str(path)) != IFSelect_RetDone:
        raise MeshError(f"not a readable {kind} file", file=path, hint=_EXPORT_HINT)
    reader.TransferRoots()
    return reader.OneShape()


def _read_brep(path: Path):
    from OCP.BRep import BRep_Builder
    from OCP.BRepTools import BRepTools
    from OCP.TopoDS import TopoDS_Shape

    shape = TopoDS_Shape()
    try:
        read = BRepTools.Read_s(shape, str(path), BRep_Builder())
    except Exception:  # noqa: BLE001 - Open CASCADE raises its own types on malformed input
        read = False
    if not read:
        raise MeshError("not a readable BREP file", file=path, hint=_EXPORT_HINT)
    return shape


def brep_shape(data: bytes, name: str = "BREP data"):
    """The shape an ASCII BREP stream holds (OpenVCAD 3's ``CADModel.from_brep_bytes``)."""
    _occ()
    from OCP.BRep import BRep_Builder
    from OCP.BRepTools import BRepTools
    from OCP.TopoDS import TopoDS_Shape

    if not isinstance(data, (bytes, bytearray)):
        raise DesignError(f"{name} must be bytes, got {type(data).__name__}")
    shape = TopoDS_Shape()
    try:
        BRepTools.Read_s(shape, io.BytesIO(bytes(data)), BRep_Builder())
    except Exception as error:  # noqa: BLE001 - Open CASCADE raises its own types on malformed input
        raise DesignError(f"{name} is not a readable BREP stream ({error})", hint=_EXPORT_HINT) from None
    return shape


def occ_shape(value, name: str = "the CAD model"):
    """The Open CASCADE shape of ``value``: a ``TopoDS_Shape``, an object wrapping one in
    ``.wrapped`` (a CadQuery ``Shape``), a CadQuery ``Workplane`` (the shapes of its
    stack, ``.vals()``) or an iterable of those (one compound). Duck-typed: CadQuery
    itself is not needed.

    Raises:
        DesignError: ``value`` is none of these, or Open CASCADE is not installed.
    """
    _occ()
    from OCP.TopoDS import TopoDS_Shape

    if isinstance(value, TopoDS_Shape):
        return value
    wrapped = getattr(value, "wrapped", None)
    if isinstance(wrapped, TopoDS_Shape):
        return wrapped
    stack = getattr(value, "vals", None)
    if callable(stack):
        items = list(stack())
    elif isinstance(value, Iterable) and not isinstance(value, (str, bytes)):
        items = list(value)
    else:
        raise DesignError(
            f"{name}: expected a CadQuery Workplane or Shape, an Open CASCADE TopoDS_Shape or a list of them, "
            f"got {type(value).__name__}",
            hint="pass the CadQuery part itself, e.g. cq.Workplane('XY').box(10, 10, 10)",
        )
    if not items:
        raise DesignError(f"{name}: the selection holds no shape", hint="select the solid(s) of the part")
    return _compound([occ_shape(item, name) for item in items])


def _compound(shapes: list):
    from OCP.BRep import BRep_Builder
    from OCP.TopoDS import TopoDS_Compound

    if len(shapes) == 1:
        return shapes[0]
    builder, compound = BRep_Builder(), TopoDS_Compound()
    builder.MakeCompound(compound)
    for shape in shapes:
        builder.Add(compound, shape)
    return compound


def _subshapes(shape, kind) -> list:
    from OCP.TopExp import TopExp_Explorer

    explorer, found = TopExp_Explorer(shape, kind), []
    while explorer.More():
        found.append(explorer.Current())
        explorer.Next()
    return found


def _cast(shape, kind: str):
    """``shape`` as its TopoDS subclass (``TopoDS.Face_s`` before OCP 8, ``TopoDS.Face`` since)."""
    from OCP.TopoDS import TopoDS

    return (getattr(TopoDS, kind + "_s", None) or getattr(TopoDS, kind))(shape)


def solids(shape, name: str, *, path: Path | None = None) -> list:
    """The closed solids of ``shape``: its solids, else its faces sewn into closed shells.

    Raises:
        MeshError: the shape is empty, or a shell is open (named by ``name``).
    """
    BRepBuilderAPI, BRepLib, _ = _occ()
    from OCP.BRep import BRep_Tool
    from OCP.TopAbs import TopAbs_FACE, TopAbs_SHELL, TopAbs_SOLID

    if shape is None or shape.IsNull() or not _subshapes(shape, TopAbs_FACE):
        raise MeshError(f"{name} holds no solid (no faces at all)", file=path, hint=_EXPORT_HINT)
    found = [_cast(s, "Solid") for s in _subshapes(shape, TopAbs_SOLID)]
    if not found:
        sewing = BRepBuilderAPI.BRepBuilderAPI_Sewing(SEWING_TOLERANCE_MM)
        for face in _subshapes(shape, TopAbs_FACE):
            sewing.Add(face)
        sewing.Perform()
        free = sewing.NbFreeEdges()
        if free:
            raise MeshError(
                f"{name} holds faces that do not close into a solid: {free} free edges are left "
                f"after sewing them to {SEWING_TOLERANCE_MM:g} mm",
                file=path, hint=_EXPORT_HINT)
        for shell in _subshapes(sewing.SewedShape(), TopAbs_SHELL):
            solid = BRepBuilderAPI.BRepBuilderAPI_MakeSolid(_cast(shell, "Shell")).Solid()
            BRepLib.BRepLib.OrientClosedSolid_s(solid)  # outward normals, whatever the faces' order
            found.append(solid)
    for number, solid in enumerate(found, 1):
        if not all(BRep_Tool.IsClosed_s(shell) for shell in _subshapes(solid, TopAbs_SHELL)):
            raise MeshError(f"{name}: solid {number} of {len(found)} has an open shell (its faces leave a gap)",
                            file=path, hint=_EXPORT_HINT)
    return found


def tessellate(shape, name: str, *, path: Path | None = None) -> MeshGeometry:
    """The closed solids of ``shape`` (see :func:`solids`) as one triangle mesh (mm),
    faces wound counter-clockwise seen from outside; ``name`` names the model in errors."""
    _, _, BRepMesh = _occ()
    from OCP.BRep import BRep_Tool
    from OCP.TopAbs import TopAbs_FACE, TopAbs_REVERSED
    from OCP.TopLoc import TopLoc_Location

    corners = []
    for solid in solids(shape, name, path=path):
        BRepMesh.BRepMesh_IncrementalMesh(solid, LINEAR_DEFLECTION_MM, False, ANGULAR_DEFLECTION_RAD, False)
        for face in _subshapes(solid, TopAbs_FACE):
            face = _cast(face, "Face")
            location = TopLoc_Location()
            mesh = BRep_Tool.Triangulation_s(face, location)
            if mesh is None:
                raise MeshError(f"{name}: Open CASCADE could not tessellate a face", file=path, hint=_EXPORT_HINT)
            nodes = np.array([mesh.Node(i).Coord() for i in range(1, mesh.NbNodes() + 1)], dtype=float)
            triangles = np.array([mesh.Triangle(i).Get() for i in range(1, mesh.NbTriangles() + 1)],
                                 dtype=np.int64).reshape(-1, 3) - 1
            if face.Orientation() == TopAbs_REVERSED:
                triangles = triangles[:, ::-1]
            if not location.IsIdentity():
                transform = location.Transformation()
                matrix = np.array([[transform.Value(r, c) for c in range(1, 5)] for r in range(1, 4)])
                nodes = nodes @ matrix[:, :3].T + matrix[:, 3]
            corners.append(nodes[triangles])
    triangles = np.concatenate(corners).reshape(-1, 3)
    return MeshGeometry(triangles, None, merge=True, path=path)
