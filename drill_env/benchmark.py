"""Speed and memory figures of the simulator and the environment (``drill-env benchmark``).

Five sections, each printed as a table and saved under one key of ``benchmark.json``:

core      real-time factor, us per step and ns per DOF per step of the default
          simulator (1000 m drill pipe + 35 m BHA, mesoscopic bit, wall contact on) on ONE
          numba thread; the plain NumPy stepper (:mod:`drill_env.physics.reference`) on a
          short run; the speed-up numba / NumPy.
env       env steps/s at the default 10 Hz policy rate: one env, N single envs looped in
          one process, the batched :class:`~drill_env.vector.DrillStringVectorEnv`; the
          Python share of a single env step (env.step minus the time inside
          ``Simulator.advance``).
scaling   us per step against string length and against element count at fixed length,
          with a least-squares line of cost against DOFs (R^2) and the spread of the cost
          per DOF; a PNG of it next to the JSON.
compile   first import to first env step in a fresh process with numba's cache cold and
          then warm (``NUMBA_CACHE_DIR`` pointing at a new temporary folder).
memory    bytes of one simulator's NumPy arrays and the RSS growth per env over 64 envs,
          measured in a fresh process.

The machines this runs on are shared and noisy, so every figure comes with a ratio
against a reference measured in the same run (the NumPy stepper, a single env, the
default mesh, the warm start, the simulator's own arrays): ratios survive a busy machine
better than absolute times. Timed loops report the best of several repeats.

When the simulator config has a ``fidelity`` field (``SolverConfig`` or
``SimulationConfig``), the core and env sections run once per fidelity level and report
the fast / full ratio.

Use ``drill-env benchmark [--quick] [--sections core,env] [--out logs]`` or
:func:`run_benchmark`.
"""

from __future__ import annotations

import contextlib
import dataclasses
import datetime
import gc
import json
import math
import os
import platform
import subprocess
import sys
import tempfile
import textwrap
import time
import warnings
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from drill_env.physics import config as physics_config
from drill_env.physics.config import SimulationConfig, SolverConfig, replace
from drill_env.physics.simulator import OperatingPoint, Simulator
from drill_env.physics.units import RPM

SECTIONS = ("core", "env", "scaling", "compile", "memory")

#: Operating point of the core and env figures: the default case of the demo.
SURFACE_SPEED = 60 * RPM
WEIGHT_ON_BIT = 100e3
#: Fidelity levels the simulator may offer, in the order they are reported.
KNOWN_FIDELITIES = ("full", "fast")


@dataclass(frozen=True)
class BenchmarkSettings:
    """Sizes of the timed runs. :data:`FULL` is the default, :data:`QUICK` a smoke test."""

    #: Simulated seconds per timed repeat of the core simulator.
    core_seconds: float = 60.0
    #: Timed repeats of each core and scaling run; the best one is reported.
    repeats: int = 5
    #: Simulator steps run (untimed) before timing: compilation and the initial state.
    warmup_steps: int = 2000
    #: Steps of the NumPy reference stepper (about 2 ms each on the default string).
    reference_steps: int = 200
    #: Timed steps of the single env (also used for the Python-overhead share).
    env_steps: int = 300
    #: Untimed env steps (calls, for the looped and batched envs) before timing: an
    #: episode's first ``metric_window`` (3 s = 30 steps) fills the metric history.
    env_warmup_steps: int = 40
    #: Env steps per configuration of the looped and batched envs (rounded up to whole
    #: calls of N envs, at least ``min_env_calls`` calls).
    env_batch_steps: int = 1500
    min_env_calls: int = 5
    env_counts: tuple[int, ...] = (1, 4, 16, 64)
    #: Drill-pipe lengths (m) of the length sweep, at the default element length.
    pipe_lengths: tuple[float, ...] = (500.0, 1000.0, 2000.0, 5000.0)
    #: Drill-pipe element lengths (m) of the mesh sweep, at ``mesh_pipe_length``.
    pipe_element_lengths: tuple[float, ...] = (20.0, 10.0, 5.0, 2.5)
    mesh_pipe_length: float = 1000.0
    #: Simulated seconds per timed repeat of each scaling point.
    scaling_seconds: float = 20.0
    #: WOB of the scaling runs (N): 100 kN compresses 20 m pipe elements beyond their own
    #: buckling load (``Simulator.check_mesh_resolves``), 60 kN is resolved by every mesh.
    scaling_weight_on_bit: float = 60e3
    #: Envs built for the memory figure.
    memory_envs: int = 64

    def __post_init__(self) -> None:
        for name in ("core_seconds", "scaling_seconds", "scaling_weight_on_bit",
                     "mesh_pipe_length"):
            physics_config.require_positive(getattr(self, name), name)
        for name in ("repeats", "reference_steps", "env_steps", "env_warmup_steps",
                     "env_batch_steps",
                     "min_env_calls", "memory_envs"):
            value = getattr(self, name)
            if not isinstance(value, int) or value < 1:
                raise ValueError(f"{name}: must be a positive integer, got {value!r}")
        if not isinstance(self.warmup_steps, int) or self.warmup_steps < 0:
            raise ValueError(f"warmup_steps: must be a non-negative integer, "
                             f"got {self.warmup_steps!r}")
        for name in ("env_counts", "pipe_lengths", "pipe_element_lengths"):
            values = getattr(self, name)
            if not values or any(not v > 0 for v in values):
                raise ValueError(f"{name}: needs positive values, got {values!r}")


