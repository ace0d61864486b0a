"""Sweeps on Ray (drill_env.distributed): same numbers as local processes, a lost
worker's task retried and counted once, an interrupted sweep resumed.

The cluster is real: a head and two one-CPU worker nodes on this machine, started by
``ray.cluster_utils.Cluster`` (separate GCS, raylet and worker processes per node); the
sweep joins it by its address as it would join a remote one."""

from __future__ import annotations

import json
import os
import signal
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from helpers import stop_after

from drill_env.stability_map import MapSettings, stability_maps

# Ray is the distributed extra (make test installs it; pip install -e ".[dev]" alone does
# not): without it these tests are skipped, not the whole suite's collection stopped
ray = pytest.importorskip("ray")
from ray.cluster_utils import Cluster  # noqa: E402

SETTINGS = MapSettings(seconds=4.0, measure=2.0)
GRID = ([40.0, 80.0, 120.0], [40e3, 90e3, 140e3])
POSITIONS = ["P1", "P4"]


@pytest.fixture(scope="module")
def cluster():
    c = Cluster(initialize_head=True,
                head_node_args={"num_cpus": 0, "include_dashboard": False})
    for _ in range(2):
        c.add_node(num_cpus=1)
    c.wait_for_nodes()
    yield c
    if ray.is_initialized():
        ray.shutdown()
    c.shutdown()


@pytest.fixture(scope="module")
def local_points(tmp_path_factory):
    """The map's points computed on local processes, as stored."""
    store = tmp_path_factory.mktemp("local") / "points.jsonl"
    maps = stability_maps(POSITIONS, settings=SETTINGS, grid_points=GRID, store=store,
                          workers=2)
    return maps, points(store)


def points(store: Path) -> dict[str, dict]:
    lines = [json.loads(line) for line in store.read_text().splitlines()]
    keys = [entry["key"] for entry in lines]
    assert len(keys) == len(set(keys)), "a point was stored twice"
    return {entry["key"]: entry["result"] for entry in lines}


def same_maps(a_maps, b_maps):
    for a, b in zip(a_maps, b_maps, strict=True):
        np.testing.assert_array_equal(a.tested, b.tested)
        np.testing.assert_array_equal(a.unstable, b.unstable)


def test_a_web_address_or_auto_without_a_cluster_says_what_to_give(tmp_path):
    """A dashboard's http:// address got Ray's advice to unset a RAY_ADDRESS nobody set,
    and 'auto' where no cluster runs Ray's advice to set its own --address flag beside
    our token hint (a new user's trial): each says what to give instead, at once. (First
    in the file: Ray's 'auto' also finds a cluster by its processes, and the module's
    cluster, started by the tests below, runs until the last of them; a cluster of the
    user's skips the 'auto' half.)"""
    import subprocess

    from drill_env.distributed import RayExecutor

    if ray.is_initialized():  # a sweep's own session only: the executor joins no other
        ray.shutdown()
    with pytest.raises(ValueError, match=r"'http://127.0.0.1:8265' is a web address .* "
                                         r"host:port \(6379 by default"):
        RayExecutor("http://127.0.0.1:8265")
    from ray._private.services import find_gcs_addresses

    if find_gcs_addresses():  # (Ray's 'auto' joins a cluster it finds by its processes)
        pytest.skip("a Ray cluster runs on this machine: 'auto' would join it")
    script = ("from drill_env.distributed import RayExecutor\n"
              "try:\n    RayExecutor('auto')\nexcept ConnectionError as error:\n"
              "    print(error)\n")
    # (Ray's temporary folder where no cluster ever started: 'auto' finds none there)
    env = {k: v for k, v in os.environ.items() if not k.startswith("RAY_ADDRESS")}
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          env={**env, "RAY_TMPDIR": str(tmp_path)}, timeout=120)
    assert done.stdout.strip() == (
        "ray_address: 'auto' found no Ray cluster started on this machine: `ray start "
        "--head` starts one to join, and 'local' one for this command alone"), done.stderr


