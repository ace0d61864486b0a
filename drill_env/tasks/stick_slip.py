"""``DrillStickSlip-v0``: the agent is the top drive's stick-slip controller."""

from __future__ import annotations

from typing import Annotated, Any

import numpy as np
from gymnasium import spaces
from pydantic import Field

from drill_env.env_config import check_set_points
from drill_env.metrics import Metric
from drill_env.physics.layout import READ
from drill_env.physics.units import RPM
from drill_env.physics.validation import (
    Count,
    NonNegative,
    Positive,
    action_values,
    check_newtons,
    config_dataclass,
)
from drill_env.tasks.base import TaskEnv
from drill_env.tasks.telemetry import TelemetrySetting

Rpm = Annotated[NonNegative, Field(le=1000.0)]
Newton = Annotated[NonNegative, Field(le=1.0e7)]
Seconds = Annotated[NonNegative, Field(le=1.0e6)]

#: What the task sets differently from ``DrillString-v0`` unless the caller says otherwise.
ENV_DEFAULTS: dict[str, Any] = {
    # the randomised sandwich-crossing distribution (realistic string of 900-1600 m,
    # three jittered rocks, a dipping layer near the bit, symmetric or asymmetric bit)
    "scenario": "random",
    # the pipe stays in tension at these WOBs, where "fast" matches "full"
    # (docs/performance.md) at ~3x the speed
    "fidelity": "fast",
    # 30 s: ~13 stick-slip periods; long enough to cure a running cycle and follow a
    # target change, short enough for many episodes per training minute
    "episode_duration": 30.0,
    # the bit starts stuck: where stick-slip can live, the first cycle is full size, so
    # the task is curing stick-slip, not only preventing its slow onset (the design note,
    # shared/design/stick-slip-task-prototype.md beside the repository)
    "startup": "stalled",
}


@config_dataclass
class StickSlipTask:
    """Targets, action, observation and reward of the stick-slip control task."""

    #: The driller's targets are drawn per episode, uniformly in these ranges: mostly
    #: where a stiff top drive stick-slips from a stalled start on the realistic string
    #: (below ~90 rpm at 70-130 kN; up to 130 kN the pipe stays in tension).
    rpm_targets: tuple[Rpm, Rpm] = (40.0, 100.0)
    weight_on_bit_targets: tuple[Newton, Newton] = (70.0e3, 130.0e3)
    #: A driller changes the targets once, at a time drawn in ``target_change_time``
    #: (s after the start), with this probability, by +- a draw in ``rpm_change`` (rpm)
    #: and ``weight_on_bit_change`` (N), kept inside the target ranges.
    target_change_probability: Annotated[NonNegative, Field(le=1.0)] = 0.5
    target_change_time: tuple[Seconds, Seconds] = (10.0, 20.0)
    rpm_change: tuple[Rpm, Rpm] = (5.0, 20.0)
    weight_on_bit_change: tuple[Newton, Newton] = (0.0, 20.0e3)
    #: The action [-1, 1] moves the speed command by up to this around the target (rpm):
    #: the prototype's +-30 rpm was enough to cure stick-slip at 35-65 rpm. At most the
    #: lowest rpm target, so that the command never turns the string backwards.
    max_correction: Positive = Field(default=30.0, ge=0.01, le=500.0)
    #: Frames of surface history in the observation (control steps): 20 frames = 2 s at
    #: 10 Hz, most of a stick-slip period (2-3 s on the 900-1600 m strings), from which the
    #: phase of the surface torque can be read. One frame did not learn in the
    #: prototype; 10 frames did on its 1.5 s period.
    history: Count = Field(default=20, ge=1, le=1000)
    #: Downhole data (bit speed, SSI, stuck share) reaches the agent only through this.
    telemetry: TelemetrySetting = "mud_pulse"
    #: Reward weights, per control step. SSI and stuck share are those of the env's
    #: metric window (3 s); both cost up to ~1 per step in full stick-slip.
    stick_slip_weight: NonNegative = Field(default=1.0, le=1.0e6)
    stuck_weight: NonNegative = Field(default=1.0, le=1.0e6)
    #: Per rpm of |mean bit speed over the window - target| beyond ``tracking_deadband``:
    #: what stops the shortcut "turn faster than the target". At 0.1 a SAC policy still
    #: ran 5-10 rpm above low targets (40-45 rpm: up to 25 % off); at 0.3 a 10 rpm offset
    #: costs 2.7 per step, more than full stick-slip (~2). The dead band is kept small
    #: because agents park inside it (design note).
    tracking_weight: NonNegative = Field(default=0.3, le=1.0e6)
    tracking_deadband: NonNegative = Field(default=1.0, le=100.0)
    #: Per mean bit displacement from its rest (the reset's) over the gauge clearance
    #: (whirl, lateral vibration: drill_env.metrics.excursion_ratio).
    whirl_weight: NonNegative = Field(default=0.5, le=1.0e6)
    #: Squared change of the action per step: a speed command that chatters wears the
    #: top drive and excites the string.
    effort_weight: NonNegative = Field(default=0.1, le=1.0e6)
    failure_weight: NonNegative = Field(default=10.0, le=1.0e6)
    ssi_cap: Positive = Field(default=2.0, le=1.0e3)

    def __post_init__(self) -> None:
        for name in ("rpm_targets", "weight_on_bit_targets", "target_change_time",
                     "rpm_change", "weight_on_bit_change"):
            low, high = getattr(self, name)
            if not low <= high:
                raise ValueError(f"{name}: the low end must not exceed the high end, got "
                                 f"{(low, high)}")
        for name in ("weight_on_bit_targets", "weight_on_bit_change"):
            check_newtons(name, getattr(self, name))
        if self.rpm_targets[0] <= 0.0:
            raise ValueError(f"rpm_targets: the lowest target must be above 0 rpm (the "
                             f"driller drills turning), got {self.rpm_targets}")
        if self.max_correction > self.rpm_targets[0]:  # (an outside check: -125 rpm at the
            # bit, target 40 rpm and a correction of 100; a top drive drills turning forward)
            raise ValueError(f"max_correction: {self.max_correction:g} rpm around targets "
                             f"from {self.rpm_targets[0]:g} rpm (rpm_targets) would command "
                             "the top drive backwards: at most the lowest target")