FULL = BenchmarkSettings()
QUICK = BenchmarkSettings(
    core_seconds=2.0, repeats=2, warmup_steps=200, reference_steps=10, env_steps=40,
    env_batch_steps=64, min_env_calls=2, env_counts=(1, 4, 16), pipe_lengths=(500.0, 1000.0,
                                                                              2000.0),
    pipe_element_lengths=(20.0, 10.0, 5.0), scaling_seconds=1.0, memory_envs=8)


# --------------------------------------------------------------------------- helpers


def fidelity_levels() -> dict[str, dict[str, str]]:
    """Fidelity levels the simulator offers: name -> dotted physics override.

    Looks for a ``fidelity`` field on ``SolverConfig`` (then ``SimulationConfig``) and
    keeps the levels of :data:`KNOWN_FIDELITIES` (and of a ``FIDELITY_LEVELS`` tuple in
    the config module, if there is one) that the config accepts. Without the field: only
    "full", with no override.
    """
    for prefix, cls in (("solver.", SolverConfig), ("", SimulationConfig)):
        if "fidelity" not in {f.name for f in dataclasses.fields(cls)}:
            continue
        declared = tuple(getattr(physics_config, "FIDELITY_LEVELS", ())) + tuple(
            getattr(physics_config, "FIDELITIES", ()))
        names = list(dict.fromkeys((*KNOWN_FIDELITIES, *declared)))
        levels = {}
        for name in names:
            override = {f"{prefix}fidelity": name}
            try:
                replace(SimulationConfig(), **override)
            except (ValueError, TypeError):
                continue
            levels[name] = override
        if levels:
            return levels
    return {"full": {}}


def _progress(items: Iterable, desc: str, enabled: bool) -> Iterator:
    """tqdm over ``items`` when installed and enabled; plain prints otherwise."""
    items = list(items)
    if not enabled:
        yield from items
        return
    try:
        from tqdm import tqdm
    except ImportError:
        for k, item in enumerate(items):
            print(f"  {desc}: {k + 1}/{len(items)}", file=sys.stderr, flush=True)
            yield item
        return
    yield from tqdm(items, desc=f"  {desc}", leave=False, file=sys.stderr)


