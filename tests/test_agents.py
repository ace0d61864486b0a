"""Policies and classical top-drive tunings."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import drill_env  # noqa: F401
from agents import ConstantSetPoints


def test_constant_set_points_drive_the_env_to_its_rpm():
    env = gym.make("DrillString-v0", episode_duration=3.0)
    policy = ConstantSetPoints(rpm=120.0, weight_on_bit=60e3)
    obs, info = env.reset(seed=0)
    policy.reset(env.unwrapped)
    for _ in range(30):
        obs, _, terminated, truncated, info = env.step(policy.act(obs, info))
        assert not terminated
    assert info["surface_speed"] == pytest.approx(120 * 2 * np.pi / 60, rel=0.02)
    assert info["weight_on_bit_setpoint"] == pytest.approx(60e3, rel=1e-6)
    with pytest.raises(ValueError, match="500 rpm is outside the env's range"):
        ConstantSetPoints(rpm=500.0, weight_on_bit=0.0).reset(env.unwrapped)


def test_a_policy_reset_in_another_tasks_env_says_which_env_it_was_trained_on():
    """Task 1's policy in task 2's env failed at its first act with numpy's broadcast
    error; reset now names the env it was trained on."""
    import gymnasium as gym

    from agents.learned import LearnedController

    policy = LearnedController.load()  # task 1's
    env = gym.make("DrillOptimise-v0")
    with pytest.raises(ValueError, match=r"takes observation \(67,\), action \(1,\) \(its "
                                         r"config.yaml names DrillStickSlip-v0\); "
                                         r"DrillOptimise-v0 has observation \(25,\)"):
        policy.reset(env.unwrapped)
    # act without a reset: the shape said, not numpy's broadcast error
    with pytest.raises(ValueError, match=r"^observation: this policy takes shape \(67,\) "
                                         r"\(DrillStickSlip-v0\), got \(25,\)$"):
        policy.act(env.reset(seed=0)[0], {})
    own = gym.make("DrillStickSlip-v0")
    policy.reset(own.unwrapped)
    env.close()
    own.close()


def test_a_policy_reset_in_its_own_task_with_another_history_is_refused():
    """The shape check is per space: task 1's policy (observation 3 x 20 + 7 = 67, action
    1) in task 1's env with ``history=10`` (observation 3 x 10 + 7 = 37, the same action)
    is refused at reset naming both observation shapes, not left to fail inside SB3 or
    the normaliser at the first act."""
    from agents.learned import LearnedController

    policy = LearnedController.load()  # task 1's
    env = gym.make("DrillStickSlip-v0", history=10)
    with pytest.raises(ValueError, match=r"takes observation \(67,\), action \(1,\) .* "
                                         r"has observation \(37,\), action \(1,\)"):
        policy.reset(env.unwrapped)
    env.close()


def test_a_run_whose_config_names_another_algorithm_says_so(tmp_path):
    """A hand-edited config.yaml (algo: ppo on a SAC model) failed deep inside SB3 (a
    TypeError of SACPolicy's arguments; the other way round, an AttributeError at the
    first action); it is named at the load."""
    import shutil

    from agents.learned import TRAINED, LearnedController

    run = tmp_path / "run"
    shutil.copytree(TRAINED / "stick_slip", run)
    config = run / "config.yaml"
    config.write_text(config.read_text().replace("algo: sac", "algo: ppo"))
    with pytest.raises(ValueError, match=r"config.yaml: algo 'ppo', but model.zip does not "
                                         r"load as one .*: the model of another algorithm"):
        LearnedController.load(run)


@pytest.mark.parametrize("name", ["soft-torque", "driller", "constant:60/100", "held:0.5",
                                  "random", "learned"])
def test_a_controller_reset_with_the_env_gym_make_returns_acts(name):
    """``reset(env)`` takes the unwrapped env; the env as gym.make returns it (wrapped)
    failed at the first act for the set-point loops ('OrderEnforcing' object has no
    attribute 'action_for', an outside trial) while ``learned`` took it: unwrapped now,
    the same action as with the unwrapped env."""
    from agents.registry import make_controller

    actions = []
    for unwrap in (False, True):
        controller = make_controller(name)
        env = gym.make(controller.env_id)
        observation, info = env.reset(seed=0)
        controller.reset(env.unwrapped if unwrap else env)
        actions.append(controller.act(observation, info))
        env.close()
    np.testing.assert_array_equal(actions[0], actions[1])
