"""The subset of OpenVCAD's ``pyvcad`` module that OpenVCAD's example scripts use.

A design script written for OpenVCAD imports this module as ``pyvcad`` (see
:mod:`fgslice.compat.script`). Each class keeps OpenVCAD's signature and meaning and is
turned into :mod:`fgslice.design.api` nodes when the rendered root is loaded:

* primitives are centred on their ``center`` (mm); ``Cylinder`` stands along Z;
* ``Rotate(pitch, yaw, roll, around)`` takes degrees, applies roll (about Z), then yaw
  (about Y), then pitch (about X), and turns about ``around``;
* a material is an id from ``default_materials.id(name)``; any other integer (OpenVCAD's
  default id 1) leaves the primitive without a material of its own, so it takes the
  fractions of its enclosing ``FGrade`` (or the design's first material);
* ``FGrade`` fields are fgslice expressions (``docs/expressions.md``) or OpenVCAD's
  Python functions ``f(x, y, z, rho, phic, r, theta, phis[, d])``, continuous in both of
  OpenVCAD's modes.

Names outside the subset raise a :class:`~fgslice.errors.DesignError` naming them.
Nodes can be mutated (``add_child``, ``set_child``, ``set_left``) until the script ends,
so they are converted when the design is built, by :func:`to_node`.
"""

from __future__ import annotations

import enum
import functools
import inspect
import numbers
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from fgslice.compat import context, numba_standin
from fgslice.design import api, lattice, nodes, smooth
from fgslice.design.expressions import combine_expressions, compile_expression
from fgslice.design.language import resolve_mesh_path
from fgslice.design.extrusion import polygon_extrude
from fgslice.design.text import text as text_shape
from fgslice.design.tile import tile
from fgslice.errors import DesignError, FgsliceError, MeshError

_DOCS = "see the supported subset in docs/language.md"

__all__ = [
    "Vec3", "MaterialDefs", "default_materials", "resources_path",
    "RectPrism", "Sphere", "Cylinder", "Strut", "Mesh", "CAD", "Function",
    "Union", "Intersection", "Difference", "Translate", "Rotate", "Scale", "FGrade",
    "LatticeType", "GraphLattice", "Tile", "ImplicitUnitCell", "GraphUnitCell", "j750_materials",
]


def _unsupported(owner: str, name: str) -> DesignError:
    return DesignError(f"{owner}.{name} is not supported by fgslice's pyvcad", hint=_DOCS)


def __getattr__(name: str):
    if name in ("ImplicitUnitCell", "GraphUnitCell"):  # OpenVCAD 3's unit cells, from the metamaterials module
        from fgslice.compat import pyvcad_metamaterials

        return getattr(pyvcad_metamaterials, name)
    if name.startswith("__"):
        raise AttributeError(name)
    if name in ("PNGLoader", "PNGColorMode"):  # OpenVCAD 3's image volumes
        from fgslice.compat import png_loader

        return getattr(png_loader, name)
    from fgslice.compat import pyvcad_v3

    if name in pyvcad_v3.__all__:
        value = globals()[name] = getattr(pyvcad_v3, name)  # found once: later look-ups skip this function
        return value
    if name in ("TriangleMeshSurface", "TrimMode"):  # OpenVCAD 3's conformal maps on meshes
        from fgslice.compat import pyvcad_metamaterials

        _REFUSED[name] = pyvcad_metamaterials.CONFORMAL_REASON
    if name in _REFUSED:
        return _Refused(name)
    raise _unsupported("pyvcad", name)


_VDB = ("its data is an OpenVDB grid, and no maintained Python package on PyPI reads OpenVDB files",
        "give the field as an expression or a @cfunc, or the shape as a Mesh (STL, OBJ, 3MF)")

_REFUSED = {
    **dict.fromkeys(("SignedDistanceField", "Vec2sVolume", "Vec3sVolume", "Vec4sVolume", "vdb_loader"), _VDB),
    "Map": ("OpenVCAD's experimental surface parameterization has no documented geometry or material to print",
            "model the part with its meshes and primitives"),
    "ConformalMap": ("OpenVCAD's experimental wrapping of a pattern onto a surface is defined by its implementation "
                     "(anchor point, transported frame, calibrated arc length), which its documentation outlines "
                     "without the formulas, so fgslice cannot print what OpenVCAD shows",
                     "model the pattern on the surface with booleans of the base and the pattern"),
    "PointMap": ("it needs the simulation's tetrahedral mesh (.inp) and nodal displacements (.csv), "
                 "which fgslice does not read",
                 "grade the part with FGrade expressions of x, y, z instead"),
}
"""OpenVCAD names fgslice refuses, with the reason and what to do instead."""


class _Refused:
    """A refused OpenVCAD name: calling it or reading any of its attributes raises a
    DesignError with the reason."""

    def __init__(self, name: str) -> None:
        self.name = name

    def _refuse(self) -> DesignError:
        reason, hint = _REFUSED[self.name]
        return DesignError(f"pyvcad.{self.name} is not supported by fgslice: {reason}", hint=hint)

    def __call__(self, *args, **kwargs):
        raise self._refuse()

    def __getattr__(self, name: str):
        if name.startswith("__"):
            raise AttributeError(name)
        raise self._refuse()


def _number(owner: str, what: str, value) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise DesignError(f"{owner}: {what} must be a number, got {value!r}", hint=_DOCS)
    return float(value)


class Vec3:
    """A point or vector (mm): ``Vec3(x, y, z)``, with attributes ``x``, ``y``, ``z``."""

    __slots__ = ("x", "y", "z")

    def __init__(self, x=0.0, y=0.0, z=0.0) -> None:
        self.x, self.y, self.z = (_number("Vec3", a, v) for a, v in zip("xyz", (x, y, z)))

    def __iter__(self):
        return iter((self.x, self.y, self.z))

    def __eq__(self, other) -> bool:
        return isinstance(other, Vec3) and tuple(self) == tuple(other)

    __hash__ = None

    def __repr__(self) -> str:
        return f"Vec3({self.x:g}, {self.y:g}, {self.z:g})"

    def __getattr__(self, name: str):
        if name.startswith("__"):
            raise AttributeError(name)
        raise _unsupported("Vec3", name)


def _vec3(owner: str, what: str, value) -> tuple[float, float, float]:
    if not isinstance(value, Vec3):
        raise DesignError(f"{owner}: {what} must be a pyvcad.Vec3, got {value!r}", hint=_DOCS)
    return tuple(value)


