"""A training run's folder: the files it holds, the checks before anything is written
(another run's folder, changed settings, a finished run), the sessions a resumed run is
made of, the seeds of each session's envs, and the checkpoint and rows it writes.
"""

from __future__ import annotations

import csv
import io
import json
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from agents.learned import latest_checkpoint, load_saved
from drill_env.physics.validation import flatten, jsonable
from drill_env.sweep import (
    LOCK_FILE,
    PARTIAL_FILE,
    FolderInUse,
    held_by_another,
    save_text,
    save_whole,
)
from training.config import (
    TRAINED_WITH,
    TRAINING_SEEDS,
    TrainConfig,
    moved_settings,
    read_run_config,
    without_inert_keys,
)


def env_seed(config: TrainConfig, done: int = 0) -> int:
    """The seed of the training envs' reset when a run starts or resumes after ``done``
    env steps (env i gets it + i, SB3's convention), drawn by NumPy's ``SeedSequence``
    from (run seed, ``done``) into ``[TRAINING_SEEDS, 2**32 - n_envs)``. Not the run
    seed + i: runs of neighbouring seeds would then share all but one env's episodes
    (env i + 1 of seed 0 is env i of seed 1), and a resumed run would replay the
    episodes it started with. Above every validation and held-out seed."""
    state = int(np.random.SeedSequence([config.seed, done]).generate_state(1)[0])
    return TRAINING_SEEDS + state % (2**32 - TRAINING_SEEDS - config.n_envs)


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


def session_starts(record: Any) -> tuple[int, ...]:
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


#: The best model's evaluation row (``evaluations.csv``'s columns) and the model file's
#: digest, written beside it: a resume from an earlier checkpoint rewinds the csv past
#: that row and keeps the model, and the row read back from the csv was another one's (a
#: fuzzing walkthrough). A record of another file (a kill between the two saves) is not
#: the model's: the csv is read, as before.
BEST_RECORD = "best_model.json"


def _model_digest(run: Path) -> str:
    import hashlib

    return hashlib.sha256((run / "best_model.zip").read_bytes()).hexdigest()


def write_best(run: Path, row: dict[str, Any]) -> None:
    """Record ``row``, the evaluation of the model saved as ``best_model.zip``."""
    record = {"row": {k: float(v) for k, v in row.items()}, "model": _model_digest(run)}
    save_text(run / BEST_RECORD, json.dumps(record, indent=1))


def best_evaluation(run: Path) -> dict[str, float] | None:
    """The evaluation row of ``run``'s best model: its :data:`BEST_RECORD` where that is
    of the model file there, else (a run of an older version) the first row of highest
    return in ``evaluations.csv`` (as training kept it, unless a resume rewound the file
    past it); None before any."""
    path = run / BEST_RECORD
    if path.exists() and (run / "best_model.zip").exists():
        try:
            record = json.loads(path.read_text(encoding="utf-8"))
            kept = {k: float(v) for k, v in record["row"].items()}
            kept["timesteps"], kept["return"], kept["ssi"]  # noqa: B018 (KeyError if missing)
            if record["model"] == _model_digest(run):
                return kept
        except (ValueError, KeyError, TypeError, AttributeError) as err:
            raise ValueError(f"{path} is damaged ({err!r}); delete it (the best model's "
                             "row is then read from evaluations.csv)") from None
    rows = read_evaluations(run / "evaluations.csv")
    if not rows:
        return None
    best = max(rows, key=lambda r: float(r["return"]))  # the first of equal returns
    return {k: float(v) for k, v in best.items()}