@contextlib.contextmanager
def _recorded_warnings(into: list[str]) -> Iterator[None]:
    """Collect the messages of warnings raised inside (each once) into ``into``: a
    benchmark runs models outside their validity on purpose (same operating point for
    every level) and says so in its table instead of on stderr."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        yield
    for w in caught:
        message = str(w.message)
        if message not in into:
            into.append(message)


def _best_time(run: Callable[[], Any], repeats: int) -> float:
    """Shortest wall time of ``repeats`` calls: the least disturbed by other processes."""
    best = math.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        run()
        best = min(best, time.perf_counter() - t0)
    return best


def _ratio(a: float, b: float) -> float:
    return a / b if b > 0 else math.nan


def _table(title: str, header: tuple[str, ...], rows: list[tuple], note: str = "") -> str:
    """A plain text table: first column left-aligned, the others right-aligned."""
    cells = [[str(c) for c in header]] + [[str(c) for c in row] for row in rows]
    widths = [max(len(r[k]) for r in cells) for k in range(len(header))]

    def line(r: list[str]) -> str:
        return "  ".join(c.ljust(w) if k == 0 else c.rjust(w)
                         for k, (c, w) in enumerate(zip(r, widths, strict=True))).rstrip()

    out = [title, line(cells[0]), "-" * len(line(cells[0]))]
    out += [line(r) for r in cells[1:]]
    width = max(len(out[1]), 88)
    for paragraph in note.splitlines():
        out.append(textwrap.fill(paragraph, width, subsequent_indent="  "))
    return "\n".join(out)


def _settled_simulator(config: SimulationConfig, weight_on_bit: float,
                       warmup_steps: int) -> Simulator:
    sim = Simulator(config)
    sim.reset(OperatingPoint(SURFACE_SPEED, weight_on_bit))
    sim.advance(max(warmup_steps, 1), SURFACE_SPEED, sim.hook_load_for(weight_on_bit))
    return sim


def _time_simulators(sims: dict[Any, Simulator], weight_on_bit: float, seconds: float,
                     repeats: int, desc: str, progress: bool) -> dict[Any, dict[str, float]]:
    """Best-of-``repeats`` wall time of ``seconds`` simulated by each simulator (records
    every 10 steps, as the env does).

    The simulators take turns repeat by repeat, so a burst of load from another process
    hits them alike instead of spoiling one of them.
    """
    best = dict.fromkeys(sims, math.inf)
    n_steps = {key: max(1, round(seconds / sim.dt)) for key, sim in sims.items()}
    for _ in _progress(range(repeats), desc, progress):
        for key, sim in sims.items():
            hook = sim.hook_load_for(weight_on_bit)
            t0 = time.perf_counter()
            sim.advance(n_steps[key], SURFACE_SPEED, hook, record_every=10)
            best[key] = min(best[key], time.perf_counter() - t0)
            if sim.status != 0:
                raise RuntimeError(f"benchmark run failed: {sim.status_message}")
    figures = {}
    for key, sim in sims.items():
        per_step = best[key] / n_steps[key]
        n_dof = 5 * sim.n_nodes
        figures[key] = {
            "n_nodes": sim.n_nodes,
            "n_dof": n_dof,
            "time_step_s": sim.dt,
            "simulated_s": n_steps[key] * sim.dt,
            "wall_s": best[key],
            "real_time_factor": n_steps[key] * sim.dt / best[key],
            "us_per_step": per_step * 1e6,
            "ns_per_dof_step": per_step / n_dof * 1e9,
        }
    return figures


@contextlib.contextmanager
def _one_numba_thread() -> Iterator[None]:
    import numba

    threads = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        yield
    finally:
        numba.set_num_threads(threads)


def source_stamp() -> float:
    """Latest modification time of the package's sources: numba's cache (and every figure)
    belongs to one version of them, so a change during a run invalidates it."""
    root = Path(__file__).resolve().parent
    return max(p.stat().st_mtime for p in root.rglob("*.py"))


def _cpu_name() -> str:
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _machine() -> dict[str, Any]:
    import numba

    info: dict[str, Any] = {
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "cpu": _cpu_name(),
        "cpu_count": os.cpu_count(),
        "platform": platform.platform(),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "numba": numba.__version__,
    }
    if hasattr(os, "getloadavg"):
        info["load_average_1min"] = os.getloadavg()[0]
    root = Path(__file__).resolve().parents[1]
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=root,
                                capture_output=True, text=True, timeout=10, check=True)
        dirty = subprocess.run(["git", "status", "--porcelain"], cwd=root,
                               capture_output=True, text=True, timeout=10, check=True)
        info["git_commit"] = commit.stdout.strip() + ("+dirty" if dirty.stdout.strip() else "")
    except (OSError, subprocess.SubprocessError):
        pass
    return info


# --------------------------------------------------------------------------- core


def bench_core(settings: BenchmarkSettings, progress: bool = True) -> dict[str, Any]:
    """Default simulator on one numba thread, per fidelity level, against NumPy."""
    from drill_env.physics.reference import ReferenceStepper

    result: dict[str, Any] = {"weight_on_bit_N": WEIGHT_ON_BIT,
                              "surface_speed_rad_s": SURFACE_SPEED, "numba_threads": 1}
    sims, caught = {}, {}
    for name, override in fidelity_levels().items():
        caught[name] = []
        with _recorded_warnings(caught[name]):
            sims[name] = _settled_simulator(replace(SimulationConfig(), **override),
                                            WEIGHT_ON_BIT, settings.warmup_steps)
    with _one_numba_thread():
        figures = _time_simulators(sims, WEIGHT_ON_BIT, settings.core_seconds,
                                   settings.repeats, "core", progress)
    result["fidelity"] = {name: {**figures[name], "warnings": caught[name]} for name in sims}

    # The NumPy stepper integrates the full model; it starts from the full simulator's state.
    base = sims.get("full") or next(iter(sims.values()))
    hook = base.hook_load_for(WEIGHT_ON_BIT)
    ref = ReferenceStepper(base)
    ref.advance(2, SURFACE_SPEED, hook)  # factorise
    chunk = max(1, settings.reference_steps // settings.repeats)
    repeats = max(1, settings.reference_steps // chunk)
    wall = _best_time(lambda: ref.advance(chunk, SURFACE_SPEED, hook), repeats)
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
        result["fast_over_full_speed"] = _ratio(
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
    note = (f"default string (1000 m DP + 35 m BHA), mesoscopic bit, contact on; "
            f"{result['weight_on_bit_N'] / 1e3:.0f} kN, "
            f"{result['surface_speed_rad_s'] / RPM:.0f} rpm; one numba thread; best of "
            f"repeats; x NumPy compares real-time factors (a level may step longer)")
    for name, fig in result["fidelity"].items():
        for message in fig.get("warnings", []):
            note += f"\n{name}: warning: {message}"
    if "fast_over_full_speed" in result:
        note += (f"\nfast / full real-time factor: {result['fast_over_full_speed']:.2f} x "
                 f"(DOFs: 5 per node, whether the level moves them or not)")
    return _table("Core simulator", ("stepper", "DOFs", "dt ms", "us/step", "ns/DOF/step",
                                     "x real time", "x NumPy"), rows, note)


# --------------------------------------------------------------------------- env


def _interleaved_rates(steps: dict[str, tuple[Callable[[], Any], int]], env_steps: int,
                       rounds: int, warmup: int) -> dict[str, float]:
    """Env steps/s of each ``name -> (step function, envs per call)``: best of ``rounds``
    rounds of about ``env_steps / rounds`` env steps each, after ``warmup`` untimed calls.

    The functions take turns round by round, so a change of the machine's load hits them
    alike and their ratios hold better than those of back-to-back runs.
    """
    for step, _ in steps.values():
        for _ in range(warmup):
            step()
    calls = {name: max(1, math.ceil(env_steps / rounds / n)) for name, (_, n) in steps.items()}
    best = dict.fromkeys(steps, math.inf)
    for _ in range(rounds):
        for name, (step, _) in steps.items():
            t0 = time.perf_counter()
            for _ in range(calls[name]):
                step()
            best[name] = min(best[name], time.perf_counter() - t0)
    return {name: calls[name] * steps[name][1] / best[name] for name in steps}


def _make_env(override: dict[str, str]):
    import gymnasium as gym

    import drill_env  # noqa: F401  (registers the ids)

    kwargs: dict[str, Any] = {"episode_duration": 1e6}
    if override:
        kwargs["physics"] = dict(override)
    return gym.make("DrillString-v0", **kwargs)


def _sb3_vec_env(n: int, override: dict[str, str]):
    """The Stable-Baselines3 VecEnv of ``n`` envs, or None without SB3 installed."""
    try:
        from drill_env.vector import make_sb3_vec_env

        return make_sb3_vec_env(n, episode_duration=1e6,
                                **({"physics": dict(override)} if override else {}))
    except ImportError:
        return None


def _python_overhead(env, action: np.ndarray, n_steps: int) -> dict[str, float]:
    """Share of ``env.step`` spent outside ``Simulator.advance``, by wrapping the env's
    ``sim.advance`` in a timer."""
    sim = env.unwrapped.sim
    inside = 0.0
    advance = sim.advance

    def timed_advance(*args: Any, **kwargs: Any) -> np.ndarray:
        nonlocal inside
        t0 = time.perf_counter()
        out = advance(*args, **kwargs)
        inside += time.perf_counter() - t0
        return out

    sim.advance = timed_advance  # instance attribute: shadows the method for this env only
    try:
        t0 = time.perf_counter()
        for _ in range(n_steps):
            _, _, terminated, truncated, _ = env.step(action)
            if terminated or truncated:
                raise RuntimeError("benchmark env episode ended; cannot time steady steps")
        total = time.perf_counter() - t0
    finally:
        del sim.advance
    return {
        "us_per_env_step": total / n_steps * 1e6,
        "us_in_simulator": inside / n_steps * 1e6,
        "simulator_steps_per_env_step": env.unwrapped._steps_per_action,
        "python_overhead_share": (total - inside) / total,
    }


def bench_env(settings: BenchmarkSettings, progress: bool = True) -> dict[str, Any]:
    """Env steps/s: one env, N envs looped, the batched vector env; per fidelity level.

    The one env is timed again beside each N (in the same rounds), and the ratios of that
    row use this same-time figure.
    """
    result: dict[str, Any] = {"cpu_count": os.cpu_count(), "fidelity": {}}
    for name, override in fidelity_levels().items():
        caught: list[str] = []
        with _recorded_warnings(caught):
            result["fidelity"][name] = _bench_env_level(override, settings, name, progress)
        result["fidelity"][name]["warnings"] = caught
    fid = result["fidelity"]
    if {"full", "fast"} <= set(fid):
        result["fast_over_full_single"] = _ratio(fid["fast"]["single"]["steps_per_s"],
                                                 fid["full"]["single"]["steps_per_s"])
        result["fast_over_full_batched"] = _ratio(
            fid["fast"]["counts"][-1]["batched_steps_per_s"],
            fid["full"]["counts"][-1]["batched_steps_per_s"])
    return result


def _bench_env_level(override: dict[str, str], settings: BenchmarkSettings, name: str,
                     progress: bool) -> dict[str, Any]:
    """One fidelity level of :func:`bench_env`."""
    from drill_env.vector import DrillStringVectorEnv

    action = np.zeros(2, dtype=np.float32)  # mid range: 100 rpm, 100 kN
    env = _make_env(override)
    env.reset(seed=0)
    single_step = (lambda env=env: env.step(action), 1)
    rate = _interleaved_rates({"single": single_step}, settings.env_steps,
                              settings.repeats, settings.env_warmup_steps)
    single = {"steps_per_s": rate["single"],
              **_python_overhead(env, action, settings.env_steps)}
    counts = []
    for n in _progress(settings.env_counts, f"env ({name})", progress):
        envs = [_make_env(override) for _ in range(n)]
        for i, e in enumerate(envs):
            e.reset(seed=i)
        vec = DrillStringVectorEnv(num_envs=n, episode_duration=1e6,
                                   **({"physics": dict(override)} if override else {}))
        vec.reset(seed=0)
        actions = np.zeros((n, 2), dtype=np.float32)
        env_steps = max(settings.env_batch_steps, n * settings.min_env_calls)
        steps = {"single": single_step,
                 "loop": (lambda envs=envs: [e.step(action) for e in envs], n),
                 "batched": (lambda vec=vec, a=actions: vec.step(a), n)}
        sb3 = _sb3_vec_env(n, override)
        if sb3 is not None:
            sb3.reset()
            steps["batched_sb3"] = (lambda sb3=sb3, a=actions: sb3.step(a), n)
        rates = _interleaved_rates(steps, env_steps, settings.repeats,
                                   settings.env_warmup_steps)
        for e in envs:
            e.close()
        vec.close()
        if sb3 is not None:
            sb3.close()
        counts.append({
            "num_envs": n,
            "env_steps": env_steps,
            "single_steps_per_s": rates["single"],
            "loop_steps_per_s": rates["loop"],
            "batched_steps_per_s": rates["batched"],
            "loop_over_single": _ratio(rates["loop"], rates["single"]),
            "batched_over_loop": _ratio(rates["batched"], rates["loop"]),
            "batched_over_single": _ratio(rates["batched"], rates["single"]),
            **({"batched_sb3_steps_per_s": rates["batched_sb3"],
                "batched_sb3_over_loop": _ratio(rates["batched_sb3"], rates["loop"]),
                "batched_sb3_over_single": _ratio(rates["batched_sb3"], rates["single"])}
               if "batched_sb3" in rates else {}),
        })
    env.close()
    return {"single": single, "counts": counts}


def format_env(result: dict[str, Any]) -> str:
    rows = []
    notes = []
    for name, fig in result["fidelity"].items():
        single = fig["single"]
        rows.append((f"{name}: one env", f"{single['steps_per_s']:.0f}", "1.00", ""))
        for c in fig["counts"]:
            n = c["num_envs"]
            envs = f"{n} envs" if n > 1 else "1 env"
            rows.append((f"{name}: {envs} looped", f"{c['loop_steps_per_s']:.0f}",
                         f"{c['loop_over_single']:.2f}", ""))
            rows.append((f"{name}: batched, N={n}", f"{c['batched_steps_per_s']:.0f}",
                         f"{c['batched_over_single']:.2f}", f"{c['batched_over_loop']:.2f}"))
            if "batched_sb3_steps_per_s" in c:
                rows.append((f"{name}: batched SB3 VecEnv, N={n}",
                             f"{c['batched_sb3_steps_per_s']:.0f}",
                             f"{c['batched_sb3_over_single']:.2f}",
                             f"{c['batched_sb3_over_loop']:.2f}"))
        notes.append(f"{name}: one env step = {single['simulator_steps_per_env_step']} "
                     f"simulator steps, {single['us_per_env_step']:.0f} us, of which "
                     f"{single['us_in_simulator']:.0f} us in Simulator.advance: Python "
                     f"overhead {single['python_overhead_share']:.0%}")
        notes += [f"{name}: warning: {m}" for m in fig.get("warnings", [])]
    if "fast_over_full_single" in result:
        notes.append(f"fast / full env steps/s: one env {result['fast_over_full_single']:.2f} x,"
                     f" batched (largest N) {result['fast_over_full_batched']:.2f} x")
    notes.append(f"10 Hz policy rate; batched: the Gymnasium VectorEnv (SB3 VecEnv: the "
                 f"Stable-Baselines3 one), one numba prange call over the envs, "
                 f"{result['cpu_count']} cores; x one env: against one env timed in the same "
                 f"rounds; best of repeats")
    return _table("Env throughput", ("configuration", "env steps/s", "x one env", "x loop"),
                  rows, "\n".join(notes))


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
            sims[key] = _settled_simulator(_scaling_config(*key), wob, settings.warmup_steps)
    with _one_numba_thread():
        figures = _time_simulators(sims, wob, settings.scaling_seconds, settings.repeats,
                                   "scaling", progress)
    points = {key: {"pipe_length_m": key[0], "pipe_element_length_m": key[1],
                    "string_length_m": sim.config.string.length,
                    "sweeps": [sweep for sweep, k in sweeps if k == key], **figures[key]}
              for key, sim in sims.items()}

    rows = sorted(points.values(), key=lambda p: p["n_dof"])
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
    return _table("Cost scaling", ("sweep", "DP m", "DP elem m", "DOFs", "us/step",
                                   "ns/DOF/step", "x ref", "x real time"), rows, note)


def plot_scaling(result: dict[str, Any], path: Path) -> Path | None:
    """us/step and ns/DOF/step against DOFs, with the fitted line; ``None`` without
    matplotlib."""
    try:
        import matplotlib
    except ImportError:
        return None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    pts = result["points"]
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
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
    axes[1].set_ylim(bottom=0)
    for ax in axes:
        ax.set_xlabel("DOFs (5 per node)")
        ax.set_xlim(left=0)
        ax.legend(loc="best", fontsize=8)
        ax.grid(alpha=0.3)
    axes[0].set_ylim(bottom=0)
    fig.suptitle(f"Simulator cost scaling, one numba thread, WOB "
                 f"{result['weight_on_bit_N'] / 1e3:.0f} kN", fontsize=10)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


# --------------------------------------------------------------------------- compile

_FIRST_STEP = """
import time
t0 = time.perf_counter()
import drill_env, gymnasium as gym
t1 = time.perf_counter()
e = gym.make("DrillString-v0")
t2 = time.perf_counter()
e.reset(seed=0)
e.step(e.action_space.sample())
t3 = time.perf_counter()
import json
print(json.dumps({"first_step_s": t3 - t0, "import_s": t1 - t0, "make_s": t2 - t1,
                  "reset_and_step_s": t3 - t2}))
