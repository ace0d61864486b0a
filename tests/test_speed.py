"""``drill-env speed``: the quick run produces every figure, finite and positive.

No timing thresholds: the figures depend on the machine and its load.
"""

import dataclasses
import json
import math
import sys
import types
from pathlib import Path
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
    text = format_env(result)
    assert "the machine's parallel gain now" in text
    # each N's ratios against the one env of its own rounds, printed: a reader can check
    # loop / single (the headline one env is timed apart)
    for name, fig in result["fidelity"].items():
        (row,) = fig["counts"]
        line = next(s for s in text.splitlines() if f"{name}: one env in N=2's rounds" in s)
        assert f"{row['single_steps_per_s']:.0f}" in line
        assert row["loop_over_single"] == pytest.approx(
            row["loop_steps_per_s"] / row["single_steps_per_s"])


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
    (tmp_path / "scratch.txt").write_text("notes")  # untracked: no source changed
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


# --------------------------------------------------------------- mutation round X


def test_a_clocked_part_adds_every_call_and_a_call_inside_another_counts_for_the_outer(
        monkeypatch):
    """Each call adds its time to its part; a policy call made inside ``train()`` counts
    once, for the update (or the parts would sum past the wall time)."""
    import training.speed as training_speed

    clock = _Clock()
    monkeypatch.setattr(training_speed, "time", clock)

    class Model:
        def train(self) -> None:
            clock.now += 2.0
            self.predict()

        def predict(self) -> None:
            clock.now += 1.0

    model = Model()
    parts = dict.fromkeys((*training_speed.PARTS, "depth"), 0.0)
    training_speed._timed(model, "train", parts, "update")
    training_speed._timed(model, "predict", parts, "policy")
    model.predict()
    model.train()
    model.predict()
    assert parts["policy"] == pytest.approx(2.0) and parts["update"] == pytest.approx(3.0)
    assert parts["env"] == 0.0 and parts["depth"] == 0


class _TwoThreadClock(_Clock):
    """Two threads busy all the time: CPU time runs at twice the wall time."""

    def process_time(self) -> float:
        return 2.0 * self.now


