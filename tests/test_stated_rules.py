"""Rules the env, its vector envs, the recorder, the render and the speed benchmark state
in their docstrings and docs, each found unchecked by an outside mutation round
(2026-12-03): action clipping both ways, the effort term's spans, the mesh limit on the
applied hook load, the SSI cap, the observation bound at -10, Gymnasium's reset_mask
semantics, termination logging, one start event, no file for an empty episode, the
render's time order, axis and wall, and the speed figures' arithmetic."""

from __future__ import annotations

import math
import time

import gymnasium
import numpy as np
import pytest

import drill_env  # noqa: F401
from drill_env.env import DrillStringEnv
from drill_env.physics.layout import RECORD_CHANNELS
from drill_env.physics.units import RPM
from drill_env.recording import EpisodeRecorder, RecordEpisode, read_recording
from drill_env.render import BIT, ORBIT, SURFACE, WALL, FrameHistory, _nice_ceiling, draw_frame
from drill_env.tools.speed import common as speed_common
from drill_env.vector import DrillStringVectorEnv

SHORT = {"episode_duration": 0.5}


def test_incremental_action_below_minus_one_is_clipped_to_one_step_down():
    """Class docstring: finite actions outside [-1, 1] are CLIPPED; incremental mode moves
    the set point by action * rpm_step: -5 acts as -1, i.e. 100 rpm -> 90 rpm."""
    env = DrillStringEnv(action_mode="incremental", rpm_step=10.0, **SHORT)
    env.reset(seed=0, options={"surface_speed": 100 * RPM, "weight_on_bit": 100e3})
    _, _, _, _, info = env.step(np.array([-5.0, 0.0]))
    assert info["speed_setpoint"] == pytest.approx(90 * RPM)


def test_applied_hook_load_never_asks_for_more_than_the_mesh_limit():
    """Docstring: the hook load is sim.hook_load_for(WOB) with the WOB 'never above
    weight_on_bit_limit'; on lateral_60 the limit is below the 200 kN range top (a reset
    option above it warns)."""
    env = DrillStringEnv(scenario="lateral_60", episode_duration=5.0)
    with pytest.warns(RuntimeWarning, match="weight_on_bit_limit"):
        _, info = env.reset(seed=0, options={"weight_on_bit": 200e3})
    limit = info["weight_on_bit_limit"]
    assert limit < 199e3
    for _ in range(5):
        env.step(np.array([0.0, 1.0]))
        hook = env.advance_request()[2]
        assert hook >= env.sim.hook_load_for(limit) - 1e-6


def test_stick_slip_term_is_capped_at_ssi_cap():
    """Docstring: stick_slip = -stick_slip_weight * min(SSI, ssi_cap)."""
    env = DrillStringEnv(scenario="stick_slip", ssi_cap=0.05, episode_duration=3.0)
    env.reset(seed=0)
    seen = []
    for _ in range(20):
        _, _, term, trunc, info = env.step(np.array([-0.7, 0.0]))
        seen.append(info["ssi"])
        w = env.config.stick_slip_weight
        assert info["reward_terms"]["stick_slip"] == pytest.approx(
            -w * min(info["ssi"], 0.05), abs=1e-12)
        if term or trunc:
            break
    assert max(seen) > 0.05  # the cap was reached: the check above meant something


def test_observation_is_clipped_at_minus_ten_too():
    """Docstring: Box(-10, 10), each entry clipped to +-10. Large seeded observation
    noise (surface sensors) pushes entries beyond -10 on steps where none passes +10."""
    env = DrillStringEnv(sensors="surface", observation_noise=12.0, episode_duration=3.0)
    obs, _ = env.reset(seed=0)
    lows = []
    for _ in range(30):
        obs, *_ = env.step(np.array([0.0, 0.0]))
        assert env.observation_space.contains(obs)
        assert obs.min() >= -10.0 and obs.max() <= 10.0
        lows.append(obs.min())
    assert min(lows) == -10.0


# ----------------------------------------------------------------- render.py


def _rows(n, **cols):
    rows = np.zeros((n, len(RECORD_CHANNELS)))
    for name, values in cols.items():
        rows[:, RECORD_CHANNELS.index(name)] = values
    return rows