def test_a_map_on_a_ray_cluster_equals_the_local_process_map(cluster, local_points,
                                                             tmp_path):
    maps, expected = local_points
    store = tmp_path / "points.jsonl"
    on_ray = stability_maps(POSITIONS, settings=SETTINGS, grid_points=GRID, store=store,
                            ray_address=cluster.address)
    same_maps(on_ray, maps)
    assert points(store) == expected  # every number, not just the map
    assert not ray.is_initialized()  # the executor let go of the cluster


def ray_task_processes() -> list[int]:
    """Pids of Ray worker processes running a task now (their title is ray::_call)."""
    pids = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            cmdline = Path(f"/proc/{entry}/cmdline").read_bytes()
        except OSError:
            continue
        if cmdline.startswith(b"ray::_call"):
            pids.append(int(entry))
    return pids


def test_a_killed_worker_loses_no_point_and_counts_none_twice(cluster, local_points,
                                                            tmp_path):
    maps, expected = local_points
    killed: list[int] = []
    stop = threading.Event()

    def kill_one_busy_worker():
        while not stop.is_set() and not killed:
            for pid in ray_task_processes():
                os.kill(pid, signal.SIGKILL)
                killed.append(pid)
                break
            time.sleep(0.01)

    killer = threading.Thread(target=kill_one_busy_worker, daemon=True)
    killer.start()
    store = tmp_path / "points.jsonl"
    simulated = []
    try:
        on_ray = stability_maps(POSITIONS, settings=SETTINGS, grid_points=GRID, store=store,
                                ray_address=cluster.address,
                                progress=lambda: simulated.append(1))
    finally:
        stop.set()
        killer.join()
    assert killed, "no busy worker was found to kill"
    same_maps(on_ray, maps)
    assert points(store) == expected
    assert len(simulated) == len(expected)  # each point reported once


def test_an_interrupted_ray_sweep_resumes_computing_only_the_missing_points(
        cluster, local_points, tmp_path):
    maps, expected = local_points
    store = tmp_path / "points.jsonl"
    with pytest.raises(KeyboardInterrupt):
        stability_maps(POSITIONS, settings=SETTINGS, grid_points=GRID, store=store,
                       ray_address=cluster.address, progress=stop_after(3))
    # the three done before the interrupt, and those in flight that ended during the wait
    kept = points(store)
    assert 3 <= len(kept) <= len(expected)
    assert all(kept[key] == expected[key] for key in kept)
    resumed = []
    again = stability_maps(POSITIONS, settings=SETTINGS, grid_points=GRID, store=store,
                           ray_address=cluster.address, progress=lambda: resumed.append(1))
    assert len(resumed) == len(expected) - len(kept)
    same_maps(again, maps)
    assert points(store) == expected


def test_a_bad_ray_address_names_the_field():
    from drill_env.distributed import RayExecutor

    with pytest.raises(ValueError, match="ray_address"):
        RayExecutor("")


def test_an_address_where_nothing_answers_fails_at_once():
    """Ray would retry it for minutes; one TCP attempt says what is wrong."""
    import socket

    from drill_env.distributed import RayExecutor

    with socket.socket() as probe:  # a port nothing listens on once the probe is closed
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    if ray.is_initialized():  # a sweep's own session only: the executor joins no other
        ray.shutdown()
    for address in (f"127.0.0.1:{port}", f"ray://127.0.0.1:{port}"):
        # our probe's message (Ray's own retries would end in another one, minutes later)
        with pytest.raises(ConnectionError, match=f"no Ray cluster at '{address}': nothing "
                                                  "answers"):
            RayExecutor(address)
    # what is not host:port is left to Ray's own check, which names it (no probe here)
    from drill_env.distributed import _check_reachable

    for other in ("auto", "http://127.0.0.1:1", "::1", "127.0.0.1"):
        assert _check_reachable(other) is None
    with pytest.raises(ConnectionError, match="nothing answers"):
        _check_reachable(f"[::1]:{port}")


