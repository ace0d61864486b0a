"""DrillString-v0: Gymnasium/SB3 conformance, determinism, pickling, bad input, rollouts."""

import math
import pickle
import re
import sys
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env

import drill_env
from drill_env.env import OBSERVATIONS, DrillStringEnv
from drill_env.physics.units import RPM
from drill_env.scenarios import SCENARIOS

SHORT = {"episode_duration": 0.5}
SPEC6_KEYS = ("time", "bit_speed", "surface_speed", "torque_on_bit", "surface_torque",
              "weight_on_bit", "hook_load", "bit_lateral", "whirl_speed", "depth", "rop",
              "rock_share")


def rollout(env, actions, seed):
    obs, info = env.reset(seed=seed)
    out = [obs]
    for a in actions:
        obs, reward, terminated, truncated, info = env.step(a)
        out += [obs, np.array([reward]), np.array([info["time"], info["bit_speed"]])]
        if terminated or truncated:
            break
    return np.concatenate([np.ravel(x) for x in out])


# --------------------------------------------------------------------------- registration


def test_import_registers_every_id_without_heavy_imports():
    for env_id in [*drill_env.ENV_IDS, *drill_env.TASK_IDS]:
        assert env_id in gym.registry
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # (gymnasium warns when an id is registered again)
        drill_env.register_envs()  # idempotent: no error, no duplicate warning
    # a submodule is imported when first named (drill_env.vector.make_sb3_vec_env after a
    # plain import, as the README writes it); a misspelt one is an AttributeError
    code = ("import sys, drill_env\n"
            "print(any(m in sys.modules for m in ('torch', 'stable_baselines3', 'rerun')),"
            " 'drill_env.vector' in sys.modules)\n"
            "print(drill_env.vector.make_sb3_vec_env.__name__)\n"
            "try:\n    drill_env.vectr\nexcept AttributeError as err:\n    print(err)")
    import subprocess

    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.splitlines() == [
        "False False", "make_sb3_vec_env", "module 'drill_env' has no attribute 'vectr'"]


# --------------------------------------------------------------------------- checkers


@pytest.mark.parametrize("env_id", list(drill_env.ENV_IDS))
def test_gymnasium_and_sb3_checkers_pass_for_every_id(env_id):
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        env = gym.make(env_id, **SHORT)
        gym_check_env(env.unwrapped, skip_render_check=True)
        sb3_check_env(gym.make(env_id, **SHORT).unwrapped, warn=True)


@pytest.mark.parametrize("scenario", list(SCENARIOS))
def test_gymnasium_and_sb3_checkers_pass_for_every_scenario(scenario):
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        env = gym.make("DrillString-v0", scenario=scenario, **SHORT)
        gym_check_env(env.unwrapped, skip_render_check=True)
        sb3_check_env(env.unwrapped, warn=True)


# --------------------------------------------------------------------------- spaces & info


def test_spaces_and_observation_layout():
    env = gym.make("DrillString-v0", **SHORT)
    assert env.action_space.shape == (2,)
    assert env.observation_space.dtype == np.float32
    assert env.unwrapped.observation_names == OBSERVATIONS["downhole"]
    surface = gym.make("DrillString-v0", sensors="surface", **SHORT)
    assert surface.observation_space.shape == (len(OBSERVATIONS["surface"]),)


def test_info_holds_spec_keys_in_si_and_reward_terms_sum_to_reward():
    env = gym.make("DrillString-v0", **SHORT)
    _, info = env.reset(seed=0)
    assert set(SPEC6_KEYS) <= set(info)
    _, reward, _, _, info = env.step(np.array([0.0, 0.0], dtype=np.float32))
    assert set(SPEC6_KEYS) <= set(info)
    assert info["bit_lateral"].shape == (2,)
    assert info["rock_share"].sum() == pytest.approx(1.0)
    assert info["weight_on_bit"] == pytest.approx(100e3)  # action 0 -> mid-range WOB
    assert info["hook_load"] == pytest.approx(env.unwrapped.sim.hook_load_for(100e3))
    assert info["speed_setpoint"] == pytest.approx(100 * RPM)
    assert set(info["reward_terms"]) == {"rop", "stick_slip", "whirl", "effort", "failure"}
    assert reward == pytest.approx(sum(info["reward_terms"].values()))
    for key in ("ssi", "stuck_fraction", "whirl_ratio", "mse", "top_drive_energy"):
        assert key in info


def test_control_interval_is_ten_hertz_of_simulator_steps():
    env = DrillStringEnv(**SHORT)
    env.reset(seed=0)
    assert env.control_interval == pytest.approx(0.1)
    _, _, _, _, info = env.step(np.zeros(2))
    assert info["time"] == pytest.approx(0.1)


def test_episode_truncates_at_its_duration():
    env = gym.make("DrillString-v0", episode_duration=0.3)
    env.reset(seed=0)
    flags = [env.step(np.zeros(2))[3] for _ in range(3)]
    assert flags == [False, False, True]


def test_the_effort_term_measures_a_change_over_the_set_point_range_s_span():
    """The effort term (class docstring): -effort_weight ((d rpm / rpm span)^2 + ...): a
    move across the whole of a 100-200 rpm range costs the whole weight, as across the
    default 0-200 rpm (a span measured from 0 read it as a quarter)."""
    env = gym.make("DrillString-v0", rpm_range=(100.0, 200.0), episode_duration=1.0)
    env.reset(seed=0)
    env.step(np.array([-1.0, 0.0], dtype=np.float32))  # 100 rpm
    *_, info = env.step(np.array([1.0, 0.0], dtype=np.float32))  # 200 rpm, the WOB kept
    weight = env.unwrapped.config.effort_weight
    assert info["reward_terms"]["effort"] == pytest.approx(-weight, rel=1e-12)


def test_incremental_actions_move_the_set_point_by_at_most_a_step():
    env = DrillStringEnv(action_mode="incremental", rpm_step=10.0, **SHORT)
    env.reset(seed=0, options={"surface_speed": 100 * RPM, "weight_on_bit": 100e3})
    _, _, _, _, info = env.step(np.array([1.0, -1.0]))
    assert info["speed_setpoint"] == pytest.approx(110 * RPM)
    assert info["weight_on_bit_setpoint"] == pytest.approx(90e3)


