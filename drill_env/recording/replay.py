"""Opening a recording in the rerun viewer, and reading one back (tests, tools)."""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import subprocess
import sys
import threading
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from drill_env.recording.writer import TIMELINE

#: Environment variable naming the viewer executable (default: rerun-sdk's ``rerun``).
VIEWER_VARIABLE = "DRILL_ENV_RERUN"


#: The web viewer's HTTP port when none is asked for (rerun's own default).
WEB_VIEWER_PORT = 9090
#: The address the viewer's servers listen on when none is asked for (the web viewer's
#: HTTP server and, native or web, its data server): this machine only (rerun's own
#: default, all interfaces, served the recording to anyone on the network, the native
#: viewer's data server too; from another machine, forward the ports over ssh or pass
#: ``0.0.0.0``).
WEB_BIND = "127.0.0.1"


def replay_command(path: str | os.PathLike | Sequence[str | os.PathLike], web: bool = False,
                   web_viewer_port: int | None = None, bind: str = WEB_BIND) -> list[str]:
    """The command line that opens ``path`` (one recording or several) in the rerun viewer
    (see :func:`replay`). The viewer's data server takes a free port where another viewer
    holds rerun's (``--port auto``): a second replay opens, not a blank page. The
    viewer's servers listen on ``bind``."""
    exe = os.environ.get(VIEWER_VARIABLE) or shutil.which(
        "rerun", path=str(Path(sys.executable).parent)) or shutil.which("rerun")
    cmd = [exe] if exe else [sys.executable, "-m", "rerun"]
    cmd += ["--port", "auto", "--bind", bind]
    if web:
        cmd += ["--web-viewer"]
        if web_viewer_port is not None:
            cmd += ["--web-viewer-port", str(int(web_viewer_port))]
    cmd += [str(p) for p in _paths(path)]
    return cmd


def _paths(path: str | os.PathLike | Sequence[str | os.PathLike]) -> list[Path]:
    return [Path(path)] if isinstance(path, (str, os.PathLike)) else [Path(p) for p in path]


def port_free(port: int, bind: str = "0.0.0.0") -> bool:
    """Whether a server could listen on ``port`` at address ``bind`` here (all
    interfaces by default; with address reuse as servers set it: a port a closed viewer
    left in TIME_WAIT is free). Raises ``PermissionError`` for a port this user may not
    open (below 1024)."""
    import socket

    family = socket.AF_INET6 if ":" in bind else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as probe:
        if os.name != "nt":  # (on Windows it lets a probe bind a port someone listens on)
            probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            probe.bind((bind, port))
        except PermissionError:
            raise
        except OSError:
            return False
    return True


def web_port(asked: int | None, bind: str = WEB_BIND) -> int:
    """The web viewer's port at address ``bind``: ``asked`` if free (else a ValueError
    naming it), else :data:`WEB_VIEWER_PORT` if free, else 0 (rerun picks a free one and
    prints it)."""
    if asked is not None:
        if not 1 <= asked <= 65535:
            raise ValueError(f"web_viewer_port: {asked} is not a port (1-65535)")
        try:
            free = port_free(asked, bind)
        except PermissionError:
            raise ValueError(f"web_viewer_port: {asked} needs privileges here (ports below "
                             "1024); give one above") from None
        if not free:
            raise ValueError(f"web_viewer_port: {asked} is in use (another viewer still "
                             "running?); give another port, or none for a free one")
        return asked
    return WEB_VIEWER_PORT if port_free(WEB_VIEWER_PORT, bind) else 0


def no_display() -> bool:
    """Whether rerun's native viewer has no display to open on here (Linux without
    DISPLAY or WAYLAND_DISPLAY: rerun fails with a winit error). A viewer of one's own
    (:data:`VIEWER_VARIABLE`) may need none: False."""
    return sys.platform.startswith("linux") and not (
        os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
        or os.environ.get(VIEWER_VARIABLE))


def check_bind(bind: str) -> None:
    """ValueError naming ``bind`` unless it is an IP address of this machine (or all of
    them: ``0.0.0.0``, ``::``), which the viewer's servers can listen on."""
    import ipaddress

    try:
        ipaddress.ip_address(bind)
    except ValueError:
        raise ValueError(f"bind: {bind!r} is not an IP address (127.0.0.1: this machine "
                         "only; 0.0.0.0 or ::, every interface)") from None
    if not port_free(0, bind):  # any free port: fails only for an address not here
        raise ValueError(f"bind: {bind} is not an address of this machine (127.0.0.1: "
                         "this machine only; 0.0.0.0 or ::, every interface)")


