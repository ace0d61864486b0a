"""Training run settings: one YAML per task and algorithm (rl-zoo3 style), validated.

A file ``training/hyperparams/<task>.yml`` holds one entry per algorithm::

    ppo:
      n_envs: 8
      n_timesteps: 1.0e6
      policy: MlpPolicy
      normalize: {norm_obs: true, norm_reward: true}
      policy_kwargs: {net_arch: [64, 64], log_std_init: -1.0}
      hyperparams: {n_steps: 256, batch_size: 256, gamma: 0.98, ...}

The keys ``n_envs``, ``n_timesteps``, ``policy``, ``normalize`` and ``policy_kwargs`` are
rl-zoo3's; everything that goes to the algorithm's constructor sits under
``hyperparams``. ``env_kwargs`` go to the env.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import BeforeValidator, Field

from drill_env.physics.validation import (
    ConfigError,
    StrictBool,
    config_dataclass,
    did_you_mean,
    flatten,
    from_dict,
    jsonable,
    read_yaml,
)
from drill_env.tasks import TASK_ENVS

HYPERPARAMS = Path(__file__).resolve().parent / "hyperparams"
#: Task name -> env id.
TASKS = TASK_ENVS
#: Seeds: the eval callback uses validation seeds from VALIDATION_SEED; the benchmark of
#: ``drill-env evaluate`` the held-out EVALUATION_SEEDS (drill_env.scenarios, from
#: 1,000,000), never seen in training or in choosing a run's model (task 2's recipe was
#: chosen on them: docs/tasks.md, "Fresh seeds"); the training envs are seeded from
#: TRAINING_SEEDS on (``training.run_folder.env_seed``), above both.
VALIDATION_SEED = 900_000
TRAINING_SEEDS = 2**31

Algo = Literal["ppo", "sac"]


def _whole(value: Any) -> Any:
    """A count as YAML writes it: ``1.5e6`` (a float) is 1500000; a bool or a quoted
    number is refused, not read as 1 or parsed."""
    if isinstance(value, (bool, np.bool_, str)):
        raise ValueError(f"must be a whole number, got {value!r}")
    if isinstance(value, float) and value.is_integer():
        return int(value)
    if not isinstance(value, int) and hasattr(value, "__index__"):  # NumPy integers
        return int(value)
    return value


#: A whole number of steps, envs, episodes or threads (see :func:`_whole`).
Whole = Annotated[int, BeforeValidator(_whole)]


def algo_class(name: str) -> Any:
    """The Stable-Baselines3 class of an ``algo`` name (imported on first use)."""
    from stable_baselines3 import PPO, SAC

    classes = {"ppo": PPO, "sac": SAC}
    if name not in classes:
        raise ValueError(f"algo: {name!r} is not one drill-env trains ({', '.join(classes)}); "
                         "a policy of another algorithm acts as a controller of your own "
                         "(docs/controllers.md)")
    return classes[name]


@config_dataclass
class Normalize:
    """VecNormalize settings (saved beside the model, loaded with it)."""

    norm_obs: StrictBool = True
    norm_reward: StrictBool = True
    clip_obs: Annotated[float, Field(gt=0.0, le=1e6)] = 10.0
    #: Discount of the reward normalisation; None: the algorithm's own ``gamma`` (a
    #: normalisation that discounts otherwise scales the returns the critic learns
    #: unlike its targets). The shipped configs give it.
    gamma: Annotated[float, Field(gt=0.0, le=1.0)] | None = None


@config_dataclass
class TrainConfig:
    """Everything a run depends on (written to ``config.yaml`` in the run folder)."""

    task: Literal["stick_slip", "drilling"]
    algo: Algo = "ppo"
    n_envs: Whole = Field(default=8, ge=1, le=1024)
    n_timesteps: Whole = Field(default=1_000_000, ge=1, le=10**10)
    seed: Whole = Field(default=0, ge=0, lt=VALIDATION_SEED)
    policy: str = "MlpPolicy"
    normalize: Normalize = Normalize()
    policy_kwargs: dict[str, Any] = Field(default_factory=dict)
    hyperparams: dict[str, Any] = Field(default_factory=dict)
    env_kwargs: dict[str, Any] = Field(default_factory=dict)
    #: Evaluate every this many env steps (all envs together) on ``eval_episodes``
    #: validation seeds; the best model is kept as ``best_model.zip``. PPO evaluates
    #: after the update of the rollout that crosses a multiple of it.
    eval_freq: Whole = Field(default=50_000, ge=1, le=10**9)
    eval_episodes: Whole = Field(default=10, ge=1, le=10_000)
    checkpoint_freq: Whole = Field(default=200_000, ge=1, le=10**10)
    #: torch's intra-op threads during the run, re-applied at every env step (numba's
    #: OpenMP layer resets the shared OpenMP thread count at each batched step). 1: the
    #: policy's small per-step batches and the 128x128 updates run faster on one thread
    #: than on two on a 2-core machine (docs/performance.md, "Training on a shared machine"); 0:
    #: leave torch's own setting. Not part of what a resumed run must match.
    torch_threads: Whole = Field(default=1, ge=0, le=1024)
    #: Adam's fused CPU kernel (``torch.optim.Adam(fused=True)``) for the policy's
    #: optimisers, unless ``policy_kwargs`` names another optimiser or its own
    #: ``optimizer_kwargs``: the same update rule in one kernel per step instead of
    #: ~10 tensor ops per parameter; a gradient step 11-14 % shorter for SAC's 64 x 64
    #: networks, 8 % for PPO's 128 x 128 (docs/performance.md, "Time to a policy"). A
    #: model keeps what it was created with (a resumed run too). Needs torch 2.4 or later
    #: (on 2.3 the plain update runs; a model trained with the fused kernel then needs 2.4
    #: to load: its saved optimiser settings name it).
    fused_adam: StrictBool = True

    @property
    def reward_gamma(self) -> float:
        """The discount of the reward normalisation: ``normalize.gamma``, else the
        algorithm's ``gamma`` (its hyperparameter, else its default)."""
        if self.normalize.gamma is not None:
            return self.normalize.gamma
        import inspect

        default = inspect.signature(algo_class(self.algo).__init__).parameters["gamma"].default
        return float(self.hyperparams.get("gamma", default))

    def __post_init__(self) -> None:
        check_algorithm_arguments(self)
        check_env_kwargs(self)

    @property
    def env_id(self) -> str:
        return TASKS[self.task]


