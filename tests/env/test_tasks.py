"""The control tasks: spaces, targets, telemetry, rewards, batching, baselines."""

from __future__ import annotations

import math
from types import MappingProxyType
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import drill_env  # noqa: F401
from drill_env.physics.units import RPM
from drill_env.tasks.telemetry import Telemetry

TASKS = ("DrillStickSlip-v0", "DrillOptimise-v0")


@pytest.mark.parametrize("env_id", TASKS)
def test_task_passes_gymnasiums_checker(env_id):
    env = gym.make(env_id, episode_duration=5.0)
    check_env(env.unwrapped, skip_render_check=True)


@pytest.mark.parametrize("env_id", TASKS)
def test_same_seed_same_episode_and_seeds_differ(env_id):
    def run(seed):
        env = gym.make(env_id, episode_duration=4.0)
        obs, _ = env.reset(seed=seed)
        out = [obs]
        for _ in range(10):
            obs, *_ = env.step(np.zeros(env.action_space.shape, dtype=np.float32))
            out.append(obs)
        return np.array(out)

    np.testing.assert_array_equal(run(5), run(5))
    assert not np.array_equal(run(5), run(6))


def test_stick_slip_targets_are_drawn_in_range_and_observed():
    env = gym.make("DrillStickSlip-v0")
    base = env.unwrapped
    speeds = []
    for seed in range(20):
        obs, info = env.reset(seed=seed)
        speed, wob = base.targets
        assert 40.0 * RPM <= speed <= 100.0 * RPM and 70e3 <= wob <= 130e3
        assert obs[-6] == pytest.approx(speed / (100.0 * RPM), rel=1e-6)  # target rpm entry
        # the target WOB over 100 kN (the class docstring's table)
        names = base.observation_names
        assert obs[names.index("target_weight_on_bit")] == pytest.approx(wob / 100e3, rel=1e-6)
        assert info["target_speed"] == speed
        speeds.append(speed)
    assert np.std(speeds) > 10.0 * RPM


def test_stick_slip_target_changes_once_during_some_episodes():
    env = gym.make("DrillStickSlip-v0", target_change_probability=1.0,
                   target_change_time=(1.0, 1.0))
    obs, info = env.reset(seed=3)
    first = env.unwrapped.targets
    for _ in range(15):
        obs, _, _, _, info = env.step(np.zeros(1, dtype=np.float32))
    second = env.unwrapped.targets
    assert second != first
    assert 5.0 <= abs(second[0] - first[0]) / RPM <= 20.0 + 1e-9
    assert info["target_speed"] == second[0]
    # it changes at 1.0 s into the episode: the 10 control steps of 0.1 s before hold it
    env.reset(seed=3)
    seen = []
    for _ in range(15):
        *_, info = env.step(np.zeros(1, dtype=np.float32))
        seen.append((round(info["episode_time"], 6), info["target_speed"]))
    step = env.unwrapped.control_interval  # 0.1 s to within half a simulator step
    assert [t for t, speed in seen if speed != first[0]][0] == pytest.approx(11 * step)


def test_stick_slip_correction_reaches_the_top_drive_at_once():
    """+1 asks for target + 30 rpm through Simulator.speed_correction, past the set-point
    ramp: within a second the surface speed is there (the PI loop's time constant)."""
    env = gym.make("DrillStickSlip-v0", startup="settled", start_kick=0.0,
                   target_change_probability=0.0)
    obs, info = env.reset(seed=1, options={"surface_speed": 60 * RPM,
                                           "weight_on_bit": 60e3})
    for _ in range(10):
        obs, _, _, _, info = env.step(np.ones(1, dtype=np.float32))
    assert info["correction"] == pytest.approx(30 * RPM)
    assert info["surface_speed"] == pytest.approx(90 * RPM, rel=0.05)
    assert info["speed_setpoint"] == pytest.approx(60 * RPM)


def test_stick_slip_reward_has_no_rop_term_and_punishes_the_shortcut():
    """Turning 30 rpm faster cures stick-slip but misses the target: the tracking term
    makes it cost more than the stick-slip it avoids (design note, lesson 4)."""
    env = gym.make("DrillStickSlip-v0", target_change_probability=0.0)
    totals = {}
    for a in (0.0, 1.0):
        obs, info = env.reset(seed=7, options={"surface_speed": 50 * RPM,
                                               "weight_on_bit": 110e3})
        terms: dict[str, float] = {}
        while True:
            obs, r, term, trunc, info = env.step(np.array([a], dtype=np.float32))
            for k, v in info["reward_terms"].items():
                terms[k] = terms.get(k, 0.0) + v
            if term or trunc:
                break
        assert "rop" not in terms
        totals[a] = terms
    assert totals[1.0]["stick_slip"] > totals[0.0]["stick_slip"]  # less stick-slip ...
    assert sum(totals[1.0].values()) < sum(totals[0.0].values())  # ... but worse overall


@pytest.mark.parametrize(("env_id", "kwargs", "name"), [
    ("DrillStickSlip-v0", {"sensors": "surface"}, "sensors"),
    ("DrillStickSlip-v0", {"action_mode": "incremental"}, "action_mode"),
    ("DrillStickSlip-v0", {"rop_weight": 2.0}, "rop_weight"),
    ("DrillOptimise-v0", {"config": {"observation_noise": 0.1}}, "observation_noise"),
    ("DrillOptimise-v0", {"effort_weight": 1.0}, "effort_weight"),
])
def test_a_plain_env_setting_a_task_does_not_use_is_refused(env_id, kwargs, name):
    """The tasks build their own observation, reward and (task 1) action: a
    DrillString-v0 setting for those was accepted and had no effect (the observation of
    ``sensors="surface"`` stayed 67 values)."""
    with pytest.raises(ValueError, match=f"^{name}: .* does not use {name} .*own settings"):
        gym.make(env_id, **kwargs)


@pytest.mark.parametrize("env_id", TASKS)
def test_a_tasks_settings_list_only_the_env_settings_it_reads(env_id):
    """``TaskEnv.settings``: ``env`` holds the DrillString-v0 settings the task reads; the
    ones a task refuses as unused (the test above: sensors, observation_noise,
    effort_weight) are not among them, the control interval it steps at is."""
    env = gym.make(env_id).unwrapped.settings()["env"]
    assert "control_interval" in env and "episode_duration" in env
    assert not {"sensors", "observation_noise", "effort_weight"} & set(env)


@pytest.mark.parametrize(("env_id", "field", "value"), [
    ("DrillStickSlip-v0", "startup", "stalled"),
    ("DrillStickSlip-v0", "episode_duration", 30.0),
    ("DrillOptimise-v0", "start_kick", 0.02),
    ("DrillOptimise-v0", "episode_duration", 300.0),
    ("DrillOptimise-v0", "control_interval", 1.0),
    ("DrillOptimise-v0", "rpm_range", (40.0, 200.0)),
    ("DrillOptimise-v0", "weight_on_bit_range", (40e3, 140e3)),
])
def test_a_tasks_documented_defaults_hold_when_the_caller_gives_none(env_id, field, value):
    """The task docstrings' defaults where DrillString-v0's differ: task 1 starts stalled
    and runs 30 s; task 2 starts kicked 2 %, runs 300 s, acts once a second, with set
    points in 40-200 rpm and 40-140 kN."""
    assert getattr(gym.make(env_id).unwrapped.config, field) == value


@pytest.mark.parametrize(("env_id", "kwargs", "field", "value"), [
    ("DrillOptimise-v0", {"config": {"control_interval": 0.5, "episode_duration": 10.0}},
     "control_interval", 0.5),
    ("DrillOptimise-v0", {"config": {"start_kick": 0.0}}, "start_kick", 0.0),
    ("DrillOptimise-v0", {"config": MappingProxyType({"start_kick": 0.0})}, "start_kick",
     0.0),
    ("DrillStickSlip-v0", {"config": {"startup": "settled"}}, "startup", "settled"),
    ("DrillStickSlip-v0", {"episode_duration": 5.0}, "episode_duration", 5.0),
])
def test_the_callers_setting_wins_over_the_tasks_default(env_id, kwargs, field, value):
    """A task's own defaults (ENV_DEFAULTS) fill in what the caller left out; a value
    given in ``config`` was overwritten by them without a word."""
    env = gym.make(env_id, **kwargs).unwrapped
    assert getattr(env.config, field) == value