def test_an_address_where_something_other_than_ray_answers_fails_at_once(monkeypatch):
    """An SSH or HTTP server at the address (a wrong port): Ray retried it for ~20 s,
    printing its own errors. A gRPC server (as Ray's GCS; the cluster tests join a real
    one) passes the check."""
    import socket
    from concurrent import futures

    import grpc

    from drill_env.distributed import _check_reachable

    for greeting in (b"SSH-2.0-OpenSSH_9.6\r\n", b"HTTP/1.1 400 Bad Request\r\n\r\n", b""):
        with socket.socket() as server:
            server.bind(("127.0.0.1", 0))
            server.listen()
            port = server.getsockname()[1]

            def answer(server=server, greeting=greeting):
                connection, _ = server.accept()
                with connection:
                    connection.sendall(greeting)

            thread = threading.Thread(target=answer, daemon=True)
            thread.start()
            started = time.perf_counter()
            with pytest.raises(ConnectionError, match=f"no Ray cluster at '127.0.0.1:{port}': "
                                                      "something answers there, but not Ray"):
                _check_reachable(f"127.0.0.1:{port}")
            assert time.perf_counter() - started < 5.0
            thread.join(5.0)
    # one that sends nothing in time is said as such (a head too busy is not "not Ray")
    monkeypatch.setattr("drill_env.distributed.CONNECT_TIMEOUT", 0.5)
    with socket.socket() as server:
        server.bind(("127.0.0.1", 0))
        server.listen()
        port = server.getsockname()[1]
        with pytest.raises(ConnectionError, match=f"nothing came back from '127.0.0.1:{port}' "
                                                  "in 0.5 s"):
            _check_reachable(f"127.0.0.1:{port}")
    server = grpc.server(futures.ThreadPoolExecutor(max_workers=1))
    port = server.add_insecure_port("127.0.0.1:0")
    server.start()
    try:
        assert _check_reachable(f"127.0.0.1:{port}") is None
        assert _check_reachable(f"ray://127.0.0.1:{port}") is None
    finally:
        server.stop(None)


def test_the_stability_map_command_runs_on_the_cluster(cluster, tmp_path):
    from drill_cli.main import main

    args = ["stability-map", "--positions", "P1", "--rpm-step", "100", "--wob-step", "100",
            "--max-rpm", "200", "--max-wob", "200", "--seconds", "4", "--out", str(tmp_path)]
    assert main([*args, "--ray-address", cluster.address]) == 0
    on_ray = points(tmp_path / "stability_map.points.jsonl")
    local = tmp_path / "local"
    assert main([*args[:-1], str(local), "--workers", "1"]) == 0
    assert points(local / "stability_map.points.jsonl") == on_ray


def test_a_training_seed_sweep_runs_its_trials_on_the_cluster(cluster, tmp_path):
    from test_training import tiny_config

    from training.sweep import train_seeds

    # no evaluation within the run (eval_freq > steps): a short sweep still summarises
    config = tiny_config(eval_freq=10**6)
    results = train_seeds(config, [7, 8], tmp_path, ray_address=cluster.address,
                          progress=False)
    assert [r["seed"] for r in results] == [7, 8]
    for r in results:
        assert (Path(r["run"]) / "model.zip").exists() and r["env_steps"] >= 2048
        assert r["best_return"] is None
    assert f"| 7 | {results[0]['env_steps']} | - |" in (tmp_path / "train_sweep.md").read_text()


def test_the_benchmark_on_the_cluster_equals_the_local_benchmark(cluster, tmp_path):
    from agents.benchmark import run_benchmark
    from agents.settings import BenchmarkSettings

    settings = BenchmarkSettings(duration=4.0, warmup=2.0, fidelity="fast")
    args = (["stiff", "z-torque"], ["stick_slip"], [0, 1])
    local = run_benchmark(*args, tmp_path / "local", settings, workers=2, progress=False)
    on_ray = run_benchmark(*args, tmp_path / "ray", settings, ray_address=cluster.address,
                           progress=False)
    assert on_ray == local


