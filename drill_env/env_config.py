"""``EnvConfig``: the settings of ``DrillString-v0`` (typed, validated, dotted-path errors)."""

from __future__ import annotations

import dataclasses
import inspect
import math
import warnings
from collections.abc import Mapping
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import Field

from drill_env.physics.config import SimulationConfig
from drill_env.physics.units import RPM
from drill_env.physics.validation import (
    ConfigError,
    Count,
    NonNegative,
    Positive,
    StrictBool,
    caller_outside,
    check_newtons,
    config_dataclass,
    did_you_mean,
    from_dict,
    numbers,
)

#: Bounds that keep the reward and the episode finite: weights up to 1e6 times terms that
#: are themselves bounded (SSI capped, excursion ratio below the runaway limit, ROP over a
#: scale of at least 1e-6 m/s) cannot overflow; time spans up to a year of simulated time.
MAX_WEIGHT = 1.0e6
MIN_SCALE = 1.0e-6
MAX_EPISODE_DURATION = 3.2e7
#: ``EnvConfig.control_interval``'s default (s): the step a ``DrillString-v0`` reward is
#: paid for (a task's env scored as the plain env scales its rate terms to it).
PLAIN_CONTROL_INTERVAL = 0.1
#: The spans of ``EnvConfig``'s default ``rpm_range`` (rad/s) and ``weight_on_bit_range``
#: (N): DrillString-v0's effort term divides set-point changes by them (set below).
PLAIN_SPANS: tuple[float, float]
#: Observation layout per ``sensors`` mode (names of the vector entries, in order).
OBSERVATIONS: dict[str, tuple[str, ...]] = {
    "downhole": (
        "torque_on_bit", "bit_speed", "weight_on_bit", "bit_x", "bit_y", "bit_vx", "bit_vy",
        "whirl_speed", "bit_force_x", "bit_force_y", "max_contact_force", "surface_speed",
        "surface_torque", "hook_load", "rop", "speed_setpoint", "weight_on_bit_setpoint",
    ),
    "surface": (
        "surface_speed", "surface_torque", "hook_load", "rop", "speed_setpoint",
        "weight_on_bit_setpoint",
    ),
}
#: Records one control step may hold (memory of the record buffer: 16 floats each).
MAX_RECORDS_PER_STEP = 100_000


def _weight(default: float) -> Any:
    return Field(default=default, ge=0.0, le=MAX_WEIGHT)


def _scale(default: float) -> Any:
    return Field(default=default, ge=MIN_SCALE, le=1.0e12)


