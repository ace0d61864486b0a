"""``drill-env speed``: the quick run produces every figure, finite and positive.

No timing thresholds: the figures depend on the machine and its load.
"""

import dataclasses
import json
import math
from types import SimpleNamespace

import numpy as np
import pytest

from drill_cli.main import main
from drill_env.tools import speed
from drill_env.tools.speed import QUICK, BenchmarkSettings, parse_sections, run_speed
from drill_env.tools.speed import core as speed_core

TINY = dataclasses.replace(
    QUICK, core_seconds=0.1, repeats=1, warmup_steps=10, reference_steps=2,
    pipe_lengths=(100.0, 200.0), pipe_element_lengths=(20.0, 10.0), mesh_pipe_length=200.0,
    scaling_seconds=0.1)


def positive_finite(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) \
        and math.isfinite(value) and value > 0


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("bench")
    run_speed(("core", "scaling"), TINY, out, progress=False, echo=None)
    return out


def test_quick_core_and_scaling_write_every_figure_as_a_positive_number(tiny_run):
    result = json.loads((tiny_run / "speed.json").read_text())
    assert {"machine", "settings", "fidelity_levels", "core", "scaling"} <= set(result)
    assert "env" not in result
    core = result["core"]
    assert set(core["fidelity"]) == set(result["fidelity_levels"])
    for fig in core["fidelity"].values():
        for key in ("real_time_factor", "us_per_step", "ns_per_dof_step", "speedup_over_numpy",
                    "n_dof", "time_step_s"):
            assert positive_finite(fig[key]), key
    for key in ("us_per_step", "ns_per_dof_step", "real_time_factor"):
        assert positive_finite(core["reference"][key]), key

    scaling = result["scaling"]
    points = scaling["points"]
    assert len(points) == 3  # 100/10, 200/10 (both sweeps), 200/20
    for p in points:
        for key in ("n_dof", "us_per_step", "ns_per_dof_step", "cost_over_reference",
                    "real_time_factor"):
            assert positive_finite(p[key]), key
    fit = scaling["fit"]
    assert math.isfinite(fit["us_per_step_intercept"])
    assert 0.0 <= fit["r_squared"] <= 1.0
    assert (tiny_run / "speed_scaling.png").stat().st_size > 0


def test_both_fidelity_levels_get_a_fast_over_full_ratio():
    result = speed_core.bench_core(TINY, progress=False)
    assert set(result["fidelity"]) == {"full", "fast"}
    assert positive_finite(result["fast_over_full_speed"])


def test_unknown_section_is_named():
    with pytest.raises(ValueError, match="bogus"):
        parse_sections("core,bogus")
    with pytest.raises(SystemExit):
        main(["speed", "--sections", "bogus"])
    with pytest.raises(SystemExit):  # it ran every section
        main(["speed", "--sections", ""])


def test_settings_reject_non_positive_sizes_by_name():
    with pytest.raises(ValueError, match="repeats"):
        BenchmarkSettings(repeats=0)
    with pytest.raises(ValueError, match="pipe_lengths"):
        BenchmarkSettings(pipe_lengths=(-1.0,))
    # the last count is reported as the largest N: (64, 1) said N = 1's figure as N = 64's
    # (a mutation round)
    for counts in ((64, 1), (4, 4)):
        with pytest.raises(ValueError, match=r"env_counts: must increase"):
            BenchmarkSettings(env_counts=counts)
    assert BenchmarkSettings(env_counts=(1, 64)).env_counts == (1, 64)