def _fake_training(monkeypatch, clock: _Clock, default_threads: int,
                   whole: int = 4) -> tuple[list, list]:
    """training/speed.py's model and env replaced by fakes on ``clock``: per call of the
    4 envs, policy 1 ms, env 3 ms, SB3's own 1 ms and an update of 5 ms (fused Adam, one
    torch thread; 10 ms unfused; divided by the threads); env-only calls 2 ms with random
    actions, 1 ms with the constant one; ``learn`` runs whole blocks of ``whole`` env
    steps (PPO's rollouts). Gives back the ``learn`` calls (steps asked, whether
    the step count restarts, torch threads, Adam fused) and the env-only calls' shapes."""
    import gymnasium as gym
    import torch

    import training.speed as training_speed

    learned: list = []
    env_only_calls: list = []

    class VecEnv:
        num_envs = 4
        action_space = gym.spaces.Box(-1.0, 1.0, (2,), np.float32)

        def step_wait(self) -> None:
            clock.now += 3e-3

        def step(self, action) -> None:
            env_only_calls.append(action.shape)
            clock.now += 2e-3 if np.any(action) else 1e-3

        def close(self) -> None:
            pass

    class Policy(torch.nn.Module):
        def __init__(self) -> None:
            super().__init__()
            self.weight = torch.nn.Parameter(torch.zeros(1))
            self.optimizer = torch.optim.Adam(self.parameters())

        def forward(self, obs=None) -> None:
            clock.now += 1e-3

        def predict(self, obs=None) -> None:
            clock.now += 1e-3

    class Model:
        policy_kwargs = {"net_arch": [8, 8]}

        def __init__(self, venv) -> None:
            self.venv, self.policy = venv, Policy()
            self.num_timesteps = 0

        def train(self) -> None:
            clock.now += self.update_s

        def learn(self, total, reset_num_timesteps=True, callback=None) -> None:
            fused = bool(self.policy.optimizer.param_groups[0]["fused"])
            learned.append((total, reset_num_timesteps, callback, fused))
            run = -(-total // whole) * whole
            self.num_timesteps = run + (0 if reset_num_timesteps else self.num_timesteps)
            calls = run // self.venv.num_envs
            self.update_s = calls * (5e-3 if fused else 10e-3) / callback
            for _ in range(calls):
                self.policy.forward()
                self.venv.step_wait()
                clock.now += 1e-3
            self.train()

    config = SimpleNamespace(seed=0, n_envs=4, torch_threads=1, fused_adam=True,
                             hyperparams={"learning_starts": 100})
    monkeypatch.setattr(training_speed, "time", clock)
    monkeypatch.setattr(training_speed, "load_config", lambda task, algo: config)
    monkeypatch.setattr(training_speed, "make_train_env", lambda config, seed: VecEnv())
    monkeypatch.setattr(training_speed, "new_model", lambda config, venv: Model(venv))
    monkeypatch.setattr(training_speed, "torch_threads_callback", lambda count: count)
    monkeypatch.setattr(torch, "get_num_threads", lambda: default_threads)
    return learned, env_only_calls


def test_the_training_section_figures_are_the_rates_shares_and_ratios_of_each_row(
        monkeypatch):
    """bench_training on a fake model, env and clock: each row's steps/s, CPU per 1000
    steps, shares of the wall time, ratio to the env alone, and which thread count and
    Adam kernel it ran with; the warm-up fills SAC's learning_starts."""
    import training.speed as training_speed

    learned, env_only_calls = _fake_training(monkeypatch, _TwoThreadClock(), default_threads=2)
    out = training_speed.bench_training({"ppo": 400, "sac": 100}, rounds=2, progress=False)
    assert out["torch_default_threads"] == 2
    assert set(out["runs"]) == {"stick_slip ppo", "drilling sac"}
    run = out["runs"]["stick_slip ppo"]
    assert run["network"] == [8, 8] and run["steps"] == 400 and run["rounds"] == 2
    rows = run["rows"]
    # 100 calls of 4 envs: 10 ms a call fused, 15 ms unfused, 7.5 ms on two threads;
    # the env alone 2 ms a call (random actions) and 1 ms (constant): 2000 and 4000 /s
    expected = {
        "torch 1 thread(s) (default)": (400.0, 0.2, 5.0, 0.3, 0.1, 0.5, 0.1),
        "torch 1 thread(s), Adam not fused": (400 / 1.5, 0.2 / 1.5, 7.5, 0.2, 0.1 / 1.5,
                                              1 / 1.5, 0.1 / 1.5),
        "torch 2 threads": (400 / 0.75, 0.2 / 0.75, 3.75, 0.4, 0.1 / 0.75, 0.25 / 0.75,
                            0.1 / 0.75)}
    assert list(rows) == [*expected, "env only, random actions", "env only, constant action"]
    for label, figures in expected.items():
        assert tuple(rows[label][k] for k in (
            "steps_per_s", "x env only", "cpu_s_per_1000", "env_share", "policy_share",
            "update_share", "rest_share")) == pytest.approx(figures), label
    assert rows["env only, random actions"] == pytest.approx(
        {"steps_per_s": 2000.0, "cpu_s_per_1000": 1.0, "x env only": 1.0})
    assert rows["env only, constant action"] == pytest.approx(
        {"steps_per_s": 4000.0, "cpu_s_per_1000": 0.5, "x env only": 2.0})
    assert run["random_over_constant"] == pytest.approx(0.5)
    # PPO then SAC: an untimed warm-up of learning_starts + 2 rounds' steps, then per
    # round the three rows in turn (threads, fused), continuing the step count
    ppo, sac = learned[:7], learned[7:]
    assert ppo == [(900, True, 1, False), *2 * [(400, False, 1, True), (400, False, 1, False),
                                                (400, False, 2, True)]]
    assert sac[0] == (300, True, 1, False) and len(sac) == 7
    # the env alone: steps // n_envs calls of all 4 envs, both action sets, each round
    assert env_only_calls == 2 * 2 * [(4, 2)] * 100 + 2 * 2 * [(4, 2)] * 25


def test_the_training_rates_count_the_steps_run_not_those_asked(monkeypatch):
    """PPO runs whole rollouts: 5,000 steps asked of a 4,096-step rollout ran 8,192, and
    steps/s came out 39 % low (a mutation round). The fake runs blocks of 64 steps: 400
    asked run 448, 112 calls of 10 ms, 400 steps/s all the same."""
    import training.speed as training_speed

    _fake_training(monkeypatch, _TwoThreadClock(), default_threads=1, whole=64)
    out = training_speed.bench_training({"ppo": 400, "sac": 100}, rounds=1, progress=False)
    row = out["runs"]["stick_slip ppo"]["rows"]["torch 1 thread(s) (default)"]
    assert row["steps_per_s"] == pytest.approx(400.0)
    assert row["cpu_s_per_1000"] == pytest.approx(5.0)


def test_the_training_table_puts_each_figure_under_its_heading(monkeypatch):
    import training.speed as training_speed

    _fake_training(monkeypatch, _TwoThreadClock(), default_threads=1)
    text = training_speed.format_training(
        training_speed.bench_training({"ppo": 400, "sac": 100}, rounds=1, progress=False))
    head = text.splitlines()[1].split()
    assert head == ["run", "what", "steps/s", "x", "env", "only", "CPU", "s/1000", "env",
                    "policy", "update", "rest"]
    lines = {line[19:57].strip(): line[57:].split() for line in text.splitlines()[2:]
             if line.startswith("stick_slip ppo")}
    assert lines["torch 1 thread(s) (default)"] == [
        "400", "0.20", "5.00", "30%", "10%", "50%", "10%"]
    assert lines["env only, constant action"] == ["4000", "2.00", "0.50"]
    assert "stick_slip ppo     random / constant actions, env only: 0.50" in text
    # one thread is torch's own count here: no third row
    assert "torch 1 threads" not in text


def test_the_training_section_runs_sac_for_a_quarter_of_ppos_steps(monkeypatch):
    import training.speed as training_speed

    seen = []
    monkeypatch.setattr(training_speed, "bench_training",
                        lambda steps, rounds, progress: seen.append((steps, rounds)) or {})
    training_speed.bench(SimpleNamespace(train_steps=4096, train_rounds=3), progress=False)
    assert seen == [({"ppo": 4096, "sac": 1024}, 3)]


def test_the_compile_section_starts_cold_in_a_new_numba_cache_then_warm(tmp_path,
                                                                        monkeypatch):
    """The cold run's process gets a new, empty NUMBA_CACHE_DIR and the warm one the same
    (filled) folder; cold / warm divides the in-process first-step times and the process
    wall time is the whole subprocess's. A change of the sources is noticed and said."""
    from drill_env.tools.speed import system

    clock = _Clock()
    monkeypatch.setattr(system, "time", clock)
    users = tmp_path / "users-cache"
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(users))
    caches: list[str] = []

    def run(argv, env, **kwargs):
        cache = Path(env["NUMBA_CACHE_DIR"])
        cache.mkdir(exist_ok=True)
        warm = (cache / "index.nbi").exists()
        caches.append(str(cache))
        (cache / "index.nbi").write_text("")
        clock.now += 1.5 if warm else 6.0
        first = 1.0 if warm else 5.0
        return SimpleNamespace(returncode=0, stderr="", stdout="numba says hello\n" + json.dumps(
            {"first_step_s": first, "import_s": 0.5, "make_s": 0.25,
             "reset_and_step_s": first - 0.75}))

    monkeypatch.setattr(system.subprocess, "run", run)
    stamps = iter([1.0, 1.0])
    monkeypatch.setattr(system, "source_stamp", lambda: next(stamps))
    result = system.bench_compile(TINY, progress=False)
    # one new folder for both, removed after: not the user's numba cache
    assert caches[0] == caches[1] != str(users) and not Path(caches[0]).exists()
    assert result["cold"]["first_step_s"] == 5.0 and result["warm"]["first_step_s"] == 1.0
    assert result["cold"]["process_wall_s"] == pytest.approx(6.0)
    assert result["warm"]["process_wall_s"] == pytest.approx(1.5)
    assert result["cold_over_warm"] == pytest.approx(5.0)
    assert result["sources_changed"] is False
    text = system.format_compile(result)
    assert "WARNING" not in text and "cold / warm: 5.0 x" in text
    cold = next(line.split() for line in text.splitlines() if line.startswith("cold  "))
    assert cold == ["cold", "5.00", "0.50", "0.25", "4.25", "6.00"]

    stamps = iter([1.0, 2.0])
    result = system.bench_compile(TINY, progress=False)
    assert result["sources_changed"] is True
    assert "WARNING: drill_env sources changed" in system.format_compile(result)


