"""One validated settings structure; printer profiles are TOML files of the same keys.

Resolution order (later wins): the structure's defaults, a built-in profile (or a user's
``--profile FILE.toml``, which may name a built-in it ``inherits``), then each
``--set KEY=VALUE``. Units: mm, mm/s, seconds, degrees Celsius, percent where named.

Settings are a frozen ``msgspec`` Struct: every field's type and range is declared with
its description (``Annotated[type, Meta(...)]``) and checked whenever Settings are made,
by :func:`load_settings` (which also turns the strings of ``--set`` into numbers and
booleans) or directly (``Settings(walls=3)``, values of the right types). Every
command loads settings, so their cost is start-up time: importing this module and
loading a profile take about 23 ms (a pydantic model of the same fields took 100 ms).
The annotations are evaluated as the module is imported (no ``from __future__ import
annotations``): as strings, msgspec evaluated all of them again on the first
validation, 15-20 ms more.
"""

import functools
import math
import tomllib
import types
import typing
from importlib import resources
from pathlib import Path
from typing import Annotated, Any, Literal

import msgspec
from msgspec import Meta

from fgslice.errors import SettingsError, did_you_mean

Dialect = Literal["marlin-mixing", "marlin-mixing-m163", "klipper-mixing", "toolchanger", "temperature", "template"]


