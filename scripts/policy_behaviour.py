"""What the shipped drilling policy does in each rock (docs/tasks.md, task 2).

    .venv/bin/python scripts/policy_behaviour.py [--seeds 10]

Plays the shipped task-2 policy on the first held-out seeds and keeps the steps after
30 s with the bit face wholly in one rock (``info["rock_share"]`` of that rock >= 0.999);
prints, per rock, the median and the 10-90 % range of the rpm and WOB set points and the
number of steps they rest on.
"""

from __future__ import annotations

import argparse
from collections import defaultdict

import gymnasium as gym
import numpy as np

import drill_env  # noqa: F401  (registers the envs)
from agents.learned import TRAINED, LearnedController
from drill_env.physics.units import RPM
from drill_env.scenarios import EVALUATION_SEEDS

SETTLE_S = 30.0
WHOLLY = 0.999


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", type=int, default=10, help="held-out seeds (default 10)")
    args = parser.parse_args()
    policy = LearnedController.load(TRAINED / "drilling")
    env = gym.make(policy.env_id, **policy.env_kwargs())
    names = None
    points: dict[str, list[tuple[float, float]]] = defaultdict(list)
    for seed in EVALUATION_SEEDS[:args.seeds]:
        obs, info = env.reset(seed=seed)
        policy.reset(env.unwrapped)
        names = [rock.name for rock in env.unwrapped.sim.config.formation.rocks]
        done = False
        while not done:
            obs, _, terminated, truncated, info = env.step(policy.act(obs, info))
            done = terminated or truncated
            share = np.asarray(info["rock_share"])
            if info["episode_time"] > SETTLE_S and share.max() >= WHOLLY:
                points[names[int(share.argmax())]].append(
                    (info["speed_setpoint"] / RPM, info["weight_on_bit_setpoint"] / 1e3))
    for rock in names or []:
        if not points[rock]:
            print(f"{rock:10s} no steps")
            continue
        rpm, wob = np.array(points[rock]).T
        print(f"{rock:10s} {len(rpm):5d} steps  rpm median {np.median(rpm):5.0f} "
              f"(10-90 %: {np.percentile(rpm, 10):.0f}-{np.percentile(rpm, 90):.0f})  "
              f"WOB median {np.median(wob):5.0f} kN "
              f"(10-90 %: {np.percentile(wob, 10):.0f}-{np.percentile(wob, 90):.0f})")


if __name__ == "__main__":
    main()
