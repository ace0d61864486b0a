"""Outputs and run folders that two processes reach at once, a full disk, and files
edited by hand: what an outside check of the filesystem found, each case failing on the
code before it."""

from __future__ import annotations

import errno
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from drill_env.sweep import (
    LOCK_FILE,
    STALE_PARTIAL_S,
    FolderInUse,
    ResultStore,
    folder_lock,
    partial_file,
    save_text,
    save_whole,
)

HOLD = """
import sys, time
from pathlib import Path
from drill_env.sweep import folder_lock
with folder_lock(Path(sys.argv[1]), "a test"):
    print("held", flush=True)
    time.sleep(60)
"""


def _holder(folder: Path) -> subprocess.Popen:
    """A process that holds ``folder``'s lock until it is killed."""
    holder = subprocess.Popen([sys.executable, "-c", HOLD, str(folder)],
                              stdout=subprocess.PIPE, text=True)
    assert holder.stdout is not None and holder.stdout.readline().strip() == "held"
    return holder


def test_two_processes_saving_one_output_each_write_their_own_partial_file(tmp_path):
    """One partial name for all processes: a second process that saved the same output
    while the first was writing moved the first's half file into place, and the first's
    rename found nothing (FileNotFoundError) after a reader had seen a mixed file."""
    target = tmp_path / "benchmark.csv"
    other = ("import sys; from pathlib import Path; from drill_env.sweep import save_text; "
             "save_text(Path(sys.argv[1]), 'theirs\\n')")

    def save_while_another_process_saves(file: str) -> None:
        Path(file).write_text("ours, first half\n")
        subprocess.run([sys.executable, "-c", other, str(target)], check=True)
        with open(file, "a") as f:
            f.write("ours, second half\n")

    save_whole(target, save_while_another_process_saves)
    assert target.read_text() == "ours, first half\nours, second half\n"
    assert partial_file(target).name == f".benchmark.{os.getpid()}.partial.csv"
    assert [p.name for p in tmp_path.iterdir()] == ["benchmark.csv"]


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="Linux's /dev/full")
def test_a_full_disk_is_said_with_the_file_it_stopped(tmp_path):
    """A write's "No space left on device" names no file; the command said only that."""
    target = tmp_path / "benchmark.csv"
    save_text(target, "the previous table\n")

    def fill(file: str) -> None:
        with open("/dev/full", "w") as f:
            f.write("x")

    with pytest.raises(OSError) as caught:
        save_whole(target, fill)
    assert (caught.value.errno, caught.value.filename) == (errno.ENOSPC, str(target))
    assert target.read_text() == "the previous table\n"  # the old file is left whole
    store = ResultStore(tmp_path / "results.jsonl", "f")
    store.path = Path("/dev/full")
    with pytest.raises(OSError) as caught:
        store.put("k", 1)
    assert (caught.value.errno, caught.value.filename) == (errno.ENOSPC, "/dev/full")


def test_an_error_that_names_its_own_file_keeps_that_name(tmp_path):
    """Only an error without a file's name (a full disk's) is said with the saved file's:
    one that names its own (an input the save reads is gone) keeps it (a mutation test:
    every error said as the saved file's passed every test)."""
    target = tmp_path / "benchmark.csv"
    missing = tmp_path / "series.npz"
    with pytest.raises(FileNotFoundError) as caught:
        save_whole(target, lambda file: missing.read_bytes())
    assert caught.value.filename == str(missing)
    assert list(tmp_path.iterdir()) == []


def test_an_error_on_the_partial_file_is_said_with_the_saved_file_s_name(tmp_path):
    """A folder made read-only during a benchmark: the error named the hidden file the
    save writes first (".benchmark.14507.partial.csv", a fuzzing walkthrough), a name
    the user never saw; it names benchmark.csv."""
    target = tmp_path / "benchmark.csv"

    def refused(file: str) -> None:
        raise PermissionError(errno.EACCES, "Permission denied", file)

    with pytest.raises(PermissionError) as caught:
        save_whole(target, refused)
    assert caught.value.filename == str(target)


