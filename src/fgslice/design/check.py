"""``fgslice check``: is a design usable, and what does it contain?

:func:`check_design` samples the design on a regular grid over its bounding box, keeps
the points inside the part and reports the materials, the box, the node count,
each material's fraction range over the part, and problems: raw fractions outside [0, 1]
(with the share of the part's volume where that happens), fractions summing to 0,
NaN/inf values, meshes that are not watertight; each process attribute's range over the
part, an error where it leaves the machine's limits (:func:`fgslice.design.attributes.limits`
under the given settings, the defaults when none). Errors make the design unusable
(nothing inside, non-finite geometry); warnings do not.

Inside/outside comes from the signed distance (sdf <= 0), except for designs holding
meshes: there it comes from the exact sections, one per grid height, tested with
``shapely.contains_xy`` (a mesh's signed distance costs a nearest-triangle search per point).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import shapely

from fgslice.design.base import Design, Material
from fgslice.design.nodes import NodeDesign
from fgslice.errors import FgsliceError

DEFAULT_SAMPLES = 64
"""Grid points along the longest side of the bounding box."""


@dataclass
class CheckReport:
    """What :func:`check_design` found.

    Attributes:
        materials: the base materials, in fraction-column order.
        bounds: axis-aligned box ``((minx, miny, minz), (maxx, maxy, maxz))``, mm.
        node_count: nodes in the design tree (0 when not a node tree).
        fraction_ranges: material name -> (min, max) normalized fraction over the part.
        attribute_ranges: attribute name -> (min, max) of its values over the samples of
            the part it covers (units of :data:`fgslice.design.attributes.UNITS`).
        attribute_cover: attribute name -> share of the part's samples it covers (0-1).
        attribute_drives: attribute name -> what it commands on the machine of the
            settings checked against; attributes without machine meaning say so, with
            what would give them one.
        design_intent: attributes of a machine name that this machine takes as design
            intent and drives nothing with (an OpenVCAD 3 ``TEMPERATURE`` that is no
            nozzle temperature here: :func:`fgslice.design.attributes.intent_temperature`).
        inside_samples: grid points found inside the part.
        spacing: grid step used, mm.
        warnings: problems that still allow slicing.
        errors: problems that make the design unusable.
        notes: facts worth knowing that are not problems (materials overridden by an
            enclosing fgrade, void cut out of the part).
    """

    materials: list[Material]
    bounds: tuple[tuple[float, float, float], tuple[float, float, float]]
    node_count: int
    fraction_ranges: dict[str, tuple[float, float]] = field(default_factory=dict)
    attribute_ranges: dict[str, tuple[float, float]] = field(default_factory=dict)
    attribute_cover: dict[str, float] = field(default_factory=dict)
    attribute_drives: dict[str, str] = field(default_factory=dict)
    design_intent: list[str] = field(default_factory=list)
    inside_samples: int = 0
    spacing: float = 0.0
    warnings: list[str] = field(default_factory=list)
    errors: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    @property
    def usable(self) -> bool:
        """True when there are no errors (the CLI exits 0)."""
        return not self.errors


MIN_PER_AXIS = 8
"""Grid points along even the thinnest side, so thin plates are sampled through."""


def _grid(bounds, samples: int):
    """Cell-centred grid points over the box and the largest grid step (mm)."""
    lo, hi = np.asarray(bounds[0], dtype=float), np.asarray(bounds[1], dtype=float)
    extent = hi - lo
    counts = np.maximum(MIN_PER_AXIS, np.ceil(extent / (extent.max() / samples))).astype(int)
    steps = extent / counts
    axes = [lo[i] + (np.arange(counts[i]) + 0.5) * steps[i] for i in range(3)]
    x, y, z = np.meshgrid(*axes, indexing="ij")
    return x.ravel(), y.ravel(), z.ravel(), float(steps.max())


def _inside_by_sections(design: Design, x: np.ndarray, y: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Whether each grid point lies in the design's section at its height (boundary included)."""
    inside = np.zeros(len(x), dtype=bool)
    heights, level = np.unique(z, return_inverse=True)
    for i, section in enumerate(design.sections(heights)):
        at = np.flatnonzero(level == i)
        if not section.is_empty:
            inside[at] = shapely.intersects_xy(section, x[at], y[at])
    return inside


def _share(mask: np.ndarray) -> str:
    return f"{100.0 * np.count_nonzero(mask) / mask.size:.1f}%"