def test_frame_history_keeps_the_last_rows_in_time_order_after_wrapping():
    """FrameHistory: a ring buffer of the last ``capacity`` rows; column() in time order."""
    h = FrameHistory(RECORD_CHANNELS, 3)
    h.add(_rows(5, time=np.arange(5.0)))
    np.testing.assert_array_equal(h.column("time"), [2.0, 3.0, 4.0])
    h.add(_rows(1, time=[5.0]))
    np.testing.assert_array_equal(h.column("time"), [3.0, 4.0, 5.0])


def test_the_history_is_the_last_rows_in_time_order_before_and_after_it_fills():
    """The frame plots the last ``capacity`` rows, oldest first: also in an episode's
    first seconds, before the ring buffer is full (its empty slots are no rows), whatever
    chunks the rows came in; a row with a non-finite value is left out."""
    h = FrameHistory(RECORD_CHANNELS, 4)
    h.add(_rows(3, time=[0.0, 1.0, 2.0]))
    np.testing.assert_array_equal(h.column("time"), [0.0, 1.0, 2.0])
    h.add(_rows(3, time=[3.0, 4.0, 5.0]))
    np.testing.assert_array_equal(h.column("time"), [2.0, 3.0, 4.0, 5.0])
    h.add(_rows(10, time=np.arange(6.0, 16.0)))
    np.testing.assert_array_equal(h.column("time"), [12.0, 13.0, 14.0, 15.0])
    h.add(_rows(1, time=[16.0], bit_x=[np.nan]))
    np.testing.assert_array_equal(h.column("time"), [12.0, 13.0, 14.0, 15.0])


def test_nice_ceiling_is_the_smallest_1_2_5_decade_at_or_above():
    """Docstring: the smallest 1, 2 or 5 x 10^k at or above value."""
    assert _nice_ceiling(1.5) == 2.0
    assert _nice_ceiling(120.0) == 200.0
    assert _nice_ceiling(3.0) == 5.0
    assert _nice_ceiling(0.7) == 1.0
    # at the 1-2-5 steps themselves the value is its own top: the half of the default
    # 0-200 rpm range, 100 rpm exactly, is drawn to 100, not 200
    for value, top in ((100.0, 100.0), (2.0, 2.0), (0.5, 0.5), (101.0, 200.0),
                       (6.0, 10.0), (0.012, 0.02), (0.0, 1.0), (np.nan, 1.0)):
        assert _nice_ceiling(value) == pytest.approx(top, rel=1e-12), value


def test_round_off_below_zero_does_not_widen_the_speed_axis():
    """render.py: a backward turn widens the axis, round-off below zero does not: a bit
    speed of -0.3 rpm draws the same frame as 0 rpm (the trace is clipped to the axis)."""
    n = 50
    t = np.linspace(0.0, 5.0, n)
    bit = np.full(n, 60.0 * RPM)
    bit[10:20] = -0.3 * RPM
    clipped = bit.copy()
    clipped[10:20] = 0.0
    frames = []
    for b in (bit, clipped):
        h = FrameHistory(RECORD_CHANNELS, 100)
        h.add(_rows(n, time=t, bit_speed=b, surface_speed=60.0 * RPM, torque_on_bit=1e3))
        frames.append(draw_frame(h, 0.01, 200 * RPM))
    np.testing.assert_array_equal(frames[0], frames[1])


