"""fgslice: slicer for functionally graded multi-material 3D printing.

The public API::

    import fgslice
    design = fgslice.load_design("examples/vase.vcad")
    settings = fgslice.load_settings("marlin-mixing", {"colors": "16", "strategy": "1"})
    result = fgslice.slice_to_gcode(design, settings, "vase.gcode")
    print(result.stats["extruded_mm3"])

Designs can also be built in Python with :mod:`fgslice.design.api`. Names are imported
on first use, so ``import fgslice`` (and the command line) starts quickly.
"""

from importlib import import_module

__version__ = "0.1.0"
"""The package version (read by the build for its metadata; written in every G-code header)."""

_EXPORTS = {
    "api": "fgslice.design",
    "check_design": "fgslice.design",
    "load_design": "fgslice.design",
    "parse_design": "fgslice.design",
    "FgsliceError": "fgslice.errors",
    "SliceResult": "fgslice.pipeline",
    "slice_to_gcode": "fgslice.pipeline",
    "Settings": "fgslice.settings",
    "load_settings": "fgslice.settings",
}

__all__ = list(_EXPORTS)


def __getattr__(name: str):
    if name not in _EXPORTS:
        raise AttributeError(f"module 'fgslice' has no attribute {name!r}")
    return getattr(import_module(_EXPORTS[name]), name)