#: Entries of one history frame.
FRAME = ("surface_torque_ripple", "surface_speed_error", "action")
#: Entries after the history.
EXTRAS = ("surface_torque_mean", "target_rpm", "target_weight_on_bit", "telemetry_bit_speed",
          "telemetry_ssi", "telemetry_stuck_fraction", "telemetry_age")
#: Time constant of the surface torque's running mean (s; a first-order low-pass, not a
#: moving average): longer than a stick-slip period (2-3 s), so the ripple around it is
#: the oscillation a controller reacts to.
TORQUE_MEAN_SECONDS = 3.0


class StickSlipEnv(TaskEnv):
    r"""Stick-slip control: the agent corrects the top drive's speed command.

    ## Description

    The driller's targets (surface rpm and WOB) are drawn per episode from ``np_random``,
    mostly where a stiff top drive stick-slips, and may change once during the episode.
    The top drive runs its stiff PI speed loop; the agent adds a bounded correction to
    its speed command ten times a second, through the same top-drive model (set-point
    rate limit, torque limit) as the classical controllers of ``agents/``. It sees what
    a top-drive controller can see: the surface torque and speed, and downhole data only
    through mud-pulse telemetry. The episode starts with the bit stuck ("stalled"), on
    the randomised sandwich-crossing scenario; the fair baselines are the classical
    controllers at the same targets (docs/tasks.md).

    ## Action Space

    ``Box(-1, 1, (1,), float32)``: speed command = target + action x ``max_correction``
    (30 rpm). The target is ramped like any set point (top-drive ``max_acceleration``);
    the correction is added after that ramp, at once, like the torque feedback of the
    classical controllers (``Simulator.speed_correction``), then goes through the PI
    loop and torque limit. Out-of-range finite actions are clipped; NaN/inf raise
    ``ValueError``. The WOB follows the target (drawworks rate limit as in
    ``DrillString-v0``).

    ## Observation Space

    ``Box(-10, 10, (3 x history + 7,), float32)``, oldest frame first. Each frame: the
    surface torque's ripple (torque - its running mean, a first-order low-pass of 3 s
    time constant) / ``torque_scale``,
    (surface speed - target) / ``max_correction``, the action taken. Then: the running
    mean / ``torque_scale``, target rpm / 100, target WOB / 100 kN, and the telemetry:
    bit speed / target, min(SSI, cap) / cap and stuck share of the window, as last
    received, and the age of that message / 10 s.

    ## Rewards

    Per step: ``-stick_slip_weight min(SSI, cap) - stuck_weight stuck - tracking_weight
    max(0, |mean bit rpm - target rpm| - deadband) - whirl_weight excursion ratio -
    effort_weight (delta action)^2``; on termination ``-failure_weight``, less each step
    cut off at the episode's lowest step reward so far (as ``DrillString-v0``); SSI, stuck
    share and mean bit speed over the env's 3 s metric window. No ROP term: the targets
    are the driller's. ``info["reward_terms"]`` holds the terms.

    ## Starting State, Episode End, Info

    As ``DrillString-v0`` with ``startup="stalled"`` and 30 s episodes; ``info`` adds
    ``target_speed`` (rad/s), ``target_weight_on_bit`` (N), ``correction`` (rad/s) and
    ``mean_bit_speed`` (rad/s, over the window). Reset options ``surface_speed`` and
    ``weight_on_bit`` fix the targets instead of drawing them (no target change then); one
    alone fixes its target, and the other is drawn from the task's range. A fixed target
    may lie outside the task's ranges (a policy tried off its training range) but not
    outside the env's ``rpm_range`` / ``weight_on_bit_range``; a speed below
    ``max_correction`` is refused (the correction would turn the top drive backwards).

    ## Arguments

    ``gymnasium.make("DrillStickSlip-v0", **kwargs)``: every field of
    :class:`StickSlipTask` (``max_correction=20``, ``telemetry="wired_pipe"``, reward
    weights, ...) and the keywords of ``DrillString-v0`` (``scenario``, ``physics``,
    EnvConfig fields such as ``control_interval``, one by one or as a ``config`` dict)
    but those the task replaces (``unused_env_fields``: sensors, delay and noise of the
    plain observation, its reward weights, action mode and steps, start ranges), which
    are refused by name; what you give wins over the task's :data:`ENV_DEFAULTS`.

    ## Version History

    - v0: initial version.
    """

    task_class = StickSlipTask
    task: StickSlipTask
    #: (the action corrects the speed command: no action mode or steps of DrillString-v0)
    unused_env_fields = TaskEnv.unused_env_fields | {  # it draws its own targets, too
        "action_mode", "rpm_step", "weight_on_bit_step", "start_rpm_range",
        "start_weight_on_bit_range"}
    env_defaults = ENV_DEFAULTS
    frame = FRAME
    extras = EXTRAS
    telemetry_values = 3

    def __init__(self, scenario: str = ENV_DEFAULTS["scenario"],
                 task: StickSlipTask | dict | None = None, **kwargs: Any) -> None:
        super().__init__(scenario, task, **kwargs)
        # targets outside the env's set-point ranges were clipped to them without a word
        for name, (low, high), (r_low, r_high), unit, scale, field in (
                ("rpm_targets", self.task.rpm_targets, self.config.rpm_range, "rpm", 1.0,
                 "rpm_range"),
                ("weight_on_bit_targets", self.task.weight_on_bit_targets,
                 self.config.weight_on_bit_range, "kN", 1e3, "weight_on_bit_range")):
            if low < r_low or high > r_high:
                raise ValueError(f"{name}: {low / scale:g}-{high / scale:g} {unit} reaches "
                                 f"outside the env's {field} {r_low / scale:g}-"
                                 f"{r_high / scale:g} {unit}")
        self.action_space = spaces.Box(-1.0, 1.0, shape=(1,), dtype=np.float32)
        self._max_correction = self.task.max_correction * RPM
        self._change_step = -1  # no target change (each reset draws one)
        self._change = (0.0, 0.0)

    # ------------------------------------------------------------------ episode state

    def _init_task_state(self) -> None:
        super()._init_task_state()
        self._torque_mean = 0.0
        self._action = 0.0
        self._action_change = 0.0

    def _start_wob_draw(self) -> tuple[float | None, str]:
        # its own draw, not the scenario's (clamped to the env's range, as every draw)
        top = min(self.task.weight_on_bit_targets[1], self.config.weight_on_bit_range[1])
        return top, "weight_on_bit_targets in gym.make or env_kwargs"

    def _start_targets(self, speed: float, wob: float, given: frozenset[str]
                       ) -> tuple[float, float]:
        # (the episode state is initialised after this: the change lives here)
        self._change_step = -1
        self._change = (0.0, 0.0)
        t, rng = self.task, self.np_random
        if given:  # the target not given is drawn from the task's range, not the scenario's
            if "surface_speed" in given and speed < self._max_correction * (1 - 1e-12):
                # (an outside check: 10 rpm and a full negative correction drove -20.8 rpm)
                raise ValueError(
                    f"reset options: surface_speed: {speed / RPM:.4g} rpm is below the "
                    f"task's max_correction {t.max_correction:g} rpm: a full negative "
                    "correction would command the top drive backwards (the task's "
                    "targets start at max_correction or above)")
            if "surface_speed" not in given:
                speed = float(rng.uniform(*t.rpm_targets)) * RPM
            if "weight_on_bit" not in given:
                wob = float(rng.uniform(*t.weight_on_bit_targets))
            return speed, wob
        speed = float(rng.uniform(*t.rpm_targets)) * RPM
        wob = float(rng.uniform(*t.weight_on_bit_targets))
        if rng.random() < t.target_change_probability:
            at = float(rng.uniform(*t.target_change_time))
            self._change_step = max(1, round(at / self.config.control_interval))
            sign = 1.0 if rng.random() < 0.5 else -1.0
            self._change = (sign * float(rng.uniform(*t.rpm_change)) * RPM,
                            float(rng.choice((-1.0, 1.0))) * float(
                                rng.uniform(*t.weight_on_bit_change)))
        return speed, wob

    # ------------------------------------------------------------------ action

    def action_for(self, surface_speed: float, weight_on_bit: float) -> np.ndarray:
        """The correction that asks for ``surface_speed`` (the WOB is the target's)."""
        surface_speed, _ = check_set_points("action_for", surface_speed, weight_on_bit)
        a = (surface_speed - self.targets[0]) / self._max_correction
        return np.array([min(max(a, -1.0), 1.0)], dtype=np.float32)

    def apply_action(self, action) -> None:
        (value,) = action_values(action, 1)
        value = 1.0 if value > 1.0 else -1.0 if value < -1.0 else value
        if self._step_count == self._change_step:
            self._change_targets()
        speed, wob = self.targets
        self._command(speed, wob)  # the driller's set points, ramped as for any driller
        # the controller's correction goes in after the set-point ramp, as the torque
        # feedback of SoftTorque / ZTorque does (Simulator.speed_correction)
        self.sim.speed_correction = value * self._max_correction
        # (not ``_effort``: the plain env's set-point change, which _command just set)
        self._action_change = (value - self._action) ** 2
        self._action = value

    def _change_targets(self) -> None:
        t = self.task
        speed = min(max(self.targets[0] + self._change[0], t.rpm_targets[0] * RPM),
                    t.rpm_targets[1] * RPM)
        wob = min(max(self.targets[1] + self._change[1], t.weight_on_bit_targets[0]),
                  t.weight_on_bit_targets[1])
        self.targets = (speed, wob)

    # ------------------------------------------------------------------ reward

    def _reward_terms(self, step: tuple[list[float], bool] | None, terminated: bool
                      ) -> dict[str, float]:
        t = self.task
        window = self._window()
        ssi = self._window_ssi()
        stuck = window[Metric.STUCK_FRACTION] if window is not None else 1.0
        mean = window[Metric.MEAN_BIT_SPEED] if window is not None else 0.0
        error = abs(mean - self.targets[0]) / RPM
        excursion = step[0][Metric.EXCURSION_RATIO] if step is not None and step[1] else 1.0
        return {
            "stick_slip": -t.stick_slip_weight * min(ssi, t.ssi_cap),
            "stuck": -t.stuck_weight * stuck,
            "tracking": -t.tracking_weight * max(0.0, error - t.tracking_deadband),
            "whirl": -t.whirl_weight * excursion,
            "effort": -t.effort_weight * self._action_change,
            "failure": -t.failure_weight if terminated else 0.0,
        }

    # ------------------------------------------------------------------ observation

    def _info(self) -> dict[str, Any]:
        info = super()._info()
        window = self._window()
        info["target_speed"], info["target_weight_on_bit"] = self.targets
        info["correction"] = self.sim.speed_correction
        info["mean_bit_speed"] = window[Metric.MEAN_BIT_SPEED] if window is not None \
            else info["bit_speed"]
        return info

    def _observation(self, info: dict[str, Any]) -> np.ndarray:
        t = self.task
        r = self._readings
        target = self.targets[0]
        torque = r[READ.SURFACE_TORQUE]
        if not self._frames_seen:
            self._torque_mean = torque
        else:
            a = self.config.control_interval / TORQUE_MEAN_SECONDS
            self._torque_mean += a / (1.0 + a) * (torque - self._torque_mean)
        scale = self.config.torque_scale
        frame = [(torque - self._torque_mean) / scale,
                 (r[READ.SURFACE_SPEED] - target) / self._max_correction, self._action]
        self._push_frame(frame)
        window = self._window()
        floor = max(abs(target), 1e-6)
        downhole = [r[READ.BIT_SPEED] / floor,
                    min(self._window_ssi(), t.ssi_cap) / t.ssi_cap if window else 0.0,
                    window[Metric.STUCK_FRACTION] if window else 0.0]
        return self._finish([self._torque_mean / scale, target / (100.0 * RPM),
                             self.targets[1] / 100.0e3, *self._received(downhole)])
