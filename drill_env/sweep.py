"""Running many independent simulations: serially, on local processes, or on Ray.

Sweeps (stability maps, the controller benchmark, training seeds) hand a module-level
function and a list of picklable arguments to an :class:`Executor` and get the results
back AS THEY FINISH, each with the index of its argument, so the caller can write them
down at once (an interrupted sweep keeps them) and show progress. Every task is a pure
function of its argument (its own simulator, its own seed), so the results do not depend
on the backend or on the order tasks finish in.

=====================  =====================================================================
backend                what runs the tasks
=====================  =====================================================================
``serial``             this process, one after the other (``workers=1``)
``processes``          a pool of local processes (``workers``, default: all cores)
``ray``                a Ray cluster (``ray_address``: ``"local"``, ``"auto"`` or an address;
                       the ``distributed`` extra); a lost worker's task is retried
=====================  =====================================================================

:class:`ResultStore` keeps finished results in a JSON-lines file, one line a result, so
a sweep run again skips what is already there.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import importlib.util
import json
import math
import os
import re
import signal
import sys
import threading
import time
import warnings
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, BrokenExecutor, Future, ProcessPoolExecutor, wait
from pathlib import Path, PurePosixPath
from typing import Any, Protocol

#: Called with ``(index, result)`` for a task that finished while a stopped sweep waited
#: for its tasks in flight (Ray's grace, :class:`drill_env.distributed.RayExecutor`): the
#: sweep keeps it as it keeps what it was yielded.
Late = Callable[[int, Any], None]


class Executor(Protocol):
    """Runs ``fn(item)`` for every item; yields ``(index, result)`` as tasks finish;
    ``late`` receives what finishes after the sweep was stopped (where the executor waits
    for its tasks: Ray; local workers are interrupted at once)."""

    name: str

    def map_unordered(self, fn: Callable[[Any], Any], items: Sequence[Any],
                      late: Late | None = None) -> Iterator[tuple[int, Any]]: ...

    def close(self) -> None: ...


class SerialExecutor:
    """This process, one task after the other."""

    name = "serial"

    def map_unordered(self, fn: Callable[[Any], Any], items: Sequence[Any],
                      late: Late | None = None) -> Iterator[tuple[int, Any]]:
        for k, item in enumerate(items):
            yield k, fn(item)

    def close(self) -> None:
        pass


#: The environment variable through which the command line names its command to the pool
#: workers it spawns (their warnings are said as the command's own: :func:`command_warning`).
COMMAND_VARIABLE = "DRILL_ENV_COMMAND"
#: The environment variable naming the folder in which the command and its pool workers
#: mark the warnings said (one empty file each), so that a warning is said once per
#: command, not once per process (a sweep's two or three workers each said it).
SAID_VARIABLE = "DRILL_ENV_WARNINGS_SAID"


def command_warning(command: str, said_folder: str | None = None) -> Any:
    """``warnings.formatwarning`` for a command: a warning meant for its user (a unit
    that looks wrong, a setting that cannot hold) on one line under the command's name,
    not Python's file and source line (a validator's warning showed pydantic's), and
    once: in this process, and in every process sharing ``said_folder`` where it is
    given and exists. On a terminal the line first clears the one it is on, where a
    progress bar may be drawn (the bar then draws itself again below it)."""
    plain = warnings.formatwarning
    said: set[str] = set()  # the same words from two places (two call sites) once

    def first_time(text: str) -> bool:
        if text in said:
            return False
        said.add(text)
        if said_folder is None:
            return True
        mark = os.path.join(said_folder, hashlib.sha1(text.encode()).hexdigest()[:16])
        try:  # created by one process only: the others find it there
            os.close(os.open(mark, os.O_CREAT | os.O_EXCL | os.O_WRONLY))
        except FileExistsError:
            return False
        except OSError:  # the folder gone (another machine's Ray worker): this process's
            pass
        return True

    def formatted(message: Any, category: type[Warning], filename: str, lineno: int,
                  line: str | None = None) -> str:
        if issubclass(category, (UserWarning, RuntimeWarning)):
            text = f"drill-env {command}: warning: {message}\n"
            if not first_time(text):
                return ""
            # (the clearing escape: not in Windows' classic console, which prints it)
            clear = sys.stderr.isatty() and os.name != "nt"
            return ("\r\033[K" if clear else "") + text
        return plain(message, category, filename, lineno, line)

    return formatted


def _single_threaded_worker(parent: int) -> None:
    """A pool worker's set-up: one numba thread (the pool is the parallelism); the first
    Ctrl-C, SIGTERM or SIGHUP interrupts its task (a training run saves its checkpoint)
    and later ones, such as the pool's forwarded copy of a Ctrl-C the whole terminal group
    got, do not cut that short; on Linux the worker is killed with its parent ``parent``
    (a killed command left its workers training into the folder a rerun uses)."""
    os.environ.setdefault("NUMBA_NUM_THREADS", "1")
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    if "numba" in sys.modules:  # (loaded while the set-up was unpickled: read again, or
        # numba starts one thread per core in each worker)
        from numba.core import config

        config.reload_config()
    for signum in STOPPING_SIGNALS:  # (a SIGHUP that came ignored, nohup's, stays so)
        if signum == signal.SIGINT or signal.getsignal(signum) is not signal.SIG_IGN:
            signal.signal(signum, _interrupt_once)
    if command := os.environ.get(COMMAND_VARIABLE):  # (a worker's warning showed Python's
        # file and source line, mixed into the command's progress bar)
        warnings.formatwarning = command_warning(command, os.environ.get(SAID_VARIABLE))
    if sys.platform.startswith("linux"):
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        # SIGKILL, not an interrupt: a worker that saved would then wait forever to hand
        # its result to the dead parent
        libc.prctl(1, int(signal.SIGKILL), 0, 0, 0)  # PR_SET_PDEATHSIG
    else:  # (macOS, Windows: no such signal) a thread that ends the worker with it
        threading.Thread(target=_end_with_parent, daemon=True,
                         name="drill-env-parent-watch").start()
    if os.getppid() != parent:  # the parent died before the call above
        os._exit(1)


def _end_with_parent() -> None:
    """In a pool worker: wait for the parent process to end, then end this one at once,
    as Linux's PR_SET_PDEATHSIG does (a portability review: off Linux a killed command
    left its workers training into the run folders)."""
    import multiprocessing

    parent = multiprocessing.parent_process()
    if parent is not None:
        parent.join()
        os._exit(1)


#: Whether this pool worker was interrupted (:func:`_interrupt_once`), and whether it is
#: running a task (:func:`_unless_interrupted`).
_interrupted = False
_busy = False


def _interrupt_once(signum: int, frame: Any) -> None:
    """Interrupt the task this worker runs; an idle worker (waiting for a task, or ending)
    only notes it: the pool's shutdown ends it, and a KeyboardInterrupt raised inside the
    pool's own queue or exit code printed two tracebacks under the error that stopped the
    command."""
    global _interrupted
    _interrupted = True
    # later ones run a handler that does nothing (SIG_IGN set here made Python print
    # "Signal 15 ignored due to race condition" for one already on its way)
    for signum in STOPPING_SIGNALS:
        signal.signal(signum, _ignore)
    if _busy:
        raise KeyboardInterrupt


def _ignore(signum: int, frame: Any) -> None:
    pass


class Terminated(KeyboardInterrupt):
    """A SIGTERM, handled as a Ctrl-C (the command line's handler raises it)."""


#: The signals that stop long work as Ctrl-C does, keeping what is done (SIGHUP: POSIX's)
STOPPING_SIGNALS: tuple[int, ...] = (signal.SIGINT, signal.SIGTERM) + (
    (signal.SIGHUP,) if hasattr(signal, "SIGHUP") else ())


#: The interrupt this process was sent (:func:`note_interrupt`), kept beside the exception
#: raised for it, which is lost where it is raised inside a ctypes callback (numba's cache
#: writes while it compiles: printed as "Exception ignored").
_noted: type[KeyboardInterrupt] | None = None


def note_interrupt(kind: type[KeyboardInterrupt] = KeyboardInterrupt) -> None:
    """Keep that this process was interrupted, and how (its signal handlers call it)."""
    global _noted
    _noted = kind


def hear_interrupts() -> bool:
    """Python's Ctrl-C handler where SIGINT came ignored, in the main thread (a background
    job of a script, ``drill-env train ... &``, inherits it so, POSIX, and so does a Ray
    worker it started): ``kill -INT`` did nothing to ``train``, which ran to its end
    unsaved, nor Ray's cancel to a task (the command's ``_main``, a scale trial;
    :mod:`drill_env.distributed`). True where installed (the command puts SIG_IGN back
    after it)."""
    if threading.current_thread() is not threading.main_thread() or \
            signal.getsignal(signal.SIGINT) is not signal.SIG_IGN:
        return False
    signal.signal(signal.SIGINT, signal.default_int_handler)
    return True


def clear_interrupt() -> None:
    """Forget a noted interrupt: whoever handled its exception calls it."""
    global _noted
    _noted = None


def noted_interrupt() -> type[KeyboardInterrupt] | None:
    """The interrupt that reached this process and was not yet handled (a pool worker's,
    or one noted by :func:`note_interrupt`), None if none: long work checks it between
    steps and raises it, so an interrupt whose exception was lost still stops it."""
    return KeyboardInterrupt if _interrupted else _noted


@contextlib.contextmanager
def watch_interrupts() -> Iterator[None]:
    """Within: a Ctrl-C is noted (:func:`noted_interrupt`) as well as raised (only where
    Python's own handler is installed, in the main thread; a pool worker's notes its own).
    The note outlives a lost exception until the block ends: the work inside handled it,
    or ended without it."""
    install = (threading.current_thread() is threading.main_thread()
               and signal.getsignal(signal.SIGINT) is signal.default_int_handler)

    def interrupt(signum: int, frame: Any) -> None:
        note_interrupt()
        raise KeyboardInterrupt

    if install:
        signal.signal(signal.SIGINT, interrupt)
    try:
        yield
    finally:
        if install:
            signal.signal(signal.SIGINT, signal.default_int_handler)
        clear_interrupt()


def _unless_interrupted(fn: Callable[[Any], Any], item: Any) -> Any:
    """``fn(item)`` in a pool worker, refused once the worker was interrupted: the tasks
    queued behind the interrupted one (the pool cannot cancel them) would run with the
    interrupts ignored until the pool killed them unsaved. Busy before the check, so an
    interrupt between the two raises here instead of being noted as an idle worker's."""
    global _busy
    _busy = True
    try:
        if _interrupted:
            raise KeyboardInterrupt
        return fn(item)
    finally:
        _busy = False


def usable_cores() -> int:
    """The cores this process may use: its CPU affinity (``taskset``, a cpuset), capped by
    a cgroup CPU quota (:func:`cgroup_quota_cores`), else ``os.cpu_count()``. The default
    number of worker processes: under ``taskset -c 0`` on 2 cores two ran 1.3-1.6x slower
    than one, and a container given a few of many cores started one per host core."""
    if hasattr(os, "sched_getaffinity"):
        cores = len(os.sched_getaffinity(0))
    else:  # (no affinity on this platform)
        cores = os.cpu_count() or 1
    quota = cgroup_quota_cores()
    return max(1, min(cores, quota or cores))


def cgroup_quota_cores(root: Path = Path("/sys/fs/cgroup"),
                       membership: Path = Path("/proc/self/cgroup")) -> int | None:
    """The fewest cores a CPU quota of this process's cgroups allows (None: no quota, or
    no cgroups): cgroup v2's ``cpu.max`` and v1's ``cpu.cfs_quota_us`` over
    ``cpu.cfs_period_us``, in the process's own cgroup (``membership``) and every one
    above it under ``root``, where a quota set higher up (a Kubernetes pod, a systemd
    slice) limits all below it. Only ``root``'s own ``cpu.max`` was read before, which
    is the process's cgroup only inside a container with its own cgroup namespace: a pod
    on cgroup v1, or a job in a slice, started a worker per host core."""
    try:
        lines = membership.read_text(encoding="utf-8").splitlines()
    except OSError:
        lines = []
    quotas = []
    for line in lines:
        _, controllers, path = (line.split(":", 2) + ["", ""])[:3]
        if controllers == "":  # cgroup v2 (in a hybrid layout, mounted at unified/)
            base = root if (root / "cgroup.controllers").exists() else root / "unified"
        elif "cpu" in controllers.split(","):  # cgroup v1's CPU controller
            base = root / controllers if (root / controllers).is_dir() else root / "cpu"
        else:
            continue
        if ".." in PurePosixPath(path.strip()).parts:  # a cgroup outside this mount's
            continue  # namespace: not readable here, and the root's quota is not its own
        here = base / path.strip().lstrip("/")
        # the process's cgroup, those above it, and the mount's own (a namespace's root)
        for folder in dict.fromkeys([*(f for f in (here, *here.parents)
                                       if f.is_relative_to(base)), base]):
            quota = _cgroup_quota(folder, v2=controllers == "")
            if quota is not None:
                quotas.append(quota)
    return min(quotas) if quotas else None


def _cgroup_quota(folder: Path, v2: bool) -> int | None:
    """The cores the CPU quota of the cgroup ``folder`` allows (None: none, or no such
    cgroup here)."""
    try:
        if v2:
            return quota_cores((folder / "cpu.max").read_text(encoding="utf-8"))
        return quota_cores((folder / "cpu.cfs_quota_us").read_text(encoding="utf-8").strip() + " "
                           + (folder / "cpu.cfs_period_us").read_text(encoding="utf-8"))
    except OSError:
        return None


def quota_cores(cpu_max: str) -> int | None:
    """The cores a cgroup v2 ``cpu.max`` (``"<quota> <period>"`` in us, or ``"max
    <period>"``; v1's quota and period in one line, -1 for none) allows, rounded up; None
    where it sets no quota or cannot be read."""
    try:
        quota, period = cpu_max.split()[:2]
        if quota in ("max", "-1"):
            return None
        return max(1, math.ceil(int(quota) / int(period)))
    except (ValueError, ZeroDivisionError):
        return None


#: The most workers ProcessPoolExecutor takes on Windows (it waits on 63 handles, 2 its own)
WINDOWS_MAX_WORKERS = 61


#: A dead worker's error (its own, if any, is printed above it).
WORKER_DIED = ("a worker process died (killed, out of memory, or a script of yours run again "
               "in it: one that starts a sweep needs it under `if __name__ == \"__main__\":`)")


class ProcessExecutor:
    """A pool of ``workers`` local processes (spawned, so numba and threads start clean)."""

    name = "processes"

    def __init__(self, workers: int | None = None) -> None:
        import multiprocessing as mp

        self.workers = max(1, workers or usable_cores())
        if sys.platform == "win32":  # (Windows' wait on the workers takes at most 61)
            self.workers = min(self.workers, WINDOWS_MAX_WORKERS)
        self._pool = ProcessPoolExecutor(self.workers, mp_context=mp.get_context("spawn"),
                                         initializer=_single_threaded_worker,
                                         initargs=(os.getpid(),))

    def map_unordered(self, fn: Callable[[Any], Any], items: Sequence[Any],
                      late: Late | None = None) -> Iterator[tuple[int, Any]]:
        futures: dict[Future, int] = {}
        pending = iter(enumerate(items))
        try:
            # Keep a few tasks per worker in flight: results stream back in order of
            # completion and an interrupt leaves little work half done.
            for k, item in pending:
                futures[self._pool.submit(_unless_interrupted, fn, item)] = k
                if len(futures) >= 2 * self.workers:
                    break
            while futures:
                done, _ = wait(futures, return_when=FIRST_COMPLETED)
                for future in done:
                    k = futures.pop(future)
                    if isinstance(future.exception(), BrokenExecutor):
                        raise RuntimeError(WORKER_DIED) from future.exception()
                    yield k, future.result()
                    for k_next, item in pending:
                        futures[self._pool.submit(_unless_interrupted, fn, item)] = k_next
                        break
        finally:
            for future in futures:
                future.cancel()

    #: Seconds an aborted pool's workers get to finish on their own (a training run
    #: saves its checkpoint at a Ctrl-C) before they are stopped.
    ABORT_GRACE = 15.0

    def close(self) -> None:
        """Shut the pool down. Called while an exception (a Ctrl-C) propagates, it gives
        the workers ``ABORT_GRACE`` seconds to end, then stops the rest: a worker
        interrupted while idle may never answer, and waiting for it could hang the
        interrupted command with its workers left running."""
        if sys.exc_info()[0] is None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            return
        # (ProcessPoolExecutor has no public way to stop its workers before Python 3.14)
        processes = list(getattr(self._pool, "_processes", {}).values())
        self._pool.shutdown(wait=False, cancel_futures=True)  # idle workers are told to end
        for process in processes:  # the interrupt reaches the workers also where it was
            # this process's alone (kill -INT); not on Windows, where os.kill with SIGINT
            # terminates the worker at once: there a Ctrl-C has reached the workers through
            # their console, and on another abort (a task's error) they are not told, and
            # are killed after the grace below without saving
            if process.is_alive() and process.pid and os.name != "nt":
                with contextlib.suppress(OSError):
                    os.kill(process.pid, signal.SIGINT)
        deadline = time.monotonic() + self.ABORT_GRACE
        for process in processes:
            process.join(max(0.0, deadline - time.monotonic()))
        for process in processes:  # (an interrupted worker ignores SIGTERM: SIGKILL)
            if process.is_alive():
                process.kill()
                process.join(2.0)


def make_executor(workers: int | None = None, ray_address: str | None = None) -> Executor:
    """The executor a sweep command asked for: Ray when ``ray_address`` is given, else
    local processes (``workers`` > 1, default all cores) or serial (``workers`` == 1)."""
    if ray_address is not None:
        from drill_env.distributed import RayExecutor

        return RayExecutor(ray_address)
    if workers is not None and workers < 1:
        raise ValueError(f"workers: must be >= 1, got {workers}")
    if workers is not None and workers > 2 * (cores := usable_cores()):  # (999: 31, 8 GB)
        warnings.warn(f"workers: {workers} processes on {cores} cores run no faster "
                      "than one per core, and each holds ~250 MB", UserWarning, stacklevel=2)
    n = workers or usable_cores()
    return SerialExecutor() if n == 1 else ProcessExecutor(n)


def digest(obj: Any) -> str:
    """A short stable key of what results depend on (a JSON-able object): the
    fingerprint a :class:`ResultStore` keeps its lines under."""
    return hashlib.sha256(json.dumps(obj, sort_keys=True).encode()).hexdigest()[:16]


@functools.cache
def source_digest(*packages: str) -> str:
    """A short hash of the Python sources of ``packages`` (importable names): stored
    results were computed by that code, so a changed model, controller or metric is not
    served the old code's results. Hashes file names and bytes, ~1 ms per 100 files."""
    h = hashlib.sha256()
    for package in packages:
        spec = importlib.util.find_spec(package)
        folders = list(spec.submodule_search_locations or []) if spec else []
        if not folders:
            raise ValueError(f"source_digest: {package!r} is not an importable package")
        for folder in folders:
            for file in sorted(Path(folder).rglob("*.py")):
                h.update(f"{package}/{file.relative_to(folder).as_posix()}\0".encode())
                h.update(file.read_bytes())
    return h.hexdigest()[:16]


class ResultStore:
    """Finished results of a sweep, one JSON object per line, appended as they arrive.

    ``fingerprint`` identifies what the results belong to (settings, configs): lines
    written under another fingerprint are ignored, so a changed sweep starts afresh
    instead of mixing old results in. A half-written last line (a killed process) is
    skipped. :attr:`ignored` counts the first, :attr:`cut` says the second, for the caller
    to say (once: the next result goes on a line of its own after the half line);
    :attr:`damaged` counts lines of JSON that are not a result (an edit), skipped as
    well. A line that is not JSON before the last is skipped without a count: a cut line
    the next result ended reads the same as damage.
    """

    def __init__(self, path: Path, fingerprint: str) -> None:
        self.path = Path(path)
        self.fingerprint = fingerprint
        self._results: dict[str, Any] = {}
        #: a killed writer's half line: the next result starts on a line of its own
        self._broken_end = False
        self.ignored = 0  # results of another fingerprint
        self.cut = False  # the last line is a killed writer's half line
        self.damaged = 0  # lines of JSON that are not a result (edits)
        if self.path.exists():
            # bytes that are not UTF-8 (a damaged file) spoil their line only: it is
            # skipped, or kept with U+FFFD in a string where it still parses as JSON
            text = self.path.read_bytes().decode("utf-8", errors="replace")
            self._broken_end = bool(text) and not text.endswith("\n")
            lines = text.splitlines()
            for index, line in enumerate(lines):
                try:
                    entry = json.loads(line)
                except json.JSONDecodeError:  # (before the last: a cut line that the
                    # next result ended, or damage; a result lost with it is run again)
                    self.cut = self._broken_end and index == len(lines) - 1
                    continue
                if not (isinstance(entry, dict) and {"key", "result"} <= entry.keys()):
                    self.damaged += 1  # not a result (an edit)
                    continue
                if entry.get("fingerprint") == fingerprint:
                    self._results[entry["key"]] = entry["result"]
                else:
                    self.ignored += 1

    def __contains__(self, key: str) -> bool:
        return key in self._results

    def __len__(self) -> int:
        return len(self._results)

    def get(self, key: str) -> Any:
        return self._results[key]

    def put(self, key: str, result: Any) -> None:
        self._results[key] = result
        self.path.parent.mkdir(parents=True, exist_ok=True)
        with naming(self.path), self.path.open("a", encoding="utf-8") as f:
            if self._broken_end:
                f.write("\n")
                self._broken_end = False
            f.write(json.dumps({"fingerprint": self.fingerprint, "key": key,
                                "result": result}) + "\n")
            f.flush()


def save_text(path: Path, text: str, newline: str | None = None) -> None:
    """``text`` into ``path`` whole (:func:`save_whole`)."""
    save_whole(path, lambda file: Path(file).write_text(text, newline=newline,
                                                       encoding="utf-8"))


def save_whole(path: Path, save: Callable[[str], Any]) -> None:
    """``save(file)`` into a hidden file beside ``path``, then renamed to it: a process
    killed mid-write leaves no truncated file where it is read (a resume of a model cut
    short crashed on an UnpicklingError; a benchmark interrupted while drawing left its
    pictures half there). A save that raises (a Ctrl-C) leaves no partial file either.
    On Windows a rename over a file another program holds open is tried again for a
    second, then refused naming the file (:data:`RENAME_TRIES`). The hidden file is this
    process's own (:func:`partial_file`). An error the system gives without a file's name
    (a full disk: "No space left on device") is raised naming ``path``."""
    partial = partial_file(path)
    try:
        with naming(path):
            save(str(partial))
            _replace(partial, path)
    finally:
        partial.unlink(missing_ok=True)


@contextlib.contextmanager
def naming(path: Path) -> Iterator[None]:
    """An error of the system raised inside without a file's name (a full disk's "No
    space left on device" comes from a write, which names none; "[Errno 28]" said not
    where: an outside check), or naming its hidden partial file (a folder made read-only:
    ".benchmark.14507.partial.csv", a fuzzing walkthrough), raised again naming ``path``."""
    try:
        yield
    except OSError as err:
        if err.filename not in (None, str(partial_file(path))) or err.errno is None:
            raise
        raise type(err)(err.errno, err.strerror, str(path)) from err


def partial_file(path: Path) -> Path:
    """The hidden file :func:`save_whole` writes ``path`` into first,
    ``.<stem>.<process id>.partial<suffix>`` (the suffix kept: matplotlib and NumPy
    choose the format by it). One name for all processes let two of them that saved the
    same output at once (two benchmarks into one folder) write into one file: one's
    rename then found nothing ("No such file or directory") and a reader saw the two
    files mixed under the final name (an outside check)."""
    return path.with_name(f".{path.stem}.{os.getpid()}.partial{path.suffix}")


#: What :func:`partial_file` names, and the single-name partial files of earlier versions.
PARTIAL_FILE = re.compile(r"\..+\.partial(\.[^.]*)?")
#: The hidden file a command holds locked in the folder it writes (:func:`folder_lock`).
LOCK_FILE = ".drill-env.lock"


class FolderInUse(OSError):
    """Another process holds the folder a command would write (:func:`folder_lock`)."""


@contextlib.contextmanager
def folder_lock(folder: Path, what: str, tidy: Sequence[str] = ()) -> Iterator[None]:
    """Hold ``folder`` for this process while a command writes it (``what``, in words:
    "this training run"); :class:`FolderInUse` naming the folder if another process holds
    it (any of the commands that take the lock: which one, the lock does not say).
    Two trainings of one run (or a ``--resume`` of one still running) trained side by side
    into its files, and a second benchmark into one ``--out`` overwrote the first's series
    (an outside check). The lock is the system's, on the hidden :data:`LOCK_FILE`
    (``filelock``): a process that dies, even by ``kill -9``, lets go of it, so a resume
    after a kill is not refused. Once held, the partial files of saves cut short
    (:func:`save_whole`) in the folder and its subfolders named in ``tidy`` are deleted,
    unless fresh (:data:`STALE_PARTIAL_S`). A folder made here that is left empty (a
    refused command) is removed again, with the parents made for it (a mutation round:
    ``runs/new/run`` refused left ``runs/new``)."""
    from filelock import FileLock, Timeout

    missing = [f for f in (folder, *folder.parents) if not f.exists()]  # deepest first
    made = bool(missing)
    folder.mkdir(parents=True, exist_ok=True)
    lock = FileLock(folder / LOCK_FILE)
    try:
        lock.acquire(timeout=0)
    except Timeout:
        raise FolderInUse(f"{folder}: another drill-env process is writing there (a "
                          "benchmark, a training run, an evaluation or a stability map): "
                          f"wait for it to end, or give {what} another folder") from None
    try:
        stale = time.time() - STALE_PARTIAL_S
        for where in (folder, *(folder / name for name in tidy)):
            for entry in where.iterdir() if where.is_dir() else ():
                with contextlib.suppress(OSError):  # (gone meanwhile; open on Windows)
                    if PARTIAL_FILE.fullmatch(entry.name) and entry.is_file() \
                            and entry.stat().st_mtime < stale:
                        entry.unlink()
        yield
    finally:
        # the file unlinked while still held: a process that opens the name now makes a
        # new lock of its own (released first, one could lock the file being unlinked);
        # Windows refuses, and filelock deletes it on release there
        empty = made and {e.name for e in folder.iterdir()} <= {LOCK_FILE}
        if empty:
            with contextlib.suppress(OSError):
                (folder / LOCK_FILE).unlink()
        lock.release()
        if empty:
            with contextlib.suppress(OSError):  # (one not empty: the rest are kept too)
                for made_here in missing:
                    made_here.rmdir()


#: A partial file (:func:`save_whole`) untouched this long is a killed writer's, which
#: :func:`folder_lock` deletes: no save here takes minutes, and a command that takes no
#: lock (a comparison written after a benchmark, a modes chart into the same folder)
#: may be writing a fresh one.
STALE_PARTIAL_S = 600.0


def check_folder_free(folder: Path, what: str) -> None:
    """:class:`FolderInUse` if another process holds ``folder`` (:func:`folder_lock`),
    for a command that checks the folder's contents before it takes the lock: a second
    ``train`` of a run still training was told first to --resume it."""
    if folder.is_dir():
        with folder_lock(folder, what):
            pass


def held_by_another(folder: Path) -> bool:
    """Whether another process holds ``folder`` (:func:`folder_lock`: a training run holds
    its folder while it trains), probed without its side effects: no lock file made, no
    partial files tidied."""
    from filelock import FileLock, Timeout

    if not (folder / LOCK_FILE).exists():
        return False
    lock = FileLock(folder / LOCK_FILE)
    try:
        lock.acquire(timeout=0)
    except Timeout:
        return True
    except OSError:  # a folder this process cannot write: nothing known, nothing said
        return False
    lock.release()
    return False


#: Windows refuses to rename over a file another program holds open (a benchmark.csv
#: open in a spreadsheet, a picture in a viewer; a virus scanner's look lasts a moment):
#: the rename is tried this many times, ``RENAME_WAIT`` seconds apart, then refused by name.
RENAME_TRIES = 5
RENAME_WAIT = 0.2


def _replace(partial: Path, path: Path) -> None:
    for attempt in range(RENAME_TRIES):
        try:
            partial.replace(path)
            return
        except PermissionError as err:
            if sys.platform != "win32":  # (a sticky folder of another user, an immutable file:
                raise  # lasting, and not a program's hold)
            if attempt == RENAME_TRIES - 1:
                raise PermissionError(
                    f"{path}: cannot be replaced ({err.strerror or err}); a program that "
                    "holds it open (a spreadsheet, a viewer) stops it on Windows: close "
                    "it and run again") from err
            time.sleep(RENAME_WAIT)
