"""Where the part sits on the bed and which layers slice it.

Placement: the design's lowest point goes to z = 0; in XY the center of its bounding box
goes to the bed's center (``settings.center``) or to ``(position_x, position_y)``. The
part must fit the bed (``bed_x`` x ``bed_y`` x ``max_z``, mm).

Layers: layer ``k`` (0-based) has its top at ``z = (k + 1) h`` and is sliced at its
mid-height ``(k + 1/2) h``. A layer exists when its slicing plane lies inside the part,
so a part of height ``H`` gets ``n = ceil(H / h - 1/2)`` layers: ``ceil(H / h)`` when the
last partial layer is more than half a layer thick, one fewer otherwise (the printed
height is ``H`` rounded to the nearest multiple of ``h``).
"""

from __future__ import annotations

import math

from fgslice.design.base import Design
from fgslice.errors import ResourceError, SliceError
from fgslice.settings import Settings
from fgslice.slicing.layers import Placement

MAX_LAYERS = 100_000
_EPS = 1e-9


def _checked_bounds(design: Design) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    (x0, y0, z0), (x1, y1, z1) = design.bounds()
    values = (x0, y0, z0, x1, y1, z1)
    if not all(math.isfinite(v) for v in values):
        raise SliceError(
            f"the design's bounding box is not finite: {values}",
            hint="bound the geometry (an infinite primitive needs an intersection with a finite one)",
        )
    if x1 < x0 or y1 < y0 or z1 < z0:
        raise SliceError("the design is empty: its bounding box has no extent", hint="check the geometry's booleans")
    return (x0, y0, z0), (x1, y1, z1)


def place_design(design: Design, settings: Settings) -> Placement:
    """The translation putting ``design`` on the bed; SliceError if it does not fit.

    Raises:
        SliceError: the footprint (mm) exceeds ``bed_x`` x ``bed_y``, the height exceeds
            ``max_z``, or (``center = false``) the part at ``position_x/y`` overhangs the bed.
    """
    (x0, y0, z0), (x1, y1, z1) = _checked_bounds(design)
    width, depth, height = x1 - x0, y1 - y0, z1 - z0
    bed = f"{settings.bed_x:g} x {settings.bed_y:g} x {settings.max_z:g} mm"
    if width > settings.bed_x + _EPS or depth > settings.bed_y + _EPS:
        raise SliceError(
            f"the part's footprint {width:.2f} x {depth:.2f} mm exceeds the bed {settings.bed_x:g} x {settings.bed_y:g} mm "
            f"(profile {settings.profile_name})",
            hint=f"scale it to fit, {_fitting_scale(width, depth, height, settings)}, or use a profile with a bigger "
                 "bed (--profile)",
        )
    if height > settings.max_z + _EPS:
        raise SliceError(
            f"the part's height {height:.2f} mm exceeds the build height {settings.max_z:g} mm (bed {bed})",
            hint=f"scale it to fit, {_fitting_scale(width, depth, height, settings)}, or use a profile with a taller "
                 "build volume (--profile)",
        )
    cx, cy = (settings.bed_x / 2, settings.bed_y / 2) if settings.center else (settings.position_x, settings.position_y)
    offset = (cx - (x0 + x1) / 2, cy - (y0 + y1) / 2, -z0)
    bx0, by0, bx1, by1 = x0 + offset[0], y0 + offset[1], x1 + offset[0], y1 + offset[1]
    if bx0 < -_EPS or by0 < -_EPS or bx1 > settings.bed_x + _EPS or by1 > settings.bed_y + _EPS:
        raise SliceError(
            f"the part centered at ({cx:g}, {cy:g}) spans x {bx0:.2f}..{bx1:.2f}, y {by0:.2f}..{by1:.2f} mm, "
            f"outside the bed 0..{settings.bed_x:g} x 0..{settings.bed_y:g} mm",
            hint="--set center=true, or move it with --set position_x=... position_y=...",
        )
    return Placement(offset=offset)


def _fitting_scale(width: float, depth: float, height: float, settings: Settings) -> str:
    """The ``--set scale=`` that fits a part of these sizes (mm, as designed times
    ``settings.scale``) on the bed with its skirt and brim around it: the largest factor
    in hundredths."""
    margin = settings.brim_width + (settings.skirt_distance + settings.skirt_loops * settings.bead_width
                                    if settings.skirt_loops else 0.0)
    room = min((settings.bed_x - 2 * margin) / width if width else math.inf,
               (settings.bed_y - 2 * margin) / depth if depth else math.inf,
               settings.max_z / height if height else math.inf)
    return f"--set scale={math.floor(100 * settings.scale * room) / 100:g}"


def layer_count(height: float, layer_height: float) -> int:
    """Layers of thickness ``layer_height`` whose mid-plane lies inside a part ``height`` mm
    tall, its top face included: the height rounded to the nearest layer, halves up (a
    1.5 mm part at 0.2 mm has 8 layers, as in the paper's tensile specimens)."""
    return max(0, math.floor(height / layer_height + 0.5 + _EPS))


def layer_heights(design: Design, settings: Settings) -> list[tuple[int, float, float]]:
    """``(index, z_top, height)`` of every layer, bed frame, mm; ``z_top = (index + 1) h``.

    Raises:
        SliceError: the part is thinner than half a layer (no layers).
        ResourceError: more than 100 000 layers (checked before building the list).
    """
    (_, _, z0), (_, _, z1) = _checked_bounds(design)
    h = settings.layer_height
    n = layer_count(z1 - z0, h)
    if n == 0:
        raise SliceError(
            f"the design has no layers: its height {z1 - z0:g} mm is less than half the layer height ({h:g} mm)",
            hint="lower layer_height (--set layer_height=...) or scale the design up",
        )
    if n > MAX_LAYERS:
        raise ResourceError(
            f"the design would need {n} layers of {h:g} mm (its height is {z1 - z0:g} mm); the limit is {MAX_LAYERS}",
            hint="raise layer_height or check the design's units (mm)",
        )
    return [(k, (k + 1) * h, h) for k in range(n)]
