"""N drill-string envs stepped together: one parallel compiled call for all their physics.

:func:`step_all` steps a list of :class:`~drill_env.env.DrillStringEnv` in three phases:
every env maps its action to set points (Python), then ONE numba call runs, in parallel
over envs (``prange``, without the GIL), each env's simulator over the control interval,
its readings, and its rolling metric window (:func:`step_many`); then every env computes
its termination, reward, observation and info from those (Python). :func:`step_batch`
(:func:`step_arrays`) does the last phase for all plain ``DrillString-v0`` envs at once,
in one compiled call (:meth:`~drill_env.env.DrillStringEnv.finish_batch`), with the same
values. Each env keeps its own arrays (meshes may differ, as in the randomised scenario)
and runs the same compiled functions as when it steps alone (``Simulator.advance(...,
read=True)`` and ``RollingMetrics.update``), so every env follows bit-for-bit its
single-env trajectory.

The vector envs of :mod:`drill_env.vector` (Gymnasium and Stable-Baselines3) step through
here. Why the metric windows are inside the call: the env's serial Python per step is
what limits the batch on a few cores (docs/performance.md).
"""

from __future__ import annotations

import math
import operator
from collections.abc import Sequence
from enum import IntEnum
from typing import Any, NamedTuple

import numba
import numpy as np
from numba import njit, prange

from drill_env.env import DrillStringEnv
from drill_env.env_batch import BatchInfo
from drill_env.metrics import Metric, WindowArrays, rolling_add
from drill_env.physics.batch import (
    NEEDS_PYTHON,
    PREPARED,
    SimulatorBatch,
    TupleSlots,
    prepare_in_call,
)
from drill_env.physics.jit import claim
from drill_env.physics.readings import advance_and_read
from drill_env.physics.simulator import Simulator
from drill_env.physics.validation import numbers

__all__ = ["BatchArrays", "EnvBatch", "step_all", "step_arrays", "step_batch", "step_many"]

#: The columns of :func:`step_many`'s ``inputs``: each env's speed set point (rad/s) and
#: hook load (N) of the interval, its string weight (N) and
#: ``Simulator.checked_weight_on_bit`` (N).
BatchInput = IntEnum("BatchInput", ["SPEED", "HOOK_LOAD", "STRING_WEIGHT", "CHECKED_WOB"],
                     start=0)
#: The entries of :func:`step_many`'s ``schedule``: the next env to hand out (the atomic
#: counter: element 0, where :func:`~drill_env.physics.jit.claim` counts) and the number
#: of threads to use.
Schedule = IntEnum("Schedule", ["NEXT", "THREADS"], start=0)


@njit(cache=True, parallel=True, nogil=True)
def step_many(n_steps, record_every, run, n_rec, flags, sims, windows, readings_out, step_out,
              window_out, inputs, schedule):
    """For each env e with ``run[e]``: prepare its simulator (``sims[e]``: its
    ``(KernelArrays, readings)``) for the interval with row e of ``inputs``
    (:data:`BatchInput` columns, for :func:`prepare_in_call`), advance it,
    then add the records to its metric window (``windows[e]``: its
    :class:`~drill_env.metrics.WindowArrays`). ``n_rec[e]``: records written; ``flags[e]``:
    the flags of :func:`~drill_env.metrics.rolling_add` (0 without records), or minus
    what :func:`prepare_in_call` returned when the simulator did not run (-STOPPED,
    -NEEDS_PYTHON). Row e of ``readings_out``, ``step_out`` and ``window_out`` receives
    the env's fresh readings (as many as fit) and, with records, its step and window
    metrics: the batch's view of every env at once, gathered while each env's data is in
    cache. Rows of envs without ``run`` are left as they are.

    ``schedule`` (int64, :data:`Schedule` entries): NEXT the next env to hand out
    (reset here), THREADS the number of threads (numba's, read in Python: a call in here
    would keep the function from numba's cache). The envs go to the threads one at a
    time, each to the next thread free, from the shared counter: a worker thread that
    wakes up late (a sleeping OpenMP worker takes ~80 us on a small VM,
    docs/performance.md) or envs of unequal size do not hold the call up, as fixed
    halves would. Each env's arithmetic is the same whichever thread runs it."""
    n = len(sims)
    schedule[Schedule.NEXT] = 0
    for _ in prange(max(1, min(schedule[Schedule.THREADS], n))):
        e = claim(schedule)
        while e < n:
            if run[e]:
                _step_env(e, n_steps, record_every, n_rec, flags, sims, windows,
                          readings_out, step_out, window_out, inputs)
            e = claim(schedule)


