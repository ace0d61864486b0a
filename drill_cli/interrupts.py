"""Ctrl-C, SIGTERM and SIGHUP: a command stops, keeps its finished work and exits with the
shell's status for the signal (130, 143, 129)."""

from __future__ import annotations

import argparse
import os
import signal
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

from drill_cli.studies import MAP_POINTS_FILE
from drill_cli.train import default_evaluation_folder
from drill_env.sweep import (
    Terminated,
    note_interrupt,
)

#: Commands that keep what they finished in their --out as it arrives, and what that is
#: (a rerun with the same settings and code reuses it; `train` says its own checkpoint).
KEEPS_FINISHED = {"benchmark": "episodes", "stability-map": "points", "evaluate": "episodes",
                  "demo": "episodes"}


def finished_work_folder(args: argparse.Namespace, out: Path | None) -> Path | None:
    """Where a stopped command of :data:`KEEPS_FINISHED` keeps its finished work: its
    ``--out``; evaluate's default beside the run; the demo's benchmark folder."""
    if args.command == "evaluate":
        return out or default_evaluation_folder(args.run, args.fidelity)
    if args.command == "demo":
        return None if out is None else out / "benchmark"
    return out


def results_file(command: str, folder: Path) -> Path:
    """The file in ``folder`` where a command of :data:`KEEPS_FINISHED` appends its
    finished episodes or points."""
    if command == "stability-map":
        return folder / MAP_POINTS_FILE
    from agents.benchmark import RESULTS_FILE

    return folder / RESULTS_FILE


def finished_since(path: Path, started: float) -> bool:
    """Whether ``path`` was written since ``started`` (``time.time()``): a result finished
    then."""
    try:
        return path.stat().st_mtime >= started
    except OSError:
        return False


class HungUp(Terminated):
    """A SIGHUP (the terminal closed: an ssh session dropped), handled as SIGTERM is."""


def exit_status(stopped: KeyboardInterrupt) -> int:
    """The shell's status of a command stopped by a signal, 128 + its number: 129 after
    SIGHUP, 143 after SIGTERM, 130 after Ctrl-C (SIGINT)."""
    if isinstance(stopped, HungUp):
        return 128 + signal.SIGHUP
    return 128 + (signal.SIGTERM if isinstance(stopped, Terminated) else signal.SIGINT)


def stop_as_interrupt() -> tuple[Callable[[], None], list[type[Terminated]]]:
    """SIGTERM (``kill``, a scheduler's stop) and SIGHUP (a closed terminal: it ended
    ``train`` at once, its work since the last checkpoint lost) handled as Ctrl-C for the
    command's duration: what is done is kept and a sweep's workers are stopped (SIGTERM
    ended this process at once, its workers left running). A SIGHUP that came ignored
    (``nohup``) stays so. Returns what puts the previous handlers back (nothing to do off
    the main thread, where none can be set) and a list the handlers append their
    exception's class to: what stopped the command also where its :class:`Terminated`
    was replaced on the way up (Ray's wait raises a KeyboardInterrupt of its own)."""
    heard: list[type[Terminated]] = []
    if threading.current_thread() is not threading.main_thread():
        return lambda: None, heard
    kinds: dict[int, type[Terminated]] = {signal.SIGTERM: Terminated}
    if hasattr(signal, "SIGHUP") and signal.getsignal(signal.SIGHUP) is not signal.SIG_IGN:
        kinds[signal.SIGHUP] = HungUp  # (POSIX only)

    def interrupt(signum: int, frame: Any) -> None:
        kind = kinds[signum]
        note_interrupt(kind)  # kept also where the raise is lost (training checks it)
        heard.append(kind)
        if kind is HungUp:
            quiet_closed_terminal()
        raise kind

    previous = {signum: signal.signal(signum, interrupt) for signum in kinds}

    def restore() -> None:
        for signum, handler in previous.items():
            signal.signal(signum, handler if handler is not None else signal.SIG_DFL)

    return restore, heard


def quiet_closed_terminal() -> None:
    """Standard output and error that went to a terminal now closed (writing to it fails
    with EIO) go to the null device instead: what a command prints while it stops (its
    checkpoint's line, its results) failed with an I/O error after the work was saved,
    exit 2 instead of 129. A file or pipe they go to is left as it is."""
    for fd in (1, 2):
        try:
            os.write(fd, b"")  # a hung-up terminal refuses even nothing; others take it
        except OSError:
            null = os.open(os.devnull, os.O_WRONLY)
            os.dup2(null, fd)
            os.close(null)
