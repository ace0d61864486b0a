"""The ``drill-env run`` command: one constant-set-point episode, summary and recording."""

import json

import pytest

from drill_env.cli import main


def test_run_writes_a_summary_and_a_recording(tmp_path, capsys):
    code = main(["run", "--scenario", "paper_case1", "--rpm", "60", "--wob", "80",
                 "--duration", "0.5", "--record", str(tmp_path / "rec"), "--out",
                 str(tmp_path)])
    assert code == 0
    summary = json.loads((tmp_path / "run_summary.json").read_text())
    assert summary["steps"] == 5 and summary["termination_reason"] == ""
    assert summary["rpm"] == 60.0 and summary["weight_on_bit"] == 80e3
    assert summary["simulated_s"] == pytest.approx(0.5)
    assert summary["mean_rop"] > 0.0
    recordings = list((tmp_path / "rec").glob("paper_case1_seed0_*.rrd"))
    assert [str(p) for p in recordings] == [summary["recording"]]
    assert "SSI" in capsys.readouterr().out


def test_run_names_an_unknown_scenario(capsys):
    with pytest.raises(SystemExit):
        main(["run", "--scenario", "nope"])
    assert "--scenario: unknown 'nope'" in capsys.readouterr().err


@pytest.mark.parametrize(("args", "name"), [(["--rpm", "500"], "rpm"),
                                            (["--duration", "-1"], "episode_duration")])
def test_run_names_a_bad_argument(tmp_path, capsys, args, name):
    with pytest.raises(SystemExit):
        main(["run", *args, "--out", str(tmp_path)])
    assert name in capsys.readouterr().err


def test_stability_map_command_writes_the_map_and_its_picture(tmp_path, capsys):
    code = main(["stability-map", "--positions", "P4", "--rpm-step", "50", "--wob-step", "50",
                 "--seconds", "10", "--out", str(tmp_path)])
    assert code == 0
    data = json.loads((tmp_path / "stability_map.json").read_text())
    (m,) = data["maps"]
    assert m["position"] == "P4" and m["rpm"] == [50, 100, 150, 200, 250]
    assert m["weight_on_bit"] == [50e3, 100e3, 150e3, 200e3]
    assert data["settings"]["seconds"] == 10.0
    assert (tmp_path / "stability_map.png").stat().st_size > 10_000
    assert "boundary tracking" in capsys.readouterr().out


def test_stability_map_command_names_a_bad_position(capsys):
    with pytest.raises(SystemExit):
        main(["stability-map", "--positions", "P7"])
    assert "position" in capsys.readouterr().err
