"""The command line: arguments checked in the units typed, summaries, recordings, maps."""

import argparse
import json
import os
import re
from pathlib import Path

import pytest
from helpers import ctrl_c_as_in_a_terminal

from drill_cli.main import main


def test_run_says_a_recording_it_could_not_write_and_its_results_before_its_files(
        tmp_path, capsys, monkeypatch):
    """A fuzzing walkthrough: on a full disk `run --record` exited 0 with 'recording:
    None (drill-env replay <file>)'; a history file it could not write lost the episode's
    results behind a bare errno."""
    from drill_env.recording import RecordEpisode

    monkeypatch.setattr(RecordEpisode, "last_path", property(lambda self: None))
    assert main(["run", "--duration", "0.3", "--record", "--out", str(tmp_path)]) == 2
    said = capsys.readouterr()
    assert "--record: the recording was not written" in said.err
    assert "recording: None" not in said.out and "SSI" in said.out
    assert (tmp_path / "run_summary.json").exists()
    monkeypatch.undo()
    (tmp_path / "blocked").mkdir()
    (tmp_path / "blocked" / "run_history.jsonl").mkdir()  # cannot be appended to
    assert main(["run", "--duration", "0.3", "--out", str(tmp_path / "blocked")]) == 2
    said = capsys.readouterr()
    assert "SSI" in said.out and "run_history.jsonl" in said.err  # the results said first


def test_record_says_a_large_recording_and_refuses_one_the_disk_cannot_hold(
        tmp_path, capsys, monkeypatch):
    """`run --duration 36000 --record` wrote 1.1 GB unannounced; on a disk without room
    the recording failed when the disk filled, hours in. The estimate is
    docs/recording.md's measured rate (60 s of the default scenario: 2.44 MB)."""
    import shutil
    from collections import namedtuple

    from drill_cli.arguments import recording_note

    assert recording_note(tmp_path, 60.0) == ""
    note = recording_note(tmp_path / "new" / "folder", 36000.0)  # (made later)
    assert note.startswith("note: --record: about 1.1 GB (1 file, ~1.9 MB per simulated "
                           "minute"), note
    assert "about 2.3 GB (20 files" in recording_note(tmp_path, 3600.0, files=20)
    usage = namedtuple("usage", "total used free")
    monkeypatch.setattr(shutil, "disk_usage", lambda path: usage(10**9, 10**9 - 50e6, 50e6))
    with pytest.raises(SystemExit):
        main(["run", "--duration", "1800", "--record", "--out", str(tmp_path / "run")])
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert err.startswith(f"drill-env run: error: --record {tmp_path / 'run' / 'recordings'}: "
                          "the recordings would take about 58 MB (1 file"), err
    assert "has 50 MB free; record a shorter --duration" in err
    assert not (tmp_path / "run").exists()  # refused before anything was written
    with pytest.raises(SystemExit):  # the benchmark counts every episode it records
        main(["benchmark", "--controllers", "stiff,soft-speed", "--scenarios",
              "stick_slip", "--seeds", "2", "--duration", "400", "--record", "--out",
              str(tmp_path / "bench")])
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert "--record " in err and "would take about 53 MB (4 files" in err, err


def test_run_writes_a_summary_and_a_recording(tmp_path, capsys):
    code = main(["run", "--scenario", "paper_case1", "--rpm", "60", "--wob", "80",
                 "--duration", "0.5", "--record", str(tmp_path / "rec"), "--out",
                 str(tmp_path)])
    assert code == 0
    summary = json.loads((tmp_path / "run_summary.json").read_text())
    assert summary["steps"] == 5 and summary["termination_reason"] == ""
    assert summary["rpm"] == 60.0 and summary["weight_on_bit_kN"] == 80.0
    assert summary["simulated_s"] == pytest.approx(0.5)
    assert summary["mean_rop"] > 0.0
    numbers = {k for k, v in summary.items() if isinstance(v, float) and k != "seed"}
    assert numbers <= set(summary["units"]), numbers - set(summary["units"])
    assert summary["units"]["mean_rop"] == "m/s"
    # what a driller reads first (a drilling engineer's walkthrough): the rig's load is
    # the string's buoyed weight less the WOB, in a vertical hole
    from drill_env.physics.simulator import Simulator
    from drill_env.scenarios import make_scenario

    hanging = Simulator(make_scenario("paper_case1").config).string_weight / 1e3
    assert summary["mean_hook_load_kN"] == pytest.approx(hanging - 80.0, rel=1e-3)
    assert summary["mean_weight_on_bit_kN"] == pytest.approx(80.0, rel=1e-3)
    assert summary["units"]["mean_surface_torque_kNm"] == "kN m"
    assert summary["mean_surface_torque_kNm"] > 0.0
    recordings = list((tmp_path / "rec").glob("stiff_paper_case1_seed0_*.rrd"))
    assert [str(p) for p in recordings] == [summary["recording"]]
    # the size --record announces for long runs (arguments.recording_note), its part per
    # file against a real file: the rate per minute is docs/recording.md's measurement
    from drill_cli.arguments import RECORDING_MB_PER_FILE, RECORDING_MB_PER_MINUTE

    estimate = RECORDING_MB_PER_FILE + RECORDING_MB_PER_MINUTE * 0.5 / 60
    assert recordings[0].stat().st_size / 1e6 == pytest.approx(estimate, rel=0.3)
    assert "SSI" in capsys.readouterr().out
    # what set the episode besides scenario and set points (a history told runs of the
    # field-well config and of the default string apart only by their length)
    assert (summary["config"], summary["start_kick"], summary["duration_given_s"]) == (
        None, 0.02, 0.5)


def test_run_says_whether_stick_slip_grows_or_decays():
    """The swing per 30 s block a tuning run reads (docs/controllers.md's k table): of a
    sine growing x2 per block, 2x per block; the trend of the last two blocks. Printed for
    a drive-rate controller in DrillString-v0 (set points held), not for a policy, whose
    speed changes would read as swing."""
    import math

    from drill_env.swing import swing_per_block, swing_trend

    speeds = [(t / 10.0, 50.0 + 0.1 * 2.0 ** (t / 300.0) * math.sin(2.0 * math.pi * 0.44
                                                                    * t / 10.0))
              for t in range(0, 1201)]  # 120 s at 10 Hz, ending on the block's edge
    swings = swing_per_block(speeds)
    assert len(swings) == 4  # whole blocks only
    for before, after in zip(swings[:-1], swings[1:], strict=True):
        assert after / before == pytest.approx(2.0, rel=0.05)
    # the second argument: the lowest bit speed of the last block (rpm)
    assert swing_trend(swings, 49.0) == "growing (x2 per 30 s)"
    assert swing_trend([4.0, 1.0], 49.0) == "decaying (x0.25 per 30 s)"
    assert swing_trend([1.0, 1.05], 49.0) == "steady"
    # the bit stops: stick-slip, whatever the speed it ran at (a 46 rpm swing at 120 rpm
    # is none, at 50 rpm it is)
    assert swing_trend([40.0, 46.0], 0.0) == "full stick-slip (the bit stops)"
    assert swing_trend([40.0, 46.0], 74.0) == "growing (x1.1 per 30 s)"
    assert swing_trend([1e-4, 3e-3], 49.9).startswith("none to speak of")
    assert swing_trend([0.0, 0.5], 49.5) == "growing (from below 0.01 rpm)"
    assert swing_trend([0.0099, 0.0101], 50.0) == "none to speak of (about 0.01 rpm)"
    assert swing_trend([0.02, 5.4], 49.5) == "growing (x270 per 30 s)"  # not x2.7e+02
    assert swing_trend([0.02, 24.48], 49.5) == "growing (x1224 per 30 s)"  # not x1,224
    assert swing_per_block(speeds[:200]) == []  # shorter than a block
    # half of (max - min) in the block: 48-52 rpm swings 2 rpm
    assert swing_per_block([(0.0, 48.0), (10.0, 52.0), (20.0, 50.0), (30.0, 50.0)]) == [2.0]
    # the bit stops only under STOPPED; a change of 10 % or less per block is steady
    assert swing_trend([40.0, 46.0], 0.5) == "growing (x1.1 per 30 s)"
    assert swing_trend([1.0, 0.95], 49.0) == "steady"


def test_run_prints_the_swing_for_a_drive_rate_loop_only(tmp_path, capsys):
    """stiff PI at 50 rpm / 100 kN stick-slips by its second block: said; the driller
    moves its set points, which would read as swing: None kept, and why none is printed
    (a walkthrough's policy-rate controller had looked for it)."""
    args = ["run", "--scenario", "stick_slip", "--duration", "60", "--out", str(tmp_path)]
    assert main([*args, "--controller", "stiff"]) == 0
    assert "per 30 s: " in capsys.readouterr().out
    swings = json.loads((tmp_path / "run_summary.json").read_text())["swing_per_block_rpm"]
    assert len(swings) == 2 and swings[1] > 20.0
    assert main([*args, "--controller", "driller"]) == 0
    out = capsys.readouterr().out
    assert "per 30 s" not in out
    assert "no bit-speed swing reported: the set points move" in out  # said, not left out
    assert json.loads((tmp_path / "run_summary.json").read_text())[
        "swing_per_block_rpm"] is None
    # one block: a trend needs two (the swing of the block is in the summary)
    args[4] = "30"
    assert main([*args, "--controller", "stiff"]) == 0
    out = capsys.readouterr().out
    assert "per 30 s: " not in out
    assert "(the bit-speed swing per 30 s, growing or decaying, needs 60 s or more" in out
    assert len(json.loads((tmp_path / "run_summary.json").read_text())[
        "swing_per_block_rpm"]) == 1


def test_a_second_config_file_is_refused_not_dropped(tmp_path, capsys):
    """``--config a --config b`` ran b alone: a string in one file and a top-drive
    setting in the other ran on the default string."""
    field = str(Path(__file__).parents[1] / "examples/field_well_string.yaml")
    for command in (["run"], ["benchmark"], ["modes"], ["stability-map"]):
        with pytest.raises(SystemExit):
            main([*command, "--config", field, "--config", field, "--out", str(tmp_path)])
        assert "--config: given twice" in capsys.readouterr().err


def test_run_notes_a_wob_that_buckles_the_bha(tmp_path, capsys):
    """modes said the field string's BHA buckles above 120 kN; run at 150 kN said
    nothing (a new user's walkthrough). It notes it now, and not below the load."""
    from drill_env.physics.modes import lateral_buckling_weight
    from drill_env.scenarios import make_scenario, with_physics

    field = Path(__file__).parents[1] / "examples" / "field_well_string.yaml"
    from drill_cli.configs import read_overrides

    limit = lateral_buckling_weight(with_physics(make_scenario("default").config,
                                                 read_overrides(field))) / 1e3
    for wob, noted in ((limit * 1.2, True), (limit * 0.8, False)):
        assert main(["run", "--config", str(field), "--wob", f"{wob:.1f}", "--duration",
                     "0.2", "--out", str(tmp_path)]) == 0
        said = capsys.readouterr().err
        assert ("buckles the straight BHA between its stabilizers" in said) is noted, wob


def test_run_and_benchmark_agree_on_the_start(tmp_path):
    """``run`` kicks the bit as the benchmark does (2 %), so the stiff drive stick-slips
    within its 60 s at 50 rpm as in the benchmark table, and starts at the env's own
    fidelity: full for DrillString-v0, the task's fast level for a task's policy."""
    assert main(["run", "--scenario", "stick_slip", "--out", str(tmp_path)]) == 0
    summary = json.loads((tmp_path / "run_summary.json").read_text())
    assert summary["fidelity"] == "full" and summary["mean_stuck_fraction"] > 0.05
    assert main(["run", "--scenario", "stick_slip", "--start-kick", "0", "--out",
                 str(tmp_path)]) == 0  # exactly settled: nothing grows within 60 s
    assert json.loads((tmp_path / "run_summary.json").read_text())[
        "mean_stuck_fraction"] < 0.01
    assert main(["run", "--controller", "learned", "--scenario", "random", "--duration", "1",
                 "--out", str(tmp_path)]) == 0
    assert json.loads((tmp_path / "run_summary.json").read_text())["fidelity"] == "fast"
    # run_summary.json is the last run's; the history keeps all three, in order
    history = [json.loads(line) for line in
               (tmp_path / "run_history.jsonl").read_text().splitlines()]
    assert [(h["controller"], h["scenario"], h["fidelity"]) for h in history] == [
        ("stiff", "stick_slip", "full"), ("stiff", "stick_slip", "full"),
        ("learned", "random", "fast")]
    assert history[0]["mean_stuck_fraction"] == summary["mean_stuck_fraction"]
    assert history[1]["mean_stuck_fraction"] < 0.01


def test_run_drives_a_policy_trained_elsewhere_on_the_scenario_asked_for(tmp_path):
    """A run's env_kwargs (its physics, its scenario) do not replace the scenario and
    --config of the run command: the policy drills what was asked for."""
    import shutil

    import yaml

    from agents.learned import TRAINED

    folder = tmp_path / "policy"
    shutil.copytree(TRAINED / "stick_slip", folder)
    config = yaml.safe_load((folder / "config.yaml").read_text())
    config["env_kwargs"] = {"physics": {"mud.density": 1250.0}, "scenario": "paper_case2"}
    # (a run trained with these env_kwargs: the shipped record of its settings is not
    # its own, and would be a note of moved settings)
    (folder / "trained_with.json").unlink()
    (folder / "config.yaml").write_text(yaml.safe_dump(config))
    assert main(["run", "--controller", f"learned:{folder}", "--scenario", "stick_slip",
                 "--duration", "1", "--out", str(tmp_path)]) == 0
    summary = json.loads((tmp_path / "run_summary.json").read_text())
    assert summary["string_length_m"] == pytest.approx(1250.0)  # stick_slip's, not case 2's


def test_run_notes_a_wob_that_buckles_the_pipe(tmp_path, capsys):
    assert main(["run", "--wob", "200", "--duration", "0.2", "--out", str(tmp_path)]) == 0
    assert "note: 200 kN compresses the 5 in HWDP" in capsys.readouterr().err
    assert main(["run", "--wob", "100", "--duration", "0.2", "--out", str(tmp_path)]) == 0
    assert "note:" not in capsys.readouterr().err
    # a torsion-only model has no lateral motion to buckle (paper case 1 at its 100 kN)
    assert main(["run", "--scenario", "paper_case1", "--duration", "0.2", "--out",
                 str(tmp_path)]) == 0
    assert "note:" not in capsys.readouterr().err


def test_run_judges_buckling_at_the_wob_the_mesh_limit_leaves(tmp_path, capsys):
    """A new user's trial: in an 80 deg hole whose 10 m pipe elements resolve at most
    ~162 kN, --wob 170 was noted as buckling the pipe, where the bit got the limit and the
    run was the same as one at the limit, without buckling. The note judges the WOB the bit
    gets; the limit's warning says how to raise it."""
    import yaml

    string = {"drill_pipe": {"kind": "drill_pipe", "length": 2000.0, "element_length": 10.0,
                             "outer_diameter": 0.1397, "inner_diameter": 0.12136}}
    config = tmp_path / "well.yaml"
    config.write_text(yaml.safe_dump({"string": string, "mud": {"density": 1500.0}, "well": {
        "md": [0, 300, 1100, 2400], "inclination": [0, 0, 80, 80],
        "azimuth": [0, 0, 90, 90]}}))
    with pytest.warns(RuntimeWarning, match="weight_on_bit_limit") as said:
        assert main(["run", "--config", str(config), "--wob", "200", "--duration", "0.2",
                     "--out", str(tmp_path)]) == 0
    warned = " ".join(str(w.message) for w in said)
    limit = float(re.search(r"weight_on_bit_limit, ([0-9.]+) kN", warned).group(1))
    assert limit < 200 and "its element_length, raise it" in warned
    err = capsys.readouterr().err
    from drill_env.physics.statics import pipe_buckling
    from drill_env.scenarios import make_scenario, with_physics

    physics = yaml.safe_load(config.read_text())
    sim_config = with_physics(make_scenario("default").config, physics)
    assert pipe_buckling(sim_config, 200e3) and not pipe_buckling(sim_config, limit * 1e3)
    assert "buckles into the wall" not in err  # (judged at the limit, which does not buckle)