#: Constructor arguments that ``training.train.new_model`` sets itself.
_SET_BY_TRAIN = {"self", "policy", "env", "seed", "verbose", "policy_kwargs",
                 "tensorboard_log", "device", "_init_setup_model"}
#: Policy constructor arguments that SB3 sets itself.
_SET_BY_SB3 = {"self", "observation_space", "action_space", "lr_schedule"}
#: Numeric hyperparameters and their ranges (SB3 would fail late, or without the name).
_RANGES: dict[str, tuple[float, float, bool]] = {  # name: (low, high, low included)
    "learning_rate": (0.0, 10.0, False), "n_steps": (1, 10**9, True),
    "batch_size": (1, 10**9, True), "n_epochs": (1, 10**6, True),
    "gamma": (0.0, 1.0, False), "gae_lambda": (0.0, 1.0, True),
    "clip_range": (0.0, 10.0, False), "clip_range_vf": (0.0, 1e6, False),
    "vf_coef": (0.0, 1e6, True), "max_grad_norm": (0.0, 1e9, False),
    "target_kl": (0.0, 1e6, False), "buffer_size": (1, 10**10, True),
    "learning_starts": (0, 10**10, True), "tau": (0.0, 1.0, False),
    "gradient_steps": (-1, 10**6, True), "train_freq": (1, 10**9, True),
    "ent_coef": (0.0, 1e6, True), "target_entropy": (-1e6, 1e6, True),
    "sde_sample_freq": (-1, 10**9, True), "target_update_interval": (1, 10**9, True),
    "stats_window_size": (1, 10**9, True),
    # policy_kwargs.log_std_init: the log of the initial standard deviation of the
    # Gaussian policy over actions in [-1, 1]: below e^-20 it never explores, above e^2
    # (std 7.4) nearly every action lands on a bound
    "log_std_init": (-20.0, 2.0, True),
}
#: The policy for the tasks' observations (vectors; SB3's CnnPolicy takes images, its
#: MultiInputPolicy dicts).
VECTOR_POLICY = "MlpPolicy"
#: Hyperparameters SB3 needs as integers: a YAML ``1e5`` arrives as a float.
_INTEGERS = {"n_steps", "batch_size", "n_epochs", "buffer_size", "learning_starts",
             "gradient_steps", "train_freq", "sde_sample_freq", "target_update_interval",
             "stats_window_size"}