class MaterialId(int):
    """What ``default_materials.id(name)`` returns: an int that remembers the name."""

    name: str

    def __new__(cls, value: int, name: str):
        self = super().__new__(cls, value)
        self.name = name
        return self

    def __repr__(self) -> str:
        return f"MaterialId({int(self)}, {self.name!r})"


class MaterialDefs:
    """OpenVCAD's material table: ``id(name)`` gives the id standing for ``name``.

    As in OpenVCAD, an id is the material's place in the table: here fgslice's built-in
    library (1 red, 2 green, 3 blue, 4 yellow, 5 cyan, ...: ``fgslice materials``), then
    other names in the order the script asks for them. Names are resolved by fgslice's
    material library when the design is built, so a name it does not know (yet) is
    reported there, with the known names.
    """

    def __init__(self, *args) -> None:
        if args:
            raise DesignError(
                "pyvcad.MaterialDefs(config file) is not supported by fgslice's pyvcad",
                hint="use pyvcad.default_materials; add materials with fgslice's --materials FILE",
            )
        from fgslice.design.materials import builtin_library

        names = [n.lower() for n in builtin_library().names if n.lower() != nodes.VOID]
        self._ids: dict[str, MaterialId] = {n: MaterialId(i, n) for i, n in enumerate(names, 1)}

    def name_of(self, number: int) -> MaterialId:
        """The material whose id is ``number``."""
        found = next((m for m in self._ids.values() if int(m) == number), None)
        if found is None:
            raise DesignError(f"material id {number} is not in the material table (ids 1 to {len(self._ids)})",
                              hint="name the material: default_materials.id(name)")
        return found

    def __call__(self) -> MaterialDefs:
        """``default_materials()``, as newer OpenVCAD scripts write it: the same table."""
        return self

    def id(self, name: str) -> MaterialId:
        """The id of the material called ``name`` (case-insensitive)."""
        if not isinstance(name, str):
            raise DesignError(f"default_materials.id takes a material name, got {name!r}")
        key = name.lower()
        if key not in self._ids:
            self._ids[key] = MaterialId(len(self._ids) + 1, key)
        return self._ids[key]

    def __getattr__(self, name: str):
        if name.startswith("__"):
            raise AttributeError(name)
        raise _unsupported("MaterialDefs", name)


default_materials = MaterialDefs()


class _J750Materials(MaterialDefs):
    """OpenVCAD's ``j750_materials``: ``id(resin)`` is the id of the filament colour
    printing that J750 resin (:mod:`fgslice.compat.j750`)."""

    def __init__(self) -> None:
        super().__init__()
        self._resins: dict[str, str] = {}
        self._run = None

    def id(self, name: str) -> MaterialId:
        from fgslice.compat import j750

        if not isinstance(name, str):
            raise DesignError(f"j750_materials.id takes a resin name, got {name!r}")
        if self._run is not context.current():  # the resins a script chose are its own
            self._resins, self._run = {}, context.current()
        filament = j750.filament_of(name)
        j750.check_distinct(self._resins, name, filament)
        self._resins[name.lower()] = filament
        return super().id(filament)


j750_materials = _J750Materials()


def _material(owner: str, material) -> str | None:
    if isinstance(material, MaterialId):
        return material.name
    if isinstance(material, numbers.Integral) and not isinstance(material, bool):
        return None
    raise DesignError(f"{owner}: a material is an id from default_materials.id(name), got {material!r}", hint=_DOCS)


def resources_path() -> str:
    """OpenVCAD's resource folder, with a trailing '/': the nearest folder above the
    running script that holds an ``examples`` folder (an OpenVCAD checkout), else the
    script's own folder."""
    run = context.current()
    start = run.path.resolve().parent if run else Path.cwd()
    found = next((p for p in (start, *start.parents) if (p / "examples").is_dir()), start)
    return str(found) + "/"


@functools.cache
def _derived():
    """OpenVCAD's derived coordinates (rho, phic, r, theta, phis) as one compiled group."""
    return combine_expressions([compile_expression(name) for name in ("rho", "phic", "r", "theta", "phis")])


def _field(owner: str, function, *, with_d: bool):
    """An expression string as it is, or OpenVCAD's point function
    ``f(x, y, z, rho, phic, r, theta, phis[, d])`` (or of some of them by name) as an
    fgslice field callable."""
    if isinstance(function, str):
        return function
    if not callable(function):
        raise DesignError(f"{owner}: a function is an expression string or a Python function, got {function!r}")
    if isinstance(function, numba_standin.CFunc):
        function = _of_xyz(owner, function)
    function = _by_name(function, with_d) or function
    takes_d = with_d and _accepts(function, 9)
    if not takes_d and not _accepts(function, 8):
        raise DesignError(f"{owner}: a Python function takes (x, y, z, rho, phic, r, theta, phis"
                          f"{', d' if with_d else ''}), '{getattr(function, '__name__', function)}' does not")
    point = _PointFunction(function)
    if takes_d:
        return point

    def without_d(x, y, z):
        return point(x, y, z)

    without_d.__name__ = point.__name__
    return without_d


def _of_xyz(owner: str, function: numba_standin.CFunc) -> Callable:
    """OpenVCAD 3's ``@cfunc`` of ``(x, y, z)`` as a function of the eight coordinates."""
    if function.arity != 3:
        raise DesignError(f"{owner}: a @cfunc takes (x, y, z), '{function.__name__}' takes {function.arity} arguments",
                          hint="declare it as @cfunc(types.float64(types.float64, types.float64, types.float64))")
    python = function.py_func

    def of_xyz(x, y, z, rho, phic, r, theta, phis):
        return python(x, y, z)

    of_xyz.__name__ = function.__name__
    return of_xyz


_COORDINATES = ("x", "y", "z", "rho", "phic", "r", "theta", "phis", "d")


