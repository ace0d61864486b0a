"""``drill-env train`` and ``drill-env evaluate``: a training run (or a sweep of seeds) and
its evaluation against the classical controllers and trivial policies."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

from drill_cli.arguments import shell_word


def say_left_out(args: argparse.Namespace, config: Any) -> None:
    """Note on stderr the settings of the task's shipped hyperparameter entry that the
    ``--config`` file's entry leaves out (a --config file is a whole entry, as rl-zoo3's)."""
    from training.config import HYPERPARAMS, left_out_settings, taken_value

    flags = {"n_timesteps": args.timesteps, "seed": args.seed, "n_envs": args.n_envs}
    left = left_out_settings(config, args.config,
                             [key for key, value in flags.items() if value is not None])

    def here(key: str) -> str:  # the value the run takes (the shipped one alone read as
        known, value = taken_value(config, key)  # it: a new user's trial)
        return json.dumps(value) if known and value is not None else "the default"

    if left:
        shown = ", ".join(f"{key} (shipped {json.dumps(value)}, here {here(key)})"
                          for key, value in left)
        print(f"note: --config {args.config}: its {args.algo} entry leaves out {len(left)} "
              f"setting{'' if len(left) == 1 else 's'} of {HYPERPARAMS / args.task}.yml, "
              f"which the run takes at its defaults (SB3's, the task's, drill-env's) "
              f"instead: {shown}. A --config file is a whole entry, as rl-zoo3's: copy "
              "the task's file to change part of it", file=sys.stderr)


def cmd_train(args: argparse.Namespace) -> int:
    from training.config import ReplacedValueError, load_config
    from training.run_folder import check_run_folder, holds_run
    from training.train import planned_steps, train

    if args.name is not None and (args.name.strip() != args.name or args.name in (".", "..")
                                  or not args.name or any(c in args.name for c in "/\\")):
        raise argparse.ArgumentTypeError(f"--name: a folder name inside --out, without "
                                         f"'/' or a space at an end, got {args.name!r}")
    from training.config import VALIDATION_SEED

    if args.seed is not None and args.seed >= VALIDATION_SEED:
        raise argparse.ArgumentTypeError(
            f"--seed: must be below {VALIDATION_SEED}, got {args.seed} (the seeds from "
            f"{VALIDATION_SEED} on are the validation and held-out episodes)")
    if args.algo is None:  # a named run resumes with its own algorithm, a --config of one
        named = args.out / args.name if args.resume and args.name else None  # entry takes
        args.algo = (named and saved_algorithm(named)) or only_algorithm(args.config) or "sac"
    try:
        config = load_config(args.task, args.algo, args.config, n_timesteps=args.timesteps,
                             seed=args.seed, n_envs=args.n_envs)
    except ValueError as err:  # a field of the entry: a flag's if given, else the file's
        field, _, rest = str(err).partition(": ")
        flag, value = TRAIN_OVERRIDES.get(field.removeprefix(f"{args.algo}."), ("", ""))
        if flag and getattr(args, value) is not None and not isinstance(err, ReplacedValueError):
            raise argparse.ArgumentTypeError(f"{flag}: {rest}") from None
        if args.config is not None and field.startswith(f"{args.algo}."):
            raise argparse.ArgumentTypeError(f"--config {args.config}: {err}") from None
        raise
    if args.config is not None:  # a file of a few keys lost the task's tuned settings
        say_left_out(args, config)  # without a word (an outside trial's reward variant)
    if args.seeds is not None:
        return train_sweep(args, config)
    if args.ray_address is not None:
        raise argparse.ArgumentTypeError("--ray-address: a single run trains here; give "
                                         "--seeds to fan several runs out")
    if args.workers is not None:  # it started a full run without a word
        raise argparse.ArgumentTypeError("--workers: a single run trains in this process; "
                                         "give --seeds to train several runs side by side")
    from drill_env.sweep import check_folder_free
    from training.sweep import run_name

    run = args.out / (args.name or run_name(config, args.config and args.config.stem))
    saved = run / "config.yaml"
    # a run still training is said so, before any advice on what the folder holds
    check_folder_free(run, "this training run")
    if args.resume and not holds_run(run) and run.is_dir():
        # stopped before it saved anything (a Ctrl-C in its first seconds): a fresh start
        # is what resuming it gives ("--resume starts it", the interrupt said)
        print(f"note: {run} holds nothing of a run yet (stopped before it saved its "
              "config): --resume starts it", file=sys.stderr)
        args.resume = False
    if args.resume and not holds_run(run):
        raise argparse.ArgumentTypeError(f"--resume: no run in {run}; name it by --name, or "
                                         "by --seed (and --algo, --config) as it was "
                                         "started")
    if args.resume and args.config is None and saved.is_file():
        # a resumed run continues with the config it was started with (--config or not)
        config = saved_run_config(saved, args.task, args.algo, n_timesteps=args.timesteps,
                                  n_envs=args.n_envs, seed=args.seed)
    done = check_run_folder(run, args.resume, args.overwrite, config)  # before announcing
    planned = planned_steps(config, done)
    # (a resume counts from the steps done, which a cut rollout leaves between two whole
    # ones: its extra steps read as rounding, a trial)
    since = f" from the {done} done (a rollout cut short is counted, not learnt from)" \
        if planned != planned_steps(config) else ""
    steps = f"{planned} env steps" + (f" ({config.n_timesteps} asked for, rounded up to "
                                      f"whole PPO rollouts{since})"
                                      if planned != config.n_timesteps else "")
    print(f"training {config.algo.upper()} on {config.env_id}: {steps}, "
          f"{config.n_envs} batched envs, seed {config.seed} -> {run}")
    t0 = time.perf_counter()
    model = train(config, run, resume=args.resume, progress=not args.no_progress,
                  overwrite=args.overwrite)
    curve = run / "learning_curve.png"
    made = f", {curve}" if curve.exists() else " (no evaluation yet: no learning curve)"
    print(f"trained in {time.perf_counter() - t0:.0f} s: {model}, {run / 'vecnormalize.pkl'}"
          f"{made}; drill-env evaluate {shell_word(run)}")
    return 0


#: Fields of a training entry that flags of `train` set: (flag, its args attribute).
TRAIN_OVERRIDES = {"n_timesteps": ("--timesteps", "timesteps"), "seed": ("--seed", "seed"),
                   "n_envs": ("--n-envs", "n_envs")}


def only_algorithm(config: Path | None) -> str | None:
    """The algorithm of a --config file with one entry (``ppo: {...}`` alone), or None:
    such a file asked for --algo ppo as well, and said the default's entry was missing."""
    from training.config import read_yaml

    try:
        data = read_yaml(config) if config is not None else None
    except ValueError:  # said by load_config, in its words
        return None
    return next(iter(data)) if isinstance(data, dict) and len(data) == 1 \
        and next(iter(data)) in ("ppo", "sac") else None


