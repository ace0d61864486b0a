"""What runs inside ``model.learn``: the validation evaluations on fixed seeds (their rows
and the best model), the checkpoints, the interrupts heard between whole model updates,
and torch's thread count while collecting and updating.
"""

from __future__ import annotations

import contextlib
import copy
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from drill_env.sweep import (
    STOPPING_SIGNALS,
    noted_interrupt,
    save_whole,
)
from training.config import (
    VALIDATION_SEED,
    TrainConfig,
)
from training.learning_curve import plot_learning_curve
from training.run_folder import (
    FRESH,
    Resumed,
    add_row,
    read_evaluations,
    write_best,
    write_checkpoint,
)


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


def crossed(before: int, now: int, every: int) -> bool:
    """Whether the env steps went past a multiple of ``every`` from ``before`` to ``now``:
    evaluations and checkpoints fall on the same grid of env steps however the run was
    interrupted and resumed (counted in calls from a resume, a run resumed from a Ctrl-C
    checkpoint at 2,092 steps evaluated at 3,092 and 4,092 instead of 3,000 and 4,000)."""
    return now // every > before // every


def training_callbacks(config: TrainConfig, run: Path, train_env: Any,
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
                    write_best(run, row)
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
            for signum in STOPPING_SIGNALS:
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
