"""Command line: ``drill-env <command>`` (or ``python -m drill_cli <command>``).

The top layer: it parses arguments in the units people type (rpm, kN, seconds), checks
them in those units, and calls the libraries below (``drill_env``, ``agents``,
``training``), which work in SI. Every command but ``replay`` prints a table and writes
its outputs under ``--out`` (default ``logs/``; ``benchmark`` ``logs/benchmark``, with
``--task`` ``logs/benchmark/<task>``, with ``--config FILE`` a folder ``config-<stem>``
inside that, ``train`` ``logs/runs``, ``evaluate`` the run's ``evaluation/``).
"""

from __future__ import annotations

import argparse
import contextlib
import os
import signal
import sys
import time
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from drill_cli.arguments import unwritable
from drill_cli.installation import compile_notice, shadowed_packages
from drill_cli.interrupts import (
    KEEPS_FINISHED,
    HungUp,
    exit_status,
    finished_since,
    finished_work_folder,
    results_file,
    stop_as_interrupt,
)
from drill_cli.parser import option_hint, option_of, parser
from drill_env.sweep import (
    Terminated,
    clear_interrupt,
    hear_interrupts,
)


def main(argv: Sequence[str] | None = None) -> int:
    """The ``drill-env`` command; returns its exit status."""
    for stream in (sys.stdout, sys.stderr):
        tolerant_output(stream)
    try:
        return _main(argv)
    except RuntimeError as err:  # no folder numba may keep the kernels in: one line, not
        # a traceback from the first import of a kernel (`--help` too)
        if not str(err).startswith("drill_env: no writable folder"):
            raise
        print(f"drill-env: error: {str(err).removeprefix('drill_env: ')}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as caught:  # before the command ran (building the parser:
        # imports), a Ctrl-C printed a traceback of dozens of lines (an outside check)
        said = "terminated" if isinstance(caught, Terminated) else "interrupted"
        print(f"drill-env: {said}", file=sys.stderr)
        return exit_status(caught)


def tolerant_output(stream: Any) -> None:
    """A stream whose encoding cannot write every character (any but UTF's: ASCII under
    ``LC_ALL=C`` without Python's UTF-8 mode or ``PYTHONIOENCODING=ascii``, Latin-1,
    cp1252) writes the ones it cannot as ``\\u2020``. A table's dagger or a path with an
    umlaut ended demo, benchmark, evaluate and run with an encoding error after their
    work, reported as a bad value (exit 2), before benchmark.md was written (an outside
    check)."""
    import codecs

    encoding = getattr(stream, "encoding", None)
    if not encoding or not hasattr(stream, "reconfigure"):
        return
    try:  # any encoding but Unicode's lacks some character (cp1252 has the dagger and
        # the umlaut, not a Polish or Chinese letter a path may hold: a review)
        unicode = codecs.lookup(encoding).name.startswith("utf")
    except LookupError:
        unicode = False
    if not unicode:
        stream.reconfigure(errors="backslashreplace")


def _joined_values(argv: Sequence[str]) -> list[str]:
    """``--seeds -1,2`` as ``--seeds=-1,2``: argparse reads a value that starts with '-'
    and is not a plain number as an option, and said "expected one argument" (a
    negative list or 1e3 refused without naming what was wrong); no option of ours
    starts with '-' and a digit, so the value is the option's, judged by its checks."""
    out: list[str] = []
    for token in argv:
        if out and token[:1] == "-" and token[1:2].isdigit() and \
                out[-1].startswith("--") and "=" not in out[-1]:
            out[-1] = f"{out[-1]}={token}"
        else:
            out.append(token)
    return out


def _main(argv: Sequence[str] | None) -> int:
    top = parser()
    argv = _joined_values(sys.argv[1:] if argv is None else argv)
    if not argv:  # no command: what the commands are
        top.print_help()
        return 2
    args, extra = top.parse_known_args(argv)
    if extra:  # said by the command's parser (argparse's own said the top usage)
        args.command_parser.error(f"unrecognized arguments: {' '.join(extra)}"
                                  + option_hint(extra[0], args.command_parser))
    out = getattr(args, "out", None)
    if out is not None and (reason := unwritable(out)):  # before the work: found after an
        args.command_parser.error(f"--out {out}: {reason}")  # hour's work, it lost the hour
    if getattr(args, "ray_address", None) is not None and getattr(args, "workers", None):
        args.command_parser.error("--workers: the local processes; with --ray-address the "
                                  "cluster's CPUs run the work: give one of the two")
    import tempfile

    try:  # where the commands' processes mark the warnings said
        marks = tempfile.TemporaryDirectory(prefix="drill-env-warnings-")
    except OSError as err:  # (a traceback of tempfile's; an outside check)
        print(f"drill-env {args.command}: error: no writable temporary folder ({err}); "
              "set TMPDIR to a folder you can write", file=sys.stderr)
        return 2
    started = time.time()  # (what its results file holds from before is not its work)
    restore_handlers, stopped_by = stop_as_interrupt()
    heard = False
    clear_interrupt()  # one noted before this command is not this command's
    from drill_env.sweep import COMMAND_VARIABLE, SAID_VARIABLE, command_warning

    shown, named = warnings.formatwarning, os.environ.get(COMMAND_VARIABLE)
    outer = os.environ.get(SAID_VARIABLE)  # a command run inside another (tests)
    warnings.formatwarning = command_warning(args.command, marks.name)
    # a sweep's pool workers (spawned) say their warnings the same way, and once in all
    os.environ[COMMAND_VARIABLE] = args.command
    os.environ[SAID_VARIABLE] = marks.name
    try:
        heard = hear_interrupts()  # (a script's background job: kill -INT stops it)
        with compile_notice(args.command) as args.compiled:
            return int(args.func(args))
    except ImportError as err:  # our agents or training package hidden by the user's
        if not (shadowed := shadowed_packages()):
            raise
        print(f"drill-env {args.command}: error: {err}: {'; '.join(shadowed)} (drill-env's "
              f"own lie in {Path(__file__).resolve().parent.parent}): a module or folder of "
              "that name in the working folder or on PYTHONPATH hides it; run from another "
              "folder or rename yours", file=sys.stderr)
        return 2
    except BrokenPipeError:  # the reader went away (`drill-env modes | head`): stop quietly
        sys.stderr.close()  # nothing more can be said on a closed pipe
        return 0
    except argparse.ArgumentTypeError as err:  # a bad argument found after parsing:
        # said as argparse says its own (the command's usage, then the error)
        args.command_parser.error(str(err))
    except (ValueError, OSError) as err:  # a bad value named by the library below
        field, colon, rest = str(err).partition(": ")  # by the option the user typed
        # an error led by a path the user typed is that file's or folder's (a folder in
        # use given as --out seeds was said as --seeds)
        typed = {str(v) for v in vars(args).values() if isinstance(v, Path)}
        option = option_of(field, args.command_parser) \
            if colon and field not in typed else None
        said = f"{option}: {rest}" if option else str(err)
        print(f"drill-env {args.command}: error: {said}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as caught:
        # a SIGTERM's Terminated may come back as a plain KeyboardInterrupt (Ray's wait
        # turns a signal's exception into its own)
        stopped = stopped_by[0]() if stopped_by else caught
        said = "its terminal closed (SIGHUP)" if isinstance(stopped, HungUp) else \
            "terminated" if isinstance(stopped, Terminated) else "interrupted"
        kept = finished_work_folder(args, out)
        if args.command in KEEPS_FINISHED and kept is not None and finished_since(
                results_file(args.command, kept), started):  # (none finished: it said so
            # all the same)
            said += (f"; its finished {KEEPS_FINISHED[args.command]} are kept in {kept}: the "
                     "same command again goes on from them")
        with contextlib.suppress(OSError):  # (a closed terminal's: EIO)
            print(f"drill-env {args.command}: {said}", file=sys.stderr)
        return exit_status(stopped)
    finally:
        warnings.formatwarning = shown
        if named is None:
            os.environ.pop(COMMAND_VARIABLE, None)
        else:
            os.environ[COMMAND_VARIABLE] = named
        if outer is None:
            os.environ.pop(SAID_VARIABLE, None)
        else:
            os.environ[SAID_VARIABLE] = outer
        marks.cleanup()
        clear_interrupt()  # handled here: not a later command's (or caller's) to act on
        restore_handlers()
        if heard:
            signal.signal(signal.SIGINT, signal.SIG_IGN)
    return 2


if __name__ == "__main__":  # python -m drill_cli.main, as python -m drill_cli
    sys.exit(main())