#: Hyperparameters that also take rl-zoo3's linear schedule ``lin_<start>``: from <start>
#: at the first update down to 0 at the end (:class:`LinearSchedule`).
_SCHEDULES = {"learning_rate", "clip_range", "clip_range_vf"}
#: Switches (a quoted "no" is refused, not read as true).
_FLAGS = {"normalize_advantage", "use_sde", "optimize_memory_usage", "use_sde_at_warmup"}
#: Keyword arguments of a buffer class.
_MAPPINGS = {"rollout_buffer_kwargs", "replay_buffer_kwargs"}
#: Python objects (a class, a noise process) that a YAML cannot give: null or left out.
_OBJECTS = {"action_noise", "rollout_buffer_class", "replay_buffer_class"}
#: SB3's None (off, or its default) where it takes one.
_NULLABLE = {"clip_range_vf", "target_kl"} | _MAPPINGS | _OBJECTS


class LinearSchedule:
    """rl-zoo3's ``lin_<start>``: ``start`` times SB3's ``progress_remaining``, which
    falls from 1 at the first update to 0 at the end (the arithmetic of rl-zoo3's
    ``SimpleLinearSchedule``; rl-zoo3 is only a dev extra here). A class, not a closure,
    so that a saved model pickles it by name."""

    def __init__(self, start: float) -> None:
        self.start = start

    def __call__(self, progress_remaining: float) -> float:
        return progress_remaining * self.start

    def __repr__(self) -> str:
        return f"LinearSchedule({self.start!r})"


def schedule_start(text: str) -> float:
    """The start value of a schedule written ``lin_<start>``; ValueError otherwise."""
    kind, _, start = text.partition("_")
    try:
        if kind != "lin":
            raise ValueError
        return float(start)
    except ValueError:
        raise ValueError(f"must be a number or a linear schedule 'lin_<start>' (rl-zoo3's, "
                         f"e.g. lin_3e-4), got {text!r}") from None


def sb3_hyperparams(hyperparams: dict[str, Any]) -> dict[str, Any]:
    """``hyperparams`` (checked by :func:`check_algorithm_arguments`) as the algorithm's
    constructor takes them: schedules as :class:`LinearSchedule`, ``train_freq``'s YAML
    list ``[4, episode]`` as SB3's tuple; a copy."""
    out = dict(hyperparams)
    for key, value in hyperparams.items():
        if key in _SCHEDULES and isinstance(value, str):
            out[key] = LinearSchedule(schedule_start(value))
        elif key == "train_freq" and isinstance(value, list):
            out[key] = tuple(value)
    return out


def _in_range(key: str, value: Any) -> None:
    """ValueError unless ``value`` is a number in ``_RANGES[key]``."""
    low, high, closed = _RANGES[key]
    number = isinstance(value, (int, float)) and not isinstance(value, bool)
    if not (number and math.isfinite(value) and (value >= low if closed else value > low)
            and value <= high):
        raise ValueError(f"must be a number {'>=' if closed else '>'} {low:g} and <= "
                         f"{high:g}, got {value!r}")


def _sac_auto(key: str, value: str) -> None:
    """SAC's string forms: ``ent_coef`` 'auto' or 'auto_<initial value>' (learnt from
    that start), ``target_entropy`` 'auto' (minus the action's dimension)."""
    if value == "auto":
        return
    if key == "ent_coef" and value.startswith("auto_"):
        try:
            start = float(value.removeprefix("auto_"))
        except ValueError:
            start = math.nan
        if start > 0.0 and start <= 1e6:
            return
    forms = "'auto' or 'auto_<initial value > 0>'" if key == "ent_coef" else "'auto'"
    raise ValueError(f"must be a number or {forms}, got {value!r}")


