"""Env throughput: steps/s of one env, of N single envs looped in one process, and of the
batched vector env (threads over the nogil kernel), at the default 10 Hz policy rate.

Prints a table and writes logs/benchmark_env.json. Ratios, not absolute times, are the
figures to compare across machines.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import gymnasium as gym
import numpy as np

import drill_env  # noqa: F401  (registers the ids)
from drill_env.vector import DrillStringVectorEnv


def steps_per_second(step, n_calls: int, envs_per_call: int) -> float:
    step()  # warm
    t = time.perf_counter()
    for _ in range(n_calls):
        step()
    return n_calls * envs_per_call / (time.perf_counter() - t)


def main(n_values=(1, 4, 16, 64), n_calls: int = 30) -> dict:
    results: dict = {}
    env = gym.make("DrillString-v0", episode_duration=1e6)
    env.reset(seed=0)
    action = np.zeros(2, dtype=np.float32)
    single = steps_per_second(lambda: env.step(action), 100, 1)
    results["single_env_steps_per_s"] = single
    print(f"{'configuration':38s} {'env steps/s':>12s} {'x single':>9s}")
    print(f"{'one env':38s} {single:12.0f} {1.0:9.2f}")
    for n in n_values:
        envs = [gym.make("DrillString-v0", episode_duration=1e6) for _ in range(n)]
        for i, e in enumerate(envs):
            e.reset(seed=i)
        loop = steps_per_second(lambda envs=envs: [e.step(action) for e in envs], n_calls, n)
        vec = DrillStringVectorEnv(num_envs=n, episode_duration=1e6)
        vec.reset(seed=0)
        actions = np.zeros((n, 2), dtype=np.float32)
        batched = steps_per_second(lambda vec=vec, a=actions: vec.step(a), n_calls, n)
        results[f"loop_{n}"] = loop
        results[f"batched_{n}"] = batched
        print(f"{f'{n} single envs looped':38s} {loop:12.0f} {loop / single:9.2f}")
        print(f"{f'batched vector env, N={n}':38s} {batched:12.0f} {batched / single:9.2f}"
              f"   ({batched / loop:.2f}x the loop)")
    Path("logs").mkdir(exist_ok=True)
    Path("logs/benchmark_env.json").write_text(json.dumps(results, indent=2))
    return results


if __name__ == "__main__":
    main()
