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
import textwrap
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import Field

from drill_env import metrics
from drill_env.physics.config import replace, require_positive
from drill_env.physics.layout import R
from drill_env.physics.simulator import OperatingPoint, Simulator
from drill_env.physics.units import RPM
from drill_env.physics.validation import (
    Count,
    NonNegative,
    Positive,
    config_dataclass,
    did_you_mean,
    jsonable,
    repeated,
)
from drill_env.scenarios import POSITIONS, make_scenario, with_physics
from drill_env.sweep import (
    ResultStore,
    digest,
    make_executor,
    save_text,
    save_whole,
    source_digest,
)

#: The paper's grid: 0-250 rpm and 0-200 kN in steps of 5 rpm / 5 kN (0 itself is
#: steady by definition: no rotation, or no bit load).
PAPER_RPM_STEP = 5.0
PAPER_WOB_STEP = 5.0e3
PAPER_MAX_RPM = 250.0
PAPER_MAX_WOB = 200.0e3
#: Bounds of a map: the scenarios' highest speed (1000 rpm) and ten times the paper's
#: WOB; a point beyond what the string carries is refused before the map starts
#: (:func:`check_map_corner`). 1000 lines of each: the boundary tracker simulates about
#: one row and one column, already ~2000 points of 30 s.
MAX_MAP_RPM = 1000.0
MAX_MAP_WOB = 2.0e6
MAX_GRID_LINES = 1000


@config_dataclass
class MapSettings:
    """How each grid point is simulated and classified."""

    #: Simulated seconds per point, from the kicked settled state.
    seconds: Positive = Field(default=30.0, le=3600.0)
    #: The last ``measure`` seconds decide: stick-slip if the bit sticks in them.
    measure: Positive = Field(default=10.0, le=3600.0)
    #: Seconds between two returns of the bit to its position. 0.02 s: the bit drills
    #: ~0.07 mm in between. At 0.5 s (until 2026-12-05) P1's bit, with the layer just
    #: below it, drilled into up to 2.2 % soft rock and jumped back twice a second, a
    #: forcing that made its map differ from P6's (both all in hard rock: 24 against
    #: 22 %; SSI 1.30 against 0.15 at 65 rpm / 95 kN); from 0.1 s down they agree.
    hold: Positive = Field(default=0.02, le=3600.0)
    #: Initial kick: the bit speed starts ``kick`` below steady (a 1 % disturbance).
    kick: NonNegative = Field(default=0.01, lt=1.0)
    #: Record every k simulator steps (the stick test reads these samples).
    record_every: Count = Field(default=5, ge=1, le=100_000)

    def __post_init__(self) -> None:
        for name in ("measure", "hold"):
            if getattr(self, name) > self.seconds:
                raise ValueError(f"{name}: must be <= seconds ({self.seconds}), got "
                                 f"{getattr(self, name)}")


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

    @classmethod
    def from_json(cls, d: dict) -> StabilityMap:
        """The map :meth:`to_json` wrote (``null`` boundaries read back as NaN)."""
        return cls(position=d["position"], rock2_share=float(d["rock2_share"]),
                   rpm=np.asarray(d["rpm"], dtype=float),
                   weight_on_bit=np.asarray(d["weight_on_bit"], dtype=float),
                   unstable=np.asarray(d["unstable"], dtype=np.bool_),
                   tested=np.asarray(d["tested"], dtype=np.int8),
                   boundary=np.asarray([np.nan if v is None else v for v in d["boundary"]],
                                       dtype=float),
                   runs=int(d["runs"]), wall_s=float(d["wall_s"]))


