"""A rule-based driller: changes the set points when the surface torque says stick-slip.

What a driller does without an anti-stick-slip top drive (field practice, e.g. the
vibration guidelines of Dupriest & Koederitz 2005 and the IADC Drilling Manual): on
stick-slip first raise the rotary speed, then take weight off the bit; once the string
has run calm for a while, step back toward the planned set points. The top drive keeps
its stiff PI loop. The driller sees what a driller sees: the surface torque, nothing
downhole. Policy rate: it decides every ``decision_period`` seconds.
"""

from __future__ import annotations

from collections import deque
from typing import Any, ClassVar

import numpy as np
from pydantic import Field

from agents.base import Rate, SetPointController
from drill_env.physics.units import RPM
from drill_env.physics.validation import Positive, config_dataclass


@config_dataclass
class DrillerRules:
    """The driller's thresholds and steps (modelling choices, each with its reason)."""

    #: Seconds of surface torque each decision looks at: about two stick-slip periods
    #: (2.26 s on the default string, 1.5 s on the paper's) so one oscillation is
    #: always in view.
    decision_period: Positive = Field(default=5.0, le=600.0)
    #: Stick-slip when the surface torque swings by more than this fraction of its mean,
    #: (max - min) / (2 mean): steady drilling stays below 0.05, stick-slip on the
    #: default string swings by 0.3-0.6.
    torque_swing: Positive = Field(default=0.15, le=10.0)
    #: Set-point steps per decision (rpm, N): a driller's usual increments.
    rpm_step: Positive = Field(default=10.0, le=200.0)
    weight_on_bit_step: Positive = Field(default=10.0e3, le=1.0e6)
    #: Most the driller raises the rpm above the plan, and the least WOB it keeps (a
    #: fraction of the planned WOB): the limits of a drilling programme.
    max_rpm_raise: Positive = Field(default=60.0, le=500.0)
    min_weight_fraction: Positive = Field(default=0.5, le=1.0)
    #: Calm decisions in a row before stepping back toward the plan.
    calm_decisions: int = Field(default=6, ge=1, le=1000)


class Driller(SetPointController):
    """Raises rpm, then lowers WOB, on surface-torque stick-slip; steps back when calm."""

    name: ClassVar[str] = "driller"
    rate: ClassVar[Rate] = "policy"

    def __init__(self, rules: DrillerRules | None = None) -> None:
        super().__init__()
        self.rules = rules or DrillerRules()
        self._env: Any = None
        self._torque: deque[float] = deque()
        self._steps_per_decision = 1
        self._step = 0
        self._calm = 0
        self._plan = (0.0, 0.0)
        self._speed = 0.0
        self._wob = 0.0

    def physics(self) -> dict[str, Any]:
        return {"top_drive.controller": "stiff"}

    def reset(self, env: Any) -> None:
        super().reset(env)
        env = self._env  # (unwrapped)
        self._plan = env.targets
        self._speed, self._wob = env.targets
        self._steps_per_decision = max(1, round(self.rules.decision_period
                                                / env.config.control_interval))
        self._torque = deque(maxlen=self._steps_per_decision)
        self._step = 0
        self._calm = 0

    @property
    def set_points(self) -> tuple[float, float]:
        """The driller's current speed (rad/s) and WOB (N) set points."""
        return self._speed, self._wob

    def act(self, observation: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        if self._env.targets != self._plan:  # the plan changed: start from the new one
            self._plan = self._env.targets
            self._speed, self._wob = self._plan
            self._calm = 0
        self._torque.append(float(info["surface_torque"]))
        self._step += 1
        if self._step % self._steps_per_decision == 0:
            self._decide()
        return self._env.action_for(self._speed, self._wob)

    def _decide(self) -> None:
        r = self.rules
        torque = np.asarray(self._torque)
        mean = float(np.mean(torque))
        swing = (torque.max() - torque.min()) / (2.0 * abs(mean)) if mean != 0.0 else 0.0
        plan_speed, plan_wob = self._plan
        if swing > r.torque_swing:
            self._calm = 0
            # no higher than the env drills: past its range the raise would be clipped,
            # and decisions spent "raising" it would not take weight off
            top = min(plan_speed + r.max_rpm_raise * RPM, self._env.config.rpm_range[1] * RPM)
            if self._speed < top - 1e-9:
                self._speed = min(self._speed + r.rpm_step * RPM, top)
            elif self._wob > r.min_weight_fraction * plan_wob + 1e-9:
                self._wob = max(self._wob - r.weight_on_bit_step,
                                r.min_weight_fraction * plan_wob)
            return
        self._calm += 1
        if self._calm < r.calm_decisions:
            return
        self._calm = 0  # one step back, then watch again
        if self._wob < plan_wob:
            self._wob = min(self._wob + r.weight_on_bit_step, plan_wob)
        elif self._speed > plan_speed:
            self._speed = max(self._speed - r.rpm_step * RPM, plan_speed)
