"""Progress bars of long work in a log or a pipe (drill_env.progress): one plain line per
interval, not tqdm's carriage-return frames on one line (an outside trial: a benchmark's
log held its frames with the table glued after them)."""

from __future__ import annotations

import io
import sys
import types

import drill_env.progress as progress


class _Log(io.StringIO):
    """A file: no terminal."""


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def _count(bar, n: int, clock: list[float]) -> None:
    for _ in range(n):
        clock[0] += 1.0  # one second per item
        bar.update(1)


def _fake_clock(monkeypatch) -> list[float]:
    clock = [0.0]
    # the clock tqdm's bars take at their start (tqdm.std's time): time without sleeping
    monkeypatch.setattr("tqdm.std.time", lambda: clock[0])
    return clock


def test_a_log_gets_a_line_per_interval_and_the_last_count(monkeypatch):
    clock = _fake_clock(monkeypatch)
    monkeypatch.setattr(progress, "LOG_INTERVAL", 10.0)
    log = _Log()
    bar = progress.progress_bar(total=35, desc="benchmark", unit="episode", file=log)
    _count(bar, 35, clock)
    bar.close()
    text = log.getvalue()
    assert "\r" not in text
    lines = text.splitlines()
    # 35 s of work: a line at 10, 20 and 30 s, the last count at the end, none repeated
    assert [line.split("|")[0].strip() for line in lines] == [
        "benchmark:  29%", "benchmark:  57%", "benchmark:  86%", "benchmark: 100%"]
    assert lines[-1].split("|")[2].startswith(" 35/35")
    assert text.isascii() and len(set(lines)) == len(lines)


def test_a_short_job_writes_nothing_to_a_log_and_a_bar_not_kept_no_blank_line(monkeypatch):
    clock = _fake_clock(monkeypatch)
    monkeypatch.setattr(progress, "LOG_INTERVAL", 10.0)
    log = _Log()
    with progress.progress_bar(total=5, desc="short", file=log) as bar:
        _count(bar, 5, clock)
    assert log.getvalue() == ""
    with progress.progress_bar(total=30, desc="gone", leave=False, file=log) as bar:
        _count(bar, 30, clock)
    # lines at 10, 20 and 30 s; the bar, not kept, then clears its line: no blank line
    assert [line.split("|")[0] for line in log.getvalue().splitlines()] == [
        "gone:  33%", "gone:  67%", "gone: 100%"]
    assert log.getvalue().endswith("]\n")


def test_items_slower_than_the_interval_get_a_line_each_in_a_log(monkeypatch):
    """The module's docstring: a line at an item's end, at most one an interval; items
    slower than that get a line each, also after quicker ones (tqdm spaced them by the
    quick items' count: a mutation test of its maxinterval)."""
    clock = _fake_clock(monkeypatch)
    monkeypatch.setattr(progress, "LOG_INTERVAL", 10.0)
    log = _Log()
    with progress.progress_bar(total=50, desc="slower", file=log) as bar:
        _count(bar, 30, clock)  # 1 s an item
        for _ in range(20):
            clock[0] += 15.0  # then 15 s an item, longer than the interval
            bar.update(1)
    counts = [int(line.split("|")[2].split("/")[0]) for line in log.getvalue().splitlines()]
    assert len(counts) == len(set(counts))  # the close does not repeat the last count
    slow = [n for n in counts if n > 30]
    # once the bar has caught up with the slower pace, every item to the end has its line
    assert len(slow) >= 5 and slow == list(range(slow[0], 51))


def test_a_kept_bar_closing_on_a_count_already_said_says_it_once(monkeypatch):
    """A kept bar's close redraws its last count with a later time and rate: in a log it
    was printed twice, once per frame (a mutation round's side note)."""
    clock = _fake_clock(monkeypatch)
    monkeypatch.setattr(progress, "LOG_INTERVAL", 10.0)
    log = _Log()
    with progress.progress_bar(total=20, desc="even", file=log) as bar:
        _count(bar, 20, clock)  # a line at 10 s and at 20 s, the last item's
        clock[0] += 5.0  # the close, 5 s later
    lines = log.getvalue().splitlines()
    assert [line.split("|")[2].split(" [")[0] for line in lines] == [" 10/20", " 20/20"]