def checked_hyperparameter(algo: str, key: str, value: Any) -> Any:
    """``value`` of hyperparameter ``key`` of ``algo`` as it is kept (a YAML ``1e5``
    count an int); ValueError saying what the key takes."""
    if value is None and key in _NULLABLE:
        return None
    if key in _OBJECTS:
        raise ValueError(f"a Python object that a YAML cannot give; leave it out or null, "
                         f"got {value!r}")
    if key in _FLAGS:
        if not isinstance(value, (bool, np.bool_)):
            raise ValueError(f"must be true or false, got {value!r}")
        return bool(value)
    if key in _MAPPINGS:
        if not isinstance(value, dict):
            raise ValueError(f"must be a mapping of keyword arguments, got {value!r}")
        return value
    if key == "train_freq" and isinstance(value, (list, tuple)):
        if len(value) != 2 or value[1] not in ("step", "episode"):
            raise ValueError(f"must be a whole number or [count, step|episode], got "
                             f"{list(value)!r}")
        count = _whole(value[0])
        _in_range(key, count)
        if not isinstance(count, int):
            raise ValueError(f"must be a whole number, got {value[0]!r}")
        return [count, value[1]]
    if isinstance(value, str):
        if key in _SCHEDULES:
            start = schedule_start(value)
            try:
                _in_range(key, start)
            except ValueError as err:
                raise ValueError(f"the start of {value!r} {err}") from None
            return value
        if algo == "sac" and key in ("ent_coef", "target_entropy"):
            _sac_auto(key, value)
            return value
    if key in _INTEGERS:
        value = _whole(value)
        if not isinstance(value, int):
            raise ValueError(f"must be a whole number, got {value!r}")
    if key in _RANGES:
        _in_range(key, value)
    return value


#: ``policy_kwargs.activation_fn`` by name (YAML holds no classes): torch.nn's module.
ACTIVATIONS = {"tanh": "Tanh", "relu": "ReLU", "elu": "ELU", "leaky_relu": "LeakyReLU",
               "gelu": "GELU", "silu": "SiLU", "selu": "SELU"}


def activation_class(name: Any) -> Any:
    """The torch.nn class a YAML names (``relu``, ``ReLU``, ``nn.ReLU``, ``torch.nn.ReLU``);
    ValueError listing the names otherwise."""
    import torch

    if isinstance(name, type) and issubclass(name, torch.nn.Module):  # given from Python
        return name
    key = str(name).removeprefix("torch.").removeprefix("nn.")
    known = ACTIVATIONS | {v.lower(): v for v in ACTIVATIONS.values()}
    if not isinstance(name, str) or key.lower() not in known:
        raise ValueError(f"must name an activation ({', '.join(ACTIVATIONS)}; or nn.ReLU "
                         f"and the like), got {name!r}")
    return getattr(torch.nn, known[key.lower()])


def sb3_policy_kwargs(policy_kwargs: dict[str, Any]) -> dict[str, Any]:
    """``policy_kwargs`` as Stable-Baselines3 takes them: ``activation_fn`` as the torch
    class the YAML names (ValueError if it names none); a copy."""
    out = dict(policy_kwargs)
    if "activation_fn" in out:
        out["activation_fn"] = activation_class(out["activation_fn"])
    return out


def read_run_config(path: Path) -> dict[str, Any]:
    """A run's saved ``config.yaml`` as a dict of its settings, read by the rules of a
    ``--config`` file (:func:`~drill_env.physics.validation.read_yaml`: ``1e-7`` a
    number, a repeated key refused); ValueError naming the file when it holds none (cut
    short by a full disk or a hand edit: it was a YAML traceback, or a missing
    ``--task`` of a resume that had given one) or a key that is not a run's setting (a
    renamed one was skipped without a word by evaluate and ``learned:RUN``, so the policy
    ran under the defaults, while a resume refused it)."""
    try:
        data = read_yaml(path)
    except ConfigError as err:
        data, problem = None, str(err).removeprefix(f"{path}: ")
    else:
        problem = "" if isinstance(data, dict) and data.get("task") in TASK_ENVS else (
            f"holds no run's settings (a task of {sorted(TASK_ENVS)}), but {data!r:.60}")
    if problem:
        raise ValueError(f"{path}: {problem}; it is written when the run starts: mend a "
                         "hand edit, train it again (--overwrite) or delete the folder")
    known = [f.name for f in dataclasses.fields(TrainConfig)]
    unknown = sorted(set(data) - set(known), key=str)
    if unknown:
        raise ValueError(f"{path}: {unknown[0]}: not a setting of a run"
                         f"{did_you_mean(str(unknown[0]), known)} (a hand edit, or a "
                         f"version that named it otherwise); known: {', '.join(known)}")
    return data


