"""Sections ``compile`` (cold and warm start) and ``memory`` (bytes per env)."""

from __future__ import annotations

import dataclasses
import gc
import json
import os
import subprocess
import sys
import tempfile
import time
from typing import Any

import numpy as np

from drill_env.tools.speed.common import (
    BenchmarkSettings,
    ratio,
    source_stamp,
    table,
    with_progress,
)
from drill_env.tools.speed.env import make_env

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
        for state in with_progress(("cold", "warm"), "compile", progress):
            runs[state] = _first_step(cache)
    return {**runs, "cold_over_warm": ratio(runs["cold"]["first_step_s"],
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
    return table("Compile time (fresh process)", ("numba cache", "first step s", "import s",
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
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError):
        return None


def memory_probe(n_envs: int) -> dict[str, Any]:
    """Build ``n_envs`` envs and measure the growth of the process (run in a fresh one)."""
    import tracemalloc

    first = make_env({})
    first.reset(seed=0)
    sim_bytes = array_bytes(first.unwrapped.sim)
    gc.collect()
    rss0 = _rss_bytes()
    method = "/proc/self/statm"  # (psutil was named where imported, never called)
    if rss0 is None:
        method = "tracemalloc"
        tracemalloc.start()
    t0 = time.perf_counter()
    envs = []
    for i in range(n_envs):
        env = make_env({})
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
    code = ("import json; from drill_env.tools.speed.system import memory_probe; "
            f"print(json.dumps(memory_probe({settings.memory_envs})))")
    if progress:
        print(f"  memory: building {settings.memory_envs} envs in a fresh process",
              file=sys.stderr, flush=True)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=900)
    if done.returncode != 0:
        raise RuntimeError(f"memory subprocess failed:\n{done.stderr[-2000:]}")
    result = json.loads(done.stdout.strip().splitlines()[-1])
    result["growth_over_simulator_arrays"] = ratio(result["growth_bytes_per_env"],
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
    return table("Memory per env", ("quantity", "KiB", "x arrays"), rows, note)