"""


def _first_step(cache_dir: str) -> dict[str, float]:
    env = {**os.environ, "NUMBA_CACHE_DIR": cache_dir}
    t0 = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", _FIRST_STEP], env=env, capture_output=True,
                          text=True, timeout=900)
    wall = time.perf_counter() - t0
    if done.returncode != 0:
        raise RuntimeError(f"first-step subprocess failed:\n{done.stderr[-2000:]}")
    result = json.loads(done.stdout.strip().splitlines()[-1])
    result["process_wall_s"] = wall
    return result


def bench_compile(settings: BenchmarkSettings, progress: bool = True) -> dict[str, Any]:
    """Import to first env step in a fresh process, numba cache cold then warm."""
    stamp = source_stamp()
    with tempfile.TemporaryDirectory(prefix="drill-env-numba-cache-") as cache:
        runs = {}
        for state in _progress(("cold", "warm"), "compile", progress):
            runs[state] = _first_step(cache)
    return {**runs, "cold_over_warm": _ratio(runs["cold"]["first_step_s"],
                                             runs["warm"]["first_step_s"]),
            "sources_changed": source_stamp() != stamp}


def format_compile(result: dict[str, Any]) -> str:
    rows = [(state, f"{r['first_step_s']:.2f}", f"{r['import_s']:.2f}", f"{r['make_s']:.2f}",
             f"{r['reset_and_step_s']:.2f}", f"{r['process_wall_s']:.2f}")
            for state, r in ((s, result[s]) for s in ("cold", "warm"))]
    note = (f"cold / warm: {result['cold_over_warm']:.1f} x; seconds from the first import "
            f"in a fresh interpreter to the end of the first env step (process: including "
            f"interpreter start-up)")
    if result.get("sources_changed"):
        note += ("\nWARNING: drill_env sources changed between the cold and the warm run; "
                 "the warm run recompiled what changed, rerun for a valid figure")
    return _table("Compile time (fresh process)", ("numba cache", "first step s", "import s",
                                                   "make s", "reset+step s", "process s"),
                  rows, note)


# --------------------------------------------------------------------------- memory


def array_bytes(obj: Any) -> int:
    """Bytes of the NumPy arrays held by ``obj``'s attributes (one level of tuples, lists,
    dicts and dataclasses such as the mesh included; shared arrays counted once)."""
    seen: set[int] = set()

    def walk(value: Any, depth: int) -> int:
        if isinstance(value, np.ndarray):
            base = value if value.base is None else value.base
            if id(base) in seen:
                return 0
            seen.add(id(base))
            return int(base.nbytes) if isinstance(base, np.ndarray) else int(value.nbytes)
        if depth > 2:
            return 0
        if isinstance(value, (tuple, list)):
            return sum(walk(v, depth + 1) for v in value)
        if isinstance(value, dict):
            return sum(walk(v, depth + 1) for v in value.values())
        if dataclasses.is_dataclass(value) and not isinstance(value, type):
            return sum(walk(getattr(value, f.name), depth + 1)
                       for f in dataclasses.fields(value))
        return 0

    return sum(walk(v, 0) for v in vars(obj).values())


def _rss_bytes() -> int | None:
    try:
        import psutil

        return int(psutil.Process().memory_info().rss)
    except ImportError:
        pass
    try:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError):
        return None


def memory_probe(n_envs: int) -> dict[str, Any]:
    """Build ``n_envs`` envs and measure the growth of the process (run in a fresh one)."""
    import tracemalloc

    first = _make_env({})
    first.reset(seed=0)
    sim_bytes = array_bytes(first.unwrapped.sim)
    gc.collect()
    rss0 = _rss_bytes()
    method = "psutil" if "psutil" in sys.modules else "/proc/self/statm"
    if rss0 is None:
        method = "tracemalloc"
        tracemalloc.start()
    t0 = time.perf_counter()
    envs = []
    for i in range(n_envs):
        env = _make_env({})
        env.reset(seed=i)
        envs.append(env)
    build = time.perf_counter() - t0
    gc.collect()
    if rss0 is None:
        grown = tracemalloc.get_traced_memory()[0]
        tracemalloc.stop()
    else:
        grown = (_rss_bytes() or 0) - rss0
    return {"simulator_array_bytes": sim_bytes, "n_nodes": first.unwrapped.sim.n_nodes,
            "envs": n_envs, "growth_bytes_per_env": grown / n_envs, "method": method,
            "build_ms_per_env": build / n_envs * 1e3}


def bench_memory(settings: BenchmarkSettings, progress: bool = True) -> dict[str, Any]:
    """Memory per env, measured in a fresh process so earlier sections' freed memory is not
    reused."""
    code = ("import json; from drill_env.benchmark import memory_probe; "
            f"print(json.dumps(memory_probe({settings.memory_envs})))")
    if progress:
        print(f"  memory: building {settings.memory_envs} envs in a fresh process",
              file=sys.stderr, flush=True)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=900)
    if done.returncode != 0:
        raise RuntimeError(f"memory subprocess failed:\n{done.stderr[-2000:]}")
    result = json.loads(done.stdout.strip().splitlines()[-1])
    result["growth_over_simulator_arrays"] = _ratio(result["growth_bytes_per_env"],
                                                    result["simulator_array_bytes"])
    return result


def format_memory(result: dict[str, Any]) -> str:
    rows = [
        ("simulator NumPy arrays", f"{result['simulator_array_bytes'] / 1024:.0f}", "1.00"),
        (f"growth per env ({result['method']}, {result['envs']} envs)",
         f"{result['growth_bytes_per_env'] / 1024:.0f}",
         f"{result['growth_over_simulator_arrays']:.2f}"),
    ]
    note = (f"default env ({result['n_nodes']} nodes); building one env takes "
            f"{result['build_ms_per_env']:.0f} ms")
    return _table("Memory per env", ("quantity", "KiB", "x arrays"), rows, note)


# --------------------------------------------------------------------------- driver

RUNNERS: dict[str, tuple[Callable[..., dict[str, Any]], Callable[[dict[str, Any]], str]]] = {
    "core": (bench_core, format_core),
    "env": (bench_env, format_env),
    "scaling": (bench_scaling, format_scaling),
    "compile": (bench_compile, format_compile),
    "memory": (bench_memory, format_memory),
}


def parse_sections(text: str) -> tuple[str, ...]:
    """``"core,env"`` -> ``("core", "env")``; ``ValueError`` naming an unknown section."""
    names = tuple(s.strip() for s in text.split(",") if s.strip())
    unknown = [s for s in names if s not in SECTIONS]
    if unknown or not names:
        raise ValueError(f"sections: unknown {unknown or text!r}; choose from "
                         f"{','.join(SECTIONS)}")
    return names


def run_benchmark(sections: Iterable[str] = SECTIONS, settings: BenchmarkSettings = FULL,
                  out: Path | None = Path("logs"), progress: bool = True,
                  echo: Callable[[str], Any] | None = print) -> dict[str, Any]:
    """Run ``sections`` in order and print each table as it finishes.

    Unless ``out`` is None, writes ``out/benchmark.json`` (every figure),
    ``out/benchmark.md`` (the tables, for docs/performance.md) and, with the scaling
    section, ``out/benchmark_scaling.png``.
    """
    sections = tuple(sections)
    parse_sections(",".join(sections))
    levels = fidelity_levels()
    result: dict[str, Any] = {
        "machine": _machine(),
        "settings": dataclasses.asdict(settings),
        "fidelity_levels": list(levels),
    }
    say = echo or (lambda _text: None)
    machine = result["machine"]
    tables = []
    say(f"drill-env benchmark {machine['date']}: {','.join(sections)}; "
        f"{machine['cpu_count']} cores; fidelity levels: {', '.join(levels)}")
    stamp = source_stamp()
    t0 = time.perf_counter()
    for name in sections:
        bench, fmt = RUNNERS[name]
        tic = time.perf_counter()
        result[name] = bench(settings, progress)
        result[name]["section_wall_s"] = time.perf_counter() - tic
        tables.append(fmt(result[name]))
        say("\n" + tables[-1])
    result["total_wall_s"] = time.perf_counter() - t0
    machine["sources_changed_during_run"] = source_stamp() != stamp
    if machine["sources_changed_during_run"]:
        say("\nWARNING: drill_env sources changed during the run: the figures mix versions, "
            "rerun")
    if hasattr(os, "getloadavg"):
        machine["load_average_1min_end"] = os.getloadavg()[0]
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        path = out / "benchmark.json"
        path.write_text(json.dumps(result, indent=2) + "\n")
        # The same tables as markdown, to paste into docs/performance.md.
        report = out / "benchmark.md"
        kind = {FULL: "", QUICK: " --quick"}.get(settings, " (custom settings)")
        head = (f"`drill-env benchmark{kind}`, "
                f"{machine['date'][:10]}, commit {machine.get('git_commit', '?')}: "
                f"{machine['cpu']}, {machine['cpu_count']} cores, {machine['platform']}, "
                f"Python {machine['python']}, NumPy {machine['numpy']}, numba "
                f"{machine['numba']}; load average {machine.get('load_average_1min', 0):.1f} "
                f"at the start, {machine.get('load_average_1min_end', 0):.1f} at the end"
                + ("; SOURCES CHANGED DURING THE RUN." if machine["sources_changed_during_run"]
                   else "; sources unchanged during the run."))
        report.write_text(head + "\n\n```text\n" + "\n\n".join(tables) + "\n```\n")
        written = [path, report]
        if "scaling" in result:
            png = plot_scaling(result["scaling"], out / "benchmark_scaling.png")
            if png is not None:
                written.append(png)
        say(f"\nwrote {', '.join(str(p) for p in written)} ({result['total_wall_s']:.0f} s)")
    return result
