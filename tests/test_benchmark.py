"""The controller benchmark: its files, its columns, and resuming after an interrupt."""

from __future__ import annotations

import contextlib
import csv
import dataclasses
import json
import math
import re
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pytest

import agents.benchmark as bm
import agents.episode as be
import agents.settings as bs
import agents.tables as bt
from agents.learned import TRAINED
from drill_cli.main import main
from drill_env.physics.config import flatten
from drill_env.sweep import ResultStore

SPEC_COLUMNS = ["controller", "scenario", "seed", "ssi", "stuck_fraction", "mean_bit_rpm",
                "target_rpm", "rpm_tracking_error", "rop_m_per_h", "radial_ratio",
                "backward_whirl_fraction", "max_lateral_force_kN", "mse_MPa",
                "top_drive_energy_MJ", "episode_return"]
SHORT = bs.BenchmarkSettings(duration=6.0, warmup=2.0)


def test_benchmark_command_writes_table_summary_plots_and_recordings(tmp_path, capsys):
    code = main(["benchmark", "--controllers", "stiff,driller", "--scenarios", "stick_slip",
                 "--seeds", "2", "--duration", "6", "--warmup", "2", "--workers", "1",
                 "--record", "--out", str(tmp_path)])
    assert code == 0
    with (tmp_path / "benchmark.csv").open() as f:
        rows = list(csv.reader(f))
    assert rows[0] == SPEC_COLUMNS
    body = [dict(zip(rows[0], r, strict=True)) for r in rows[1:]]
    assert {(r["controller"], r["seed"]) for r in body} == {
        ("stiff", "0"), ("stiff", "1"), ("driller", "0"), ("driller", "1")}
    for r in body:
        assert float(r["target_rpm"]) == 50.0
        assert float(r["mean_bit_rpm"]) == pytest.approx(50.0, rel=0.05)
        assert float(r["rop_m_per_h"]) > 0.0
    assert "Controller benchmark (means over seeds)" in capsys.readouterr().out
    assert "| stick_slip | stiff | 2 |" in (tmp_path / "benchmark.md").read_text()
    for png in ("benchmark_bars.png", "benchmark_stick_slip_series.png"):
        assert (tmp_path / png).stat().st_size > 20_000
    names = sorted(p.name for p in (tmp_path / "recordings").glob("*.rrd"))
    assert names == [f"{c}_stick_slip_seed{s}.rrd" for c in ("driller", "stiff")
                     for s in (0, 1)]  # a row's recording is found by its name


def test_benchmark_csv_holds_numbers_to_six_significant_digits(tmp_path):
    """docs/controllers.md: benchmark.csv holds "numbers to 6 significant digits" (each
    episode's full precision is in benchmark_results.jsonl); whole numbers as they are."""
    row = {"controller": "stiff", "scenario": "stick_slip", "seed": 3,
           **{c: 1.0 / 3.0 for c in SPEC_COLUMNS[3:]}, "mse_MPa": 2.0e4 / 3.0,
           "episode_return": -7}
    bt.write_csv([row], tmp_path / "benchmark.csv")
    with (tmp_path / "benchmark.csv").open(newline="") as f:
        header, body = list(csv.reader(f))
    assert header == SPEC_COLUMNS
    cells = dict(zip(header, body, strict=True))
    assert (cells["seed"], cells["episode_return"]) == ("3", "-7")
    # by hand: 1/3 = 0.333333|3..., 20000/3 = 6666.66|67... to six digits
    assert (cells["ssi"], cells["mse_MPa"]) == ("0.333333", "6666.67")


def test_two_seeds_start_different_episodes():
    rows = [be.run_episode(bs.Episode("stiff", "stick_slip", seed, vars(SHORT), "unused"))
            for seed in (0, 1)]
    assert rows[0]["mean_bit_rpm"] != rows[1]["mean_bit_rpm"]


def test_a_rows_values_are_its_episodes_measured_window_and_summed_reward(tmp_path):
    """A row recomputed from outside the harness: constant set points of 100 rpm in the
    stick_slip scenario (plan 50 rpm), so the bit runs far from the target. The mean bit
    speed is the saved series' over t >= warm-up, rpm_tracking_error is SPEC section 5's
    |mean - target| / target, and episode_return the sum of the rewards of the same
    episode stepped by hand."""
    import gymnasium as gym

    from agents.registry import make_controller
    from drill_env.physics.units import RPM

    name = "constant:100/100"
    row = be.run_episode(bs.Episode(name, "stick_slip", 0, vars(SHORT), str(tmp_path),
                                    series=True))
    assert row["target_rpm"] == pytest.approx(50.0)
    assert row["rpm_tracking_error"] == pytest.approx(
        abs(row["mean_bit_rpm"] - 50.0) / 50.0, rel=1e-12)
    assert row["rpm_tracking_error"] > 0.9  # the bit turns at ~100 rpm
    series = np.load(tmp_path / "series" / f"{bs.label(name)}_stick_slip_seed0.npz")
    after = series["time"] >= SHORT.warmup - 1e-9  # the episode starts at t = 0
    assert 0 < after.sum() < len(after)
    assert row["mean_bit_rpm"] == pytest.approx(
        series["bit_speed"][after].mean() / RPM, rel=1e-9)
    env = gym.make("DrillString-v0", scenario="stick_slip", episode_duration=SHORT.duration,
                   start_kick=SHORT.start_kick, fidelity=SHORT.fidelity,
                   physics=make_controller(name).physics())
    env.reset(seed=0)
    action = env.unwrapped.action_for(100 * RPM, 100e3)
    total, done = 0.0, False
    while not done:
        _, reward, terminated, truncated, _ = env.step(action)
        total += reward
        done = terminated or truncated
    assert row["episode_return"] == pytest.approx(total, rel=1e-12)


def test_an_interrupted_benchmark_keeps_its_rows_and_reruns_only_the_rest(tmp_path,
                                                                          monkeypatch):
    real = be.run_episode
    calls: list[str] = []

    def interrupted_after_two(episode):
        if len(calls) == 2:
            raise KeyboardInterrupt
        calls.append(episode.key)
        return real(episode)

    monkeypatch.setattr(bm, "run_episode", interrupted_after_two)
    with pytest.raises(KeyboardInterrupt):
        bm.run_benchmark(["stiff", "z-torque"], ["stick_slip"], [0, 1], tmp_path, SHORT,
                         workers=1, progress=False)
    assert len((tmp_path / bm.RESULTS_FILE).read_text().splitlines()) == 2
    done = list(calls)

    calls.clear()
    monkeypatch.setattr(bm, "run_episode", lambda e: calls.append(e.key) or real(e))
    rows = bm.run_benchmark(["stiff", "z-torque"], ["stick_slip"], [0, 1], tmp_path, SHORT,
                            workers=1, progress=False)
    assert len(rows) == 4 and len(calls) == 2 and not set(calls) & set(done)

    calls.clear()  # everything there: nothing runs, the outputs are rewritten
    bm.run_benchmark(["stiff", "z-torque"], ["stick_slip"], [0, 1], tmp_path, SHORT,
                     workers=1, progress=False)
    assert calls == []
    assert len((tmp_path / "benchmark.csv").read_text().splitlines()) == 5


def test_physics_that_would_make_every_controller_one_is_refused(tmp_path, capsys):
    """``--config`` physics reach every controller's episode: a top-drive controller or
    gain there would override each controller's own rule (and leave the driller and a
    learned policy on that drive), so it is refused naming the field; tuning knobs that
    only their own controller reads may stay."""
    from drill_env.physics.validation import ConfigError

    for physics in ({"top_drive": {"controller": "z_torque"}},
                    {"top_drive.proportional_gain": 500.0},
                    {"top_drive.integral_gain": 10.0},
                    {"top_drive.torque_feedback": "high_pass"},
                    {"top_drive.feedback_gain": 1e-3}):  # the rules' 1/Z
        key = next(iter(flatten(physics)))
        with pytest.raises(ConfigError, match=f"physics.{key}: the benchmark gives each"):
            bs.BenchmarkSettings(duration=6.0, warmup=2.0, physics=physics)
    bs.BenchmarkSettings(duration=6.0, warmup=2.0,
                         physics={"top_drive": {"impedance_factor": 3.0}})
    # a misspelt field or level fails when the settings are made, not in the workers
    with pytest.raises(ConfigError, match="physics.mud.densty: unknown field of MudConfig"):
        bs.BenchmarkSettings(duration=6.0, warmup=2.0, physics={"mud.densty": 1300.0})
    with pytest.raises(ConfigError, match="fidelity: Input should be 'full' or 'fast'"):
        bs.BenchmarkSettings(duration=6.0, warmup=2.0, fidelity="fsat")
    # values for a scenario's own string (components the default config lacks) pass
    bs.BenchmarkSettings(duration=6.0, warmup=2.0,
                         physics={"string.components[2].length": 20.0})
    config = tmp_path / "drive.yaml"
    config.write_text("top_drive:\n  integral_gain: 10.0\n")
    with pytest.raises(SystemExit):  # said as argparse says a bad argument
        main(["benchmark", "--controllers", "stiff", "--scenarios", "default", "--seeds", "1",
              "--config", str(config), "--out", str(tmp_path / "out")])
    assert f"--config {config}: top_drive.integral_gain: the benchmark gives each" in \
        capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_set_points_at_the_ends_of_drill_strings_ranges_are_taken():
    """DrillString-v0's action ranges are closed (``set_point_outside``: outside is below
    low or above high): a benchmark's set points at their ends, the bit off bottom at 0 kN
    among them, are taken; one a kilonewton past the end is refused."""
    from drill_env.env_config import EnvConfig
    from drill_env.physics.units import RPM

    config = EnvConfig()
    rpm_high, (wob_low, wob_high) = config.rpm_range[1], config.weight_on_bit_range
    for wob in (wob_low, wob_high):
        settings = dataclasses.replace(SHORT, surface_speed=rpm_high * RPM, weight_on_bit=wob)
        assert settings.set_points() == {"surface_speed": rpm_high * RPM,
                                         "weight_on_bit": wob}
    with pytest.raises(ValueError, match="^weight_on_bit: .* outside DrillString-v0's range"):
        dataclasses.replace(SHORT, weight_on_bit=wob_high + 1e3)


def test_a_warmup_as_long_as_the_episode_is_refused():
    """BenchmarkSettings: the warm-up, left out of the metrics, must be shorter than the
    episode (its error says so): one as long leaves nothing to measure."""
    with pytest.raises(ValueError, match=r"^warmup: 6.0 s must be shorter than the duration"):
        bs.BenchmarkSettings(duration=6.0, warmup=6.0)
    assert bs.BenchmarkSettings(duration=6.0, warmup=5.5).warmup == 5.5


def test_a_policy_of_another_task_is_refused_before_any_episode(tmp_path):
    """It was refused in its first episode, after the other controllers had run."""
    with pytest.raises(ValueError, match="learned:.*drilling is a policy of "
                                         "DrillOptimise-v0; it cannot act in DrillStickSlip-v0"):
        bs.task_settings(["soft-speed", f"learned:{TRAINED / 'drilling'}"],
                         "DrillStickSlip-v0")


OWN_POLICY = '''
import numpy as np

from agents import SetPointController


class Full(SetPointController):
    """Always the largest correction: a policy of its own task, trained with KWARGS."""

    name = "full"
    rate = "policy"
    env_id = "ENV"

    def env_kwargs(self):
        return KWARGS

    def reset(self, env):
        super().reset(env)
        with open("seen.txt", "a") as f:  # the episode may run in a worker process
            f.write(f"{env.task.max_correction}\\n")

    def act(self, observation, info):
        return np.ones(1, dtype=np.float32)
'''


