"""Batched drill-string environments: a Gymnasium ``VectorEnv`` and an SB3 ``VecEnv``.

Both hold N :class:`~drill_env.env.DrillStringEnv` instances and step them in three
phases (:func:`drill_env.batching.step_all`): every env maps its action to set points,
all simulators and metric windows run one control interval in ONE numba call, parallel
over envs (``prange``), then every env computes its observation, reward and info (for
plain ``DrillString-v0`` envs all at once, in one compiled call: ``step_arrays``). Each
env keeps its own arrays (meshes may differ, as in the randomised scenario) and runs the
single-env compiled functions, so every env follows bit-for-bit the trajectory it would
follow alone.

- :class:`DrillStringVectorEnv` (``gymnasium.make_vec("DrillString-v0", num_envs=N)``):
  Gymnasium 1.x semantics; ``autoreset_mode`` NEXT_STEP (default: the step after an
  episode end returns the reset observation with reward 0), SAME_STEP (the reset
  happens in the same step; the last observation and info are in ``info["final_obs"]``
  and ``info["final_info"]``) or DISABLED; pass it as a keyword of the env,
  ``gymnasium.make_vec(id, num_envs=N, autoreset_mode="SameStep")`` (Gymnasium refuses
  ``vector_kwargs`` for an env with its own vector entry point).
- ``DrillStringSB3VecEnv`` (:func:`make_sb3_vec_env`): a Stable-Baselines3 ``VecEnv``
  (SB3 cannot take Gymnasium vector envs) with SB3's auto-reset: ``infos[i]
  ["terminal_observation"]`` and ``infos[i]["TimeLimit.truncated"]``. SB3 is imported
  only when this class is first used.
"""

from __future__ import annotations

from collections.abc import Sequence
from itertools import chain
from operator import itemgetter
from typing import Any

import numpy as np
from gymnasium.error import ResetNeeded
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from drill_env.batching import EnvBatch, step_all, step_arrays
from drill_env.env import DrillStringEnv

__all__ = ["DrillStringVectorEnv", "make_sb3_vec_env", "step_all"]


def autoreset_mode_of(mode: Any) -> AutoresetMode:
    """An :class:`AutoresetMode` from itself, its value (``"SameStep"``) or its name in any
    case (``"same_step"``); ValueError listing them otherwise."""
    if isinstance(mode, AutoresetMode):
        return mode
    for member in AutoresetMode:
        if isinstance(mode, str) and mode.replace("_", "").lower() in (
                member.value.lower(), member.name.replace("_", "").lower()):
            return member
    raise ValueError(f"autoreset_mode: must be one of "
                     f"{', '.join(repr(m.value) for m in AutoresetMode)}, got {mode!r}")


#: The most envs one batch takes: 10^9 filled a 24 GiB machine's memory until the kernel
#: ended the process (an outside check); 4,096 hold ~1.6 GiB (0.33-0.40 MiB each after a
#: reset, measured 2026-12-05), where the batched physics call saturates two cores from
#: N = 16 (docs/performance.md) and a 128-core machine from a few hundred.
MAX_NUM_ENVS = 4096


def check_num_envs(num_envs: Any) -> None:
    """ValueError naming ``num_envs`` unless it is an integer in 1-:data:`MAX_NUM_ENVS`."""
    if not isinstance(num_envs, (int, np.integer)) or isinstance(num_envs, bool) \
            or num_envs < 1:
        raise ValueError(f"num_envs: must be a positive integer, got {num_envs!r}")
    if num_envs > MAX_NUM_ENVS:
        raise ValueError(f"num_envs: at most {MAX_NUM_ENVS}, got {num_envs} (each env holds "
                         "~0.4 MiB and the batch's physics call gains nothing past a few "
                         "envs per core)")


