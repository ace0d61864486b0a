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

from pathlib import Path
from typing import Annotated, Any, Literal

import yaml
from pydantic import Field

from drill_env.physics.validation import ConfigError, config_dataclass, from_dict

HYPERPARAMS = Path(__file__).resolve().parent / "hyperparams"
#: Task name -> env id.
TASKS = {"stick_slip": "DrillStickSlip-v0", "drilling": "DrillOptimise-v0"}
#: Seeds: training envs draw below VALIDATION_SEED; the eval callback uses validation
#: seeds; the benchmark of ``drill-env evaluate`` the held-out EVALUATION_SEEDS
#: (drill_env.scenarios), never seen in training or model selection.
VALIDATION_SEED = 900_000

Algo = Literal["ppo", "sac"]


@config_dataclass
class Normalize:
    """VecNormalize settings (saved beside the model, loaded with it)."""

    norm_obs: bool = True
    norm_reward: bool = True
    clip_obs: Annotated[float, Field(gt=0.0, le=1e6)] = 10.0
    gamma: Annotated[float, Field(gt=0.0, le=1.0)] = 0.98


@config_dataclass
class TrainConfig:
    """Everything a run depends on (written to ``config.yaml`` in the run folder)."""

    task: Literal["stick_slip", "drilling"]
    algo: Algo = "ppo"
    n_envs: int = Field(default=8, ge=1, le=1024)
    n_timesteps: int = Field(default=1_000_000, ge=1, le=10**10)
    seed: int = Field(default=0, ge=0, lt=VALIDATION_SEED)
    policy: str = "MlpPolicy"
    normalize: Normalize = Normalize()
    policy_kwargs: dict[str, Any] = Field(default_factory=dict)
    hyperparams: dict[str, Any] = Field(default_factory=dict)
    env_kwargs: dict[str, Any] = Field(default_factory=dict)
    #: Evaluate every this many env steps (all envs together) on ``eval_episodes``
    #: validation seeds; the best model is kept as ``best_model.zip``.
    eval_freq: int = Field(default=50_000, ge=1, le=10**9)
    eval_episodes: int = Field(default=10, ge=1, le=10_000)
    checkpoint_freq: int = Field(default=200_000, ge=1, le=10**10)
    #: torch's intra-op threads during the run, re-applied at every env step (numba's
    #: OpenMP layer resets the shared OpenMP thread count at each batched step). 1: the
    #: policy's small per-step batches and the 128x128 updates run faster on one thread
    #: than on two on a 2-core machine (docs/performance.md, "Training on a shared machine"); 0:
    #: leave torch's own setting. Not part of what a resumed run must match.
    torch_threads: int = Field(default=1, ge=0, le=1024)

    @property
    def env_id(self) -> str:
        return TASKS[self.task]


def load_config(task: str, algo: str = "ppo", path: str | Path | None = None,
                **overrides: Any) -> TrainConfig:
    """The run config of ``task`` and ``algo`` from ``path`` (default: the task's file in
    ``training/hyperparams``), with ``overrides`` on top."""
    if task not in TASKS:
        raise ConfigError(f"task: must be one of {sorted(TASKS)}, got {task!r}")
    file = Path(path) if path is not None else HYPERPARAMS / f"{task}.yml"
    data = yaml.safe_load(file.read_text()) or {}
    if algo not in data:
        raise ConfigError(f"algo: {file} has no entry {algo!r}; it has {sorted(data)}")
    entry = dict(data[algo])
    if "n_timesteps" in entry:
        entry["n_timesteps"] = int(float(entry["n_timesteps"]))
    entry.update({k: v for k, v in overrides.items() if v is not None})
    return from_dict(TrainConfig, {"task": task, "algo": algo, **entry})
