"""Whether a design is nothing but lattice struts or TPMS walls too thin for a bead.

A strut of radius ``r`` holds, in the plane through its axis, a disc of radius ``r``; so a
lattice whose struts are at least a bead wide (``2 r >= bead_width``) always prints. A
thinner one may still print where struts meet (a body-centred cubic junction holds a
disc of about ``1.22 r``): its sections are traced over one period in Z (every
``_DZ`` mm) on a block of 3 x 3 cells, so that junctions on the middle cell's sides are
whole, and eroded by half a bead, which leaves where a bead's centre line can run. When
no erosion holds a path a bead long (every piece's half perimeter is shorter), no layer
of the lattice prints more than a dot. A graded radius or wall is taken at its largest
over the lattice's window.

A design is too thin when its geometry lies within such lattices: a lattice itself; an
intersection with one too-thin child; a union of too-thin children; a difference whose
first child is too thin; a translation, rotation about Z or scaling (the bead measured in
the child's frame: ``bead_width`` over the largest stretch in XY) or a node that only sets
materials over a too-thin child. Anything else (a solid, a tilting transform, a smooth
boolean) counts as printable, so the check never refuses a design that prints.

With ``thin_features`` on (the default), a part narrower than a bead is printed as a
single bead when it is at least ``min_feature_size`` wide: the same test then runs with
``min_feature_size`` in place of the bead, and any piece its erosion keeps (a dot
included) prints.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np
import shapely

from fgslice.design import nodes
from fgslice.design.lattice import TPMS, Length, Periodic, StrutLattice
from fgslice.errors import SliceError

_DZ = 0.05
"""Height step (mm) of the sections a thin lattice is tested on."""

_MOST_SECTIONS = 400
"""Most heights tested per lattice (a lattice without a period, taller than this many
steps, is taken as printable rather than traced here at the slicer's cost)."""


@dataclass(frozen=True)
class ThinLattice:
    """A lattice too thin for a bead: its kind, its widest strut or wall (mm, in the
    design's frame) and the radius it was given (struts; None for a TPMS wall)."""

    kind: str
    width: float
    radius: float | None


def thin_lattice(root: nodes.Node, bead_width: float, dots: bool = False) -> ThinLattice | None:
    """The widest too-thin lattice when the whole of ``root`` is too thin to print
    (see the module docstring), else None; ``dots``: a piece of any length that holds
    a disc of ``bead_width`` prints (thin features, ``bead_width`` then being
    ``min_feature_size``)."""
    found = _thin(root, bead_width, 1.0, dots)
    return None if not found else max(found, key=lambda t: t.width)


def check_lattice_widths(design, settings) -> None:
    """Refuse a design made only of lattices too thin to print (nothing would print):
    thinner than ``min_feature_size`` with ``thin_features`` on, than a bead otherwise.

    Raises:
        SliceError: naming the struts' (or walls') width, the setting and how to fix it.
    """
    from fgslice.toolpaths.thin_features import feature_limits

    root = getattr(design, "root", None)
    if settings.thin_features:
        limit = feature_limits(settings)[0]
        setting, fix = f"min_feature_size = {settings.min_feature_size} ({limit:g} mm)", "lower min_feature_size"
    else:
        limit, setting = settings.bead_width, f"bead_width = {settings.bead_width:g} mm"
        fix = "set thin_features = true, or lower bead_width (with a smaller nozzle)"
    thin = thin_lattice(root, limit, settings.thin_features) if isinstance(root, nodes.Node) else None
    if thin is None:
        return
    if thin.radius is not None:
        what = f"its struts are {thin.width:.3g} mm across (radius {thin.radius:.3g} mm)"
        hint = ("OpenVCAD's GraphLattice, Strut and beam_radius give the strut's radius, not its diameter: "
                f"a radius of at least {limit / 2:g} mm prints; or {fix}, or scale the part up")
    else:
        what = f"its walls are {thin.width:.3g} mm thick"
        hint = f"give a wall_thickness of at least {limit:g} mm, or {fix}"
    narrower = "narrower than the smallest feature printed" if settings.thin_features else "narrower than a bead"
    raise SliceError(f"nothing to print: the design is a {thin.kind} whose layers hold no bead's path: {what}, "
                     f"{narrower} ({setting})", hint=hint)


def _thin(node: nodes.Node, bead: float, scale: float, dots: bool = False) -> list[ThinLattice] | None:
    """The too-thin lattices making up ``node`` (mm widths times ``scale``, the design
    frame's stretch), or None when ``node`` may print."""
    from fgslice.design.attributes import Attribute
    from fgslice.design.moved import Placed

    if isinstance(node, Periodic):
        return _thin_lattice(node, bead, scale, dots)
    kind = type(node)
    if kind in (nodes.Intersection, nodes.Union, nodes.Difference):
        parts = [_thin(c, bead, scale, dots) for c in (node.children[:1] if kind is nodes.Difference else node.children)]
        thin = [p for p in parts if p is not None]
        if kind is nodes.Intersection:
            return min(thin, key=lambda p: max(t.width for t in p)) if thin else None
        return [t for p in thin for t in p] if len(thin) == len(parts) else None
    if isinstance(node, nodes.Affine):
        if node.moved_tree is not None or not node.keeps_z_vertical:
            return None
        stretch = float(np.linalg.svd(node.matrix[:2, :2], compute_uv=False).max())
        return _thin(node._body, bead / stretch, scale * stretch, dots)
    if isinstance(node, Placed):
        return _thin(node.shape, bead, scale, dots)
    if isinstance(node, (nodes.MaterialNode, Attribute)):
        return _thin(node._body, bead, scale, dots)
    return None


def _thin_lattice(node: Periodic, bead: float, scale: float, dots: bool = False) -> list[ThinLattice] | None:
    if isinstance(node, StrutLattice):
        width, radius = 2 * node.reach, node.reach
        thickest = copy.copy(node)
        thickest.beam = Length(node.kind, "radius", radius)
        if len(node.joints):
            thickest.joint = thickest.beam
    elif isinstance(node, TPMS) and node.mode == "sheet":
        width, radius = node.thickness.range_over(*node.bounds())[1], None
        thickest = copy.copy(node)
        thickest.thickness = Length(node.kind, "wall_thickness", width)
    else:
        return None
    if width >= bead:
        return None
    if node.period is not None:  # 3 x 3 cells in XY around the cell at the origin, one period in Z
        lo = np.where(np.arange(3) < 2, node.origin - node.period, node.origin)
        hi = np.where(np.arange(3) < 2, node.origin + 2 * node.period, node.origin + node.period)
    else:
        lo, hi = (np.asarray(v, dtype=float) for v in node.bounds())
    heights = np.arange(lo[2], hi[2] + _DZ / 2, _DZ)
    if heights.size > _MOST_SECTIONS:
        return None
    thickest.window = (lo, hi)
    for name in ("_cached_bounds", "copies", "_kept_sections"):
        thickest.__dict__.pop(name, None)
    spacing = min(0.1, width / 4)
    for section in thickest.sections(list(heights), spacing):
        if section.is_empty:
            continue
        centres = shapely.get_parts(shapely.buffer(section, -bead / 2))
        centres = centres[~shapely.is_empty(centres)]
        if len(centres) and (dots or np.any(shapely.length(centres) / 2 >= bead)):
            return None
    kind = "lattice" if radius is not None else "TPMS sheet"
    return [ThinLattice(kind, width * scale, None if radius is None else radius * scale)]
