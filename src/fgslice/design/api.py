"""Build designs in Python: the same primitives and operators as the .vcad language.

Example::

    from fgslice.design import api
    part = api.fgrade(["z/70", lambda x, y, z: 1 - z / 70], ["blue", "yellow"],
                      api.translate((0, 0, 35), api.cylinder(15, 70)))
    design = api.design(part)

Fields are expression strings (see ``docs/language.md``) or Python callables taking numpy
arrays ``x, y, z`` (and optionally ``d``, the child's signed distance) and returning an
array of their shape. Lengths in mm, angles of :func:`rotate` in degrees.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from pathlib import Path

from fgslice.design import nodes
from fgslice.design.blend import Blend
from fgslice.design.language import load_design, parse_design, resolve_mesh_path
from fgslice.design.materials import MaterialLibrary, builtin_library, load_library
from fgslice.errors import DesignError, MeshError

__all__ = [
    "sphere",
    "cube",
    "rectprism",
    "cylinder",
    "strut",
    "function",
    "mesh",
    "cad",
    "cad_shape",
    "union",
    "intersection",
    "difference",
    "translate",
    "rotate",
    "scale",
    "fgrade",
    "attribute",
    "blend",
    "offset",
    "shell",
    "design",
    "load_design",
    "parse_design",
]

Field = str | Callable


def _positive(name: str, what: str, value: float) -> float:
    try:
        value = float(value)
    except (TypeError, ValueError):
        raise DesignError(f"{name}: {what} must be a number, got {value!r}") from None
    if not value > 0:
        raise DesignError(f"{name}: {what} must be positive, got {value:g}")
    return value


def _vector(name: str, what: str, value) -> tuple[float, float, float]:
    try:
        vector = tuple(float(v) for v in value)
    except (TypeError, ValueError):
        raise DesignError(f"{name}: {what} must be 3 numbers, got {value!r}") from None
    if len(vector) != 3:
        raise DesignError(f"{name}: {what} must be 3 numbers, got {len(vector)}")
    return vector


def _material(material) -> str | None:
    if material is not None and not isinstance(material, str):
        raise DesignError(f"a material is named by a string, got {material!r}")
    return material


def _children(name: str, children: Sequence) -> tuple[nodes.Node, ...]:
    if not children:
        raise DesignError(f"{name} has no children", hint=f"pass at least one node to {name}(...)")
    for child in children:
        if not isinstance(child, nodes.Node):
            raise DesignError(f"{name}: children must be nodes, got {type(child).__name__}")
    return tuple(children)


def sphere(r: float, material: str | None = None) -> nodes.Node:
    """Ball of radius ``r`` (mm) centered at the origin."""
    return nodes.Sphere(_positive("sphere", "r", r), _material(material))


def cube(size: float, material: str | None = None) -> nodes.Node:
    """Cube of edge ``size`` (mm) centered at the origin."""
    return nodes.Box([_positive("cube", "size", size)] * 3, _material(material))


def rectprism(sx, sy=None, sz=None, material: str | None = None) -> nodes.Node:
    """Box of sizes ``(sx, sy, sz)`` (mm) centered at the origin; ``sx`` may be the 3-tuple."""
    size = _vector("rectprism", "size", sx) if sy is None and sz is None else (sx, sy, sz)
    return nodes.Box([_positive("rectprism", a, v) for a, v in zip(("sx", "sy", "sz"), size)], _material(material))


def cylinder(r: float, h: float, material: str | None = None) -> nodes.Node:
    """Cylinder of radius ``r`` along Z from ``-h/2`` to ``h/2`` (mm)."""
    return nodes.Cylinder(_positive("cylinder", "r", r), _positive("cylinder", "h", h), _material(material))


def strut(a, b, r: float, material: str | None = None) -> nodes.Node:
    """Capsule of radius ``r`` around the segment from ``a`` to ``b`` (mm)."""
    return nodes.Strut(_vector("strut", "a", a), _vector("strut", "b", b), _positive("strut", "r", r), _material(material))


def function(lo, hi, field: Field, material: str | None = None) -> nodes.Node:
    """Inside where ``field(x, y, z) <= 0``, within the box from ``lo`` to ``hi`` (mm)."""
    lo, hi = _vector("function", "lo", lo), _vector("function", "hi", hi)
    if any(h <= l for l, h in zip(lo, hi)):
        raise DesignError("function: the box's first corner must be below the second on every axis")
    return nodes.FunctionShape(lo, hi, nodes.Field(field), _material(material))


def mesh(path: str | Path, material: str | None = None) -> nodes.Node:
    """A mesh file (STL, 3MF, OBJ) in its own coordinates; relative paths from the cwd.
    A CAD file (STEP, IGES, BREP) is read by :func:`cad`."""
    from fgslice.design.cad import is_cad_file
    from fgslice.design.mesh import load_mesh

    if is_cad_file(path):
        return cad(path, material)
    return _loaded_mesh(path, load_mesh, "mesh", material)


def cad(path: str | Path, material: str | None = None) -> nodes.Node:
    """A CAD file (STEP, IGES, BREP) in its own coordinates (mm), its solids tessellated
    (:mod:`fgslice.design.cad`; needs the ``cad`` extra); relative paths from the cwd."""
    from fgslice.design.cad import load_cad

    return _loaded_mesh(path, load_cad, "CAD file", material)


def _loaded_mesh(path: str | Path, load, what: str, material: str | None) -> nodes.Node:
    """The mesh node of the file ``path`` (relative: from the cwd) read by ``load``; its
    errors name the file as ``what``."""
    found = resolve_mesh_path(str(path), None)
    try:
        geometry = load(found)
    except MeshError as exc:
        raise MeshError(f"{what} '{path}': {exc.message}", file=found, hint=exc.hint) from None
    return nodes.MeshShape(geometry, str(found), _material(material))


def cad_shape(shape, material: str | None = None, name: str = "the CAD model") -> nodes.Node:
    """An Open CASCADE shape, or a CadQuery ``Workplane``/``Shape`` wrapping one (mm), its
    solids tessellated (:func:`fgslice.design.cad.occ_shape`; needs the ``cad`` extra)."""
    from fgslice.design.cad import occ_shape, tessellate

    return nodes.MeshShape(tessellate(occ_shape(shape, name), name), f"<{name}>", _material(material))


def union(*children: nodes.Node) -> nodes.Node:
    """Union of the children; where they overlap the first child's material wins."""
    return nodes.Union(_children("union", children))