def check_recording(path: str | os.PathLike) -> str | None:
    """Read ``path`` through with rerun's reader, as the viewer will. A file the viewer
    would show as an empty page (rerun's format of another version, too short to hold a
    recording, no recording in it) is a ValueError naming it. A file rerun cannot read
    to its end (cut short: a copy or a disk that ran out) returns a warning: the viewer
    shows what it can. None: the whole file reads."""
    import warnings

    import rerun
    from rerun.chunk import RrdReader

    try:
        with warnings.catch_warnings():  # "no footer": a file cut short is scanned whole
            warnings.simplefilter("ignore")
            reader = RrdReader(str(path))
            stores = reader.recordings()
            if stores:
                for _ in reader.stream(store=stores[0]):
                    pass
    except RuntimeError as err:  # rerun's "Failed to read RRD file at <path>: <why>"
        why = str(err).partition(f"{path}: ")[2] or str(err)
        # (a header of rerun's magic bytes over garbage: "Invalid encoding options"; the
        # viewer started on an empty page)
        if "incompatible" in why or "too small" in why or "encoding options" in why:
            raise ValueError(f"path: {path} cannot be opened by rerun {rerun.__version__}: "
                             f"{why}") from None
        return (f"{path}: rerun cannot read it to its end ({why}): cut short? The viewer "
                "shows what it can read")
    if not stores:
        raise ValueError(f"path: {path} holds no recording")
    return None


def stop_viewer(proc: subprocess.Popen, timeout: float = 5.0) -> int:
    """Stop the viewer and every process it started (its process group): SIGTERM, then
    SIGKILL after ``timeout`` seconds. Returns its exit code. On Windows, which has
    neither nor process groups of that kind, ``taskkill /T /F`` ends the viewer's tree:
    ``rerun.exe`` is a launcher whose child is the viewer, which ``terminate`` alone left
    running (a review)."""
    if not hasattr(os, "killpg"):  # Windows
        with contextlib.suppress(OSError):  # (no taskkill: the viewer alone, below)
            subprocess.run(["taskkill", "/PID", str(proc.pid), "/T", "/F"],
                           capture_output=True, check=False)
        if proc.poll() is None:
            proc.kill()
        return proc.wait()
    for sig in (signal.SIGTERM, signal.SIGKILL):
        try:
            os.killpg(proc.pid, sig)
        except ProcessLookupError:
            break
        try:
            return proc.wait(timeout)
        except subprocess.TimeoutExpired:
            continue
    return proc.wait()


def viewer_env() -> dict[str, str]:
    """The viewer's environment: ours, with ``NO_COLOR=1`` where our stderr, which the
    viewer writes its log lines to, is not a terminal (a log file read the colour codes of
    rerun's lines as text: ``^[[2m2026-...^[[0m ^[[32m INFO``). A NO_COLOR of one's own
    is kept; an empty one is as none (no-color.org's rule, which rerun follows)."""
    env = dict(os.environ)
    if not (sys.stderr is not None and sys.stderr.isatty()) and not env.get("NO_COLOR"):
        env["NO_COLOR"] = "1"
    return env


def replay(path: str | os.PathLike | Sequence[str | os.PathLike], web: bool = False, *,
           web_viewer_port: int | None = None, bind: str = WEB_BIND,
           wait: bool = True) -> int | subprocess.Popen:
    """Open a recording, or several (the viewer's recordings panel switches between
    them), in the rerun viewer (the ``rerun`` binary shipped with rerun-sdk).

    ``web=True`` serves the web viewer over HTTP instead (``rerun --web-viewer``; port
    ``web_viewer_port``, else 9090, else a free one: :func:`web_port`; on address
    ``bind``, this machine only unless given: :data:`WEB_BIND`, where the native viewer's
    data server listens too) and opens a browser if
    there is one. rerun 0.41's web server keeps one core busy while it runs, a browser
    attached or not: stop it when done. Blocks until the viewer exits and returns its exit code;
    ``wait=False`` returns the process. The
    viewer runs in its own process group: Ctrl-C or SIGTERM stops it and its servers
    (nothing is left holding the ports), then raises on in the caller as
    ``KeyboardInterrupt`` (SIGTERM: :class:`drill_env.sweep.Terminated`, a subclass), so a
    command line exits 130 or 143. Needs a display (native) or a browser (web).
    """
    paths = _paths(path)
    for p in paths:
        if not p.is_file():
            raise FileNotFoundError(f"path: no recording at {p}")
    if not paths:
        raise ValueError("path: no recording given")
    if not web and no_display():  # (rerun's own error, a winit EventLoopError, and 1)
        raise ValueError("web: no display here (DISPLAY is not set) for the native "
                         "viewer; web=True serves the web viewer instead")
    check_bind(bind)
    port = web_port(web_viewer_port, bind) if web else None
    command = replay_command(paths, web, port, bind)
    if not wait:
        return subprocess.Popen(command, start_new_session=True, env=viewer_env())

    from drill_env.sweep import Terminated

    def terminate(signum: int, frame: object) -> None:
        raise Terminated

    # only the main thread may set a handler: elsewhere SIGTERM is the main thread's,
    # and the viewer is stopped below whatever ends the wait. Set before the viewer
    # starts: a SIGTERM between the two left the viewer running with no one to stop it
    main = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGTERM, terminate) if main else None
    proc = None
    try:
        proc = subprocess.Popen(command, start_new_session=True, env=viewer_env())
        return proc.wait()
    except KeyboardInterrupt:
        if proc is not None:
            stop_viewer(proc)
        raise
    finally:
        if main:
            signal.signal(signal.SIGTERM, previous)
        if proc is not None and proc.poll() is None:
            stop_viewer(proc)


