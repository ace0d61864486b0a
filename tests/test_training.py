"""The training pipeline at CI size: train, save, reload, evaluate, resume."""

from __future__ import annotations

import contextlib
import csv
import dataclasses
import json
import pickle
import re
import zipfile
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
import yaml
from helpers import ctrl_c_as_in_a_terminal

from agents.learned import TRAINED, LearnedController, latest_checkpoint
from agents.registry import make_controller
from drill_cli.main import main
from training.config import load_config
from training.train import planned_steps, train


def tiny_config(**overrides):
    """PPO on task 1 at CI size: 2048 steps, 3 s episodes, evaluated every 1024 steps."""
    from drill_env.physics.config import replace

    settings = {"n_timesteps": 2048, "n_envs": 4, "eval_freq": 1024, "eval_episodes": 2,
                "checkpoint_freq": 1024, "env_kwargs": {"episode_duration": 3.0}}
    cfg = load_config("stick_slip", "ppo", **{**settings, **overrides})
    hyper = dict(cfg.hyperparams, n_steps=128, batch_size=128, n_epochs=2)
    return replace(cfg, hyperparams=hyper)


def train_interrupted_at(steps: int, cfg, folder, monkeypatch) -> None:
    """Train ``cfg`` into ``folder`` with a Ctrl-C at the first env step at or past
    ``steps`` (the KeyboardInterrupt the run saves its checkpoint on, then raises)."""
    from stable_baselines3.common.callbacks import BaseCallback

    import training.callbacks as tcb
    import training.train as tt

    class CtrlC(BaseCallback):
        def _on_step(self) -> bool:
            if self.num_timesteps >= steps:
                raise KeyboardInterrupt
            return True

    made = tcb.training_callbacks
    with monkeypatch.context() as patch:
        patch.setattr(tt, "training_callbacks", lambda *a, **k: [*made(*a, **k), CtrlC()])
        with pytest.raises(KeyboardInterrupt):
            train(cfg, folder, progress=False)


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    folder = tmp_path_factory.mktemp("runs") / "tiny"
    cfg = tiny_config()
    train(cfg, folder, progress=False)
    return folder, cfg


