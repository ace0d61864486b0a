"""Batched env: same trajectories as single envs, Gymnasium autoreset, SB3 VecEnv."""

import copy
import pickle
import re
import sys

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import drill_env  # noqa: F401  (registers the ids)
from drill_env.env import DrillStringEnv
from drill_env.vector import DrillStringVectorEnv, make_sb3_vec_env

N = 4
KW = {"episode_duration": 0.3}


def actions_for(n_steps, seed=0):
    return np.random.default_rng(seed).uniform(-1, 1, size=(n_steps, N, 2)).astype(np.float32)


def single_trajectories(actions, seed, **kwargs):
    out = []
    for i in range(N):
        env = DrillStringEnv(**kwargs)
        obs, _ = env.reset(seed=seed + i)
        rows = [obs]
        for a in actions[:, i]:
            obs, reward, terminated, truncated, info = env.step(a)
            rows.append(np.concatenate([obs, [reward, info["time"], info["bit_speed"]]]))
            if terminated or truncated:
                break
        out.append(np.concatenate(rows))
    return out


def test_make_vec_uses_the_vector_entry_point():
    envs = gym.make_vec("DrillString-v0", num_envs=N, vectorization_mode="vector_entry_point",
                        **KW)
    assert isinstance(envs.unwrapped, DrillStringVectorEnv)
    assert envs.num_envs == N
    assert envs.observation_space.shape == (N, 17)
    assert envs.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    obs, info = envs.reset(seed=0)
    assert obs.shape == (N, 17) and obs.dtype == np.float32
    assert info["time"].shape == (N,)


def assert_batch_follows_single_envs(actions, seed, **kwargs):
    """The vector env's observations, rewards, times and bit speeds over ``actions``
    (up to the first episode end, which the envs must reach together) are those of single
    envs seeded ``seed + i``. Returns the last step's (terminated, truncated, info)."""
    singles = single_trajectories(actions, seed=seed, **kwargs)
    envs = DrillStringVectorEnv(num_envs=N, **kwargs)
    obs, _ = envs.reset(seed=seed)
    rows = [[obs[i]] for i in range(N)]
    for a in actions:
        obs, rewards, terminated, truncated, info = envs.step(a)
        for i in range(N):
            rows[i].append(np.concatenate([obs[i], [rewards[i], info["time"][i],
                                                    info["bit_speed"][i]]]))
        if (terminated | truncated).any():
            break
    for i in range(N):
        np.testing.assert_array_equal(np.concatenate(rows[i]), singles[i])
    return terminated, truncated, info


@pytest.mark.parametrize("scenario", ["default", "random"])
def test_batched_env_matches_single_envs_bit_for_bit(scenario):
    assert_batch_follows_single_envs(actions_for(5), 10, **dict(KW, scenario=scenario,
                                                                episode_duration=0.5))


def test_a_control_step_longer_than_the_metric_window_batches_as_single_envs():
    """A step's records must fit the window's buffer (batching: the batch reserves each
    window's room before its compiled call, as ``RollingMetrics.update`` does alone):
    0.5 s steps bring 25 records to a 0.1 s window of 5, whose buffer holds 10."""
    assert_batch_follows_single_envs(actions_for(3), 10, episode_duration=5.0,
                                     control_interval=0.5, metric_window=0.1)


def test_batched_env_matches_single_envs_across_autoresets():
    """After an autoreset each env has a new metric window (and, randomised, a new
    simulator): the batch must re-point its slots and still follow the single envs."""
    kwargs = dict(KW, scenario="random")  # 3 control steps per episode
    actions = actions_for(8, seed=3)
    envs = DrillStringVectorEnv(num_envs=N, **kwargs)
    obs, _ = envs.reset(seed=20)
    got = [obs]
    for a in actions:
        obs, rewards, terminated, truncated, info = envs.step(a)
        got.append(np.concatenate([obs, rewards[:, None], info["ssi"][:, None],
                                   info["time"][:, None]], axis=1))
    for i in range(N):
        env = DrillStringEnv(**kwargs)
        obs, _ = env.reset(seed=20 + i)
        np.testing.assert_array_equal(got[0][i], obs)
        done = False
        for k, a in enumerate(actions[:, i]):
            if done:  # NEXT_STEP: this step resets, the action is ignored
                obs, info = env.reset()
                row, done = np.concatenate([obs, [0.0, info["ssi"], info["time"]]]), False
            else:
                obs, reward, terminated, truncated, info = env.step(a)
                row = np.concatenate([obs, [reward, info["ssi"], info["time"]]])
                done = terminated or truncated
            np.testing.assert_array_equal(got[k + 1][i], row)
    assert envs._batch._windows._keys != [None] * N  # the windows went through the slots


def test_next_step_autoreset_returns_the_reset_observation_with_zero_reward():
    envs = DrillStringVectorEnv(num_envs=N, **KW)  # 3 control steps per episode
    envs.reset(seed=0)
    zero = np.zeros((N, 2))
    for _ in range(2):
        _, _, _, truncated, _ = envs.step(zero)
        assert not truncated.any()
    _, _, terminated, truncated, info = envs.step(zero)
    assert truncated.all() and not terminated.any()
    assert info["time"] == pytest.approx(np.full(N, 0.3))
    obs, rewards, terminated, truncated, info = envs.step(zero)
    assert np.all(rewards == 0.0) and not truncated.any()
    assert info["time"] == pytest.approx(np.zeros(N))  # reset happened
    _, _, _, _, info = envs.step(zero)
    assert info["time"] == pytest.approx(np.full(N, 0.1))