class DrillStringVectorEnv(VectorEnv):
    """N drill-string envs stepped together (Gymnasium ``VectorEnv``).

    Args:
        num_envs: number of sub-environments.
        autoreset_mode: an :class:`gymnasium.vector.AutoresetMode`, or its value or name
            in any case (``"same_step"``).
        **env_kwargs: keywords of :class:`~drill_env.env.DrillStringEnv`, the same for all.

    ``reset(seed=s)`` seeds env i with ``s + i`` (as ``SyncVectorEnv``), so env i follows
    exactly the trajectory of a single env reset with ``s + i``. ``info`` is batched:
    one array per key and a boolean mask ``_key``.
    """

    metadata = {"render_modes": ["rgb_array"], "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(self, num_envs: int = 1,
                 autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
                 env_class: type[DrillStringEnv] | str | None = None,
                 **env_kwargs: Any) -> None:
        check_num_envs(num_envs)
        self.autoreset_mode = autoreset_mode_of(autoreset_mode)
        if "max_episode_steps" in env_kwargs:
            raise ValueError("max_episode_steps: the batched vector env ends its episodes "
                             "by episode_duration (s); give that, or "
                             "vectorization_mode='sync' for Gymnasium's TimeLimit")
        cls = env_class_of(env_class)
        self.envs = [cls(**env_kwargs) for _ in range(num_envs)]
        self.num_envs = int(num_envs)
        self._batch = EnvBatch(self.num_envs)
        # a batch finished as arrays (DrillStringEnv.finish_batch) where the envs allow it
        self._as_arrays = DrillStringEnv.finishes_batch(self.envs)
        # the envs' own (render modes and fps), as Gymnasium's SyncVectorEnv copies them
        self.metadata = {**self.envs[0].metadata, "autoreset_mode": self.autoreset_mode}
        self.render_mode = env_kwargs.get("render_mode")  # each env renders its own
        self.single_observation_space = self.envs[0].observation_space
        self.single_action_space = self.envs[0].action_space
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        n_obs = len(self.envs[0].observation_names)
        self._obs = np.zeros((self.num_envs, n_obs), dtype=np.float32)
        self._rewards = np.zeros(self.num_envs, dtype=np.float64)
        self._terminations = np.zeros(self.num_envs, dtype=np.bool_)
        self._truncations = np.zeros(self.num_envs, dtype=np.bool_)
        self._autoreset_envs = np.zeros(self.num_envs, dtype=np.bool_)
        self._info_plans: dict[tuple, tuple] = {}  # see _batch_uniform_infos
        # a step before every env was reset is refused, as a single env's (Gymnasium's
        # OrderEnforcing); it stepped envs that had no episode
        self._has_episode = np.zeros(self.num_envs, dtype=np.bool_)

    def reset(self, *, seed: int | list[int | None] | None = None,
              options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        try:
            seeds, options, mask = self._reset_arguments(seed, options)
        except (ValueError, TypeError):  # a refused reset leaves no episode, as a single
            self._has_episode[:] = False  # env's (old episodes stepped on after a bad seed)
            raise
        entries: list[tuple[int, dict[str, Any]]] = []
        self._has_episode[mask] = False  # until each is reset (a refused one has none)
        for i in np.flatnonzero(mask):
            self._obs[i], info = self.envs[i].reset(seed=seeds[i], options=options or None)
            entries.append((int(i), info))
        infos = self._batch_infos(entries)
        self._has_episode[mask] = True
        self._terminations[mask] = False
        self._truncations[mask] = False
        self._autoreset_envs[mask] = False
        return self._obs.copy(), infos

    def _reset_arguments(self, seed: Any, options: Any
                         ) -> tuple[list[int | None], dict[str, Any], np.ndarray]:
        """``reset``'s seed, options and ``reset_mask`` checked: the seed of each env, the
        options for each env's reset and the mask of the envs to reset."""
        if isinstance(seed, np.ndarray) and seed.ndim == 0:  # a 0-d array: its number
            seed = seed.item()
        if seed is None:
            seeds: list[int | None] = [None] * self.num_envs
        elif isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
            seeds = [int(seed) + i for i in range(self.num_envs)]
        elif not isinstance(seed, (list, tuple, np.ndarray)):
            raise ValueError(f"seed: an integer or a list of num_envs={self.num_envs} seeds, "
                             f"got {seed!r}")
        else:
            seeds = [int(s) if isinstance(s, np.integer) else s for s in list(seed)]
            if len(seeds) != self.num_envs:
                raise ValueError(f"seed: a list needs num_envs={self.num_envs} entries, "
                                 f"got {len(seeds)}")
        if options is not None and not isinstance(options, dict):  # (dict() of a list: a
            # TypeError about "dictionary update sequence")
            raise ValueError(f"reset options: must be a dict, got {options!r}")
        options = dict(options or {})
        mask = options.pop("reset_mask", None)
        if mask is None:
            mask = np.ones(self.num_envs, dtype=np.bool_)
        else:
            mask = np.asarray(mask)
            if mask.shape != (self.num_envs,) or mask.dtype != np.bool_:
                raise ValueError(f"options['reset_mask']: needs a bool array of shape "
                                 f"({self.num_envs},), got {mask.dtype} {mask.shape}")
        return seeds, options, mask

    def step(self, actions) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                     dict[str, Any]]:
        if not self._has_episode.all():
            raise ResetNeeded("step: call reset() first (envs "
                              f"{np.flatnonzero(~self._has_episode).tolist()} have no "
                              "episode: none yet, or their last reset was refused)")
        mode = self.autoreset_mode
        if mode == AutoresetMode.DISABLED and np.any(self._autoreset_envs):
            raise ValueError("autoreset is disabled: reset the finished envs "
                             f"{np.flatnonzero(self._autoreset_envs).tolist()} (reset_mask) "
                             "before stepping")
        resetting = self._autoreset_envs.copy() if mode == AutoresetMode.NEXT_STEP else \
            np.zeros(self.num_envs, dtype=np.bool_)
        stepping = np.flatnonzero(~resetting)
        if stepping.size and self._as_arrays and DrillStringEnv.same_readings(self.envs):
            returned, results = self._step_as_arrays(actions, resetting, stepping)
            if returned is not None:
                return returned
        else:
            results = step_all(self.envs, actions, self._batch, ~resetting)  # checks actions
        entries: list[tuple[int, dict[str, Any]]] = []
        for i in np.flatnonzero(resetting).tolist():
            self._obs[i], info = self.envs[i].reset()
            self._rewards[i] = 0.0
            self._terminations[i] = False
            self._truncations[i] = False
            entries.append((i, info))
        if stepping.size:
            obs, rewards, terms, truncs, infos = zip(*(results[i] for i in stepping),
                                                     strict=True)
            self._obs[stepping] = obs
            self._rewards[stepping] = rewards
            self._terminations[stepping] = terms
            self._truncations[stepping] = truncs
            ended = (mode == AutoresetMode.SAME_STEP
                     and (self._terminations[stepping] | self._truncations[stepping]).any())
            for i, info in zip(stepping.tolist(), infos, strict=True):
                if ended and (self._terminations[i] or self._truncations[i]):
                    entries.append((i, {"final_obs": self._obs[i].copy(), "final_info": info}))
                    self._obs[i], info = self.envs[i].reset()
                entries.append((i, info))
        batched = self._batch_infos(entries)
        self._autoreset_envs = np.logical_or(self._terminations, self._truncations)
        return (self._obs.copy(), self._rewards.copy(), self._terminations.copy(),
                self._truncations.copy(), batched)

    def _step_as_arrays(self, actions, resetting: np.ndarray, stepping: np.ndarray
                        ) -> tuple[tuple | None, list]:
        """The physics and the envs' finish as arrays (``step_batch``). When every env
        stepped and none resets in this step (the usual step): :meth:`step`'s return,
        built from the arrays. Otherwise (None, the per-env results) for its general path.
        """
        obs, rewards, terms, truncs, batch_info = step_arrays(
            self.envs, actions, self._batch, ~resetting)  # checks actions
        ends = terms | truncs
        if stepping.size == self.num_envs and not (
                self.autoreset_mode == AutoresetMode.SAME_STEP and ends.any()):
            self._obs[:] = obs
            self._rewards[:] = rewards
            self._terminations[:] = terms
            self._truncations[:] = truncs
            self._autoreset_envs = ends
            return (self._obs.copy(), self._rewards.copy(), self._terminations.copy(),
                    self._truncations.copy(), batch_info.batched()), []
        results: list = [None] * self.num_envs
        for j, (i, info) in enumerate(zip(stepping.tolist(), batch_info.dicts(), strict=True)):
            results[i] = (obs[j], rewards[j], terms[j], truncs[j], info)
        return None, results

    def _batch_infos(self, entries: list[tuple[int, dict[str, Any]]]) -> dict[str, Any]:
        """Gymnasium's batched ``info`` layout for (env index, info) pairs, built in one go.

        The same result as calling ``VectorEnv._add_info`` pair by pair (an array per
        key typed by its first value, a ``_key`` mask, nested dicts recursively,
        ``final_obs`` as an object array), without its per-env, per-key Python loop,
        which cost more than the rest of an env step. The usual step (every env once, in
        order, all with the same keys) is transposed in one go.
        """
        n = self.num_envs
        infos = [info for _, info in entries]
        if not infos:
            return {}
        first_keys = tuple(infos[0])
        if len(infos) == n and [i for i, _ in entries] == list(range(n)) and all(
                tuple(info) == first_keys for info in infos):
            return self._batch_uniform_infos(first_keys, infos)
        index = [i for i, _ in entries]
        keys = dict.fromkeys(chain.from_iterable(infos))  # first-appearance order
        common = set(infos[0]).intersection(*infos[1:])
        # Float keys that every entry has go through one 2D array.
        shared = [k for k in keys if k in common and type(infos[0][k]) is float]
        column = {k: j for j, k in enumerate(shared)}
        if shared:
            getter = itemgetter(*shared) if len(shared) > 1 else lambda info: (info[shared[0]],)
            rows = np.fromiter(chain.from_iterable(getter(info) for info in infos),
                               np.float64, len(infos) * len(shared))
            table = np.zeros((len(shared), n))
            table[:, index] = rows.reshape(len(infos), len(shared)).T
            everywhere = np.zeros((len(shared), n), dtype=np.bool_)
            everywhere[:, index] = True
        out: dict[str, Any] = {}
        for key in keys:
            if key in column:
                out[key] = table[column[key]]
                out[f"_{key}"] = everywhere[column[key]]
                continue
            present = [(i, info[key]) for i, info in entries if key in info]
            where = [i for i, _ in present]
            mask = np.zeros(n, dtype=np.bool_)
            mask[where] = True
            out[key] = self._batch_column(key, where, [value for _, value in present])
            out[f"_{key}"] = mask
        return out

    def _batch_uniform_infos(self, keys: tuple[str, ...], infos: list[dict[str, Any]]
                             ) -> dict[str, Any]:
        """:meth:`_batch_infos` of one info per env, in env order, all with ``keys``.

        The layout (which keys are floats, the output key order) depends only on the
        keys and the first env's value types, so it is worked out once and reused.
        """
        n = self.num_envs
        first = infos[0].values()
        plan_key = (keys, tuple(map(type, first)))
        plan = self._info_plans.get(plan_key)
        if plan is None:
            floats = [j for j, value in enumerate(first) if type(value) is float]
            others = [j for j in range(len(keys)) if j not in set(floats)]
            names = [name for key in keys for name in (key, f"_{key}")]
            plan = self._info_plans[plan_key] = (floats, others, names)
        floats, others, names = plan
        columns = list(zip(*(info.values() for info in infos), strict=True))  # per key
        values: list[Any] = [None] * (2 * len(keys))
        if floats:
            table = np.array(itemgetter(*floats)(columns) if len(floats) > 1 else
                             [columns[floats[0]]], dtype=np.float64)
            for j, row in zip(floats, table, strict=True):
                values[2 * j] = row
        for j in others:
            values[2 * j] = self._batch_column(keys[j], slice(None), columns[j])
        values[1::2] = np.ones((len(keys), n), dtype=np.bool_)  # every env has every key
        return dict(zip(names, values, strict=True))

    def _batch_column(self, key: str, where: list[int] | slice, values: Sequence[Any]) -> Any:
        """The batched array of one key: ``values`` of the envs ``where`` (indices, or
        ``slice(None)`` for every env in order), typed by the first value as
        ``VectorEnv._add_info`` does (nested dicts recursively)."""
        n = self.num_envs
        first = values[0]
        index = range(n)[where] if isinstance(where, slice) else where
        if _object_column(key, first):
            array = np.full(n, None, dtype=object)
            for i, value in zip(index, values, strict=True):
                array[i] = value  # one by one: sequences stay objects
            return array
        if isinstance(first, dict):
            return self._batch_infos(list(zip(index, values, strict=True)))
        array = np.zeros((n, *first.shape), dtype=first.dtype) \
            if isinstance(first, np.ndarray) else np.zeros(n, dtype=type(first))
        array[where] = values
        return array

    # a tuple, as SyncVectorEnv's (which overrides VectorEnv's single values likewise)
    @property
    def np_random_seed(self) -> tuple[int, ...]:  # type: ignore[override]
        """The envs' seeds (as Gymnasium's ``SyncVectorEnv``: each env seeds itself)."""
        return self.get_attr("np_random_seed")

    @property  # type: ignore[misc]
    def np_random(self) -> tuple[np.random.Generator, ...]:  # type: ignore[override]
        """The envs' random generators (as Gymnasium's ``SyncVectorEnv``)."""
        return self.get_attr("np_random")

    def render(self) -> tuple[Any, ...]:
        """Each env's frame (``render_mode="rgb_array"``; None each, with the env's warning,
        without a render mode), as Gymnasium's sync vector env."""
        return tuple(env.render() for env in self.envs)

    def get_attr(self, name: str) -> tuple[Any, ...]:
        """The attribute ``name`` of every sub-environment."""
        return tuple(getattr(env, name) for env in self.envs)

    def set_attr(self, name: str, values: list[Any] | tuple[Any, ...] | Any) -> None:
        """Set ``name`` on every sub-environment: one value each (a list or tuple of
        ``num_envs``), or the same value for all (as Gymnasium's ``SyncVectorEnv``)."""
        if not isinstance(values, (list, tuple)):
            values = [values] * self.num_envs
        if len(values) != self.num_envs:
            raise ValueError(f"values: expected one per env ({self.num_envs}), got "
                             f"{len(values)}")
        for env, value in zip(self.envs, values, strict=True):
            setattr(env, name, value)

    def call(self, name: str, *args: Any, **kwargs: Any) -> tuple[Any, ...]:
        """Call ``name`` (or read it, if not callable) on every sub-environment."""
        out = []
        for env in self.envs:
            attr = getattr(env, name)
            out.append(attr(*args, **kwargs) if callable(attr) else attr)
        return tuple(out)

    def close_extras(self, **kwargs: Any) -> None:
        for env in self.envs:
            env.close()