def test_a_wob_given_is_the_one_the_scenario_checks_for_buckling(tmp_path, capsys,
                                                                   monkeypatch):
    """On a horizontal well the scenario's own 100 kN buckles the pipe: `run` and
    `benchmark` refused --wob 60, which does not, for the 100 kN they were not going to
    run (a directional driller's walkthrough)."""
    well = tmp_path / "horizontal.yaml"
    well.write_text("well: {md: [0, 300, 900, 1400], inclination: [0, 0, 90, 90], "
                    "azimuth: [45, 45, 45, 45]}\n")
    out = tmp_path / "out"
    assert main(["run", "--config", str(well), "--duration", "0.2", "--out", str(out)]) == 2
    assert "weight_on_bit: 100 kN compresses the 5 in DP" in capsys.readouterr().err
    assert main(["run", "--config", str(well), "--wob", "60", "--duration", "0.2",
                 "--out", str(out)]) == 0
    summary = json.loads((out / "run_summary.json").read_text())
    assert summary["weight_on_bit_kN"] == pytest.approx(60.0)
    assert summary["mean_setpoint_kN"] == pytest.approx(60.0, rel=1e-6)  # float32 actions
    capsys.readouterr()
    with monkeypatch.context() as here:
        here.chdir(tmp_path)
        assert main(["benchmark", "--controllers", "stiff", "--scenarios", "default",
                     "--config", str(well), "--wob", "60", "--seeds", "1", "--duration",
                     "1", "--warmup", "0.5", "--workers", "1"]) == 0
    assert "error" not in capsys.readouterr().err
    # without --out, a --config variant's outputs go to a folder named by the file, not
    # over the benchmark's own in logs/benchmark (make demo's)
    assert (tmp_path / "logs/benchmark/config-horizontal/benchmark.csv").exists()
    assert not (tmp_path / "logs/benchmark/benchmark.csv").exists()
    # 110 kN buckles it too: refused by the value typed (it named the scenario's 100 kN)
    assert main(["run", "--config", str(well), "--wob", "110", "--duration", "0.2",
                 "--out", str(out)]) == 2
    assert "weight_on_bit: 110 kN compresses the 5 in DP" in capsys.readouterr().err
    # a task policy's own range names the flag (DrillOptimise-v0: 40-200 rpm)
    with pytest.raises(SystemExit):
        main(["run", "--controller", "learned:agents/trained/drilling", "--rpm", "30",
              "--duration", "2", "--out", str(out)])
    assert "--rpm: 30 rpm is outside the env's range 40-200 rpm" in capsys.readouterr().err


def test_a_wob_given_with_an_rpm_is_the_one_the_scenario_checks(tmp_path, capsys):
    """As the test above, with --rpm beside --wob (how a driller types a run): the
    scenario starts at both (rpm -> rad/s by 2 pi / 60, kN -> N by 1000), so the
    horizontal well is checked at the 60 kN typed, which does not buckle its pipe, not at
    the scenario's own 100 kN, which does: the run goes, at 60 rpm and 60 kN."""
    well = tmp_path / "horizontal.yaml"
    well.write_text("well: {md: [0, 300, 900, 1400], inclination: [0, 0, 90, 90], "
                    "azimuth: [45, 45, 45, 45]}\n")
    out = tmp_path / "out"
    assert main(["run", "--config", str(well), "--rpm", "60", "--wob", "60",
                 "--duration", "0.2", "--out", str(out)]) == 0, capsys.readouterr().err
    summary = json.loads((out / "run_summary.json").read_text())
    assert summary["rpm"] == pytest.approx(60.0)
    assert summary["weight_on_bit_kN"] == pytest.approx(60.0)


@pytest.mark.parametrize("command", [["run", "--duration", "0.2"], ["modes"],
                                     ["speed", "--quick", "--sections", "memory"]])
def test_an_out_that_is_a_file_is_refused_before_the_work(tmp_path, capsys, command):
    """It failed with "[Errno 17] File exists", naming no option, and only after the whole
    computation."""
    taken = tmp_path / "taken"
    taken.write_text("")
    with pytest.raises(SystemExit):
        main([*command, "--out", str(taken)])
    err = capsys.readouterr().err
    assert f"--out {taken}: is a file; give a folder" in err
    assert "wrote" not in err


def test_run_records_its_scenario_and_controller_apart(tmp_path):
    """The recording's scenario was "stiff_stick_slip", which is no scenario: the
    controller now has its own field (and still leads the file's name)."""
    from drill_env.recording.replay import read_recording

    assert main(["run", "--scenario", "stick_slip", "--duration", "0.3", "--record",
                 str(tmp_path), "--out", str(tmp_path)]) == 0
    (path,) = tmp_path.glob("*.rrd")
    assert path.name.startswith("stiff_stick_slip_seed0_ep0000_")
    events = [text for _, _, text in read_recording(path).text_logs["/events"]]
    assert events[0].startswith("episode start: stiff, scenario stick_slip, seed 0")


def test_run_refuses_a_top_drive_controller_in_its_config_file(tmp_path, capsys):
    """`drill-env run --config` with a top_drive.controller ran stiff PI silently: the
    --controller (default stiff) set its own top drive over the file's."""
    config = tmp_path / "drive.yaml"
    config.write_text("top_drive:\n  controller: z_torque\n")
    with pytest.raises(SystemExit):  # said as argparse says a bad argument
        main(["run", "--config", str(config), "--duration", "0.2", "--out",
              str(tmp_path / "out")])
    assert (f"--config {config}: top_drive.controller: drill-env run takes the controller "
            "from --controller (default stiff); give --controller z-torque instead") in \
        capsys.readouterr().err
    config.write_text("top_drive:\n  proportional_gain: 2000.0\n")  # one drive's own gain
    assert main(["run", "--config", str(config), "--duration", "0.2", "--out",
                 str(tmp_path / "out")]) == 0


def test_a_task_benchmark_runs_at_the_tasks_fidelity(tmp_path, capsys, monkeypatch):
    from agents.benchmark import RESULTS_FILE, fingerprint
    from agents.settings import BenchmarkSettings
    from drill_cli.benchmark import same_physics
    from drill_env.sweep import ResultStore

    monkeypatch.chdir(tmp_path)
    assert main(["benchmark", "--task", "stick_slip", "--controllers", "stiff", "--seeds",
                 "1", "--duration", "3", "--warmup", "1", "--workers", "1"]) == 0
    assert "Means over seeds, +- the half-width of their 95 % interval" in (
        capsys.readouterr().out)
    # by default beside the scenario benchmark's outputs, not over them (it replaced
    # make demo's table and pictures in logs/benchmark)
    tmp_path = tmp_path / "logs" / "benchmark" / "stick_slip"
    assert (tmp_path / "benchmark.csv").exists()
    assert not (tmp_path.parent / "benchmark.csv").exists()
    # which task and seeds, in benchmark.md's heading and so in its pictures' titles (the
    # two tasks' bar charts said "Controller benchmark" and "random" alone)
    assert (tmp_path / "benchmark.md").read_text().startswith(
        "# Controller benchmark, task stick_slip (DrillStickSlip-v0), seed 0\n")
    # scenarios that differ only in set points are the same task episodes: said
    assert same_physics(["default", "stick_slip", "random", "paper_case2"]) == [
        "default", "stick_slip"]
    assert same_physics(["default", "paper_case2"]) == []
    fast = BenchmarkSettings(duration=3.0, warmup=1.0, fidelity="fast")
    assert len(ResultStore(tmp_path / RESULTS_FILE,
                           fingerprint(fast, "DrillStickSlip-v0"))) == 1


def test_run_names_an_unknown_scenario(capsys):
    with pytest.raises(SystemExit):
        main(["run", "--scenario", "nope"])
    assert "--scenario: invalid choice: 'nope'" in capsys.readouterr().err
    # a misspelt choice, or command, names the one it was probably meant to be
    for args, meant in ((["run", "--scenario", "defualt"], "(did you mean default?)"),
                        (["benchmak"], "invalid choice: 'benchmak' (choose from "),
                        (["benchmak"], "(did you mean benchmark?)"),
                        (["train", "--task", "stick-slip"], "(did you mean stick_slip?)"),
                        # a name cut short, three letters at least (a fuzzing walkthrough)
                        (["bench"], "(did you mean benchmark?)"),
                        (["run", "--contr", "stiff"], "(did you mean --controller?)")):
        with pytest.raises(SystemExit):
            main(args)
        assert meant in capsys.readouterr().err
    # an empty path read as the current folder (evaluate scored it; a fuzzing walkthrough)
    for args in (["well", "--survey", ""], ["evaluate", " "]):
        with pytest.raises(SystemExit):
            main(args)
        assert "give a path, got" in capsys.readouterr().err
    from drill_env.physics.validation import closest

    assert closest("st", ["stiff", "stack"]) is None  # too short
    assert closest("soft", ["soft-speed", "soft-torque"]) is None  # two begin so
    assert closest("soft-t", ["soft-speed", "soft-torque"]) == "soft-torque"
    from drill_env.physics.validation import repeated  # of any iterable (a review: keys())

    assert repeated({"p1": 1, "p2": 2}.keys()) is None and repeated(iter("abcb")) == "b"


@pytest.mark.parametrize(("args", "message"), [
    (["--rpm", "500"], "--rpm: 500 rpm is outside the env's range 0-200 rpm"),
    (["--wob", "250"], "--wob: 250 kN is outside the env's range 0-200 kN"),  # kN, not N
    # typed in newtons, as the Python API takes it: said (a new user's trial)
    (["--wob", "100000"], "--wob: 100000 kN is outside the env's range 0-200 kN (in kN: did "
                          "you mean 100?)"),
    (["--wob", "-5"], "--wob: must be >= 0 kN, got -5"),
    (["--wob", "nan"], "--wob: must be a finite number of kN"),
    (["--duration", "-1"], "--duration: must be > 0 s"),
    (["--duration", "0"], "--duration: must be > 0 s, got 0"),  # an open bound (number())
    (["--seed", "-2"], "--seed: must be >= 0")])
def test_run_names_a_bad_argument_in_the_units_typed(tmp_path, capsys, args, message):
    with pytest.raises(SystemExit):
        main(["run", *args, "--out", str(tmp_path)])
    assert message in capsys.readouterr().err


def test_run_names_the_unit_of_a_duration_past_the_envs_bound(tmp_path, capsys):
    # pydantic's bound said no unit (a fuzzing walkthrough)
    assert main(["run", "--duration", "1e12", "--out", str(tmp_path)]) == 2
    assert "--duration: Input should be less than or equal to 32000000, got " \
        "1000000000000.0 (s; a year is 3.15e7 s)" in capsys.readouterr().err


@pytest.mark.parametrize(("flag", "value", "unit"), [("--rpm", "500", "rpm"),
                                                     ("--wob", "250", "kN")])
def test_benchmark_names_a_set_point_outside_drillstrings_range_by_its_option(
        tmp_path, capsys, flag, value, unit):
    """SPEC section 6: an error names the bad field; ``benchmark_set_points``: --rpm and
    --wob are checked against DrillString-v0's ranges (0-200 rpm, 0-200 kN), each refused
    under its own option, in the unit typed."""
    with pytest.raises(SystemExit):
        main(["benchmark", "--controllers", "stiff", flag, value, "--out", str(tmp_path)])
    assert f"error: {flag}: {value} {unit} is outside DrillString-v0's range 0-200 {unit}" \
        in capsys.readouterr().err


def test_a_wob_of_zero_is_taken_and_one_under_a_kilonewton_is_refused():
    """``kilonewtons``' docstring: a finite number >= 0, and none between 0 and 1 kN (what a
    WOB typed in MN gives). 0 kN (the bit off bottom, inside the env's 0-200 kN range)
    and 1 kN are taken; 0.5 kN is refused saying it is 500 N."""
    from drill_cli.arguments import kilonewtons

    assert kilonewtons("0") == 0.0
    assert kilonewtons("1") == 1.0
    with pytest.raises(argparse.ArgumentTypeError, match=r"^0.5 kN is only 500 N"):
        kilonewtons("0.5")


def test_a_number_argument_takes_its_upper_bound():
    """``number``'s docstring: a finite number in [low, high], a closed range: --start-kick
    (at most 0.5) takes 0.5 and refuses more, saying "must be <= 0.5"."""
    from drill_cli.arguments import number

    parse = number("", high=0.5)
    assert (parse("0"), parse("0.5")) == (0.0, 0.5)
    with pytest.raises(argparse.ArgumentTypeError, match=r"^must be <= 0.5, got 0.51$"):
        parse("0.51")


def test_a_length_range_may_be_one_length():
    """``--string-lengths LO,HI`` takes 0 < LO <= HI (its error says so): 1000,1000 is
    every seed's string 1000 m long; 1000,900 and 0,900 are refused."""
    from drill_cli.arguments import length_range

    assert length_range("1000,1000") == (1000.0, 1000.0)
    for bad in ("1000,900", "0,900"):
        with pytest.raises(argparse.ArgumentTypeError, match="0 < LO <= HI"):
            length_range(bad)


@pytest.mark.parametrize(("command", "message"), [
    (["run", "--controller", "pid"], "drill-env run: error: --controller: unknown name 'pid'"),
    (["run", "--controller", "constant:-1/2"], "drill-env run: error: --controller: rpm and "
                                              "WOB must be finite and >= 0"),
    (["benchmark", "--controllers", "stiff,pid"], "drill-env benchmark: error: "
                                                  "--controllers: unknown name 'pid'"),
    (["benchmark", "--controllers", "constant:1e2/90,constant:100/90"],
     "drill-env benchmark: error: --controllers: constant:1e2/90, constant:100/90 are the "
     "same set points"),
    (["run", "--controller", "learned:no/such/run"], "drill-env run: error: --controller: "
                                                     "no such folder no/such/run")])