def without_inert_keys(saved: dict[str, Any]) -> dict[str, Any]:
    """A run's saved ``config.yaml`` without the settings that never acted, which the
    checks now refuse: a SAC ``policy_kwargs.log_std_init`` without gSDE (runs from
    before the check carried it). Resuming or evaluating such a run changes nothing."""
    kwargs = saved.get("policy_kwargs") or {}
    if saved.get("algo") == "sac" and "log_std_init" in kwargs and not (
            saved.get("hyperparams") or {}).get("use_sde", False):
        saved = {**saved, "policy_kwargs": {k: v for k, v in kwargs.items()
                                             if k != "log_std_init"}}
    return saved


def check_algorithm_arguments(config: TrainConfig) -> None:
    """``hyperparams`` and ``policy_kwargs`` against the algorithm's and the policy's
    constructors, so a misspelt or impossible value fails before a run folder exists, with
    its YAML path (``ppo.hyperparams.n_epochs``) instead of a traceback from SB3 or torch."""
    import inspect

    algo = algo_class(config.algo)
    where = f"{config.algo}.hyperparams"
    known = set(inspect.signature(algo.__init__).parameters) - _SET_BY_TRAIN
    wrong = []  # every bad key at once (the first alone was said: a walkthrough's n_epoch
    # hid its gamma: high)
    for key, value in list(config.hyperparams.items()):
        if key not in known:
            wrong.append(f"{where}.{key}: not an argument of {algo.__name__}"
                         f"{did_you_mean(key, sorted(known))}")
            continue
        try:
            config.hyperparams[key] = checked_hyperparameter(config.algo, key, value)
        except ValueError as err:
            wrong.append(f"{where}.{key}: {err}")
    if wrong:
        unknown = any("not an argument" in w for w in wrong)
        # (the objects YAML cannot hold are refused by name: not offered as known)
        offered = ", ".join(sorted(known - _OBJECTS))
        raise ConfigError("; ".join(wrong) + (f" (known: {offered})" if unknown else ""))
    if config.algo == "ppo":  # SB3 only warns, then trains on truncated mini-batches
        batch = config.hyperparams.get("batch_size", 64)
        rollout = config.hyperparams.get("n_steps", 2048) * config.n_envs
        if isinstance(batch, int) and isinstance(rollout, int) and batch > rollout:
            raise ConfigError(f"{where}.batch_size: {batch} is more than a rollout holds "
                              f"(n_steps x n_envs = {rollout})")
        if batch == 1 and config.hyperparams.get("normalize_advantage", True):
            # (SB3's AssertionError otherwise: a traceback without the YAML path)
            raise ConfigError(f"{where}.batch_size: 1 cannot normalise the advantages (a "
                              "mini-batch of one has no spread): give 2 or more, or "
                              "normalize_advantage: false")
    if {"buffer_size", "batch_size"} <= known:  # SB3 samples a batch with replacement
        defaults = inspect.signature(algo.__init__).parameters
        batch = config.hyperparams.get("batch_size", defaults["batch_size"].default)
        buffer = config.hyperparams.get("buffer_size", defaults["buffer_size"].default)
        if isinstance(batch, int) and isinstance(buffer, int) and batch > buffer:
            raise ConfigError(f"{where}.buffer_size: {buffer} holds less than one batch "
                              f"(batch_size = {batch}): every batch would repeat transitions")
    policies = getattr(algo, "policy_aliases", {})
    if config.policy not in policies:
        raise ConfigError(f"{config.algo}.policy: must be one of {sorted(policies)}, got "
                          f"{config.policy!r}")
    if config.policy != VECTOR_POLICY:  # (SB3's AssertionError on the first env: a traceback)
        raise ConfigError(f"{config.algo}.policy: the tasks' observations are vectors, for "
                          f"{VECTOR_POLICY}; {config.policy} is for "
                          + ("images" if "Cnn" in config.policy else "dict observations"))
    where = f"{config.algo}.policy_kwargs"
    known = set(inspect.signature(policies[config.policy].__init__).parameters) - _SET_BY_SB3
    for key in config.policy_kwargs:
        if key not in known:
            raise ConfigError(f"{where}.{key}: not an argument of {config.policy} "
                              f"({config.algo}){did_you_mean(key, sorted(known))}; known: "
                              f"{', '.join(sorted(known))}")
    if (config.algo == "sac" and "log_std_init" in config.policy_kwargs
            and not config.hyperparams.get("use_sde", False)):
        # SB3's SAC actor learns its log std from the state; only gSDE takes the value
        raise ConfigError(f"{where}.log_std_init: has no effect on SAC without "
                          "gSDE (the actor's log std is a learned layer, std ~1 at first); "
                          "leave it out or set sac.hyperparams.use_sde: true")
    if "log_std_init" in config.policy_kwargs:  # (1e308: the first action was NaN, a
        try:  # torch error with no field in it)
            _in_range("log_std_init", config.policy_kwargs["log_std_init"])
        except ValueError as err:
            raise ConfigError(f"{where}.log_std_init: {err}") from None
    try:
        sb3_policy_kwargs(config.policy_kwargs)
    except ValueError as err:
        raise ConfigError(f"{where}.activation_fn: {err}") from None
    arch = config.policy_kwargs.get("net_arch")
    layers = arch.items() if isinstance(arch, dict) else [("", arch)] if arch is not None \
        else []
    for name, sizes in layers:
        path = f"{where}.net_arch" + (f".{name}" if name else "")
        if not (isinstance(sizes, list) and all(isinstance(n, int) and not isinstance(n, bool)
                                                and 1 <= n <= 100_000 for n in sizes)):
            raise ConfigError(f"{path}: must be a list of layer widths (integers >= 1), got "
                              f"{sizes!r}")