class _Fields(msgspec.Struct, kw_only=True, frozen=True, forbid_unknown_fields=True):
    """Every setting with its type, range, default and description (see :class:`Settings`)."""

    # -- machine ---------------------------------------------------------------
    profile_name: Annotated[str, Meta(description="name of the profile these settings came from")] = "marlin-mixing"
    description: Annotated[str, Meta(description="one line about the machine")] = ""
    dialect: Annotated[Dialect, Meta(description="how a state change is written")] = "marlin-mixing"
    channels: Annotated[int, Meta(ge=1, le=6, description="mixing channels (A, B, C, ...) of a mixing hotend")] = 2
    mixing_rotation_distance: Annotated[float, Meta(gt=0, le=1000, description="klipper-mixing: rotation_distance of every channel's [extruder_stepper] in printer.cfg, mm")] = 33.5
    tool_count: Annotated[int, Meta(ge=1, le=64, description="tools of a toolchanger (T0..Tn-1)")] = 5
    bed_x: Annotated[float, Meta(gt=0, le=5000, description="bed width, mm")] = 220.0
    bed_y: Annotated[float, Meta(gt=0, le=5000, description="bed depth, mm")] = 220.0
    max_z: Annotated[float, Meta(gt=0, le=5000, description="build height, mm")] = 250.0
    nozzle_diameter: Annotated[float, Meta(gt=0.05, le=5.0, description="nozzle bore, mm")] = 0.4
    filament_diameter: Annotated[float, Meta(gt=0.1, le=5.0, description="filament diameter, mm")] = 1.75
    host_filament_type: Annotated[str, Meta(min_length=1, max_length=32, pattern=r"^[A-Za-z0-9_+-]+$", description="filament type hosts show (PrusaSlicer's filament_type: PLA, PETG, FLEX, ...)")] = "PLA"
    host_filament_name: Annotated[str, Meta(max_length=200, description="name of the filament hosts show on one-extruder machines (temperature and template dialects); empty: the design's first material")] = ""
    filament_density: Annotated[float, Meta(gt=0.1, le=25.0, description="filament density for mass estimates, g/cm^3")] = 1.24

    # -- state of a color ---------------------------------------------------------
    temperature_a: Annotated[float, Meta(ge=0, le=500, description="nozzle temperature at 100% material A (temperature dialect), C")] = 190.0
    temperature_b: Annotated[float, Meta(ge=0, le=500, description="nozzle temperature at 100% material B (temperature dialect), C")] = 225.0
    flow_model: Annotated[Literal["none", "pla", "tpu"], Meta(description="foaming flow compensation polynomial (M221), for the temperature dialect and temperature attributes")] = "none"
    filament_colors: Annotated[str, Meta(description="colours of the loaded filaments, one per channel or tool, '#rrggbb' comma-separated: a design's COLOR_RGB(A) attribute is printed as their nearest mixture")] = ""
    state_template: Annotated[str, Meta(description="template dialect: text emitted per state change; placeholders {color}, {f0}..{f5} (0-1), {pct0}..{pct5} (0-100), {pwm0}..{pwm5} (0-255), {temperature}")] = ""

    # -- process -------------------------------------------------------------------
    layer_height: Annotated[float, Meta(gt=0.01, le=2.0, description="layer height h, mm")] = 0.2
    bead_width: Annotated[float, Meta(gt=0.05, le=5.0, description="extrusion bead width w, mm")] = 0.4
    strategy: Annotated[Literal[1, 2], Meta(description="1: walls/skins/infill cut into colors; 2: faces filled densely")] = 2
    colors: Annotated[int, Meta(ge=1, le=1024, description="palette size N")] = 4
    palette: Annotated[Literal["centers", "ends"], Meta(description="palette colors: centers of equal bins (the paper's) or a lattice including the pure materials, nearest color per face")] = "centers"
    fill_pattern: Annotated[Literal["concentric", "rectilinear"], Meta(description="strategy 2 fill")] = "concentric"
    walls: Annotated[int, Meta(ge=0, le=100, description="strategy 1 perimeters")] = 2
    wall_order: Annotated[Literal["outer_first", "inner_first"], Meta(description="strategy 1 perimeter order")] = "inner_first"
    top_layers: Annotated[int, Meta(ge=0, le=100, description="strategy 1 top solid layers")] = 3
    bottom_layers: Annotated[int, Meta(ge=0, le=100, description="strategy 1 bottom solid layers")] = 3
    skin_margin: Annotated[float, Meta(ge=0, le=50, description="strategy 1: top/bottom solid areas extend this far into the sparse area around them, mm")] = 0.8
    sparse_min_width: Annotated[float, Meta(ge=0, le=50, description="strategy 1: sparse areas narrower than this become solid, mm")] = 2.0
    infill_density: Annotated[float, Meta(ge=0, le=100, description="strategy 1 sparse infill, percent")] = 20.0
    infill_pattern: Annotated[Literal["rectilinear", "concentric"], Meta(description="strategy 1 sparse infill pattern")] = "rectilinear"
    infill_angle: Annotated[float, Meta(ge=-360, le=360, description="direction of rectilinear lines on even layers, degrees")] = 45.0
    seam_position: Annotated[Literal["nearest", "aligned", "rear", "random"], Meta(description="where closed loops (walls, concentric loops, skirt, brim) start: nearest the nozzle, at the sharpest corner, rearmost, or at random")] = "nearest"
    bridge_flow: Annotated[float, Meta(ge=10, le=200, description="bridge lines extrude this percent of a bead's volume")] = 100.0
    feature_order: Annotated[Literal["walls_first", "infill_first"], Meta(description="within a color, strategy 1")] = "walls_first"
    thin_features: Annotated[bool, Meta(description="print parts narrower than a bead (at least min_feature_size wide) as one bead along their centre line, as PrusaSlicer's Arachne perimeters do")] = True
    min_feature_size: Annotated[float | str, Meta(description="thin_features: narrower parts are dropped; mm, or percent of nozzle_diameter ('25%')")] = "25%"
    min_bead_width: Annotated[float | str, Meta(description="thin_features: beads are at least this wide (at most bead_width); mm, or percent of nozzle_diameter ('85%')")] = "85%"
    min_segment_mm: Annotated[float, Meta(ge=0, le=1000, description="strategy 1 warns when color pieces are shorter, mm")] = 5.0
    zipper: Annotated[float, Meta(ge=0, le=100, description="zipper overlap band beta, percent of the gradient range")] = 0.0
    temperature_step: Annotated[float, Meta(ge=0.5, le=100, description="a temperature attribute is commanded in levels this far apart (multiples of it), C")] = 5.0
    attribute_tolerance: Annotated[float, Meta(gt=0, le=100, description="largest change of a fan, flow or speed attribute over one extrusion piece, points of percent")] = 2.0
    gcode_resolution: Annotated[float, Meta(gt=0, le=1.0, description="how far simplification may move strategy 1's layer outlines (before walls, skins and infill) and its walls, mm")] = 0.0125
    arc_fitting: Annotated[Literal["disabled", "emit_center"], Meta(description="disabled: straight moves only; emit_center: runs of short moves on a circle (within gcode_resolution) written as one G2/G3 with I J, as PrusaSlicer's arc_fitting (Marlin, Klipper with [gcode_arcs], RepRapFirmware; not on the template dialect)")] = "disabled"

    # -- placement -------------------------------------------------------------------
    center: Annotated[bool, Meta(description="center the part on the bed")] = True
    position_x: Annotated[float, Meta(ge=-5000, le=5000, description="part center X when center = false, mm")] = 0.0
    position_y: Annotated[float, Meta(ge=-5000, le=5000, description="part center Y when center = false, mm")] = 0.0
    scale: Annotated[float, Meta(gt=0, le=100, description="the design scaled by this factor about its origin before it is placed (PrusaSlicer's --scale); 1: as designed")] = 1.0
    skirt_loops: Annotated[int, Meta(ge=0, le=20, description="loops around the part on the first layer")] = 1
    skirt_distance: Annotated[float, Meta(ge=0, le=100, description="gap between skirt and part, mm")] = 3.0
    brim_width: Annotated[float, Meta(ge=0, le=100, description="loops of a brim around the part on the first layer cover this width, mm; 0: no brim")] = 0.0

    # -- support material ------------------------------------------------------------
    support: Annotated[bool, Meta(description="print support under overhangs")] = False
    support_angle: Annotated[float, Meta(ge=0, le=89, description="overhangs leaning further than this from the vertical get support, degrees")] = 45.0
    support_to: Annotated[Literal["bed", "part"], Meta(description="support stands on the bed only (columns meeting the part are dropped) or also on the part")] = "bed"
    support_xy_gap: Annotated[float, Meta(ge=0, le=10, description="gap between the part and the edge of a support bead, mm")] = 0.3
    support_expansion: Annotated[float, Meta(ge=0, le=50, description="support reaches this far beyond the overhang it holds, for a wider footing, mm")] = 3.0
    support_top_z_gap: Annotated[float, Meta(ge=0, le=10, description="gap between the top of the support and the surface it holds, mm (whole layers)")] = 0.2
    support_bottom_z_gap: Annotated[float, Meta(ge=0, le=10, description="gap between the part and support standing on it, mm (whole layers)")] = 0.2
    support_interface_layers: Annotated[int, Meta(ge=0, le=50, description="dense layers at the top of the support")] = 3
    support_pattern: Annotated[Literal["rectilinear", "grid"], Meta(description="support lines along X (rectilinear) or along X and Y (grid)")] = "rectilinear"
    support_spacing: Annotated[float, Meta(gt=0, le=50, description="distance between support lines, mm")] = 2.0
    support_interface_spacing: Annotated[float, Meta(gt=0, le=50, description="distance between support interface lines, mm")] = 0.6
    support_state: Annotated[int | Literal["cheapest", "current"], Meta(description="palette color support is printed in; 'current': whatever state the nozzle is in (no state change, no purge); 'cheapest': the palette color of the lowest filament_costs, 'current' without costs")] = "cheapest"
    support_mix: Annotated[str, Meta(description="mixing hotend: support is printed in this mix of the design's materials, fractions comma-separated (e.g. '1,0'), a state of its own outside the palette; empty: support_state")] = ""
    support_tool: Annotated[int, Meta(ge=-1, le=63, description="toolchanger: the tool support is printed with (e.g. soluble PVA), one the palette's colors do not use (colors <= support_tool < tool_count); -1: none, support_state decides")] = -1
    support_temperature: Annotated[float, Meta(ge=0, le=500, description="nozzle temperature of support_tool, C; 0: nozzle_temperature")] = 0.0
    attribute_tables: Annotated[str, Meta(description="tables from a design's attributes to machine attributes, 'source -> target: key value, key value, ...' separated by ';' (linear between rows, flat beyond), e.g. 'density -> temperature: 0.4 250, 1.2 205': applied where the design sets the source and not the target")] = ""
    filament_costs: Annotated[str, Meta(description="cost per kg of each loaded filament (mixing channel or tool), comma-separated, as PrusaSlicer's filament_cost; support_state = cheapest prints support in the cheapest palette color")] = ""
    dont_support_bridges: Annotated[bool, Meta(description="no support under overhangs that lines across land on the layer below at both ends (bridges), as PrusaSlicer's")] = True

    # -- purge and dead volume -------------------------------------------------------
    purge: Annotated[bool, Meta(description="strategy 1 purge tower on state changes")] = True
    melt_volume_mm3: Annotated[float, Meta(ge=0, le=10000, description="melt chamber volume V_melt, mm^3")] = 68.5
    purge_size: Annotated[Literal["full", "model"], Meta(description="purge length: full (V_melt every change) or model (what the dead-volume model says the change needs to reach purge_tolerance)")] = "full"
    purge_tolerance: Annotated[float | Literal["auto"], Meta(description="purge_size = model: composition distance (0-1; degC for the temperature dialect) left after a purge; 'auto' is a tenth of a palette bin")] = "auto"
    purge_into_infill: Annotated[bool, Meta(description="strategy 1: after a state change print the new color's sparse infill first, counting it against the purge")] = False
    purge_tower_x: Annotated[float | None, Meta(description="tower center X (bed frame), mm; None: automatic")] = None
    purge_tower_y: Annotated[float | None, Meta(description="tower center Y (bed frame), mm; None: automatic")] = None
    lookahead_mm: Annotated[float | Literal["auto"], Meta(description="issue state changes this far ahead (extruded path length), mm; 'auto' derives it from melt_volume_mm3")] = 0.0
    temperature_lead_s: Annotated[float, Meta(ge=0, le=3600, description="temperature dialect, and a temperature attribute on a mixing hotend: issue temperature changes this long ahead, s")] = 0.0
    tau_s: Annotated[float, Meta(gt=0, le=3600, description="thermal time constant of the hotend for simulation, s")] = 8.0
    mixing_share: Annotated[float, Meta(ge=0, le=1, description="share of the melt chamber that is well mixed (simulation)")] = 0.3

    # -- speeds, mm/s ----------------------------------------------------------------
    print_speed: Annotated[float, Meta(gt=0, le=1000, description="perimeters and solid fill, mm/s")] = 40.0
    outer_wall_speed: Annotated[float, Meta(gt=0, le=1000, description="external perimeters, mm/s")] = 25.0
    infill_speed: Annotated[float, Meta(gt=0, le=1000, description="sparse infill, mm/s")] = 60.0
    bridge_speed: Annotated[float, Meta(gt=0, le=1000, description="bridges, mm/s")] = 30.0
    first_layer_speed: Annotated[float, Meta(gt=0, le=1000, description="every extrusion on layer 0, mm/s")] = 20.0
    travel_speed: Annotated[float, Meta(gt=0, le=2000, description="travel moves, mm/s")] = 150.0
    z_speed: Annotated[float, Meta(gt=0, le=500, description="Z moves, mm/s")] = 10.0

    # -- motion (the time estimate: docs/gcode.md, "Print time") ----------------------
    motion_planner: Annotated[Literal["klipper", "marlin"], Meta(description="firmware whose motion planner the time estimate follows: klipper (square_corner_velocity, minimum_cruise_ratio) or marlin (junction_deviation; classic jerk when it is 0)")] = "marlin"
    acceleration: Annotated[float, Meta(gt=0, le=100000, description="printing and travel acceleration (Klipper's max_accel, Marlin's M204), mm/s^2")] = 3000.0
    z_acceleration: Annotated[float, Meta(gt=0, le=100000, description="largest acceleration along Z (Klipper's max_z_accel, Marlin's Z max acceleration), mm/s^2")] = 100.0
    retract_acceleration: Annotated[float | Literal["auto"], Meta(description="acceleration of retractions and other extrude-only moves, mm/s^2; 'auto': the firmware's default (Klipper: acceleration x 4 nozzle_diameter^2 / filament cross-section, Marlin: acceleration)")] = "auto"
    square_corner_velocity: Annotated[float, Meta(ge=0, le=1000, description="Klipper: speed through a 90 degree corner, mm/s")] = 5.0
    minimum_cruise_ratio: Annotated[float, Meta(ge=0, lt=1, description="Klipper: share of a short move that cruises (its planner's pseudo-acceleration is acceleration x (1 - ratio))")] = 0.5
    junction_deviation: Annotated[float, Meta(ge=0, le=10, description="Marlin: junction deviation, mm; 0 for classic jerk")] = 0.013
    jerk: Annotated[float, Meta(gt=0, le=1000, description="Marlin with junction_deviation = 0: classic jerk of X and Y, mm/s (Z 0.3, E 5)")] = 10.0
    # -- retraction ------------------------------------------------------------------
    retract_length: Annotated[float, Meta(ge=0, le=50, description="retraction length, mm of filament")] = 0.8
    retract_speed: Annotated[float, Meta(gt=0, le=500, description="retraction speed, mm/s")] = 35.0
    retract_min_travel: Annotated[float, Meta(ge=0, le=1000, description="retract only on travels longer than this, mm")] = 1.0
    coast_mm: Annotated[float, Meta(ge=0, le=20, description="before a retraction, move the path's last this many mm without extruding (coasting), mm")] = 0.0
    wipe_mm: Annotated[float, Meta(ge=0, le=20, description="on a retraction, move back along the last path this far while retracting, mm")] = 0.0
    z_hop: Annotated[float, Meta(ge=0, le=10, description="lift on retracted travels, mm")] = 0.0

    # -- temperatures and cooling ----------------------------------------------------
    nozzle_temperature: Annotated[float, Meta(ge=0, le=500, description="nozzle temperature, C")] = 210.0
    bed_temperature: Annotated[float, Meta(ge=0, le=200, description="bed temperature, C")] = 60.0
    fan_speed: Annotated[float, Meta(ge=0, le=100, description="part cooling fan, percent")] = 100.0
    fan_off_layers: Annotated[int, Meta(ge=0, le=1000, description="layers printed with the fan off")] = 1

    # -- machine limits (checked by verify) ------------------------------------------
    max_nozzle_temperature: Annotated[float, Meta(ge=0, le=600, description="hottest nozzle allowed, C")] = 300.0
    max_bed_temperature: Annotated[float, Meta(ge=0, le=300, description="hottest bed allowed, C")] = 120.0
    min_extrude_temperature: Annotated[float, Meta(ge=0, le=600, description="no extrusion below this nozzle temperature, C")] = 170.0
    max_cross_section_mm2: Annotated[float, Meta(gt=0, le=100, description="largest extruded cross-section (E volume per mm of XY travel), mm^2")] = 2.0
    min_flow_percent: Annotated[float, Meta(ge=0, le=1000, description="smallest M221 flow allowed, percent")] = 10.0
    max_flow_percent: Annotated[float, Meta(ge=0, le=1000, description="largest M221 flow allowed, percent")] = 200.0

    # -- G-code text -----------------------------------------------------------------
    start_gcode: Annotated[str, Meta(description="emitted before the first layer; placeholders {nozzle_temperature} {bed_temperature}")] = "G28 ; home\nG90\nM83\nM140 S{bed_temperature}\nM104 S{nozzle_temperature}\nM190 S{bed_temperature}\nM109 S{nozzle_temperature}\nG92 E0"
    end_gcode: Annotated[str, Meta(description="emitted after the last layer")] = "M104 S0\nM140 S0\nM107\nG91\nG1 Z5 F600\nG90\nM84"
    thumbnails: Annotated[str, Meta(description="thumbnail sizes WxH, comma separated; empty for none")] = "16x16,220x124"


