"""Policies and classical top-drive tunings."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import drill_env  # noqa: F401
from agents import ConstantSetpoint


def test_constant_setpoint_drives_the_env_to_its_rpm():
    env = gym.make("DrillString-v0", episode_duration=3.0)
    policy = ConstantSetpoint(rpm=120.0, weight_on_bit=60e3)
    obs, info = env.reset(seed=0)
    for _ in range(30):
        obs, _, terminated, truncated, info = env.step(policy.act(obs, info))
        assert not terminated
    assert info["surface_speed"] == pytest.approx(120 * 2 * np.pi / 60, rel=0.02)
    with pytest.raises(ValueError, match="rpm"):
        ConstantSetpoint(rpm=500.0, weight_on_bit=0.0)