def check_env_kwargs(config: TrainConfig) -> None:
    """Build the task's env once with ``env_kwargs``, so that a misspelt or impossible
    setting fails with its YAML path (``ppo.env_kwargs: ...``) before a run folder exists,
    not when training starts."""
    if not config.env_kwargs:
        return
    from drill_env.vector import registered

    env_class, defaults = registered(config.env_id)
    try:
        env_class(**{**defaults, **config.env_kwargs}).close()
    except (ValueError, TypeError) as err:
        raise ConfigError(f"env_kwargs: {err}") from None


#: A run's record of what it trained under (written when it starts): the drill-env
#: version and source digest, and what its env resolved
#: (:meth:`drill_env.tasks.base.TaskEnv.settings`: task and env settings with their
#: defaults, the scenario and its parameters, the physics overrides), which a
#: ``config.yaml`` of the keywords given does not hold.
TRAINED_WITH = "trained_with.json"


def trained_settings(env_id: str, env_kwargs: dict[str, Any]) -> dict[str, Any]:
    """The settings an env of task ``env_id`` resolves today from ``env_kwargs`` (one env
    built and closed: ~0.3 s)."""
    from drill_env.tasks.base import TaskEnv
    from drill_env.vector import registered

    env_class, defaults = registered(env_id)
    env = env_class(**{**defaults, **env_kwargs})
    try:
        if not isinstance(env, TaskEnv):
            raise ValueError(f"env_id: {env_id} is not a control task's env")
        return env.settings()
    finally:
        env.close()


def trained_with(config: TrainConfig) -> dict[str, Any]:
    """The record of :data:`TRAINED_WITH` for a run of ``config`` started now."""
    import drill_env
    from drill_env.sweep import source_digest

    return {"drill_env": drill_env.__version__, "source_digest": source_digest("drill_env"),
            "env_id": config.env_id, **trained_settings(config.env_id, config.env_kwargs)}