def saved_algorithm(run: Path) -> str | None:
    """The algorithm the run in folder ``run`` was trained with (None: no config there)."""
    from training.config import read_run_config

    saved = run / "config.yaml"
    if not saved.is_file():
        return None
    algo = read_run_config(saved).get("algo")
    return algo if algo in ("ppo", "sac") else None


def saved_run_config(saved: Path, task: str, algo: str, **overrides: Any) -> Any:
    """The :class:`~training.config.TrainConfig` a run saved (its ``config.yaml``), with
    the ``overrides`` given (None: keep the run's)."""
    from drill_env.physics.validation import from_dict
    from training.config import TrainConfig, read_run_config, without_inert_keys

    data = without_inert_keys(read_run_config(saved))
    for flag, value in (("task", task), ("algo", algo)):
        if data.get(flag, value) != value:
            raise argparse.ArgumentTypeError(f"--{flag}: {saved.parent} was trained with "
                                             f"{data[flag]}, not {value}")
    data.update({k: v for k, v in overrides.items() if v is not None})
    try:
        return from_dict(TrainConfig, data)
    except ValueError as err:  # a field of the saved file (a hand edit; the flags passed
        # load_config's checks already): name the file
        raise ValueError(f"{saved}: {err}") from None


def train_sweep(args: argparse.Namespace, config) -> int:
    from training.sweep import train_seeds

    try:
        seeds = [int(k) for k in args.seeds.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"--seeds: comma-separated integers, got "
                                         f"{args.seeds!r}") from None
    from training.config import VALIDATION_SEED

    if any(not 0 <= k < VALIDATION_SEED for k in seeds) or len(set(seeds)) < len(seeds):
        raise argparse.ArgumentTypeError(f"--seeds: distinct integers in 0-"
                                         f"{VALIDATION_SEED - 1} (the validation seeds "
                                         f"start at {VALIDATION_SEED}), got {args.seeds!r}")
    if args.name is not None or args.resume or args.overwrite or args.seed is not None:
        raise argparse.ArgumentTypeError("--seeds: runs are named <task>_<algo>_seed<k> "
                                         "(<task>_<algo>_<config file>_seed<k>) and "
                                         "always resume; drop --name / --resume / "
                                         "--overwrite / --seed")
    from training.run_folder import check_learns

    check_learns(config, 0)
    t0 = time.perf_counter()
    results = train_seeds(config, seeds, args.out, workers=args.workers,
                          ray_address=args.ray_address, progress=not args.no_progress,
                          label=args.config and args.config.stem)
    for r in results:
        best = "no validation yet (raise --timesteps past eval_freq)" \
            if r["best_return"] is None else \
            f"best validation return {r['best_return']:.1f} at {r['best_at_steps']} steps"
        print(f"seed {r['seed']}: {best} -> {r['run']}")
    print(f"{len(results)} runs in {time.perf_counter() - t0:.0f} s; summary in "
          f"{args.out / 'train_sweep.md'}")
    return 0


