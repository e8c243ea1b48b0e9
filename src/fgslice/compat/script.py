"""Run an OpenVCAD design script (``design.py``) and return the design it renders.

The script runs as Python, in a fresh ``__main__`` namespace, with ``pyvcad``,
``pyvcad_rendering``, ``pyvcad_compilers``, ``pyvcad_metamaterials`` and ``pyvcad_attribute_resolver``
importable as :mod:`fgslice.compat.pyvcad`, :mod:`fgslice.compat.pyvcad_rendering`,
:mod:`fgslice.compat.pyvcad_compilers`, :mod:`fgslice.compat.pyvcad_metamaterials` and
:mod:`fgslice.compat.pyvcad_attribute_resolver`, and
``numba`` as :mod:`fgslice.compat.numba_standin`, ``pyvcad_rendering.render`` and its other
modules as :mod:`fgslice.compat.pyvcad_rendering`'s (``sys.modules`` entries and the script's folder
on ``sys.path``, both restored afterwards). The design is the root passed to the last
``Export`` (or compiled by a ``pyvcad_compilers`` compiler), else to the last ``Render``, else the top-level variable ``root``.
A slicer-project compiler's filaments and material slots go with the design
(:mod:`fgslice.compat.slicer_project`). Any error —
the script's own exception, an unsupported pyvcad name or argument, an invalid value — is
a :class:`~fgslice.errors.FgsliceError` at the script's file and line.

Running a script executes its Python: only run scripts you trust. ``.vcad`` files are
never run as Python.
"""

from __future__ import annotations

import builtins
import contextlib
import sys
from pathlib import Path

from fgslice.compat import context, numba_standin, pyvcad, pyvcad_rendering, slicer_project
from fgslice.design import api, nodes
from fgslice.design.language import read_design_text
from fgslice.design.materials import MaterialLibrary
from fgslice.errors import DesignError, DesignSyntaxError, FgsliceError

def load_script(path: str | Path, materials: MaterialLibrary | str | Path | None = None) -> nodes.NodeDesign:
    """Run the OpenVCAD script at ``path`` and build the design it renders.

    ``materials``: a library or a JSON materials file extending the built-in library.
    """
    path = Path(path)
    code = _compile(path, read_design_text(path, hint="a .py design is UTF-8 Python source"))
    namespace = {"__name__": "__main__", "__file__": str(path), "__builtins__": builtins}
    with context.running(path) as run, _pyvcad_importable(path.resolve().parent):
        try:
            exec(code, namespace)
        except SystemExit as stop:
            if stop.code not in (None, 0):
                raise _script_error(stop, path, f"the script exited with status {stop.code}") from None
        except FgsliceError as error:
            raise context.locate(error, _script_frame(error.__traceback__, path)) from None
        except Exception as error:  # noqa: BLE001 - any failure of the user's script is reported, located
            raise _script_error(error, path, f"the script raised {type(error).__name__}: {error}") from None
    root, where = _root(run, namespace, path)
    try:
        design = api.design(pyvcad.to_node(root), materials)
        project = run.projects.get(id(root))
        if project is not None:
            design = slicer_project.applied(design, project)
    except FgsliceError as error:
        raise context.locate(error, where) from None
    return design


def _compile(path: Path, source: str):
    try:
        return compile(source, str(path), "exec")
    except SyntaxError as error:
        raise DesignSyntaxError(
            f"the script is not valid Python: {error.msg}", file=path, line=error.lineno,
            column=error.offset, source_line=error.text.rstrip("\n") if error.text and error.offset else None,
        ) from None


@contextlib.contextmanager
def _pyvcad_importable(folder: Path):
    """``import pyvcad`` / ``pyvcad_rendering`` give fgslice's modules; the folder is on sys.path."""
    from fgslice.compat import pyvcad_attribute_resolver, pyvcad_compilers, pyvcad_metamaterials

    names = {"pyvcad": pyvcad, "pyvcad_rendering": pyvcad_rendering, "pyvcad_compilers": pyvcad_compilers,
             "pyvcad_metamaterials": pyvcad_metamaterials, "pyvcad_attribute_resolver": pyvcad_attribute_resolver,
             "numba": numba_standin,
             **{f"pyvcad_rendering.{name}": module for name, module in pyvcad_rendering.MODULES.items()}}
    saved = {name: sys.modules.get(name) for name in names}
    sys.modules.update(names)
    sys.path.insert(0, str(folder))
    try:
        yield
    finally:
        with contextlib.suppress(ValueError):
            sys.path.remove(str(folder))
        for name, module in saved.items():
            if module is None:
                sys.modules.pop(name, None)
            else:
                sys.modules[name] = module


def _script_frame(traceback, path: Path) -> nodes.Where:
    """The innermost frame of ``traceback`` in the script, as a :class:`Where`."""
    where = nodes.NOWHERE
    while traceback is not None:
        if traceback.tb_frame.f_code.co_filename == str(path):
            where = context.where_of_line(str(path), traceback.tb_lineno)
        traceback = traceback.tb_next
    return where


def _script_error(error: BaseException, path: Path, message: str) -> DesignError:
    where = _script_frame(error.__traceback__, path)
    if where.file is None:
        where = nodes.Where(str(path))
    hint = "the error is in the script, at the line shown"
    if isinstance(error, ModuleNotFoundError) and error.name:
        hint = (f"the script imports '{error.name}', which is not installed in fgslice's Python environment: "
                f"install it there (e.g. pip install {error.name.split('.')[0]})")
    return DesignError(message, hint=hint, **where.error_kwargs())


def _root(run: context.Run, namespace: dict, path: Path) -> tuple[pyvcad.Node, nodes.Where]:
    """The design's root and where the script named it."""
    for recorded in (run.exported, run.rendered):
        if recorded:
            return recorded[-1]
    root = namespace.get("root")
    if root is None:
        raise DesignError(
            "the script renders no design", file=path,
            hint="pass the root node to pyvcad_rendering.Render(root, materials), or name it 'root'",
        )
    if not isinstance(root, pyvcad.Node):
        raise DesignError(f"the script's 'root' is a {type(root).__name__}, not a pyvcad node", file=path)
    return root, nodes.Where(str(path))