@pytest.mark.parametrize("physics", [{"solver.fidelity": "full"},
                                     {"solver": {"fidelity": "full"}}])
def test_a_fidelity_in_physics_wins_over_the_tasks_fast_default(physics):
    env = gym.make("DrillStickSlip-v0", physics=physics).unwrapped
    assert env.sim.config.solver.fidelity == "full"
    assert gym.make("DrillStickSlip-v0").unwrapped.sim.config.solver.fidelity == "fast"


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"rpm_targets": (400.0, 900.0)}, "rpm_targets: 400-900 rpm reaches outside the env's "
                                      "rpm_range 0-200 rpm"),
    ({"weight_on_bit_targets": (70e3, 150e3), "weight_on_bit_range": (0.0, 120e3)},
     "weight_on_bit_targets: 70-150 kN reaches outside the env's weight_on_bit_range"),
    # a correction past the lowest target turned the string backwards (-125 rpm at the bit
    # after 10 s at action -1, an outside check); the default 30 around 40 rpm is forward
    ({"max_correction": 100.0, "rpm_targets": (40.0, 40.0)},
     "max_correction: 100 rpm around targets from 40 rpm \\(rpm_targets\\) would command "
     "the top drive backwards"),
    ({"rpm_targets": (0.0, 0.0)}, "rpm_targets: the lowest target must be above 0 rpm")])
def test_targets_outside_the_set_point_ranges_are_refused(kwargs, message):
    # they were clipped to the range without a word: a 400-900 rpm task drilled at 200
    with pytest.raises(ValueError, match=f"^{message}"):
        gym.make("DrillStickSlip-v0", **kwargs)


@pytest.mark.parametrize("kwargs", [
    {"rpm_targets": (40.0, 200.0)},  # up to the default rpm_range's top, 200 rpm
    {"weight_on_bit_targets": (70e3, 120e3), "weight_on_bit_range": (0.0, 120e3)},
    {"rpm_targets": (40.0, 100.0), "rpm_range": (40.0, 200.0)},  # from its low end
])
def test_targets_at_the_ends_of_the_set_point_ranges_are_allowed(kwargs):
    """StickSlipEnv's docstring refuses targets *outside* the env's ``rpm_range`` /
    ``weight_on_bit_range``: a target range that ends on an end of the env's range lies
    inside it and builds."""
    env = gym.make("DrillStickSlip-v0", **kwargs)
    assert env.unwrapped.task.rpm_targets == kwargs.get("rpm_targets", (40.0, 100.0))


def test_a_correction_equal_to_the_lowest_target_is_allowed():
    """StickSlipTask.max_correction's comment: "At most the lowest rpm target" (the
    command then reaches 0 rpm, never backwards), and the env's docstring refuses a fixed
    speed *below* max_correction: the equal values are the edge of what is allowed, so
    40 rpm of correction around targets from 40 rpm builds, and a reset fixing the speed
    at exactly 40 rpm runs, commanding 0 rpm at a full negative action."""
    env = gym.make("DrillStickSlip-v0", max_correction=40.0, rpm_targets=(40.0, 100.0))
    env.reset(seed=0, options={"surface_speed": 40.0 * RPM})
    _, _, _, _, info = env.step(np.array([-1.0], dtype=np.float32))
    assert info["target_speed"] + info["correction"] == pytest.approx(0.0, abs=1e-9)
    with pytest.raises(ValueError, match="max_correction"):
        gym.make("DrillStickSlip-v0", max_correction=40.5, rpm_targets=(40.0, 100.0))


def test_a_task_refuses_an_env_config_instance_by_name():
    from drill_env.env_config import EnvConfig

    with pytest.raises(ValueError, match="^config: DrillingEnv takes its DrillString-v0 "
                                         "settings as keywords or a dict"):
        gym.make("DrillOptimise-v0", config=EnvConfig(control_interval=0.5))


@pytest.mark.parametrize("env_id, name", [("DrillStickSlip-v0", "stick_slip_weight"),
                                           ("DrillOptimise-v0", "rop_weight")])
def test_a_reward_weight_in_the_config_dict_reaches_the_task(env_id, name):
    """The reward weights are fields of both EnvConfig and the task config: given in
    ``config={...}`` (the docstrings' other way to give DrillString-v0 settings) one
    landed in EnvConfig, which the task's reward does not read, and changed nothing (an
    RL researcher's walkthrough). A keyword beside it wins, as in DrillString-v0."""
    def run(**kwargs):
        env = gym.make(env_id, episode_duration=6.0, **kwargs)
        env.reset(seed=1)
        total = sum(env.step(np.zeros(env.action_space.shape, np.float32))[4]["reward_terms"][
            "stick_slip" if name == "stick_slip_weight" else "rop"] for _ in range(5))
        return env.unwrapped.task, total

    base_task, base = run()
    task, scaled = run(config={name: 5.0 * getattr(base_task, name)})
    assert getattr(task, name) == 5.0 * getattr(base_task, name)
    assert base != 0.0 and scaled == pytest.approx(5.0 * base, rel=1e-9)
    keyword, _ = run(config={name: 5.0}, **{name: 2.0})
    assert getattr(keyword, name) == 2.0
    # beside the task dict it is refused (the dict's value was dropped without a word)
    for beside in ({name: 2.0}, {"config": {name: 2.0}}):
        with pytest.raises(ValueError, match=f"^{name}: given twice \\(in the task dict and "):
            gym.make(env_id, task={name: 5.0}, **beside)


@pytest.mark.parametrize("env_id", TASKS)
def test_a_task_only_setting_in_the_config_dict_reaches_the_task(env_id):
    """TaskEnv's rule: "a task setting in the dict is the task's", also one EnvConfig
    lacks (``history``): it sets the task's history (the observation 3 frames deep) while
    the dict's DrillString-v0 setting beside it reaches the env."""
    env = gym.make(env_id, config={"history": 3, "episode_duration": 5.0}).unwrapped
    assert env.task.history == 3 and env.config.episode_duration == 5.0
    frame = [n for n in env.observation_names if n.endswith("[0]")]
    assert sum(n.endswith("[2]") for n in env.observation_names) == len(frame)
    assert not any(n.endswith("[3]") for n in env.observation_names)


def test_a_task_settings_typo_lists_the_tasks_own_settings():
    with pytest.raises(ValueError, match=r"^StickSlipEnv: unknown argument\(s\) "
                                         r"\['max_corection'\] \(did you mean "
                                         r"max_correction\?\);.*task settings: .*"
                                         r"'max_correction'"):
        gym.make("DrillStickSlip-v0", max_corection=20.0)
    # a task's own setting is suggested as EnvConfig's are (a walkthrough's typo got none)
    with pytest.raises(ValueError, match=r"\['tracking_wieght'\] \(did you mean "
                                         r"tracking_weight\?\)") as err:
        gym.make("DrillStickSlip-v0", tracking_wieght=1.0)
    # and the EnvConfig fields listed are those the task reads (observation_noise, listed,
    # was then refused as a setting the task does not use)
    listed = str(err.value).partition("EnvConfig fields: ")[2].partition("]")[0]
    assert "'control_interval'" in listed and "'observation_noise'" not in listed
    gym.make("DrillOptimise-v0", action_mode="incremental", rop_weight=2.0)  # it uses both


def test_a_typo_lists_the_random_starts_ranges_where_the_env_takes_them():
    """The start ranges the random scenario draws in (docs/env.md) are listed with its
    parameters where an env takes them: a new user's trial found DrillOptimise-v0's list
    without them, while another refusal told them to give start_rpm_range."""
    with pytest.raises(ValueError, match=r"\(did you mean start_rpm_range\?\)") as err:
        gym.make("DrillOptimise-v0", start_rpm_rnage=(50.0, 60.0))
    listed = str(err.value).partition("scenario 'random' parameters: ")[2]
    assert "'start_rpm_range'" in listed and "'start_weight_on_bit_range'" in listed
    env = gym.make("DrillOptimise-v0", start_rpm_range=(50.0, 60.0))  # and it takes them
    assert env.unwrapped.scenario_params["rpm_range"] == (50.0, 60.0)  # (the draw's range)
    # task 1 draws its own targets: no start range offered (giving one is refused)
    with pytest.raises(ValueError) as err:
        gym.make("DrillStickSlip-v0", start_rpm_rnage=(50.0, 60.0))
    assert "start_rpm_range" not in str(err.value)
    # nor for a scenario that draws no start
    with pytest.raises(ValueError) as err:
        gym.make("DrillOptimise-v0", scenario="default", start_rpm_rnage=(50.0, 60.0))
    assert "start_rpm_range" not in str(err.value)