def test_next_step_autoreset_ignores_the_action_of_a_resetting_env():
    """As Gymnasium's SyncVectorEnv: the step that resets a finished env does not read its
    action (a NaN placeholder there is fine); the other envs' actions are still checked."""
    envs = DrillStringVectorEnv(num_envs=N, **KW)
    envs.reset(seed=0)
    zero = np.zeros((N, 2))
    for _ in range(3):
        _, _, _, truncated, _ = envs.step(zero)
    assert truncated.all()
    placeholder = np.full((N, 2), np.nan)
    obs, rewards, _, _, info = envs.step(placeholder)
    assert np.all(rewards == 0.0) and np.isfinite(obs).all()
    assert info["time"] == pytest.approx(np.zeros(N))
    stepping = zero.copy()
    stepping[1] = np.nan  # env 1 runs in this step: its NaN is refused
    with pytest.raises(ValueError, match="env 1"):
        envs.step(stepping)
    # envs out of step: 0 and 2 end their episode a step before 1 and 3 do
    envs.reset(seed=0)
    envs.step(zero)
    envs.reset(options={"reset_mask": np.array([False, True, False, True])})
    envs.step(zero)
    _, _, _, truncated, _ = envs.step(zero)
    assert truncated.tolist() == [True, False, True, False]
    mixed = zero.copy()
    mixed[0] = np.nan  # env 0 resets in the next step: not read
    envs.step(mixed)  # the step that resets 0 and 2 and ends 1 and 3
    mixed[0] = 0.0
    mixed[1] = np.nan  # env 1 resets now, but env 2 runs
    mixed[2] = np.nan
    with pytest.raises(ValueError, match="env 2"):
        envs.step(mixed)


def test_vector_env_seeds_and_metadata_are_sync_vector_envs():
    """np_random_seed, np_random and metadata as Gymnasium's SyncVectorEnv gives them."""
    kw = {"episode_duration": 0.3, "scenario": "random"}
    ours = DrillStringVectorEnv(num_envs=2, **kw)
    sync = gym.make_vec("DrillString-v0", num_envs=2, vectorization_mode="sync", **kw)
    for envs in (ours, sync):
        envs.reset(seed=3)
    assert ours.np_random_seed == sync.np_random_seed == (3, 4)
    assert all(g is env.np_random for g, env in zip(ours.np_random, ours.envs, strict=True))
    assert ours.metadata["render_fps"] == sync.metadata["render_fps"] == 10.0
    assert ours.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    a, _ = ours.reset(seed=np.array([5, 6]))  # an array of seeds, as a list
    b, _ = ours.reset(seed=[5, 6])
    np.testing.assert_array_equal(a, b)
    assert ours.np_random_seed == (5, 6)


def test_same_step_autoreset_reports_final_obs_and_info():
    envs = DrillStringVectorEnv(num_envs=N, autoreset_mode=AutoresetMode.SAME_STEP, **KW)
    envs.reset(seed=0)
    zero = np.zeros((N, 2))
    for _ in range(2):
        envs.step(zero)
    obs, _, _, truncated, info = envs.step(zero)
    assert truncated.all()
    assert info["_final_obs"].all()
    assert info["final_obs"][0].shape == (17,)
    assert info["final_info"]["time"] == pytest.approx(np.full(N, 0.3))
    assert info["time"] == pytest.approx(np.zeros(N))


def test_reset_mask_resets_only_the_masked_envs():
    envs = DrillStringVectorEnv(num_envs=N, **KW)
    envs.reset(seed=0)
    envs.step(np.zeros((N, 2)))
    mask = np.array([True, False, True, False])
    _, info = envs.reset(options={"reset_mask": mask})
    assert info["_time"].tolist() == mask.tolist()
    times = envs.get_attr("sim")
    assert [s.time for s in times] == pytest.approx([0.0, 0.1, 0.0, 0.1])
    # options that are no dict: named, as a single env names them (dict() of a list was a
    # TypeError about "dictionary update sequence", a fuzzing walkthrough)
    with pytest.raises(ValueError, match=r"^reset options: must be a dict, got \[1, 2\]"):
        envs.reset(options=[1, 2])


def test_set_attr_sets_one_value_per_env_or_one_for_all_as_gymnasium_does():
    envs = DrillStringVectorEnv(num_envs=N, **KW)
    envs.set_attr("tag", list(range(N)))
    assert envs.get_attr("tag") == tuple(range(N))
    envs.set_attr("tag", "same")
    assert envs.get_attr("tag") == ("same",) * N
    reference = gym.vector.SyncVectorEnv([lambda: gym.make("DrillString-v0", **KW)] * 2)
    reference.set_attr("tag", "same")
    assert reference.get_attr("tag") == ("same", "same")
    with pytest.raises(ValueError, match="values: expected one per env"):
        envs.set_attr("tag", [1, 2])


def test_nan_action_in_a_batch_names_the_env():
    envs = DrillStringVectorEnv(num_envs=N, **KW)
    envs.reset(seed=0)
    actions = np.zeros((N, 2))
    actions[2, 1] = np.nan
    with pytest.raises(ValueError, match="env 2"):
        envs.step(actions)
    with pytest.raises(ValueError, match="actions: expected numbers"):
        envs.step([["fast", "heavy"]] * N)


