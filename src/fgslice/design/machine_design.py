"""A design as the machine of a slice's settings prints it.

:func:`for_machine` applies, in order, the profile's ``attribute_tables``
(:mod:`fgslice.design.profile_tables`: attributes without machine meaning converted to
machine attributes) and the filament colours (:mod:`fgslice.design.color_mix`: a colour
attribute printed as filament mixtures). ``slice``, ``check``, ``simulate`` and the report
all see the design through it, so they agree on what is printed.
"""

from __future__ import annotations

from fgslice.design.color_mix import mix_colors
from fgslice.design.profile_tables import apply_attribute_tables


def for_machine(design, settings):
    """``design`` as the machine of ``settings`` prints it (itself when nothing applies)."""
    return mix_colors(apply_attribute_tables(design, settings), settings)