@config_dataclass
class EnvConfig:
    """Environment settings (typed defaults; ``gymnasium.make`` keywords override them)."""

    #: Policy period (s); the simulator takes ``round(control_interval / dt)`` steps per
    #: action (10 Hz by default).
    control_interval: Positive = Field(default=PLAIN_CONTROL_INTERVAL, le=60.0)
    #: Episode length in simulated seconds; ``None`` takes the scenario's default.
    episode_duration: Annotated[Positive, Field(le=MAX_EPISODE_DURATION)] | None = None
    #: Surface speed set-point range (rpm) mapped from action[0] in [-1, 1].
    rpm_range: tuple[Annotated[NonNegative, Field(le=1000.0)],
                     Annotated[NonNegative, Field(le=1000.0)]] = (0.0, 200.0)
    #: Weight-on-bit range (N) mapped from action[1]; applied as the hook load
    #: ``string_weight - WOB``. Not cut to what the string carries: the default string's
    #: HWDP buckles above ~141 kN (``statics.pipe_buckling``; its BHA weighs ~122 kN in
    #: mud), which the coupled model then shows, as a real string would; only a start WOB
    #: is screened (``Scenario``). Task 2 (DrillOptimise-v0) drills up to 140 kN.
    weight_on_bit_range: tuple[Annotated[NonNegative, Field(le=1.0e7)],
                               Annotated[NonNegative, Field(le=1.0e7)]] = (0.0, 200.0e3)
    #: "absolute": action -> set point in the range; "incremental": action -> change of
    #: the set point, at most ``rpm_step`` / ``weight_on_bit_step`` per control step.
    action_mode: Literal["absolute", "incremental"] = "absolute"
    rpm_step: Positive = Field(default=10.0, le=1000.0)
    weight_on_bit_step: Positive = Field(default=10.0e3, le=1.0e7)
    #: Drawworks rate limit of the applied WOB (N/s): 50 kN/s moves the WOB across a
    #: typical 100 kN change in 2 s, as fast as a driller or autodriller releases line.
    #: The top-drive acceleration limit is in the simulator
    #: (``TopDriveConfig.max_acceleration``).
    drawworks_rate: Positive = Field(default=50.0e3, le=1.0e9)
    #: "downhole" (MWD at the bit + surface) or "surface" (surface measurements only).
    sensors: Literal["downhole", "surface"] = "downhole"
    #: Telemetry delay of the observation, in control steps.
    telemetry_delay: Count = Field(default=0, ge=0, le=10_000)
    #: Std of Gaussian noise added to the normalised observation (from ``np_random``).
    observation_noise: NonNegative = Field(default=0.0, le=100.0)
    #: Make-up torque of the drill-pipe connections (N m): exceeding it terminates. 40 kN m
    #: is the order of API RP7G's make-up torque for the NC50 connection of 5 in drill
    #: pipe (about 30-45 kN m by grade); a stick-slip cycle's peak torque reaches it.
    makeup_torque: Positive = Field(default=40.0e3, le=1.0e7)
    #: "settled": start at the scenario's operating point in steady rotation (see
    #: ``Simulator.reset``); "stalled": the same twist, but the string below the top drive
    #: at rest, as after a stall: the bit sticks at once and, where stick-slip can live,
    #: the first cycle is full size (the control tasks start so); "paper": ramp the rpm
    #: over 10 s, hold 10 s off bottom, apply the WOB at 20 s, then hand over.
    startup: Literal["settled", "stalled", "paper"] = "settled"
    #: Relative kick of the bit speed after a settled start, drawn uniformly in
    #: +-start_kick from the episode's ``np_random``: steady rotation is an equilibrium,
    #: and the kick lets seeds start different episodes (the benchmark and the control
    #: tasks use 0.02). 0: every seed starts in the same settled state. No effect with
    #: ``startup="stalled"`` (the bit is at rest) or ``"paper"`` (its own ramp).
    start_kick: NonNegative = Field(default=0.0, le=0.5)
    #: Record every k simulator steps inside a control interval (for the metrics); the
    #: env takes the largest divisor of the interval's steps up to k, so the records are
    #: evenly spaced (25 steps of 4 ms per 0.1 s: every 5th; 26 of 3.8 ms: every 2nd).
    record_every: Count = Field(default=10, ge=1, le=1_000_000)
    #: Length of the rolling window of the stick-slip metrics (s).
    metric_window: Positive = Field(default=3.0, le=3600.0)
    #: Cap the applied WOB at the largest WOB the FE mesh resolves
    #: (``Simulator.check_mesh_resolves``); without the cap a larger WOB stops the
    #: simulator (terminated, "mesh buckling" status). The cap is ``info[
    #: "weight_on_bit_limit"]``.
    limit_weight_on_bit_to_mesh: StrictBool = True
    #: Reward weights (the terms are in DrillStringEnv's docstring), chosen so that the terms
    #: are of one order at typical operating points: drilling at ~30 m/h earns ~0.8 per
    #: step (ROP over ``rop_scale``), full stick-slip (SSI ~1.3) costs ~1.3, so drilling
    #: fast in stick-slip earns less than drilling smoothly; the bit whirling on the wall all
    #: the time costs ~0.5 (whirl: weaker than stick-slip, as in the paper's priorities); a
    #: set-point jump across the whole range costs 0.2 per action (effort), a small
    #: trim almost nothing; a failure (torque over the make-up torque, divergence) costs
    #: 10, an order above any one step's terms, and each step it cuts off the episode's
    #: lowest step reward so far (where below 0): an outside review found that ending a
    #: costly episode early paid (task 1 at a low make-up torque: -188 failing at step 7,
    #: -1,816 running on).
    rop_weight: NonNegative = _weight(1.0)
    stick_slip_weight: NonNegative = _weight(1.0)
    whirl_weight: NonNegative = _weight(0.5)
    effort_weight: NonNegative = _weight(0.1)
    failure_weight: NonNegative = _weight(10.0)
    #: Cap on the SSI entering the reward (a stalled bit has an unbounded SSI; full
    #: stick-slip is 1-1.5).
    ssi_cap: Positive = Field(default=2.0, le=1.0e3)
    #: Normalisation scales of the observation, each near the top of its channel's
    #: typical range so the entries stay O(1): bit and surface torques of a few kN m,
    #: lateral forces of kN to tens of kN, ROPs up to 0.01 m/s (36 m/h).
    torque_scale: Positive = _scale(10.0e3)
    force_scale: Positive = _scale(10.0e3)
    rop_scale: Positive = _scale(0.01)

    def __post_init__(self) -> None:
        for name in ("rpm_range", "weight_on_bit_range"):
            low, high = getattr(self, name)
            if not high > low:
                raise ValueError(f"{name}: the high end must exceed the low end, got "
                                 f"{(low, high)}")
        check_newtons("weight_on_bit_range", self.weight_on_bit_range)