def test_evaluate_on_the_cluster_equals_evaluate_here(cluster, tmp_path):
    """``drill-env evaluate RUN --ray-address``: the shipped stick-slip policy against the
    classical controllers and the trivial policies (random actions drawn from the episode
    seed, wherever it runs) on one held-out seed, the same rows as on local processes."""
    import csv

    from drill_cli.main import main

    run = Path(__file__).parent.parent / "agents" / "trained" / "stick_slip"
    tables = []
    for where, extra in (("ray", ["--ray-address", cluster.address]),
                         ("local", ["--workers", "1"])):
        assert main(["evaluate", str(run), "--seeds", "1", "--out", str(tmp_path / where),
                     *extra]) == 0
        with (tmp_path / where / "benchmark.csv").open() as f:
            tables.append(sorted(list(csv.DictReader(f)), key=lambda r: r["controller"]))
    assert tables[0] == tables[1] and len(tables[0]) == 10


def _wait_for_the_other(paths: tuple[str, str]) -> bool:
    """Mark this task started; whether the other task starts too within 30 s."""
    mine, other = paths
    Path(mine).touch()
    deadline = time.monotonic() + 30.0
    while time.monotonic() < deadline:
        if Path(other).exists():
            return True
        time.sleep(0.05)
    return False


def test_a_sweep_runs_as_many_tasks_at_once_as_the_cluster_has_cpus(cluster, tmp_path):
    """The module's rule: up to 2 x the cluster's CPUs in flight, so the cluster's CPUs
    work side by side: on the 2 CPUs here two tasks each see the other start (one task
    in flight at a time left a CPU idle, and each waited in vain)."""
    import ray.cloudpickle

    from drill_env.distributed import RayExecutor

    ray.cloudpickle.register_pickle_by_value(sys.modules[__name__])  # the workers can't
    executor = RayExecutor(cluster.address)                        # import this file
    a, b = str(tmp_path / "a"), str(tmp_path / "b")
    try:
        results = dict(executor.map_unordered(_wait_for_the_other, [(a, b), (b, a)]))
    finally:
        executor.close()
        ray.cloudpickle.unregister_pickle_by_value(sys.modules[__name__])
    assert results == {0: True, 1: True}


def _fail_and_count(path: str) -> None:
    """A task that raises every time it runs, leaving one line per run in ``path``."""
    with open(path, "a") as f:
        f.write("ran\n")
    raise ValueError("this point cannot be computed")


def test_a_task_that_raises_is_not_run_again_and_stops_the_sweep_with_its_error(
        cluster, tmp_path):
    """Retries are for lost workers only: a task is a pure function of its item, so
    running one that raised again would raise again (and take the time three times)."""
    import ray.cloudpickle

    from drill_env.distributed import RayExecutor

    ray.cloudpickle.register_pickle_by_value(sys.modules[__name__])  # the workers can't
    executor = RayExecutor(cluster.address)                        # import this file
    log = tmp_path / "runs.txt"
    try:
        with pytest.raises(ValueError, match="this point cannot be computed"):
            list(executor.map_unordered(_fail_and_count, [str(log)]))
    finally:
        executor.close()
        ray.cloudpickle.unregister_pickle_by_value(sys.modules[__name__])
    assert log.read_text().splitlines() == ["ran"]


def _warn_often(n: int) -> int:
    import warnings

    for _ in range(100):
        warnings.warn("at every step", RuntimeWarning, stacklevel=1)
    return n


class _CodedWarning(UserWarning):
    """A warning not rebuilt from its text alone."""

    def __init__(self, message: str, code: int) -> None:
        super().__init__(message)
        self.code = code


def _warn_coded(n: int) -> int:
    import warnings

    warnings.warn(_CodedWarning("coded", 7), stacklevel=1)
    return n


