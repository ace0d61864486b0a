"""The controller benchmark: controllers x scenarios x seeds on equal terms.

Every episode starts from the scenario's settled operating point at the driller's set
points (the scenario's rpm and WOB), with the bit speed kicked by up to
``start_kick`` from the seed, and runs ``duration`` simulated seconds; the metrics
(:func:`drill_env.metrics.window_metrics`, the code of the env's reward) are taken over
the part after ``warmup`` (stick-slip takes ~25 s to grow from a settled start). Each
controller acts in its own env (``Controller.env_id``) built from the same scenario,
seed and targets, so all of them see the same string, rock and start.

Results stream into ``benchmark_results.jsonl`` as episodes finish (an interrupted
benchmark keeps them; rerunning with the same settings and code computes only the rest,
and the episodes whose recording is asked for and missing), then ``benchmark.csv`` (one row
per controller, scenario and seed, the columns of docs/controllers.md), ``benchmark.md`` and
the plots are written from all finished rows.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import json
import re
import sys
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from agents.episode import run_episode
from agents.learned import PINNED
from agents.settings import (
    UNFINISHED,
    BenchmarkSettings,
    Episode,
    guest_env_kwargs,
    labels,
    set_point_outside,
    stamp,
    task_settings,
)
from agents.tables import COLUMNS, write_outputs
from drill_env.physics.validation import (
    ConfigError,
    jsonable,
    repeated,
)
from drill_env.sweep import save_whole, usable_cores

RESULTS_FILE = "benchmark_results.jsonl"


def controller_digest(controller: str, env_id: str | None = None) -> str:
    """A short hash of a learned controller's model files, or of the source file of a
    controller of your own and what its ``physics()`` and ``env_kwargs()`` return ("" for
    this project's, whose code the fingerprint follows): rows of a benchmark results file
    are reused only for the same model, or the same code and settings."""
    import hashlib

    from agents.registry import (
        CONTROLLERS,
        data_files,
        imported_factory,
        is_imported,
        make_controller,
        source_file,
    )

    digest = hashlib.sha256()
    if controller == "learned" or controller.startswith("learned:"):
        for data in policy_bytes(controller, env_id)[1]:
            digest.update(data)
        return digest.hexdigest()[:12]
    factory = imported_factory(controller) if is_imported(controller) \
        else CONTROLLERS.get(controller)
    own = source_file(factory) if factory is not None else None
    files: list[Path] = []
    if is_imported(controller):  # a factory function's controllers: their class's files
        owner = factory if isinstance(factory, type) else type(make_controller(controller))
        files = data_files(controller, owner)
    if own is None and not files:
        return ""
    if is_imported(controller):  # which of a file's controllers: two of one name in one
        # file shared their rows (the second served the first's numbers)
        digest.update(getattr(factory, "__qualname__", "").encode() + b"\0")
    if own is not None:
        digest.update(own.read_bytes())
    for file in files:
        digest.update(str(file).encode() + b"\0" + file.read_bytes())
    if is_imported(controller):  # what it asks of the physics and the env, resolved: a gain
        # read from a helper module or an environment variable changed these, not its file
        try:
            made = make_controller(controller)
            settings = [getattr(made, name)() for name in ("physics", "env_kwargs")
                        if callable(getattr(made, name, None))]
        except Exception:  # noqa: BLE001 - a controller that cannot be made is said where
            settings = []  # the benchmark makes it; its files still key its rows
        for value in settings:
            digest.update(json.dumps(value, sort_keys=True, default=repr).encode() + b"\0")
    return digest.hexdigest()[:12]


#: How long :func:`policy_bytes` waits at most for a training's save of a new best to
#: end (its model, statistics and record take milliseconds; a record left unmatched by a
#: kill between them waits this long at every benchmark's start).
SAVE_WAIT_S = 2.0


def policy_bytes(controller: str, env_id: str | None = None
                 ) -> tuple[tuple[Path, Path], tuple[bytes, bytes]]:
    """The (model, statistics) files of a ``learned`` controller and what they hold, read
    until two reads agree and a run's best model is the one its record names
    (``best_model.json``, written after the model and its statistics): a training of the
    run may save a new best between them, the new model beside the old statistics."""
    import hashlib
    import time

    from agents.learned import policy_files
    from training.run_folder import BEST_RECORD

    def settled(files: tuple[Path, Path], model: bytes) -> bool:
        record = files[0].parent / BEST_RECORD
        if files[0].name != "best_model.zip" or not record.exists():
            return True
        try:
            return bool(json.loads(record.read_text(encoding="utf-8"))["model"]
                        == hashlib.sha256(model).hexdigest())
        except (OSError, ValueError, KeyError, TypeError):  # (damaged: said where read)
            return True

    path = controller.partition(":")[2] or None
    read = policy_files(path, env_id)
    data = (read[0].read_bytes(), read[1].read_bytes())
    for _ in range(round(SAVE_WAIT_S / 0.1)):
        again = policy_files(path, env_id)
        now = (again[0].read_bytes(), again[1].read_bytes())
        if (again, now) == (read, data) and settled(again, now[0]):
            break
        read, data = again, now
        time.sleep(0.1)
    return read, data


def pin_policy(controller: str, env_id: str | None, out: Path) -> tuple[str, tuple[str, str]]:
    """A ``learned:RUN`` controller's digest (:func:`controller_digest`) and its files as
    they are now, copied into ``out``'s :data:`PINNED` folder, for every episode to load:
    each loaded the run's files afresh, so an evaluation beside a training of the run
    mixed the models it saved on the way in one table, under the first one's name (a
    fuzzing walkthrough)."""
    import hashlib

    files, data = policy_bytes(controller, env_id)
    digest = hashlib.sha256(data[0] + data[1]).hexdigest()[:12]
    run = Path(controller.partition(":")[2])
    pinned = []
    for file, content in zip(files, data, strict=True):  # (at its path in the run)
        copy = out / PINNED / digest / (file.relative_to(run) if file.is_relative_to(run)
                                        else file.name)
        copy.parent.mkdir(parents=True, exist_ok=True)
        save_whole(copy, functools.partial(write_bytes, content))
        pinned.append(str(copy))
    return digest, (pinned[0], pinned[1])


@contextlib.contextmanager
def pinned_in(out: Path) -> Iterator[None]:
    """Within: the policies a benchmark into ``out`` pins there (:data:`PINNED`); removed
    when it ends, also what a killed one left: the digest-named folders alone, and
    :data:`PINNED` where that leaves it empty (a folder of one's own of that name is
    left as it is)."""
    def remove() -> None:
        import shutil

        for folder in (out / PINNED).glob("*"):
            if folder.is_dir() and not folder.is_symlink() and \
                    re.fullmatch("[0-9a-f]{12}", folder.name):
                shutil.rmtree(folder, ignore_errors=True)
        with contextlib.suppress(OSError):  # (none, or not empty)
            (out / PINNED).rmdir()

    remove()
    try:
        yield
    finally:
        remove()


def write_bytes(content: bytes, path: str) -> None:
    """``content`` into the file ``path`` (what :func:`save_whole` calls)."""
    Path(path).write_bytes(content)


def episodes(controllers: Sequence[str], scenarios: Sequence[str], seeds: Sequence[int],
             settings: BenchmarkSettings, out: Path, record: bool = False,
             env_id: str | None = None) -> list[Episode]:
    """Every (controller, scenario, seed); the first seed keeps its time series. A
    ``learned:RUN`` controller's policy files are pinned in ``out`` (:func:`pin_policy`)."""
    plain = dataclasses.asdict(settings)
    names = dict(zip(controllers, labels(controllers), strict=True))
    pinned = {c: pin_policy(c, env_id, out) for c in controllers if c.startswith("learned:")}
    digests = {c: pinned[c][0] if c in pinned else controller_digest(c, env_id)
               for c in controllers}
    return [Episode(c, s, seed, plain, str(out), record, seed == seeds[0], env_id,
                    names[c], digests[c], policy=pinned[c][1] if c in pinned else None)
            for s in scenarios for seed in seeds for c in controllers]