def test_a_run_folder_holds_everything(run):
    folder, cfg = run
    for name in ("config.yaml", "model.zip", "vecnormalize.pkl", "best_model.zip",
                 "best_vecnormalize.pkl", "best_model.json", "evaluations.csv",
                 "learning_curve.png", "run.json"):
        assert (folder / name).exists(), name
    assert yaml.safe_load((folder / "config.yaml").read_text())["n_timesteps"] == 2048
    with (folder / "evaluations.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert [int(r["timesteps"]) for r in rows] == [1024, 2048]
    # the best model's row, as the csv has it (the first of the highest return)
    best = max(rows, key=lambda r: float(r["return"]))
    kept = json.loads((folder / "best_model.json").read_text())["row"]
    assert kept == {k: pytest.approx(float(v), rel=1e-12) for k, v in best.items()}
    assert list((folder / "checkpoints").glob("model_*_steps.zip"))
    assert list((folder / "tb").iterdir())


def test_tensorboard_has_each_validation_score_at_its_evaluation(run):
    """Recorded in SB3's logger, the scores waited for its next dump: each came under the
    next dump's steps, and the last evaluation's never came (a new user's trial)."""
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    folder, _ = run
    with (folder / "evaluations.csv").open() as f:
        rows = list(csv.DictReader(f))
    logged: dict[int, float] = {}
    for events in (folder / "tb").iterdir():
        acc = EventAccumulator(str(events))
        acc.Reload()
        if "validation/return" in acc.Tags()["scalars"]:
            logged |= {e.step: e.value for e in acc.Scalars("validation/return")}
    assert sorted(logged) == [int(r["timesteps"]) for r in rows] == [1024, 2048]
    for r in rows:  # (TensorBoard keeps float32)
        assert logged[int(r["timesteps"])] == pytest.approx(float(r["return"]), rel=1e-6)


def test_reloaded_policy_acts_deterministically_with_its_normalisation(run):
    folder, _ = run
    controller = make_controller(f"learned:{folder}")
    assert isinstance(controller, LearnedController)
    assert controller.env_id == "DrillStickSlip-v0"

    def episode():
        env = gym.make(controller.env_id, **controller.env_kwargs())
        obs, info = env.reset(seed=123)
        controller.reset(env.unwrapped)
        actions, total = [], 0.0
        while True:
            a = controller.act(obs, info)
            actions.append(a.copy())
            obs, r, term, trunc, info = env.step(a)
            total += r
            if term or trunc:
                return np.array(actions), total

    (a1, r1), (a2, r2) = episode(), episode()
    np.testing.assert_array_equal(a1, a2)
    assert r1 == r2
    # the normalisation is the training one, frozen
    assert controller.normalizer.training is False
    assert controller.normalizer.obs_rms.count > 1000


def test_a_loaded_policy_brings_the_env_keywords_it_was_trained_with(run):
    """agents.learned: a policy acts "with the env keywords it was trained with" (its
    config.yaml's env_kwargs), which ``drill-env run --controller learned:RUN`` builds its
    task env from (a mutation test: a load that dropped them passed every test; a run
    trained with another ``history`` was then refused at reset in its own task)."""
    from agents.settings import guest_env_kwargs

    folder, cfg = run
    controller = make_controller(f"learned:{folder}")
    assert controller.env_kwargs() == cfg.env_kwargs == {"episode_duration": 3.0}
    assert guest_env_kwargs(controller) == cfg.env_kwargs


def test_evaluate_runs_the_policy_through_the_benchmark(run, tmp_path, capsys):
    folder, _ = run
    code = main(["evaluate", str(folder), "--seeds", "2", "--workers", "1",
                 "--out", str(tmp_path)])
    assert code == 0
    kept = "best_model.zip" if (folder / "best_model.zip").exists() else "model.zip"
    printed = capsys.readouterr().out
    assert f"evaluating {folder / kept} (" in printed
    with (tmp_path / "benchmark.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert {r["controller"] for r in rows} == {"learned", "stiff", "soft-speed",
                                               "soft-torque", "z-torque", "driller",
                                               "held-1", "held+0", "held+1", "random"}
    assert {int(r["seed"]) for r in rows} == {1_000_000, 1_000_001}
    # the policy paired against every other controller, printed and written
    comparison = (tmp_path / "comparison.md").read_text()
    for name in ("stiff", "driller", "held-1", "held+0", "held+1", "random"):
        assert f"| {name} | " in comparison
    assert "| learned | " not in comparison
    assert "one-sided paired t-test" in printed
    # the report names what it evaluated
    assert (tmp_path / "benchmark.md").read_text().startswith(
        f"# Evaluation of {folder.name} ({kept}, ppo on task stick_slip), held-out seeds "
        "1000000-1000001, physics level fast\n")  # no physics of its own: none named
    assert comparison.startswith(f"# Evaluation of {folder.name} (")
    # same targets for every controller of a seed
    for seed in ("1000000", "1000001"):
        assert len({r["target_rpm"] for r in rows if r["seed"] == seed}) == 1


def test_an_evaluation_names_the_physics_its_run_trained_on():
    """A run trained on a curved well (and a heavier mud) was evaluated there, as it must
    be, but comparison.md and the pictures read as if on the random scenario's vertical
    wells (an RL researcher's walkthrough)."""
    from training.evaluate import evaluation_heading

    trained = {"fidelity": "full", "physics": {"well": {"md": [0, 300]},
                                               "mud.density": 1300.0}}
    assert evaluation_heading("curved", "model.zip", "sac", "stick_slip", [7, 9], trained) \
        == ("Evaluation of curved (model.zip, sac on task stick_slip), held-out seeds 7-9, "
            "physics level full, the run's own mud, well")
    # one seed is said as one (it read "held-out seeds 1000000-1000000", a trial)
    assert ", held-out seed 7, physics" in evaluation_heading("one", "model.zip", "sac",
                                                              "stick_slip", [7], trained)


def test_resume_continues_from_the_last_checkpoint(run, tmp_path):
    """A resumed run may run longer (n_timesteps), not with other settings."""
    import shutil

    from drill_env.physics.config import replace

    folder, cfg = run
    copy = tmp_path / "copy"
    shutil.copytree(folder, copy)
    # advice a seed sweep (which takes no --name or --resume) can follow too
    with pytest.raises(ValueError, match=r"another config \(seed: the run's 0, now 5;"
                                         r".*under another "
                                         r"--name \(a --seeds sweep: another --out\)"):
        train(replace(cfg, seed=5), copy, resume=True, progress=False)
    train(replace(cfg, n_timesteps=3072), copy, resume=True, progress=False)
    with (copy / "evaluations.csv").open() as f:
        steps = [int(r["timesteps"]) for r in csv.DictReader(f)]
    assert steps[:2] == [1024, 2048] and steps[-1] == 3072


def test_a_resume_may_change_the_steps_the_threads_and_the_optimiser_kernel(run):
    """check_same_config: n_timesteps, torch_threads and fused_adam may change on a resume
    (torch's threads are the machine's; a model keeps the optimiser it was made with),
    nothing else (a mutation test: fused_adam left out of the free keys refused every
    resume that changed it, and no test said so)."""
    from drill_env.physics.config import replace
    from training.run_folder import check_same_config

    folder, cfg = run
    check_same_config(folder, replace(cfg, n_timesteps=4096, torch_threads=2,
                                      fused_adam=not cfg.fused_adam))
    with pytest.raises(ValueError, match=r"another config \(eval_episodes: the run's 2, now 3;"):
        check_same_config(folder, replace(cfg, eval_episodes=3))
    # a section emptied is said by the keys it lost, not as "the run's unset, now {}"
    # beside them (a trial: a variant run resumed with a file without env_kwargs)
    assert cfg.env_kwargs == {"episode_duration": 3.0}  # (the run's own)
    with pytest.raises(ValueError) as refused:
        check_same_config(folder, replace(cfg, env_kwargs={}))
    said = str(refused.value)
    assert "env_kwargs.episode_duration: the run's 3.0, now unset" in said
    assert "env_kwargs: " not in said


def test_a_resumed_run_keeps_counting_its_observation_statistics(run, tmp_path):
    """A resume loads the saved VecNormalize statistics and trains on with them: a fresh
    normaliser would show the policy differently scaled inputs mid-training and save
    statistics of the resumed steps alone."""
    import pickle
    import shutil

    from drill_env.physics.config import replace

    def counted(path):
        with open(path, "rb") as f:
            return pickle.load(f).obs_rms.count

    folder, cfg = run
    copy = tmp_path / "copy"
    shutil.copytree(folder, copy)
    before = counted(copy / "vecnormalize.pkl")
    assert before > cfg.n_timesteps - 1  # one observation per env step
    train(replace(cfg, n_timesteps=3072), copy, resume=True, progress=False)
    # on from the saved count: 1024 env steps and the resumed run's first reset (n_envs)
    assert counted(copy / "vecnormalize.pkl") == pytest.approx(before + 1024 + cfg.n_envs,
                                                               abs=0.5)


def test_validation_episodes_show_the_policy_normalised_observations():
    """The validation score (evaluations.csv, the choice of best_model.zip) runs the
    policy on the observations as it trained on them, through the frozen statistics."""
    from training.callbacks import evaluate_policy_on_seeds

    class Env:
        def reset(self, seed):
            self.t = 0
            return np.full(3, float(seed)), {}

        def step(self, action):
            self.t += 1
            info = {"ssi": 0.5 * self.t, "stuck_fraction": 0.25}
            return np.full(3, 10.0 + self.t), float(action[0]), False, self.t == 2, info

    class Normalizer:
        def normalize_obs(self, obs):
            return (obs - 4.0) / 2.0

    class Model:
        seen: list = []

        def predict(self, obs, deterministic):
            assert deterministic
            self.seen.append(obs.copy())
            return np.array([[1.0 + obs[0, 0]]]), None

    model = Model()
    scores = evaluate_policy_on_seeds(model, Normalizer(), Env(), [6, 8])
    np.testing.assert_array_equal(np.concatenate(model.seen)[:, 0], [1.0, 3.5, 2.0, 3.5])
    # returns: 2 + 4.5 and 3 + 4.5; SSI the mean of 0.5 and 1.0 per episode
    assert scores == pytest.approx({"return": 7.0, "return_std": 0.5, "ssi": 0.75,
                                    "stuck_fraction": 0.25})


def test_each_evaluation_plays_its_eval_episodes_validation_seeds(tmp_path, monkeypatch):
    """An evaluation scores the policy on ``eval_episodes`` fixed seeds from
    VALIDATION_SEED on, the ones run.json names (first and count; a mutation test: a range
    one seed short passed every test, each score then a mean over one seed fewer)."""
    import training.callbacks as tcb
    from training.config import VALIDATION_SEED

    played = []

    def scored(model, normalizer, env, seeds):
        played.append(list(seeds))
        return {"return": 0.0, "return_std": 0.0, "ssi": 0.0, "stuck_fraction": 0.0}

    monkeypatch.setattr(tcb, "evaluate_policy_on_seeds", scored)
    cfg = tiny_config(n_timesteps=512, eval_freq=512, checkpoint_freq=10_000, eval_episodes=3)
    train(cfg, tmp_path / "run", progress=False)
    record = json.loads((tmp_path / "run" / "run.json").read_text())
    assert record["validation_seeds"] == {"first": VALIDATION_SEED, "count": 3}
    assert played == [[VALIDATION_SEED, VALIDATION_SEED + 1, VALIDATION_SEED + 2]]


def test_evaluate_scores_a_run_at_the_fidelity_it_trained_at(run, tmp_path, monkeypatch):
    """A run trained at the full level is evaluated at the full level (its benchmark and
    the classical controllers beside it), not at the task's default fast level."""
    import shutil

    import training.evaluate as ev

    folder, _ = run
    copy = tmp_path / "full"
    shutil.copytree(folder, copy)
    config = yaml.safe_load((copy / "config.yaml").read_text())
    config["env_kwargs"] = {**config.get("env_kwargs", {}), "fidelity": "full"}
    (copy / "config.yaml").write_text(yaml.safe_dump(config))
    seen = []
    monkeypatch.setattr(ev, "run_benchmark", lambda *args, **kw: seen.append(args) or [])
    ev.evaluate_run(copy, seeds=1, out=tmp_path / "out", progress=False)
    assert [args[4].fidelity for args in seen] == ["full"]


def test_evaluate_judges_a_fast_trained_run_in_the_full_model_when_asked(
        run, tmp_path, monkeypatch, capsys):
    """``--fidelity full``: the policy and every controller beside it in the full model,
    said in a note and in the title, written beside the evaluation at the run's own level
    (RUN/evaluation_full), not over it. The tasks train at the fast level; judging there
    only was the one way (benchmark --task --fidelity full did it without the paired
    comparison)."""
    import training.evaluate as ev
    from drill_cli.train import default_evaluation_folder

    folder, _ = run
    seen = []
    monkeypatch.setattr(ev, "run_benchmark", lambda *args, **kw: seen.append((args, kw)) or [])
    ev.evaluate_run(folder, seeds=1, out=tmp_path / "out", progress=False, fidelity="full")
    assert [args[4].fidelity for args, _ in seen] == ["full"]
    assert "physics level full (trained at fast)" in seen[0][1]["heading"]
    assert "the run trained at the fast level; evaluate scores it" in capsys.readouterr().out
    assert default_evaluation_folder(folder, "full") == folder / "evaluation_full"
    assert default_evaluation_folder(folder, "fast") == default_evaluation_folder(folder) \
        == folder / "evaluation"
    with pytest.raises(SystemExit):
        main(["evaluate", str(folder), "--fidelity", "medium"])
    assert "argument --fidelity: invalid choice: 'medium'" in capsys.readouterr().err


@pytest.mark.parametrize("signum", ["SIGINT", "SIGTERM"])
def test_an_interrupt_whose_exception_is_lost_still_stops_training(tmp_path, monkeypatch,
                                                                   signum):
    """A Ctrl-C (or the command line's SIGTERM) that lands in numba's compile callbacks
    (ctypes) has its exception printed as "Exception ignored" and dropped: the run
    trained on. Emulated by the signal raised and its exception swallowed, once while the
    envs are built and once inside a step's callbacks: the run stops before its first
    step (nothing to save) or at that step (its checkpoint saved), with the signal's own
    exception (a SIGTERM exits 143, not 130)."""
    import signal

    import training.callbacks as tcb
    import training.train as tt
    from drill_cli.interrupts import stop_as_interrupt
    from drill_env.sweep import Terminated

    def lose_one() -> None:
        number = getattr(signal, signum)
        try:
            signal.getsignal(number)(number, None)  # the handler the signal runs
        except KeyboardInterrupt:
            pass  # lost, as inside a ctypes callback

    expected = Terminated if signum == "SIGTERM" else KeyboardInterrupt
    restore, _ = stop_as_interrupt()  # the command line's SIGTERM and SIGHUP handlers
    try:
        with ctrl_c_as_in_a_terminal():
            real_make, real_crossed, calls = tt.make_train_env, tcb.crossed, []

            def make_train_env(config, seed):
                lose_one()
                return real_make(config, seed)

            monkeypatch.setattr(tt, "make_train_env", make_train_env)
            with pytest.raises(expected):
                train(tiny_config(), tmp_path / "while_built", progress=False)
            assert latest_checkpoint(tmp_path / "while_built") is None
            monkeypatch.setattr(tt, "make_train_env", real_make)

            def crossed(before, now, every):
                calls.append(now)
                if len(calls) == 300:
                    lose_one()
                return real_crossed(before, now, every)

            monkeypatch.setattr(tcb, "crossed", crossed)
            folder = tmp_path / "while_stepping"
            with pytest.raises(expected):
                train(tiny_config(), folder, progress=False)
            saved = latest_checkpoint(folder)
            assert saved is not None
            steps = int(saved[0].stem.split("_")[1])
            assert steps < 2048 and steps == calls[299]  # the step the interrupt arrived in
            assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # restored
    finally:
        restore()


@pytest.mark.parametrize("signum", ["SIGINT", "SIGTERM", "SIGHUP"])
def test_an_interrupt_in_the_update_waits_for_the_update_to_end(run, tmp_path, monkeypatch,
                                                                capsys, signum):
    """A Ctrl-C (or the command line's SIGTERM or SIGHUP) in PPO's epochs saved a checkpoint that
    had done some of them under the rollout's full count of steps, and the resumed run
    never did the rest (a new user's trial: 7 of 10). Now the run stops when the update
    ends, before the evaluation due there; the resume does that evaluation with the
    checkpoint's model, which is the uninterrupted run's: its row is the same."""
    import os
    import signal

    from stable_baselines3 import PPO

    from drill_cli.interrupts import HungUp, stop_as_interrupt
    from drill_env.sweep import Terminated
    from training.run_folder import read_evaluations, saved_steps

    number = getattr(signal, signum)
    real, calls = PPO.train, []

    def update(self):
        calls.append(self.num_timesteps)
        if len(calls) == 2:  # the second update (at 1024 steps, an evaluation's line)
            os.kill(os.getpid(), number)  # lands as it begins
        real(self)

    monkeypatch.setattr(PPO, "train", update)
    folder = tmp_path / "cut"
    with ctrl_c_as_in_a_terminal():  # (first: a nohup'd run's SIGHUP is then no more
        # ignored, and the command line's handler takes it)
        restore, _ = stop_as_interrupt()  # the command line's SIGTERM and SIGHUP handlers
        try:
            with pytest.raises({"SIGINT": KeyboardInterrupt, "SIGTERM": Terminated,
                                "SIGHUP": HungUp}[signum]):
                train(tiny_config(), folder, progress=False)
            assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
        finally:
            assert signal.getsignal(signal.SIGTERM) is not signal.SIG_DFL  # (put back)
            restore()
    assert "stops when the model's update in progress ends" in capsys.readouterr().err
    saved = latest_checkpoint(folder)
    assert saved is not None
    assert saved_steps(saved[0]) == (1024, 4)  # two whole updates of 2 epochs each
    assert not (folder / "evaluations.csv").exists()  # due after the update: not done
    if signum != "SIGINT":
        return
    monkeypatch.setattr(PPO, "train", real)
    train(tiny_config(), folder, resume=True, progress=False)
    rows = read_evaluations(folder / "evaluations.csv")
    reference = read_evaluations(run[0] / "evaluations.csv")
    assert [int(float(r["timesteps"])) for r in rows] == [1024, 2048]
    assert float(rows[0]["return"]) == pytest.approx(float(reference[0]["return"]),
                                                     rel=1e-9)


def test_a_second_interrupt_in_an_update_stops_at_once():
    """The first interrupt in an update waits for its end (the rollout's start gives it);
    a second stops at once (a scheduler's grace, an update of one's own that takes long:
    a review); without one, nothing is raised and the handlers come back."""
    import os
    import signal

    from training.callbacks import whole_updates

    with ctrl_c_as_in_a_terminal():
        whole = whole_updates()
        whole._on_rollout_end()  # the update begins
        os.kill(os.getpid(), signal.SIGINT)  # heard, held
        with pytest.raises(KeyboardInterrupt):
            os.kill(os.getpid(), signal.SIGINT)  # again: at once
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
        whole._on_rollout_end()
        os.kill(os.getpid(), signal.SIGINT)
        with pytest.raises(KeyboardInterrupt):
            whole._on_rollout_start()  # given when the update is over
        whole._on_rollout_end()
        whole._on_rollout_start()  # none heard: nothing raised
        whole._on_rollout_end()
        os.kill(os.getpid(), signal.SIGINT)
        whole.release(give=False)  # the update raised: its exception goes on, not this
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_a_damaged_checkpoint_is_named_and_files_are_written_whole(run, tmp_path):
    """A checkpoint cut short (a full disk, a copy killed) made --resume crash with an
    UnpicklingError or BadZipFile traceback; now the error names the file and the way on.
    Saved files go through a hidden partial name, so a killed writer leaves none cut
    short under the names a resume reads (and no partial file after a clean save)."""
    import shutil

    from drill_env.physics.config import replace

    folder, cfg = run
    assert not list(folder.rglob(".*.partial*"))
    for damaged in ("vecnormalize", "model"):
        copy = tmp_path / damaged
        shutil.copytree(folder, copy)
        for name in ("model.zip", "vecnormalize.pkl"):  # resume from the checkpoint
            (copy / name).unlink()
        model, norm = latest_checkpoint(copy)
        path = norm if damaged == "vecnormalize" else model
        path.write_bytes(path.read_bytes()[:200])
        with pytest.raises(ValueError, match=rf"^{re.escape(str(path))}: damaged, cannot be "
                                             r"loaded .*delete it"):
            train(replace(cfg, n_timesteps=3072), copy, resume=True, progress=False)
        # evaluate and learned:<run> name the file too (SB3's own error named no run)
        with pytest.raises(ValueError, match=rf"^{re.escape(str(path))}: damaged"):
            LearnedController.load(copy, files=(model, norm))
        if damaged == "vecnormalize":  # text over it: pickle read "garbage" as opcodes
            # and gave int()'s ValueError, naming no file (an outside check)
            norm.write_bytes(b"garbage\n")
            with pytest.raises(ValueError, match=rf"^{re.escape(str(norm))}: damaged, "
                                                 r"cannot be loaded \(UnpicklingError: "
                                                 "ValueError"):
                LearnedController.load(copy, files=(model, norm))


class _Noting:
    """Unpickles as a call of ``_note``: a line written to a file, then an error."""

    def __init__(self, marker: str) -> None:
        self.marker = marker

    def __reduce__(self):
        return (_note, (self.marker,))


def _note(marker: str):
    with open(marker, "a") as f:
        f.write("RAN\n")
    raise ValueError("a payload's error")


def test_a_pickle_is_unpickled_once_and_must_hold_statistics(run, tmp_path):
    """A security review: a statistics file whose unpickling fails was unpickled a second
    time to tell damage from the load's own error, running its code twice; and a pickle
    of something other than VecNormalize statistics ended the load of a policy with
    "'int' object has no attribute 'training'". Now the file is unpickled once (its error
    is damage, named), and what it holds is checked for the policy and for a resume."""
    import pickle
    import shutil

    from drill_env.physics.config import replace

    folder, cfg = run
    copy = tmp_path / "copy"
    shutil.copytree(folder, copy)
    marker = tmp_path / "marker"
    (copy / "vecnormalize.pkl").write_bytes(pickle.dumps(_Noting(str(marker))))
    with pytest.raises(ValueError, match=r"vecnormalize.pkl: damaged, cannot be loaded "
                                         r"\(UnpicklingError: ValueError: a payload's"):
        LearnedController.load(copy, files=(copy / "model.zip", copy / "vecnormalize.pkl"))
    assert marker.read_text() == "RAN\n"
    # statistics under another suffix load as statistics (they are judged by what they
    # hold, not by their name)
    renamed = tmp_path / "stats.pickle"
    shutil.copy(folder / "vecnormalize.pkl", renamed)
    LearnedController.load(copy, files=(copy / "model.zip", renamed))
    (copy / "vecnormalize.pkl").write_bytes(pickle.dumps(7))
    with pytest.raises(ValueError, match=r"vecnormalize.pkl holds int, not VecNormalize "
                                         r"statistics"):
        LearnedController.load(copy, files=(copy / "model.zip", copy / "vecnormalize.pkl"))
    for name in ("model.zip", "vecnormalize.pkl"):  # resume from the checkpoint
        (copy / name).unlink()
    _, norm = latest_checkpoint(copy)
    norm.write_bytes(pickle.dumps([1, 2]))
    with pytest.raises(ValueError, match=r"resume: the checkpoint's statistics hold "
                                         r"list, not VecNormalize"):
        train(replace(cfg, n_timesteps=3072), copy, resume=True, progress=False)


@pytest.mark.parametrize("text", ["", "ppo: {n_envs: 4", "- a list\n", "algo: ppo\n"])
def test_a_damaged_run_config_is_named_by_every_command_that_reads_it(run, tmp_path, text,
                                                                      capsys):
    """From a walkthrough: a config.yaml cut short (it was written in place, so a kill or
    a full disk could leave it so) gave evaluate, train --resume and a benchmark of
    learned:RUN a YAML or TypeError traceback, or blamed a --task that was given. Now
    each names the file and the way on, and the file is written whole (a hidden partial
    file renamed)."""
    import shutil

    from agents.settings import task_settings
    from drill_cli.main import main
    from training.evaluate import evaluate_run

    folder, cfg = run
    copy = tmp_path / "run"
    shutil.copytree(folder, copy)
    saved = copy / "config.yaml"
    saved.write_text(text)
    said = rf"^{re.escape(str(saved))}: .*train it again \(--overwrite\) or delete the folder"
    with pytest.raises(ValueError, match=said):
        evaluate_run(copy, seeds=1, progress=False)
    with pytest.raises(ValueError, match=said):
        train(cfg, copy, resume=True, progress=False)
    with pytest.raises(ValueError, match=said):
        LearnedController.load(copy)
    with pytest.raises(ValueError, match=said):
        task_settings([f"learned:{copy}"], "DrillStickSlip-v0")
    assert main(["train", "--task", "stick_slip", "--algo", "ppo", "--resume",
                 "--name", copy.name, "--out", str(tmp_path)]) == 2
    assert f"drill-env train: error: {saved}: " in capsys.readouterr().err


def test_a_benchmark_refuses_a_damaged_policy_before_any_episode(run, tmp_path):
    """A damaged policy file stopped `evaluate` and `benchmark` only after the classical
    controllers' episodes had run (the policy is first loaded in its own episode's
    worker); it is loaded once up front now, so nothing runs and nothing is stored."""
    import shutil

    from agents.benchmark import RESULTS_FILE, run_benchmark
    from agents.settings import BenchmarkSettings

    folder, _ = run
    copy = tmp_path / "damaged"
    shutil.copytree(folder, copy)
    norm = copy / "best_vecnormalize.pkl"
    norm.write_bytes(b"junk")
    out = tmp_path / "bench"
    with pytest.raises(ValueError, match=rf"^{re.escape(str(norm))}: damaged"):
        run_benchmark(["stiff", f"learned:{copy}"], ["random"], [0], out,
                      BenchmarkSettings(duration=2.0, warmup=1.0, fidelity="fast"),
                      workers=1, progress=False, env_id="DrillStickSlip-v0")
    assert not (out / RESULTS_FILE).exists() or not (out / RESULTS_FILE).read_text().strip()


def test_a_finished_run_resumes_from_its_final_model_not_an_older_checkpoint(run, tmp_path):
    """A run that ended keeps checkpoints older than its final model: a resume continues
    from the final model (resumed from the last checkpoint it threw finished steps away
    and overwrote the final model), and a --timesteps at or below what the final model
    did is refused. A Ctrl-C after that resume saves a checkpoint past the final model,
    which the next resume takes."""
    import shutil

    from drill_env.physics.config import replace
    from training.run_folder import resume_files, resume_point, saved_steps

    folder, cfg = run
    copy = tmp_path / "copy"
    shutil.copytree(folder, copy)
    done = json.loads((copy / "run.json").read_text())["env_steps"]
    assert resume_files(copy) == (copy / "model.zip", copy / "vecnormalize.pkl")
    assert resume_point(copy)[0] == done == cfg.n_timesteps
    for steps in (done, done - 512):  # (a resume of a finished run says it is first)
        with pytest.raises(ValueError, match=f"^--timesteps: .* has done {done} env steps "
                                             f"already, {steps} asked for; give "
                                             f"--timesteps above {done}"):
            train(replace(cfg, n_timesteps=steps), copy, resume=True, progress=False)
    later = copy / "checkpoints" / f"model_{done + 512}_steps.zip"  # as a Ctrl-C saves
    shutil.copy(copy / "model.zip", later)
    shutil.copy(copy / "vecnormalize.pkl", copy / "checkpoints" / f"vecnormalize_{done + 512}.pkl")
    with zipfile.ZipFile(later) as old, zipfile.ZipFile(tmp_path / "m.zip", "w") as new:
        for item in old.infolist():
            data = old.read(item.filename)
            if item.filename == "data":
                record = json.loads(data)
                record["num_timesteps"] = done + 512
                data = json.dumps(record).encode()
            new.writestr(item, data)
    shutil.move(tmp_path / "m.zip", later)
    assert resume_files(copy)[0] == later and saved_steps(later)[0] == done + 512


def test_a_ppo_checkpoint_holds_the_model_that_learnt_from_its_steps(run):
    """PPO's scheduled checkpoints were written where the rollout crossed the grid line,
    before that rollout's update: a run resumed from one (after a kill) never learnt from
    that rollout, and a Ctrl-C checkpoint of the same name held a model one update on (an
    outside check of interrupts). Written after the update, as the evaluations are, the
    checkpoint at 1,024 steps has the updates of two rollouts, and the last one is the
    final model."""
    import torch
    from stable_baselines3 import PPO

    folder, cfg = run
    epochs, rollout = cfg.hyperparams["n_epochs"], cfg.hyperparams["n_steps"] * cfg.n_envs
    first = PPO.load(folder / "checkpoints" / "model_1024_steps.zip")
    assert first._n_updates == epochs * 1024 // rollout
    last = PPO.load(folder / "checkpoints" / f"model_{cfg.n_timesteps}_steps.zip")
    final = PPO.load(folder / "model.zip")
    assert last._n_updates == final._n_updates == epochs * cfg.n_timesteps // rollout
    weights, kept = final.policy.state_dict(), last.policy.state_dict()
    assert all(torch.equal(weights[k], kept[k]) for k in weights)


def test_a_run_stopped_between_its_last_step_and_its_final_save_finishes_on_resume(
        run, tmp_path):
    """Killed after its last checkpoint (the last step's) but before model.zip and
    run.json were written, a run could never be finished: resume and a seed sweep refused
    it as having done its steps (an outside check of interrupts). Resumed, it saves its
    final files from that checkpoint, its weights as they were, without a step more."""
    import shutil

    import torch
    from stable_baselines3 import PPO

    from agents.learned import latest_checkpoint
    from drill_env.physics.config import replace
    from training.run_folder import saved_steps

    folder, cfg = run
    copy = tmp_path / "copy"
    shutil.copytree(folder, copy)
    for name in ("model.zip", "vecnormalize.pkl", "run.json"):
        (copy / name).unlink()
    last, _ = latest_checkpoint(copy)
    assert saved_steps(last)[0] == cfg.n_timesteps
    # fewer steps than it was started for is still refused, not "finished" short
    with pytest.raises(ValueError, match=f"has done {cfg.n_timesteps} env steps already"):
        train(replace(cfg, n_timesteps=1024), copy, resume=True, progress=False)
    train(cfg, copy, resume=True, progress=False)
    record = json.loads((copy / "run.json").read_text())
    assert record["env_steps"] == cfg.n_timesteps and (copy / "vecnormalize.pkl").exists()
    before = PPO.load(last).policy.state_dict()
    after = PPO.load(copy / "model.zip").policy.state_dict()
    assert all(torch.equal(before[k], after[k]) for k in before)
    with pytest.raises(ValueError, match=f"has done {cfg.n_timesteps} env steps already"):
        train(cfg, copy, resume=True, progress=False)  # finished now


def test_a_resumed_run_redoes_the_evaluations_after_its_checkpoint(run, tmp_path):
    """Killed after the evaluation at 2048 steps but before its checkpoint, a run resumes
    from 1024: the evaluation at 2048 is done again and replaces the old row, and the
    wall time counts on from the checkpoint's instead of starting at zero."""
    import shutil

    folder, cfg = run
    copy = tmp_path / "copy"
    shutil.copytree(folder, copy)
    for name in ("model_2048_steps.zip", "vecnormalize_2048.pkl", "progress_2048.json"):
        (copy / "checkpoints" / name).unlink()
    for name in ("model.zip", "vecnormalize.pkl", "run.json"):  # killed: it never ended
        (copy / name).unlink()
    at_checkpoint = json.loads((copy / "checkpoints" / "progress_1024.json").read_text())
    train(cfg, copy, resume=True, progress=False)
    with (copy / "evaluations.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert [int(r["timesteps"]) for r in rows] == [1024, 2048]
    assert float(rows[1]["wall_s"]) > at_checkpoint["wall_s"] > 0.0
    run_info = json.loads((copy / "run.json").read_text())
    assert run_info["wall_s"] > run_info["wall_s_this_session"] + at_checkpoint["wall_s"] - 1e-9


def test_an_existing_run_is_neither_overwritten_nor_silently_restarted(run, tmp_path,
                                                                       capsys):
    import shutil

    from drill_env.physics.config import replace

    folder, cfg = run
    copy = tmp_path / "copy"
    shutil.copytree(folder, copy)
    (copy / "evaluation").mkdir()  # what drill-env evaluate leaves beside a run
    with pytest.raises(FileExistsError, match="--resume continues it, --overwrite"):
        train(cfg, copy, progress=False)
    # a finished run without checkpoints resumes from its final model, and not below
    # the steps it has done
    shutil.rmtree(copy / "checkpoints")
    with pytest.raises(ValueError, match="--timesteps: .* has done 2048 env steps"):
        train(cfg, copy, resume=True, progress=False)
    # the command refuses it before it announces a training; a named run resumes with
    # its own algorithm (PPO here, where the command's default is SAC)
    capsys.readouterr()
    assert main(["train", "--task", "stick_slip", "--out", str(tmp_path),
                 "--name", "copy", "--resume", "--timesteps", "2048"]) != 0
    said = capsys.readouterr()
    assert "has done 2048 env steps" in said.err and "training PPO" not in said.out
    assert "(a --seeds sweep: another --out)" in said.err  # (a sweep adopts such a run)
    assert yaml.safe_load((copy / "config.yaml").read_text())["n_timesteps"] == 2048
    # PPO runs whole rollouts (128 x 4 here): 2300 steps end at 2560
    longer = replace(cfg, n_timesteps=2300)
    train(longer, copy, resume=True, progress=False)
    assert "nothing to resume" not in capsys.readouterr().out
    done = json.loads((copy / "run.json").read_text())["env_steps"]
    assert done == planned_steps(longer, 2048) == 2560
    assert planned_steps(replace(load_config("stick_slip", "sac"), n_timesteps=2300)) == 2300
    # nothing at all to resume: said, then trained from the start
    fresh = tmp_path / "fresh"
    small = tiny_config(n_timesteps=512, eval_freq=10_000, checkpoint_freq=10_000)
    train(small, fresh, resume=True, progress=False)
    assert "nothing to resume" in capsys.readouterr().out
    train(small, copy, overwrite=True, progress=False)  # a new run: the old one is gone
    assert not (copy / "evaluation").exists() and not (copy / "evaluations.csv").exists()
    assert (copy / "model.zip").exists()
    # every entry a run holds is one --overwrite may delete (a new output would be left
    # out of RUN_OUTPUTS, and a folder of it refused as not a run's own)
    from training.run_folder import run_outputs

    assert run_outputs(copy)[1] == []


def test_overwrite_deletes_only_a_runs_own_files(tmp_path):
    """A security review: `train --overwrite` on a folder that held a config.yaml beside a
    project's sources (src/, notes.md) deleted the whole folder. Now a folder with files
    training did not write is refused, naming them, and nothing is deleted; a run's own
    files (an evaluation and a save cut short included) are deleted, and the run starts
    afresh."""
    import shutil

    from training.run_folder import check_run_folder, clear_run

    project = tmp_path / "proj"
    (project / "src").mkdir(parents=True)
    (project / "config.yaml").write_text("key: 1\n")
    (project / "src" / "important.txt").write_text("precious\n")
    (project / "notes.md").write_text("x\n")
    # a run by its config.yaml: refused before anything is said or deleted
    for refuse in (lambda: check_run_folder(project, resume=False, overwrite=True),
                   lambda: clear_run(project)):
        with pytest.raises(FileExistsError, match=r"files training did not write \(notes.md, "
                                                  r"src\): --overwrite deletes only"):
            refuse()
    assert (project / "src" / "important.txt").read_text() == "precious\n"
    assert (project / "config.yaml").exists() and (project / "notes.md").exists()
    # names near evaluate's and a save's are not theirs (a review: a note named
    # evaluation_notes.md and a hidden folder .partial_keep were deleted)
    (project / "notes.md").unlink()
    shutil.rmtree(project / "src")
    (project / "evaluation_notes.md").write_text("mine\n")
    (project / ".partial_keep").mkdir()
    (project / "evaluation_fast").write_text("a file, not evaluate's folder\n")
    with pytest.raises(FileExistsError, match=r"\(.partial_keep, evaluation_fast, "
                                              r"evaluation_notes.md\)"):
        clear_run(project)
    run = tmp_path / "run"
    run.mkdir()
    for name in ("config.yaml", "model.zip", "run.json", "vecnormalize.pkl",
                 ".model.partial.zip"):
        (run / name).write_text("x")
    own = ["checkpoints/model_2048_steps.zip", "checkpoints/vecnormalize_2048.pkl",
           "checkpoints/progress_2048.json", "checkpoints/.drill-env.lock",
           "tb/SAC_1/events.out.tfevents.1765000000.host.42.0",
           "evaluation/benchmark.csv", "evaluation/benchmark.md", "evaluation/comparison.md",
           "evaluation/benchmark_results.jsonl", "evaluation/benchmark_bars.png",
           "evaluation/benchmark_random_series.png", "evaluation/series/stiff_random_seed0.npz",
           "evaluation/recordings/stiff_random_seed0.rrd",
           "evaluation/recordings/stiff_random_seed0.rrd.stamp",
           "evaluation/recordings/other_runs/0a1b/stiff_random_seed0.rrd",
           "evaluation/grid_search/benchmark.csv",
           "evaluation/grid_search/series/constant-120rpm-90kN_random_seed0.npz",
           "evaluation_full/benchmark.md", "evaluation_full/series/.x.7.partial.npz"]
    for name in own:
        (run / name).parent.mkdir(parents=True, exist_ok=True)
        (run / name).write_text("x")
    # a file of one's own inside the run's folders: refused, naming it, nothing deleted
    # (a trial: a notes.txt in evaluation/ went with its folder, exit 0, no word)
    # and names only near the run's own (a fuzzing walkthrough: each went, unnamed)
    for mine in ("evaluation/notes.txt", "evaluation/mine/a.txt", "checkpoints/notes.txt",
                 "tb/notes.txt", "evaluation_full/series/mine.csv",
                 "evaluation/benchmark_bars_annotated.png", "evaluation/series/my_analysis.npz",
                 "tb/SAC_1/events.out.tfevents.backup",
                 "tb/SAC_1/events.out.tfevents.1765000000.host.42.0.bak",
                 "checkpoints/model_2048_steps.zip.bak", "evaluation/recordings/mine.rrd"):
        (run / mine).parent.mkdir(parents=True, exist_ok=True)
        (run / mine).write_text("mine\n")
        named = "evaluation/mine" if mine.startswith("evaluation/mine/") else mine
        with pytest.raises(FileExistsError, match=rf"did not write \({re.escape(named)}\)"):
            clear_run(run)
        assert all((run / name).exists() for name in own)
        (run / mine).unlink()
        if named != mine:
            (run / named).rmdir()
    # a folder of one's own, empty, and a link (to a folder or a file) inside them
    (run / "evaluation" / "my_notes").mkdir()
    with pytest.raises(FileExistsError, match=r"did not write \(evaluation/my_notes\)"):
        clear_run(run)
    (run / "evaluation" / "my_notes").rmdir()
    for target in (tmp_path / "proj", tmp_path / "proj" / "config.yaml"):
        (run / "evaluation" / "link").symlink_to(target)
        with pytest.raises(FileExistsError, match=r"did not write \(evaluation/link\)"):
            clear_run(run)
        (run / "evaluation" / "link").unlink()
    assert all((run / name).exists() for name in own)
    for junk in (".DS_Store", "evaluation/.DS_Store", "tb/Thumbs.db"):  # a file browser's
        (run / junk).write_text("x")
    clear_run(run)
    assert [f.name for f in run.iterdir()] == [".DS_Store"]  # (the folder's own, left)


def test_training_envs_are_seeded_apart_per_run_and_per_resume(tmp_path, monkeypatch):
    """Neighbouring run seeds do not share envs (SB3's seed + i would give env i + 1 of
    seed 0 the episodes of env i of seed 1), a resumed run does not replay the episodes
    it started with, and no training env meets a validation or held-out seed."""
    from drill_env.env import DrillStringEnv
    from drill_env.physics.config import replace
    from drill_env.scenarios import EVALUATION_SEEDS
    from training.config import TRAINING_SEEDS, VALIDATION_SEED
    from training.run_folder import env_seed

    cfg = tiny_config(n_timesteps=256, n_envs=2, eval_freq=10_000, checkpoint_freq=10_000)
    blocks = [range(env_seed(replace(cfg, seed=s), done), env_seed(replace(cfg, seed=s),
                                                                   done) + cfg.n_envs)
              for s in range(4) for done in (0, 256, 512)]
    assert len({b.start for b in blocks}) == len(blocks)
    assert all(set(a).isdisjoint(b) for i, a in enumerate(blocks) for b in blocks[i + 1:])
    assert all(TRAINING_SEEDS <= b.start and b.stop <= 2**32 for b in blocks)
    assert TRAINING_SEEDS > max(VALIDATION_SEED + 10**5, max(EVALUATION_SEEDS))
    # the last env's seed stays a 32-bit seed however high the draw (a mutation test:
    # the range without its n_envs passed, a draw near 2**32 then overflowing it)
    import unittest.mock

    for top in (2**32 - 1, 2**32 - TRAINING_SEEDS - 1):
        class Drawn:  # (a SeedSequence whose draw is ``top``)
            def __init__(self, entropy, top=top):
                self.top = top

            def generate_state(self, n):
                return np.array([self.top], np.uint32)

        with unittest.mock.patch.object(np.random, "SeedSequence", Drawn):
            highest = env_seed(replace(cfg, n_envs=16)) + 16 - 1
        assert TRAINING_SEEDS <= highest < 2**32

    seeds = []
    reset = DrillStringEnv.reset

    def recording(self, *, seed=None, options=None):
        if seed is not None and seed >= TRAINING_SEEDS:
            seeds.append(seed)
        return reset(self, seed=seed, options=options)

    monkeypatch.setattr(DrillStringEnv, "reset", recording)
    train(cfg, tmp_path / "run", progress=False)
    first = sorted(seeds)
    seeds.clear()
    train(replace(cfg, n_timesteps=512), tmp_path / "run", resume=True, progress=False)
    assert first == [env_seed(cfg, 0), env_seed(cfg, 0) + 1]
    assert sorted(seeds) == [env_seed(cfg, 256), env_seed(cfg, 256) + 1]
    record = json.loads((tmp_path / "run" / "run.json").read_text())
    assert record["env_seed"] == env_seed(cfg, 256)
    # every session's seed, not only the last one's
    assert record["sessions"] == [{"from_env_steps": 0, "env_seed": env_seed(cfg, 0)},
                                  {"from_env_steps": 256, "env_seed": env_seed(cfg, 256)}]


def test_a_ppo_run_resumed_inside_a_rollout_ends_where_it_says(tmp_path, monkeypatch):
    """A Ctrl-C checkpoint need not fall on a whole rollout (the scheduled ones do, after
    the update): resumed from one, PPO does whole rollouts from there, and the step count
    announced (planned_steps) is the one reached."""
    from drill_env.physics.config import replace
    from training.run_folder import resume_point

    cfg = tiny_config(n_timesteps=1024, checkpoint_freq=10_000, eval_freq=10_000)
    train_interrupted_at(768, cfg, tmp_path / "run", monkeypatch)  # rollouts of 4 x 128
    done = resume_point(tmp_path / "run")[0]
    assert done % 512  # the checkpoint at 768 lies inside the second rollout
    longer = replace(cfg, n_timesteps=2048)
    train(longer, tmp_path / "run", resume=True, progress=False)
    record = json.loads((tmp_path / "run" / "run.json").read_text())
    assert record["env_steps"] == planned_steps(longer, done) == done + 1536 != \
        planned_steps(longer)
    # the interrupted session is known from its checkpoint's progress record
    assert [s["from_env_steps"] for s in record["sessions"]] == [0, done]


def test_ppo_learns_to_the_end_of_its_last_rollout_which_its_progress_bar_counts_to(
        tmp_path, monkeypatch):
    """600 steps asked of rollouts of 512 run 1024; SB3's progress bar counts to the
    total given to ``learn``, which was 600 (it read 1,024/600 at the end)."""
    from stable_baselines3 import PPO

    totals = []
    original = PPO.learn

    def learn(self, total_timesteps, *args, **kwargs):
        totals.append(total_timesteps)
        return original(self, total_timesteps, *args, **kwargs)

    monkeypatch.setattr(PPO, "learn", learn)
    cfg = tiny_config(n_timesteps=600, eval_freq=10_000, checkpoint_freq=10_000)
    train(cfg, tmp_path / "run", progress=False)
    reached = json.loads((tmp_path / "run" / "run.json").read_text())["env_steps"]
    assert totals == [reached] == [planned_steps(cfg)] == [1024]


def test_ppo_scores_the_model_its_last_rollout_trained_not_the_one_before(tmp_path):
    """A PPO run of one rollout (4 x 128 steps) crosses its evaluation line inside that
    rollout, before the update: scored there, the untrained policy became
    best_model.zip, which evaluate and learned:<run> prefer, and the trained one was
    never scored. The evaluation waits for the update: the best model is the final one."""
    from stable_baselines3 import PPO

    cfg = tiny_config(n_timesteps=512, eval_freq=512, checkpoint_freq=10_000)
    folder = tmp_path / "run"
    train(cfg, folder, progress=False)
    with (folder / "evaluations.csv").open() as f:
        assert [int(r["timesteps"]) for r in csv.DictReader(f)] == [512]
    final = PPO.load(folder / "model.zip").policy.state_dict()
    best = PPO.load(folder / "best_model.zip").policy.state_dict()
    assert final.keys() == best.keys()
    for key in final:
        np.testing.assert_array_equal(best[key].numpy(), final[key].numpy(), err_msg=key)


@pytest.mark.parametrize(("n_envs", "first"), [(4, 1024), (3, 1152)])
def test_a_ctrl_c_during_an_evaluation_is_evaluated_again_on_resume(tmp_path, monkeypatch,
                                                                    n_envs, first):
    """The Ctrl-C checkpoint lands where the evaluation it cut short ran: PPO evaluates
    after the update of the rollout that crossed the grid line (3 envs cross 1024 at 1026,
    inside the rollout that ends at 1152). Counted from there, the resumed run never
    evaluated that line (evaluations.csv kept its row out for good). It scores with the
    observation statistics the checkpoint saved, as the uninterrupted run did: SB3's
    learn() resets the envs first, which added their observations to them (a new user's
    trial: the redone row was 0.03 off the uninterrupted run's)."""
    import training.callbacks as tcb

    real = tcb.evaluate_policy_on_seeds
    seen = []

    def recorded(model, normalizer, *args, **kwargs):
        seen.append((normalizer.obs_rms.count, normalizer.obs_rms.mean.copy()))
        return real(model, normalizer, *args, **kwargs)

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    cfg = tiny_config(n_envs=n_envs)
    folder = tmp_path / "run"
    monkeypatch.setattr(tcb, "evaluate_policy_on_seeds", interrupted)
    with pytest.raises(KeyboardInterrupt):
        train(cfg, folder, progress=False)
    assert (folder / "checkpoints" / f"model_{first}_steps.zip").exists()
    assert not (folder / "evaluations.csv").exists()
    monkeypatch.setattr(tcb, "evaluate_policy_on_seeds", recorded)
    train(cfg, folder, resume=True, progress=False)
    with (folder / "evaluations.csv").open() as f:
        steps = [int(r["timesteps"]) for r in csv.DictReader(f)]
    assert steps[0] == first and [s // 1024 for s in steps] == [1, 2]
    with (folder / "checkpoints" / f"vecnormalize_{first}.pkl").open("rb") as f:
        saved = pickle.load(f).obs_rms
    count, mean = seen[0]
    assert count == saved.count  # (the same floats, unpickled: no arithmetic between)
    np.testing.assert_array_equal(mean, saved.mean)
    assert seen[1][0] > count  # the next evaluation, on the statistics trained on since


def test_a_run_killed_before_its_first_checkpoint_starts_its_records_afresh(tmp_path,
                                                                            capsys):
    """Nothing to resume from: it trains from the start, and the evaluations of the
    killed session leave evaluations.csv (it held 1024 twice)."""
    import shutil

    cfg = tiny_config(checkpoint_freq=4096)
    folder = tmp_path / "run"
    train(cfg, folder, progress=False)
    shutil.rmtree(folder / "checkpoints", ignore_errors=True)  # none at 4096 either
    for name in ("model.zip", "vecnormalize.pkl", "run.json"):
        (folder / name).unlink()
    (folder / "best_model.zip").write_bytes(b"half")  # the killed session's, unrecorded
    train(cfg, folder, resume=True, progress=False)
    assert "nothing to resume" in capsys.readouterr().out
    with (folder / "evaluations.csv").open() as f:
        assert [int(r["timesteps"]) for r in csv.DictReader(f)] == [1024, 2048]
    assert zipfile.is_zipfile(folder / "best_model.zip")  # this session's best


def test_evaluations_and_checkpoints_stay_on_their_grid_across_a_resume(tmp_path,
                                                                       monkeypatch):
    """Resumed from a Ctrl-C checkpoint off the evaluation grid (768 steps, evaluations
    every 1024), the run evaluates once per grid line like an uninterrupted one: counted
    in callback calls from the resume, it evaluated at 1792 and 2816 and skipped its last.
    Its rollouts of 512 now end at 1280, 1792, ..., 3328: each line is scored, and
    checkpointed (every 768), after the update of the rollout that crosses it."""
    from drill_env.physics.config import replace

    cfg = tiny_config(n_timesteps=1536, checkpoint_freq=768, eval_freq=1024)
    folder = tmp_path / "run"
    train_interrupted_at(768, cfg, folder, monkeypatch)
    train(replace(cfg, n_timesteps=3072), folder, resume=True, progress=False)
    with (folder / "evaluations.csv").open() as f:
        assert [int(r["timesteps"]) for r in csv.DictReader(f)] == [1280, 2304, 3328]
    saved = sorted(int(p.stem.split("_")[1]) for p in (folder / "checkpoints").glob(
        "model_*_steps.zip"))
    assert saved == [768, 1792, 2304, 3328]


def test_a_resumed_run_keeps_its_best_model_until_an_evaluation_beats_it(run, tmp_path):
    import hashlib
    import shutil

    from drill_env.physics.config import replace

    folder, cfg = run
    copy = tmp_path / "copy"
    shutil.copytree(folder, copy)
    with (copy / "evaluations.csv").open() as f:
        rows = list(csv.DictReader(f))
    rows[-1]["return"] = "1e9"  # an earlier evaluation nothing will beat
    with (copy / "evaluations.csv").open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    best = hashlib.sha256((copy / "best_model.zip").read_bytes()).hexdigest()
    train(replace(cfg, n_timesteps=3072), copy, resume=True, progress=False)
    with (copy / "evaluations.csv").open() as f:
        assert int(list(csv.DictReader(f))[-1]["timesteps"]) == 3072  # it did evaluate
    assert hashlib.sha256((copy / "best_model.zip").read_bytes()).hexdigest() == best


def test_the_best_model_is_the_evaluation_of_highest_return_not_the_last(tmp_path,
                                                                          monkeypatch):
    """best_model.zip is the model of the evaluation with the highest validation return
    (training/train.py's docstring: the best model on the validation seeds), kept when a
    later evaluation scores lower (a mutation test: the best return never updated, every
    evaluation replaced it)."""
    import training.callbacks as tcb
    import training.run_folder as trf
    import training.train as tt
    from training.run_folder import saved_steps

    returns = iter([1.0, 3.0, 2.0])

    def scored(model, normalizer, env, seeds):
        return {"return": next(returns), "return_std": 0.0, "ssi": 0.0, "stuck_fraction": 0.0}

    monkeypatch.setattr(tcb, "evaluate_policy_on_seeds", scored)
    for module in (tt, tcb):  # (each draws the curve: at an evaluation, at the end)
        monkeypatch.setattr(module, "plot_learning_curve", lambda run, sessions=None: None)
    cfg = tiny_config(n_timesteps=1536, eval_freq=512, checkpoint_freq=10_000)
    train(cfg, tmp_path / "run", progress=False)
    rows = trf.read_evaluations(tmp_path / "run" / "evaluations.csv")
    assert [float(r["return"]) for r in rows] == [1.0, 3.0, 2.0]
    best = int(float(rows[1]["timesteps"]))
    assert best < int(float(rows[2]["timesteps"]))
    assert saved_steps(tmp_path / "run" / "best_model.zip")[0] == best


def test_a_bad_training_yaml_is_named_before_a_run_folder_exists(tmp_path, capsys):
    cases = (({"hyperparams": {"n_epoch": 3}}, "ppo.hyperparams.n_epoch: not an argument"),
             ({"hyperparams": {"learning_rate": -3e-4}}, "ppo.hyperparams.learning_rate"),
             ({"policy_kwargs": {"net_arch": [128, -5]}}, "ppo.policy_kwargs.net_arch"),
             ({"policy_kwargs": {"net_archs": [64]}}, "ppo.policy_kwargs.net_archs: not "
              "an argument of MlpPolicy (ppo) (did you mean net_arch?); known: "),
             # the env's settings, found when training started (an empty run folder left)
             ({"env_kwargs": {"max_corection": 20.0}},
              "ppo.env_kwargs: StickSlipEnv: unknown argument(s) ['max_corection']"),
             ({"env_kwargs": {"max_correction": -5.0}}, "ppo.env_kwargs: max_correction"),
             # a quoted number reached SB3 (a TypeError there); a batch larger than the
             # rollout only made SB3 warn and truncate
             ({"hyperparams": {"n_steps": "64"}}, "ppo.hyperparams.n_steps: must be a "
                                                  "whole number, got '64'"),
             ({"hyperparams": {"n_epochs": True}}, "ppo.hyperparams.n_epochs: must be a "
                                                   "whole number, got True"),
             ({"n_envs": 2, "hyperparams": {"n_steps": 64, "batch_size": 512}},
              "ppo.hyperparams.batch_size: 512 is more than a rollout holds (n_steps x "
              "n_envs = 128)"),
             # a bool or a quoted count read as 1 or parsed; "no" read as False
             ({"n_envs": True}, "ppo.n_envs: must be a whole number, got True"),
             ({"eval_episodes": "10"}, "ppo.eval_episodes: must be a whole number, got '10'"),
             ({"fused_adam": "no"}, "ppo.fused_adam: Input should be a valid boolean"),
             # a class name in YAML reached SB3 as a string (TypeError, a run folder left)
             ({"policy_kwargs": {"activation_fn": "softplusish"}},
              "ppo.policy_kwargs.activation_fn: must name an activation (tanh, relu"),
             ({"n_timesteps": True}, "ppo.n_timesteps: must be a whole number, got True"),
             # a NaN entropy coefficient trained on without a word
             ({"hyperparams": {"ent_coef": -0.1}}, "ppo.hyperparams.ent_coef: must be a "
                                                   "number >= 0"),
             # strings where SB3 takes numbers: an AssertionError or a TypeError deep in
             # SB3 (naming clip_range's schedule as the learning rate), a run folder left
             ({"hyperparams": {"clip_range": "big"}},
              "ppo.hyperparams.clip_range: must be a number or a linear schedule "
              "'lin_<start>'"),
             ({"hyperparams": {"gamma": "high"}},
              "ppo.hyperparams.gamma: must be a number > 0 and <= 1, got 'high'"),
             ({"hyperparams": {"learning_rate": "lin_0"}},
              "ppo.hyperparams.learning_rate: the start of 'lin_0' must be a number > 0"),
             ({"hyperparams": {"normalize_advantage": "no"}},
              "ppo.hyperparams.normalize_advantage: must be true or false, got 'no'"),
             ({"hyperparams": {"rollout_buffer_class": "RolloutBuffer"}},
              "ppo.hyperparams.rollout_buffer_class: a Python object that a YAML cannot "
              "give"),
             # every bad key at once (a walkthrough's n_epoch hid its gamma: high)
             ({"hyperparams": {"n_epoch": 3, "gamma": "high"}},  # (dumped sorted)
              "ppo.hyperparams.gamma: must be a number > 0 and <= 1, got 'high'; "
              "ppo.hyperparams.n_epoch: not an argument of PPO (did you mean n_epochs?) "
              "(known: "))
    for entry, message in cases:
        path = tmp_path / "h.yml"
        path.write_text(yaml.safe_dump({"ppo": entry}))
        try:  # a field of the file: said as argparse says a bad argument
            code = main(["train", "--task", "stick_slip", "--algo", "ppo", "--config",
                         str(path), "--out", str(tmp_path / "runs")])
        except SystemExit as stop:
            code = stop.code
        assert code == 2
        assert f"--config {path}: {message}" in capsys.readouterr().err  # names the file
    # a file without an entry per algorithm is the --config's fault, not --algo's
    for text, message in (("", "holds nothing"), ("- ppo\n", "holds a list")):
        path.write_text(text)
        assert main(["train", "--task", "stick_slip", "--algo", "ppo", "--config", str(path),
                     "--out", str(tmp_path / "runs")]) == 2
        assert f"--config: {path} {message}; it needs one entry per algorithm" in \
            capsys.readouterr().err
    # an entry that is not a mapping (left empty, a number, a list) was a traceback
    for text, shown in (("ppo:\n", "nothing"), ("ppo: 5\n", "5"), ("ppo: [1, 2]\n", "[1, 2]")):
        path.write_text(text)
        assert main(["train", "--task", "stick_slip", "--algo", "ppo", "--config", str(path),
                     "--out", str(tmp_path / "runs")]) == 2
        assert f"ppo: {path} gives {shown}; it needs a mapping of settings" in \
            capsys.readouterr().err
    # a flag's bad value is the flag's, not the file's it overrides
    path.write_text(yaml.safe_dump({"ppo": {"n_envs": 4}}))
    with pytest.raises(SystemExit):
        main(["train", "--task", "stick_slip", "--algo", "ppo", "--config", str(path),
              "--n-envs", "2000", "--out", str(tmp_path / "runs")])
    assert "error: --n-envs: Input should be less than or equal to" in capsys.readouterr().err
    # and a bad value of the file is the file's though a flag replaces it (a new user's
    # trial: it trained without a word while --timesteps was given)
    path.write_text(yaml.safe_dump({"ppo": {"n_timesteps": "lots"}}))
    with pytest.raises(SystemExit):
        main(["train", "--task", "stick_slip", "--algo", "ppo", "--config", str(path),
              "--timesteps", "2000", "--out", str(tmp_path / "runs")])
    assert f"error: --config {path}: ppo.n_timesteps: must be a whole number, got 'lots'" \
        in capsys.readouterr().err
    assert not (tmp_path / "runs").exists()
    # a section the override replaces is not judged without the entry's other fields: the
    # file's batch fits its own 16 envs' rollout (it was refused as if 8 envs ran it)
    from training.config import load_config

    path.write_text(yaml.safe_dump({"ppo": {"n_envs": 16, "hyperparams": {
        "n_steps": 64, "batch_size": 1024}}}))
    given = {"n_steps": 64, "batch_size": 512}
    assert load_config("stick_slip", "ppo", path, hyperparams=given).hyperparams == given


def test_integer_hyperparameters_written_as_floats_become_integers():
    # YAML's 1e5 is a float: SB3 failed on it deep inside (a float buffer size)
    from training.config import TrainConfig

    config = TrainConfig(task="drilling", algo="sac", hyperparams={
        "buffer_size": 1e5, "learning_starts": 1.0e3, "learning_rate": 3e-4})
    assert config.hyperparams["buffer_size"] == 100_000
    assert type(config.hyperparams["buffer_size"]) is int
    assert type(config.hyperparams["learning_rate"]) is float
    with pytest.raises(ValueError, match=r"^sac.hyperparams.batch_size: must be a whole "
                                         r"number, got 64.5"):
        TrainConfig(task="drilling", algo="sac", hyperparams={"batch_size": 64.5})


def test_train_command_names_bad_input(capsys):
    with pytest.raises(SystemExit):
        main(["train", "--task", "juggling"])
    assert "--task" in capsys.readouterr().err
    # named by the flag typed, not the YAML field it sets (ppo.seed)
    with pytest.raises(SystemExit):
        main(["train", "--task", "stick_slip", "--seed", "900000"])
    assert "--seed: must be below 900000, got 900000" in capsys.readouterr().err
    # a seed sweep took '0,,1' and quietly dropped --seed and --overwrite
    for args, message in ((["--seeds", "0,,1"], "--seeds: comma-separated integers"),
                          (["--seeds=-1,2"], "--seeds: distinct integers in 0-"),
                          (["--seeds", "0,0"], "--seeds: distinct integers in 0-899999"),
                          (["--seeds", "900000"], "the validation seeds start at 900000"),
                          (["--seeds", "0,1", "--seed", "3"], "drop --name / --resume / "
                                                              "--overwrite / --seed"),
                          (["--seeds", "0,1", "--overwrite"], "--overwrite / --seed")):
        with pytest.raises(SystemExit):
            main(["train", "--task", "stick_slip", *args])
        assert message in capsys.readouterr().err


def test_the_standard_rl_zoo3_client_trains_a_task(tmp_path):
    """``python -m rl_zoo3.train --gym-packages drill_env --conf-file training.zoo.ppo``."""
    import subprocess
    import sys

    pytest.importorskip("rl_zoo3")
    result = subprocess.run(
        [sys.executable, "-m", "rl_zoo3.train", "--algo", "ppo", "--env", "DrillStickSlip-v0",
         "--gym-packages", "drill_env", "--conf-file", "training.zoo.ppo", "-n", "512",
         "--eval-freq", "-1", "-f", str(tmp_path), "--hyperparams", "n_envs:2",
         "n_steps:256", "batch_size:256", "--env-kwargs", "episode_duration:3.0"],
        capture_output=True, text=True, timeout=600, cwd=tmp_path)
    assert result.returncode == 0, result.stderr[-2000:]
    assert list(tmp_path.glob("ppo/DrillStickSlip-v0_1/DrillStickSlip-v0.zip"))


def test_the_smallest_training_script_saves_its_final_model_where_it_says(tmp_path,
                                                                           monkeypatch):
    """training/train_ppo.py (read top to bottom; scripts/ppo_then_now.py's workload): its
    flags are Args' fields, and the final model goes to ``<out>/ppo_<scenario>/`` (its
    docstring). SB3's PPO stops after a whole rollout: n_steps 256 x 1 env."""
    import sys

    from training import train_ppo

    monkeypatch.setenv("SB3_LOGDIR", str(tmp_path / "sb3"))  # (not the system's temp)
    monkeypatch.setattr(sys, "argv", [
        "train_ppo", "--scenario", "default", "--num-envs", "1", "--total-timesteps", "1",
        "--episode-duration", "2.0", "--out", str(tmp_path)])
    args = train_ppo.parse()
    assert args == train_ppo.Args("default", 1, 1, 2.0, 0, tmp_path)
    model = train_ppo.train(args)
    assert model.num_timesteps == 256
    assert (tmp_path / "ppo_default" / "final.zip").is_file()


def test_zoo_hyperparameters_are_the_yaml_ones():
    from training.zoo import zoo_hyperparams

    zoo = zoo_hyperparams("ppo")["DrillStickSlip-v0"]
    cfg = load_config("stick_slip", "ppo")
    assert zoo["n_timesteps"] == cfg.n_timesteps and zoo["gamma"] == cfg.hyperparams["gamma"]
    assert zoo["policy_kwargs"] == cfg.policy_kwargs
    # the reward normalisation's discount too (rl-zoo3's default was 0.99 for SAC's 0.98)
    sac = zoo_hyperparams("sac")["DrillStickSlip-v0"]
    assert "gamma=0.98)" in sac["normalize"]
    assert load_config("stick_slip", "sac").reward_gamma == 0.98


def test_zoo_hyperparameters_carry_a_configs_own_normalisation_and_env_kwargs(monkeypatch):
    """training.zoo's docstring: rl-zoo3 reads the same config as drill-env train (its
    normalize, env_kwargs): a config's own values, not the shipped files' (all true,
    clip 10, no env keywords); ``normalize`` in rl-zoo3's form, a dict(...) expression."""
    import training.zoo as zoo
    from training.config import Normalize

    def own(task, algo):
        return load_config(task, algo, env_kwargs={"episode_duration": 3.0},
                           normalize=Normalize(norm_obs=False, norm_reward=True,
                                               clip_obs=5.0, gamma=0.9))

    monkeypatch.setattr(zoo, "load_config", own)
    for entry in zoo.zoo_hyperparams("ppo").values():
        assert eval(entry["normalize"], {"dict": dict}) == {  # as rl-zoo3 reads it
            "norm_obs": False, "norm_reward": True, "clip_obs": 5.0, "gamma": 0.9}
        assert entry["env_kwargs"] == {"episode_duration": 3.0}


def test_a_seed_sweep_trains_one_run_per_seed_and_skips_finished_ones(tmp_path, capsys):
    from training.sweep import RESULTS_FILE, train_seeds

    cfg = tiny_config()
    results = train_seeds(cfg, [3, 4], tmp_path, workers=2, progress=False)
    assert [r["seed"] for r in results] == [3, 4]
    for r in results:
        folder = tmp_path / f"stick_slip_ppo_seed{r['seed']}"
        assert r["run"] == str(folder) and r["env_steps"] >= 2048
        assert yaml.safe_load((folder / "config.yaml").read_text())["seed"] == r["seed"]
        assert np.isfinite(r["best_return"])
    summary = (tmp_path / "train_sweep.md").read_text()
    assert "+-" in summary
    # what each run trained, which a PPO rollout rounds up past the asked-for steps
    assert f"| 3 | {results[0]['env_steps']} | " in summary
    stamp = (tmp_path / "stick_slip_ppo_seed3" / "run.json").stat().st_mtime_ns
    # run again with one more seed: only seed 5 trains
    again = train_seeds(cfg, [3, 4, 5], tmp_path, workers=1, progress=False)
    assert [r["seed"] for r in again] == [3, 4, 5] and again[:2] == results
    assert (tmp_path / "stick_slip_ppo_seed3" / "run.json").stat().st_mtime_ns == stamp
    assert len((tmp_path / RESULTS_FILE).read_text().splitlines()) == 3
    # a sweep stopped after a run finished but before it noted it: the rerun takes the run
    # as it is (it refused it: "--timesteps: ... has done 2048 env steps already")
    store = tmp_path / RESULTS_FILE
    lines = store.read_text().splitlines(keepends=True)
    store.write_text("".join(line for line in lines if json.loads(line)["key"] != "4"))
    stamp = (tmp_path / "stick_slip_ppo_seed4" / "run.json").stat().st_mtime_ns
    assert train_seeds(cfg, [3, 4], tmp_path, workers=1, progress=False) == results
    assert (tmp_path / "stick_slip_ppo_seed4" / "run.json").stat().st_mtime_ns == stamp
    train_seeds(cfg, [3, 5], tmp_path, workers=1)  # said (it said "2 runs in 0 s" only)
    assert f"2 of 2 runs already in {tmp_path / RESULTS_FILE} (same config): not rerun" in \
        capsys.readouterr().err
    with pytest.raises(ValueError, match="seeds"):
        train_seeds(cfg, [1, 1], tmp_path)
    # a sweep's run is the single run of its seed, weight for weight: its worker held
    # torch at one thread where this process may have more (the initial weights depend
    # on the count: they differed)
    import torch

    torch.set_num_threads(2)
    single = tmp_path / "single"
    train(dataclasses.replace(cfg, seed=3), single, progress=False)
    swept = tmp_path / "stick_slip_ppo_seed3"
    assert _params(single / "model.zip") == _params(swept / "model.zip")


def _params(path) -> dict[str, Any]:
    """A saved SB3 model's parameters as bytes, by name."""
    from stable_baselines3 import PPO

    model = PPO.load(path, device="cpu")
    return {k: v.numpy().tobytes() for k, v in model.policy.state_dict().items()}


def test_torch_stays_at_its_configured_threads_through_batched_steps():
    """In a process that imports drill_env before torch (``drill-env train``), numba's
    OpenMP layer sets the process's OpenMP thread count at every batched env step, and
    torch reads that count, so a torch.set_num_threads before learn does not last. The
    callback sets it again after every env step: every policy call and every update
    runs on the configured count (TrainConfig.torch_threads, default 1), whatever the
    count was before."""
    import torch
    from stable_baselines3 import PPO

    from training.callbacks import torch_threads_callback
    from training.train import make_train_env

    cfg = load_config("stick_slip", "ppo", n_envs=4, env_kwargs={"episode_duration": 3.0})
    assert cfg.torch_threads == 1
    env = make_train_env(cfg, 0)
    model = PPO("MlpPolicy", env, n_steps=32, batch_size=32, n_epochs=1, seed=0)
    seen = []
    inner = model.policy.forward

    def spy(*args, **kwargs):
        seen.append(torch.get_num_threads())
        return inner(*args, **kwargs)

    model.policy.forward = spy
    updates = []
    train = model.train

    def spy_train():
        updates.append(torch.get_num_threads())
        return train()

    model.train = spy_train
    before = torch.get_num_threads()
    try:
        torch.set_num_threads(2)
        model.learn(128, callback=torch_threads_callback(1))
        assert len(seen) > 4 and set(seen) == {1}
        assert updates == [1]  # one rollout of 4 envs x 32 steps, then its update
    finally:
        torch.set_num_threads(before)
        env.close()


def test_a_resumed_sac_run_warms_its_empty_replay_buffer_up_again(tmp_path, capsys):
    """SAC's buffer is not checkpointed: after a resume it collects ``learning_starts``
    steps again before its first gradient step; a resume that ends inside that warm-up
    says it learns nothing (it said "trained in 2 s": a new user's check)."""
    from stable_baselines3 import SAC

    from drill_env.physics.config import replace

    cfg = load_config("stick_slip", "sac", n_timesteps=256, n_envs=4, eval_freq=10_000,
                      checkpoint_freq=10_000, env_kwargs={"episode_duration": 3.0})
    cfg = replace(cfg, hyperparams=dict(cfg.hyperparams, learning_starts=64,
                                        buffer_size=1000, batch_size=32))
    train(cfg, tmp_path / "sac", progress=False)
    from training.run_folder import resume_point

    done, updates = resume_point(tmp_path / "sac")  # as the model file records them
    assert done == 256 and updates > 0
    train(replace(cfg, n_timesteps=384), tmp_path / "sac", resume=True, progress=False)
    model = SAC.load(tmp_path / "sac" / "model.zip", device="cpu")
    assert model.num_timesteps == 384
    assert model.learning_starts == 256 + 64
    assert "takes no gradient step" not in capsys.readouterr().out
    learnt = resume_point(tmp_path / "sac")[1]
    train(replace(cfg, n_timesteps=420), tmp_path / "sac", resume=True, progress=False)
    assert "note: SAC refills its replay buffer for 64 steps after a resume before it " \
           "learns, more than the 36 left to --timesteps 420: this session takes no " \
           "gradient step" in capsys.readouterr().out
    assert resume_point(tmp_path / "sac")[1] == learnt


def test_a_sac_run_that_would_end_in_its_warm_up_is_refused(tmp_path, capsys):
    """SAC makes no gradient step before ``learning_starts`` env steps (5000 in task 1's
    YAML): a run ending there would save its random initial policy as a trained one."""
    from drill_env.physics.config import replace
    from training.run_folder import check_learns

    assert main(["train", "--task", "stick_slip", "--timesteps", "3000",
                 "--out", str(tmp_path)]) == 2
    said = capsys.readouterr()
    assert "--timesteps: SAC learns only after its replay buffer's warm-up of 5000" in said.err
    assert "training SAC" not in said.out and not any(tmp_path.iterdir())
    cfg = load_config("stick_slip", "sac")
    check_learns(replace(cfg, n_timesteps=5001), 0)  # one step past the warm-up learns
    # resumed from an untrained run, the buffer warms up again from where it stopped
    with pytest.raises(ValueError, match="fills its empty replay buffer again.*more than "
                                         "8000"):
        check_learns(replace(cfg, n_timesteps=8000), 3000)
    check_learns(replace(cfg, n_timesteps=8001), 3000)
    # past learning_starts but never learnt (resumed inside a warm-up before): refused
    with pytest.raises(ValueError, match="more than 12000"):
        check_learns(replace(cfg, n_timesteps=9000), 7000)
    check_learns(replace(cfg, n_timesteps=300_500), 300_000, learnt=True)  # let through
    check_learns(replace(load_config("stick_slip", "ppo"), n_timesteps=10), 0)


def _learning_curve_axes(run, monkeypatch, rows: str) -> dict[str, Any]:
    """The SSI and stuck-share axes of ``learning_curve.png`` drawn from these
    ``evaluations.csv`` rows."""
    from helpers import keep_saved_figures

    from training.learning_curve import plot_learning_curve

    (run / "evaluations.csv").write_text(
        "timesteps,return,return_std,ssi,stuck_fraction,wall_s\n" + rows)
    saved = keep_saved_figures(monkeypatch)
    plot_learning_curve(run)
    return {name: next(ax for ax in saved[0].axes if name in ax.get_ylabel())
            for name in ("SSI", "stuck")}


def test_the_learning_curve_marks_where_a_resumed_session_started(tmp_path, monkeypatch):
    """After a resume the training is not the uninterrupted run's (its envs start new
    episodes): the curve had no mark there, and its bumps read as learning (a new user's
    trial). A dotted line per resumed session, said in the title; the sessions given, or
    run.json's."""
    from helpers import keep_saved_figures

    from training.learning_curve import plot_learning_curve

    (tmp_path / "evaluations.csv").write_text(
        "timesteps,return,return_std,ssi,stuck_fraction,wall_s\n"
        "1000,-900,200,0.9,0.12,60\n2000,-400,100,0.3,0.01,120\n")
    saved = keep_saved_figures(monkeypatch)

    def marks() -> list[list[float]]:
        return [[float(line.get_xdata()[0]) for line in ax.get_lines()
                 if line.get_linestyle() == ":"] for ax in saved[-1].axes[:2]]

    plot_learning_curve(tmp_path, (0, 1500))
    assert marks() == [[1.5], [1.5]]
    assert "dotted: resumed at 1,500 env steps" in saved[-1]._suptitle.get_text()
    plot_learning_curve(tmp_path)  # no run.json yet: none
    assert marks() == [[], []]
    (tmp_path / "run.json").write_text(json.dumps(
        {"sessions": [{"from_env_steps": 0, "env_seed": 1}, {"from_env_steps": 1200,
                                                             "env_seed": 2}]}))
    plot_learning_curve(tmp_path)
    assert marks() == [[1.2], [1.2]]


def test_the_learning_curve_draws_the_stuck_share_in_percent(tmp_path, monkeypatch):
    """As every other picture does (it drew 0.12 beside the SSI on one axis)."""
    stuck_axis = _learning_curve_axes(tmp_path, monkeypatch, "1000,-900,200,0.9,0.12,60\n"
                                      "2000,-400,100,0.3,0.01,120\n")["stuck"]
    assert "%" in stuck_axis.get_ylabel()
    assert list(stuck_axis.get_lines()[0].get_ydata()) == pytest.approx([12.0, 1.0])


def test_flat_learning_curves_keep_off_the_frame_and_apart(tmp_path, monkeypatch):
    """A run whose SSI and stuck share barely move: both lines sat on the top of the
    frame, over each other."""
    axes = _learning_curve_axes(tmp_path, monkeypatch, "1000,-270,20,1.02,0.23,60\n"
                                "2000,-268,20,1.01,0.23,120\n")
    heights = []
    for ax in (axes["SSI"], axes["stuck"]):
        low, high = ax.get_ylim()
        top = max(ax.get_lines()[0].get_ydata())
        assert low == 0.0 and top < 0.9 * high
        heights.append(top / high)
    assert abs(heights[0] - heights[1]) > 0.1


def test_a_learning_curve_of_zeros_says_so(tmp_path, monkeypatch):
    """A check of the pictures: task 2's stuck share, zero at every evaluation, lay on the
    frame's bottom, where it could not be seen. Said across the panel; a curve that
    moves says nothing."""
    axes = _learning_curve_axes(tmp_path, monkeypatch, "1000,90,20,0.02,0.0,60\n"
                                "2000,110,20,0.01,0.0,120\n")
    assert [t.get_text() for t in axes["SSI"].texts] == ["never stuck\nat any evaluation"]
    axes = _learning_curve_axes(tmp_path, monkeypatch, "1000,90,20,0.02,0.01,60\n")
    assert not list(axes["SSI"].texts)
    # an SSI not defined at any evaluation is not "no stick-slip"
    axes = _learning_curve_axes(tmp_path, monkeypatch, "1000,90,20,nan,0.01,60\n")
    assert not list(axes["SSI"].texts)


def test_evaluate_says_which_training_settings_its_standard_episodes_replace():
    """A run trained on 10 s episodes is scored, as every run of its task, on the task's
    30 s held-out episodes: said, not done silently (an outside test found it)."""
    from training.evaluate import settings_of, standard_episode_notes

    settings = settings_of("stick_slip", "fast")
    notes = standard_episode_notes({"episode_duration": 10.0, "tracking_weight": 3.0},
                                   settings)
    assert notes == ["note: the run trained with episode_duration=10.0; evaluate scores it "
                     "on the task's standard held-out episodes (episode_duration=30.0), as "
                     "every run of the task"]
    assert standard_episode_notes({"episode_duration": 30.0, "scenario": "random"},
                                  settings) == []


def test_evaluate_tells_a_missing_folder_from_a_folder_that_is_no_run(tmp_path, capsys):
    (tmp_path / "a_file").write_text("")
    for folder, said in ((tmp_path / "none", "RUN: no such folder"),
                         (tmp_path, "is not a run folder of drill-env train (no config.yaml)"),
                         (tmp_path / "a_file", "a_file is a file, not a run folder")):
        with pytest.raises(SystemExit):
            main(["evaluate", str(folder)])
        err = capsys.readouterr().err
        assert said in err
        if "no config.yaml" in err:  # where a model of rl-zoo3 or SB3's own goes instead
            assert "agents.learned.sb3_policy(model, vecnormalize, algo=..., env_id=...)" \
                in " ".join(err.split())
    # a run's name typed without its seed gets the folder beside it, as other names do
    # (a new user's trial); a name near no folder gets none
    (tmp_path / "stick_slip_ppo_seed0").mkdir()
    for typed, meant in (("stick_slip_ppo", "stick_slip_ppo_seed0"), ("drilling_sac", None)):
        with pytest.raises(SystemExit):
            main(["evaluate", str(tmp_path / typed)])
        err = " ".join(capsys.readouterr().err.split())
        if meant:
            assert f"(did you mean {tmp_path / meant}?)" in err
        else:
            assert "did you mean" not in err
    with pytest.raises(SystemExit):  # and as a learned controller of the benchmark
        main(["benchmark", "--task", "stick_slip", "--seeds", "1", "--controllers",
              f"learned:{tmp_path / 'stick_slip_ppo'}", "--out", str(tmp_path / "b")])
    assert f"(did you mean {tmp_path / 'stick_slip_ppo_seed0'}?)" in \
        " ".join(capsys.readouterr().err.split())
    # a folder of runs (logs/runs) lists them (a trial: it gave the advice for a model
    # trained elsewhere)
    (tmp_path / "stick_slip_ppo_seed0" / "config.yaml").write_text("task: stick_slip\n")
    with pytest.raises(SystemExit):
        main(["evaluate", str(tmp_path)])
    assert f"RUN: {tmp_path} is a folder of runs, not one: give one of them " \
        f"(stick_slip_ppo_seed0), e.g. {tmp_path / 'stick_slip_ppo_seed0'}" in \
        " ".join(capsys.readouterr().err.split())


def test_evaluate_offers_the_task_a_misspelt_shipped_policys_name_meant(tmp_path, capsys,
                                                                        monkeypatch):
    """A bare name near a task's (stick-slip) is its shipped policy misspelt: said as the
    run folders' and scenarios' names are; a path is a folder, offered none."""
    monkeypatch.chdir(tmp_path)
    for typed, said in (("stick-slip", "no such folder stick-slip (did you mean stick_slip?)"),
                        ("drillng", "no such folder drillng (did you mean drilling?)"),
                        ("runs/stick-slip", "no such folder runs/stick-slip (a run folder")):
        with pytest.raises(SystemExit):
            main(["evaluate", typed])
        assert said in " ".join(capsys.readouterr().err.split())


def test_a_plain_sb3_folder_given_as_a_run_says_where_such_a_model_goes(tmp_path):
    """A folder of a plain SB3 script's model.zip and vecnormalize.pkl, given as learned:
    (an outside trial): a bare FileNotFoundError of its config.yaml; now the error names
    sb3_policy, the way such a model is benchmarked."""
    import shutil

    from agents.learned import TRAINED, LearnedController

    for name in ("model.zip", "vecnormalize.pkl"):
        shutil.copy(TRAINED / "stick_slip" / name, tmp_path / name)
    with pytest.raises(FileNotFoundError, match=r"has no config.yaml, so it is not a run "
                                                r"folder of drill-env train; .*sb3_policy"):
        LearnedController.load(tmp_path)
    (tmp_path / "empty").mkdir()
    with pytest.raises(FileNotFoundError, match=r"holds neither .*sb3_policy"):
        LearnedController.load(tmp_path / "empty")


def test_evaluate_says_a_run_still_training_or_stopped_before_its_first_checkpoint(
        run, tmp_path, monkeypatch, capsys):
    """evaluate on a run that was still training went ahead without a word, and one
    killed before its first checkpoint was refused without the way on (a new user's
    trial). A run's training holds its folder's lock: that tells them apart."""
    import shutil

    import training.evaluate
    from drill_env.sweep import folder_lock

    scored = []
    monkeypatch.setattr(training.evaluate, "evaluate_run",
                        lambda run, **kw: scored.append(run))
    live = tmp_path / "live"
    shutil.copytree(run[0], live)
    assert main(["evaluate", str(live), "--seeds", "1"]) == 0  # a finished run: no note
    assert "still running" not in capsys.readouterr().err
    with folder_lock(live, "this training run"):
        assert main(["evaluate", str(live), "--seeds", "1"]) == 0
    assert f"note: {live} is held by another drill-env process, a training still " \
        "running" in " ".join(capsys.readouterr().err.split())
    assert scored == [live, live]
    early = tmp_path / "early"  # killed before its first checkpoint: its config alone
    early.mkdir()
    shutil.copy(run[0] / "config.yaml", early)
    for held, said in ((False, "stopped before its first checkpoint: drill-env train "
                               "--resume starts it again"),
                       (True, "still training: evaluate it once it has saved one")):
        with folder_lock(early, "x") if held else contextlib.nullcontext():
            with pytest.raises(SystemExit):
                main(["evaluate", str(early)])
        err = " ".join(capsys.readouterr().err.split())
        # not the advice for a model trained elsewhere (rl-zoo3: a fuzzing walkthrough)
        assert f"RUN: {early} holds no model yet ({said})" in err and "rl-zoo3" not in err
    # a checkpoint or the run's checkpoints folder: scored through its run
    for inside in (live / "checkpoints", next((live / "checkpoints").glob("model_*.zip"))):
        with pytest.raises(SystemExit):
            main(["evaluate", str(inside)])
        assert f"RUN: {inside} lies inside the run {live}: evaluate the run" in \
            " ".join(capsys.readouterr().err.split())
    # a run in a project whose own config.yaml lies above it is the run (a review: refused
    # as 'inside the run' the project)
    project = tmp_path / "proj"
    (project / "runs").mkdir(parents=True)
    (project / "config.yaml").write_text("lr: 1\n")
    shutil.copytree(live, project / "runs" / "live")
    assert main(["evaluate", str(project / "runs" / "live"), "--seeds", "1"]) == 0
    assert scored[-1] == project / "runs" / "live"


def test_evaluate_takes_a_tasks_name_for_its_shipped_policy(tmp_path, monkeypatch, capsys):
    """Installed from a wheel, the shipped policies lie in site-packages: `evaluate`
    promised logs/evaluation/<task> for one but took only its folder's path (an outside
    check). A task's name names it; a run folder of that name in the working folder wins."""
    import training.evaluate
    from agents.learned import TRAINED

    scored = []
    monkeypatch.setattr(training.evaluate, "evaluate_run",
                        lambda run, **kw: scored.append((run, kw["out"])))
    monkeypatch.chdir(tmp_path)
    assert main(["evaluate", "stick_slip", "--seeds", "1"]) == 0
    assert scored == [(TRAINED / "stick_slip", Path("logs") / "evaluation" / "stick_slip")]
    assert "the shipped policy's" in capsys.readouterr().out
    (tmp_path / "drilling").mkdir()  # the user's own folder of that name is theirs
    with pytest.raises(SystemExit):
        main(["evaluate", "drilling"])
    said = " ".join(capsys.readouterr().err.split())
    assert "drilling is not a run folder of drill-env train (no config.yaml); drilling " \
        f"here is yours, not the task's shipped policy, which is {TRAINED / 'drilling'}" \
        in said
    with pytest.raises(SystemExit):
        main(["evaluate", "stick"])
    assert "or a task's name for its shipped policy: drilling, stick_slip" in \
        capsys.readouterr().err
    # a copy of the shipped policy's folder under the task's name here is evaluated, and
    # said to be this folder's, not the shipped policy (a security review: it read
    # "the shipped policy's chosen model")
    import shutil

    shutil.copytree(TRAINED / "stick_slip", tmp_path / "stick_slip")
    scored.clear()
    assert main(["evaluate", "stick_slip", "--seeds", "1"]) == 0
    said = " ".join(capsys.readouterr().out.split())
    assert scored[0][0] == Path("stick_slip") and "shipped policy's chosen" not in said
    assert "(the folder's model: no run.json" in said
    assert "note: stick_slip here is yours, not the task's shipped policy" in said


def test_evaluate_names_the_model_files_it_looked_for(tmp_path, capsys):
    """A run folder stopped before it saved a model: the error lists both pairs of files
    `evaluate` loads (the best model, else the final one), under the argument's name."""
    (tmp_path / "config.yaml").write_text("task: stick_slip\n")
    with pytest.raises(SystemExit) as stop:
        main(["evaluate", str(tmp_path)])
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert "RUN:" in err and "best_model.zip" in err and "model.zip + vecnormalize.pkl" in err
    assert "nor a checkpoint" in err


def test_the_reward_normalisation_discounts_as_the_algorithm_does_unless_told():
    """A YAML without ``normalize.gamma`` normalised rewards with 0.98 whatever the
    algorithm's gamma; now with the algorithm's (its hyperparameter, else SB3's default)."""
    from training.train import make_train_env

    for algo, hyperparams, want in (("sac", {"gamma": 0.95}, 0.95), ("ppo", {}, 0.99)):
        cfg = load_config("stick_slip", algo, n_envs=1, normalize={"norm_reward": True},
                          hyperparams=hyperparams)
        assert cfg.reward_gamma == want
        venv = make_train_env(cfg, cfg.seed)
        try:
            assert venv.gamma == want
        finally:
            venv.close()
    given = load_config("stick_slip", "sac", n_envs=1)
    assert given.normalize.gamma == given.reward_gamma == 0.98  # the YAML's own


def test_a_policy_saved_before_its_first_gradient_step_is_said_untrained(tmp_path):
    """A Ctrl-C in SAC's warm-up leaves a checkpoint of random actions: evaluate and
    learned:<run> load it, with a warning (it was used without one)."""
    import pickle

    from drill_env.physics.validation import jsonable
    from training.train import make_train_env, new_model

    for algo, why in (("sac", "SAC's learning_starts"),
                      ("ppo", "PPO updates only after its first rollout")):
        cfg = load_config("stick_slip", algo, n_envs=1)
        venv = make_train_env(cfg, cfg.seed)
        try:
            new_model(cfg, venv).save(tmp_path / "model.zip")
            with (tmp_path / "vecnormalize.pkl").open("wb") as f:
                pickle.dump(venv, f)
        finally:
            venv.close()
        (tmp_path / "config.yaml").write_text(yaml.safe_dump(jsonable(cfg)))
        with pytest.warns(RuntimeWarning, match=f"saved at 0 env steps, before the first "
                                                f"gradient step .*{why}.*an untrained policy"):
            LearnedController.load(tmp_path)
    import warnings

    with warnings.catch_warnings():  # trained ones load without it
        warnings.simplefilter("error")
        for task in ("stick_slip", "drilling"):
            LearnedController.load(TRAINED / task)
    # a NumPy bool is not a count either
    import numpy as np

    with pytest.raises(ValueError, match="n_envs: must be a whole number"):
        load_config("stick_slip", "sac", n_envs=np.True_)


def test_a_log_std_init_sac_would_ignore_is_refused(tmp_path):
    """SB3's SAC actor learns its log std as a layer; only gSDE takes log_std_init. The
    shipped SAC configs once carried it, believing it set a small exploration noise."""
    import torch

    cfg = load_config("stick_slip", "sac", n_envs=1)
    assert "log_std_init" not in cfg.policy_kwargs
    with pytest.raises(ValueError, match="sac.policy_kwargs.log_std_init: has no effect "
                                         "on SAC without gSDE"):
        load_config("stick_slip", "sac", n_envs=1,
                    policy_kwargs={**cfg.policy_kwargs, "log_std_init": -1.0})
    # a run saved before the check (its config.yaml carries the value) still loads for a
    # resume, as the same config
    import yaml

    from drill_cli.train import saved_run_config
    from training.config import without_inert_keys

    saved = tmp_path / "config.yaml"
    old = yaml.safe_load((TRAINED / "stick_slip" / "config.yaml").read_text())
    old["policy_kwargs"]["log_std_init"] = -1.0
    saved.write_text(yaml.safe_dump(old))
    loaded = saved_run_config(saved, "stick_slip", "sac")
    assert "log_std_init" not in loaded.policy_kwargs
    assert without_inert_keys(old)["policy_kwargs"] == {"net_arch": [64, 64]}
    with_sde = load_config("stick_slip", "sac", n_envs=1,
                           policy_kwargs={**cfg.policy_kwargs, "log_std_init": -1.0},
                           hyperparams={**cfg.hyperparams, "use_sde": True})
    # the reason, measured on SB3: without gSDE the value changes nothing
    from stable_baselines3 import SAC

    from training.train import make_train_env, new_model

    venv = make_train_env(cfg, cfg.seed)
    try:
        obs = torch.zeros((1, *venv.observation_space.shape))
        stds = []
        for value in (-3.0, 2.0):
            model = SAC("MlpPolicy", venv, seed=0, policy_kwargs={
                "net_arch": [64, 64], "log_std_init": value})
            with torch.no_grad():
                stds.append(float(model.policy.actor.get_action_dist_params(obs)[1].mean()))
        assert stds[0] == pytest.approx(stds[1], abs=1e-12)
        assert new_model(with_sde, venv).policy.actor.use_sde
    finally:
        venv.close()


@pytest.mark.parametrize(("algo", "changes", "message"), [
    ("ppo", {"hyperparams": {"n_steps": 64, "batch_size": 1}},
     "ppo.hyperparams.batch_size: 1 cannot normalise the advantages"),
    ("ppo", {"policy": "CnnPolicy"}, "ppo.policy: the tasks' observations are vectors, for "
                                     "MlpPolicy; CnnPolicy is for images"),
    ("sac", {"policy": "MultiInputPolicy"}, "sac.policy: the tasks' observations are "
                                            "vectors"),
    ("ppo", {"policy_kwargs": {"log_std_init": 1e308}},
     "ppo.policy_kwargs.log_std_init: must be a number >= -20 and <= 2, got 1e+308"),
    ("ppo", {"policy_kwargs": {"log_std_init": "-1"}},
     "ppo.policy_kwargs.log_std_init: must be a number")])
def test_settings_sb3_or_torch_would_fail_on_name_their_field(algo, changes, message):
    """From a fuzzing walkthrough: each was an AssertionError of SB3 or a torch NaN dump
    once training began, without the field (batch_size 1 with normalised advantages, an
    image policy for vector observations, an initial log std of 1e308)."""
    with pytest.raises(ValueError, match=message.replace("(", r"\(").replace("+", r"\+")):
        load_config("stick_slip", algo, n_envs=1, **changes)
    load_config("stick_slip", "ppo", n_envs=1,  # without normalised advantages SB3 takes 1
                hyperparams={"n_steps": 64, "batch_size": 1, "normalize_advantage": False})


def test_a_run_that_diverges_says_so_not_torchs_tensor_dump(tmp_path, monkeypatch):
    """A learning rate inside its range can still diverge (10 did, for PPO and SAC): torch
    then stopped the run with "Expected parameter loc ... found invalid values" and 64
    lines of NaN. The run now says it diverged, where, and what to look at."""
    import torch

    from training import train as train_module

    original = train_module.new_model

    def poisoned(config, env, **kwargs):  # a policy whose outputs are NaN: a divergence
        model = original(config, env, **kwargs)
        with torch.no_grad():
            for parameter in model.policy.parameters():
                parameter.fill_(float("nan"))
        return model

    monkeypatch.setattr(train_module, "new_model", poisoned)
    cfg = tiny_config(n_timesteps=256, eval_freq=10_000, checkpoint_freq=10_000)
    with pytest.raises(ValueError, match=r"^ppo: training diverged at \d+ env steps \(the "
                                         r"policy's outputs became NaN\): ppo\.hyperparams\."
                                         r"learning_rate .*no checkpoint yet"):
        train(cfg, tmp_path / "run", progress=False)


@pytest.mark.parametrize("algo", ["ppo", "sac"])
def test_the_policy_optimisers_are_fused_adam_unless_the_yaml_says_otherwise(algo):
    """``fused_adam`` (default) gives every policy optimiser Adam's fused kernel; a
    ``policy_kwargs`` that names its own optimiser settings keeps them as written."""
    from training.train import make_train_env, new_model

    def optimisers(model):
        policy = model.policy
        return [policy.optimizer] if algo == "ppo" else [policy.actor.optimizer,
                                                        policy.critic.optimizer]

    cfg = load_config("stick_slip", algo, n_envs=1)
    venv = make_train_env(cfg, cfg.seed)
    try:
        for opt in optimisers(new_model(cfg, venv)):
            assert type(opt).__name__ == "Adam" and opt.defaults["fused"] is True
        plain = load_config("stick_slip", algo, n_envs=1, fused_adam=False)
        for opt in optimisers(new_model(plain, venv)):
            assert not opt.defaults["fused"]
        import torch

        for name in ("elu", "nn.ELU", torch.nn.ELU):  # neither algorithm's default
            elu = load_config("stick_slip", algo, n_envs=1, policy_kwargs={
                **cfg.policy_kwargs, "activation_fn": name})
            assert any(type(m).__name__ == "ELU" for m in new_model(elu, venv).policy.modules())
        own = load_config("stick_slip", algo, n_envs=1, policy_kwargs={
            **cfg.policy_kwargs, "optimizer_kwargs": {"eps": 1e-6}})
        for opt in optimisers(new_model(own, venv)):
            assert not opt.defaults["fused"] and opt.defaults["eps"] == 1e-6
        # torch 2.3 (the oldest the project takes) has no fused CPU Adam: the plain one
        import torch

        with pytest.MonkeyPatch.context() as patch:
            patch.setattr(torch, "__version__", "2.3.1+cpu")
            for opt in optimisers(new_model(cfg, venv)):
                assert not opt.defaults["fused"]
    finally:
        venv.close()


def test_a_ctrl_c_saves_a_checkpoint_that_resume_continues_from(tmp_path, monkeypatch,
                                                                 capsys):
    """Interrupted between periodic checkpoints, a run keeps its progress: the model, its
    normalisation and the wall time at the interrupt, which --resume picks up."""
    cfg = tiny_config()
    folder = tmp_path / "cut"
    train_interrupted_at(600, cfg, folder, monkeypatch)
    (saved,) = (folder / "checkpoints").glob("model_*_steps.zip")
    steps = int(saved.stem.split("_")[1])
    assert 600 <= steps < 1024  # before the first periodic checkpoint
    assert (folder / "checkpoints" / f"vecnormalize_{steps}.pkl").exists()
    progress = json.loads((folder / "checkpoints" / f"progress_{steps}.json").read_text())
    assert progress["wall_s"] > 0.0 and progress["steps"] == steps  # docs/tasks.md
    assert f"interrupted at {steps} env steps" in capsys.readouterr().out
    # stopped before its first evaluation, the run is evaluated from that checkpoint
    from agents.learned import policy_files

    assert policy_files(folder) == (saved, folder / "checkpoints" /
                                    f"vecnormalize_{steps}.pkl")
    train(cfg, folder, resume=True, progress=False)
    assert f"resuming from {saved.name} ({steps} steps)" in capsys.readouterr().out
    assert json.loads((folder / "run.json").read_text())["env_steps"] >= cfg.n_timesteps


def test_train_command_resumes_with_the_runs_own_config_and_checks_its_flags(tmp_path,
                                                                            capsys):
    """A run started from --config resumes without it (its saved config.yaml is the
    config); --resume with --overwrite, a --name outside --out and a missing --config
    are refused by name; --timesteps takes 3e3 as the YAMLs write it."""
    from drill_env.physics.validation import jsonable

    entry = {k: v for k, v in jsonable(tiny_config()).items() if k not in ("task", "algo")}
    custom = tmp_path / "mine.yml"
    custom.write_text(yaml.safe_dump({"ppo": entry}))

    def command(*extra, name="mine"):
        return ["train", "--task", "stick_slip", "--algo", "ppo", "--name", name, "--out",
                str(tmp_path / "runs"), "--no-progress", *extra]

    assert main(command("--config", str(custom))) == 0
    assert main(command("--resume", "--timesteps", "3e3")) == 0
    assert json.loads((tmp_path / "runs" / "mine" / "run.json").read_text())[
        "env_steps"] >= 3000
    for args, says in ((command("--resume", "--overwrite"), "not allowed with"),
                       (command("--resume", name="other"), "--resume: no run in"),
                       (command(name="../escape"), "--name"),
                       # a space at an end made "logs/runs/ x" (a fuzzing walkthrough)
                       (command(name=" x"), "without '/' or a space at an end, got ' x'"),
                       (command("--config", str(tmp_path / "none.yml")), "--config")):
        with pytest.raises(SystemExit):
            main(args)
        assert says in capsys.readouterr().err
    # a run stopped in its first seconds leaves a folder without its config, and the
    # interrupt says "--resume starts it": it does (it said "no run in", an RL review)
    (tmp_path / "runs" / "early").mkdir()
    assert main(command("--config", str(custom), "--resume", name="early")) == 0
    assert "holds nothing of a run yet" in capsys.readouterr().err
    assert (tmp_path / "runs" / "early" / "run.json").is_file()


def test_a_run_of_an_algorithm_drill_env_does_not_train_is_named_before_any_episode(
        tmp_path, monkeypatch):
    """A run folder whose config names another algorithm (a model of TD3 beside a copied
    config) was evaluated after the drilling task's grid search and then called damaged,
    with the advice to delete a sound model; now the algo field is named first."""
    import shutil

    import training.evaluate as ev
    from agents.learned import TRAINED

    run = tmp_path / "td3run"
    shutil.copytree(TRAINED / "drilling", run)
    config = yaml.safe_load((run / "config.yaml").read_text())
    (run / "config.yaml").write_text(yaml.safe_dump({**config, "algo": "td3"}))

    def no_grid(*args, **kwargs):
        raise AssertionError("the grid search ran before the policy was loaded")

    monkeypatch.setattr(ev, "best_constant", no_grid)
    with pytest.raises(ValueError, match=r"config.yaml: algo: 'td3' is not one drill-env "
                                         r"trains \(ppo, sac\)"):
        ev.evaluate_run(run, seeds=1, out=tmp_path / "out", progress=False)
    assert not (tmp_path / "out").exists()


def test_the_best_constant_is_the_grid_point_of_highest_mean_return(tmp_path, monkeypatch,
                                                                     capsys):
    """The grid search's rows stubbed: each point's return set by hand, two seeds each;
    the best constant is the one with the highest mean, not the first or the lowest. Its
    table has a title of its own and the winner is said (evaluate printed two tables
    both called "controller benchmark", the first not saying which constant won)."""
    import training.evaluate as ev
    from agents.settings import label

    returns: dict[str, float] = {}
    headings: list[str] = []

    def grid(names, scenarios, seeds, *args, **kwargs):
        headings.append(kwargs["heading"])
        rows = []
        order = np.random.default_rng(0).permutation(len(names))  # not monotone
        for i, name in enumerate(names):
            returns[name] = float(order[i])
            rows += [{"controller": label(name), "episode_return": returns[name] + s}
                     for s in (-1.0, 1.0)]
        return rows

    monkeypatch.setattr(ev, "run_benchmark", grid)
    name, rows = ev.best_constant(tmp_path, progress=False)
    assert name == max(returns, key=returns.__getitem__)
    assert returns[name] == len(returns) - 1 and len(rows) == 2 * len(returns)
    assert headings == [f"Grid search of {len(returns)} constant set points on "
                        f"{len(ev.GRID_SEEDS)} training seeds (the best joins the "
                        "evaluation)"]
    assert capsys.readouterr().out == ""
    ev.best_constant(tmp_path)
    assert capsys.readouterr().out == (
        f"grid search: the best constant set point is {label(name)} (mean return "
        f"{len(returns) - 1:.1f} over {len(ev.GRID_SEEDS)} seeds)\n")


def test_the_grid_search_spans_the_runs_own_action_ranges():
    """An outside check: a task-2 run trained on rpm_range 60-180 had its evaluation
    refused at the fixed grid's 40 rpm ("constant:40/40 is outside the env's range"). The
    grid spans the ranges the run trained with; the task's defaults give the docs' grid."""
    from training.evaluate import GRID_STEPS, grid_points

    default = grid_points({})
    assert sorted({r for r, _ in default}) == [40.0, 80.0, 120.0, 160.0, 200.0]
    assert sorted({w for _, w in default}) == [40.0, 65.0, 90.0, 115.0, 140.0]
    narrow = grid_points({"rpm_range": [60.0, 180.0], "weight_on_bit_range": [50e3, 90e3]})
    assert sorted({r for r, _ in narrow}) == [60.0, 90.0, 120.0, 150.0, 180.0]
    assert sorted({w for _, w in narrow}) == [50.0, 60.0, 70.0, 80.0, 90.0]
    assert len(narrow) == GRID_STEPS**2
    # ends off the 0.1 grid round inwards (40.04 gave 40, refused as outside), a range
    # narrower than the steps gives each point once (an outside review)
    odd = grid_points({"rpm_range": [40.04, 199.96], "weight_on_bit_range": [50040.0, 9e4]})
    assert min(r for r, _ in odd) >= 40.04 and max(r for r, _ in odd) <= 199.96
    assert min(w for _, w in odd) >= 50.04
    tight = grid_points({"rpm_range": [100.0, 100.1]})
    assert len(tight) == len(set(tight)) == 2 * GRID_STEPS
    with pytest.raises(ValueError, match="rpm_range: the run's range holds no 0.1 rpm step"):
        grid_points({"rpm_range": [100.01, 100.09]})
    assert min(w for _, w in grid_points({"weight_on_bit_range": [16.1 * 1000, 9e4]})) == 16.1


def test_every_held_out_seed_can_be_asked_for(tmp_path, monkeypatch):
    import training.evaluate as ev
    from agents.learned import TRAINED
    from drill_env.scenarios import EVALUATION_SEEDS

    asked: list[list[int]] = []
    monkeypatch.setattr(ev, "run_benchmark",
                        lambda names, scenarios, seeds, *a, **k: asked.append(seeds) or [])
    ev.evaluate_run(TRAINED / "stick_slip", seeds=len(EVALUATION_SEEDS), out=tmp_path,
                    progress=False)
    assert asked == [list(EVALUATION_SEEDS)]
    with pytest.raises(ValueError, match="seeds: at most"):
        ev.evaluate_run(TRAINED / "stick_slip", seeds=len(EVALUATION_SEEDS) + 1,
                        out=tmp_path, progress=False)


def test_reward_normalisation_uses_normalize_gamma_when_given():
    # Normalize.gamma: the discount of the reward normalisation; None -> algorithm's gamma
    from training.config import load_config

    cfg = load_config("stick_slip", "sac", n_envs=1,
                      normalize={"norm_reward": True, "gamma": 0.9},
                      hyperparams={"gamma": 0.95})
    assert cfg.reward_gamma == 0.9


def test_a_normalisation_discount_of_zero_is_refused_by_its_path():
    """Normalize.gamma: a discount in (0, 1] (training/config.py, Field(gt=0, le=1)): a
    zero (a running return of the last reward alone) is refused naming normalize.gamma."""
    with pytest.raises(ValueError, match=r"^ppo\.normalize\.gamma: .*greater than 0"):
        load_config("stick_slip", "ppo", normalize={"gamma": 0.0})
    assert load_config("stick_slip", "ppo", normalize={"gamma": 1.0}).reward_gamma == 1.0


def test_a_run_seed_lies_below_the_validation_seeds():
    """TrainConfig.seed < VALIDATION_SEED (training/config.py: validation seeds start
    there), in a YAML as on the command line: the first validation seed is refused."""
    from training.config import VALIDATION_SEED

    with pytest.raises(ValueError, match=rf"^ppo\.seed: .*less than {VALIDATION_SEED}"):
        load_config("stick_slip", "ppo", seed=VALIDATION_SEED)
    assert load_config("stick_slip", "ppo", seed=VALIDATION_SEED - 1).seed == \
        VALIDATION_SEED - 1


def test_a_learning_rate_of_zero_is_refused():
    # _RANGES: learning_rate must be > 0 (low end excluded)
    from training.config import load_config

    with pytest.raises(ValueError, match="learning_rate: must be a number > 0"):
        load_config("stick_slip", "ppo", hyperparams={"learning_rate": 0.0})


def test_a_hyperparameter_may_sit_at_the_high_end_of_its_range():
    """_RANGES: the high end is included ("must be a number > 0 and <= 1"): an undiscounted
    gamma and a gae_lambda of 1 (plain Monte Carlo advantages) are accepted."""
    hyperparams = {"gamma": 1.0, "gae_lambda": 1.0}
    assert load_config("stick_slip", "ppo", hyperparams=hyperparams).hyperparams == \
        hyperparams


def test_a_ppo_batch_just_larger_than_the_rollout_is_refused():
    # check_algorithm_arguments: a batch larger than n_steps x n_envs is refused
    from training.config import load_config

    with pytest.raises(ValueError, match="batch_size: 200 is more than a rollout holds"):
        load_config("stick_slip", "ppo", n_envs=2,
                    hyperparams={"n_steps": 64, "batch_size": 200})


def test_a_sac_buffer_smaller_than_a_batch_is_refused():
    # check_algorithm_arguments: SB3 samples each batch with replacement from the
    # buffer, so a buffer under one batch repeated transitions in every batch (it trained
    # without a word: an outside check); one batch exactly is accepted
    from training.config import load_config

    with pytest.raises(ValueError, match=r"sac.hyperparams.buffer_size: 10 holds less than "
                                         r"one batch \(batch_size = 256\)"):
        load_config("stick_slip", "sac", hyperparams={"buffer_size": 10, "batch_size": 256})
    with pytest.raises(ValueError, match="buffer_size: 100 holds less than one batch"):
        load_config("stick_slip", "sac", hyperparams={"buffer_size": 100})  # SB3's 256
    assert load_config("stick_slip", "sac", hyperparams={"buffer_size": 256,
                                                          "batch_size": 256})


def test_a_misspelt_hyperparameter_is_not_offered_what_yaml_cannot_give():
    """The known arguments listed beside a misspelt one leave out the Python objects a YAML
    cannot hold (action_noise, a buffer class: refused by name, docs/tasks.md), which a
    new user read as on offer; a buffer's keyword arguments, a mapping, stay."""
    from training.config import load_config

    with pytest.raises(ValueError, match=r"sac.hyperparams.gama: not an argument of SAC "
                                         r"\(did you mean gamma\?\) \(known: ") as refused:
        load_config("stick_slip", "sac", hyperparams={"gama": 0.99})
    known = str(refused.value).split("(known: ")[1]
    assert "replay_buffer_kwargs" in known and "gamma" in known
    assert not {"action_noise", "replay_buffer_class"} & set(known.rstrip(")").split(", "))


def test_a_zero_width_layer_is_refused():
    # check_algorithm_arguments: net_arch is a list of layer widths (integers >= 1)
    from training.config import load_config

    with pytest.raises(ValueError, match="net_arch: must be a list of layer widths"):
        load_config("stick_slip", "ppo", policy_kwargs={"net_arch": [64, 0]})


def test_sac_hyperparameters_take_their_string_forms_and_nothing_else():
    # SB3 took 'lots' as ent_coef until float() failed after training had started, and a
    # list tau or a noise name as a TypeError mid-run
    for hyperparams in ({"ent_coef": "auto_0.1"}, {"target_entropy": "auto"},
                        {"target_entropy": -2.0}, {"train_freq": [4, "episode"]},
                        {"action_noise": None}):
        assert load_config("drilling", "sac", hyperparams=hyperparams).hyperparams == \
            hyperparams
    refused = (({"ent_coef": "lots"}, "ent_coef: must be a number or 'auto' or 'auto_<"),
               ({"ent_coef": "auto_-1"}, "ent_coef: must be a number or 'auto'"),
               ({"ent_coef": "auto_0"}, "ent_coef: must be a number or 'auto'"),  # > 0
               ({"target_entropy": "low"}, "target_entropy: must be a number or 'auto', "),
               ({"tau": [0.02]}, "tau: must be a number > 0 and <= 1, got [0.02]"),
               ({"action_noise": "normal"}, "action_noise: a Python object"),
               ({"train_freq": [4, "epoch"]}, "train_freq: must be a whole number or "
                                              "[count, step|episode]"),
               ({"replay_buffer_kwargs": 3}, "replay_buffer_kwargs: must be a mapping"))
    for hyperparams, message in refused:
        with pytest.raises(ValueError, match=r"^sac\.hyperparams\." + re.escape(message)):
            load_config("drilling", "sac", hyperparams=hyperparams)


def test_linear_schedules_reach_sb3_as_rl_zoo3_builds_them(tmp_path):
    # rl-zoo3's "lin_<start>" (the YAMLs are rl-zoo3's layout): start x progress_remaining,
    # against rl-zoo3's own schedule; kept through a save and load; train_freq's YAML
    # list becomes SB3's tuple
    from rl_zoo3.utils import SimpleLinearSchedule
    from stable_baselines3 import PPO

    from training.train import make_train_env, new_model

    config = load_config("stick_slip", "ppo", n_envs=2, hyperparams={
        "learning_rate": "lin_3e-4", "clip_range": "lin_0.2", "n_steps": 64,
        "batch_size": 64, "n_epochs": 1})
    env = make_train_env(config, 0)
    model = new_model(config, env)
    for progress in (1.0, 0.7, 0.25, 0.0):
        assert model.lr_schedule(progress) == pytest.approx(
            SimpleLinearSchedule(3e-4)(progress), rel=1e-12, abs=0.0)
        assert model.clip_range(progress) == pytest.approx(
            SimpleLinearSchedule(0.2)(progress), rel=1e-12, abs=0.0)
    model.save(tmp_path / "model.zip")
    env.close()
    assert PPO.load(tmp_path / "model.zip").clip_range(0.5) == pytest.approx(0.1)
    config = load_config("drilling", "sac", n_envs=1, hyperparams={
        "train_freq": [4, "episode"], "buffer_size": 1000})
    env = make_train_env(config, 0)
    freq = new_model(config, env).train_freq
    env.close()
    assert (freq.frequency, freq.unit.value) == (4, "episode")


def test_a_seed_summary_reports_the_best_evaluation_not_the_last(tmp_path, monkeypatch):
    # training/sweep.py docstring: the validation return of the best model per seed
    import json

    import training.run_folder as trf
    import training.train as tt
    from training.config import load_config
    from training.sweep import _train_task

    monkeypatch.setattr(tt, "train", lambda *a, **k: None)
    monkeypatch.setattr(trf, "holds_run", lambda run: False)
    run = tmp_path / "r"
    run.mkdir()
    (run / "run.json").write_text(json.dumps({"env_steps": 100, "wall_s": 1.0}))
    (run / "evaluations.csv").write_text(
        "timesteps,return,ssi\n10,-5.0,0.5\n20,-1.0,0.2\n30,-3.0,0.4\n")
    s = _train_task((load_config("stick_slip", "ppo"), str(run)))
    assert (s["best_return"], s["best_at_steps"], s["best_ssi"]) == (-1.0, 20, 0.2)


def test_a_seed_sweeps_started_run_is_resumed_and_a_new_one_started(tmp_path, monkeypatch):
    # training/sweep.py docstring: a run whose worker died (or that was interrupted)
    # resumes from its last checkpoint (train() refuses a started run without resume)
    import training.train as tt
    from training.sweep import _train_task

    resumed = []

    def fake_train(config, run, resume=False, progress=True):
        resumed.append(resume)
        run.mkdir(exist_ok=True)
        (run / "run.json").write_text(json.dumps({"env_steps": 100, "wall_s": 1.0}))

    monkeypatch.setattr(tt, "train", fake_train)
    started = tmp_path / "started"
    (started / "checkpoints").mkdir(parents=True)  # what an interrupted run leaves
    _train_task((tiny_config(), str(started)))
    _train_task((tiny_config(), str(tmp_path / "new")))
    assert resumed == [True, False]


def _summary(seed: int, best: float | None) -> dict[str, Any]:
    return {"seed": seed, "run": f"run{seed}", "env_steps": 2048, "wall_s": 1.0,
            "best_return": best, "best_at_steps": None if best is None else 1024,
            "best_ssi": None if best is None else 0.1}


def test_a_seed_summary_gives_the_mean_and_sample_std_of_the_best_returns(tmp_path):
    import math

    from training.sweep import write_summary

    results = [_summary(0, 1.0), _summary(1, 2.0), _summary(2, 6.0), _summary(3, None)]
    text = write_summary(results, tmp_path / "train_sweep.md", tiny_config()).read_text()
    # mean 3, sample variance (4 + 1 + 9) / (3 - 1) = 7; the seed not yet evaluated left out
    assert (f"Best validation return over seeds: 3.0 +- {math.sqrt(7):.1f} (mean +- std, "
            "3 seeds).") in text


def test_a_seed_sweep_keeps_its_finished_seeds_whatever_seed_its_config_holds(
        tmp_path, monkeypatch):
    # training/sweep.py: each run takes its own seed, so the seed the config holds is no
    # part of what the stored results belong to; a rerun skips the finished seeds
    import training.sweep as sweep

    ran = []

    class Serial:
        def map_unordered(self, fn, items, late=None):
            for k, (config, _) in enumerate(items):
                ran.append(config.seed)
                yield k, _summary(config.seed, None)

        def close(self):
            pass

    monkeypatch.setattr(sweep, "make_executor", lambda *args: Serial())
    config = tiny_config()
    sweep.train_seeds(config, [3, 4], tmp_path, progress=False)
    sweep.train_seeds(dataclasses.replace(config, seed=config.seed + 1), [3, 4, 5], tmp_path,
                      progress=False)
    assert ran == [3, 4, 5]


def test_a_run_folder_loads_its_best_model_before_its_final_one(tmp_path):
    # agents/learned.py docstring: its best model on the validation seeds if there is
    # one, else its final model, else its last checkpoint
    from agents.learned import policy_files

    for name in ("best_model.zip", "best_vecnormalize.pkl", "model.zip", "vecnormalize.pkl"):
        (tmp_path / name).write_bytes(b"")
    assert policy_files(tmp_path) == (tmp_path / "best_model.zip",
                                      tmp_path / "best_vecnormalize.pkl")
    # a best model without its statistics (a kill between the two saves) is passed over
    (tmp_path / "best_vecnormalize.pkl").unlink()
    assert policy_files(tmp_path) == (tmp_path / "model.zip", tmp_path / "vecnormalize.pkl")


def test_a_checkpoint_without_its_statistics_is_passed_over(tmp_path):
    # agents.learned.latest_checkpoint: the last *complete* checkpoint, its model beside
    # its VecNormalize statistics; a model whose statistics were never written (a kill
    # between the two saves) is passed over, not handed to a resume without them
    kept = tmp_path / "checkpoints"
    kept.mkdir()
    for name in ("model_1024_steps.zip", "vecnormalize_1024.pkl", "model_2048_steps.zip",
                 "vecnormalize_512.pkl", "model_x_steps.zip"):
        (kept / name).write_bytes(b"")
    assert latest_checkpoint(tmp_path) == (kept / "model_1024_steps.zip",
                                           kept / "vecnormalize_1024.pkl")


def _evaluations(run, steps_and_returns):
    import csv

    run.mkdir(parents=True, exist_ok=True)
    with (run / "evaluations.csv").open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=["timesteps", "return", "return_std", "ssi",
                                          "stuck_fraction", "wall_s"])
        w.writeheader()
        for k, (s, r) in enumerate(steps_and_returns):
            w.writerow({"timesteps": s, "return": r, "return_std": 0, "ssi": 0,
                        "stuck_fraction": 0, "wall_s": 10.0 * (k + 1)})


def test_rewind_keeps_the_evaluation_at_the_checkpoint_step(tmp_path):
    import csv

    from training.run_folder import rewind as _rewind

    run = tmp_path / "run"
    _evaluations(run, [(1024, -5.0), (2048, -3.0), (3072, -1.0)])
    resumed = _rewind(run, 2048, from_checkpoint=True)
    with (run / "evaluations.csv").open() as f:
        kept = [int(r["timesteps"]) for r in csv.DictReader(f)]
    assert kept == [1024, 2048]  # "evaluations after it" leave; the one at it stays
    assert resumed.wall_s == pytest.approx(20.0)  # no progress file: its last evaluation


def test_rewind_without_a_best_model_has_no_best_return(tmp_path):
    from training.run_folder import rewind as _rewind

    run = tmp_path / "run"
    _evaluations(run, [(1024, -5.0), (2048, -3.0)])
    assert _rewind(run, 2048, from_checkpoint=True).best_return == -np.inf
    (run / "best_model.zip").write_bytes(b"")
    assert _rewind(run, 2048, from_checkpoint=True).best_return == pytest.approx(-3.0)


def test_the_best_models_row_outlives_a_rewind_past_it(tmp_path):
    """A run killed without its interrupt checkpoint resumes from an earlier one: the
    rows after it leave the csv, the best model stays, and its steps were read from
    another row ('trained 2,048 env steps' for a model of 7,168; a fuzzing walkthrough).
    The row is recorded with the model's digest: a record of another model file (a kill
    between the two saves) is not taken, and a run of an older version gets its record
    before the rewind (both from a review)."""
    from drill_cli.train import trained_steps
    from training.run_folder import best_evaluation, write_best
    from training.run_folder import rewind as _rewind

    run = tmp_path / "run"
    _evaluations(run, [(1024, -5.0), (2048, -3.0), (3072, -1.0)])
    assert best_evaluation(run)["timesteps"] == 3072  # no record: read from the csv
    (run / "best_model.zip").write_bytes(b"the model of 3072 steps")
    assert _rewind(run, 2048, from_checkpoint=True).best_return == pytest.approx(-1.0)
    assert trained_steps(run, run / "best_model.zip") == 3072  # recorded before the rewind
    assert (run / "best_model.json").exists()
    # a record of the model before it: the csv's row (as before the record)
    _evaluations(run, [(1024, -5.0), (2048, -3.0), (3072, -1.0)])
    (run / "best_model.zip").write_bytes(b"the model of 2048 steps")
    write_best(run, {"timesteps": 2048, "return": -3.0, "ssi": 0.25})
    assert best_evaluation(run) == {"timesteps": 2048.0, "return": -3.0, "ssi": 0.25}
    (run / "best_model.zip").write_bytes(b"the model of 3072 steps, saved then killed")
    assert best_evaluation(run)["timesteps"] == 3072
    assert _rewind(run, 3072, from_checkpoint=True).best_return == pytest.approx(-1.0)
    (run / "best_model.json").write_text('{"row": {"return": -1.0}}')
    with pytest.raises(ValueError, match="best_model.json is damaged.*delete it"):
        best_evaluation(run)


def test_crossed_only_when_a_grid_line_is_passed():
    from training.callbacks import crossed

    assert not crossed(0, 4, 1024)
    assert not crossed(1024, 2047, 1024)
    assert crossed(1020, 1024, 1024) and crossed(2092, 3092, 1000)


def test_sac_warm_up_defaults_to_sb3s_100_steps():
    # check_learns docstring: SB3's default learning_starts is 100
    from drill_env.physics.config import replace
    from training.config import load_config
    from training.run_folder import check_learns

    cfg = load_config("stick_slip", "sac")
    hyper = {k: v for k, v in cfg.hyperparams.items() if k != "learning_starts"}
    cfg = replace(cfg, hyperparams=hyper)
    with pytest.raises(ValueError):
        check_learns(replace(cfg, n_timesteps=100), 0)
    check_learns(replace(cfg, n_timesteps=101), 0)


def test_a_model_without_a_log_folder_leaves_no_folder_in_the_temporary_directory(
        tmp_path, monkeypatch):
    """SB3 gives each ``learn`` of a model with no logger and no ``tensorboard_log`` a
    new folder under the system's temporary directory (``SB3-<date>``) that nothing
    removes (``drill-env speed``'s training section made two per run); ``new_model``
    gives such a model a logger without a folder. A run's own model still logs into its
    run folder (``tensorboard_log``)."""
    import tempfile

    from training.train import make_train_env, new_model

    monkeypatch.delenv("SB3_LOGDIR", raising=False)
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    cfg = load_config("stick_slip", "ppo", n_envs=2, env_kwargs={"episode_duration": 3.0},
                      hyperparams={"n_steps": 16, "batch_size": 32, "n_epochs": 1})
    venv = make_train_env(cfg, cfg.seed)
    try:
        model = new_model(cfg, venv)
        model.learn(32)
        model.learn(32, reset_num_timesteps=False)
        assert model.num_timesteps == 64 and model.logger.get_dir() is None
        assert not list(tmp_path.glob("SB3-*"))
        logged = new_model(cfg, venv, tensorboard_log=str(tmp_path / "tb"))
        logged.learn(32)
        assert (tmp_path / "tb").is_dir() and not list(tmp_path.glob("SB3-*"))
    finally:
        venv.close()


def test_an_evaluation_row_is_added_whole(tmp_path, monkeypatch):
    """A process killed while it added a row left half a row, the next row was glued to it
    and every later resume failed ("'yerr' must not contain negative values"): a row now
    goes in with the whole file written beside it and renamed into place."""
    from pathlib import Path

    from training.run_folder import add_row

    path = tmp_path / "evaluations.csv"
    add_row(path, {"timesteps": 1024, "return": -1.5, "wall_s": 2.0})
    add_row(path, {"timesteps": 2048, "return": -1.0, "wall_s": 4.0})
    real = Path.write_text

    def killed_half_way(self, text, *args, **kwargs):
        real(self, text[: len(text) // 2], *args, **kwargs)
        raise OSError("killed")

    monkeypatch.setattr(Path, "write_text", killed_half_way)
    with pytest.raises(OSError, match="killed"):
        add_row(path, {"timesteps": 3072, "return": -0.5, "wall_s": 6.0})
    monkeypatch.undo()
    with path.open() as f:
        rows = list(csv.DictReader(f))
    assert [(int(r["timesteps"]), float(r["return"])) for r in rows] == [(1024, -1.5),
                                                                         (2048, -1.0)]
    raw = path.read_bytes()  # the csv module's line ends throughout, not mixed
    assert raw.count(b"\r\n") == raw.count(b"\n") == 3


def test_a_finished_run_is_one_of_the_same_config_and_steps(run):
    """A seed sweep takes a finished run as its result only for the config and steps it
    was trained with (a longer run is not the result of a shorter one)."""
    from drill_env.physics.config import replace
    from training.run_folder import finished

    folder, cfg = run
    assert finished(folder, cfg)
    assert not finished(folder, replace(cfg, n_timesteps=1024))
    with pytest.raises(ValueError, match="another config"):
        finished(folder, replace(cfg, eval_episodes=3))


def test_a_damaged_progress_file_is_named(tmp_path):
    from training.run_folder import rewind as _rewind

    (tmp_path / "checkpoints").mkdir()
    (tmp_path / "checkpoints" / "progress_512.json").write_text("")
    with pytest.raises(ValueError, match=r"resume: .*progress_512.json is damaged"):
        _rewind(tmp_path, 512, from_checkpoint=True)


def test_a_ppo_run_whose_config_says_sac_is_named_at_the_load(run, tmp_path):
    """A PPO model loaded as SAC (a hand-edited config.yaml) failed with "no attribute
    'actor'" (a traceback): named at the load now."""
    import shutil

    copy = tmp_path / "run"
    shutil.copytree(run[0], copy)
    config = copy / "config.yaml"
    config.write_text(config.read_text().replace("algo: ppo", "algo: sac"))
    with pytest.raises(ValueError, match=r"algo 'sac', but .*model.zip does not load as "
                                         r"one .*: the model of another algorithm"):
        LearnedController.load(copy)


def test_a_session_interrupted_before_its_first_step_is_recorded_once(tmp_path, monkeypatch):
    """A review: a resumed session stopped before its first env step saves a checkpoint
    at the steps it resumed from, with itself among the sessions; the next resume from
    that checkpoint appended its start again. run.json lists each session once."""
    from training import callbacks as tcb
    from training import train as train_module

    cfg = tiny_config(n_timesteps=512, n_envs=2, eval_freq=10_000, checkpoint_freq=10_000)
    calls = []

    def interrupt_after(n):  # a Ctrl-C noticed at the n-th check (one a step, and one
        def noted():  # before learn starts)
            calls.append(1)
            return KeyboardInterrupt() if len(calls) > n else None
        return noted

    for module in (train_module, tcb):  # (the check before learn starts, then one a step)
        monkeypatch.setattr(module, "noted_interrupt", interrupt_after(100))
    with pytest.raises(KeyboardInterrupt):  # the first session, stopped after some steps
        train(cfg, tmp_path / "run", progress=False)
    calls.clear()
    for module in (train_module, tcb):
        monkeypatch.setattr(module, "noted_interrupt", interrupt_after(0))
    with pytest.raises(KeyboardInterrupt):  # the second, before its first step
        train(cfg, tmp_path / "run", resume=True, progress=False)
    monkeypatch.undo()
    train(cfg, tmp_path / "run", resume=True, progress=False)
    record = json.loads((tmp_path / "run" / "run.json").read_text())
    starts = [s["from_env_steps"] for s in record["sessions"]]
    assert len(starts) == 2 and starts[0] == 0 and 0 < starts[1] < 512, starts


def test_a_stopped_seed_sweep_says_what_finished_and_what_continues(tmp_path, capsys,
                                                                   monkeypatch):
    """On Ray a run's own line (what it saved, how to go on) does not reach the console:
    a stopped sweep said only "interrupted" (an outside check). The sweep says which runs
    finished and which continue from their checkpoints when the command runs again."""
    import training.run_folder as trf
    import training.sweep as sweep

    summary = _summary(3, 1.0)

    class StoppedAfterOne:  # the first run finishes, then a Ctrl-C
        def map_unordered(self, fn, items, late=None):
            yield 0, summary
            raise KeyboardInterrupt

        def close(self):
            pass


    monkeypatch.setattr(sweep, "make_executor", lambda *args: StoppedAfterOne())
    # seed 4 saved a checkpoint before the Ctrl-C, seed 5 had not (or never started)
    monkeypatch.setattr(trf, "resume_point",
                        lambda run: (1024, 0) if run.name.endswith("seed4") else None)
    with pytest.raises(KeyboardInterrupt):
        sweep.train_seeds(tiny_config(), [3, 4, 5], tmp_path)
    said = capsys.readouterr().err
    assert (f"stopped with 1 of 3 runs finished ({tmp_path / sweep.RESULTS_FILE}); the "
            f"same command goes on with stick_slip_ppo_seed4 from the checkpoints in "
            f"{tmp_path} and starts stick_slip_ppo_seed5 anew (nothing saved)") in said
    # and a command finding a run's checkpoint says so as it starts (a new user's rerun
    # on Ray went on silently: the run's own "resuming" line stays on its worker)
    assert said.startswith(f"training seeds: going on with stick_slip_ppo_seed4 from 1,024 "
                           f"env steps (checkpoints in {tmp_path})\n")


def test_a_partial_config_file_says_which_tuned_settings_it_leaves_out(tmp_path, capsys):
    """A --config file is a whole entry (rl-zoo3's way): one holding only a reward change
    trained SAC with SB3's gamma, buffer and start and SB3's 256 x 256 network instead of
    the task's tuned ones, without a word (an outside trial). train now names each shipped
    setting the file leaves out where the run gets another value; none for a copy of the
    shipped file, none that a flag sets, none whose default is the shipped value."""
    import yaml

    from drill_cli.main import main
    from training.config import HYPERPARAMS, left_out_settings, load_config

    partial = tmp_path / "variant.yml"
    partial.write_text("sac: {env_kwargs: {stick_slip_weight: 3.0, effort_weight: 0.02}}\n")
    left = dict(left_out_settings(load_config("stick_slip", "sac", partial), partial))
    shipped = yaml.safe_load((HYPERPARAMS / "stick_slip.yml").read_text())["sac"]
    assert left["hyperparams.gamma"] == shipped["hyperparams"]["gamma"] == 0.98  # SB3: 0.99
    assert left["hyperparams.learning_starts"] == 5000  # SB3's 100
    assert left["policy_kwargs.net_arch"] == [64, 64]
    assert left["n_timesteps"] == 4.0e5  # drill-env's default 1e6
    for same in ("hyperparams.learning_rate", "hyperparams.batch_size", "n_envs", "policy"):
        assert same not in left  # SB3's / drill-env's default is the shipped value
    given = load_config("stick_slip", "sac", partial, n_timesteps=1000)
    assert "n_timesteps" not in dict(left_out_settings(given, partial, ["n_timesteps"]))
    assert left["normalize.gamma"] == 0.98  # the reward's discount: SB3's gamma, 0.99
    discounted = tmp_path / "discounted.yml"  # ... but the algorithm's 0.98 given: the
    discounted.write_text("sac: {hyperparams: {gamma: 0.98}}\n")  # shipped value
    assert "normalize.gamma" not in dict(
        left_out_settings(load_config("stick_slip", "sac", discounted), discounted))
    whole = tmp_path / "whole.yml"
    whole.write_text((HYPERPARAMS / "stick_slip.yml").read_text())
    assert left_out_settings(load_config("stick_slip", "sac", whole), whole) == []
    # the command says it before it starts (here it then stops: nothing to resume)
    with pytest.raises(SystemExit):
        main(["train", "--task", "stick_slip", "--config", str(partial), "--resume",
              "--out", str(tmp_path / "runs")])
    err = capsys.readouterr().err
    assert f"note: --config {partial}: its sac entry leaves out 9 settings of " in err
    # the shipped value and the one the run takes (the shipped one alone read as it)
    assert "hyperparams.gamma (shipped 0.98, here 0.99)" in err and "copy the task's file" in err
    assert "n_timesteps (shipped 400000.0, here 1000000)" in err
    assert "policy_kwargs.net_arch (shipped [64, 64], here the default)" in err
    # the run is named by the file too: a variant's run and the task's own told apart
    assert f"--resume: no run in {tmp_path / 'runs' / 'stick_slip_sac_variant_seed0'}; " \
        "name it by --name, or by --seed (and --algo, --config)" in err
    # a file of one entry names the algorithm: no --algo needed (it said the default's
    only = tmp_path / "only.yml"  # entry, sac, was missing)
    only.write_text("ppo: {env_kwargs: {stick_slip_weight: 3.0}}\n")
    with pytest.raises(SystemExit):
        main(["train", "--task", "stick_slip", "--config", str(only), "--resume",
              "--out", str(tmp_path / "runs")])
    err = capsys.readouterr().err
    assert f"note: --config {only}: its ppo entry leaves out " in err
    assert f"no run in {tmp_path / 'runs' / 'stick_slip_ppo_only_seed0'}" in err
    # one of no algorithm drill-env trains is the file's fault, not --algo's, not given
    # (a fuzzing walkthrough: "--algo: ... has no entry 'sac'")
    for entry, said in (("td3", "['td3'] name no algorithm drill-env trains: ppo or sac"),
                        ("PPO", "['PPO'] name no algorithm drill-env trains: ppo or sac "
                                "(lower case: PPO as ppo)")):
        only.write_text(f"{entry}: {{n_envs: 2}}\n")
        assert main(["train", "--task", "stick_slip", "--config", str(only),
                     "--out", str(tmp_path / "runs")]) == 2
        assert f"--config: {only}'s entries {said}" in capsys.readouterr().err


def test_an_interrupted_run_gives_stdout_back_from_its_progress_bar(tmp_path, monkeypatch,
                                                                     capsys):
    """SB3's rich progress bar holds stdout and stderr while it runs, and SB3 closes it
    only when learning ends: after a Ctrl-C in a notebook every later cell's output came
    as the bar's HTML (an outside check). train() closes it whatever ends the run."""
    import sys

    from stable_baselines3.common.callbacks import BaseCallback

    import training.callbacks as tcb
    import training.train as tt

    class CtrlC(BaseCallback):
        def _on_step(self) -> bool:
            if self.num_timesteps >= 256:
                raise KeyboardInterrupt
            return True

    import rich

    # rich takes stdout only on a terminal (or in Jupyter): a fresh console that thinks so
    monkeypatch.setenv("FORCE_COLOR", "1")
    monkeypatch.setattr(rich, "_console", None)
    stdout, stderr = sys.stdout, sys.stderr
    made = tcb.training_callbacks
    monkeypatch.setattr(tt, "training_callbacks", lambda *a, **k: [*made(*a, **k), CtrlC()])
    with pytest.raises(KeyboardInterrupt):
        train(tiny_config(), tmp_path / "run", progress=True)
    assert (sys.stdout, sys.stderr) == (stdout, stderr)
    assert latest_checkpoint(tmp_path / "run") is not None  # saved as before
    # called from Python, the way on is train()'s argument, not the command line's option
    said = capsys.readouterr().out
    assert "train() with resume=True (instead of overwrite=True" in said
    assert "--resume" not in said


def test_a_run_records_the_settings_and_code_it_trained_under(run, tmp_path, capsys):
    """An upgrade review: a run folder named no drill-env version or code, and its
    config.yaml holds only the keywords given (``env_kwargs``), so a later version whose
    task defaults moved scored the run under them without a word. A run now keeps
    ``trained_with.json`` (version, source digest, every task and env setting its env
    resolved, the scenario and its parameters, the physics overrides); a moved one is a
    note where it is evaluated or benchmarked and refuses a resume, by name, and one
    added since is taken at its default without a word; run.json names the package
    versions."""
    import json
    import shutil

    import drill_env
    from agents.settings import task_settings
    from drill_cli.benchmark import replaced_episode_notes
    from drill_env.physics.config import replace
    from drill_env.sweep import source_digest
    from drill_env.tasks.stick_slip import StickSlipEnv
    from training.config import TRAINED_WITH, settings_changes
    from training.evaluate import evaluate_run, settings_of
    from training.run_folder import finished

    folder, cfg = run
    record = json.loads((folder / TRAINED_WITH).read_text(encoding="utf-8"))
    assert record["drill_env"] == drill_env.__version__
    assert record["source_digest"] == source_digest("drill_env")
    env = StickSlipEnv(episode_duration=3.0)  # what the run's env_kwargs give, built alone
    assert {k: record[k] for k in ("task", "env", "scenario", "scenario_params",
                                   "physics")} == env.settings()
    assert record["task"]["history"] == 20 and record["physics"] == {"solver.fidelity": "fast"}
    assert record["scenario_params"]["rpm_range"] == [40.0, 160.0]
    info = json.loads((folder / "run.json").read_text(encoding="utf-8"))
    assert info["drill_env"] and info["torch"] and info["stable_baselines3"]
    assert info["drill_env_source_digest"] == record["source_digest"]

    copy = tmp_path / "moved"
    shutil.copytree(folder, copy)
    # a setting added since (not in the record): its default keeps the old behaviour
    del record["task"]["tracking_deadband"], record["env"]["start_kick"]
    (copy / TRAINED_WITH).write_text(json.dumps(record), encoding="utf-8")
    assert not any("trained under" in note for note in replaced_episode_notes(
        [f"learned:{copy}"], "DrillStickSlip-v0", ["random"], settings_of("stick_slip")))
    # as if trained when the task's default history was 10 and its telemetry wired pipe,
    # with a setting since removed
    record["task"].update(history=10, telemetry="wired_pipe", old_weight=2.0)
    (copy / TRAINED_WITH).write_text(json.dumps(record), encoding="utf-8")
    said = (f"note: learned:{copy} trained under other DrillStickSlip-v0 settings than this "
            "code gives it (task.history 10 then, 20 now; task.old_weight 2.0 then, (not set) "
            "now; task.telemetry 'wired_pipe' then, 'mud_pulse' now; trained under "
            f"drill-env {drill_env.__version__}, sources {record['source_digest']}): it is "
            "scored under today's")
    task_settings([f"learned:{copy}"], "DrillStickSlip-v0")  # (a note, not an error)
    settings = settings_of("stick_slip")
    notes = replaced_episode_notes([f"learned:{copy}"], "DrillStickSlip-v0", ["random"],
                                   settings)
    assert any(note.startswith(said) for note in notes), notes
    assert not any("trained under" in note for note in replaced_episode_notes(
        [f"learned:{folder}"], "DrillStickSlip-v0", ["random"], settings))
    evaluate_run(copy, seeds=1, controllers=["stiff"], progress=False)
    assert "note: the run trained under other DrillStickSlip-v0 settings" in \
        capsys.readouterr().out
    with pytest.raises(ValueError, match=r"^resume: .*moved started under other "
                                         r"DrillStickSlip-v0 settings than this code gives it "
                                         r"\(task.history 10 then, 20 now.*another --name \(a "
                                         r"--seeds sweep: another --out\)"):
        train(replace(cfg, n_timesteps=3072), copy, resume=True, progress=False)
    assert finished(copy, cfg)  # a sweep's finished run: not trained on, not refused
    # physics given now and not then (a task's new fidelity default) is a change
    assert ("physics.solver.fidelity", "(not set)", "fast") in settings_changes(
        {**record, "physics": {}}, env.settings())
    (copy / TRAINED_WITH).write_text("{", encoding="utf-8")  # damaged: named
    with pytest.raises(ValueError, match=rf"^{re.escape(str(copy / TRAINED_WITH))}: is not "
                                         "valid JSON"):
        train(replace(cfg, n_timesteps=3072), copy, resume=True, progress=False)


def test_a_runs_config_is_read_by_the_rules_of_a_config_file(run, tmp_path):
    """An upgrade review: evaluate and learned:RUN skipped a key of a run's config.yaml
    they did not know (``env_args`` for ``env_kwargs``: the policy ran under the
    defaults) where a resume refused it; a repeated key kept its last value; ``1e-7``
    written by hand was a string (YAML 1.1). Every reader now refuses an unknown key or
    a repeated one naming the file, and reads 1e-7 as a number; a resume names the
    nested setting that differs (hyperparams.n_epochs, not hyperparams)."""
    import shutil

    from agents.settings import task_settings
    from drill_env.physics.config import replace
    from training.config import read_run_config
    from training.evaluate import evaluate_run

    folder, cfg = run
    copy = tmp_path / "edited"
    shutil.copytree(folder, copy)
    saved = copy / "config.yaml"
    text = saved.read_text(encoding="utf-8")
    saved.write_text(text.replace("env_kwargs:", "env_args:"), encoding="utf-8")
    said = (rf"^{re.escape(str(saved))}: env_args: not a setting of a run \(did you mean "
            r"env_kwargs\?\)")
    with pytest.raises(ValueError, match=said):
        evaluate_run(copy, seeds=1, progress=False)
    with pytest.raises(ValueError, match=said):
        LearnedController.load(copy)
    with pytest.raises(ValueError, match=said):
        task_settings([f"learned:{copy}"], "DrillStickSlip-v0")
    saved.write_text(text + "task: drilling\n", encoding="utf-8")
    with pytest.raises(ValueError, match=rf"^{re.escape(str(saved))}: not valid YAML at line "
                                         r"\d+, column 1 \(duplicate key 'task'"):
        LearnedController.load(copy)
    saved.write_text(text.replace("hyperparams:\n", "hyperparams:\n  max_grad_norm: 1e-7\n", 1),
                     encoding="utf-8")
    assert read_run_config(saved)["hyperparams"]["max_grad_norm"] == 1e-7
    saved.write_text(text, encoding="utf-8")
    with pytest.raises(ValueError,
                       match=r"another config \(hyperparams.n_epochs: the run's 2, now 3;"):
        train(replace(cfg, hyperparams={**cfg.hyperparams, "n_epochs": 3}), copy,
              resume=True, progress=False)