class Settings(_Fields, kw_only=True, frozen=True, forbid_unknown_fields=True):
    """Every setting of a slice. Field descriptions are shown by ``fgslice profiles --keys``.

    Raises (when made):
        ValueError: a value of the wrong type or out of range (``msgspec.ValidationError``),
            or settings that contradict each other; :func:`load_settings` turns either
            into a :class:`~fgslice.errors.SettingsError`.
    """

    def __post_init__(self) -> None:
        msgspec.convert(self.as_dict(), _Fields)  # each field's type and range
        if self.bead_width < self.layer_height:
            raise ValueError(
                f"bead_width ({self.bead_width} mm) must be at least layer_height ({self.layer_height} mm)"
            )
        area = self.bead_area
        if area > self.max_cross_section_mm2:
            raise ValueError(
                f"a {self.bead_width} x {self.layer_height} mm bead has a {area:.3f} mm^2 cross-section, more than "
                f"this machine's max_cross_section_mm2 = {self.max_cross_section_mm2}; use a smaller bead or layer, "
                "or raise max_cross_section_mm2 if the machine can extrude that much"
            )
        if self.lookahead_mm != "auto" and self.lookahead_mm < 0:
            raise ValueError("lookahead_mm must be >= 0 or 'auto'")
        if self.retract_acceleration != "auto" and self.retract_acceleration <= 0:
            raise ValueError("retract_acceleration must be > 0 or 'auto'")
        if self.purge_tolerance != "auto" and self.purge_tolerance <= 0:
            raise ValueError("purge_tolerance must be > 0 or 'auto'")
        from fgslice.toolpaths.thin_features import feature_limits

        feature_limits(self)
        if self.arc_fitting != "disabled" and self.dialect == "template":
            raise ValueError("arc_fitting writes G2/G3 arcs, which the template dialect's machine may not know; "
                             "set arc_fitting = disabled, or use a Marlin, Klipper or RepRapFirmware dialect")

    def as_dict(self) -> dict[str, Any]:
        """Every setting by name, in declaration order."""
        return msgspec.structs.asdict(self)

    @property
    def bead_area(self) -> float:
        """Capsule cross-section ``h (w - h) + pi h^2 / 4`` of a bead, mm²."""
        from fgslice.toolpaths.paths import bead_area

        return bead_area(self.bead_width, self.layer_height)

    @property
    def lookahead_distance(self) -> float:
        """The look-ahead in mm: the set value, or ``V_melt / A`` when 'auto'."""
        if self.lookahead_mm == "auto":
            return self.melt_volume_mm3 / self.bead_area
        return float(self.lookahead_mm)


