"""Sections ``core`` (the simulator against NumPy) and ``scaling`` (cost against DOFs)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from drill_env.physics import config as physics_config
from drill_env.physics.config import SimulationConfig, replace
from drill_env.physics.simulator import Simulator
from drill_env.physics.units import RPM
from drill_env.sweep import save_whole
from drill_env.tools.speed.common import (
    SETUP_WARNING,
    SURFACE_SPEED,
    WEIGHT_ON_BIT,
    BenchmarkSettings,
    best_time,
    fidelity_levels,
    one_numba_thread,
    ratio,
    recorded_warnings,
    settled_simulator,
    table,
    time_simulators,
)


def bench_core(settings: BenchmarkSettings, progress: bool = True) -> dict[str, Any]:
    """Default simulator on one numba thread, per fidelity level, against NumPy."""
    from drill_env.physics.reference import ReferenceStepper

    result: dict[str, Any] = {"weight_on_bit_N": WEIGHT_ON_BIT,
                              "surface_speed_rad_s": SURFACE_SPEED, "numba_threads": 1}
    sims: dict[str, Simulator] = {}
    caught: dict[str, list[str]] = {}
    for name, override in fidelity_levels().items():
        caught[name] = []
        with recorded_warnings(caught[name]):
            sims[name] = settled_simulator(replace(SimulationConfig(), **override),
                                            WEIGHT_ON_BIT, settings.warmup_steps)
    with one_numba_thread():
        figures = time_simulators(sims, WEIGHT_ON_BIT, settings.core_seconds,
                                   settings.repeats, "core", progress)
    result["fidelity"] = {name: {**figures[name], "warnings": caught[name]} for name in sims}

    # The NumPy stepper integrates the full model; it starts from the full simulator's state.
    base = sims.get("full") or next(iter(sims.values()))
    hook = base.hook_load_for(WEIGHT_ON_BIT)
    ref = ReferenceStepper(base)
    ref.advance(2, SURFACE_SPEED, hook)  # factorise
    chunk = max(1, settings.reference_steps // settings.repeats)
    repeats = max(1, settings.reference_steps // chunk)
    wall = best_time(lambda: ref.advance(chunk, SURFACE_SPEED, hook), repeats)
    ref_per_step = wall / chunk
    result["reference"] = {
        "steps": chunk * repeats,
        "n_dof": 5 * base.n_nodes,
        "time_step_s": base.dt,
        "us_per_step": ref_per_step * 1e6,
        "ns_per_dof_step": ref_per_step / (5 * base.n_nodes) * 1e9,
        "real_time_factor": base.dt / ref_per_step,
    }
    # In simulated seconds per wall second: a coarser level may take longer steps.
    for fig in result["fidelity"].values():
        fig["speedup_over_numpy"] = fig["real_time_factor"] / result["reference"][
            "real_time_factor"]
    if {"full", "fast"} <= set(result["fidelity"]):
        result["fast_over_full_speed"] = ratio(
            result["fidelity"]["fast"]["real_time_factor"],
            result["fidelity"]["full"]["real_time_factor"])
    return result


def format_core(result: dict[str, Any]) -> str:
    ref = result["reference"]
    rows = []
    for name, fig in result["fidelity"].items():
        rows.append((f"numba, {name}", fig["n_dof"], f"{fig['time_step_s'] * 1e3:.3g}",
                     f"{fig['us_per_step']:.2f}",
                     f"{fig['ns_per_dof_step']:.1f}", f"{fig['real_time_factor']:.1f}",
                     f"{fig['speedup_over_numpy']:.0f}"))
    rows.append(("NumPy reference (full)", result["reference"]["n_dof"],
                 f"{ref['time_step_s'] * 1e3:.3g}", f"{ref['us_per_step']:.0f}",
                 f"{ref['ns_per_dof_step']:.0f}",
                 f"{ref['real_time_factor']:.2f}", "1"))
    note = (f"paper string, Simulator()'s default (1000 m DP + 35 m BHA), mesoscopic bit, "
            f"contact on; "
            f"{result['weight_on_bit_N'] / 1e3:.0f} kN, "
            f"{result['surface_speed_rad_s'] / RPM:.0f} rpm; one numba thread; best of "
            f"repeats; x NumPy compares real-time factors (a level may step longer)")
    for name, fig in result["fidelity"].items():
        for message in fig.get("warnings", []):
            note += f"\n{name}: {SETUP_WARNING}: {message}"
    if "fast_over_full_speed" in result:
        note += (f"\nfast / full real-time factor: {result['fast_over_full_speed']:.2f} x "
                 f"(DOFs: 5 per node, whether the level moves them or not)")
    return table("Core simulator", ("stepper", "DOFs", "dt ms", "us/step", "ns/DOF/step",
                                     "x real time", "x NumPy"), rows, note)



# --------------------------------------------------------------------------- scaling


def _scaling_config(pipe_length: float, element_length: float) -> SimulationConfig:
    return replace(SimulationConfig(), **{"string.drill_pipe.length": float(pipe_length),
                                          "string.drill_pipe.element_length":
                                              float(element_length)})


def bench_scaling(settings: BenchmarkSettings, progress: bool = True) -> dict[str, Any]:
    """us/step against string length and element count; a straight-line fit against DOFs."""
    default = physics_config.StringConfig().drill_pipe
    sweeps = [("length", (length, default.element_length)) for length in settings.pipe_lengths]
    sweeps += [("mesh", (settings.mesh_pipe_length, el))
               for el in settings.pipe_element_lengths]
    wob = settings.scaling_weight_on_bit
    sims: dict[tuple[float, float], Simulator] = {}
    for _, key in sweeps:
        if key not in sims:
            sims[key] = settled_simulator(_scaling_config(*key), wob, settings.warmup_steps)
    with one_numba_thread():
        figures = time_simulators(sims, wob, settings.scaling_seconds, settings.repeats,
                                   "scaling", progress)
    points = {key: {"pipe_length_m": key[0], "pipe_element_length_m": key[1],
                    "string_length_m": sim.config.string.length,
                    "sweeps": [sweep for sweep, k in sweeps if k == key], **figures[key]}
              for key, sim in sims.items()}

    rows: list[dict[str, Any]] = sorted(points.values(), key=lambda p: int(p["n_dof"]))
    ref_key = (default.length, default.element_length)
    ref = points.get(ref_key, rows[0])
    for p in rows:
        p["cost_over_reference"] = p["us_per_step"] / ref["us_per_step"]
    n_dof = np.array([p["n_dof"] for p in rows], dtype=float)
    cost = np.array([p["us_per_step"] for p in rows])
    per_dof = np.array([p["ns_per_dof_step"] for p in rows])
    fit: dict[str, float] = {}
    if len(np.unique(n_dof)) >= 2:
        slope, intercept = np.polyfit(n_dof, cost, 1)
        predicted = intercept + slope * n_dof
        ss_res = float(np.sum((cost - predicted) ** 2))
        ss_tot = float(np.sum((cost - cost.mean()) ** 2))
        fit = {"us_per_step_intercept": float(intercept),
               "ns_per_dof_step_slope": float(slope * 1e3),
               "r_squared": 1.0 - ss_res / ss_tot if ss_tot > 0 else 1.0}
    fit["cost_per_dof_max_over_min"] = float(per_dof.max() / per_dof.min())
    return {"weight_on_bit_N": wob, "surface_speed_rad_s": SURFACE_SPEED,
            "reference": {"pipe_length_m": ref["pipe_length_m"],
                          "pipe_element_length_m": ref["pipe_element_length_m"]},
            "points": rows, "fit": fit}


def format_scaling(result: dict[str, Any]) -> str:
    rows = []
    for p in result["points"]:
        rows.append(("+".join(p["sweeps"]), f"{p['pipe_length_m']:.0f}",
                     f"{p['pipe_element_length_m']:g}", p["n_dof"],
                     f"{p['us_per_step']:.1f}", f"{p['ns_per_dof_step']:.1f}",
                     f"{p['cost_over_reference']:.2f}", f"{p['real_time_factor']:.0f}"))
    fit = result["fit"]
    ref = result["reference"]
    note = (f"WOB {result['weight_on_bit_N'] / 1e3:.0f} kN (every mesh here resolves it; "
            f"the default 100 kN buckles 20 m pipe elements), "
            f"{result['surface_speed_rad_s'] / RPM:.0f} rpm, 35 m BHA, one numba thread; "
            f"x ref: against {ref['pipe_length_m']:.0f} m / "
            f"{ref['pipe_element_length_m']:g} m elements")
    if "r_squared" in fit:
        note += (f"\nleast squares: us/step = {fit['us_per_step_intercept']:.2f} + "
                 f"{fit['ns_per_dof_step_slope']:.2f} ns x DOFs, R^2 = {fit['r_squared']:.4f}")
    note += f"\ncost per DOF, max / min: {fit['cost_per_dof_max_over_min']:.2f}"
    return table("Cost scaling", ("sweep", "DP m", "DP elem m", "DOFs", "us/step",
                                   "ns/DOF/step", "x ref", "x real time"), rows, note)


def plot_scaling(result: dict[str, Any], path: Path) -> Path | None:
    """us/step and ns/DOF/step against DOFs, with the fitted line."""
    from drill_env.figures import agg_figure

    pts = result["points"]
    fig = agg_figure(figsize=(10, 4))
    axes = fig.subplots(1, 2)
    for sweep, marker in (("length", "o"), ("mesh", "s")):
        sel = [p for p in pts if sweep in p["sweeps"]]
        label = "string length" if sweep == "length" else "element length"
        axes[0].plot([p["n_dof"] for p in sel], [p["us_per_step"] for p in sel], marker,
                     fillstyle="none", ms=8, label=f"sweep: {label}")
        axes[1].plot([p["n_dof"] for p in sel], [p["ns_per_dof_step"] for p in sel], marker,
                     fillstyle="none", ms=8, label=f"sweep: {label}")
    fit = result["fit"]
    if "r_squared" in fit:
        x = np.linspace(0, max(p["n_dof"] for p in pts) * 1.05, 50)
        axes[0].plot(x, fit["us_per_step_intercept"] + fit["ns_per_dof_step_slope"] * 1e-3 * x,
                     "k--", lw=1, label=f"fit, R$^2$ = {fit['r_squared']:.4f}")
    axes[0].set_ylabel("wall time per step (us)")
    axes[1].set_ylabel("wall time per DOF per step (ns)")
    # headroom: a marker on the largest value would otherwise be cut by the frame
    axes[1].set_ylim(0.0, 1.1 * max(p["ns_per_dof_step"] for p in pts))
    for ax, corner in zip(axes, ("upper left", "lower left"), strict=True):  # empty corners
        ax.set_xlabel("DOFs (5 per node)")
        ax.set_xlim(left=0)
        ax.legend(loc=corner, fontsize=8)
        ax.grid(alpha=0.3)
    axes[0].set_ylim(bottom=0)
    fig.suptitle(f"Simulator cost scaling, one numba thread, WOB "
                 f"{result['weight_on_bit_N'] / 1e3:.0f} kN", fontsize=10)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    save_whole(path, lambda file: fig.savefig(file, dpi=110))
    return path