def replaced_episode_settings(trained: dict[str, Any], settings: BenchmarkSettings,
                              scenario: str) -> list[tuple[str, Any, Any]]:
    """(key, trained value, benchmark value) of each episode setting (scenario, length,
    start kick) a policy trained under and the benchmark's own episodes replace: what
    ``evaluate`` and a task benchmark say, so that it is not done silently."""
    ours = {"scenario": scenario, "episode_duration": settings.duration,
            "start_kick": settings.start_kick}
    return [(key, trained[key], value) for key, value in ours.items()
            if key in trained and trained[key] != value]


def run_stamp(fingerprint: str) -> str:
    """A short digest of a run's fingerprint: the same for all its rows."""
    import hashlib

    return hashlib.sha256(fingerprint.encode()).hexdigest()[:16]


def fingerprint(settings: BenchmarkSettings, env_id: str | None = None) -> str:
    """What a stored row depends on besides its key: rows of other settings, or computed
    by other code (the simulator, scenarios, metrics, controllers), are not reused."""
    from drill_env.sweep import source_digest

    return json.dumps({"settings": jsonable(settings), "env_id": env_id,
                       "code": source_digest("drill_env", "agents")}, sort_keys=True)


def check_guest_set_points(controllers: Sequence[str], settings: BenchmarkSettings) -> None:
    """ConfigError naming a controller that acts in a task's env (a guest) whose set-point
    ranges do not hold the set points given: found before any episode runs, not in it."""
    import gymnasium as gym

    import drill_env  # noqa: F401  (registers the env ids)
    from agents.registry import make_controller

    for name in controllers:
        controller = make_controller(name)
        if controller.env_id == "DrillString-v0":
            continue
        env: Any = gym.make(controller.env_id, **guest_env_kwargs(controller))
        config = env.unwrapped.config
        env.close()
        if out := set_point_outside(settings.surface_speed, settings.weight_on_bit, config):
            key, value, low, high, unit = out
            raise ConfigError(
                f"{key}: {value:g} {unit} lies outside {controller.env_id}'s range "
                f"{low:g}-{high:g} {unit}, where {name} acts (a task's policy drills a "
                "scenario benchmark in its own env)")


