"""What differs off Linux, simulated here (a portability review, 2026-12-06: CI runs on
Linux only). Each test takes away or fakes what macOS or Windows lacks and checks the
code's own way around it."""

from __future__ import annotations

import os
import pathlib
import re
import subprocess
import sys

import pytest


def test_an_output_folder_on_a_root_that_is_not_there_is_refused(monkeypatch):
    """An unmapped drive (Z:\\) is its own parent and does not exist: the walk up to an
    existing folder never ended. Simulated: no path exists at all."""
    from drill_cli.arguments import unwritable

    monkeypatch.setattr(pathlib.Path, "exists", lambda self: False)
    said = unwritable(pathlib.Path("/nowhere/out"))
    assert said.endswith("does not exist") and said.startswith(os.sep)


def test_the_viewer_stops_without_process_groups(monkeypatch):
    """Windows has neither os.killpg nor SIGKILL: stop_viewer raised AttributeError at a
    Ctrl-C of `drill-env replay`. Without killpg it has taskkill end the viewer's process
    tree (rerun.exe is a launcher whose child is the viewer). Simulated: taskkill's call
    recorded, the process ended as taskkill would; and with no taskkill at all, the
    viewer itself is killed."""
    import importlib

    replay = importlib.import_module("drill_env.recording.replay")  # (the module: the
    # package exports a function of its name)

    monkeypatch.delattr(os, "killpg")
    ran: list[list[str]] = []

    def taskkill(command, **kwargs):
        ran.append(command)
        proc.kill()

    monkeypatch.setattr(replay.subprocess, "run", taskkill)
    proc = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    assert replay.stop_viewer(proc) != 0 and proc.poll() is not None
    assert ran == [["taskkill", "/PID", str(proc.pid), "/T", "/F"]]

    def missing(command, **kwargs):
        raise FileNotFoundError("taskkill")

    monkeypatch.setattr(replay.subprocess, "run", missing)
    proc = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    assert replay.stop_viewer(proc) != 0 and proc.poll() is not None


def test_a_pool_on_windows_takes_at_most_61_workers(monkeypatch):
    """ProcessPoolExecutor refuses more than 61 workers on Windows: every sweep failed
    on a 64-core workstation. Simulated: the platform's name, the pool not started."""
    import drill_env.sweep as sweep

    asked = []
    monkeypatch.setattr(sweep, "ProcessPoolExecutor",
                        lambda workers, **kw: asked.append(workers))
    monkeypatch.setattr(sys, "platform", "win32")
    assert sweep.ProcessExecutor(128).workers == sweep.WINDOWS_MAX_WORKERS == 61
    monkeypatch.setattr(sys, "platform", "linux")
    assert sweep.ProcessExecutor(128).workers == 128
    assert asked == [61, 128]


@pytest.mark.skipif(not hasattr(os, "killpg"), reason="process groups: POSIX")
def test_the_viewer_still_stops_its_process_group_where_there_is_one():
    from drill_env.recording.replay import stop_viewer

    proc = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"],
                            start_new_session=True)
    assert stop_viewer(proc, timeout=5.0) == -15


_ORPHAN = '''
import multiprocessing as mp, os, sys, threading, time

from drill_env.sweep import _end_with_parent


def child(path):
    threading.Thread(target=_end_with_parent, daemon=True).start()
    with open(path, "w") as f:
        f.write(str(os.getpid()))
    time.sleep(60)


if __name__ == "__main__":
    mp.get_context("spawn").Process(target=child, args=(sys.argv[1],)).start()
    time.sleep(60)
'''