def test_a_held_folder_is_refused_by_name_and_let_go_when_its_holder_is_killed(tmp_path):
    """The lock is the system's: a kill -9 of its holder frees the folder (a resume after
    a kill is not refused), and the partial files of its cut saves are deleted by the next
    holder (they piled up under one name per process)."""
    folder = tmp_path / "run"
    holder = _holder(folder)
    try:
        with pytest.raises(FolderInUse, match=rf"^{folder}: another drill-env process is "
                                              r"writing there \(.*\): wait for it to end, "
                                              r"or give this training run another folder$"):
            with folder_lock(folder, "this training run"):
                pass
    finally:
        holder.kill()  # (SIGKILL)
        holder.wait()
    (folder / "checkpoints").mkdir()
    old = time.time() - STALE_PARTIAL_S - 1.0
    for name in (".model.4242.partial.zip", "checkpoints/.model_1024_steps.partial.zip",
                 "notes.partial.txt", ".plot.4343.partial.png"):
        (folder / name).write_bytes(b"cut")
        if name != ".plot.4343.partial.png":  # (fresh: a command without a lock writes it)
            os.utime(folder / name, (old, old))
    with folder_lock(folder, "a training run", tidy=("checkpoints",)):
        left = sorted(p.relative_to(folder).as_posix() for p in folder.rglob("*"))
    # (notes.partial.txt is not hidden: not a save's)
    assert left == [LOCK_FILE, ".plot.4343.partial.png", "checkpoints", "notes.partial.txt"]


def test_a_refused_command_leaves_no_folder_it_made(tmp_path):
    folder = tmp_path / "new" / "run"
    with pytest.raises(ValueError, match="refused"), folder_lock(folder, "a test"):
        raise ValueError("refused")
    assert list(tmp_path.iterdir()) == []  # new/ too (it was left: a mutation round)
    (tmp_path / "new").mkdir()
    (tmp_path / "new" / "other").write_text("")  # a parent it made, not empty: kept
    with pytest.raises(ValueError, match="refused"), folder_lock(tmp_path / "new" / "a" / "b",
                                                                 "a test"):
        (tmp_path / "new" / "a" / "note").write_text("")
        raise ValueError("refused")
    assert sorted(p.name for p in (tmp_path / "new").iterdir()) == ["a", "other"]
    assert [p.name for p in (tmp_path / "new" / "a").iterdir()] == ["note"]
    with folder_lock(folder, "a test"):
        (folder / "result.txt").write_text("kept")
    assert sorted(p.name for p in folder.iterdir()) == [LOCK_FILE, "result.txt"]
    # an empty folder it did not make (an --out made beforehand) stays (a mutation test:
    # a refused command removed it, and that passed every test)
    mine = tmp_path / "mine"
    mine.mkdir()
    with pytest.raises(ValueError, match="refused"), folder_lock(mine, "a test"):
        raise ValueError("refused")
    assert mine.is_dir()


def test_a_second_benchmark_into_a_held_folder_is_refused_before_any_episode(
        tmp_path, capsys, monkeypatch):
    """Two benchmarks into one --out: with other settings the second's series replaced
    the first's and the first dropped every series picture without a word. The folder
    is said by its path (`--out seeds` was said as the option --seeds)."""
    from drill_cli.main import main

    monkeypatch.chdir(tmp_path)
    holder = _holder(tmp_path / "seeds")
    try:
        status = main(["benchmark", "--controllers", "stiff", "--scenarios", "stick_slip",
                       "--seeds", "1", "--duration", "6", "--warmup", "2", "--workers", "1",
                       "--out", "seeds"])
    finally:
        holder.kill()
        holder.wait()
    err = capsys.readouterr().err
    assert status == 2
    assert "error: seeds: another drill-env process is writing there" in err
    assert "or give this benchmark another folder" in err
    assert not (tmp_path / "seeds" / "benchmark_results.jsonl").exists()


def test_a_second_stability_map_into_a_held_folder_is_refused_before_any_point(
        tmp_path, capsys):
    """Two stability maps into one --out appended to one points file and each rewrote
    the JSON and the picture with its own positions only."""
    from drill_cli.main import main
    from drill_cli.studies import MAP_POINTS_FILE

    holder = _holder(tmp_path / "maps")
    try:
        status = main(["stability-map", "--positions", "P1", "--rpm-step", "50",
                       "--wob-step", "100", "--workers", "1",
                       "--out", str(tmp_path / "maps")])
    finally:
        holder.kill()
        holder.wait()
    err = capsys.readouterr().err
    assert status == 2
    assert f"error: {tmp_path / 'maps'}: another drill-env process is writing there" in err
    assert "or give this stability map another folder" in err
    assert not (tmp_path / "maps" / MAP_POINTS_FILE).exists()