def test_finished_sections_are_written_before_an_interrupt(tmp_path, monkeypatch):
    def interrupted(settings, progress=True):
        raise KeyboardInterrupt

    monkeypatch.setitem(speed.RUNNERS, "scaling", (interrupted, speed.RUNNERS["scaling"][1]))
    with pytest.raises(KeyboardInterrupt):
        run_speed(("core", "scaling"), TINY, tmp_path, progress=False, echo=None)
    (tmp_path / "speed_scaling.png").write_bytes(b"an earlier run's picture")
    with pytest.raises(KeyboardInterrupt):
        run_speed(("core", "scaling"), TINY, tmp_path, progress=False, echo=None)
    result = json.loads((tmp_path / "speed.json").read_text())
    assert result["finished_sections"] == ["core"] and "core" in result
    # the tables agree with speed.json (they were an earlier run's) and say so
    report = (tmp_path / "speed.md").read_text()
    assert "UNFINISHED: sections done so far core." in report and "Core" in report
    assert not (tmp_path / "speed_scaling.png").exists()


def test_importing_drill_env_makes_openmp_workers_wait_passively_unless_told():
    """Spinning OpenMP workers cost PPO 3x its speed beside one busy process
    (scripts/threading_study.py); the user's own OMP_WAIT_POLICY is kept."""
    import os
    import subprocess
    import sys

    code = "import os, drill_env; print(os.environ['OMP_WAIT_POLICY'])"
    env = {k: v for k, v in os.environ.items() if k != "OMP_WAIT_POLICY"}
    default = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                             text=True, check=True).stdout.strip()
    chosen = subprocess.run([sys.executable, "-c", code],
                            env={**env, "OMP_WAIT_POLICY": "ACTIVE"}, capture_output=True,
                            text=True, check=True).stdout.strip()
    assert (default, chosen) == ("PASSIVE", "ACTIVE")
    # imported after torch: too late for torch's own threads, and said with what to do,
    # in a notebook too (setting the variable then reaches only child processes)
    late = subprocess.run([sys.executable, "-W", "always", "-c", "import torch, drill_env"],
                          env=env, capture_output=True, text=True, check=True).stderr
    assert "drill_env was imported after torch" in late
    assert "in a notebook: restart the kernel and import drill_env before torch" in late


def test_the_batched_envs_run_on_tbb_where_its_wheel_is_installed_unless_told():
    """The ``tbb`` wheel puts libtbb.so.12 off the loader's path, where numba's TBB
    layer cannot find it and numba falls back to OpenMP, whose sleeping workers join a
    parallel call ~80 us late (batched / loop 1.6-1.7 at the fast level, N = 16, against
    1.9 on TBB: docs/performance.md). ``import drill_env`` loads it by its path; a
    layer the user chose stands. On x86-64 Linux the wheel is a dependency, so there
    the test insists on TBB."""
    import os
    import platform
    import subprocess
    import sys

    code = ("import drill_env, numba, numpy as np\n"
            "@numba.njit(parallel=True)\n"
            "def total(a):\n"
            "    s = 0.0\n"
            "    for i in numba.prange(a.size):\n"
            "        s += a[i]\n"
            "    return s\n"
            "assert total(np.ones(1000)) == 1000.0\n"
            "print(numba.threading_layer(), drill_env.TBB_LIBRARY is not None)")
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_THREADING_LAYER"}

    def layer(**extra: str) -> str:
        return subprocess.run([sys.executable, "-c", code], env={**env, **extra},
                              capture_output=True, text=True, check=True).stdout.strip()

    if sys.platform == "linux" and platform.machine() == "x86_64":
        assert layer() == "tbb True"
    assert layer(NUMBA_THREADING_LAYER="omp") == "omp False"