def _object_column(key: str, first: Any) -> bool:
    """Whether ``VectorEnv._add_info`` batches this key into an object array."""
    return key == "final_obs" or not (isinstance(first, (dict, np.ndarray))
                                      or type(first) in (int, float, bool)
                                      or isinstance(first, np.number))


# --------------------------------------------------------------------------- SB3

_SB3_CLASS: type | None = None


def _sb3_class() -> type:
    """Build the SB3 VecEnv subclass on first use (keeps ``import drill_env`` light)."""
    global _SB3_CLASS
    if _SB3_CLASS is not None:
        return _SB3_CLASS
    from stable_baselines3.common.vec_env import DummyVecEnv

    class DrillStringSB3VecEnv(DummyVecEnv):
        """Stable-Baselines3 ``VecEnv`` over N drill-string envs, batched physics.

        SB3 semantics: ``step`` returns ``(obs, rewards, dones, infos)``; a finished env
        is reset at once, its last observation is ``infos[i]["terminal_observation"]``
        and ``infos[i]["TimeLimit.truncated"]`` tells a time-out from a failure.
        ``seed(s)`` seeds env i with ``s + i`` at the next ``reset``.
        """

        def __init__(self, num_envs: int = 1,
                     env_class: type[DrillStringEnv] | str | None = None,
                     **env_kwargs: Any) -> None:
            check_num_envs(num_envs)
            self.env_class = env_class_of(env_class)
            self.env_kwargs = dict(env_kwargs)
            super().__init__([self._make_env for _ in range(int(num_envs))])
            self._batch = EnvBatch(self.num_envs)
            # a batch finished as arrays (DrillStringEnv.finish_batch) where it can be
            self._as_arrays = DrillStringEnv.finishes_batch(self.envs) and self.keys == [None]

        def _make_env(self) -> DrillStringEnv:
            return self.env_class(**self.env_kwargs)

        def seed(self, seed: int | None = None) -> Sequence[int | None]:
            # refused here, naming it, not at the next reset by Gymnasium's check of env
            # 0 (-1, 1.5 and "a" were taken: an outside check of bad input)
            if seed is not None and (not isinstance(seed, (int, np.integer))
                                     or isinstance(seed, bool) or seed < 0):
                raise ValueError(f"seed: a whole number >= 0 (env i gets seed + i) or None, "
                                 f"got {seed!r}")
            # as a Python int: Gymnasium's reset refuses a NumPy one (SB3 passes it on)
            return super().seed(None if seed is None else int(seed))

        def reset(self):
            self._reset_done = False  # no step after a refused reset
            obs = super().reset()
            self._reset_done = True
            return obs

        def step_async(self, actions) -> None:
            # as the Gymnasium batch and SB3's own make_vec_env: no episode, no step
            if not getattr(self, "_reset_done", False):
                raise ResetNeeded("step: call reset() first (no episode: none yet, or the "
                                  "last reset was refused)")
            super().step_async(actions)

        def step_wait(self):
            if self._as_arrays and DrillStringEnv.same_readings(self.envs):
                return self._step_wait_arrays()
            results = step_all(self.envs, self.actions, self._batch)
            for i, (obs, rew, term, trunc, info) in enumerate(results):
                self.buf_rews[i] = rew
                self.buf_dones[i] = term or trunc
                info["TimeLimit.truncated"] = trunc and not term
                if self.buf_dones[i]:
                    info["terminal_observation"] = obs
                    obs, self.reset_infos[i] = self.envs[i].reset()
                self.buf_infos[i] = info
                self._save_obs(i, obs)
            return (self._obs_from_buf(), np.copy(self.buf_rews), np.copy(self.buf_dones),
                    [dict(info) for info in self.buf_infos])

        def _obs_from_buf(self):
            # SB3 deep-copies its buffer dict (~20 us a step at N = 16): a Box
            # observation's one array, copied; any other space as SB3 does
            if len(self.buf_obs) == 1 and None in self.buf_obs:
                return np.copy(self.buf_obs[None])
            return super()._obs_from_buf()

        def _step_wait_arrays(self):
            """:meth:`step_wait` with the batch's results as arrays (``step_batch``): the
            same values, one dict per env built from them."""
            obs, rewards, terms, truncs, batch_info = step_arrays(self.envs, self.actions,
                                                                  self._batch)
            dones = terms | truncs
            self.buf_rews[:] = rewards
            self.buf_dones[:] = dones
            self.buf_obs[None][:] = obs
            infos = batch_info.dicts()
            for i, info in enumerate(infos):
                info["TimeLimit.truncated"] = bool(truncs[i] and not terms[i])
                if dones[i]:
                    info["terminal_observation"] = obs[i]
                    first, self.reset_infos[i] = self.envs[i].reset()
                    self._save_obs(i, first)
            self.buf_infos = infos
            # fresh dicts every step: nothing else holds them, so no copy (SB3 copies its
            # reused buffers)
            return (self._obs_from_buf(), np.copy(self.buf_rews), np.copy(self.buf_dones),
                    list(infos))

    DrillStringSB3VecEnv.__module__ = __name__
    DrillStringSB3VecEnv.__qualname__ = "DrillStringSB3VecEnv"
    _SB3_CLASS = DrillStringSB3VecEnv
    return _SB3_CLASS


