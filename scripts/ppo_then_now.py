"""PPO end to end: the code of the day the speed issue was filed against today's, timed
in the same run (issue 16, acceptance 1a).

    .venv/bin/python scripts/ppo_then_now.py [--workload task] [--rounds 3] [--loaded]

The issue measured ~2,000 env steps/s for PPO on the batched env with the update at
52-59 % of the wall time: the task-1 PPO run (``training/hyperparams/
stick_slip.yml``: 8 batched ``DrillStickSlip-v0`` envs in VecNormalize, 512 steps per
env and update, 10 epochs, 128 x 128). Figures taken on different days on a shared
machine cannot be compared, so this script checks the code of that day out in a
temporary git worktree (``--base``; default ``9a286b1``, the last commit before the first
change made for the issue) and trains the same model on the same envs with both trees,
in a fresh process each, in alternating turns (``--rounds``), quiet or beside one
CPU-bound process (``--loaded``). Each tree runs with its own defaults: the old one as
it was (libgomp's spinning wait, torch's own thread count), today's as ``drill-env
train`` does (``import drill_env`` sets a passive OpenMP wait and, since 2026-12-04,
puts numba's parallel calls on TBB; torch held at one thread by
``training.callbacks.torch_threads_callback``). The first ``--warmup`` steps of each
process are not timed (numba cache load or compile, first update).

``--workload train_ppo`` runs instead ``training/train_ppo.py`` of the first speed issue
(PPO with SB3's defaults but ``n_steps=256, batch_size=256`` on 8 batched
``DrillString-v0`` envs, 30 s episodes, ``--scenario``; base ``9e78440``). Its randomised
scenario has since become the realistic 900-1600 m string (178 nodes instead of 136), so
there ``--scenario default``, the same string in both trees, compares equal work.

Prints env steps/s (best and median over rounds), CPU seconds per 1,000 env steps and
the ratio today / then; writes ``logs/ppo_then_now_<workload>.json`` after every run
(``summary`` is filled in at the end).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: The last commit before the first change made for the speed issue, per workload.
BASES = {"task": "9a286b1", "train_ppo": "9e78440"}

#: Runs in the tree under test (its cwd): only APIs both trees have.
CHILD = r"""
import json, sys, time
import drill_env
from drill_env.vector import make_sb3_vec_env
import torch
from stable_baselines3 import PPO

steps, warmup, today = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3] == "1"
workload, scenario = sys.argv[4], sys.argv[5]
callback = None
if today:
    from training.callbacks import torch_threads_callback
    callback = torch_threads_callback(1)
if workload == "task":  # the task-1 PPO run, as drill-env train --algo ppo builds it
    from training.config import load_config
    from training.train import make_train_env
    config = load_config("stick_slip", "ppo")
    model = PPO(config.policy, make_train_env(config, 0), seed=0, verbose=0,
                policy_kwargs=dict(config.policy_kwargs), **config.hyperparams)
else:  # training/train_ppo.py of the issue's day
    venv = make_sb3_vec_env(8, scenario=scenario, episode_duration=30.0)
    venv.seed(0)
    model = PPO("MlpPolicy", venv, n_steps=256, batch_size=256, seed=0, verbose=0)
model.learn(warmup, callback=callback)
wall, cpu = time.perf_counter(), time.process_time()
model.learn(steps, reset_num_timesteps=False, callback=callback)
wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
print(json.dumps({"steps_per_s": steps / wall, "cpu_s_per_1000": 1e3 * cpu / steps,
                  "module": drill_env.__file__, "torch_threads": torch.get_num_threads()}))
"""


def run_child(tree: Path, args: argparse.Namespace, today: bool, logs: Path) -> dict:
    """One timed training in ``tree``; SB3's logger writes to ``logs`` (without a folder
    it would leave one in the system's temporary directory per ``learn``)."""
    out = subprocess.run([sys.executable, "-c", CHILD, str(args.steps), str(args.warmup),
                          "1" if today else "0", args.workload, args.scenario], cwd=tree,
                         capture_output=True, text=True,
                         env={**os.environ, "SB3_LOGDIR": str(logs)})
    if out.returncode != 0:
        raise RuntimeError(f"the run in {tree} failed:\n{out.stderr[-3000:]}")
    row = json.loads(out.stdout.strip().splitlines()[-1])
    if not row["module"].startswith(str(tree)):  # an installed copy would shadow the tree
        raise RuntimeError(f"{tree}: imported drill_env from {row['module']}")
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--workload", choices=("train_ppo", "task"), default="task")
    parser.add_argument("--base", default=None,
                        help="the tree to compare with (default: the workload's base)")
    parser.add_argument("--steps", type=int, default=16384)
    parser.add_argument("--warmup", type=int, default=4096)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--scenario", default="random", help="train_ppo only")
    parser.add_argument("--loaded", action="store_true",
                        help="run beside one CPU-bound process")
    parser.add_argument("--out", type=Path, default=None,
                        help="default: logs/ppo_then_now_<workload>.json (train_ppo: "
                             "_<scenario> appended)")
    args = parser.parse_args()
    args.base = args.base or BASES[args.workload]
    label = args.workload if args.workload == "task" else f"{args.workload}_{args.scenario}"
    args.out = args.out or ROOT / "logs" / f"ppo_then_now_{label}.json"
    with tempfile.TemporaryDirectory() as tmp:
        base = Path(tmp) / "base"
        subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", str(base),
                        args.base], check=True, capture_output=True)
        hog = (subprocess.Popen([sys.executable, "-c", "while True: pass"])
               if args.loaded else None)
        runs: dict[str, list[dict]] = {"then": [], "today": []}
        try:
            for k in range(args.rounds):
                for name, tree in (("then", base), ("today", ROOT)):
                    row = run_child(tree, args, name == "today", Path(tmp) / "sb3")
                    runs[name].append(row)
                    write(args, label, runs)  # each run as it arrives
                    print(f"round {k + 1}: {name:5s} {row['steps_per_s']:7.0f} env steps/s, "
                          f"{row['cpu_s_per_1000']:.2f} CPU s per 1,000", flush=True)
        finally:
            if hog is not None:
                hog.kill()
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force",
                            str(base)], capture_output=True)
    summary = {}
    for name, rows in runs.items():
        rates = [r["steps_per_s"] for r in rows]
        summary[name] = {"best": max(rates), "median": statistics.median(rates),
                         "cpu_s_per_1000_min": min(r["cpu_s_per_1000"] for r in rows)}
    ratios = [t["steps_per_s"] / b["steps_per_s"]
              for t, b in zip(runs["today"], runs["then"], strict=True)]
    summary["ratio_per_round"] = ratios
    print(f"\n{'tree':6s} {'best':>7s} {'median':>7s} {'CPU s/1000':>11s}")
    for name in ("then", "today"):
        s = summary[name]
        print(f"{name:6s} {s['best']:7.0f} {s['median']:7.0f} {s['cpu_s_per_1000_min']:11.2f}")
    print(f"today / then: best {summary['today']['best'] / summary['then']['best']:.2f}x, "
          f"per round {min(ratios):.2f}-{max(ratios):.2f}x "
          f"({'beside one busy process' if args.loaded else 'quiet'}; {label}; "
          f"base {args.base})")
    write(args, label, runs, summary)
    print(f"wrote {args.out}")


def write(args: argparse.Namespace, label: str, runs: dict, summary: dict | None = None
          ) -> None:
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"base": args.base, "loaded": args.loaded,
                                    "workload": label, "steps": args.steps,
                                    "summary": summary, "runs": runs}, indent=2))


if __name__ == "__main__":
    main()