def test_old_numba_caches_beyond_the_recent_ones_are_removed_after_a_day(tmp_path,
                                                                        monkeypatch):
    """Every version of the sources gets its own numba cache folder (drill_env's
    ``_numba_cache_dir``); a version's folder goes once it is beyond the CACHES_KEPT most
    recently used and unused for a day. In a folder the user chose (NUMBA_CACHE_DIR) only
    folders marked as drill_env's are candidates; under drill_env's own base, unmarked
    16-hex-digit folders (made before the marker) are too. Nothing else is touched."""
    import os
    import time

    import drill_env

    def version_folders(base, marked):
        now = time.time()
        for k, hours in enumerate([1, 2, 30, 40, 50, 60, 70, 80, 90]):
            folder = base / f"{k:016x}"
            (folder / "sub").mkdir(parents=True)
            (folder / "sub" / "kernel.nbc").write_bytes(b"x")
            if marked:
                (folder / drill_env.CACHE_MARKER).touch()
            os.utime(folder, (now - hours * 3600.0, now - hours * 3600.0))
        for name in ("not-a-version", "abcdefabcdefabcd"):  # another program's folders
            (base / name).mkdir()
            os.utime(base / name, (now - 1e6, now - 1e6))

    def prune(current):
        return sorted(p.name for p in drill_env._prune_numba_caches(
            current, keep=5, unused_for=86400.0))

    # a folder the user chose: the marked versions beyond the five most recent that are
    # older than a day go (two under a day, three over stay); the others stay
    chosen = tmp_path / "chosen"
    version_folders(chosen, marked=True)
    current = chosen / "ffffffffffffffff"
    assert prune(current) == [f"{k:016x}" for k in (5, 6, 7, 8)]
    assert sorted(p.name for p in chosen.iterdir()) == sorted(
        [*(f"{k:016x}" for k in range(5)), "ffffffffffffffff", "not-a-version",
         "abcdefabcdefabcd"])
    assert (current / drill_env.CACHE_MARKER).exists()
    assert time.time() - current.stat().st_mtime < 60.0
    assert prune(current) == []
    # drill_env's own base: the unmarked version folders of before the marker go too,
    # and "abcdefabcdefabcd" (16 hex digits, the oldest) with them; "not-a-version" stays
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    own = tmp_path / "xdg" / "drill_env" / "numba"
    version_folders(own, marked=False)
    assert prune(own / "ffffffffffffffff") == [
        *(f"{k:016x}" for k in (5, 6, 7, 8)), "abcdefabcdefabcd"]
    assert (own / "not-a-version").exists()


def test_the_training_section_splits_each_shipped_run_and_checks_the_torch_default(tmp_path):
    """``drill-env speed --sections training``: PPO (task 1) and SAC (task 2) trained for
    a moment; every row a positive steps/s with its ratio to the env alone, the shares
    of env, policy inference, update and the rest summing to 1, and both torch thread
    counts and Adam with and without its fused kernel timed."""
    tiny = dataclasses.replace(QUICK, train_steps=4096, train_rounds=1)
    from training.speed import RUNNER

    run_speed(("training",), tiny, tmp_path, progress=False, echo=None,
              runners={"training": RUNNER})
    result = json.loads((tmp_path / "speed.json").read_text())["training"]
    assert set(result["runs"]) == {"stick_slip ppo", "drilling sac"}
    for run in result["runs"].values():
        rows = run["rows"]
        assert {"env only, random actions", "env only, constant action"} <= set(rows)
        trained = [r for label, r in rows.items() if label.startswith("torch")]
        assert len(trained) == (2 if result["torch_default_threads"] == 1 else 3)
        assert any("Adam not fused" in label for label in rows)
        for row in rows.values():
            assert positive_finite(row["steps_per_s"]) and positive_finite(row["x env only"])
            assert positive_finite(row["cpu_s_per_1000"])
        for row in trained:
            shares = (row["env_share"], row["policy_share"], row["update_share"],
                      row["rest_share"])
            # rest = 1 - the timed parts: negative if a part were counted twice
            assert all(0.0 <= s <= 1.0 for s in shares)
            assert row["update_share"] > 0.0 and row["policy_share"] > 0.0
        assert positive_finite(run["random_over_constant"])
    assert "Time to a policy" in (tmp_path / "speed.md").read_text()