class BoundaryTracker:
    """The boundary tracking of the module docstring as a state machine over an
    (n_wob x n_rpm) grid: :meth:`next_point` says which point to simulate, :meth:`report`
    takes its verdict. A sweep can so run the next points of many maps at once."""

    def __init__(self, n_rpm: int, n_wob: int) -> None:
        if n_rpm < 1 or n_wob < 1:
            raise ValueError(f"grid: needs at least one speed and one WOB, got "
                             f"{n_rpm} x {n_wob}")
        self.n_rpm, self.n_wob = n_rpm, n_wob
        self.unstable = np.zeros((n_wob, n_rpm), dtype=np.bool_)
        self.tested = np.full((n_wob, n_rpm), -1, dtype=np.int8)
        self.i = self.j = 0

    def next_point(self) -> tuple[int, int] | None:
        """(speed index, WOB index) of the next point, or None when the map is done.
        Speeds past the last one reached (the WOB ran out) count as steady: the
        boundary rises with speed."""
        if self.i < self.n_rpm and self.j < self.n_wob:
            return self.i, self.j
        return None

    def points_left(self) -> int:
        """The most points the map can still need: each point moves one speed or one
        WOB on, and the map ends when either runs out."""
        if self.next_point() is None:
            return 0
        return (self.n_rpm - self.i) + (self.n_wob - self.j) - 1

    def report(self, stick_slip: bool) -> None:
        i, j = self.i, self.j
        if stick_slip:
            self.tested[j, i] = 1
            self.unstable[j:, i] = True  # rule 1: every higher WOB sticks too; next speed
            self.i += 1
        else:
            self.tested[j, i] = 0  # rule 2: only the WOB increases
            self.j += 1


def track_boundary(stick_slip: Callable[[int, int], bool], n_rpm: int, n_wob: int
                   ) -> tuple[np.ndarray, np.ndarray]:
    """:class:`BoundaryTracker` with ``stick_slip(i_rpm, j_wob)`` simulating each point.
    Returns ``(unstable, tested)`` as in :class:`StabilityMap`."""
    tracker = BoundaryTracker(n_rpm, n_wob)
    while (point := tracker.next_point()) is not None:
        tracker.report(stick_slip(*point))
    return tracker.unstable, tracker.tested


def check_map_corner(config, max_rpm: float, max_wob: float) -> None:
    """ValueError naming ``max_wob`` when one step at the map's highest speed and WOB
    already fails (a string buckled beyond what the mesh carries), before any point runs."""
    sim = Simulator(config)
    try:
        sim.reset(OperatingPoint(max_rpm * RPM, max_wob))
        sim.advance(1, max_rpm * RPM, sim.hook_load_for(max_wob), 0)
    except ValueError as err:
        raise ValueError(f"max_wob: {max_wob / 1e3:g} kN: {err}") from None
    if sim.status:
        raise ValueError(f"max_wob: {max_wob / 1e3:g} kN at {max_rpm:g} rpm: "
                         f"{sim.status_message}")