@pytest.mark.parametrize("fidelity", ["full", "fast"])
def test_drawworks_rate_limits_the_applied_weight_on_bit(fidelity):
    """The applied WOB moves by at most ``drawworks_rate * control_interval`` a step (class
    docstring), the interval being the step's own length, round(0.1 s / dt) simulator
    steps: 0.1 s at the full level, 26 x ~3.8 ms = ~0.099 s at the fast one."""
    env = DrillStringEnv(drawworks_rate=50e3, fidelity=fidelity, **SHORT)
    env.reset(seed=0, options={"weight_on_bit": 100e3})
    interval = round(0.1 / env.sim.dt) * env.sim.dt
    _, _, _, _, info = env.step(np.array([0.0, 1.0]))  # ask for 200 kN
    assert info["weight_on_bit_setpoint"] == pytest.approx(200e3)
    assert info["weight_on_bit"] == pytest.approx(100e3 + 50e3 * interval)  # 50 kN/s


def test_out_of_range_finite_actions_are_clipped():
    env = DrillStringEnv(**SHORT)
    env.reset(seed=0)
    _, _, _, _, info = env.step(np.array([5.0, -7.0]))
    assert info["speed_setpoint"] == pytest.approx(200 * RPM)
    assert info["weight_on_bit_setpoint"] == 0.0


def test_make_up_torque_terminates_with_a_reason():
    env = DrillStringEnv(makeup_torque=1.0, **SHORT)
    env.reset(seed=0)
    _, reward, terminated, truncated, info = env.step(np.zeros(2))
    assert terminated and not truncated
    assert "make-up torque" in info["termination_reason"]
    assert info["reward_terms"]["failure"] < 0


def test_make_up_torque_is_felt_at_its_peak_inside_a_control_step():
    """The make-up torque rule (a joint would unscrew) holds at every record inside the
    control step (every ``record_every`` simulator steps), not only at its end: with the
    limit between the highest surface torque seen at control-step ends and the highest
    in the steps' records, a stalled start terminates, at the first step whose records
    pass the limit."""
    from drill_env.physics.layout import R

    def run(limit):
        env = gym.make("DrillString-v0", scenario="stick_slip", episode_duration=8.0,
                       start_kick=0.02, startup="stalled", makeup_torque=limit)
        env.reset(seed=0)
        base = env.unwrapped
        action = base.action_for(*base.targets)
        peaks, ends = [], []
        for _ in range(80):
            _, _, terminated, truncated, info = env.step(action)
            peaks.append(float(np.abs(base.last_records[:, R.SURFACE_TORQUE]).max()))
            ends.append(abs(info["surface_torque"]))
            if terminated or truncated:
                break
        return terminated, peaks, ends

    terminated, peaks, ends = run(1e7)
    assert not terminated
    limit = 0.5 * (max(peaks) + max(ends))
    assert max(ends) < limit < max(peaks)  # a peak the step ends do not show
    terminated, peaks_again, _ = run(limit)
    first = next(k for k, peak in enumerate(peaks) if peak > limit)
    assert terminated and len(peaks_again) == first + 1


def test_paper_startup_hands_over_at_twenty_seconds_with_weight_on_bit():
    env = DrillStringEnv(startup="paper", **SHORT)
    obs, info = env.reset(seed=0, options={"surface_speed": 60 * RPM, "weight_on_bit": 80e3})
    assert info["time"] == pytest.approx(20.0)
    assert info["weight_on_bit"] == pytest.approx(80e3)
    assert info["surface_speed"] == pytest.approx(60 * RPM, rel=0.05)
    assert np.all(np.isfinite(obs))


def test_paper_startup_ramps_the_set_point_over_ten_seconds_then_holds_it_off_bottom(
        monkeypatch):
    """``startup="paper"`` (class docstring; paper section 4): from rest the speed set
    point rises linearly to the target, reaching it at 10 s, is held to 20 s with the hook
    carrying the whole string (no WOB), then the WOB is applied at 20 s."""
    env = DrillStringEnv(startup="paper", **SHORT)
    sim, target = env.sim, 60 * RPM
    calls = []
    advance = sim.advance

    def spy(n_steps, speed_setpoint=None, hook_load=None, **kwargs):
        out = advance(n_steps, speed_setpoint, hook_load, **kwargs)
        calls.append((sim.time, speed_setpoint, hook_load))  # (time at the call's end)
        return out

    monkeypatch.setattr(sim, "advance", spy)
    env.reset(seed=0, options={"surface_speed": target, "weight_on_bit": 80e3})
    *ramp, (t_last, speed_last, hook_last) = calls
    assert len(ramp) == 200 and ramp[-1][0] == pytest.approx(20.0)
    for t, speed, hook in ramp:
        assert speed == pytest.approx(target * min(1.0, t / 10.0), rel=1e-9)
        assert hook == sim.string_weight
    assert t_last == pytest.approx(20.0) and speed_last is None
    assert hook_last == pytest.approx(sim.string_weight - 80e3)


def test_delay_and_noise_are_seeded():
    kwargs = dict(telemetry_delay=2, observation_noise=0.01, **SHORT)
    actions = [np.array([0.2, -0.1])] * 4
    a = rollout(DrillStringEnv(**kwargs), actions, seed=5)
    b = rollout(DrillStringEnv(**kwargs), actions, seed=5)
    c = rollout(DrillStringEnv(**kwargs), actions, seed=6)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)


def test_telemetry_delay_returns_old_observations():
    env = DrillStringEnv(telemetry_delay=2, **SHORT)
    obs0, _ = env.reset(seed=0)
    obs1, *_ = env.step(np.array([1.0, 0.0]))
    obs2, *_ = env.step(np.array([1.0, 0.0]))
    obs3, *_ = env.step(np.array([1.0, 0.0]))
    np.testing.assert_array_equal(obs1, obs0)
    np.testing.assert_array_equal(obs2, obs0)
    assert not np.array_equal(obs3, obs0)


# --------------------------------------------------------------------------- determinism


def test_same_seed_same_actions_give_identical_trajectories():
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, size=(5, 2)).astype(np.float32)
    for scenario in ("default", "random"):
        a = rollout(gym.make("DrillString-v0", scenario=scenario, **SHORT), actions, seed=3)
        b = rollout(gym.make("DrillString-v0", scenario=scenario, **SHORT), actions, seed=3)
        np.testing.assert_array_equal(a, b)


def test_a_step_before_the_first_reset_is_refused_by_the_unwrapped_env_too():
    """From a fuzz of the API: only gymnasium.make's OrderEnforcing stopped it; the
    unwrapped task env ran an episode with (0, 0) targets."""
    from gymnasium.error import ResetNeeded

    for env in (DrillStringEnv(**SHORT), gym.make("DrillStickSlip-v0", **SHORT).unwrapped):
        action = np.zeros(env.action_space.shape, dtype=np.float32)
        with pytest.raises(ResetNeeded, match="^step: call reset"):
            env.step(action)
        env.reset(seed=0)
        env.step(action)
        pickle.loads(pickle.dumps(env)).step(action)  # the reset is carried along


