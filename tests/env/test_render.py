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


def _records(rows: list[dict[str, float]]) -> np.ndarray:
    """Simulator records of ``rows`` (record channels by name, the others 0)."""
    from drill_env.physics.simulator import RECORD_CHANNELS

    records = np.zeros((len(rows), len(RECORD_CHANNELS)))
    for k, row in enumerate(rows):
        for name, value in row.items():
            records[k, RECORD_CHANNELS.index(name)] = value
    return records


def _history(rows: list[dict[str, float]], capacity: int = 8):
    """A frame history holding ``rows``."""
    from drill_env.physics.simulator import RECORD_CHANNELS
    from drill_env.render import FrameHistory

    history = FrameHistory(RECORD_CHANNELS, capacity)
    history.add(_records(rows))
    return history


def test_the_history_is_the_last_rows_in_time_order_before_and_after_it_fills():
    """The frame plots the last ``capacity`` rows, oldest first: also in an episode's
    first seconds, before the ring buffer is full (its empty slots are no rows), whatever
    chunks the rows came in; a row with a non-finite value is left out."""
    history = _history([{"time": t} for t in (0.0, 1.0, 2.0)], capacity=4)
    np.testing.assert_array_equal(history.column("time"), [0.0, 1.0, 2.0])
    history.add(_records([{"time": t} for t in (3.0, 4.0, 5.0)]))
    np.testing.assert_array_equal(history.column("time"), [2.0, 3.0, 4.0, 5.0])
    history.add(_records([{"time": t} for t in np.arange(6.0, 16.0)]))
    np.testing.assert_array_equal(history.column("time"), [12.0, 13.0, 14.0, 15.0])
    history.add(_records([{"time": 16.0, "bit_x": np.nan}]))
    np.testing.assert_array_equal(history.column("time"), [12.0, 13.0, 14.0, 15.0])


def _wall_and_orbit(frame: np.ndarray) -> tuple[float, float, float, np.ndarray]:
    """The wall circle's centre (column, row) and radius in pixels, from its pixels in the
    orbit panel (the right third) off the text lines, and the (row, column) of every
    orbit pixel."""
    wall = np.all(frame == np.array(WALL, np.uint8), axis=-1)
    wall[:40], wall[-20:], wall[:, :int(0.6 * frame.shape[1])] = False, False, False
    rows, cols = np.nonzero(wall)
    cx, radius = 0.5 * (cols.min() + cols.max()), 0.5 * (cols.max() - cols.min())
    cy = float(np.mean(rows[cols == cols.min()]))
    return cx, cy, radius, np.argwhere(np.all(frame == np.array(ORBIT, np.uint8), axis=-1))


def test_the_orbit_is_drawn_north_up_and_east_right():
    """The bit centre at +y (north of the hole axis) is drawn above the centre of the
    clearance circle, at +x to its right, as the orbit of the rerun recording is."""
    from drill_env.render import draw_frame

    clearance = 0.02
    steady = [{"time": 0.1 * k, "bit_y": 0.5 * clearance} for k in range(5)]
    cx, cy, radius, orbit = _wall_and_orbit(draw_frame(_history(steady), clearance, 20.0))
    assert np.all(orbit[:, 0] < cy - 0.3 * radius)  # up: smaller row numbers
    assert np.all(np.abs(orbit[:, 1] - cx) <= 4)
    east = [{"time": 0.1 * k, "bit_x": 0.5 * clearance} for k in range(5)]
    cx, cy, radius, orbit = _wall_and_orbit(draw_frame(_history(east), clearance, 20.0))
    assert np.all(orbit[:, 1] > cx + 0.3 * radius) and np.all(np.abs(orbit[:, 0] - cy) <= 4)


def test_the_speed_axis_tops_at_the_next_1_2_or_5_step():
    """``_nice_ceiling``: the smallest 1, 2 or 5 x 10^k at or above the value: the half of
    the default 0-200 rpm range, 100 rpm exactly, is its own top, not 200."""
    from drill_env.render import _nice_ceiling

    for value, top in ((100.0, 100.0), (2.0, 2.0), (0.5, 0.5), (101.0, 200.0),
                       (3.0, 5.0), (6.0, 10.0), (0.012, 0.02), (0.0, 1.0), (np.nan, 1.0)):
        assert _nice_ceiling(value) == pytest.approx(top, rel=1e-12), value


def _row_of(frame: np.ndarray, rgb: tuple[int, int, int]) -> float:
    """The mean pixel row of a horizontal trace drawn in ``rgb``."""
    rows, _ = np.nonzero(np.all(frame == np.array(rgb, np.uint8), axis=-1))
    return float(rows.mean())


def test_bit_and_surface_speed_are_drawn_on_one_rpm_scale():
    """Both speeds are plotted in rpm on the same axis: with the surface at 100 rpm (the
    axis top for a 200 rpm range) a bit at 50 rpm lies halfway between a bit at rest and
    the surface line."""
    from drill_env.physics.units import RPM
    from drill_env.render import SURFACE, draw_frame

    rows = {}
    for bit_rpm in (0.0, 50.0):
        steady = [{"time": 0.1 * k, "bit_speed": bit_rpm * RPM, "surface_speed": 100.0 * RPM}
                  for k in range(5)]
        frame = draw_frame(_history(steady), 0.02, 200.0 * RPM)
        rows[bit_rpm] = _row_of(frame, BIT)
        top = _row_of(frame, SURFACE)
    assert rows[0.0] - top > 50  # the speed panel's height
    assert rows[50.0] == pytest.approx(0.5 * (rows[0.0] + top), abs=2.0)