PROFILE_PACKAGE = "fgslice.machine.profiles"


def builtin_profiles() -> dict[str, str]:
    """Names of the built-in profiles mapped to their one-line descriptions."""
    out = {}
    for entry in sorted(resources.files(PROFILE_PACKAGE).iterdir(), key=lambda p: p.name):
        if entry.name.endswith(".toml"):
            data = tomllib.loads(entry.read_text(encoding="utf-8"))
            out[entry.name[:-5]] = str(data.get("description", ""))
    return out


def _read_toml(path: Path | None, text: str, label: str) -> dict[str, Any]:
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SettingsError(f"{label} is not valid TOML: {exc}", file=path, hint="check quotes and '=' signs") from None
    except RecursionError:
        raise SettingsError(f"{label} nests arrays or tables too deeply to read", file=path,
                            hint="a profile is flat key = value lines, with [sections]") from None


def _profile_values(name_or_path: str, seen: tuple[str, ...] = ()) -> dict[str, Any]:
    """The key/values of a profile (built-in name or TOML file), inheritance resolved."""
    if name_or_path in seen:
        raise SettingsError(f"profile inheritance loops: {' -> '.join(seen + (name_or_path,))}")
    builtins = builtin_profiles()
    if name_or_path in builtins:
        text = resources.files(PROFILE_PACKAGE).joinpath(f"{name_or_path}.toml").read_text(encoding="utf-8")
        values = _read_toml(None, text, f"built-in profile {name_or_path}")
        values.setdefault("profile_name", name_or_path)
    else:
        path = Path(name_or_path)
        if not path.suffix == ".toml" and not path.exists():
            hint = did_you_mean(name_or_path, builtins) or f"built-in profiles: {', '.join(builtins)}"
            raise SettingsError(f"unknown profile '{name_or_path}'", hint=hint)
        try:
            text = path.read_text(encoding="utf-8")
        except OSError as exc:
            raise SettingsError(f"cannot read profile: {exc.strerror}", file=path) from None
        except UnicodeDecodeError:
            raise SettingsError("profile is not UTF-8 text", file=path) from None
        values = _read_toml(path, text, "profile")
        values.setdefault("profile_name", path.stem)
    parent = values.pop("inherits", None)
    if parent is not None:
        base = _profile_values(str(parent), seen + (name_or_path,))
        base.update(values)
        values = base
    return values