ENV_FIELDS = frozenset(f.name for f in dataclasses.fields(EnvConfig))
#: A randomised scenario's ranges of the drawn start set point, by the env keyword that
#: sets them (the scenario's own names are the env's action ranges): keyword -> the
#: scenario's parameter.
START_RANGES = {"start_rpm_range": "rpm_range",
                "start_weight_on_bit_range": "weight_on_bit_range"}


def start_ranges(scenario: str, given: dict[str, Any], config: EnvConfig) -> dict[str, Any]:
    """The ranges (rpm, N) a randomised ``scenario`` draws its start set point in, as its
    parameters: those ``given`` (``start_rpm_range``, ``start_weight_on_bit_range``),
    else the scenario's own cut to the env's action ranges: ``rpm_range=(0, 100)`` drew
    40-160 rpm and clamped every draw above 100 onto 100 (half the episodes). ValueError,
    naming the keyword, for a range given to a scenario that draws no start, reaching
    outside the action range, or an action range that misses the scenario's own."""
    from drill_env.scenarios import RANDOMISED, SCENARIOS

    if scenario not in RANDOMISED:
        if given:
            raise ValueError(f"{next(iter(given))}: scenario {scenario!r} draws no start; "
                             "it starts at its surface_speed and weight_on_bit")
        return {}
    defaults = inspect.signature(SCENARIOS[scenario]).parameters
    out = {}
    for key, param in START_RANGES.items():
        unit, scale = ("rpm", 1.0) if param == "rpm_range" else ("kN", 1e3)
        low, high = getattr(config, param)
        span = f"the env's {param} {low / scale:g}-{high / scale:g} {unit}"
        if key in given:
            pair = numbers(given[key], key)
            if pair.shape != (2,) or not np.all(np.isfinite(pair)):
                raise ValueError(f"{key}: expected (low, high) in {unit.replace('kN', 'N')}, "
                                 f"got {given[key]!r}")
            if param == "weight_on_bit_range":
                check_newtons(key, tuple(pair))
            lo, hi = float(pair[0]), float(pair[1])
            if not low <= lo <= hi <= high:
                raise ValueError(f"{key}: {lo / scale:g}-{hi / scale:g} {unit} must be an "
                                 f"ordered range within {span}")
        else:
            own_lo, own_hi = defaults[param].default
            lo, hi = max(own_lo, low), min(own_hi, high)
            if lo > hi:
                raise ValueError(f"{param}: {span} misses the {scenario} scenario's starting "
                                 f"draws, {own_lo / scale:g}-{own_hi / scale:g} {unit}; give "
                                 f"{key} within it")
        out[param] = (lo, hi)
    return out


def even_record_every(steps_per_action: int, record_every: int) -> int:
    """The record interval (simulator steps) the env uses: the largest divisor of the
    control interval's ``steps_per_action`` that is at most ``record_every``, so that the
    records are evenly spaced in time and every one stands for the same ``dt``. (The fast
    level's 0.1 s were 25 steps of 4 ms: recording every 10th step kept two records 40
    and 60 ms apart, and the metrics, which weigh every record by 40 ms, read 80 ms of
    each 100 ms: a 20 % low top-drive energy and a 3.75 s "3 s" window.)"""
    return max(k for k in range(1, min(record_every, steps_per_action) + 1)
               if steps_per_action % k == 0)


def step_plan(cfg: EnvConfig, dt: float, episode_duration: float) -> tuple[int, int]:
    """The simulator steps (of ``dt`` s) per control interval and per record of an env of
    ``cfg`` whose episodes last ``episode_duration`` s; ValueError naming the period that
    cannot be kept: a control interval or an episode under half its unit (not silently
    one: the policy's period would change), more than :data:`MAX_RECORDS_PER_STEP`
    records a step, a metric window of fewer than two records."""
    steps = round(cfg.control_interval / dt)
    if steps < 1:
        raise ValueError(f"control_interval: {cfg.control_interval:g} s is at most half the "
                         f"simulator's step ({dt:.3g} s)")
    if round(episode_duration / cfg.control_interval) < 1:
        raise ValueError(f"episode_duration: {episode_duration:g} s is at most half a "
                         f"control interval ({cfg.control_interval:g} s)")
    every = even_record_every(steps, cfg.record_every)
    if steps // every > MAX_RECORDS_PER_STEP:
        raise ValueError(f"record_every: {cfg.record_every} keeps {steps // every} records "
                         f"per control step ({cfg.control_interval} s at dt = {dt:.2e} s), "
                         f"more than {MAX_RECORDS_PER_STEP}: raise record_every")
    spacing = every * dt  # (one record's SSI and stuck share are 0: the stick-slip reward
    if round(cfg.metric_window / spacing) < 2:  # term vanished unsaid; a fuzzing walkthrough)
        raise ValueError(f"metric_window: {cfg.metric_window:g} s holds fewer than two "
                         f"records ({spacing:g} s apart): its metrics (SSI, stuck share) "
                         f"would read 0; give at least {2 * spacing:g} s")
    return steps, every