def check_held_actions(controllers: Sequence[str], env_id: str | None) -> None:
    """ValueError unless each ``held:...`` gives one value, or one per action, of the env
    it acts in (``env_id``, else ``DrillString-v0``): said before any episode runs, not in
    a worker after other controllers' episodes."""
    held = [n for n in controllers if n.startswith("held:")]
    if not held:
        return
    import gymnasium as gym

    import drill_env  # noqa: F401  (registers the env ids)
    from agents.trivial import HeldAction

    env = gym.make(env_id or "DrillString-v0")
    try:
        size = int(np.prod(env.action_space.shape or ()))
    finally:
        env.close()
    for name in held:
        try:
            HeldAction.parse(name.partition(":")[2]).check_size(size)
        except ValueError as err:
            raise ValueError(f"controllers: {str(err).partition(': ')[2]} "
                             f"({env_id or 'DrillString-v0'})") from None


def run_benchmark(controllers: Sequence[str], scenarios: Sequence[str], seeds: Sequence[int],
                  out: Path, settings: BenchmarkSettings | None = None,
                  workers: int | None = None, ray_address: str | None = None,
                  record: bool = False, progress: bool = True, env_id: str | None = None,
                  heading: str = "Controller benchmark") -> list[dict[str, Any]]:
    """Run what is not in ``out/benchmark_results.jsonl`` yet, then write the table,
    summary and plots of every finished row (``heading``: benchmark.md's title) and print
    the table (``progress``: the progress bar and the note of reused rows). Returns the
    rows."""
    from drill_env.progress import progress_bar
    from drill_env.sweep import ResultStore, folder_lock, make_executor

    settings = settings or BenchmarkSettings()
    if objects := [c for c in controllers if not isinstance(c, str)]:  # (an AttributeError
        # deep inside: 'type' object has no attribute 'startswith')
        raise TypeError(f"controllers: names, not {type(objects[0]).__name__} objects "
                        f"({objects[0]!r:.60}): a built-in name, or a class of your own as "
                        "'file.py:ClassName' (worker processes import it by name, and "
                        "stored rows follow its file; one defined in a notebook or at the "
                        "prompt: save it in a .py file first; docs/controllers.md)")
    if (twice := repeated(scenarios)) is not None:
        raise ValueError(f"scenarios: {twice!r} is given twice")
    if env_id is not None and settings.set_points():
        raise ConfigError(
            f"{next(iter(settings.set_points()))}: a task benchmark drills at the targets its "
            "task draws from each seed (the same for every controller); set points are a "
            "scenario benchmark's")
    if env_id is None and settings.set_points():
        check_guest_set_points(controllers, settings)
    if env_id is None and settings.env_kwargs:
        raise ConfigError(
            f"env_kwargs: {sorted(settings.env_kwargs)} would change nothing in a scenario "
            "benchmark, where each controller runs in its own env at the scenario's set "
            "points: they are a task benchmark's (env_id, --task); config overrides go in "
            "physics")
    check_held_actions(controllers, env_id)
    if env_id is not None:  # the policies' task settings, unless the caller gave its own
        settings = dataclasses.replace(settings, env_kwargs={
            **task_settings(controllers, env_id), **settings.env_kwargs})
    labels(controllers)  # a name that does not load is refused before --out is made
    out = Path(out)
    # one process writes the folder: a second benchmark into it is refused
    with folder_lock(out, "this benchmark", tidy=("series",)), pinned_in(out):
        store = ResultStore(out / RESULTS_FILE, fingerprint(settings, env_id))
        todo_all = [dataclasses.replace(e, stamp=stamp(store.fingerprint, e.key),
                                        run=run_stamp(store.fingerprint))
                    for e in episodes(controllers, scenarios, seeds, settings, out, record,
                                      env_id)]
        # a stored row is rerun only to write its series or a recording asked for, missing
        # or made by another run, or where it is not a row this episode writes (an edit)
        unsound = [e.key for e in todo_all
                   if e.key in store and not sound_row(store.get(e.key), e)]
        todo = [e for e in todo_all
                if e.key not in store or e.key in unsound or not e.outputs_current()]
        reused = len(todo_all) - len(todo)
        if store.ignored and progress:  # (it started afresh without a word)
            print(f"benchmark: {store.ignored} stored row(s) of other settings or code in "
                  f"{out / RESULTS_FILE}: not used (kept in the file)", file=sys.stderr)
        if store.cut and progress:
            print(f"benchmark: the last line of {out / RESULTS_FILE} was cut (a run stopped "
                  "while writing it): skipped, its episode runs again", file=sys.stderr)
        if (store.damaged or unsound) and progress:
            print(f"benchmark: {store.damaged + len(unsound)} line(s) of {out / RESULTS_FILE} "
                  "are not rows this run can use (damaged or edited by hand"
                  + (f": {unsound[0]}" if unsound else "") + "): skipped, their episodes "
                  "run again", file=sys.stderr)
        if reused and progress:
            print(f"benchmark: {reused} of {len(todo_all)} episodes already in "
                  f"{out / RESULTS_FILE} (same settings and code; a controller of your own: its "
                  f"file and data_files): not rerun", file=sys.stderr)
        # before any episode: one recorded now would replace theirs under the same name
        set_aside_stale_recordings(todo_all, out, progress)
        if todo:
            from agents.registry import make_controller

            # each policy loaded once here first: a damaged file is the command's error before
            # any episode runs, not after the classical controllers' episodes
            for name, episode_env in {(e.controller, e.env_id) for e in todo
                                      if e.controller.startswith("learned")}:
                make_controller(name, env_id=episode_env)  # (the run's files: named)
            local = min(workers or usable_cores(), len(todo))
            executor = make_executor(local if ray_address is None else None, ray_address)
            bar = progress_bar(total=len(todo_all), initial=len(todo_all) - len(todo),
                               unit="episode", desc="benchmark", disable=not progress,
                               file=sys.stderr)
            try:
                def keep(k: int, row: dict[str, Any]) -> None:
                    store.put(todo[k].key, row)
                    bar.update(1)

                for k, row in executor.map_unordered(run_episode, todo, late=keep):
                    keep(k, row)
            finally:
                bar.close()
                executor.close()
        rows = [store.get(e.key) for e in todo_all]
        names = labels(controllers)
        # the model file the rows ran, as pinned (the run's files may have moved on since:
        # a checkpoint newer than the one pinned was named; a review)
        pinned = {e.controller: Path(e.policy[0]).name for e in todo_all if e.policy}
        runs = {name: f"{c.partition(':')[2]} ({pinned[c]})"
                for c, name in zip(controllers, names, strict=True) if c in pinned}
        first_seed = seeds[0] if len(seeds) else 0
        # the series this run's episodes wrote (another benchmark into the same folder at the
        # same time overwrote them: a picture of its episodes beside this run's table)
        stamps = {(e.label, e.scenario): e.stamp for e in todo_all if e.seed == first_seed}
        write_outputs(rows, out, names, scenarios, settings, env_id, heading,
                      first_seed=first_seed, runs=runs, stamps=stamps)
        return rows


