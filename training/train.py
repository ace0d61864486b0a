"""Train PPO or SAC on a control task: ``drill-env train --task stick_slip``.

A run lives in ``logs/runs/<name>/``:

==========================  ===========================================================
``config.yaml``             the exact :class:`~training.config.TrainConfig` of the run
``trained_with.json``       drill-env's version and source digest, the task and env
                            settings the env resolved (defaults included), its
                            scenario with the parameters given and the physics
                            overrides: a later version whose defaults moved says so
``model.zip``               the final model; ``vecnormalize.pkl`` its normalisation
``best_model.zip``          the best model on the validation seeds (+ its
                            ``best_vecnormalize.pkl``)
``checkpoints/``            models every ``checkpoint_freq`` steps and at a Ctrl-C
                            (resume from the last), their normalisation and the
                            training wall time at each
``evaluations.csv``         validation return, SSI, stuck share, wall time per evaluation
                            (a resumed run drops the rows after its checkpoint)
``learning_curve.png``      the validation curve, redrawn at every evaluation
``tb/``                     TensorBoard logs
``run.json``                seeds, env steps, wall time, versions (once the run finishes)
==========================  ===========================================================

The training envs are the batched SB3 VecEnv (:func:`drill_env.vector.make_sb3_vec_env`):
all envs' physics in one compiled call per step, seeded by :func:`env_seed` (above every
validation and evaluation seed); the evaluation callback replays fixed validation seeds
(deterministic policy, the training normalisation frozen), so its curve is comparable
across evaluations.
"""

from __future__ import annotations

import contextlib
import copy
import csv
import io
import json
import os
import platform
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import yaml

from agents.learned import latest_checkpoint, load_saved
from drill_env.physics.validation import flatten, jsonable
from drill_env.sweep import (
    LOCK_FILE,
    PARTIAL_FILE,
    folder_lock,
    noted_interrupt,
    save_text,
    save_whole,
    watch_interrupts,
)
from training.config import (
    TRAINED_WITH,
    TRAINING_SEEDS,
    VALIDATION_SEED,
    TrainConfig,
    algo_class,
    moved_settings,
    read_run_config,
    sb3_hyperparams,
    sb3_policy_kwargs,
    trained_with,
    without_inert_keys,
)


