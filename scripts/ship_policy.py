"""Copy a training run's policy into agents/trained/<task>/ (the controller ``learned``).

    .venv/bin/python scripts/ship_policy.py logs/runs/stick_slip_ppo_seed0

Copies the best model on the validation seeds (else the final one; ``--final``: the
final one) with its VecNormalize statistics and the run's config, and writes a README
with the command that reproduces it, its env steps and wall time. Refuses a policy over
2 MB.

    .venv/bin/python scripts/ship_policy.py logs/runs/drilling_sac_seed0 --final
"""

from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path

from agents.learned import TRAINED, _files
from training.config import TRAINED_WITH, read_run_config

LIMIT = 2 * 1024 * 1024


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("run", type=Path)
    parser.add_argument("--final", action="store_true",
                        help="ship the final model, not the best on the validation seeds")
    args = parser.parse_args()
    config = read_run_config(args.run / "config.yaml")
    info = json.loads((args.run / "run.json").read_text())
    model, norm = ((args.run / "model.zip", args.run / "vecnormalize.pkl") if args.final
                   else _files(args.run))
    size = model.stat().st_size + norm.stat().st_size
    if not (args.run / TRAINED_WITH).exists():
        raise SystemExit(f"{args.run} has no {TRAINED_WITH} (a run of a version before "
                         "2026-12-06): tests/test_shipped_policies.py needs the settings a "
                         "shipped policy trained under; train it again")
    if size > LIMIT:
        raise SystemExit(f"{model} + {norm}: {size / 1e6:.1f} MB, over the 2 MB limit")
    target = TRAINED / config["task"]
    target.mkdir(parents=True, exist_ok=True)
    shutil.copy(model, target / "model.zip")
    shutil.copy(norm, target / "vecnormalize.pkl")
    shutil.copy(args.run / "config.yaml", target / "config.yaml")
    # the settings it trained under (tests/test_shipped_policies.py checks them against
    # today's)
    shutil.copy(args.run / TRAINED_WITH, target / TRAINED_WITH)
    best = "final model"
    ship = f"scripts/ship_policy.py logs/runs/{args.run.name}"  # where train writes the run
    if args.final:
        best = ("final model (chosen over the run's best on its validation episodes by "
                "`scripts/rank_models.py` on more validation seeds)")
        ship += " --final"
    if model.name.startswith("best"):
        import csv

        with (args.run / "evaluations.csv").open() as f:
            rows = list(csv.DictReader(f))
        top = max(rows, key=lambda r: float(r["return"]))
        best = (f"best model on the validation seeds (after {int(top['timesteps']):,} steps, "
                f"{float(top['wall_s']) / 60:.0f} min; validation SSI {float(top['ssi']):.2f})")
    (target / "README.md").write_text(f"""# Shipped policy: {config['task']}

{config['algo'].upper()} on `{info['env_id']}`, seed {config['seed']}: the {best} of a run
of {info['env_steps']:,} env steps ({config['n_envs']} batched envs) that took
{info['wall_s'] / 60:.0f} min on {info['machine']}. Reproduce with

    drill-env train --task {config['task']} --algo {config['algo']} --seed {config['seed']}
    .venv/bin/python {ship}

(hyperparameters: `training/hyperparams/{config['task']}.yml`, copied here as
`config.yaml`; the task settings it trained under in `trained_with.json`). Use it as
the controller `learned`
(`drill-env benchmark --task {config['task']} --controllers learned,...`); measured
results: docs/tasks.md.
""")
    print(f"shipped {model.name} ({size / 1e3:.0f} kB) to {target}")


if __name__ == "__main__":
    main()