def test_a_second_training_of_a_held_run_is_refused(tmp_path, capsys):
    """Two `train` of one run (or a --resume of one still training) both passed the
    "already holds a run" check and trained side by side: evaluations.csv held every
    row twice and run.json's sessions a resume that never was."""
    from drill_cli.main import main

    run = tmp_path / "runs" / "mine"
    holder = _holder(run)
    try:
        for resume in ([], ["--resume"]):
            status = main(["train", "--task", "stick_slip", "--algo", "ppo", "--timesteps",
                           "256", "--out", str(tmp_path / "runs"), "--name", "mine",
                           "--no-progress", *resume])
            assert status == 2
            err = capsys.readouterr().err
            assert f"error: {run}: another drill-env process is writing there" in err
            assert "or give this training run another folder" in err
            assert "--resume starts it" not in err  # (said first: advice for a stopped run)
    finally:
        holder.kill()
        holder.wait()
    assert sorted(p.name for p in run.iterdir()) == [LOCK_FILE]  # nothing written


def test_an_overwrite_of_a_run_being_evaluated_is_refused(tmp_path, capsys):
    """`train --overwrite RUN` deleted RUN/evaluation under a running `evaluate RUN`,
    which then ended in a bare errno, its rows lost, or said "wrote" of files gone (a
    fuzzing walkthrough): it is refused, naming the folder, and nothing is deleted."""
    from drill_cli.main import main

    run = tmp_path / "runs" / "mine"
    (run / "evaluation" / "grid_search").mkdir(parents=True)
    (run / "config.yaml").write_text("algo: ppo\n")
    (run / "evaluation" / "benchmark.csv").write_text("controller\n")
    # the evaluation's folder, and a drilling run's grid search, which holds only its own
    # folder while it runs (a review)
    for held in (run / "evaluation", run / "evaluation" / "grid_search"):
        holder = _holder(held)
        try:
            status = main(["train", "--task", "stick_slip", "--algo", "ppo", "--timesteps",
                           "256", "--out", str(tmp_path / "runs"), "--name", "mine",
                           "--no-progress", "--overwrite"])
        finally:
            holder.kill()
            holder.wait()
        assert status == 2
        assert (f"error: {held}: another drill-env process is writing there (an "
                "evaluation of this run)") in capsys.readouterr().err
        assert (run / "evaluation" / "benchmark.csv").exists()
        assert (run / "config.yaml").exists()


def test_rows_edited_by_hand_are_run_again_and_said(tmp_path, capsys):
    """A stored row with "abc" for a number ended the command with "could not convert
    string to float: 'abc'" naming neither file nor row; another seed under a row's key
    went into benchmark.csv; a damaged line before the last was skipped without a word."""
    import agents.benchmark as bm
    import agents.settings as bs

    short = bs.BenchmarkSettings(duration=6.0, warmup=2.0)
    args = (["stiff"], ["stick_slip"], [0, 1], tmp_path, short)
    bm.run_benchmark(*args, workers=1, progress=False)
    table = (tmp_path / "benchmark.csv").read_text()
    path = tmp_path / bm.RESULTS_FILE
    lines = path.read_text().splitlines()
    first, second = (json.loads(line) for line in lines)
    first["result"]["rop_m_per_h"] = "abc"
    second["result"]["seed"] = 99
    path.write_text("\n".join([json.dumps(first), "{not json", json.dumps(second)]) + "\n")
    capsys.readouterr()
    bm.run_benchmark(*args, workers=1, progress=True)
    err = capsys.readouterr().err
    assert f"2 line(s) of {path} are not rows this run can use (damaged or edited by " \
           f"hand: {first['key']})" in err
    assert (tmp_path / "benchmark.csv").read_text() == table


