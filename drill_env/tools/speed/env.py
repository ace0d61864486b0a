"""Section ``env``: env steps/s, single, looped and batched, and the Python share."""

from __future__ import annotations

import functools
import math
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from drill_env.sweep import usable_cores
from drill_env.tools.speed.common import (
    SETUP_WARNING,
    BenchmarkSettings,
    fidelity_levels,
    ratio,
    recorded_warnings,
    table,
    with_progress,
)

#: Random actions drawn once (seeded) and cycled through: every set-up of a level steps
#: with the same sequence, each env of a batch or loop with its own column.
RANDOM_ACTIONS = 64


def _step_each(envs: list, actions: np.ndarray) -> None:
    """Step env i of a loop with row i of ``actions``."""
    for env, action in zip(envs, actions, strict=True):
        env.step(action)


class _RandomSteps:
    """A step function for :func:`_interleaved_rates`: each call hands ``step`` the next
    of ``actions`` (shape (k, 2) for one env, (k, n, 2) for n), cycling."""

    def __init__(self, step: Callable[[np.ndarray], Any], actions: np.ndarray) -> None:
        self.step, self.actions, self.k = step, actions, 0

    def __call__(self) -> None:
        self.k = (self.k + 1) % len(self.actions)
        self.step(self.actions[self.k])


def random_actions(shape: tuple[int, ...], seed: int = 0) -> np.ndarray:
    """``RANDOM_ACTIONS`` uniform actions in [-1, 1] of ``shape`` each, as a policy draws
    them (float32): every WOB change runs as in training, not a constant set point."""
    rng = np.random.default_rng(seed)
    return rng.uniform(-1.0, 1.0, (RANDOM_ACTIONS, *shape)).astype(np.float32)


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


class _PhysicsOnly:
    """A step function for :func:`_interleaved_rates`: the batch's parallel call alone
    (prepare, physics, readings, metric windows; ``EnvBatch.run``) for ``envs`` at their
    current set points, on ``threads`` numba threads; no action, no finish, no Python per
    env. Its rate on all threads over one is the most a batch can gain over a loop on
    this machine at this moment (docs/performance.md, "What two threads can buy")."""

    def __init__(self, envs: list, threads: int) -> None:
        from drill_env.batching import EnvBatch

        self.envs = [env.unwrapped for env in envs]
        self.batch = EnvBatch(len(envs))
        self.on = np.ones(len(envs), dtype=np.bool_)
        self.threads = threads

    def __call__(self) -> None:
        import numba

        default = numba.get_num_threads()
        numba.set_num_threads(self.threads)
        try:
            self.batch.run(self.envs, self.on)
        finally:
            numba.set_num_threads(default)


def make_env(override: dict[str, str]):
    import gymnasium as gym

    import drill_env  # noqa: F401  (registers the ids)

    kwargs: dict[str, Any] = {"episode_duration": 1e6}
    if override:
        kwargs["physics"] = dict(override)
    return gym.make("DrillString-v0", **kwargs)


def _sb3_vec_env(n: int, override: dict[str, str]):
    """The Stable-Baselines3 VecEnv of ``n`` envs, or None without SB3 installed."""
    from drill_env.vector import make_sb3_vec_env

    kwargs: dict = {"physics": dict(override)} if override else {}
    return make_sb3_vec_env(n, episode_duration=1e6, **kwargs)


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
    result: dict[str, Any] = {"cores": usable_cores(), "fidelity": {}}
    for name, override in fidelity_levels().items():
        caught: list[str] = []
        with recorded_warnings(caught):
            result["fidelity"][name] = _bench_env_level(override, settings, name, progress)
        result["fidelity"][name]["warnings"] = caught
    fid = result["fidelity"]
    if {"full", "fast"} <= set(fid):
        result["fast_over_full_single"] = ratio(fid["fast"]["single"]["steps_per_s"],
                                                 fid["full"]["single"]["steps_per_s"])
        result["fast_over_full_batched"] = ratio(
            fid["fast"]["counts"][-1]["batched_steps_per_s"],
            fid["full"]["counts"][-1]["batched_steps_per_s"])
    return result


