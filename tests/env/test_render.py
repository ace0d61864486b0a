"""render_mode="rgb_array": frames for Gymnasium's wrappers and SB3's make_vec_env."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import drill_env  # noqa: F401
from drill_env.render import BACKGROUND, BIT, ORBIT, WALL

SHORT = {"episode_duration": 1.0}


def frame_after(steps: int, **kwargs) -> np.ndarray:
    env = gym.make("DrillString-v0", render_mode="rgb_array", **kwargs)
    env.reset(seed=0)
    for _ in range(steps):
        env.step(np.array([-0.5, 0.0], dtype=np.float32))
    return env.render()


def has_colour(frame: np.ndarray, rgb: tuple[int, int, int]) -> bool:
    return bool(np.any(np.all(frame == np.array(rgb, dtype=np.uint8), axis=-1)))


def test_a_frame_shows_the_traces_and_the_orbit():
    frame = frame_after(20, scenario="paper_case4")
    assert frame.dtype == np.uint8 and frame.ndim == 3 and frame.shape[2] == 3
    for colour in (BIT, ORBIT, WALL):
        assert has_colour(frame, colour), colour
    assert np.mean(np.all(frame == np.array(BACKGROUND, np.uint8), axis=-1)) > 0.5


def test_the_first_frame_after_reset_draws_the_empty_panels():
    env = gym.make("DrillString-v0", render_mode="rgb_array", **SHORT)
    env.reset(seed=0)
    frame = env.render()
    assert has_colour(frame, WALL) and not has_colour(frame, BIT)


def test_gymnasium_checker_passes_with_the_render_check():
    check_env(gym.make("DrillString-v0", render_mode="rgb_array", **SHORT).unwrapped)


def test_render_collection_collects_one_frame_per_step():
    env = gym.wrappers.RenderCollection(
        gym.make("DrillString-v0", render_mode="rgb_array", **SHORT))
    env.reset(seed=0)
    for _ in range(3):
        env.step(env.action_space.sample())
    frames = env.render()
    assert len(frames) == 4 and all(f.shape == frames[0].shape for f in frames)


def test_sb3_make_vec_env_builds_steps_and_renders():
    from stable_baselines3.common.env_util import make_vec_env

    venv = make_vec_env("DrillString-v0", n_envs=4, env_kwargs=SHORT, seed=0)
    obs = venv.reset()
    obs, rewards, dones, infos = venv.step(np.zeros((4, 2), dtype=np.float32))
    assert obs.shape == (4, len(drill_env.env.OBSERVATIONS["downhole"]))
    assert np.all(np.isfinite(rewards))
    images = venv.get_images()
    assert len(images) == 4 and images[0].ndim == 3
    venv.close()


def test_unsupported_render_modes_are_refused_by_name():
    with pytest.raises(ValueError, match="render_mode"):
        drill_env.env.DrillStringEnv(render_mode="ansi")


def test_render_without_a_mode_warns_and_returns_none():
    env = drill_env.env.DrillStringEnv(**SHORT)
    env.reset(seed=0)
    with pytest.warns(UserWarning, match="render_mode"):
        assert env.render() is None


def test_the_batched_vector_env_renders_each_envs_frame():
    """``gym.make_vec(..., render_mode="rgb_array")`` on the package's vector env: one frame
    per env, each the frame the same env would draw stepped alone (its traces too)."""
    envs = gym.make_vec("DrillString-v0", num_envs=2, render_mode="rgb_array",
                        scenario="paper_case4")
    alone = gym.make("DrillString-v0", render_mode="rgb_array", scenario="paper_case4")
    envs.reset(seed=0)
    alone.reset(seed=1)  # env 1 of a vector env seeded 0
    action = np.array([-0.5, 0.0], dtype=np.float32)
    for _ in range(20):
        envs.step(np.stack([action, action]))
        alone.step(action)
    frames = envs.render()
    assert envs.render_mode == "rgb_array" and len(frames) == 2
    np.testing.assert_array_equal(frames[1], alone.render())
    assert has_colour(frames[0], BIT)
    with pytest.raises(ValueError, match="max_episode_steps: .* episode_duration"):
        gym.make_vec("DrillString-v0", num_envs=2, max_episode_steps=5)