def test_an_orbit_beyond_the_wall_is_drawn_on_the_wall():
    """draw_frame: the bit centre beyond the clearance circle is drawn on it: no orbit
    pixel lies outside the circle (plus the 3 px end marker)."""
    width, height = 640, 360
    n = 40
    ang = np.linspace(0.0, 2 * np.pi, n)
    h = FrameHistory(RECORD_CHANNELS, 100)
    h.add(_rows(n, time=np.linspace(0, 4, n), bit_speed=1.0, surface_speed=1.0,
                torque_on_bit=1.0, bit_x=0.02 * np.cos(ang), bit_y=0.02 * np.sin(ang)))
    frame = draw_frame(h, 0.01, 200 * RPM, width=width, height=height)  # 2x the clearance
    split = int(width * 0.62)
    cx, cy = split + (width - split) // 2, height // 2
    r_px = min(width - split - 20, height - 60) / 2
    ys, xs = np.nonzero(np.all(frame == np.array(ORBIT, np.uint8), axis=-1))
    assert xs.size > 0
    assert np.max(np.hypot(xs - cx, ys - cy)) <= r_px + 5


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
    clearance = 0.02
    for axis in ("bit_y", "bit_x"):
        h = FrameHistory(RECORD_CHANNELS, 8)
        h.add(_rows(5, time=0.1 * np.arange(5), **{axis: 0.5 * clearance}))
        cx, cy, radius, orbit = _wall_and_orbit(draw_frame(h, clearance, 20.0))
        if axis == "bit_y":  # up: smaller row numbers
            assert np.all(orbit[:, 0] < cy - 0.3 * radius)
            assert np.all(np.abs(orbit[:, 1] - cx) <= 4)
        else:
            assert np.all(orbit[:, 1] > cx + 0.3 * radius)
            assert np.all(np.abs(orbit[:, 0] - cy) <= 4)


def _row_of(frame: np.ndarray, rgb: tuple[int, int, int]) -> float:
    """The mean pixel row of a horizontal trace drawn in ``rgb``."""
    rows, _ = np.nonzero(np.all(frame == np.array(rgb, np.uint8), axis=-1))
    return float(rows.mean())


def test_bit_and_surface_speed_are_drawn_on_one_rpm_scale():
    """Both speeds are plotted in rpm on the same axis: with the surface at 100 rpm (the
    axis top for a 200 rpm range) a bit at 50 rpm lies halfway between a bit at rest and
    the surface line."""
    rows = {}
    for bit_rpm in (0.0, 50.0):
        h = FrameHistory(RECORD_CHANNELS, 8)
        h.add(_rows(5, time=0.1 * np.arange(5), bit_speed=bit_rpm * RPM,
                    surface_speed=100.0 * RPM))
        frame = draw_frame(h, 0.02, 200.0 * RPM)
        rows[bit_rpm] = _row_of(frame, BIT)
        top = _row_of(frame, SURFACE)
    assert rows[0.0] - top > 50  # the speed panel's height
    assert rows[50.0] == pytest.approx(0.5 * (rows[0.0] + top), abs=2.0)


# ----------------------------------------------------------------- tools/speed/common.py


def test_ratio_over_zero_is_nan_not_an_error():
    assert math.isnan(speed_common.ratio(1.0, 0.0))
    assert math.isnan(speed_common.ratio(1.0, -2.0))
    assert speed_common.ratio(3.0, 2.0) == 1.5


def test_best_time_is_the_shortest_call():
    """Docstring: shortest wall time of ``repeats`` calls."""
    delays = iter([0.2, 0.0, 0.0])
    best = speed_common.best_time(lambda: time.sleep(next(delays)), 3)
    assert best < 0.1


class _FakeSim:
    dt = 0.002
    n_nodes = 10
    status = 0
    status_message = ""

    def hook_load_for(self, wob):
        return 1e6 - wob

    def advance(self, n, *args, **kwargs):
        time.sleep(0.01)


def test_real_time_factor_is_simulated_over_wall_time():
    figures = speed_common.time_simulators({"a": _FakeSim()}, 1e5, 1.0, 1, "x", False)["a"]
    assert figures["simulated_s"] == pytest.approx(1.0)
    assert figures["real_time_factor"] == pytest.approx(
        figures["simulated_s"] / figures["wall_s"])
    assert figures["real_time_factor"] > 1.0  # 1 s simulated in ~10 ms


class _Ticks:
    """A ``time`` whose clock moves only when a fake run moves it: the figures'
    arithmetic checked without timing anything."""

    def __init__(self) -> None:
        self.now = 0.0

    def perf_counter(self) -> float:
        return self.now