def read_trained_with(folder: Path) -> dict[str, Any] | None:
    """A run's :data:`TRAINED_WITH` record (None where it has none: a run of a version
    before 2026-12-06); ValueError naming the file where it is damaged."""
    import json

    path = Path(folder) / TRAINED_WITH
    if not path.exists():
        return None
    try:
        record = json.loads(path.read_text(encoding="utf-8"))
    except (ValueError, UnicodeDecodeError) as err:
        record, reason = None, f"is not valid JSON ({err})"
    else:
        reason = f"holds {type(record).__name__}, not a record of settings"
    if not isinstance(record, dict) or not {"task", "env"} <= set(record):
        raise ValueError(f"{path}: {reason}; it is written when the run starts: delete it "
                         "to load the run without the check of its settings")
    return record


def settings_changes(saved: dict[str, Any], now: dict[str, Any]
                     ) -> list[tuple[str, Any, Any]]:
    """(dotted setting, value saved, value now) for each setting of two
    :meth:`~drill_env.tasks.base.TaskEnv.settings` records that differs, :data:`NOT_SET`
    on the side that lacks it. A task or env field added since (not in ``saved``) is not
    a change: a new field's default is meant to keep what the code did before it. The
    scenario, its parameters and the physics overrides are what was given, so one given
    now and not then (a task's new fidelity default) is."""
    sections = (*_FIELDS, "scenario", "scenario_params", "physics")
    old, new = (flatten({k: record[k] for k in sections if record.get(k) not in (None, {})})
                for record in (saved, now))
    keys = sorted({*old, *(k for k in new if k.partition(".")[0] not in _FIELDS)})
    return [(key, old.get(key, NOT_SET), new.get(key, NOT_SET)) for key in keys
            if old.get(key, NOT_SET) != new.get(key, NOT_SET)]


#: The sections of :func:`settings_changes` that are a config class's fields.
_FIELDS = ("task", "env")
#: A setting's value on the side of :func:`settings_changes` that lacks it.
NOT_SET = "(not set)"


def moved_settings(folder: Path, env_id: str, env_kwargs: dict[str, Any]) -> str | None:
    """Where the settings an env of ``env_id`` resolves today from ``env_kwargs`` differ
    from those the run in ``folder`` trained under (its :data:`TRAINED_WITH`: a default
    moved since), each change and the code of the record, in words (``task.history 10
    then, 20 now; trained under drill-env 0.1.0, sources ...``); None where they agree or
    the run has no record. For a resume's refusal and the note of an evaluation."""
    record = read_trained_with(folder)
    if record is None:
        return None
    moved = settings_changes(record, trained_settings(env_id, env_kwargs))
    return f"{changes_text(moved)}; {code_of(record)}" if moved else None


def code_of(record: dict[str, Any]) -> str:
    """``trained under drill-env 0.1.0, sources 9610e400394a8c39`` of a
    :data:`TRAINED_WITH` record (the version alone says little while it stays 0.1.0)."""
    return (f"trained under drill-env {record.get('drill_env', '?')}, sources "
            f"{record.get('source_digest', 'not recorded')}")


def changes_text(changes: Sequence[tuple[str, Any, Any]]) -> str:
    """``task.history 20 then, 10 now; ...`` for :func:`settings_changes`."""
    def shown(value: Any) -> str:
        return value if value is NOT_SET else repr(value)

    return "; ".join(f"{key} {shown(was)} then, {shown(now)} now" for key, was, now in changes)


def left_out_settings(config: TrainConfig, path: str | Path,
                      given: Sequence[str] = ()) -> list[tuple[str, Any]]:
    """The settings (dotted, with the shipped value) that the task's shipped entry for
    ``config.algo`` sets and the file ``path``'s entry leaves out (``given``: set by a
    flag), where ``config`` (the run's, loaded from ``path``) takes them at another value
    (a default: SB3's, the task's, drill-env's) or one not known here (policy and env
    keywords left to SB3 and the env). A file of another shape gives none."""
    task, algo = config.task, config.algo

    def same(key: str, value: Any) -> bool:  # does the run get the shipped value anyway?
        known, got = taken_value(config, key)
        return known and got == value

    mine = read_yaml(Path(path)) or {}
    shipped = read_yaml(HYPERPARAMS / f"{task}.yml") or {}
    if not isinstance(mine, dict) or not isinstance(mine.get(algo), dict):
        return []
    ours = flatten(mine[algo])  # (the entry loaded already: its keys are names)
    return [(key, value) for key, value in flatten(shipped.get(algo, {})).items()
            if key not in ours and key.partition(".")[0] not in given
            and not same(key, jsonable(value))]


