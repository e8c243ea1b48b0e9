"""Up-front refusal of jobs that would need an absurd amount of work or memory.

:func:`check_resources` estimates, from the design's bounding box and the settings alone
(no geometry is sectioned, nothing large is allocated), how many field samples a layer's
color faces need and how long the toolpaths get, and raises
:class:`~fgslice.errors.ResourceError` naming the numbers and the setting to change when
an estimate exceeds its limit. The layer count has its own guard in
:func:`fgslice.slicing.plan_layers.layer_heights`.

Estimates (mm, mm^2):

* face samples per layer (strategy 2, more than one color): the grid of
  :func:`fgslice.slicing.regions.color_faces` over the footprint, spacing ``bead_width``;
* toolpath length: footprint area x layers / line spacing. The footprint is the XY
  bounding box, an upper bound of any section's area. Strategy 2 fills every layer
  densely (spacing ``bead_width``); strategy 1 fills ``top_layers + bottom_layers``
  layers densely and the others at ``infill_density`` percent, plus ``walls`` loops of
  the bounding box's perimeter on every layer.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from fgslice.design.base import Design
from fgslice.errors import ResourceError
from fgslice.settings import Settings
from fgslice.slicing.regions import MAX_GRID_POINTS, face_spacing

MAX_LAYER_PATH_MM = 1e7
"""Longest toolpath estimate of one layer, mm (10 km: about two days at 60 mm/s)."""

MAX_TOTAL_PATH_MM = 1e9
"""Longest toolpath estimate of a print, mm (1000 km: about half a year at 60 mm/s)."""


@dataclass(frozen=True)
class Estimate:
    """What a job would need, from its bounding box and settings.

    Attributes:
        layers: layer count.
        face_samples: field samples of one layer's color faces (0 when none are sampled).
        layer_path_mm: toolpath length of the densest layer, mm.
        total_path_mm: toolpath length of the print, mm.
    """

    layers: int
    face_samples: int
    layer_path_mm: float
    total_path_mm: float


def estimate(design: Design, settings: Settings, layers: int) -> Estimate:
    """The work ``design`` sliced with ``settings`` into ``layers`` layers would need."""
    (x0, y0, _), (x1, y1, _) = design.bounds()
    width, depth = max(x1 - x0, 0.0), max(y1 - y0, 0.0)
    w = settings.bead_width
    samples = 0
    if settings.strategy == 2 and settings.colors > 1 and len(design.materials) > 1:
        spacing = face_spacing(settings)
        samples = (math.ceil(width / spacing) + 3) * (math.ceil(depth / spacing) + 3)
    dense = width * depth / w
    if settings.strategy == 2:
        layer_mm, total_mm = dense, dense * layers
    else:
        walls = settings.walls * 2.0 * (width + depth)
        solid = min(layers, settings.top_layers + settings.bottom_layers)
        sparse = dense * settings.infill_density / 100.0
        layer_mm = walls + (dense if solid else sparse)
        total_mm = walls * layers + dense * solid + sparse * (layers - solid)
    return Estimate(layers, samples, layer_mm, total_mm)


def _days(length_mm: float, settings: Settings) -> str:
    days = length_mm / settings.print_speed / 86400.0
    return f"{days:.3g} days" if days >= 1 else f"{days * 24:.3g} h"


def check_resources(design: Design, settings: Settings, layers: int) -> Estimate:
    """Refuse a job whose estimates exceed the limits; return the estimate otherwise.

    Runs in microseconds: only the bounding box and the settings are read.

    Raises:
        ResourceError: more than ``MAX_GRID_POINTS`` face samples per layer, a layer's
            toolpaths longer than :data:`MAX_LAYER_PATH_MM`, or the print's longer than
            :data:`MAX_TOTAL_PATH_MM`; the message gives the estimate and the limit.
    """
    est = estimate(design, settings, layers)
    w = settings.bead_width
    lower = "infill_density, " if settings.strategy == 1 else ""
    if est.face_samples > MAX_GRID_POINTS:
        raise ResourceError(
            f"the color faces of one layer would need {est.face_samples:.3g} field samples at the "
            f"bead_width spacing of {w:g} mm (limit {MAX_GRID_POINTS:.3g})",
            hint="raise bead_width (--set bead_width=...), slice fewer colors (--colors), or check the design's units (mm)",
        )
    if est.layer_path_mm > MAX_LAYER_PATH_MM:
        raise ResourceError(
            f"one layer would need about {est.layer_path_mm / 1e6:.3g} km of toolpaths "
            f"({_days(est.layer_path_mm, settings)} at {settings.print_speed:g} mm/s) with bead_width {w:g} mm; "
            f"the limit is {MAX_LAYER_PATH_MM / 1e6:g} km",
            hint=f"raise bead_width, lower {lower}or check the design's units (mm)",
        )
    if est.total_path_mm > MAX_TOTAL_PATH_MM:
        raise ResourceError(
            f"the print would need about {est.total_path_mm / 1e6:.3g} km of toolpaths over {layers} layers "
            f"({_days(est.total_path_mm, settings)} at {settings.print_speed:g} mm/s); "
            f"the limit is {MAX_TOTAL_PATH_MM / 1e6:g} km",
            hint=f"raise layer_height or bead_width, lower {lower}or check the design's units (mm)",
        )
    return est
