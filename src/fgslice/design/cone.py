"""A solid right circular cone (OpenVCAD 3's ``Cone(angle, height)``).

The apex is at the origin and the axis runs down the -Z axis: the base, a disc of
radius ``height * tan(angle)``, lies in the plane ``z = -height`` (``angle``: the aperture
half-angle, radians, in (0, pi/2); lengths mm). The signed distance is the exact one (the
nearest point on the slanted side or on the base disc); sections are circles of radius
``-z * tan(angle)``.
"""

from __future__ import annotations

import math

import numpy as np

from fgslice.design import nodes


class Cone(nodes.Primitive):
    """The cone of aperture half-angle ``angle`` (radians) and ``height`` (mm), apex at
    the origin, base at ``z = -height``."""

    kind = "cone"

    def __init__(self, angle: float, height: float, material: str | None = None,
                 where: nodes.Where = nodes.NOWHERE) -> None:
        super().__init__(material, where)
        self.angle = float(angle)
        self.height = float(height)
        self.radius = self.height * math.tan(self.angle)

    def sdf(self, x, y, z):
        # 2-D problem in (w1, w2) = (distance from the axis, z); q = the base's rim.
        w1, w2 = np.sqrt(x * x + y * y), np.asarray(z, dtype=float)
        q1, q2 = self.radius, -self.height
        t = np.clip((w1 * q1 + w2 * q2) / (q1 * q1 + q2 * q2), 0.0, 1.0)
        side = (w1 - q1 * t) ** 2 + (w2 - q2 * t) ** 2
        base = (w1 - q1 * np.clip(w1 / q1, 0.0, 1.0)) ** 2 + (w2 - q2) ** 2
        # inside: within the slanted side (w1 h + w2 r <= 0) and above the base (w2 >= -h)
        sign = np.where(np.maximum(w1 * -q2 + w2 * q1, q2 - w2) > 0, 1.0, -1.0)
        return np.sqrt(np.minimum(side, base)) * sign

    def _bounds(self):
        r = self.radius
        return np.array([-r, -r, -self.height]), np.array([r, r, 0.0])

    def _section(self, z, spacing):
        r = -z * math.tan(self.angle)
        return nodes._circle(0.0, 0.0, r, spacing) if r > 0 else nodes._EMPTY
