"""What a curved hole costs and changes (docs/model.md section 6, issue 18).

    .venv/bin/python scripts/curved_well_study.py

A 3,000 m string of the default components, vertical against the ``lateral_60`` well:

1. cost per step at the full and fast levels, best of 4 interleaved 10 s runs at
   120 rpm / 100 kN;
2. off-bottom rotating torque at 60 rpm at the three levels (full, fast, torsion only)
   against the soft-string torque-and-drag model;
3. stick-slip at 30 and 50 rpm / 100 kN: SSI, period (peak of the bit-speed spectrum
   over the last 80 s of 120 s) and mean surface torque.
"""

from __future__ import annotations

import math
import time

import numpy as np

from drill_env.metrics import stick_slip_severity
from drill_env.physics.config import replace
from drill_env.physics.layout import R
from drill_env.physics.simulator import OperatingPoint, Simulator
from drill_env.physics.trajectory import Survey, Trajectory, soft_string
from drill_env.physics.units import RPM
from drill_env.scenarios import make_scenario
from drill_env.well import column_for, rotating_wall_torque, sliding_friction

LENGTH = 3000.0
LEVELS = {"full": {}, "fast": {"solver.fidelity": "fast"},
          "torsion only": {"solver.lateral": False}}


def config(name: str, level: str):
    return replace(make_scenario(name, string_length=LENGTH).config, **LEVELS[level])


def cost() -> None:
    sims = {(name, level): Simulator(config(name, level))
            for name in ("default", "lateral_60") for level in ("full", "fast")}
    best = dict.fromkeys(sims, math.inf)
    for _ in range(4):
        for key, sim in sims.items():
            sim.reset(OperatingPoint(120 * RPM, 100e3))
            n = int(10.0 / sim.dt)
            start = time.perf_counter()
            sim.advance(n, record_every=10)
            best[key] = min(best[key], (time.perf_counter() - start) / n)
    for level in ("full", "fast"):
        vertical, deviated = best[("default", level)], best[("lateral_60", level)]
        print(f"{level}: {vertical * 1e6:.2f} us/step vertical, {deviated * 1e6:.2f} deviated "
              f"({deviated / vertical:.2f}x)")


def torque() -> None:
    cfg = config("lateral_60", "full")
    speed = 60 * RPM
    mu = sliding_friction(cfg, speed)
    well = cfg.well
    survey = Survey.from_stations(well.md, well.inclination, well.azimuth, warn=False)
    soft = soft_string(Trajectory(survey), column_for(cfg, LENGTH), LENGTH, mu)
    print(f"soft-string model: {soft.surface_torque / 1e3:.1f} kN m "
          f"({soft.surface_torque / math.sqrt(1 + mu * mu) / 1e3:.1f} after the friction angle)")
    for level in LEVELS:
        wall, _ = rotating_wall_torque(config("lateral_60", level), speed, seconds=15.0)
        print(f"{level}: rotating off bottom {wall / 1e3:.1f} kN m")


def stick_slip() -> None:
    for name in ("default", "lateral_60"):
        for level in ("full", "fast"):
            sim = Simulator(config(name, level))
            for rpm in (30, 50):
                sim.reset(OperatingPoint(rpm * RPM, 100e3))
                sim.vt[-1] *= 0.9
                rec = sim.run(120.0, record_every=5)
                late = rec[rec[:, R.TIME] > 40.0]
                w = late[:, R.BIT_SPEED]
                ssi = stick_slip_severity(w)
                dt = late[1, R.TIME] - late[0, R.TIME]
                power = np.abs(np.fft.rfft(w - w.mean()))
                freq = np.fft.rfftfreq(len(w), dt)
                period = 1.0 / freq[1:][np.argmax(power[1:])]
                print(f"{name} {level} {rpm} rpm: SSI {ssi:.2f}, period {period:.2f} s, "
                      f"surface torque {late[:, R.SURFACE_TORQUE].mean() / 1e3:.1f} kN m")


if __name__ == "__main__":
    import argparse

    # no options: --help says what the study measures and how long it takes
    argparse.ArgumentParser(description=__doc__,
                            formatter_class=argparse.RawDescriptionHelpFormatter).parse_args()
    cost()
    torque()
    stick_slip()