def _by_name(function: Callable, with_d: bool) -> Callable | None:
    """For a function that does not take OpenVCAD's eight (or nine) coordinates in order
    but names some of them (``def f(theta, offset=0.5)``, as OpenVCAD Studio's examples
    write them): a function of all of them that passes it the ones it names; else None."""
    try:
        parameters = inspect.signature(function).parameters.values()
    except (TypeError, ValueError):
        return None
    known = _COORDINATES if with_d else _COORDINATES[:-1]
    named = [p.name for p in parameters if p.name in known]
    required = [p.name for p in parameters if p.default is inspect.Parameter.empty
                and p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)]
    if _accepts(function, 8) or not named or not set(required) <= set(named):
        return None

    def coordinates(*values):
        return function(**{name: values[_COORDINATES.index(name)] for name in named})

    def with_distance(x, y, z, rho, phic, r, theta, phis, d):
        return coordinates(x, y, z, rho, phic, r, theta, phis, d)

    def without_distance(x, y, z, rho, phic, r, theta, phis):
        return coordinates(x, y, z, rho, phic, r, theta, phis)

    chosen = with_distance if "d" in named else without_distance
    chosen.__name__ = getattr(function, "__name__", "function")
    return chosen


def _accepts(function: Callable, count: int) -> bool:
    try:
        inspect.signature(function).bind(*range(count))
    except (TypeError, ValueError):
        return False
    return True


class _PointFunction:
    """A Python function of OpenVCAD's coordinates evaluated on numpy arrays: called once
    with whole arrays, or point by point when it only takes numbers (``math.sin``, ``if``)."""

    def __init__(self, function: Callable) -> None:
        self.function = function
        self.__name__ = getattr(function, "__name__", "function")
        self.per_point = False

    def __call__(self, x, y, z, d=None) -> np.ndarray:
        args = (x, y, z, *_derived()(x, y, z)) + (() if d is None else (d,))
        if not self.per_point:
            try:
                return np.asarray(self.function(*args), dtype=float)
            except (TypeError, ValueError):
                self.per_point = True
        return np.frompyfunc(self.function, len(args), 1)(*args).astype(float)


class Node:
    """Base of the pyvcad node classes: where it was made; unsupported methods fail by name."""

    def __init__(self) -> None:
        self._where = context.site()

    def __getattr__(self, name: str):
        if name.startswith("__"):
            raise AttributeError(name)
        raise _unsupported(type(self).__name__, name)

    def _build(self, convert) -> nodes.Node:
        raise NotImplementedError

    def evaluate(self, *point) -> float:
        """The signed distance at ``(x, y, z)`` (:mod:`fgslice.compat.evaluation`)."""
        from fgslice.compat import evaluation

        return evaluation.evaluate(self, *point)

    def gradient(self, *point) -> Vec3:
        """The distance's gradient at ``(x, y, z)`` or a ``Vec3`` (:mod:`fgslice.compat.evaluation`)."""
        from fgslice.compat import evaluation

        return evaluation.gradient(self, *point)

    def snap(self, point) -> Vec3:
        """The nearest point on the surface (:mod:`fgslice.compat.evaluation`)."""
        from fgslice.compat import evaluation

        return evaluation.snap(self, point)

    def bounding_box(self) -> tuple[Vec3, Vec3]:
        """The shape's ``(min, max)`` corners (:mod:`fgslice.compat.evaluation`)."""
        from fgslice.compat import evaluation

        return evaluation.bounding_box(self)

    def prepare(self, voxel_size, *bandwidths) -> None:
        """OpenVCAD's sampling set-up: nothing to do here (:mod:`fgslice.compat.evaluation`)."""
        from fgslice.compat import evaluation

        evaluation.prepare(self, voxel_size, *bandwidths)

    def set_attribute(self, name, attribute) -> None:
        """OpenVCAD 3: attach ``attribute`` as ``name`` (:mod:`fgslice.compat.pyvcad_v3`)."""
        from fgslice.compat import pyvcad_v3

        pyvcad_v3.set_attribute(self, name, attribute)

    def set_attribute_conflict_resolver(self, name, resolver) -> None:
        """OpenVCAD 3: how the children's attribute ``name`` combines where they overlap."""
        from fgslice.compat import pyvcad_v3

        pyvcad_v3.set_attribute_conflict_resolver(self, name, resolver)

    def attribute_list(self) -> list[str]:
        """OpenVCAD 3: the attribute names of this node's design (:func:`fgslice.compat.pyvcad_v3.attribute_list`)."""
        from fgslice.compat import pyvcad_v3

        return pyvcad_v3.attribute_list(self)


def _centred(center, node: nodes.Node) -> nodes.Node:
    return node if not any(center) else api.translate(center, node)


class _Leaf(Node):
    """A primitive: its fgslice node is built at once, so bad values fail on their line."""

    def __init__(self, node: nodes.Node) -> None:
        super().__init__()
        self._node = node

    def _build(self, convert) -> nodes.Node:
        return self._node


def _overload(owner: str, args: tuple, forms: dict[int, str], then: str = "") -> None:
    """A DesignError listing ``forms`` (argument count -> names) unless ``args`` fits one."""
    if len(args) not in forms:
        takes = " or ".join(f"({forms[n]})" for n in sorted(forms))
        raise DesignError(f"{owner} takes {takes}{then}, got {len(args)} arguments", hint=_DOCS)


class RectPrism(_Leaf):
    """``RectPrism(center, size, material=1)``: a box of ``size`` centred on ``center``."""

    def __init__(self, *args, **kwargs) -> None:
        center, size, material = _bind("RectPrism", ("center", "size", "material"), args, kwargs,
                                       {"center": Vec3(), "size": Vec3(1, 1, 1), "material": 1})
        center, size = _vec3("RectPrism", "center", center), _vec3("RectPrism", "size", size)
        super().__init__(_centred(center, api.rectprism(size, material=_material("RectPrism", material))))

    @staticmethod
    def FromMinAndMax(min, max) -> RectPrism:  # noqa: A002 - OpenVCAD's argument names
        """OpenVCAD 3: the box between the corners ``min`` and ``max`` (Vec3, mm)."""
        lo, hi = _vec3("RectPrism.FromMinAndMax", "min", min), _vec3("RectPrism.FromMinAndMax", "max", max)
        if not all(b > a for a, b in zip(lo, hi)):
            raise DesignError(f"RectPrism.FromMinAndMax: max {tuple(hi)} must exceed min {tuple(lo)} on every axis")
        return RectPrism(Vec3(*((a + b) / 2 for a, b in zip(lo, hi))), Vec3(*(b - a for a, b in zip(lo, hi))))