def test_an_infinite_action_in_a_batch_names_the_env_as_a_nan_does():
    # drill_env/batching.py check_actions: a non-finite action of an active env is a
    # ValueError naming it; +inf and -inf each move only one end of the batch's range
    envs = DrillStringVectorEnv(num_envs=N, **KW)
    envs.reset(seed=0)
    for bad in (np.inf, -np.inf):
        actions = np.zeros((N, 2))
        actions[1, 0] = bad
        with pytest.raises(ValueError, match="env 1"):
            envs.step(actions)


def test_the_vector_envs_arguments_are_refused_by_name():
    """From a fuzz of the API: a float seed was a TypeError, a snake-case autoreset mode
    was refused without the valid ones, ``num_envs=True`` made one env, a step before
    the first reset ran on envs with no episode, finite actions of 1e308 overflowed the
    finiteness check's sum (a RuntimeWarning)."""
    import warnings

    from gymnasium.error import ResetNeeded

    envs = DrillStringVectorEnv(num_envs=2, **KW)
    with pytest.raises(ResetNeeded, match="reset"):
        envs.step(np.zeros((2, 2)))
    with pytest.raises(ValueError, match=r"^seed: an integer or a list of num_envs=2 seeds, "
                                         r"got 1\.5"):
        envs.reset(seed=1.5)
    envs.reset(options={"reset_mask": np.array([True, False])})
    with pytest.raises(ResetNeeded, match=r"envs \[1\] have no episode"):
        envs.step(np.zeros((2, 2)))
    envs.reset(options={"reset_mask": np.array([False, True])})  # every env in parts
    envs.step(np.zeros((2, 2)))
    envs.reset(seed=0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        envs.step(np.full((2, 2), 1e308))  # clipped to the action range
    assert DrillStringVectorEnv(num_envs=1, autoreset_mode="same_step", **KW) \
        .autoreset_mode == AutoresetMode.SAME_STEP
    with pytest.raises(ValueError, match=r"^autoreset_mode: must be one of 'NextStep', "
                                         r"'SameStep', 'Disabled', got 'later'"):
        DrillStringVectorEnv(num_envs=1, autoreset_mode="later", **KW)
    with pytest.raises(ValueError, match=r"^num_envs: must be a positive integer, got True"):
        DrillStringVectorEnv(num_envs=True, **KW)
    # 10^9 was taken at its word and filled the machine's memory (an outside check)
    from drill_env.vector import MAX_NUM_ENVS, make_sb3_vec_env

    for make in (DrillStringVectorEnv, make_sb3_vec_env):
        with pytest.raises(ValueError, match=rf"^num_envs: at most {MAX_NUM_ENVS}, got "
                                             rf"{MAX_NUM_ENVS + 1} \(each env holds"):
            make(num_envs=MAX_NUM_ENVS + 1, **KW)
        with pytest.raises(ValueError, match=r"^num_envs: must be a positive integer, got 0"):
            make(num_envs=0, **KW)
    # both ends of check_num_envs' range "1-MAX_NUM_ENVS" are taken (its docstring; the
    # check alone: 4,096 envs would hold ~1.6 GiB)
    from drill_env.vector import check_num_envs

    check_num_envs(1)
    check_num_envs(MAX_NUM_ENVS)
    with pytest.raises(ValueError, match=r"^scenario: unknown name \['default'\]"):
        DrillStringVectorEnv(num_envs=1, scenario=["default"])


def test_vector_env_pickles():
    envs = DrillStringVectorEnv(num_envs=2, **KW)
    envs.reset(seed=0)
    envs.step(np.zeros((2, 2)))
    clone = pickle.loads(pickle.dumps(envs))
    a = envs.step(np.full((2, 2), 0.3))
    b = clone.step(np.full((2, 2), 0.3))
    np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_array_equal(a[1], b[1])


@pytest.mark.parametrize("seed", [-1, 1.5, "a", True])
def test_sb3_vec_env_refuses_a_seed_gymnasium_would_refuse_at_reset(seed):
    """SB3's VecEnv.seed took -1, 1.5 and "a", to fail at the next reset in Gymnasium's
    check of env 0 (an outside check of bad input): refused when given, by name."""
    venv = make_sb3_vec_env(2, **KW)
    with pytest.raises(ValueError, match=r"^seed: a whole number >= 0 \(env i gets seed \+ i\)"):
        venv.seed(seed)
    assert venv.seed(5) == [5, 6] and len(venv.seed(None)) == 2
    # a NumPy integer is a seed (as in the Gymnasium batch), handed on as a Python one:
    # Gymnasium's reset refused the np.int64 SB3 passed on (an outside check of the API)
    assert venv.seed(np.int64(5)) == [5, 6]
    venv.reset()


def test_a_refused_reset_of_a_batch_leaves_no_episode_to_step():
    """A reset refused for one env's target out of range left the batch's others to step
    the old episode's state under a new string (an outside check of the API)."""
    from gymnasium.error import ResetNeeded

    for envs in (gym.make_vec("DrillStickSlip-v0", num_envs=2, **KW),
                 make_sb3_vec_env(2, env_id="DrillStickSlip-v0", **KW)):
        def step(e):
            return e.step(np.zeros((2, 1), np.float32))

        if isinstance(envs, DrillStringVectorEnv):
            # arguments refused before any env's reset leave no episode either (an
            # outside review: the old episodes stepped on after a bad seed)
            for bad, said in (({"seed": 1.5}, "seed"), ({"seed": np.array(1.5)}, "seed"),
                              ({"options": [1]}, "options"),
                              ({"options": {"reset_mask": np.array([1, 0])}}, "reset_mask")):
                envs.reset(seed=0)
                step(envs)
                with pytest.raises(ValueError, match=said):
                    envs.reset(**bad)
                with pytest.raises(ResetNeeded, match="reset"):
                    step(envs)
            envs.reset(seed=0)
            step(envs)
            with pytest.raises(ValueError, match="surface_speed"):
                envs.reset(seed=1, options={"surface_speed": 1.0e9})
        else:
            envs.reset()
            step(envs)
            envs.set_options({"surface_speed": 1.0e9})
            with pytest.raises(ValueError, match="surface_speed"):
                envs.reset()
            envs.set_options({})
        with pytest.raises(ResetNeeded, match="reset"):
            step(envs)
        envs.reset()
        step(envs)


def test_sb3_vec_env_pickles_and_its_class_is_importable_by_its_name():
    """From a fuzz of the API: the class was built inside a function, so pickle (which
    looks a class up by module and name) refused it, unlike SB3's own DummyVecEnv."""
    import drill_env.vector as vector

    venv = make_sb3_vec_env(2, **KW)
    assert type(venv) is vector.DrillStringSB3VecEnv
    venv.seed(3)
    venv.reset()
    clone = pickle.loads(pickle.dumps(venv))
    for _ in range(2):
        a, b = venv.step(np.full((2, 2), 0.3)), clone.step(np.full((2, 2), 0.3))
        np.testing.assert_array_equal(a[0], b[0])
        np.testing.assert_array_equal(a[1], b[1])
    with pytest.raises(AttributeError, match="DrillStringSB3Vec'"):
        vector.DrillStringSB3Vec  # noqa: B018  (a misspelt name still fails)


def test_a_per_env_wrapper_for_the_sb3_vec_env_is_refused_with_the_way_to_wrap_it():
    """From a walkthrough: ``wrappers=`` was an unknown env argument, with no word on how
    to reshape a reward on the batched env (docs/tasks.md shows the VecEnvWrapper)."""
    for key in ("wrappers", "wrapper_class"):
        with pytest.raises(ValueError, match=rf"^{key}: the batched VecEnv .* wrap the "
                                             r"VecEnv \(an SB3 VecEnvWrapper"):
            make_sb3_vec_env(2, **{key: [gym.Wrapper]}, **KW)


def test_render_without_a_render_mode_is_none_per_env_as_in_the_sync_vector_env():
    ours = DrillStringVectorEnv(num_envs=2, **KW)
    sync = gym.make_vec("DrillString-v0", num_envs=2, vectorization_mode="sync", **KW)
    for envs in (ours, sync):
        envs.reset(seed=0)
        with pytest.warns(UserWarning, match="render_mode"):
            assert envs.render() == (None, None)


def test_sb3_vec_env_autoresets_with_terminal_observation():
    from stable_baselines3.common.vec_env import VecEnv

    venv = make_sb3_vec_env(N, **KW)
    assert isinstance(venv, VecEnv)
    assert "stable_baselines3" in sys.modules
    venv.seed(7)
    first = venv.reset()
    assert first.shape == (N, 17)
    zero = np.zeros((N, 2), dtype=np.float32)
    for _ in range(2):
        _, _, dones, infos = venv.step(zero)
        assert not dones.any()
        assert all("terminal_observation" not in i for i in infos)
    obs, rewards, dones, infos = venv.step(zero)
    assert dones.all()
    for i, info in enumerate(infos):
        assert info["terminal_observation"].shape == (17,)
        assert info["TimeLimit.truncated"] is True
        assert not np.array_equal(info["terminal_observation"], obs[i])
    # seeds are used once: env i was seeded 7 + i and now runs unseeded episodes
    assert venv.get_attr("sim")[0].time == 0.0


def test_sb3_vec_env_matches_single_envs():
    actions = actions_for(3, seed=1)
    singles = single_trajectories(actions, seed=20, **KW)
    venv = make_sb3_vec_env(N, **KW)
    venv.seed(20)
    obs = venv.reset()
    for i in range(N):
        np.testing.assert_array_equal(obs[i], singles[i][:17])
    for k, a in enumerate(actions):
        obs, rewards, dones, infos = venv.step(a)
        for i in range(N):
            width = 17 + 3
            start = 17 + k * width
            expected = singles[i][start:start + width]
            got_obs = infos[i]["terminal_observation"] if dones[i] else obs[i]
            np.testing.assert_array_equal(got_obs, expected[:17])
            assert rewards[i] == pytest.approx(expected[17], rel=1e-6)  # SB3 stores float32


def test_sb3_can_run_a_few_ppo_steps_on_the_vec_env():
    from stable_baselines3 import PPO

    venv = make_sb3_vec_env(2, **KW)
    model = PPO("MlpPolicy", venv, n_steps=8, batch_size=8, n_epochs=1, seed=0, device="cpu")
    before = [w.detach().clone() for w in model.policy.parameters()]
    model.learn(total_timesteps=16)
    assert model.num_timesteps == 16  # one rollout, 8 steps of 2 envs, then an update
    after = list(model.policy.parameters())
    assert all(bool(w.isfinite().all()) for w in after)
    assert any(not bool((a == b).all()) for a, b in zip(after, before, strict=True))


def _assert_same_infos(a: dict, b: dict) -> None:
    assert list(a) == list(b)
    for key in a:
        if isinstance(a[key], dict):
            _assert_same_infos(a[key], b[key])
        else:
            assert a[key].dtype == b[key].dtype, key
            for x, y in zip(a[key], b[key], strict=True):
                np.testing.assert_array_equal(np.asarray(x, dtype=object),
                                              np.asarray(y, dtype=object))


def test_batched_infos_equal_gymnasiums_add_info():
    """The one-pass info batching gives VectorEnv._add_info's layout, key for key."""
    vec = DrillStringVectorEnv(num_envs=4)
    entries = [
        (2, {"a": 1.5, "n": 3, "flag": True, "xy": np.array([1.0, 2.0]), "why": "",
             "terms": {"rop": 0.1, "whirl": -0.2}, "f32": np.float32(0.5)}),
        (0, {"a": 2.5, "xy": np.array([3.0, 4.0]), "why": "torque",
             "terms": {"rop": 0.3}, "only0": None}),
        (3, {"final_obs": np.zeros(3), "final_info": {"a": 9.0}}),
        (3, {"a": -1.0, "n": 7, "flag": False, "f32": np.float32(1.5)}),
    ]
    expected: dict = {}
    for i, info in entries:
        expected = vec._add_info(expected, info, i)
    _assert_same_infos(vec._batch_infos(entries), expected)


def test_uniform_infos_take_the_transposed_path_with_add_infos_layout():
    """One info per env, in order, same keys (every ordinary step): the fast path."""
    vec = DrillStringVectorEnv(num_envs=4)
    entries = [(i, {"a": 0.5 * i, "n": i, "flag": i % 2 == 0, "xy": np.array([i, 2.0 * i]),
                    "why": "torque" if i == 1 else "", "f32": np.float32(i),
                    "terms": {"rop": 0.1 * i, "whirl": -0.2}, "none": None})
               for i in range(4)]
    expected: dict = {}
    for i, info in entries:
        expected = vec._add_info(expected, info, i)
    for _ in range(2):  # the second call reuses the cached layout
        _assert_same_infos(vec._batch_infos(entries), expected)
    assert vec._info_plans


def _same_floats(a, b) -> bool:
    """The same floats bit for bit (-0.0 is not 0.0), except that any NaN equals any NaN:
    compiled code may take a NaN's sign or payload from either operand of a sum."""
    a, b = np.asarray(a), np.asarray(b)
    nan = np.isnan(a)
    return a.shape == b.shape and bool(np.array_equal(nan, np.isnan(b))) and \
        a[~nan].tobytes() == b[~nan].tobytes()


def _assert_same_values(got, expected, where="info"):
    """Equal key for key, in the same order, with the same types and the same floats
    (:func:`_same_floats`)."""
    if isinstance(expected, dict):
        assert list(got) == list(expected), where
        for key in expected:
            _assert_same_values(got[key], expected[key], f"{where}[{key!r}]")
    elif isinstance(expected, np.ndarray):
        assert isinstance(got, np.ndarray) and got.dtype == expected.dtype, where
        if expected.dtype.kind == "f":
            assert _same_floats(got, expected), (where, got, expected)
        else:
            assert got.tolist() == expected.tolist(), where
    elif isinstance(expected, float):
        assert type(got) is float and _same_floats(got, expected), (where, got, expected)
    else:
        assert type(got) is type(expected) and got == expected, (where, got, expected)


def _diverge(env):
    env.sim.ut[5] = np.nan  # a broken state: the kernel stops on it


ARRAY_FINISH_CASES = {
    "default": dict(KW, episode_duration=0.5),
    "surface, incremental": dict(KW, episode_duration=0.5, sensors="surface",
                                 action_mode="incremental"),
    "random scenario": dict(KW, episode_duration=0.5, scenario="random"),
    "make-up torque": dict(KW, episode_duration=0.5, makeup_torque=1.0),
    "diverged env": dict(KW, episode_duration=0.5),
    # a change of WOB that Simulator.prepare checks in Python: a curved hole's loads at
    # every WOB; the mesh check above paper_case2's 235 kN
    "curved hole": dict(KW, episode_duration=0.5, scenario="j_shaped", fidelity="fast"),
    "mesh check": dict(KW, episode_duration=0.5, scenario="paper_case2",
                       weight_on_bit_range=(0.0, 400e3), limit_weight_on_bit_to_mesh=False,
                       drawworks_rate=2e6),
}


@pytest.mark.parametrize("case", list(ARRAY_FINISH_CASES))
def test_array_finish_gives_every_value_of_each_envs_own_step(case):
    """The batch computes observation, reward and info for all envs at once
    (DrillStringEnv.finish_batch): every value, info key and type must be what each env's
    own step gives, in Gymnasium's batched layout and as SB3's dicts."""
    kwargs = ARRAY_FINISH_CASES[case]
    actions = actions_for(5, seed=4)
    poke = 2 if case == "diverged env" else None  # after this step, env 1 is broken
    singles = [DrillStringEnv(**kwargs) for _ in range(N)]
    vec = DrillStringVectorEnv(num_envs=N, **kwargs)
    sb3 = make_sb3_vec_env(N, **kwargs)
    assert DrillStringEnv.finishes_batch(vec.envs)
    for i, env in enumerate(singles):
        env.reset(seed=30 + i)
    vec.reset(seed=30)
    sb3.seed(30)
    sb3.reset()
    for k, a in enumerate(actions):
        steps = [env.step(row) for env, row in zip(singles, a, strict=True)]
        got = vec.step(a)
        obs, rewards, dones, infos = sb3.step(a)
        expected = [np.stack([s[j] for s in steps]) for j in range(4)]
        for j in range(4):
            np.testing.assert_array_equal(got[j], expected[j])
        batched: dict = {}
        for i, s in enumerate(steps):
            batched = vec._add_info(batched, s[4], i)
        _assert_same_values(got[4], batched)
        np.testing.assert_array_equal(rewards, expected[1].astype(np.float32))
        for i, s in enumerate(steps):
            info = dict(infos[i])
            assert info.pop("TimeLimit.truncated") == (s[3] and not s[2])
            if dones[i]:
                np.testing.assert_array_equal(info.pop("terminal_observation"), s[0])
            else:
                np.testing.assert_array_equal(obs[i], s[0])
            _assert_same_values(info, s[4], f"env {i} info")
        if k == poke:
            for env in (singles[1], vec.envs[1], sb3.envs[1]):
                _diverge(env)
        if expected[2].any():  # the vector envs reset a terminated env: stop comparing
            break
    reasons = got[4]["termination_reason"]
    if case == "make-up torque":
        assert k == 0 and expected[2].all() and "make-up torque" in reasons[0]
    elif case == "diverged env":
        assert k == poke + 1 and expected[2][1] and "diverged" in reasons[1]
    elif case == "mesh check":  # an env pushed beyond its mesh is stopped by the check
        assert any("mesh resolution" in r for r in reasons)
    else:
        assert k == len(actions) - 1 and expected[3].all()  # the episodes ran out


def test_envs_that_compute_their_own_step_are_not_finished_as_arrays():
    """A task (its own observation and reward), delayed or noisy observations: the
    batch falls back to each env's own finish_metrics."""
    from drill_env.tasks.stick_slip import StickSlipEnv

    assert not DrillStringEnv.finishes_batch([StickSlipEnv()])
    assert not DrillStringEnv.finishes_batch([DrillStringEnv(telemetry_delay=2)])
    assert not DrillStringEnv.finishes_batch([DrillStringEnv(observation_noise=0.1)])
    assert_batch_follows_single_envs(actions_for(3, seed=5), 40, **dict(
        KW, episode_duration=0.5, observation_noise=0.05))


def test_a_stopped_simulator_in_a_batch_is_read_not_run():
    """A diverged env stepped again (step_batch, as a caller without autoreset would):
    its simulator is stopped, the batch reads it, and the step equals the env's own."""
    from drill_env.batching import EnvBatch, step_batch

    kwargs = dict(KW, episode_duration=0.5)
    singles = [DrillStringEnv(**kwargs) for _ in range(2)]
    batched = [DrillStringEnv(**kwargs) for _ in range(2)]
    for i in range(2):
        singles[i].reset(seed=50 + i)
        batched[i].reset(seed=50 + i)
    batch = EnvBatch(2)
    actions = actions_for(3, seed=6)[:, :2]
    for k, a in enumerate(actions):
        if k == 1:
            _diverge(singles[0])
            _diverge(batched[0])
        steps = [env.step(row) for env, row in zip(singles, a, strict=True)]
        obs, rewards, terminated, truncated, info = step_batch(batched, a, batch)
        np.testing.assert_array_equal(obs, np.stack([s[0] for s in steps]))
        np.testing.assert_array_equal(rewards, [s[1] for s in steps])
        np.testing.assert_array_equal(terminated, [s[2] for s in steps])
        for i, s in enumerate(steps):
            _assert_same_values(info.dicts()[i], s[4], f"step {k} env {i}")
    assert terminated[0] and singles[0].sim.status != 0


def _value(rng, scale):
    """A float that exercises the finish: NaN, infinities, signed zeros, subnormals,
    huge values, or an ordinary one."""
    special = [0.0, -0.0, np.nan, np.inf, -np.inf, 1e308, -1e308, 1e-320, -1e-320, 1.0]
    if rng.random() < 0.35:
        return float(rng.choice(special)) * (scale if rng.random() < 0.5 else 1.0)
    return float(rng.normal() * scale)


@pytest.mark.parametrize("sensors", ["downhole", "surface"])
def test_array_finish_equals_finish_metrics_on_crafted_inputs(sensors):
    """The compiled finish (finish_batch) against its reference, finish_metrics, on
    crafted metrics and readings: NaN, infinities, -0.0, subnormals, every flag
    combination, steps without records, stopped simulators, windows whose bit speed is
    not finite, episodes started at any simulated time. Outputs bit for bit and every
    env's state after it."""
    from drill_env.metrics import Metric
    from drill_env.physics.layout import READ, S

    rng = np.random.default_rng(7 if sensors == "downhole" else 8)
    base = DrillStringEnv(episode_duration=0.5, sensors=sensors, makeup_torque=5e3)
    base.reset(seed=0)
    base.step(np.zeros(2, np.float32))
    n, width = 6, len(base.sim.readings)
    state = ("_step_count", "_status", "_readings", "_last_obs", "_window_metrics",
             "_episode_energy")
    for trial in range(25):
        ours = [copy.deepcopy(base) for _ in range(n)]
        reference = [copy.deepcopy(base) for _ in range(n)]
        n_rec = rng.choice([0, 5], n)
        flags = np.where(n_rec > 0, rng.integers(0, 4, n), 0)
        step = np.array([[_value(rng, 1e3) for _ in Metric] for _ in range(n)])
        window = np.array([[_value(rng, 1.0) for _ in Metric] for _ in range(n)])
        readings = np.array([[_value(rng, 1e3) for _ in range(width)] for _ in range(n)])
        for e in range(n):
            readings[e, READ.STATUS] = rng.choice([0.0, 0.0, 1.0, 2.0])
            effort, speed, energy = _value(rng, 1.0), abs(_value(rng, 10.0)), _value(rng, 1e6)
            count = int(rng.choice([0, base._max_steps - 1]))
            speed_nan = rng.random() < 0.3
            start = _value(rng, 1e3)  # the episode's start (sim.time after the start-up)
            for env in (ours[e], reference[e]):
                env.sim.state[S.STATUS] = readings[e, READ.STATUS]
                env.sim.readings[:] = readings[e]
                env._effort, env._step_count, env._start_time = effort, count, start
                env._speed_target, env._episode_energy = speed, energy
                if speed_nan:
                    env.rolling_metrics.bit_speed[-1] = np.nan
        expected = []
        for e, env in enumerate(reference):
            if n_rec[e]:
                metrics = ((step[e].tolist(), bool(flags[e] & 1)),
                           (window[e].tolist(), bool(flags[e] & 2)))
            else:
                metrics = (None, env.rolling_metrics.window())
            expected.append(env.finish_metrics(*metrics))
        obs, rewards, terminated, truncated, info = DrillStringEnv.finish_batch(
            ours, n_rec, flags, step, window, readings)
        for e, (o, r, te, tr, inf) in enumerate(expected):
            where = f"trial {trial} env {e}"
            assert _same_floats(obs[e], o), where
            _assert_same_values(float(rewards[e]), r, where)
            assert (terminated[e], truncated[e]) == (te, tr), where
            _assert_same_values(info.dicts()[e], inf, where)
            for name in state:
                _assert_same_values(_plain(getattr(ours[e], name)),
                                    _plain(getattr(reference[e], name)), f"{where} {name}")


def test_array_finish_ends_an_episode_on_a_fresh_surface_torque_above_make_up():
    """``DrillStringEnv._termination_reason``: the surface torque above make-up ends the
    episode whether the step's records or the fresh reading show it; the array finish
    reads the fresh reading too (records that peak at 0 N m, a reading of 6 kN m)."""
    from drill_env.metrics import Metric
    from drill_env.physics.layout import READ, S

    base = DrillStringEnv(episode_duration=0.5, makeup_torque=5e3)
    base.reset(seed=0)
    base.step(np.zeros(2, np.float32))
    ours, reference = copy.deepcopy(base), copy.deepcopy(base)
    readings = np.array([base.sim.readings], dtype=np.float64)
    readings[0, READ.STATUS] = 0.0
    readings[0, READ.SURFACE_TORQUE] = 6e3
    step, window = np.zeros((1, len(Metric))), np.zeros((1, len(Metric)))
    reference.sim.state[S.STATUS] = 0.0
    reference.sim.readings[:] = readings[0]
    expected = reference.finish_metrics((step[0].tolist(), True), (window[0].tolist(), True))
    _, _, terminated, _, info = DrillStringEnv.finish_batch(
        [ours], np.array([5]), np.array([3]), step, window, readings)
    assert expected[2] and terminated[0]
    assert info.reasons == [expected[4]["termination_reason"]] == [
        "surface torque above make-up torque"]


def _plain(value):
    """Lists and tuples as nested dicts of their items, so _assert_same_values compares
    them item by item."""
    if isinstance(value, (list, tuple)):
        return {str(k): _plain(v) for k, v in enumerate(value)}
    return value


def test_a_batch_refuses_envs_it_cannot_finish_as_arrays():
    from drill_env.batching import EnvBatch, step_batch

    envs = [DrillStringEnv(**KW), DrillStringEnv(makeup_torque=1.0, **KW)]
    for env in envs:
        env.reset(seed=0)
    with pytest.raises(ValueError, match="finishes_batch"):
        step_batch(envs, np.zeros((2, 2)), EnvBatch(2))  # two configs
    with pytest.raises(ValueError, match="holds 3 envs"):
        step_batch(envs[:1] * 2, np.zeros((2, 2)), EnvBatch(3))


def test_a_batch_call_uses_no_more_threads_than_envs_that_run(monkeypatch):
    """One env that runs goes on the calling thread alone (no worker woken for nothing),
    and numba's thread count is the caller's again afterwards."""
    import numba

    from drill_env.batching import EnvBatch

    # numba's pool, not get_num_threads(): an earlier batch call that left the count at
    # one (the failure this test is about) made it skip
    threads = numba.config.NUMBA_NUM_THREADS
    if threads < 2:
        pytest.skip("one numba thread: nothing to limit")
    numba.set_num_threads(threads)  # (the count a process starts with)
    calls = []
    set_threads = numba.set_num_threads
    monkeypatch.setattr(numba, "set_num_threads", lambda n: (calls.append(n), set_threads(n)))
    envs = [DrillStringEnv(episode_duration=5.0) for _ in range(3)]
    for k, env in enumerate(envs):
        env.reset(seed=k)
    batch = EnvBatch(3)
    batch.run(envs, np.ones(3, dtype=np.bool_))  # first call: record buffers, Python prepare
    for active, expected in (([True, False, False], [1, threads]), ([True] * 3, [])):
        calls.clear()
        out = batch.run(envs, np.array(active))
        assert calls == expected
        assert numba.get_num_threads() == threads
        assert (out.n_rec[np.array(active)] > 0).all()


def test_a_batch_pickled_before_the_schedule_existed_still_runs():
    from drill_env.batching import EnvBatch, Schedule

    state = EnvBatch(2).__getstate__()
    del state["_schedule"]
    old = EnvBatch.__new__(EnvBatch)
    old.__setstate__(state)
    envs = [DrillStringEnv(episode_duration=5.0) for _ in range(2)]
    for k, env in enumerate(envs):
        env.reset(seed=k)
    assert old._schedule.shape == (len(Schedule),)
    fresh = [DrillStringEnv(episode_duration=5.0) for _ in range(2)]
    for k, env in enumerate(fresh):
        env.reset(seed=k)
    want = EnvBatch(2).run(fresh, np.ones(2, dtype=np.bool_)).n_rec
    assert (want > 0).all()
    np.testing.assert_array_equal(old.run(envs, np.ones(2, dtype=np.bool_)).n_rec, want)


@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP,
                                  AutoresetMode.DISABLED])
