"""Speed of the numba core: real-time factor, ns per DOF per step, speed-up over NumPy.

Default simulator (1000 m of 5 in pipe over a 35 m BHA, mesoscopic bit, wall contact on)
drilling at 100 kN WOB and 60 rpm, on ONE core. The plain NumPy reference
(:mod:`drill_env.physics.reference`) integrates the same model; it is timed on a shorter
run and scaled per step. Prints a table and writes ``logs/benchmark_core.json``.

    python scripts/benchmark_core.py [--seconds 60] [--reference-steps 200]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numba  # noqa: E402
import numpy as np  # noqa: E402

from drill_env.physics.reference import ReferenceStepper  # noqa: E402
from drill_env.physics.simulator import OperatingPoint, Simulator  # noqa: E402

RPM = 2.0 * np.pi / 60.0
WOB = 100e3
SPEED = 60 * RPM


def settled_simulator() -> Simulator:
    sim = Simulator()
    sim.reset(OperatingPoint(SPEED, WOB))
    sim.advance(2000, SPEED, sim.hook_load_for(WOB))  # compile + leave the initial state
    return sim


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=60.0, help="simulated time (s)")
    parser.add_argument("--reference-steps", type=int, default=200)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--out", type=Path, default=Path("logs/benchmark_core.json"))
    args = parser.parse_args()
    numba.set_num_threads(1)

    sim = settled_simulator()
    n_steps = round(args.seconds / sim.dt)
    hook = sim.hook_load_for(WOB)
    times = []
    for _ in range(args.repeats):
        t0 = time.perf_counter()
        sim.advance(n_steps, SPEED, hook, record_every=10)
        times.append(time.perf_counter() - t0)
    if sim.status != 0:
        raise SystemExit(f"simulation failed: {sim.status_message}")
    wall = min(times)
    per_step = wall / n_steps
    n_dof = 5 * sim.n_nodes

    ref = ReferenceStepper(sim)
    ref.advance(5, SPEED, hook)  # factorise
    t0 = time.perf_counter()
    ref.advance(args.reference_steps, SPEED, hook)
    ref_per_step = (time.perf_counter() - t0) / args.reference_steps

    result = {
        "model": "1000 m 5 in DP + 35 m 6.5 in BHA, mesoscopic bit, contact on",
        "weight_on_bit_kN": WOB / 1e3,
        "surface_speed_rpm": SPEED / RPM,
        "n_nodes": sim.n_nodes,
        "n_dof": n_dof,
        "time_step_s": sim.dt,
        "simulated_s": n_steps * sim.dt,
        "wall_s": wall,
        "real_time_factor": n_steps * sim.dt / wall,
        "us_per_step": per_step * 1e6,
        "ns_per_dof_step": per_step / n_dof * 1e9,
        "reference_steps": args.reference_steps,
        "reference_us_per_step": ref_per_step * 1e6,
        "reference_real_time_factor": sim.dt / ref_per_step,
        "speedup_over_reference": ref_per_step / per_step,
        "numba_threads": numba.get_num_threads(),
        "numba_version": numba.__version__,
        "numpy_version": np.__version__,
        "cpu": platform.processor() or platform.machine(),
        "python": platform.python_version(),
    }
    rows = [
        ("model", result["model"]),
        ("DOFs (5 per node)", f"{n_dof} ({sim.n_nodes} nodes)"),
        ("time step", f"{sim.dt * 1e3:.3f} ms"),
        ("numba: wall per step", f"{result['us_per_step']:.2f} us"),
        ("numba: ns per DOF per step", f"{result['ns_per_dof_step']:.1f}"),
        ("numba: real-time factor (1 core)", f"{result['real_time_factor']:.1f} x"),
        ("NumPy reference: wall per step", f"{result['reference_us_per_step']:.0f} us"),
        ("NumPy reference: real-time factor", f"{result['reference_real_time_factor']:.3f} x"),
        ("speed-up numba / NumPy", f"{result['speedup_over_reference']:.0f} x"),
    ]
    width = max(len(k) for k, _ in rows)
    print(f"{'quantity':<{width}}  value")
    print("-" * (width + 2 + 50))
    for key, value in rows:
        print(f"{key:<{width}}  {value}")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2) + "\n")
    print(f"\nsaved {args.out}")


if __name__ == "__main__":
    main()