def mesh_weight_on_bit_limit(sim: Any, upper: float, tol: float = 100.0) -> float:
    """Largest WOB in [0, ``upper``] (N) that ``sim``'s mesh resolves (bisection, ``tol`` N).

    The simulator refuses a WOB that compresses an element beyond 80 % of its own
    buckling load (``Simulator.check_mesh_resolves``): ~294 kN on the ``default``
    string, ~235 kN on the paper's (``paper_case2``), ~196 kN in the ``lateral_60`` well,
    so the action range's 200 kN top is the limit but there. Returns ``upper`` when the
    simulator has no such check.
    """
    check = getattr(sim, "check_mesh_resolves", None)
    if check is None:
        return upper

    def ok(wob: float) -> bool:
        try:
            check(wob)
        except ValueError:
            return False
        return True

    if ok(upper):
        return upper
    lo, hi = 0.0, upper
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if ok(mid) else (lo, mid)
    return lo


def check_set_points(where: str, surface_speed: float, weight_on_bit: float
                     ) -> tuple[float, float]:
    """The set points a controller asks for (rad/s, N) as floats; ValueError unless they
    are finite numbers: clipped into the ranges, a NaN became a NaN action."""
    said = (f"{where}: set points must be finite numbers, got surface_speed "
            f"{surface_speed!r} rad/s, weight_on_bit {weight_on_bit!r} N")
    try:  # any one number (a 0-d array, a one-element tensor); not a string or a bool
        speed, wob = (float(numbers(v, where).reshape(()))
                      for v in (surface_speed, weight_on_bit))
    except ValueError:
        raise ValueError(said) from None
    if not (math.isfinite(speed) and math.isfinite(wob)):
        raise ValueError(said)
    return speed, wob


def warn_above_limit(where: str, wob: float, limit: float) -> None:
    """RuntimeWarning where a start WOB a caller gave (N) is above the env's
    ``weight_on_bit_limit`` (:func:`mesh_weight_on_bit_limit`): the bit gets the limit."""
    if wob > limit * (1 + 1e-12):
        warnings.warn(f"{where}weight_on_bit: {wob / 1e3:.4g} kN is above this string's "
                      f"weight_on_bit_limit, {limit / 1e3:.4g} kN, the largest WOB its mesh "
                      "resolves (info['weight_on_bit_limit']; EnvConfig."
                      "limit_weight_on_bit_to_mesh): the bit gets at most that (shorter "
                      "elements of the pipe it compresses, its element_length, raise it)",
                      RuntimeWarning, stacklevel=caller_outside())


def _default_spans() -> tuple[float, float]:
    default = EnvConfig()
    (s_lo, s_hi), (w_lo, w_hi) = default.rpm_range, default.weight_on_bit_range
    return s_hi * RPM - s_lo * RPM, w_hi - w_lo  # as the env's own ranges


PLAIN_SPANS = _default_spans()


def reset_options(options: Any) -> dict[str, Any]:
    """``reset(options=...)`` of a single env, checked: a dict of ``surface_speed`` and
    ``weight_on_bit``, each a finite number (a 0-d array too, not a bool or text); their
    ranges are judged once the episode's scenario is drawn."""
    if not isinstance(options, (Mapping, type(None))):
        raise ValueError(f"reset options: must be a dict, got {options!r}")
    options = dict(options or {})
    known = ["surface_speed", "weight_on_bit"]
    if unknown := sorted(map(str, set(options) - set(known))):
        raise ValueError(f"reset options: unknown key(s) {unknown}"
                         f"{did_you_mean(unknown[0], known)}; known: {known}")
    for name, value in options.items():
        try:
            number = None if isinstance(value, (bool, np.bool_, str, bytes)) else float(value)
        except (TypeError, ValueError):
            number = None
        if number is None or not math.isfinite(number):
            raise ValueError(f"reset options: {name}: must be a finite number, got {value!r}")
    return options


def env_config_from(config: Mapping[str, Any] | EnvConfig | None) -> EnvConfig:
    """The env's ``config=`` as an :class:`EnvConfig`; a key of the simulator's config
    (``mud.density``, ``string``) is said to belong in ``physics=`` (it was listed as an
    unknown field of EnvConfig beside the env's 26 settings: a new user's trial)."""
    try:
        return from_dict(EnvConfig, config)
    except ConfigError:
        sections = {f.name for f in dataclasses.fields(SimulationConfig)}
        given = [str(key) for key in (config if isinstance(config, Mapping) else {})
                 if str(key).split(".")[0].split("[")[0] in sections]
        if given:
            raise ConfigError(f"config: {', '.join(given)}: the simulator's config, not the "
                              "env's settings: give it as physics= (gym.make(..., physics="
                              f"{{{given[0]!r}: ...}}))") from None
        raise
