"""Hashes of reference trajectories, to prove a refactor left the numbers bit-identical.

    .venv/bin/python scripts/trajectory_hashes.py --save logs/trajectory_hashes.json
    ... refactor ...
    .venv/bin/python scripts/trajectory_hashes.py --check logs/trajectory_hashes.json

Bit-identity holds for the same code path on the same machine only (the compiled
kernels may contract floating-point operations differently on another CPU), so the
hashes live under ``logs/``, not in the repository. Covered: the default scenario, paper
cases 1-4 and the randomised scenario through ``gymnasium.make`` with a seeded random
action sequence, both bit models, the bare simulator on every paper case, and a batched
vector env of 8.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from pathlib import Path

import numpy as np

#: info keys of SPEC section 6 that every version of the env reports.
INFO_KEYS = ("time", "bit_speed", "surface_speed", "torque_on_bit", "surface_torque",
             "weight_on_bit", "hook_load", "bit_lateral", "whirl_speed", "depth", "rop",
             "rock_share")


def _digest(parts: list[np.ndarray]) -> str:
    h = hashlib.sha256()
    for part in parts:
        h.update(np.ascontiguousarray(part, dtype=np.float64).tobytes())
    return h.hexdigest()


def _info_values(info: dict) -> np.ndarray:
    return np.concatenate([np.atleast_1d(np.asarray(info[k], dtype=np.float64))
                           for k in INFO_KEYS])


def env_trajectory(env_id: str, steps: int, seed: int, **kwargs) -> str:
    import gymnasium as gym

    import drill_env  # noqa: F401

    env = gym.make(env_id, **kwargs)
    obs, info = env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    parts = [obs, _info_values(info)]
    for _ in range(steps):
        action = rng.uniform(-0.4, 0.4, 2).astype(np.float32) + np.float32(0.2)
        obs, reward, terminated, truncated, info = env.step(action)
        parts += [obs, np.array([reward, terminated, truncated]), _info_values(info)]
        if terminated or truncated:
            obs, info = env.reset()
            parts.append(obs)
    env.close()
    return _digest(parts)


def vector_trajectory(n: int, steps: int, seed: int, **kwargs) -> str:
    import gymnasium as gym

    import drill_env  # noqa: F401

    venv = gym.make_vec("DrillString-v0", num_envs=n, **kwargs)
    obs, info = venv.reset(seed=seed)
    rng = np.random.default_rng(seed)
    parts = [obs]
    for _ in range(steps):
        actions = rng.uniform(-0.5, 0.5, (n, 2)).astype(np.float32)
        obs, rewards, terms, truncs, info = venv.step(actions)
        parts += [obs, rewards, terms, truncs, info["bit_speed"], info["torque_on_bit"]]
    venv.close()
    return _digest(parts)


def simulator_trajectory(scenario: str, seconds: float, **params) -> str:
    from drill_env.physics.simulator import OperatingPoint, Simulator
    from drill_env.scenarios import make_scenario

    sc = make_scenario(scenario, **params)
    sim = Simulator(sc.config)
    sim.reset(OperatingPoint(sc.surface_speed, sc.weight_on_bit))
    sim.vt[-1] *= 0.99
    hook = sim.hook_load_for(sc.weight_on_bit)
    records = [sim.advance(round(seconds / sim.dt), sc.surface_speed, hook, 5)]
    return _digest(records)


def cases() -> dict[str, object]:
    return {
        "env default": lambda: env_trajectory("DrillString-v0", 60, 0),
        "env default macroscopic": lambda: env_trajectory("DrillStringMacro-v0", 60, 1),
        "env paper_case1 P3": lambda: env_trajectory("DrillString-v0", 60, 2,
                                                     scenario="paper_case1", position="P3"),
        "env paper_case4": lambda: env_trajectory("DrillString-v0", 40, 3,
                                                  scenario="paper_case4"),
        "env random": lambda: env_trajectory("DrillStringRandom-v0", 120, 4,
                                             episode_duration=3.0),
        "env fast": lambda: env_trajectory("DrillString-v0", 40, 5, scenario="paper_case2",
                                           fidelity="fast"),
        "vector N=8 random": lambda: vector_trajectory(8, 40, 6, scenario="random",
                                                       episode_duration=2.0),
        "sim paper_case1 P1": lambda: simulator_trajectory("paper_case1", 8.0),
        "sim paper_case2": lambda: simulator_trajectory("paper_case2", 6.0),
        "sim paper_case3": lambda: simulator_trajectory("paper_case3", 6.0, lead=0.0),
        "sim paper_case4": lambda: simulator_trajectory("paper_case4", 6.0),
        "sim default": lambda: simulator_trajectory("default", 6.0),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    group = parser.add_mutually_exclusive_group(required=True)
    group.add_argument("--save", type=Path, help="write the hashes to this JSON file")
    group.add_argument("--check", type=Path, help="compare with the hashes in this file")
    parser.add_argument("--only", default=None, help="comma-separated subset of case names")
    args = parser.parse_args(argv)
    selected = cases()
    if args.only:
        keep = {name.strip() for name in args.only.split(",")}
        selected = {k: v for k, v in selected.items() if k in keep}
    hashes = {}
    for name, run in selected.items():
        hashes[name] = run()
        print(f"{name:<28} {hashes[name][:16]}", flush=True)
    if args.save:
        args.save.parent.mkdir(parents=True, exist_ok=True)
        args.save.write_text(json.dumps(hashes, indent=1))
        print(f"wrote {args.save}")
        return 0
    saved = json.loads(args.check.read_text())
    differ = [k for k in hashes if saved.get(k) != hashes[k]]
    for name in differ:
        print(f"DIFFERS: {name}")
    print("all bit-identical" if not differ else f"{len(differ)} of {len(hashes)} differ")
    return 1 if differ else 0


if __name__ == "__main__":
    sys.exit(main())