def test_a_warning_a_task_gives_on_ray_is_given_here(cluster, capsys):
    """A Ray worker's stderr does not reach the command: a benchmark on a curved well said
    its WOB above the string's limit on local processes and nothing on Ray (an outside
    check). The warnings come back with the result and are given in the driver."""
    import warnings

    import ray.cloudpickle

    from drill_env.distributed import RayExecutor

    ray.cloudpickle.register_pickle_by_value(sys.modules[__name__])  # _warn_often
    executor = RayExecutor(cluster.address)
    said = ["weight_on_bit: 100 kN is above the limit", "the pipe is in compression"]
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            results = sorted(executor.map_unordered(warnings.warn, said))
            # a task that gives the same warning at every step sends it back once
            assert list(executor.map_unordered(_warn_often, [3])) == [(0, 3)]
            # one that cannot be given again here is printed, and the result kept
            assert list(executor.map_unordered(_warn_coded, [5])) == [(0, 5)]
    finally:
        executor.close()
        ray.cloudpickle.unregister_pickle_by_value(sys.modules[__name__])
    assert results == [(0, None), (1, None)]
    assert sorted(str(w.message) for w in caught) == sorted([*said, "at every step"])
    assert {w.category for w in caught} == {UserWarning, RuntimeWarning}
    assert "_CodedWarning: coded" in capsys.readouterr().err
    # given at the task's own line, not at the executor's
    assert any(w.filename == __file__ for w in caught)


def test_a_warning_given_again_is_filtered_by_its_module_as_where_it_was_said():
    """A filter by module (``-W ignore::UserWarning:drill_env.env_config``) silenced the
    WOB-limit warning on local processes but not from a Ray task: given again with its
    file alone, its module read as the file's path."""
    import re
    import warnings

    from drill_env.distributed import _call, _said

    reply = _call(_warn_limit, 4)
    assert reply[1][0][4] == __name__
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        warnings.filterwarnings("ignore", module=re.escape(__name__) + "$")
        assert _said(reply, {}) == 4
    assert caught == []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        warnings.filterwarnings("ignore", module="another_module")
        _said(reply, {})
    assert [str(w.message) for w in caught] == ["limit"]


def test_a_warning_many_tasks_give_is_given_here_once_per_place():
    """_said's ``registry`` (the sweep's): under Python's default filter each place's first
    warning is shown once, however many tasks of the sweep give it, as on local processes
    (a fresh registry per task showed it once a task)."""
    import warnings

    from drill_env.distributed import _call, _said

    reply = _call(_warn_limit, 4)
    registry: dict = {}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("default")
        assert [_said(reply, registry) for _ in range(3)] == [4, 4, 4]
    assert [str(w.message) for w in caught] == ["limit"]


def _folder(_: int) -> str:
    return os.getcwd()


def test_a_task_on_a_cluster_runs_in_the_folder_the_command_runs_in(cluster, tmp_path,
                                                                     monkeypatch):
    """Paths typed relative to where the command runs (--out, a run folder) mean the same
    on the cluster: its workers started in the folder the nodes were started from, where a
    training sweep's run folders landed (an outside check; README, Scaling out on Ray)."""
    from drill_env.distributed import RayExecutor

    monkeypatch.chdir(tmp_path)
    executor = RayExecutor(cluster.address)
    try:
        # (a function of the standard library: a worker cannot import this test module)
        folders = dict(executor.map_unordered(os.path.abspath, [".", ".", "."]))
    finally:
        executor.close()
    assert {os.path.realpath(f) for f in folders.values()} == {os.path.realpath(tmp_path)}


def test_a_node_without_the_commands_folder_runs_the_task_where_it_is_and_says_so(
        tmp_path):
    """A cluster without a shared filesystem: a node lacking the command's folder runs the
    task in its own (the task may write nothing) and warns where the files went; a node
    with it runs the task there and leaves the worker's folder as it was."""
    from drill_env.distributed import _call

    here = os.getcwd()
    result, said = _call(_folder, 0, str(tmp_path / "not-on-this-node"))
    assert result == here == os.getcwd()
    assert [(category, "not-on-this-node" in text, f"ran in {here}," in text)
            for text, category, *_ in said] == [(RuntimeWarning, True, True)]
    result, said = _call(_folder, 0, str(tmp_path))
    assert (os.path.realpath(result), said) == (os.path.realpath(tmp_path), [])
    assert os.getcwd() == here


def _warn_limit(n: int) -> int:
    import warnings

    warnings.warn("limit", UserWarning, stacklevel=1)
    return n