@njit(cache=True, nogil=True, inline="always")
def _step_env(e, n_steps, record_every, n_rec, flags, sims, windows, readings_out, step_out,
              window_out, inputs):
    """Env e of :func:`step_many`."""
    n_rec[e] = 0
    flags[e] = 0
    arrays, readings = sims[e]
    prepared = prepare_in_call(arrays, n_steps[e], record_every[e],
                               inputs[e, BatchInput.SPEED], inputs[e, BatchInput.HOOK_LOAD],
                               inputs[e, BatchInput.STRING_WEIGHT],
                               inputs[e, BatchInput.CHECKED_WOB])
    if prepared != PREPARED:
        flags[e] = -prepared
        return
    k = advance_and_read(n_steps[e], record_every[e], arrays, readings)
    n_rec[e] = k
    for j in range(min(readings.shape[0], readings_out.shape[1])):
        readings_out[e, j] = readings[j]
    if k > 0:
        window = windows[e]
        flags[e] = rolling_add(arrays.record[:k], window, True)
        step_out[e, :] = window.step_out
        window_out[e, :] = window.window_out


def window_arrays(env: DrillStringEnv) -> WindowArrays:
    return env.rolling_metrics.arrays


def window_key(env: DrillStringEnv) -> int:
    """A new window (every reset) or a grown buffer re-points the slot. Safe against
    reused ids: the slot keeps the old buffer alive, so a new one cannot have its id."""
    return id(env.rolling_metrics.arrays.samples)


class BatchArrays(NamedTuple):
    """One control interval of a batch, as :meth:`EnvBatch.run` leaves it: row e is env e
    (rows of envs that did not step are stale). The arrays are reused by the next call."""

    n_rec: np.ndarray     # int64: records written this interval
    flags: np.ndarray     # int64: rolling_add's flags (STEP_FINITE, WINDOW_FINITE bits)
    step: np.ndarray      # (n, len(Metric)): metrics of this interval's records
    window: np.ndarray    # (n, len(Metric)): metrics of the window
    readings: np.ndarray  # (n, len(readings)): the fresh readings