# --------------------------------------------------------------------------- reading back


@dataclass
class RecordingContents:
    """What :func:`read_recording` found in a ``.rrd`` file."""

    application_id: str
    recording_id: str
    #: Every entity path (leading ``/``) with at least one chunk.
    entities: set[str]
    #: Scalar series: entity -> (sim_time in s, values), sorted by time.
    scalars: dict[str, tuple[np.ndarray, np.ndarray]]
    #: Text log lines: entity -> list of (sim_time s, level, text), sorted by time.
    text_logs: dict[str, list[tuple[float, str, str]]]
    #: Number of blueprint stores in the file.
    n_blueprints: int
    #: ``config/episode``'s fields as last written (scenario, seed, state, the
    #: ``drill_env_version`` and ``drill_env_sources`` digest of the code that wrote it).
    episode: dict[str, Any]


class EntityDict(dict):
    """A dict keyed by entity path; a path typed without its leading ``/`` (as the docs'
    tables list them) is a KeyError that names the key to use."""

    def __missing__(self, key: Any) -> Any:
        if isinstance(key, str) and "/" + key in self:
            raise KeyError(f"{key!r}; entity paths start with '/': {'/' + key!r}")
        raise KeyError(key)


def _first(cell: list | None, empty: Any) -> Any:
    """The one value of a rerun component cell (a list), ``empty`` for an empty cell."""
    return cell[0] if cell else empty


def read_recording(path: str | os.PathLike) -> RecordingContents:
    """Read a recording back with rerun's own reader (``rerun.chunk.RrdReader``).
    ValueError naming the file where it cannot be read to its end (cut short, or still
    being written): rerun's bare RuntimeError stopped a loop over a folder."""
    try:
        return _read_recording(path)
    except RuntimeError as err:
        raise ValueError(f"path: {path} cannot be read to its end ({err}); "
                         "check_recording(path) says what the viewer can show") from None


def _read_recording(path: str | os.PathLike) -> RecordingContents:
    """:func:`read_recording` but rerun's errors."""
    import pyarrow as pa
    from rerun.chunk import RrdReader

    reader = RrdReader(str(path))
    stores = reader.recordings()
    if not stores:
        raise ValueError(f"path: {path} holds no recording")
    entry = stores[0]
    entities: set[str] = set()
    raw: dict[str, list[tuple[np.ndarray, np.ndarray]]] = {}
    logs: dict[str, list[tuple[float, str, str]]] = {}
    episode: dict[str, Any] = {}
    for chunk in reader.stream(store=entry):
        entity = chunk.entity_path
        entities.add(entity)
        batch = chunk.to_record_batch()
        names = batch.schema.names
        if entity == "/config/episode":  # static: the last chunk is what the viewer shows
            episode = {name: _first(batch.column(name).to_pylist()[-1], None)
                       for name in names if not name.startswith("rerun.")}
        if TIMELINE not in names:
            continue
        times = batch.column(TIMELINE).cast(pa.int64()).to_numpy(
            zero_copy_only=False).astype(np.float64) * 1e-9
        if "Scalars:scalars" in names:
            col = batch.column("Scalars:scalars")
            values = np.array([_first(cell, np.nan) for cell in col.to_pylist()],
                              dtype=np.float64)
            raw.setdefault(entity, []).append((times, values))
        if "TextLog:text" in names:
            texts = [_first(cell, "") for cell in batch.column("TextLog:text").to_pylist()]
            levels = (["" for _ in texts] if "TextLog:level" not in names else
                      [_first(cell, "") for cell in
                       batch.column("TextLog:level").to_pylist()])
            logs.setdefault(entity, []).extend(zip(times.tolist(), levels, texts, strict=True))
    scalars = EntityDict()
    for entity, parts in raw.items():
        tt = np.concatenate([times for times, _ in parts])
        vv = np.concatenate([values for _, values in parts])
        order = np.argsort(tt, kind="stable")
        scalars[entity] = (tt[order], vv[order])
    for lines in logs.values():
        lines.sort(key=lambda e: e[0])
    if episode:  # rerun drops the empty string written for "no controller": as written
        episode["controller"] = episode.get("controller") or ""
        episode["env_id"] = episode.get("env_id") or ""  # (older files: none written)
    return RecordingContents(entry.application_id, entry.recording_id, entities, scalars,
                             EntityDict(logs), len(reader.blueprints()), episode)
