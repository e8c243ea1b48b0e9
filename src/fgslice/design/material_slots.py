"""A design's materials put on chosen filament slots (mixing channels, tools).

A design's materials go to the machine in the order the design first names them: the
first on channel A (tool T0 of the palette), the second on B, and so on.
:func:`slotted` puts them in the order of slots given by name (OpenVCAD's
``volume_fraction_materials = {"red": 1, "blue": 2}``, 1-based): its root is wrapped in a
:class:`MaterialSlots` grade whose materials are the named ones in slot order and whose
fractions are the design's own. A material of the design without a slot is left out, and
the named materials' fractions are normalized without it (as OpenVCAD's slicer-project
compilers do); where only unnamed materials are, the first slot's material is printed.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from fgslice.design import nodes
from fgslice.errors import DesignError


class MaterialSlots(nodes.Fgrade):
    """The child's normalized fractions of the materials ``names``, in that order
    (``columns``: the child's own material columns, as its design evaluates them)."""

    kind = "material_slots"

    def __init__(self, names: list[str], columns: nodes.Columns, child: nodes.Node) -> None:
        super().__init__([], names, (child,))
        self.inner = columns

    _group = None

    def _values(self, x, y, z) -> list:
        shape = np.broadcast_shapes(*map(np.shape, (x, y, z)))
        x, y, z = (np.ravel(v) for v in np.broadcast_arrays(x, y, z))
        fractions = nodes.normalized(self._body.raw(x, y, z, self.inner))
        return [fractions[:, self.inner.index[name.lower()]].reshape(shape) for name in self.materials]


def slotted(design: nodes.NodeDesign, slots: Mapping[str, int]) -> nodes.NodeDesign:
    """``design`` with its materials on the 1-based ``slots`` given by material name:
    itself when they are already so; materials without a slot are left out.

    Raises:
        DesignError: a name is not one of the design's materials, or the slots are not
            1, 2, ... n, each once (a machine's channels have no gaps).
    """
    names = {m.name.lower(): m.name for m in design.materials}
    unknown = [name for name in slots if name.lower() not in names]
    if unknown:
        raise DesignError(f"volume_fraction_materials names '{unknown[0]}', which the design's volume fractions do "
                          f"not hold (they hold {', '.join(names.values())})",
                          hint="give each material of the VolumeFractionsAttribute its filament slot")
    order = sorted(slots.items(), key=lambda item: item[1])
    if [slot for _, slot in order] != list(range(1, len(order) + 1)):
        raise DesignError(f"volume_fraction_materials puts materials on slots {', '.join(str(s) for _, s in order)}: "
                          "fgslice gives a design's materials channels 1, 2, ... n, each to one material",
                          hint="number the slots from 1 without gaps, in the order the filaments are loaded")
    wanted = [names[name.lower()] for name, _ in order]
    present = [m.name for m in design.materials]
    if wanted == present:
        return design
    if design.has_void:
        wanted.append(nodes.VOID)
    root = MaterialSlots(wanted, design.columns, design.root)
    return nodes.NodeDesign(root, design.library, hint_bounds=design.hint_bounds, voxel_size=design.voxel_size,
                            section_spacing=design.section_spacing, source=design.source)
