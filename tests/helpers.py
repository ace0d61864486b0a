"""Helpers shared by several test modules (importable: ``pythonpath = ["tests"]``)."""

from __future__ import annotations

import contextlib
import signal
from collections.abc import Callable, Iterator

import numpy as np

from drill_env.physics.config import SimulationConfig
from drill_env.physics.trajectory import Survey
from drill_env.physics.units import RPM
from drill_env.scenarios import make_scenario
from drill_env.well import rotating_wall_torque, sliding_friction, with_survey

# --------------------------------------------------------------------------- tolerances


def conditioned(reference: Callable[..., np.ndarray], *arrays: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
    """``reference(*arrays)`` (floats) and the tolerance another implementation of it
    (another summation order, a rolling update) must meet, set by the values'
    conditioning on these inputs: the spread of the reference when every input is
    perturbed by a few eps (means of signed samples, ptp over a mean, ratios of sums lose
    digits to cancellation), times the log2(n) growth of a summation's error in another
    order, plus the round-off of the value itself."""
    value = np.asarray(reference(*arrays), dtype=float)
    rng = np.random.default_rng(0)
    eps = np.finfo(float).eps
    spread = np.zeros_like(value)
    for _ in range(4):
        noisy = [a * (1.0 + 4.0 * eps * rng.standard_normal(np.shape(a))) for a in arrays]
        spread = np.maximum(spread, np.abs(np.asarray(reference(*noisy)) - value))
    n = max(len(a) for a in arrays)
    return value, 10.0 * max(1.0, np.log2(n)) * (spread + 4.0 * eps * np.abs(value))


# --------------------------------------------------------------------------- curved holes

#: Off-bottom rotation speed of the curved-hole torque tests.
SPEED = 60 * RPM


def straight_hole(inclination: float = 60.0) -> tuple[SimulationConfig, Survey]:
    """The default string in a straight hole at ``inclination`` (deg, toward north),
    reaching 100 m below the bit."""
    config = make_scenario("default").config
    length = config.string.length
    survey = Survey.from_stations([0.0, length + 100.0], [inclination] * 2, [0.0, 0.0])
    return with_survey(config, survey), survey


def build_section() -> tuple[SimulationConfig, Survey]:
    """The default string in a shallow build: 3 deg/30 m from 100 m to a 30-degree hold,
    so ~1 km of string hangs below the build."""
    config = make_scenario("default").config
    survey = Survey.profile(config.string.length + 100.0, kickoff=100.0, build_rate=3.0,
                            hold_inclination=30.0)
    return with_survey(config, survey), survey


def rotate_off_bottom(config: SimulationConfig, seconds: float = 10.0, wound: bool = True):
    """Wall torque and simulator of ``config`` turning off bottom at :data:`SPEED`
    (:func:`drill_env.well.rotating_wall_torque`)."""
    return rotating_wall_torque(config, SPEED, seconds, wound=wound)


def pipe_friction(config: SimulationConfig) -> float:
    """The drill pipe's sliding friction coefficient at :data:`SPEED`."""
    return sliding_friction(config, SPEED)


# --------------------------------------------------------------------------- interrupts


def stop_after(n: int):
    """A progress callback that raises KeyboardInterrupt at its ``n``-th call (a user
    pressing Ctrl-C in the middle of a sweep)."""
    calls = []

    def progress() -> None:
        calls.append(1)
        if len(calls) == n:
            raise KeyboardInterrupt

    return progress


def keep_saved_figures(monkeypatch) -> list:
    """The matplotlib figures saved from now on, appended to the returned list as they
    are saved."""
    from matplotlib.figure import Figure

    saved: list = []
    original = Figure.savefig
    monkeypatch.setattr(Figure, "savefig",
                        lambda fig, *a, **kw: (saved.append(fig), original(fig, *a, **kw)))
    return saved


# --------------------------------------------------------------------------- sweeps


def save_on_interrupt(marker: str) -> str:
    """A sweep task that waits for a Ctrl-C, as a training run does, and then "saves"
    (writes ``marker``) while a second Ctrl-C arrives, which must not cut the save short."""
    import os
    import signal
    import time
    from pathlib import Path

    try:
        Path(marker).write_text("started")
        time.sleep(60.0)
    except KeyboardInterrupt:
        Path(marker).write_text("interrupted")
        os.kill(os.getpid(), signal.SIGINT)  # the group's Ctrl-C and the pool's copy
        time.sleep(0.3)
        Path(marker).write_text("saved")
        raise
    return "not interrupted"


def write_pid_and_wait(path: str) -> None:
    """A sweep task that writes its process id to ``path`` and waits a minute."""
    import os
    import time
    from pathlib import Path

    Path(path).write_text(str(os.getpid()))
    time.sleep(60.0)


def sleep_through_interrupts(marker: str) -> None:
    """A sweep task that does not end on a Ctrl-C or SIGTERM (as a worker busy in
    compiled code); writes ``marker`` once it ignores them, then waits a minute."""
    import signal
    import time
    from pathlib import Path

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    Path(marker).write_text("started")
    time.sleep(60.0)


def lose_an_interrupt(marker: str) -> str:
    """A sweep task whose interrupt's exception is lost, as one raised inside numba's
    compile callbacks is (printed as "Exception ignored"): writes ``marker``, waits for
    the interrupt, swallows it, and returns the name of what
    :func:`drill_env.sweep.noted_interrupt` then says, for the task to act on."""
    import time
    from pathlib import Path

    from drill_env.sweep import noted_interrupt

    try:
        Path(marker).write_text("started")
        time.sleep(60.0)
    except KeyboardInterrupt:
        pass
    return getattr(noted_interrupt(), "__name__", "None")


def hang_up_handling(k: int) -> str:
    """A sweep task that says what its worker does with a SIGHUP: "ignored" (SIG_IGN),
    "interrupts" (the first interrupt's handler) or another handler's name."""
    import signal

    from drill_env.sweep import _interrupt_once

    handler = signal.getsignal(signal.SIGHUP)
    return "ignored" if handler is signal.SIG_IGN else \
        "interrupts" if handler is _interrupt_once else str(handler)


def fail_last(k: int) -> int:
    """A sweep task that returns ``k`` at once, except for ``k`` = 3, which fails after
    the others are done (their workers idle when the pool is aborted)."""
    import time

    if k == 3:
        time.sleep(0.5)
        raise ValueError("task 3 failed")
    return k


@contextlib.contextmanager
def ctrl_c_as_in_a_terminal() -> Iterator[None]:
    """Python's own SIGINT handler (KeyboardInterrupt) and SIGHUP's default for the block,
    the previous ones after it: a test run started in the background (``nohup ... &``)
    inherits SIGINT and SIGHUP ignored (POSIX), and there Python never installs its
    handler, nor the command line its SIGHUP one (a nohup it respects)."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    hang_up = signal.signal(signal.SIGHUP, signal.SIG_DFL) if hasattr(signal, "SIGHUP") \
        else None
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
        if hang_up is not None:
            signal.signal(signal.SIGHUP, hang_up)
