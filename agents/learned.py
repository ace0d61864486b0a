"""A trained policy behind the controller interface: the controller ``learned``.

``LearnedController.load()`` takes a run folder of ``drill-env train``
(``logs/runs/<name>``: its best model on the validation seeds if there is one, else its
final model, else its last checkpoint) or a shipped policy (``agents/trained/<task>/``,
the default). It acts in the env of its task (``env_id``) with the env keywords it was
trained with, normalises the observation with the training statistics (VecNormalize,
frozen) and predicts deterministically. Policy rate.
"""

from __future__ import annotations

import json
import pickle
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from agents.base import Rate
from drill_env.tasks import TASK_ENVS

#: Shipped policies, one folder per task: model.zip, vecnormalize.pkl, config.yaml,
#: README.md (how it was trained, the command that reproduces it).
TRAINED = Path(__file__).resolve().parent / "trained"
#: Env id -> task name of the shipped policies.
TASK_OF_ENV = {env_id: task for task, env_id in TASK_ENVS.items()}


class LearnedController:
    """A Stable-Baselines3 policy with its observation normalisation."""

    name: ClassVar[str] = "learned"
    rate: ClassVar[Rate] = "policy"
    #: Where its env id comes from, as a refused reset says it.
    env_id_from: ClassVar[str] = "its config.yaml names"

    def __init__(self, model: Any, normalizer: Any, env_id: str, env_kwargs: dict[str, Any],
                 source: Path) -> None:
        self.model = model
        self.normalizer = normalizer
        self.env_id = env_id
        self._env_kwargs = dict(env_kwargs)
        self.source = source

    @classmethod
    def load(cls, path: str | Path | None = None, env_id: str | None = None,
             files: tuple[Path, Path] | None = None) -> LearnedController:
        """From a run folder or a shipped policy folder; default: the shipped policy of
        ``env_id``'s task (``DrillStickSlip-v0`` when none is given). ``files``: the
        (model, VecNormalize statistics) to load instead of the folder's own, e.g. one of
        the run's checkpoints."""
        folder = policy_folder(path, env_id)
        model_file, norm_file = files if files is not None else _files(folder)
        from training.config import algo_class, read_run_config

        if not (folder / "config.yaml").exists():  # (a plain SB3 run's model.zip and
            # vecnormalize.pkl: a bare errno of the missing file, an outside trial)
            raise FileNotFoundError(f"learned: {folder} has no config.yaml, so it is not a "
                                    f"run folder of drill-env train; {ELSEWHERE}")
        config = read_run_config(folder / "config.yaml")

        try:
            algo = algo_class(config.get("algo", "ppo"))
        except ValueError as err:
            raise ValueError(f"{folder / 'config.yaml'}: {err}") from None
        name = f"{folder / 'config.yaml'}: algo {config.get('algo', 'ppo')!r}, but "
        try:
            model = load_saved(model_file, lambda p: algo.load(p, device="cpu"))
        except (TypeError, AttributeError) as err:  # (a SAC model loaded as PPO: a TypeError
            # of SACPolicy's arguments; PPO's as SAC: no attribute 'actor'; or a model of
            # another SB3 version or policy class)
            raise ValueError(f"{name}{model_file.name} does not load as one ({err}): the "
                             "model of another algorithm, or of another Stable-Baselines3 "
                             "version?") from None
        if getattr(model, "_n_updates", 1) == 0:  # saved before any gradient step
            import warnings

            why = ("SAC's learning_starts" if config.get("algo") == "sac"
                   else "PPO updates only after its first rollout")
            warnings.warn(f"{run_file(model_file, folder)}: saved at {model.num_timesteps} "
                          f"env steps, before the first gradient step ({why}): an untrained "
                          "policy", RuntimeWarning, stacklevel=2)

        normalizer = _statistics((norm_file,))
        return cls(model, normalizer, TASK_ENVS[config["task"]], config.get("env_kwargs", {}),
                   folder)

    def env_kwargs(self) -> dict[str, Any]:
        return dict(self._env_kwargs)

    def physics(self) -> dict[str, Any]:
        return {}  # the task's top drive (stiff PI) with the policy's correction

    def reset(self, env: Any) -> None:
        """Check that ``env`` (unwrapped) takes what the policy was trained on: the same
        observation and action shapes (a policy of one task in another's env)."""
        shapes = [(getattr(getattr(env, space, None), "shape", None),
                   getattr(self.model, space).shape)
                  for space in ("observation_space", "action_space")]
        if any(have is not None and have != want for have, want in shapes):
            spec = getattr(env, "spec", None)
            # (not "trained on": the env id is its config.yaml's word, which can be wrong)
            raise ValueError(f"controller: this policy's model takes observation "
                             f"{shapes[0][1]}, action {shapes[1][1]} ({self.env_id_from} "
                             f"{self.env_id}); {getattr(spec, 'id', type(env).__name__)} has "
                             f"observation {shapes[0][0]}, action {shapes[1][0]}")

    def act(self, observation: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        observation = np.asarray(observation, dtype=np.float32)
        if observation.shape != self.model.observation_space.shape:  # (numpy's broadcast
            # error from inside the normalisation, a new user's trial)
            raise ValueError(f"observation: this policy takes shape "
                             f"{self.model.observation_space.shape} ({self.env_id}), got "
                             f"{observation.shape}")
        obs = self.normalizer.normalize_obs(observation[None])
        action, _ = self.model.predict(obs, deterministic=True)
        return np.asarray(action[0], dtype=np.float32)


def sb3_policy(model: str | Path, statistics: str | Path | None = None, *, algo: str | type,
               env_id: str, name: str = "my-policy", env_kwargs: dict[str, Any] | None = None
               ) -> type[LearnedController]:
    """A controller class for a Stable-Baselines3 model trained elsewhere (plain SB3,
    rl-zoo3): ``model`` its ``.zip``, ``statistics`` its ``VecNormalize`` file (None: the
    observations went in raw), ``algo`` its algorithm (``"ppo"``, ``"sac"``, an
    sb3-contrib name such as ``"tqc"``, or the class: a zip does not say which of the
    algorithms sharing a policy class saved it), ``env_id`` the env it was trained in,
    ``env_kwargs`` the settings it was trained with (a task benchmark runs every
    controller under them). Its files are the class's ``data_files``: a benchmark reruns
    its rows when they, or the file that calls this, change. In ``mine.py``::

        MyPolicy = sb3_policy("runs/x/model.zip", "runs/x/vecnormalize.pkl", algo="sac",
                              env_id="DrillOptimise-v0", name="my-sac")

    then ``drill-env benchmark --task drilling --controllers mine.py:MyPolicy,learned``.
    Files, algorithm and env id are checked when the class is made, the model loaded
    when it is called."""
    import zipfile

    import gymnasium

    from agents.tables import CHOOSES_RPM
    from drill_env.vector import registered

    try:
        registered(env_id)
    except gymnasium.error.Error as err:  # NameNotFound, VersionNotFound...
        raise ValueError(f"env_id: {err}") from None
    algorithm = algorithm_class(algo)
    files = tuple(Path(f) for f in (model, statistics) if f is not None)
    for field, file in zip(("model", "statistics"), files, strict=False):
        if not file.is_file():
            raise ValueError(f"{field}: no file {file}")
    if len(files) == 2 and zipfile.is_zipfile(files[1]):  # (the two swapped: "damaged")
        raise ValueError(f"statistics: {files[1]} is a zip file (a saved model?), not the "
                         "VecNormalize statistics VecNormalize.save writes (a pickle, .pkl)")
    kwargs = dict(env_kwargs or {})

    def __init__(self: LearnedController) -> None:
        try:
            loaded = load_saved(files[0], lambda p: algorithm.load(p, device="cpu"))
        except (TypeError, AttributeError) as err:  # as LearnedController.load says it
            raise ValueError(f"model: {files[0]} does not load as {algorithm.__name__} ({err}):"
                             " the model of another algorithm (algo=), or of another "
                             "Stable-Baselines3 version?") from None
        LearnedController.__init__(self, loaded, _statistics(files[1:]), env_id, kwargs,
                                   files[0].parent)

    caller = sys._getframe(1).f_globals.get("__name__", __name__)
    return type(name, (LearnedController,), {
        "__init__": __init__, "name": name, "data_files": tuple(map(str, files)),
        "env_id": env_id, "env_id_from": "sb3_policy's env_id names",
        "sets_own_speed": env_id == CHOOSES_RPM,
        # the caller's module: a benchmark's stored rows follow that file's code too
        "__module__": caller,
        "__doc__": f"{files[0]} ({algorithm.__name__}) in {env_id} (agents.learned.sb3_policy)"})


def algorithm_class(algo: str | type) -> Any:
    """The Stable-Baselines3 or sb3-contrib algorithm ``algo`` names (any case), or
    ``algo`` itself if it is a class with ``load``."""
    import importlib

    if isinstance(algo, type):
        if not callable(getattr(algo, "load", None)):
            raise ValueError(f"algo: {algo.__name__} has no load(): not an algorithm class")
        return algo
    known: dict[str, Any] = {}
    for package in ("stable_baselines3", "sb3_contrib"):
        try:
            module = importlib.import_module(package)
        except ImportError:
            continue
        known.update({n.lower(): getattr(module, n) for n in getattr(module, "__all__", ())
                      if isinstance(getattr(module, n, None), type)
                      and callable(getattr(getattr(module, n), "load", None))})
    if not isinstance(algo, str) or algo.lower() not in known:
        raise ValueError(f"algo: {algo!r} is not an algorithm of Stable-Baselines3 or "
                         f"sb3-contrib; known: {sorted(known)}")
    return known[algo.lower()]


class _Raw:
    """Observations as they come: a model trained without VecNormalize."""

    @staticmethod
    def normalize_obs(observation: np.ndarray) -> np.ndarray:
        return observation


def _statistics(files: tuple[Path, ...]) -> Any:
    """The VecNormalize statistics in ``files`` (none: :class:`_Raw`), frozen."""
    if not files:
        return _Raw()

    from stable_baselines3.common.vec_env import VecNormalize

    normalizer = load_saved(files[0], lambda saved: saved, pickled=True)  # (no venv)
    if not isinstance(normalizer, VecNormalize):
        raise ValueError(f"statistics: {files[0]} holds {type(normalizer).__name__}, not "
                         "VecNormalize statistics (VecNormalize.save)")
    normalizer.training = False
    return normalizer


#: The folder of a benchmark's ``--out`` where it keeps the ``learned:RUN`` policies'
#: files it runs, as they were when it started, each at its path in the run under the
#: files' digest (:func:`agents.benchmark.pin_policy`); removed when it ends.
PINNED = ".policies"


def run_file(file: Path, folder: Path) -> Path:
    """``file`` by its name in the run ``folder``: a pinned copy's (:data:`PINNED`) is
    named as the run's own file, as the user knows it."""
    parts = Path(file).parts
    if PINNED not in parts[:-2]:
        return Path(file)
    return folder.joinpath(*parts[parts.index(PINNED) + 2:])


def policy_folder(path: str | Path | None = None, env_id: str | None = None) -> Path:
    """The folder :meth:`LearnedController.load` reads: ``path``, or the shipped policy
    of ``env_id``'s task (``DrillStickSlip-v0`` when none is given)."""
    if path is not None:
        return Path(path)
    task = TASK_OF_ENV.get(env_id or "DrillStickSlip-v0")
    if task is None:
        raise ValueError(f"learned: no shipped policy for {env_id}; known: "
                         f"{sorted(TASK_OF_ENV)}")
    return TRAINED / task


def moved_settings_note(name: str, folder: Path, env_id: str, env_kwargs: dict[str, Any]
                        ) -> str | None:
    """A note where the task settings the env ``env_id`` resolves today from the run's
    ``env_kwargs`` (as its caller read them from the run's config) differ from those the
    run in ``folder`` trained under (its ``trained_with.json``: a default moved in a
    later version), naming each; None where they agree or the run has no record (a run
    of a version before 2026-12-06, a policy of your own). The policy is still run: a
    study of a changed setting is a use, not a mistake."""
    from training.config import moved_settings

    moved = moved_settings(folder, env_id, env_kwargs)
    if moved is None:
        return None
    return (f"note: {name} trained under other {env_id} settings than this code "
            f"gives it ({moved}): it is scored under today's, which its observations and "
            "reward follow")


def trained_env(path: str | Path | None = None, env_id: str | None = None
                ) -> tuple[str, dict[str, Any]]:
    """(env id of its task, env keywords) a policy was trained with, from its run's
    ``config.yaml`` read once, without loading the model; a folder without a policy is
    refused as :func:`policy_files` does."""
    policy_files(path, env_id)
    from training.config import read_run_config

    config = read_run_config(policy_folder(path, env_id) / "config.yaml")
    return TASK_ENVS[config["task"]], dict(config.get("env_kwargs") or {})


def policy_files(path: str | Path | None = None, env_id: str | None = None
                 ) -> tuple[Path, Path]:
    """(model, normalisation) files that :meth:`LearnedController.load` would load."""
    return _files(policy_folder(path, env_id))


def load_saved(path: Path, load: Any, pickled: bool = False) -> Any:
    """``load(path)``, or with ``pickled`` ``load`` of the object the pickle ``path``
    holds; a damaged file (a full disk, a copy cut short) is a ValueError naming it and
    what to do, not a traceback from pickle or zipfile. A pickle is unpickled once, here:
    whatever fails in it is damage (telling damage from the load's own error by unpickling
    the file a second time ran its code twice, a security review). Unpickling runs code
    the file names: load only runs of your own or of a source you trust (docs/tasks.md)."""
    import zipfile

    damage = (pickle.UnpicklingError, zipfile.BadZipFile, EOFError, KeyError,
              json.JSONDecodeError)
    try:
        if Path(path).suffix == ".zip" and Path(path).exists() and not zipfile.is_zipfile(path):
            # Stable-Baselines3 says so in a ValueError of its own, naming no run
            raise zipfile.BadZipFile("not a zip file")
        if not pickled:
            return load(str(path))
        with open(path, "rb") as f:  # (a missing file: its FileNotFoundError)
            try:
                saved = pickle.load(f)
            except damage:
                raise
            except Exception as err:  # noqa: BLE001 - garbage can fail in any of pickle's
                # opcodes ("garbage": a ValueError from int())
                raise pickle.UnpicklingError(f"{type(err).__name__}: {err}") from None
        return load(saved)
    except damage as err:
        raise ValueError(f"{path}: damaged, cannot be loaded ({type(err).__name__}: {err}); "
                         "delete it and the files saved with it, and the run's other files "
                         "are used (train --resume: the newest complete checkpoint left; "
                         "nothing falls back by itself); or retrain with --overwrite"
                         ) from None


def checkpoint_steps(model: Path) -> int | None:
    """The env steps in a checkpoint's model file name (``model_<steps>_steps.zip``, as
    training writes it), or None for another file."""
    import re

    found = re.fullmatch(r"model_(\d+)_steps\.zip", Path(model).name)
    return int(found.group(1)) if found else None


def latest_checkpoint(run: Path) -> tuple[Path, Path] | None:
    """(model, normalisation) of the run's last complete checkpoint, as training writes
    them (``checkpoints/model_<steps>_steps.zip`` beside ``vecnormalize_<steps>.pkl``; a
    Ctrl-C saves one too); None if it has none. Other files there are ignored."""
    kept = Path(run) / "checkpoints"
    steps = [k for p in kept.glob("model_*_steps.zip") if (k := checkpoint_steps(p)) is not None]
    for k in sorted(steps, reverse=True):
        if (kept / f"vecnormalize_{k}.pkl").exists():
            return kept / f"model_{k}_steps.zip", kept / f"vecnormalize_{k}.pkl"
    return None


#: Where a model trained outside drill-env train goes (said where one is given as a run).
ELSEWHERE = ("a model trained elsewhere (rl-zoo3, your own SB3 script) is benchmarked by "
             "agents.learned.sb3_policy(model, vecnormalize, algo=..., env_id=...) in a "
             "controller file of yours (docs/controllers.md)")


def no_such_folder(folder: Path, names: Sequence[str] = ()) -> str:
    """"no such folder ``folder``", with the folder beside it that was probably meant
    (a run's name without its ``_seed0``), else, for a bare name, one of ``names`` (a
    task's, misspelt: ``stick-slip``)."""
    from drill_env.physics.validation import closest

    try:
        near = [p.name for p in folder.parent.iterdir() if p.is_dir()]
    except OSError:  # (no such parent either, or not readable)
        near = []
    meant = closest(folder.name, near)
    if meant:
        return f"no such folder {folder} (did you mean {folder.parent / meant}?)"
    named = closest(str(folder), list(names)) if len(folder.parts) == 1 else None
    return f"no such folder {folder}" + (f" (did you mean {named}?)" if named else "")


def _files(folder: Path) -> tuple[Path, Path]:
    """(model, normalisation) of a run or policy folder: the best model if kept."""
    if not folder.is_dir():
        what = f"{folder} is a file, not a folder" if folder.exists() else \
            no_such_folder(folder)
        raise FileNotFoundError(f"learned: {what} (learned:<run folder of drill-env train>)")
    for model, norm in (("best_model.zip", "best_vecnormalize.pkl"),
                        ("model.zip", "vecnormalize.pkl")):
        if (folder / model).exists() and (folder / norm).exists():
            return folder / model, folder / norm
    latest = latest_checkpoint(folder)  # a run stopped before its first evaluation
    if latest is not None:
        return latest
    raise FileNotFoundError(f"learned: {folder} holds neither best_model.zip + "
                            "best_vecnormalize.pkl nor model.zip + vecnormalize.pkl nor a "
                            "checkpoint (a run folder of drill-env train or a shipped "
                            f"policy); {ELSEWHERE}")