def default_evaluation_folder(run: Path, fidelity: str | None = None) -> Path:
    """``RUN/evaluation`` beside a training run; for a policy shipped in the package
    (``agents/trained/<task>``), ``logs/evaluation/<task>``: not into the source tree.
    At a physics level other than the run's own (``--fidelity``), ``_<level>`` is added,
    so that the evaluation at the run's level is kept beside it."""
    from agents.learned import TRAINED

    if run.resolve().is_relative_to(TRAINED):
        folder = Path("logs") / "evaluation" / run.resolve().name
    else:
        folder = run / "evaluation"
    if fidelity is not None and (run / "config.yaml").exists():
        from training.config import read_run_config
        from training.evaluate import trained_fidelity

        own = trained_fidelity(read_run_config(run / "config.yaml").get("env_kwargs") or {})
        if fidelity != own:
            folder = folder.with_name(f"{folder.name}_{fidelity}")
    return folder


def which_model(run: Path, model: Path) -> str:
    """What ``model`` (from :func:`agents.learned.policy_files`) is, said when evaluating
    ``run``: a training run's best or final model, its last checkpoint, or the model a
    shipped policy folder (a README, no run.json) holds."""
    if model.name.startswith("best_"):
        return "the best model on the validation seeds"
    if model.name != "model.zip":
        return "the last checkpoint: the run stopped before its first evaluation"
    if (run / "README.md").exists() and not (run / "run.json").exists():
        from agents.learned import TRAINED

        if run.resolve().is_relative_to(TRAINED):
            return "the shipped policy's chosen model: its README says which"
        return "the folder's model: no run.json, not a training run's record"
    return "the run's final model: it kept no best model"


def trained_steps(run: Path, model: Path) -> int | None:
    """The env steps ``model`` of ``run`` had trained when it was saved: the best model's
    evaluation row (:func:`training.run_folder.best_evaluation`), a checkpoint's name,
    the final model's run.json; None where the run does not say (a shipped policy
    folder). A run of one PPO update was scored like any other without a word on how
    little it trained (a new user's trial)."""
    from agents.learned import checkpoint_steps
    from training.run_folder import best_evaluation

    try:
        if model.name.startswith("best_"):
            best = best_evaluation(run)
            return int(best["timesteps"]) if best else None
        if (steps := checkpoint_steps(model)) is not None:
            return steps
        return int(json.loads((run / "run.json").read_text(encoding="utf-8"))["env_steps"])
    except (OSError, ValueError, KeyError, TypeError):
        return None


