"""What implicit contacts (``solver.implicit_contacts``) buy and keep: docs/performance.md.

Prints two markdown tables:

* speed: the core benchmark's string and operating point (``Simulator()``'s default,
  100 kN, 60 rpm, settled, one numba thread), explicit and implicit contacts at each
  level and step, timed in turns (``drill_env.tools.speed.common.time_simulators``) in
  ``--rounds`` rounds: min and median of the real-time factor and of its ratio to the
  explicit run of the same level in the same round;
* accuracy: a 9 m span of the BHA thrown at the wall at 2 m/s (deepest penetration and
  largest normal force against the explicit run at 0.5 ms), and the stick-slip of the
  ``default`` and ``paper_case2`` scenarios at 50 rpm (SSI and stuck share over 20-60 s);

and with ``--divergence N``, how many of N task-2 episodes at the fast level
(``DrillOptimise-v0``, env seeds 100 to 100 + N - 1, uniformly random actions from
``default_rng(seed)``, 300 steps) end with the simulation diverged, and their reasons.

Usage: ``python scripts/implicit_contact_study.py [--rounds 3] [--divergence 300]
[--implicit] [--only-divergence]`` (~3 min on 2 cores; 300 episodes 20-40 s more;
``--implicit``: count them with implicit contacts at 10 ms).
"""

from __future__ import annotations

import argparse
import math
import statistics
import warnings

import numpy as np

from drill_env.physics.config import SimulationConfig, replace
from drill_env.physics.simulator import OperatingPoint, Simulator
from drill_env.physics.units import RPM
from drill_env.scenarios import make_scenario
from drill_env.tools.speed.common import (
    WEIGHT_ON_BIT,
    one_numba_thread,
    settled_simulator,
    time_simulators,
)
from drill_env.tools.studies import simulate, stick_slip_summary

IMPLICIT = "solver.implicit_contacts"
#: (label, level, requested step or None for the level's own, implicit contacts)
VARIANTS = [
    ("full, explicit", "full", None, False),
    ("full, implicit 4 ms", "full", 0.004, True),
    ("full, implicit 5 ms", "full", 0.005, True),
    ("full, implicit 6 ms", "full", 0.006, True),
    ("fast, explicit", "fast", None, False),
    ("fast, implicit 6 ms", "fast", 0.006, True),
    ("fast, implicit 8 ms", "fast", 0.008, True),
    ("fast, implicit 10 ms", "fast", 0.010, True),
]


def variant(config: SimulationConfig, level: str, step: float | None,
            implicit: bool) -> SimulationConfig:
    config = replace(config, **{"solver.fidelity": level}).resolved()
    extra: dict = {IMPLICIT: implicit}
    if step is not None:
        extra["solver.time_step"] = step
    return replace(config, **extra)


def speed_table(rounds: int, seconds: float) -> list[str]:
    factors: dict[str, list[float]] = {label: [] for label, *_ in VARIANTS}
    ratios: dict[str, list[float]] = {label: [] for label, *_ in VARIANTS}
    steps = {}
    for _ in range(rounds):
        sims = {label: settled_simulator(variant(SimulationConfig(), *rest), WEIGHT_ON_BIT,
                                         2000) for label, *rest in VARIANTS}
        with one_numba_thread():
            figures = time_simulators(sims, WEIGHT_ON_BIT, seconds, 5, "speed", False)
        for label, level, *_ in VARIANTS:
            factors[label].append(figures[label]["real_time_factor"])
            ratios[label].append(figures[label]["real_time_factor"]
                                 / figures[f"{level}, explicit"]["real_time_factor"])
            steps[label] = figures[label]["time_step_s"]
    lines = ["| variant | step ms | x real time (min / median) | over explicit, same level "
             "(min / median) |", "| --- | --- | --- | --- |"]
    for label, *_ in VARIANTS:
        lines.append(f"| {label} | {steps[label] * 1e3:.2f} | {min(factors[label]):,.0f} / "
                     f"{statistics.median(factors[label]):,.0f} | {min(ratios[label]):.2f} / "
                     f"{statistics.median(ratios[label]):.2f} |")
    return lines


def thrown_span(config: SimulationConfig, seconds: float = 0.2) -> tuple[float, float, int]:
    """Deepest penetration (m), largest wall force (N) and status of the throw."""
    sim = Simulator(config)
    sim.reset(OperatingPoint(60 * RPM, 30e3))
    height = sim.node_depth[-1] - sim.node_depth[sim.lateral_start:]
    span = (height > 10.0 + 1e-9) & (height < 19.0 - 1e-9)
    sim.vl[0::2, 0][span] = 2.0 * np.sin(math.pi * (height[span] - 10.0) / 9.0)
    deepest = peak = 0.0
    for _ in range(int(round(seconds / sim.dt))):
        sim.advance(1)
        if sim.status:
            break
        radius = np.hypot(sim.ul[0::2, 0], sim.ul[0::2, 1])
        contact = sim.node_contact[sim.lateral_start:] > 0
        deepest = max(deepest, float(np.max(radius[contact]
                                            - sim.node_clearance[sim.lateral_start:][contact])))
        peak = max(peak, float(np.max(sim.contact_forces[:-1])))
    return deepest, peak, sim.status