def test_simulators_take_turns_and_each_keeps_its_fastest_repeat(monkeypatch):
    """Docstring: best of ``repeats``, the simulators taking turns repeat by repeat (a
    burst of load hits them alike), each advanced at the hook load of the WOB asked
    for; a run's figures from the whole steps it ran (5 DOFs a node)."""
    clock = _Ticks()
    monkeypatch.setattr(speed_common, "time", clock)
    calls: list[tuple] = []

    class Sim(_FakeSim):
        def __init__(self, name: str, dt: float, walls: list[float]) -> None:
            self.name, self.dt, self.walls = name, dt, iter(walls)

        def advance(self, n, surface_speed, hook, **kwargs):
            calls.append((self.name, n, surface_speed, hook))
            clock.now += next(self.walls)

    sims = {"a": Sim("a", 0.1, [3.0, 1.0, 2.0]), "b": Sim("b", 0.002, [0.5, 0.25, 0.75])}
    figures = speed_common.time_simulators(sims, 60e3, 0.34, 3, "x", False)
    hook = 1e6 - 60e3
    assert calls == [("a", 3, speed_common.SURFACE_SPEED, hook),
                     ("b", 170, speed_common.SURFACE_SPEED, hook)] * 3
    a, b = figures["a"], figures["b"]
    # 0.34 s at 0.1 s steps: 3 steps, 0.3 s simulated, the fastest repeat 1 s
    assert (a["wall_s"], a["simulated_s"]) == (1.0, pytest.approx(0.3))
    assert a["real_time_factor"] == pytest.approx(0.3)
    assert (a["n_nodes"], a["n_dof"]) == (10, 50)
    assert a["us_per_step"] == pytest.approx(1e6 / 3)
    assert a["ns_per_dof_step"] == pytest.approx(1e9 / 3 / 50)
    assert b["wall_s"] == 0.25 and b["real_time_factor"] == pytest.approx(0.34 / 0.25)
    # shorter than a step: one step, not none; 0.3 s at 0.1 s steps: 3 steps, although
    # 0.3 / 0.1 = 2.9999999999999996
    calls.clear()
    for seconds in (0.01, 0.3):
        speed_common.time_simulators({"a": Sim("a", 0.1, [2.0])}, 60e3, seconds, 1, "x",
                                     False)
    assert [n for _, n, _, _ in calls] == [1, 3]


def test_a_failed_benchmark_run_is_an_error_naming_its_status():
    class Failed(_FakeSim):
        status = 2
        status_message = "the bit left the hole"

        def advance(self, n, *args, **kwargs):
            pass

    with pytest.raises(RuntimeError, match="benchmark run failed: the bit left the hole"):
        speed_common.time_simulators({"a": Failed()}, 1e5, 0.1, 1, "x", False)


def test_a_settled_simulator_starts_and_warms_up_at_the_wob_asked_for(monkeypatch):
    """The scaling runs' 60 kN (not the core figures' 100 kN), the warm-up steps asked
    for, at least one."""
    seen: list[tuple] = []

    class Sim(_FakeSim):
        def __init__(self, config) -> None:
            self.config = config

        def reset(self, point) -> None:
            seen.append(("reset", point.surface_speed, point.weight_on_bit))

        def advance(self, n, surface_speed, hook, **kwargs):
            seen.append(("advance", n, surface_speed, hook))

    monkeypatch.setattr(speed_common, "Simulator", Sim)
    for warmup in (7, 0):
        sim = speed_common.settled_simulator("config", 60e3, warmup)
        assert sim.config == "config"
    speed = speed_common.SURFACE_SPEED
    assert seen == [("reset", speed, 60e3), ("advance", 7, speed, 1e6 - 60e3),
                    ("reset", speed, 60e3), ("advance", 1, speed, 1e6 - 60e3)]


def test_a_table_aligns_names_left_and_figures_right_under_a_full_rule():
    """The first column left-aligned, the others right-aligned (no trailing blanks);
    the note's lines are paragraphs, each wrapped at 88 columns (or the table's width)
    with a hanging indent."""
    note = "short note\n" + "word " * 30
    rows = [("a", 1.5), ("longer", 10), ("blank", "")]
    text = speed_common.table("Title", ("name", "value"), rows, note)
    wrapped = ("word " * 17).rstrip()
    assert text.splitlines() == [
        "Title",
        "name    value",
        "-------------",
        "a         1.5",
        "longer     10",
        "blank",
        "short note",
        wrapped,
        "  " + ("word " * 13).rstrip(),
    ]
    assert max(map(len, text.splitlines())) <= 88 and len(wrapped) > 80