@pytest.mark.parametrize("kind", ["wired_pipe", (1.0, 0.01)])
def test_a_delay_under_a_control_step_still_arrives_a_step_late(kind):
    """A delay shorter than the control interval (wired pipe's 50 ms at 0.1 s, a channel
    of your own at 10 ms) is rounded up to one step, not down to none: downhole data
    never arrives in the step it is measured (a mutation test: rounding it to zero
    steps passed every test, which tried mud pulse only)."""
    tele = Telemetry(kind, 1)
    tele.reset(0.0, 0.1)
    held = [tele.update(0.1 * k, [float(k + 1)])[0] for k in range(3)]
    assert held[0] == 0.0  # nothing yet: the first sample is still on its way
    if kind == "wired_pipe":  # a sample every step, each one step late
        assert held == [0.0, 1.0, 2.0]
    else:  # one sample a second: the first, one step late, then held
        assert held == [0.0, 1.0, 1.0]


@pytest.mark.parametrize("kind, period, delay, dt", [
    ("mud_pulse", 2.0, 3.0, 0.1),  # the module's docstring: every 2 s, 3 s late
    ("wired_pipe", 0.1, 0.05, 0.01),  # 10 samples a second, 50 ms late
    ((1.0, 2.0), 1.0, 2.0, 0.1),  # a channel of one's own: (period, delay) s
    ([0.5, 0.0], 0.5, 0.0, 0.1),  # (a YAML list) delivered as sampled
])
def test_telemetry_is_sampled_delayed_and_held(kind, period, delay, dt):
    times = np.arange(0.0, 50 * period + 1e-9, dt)
    tele = Telemetry(kind, 1)
    tele.reset(0.0, dt)
    got = [tele.update(t, [t])[0] for t in times]
    assert all(v == 0.0 for v, t in zip(got, times, strict=True) if t < delay - 1e-9)
    for v, t in zip(got, times, strict=True):
        if t >= delay - 1e-9:  # the message sampled at the last multiple of the period
            assert v == pytest.approx(period * np.floor((t - delay + 1e-9) / period),
                                      abs=1e-6)
    # the age of what is held: since its sampling, not since it arrived; before the first
    # message it is stale beyond any cap (the task observation clips it), not fresh
    tele = Telemetry(kind, 1)
    tele.reset(0.0, dt)
    for t in times:
        tele.update(t, [t])
        if t >= delay - 1e-9:
            sampled = period * np.floor((t - delay + 1e-9) / period)
            assert tele.age(t) == pytest.approx(t - sampled, abs=1e-6)
        else:
            assert tele.age(t) > 1e6
    from typing import get_args

    from drill_env.tasks.telemetry import TELEMETRY, TelemetryKind

    assert set(get_args(TelemetryKind)) == {*TELEMETRY, "none"}  # the names it takes
    # telemetry_setting: "both at most an hour", an hour itself taken
    hour = Telemetry((3600.0, 3600.0), 1)
    assert (hour.period, hour.delay) == (3600.0, 3600.0)
    for bad in ("smoke", (0.0, 1.0), (1.0, -0.1), (math.nan, 1.0), (1.0, 2.0, 3.0), (True, 1),
                (3600.5, 1.0), (1.0, 3600.5)):
        with pytest.raises(ValueError, match=r"must be one of 'mud_pulse', 'wired_pipe', "
                                             r"'none' or \(period, delay\) in seconds"):
            Telemetry(bad, 1)


def test_a_task_takes_a_telemetry_channel_of_ones_own():
    """``telemetry=(period, delay)`` in gym.make (a list in a training YAML's env_kwargs):
    task 1 at 10 Hz with a message every 1 s, 2 s late, sees the held message's age cycle
    through 2.0-2.9 s once the first has come; a bad channel is refused naming the field
    (an outside trial found only the two presets, in the source)."""
    from training.config import load_config

    env = gym.make("DrillStickSlip-v0", telemetry=[1.0, 2.0])
    base = env.unwrapped
    age = base.observation_names.index("telemetry_age")
    env.reset(seed=3)
    seen = []
    for _ in range(60):
        obs, *_ = env.step(np.zeros(1, dtype=np.float32))
        seen.append(round(float(obs[age]) * 10.0 / base.control_interval))
    assert min(seen[:19]) > 50  # nothing before the 20th step (the age at its cap)
    assert sorted(set(seen[19:])) == list(range(20, 30))
    with pytest.raises(ValueError, match=r"^telemetry: must be one of .* got \(1.0, -2.0\)"):
        gym.make("DrillOptimise-v0", telemetry=(1.0, -2.0))
    config = load_config("stick_slip", "sac", None)
    load_config("stick_slip", "sac", None, env_kwargs={
        **config.env_kwargs, "telemetry": [1.0, 2.0]})  # (checked by building the env)