class Sphere(_Leaf):
    """``Sphere(center, radius, material=1)`` or ``Sphere(cx, cy, cz, radius, material=1)``."""

    def __init__(self, *args, **kwargs) -> None:
        if args and not isinstance(args[0], Vec3):
            _overload("Sphere", args, {4: "cx, cy, cz, radius", 5: "cx, cy, cz, radius, material"})
            args = (Vec3(*args[:3]), *args[3:])
        center, radius, material = _bind("Sphere", ("center", "radius", "material"), args, kwargs,
                                         {"center": Vec3(), "radius": 1.0, "material": 1})
        center = _vec3("Sphere", "center", center)
        super().__init__(_centred(center, api.sphere(radius, _material("Sphere", material))))


class Cylinder(_Leaf):
    """``Cylinder(center, radius, height, material=1)``: along Z, centred on ``center``."""

    def __init__(self, *args, **kwargs) -> None:
        center, radius, height, material = _bind(
            "Cylinder", ("center", "radius", "height", "material"), args, kwargs,
            {"center": Vec3(), "radius": 1.0, "height": 1.0, "material": 1})
        center = _vec3("Cylinder", "center", center)
        super().__init__(_centred(center, api.cylinder(radius, height, _material("Cylinder", material))))


class Strut(_Leaf):
    """``Strut(start, end, radius, material=1)``: a capsule around the segment."""

    def __init__(self, *args, **kwargs) -> None:
        start, end, radius, material = _bind("Strut", ("start", "end", "radius", "material"), args, kwargs,
                                             {"material": 1})
        a, b = _vec3("Strut", "start", start), _vec3("Strut", "end", end)
        super().__init__(api.strut(a, b, radius, _material("Strut", material)))


class Mesh(_Leaf):
    """``Mesh(path, material=1, disable_validation=False)`` (OpenVCAD 2) or ``Mesh(path,
    center=False, disable_validation=False, override_voxel_size=None,
    compensate_slicer_ras=False)`` (OpenVCAD 3); either may take a ``sample_size`` (Vec3)
    second argument. ``center`` moves the mesh's bounding-box centre to the origin;
    ``compensate_slicer_ras`` mirrors it across the XZ plane (y -> -y) first, as OpenVCAD
    does for 3D Slicer's RAS exports. The voxel sizes are accepted and not used: fgslice
    slices the mesh itself, not a voxelization. Relative paths: the script's folder, then
    the cwd."""

    _V3 = ("center", "disable_validation", "override_voxel_size", "compensate_slicer_ras")

    def __init__(self, path, *args, **kwargs) -> None:
        if args and isinstance(args[0], (Vec3, float)):
            args = args[1:]
        kwargs.pop("sample_size", None)
        v3 = (args and isinstance(args[0], bool)) or bool(set(kwargs) & {"center", "override_voxel_size",
                                                                           "compensate_slicer_ras"})
        if v3:
            center, _, _, mirror = _bind("Mesh", self._V3, args, kwargs, {
                "center": False, "disable_validation": False, "override_voxel_size": None,
                "compensate_slicer_ras": False})
            material = 1
        else:
            material, _ = _bind("Mesh", ("material", "disable_validation"), args, kwargs,
                                {"material": 1, "disable_validation": False})
            center = mirror = False
        if not isinstance(path, (str, Path)):
            raise DesignError(f"Mesh: path must be a file name, got {path!r}", hint=_DOCS)
        run = context.current()
        found = resolve_mesh_path(str(path), run.path.resolve().parent if run else None)
        try:
            node = api.mesh(found, _material("Mesh", material))
        except MeshError as error:
            error.file = error.line = error.column = error.source_line = None
            raise
        if mirror:
            node = api.scale((1.0, -1.0, 1.0), node)
        if center:
            lo, hi = node.bounds()
            node = api.translate(tuple(-(lo + hi) / 2), node)
        super().__init__(node)


class CAD(_Leaf):
    """``CAD(path, use_fast_mode=True, material=1)`` (OpenVCAD 3: ``CAD(path,
    use_fast_mode=True)``): the closed solids of a STEP, IGES (or BREP) file, in its own
    coordinates (mm), tessellated to 0.0125 mm in both modes (:mod:`fgslice.design.cad`;
    the ``cad`` extra). Relative paths: the script's folder, then the cwd."""

    def __init__(self, path, *args, **kwargs) -> None:
        _, material = _bind("CAD", ("use_fast_mode", "material"), args, kwargs, {"use_fast_mode": True, "material": 1})
        if not isinstance(path, (str, Path)):
            raise DesignError(f"CAD: path must be a file name, got {path!r}", hint=_DOCS)
        run = context.current()
        try:
            found = resolve_mesh_path(str(path), run.path.resolve().parent if run else None)
        except MeshError as error:
            raise MeshError(f"CAD file not found: '{path}'", hint=error.hint) from None
        try:
            node = api.cad(found, _material("CAD", material))
        except MeshError as error:
            error.file = error.line = error.column = error.source_line = None
            raise
        super().__init__(node)


class Function(_Leaf):
    """``Function(function, material=1, min=Vec3(-10, -10, -10), max=Vec3(10, 10, 10))``
    (OpenVCAD 2) or ``Function(function, min, max)`` (OpenVCAD 3, no material): inside
    where the function is <= 0, within the box from ``min`` to ``max`` (OpenVCAD's default
    box: 20 mm about the origin)."""

    def __init__(self, *args, **kwargs) -> None:
        if len(args) >= 2 and isinstance(args[1], Vec3):
            args = (args[0], 1, *args[1:])
        function, material, lo, hi = _bind("Function", ("function", "material", "min", "max"), args, kwargs,
                                           {"material": 1, "min": Vec3(-10, -10, -10), "max": Vec3(10, 10, 10)})
        function = _field("Function", function, with_d=False)
        lo, hi = _vec3("Function", "min", lo), _vec3("Function", "max", hi)
        super().__init__(api.function(lo, hi, function, _material("Function", material)))


class _LatticeKind:
    """One value of ``LatticeType``: its OpenVCAD name and its catalog cell name."""

    def __init__(self, name: str, cell: str) -> None:
        self.name, self.value = name, cell

    def __repr__(self) -> str:
        return f"LatticeType.{self.name}"


class _LatticeTypes(type):
    def __getattr__(cls, name: str):
        if name.startswith("__"):
            raise AttributeError(name)
        raise DesignError(f"pyvcad.LatticeType.{name} is not supported by fgslice's pyvcad",
                          hint="the lattice types are BodyCenteredCubic, FaceCenteredCubic, Cubic and KelvinCell")