def _bench_env_level(override: dict[str, str], settings: BenchmarkSettings, name: str,
                     progress: bool) -> dict[str, Any]:
    """One fidelity level of :func:`bench_env`."""
    from drill_env.vector import DrillStringVectorEnv

    action = np.zeros(2, dtype=np.float32)  # mid range (100 rpm, 100 kN): the Python share
    env = make_env(override)
    env.reset(seed=0)
    single_step = (_RandomSteps(env.step, random_actions((2,))), 1)
    rate = _interleaved_rates({"single": single_step}, settings.env_steps,
                              settings.repeats, settings.env_warmup_steps)
    single = {"steps_per_s": rate["single"],
              **_python_overhead(env, action, settings.env_steps)}
    counts = []
    for n in with_progress(settings.env_counts, f"env ({name})", progress):
        envs = [make_env(override) for _ in range(n)]
        for i, e in enumerate(envs):
            e.reset(seed=i)
        vec = DrillStringVectorEnv(num_envs=n, episode_duration=1e6,
                                   physics=dict(override) if override else None)
        vec.reset(seed=0)
        actions = random_actions((n, 2), seed=n)
        env_steps = max(settings.env_batch_steps, n * settings.min_env_calls)
        steps: dict[str, tuple[Callable[[], Any], int]] = {
            "single": single_step,
            "loop": (_RandomSteps(functools.partial(_step_each, envs), actions), n),
            "batched": (_RandomSteps(vec.step, actions), n)}
        import numba

        physics_envs = [make_env(override) for _ in range(n)]
        for i, e in enumerate(physics_envs):
            e.reset(seed=i)
        threads = numba.get_num_threads()
        steps["physics"] = (_PhysicsOnly(physics_envs, threads), n)
        steps["physics_one_thread"] = (_PhysicsOnly(physics_envs, 1), n)
        sb3 = _sb3_vec_env(n, override)
        if sb3 is not None:
            sb3.reset()
            steps["batched_sb3"] = (_RandomSteps(sb3.step, actions), n)
        rates = _interleaved_rates(steps, env_steps, settings.repeats,
                                   settings.env_warmup_steps)
        for e in envs + physics_envs:
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
            "loop_over_single": ratio(rates["loop"], rates["single"]),
            "batched_over_loop": ratio(rates["batched"], rates["loop"]),
            "batched_over_single": ratio(rates["batched"], rates["single"]),
            "physics_threads": threads,
            "physics_steps_per_s": rates["physics"],
            "physics_one_thread_steps_per_s": rates["physics_one_thread"],
            "physics_threads_over_one": ratio(rates["physics"], rates["physics_one_thread"]),
            **({"batched_sb3_steps_per_s": rates["batched_sb3"],
                "batched_sb3_over_loop": ratio(rates["batched_sb3"], rates["loop"]),
                "batched_sb3_over_single": ratio(rates["batched_sb3"], rates["single"])}
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
            # the reference of this N's ratios, timed in its rounds (the headline one env,
            # timed alone and shorter, could not check them: a new user's trial)
            rows.append((f"  {name}: one env in N={n}'s rounds",
                         f"{c['single_steps_per_s']:.0f}", "1.00", ""))
            rows.append((f"{name}: {envs} looped", f"{c['loop_steps_per_s']:.0f}",
                         f"{c['loop_over_single']:.2f}", ""))
            rows.append((f"{name}: batched, N={n}", f"{c['batched_steps_per_s']:.0f}",
                         f"{c['batched_over_single']:.2f}", f"{c['batched_over_loop']:.2f}"))
            if "batched_sb3_steps_per_s" in c:
                rows.append((f"{name}: batched SB3 VecEnv, N={n}",
                             f"{c['batched_sb3_steps_per_s']:.0f}",
                             f"{c['batched_sb3_over_single']:.2f}",
                             f"{c['batched_sb3_over_loop']:.2f}"))
        ceiling = ", ".join(f"N={c['num_envs']} {c['physics_threads_over_one']:.2f}"
                            for c in fig["counts"] if "physics_threads_over_one" in c)
        if ceiling:
            threads = fig["counts"][-1]["physics_threads"]
            notes.append(f"{name}: the machine's parallel gain now: the batch's physics call "
                         f"alone on {threads} threads over one thread, same rounds: {ceiling} "
                         f"(x loop is near it when the batch's Python is small; short runs "
                         f"scatter both)")
        notes.append(f"{name}: one env step = {single['simulator_steps_per_env_step']} "
                     f"simulator steps, {single['us_per_env_step']:.0f} us, of which "
                     f"{single['us_in_simulator']:.0f} us in Simulator.advance: Python "
                     f"overhead {single['python_overhead_share']:.0%}")
        notes += [f"{name}: {SETUP_WARNING}: {m}" for m in fig.get("warnings", [])]
    if "fast_over_full_single" in result:
        notes.append(f"fast / full env steps/s: one env {result['fast_over_full_single']:.2f} x,"
                     f" batched (largest N) {result['fast_over_full_batched']:.2f} x")
    notes.append(f"10 Hz policy rate, random actions (one seeded sequence per set-up; the "
                 f"Python share: a constant one); batched: the Gymnasium VectorEnv (SB3 "
                 f"VecEnv: the Stable-Baselines3 one), one numba prange call over the envs, "
                 f"{result['cores']} cores; x one env: against one env timed in the same "
                 f"rounds (its row above each N's); best of repeats")
    return table("Env throughput", ("configuration", "env steps/s", "x one env", "x loop"),
                  rows, "\n".join(notes))


