"""OpenVCAD compatibility: run OpenVCAD's Python design scripts unchanged.

:func:`open_design` loads a ``.py`` script (through
:func:`fgslice.compat.script.load_script`) or a ``.vcad`` file;
:mod:`fgslice.compat.pyvcad` and :mod:`fgslice.compat.pyvcad_rendering` are what the
script imports as ``pyvcad`` and ``pyvcad_rendering``. See docs/language.md.
"""

from __future__ import annotations

from pathlib import Path

SCRIPT_SUFFIX = ".py"
"""Designs whose file name ends so are OpenVCAD Python scripts; all others are .vcad text."""


def open_design(path: str | Path, materials: str | Path | None = None):
    """The :class:`~fgslice.design.nodes.NodeDesign` in ``path``: an OpenVCAD script when
    it ends in ``.py``, else ``.vcad`` text (never run as Python). The script's modules
    are imported only for a script."""
    path = Path(path)
    if path.suffix.lower() == SCRIPT_SUFFIX:
        from fgslice.compat.script import load_script

        return load_script(path, materials)
    from fgslice.design.language import load_design

    return load_design(path, materials)


__all__ = ["open_design", "SCRIPT_SUFFIX"]
