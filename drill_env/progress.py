"""Progress bars for long work (a benchmark, a stability map, a sweep of training seeds):
tqdm's bar on a terminal and in a notebook, and plain lines, at most one every
:data:`LOG_INTERVAL` seconds, where the output is a log or a pipe.

tqdm redraws its line with carriage returns, which a terminal and a notebook overwrite in
place; a file keeps every frame, so a benchmark's log held hundreds of frames on one line
with the table glued after them (an outside trial). In a log a job shorter than
:data:`LOG_INTERVAL` prints nothing; a longer one a line of its count, rate and time left
as work progresses (at an item's end, at most one a minute: items slower than that get a
line each), and its last count at the end where the bar is kept (``leave``).
"""

from __future__ import annotations

import sys
from typing import IO, Any

#: Seconds between two lines of a bar written to a log or a pipe (and before its first):
#: a line a minute is ~60 lines an hour of a sweep, few enough to read past.
LOG_INTERVAL = 60.0


class _Lines:
    """A stream for tqdm that writes each of its frames as one line: the carriage returns
    dropped, the blanks that clear a line skipped, and a frame of the count the last line
    gave skipped too (a kept bar's close redraws its last count, with a later time and
    rate: the count printed twice)."""

    def __init__(self, stream: IO[str]) -> None:
        self.stream = stream
        self.last = ""

    def write(self, text: str) -> int:
        line = text.replace("\r", "").rstrip()
        count = line.rsplit(" [", 1)[0]  # (the bar and count, without "[time, rate]")
        if line and count != self.last:
            self.stream.write(line + "\n")
            self.last = count
        return len(text)

    def flush(self) -> None:
        self.stream.flush()


def in_notebook() -> bool:
    """Whether this process is a Jupyter kernel (its output renders a carriage return in
    place, as a terminal does, though its streams are no terminal)."""
    shell = sys.modules.get("IPython")
    get = getattr(shell, "get_ipython", None)
    try:
        return get is not None and "IPKernelApp" in get().config
    except Exception:  # noqa: BLE001 - no IPython shell at all: not a kernel
        return False


def is_terminal(stream: IO[str]) -> bool:
    """Whether ``stream`` is an interactive terminal (False for files, pipes and closed
    or replaced streams without ``isatty``)."""
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError, OSError):
        return False


def progress_bar(*, file: IO[str] | None = None, disable: bool = False,
                 **kwargs: Any) -> Any:
    """A ``tqdm`` bar with ``kwargs`` (total, desc, unit, initial, leave, delay, ...) on ``file``
    (stderr by default): as given on a terminal or in a notebook; to a log or a pipe, one
    plain ASCII line at most every :data:`LOG_INTERVAL` seconds, none for a job shorter
    than that."""
    from tqdm import tqdm

    stream = sys.stderr if file is None else file
    shown = stream in (sys.stdout, sys.stderr) and in_notebook()  # (a kernel's cell)
    if disable or is_terminal(stream) or shown:
        return tqdm(file=stream, disable=disable, **kwargs)

    class LogBar(tqdm):
        """tqdm draws the bar at a reset: in a log a 0 % line, ahead of its delay (the
        run command resets after the first step's compile: `run | cat` kept it)."""

        resetting = False

        def reset(self, total: Any = None) -> None:
            self.resetting = True
            try:
                super().reset(total)
            finally:
                self.resetting = False

        def refresh(self, *args: Any, **kwargs: Any) -> Any:
            return None if self.resetting else super().refresh(*args, **kwargs)

    return LogBar(file=_Lines(stream), mininterval=LOG_INTERVAL, maxinterval=LOG_INTERVAL,
                  delay=max(LOG_INTERVAL, kwargs.pop("delay", 0.0)),
                  ascii=True, dynamic_ncols=False, **kwargs)