def test_staggered_episodes_follow_gymnasiums_sync_vector_env(mode):
    """Gymnasium's own SyncVectorEnv of the same envs is the oracle, with episodes out of
    step (a masked reset after the first step, randomised strings, a different action per
    env): observations, rewards, ends and every info entry, step for step, in each
    autoreset mode. Where only some envs step, each must get its own readings; SAME_STEP
    resets only the envs that ended; a masked reset cancels a pending autoreset; DISABLED
    refuses a step while an env is finished (SyncVectorEnv asserts)."""
    kwargs = {"episode_duration": 0.3, "scenario": "random"}  # 3 steps per episode
    ours = DrillStringVectorEnv(num_envs=N, autoreset_mode=mode, **kwargs)
    sync = gym.make_vec("DrillString-v0", num_envs=N, vectorization_mode="sync",
                        vector_kwargs={"autoreset_mode": mode}, **kwargs)
    actions = actions_for(10, seed=5)
    stagger = np.array([False, True, False, True])
    for envs in (ours, sync):
        envs.reset(seed=7)
        envs.step(actions[0])
    got = [ours.reset(options={"reset_mask": stagger.copy()}),
           sync.reset(options={"reset_mask": stagger.copy()})]
    _assert_same_values(got[0][0], got[1][0], "obs")
    _assert_same_infos(got[0][1], got[1][1])
    refused = 0
    for k, a in enumerate(actions[1:], start=1):
        if mode == AutoresetMode.DISABLED and ours._autoreset_envs.any():
            finished = ours._autoreset_envs.copy()
            with pytest.raises(ValueError, match=re.escape(  # (which: a fuzzing walkthrough)
                    f"autoreset is disabled: reset the finished envs "
                    f"{np.flatnonzero(finished).tolist()} (reset_mask)")):
                ours.step(a)  # (SyncVectorEnv asserts, after stepping the envs before
            refused += 1  # the first finished one: it is not asked here)
            got = [ours.reset(options={"reset_mask": finished.copy()}),
                   sync.reset(options={"reset_mask": finished.copy()})]
            _assert_same_values(got[0][0], got[1][0], f"obs after the reset before {k}")
            _assert_same_infos(got[0][1], got[1][1])
        ours_step, sync_step = ours.step(a), sync.step(a)
        for name, x, y in zip(("obs", "reward", "terminated", "truncated"), ours_step[:4],
                              sync_step[:4], strict=True):
            _assert_same_values(x, y, f"{name} at step {k}")
        _assert_same_infos(ours_step[4], sync_step[4])
    if mode == AutoresetMode.DISABLED:
        assert refused >= 3  # both halves of the stagger ended, more than once