class LatticeType(metaclass=_LatticeTypes):
    """OpenVCAD 2's unit cells of ``GraphLattice``, by their catalog names in
    :data:`fgslice.design.lattice.GRAPH_CELLS`."""

    BodyCenteredCubic = _LatticeKind("BodyCenteredCubic", "bcc")
    FaceCenteredCubic = _LatticeKind("FaceCenteredCubic", "fcc")
    Cubic = _LatticeKind("Cubic", "cubic")
    KelvinCell = _LatticeKind("KelvinCell", "kelvin")


class GraphLattice(_Leaf):
    """``GraphLattice(type, size, radius, material=1)``: one unit cell of ``type``, of
    ``size`` (Vec3) centred on the origin, struts of ``radius``; or
    ``GraphLattice(edges, radius, material=1)`` with edges ``[(start, end), ...]`` of Vec3.
    ``Tile(lattice)`` repeats it."""

    def __init__(self, *args, **kwargs) -> None:
        if args and isinstance(args[0], _LatticeKind) or "type" in kwargs:
            kind, size, radius, material = _bind("GraphLattice", ("type", "size", "radius", "material"), args, kwargs,
                                                 {"material": 1})
            if not isinstance(kind, _LatticeKind):
                raise DesignError(f"GraphLattice: type must be a pyvcad.LatticeType, got {kind!r}", hint=_DOCS)
            size = np.asarray(_vec3("GraphLattice", "size", size))
            if not np.all(size > 0):
                raise DesignError(f"GraphLattice: the cell size must be positive, got {tuple(size)}")
            edges = lattice.graph_cell(kind.value) * size - size / 2
        else:
            edges, radius, material = _bind("GraphLattice", ("edges", "radius", "material"), args, kwargs,
                                            {"material": 1})
            edges = _edges("GraphLattice", edges)
        self.extent = (edges.reshape(-1, 3).min(axis=0), edges.reshape(-1, 3).max(axis=0))
        self.radius = lattice.Length("GraphLattice", "radius", radius)
        self.material = _material("GraphLattice", material)
        super().__init__(lattice.StrutLattice(edges, self.radius, material=self.material))


def _edges(owner: str, edges) -> np.ndarray:
    """``[(Vec3, Vec3), ...]`` as an array ``(n, 2, 3)``."""
    if isinstance(edges, (str, Vec3)) or not isinstance(edges, Sequence) or not edges:
        raise DesignError(f"{owner}: edges must be a non-empty list of (start, end) pairs of pyvcad.Vec3", hint=_DOCS)
    out = []
    for edge in edges:
        if not isinstance(edge, Sequence) or len(edge) != 2:
            raise DesignError(f"{owner}: an edge is a (start, end) pair of pyvcad.Vec3, got {edge!r}", hint=_DOCS)
        out.append([_vec3(owner, "an edge's end", end) for end in edge])
    return np.asarray(out, dtype=float)


class Tile(Node):
    """``Tile([cell_x, cell_y, cell_z][, child])`` or ``Tile()`` with ``set_child``: repeats
    the child without end, every cell of the given sizes (mm) or else every box of the
    child's bounds, the cell centred on the child's bounds (:mod:`fgslice.design.tile`;
    a ``GraphLattice`` child repeats its struts exactly, :mod:`fgslice.design.lattice`).
    It has no bounds: intersect it with a bounded shape."""

    def __init__(self, *args) -> None:
        super().__init__()
        self._child = None
        if args and isinstance(args[-1], Node):
            self.set_child(args[-1])
            args = args[:-1]
        _overload("Tile", args, {0: "", 3: "cell_x, cell_y, cell_z"}, then=", then optionally the child")
        self._cell = np.array([_number("Tile", a, v) for a, v in zip(("cell_x", "cell_y", "cell_z"), args)]) if args else None
        if self._cell is not None and not np.all(self._cell > 0):
            raise DesignError(f"Tile: cell sizes must be positive, got {tuple(self._cell)}")

    def set_child(self, child) -> None:
        """The node to repeat."""
        self._child = _child("Tile", child)

    def _build(self, convert) -> nodes.Node:
        if self._child is None:
            raise DesignError("Tile has no child", hint="give it the node to repeat with set_child(node)")
        cell = self._child
        if not isinstance(cell, GraphLattice):
            return tile(convert(cell), self._cell)
        lo, hi = cell.extent
        period = self._cell if self._cell is not None else hi - lo
        if not np.all(period > 0):
            raise DesignError("Tile: the lattice's edges span no volume, so its cell size is unknown",
                              hint="give the cell sizes: Tile(cell_x, cell_y, cell_z, lattice)")
        origin = (lo + hi) / 2 - period / 2
        return lattice.StrutLattice(cell._node.edges, cell.radius, period=period, origin=origin, material=cell.material)


def _bind(owner: str, names: tuple[str, ...], args: tuple, kwargs: dict, defaults: dict) -> list:
    """The values of ``names`` from positional and keyword arguments, or a DesignError naming the odd one."""
    if len(args) > len(names):
        raise DesignError(f"{owner} takes at most {len(names)} arguments ({', '.join(names)}), got {len(args)}",
                          hint=_DOCS)
    values = dict(zip(names, args))
    for key, value in kwargs.items():
        if key not in names:
            raise DesignError(f"{owner} has no argument '{key}'", hint=f"its arguments are {', '.join(names)}")
        if key in values:
            raise DesignError(f"{owner} got '{key}' twice")
        values[key] = value
    missing = [n for n in names if n not in values and n not in defaults]
    if missing:
        raise DesignError(f"{owner} is missing its argument '{missing[0]}'", hint=_DOCS)
    return [values.get(n, defaults.get(n)) for n in names]


