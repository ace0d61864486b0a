"""The policy interface shared by classical and learned controllers.

A policy maps an observation (and the env's ``info``) to an action of
``DrillString-v0``: two numbers in [-1, 1] that the env maps to the RPM set point and
the weight on bit (absolute action mode).
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np


class Policy(Protocol):
    def reset(self) -> None: ...

    def act(self, observation: np.ndarray, info: dict[str, Any]) -> np.ndarray: ...


def _to_unit(value: float, low: float, high: float, name: str) -> float:
    if not low <= value <= high:
        raise ValueError(f"{name}: {value} outside the env's range [{low}, {high}]")
    return 2.0 * (value - low) / (high - low) - 1.0


class ConstantSetpoint:
    """Constant RPM set point and WOB: what a driller with a classical top drive does."""

    def __init__(self, rpm: float, weight_on_bit: float,
                 rpm_range: tuple[float, float] = (0.0, 200.0),
                 weight_on_bit_range: tuple[float, float] = (0.0, 200e3)) -> None:
        self.action = np.array([_to_unit(rpm, *rpm_range, "rpm"),
                                _to_unit(weight_on_bit, *weight_on_bit_range,
                                         "weight_on_bit")], dtype=np.float32)

    def reset(self) -> None:
        pass

    def act(self, observation: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        return self.action.copy()


class SB3Policy:
    """A trained Stable-Baselines3 model behind the same interface."""

    def __init__(self, model: Any, deterministic: bool = True) -> None:
        self.model = model
        self.deterministic = deterministic

    def reset(self) -> None:
        pass

    def act(self, observation: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        action, _ = self.model.predict(observation, deterministic=self.deterministic)
        return np.asarray(action, dtype=np.float32)