def test_the_env_section_times_every_set_up_and_the_parallel_ceiling(tmp_path):
    """Single, looped, batched (both APIs) and the batch's physics call alone on all
    threads and on one, whose ratio bounds batched / loop on the machine of the run. The
    report names numba's threading layer, which the batched figures depend on."""
    import numba

    from drill_env.tools.speed.env import format_env

    settings = dataclasses.replace(TINY, env_counts=(2,), env_steps=20, env_warmup_steps=2,
                                   env_batch_steps=8, min_env_calls=2)
    run_speed(("env",), settings, tmp_path, progress=False, echo=None)
    written = json.loads((tmp_path / "speed.json").read_text())
    assert written["machine"]["numba_threading_layer"] == numba.threading_layer()
    assert f"({numba.threading_layer()} layer)" in (tmp_path / "speed.md").read_text()
    result = written["env"]
    for fig in result["fidelity"].values():
        assert positive_finite(fig["single"]["steps_per_s"])
        (row,) = fig["counts"]
        for key in ("loop_steps_per_s", "batched_steps_per_s", "batched_sb3_steps_per_s",
                    "physics_steps_per_s", "physics_one_thread_steps_per_s",
                    "physics_threads_over_one", "batched_over_loop"):
            assert positive_finite(row[key]), key
        assert row["physics_threads"] >= 1
    assert "the machine's parallel gain now" in format_env(result)


def test_the_commit_recorded_is_drill_envs_own_not_an_enclosing_repositorys(tmp_path):
    """Installed from a wheel into a venv inside the user's own git repository, speed.json
    named the user's commit (an outside check): only the top of a work tree counts."""
    import subprocess
    from pathlib import Path

    from drill_env.tools.speed.common import checkout_commit

    def git(*args: str) -> str:
        return subprocess.run(["git", "-c", "user.name=t", "-c", "user.email=t@t", *args],
                              cwd=tmp_path, capture_output=True, text=True,
                              check=True).stdout.strip()

    site = tmp_path / "venv" / "lib" / "site-packages"
    site.mkdir(parents=True)
    assert checkout_commit(site) is None  # in no work tree: git's error, caught
    (tmp_path / "a.txt").write_text("a")
    git("init", "-q")
    git("add", "a.txt")
    git("commit", "-q", "-m", "user's")
    assert checkout_commit(site) is None
    assert checkout_commit(tmp_path) == git("rev-parse", "--short", "HEAD")
    (tmp_path / "a.txt").write_text("b")
    assert checkout_commit(tmp_path).endswith("+dirty")
    assert checkout_commit(tmp_path / "nowhere") is None
    this = Path(__file__).resolve().parents[1]
    if (this / ".git").exists():  # a checkout (CI clones one), not an unpacked sdist
        assert checkout_commit(this) is not None


class _Clock:
    """A clock that moves only when a fake step moves it (CPU time = wall time): the
    figures' arithmetic checked without timing anything."""

    def __init__(self) -> None:
        self.now = 0.0

    def perf_counter(self) -> float:
        return self.now

    process_time = perf_counter


def test_random_actions_cycle_past_their_last_one():
    """_RandomSteps cycles through its actions: a full run steps the single env for
    more calls (warm-up + repeats x env_steps) than there are RANDOM_ACTIONS."""
    from drill_env.tools.speed.env import RANDOM_ACTIONS, _RandomSteps, random_actions

    actions = random_actions((2,))
    seen: list = []
    steps = _RandomSteps(seen.append, actions)
    for _ in range(2 * RANDOM_ACTIONS + 1):
        steps()
    assert sorted(map(tuple, seen[:RANDOM_ACTIONS])) == sorted(map(tuple, actions))
    np.testing.assert_array_equal(seen[RANDOM_ACTIONS:2 * RANDOM_ACTIONS],
                                  seen[:RANDOM_ACTIONS])


def test_env_rates_count_every_env_a_call_steps(monkeypatch):
    from drill_env.tools.speed import env as speed_env

    clock = _Clock()
    monkeypatch.setattr(speed_env, "time", clock)
    calls = {"one": 0, "four": 0}

    def step(name):
        def call() -> None:
            calls[name] += 1
            clock.now += 1e-3

        return call

    rates = speed_env._interleaved_rates({"one": (step("one"), 1), "four": (step("four"), 4)},
                                         env_steps=8, rounds=2, warmup=1)
    # 1 ms a call: one env a call is 1000 env steps/s, four envs a call 4000
    assert rates == pytest.approx({"one": 1000.0, "four": 4000.0})
    # after the warm-up call, rounds of 8 / 2 env steps: 4 calls of one env, 1 of four
    assert calls == {"one": 1 + 2 * 4, "four": 1 + 2 * 1}