def test_a_refused_reset_leaves_no_episode_to_step_or_render():
    """From an outside check of the API: a reset refused for a target out of range had
    already drawn a new string (the task's scenario is randomised) under the old
    episode's step count and targets, and step() ran on it (time 0.5 -> 0.1 s, another
    string); render() before any reset was an AttributeError in the batched envs, which
    build the raw class. Both say ResetNeeded; options of the wrong kind are refused
    before the seed is taken."""
    from gymnasium.error import ResetNeeded

    env = gym.make("DrillStickSlip-v0", **SHORT).unwrapped
    action = np.zeros(env.action_space.shape, dtype=np.float32)
    env.reset(seed=0)
    env.step(action)
    with pytest.raises(ValueError, match="surface_speed"):
        env.reset(seed=1, options={"surface_speed": 1.0e9})
    with pytest.raises(ResetNeeded, match="^step: call reset"):
        env.step(action)
    env.reset(seed=2)
    with pytest.raises(ValueError, match="unknown key"):
        env.reset(seed=9, options={"rpm": 5.0})
    assert env.np_random_seed == 2  # not reseeded by a reset refused at its options
    with pytest.raises(ResetNeeded, match="the last reset was refused"):
        env.step(action)  # no episode either, as in the batches
    fresh = DrillStringEnv(render_mode="rgb_array", **SHORT)
    with pytest.raises(ResetNeeded, match="^render: call reset"):
        fresh.render()
    fresh.reset(seed=0)
    assert fresh.render().ndim == 3


def test_pickle_round_trip_of_fresh_and_stepped_env():
    env = DrillStringEnv(scenario="random", observation_noise=0.01, **SHORT)
    env2 = pickle.loads(pickle.dumps(env))
    assert env2.config == env.config
    env.reset(seed=1)
    env.step(np.array([0.3, 0.1]))
    clone = pickle.loads(pickle.dumps(env))
    a = [env.step(np.array([0.1, 0.2])) for _ in range(2)]
    b = [clone.step(np.array([0.1, 0.2])) for _ in range(2)]
    for (oa, ra, *_), (ob, rb, *_) in zip(a, b, strict=True):
        np.testing.assert_array_equal(oa, ob)
        assert ra == rb


# --------------------------------------------------------------------------- bad input


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_action_raises_naming_the_action(bad):
    env = gym.make("DrillString-v0", **SHORT)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="action"):
        env.unwrapped.step(np.array([0.0, bad]))


@pytest.mark.parametrize("env_id, bad", [
    ("DrillString-v0", np.array(["a", "b"])), ("DrillString-v0", {"rpm": 1.0}),
    ("DrillString-v0", ["0.1", "0.2"]), ("DrillString-v0", None),
    ("DrillStickSlip-v0", "x"), ("DrillOptimise-v0", [[1.0], [2.0, 3.0]])])
def test_an_action_that_is_not_numbers_raises_naming_the_action(env_id, bad):
    env = gym.make(env_id, episode_duration=2.0)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="action: expected numbers"):
        env.unwrapped.step(bad)


@pytest.mark.parametrize("env_id, bad", [
    ("DrillString-v0", np.zeros((1, 2))), ("DrillString-v0", np.zeros((2, 1))),
    ("DrillString-v0", [0.1, 0.2, 0.3]), ("DrillStickSlip-v0", 0.5),
    ("DrillStickSlip-v0", np.zeros((1, 1))), ("DrillOptimise-v0", np.zeros(4))])
def test_an_action_of_the_wrong_shape_raises_naming_its_shape(env_id, bad):
    # a batch of one, (1, 2), was flattened and taken: it hides a batching mistake
    env = gym.make(env_id, episode_duration=2.0)
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"^action: expected shape \((2|1),\), got"):
        env.unwrapped.step(bad)


def test_a_boolean_action_is_refused():
    env = gym.make("DrillString-v0", episode_duration=2.0)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="action: expected numbers"):
        env.unwrapped.step(np.array([True, False]))


def test_a_task_config_of_the_wrong_type_is_named():
    with pytest.raises(ValueError, match="task: expected a StickSlipTask or a dict"):
        gym.make("DrillStickSlip-v0", task=[1, 2])


def test_unknown_scenario_lists_the_known_ones():
    with pytest.raises(ValueError, match="paper_case1"):
        gym.make("DrillString-v0", scenario="moon_rock")
    # a Scenario object (a walkthrough's try) is told what to pass, not shown its ~4 kB repr
    from drill_env.scenarios import make_scenario

    with pytest.raises(ValueError, match=r"^scenario: takes a scenario's name, not a Scenario "
                                         r"\(this one: 'default'\); give its parameters as "
                                         r"keywords"):
        gym.make("DrillString-v0", scenario=make_scenario("default"))


@pytest.mark.parametrize("physics", [{"string.drill_pipe.length": 1500.0},
                                     {"string": {"drill_pipe": {"length": 1500.0}}},
                                     {"string.components": []}, {"string.bha.length": 150.0}])
def test_a_string_length_beside_overrides_that_set_it_is_refused(physics):
    """From a walkthrough: string_length=1800 with a YAML string of 2500 m drilled at
    2500 m without a word (the overrides won); overrides that keep the length pass."""
    with pytest.raises(ValueError, match=r"^string_length: the physics overrides set the "
                                         r"string's length too \(string\.(drill_pipe\.length|"
                                         r"components|bha\.length)\); give one of them"):
        gym.make("DrillString-v0", string_length=1800.0, physics=physics)
    for scenario, keep in (("default", {"string.drill_pipe.element_length": 9.0}),
                           ("default", {"string.components[2].outer_diameter": 0.17}),
                           ("paper_case2", {"string.bha.outer_diameter": 0.17})):
        env = gym.make("DrillString-v0", scenario=scenario, string_length=1800.0,
                       physics=keep)
        assert env.unwrapped.sim.config.string.length == pytest.approx(1800.0)


