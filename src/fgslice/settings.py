"""One validated settings model; printer profiles are TOML files of the same keys.

Resolution order (later wins): the model's defaults, a built-in profile (or a user's
``--profile FILE.toml``, which may name a built-in it ``inherits``), then each
``--set KEY=VALUE``. Units: mm, mm/s, seconds, degrees Celsius, percent where named.
"""

from __future__ import annotations

import tomllib
from importlib import resources
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from fgslice.errors import SettingsError, did_you_mean

Dialect = Literal["marlin-mixing", "marlin-mixing-m163", "toolchanger", "temperature", "template"]


class Settings(BaseModel):
    """Every setting of a slice. Field descriptions are shown by ``fgslice profiles --keys``."""

    model_config = ConfigDict(extra="forbid", validate_assignment=True, frozen=False)

    # -- machine ---------------------------------------------------------------
    profile_name: str = Field("marlin-mixing", description="name of the profile these settings came from")
    description: str = Field("", description="one line about the machine")
    dialect: Dialect = Field("marlin-mixing", description="how a state change is written")
    channels: int = Field(2, ge=1, le=6, description="mixing channels (A, B, C, ...) of a mixing hotend")
    tool_count: int = Field(5, ge=1, le=64, description="tools of a toolchanger (T0..Tn-1)")
    bed_x: float = Field(220.0, gt=0, le=5000, description="bed width, mm")
    bed_y: float = Field(220.0, gt=0, le=5000, description="bed depth, mm")
    max_z: float = Field(250.0, gt=0, le=5000, description="build height, mm")
    nozzle_diameter: float = Field(0.4, gt=0.05, le=5.0, description="nozzle bore, mm")
    filament_diameter: float = Field(1.75, gt=0.1, le=5.0, description="filament diameter, mm")
    filament_density: float = Field(1.24, gt=0.1, le=25.0, description="filament density for mass estimates, g/cm^3")

    # -- state of a color ---------------------------------------------------------
    temperature_a: float = Field(190.0, ge=0, le=500, description="nozzle temperature at 100% material A (temperature dialect), C")
    temperature_b: float = Field(225.0, ge=0, le=500, description="nozzle temperature at 100% material B (temperature dialect), C")
    flow_model: Literal["none", "pla", "tpu"] = Field("none", description="foaming flow compensation polynomial (M221)")
    state_template: str = Field(
        "",
        description="template dialect: text emitted per state change; placeholders {color}, {f0}..{f5} (0-1), {pct0}..{pct5} (0-100), {pwm0}..{pwm5} (0-255), {temperature}",
    )

    # -- process -------------------------------------------------------------------
    layer_height: float = Field(0.2, gt=0.01, le=2.0, description="layer height h, mm")
    bead_width: float = Field(0.4, gt=0.05, le=5.0, description="extrusion bead width w, mm")
    strategy: Literal[1, 2] = Field(2, description="1: walls/skins/infill cut into colors; 2: faces filled densely")
    colors: int = Field(4, ge=1, le=1024, description="palette size N")
    fill_pattern: Literal["concentric", "rectilinear"] = Field("concentric", description="strategy 2 fill")
    walls: int = Field(2, ge=0, le=100, description="strategy 1 perimeters")
    wall_order: Literal["outer_first", "inner_first"] = Field("inner_first", description="strategy 1 perimeter order")
    top_layers: int = Field(3, ge=0, le=100, description="strategy 1 top solid layers")
    bottom_layers: int = Field(3, ge=0, le=100, description="strategy 1 bottom solid layers")
    infill_density: float = Field(20.0, ge=0, le=100, description="strategy 1 sparse infill, percent")
    infill_pattern: Literal["rectilinear", "concentric"] = Field("rectilinear", description="strategy 1 sparse infill pattern")
    infill_angle: float = Field(45.0, ge=-360, le=360, description="direction of rectilinear lines on even layers, degrees")
    feature_order: Literal["walls_first", "infill_first"] = Field("walls_first", description="within a color, strategy 1")
    min_segment_mm: float = Field(5.0, ge=0, le=1000, description="strategy 1 warns when color pieces are shorter, mm")
    zipper: float = Field(0.0, ge=0, le=100, description="zipper overlap band beta, percent of the gradient range")
    gcode_resolution: float = Field(0.0125, gt=0, le=1.0, description="path simplification tolerance, mm")

    # -- placement -------------------------------------------------------------------
    center: bool = Field(True, description="center the part on the bed")
    position_x: float = Field(0.0, ge=-5000, le=5000, description="part center X when center = false, mm")
    position_y: float = Field(0.0, ge=-5000, le=5000, description="part center Y when center = false, mm")
    skirt_loops: int = Field(1, ge=0, le=20, description="loops around the part on the first layer")
    skirt_distance: float = Field(3.0, ge=0, le=100, description="gap between skirt and part, mm")

    # -- purge and dead volume -------------------------------------------------------
    purge: bool = Field(True, description="strategy 1 purge tower on state changes")
    melt_volume_mm3: float = Field(68.5, ge=0, le=10000, description="melt chamber volume V_melt, mm^3")
    purge_scale_by_change: bool = Field(False, description="scale purge by the size of the state change")
    purge_tower_x: float | None = Field(None, description="tower center X (bed frame), mm; None: automatic")
    purge_tower_y: float | None = Field(None, description="tower center Y (bed frame), mm; None: automatic")
    lookahead_mm: float | Literal["auto"] = Field(0.0, description="issue state changes this far ahead (extruded path length), mm; 'auto' derives it from melt_volume_mm3")
    temperature_lead_s: float = Field(0.0, ge=0, le=3600, description="temperature dialect: issue changes this long ahead, s")
    tau_s: float = Field(8.0, gt=0, le=3600, description="thermal time constant of the hotend for simulation, s")
    mixing_share: float = Field(0.3, ge=0, le=1, description="share of the melt chamber that is well mixed (simulation)")

    # -- speeds, mm/s ----------------------------------------------------------------
    print_speed: float = Field(40.0, gt=0, le=1000, description="perimeters and solid fill, mm/s")
    outer_wall_speed: float = Field(25.0, gt=0, le=1000, description="external perimeters, mm/s")
    infill_speed: float = Field(60.0, gt=0, le=1000, description="sparse infill, mm/s")
    first_layer_speed: float = Field(20.0, gt=0, le=1000, description="every extrusion on layer 0, mm/s")
    travel_speed: float = Field(150.0, gt=0, le=2000, description="travel moves, mm/s")
    z_speed: float = Field(10.0, gt=0, le=500, description="Z moves, mm/s")

    # -- retraction ------------------------------------------------------------------
    retract_length: float = Field(0.8, ge=0, le=50, description="retraction length, mm of filament")
    retract_speed: float = Field(35.0, gt=0, le=500, description="retraction speed, mm/s")
    retract_min_travel: float = Field(1.0, ge=0, le=1000, description="retract only on travels longer than this, mm")
    z_hop: float = Field(0.0, ge=0, le=10, description="lift on retracted travels, mm")

    # -- temperatures and cooling ----------------------------------------------------
    nozzle_temperature: float = Field(210.0, ge=0, le=500, description="nozzle temperature, C")
    bed_temperature: float = Field(60.0, ge=0, le=200, description="bed temperature, C")
    fan_speed: float = Field(100.0, ge=0, le=100, description="part cooling fan, percent")
    fan_off_layers: int = Field(1, ge=0, le=1000, description="layers printed with the fan off")

    # -- machine limits (checked by verify) ------------------------------------------
    max_nozzle_temperature: float = Field(300.0, ge=0, le=600, description="hottest nozzle allowed, C")
    max_bed_temperature: float = Field(120.0, ge=0, le=300, description="hottest bed allowed, C")
    min_extrude_temperature: float = Field(170.0, ge=0, le=600, description="no extrusion below this nozzle temperature, C")
    max_cross_section_mm2: float = Field(2.0, gt=0, le=100, description="largest extruded cross-section (E volume per mm of XY travel), mm^2")
    min_flow_percent: float = Field(10.0, ge=0, le=1000, description="smallest M221 flow allowed, percent")
    max_flow_percent: float = Field(200.0, ge=0, le=1000, description="largest M221 flow allowed, percent")

    # -- G-code text -----------------------------------------------------------------
    start_gcode: str = Field(
        "G28 ; home\nG90\nM83\nM140 S{bed_temperature}\nM104 S{nozzle_temperature}\nM190 S{bed_temperature}\nM109 S{nozzle_temperature}\nG92 E0",
        description="emitted before the first layer; placeholders {nozzle_temperature} {bed_temperature}",
    )
    end_gcode: str = Field(
        "M104 S0\nM140 S0\nM107\nG91\nG1 Z5 F600\nG90\nM84",
        description="emitted after the last layer",
    )
    thumbnails: str = Field("16x16,220x124", description="thumbnail sizes WxH, comma separated; empty for none")

    @model_validator(mode="after")
    def _consistent(self) -> "Settings":
        if self.bead_width < self.layer_height:
            raise ValueError(
                f"bead_width ({self.bead_width} mm) must be at least layer_height ({self.layer_height} mm)"
            )
        from fgslice.toolpaths.paths import bead_area

        area = bead_area(self.bead_width, self.layer_height)
        if area > self.max_cross_section_mm2:
            raise ValueError(
                f"a {self.bead_width} x {self.layer_height} mm bead has a {area:.3f} mm^2 cross-section, more than "
                f"this machine's max_cross_section_mm2 = {self.max_cross_section_mm2}; use a smaller bead or layer, "
                "or raise max_cross_section_mm2 if the machine can extrude that much"
            )
        if isinstance(self.lookahead_mm, float) and self.lookahead_mm < 0:
            raise ValueError("lookahead_mm must be >= 0 or 'auto'")
        return self

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