def cmd_evaluate(args: argparse.Namespace) -> int:
    from agents.learned import TRAINED, no_such_folder
    from training.config import TASKS, TRAINED_WITH
    from training.evaluate import evaluate_run

    # a task's name is its shipped policy, unless a file or folder here has that name
    local = f"; {args.run} here is yours, not the task's shipped policy, which is " \
        f"{TRAINED / str(args.run)}" if str(args.run) in TASKS else ""
    if not args.run.exists() and local:
        args.run, local = TRAINED / str(args.run), ""
    # a file or folder inside a run (a checkpoint, its folder) is scored through the run;
    # a run's own config.yaml wins, and a folder above is a run by its checkpoints or
    # trained_with.json too (a project's config.yaml above a run refused it: a review)
    inside = None if not args.run.exists() or (args.run / "config.yaml").is_file() else next(
        (p for p in args.run.resolve().parents[:2] if (p / "config.yaml").is_file()
         and ((p / "checkpoints").is_dir() or (p / TRAINED_WITH).is_file())), None)
    if inside is not None:
        raise argparse.ArgumentTypeError(
            f"RUN: {args.run} lies inside the run {inside}: evaluate the run (its best "
            "model, else its final one, else its last checkpoint)")
    if not args.run.is_dir():
        what = f"{args.run} is a file, not a run folder{local}" if args.run.exists() else \
            no_such_folder(args.run, sorted(TASKS))
        raise argparse.ArgumentTypeError(f"RUN: {what} (a run folder of drill-env train, "
                                         "e.g. logs/runs/<name>, or a task's name for its "
                                         f"shipped policy: {', '.join(sorted(TASKS))})")
    if not (args.run / "config.yaml").exists():
        from agents.learned import ELSEWHERE
        from drill_env.physics.units import few

        # a folder of runs (logs/runs): the runs it holds, not the advice for others' models
        runs = sorted(f.name for f in args.run.iterdir() if (f / "config.yaml").is_file())
        if runs:
            raise argparse.ArgumentTypeError(
                f"RUN: {args.run} is a folder of runs, not one: give one of them ("
                + few(runs, "in it") + f"), e.g. {args.run / runs[0]}")
        raise argparse.ArgumentTypeError(f"RUN: {args.run} is not a run folder of drill-env "
                                         f"train (no config.yaml){local}; {ELSEWHERE}, then "
                                         "drill-env benchmark --task")
    from agents.learned import policy_files
    from drill_env.sweep import held_by_another

    live = held_by_another(args.run)
    try:
        model, _ = policy_files(args.run)
    except FileNotFoundError:  # a run stopped before its first evaluation or checkpoint
        why = "still training: evaluate it once it has saved one" if live else \
            "stopped before its first checkpoint: drill-env train --resume starts it again"
        raise argparse.ArgumentTypeError(
            f"RUN: {args.run} holds no model yet ({why}): neither best_model.zip + "
            "best_vecnormalize.pkl nor model.zip + vecnormalize.pkl nor a checkpoint"
        ) from None
    steps = trained_steps(args.run, model)
    print(f"evaluating {model} ({which_model(args.run, model)}"
          + (f"; trained {steps:,} env steps" if steps is not None else "") + ")")
    if live:  # (went ahead without a word: a new user's trial)
        print(f"note: {args.run} is held by another drill-env process, a training still "
              "running: this evaluates the model it has saved so far (a better one saved "
              "meanwhile joins no row), and goes stale when training saves one",
              file=sys.stderr)
    if local:  # a folder here took a task's name (a security review: said only on errors)
        print(f"note: {local.removeprefix('; ')}")
    out = args.out or default_evaluation_folder(args.run, args.fidelity)
    evaluate_run(args.run, seeds=args.seeds, workers=args.workers, out=out,
                 ray_address=args.ray_address, fidelity=args.fidelity)
    print(f"wrote {out / 'benchmark.csv'}, benchmark.md, comparison.md and the plots")
    return 0
