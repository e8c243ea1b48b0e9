"""Support material: where overhangs need it (from consecutive layer outlines), and its
lines.

Regions (:func:`plan_supports`, for the whole print, top layer down; bed frame, mm):

1. **Overhangs.** Layer ``k``'s overhang is its outline minus the outline of layer
   ``k - 1`` grown by ``h tan(support_angle)`` (``support_angle`` from the vertical, as
   Cura's overhang angle: a wall leaning further out than that from one layer to the next
   needs support), opened by :data:`SLIVER_MM` so that the slivers of a wall leaning
   exactly at the angle are dropped, pieces under ``w^2`` dropped, and with
   ``dont_support_bridges`` the pieces a bridge spans (:mod:`.bridgeable`) keep only
   their edge along the outline, where the walls run (``walls`` beads wide, at least
   one), grown by :data:`BRIDGE_EDGE_MM` instead of the expansion below, and pieces
   within that edge alone (bridged walls) need none: as PrusaSlicer supports the
   unanchored edges of bridged infill only; the enforcers of the design
   (its ``support`` bodies, :mod:`fgslice.design.support_bodies`) are added and its
   blockers (``support_blocker`` bodies) taken away. Each overhang is smoothed by a
   closing of :data:`CLOSING_MM` (bits a few mm apart become one area, as PrusaSlicer's
   closing radius) and grown by ``w / 2 + support_expansion`` (the beads along its edge
   lie on support, and the support's footing is wider than the overhang, as PrusaSlicer's
   support, whose areas it snaps outward to its line grid); of the grown area, only what
   the part of the layer below (grown by the XY gap) does not cut off from the overhang
   is kept: the footing does not reach through a wall to its far side.
2. **Projection.** The support of layer ``j`` is that of layer ``j + 1`` plus the
   overhangs of layer ``j + 1 + top`` (``top`` = ``support_top_z_gap`` in whole layers: the
   support's top stays that far below the surface it holds), minus the part grown by
   the XY gap (``support_xy_gap`` between the part and a support bead's edge, so the
   region keeps ``support_xy_gap + w / 2`` away from the outline). ``support_to = bed``:
   support only stands on the bed, so a column that meets the part on its way down is
   dropped whole (the region minus every layer's outline at or below ``j``, grown by the
   gap); ``support_to = part``: it may also stand on the part, ``bottom`` layers
   (``support_bottom_z_gap``) above its surface. A blocker removes support from its
   own layers (the column goes on below it).
3. **Interface.** Of each layer's support, what is not support on every one of the
   ``support_interface_layers`` layers above it is interface (the top of each column).

Lines (:func:`support_paths`): the body gets a sheath (one loop ``w / 2`` inside its
edge, as PrusaSlicer's default, so that the interface's line ends lie on something) and
inside it lines ``support_spacing`` apart
along X on every layer (the same grid, so they stack into walls; ``grid`` adds lines
along Y), role SUPPORT; the interface with lines ``support_interface_spacing`` apart
along Y, role SUPPORT_INTERFACE; neighbouring lines are linked into serpentines where
the link lies inside the region. Their color is the support's state
(:func:`fgslice.toolpaths.support_state.resolve_support_state`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import shapely

from fgslice.settings import Settings
from fgslice.toolpaths.bridgeable import bridgeable
from fgslice.toolpaths.infill import line_fill, open_paths
from fgslice.toolpaths.paths import Path, Role, bead_area
from fgslice.toolpaths.support_state import CURRENT_STATE
from fgslice.toolpaths.walls import bead_spacing, opening, ring_groups, split_rings

SLIVER_MM = 0.005
"""Overhangs are opened by this radius (mm): what a wall leaning exactly at the angle
leaves is rounding, not overhang."""

CLOSING_MM = 2.0
"""Closing radius that smooths each overhang's support area, mm."""

BRIDGE_EDGE_MM = 1.5
"""How far (at most ``support_expansion``) the support of a bridge's unanchored edge
reaches beyond it, mm: PrusaSlicer's support margin."""

@dataclass(frozen=True)
class SupportLayer:
    """One layer's support regions (bed frame, mm): ``body`` filled sparsely, ``interface``
    densely; either may be empty."""

    body: shapely.Geometry
    interface: shapely.Geometry

    @property
    def empty(self) -> bool:
        return self.body.is_empty and self.interface.is_empty


def _layers(value: float, h: float) -> int:
    """A z gap (mm) in whole layers of height ``h``."""
    return int(round(value / h))