class EnvBatch:
    """The simulators and metric windows of ``size`` envs, for :func:`step_all`.

    Slots are re-pointed when an env gets a new simulator (randomised scenarios build one
    per episode) or a new window; the typed lists are built on first use and rebuilt
    after unpickling.
    """

    def __init__(self, size: int) -> None:
        self.size = int(size)
        self.sims = SimulatorBatch(self.size)
        self._windows = TupleSlots(self.size, window_arrays, window_key)
        self._flags = np.zeros(self.size, dtype=np.int64)
        self._step = np.zeros((self.size, len(Metric)))
        self._window = np.zeros((self.size, len(Metric)))
        self._readings = np.zeros((self.size, 0))
        self._layout: list[Any] = []  # per env: its simulator's and its window's arrays
        self._lists: tuple[Any, Any] | None = None  # the typed lists of those
        self._constants = np.zeros((self.size, 2))  # string weight, checked WOB
        self._schedule = np.zeros(len(Schedule), dtype=np.int64)  # step_many's

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()  # typed lists do not pickle; rebuilt on first use
        state.update(_layout=[], _lists=None)
        return state

    def _refresh(self, envs: Sequence[DrillStringEnv], sims: list[Simulator],
                 n_records: list[int]) -> tuple[Any, Any]:
        """What depends only on each env's simulator and metric window, looked up again
        when one of them is new since the last call (a reset, a grown buffer): the
        windows' room for ``n_records``, the typed lists, the simulators' constants.
        Most steps find them unchanged and skip every per-env lookup. Returns the typed
        lists of the simulators and of the windows."""
        layout = [a for env, sim in zip(envs, sims, strict=True)
                  for a in (sim.kernel_arrays(), env.rolling_metrics.arrays)]
        if self._lists is not None and len(layout) == len(self._layout) \
                and all(map(operator.is_, layout, self._layout)):
            return self._lists
        for env, n in zip(envs, n_records, strict=True):
            env.rolling_metrics.reserve(n)  # may give a window new arrays
        self._lists = (self.sims.slots(sims), self._windows.of(envs))
        self._constants = np.array([(sim.string_weight, sim.checked_weight_on_bit)
                                    for sim in sims])
        self._layout = [a for env, sim in zip(envs, sims, strict=True)
                        for a in (sim.kernel_arrays(), env.rolling_metrics.arrays)]
        return self._lists

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)  # (a batch pickled before the schedule had none)
        self.__dict__.setdefault("_schedule", np.zeros(len(Schedule), dtype=np.int64))

    def threads_for(self, run: np.ndarray) -> int:
        """Numba's threads, at most one per env in ``run`` (at least one)."""
        return max(1, min(numba.get_num_threads(), int(np.count_nonzero(run))))

    def _step_many(self, run: np.ndarray, arguments: tuple[Any, ...]) -> None:
        """:func:`step_many` for the envs in ``run``, ``arguments`` its others after
        ``run`` up to the schedule, on :meth:`threads_for` threads: a single env runs on
        the calling thread alone, without waking a worker that would have nothing to do
        (a sleeping OpenMP worker's wake-up, ~80 us, would hold the call up)."""
        threads = numba.get_num_threads()
        used = self.threads_for(run)
        self._schedule[Schedule.THREADS] = used
        steps, every, *rest = arguments
        full: tuple[Any, ...] = (steps, every, run, *rest, self._schedule)
        if used < threads:
            numba.set_num_threads(used)
        try:
            step_many(*full)
        finally:
            if used < threads:
                numba.set_num_threads(threads)

    def run(self, envs: Sequence[DrillStringEnv], active: np.ndarray) -> BatchArrays:
        """Run every active env's control interval in one parallel call; the batch's
        arrays (:class:`BatchArrays`). The readings' width is that of env 0's.

        The simulators are prepared inside the call; one that needs Python there (a
        mesh check, a curved hole's loads, a longer record buffer) is prepared by
        ``Simulator.prepare`` and run in a second call, a stopped one is read."""
        if len(envs) != self.size:
            raise ValueError(f"envs: this batch holds {self.size} envs, got {len(envs)}")
        arguments = [env.advance_request() for env in envs]
        n_steps, speeds, hooks, every = zip(*arguments, strict=True)
        sims = [env.sim for env in envs]
        sim_list, window_list = self._refresh(envs, sims, [
            n // k if k > 0 else 0 for n, k in zip(n_steps, every, strict=True)])
        inputs = np.empty((self.size, len(BatchInput)))
        inputs[:, BatchInput.SPEED] = speeds
        inputs[:, BatchInput.HOOK_LOAD] = hooks
        inputs[:, BatchInput.STRING_WEIGHT:] = self._constants  # and CHECKED_WOB
        steps = np.asarray(n_steps, dtype=np.int64)
        every_array = np.asarray(every, dtype=np.int64)
        width = len(sims[0].readings)
        if self._readings.shape[1] != width:
            self._readings = np.zeros((self.size, width))
        n_rec, flags = self.sims.n_rec, self._flags
        on = np.asarray(active, dtype=np.bool_)
        self._step_many(on, (steps, every_array, n_rec, flags, sim_list, window_list,
                             self._readings, self._step, self._window, inputs))
        if (flags[on] < 0).any():  # rare: Python's prepare, then run those; read the stopped
            retry = np.zeros(self.size, dtype=np.bool_)
            for e in np.flatnonzero(on & (flags == -NEEDS_PYTHON)).tolist():
                retry[e] = sims[e].prepare(n_steps[e], speeds[e], hooks[e], every[e])
            stopped = on & (flags < 0) & ~retry
            if retry.any():  # (prepare may have given a simulator a new record buffer)
                self._step_many(retry, (steps, every_array, n_rec, flags,
                                        self.sims.slots(sims), window_list, self._readings,
                                        self._step, self._window, inputs))
                self._layout = []  # looked up again at the next call
            for e in np.flatnonzero(stopped).tolist():
                fresh = sims[e].read()
                m = min(len(fresh), width)
                self._readings[e, :m] = fresh[:m]
                n_rec[e] = flags[e] = 0
        return BatchArrays(n_rec, flags, self._step, self._window, self._readings)

    def advance(self, envs: Sequence[DrillStringEnv], active: np.ndarray
                ) -> list[tuple[Any, Any] | None]:
        """Run every active env's control interval; per env its (step, window) metrics
        as ``RollingMetrics.update`` returns them (None where not active)."""
        n_rec = self.run(envs, active).n_rec
        out: list[tuple[Any, Any] | None] = []
        for e, env in enumerate(envs):
            if not active[e]:
                out.append(None)
            elif n_rec[e]:
                if env.render_mode is not None:  # a rendered env draws its records too
                    env.keep_records(env.sim.records(int(n_rec[e])))
                out.append(env.rolling_metrics.result(int(self._flags[e])))
            else:
                out.append((None, env.rolling_metrics.window()))
        return out


def step_all(envs: Sequence[DrillStringEnv], actions: np.ndarray,
             batch: EnvBatch | None = None, active: np.ndarray | None = None
             ) -> list[tuple[np.ndarray, float, bool, bool, dict[str, Any]] | None]:
    """Step ``envs`` with ``actions`` (one row each) in the three phases; per-env results.

    With a ``batch`` (one slot per env) all envs' physics and metric windows advance in
    one parallel numba call; without one, env after env. The results are bit-identical
    either way. Envs with ``active[i]`` False are left alone (None).
    """
    active = apply_actions(envs, actions, active)
    results: list = [None] * len(envs)
    if batch is None:
        for i, env in enumerate(envs):
            if active[i]:
                results[i] = env.finish_step(env.advance())
        return results
    for i, metrics in enumerate(batch.advance(envs, active)):
        if metrics is not None:
            results[i] = envs[i].finish_metrics(*metrics)
    return results


def step_batch(envs: Sequence[DrillStringEnv], actions: np.ndarray, batch: EnvBatch,
               active: np.ndarray | None = None
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, BatchInfo]:
    """:func:`step_all` through ``batch`` for envs that
    :meth:`DrillStringEnv.finishes_batch` accepts, with the results as arrays
    (:meth:`DrillStringEnv.finish_batch`): observations, rewards, terminated, truncated
    and a :class:`~drill_env.env_batch.BatchInfo`, one row per active env in their order.
    The same values as :func:`step_all`'s, without its per-env Python after the call.
    ValueError if the envs are not such envs (the vector envs check once, then only
    :meth:`DrillStringEnv.same_readings`, and call :func:`step_arrays`)."""
    if not DrillStringEnv.finishes_batch(envs):
        raise ValueError("envs: step_batch needs plain DrillStringEnv instances of one "
                         "config without delay, noise or frames, whose readings have one "
                         "length (DrillStringEnv.finishes_batch); use step_all")
    return step_arrays(envs, actions, batch, active)


def step_arrays(envs: Sequence[DrillStringEnv], actions: np.ndarray, batch: EnvBatch,
                active: np.ndarray | None = None
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, BatchInfo]:
    """:func:`step_batch` without its check, for a caller that made it."""
    active = apply_actions(envs, actions, active)
    arrays = batch.run(envs, active)
    n_rec, flags, step, window, readings = (arrays.n_rec, arrays.flags, arrays.step,
                                            arrays.window, arrays.readings)
    if not active.all():
        index = np.flatnonzero(active)
        envs = [envs[i] for i in index.tolist()]
        n_rec, flags, step, window, readings = (n_rec[index], flags[index], step[index],
                                                window[index], readings[index])
    return DrillStringEnv.finish_batch(list(envs), n_rec, flags, step, window, readings)


def apply_actions(envs: Sequence[DrillStringEnv], actions: np.ndarray,
                  active: np.ndarray | None) -> np.ndarray:
    """The first phase of a step: every active env maps its row of ``actions`` (checked
    by :func:`check_actions`) to set points. Returns ``active`` (all envs if None)."""
    size = int(np.prod(envs[0].action_space.shape or (2,))) if envs else 2
    if active is None:
        active = np.ones(len(envs), dtype=np.bool_)
    a = check_actions(actions, len(envs), size, active)
    for env, row, on in zip(envs, a, active, strict=True):
        if on:
            env.apply_action(row)
    return active


def check_actions(actions: np.ndarray, n: int, size: int, active: np.ndarray) -> np.ndarray:
    """``actions`` as a float64 (n, size) array; ValueError naming a non-finite one of
    an ``active`` env: the row of an env that resets in this step is not read
    (Gymnasium's next-step autoreset ignores it), so a placeholder there is fine."""
    a = numbers(actions, "actions")
    if a.shape != (n, size):
        raise ValueError(f"actions: expected shape ({n}, {size}), got {a.shape}")
    if math.isfinite(a.max()) and math.isfinite(a.min()):  # NaN and inf show in them, and
        return a  # they do not overflow as a sum of finite 1e308s did (a RuntimeWarning)
    bad = np.flatnonzero(~np.all(np.isfinite(a), axis=1) & active)
    if bad.size:
        raise ValueError(f"actions: must be finite, env {int(bad[0])} got "
                         f"{a[bad[0]].tolist()} (NaN/inf)")
    return a
