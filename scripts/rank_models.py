"""Rank a training run's models on validation seeds, to choose which one to ship.

    .venv/bin/python scripts/rank_models.py logs/runs/drilling_sac_seed0 [more runs]

The run's own "best" model is chosen on 8 validation episodes, too few for a task whose
scenario draws differ this much (docs/tasks.md, task 2). This plays every candidate of
each run (its best model, its final model and the checkpoints from ``--from-steps`` on)
and the trivial policies (each action held at +1, 0 and -1, random actions; for the
drilling task the grid search's best constant, 160 rpm / 65 kN) on ``--seeds``
validation seeds from 900100 on: above the 8 seeds that training evaluates on (900000+)
and below the held-out seeds of ``drill-env evaluate`` and
``tests/test_shipped_policies.py`` (1000000+), which stay unseen. Prints each
candidate's mean return and its one-sided paired t-test p against every trivial policy
(the test's criterion).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import gymnasium as gym
from scipy.stats import ttest_rel

import drill_env  # noqa: F401  (registers the envs)
from agents.classical import ConstantSetPoints
from agents.learned import LearnedController
from agents.trivial import HeldAction, RandomActions
from training.config import TASKS, read_run_config
from training.evaluate import acting, returns_on

FIRST_SEED = 900_100
#: The drilling task's best constant set point (docs/tasks.md: 5 x 5 grid, training seeds).
BEST_CONSTANT = (160.0, 65.0e3)


def candidates(run: Path, from_steps: int) -> list[tuple[str, Path, Path]]:
    out = []
    for name, model, norm in (("best", "best_model.zip", "best_vecnormalize.pkl"),
                              ("final", "model.zip", "vecnormalize.pkl")):
        if (run / model).exists():
            out.append((f"{run}/{name}", run / model, run / norm))
    for ck in sorted((run / "checkpoints").glob("model_*_steps.zip"),
                     key=lambda p: int(p.stem.split("_")[1])):
        steps = int(ck.stem.split("_")[1])
        if steps >= from_steps:
            out.append((f"{run}/checkpoint {steps}", ck,
                        run / "checkpoints" / f"vecnormalize_{steps}.pkl"))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("runs", type=Path, nargs="+", help="run folders of drill-env train")
    parser.add_argument("--seeds", type=int, default=60, help="validation seeds (default 60)")
    parser.add_argument("--from-steps", type=int, default=0,
                        help="checkpoints from this many env steps on (default: all)")
    args = parser.parse_args()
    configs = [read_run_config(run / "config.yaml") for run in args.runs]
    tasks = {c["task"] for c in configs}
    if len(tasks) != 1:
        raise SystemExit(f"runs: all of one task, got {sorted(tasks)}")
    task = tasks.pop()
    env_id = TASKS[task]
    env = gym.make(env_id, **configs[0].get("env_kwargs", {}))
    seeds = list(range(FIRST_SEED, FIRST_SEED + args.seeds))
    others = {"+1": acting(HeldAction((1.0,))), "0": acting(HeldAction((0.0,))),
              "-1": acting(HeldAction((-1.0,))), "random": acting(RandomActions())}
    if task == "drilling":
        others["constant"] = acting(ConstantSetPoints(*BEST_CONSTANT))
    baseline = {name: returns_on(env, seeds, make) for name, make in others.items()}
    print(f"{len(seeds)} validation seeds {seeds[0]}-{seeds[-1]}; mean returns: "
          + ", ".join(f"{name} {r.mean():.1f}" for name, r in baseline.items()))
    for run in args.runs:
        for name, model, norm in candidates(run, args.from_steps):
            policy = LearnedController.load(run, files=(model, norm))
            r = returns_on(env, seeds, acting(policy))
            p = {k: ttest_rel(r, v, alternative="greater").pvalue for k, v in baseline.items()}
            print(f"{name:55s} mean {r.mean():7.1f}  p against "
                  + "  ".join(f"{k} {v:.2g}" for k, v in p.items()), flush=True)


if __name__ == "__main__":
    main()