def test_physics_that_is_not_a_dict_is_refused_and_a_files_path_names_its_reader(tmp_path):
    """A YAML file's path as physics= (as --config takes it) was refused with 'got str' and
    no pointer (a new user's trial); it now names the reader, whose result the env takes
    as --config's; other types are refused by their type."""
    from drill_env.physics.validation import read_yaml

    path = tmp_path / "mud.yaml"
    path.write_text("mud: {density: 1300}\n")
    for given in (str(path), path):
        with pytest.raises(ValueError, match=r"^physics: expected a dict of overrides, got the "
                                             r"path .*physics=read_yaml\(path\)"):
            gym.make("DrillString-v0", physics=given)
    with pytest.raises(ValueError, match="^physics: expected a dict of overrides, got list$"):
        gym.make("DrillString-v0", physics=[("mud.density", 1300.0)])
    env = gym.make("DrillString-v0", physics=read_yaml(path))
    assert env.unwrapped.sim.config.mud.density == 1300.0


def test_a_start_set_point_outside_the_action_ranges_is_refused_naming_it():
    """The env used to clamp these silently: ``surface_speed=50`` (rad/s, 477 rpm) drilled
    at 200 rpm, a reset at 250 kN at 200 kN, a 10 rpm reset of the drilling task (range
    40-200 rpm) at 40 rpm. The action ranges bound what an episode can hold, so a start
    outside them is an error naming the key, in the user's units; the range ends pass."""
    with pytest.raises(ValueError, match=r"^surface_speed: 477.5 rpm lies outside the "
                                         r"env's rpm_range 0-200 rpm \(surface_speed is in "
                                         r"rad/s: 50 rad/s\)"):
        gym.make("DrillString-v0", surface_speed=50.0)
    with pytest.raises(ValueError, match="^weight_on_bit: 100 kN .*weight_on_bit_range 0-80 kN"):
        gym.make("DrillString-v0", weight_on_bit_range=(0.0, 80e3))  # the scenario's 100 kN
    env = gym.make("DrillString-v0")
    with pytest.raises(ValueError, match=r"^reset options: weight_on_bit: 250 kN lies outside"):
        env.reset(seed=0, options={"weight_on_bit": 250e3})
    # (a walkthrough's WOB typed in kN was refused by the constructor, not by reset)
    with pytest.raises(ValueError, match=r"^reset options: weight_on_bit: 100 N is below 1 "
                                         r"kN; WOB is in newtons: did you mean 100e3\?"):
        env.reset(seed=0, options={"weight_on_bit": 100.0})
    env.reset(seed=0, options={"surface_speed": 200 * RPM, "weight_on_bit": 200e3})
    assert env.unwrapped.targets == pytest.approx((200 * RPM, 200e3))
    task = gym.make("DrillOptimise-v0")
    with pytest.raises(ValueError, match=r"^reset options: surface_speed: 10 rpm .*40-200 rpm"):
        task.reset(seed=0, options={"surface_speed": 10 * RPM})
    # task 1: a target below the correction's reach would turn the top drive backwards (an
    # outside check: 10 rpm and action -1 commanded -20.8 rpm); off the task's own target
    # range but inside the env's is taken (a policy tried off its training range)
    stick = gym.make("DrillStickSlip-v0")
    with pytest.raises(ValueError, match=r"^reset options: surface_speed: 10 rpm is below "
                                         r"the task's max_correction 30 rpm: "):
        stick.reset(seed=0, options={"surface_speed": 10 * RPM, "weight_on_bit": 100e3})
    assert stick.unwrapped.task.rpm_targets[1] < 150.0
    assert stick.unwrapped.task.max_correction == 30.0
    # the same env, after its refused first reset: gymnasium 1.4's passive checker (on by
    # default then) broke its every later step (a fuzzing walkthrough)
    stick.reset(seed=0, options={"surface_speed": 30 * RPM})
    stick.reset(seed=0, options={"surface_speed": 150 * RPM})
    stick.step(np.array([-1.0], dtype=np.float32))
    assert stick.unwrapped.sim.speed_correction == pytest.approx(-30 * RPM)


@pytest.mark.parametrize(("options", "message"), [
    ({"surface_speed": "fast"}, r"^reset options: surface_speed: must be a finite number, "
                                r"got 'fast'"),  # it was float()'s ValueError
    ({"weight_on_bit": None}, r"^reset options: weight_on_bit: must be a finite number"),
    ({"surface_speed": True}, r"^reset options: surface_speed: .* got True"),  # 1 rad/s
    ({"surface_speed": math.nan}, r"^reset options: surface_speed: .* got nan"),
    ("fast", r"^reset options: must be a dict, got 'fast'"),
    ({"speed": 5.0}, r"^reset options: unknown key\(s\) \['speed'\]; known: "),
    ({"surface_sped": 5.0}, r"^reset options: unknown key\(s\) \['surface_sped'\] "
                            r"\(did you mean surface_speed\?\); known: ")])
def test_reset_options_must_be_finite_numbers_by_name(options, message):
    for env_id in ("DrillString-v0", "DrillStickSlip-v0"):
        with pytest.raises(ValueError, match=message):
            gym.make(env_id).reset(seed=0, options=options)


@pytest.mark.parametrize(("env_id", "kwargs", "message"), [
    ("DrillString-v0", {"weight_on_bit_range": (0.0, 200.0)},
     r"weight_on_bit_range: \(0, 200\) N reaches only 200 N; WOB is in newtons: did you "
     r"mean \(0, 200e3\)\?"),
    ("DrillString-v0", {"weight_on_bit": 100.0}, r"weight_on_bit: 100 N .*did you mean 100e3"),
    ("DrillString-v0", {"scenario": "random", "weight_on_bit_range": (50.0, 130.0)},
     "weight_on_bit_range: .*130e3"),
    ("DrillStickSlip-v0", {"task": {"weight_on_bit_targets": (70.0, 130.0)}},
     r"weight_on_bit_targets: \(70, 130\) N .*\(70e3, 130e3\)"),
])
def test_a_weight_on_bit_typed_in_kn_is_refused(env_id, kwargs, message):
    """WOB is in newtons everywhere; (0, 200) meant as kN drilled on at most 200 N."""
    with pytest.raises(ValueError, match=message):
        gym.make(env_id, **kwargs)


def test_unknown_keyword_is_named():
    with pytest.raises(ValueError, match="episode_lenght"):
        gym.make("DrillString-v0", episode_lenght=3.0)