def test_the_core_and_scaling_runs_take_one_numba_thread_and_give_it_back():
    import numba

    threads = min(2, numba.config.NUMBA_NUM_THREADS)
    before = numba.get_num_threads()
    numba.set_num_threads(threads)
    try:
        with speed_common.one_numba_thread():
            assert numba.get_num_threads() == 1
        assert numba.get_num_threads() == threads
    finally:
        numba.set_num_threads(before)


def test_the_source_stamp_is_the_newest_python_file_anywhere_in_the_package(tmp_path,
                                                                           monkeypatch):
    """Docstring: latest modification time of the package's sources (drill_env/ and
    every folder in it; a file beside the package is not one of them)."""
    import os

    package = tmp_path / "drill_env"
    for name, mtime in (("a.py", 100), ("physics/b.py", 300), ("tools/c.py", 50),
                        ("tools/speed/common.py", 200), ("physics/d.txt", 800),
                        ("../outside.py", 900)):
        path = package / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text("")
        os.utime(path, (mtime, mtime))
    monkeypatch.setattr(speed_common, "__file__", str(package / "tools/speed/common.py"))
    assert speed_common.source_stamp() == 300


def test_the_machine_info_names_the_cpu_model_the_cores_and_the_commit(monkeypatch):
    """The "model name" line of /proc/cpuinfo (not the "model" number before it), the
    cores this process may use (affinity, quota) beside the machine's, and the commit
    of the checkout."""
    import io
    import os
    from pathlib import Path

    cpuinfo = "processor\t: 0\nmodel\t\t: 85\nmodel name\t: Some CPU @ 2.0GHz\n"
    monkeypatch.setattr(speed_common, "open", lambda path: io.StringIO(cpuinfo),
                        raising=False)
    monkeypatch.setattr(speed_common, "usable_cores", lambda: 1)
    info = speed_common.machine_info()
    assert info["cpu"] == "Some CPU @ 2.0GHz"
    assert (info["cores"], info["cpu_count"]) == (1, os.cpu_count())
    commit = speed_common.checkout_commit(Path(drill_env.__file__).resolve().parents[1])
    assert info.get("git_commit") == commit


# ----------------------------------------------------------------- vector.py


def test_a_masked_reset_keeps_the_pending_autoreset_of_the_other_envs():
    """Gymnasium's SyncVectorEnv (the documented NEXT_STEP semantics): a reset with a
    reset_mask clears the pending autoreset of the masked envs only; an unmasked env whose
    episode ended is still reset on the next step (reward 0, not done)."""
    kwargs = {"episode_duration": 0.1}  # one step per episode
    ours = DrillStringVectorEnv(num_envs=2, **kwargs)
    sync = gymnasium.make_vec("DrillString-v0", num_envs=2, vectorization_mode="sync", **kwargs)
    a = np.zeros((2, 2), dtype=np.float32)
    mask = np.array([True, False])
    out = []
    for envs in (ours, sync):
        envs.reset(seed=0)
        _, _, _, trunc, _ = envs.step(a)
        assert trunc.tolist() == [True, True]
        envs.reset(options={"reset_mask": mask.copy()})
        out.append(envs.step(a))
    assert out[1][1][1] == 0.0 and not out[1][3][1]  # the oracle reset env 1
    np.testing.assert_array_equal(out[0][1], out[1][1])
    np.testing.assert_array_equal(out[0][2], out[1][2])
    np.testing.assert_array_equal(out[0][3], out[1][3])


def test_a_reset_mask_of_integers_is_refused():
    """Gymnasium: reset_mask is a boolean array (SyncVectorEnv asserts its dtype); an int
    array [1, 0] would otherwise index envs 1 and 0 as positions."""
    envs = DrillStringVectorEnv(num_envs=2, episode_duration=0.5)
    envs.reset(seed=0)
    with pytest.raises(ValueError, match="reset_mask"):
        envs.reset(options={"reset_mask": np.array([1, 0])})


# ----------------------------------------------------------------- recording