def point_sticks(config, rpm: float, weight_on_bit: float, settings: MapSettings
                 ) -> dict[str, float]:
    """Simulate one grid point, bit held at its position; its stick-slip metrics."""
    sim = Simulator(config)
    omega = rpm * RPM
    sim.reset(OperatingPoint(omega, weight_on_bit))
    sim.vt[-1] *= 1.0 - settings.kick  # steady rotation is an equilibrium; the kick tests it
    depth = sim.depth
    hook = sim.hook_load_for(weight_on_bit)
    every = settings.record_every
    if settings.measure < every * sim.dt:
        raise ValueError(f"measure: {settings.measure:g} s holds no sample: one is recorded "
                         f"every record_every x dt = {every} x {sim.dt:g} s")
    chunk = max(every, round(settings.hold / sim.dt) // every * every)
    # whole records only: a last partial chunk would run steps that no sample judges
    steps = -(-round(settings.seconds / sim.dt) // every) * every
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
    """Speeds (rpm) and WOBs (N) of the map, from one step up to the maximum; at most
    :data:`MAX_GRID_LINES` of each, up to :data:`MAX_MAP_RPM` and :data:`MAX_MAP_WOB`."""
    for name, value in (("rpm_step", rpm_step), ("wob_step", wob_step), ("max_rpm", max_rpm),
                        ("max_wob", max_wob)):
        require_positive(value, name)
    for name, step, top, unit, scale in (("rpm_step", rpm_step, max_rpm, "rpm", 1.0),
                                         ("wob_step", wob_step, max_wob, "kN", 1e3)):
        if step > top:
            raise ValueError(f"{name}: {step / scale:g} {unit} is more than the map's maximum "
                             f"({top / scale:g} {unit}): no line would fit")
    for name, value, cap, unit, scale in (("max_rpm", max_rpm, MAX_MAP_RPM, "rpm", 1.0),
                                          ("max_wob", max_wob, MAX_MAP_WOB, "kN", 1e3)):
        if value > cap:
            raise ValueError(f"{name}: at most {cap / scale:g} {unit}, got {value / scale:g}")
    for name, lines in (("rpm_step", max_rpm / rpm_step), ("wob_step", max_wob / wob_step)):
        if lines > MAX_GRID_LINES + 1e-9:
            raise ValueError(f"{name}: the map would have {lines:.3g} lines of points; at "
                             f"most {MAX_GRID_LINES} (a larger step)")
    rpm = np.arange(1, math.floor(max_rpm / rpm_step + 1e-9) + 1) * rpm_step
    wob = np.arange(1, math.floor(max_wob / wob_step + 1e-9) + 1) * wob_step
    return rpm, wob


def stability_map(position: str, rpm: Sequence[float], weight_on_bit: Sequence[float],
                  settings: MapSettings = DEFAULT_SETTINGS, config=None,
                  progress: Callable[[], None] | None = None) -> StabilityMap:
    """The map of one ``position`` (P1..P6) over the grid, serially (see
    :func:`stability_maps` for several maps, in parallel and resumable).

    ``config``: the simulation config (default: ``paper_case1`` at ``position``);
    ``progress``: called after every simulated point.
    """
    return stability_maps([position], settings=settings, grid_points=(rpm, weight_on_bit),
                          configs={position: config} if config is not None else None,
                          progress=progress or False, workers=1)[0]


def map_config(position: str, physics: dict[str, Any] | None = None):
    """``paper_case1`` at ``position``, with dotted physics overrides (a controller's
    top drive: ``{"top_drive.controller": "z_torque"}``)."""
    return with_physics(make_scenario("paper_case1", position=position).config, physics or {})


def _point_task(args: tuple) -> dict[str, float]:
    config, rpm, wob, settings = args
    return point_sticks(config, rpm, wob, settings)


def fingerprint(config, settings: MapSettings) -> str:
    """What a point's result depends on: the physics, how it is simulated and judged, and
    the code that does it (:func:`~drill_env.sweep.source_digest`)."""
    return digest({"config": jsonable(config), "settings": asdict(settings),
                   "code": source_digest("drill_env")})


def stability_maps(positions: Sequence[str] = tuple(POSITIONS), rpm_step: float = PAPER_RPM_STEP,
                   wob_step: float = PAPER_WOB_STEP, settings: MapSettings = DEFAULT_SETTINGS,
                   max_rpm: float = PAPER_MAX_RPM, max_wob: float = PAPER_MAX_WOB,
                   progress: bool | Callable[[], None] = False, *,
                   grid_points: tuple[Sequence[float], Sequence[float]] | None = None,
                   configs: dict[str, Any] | None = None, store: Path | None = None,
                   workers: int | None = 1, ray_address: str | None = None,
                   ) -> list[StabilityMap]:
    """The maps of ``positions`` on one grid, boundary tracking all of them in lockstep.

    Each round simulates the next point of every unfinished map at once, on ``workers``
    local processes (1: serially) or on Ray (``ray_address``); the results do not depend
    on the backend. ``store``: a JSON-lines file of finished points, appended as they
    arrive; a run with the same physics and settings skips the points already in it (an
    interrupted map resumes where it stopped). ``configs``: per position (default
    :func:`map_config`). ``progress``: True for a tqdm bar, or a function called after
    every simulated point (stored points are not simulated and do not call it).
    """
    if grid_points is None:
        rpm, wob = grid(rpm_step, wob_step, max_rpm, max_wob)
    else:
        rpm, wob = (np.asarray(g, dtype=float) for g in grid_points)
    if (twice := repeated(positions)) is not None:
        raise ValueError(f"positions: {twice} given twice")
    for position in positions:
        if position not in POSITIONS:
            raise ValueError(f"position: must be one of {sorted(POSITIONS)}, got "
                             f"{position!r}" + did_you_mean(str(position), list(POSITIONS)))
    configs = {p: (configs or {}).get(p) or map_config(p) for p in positions}
    for axis, values in (("speeds (rpm)", rpm), ("WOBs (N)", wob)):
        # the boundary tracking walks each axis upward from the lowest line
        if values.ndim != 1 or not (np.all(np.isfinite(values)) and np.all(values > 0.0)
                                    and np.all(np.diff(values) > 0.0)):
            raise ValueError(f"grid_points: the {axis} must be a list, finite, above 0 and "
                             f"strictly increasing, got {values.tolist()}")
    if not (len(rpm) and len(wob)):
        raise ValueError("grid_points: the map needs at least one speed and one WOB")
    for config in configs.values():
        check_map_corner(config, float(np.max(rpm)), float(np.max(wob)))
    prints = {p: fingerprint(configs[p], settings) for p in positions}
    results = ResultStore(store, "stability-map") if store is not None else None
    trackers = {p: BoundaryTracker(len(rpm), len(wob)) for p in positions}
    runs = dict.fromkeys(positions, 0)
    t0 = time.perf_counter()
    bar = None
    tick = progress if callable(progress) else None
    if progress is True:
        from drill_env.progress import progress_bar

        # the total is the most points the maps can still need (boundary tracking: one
        # row plus one column at most), lowered as they go; it ends at the points run ("at most"
        # in the bar: a new user read the falling total as a fault)
        bar = progress_bar(total=sum(t.points_left() for t in trackers.values()),
                           desc="  stability map (at most)", unit="point", leave=False)
        tick = bar.update
    executor = None  # started at the first point to simulate (a finished map needs none)
    try:
        while True:
            wanted = {p: ij for p, t in trackers.items() if (ij := t.next_point()) is not None}
            if not wanted:
                break
            keys = {p: f"{prints[p]}|{rpm[i]:g}|{wob[j]:g}" for p, (i, j) in wanted.items()}
            todo = [p for p in wanted if results is None or keys[p] not in results]
            found = {p: results.get(keys[p]) for p in wanted if p not in todo} \
                if results is not None else {}
            if bar is not None and found:
                bar.update(len(found))  # reused from the store: done as well
            tasks = [(configs[p], float(rpm[wanted[p][0]]), float(wob[wanted[p][1]]),
                      settings) for p in todo]
            if tasks:
                if executor is None:
                    executor = make_executor(workers, ray_address)
                # (bound now: the map is consumed, late results included, in this turn)
                def keep(k: int, result: dict[str, Any], todo: list[Any] = todo,
                         found: dict[Any, Any] = found, keys: dict[Any, Any] = keys) -> None:
                    p = todo[k]
                    found[p] = result
                    runs[p] += 1
                    if results is not None:
                        results.put(keys[p], result)
                    if tick is not None:
                        tick()

                # the results' iterator is not kept in a variable: an exception (an
                # interrupt) closes it at once, before the executor shuts down
                for k, result in executor.map_unordered(_point_task, tasks, late=keep):
                    keep(k, result)
            for p in wanted:
                trackers[p].report(found[p]["stuck_fraction"] > 0.0)
            if bar is not None:
                bar.total = bar.n + sum(t.points_left() for t in trackers.values())
                bar.refresh()
    finally:
        if executor is not None:
            executor.close()
        if bar is not None:
            bar.close()
    wall = time.perf_counter() - t0
    maps = []
    for p in positions:
        t = trackers[p]
        first = np.where(t.unstable.any(axis=0), t.unstable.argmax(axis=0), -1)
        boundary = np.where(first >= 0, wob[np.maximum(first, 0)], np.nan)
        maps.append(StabilityMap(p, POSITIONS[p][0], rpm, wob, t.unstable, t.tested, boundary,
                                 runs[p], wall))
    return maps


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


def plot_maps(maps: Sequence[StabilityMap], path: Path, controller: str = "stiff",
              source: str | None = None) -> Path:
    """Fig. 15 style: one panel per position, the stick-slip zone shaded, simulated
    points marked (x steady, o stick-slip); ``source``: the config file named in the
    title."""
    fig = maps_figure(maps, controller, source)
    path.parent.mkdir(parents=True, exist_ok=True)
    save_whole(path, lambda file: fig.savefig(file, dpi=120))
    return path


def maps_figure(maps: Sequence[StabilityMap], controller: str = "stiff",
                source: str | None = None) -> Any:
    """The matplotlib ``Figure`` of :func:`plot_maps`, laid out (not pyplot's: the
    process's backend is left as it is)."""
    import matplotlib

    from drill_env.figures import agg_figure

    cols = min(3, len(maps))
    rows = math.ceil(len(maps) / cols)
    # one map alone gets more room: at 4.2 x 3.4 in its three-line title took a third of
    # the picture (a check of the pictures)
    width, height = (4.2, 3.4) if cols > 1 else (6.0, 4.8)
    fig = agg_figure(figsize=(width * cols, height * rows))
    axes = fig.subplots(rows, cols, squeeze=False, sharex=True, sharey=True)
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
    for k in range(len(maps), rows * cols):  # an empty place: the map above it shows
        axes.flat[k].set_visible(False)      # the speed axis (sharex hid its labels)
        above = axes.flat[k - cols]
        above.xaxis.set_tick_params(labelbottom=True)
        above.set_xlabel("rotary speed (rpm)")
    from matplotlib.patches import Patch

    handles, _ = axes.flat[0].get_legend_handles_labels()
    reds = matplotlib.colormaps["Reds"]  # the colours pcolormesh gives unstable = 1 and 0
    handles.append(Patch(color=reds(1.0 / 2.5), label="stick-slip zone (inferred)"))
    handles.append(Patch(facecolor=reds(0.0), edgecolor="0.6", linewidth=0.5,
                         label="steady zone (inferred)"))
    ncol = 4 if cols > 1 else 2  # one panel's width holds two entries a line
    fig.legend(handles=handles, loc="lower center", ncol=ncol, fontsize=7, frameon=False)
    title = ("Torsional stability maps by boundary tracking (paper Fig. 15), "
             f"{controller} top drive" + (f", {Path(source).name}" if source else ""))
    # ~11 characters of the 12 pt title per inch: one panel's width holds half of it
    fig.suptitle(textwrap.fill(title, width=int(11 * width * cols)))
    # the legend below the maps: its lines' height over the figure's
    fig.tight_layout(rect=(0.0, 0.24 / fig.get_figheight() * (4 // ncol), 1.0, 1.0))
    return fig


def map_stem(controller: str = "stiff", source: str | None = None) -> str:
    """The file name of a controller's maps, without suffix: ``stability_map`` for the
    stiff PI (the paper's), ``stability_map_<controller>`` for the others, and
    ``_<config file's stem>`` after it for a string of your own (``source``), so maps of
    several controllers and strings written to one folder do not overwrite each other."""
    stem = "stability_map" if controller == "stiff" else f"stability_map_{controller}"
    return stem + (f"_{Path(source).stem}" if source else "")


def write_maps(maps: Sequence[StabilityMap], out: Path, settings: MapSettings,
               controller: str = "stiff", physics: dict[str, Any] | None = None,
               source: str | None = None) -> list[Path]:
    """``<stem>.json`` and ``<stem>.png`` in ``out`` (stem: ``map_stem``). The maps of
    other positions already in that file join them (:func:`kept_maps`), so maps made a
    few positions at a time add up to one file and one picture. ``physics``: the config
    overrides the maps were made under (a string of your own), named ``source`` (its
    file) in the title."""
    out.mkdir(parents=True, exist_ok=True)
    json_path = out / f"{map_stem(controller, source)}.json"
    maps = sorted([*maps, *kept_maps(json_path, maps, settings, controller, physics, source)],
                  key=lambda m: list(POSITIONS).index(m.position))
    # the units of the keys that name none (as modes.json and a well's JSON say theirs:
    # a drilling engineer's check)
    units = {"settings": {"seconds": "s", "measure": "s", "hold": "s", "kick": "1 (share "
                          "of the steady bit speed)", "record_every": "simulator steps"},
             "maps": {"rock2_share": "1", "rpm": "rpm", "weight_on_bit": "N",
                      "boundary": "N (lowest stick-slip WOB per speed; null: none)",
                      "unstable": "bool [wob][rpm]", "tested": "-1 not simulated, 0 steady, "
                      "1 stick-slip [wob][rpm]", "wall_s": "s"}}
    data = {"settings": asdict(settings), "controller": controller,
            "physics": jsonable(physics or {}), "config": source,
            "code": source_digest("drill_env"), "units": units,
            "maps": [m.to_json() for m in maps]}
    save_text(json_path, json.dumps(data, indent=1))
    return [json_path, plot_maps(maps, out / f"{map_stem(controller, source)}.png",
                                 controller, source)]


def kept_maps(path: Path, maps: Sequence[StabilityMap], settings: MapSettings,
              controller: str, physics: dict[str, Any] | None = None,
              source: str | None = None) -> list[StabilityMap]:
    """The maps in ``path`` of positions ``maps`` lacks, where they were made by the same
    controller under the same physics and code with the same settings on the same grid
    (else they do not belong in one picture and are replaced); [] without a readable
    file."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
        old = [StabilityMap.from_json(d) for d in data["maps"]]
    except (OSError, ValueError, KeyError, TypeError):
        return []
    if data.get("controller") != controller or data.get("settings") != jsonable(asdict(settings)) \
            or data.get("physics", {}) != jsonable(physics or {}) \
            or data.get("config") != source or not maps \
            or data.get("code") != source_digest("drill_env"):  # maps of older code
        return []
    new = {m.position for m in maps}
    return [m for m in old if m.position not in new and m.position in POSITIONS
            and np.array_equal(m.rpm, maps[0].rpm)
            and np.array_equal(m.weight_on_bit, maps[0].weight_on_bit)]


#: The speeds format_maps samples the boundary at, where the grid has them all.
SUMMARY_RPM = (25.0, 50.0, 100.0, 150.0)


def summary_speeds(rpm: np.ndarray) -> tuple[float, ...]:
    """The speeds the table samples: :data:`SUMMARY_RPM` where the grid holds each of
    them, else four of the grid's own speeds spread evenly over its columns (a 30 rpm
    grid printed "-" in every column)."""
    if all(np.isclose(rpm, r).any() for r in SUMMARY_RPM):
        return SUMMARY_RPM
    picks = np.unique(np.round(np.linspace(0, rpm.size - 1, min(4, rpm.size))).astype(int))
    return tuple(float(rpm[k]) for k in picks)


def format_maps(maps: Sequence[StabilityMap]) -> str:
    """A table a person can read: per position, unstable share and boundary samples at
    the speeds :func:`summary_speeds` picks from the first map's grid."""
    speeds = summary_speeds(maps[0].rpm) if maps else SUMMARY_RPM
    lines = ["position  rock 2  unstable  runs  grid   boundary WOB (kN) at "
             + "/".join(f"{r:g}" for r in speeds) + " rpm", "-" * 80]
    for m in maps:
        samples = []
        for r in speeds:
            k = np.flatnonzero(np.isclose(m.rpm, r))
            value = m.boundary[k[0]] if k.size else np.nan
            samples.append("-" if not k.size else ("none" if math.isnan(value)
                                                    else f"{value / 1e3:g}"))
        lines.append(f"{m.position:<9} {m.rock2_share:>5.0%}  {m.unstable_fraction:>7.0%}  "
                     f"{m.runs:>4}  {m.unstable.size:>5}   {' / '.join(samples)}")
    lines += ["boundary: the lowest WOB that stick-slips at that speed; none: no WOB of "
              "the grid does;", "-: that speed is not on the grid; runs: simulated now "
              "(points stored by an earlier run are reused)"]
    return "\n".join(lines)