def test_the_memory_per_env_is_the_growth_after_the_first_envs_garbage_is_collected(
        monkeypatch):
    """memory_probe's growth and build time are per env of the ``n_envs`` built after the
    first one (whose garbage is collected before the baseline)."""
    from drill_env.tools.speed import system

    clock = _Clock()
    monkeypatch.setattr(system, "time", clock)
    memory = {"live": 10_000, "garbage": 0}

    def make_env(override):
        memory["live"] += 4096
        memory["garbage"] += 2048
        clock.now += 0.05
        sim = SimpleNamespace(state=np.zeros(64), n_nodes=7)
        return SimpleNamespace(reset=lambda seed: None, unwrapped=SimpleNamespace(sim=sim))

    monkeypatch.setattr(system, "make_env", make_env)
    monkeypatch.setattr(system, "gc", SimpleNamespace(collect=lambda: memory.update(garbage=0)))
    monkeypatch.setattr(system, "_rss_bytes", lambda: memory["live"] + memory["garbage"])
    # psutil imported by someone: the RSS is still /proc's, and named so (it said psutil)
    monkeypatch.setitem(sys.modules, "psutil", types.ModuleType("psutil"))
    result = system.memory_probe(3)
    assert result["method"] == "/proc/self/statm"
    assert result["growth_bytes_per_env"] == pytest.approx(4096.0)
    assert result["build_ms_per_env"] == pytest.approx(50.0)
    assert result["simulator_array_bytes"] == 64 * 8
    assert (result["envs"], result["n_nodes"]) == (3, 7)