@pytest.mark.parametrize("kwargs, name", [
    ({"string_length": 30.0}, "string_length"),  # BHA (35 m) longer than the string
    ({"physics": {"bit.gauge_clearance": 0.0}}, "gauge_clearance"),
    ({"physics": {"string.hole_diameter": 0.15}}, "clearance <= 0"),
    # where it places stabilizers: the paper string's (components carry their own)
    ({"scenario": "paper_case1", "physics": {"string.stabilizer_diameter": 0.3}},
     "stabilizer_diameter"),
    # blades on one angle (modulo 360): two blades in one place
    ({"physics": {"bit.blade_angles": [0.0] * 6}}, r"bit.blade_angles\[1\]: 0 deg repeats"),
    ({"physics": {"bit.blade_angles": [0, 60, 120, 180, 240, 360]}},
     r"bit.blade_angles\[5\]: 360 deg repeats entry \[0\]"),
    ({"physics": {"initial_depth": -100.0}}, "initial_depth"),  # a bit above the wellhead
    ({"weight_on_bit_range": (-10e3, 100e3)}, "weight_on_bit_range"),
    ({"rpm_range": (100.0, 50.0)}, "rpm_range"),
    ({"action_mode": "relative"}, "action_mode"),
    ({"sensors": "psychic"}, "sensors"),
    ({"scenario": "paper_case1", "position": "P9"}, "position"),
    ({"episode_duration": -1.0}, "episode_duration"),
    # below MIN_SCALE (env_config: "ROP over a scale of at least 1e-6 m/s")
    ({"rop_scale": 1e-7}, "rop_scale"),
    # faster than half the solver's step (2 ms): it would act every step, not at 1 us
    ({"control_interval": 1e-6}, "control_interval: 1e-06 s is at most half"),
    ({"episode_duration": 0.05}, "episode_duration: 0.05 s is at most half a control "
                                 "interval"),  # exactly half rounds to no step
    # shorter than half its one step: it would run 60 s, not 1 s
    ({"control_interval": 60.0, "episode_duration": 1.0}, "episode_duration: 1 s"),
    # one record in the window (records 20 ms apart): its SSI and stuck share read 0, the
    # stick-slip reward term gone unsaid (a fuzzing walkthrough)
    ({"metric_window": 0.025}, r"^metric_window: 0.025 s holds fewer than two records "
                               r"\(0.02 s apart\): .* give at least 0.04 s"),
    ({"fidelity": "Fast"}, r"fidelity: .* got 'Fast' \(did you mean fast\?\)"),
    ({"scenario": "paper_case1", "position": "p3"}, r"position: .* \(did you mean P3\?\)"),
    # an array (NumPy's "truth value ... is ambiguous", naming no field)
    ({"physics": {"string.components": np.array([1, 2])}}, r"string.components\[0\]: "),
])
def test_inconsistent_configuration_raises_naming_the_field(kwargs, name):
    with pytest.raises(ValueError, match=name):
        gym.make("DrillString-v0", **kwargs)


def test_a_numpy_integer_seed_is_taken_as_the_batched_env_takes_it():
    """A seed loop over ``np.arange`` ran batched and was refused by the single env
    (gymnasium: "Seed must be a python integer"; a fuzzing walkthrough): the same episode
    as the Python integer's."""
    first, second = (gym.make("DrillString-v0", scenario="random", **SHORT) for _ in "12")
    obs, _ = first.reset(seed=np.int64(5))
    same, _ = second.reset(seed=5)
    np.testing.assert_array_equal(obs, same)
    assert not np.array_equal(second.reset(seed=6)[0], same)  # (the seed draws the start)
    second.reset(seed=5)
    action = np.array([0.3, -0.2], np.float32)
    np.testing.assert_array_equal(first.step(action)[0], second.step(action)[0])


def test_a_control_interval_of_one_simulator_step_is_accepted():
    """The refusal of a too-short ``control_interval`` is for one at most half the
    simulator's step (it rounds to no step); an interval of one step, or of 0.75 of one,
    rounds to one simulator step per action and is accepted: after one step the clock
    reads one ``dt`` (the env's own time step, read from a default env)."""
    dt = DrillStringEnv(**SHORT).sim.dt
    for interval in (dt, 0.75 * dt):
        env = DrillStringEnv(control_interval=interval, episode_duration=20 * dt)
        _, info = env.reset(seed=0)
        start = info["time"]
        _, _, _, _, info = env.step(np.zeros(2))
        assert info["time"] - start == pytest.approx(dt, rel=1e-6)


# --------------------------------------------------------------------------- rollouts


def run_episode(env, policy, seed=0):
    obs, info = env.reset(seed=seed)
    steps, total = 0, 0.0
    while True:
        obs, reward, terminated, truncated, info = env.step(policy(obs))
        assert np.all(np.isfinite(obs)) and np.isfinite(reward)
        for key in SPEC6_KEYS:
            assert np.all(np.isfinite(info[key])), key
        steps += 1
        total += reward
        if terminated or truncated:
            return steps, terminated, info


def test_random_policy_runs_a_full_episode_without_nan():
    env = gym.make("DrillString-v0", episode_duration=3.0)
    env.action_space.seed(0)
    steps, terminated, _ = run_episode(env, lambda obs: env.action_space.sample())
    assert steps == 30 and not terminated


def test_constant_rpm_policy_runs_a_full_episode_without_nan():
    env = gym.make("DrillString-v0", episode_duration=3.0)
    constant = np.array([-0.4, 0.0], dtype=np.float32)  # 60 rpm, 100 kN
    steps, terminated, info = run_episode(env, lambda obs: constant)
    assert steps == 30 and not terminated
    assert info["speed_setpoint"] == pytest.approx(60 * RPM)
    assert info["depth"] > env.unwrapped.simulation_config.initial_depth


def test_fidelity_keyword_selects_the_fast_physics():
    env = gym.make("DrillString-v0", scenario="paper_case4", fidelity="fast")
    env.reset(seed=0)
    cfg = env.unwrapped.sim.config
    assert cfg.solver.fidelity == "fast" and cfg.solver.pipe_lateral is False
    obs, *_ = env.step(env.action_space.sample())
    assert np.all(np.isfinite(obs))
    with pytest.raises(ValueError, match="^fidelity: must be one of"):
        gym.make("DrillString-v0", fidelity="turbo").reset(seed=0)


def _finite_info_values(info) -> list[str]:
    """Names of the info values that are not finite (nested reward terms included)."""
    bad = []
    for key, value in info.items():
        if isinstance(value, dict):
            bad += [f"{key}.{k}" for k, v in value.items() if not np.all(np.isfinite(v))]
        elif not isinstance(value, str) and not np.all(np.isfinite(value)):
            bad.append(key)
    return bad