class _Children(Node):
    """Union / Intersection: ``([k][, flag][, [children]])`` or the children themselves
    (OpenVCAD 3). A smoothing radius ``k > 0`` blends the children (:mod:`fgslice.design.smooth`);
    the distribution flag mixes an
    intersection's materials (a union's overlaps take the first child's materials);
    ``add_child`` adds one child."""

    _make = None
    _k = 0.0

    def __init__(self, *args) -> None:
        super().__init__()
        owner = type(self).__name__
        if args and all(isinstance(a, Node) for a in args):
            args = (list(args),)
        rest = list(args)
        self._k = 0.0
        if rest and not isinstance(rest[0], bool) and isinstance(rest[0], numbers.Real):
            self._k = float(rest.pop(0))
            if self._k < 0:
                raise DesignError(f"{owner}: the smoothing radius k must be >= 0, got {self._k:g}", hint=_DOCS)
        self._distribution = bool(rest.pop(0)) if rest and isinstance(rest[0], bool) else False
        children = rest.pop(0) if rest and isinstance(rest[0], Sequence) and not isinstance(rest[0], str) else []
        if rest:
            raise DesignError(f"{owner} takes ([k][, flag][, [children]]) or nodes, got {args!r}", hint=_DOCS)
        self._children = []
        for child in children:
            self.add_child(child)

    def add_child(self, child) -> None:
        """Append ``child``."""
        self._children.append(_child(type(self).__name__, child))

    def _build(self, convert) -> nodes.Node:
        if not self._children:
            raise DesignError(f"{type(self).__name__} has no children", hint="add them with add_child(node)")
        if self._k > 0:
            return smooth.SmoothUnion(self._k, [convert(c) for c in self._children])
        return type(self)._make(*(convert(c) for c in self._children))


class Union(_Children):
    _make = staticmethod(api.union)


class Intersection(_Children):
    """``Intersection(True, ...)`` (``intersect_distribution``) mixes the children's
    materials: the mean of their fractions."""

    def _build(self, convert) -> nodes.Node:
        if not self._children:
            raise DesignError("Intersection has no children", hint="add them with add_child(node)")
        if self._k > 0 and self._distribution:
            raise DesignError("Intersection: a smooth blend (k > 0) with intersect_distribution is not supported "
                              "by fgslice", hint="use one of the two: Intersection(k, False, ...) or Intersection(True, ...)")
        if self._k > 0:
            return smooth.SmoothIntersection(self._k, [convert(c) for c in self._children])
        return api.intersection(*(convert(c) for c in self._children), mix=self._distribution)


def _child(owner: str, child) -> Node:
    if not isinstance(child, Node):
        raise DesignError(f"{owner}: a child must be a pyvcad node, got {type(child).__name__}")
    return child


class Difference(Node):
    """``Difference(left, right)`` (or ``()`` with ``set_left`` / ``set_right``): left
    minus right, with left's materials; a leading smoothing radius ``k > 0`` rounds the
    cut (:mod:`fgslice.design.smooth`)."""

    _k = 0.0

    def __init__(self, *args) -> None:
        super().__init__()
        if len(args) in (1, 3):
            self._k, args = _number("Difference", "k", args[0]), args[1:]
            if self._k < 0:
                raise DesignError(f"Difference: the smoothing radius k must be >= 0, got {self._k:g}", hint=_DOCS)
        _overload("Difference", args, {0: "", 2: "left, right"})
        self._left = self._right = None
        if args:
            self.set_left(args[0])
            self.set_right(args[1])

    def set_left(self, child) -> None:
        """The node to cut from."""
        self._left = _child("Difference", child)

    def set_right(self, child) -> None:
        """The node cut away."""
        self._right = _child("Difference", child)

    def _build(self, convert) -> nodes.Node:
        if self._left is None or self._right is None:
            raise DesignError("Difference needs a left and a right child", hint="use set_left(a) and set_right(b)")
        if self._k > 0:
            return smooth.SmoothDifference(self._k, [convert(self._left), convert(self._right)])
        return api.difference(convert(self._left), convert(self._right))


class _Unary(Node):
    """A node with one child, given last in the constructor or by ``set_child``."""

    def __init__(self, owner: str, args: tuple, forms: dict[int, str]) -> None:
        super().__init__()
        self._child = None
        if args and isinstance(args[-1], Node):
            self.set_child(args[-1])
            args = args[:-1]
        _overload(owner, args, forms, then=", then optionally the child")
        self._args = args

    def set_child(self, child) -> None:
        """The node this one applies to."""
        self._child = _child(type(self).__name__, child)

    def _build(self, convert) -> nodes.Node:
        if self._child is None:
            raise DesignError(f"{type(self).__name__} has no child", hint="give it with set_child(node)")
        return self._apply(convert(self._child))


def _xyz(owner: str, args: tuple, default: float) -> tuple[float, float, float]:
    return tuple(_number(owner, a, v) for a, v in zip("xyz", args)) if args else (default,) * 3


class Translate(_Unary):
    """``Translate(x, y, z[, child])``: moves the child (mm)."""

    def __init__(self, *args) -> None:
        super().__init__("Translate", args, {0: "", 3: "x, y, z"})
        self._offset = _xyz("Translate", self._args, 0.0)

    def _apply(self, child: nodes.Node) -> nodes.Node:
        return api.translate(self._offset, child)


class Scale(_Unary):
    """``Scale(x, y, z[, child])`` or ``Scale(factor[, child])`` (OpenVCAD 3): stretches
    the child by non-zero factors."""

    def __init__(self, *args) -> None:
        super().__init__("Scale", args, {0: "", 1: "factor", 3: "x, y, z"})
        self._factors = _xyz("Scale", self._args * 3 if len(self._args) == 1 else self._args, 1.0)
        if not all(self._factors):
            raise DesignError("Scale: factors must be non-zero")

    def _apply(self, child: nodes.Node) -> nodes.Node:
        return api.scale(self._factors, child)


class Rotate(_Unary):
    """``Rotate(pitch, yaw, roll[, around][, child])`` or ``Rotate(Vec3(pitch, yaw, roll)[,
    child])``: degrees about X, Y and Z, applied in OpenVCAD's order roll, then yaw, then
    pitch (about the fixed axes), turning about the point ``around`` (default the origin)."""

    def __init__(self, *args) -> None:
        super().__init__("Rotate", args, {0: "", 1: "angles: Vec3", 3: "pitch, yaw, roll",
                                          4: "pitch, yaw, roll, around: Vec3"})
        angles = _vec3("Rotate", "angles", self._args[0]) if len(self._args) == 1 else self._args[:3] or (0, 0, 0)
        self._angles = tuple(_number("Rotate", a, v) for a, v in zip(("pitch", "yaw", "roll"), angles))
        self._around = _vec3("Rotate", "around", self._args[3]) if len(self._args) == 4 else (0.0, 0.0, 0.0)

    def _apply(self, child: nodes.Node) -> nodes.Node:
        pitch, yaw, roll = self._angles
        turned = child if not any(self._around) else api.translate(tuple(-v for v in self._around), child)
        for angles in ((0.0, 0.0, roll), (0.0, yaw, 0.0), (pitch, 0.0, 0.0)):
            if any(angles):
                turned = api.rotate(angles, turned)
        return turned if not any(self._around) else api.translate(self._around, turned)


