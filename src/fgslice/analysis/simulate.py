"""Dead-volume simulation: the composition a printer actually deposits on every segment.

Two models of the hotend, both first-order systems driven by the commanded state:

* **Melt chamber** (mixing hotends, toolchangers, template machines): the chamber of
  volume ``V_melt`` (mm³) is plug flow through ``V_plug = (1 - s) V_melt`` followed by a
  well-mixed volume ``V_mix = s V_melt`` (``s`` = ``settings.mixing_share``). The
  composition leaving the nozzle once a cumulative volume ``v`` has been extruded is
  the commanded composition at ``v - V_plug``, smoothed by ``dy/dv = (u - y) / V_mix``.
  The mean residence volume is ``V_melt`` — the volume Appendix A's look-ahead
  ``L = V_melt / A`` purges. A toolchanger is treated the same way, as mixing of the
  commanded state vector.
* **Thermal lag** (temperature dialect): the nozzle temperature follows the commanded
  one with ``dT/dt = (T_cmd - T) / tau`` (``settings.tau_s``, seconds) over the time of
  every move, travels included; the deposited "composition" is the fraction of the
  first material that the linear mapping ``T = T_b + f_A (T_a - T_b)`` gives at the
  actual temperature (clamped to [0, 1]).

Both are solved exactly for piecewise-constant inputs (no time stepping): the result
for a segment is the average of the model output over the segment's volume (or time).
The core works on plain arrays (:class:`SegmentTrace`); :func:`simulate` builds the
trace from a G-code program and evaluates the design at the segment midpoints.

Conventions: mm, mm³, s, degC; fractions in the design's material order, rows sum to 1;
coordinates of a trace are in the bed frame (``bed = design + placement offset``).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from os import PathLike

import numpy as np

from fgslice.design.base import Design, Material
from fgslice.errors import DesignError, SettingsError, SliceError
from fgslice.machine.gcode_header import GcodeHeader, parse_header, read_header
from fgslice.slicing.layers import Placement

#: Per-interval decay exponent cap: beyond it the previous state weighs < 5e-18.
_MAX_DECAY = 40.0
#: Exponent span of one block of the exact scan (keeps exp(+span) far from overflow).
_BLOCK_DECAY = 500.0


def _lag_start(decay: np.ndarray, u2: np.ndarray, y0: np.ndarray) -> np.ndarray:
    """State of ``dy/ds = (u - y)`` at the start of each interval.

    ``decay`` ``(m,)`` are the interval lengths in units of the constant, ``u2``
    ``(m, k)`` the constant inputs, ``y0`` ``(k,)`` the state before the first interval.
    A prefix sum per block of bounded decay (at most ``total decay / 500`` blocks), so
    the cost is linear in ``m``.
    """
    xc = np.minimum(decay, _MAX_DECAY)
    e_end = np.cumsum(xc)
    e_start = e_end - xc
    block = (e_start // _BLOCK_DECAY).astype(np.int64)
    first = np.flatnonzero(np.r_[True, block[1:] != block[:-1]])
    bounds = np.r_[first, len(decay)]
    rel_end = e_end - np.repeat(e_start[first], np.diff(bounds))
    terms = (-np.expm1(-xc) * np.exp(rel_end))[:, None] * u2
    sums = np.empty_like(terms)
    for lo, hi in zip(bounds[:-1], bounds[1:]):
        np.cumsum(terms[lo:hi], axis=0, out=sums[lo:hi])
    decay_end = np.exp(-rel_end)[:, None]
    zero_start = decay_end * sums
    # Each block spans > 460 units of decay, so a block's end forgets its own start state.
    block_start = np.empty((len(first),) + u2.shape[1:])
    block_start[0] = y0
    block_start[1:] = zero_start[first[1:] - 1]
    y_end = zero_start + decay_end * np.repeat(block_start, np.diff(bounds), axis=0)
    return np.vstack([y0[None, :], y_end[:-1]])


def lag_average(widths: np.ndarray, inputs: np.ndarray, scale: float, initial: np.ndarray) -> np.ndarray:
    """Average output of a first-order lag over consecutive intervals of constant input.

    Solves ``dy/ds = (u - y) / scale`` exactly where ``u`` is constant (row ``inputs[i]``)
    over interval ``i`` of length ``widths[i]`` (same unit as ``scale``: mm³ or s), from
    ``y = initial`` at the start of the first interval, and returns the mean of ``y``
    over each interval. Vectorized, linear in the number of intervals.

    Args:
        widths: ``(m,)`` positive interval lengths.
        inputs: ``(m,)`` or ``(m, k)`` input held over each interval.
        scale: time or volume constant (> 0; 0 returns ``inputs`` unchanged).
        initial: ``()`` or ``(k,)`` state before the first interval.

    Returns:
        Array shaped like ``inputs``: the mean output over each interval.
    """
    u = np.asarray(inputs, dtype=float)
    if scale <= 0 or len(u) == 0:
        return u.copy()
    flat = u.ndim == 1
    u2 = u[:, None] if flat else u
    y0 = np.broadcast_to(np.asarray(initial, dtype=float), u2.shape[1:])
    x = np.asarray(widths, dtype=float) / scale
    y_begin = _lag_start(x, u2, y0)
    gain = np.where(x > 0, -np.expm1(-x) / np.where(x > 0, x, 1.0), 1.0)[:, None]
    mean = u2 + (y_begin - u2) * gain
    return mean[:, 0] if flat else mean


def mixing_deposit(
    volumes: np.ndarray,
    commanded: np.ndarray,
    v_plug: float,
    v_mix: float,
    initial: np.ndarray | None = None,
) -> np.ndarray:
    """Composition deposited on each extrusion segment by the melt-chamber model.

    The chamber's input is piecewise constant in extruded volume: *runs* that start
    where a commanded change has been pushed through the plug (``v_plug`` after it).
    The lag state at the start of each run comes from :func:`_lag_start` over the runs;
    within a run the output is ``u + (y_r - u) exp(-(v - V_r) / v_mix)``, integrated in
    closed form over each piece of a segment between run starts.

    Args:
        volumes: ``(n,)`` extruded volume of each segment in printing order, mm³ (> 0).
        commanded: ``(n, k)`` composition commanded while each segment is extruded.
        v_plug: plug-flow volume, mm³ (delay).
        v_mix: well-mixed volume, mm³ (exponential smoothing constant).
        initial: ``(k,)`` chamber content before the first segment; default: the first
            commanded composition (a primed hotend).

    Returns:
        ``(n, k)`` volume-averaged deposited composition of each segment.
    """
    vol = np.asarray(volumes, dtype=float)
    cmd = np.asarray(commanded, dtype=float)
    n = len(vol)
    if n == 0:
        return cmd.copy()
    start = cmd[0] if initial is None else np.asarray(initial, dtype=float)
    edges = np.concatenate([[0.0], np.cumsum(vol)])
    total = edges[-1]
    changed = np.flatnonzero(np.any(cmd[1:] != cmd[:-1], axis=1)) + 1
    run_start = np.concatenate([[0.0, v_plug], edges[changed] + v_plug])
    run_input = np.concatenate([start[None, :], cmd[:1], cmd[changed]])
    inside = run_start < total
    run_start, run_input = run_start[inside], run_input[inside]
    # pieces: the segments cut at every later run start (inserted after an equal edge)
    at = np.searchsorted(edges, run_start[1:], side="right")
    grid = np.insert(edges, at, run_start[1:])
    is_run = np.insert(np.zeros(n + 1, dtype=bool), at, True)
    run = np.cumsum(is_run[:-1])
    first_piece = np.flatnonzero(~is_run[:-1])
    widths = np.diff(grid)
    u = run_input[run]
    integral = u * widths[:, None]
    if v_mix > 0:
        y_run = _lag_start(np.diff(np.r_[run_start, total]) / v_mix, run_input, start)
        faded = np.exp(-(grid[:-1] - run_start[run]) / v_mix) * -np.expm1(-widths / v_mix) * v_mix
        integral += (y_run[run] - u) * faded[:, None]
    return np.add.reduceat(integral, first_piece, axis=0) / vol[:, None]


def thermal_temperature(durations: np.ndarray, commanded: np.ndarray, tau_s: float, initial: float | None = None) -> np.ndarray:
    """Mean nozzle temperature over each move under a first-order thermal lag.

    Args:
        durations: ``(n,)`` duration of every move in order (travels included), s.
        commanded: ``(n,)`` commanded nozzle temperature during each move, degC.
        tau_s: thermal time constant, s.
        initial: temperature before the first move; default the first commanded one
            (the start G-code waits for it with M109).

    Returns:
        ``(n,)`` mean actual temperature over each move, degC.
    """
    t_cmd = np.asarray(commanded, dtype=float)
    if len(t_cmd) == 0:
        return t_cmd.copy()
    start = t_cmd[0] if initial is None else float(initial)
    widths = np.maximum(np.asarray(durations, dtype=float), 1e-9)
    return lag_average(widths, t_cmd, tau_s, np.asarray(start))


def fraction_from_temperature(temperature: np.ndarray, temperature_a: float, temperature_b: float) -> np.ndarray:
    """Two-material fractions ``(n, 2)`` the linear temperature mapping gives, clamped.

    ``temperature_a`` is the temperature of 100 % material A, ``temperature_b`` of 100 % B.
    """
    if temperature_a == temperature_b:
        raise SettingsError(
            "temperature_a equals temperature_b: a temperature cannot encode a composition",
            hint="set different temperature_a and temperature_b",
        )
    f_a = np.clip((np.asarray(temperature, dtype=float) - temperature_b) / (temperature_a - temperature_b), 0.0, 1.0)
    return np.stack([f_a, 1.0 - f_a], axis=-1)


@dataclass
class SegmentTrace:
    """Every move of a print in order, as plain arrays (bed frame, mm, mm³, s, degC).

    A trace read for the melt-chamber model may hold only the extrusion moves: travels
    deposit nothing and take no part in mixing.

    Attributes:
        start: ``(n, 3)`` start point of each move.
        end: ``(n, 3)`` end point of each move.
        volume: ``(n,)`` deposited volume (0 for travels), mm³.
        duration: ``(n,)`` time the move takes, s.
        commanded: ``(n, k)`` composition commanded during the move.
        temperature: ``(n,)`` commanded nozzle temperature, degC (temperature dialect).
        height: ``(n,)`` layer height of the move, mm.
        layer: ``(n,)`` 0-based layer index.
        line: ``(n,)`` 1-based line in the G-code (0 when not from a file).
        part: ``(n,)`` True for moves that build the part (not skirt, purge or custom).
        feature: ``(n,)`` index into :data:`FEATURES` of each move's role (None: unknown).
    """

    start: np.ndarray
    end: np.ndarray
    volume: np.ndarray
    duration: np.ndarray
    commanded: np.ndarray
    temperature: np.ndarray
    height: np.ndarray
    layer: np.ndarray
    line: np.ndarray
    part: np.ndarray
    feature: np.ndarray | None = None


#: What a move prints, for the account of transition material (:func:`feature_of_roles`).
FEATURES = ("walls", "skins", "infill", "tower", "other")
#: Words of ``;TYPE:`` names (fgslice/PrusaSlicer and Cura) per feature, checked in order.
_FEATURE_WORDS = (
    (3, ("wipe", "prime", "purge")),
    (0, ("perimeter", "wall", "gap")),
    (1, ("solid", "skin", "bridge", "top", "bottom")),
    (2, ("infill", "fill")),
)


def feature_of_roles(names) -> np.ndarray:
    """Index into :data:`FEATURES` of each ``;TYPE:`` role name: wipe/prime/purge tower,
    walls (perimeters, gap fill, Cura's WALL-*), skins (solid, top, bottom, bridge, Cura's SKIN),
    sparse infill (Internal infill, Cura's FILL), anything else "other"."""
    out = np.full(len(names), len(FEATURES) - 1, dtype=np.int64)
    for i, name in enumerate(names):
        low = name.lower()
        out[i] = next((k for k, words in _FEATURE_WORDS if any(w in low for w in words)), out[i])
    return out


@dataclass(frozen=True)
class MeltModel:
    """Parameters of the simulation.

    Attributes:
        kind: ``"mixing"`` (melt chamber) or ``"thermal"`` (temperature dialect).
        melt_volume_mm3: V_melt, mm³ (mixing).
        mixing_share: share of V_melt that is well mixed (mixing).
        tau_s: thermal time constant, s (thermal).
        temperature_a: degC at 100 % material A (thermal).
        temperature_b: degC at 100 % material B (thermal).
    """

    kind: str
    melt_volume_mm3: float = 0.0
    mixing_share: float = 0.0
    tau_s: float = 0.0
    temperature_a: float = 0.0
    temperature_b: float = 0.0

    @classmethod
    def from_settings(cls, settings, melt_volume_mm3: float | None = None) -> "MeltModel":
        """The model of ``settings``' dialect; ``melt_volume_mm3`` overrides V_melt."""
        volume = settings.melt_volume_mm3 if melt_volume_mm3 is None else float(melt_volume_mm3)
        if volume < 0:
            raise SettingsError(f"melt volume must be >= 0 mm^3, got {volume}", hint="--melt-volume 68.5")
        return cls(
            kind="thermal" if settings.dialect == "temperature" else "mixing",
            melt_volume_mm3=volume,
            mixing_share=settings.mixing_share,
            tau_s=settings.tau_s,
            temperature_a=settings.temperature_a,
            temperature_b=settings.temperature_b,
        )

    @property
    def v_plug(self) -> float:
        """Plug-flow volume ``(1 - s) V_melt``, mm³."""
        return (1.0 - self.mixing_share) * self.melt_volume_mm3

    @property
    def v_mix(self) -> float:
        """Well-mixed volume ``s V_melt``, mm³."""
        return self.mixing_share * self.melt_volume_mm3


def _extruding(trace: SegmentTrace) -> np.ndarray | slice:
    """Selects the trace's extrusion moves: a mask, or a slice (views, no copies) when all extrude."""
    extruding = trace.volume > 0
    return slice(None) if extruding.all() else extruding


def deposit(trace: SegmentTrace, model: MeltModel) -> np.ndarray:
    """Deposited composition ``(n_extrusions, k)`` of the trace's extrusion moves, in order."""
    extruding = _extruding(trace)
    if model.kind == "thermal":
        actual = thermal_temperature(trace.duration, trace.temperature, model.tau_s)
        return fraction_from_temperature(actual[extruding], model.temperature_a, model.temperature_b)
    return mixing_deposit(trace.volume[extruding], trace.commanded[extruding], model.v_plug, model.v_mix)


@dataclass
class SimulationResult:
    """What a print deposits, segment by segment (extrusion moves only, printing order).

    Attributes:
        deposited: ``(n, k)`` simulated deposited fractions.
        commanded: ``(n, k)`` fractions commanded while the segment was printed.
        designed: ``(n, k)`` the design's fractions at the segment midpoints.
        volume: ``(n,)`` extruded volume, mm³.
        start: ``(n, 3)`` segment start, bed frame, mm.
        end: ``(n, 3)`` segment end, bed frame, mm.
        layer: ``(n,)`` layer index.
        line: ``(n,)`` G-code line of the move (0 when not from a file).
        part: ``(n,)`` True where the segment builds the part (metrics use only these).
        materials: the design's materials (for colors).
        palette_size: N from the G-code's ``; colors = N`` comment, if any.
        model: the model used.
        feature: ``(n,)`` index into :data:`FEATURES` (None: unknown).
        palette_kind: the palette's kind (``centers`` or ``ends``), for its bin size.
    """

    deposited: np.ndarray
    commanded: np.ndarray
    designed: np.ndarray
    volume: np.ndarray
    start: np.ndarray
    end: np.ndarray
    layer: np.ndarray
    line: np.ndarray
    part: np.ndarray
    materials: list[Material]
    palette_size: int | None
    model: MeltModel
    feature: np.ndarray | None = None
    palette_kind: str = "centers"


def designed_at(design: Design, offset: tuple[float, float, float], points: np.ndarray, height: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The design's fractions and signed distance at bead centers.

    Args:
        design: the design (design frame).
        offset: placement offset, ``bed = design + offset``, mm.
        points: ``(n, 3)`` nozzle positions (bed frame, z = top of the layer), mm.
        height: ``(n,)`` layer heights; the bead center is at ``z - height / 2``.

    Returns:
        ``((n, k) fractions, (n,) signed distance in mm)``.
    """
    x = points[:, 0] - offset[0]
    y = points[:, 1] - offset[1]
    z = points[:, 2] - height / 2 - offset[2]
    return design.fractions(x, y, z), design.sdf(x, y, z)


def simulate_trace(
    trace: SegmentTrace,
    design: Design,
    offset: tuple[float, float, float],
    model: MeltModel,
    *,
    palette_size: int | None = None,
    palette_kind: str = "centers",
    part_tolerance_mm: float = 0.2,
) -> SimulationResult:
    """Simulate a trace and compare with the design placed at ``offset``.

    Segments whose midpoint lies farther than ``part_tolerance_mm`` outside the design
    (skirt, purge towers, travel-side artefacts of other slicers) or whose move is not
    part of the part (``trace.part``) are kept in the result but flagged ``part=False``.
    """
    extruding = _extruding(trace)
    deposited = deposit(trace, model)
    start = trace.start[extruding]
    end = trace.end[extruding]
    designed, distance = designed_at(design, offset, (start + end) / 2, trace.height[extruding])
    return SimulationResult(
        deposited=deposited,
        commanded=trace.commanded[extruding],
        designed=designed,
        volume=trace.volume[extruding],
        start=start,
        end=end,
        layer=trace.layer[extruding],
        line=trace.line[extruding],
        part=trace.part[extruding] & (distance <= part_tolerance_mm),
        materials=list(design.materials),
        palette_size=palette_size,
        model=model,
        feature=None if trace.feature is None else trace.feature[extruding],
        palette_kind=palette_kind,
    )


def _feed_mm_s(role, layer_index: int, settings) -> float:
    """Printing speed of a path, mm/s (first-layer speed, else by role)."""
    from fgslice.toolpaths.paths import Role

    if layer_index == 0:
        return settings.first_layer_speed
    if role is Role.EXTERNAL_PERIMETER:
        return settings.outer_wall_speed
    if role is Role.INTERNAL_INFILL:
        return settings.infill_speed
    return settings.print_speed


def trace_from_plans(plans, centers: np.ndarray, settings) -> SegmentTrace:
    """The moves a plan will make, without writing G-code (predictions, calibration).

    Each path vertex pair is an extrusion of ``length x bead_area(width, height)`` mm³ at
    the role's speed; a travel at ``travel_speed`` joins consecutive paths. The
    commanded composition is ``centers[color]`` of the latest :class:`SetState` (the
    first path's color before any); its temperature follows the linear mapping.

    Args:
        plans: iterable of :class:`fgslice.planning.plan.LayerPlan`.
        centers: ``(N, k)`` palette centers (:attr:`Palette.centers`).
        settings: speeds and temperatures.

    Raises:
        SliceError: the plans hold no paths.
    """
    from fgslice.planning.plan import SetState
    from fgslice.toolpaths.paths import Role, bead_area

    non_part = {Role.SKIRT, Role.WIPE_TOWER, Role.CUSTOM, Role.SUPPORT, Role.SUPPORT_INTERFACE}
    feature_of = dict(zip(Role, feature_of_roles([role.value for role in Role]).tolist()))
    rows = []   # (xy, z, (area, speed, color, part, layer, height, feature)) per path or travel
    color = None
    last = None
    for plan in plans:
        for step in plan.steps:
            if isinstance(step, SetState):
                color = step.color
                continue
            color = step.color if color is None else color
            xy = step.vertices
            if last is not None:
                travel = (0.0, settings.travel_speed, color, False, plan.index, plan.height, len(FEATURES) - 1)
                rows.append((np.array([last, xy[0]]), plan.z, travel))
            speed = _feed_mm_s(step.role, plan.index, settings)
            extrusion = (bead_area(step.width, step.height), speed, color, step.role not in non_part, plan.index,
                         plan.height, feature_of[step.role])
            rows.append((xy, plan.z, extrusion))
            last = xy[-1]
    if not rows:
        raise SliceError("the plans hold no paths to simulate")
    counts = np.array([len(r[0]) - 1 for r in rows])
    start = np.concatenate([np.column_stack([r[0][:-1], np.full(len(r[0]) - 1, r[1])]) for r in rows])
    end = np.concatenate([np.column_stack([r[0][1:], np.full(len(r[0]) - 1, r[1])]) for r in rows])
    length = np.linalg.norm(end - start, axis=1)
    area, speed, color_index, part, layer, height, feature = np.repeat(np.array([r[2] for r in rows], dtype=float), counts, axis=0).T
    color_index = color_index.astype(np.int64)
    commanded = np.asarray(centers, dtype=float)[color_index]
    temperature = settings.temperature_b + commanded[:, 0] * (settings.temperature_a - settings.temperature_b)
    return SegmentTrace(
        start=start,
        end=end,
        volume=length * area,
        duration=length / speed,
        commanded=commanded,
        temperature=temperature,
        height=height,
        layer=layer.astype(np.int64),
        line=np.zeros(len(length), dtype=np.int64),
        part=part.astype(bool),
        feature=feature.astype(np.int64),
    )


#: Settings a simulation depends on, read back from the ``; key = value`` comments fgslice writes.
SIMULATION_KEYS = (
    "profile_name", "dialect", "channels", "tool_count", "colors", "melt_volume_mm3", "mixing_share", "tau_s",
    "temperature_a", "temperature_b", "nozzle_temperature", "filament_diameter", "layer_height", "bead_width",
    "travel_speed", "bed_x", "bed_y", "center", "position_x", "position_y", "scale",
)
_NON_PART_ROLES = ("skirt", "brim", "wipe", "prime", "purge", "custom", "support")


def simulation_settings(gcode: str | PathLike | bytes, profile: str | None = None, overrides: dict[str, str] | None = None):
    """Settings to simulate a G-code file with.

    With ``profile``: ``load_settings(profile, overrides)``, the file's comments ignored.
    Without: the file's own :data:`SIMULATION_KEYS` comments (fgslice writes every
    setting into its G-code) over its built-in profile (or the default profile), then
    ``overrides`` (``--set``, ``--melt-volume``). A file without such comments (another
    slicer's) gets the default profile.
    """
    from fgslice.settings import builtin_profiles, load_settings

    if profile is not None:
        return load_settings(profile, overrides)
    values = {k: v for k, v in _header_of(gcode).settings.items() if k in SIMULATION_KEYS}
    name = values.pop("profile_name", None)
    values.update(overrides or {})
    return load_settings(name if name in builtin_profiles() else None, values)


def _state_compositions(program, settings, centers: np.ndarray, n_materials: int) -> np.ndarray:
    """``(len(program.states), k)`` composition each machine state commands.

    Mixing dialects: the M165/M163 factors (normalized, channels beyond k dropped);
    toolchanger: the palette center of the tool index; template: the center of the
    ``;STATE:`` color; temperature: the linear mapping of the nozzle target. A state
    that says nothing usable falls back to the ``;STATE:`` color, then to material A.
    """
    size = len(centers)
    out = np.zeros((len(program.states), n_materials))
    out[:, 0] = 1.0
    for i, state in enumerate(program.states):
        if settings.dialect == "temperature" and state.temperature is not None:
            out[i] = fraction_from_temperature(np.array(state.temperature), settings.temperature_a, settings.temperature_b)[: n_materials]
            continue
        mix = state.mix_fractions(n_materials) if settings.dialect.startswith("marlin-mixing") else None
        if mix is not None:
            out[i] = mix
            continue
        if settings.dialect == "toolchanger" and 0 <= state.tool < size:
            out[i] = centers[state.tool]
            continue
        if state.color is not None and 0 <= state.color < size:
            out[i] = centers[state.color]
    return out


def trace_from_program(program, settings, centers: np.ndarray, *, travels: bool = True) -> SegmentTrace:
    """The moves of a read G-code program as a :class:`SegmentTrace`.

    Works for any slicer's G-code (relative or absolute E, ``G92``): a move deposits
    ``E x filament area x M221 flow`` mm³ when it has positive E and moves in XY;
    retractions and primes deposit nothing. Durations are the 3D length (or |E| for
    E-only moves) over the feed rate. Layer heights come from the ``;Z:`` comments when
    there are any, else ``settings.layer_height``. Moves whose ``;TYPE:`` names a
    skirt, brim, wipe/purge tower or custom G-code are not part of the part.

    Args:
        program: a :class:`fgslice.machine.gcode_reader.GcodeProgram`.
        settings: dialect, filament diameter, temperatures.
        centers: ``(N, k)`` palette centers (composition of color / tool ``i``).
        travels: keep the moves that deposit nothing (False: extrusion moves only).
    """
    return trace_from_chunks([program], settings, centers, travels=travels)


#: Per-move arrays a trace keeps from each chunk of G-code.
_CHUNK_FIELDS = ("start", "end", "volume", "duration", "state", "role", "layer", "line")


def _chunk_moves(program, settings, travels: bool) -> dict[str, np.ndarray]:
    """The :data:`_CHUNK_FIELDS` of one chunk's moves (see :func:`trace_from_program`)."""
    filament_area = np.pi * settings.filament_diameter**2 / 4
    flow = program.flow_of_moves() / 100.0
    deposits = (program.e > 0) & (program.length > 0)
    volume = np.where(deposits, program.e * filament_area * flow, 0.0)
    delta = program.end - program.start
    distance = np.maximum(np.sqrt(np.einsum("ij,ij->i", delta, delta)), np.abs(program.e))
    speed = np.where(program.feed > 0, program.feed / 60.0, settings.travel_speed)
    keep = slice(None) if travels else volume > 0
    return {
        "start": program.start[keep],
        "end": program.end[keep],
        "volume": volume[keep],
        "duration": (distance / speed)[keep],
        "state": program.state[keep].astype(np.int32),
        "role": program.role[keep].astype(np.int32),
        "layer": np.maximum(program.layer[keep], 0),
        "line": program.line[keep],
    }


def trace_from_chunks(chunks: Iterable, settings, centers: np.ndarray, *, travels: bool = True) -> SegmentTrace:
    """:func:`trace_from_program` over the chunks of
    :func:`fgslice.machine.gcode_reader.iter_gcode`, keeping only the arrays a trace
    needs from each chunk, so a long file never sits in memory as a whole program.

    Raises:
        GcodeError: from the chunks' reader (unreadable, empty, no moves).
    """
    parts: dict[str, list[np.ndarray]] = {name: [] for name in _CHUNK_FIELDS}
    last = None
    for last in chunks:
        for name, array in _chunk_moves(last, settings, travels).items():
            parts[name].append(array)
    moves = {name: np.concatenate(parts.pop(name)) for name in _CHUNK_FIELDS}
    centers = np.asarray(centers, dtype=float)
    temps = np.array([settings.nozzle_temperature if s.temperature is None else s.temperature for s in last.states])
    non_part = np.array([any(word in name.lower() for word in _NON_PART_ROLES) for name in last.roles] + [False])
    layer = moves["layer"]
    tops = np.asarray(last.layer_z, dtype=float)
    heights = np.diff(np.r_[0.0, tops]) if len(tops) else np.zeros(0)
    height = np.full(len(layer), settings.layer_height)
    known = (layer < len(heights))
    height[known] = heights[layer[known]]
    height = np.where(height > 0, height, settings.layer_height)
    commanded = _state_compositions(last, settings, centers, centers.shape[1])[moves["state"]]
    return SegmentTrace(
        start=moves["start"],
        end=moves["end"],
        volume=moves["volume"],
        duration=moves["duration"],
        commanded=commanded,
        temperature=temps[moves["state"]],
        height=height,
        layer=layer,
        line=moves["line"],
        part=~non_part[moves["role"]],
        feature=np.r_[feature_of_roles(last.roles), len(FEATURES) - 1][moves["role"]],
    )


def simulate(
    gcode,
    design: Design,
    placement: Placement | None,
    settings,
    *,
    melt_volume_mm3: float | None = None,
    palette_size: int | None = None,
) -> SimulationResult:
    """Simulate what a G-code file deposits and compare it with the design.

    Args:
        gcode: a G-code path, its text, or a read ``GcodeProgram`` (then its header
            comments are not available: pass ``placement`` and ``palette_size``).
        design: the design the G-code was sliced from.
        placement: design-to-bed translation; None: the file's
            ``; placement_offset = dx,dy,dz`` comment, else the slicer's default
            placement (:func:`fgslice.slicing.plan_layers.place_design`: lowest point on
            the bed, centered or at ``position_x/y``).
        settings: the machine profile (dialect, melt volume, mixing share, tau,
            temperatures, filament diameter).
        melt_volume_mm3: overrides ``settings.melt_volume_mm3`` (``--melt-volume``).
        palette_size: N; default the file's ``; colors = N``, else ``settings.colors``
            (``tool_count`` for a toolchanger).

    Raises:
        GcodeError: unreadable G-code or malformed header comments.
        SettingsError: a negative melt volume, equal temperatures of the mapping, a
            temperature profile for a design of other than two materials.
    """
    from fgslice.machine.gcode_reader import GcodeProgram, iter_gcode
    from fgslice.slicing.plan_layers import place_design
    from fgslice.slicing.states import header_palette, material_palette

    from fgslice.design.machine_design import for_machine
    from fgslice.design.fingerprint import fingerprint

    header = GcodeHeader() if isinstance(gcode, GcodeProgram) else _header_of(gcode)
    recorded = header.settings.get("design_fingerprint")
    if recorded and recorded != fingerprint(design):
        raise DesignError(
            f"the G-code was sliced from another design (its design_fingerprint {recorded} is not this "
            f"design's {fingerprint(design)}: the shape or the field differ)",
            hint="pass the design the G-code was sliced from (--design), or slice this design again",
        )
    design = for_machine(design, settings)  # as sliced
    names = tuple(m.name for m in design.materials)
    if header.materials and header.materials != names:
        raise DesignError(
            f"the G-code was sliced from a design of materials {', '.join(header.materials)}; this design has "
            f"{', '.join(names)}",
            hint="pass the design the G-code was sliced from (--design)",
        )
    foaming = settings.dialect == "temperature" and len(design.materials) == 1
    if foaming:  # the nozzle temperature is the graded quantity
        from fgslice.analysis.thermal_states import print_levels, thermal_states

        levels = print_levels(design, settings, header.settings.get("temperature_levels"))
        design, settings, levels_count = thermal_states(design, settings, levels)
        palette_size = levels_count  # one palette color per temperature level
    if settings.dialect == "temperature" and len(design.materials) != 2:
        raise SettingsError(
            f"the temperature dialect grades two materials; the design has {len(design.materials)}",
            hint="simulate with the profile the G-code was sliced for (--profile)",
        )
    size = palette_size or header.colors or (settings.tool_count if settings.dialect == "toolchanger" else settings.colors)
    palette = header_palette(len(design.materials), size, "ends" if foaming else header.palette or settings.palette,
                             None if foaming else header.settings.get("temperature_levels"))
    if placement is not None:
        offset = tuple(placement.offset)
    elif header.placement_offset is not None:
        offset = header.placement_offset
    else:
        offset = tuple(place_design(design, settings).offset)
    model = MeltModel.from_settings(settings, melt_volume_mm3)
    # arcs (G2/G3) as the straight pieces the firmware prints them in
    chunks = [gcode.split_arcs()] if isinstance(gcode, GcodeProgram) else (c.split_arcs() for c in iter_gcode(gcode))
    # a toolchanger's tool n prints material color n (whatever the temperature level)
    centers = material_palette(palette).centers if settings.dialect == "toolchanger" else palette.centers
    trace = trace_from_chunks(chunks, settings, centers, travels=model.kind == "thermal")
    result = simulate_trace(trace, design, offset, model, palette_size=size, palette_kind=palette.kind,
                            part_tolerance_mm=settings.bead_width / 2)
    claimed = float(result.volume[trace.part[_extruding(trace)]].sum())
    matched = float(result.volume[result.part].sum())
    if claimed > 0 and matched < MATCHED_SHARE * claimed:
        raise DesignError(
            f"only {100 * matched / claimed:.0f} % of the G-code's part extrusion lies in this design (placed at "
            f"offset {', '.join(f'{v + 0.0:g}' for v in offset)} mm): it was not sliced from it",
            hint="pass the design the G-code was sliced from (--design)",
        )
    return result


MATCHED_SHARE = 0.9
""":func:`simulate` refuses a design that holds less than this share of the G-code's part
extrusion (within half a bead): the G-code was sliced from another design."""


def _header_of(gcode) -> GcodeHeader:
    """The header comments of a G-code path (read only up to the first layer change),
    bytes or text."""
    if isinstance(gcode, bytes):
        return parse_header(gcode.decode("utf-8", errors="replace"))
    if isinstance(gcode, PathLike) or (isinstance(gcode, str) and "\n" not in gcode and len(gcode) < 4096):
        return read_header(gcode)
    return parse_header(str(gcode))
