"""How much a longer step or a coarser pipe mesh changes the default scenario, and what
it buys (docs/performance.md, "Step and mesh"; issue 16).

    .venv/bin/python scripts/step_study.py

The default string at two operating points (50 rpm / 100 kN: stick-slip; 120 rpm /
100 kN: smooth rotation with the pipe against the wall), 60 s from a settled start with
a 2 % kick to the bit, metrics over 20-60 s (:func:`drill_env.metrics.window_metrics`)
for each variant against the reference (1 ms step, the default mesh), and the cost per
simulated second (best of 3, interleaved). A variant's step is what the simulator takes:
``stable_time_step`` shortens a request to ``critical_step_fraction`` of the explicit
contacts' critical step.
"""

from __future__ import annotations

import math
import time

from drill_env.metrics import window_metrics
from drill_env.physics.config import replace
from drill_env.physics.layout import RECORD_CHANNELS, R
from drill_env.physics.simulator import OperatingPoint, Simulator
from drill_env.physics.units import RPM
from drill_env.scenarios import make_scenario

VARIANTS = {
    "reference: 1 ms": {"solver.time_step": 1e-3},
    "default: 2 ms": {},
    "4 ms requested (fraction 0.5)": {"solver.time_step": 4e-3},
    "4 ms at fraction 0.8": {"solver.time_step": 4e-3, "solver.critical_step_fraction": 0.8},
    "20 m pipe elements, 2 ms": {"string.drill_pipe.element_length": 20.0},
    "20 m pipe elements, 4 ms at 0.8": {"string.drill_pipe.element_length": 20.0,
                                        "solver.time_step": 4e-3,
                                        "solver.critical_step_fraction": 0.8},
}
POINTS = {"50 rpm": 50 * RPM, "120 rpm": 120 * RPM}
METRICS = ("ssi", "stuck_fraction", "rop", "radial_ratio", "whirl_ratio")
SECONDS, FROM = 60.0, 20.0


def run(sim: Simulator, speed: float) -> tuple[dict[str, float], float, float]:
    sim.reset(OperatingPoint(speed, 100e3))
    sim.vt[-1] *= 0.98
    every = max(1, round(0.01 / sim.dt))
    start = time.perf_counter()
    rec = sim.run(SECONDS, record_every=every)
    wall = time.perf_counter() - start
    late = rec[rec[:, R.TIME] > FROM]
    bit = sim.config.bit
    m = window_metrics(late, RECORD_CHANNELS, every * sim.dt, bit.gauge_clearance,
                       bit.diameter)
    m["mean_torque"] = float(late[:, R.SURFACE_TORQUE].mean())
    return m, wall, sim.dt


def main() -> None:
    base = make_scenario("default").config
    sims = {name: Simulator(replace(base, **changes)) for name, changes in VARIANTS.items()}
    results: dict = {}
    for _ in range(3):
        for name, sim in sims.items():
            for point, speed in POINTS.items():
                metrics, wall, dt = run(sim, speed)
                old = results.get((name, point))
                if old is None or wall < old[1]:
                    results[(name, point)] = (metrics, wall, dt)
    keys = (*METRICS, "mean_torque")
    print(f"{'variant':34s} {'point':8s} {'dt ms':>6s} {'x real time':>11s} {'speed-up':>8s}  "
          + "  ".join(f"{k:>14s}" for k in keys))
    for point in POINTS:
        ref = results[("reference: 1 ms", point)][0]
        default_wall = results[("default: 2 ms", point)][1]
        for name in VARIANTS:
            metrics, wall, dt = results[(name, point)]
            cells = []
            for k in keys:
                scale = max(abs(ref[k]), 0.05 if k != "mean_torque" else 1.0)
                err = (metrics[k] - ref[k]) / scale
                cells.append(f"{metrics[k]:8.3g} ({err:+.1%})" if math.isfinite(err)
                             else f"{metrics[k]:14.3g}")
            print(f"{name:34s} {point:8s} {dt * 1e3:6.2f} {SECONDS / wall:11.0f} "
                  f"{default_wall / wall:8.2f}  " + "  ".join(f"{c:>14s}" for c in cells))


if __name__ == "__main__":
    import argparse

    # no options: --help says what the study measures and how long it takes
    argparse.ArgumentParser(description=__doc__,
                            formatter_class=argparse.RawDescriptionHelpFormatter).parse_args()
    main()
