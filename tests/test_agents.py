"""Policies and classical top-drive tunings."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import drill_env  # noqa: F401
from agents import ConstantSetpoint, soft_speed_gains, stiff_gains
from drill_env.physics.config import SimulationConfig


def test_stiff_gains_follow_the_impedance_rule():
    cfg = SimulationConfig()
    td = stiff_gains(cfg)
    z = cfg.string.drill_pipe.torsional_impedance
    assert td.proportional_gain == pytest.approx(50 * z)
    assert td.integral_gain == pytest.approx(5 * cfg.top_drive.inertia)


def test_soft_speed_cancels_top_drive_inertia_at_the_tuning_frequency():
    cfg = SimulationConfig()
    td = soft_speed_gains(cfg, stick_slip_frequency=0.66)
    w = 2 * math.pi * 0.66
    # the I-term's impedance ki / (j w) cancels the inertia's j w J at w
    assert td.integral_gain / w == pytest.approx(w * cfg.top_drive.inertia)
    with pytest.raises(ValueError, match="stick_slip_frequency"):
        soft_speed_gains(cfg, stick_slip_frequency=0.0)


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