def _flatten(values: dict[str, Any]) -> dict[str, Any]:
    """Profiles may group keys in TOML tables ([machine], [speeds], ...); keys are flat."""
    flat: dict[str, Any] = {}
    for key, value in values.items():
        if isinstance(value, dict):
            flat.update(_flatten(value))
        else:
            flat[key] = value
    return flat


#: Every setting's name, in declaration order.
SETTING_NAMES: tuple[str, ...] = _Fields.__struct_fields__


@functools.cache
def _declared() -> dict[str, Any]:
    """Every setting's declared ``Annotated[type, Meta]``, by name (resolved once)."""
    return typing.get_type_hints(_Fields, include_extras=True)


def describe_settings() -> list[tuple[str, Any, str]]:
    """``(name, default, description)`` of every setting, in declaration order."""
    defaults = _Fields()
    return [(name, getattr(defaults, name), _declared()[name].__metadata__[0].description) for name in SETTING_NAMES]


_KINDS = {int: "a whole number", float: "a number", bool: "true or false", str: "text", type(None): "none"}


def _expected(key: str) -> str:
    """What setting ``key`` accepts, in words: its kind and range (``a whole number, at
    least 0, at most 100``; ``one of 1, 2``; ``a number or 'auto'``)."""
    kind, meta = typing.get_args(_declared()[key])
    options = typing.get_args(kind) if typing.get_origin(kind) in (typing.Union, types.UnionType) else (kind,)
    words = []
    for option in options:
        if typing.get_origin(option) is Literal:
            words.append(", ".join(map(repr, typing.get_args(option))))
        else:
            words.append(_KINDS[option])
    text = " or ".join(words)
    if len(options) == 1 and typing.get_origin(kind) is Literal:
        text = "one of " + text
    limits = (("gt", "above"), ("ge", "at least"), ("lt", "below"), ("le", "at most"))
    return ", ".join([text] + [f"{word} {getattr(meta, name)}" for name, word in limits if getattr(meta, name) is not None])