def test_info_is_finite_with_the_bit_turning_under_zero_rpm():
    """Regression: all -1 (0 rpm, 0 WOB) on the random scenario gave info["mse"] = inf."""
    env = gym.make("DrillStringRandom-v0", episode_duration=6.0)
    for seed in (1, 3):  # the bit winds back as the rpm drops: 5 s in, MSE was inf
        env.reset(seed=seed)
        done = False
        while not done:
            _, reward, terminated, truncated, info = env.step(-np.ones(2, dtype=np.float32))
            assert not _finite_info_values(info) and math.isfinite(reward)
            done = terminated or truncated


def test_a_step_whose_records_are_not_all_finite_adds_no_energy_to_info():
    """A metrics audit: the episode's top-drive energy summed every step's without the
    finite flag, so a record with a NaN motor torque put NaN in info["top_drive_energy"]
    (info holds no NaN, docs): that step adds none, the steps after it count again."""
    from drill_env.physics.layout import R

    env = gym.make("DrillString-v0", scenario="stick_slip", episode_duration=5.0,
                   fidelity="fast")
    env.reset(seed=0)
    held = np.zeros(2, dtype=np.float32)
    before = env.step(held)[4]["top_drive_energy"]
    records = env.unwrapped.last_records.copy()
    records[-1, R.MOTOR_TORQUE] = np.nan
    info = env.unwrapped.finish_step(records)[4]
    assert info["top_drive_energy"] == before and not _finite_info_values(info)
    assert env.step(held)[4]["top_drive_energy"] > before


def test_the_random_scenario_draws_its_start_within_the_action_ranges_or_as_told():
    """The random scenario's own start ranges (rpm_range, weight_on_bit_range) share their
    names with the env's action ranges, which took them: ``rpm_range=(0, 100)`` drew
    40-160 rpm and clamped every draw above 100 onto 100. The draws are cut to the action
    ranges now, and ``start_rpm_range`` / ``start_weight_on_bit_range`` set them."""
    def starts(**kwargs):
        env = gym.make("DrillStringRandom-v0", episode_duration=0.5, **kwargs)
        out = []
        for seed in range(16):
            _, info = env.reset(seed=seed)
            out.append((info["speed_setpoint"] / RPM, info["weight_on_bit_setpoint"]))
        return np.array(out), env.unwrapped.scenario_params

    rpm, params = starts()
    assert params == {"rpm_range": (40.0, 160.0), "weight_on_bit_range": (50.0e3, 130.0e3)}
    narrowed, params = starts(rpm_range=(0.0, 100.0), weight_on_bit_range=(0.0, 90.0e3))
    assert params == {"rpm_range": (40.0, 100.0), "weight_on_bit_range": (50.0e3, 90.0e3)}
    assert np.all((narrowed[:, 0] >= 40.0) & (narrowed[:, 0] < 100.0))
    assert np.all((narrowed[:, 1] >= 50.0e3) & (narrowed[:, 1] < 90.0e3))
    assert np.ptp(narrowed[:, 0]) > 30.0  # spread over the range, not piled on its end
    told, _ = starts(start_rpm_range=(60.0, 70.0), start_weight_on_bit_range=(80e3, 90e3))
    assert np.all((told >= (60.0, 80e3)) & (told <= (70.0, 90e3)))
    for kwargs, message in (
            ({"start_rpm_range": (0.0, 300.0)}, "start_rpm_range: 0-300 rpm must be an "
             "ordered range within the env's rpm_range 0-200 rpm"),
            ({"start_rpm_range": (90.0, 60.0)}, "start_rpm_range: 90-60 rpm must be"),
            ({"start_rpm_range": (60.0, "fast")}, "start_rpm_range: expected numbers"),
            ({"start_weight_on_bit_range": (80, 90)}, "start_weight_on_bit_range: .* N "
             "reaches only 90 N; WOB is in newtons"),
            ({"rpm_range": (170.0, 200.0)}, "rpm_range: the env's rpm_range 170-200 rpm misses "
             "the random scenario's starting draws, 40-160 rpm; give start_rpm_range")):
        with pytest.raises(ValueError, match=message):
            gym.make("DrillStringRandom-v0", **kwargs)
    with pytest.raises(ValueError, match="start_rpm_range: scenario 'default' draws no start"):
        gym.make("DrillString-v0", start_rpm_range=(60.0, 70.0))
    with pytest.raises(ValueError, match="start_rpm_range: StickSlipEnv does not use"):
        gym.make("DrillStickSlip-v0", start_rpm_range=(60.0, 70.0))  # its targets' ranges
    env = gym.make("DrillOptimise-v0", start_rpm_range=(60.0, 70.0))  # starts as drawn
    assert 60.0 <= env.reset(seed=3)[1]["speed_setpoint"] / RPM <= 70.0


def test_info_after_a_divergence_holds_the_last_finite_state():
    env = gym.make("DrillString-v0", episode_duration=2.0)
    env.reset(seed=0)
    _, _, _, _, before = env.step(np.zeros(2, dtype=np.float32))
    env.unwrapped.sim.ut[5] = np.nan  # a broken state: the kernel must stop on it
    obs, reward, terminated, _, info = env.step(np.zeros(2, dtype=np.float32))
    assert terminated and "diverged" in info["termination_reason"]
    assert not _finite_info_values(info) and math.isfinite(reward)
    assert np.all(np.isfinite(obs))
    assert info["bit_speed"] == before["bit_speed"] and info["time"] == before["time"]
    assert info["reward_terms"]["failure"] < 0.0


# ------------------------------------------------------- the action mapping's rules (docstring)


def test_incremental_actions_step_from_the_set_point_clipped_to_one_step():
    """Incremental mode moves the set point by ``action * step`` from the set point (not
    from the WOB the slow drawworks has reached), an action beyond +-1 by one step."""
    env = DrillStringEnv(action_mode="incremental", drawworks_rate=10e3, **SHORT)
    env.reset(seed=0, options={"surface_speed": 100 * RPM, "weight_on_bit": 100e3})
    for _ in range(2):
        _, _, _, _, info = env.step(np.array([0.0, 1.0]))
    assert info["weight_on_bit_setpoint"] == pytest.approx(120e3)
    assert info["weight_on_bit"] == pytest.approx(102e3)  # 10 kN/s x 0.2 s behind
    _, _, _, _, info = env.step(np.array([5.0, -7.0]))
    assert info["speed_setpoint"] == pytest.approx(110 * RPM)
    assert info["weight_on_bit_setpoint"] == pytest.approx(110e3)