def intersection(*children: nodes.Node, mix: bool = False) -> nodes.Node:
    """Intersection of the children, with the first child's materials; ``mix``: the
    mean of every child's fractions instead (OpenVCAD's ``intersect_distribution``).
    Lattices that repeat without end below it take the bounds of the bounded children."""
    from fgslice.design.lattice import confine

    children = _children("intersection", children)
    confine(children)
    if mix:
        from fgslice.design.mixed import MixedIntersection

        return MixedIntersection(children)
    return nodes.Intersection(children)


def difference(first: nodes.Node, *others: nodes.Node) -> nodes.Node:
    """``first`` minus the union of ``others``, with ``first``'s materials."""
    return nodes.Difference(_children("difference", (first, *others)))


def translate(offset, *children: nodes.Node) -> nodes.Node:
    """Move the children by ``offset = (dx, dy, dz)`` (mm)."""
    return nodes.Translate(_vector("translate", "offset", offset), _children("translate", children))


def rotate(angles, *children: nodes.Node) -> nodes.Node:
    """Rotate the children by ``angles = (pitch, yaw, roll)`` degrees about X, then Y, then Z."""
    return nodes.Rotate(_vector("rotate", "angles", angles), _children("rotate", children))


def scale(factors, *children: nodes.Node) -> nodes.Node:
    """Stretch the children by ``factors = (sx, sy, sz)`` (or one number for all axes)."""
    vector = (float(factors),) * 3 if isinstance(factors, (int, float)) else _vector("scale", "factors", factors)
    if any(v == 0 for v in vector):
        raise DesignError("scale: factors must be non-zero")
    return nodes.Scale(vector, _children("scale", children))