def test_a_bad_controller_is_an_error_of_the_option_typed(tmp_path, capsys, command,
                                                          message):
    with pytest.raises(SystemExit):
        main([*command, "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert message in err and f"usage: drill-env {command[0]}" in err  # the command's usage


def test_no_command_prints_the_commands(capsys):
    assert main([]) == 2
    out = capsys.readouterr().out
    assert out.startswith("usage: drill-env") and "benchmark" in out and "train" in out


def test_help_shows_defaults_and_scenario_names(capsys):
    with pytest.raises(SystemExit):
        main(["run", "--help"])
    out = capsys.readouterr().out
    assert "(default: logs)" in out and "paper_case1" in out and "random" in out


def test_controller_help_names_every_registered_controller():
    # the parser stays light (no agents import), so its help spells the names out: they
    # must follow the registry
    from agents.registry import CLASSICAL, CONTROLLERS
    from drill_cli.parser import parser

    sub = next(a for a in parser()._actions if isinstance(a, argparse._SubParsersAction))

    def option(command: str, flag: str) -> argparse.Action:
        return next(a for a in sub.choices[command]._actions if flag in a.option_strings)

    assert all(name in option("run", "--controller").help for name in CONTROLLERS)
    drive_rate = [name for name in CLASSICAL if name != "driller"]
    assert all(name in option("stability-map", "--controller").help for name in drive_rate)
    assert option("benchmark", "--controllers").default == ",".join(CLASSICAL)


def test_replay_of_a_missing_file_is_one_line(tmp_path, capsys):
    with pytest.raises(SystemExit):
        main(["replay", str(tmp_path / "missing.rrd")])
    err = capsys.readouterr().err
    assert "no recording at" in err and "Traceback" not in err


def test_stability_map_command_writes_the_map_and_its_picture(tmp_path, capsys):
    code = main(["stability-map", "--positions", "P4", "--rpm-step", "50", "--wob-step", "50",
                 "--seconds", "12", "--out", str(tmp_path)])
    assert code == 0
    data = json.loads((tmp_path / "stability_map.json").read_text())
    (m,) = data["maps"]
    assert m["position"] == "P4" and m["rpm"] == [50, 100, 150, 200, 250]
    assert m["weight_on_bit"] == [50e3, 100e3, 150e3, 200e3]
    # the stick test reads the last 10 s (MapSettings.measure), not the whole run with
    # the kick's transient
    assert (data["settings"]["seconds"], data["settings"]["measure"]) == (12.0, 10.0)
    assert (tmp_path / "stability_map.png").stat().st_size > 10_000
    said = capsys.readouterr()
    assert "boundary tracking" in said.out and "not a whole number" not in said.err
    # another controller's maps in the same folder keep the stiff PI's (and a position
    # typed in lower case is the position: 'p4' was unknown without a hint)
    assert main(["stability-map", "--positions", "p4", "--rpm-step", "100", "--wob-step",
                 "100", "--seconds", "10", "--controller", "z-torque",
                 "--out", str(tmp_path)]) == 0
    assert json.loads((tmp_path / "stability_map_z-torque.json").read_text())["controller"] \
        == "z-torque"
    assert json.loads((tmp_path / "stability_map.json").read_text()) == data
    assert (tmp_path / "stability_map_z-torque.png").is_file()
    capsys.readouterr()
    # another grid into the same file: P4's map of the old grid is left out, and said so;
    # a step that does not divide the maximum WOB is said (a new user's --wob-step 3 map
    # ended at 198 kN without a word)
    assert main(["stability-map", "--positions", "P1", "--rpm-step", "100", "--wob-step",
                 "90", "--seconds", "10", "--out", str(tmp_path)]) == 0
    (m,) = json.loads((tmp_path / "stability_map.json").read_text())["maps"]
    assert m["position"] == "P1" and m["weight_on_bit"] == [90e3, 180e3]
    said = capsys.readouterr()
    assert "note: the maps of P4 that " in said.out
    assert ("note: --max-wob 200 kN is not a whole number of --wob-steps: the map's last "
            "line is at 180 kN") in said.err
    assert "note: --max-rpm 250 rpm is not a whole number of --rpm-steps: the map's last " \
        "line is at 200 rpm" in said.err


def test_stability_map_of_a_string_of_your_own(tmp_path, capsys):
    """``--config`` maps a string of your own (a drilling engineer could not): its maps
    are named and titled by the file, hold its overrides, and neither replace nor join
    the paper string's maps in the same folder."""
    field = Path(__file__).parents[1] / "examples" / "field_well_string.yaml"
    grid = ["--positions", "P4", "--rpm-step", "125", "--wob-step", "100", "--seconds", "10",
            "--out", str(tmp_path)]
    assert main(["stability-map", *grid]) == 0
    paper = (tmp_path / "stability_map.json").read_text()
    assert main(["stability-map", *grid, "--config", str(field)]) == 0
    data = json.loads((tmp_path / "stability_map_field_well_string.json").read_text())
    assert data["config"] == str(field)
    assert data["physics"]["string.drill_pipe.length"] == 2205.5
    assert [m["position"] for m in data["maps"]] == ["P4"]
    assert (tmp_path / "stability_map_field_well_string.png").stat().st_size > 10_000
    assert (tmp_path / "stability_map.json").read_text() == paper
    assert json.loads(paper)["physics"] == {} and json.loads(paper)["config"] is None
    capsys.readouterr()
    with pytest.raises(SystemExit):  # a file that is no config: named
        bad = tmp_path / "bad.yaml"
        bad.write_text("string: {hole_diameter: 5.0}\n")
        main(["stability-map", *grid, "--config", str(bad)])
    assert f"--config {bad}: string.hole_diameter" in capsys.readouterr().err


def test_stability_map_command_names_a_bad_position(capsys):
    with pytest.raises(SystemExit):
        main(["stability-map", "--positions", "P7"])
    assert "position" in capsys.readouterr().err
    # too short to hold a stick-slip cycle: the paper string's first torsional mode is
    # 0.66 Hz (its period 1.5 s)
    with pytest.raises(SystemExit):
        main(["stability-map", "--positions", "P1", "--seconds", "0.01"])
    err = " ".join(capsys.readouterr().err.split())
    assert "--seconds: 0.01 s is too short to tell stick-slip: the string's first " \
           "torsional period is 1.52 s; give at least 3.1 s" in err
    # the minimum it names is enough (two periods, rounded up)
    from drill_env.physics.modes import torsional_modes
    from drill_env.stability_map import map_config

    period = 1.0 / float(torsional_modes(map_config("P1")).frequency[0])
    assert 3.0 < 2.0 * period <= 3.1


def test_modes_shows_a_bar_on_a_terminal_for_its_slow_analyses(tmp_path, capsys,
                                                                monkeypatch):
    """A 14 km string's modes took 2 min 20 s without a word (its four stick-slip
    thresholds, dense eigenproblems, 112 s): a bar now counts the six analyses, from
    MODES_BAR_DELAY on, on stderr and cleared (the report on stdout stays clean); in a
    log, whose bars wait a minute, the delay is no error."""
    import io
    import sys

    import drill_cli.studies as studies

    class Terminal(io.StringIO):
        def isatty(self) -> bool:
            return True

    terminal = Terminal()
    monkeypatch.setattr(studies, "MODES_BAR_DELAY", 0.0)
    monkeypatch.setattr(sys, "stderr", terminal)
    assert main(["modes", "--out", str(tmp_path)]) == 0
    frames = terminal.getvalue()
    assert "modes:" in frames and "analysis" in frames and "/6" in frames, frames
    assert "modes:" not in capsys.readouterr().out
    monkeypatch.setattr(sys, "stderr", io.StringIO())  # a log: its bar waits a minute
    assert main(["modes", "--out", str(tmp_path)]) == 0
    assert "modes:" not in sys.stderr.getvalue()


def test_modes_command_reads_a_component_string_from_yaml(tmp_path, capsys):
    root = __import__("pathlib").Path(__file__).parents[1]
    code = main(["modes", "--config", str(root / "examples/field_well_string.yaml"),
                 "--out", str(tmp_path)])
    assert code == 0
    out = capsys.readouterr().out
    assert "string 2500 m" in out and "6 1/2 in DC" in out and "5 1/2 in DP" in out
    # the scenario's description (its string, rock) is not the file's
    assert "field_well_string.yaml (scenario default): the file changes its string" in out
    assert "1250 m" not in out.splitlines()[0]
    rock = tmp_path / "rock.yaml"
    rock.write_text("formation:\n  rocks:\n    - {mu_min: 0.4, mu_max: 0.8}\n")
    assert main(["modes", "--config", str(rock), "--out", str(tmp_path)]) == 0
    head = capsys.readouterr().out.splitlines()[0]
    assert head.startswith("default with rock.yaml: the file changes its formation;")
    assert "hard rock" not in head
    data = json.loads((tmp_path / "modes.json").read_text())
    assert data["modes"][0]["frequency_Hz"][0] > 0.0
    # what it analysed (a --config's read as the default scenario's: a fuzzing walkthrough)
    assert (data["scenario"], data["config"], data["seed"], data["top"]) == (
        "default", str(rock), None, "fixed")
    # every list of records whose keys carry no unit says its units
    units = data["units"]
    assert {"components_N", "critical_speeds", "top_drive_controllers"} == set(units)
    for key, unit in units.items():  # a unit for every field of the records but names
        fields = {k for k, v in data[key][0].items() if isinstance(v, float | None)}
        assert fields <= set(unit), (key, fields - set(unit))
    assert units["critical_speeds"]["frequency"] == "Hz"
    assert (tmp_path / "modes_critical_speeds.png").stat().st_size > 10_000


def test_modes_prints_the_top_drive_gains_the_string_tunes(tmp_path, capsys):
    """The gains of docs/controllers.md's table, for the string analysed: no command
    showed them (a controls engineer computed them in Python). Checked against the closed
    forms: Z = J_p sqrt(G rho) of the drill pipe from its diameters, stiff P = 50 Z,
    SoftSpeed P = 4 Z and I = (2 pi f_s)^2 J_td, the torque feedback's gain 1/Z, ZTorque's
    corner f_s / 4, with f_s the first torsional frequency modes prints."""
    import math

    from drill_env.scenarios import make_scenario

    assert main(["modes", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "top-drive controllers tuned for this string" in out
    assert re.search(r"soft-speed\s+1,187\s+7,762\s+none", out)
    def strict(constant):  # JSON has no NaN: strict readers refuse the file
        raise AssertionError(f"modes.json holds {constant}")

    laws = {law["controller"]: law for law in json.loads(
        (tmp_path / "modes.json").read_text(), parse_constant=strict)["top_drive_controllers"]}
    assert laws["stiff"]["tuning_frequency"] is None  # the stiff PI tunes to none
    pipe = make_scenario("default").config.string.drill_pipe
    j_p = math.pi / 32.0 * (pipe.outer_diameter ** 4 - pipe.inner_diameter ** 4)
    z = j_p * math.sqrt(pipe.shear_modulus * pipe.density)
    f_s = json.loads((tmp_path / "modes.json").read_text())["modes"][0]["frequency_Hz"][0]
    assert laws["stiff"]["proportional_gain"] == pytest.approx(50.0 * z, rel=1e-9)
    assert laws["soft_speed"]["proportional_gain"] == pytest.approx(4.0 * z, rel=1e-9)
    # modes lists the damped frequency; the tuning uses the undamped one (9 % damping:
    # sqrt(1 - 0.09^2) = 0.996)
    assert laws["soft_speed"]["tuning_frequency"] == pytest.approx(f_s, rel=5e-3)
    f = laws["soft_speed"]["tuning_frequency"]
    assert laws["soft_speed"]["integral_gain"] == pytest.approx(
        (2.0 * math.pi * f) ** 2 * laws["soft_speed"]["inertia"], rel=1e-9)
    assert laws["z_torque"]["filter_frequency"] == pytest.approx(f / 4.0, rel=1e-9)
    assert laws["soft_torque"]["feedback_gain"] == pytest.approx(1.0 / z, rel=1e-9)


def test_an_empty_config_file_overrides_nothing_and_a_list_is_refused(tmp_path):
    from drill_cli.configs import read_overrides

    empty = tmp_path / "empty.yaml"
    empty.write_text("# nothing yet\n")
    with pytest.warns(UserWarning, match="holds no settings"):  # said: a walkthrough's
        assert read_overrides(empty) == {}  # empty file ran the defaults unsaid
    listed = tmp_path / "list.yaml"
    listed.write_text("- string\n")
    with pytest.raises(ValueError, match="expected a mapping of config sections"):
        read_overrides(listed)


def test_an_operating_point_in_a_config_file_points_to_its_option(tmp_path, capsys):
    # "rpm: 80" in --config listed the config sections, not where the speed goes
    path = tmp_path / "rpm.yaml"
    path.write_text("rpm: 80\nmud: {density: 1200}\n")
    assert main(["run", "--config", str(path), "--duration", "1", "--out",
                 str(tmp_path / "o")]) == 2
    assert (f"--config {path}: rpm: not a config section; the speed is an option of the "
            "command (drill-env run --rpm, in rpm)") in capsys.readouterr().err


def test_a_start_wob_above_the_mesh_limit_is_said_once(tmp_path):
    """run --wob gives the WOB to the scenario's start and to the reset: above the mesh's
    limit each warned, the second as 'reset options: ...' (a new user's trial)."""
    import warnings

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert main(["run", "--scenario", "lateral_60", "--wob", "200", "--duration", "0.2",
                     "--out", str(tmp_path)]) == 0
    said = [str(w.message) for w in caught if "weight_on_bit_limit, " in str(w.message)]
    assert len(said) == 1 and said[0].startswith("weight_on_bit: 200 kN is above"), said


def test_an_env_setting_in_a_config_file_or_physics_in_config_says_where_it_goes(tmp_path):
    """episode_duration in a --config file was "unknown field of SimulationConfig", and
    gym.make(config={"mud.density": ...}) "unknown field of EnvConfig": each now says where
    it belongs (a new user's trial)."""
    import gymnasium as gym

    from drill_cli.configs import read_overrides
    from drill_env.physics.validation import ConfigError

    path = tmp_path / "env.yaml"
    for text, said in (("episode_duration: 10\n", "episode_duration: not a config section; "
                        "the episode's length is an option of the command (--duration"),
                       ("control_interval: 0.2\n", "control_interval: an env setting "
                        "(EnvConfig), not the simulator's config")):
        path.write_text(text)
        with pytest.raises(ValueError, match=re.escape(f"--config {path}: {said}")):
            read_overrides(path)
    for config, key in (({"mud.density": 1350.0}, "'mud.density'"),
                        ({"string": {"hole_diameter": 0.25}}, "'string'")):
        with pytest.raises(ConfigError, match=re.escape(
                f"the simulator's config, not the env's settings: give it as physics= "
                f"(gym.make(..., physics={{{key}: ...}}))")):
            gym.make("DrillString-v0", config=config)
    with pytest.raises(ConfigError, match="control_intervall: unknown field of EnvConfig"):
        gym.make("DrillString-v0", config={"control_intervall": 0.2})  # the env's: as before


def test_the_example_component_string_fits_every_scenario():
    """The README's example file over any scenario: its components replace the
    scenario's BHA, also the crossing cases' 120 m of collars and their stabilizers
    (refused as 'bha and components, not both' before)."""
    from pathlib import Path

    from drill_cli.configs import read_overrides
    from drill_env.physics.config import StringConfig
    from drill_env.scenarios import SCENARIOS, make_scenario, with_physics

    path = Path(__file__).parents[1] / "examples/field_well_string.yaml"
    overrides = read_overrides(path)
    for name in SCENARIOS:
        config = with_physics(make_scenario(name).config, overrides)
        assert [c.name for c in config.string.components] == [
            c["name"] for c in overrides["string.components"]], name
        assert config.string.bha == StringConfig().bha, name
        assert config.string.stabilizer_positions == (), name
        assert config.string.length == pytest.approx(2500.0), name


def test_modes_gives_each_loops_stick_slip_threshold_a_heavy_drive_moves(tmp_path, capsys):
    """The linear stick-slip threshold of each drive-rate loop at the WOB: SoftSpeed's
    rises past the 50 rpm its docs' runs grew at as the top drive gets heavier (46 rpm at
    1,000, 55 at 2,000 kg m^2), the torque-feedback loops' stay below it (they hold the
    heavy drive), the stiff PI's stays at 72 (tests/physics/test_stick_slip.py checks
    them against the simulator); none on a rock curve that does not fall. modes left the
    bit's falling friction out and could not tell (a controls engineer)."""
    from drill_env.physics.config import replace
    from drill_env.physics.simulator import Simulator
    from drill_env.physics.stability import stick_slip_threshold
    from drill_env.physics.units import RPM
    from drill_env.scenarios import make_scenario

    heavy = tmp_path / "heavy.yaml"
    heavy.write_text("top_drive: {inertia: 2000.0}\n")
    flat = tmp_path / "flat.yaml"
    flat.write_text("formation: {rocks: [{name: flat, mu_min: 0.5, mu_max: 0.5}]}\n")
    # a feedback gain of the file's is the feedback loops' only (the stiff PI refused it)
    gain = tmp_path / "gain.yaml"
    gain.write_text("top_drive: {controller: soft_torque, feedback_gain: 0.002}\n")
    found = {}
    for name, extra in (("light", []), ("heavy", ["--config", str(heavy)]),
                        ("flat", ["--config", str(flat)]), ("gain", ["--config", str(gain)])):
        assert main(["modes", *extra, "--out", str(tmp_path / name)]) == 0
        out = capsys.readouterr().out
        found[name] = json.loads((tmp_path / name / "modes.json").read_text())[
            "stick_slip_threshold_rpm"]
        assert "linear stick-slip threshold at 100 kN" in out
        assert list(found[name]) == ["stiff", "soft-speed", "soft-torque", "z-torque"]
    assert found["light"]["soft-speed"] < 50.0 < found["heavy"]["soft-speed"]
    assert max(found["heavy"]["soft-torque"], found["heavy"]["z-torque"]) < 50.0
    assert found["heavy"]["stiff"] == pytest.approx(found["light"]["stiff"], abs=0.5)
    assert set(found["flat"].values()) == {None}
    assert found["gain"]["stiff"] == found["light"]["stiff"]
    assert found["gain"]["soft-torque"] != found["light"]["soft-torque"]
    config = replace(make_scenario("default").config, **{"top_drive.inertia": 2000.0,
                                                          "top_drive.controller": "soft_speed"})
    assert found["heavy"]["soft-speed"] == pytest.approx(
        stick_slip_threshold(Simulator(config), 100e3) / RPM, rel=1e-9)


def test_modes_command_draws_random_by_seed_and_names_what_it_cannot_analyse(tmp_path,
                                                                              capsys):
    import numpy as np

    from drill_env.scenarios import make_scenario

    drawn = make_scenario("random", rng=np.random.default_rng(7)).config.string.length
    for _ in range(2):  # the same string every time (it drew a new one per call)
        assert main(["modes", "--scenario", "random", "--seed", "7", "--out",
                     str(tmp_path)]) == 0
        assert f"string {drawn:.0f} m" in capsys.readouterr().out
    # no --seed: its help's default, seed 0
    drawn = make_scenario("random", rng=np.random.default_rng(0)).config.string.length
    assert main(["modes", "--scenario", "random", "--out", str(tmp_path)]) == 0
    assert f"string {drawn:.0f} m" in capsys.readouterr().out
    well = tmp_path / "well.yaml"
    well.write_text("well: {md: [0, 300, 1250], inclination: [0, 0, 40], "
                    "azimuth: [0, 0, 90]}\n")
    for args, message in ((["--config", str(well)], f"--config {well}: well: the modal "
                                                     "analysis is for vertical holes"),
                          (["--scenario", "default", "--seed", "3"], "--seed: draws a "
                                                                     "randomised scenario"),
                          (["--scenario", "lateral_60"], "invalid choice: 'lateral_60'")):
        with pytest.raises(SystemExit):
            main(["modes", *args, "--out", str(tmp_path)])
        assert message in capsys.readouterr().err
    # a WOB that buckles the pipe: analysed (the straight string) with a note
    assert main(["modes", "--wob", "150", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "note: at 150 kN the 5 in HWDP is compressed" in out
    assert "a scenario refuses to start there" in out
    # a torsion-only scenario drills it straight (it said drill-env run refused it)
    assert main(["modes", "--scenario", "paper_case1", "--out", str(tmp_path)]) == 0
    assert "this scenario is torsion only (solver.lateral false)" in capsys.readouterr().out


def test_modes_command_says_when_the_model_has_fewer_modes_than_asked(tmp_path, capsys):
    assert main(["modes", "-n", "100000", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    data = json.loads((tmp_path / "modes.json").read_text())
    for m in data["modes"]:
        assert 0 < len(m["frequency_Hz"]) < 100000
        assert (f"({m['kind']}: -n 100000 asked, the model has {len(m['frequency_Hz'])} "
                "oscillating modes") in out


def test_yaml_numbers_in_short_scientific_form_are_numbers(tmp_path):
    # PyYAML reads 2.1e11 (no dot) as a string: "not a valid number", SB3 tracebacks
    from drill_env.physics.validation import read_yaml

    path = tmp_path / "n.yaml"
    path.write_text("a: 2.1e11\nb: 3e-4\nc: -1E+3\nd: 3.0e-4\ne: 12\nf: '3e-4'\ng: 1e\n"
                    "h: .5e3\n")
    assert read_yaml(path) == {"a": 2.1e11, "b": 3e-4, "c": -1e3, "d": 3e-4, "e": 12,
                               "f": "3e-4", "g": "1e", "h": 500.0}
    # YAML 1.1's base 60: "density: 20:00" ran at 1200 kg/m^3 (a fuzzing walkthrough)
    for text, value in (("20:00", "1200"), ("1:30.5", "90.5")):
        path.write_text(f"a: {text}\n")
        with pytest.raises(ValueError, match=f"at line 1, column 4 \\({text} is the base-60 "
                                             f"number {value} to YAML 1.1"):
            read_yaml(path)
    path.write_text("a: '20:00'\nb: 12:a\n")  # quoted, or not a number: text
    assert read_yaml(path) == {"a": "20:00", "b": "12:a"}


def test_a_yaml_file_of_nested_aliases_is_refused_and_a_long_value_said_short(tmp_path,
                                                                              capsys):
    """A fuzzing walkthrough: 448 bytes of nested aliases (9 levels of 9) held 387 million
    values; the error for the field printed them all and ran out of memory, and a list
    pasted into a number's field printed whole."""
    lines = ["mud:", "  density:", "    - &a0 [1, 1, 1, 1, 1, 1, 1, 1, 1]"]
    lines += [f"    - &a{i} [" + ", ".join([f"*a{i - 1}"] * 9) + "]" for i in range(1, 9)]
    bomb = tmp_path / "bomb.yaml"
    bomb.write_text("\n".join(lines) + "\n")
    assert main(["modes", "--config", str(bomb), "--out", str(tmp_path)]) == 2
    assert "holds more than 1,000,000 values once its aliases (*name) are expanded" in \
        capsys.readouterr().err
    pasted = tmp_path / "pasted.yaml"
    pasted.write_text("mud:\n  density: [" + ", ".join(["1200.0"] * 5000) + "]\n")
    assert main(["modes", "--config", str(pasted), "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "mud.density:" in err and "got [1200.0, 1200.0," in err and "...]" in err
    assert len(err) < 2000


def test_a_yaml_key_written_twice_is_refused_with_its_lines(tmp_path, capsys):
    path = tmp_path / "twice.yaml"
    path.write_text("string:\n  hole_diameter: 0.3\nmud:\n  density: 1200\n"
                    "string:\n  hole_diameter: 0.25\n")
    assert main(["modes", "--config", str(path), "--out", str(tmp_path)]) == 2
    assert "at line 5, column 1 (duplicate key 'string' (first at line 1))" in \
        capsys.readouterr().err


def test_benchmark_refuses_a_seed_count_or_scenario_list_it_cannot_mean(tmp_path, capsys,
                                                                         monkeypatch):
    """From a fuzzing walkthrough: --seeds 1e12 was a MemoryError traceback (the seed
    list), --scenarios default,default ran every episode twice into two identical rows,
    and --out '' (an unset variable) wrote into the current folder."""
    monkeypatch.chdir(tmp_path)
    for args, message in ((["--seeds", "1e12"], "--seeds: must be <= 10,000"),
                          (["--seeds", "0"], "--seeds: must be >= 1, got 0"),  # a count
                          (["--scenarios", "default,default"],
                           "--scenarios: 'default' is given twice"),
                          (["--out", " "], "--out: give a folder's name")):
        with pytest.raises(SystemExit):
            main(["benchmark", "--controllers", "stiff", *args])
        assert message in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["run", "--out", ""])
    assert "--out: give a folder's name" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []
    from agents.benchmark import run_benchmark

    with pytest.raises(ValueError, match="scenarios: 'default' is given twice"):
        run_benchmark(["stiff"], ["default", "default"], [0], tmp_path / "out")


def test_an_unwritable_out_is_refused_before_the_work(tmp_path, capsys):
    (tmp_path / "file").write_text("")
    for out, message in ((tmp_path / "file" / "sub", "file is a file, not a folder"),
                         ("/proc/drill-env-out", "cannot write there")):
        with pytest.raises(SystemExit):
            main(["modes", "--out", str(out)])
        assert message in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file"]  # and nothing created


def test_a_folder_that_takes_no_new_files_is_said_so(tmp_path, monkeypatch):
    """/proc answers "No such file or directory" for a folder it has: the message said
    "/proc: cannot write there (No such file or directory)" (a new user's trial)."""
    import errno
    import os
    import tempfile

    from drill_cli.arguments import unwritable

    def refuse(err):
        def mkdtemp(*args, **kwargs):
            raise OSError(err, os.strerror(err))
        return mkdtemp

    monkeypatch.setattr(tempfile, "mkdtemp", refuse(errno.ENOENT))
    assert unwritable(tmp_path / "out") == (
        f"{tmp_path}: cannot write there (a file system that takes no new files)")
    monkeypatch.setattr(tempfile, "mkdtemp", refuse(errno.EACCES))
    assert unwritable(tmp_path) == f"cannot write there ({os.strerror(errno.EACCES)})"


@pytest.mark.parametrize(("args", "message"), [
    (["--max-rpm", "1e9"], "--max-rpm: at most 1000 rpm, got 1e+09"),
    (["--rpm-step", "1e-6"], "--rpm-step: the map would have 2.5e+08 lines of points"),
    (["--max-wob", "1e9"], "--max-wob: at most 2000 kN"),
    (["--positions", "P1,P1"], "--positions: P1 given twice"),
    # the one step at fault, not both (a walkthrough)
    (["--max-rpm", "1", "--rpm-step", "5"], "--rpm-step: 5 rpm is more than the map's "
                                            "maximum (1 rpm)"),
    (["--max-wob", "10", "--wob-step", "20"], "--wob-step: 20 kN is more than the map's "
                                              "maximum (10 kN)"),
    (["--max-wob", "600"], "--max-wob: 600 kN at 250 rpm: lateral stiffness not positive "
                           "definite")])
def test_a_stability_map_beyond_its_bounds_is_refused_naming_the_option(tmp_path, capsys,
                                                                       args, message):
    # it ran out of memory, or simulated for a minute and then raised a traceback
    assert main(["stability-map", "--positions", "P1", *args, "--out", str(tmp_path)]) == 2
    assert message in capsys.readouterr().err


def test_well_refuses_a_length_no_string_can_have(tmp_path, capsys, monkeypatch):
    with pytest.raises(SystemExit):
        main(["well", "--well", "j_shaped", "--total-md", "1e5", "--out", str(tmp_path)])
    assert "--total-md: must be <= 15000 m, got 100000" in capsys.readouterr().err
    # "<= 15000 m": a closed bound; 15000 m goes on to the preset's own judgement (here a
    # stand-in that refuses every length, so that no 15 km chart is drawn)
    import drill_env.well

    def refuse(total_md):
        raise ValueError(f"survey.total_md: {total_md:g} m reached the preset")

    monkeypatch.setitem(drill_env.well.WELLS, "j_shaped", refuse)
    with pytest.raises(SystemExit):
        main(["well", "--well", "j_shaped", "--total-md", "15000", "--out", str(tmp_path)])
    assert "--total-md: 15000 m reached the preset" in capsys.readouterr().err


def test_modes_command_names_the_bad_field_of_the_yaml(tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text("string:\n  components:\n    - {length: -1, outer_diameter: 0.1, "
                   "inner_diameter: 0.05, element_length: 1}\n")
    assert main(["modes", "--config", str(bad), "--out", str(tmp_path)]) == 2
    assert "string.components[0].length" in capsys.readouterr().err


def test_modes_refuses_what_it_cannot_analyse(tmp_path, capsys):
    with pytest.raises(SystemExit):
        main(["modes", "--wob", "200", "--out", str(tmp_path)])
    said = capsys.readouterr().err
    assert "--wob: 200 kN buckles the BHA" in said
    assert "a buckled BHA drills on" in said  # so run and benchmark drilling it is no slip


def test_replay_refuses_what_the_viewer_cannot_open(tmp_path, capsys, monkeypatch):
    """Each of these was served as an empty viewer page (or, without a display, blamed
    the display): the file is checked first, with rerun's own reader."""
    import importlib
    import socket

    replay_module = importlib.import_module("drill_env.recording.replay")

    text = tmp_path / "notes.txt"
    text.write_text("not a recording")
    empty = tmp_path / "empty.rrd"
    empty.write_bytes(b"")
    assert main(["run", "--scenario", "stick_slip", "--duration", "0.3", "--record",
                 str(tmp_path / "rec"), "--out", str(tmp_path)]) == 0
    (good,) = (tmp_path / "rec").glob("*.rrd")
    data = good.read_bytes()
    other = tmp_path / "other_version.rrd"  # the header's rerun version made 0.20.0
    at = data.index(b"RRF2") + 4
    other.write_bytes(data[:at] + bytes([0, 20, 0, 0]) + data[at + 4:])
    cut = tmp_path / "cut.rrd"  # too short to hold a recording
    cut.write_bytes(data[:8])
    half = tmp_path / "half.rrd"  # a run killed while writing: most of it is there
    half.write_bytes(data[:len(data) // 2])
    garbage = tmp_path / "garbage.rrd"  # rerun's magic over garbage: the viewer's page was
    garbage.write_bytes(b"RRF2garbagegarbagegarbage")  # empty, with a warning (a fuzzer)
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr("sys.platform", "linux")
    opened: list[list[str]] = []

    class Viewer:  # stands in for the rerun viewer: records its command line
        pid = 0

        def __init__(self, command, **kwargs):
            opened.append(command)

        def wait(self):
            return 0

        def poll(self):
            return 0

    # (from the start: a file the checks let through opened a real viewer, which ran for
    # minutes at a full core before the test could fail)
    monkeypatch.setattr(replay_module.subprocess, "Popen", Viewer)
    for args, said in [([text], "is not a rerun recording (.rrd)"),
                       ([empty], "is not a rerun recording (no RRF header)"),
                       ([empty, "--web"], "is not a rerun recording (no RRF header)"),
                       ([other, "--web"], "incompatible with the local Rerun version"),
                       ([cut, "--web"], f"FILE: {cut} cannot be opened by rerun"),
                       ([garbage, "--web"], f"FILE: {garbage} cannot be opened by rerun "),
                       ([tmp_path / "rec"], f"FILE: {tmp_path / 'rec'} is a folder; give "
                                            f"its recordings: {good.name}"),
                       ([good, good.with_name("gone.rrd")], "FILE: no recording at"),
                       ([good], "add --web"),  # a good file: now the display
                       ([good, "--port", "9191"], "--port: the web viewer's port; add --web")]:
        with pytest.raises(SystemExit):
            main(["replay", *map(str, args)])
        assert said in capsys.readouterr().err, args
    assert main(["replay", str(good), str(half), "--web"]) == 0
    assert opened[-1][-2:] == [str(good), str(half)]  # several recordings in one viewer
    assert "warning: " in capsys.readouterr().err  # the half file: read in part
    with socket.socket() as holder:  # a port another viewer holds
        holder.bind(("0.0.0.0", 0))
        holder.listen()
        taken = holder.getsockname()[1]
        with pytest.raises(SystemExit):
            main(["replay", str(good), "--web", "--port", str(taken)])
        assert f"--port: {taken} is in use" in capsys.readouterr().err
        monkeypatch.setattr(replay_module, "WEB_VIEWER_PORT", taken)
        assert main(["replay", str(good), "--web"]) == 0
        command = opened[-1]  # the default port taken: rerun picks a free one
        assert command[command.index("--web-viewer-port") + 1] == "0"
    for port, said in [("70000", "--port: 70000 is not a port (1-65535)")]:
        with pytest.raises(SystemExit):  # not a traceback (an OverflowError)
            main(["replay", str(good), "--web", "--port", port])
        assert said in capsys.readouterr().err
    # the web viewer serves this machine only unless asked (rerun's default served every
    # interface, a review); 192.0.2.1 is a documentation address, never a machine's own
    command = opened[-1]
    assert command[command.index("--bind") + 1] == "127.0.0.1"
    assert main(["replay", str(good), "--web", "--bind", "0.0.0.0"]) == 0
    assert opened[-1][opened[-1].index("--bind") + 1] == "0.0.0.0"
    # the native viewer's data server too (it listened on every interface: an outside
    # check), and --bind serves it to the network where asked
    monkeypatch.setenv("DISPLAY", ":0")
    assert main(["replay", str(good)]) == 0
    assert opened[-1][opened[-1].index("--bind") + 1] == "127.0.0.1"
    assert main(["replay", str(good), "--bind", "0.0.0.0"]) == 0
    assert opened[-1][opened[-1].index("--bind") + 1] == "0.0.0.0"
    capsys.readouterr()
    # a DISPLAY no server answers: rerun's own winit error alone, and 1 (a fuzzing
    # walkthrough): the way to the web viewer is said after it
    monkeypatch.setattr(Viewer, "wait", lambda self: 1)
    assert main(["replay", str(good)]) == 1
    assert "the native viewer ended with status 1: where it cannot open a window" in \
        " ".join(capsys.readouterr().err.split())
    monkeypatch.setattr(Viewer, "wait", lambda self: 0)
    for args, said in [(["--web", "--bind", "localhost:1"], "--bind: 'localhost:1' is not an "
                                                            "IP address"),
                       (["--web", "--bind", "192.0.2.1"], "--bind: 192.0.2.1 is not an "
                                                          "address of this machine")]:
        with pytest.raises(SystemExit):
            main(["replay", str(good), *args])
        assert said in capsys.readouterr().err, args


def test_a_misspelt_option_gets_its_commands_usage_and_a_suggestion(capsys):
    """From a walkthrough: ``run --rmp 50`` printed the top-level usage and no hint."""
    for argv, said in [(["run", "--rmp", "50"], "drill-env run: error: unrecognized "
                                                "arguments: --rmp 50 (did you mean --rpm?)"),
                       (["benchmark", "--seeds", "1", "--wobb=3"],
                        "unrecognized arguments: --wobb=3 (did you mean --wob?)"),
                       (["benchmark", "extra"], "benchmark: error: unrecognized arguments: "
                                                "extra\n")]:
        with pytest.raises(SystemExit):
            main(argv)
        err = capsys.readouterr().err
        assert said in err and f"usage: drill-env {argv[0]} " in err, argv


def test_version_and_exclusive_well_inputs(tmp_path, capsys):
    with pytest.raises(SystemExit) as done:
        main(["--version"])
    assert done.value.code == 0 and "drill-env 0." in capsys.readouterr().out
    survey = tmp_path / "s.csv"
    survey.write_text("md,inclination,azimuth\n0,0,0\n1000,10,0\n")
    with pytest.raises(SystemExit):
        main(["well", "--well", "vertical", "--survey", str(survey), "--out", str(tmp_path)])
    assert "--well: give a preset well or --survey, not both" in capsys.readouterr().err


def test_run_keeps_the_seeds_own_set_points_unless_given(tmp_path):
    """A randomised scenario draws its set points per seed at reset; --rpm/--wob override."""
    points = []
    for args in (["--seed", "0"], ["--seed", "1"], ["--seed", "1", "--rpm", "70"]):
        assert main(["run", "--scenario", "random", "--duration", "0.3", *args, "--out",
                     str(tmp_path)]) == 0
        summary = json.loads((tmp_path / "run_summary.json").read_text())
        points.append((round(summary["rpm"], 6), round(summary["weight_on_bit_kN"], 6)))
    assert points[0] != points[1]
    assert points[2] == (70.0, points[1][1])


def test_a_task_policy_runs_at_the_scenarios_set_points(tmp_path):
    """Spec section 4: every controller at the same driller's set points. The shipped
    stick-slip policy acts in its task's env, which draws its own targets unless given:
    ``run`` and the benchmark give it the scenario's (a randomised one's drawn per seed)."""
    def run(*args):
        assert main(["run", "--duration", "0.3", *args, "--out", str(tmp_path)]) == 0
        return json.loads((tmp_path / "run_summary.json").read_text())

    fixed = run("--controller", "learned", "--scenario", "stick_slip")
    assert (fixed["rpm"], fixed["weight_on_bit_kN"]) == pytest.approx((50.0, 100.0))
    drawn = [run("--controller", c, "--scenario", "random", "--seed", "3")
             for c in ("learned", "stiff")]
    assert drawn[0]["rpm"] == pytest.approx(drawn[1]["rpm"], rel=1e-12)
    assert drawn[0]["weight_on_bit_kN"] == pytest.approx(drawn[1]["weight_on_bit_kN"],
                                                        rel=1e-12)

    assert main(["benchmark", "--controllers", "learned,stiff", "--scenarios", "stick_slip",
                 "--seeds", "1", "--duration", "2", "--warmup", "1", "--workers", "1",
                 "--out", str(tmp_path / "bench")]) == 0
    rows = (tmp_path / "bench" / "benchmark.csv").read_text().splitlines()
    header = rows[0].split(",")
    targets = {r.split(",")[0]: float(r.split(",")[header.index("target_rpm")])
               for r in rows[1:]}
    assert targets == pytest.approx({"learned": 50.0, "stiff": 50.0})


def test_a_task_policy_drills_a_scenario_from_its_start_and_for_its_length(tmp_path,
                                                                             capsys):
    """Outside ``--task`` the policy acts in its task's env but drills the scenario as
    every other controller does: settled start (not the task's stalled bit), the
    scenario's episode length (not the task's 30 s), the same first bit speed as the
    stiff drive's in the benchmark; its return is DrillString-v0's reward, its task's
    reward kept apart."""
    import csv

    import numpy as np

    summaries = {}
    for c in ("learned", "stiff"):
        assert main(["run", "--controller", c, "--scenario", "stick_slip", "--out",
                     str(tmp_path / c), "--duration", "0.5"]) == 0
        summaries[c] = json.loads((tmp_path / c / "run_summary.json").read_text())
    assert summaries["learned"]["startup"] == summaries["stiff"]["startup"] == "settled"
    assert summaries["learned"]["env_id"] == "DrillStickSlip-v0"
    # scored as DrillString-v0 scores the stiff drive; its task's reward kept apart
    assert np.isfinite(summaries["learned"]["return"])
    assert isinstance(summaries["learned"]["task_return"], float)
    assert summaries["learned"]["task_return"] != summaries["learned"]["return"]
    assert summaries["stiff"]["task_return"] is None
    assert main(["run", "--controller", "learned", "--scenario", "stick_slip",
                 "--out", str(tmp_path), "--fidelity", "fast"]) == 0
    scenario_length = json.loads((tmp_path / "run_summary.json").read_text())["simulated_s"]
    # the stick_slip scenario's, not 30 s (to within the steps' rounding: the fast level's
    # step need not divide 0.1 s)
    assert scenario_length == pytest.approx(60.0, abs=0.01)

    out = tmp_path / "bench"
    shipped = Path(__file__).parents[1] / "agents/trained/stick_slip"
    assert main(["benchmark", "--controllers", f"learned:{shipped},stiff", "--scenarios",
                 "stick_slip", "--seeds", "1", "--duration", "2", "--warmup", "1",
                 "--workers", "1", "--out", str(out)]) == 0
    # the row is "learned"; the table (printed and benchmark.md) says which model that is
    assert "Trained runs" in capsys.readouterr().out
    assert (f"Trained runs: learned: the policy of {shipped} (model.zip)."
            in (out / "benchmark.md").read_text())
    first = {c: float(np.load(out / "series" / f"{c}_stick_slip_seed0.npz")["bit_speed"][0])
             for c in ("learned", "stiff")}
    assert first["learned"] == pytest.approx(first["stiff"], rel=1e-9)
    assert first["stiff"] > 4.0  # ~50 rpm: turning, not stalled
    with (out / "benchmark.csv").open() as f:
        rows = {r["controller"]: r for r in csv.DictReader(f)}
    for c in ("learned", "stiff"):  # every column a finite number
        assert all(np.isfinite(float(rows[c][k])) for k in rows[c]
                   if k not in ("controller", "scenario"))
    summary = (out / "benchmark.md").read_text()
    assert "its return DrillString-v0's reward" in summary and "nan" not in summary


def test_run_reports_the_set_points_a_controller_applied(tmp_path, capsys):
    """A constant controller drills at its own set points, not the scenario's targets."""
    assert main(["run", "--controller", "constant:160/65", "--duration", "0.3", "--out",
                 str(tmp_path)]) == 0
    summary = json.loads((tmp_path / "run_summary.json").read_text())
    assert (summary["rpm"], summary["weight_on_bit_kN"]) == pytest.approx((100.0, 100.0))
    assert summary["mean_setpoint_rpm"] == pytest.approx(160.0)
    assert summary["mean_setpoint_kN"] == pytest.approx(65.0)
    assert "set points applied: mean 160 rpm, 65 kN" in capsys.readouterr().out
    # one set point of its own is said too: here the WOB, at the scenario's 100 rpm
    assert main(["run", "--controller", "constant:100/65", "--duration", "0.3", "--out",
                 str(tmp_path)]) == 0
    assert "set points applied: mean 100 rpm, 65 kN" in capsys.readouterr().out


def test_evaluating_a_shipped_policy_writes_to_logs_not_into_the_package(tmp_path):
    from pathlib import Path

    from agents.learned import TRAINED
    from drill_cli.train import default_evaluation_folder

    assert default_evaluation_folder(TRAINED / "drilling") == Path("logs/evaluation/drilling")
    assert default_evaluation_folder(tmp_path / "run") == tmp_path / "run" / "evaluation"


def test_run_and_benchmark_drill_the_string_of_a_config_file(tmp_path, capsys):
    """``--config`` merges a YAML of config sections into the scenario, as `modes` does:
    the 2.5 km field string of the example drills in `run` and in every benchmark
    episode, and a bad field fails at once, named by its dotted path."""
    from pathlib import Path

    field = Path(__file__).parents[1] / "examples" / "field_well_string.yaml"
    summary = {}
    for name, extra in (("default", []), ("field", ["--config", str(field)])):
        assert main(["run", "--duration", "0.5", "--out", str(tmp_path / name), "--record",
                     *extra]) == 0
        summary[name] = json.loads((tmp_path / name / "run_summary.json").read_text())
    assert summary["field"]["steps"] == summary["default"]["steps"] == 5
    # the recording names the file of the well it drilled (runs of two wells apart)
    assert Path(summary["field"]["recording"]).name.startswith(
        "stiff_default_field_well_string_seed0_")  # ("+" is no file name's character)
    assert Path(summary["default"]["recording"]).name.startswith("stiff_default_seed0_")
    # 2205.5 m of drill pipe over 190 m of HWDP and ~100 m of BHA (examples/)
    assert 2450.0 < summary["field"]["string_length_m"] < 2550.0
    assert summary["default"]["string_length_m"] < 2000.0
    assert main(["benchmark", "--controllers", "stiff", "--scenarios", "default", "--seeds",
                 "1", "--duration", "1", "--warmup", "0.5", "--workers", "1",
                 "--config", str(field), "--out", str(tmp_path / "bench")]) == 0
    stored = (tmp_path / "bench" / "benchmark_results.jsonl").read_text()
    assert "2205.5" in stored  # the drill pipe length of the file, in the fingerprint
    markdown = (tmp_path / "bench" / "benchmark.md").read_text()
    assert ("config overrides (--config) string.components = a list of 10, "
            "string.drill_pipe.element_length = 10, ") in markdown
    assert "string.drill_pipe.length = 2205.5" in markdown
    assert markdown.startswith(f"# Controller benchmark, config {field}")  # which file
    bad = tmp_path / "bad.yaml"
    bad.write_text("string:\n  drill_pipe: {length: -5.0}\n")
    for command in (["run"], ["benchmark", "--controllers", "stiff"]):
        assert main([*command, "--config", str(bad), "--out", str(tmp_path / "x")]) == 2
        err = capsys.readouterr().err
        assert "--config" in err and "string.drill_pipe.length" in err, err
    broken = tmp_path / "broken.yaml"
    broken.write_text("string: [unclosed\n")
    assert main(["run", "--config", str(broken), "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    assert err.count("--config") == 1 and "not valid YAML" in err, err


def test_a_task_benchmark_runs_the_tasks_evaluation_episodes_and_says_so(tmp_path):
    """``benchmark --task`` defaults to the episode and warm-up `evaluate` measures the
    task on (README's commands give the figures of docs/tasks.md), and benchmark.md
    describes the task's start and drawn targets, not DrillString-v0's."""
    from training.evaluate import EVALUATION_WINDOWS

    assert main(["benchmark", "--task", "stick_slip", "--controllers", "stiff", "--seeds", "1",
                 "--workers", "1", "--out", str(tmp_path)]) == 0
    duration, warmup = EVALUATION_WINDOWS["stick_slip"]
    text = (tmp_path / "benchmark.md").read_text()
    assert f"{duration:g} s episodes of DrillStickSlip-v0: its own start (stalled)" in text
    assert f"metrics over the last {duration - warmup:g} s" in text
    assert "settled state" not in text


def test_file_arguments_and_a_ray_address_are_named_when_wrong(tmp_path, capsys):
    """A missing file or a folder given for a file fails in argparse, naming the flag;
    a malformed Ray address says what an address looks like."""
    cases = ((["well", "--survey", str(tmp_path / "none.csv")], "--survey: no such file"),
             (["run", "--config", str(tmp_path)], "--config: " + f"{tmp_path} is a folder"),
             (["modes", "--config", str(tmp_path / "none.yaml")], "--config: no such file"),
             # it exists: "no such file" was wrong (a fuzzing walkthrough)
             (["run", "--config", "/dev/null"], "--config: /dev/null is not a regular file"))
    for args, says in cases:
        with pytest.raises(SystemExit):
            main(args)
        assert says in capsys.readouterr().err
    # "overrides: keys must be strings, got 3" named neither the file nor where
    numbers = tmp_path / "numbers.yaml"
    numbers.write_text("mud:\n  3: 1\n")
    assert main(["run", "--config", str(numbers), "--out", str(tmp_path)]) == 2
    assert f"--config {numbers}: mud: the key 3 is not a field's name" in \
        capsys.readouterr().err
    # errors of the library's fields, named by the option that set them
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    bad = tmp_path / "bad.csv"
    bad.write_text("md,inclination,azimuth\n0,0,0\n500,0,0\n400,45,90\n")
    typo = tmp_path / "typo.csv"
    typo.write_text("md,inclination,azimuth\n0,0,0\n500,abc,0\n")
    for args, says in ((["run", "--record", str(blocker), "--duration", "0.2"],
                        f"--record {blocker}: is a file"),
                       (["run", "--record", str(tmp_path / "x.rrd"), "--duration", "0.2"],
                        f"--record {tmp_path / 'x.rrd'}: a folder, in which each episode's "
                        f"file is named by its controller, scenario and seed; give {tmp_path}"),
                       (["well", "--well", "j_shaped", "--total-md", "400"],
                        "--total-md: 400.0 m ends before the profile's last curve"),
                       (["well", "--survey", str(bad)], f"--survey: survey {bad}, line 4, "
                                                        "column md: must increase: 400 m "
                                                        "after 500 m"),
                       (["well", "--survey", str(typo)], f"--survey: survey {typo}, line 3, "
                                                         "column inclination: 'abc' is not "
                                                         "a number"),
                       (["stability-map", "--controller", "ztorque"],
                        "--controller: ztorque is not a controller (did you mean "
                        "z-torque?); choose a drive-rate controller: stiff, soft-speed, "
                        "soft-torque, z-torque"),
                       (["stability-map", "--controller", "soft-speed:3"],
                        "--controller: soft-speed:3 is not a controller"),
                       (["stability-map", "--controller", "driller"],
                        "--controller: driller acts at the policy rate"),
                       (["stability-map", "--controller", "constant-120rpm-100kN"],
                        "--controller: constant:120/100 acts at the policy rate"),
                       (["stability-map", "--controller", "learned-mine"],
                        "--controller: 'learned-mine' is a trained run's name in a "
                        "benchmark table; give it as learned:<run folder>"),
                       (["run", "--controller", "learned-mine"],
                        "give it as learned:<run folder>")):
        with pytest.raises(SystemExit):
            main([*args, "--out", str(tmp_path / "out")])
        assert says in capsys.readouterr().err, args
    broken = tmp_path / "broken.yml"
    broken.write_text("ppo: [unclosed\n")
    for command in (["train", "--task", "stick_slip"], ["run"]):
        assert main([*command, "--config", str(broken)]) == 2
        err = "\n".join(line for line in capsys.readouterr().err.splitlines()
                        if "numba compiles" not in line)  # (a new install's notice)
        assert "not valid YAML at line 2, column 1" in err and len(err.splitlines()) == 1
    # UTF-16 (Notepad's "Unicode") named no file: 'utf-8' codec can't decode byte 0xff
    utf16 = tmp_path / "utf16.yaml"
    utf16.write_text("mud: {density: 1200.0}\n", encoding="utf-16")
    for command in (["train", "--task", "stick_slip"], ["run"]):
        assert main([*command, "--config", str(utf16)]) == 2
        err = capsys.readouterr().err
        assert f"{utf16}: not UTF-8 text (byte 0: invalid start byte); save it as UTF-8" in err
    # train without --seeds started a full single run and ignored --workers
    with pytest.raises(SystemExit):
        main(["train", "--task", "stick_slip", "--workers", "2", "--out",
              str(tmp_path / "runs")])
    assert "--workers: a single run trains in this process; give --seeds" in \
        capsys.readouterr().err
    assert not (tmp_path / "runs").exists()
    pytest.importorskip("ray")
    assert main(["benchmark", "--controllers", "stiff", "--scenarios", "default", "--seeds",
                 "1", "--duration", "1", "--warmup", "0.5", "--ray-address", "nope",
                 "--out", str(tmp_path)]) == 2
    assert "benchmark: error: --ray-address: 'nope' is not 'local', 'auto' or a cluster " \
           "address" in capsys.readouterr().err
    # --workers was ignored silently beside --ray-address
    with pytest.raises(SystemExit):
        main(["benchmark", "--controllers", "stiff", "--workers", "2", "--ray-address",
              "local", "--out", str(tmp_path)])
    assert "benchmark: error: --workers: the local processes; with --ray-address" in \
        capsys.readouterr().err


def test_console_numbers_have_no_negative_zero_and_counts_agree_with_their_noun():
    from drill_cli.arguments import counted, fixed

    assert [fixed(v) for v in (-0.001, -0.0, 0.004, -0.01, -1.5)] == \
        ["0.00", "0.00", "0.00", "-0.01", "-1.50"]
    assert fixed(-0.04, 1) == "0.0" and fixed(-0.06, 1) == "-0.1"
    assert (counted(1, "seed"), counted(3, "episode")) == ("1 seed", "3 episodes")


def test_integer_arguments_take_exponents_and_keep_large_values_exact():
    from drill_cli.arguments import integer

    parse = integer(0)
    assert parse("3e3") == 3000 and parse("4.0e5") == 400_000
    assert parse("9007199254740993") == 9007199254740993  # above 2**53: not via float
    for bad in ("2.5", "nan", "inf", "x"):
        with pytest.raises(argparse.ArgumentTypeError):
            parse(bad)


def test_the_demos_stick_slip_table_reproduces_paper_result_1(tmp_path):
    """The main job's first part: stick-slip at 50 rpm, none at 100 rpm (paper case 1);
    the stuck bit, which creeps back by hundredths of an rpm, reads 0.0, not -0.0."""
    from drill_env.tools.demo import stick_slip_demo

    said: list[str] = []
    rows, verdict = stick_slip_demo(tmp_path, echo=said.append)
    assert verdict and rows[0]["stuck_fraction"] > 0.1
    assert "reproduced" in said[-2] and not any("-0.0 " in line for line in said)
    assert (tmp_path / "demo_stick_slip.png").stat().st_size > 10_000
    assert json.loads((tmp_path / "demo_summary.json").read_text()) == rows  # (docstring)
    # bit rpm min-max over the SSI's window: SSI = (max - min) / (2 mean) (SPEC section
    # 5), and over whole stick-slip cycles the bit's mean is the 50 rpm set point
    swing = rows[0]["bit_rpm_max"] - rows[0]["bit_rpm_min"]
    assert swing == pytest.approx(2.0 * rows[0]["ssi"] * 50.0, rel=0.1)
    # in m/h, as named: a PDC bit in hard rock at 100 rpm and 100 kN drills metres an
    # hour (thousandths of a metre a second)
    assert 0.5 < rows[1]["rop_m_per_h"] < 100.0


def test_the_demo_fails_where_paper_result_1_is_not_reproduced(monkeypatch, tmp_path):
    """``drill-env demo`` (make demo, the main job) exits 0 where its table reproduces
    paper result 1 and 1 where it prints "NOT reproduced", so a script or CI running it
    sees the failure; the benchmark part (stubbed here) runs either way."""
    import agents.benchmark as bm
    import drill_env.tools.demo as demo

    ran = []
    monkeypatch.setattr(bm, "run_benchmark", lambda *args, **kw: ran.append(args[3]) or [])
    for reproduced, status in ((True, 0), (False, 1)):
        monkeypatch.setattr(demo, "stick_slip_demo", lambda out, r=reproduced: ([], r))
        assert main(["demo", "--out", str(tmp_path)]) == status
    assert ran == [tmp_path / "benchmark"] * 2
    # a second demo into a folder one is writing: refused before its part 1, naming
    # --out (it redid part 1, then named "this benchmark", which demo cannot move; a fuzz)
    from drill_env.sweep import folder_lock

    with folder_lock(tmp_path, "another demo"):
        assert main(["demo", "--out", str(tmp_path)]) == 2
    assert ran == [tmp_path / "benchmark"] * 2


def test_the_demo_says_not_reproduced_where_both_set_points_stick_slip(tmp_path,
                                                                       monkeypatch):
    """Paper result 1 is stick-slip at 50 rpm and none at 100 rpm (SPEC section 2.4):
    a table with stick-slip at both set points (SSI 1.0 each, stubbed) is "NOT
    reproduced"."""
    import drill_env.tools.demo as demo

    monkeypatch.setattr(demo, "stick_slip_summary",
                        lambda run, t0: {"ssi": 1.0, "stuck_fraction": 0.3})
    said: list[str] = []
    _, verdict = demo.stick_slip_demo(tmp_path, echo=said.append)
    assert not verdict and said[-2].endswith(": NOT reproduced")


def test_the_demos_table_reads_the_last_half_of_each_run_in_its_units(tmp_path,
                                                                      monkeypatch):
    """Each row from its own run's last 30 s (the start's transient left out), torque in
    kN m, ROP in m/h, simulated over wall seconds, the run's status; both runs
    torsional (paper case 1: lateral DOFs frozen). Runs and clock stubbed."""
    import numpy as np

    import drill_env.tools.demo as demo
    from drill_env.physics.units import HOUR, RPM
    from drill_env.tools.studies import COL, Run

    configs = []

    def simulate(config, rpm, wob, seconds, progress=None):
        configs.append(config)
        t = np.arange(0.0, seconds, 0.1)
        records = np.zeros((t.size, len(COL)))
        records[:, COL["time"]] = t
        late = t >= seconds / 2
        # a start transient at twice the set point, then +-10 % about it
        records[:, COL["bit_speed"]] = np.where(
            late, rpm * (1.0 + 0.1 * np.sin(t)), 2.0 * rpm) * RPM
        records[:, COL["surface_speed"]] = rpm * RPM
        records[:, COL["torque_on_bit"]] = np.where(late, 3e3, 9e3)
        records[:, COL["rop"]] = np.where(late, 2.0 / HOUR, 0.0)
        return Run(config, records, t, np.ones((t.size, 1)),
                   "bit stuck" if rpm == 50.0 else "")

    class Clock:  # a second of wall time a reading
        now = 0.0

        def perf_counter(self) -> float:
            self.now += 1.0
            return self.now

    monkeypatch.setattr(demo, "simulate", simulate)
    monkeypatch.setattr(demo, "time", Clock())
    rows, _ = demo.stick_slip_demo(tmp_path, echo=lambda text: None)
    assert all(not c.solver.lateral for c in configs)
    for row, rpm in zip(rows, (50.0, 100.0), strict=True):
        assert row["bit_rpm_min"] == pytest.approx(0.9 * rpm, rel=1e-3)
        assert row["bit_rpm_max"] == pytest.approx(1.1 * rpm, rel=1e-3)
        assert row["mean_tob_kNm"] == pytest.approx(3.0)
        assert row["rop_m_per_h"] == pytest.approx(2.0)
        assert row["real_time_factor"] == pytest.approx(60.0)  # 60 s in one second
    assert [r["status"] for r in rows] == ["bit stuck", "ok"]


@pytest.mark.parametrize("ssi", [(0.7, 0.0), (0.9, 0.3)])
def test_the_demo_needs_strong_stick_slip_at_50_rpm_and_little_at_100(tmp_path, monkeypatch,
                                                                        ssi):
    """Paper result 1 reproduced: SSI above 0.8 at 50 rpm and below 0.2 at 100 rpm; an
    SSI of 0.7 at 50 rpm, or of 0.3 at 100 rpm, is "NOT reproduced" (summaries
    stubbed)."""
    import drill_env.tools.demo as demo

    at = iter(ssi)
    monkeypatch.setattr(demo, "stick_slip_summary",
                        lambda run, t0: {"ssi": next(at), "stuck_fraction": 0.0})
    said: list[str] = []
    _, verdict = demo.stick_slip_demo(tmp_path, echo=said.append)
    assert not verdict and said[-2].endswith(": NOT reproduced")


@pytest.mark.parametrize("signum, status, said, replaced", [
    ("SIGTERM", 143, "terminated", False), ("SIGINT", 130, "interrupted", False),
    ("SIGTERM", 143, "terminated", True), ("SIGHUP", 129, "its terminal closed (SIGHUP)", False),
    ("SIGHUP", 129, "its terminal closed (SIGHUP)", True)])
def test_a_stopped_command_exits_with_the_signal_s_status(monkeypatch, capsys, signum,
                                                         status, said, replaced):
    """A command stopped by a signal exits as the shell reports one, 128 + its number: a
    SIGTERM (a scheduler's stop) exited 130 as if Ctrl-C had stopped it. Also where the
    handler's exception comes back as a plain KeyboardInterrupt (``replaced``: Ray's wait
    does so; a training sweep on Ray said "interrupted" and exited 130)."""
    import signal

    import drill_cli.parser as cli  # where main finds each command

    def stopped(args):
        # the handler the signal would run, run here: a signal sent to the process may
        # be handled by Python later than this call (another thread took it)
        number = getattr(signal, signum)
        try:
            signal.getsignal(number)(number, None)
        except KeyboardInterrupt:
            if replaced:
                raise KeyboardInterrupt from None
            raise
        return 0

    monkeypatch.setattr(cli, "cmd_modes", stopped)
    before = signal.getsignal(signal.SIGTERM), signal.getsignal(signal.SIGHUP)
    with ctrl_c_as_in_a_terminal():
        assert main(["modes"]) == status
    assert f"drill-env modes: {said}" in capsys.readouterr().err
    # the command's handlers are gone
    assert (signal.getsignal(signal.SIGTERM), signal.getsignal(signal.SIGHUP)) == before
    from drill_env.sweep import noted_interrupt

    assert noted_interrupt() is None  # handled: a later training run must not act on it


@pytest.mark.skipif(not hasattr(os, "fork"), reason="a pseudo-terminal is POSIX's")
def test_a_closed_terminal_stops_a_command_as_ctrl_c_does(tmp_path):
    """An ssh session that dropped (its terminal closed: SIGHUP) ended a command at once:
    `train` lost its work since the last checkpoint, `run` its results, with no status
    of its own. Now it stops as on Ctrl-C, keeping what is done, its lines to the closed
    terminal dropped (they failed with an I/O error after the save: exit 2), and exits
    129. Here `run` on a pseudo-terminal, closed once its progress bar shows."""
    import fcntl
    import pty
    import select
    import signal
    import struct
    import sys
    import termios
    import time

    pid, terminal = pty.fork()  # the child: a session whose terminal is the pty
    if pid == 0:  # (the child: SIGHUP's default, as in a terminal, not a nohup'd test
        signal.signal(signal.SIGHUP, signal.SIG_DFL)  # run's ignoring; then the exec)
        os.execv(sys.executable, [sys.executable, "-m", "drill_cli", "run", "--duration",
                                  "100000", "--out", str(tmp_path)])
    # a terminal of 80 columns: on one of none (a new pty's size) tqdm draws nothing
    fcntl.ioctl(terminal, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 80, 0, 0))
    shown, deadline = b"", time.monotonic() + 300.0  # (imports, a first compile)
    try:
        while not re.search(rb"\| [1-9][0-9]*/", shown):  # the progress bar counts
            assert time.monotonic() < deadline, shown[-500:]
            if select.select([terminal], [], [], 1.0)[0]:
                shown += os.read(terminal, 65536)
    finally:
        os.close(terminal)  # the terminal goes: the kernel hangs it up
    while (ended := os.waitpid(pid, os.WNOHANG))[0] == 0:
        assert time.monotonic() < deadline + 60.0
        time.sleep(0.1)
    assert os.WIFEXITED(ended[1]) and os.WEXITSTATUS(ended[1]) == 129
    summary = json.loads((tmp_path / "run_summary.json").read_text())
    assert summary["termination_reason"] == "interrupted" and summary["steps"] > 0


def test_an_interrupted_sweep_says_where_its_finished_work_is(monkeypatch, capsys,
                                                             tmp_path):
    """An interrupted benchmark or stability map keeps its finished episodes or points
    and a rerun goes on from them: it says so (it said only "interrupted"), once one
    finished (an outside check: it said so of a benchmark stopped before any)."""
    import agents.benchmark as bm

    kept: list[Path] = []  # the files where the stopped work had finished an episode

    def stopped(*args, **kwargs):
        for file in kept:
            file.parent.mkdir(parents=True, exist_ok=True)
            file.write_text('{"a finished episode": 1}\n')
        raise KeyboardInterrupt

    monkeypatch.setattr(bm, "run_benchmark", stopped)
    out = tmp_path / "b"
    command = ["benchmark", "--controllers", "stiff", "--seeds", "1", "--out", str(out)]
    assert main(command) == 130
    assert capsys.readouterr().err.strip().endswith("drill-env benchmark: interrupted")
    # nor when the folder holds results from before, or other commands' lines (a run's
    # history): only this command's finished work counts (a review)
    out.mkdir()
    (out / "run_history.jsonl").write_text('{"a run": 1}\n')
    (out / bm.RESULTS_FILE).write_text('{"an older episode": 1}\n')
    import os

    os.utime(out / bm.RESULTS_FILE, (0, 0))
    assert main(command) == 130
    assert capsys.readouterr().err.strip().endswith("drill-env benchmark: interrupted")
    kept.append(out / bm.RESULTS_FILE)
    assert main(command) == 130
    assert (f"drill-env benchmark: interrupted; its finished episodes are kept in {out}: "
            "the same command again goes on from them") in capsys.readouterr().err
    # evaluate's episodes are kept in the run's evaluation folder when no --out is given
    import shutil

    from agents.learned import TRAINED
    from drill_cli.train import default_evaluation_folder

    run = shutil.copytree(TRAINED / "stick_slip", tmp_path / "run")
    kept.append(default_evaluation_folder(run) / bm.RESULTS_FILE)
    monkeypatch.setattr("training.evaluate.evaluate_run", stopped)
    assert main(["evaluate", str(run)]) == 130
    assert (f"drill-env evaluate: interrupted; its finished episodes are kept in "
            f"{default_evaluation_folder(run)}: ") in capsys.readouterr().err
    # the stability map's points, in its --out; the demo's episodes, in its benchmark's
    from drill_cli.studies import MAP_POINTS_FILE

    kept.append(tmp_path / "map" / MAP_POINTS_FILE)
    monkeypatch.setattr("drill_cli.parser.cmd_stability_map", stopped)
    assert main(["stability-map", "--out", str(tmp_path / "map")]) == 130
    assert (f"drill-env stability-map: interrupted; its finished points are kept in "
            f"{tmp_path / 'map'}: ") in capsys.readouterr().err
    kept.append(tmp_path / "demo" / "benchmark" / bm.RESULTS_FILE)
    monkeypatch.setattr("drill_cli.parser.cmd_demo", stopped)
    assert main(["demo", "--out", str(tmp_path / "demo")]) == 130
    assert (f"drill-env demo: interrupted; its finished episodes are kept in "
            f"{tmp_path / 'demo' / 'benchmark'}: ") in capsys.readouterr().err
    monkeypatch.setattr("drill_cli.parser.cmd_modes", stopped)
    assert main(["modes", "--out", str(tmp_path / "m")]) == 130
    assert capsys.readouterr().err.strip() == "drill-env modes: interrupted"


def test_benchmark_windows_default_to_what_help_and_docs_say(monkeypatch, tmp_path):
    """Without --duration and --warmup a scenario benchmark runs 60 s episodes measured
    after 30 s (docs/controllers.md, the options' help); with --task, the task's
    evaluation episode (training.evaluate.EVALUATION_WINDOWS)."""
    import agents.benchmark as bm
    from training.evaluate import EVALUATION_WINDOWS

    seen = []
    monkeypatch.setattr(bm, "run_benchmark", lambda *args, **kw: seen.append(args[4]) or [])
    assert main(["benchmark", "--controllers", "stiff", "--seeds", "1", "--out",
                 str(tmp_path / "a")]) == 0
    assert main(["benchmark", "--task", "stick_slip", "--controllers", "stiff", "--seeds",
                 "1", "--out", str(tmp_path / "b")]) == 0
    assert [(s.duration, s.warmup) for s in seen] == [(60.0, 30.0),
                                                      EVALUATION_WINDOWS["stick_slip"]]


def test_benchmark_seeds_count_up_from_seed_start(monkeypatch, tmp_path):
    """--seed-start is the first seed and --seeds how many per pair (their help): from
    1000000 (where the held-out evaluation seeds start), two are 1000000 and 1000001."""
    import agents.benchmark as bm

    seen = []
    monkeypatch.setattr(bm, "run_benchmark", lambda *args, **kw: seen.append(args[2]) or [])
    assert main(["benchmark", "--controllers", "stiff", "--seeds", "2", "--seed-start",
                 "1000000", "--out", str(tmp_path)]) == 0
    assert seen == [[1_000_000, 1_000_001]]


def test_a_list_of_seeds_where_seeds_is_a_count_says_which_it_is(capsys):
    """--seeds is a list in train (0,1,...) but a count in benchmark and evaluate (the
    README writes both side by side): a list typed there says it is a count, from where,
    and that the list is train's (a new user's '0,1' read only "is not an integer")."""
    for argv, first in ((["benchmark", "--controllers", "stiff"], "counted from --seed-start"),
                        (["evaluate", "stick_slip"], "counted from 1000000")):
        with pytest.raises(SystemExit):
            main([*argv, "--seeds", "0,1"])
        err = capsys.readouterr().err
        assert "--seeds: '0,1': a number of seeds here" in err and first in err
        assert "a list of seeds is train's --seeds" in err


@pytest.mark.parametrize("argv, said", [
    (["benchmark", "--scenarios", "stik_slip"], "--scenarios: unknown ['stik_slip'] (did you "
                                                "mean stick_slip?); known: "),
    (["stability-map", "--controller", "soft_speed"], "--controller: soft_speed is not a "
                                                      "controller (did you mean soft-speed?)"),
    # an empty list (an unset shell variable) ran the default set quietly
    (["benchmark", "--scenarios", ""], "--scenarios: give at least one name"),
    (["benchmark", "--scenarios", " , "], "--scenarios: give at least one name")])
def test_a_misspelt_name_gets_the_name_it_was_probably_meant_to_be(argv, said, tmp_path,
                                                                   capsys):
    with pytest.raises(SystemExit) as stopped:
        main([*argv, "--out", str(tmp_path)])
    assert stopped.value.code == 2
    assert said in capsys.readouterr().err


def test_a_run_shorter_than_the_metric_window_says_so(tmp_path, capsys):
    assert main(["run", "--duration", "0.15", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "default: 1 step (0.1 s)" in out
    assert "window metrics (the episode, 0.1 s, is shorter than the window" in out


def test_a_stopped_run_averages_its_metrics_over_the_steps_it_ran(tmp_path, monkeypatch):
    """run's summary gives "episode mean"s of the window metrics: a run stopped (Ctrl-C)
    after the steps of a shorter run holds that run's means, not their sums spread over
    the steps it never ran."""
    import agents.episode as be

    assert main(["run", "--duration", "0.3", "--out", str(tmp_path / "whole")]) == 0
    whole = json.loads((tmp_path / "whole" / "run_summary.json").read_text())
    real, calls = be.act, []

    def stopping(*args):
        calls.append(1)
        if len(calls) > whole["steps"]:
            raise KeyboardInterrupt
        return real(*args)

    monkeypatch.setattr(be, "act", stopping)  # where run_episode finds it
    assert main(["run", "--duration", "2", "--out", str(tmp_path / "stopped")]) == 130
    stopped = json.loads((tmp_path / "stopped" / "run_summary.json").read_text())
    assert stopped["steps"] == whole["steps"] > 0
    assert stopped["termination_reason"] == "interrupted"
    for key in ("mean_ssi", "mean_radial_ratio", "mean_lateral_force", "mean_rop"):
        # the same steps from the same seed: the same sums over as many steps
        assert stopped[key] == pytest.approx(whole[key], rel=1e-9), key
    assert whole["mean_lateral_force"] > 0.0 and whole["mean_rop"] > 0.0


def test_evaluate_says_which_model_it_scores(tmp_path):
    from agents.learned import TRAINED
    from drill_cli.train import which_model

    shipped = TRAINED / "drilling"
    assert which_model(shipped, shipped / "model.zip").startswith("the shipped policy's")
    (tmp_path / "README.md").write_text("a copy of a shipped policy's folder\n")
    assert which_model(tmp_path, tmp_path / "model.zip").startswith("the folder's model")
    (tmp_path / "run.json").write_text("{}")
    assert which_model(tmp_path, tmp_path / "model.zip").startswith("the run's final model")
    assert which_model(tmp_path, tmp_path / "best_model.zip").startswith("the best model")
    checkpoint = tmp_path / "checkpoints" / "model_5000_steps.zip"
    assert which_model(tmp_path, checkpoint).startswith("the last checkpoint")
    # and how long it trained (a run of one PPO update was scored without a word on it):
    # the best model's row is the first with the highest return, as training keeps it
    from drill_cli.train import trained_steps

    assert trained_steps(tmp_path, tmp_path / "model.zip") is None  # (run.json says none)
    (tmp_path / "run.json").write_text('{"env_steps": 8192}')
    (tmp_path / "evaluations.csv").write_text("timesteps,return\n1000,-50\n2000,-20\n"
                                              "3000,-30\n4000,-20\n")
    assert [trained_steps(tmp_path, tmp_path / name) for name in (
        "model.zip", "best_model.zip", "checkpoints/model_5000_steps.zip")] == [
        8192, 2000, 5000]
    assert trained_steps(shipped, shipped / "model.zip") is None


def test_a_task_benchmark_on_a_curved_well_draws_the_lengths_given(tmp_path, capsys):
    """On a horizontal well the task's default strings (900-1600 m) buckle the pipe for
    1015-1600 m, where the build leaves the vertical; `benchmark --task` had no way to
    draw others (a researcher's walkthrough: the classical controllers alone could not be
    benchmarked on the docs' example well, where 900-1110 m buckled while the build's
    2-10 degrees took the vertical-hole load). The refusal names the lengths that buckle
    and the flag."""
    well = tmp_path / "horizontal.yaml"
    well.write_text("well: {md: [0, 300, 1000, 2000], inclination: [0, 0, 90, 90], "
                    "azimuth: [0, 0, 90, 90]}\n")
    args = ["benchmark", "--task", "stick_slip", "--controllers", "stiff", "--config",
            str(well), "--seeds", "1", "--duration", "1", "--warmup", "0.5", "--workers",
            "1", "--out", str(tmp_path / "b")]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "strings of 1015-1600 m buckle" in err and "--string-lengths" in err
    assert "top_drive" not in err  # the benchmark's own settings are not the user's
    assert main([*args, "--string-lengths", "900,1010"]) == 0
    md = (tmp_path / "b" / "benchmark.md").read_text()
    assert "string_length_range (900.0, 1010.0)" in md
    with pytest.raises(SystemExit):  # a scenario benchmark draws no lengths
        main(["benchmark", "--string-lengths", "1300,1600", "--out", str(tmp_path / "c")])
    assert "--string-lengths: the range a task's random scenario draws" in \
        capsys.readouterr().err
    # a range the random scenario refuses is named as typed, before any episode (the
    # refusal quoted the length a seed drew: "got (20.0, 20.0)" for 10,20)
    for typed, message in (("10,20", "the strings need more than"),
                           ("900,20000", r"\[1\]: Input should be less")):
        with pytest.raises(SystemExit):
            main(["benchmark", "--task", "stick_slip", "--controllers", "stiff",
                  "--string-lengths", typed, "--out", str(tmp_path / "d")])
        err = capsys.readouterr().err
        assert re.search(rf"error: --string-lengths {typed}: string_length_range.*"
                         rf"{message}", err), err
        assert "np.float64" not in err and not (tmp_path / "d").exists()


def test_a_command_says_its_warnings_on_one_line_under_its_name(tmp_path, capsys):
    """A plausibility warning (a mud density typed in ppg) showed pydantic's file and
    source line (an outside check): a command prints its user's warnings as one line
    under its name, keeps Python's format for the others, and gives the format back."""
    import subprocess
    import sys
    import warnings

    from drill_env.sweep import command_warning

    said = command_warning("run")
    assert said(UserWarning("x: looks wrong"), UserWarning, "/lib/p.py", 3) == \
        "drill-env run: warning: x: looks wrong\n"
    # the same words from another call site are said once (both zero gains, 2026-12-05)
    assert said(UserWarning("x: looks wrong"), UserWarning, "/lib/q.py", 9) == ""
    assert "DeprecationWarning" in said(DeprecationWarning("old"), DeprecationWarning,
                                        "/lib/p.py", 3)
    # a RuntimeWarning is its user's too (drill_env's own: no writable folder for numba's
    # kernels; a mutation test: Python's format for it passed every test)
    assert said(RuntimeWarning("y: kept elsewhere"), RuntimeWarning, "/lib/p.py", 3) == \
        "drill-env run: warning: y: kept elsewhere\n"
    before = warnings.formatwarning
    assert main(["run", "--duration", "0.2", "--out", str(tmp_path)]) == 0
    assert warnings.formatwarning is before
    config = tmp_path / "mud.yaml"
    config.write_text("mud: {density: 10.0}\n")
    done = subprocess.run([sys.executable, "-m", "drill_cli", "run", "--config", str(config),
                           "--duration", "0.2", "--out", str(tmp_path)],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert "drill-env run: warning: mud.density: 10 kg/m^3" in done.stderr
    assert "pydantic" not in done.stderr


def test_a_sweeps_warning_is_said_once_not_once_per_process(tmp_path):
    """A mud density typed in ppg was said three times by a two-worker benchmark (the
    command and each pool worker): the processes of a command mark what they said in
    one folder. Two formatters on one folder (two processes) say it once; without the
    folder (a Ray worker on another machine) each process says it once."""
    import subprocess
    import sys

    from drill_env.sweep import command_warning

    first, second = command_warning("x", str(tmp_path)), command_warning("x", str(tmp_path))
    assert first(UserWarning("w"), UserWarning, "a.py", 1) == "drill-env x: warning: w\n"
    assert second(UserWarning("w"), UserWarning, "b.py", 2) == ""
    gone = str(tmp_path / "gone")
    assert command_warning("x", gone)(UserWarning("w"), UserWarning, "a.py", 1) != ""
    config = tmp_path / "mud.yaml"
    config.write_text("mud: {density: 10.0}\n")
    done = subprocess.run([sys.executable, "-m", "drill_cli", "benchmark", "--controllers",
                           "stiff", "--scenarios", "default,stick_slip", "--seeds", "2",
                           "--duration", "1", "--warmup", "0.5", "--workers", "2",
                           "--config", str(config), "--out", str(tmp_path / "out")],
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    assert done.stderr.count("warning: mud.density") == 1, done.stderr


def test_an_option_cut_short_is_not_taken_for_a_longer_one(tmp_path, capsys):
    """argparse took `--seed 3` for evaluate's --seeds (three seeds, not seed 3) and
    `--dur` for --duration (an outside check): the commands take whole names only."""
    for argv, cut in ((["run", "--dur", "0.2"], "--dur"),
                      (["benchmark", "--seed", "3"], "--seed")):
        with pytest.raises(SystemExit) as stopped:
            main([*argv, "--out", str(tmp_path)])
        assert stopped.value.code == 2
        assert f"unrecognized arguments: {cut}" in capsys.readouterr().err


def test_run_refuses_a_config_value_its_own_controller_would_replace(tmp_path, monkeypatch,
                                                                    capsys):
    """From an outside check: `run --config` with a top-drive gain that the controller of
    your own also sets ran the controller's and dropped the file's without a word (the
    benchmark refuses such keys, `modes` says the config wins). Refused, naming both
    values; the same value in both is fine."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "mine.py").write_text(
        "from agents import SetPointController\n\n\nclass GentlePI(SetPointController):\n"
        "    name = 'gentle-pi'\n\n    def physics(self):\n"
        "        return {'top_drive.controller': 'stiff', "
        "'top_drive.proportional_gain': 3000.0, 'top_drive.integral_gain': 800.0}\n")
    for gain, refused in ((100000.0, True), (3000.0, False)):
        (tmp_path / "pg.yaml").write_text(f"top_drive: {{proportional_gain: {gain}}}\n")
        argv = ["run", "--controller", "mine.py:GentlePI", "--scenario", "stick_slip",
                "--config", "pg.yaml", "--duration", "0.5", "--out", str(tmp_path / "o")]
        if refused:
            with pytest.raises(SystemExit):
                main(argv)
            assert ("--config pg.yaml: top_drive.proportional_gain: --controller "
                    "mine.py:GentlePI sets it (3000.0), which would replace the file's "
                    "100000.0") in capsys.readouterr().err
        else:
            assert main(argv) == 0


def test_a_config_string_is_judged_at_the_wob_given_not_the_scenarios_string(tmp_path,
                                                                              capsys):
    """docs/config.md's J-well at 170 kN: its 90 m of collars carry it, but the run was
    refused for the default scenario's heavy-weight pipe, which the --config replaces
    (an outside check): the starting WOB's buckling check is made on the string drilled."""
    from drill_cli.configs import read_overrides
    from drill_env.physics.statics import pipe_buckling
    from drill_env.scenarios import make_scenario, scenario_with_physics, with_physics

    text = (Path(__file__).parents[1] / "docs" / "config.md").read_text()
    config = tmp_path / "jwell.yaml"
    config.write_text(text.split("```yaml\n", 1)[1].split("```", 1)[0])
    assert pipe_buckling(make_scenario("default").config, 170e3)  # the scenario's own
    assert not pipe_buckling(with_physics(make_scenario("default").config,
                                          read_overrides(config)), 170e3)
    # scenarios.scenario_with_physics: the WOB asked stands on the overrides' string
    assert scenario_with_physics("default", None, {"weight_on_bit": 170e3},
                                 read_overrides(config)).weight_on_bit == 170e3
    assert main(["run", "--rpm", "60", "--wob", "170", "--config", str(config),
                 "--duration", "0.2", "--out", str(tmp_path / "out")]) == 0
    assert "buckl" not in capsys.readouterr().err
    summary = json.loads((tmp_path / "out" / "run_summary.json").read_text())
    assert summary["weight_on_bit_kN"] == 170.0


def test_modes_refuses_a_chart_speed_no_string_turns_at(tmp_path, capsys):
    """--max-rpm 1e20 ran, warning of a division by zero and printing a 300-digit
    heading at 1e300 (a fuzzing walkthrough)."""
    with pytest.raises(SystemExit):
        main(["modes", "--max-rpm", "1e20", "--out", str(tmp_path)])
    assert "--max-rpm: must be <= 10000 rpm, got 1e20" in capsys.readouterr().err


@pytest.mark.parametrize(("argv", "said"), [
    (["stability-map", "--positions", "P1,,P2"], "--positions: an empty position in "
                                                 "'P1,,P2'"),
    (["well", "--friction", "0.1,0.2,"], "--friction: an empty factor in '0.1,0.2,'"),
    (["well", "--friction", " "], "--friction: give at least one factor"),
    (["speed", "--quick", "--sections", "core,,env"], "--sections: an empty section in "),
    (["benchmark", "--scenarios", "default,,stick_slip"], "--scenarios: an empty name in ")])
def test_an_empty_item_in_a_comma_list_is_refused_by_every_command(argv, said, tmp_path,
                                                                   capsys):
    """``--controllers a,,b`` and ``--seeds 0,,1`` were refused (a name left out), while
    these lists dropped the empty item and ran (an outside check of bad input): a typo
    there now stops the command the same way, before any work."""
    try:
        code = main([*argv, "--out", str(tmp_path / "out")])
    except SystemExit as stop:  # (argparse's way of saying a bad argument)
        code = stop.code
    assert code == 2
    err = capsys.readouterr().err
    assert said in err and "Traceback" not in err
    assert not (tmp_path / "out").exists()


def test_a_ctrl_c_before_the_command_runs_is_said_in_one_line(monkeypatch, capsys):
    """A Ctrl-C while the command line was read (the parser's imports: the first half
    second of any command) printed a traceback of dozens of lines, exit 130 (an outside
    check of interrupts): it is said in one line, with the same status."""
    import drill_cli.main as cli

    def interrupted() -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(cli, "parser", interrupted)
    assert main(["--version"]) == 130
    assert capsys.readouterr().err == "drill-env: interrupted\n"


def test_a_sweeps_workers_say_their_warnings_as_the_command_does(tmp_path, capfd):
    """A benchmark's pool workers (spawned) printed a warning in Python's format, with its
    file and source line, once per worker and into the progress bar (a new user's
    walkthrough): they say it as the command does, on one line under its name."""
    config = tmp_path / "mud.yaml"
    config.write_text("mud: {density: 10.0}\n")  # in ppg, where kg/m^3 go: a warning
    assert main(["benchmark", "--config", str(config), "--controllers", "stiff",
                 "--scenarios", "default", "--seeds", "2", "--duration", "1", "--warmup",
                 "0", "--workers", "2", "--out", str(tmp_path / "out")]) == 0
    err = capfd.readouterr().err
    said = err.count("drill-env benchmark: warning: mud.density: 10 kg/m^3")
    assert said >= 1 and err.lower().count("warning") == said, err
    assert "warnings.warn(" not in err and ".py:" not in err


def test_a_task_benchmark_checks_a_curved_survey_against_the_string_lengths_typed(
        tmp_path, capsys):
    """A survey that reaches the longest string of --string-lengths is taken every time
    (an outside check: it was checked on an unseeded draw from the default 900-1600 m, and
    refused at random, 4 runs in 7); one shorter than the range's top is refused always,
    naming the range and what narrows it (run has nothing that does)."""
    from drill_cli.configs import checked_overrides

    survey = tmp_path / "curved.yaml"
    survey.write_text("well: {md: [0, 200, 500, 700, 900, 1400], inclination: [0, 0, 45, "
                      "45, 90, 90], azimuth: [0, 0, 0, 0, 30, 30]}\n")
    for _ in range(12):
        assert checked_overrides(survey, ["random"],
                                 {"string_length_range": (900.0, 980.0)})["well.md"][-1] == 1400
    assert main(["benchmark", "--task", "stick_slip", "--controllers", "stiff", "--seeds",
                 "1", "--duration", "2", "--warmup", "1", "--string-lengths", "900,980",
                 "--config", str(survey), "--out", str(tmp_path / "fits")]) == 0
    for argv, remedy in ((["benchmark", "--task", "stick_slip"],
                          " (--string-lengths with --task); extend the survey or narrow the "
                          "range"),
                         (["run", "--scenario", "random"], "; extend the survey\n")):
        assert main([*argv, "--config", str(survey), "--out", str(tmp_path / "short")]) == 2
        err = capsys.readouterr().err
        assert "survey ends at 1400.0 m" in err and "draws strings of 900-1600 m" + remedy in err


def test_run_says_the_weight_on_bit_the_bit_got_where_the_mesh_limits_it(tmp_path,
                                                                          capsys):
    """On a horizontal well the default string's mesh resolves at most ~96.6 kN: the
    summary said the 100 kN asked for and nothing of what the bit got (an outside check)."""
    survey = tmp_path / "curved.yaml"
    survey.write_text("well: {md: [0, 200, 500, 700, 900, 1400], inclination: [0, 0, 45, "
                      "45, 90, 90], azimuth: [0, 0, 0, 0, 30, 30]}\n")
    with pytest.warns(RuntimeWarning, match="weight_on_bit_limit"):
        assert main(["run", "--config", str(survey), "--duration", "0.5", "--out",
                     str(tmp_path)]) == 0
    summary = json.loads((tmp_path / "run_summary.json").read_text())
    assert summary["weight_on_bit_kN"] == 100.0
    assert 90.0 < summary["mean_weight_on_bit_kN"] < 99.0
    assert f"at the bit: WOB {summary['mean_weight_on_bit_kN']:.1f} kN" in \
        capsys.readouterr().out


def test_a_value_starting_with_a_minus_sign_is_the_options_and_judged_by_its_check(capsys):
    """argparse read `--seeds -1,2` (and `--wob -1e3`) as an option and said only
    "expected one argument"; the value is the option's, and its own check names what is
    wrong with it."""
    for argv, said in ((["train", "--task", "stick_slip", "--seeds", "-1,2"],
                        "--seeds: distinct integers"),
                       (["benchmark", "--wob", "-1e3"], "--wob: must be >= 0 kN, got -1e3")):
        with pytest.raises(SystemExit):
            main(argv)
        err = capsys.readouterr().err
        assert said in err and "expected one argument" not in err


def test_a_users_training_module_in_the_working_folder_is_named_not_imported(tmp_path):
    """drill-env's `agents` and `training` are top-level packages (SPEC section 1):
    `python -m drill_cli train ...` from a folder holding a training.py imported that one
    and failed with "No module named 'training.config'" (an outside check)."""
    import os
    import subprocess
    import sys

    home = Path(__file__).resolve().parents[1]
    (tmp_path / "training.py").write_text("x = 1\n")
    env = {**os.environ, "PYTHONPATH": str(home)}  # drill_cli found, the user's first

    def ran(*argv: str) -> subprocess.CompletedProcess:
        return subprocess.run([sys.executable, "-m", "drill_cli", *argv], cwd=tmp_path,
                              env=env, capture_output=True, text=True, timeout=120)

    done = ran("evaluate", "somewhere")  # evaluate imports training
    assert done.returncode == 2
    said = " ".join(done.stderr.split())
    assert "No module named 'training.config'" in said
    assert f"training is {tmp_path / 'training.py'} (drill-env's own lie in {home})" in said
    assert "agents is" not in said
    assert ran("--version").returncode == 0  # what does not import it is not blocked
    (tmp_path / "training.py").unlink()
    done = ran("evaluate", "somewhere")
    assert "RUN: no such folder somewhere" in done.stderr and "hides" not in done.stderr


def test_trains_help_names_where_the_shipped_hyperparameters_lie(capsys):
    """Installed from a wheel, "default: training/hyperparams/<task>.yml" read as a path
    in the working folder, where `--config training/hyperparams/stick_slip.yml` was then
    refused (an outside check): the help names the installed folder."""
    from drill_cli.installation import shipped_hyperparameters
    from training.config import HYPERPARAMS

    assert Path(shipped_hyperparameters()) == HYPERPARAMS
    assert (HYPERPARAMS / "stick_slip.yml").is_file()
    with pytest.raises(SystemExit):
        main(["train", "--help"])
    assert "".join(capsys.readouterr().out.split()).count(
        "".join(f"{HYPERPARAMS}/<task>.yml".split())) == 1


def test_modes_marks_a_controller_as_the_configs_only_where_the_file_sets_its_drive(
        tmp_path, capsys):
    """A file of only a string marked the stiff PI "<- the config's" (the scenario's own
    drive; a drilling engineer's review): the mark is for a top drive the file changes."""
    string_only = Path(__file__).parents[1] / "examples" / "field_well_string.yaml"
    drive = tmp_path / "drive.yaml"
    drive.write_text("top_drive: {controller: soft_torque}\n")
    marked = {}
    for file in (string_only, drive):
        assert main(["modes", "--config", str(file), "--out", str(tmp_path / file.stem)]) == 0
        marked[file.stem] = [line.split()[0] for line in capsys.readouterr().out.splitlines()
                             if line.endswith("<- the config's")]
    assert marked == {"field_well_string": [], "drive": ["soft-torque"]}


def test_a_command_started_with_sigint_ignored_still_stops_on_one(tmp_path):
    """A script's background job (`drill-env train ... &`) inherits SIGINT ignored: `kill
    -INT` stopped the sweeps but `train` ran to its end, unsaved (a scale trial). Every
    command hears it: 10 h at the fast level stop at the first SIGINT after start-up (sent
    each second until it ends) with 130, not after its ~30 s of work with 0."""
    import os
    import signal
    import subprocess
    import sys
    import time

    home = Path(__file__).resolve().parents[1]
    env = {**os.environ, "PYTHONPATH": str(home)}
    process = subprocess.Popen(
        [sys.executable, "-m", "drill_cli", "run", "--duration", "36000", "--fidelity",
         "fast", "--out", str(tmp_path)], cwd=tmp_path, env=env, stdout=subprocess.PIPE,
        stderr=subprocess.PIPE, text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
    started = time.monotonic()
    while process.poll() is None and time.monotonic() - started < 120:
        time.sleep(1.0)
        process.send_signal(signal.SIGINT)
    out, err = process.communicate(timeout=60)
    assert process.returncode == 130, err
    # the summary of what it ran; or, where the kernels were still compiling (a fresh
    # cache), the command's own word
    assert "ended: interrupted" in out or "drill-env run: interrupted" in err


def test_run_and_modes_note_a_string_past_the_allowable_tension(tmp_path, capsys,
                                                                 monkeypatch):
    """Where the statics find a component past S-135's allowable tension (a 13 km string:
    tests/physics/test_statics.py; too slow to build here, so the finding is put in), run
    notes it on stderr and modes with its loads table, in kN as typed."""
    from drill_env.physics import statics

    found = [statics.OverTension("5 in DP", 3.237e6, 3.150e6)]
    monkeypatch.setattr(statics, "over_allowable_tension", lambda config, wob: found)
    assert main(["run", "--duration", "0.2", "--out", str(tmp_path / "run")]) == 0
    err = capsys.readouterr().err
    assert "note: the 5 in DP carries 3,237 kN at its top hanging straight, above 3,150 kN" \
        in err
    assert main(["modes", "-n", "1", "--out", str(tmp_path / "modes")]) == 0
    assert "note: the 5 in DP carries 3,237 kN" in capsys.readouterr().out
    monkeypatch.setattr(statics, "over_allowable_tension", lambda config, wob: [])
    assert main(["run", "--duration", "0.2", "--out", str(tmp_path / "run")]) == 0
    assert "allowable tension" not in capsys.readouterr().err


def test_modes_says_what_the_bits_row_of_its_load_table_holds(tmp_path, capsys):
    """The load table's lowest "N bottom" is not -WOB: the bit's own weight in mud
    (mass x g x (1 - rho_mud / rho_steel), by hand here) hangs below it, which the line
    under the table says (a user read -99.6 kN against a stated 100 kN unexplained)."""
    from drill_env.physics.units import GRAVITY
    from drill_env.scenarios import make_scenario

    config = make_scenario("default").config
    steel = config.string.lower[0].density
    bit = config.bit.mass * GRAVITY * (1.0 - config.mud.density / steel) / 1e3
    assert main(["modes", "-n", "1", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert (f"(the lowest N bottom is the bit's own weight in mud, {bit:.1f} kN, less the "
            "WOB)") in out
    first_row = out.split("(m, kN; tension > 0)\n")[1].splitlines()[0].split()
    assert float(first_row[-2]) == pytest.approx(bit - 100.0, abs=0.06)  # N bottom, kN


def test_a_first_run_says_it_compiles_the_kernels(tmp_path, capsys, monkeypatch):
    """A simulating command says on stderr when numba starts compiling (a first run after
    an install: ~20 s on the first step unexplained, the progress bar projecting three
    hours), once, and nothing where numba has the function already (its compile event
    comes only on a cache miss) or the command compiles nothing; run's summary line says
    how much of its wall time the reset and first step (the compile) took."""
    import contextlib

    from numba import njit

    import drill_cli.installation as cli
    from drill_env import numba_cache_dir

    def plus_one(x: float) -> float:
        return x + 1.0

    monkeypatch.setattr(cli, "no_kernels_cached", lambda: False)  # (a warm cache)
    kernel = njit(plus_one)
    with cli.compile_notice("run") as said:
        assert kernel(1.0) == 2.0 and njit(plus_one)(2.0) == 3.0  # two compiles, one note
    assert said == [True]
    assert capsys.readouterr().err == (
        "drill-env run: numba compiles the kernels its cache lacks, once for this version "
        "of drill-env (all of them 20-60 s on 2 cores, one left out by an earlier command "
        f"far less; cached in {numba_cache_dir()})\n")
    for command, function in (("run", kernel), ("well", njit(plus_one))):
        with cli.compile_notice(command) as said:
            function(3.0)
        assert said == [False] and capsys.readouterr().err == ""

    # a new install's empty cache is said at once: a benchmark's workers compile unheard
    monkeypatch.setattr(cli, "no_kernels_cached", lambda: True)
    with cli.compile_notice("benchmark") as said:
        pass
    assert said == [True] and "drill-env benchmark: numba compiles" in capsys.readouterr().err

    @contextlib.contextmanager
    def compiled(command: str):
        yield [True]

    monkeypatch.setattr(cli, "compile_notice", compiled)
    assert main(["run", "--duration", "0.2", "--out", str(tmp_path)]) == 0
    assert "s of it the reset and first step, which compiled the kernels)" in \
        capsys.readouterr().out


def test_no_kernels_cached_reads_numbas_own_cache(tmp_path):
    """The empty-cache check of the first-run notice is False once numba has cached one
    of drill_env's kernels in this version's folder: checked against numba itself (its
    index files), in a fresh process with a NUMBA_CACHE_DIR of its own. Another checkout's
    kernels of the same version do not count (numba keeps them under their own folder's
    path; a second clone's first run compiled unannounced), nor another library's
    (numba keeps it elsewhere, test_numba_cache.py)."""
    import os
    import subprocess
    import sys

    code = ("import numpy as np\nfrom drill_cli.installation import no_kernels_cached\n"
            "from drill_env import numba_cache_dir\n"
            "from drill_env.physics.linalg import band_cholesky\n"
            "other = numba_cache_dir() / ('physics_' + 40 * '0')\n"
            "other.mkdir(parents=True)\n"
            "(other / 'linalg.band_cholesky-1.py311.nbi').write_bytes(b'')\n"
            "before = no_kernels_cached()\n"
            "band_cholesky(np.array([[0.0, 0.0], [4.0, 4.0]]), np.zeros((2, 2)))\n"
            "print(before, no_kernels_cached())\n")
    home = Path(__file__).resolve().parents[1]
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache"),
           "PYTHONPATH": str(home)}
    done = subprocess.run([sys.executable, "-c", code], env=env, cwd=tmp_path,
                          capture_output=True, text=True, check=True)
    assert done.stdout.split() == ["True", "False"], done


def test_an_ascii_terminal_gets_escapes_not_an_encoding_error(tmp_path, monkeypatch):
    """``PYTHONIOENCODING=ascii`` (or LC_ALL=C without Python's UTF-8 mode): the driller's
    dagger in the table ended the benchmark with "'ascii' codec can't encode" as a bad
    value (exit 2) before benchmark.md was written (an outside check). The characters the
    stream cannot write are escaped instead."""
    import io
    import sys

    raw = io.BytesIO()
    out = io.TextIOWrapper(raw, encoding="ascii")
    monkeypatch.setattr(sys, "stdout", out)
    target = tmp_path / "\N{LATIN SMALL LETTER U WITH DIAERESIS}"
    assert main(["benchmark", "--controllers", "stiff,driller", "--scenarios", "stick_slip",
                 "--seeds", "1", "--duration", "3", "--warmup", "1", "--workers", "1",
                 "--out", str(target)]) == 0
    out.flush()
    text = raw.getvalue().decode("ascii")
    assert "\\u2020" in text and "\\xfc" in text
    assert (target / "benchmark.md").exists()
    # cp1252 has the dagger and the umlaut but not every letter a path may hold; UTF-8
    # is left as it is
    from drill_cli.main import tolerant_output

    for encoding, errors in (("cp1252", "backslashreplace"), ("utf-8", "strict")):
        stream = io.TextIOWrapper(io.BytesIO(), encoding=encoding)
        tolerant_output(stream)
        assert stream.errors == errors, encoding


def test_no_writable_temporary_folder_is_said_not_a_traceback(monkeypatch, capsys, tmp_path):
    """With /tmp and its fallbacks read-only every command ended in tempfile's traceback
    (an outside check): it is one line naming TMPDIR, and the signal handlers stay."""
    import signal
    import tempfile

    def none_usable(*args, **kwargs):
        raise FileNotFoundError(2, "No usable temporary directory found in ['/tmp']")

    monkeypatch.setattr(tempfile, "TemporaryDirectory", none_usable)
    before = signal.getsignal(signal.SIGTERM)
    assert main(["run", "--duration", "0.2", "--out", str(tmp_path)]) == 2
    assert "drill-env run: error: no writable temporary folder ([Errno 2] No usable " \
           "temporary directory found in ['/tmp']); set TMPDIR" in capsys.readouterr().err
    assert signal.getsignal(signal.SIGTERM) is before


def test_run_draws_no_progress_bar_into_a_log(tmp_path, capsys):
    """`drill-env run ... 2>&1 | tee log`: the bar's carriage-return frames filled the log
    and the summary was glued after them (an outside check); with stderr no terminal
    there is no bar."""
    assert main(["run", "--scenario", "paper_case1", "--duration", "0.5", "--out",
                 str(tmp_path)]) == 0
    assert "\r" not in capsys.readouterr().err