def accuracy_table() -> list[str]:
    lines = ["| variant | step ms | throw: deepest mm | throw: peak kN | default: SSI / stuck "
             "| paper_case2: SSI / stuck |", "| --- | --- | --- | --- | --- | --- |"]
    base = SimulationConfig()
    ref_deep, ref_peak, _ = thrown_span(replace(base, **{"solver.time_step": 5e-4}))
    lines.append(f"| full, explicit, reference | 0.50 | {ref_deep * 1e3:.2f} | "
                 f"{ref_peak / 1e3:.1f} | | |")
    scenarios = [make_scenario(name) for name in ("default", "paper_case2")]
    rows = VARIANTS + [("full, implicit 8 ms", "full", 0.008, True),
                       ("full, implicit 10 ms", "full", 0.010, True),
                       ("full, implicit 12 ms", "full", 0.012, True)]
    for label, level, step, implicit in rows:
        config = variant(base, level, step, implicit)
        deep, peak, status = thrown_span(config)
        dt = Simulator(config).dt
        throw = (f"{deep * 1e3:.2f} | {peak / 1e3:.1f}" if status == 0 else
                 "diverged | diverged")
        cells = []
        for sc in scenarios:
            if step is not None and step > 0.008 and level == "full":
                cells.append("")
                continue
            summary = stick_slip_summary(simulate(variant(sc.config, level, step, implicit),
                                                  50.0, sc.weight_on_bit, 60.0), 20.0)
            cells.append(f"{summary['ssi']:.3f} / {summary['stuck_fraction']:.3f}")
        lines.append(f"| {label} | {dt * 1e3:.2f} | {throw} | {cells[0]} | {cells[1]} |")
    return lines


def one_random_episode(seed: int, physics: dict | None = None) -> str:
    """The termination reason of one task-2 episode under random actions ("" if none),
    at the fast level with ``physics`` overrides."""
    import gymnasium as gym

    import drill_env  # noqa: F401  (registers the tasks)

    env = gym.make("DrillOptimise-v0", physics=physics or {})
    env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    reason = ""
    for _ in range(env.unwrapped.max_episode_steps):
        _, _, terminated, truncated, info = env.step(rng.uniform(-1.0, 1.0, size=2))
        if terminated or truncated:
            reason = info.get("termination_reason", "")
            break
    env.close()
    return reason


def divergence_count(episodes: int, physics: dict | None = None) -> str:
    from concurrent.futures import ProcessPoolExecutor
    from functools import partial

    seeds = range(100, 100 + episodes)
    with ProcessPoolExecutor() as pool:
        reasons = list(pool.map(partial(one_random_episode, physics=physics), seeds))
    ended = {seed: reason for seed, reason in zip(seeds, reasons, strict=True) if reason}
    diverged = sum("diverged" in reason for reason in ended.values())
    return (f"task 2 at the fast level ({physics or 'as it is'}), random actions, env "
            f"seeds {seeds[0]}-{seeds[-1]}: "
            f"{diverged} of {episodes} diverged; terminations: {ended or 'none'}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--seconds", type=float, default=10.0,
                        help="simulated seconds per timed run")
    parser.add_argument("--divergence", type=int, default=0, metavar="N",
                        help="also count diverging random-action task-2 episodes of N")
    parser.add_argument("--only-divergence", action="store_true",
                        help="skip the speed and accuracy tables")
    parser.add_argument("--implicit", action="store_true",
                        help="count the divergences with implicit contacts at 10 ms")
    args = parser.parse_args()
    if args.divergence < 0:
        parser.error(f"--divergence: expected a count >= 0, got {args.divergence}")
    physics = {IMPLICIT: True, "solver.time_step": 0.01} if args.implicit else None
    if args.only_divergence:
        print(divergence_count(args.divergence or 300, physics))
        return
    warnings.simplefilter("ignore", RuntimeWarning)  # the 100 kN pipe warning, known
    print("\n".join(speed_table(args.rounds, args.seconds)))
    print()
    print("\n".join(accuracy_table()))
    if args.divergence:
        print()
        print(divergence_count(args.divergence, physics))


if __name__ == "__main__":
    main()
