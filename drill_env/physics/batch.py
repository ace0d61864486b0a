"""Many simulators advanced by one numba kernel, in parallel over simulators (``prange``).

Each simulator keeps its own arrays (meshes may differ between simulators, e.g. in the
randomised scenario). :class:`SimulatorBatch` hands them to :func:`advance_many` as one
numba typed ``List`` with a tuple of arrays per simulator, built once; a slot is
re-pointed only when its simulator or record buffer is replaced. Every simulator runs
exactly the single-simulator kernel (:func:`~drill_env.physics.readings.advance_and_read`:
the integrator, then the readings) on its own data, so the results are bit-identical to
advancing them one by one with ``Simulator.advance(..., read=True)``.

:meth:`SimulatorBatch.advance` is ONE call over all simulators, on all of numba's
threads (``NUMBA_NUM_THREADS``), without the GIL. (Slicing the batch over worker threads
so that finished slices' env Python overlaps the physics measured slower on 2 cores:
1.3-1.5x the loop of single envs against 1.5-1.6x for the one call.)
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numba import njit, prange
from numba.typed import List

from drill_env.physics.layout import KernelArrays, S
from drill_env.physics.readings import advance_and_read
from drill_env.physics.simulator import Simulator


@njit(cache=True, parallel=True, nogil=True)
def advance_many(lo, hi, n_steps, record_every, active, n_rec, sims):
    """Advance simulator e (lo <= e < hi) by ``n_steps[e]`` steps where ``active[e]``;
    ``n_rec[e]`` receives its number of records.

    ``sims``: a typed list with one ``(KernelArrays, readings)`` pair per simulator
    (:func:`simulator_arrays`); each simulator's readings are refreshed.
    """
    for i in prange(lo, hi):
        e = np.int64(i)  # typed lists take signed indices; prange's are unsigned
        if not active[e]:
            n_rec[e] = 0
            continue
        arrays, readings = sims[e]
        n_rec[e] = advance_and_read(n_steps[e], record_every[e], arrays, readings)


#: What :func:`prepare_in_call` found: the simulator runs, is stopped, or needs Python.
PREPARED, STOPPED, NEEDS_PYTHON = 0, 1, 2


@njit(cache=True, nogil=True, inline="always")
def prepare_in_call(arrays, n_steps, record_every, speed, hook, string_weight, checked):
    """:meth:`Simulator.prepare` inside a compiled batch call, where it needs no Python:
    the set point ``speed`` (rad/s), the hook load ``hook`` (N) and the WOB it leaves
    (``string_weight`` minus it, at least 0, as ``Simulator.weight_on_bit_for``).
    Returns PREPARED, STOPPED (status set: reset first), or NEEDS_PYTHON with nothing
    written (a non-finite input, a record buffer too short, or a change of WOB at or
    above ``checked``, :attr:`Simulator.checked_weight_on_bit`): then the caller runs
    ``Simulator.prepare``."""
    state = arrays.state
    if int(state[S.STATUS]) != 0:
        return STOPPED
    wob = string_weight - hook
    wob = wob if wob > 0.0 else 0.0
    rows = n_steps // record_every if record_every > 0 else 0
    if not (math.isfinite(speed) and math.isfinite(hook)) \
            or arrays.record.shape[0] < max(rows, 1) \
            or (wob != state[S.WOB] and wob >= checked):
        return NEEDS_PYTHON
    state[S.SETPOINT_TARGET] = speed
    state[S.HOOK_LOAD] = hook
    state[S.WOB] = wob
    return PREPARED


def simulator_arrays(sim: Simulator) -> tuple[KernelArrays, np.ndarray]:
    """One simulator in :func:`advance_many`'s list: its kernel arrays and readings."""
    return sim.kernel_arrays(), sim.readings


def simulator_key(sim: Simulator) -> tuple[int, int]:
    """What re-points a slot: a new simulator or a new record buffer.

    Safe against reused ids: the list keeps the old record buffer alive, so a new
    simulator's buffer cannot have its id.
    """
    return id(sim), id(sim.kernel_arrays().record)