def check_design(design: Design, *, samples: int = DEFAULT_SAMPLES, settings=None) -> CheckReport:
    """Inspect ``design`` on a grid of about ``samples`` points along its longest side;
    ``settings`` (:class:`fgslice.settings.Settings`) give the machine's limits of the
    process attributes (the defaults when None)."""
    if settings is not None:
        from fgslice.design.machine_design import for_machine

        design = for_machine(design, settings)
    bounds = design.bounds()
    node_count = design.node_count if isinstance(design, NodeDesign) else 0
    report = CheckReport(list(design.materials), bounds, node_count)
    if isinstance(design, NodeDesign):
        for name, where in design.overridden:
            at = f" (line {where.line})" if where.line is not None else ""
            report.notes.append(
                f"material '{name}'{at} is overridden by an enclosing fgrade and is never printed"
            )
        if design.has_void:
            report.notes.append("'void' is empty space: nothing is printed where it has the largest fraction")
        for mesh in design.meshes:
            if not mesh.geometry.watertight:
                report.warnings.append(
                    f"mesh {mesh.path} is not watertight: inside/outside may be wrong near its holes"
                )
    lo, hi = np.asarray(bounds[0]), np.asarray(bounds[1])
    if not np.all(np.isfinite(lo)) or not np.all(np.isfinite(hi)) or np.any(hi <= lo):
        report.errors.append(f"the design is empty or unbounded (bounding box {bounds})")
        return report
    if settings is not None:
        _check_machine(design, settings, report)
    x, y, z, report.spacing = _grid(bounds, samples)
    try:
        if isinstance(design, NodeDesign) and design.meshes:
            inside = np.flatnonzero(_inside_by_sections(design, x, y, z))
        else:
            sdf = np.asarray(design.sdf(x, y, z))
            bad = ~np.isfinite(sdf)
            if bad.any():
                report.errors.append(f"the signed distance is NaN or infinite at {_share(bad)} of the box's samples")
            inside = np.flatnonzero(sdf <= 0)
    except FgsliceError as exc:
        report.errors.append(f"geometry cannot be evaluated: {exc.message}")
        return report
    report.inside_samples = int(inside.size)
    if inside.size == 0:
        report.errors.append("no sample point lies inside the part: the design is empty at this resolution")
        return report
    x, y, z = x[inside], y[inside], z[inside]
    try:
        fractions = design.fractions(x, y, z)
        raw = design.raw_fractions(x, y, z) if isinstance(design, NodeDesign) else fractions
    except FgsliceError as exc:
        report.errors.append(f"materials cannot be evaluated: {exc.message}")
        return report
    for i, material in enumerate(report.materials):
        column = fractions[:, i]
        report.fraction_ranges[material.name] = (float(column.min()), float(column.max()))
    if np.isnan(raw).any():
        report.warnings.append(f"raw fractions are NaN over {_share(np.isnan(raw).any(axis=1))} of the part "
                               "(treated as 0)")
    if np.isinf(raw).any():
        report.warnings.append(f"raw fractions are infinite over {_share(np.isinf(raw).any(axis=1))} of the part "
                               "(clamped: +inf counts as 1, -inf as 0)")
    raw = np.nan_to_num(raw, nan=0.0, posinf=1.0, neginf=0.0)
    for i, material in enumerate(report.materials):
        outside = (raw[:, i] < -1e-9) | (raw[:, i] > 1 + 1e-9)
        if outside.any():
            report.warnings.append(
                f"raw fraction of '{material.name}' leaves [0, 1] over {_share(outside)} of the part "
                f"(range {raw[:, i].min():.3g} to {raw[:, i].max():.3g}; clamped)"
            )
    _check_attributes(design, x, y, z, settings, report)
    zero = np.clip(raw, 0, 1).sum(axis=1) <= 0
    if zero.any():
        report.warnings.append(
            f"fractions sum to 0 over {_share(zero)} of the part (the first material, "
            f"'{report.materials[0].name}', is used there)"
        )
    return report


def _check_machine(design: Design, settings, report: CheckReport) -> None:
    """The refusals ``fgslice slice`` would meet under ``settings`` before any layer: a
    palette that does not fit the materials, fewer machine channels than materials, a
    part larger than the bed."""
    from fgslice.design.attributes import attribute_fields
    from fgslice.machine.state_dialect import dialect_for
    from fgslice.slicing.plan_layers import place_design
    from fgslice.slicing.states import make_palette

    fields = attribute_fields(design)
    steps = [lambda: place_design(design, settings)]
    if fields is None or "temperature" not in fields.names:  # temperature states: checked with their levels
        steps.insert(0, lambda: dialect_for(settings, make_palette(len(design.materials), settings.colors,
                                                                   settings.palette, None)))
    for step in steps:
        try:
            step()
        except FgsliceError as exc:
            report.errors.append(exc.message + (f" ({exc.hint})" if exc.hint else ""))