def planned_steps(config: TrainConfig, done: int = 0) -> int:
    """The env steps a run of ``config`` ends at, started or resumed after ``done``:
    ``n_timesteps``, except that SB3's PPO stops only after a whole rollout of
    ``n_steps`` x ``n_envs``, so it rounds the steps still to do up."""
    if config.algo != "ppo":
        return config.n_timesteps
    import inspect

    default = inspect.signature(algo_class("ppo")).parameters["n_steps"].default
    rollout = int(config.hyperparams.get("n_steps", default)) * config.n_envs
    return done + -(-(config.n_timesteps - done) // rollout) * rollout


def env_seed(config: TrainConfig, done: int = 0) -> int:
    """The seed of the training envs' reset when a run starts or resumes after ``done``
    env steps (env i gets it + i, SB3's convention), drawn by NumPy's ``SeedSequence``
    from (run seed, ``done``) into ``[TRAINING_SEEDS, 2**32 - n_envs)``. Not the run
    seed + i: runs of neighbouring seeds would then share all but one env's episodes
    (env i + 1 of seed 0 is env i of seed 1), and a resumed run would replay the
    episodes it started with. Above every validation and held-out seed."""
    state = int(np.random.SeedSequence([config.seed, done]).generate_state(1)[0])
    return TRAINING_SEEDS + state % (2**32 - TRAINING_SEEDS - config.n_envs)


def package_versions() -> dict[str, str]:
    """The versions a run's results depend on, for ``run.json`` (drill-env's and its
    sources' digest: a run folder said nothing of the code that trained it)."""
    from importlib.metadata import PackageNotFoundError, version

    from drill_env.sweep import source_digest

    found = {"drill_env_source_digest": source_digest("drill_env")}
    for package in ("drill-env", "stable-baselines3", "torch", "gymnasium", "numpy",
                    "numba"):
        try:
            found[package.replace("-", "_")] = version(package)
        except PackageNotFoundError:  # (drill-env run from its sources, not installed)
            found[package.replace("-", "_")] = "not installed"
    return found


def make_train_env(config: TrainConfig, seed: int) -> Any:
    """The batched training VecEnv, seeded, in a VecMonitor (the episode returns and
    lengths SB3 logs: ``rollout/ep_rew_mean`` in TensorBoard) and VecNormalize."""
    from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

    from drill_env.vector import make_sb3_vec_env

    venv = VecMonitor(make_sb3_vec_env(config.n_envs, env_id=config.env_id,
                                       **config.env_kwargs))
    venv.seed(seed)
    n = config.normalize
    return VecNormalize(venv, norm_obs=n.norm_obs, norm_reward=n.norm_reward,
                        clip_obs=n.clip_obs, gamma=config.reward_gamma)


def evaluate_policy_on_seeds(model: Any, normalizer: Any, env: Any, seeds: list[int]
                             ) -> dict[str, float]:
    """Deterministic episodes on ``seeds``: mean return, SSI and stuck share (info)."""
    returns, ssi, stuck = [], [], []
    for seed in seeds:
        obs, info = env.reset(seed=seed)
        total, ssis, stucks = 0.0, [], []
        while True:
            a, _ = model.predict(normalizer.normalize_obs(obs[None]), deterministic=True)
            obs, reward, terminated, truncated, info = env.step(a[0])
            total += float(reward)
            ssis.append(info["ssi"])
            stucks.append(info["stuck_fraction"])
            if terminated or truncated:
                break
        returns.append(total)
        ssi.append(float(np.mean(ssis)))
        stuck.append(float(np.mean(stucks)))
    return {"return": float(np.mean(returns)), "return_std": float(np.std(returns)),
            "ssi": float(np.mean(ssi)), "stuck_fraction": float(np.mean(stuck))}


class Resumed(NamedTuple):
    """Where a resumed run stands: training wall time so far (s), the validation return
    of its best model (-inf: none kept) and the env steps each earlier session started
    from (each session's envs were seeded by :func:`env_seed` from them; recorded since
    2026-12-05, empty for a run of an older version)."""

    wall_s: float
    best_return: float
    sessions: tuple[int, ...] = ()


#: A run that starts from nothing.
FRESH = Resumed(0.0, -np.inf)


def session_record(config: TrainConfig, sessions: Sequence[int]) -> list[dict[str, int]]:
    """``run.json``'s ``sessions``: the env steps each session started from and the seed
    of its envs' first reset (env i: + i), so a resumed run says every seed it trained on."""
    return [{"from_env_steps": done, "env_seed": env_seed(config, done)} for done in sessions]


def _sessions(record: Any) -> tuple[int, ...]:
    """The sessions' start steps from a progress or ``run.json`` record (none if it
    predates them)."""
    found = record.get("sessions", []) if isinstance(record, dict) else []
    return tuple(int(s["from_env_steps"]) if isinstance(s, dict) else int(s) for s in found)


def read_evaluations(path: Path) -> list[dict[str, str]]:
    """The rows of a run's ``evaluations.csv`` (none if there is none), each value a
    number: one that is not (an edit by hand) is a ValueError naming the file, its line
    and column. Read by a resume, the learning curve and a seed sweep's summary, it
    ended a resume with "could not convert string to float: 'abc'" after "resuming from",
    and again at every resume (an outside check)."""
    if not path.exists():
        return []
    with path.open(encoding="utf-8", newline="") as f:
        rows = list(csv.DictReader(f))
    for line, row in enumerate(rows, start=2):
        for column, value in row.items():
            try:
                float(value)
            except (TypeError, ValueError):
                raise ValueError(
                    f"{path}, line {line}: {column} {value!r} is not a number (edited by "
                    "hand?); mend or delete that line (a resume rewinds the file to its "
                    "checkpoint itself)") from None
    return rows


def _rewind(run: Path, steps: int, from_checkpoint: bool) -> Resumed:
    """Rewind the run's records to ``steps``, the checkpoint (or final model) it resumes
    from: evaluations after it belong to training that is done again, so their rows
    leave ``evaluations.csv``. The best model stays (it was evaluated), with its return."""
    path = run / "evaluations.csv"
    rows = read_evaluations(path)
    best = max((float(r["return"]) for r in rows), default=-np.inf) \
        if (run / "best_model.zip").exists() else -np.inf
    kept = [r for r in rows if int(float(r["timesteps"])) <= steps]
    if len(kept) < len(rows):
        save_text(path, csv_text(rows[0], kept), newline="")  # whole, as add_row writes
    progress = run / "checkpoints" / f"progress_{steps}.json"
    sessions: tuple[int, ...] = ()
    if from_checkpoint and progress.exists():
        try:
            record = json.loads(progress.read_text(encoding="utf-8"))
            wall = float(record["wall_s"])
            sessions = _sessions(record)
        except (ValueError, KeyError, TypeError) as err:  # written whole since 2026-12-05
            raise ValueError(f"resume: {progress} is damaged ({err!r}); delete it (the run's "
                             "wall time then counts from its last evaluation)") from None
    elif not from_checkpoint and (run / "run.json").exists():
        record = json.loads((run / "run.json").read_text(encoding="utf-8"))
        wall = float(record.get("wall_s", 0.0))
        sessions = _sessions(record)
    else:  # a checkpoint of an older version: the last evaluation before it
        wall = float(kept[-1]["wall_s"]) if kept else 0.0
    return Resumed(wall, best, sessions)


def crossed(before: int, now: int, every: int) -> bool:
    """Whether the env steps went past a multiple of ``every`` from ``before`` to ``now``:
    evaluations and checkpoints fall on the same grid of env steps however the run was
    interrupted and resumed (counted in calls from a resume, a run resumed from a Ctrl-C
    checkpoint at 2,092 steps evaluated at 3,092 and 4,092 instead of 3,000 and 4,000)."""
    return now // every > before // every


def _callbacks(config: TrainConfig, run: Path, train_env: Any,
               resumed: Resumed = FRESH, sessions: Sequence[int] = (0,)) -> list[Any]:
    import gymnasium as gym
    from stable_baselines3.common.callbacks import BaseCallback

    seeds = list(range(VALIDATION_SEED, VALIDATION_SEED + config.eval_episodes))
    eval_env = gym.make(config.env_id, **config.env_kwargs)
    # the run's training wall time, counted on from where a resumed run stopped
    started = time.perf_counter() - resumed.wall_s

    class OnGrid(BaseCallback):
        """Calls :meth:`fire` when the env steps pass a multiple of ``every``
        (:func:`crossed`). PPO crosses a grid line inside a rollout, whose update comes
        after it: it fires after that update (the next rollout's start, or the end of
        training), so that what it saves or scores under a number of steps is the model
        that learnt from them."""

        def __init__(self, every: int) -> None:
            super().__init__()
            self.every = every
            self.last = 0
            self.on_policy = False
            self.pending = False

        def _on_training_start(self) -> None:
            from stable_baselines3.common.on_policy_algorithm import OnPolicyAlgorithm

            self.on_policy = isinstance(self.model, OnPolicyAlgorithm)
            self.last = int(self.model.num_timesteps)

        def _on_step(self) -> bool:
            before, self.last = self.last, self.num_timesteps
            if crossed(before, self.last, self.every):
                self.act()
            return True

        def act(self) -> None:
            if self.on_policy:
                self.pending = True
            else:
                self.fire()

        def _on_rollout_start(self) -> None:
            if self.pending:
                self.fire()

        def _on_training_end(self) -> None:
            if self.pending:
                self.fire()

        def fire(self) -> None:
            raise NotImplementedError

    class SeededEval(OnGrid):
        """EvalCallback on fixed validation seeds: the same episodes every time, every
        ``eval_freq`` env steps (PPO's after the update: scored where the line was
        crossed, a one-rollout run kept its untrained policy as the best model and never
        scored the trained one)."""

        def __init__(self) -> None:
            super().__init__(config.eval_freq)
            self.path = run / "evaluations.csv"
            # a resumed run keeps its best model until an evaluation beats it
            self.best = resumed.best_return
            # the statistics as loaded, for an evaluation done again on resume: SB3's
            # learn() resets the envs first, which adds their observations to them (a new
            # user's trial: the redone row differed from the uninterrupted run's)
            self.loaded_rms: Any = copy.deepcopy(train_env.obs_rms)
            self.redo = False

        def _on_training_start(self) -> None:
            super()._on_training_start()
            # a Ctrl-C during an evaluation saves its checkpoint at the step that crossed
            # the grid line (on it when n_envs divides eval_freq) without that evaluation's
            # row: the resumed run evaluates there first
            line = self.last // self.every
            if line > 0 and not self._evaluated(line):
                self.num_timesteps = self.last
                self.redo = True
                self.act()

        def _evaluated(self, line: int) -> bool:
            """Whether an evaluation after crossing grid line ``line`` has its row."""
            return any(int(float(r["timesteps"])) // self.every == line
                       for r in read_evaluations(self.path))

        def to_tensorboard(self, scores: dict[str, float]) -> None:
            """Written at once at the evaluation's steps: recorded in SB3's logger, they
            waited for its next dump and came under that dump's steps, and the last
            evaluation's never came (a new user's trial)."""
            from stable_baselines3.common.logger import TensorBoardOutputFormat

            for output in self.logger.output_formats:
                if isinstance(output, TensorBoardOutputFormat):
                    output.write(scores, {key: () for key in scores},
                                 int(self.model.num_timesteps))
                    output.writer.flush()

        def fire(self) -> None:
            self.pending = False
            live = train_env.obs_rms
            if self.redo:  # scored (and kept as the best) with the checkpoint's statistics
                self.redo, train_env.obs_rms = False, self.loaded_rms
            try:
                result = evaluate_policy_on_seeds(self.model, train_env, eval_env, seeds)
                row = {"timesteps": int(self.model.num_timesteps), **result,
                       "wall_s": time.perf_counter() - started}
                add_row(self.path, row)
                self.to_tensorboard({f"validation/{key}": float(result[key])
                                     for key in ("return", "ssi", "stuck_fraction")})
                if result["return"] > self.best:
                    self.best = result["return"]
                    save_whole(run / "best_model.zip", self.model.save)
                    save_whole(run / "best_vecnormalize.pkl", train_env.save)
            finally:
                train_env.obs_rms = live
            plot_learning_curve(run, sessions)

    class Checkpoints(OnGrid):
        """Every ``checkpoint_freq`` env steps: :func:`write_checkpoint` (PPO's after the
        update: written where the line was crossed, a checkpoint held the model from
        before its last rollout's update, and a run resumed from it never learnt from
        that rollout, an outside check of interrupts found)."""

        def __init__(self) -> None:
            super().__init__(config.checkpoint_freq)

        def fire(self) -> None:
            self.pending = False
            write_checkpoint(run, self.model, train_env, time.perf_counter() - started,
                             sessions)

    callbacks = [SeededEval(), Checkpoints()]
    if config.torch_threads:
        callbacks.insert(0, torch_threads_callback(config.torch_threads))
    return callbacks


def new_model(config: TrainConfig, env: Any, **kwargs: Any) -> Any:
    """An untrained model of ``config`` (algorithm, policy, its kwargs, hyperparameters,
    seed) on ``env``; ``kwargs`` go to the algorithm (e.g. ``tensorboard_log``; without
    one the model logs nowhere)."""
    policy_kwargs = sb3_policy_kwargs(config.policy_kwargs)
    if config.algo == "sac":  # SAC's net_arch is per network; a list is shared
        policy_kwargs.setdefault("net_arch", [256, 256])
    if config.fused_adam and fused_adam_on_cpu() and not (
            {"optimizer_class", "optimizer_kwargs"} & set(policy_kwargs)):
        policy_kwargs["optimizer_kwargs"] = {"fused": True}  # SB3's default class: Adam
    model = algo_class(config.algo)(config.policy, env, seed=config.seed, verbose=0,
                                     policy_kwargs=policy_kwargs, **kwargs,
                                     **sb3_hyperparams(config.hyperparams))
    if kwargs.get("tensorboard_log") is None:
        # SB3 otherwise gives every learn() without a log folder an empty folder of its
        # own in the system's temporary directory (tempdir/SB3-<date>), never removed
        from stable_baselines3.common.logger import Logger

        model.set_logger(Logger(folder=None, output_formats=[]))
    return model


def fused_adam_on_cpu() -> bool:
    """Whether this torch has Adam's fused CPU kernel (torch 2.4 on; the project takes
    torch 2.3 too, where ``fused_adam`` then falls back to the plain update)."""
    import torch

    major, minor = (int(part) for part in torch.__version__.split(".")[:2])
    return (major, minor) >= (2, 4)


def stop_when_interrupted() -> Any:
    """An SB3 callback that raises KeyboardInterrupt at the env step after an interrupt
    whose own KeyboardInterrupt was lost (raised inside numba's compile callbacks, a
    Ctrl-C in the first minute of a run on an empty cache left it training)."""
    from stable_baselines3.common.callbacks import BaseCallback

    class StopWhenInterrupted(BaseCallback):
        def _on_step(self) -> bool:
            if (lost := noted_interrupt()) is not None:
                raise lost  # KeyboardInterrupt, or Terminated after a SIGTERM
            return True

    return StopWhenInterrupted()


def whole_updates() -> Any:
    """An SB3 callback under which an interrupt (Ctrl-C, SIGTERM) that arrives during a
    model update waits for the update to end: from the end of a rollout (``on_rollout_end``,
    PPO's epochs over it or SAC's gradient steps follow) to the next rollout's start or
    the end of training, the signals whose handlers are Python's are only heard, then
    given to those handlers. A Ctrl-C in PPO's epochs saved a checkpoint that had done
    7 of its 10 under the rollout's full count of steps, and the resumed run never did
    the other 3 (a new user's trial). A second interrupt stops it at once. Call
    ``release(give=False)`` on the way out of ``learn`` (an exception in the update) to
    put the handlers back."""
    import signal
    import sys
    import threading

    from stable_baselines3.common.callbacks import BaseCallback

    class WholeUpdates(BaseCallback):
        def __init__(self) -> None:
            super().__init__()
            self.held: dict[int, Any] = {}
            self.heard: list[int] = []

        def _on_step(self) -> bool:
            return True

        def _on_rollout_end(self) -> None:
            if threading.current_thread() is not threading.main_thread():
                return  # (signals reach the main thread only)
            for signum in (signal.SIGINT, signal.SIGTERM):
                handler = signal.getsignal(signum)
                if callable(handler):  # not SIG_IGN or SIG_DFL: left as they are
                    self.held[signum] = handler
                    signal.signal(signum, self.hear)

        def hear(self, signum: int, frame: Any) -> None:
            if self.heard:  # asked twice: at once, the update cut short (a scheduler's
                self.heard.append(signum)  # grace, a long update of one's own: a review)
                self.release()
                return
            with contextlib.suppress(RuntimeError, ValueError, OSError):
                print("interrupt heard: training stops when the model's update in "
                      "progress ends, so that its checkpoint holds the whole update (again: "
                      "at once, the update cut short)", file=sys.stderr, flush=True)
            self.heard.append(signum)

        def release(self, give: bool = True) -> None:
            for signum, handler in self.held.items():
                signal.signal(signum, handler)
            heard, self.held, self.heard = self.heard, {}, []
            if heard and give:
                signal.raise_signal(heard[0])  # its handler raises (KeyboardInterrupt)

        def _on_rollout_start(self) -> None:
            self.release()

        def _on_training_end(self) -> None:
            self.release()

    return WholeUpdates()


def torch_threads_callback(threads: int) -> Any:
    """An SB3 callback that holds torch at ``threads`` intra-op threads. torch's OpenMP
    thread count is the process's OpenMP one, which numba's OpenMP layer sets at every
    parallel (batched) env step, so a ``torch.set_num_threads`` before ``learn`` lasts
    one step; this sets it again after each env step (SB3 calls ``on_step`` after every
    env step, so the update that ends a rollout runs with it too)."""
    import torch
    from stable_baselines3.common.callbacks import BaseCallback

    class TorchThreads(BaseCallback):
        def _on_training_start(self) -> None:
            torch.set_num_threads(threads)

        def _on_step(self) -> bool:
            torch.set_num_threads(threads)
            return True

    return TorchThreads()


#: What a run folder holds once training started (any of them: the folder is a run).
RUN_FILES = ("config.yaml", TRAINED_WITH, "model.zip", "run.json", "checkpoints")
#: Everything training and evaluate write into a run folder: what ``overwrite`` deletes
#: (with the hidden ``.<name>.<pid>.partial<ext>`` of a save cut short, and evaluate's
#: ``evaluation`` and ``evaluation_<level>`` folders).
RUN_OUTPUTS = (*RUN_FILES, "vecnormalize.pkl", "best_model.zip", "best_vecnormalize.pkl",
               "evaluations.csv", "learning_curve.png", "tb")


def run_outputs(run: Path) -> tuple[list[Path], list[Path]]:
    """The entries of the folder ``run`` that training or evaluate wrote (see
    :data:`RUN_OUTPUTS`; evaluate's folders ``evaluation`` and ``evaluation_<level>``, a
    save's partial file), and the others."""
    from drill_env.physics.config import FIDELITY_LEVELS

    folders = {"evaluation", *(f"evaluation_{level}" for level in FIDELITY_LEVELS)}
    ours: list[Path] = []
    others: list[Path] = []
    for entry in sorted(run.iterdir()) if run.is_dir() else []:
        name = entry.name
        if name == LOCK_FILE:  # (held while a command writes the run: not deleted)
            continue
        written = (name in RUN_OUTPUTS or (name in folders and entry.is_dir())
                   or (PARTIAL_FILE.fullmatch(name) is not None and entry.is_file()))
        (ours if written else others).append(entry)
    return ours, others


def check_overwrite(run: Path) -> None:
    """FileExistsError, naming them, if ``run`` holds files training did not write:
    ``overwrite`` deletes only a run's own (``--overwrite`` on a folder that merely held
    a config.yaml deleted the whole folder: a security review)."""
    others = run_outputs(run)[1]
    if others:
        from drill_env.physics.units import few

        raise FileExistsError(
            f"{run} holds a training run and files training did not write ("
            + few([e.name for e in others], "in the folder") + "): --overwrite deletes "
            "only a run's own files; move those, delete the folder yourself or give "
            "another --name")


def clear_run(run: Path) -> None:
    """Delete what training and evaluate wrote into ``run`` (``overwrite``); a folder that
    holds anything else as well is refused (:func:`check_overwrite`), nothing deleted."""
    import shutil

    check_overwrite(run)
    ours, _ = run_outputs(run)
    for entry in ours:
        if entry.is_dir() and not entry.is_symlink():
            shutil.rmtree(entry)
        else:
            entry.unlink()


def holds_run(run: Path) -> bool:
    """Whether the folder ``run`` holds a training run (started or finished)."""
    return any((run / name).exists() for name in RUN_FILES)


def check_run_folder(run: Path, resume: bool, overwrite: bool,
                     config: TrainConfig | None = None) -> int:
    """FileExistsError if ``run`` holds a run and neither ``resume`` nor ``overwrite``.
    With ``resume`` and a ``config``, ValueError if the run was started with another
    config or has done ``config.n_timesteps`` env steps already (as the model it would load
    records them: :func:`resume_point`) and saved its final record (``run.json``; one
    stopped between its last step and that record goes on to save it), and (any run)
    if SAC would save a policy that never learnt (:func:`check_learns`). Returns the env
    steps the run starts from (0 but for a resume)."""
    if holds_run(run) and not (resume or overwrite):
        raise FileExistsError(f"{run} already holds a training run: --resume continues it, "
                              "--overwrite deletes its files and starts again, or give "
                              "another --name")
    if holds_run(run) and overwrite and not resume:
        check_overwrite(run)
    if config is None:
        return 0
    if not resume:
        check_learns(config, 0)
        return 0
    check_same_config(run, config)
    point = resume_point(run)
    if point is None:
        check_learns(config, 0)  # nothing to resume: it starts from the beginning
        return 0
    done, updates = point
    saved = run / "config.yaml"
    if done >= config.n_timesteps and not (run / "run.json").exists() and saved.exists() \
            and read_run_config(saved).get("n_timesteps") == config.n_timesteps:
        return done  # stopped after its last step, before its final save: it saves now
    if done >= config.n_timesteps:
        raise ValueError(f"--timesteps: {run} is finished (it has done {done} env steps "
                         f"already, {config.n_timesteps} asked for); give more than {done} "
                         "to continue it")
    check_learns(config, done, learnt=updates > 0)
    return done


def check_same_config(run: Path, config: TrainConfig, settings: bool = True) -> None:
    """ValueError if ``run`` was started with another config than ``config`` in anything
    but ``n_timesteps``, ``torch_threads`` and ``fused_adam`` (named by dotted path), or,
    with ``settings``, where its env's settings today differ from those it started
    under (its ``trained_with.json``: a default moved since)."""
    saved = run / "config.yaml"
    if saved.exists():
        old = flatten(without_inert_keys(read_run_config(saved)))
        new = flatten(jsonable(config))
        # change nothing a resumed run learnt (its model keeps its own optimiser)
        free = ("n_timesteps", "torch_threads", "fused_adam")
        changed = sorted(k for k in {*old, *new} if k not in free
                         and old.get(k) != new.get(k))
        if changed:  # each with both values (`--n-envs 4` was said as "n_envs differ")
            def shown(value: Any) -> str:
                return "unset" if value is None else json.dumps(value)

            said = "; ".join(f"{k}: the run's {shown(old.get(k))}, now {shown(new.get(k))}"
                             for k in changed)
            raise ValueError(f"resume: {run} was trained with another config ({said}; "
                             "only n_timesteps, torch_threads and fused_adam may change); "
                             "train it under another --name (a --seeds sweep: another "
                             "--out), or start it again (--overwrite)")
    # the same keywords, but the env's defaults moved since
    moved = moved_settings(run, config.env_id, config.env_kwargs) if settings else None
    if moved is not None:
        raise ValueError(f"resume: {run} started under other {config.env_id} settings "
                         f"than this code gives it ({moved}); train it again under another "
                         "--name (a --seeds sweep: another --out), or afresh (--overwrite)")


def finished(run: Path, config: TrainConfig) -> bool:
    """Whether ``run`` is a finished run of ``config``: its final record (``run.json``)
    written and its model at ``n_timesteps`` or beyond (ValueError if of another
    config). A seed sweep stopped after a run finished but before it noted the run goes
    on from it instead of refusing to train it further."""
    if not ((run / "run.json").exists() and (run / "config.yaml").exists()):
        return False
    check_same_config(run, config, settings=False)  # (a finished run is not trained on:
    # a default moved since is evaluate's note, not a reason to refuse the sweep)
    # a run trained for more steps than asked is not this config's result
    asked = read_run_config(run / "config.yaml").get("n_timesteps")
    point = resume_point(run)
    return asked == config.n_timesteps and point is not None and \
        point[0] >= config.n_timesteps


def check_learns(config: TrainConfig, done: int, learnt: bool = False) -> None:
    """ValueError if a run from ``done`` env steps to ``config.n_timesteps`` would save a
    policy that never made a gradient step: SAC first fills its replay buffer for
    ``learning_starts`` env steps (at the start, and again after a resume, as the buffer is
    not saved). A resumed model that ``learnt`` before is let through."""
    if config.algo != "sac" or learnt:
        return
    warm_up = int(config.hyperparams.get("learning_starts", 100))  # SB3's default: 100
    if config.n_timesteps <= done + warm_up:
        again = " (a resumed run fills its empty replay buffer again)" if done else ""
        raise ValueError(f"--timesteps: SAC learns only after its replay buffer's warm-up of "
                         f"{warm_up} env steps (learning_starts){again}; "
                         f"{config.n_timesteps} would save an untrained policy: give more "
                         f"than {done + warm_up}")


def resume_files(run: Path) -> tuple[Path, Path] | None:
    """(model, VecNormalize statistics) a resume of ``run`` loads: of its last checkpoint
    and its final model the one further on (a finished run's checkpoints are older than
    its final model; a Ctrl-C after a resume saves a checkpoint past it), the final one on
    a tie; None if it has neither."""
    final = (run / "model.zip", run / "vecnormalize.pkl")
    checkpoint = latest_checkpoint(run)
    if not all(p.exists() for p in final):
        return checkpoint
    if checkpoint is None or saved_steps(final[0])[0] >= saved_steps(checkpoint[0])[0]:
        return final
    return checkpoint


def resumed_statistics(saved: Any, venv: Any) -> Any:
    """The VecNormalize statistics ``saved`` (unpickled by :func:`load_saved`) on ``venv``,
    as ``VecNormalize.load`` sets them; a file holding something else is a ValueError."""
    from stable_baselines3.common.vec_env import VecNormalize

    if not isinstance(saved, VecNormalize):
        raise ValueError(f"resume: the checkpoint's statistics hold "
                         f"{type(saved).__name__}, not VecNormalize statistics "
                         "(VecNormalize.save)")
    saved.set_venv(venv)
    return saved


def saved_steps(model: Path) -> tuple[int, int]:
    """(env steps, gradient steps) a saved SB3 model records; reads the zip's ``data``
    entry only, not the networks."""
    import zipfile

    def read(path: str) -> dict[str, Any]:
        with zipfile.ZipFile(path) as archive:
            return json.loads(archive.read("data"))

    data = load_saved(model, read)
    return int(data["num_timesteps"]), int(data.get("_n_updates", 0))


def resume_point(run: Path) -> tuple[int, int] | None:
    """(env steps, gradient steps) of the model a resume of ``run`` would load
    (:func:`resume_files`), as the model file records them; None if it has none."""
    files = resume_files(run)
    return None if files is None else saved_steps(files[0])


def train(config: TrainConfig, run: Path, resume: bool = False, progress: bool = True,
          overwrite: bool = False) -> Path:
    """Train (or resume) the run in folder ``run``; returns the path of the final model.

    A folder that already holds a run is refused unless ``resume`` (continue it) or
    ``overwrite`` (delete it and start again). Resuming loads the last checkpoint's model
    and VecNormalize statistics, or the final model of a finished run without
    checkpoints; with nothing to resume it says so and starts from the beginning. SAC's
    replay buffer is not checkpointed (it would be ~100x the model), so a resumed SAC run
    starts from an empty buffer, which it fills for ``learning_starts`` steps (random
    actions, as at the start) before its first gradient step. Resuming with
    ``n_timesteps`` at or below the steps done is refused, but for a run stopped between
    its last step and its final save, resumed at its own ``n_timesteps``: it saves."""
    # one process trains a run: a second (a --resume of one still running) is refused
    with folder_lock(run, "this training run", tidy=("checkpoints",)):
        check_run_folder(run, resume, overwrite, config)
        if overwrite and not resume and holds_run(run):
            clear_run(run)
        # from here a Ctrl-C is noted as well as raised: one lost while the envs compile
        # (numba's first minute on an empty cache) stops the run at its first step
        with watch_interrupts():
            return _train(config, run, resume, progress)


def _train(config: TrainConfig, run: Path, resume: bool, progress: bool) -> Path:
    """:func:`train` once the folder is checked."""
    run.mkdir(parents=True, exist_ok=True)
    saved = run / "config.yaml"
    algo = algo_class(config.algo)
    latest = resume_files(run) if resume else None
    # else from the final model (or from nothing): which records _rewind keeps
    from_checkpoint = latest is not None and latest[0].name != "model.zip"
    if resume and latest is None:
        print(f"resume: nothing to resume in {run} yet (no checkpoint, no final model): "
              "training from the start")
    env = make_train_env(config, config.seed)
    if config.torch_threads:
        import torch

        # the model's initial weights depend on torch's thread count (the orthogonal
        # init's QR): built at the count the run trains with, a run of a seed sweep (its
        # workers hold torch at one thread) is the single run of that seed, weight for
        # weight. After the env: its first parallel reset sets the OpenMP thread count
        torch.set_num_threads(config.torch_threads)
    if latest is not None:  # its steps are below n_timesteps: check_run_folder said so
        model_path, norm_path = latest
        env = load_saved(norm_path, lambda saved: resumed_statistics(saved, env.venv),
                         pickled=True)
        model = load_saved(model_path, lambda p: algo.load(p, env=env,
                                                           tensorboard_log=str(run / "tb")))
        if hasattr(model, "learning_starts"):  # SAC: the replay buffer is not saved,
            # so it warms up again as at the start (learning_starts steps) before the
            # first gradient step: else the first updates sample 256 transitions from the
            # first few
            model.learning_starts = model.num_timesteps + int(
                config.hyperparams.get("learning_starts", 100))  # SB3's default: 100
        print(f"resuming from {model_path.name} ({model.num_timesteps} steps)")
        if getattr(model, "learning_starts", 0) >= config.n_timesteps:  # ("trained in 2 s")
            refill = model.learning_starts - model.num_timesteps
            print(f"note: SAC refills its replay buffer for {refill} steps after a resume "
                  f"before it learns, more than the "
                  f"{config.n_timesteps - model.num_timesteps} left to --timesteps "
                  f"{config.n_timesteps}: this session takes no gradient step, the model "
                  f"stays the checkpoint's (give --timesteps above {model.learning_starts} "
                  "to learn more)")
        resumed = _rewind(run, model.num_timesteps, from_checkpoint)
    else:
        model = new_model(config, env, tensorboard_log=str(run / "tb"))
        if resume:  # killed before its first checkpoint: its records go with it
            for name in ("evaluations.csv", "best_model.zip", "best_vecnormalize.pkl"):
                (run / name).unlink(missing_ok=True)
        resumed = FRESH
    # after SB3, which seeds the envs with the run seed (+ i) when it builds or loads
    seed = env_seed(config, int(model.num_timesteps))
    sessions = resumed.sessions  # and this one, unless it resumes one that did no step
    if not sessions or sessions[-1] != int(model.num_timesteps):
        sessions = (*sessions, int(model.num_timesteps))
    env.seed(seed)
    save_text(saved, yaml.safe_dump(jsonable(config), sort_keys=False))
    if latest is None:  # a resumed run keeps its start's (check_same_config compared it
        # with today's); one of a version before the record has none: today's settings
        # need not be those it trained under
        save_text(run / TRAINED_WITH, json.dumps(trained_with(config), indent=1))
    t0 = time.perf_counter()
    # to where the run ends (PPO: whole rollouts), so that the progress bar's total is
    # what it counts to (4,096 of 1,024 once read)
    remaining = max(0, planned_steps(config, model.num_timesteps) - model.num_timesteps)
    # SB3's progress bar, held here: SB3 closes it only when learning ends, so an
    # interrupt left rich's bar holding stdout and stderr, and in a notebook every later
    # cell's output came as the bar's HTML (an outside check)
    from stable_baselines3.common.callbacks import ProgressBarCallback

    bar = [ProgressBarCallback()] if progress else []
    try:
        if (lost := noted_interrupt()) is not None:  # while the envs were built
            raise lost
        # first: an interrupt heard in the update stops the run before a pending
        # evaluation or checkpoint runs (the resume does them)
        whole = whole_updates()
        try:
            model.learn(remaining, callback=[whole,
                                             *_callbacks(config, run, env, resumed, sessions),
                                             stop_when_interrupted(), *bar],
                        reset_num_timesteps=latest is None, tb_log_name=config.algo)
        finally:
            whole.release(give=False)  # (an exception in the update: the handlers back)
            # before the interrupt's message (closing twice, after SB3's own close, does
            for shown in bar:  # nothing)
                if getattr(shown, "pbar", None) is not None:
                    shown.pbar.close()
    except KeyboardInterrupt:
        save_interrupted(run, model, env, resumed.wall_s + time.perf_counter() - t0,
                         sessions)
        env.close()
        raise
    except ValueError as err:  # torch's distribution check: the policy's outputs are NaN
        if "found invalid values" not in str(err):
            raise
        env.close()
        raise ValueError(diverged_message(config, run, int(model.num_timesteps))) from None
    wall = time.perf_counter() - t0
    save_whole(run / "model.zip", model.save)
    save_whole(run / "vecnormalize.pkl", env.save)
    info = {"env_id": config.env_id, "algo": config.algo, "seed": config.seed,
            "env_steps": int(model.num_timesteps), "wall_s_this_session": wall,
            "wall_s": resumed.wall_s + wall,
            "env_seed": seed,  # of this session's first reset (env i: + i)
            "sessions": session_record(config, sessions),  # every session's
            "validation_seeds": {"first": VALIDATION_SEED, "count": config.eval_episodes},
            "machine": platform.platform(), "python": platform.python_version(),
            **package_versions()}
    save_text(run / "run.json", json.dumps(info, indent=2))
    plot_learning_curve(run, sessions)
    env.close()
    return run / "model.zip"


def diverged_message(config: TrainConfig, run: Path, steps: int) -> str:
    """What to say when training diverged (torch found NaN in the policy's outputs: a
    64-line tensor dump without a cause)."""
    rate = config.hyperparams.get("learning_rate")
    kept = latest_checkpoint(run)
    return (f"{config.algo}: training diverged at {steps} env steps (the policy's outputs "
            f"became NaN): {config.algo}.hyperparams.learning_rate "
            f"({rate if rate is not None else 'the default'}) or the network's scale "
            f"(policy_kwargs) too large for this task? Nothing saved at the divergence; "
            + (f"the last checkpoint is {kept[0]}" if kept else "no checkpoint yet"))


def save_interrupted(run: Path, model: Any, env: Any, wall_s: float,
                     sessions: Sequence[int] = (0,)) -> Path | None:
    """After a Ctrl-C: the model, its VecNormalize statistics and the wall time so far
    as a checkpoint (:func:`write_checkpoint`, as the periodic ones), so that ``--resume``
    continues from here and not from the last periodic checkpoint. Says what it kept.
    What is not kept: the steps of a PPO rollout cut short (counted in the model's steps,
    never learnt from, so the resumed run learns from that many fewer) and SAC's replay
    buffer (as at every resume). Returns the model's checkpoint (None before the first
    env step: nothing saved)."""
    from drill_env.sweep import COMMAND_VARIABLE

    steps = int(model.num_timesteps)
    # from the command line its options; from Python (a notebook) train()'s arguments
    command = bool(os.environ.get(COMMAND_VARIABLE))
    if steps <= 0:
        print(f"interrupted before the first env step: nothing saved in {run} but its "
              + ("config (--resume starts it, --overwrite starts afresh)" if command else
                 "config (train(..., resume=True) starts it, overwrite=True afresh)"))
        return None
    path = write_checkpoint(run, model, env, wall_s, sessions)
    # one write, so that the lines of a sweep's workers do not run into each other
    how = ("the same command with --resume (instead of --overwrite, if it had that) "
           "continues from it (a --seeds sweep: the same command)" if command else
           "train() with resume=True (instead of overwrite=True, if it had that) continues "
           "from it")
    print(f"interrupted at {steps} env steps: saved {path}; {how}\n", end="", flush=True)
    return path


def write_checkpoint(run: Path, model: Any, env: Any, wall_s: float,
                     sessions: Sequence[int] = (0,)) -> Path:
    """The model, its VecNormalize statistics (a resume needs both), the training wall
    time so far (a resumed run counts on from it) and the env steps each session started
    from (``run.json``'s ``sessions``), as ``checkpoints/model_<steps>_steps.zip``,
    ``vecnormalize_<steps>.pkl`` and ``progress_<steps>.json``; returns the model's file."""
    steps = int(model.num_timesteps)
    folder = run / "checkpoints"
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"model_{steps}_steps.zip"
    save_whole(path, model.save)
    save_whole(folder / f"vecnormalize_{steps}.pkl", env.save)
    save_text(folder / f"progress_{steps}.json", json.dumps(
        {"steps": steps, "wall_s": wall_s, "sessions": list(sessions)}))
    return path


def add_row(path: Path, row: dict[str, Any]) -> None:
    """Add ``row`` to the CSV file ``path`` (its header first if new), the whole file
    written anew and renamed into place (:func:`save_whole`): a process killed while it
    appended left a half row that the next row was glued to, and every later resume
    failed on it."""
    old = ""
    if path.exists():
        # its \r\n line ends as the csv module wrote them
        with path.open(newline="", encoding="utf-8") as f:
            old = f.read()
    save_text(path, old + csv_text(row, [row], header=not old), newline="")


def csv_text(fieldnames: Any, rows: list[dict[str, Any]], header: bool = True) -> str:
    """``rows`` as CSV text (the csv module's \r\n line ends), the header first."""
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=list(fieldnames))
    if header:
        writer.writeheader()
    writer.writerows(rows)
    return buffer.getvalue()


