"""A training seed sweep: one run per seed, on local processes or on Ray.

``drill-env train --task stick_slip --seeds 0,1,2,3 [--ray-address auto]`` trains the same
config once per seed, each run in its own folder ``<out>/<task>_<algo>_seed<k>``
(``<task>_<algo>_<file>_seed<k>`` from a ``--config`` file) as a single ``drill-env
train`` would, one run per worker (torch and numba single-threaded: the workers are the
parallelism). Each finished run's summary is appended to
``<out>/train_sweep.jsonl`` as it arrives; the sweep run again skips finished seeds, and
a run whose worker died (or that was interrupted) resumes from its last checkpoint
(SAC restarts its replay buffer there, see :func:`training.train.train`). The summary
table is ``<out>/train_sweep.md``: the env steps each run trained, the validation return
of the best model per seed, and mean +- std over seeds. A Ctrl-C or SIGTERM (``kill``)
of the command reaches the workers, which save a checkpoint and stop; on Linux a worker
dies with its parent. On Ray each running run is interrupted the same way
(:meth:`drill_env.distributed.RayExecutor._stop`) and saves its checkpoint.
"""

from __future__ import annotations

import dataclasses
import json
import statistics
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from drill_env.physics.validation import jsonable
from drill_env.sweep import ResultStore, digest, make_executor, save_text
from training.config import TrainConfig

RESULTS_FILE = "train_sweep.jsonl"


def run_name(config: TrainConfig, label: str | None = None) -> str:
    """``<task>_<algo>_seed<k>``, with ``label`` (a --config file's name) before the seed:
    runs of two configs in one folder told apart (an outside trial's reward variant took
    the default run's name, and ``--resume`` went on with it unannounced)."""
    return f"{config.task}_{config.algo}_{label + '_' if label else ''}seed{config.seed}"


def _train_task(args: tuple[TrainConfig, str]) -> dict[str, Any]:
    """One seed's run (resumed from its last checkpoint if it has one)."""
    import torch

    from training.run_folder import best_evaluation, finished, holds_run
    from training.train import train

    config, folder = args
    torch.set_num_threads(1)
    run = Path(folder)
    # an interrupted sweep continues its runs, and takes those it had finished as they
    # are (stopped before it noted them); a new one starts them
    if not finished(run, config):
        train(config, run, resume=holds_run(run), progress=False)
    info = json.loads((run / "run.json").read_text(encoding="utf-8"))
    best = best_evaluation(run)  # none before the first evaluation
    return {"seed": config.seed, "run": str(run), "env_steps": info["env_steps"],
            "wall_s": info["wall_s"],
            "best_return": best["return"] if best else None,
            "best_at_steps": int(best["timesteps"]) if best else None,
            "best_ssi": best["ssi"] if best else None}


def train_seeds(config: TrainConfig, seeds: Sequence[int], out: Path,
                workers: int | None = None, ray_address: str | None = None,
                progress: bool = True, label: str | None = None) -> list[dict[str, Any]]:
    """Train ``config`` once per seed (runs named by :func:`run_name` with ``label``);
    returns one summary per seed, in seed order."""
    from drill_env.progress import progress_bar

    if not seeds or len(set(seeds)) != len(seeds):
        raise ValueError(f"--seeds: give one or more distinct seeds, got {list(seeds)}")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    common = {k: v for k, v in jsonable(config).items() if k != "seed"}
    store = ResultStore(out / RESULTS_FILE, digest(common))
    configs = [dataclasses.replace(config, seed=int(s)) for s in seeds]
    todo = [c for c in configs if str(c.seed) not in store]
    if len(todo) < len(configs) and progress:
        print(f"training seeds: {len(configs) - len(todo)} of {len(configs)} runs already in "
              f"{out / RESULTS_FILE} (same config): not rerun", file=sys.stderr)
    if todo and progress:  # (the runs' own "resuming" lines do not reach this console)
        from training.run_folder import resume_point

        points = {name: resume_point(out / name) for name in (run_name(c, label) for c in todo)}
        going_on = [f"{name} from {at[0]:,} env steps" for name, at in points.items()
                    if at is not None]
        if going_on:
            print(f"training seeds: going on with {', '.join(going_on)} (checkpoints in "
                  f"{out})", file=sys.stderr)
    if todo:
        executor = make_executor(min(workers or len(todo), len(todo))
                                 if ray_address is None else None, ray_address)
        bar = progress_bar(total=len(configs), initial=len(configs) - len(todo), unit="run",
                           desc="training seeds", disable=not progress)
        try:
            items = [(c, str(out / run_name(c, label))) for c in todo]
            def keep(k: int, summary: dict[str, Any]) -> None:
                store.put(str(todo[k].seed), summary)
                bar.update(1)

            for k, summary in executor.map_unordered(_train_task, items, late=keep):
                keep(k, summary)
        except KeyboardInterrupt:  # (on Ray the runs' own lines, what each saved, do not
            # reach this console: the sweep said only "interrupted")
            bar.close()
            if progress:
                print(stopped_note(configs, todo, store, out, label), file=sys.stderr)
            raise
        finally:
            bar.close()
            executor.close()
    results = [store.get(str(c.seed)) for c in configs]
    write_summary(results, out / "train_sweep.md", config)
    return results


def stopped_note(configs: Sequence[TrainConfig], todo: Sequence[TrainConfig],
                 store: ResultStore, out: Path, label: str | None = None) -> str:
    """What a stopped sweep finished, and what the same command does with the rest: a run
    with a saved model goes on from it, one without starts anew."""
    from training.run_folder import resume_point

    left = [run_name(c, label) for c in todo if str(c.seed) not in store]
    going_on = [name for name in left if resume_point(out / name) is not None]
    anew = [name for name in left if name not in going_on]
    then = ([f"goes on with {', '.join(going_on)} from the checkpoints in {out}"]
            if going_on else []) + ([f"starts {', '.join(anew)} anew (nothing saved)"]
                                    if anew else [])
    return (f"training seeds: stopped with {len(configs) - len(left)} of {len(configs)} "
            f"runs finished ({out / RESULTS_FILE})"
            + (f"; the same command {' and '.join(then)}" if then else ""))


def write_summary(results: list[dict[str, Any]], path: Path, config: TrainConfig) -> Path:
    lines = [f"# Seed sweep: {config.algo.upper()} on {config.env_id}, "
             f"{config.n_timesteps} env steps per seed asked for", "",
             "A run ends after the asked-for steps once its last rollout is whole (PPO), and "
             "a resumed one also counts the steps of the rollout an interrupt cut short: "
             "'trained' is what each run did.", "",
             "| seed | env steps trained | best validation return | at env steps | SSI there "
             "| wall s | run |",
             "| --- | --- | --- | --- | --- | --- | --- |"]
    for r in results:
        best = "-" if r["best_return"] is None else f"{r['best_return']:.1f}"
        at = "-" if r["best_at_steps"] is None else r["best_at_steps"]
        ssi = "-" if r["best_ssi"] is None else round(r["best_ssi"], 3)
        lines.append(f"| {r['seed']} | {r['env_steps']} | {best} | {at} | {ssi} | "
                     f"{r['wall_s']:.0f} | {r['run']} |")
    values = [r["best_return"] for r in results if r["best_return"] is not None]
    if len(values) > 1:
        lines += ["", f"Best validation return over seeds: {statistics.mean(values):.1f} +- "
                      f"{statistics.stdev(values):.1f} (mean +- std, {len(values)} seeds)."]
    save_text(path, "\n".join(lines) + "\n")
    return path