def test_a_ray_session_the_user_started_is_theirs_to_stop(cluster):
    from drill_env.distributed import RayExecutor

    if ray.is_initialized():
        ray.shutdown()
    ray.init(address=cluster.address, log_to_driver=False)
    try:
        executor = RayExecutor(cluster.address)  # joins the user's session
        assert sorted(executor.map_unordered(abs, [-1, -2])) == [(0, 1), (1, 2)]
        executor.close()
        assert ray.is_initialized()  # still the user's
        assert ray.get(ray.put(3)) == 3
    finally:
        ray.shutdown()


def test_joining_ray_keeps_the_commands_sigterm_handler(cluster):
    """ray.init sets a SIGTERM handler of its own (sys.exit(15)): a sweep on Ray stopped by
    SIGTERM exited 15 without saying what it kept, instead of the command's handling
    (exit 143, finished work kept, a training run's checkpoint saved)."""
    from drill_env.distributed import RayExecutor

    if ray.is_initialized():
        ray.shutdown()

    def ours(signum, frame):  # the command's (drill_cli.interrupts.stop_as_interrupt)
        raise AssertionError("not called here")

    previous = signal.signal(signal.SIGTERM, ours)
    try:
        executor = RayExecutor(cluster.address)
        try:
            assert signal.getsignal(signal.SIGTERM) is ours
        finally:
            executor.close()
    finally:
        signal.signal(signal.SIGTERM, previous)


def _sleep_then_say(args: tuple[str, float]) -> None:
    """Sleep; on an interrupt write "interrupted" to the file (as a training run saves
    its checkpoint), else "finished" at the end."""
    path, seconds = args
    Path(f"{path}.started").touch()
    try:
        for _ in range(round(seconds / 0.05)):  # Ray's interrupt lands between sleeps
            time.sleep(0.05)
    except KeyboardInterrupt:
        Path(path).write_text("interrupted")
        raise
    Path(path).write_text("finished")


def test_tasks_in_flight_when_a_sweep_stops_end_or_are_interrupted(cluster, tmp_path,
                                                                   monkeypatch):
    """An interrupted sweep (its generator closed, as Ctrl-C does) leaves no task running
    on the cluster. A task about to end is left to end (cancelling one as its reply came
    in crashed Ray's task manager now and then); a long one gets a KeyboardInterrupt, as a
    local worker does, so a training run saves its checkpoint (its worker was killed:
    the steps since the last regular checkpoint were lost), also where the workers
    inherited SIGINT ignored (this suite run as a background job: it failed so). What
    ends during the wait goes to ``late``, for the sweep to keep."""
    import ray.cloudpickle

    import drill_env.distributed as distributed

    monkeypatch.setattr(distributed, "SETTLE_GRACE", 5.0)
    ray.cloudpickle.register_pickle_by_value(sys.modules[__name__])  # the workers can't
    executor = distributed.RayExecutor(cluster.address)              # import this file
    short, long = tmp_path / "short", tmp_path / "long"
    kept: list[int] = []
    try:
        results = executor.map_unordered(_sleep_then_say, [(str(tmp_path / "first"), 0.0),
                                                           (str(short), 3.0),
                                                           (str(long), 120.0)],
                                         late=lambda k, result: kept.append(k))
        assert next(results)[0] == 0
        started = [Path(f"{path}.started") for path in (short, long)]
        deadline = time.monotonic() + 60.0
        while not all(p.exists() for p in started) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert all(p.exists() for p in started), "the two slow tasks did not start"
        results.close()
        deadline = time.monotonic() + 30.0
        while ray_task_processes() and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not ray_task_processes()
        assert (short.read_text(), long.read_text()) == ("finished", "interrupted")
        # what ended during the wait is handed back to be kept (it was dropped: a rerun
        # ran it again); the interrupted one is not
        assert kept == [1]
    finally:
        executor.close()
        ray.cloudpickle.unregister_pickle_by_value(sys.modules[__name__])