class TupleSlots:
    """A numba typed ``List`` with one tuple of arrays per slot, kept in step with owners.

    ``slots.of(owners)`` returns the list, built on first use from ``arrays(owner)``; a
    slot is re-pointed when ``key(owner)`` changes (a new simulator, a grown buffer).
    One list of tuples, not one list per array: a typed list costs about a microsecond
    to pass into a compiled call. ``arrays`` and ``key`` are module-level functions so the
    slots pickle (the list itself is rebuilt after unpickling).
    """

    def __init__(self, size: int, arrays: Callable[[Any], tuple], key: Callable[[Any], Any]
                 ) -> None:
        self.size = int(size)
        self._arrays, self._key = arrays, key
        self._list: List | None = None
        self._keys: list[tuple | None] = [None] * self.size

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()  # typed lists do not pickle
        state["_list"] = None
        state["_keys"] = [None] * self.size
        return state

    def of(self, owners: Sequence[Any]) -> List:
        if self._list is None:
            self._list = typed_list(self._arrays(owners[0]))
            for owner in owners[1:]:
                typed_append(self._list, self._arrays(owner))
            self._keys = [self._key(owner) for owner in owners]
        for e, owner in enumerate(owners):
            key = self._key(owner)
            if key != self._keys[e]:
                typed_put(self._list, e, self._arrays(owner))
                self._keys[e] = key
        return self._list


# A typed list's methods called from Python compile in every process (~0.8 s each for
# these tuples: numba does not cache them); called inside these cached functions, they
# are compiled once and loaded from the cache after.
@njit(cache=True)
def typed_list(item):
    """A typed list holding ``item``."""
    out = List()
    out.append(item)
    return out


@njit(cache=True)
def typed_append(items, item):
    items.append(item)


@njit(cache=True)
def typed_put(items, index, item):
    items[index] = item


class SimulatorBatch:
    """Advance a fixed number of simulator slots together; see the module docstring.

    ``batch.advance(sims, n_steps, speeds, hook_loads, record_every, active)`` returns one
    record array per simulator, the same as ``sim.advance(..., read=True)`` would (empty
    where ``active`` is False), and leaves the same readings. A slot whose simulator (or
    record buffer) is a new object is re-pointed in place, without rebuilding the list.
    :meth:`prepare`, :meth:`slots` and :meth:`finish` are the steps of :meth:`advance`
    for a caller with its own kernel around :func:`advance_and_read` (the env batch).
    """

    def __init__(self, size: int) -> None:
        if size < 1:
            raise ValueError(f"size: a batch needs at least one simulator, got {size}")
        self.size = int(size)
        self._slots = TupleSlots(self.size, simulator_arrays, simulator_key)
        self.n_rec = np.zeros(self.size, dtype=np.int64)

    def slots(self, sims: Sequence[Simulator]) -> List:
        """The typed list of the simulators' arrays (:func:`simulator_arrays`)."""
        return self._slots.of(sims)

    def prepare(self, sims: Sequence[Simulator], n_steps: Sequence[int],
                speed_setpoints: Sequence[float | None], hook_loads: Sequence[float | None],
                record_every: Sequence[int], active: Sequence[bool] | np.ndarray | None
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``Simulator.prepare`` each active simulator: (n_steps, record_every, run)."""
        if len(sims) != self.size:
            raise ValueError(f"sims: this batch holds {self.size} simulators, got {len(sims)}")
        if active is None:
            active = [True] * self.size
        run = np.array([bool(a) and sim.prepare(n, w, h, r) for sim, a, n, w, h, r in zip(
            sims, active, n_steps, speed_setpoints, hook_loads, record_every, strict=True)])
        return (np.asarray(n_steps, dtype=np.int64), np.asarray(record_every, dtype=np.int64),
                run)

    @staticmethod
    def finish(sims: Sequence[Simulator], run: np.ndarray,
               active: Sequence[bool] | np.ndarray | None) -> None:
        """Read the simulators that were active but stopped before the kernel."""
        for e, sim in enumerate(sims):
            if not run[e] and (active is None or active[e]):
                sim.read()

    def advance(self, sims: Sequence[Simulator], n_steps: Sequence[int],
                speed_setpoints: Sequence[float | None], hook_loads: Sequence[float | None],
                record_every: Sequence[int], active: Sequence[bool] | np.ndarray | None = None
                ) -> list[np.ndarray]:
        """All simulators in one parallel kernel call; one record array per simulator.

        Every simulator with ``active`` True has fresh :attr:`Simulator.readings`
        afterwards, stopped ones included.
        """
        steps, every, run = self.prepare(sims, n_steps, speed_setpoints, hook_loads,
                                         record_every, active)
        advance_many(0, self.size, steps, every, run, self.n_rec, self.slots(sims))
        self.finish(sims, run, active)
        return [sim.records(int(k)) for sim, k in zip(sims, self.n_rec, strict=True)]