def test_an_evaluation_row_edited_by_hand_is_named_with_its_line(tmp_path):
    from training.run_folder import read_evaluations

    path = tmp_path / "evaluations.csv"
    path.write_text("timesteps,return,wall_s\r\n1000,-3.5,12.0\r\n2000,abc,20.1\r\n")
    with pytest.raises(ValueError, match=rf"^{path}, line 3: return 'abc' is not a number"):
        read_evaluations(path)
    path.write_text("timesteps,return,wall_s\r\n1000,-3.5,12.0\r\n")
    assert read_evaluations(path) == [{"timesteps": "1000", "return": "-3.5",
                                       "wall_s": "12.0"}]
    assert read_evaluations(tmp_path / "none.csv") == []


def test_a_home_folder_typed_after_an_equals_sign_is_the_home_folder(tmp_path,
                                                                     monkeypatch):
    """--out=~/x reaches the command unexpanded: it wrote into a folder named ~."""
    from drill_cli.arguments import out_folder, shell_word

    monkeypatch.setenv("HOME", str(tmp_path))
    monkeypatch.setenv("USERPROFILE", str(tmp_path))  # (Windows)
    assert out_folder("~/runs") == tmp_path / "runs"
    assert out_folder("~no_such_user_here/x") == Path("~no_such_user_here/x")  # as typed
    if os.name != "nt":
        assert shell_word(Path("logs/runs/sp ace ü")) == "'logs/runs/sp ace ü'"
        assert shell_word(Path("logs/runs/plain")) == "logs/runs/plain"



def test_a_cut_line_the_next_result_ended_is_not_counted_as_an_edit(tmp_path):
    """Once the next result ended it, a killed writer's half line sits before the last:
    it is skipped as before, and not said as damage at every later run."""
    path = tmp_path / "results.jsonl"
    ResultStore(path, "f").put("a", 1)
    with path.open("a") as f:
        f.write('{"fingerprint": "f", "ke')
    store = ResultStore(path, "f")
    assert (store.cut, store.damaged) == (True, 0)
    store.put("b", 2)
    with path.open("a") as f:
        f.write('{"an": "edit"}\n')
    again = ResultStore(path, "f")
    assert (again.cut, again.damaged, again.get("b")) == (False, 1, 2)


def test_a_damaged_line_before_a_whole_last_line_is_no_cut_and_a_store_makes_its_folder(
        tmp_path):
    """A damaged line before a last line that lacks only its newline does not make the
    store say its last line was cut (that one is whole, and kept); and the first result
    makes the store's folder (mutation tests: each passed every test)."""
    path = tmp_path / "new" / "results.jsonl"
    ResultStore(path, "f").put("a", 1)
    with path.open("a") as f:
        f.write("{damaged\n")
        f.write(json.dumps({"fingerprint": "f", "key": "c", "result": 3}))  # no newline
    store = ResultStore(path, "f")
    assert (store.cut, store.damaged, len(store)) == (False, 0, 2)
    store.put("d", 4)
    assert (ResultStore(path, "f").get("c"), ResultStore(path, "f").get("d")) == (3, 4)


UNGUARDED = """
from pathlib import Path
from agents.benchmark import BenchmarkSettings, run_benchmark
run_benchmark(["stiff"], ["stick_slip"], [0, 1], Path("out"),
              BenchmarkSettings(duration=2.0, warmup=1.0), workers=2, progress=False)
"""


def test_a_script_that_starts_a_sweep_at_its_top_level_is_told_to_guard_it(tmp_path):
    """A script calling run_benchmark with workers at its top level, without `if __name__
    == "__main__":`, ended in BrokenProcessPool after 'another drill-env process is
    writing there' (its workers, importing the script, ran it again; a new user's trial):
    the error the script stops with now says what it needs."""
    script = tmp_path / "unguarded.py"
    script.write_text(UNGUARDED)
    root = Path(__file__).resolve().parents[1]
    done = subprocess.run([sys.executable, str(script)], cwd=tmp_path, capture_output=True,
                          text=True, timeout=300,
                          env={**os.environ, "PYTHONPATH": str(root)})
    assert done.returncode == 1
    last = done.stderr.strip().splitlines()[-1]
    assert last.startswith("RuntimeError: a worker process died") and \
        'under `if __name__ == "__main__":`' in last, done.stderr[-2000:]
