"""How much two numba threads can buy on this machine, whatever the env does
(docs/performance.md, "Where a step's time goes"; issue 16, acceptance 3).

    .venv/bin/python scripts/parallel_ceiling.py

Three workloads of two equal, independent halves, each timed on one and on two numba
threads (``prange`` over the halves), interleaved, 7 rounds; min and median of the
one-thread / two-thread time ratio:

chain       a latency-bound recurrence (one multiply-add per element waiting for the last)
stream      a vectorised streaming update (multiply-adds over arrays in L1)
simulator   two copies of the default simulator (full level), 0.5 s each, in one
            parallel call (``SimulatorBatch``, as the batched envs run them)

Batched/loop at N envs cannot beat the ``simulator`` ratio: the env's serial Python
only lowers it. On this shared 2-vCPU VM the ratio moves between runs (1.47x and
1.84x median on 2026-11-30, minutes apart) while the latency-bound chain stays at
~1.99x. Our reading: throughput-bound work shares the cores' execution units with
whatever else the host runs, while a latency-bound chain leaves them idle.
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable

import numba
import numpy as np
from numba import njit, prange

from drill_env.physics.batch import SimulatorBatch
from drill_env.physics.config import SimulationConfig
from drill_env.physics.simulator import OperatingPoint, Simulator
from drill_env.physics.units import RPM

ROUNDS = 7


@njit(parallel=True, cache=True)
def chain(a, reps):
    for h in prange(a.shape[0]):
        x = a[h]
        for _ in range(reps):
            for i in range(1, x.shape[0]):
                x[i] = x[i] * 0.999 + x[i - 1] * 0.001


@njit(parallel=True, cache=True)
def stream(a, b, reps):
    for h in prange(a.shape[0]):
        x = a[h]
        y = b[h]
        for _ in range(reps):
            for i in range(x.shape[0]):
                x[i] = x[i] * 0.999 + y[i] * 0.001


def _ratio(run: Callable[[], None]) -> tuple[float, float]:
    """(min, median) over rounds of time on one thread / time on two."""
    run()  # compile and warm
    ratios = []
    for _ in range(ROUNDS):
        times = {}
        for threads in (1, 2):
            numba.set_num_threads(threads)
            start = time.perf_counter()
            run()
            times[threads] = time.perf_counter() - start
        ratios.append(times[1] / times[2])
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    return min(ratios), statistics.median(ratios)


def main() -> None:
    rng = np.random.default_rng(0)
    a = rng.random((2, 1000))
    b = rng.random((2, 1000))
    sims = []
    for _ in range(2):
        sim = Simulator(SimulationConfig())
        sim.reset(OperatingPoint(60 * RPM, 100e3))
        sim.advance(500, 60 * RPM, sim.hook_load_for(100e3))
        sims.append(sim)
    batch = SimulatorBatch(2)
    steps = [round(0.5 / sims[0].dt)] * 2
    speeds = [60 * RPM] * 2
    hooks = [sim.hook_load_for(100e3) for sim in sims]

    def simulators() -> None:
        batch.advance(sims, steps, speeds, hooks, [10, 10])  # the env's record rate

    rows = {"chain": lambda: chain(a, 40000), "stream": lambda: stream(a, b, 400000),
            "simulator": simulators}
    print(f"two equal halves, one numba thread / two ({ROUNDS} rounds, interleaved)")
    for name, run in rows.items():
        low, mid = _ratio(run)
        print(f"  {name:10s} min {low:.2f}x  median {mid:.2f}x")


if __name__ == "__main__":
    import argparse

    # no options: --help says what the study measures and how long it takes
    argparse.ArgumentParser(description=__doc__,
                            formatter_class=argparse.RawDescriptionHelpFormatter).parse_args()
    main()
