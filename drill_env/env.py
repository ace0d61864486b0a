"""``DrillString-v0``: a Gymnasium environment over the FE drill-string simulator."""

from __future__ import annotations

import math
from collections import deque
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.error import ResetNeeded

from drill_env import metrics
from drill_env.env_batch import (  # noqa: F401  (OBS_BOUND, INFO_WINDOW_METRICS: the surface)
    _BIT_X,
    _BIT_Y,
    _STATUS,
    _SURFACE_TORQUE,
    _TIME,
    INFO_METRICS,
    INFO_READINGS,
    INFO_WINDOW_METRICS,
    OBS_BOUND,
    BatchFinish,
)
from drill_env.env_config import (  # noqa: F401  (EnvConfig, OBSERVATIONS: the env's surface)
    ENV_FIELDS,
    MAX_EPISODE_DURATION,
    MAX_RECORDS_PER_STEP,
    MAX_WEIGHT,
    MIN_SCALE,
    OBSERVATIONS,
    PLAIN_CONTROL_INTERVAL,
    PLAIN_SPANS,
    START_RANGES,
    EnvConfig,
    check_set_points,
    env_config_from,
    mesh_weight_on_bit_limit,
    reset_options,
    start_ranges,
    step_plan,
    warn_above_limit,
)
from drill_env.metrics import Metric
from drill_env.overrides import physics_overrides
from drill_env.physics.config import FIDELITY_LEVELS, SimulationConfig, flatten, replace
from drill_env.physics.layout import N_READINGS, READINGS, RECORD_CHANNELS
from drill_env.physics.simulator import OperatingPoint, Simulator
from drill_env.physics.units import RPM
from drill_env.physics.validation import action_values, check_newtons, did_you_mean
from drill_env.scenarios import (
    RANDOMISED,
    Scenario,
    check_draws,
    check_one_string_length,
    scenario_parameters,
    scenario_with_physics,
)

#: Seconds of history in a rendered frame (``render_mode="rgb_array"``).
RENDER_SECONDS = 10.0


