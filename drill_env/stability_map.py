"""Torsional stability maps (paper section 4.1, Fig. 15) by boundary tracking.

For each bit position P1..P6 of the hard-soft-hard sandwich (``paper_case1``: symmetric
bit, torsion only, stiff top drive) the map says, over a grid of rotary speed x weight on
bit, where steady drilling turns into stick-slip. One grid point is one simulation: the
settled state at that set point and WOB, kicked by 1 % of the bit speed, run for
``seconds``; it counts as stick-slip when the bit sticks (|bit speed| < 1 rpm, the
metric of :func:`drill_env.metrics.stuck_fraction`) in the last ``measure`` seconds.

The bit is held at its position: every ``hold`` seconds the depth goes back to the
start, so the share of each rock under the blades stays that of the position (drilling
on at ~12 m/h would cross the 45 deg interface within the run).

Boundary tracking, the paper's algorithm instead of a full grid scan: stick-slip lies
at high WOB and low speed, so at each speed the WOB boundary is a threshold, and it rises
with speed. Start at the lowest speed and WOB;

1. stick-slip: every higher WOB at this speed sticks too, and the next point is the
   next speed;
2. no stick-slip: only the WOB increases in the next step.

The walk is a staircase along the boundary: at most (speeds + WOBs) points instead of
speeds x WOBs, and exact for any boundary that does not fall with speed (tested against
a full scan). The paper words rule 1 as WOB and speed "increase linearly" in the next
step; stepping the WOB up as well would skip the point where the boundary stays level,
and the map would follow the grid diagonal wherever the true boundary rises by less
than one WOB step per speed step (it did, at 5 rpm / 5 kN steps below 60 rpm), so the
next point keeps the WOB.

The boundary is that of stick-slip that develops within ``seconds`` from a 1 % kick:
near the linear stability limit the oscillation grows too slowly to stick in the run
(growth rates below about ln(1 / kick) / seconds), so the map's unstable zone lies
inside the linearly unstable one (:func:`linear_boundary`) and approaches it as
``seconds`` grows.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
from pydantic import Field

from drill_env import metrics
from drill_env.physics.config import replace, require_positive
from drill_env.physics.layout import R
from drill_env.physics.simulator import OperatingPoint, Simulator
from drill_env.physics.units import RPM
from drill_env.physics.validation import Count, NonNegative, Positive, config_dataclass
from drill_env.scenarios import POSITIONS, make_scenario

#: The paper's grid: 0-250 rpm and 0-200 kN in steps of 5 rpm / 5 kN (0 itself is
#: steady by definition: no rotation, or no bit load).
PAPER_RPM_STEP = 5.0
PAPER_WOB_STEP = 5.0e3
PAPER_MAX_RPM = 250.0
PAPER_MAX_WOB = 200.0e3


@config_dataclass
class MapSettings:
    """How each grid point is simulated and classified."""

    #: Simulated seconds per point, from the kicked settled state.
    seconds: Positive = Field(30.0, le=3600.0)
    #: The last ``measure`` seconds decide: stick-slip if the bit sticks in them.
    measure: Positive = Field(10.0, le=3600.0)
    #: Seconds between two returns of the bit to its position.
    hold: Positive = Field(0.5, le=3600.0)
    #: Initial kick: the bit speed starts ``kick`` below steady (a 1 % disturbance).
    kick: NonNegative = Field(0.01, lt=1.0)
    #: Record every k simulator steps (the stick test reads these samples).
    record_every: Count = Field(5, ge=1, le=100_000)

    def __post_init__(self) -> None:
        if self.measure > self.seconds:
            raise ValueError(f"measure: must be <= seconds ({self.seconds}), got "
                             f"{self.measure}")


#: The settings of ``drill-env stability-map``.
DEFAULT_SETTINGS = MapSettings()


@dataclass
class StabilityMap:
    """The map of one position. Arrays are indexed [wob, rpm]."""

    position: str
    rock2_share: float  # share of the front blades in rock 2 (the soft layer)
    rpm: np.ndarray  # (n_rpm,) grid speeds (rpm)
    weight_on_bit: np.ndarray  # (n_wob,) grid WOBs (N)
    unstable: np.ndarray  # (n_wob, n_rpm) bool: stick-slip (tracked or implied)
    tested: np.ndarray  # (n_wob, n_rpm) int8: -1 not simulated, 0 steady, 1 stick-slip
    boundary: np.ndarray  # (n_rpm,) lowest stick-slip WOB (N) per speed; NaN: none
    runs: int
    wall_s: float

    @property
    def unstable_fraction(self) -> float:
        return float(self.unstable.mean())

    def to_json(self) -> dict:
        d = asdict(self)
        for key, value in d.items():
            if isinstance(value, np.ndarray):
                d[key] = [None if isinstance(v, float) and math.isnan(v) else v
                          for v in value.tolist()] if value.ndim == 1 else value.tolist()
        d["unstable_fraction"] = self.unstable_fraction
        return d


def track_boundary(stick_slip: Callable[[int, int], bool], n_rpm: int, n_wob: int
                   ) -> tuple[np.ndarray, np.ndarray]:
    """The boundary tracking of the module docstring over an (n_wob x n_rpm) grid.

    ``stick_slip(i_rpm, j_wob)`` simulates one point. Returns ``(unstable, tested)``
    as in :class:`StabilityMap`. Speeds past the last one reached (the WOB ran out)
    count as steady: the boundary rises with speed.
    """
    if n_rpm < 1 or n_wob < 1:
        raise ValueError(f"grid: needs at least one speed and one WOB, got {n_rpm} x {n_wob}")
    unstable = np.zeros((n_wob, n_rpm), dtype=np.bool_)
    tested = np.full((n_wob, n_rpm), -1, dtype=np.int8)
    i = j = 0
    while i < n_rpm and j < n_wob:
        if stick_slip(i, j):
            tested[j, i] = 1
            unstable[j:, i] = True  # rule 1: every higher WOB sticks too; next speed
            i += 1
        else:
            tested[j, i] = 0  # rule 2: only the WOB increases
            j += 1
    return unstable, tested


def point_sticks(config, rpm: float, weight_on_bit: float, settings: MapSettings
                 ) -> dict[str, float]:
    """Simulate one grid point, bit held at its position; its stick-slip metrics."""
    sim = Simulator(config)
    omega = rpm * RPM
    sim.reset(OperatingPoint(omega, weight_on_bit))
    sim.vt[-1] *= 1.0 - settings.kick  # steady rotation is an equilibrium; the kick tests it
    depth = sim.depth
    hook = sim.hook_load_for(weight_on_bit)
    chunk = max(settings.record_every,
                round(settings.hold / sim.dt) // settings.record_every * settings.record_every)
    steps = round(settings.seconds / sim.dt)
    records = []
    done = 0
    while done < steps and not sim.status:
        n = min(chunk, steps - done)
        records.append(sim.advance(n, omega, hook, settings.record_every))
        sim.set_depth(depth)  # hold the position
        done += n
    if sim.status:
        raise RuntimeError(f"stability map point {rpm:.0f} rpm, {weight_on_bit / 1e3:.0f} kN: "
                           f"{sim.status_message}")
    rec = np.concatenate(records)
    late = rec[rec[:, R.TIME] > sim.time - settings.measure, R.BIT_SPEED]
    return {"stuck_fraction": metrics.stuck_fraction(late),
            "ssi": metrics.stick_slip_severity(late)}


def grid(rpm_step: float = PAPER_RPM_STEP, wob_step: float = PAPER_WOB_STEP,
         max_rpm: float = PAPER_MAX_RPM, max_wob: float = PAPER_MAX_WOB
         ) -> tuple[np.ndarray, np.ndarray]:
    """Speeds (rpm) and WOBs (N) of the map, from one step up to the maximum."""
    for name, value in (("rpm_step", rpm_step), ("wob_step", wob_step), ("max_rpm", max_rpm),
                        ("max_wob", max_wob)):
        require_positive(value, name)
    if rpm_step > max_rpm or wob_step > max_wob:
        raise ValueError("rpm_step/wob_step: a step must not exceed the map's maximum")
    rpm = np.arange(1, math.floor(max_rpm / rpm_step + 1e-9) + 1) * rpm_step
    wob = np.arange(1, math.floor(max_wob / wob_step + 1e-9) + 1) * wob_step
    return rpm, wob


def stability_map(position: str, rpm: Sequence[float], weight_on_bit: Sequence[float],
                  settings: MapSettings = DEFAULT_SETTINGS, config=None,
                  progress: Callable[[], None] | None = None) -> StabilityMap:
    """The map of ``position`` (P1..P6) over the grid, by :func:`track_boundary`.

    ``config``: the simulation config (default: ``paper_case1`` at ``position``);
    ``progress``: called after every simulated point.
    """
    if position not in POSITIONS:
        raise ValueError(f"position: must be one of {sorted(POSITIONS)}, got {position!r}")
    rpm = np.asarray(rpm, dtype=float)
    wob = np.asarray(weight_on_bit, dtype=float)
    if config is None:
        config = make_scenario("paper_case1", position=position).config
    t0 = time.perf_counter()
    runs = 0

    def sticks(i: int, j: int) -> bool:
        nonlocal runs
        runs += 1
        result = point_sticks(config, float(rpm[i]), float(wob[j]), settings)
        if progress is not None:
            progress()
        return result["stuck_fraction"] > 0.0

    unstable, tested = track_boundary(sticks, len(rpm), len(wob))
    first = np.where(unstable.any(axis=0), unstable.argmax(axis=0), -1)
    boundary = np.where(first >= 0, wob[np.maximum(first, 0)], np.nan)
    return StabilityMap(position, POSITIONS[position][0], rpm, wob, unstable, tested,
                        boundary, runs, time.perf_counter() - t0)


def stability_maps(positions: Sequence[str] = tuple(POSITIONS), rpm_step: float = PAPER_RPM_STEP,
                   wob_step: float = PAPER_WOB_STEP, settings: MapSettings = DEFAULT_SETTINGS,
                   max_rpm: float = PAPER_MAX_RPM, max_wob: float = PAPER_MAX_WOB,
                   progress: bool = False) -> list[StabilityMap]:
    """:func:`stability_map` of each position on one grid (tqdm bar if ``progress``)."""
    rpm, wob = grid(rpm_step, wob_step, max_rpm, max_wob)
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=len(positions) * (len(rpm) + len(wob)), desc="  stability map",
                   unit="run", leave=False)
    try:
        return [stability_map(p, rpm, wob, settings,
                              progress=bar.update if bar is not None else None)
                for p in positions]
    finally:
        if bar is not None:
            bar.close()


def linear_boundary(position: str, rpm: Sequence[float], max_wob: float = PAPER_MAX_WOB,
                    tol: float = 100.0) -> np.ndarray:
    """Lowest WOB (N) at which steady drilling is linearly unstable, per speed (NaN: none
    up to ``max_wob``), for a position in ONE rock (P1, P4, P6): the eigenvalues of
    :func:`drill_env.physics.stability.torsional_growth_rate`, independent of the time
    integrator. Positions on an interface have no single-rock curve."""
    from drill_env.physics.stability import torsional_growth_rate

    share = POSITIONS[position][0]
    if share not in (0.0, 1.0):
        raise ValueError(f"position: {position} straddles the interface (rock 2 share "
                         f"{share}); the linear boundary needs one rock")
    config = make_scenario("paper_case1", position=position).config
    config = replace(config, bit_model="macroscopic")
    sim = Simulator(config)
    rock = 1 if share == 1.0 else 0
    out = np.full(len(rpm), np.nan)
    for k, r in enumerate(rpm):
        omega = float(r) * RPM
        if torsional_growth_rate(sim, omega, max_wob, rock) <= 0.0:
            continue
        lo, hi = 0.0, max_wob  # growth rate rises with WOB (more negative bit damping)
        while hi - lo > tol:
            mid = 0.5 * (lo + hi)
            lo, hi = (lo, mid) if torsional_growth_rate(sim, omega, mid, rock) > 0.0 else \
                (mid, hi)
        out[k] = hi
    return out


def plot_maps(maps: Sequence[StabilityMap], path: Path) -> Path:
    """Fig. 15 style: one panel per position, the stick-slip zone shaded, simulated
    points marked (x steady, o stick-slip)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cols = min(3, len(maps))
    rows = math.ceil(len(maps) / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 3.4 * rows), squeeze=False,
                             sharex=True, sharey=True)
    for ax, m in zip(axes.flat, maps, strict=False):
        kn = m.weight_on_bit / 1e3
        ax.pcolormesh(m.rpm, kn, m.unstable, cmap="Reds", vmin=0, vmax=2.5, shading="nearest")
        steady = np.argwhere(m.tested == 0)
        sticky = np.argwhere(m.tested == 1)
        ax.plot(m.rpm[steady[:, 1]], kn[steady[:, 0]], "x", color="tab:blue", ms=3,
                label="steady")
        ax.plot(m.rpm[sticky[:, 1]], kn[sticky[:, 0]], "o", color="tab:red", ms=3,
                mfc="none", label="stick-slip")
        ax.set_title(f"{m.position}: {m.rock2_share:.0%} in rock 2, "
                     f"{m.unstable_fraction:.0%} unstable", fontsize=9)
    for ax in axes[-1]:
        ax.set_xlabel("rotary speed (rpm)")
    for ax in axes[:, 0]:
        ax.set_ylabel("WOB (kN)")
    for ax in list(axes.flat)[len(maps):]:
        ax.set_visible(False)
    axes.flat[0].legend(loc="upper right", fontsize=7)
    fig.suptitle("Torsional stability maps by boundary tracking (paper Fig. 15)")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def write_maps(maps: Sequence[StabilityMap], out: Path, settings: MapSettings) -> list[Path]:
    """``stability_map.json`` and ``stability_map.png`` in ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    data = {"settings": asdict(settings), "maps": [m.to_json() for m in maps]}
    json_path = out / "stability_map.json"
    json_path.write_text(json.dumps(data, indent=1))
    return [json_path, plot_maps(maps, out / "stability_map.png")]


def format_maps(maps: Sequence[StabilityMap]) -> str:
    """A table a person can read: per position, unstable share and boundary samples."""
    lines = ["position  rock 2  unstable  runs  grid   boundary WOB (kN) at 25/50/100/150 rpm",
             "-" * 80]
    for m in maps:
        samples = []
        for r in (25.0, 50.0, 100.0, 150.0):
            k = np.flatnonzero(np.isclose(m.rpm, r))
            value = m.boundary[k[0]] if k.size else np.nan
            samples.append("-" if not k.size else ("none" if math.isnan(value)
                                                    else f"{value / 1e3:.0f}"))
        lines.append(f"{m.position:<9} {m.rock2_share:>5.0%}  {m.unstable_fraction:>7.0%}  "
                     f"{m.runs:>4}  {m.unstable.size:>5}   {' / '.join(samples)}")
    return "\n".join(lines)