def rewind(run: Path, steps: int, from_checkpoint: bool) -> Resumed:
    """Rewind the run's records to ``steps``, the checkpoint (or final model) it resumes
    from: evaluations after it belong to training that is done again, so their rows
    leave ``evaluations.csv``. The best model stays (it was evaluated), with its return."""
    path = run / "evaluations.csv"
    rows = read_evaluations(path)
    kept_best = best_evaluation(run) if (run / "best_model.zip").exists() else None
    best = kept_best["return"] if kept_best else -np.inf
    if kept_best:  # recorded before its row may leave the csv (a run of an older version)
        write_best(run, kept_best)
    kept = [r for r in rows if int(float(r["timesteps"])) <= steps]
    if len(kept) < len(rows):
        save_text(path, csv_text(rows[0], kept), newline="")  # whole, as add_row writes
    progress = run / "checkpoints" / f"progress_{steps}.json"
    sessions: tuple[int, ...] = ()
    if from_checkpoint and progress.exists():
        try:
            record = json.loads(progress.read_text(encoding="utf-8"))
            wall = float(record["wall_s"])
            sessions = session_starts(record)
        except (ValueError, KeyError, TypeError) as err:  # written whole since 2026-12-05
            raise ValueError(f"resume: {progress} is damaged ({err!r}); delete it (the run's "
                             "wall time then counts from its last evaluation)") from None
    elif not from_checkpoint and (run / "run.json").exists():
        record = json.loads((run / "run.json").read_text(encoding="utf-8"))
        wall = float(record.get("wall_s", 0.0))
        sessions = session_starts(record)
    else:  # a checkpoint of an older version: the last evaluation before it
        wall = float(kept[-1]["wall_s"]) if kept else 0.0
    return Resumed(wall, best, sessions)


#: What a run folder holds once training started (any of them: the folder is a run).
RUN_FILES = ("config.yaml", TRAINED_WITH, "model.zip", "run.json", "checkpoints")
#: Everything training and evaluate write into a run folder: what ``overwrite`` deletes
#: (with the hidden ``.<name>.<pid>.partial<ext>`` of a save cut short, and evaluate's
#: ``evaluation`` and ``evaluation_<level>`` folders).
RUN_OUTPUTS = (*RUN_FILES, "vecnormalize.pkl", "best_model.zip", "best_vecnormalize.pkl",
               BEST_RECORD, "evaluations.csv", "learning_curve.png", "tb")
#: The files training and evaluate write inside those folders (paths from the run): the
#: checkpoints, TensorBoard's event files (time, host, process, count), an evaluation's
#: tables, pictures, series and recordings (its grid search's too; an episode's files are
#: <controller>_<scenario>_seed<N>), the policy files it pinned (left by a kill -9). A
#: file of one's own among them makes the run refused by ``overwrite``: a notes.txt in
#: evaluation/ went with its folder (a trial), and so did names only near ours
#: (benchmark_bars_annotated.png, series/my_analysis.npz, a tfevents file's .backup copy:
#: a fuzzing walkthrough).
OWN_FILES = re.compile(
    r"checkpoints/(model_\d+_steps\.zip|vecnormalize_\d+\.pkl|progress_\d+\.json)"
    r"|tb/[A-Za-z0-9]+_\d+/events\.out\.tfevents\.\d+\.[^/]+\.\d+\.\d+"
    r"|evaluation(_[a-z]+)?/(grid_search/)?(benchmark\.(csv|md)|benchmark_results\.jsonl"
    r"|comparison\.md|benchmark_bars\.png|benchmark_[^/]+_series\.png"
    r"|series/[^/]+_seed\d+\.npz|\.policies/[0-9a-f]+/(checkpoints/)?[^/]+\.(zip|pkl)"
    r"|recordings/(other_runs/[A-Za-z0-9]+/)?[^/]+_seed\d+\.rrd(\.stamp)?)")