def _raise_validation(exc: ValidationError, origin: str) -> None:
    first = exc.errors()[0]
    key = ".".join(str(p) for p in first["loc"]) or "settings"
    if first["type"] == "extra_forbidden":
        raise SettingsError(
            f"unknown setting '{key}' ({origin})",
            hint=did_you_mean(key, Settings.model_fields) or "run 'fgslice profiles --keys' for the list",
        ) from None
    msg = first["msg"].removeprefix("Value error, ")
    if not first["loc"]:
        raise SettingsError(f"inconsistent settings ({origin}): {msg}") from None
    raise SettingsError(f"setting '{key}' = {first.get('input')!r} is invalid ({origin}): {msg}") from None


def parse_overrides(pairs: list[str] | tuple[str, ...]) -> dict[str, str]:
    """``["key=value", ...]`` to a dict; values stay strings for the model to coerce."""
    out: dict[str, str] = {}
    for pair in pairs:
        key, sep, value = pair.partition("=")
        key = key.strip()
        if not sep or not key:
            raise SettingsError(f"--set expects KEY=VALUE, got '{pair}'", hint="for example --set walls=3")
        if key not in Settings.model_fields:
            raise SettingsError(
                f"unknown setting '{key}' (--set)",
                hint=did_you_mean(key, Settings.model_fields) or "run 'fgslice profiles --keys' for the list",
            )
        out[key] = value.strip().replace("\\n", "\n")
    return out


def _coerce(key: str, value: Any) -> Any:
    """Turn a --set string into the type a field expects where pydantic would not."""
    if isinstance(value, str) and key in ("purge_tower_x", "purge_tower_y") and value.lower() in ("none", "auto", ""):
        return None
    if isinstance(value, str) and key == "lookahead_mm" and value != "auto":
        try:
            return float(value)
        except ValueError:
            return value
    if isinstance(value, str) and key == "strategy" and value.strip() in ("1", "2"):
        return int(value)
    return value


def load_settings(profile: str | None = None, overrides: dict[str, Any] | None = None) -> Settings:
    """Resolve defaults, a profile (built-in name or TOML path) and overrides into Settings.

    Raises:
        SettingsError: unknown profile or key, malformed TOML, value out of range.
    """
    name = profile or "marlin-mixing"
    values = _flatten(_profile_values(name))
    origin = f"profile {name}"
    try:
        settings = Settings(**values)
    except ValidationError as exc:
        _raise_validation(exc, origin)
    if overrides:
        merged = settings.model_dump()
        merged.update({k: _coerce(k, v) for k, v in overrides.items()})
        try:
            settings = Settings(**merged)
        except ValidationError as exc:
            _raise_validation(exc, "--set")
    return settings