def test_the_sb3_vec_env_refuses_a_step_before_its_first_reset():
    """As the Gymnasium batch and SB3's own ``make_vec_env``: a step with no episode ran
    a meaningless one (targets 0, reward -1) without a word."""
    from gymnasium.error import ResetNeeded

    venv = make_sb3_vec_env(1, env_id="DrillStickSlip-v0")
    with pytest.raises(ResetNeeded, match="reset"):
        venv.step(np.zeros((1, 1), np.float32))
    venv.reset()
    venv.step(np.zeros((1, 1), np.float32))
    venv.close()


def test_a_failure_after_costly_steps_is_charged_alike_in_a_batch():
    """A failure costs ``failure_weight`` and each step it cuts off at the episode's lowest
    step reward so far (DrillStringEnv's docstring): the batch's compiled finish
    (``finish_rows``) must charge it as each env's own step does, to the bit. The stalled
    stick-slip string pushed to the top of both ranges passes a 6 kN m make-up torque at
    its 5th step of 30, its steps until then costing up to ~2 each."""
    kwargs = dict(scenario="stick_slip", startup="stalled", makeup_torque=6.0e3,
                  episode_duration=3.0)
    assert DrillStringEnv.finishes_batch(DrillStringVectorEnv(num_envs=N, **kwargs).envs)
    terminated, truncated, info = assert_batch_follows_single_envs(
        np.ones((8, N, 2), dtype=np.float32), 0, **kwargs)
    assert terminated.all() and not truncated.any()
    assert (info["reward_terms"]["failure"] < -20.0).all()  # more than the bare 10