class _EndsAtOnce(gymnasium.Env):
    """An env that terminates on its first step and gives no termination_reason."""

    observation_space = gymnasium.spaces.Box(-1.0, 1.0, (1,))
    action_space = gymnasium.spaces.Box(-1.0, 1.0, (1,))

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        return np.zeros(1, np.float32), {"time": 0.0, "bit_speed": 1.0}

    def step(self, action):
        return np.zeros(1, np.float32), 0.0, True, False, {"time": 0.1, "bit_speed": 1.0}


def test_a_termination_without_a_reason_is_still_logged_as_terminated(tmp_path):
    """RecordEpisode: the file is finished when the episode terminates; EpisodeRecorder.
    finish: a termination is an ERROR event. Without info['termination_reason'] the end
    must still read as a termination, not as a plain 'episode end'."""
    env = RecordEpisode(_EndsAtOnce(), tmp_path, scenario="fake")
    env.reset(seed=0)
    env.step(np.zeros(1, np.float32))
    assert env.last_path is not None
    level, text = read_recording(env.last_path).text_logs["/events"][-1][1:]
    assert level == "ERROR" and text.startswith("terminated")


def test_steps_without_a_time_get_distinct_increasing_times(tmp_path):
    """EpisodeRecorder.record: one sample per step; without info['time'] (and no sim)
    the steps must still be distinct points of the timeline, in order."""
    rec = EpisodeRecorder(tmp_path)
    rec.begin(scenario="bare", seed=1)
    for k in range(5):
        rec.record({"bit_speed": float(k + 1)})
    path = rec.finish("done")
    times, values = read_recording(path).scalars["/timeseries/speed_rpm/bit"]
    assert len(values) == 5
    assert np.all(np.diff(np.asarray(times, dtype=float)) > 0)


def test_an_episode_without_a_sample_leaves_no_file(tmp_path):
    """EpisodeRecorder.finish docstring: None if the episode has no sample, 'in which case
    no file is left'."""
    rec = EpisodeRecorder(tmp_path)
    rec.begin(scenario="empty", seed=0)
    assert rec.finish() is None
    assert list(tmp_path.glob("*.rrd")) == []


def test_the_episode_start_event_is_logged_once_across_chunks(tmp_path):
    """One episode, one 'episode start' event, also when written in chunks of two steps."""
    rec = EpisodeRecorder(tmp_path, flush_every=2)
    rec.begin(scenario="chunks", seed=0)
    for k in range(7):
        rec.record({"time": 0.1 * k, "bit_speed": 5.0})
    path = rec.finish("done")
    texts = [text for _, _, text in read_recording(path).text_logs["/events"]]
    assert sum(text.startswith("episode start") for text in texts) == 1


def test_effort_term_uses_each_set_points_own_span():
    """Docstring: effort = -effort_weight * ((d rpm / rpm span)^2 + (d WOB / WOB span)^2).
    From 100 rpm / 100 kN, action (0, 1) keeps 100 rpm and asks 200 kN: (100/200)^2."""
    env = DrillStringEnv(**SHORT)
    env.reset(seed=0, options={"surface_speed": 100 * RPM, "weight_on_bit": 100e3})
    _, _, _, _, info = env.step(np.array([0.0, 1.0]))
    assert info["speed_setpoint"] == pytest.approx(100 * RPM)
    assert info["reward_terms"]["effort"] == pytest.approx(
        -env.config.effort_weight * 0.25, rel=1e-9)


def test_the_unit_constants_are_their_definitions():
    """drill_env.physics.units, multiplied in at every edge (CLI, tables, configs in
    inches and feet, pipe grades in psi): each constant is its exact definition (the
    international inch and foot of 1959, the psi of the pound-force 4.4482216152605 N on
    a square inch, 2 pi / 60 rad/s per rpm), so a number read in field units is the one
    the code uses."""
    from drill_env.physics import units

    assert units.RPM == 2.0 * math.pi / 60.0
    assert units.INCH == 0.0254
    assert units.FOOT == pytest.approx(12 * units.INCH, rel=1e-15)
    assert units.PSI == pytest.approx(4.4482216152605 / units.INCH**2, rel=1e-7)
    assert (units.KILO, units.MEGA, units.HOUR) == (1e3, 1e6, 3600.0)
