"""Bridges: solid areas over air, filled in one direction across their shortest span.

Strategy 1 (bed frame, mm). A layer's *bridge* is the part of its top and solid skin with
nothing of the layer below under it (outline minus the outline below), less what is
narrower than a bead (an opening by ``w / 2``: the edge of a gently leaning wall is no
bridge), grown by :data:`ANCHOR_BEADS` beads into the skin around it so that the lines
reach onto what carries them, as PrusaSlicer anchors its bridges. Each connected bridge
is filled with parallel lines along the short side of its minimum rotated rectangle,
i.e. across its shortest span (a roof over a channel: from one wall to the other),
linked into serpentines inside the bridge; role BRIDGE_INFILL (PrusaSlicer's ``Bridge
infill``), printed at ``bridge_speed`` (:func:`fgslice.machine.gcode.role_speeds`). Their
bead cross-section is ``bridge_flow`` percent of a bead's (the width that gives it, lines
``A' / h`` apart, so a bridge of area ``R`` still receives ``R h`` times the flow). Needs
``bottom_layers >= 1`` (the outline below is the nearest of the bottom-skin neighbours).

Strategy 2 (:func:`face_bridges`): the area over air, grown onto its anchors, within the
outline eroded by a bead, is cut out of the color faces and filled the same way, each
face's share in the face's color; the rest of each face is filled densely as usual.
"""

from __future__ import annotations

import math

import numpy as np
import shapely

from fgslice.islands import difference_by_islands
from fgslice.settings import Settings
from fgslice.toolpaths.infill import line_fill, open_paths
from fgslice.toolpaths.paths import Path, Role, bead_area
from fgslice.toolpaths.skins import InnerAreas
from fgslice.toolpaths.walls import opening

ANCHOR_BEADS = 2.0
"""How far (in bead widths) a bridge reaches into the skin around it."""


def split_bridges(areas: InnerAreas, below, settings: Settings) -> tuple[InnerAreas, shapely.Geometry]:
    """``areas`` without their bridges, and the bridges (see the module); ``below``: the
    outline of the layer under this one (None on the first layer: the bed carries it)."""
    skins = shapely.union(areas.top, areas.solid)
    if below is None or skins.is_empty:
        return areas, shapely.Polygon()
    w = settings.bead_width
    over_air = opening(shapely.difference(skins, below), w / 2)
    if over_air.is_empty:
        return areas, over_air
    bridges = shapely.intersection(shapely.buffer(over_air, ANCHOR_BEADS * w, join_style="mitre"), skins)
    bridges = shapely.union_all([piece for _, _, piece in bridge_pieces(bridges, w)])
    return InnerAreas(shapely.difference(areas.top, bridges), shapely.difference(areas.solid, bridges),
                      areas.sparse), bridges


def span_angle(region) -> float:
    """Direction (degrees) of the short side of ``region``'s minimum rotated rectangle."""
    corners = np.asarray(shapely.minimum_rotated_rectangle(region).exterior.coords)[:3]
    sides = np.diff(corners, axis=0)
    short = sides[np.argmin(np.hypot(*sides.T))]
    return math.degrees(math.atan2(short[1], short[0])) % 180.0


def bridge_pieces(bridges, w: float, faces=None) -> list[tuple[float, int, shapely.Geometry]]:
    """``(angle, color, piece)`` of every bridge: its direction across the shortest span
    (degrees), and the bridge itself in color 0 or, with ``faces`` (one per palette color,
    strategy 2), each face's share of it in the face's color. Pieces smaller than a bead's
    square are left out: their area stays with the fill around them."""
    out = []
    for part in shapely.get_parts(bridges):
        if part.area < w * w:
            continue
        angle = span_angle(part)
        shares = [(0, part)] if faces is None else [(c, shapely.intersection(part, f)) for c, f in enumerate(faces)]
        out += [(angle, color, share) for color, share in shares if share.area >= w * w]
    return out


def bridge_paths(bridges, settings: Settings, faces=None, pieces=None) -> list[Path]:
    """Lines across each bridge's shortest span (see the module), color 0 (cut into colors
    later); with ``faces`` (one per palette color, strategy 2), each face's share of a
    bridge gets that bridge's lines in the face's color; ``pieces``: :func:`bridge_pieces`
    already computed."""
    if bridges.is_empty:
        return []
    w, h = settings.bead_width, settings.layer_height
    area = bead_area(w, h) * settings.bridge_flow / 100.0
    width = max((area - math.pi * h * h / 4) / h + h, h)
    out: list[Path] = []
    for angle, color, piece in bridge_pieces(bridges, w, faces) if pieces is None else pieces:
        points, chain, _ = line_fill(piece, area / h, angle, width)
        out += open_paths(points, chain, Role.BRIDGE_INFILL, color, width, h)
    return out


def face_bridges(outline, below, settings: Settings) -> shapely.Geometry:
    """Strategy 2: the layer's area over air (``outline`` minus ``below``, the outline of
    the layer under it; None on the first layer), less what is narrower than two beads
    (the crescent a leaning strut or wall overhangs by is printed by the face's loops),
    grown :data:`ANCHOR_BEADS` beads onto what carries it, within the outline eroded by a
    bead (the outermost loop still runs along the surface)."""
    if below is None:
        return shapely.Polygon()
    w = settings.bead_width
    over_air = opening(difference_by_islands(outline, below), w)
    if over_air.is_empty:
        return over_air
    inside = shapely.buffer(outline, -w, join_style="mitre")
    return shapely.intersection(shapely.buffer(over_air, ANCHOR_BEADS * w, join_style="mitre"), inside)