def test_a_bar_reset_in_a_log_draws_nothing_ahead_of_its_interval(monkeypatch):
    """tqdm draws its bar at a reset: `drill-env run | cat` (reset after the compiling
    first step) kept a "0%" line above the summary. A reset bar counts as before."""
    clock = _fake_clock(monkeypatch)
    monkeypatch.setattr(progress, "LOG_INTERVAL", 10.0)
    log = _Log()
    with progress.progress_bar(total=30, desc="run", leave=False, file=log) as bar:
        _count(bar, 1, clock)
        bar.reset()
        assert (log.getvalue(), bar.n) == ("", 0)
        _count(bar, 5, clock)
    assert log.getvalue() == ""
    with progress.progress_bar(total=30, desc="run", file=log) as bar:
        bar.reset()
        _count(bar, 30, clock)
    assert [line.split("|")[0] for line in log.getvalue().splitlines()] == [
        "run:  33%", "run:  67%", "run: 100%"]


def test_a_terminal_keeps_tqdms_redrawn_line(monkeypatch):
    clock = _fake_clock(monkeypatch)
    term = _Terminal()
    with progress.progress_bar(total=3, desc="bench", file=term) as bar:
        _count(bar, 3, clock)
    assert "\r" in term.getvalue()
    off = _Log()
    with progress.progress_bar(total=3, file=off, disable=True) as bar:
        _count(bar, 3, clock)
    assert off.getvalue() == ""


def test_a_closed_or_replaced_stream_is_no_terminal(monkeypatch):
    """drill_env.progress.is_terminal: False for closed streams and streams without
    ``isatty`` (its docstring), so a bar there writes plain lines, no carriage return."""
    clock = _fake_clock(monkeypatch)
    monkeypatch.setattr(progress, "LOG_INTERVAL", 10.0)
    closed = _Log()
    closed.close()  # isatty() of a closed stream: ValueError

    class Replaced:  # a stream of one's own: write and flush only
        def __init__(self) -> None:
            self.text = ""

        def write(self, text: str) -> int:
            self.text += text
            return len(text)

        def flush(self) -> None:
            pass

    replaced = Replaced()
    assert not progress.is_terminal(closed) and not progress.is_terminal(replaced)
    with progress.progress_bar(total=30, desc="own", file=replaced) as bar:
        _count(bar, 30, clock)
    assert "\r" not in replaced.text and replaced.text.count("\n") == 3


class _Shell:
    def __init__(self, config: dict) -> None:
        self.config = config


def test_a_notebooks_cell_keeps_tqdms_bar_and_a_file_given_there_gets_lines(monkeypatch):
    """In a Jupyter kernel stderr is no terminal, but its cell redraws a carriage return
    in place: the bar stays tqdm's. A file given there is still a file; and IPython
    imported without a kernel (a script, the terminal shell) is no notebook."""
    clock = _fake_clock(monkeypatch)
    monkeypatch.setattr(progress, "LOG_INTERVAL", 10.0)
    fake = types.ModuleType("IPython")
    fake.get_ipython = lambda: _Shell({"IPKernelApp": {}})
    monkeypatch.setitem(sys.modules, "IPython", fake)
    assert progress.in_notebook()
    cell = _Log()
    monkeypatch.setattr(sys, "stderr", cell)
    with progress.progress_bar(total=3, desc="cell") as bar:
        _count(bar, 3, clock)
    assert "\r" in cell.getvalue()
    log = _Log()
    with progress.progress_bar(total=30, desc="file", file=log) as bar:
        _count(bar, 30, clock)
    assert "\r" not in log.getvalue() and log.getvalue().count("\n") == 3
    for shell in (lambda: _Shell({"TerminalIPythonApp": {}}), lambda: None):
        fake.get_ipython = shell
        assert not progress.in_notebook()
