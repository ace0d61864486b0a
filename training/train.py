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
                            ``best_vecnormalize.pkl`` and its evaluation's row,
                            ``best_model.json``)
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
all envs' physics in one compiled call per step, seeded by
:func:`~training.run_folder.env_seed` (above every validation and evaluation seed); the
evaluation callback replays fixed validation seeds (deterministic policy, the training
normalisation frozen), so its curve is comparable across evaluations. The run's folder
and its checks live in :mod:`training.run_folder`, the callbacks inside ``learn`` in
:mod:`training.callbacks`, the curve's picture in :mod:`training.learning_curve`.
"""

from __future__ import annotations

import contextlib
import json
import os
import platform
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import yaml

from agents.learned import latest_checkpoint, load_saved
from drill_env.physics.validation import jsonable
from drill_env.sweep import (
    folder_lock,
    noted_interrupt,
    save_text,
    save_whole,
    watch_interrupts,
)
from training.callbacks import stop_when_interrupted, training_callbacks, whole_updates
from training.config import (
    TRAINED_WITH,
    VALIDATION_SEED,
    TrainConfig,
    algo_class,
    sb3_hyperparams,
    sb3_policy_kwargs,
    trained_with,
)
from training.learning_curve import plot_learning_curve
from training.run_folder import (
    BEST_RECORD,
    FRESH,
    check_run_folder,
    clear_run,
    env_seed,
    holds_run,
    resume_files,
    resumed_statistics,
    rewind,
    session_record,
    write_checkpoint,
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
    # else from the final model (or from nothing): which records rewind keeps
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
        resumed = rewind(run, model.num_timesteps, from_checkpoint)
    else:
        model = new_model(config, env, tensorboard_log=str(run / "tb"))
        if resume:  # killed before its first checkpoint: its records go with it
            for name in ("evaluations.csv", "best_model.zip", "best_vecnormalize.pkl",
                         BEST_RECORD):
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
            own = training_callbacks(config, run, env, resumed, sessions)
            model.learn(remaining, callback=[whole, *own, stop_when_interrupted(), *bar],
                        reset_num_timesteps=latest is None, tb_log_name=config.algo)
        finally:
            whole.release(give=False)  # (an exception in the update: the handlers back)
            # before the interrupt's message (closing twice, after SB3's own close, does
            for shown in bar:  # nothing; on a closed terminal it cannot write: EIO)
                if getattr(shown, "pbar", None) is not None:
                    with contextlib.suppress(OSError):
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
    with contextlib.suppress(OSError):  # (a closed terminal, SIGHUP's: EIO; saved all
        # the same)
        print(f"interrupted at {steps} env steps: saved {path}; {how}\n", end="",
              flush=True)
    return path