def test_the_drawworks_unloads_at_its_rate_and_never_past_the_mesh_limit():
    """The applied WOB follows the set point at ``drawworks_rate`` both ways, and never
    exceeds ``weight_on_bit_limit`` (the largest WOB the mesh resolves: below the action
    range's 200 kN on the 60-degree well), at reset either, where a reset option above
    it says so (it was silent: an outside check)."""
    env = DrillStringEnv(drawworks_rate=50e3, **SHORT)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # below the limit: no warning
        env.reset(seed=0, options={"weight_on_bit": 100e3})
    _, _, _, _, info = env.step(np.array([0.0, -1.0]))  # ask for 0 kN
    assert info["weight_on_bit"] == pytest.approx(95e3)  # 50 kN/s x 0.1 s
    env = DrillStringEnv(scenario="lateral_60", episode_duration=5.0)
    with pytest.warns(RuntimeWarning, match=r"reset options: weight_on_bit: 200 kN is above "
                                            r"this string's weight_on_bit_limit, 19\d\.\d kN"
                      ) as said:
        _, info = env.reset(seed=0, options={"weight_on_bit": 200e3})
    # at the line that asked (it pointed into the env, or through gym.make into gymnasium)
    assert said[0].filename == __file__
    with pytest.warns(RuntimeWarning, match="weight_on_bit_limit") as said:
        gym.make("DrillString-v0", scenario="lateral_60", weight_on_bit=200e3)
    assert said[0].filename == __file__
    limit = info["weight_on_bit_limit"]
    assert limit < 199e3 and info["weight_on_bit"] <= limit
    for _ in range(45):  # 100 kN/s x 4.5 s: the set point's 200 kN is long reached
        _, _, _, _, info = env.step(np.array([0.0, 1.0]))
        assert info["weight_on_bit"] <= limit
    assert info["weight_on_bit"] == pytest.approx(limit)


def test_the_weight_on_bit_limit_is_the_range_top_where_the_mesh_resolves_it():
    """EnvConfig.limit_weight_on_bit_to_mesh caps the WOB at the largest the mesh resolves
    (env_config.mesh_weight_on_bit_limit; the lateral_60 well's below 200 kN in the test
    above): a range top the mesh resolves is the limit exactly, not cut to the bisection's
    100 N tolerance."""
    assert DrillStringEnv(weight_on_bit_range=(0.0, 100e3), **SHORT
                          ).weight_on_bit_limit == 100e3


def test_the_start_kick_is_drawn_both_ways_within_its_size():
    """``start_kick`` kicks the bit speed by a fraction drawn in [-kick, +kick]."""
    settled = DrillStringEnv(**SHORT).reset(seed=0)[1]["bit_speed"]
    env = DrillStringEnv(start_kick=0.1, **SHORT)
    ratios = np.array([env.reset(seed=s)[1]["bit_speed"] / settled for s in range(20)])
    assert ratios.min() < 0.97 and ratios.max() > 1.03
    assert np.all(np.abs(ratios - 1.0) <= 0.1 + 1e-12)


def test_paper_startup_counts_episode_time_from_the_hand_over():
    env = DrillStringEnv(startup="paper", **SHORT)
    _, info = env.reset(seed=0)
    assert info["episode_time"] == 0.0 and info["time"] == pytest.approx(20.0)
    _, _, _, _, info = env.step(np.zeros(2))
    assert info["episode_time"] == pytest.approx(0.1)
    assert info["time"] == pytest.approx(20.1)


def test_each_reward_weight_scales_its_own_term():
    """The same episode with other reward weights: the physics does not change, so each
    term scales by its weight's ratio (the tests used the default weights only)."""
    weights = {"rop_weight": 2.5, "stick_slip_weight": 3.0, "whirl_weight": 4.0,
               "effort_weight": 0.5}
    terms = {"rop": "rop_weight", "stick_slip": "stick_slip_weight", "whirl": "whirl_weight",
             "effort": "effort_weight"}
    actions = np.random.default_rng(1).uniform(-1, 1, (8, 2))
    runs = []
    for kwargs in ({}, weights):
        env = DrillStringEnv(scenario="stick_slip", **kwargs, **SHORT)
        env.reset(seed=0)
        runs.append([env.step(a)[4]["reward_terms"] for a in actions[:5]])
    default = DrillStringEnv(**SHORT).config
    for plain, weighted in zip(*runs, strict=True):
        for term, weight in terms.items():
            ratio = weights[weight] / getattr(default, weight)
            assert weighted[term] == pytest.approx(ratio * plain[term], rel=1e-12, abs=1e-300)
    assert all(abs(step[t]) > 0 for step in runs[0][1:] for t in ("rop", "effort"))


def test_a_failure_is_terminated_not_truncated_and_a_truncation_pays_no_failure():
    """Gymnasium: ``terminated`` on the failure (the make-up torque), ``truncated`` only at
    the time limit, not both on one step; the failure weight is paid on a termination
    only."""
    env = DrillStringEnv(makeup_torque=1.0, episode_duration=0.1)
    env.reset(seed=0)
    _, _, terminated, truncated, info = env.step(np.zeros(2))
    assert terminated and not truncated
    assert info["reward_terms"]["failure"] == -env.config.failure_weight
    env = DrillStringEnv(episode_duration=0.1)
    env.reset(seed=0)
    _, _, terminated, truncated, info = env.step(np.zeros(2))
    assert truncated and not terminated and info["reward_terms"]["failure"] == 0.0


def test_the_macroscopic_id_refuses_physics_that_asks_for_the_other_bit():
    """DrillStringMacro-v0 is the macroscopic bit; physics={"bit_model": "mesoscopic"}
    was overridden by the id's own without a word (an outside check). Refused by name;
    the same model given twice is fine."""
    env = gym.make("DrillStringMacro-v0")
    assert env.unwrapped.sim.config.bit_model == "macroscopic"
    with pytest.raises(ValueError, match=r"physics.bit_model: 'mesoscopic' against "
                                         r"bit_model='macroscopic'"):
        gym.make("DrillStringMacro-v0", physics={"bit_model": "mesoscopic"})
    same = gym.make("DrillStringMacro-v0", physics={"bit_model": "macroscopic"})
    assert same.unwrapped.sim.config.bit_model == "macroscopic"


def test_a_misspelt_keyword_of_the_plain_env_gets_the_field_it_was_meant_to_be():
    # an outside check: the refusal listed every field but suggested none, where config
    # errors and the tasks' keywords do
    with pytest.raises(ValueError, match=r"^DrillStringEnv: unknown argument\(s\) "
                                         r"\['whirl_wieght'\] \(did you mean whirl_weight\?\)"):
        gym.make("DrillString-v0", whirl_wieght=1.0)
    with pytest.raises(ValueError, match=r"\(did you mean string_length\?\)"):
        gym.make("DrillString-v0", string_lenght=1300.0)


