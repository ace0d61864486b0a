"""Same code, same machine, same numbers: compiled fresh or loaded from numba's cache,
in this process or another, pickled or not."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np

_TRAJECTORY = """
import hashlib, sys
from drill_env.physics.simulator import Simulator, OperatingPoint
from drill_env.scenarios import make_scenario
for name in ("default", "paper_case4"):
    sc = make_scenario(name)
    sim = Simulator(sc.config)
    sim.reset(OperatingPoint(sc.surface_speed, sc.weight_on_bit))
    sim.vt[-1] *= 0.99
    records = sim.advance(1500, sc.surface_speed, sim.hook_load_for(sc.weight_on_bit), 10)
    print(hashlib.sha256(records.tobytes()).hexdigest())
"""


def _run(cache_dir: str) -> list[str]:
    env = {**os.environ, "NUMBA_CACHE_DIR": cache_dir}
    out = subprocess.run([sys.executable, "-c", _TRAJECTORY], env=env, capture_output=True,
                         text=True, check=True, timeout=900)
    return out.stdout.split()


def test_a_fresh_compile_and_a_cached_one_give_the_same_trajectory(tmp_path):
    """Regression: with FMA contraction on, numba's JIT and its cached object code fused
    multiply-adds differently, so the first (compiling) process drilled another
    trajectory than every later one."""
    cache = str(tmp_path / "numba_cache")
    fresh = _run(cache)  # compiles into the empty cache
    cached = _run(cache)  # loads it
    assert len(fresh) == 2 and fresh == cached


def test_the_same_start_gives_the_same_trajectory_in_one_process():
    from drill_env.physics.simulator import OperatingPoint, Simulator
    from drill_env.scenarios import make_scenario

    sc = make_scenario("paper_case2")
    runs = []
    for _ in range(2):
        sim = Simulator(sc.config)
        sim.reset(OperatingPoint(sc.surface_speed, sc.weight_on_bit))
        runs.append(sim.advance(800, sc.surface_speed, sim.hook_load_for(sc.weight_on_bit), 5))
    np.testing.assert_array_equal(runs[0], runs[1])