#: Settings that were removed, with what replaces them.
RETIRED = {
    "purge_scale_by_change": "it was removed: purges scaled by the change left the vase 8% within half a bin; "
    "--set purge_size=model sizes each purge by what the change needs",
}


def _unknown_key(key: str, origin: str) -> SettingsError:
    return SettingsError(
        f"unknown setting '{key}' ({origin})",
        hint=RETIRED.get(key) or did_you_mean(key, SETTING_NAMES) or "run 'fgslice profiles --keys' for the list",
    )


def _validated(values: dict[str, Any], origin: str) -> Settings:
    """``values`` as Settings (strings of numbers and booleans converted); a
    SettingsError naming the key, its value and the rule it breaks otherwise."""
    try:
        settings = msgspec.convert(values, Settings, strict=False)
    except msgspec.ValidationError as exc:
        message = str(exc)
    else:
        for key, value in settings.as_dict().items():
            if isinstance(value, float) and not math.isfinite(value):  # NaN passes every bound
                raise SettingsError(f"setting '{key}' = {value!r} is invalid ({origin}): it takes a finite number",
                                    hint=f"its default is {getattr(_Fields(), key)!r}")
        return settings
    unknown = message.removeprefix("Object contains unknown field `")
    if unknown != message:
        raise _unknown_key(unknown.partition("`")[0], origin) from None
    _, at, path = message.rpartition(" - at `$.")
    if not at:
        raise SettingsError(f"inconsistent settings ({origin}): {message}") from None
    key = path.rstrip("`")
    raise SettingsError(
        f"setting '{key}' = {values.get(key)!r} is invalid ({origin}): it takes {_expected(key)}",
        hint=f"its default is {getattr(_Fields(), key)!r}",
    ) from None