@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="reads Linux's /proc")
def test_the_rss_is_the_resident_set_not_the_address_space():
    from drill_env.tools.speed.system import _rss_bytes

    with open("/proc/self/status") as f:
        fields = dict(line.split(":", 1) for line in f)
    resident = int(fields["VmRSS"].split()[0]) * 1024
    assert 0.8 < _rss_bytes() / resident < 1.25


def test_an_array_met_first_as_a_view_counts_its_whole_base():
    from drill_env.tools.speed.system import array_bytes

    state = np.zeros(100)
    assert array_bytes(SimpleNamespace(head=state[:10], state=state)) == 800


def test_the_memory_section_builds_the_settings_envs_and_divides_growth_by_the_arrays(
        monkeypatch):
    from drill_env.tools.speed import system

    codes: list[str] = []

    def run(argv, **kwargs):
        codes.append(argv[-1])
        return SimpleNamespace(returncode=0, stderr="", stdout=json.dumps(
            {"simulator_array_bytes": 20480, "n_nodes": 7, "envs": 3,
             "growth_bytes_per_env": 102400.0, "method": "/proc/self/statm",
             "build_ms_per_env": 12.0}))

    monkeypatch.setattr(system.subprocess, "run", run)
    result = system.bench_memory(dataclasses.replace(TINY, memory_envs=3), progress=False)
    assert codes[0].endswith("print(json.dumps(memory_probe(3)))")
    assert result["growth_over_simulator_arrays"] == pytest.approx(5.0)
    rows = system.format_memory(result).splitlines()  # KiB
    assert any(line.split()[-2:] == ["100", "5.00"] for line in rows if "growth" in line)
    assert any(line.split()[-2:] == ["20", "1.00"] for line in rows if "simulator" in line)