class FGrade(_Unary):
    """``FGrade(functions, materials, prob_mode[, child])``: ``functions[i]`` (an
    expression string) is the fraction of ``materials[i]`` (ids from
    ``default_materials.id``, or plain numbers: the material of that id in
    :class:`MaterialDefs`). Both modes give the continuous fractions."""

    def __init__(self, *args) -> None:
        super().__init__("FGrade", args, {3: "functions, materials, prob_mode"})
        functions, materials, prob_mode = self._args
        if isinstance(functions, str) or not isinstance(functions, Sequence):
            raise DesignError(f"FGrade: functions must be a list of expression strings, got {functions!r}")
        if not isinstance(materials, Sequence) or not all(
                isinstance(m, numbers.Integral) and not isinstance(m, bool) for m in materials):
            raise DesignError("FGrade: materials must be a list of ids from default_materials.id(name)", hint=_DOCS)
        materials = [m if isinstance(m, MaterialId) else default_materials.name_of(m) for m in materials]
        if not isinstance(prob_mode, bool):
            raise DesignError(f"FGrade: prob_mode must be True or False, got {prob_mode!r}")
        self._fields, self._names = [_field("FGrade", f, with_d=True) for f in functions], [m.name for m in materials]

    def _apply(self, child: nodes.Node) -> nodes.Node:
        return api.fgrade(self._fields, self._names, child)


def to_node(root: Node) -> nodes.Node:
    """The fgslice node tree of ``root``; errors name the line where the failing node was made."""
    if not isinstance(root, Node):
        raise DesignError(f"the design's root must be a pyvcad node, got {type(root).__name__}")
    from fgslice.compat import pyvcad_v3

    building: set[int] = set()
    above: list[frozenset[str]] = [frozenset()]  # attribute names set by the ancestors (OpenVCAD 3)

    def convert(node: Node) -> nodes.Node:
        if id(node) in building:
            raise context.locate(DesignError(f"{type(node).__name__} contains itself"), node._where)
        building.add(id(node))
        above.append(above[-1] | pyvcad_v3.produced(node))
        try:
            built = node._build(convert)
            return _stamp(pyvcad_v3.dress(node, built, above[-2]), node._where)
        except FgsliceError as error:
            raise context.locate(error, node._where)
        finally:
            above.pop()
            building.discard(id(node))

    return convert(root)


def _stamp(top: nodes.Node, where: nodes.Where) -> nodes.Node:
    """Give ``where`` to the nodes of ``top`` that have no place yet (those just made),
    so that errors found when the design is built name the script's line."""
    stack = [top]
    while stack:
        node = stack.pop()
        if node.where == nodes.NOWHERE:
            node.where = where
            stack.extend(node.children)
    return top


class FontAspect(enum.Enum):
    """``pyvcad.FontAspect``: the style of a ``Text``'s font."""

    Regular = "regular"
    Bold = "bold"
    Italic = "italic"
    BoldItalic = "bolditalic"


class HorizontalAlignment(enum.Enum):
    """``pyvcad.HorizontalAlignment``: where each line of a ``Text`` sits on X = 0."""

    Left = "left"
    Center = "center"
    Right = "right"


class VerticalAlignment(enum.Enum):
    """``pyvcad.VerticalAlignment``: where a ``Text`` block sits on Y = 0."""

    Bottom = "bottom"
    Center = "center"
    Top = "top"


class Text(_Leaf):
    """``Text(text, height, depth, material=1, aspect=FontAspect.Regular, font='Consolas',
    h_align=HorizontalAlignment.Center, v_align=VerticalAlignment.Center)``: the string
    (lines split at ``\\n``) ``height`` mm tall over all lines, extruded ``depth`` mm
    about Z = 0 (:mod:`fgslice.design.text`; fonts other than matplotlib's map to DejaVu)."""

    def __init__(self, *args, **kwargs) -> None:
        content, height, depth, material, aspect, font, h_align, v_align = _bind(
            "Text", ("text", "height", "depth", "material", "aspect", "font", "h_align", "v_align"), args, kwargs,
            {"material": 1, "aspect": FontAspect.Regular, "font": "Consolas", "h_align": HorizontalAlignment.Center,
             "v_align": VerticalAlignment.Center})
        if not isinstance(content, str):
            raise DesignError(f"Text: the text must be a string, got {content!r}", hint=_DOCS)
        for what, value, kind in (("aspect", aspect, FontAspect), ("h_align", h_align, HorizontalAlignment),
                                  ("v_align", v_align, VerticalAlignment)):
            if not isinstance(value, kind):
                raise DesignError(f"Text: {what} must be a pyvcad.{kind.__name__}, got {value!r}", hint=_DOCS)
        super().__init__(text_shape(content, _number("Text", "height", height), _number("Text", "depth", depth),
                                    _material("Text", material), font=str(font), aspect=aspect.value,
                                    h_align=h_align.value, v_align=v_align.value))


__all__ += ["FontAspect", "HorizontalAlignment", "VerticalAlignment", "Text"]


class PolygonExtrude(_Leaf):
    """``PolygonExtrude(vertices, height, symmetric=False, material=1)``: a planar polygon of
    ``Vec3`` vertices extruded along its normal (:func:`fgslice.design.extrusion.polygon_extrude`);
    ``PolygonExtrude()`` is the unit square from the origin to (1, 1, 0) extruded 1 mm in +Z."""

    def __init__(self, *args, **kwargs) -> None:
        if not args and not kwargs:
            args = ([Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(1, 1, 0), Vec3(0, 1, 0)], 1.0)
        vertices, height, symmetric, material = _bind(
            "PolygonExtrude", ("vertices", "height", "symmetric", "material"), args, kwargs,
            {"symmetric": False, "material": 1})
        if isinstance(vertices, (str, bytes)) or not isinstance(vertices, Sequence):
            raise DesignError(f"PolygonExtrude: vertices must be a list of Vec3, got {vertices!r}", hint=_DOCS)
        points = [tuple(_vec3("PolygonExtrude", "a vertex", p)) for p in vertices]
        super().__init__(polygon_extrude(points, _number("PolygonExtrude", "height", height), bool(symmetric),
                                         _material("PolygonExtrude", material)))


__all__ += ["PolygonExtrude"]