def sound_row(row: Any, episode: Episode) -> bool:
    """Whether ``row``, stored under ``episode``'s key, is one :func:`run_episode` writes
    for it: its columns there, the episode's controller, scenario and seed, numbers where
    the metrics are. A row edited by hand ("abc" for a ROP) ended the command with "could
    not convert string to float: 'abc'", naming neither file nor row; a seed changed by
    hand went into benchmark.csv (an outside check)."""
    if not (isinstance(row, dict) and set(COLUMNS) <= row.keys()):
        return False
    if (row["controller"], row["scenario"], row["seed"]) != (
            episode.label, episode.scenario, episode.seed):
        return False
    return all(isinstance(row[c], int | float) and not isinstance(row[c], bool)
               for c in COLUMNS[3:])


def set_aside_stale_recordings(episodes: Sequence[Episode], out: Path, say: bool) -> None:
    """Move the recordings under these rows' names that another run made (other
    settings or code: the stamp beside them differs, or is missing) to
    ``recordings/other_runs/<their stamp>/``, before the run records its own: a rerun
    into the folder, with ``--record``, replaced them, without it, left them beside a table
    they do not replay. Says how many it moved."""
    moved = cut = 0
    for e in episodes:
        if not e.recording.exists() or e.recording_current():
            continue
        sidecar = e.recording_stamp
        lines = sidecar.read_text(encoding="utf-8").split() if sidecar.exists() else []
        if lines == [UNFINISHED, e.run]:  # this run's own, cut short by an interrupt
            e.recording.unlink()
            sidecar.unlink()
            cut += 1
            continue
        # one folder per run (its run stamp; a recording of before it had only its row's),
        # so a second set-aside keeps the first; a damaged stamp is not a path
        stamp = lines[-1] if lines else ""
        folder = stamp if stamp.isalnum() and stamp.isascii() else "unstamped"
        aside = out / "recordings" / "other_runs" / folder
        aside.mkdir(parents=True, exist_ok=True)
        for file in (e.recording, sidecar):
            if file.exists():
                file.replace(aside / file.name)
        moved += 1
    if moved and say:
        print(f"benchmark: {moved} recording(s) of another run (other settings or code) "
              f"under this table's names moved to {out / 'recordings' / 'other_runs'}",
              file=sys.stderr)
    if cut and say:
        again = ", recorded again" if any(e.record for e in episodes) else ""
        print(f"benchmark: {cut} recording(s) an interrupt cut short: deleted{again}",
              file=sys.stderr)