def __getattr__(name: str) -> Any:
    """``drill_env.vector.DrillStringSB3VecEnv``, built on first use: importable by its
    name, and so picklable (pickle finds a class by its module and name)."""
    if name == "DrillStringSB3VecEnv":
        return _sb3_class()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def make_sb3_vec_env(num_envs: int = 1, env_id: str | None = None, **env_kwargs: Any):
    """A Stable-Baselines3 ``VecEnv`` of ``num_envs`` drill-string envs (imports SB3).

    ``env_id``: a registered id (``DrillStickSlip-v0``, ...) whose class and default
    keywords to use; ``env_kwargs`` override its keywords. Default: ``DrillString-v0``.
    For episode returns and lengths in ``info["episode"]`` (what SB3 logs as
    ``ep_rew_mean``), wrap it in SB3's ``VecMonitor``, as ``drill-env train`` does (SB3's
    own ``make_vec_env`` puts a ``Monitor`` in each env instead)."""
    if given := sorted({"wrappers", "wrapper_class"} & set(env_kwargs)):
        raise ValueError(
            f"{given[0]}: the batched VecEnv steps all envs' physics in one call, so a "
            "per-env wrapper cannot sit inside it: wrap the VecEnv (an SB3 VecEnvWrapper; "
            "docs/tasks.md, \"Your own reward on the batched env\"), or use SB3's "
            "make_vec_env(id, wrapper_class=...) without the batching")
    if env_id is not None:
        cls, defaults = registered(env_id)
        env_kwargs = {**defaults, **env_kwargs}
        env_kwargs.setdefault("env_class", cls)
    return _sb3_class()(num_envs=num_envs, **env_kwargs)


