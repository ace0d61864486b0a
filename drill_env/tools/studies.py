"""Paper studies on the bare simulator: steady drilling and sandwich crossings.

Shared by the paper-result tests, ``scripts/paper_reproduction.py`` and the CLI demo,
so the figures, the tests and the demo read the same runs (one source of truth).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drill_env import metrics
from drill_env.physics.config import SimulationConfig
from drill_env.physics.simulator import RECORD_CHANNELS, OperatingPoint, Simulator
from drill_env.physics.units import RPM
from drill_env.progress import progress_bar

COL = {name: i for i, name in enumerate(RECORD_CHANNELS)}  # column of each record channel


@dataclass
class Run:
    """Records of one run (columns :data:`RECORD_CHANNELS`) and rock shares over time."""

    config: SimulationConfig
    records: np.ndarray
    share_time: np.ndarray  # (k,) s
    shares: np.ndarray  # (k, n_rock) share of front blade length in each rock
    status: str

    def channel(self, name: str) -> np.ndarray:
        return self.records[:, COL[name]]

    @property
    def time(self) -> np.ndarray:
        return self.records[:, COL["time"]]

    def window(self, t0: float, t1: float = np.inf) -> np.ndarray:
        t = self.time
        return self.records[(t >= t0) & (t < t1)]

    def share_at(self, t: np.ndarray, rock: int) -> np.ndarray:
        return np.interp(t, self.share_time, self.shares[:, rock])


def simulate(config: SimulationConfig, rpm: float, weight_on_bit: float, seconds: float,
             record_every: int = 10, kick: float = 0.01, chunk_seconds: float = 1.0,
             progress: str | None = None) -> Run:
    """Drill at constant set point and WOB from the settled state, with a small kick.

    ``progress``: label of a tqdm progress bar over the simulated seconds (None: none).
    """
    sim = Simulator(config)
    sim.reset(OperatingPoint(rpm * RPM, weight_on_bit))
    sim.vt[-1] *= 1.0 - kick  # steady rotation is an equilibrium; the kick tests it
    chunk = max(record_every, round(chunk_seconds / sim.dt) // record_every * record_every)
    steps = round(seconds / sim.dt)
    records, times, shares = [], [], []
    hook = sim.hook_load_for(weight_on_bit)
    done = 0
    bar = (progress_bar(total=steps, desc=progress, leave=False) if progress is not None
           else None)
    while done < steps and not sim.status:
        n = min(chunk, steps - done)
        records.append(sim.advance(n, rpm * RPM, hook, record_every))
        done += n
        times.append(sim.time)
        shares.append(sim.rock_share)
        if bar is not None:
            bar.update(n)
    if bar is not None:
        bar.close()
    return Run(config, np.concatenate(records), np.asarray(times), np.asarray(shares),
               sim.status_message)


def stick_slip_summary(run: Run, t0: float, t1: float = np.inf) -> dict[str, float]:
    w = run.window(t0, t1)[:, COL["bit_speed"]]
    return {"ssi": metrics.stick_slip_severity(w), "stuck_fraction": metrics.stuck_fraction(w)}


def lateral_force(run: Run) -> np.ndarray:
    return np.hypot(run.channel("bit_force_x"), run.channel("bit_force_y"))


def radial_displacement(run: Run) -> np.ndarray:
    return np.hypot(run.channel("bit_x"), run.channel("bit_y"))