@pytest.mark.parametrize("interval", [0.9986, 1.0, 1.0005, 0.0998, 0.1002])
def test_mud_pulse_keeps_its_schedule_when_the_step_is_a_little_off(interval):
    """A task's control step is a whole number of the drawn simulator step: 0.9986 s on
    task 2's seed 3. Sampled by the clock, the 2 s mark fell 3 ms after the second step
    and the message went at the third: every 3 s and 4 s late on ~40 % of task 2's seeds
    (an outside check). Counted in steps: every 2 s and 3 s late, to within the step's
    own error, on every seed; the held message's age cycles 3-4 steps."""
    steps = round(2.0 / interval), round(3.0 / interval)
    tele = Telemetry("mud_pulse", 1)
    tele.reset(0.0, interval)
    ages = []
    for k in range(40 * steps[0]):
        t = k * interval
        held = tele.update(t, [float(k)])[0]
        if k >= steps[1]:  # the message of the last sampling step at least 3 s back
            assert held == steps[0] * ((k - steps[1]) // steps[0])
            ages.append(round(tele.age(t) / interval))
        else:
            assert held == 0.0
    assert sorted(set(ages)) == list(range(steps[1], steps[1] + steps[0]))


@pytest.mark.parametrize("interval", [0.0, -0.1, math.nan])
def test_a_telemetry_reset_refuses_a_control_step_that_is_not_positive(interval):
    """``Telemetry.reset`` counts the period and delay in control steps of ``interval``
    seconds: one of 0 s, below or NaN is refused by name (not a ZeroDivisionError)."""
    tele = Telemetry("mud_pulse", 1)
    with pytest.raises(ValueError, match=r"^interval: must be > 0"):
        tele.reset(0.0, interval)


def test_task_2_telemetry_arrives_every_2_s_and_3_s_late_on_every_seed():
    """Over seeds whose control step rounds both ways, the first message arrives at the
    third step and messages two steps apart (their ages 3 or 4 steps)."""
    env = gym.make("DrillOptimise-v0")
    base = env.unwrapped
    age = base.observation_names.index("telemetry_age")
    for seed in range(8):
        obs, _ = env.reset(seed=seed)
        seen = []
        for _ in range(9):
            obs, *_ = env.step(np.zeros(2, dtype=np.float32))
            seen.append(round(float(obs[age]) * 10.0 / base.control_interval))
        assert min(seen[:2]) > 10  # nothing before the 3rd step (the age reads its cap)
        assert seen[2:] == [3, 4, 3, 4, 3, 4, 3], (seed, base.control_interval, seen)


@pytest.mark.parametrize("env_id, kwargs", [
    *((env_id, {}) for env_id in TASKS),
    ("DrillStickSlip-v0", {"telemetry": [0.2, 0.3]}),  # a channel of one's own: 2 messages
])
def test_batched_task_env_follows_the_single_env(env_id, kwargs):
    from drill_env.vector import make_sb3_vec_env

    venv = make_sb3_vec_env(2, env_id=env_id, episode_duration=10.0,  # no reset in 5 steps
                            **kwargs)
    venv.seed(11)
    obs = venv.reset()
    single = gym.make(env_id, episode_duration=10.0, **kwargs)
    ref, _ = single.reset(seed=12)
    np.testing.assert_array_equal(obs[1], ref)
    action = np.full((2,) + single.action_space.shape, 0.3, dtype=np.float32)
    for _ in range(5):
        obs, rew, done, _ = venv.step(action)
        ref, r, *_ = single.step(action[1])
    np.testing.assert_array_equal(obs[1], ref)
    assert rew[1] == r


@pytest.mark.parametrize("env_id", TASKS)
def test_make_vec_builds_the_batched_task(env_id):
    """``gymnasium.make_vec(id, num_envs=N)`` builds the id's own task, batched (SPEC
    section 6): its spaces are those of ``gymnasium.make(id)``."""
    venv = gym.make_vec(env_id, num_envs=2, episode_duration=2.0)
    single = gym.make(env_id, episode_duration=2.0)
    assert venv.single_action_space == single.action_space
    assert venv.single_observation_space == single.observation_space
    obs, _ = venv.reset(seed=0)
    assert obs.shape == (2, venv.single_observation_space.shape[0])
    obs, *_ = venv.step(np.zeros((2, *single.action_space.shape), dtype=np.float32))
    assert np.all(np.isfinite(obs))


def drilled_terms(rock, wob: float) -> dict[str, float]:
    """The drilling task's reward terms summed over 30 control steps at 120 rpm and a
    held ``wob``, in homogeneous ``rock`` on the default string."""
    physics = {"formation.rocks": [vars_of(rock)], "formation.interfaces": [],
               "formation.layers": [0]}
    env = gym.make("DrillOptimise-v0", scenario="default", physics=physics,
                   episode_duration=30.0)
    base = env.unwrapped
    env.reset(seed=0, options={"surface_speed": 120 * RPM, "weight_on_bit": wob})
    terms: dict[str, float] = {}
    for _ in range(30):
        *_, info = env.step(base.action_for(120 * RPM, wob))
        for k, v in info["reward_terms"].items():
            terms[k] = terms.get(k, 0.0) + v
    return terms


def test_drilling_task_founder_point_makes_more_weight_worse_in_soft_rock():
    """Above the founder WOB the depth of cut falls: holding 140 kN in homogeneous soft
    rock drills slower than 100 kN (founder 111 kN) and wears the bit more."""
    from drill_env.scenarios import SOFT

    rewards = {wob: drilled_terms(SOFT, wob) for wob in (100e3, 140e3)}
    assert rewards[140e3]["rop"] < rewards[100e3]["rop"]
    assert rewards[140e3]["wear"] < rewards[100e3]["wear"]


def test_drilling_task_founder_point_holds_in_hard_rock_too():
    """The hard rock's founder WOB (its own curve, ~150 kN on this bit) lies above the
    task's 140 kN: there the depth of cut still grows with WOB, so 140 kN drills faster
    than 100 kN, where the soft rock (founder 111 kN) drills slower."""
    from drill_env.scenarios import HARD

    assert drilled_terms(HARD, 140e3)["rop"] > drilled_terms(HARD, 100e3)["rop"]


def vars_of(rock):
    import dataclasses

    return {f.name: getattr(rock, f.name) for f in dataclasses.fields(rock)}


def test_drilling_observation_tells_the_rock_apart_by_its_drillability():
    """The drillability feature (ROP per revolution per newton of WOB, from surface data)
    reads O(1) in hard rock (2 by the scale's choice) and clearly more in soft rock at
    the same set points (4: the soft rock's depth of cut per unit WOB is twice the hard
    one's in the presets), so a policy can see which rock it is in."""
    from drill_env.scenarios import HARD, SOFT
    from drill_env.tasks.drilling import FRAME

    readings = {}
    for rock in (HARD, SOFT):
        physics = {"formation.rocks": [vars_of(rock)], "formation.interfaces": [],
                   "formation.layers": [0]}
        env = gym.make("DrillOptimise-v0", scenario="default", physics=physics,
                       episode_duration=30.0)
        base = env.unwrapped
        env.reset(seed=0, options={"surface_speed": 100 * RPM, "weight_on_bit": 80e3})
        for _ in range(20):
            obs, *_ = env.step(base.action_for(100 * RPM, 80e3))
        last_frame = (base.task.history - 1) * len(FRAME)
        readings[rock.name] = float(obs[last_frame + FRAME.index("drillability")])
    assert 1.0 < readings["hard"] < 3.0
    assert readings["soft"] > 1.5 * readings["hard"]


@pytest.mark.parametrize("action, rpm, kn", [(-1.0, 40.0, 40.0), (1.0, 200.0, 140.0)])
def test_the_drilling_set_point_entries_are_over_the_ranges_tops(action, rpm, kn):
    """DrillingEnv's docstring: each frame holds the rpm set point / 200 rpm and the WOB
    set point / 140 kN (the tops of the default ranges 40-200 rpm, 40-140 kN); the action
    -1 asks for the ranges' low ends and +1 for their tops, so the newest frame reads
    40/200 and 40/140, or 1 and 1 (to float32 rounding)."""
    env = gym.make("DrillOptimise-v0")
    names = env.unwrapped.observation_names
    history = env.unwrapped.task.history
    env.reset(seed=0)
    obs, *_ = env.step(np.full(2, action, dtype=np.float32))
    last = history - 1
    assert obs[names.index(f"speed_setpoint[{last}]")] == pytest.approx(rpm / 200.0, rel=1e-6)
    assert obs[names.index(f"weight_on_bit_setpoint[{last}]")] == pytest.approx(
        kn / 140.0, rel=1e-6)


def test_reward_terms_follow_their_documented_formulas_from_the_raw_records():
    """Each term recomputed from the simulator's records of the step (and the last 3 s of
    them for the window terms) by the formulas of docs/tasks.md, not by the env's code:
    task 2's ROP / 30 m/h, wear -0.4 (rpm / 100)^1.5 (WOB / 100 kN), energy -0.05 P /
    100 kW with P = sum |T_motor w_top| dt over the nominal 1 s of the step; task 1's tracking
    -0.3 max(0, |mean bit rpm over 3 s - target| - 1)."""
    from drill_env import metrics
    from drill_env.physics.layout import R

    env = gym.make("DrillOptimise-v0")
    obs, info = env.reset(seed=3)
    base = env.unwrapped
    for k in range(30):
        obs, reward, *_, info = env.step(np.array([0.4 - 0.05 * k, -0.3], dtype=np.float32))
        rec = base.last_records
        dt = rec[1, R.TIME] - rec[0, R.TIME]
        terms = info["reward_terms"]
        assert terms["rop"] == pytest.approx(rec[:, R.ROP].mean() / (30.0 / 3600.0),
                                             rel=1e-9)
        rpm, wob = info["speed_setpoint"] / RPM, info["weight_on_bit_setpoint"]
        assert terms["wear"] == pytest.approx(-0.4 * (rpm / 100.0) ** 1.5 * wob / 100e3,
                                              rel=1e-12)
        energy = np.sum(np.abs(rec[:, R.MOTOR_TORQUE] * rec[:, R.SURFACE_SPEED])) * dt
        power = energy / base.config.control_interval  # J over the nominal step's 1 s
        assert terms["energy"] == pytest.approx(-0.05 * power / 100e3, rel=1e-9)
        # whirl: the share of the step's records that whirl (metrics.whirling: off
        # centre AND travelling round the hole axis; a bit resting off centre is not)
        off_centre = np.hypot(rec[:, R.BIT_X], rec[:, R.BIT_Y]) / base.clearance
        share = np.mean(metrics.whirling(off_centre, rec[:, R.WHIRL_SPEED],
                                         rec[:, R.BIT_SPEED], dt))
        assert terms["whirl"] == pytest.approx(-base.task.whirl_weight * share,
                                               abs=1e-12)
        assert reward == pytest.approx(sum(terms.values()), rel=1e-12)

    env = gym.make("DrillStickSlip-v0")
    env.reset(seed=5)
    base = env.unwrapped
    kept = []
    for _ in range(60):
        *_, info = env.step(np.array([0.5], dtype=np.float32))
        kept.append(base.last_records)
        rec = np.concatenate(kept)
        window = rec[rec[:, R.TIME] > rec[-1, R.TIME] - 3.0 + 1e-9]
        error = abs(window[:, R.BIT_SPEED].mean() - base.targets[0]) / RPM
        assert info["reward_terms"]["tracking"] == pytest.approx(
            -0.3 * max(0.0, error - 1.0), rel=1e-6, abs=1e-9)


def test_a_task_env_scored_as_the_plain_env_pays_what_the_plain_env_pays():
    """``plain_return`` (a task's policy scored beside the classical controllers in a
    scenario benchmark): in DrillString-v0 it is the return; in the stick-slip task with no
    correction, which drills exactly as DrillString-v0 holding its set points does, it is
    DrillString-v0's return of that episode; the task's own reward differs."""
    kwargs = {"scenario": "stick_slip", "startup": "settled", "episode_duration": 3.0,
              "fidelity": "fast"}
    options = {"surface_speed": 50 * RPM, "weight_on_bit": 100e3}
    plain = gym.make("DrillString-v0", **kwargs)
    task = gym.make("DrillStickSlip-v0", target_change_probability=0.0, **kwargs)
    returns = {}
    for name, env, action in (("plain", plain, plain.unwrapped.action_for(*options.values())),
                              ("task", task, np.zeros(1, dtype=np.float32))):
        env.reset(seed=3, options=options)
        assert env.unwrapped.plain_return is None  # not summed unless asked
        env.unwrapped.plain_return = 0.0
        total, done = 0.0, False
        while not done:
            _, reward, terminated, truncated, info = env.step(action)
            total += reward
            done = terminated or truncated
        returns[name] = (total, env.unwrapped.plain_return, info["bit_speed"])
    assert returns["task"][2] == returns["plain"][2]  # the same trajectory
    assert returns["plain"][1] == pytest.approx(returns["plain"][0], rel=1e-12)
    assert returns["task"][1] == pytest.approx(returns["plain"][0], rel=1e-12)
    assert abs(returns["task"][0] - returns["plain"][0]) > 1.0  # another reward


def test_a_one_second_task_step_is_scored_as_ten_plain_steps():
    """The drilling task acts once a second: DrillString-v0's rate terms (ROP,
    stick-slip, whirl) of a 1 s step count ten times, so a held WOB and rpm earn the plain
    env's return over the same seconds (smooth drilling here: the ROP term's means over
    ten 0.1 s steps and over one 1 s step are of the same records, equal to rounding)."""
    kwargs = {"scenario": "default", "startup": "settled", "episode_duration": 5.0,
              "fidelity": "full", "start_kick": 0.0}  # 2 ms: both steps span the same 5 s
    options = {"surface_speed": 120 * RPM, "weight_on_bit": 90e3}
    returns = []
    for env_id in ("DrillString-v0", "DrillOptimise-v0"):
        extra = {"rpm_range": (40.0, 200.0), "weight_on_bit_range": (40e3, 140e3)}
        env = gym.make(env_id, **kwargs, **(extra if env_id == "DrillString-v0" else {}))
        env.reset(seed=0, options=options)
        env.unwrapped.plain_return = 0.0
        action = np.array([0.0, 0.0], dtype=np.float32)  # mid-range: 120 rpm, 90 kN
        done = False
        while not done:
            _, _, terminated, truncated, _ = env.step(action)
            done = terminated or truncated
        returns.append(env.unwrapped.plain_return)
    assert returns[0] > 10.0  # ROP earned, nothing sticks
    assert returns[1] == pytest.approx(returns[0], rel=1e-6)


@pytest.mark.parametrize(("env_id", "kwargs", "field"), [
    # a denormal clearance made the radial ratio and the whirl term inf; a denormal ROP
    # reference the drilling reward inf; a denormal correction the observation
    ("DrillStickSlip-v0", {"physics": {"bit.gauge_clearance": 5e-324}}, "bit.gauge_clearance"),
    ("DrillOptimise-v0", {"rop_reference": 5e-324}, "rop_reference"),
    ("DrillStickSlip-v0", {"max_correction": 1e-300}, "max_correction")])
def test_a_divisor_of_the_reward_or_observation_has_a_floor(env_id, kwargs, field):
    with pytest.raises(ValueError, match=rf"^{field}: Input should be greater than or equal"):
        gym.make(env_id, **kwargs)


def test_task_observation_values_are_clipped_to_the_bound_keeping_their_sign():
    """The task observation's values go through ``_bounded``: NaN -> 0, beyond the bound
    -> the bound of the same sign; the reference is the docstring's own,
    ``np.clip(np.nan_to_num(v), -OBS_BOUND, OBS_BOUND)``, on values either side of it."""
    from drill_env.env import OBS_BOUND
    from drill_env.tasks.base import _bounded

    values = [math.nan, math.inf, -math.inf, 1e9, -1e9, OBS_BOUND + 0.5,
              -OBS_BOUND - 0.5, -3.0, 2.5, 0.0]
    want = np.clip(np.nan_to_num(np.array(values)), -OBS_BOUND, OBS_BOUND)
    np.testing.assert_array_equal(np.array(_bounded(values)), want)


def test_a_set_point_change_in_a_task_is_charged_as_the_plain_env_charges_it():
    """The effort term of ``plain_return`` divides a change by DrillString-v0's default
    ranges (0-200 rpm, 0-200 kN), not the task's narrower ones (40-200, 40-140), which
    charged the same change 1.6x (rpm) and 4x (WOB) more: at the same step the drilling
    task's scored return is DrillString-v0's return for the same change."""
    kwargs = {"scenario": "default", "startup": "settled", "fidelity": "fast",
              "start_kick": 0.0, "episode_duration": 2.0}
    options = {"surface_speed": 120 * RPM, "weight_on_bit": 90e3}
    plain = gym.make("DrillString-v0", **kwargs)
    task = gym.make("DrillOptimise-v0", control_interval=0.1, **kwargs)
    returns = []
    for env, action in ((plain, plain.unwrapped.action_for(200 * RPM, 140e3)),
                        (task, np.ones(2, dtype=np.float32))):  # the task's 200 rpm, 140 kN
        env.reset(seed=0, options=options)
        env.unwrapped.plain_return = 0.0
        _, reward, _, _, info = env.step(action)
        returns.append((reward, env.unwrapped.plain_return, info["reward_terms"]))
    (plain_reward, _, terms), (_, task_scored, _) = returns
    assert plain.unwrapped.targets == task.unwrapped.targets
    # the change is charged: 0.1 x ((80 / 200)^2 + (50 / 200)^2); the plain env's action
    # is float32, so its set points are the asked-for ones to ~1e-7
    assert terms["effort"] == pytest.approx(-0.1 * (0.4**2 + 0.25**2), rel=1e-6)
    assert task_scored == pytest.approx(plain_reward, rel=1e-6)


@pytest.mark.parametrize("env_id", TASKS)
def test_the_first_frame_fills_the_history_and_the_telemetry_age_starts_at_its_cap(env_id):
    """After a reset every frame of the observation's history is the first one (the
    docstring: it fills the whole history; zeros would read as a stalled string), and no
    telemetry message has arrived yet: its age reads the cap, 100 s / 10."""
    env = gym.make(env_id)
    obs, _ = env.reset(seed=0)
    base = env.unwrapped
    history = base.task.history
    names = base.observation_names
    width = len([n for n in names if n.endswith("[0]")])
    block = obs[: width * history].reshape(history, width)
    assert np.all(block == block[-1])
    if env_id == "DrillOptimise-v0":  # (task 1's first frame is zeros by its definition:
        # the torque less its own mean, the surface at its target, no action yet)
        assert np.all(block[-1][[0, 3, 4]] > 0.1)  # torque and set points
    assert names[-1] == "telemetry_age" and obs[-1] == pytest.approx(10.0)


def test_the_observation_names_label_the_history_oldest_first():
    """``observation_names[i]`` names the value at ``obs[i]``: the task docstring's layout,
    frames oldest first, each frame in FRAME's order. Task 1's ``action[k]`` entry holds
    the action of the k-th of the last ``history`` steps, by hand: after the actions
    0.1, 0.2, 0.3 with a 3-frame history, action[0..2] read 0.1, 0.2, 0.3 (float32)."""
    env = gym.make("DrillStickSlip-v0", history=3)
    base = env.unwrapped
    names = base.observation_names
    assert len(names) == env.observation_space.shape[0]
    env.reset(seed=0)
    for a in (0.1, 0.2, 0.3):
        obs, *_ = env.step(np.array([a], dtype=np.float32))
    for k, a in enumerate((0.1, 0.2, 0.3)):
        assert obs[names.index(f"action[{k}]")] == pytest.approx(a, abs=1e-6)
    # the target's entry (an extra) reads target rpm / 100
    target_rpm = base.targets[0] / RPM
    assert obs[names.index("target_rpm")] == pytest.approx(target_rpm / 100.0, rel=1e-5)


def test_a_target_change_stays_in_the_target_range_and_is_forgotten_at_a_reset():
    """The driller's change is kept inside the target ranges (an rpm change of 15-20 either
    way from 90-100 rpm ends at 90 or 100; a WOB change of 15-20 kN either way from
    120-130 kN at 120 or 130 kN), and an episode started at given targets (reset
    options) has no change, even right after an episode that drew one."""
    env = gym.make("DrillStickSlip-v0", rpm_targets=(90.0, 100.0), rpm_change=(15.0, 20.0),
                   weight_on_bit_targets=(120e3, 130e3), weight_on_bit_change=(15e3, 20e3),
                   target_change_probability=1.0, target_change_time=(0.2, 0.3))
    base = env.unwrapped
    changed = []
    for seed in range(6):
        env.reset(seed=seed)
        for _ in range(5):
            env.step(np.zeros(1, dtype=np.float32))
        changed.append((base.targets[0] / RPM, base.targets[1] / 1e3))
    assert sorted({round(rpm, 9) for rpm, _ in changed}) == [90.0, 100.0]  # both ends
    assert sorted({round(kn, 9) for _, kn in changed}) == [120.0, 130.0]  # reached
    env.reset(seed=3)
    env.reset(seed=3, options={"surface_speed": 60 * RPM, "weight_on_bit": 100e3})
    for _ in range(10):
        env.step(np.zeros(1, dtype=np.float32))
        assert base.targets == pytest.approx((60 * RPM, 100e3))


def test_the_stick_slip_effort_is_the_squared_change_of_the_action():
    """docs/tasks.md, task 1: effort -0.1 (a_k - a_(k-1))^2: a held correction costs
    nothing after its first step."""
    env = gym.make("DrillStickSlip-v0")
    env.reset(seed=0)
    efforts = [env.step(np.array([0.5], dtype=np.float32))[4]["reward_terms"]["effort"]
               for _ in range(3)]
    assert efforts == pytest.approx([-0.1 * 0.25, 0.0, 0.0])


def test_the_drilling_energy_term_is_a_power_at_any_control_interval():
    """Task 2's energy term is -0.05 P / 100 kW with P the motor's work over the step
    divided by the step's seconds: at a 0.5 s interval as at the default 1 s (where work
    and power have the same number)."""
    from drill_env.physics.layout import R

    env = gym.make("DrillOptimise-v0", control_interval=0.5)
    env.reset(seed=3)
    base = env.unwrapped
    assert base.config.control_interval == 0.5  # (nominal; the simulator's steps: ~0.5 s)
    for _ in range(4):
        *_, info = env.step(np.array([0.2, -0.3], dtype=np.float32))
        rec = base.last_records
        dt = rec[1, R.TIME] - rec[0, R.TIME]
        work = np.sum(np.abs(rec[:, R.MOTOR_TORQUE] * rec[:, R.SURFACE_SPEED])) * dt
        assert info["reward_terms"]["energy"] == pytest.approx(-0.05 * work / 0.5 / 100e3,
                                                               rel=1e-9)


def test_the_telemetry_bit_speed_is_a_past_bit_speed_over_the_target():
    """Task 1's downhole entry is the bit speed (over the target) as some earlier step
    read it, delivered by the telemetry: from a stalled start, while the surface turns at
    its target, every value it shows is one of the bit speeds seen before (0 before the
    first message), not the surface speed."""
    env = gym.make("DrillStickSlip-v0", telemetry="wired_pipe")
    _, info = env.reset(seed=0)
    base = env.unwrapped
    k = base.observation_names.index("telemetry_bit_speed")
    target = base.targets[0]
    seen, shown = [0.0, info["bit_speed"] / target], []
    for _ in range(40):
        obs, *_, info = env.step(np.zeros(1, dtype=np.float32))
        shown.append(float(obs[k]))
        seen.append(info["bit_speed"] / target)
    assert any(abs(v - 1.0) < 0.2 for v in shown)  # the bit got going, and it showed
    for value in shown:
        assert min(abs(value - s) for s in seen) <= 1e-6 * max(1.0, abs(value)), value


@pytest.mark.parametrize(("env_id", "action"), [("DrillStickSlip-v0", [0.0]),
                                                ("DrillOptimise-v0", [-1.0, 1.0])])
def test_the_telemetry_entries_are_past_downhole_values_as_documented(env_id, action):
    """Both task docstrings: the telemetry carries bit speed / set point (task 1: the
    target), min(SSI, cap) / cap and the metric window's stuck share; each value shown
    is that of some earlier step (info's ``ssi``, ``stuck_fraction``), 0 before the first
    message. Through wired pipe, from a start that sticks (task 1 stalled; task 2 at
    40 rpm and 140 kN), so SSI and stuck share are not 0."""
    env = gym.make(env_id, telemetry="wired_pipe")
    base = env.unwrapped
    cap = base.task.ssi_cap
    names = ("telemetry_bit_speed", "telemetry_ssi", "telemetry_stuck_fraction")

    def downhole(info):
        target = info.get("target_speed", info["speed_setpoint"])
        return (info["bit_speed"] / target, min(info["ssi"], cap) / cap,
                info["stuck_fraction"])

    _, info = env.reset(seed=0)
    seen, shown = [(0.0, 0.0, 0.0), downhole(info)], []
    for _ in range(12):
        obs, *_, info = env.step(np.array(action, dtype=np.float32))
        shown.append([float(obs[base.observation_names.index(n)]) for n in names])
        seen.append(downhole(info))
    for j, name in enumerate(names):
        values = [s[j] for s in seen]
        assert max(v[j] for v in shown) > 0.1, name
        for v in shown:
            assert min(abs(v[j] - s) for s in values) <= 1e-6 * max(1.0, abs(v[j])), name


def test_the_drilling_reward_counts_whirl_both_ways_and_a_missing_window_as_stuck():
    """Task 2's whirl term is the share of the step that whirls in either direction (the
    metrics' whirl fraction, not its backward part), and a window without finite values
    reads as stuck all the time (as the plain env reads it as whirl), on crafted window
    values."""
    from drill_env.metrics import Metric

    env = gym.make("DrillOptimise-v0")
    env.reset(seed=0)
    base = env.unwrapped
    values = [0.0] * len(Metric)
    values[Metric.WHIRL_FRACTION], values[Metric.BACKWARD_WHIRL_FRACTION] = 0.3, 0.1
    values[Metric.STUCK_FRACTION] = 0.2
    base._window_metrics = (values, True)
    terms = base._reward_terms((values, True), False)
    assert terms["whirl"] == pytest.approx(-base.task.whirl_weight * 0.3)
    assert terms["stuck"] == pytest.approx(-base.task.stuck_weight * 0.2)
    base._window_metrics = (values, False)
    assert base._reward_terms((values, True), False)["stuck"] == -base.task.stuck_weight


@pytest.mark.parametrize("scenario, action", [
    ("paper_case2", [0.6, 0.8]),  # the bit crossing into a dipping layer, pushed off centre
    # the bit lying on the low side of a 45-degree hole, off the axis without an orbit:
    # its radial ratio (~0.36), not the excursion from where it rests (~0)
    ("j_shaped", [0.0, 0.0]),
])
def test_the_drilling_telemetry_radial_entry_is_a_past_window_mean(scenario, action):
    """Task 2's downhole radial entry is the metric window's mean radial ratio
    (``info["radial_ratio"]``: radial displacement over clearance, docs/tasks.md) as some
    earlier step read it, through the telemetry."""
    env = gym.make("DrillOptimise-v0", telemetry="wired_pipe", scenario=scenario)
    _, info = env.reset(seed=0)
    k = env.unwrapped.observation_names.index("telemetry_radial_ratio")
    seen, shown = [0.0, info["radial_ratio"]], []
    for _ in range(15):
        obs, *_, info = env.step(np.array(action, dtype=np.float32))
        shown.append(float(obs[k]))
        seen.append(info["radial_ratio"])
    assert max(shown) > 0.1
    for value in shown:
        assert min(abs(value - s) for s in seen) <= 1e-6 * max(1.0, abs(value)), value


def _with_window_metric(env_id: str, name: str, value: float) -> tuple[Any, list[float]]:
    """A task env after a reset, and window-metric values that are 0 but ``name``."""
    from drill_env.metrics import Metric

    env = gym.make(env_id)
    env.reset(seed=0)
    values = [0.0] * len(Metric)
    values[Metric[name]] = value
    env.unwrapped._window_metrics = (values, True)
    return env.unwrapped, values


def test_stick_slip_whirl_term_reads_a_non_finite_step_as_full_excursion():
    # the plain env (drill_env/env.py, non-finite step -> excursion 1.0) and task 2 (whirl
    # share 1.0) both charge a step without finite values the full whirl penalty
    base, values = _with_window_metric("DrillStickSlip-v0", "EXCURSION_RATIO", 0.3)
    assert base._reward_terms((values, True), False)["whirl"] == pytest.approx(
        -base.task.whirl_weight * 0.3)
    assert base._reward_terms((values, False), False)["whirl"] == pytest.approx(
        -base.task.whirl_weight * 1.0)
    assert base._reward_terms(None, False)["whirl"] == pytest.approx(-base.task.whirl_weight)


def test_stick_slip_stuck_term_reads_a_missing_window_as_stuck_all_the_time():
    """As task 2 (test_the_drilling_reward_counts_whirl_both_ways_and_a_missing_window_as_stuck)
    and the whirl term above: a window without finite values costs the full stuck
    penalty, -stuck_weight x 1; a finite one its stuck share."""
    base, values = _with_window_metric("DrillStickSlip-v0", "STUCK_FRACTION", 0.2)
    assert base._reward_terms((values, True), False)["stuck"] == pytest.approx(
        -base.task.stuck_weight * 0.2)
    base._window_metrics = (values, False)
    assert base._reward_terms((values, True), False)["stuck"] == -base.task.stuck_weight


@pytest.mark.parametrize("env_id", TASKS)
def test_a_terminated_step_costs_the_failure_weight(env_id):
    """Both task docstrings: ``-failure_weight`` (10 by default) on termination, 0 on
    any other step."""
    base, values = _with_window_metric(env_id, "SSI", 0.5)
    assert base._reward_terms((values, True), True)["failure"] == -10.0
    assert base._reward_terms((values, True), False)["failure"] == 0.0


def test_the_tracking_term_has_the_configured_dead_band():
    """StickSlipEnv's docstring: ``-tracking_weight max(0, |mean bit rpm - target rpm| -
    deadband)``: with ``tracking_deadband=5`` around a 60 rpm target, a window mean of
    52 rpm costs 0.3 x (8 - 5) = 0.9 and one of 64 rpm, inside the band, nothing."""
    from drill_env.metrics import Metric

    env = gym.make("DrillStickSlip-v0", tracking_deadband=5.0, target_change_probability=0.0)
    env.reset(seed=0, options={"surface_speed": 60 * RPM, "weight_on_bit": 100e3})
    base = env.unwrapped
    for mean, want in ((52.0, -0.9), (64.0, 0.0)):
        values = [0.0] * len(Metric)
        values[Metric.MEAN_BIT_SPEED] = mean * RPM
        base._window_metrics = (values, True)
        assert base._reward_terms((values, True), False)["tracking"] == pytest.approx(
            want, abs=1e-12)


@pytest.mark.parametrize("a", [-5.0, 5.0])
def test_stick_slip_out_of_range_actions_are_clipped_both_ways(a):
    # StickSlipEnv docstring: speed command = target + action x max_correction (30 rpm);
    # out-of-range finite actions are clipped to [-1, 1]
    env = gym.make("DrillStickSlip-v0", target_change_probability=0.0)
    env.reset(seed=0)
    _, _, _, _, info = env.step(np.array([a], dtype=np.float32))
    assert info["correction"] == pytest.approx(math.copysign(30.0 * RPM, a))


@pytest.mark.parametrize("env_id", TASKS)
def test_stick_slip_penalty_is_capped_at_ssi_cap(env_id):
    # both task docstrings: -stick_slip_weight min(SSI, cap) (cap 2)
    base, values = _with_window_metric(env_id, "SSI", 7.0)
    terms = base._reward_terms((values, True), False)
    assert terms["stick_slip"] == pytest.approx(-base.task.stick_slip_weight * 2.0)


@pytest.mark.parametrize("env_id", ["DrillString-v0", "DrillStickSlip-v0",
                                    "DrillOptimise-v0"])
def test_action_for_refuses_set_points_that_are_not_finite(env_id):
    # a NaN set point came back as a NaN action (an outside check; step() refuses one);
    # a string or a bool was a bare TypeError, or a number (another outside check)
    env = gym.make(env_id)
    env.reset(seed=0)
    for speed, wob in ((math.nan, 100e3), (60 * RPM, math.inf), ("a", 100e3),
                       (60 * RPM, True)):
        with pytest.raises(ValueError, match="action_for: set points must be finite"):
            env.unwrapped.action_for(speed, wob)
    assert np.all(np.isfinite(env.unwrapped.action_for(60 * RPM, 100e3)))
    # any number goes: a 0-d array, a NumPy scalar (a review of the check above)
    assert np.array_equal(env.unwrapped.action_for(np.array(60 * RPM), np.float32(100e3)),
                          env.unwrapped.action_for(60 * RPM, 100e3))


def test_stick_slip_action_for_maps_a_speed_above_the_target_to_a_positive_action():
    # StickSlipEnv: speed command = target + action x max_correction (30 rpm)
    env = gym.make("DrillStickSlip-v0", target_change_probability=0.0)
    env.reset(seed=0, options={"surface_speed": 60 * RPM, "weight_on_bit": 100e3})
    base = env.unwrapped
    assert base.action_for(75 * RPM, 100e3)[0] == pytest.approx(0.5)
    assert base.action_for(30 * RPM, 100e3)[0] == pytest.approx(-1.0)


def test_drilling_whirl_term_reads_a_non_finite_step_as_whirling_all_the_time():
    # as the plain env (env.py: non-finite step -> radial 1.0): no finite values this
    # step means the worst whirl share, 1; and it earns no depth: ROP 0, as the plain
    # env's (env.py: non-finite step -> ROP 0)
    from drill_env.metrics import Metric

    base, values = _with_window_metric("DrillOptimise-v0", "WHIRL_FRACTION", 0.3)
    assert base._reward_terms((values, False), False)["whirl"] == pytest.approx(
        -base.task.whirl_weight * 1.0)
    values[Metric.ROP] = 0.01
    assert base._reward_terms((values, False), False)["rop"] == 0.0
    assert base._reward_terms(None, False)["whirl"] == pytest.approx(-base.task.whirl_weight)


def test_a_stick_slip_reset_fixing_one_target_draws_the_other_from_the_task_range():
    """Only ``weight_on_bit`` (or only ``surface_speed``) in the reset options: the other
    target is the task's draw, not the random scenario's own set point (40-159 rpm and
    51-128 kN were seen, outside the task's 40-100 rpm and 70-130 kN)."""
    env = gym.make("DrillStickSlip-v0")
    task = env.unwrapped.task
    low, high = task.rpm_targets
    w_low, w_high = task.weight_on_bit_targets
    for seed in range(20):
        _, info = env.reset(seed=seed, options={"weight_on_bit": 90e3})
        assert info["target_weight_on_bit"] == 90e3
        assert low * RPM <= info["target_speed"] <= high * RPM
        _, info = env.reset(seed=seed, options={"surface_speed": 60 * RPM})
        assert info["target_speed"] == pytest.approx(60 * RPM)
        assert w_low <= info["target_weight_on_bit"] <= w_high
    env.close()


@pytest.mark.parametrize("options", [
    {"surface_speed": 10.0 * RPM},  # the speed alone
    {"surface_speed": 10.0 * RPM, "weight_on_bit": 100.0e3},  # both
])
def test_a_reset_speed_below_the_correction_is_refused(options):
    """StickSlipEnv's docstring: "a speed below ``max_correction`` is refused (the
    correction would turn the top drive backwards)": 10 rpm with the default 30 rpm
    correction would command 10 - 30 = -20 rpm at a full negative action. The refusal
    names the option and the task setting, whether the WOB is fixed too or not."""
    env = gym.make("DrillStickSlip-v0")
    with pytest.raises(ValueError, match=r"surface_speed: 10 rpm is below the task's "
                                         r"max_correction 30 rpm"):
        env.reset(seed=0, options=options)


def test_the_stick_slip_speed_error_entry_is_over_the_correction():
    """StickSlipEnv's docstring, each frame: (surface speed - target) / ``max_correction``;
    with a 20 rpm correction around a fixed 60 rpm target, the newest frame's entry is
    (info's surface speed - 60 rpm) / 20 rpm (to float32 rounding)."""
    env = gym.make("DrillStickSlip-v0", max_correction=20.0, target_change_probability=0.0)
    base = env.unwrapped
    k = base.observation_names.index(f"surface_speed_error[{base.task.history - 1}]")
    env.reset(seed=1, options={"surface_speed": 60 * RPM, "weight_on_bit": 100e3})
    errors = []
    for a in (0.0, 1.0, 1.0, -0.5, -0.5, -0.5):
        obs, *_, info = env.step(np.array([a], dtype=np.float32))
        errors.append((info["surface_speed"] - 60 * RPM) / (20 * RPM))
        assert obs[k] == pytest.approx(errors[-1], rel=1e-6, abs=1e-6)
    assert max(abs(e) for e in errors) > 0.2  # (the surface did move off its target)


def test_the_surface_torque_mean_is_a_backward_euler_low_pass_of_3_s():
    """Task 1's surface_torque_mean, rebuilt from each step's surface torque (info) by
    m_k = m_(k-1) + a / (1 + a) (T_k - m_(k-1)), a = control interval / 3 s (backward
    Euler of dm/dt = (T - m) / 3 s: unconditionally stable for any interval), started
    at the first reading. A forward-Euler gain a passed every test (a mutation test);
    over 20 steps it moves the mean by ~6e-5 of itself, the float32 observation ~1e-7."""
    env = gym.make("DrillStickSlip-v0")
    obs, info = env.reset(seed=1)
    task = env.unwrapped
    k = task.observation_names.index("surface_torque_mean")
    scale = task.config.torque_scale
    a = task.config.control_interval / 3.0
    mean = info["surface_torque"]
    rng = np.random.default_rng(0)
    for _ in range(20):
        obs, _, _, _, info = env.step(rng.uniform(-1.0, 1.0, env.action_space.shape))
        mean += a / (1.0 + a) * (info["surface_torque"] - mean)
        assert obs[k] * scale == pytest.approx(mean, rel=2e-6)
    env.close()


def _held_return(env_id: str, seed: int, **kwargs: Any) -> tuple[float, int, bool]:
    """(return, steps, terminated) of one episode with the action held at 0."""
    env = gym.make(env_id, **kwargs)
    env.reset(seed=seed)
    total, steps = 0.0, 0
    while True:
        _, reward, terminated, truncated, _ = env.step(
            np.zeros(env.action_space.shape, dtype=np.float32))
        total, steps = total + float(reward), steps + 1
        if terminated or truncated:
            return total, steps, terminated


def test_a_failure_never_raises_a_task_1_return():
    """An outside review: with a bare -10 for a failure, ending an episode was the best
    action wherever a policy could reach the make-up torque. The default 40 kN m is out of
    reach of +-30 rpm (peaks of 10-14 kN m), so a lower one stands for a string where it
    is not: on seed 1000001 the stiff drive passes 11 kN m at step 7, where the stalled
    start costs ~30 a step (tracking: 0.3 x the target in rpm), and had returned -188
    there against -1,816 running the whole episode. A failure that charges each step it
    cuts off at the episode's worst so far returns less than running on."""
    full, n_full, failed = _held_return("DrillStickSlip-v0", 1_000_001)
    assert not failed
    cut, n_cut, failed = _held_return("DrillStickSlip-v0", 1_000_001, makeup_torque=11.0e3)
    assert failed and n_cut < n_full  # the lower make-up torque ends it early
    assert cut < full, (f"ending the episode at step {n_cut} by a failure returned "
                        f"{cut:.1f}, running it to step {n_full} {full:.1f}: failing pays")


@pytest.mark.parametrize("env_id", TASKS)
def test_the_batched_training_env_tells_task_time_outs_from_failures(env_id):
    """SB3 bootstraps the value of a time-out (``TimeLimit.truncated``, from
    ``terminal_observation``) and not of a failure: the training VecEnv of a task (its
    Python finish, not the plain env's arrays) must say which it was (an outside review)."""
    from drill_env.vector import make_sb3_vec_env

    short = 0.5 if env_id == "DrillStickSlip-v0" else 3.0
    venv = make_sb3_vec_env(2, env_id=env_id, episode_duration=short)
    venv.seed(3)
    venv.reset()
    zero = np.zeros((2, *venv.action_space.shape), dtype=np.float32)
    while not (done := venv.step(zero))[2].any():
        pass
    obs, _, dones, infos = done
    assert dones.all()
    for i, info in enumerate(infos):
        assert info["TimeLimit.truncated"] is True
        assert info["terminal_observation"].shape == obs[i].shape
        assert not np.array_equal(info["terminal_observation"], obs[i])  # obs: the reset's
    venv = make_sb3_vec_env(1, env_id="DrillStickSlip-v0", makeup_torque=11.0e3)
    venv.seed(1_000_001)
    venv.reset()
    for _ in range(20):
        _, _, dones, infos = venv.step(np.zeros((1, 1), dtype=np.float32))
        if dones[0]:
            break
    assert dones[0] and infos[0]["TimeLimit.truncated"] is False


@pytest.mark.parametrize("env_id", TASKS)
def test_batched_task_env_follows_the_single_env_across_autoresets(env_id):
    """Same seed, same actions: env i of the training VecEnv plays, episode after episode
    (its autoresets draw new strings, rocks and targets from its own generator), what a
    single env reset with seed + i and then without a seed plays (an outside review)."""
    from drill_env.vector import make_sb3_vec_env

    short, n = (0.5 if env_id == "DrillStickSlip-v0" else 3.0), 3
    venv = make_sb3_vec_env(n, env_id=env_id, episode_duration=short)
    venv.seed(40)
    first = venv.reset()
    actions = np.random.default_rng(0).uniform(
        -1, 1, (16, n, *venv.action_space.shape)).astype(np.float32)
    got: list[list[np.ndarray]] = [[first[i]] for i in range(n)]
    rewards: list[list[float]] = [[] for _ in range(n)]
    for a in actions:
        obs, r, dones, infos = venv.step(a)
        for i in range(n):
            got[i].append(infos[i]["terminal_observation"] if dones[i] else obs[i])
            rewards[i].append(float(r[i]))
            if dones[i]:
                got[i].append(obs[i])
    for i in range(n):
        env = gym.make(env_id, episode_duration=short)
        obs, _ = env.reset(seed=40 + i)
        want, want_rewards, resets = [obs], [], 0
        for a in actions[:, i]:
            obs, r, terminated, truncated, _ = env.step(a)
            want.append(obs)
            want_rewards.append(float(np.float32(r)))  # SB3 hands rewards on as float32
            if terminated or truncated:
                obs, _ = env.reset()
                want.append(obs)
                resets += 1
        assert resets >= 2
        assert len(got[i]) == len(want)
        for k, (g, w) in enumerate(zip(got[i], want, strict=True)):
            np.testing.assert_array_equal(g, w, err_msg=f"env {i}, entry {k}")
        np.testing.assert_array_equal(rewards[i], want_rewards)