def parse_overrides(pairs: list[str] | tuple[str, ...]) -> dict[str, str]:
    """``["key=value", ...]`` to a dict; values stay strings for :func:`load_settings` to convert."""
    out: dict[str, str] = {}
    for pair in pairs:
        key, sep, value = pair.partition("=")
        key = key.strip()
        if not sep or not key:
            raise SettingsError(f"--set expects KEY=VALUE, got '{pair}'", hint="for example --set walls=3")
        if key not in SETTING_NAMES:
            raise _unknown_key(key, "--set")
        out[key] = value.strip().replace("\\n", "\n")
    return out


def _coerce(key: str, value: Any) -> Any:
    """A --set string the conversion would not turn into what the field expects: 'none',
    'auto' or nothing for the purge tower's position (automatic)."""
    if isinstance(value, str) and key in ("purge_tower_x", "purge_tower_y") and value.lower() in ("none", "auto", ""):
        return None
    return value


def load_settings(profile: str | None = None, overrides: dict[str, Any] | None = None) -> Settings:
    """Resolve defaults, a profile (built-in name or TOML path) and overrides into Settings.

    Raises:
        SettingsError: unknown profile or key, malformed TOML, value out of range.
    """
    name = profile or "marlin-mixing"
    values = _flatten(_profile_values(name))
    settings = _validated(values, f"profile {name}")
    if overrides:
        merged = settings.as_dict()
        merged.update({k: _coerce(k, v) for k, v in overrides.items()})
        settings = _validated(merged, "--set")
    return settings
