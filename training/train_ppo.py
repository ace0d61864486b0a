"""Train PPO on DrillString-v0 with the batched SB3 VecEnv; read top to bottom.

    .venv/bin/python -m training.train_ppo --scenario random --total-timesteps 200000

Checkpoints and the final model go to ``logs/ppo_<scenario>/``. The smallest training
script, for reading and for ``scripts/ppo_then_now.py``'s ``train_ppo`` workload: the
plain env, not a control task, with SB3's default PPO and settings of its own. It does
not evaluate; the task runs (``drill-env train``, hyperparameters in
``training/hyperparams/*.yml``, validation and held-out evaluation) are ``training.train``.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from pathlib import Path


@dataclass
class Args:
    scenario: str = "random"
    num_envs: int = 8
    total_timesteps: int = 200_000
    episode_duration: float = 30.0
    seed: int = 0
    out: Path = Path("logs")


def parse() -> Args:
    parser = argparse.ArgumentParser(description=__doc__)
    for name, default in Args().__dict__.items():
        parser.add_argument(f"--{name.replace('_', '-')}", type=type(default), default=default)
    return Args(**vars(parser.parse_args()))


def train(args: Args):
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import CheckpointCallback

    from drill_env.vector import make_sb3_vec_env

    out = args.out / f"ppo_{args.scenario}"
    out.mkdir(parents=True, exist_ok=True)
    venv = make_sb3_vec_env(args.num_envs, scenario=args.scenario,
                            episode_duration=args.episode_duration)
    venv.seed(args.seed)
    model = PPO("MlpPolicy", venv, n_steps=256, batch_size=256, seed=args.seed, verbose=1)
    model.learn(args.total_timesteps, progress_bar=False,
                callback=CheckpointCallback(50_000, str(out), name_prefix="ppo"))
    model.save(out / "final")
    return model


if __name__ == "__main__":
    train(parse())