def plot_learning_curve(run: Path, sessions: Sequence[int] | None = None) -> Path | None:
    """``learning_curve.png``: validation return, SSI and stuck share against env steps;
    a dotted line where a resumed session started (``sessions``: the env steps each
    started from; None: ``run.json``'s), after which the training is not the
    uninterrupted run's (a new user's trial read the bumps there as learning)."""
    rows = read_evaluations(run / "evaluations.csv")
    if not rows:
        return None
    if sessions is None:
        try:
            sessions = _sessions(json.loads((run / "run.json").read_text(encoding="utf-8")))
        except (OSError, ValueError):
            sessions = ()
    resumed = sorted({s for s in sessions if s > 0})
    from drill_env.figures import agg_figure

    steps = np.array([float(r["timesteps"]) for r in rows]) / 1e3
    fig = agg_figure(figsize=(10, 3.6))
    axes = fig.subplots(1, 2)
    ret = np.array([float(r["return"]) for r in rows])
    std = np.array([float(r["return_std"]) for r in rows])
    # whiskers as well as the band: a band of one evaluation is not drawn
    axes[0].errorbar(steps, ret, yerr=std, fmt="o-", ms=3, capsize=3, elinewidth=0.8)
    axes[0].fill_between(steps, ret - std, ret + std, alpha=0.2)
    axes[0].set_ylabel("validation return (mean +- std)")
    ssi_values = np.array([float(r["ssi"]) for r in rows])
    stuck_values = np.array([100.0 * float(r["stuck_fraction"]) for r in rows])
    ssi = axes[1].plot(steps, ssi_values, "o-", ms=3, color="tab:blue", label="SSI")
    stuck_axis = axes[1].twinx()  # in % like every other picture's stuck share
    stuck = stuck_axis.plot(steps, stuck_values, "s--", ms=3, color="tab:orange",
                            label="time stuck (%)")
    axes[1].legend(handles=ssi + stuck, fontsize=8)
    # each axis in its line's colour: two scales share the panel
    axes[1].set_ylabel("SSI (of the env's 3 s metric\nwindow, mean over the episode)",
                       color="tab:blue")
    axes[1].tick_params(axis="y", colors="tab:blue")
    stuck_axis.set_ylabel("time stuck (% of the 3 s metric\nwindow, mean over the episode)",
                          color="tab:orange")
    stuck_axis.tick_params(axis="y", colors="tab:orange")
    # from 0, with room above the highest point (a flat curve sat on the frame's top);
    # the stuck share's highest point lower than the SSI's, so two flat lines part
    def highest(values: np.ndarray) -> float:
        finite = values[np.isfinite(values)]
        return float(finite.max()) if finite.size else 0.0

    stuck_axis.set_ylim(0.0, max(1.6 * highest(stuck_values), 1.0))
    axes[1].set_ylim(0.0, max(1.15 * highest(ssi_values), 0.05))
    # a line of zeros lies on the frame's bottom, where it cannot be seen: said (a check of
    # the pictures: task 2's stuck share, zero at every evaluation)
    nothing = [words for values, words in ((ssi_values, "no stick-slip (SSI 0)"),
                                           (stuck_values, "never stuck"))
               if np.isfinite(values).any() and highest(values) == 0.0]  # (not undefined)
    if nothing:
        axes[1].text(0.5, 0.5, " and ".join(nothing) + "\nat every evaluation",
                     transform=axes[1].transAxes, ha="center", va="center", fontsize=9,
                     color="0.3")
    axes[0].set_title("return", fontsize=10)
    axes[1].set_title("stick-slip", fontsize=10)
    for ax in axes:
        ax.set_xlabel("env steps (thousands)")
        ax.grid(alpha=0.3)
        for start in resumed:
            ax.axvline(start / 1e3, color="0.4", linestyle=":", linewidth=1.2)
    saved = run / "config.yaml"
    try:
        config = read_run_config(saved) if saved.exists() else {}
    except ValueError:
        config = {}  # the plot says less
    what = (f"{str(config['algo']).upper()} on task {config['task']}, deterministic policy "
            f"on {config['eval_episodes']} fixed validation seed"
            f"{'' if config['eval_episodes'] == 1 else 's'}"
            if {"algo", "task", "eval_episodes"} <= set(config)
            else "deterministic policy on the fixed validation seeds")
    if resumed:
        what += (f"; dotted: resumed at {', '.join(f'{start:,}' for start in resumed)} "
                 "env steps")
    from agents.plots import balanced_fill

    fig.suptitle(balanced_fill(f"{run.name}: {what}", 120))  # (a long run name and the
    fig.tight_layout()  # resumes ran off both sides)
    out = run / "learning_curve.png"
    save_whole(out, lambda file: fig.savefig(file, dpi=110))
    return out