def _check_attributes(design: Design, x, y, z, settings, report: CheckReport) -> None:
    """Each attribute's range over the samples inside the part, and an error for each
    range the machine cannot command."""
    from fgslice.design.attributes import attribute_fields, drives, intent_temperature, out_of_limits
    from fgslice.settings import Settings

    fields = attribute_fields(design)
    if fields is None:
        return
    settings = settings or Settings()
    for name in fields.names:
        try:
            values = fields.values(name, x, y, z)
        except FgsliceError as exc:
            report.errors.append(f"attribute '{name}' cannot be evaluated: {exc.message}")
            continue
        report.attribute_cover[name] = float(np.isfinite(values).mean()) if values.size else 0.0
        values = values[np.isfinite(values)]
        if not values.size:
            report.warnings.append(f"attribute '{name}' covers no sample of the part (the settings apply)")
            continue
        low, high = float(values.min()), float(values.max())
        report.attribute_ranges[name] = (low, high)
        driven = drives(name, settings)
        intent = intent_temperature(fields.root, low, high, settings) if name == "temperature" else None
        if intent:
            report.attribute_drives[name] = f"nothing on this machine: {intent}"
            report.design_intent.append(name)
            continue
        report.attribute_drives[name] = driven or _undriven(design, name, settings)
        if driven is None:
            continue
        problem = out_of_limits(name, low, high, settings)
        if problem:
            report.errors.append(problem)


def _undriven(design: Design, name: str, settings) -> str:
    """What attribute ``name``, which has no machine meaning of its own, does on this
    machine: a colour channel may drive the mixture (:mod:`fgslice.design.color_mix`)."""
    from fgslice.design.attributes import INTENT_HINT
    from fgslice.design.color_mix import COLOR_ATTRIBUTES, ColorMix
    from fgslice.design.profile_tables import profile_targets

    targets = profile_targets(design, name)
    if targets:
        return f"{', '.join(targets)} through the profile's attribute_tables"
    if name.partition(".")[0] not in COLOR_ATTRIBUTES:
        return (f"nothing on this machine: {INTENT_HINT}, or give the profile a table of your filament: "
                f"attribute_tables = '{name} -> temperature: key value, key value, ...'")
    root = getattr(design, "root", None)
    if isinstance(root, ColorMix) and name in root.channels:
        return f"the mixture of the filaments {settings.filament_colors} nearest to the colour (CIELAB)"
    if isinstance(root, ColorMix):
        return "nothing: the other colour attribute decides the mixture"
    if not settings.filament_colors:
        return ("nothing on this machine: declare the loaded filaments' colours (filament_colors = "
                "'#rrggbb,#rrggbb' in the profile) to print the colour as their mixture")
    return "nothing: the design's volume fractions decide the mixture"


def format_report(report: CheckReport) -> str:
    """The report as plain text lines for the terminal."""
    (x0, y0, z0), (x1, y1, z1) = report.bounds
    lines = ["materials:"]
    for m in report.materials:
        r, g, b, a = (round(255 * c) for c in m.rgba)
        lo, hi = report.fraction_ranges.get(m.name, (float("nan"), float("nan")))
        lines.append(f"  {m.name:<12} #{r:02x}{g:02x}{b:02x} alpha {a:3d}   fraction {lo:.3f} .. {hi:.3f}")
    lines.append(
        f"bounding box: x {x0:.3f} .. {x1:.3f}, y {y0:.3f} .. {y1:.3f}, z {z0:.3f} .. {z1:.3f} mm "
        f"({x1 - x0:.2f} x {y1 - y0:.2f} x {z1 - z0:.2f} mm)"
    )
    from fgslice.design.attributes import UNITS

    for name, (lo, hi) in report.attribute_ranges.items():
        unit = f" {UNITS[name]}" if name in UNITS else ""
        drives = report.attribute_drives.get(name)
        lines.append(f"attribute {name:<14} {lo:.4g} .. {hi:.4g}{unit}" + (f" -> drives {drives}" if drives else ""))
    lines.append(f"nodes: {report.node_count}")
    lines.append(f"samples inside the part: {report.inside_samples} (grid step {report.spacing:.3g} mm)")
    lines.extend(f"note: {n}" for n in report.notes)
    lines.extend(f"warning: {w}" for w in report.warnings)
    lines.extend(f"error: {e}" for e in report.errors)
    lines.append("usable: yes" if report.usable else "usable: no")
    return "\n".join(lines)