def test_the_python_share_of_an_env_step_is_its_time_outside_the_simulator(monkeypatch):
    from drill_env.tools.speed import env as speed_env

    clock = _Clock()
    monkeypatch.setattr(speed_env, "time", clock)

    class Sim:
        def advance(self, *args, **kwargs) -> None:
            clock.now += 3e-3

    class Env:
        _steps_per_action = 50

        def __init__(self) -> None:
            self.sim = Sim()
            self.unwrapped = self

        def step(self, action):
            clock.now += 1e-3  # the env's own Python
            self.sim.advance(self._steps_per_action)
            return None, 0.0, False, False, {}

    env = Env()
    out = speed_env._python_overhead(env, np.zeros(2), 4)
    assert out["us_per_env_step"] == pytest.approx(4e3)
    assert out["us_in_simulator"] == pytest.approx(3e3)
    assert out["python_overhead_share"] == pytest.approx(0.25)
    assert "advance" not in vars(env.sim)  # the timer taken off again


def test_the_scaling_fit_gives_back_a_cost_linear_in_the_dofs(monkeypatch):
    """bench_scaling's least squares: a cost of exactly 3 us + 2 ns x DOFs gives back its
    intercept and slope (ns per DOF), R^2 = 1, and each point's cost over the
    reference point's."""

    def linear(sims, weight_on_bit, seconds, repeats, desc, progress):
        figures = {}
        for key, sim in sims.items():
            n_dof = 5 * sim.n_nodes
            us = 3.0 + 2e-3 * n_dof
            figures[key] = {"n_nodes": sim.n_nodes, "n_dof": n_dof, "us_per_step": us,
                            "ns_per_dof_step": us / n_dof * 1e3, "real_time_factor": 1.0}
        return figures

    monkeypatch.setattr(speed_core, "time_simulators", linear)
    result = speed_core.bench_scaling(TINY, progress=False)
    fit, points = result["fit"], result["points"]
    assert len({p["n_dof"] for p in points}) >= 2
    assert fit["us_per_step_intercept"] == pytest.approx(3.0)
    assert fit["ns_per_dof_step_slope"] == pytest.approx(2.0)
    assert fit["r_squared"] == pytest.approx(1.0)
    per_dof = [p["ns_per_dof_step"] for p in points]
    assert fit["cost_per_dof_max_over_min"] == pytest.approx(max(per_dof) / min(per_dof))
    where = (result["reference"]["pipe_length_m"], result["reference"]["pipe_element_length_m"])
    (ref,) = [p for p in points if (p["pipe_length_m"], p["pipe_element_length_m"]) == where]
    for p in points:
        assert p["cost_over_reference"] == pytest.approx(p["us_per_step"] / ref["us_per_step"])


def test_a_simulators_array_bytes_count_an_array_shared_by_views_once():
    from types import SimpleNamespace

    from drill_env.tools.speed.system import array_bytes

    state = np.zeros(100)  # 800 bytes
    holder = SimpleNamespace(state=state, head=state[:10], parts=[state[5:], np.zeros(5)],
                             name="not an array")
    assert array_bytes(holder) == 800 + 5 * 8


def test_env_only_rates_count_every_env_of_each_call(monkeypatch):
    import training.speed as training_speed

    clock = _Clock()
    monkeypatch.setattr(training_speed, "time", clock)

    class VecEnv:
        def step(self, action) -> None:
            clock.now += 0.5

    out = training_speed._env_only(VecEnv(), np.zeros((3, 4, 2), np.float32))
    # 3 calls of 4 envs in 1.5 s: 8 env steps/s, 1.5 s / 12 steps = 125 s per 1000
    assert out["steps_per_s"] == pytest.approx(8.0)
    assert out["cpu_s_per_1000"] == pytest.approx(125.0)


