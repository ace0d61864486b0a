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

from collections.abc import Sequence

import numpy as np
from numba import njit, prange
from numba.typed import List

from drill_env.physics.readings import advance_and_read
from drill_env.physics.simulator import Simulator


@njit(cache=True, parallel=True, nogil=True)
def advance_many(lo, hi, n_steps, record_every, active, n_rec, sims):
    """Advance simulator e (lo <= e < hi) by ``n_steps[e]`` steps where ``active[e]``;
    ``n_rec[e]`` receives its number of records.

    ``sims``: a typed list with one tuple per simulator, the arguments of
    :func:`~drill_env.physics.readings.advance_and_read` after ``n_steps`` and
    ``record_every`` (:meth:`SimulatorBatch.kernel_arrays`); each simulator's readings
    are refreshed. One list of tuples rather than one list per argument: each typed list
    costs about a microsecond to pass into the call.
    """
    for i in prange(lo, hi):
        e = np.int64(i)  # typed lists take signed indices; prange's are unsigned
        if not active[e]:
            n_rec[e] = 0
            continue
        n_rec[e] = advance_and_read(n_steps[e], record_every[e], *sims[e])


class SimulatorBatch:
    """Advance a fixed number of simulator slots together; see the module docstring.

    ``batch.advance(sims, n_steps, speeds, hook_loads, record_every, active)`` returns one
    record array per simulator, the same as ``sim.advance(..., read=True)`` would (empty
    where ``active`` is False), and leaves the same readings. A slot whose simulator (or
    record buffer) is a new object is re-pointed in place, without rebuilding the list.
    """

    def __init__(self, size: int) -> None:
        if size < 1:
            raise ValueError(f"size: a batch needs at least one simulator, got {size}")
        self.size = int(size)
        self._keys: list[tuple[int, int] | None] = [None] * self.size
        self._sims: List | None = None
        self._n_rec = np.zeros(self.size, dtype=np.int64)

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()  # typed lists do not pickle: rebuilt on next use
        state["_sims"] = None
        state["_keys"] = [None] * self.size
        return state

    @staticmethod
    def kernel_arrays(sim: Simulator) -> tuple[np.ndarray, ...]:
        """The arrays of one simulator in :func:`advance_many`'s tuples."""
        return (*sim.kernel_arrays(), sim.readings)

    def _arguments(self, sims: Sequence[Simulator]) -> List:
        """The typed list of the simulators' arrays, kept in step with the simulators."""
        if self._sims is None:
            self._sims = List([self.kernel_arrays(sim) for sim in sims])
            self._keys = [(id(sim), id(sim._record)) for sim in sims]
        for e, sim in enumerate(sims):
            key = (id(sim), id(sim._record))
            if key != self._keys[e]:
                self._sims[e] = self.kernel_arrays(sim)
                self._keys[e] = key
        return self._sims

    def _start(self, sims: Sequence[Simulator], n_steps: Sequence[int],
               speed_setpoints: Sequence[float | None], hook_loads: Sequence[float | None],
               record_every: Sequence[int], active: Sequence[bool] | None) -> tuple:
        if len(sims) != self.size:
            raise ValueError(f"sims: this batch holds {self.size} simulators, got {len(sims)}")
        if active is None:
            active = [True] * self.size
        run = np.array([bool(a) and sim.prepare(n, w, h, r) for sim, a, n, w, h, r in zip(
            sims, active, n_steps, speed_setpoints, hook_loads, record_every, strict=True)])
        return (np.asarray(n_steps, dtype=np.int64), np.asarray(record_every, dtype=np.int64),
                run, self._n_rec, self._arguments(sims))

    def advance(self, sims: Sequence[Simulator], n_steps: Sequence[int],
                speed_setpoints: Sequence[float | None], hook_loads: Sequence[float | None],
                record_every: Sequence[int], active: Sequence[bool] | None = None
                ) -> list[np.ndarray]:
        """All simulators in one parallel kernel call; one record array per simulator.

        Every simulator with ``active`` True has fresh :attr:`Simulator.readings`
        afterwards, stopped ones included.
        """
        args = self._start(sims, n_steps, speed_setpoints, hook_loads, record_every, active)
        advance_many(0, self.size, *args)
        run = args[2]
        for e, sim in enumerate(sims):
            if not run[e] and (active is None or active[e]):
                sim.read()  # stopped before the kernel: read its final state here
        return [sim.records(int(k)) for sim, k in zip(sims, self._n_rec, strict=True)]