def test_a_local_ray_instance_starts_without_notices_on_the_console(tmp_path):
    """`--ray-address local` printed Ray's token-authentication notice (asking to opt out
    of a safe default) and a C++ log line that it set the log level from an environment
    variable we set, above the progress bar. Token authentication stays on."""
    import subprocess

    script = ("import os, ray; from drill_env.distributed import RayExecutor; "
              "e = RayExecutor('local'); "
              "print(sorted(e.map_unordered(abs, [-1, -2]))); "
              "print(os.environ.get('RAY_AUTH_MODE')); "
              "print(int(ray.cluster_resources()['object_store_memory'])); e.close()")
    env = {k: v for k, v in os.environ.items()
           if not k.startswith(("RAY_AUTH", "RAY_BACKEND_LOG"))}
    env["HOME"] = str(tmp_path)  # Ray keeps the token it makes in ~/.ray
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          env=env, timeout=300, check=True)
    # its object store a fixed 256 MB, not Ray's 30 % of the machine's memory (mapped at
    # start: under a 4 GB address-space limit the start failed; an outside check)
    assert done.stdout.split() == ["[(0,", "1),", "(1,", "2)]", "token", str(256 * 1024**2)]
    assert "Token authentication" not in done.stderr and "logging.cc" not in done.stderr


def test_joining_a_cluster_with_token_authentication_by_its_address_says_how(tmp_path):
    """`ray start` (Ray >= 2.59) turns token authentication on where ~/.ray/auth_token
    exists, which a `--ray-address local` run writes, and Ray sends the token to an
    explicit address only with RAY_AUTH_MODE=token: the join failed as "no Ray cluster"
    (an outside check). The error says what Ray wants, and what it says works."""
    import secrets
    import shutil
    import socket
    import subprocess
    import tempfile

    if tuple(int(v) for v in ray.__version__.split(".")[:2]) < (2, 59):
        pytest.skip("ray start turns token authentication on from Ray 2.59")

    home = tmp_path / "home"
    (home / ".ray").mkdir(parents=True)
    (home / ".ray" / "auth_token").write_text(secrets.token_hex(32))
    env = {k: v for k, v in os.environ.items()
           if not k.startswith(("RAY_AUTH", "RAY_ADDRESS"))}
    env["HOME"] = str(home)
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    ray_bin = Path(sys.executable).with_name("ray")
    # its own session folder (short: Ray's socket paths must fit 107 bytes) and its own
    # process group, stopped below without `ray stop`, which would stop every cluster
    temp = tempfile.mkdtemp(prefix="rt", dir="/tmp")
    head = subprocess.Popen([str(ray_bin), "start", "--head", "--block", f"--port={port}",
                             "--num-cpus=1", "--include-dashboard=false",
                             "--disable-usage-stats", f"--temp-dir={temp}"], env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True)
    script = ("from drill_env.distributed import RayExecutor\n"
              "try:\n"
              f"    e = RayExecutor('127.0.0.1:{port}')\n"
              "    print('joined', sorted(e.map_unordered(abs, [-3]))); e.close()\n"
              "except ConnectionError as err:\n"
              "    print(err)\n")
    try:
        deadline = time.monotonic() + 60.0
        while True:  # the head's GCS port open
            try:
                socket.create_connection(("127.0.0.1", port), timeout=1.0).close()
                break
            except OSError:
                assert time.monotonic() < deadline, "the head did not start"
                time.sleep(0.5)
        # (Ray's ~20 s of retries cut to 5: the refusal is the first answer)
        plain = subprocess.run([sys.executable, "-c", script], capture_output=True,
                               text=True, timeout=180,
                               env={**env, "RAY_gcs_server_port_wait_time_s": "5"})
        assert "could not join a Ray cluster" in plain.stdout
        assert "RAY_AUTH_MODE=token" in plain.stdout
        told = subprocess.run([sys.executable, "-c", script], capture_output=True,
                              text=True, env={**env, "RAY_AUTH_MODE": "token"}, timeout=180)
        assert told.stdout.split() == ["joined", "[(0,", "3)]"], told.stderr[-2000:]
    finally:  # (SIGTERM: ~33 s of Ray's own shutdown once a driver had joined)
        os.killpg(head.pid, signal.SIGKILL)
        head.wait(timeout=60)
        shutil.rmtree(temp, ignore_errors=True)
