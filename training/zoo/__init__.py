"""rl-zoo3 hyperparameters of the control tasks, built from ``training/hyperparams``:
one source of truth for ``drill-env train`` and the standard rl-zoo3 client::

    python -m rl_zoo3.train --algo ppo --env DrillStickSlip-v0 --gym-packages drill_env \\
        --conf-file training.zoo.ppo

(``training.zoo.sac`` for SAC). rl-zoo3 reads the module's ``hyperparams``: per env id the
flat keys of its YAML format (``n_envs``, ``n_timesteps``, ``policy``, ``normalize``,
``policy_kwargs``, ``env_kwargs`` and the algorithm's arguments). rl-zoo3 builds its own
(unbatched) vector env; ``drill-env train`` uses the batched one.
"""

from __future__ import annotations

from typing import Any

from training.config import TASKS, load_config, sb3_policy_kwargs


def zoo_hyperparams(algo: str) -> dict[str, dict[str, Any]]:
    """``{env_id: flat rl-zoo3 hyperparameters}`` of every task for ``algo``."""
    out = {}
    for task, env_id in TASKS.items():
        cfg = load_config(task, algo)
        n = cfg.normalize
        entry: dict[str, Any] = {
            "n_envs": cfg.n_envs, "n_timesteps": cfg.n_timesteps, "policy": cfg.policy,
            "normalize": f"dict(norm_obs={n.norm_obs}, norm_reward={n.norm_reward}, "
                         f"clip_obs={n.clip_obs}, gamma={cfg.reward_gamma})",
            "policy_kwargs": sb3_policy_kwargs(cfg.policy_kwargs),
            **cfg.hyperparams,
        }
        if cfg.env_kwargs:
            entry["env_kwargs"] = dict(cfg.env_kwargs)
        out[env_id] = entry
    return out