def fgrade(fields: Sequence[Field], materials: Sequence[str], *children: nodes.Node, mode: str = "prob") -> nodes.Node:
    """Grade the children: ``fields[i]`` is the raw fraction of ``materials[i]``.

    The grade overrides every material named below it (the children give the geometry
    only). Fields are evaluated in this node's frame. ``mode``: "prob" (continuous fractions) or
    "thresh" (the material with the largest fraction takes the point).
    """
    fields, materials = list(fields), list(materials)
    if not fields:
        raise DesignError("fgrade needs at least one field")
    if len(fields) != len(materials):
        raise DesignError(
            f"fgrade has {len(fields)} fields but {len(materials)} materials",
            hint="give one field per material, in the same order",
        )
    if any(not isinstance(m, str) for m in materials):
        raise DesignError("fgrade: materials must be names (strings)")
    if len({m.lower() for m in materials}) != len(materials):
        raise DesignError("fgrade: a material appears twice")
    if mode not in ("prob", "thresh"):
        raise DesignError(f'fgrade mode must be "prob" or "thresh", got {mode!r}')
    return nodes.Fgrade([nodes.Field(f) for f in fields], materials, _children("fgrade", children), mode)


def attribute(name: str, field: Field | float, *children: nodes.Node) -> nodes.Node:
    """Grade the process parameter ``name`` over the children (see
    :mod:`fgslice.design.attributes`: fan, flow or flow_rate, speed, temperature,
    infill_density); ``field`` is evaluated in this node's frame, a number is constant."""
    from fgslice.design.attributes import Attribute

    if not isinstance(name, str):
        raise DesignError(f"attribute: the name must be a string, got {name!r}")
    if isinstance(field, (int, float)) and not isinstance(field, bool):
        field = repr(float(field))
    return Attribute(name, nodes.Field(field), _children("attribute", children))


def blend(size, *children: nodes.Node) -> nodes.Node:
    """Average the children's fractions over a box of ``size = (sx, sy, sz)`` mm (or one
    number for all axes) centred at each point; the geometry is the children's."""
    vector = (float(size),) * 3 if isinstance(size, (int, float)) else _vector("blend", "size", size)
    if any(v < 0 for v in vector) or not any(v > 0 for v in vector):
        raise DesignError("blend: sizes must be >= 0 with at least one positive")
    return Blend(vector, _children("blend", children))


def offset(distance: float, *children: nodes.Node) -> nodes.Node:
    """The children (their union) grown by ``distance`` mm, or shrunk when it is negative
    (:mod:`fgslice.design.offset`); materials and attributes are the children's."""
    from fgslice.design.offset import Offset

    try:
        distance = float(distance)
    except (TypeError, ValueError):
        raise DesignError(f"offset: the distance must be a number, got {distance!r}") from None
    if not math.isfinite(distance):
        raise DesignError(f"offset: the distance must be finite, got {distance!r}")
    body = _children("offset", children)
    return Offset(distance, body[0] if len(body) == 1 else nodes.Union(body))


def shell(thickness: float, *children: nodes.Node) -> nodes.Node:
    """The children (their union) hollowed to a closed wall ``thickness`` mm thick inside
    their surface (:mod:`fgslice.design.offset`); materials and attributes are theirs."""
    from fgslice.design.offset import Shell

    body = _children("shell", children)
    return Shell(_positive("shell", "thickness", thickness), body[0] if len(body) == 1 else nodes.Union(body))


def design(
    root: nodes.Node,
    materials: MaterialLibrary | str | Path | None = None,
    *,
    section_spacing: float = nodes.DEFAULT_SECTION_SPACING,
) -> nodes.NodeDesign:
    """A :class:`~fgslice.design.base.Design` from a node tree.

    ``materials``: a library or a JSON materials file (extends the built-in library).
    ``section_spacing``: sampling step (mm) of sections that are not exact.
    """
    if not isinstance(root, nodes.Node):
        raise DesignError(f"design() takes a node, got {type(root).__name__}")
    if isinstance(materials, MaterialLibrary):
        library = materials
    else:
        library = builtin_library() if materials is None else load_library(materials)
    return nodes.NodeDesign(root, library, section_spacing=_positive("design", "section_spacing", section_spacing))