class DrillStringEnv(BatchFinish, gym.Env):
    r"""Drill-string stick-slip and whirl control: top-drive rpm and hook load.

    ## Description

    A finite-element drill string (the ``default`` scenario's realistic 1250 m string:
    5 in pipe over 140 m of heavy-weight pipe and a packed BHA; lateral and torsional
    dynamics, borehole-wall contact) drives a mesoscopic PDC bit (``drill_env.physics``)
    through one hard rock (``default``, ``stick_slip``) or a dipping hard-soft-hard sandwich
    (``paper_case2``-``4``, ``random``: the tasks'). The agent sets the top drive's speed
    set point and the hook load (as the WOB it leaves) ten times a second; the simulator
    integrates the string in between (``round(control_interval / dt)`` steps of 2 ms at the
    full level) and records the bit's motion, from which :mod:`drill_env.metrics` computes
    the stick-slip and whirl metrics. The task: drill fast without stick-slip and whirl,
    and in a layered scenario while the bit crosses formation changes.

    ## Action Space

    ``Box(-1, 1, (2,), float32)``. Finite actions outside [-1, 1] are CLIPPED; NaN or
    infinite actions raise ``ValueError``.

    | Num | Action                  | absolute mode             | incremental mode            |
    |-----|-------------------------|---------------------------|-----------------------------|
    | 0   | surface speed set point | ``rpm_range`` (0-200 rpm) | +- ``rpm_step`` (10 rpm)    |
    | 1   | hook load, as its WOB   | ``weight_on_bit_range``   | +- ``weight_on_bit_step``   |
    |     |                         | (0-200 kN)                | (10 kN)                     |

    Absolute mode maps [-1, 1] linearly onto the range; incremental mode changes the set
    point by ``action * step`` per control step (clipped to the range).

    The second action is the drawworks' hook load, commanded as the WOB it leaves on the
    bit (the same quantity in units a driller sets): applied as ``sim.hook_load_for(WOB)``
    (buoyed string weight minus WOB, ``info["hook_load"]``), it moves by at most
    ``drawworks_rate * control_interval`` per step (drawworks rate limit) and never above
    ``weight_on_bit_limit``, the largest WOB the FE mesh resolves (see
    ``limit_weight_on_bit_to_mesh``: the top of the default 0-200 kN range in the built-in
    scenarios, 195 kN in ``lateral_60``, less on a string with a light BHA or in a long
    build: a reset option above it warns); the speed set point is rate limited inside the
    simulator (top-drive ``max_acceleration``). The WOB is held within a control interval.

    ## Observation Space

    ``Box(-10, 10, (n,), float32)``, each entry normalised to O(1) and clipped to +-10.
    ``sensors="downhole"`` (n = 17):

    | Num | Observation              | Normalised by                               |
    |-----|--------------------------|---------------------------------------------|
    | 0   | torque on bit            | ``torque_scale`` (10 kN m)                  |
    | 1   | bit speed                | max of ``rpm_range`` in rad/s               |
    | 2   | weight on bit            | max of ``weight_on_bit_range``              |
    | 3-4 | bit lateral x, y         | gauge clearance                             |
    | 5-6 | bit lateral velocity     | clearance x max speed                       |
    | 7   | whirl speed              | max speed (clipped: noisy when centred)     |
    | 8-9 | bit lateral force x, y   | ``force_scale`` (10 kN)                     |
    | 10  | max wall contact force   | ``force_scale``                             |
    | 11  | surface speed            | max speed                                   |
    | 12  | surface torque           | ``torque_scale``                            |
    | 13  | hook load                | string weight                               |
    | 14  | ROP                      | ``rop_scale`` (0.01 m/s)                    |
    | 15  | speed set point (cmd)    | max speed                                   |
    | 16  | WOB set point (cmd)      | max of ``weight_on_bit_range``              |

    ``sensors="surface"`` (n = 6): entries 11-16 only. The names are in
    ``env.unwrapped.observation_names``. ``telemetry_delay`` delays the observation by that
    many control steps; ``observation_noise`` adds Gaussian noise of that standard
    deviation, in the observation's own scaled units, drawn from ``np_random``, to every
    entry (the set points' echo too).

    ## Rewards

    ``reward = sum(info["reward_terms"].values())`` (batched: less the ``_`` masks), per step:

    - ``rop``: ``rop_weight * mean ROP / rop_scale`` over the control interval;
    - ``stick_slip``: ``-stick_slip_weight * min(SSI, ssi_cap)``, SSI of the bit speed over
      the last ``metric_window`` seconds (:func:`drill_env.metrics.stick_slip_severity`);
    - ``whirl``: ``-whirl_weight * mean excursion ratio`` over the interval: the bit's lateral
      distance from where the reset put it (:func:`drill_env.metrics.excursion_ratio`);
    - ``effort``: ``-effort_weight * ((d rpm / rpm span)^2 + (d WOB / WOB span)^2)``, the
      change of the commanded set points;
    - ``failure``: on a termination (torque limit, divergence) ``-failure_weight``, less
      each step it cuts off at the episode's lowest step reward so far (if below 0).

    ## Starting State

    ``startup="settled"`` (default): ``Simulator.reset`` at the scenario's operating point,
    i.e. steady rotation with the static twist that balances mud drag, bit torque and wall
    friction, the string straight (vertical hole) or at rest on the wall (curved hole).
    ``startup="stalled"``: that state with the string below the top drive at rest.
    ``start_kick`` (a settled start only) kicks the bit speed by a fraction drawn from the
    seed. ``startup="paper"``: rest, rpm ramped to the target over 10 s, held 10 s off
    bottom, WOB applied at 20 s; the agent starts at 20 s. ``reset`` options
    ``surface_speed`` (rad/s) and ``weight_on_bit`` (N) override the scenario's set points.

    ## Episode End

    Terminated when the surface torque exceeds ``makeup_torque`` (``info[
    "termination_reason"] = "surface torque above make-up torque"``) or the simulator
    diverges (``sim.status != 0``: the reason is ``sim.status_message``). After a
    divergence the observation's measured entries repeat the last finite ones (the set
    points are the ones commanded) and every physical value in ``info`` is that of the
    last finite state; the window metrics read 0 while their window holds non-finite
    samples, and the reward terms stay finite. ``info`` never holds NaN or inf.
    Truncated after ``episode_duration`` seconds, by the env itself: the registered ids
    set no ``max_episode_steps`` (``env.spec.max_episode_steps`` is None, no TimeLimit);
    ``env.unwrapped.max_episode_steps`` is the count of the episode at hand.

    ## Info

    Every step, in SI: ``time``, ``episode_time`` (s), ``bit_speed``, ``surface_speed``
    (rad/s), ``torque_on_bit``, ``surface_torque`` (N m), ``weight_on_bit``, ``hook_load``
    (N), ``bit_lateral`` (x, y m), ``bit_force_x``, ``bit_force_y`` (the lateral force on
    the bit, N), ``max_contact_force`` (the largest wall force along the string, N),
    ``whirl_speed`` (rad/s), ``depth`` (m), ``rop`` (m/s), ``rock_share``,
    ``bit_inclination`` (rad); the set points ``speed_setpoint`` (rad/s),
    ``weight_on_bit_setpoint`` and the WOB the mesh resolves, ``weight_on_bit_limit`` (N);
    the window metrics ``ssi``, ``stuck_fraction``, ``whirl_ratio``, ``radial_ratio``,
    ``lateral_force``, ``mse`` (Pa, ``metrics.MSE_CEILING`` when the bit cuts without
    drilling: torque, no ROP); ``top_drive_energy`` (J, this episode: sum of |T w| dt, braking
    counted as spent, no regeneration); ``reward_terms``, ``termination_reason``.

    ## Arguments

    ``gymnasium.make("DrillString-v0", scenario="default", **kwargs)``:

    - ``scenario``: a name of :data:`drill_env.scenarios.SCENARIOS`; keywords that are
      parameters of that scenario (e.g. ``position="P3"`` for ``paper_case1``) go to it;
      ``random`` draws its start in ``start_rpm_range`` (rpm) and
      ``start_weight_on_bit_range`` (N), by default its own cut to the action ranges;
    - ``config``: an :class:`EnvConfig` or dict; every :class:`EnvConfig` field can also be
      passed as a keyword (``episode_duration=5.0``, ``action_mode="incremental"``,
      ``stick_slip_weight=2.0``, ...);
    - ``physics``: dotted-path overrides of the scenario's ``SimulationConfig``, e.g.
      ``{"mud.density": 1300.0, "top_drive.proportional_gain": 2e3}``; a string of
      another length keeps the bit at its bottom (``scenarios.with_physics``);
    - ``bit_model``: "mesoscopic" (default) or "macroscopic";
    - ``fidelity``: "full" (default) or "fast" (``solver.fidelity``: drill pipe held
      laterally straight on 20 m elements, a 4 ms step asked (~3.8 ms taken), ~5x faster;
      valid while the pipe is in tension, e.g. ``paper_case2``-``4``; docs/performance.md).

    Unknown keywords raise ``ValueError`` naming them.

    ## Version History

    - v0: initial version (``fidelity`` keyword added without changing "full" results).
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 10}
    own_settings: tuple[str, ...] = ()  # a subclass's settings besides EnvConfig's,
    unused_env_fields: frozenset[str] = frozenset()  # and the EnvConfig ones it ignores

    def __init__(self, scenario: str = "default", config: EnvConfig | dict | None = None, *,
                 physics: dict[str, Any] | None = None, bit_model: str | None = None,
                 fidelity: str | None = None, render_mode: str | None = None,
                 **overrides: Any) -> None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode: {render_mode!r} is not supported; supported: "
                             f"{self.metadata['render_modes']} or None (for whole episodes "
                             "with every channel, record them to rerun)")
        self.render_mode = render_mode
        params = set(scenario_parameters(scenario))  # validates the name
        env_over = {k: v for k, v in overrides.items() if k in ENV_FIELDS}
        scen_over = {k: v for k, v in overrides.items() if k in params and k not in ENV_FIELDS}
        starts = {k: v for k, v in overrides.items() if k in START_RANGES}
        unknown = set(overrides) - set(env_over) - set(scen_over) - set(starts)
        if unknown:
            fields = sorted(set(ENV_FIELDS) - self.unused_env_fields)  # the ones it reads
            params |= {*START_RANGES} - self.unused_env_fields if scenario in RANDOMISED else set()
            hint = did_you_mean(min(unknown), [*fields, *params, *self.own_settings])
            raise ValueError(f"DrillStringEnv: unknown argument(s) {sorted(unknown)}{hint}; "
                             f"EnvConfig fields: {fields}; scenario {scenario!r} "
                             f"parameters: {sorted(params)}")
        self.config: EnvConfig = replace(env_config_from(config), **env_over)
        self.scenario_name = scenario
        self.scenario_params = {**scen_over, **start_ranges(scenario, starts, self.config)}
        # {"mud": {"density": 1300}} and {"mud.density": 1300} both set one field.
        self.physics_overrides = physics_overrides(physics)
        if bit_model is not None:
            if self.physics_overrides.get("bit_model", bit_model) != bit_model:
                raise ValueError(f"physics.bit_model: {self.physics_overrides['bit_model']!r}"
                                 f" against bit_model={bit_model!r} (DrillStringMacro-v0's "
                                 "is 'macroscopic'): give one of the two")
            self.physics_overrides["bit_model"] = bit_model
        if fidelity is not None:
            if fidelity not in FIDELITY_LEVELS:
                raise ValueError(f"fidelity: must be one of {FIDELITY_LEVELS}, got {fidelity!r}"
                                 + did_you_mean(str(fidelity), list(FIDELITY_LEVELS)))
            self.physics_overrides["solver.fidelity"] = fidelity
        self.randomised = scenario in RANDOMISED
        check_one_string_length(self.scenario_params, self.physics_overrides)

        cfg = self.config
        self.observation_names = OBSERVATIONS[cfg.sensors]
        self.action_space = spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
        self.observation_space = spaces.Box(-OBS_BOUND, OBS_BOUND, dtype=np.float32,
                                            shape=(len(self.observation_names),))
        self._speed_range = (cfg.rpm_range[0] * RPM, cfg.rpm_range[1] * RPM)
        self._wob_range = tuple(float(v) for v in cfg.weight_on_bit_range)

        # Build (and validate) the physics now; randomised scenarios redraw at reset.
        check_draws(scenario, self.scenario_params, flatten(physics or {}),  # before a draw
                    *self._start_wob_draw())
        self.scenario: Scenario = self._build_scenario(np.random.default_rng(0))
        self._set_simulator(Simulator(self.scenario.config))
        if not self.randomised:
            self._check_range(self.scenario.surface_speed, self.scenario.weight_on_bit, "")
        self._init_episode_state()
        self._reset_done = False  # (step refuses to run before the first reset)
        self._ended = ""  # why the episode terminated ("": it did not); step warns past it

    # ------------------------------------------------------------------ set-up

    def _build_scenario(self, rng: np.random.Generator) -> Scenario:
        return scenario_with_physics(self.scenario_name, rng, self.scenario_params,
                                     self.physics_overrides, self.randomised)

    def _check_range(self, speed: float, wob: float, where: str) -> None:
        """ValueError naming a start set point (rad/s, N) outside the action ranges (or a
        WOB typed in kN), with the units it was read in."""
        check_newtons(f"{where}weight_on_bit", (wob,))
        for name, value, (low, high), unit, scale, field, si in (
                ("surface_speed", speed, self._speed_range, "rpm", RPM, "rpm_range", "rad/s"),
                ("weight_on_bit", wob, self._wob_range, "kN", 1e3, "weight_on_bit_range", "N")):
            if not low * (1 - 1e-12) <= value <= high * (1 + 1e-12):
                raise ValueError(f"{where}{name}: {value / scale:.4g} {unit} lies outside the "
                                 f"env's {field} {low / scale:g}-{high / scale:g} {unit} "
                                 f"({name} is in {si}: {value:.4g} {si})")
        warn_above_limit(where, wob, self.weight_on_bit_limit)

    def _set_simulator(self, sim: Simulator) -> None:
        self.sim = sim
        cfg = self.config
        self._steps_per_action, self._record_every = step_plan(cfg, sim.dt,
                                                               self.episode_duration)
        self.metadata = {**type(self).metadata, "render_fps": 1.0 / self.control_interval}
        self.weight_on_bit_limit = self._wob_range[1]
        if cfg.limit_weight_on_bit_to_mesh:
            self.weight_on_bit_limit = min(self.weight_on_bit_limit, mesh_weight_on_bit_limit(
                sim, self._wob_range[1]))
        # Constants of every step, looked up once per simulator (reset may build another).
        self._max_steps = self.max_episode_steps
        self._clearance = self.clearance
        self._string_weight = sim.string_weight
        self._max_wob_change = cfg.drawworks_rate * self.control_interval  # per step (N)
        self._obs_plan = self._observation_plan()

    def _init_episode_state(self) -> None:
        self._step_count = 0
        self._speed_target = 0.0
        self._wob_target = 0.0
        self._wob_applied = 0.0
        self._effort = 0.0
        self._worst_step = self._worst_plain = math.inf  # the episode's lowest step reward
        self._setpoint_change = (0.0, 0.0)  # of the set points (rad/s, N) at the last command
        #: None after every reset (not summed); set to 0.0 after ``reset``, it sums
        #: :meth:`_plain_reward` over that episode (a task's env scored as DrillString-v0).
        self.plain_return: float | None = None
        self.last_records = np.zeros((0, len(RECORD_CHANNELS)))
        #: The driller's set points of the episode (rad/s, N): the scenario's or the
        #: reset options'; actions move the set points, not these.
        self.targets = (0.0, 0.0)
        # The metrics of the records of the last ``metric_window`` seconds.
        record_dt = self._record_every * self.sim.dt
        self.rolling_metrics = metrics.RollingMetrics(
            max(1, round(self.config.metric_window / record_dt)), RECORD_CHANNELS, record_dt,
            self._clearance, self.sim.config.bit.diameter)
        self._window_metrics: tuple[list[float], bool] | None = None
        self._obs_queue: deque[list[float]] = deque(maxlen=self.config.telemetry_delay + 1)
        self._last_obs = np.zeros(len(self.observation_names), dtype=np.float32)
        self._episode_energy = 0.0
        self._start_time = 0.0
        self._frames = None
        if self.render_mode == "rgb_array":
            from drill_env.render import FrameHistory

            self._frames = FrameHistory(RECORD_CHANNELS, round(RENDER_SECONDS / record_dt))

    @property
    def simulation_config(self) -> SimulationConfig:
        return self.scenario.config

    @property
    def control_interval(self) -> float:
        """Actual policy period (s): an integer number of simulator steps."""
        return self._steps_per_action * self.sim.dt

    @property
    def episode_duration(self) -> float:
        d = self.config.episode_duration
        return d if d is not None else self.scenario.episode_duration

    @property
    def max_episode_steps(self) -> int:
        return max(1, round(self.episode_duration / self.control_interval))

    @property
    def clearance(self) -> float:
        return self.scenario.config.bit.gauge_clearance

    # ------------------------------------------------------------------ gym API

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[np.ndarray, dict[str, Any]]:
        # no step until this reset has finished: a refused one (a target out of range)
        # left a new string drawn under the old episode's state, and steps ran on it
        self._reset_done = False
        options = reset_options(options)  # refused before the seed is taken
        super().reset(seed=int(seed) if isinstance(seed, np.integer) else seed)  # np.int64 too
        given = frozenset(options)  # the targets the caller fixed
        if self.randomised:
            self.scenario = self._build_scenario(self.np_random)
            self._set_simulator(Simulator(self.scenario.config))
        speed = float(options.get("surface_speed", self.scenario.surface_speed))
        wob = float(options.get("weight_on_bit", self.scenario.weight_on_bit))
        speed, wob = self._start_targets(speed, wob, given)
        if given:  # (a random draw beyond ranges the user narrowed is clamped)
            self._check_range(speed, wob, "reset options: ")
        speed = min(max(speed, self._speed_range[0]), self._speed_range[1])
        wob = min(max(wob, self._wob_range[0]), self._wob_range[1])

        self._init_episode_state()
        wob_start = min(wob, self.weight_on_bit_limit)
        sim = self.sim
        settled = self.config.startup in ("settled", "stalled")
        sim.reset(OperatingPoint(speed, wob_start) if settled else OperatingPoint(0.0, 0.0))
        # the whirl reward's excursion is measured from where the reset put the bit
        self.rolling_metrics.set_rest(sim.readings[_BIT_X], sim.readings[_BIT_Y])
        if self.config.startup == "stalled":
            sim.vt[1:] = 0.0  # the string below the top drive at rest, twisted
            sim.read()
        if settled and self.config.start_kick > 0.0:
            sim.vt[-1] *= 1.0 + self.config.start_kick * self.np_random.uniform(-1.0, 1.0)
            sim.read()
        if not settled:
            self._paper_startup(speed, wob_start)
        self._speed_target, self._wob_target = self.targets = (speed, wob)
        self._wob_applied = wob_start
        self._start_time = sim.time
        self._window_metrics = self.rolling_metrics.window()
        self._readings = sim.readings.tolist()  # fresh after reset and the start-up
        self._status = self._readings[_STATUS]
        info = self._info()
        self._reset_done, self._ended = True, ""
        return self._observation(info), info

    def _start_wob_draw(self) -> tuple[float | None, str]:
        """The most WOB an episode of a randomised scenario starts at (N; None: its own
        range's top) and the setting that lowers it: the draws' buckling check."""
        return None, "start_weight_on_bit_range in gym.make"

    def _start_targets(self, speed: float, wob: float, given: frozenset[str]
                       ) -> tuple[float, float]:
        """The episode's set points (rad/s, N) from the scenario's or the reset options'
        (``given``: their names); a task draws the others here from ``np_random``."""
        return speed, wob

    def _paper_startup(self, speed: float, wob: float) -> None:
        """Paper section 4 start-up: ramp rpm over 10 s, hold 10 s off bottom, WOB at 20 s."""
        sim, n = self.sim, self._steps_per_action
        off_bottom = sim.string_weight  # the hook carries everything: WOB = 0
        ramp = max(1, round(10.0 / (n * sim.dt)))  # control steps in 10 s
        for k in range(2 * ramp):
            set_point = speed * (k + 1) / ramp if k < ramp else speed
            self.rolling_metrics.add(sim.advance(n, speed_setpoint=set_point,
                                                 hook_load=off_bottom,
                                                 record_every=self._record_every))
        sim.advance(0, hook_load=sim.hook_load_for(wob), read=True)

    def step(self, action) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        if not self._reset_done:  # (as gymnasium.make's OrderEnforcing and the vector envs)
            raise ResetNeeded("step: call reset() first (no episode: none yet, or the last "
                              "reset was refused)")
        if self._ended or self._step_count >= self._max_steps:  # undefined in Gymnasium:
            # said, as CartPole does (a loop that forgot to reset: an outside trial)
            ended = f"terminated: {self._ended}" if self._ended else "truncated"
            gym.logger.warn("step: past the episode's end (%s): call reset()", ended)  # (a
            # reason's own % read as a format: a buckled string's "80 %" raised TypeError)
        self.apply_action(action)
        self.keep_records(records := self.advance())
        result = self.finish_step(records)
        if result[2] and not self._ended:  # kept until a reset, judged again or not
            self._ended = result[4]["termination_reason"]
        return result

    def keep_records(self, records: np.ndarray) -> None:
        """This step's records as :attr:`last_records`, and in the rendered frames."""
        self.last_records = records
        if self._frames is not None:
            self._frames.add(records)

    # The three phases of a step are separate so a batched env can advance many simulators
    # between them (drill_env.batching: the metric windows are updated in the parallel
    # call, finish_metrics does the rest). The Python around the simulator call works on
    # floats read from its compiled readout (a NumPy call per quantity cost a third of the
    # physics), the metrics on a preallocated rolling window.

    def action_for(self, surface_speed: float, weight_on_bit: float) -> np.ndarray:
        """The action that asks for these set points (rad/s, N), clipped to the env's
        ranges: how a controller that thinks in set points drives the env. Incremental
        mode: the step toward them from the present set points, at most one ``rpm_step``
        and ``weight_on_bit_step``, so that set-point controllers drive such envs too."""
        surface_speed, weight_on_bit = check_set_points("action_for", surface_speed,
                                                        weight_on_bit)
        (s_lo, s_hi), (w_lo, w_hi) = self._speed_range, self._wob_range
        if self.config.action_mode == "absolute":
            a = (2.0 * (surface_speed - s_lo) / (s_hi - s_lo) - 1.0,
                 2.0 * (weight_on_bit - w_lo) / (w_hi - w_lo) - 1.0)
        else:
            a = ((min(max(surface_speed, s_lo), s_hi) - self._speed_target)
                 / (self.config.rpm_step * RPM),
                 (min(max(weight_on_bit, w_lo), w_hi) - self._wob_target)
                 / self.config.weight_on_bit_step)
        return np.clip(np.array(a, dtype=np.float32), -1.0, 1.0)

    def apply_action(self, action) -> None:
        """Validate ``action``, map it to set points (clipped, rate limited)."""
        a0, a1 = action_values(action, 2)
        a0 = 1.0 if a0 > 1.0 else -1.0 if a0 < -1.0 else a0
        a1 = 1.0 if a1 > 1.0 else -1.0 if a1 < -1.0 else a1
        cfg = self.config
        s_lo, s_hi = self._speed_range
        w_lo, w_hi = self._wob_range
        if cfg.action_mode == "absolute":
            speed = s_lo + 0.5 * (a0 + 1.0) * (s_hi - s_lo)
            wob = w_lo + 0.5 * (a1 + 1.0) * (w_hi - w_lo)
        else:
            speed = self._speed_target + a0 * cfg.rpm_step * RPM
            wob = self._wob_target + a1 * cfg.weight_on_bit_step
        self._command(speed, wob)

    def _command(self, speed: float, wob: float) -> None:
        """Send set points (rad/s, N): clipped to the ranges; the applied WOB follows at
        the drawworks rate and stays under the mesh limit; ``_effort`` is their change."""
        s_lo, s_hi = self._speed_range
        w_lo, w_hi = self._wob_range
        speed = s_hi if speed > s_hi else s_lo if speed < s_lo else speed
        wob = w_hi if wob > w_hi else w_lo if wob < w_lo else wob
        self._setpoint_change = (speed - self._speed_target, wob - self._wob_target)
        self._effort = (self._setpoint_change[0] / (s_hi - s_lo)) ** 2 + (
            self._setpoint_change[1] / (w_hi - w_lo)) ** 2
        self._speed_target, self._wob_target = speed, wob
        change = wob - self._wob_applied
        max_change = self._max_wob_change
        change = max_change if change > max_change else -max_change if change < -max_change \
            else change
        applied = self._wob_applied + change
        limit = self.weight_on_bit_limit
        self._wob_applied = limit if applied > limit else applied

    def advance(self) -> np.ndarray:
        """Run the simulator over one control interval; returns the records. Its
        ``readings`` are refreshed in the same compiled call (a batch: in its kernel)."""
        return self.sim.advance(*self.advance_request(), read=True)

    def advance_request(self) -> tuple[int, float, float, int]:
        """(n_steps, speed set point, hook load, record_every) of one control interval."""
        return (self._steps_per_action, self._speed_target,
                self.sim.hook_load_for(self._wob_applied), self._record_every)

    def finish_step(self, records: np.ndarray
                    ) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Everything after the simulator call: metrics, termination, reward, info."""
        return self.finish_metrics(*self.rolling_metrics.update(records))

    def finish_metrics(self, step: tuple[list[float], bool] | None,
                       window: tuple[list[float], bool] | None
                       ) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """:meth:`finish_step` once the records are in the window: ``step`` and
        ``window`` are their metrics and the window's (``step`` None: no records). A batch
        updates the windows of all envs in its compiled call, then calls this."""
        self._step_count += 1
        if step is not None:
            if step[1]:  # records not all finite add no energy: info stays finite
                self._episode_energy += step[0][Metric.TOP_DRIVE_ENERGY]
            self._window_metrics = window
        fresh = self.sim.readings.tolist()
        self._status = fresh[_STATUS]
        if all(map(math.isfinite, fresh)):
            self._readings = fresh
        # else: a diverged state; info keeps the last finite readings (see "Episode End")
        reason = self._termination_reason(step)
        terminated = bool(reason)
        truncated = (not terminated) and self._step_count >= self._max_steps
        terms = self._reward_terms(step, terminated)
        self._worst_step = min(self._worst_step, metrics.summed(
            value for key, value in terms.items() if key != "failure"))
        if terminated:  # and each step it cuts off at the episode's worst: failing never pays
            terms["failure"] -= (self._max_steps - self._step_count) * max(0.0, -self._worst_step)
        if self.plain_return is not None:  # a task's env as a guest (agents.benchmark)
            self.plain_return += self._plain_reward(step, terminated)
        info = self._info()
        obs = self._observation(info)
        info["reward_terms"] = terms
        info["termination_reason"] = reason
        return obs, metrics.summed(terms.values()), terminated, truncated, info

    # ------------------------------------------------------------------ hooks

    def _termination_reason(self, step: tuple[list[float], bool] | None) -> str:
        """Why the episode ends now ("" if it goes on). ``step``: the metrics of this
        interval's records and whether they are all finite (``None``: no records), from
        :class:`drill_env.metrics.RollingMetrics`."""
        if self._status != 0:
            return self.sim.status_message
        peak = step[0][Metric.SURFACE_TORQUE_MAX] if step is not None else 0.0
        if max(peak, abs(self._readings[_SURFACE_TORQUE])) > self.config.makeup_torque:
            return "surface torque above make-up torque"
        return ""

    def _reward_terms(self, step: tuple[list[float], bool] | None, terminated: bool
                      ) -> dict[str, float]:
        """The reward terms of this step (they sum to the reward); ``step`` as above."""
        cfg = self.config
        if step is not None and step[1]:
            rop, excursion = step[0][Metric.ROP], step[0][Metric.EXCURSION_RATIO]
        else:
            rop, excursion = 0.0, 1.0
        ssi = self._window_ssi()
        return {
            "rop": cfg.rop_weight * rop / cfg.rop_scale,
            "stick_slip": -cfg.stick_slip_weight * min(ssi, cfg.ssi_cap),
            "whirl": -cfg.whirl_weight * excursion,
            "effort": -cfg.effort_weight * self._effort,
            "failure": -cfg.failure_weight if terminated else 0.0,
        }

    def _plain_reward(self, step: tuple[list[float], bool] | None, terminated: bool
                      ) -> float:
        """What ``DrillString-v0`` pays for this step with its default weights, also in a
        task's env (a task's policy scored beside the classical controllers): the rate
        terms (ROP, stick-slip, whirl) weighted by the nominal control interval over the
        plain env's 0.1 s (a 1 s step counts as ten, an uneven 0.0988 s one as one); the
        effort over the plain env's set-point ranges and the failure as they are."""
        terms = DrillStringEnv._reward_terms(self, step, terminated)
        k = self.config.control_interval / PLAIN_CONTROL_INTERVAL
        change = self._setpoint_change
        effort = (change[0] / PLAIN_SPANS[0]) ** 2 + (change[1] / PLAIN_SPANS[1]) ** 2
        plain = (k * (terms["rop"] + terms["stick_slip"] + terms["whirl"])
                 - self.config.effort_weight * effort)
        self._worst_plain = min(self._worst_plain, plain)
        cut_off = (self._max_steps - self._step_count) * max(0.0, -self._worst_plain)
        return plain + (terms["failure"] - cut_off if terminated else 0.0)

    def _window(self) -> list[float] | None:
        """The metric window's values, None until it holds finite ones."""
        w = self._window_metrics
        return w[0] if w is not None and w[1] else None

    def _window_ssi(self) -> float:
        if self._window_metrics is None:
            return 0.0
        values, finite = self._window_metrics
        if not finite and not np.all(np.isfinite(self.rolling_metrics.bit_speed)):
            return math.inf
        return values[Metric.SSI]

    def _observation_plan(self) -> list[tuple[int, float]]:
        """(source, divisor) of every observation entry: the source indexes the readings
        followed by the two set points (:meth:`_raw_observation`)."""
        cfg = self.config
        w_max = self._speed_range[1]
        c = self._clearance
        divisor = {
            "torque_on_bit": cfg.torque_scale, "surface_torque": cfg.torque_scale,
            "bit_speed": w_max, "surface_speed": w_max, "whirl_speed": w_max,
            "speed_setpoint": w_max, "weight_on_bit": self._wob_range[1],
            "weight_on_bit_setpoint": self._wob_range[1], "bit_x": c, "bit_y": c,
            "bit_vx": c * w_max, "bit_vy": c * w_max, "bit_force_x": cfg.force_scale,
            "bit_force_y": cfg.force_scale, "max_contact_force": cfg.force_scale,
            "hook_load": self._string_weight, "rop": cfg.rop_scale,
        }
        n = len(self.sim.readings)
        source = {name: k for k, name in enumerate(READINGS)}
        source.update(speed_setpoint=n, weight_on_bit_setpoint=n + 1)
        return [(source[name], divisor[name]) for name in self.observation_names]

    def _raw_observation(self, info: dict[str, Any]) -> list[float]:
        """The observation before delay, noise and clipping: each entry of
        :data:`OBSERVATIONS` (a reading or a set point) over its scale."""
        values = self._readings + [self._speed_target, self._wob_target]
        return [values[k] / d for k, d in self._obs_plan]

    def _observation(self, info: dict[str, Any]) -> np.ndarray:
        raw = self._raw_observation(info)
        if not all(map(math.isfinite, raw)):  # diverged: repeat the last finite observation
            return self._last_obs.copy()
        if self.config.telemetry_delay:
            self._obs_queue.append(raw)
            raw = self._obs_queue[0]  # telemetry_delay steps old (oldest kept)
        if self.config.observation_noise > 0:
            noisy = np.array(raw) + self.config.observation_noise * \
                self.np_random.standard_normal(len(raw))
            raw = noisy.tolist()
        # Clipped as float64, then rounded: the same as clipping the float32 (+-10 is exact).
        if max(raw) > OBS_BOUND or min(raw) < -OBS_BOUND:
            raw = [OBS_BOUND if v > OBS_BOUND else -OBS_BOUND if v < -OBS_BOUND else v
                   for v in raw]
        obs = np.array(raw, dtype=np.float32)
        self._last_obs = obs
        return obs.copy()

    def _info(self) -> dict[str, Any]:
        r = self._readings  # the simulator's last finite readings
        info: dict[str, Any] = {name: r[k] for name, k in INFO_READINGS}
        info["bit_lateral"] = np.array(r[_BIT_X:_BIT_Y + 1])
        info["rock_share"] = np.array(r[N_READINGS:])
        info["speed_setpoint"] = self._speed_target
        info["weight_on_bit_setpoint"] = self._wob_target
        info["weight_on_bit_limit"] = self.weight_on_bit_limit
        info["episode_time"] = r[_TIME] - self._start_time
        info["top_drive_energy"] = self._episode_energy
        info["bit_inclination"] = self.sim.bit_inclination  # rad; the hole at the bit
        values = self._window()
        for name, k in INFO_METRICS:
            info[name] = values[k] if values is not None else 0.0
        info["reward_terms"] = {}
        info["termination_reason"] = ""
        return info

    def render(self) -> np.ndarray | None:
        """``render_mode="rgb_array"``: the last ``RENDER_SECONDS`` of bit and surface
        speed, torque on bit and the bit orbit in its clearance, as an RGB array
        (:mod:`drill_env.render`). Without a render mode: a warning and None."""
        if not self._reset_done:  # (it read the readings of no episode)
            raise ResetNeeded("render: call reset() before rendering")
        if self.render_mode is None or self._frames is None:
            gym.logger.warn("render() called without a render_mode: pass render_mode="
                            "'rgb_array' to gymnasium.make")
            return None
        from drill_env.render import draw_frame

        return draw_frame(self._frames, self._clearance, self._speed_range[1],
                          title=f"{self.scenario.name}: t = {self._readings[_TIME]:.1f} s")