#: What a desktop's file browser leaves in every folder it shows (macOS's Finder, Windows'
#: Explorer): no one's data, so neither refused nor kept apart (a review: a Finder visit
#: made --overwrite refuse a run).
DESKTOP_FILES = (".DS_Store", "Thumbs.db", "desktop.ini")
#: The folders they lie in: any other folder inside the run's, empty or not, or a link
#: of one's own there, is not the run's (both went with their folder).
OWN_FOLDERS = re.compile(
    r"tb/[A-Za-z0-9]+_\d+|evaluation(_[a-z]+)?(/grid_search)?"
    r"(/series|/\.policies(/[0-9a-f]+(/checkpoints)?)?|/recordings(/other_runs(/[A-Za-z0-9]+)?)?)?")


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
        if name == LOCK_FILE or name in DESKTOP_FILES:  # (the lock: held while a command
            continue  # writes the run, not deleted)
        written = (name in RUN_OUTPUTS or (name in folders and entry.is_dir())
                   or (PARTIAL_FILE.fullmatch(name) is not None and entry.is_file()))
        (ours if written else others).append(entry)
        if written and entry.is_dir() and not entry.is_symlink():
            others += foreign_inside(run, entry)
    return ours, others


def foreign_inside(run: Path, folder: Path) -> list[Path]:
    """What lies in ``folder`` of ``run`` that training and evaluate do not write (see
    :data:`OWN_FILES`, :data:`OWN_FOLDERS`): a folder of one's own is named, not what
    it holds."""
    found: list[Path] = []
    for f in sorted(folder.rglob("*")):
        if f.name in (LOCK_FILE, *DESKTOP_FILES) or PARTIAL_FILE.fullmatch(f.name) or \
                any(f.is_relative_to(other) for other in found):
            continue
        own = OWN_FOLDERS if f.is_dir() and not f.is_symlink() else OWN_FILES
        if f.is_symlink() or not own.fullmatch(f.relative_to(run).as_posix()):
            found.append(f)
    return found


def check_overwrite(run: Path) -> None:
    """FileExistsError, naming them, if ``run`` holds files training did not write:
    ``overwrite`` deletes only a run's own (``--overwrite`` on a folder that merely held
    a config.yaml deleted the whole folder: a security review); FolderInUse where another
    process writes in a folder of its own (an evaluation)."""
    ours, others = run_outputs(run)
    # an evaluation still writing in one of them, at any depth (a drilling run's grid
    # search holds evaluation/grid_search alone: a review), was deleted under it: a bare
    # errno and its rows lost, or "wrote" said of files gone (a fuzzing walkthrough)
    for lock in (f for folder in ours if folder.is_dir() and not folder.is_symlink()
                 for f in sorted(folder.rglob(LOCK_FILE))):
        if held_by_another(lock.parent):
            raise FolderInUse(f"{lock.parent}: another drill-env process is writing there "
                              "(an evaluation of this run): wait for it to end before "
                              "--overwrite, or give another --name")
    if others:
        from drill_env.physics.units import few

        raise FileExistsError(
            f"{run} holds a training run and files training did not write ("
            + few([e.relative_to(run).as_posix() for e in others], "in the folder")
            + "): --overwrite deletes "
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
        raise ValueError(f"--timesteps: {run} has done {done} env steps already, "
                         f"{config.n_timesteps} asked for; give --timesteps above "
                         f"{done} to continue it, or train afresh under another --name (a "
                         "--seeds sweep: another --out)")
    check_learns(config, done, learnt=updates > 0)
    return done


def check_same_config(run: Path, config: TrainConfig, settings: bool = True) -> None:
    """ValueError if ``run`` was started with another config than ``config`` in anything
    but ``n_timesteps``, ``torch_threads`` and ``fused_adam`` (named by dotted path), or,
    with ``settings``, where its env's settings today differ from those it started
    under (its ``trained_with.json``: a default moved since)."""
    saved = run / "config.yaml"
    if saved.exists():
        # (an empty section is as none: "env_kwargs: the run's unset, now {}" beside the
        # run's own env_kwargs.<key>s, a trial)
        old, new = ({k: v for k, v in flatten(c).items() if v != {}}
                    for c in (without_inert_keys(read_run_config(saved)), jsonable(config)))
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