def overhangs(outlines: list[shapely.Geometry], settings: Settings,
              blockers: list[shapely.Geometry] | None = None) -> np.ndarray:
    """Per layer, the area that needs support under it (empty on layer 0), smoothed and
    grown as the module says; overhangs within ``blockers`` (per layer) need none."""
    w, h = settings.bead_width, settings.layer_height
    n = len(outlines)
    out = np.full(n, shapely.Polygon(), dtype=object)
    if n < 2:
        return out
    reach = h * math.tan(math.radians(settings.support_angle))
    lower = shapely.buffer(np.asarray(outlines[:-1], dtype=object), reach, join_style="mitre", mitre_limit=3.0)
    raw = shapely.difference(np.asarray(outlines[1:], dtype=object), lower)
    if blockers is not None:
        raw = shapely.difference(raw, np.asarray(blockers[1:], dtype=object))
    raw = opening(raw, SLIVER_MM)
    parts, owner = shapely.get_parts(raw, return_index=True)
    big = shapely.area(parts) >= w * w
    edges = np.full(n - 1, shapely.Polygon(), dtype=object)  # what bridges leave to support
    if settings.dont_support_bridges:
        band = max(settings.walls, 1) * bead_spacing(w, h)
        for i in np.flatnonzero(big).tolist():
            k = owner[i]
            if bridgeable(parts[i], outlines[k], reach, w):
                inner = shapely.buffer(outlines[k + 1], -band, join_style="mitre", mitre_limit=3.0)
                if shapely.intersection(parts[i], inner).area >= w * w:  # bridged infill: its edges need support
                    edges[k] = shapely.union(edges[k], _without_crumbs(shapely.difference(parts[i], inner), w))
                big[i] = False
    merged = np.full(n - 1, shapely.Polygon(), dtype=object)
    for k in np.unique(owner[big]).tolist():
        merged[k] = shapely.union_all(parts[big & (owner == k)])
    smooth = shapely.buffer(shapely.buffer(merged, CLOSING_MM, join_style="mitre", mitre_limit=3.0), -CLOSING_MM,
                            join_style="mitre", mitre_limit=3.0)
    grown = shapely.union(
        shapely.buffer(smooth, w / 2 + settings.support_expansion, join_style="mitre", mitre_limit=3.0),
        shapely.buffer(edges, w / 2 + min(settings.support_expansion, BRIDGE_EDGE_MM), join_style="mitre",
                       mitre_limit=3.0))
    smooth = shapely.union(smooth, edges)
    gap = settings.support_xy_gap + w / 2
    for k in np.flatnonzero(~shapely.is_empty(smooth)).tolist():
        # the footing spreads around the overhang, not through the part to its far side
        pieces = shapely.get_parts(shapely.difference(grown[k], shapely.buffer(outlines[k], gap, join_style="mitre",
                                                                                mitre_limit=3.0)))
        near = shapely.buffer(smooth[k], gap + w, join_style="mitre", mitre_limit=3.0)
        grown[k] = shapely.union_all(pieces[shapely.intersects(pieces, near)])
    out[1:] = np.where(shapely.is_empty(smooth), smooth, grown)
    return out


def plan_supports(outlines: list[shapely.Geometry], settings: Settings,
                  enforcers: list[shapely.Geometry] | None = None,
                  blockers: list[shapely.Geometry] | None = None) -> list[SupportLayer]:
    """Every layer's support regions (see the module); ``enforcers``: per layer, areas
    that get support whether they overhang or not; ``blockers``: per layer, areas kept
    free of support (bed frame; None: none)."""
    n = len(outlines)
    w, h = settings.bead_width, settings.layer_height
    empty = shapely.Polygon()
    if n == 0:
        return []
    need = overhangs(outlines, settings, blockers)
    if enforcers is not None:
        need = shapely.union(need, np.asarray(enforcers, dtype=object))
    if blockers is not None:
        need = shapely.difference(need, np.asarray(blockers, dtype=object))
    top, bottom = _layers(settings.support_top_z_gap, h), _layers(settings.support_bottom_z_gap, h)
    keep_out = shapely.buffer(np.asarray(outlines, dtype=object), settings.support_xy_gap + w / 2,
                              join_style="mitre", mitre_limit=3.0)
    if settings.support_to == "bed":
        shadow, below = empty, []
        for grown in keep_out:
            shadow = shapely.union(shadow, grown)
            below.append(shadow)
    regions = [empty] * n
    carried = empty
    for j in range(n - 1, -1, -1):
        k = j + 1 + top
        new = need[k] if k < n and not need[k].is_empty else None
        if new is None and carried.is_empty:
            continue
        if settings.support_to == "bed":
            # what is carried keeps clear of every outline up to the layer above, hence up to
            # this one: only the new overhang is cut (the column is the same object until then)
            if new is not None:
                carried = _without_crumbs(shapely.union(carried, shapely.difference(new, below[j])), w)
        else:
            carried = carried if new is None else _without_crumbs(shapely.union(carried, new), w)
            carried = _minus(carried, shapely.union_all(keep_out[max(0, j - bottom) : j + 1]), w)
        regions[j] = carried if blockers is None else _without_crumbs(shapely.difference(carried, blockers[j]), w)
    return _split_interface(regions, settings.support_interface_layers, w)