class Offset(_Unary):
    """``Offset(offset[, child])``: the child's signed distance shifted by ``offset`` mm
    (> 0 grows the part, < 0 shrinks it; :mod:`fgslice.design.offset`)."""

    def __init__(self, *args) -> None:
        super().__init__("Offset", args, {0: "", 1: "offset"})
        self._distance = _number("Offset", "offset", self._args[0]) if self._args else 0.0

    def _apply(self, child: nodes.Node) -> nodes.Node:
        return api.offset(self._distance, child)


class Shell(_Unary):
    """``Shell(thickness[, child])``: the child hollowed to a closed wall ``thickness`` mm
    (> 0) thick inside its surface (:mod:`fgslice.design.offset`)."""

    def __init__(self, *args) -> None:
        super().__init__("Shell", args, {1: "thickness"})
        self._thickness = _number("Shell", "thickness", self._args[0])
        if not self._thickness > 0:
            raise DesignError(f"Shell: thickness must be positive, got {self._thickness:g}", hint=_DOCS)

    def _apply(self, child: nodes.Node) -> nodes.Node:
        return api.shell(self._thickness, child)


__all__ += ["Offset", "Shell"]


class Sum(Node):
    """``Sum([iso_value][, [children]])`` + ``add_child``: the children's signed distances
    added; inside where the sum is at most ``iso_value`` mm (:mod:`fgslice.design.sum`)."""

    def __init__(self, *args) -> None:
        super().__init__()
        _overload("Sum", args, {0: "", 1: "iso_value", 2: "iso_value, children"})
        self._iso = _number("Sum", "iso_value", args[0]) if args else 0.0
        children = args[1] if len(args) == 2 else []
        if isinstance(children, (str, Node)) or not isinstance(children, Sequence):
            raise DesignError(f"Sum: children must be a list of pyvcad nodes, got {children!r}", hint=_DOCS)
        self._children = []
        for child in children:
            self.add_child(child)

    def add_child(self, child) -> None:
        """Append ``child``."""
        self._children.append(_child("Sum", child))

    def _build(self, convert) -> nodes.Node:
        from fgslice.design.sum import Sum as SumNode

        if not self._children:
            raise DesignError("Sum has no children", hint="add them with add_child(node)")
        return SumNode(self._iso, [convert(c) for c in self._children])


class Blend(_Unary):
    """OpenVCAD 2: ``Blend(radius[, child])``: the child's materials averaged over the box
    ``radius`` mm each side of every point (``blend(2 radius) { child }``); the geometry
    is the child's. OpenVCAD 3's ``Blend(child, attributes, physical_radius, ...)`` is
    :class:`fgslice.compat.pyvcad_v3.AttributeBlend`."""

    def __new__(cls, *args, **kwargs):
        if (args and isinstance(args[0], Node)) or kwargs:
            from fgslice.compat import pyvcad_v3

            return pyvcad_v3.AttributeBlend(*args, **kwargs)
        return super().__new__(cls)

    def __init__(self, *args) -> None:
        super().__init__("Blend", args, {1: "radius"})
        self._radius = _number("Blend", "radius", self._args[0])
        if not self._radius > 0:
            raise DesignError(f"Blend: radius must be positive, got {self._radius:g}", hint=_DOCS)

    def _apply(self, child: nodes.Node) -> nodes.Node:
        return api.blend(2 * self._radius, child)


class Convolution(Node):
    """OpenVCAD 2's ``Convolution(kernel[, child])``: refused. Its integer kernel counts
    voxels of OpenVCAD's sampler, a grid fgslice does not have (it samples the design
    exactly), so the kernel has no size here; ``Blend(radius, child)`` gives the
    blending kernel a size in mm. ``BlendKernel`` and ``PassKernel`` build the kernels."""

    def __init__(self, *args) -> None:
        super().__init__()
        raise DesignError("Convolution is not supported by fgslice: its kernel is counted in voxels of OpenVCAD's "
                          "sampler, which fgslice does not use, so the kernel has no size in mm",
                          hint="blend materials with pv.Blend(radius_mm, child)")

    @staticmethod
    def BlendKernel(x: int, y: int, z: int) -> list:
        """A kernel of ``x`` by ``y`` by ``z`` ones."""
        return [[[1] * int(z) for _ in range(int(y))] for _ in range(int(x))]

    @staticmethod
    def PassKernel(x: int, y: int, z: int) -> list:
        """A kernel of zeros with a one at its centre."""
        kernel = [[[0] * int(z) for _ in range(int(y))] for _ in range(int(x))]
        kernel[int(x) // 2][int(y) // 2][int(z) // 2] = 1
        return kernel


__all__ += ["Sum", "Blend", "Convolution"]


class SupportAnalyzer:
    """``SupportAnalyzer(input_model, voxel_size, material_id=1)``: ``analyze()`` gives the
    support under the model's overhangs in ``material_id``, as a node: the points outside
    the model with model material above them, down to its lowest z
    (:mod:`fgslice.design.shadow_support`). The model's sections are stacked every
    ``voxel_size.z`` mm (at least 0.1 mm); in x and y the support is as exact as they are."""

    def __init__(self, *args, **kwargs) -> None:
        owner = type(self).__name__
        model, voxel, material = _bind(owner, ("input_model", "voxel_size", "material_id"), args, kwargs,
                                       {"material_id": 1})
        self._model = _child(owner, model)
        self._voxel = _vec3(owner, "voxel_size", voxel)
        if not min(self._voxel) > 0:
            raise DesignError(f"{owner}: voxel_size must be positive on every axis, got {self._voxel}", hint=_DOCS)
        self._material = _material(owner, material)

    def analyze(self) -> Node:
        """The support volume (a node to add to the design)."""
        return _Support(self._model, self._voxel[2], self._material)


class SupportAnalyzerParallel(SupportAnalyzer):
    """OpenVCAD's multi-threaded ``SupportAnalyzer``: the same support."""


class _Support(Node):
    """What ``SupportAnalyzer.analyze()`` returns; built when the design is."""

    def __init__(self, model: Node, step: float, material: str | None) -> None:
        super().__init__()
        self._model, self._step, self._material = model, step, material

    def _build(self, convert) -> nodes.Node:
        from fgslice.design.shadow_support import ShadowSupport

        return ShadowSupport(convert(self._model), self._step, self._material)


__all__ += ["SupportAnalyzer", "SupportAnalyzerParallel"]