def env_class_of(env_class: type[DrillStringEnv] | str | None) -> type[DrillStringEnv]:
    """The env class: a class, ``"module:Class"`` or None (``DrillStringEnv``)."""
    if env_class is None:
        return DrillStringEnv
    if isinstance(env_class, str):
        import importlib

        module, _, name = env_class.partition(":")
        env_class = getattr(importlib.import_module(module), name)
    if not (isinstance(env_class, type) and issubclass(env_class, DrillStringEnv)):
        raise ValueError(f"env_class: must be DrillStringEnv or a subclass, got {env_class!r}")
    return env_class


def registered(env_id: str) -> tuple[type[DrillStringEnv], dict[str, Any]]:
    """Class and default keywords of a registered drill-env id."""
    import gymnasium

    import drill_env  # noqa: F401  (registers the ids)

    spec = gymnasium.spec(env_id)
    entry = spec.entry_point
    if not isinstance(entry, str):
        raise ValueError(f"env_id: {env_id} has no importable entry point")
    return env_class_of(entry), dict(spec.kwargs or {})


def stick_slip_vector_env(num_envs: int = 1, **kwargs: Any) -> DrillStringVectorEnv:
    """``gymnasium.make_vec("DrillStickSlip-v0", num_envs)``: batched task 1."""
    return DrillStringVectorEnv(num_envs, env_class="drill_env.tasks.stick_slip:StickSlipEnv",
                                **kwargs)


def drilling_vector_env(num_envs: int = 1, **kwargs: Any) -> DrillStringVectorEnv:
    """``gymnasium.make_vec("DrillOptimise-v0", num_envs)``: batched task 2."""
    return DrillStringVectorEnv(num_envs, env_class="drill_env.tasks.drilling:DrillingEnv",
                                **kwargs)