def _alive(pid: int) -> bool:
    """Whether ``pid`` runs (a zombie no one has reaped yet does not)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    stat = pathlib.Path(f"/proc/{pid}/stat")
    try:
        return stat.read_text().rpartition(")")[2].split()[0] != "Z"
    except OSError:  # no /proc (macOS): kill's answer
        return True


@pytest.mark.skipif(not hasattr(os, "getpgid"), reason="signals to a pid: POSIX")
def test_a_worker_ends_with_its_killed_parent_without_linux_signals(tmp_path):
    """Off Linux there is no PR_SET_PDEATHSIG: a command killed outright left its pool's
    workers running. The worker's watch thread (used there) ends it with its parent; here
    a spawned child of a parent killed with SIGKILL."""
    import signal
    import time

    script = tmp_path / "orphan.py"
    script.write_text(_ORPHAN)
    marker = tmp_path / "child.pid"
    parent = subprocess.Popen([sys.executable, str(script), str(marker)])
    try:
        deadline = time.monotonic() + 60
        while not (marker.exists() and marker.read_text()) and time.monotonic() < deadline:
            time.sleep(0.1)
        child = int(marker.read_text())
        assert _alive(child)
        parent.send_signal(signal.SIGKILL)
        parent.wait(10)
        deadline = time.monotonic() + 10
        while _alive(child) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert not _alive(child)
    finally:
        parent.kill()
        if marker.exists() and marker.read_text() and _alive(int(marker.read_text())):
            os.kill(int(marker.read_text()), signal.SIGKILL)  # (a watch that failed)


def test_on_macos_the_batched_envs_take_numbas_workqueue_layer():
    """numba's OpenMP layer can bind the libomp torch loaded before it on macOS, and a
    parallel kernel after `import torch` then crashes (numba#10492): there `import
    drill_env` sets the workqueue layer, unless the user chose one. Simulated: the
    platform's name before the import, in a fresh process."""
    code = ("import os, sys; sys.platform = 'darwin'; import drill_env; "
            "print(os.environ.get('NUMBA_THREADING_LAYER'), drill_env.TBB_LIBRARY)")
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_THREADING_LAYER"}
    said = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env=env, timeout=120, check=True).stdout.split()
    assert said == ["workqueue", "None"]
    env["NUMBA_THREADING_LAYER"] = "omp"
    said = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env=env, timeout=120, check=True).stdout.split()
    assert said == ["omp", "None"]
    # numba imported first read its settings then: drill_env has it read them again (a
    # review: from the cache no compile would, and the choice went unheard)
    del env["NUMBA_THREADING_LAYER"]
    first = ("import sys, numba; sys.platform = 'darwin'; import drill_env; "
             "from numba.core import config; print(config.THREADING_LAYER)")
    said = subprocess.run([sys.executable, "-c", first], capture_output=True, text=True,
                          env=env, timeout=120, check=True).stdout.split()
    assert said == ["workqueue"]


def test_a_file_held_open_on_windows_is_waited_for_then_refused_by_name(tmp_path,
                                                                        monkeypatch):
    """Windows refuses the rename that saves a file whole while another program holds the
    target (a benchmark.csv open in a spreadsheet): a passing hold is waited out, a lasting
    one gives an error naming the file and what to do, and no partial file stays."""
    from drill_env import sweep

    target = tmp_path / "benchmark.csv"
    target.write_text("old\n", encoding="utf-8")
    real = pathlib.Path.replace
    refusals = []

    def held(self, other, times):
        if len(refusals) < times:
            refusals.append(other)
            raise PermissionError(13, "Access is denied")
        return real(self, other)

    monkeypatch.setattr(sweep, "RENAME_WAIT", 0.0)
    monkeypatch.setattr(pathlib.Path, "replace", lambda s, o: held(s, o, 1))
    with pytest.raises(PermissionError, match=r"^\[Errno 13\] Access is denied: "
                                              r"'.*benchmark\.csv'$"):  # lasting (a sticky
        sweep.save_text(target, "new\n")  # folder): no wait, its own error, named
    assert len(refusals) == 1 and target.read_text(encoding="utf-8") == "old\n"
    refusals.clear()
    monkeypatch.setattr(sys, "platform", "win32")
    monkeypatch.setattr(pathlib.Path, "replace", lambda s, o: held(s, o, 2))
    sweep.save_text(target, "new\n")
    assert target.read_text(encoding="utf-8") == "new\n" and len(refusals) == 2

    refusals.clear()
    monkeypatch.setattr(pathlib.Path, "replace", lambda s, o: held(s, o, 99))
    with pytest.raises(PermissionError, match=rf"^{re.escape(str(target))}: cannot be "
                                              r"replaced \(Access is denied\); .*close it"):
        sweep.save_text(target, "newer\n")
    assert len(refusals) == sweep.RENAME_TRIES
    assert target.read_text(encoding="utf-8") == "new\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["benchmark.csv"]