def test_best_of_rounds_keeps_the_fastest_round():
    from training.speed import _keep_faster

    best: dict = {}
    for rate in (5.0, 9.0, 7.0):
        _keep_faster(best, "run", {"steps_per_s": rate})
    assert best == {"run": {"steps_per_s": 9.0}}


def test_env_rates_keep_each_ones_fastest_round_in_turns_of_whole_calls(monkeypatch):
    """The functions take turns round by round (a change of load hits them alike), each
    keeps its fastest round, and a round's env steps are rounded UP to whole calls."""
    from drill_env.tools.speed import env as speed_env

    clock = _Clock()
    monkeypatch.setattr(speed_env, "time", clock)
    order: list[str] = []

    def step(name, walls):
        walls = iter(walls)

        def call() -> None:
            order.append(name)
            clock.now += next(walls)

        return call

    # 10 env steps in 2 rounds: 5 a round, 2 calls of four envs (not 1), 5 of one env
    one = step("one", [0.0] + [3.0] * 5 + [1.0] * 5)
    four = step("four", [0.0] + [1.0] * 2 + [2.0] * 2)
    rates = speed_env._interleaved_rates({"one": (one, 1), "four": (four, 4)},
                                         env_steps=10, rounds=2, warmup=1)
    assert order == ["one", "four"] + (["one"] * 5 + ["four"] * 2) * 2
    # the fastest rounds: 5 steps in 5 s, 8 steps in 2 s
    assert rates == pytest.approx({"one": 1.0, "four": 4.0})


def test_the_env_tables_ratios_divide_the_right_rates(monkeypatch):
    """Each row's ratio over the rates of the same rounds (x one env, x loop, the
    parallel ceiling, SB3's), and fast / full: one env, and batched at the LARGEST N."""
    import drill_env.vector
    from drill_env.tools.speed import env as speed_env

    level = {}

    class Env:
        def __init__(self, override=None) -> None:
            level["now"] = (override or {}).get("solver.fidelity")
            self.unwrapped = self

        def reset(self, **kwargs) -> tuple:
            return None, {}

        def step(self, action) -> None:
            pass

        def close(self) -> None:
            pass

    def rates(steps, env_steps, rounds, warmup):
        n = steps["loop"][1] if "loop" in steps else 1  # the one env alone first
        fast = level["now"] == "fast"
        # the fast level: one env 2 x full, its batch (2 x N) x full
        return {"single": 100.0 * (2 if fast else 1), "loop": 300.0,
                "batched": 600.0 * n * (2 * n if fast else 1), "physics": 800.0,
                "physics_one_thread": 200.0, "batched_sb3": 450.0}

    monkeypatch.setattr(speed_env, "make_env", Env)
    monkeypatch.setattr(speed_env, "_sb3_vec_env", lambda n, override: Env(override))
    monkeypatch.setattr(speed_env, "_PhysicsOnly", lambda envs, threads: Env())
    monkeypatch.setattr(speed_env, "_python_overhead", lambda env, action, n: {})
    monkeypatch.setattr(speed_env, "_interleaved_rates", rates)
    monkeypatch.setattr(drill_env.vector, "DrillStringVectorEnv",
                        lambda num_envs, **kwargs: Env(kwargs.get("physics")))
    settings = dataclasses.replace(TINY, env_counts=(1, 3))
    result = speed_env.bench_env(settings, progress=False)
    full = result["fidelity"]["full"]["counts"]
    assert [c["num_envs"] for c in full] == [1, 3]
    for c in full:
        n = c["num_envs"]
        assert c["loop_over_single"] == pytest.approx(3.0)
        assert c["batched_over_loop"] == pytest.approx(2.0 * n)
        assert c["batched_over_single"] == pytest.approx(6.0 * n)
        assert c["physics_threads_over_one"] == pytest.approx(4.0)
        assert c["batched_sb3_over_loop"] == pytest.approx(1.5)
        assert c["batched_sb3_over_single"] == pytest.approx(4.5)
    assert result["fast_over_full_single"] == pytest.approx(2.0)
    assert result["fast_over_full_batched"] == pytest.approx(6.0)


