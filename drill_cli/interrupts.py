"""Ctrl-C and SIGTERM: a command stops, keeps its finished work and exits with the shell's
status for the signal (130, 143)."""

from __future__ import annotations

import argparse
import signal
import threading
from pathlib import Path
from typing import Any

from drill_cli.studies import MAP_POINTS_FILE
from drill_cli.train import default_evaluation_folder
from drill_env.sweep import (
    Terminated,
    note_interrupt,
)

NOT_INSTALLED = object()
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


def exit_status(stopped: KeyboardInterrupt) -> int:
    """The shell's status of a command stopped by a signal, 128 + its number: 143 after
    SIGTERM, 130 after Ctrl-C (SIGINT)."""
    return 128 + (signal.SIGTERM if isinstance(stopped, Terminated) else signal.SIGINT)


def stop_as_interrupt() -> tuple[Any, threading.Event]:
    """SIGTERM (``kill``, a scheduler's stop) handled as Ctrl-C for the command's duration:
    what is done is kept and a sweep's workers are stopped (it ended this process at once,
    its workers left running). Returns the previous handler (``NOT_INSTALLED`` off the
    main thread, where none can be set) and an event the handler sets: what stopped the
    command also where its :class:`Terminated` was replaced on the way up (Ray's wait
    raises a KeyboardInterrupt of its own)."""
    terminated = threading.Event()
    if threading.current_thread() is not threading.main_thread():
        return NOT_INSTALLED, terminated

    def interrupt(signum: int, frame: Any) -> None:
        note_interrupt(Terminated)  # kept also where the raise is lost (training checks it)
        terminated.set()
        raise Terminated

    return signal.signal(signal.SIGTERM, interrupt), terminated