def _minus(region: shapely.Geometry, cut: shapely.Geometry, w: float) -> shapely.Geometry:
    """``region - cut`` without crumbs, overlaying only the polygons of ``region`` that meet
    ``cut`` (the others are kept as they are)."""
    parts = shapely.get_parts(region)
    if not len(parts):
        return region
    shapely.prepare(cut)
    hit = shapely.intersects(parts, cut)
    if not hit.any():
        return region
    cut_parts = shapely.get_parts(shapely.difference(_polygons(parts[hit]), cut))
    return _without_crumbs(_polygons(np.concatenate([parts[~hit], cut_parts])), w)


def _polygons(parts: np.ndarray) -> shapely.Geometry:
    """The polygons among ``parts`` (disjoint but at points: parts of valid polygonal
    regions, or of their overlays) as one geometry, without a union."""
    parts = parts[shapely.get_type_id(parts) == 3]
    if not len(parts):
        return shapely.Polygon()
    return parts[0] if len(parts) == 1 else shapely.multipolygons(parts)


def _split_interface(regions: list[shapely.Geometry], count: int, w: float) -> list[SupportLayer]:
    """Each layer's support split into body and interface: what is not support on every
    one of the ``count`` layers above.

    A point of layer ``j``'s support missing from one of the layers above is missing
    first from some layer ``j + i + 1`` (``i < count``) while on layer ``j + i``: it lies
    in ``changed[j + i]``, what layer ``j + i``'s support has that the next layer's has
    not. So the interface is layer ``j``'s support within the union of those ``count``
    differences (small areas), computed once per layer; a run of layers carrying one
    unchanged column (the same region object) has none."""
    n, empty = len(regions), shapely.Polygon()
    changed = np.full(n, empty, dtype=object)
    differ = [j for j in range(n - 1) if regions[j] is not regions[j + 1] and not regions[j].is_empty]
    if differ:
        index = np.array(differ)
        changed[index] = shapely.difference(np.asarray(regions, dtype=object)[index],
                                            np.asarray(regions, dtype=object)[index + 1])
    layers = []
    for j, region in enumerate(regions):
        above = regions[j + 1 : j + 1 + count]
        if region.is_empty:
            layers.append(SupportLayer(empty, empty))
        elif not count:
            layers.append(SupportLayer(region, empty))
        elif len(above) < count or any(r.is_empty for r in above):
            layers.append(SupportLayer(empty, region))
        else:
            fresh = shapely.union_all(changed[j : j + count])
            interface = empty if fresh.is_empty else shapely.intersection(region, fresh)
            body = region if interface.is_empty else _minus(region, interface, w)
            layers.append(SupportLayer(body, _without_crumbs(interface, w)))
    return layers


def _without_crumbs(region: shapely.Geometry, w: float) -> shapely.Geometry:
    """``region`` without its polygons smaller than a bead square (``w^2``)."""
    if region.is_empty:
        return region
    parts = shapely.get_parts(region)
    big = shapely.area(parts) >= w * w
    if big.all() and shapely.get_type_id(region) in (3, 6):  # a polygon or multipolygon without crumbs
        return region
    parts = parts[big]
    if not len(parts):
        return shapely.Polygon()
    # the parts of a valid (multi)polygon are disjoint polygons: no union needed
    return parts[0] if len(parts) == 1 else shapely.multipolygons(parts)


def support_paths(layer: SupportLayer, settings: Settings, color: int = CURRENT_STATE) -> list[Path]:
    """The support lines of one layer (see the module), of ``color`` (the support's state,
    :mod:`.support_state`)."""
    if layer.empty:
        return []
    w, h = settings.bead_width, settings.layer_height
    out: list[Path] = []
    angles = (0.0, 90.0) if settings.support_pattern == "grid" else (0.0,)
    if not layer.body.is_empty:
        s = bead_spacing(w, h)
        sheath = shapely.buffer(layer.body, -w / 2, join_style="mitre", mitre_limit=3.0)
        coords, ring, _ = ring_groups(sheath)
        out += split_rings(coords, ring, Role.SUPPORT, color, w, h)
        inside = shapely.buffer(sheath, -s / 2, join_style="mitre", mitre_limit=3.0)
        for angle in angles:
            points, chain, _ = line_fill(inside, settings.support_spacing, angle, w)
            out += open_paths(points, chain, Role.SUPPORT, color, w, h)
    if not layer.interface.is_empty:
        points, chain, _ = line_fill(layer.interface, settings.support_interface_spacing, 90.0, w)
        out += open_paths(points, chain, Role.SUPPORT_INTERFACE, color, w, h)
    return out


def support_volume(paths: list[Path]) -> float:
    """Extruded volume of the support paths among ``paths``, mm^3."""
    return float(sum(p.length * bead_area(p.width, p.height) for p in paths
                     if p.role in (Role.SUPPORT, Role.SUPPORT_INTERFACE)))
