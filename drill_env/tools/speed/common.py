"""Settings and timing helpers shared by the sections of the speed benchmark."""

from __future__ import annotations

import contextlib
import datetime
import math
import os
import platform
import subprocess
import sys
import textwrap
import time
import warnings
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from drill_env.physics import config as physics_config
from drill_env.physics.config import FIDELITY_LEVELS, SimulationConfig
from drill_env.physics.simulator import OperatingPoint, Simulator
from drill_env.physics.units import RPM
from drill_env.sweep import usable_cores

SECTIONS = ("core", "env", "scaling", "compile", "memory")

#: Operating point of the core and env figures (docs/performance.md, "Core").
SURFACE_SPEED = 60 * RPM
WEIGHT_ON_BIT = 100e3
#: Fidelity levels the simulator may offer, in the order they are reported.


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
    #: Timed env steps per round of the ``training`` section (``drill-env speed``,
    #: training/speed.py): PPO's; SAC takes a quarter (a gradient step per env step).
    train_steps: int = 16384
    train_rounds: int = 2

    def __post_init__(self) -> None:
        for name in ("core_seconds", "scaling_seconds", "scaling_weight_on_bit",
                     "mesh_pipe_length"):
            physics_config.require_positive(getattr(self, name), name)
        for name in ("repeats", "reference_steps", "env_steps", "env_warmup_steps",
                     "env_batch_steps",
                     "min_env_calls", "memory_envs", "train_steps", "train_rounds"):
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
        if list(self.env_counts) != sorted(set(self.env_counts)):  # the last is reported
            # as the largest N (fast over full, batched): (64, 1) said N = 1's as N = 64's
            raise ValueError(f"env_counts: must increase, got {self.env_counts!r}")


FULL = BenchmarkSettings()
QUICK = BenchmarkSettings(
    core_seconds=2.0, repeats=2, warmup_steps=200, reference_steps=10, env_steps=40,
    env_batch_steps=64, min_env_calls=2, env_counts=(1, 4, 16), pipe_lengths=(500.0, 1000.0,
                                                                              2000.0),
    pipe_element_lengths=(20.0, 10.0, 5.0), scaling_seconds=1.0, memory_envs=8,
    train_steps=4096, train_rounds=1)


# --------------------------------------------------------------------------- helpers


def fidelity_levels() -> dict[str, dict[str, str]]:
    """Fidelity levels of the simulator: name -> dotted physics override."""
    return {name: {"solver.fidelity": name} for name in FIDELITY_LEVELS}



def with_progress(items: Iterable, desc: str, enabled: bool) -> Iterator:
    """A tqdm bar over ``items`` when enabled (:func:`drill_env.progress.progress_bar`:
    at most a line a minute in a log)."""
    from drill_env.progress import progress_bar as bar

    yield from bar(iterable=list(items), desc=f"  {desc}", leave=False, file=sys.stderr,
                   disable=not enabled)


#: How a table names a warning :func:`recorded_warnings` kept: about the benchmark's own
#: set-up (its advice is not the reader's to follow).
#: (a new user read "not for you to act on" and then the warning's own advice as a
#: contradiction: the advice is for runs of one's own, the benchmark's set-up stays fixed)
SETUP_WARNING = ("the simulator warned of this benchmark's fixed set-up, kept so that runs "
                 "compare (its advice is for runs of your own)")


@contextlib.contextmanager
def recorded_warnings(into: list[str]) -> Iterator[None]:
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


def best_time(run: Callable[[], Any], repeats: int) -> float:
    """Shortest wall time of ``repeats`` calls: the least disturbed by other processes."""
    best = math.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        run()
        best = min(best, time.perf_counter() - t0)
    return best


def ratio(a: float, b: float) -> float:
    return a / b if b > 0 else math.nan


def table(title: str, header: tuple[str, ...], rows: list[tuple], note: str = "") -> str:
    """A plain text table: first column left-aligned, the others right-aligned."""
    cells = [[str(c) for c in header]] + [[str(c) for c in row] for row in rows]
    widths = [max(len(r[k]) for r in cells) for k in range(len(header))]

    def line(r: list[str]) -> str:
        return "  ".join(c.ljust(w) if k == 0 else c.rjust(w)
                         for k, (c, w) in enumerate(zip(r, widths, strict=True))).rstrip()

    head = line(cells[0])
    lines = [title, head, "-" * len(head)] + [line(r) for r in cells[1:]]
    width = max(len(head), 88)
    for paragraph in note.splitlines():
        lines.append(textwrap.fill(paragraph, width, subsequent_indent="  "))
    return "\n".join(lines)


def settled_simulator(config: SimulationConfig, weight_on_bit: float,
                      warmup_steps: int) -> Simulator:
    sim = Simulator(config)
    sim.reset(OperatingPoint(SURFACE_SPEED, weight_on_bit))
    sim.advance(max(warmup_steps, 1), SURFACE_SPEED, sim.hook_load_for(weight_on_bit))
    return sim


def time_simulators(sims: dict[Any, Simulator], weight_on_bit: float, seconds: float,
                     repeats: int, desc: str, progress: bool) -> dict[Any, dict[str, float]]:
    """Best-of-``repeats`` wall time of ``seconds`` simulated by each simulator (records
    every 10 steps, as the env does).

    The simulators take turns repeat by repeat, so a burst of load from another process
    hits them alike instead of spoiling one of them.
    """
    best = dict.fromkeys(sims, math.inf)
    n_steps = {key: max(1, round(seconds / sim.dt)) for key, sim in sims.items()}
    for _ in with_progress(range(repeats), desc, progress):
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
def one_numba_thread() -> Iterator[None]:
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
    root = Path(__file__).resolve().parents[2]  # drill_env/
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


def threading_layer() -> str | None:
    """The threading layer numba's parallel calls run on (``tbb``, ``omp``,
    ``workqueue``), or None before the process's first parallel call chose one."""
    import numba

    try:
        return numba.threading_layer()
    except ValueError:
        return None


def machine_info() -> dict[str, Any]:
    import numba

    import drill_env

    info: dict[str, Any] = {
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "cpu": _cpu_name(),
        "cpu_count": os.cpu_count(),  # the machine's
        "cores": usable_cores(),  # this process's (affinity, cgroup quota): the tables
        "platform": platform.platform(),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "numba": numba.__version__,
    }
    if hasattr(os, "getloadavg"):
        info["load_average_1min"] = os.getloadavg()[0]
    info["drill_env"] = drill_env.__version__
    commit = checkout_commit(Path(drill_env.__file__).resolve().parent.parent)
    if commit is not None:
        info["git_commit"] = commit
    return info


def checkout_commit(root: Path) -> str | None:
    """The commit of the drill-env checkout at ``root`` (``+dirty`` with changes to tracked
    files: an untracked scratch folder changes no source; a fuzzing walkthrough), or None
    where ``root`` is not the top of a git work tree: an installed package's root is
    site-packages, whose enclosing repository (a project that keeps its venv inside) is
    not ours (an outside check found its commit in speed.json)."""
    def git(*args: str) -> str:
        return subprocess.run(["git", *args], cwd=root, capture_output=True, text=True,
                              timeout=10, check=True).stdout.strip()

    try:
        if Path(git("rev-parse", "--show-toplevel")).resolve() != root.resolve():
            return None
        return git("rev-parse", "--short", "HEAD") + (
            "+dirty" if git("status", "--porcelain", "--untracked-files=no") else "")
    except (OSError, subprocess.SubprocessError):
        return None