def test_a_configs_plausibility_warning_points_at_the_users_line():
    """A mud density typed in ppg warned from pydantic's dataclass module (a new user's
    trial): the warning points at the line that built the env, as the env's own do."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        gym.make("DrillString-v0", physics={"mud.density": 10.0})
    said = [w for w in caught if "mud.density: 10 kg/m^3" in str(w.message)]
    assert said and all(w.filename == __file__ for w in said)


def test_a_step_past_the_episodes_end_is_said() -> None:
    """From an RL researcher's review: a single env stepped on after its truncation went
    on silently (the vector envs raise ResetNeeded; Gymnasium leaves it undefined and
    its own CartPole warns, as this does)."""
    env = gym.make("DrillString-v0", episode_duration=0.3)
    env.reset(seed=0)
    truncated = False
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # nothing said within the episode
        while not truncated:
            *_, truncated, _ = env.step(env.action_space.sample())
    with pytest.warns(UserWarning, match="past the episode's end"):
        env.step(env.action_space.sample())
    env.reset(seed=0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        env.step(env.action_space.sample())  # a new episode: nothing said


def test_a_step_past_a_terminated_episode_is_said() -> None:
    """A Gymnasium conformance trial: after a termination (a connection twisted off) a
    hand-written loop that forgot to reset went on silently, the failure penalty summed
    again every step. It is said, with the episode's reason; a reset clears it."""
    env = gym.make("DrillString-v0", makeup_torque=5000.0, episode_duration=3.0)
    env.reset(seed=0)
    push = np.ones(2, np.float32)  # the top of both ranges: past the make-up torque
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        while not (result := env.step(push))[2]:
            pass
    reason = result[4]["termination_reason"]
    assert reason and not result[3]
    with pytest.warns(UserWarning, match=rf"past the episode's end \(terminated: "
                                         rf"{re.escape(reason)}\): call reset"):
        env.step(push)
    env.reset(seed=0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        env.step(np.zeros(2, np.float32))


def test_a_step_past_a_buckled_string_s_end_is_said_with_its_percent_sign() -> None:
    """A fuzzing walkthrough: the buckled string's reason holds a percentage ("to 80 % of
    its own buckling load"), which gymnasium's logger read as a format: the step past the
    end raised TypeError ("not enough arguments for format string") instead of warning."""
    env = gym.make("DrillString-v0", limit_weight_on_bit_to_mesh=False,
                   weight_on_bit_range=(0.0, 1e6))
    env.reset(seed=0)
    while not (result := env.step(np.ones(2)))[2]:
        pass
    reason = result[4]["termination_reason"]
    assert reason.startswith("string buckled beyond the mesh resolution") and "%" in reason
    with pytest.warns(UserWarning, match=re.escape(f"past the episode's end (terminated: "
                                                   f"{reason}): call reset")):
        env.step(np.ones(2))


def test_every_step_past_a_termination_is_said(monkeypatch) -> None:
    """A review: the warning kept the reason only while each later step terminated again
    (the make-up torque is judged afresh every step), so a one-off end warned once. Here
    the episode ends at its second step for a reason not judged again: steps 3 and 4 both
    warn."""
    env = DrillStringEnv(episode_duration=3.0)
    calls = iter(["", "an end judged once"])
    monkeypatch.setattr(env, "_termination_reason", lambda step: next(calls, ""))
    env.reset(seed=0)
    action = np.zeros(2, np.float32)
    assert not env.step(action)[2] and env.step(action)[2]
    for _ in range(2):
        with pytest.warns(UserWarning, match=r"\(terminated: an end judged once\)"):
            assert not env.step(action)[2]


def test_action_for_steps_toward_set_points_in_incremental_mode():
    """An outside check: a task-2 run trained with action_mode incremental could not be
    evaluated, every classical controller failing with "action_for: needs action_mode
    'absolute'". In incremental mode the action is the step toward the set points, at
    most one rpm_step / weight_on_bit_step, zero where they are."""
    from drill_env.physics.units import RPM

    env = gym.make("DrillString-v0", action_mode="incremental", rpm_step=5.0,
                   weight_on_bit_step=10e3, **SHORT).unwrapped
    _, info = env.reset(seed=0)
    speed, wob = env.targets
    np.testing.assert_array_equal(env.action_for(speed, wob), [0.0, 0.0])
    np.testing.assert_allclose(env.action_for(speed + 2.5 * RPM, wob - 30e3), [0.5, -1.0])
    goal = (speed + 12.0 * RPM, wob - 25e3)
    for _ in range(3):
        _, _, _, _, info = env.step(env.action_for(*goal))
    assert info["speed_setpoint"] == pytest.approx(goal[0], rel=1e-6)
    assert info["weight_on_bit_setpoint"] == pytest.approx(goal[1], rel=1e-6)
    top = env.action_for(1e3, 1e9)  # beyond the ranges: toward their ends
    assert top.tolist() == [1.0, 1.0]


@pytest.mark.parametrize("scenario, limit", [("stick_slip", 6.0e3), ("default", 5.0e3)])
def test_a_failure_costs_each_step_it_cuts_off_at_the_episodes_worst(scenario, limit):
    """The docstring's failure term: ``-failure_weight``, less each step cut off at the
    episode's lowest step reward so far where that is below 0 (an outside review: a bare
    -10 made ending a costly episode early pay). Recomputed from the steps' own reward
    terms: the stalled stick-slip string at the top of both ranges fails at step 5 of 30
    after steps costing up to ~2 (charged); the default string drills there at a profit
    until it fails (its worst step above 0: the bare weight)."""
    env = gym.make("DrillString-v0", scenario=scenario, makeup_torque=limit,
                   episode_duration=3.0, startup="stalled" if scenario == "stick_slip"
                   else "settled")
    env.reset(seed=0)
    worst, steps = float("inf"), 0
    while True:
        _, reward, terminated, truncated, info = env.step(np.ones(2, np.float32))
        terms, steps = info["reward_terms"], steps + 1
        worst = min(worst, sum(v for k, v in terms.items() if k != "failure"))
        if terminated or truncated:
            break
    assert terminated and steps < env.unwrapped.max_episode_steps
    cut_off = env.unwrapped.max_episode_steps - steps
    want = -10.0 - cut_off * max(0.0, -worst)
    assert terms["failure"] == pytest.approx(want, rel=1e-12, abs=1e-12)
    assert reward == pytest.approx(sum(terms.values()), rel=1e-12, abs=1e-12)
    assert (worst < -1.0) == (scenario == "stick_slip")  # the cases do what they say
