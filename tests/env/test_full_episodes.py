"""Issue 4, acceptance 5: long runs of the default scenario stay finite and converge.

A random policy (uniform actions every control step) and a constant-RPM policy each
drive 10 full episodes (60 s of drilling, 600 control steps each). Every observation,
reward and physical ``info`` value must be finite, no episode may end in a divergence,
and every episode must reach its time limit.
"""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import drill_env  # noqa: F401  (registers the ids)
from agents import ConstantSetPoints

N_EPISODES = 10
SCALARS = ("bit_speed", "surface_speed", "torque_on_bit", "surface_torque", "weight_on_bit",
           "whirl_speed", "depth", "rop", "ssi", "stuck_fraction", "radial_ratio")


def run_episodes(policy_name: str) -> list[int]:
    env = gym.make("DrillString-v0")
    lengths = []
    constant = ConstantSetPoints(60.0, 80e3)
    for episode in range(N_EPISODES):
        obs, info = env.reset(seed=1000 + episode)
        constant.reset(env.unwrapped)
        env.action_space.seed(1000 + episode)
        steps, done = 0, False
        while not done:
            if policy_name == "random":
                action = env.action_space.sample()
            else:
                action = constant.act(obs, info)
            obs, reward, terminated, truncated, info = env.step(action)
            steps += 1
            assert np.all(np.isfinite(obs)), (episode, steps, obs)
            assert math.isfinite(reward), (episode, steps)
            for key in SCALARS:
                assert math.isfinite(info[key]), (episode, steps, key, info[key])
            assert not terminated, f"episode {episode} step {steps}: " \
                                   f"{info['termination_reason']}"
            done = truncated
        lengths.append(steps)
    env.close()
    return lengths


@pytest.mark.slow
@pytest.mark.parametrize("policy_name", ["random", "constant_rpm"])
def test_ten_full_default_episodes_stay_finite_and_reach_the_time_limit(policy_name):
    lengths = run_episodes(policy_name)
    expected = gym.make("DrillString-v0").unwrapped.max_episode_steps
    assert expected == 600
    assert lengths == [expected] * N_EPISODES
