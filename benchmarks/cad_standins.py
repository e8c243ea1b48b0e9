"""Stand-ins for the CAD files (STEP, IGES) an OpenVCAD-Public checkout keeps as Git LFS pointers.

Built with Open CASCADE (the ``cad`` extra): an L bracket for ``bracket.*`` and any other
name, 40 mm long, 20 mm wide, a 4 mm plate and a 30 mm upright, each with a 6 mm hole;
for a name holding ``left`` or ``right`` (OpenVCAD's ``card_left.step`` and
``card_right.step``, the two halves of a card) a 40 x 50 x 3 mm plate with a 10 mm hole,
on the side of x = 0 its name says, so the two touch along x = 0. STEP files hold
solids; IGES files hold faces, as most CAD programs export them (fgslice sews them).
"""

from __future__ import annotations

from pathlib import Path

CAD_SUFFIXES = {".step": "step", ".stp": "step", ".iges": "iges", ".igs": "iges"}


def _box(x0, y0, z0, dx, dy, dz):
    from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox
    from OCP.gp import gp_Pnt

    return BRepPrimAPI_MakeBox(gp_Pnt(x0, y0, z0), dx, dy, dz).Shape()


def _hole(x, y, z, axis, radius, length):
    from OCP.BRepPrimAPI import BRepPrimAPI_MakeCylinder
    from OCP.gp import gp_Ax2, gp_Dir, gp_Pnt

    return BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(x, y, z), gp_Dir(*axis)), radius, length).Shape()


def standin_shape(stem: str):
    """The solid standing in for the CAD file named ``stem`` (mm)."""
    from OCP.BRepAlgoAPI import BRepAlgoAPI_Cut, BRepAlgoAPI_Fuse

    stem = stem.lower()
    if "left" in stem or "right" in stem:
        x0 = -40.0 if "left" in stem else 0.0
        return BRepAlgoAPI_Cut(_box(x0, -25, 0, 40, 50, 3), _hole(x0 + 20, 0, -1, (0, 0, 1), 5, 5)).Shape()
    bracket = BRepAlgoAPI_Fuse(_box(-20, -10, 0, 40, 20, 4), _box(16, -10, 0, 4, 20, 30)).Shape()
    bracket = BRepAlgoAPI_Cut(bracket, _hole(-8, 0, -1, (0, 0, 1), 3, 6)).Shape()
    return BRepAlgoAPI_Cut(bracket, _hole(15, 0, 20, (1, 0, 0), 3, 6)).Shape()


def write_standin(path: Path) -> bool:
    """Write the stand-in of the CAD file ``path`` in its format; False when Open CASCADE is
    not installed (the pointer is then left in place)."""
    try:
        from OCP.IGESControl import IGESControl_Writer
        from OCP.STEPControl import STEPControl_AsIs, STEPControl_Writer
    except ImportError:
        return False
    from fgslice.design.cad import _occ

    _occ()  # quiets Open CASCADE's messages
    shape = standin_shape(path.stem)
    if CAD_SUFFIXES[path.suffix.lower()] == "step":
        writer = STEPControl_Writer()
        writer.Transfer(shape, STEPControl_AsIs)
    else:
        writer = IGESControl_Writer("MM", 0)
        writer.AddShape(shape)
        writer.ComputeModel()
    path.unlink()
    writer.Write(str(path))
    return True