def test_the_core_figures_compare_each_level_with_numpy_over_the_full_levels_state(
        monkeypatch):
    """x NumPy is each level's real-time factor over the NumPy stepper's, which starts
    from the full level's simulator and is timed in ``reference_steps / repeats``-step
    chunks; fast / full is the fast level's real-time factor over the full one's."""
    import drill_env.physics.reference as reference

    def sim(dt: float, n_nodes: int) -> SimpleNamespace:
        return SimpleNamespace(dt=dt, n_nodes=n_nodes, hook_load_for=lambda wob: 1e6 - wob)

    made = {"full": sim(1e-3, 100), "fast": sim(4e-3, 60)}
    levels = iter(made)
    monkeypatch.setattr(speed_core, "settled_simulator", lambda *a: made[next(levels)])
    monkeypatch.setattr(speed_core, "time_simulators", lambda sims, *a: {
        name: {"real_time_factor": {"full": 10.0, "fast": 30.0}[name]} for name in sims})
    started: list = []

    class Stepper:
        def __init__(self, sim) -> None:
            started.append(sim)

        def advance(self, n, *args) -> None:
            pass

    monkeypatch.setattr(reference, "ReferenceStepper", Stepper)
    timed: list[int] = []
    monkeypatch.setattr(speed_core, "best_time", lambda run, repeats: timed.append(repeats)
                        or 0.5)
    settings = dataclasses.replace(TINY, reference_steps=10, repeats=2)
    result = speed_core.bench_core(settings, progress=False)
    assert started == [made["full"]] and timed == [2]
    ref = result["reference"]
    # 0.5 s for a chunk of 5 steps of 1 ms: 0.1 s a step, 0.01 x real time
    assert ref["steps"] == 10 and ref["time_step_s"] == 1e-3 and ref["n_dof"] == 500
    assert ref["us_per_step"] == pytest.approx(1e5)
    assert ref["real_time_factor"] == pytest.approx(0.01)
    assert result["fidelity"]["full"]["speedup_over_numpy"] == pytest.approx(1000.0)
    assert result["fidelity"]["fast"]["speedup_over_numpy"] == pytest.approx(3000.0)
    assert result["fast_over_full_speed"] == pytest.approx(3.0)


def test_the_scaling_costs_are_against_the_default_mesh_where_it_was_run(monkeypatch):
    """x ref is against the default string (1000 m of 10 m elements) where the sweeps
    include it, not against the smallest point."""

    def costs(sims, *args):
        return {key: {"n_nodes": sim.n_nodes, "n_dof": 5 * sim.n_nodes,
                      "us_per_step": 1.0 * sim.n_nodes, "ns_per_dof_step": 200.0,
                      "real_time_factor": 1.0} for key, sim in sims.items()}

    monkeypatch.setattr(speed_core, "time_simulators", costs)
    monkeypatch.setattr(speed_core, "settled_simulator", lambda config, *a: SimpleNamespace(
        config=config, n_nodes=round(config.string.drill_pipe.length
                                     / config.string.drill_pipe.element_length)))
    settings = dataclasses.replace(TINY, pipe_lengths=(200.0, 1000.0),
                                   pipe_element_lengths=(20.0, 10.0),
                                   mesh_pipe_length=1000.0)
    result = speed_core.bench_scaling(settings, progress=False)
    assert result["reference"] == {"pipe_length_m": 1000.0, "pipe_element_length_m": 10.0}
    x_ref = {(p["pipe_length_m"], p["pipe_element_length_m"]): p["cost_over_reference"]
             for p in result["points"]}
    assert x_ref == pytest.approx({(200.0, 10.0): 0.2, (1000.0, 20.0): 0.5,
                                   (1000.0, 10.0): 1.0})