def test_a_policy_of_your_own_acts_under_its_env_kwargs_and_only_in_its_task(tmp_path,
                                                                            monkeypatch):
    """From a walkthrough: a policy of your own trained with max_correction 15 rpm ran at
    30 (the default) in a task benchmark, its env_kwargs() read only where it was a
    guest, and one of task 2 entered a task-1 table (its first act failed on the
    observation's shape). Now its env_kwargs() join the task settings as a learned run's
    do (and are refused beside a run trained under others), and a policy of another task
    is refused before any episode."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "mine.py").write_text(OWN_POLICY.replace("ENV", "DrillStickSlip-v0")
                                      .replace("KWARGS", "{'max_correction': 15.0}"))
    (tmp_path / "other.py").write_text(OWN_POLICY.replace("ENV", "DrillOptimise-v0")
                                       .replace("KWARGS", "{}"))
    assert bs.task_settings(["mine.py:Full", "stiff"], "DrillStickSlip-v0") == {
        "max_correction": 15.0}
    rows = bm.run_benchmark(["mine.py:Full"], ["random"], [0], tmp_path / "out", SHORT,
                            workers=1, progress=False, env_id="DrillStickSlip-v0")
    assert len(rows) == 1
    assert (tmp_path / "seen.txt").read_text().split() == ["15.0"]
    with pytest.raises(ValueError, match="trained on different DrillStickSlip-v0 settings"):
        bs.task_settings(["mine.py:Full", "learned"], "DrillStickSlip-v0")
    with pytest.raises(ValueError, match=r"other\.py:Full is a policy of DrillOptimise-v0; "
                                         "it cannot act in DrillStickSlip-v0"):
        bm.run_benchmark(["stiff", "other.py:Full"], ["random"], [0], tmp_path / "x", SHORT,
                         workers=1, progress=False, env_id="DrillStickSlip-v0")
    assert not (tmp_path / "x" / bm.RESULTS_FILE).exists()
    # env_kwargs() that returns no dict, or raises, is named in one line
    (tmp_path / "bad.py").write_text(OWN_POLICY.replace("ENV", "DrillStickSlip-v0")
                                     .replace("return KWARGS", "return None"))
    with pytest.raises(ValueError, match=r"^controller: bad\.py:Full\.env_kwargs\(\) "
                                         "returned None, not a dict of env keywords"):
        bs.task_settings(["bad.py:Full"], "DrillStickSlip-v0")
    # a model's policy of DrillString-v0 reads its observation: refused in a task (a
    # set-point controller of DrillString-v0, as the driller, acts through action_for)
    (tmp_path / "base.py").write_text(
        "from agents.learned import sb3_policy\n"
        f"Base = sb3_policy({str(TRAINED / 'stick_slip' / 'model.zip')!r}, algo='sac', "
        "env_id='DrillString-v0', name='base')\n")
    with pytest.raises(ValueError, match="base.py:Base is a policy of DrillString-v0; it "
                                         "cannot act in DrillStickSlip-v0"):
        bs.task_settings(["driller", "base.py:Base"], "DrillStickSlip-v0")


def test_a_task_variants_benchmark_gets_a_folder_of_its_own(tmp_path, monkeypatch, capsys):
    """A benchmark of policies trained under other task settings (a variant: every
    controller acts under them) wrote its table over the task's own in
    logs/benchmark/<task> (a closing note's rough edge): without --out it now goes to
    variant-<run or file> inside it; the task's own settings keep the task's folder."""
    from drill_cli.benchmark import variant_folder

    monkeypatch.chdir(tmp_path)
    (tmp_path / "mine.py").write_text(OWN_POLICY.replace("ENV", "DrillStickSlip-v0")
                                      .replace("KWARGS", "{'max_correction': 15.0}"))
    (tmp_path / "same.py").write_text(OWN_POLICY.replace("ENV", "DrillStickSlip-v0")
                                      .replace("KWARGS", "{}"))
    mine = variant_folder(["stiff", "mine.py:Full"], "DrillStickSlip-v0")
    assert re.fullmatch(r"variant-mine-[0-9a-f]{6}", mine)
    assert variant_folder(["stiff", "same.py:Full"], "DrillStickSlip-v0") == ""
    # named after the one that carries the settings, not the first file of one's own (a
    # review: a set-point file first put two variants' runs in one folder)
    (tmp_path / "gentle.py").write_text(OWN_CONTROLLER.replace("GAIN", "2000.0"))
    assert variant_folder(["gentle.py:Gentle", "mine.py:Full"], "DrillStickSlip-v0") == mine
    assert variant_folder(["stiff", "learned"], "DrillStickSlip-v0") == ""  # shipped
    # a file of that name elsewhere, of other settings, has a folder of its own (a fuzzing
    # walkthrough: two runs of one name shared one, the second table over the first)
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "mine.py").write_text(
        OWN_POLICY.replace("ENV", "DrillStickSlip-v0").replace("KWARGS",
                                                               "{'max_correction': 12.0}"))
    other = variant_folder(["stiff", "other/mine.py:Full"], "DrillStickSlip-v0")
    assert other.startswith("variant-mine-") and other != mine
    (tmp_path / "other" / "mine.py").write_text(  # the same settings, typed otherwise
        OWN_POLICY.replace("ENV", "DrillStickSlip-v0").replace("KWARGS",
                                                               "{'max_correction': 15}"))
    assert variant_folder(["stiff", "other/mine.py:Full"], "DrillStickSlip-v0") == mine
    short = ["--seeds", "1", "--duration", "1", "--warmup", "0.5", "--workers", "1"]
    for controllers, folder in (("stiff,mine.py:Full", f"stick_slip/{mine}"),
                                ("stiff,same.py:Full", "stick_slip")):
        assert main(["benchmark", "--task", "stick_slip", "--controllers", controllers,
                     *short]) == 0
        rows = list(csv.DictReader((tmp_path / "logs/benchmark" / folder
                                    / "benchmark.csv").open()))
        assert {row["controller"] for row in rows} == {"stiff", "full"}  # (Full's name)
        said = capsys.readouterr().err
        assert (f"the benchmark goes to logs/benchmark/stick_slip/{mine}, apart from "
                "the task's own" in said) == (folder != "stick_slip")


def test_a_set_point_policy_of_drill_string_in_a_task_is_named_and_keeps_its_own_settings(
        tmp_path, monkeypatch):
    """From a walkthrough: a policy-rate controller of DrillString-v0 of your own that
    declared its sensors (env_kwargs() {"sensors": "surface"}) broke a task benchmark with
    "sensors: StickSlipEnv does not use sensors ... (the episode of stiff on random)": its
    DrillString-v0 settings were taken as the task's and tried on the stiff PI. They are
    its own (not the task's), and it is listed for the note that its act reads the task's
    observation; a task policy's env_kwargs() that the task refuses name that policy."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "mine.py").write_text(
        "from agents import SetPointController\n\n"
        "class Slow(SetPointController):\n"
        "    name = 'slow'\n    rate = 'policy'\n\n"
        "    def env_kwargs(self):\n        return {'sensors': 'surface'}\n\n"
        "class Drive(Slow):\n    name = 'drive'\n    rate = 'drive'\n")
    assert bs.task_settings(["stiff", "mine.py:Slow"], "DrillStickSlip-v0") == {}
    assert bs.set_point_guests(["stiff", "driller", "mine.py:Slow", "mine.py:Drive"],
                               "DrillStickSlip-v0") == ["mine.py:Slow"]
    assert bs.set_point_guests(["mine.py:Slow"], "DrillString-v0") == []
    (tmp_path / "task.py").write_text(OWN_POLICY.replace("ENV", "DrillStickSlip-v0")
                                      .replace("KWARGS", "{'sensors': 'surface'}"))
    with pytest.raises(ValueError, match=r"^controllers: task\.py:Full\.env_kwargs\(\): "
                                         "sensors: StickSlipEnv does not use sensors"):
        bs.task_settings(["stiff", "task.py:Full"], "DrillStickSlip-v0")


def test_changed_settings_do_not_reuse_old_rows_and_say_so(tmp_path, capsys):
    """Rows of other settings are not reused, and a run that starts afresh beside them
    says how many it left (it said nothing; an outside check of interrupts), as it says
    how many half-written lines it skipped."""
    bm.run_benchmark(["stiff"], ["stick_slip"], [0], tmp_path, SHORT, workers=1,
                     progress=False)
    other = bs.BenchmarkSettings(duration=5.0, warmup=2.0)
    assert len(ResultStore(tmp_path / bm.RESULTS_FILE, bm.fingerprint(SHORT))) == 1
    assert len(ResultStore(tmp_path / bm.RESULTS_FILE, bm.fingerprint(other))) == 0
    with (tmp_path / bm.RESULTS_FILE).open("a") as f:
        f.write('{"fingerprint": "f", "ke')  # a writer killed mid-line
    capsys.readouterr()
    bm.run_benchmark(["stiff"], ["stick_slip"], [0], tmp_path, other, workers=1)
    said = " ".join(capsys.readouterr().err.split())
    assert (f"benchmark: 1 stored row(s) of other settings or code in "
            f"{tmp_path / bm.RESULTS_FILE}: not used (kept in the file)") in said
    assert f"benchmark: the last line of {tmp_path / bm.RESULTS_FILE} was cut" in said
    store = ResultStore(tmp_path / bm.RESULTS_FILE, bm.fingerprint(other))
    assert (len(store), store.ignored, store.cut) == (1, 1, False)  # said once (a review:
    # the half line, kept in the file, was said at every later run)


def test_a_damaged_line_of_the_results_file_costs_that_line_only(tmp_path):
    """Bytes that are not UTF-8 made the whole store unreadable (an error naming no
    file); now their line is skipped as a half-written one is."""
    bm.run_benchmark(["stiff"], ["stick_slip"], [0], tmp_path, SHORT, workers=1,
                     progress=False)
    with (tmp_path / bm.RESULTS_FILE).open("ab") as f:
        f.write(b"\xff\xfe\x00garbage\n")
        # a hand-edited line of the right fingerprint without a result: skipped (KeyError)
        f.write(json.dumps({"fingerprint": bm.fingerprint(SHORT), "key": 5}).encode() + b"\n")
    assert len(ResultStore(tmp_path / bm.RESULTS_FILE, bm.fingerprint(SHORT))) == 1


def test_a_stored_row_is_sound_only_with_a_number_in_every_metric_column():
    """``sound_row``'s docstring: a stored row is reused only with numbers where the
    metrics are (SPEC section 5's columns after controller, scenario and seed); text or a
    boolean in any one of them is an edit, and its episode runs again."""
    episode = bs.Episode("stiff", "stick_slip", 0, {}, "")
    row = {"controller": "stiff", "scenario": "stick_slip", "seed": 0,
           **{c: 1.0 for c in SPEC_COLUMNS[3:]}, "episode_return": -2}
    assert bm.sound_row(row, episode)
    for column in SPEC_COLUMNS[3:]:
        for edit in ("abc", True):
            assert not bm.sound_row({**row, column: edit}, episode), (column, edit)


def test_a_result_put_after_a_killed_writers_half_line_is_kept(tmp_path):
    """The next result goes on a line of its own: glued to the half line, it was lost
    too, and a resumed sweep redid it."""
    path = tmp_path / "results.jsonl"
    store = ResultStore(path, "f")
    store.put("k1", 1)
    with path.open("a") as f:
        f.write('{"fingerprint": "f", "ke')  # a writer killed mid-line
    store = ResultStore(path, "f")
    store.put("k2", 2)
    store.put("k3", 3)  # the half line was ended once: no empty line before this one (a
    # mutation test: a newline written before every later result passed every test)
    again = ResultStore(path, "f")
    assert ("k1" in again, "k2" in again, len(again)) == (True, True, 3)
    assert again.get("k2") == 2
    assert "\n\n" not in path.read_text()


@pytest.mark.parametrize("workers", [1, 2])
def test_every_item_of_a_long_sweep_comes_back_under_its_own_index(workers):
    """More items than the pool keeps in flight (2 per worker): each result must come
    back with the index of the item it was computed from, once."""
    from drill_env.sweep import make_executor

    items = [-k for k in range(11)]
    executor = make_executor(workers)
    try:
        got = list(executor.map_unordered(abs, items))
    finally:
        executor.close()
    assert sorted(k for k, _ in got) == list(range(11))
    assert all(result == abs(items[k]) for k, result in got)


def test_a_sweep_keeps_two_tasks_per_worker_in_flight_and_cancels_them_when_stopped(
        monkeypatch):
    """ProcessExecutor keeps a few tasks per worker in flight (two), one more queued for
    each result, so that an interrupt leaves little work half done; a sweep stopped (its
    generator closed, as a Ctrl-C in the loop over it does) cancels those queued. A pool
    simulated, which runs the first ``done`` tasks at once and leaves the rest queued
    (mutation tests: one task per worker, every task queued at the first result, and
    none cancelled each passed every test)."""
    from concurrent.futures import Future

    import drill_env.sweep as sweep

    class Pool:
        def __init__(self, *args, **kwargs) -> None:
            self.futures: list[Future] = []
            self.done = math.inf

        def submit(self, fn, *args) -> Future:
            future: Future = Future()
            if len(self.futures) < self.done:
                future.set_result(fn(*args))
            self.futures.append(future)
            return future

    monkeypatch.setattr(sweep, "ProcessPoolExecutor", Pool)
    executor = sweep.ProcessExecutor(2)
    in_flight = []
    for n, (k, result) in enumerate(executor.map_unordered(abs, [-k for k in range(11)])):
        assert result == k
        in_flight.append(len(executor._pool.futures) - n)  # queued, less those yielded
    assert len(in_flight) == 11 and max(in_flight) == 4
    executor = sweep.ProcessExecutor(2)
    executor._pool.done = 1
    stopped = executor.map_unordered(abs, range(11))
    assert next(stopped) == (0, 0)
    stopped.close()
    queued = executor._pool.futures[1:]
    assert len(queued) == 3 and all(future.cancelled() for future in queued)


def test_rows_of_other_code_are_not_reused(tmp_path, monkeypatch):
    """The fingerprint holds a hash of the package sources: after a change to the
    simulator or a controller, a benchmark (``make demo`` run again) recomputes."""
    import drill_env.sweep as sweep

    before = bm.fingerprint(SHORT)
    monkeypatch.setattr(sweep, "source_digest", lambda *packages: "edited")
    assert bm.fingerprint(SHORT) != before


def test_source_digest_follows_the_files(tmp_path, monkeypatch):
    from drill_env.sweep import source_digest

    package = tmp_path / "pkg_for_digest"
    (package / "sub").mkdir(parents=True)
    (package / "__init__.py").write_text("")
    (package / "sub" / "model.py").write_text("K = 1.0\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    first = source_digest("pkg_for_digest")
    source_digest.cache_clear()
    assert source_digest("pkg_for_digest") == first  # same files, same hash
    (package / "sub" / "model.py").write_text("K = 2.0\n")
    source_digest.cache_clear()
    second = source_digest("pkg_for_digest")
    assert second != first
    (package / "sub" / "model.py").rename(package / "sub" / "other.py")  # same bytes
    source_digest.cache_clear()
    assert source_digest("pkg_for_digest") != second  # a moved module is other code
    with pytest.raises(ValueError, match="'no_such_package_here'"):
        source_digest("no_such_package_here")


def test_a_rerun_writes_the_recordings_that_are_missing(tmp_path, monkeypatch, capsys):
    """Stored rows are reused, except where ``--record`` asks for a recording that is not
    there; the run says how many it reused."""
    real = be.run_episode
    calls: list[str] = []
    monkeypatch.setattr(bm, "run_episode", lambda e: calls.append(e.key) or real(e))
    args = (["stiff", "z-torque"], ["stick_slip"], [0], tmp_path, SHORT)
    bm.run_benchmark(*args, workers=1, progress=False)
    assert len(calls) == 2 and not (tmp_path / "recordings").exists()
    calls.clear()
    bm.run_benchmark(*args, workers=1, record=True)
    assert len(calls) == 2  # stored rows, but no recordings yet
    (tmp_path / "recordings" / "z-torque_stick_slip_seed0.rrd").unlink()
    calls.clear()
    capsys.readouterr()
    bm.run_benchmark(*args, workers=1, record=True)
    assert calls == ["z-torque|stick_slip|0"]
    assert "1 of 2 episodes already in" in capsys.readouterr().err
    assert sorted(p.name for p in (tmp_path / "recordings").glob("*.rrd")) == [
        "stiff_stick_slip_seed0.rrd", "z-torque_stick_slip_seed0.rrd"]


def test_a_rerun_without_record_sets_aside_the_recordings_of_other_settings(tmp_path,
                                                                            capsys):
    """A benchmark with --record, then one of other settings without it into the same
    folder: the table held the new rows and recordings/ the old episodes under the same
    names, which replayed episodes the table does not show. Now they are moved to
    recordings/other_runs/<their run's stamp>/, one folder per run (both seeds of a run
    together; they went to one folder per episode), so a second set-aside keeps the
    first; a recording of the table's own rows stays."""
    other = bs.BenchmarkSettings(duration=5.0, warmup=2.0)
    third = bs.BenchmarkSettings(duration=4.0, warmup=2.0)
    args = (["stiff"], ["stick_slip"], [0, 1], tmp_path)
    recordings = [tmp_path / "recordings" / f"stiff_stick_slip_seed{k}.rrd" for k in (0, 1)]
    sidecars = [r.with_name(r.name + ".stamp") for r in recordings]
    aside = tmp_path / "recordings" / "other_runs"
    made = {}
    for settings in (SHORT, third):
        bm.run_benchmark(*args, settings, workers=1, record=True, progress=False)
        run = {s.read_text().split()[1] for s in sidecars}
        assert len(run) == 1 and {s.read_text().split()[0] for s in sidecars} != run
        made[run.pop()] = [(r.read_bytes(), s.read_text())
                           for r, s in zip(recordings, sidecars, strict=True)]
        bm.run_benchmark(*args, settings, workers=1, progress=True)  # its own: kept
        assert [r.read_bytes() for r in recordings] == [data for data, _ in
                                                         list(made.values())[-1]]
        capsys.readouterr()
        bm.run_benchmark(*args, other, workers=1, progress=True)
        assert not any(r.exists() or s.exists() for r, s in zip(recordings, sidecars,
                                                                strict=True))
        assert "2 recording(s) of another run" in capsys.readouterr().err
    assert len(made) == 2
    assert sorted(p.name for p in aside.iterdir()) == sorted(made)
    for run, files in made.items():
        for recording, sidecar, (data, stamp) in zip(recordings, sidecars, files,
                                                     strict=True):
            assert (aside / run / recording.name).read_bytes() == data
            assert (aside / run / sidecar.name).read_text() == stamp


def test_a_rerun_with_record_keeps_the_recordings_of_other_settings(tmp_path, capsys):
    """Two recorded benchmarks of other settings into one folder: the second's
    recordings replaced the first's under the same names, silently. Now the first's are
    set aside before the second records."""
    other = bs.BenchmarkSettings(duration=5.0, warmup=2.0)
    args = (["stiff"], ["stick_slip"], [0], tmp_path)
    recording = tmp_path / "recordings" / "stiff_stick_slip_seed0.rrd"
    sidecar = recording.with_name(recording.name + ".stamp")
    bm.run_benchmark(*args, SHORT, workers=1, record=True, progress=False)
    first, stamp = recording.read_bytes(), sidecar.read_text()
    capsys.readouterr()
    bm.run_benchmark(*args, other, workers=1, record=True, progress=True)
    assert "1 recording(s) of another run" in capsys.readouterr().err
    (kept,) = (tmp_path / "recordings" / "other_runs").iterdir()
    assert (kept / recording.name).read_bytes() == first
    assert (kept / sidecar.name).read_text() == stamp
    assert recording.read_bytes() != first and sidecar.read_text() != stamp


def test_a_recording_an_interrupt_cut_short_is_recorded_again_not_set_aside(
        tmp_path, monkeypatch, capsys):
    """A rerun after an interrupted `benchmark --record` called the run's own recording
    cut short "of another run (other settings or code)" and kept it in other_runs/
    unstamped/, where such stubs piled up (a fuzzing walkthrough). A recording is marked
    unfinished while it is made; the rerun deletes its own unfinished ones and records
    them again, and sets aside another run's as before."""
    import drill_env.recording as rec

    real = rec.RecordEpisode

    def cut_short(env, folder, **kwargs):  # the episode interrupted as it records
        recording = Path(folder) / f"{kwargs['stem']}.rrd"
        stamp = recording.with_name(recording.name + ".stamp").read_text().split()
        assert stamp[0] == bs.UNFINISHED  # marked before it starts
        recording.write_bytes(b"cut short")
        raise KeyboardInterrupt

    monkeypatch.setattr(rec, "RecordEpisode", cut_short)
    args = (["stiff"], ["stick_slip"], [0], tmp_path, SHORT)
    with pytest.raises(KeyboardInterrupt):
        bm.run_benchmark(*args, workers=1, record=True, progress=False)
    monkeypatch.setattr(rec, "RecordEpisode", real)
    capsys.readouterr()
    bm.run_benchmark(*args, workers=1, record=True, progress=True)
    assert "1 recording(s) an interrupt cut short: deleted, recorded again" in \
        capsys.readouterr().err
    recording = tmp_path / "recordings" / "stiff_stick_slip_seed0.rrd"
    assert recording.read_bytes() != b"cut short"
    assert recording.with_name(recording.name + ".stamp").read_text().split()[0] != \
        bs.UNFINISHED
    assert not (tmp_path / "recordings" / "other_runs").exists()
    # another run's unfinished one is set aside under that run's stamp, as a finished one
    episode = bs.Episode("stiff", "stick_slip", 1, {}, str(tmp_path), record=True,
                         stamp="this", run="thisrun")
    episode.recording.write_bytes(b"another run's, cut short")
    episode.recording_stamp.write_text(f"{bs.UNFINISHED}\notherrun\n")
    bm.set_aside_stale_recordings([episode], tmp_path, say=False)
    aside = tmp_path / "recordings" / "other_runs" / "otherrun"
    assert (aside / episode.recording.name).read_bytes() == b"another run's, cut short"


def test_a_recording_whose_stamp_is_damaged_is_set_aside_as_unstamped(tmp_path):
    """``set_aside_stale_recordings``: a recording of another run goes to
    recordings/other_runs/<its run's stamp>/, "a damaged stamp is not a path": one that
    reads as a path goes to other_runs/unstamped, not where the path points."""
    episode = bs.Episode("stiff", "stick_slip", 0, {}, str(tmp_path), record=True,
                         stamp="this", run="thisrun")
    episode.recording.parent.mkdir(parents=True)
    episode.recording.write_bytes(b"another run's")
    episode.recording_stamp.write_text("other\n../../elsewhere\n")
    bm.set_aside_stale_recordings([episode], tmp_path, say=False)
    aside = tmp_path / "recordings" / "other_runs" / "unstamped"
    assert (aside / episode.recording.name).read_bytes() == b"another run's"
    assert (aside / episode.recording_stamp.name).is_file()
    assert [p.name for p in tmp_path.iterdir()] == ["recordings"]


def test_a_row_is_reused_only_with_the_series_and_recording_of_its_own_run(tmp_path,
                                                                           monkeypatch):
    """A benchmark into a folder that a run of other settings used: a stored row came
    back with that run's recording (and series, drawn in the picture) beside it; a row
    whose series file was deleted came back without its picture."""
    real = be.run_episode
    calls: list[str] = []
    monkeypatch.setattr(bm, "run_episode", lambda e: calls.append(e.key) or real(e))
    other = bs.BenchmarkSettings(duration=5.0, warmup=2.0)
    args = (["stiff"], ["stick_slip"], [0])
    bm.run_benchmark(*args, tmp_path, SHORT, workers=1, record=True, progress=False)
    bm.run_benchmark(*args, tmp_path, other, workers=1, record=True, progress=False)
    calls.clear()  # SHORT's row is stored, but the recording and series are other's
    bm.run_benchmark(*args, tmp_path, SHORT, workers=1, record=True, progress=False)
    assert calls == ["stiff|stick_slip|0"]
    series = np.load(tmp_path / "series" / "stiff_stick_slip_seed0.npz")
    assert series["time"][-1] == pytest.approx(SHORT.duration, abs=0.2)
    calls.clear()
    bm.run_benchmark(*args, tmp_path, SHORT, workers=1, record=True, progress=False)
    assert calls == []  # all its own: nothing runs
    (tmp_path / "series" / "stiff_stick_slip_seed0.npz").unlink()
    bm.run_benchmark(*args, tmp_path, SHORT, workers=1, progress=False)
    assert calls == ["stiff|stick_slip|0"]
    assert (tmp_path / "benchmark_stick_slip_series.png").exists()
    calls.clear()  # half a file (a run killed while writing it): run again, no traceback
    series = tmp_path / "series" / "stiff_stick_slip_seed0.npz"
    series.write_bytes(series.read_bytes()[:100])
    bm.run_benchmark(*args, tmp_path, SHORT, workers=1, progress=False)
    assert calls == ["stiff|stick_slip|0"]


def test_the_series_picture_draws_the_first_seed_of_this_benchmark(tmp_path, monkeypatch):
    """``seed10`` sorts before ``seed2``: the picture of a benchmark of seed 2 drew an
    older benchmark's seed 10."""
    from agents import plots

    drawn: list[str] = []
    real_load = plots.np.load
    monkeypatch.setattr(plots.np, "load", lambda f, *a, **k: drawn.append(Path(f).name)
                        or real_load(f, *a, **k))
    _series(tmp_path, ["stiff"], ["stick_slip"])
    for seed in (10, 2):
        (tmp_path / "series" / f"stiff_stick_slip_seed{seed}.npz").write_bytes(
            (tmp_path / "series" / "stiff_stick_slip_seed0.npz").read_bytes())
    bt.write_outputs([_row("stiff", "stick_slip")], tmp_path, ["stiff"], ["stick_slip"],
                     SHORT, first_seed=2)
    assert drawn == ["stiff_stick_slip_seed2.npz"]


def test_a_task_benchmark_says_which_training_episodes_it_replaces(tmp_path):
    """A policy trained on 5 s episodes ran on the benchmark's 30 s ones without a
    word, where evaluate says so."""
    import shutil
    from types import SimpleNamespace

    import yaml

    from drill_cli.benchmark import replaced_episode_notes

    run = tmp_path / "short"
    shutil.copytree(TRAINED / "stick_slip", run)
    config = yaml.safe_load((run / "config.yaml").read_text())
    config["env_kwargs"] = {"episode_duration": 5.0, "max_correction": 20.0}
    # (a run trained with these env_kwargs: the shipped record of its settings is not
    # its own, and would be a note of moved settings)
    (run / "trained_with.json").unlink()
    (run / "config.yaml").write_text(yaml.safe_dump(config))
    settings = SimpleNamespace(duration=30.0, start_kick=0.02)
    notes = replaced_episode_notes([f"learned:{run}", "stiff"], "DrillStickSlip-v0",
                                   ["random"], settings)
    assert notes == [f"note: learned:{run} trained with episode_duration=5.0; the "
                     "benchmark runs every controller on its own episodes "
                     "(episode_duration=30.0)"]
    assert replaced_episode_notes(["learned"], "DrillStickSlip-v0", ["random"],
                                  settings) == []  # the shipped policy: the task's own
    # a model of your own (sb3_policy) says the episodes it trained on the same way
    mine = tmp_path / "mine.py"
    mine.write_text("from agents.learned import sb3_policy\n"
                    f"Mine = sb3_policy({str(run / 'model.zip')!r}, "
                    f"{str(run / 'vecnormalize.pkl')!r}, algo='sac', "
                    "env_id='DrillStickSlip-v0', env_kwargs={'episode_duration': 60.0})\n")
    assert replaced_episode_notes([f"{mine}:Mine"], "DrillStickSlip-v0", ["random"],
                                  settings) == [
        f"note: {mine}:Mine trained with episode_duration=60.0; the benchmark runs every "
        "controller on its own episodes (episode_duration=30.0)"]


def test_benchmark_names_bad_input(capsys, monkeypatch):
    for args, message in ((["--controllers", "pid"], "unknown name 'pid'"),
                          (["--scenarios", "moon"], "--scenarios"),
                          (["--duration", "10", "--warmup", "20"], "--warmup"),
                          (["--task", "stick_slip", "--duration", "3"],
                           "--warmup: 5 s (the default of --task stick_slip) must be "
                           "shorter than --duration (3 s); give a shorter --warmup"),
                          (["--controllers", "stiff,learned:/no/such/run"],
                           "--controllers: learned: no such folder /no/such/run"),
                          (["--controllers", f"stiff,learned:{__file__}"],
                           f"--controllers: learned: {__file__} is a file, not a folder"),
                          (["--rpm", "500"], "--rpm: 500 rpm is outside DrillString-v0's "
                                             "range 0-200 rpm"),
                          (["--wob", "0.1"], "--wob: 0.1 kN is only 100 N: the WOB is in kN"),
                          (["--rpm", "0"], "--rpm: must be > 0 rpm, got 0"),
                          (["--task", "stick_slip", "--wob", "100"],
                           "--wob: a task benchmark drills at the targets its task draws")):
        with pytest.raises(SystemExit):
            main(["benchmark", *args])
        assert message in capsys.readouterr().err
    # from Python: no workers is no way to run, not "all cores"
    from drill_env.sweep import make_executor

    with pytest.raises(ValueError, match="workers: must be >= 1, got 0"):
        make_executor(0)
    # far more than the cores is said (999 started 31 processes of 8 GB: a fuzz)
    import drill_env.sweep as sweep

    monkeypatch.setattr(sweep, "usable_cores", lambda: 2)
    with pytest.warns(UserWarning, match="workers: 5 processes on 2 cores run no faster"):
        make_executor(5).close()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        make_executor(4).close()


def test_every_controller_gets_its_own_table_name():
    assert bs.labels(["learned", "learned:/runs/a", "stiff"]) == ["learned", "learned-a",
                                                                   "stiff"]
    assert bs.labels(["learned:/runs/a"]) == ["learned"]  # alone it is "the" policy
    # a run folder named relative, as an identifier: still the registry's learned:<run
    # folder>, not the import form <module>:<class> of a controller of one's own
    assert bs.labels(["learned:run1", "stiff"]) == ["learned", "stiff"]
    with pytest.raises(ValueError, match="'stiff' is given twice"):
        bs.labels(["stiff", "stiff"])
    with pytest.raises(ValueError, match="share the name 'learned-run'"):
        bs.labels(["learned:/x/run", "learned:/y/run", "learned"])
    # one run spelt two ways is given twice, not two runs to rename (a fuzzing walkthrough)
    with pytest.raises(ValueError, match=r"learned:/x/run, learned:/x/run/ are the same run "
                                         r"\(/x/run\), given twice"):
        bs.labels(["learned:/x/run", "learned:/x/run/"])
    # set points have one name however they are typed
    assert bs.labels(["constant:1e2/90.0", "constant:120/100"]) == [
        "constant-100rpm-90kN", "constant-120rpm-100kN"]
    with pytest.raises(ValueError, match="constant:1e2/100, constant:100/100 are the same"):
        bs.labels(["constant:1e2/100", "constant:100/100"])
    assert bs.labels(["constant:123.4567/100", "constant:123.4568/100"]) == [
        "constant-123.4567rpm-100kN", "constant-123.4568rpm-100kN"]  # apart, as typed


def test_a_table_name_of_set_points_runs_them_again():
    """benchmark.csv names constant set points constant-<rpm>rpm-<kN>kN: that name given
    back to --controllers is the same controller (the same label, the same set points);
    a trained run's table name is refused with the form to give."""
    from agents.registry import make_controller, parse_controllers

    for typed in ("constant:160/65", "constant:1e2/90.5"):
        table = bs.label(typed)
        (again,) = parse_controllers(table)
        assert bs.label(again) == table
        assert make_controller(table).physics() == make_controller(typed).physics()
        assert (make_controller(table).speed, make_controller(table).weight_on_bit) == (
            make_controller(typed).speed, make_controller(typed).weight_on_bit)
    with pytest.raises(ValueError, match="give it as learned:<run folder>"):
        parse_controllers("stiff,learned-a")


def test_a_retrained_policy_is_not_served_its_old_rows(tmp_path):
    """The stored rows of a learned controller are keyed by its model files' hash."""
    import shutil

    from agents.learned import TRAINED

    run = tmp_path / "run"
    shutil.copytree(TRAINED / "stick_slip", run)
    before = bm.episodes([f"learned:{run}", "stiff"], ["stick_slip"], [0], SHORT, tmp_path)
    with (run / "model.zip").open("ab") as f:
        f.write(b"retrained")
    after = bm.episodes([f"learned:{run}", "stiff"], ["stick_slip"], [0], SHORT, tmp_path)
    assert before[0].key != after[0].key  # the policy
    assert before[1].key == after[1].key  # the classical controller
    assert before[0].label == after[0].label == "learned"


def test_a_bad_constant_set_point_names_the_flag_typed(capsys):
    with pytest.raises(SystemExit):
        main(["benchmark", "--controllers", "constant:abc"])
    assert "--controllers: constant:<rpm>/<kN> expected" in capsys.readouterr().err


def test_a_constant_set_point_outside_the_envs_range_is_refused_not_clipped(tmp_path,
                                                                           capsys):
    """The env would clip 500 rpm to 200 and the row would carry a name it never drilled;
    a negative one is named in the units typed."""
    for text, says in (("constant:500/80", "500 rpm is outside the env's range 0-200 rpm"),
                       ("constant:120/900", "900 kN is outside the env's range"),
                       ("constant:-10/80", "got -10 rpm, 80 kN")):
        with pytest.raises(SystemExit) as stopped:
            main(["run", "--controller", text, "--duration", "0.2", "--out", str(tmp_path)])
        assert stopped.value.code == 2
        err = capsys.readouterr().err
        assert "run: error: --controller: " in err and says in err
    # the benchmark refuses it before its first episode, not in a worker mid-run
    with pytest.raises(SystemExit) as stopped:
        main(["benchmark", "--controllers", "stiff,constant:500/80", "--scenarios",
              "default", "--seeds", "1", "--out", str(tmp_path / "bench")])
    assert stopped.value.code == 2
    assert "--controllers: constant:500/80: 500 rpm is outside" in capsys.readouterr().err
    assert not (tmp_path / "bench" / "benchmark_results.jsonl").exists()


def test_the_series_chart_lays_out_a_sweep_of_many_controllers(tmp_path):
    """`training.evaluate` benchmarks a grid of 25 constant set points: the legend of
    every controller must not push the plots off the page (matplotlib then warns that
    tight_layout cannot apply and the figure comes out squashed)."""
    import warnings

    import numpy as np

    from agents.plots import series_chart

    names = [bs.label(f"constant:{r}/{w}") for r in (40, 80, 120, 160, 200)
             for w in (40, 65, 90, 115, 140)]
    t = np.linspace(0.0, 10.0, 101)
    for k, name in enumerate(names):
        np.savez(tmp_path / f"{name}_random_seed0.npz", time=t, bit_x=0.001 * np.sin(t),
                 bit_y=0.001 * np.cos(t), clearance=0.02, bit_speed=(5.0 + k) * (1 + 0 * t),
                 torque_on_bit=2e3 + 0 * t, surface_torque=3e3 + 0 * t)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        series_chart(tmp_path, names, "random", tmp_path / "series.png", warmup=2.0)
    assert (tmp_path / "series.png").stat().st_size > 10_000


def test_the_series_picture_draws_only_this_runs_episodes(tmp_path):
    """Two benchmarks into one folder at once: the picture beside one's table showed the
    other's episodes (the series files are shared); a file of another stamp is left out."""
    import numpy as np

    from agents.plots import series_chart

    t = np.linspace(0.0, 10.0, 101)
    np.savez(tmp_path / "stiff_stick_slip_seed0.npz", time=t, bit_x=0 * t, bit_y=0 * t,
             clearance=0.02, bit_speed=5.0 + 0 * t, torque_on_bit=2e3 + 0 * t,
             surface_torque=3e3 + 0 * t, stamp=np.array("other run"))
    picture = tmp_path / "series.png"
    assert not series_chart(tmp_path, ["stiff"], "stick_slip", picture, warmup=2.0,
                            stamps={"stiff": "this run"})
    assert not picture.exists()
    assert series_chart(tmp_path, ["stiff"], "stick_slip", picture, warmup=2.0,
                        stamps={"stiff": "other run"})


def test_an_aborted_process_pool_stops_workers_that_do_not_end(monkeypatch, tmp_path):
    """Closed while an exception (a Ctrl-C) propagates, the pool gives its workers a grace
    period, then stops them: an interrupted sweep must neither hang nor leave workers."""
    import os
    import time
    from pathlib import Path

    from helpers import sleep_through_interrupts

    from drill_env.sweep import ProcessExecutor

    monkeypatch.setattr(ProcessExecutor, "ABORT_GRACE", 1.0)
    executor = ProcessExecutor(2)
    markers = [tmp_path / f"task{k}" for k in range(2)]
    for m in markers:
        executor._pool.submit(sleep_through_interrupts, str(m))
    deadline = time.monotonic() + 120.0  # spawned workers import numba first
    while not all(m.exists() for m in markers):
        assert time.monotonic() < deadline
        time.sleep(0.05)
    processes = list(executor._pool._processes.values())
    start = time.monotonic()
    try:
        raise KeyboardInterrupt
    except KeyboardInterrupt:
        executor.close()
    assert time.monotonic() - start < 10.0

    def gone(pid: int) -> bool:
        """No such process, or a zombie (its exit is done; ``is_alive`` cannot tell
        when the pool's own thread has reaped it first)."""
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return True
        stat = Path(f"/proc/{pid}/stat")
        return stat.exists() and stat.read_text().rsplit(")", 1)[1].split()[0] == "Z"

    deadline = time.monotonic() + 5.0
    while not all(gone(p.pid) for p in processes) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert all(gone(p.pid) for p in processes)


def test_an_interrupt_of_the_command_alone_reaches_the_workers_once(tmp_path):
    """``kill -INT`` of the command (not of its process group) left the workers training
    for the grace period, then stopped them unsaved; now the pool forwards the interrupt,
    and a worker that already had one (a terminal's Ctrl-C reaches the whole group) does
    not have its save cut short by the copy. The tasks queued behind (the pool cannot
    cancel them) do not start: they ran with the interrupts ignored until the pool killed
    them unsaved, and kept the command waiting the whole grace period."""
    from helpers import save_on_interrupt

    from drill_env.sweep import ProcessExecutor, _unless_interrupted

    executor = ProcessExecutor(2)
    markers = [str(tmp_path / f"task{k}") for k in range(4)]
    for m in markers:  # as map_unordered submits them
        executor._pool.submit(_unless_interrupted, save_on_interrupt, m)
    deadline = time.monotonic() + 120.0  # spawned workers import numba first
    while not all(Path(m).exists() for m in markers[:2]):
        assert time.monotonic() < deadline
        time.sleep(0.05)
    start = time.monotonic()
    try:
        raise KeyboardInterrupt  # what the command's own Ctrl-C raises here
    except KeyboardInterrupt:
        executor.close()
    assert time.monotonic() - start < 0.5 * ProcessExecutor.ABORT_GRACE
    assert [Path(m).read_text() for m in markers[:2]] == ["saved", "saved"]
    assert not any(Path(m).exists() for m in markers[2:])


@pytest.mark.parametrize("signum", ["SIGTERM", "SIGHUP"])
def test_a_sigterm_interrupts_a_workers_task_and_is_noted_where_its_exception_is_lost(
        tmp_path, signum):
    """A pool worker's first SIGTERM (a scheduler's stop of the job's process group) or
    SIGHUP (the job's terminal closed) is handled as its first Ctrl-C: the task is
    interrupted (a training run saves its checkpoint), where the signal's default killed
    the worker unsaved and broke the pool; and where the task's exception is lost (numba's
    compile callbacks), ``noted_interrupt`` still says it, for the training loop to stop
    at its next step (mutation tests: the worker's SIGTERM handler dropped, and a worker's
    interrupt not noted, each passed every test)."""
    import os
    import signal

    from helpers import ctrl_c_as_in_a_terminal, lose_an_interrupt

    from drill_env.sweep import ProcessExecutor, _unless_interrupted

    executor = ProcessExecutor(1)
    marker = tmp_path / "task"
    # (the pool starts its worker at the first task: with SIGHUP's default, as under a
    # terminal, not a nohup'd test run's ignoring, which the worker would keep)
    try:
        with ctrl_c_as_in_a_terminal():
            future = executor._pool.submit(_unless_interrupted, lose_an_interrupt,
                                           str(marker))
            deadline = time.monotonic() + 120.0  # a spawned worker imports numba first
            while not marker.exists():
                assert time.monotonic() < deadline
                time.sleep(0.05)
        (worker,) = executor._pool._processes.values()
        os.kill(worker.pid, getattr(signal, signum))
        assert future.result(timeout=60) == "KeyboardInterrupt"
    finally:
        executor.close()


def test_a_hang_up_ignored_by_nohup_stays_ignored_in_the_workers():
    """``nohup drill-env benchmark ...``: the command and its pool workers keep running
    when the terminal closes (SIGHUP came ignored); without nohup a worker's SIGHUP
    interrupts its task as a Ctrl-C does."""
    import signal

    from helpers import ctrl_c_as_in_a_terminal, hang_up_handling

    from drill_env.sweep import ProcessExecutor

    before = signal.signal(signal.SIGHUP, signal.SIG_IGN)  # as nohup starts a command
    try:
        executor = ProcessExecutor(1)  # (spawned: a SIG_IGN lasts through exec)
        try:
            assert dict(executor.map_unordered(hang_up_handling, [0])) == {0: "ignored"}
        finally:
            executor.close()
    finally:
        signal.signal(signal.SIGHUP, before)
    executor = ProcessExecutor(1)
    try:  # (its worker starts at the first task: SIGHUP's default, as in a terminal)
        with ctrl_c_as_in_a_terminal():
            assert dict(executor.map_unordered(hang_up_handling, [0])) == {0: "interrupts"}
    finally:
        executor.close()


def test_a_failed_task_stops_the_pool_without_the_idle_workers_tracebacks():
    """A task's error (a damaged policy file) aborts the pool; its idle workers, told to
    stop while waiting for a task or ending, printed two KeyboardInterrupt tracebacks
    from the pool's own code above the error the command then reported."""
    import subprocess

    code = ("import sys; sys.path.insert(0, 'tests'); from helpers import fail_last\n"
            "from drill_env.sweep import ProcessExecutor\n"
            "if __name__ == '__main__':\n"
            "    e = ProcessExecutor(2)\n"
            "    try:\n"
            "        try:\n"
            "            print(sorted(k for k, _ in e.map_unordered(fail_last, range(4))))\n"
            "        finally:\n"
            "            e.close()\n"
            "    except ValueError as err:\n"
            "        print('error:', err)\n")
    done = subprocess.run([sys.executable, "-c", code], cwd=Path(__file__).parents[1],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert "error: task 3 failed" in done.stdout
    assert "Traceback" not in done.stderr, done.stderr


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="PR_SET_PDEATHSIG")
def test_the_workers_end_with_a_killed_command(tmp_path):
    """A command killed outright (SIGKILL, the OOM killer) left its pool's workers
    running, training into the folder a rerun then used too."""
    import os
    import signal
    import subprocess

    pid_file = tmp_path / "worker.pid"
    code = ("import sys, time; sys.path.insert(0, 'tests'); "
            "from drill_env.sweep import ProcessExecutor; from helpers import "
            "write_pid_and_wait; e = ProcessExecutor(1); "
            f"e._pool.submit(write_pid_and_wait, {str(pid_file)!r}); time.sleep(120)")
    command = subprocess.Popen([sys.executable, "-c", code],
                               cwd=Path(__file__).parents[1])
    try:
        deadline = time.monotonic() + 60.0
        while not pid_file.exists() or not pid_file.read_text():
            assert time.monotonic() < deadline and command.poll() is None
            time.sleep(0.1)
        worker = int(pid_file.read_text())
        command.send_signal(signal.SIGKILL)
        command.wait()
        deadline = time.monotonic() + 10.0
        while Path(f"/proc/{worker}").exists() and "\nState:\tZ" not in Path(
                f"/proc/{worker}/status").read_text() and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not Path(f"/proc/{worker}").exists() or "\nState:\tZ" in Path(
            f"/proc/{worker}/status").read_text()
    finally:
        command.kill()
        if pid_file.exists() and pid_file.read_text():
            with contextlib.suppress(ProcessLookupError):
                os.kill(int(pid_file.read_text()), signal.SIGKILL)


# --------------------------------------------------------------------------- outputs


def _row(controller: str, scenario: str, seed: int = 0, **values: float) -> dict:
    """A benchmark row of steady drilling at 50 rpm, ``values`` overriding columns."""
    row = {c: 0.0 for c in SPEC_COLUMNS}
    row.update(controller=controller, scenario=scenario, seed=seed, mean_bit_rpm=50.0,
               target_rpm=50.0, rop_m_per_h=12.0, mse_MPa=146.0, top_drive_energy_MJ=0.66,
               episode_return=198.0, termination="")
    row.update(values)
    return row


def _series(out, controllers, scenarios, radial: float = 0.3, **channels) -> None:
    """First-seed time series as ``run_episode`` keeps them, the bit ``radial`` of the
    clearance off the hole axis; ``channels`` replace or add series by name."""
    import numpy as np

    (out / "series").mkdir(parents=True, exist_ok=True)
    t = np.linspace(0.0, 10.0, 101)
    kept = {"time": t, "clearance": 0.02, "bit_x": 0.02 * radial + 0 * t, "bit_y": 0 * t,
            "bit_speed": 5.2 + 0 * t, "torque_on_bit": 3.5e3 + 0 * t,
            "surface_torque": 4.3e3 + 0 * t} | channels
    for c in controllers:
        for s in scenarios:
            np.savez(out / "series" / f"{c}_{s}_seed0.npz", **kept)


def _drawn_texts(monkeypatch, ticks: list[int] | None = None) -> list[str]:
    """The texts written into the panels of every figure saved from now on (and, into
    ``ticks``, each panel's number of y ticks)."""
    from matplotlib.figure import Figure

    texts: list[str] = []
    save = Figure.savefig

    def keep_texts(fig, *args, **kwargs):
        texts.extend(t.get_text() for ax in fig.axes for t in ax.texts)
        if ticks is not None:
            ticks.extend(len(ax.get_yticks()) for ax in fig.axes)
        return save(fig, *args, **kwargs)

    monkeypatch.setattr(Figure, "savefig", keep_texts)
    return texts


def test_a_panel_whose_values_are_all_zero_says_so(tmp_path, monkeypatch):
    """No backward whirl and no stuck bit in any episode (the demo): those panels say so
    instead of an empty 0-0.05 axis that looks like a broken plot; the others do not."""
    from agents.plots import bar_chart, series_chart

    ticked: list[int] = []  # y ticks per panel: an empty one has no scale to misread
    texts = _drawn_texts(monkeypatch, ticked)
    rows = [_row("stiff", "stick_slip", ssi=1.3), _row("z-torque", "stick_slip")]
    bar_chart(rows, ["stiff", "z-torque"], ["stick_slip"], tmp_path / "bars.png")
    assert ticked.count(0) == 2 and len(ticked) > 2
    assert "no backward whirl in any episode" in texts
    assert "the bit never stuck in any episode" in texts
    assert not any("no stick-slip" in t for t in texts)  # the stiff one stick-slips
    assert len(texts) == 2
    texts.clear()  # a smooth run's SSI is round-off, ~1e-7: no stick-slip, said
    rows = [_row("stiff", "default", ssi=2e-7), _row("z-torque", "default", ssi=1e-7)]
    bar_chart(rows, ["stiff", "z-torque"], ["default"], tmp_path / "bars.png")
    assert "no stick-slip in any episode (SSI under 0.001)" in texts

    texts.clear()  # the bit on the hole axis throughout: the radial panel says so
    _series(tmp_path, ["stiff"], ["default"], radial=1e-12)
    assert series_chart(tmp_path / "series", ["stiff"], "default", tmp_path / "s.png", 2.0)
    assert len(texts) == 1 and "stays on the hole axis" in texts[0]
    texts.clear()
    _series(tmp_path, ["stiff"], ["default"], radial=0.3)
    assert series_chart(tmp_path / "series", ["stiff"], "default", tmp_path / "s.png", 2.0)
    assert texts == []


def test_the_bars_whiskers_are_the_tables_interval(tmp_path, monkeypatch):
    """The table's "+-" is the 95 % interval of the mean over seeds; the bar chart drew
    only the seeds' dots. Its whisker is now that interval, by hand: SSI 0.2 and 0.4 ->
    0.30 +- 12.706 x 0.1; the stuck share 10 % and 30 % in percent, x 100; none where the
    seeds agree; cut at the metric's range, and at the panel's edge, which the bars and
    dots set (two seeds' interval, t = 12.7, flattened every bar: a new user's trial),
    with an arrowhead there."""
    from matplotlib.axes import Axes

    from agents.plots import HEADROOM, bar_chart

    drawn: list[tuple[float, ...]] = []
    arrows: list[tuple[float, str]] = []
    errorbar, plot = Axes.errorbar, Axes.plot

    def keep(ax, x, y, yerr=None, **kwargs):
        drawn.append((float(y), *np.ravel(yerr)))
        return errorbar(ax, x, y, yerr=yerr, **kwargs)

    def keep_arrow(ax, *args, marker=None, **kwargs):
        arrows.append((float(args[1][0]), marker))
        return plot(ax, *args, marker=marker, **kwargs)

    monkeypatch.setattr(Axes, "errorbar", keep)
    monkeypatch.setattr(Axes, "plot", keep_arrow)
    rows = [_row("stiff", "stick_slip", seed=k, ssi=v, stuck_fraction=f)
            for k, (v, f) in enumerate([(0.2, 0.1), (0.4, 0.3)])]
    rows += [_row("z-torque", "stick_slip", seed=k) for k in range(2)]
    bar_chart(rows, ["stiff", "z-torque"], ["stick_slip"], tmp_path / "bars.png")
    # (mean, down, up): down cut at the metric's range (an SSI and a stuck share at 0);
    # up at the panel's top, the highest dot and its headroom (0.4 and 30 %)
    ssi_top, stuck_top = (1 + HEADROOM) * 0.4, (1 + HEADROOM) * 30.0
    assert drawn == [pytest.approx((0.3, 0.3, ssi_top - 0.3), abs=1e-4),
                     pytest.approx((20.0, 20.0, stuck_top - 20.0), abs=1e-2)]
    assert arrows == [(pytest.approx(ssi_top), "^"), (pytest.approx(stuck_top), "^")]
    rows = [_row("stiff", "stick_slip", seed=k, ssi=v, stuck_fraction=f)
            for k, (v, f) in enumerate([(0.6, 0.5), (0.62, 0.52)])]
    rows += [_row("z-torque", "stick_slip", seed=k, ssi=1.0, stuck_fraction=0.6)
             for k in range(2)]
    drawn.clear()  # an interval inside the panel is drawn whole: 0.61 +- 12.706 x 0.01
    arrows.clear()
    bar_chart(rows, ["stiff", "z-torque"], ["stick_slip"], tmp_path / "bars.png")
    assert drawn == [pytest.approx((0.61, 0.12706, 0.12706), abs=1e-4),
                     pytest.approx((51.0, 12.706, 12.706), abs=1e-2)]
    assert arrows == []


def test_a_task_benchmarks_bars_add_the_return_below_and_above_zero(tmp_path, monkeypatch):
    """An evaluation is judged by the return, which the bar chart did not show: a tiny
    policy's loss to the best constant (-33 against 82) was not in it (a new user's
    trial). A task's chart has a fifth panel, whose scale reaches below zero."""
    from helpers import keep_saved_figures

    from agents.plots import bar_chart

    rows = [_row("learned", "random", seed=k, episode_return=r)
            for k, r in enumerate([-40.0, -26.0])]
    rows += [_row("constant", "random", seed=k, episode_return=r)
             for k, r in enumerate([80.0, 84.0])]
    saved = keep_saved_figures(monkeypatch)
    bar_chart(rows, ["learned", "constant"], ["random"], tmp_path / "bars.png",
              with_return=True)
    shown = [ax for ax in saved[0].axes if ax.axison]
    assert [ax.get_title() for ax in shown][-1] == "episode return (higher is better)"
    heights = sorted(p.get_height() for p in shown[-1].patches if p.get_width() > 0)
    assert heights == pytest.approx([-33.0, 82.0])
    low, high = shown[-1].get_ylim()
    assert low <= -40.0 and high >= 84.0
    saved.clear()  # a scenario benchmark's chart: four panels, no return
    bar_chart(rows, ["learned", "constant"], ["random"], tmp_path / "bars.png")
    assert len([ax for ax in saved[0].axes if ax.axison]) == 4
    # its key wrapped as the title is (one line of it ran off both sides: a review)
    lines = saved[0]._suptitle.get_text().splitlines()
    assert len(lines) >= 3 and max(map(len, lines)) <= 100


def test_benchmark_md_shows_the_series_picture_of_every_scenario(tmp_path):
    """Each scenario's picture under its own heading, in its own paragraph (not two
    images on consecutive lines, shown as one), and every picture it names is there."""
    import re

    scenarios = ["default", "stick_slip"]
    _series(tmp_path, ["stiff"], scenarios)
    bt.write_outputs([_row("stiff", s) for s in scenarios], tmp_path, ["stiff"], scenarios,
                     SHORT)
    lines = (tmp_path / "benchmark.md").read_text().splitlines()
    for s in scenarios:
        picture = f"benchmark_{s}_series.png"
        at = [k for k, line in enumerate(lines) if f"]({picture})" in line]
        assert len(at) == 1, picture
        assert lines[at[0] - 1] == "" and lines[at[0] - 2].startswith(f"## {s}")
        assert (tmp_path / picture).stat().st_size > 10_000
    for name in re.findall(r"\]\(([^)]+)\)", "\n".join(lines)):
        assert (tmp_path / name).exists(), name


def test_the_rpm_error_of_a_controller_that_sets_its_own_speed_is_marked(tmp_path,
                                                                          capsys):
    """The driller's 58 % is its departure from the planned rpm, not a failure: its cell
    (and a constant set point's, and the drilling task's policy's) carries a mark
    explained under the table, on screen and in benchmark.md; the tracking controllers'
    cells do not, nor the stick-slip policy's (it corrects the drive around the target).
    The csv keeps the plain number."""
    names = ["stiff", "driller", "learned", "constant-120rpm-100kN"]
    rows = [_row("stiff", "stick_slip", rpm_tracking_error=0.02),
            _row("driller", "stick_slip", rpm_tracking_error=0.582, mean_bit_rpm=79.1),
            _row("learned", "stick_slip", rpm_tracking_error=1.87),
            _row("constant-120rpm-100kN", "stick_slip", rpm_tracking_error=1.4)]
    table = bt.summary_table(rows, names, ["stick_slip"])
    error = [h for _, h, _ in bt.SUMMARY].index("rpm error") + 3
    cells = {r[1]: r[error] for r in table}
    assert cells["stiff"] == "2.0%"
    assert cells["driller"] == f"58.2% {bt.OWN_SPEED_MARK}"
    assert cells["learned"] == "187.0%"  # the stick-slip task's policy tracks the target
    assert cells["constant-120rpm-100kN"].endswith(bt.OWN_SPEED_MARK)
    drilling = {r[1]: r[error] for r in bt.summary_table(rows, names, ["stick_slip"],
                                                         "DrillOptimise-v0")}
    assert drilling["learned"] == f"187.0% {bt.OWN_SPEED_MARK}"
    assert drilling["stiff"] == "2.0%"
    bt.write_outputs(rows, tmp_path, names, ["stick_slip"], SHORT)
    text = (tmp_path / "benchmark.md").read_text()
    assert f"| 58.2% {bt.OWN_SPEED_MARK} |" in text and bt.OWN_SPEED_NOTE in text
    printed = " ".join(capsys.readouterr().out.split())  # rich wraps the note
    assert "sets its own speed" in printed and "not a failure to track it" in printed
    with (tmp_path / "benchmark.csv").open() as f:
        body = list(csv.reader(f))
    assert body[0] == SPEC_COLUMNS
    assert body[2][SPEC_COLUMNS.index("rpm_tracking_error")] == "0.582"

    # a learned row's sensors and rate are not the classical drives': said under the table,
    # also where several runs are labelled learned-<run> (labels())
    assert "Sensors: a learned policy reads its env's observation" in text
    assert bs.labels(["learned:/runs/a", "learned:/runs/b"]) == ["learned-a", "learned-b"]
    bt.write_outputs([_row("learned-a", "stick_slip")], tmp_path, ["learned-a"],
                     ["stick_slip"], SHORT)
    assert "Sensors: a learned policy" in (tmp_path / "benchmark.md").read_text()
    bt.write_outputs(rows[:1], tmp_path, ["stiff"], ["stick_slip"], SHORT)
    text = (tmp_path / "benchmark.md").read_text()
    assert bt.OWN_SPEED_MARK not in text and "Sensors:" not in text  # no footnotes


def test_a_drilling_policy_is_marked_as_a_guest_in_a_scenario_benchmark():
    """Whether a controller chose its own rpm is judged in the env it acted in: the drilling
    task's policy does so as a guest in a benchmark of DrillString-v0 scenarios too, the
    stick-slip task's policy and a tracking controller do not."""
    from agents.learned import TRAINED

    names = [f"learned:{TRAINED / 'drilling'}", "learned", "stiff"]
    rows = {}
    for name, table_name in zip(names, bs.labels(names), strict=True):
        episode = bs.Episode(name, "stick_slip", 0, vars(SHORT), "unused", name=table_name)
        rows[table_name] = be.run_episode(episode)
    assert {n: r["own_speed"] for n, r in rows.items()} == {
        "learned-drilling": True, "learned": False, "stiff": False}
    table = bt.summary_table(list(rows.values()), list(rows), ["stick_slip"])
    error = [h for _, h, _ in bt.SUMMARY].index("rpm error") + 3
    marked = {r[1]: r[error].endswith(bt.OWN_SPEED_MARK) for r in table}
    assert marked == {"learned-drilling": True, "learned": False, "stiff": False}


def _policy_trained_with(folder, env_kwargs):
    """The shipped stick-slip policy in ``folder``, as if trained with ``env_kwargs``."""
    import shutil

    import yaml

    from agents.learned import TRAINED

    shutil.copytree(TRAINED / "stick_slip", folder)
    config = yaml.safe_load((folder / "config.yaml").read_text())
    (folder / "config.yaml").write_text(yaml.safe_dump({**config, "env_kwargs": env_kwargs}))
    # (a run trained with these env_kwargs: the shipped record of its settings is not
    # its own, and would be a note of moved settings)
    (folder / "trained_with.json").unlink()
    return f"learned:{folder}"


def test_a_task_benchmark_runs_every_controller_under_the_policys_task_settings(tmp_path):
    """A policy trained with other reward weights and physics (its run's env_kwargs) is
    compared with the classical controllers under those, not under the defaults: with
    every reward weight at zero every return is zero, the stiff controller's too. Policies
    trained under different settings are refused; a guest policy runs under the scenario
    benchmark's physics."""
    zero = {f"{w}_weight": 0.0 for w in ("stick_slip", "stuck", "tracking", "whirl",
                                         "effort", "failure")}
    trained = _policy_trained_with(tmp_path / "run", {
        **zero, "physics": {"mud": {"density": 1250.0}}, "episode_duration": 3.0})
    assert bs.task_settings([trained, "stiff"], "DrillStickSlip-v0") == {
        **zero, "physics": {"mud.density": 1250.0}}  # the benchmark sets the duration
    rows = bm.run_benchmark([trained, "stiff"], ["random"], [0], tmp_path / "out", SHORT,
                            progress=False, env_id="DrillStickSlip-v0")
    assert [r["episode_return"] for r in rows] == [0.0, 0.0]
    written = (tmp_path / "out" / "benchmark.md").read_text()
    assert "under these task settings (the learned policies' training settings" in written
    # and beside the returns (the table's note on screen too): not the task's own reward
    assert "return: DrillStickSlip-v0's reward summed over the episode (docs/tasks.md), " \
        "under the task settings effort_weight 0.0, " in written
    with pytest.raises(ValueError, match="trained on different DrillStickSlip-v0 settings"):
        bm.run_benchmark([trained, "learned", "stiff"], ["random"], [0], tmp_path / "x",
                         SHORT, progress=False, env_id="DrillStickSlip-v0")
    # settings at their defaults are the defaults: such a run shares a table with the
    # shipped policy, and so does the order of its keys
    same = _policy_trained_with(tmp_path / "same", {"physics": None, "stick_slip_weight": 1,
                                                     "telemetry": "mud_pulse",
                                                     "rpm_targets": [40, 100]})
    assert bs.task_settings([same, "learned"], "DrillStickSlip-v0") == {}
    guest = be.run_episode(bs.Episode(trained, "stick_slip", 0, vars(SHORT), "unused"))
    # a guest: scored by DrillString-v0's reward, a finite number like the others'
    assert math.isfinite(guest["episode_return"]) and guest["mean_bit_rpm"] > 0.0


def test_the_tables_show_no_negative_zero(tmp_path, capsys):
    """A mean that rounds to zero from below is shown as 0.0 (or 0%), never -0.0."""
    import re

    rows = [_row("stiff", "stick_slip", mean_bit_rpm=-0.03, episode_return=-0.04,
                 rop_m_per_h=-0.0, stuck_fraction=-0.001, ssi=-0.0),
            _row("stiff", "stick_slip", seed=1, mean_bit_rpm=-0.01, episode_return=-0.02,
                 rop_m_per_h=-0.0, stuck_fraction=-0.002, ssi=-0.0)]
    bt.write_outputs(rows, tmp_path, ["stiff"], ["stick_slip"], SHORT)
    negative_zero = re.compile(r"(?<![\d.])-0(\.0*)?%?(?![\d.])")
    text = (tmp_path / "benchmark.md").read_text()
    # two seeds: the intervals' t(0.975, 1) = 12.7 shows the stuck share's and rpm's spread
    assert "| stick_slip | stiff | 2 (2 not drilling) | 0.00 | 0% +-1% | 0.0 +-0.1 |" in text
    assert not negative_zero.search(text), text
    assert not negative_zero.search(capsys.readouterr().out)
    # a real negative keeps its sign, an infinite one too
    from drill_env.physics.units import shown

    assert shown("{:.1f}", -0.06) == "-0.1"
    assert shown("{:.1f}", -math.inf) == "-inf"
    assert shown("{:7.1f}", -0.03) == "    0.0"  # a padded column keeps its width


def test_a_benchmark_into_a_used_folder_removes_the_old_series_pictures(tmp_path):
    """A second benchmark of other scenarios into the same --out leaves beside its
    benchmark.md only its own series pictures; the results store and other files stay."""
    _series(tmp_path, ["stiff"], ["default", "stick_slip"])
    bt.write_outputs([_row("stiff", s) for s in ("default", "stick_slip")], tmp_path,
                     ["stiff"], ["default", "stick_slip"], SHORT)
    assert (tmp_path / "benchmark_default_series.png").exists()
    for name in (bm.RESULTS_FILE, "my_series.png", "benchmark_notes.txt"):
        (tmp_path / name).write_text("kept")
    bt.write_outputs([_row("stiff", "stick_slip")], tmp_path, ["stiff"], ["stick_slip"],
                     SHORT)
    assert sorted(p.name for p in tmp_path.glob("*.png")) == [
        "benchmark_bars.png", "benchmark_stick_slip_series.png", "my_series.png"]
    for name in (bm.RESULTS_FILE, "my_series.png", "benchmark_notes.txt"):
        assert (tmp_path / name).read_text() == "kept"
    assert "benchmark_default_series" not in (tmp_path / "benchmark.md").read_text()


def test_an_interrupt_while_the_outputs_are_written_leaves_every_linked_picture(
        tmp_path, monkeypatch):
    """The series pictures were removed before the new ones were drawn: a Ctrl-C in
    between left benchmark.md linking pictures that were gone (an outside check). Now
    the old ones stay until the new ones are drawn, and each file is written beside
    itself and moved into place, so an interrupt at any picture leaves every picture
    benchmark.md links whole, and no part files."""
    import re

    from matplotlib.figure import Figure

    scenarios = ["default", "stick_slip"]
    _series(tmp_path, ["stiff"], scenarios)
    rows = [_row("stiff", s) for s in scenarios]
    bt.write_outputs(rows, tmp_path, ["stiff"], scenarios, SHORT)
    sizes = {p.name: p.stat().st_size for p in tmp_path.glob("*.png")}
    drawn = []
    real = Figure.savefig

    def savefig_then_stop(fig, *args, **kwargs):
        drawn.append(1)
        if len(drawn) == 2:  # amid the first series picture: half a file written
            Path(args[0]).write_bytes(b"torn")
            raise KeyboardInterrupt
        return real(fig, *args, **kwargs)

    monkeypatch.setattr(Figure, "savefig", savefig_then_stop)
    with pytest.raises(KeyboardInterrupt):
        bt.write_outputs(rows, tmp_path, ["stiff"], scenarios, SHORT)
    monkeypatch.undo()
    text = (tmp_path / "benchmark.md").read_text()
    for name in re.findall(r"\]\(([^)]+)\)", text):
        assert (tmp_path / name).stat().st_size == sizes[name], name
    assert not [p.name for p in tmp_path.iterdir() if ".partial" in p.name]


def test_a_policy_and_its_five_baselines_each_draw_their_own_line_style(tmp_path,
                                                                       monkeypatch):
    """The evaluation's series: with four dash patterns the policy (first) and ZTorque
    (fifth) were both solid, in brown and red, which read as one colour; each line now
    differs from every other in its dashes."""
    import numpy as np
    from helpers import keep_saved_figures

    from agents.plots import series_chart

    names = ["learned", "stiff", "soft-speed", "soft-torque", "z-torque", "driller"]
    t = np.linspace(0.0, 10.0, 101)
    for k, name in enumerate(names):
        np.savez(tmp_path / f"{name}_random_seed0.npz", time=t, bit_x=0 * t, bit_y=0 * t,
                 clearance=0.02, bit_speed=(5.0 + k) + 0 * t, torque_on_bit=2e3 + 0 * t,
                 surface_torque=3e3 + 0 * t)
    saved = keep_saved_figures(monkeypatch)
    series_chart(tmp_path, names, "random", tmp_path / "series.png", warmup=2.0)
    lines = [line for line in saved[0].axes[0].get_lines() if line.get_label() in names]
    assert sorted(line.get_label() for line in lines) == sorted(names)
    dashes = {str(line._dash_pattern) for line in lines}
    assert len(dashes) == len(names)


def test_a_controller_keeps_its_colour_in_every_picture():
    """Colours follow the controller's name, not its place in --controllers or the names
    beside it: the driller is the same colour in the demo's five-controller benchmark and
    in a pair (docs/controllers.md, "What the pictures show")."""
    from agents.plots import _colours

    five = _colours(["stiff", "soft-speed", "soft-torque", "z-torque", "driller"])
    pair = _colours(["driller", "constant-120rpm-100kN"])
    assert pair["driller"] == five["driller"]
    named = set(map(tuple, five.values())) | {tuple(pair["driller"])}
    assert tuple(pair["constant-120rpm-100kN"]) not in named  # others take a free colour
    # an evaluation of task 2: eleven controllers, eleven colours (the eleventh repeated
    # the seventh's)
    evaluation = ["learned", *five, "held-1", "held+0", "held+1", "random",
                  "constant-160rpm-65kN"]
    assert len({tuple(c) for c in _colours(evaluation).values()}) == 11
    # a check of the pictures: thirteen in task 2's benchmark gave "random" a gold-brown
    # 0.14 from the policy's brown; every colour is now DISTINCT from each other one
    from agents.plots import DISTINCT

    thirteen = [*evaluation, "constant-120rpm-90kN", "constant-200rpm-140kN"]
    rgb = [np.array(c[:3]) for c in _colours(thirteen).values()]
    assert min(np.linalg.norm(a - b) for i, a in enumerate(rgb) for b in rgb[i + 1:]) \
        >= DISTINCT
    # a new user's trial: the trivial policies, a run and a controller of one's own
    # changed colour between an evaluation's picture and a benchmark's (held-1 pink in one,
    # grey in the other): the built-in names keep theirs, and a name of one's own keeps the
    # one it draws wherever it stands among them
    run = "learned-stick_slip_ppo_seed0"
    pictures = [_colours(evaluation), _colours([run, *evaluation]),
                _colours(["stiff", "random", run, "held+1", "held-1"]),
                _colours(["held+0", run])]
    for name in ("held-1", "held+0", "held+1", "random", run):
        assert len({tuple(p[name]) for p in pictures if name in p}) == 1, name
    # and two names of one picture never share a colour, whatever their names draw
    many = [f"mine-{k}" for k in range(23)]  # (OWN_COLOURS' five, tab20b's other eighteen)
    assert len({tuple(c) for c in _colours(many).values()}) == 23


def test_the_bar_charts_legend_wraps_into_rows_inside_the_picture(tmp_path, monkeypatch):
    """A check of the pictures: thirteen controllers in one legend row ran off both sides
    of the bar chart. In rows of at most six, inside the figure."""
    import matplotlib.figure

    from agents.plots import LEGEND_ROW, bar_chart

    legends = []
    real = matplotlib.figure.Figure.legend

    def keep(fig, *args, **kwargs):
        legends.append((fig, real(fig, *args, **kwargs)))
        return legends[-1][1]

    monkeypatch.setattr(matplotlib.figure.Figure, "legend", keep)
    names = [f"constant-{100 + k}rpm-90kN" for k in range(13)]
    rows = [_row(c, "random", ssi=0.1 * k) for k, c in enumerate(names)]
    monkeypatch.setattr("agents.plots.save", lambda fig, path: fig.canvas.draw())
    bar_chart(rows, names, ["random"], tmp_path / "bars.png")
    fig, legend = legends[0]
    assert legend._ncols <= LEGEND_ROW
    box = legend.get_window_extent(fig.canvas.get_renderer())
    width, height = fig.canvas.get_width_height()
    assert 0 <= box.x0 and box.x1 <= width and 0 <= box.y0


def test_a_lines_swing_is_its_oscillation_not_a_change_of_target():
    """The series picture draws a line translucent and low when it swings by more than
    ``SWINGING``: stick-slip does, a steady line with a change of target does not (every
    task-1 line went translucent at its target change)."""
    import numpy as np

    from agents.plots import SWINGING, _swing
    from drill_env.physics.units import RPM

    t = np.arange(0.0, 60.0, 0.02)
    step = np.where(t < 30.0, 91.0, 72.0) * RPM
    stick_slip = (80.0 + 80.0 * np.sin(2 * np.pi * t / 4.0)) * RPM
    assert _swing(t, step, 5.0) < 0.1 * SWINGING
    assert _swing(t, stick_slip, 5.0) > 2 * SWINGING  # 160 rpm from stop to top
    diverged = stick_slip.copy()
    diverged[-300:] = np.nan  # a diverged episode's end
    assert _swing(t, diverged, 5.0) == pytest.approx(_swing(t, stick_slip, 5.0), rel=0.02)
    assert _swing(np.zeros(3), np.ones(3), 0.0) == 0.0  # one time stamp, no crash


OWN_CONTROLLER = '''
from agents import SetPointController


class Gentle(SetPointController):
    """The stiff PI loop with gains of its own."""

    name = "gentle"

    def physics(self):
        return {"top_drive.controller": "stiff", "top_drive.proportional_gain": GAIN,
                "top_drive.integral_gain": 800.0}
'''


def test_a_controller_of_your_own_is_named_by_its_file_and_its_edits_rerun(tmp_path):
    """docs/controllers.md, "Your own controller": ``file.py:Class`` runs in the pool's
    fresh worker processes and in this one, is named by its class's ``name``, and an edit
    of the file reruns its rows (the source digest covers only this project's packages):
    a rerun in this process after the edit gives what fresh processes give, not the rows
    (or the module) of the file as it was."""
    file = tmp_path / "mine.py"
    file.write_text(OWN_CONTROLLER.replace("GAIN", "1500.0"))
    name = f"{file}:Gentle"
    args = ([name, "stiff"], ["stick_slip"], [0])
    first = bm.run_benchmark(*args, tmp_path / "a", SHORT, workers=2, progress=False)
    assert [r["controller"] for r in first] == ["gentle", "stiff"]
    file.write_text(OWN_CONTROLLER.replace("GAIN", "6000.0"))
    edited = bm.run_benchmark(*args, tmp_path / "a", SHORT, workers=1, progress=False)
    fresh = bm.run_benchmark(*args, tmp_path / "b", SHORT, workers=2, progress=False)
    assert edited[1] == first[1]  # stiff: reused
    assert edited[0] != first[0]  # the gains changed what the drive does
    assert edited[0] == fresh[0]


INSTANCE_FILES = ('    def __init__(self):\n        super().__init__()\n'
                  '        self.data_files = ("gain.txt",)')


def test_the_files_a_controller_of_your_own_reads_are_followed_as_its_code_is(
        tmp_path, monkeypatch):
    """From a walkthrough: a policy class that loads a model was served its old rows after
    the model was retrained (only the .py was followed); its ``data_files`` are now."""
    from agents.registry import parse_controllers

    monkeypatch.chdir(tmp_path)
    (tmp_path / "gain.txt").write_text("1500.0")
    (tmp_path / "mine.py").write_text(OWN_CONTROLLER.replace("GAIN", "float(open('gain.txt')"
                                                             ".read())").replace(
        '    name = "gentle"', '    name = "gentle"\n    data_files = ("gain.txt",)'))
    before = bm.controller_digest("mine.py:Gentle")
    assert bm.controller_digest("mine.py:Gentle") == before  # the same bytes
    (tmp_path / "gain.txt").write_text("2000.0")
    assert bm.controller_digest("mine.py:Gentle") not in ("", before)
    for files, said in [('("gone.txt",)', "data_files: 'gone.txt' is not a file"),
                        ('"gain.txt"', "data_files is 'gain.txt', not a tuple of file "
                                       "paths")]:
        (tmp_path / "odd.py").write_text((tmp_path / "mine.py").read_text().replace(
            '("gain.txt",)', files))
        with pytest.raises(ValueError, match=f"^controllers: odd.py:Gentle: {re.escape(said)}"):
            parse_controllers("odd.py:Gentle")
        with pytest.raises(ValueError, match=f"^controller: odd.py:Gentle: {re.escape(said)}"):
            bm.controller_digest("odd.py:Gentle")
    # set on the instance, it would be checked but not followed (the digest reads the class)
    (tmp_path / "odd.py").write_text((tmp_path / "mine.py").read_text().replace(
        '    data_files = ("gain.txt",)', INSTANCE_FILES))
    with pytest.raises(ValueError, match="^controllers: odd.py:Gentle: data_files is set on "
                                         "the instance; set it on the class"):
        parse_controllers("odd.py:Gentle")
    # a factory function's controllers are followed by their class's data_files
    (tmp_path / "made.py").write_text((tmp_path / "mine.py").read_text()
                                      + "\n\ndef make():\n    return Gentle()\n")
    before = bm.controller_digest("made.py:make")
    (tmp_path / "gain.txt").write_text("2500.0")
    assert bm.controller_digest("made.py:make") not in ("", before)


def test_a_gain_read_from_outside_its_file_is_followed_through_physics(tmp_path,
                                                                      monkeypatch):
    """From an outside check: a controller whose gain came from a helper module (here an
    environment variable, as a new process would read either) was served its old rows
    after the gain changed, its file unchanged. What its physics() returns is now in its
    digest; the same value, the same digest."""
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("MY_GAIN", "3000.0")
    (tmp_path / "mine.py").write_text("import os\n" + OWN_CONTROLLER.replace(
        "GAIN", "float(os.environ['MY_GAIN'])"))
    before = bm.controller_digest("mine.py:Gentle")
    assert bm.controller_digest("mine.py:Gentle") == before
    monkeypatch.setenv("MY_GAIN", "20000.0")
    assert bm.controller_digest("mine.py:Gentle") not in ("", before)


def test_set_points_of_your_own_drive_every_scenario_of_a_benchmark(tmp_path):
    """From a walkthrough: ``benchmark`` had no --rpm / --wob as ``run`` has. Given, they
    are every episode's set points, on a fixed and on a randomised scenario (which would
    draw its own), said in benchmark.md; one alone leaves the other the scenario's."""
    from drill_env.physics.units import RPM

    settings = dataclasses.replace(SHORT, surface_speed=60 * RPM, weight_on_bit=120e3)
    rows = bm.run_benchmark(["stiff"], ["default", "random"], [0], tmp_path / "both",
                            settings, progress=False)
    assert [r["target_rpm"] for r in rows] == pytest.approx([60.0, 60.0])
    assert [r["mean_bit_rpm"] for r in rows] == pytest.approx([60.0, 60.0], abs=0.5)
    assert "at the set points 60 rpm and 120 kN in every scenario" in \
        (tmp_path / "both" / "benchmark.md").read_text()
    plain = bm.run_benchmark(["stiff"], ["default"], [0], tmp_path / "plain", SHORT,
                             progress=False)
    heavier = bm.run_benchmark(["stiff"], ["default"], [0], tmp_path / "wob",
                               dataclasses.replace(SHORT, weight_on_bit=120e3),
                               progress=False)
    assert heavier[0]["target_rpm"] == plain[0]["target_rpm"] == pytest.approx(100.0)
    assert heavier[0]["rop_m_per_h"] > plain[0]["rop_m_per_h"]  # 120 kN drills faster
    assert "at the set points 120 kN in every scenario (the other set point each " \
        "scenario's)" in (tmp_path / "wob" / "benchmark.md").read_text()
    with pytest.raises(ValueError, match="^weight_on_bit: 160 kN lies outside "
                                         "DrillOptimise-v0's range 40-140 kN, where "
                                         "learned:agents/trained/drilling acts"):
        bm.run_benchmark(["stiff", "learned:agents/trained/drilling"], ["default"], [0],
                         tmp_path / "guest", dataclasses.replace(SHORT, weight_on_bit=160e3),
                         progress=False)
    assert not (tmp_path / "guest").exists()  # refused before any episode
    with pytest.raises(ValueError, match="^surface_speed: a task benchmark drills at the "
                                         "targets its task draws"):
        bm.run_benchmark(["stiff"], ["random"], [0], tmp_path / "task",
                         dataclasses.replace(SHORT, surface_speed=6.0), progress=False,
                         env_id="DrillStickSlip-v0")
    with pytest.raises(ValueError, match="^weight_on_bit: 120 N is below 1 kN"):
        dataclasses.replace(SHORT, weight_on_bit=120.0)
    with pytest.raises(ValueError, match="^surface_speed: 60 rad/s is 573 rpm, outside "
                                         "DrillString-v0's range 0-200 rpm"):
        dataclasses.replace(SHORT, surface_speed=60.0)  # rpm typed for rad/s
    # a WOB that buckles a scenario's pipe at the start runs, with run's note
    from drill_cli.benchmark import buckling_notes

    notes = buckling_notes(["default", "paper_case1"], 200e3, {})
    assert len(notes) == 1 and notes[0].startswith("note: --wob 200 kN compresses the 5 in "
                                                   "HWDP of default by")
    assert buckling_notes(["default"], 100e3, {}) == []


def test_scenarios_that_set_points_make_one_episode_run_once(tmp_path, capsys):
    """From a walkthrough: the README's ``benchmark --rpm 60 --wob 120`` ran default and
    stick_slip (default at 50 rpm) as two names of one episode, bit-identical rows, twice
    the time, nothing said. Now the later name is dropped with a note; a WOB alone
    leaves their speeds apart."""
    from drill_cli.benchmark import same_episodes
    from drill_env.physics.units import RPM

    names = ["default", "stick_slip", "paper_case1", "random"]
    assert same_episodes(names, {"surface_speed": 60 * RPM}) == {"stick_slip": "default"}
    assert same_episodes(names, {"weight_on_bit": 80e3}) == {}
    # a name given twice is not its own twin (it would be dropped altogether)
    assert same_episodes(["default", "default"], {"surface_speed": 60 * RPM}) == {}
    # a WOB that buckles the pipe at the start: the benchmark runs it with a note, so the
    # check must not build the scenario's own (refused) start (it did: an error)
    assert same_episodes(names, {"surface_speed": 60 * RPM, "weight_on_bit": 200e3}) \
        == {"stick_slip": "default"}
    assert same_episodes(["stick_slip", "default"], {"surface_speed": 60 * RPM,
                                                     "weight_on_bit": 80e3}) \
        == {"default": "stick_slip"}
    assert main(["benchmark", "--controllers", "stiff", "--seeds", "1", "--duration", "12",
                 "--warmup", "4", "--rpm", "60", "--out", str(tmp_path)]) == 0
    assert "note: at --rpm 60, stick_slip is the same episode as default (they differ " \
        "only in set points): run once, as default" in capsys.readouterr().err
    with (tmp_path / "benchmark.csv").open() as f:
        assert [r["scenario"] for r in csv.DictReader(f)] == ["default"]


def test_env_kwargs_of_a_scenario_benchmark_are_refused_not_ignored(tmp_path):
    """From a walkthrough: ``BenchmarkSettings(env_kwargs=...)`` without a task changed
    nothing (a scenario benchmark runs each controller in its own env)."""
    from drill_env.physics.validation import ConfigError

    settings = dataclasses.replace(SHORT, env_kwargs={"surface_speed": 9.42})
    with pytest.raises(ConfigError, match=r"^env_kwargs: \['surface_speed'\] would change "
                                          "nothing in a scenario benchmark"):
        bm.run_benchmark(["stiff"], ["default"], [0], tmp_path, settings, progress=False)
    assert not (tmp_path / bm.RESULTS_FILE).exists()


def test_a_controller_of_your_own_that_is_not_one_is_refused_by_name(tmp_path, monkeypatch):
    from agents.registry import make_controller, parse_controllers

    (tmp_path / "odd.py").write_text("class Half:\n    name = 'half'\n    rate = 'drive'\n")
    (tmp_path / "mine.py").write_text(OWN_CONTROLLER.replace("GAIN", "1500.0"))
    monkeypatch.chdir(tmp_path)
    for typed, said in [("odd.py:Half", "odd.py:Half is not a controller: it has no "
                                        "env_id, physics, reset, act"),
                        ("mine.py:Nope", "mine.py has no 'Nope'; its controller classes: "
                                         "Gentle"),
                        ("odd.py:Nope", "odd.py has no 'Nope'; it defines no controller "
                                        "class"),
                        ("gone.py:Gentle", "no file 'gone.py'"),
                        ("gone_module:Gentle", "cannot import 'gone_module'")]:
        with pytest.raises(ValueError, match=f"^controllers: {re.escape(said)}"):
            parse_controllers(f"stiff,{typed}")
    # a module in the working folder imports as with python -m
    assert make_controller("mine:Gentle").physics()["top_drive.proportional_gain"] == 1500.0
    # a package's module there too (package.module:ClassName, agents.registry's docstring)
    (tmp_path / "ours").mkdir()
    (tmp_path / "ours" / "__init__.py").write_text("")
    (tmp_path / "ours" / "tuned.py").write_text(OWN_CONTROLLER.replace("GAIN", "1700.0"))
    assert make_controller("ours.tuned:Gentle").physics()[
        "top_drive.proportional_gain"] == 1700.0
    # the controller classes the file defines, not the SetPointController it imports
    with pytest.raises(ValueError, match=r"its controller classes: Gentle$"):
        parse_controllers("mine.py:Nope")
    assert bs.labels(["mine:Gentle", "stiff"]) == ["gentle", "stiff"]
    with pytest.raises(ValueError, match="share the name 'gentle'"):
        bs.labels(["mine:Gentle", "mine.py:Gentle"])
    # one put in the registry by hand is followed by its file too; ours by the fingerprint
    from agents.registry import CONTROLLERS, imported_factory

    monkeypatch.setitem(CONTROLLERS, "gentle", imported_factory("mine.py:Gentle"))
    before = bm.controller_digest("gentle")
    assert before and bm.controller_digest("stiff") == ""
    (tmp_path / "mine.py").write_text(OWN_CONTROLLER.replace("GAIN", "2000.0"))
    assert bm.controller_digest("gentle") not in ("", before)
    for module in ("mine", "ours.tuned", "ours"):  # imported from this test's folder
        sys.modules.pop(module, None)


BROKEN = {  # file -> (code, what the one-line error says)
    "syntax.py": ("from agents import SetPointController\nclass Bad(SetPointController)\n"
                  "    name = 'bad'\n", "SyntaxError: expected ':' (syntax.py, line 2)"),
    "missing.py": ("import not_installed_anywhere\n",
                   "ModuleNotFoundError: No module named 'not_installed_anywhere' "
                   "(missing.py, line 1)"),
    "raises.py": ("raise RuntimeError('no licence server')\n",
                  "RuntimeError: no licence server (raises.py, line 1)"),
    "needs.py": ("from agents import SetPointController\n\n\n"
                 "class Bad(SetPointController):\n    name = 'needs'\n\n"
                 "    def __init__(self, gain):\n        super().__init__()\n",
                 "cannot be made with no arguments: TypeError: missing a required "
                 "argument: 'gain'"),
    # an error inside it is its own, not "no arguments" (a new user's trial: a model of
    # another algorithm read so)
    "init.py": ("from agents import SetPointController\n\n\n"
                "class Bad(SetPointController):\n    name = 'init'\n\n"
                "    def __init__(self):\n        raise OSError('no model here')\n",
                "init.py:Bad failed as it was made: OSError: no model here (init.py, line 8)"),
    "number.py": ("Bad = 3\n", "number.py:Bad is int 3, not a controller class"),
    "nophysics.py": ("from agents import SetPointController\n\n\n"
                     "class Bad(SetPointController):\n    name = 'nophysics'\n\n"
                     "    def physics(self):\n        pass\n",
                     "physics() returned NoneType, not a dict"),
    # a misspelt key of its own top drive read as the user's --config
    "gain.py": ("from agents import SetPointController\n\n\n"
                "class Bad(SetPointController):\n    name = 'gain'\n\n"
                "    def physics(self):\n"
                "        return {'top_drive.proportional_gian': 3000.0}\n",
                "Bad: physics() returned top_drive.proportional_gian: unknown field of "
                "TopDriveConfig (did you mean proportional_gain?)"),
    "typo.py": ("from agents import SetPointController\n\n\n"
                "class Bad(SetPointController):\n    name = 'typo'\n"
                "    env_id = 'DrillStrin-v0'\n",
                "env_id 'DrillStrin-v0' is not a registered env; the drill-env ones: "
                "DrillString-v0"),
    # another registered env (a pool's traceback from CartPole's constructor, or an
    # env_class the user never typed: a fuzzing walkthrough)
    "cartpole.py": ("from agents import SetPointController\n\n\n"
                    "class Bad(SetPointController):\n    name = 'cartpole'\n"
                    "    env_id = 'CartPole-v1'\n",
                    "env_id 'CartPole-v1' is not a drill-env env; the drill-env ones: "
                    "DrillString-v0"),
    "slash.py": ("from agents import SetPointController\n\n\n"
                 "class Bad(SetPointController):\n    name = 'my/ctl'\n",
                 "name 'my/ctl' cannot name its rows and files"),
    "stiff.py": ("from agents import SetPointController\n\n\n"
                 "class Bad(SetPointController):\n    name = 'stiff'\n",
                 "name 'stiff' is a built-in controller's"),
    # a built-in's name in other case: its series and recordings would be the built-in's
    # files on a case-blind file system (macOS, Windows; a portability review)
    "upper.py": ("from agents import SetPointController\n\n\n"
                 "class Bad(SetPointController):\n    name = 'Stiff'\n",
                 "name 'Stiff' is a built-in controller's"),
    # the deepest line of the user's code: a helper of the file, not its caller
    "deep.py": ("from agents import SetPointController\n\n\ndef helper():\n"
                "    raise RuntimeError('no gain table')\n\n\n"
                "class Bad(SetPointController):\n    name = 'deep'\n\n"
                "    def __init__(self):\n        super().__init__()\n        helper()\n",
                "RuntimeError: no gain table (deep.py, line 5)"),
    # a trained run's table name (learned-<folder>, agents.registry.canonical)
    "trained.py": ("from agents import SetPointController\n\n\n"
                   "class Bad(SetPointController):\n    name = 'learned-mine'\n",
                   "name 'learned-mine' is a built-in controller's"),
    "held.py": ("from agents import SetPointController\n\n\n"
                "class Bad(SetPointController):\n    name = 'HELD+1'\n",
                "name 'HELD+1' is a built-in controller's"),
    # a sys.exit in the user's code (a script's last line without a __main__ guard ended
    # the command at the import with exit 0, nothing said)
    "script.py": ("import sys\nfrom agents import SetPointController\n\n\n"
                  "class Bad(SetPointController):\n    name = 'script'\n\n\n"
                  "sys.exit(0)\n",
                  "script.py: SystemExit: 0 (script.py, line 9)"),
    "quits.py": ("import sys\nfrom agents import SetPointController\n\n\n"
                 "class Bad(SetPointController):\n    name = 'quits'\n\n"
                 "    def __init__(self):\n        sys.exit('no gains')\n",
                 "Bad failed as it was made: SystemExit: no gains (quits.py, line 9)"),
    "quitphysics.py": ("import sys\nfrom agents import SetPointController\n\n\n"
                       "class Bad(SetPointController):\n    name = 'quitphysics'\n\n"
                       "    def physics(self):\n        sys.exit(4)\n",
                       "Bad: physics() raised SystemExit: 4 (quitphysics.py, line 9)"),
}


def test_labels_that_differ_only_in_case_are_refused(tmp_path, monkeypatch):
    """Two controllers of one's own, Gentle and gentle, wrote the same series and
    recording files on macOS and Windows, each over the other's."""
    (tmp_path / "mine.py").write_text(
        "from agents import SetPointController\n\n\n"
        "class Gentle(SetPointController):\n    pass\n\n\n"
        "class gentle(SetPointController):\n    pass\n")
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ValueError, match=r"would share the name 'Gentle' in the table "
                                         r"\(names that differ only in case"):
        bs.labels(["mine.py:Gentle", "mine.py:gentle"])


@pytest.mark.parametrize("file", sorted(BROKEN))
def test_a_broken_controller_file_is_one_line_naming_it_and_exit_2(tmp_path, capsys, file):
    code, said = BROKEN[file]
    (tmp_path / file).write_text(code)
    typed = f"{tmp_path / file}:Bad"
    with pytest.raises(SystemExit) as stopped:  # a bad argument: usage, then one line
        main(["benchmark", "--controllers", f"stiff,{typed}", "--out", str(tmp_path / "o")])
    assert stopped.value.code == 2
    err = capsys.readouterr().err
    last = err.strip().splitlines()[-1]
    assert "Traceback" not in err and last.startswith("drill-env benchmark: error: "
                                                      "--controllers: "), err
    assert said in last and file in last


@pytest.mark.parametrize("body, said", [
    ("        raise KeyError('gain')\n", "act() raised KeyError: 'gain' (acts.py, line 10)"),
    # (it exited the command with status 3 and said nothing: a fuzzing walkthrough)
    ("        raise SystemExit(3)\n", "act() raised SystemExit: 3 (acts.py, line 10)"),
    ("        return np.linalg.inv(np.zeros((2, 2)))\n",  # raised inside numpy: your line
     "act() raised LinAlgError: Singular matrix (acts.py, line 10)"),
    ("        return np.zeros(1)\n", "act() returned an action of shape (1,); the env "
                                     "takes (2,)"),
    ("        return None\n", "act() returned None; the env takes an action of shape (2,)"),
    ("        return np.array([np.nan, 0.0])\n", "act() returned [nan, 0.0], not finite "
                                               "numbers"),
    ("        return np.array(['1', '2'])\n", "act() returned an action: expected numbers, "
                                            "got array(['1', '2']")])
def test_a_controller_of_your_own_that_acts_wrongly_is_named_in_one_line(tmp_path, capsys,
                                                                          body, said):
    """In a pool's worker too: its error comes back as one line naming the controller,
    its file's line and the episode, not the pool's traceback."""
    file = tmp_path / "acts.py"
    file.write_text("import numpy as np\nfrom agents import SetPointController\n\n\n"
                    "class Bad(SetPointController):\n    name = 'acts'\n    rate = 'policy'"
                    "\n\n    def act(self, observation, info):\n" + body)
    assert main(["benchmark", "--controllers", f"stiff,{file}:Bad", "--scenarios",
                 "stick_slip", "--seeds", "1", "--duration", "4", "--warmup", "2",
                 "--workers", "2", "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    last = err.strip().splitlines()[-1]  # after the progress bar
    assert "Traceback" not in err and last.startswith(
        "drill-env benchmark: error: --controllers: "), err
    assert said in last and f"{file}:Bad" in last and "(scenario stick_slip, seed 0)" in last


def test_run_says_an_act_error_of_your_own_in_one_line_too(tmp_path, capsys):
    file = tmp_path / "acts.py"
    file.write_text("from agents import SetPointController\n\n\n"
                    "class Bad(SetPointController):\n    name = 'acts'\n    rate = 'policy'"
                    "\n\n    def act(self, observation, info):\n        return 1 / 0\n")
    assert main(["run", "--controller", f"{file}:Bad", "--scenario", "stick_slip",
                 "--duration", "2", "--seed", "3", "--out", str(tmp_path / "out")]) == 2
    last = capsys.readouterr().err.strip().splitlines()[-1]
    assert last == (f"drill-env run: error: --controller: {file}:Bad: act() raised "
                    "ZeroDivisionError: division by zero (acts.py, line 9) (scenario "
                    "stick_slip, seed 3)")


def test_a_reset_of_your_own_that_raises_is_named_in_one_line_in_run_and_benchmark(
        tmp_path, capsys):
    """``reset`` as ``act``: a raising reset gave a traceback through the benchmark's
    episode and exit 1 (a new user's trial), where every other hook gave one line, exit 2."""
    file = tmp_path / "resets.py"
    file.write_text("from agents import SetPointController\n\n\n"
                    "class Bad(SetPointController):\n    name = 'resets'\n    rate = 'policy'"
                    "\n\n    def reset(self, env):\n        raise KeyError('boom')\n")
    said = (f"--controller{{}}: {file}:Bad: reset() raised KeyError: 'boom' (resets.py, "
            "line 9) (scenario stick_slip, seed {})")
    assert main(["run", "--controller", f"{file}:Bad", "--scenario", "stick_slip",
                 "--duration", "2", "--seed", "3", "--out", str(tmp_path / "out")]) == 2
    assert capsys.readouterr().err.strip().splitlines()[-1] == \
        "drill-env run: error: " + said.format("", 3)
    assert main(["benchmark", "--controllers", f"stiff,{file}:Bad", "--scenarios",
                 "stick_slip", "--seeds", "1", "--duration", "2", "--warmup", "1",
                 "--workers", "1", "--out", str(tmp_path / "bench")]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and err.strip().splitlines()[-1] == \
        "drill-env benchmark: error: " + said.format("s", 0)


def test_an_action_of_your_own_outside_the_space_is_clipped_and_said_once(tmp_path):
    """The env clips an action outside [-1, 1]; a controller of your own returning 5.0 ran
    at the top speed without a word, its table saying "rpm error 193 %" (a new user's
    trial). It is said once, at the first such action; one inside the space says nothing."""
    file = tmp_path / "far.py"
    for name, action in (("Near", "[1.0, -1.0]"), ("Far", "[5.0, 0.0]")):
        file.write_text("import numpy as np\nfrom agents import SetPointController\n\n\n"
                        f"class {name}(SetPointController):\n    name = 'far'\n    rate = "
                        "'policy'\n\n    def act(self, observation, info):\n"
                        f"        return np.array({action})\n")
        be.CLIPPED.clear()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            assert main(["run", "--controller", f"{file}:{name}", "--scenario", "stick_slip",
                         "--duration", "2", "--seed", "3", "--out", str(tmp_path / "out")]) == 0
        warned = [str(w.message) for w in caught if "clips" in str(w.message)]
        assert warned == ([] if name == "Near" else [
            f"controller: {file}:Far: act() returned [5.0, 0.0], outside the action space "
            "[-1, 1]: the env clips it (scenario stick_slip, seed 3; said at the first)"])


def test_a_controller_file_imports_the_helper_module_beside_it(tmp_path):
    """As ``python file.py`` does: the file's folder is on the import path."""
    from agents.registry import make_controller

    (tmp_path / "gains_of_mine.py").write_text("GAIN = 1234.0\n")
    (tmp_path / "tuned.py").write_text(
        OWN_CONTROLLER.replace("GAIN,", "gains_of_mine.GAIN,").replace(
            "from agents import", "import gains_of_mine\nfrom agents import"))
    controller = make_controller(f"{tmp_path / 'tuned.py'}:Gentle")
    assert controller.physics()["top_drive.proportional_gain"] == 1234.0
    sys.modules.pop("gains_of_mine", None)


def test_two_classes_of_the_same_name_are_told_to_rename_a_class(tmp_path):
    for stem in ("one", "two"):
        (tmp_path / f"{stem}.py").write_text(OWN_CONTROLLER.replace("GAIN", "1500.0"))
    with pytest.raises(ValueError, match="share the name 'gentle' in the table; set another "
                                         "name attribute"):
        bs.labels([f"{tmp_path / 'one.py'}:Gentle", f"{tmp_path / 'two.py'}:Gentle"])


def test_a_policy_of_your_own_that_chooses_its_rpm_is_marked_as_the_driller(tmp_path):
    """``sets_own_speed = True`` on a policy-rate controller of your own: its rpm error is
    its choice, marked as the driller's (docs/controllers.md, "Your own controller")."""
    file = tmp_path / "faster.py"
    file.write_text(
        "from agents import SetPointController\n\n\n"
        "class Faster(SetPointController):\n"
        "    name = 'faster'\n    rate = 'policy'\n    sets_own_speed = True\n\n"
        "    def act(self, observation, info):\n"
        "        speed, wob = self._env.targets\n"
        "        return self._env.action_for(1.2 * speed, wob)\n")
    rows = bm.run_benchmark([f"{file}:Faster", "stiff"], ["stick_slip"], [0],
                            tmp_path / "out", SHORT, workers=1, progress=False)
    assert [r["own_speed"] for r in rows] == [True, False]
    assert rows[0]["mean_bit_rpm"] > 1.1 * rows[0]["target_rpm"]  # it did choose
    table = (tmp_path / "out" / "benchmark.md").read_text()
    marked = [line for line in table.splitlines() if "faster" in line and "†" in line]
    assert marked and not any("stiff" in line and "†" in line for line in table.splitlines())


@pytest.mark.parametrize("recipe", ["sb3_policy(", "class MyPolicy"])
def test_the_docs_recipe_for_a_policy_trained_elsewhere_scores_as_the_shipped_one(tmp_path,
                                                                                  recipe):
    """docs/controllers.md's ways to benchmark a Stable-Baselines3 model trained
    elsewhere (agents.learned.sb3_policy, and a class by hand), with the shipped task-2
    policy's files, act as ``learned`` does: the same rows."""
    text = (Path(__file__).resolve().parents[1] / "docs" / "controllers.md").read_text()
    code = next(block for block in text.split("```python\n")[1:]
                if recipe in block).split("```")[0]
    assert "agents/trained/drilling" in code
    file = tmp_path / "mine.py"
    file.write_text(code.replace("agents/trained/drilling", str(TRAINED / "drilling")))
    settings = bs.BenchmarkSettings(duration=20.0, warmup=10.0)
    rows = bm.run_benchmark([f"{file}:MyPolicy", "learned"], ["random"], [1000000],
                            tmp_path / "out", settings, workers=1, progress=False,
                            env_id="DrillOptimise-v0")
    assert [r["controller"] for r in rows] == ["my-sac", "learned"]
    mine, shipped = ({k: v for k, v in r.items() if k != "controller"} for r in rows)
    assert mine == shipped and mine["own_speed"] is True


def test_sb3_policy_checks_its_files_and_acts_with_or_without_statistics(tmp_path,
                                                                          monkeypatch):
    """agents.learned.sb3_policy: files, algorithm and env id checked when the class is
    made; a wrong statistics file named; without statistics the observation goes in raw;
    a PPO model acts too (the algorithm was first guessed from the zip's policy class,
    which PPO and A2C share: every PPO was refused); the benchmark's stored rows follow
    the model's bytes (the class was made in agents.learned, so nothing was hashed)."""
    import pickle
    import shutil

    import gymnasium as gym
    from stable_baselines3 import PPO

    from agents.learned import sb3_policy

    model, stats = TRAINED / "drilling" / "model.zip", TRAINED / "drilling" / "vecnormalize.pkl"
    policy = sb3_policy(model, stats, algo="sac", env_id="DrillOptimise-v0", name="mine")
    assert (policy.name, policy.data_files, policy.sets_own_speed) == (
        "mine", (str(model), str(stats)), True)
    assert policy.env_id == "DrillOptimise-v0"  # on the class, as the interface has it
    with pytest.raises(ValueError, match=r"\(sb3_policy's env_id names DrillOptimise-v0\); "
                                         r"DrillStickSlip-v0 has observation \(67,\)"):
        policy().reset(gym.make("DrillStickSlip-v0").unwrapped)  # (no config.yaml said)
    assert not sb3_policy(model, algo="SAC", env_id="DrillStickSlip-v0").sets_own_speed
    for kwargs, said in (({"model": tmp_path / "none.zip"}, "^model: no file"),
                         ({"statistics": tmp_path / "none.pkl"}, "^statistics: no file"),
                         ({"env_id": "DrillOptimize-v0"},
                          "^env_id: Environment `DrillOptimize` doesn.t exist"),
                         ({"algo": "sack"}, "^algo: 'sack' is not an algorithm of "
                                            "Stable-Baselines3 or sb3-contrib; known: .*'sac'")):
        with pytest.raises(ValueError, match=said):
            sb3_policy(**{"model": model, "algo": "sac", "env_id": "DrillOptimise-v0",
                          **kwargs})
    wrong = tmp_path / "wrong.pkl"
    wrong.write_bytes(pickle.dumps({"mean": 0.0}))
    with pytest.raises(ValueError, match=r"^statistics: .*wrong\.pkl holds dict, not "
                                         "VecNormalize statistics"):
        sb3_policy(model, wrong, algo="sac", env_id="DrillOptimise-v0")()
    # the two files swapped, or the model given twice, read as "damaged; delete it" (a
    # new user's trial): the model named as what it is
    with pytest.raises(ValueError, match=r"^statistics: .*model\.zip is a zip file \(a saved "
                                         r"model\?\), not the VecNormalize statistics"):
        sb3_policy(stats, model, algo="sac", env_id="DrillOptimise-v0")
    env = gym.make("DrillStickSlip-v0")
    PPO("MlpPolicy", env, n_steps=64, batch_size=64, device="cpu").save(tmp_path / "ppo.zip")
    # a model of another algorithm: said as such, not SB3's AttributeError alone
    with pytest.raises(ValueError, match=r"^model: .*ppo\.zip does not load as SAC \(.*\): "
                                         r"the model of another algorithm \(algo=\)"):
        sb3_policy(tmp_path / "ppo.zip", algo="sac", env_id="DrillStickSlip-v0")()
    for mine in (sb3_policy(tmp_path / "ppo.zip", algo="ppo", env_id="DrillStickSlip-v0")(),
                 sb3_policy(model, algo="sac", env_id="DrillOptimise-v0")()):
        env = gym.make(mine.env_id)
        obs, info = env.reset(seed=0)
        mine.reset(env.unwrapped)
        action = mine.act(obs, info)
        assert action.shape == env.action_space.shape and np.all(np.isfinite(action))
        env.close()
    # a benchmark of mine.py:Mine follows the model file's bytes
    monkeypatch.chdir(tmp_path)
    (tmp_path / "mine.py").write_text(
        "from agents.learned import sb3_policy\n"
        "Mine = sb3_policy('ppo.zip', algo='ppo', env_id='DrillStickSlip-v0', name='mine')\n")
    before = bm.controller_digest("mine.py:Mine")
    shutil.copy(model, tmp_path / "ppo.zip")  # another model under the same name
    assert before and bm.controller_digest("mine.py:Mine") != before


def test_plot_swing_ignores_the_warmup():
    # _swing docstring: how widely speed swings after ``warmup``
    from agents.plots import _swing

    t = np.arange(0.0, 20.0, 0.1)
    speed = np.where(t < 15.0, 10.0 * np.sin(3.0 * t), 5.0)
    assert _swing(t, speed, warmup=15.0) == 0.0


def test_plot_swing_is_the_median_block_range_not_a_one_off_step():
    # _swing docstring: a change of target moves one block only (median over 5 s blocks)
    from agents.plots import _swing

    t = np.arange(0.0, 25.0, 0.1)
    speed = np.where(t < 12.0, 5.0, 8.0)  # one step, inside the third 5 s block
    assert _swing(t, speed, warmup=0.0) == 0.0


EQUAL_TERMS = '''
from agents import SetPointController


class Mild(SetPointController):
    name = "my-lp"

    def physics(self):
        return {"top_drive.controller": "stiff", "top_drive.proportional_gain": 1500.0}


class Strong(Mild):
    def physics(self):
        return {"top_drive.controller": "stiff", "top_drive.proportional_gain": 9000.0}


class RockSwap(SetPointController):
    name = "rock-swap"

    def physics(self):
        return {"top_drive.controller": "stiff", "formation.rocks[0].mu_max": 0.5}


class NoStickSlipCost(SetPointController):
    name = "no-cost"

    def physics(self):
        return {"top_drive.controller": "stiff"}

    def env_kwargs(self):
        return {"stick_slip_weight": 0.0, "config": {"rop_weight": 5.0}}


class Huge(SetPointController):
    name = "huge"

    def physics(self):
        return {"top_drive.controller": "stiff", "top_drive.proportional_gain": 1e9,
                "top_drive.integral_gain": 1e9}


class HardTop(NoStickSlipCost):
    name = "hard-top"

    def physics(self):
        return {"top_drive": {"controller": "stiff", "inertia": 50.0,
                              "max_torque": 5.0e5}}


class OwnMakeUp(NoStickSlipCost):
    name = "own-makeup"

    def env_kwargs(self):
        return {"makeup_torque": 3000.0}


class OwnMakeUpConfig(NoStickSlipCost):
    name = "own-makeup-config"

    def env_kwargs(self):
        from drill_env.env_config import EnvConfig

        return {"config": EnvConfig(makeup_torque=3000.0, sensors="surface")}
'''


def test_a_controller_of_your_own_is_compared_on_equal_terms(tmp_path, monkeypatch):
    """From a controls engineer's walkthrough: a controller's physics() softened the rock
    and was listed as curing stick-slip at twice the ROP; its env_kwargs() zeroed the
    stick-slip weight and led the return column with the stiff PI's stick-slip, or set its
    own make-up torque; one gave itself a 50 kg m^2 rotor and a 500 kN m rating; and a
    second class of the same name in the same file was served the first's rows. Now
    physics() sets the top drive's loop only, a controller's reward
    weights are the benchmark's and its episode settings are refused, and the rows of two
    classes are told apart."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "mine.py").write_text(EQUAL_TERMS)
    with pytest.raises(ValueError, match=r"controller: .*RockSwap.*physics\(\) sets "
                                         r"formation\.rocks\[0\]\.mu_max: a controller sets "
                                         r"its top drive only"):
        bm.run_benchmark(["mine.py:RockSwap"], ["stick_slip"], [0], tmp_path / "r", SHORT,
                         workers=1, progress=False)
    with pytest.raises(ValueError, match=r"controller: .*HardTop.*physics\(\) sets "
                                         r"top_drive\.inertia, top_drive\.max_torque: the "
                                         r"top drive's hardware"):  # its own 50 kg m^2 rotor
        bm.run_benchmark(["mine.py:HardTop"], ["stick_slip"], [0], tmp_path / "t", SHORT,
                         workers=1, progress=False)
    from agents.registry import TOP_DRIVE_LOOP
    from drill_env.physics.config import TopDriveConfig

    fields = {f.name for f in dataclasses.fields(TopDriveConfig)}
    assert fields - TOP_DRIVE_LOOP == {"inertia", "max_torque", "max_acceleration"}
    assert TOP_DRIVE_LOOP <= fields  # a field renamed would not become hardware unseen
    with pytest.raises(ValueError, match=r"controller: own-makeup\.env_kwargs\(\) sets "
                                         r"makeup_torque: in a scenario benchmark"):
        bm.run_benchmark(["mine.py:OwnMakeUp"], ["stick_slip"], [0], tmp_path / "m", SHORT,
                         workers=1, progress=False)
    with pytest.raises(ValueError, match=r"own-makeup-config\.env_kwargs\(\) sets makeup_torque"):
        bm.run_benchmark(["mine.py:OwnMakeUpConfig"], ["stick_slip"], [0], tmp_path / "c",
                         SHORT, workers=1, progress=False)  # in an EnvConfig too
    with pytest.raises(ValueError, match=r"proportional_gain.*\(the episode of huge on "
                                         r"stick_slip\)"):  # whose gains, said
        bm.run_benchmark(["mine.py:Huge"], ["stick_slip"], [0], tmp_path / "h", SHORT,
                         workers=1, progress=False)
    rows = bm.run_benchmark(["stiff", "mine.py:NoStickSlipCost"], ["stick_slip"], [0],
                            tmp_path / "w", SHORT, workers=1, progress=False)
    assert rows[0]["ssi"] == rows[1]["ssi"]  # the same drive, the same episode
    assert rows[1]["episode_return"] == rows[0]["episode_return"]  # scored alike
    mild = bm.run_benchmark(["mine.py:Mild"], ["stick_slip"], [0], tmp_path / "d", SHORT,
                            workers=1, progress=False)
    strong = bm.run_benchmark(["mine.py:Strong"], ["stick_slip"], [0], tmp_path / "d",
                              SHORT, workers=1, progress=False)
    alone = bm.run_benchmark(["mine.py:Strong"], ["stick_slip"], [0], tmp_path / "s",
                             SHORT, workers=1, progress=False)
    assert strong == alone != mild


def test_an_episode_a_failure_ends_in_the_warm_up_is_a_row_and_is_said(tmp_path, capfd):
    """From a controls engineer's walkthrough: a controller whose episode tripped the
    make-up torque in the warm-up stopped the whole benchmark with a traceback, and one
    that tripped it later was scored as if fine, said only on benchmark.md's last line.
    Now the first is a row with the whole episode's metrics, and both are marked in the
    table on screen and in benchmark.md."""
    settings = dataclasses.replace(SHORT, warmup=4.0, env_kwargs={"makeup_torque": 500.0})
    out = tmp_path / "out"
    rows = bm.run_benchmark(["stiff", "soft-speed"], ["random"], [0], out, settings,
                            workers=1, progress=False, env_id="DrillStickSlip-v0")
    assert all("in the warm-up: metrics over the whole episode" in r["termination"]
               for r in rows)
    printed = capfd.readouterr().out
    assert "Episodes that ended early (metrics until then): stiff/random/0" in " ".join(
        printed.split())
    # (a bit that stalled at once is not drilling either: "1 ended early, 1 not drilling")
    assert "| 1 (1 ended early" in (out / "benchmark.md").read_text()


def test_an_episode_that_stops_before_a_second_sample_is_said_in_one_line(
        tmp_path, capsys, monkeypatch):
    """An episode whose simulation diverged in its first step (an outside check: a rock
    curve steeper than the step carries, since refused) left no samples to measure and
    ended the benchmark with twenty lines of a process pool's traceback. It is said in
    one line naming the episode and the reason, exit status 2."""
    from drill_env.env import DrillStringEnv

    step = DrillStringEnv.step

    def diverging(self, action):
        obs, reward, _, truncated, info = step(self, action)
        self.last_records = self.last_records[:1]
        return obs, reward, True, truncated, {**info, "termination_reason":
                                              "simulation diverged (a test's)"}

    monkeypatch.setattr(DrillStringEnv, "step", diverging)
    assert main(["benchmark", "--controllers", "stiff", "--scenarios", "default", "--seeds",
                 "1", "--duration", "5", "--warmup", "0", "--workers", "1",
                 "--out", str(tmp_path / "out")]) == 2
    err = [line for line in capsys.readouterr().err.splitlines()
           if line.strip() and not line.startswith("benchmark:")  # (the progress bar's)
           and "numba compiles" not in line]  # (a first run's: a test alone, cache cold)
    assert len(err) == 1 and err[0].startswith("drill-env benchmark: error: ")
    err = err[0]
    assert ("the episode of stiff on default, seed 0, ended before a second sample, with "
            "nothing to measure (simulation diverged (a test's))") in err


def test_the_table_fits_the_terminal_without_cutting_a_figure(monkeypatch, capsys) -> None:
    """On a terminal narrower than the table (100 columns against ~150) the columns go to
    stacked tables, each with the scenario and controller, every figure whole on one line:
    the terminal wrapped every row of one wide table (a review). In a pipe or a log, one
    table as wide as its cells."""
    header = ["scenario", "controller", *(f"metric {k}" for k in range(12))]
    table = [["stick_slip", name, *(f"{k}.{k}5 +-0.0{k}" for k in range(12))]
             for name in ("soft-speed", "z-torque")]
    note = "a note " * 30
    monkeypatch.setenv("FORCE_COLOR", "1")  # rich: a terminal
    monkeypatch.setenv("COLUMNS", "100")
    bt.print_table(header, table, [note])
    out = re.sub(r"\x1b\[[0-9;]*m", "", capsys.readouterr().out)
    assert max(map(len, out.splitlines())) <= 100
    assert out.count("┃ controller") >= 2  # several tables, each naming the rows
    for row in table:
        for cell in row:
            assert re.search(rf"│ {re.escape(cell)}\s+│", out), cell
    monkeypatch.delenv("FORCE_COLOR")
    monkeypatch.setattr("sys.stdout.isatty", lambda: False, raising=False)
    bt.print_table(header, table, [note])
    out = capsys.readouterr().out
    assert out.count("┃ controller") == 1 and max(map(len, out.splitlines())) > 100


def test_a_title_wraps_into_even_lines_not_a_lone_last_word() -> None:
    """From a walkthrough: an evaluation's series title wrapped at 110 characters left
    "fast" alone on its second line."""
    from agents.plots import balanced_fill

    title = ("Evaluation of stick_slip (logs/runs/stick_slip_sac_seed0/best_model.zip, sac "
             "on task stick_slip), held-out seeds 1000000-1000019, physics level fast")
    lines = balanced_fill(title, 110).split("\n")
    assert len(lines) == 2 and " ".join(lines) == title
    assert min(map(len, lines)) > 0.8 * max(map(len, lines))  # even, not 110 + 4
    assert balanced_fill("short", 110) == "short"


def test_a_stick_slip_still_growing_in_the_metric_window_is_marked(tmp_path, monkeypatch):
    """A controls engineer's check: SoftSpeed on a 2,000 kg m^2 top drive read SSI 0.00
    and 0 % stuck over the window (30-60 s) while its bit-speed swing grew x4 per 30 s, to
    full stick-slip by ~200 s (drill-env run --duration 240), beside the torque-feedback
    loops that do cure it. Its row is marked growing, in the table and benchmark.md."""
    settings = bs.BenchmarkSettings(physics={"top_drive.inertia": 2000.0})
    texts = _drawn_texts(monkeypatch)
    rows = bm.run_benchmark(["soft-speed", "soft-torque", "stiff", "constant:50/100"],
                            ["stick_slip"], [0], tmp_path, settings, workers=1,
                            progress=False)
    trend = {r["controller"]: r["swing_trend"] for r in rows}
    # a constant set point is judged as the stiff PI that holds it (it was not: a
    # policy-rate controller, an outside review)
    assert trend["stiff"] == trend["constant-50rpm-100kN"] == "full stick-slip (the bit stops)"
    assert trend["soft-speed"].startswith("growing (x")
    assert rows[0]["ssi"] < 0.01  # what the window shows without the mark
    assert trend["soft-torque"] == ""  # its swing under the floor: not judged
    markdown = (tmp_path / "benchmark.md").read_text()
    assert "| stick_slip | soft-speed | 1 (1 growing) |" in markdown
    assert "| stick_slip | soft-torque | 1 |" in markdown
    assert "soft-speed/stick_slip/0 (x" in markdown
    assert texts.count("growing") == 1  # on its SSI bar
    # a layer crossed raises the swing of a loop that holds (an outside review: ZTorque
    # on paper_case2 was marked x2.5 at SSI 0.02)
    rows = bm.run_benchmark(["z-torque"], ["paper_case2"], [0], tmp_path / "crossing",
                            bs.BenchmarkSettings(), workers=1, progress=False)
    assert rows[0]["swing_trend"] == bt.ROCK_CHANGED  # and said: no mark is not "holds"
    said = " ".join((tmp_path / "crossing" / "benchmark.md").read_text().split())
    assert ("the rock under the bit changed (a layer crossed raises the swing by itself): "
            "z-torque on paper_case2 (1 episode)") in said
    # nor where a policy moves its set points (the driller of the demo's benchmark)
    rows = bm.run_benchmark(["driller"], ["stick_slip"], [0], tmp_path / "driller",
                            bs.BenchmarkSettings(), workers=1, progress=False)
    assert rows[0]["swing_trend"] == "not judged: a set point moved"
    assert "a set point moved (a policy's action or a target): driller on stick_slip" in \
        " ".join((tmp_path / "driller" / "benchmark.md").read_text().split())
    # a loop that holds, whose swing humps to 0.028 rpm at 60-90 s and decays (SoftSpeed
    # k = 5 on a 1,500 kg m^2 drive): under the floor, not marked
    hump = bs.BenchmarkSettings(duration=90.0, warmup=60.0, physics={
        "top_drive.inertia": 1500.0, "top_drive.impedance_factor": 5.0})
    rows = bm.run_benchmark(["soft-speed"], ["stick_slip"], [0], tmp_path / "hump", hump,
                            workers=1, progress=False)
    assert not bt.growing(rows[0])


def test_the_window_swing_trend_compares_equal_blocks_where_set_points_and_rock_held():
    """The swing of the window's last block against the block before the window, blocks
    the shorter of warm-up and window; none where a set point moved (a driller's change
    would read as swing) or the bit met another rock (a layer crossed raised
    paper_case2's ZTorque swing x2.5, an outside review), nor under the floor (0.0099 ->
    0.0101 rpm read as growing)."""
    from drill_env.physics.layout import RECORD_CHANNELS, R
    from drill_env.physics.units import RPM

    t = np.arange(0.0, 60.0, 0.01)
    records = np.zeros((len(t), len(RECORD_CHANNELS)))
    records[:, R.TIME] = t
    amplitude = 0.5 * 2.0 ** (t / 20.0)  # x2 per 20 s: x4 from 10-20 s to 50-60 s
    records[:, R.BIT_SPEED] = (50.0 + amplitude * np.sin(2.0 * np.pi * 0.44 * t)) * RPM
    settings = bs.BenchmarkSettings(duration=60.0, warmup=20.0)

    def held(speed=lambda x: 5.0, share=lambda x: 1.0):
        return [(float(x), (speed(x), 1.0e5, share(x), 1.0 - share(x))) for x in t[::10]]

    trend = be.window_swing_trend(records, held(), 0.0, settings)
    factor = re.fullmatch(r"growing \(x(\S+) per 40 s\)", trend)
    assert factor and float(factor[1]) == pytest.approx(4.0, rel=0.05), trend
    moved = held(speed=lambda x: 5.0 if x < 15.0 else 6.0)
    assert be.window_swing_trend(records, moved, 0.0, settings) == \
        "not judged: a set point moved"
    crossed = held(share=lambda x: 1.0 if x < 30.0 else 0.7)  # a layer under the bit
    assert be.window_swing_trend(records, crossed, 0.0, settings) == bt.ROCK_CHANGED
    jitter = held(share=lambda x: 1.0 - 0.5 * be.SAME_ROCK * (x % 2.0))  # the same rock
    assert be.window_swing_trend(records, jitter, 0.0, settings).startswith("growing")
    late = bs.BenchmarkSettings(duration=60.0, warmup=40.0)  # blocks 20-40 s and 40-60 s
    early = held(speed=lambda x: 5.0 if x < 15.0 else 6.0)  # before the blocks: judged
    trend = be.window_swing_trend(records, early, 0.0, late)
    factor = re.fullmatch(r"growing \(x(\S+) per 20 s\)", trend)
    assert factor and float(factor[1]) == pytest.approx(2.0, rel=0.05), trend
    records[:, R.BIT_SPEED] = (50.0 + 0.5 * 0.5 ** (t / 20.0) * np.sin(t)) * RPM
    assert be.window_swing_trend(records, held(), 0.0, settings).startswith("decaying")
    small = be.GROWING_FLOOR * 0.9 * 2.0 ** ((t - 60.0) / 20.0)  # growing, under the floor
    records[:, R.BIT_SPEED] = (50.0 + small * np.sin(2.0 * np.pi * 0.44 * t)) * RPM
    assert be.window_swing_trend(records, held(), 0.0, settings) == ""


def test_the_series_picture_shows_the_drives_surface_torque(tmp_path, monkeypatch):
    """A controls engineer's check: the series showed the bit alone, not the surface
    torque through which a drive-rate loop acts (stiff PI's 1.3-7.8 kN m swing, the tuned
    loops' flat line). A panel of its own, in kN m."""
    from helpers import keep_saved_figures

    from agents.plots import series_chart

    _series(tmp_path, ["stiff"], ["default"])
    saved = keep_saved_figures(monkeypatch)
    assert series_chart(tmp_path / "series", ["stiff"], "default", tmp_path / "s.png", 2.0)
    panel = next(ax for ax in saved[0].axes if ax.get_ylabel() == "surface torque (kN m)")
    assert list(panel.get_lines()[0].get_ydata()) == pytest.approx([4.3] * 101)


def test_a_drift_the_same_under_every_controller_is_said_not_to_be_theirs(tmp_path,
                                                                           monkeypatch):
    """A controls engineer's check: the demo's radial panel ends mid-rise under every
    controller (the compressed BHA settling, seeded by round-off) and read as a lateral
    instability of theirs. Said where every line ends the same and still rising; not for
    one controller, lines that differ, or a bit resting where it is."""
    from agents.plots import series_chart

    t = np.linspace(0.0, 60.0, 601)

    def write(name, radial):
        (tmp_path / "series").mkdir(exist_ok=True)
        np.savez(tmp_path / "series" / f"{name}_default_seed0.npz", time=t, clearance=0.02,
                 bit_x=0.02 * radial, bit_y=0 * t, bit_speed=5.2 + 0 * t,
                 torque_on_bit=3.5e3 + 0 * t, surface_torque=4.3e3 + 0 * t)

    texts = _drawn_texts(monkeypatch)
    rising = 0.16 * np.exp((t - 60.0) / 2.0)
    cases = {"same, rising": (rising, rising * 1.02, True),
             "alike, the default's ends": (rising, rising * 1.37, True),
             "differ": (rising, rising * 1.6, False),
             "resting": (0.32 + 0 * t, 0.32 + 0 * t, False)}
    for name, (a, b, said) in cases.items():
        write("stiff", a)
        write("z-torque", b)
        texts.clear()
        assert series_chart(tmp_path / "series", ["stiff", "z-torque"], "default",
                            tmp_path / "s.png", 30.0)
        assert any("not of their making" in x for x in texts) == said, name
    texts.clear()
    series_chart(tmp_path / "series", ["stiff"], "default", tmp_path / "s.png", 30.0)
    assert not any("not of their making" in x for x in texts)


def test_a_bit_that_drills_nothing_is_marked_not_drilling(tmp_path):
    """A metrics audit: a bit held at 0 rpm and 200 kN read SSI 0.00 and MSE 5 MPa (the
    thrust term alone), the best of its table beside a stiff PI drilling at 146 MPa. Its
    row is marked: the stuck share and ROP say what happened."""
    settings = bs.BenchmarkSettings(duration=20.0, warmup=10.0, fidelity="fast")
    rows = bm.run_benchmark(["held:-1/1", "stiff"], ["stick_slip"], [0], tmp_path,
                            settings, workers=1, progress=False)
    held, stiff = rows
    assert held["stuck_fraction"] == 1.0 and held["rop_m_per_h"] == 0.0
    assert held["ssi"] < stiff["ssi"] and held["mse_MPa"] < stiff["mse_MPa"]  # unmarked: best
    assert [bt.not_drilling(r) for r in rows] == [True, False]
    markdown = " ".join((tmp_path / "benchmark.md").read_text().split())
    assert f"| stick_slip | {held['controller']} | 1 (1 not drilling) |" in markdown
    assert "| stick_slip | stiff | 1 (1 growing) |" in markdown  # 50 rpm stick-slips
    assert "Not drilling: the bit drilled nothing in the metric window" in markdown
    assert f"{held['controller']}/stick_slip/0." in markdown


def test_not_drilling_is_the_metrics_floor_read_in_the_rows_metres_per_hour():
    """The row's ROP is in m/h (3,600 s to the hour); the floor under which the window
    metrics take the MSE's thrust term alone is in m/s. A row is marked exactly where the
    metrics took that branch: half the floor is not drilling, twice it is (a floor read
    per minute would call ~60x the floor's crawl drilling)."""
    from drill_env.metrics import MSE_MIN_ROP

    for factor, marked in ((0.0, True), (0.5, True), (0.98, True), (1.02, False),
                           (2.0, False), (100.0, False)):
        row = {"rop_m_per_h": factor * MSE_MIN_ROP * 3600.0}
        assert bt.not_drilling(row) == marked, factor


def test_a_warm_up_past_the_last_whole_control_step_says_where_the_episode_ends(
        tmp_path, capsys):
    """A metrics audit: 20 s at the fast level are 202 control steps of 0.0988 s, 19.97 s;
    a 19.98 s warm-up passed the settings' check and the episode then said it "ended before
    a second sample (no samples)", as if it had failed. It says where it ends and why."""
    from drill_cli.main import main

    assert main(["benchmark", "--controllers", "stiff", "--scenarios", "stick_slip",
                 "--seeds", "1", "--duration", "20", "--warmup", "19.98", "--fidelity",
                 "fast", "--workers", "1", "--out", str(tmp_path)]) == 2
    import re

    err = " ".join(capsys.readouterr().err.split())
    said = re.search(r"ended before a second sample, with nothing to measure \(the "
                     r"warm-up, 19.98 s, leaves no two samples in it: it ends at ([\d.]+) s, "
                     r"(\d+) control steps of ([\d.]+) s\)", err)
    assert said, err
    ends, steps, interval = float(said[1]), int(said[2]), float(said[3])
    assert ends < 19.98 and ends == pytest.approx(steps * interval, rel=1e-3)


def test_a_note_that_lists_episodes_shows_the_first_and_last_few(tmp_path, capsys):
    """A scale trial: a 200-seed benchmark listed 199 episodes in one note (9 KB on screen
    and in benchmark.md). A list longer than twelve shows six at each end and how many
    more there are, and where they all are."""
    from drill_env.physics.units import FEW, few

    assert few(list("abc"), "x") == "a, b, c"
    many = [str(k) for k in range(30)]
    assert few(many, "in the CSV") == "0, 1, 2, 3, 4, 5, ... 18 more in the CSV ..., " \
        "24, 25, 26, 27, 28, 29"
    assert few(many[:FEW + 2], "x") == ", ".join(many[:FEW + 2])  # hiding 2 saves nothing
    assert "... 3 more x ..." in few(many[:FEW + 3], "x")
    rows = [_row("stiff", "stick_slip", seed=k, rop_m_per_h=0.0) for k in range(30)]
    bt.write_outputs(rows, tmp_path, ["stiff"], ["stick_slip"], SHORT)
    said = " ".join((tmp_path / "benchmark.md").read_text().split())
    assert ("stiff/stick_slip/5, ... 18 more with ROP 0 in benchmark.csv ..., "
            "stiff/stick_slip/24") in said
    assert "stiff/stick_slip/12" not in said


def test_benchmark_paired_gives_any_controller_evaluates_t_tests(tmp_path, capsys):
    """A policy trained outside drill-env train (here held:1 stands in) gets evaluate's
    paired comparison from a benchmark (an outside trial with rl-zoo3: only a run folder
    had it): --paired names one of --controllers as typed; its lead over each other on the
    same episodes, in comparison.md and on screen; a name not among them is refused."""
    from drill_cli.main import main

    args = ["benchmark", "--controllers", "held:1,stiff,held:0", "--scenarios",
            "default,stick_slip", "--seeds", "2", "--duration", "3", "--warmup", "1",
            "--workers", "1", "--out", str(tmp_path)]
    assert main([*args, "--paired", "held:1"]) == 0
    out = capsys.readouterr().out
    text = (tmp_path / "comparison.md").read_text()
    assert text.startswith("# Controller benchmark, paired against held+1\n")
    rows = list(csv.DictReader((tmp_path / "benchmark.csv").open()))
    for other in ("stiff", "held+0"):  # 4 episodes: 2 scenarios x 2 seeds
        lead = sum(float(a["episode_return"]) - float(b["episode_return"])
                   for a in rows if a["controller"] == "held+1"
                   for b in rows if b["controller"] == other
                   and (a["scenario"], a["seed"]) == (b["scenario"], b["seed"])) / 4
        assert f"| {other} | " in text and f"| {lead:+.1f} | " in text
        assert " of 4 | " in text
    assert "Paired by episode (scenario and seed): held+1 (mean return" in out
    assert "over the 2 comparisons" in text and "held+1's return minus theirs" in text
    with pytest.raises(SystemExit):
        main([*args, "--paired", "learned"])
    assert "--paired: 'learned' is not one of --controllers (held:1, stiff, held:0)" in \
        capsys.readouterr().err
    # its table name is taken too (a new user typed the name the table showed): the same
    # comparison, from the finished episodes
    (tmp_path / "comparison.md").unlink()
    assert main([*args, "--paired", "held+1"]) == 0
    assert (tmp_path / "comparison.md").read_text() == text


def test_among_many_controllers_the_first_and_the_target_stay_in_sight(tmp_path,
                                                                         monkeypatch):
    """An evaluation draws eleven controllers; four of them in stick-slip made one solid
    band over the policy's line and the target (a new user's check). The first (the
    policy) is drawn on top and wider, the target just under it, and the bands of
    stick-slip, three or more, let more of what lies behind them show through."""
    import numpy as np
    from matplotlib.figure import Figure

    from agents.plots import series_chart

    names = ["learned", "stiff", "driller", "random", "held-1", "z-torque"]
    (tmp_path / "series").mkdir()
    t = np.linspace(0.0, 30.0, 301)
    for k, name in enumerate(names):
        swing = 4.0 * (0 < k < 5) * np.sin(2.0 * np.pi * t / 3.0 + k)  # four stick-slip
        np.savez(tmp_path / "series" / f"{name}_random_seed0.npz", time=t, clearance=0.02,
                 bit_x=0.006 + 0 * t, bit_y=0 * t, bit_speed=8.0 + swing,
                 torque_on_bit=3.5e3 + 0 * t, surface_torque=4.3e3 + 0 * t,
                 target_time=np.array([0.0]), target_rpm=np.array([80.0]))
    drawn: dict[str, tuple[float, float, float | None]] = {}
    save = Figure.savefig

    def keep(fig, *args, **kwargs):
        for line in fig.axes[0].get_lines():
            drawn[line.get_label()] = (line.get_zorder(), line.get_linewidth(),
                                       line.get_alpha())
        return save(fig, *args, **kwargs)

    monkeypatch.setattr(Figure, "savefig", keep)
    assert series_chart(tmp_path / "series", names, "random", tmp_path / "s.png", 5.0)
    top = max(z for z, _, _ in drawn.values())
    assert drawn["learned"][:2] == (top, 1.4)
    assert max(z for name, (z, _, _) in drawn.items() if name != "learned") \
        == drawn["target"][0]
    assert {drawn[n][2] for n in ("stiff", "driller", "random", "held-1")} == {0.3}
    assert drawn["z-torque"][2] is None and drawn["z-torque"][1] == 0.8


def test_the_series_chart_draws_each_channel_in_its_unit_and_one_target_line(tmp_path,
                                                                              monkeypatch):
    """Each panel is the channel its axis names, in the unit it says, against time: bit
    speed (rpm), surface torque and torque on bit (kN m), radial position over the
    clearance; the planned rpm is drawn once (the first controller's), not per line."""
    from helpers import keep_saved_figures

    from agents.plots import series_chart
    from drill_env.physics.units import RPM

    t = np.linspace(0.0, 10.0, 101)
    channels = {"time": t, "clearance": 0.02, "bit_x": 0.004 + 0.001 * np.sin(t),
                "bit_y": 0.003 * np.cos(t), "bit_speed": (80.0 + 10.0 * np.sin(t)) * RPM,
                "surface_torque": 6e3 + 500.0 * np.cos(t), "torque_on_bit": 2e3 + 0.1 * t,
                "target_time": np.array([0.0, 5.0]), "target_rpm": np.array([80.0, 90.0])}
    _series(tmp_path, ["stiff", "z-torque", "driller"], ["random"], **channels)
    saved = keep_saved_figures(monkeypatch)
    assert series_chart(tmp_path / "series", ["stiff", "z-torque", "driller"], "random",
                        tmp_path / "series.png", warmup=2.0)
    axes = saved[0].axes
    want = (channels["bit_speed"] / RPM, channels["surface_torque"] / 1e3,
            channels["torque_on_bit"] / 1e3,
            np.hypot(channels["bit_x"], channels["bit_y"]) / 0.02)
    for ax, values in zip(axes[:4], want, strict=True):
        (line,) = [line for line in ax.get_lines() if line.get_label() == "stiff"]
        np.testing.assert_allclose(line.get_xdata(), t)
        np.testing.assert_allclose(line.get_ydata(), values, rtol=1e-12)
    assert [line.get_label() for line in axes[0].get_lines()].count("target") == 1


def test_the_bars_stand_on_their_scenario_in_the_panels_unit(tmp_path, monkeypatch):
    """Each scenario's bars are centred on its tick, one per controller side by side; the
    panels in % (time stuck, in backward whirl) show the mean share x 100."""
    from helpers import keep_saved_figures

    from agents.plots import bar_chart

    names, scenarios = ["stiff", "z-torque", "driller"], ["default", "stick_slip"]
    rows = [_row(c, s, seed=k, stuck_fraction=0.1 * (i + 1) + 0.02 * k + 0.3 * j, ssi=0.5,
                 backward_whirl_fraction=0.05 * (i + 1))
            for i, c in enumerate(names) for j, s in enumerate(scenarios) for k in range(2)]
    saved = keep_saved_figures(monkeypatch)
    bar_chart(rows, names, scenarios, tmp_path / "bars.png")
    stuck, whirl = saved[0].axes[1], saved[0].axes[3]
    bars = [p for p in stuck.patches if p.get_width() > 0]
    assert len(bars) == len(names) * len(scenarios)
    centres = np.array([p.get_x() + 0.5 * p.get_width() for p in bars])
    for j in range(len(scenarios)):
        group = centres[np.abs(centres - j) < 0.5]
        assert len(group) == len(names) and np.mean(group) == pytest.approx(j, abs=1e-9)
    # each tick says it is a scenario: "random" alone under the bars read as the random
    # policy's (a new user's trial)
    assert [t.get_text() for t in stuck.get_xticklabels()] == [
        "default scenario", "stick_slip scenario"]
    for c in names:
        for s in scenarios:
            mean = 100.0 * np.mean([r["stuck_fraction"] for r in rows
                                    if r["controller"] == c and r["scenario"] == s])
            assert any(p.get_height() == pytest.approx(mean, rel=1e-12) for p in bars)
    heights = sorted({round(p.get_height(), 9) for p in whirl.patches if p.get_width() > 0})
    assert heights == pytest.approx([5.0, 10.0, 15.0])
    for ax in saved[0].axes[:4]:  # each panel's scale reaches its tallest bar, from 0
        low, high = ax.get_ylim()
        assert low == 0.0 and high >= max(p.get_height() for p in ax.patches)


def test_a_policy_saved_anew_during_a_benchmark_does_not_join_its_table(tmp_path,
                                                                         monkeypatch):
    """`evaluate RUN` beside a training of RUN loaded the run's files afresh for every
    episode: once the training saved a new best, the episodes left ran that model, all
    in one table under the first model's name (a fuzzing walkthrough: 11 of 20 rows).
    The files are pinned when the benchmark starts: every row is the first model's, as a
    benchmark of an untouched copy gives them, and the pins are gone afterwards."""
    import shutil

    from stable_baselines3 import SAC

    run, untouched = tmp_path / "run", tmp_path / "untouched"
    for folder in (run, untouched):
        shutil.copytree(TRAINED / "stick_slip", folder)
    other = SAC.load(run / "model.zip", device="cpu")  # a model that acts otherwise
    with torch_no_grad():
        for p in other.actor.parameters():
            p.mul_(-1.0)
    other.save(tmp_path / "other.zip")
    real, calls = bm.run_episode, []

    def then_saved_anew(episode):  # a training saving its new best after the first
        row = real(episode)
        calls.append(episode.seed)
        if len(calls) == 1:
            shutil.copyfile(tmp_path / "other.zip", run / "model.zip")
        return row

    monkeypatch.setattr(bm, "run_episode", then_saved_anew)
    short = dataclasses.replace(SHORT, start_kick=0.02)
    rows = bm.run_benchmark([f"learned:{run}"], ["random"], [0, 1, 2], tmp_path / "out",
                            short, workers=1, progress=False, env_id="DrillStickSlip-v0")
    monkeypatch.setattr(bm, "run_episode", real)
    assert len(calls) == 3 and not (tmp_path / "out" / bm.PINNED).exists()
    own = tmp_path / "ref" / bm.PINNED / "notes" / "mine.txt"  # a folder of one's own of
    own.parent.mkdir(parents=True)  # that name: left as it is (a review)
    own.write_text("mine")
    reference = bm.run_benchmark([f"learned:{untouched}"], ["random"], [0, 1, 2],
                                 tmp_path / "ref", short, workers=1, progress=False,
                                 env_id="DrillStickSlip-v0")
    assert [r["episode_return"] for r in rows] == [r["episode_return"] for r in reference]
    assert own.read_text() == "mine" and [p.name for p in own.parents[1].iterdir()] == [
        "notes"]
    moved = bm.run_benchmark([f"learned:{run}"], ["random"], [1], tmp_path / "moved",
                             short, workers=1, progress=False, env_id="DrillStickSlip-v0")
    # (the new model does act otherwise)
    assert moved[0]["episode_return"] != rows[1]["episode_return"]
    # a pinned copy, at its path in the run, is named as the run's own file
    from agents.learned import PINNED, run_file

    copy = tmp_path / "out" / PINNED / "0a1b2c" / "checkpoints" / "model_8_steps.zip"
    assert run_file(copy, run) == run / "checkpoints" / "model_8_steps.zip"
    assert run_file(run / "model.zip", run) == run / "model.zip"


@contextlib.contextmanager
def torch_no_grad():
    import torch

    with torch.no_grad():
        yield


def test_a_best_model_is_pinned_once_its_record_names_it(tmp_path, monkeypatch):
    """Training saves a new best as its model, then its statistics, then its record: two
    reads of the files that agreed between the first two saves pinned the new model beside
    the old statistics (a review). The pin waits until the record names the model read,
    at most SAVE_WAIT_S (a record a kill left unmatched: then it goes on)."""
    import hashlib
    import shutil

    run = tmp_path / "run"
    shutil.copytree(TRAINED / "stick_slip", run)
    (run / "model.zip").rename(run / "best_model.zip")
    (run / "vecnormalize.pkl").rename(run / "best_vecnormalize.pkl")
    record = run / "best_model.json"
    record.write_text(json.dumps({"row": {}, "model": "0" * 64}))  # the last best's
    naps: list[float] = []

    def saved_meanwhile(seconds):  # the save in progress ends: its record is written
        naps.append(seconds)
        digest = hashlib.sha256((run / "best_model.zip").read_bytes()).hexdigest()
        record.write_text(json.dumps({"row": {}, "model": digest}))

    monkeypatch.setattr("time.sleep", saved_meanwhile)
    files, data = bm.policy_bytes(f"learned:{run}")
    assert len(naps) == 1 and files[0] == run / "best_model.zip"
    assert data[1] == (run / "best_vecnormalize.pkl").read_bytes()
    record.write_text(json.dumps({"row": {}, "model": "0" * 64}))  # never matched
    naps.clear()
    monkeypatch.setattr("time.sleep", naps.append)
    bm.policy_bytes(f"learned:{run}")
    assert sum(naps) == pytest.approx(bm.SAVE_WAIT_S)
    record.unlink()  # a run of a version before the record: read at once
    naps.clear()
    bm.policy_bytes(f"learned:{run}")
    assert naps == []


def test_an_env_id_registered_for_a_factory_function_is_taken():
    """is_drill_env refused an id registered for a function that makes a drill-env env (a
    review): only a class tells what it makes; CartPole's class is not one."""
    import gymnasium

    from agents.registry import is_drill_env
    from drill_env.env import DrillStringEnv

    def make(**kwargs):
        return DrillStringEnv(**kwargs)

    gymnasium.register(id="DrillFactoryTest-v0", entry_point=make)
    try:
        assert is_drill_env("DrillFactoryTest-v0") and is_drill_env("DrillStickSlip-v0")
        assert not is_drill_env("CartPole-v1") and not is_drill_env("NoSuchEnv-v0")
    finally:
        del gymnasium.registry["DrillFactoryTest-v0"]
