"""Two bodies mixed by a weight field (OpenVCAD 3's ``pyvcad_metamaterials.mix``).

The mixed body's signed distance is ``(1 - w) a + w b`` of the two bodies' distances ``a``
and ``b`` (mm), ``w`` the weight field clamped to 0..1: the first body where ``w = 0``,
the second where ``w = 1``, a continuous change of shape between. It lies within the
union of the two, whose bounds it takes. Sections are traced on the mixed distance
(:func:`fgslice.design.nodes.sampled_section`). Materials and attributes blend with the
same weight, as OpenVCAD's do: the fractions ``(1 - w) f_a + w f_b`` (normalized later
like any), an attribute ``(1 - w) v_a + w v_b`` per channel where both bodies give it,
the one body's value where only it does (:mod:`fgslice.design.attributes`).
"""

from __future__ import annotations

import numpy as np

from fgslice.design import nodes
from fgslice.design.lattice import Length


class Mix(nodes.Union):
    """``first`` where ``weight`` is 0, ``second`` where it is 1, their distances mixed between."""

    kind = "mix"

    def __init__(self, first: nodes.Node, second: nodes.Node, weight: Length, where: nodes.Where = nodes.NOWHERE) -> None:
        super().__init__([first, second], where)
        self.weight = weight

    def sdf(self, x, y, z):
        w = np.clip(self.weight(x, y, z), 0.0, 1.0)
        return (1 - w) * self.children[0].sdf(x, y, z) + w * self.children[1].sdf(x, y, z)

    def mixed(self, first, second, x, y, z) -> np.ndarray:
        """``(1 - w) first + w second`` of values ``(N,)`` or ``(N, k)`` at the points."""
        w = np.clip(np.broadcast_to(self.weight(x, y, z), np.shape(x)), 0.0, 1.0)
        if np.ndim(first) == 2:
            w = w[:, None]
        return (1 - w) * first + w * second

    def raw(self, x, y, z, columns):
        return self.mixed(self.children[0].raw(x, y, z, columns), self.children[1].raw(x, y, z, columns), x, y, z)

    def _sections(self, zs, spacing):
        return [nodes.sampled_section(self, z, spacing) for z in zs]