def taken_value(config: TrainConfig, key: str) -> tuple[bool, Any]:
    """Whether the value the run ``config`` takes for the dotted setting ``key`` is known
    here, and that value (as JSON): a hyperparameter the config leaves out is SB3's
    default, a policy or env keyword left out its class's (not looked up: unknown)."""
    import inspect

    if key == "normalize.gamma":  # None: the algorithm's gamma (a review: a file giving
        return True, config.reward_gamma  # the shipped 0.98 there was said to differ)
    head, _, rest = key.partition(".")
    if head == "hyperparams":
        sb3 = inspect.signature(algo_class(config.algo).__init__).parameters
        got = config.hyperparams.get(rest, sb3[rest].default if rest in sb3 else None)
        if got is None or got is inspect.Parameter.empty:
            return False, None
        return True, jsonable(got)
    if head in ("policy_kwargs", "env_kwargs"):
        return False, None
    got = jsonable(config).get(head)
    return True, (got.get(rest) if isinstance(got, dict) else got)


def load_config(task: str, algo: str = "ppo", path: str | Path | None = None,
                **overrides: Any) -> TrainConfig:
    """The run config of ``task`` and ``algo`` from ``path`` (default: the task's file in
    ``training/hyperparams``), with ``overrides`` on top."""
    if task not in TASKS:
        raise ConfigError(f"task: must be one of {sorted(TASKS)}, got {task!r}")
    file = Path(path) if path is not None else HYPERPARAMS / f"{task}.yml"
    data = read_yaml(file) or {}
    if not isinstance(data, dict) or not data:
        what = f"a {type(data).__name__}" if data else "nothing"
        raise ConfigError(f"config: {file} holds {what}; it needs one entry per algorithm "
                          f"({algo}: {{n_envs: ..., hyperparams: {{...}}}}), as "
                          "training/hyperparams/<task>.yml has")
    if algo not in data:
        names = [str(k) for k in data]
        if not set(names) & {"ppo", "sac"}:  # not --algo's fault: it was not given (a fuzz)
            upper = [n for n in names if n.lower() in ("ppo", "sac")]
            raise ConfigError(f"config: {file}'s entries {names} name no algorithm "
                              "drill-env trains: ppo or sac"
                              + (f" (lower case: {upper[0]} as {upper[0].lower()})"
                                 if upper else ""))
        raise ConfigError(f"algo: {file} has no entry {algo!r}; it has {sorted(data)}")
    if not isinstance(data[algo], dict):
        shown = "nothing" if data[algo] is None else repr(data[algo])
        raise ConfigError(f"{algo}: {file} gives {shown}; it needs a mapping of "
                          f"settings ({algo}: {{n_envs: ..., hyperparams: {{...}}}})")
    entry = dict(data[algo])
    given = {k: v for k, v in overrides.items() if v is not None}
    # a value of the file that an override replaces is checked all the same: a new user's
    # trial had a typo in it pass for as long as the flag was given (a number's own checks:
    # a section, hyperparams, is checked with the entry's other fields, which it replaces)
    for key in sorted(k for k in given.keys() & entry.keys() if not isinstance(entry[k], dict)):
        _built(task, algo, {key: entry[key]}, ReplacedValueError)
    return _built(task, algo, {**entry, **given}, ConfigError)


def _built(task: str, algo: str, fields: dict[str, Any], error: type[ConfigError]
           ) -> TrainConfig:
    """The :class:`TrainConfig` of ``fields``; ``error`` naming the YAML path where they
    are refused (the entry sits under the algorithm)."""
    try:
        return from_dict(TrainConfig, {"task": task, "algo": algo, **fields})
    except ConfigError as err:
        text = str(err)
        raise error(text if text.startswith(f"{algo}.") else f"{algo}.{text}") from None


class ReplacedValueError(ConfigError):
    """A bad value in a config file under one that an override of :func:`load_config`
    replaces: the file's fault, not the override's."""