def _toy_sections(clock: _Clock) -> dict:
    """Sections that take 2 s and 3 s on ``clock`` and print one line each."""
    def section(seconds: float):
        def bench(settings, progress=True) -> dict:
            clock.now += seconds
            return {"seconds": seconds}

        return bench, lambda figures: f"Toy {figures['seconds']:g} s"

    return {"two": section(2.0), "three": section(3.0)}


def test_speed_md_heads_its_tables_with_the_command_and_the_run_it_was(tmp_path,
                                                                      monkeypatch):
    """The first line of speed.md is the command that made it (--quick, custom settings,
    --sections only where some were left out), the threading layer, the load at the start
    and at the end and whether the sources changed; speed.json has each section's and the
    whole run's wall time and the settings."""
    clock = _Clock()
    monkeypatch.setattr(speed, "time", clock)
    monkeypatch.setattr(speed, "threading_layer", lambda: "tbb")
    monkeypatch.setattr(speed, "plot_scaling", lambda figures, path: None)
    loads = iter([(0.5, 9.0, 9.0), (1.5, 9.0, 9.0)])
    monkeypatch.setattr(speed.os, "getloadavg", lambda: next(loads))
    toys = _toy_sections(clock)
    for name in speed.RUNNERS:
        monkeypatch.setitem(speed.RUNNERS, name, toys["two"])
    stamps = iter([1.0, 1.0])
    monkeypatch.setattr(speed, "source_stamp", lambda: next(stamps))
    run_speed(speed.SECTIONS, QUICK, tmp_path, progress=False, echo=None)
    head = (tmp_path / "speed.md").read_text().splitlines()[0]
    assert head.startswith("`drill-env speed --quick`, ")
    assert "(tbb layer); load average 0.5 at the start, 1.5 at the end; sources " \
           "unchanged during the run." in head

    said: list[str] = []
    loads = iter([(0.5, 9.0, 9.0), (1.5, 9.0, 9.0)])
    stamps = iter([1.0, 2.0])
    result = run_speed(("two", "three"), TINY, tmp_path, progress=False, echo=said.append,
                       runners=toys)
    head = (tmp_path / "speed.md").read_text().splitlines()[0]
    assert head.startswith("`drill-env speed (custom settings) --sections two,three`, ")
    assert head.endswith("; SOURCES CHANGED DURING THE RUN.")
    assert any("WARNING: drill_env sources changed during the run" in s for s in said)
    saved = json.loads((tmp_path / "speed.json").read_text())
    assert saved["machine"]["sources_changed_during_run"] is True
    assert saved["machine"]["numba_threading_layer"] == "tbb"
    assert result["settings"] == dataclasses.asdict(TINY)
    assert saved["two"]["section_wall_s"] == pytest.approx(2.0)
    assert saved["three"]["section_wall_s"] == pytest.approx(3.0)
    assert saved["total_wall_s"] == pytest.approx(5.0) == result["total_wall_s"]


def test_an_unknown_section_is_refused_before_any_work(tmp_path):
    out = tmp_path / "out"
    said: list[str] = []
    with pytest.raises(ValueError, match="bogus"):
        run_speed(("core", "bogus"), TINY, out, progress=False, echo=said.append)
    assert said == [] and not out.exists()


def test_the_speed_command_runs_every_section_and_training_unless_told(tmp_path,
                                                                       monkeypatch):
    seen = []
    monkeypatch.setattr(speed, "run_speed", lambda sections, settings, out, runners: seen.append(
        (sections, settings, set(runners))))
    assert main(["speed", "--quick", "--out", str(tmp_path)]) == 0
    assert main(["speed", "--sections", "memory,training", "--out", str(tmp_path)]) == 0
    assert seen == [((*speed.SECTIONS, "training"), QUICK, {"training"}),
                    (("memory", "training"), speed.FULL, {"training"})]
