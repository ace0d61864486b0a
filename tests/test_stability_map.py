"""Torsional stability maps (paper Fig. 15): boundary tracking and the paper's result."""

from __future__ import annotations

import math

import numpy as np
import pytest
from helpers import stop_after
from hypothesis import given
from hypothesis import strategies as st

from drill_env import stability_map as sm
from drill_env.physics.config import replace
from drill_env.physics.simulator import Simulator
from drill_env.physics.stability import torsional_growth_rate
from drill_env.scenarios import make_scenario
from drill_env.stability_map import (
    RPM,
    BoundaryTracker,
    MapSettings,
    grid,
    stability_maps,
    track_boundary,
)

# ----------------------------------------------------------------- the algorithm


def full_scan(boundary: np.ndarray, n_wob: int) -> np.ndarray:
    """Every grid point: unstable at and above the boundary WOB index of its speed."""
    return np.arange(n_wob)[:, None] >= boundary[None, :]


@pytest.mark.parametrize("seed", range(20))
def test_tracking_equals_a_full_scan_for_any_rising_boundary(seed):
    rng = np.random.default_rng(seed)
    n_rpm, n_wob = int(rng.integers(1, 30)), int(rng.integers(1, 30))
    # Rising in steps of 0, 1 or several WOB points, starting anywhere, leaving the grid.
    boundary = np.cumsum(rng.choice([0, 0, 1, 3], size=n_rpm)) + rng.integers(0, n_wob)
    visited = []

    def sticks(i, j):
        visited.append((i, j))
        return j >= boundary[i]

    unstable, tested = track_boundary(sticks, n_rpm, n_wob)
    np.testing.assert_array_equal(unstable, full_scan(boundary, n_wob))
    assert len(visited) == len(set(visited)) <= n_rpm + n_wob
    assert (tested >= 0).sum() == len(visited)


def test_no_stick_raises_only_the_wob_and_a_stick_moves_to_the_next_speed():
    boundary = np.array([1, 1, 3])
    visited = []

    def sticks(i, j):
        visited.append((i, j))
        return j >= boundary[i]

    track_boundary(sticks, 3, 5)
    assert visited == [(0, 0), (0, 1), (1, 1), (2, 1), (2, 2), (2, 3)]


@given(st.integers(1, 25), st.integers(1, 25), st.lists(st.booleans(), max_size=60))
def test_points_left_bounds_the_points_a_map_still_runs_and_reaches_zero(n_rpm, n_wob,
                                                                        verdicts):
    """The progress bar's total: ``points_left`` never promises fewer points than the
    map still runs, falls by at least one per point, and is 0 once it is done (the bar
    ends full, at the points run)."""
    tracker = BoundaryTracker(n_rpm, n_wob)
    history = [tracker.points_left()]
    assert history[0] == n_rpm + n_wob - 1
    answers = iter(verdicts)
    while tracker.next_point() is not None:
        tracker.report(next(answers, True))
        history.append(tracker.points_left())
    assert history[-1] == 0
    runs = len(history) - 1
    for k, left in enumerate(history):
        assert left >= runs - k  # never fewer than the points still to run
        if k:
            assert left <= history[k - 1] - 1


def test_grid_and_settings_name_bad_values():
    rpm, wob = grid(50.0, 50e3, 250.0, 200e3)
    assert rpm.tolist() == [50, 100, 150, 200, 250] and wob.tolist() == [50e3, 100e3, 150e3,
                                                                         200e3]
    with pytest.raises(ValueError, match="rpm_step"):
        grid(-5.0)
    with pytest.raises(ValueError, match="measure"):
        MapSettings(seconds=5.0, measure=10.0)
    with pytest.raises(ValueError, match="kick"):
        MapSettings(kick=1.5)
    with pytest.raises(ValueError, match=r"hold: must be <= seconds \(30.0\), got 1000.0"):
        MapSettings(hold=1000.0)
    with pytest.raises(ValueError, match="grid"):
        track_boundary(lambda i, j: True, 0, 3)
    # the boundary tracking walks each axis upward: anything else would map wrongly
    for rpm_axis, wob_axis in (([80.0, 40.0], [50e3]), ([40.0, 40.0], [50e3]),
                               ([0.0, 40.0], [50e3]), ([40.0], [50e3, float("nan")]),
                               (60.0, [50e3])):
        with pytest.raises(ValueError, match="grid_points: the .* strictly increasing"):
            stability_maps(["P1"], grid_points=(rpm_axis, wob_axis), workers=1)
    # a window shorter than one record holds no sample: named, not an empty-signal error
    from drill_env.stability_map import point_sticks

    with pytest.raises(ValueError, match="measure: 0.001 s holds no sample"):
        point_sticks(sm.map_config("P1"), 60.0, 50e3,
                     MapSettings(seconds=0.1, measure=0.001, hold=0.05, record_every=50))


# ----------------------------------------------------------------- the physics

SETTINGS = MapSettings()


@pytest.fixture(scope="module")
def maps():
    """All six positions on a 10 rpm x 10 kN grid up to 150 rpm, 200 kN."""
    return {m.position: m for m in stability_maps(rpm_step=10.0, wob_step=10e3,
                                                  max_rpm=150.0, settings=SETTINGS)}


def test_stick_slip_at_high_wob_and_low_speed_only(maps):
    for m in maps.values():
        assert m.unstable[-1, 0], m.position  # lowest speed, highest WOB
        assert not m.unstable[:, -1].any(), m.position  # 150 rpm: steady at any WOB
        assert not m.unstable[0, 1:].any(), m.position  # 10 kN: steady from 20 rpm on
        assert m.runs <= len(m.rpm) + len(m.weight_on_bit)


def test_unstable_zone_grows_with_contact_to_rock_one(maps):
    """Paper Fig. 15: share of the blades on rock 1 (hard) P4 0 % < P3 25 % < P5 50 %
    < P2 75 % < P1, P6 100 %; the unstable zone grows in that order."""
    f = {p: m.unstable_fraction for p, m in maps.items()}
    assert f["P4"] < f["P3"] < f["P5"] < f["P2"] <= max(f["P1"], f["P6"]) + 0.01
    assert f["P4"] < 0.5 * f["P1"]
    # both all in hard rock, the bit held there: the same map (with the bit returned
    # every 0.5 s P1's drilled into the layer below it and differed by 2 points)
    assert f["P1"] == f["P6"]


def test_hard_rock_map_lies_within_the_linear_instability(maps):
    """P6 (all hard rock, moving away from the layer) against the eigenvalues of the
    linearised torsional dynamics (scipy, independent of the integrator): stick-slip only
    where steady drilling is linearly unstable, and steady only where the growth is slow:
    below twice the rate that turns a 1 % kick into stick-slip within the run (the factor
    2 for the kick's share of the unstable mode and the mesoscopic bit's own slope; at
    20 rpm and 20 kN, linear growth 0.25 /s, stick-slip takes 30-60 s)."""
    m = maps["P6"]
    config = replace(make_scenario("paper_case1", position="P6").config,
                     bit_model="macroscopic")
    sim = Simulator(config)
    slowest = 2.0 * math.log(1.0 / SETTINGS.kick) / (SETTINGS.seconds - SETTINGS.measure)
    for j, i in np.argwhere(m.tested >= 0):
        growth = torsional_growth_rate(sim, m.rpm[i] * RPM, m.weight_on_bit[j], rock=0)
        if m.tested[j, i] == 1:
            assert growth > 0.0, (m.rpm[i], m.weight_on_bit[j])
        else:
            assert growth < slowest, (m.rpm[i], m.weight_on_bit[j])


def test_linear_boundary_brackets_the_sign_change_and_bounds_the_map(maps):
    """linear_boundary: the growth rate changes sign at it (to its 100 N tolerance), it
    rises with speed, and the simulated stick-slip boundary lies at or above it."""
    from drill_env.stability_map import linear_boundary

    m = maps["P6"]
    rpm = m.rpm[:6]  # 10-60 rpm: all inside the 200 kN of the grid
    limit = linear_boundary("P6", rpm)
    assert np.all(np.diff(limit) > 0)
    config = replace(make_scenario("paper_case1", position="P6").config,
                     bit_model="macroscopic")
    sim = Simulator(config)
    for r, b in zip(rpm, limit, strict=True):
        assert torsional_growth_rate(sim, r * RPM, b, rock=0) > 0.0
        assert torsional_growth_rate(sim, r * RPM, b - 100.0, rock=0) <= 0.0
    simulated = m.boundary[:6]
    assert np.all(simulated >= limit)
    with pytest.raises(ValueError, match="straddles"):
        linear_boundary("P2", rpm)


# --------------------------------------------------------------------------- resume

def test_an_interrupted_map_resumes_computing_only_the_missing_points(tmp_path):
    from drill_env.stability_map import MapSettings, stability_maps

    settings = MapSettings(seconds=4.0, measure=2.0)
    grid_points = ([40.0, 80.0, 120.0], [40e3, 90e3, 140e3])
    store = tmp_path / "points.jsonl"
    fresh = stability_maps(["P1", "P4"], settings=settings, grid_points=grid_points)
    total = sum(m.runs for m in fresh)
    assert total >= 6

    with pytest.raises(KeyboardInterrupt):
        stability_maps(["P1", "P4"], settings=settings, grid_points=grid_points, store=store,
                       progress=stop_after(3))
    assert len(store.read_text().splitlines()) == 3  # written as they arrived

    resumed_calls = []
    resumed = stability_maps(["P1", "P4"], settings=settings, grid_points=grid_points,
                             store=store, progress=lambda: resumed_calls.append(1))
    assert len(resumed_calls) == total - 3  # only the missing points were simulated
    for a, b in zip(resumed, fresh, strict=True):
        np.testing.assert_array_equal(a.unstable, b.unstable)
        np.testing.assert_array_equal(a.tested, b.tested)
    # the same points under other settings are not reused
    other = []
    stability_maps(["P1"], settings=MapSettings(seconds=4.0, measure=1.0),
                   grid_points=grid_points, store=store, progress=lambda: other.append(1))
    assert other


def test_a_map_on_local_processes_equals_the_serial_map():
    from drill_env.stability_map import MapSettings, stability_maps

    settings = MapSettings(seconds=4.0, measure=2.0)
    grid_points = ([40.0, 100.0], [50e3, 150e3])
    serial = stability_maps(["P1", "P3"], settings=settings, grid_points=grid_points)
    pooled = stability_maps(["P1", "P3"], settings=settings, grid_points=grid_points,
                            workers=2)
    for a, b in zip(serial, pooled, strict=True):
        np.testing.assert_array_equal(a.tested, b.tested)


@pytest.mark.slow
def test_tuned_controllers_shrink_the_stick_slip_zone_at_every_position():
    """The paper's maps (10 rpm / 10 kN grid) under SoftSpeed and ZTorque: a smaller
    stick-slip zone than under stiff PI at each of P1-P6 (docs/controllers.md)."""
    zones = {}
    for controller in ("stiff", "soft_speed", "z_torque"):
        configs = {p: sm.map_config(p, {"top_drive.controller": controller})
                   for p in sm.POSITIONS}
        maps = sm.stability_maps(tuple(sm.POSITIONS), 10.0, 10e3, configs=configs,
                                 workers=1)
        zones[controller] = {m.position: int(m.unstable.sum()) for m in maps}
    for position in sm.POSITIONS:
        assert zones["stiff"][position] > 0, position
        for tuned in ("soft_speed", "z_torque"):
            assert zones[tuned][position] < zones["stiff"][position], (tuned, position)


@pytest.mark.parametrize("positions", [["P1"], ["P1", "P2"], list(sm.POSITIONS)])
def test_map_figure_keeps_its_title_on_the_page(positions):
    """One panel is 4.2 in wide: the title, one line over six panels, would run off a
    single panel's figure."""
    rpm, wob = np.array([50.0, 100.0]), np.array([50e3, 100e3])
    unstable = np.array([[False, False], [True, False]])
    maps = [sm.StabilityMap(p, 0.0, rpm, wob, unstable, unstable.astype(np.int8),
                            np.array([100e3, np.nan]), 2, 0.1) for p in positions]
    fig = sm.maps_figure(maps, controller="soft-torque")
    renderer = fig.canvas.get_renderer()
    title = fig._suptitle.get_window_extent(renderer)
    page = fig.bbox
    assert page.x0 <= title.x0 and title.x1 <= page.x1, (title, page)
    assert "soft-torque" in fig._suptitle.get_text()
    # the maps, not the title and legend, fill most of it: one map alone at 4.2 x 3.4 in
    # was a 400 x 160 px panel under a three-line title (a check of the pictures)
    rows = math.ceil(len(positions) / 3)
    panels = rows * fig.axes[0].get_window_extent(renderer).height
    assert panels > 0.5 * page.height, (panels, page.height)


# ----------------------------------------------------------------- bookkeeping rules


def test_a_speed_that_sticks_at_the_lowest_wob_has_that_wob_as_its_boundary(monkeypatch
                                                                             ) -> None:
    monkeypatch.setattr(sm, "_point_task", lambda args: {"stuck_fraction": 1.0, "ssi": 1.0})
    (m,) = stability_maps(["P1"], grid_points=([40.0, 80.0], [50e3, 100e3]))
    np.testing.assert_array_equal(m.boundary, [50e3, 50e3])


def test_only_the_measured_window_judges_a_point(monkeypatch) -> None:
    """A bit stuck for the first second of a 4 s point, moving after it: with a 1 s
    measurement window the point does not stick."""
    from drill_env.physics.layout import R

    class StuckFirst:
        dt, status, status_message, depth = 0.01, 0, "", 0.0

        def __init__(self, config) -> None:
            self.time = 0.0
            self.vt = np.ones(3)  # node speeds: the point kicks the bit's

        def reset(self, operating_point) -> None:
            pass

        def hook_load_for(self, weight_on_bit) -> float:
            return 0.0

        def set_depth(self, depth) -> None:
            pass

        def advance(self, n, omega, hook, every):
            k = n // every
            rec = np.zeros((k, max(R.TIME, R.BIT_SPEED) + 1))
            rec[:, R.TIME] = self.time + self.dt * every * np.arange(1, k + 1)
            rec[:, R.BIT_SPEED] = np.where(rec[:, R.TIME] < 1.0, 0.0, omega)
            self.time = rec[-1, R.TIME]
            return rec

    monkeypatch.setattr(sm, "Simulator", StuckFirst)
    late = sm.point_sticks(None, 100.0, 50e3, MapSettings(seconds=4.0, measure=1.0))
    assert late["stuck_fraction"] == 0.0
    whole = sm.point_sticks(None, 100.0, 50e3, MapSettings(seconds=4.0, measure=4.0))
    assert whole["stuck_fraction"] > 0.2


def test_a_step_that_divides_the_maximum_in_floating_point_keeps_its_last_line() -> None:
    rpm, wob = grid(rpm_step=0.1, max_rpm=0.3, wob_step=5e3, max_wob=10e3)
    assert len(rpm) == 3 and len(wob) == 2  # 0.3 / 0.1 = 2.9999999999999996


def test_a_map_without_stick_slip_writes_valid_json() -> None:
    import json

    m = sm.StabilityMap("P1", 0.0, np.array([10.0]), np.array([1e3]),
                        np.zeros((1, 1), bool), np.zeros((1, 1), np.int8),
                        np.array([np.nan]), 1, 0.0)
    text = json.dumps(m.to_json(), allow_nan=False)  # NaN is not JSON
    assert json.loads(text)["boundary"] == [None]


def _toy_map(position: str, rpm=(50.0, 100.0), share: float = 0.0) -> sm.StabilityMap:
    rpm, wob = np.array(rpm), np.array([50e3, 100e3])
    unstable = np.zeros((2, len(rpm)), bool)
    unstable[1, 0] = True
    boundary = np.full(len(rpm), np.nan)
    boundary[0] = 100e3
    return sm.StabilityMap(position, share, rpm, wob, unstable, unstable.astype(np.int8),
                           boundary, 2, 0.1)


def test_maps_written_a_few_positions_at_a_time_add_up_in_one_file(tmp_path) -> None:
    import json

    settings = sm.MapSettings(seconds=12.0, measure=10.0)
    sm.write_maps([_toy_map("P4", share=0.4)], tmp_path, settings)
    sm.write_maps([_toy_map("P1"), _toy_map("P2")], tmp_path, settings)
    data = json.loads((tmp_path / "stability_map.json").read_text())
    assert [m["position"] for m in data["maps"]] == ["P1", "P2", "P4"]  # the paper's order
    # every key whose name carries no unit has one in "units" (a drilling engineer's check)
    for section in ("settings", "maps"):
        record = data[section] if section == "settings" else data[section][0]
        unitless = {k for k, v in record.items() if isinstance(v, (float, int, list))
                    and not isinstance(v, bool)} - {"runs", "unstable_fraction"}
        assert unitless <= set(data["units"][section]), (section, unitless)
    assert data["units"]["maps"]["weight_on_bit"] == "N"
    back = sm.StabilityMap.from_json(data["maps"][2])
    want = _toy_map("P4", share=0.4)
    assert back.rock2_share == 0.4 and np.array_equal(back.unstable, want.unstable)
    assert np.array_equal(back.boundary, want.boundary, equal_nan=True)
    # a position made again replaces its old map
    sm.write_maps([_toy_map("P4", share=0.5)], tmp_path, settings)
    data = json.loads((tmp_path / "stability_map.json").read_text())
    assert [(m["position"], m["rock2_share"]) for m in data["maps"]] == [
        ("P1", 0.0), ("P2", 0.0), ("P4", 0.5)]
    # other settings or another grid: the old maps do not belong in the same picture
    longer = sm.MapSettings(seconds=20.0, measure=10.0)
    for k, (maps, then) in enumerate([([_toy_map("P3")], longer),
                                      ([_toy_map("P3", rpm=(25.0, 50.0))], settings)]):
        sm.write_maps([_toy_map("P1")], tmp_path / str(k), settings)
        sm.write_maps(maps, tmp_path / str(k), then)
        data = json.loads((tmp_path / str(k) / "stability_map.json").read_text())
        assert [m["position"] for m in data["maps"]] == ["P3"]
    # maps of older code do not join (the points store reruns them too)
    data = json.loads((tmp_path / "stability_map.json").read_text())
    (tmp_path / "stability_map.json").write_text(json.dumps({**data, "code": "older"}))
    sm.write_maps([_toy_map("P3")], tmp_path, settings)
    data = json.loads((tmp_path / "stability_map.json").read_text())
    assert [m["position"] for m in data["maps"]] == ["P3"]
    # another controller's maps go to their own file
    sm.write_maps([_toy_map("P4")], tmp_path, settings, "z-torque")
    assert len(json.loads((tmp_path / "stability_map.json").read_text())["maps"]) == 1


def test_results_are_stored_under_a_key_that_does_not_depend_on_dict_order() -> None:
    from drill_env.sweep import digest

    assert digest({"a": 1, "b": {"c": 2, "d": 3}}) == digest({"b": {"d": 3, "c": 2}, "a": 1})
    assert digest({"a": 1}) != digest({"a": 2})


def test_a_sweep_uses_the_workers_asked_for_not_every_core(monkeypatch) -> None:
    import os

    from drill_env.sweep import make_executor

    monkeypatch.setattr(os, "cpu_count", lambda: 64)
    executor = make_executor(2)
    try:
        assert executor.workers == 2 and executor._pool._max_workers == 2
    finally:
        executor.close()


def test_the_map_command_runs_under_a_drive_rate_controller_of_your_own(tmp_path, capsys):
    """docs/controllers.md: the map under any drive-rate controller, yours too, written
    under its table name; a policy-rate one of yours is refused, saying why."""
    import json

    from drill_cli.main import main

    gains = ('"top_drive.controller": "stiff", "top_drive.proportional_gain": 3000.0, '
             '"top_drive.integral_gain": 800.0')
    (tmp_path / "mine.py").write_text(
        "from agents import SetPointController\n\n\n"
        f"class GentlePI(SetPointController):\n    name = 'gentle-pi'\n\n"
        f"    def physics(self):\n        return {{{gains}}}\n\n\n"
        "class Chooser(GentlePI):\n    name = 'chooser'\n    rate = 'policy'\n\n\n"
        "class Acting(GentlePI):\n    name = 'acting'\n\n"
        "    def act(self, observation, info):\n        return super().act(observation, info)\n")
    args = ["stability-map", "--positions", "P1", "--rpm-step", "100", "--wob-step", "100",
            "--max-rpm", "200", "--max-wob", "200", "--seconds", "4", "--workers", "1",
            "--out", str(tmp_path / "maps")]
    assert main([*args, "--controller", f"{tmp_path / 'mine.py'}:GentlePI"]) == 0
    data = json.loads((tmp_path / "maps" / "stability_map_gentle-pi.json").read_text())
    assert data["controller"] == "gentle-pi" and len(data["maps"]) == 1
    with pytest.raises(SystemExit):
        main([*args, "--controller", f"{tmp_path / 'mine.py'}:Chooser"])
    assert "acts at the policy rate" in capsys.readouterr().err
    # a drive-rate one with an act() of its own: the map ran its physics() alone (a
    # controls engineer's walkthrough: its low-pass loop mapped as the stiff PI)
    with pytest.raises(SystemExit):
        main([*args, "--controller", f"{tmp_path / 'mine.py'}:Acting"])
    assert "has rate 'drive' but an act() of its own" in capsys.readouterr().err


def test_the_table_prints_boundaries_on_the_grid_as_they_are():
    # a 2.5 kN grid printed 22.5 and 47.5 kN as 22 and 48 (Python rounds halves to even)
    rpm = np.array([25.0, 50.0, 100.0, 150.0])
    wob = np.arange(1, 41) * 2.5e3
    boundary = np.array([22.5e3, 47.5e3, 100.0e3, math.nan])
    unstable = wob[:, None] >= np.nan_to_num(boundary, nan=math.inf)[None, :]
    m = sm.StabilityMap("P1", 0.0, rpm, wob, unstable, unstable.astype(np.int8), boundary,
                        runs=0, wall_s=0.0)
    assert "at 25/50/100/150 rpm" in sm.format_maps([m])
    assert "22.5 / 47.5 / 100 / none" in sm.format_maps([m])


def test_the_table_samples_a_grid_without_the_usual_speeds_at_its_own_speeds():
    """A 30 rpm grid printed "-" in all four 25/50/100/150 columns: the table then
    samples four of the grid's own speeds, first and last among them, and says which."""
    rpm = np.array([30.0, 60.0, 90.0, 120.0, 150.0])
    wob = np.arange(1, 11) * 10e3
    boundary = np.array([20e3, 40e3, 60e3, 80e3, math.nan])
    unstable = wob[:, None] >= np.nan_to_num(boundary, nan=math.inf)[None, :]
    m = sm.StabilityMap("P1", 0.0, rpm, wob, unstable, unstable.astype(np.int8), boundary,
                        runs=0, wall_s=0.0)
    table = sm.format_maps([m])
    assert "at 30/60/120/150 rpm" in table
    assert "20 / 40 / 80 / none" in table
    one = sm.StabilityMap("P1", 0.0, rpm[:1], wob, unstable[:, :1], unstable[:, :1].astype(np.int8),
                          boundary[:1], runs=0, wall_s=0.0)
    assert "at 30 rpm" in sm.format_maps([one]) and "   20\n" in sm.format_maps([one])


def test_the_default_workers_are_the_cores_this_process_may_use():
    """Under ``taskset -c 0`` on 2 cores the benchmark started two workers on one core
    (1.3-1.6x slower than one; an outside check): the default follows the process's CPU
    affinity, and a cgroup's CPU quota where one is set."""
    import subprocess
    import sys

    from drill_env.sweep import quota_cores

    code = ("import os; from drill_env.sweep import make_executor, usable_cores; "
            "os.sched_setaffinity(0, {min(os.sched_getaffinity(0))}); "
            "print(usable_cores(), type(make_executor(None)).__name__)")
    if hasattr(__import__("os"), "sched_setaffinity"):
        done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                              timeout=120)
        assert done.returncode == 0, done.stderr
        assert done.stdout.split() == ["1", "SerialExecutor"]
    assert quota_cores("200000 100000\n") == 2
    assert quota_cores("150000 100000") == 2  # 1.5 cores: two workers share them
    assert quota_cores("50000 100000") == 1
    assert quota_cores("max 100000") is None
    assert quota_cores("") is None
    assert quota_cores("-1 100000") is None  # cgroup v1: no quota
    assert quota_cores("100000 0") is None


def _cgroup(root, relative: str, **files: str) -> None:
    folder = root / relative
    folder.mkdir(parents=True, exist_ok=True)
    for name, text in files.items():
        (folder / name.replace("_", ".", 1)).write_text(text)


def test_a_cpu_quota_above_the_process_in_its_cgroups_caps_the_workers(tmp_path):
    """Only the cgroup mount's own cpu.max was read: right inside a container with its own
    cgroup namespace, but a job in a systemd slice or a Kubernetes pod on cgroup v1 (whose
    quota is set on the pod, above the process's cgroup) started a worker per host core.
    Fake cgroup trees: v2 with the quota on a parent, v1 CFS with it on the pod, a hybrid
    layout (v2 at unified/), and none at all."""
    from drill_env.sweep import cgroup_quota_cores

    v2 = tmp_path / "v2"
    _cgroup(v2, "", cgroup_controllers="cpu memory\n", cpu_max="max 100000\n")
    _cgroup(v2, "slice", cpu_max="300000 100000\n")  # 3 cores for the slice
    _cgroup(v2, "slice/job", cpu_max="max 100000\n")
    own = tmp_path / "own_v2"
    own.write_text("0::/slice/job\n")
    assert cgroup_quota_cores(v2, own) == 3
    _cgroup(v2, "slice/job", cpu_max="150000 100000\n")  # a tighter one below: 2
    assert cgroup_quota_cores(v2, own) == 2
    v1 = tmp_path / "v1"
    _cgroup(v1, "cpu,cpuacct/kubepods/pod1", cpu_cfs_quota_us="200000\n",
            cpu_cfs_period_us="100000\n")
    _cgroup(v1, "cpu,cpuacct/kubepods/pod1/box", cpu_cfs_quota_us="-1\n",
            cpu_cfs_period_us="100000\n")
    mine = tmp_path / "own_v1"
    mine.write_text("4:memory:/kubepods/pod1/box\n2:cpu,cpuacct:/kubepods/pod1/box\n"
                    "0::/\n")
    assert cgroup_quota_cores(v1, mine) == 2
    hybrid = tmp_path / "hybrid"  # v1 controllers, v2 at unified/ without a quota
    _cgroup(hybrid, "unified", cpu_max="max 100000\n")
    _cgroup(hybrid, "cpu", cpu_cfs_quota_us="-1\n", cpu_cfs_period_us="100000\n")
    both = tmp_path / "own_hybrid"
    both.write_text("1:cpu:/\n0::/\n")
    assert cgroup_quota_cores(hybrid, both) is None
    # a namespace: the process's path is not under this mount, the mount's root counts
    _cgroup(hybrid, "cpu", cpu_cfs_quota_us="400000\n")
    both.write_text("1:cpu:/docker/abc\n0::/docker/abc\n")
    assert cgroup_quota_cores(hybrid, both) == 4
    assert cgroup_quota_cores(tmp_path / "nothing", tmp_path / "missing") is None
    # a cgroup outside the mount's namespace (a path through ..): nothing read above the
    # mount, nor the namespace root's quota taken for it (a review)
    _cgroup(tmp_path, "", cpu_max="100000 100000\n")
    both.write_text("0::/../x\n")
    _cgroup(hybrid, "unified", cpu_max="200000 100000\n")
    assert cgroup_quota_cores(hybrid, both) is None
    # a hybrid layout's quota set on its v2 tree (unified/), none on the v1 controllers:
    # read at unified/, not at the mount's root (a mutation test: passed every case above)
    split = tmp_path / "split"
    _cgroup(split, "unified", cpu_max="200000 100000\n")
    _cgroup(split, "cpu", cpu_cfs_quota_us="-1\n", cpu_cfs_period_us="100000\n")
    both.write_text("1:cpu:/\n0::/\n")
    assert cgroup_quota_cores(split, both) == 2


def test_the_default_workers_are_the_fewer_of_the_cores_and_the_cpu_quota(monkeypatch):
    """usable_cores: the cores of the process's CPU affinity, capped by a cgroup's CPU
    quota where that allows fewer (a mutation test: the larger of the two passed every
    test, on a machine whose cgroups set no quota). Simulated: 4 cores."""
    import os

    import drill_env.sweep as sweep

    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0, 1, 2, 3}, raising=False)
    monkeypatch.setattr(os, "cpu_count", lambda: 4)
    for quota, cores in ((None, 4), (2, 2), (8, 4)):
        monkeypatch.setattr(sweep, "cgroup_quota_cores", lambda quota=quota: quota)
        assert sweep.usable_cores() == cores, quota


def _numba_threads(_: int) -> tuple[int, int]:
    """In a pool worker: numba's thread setting and its threads, after a cached kernel."""
    import numba

    from drill_env.physics.linalg import band_cholesky

    band_cholesky(np.array([[0.0, 0.0], [4.0, 4.0]]), np.zeros((2, 2)))
    return numba.config.NUMBA_NUM_THREADS, numba.get_num_threads()


def test_pool_workers_run_one_numba_thread_each() -> None:
    """The pool is the parallelism: each worker runs one numba thread. When `import
    drill_env` loaded numba, numba read NUMBA_NUM_THREADS before the worker's set-up set
    it, and every worker started a thread per core (a review)."""
    from drill_env.sweep import ProcessExecutor

    executor = ProcessExecutor(2)
    try:
        assert sorted(executor.map_unordered(_numba_threads, [0, 1])) == [
            (0, (1, 1)), (1, (1, 1))]
    finally:
        executor.close()


NUMBA_FIRST = """
import numba  # (a spawned pool worker imports this file before its set-up runs)

from drill_env.sweep import ProcessExecutor


def threads(_):
    return numba.config.NUMBA_NUM_THREADS


if __name__ == "__main__":
    executor = ProcessExecutor(1)
    try:
        print(list(executor.map_unordered(threads, [0])))
    finally:
        executor.close()
"""


def test_pool_workers_run_one_numba_thread_also_under_a_script_that_loads_numba(
        tmp_path) -> None:
    """A spawned worker imports the main script before its set-up runs: where that script
    imports numba, numba has read NUMBA_NUM_THREADS (one thread per core) by then, and
    the set-up has it read the setting again. ``import drill_env`` no longer loads numba,
    so the test above no longer reaches that reading (a mutation test: it dropped passed
    every test). (On one core numba's default is one thread either way.)"""
    import os
    import subprocess
    import sys

    script = tmp_path / "numba_first.py"
    script.write_text(NUMBA_FIRST)
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_NUM_THREADS"}
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                          env=env, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[(0, 1)]"


def test_the_picture_shades_and_marks_each_point_at_its_speed_and_wob() -> None:
    """Fig. 15: each grid point's shade sits at its (rpm, kN), darker where it sticks,
    in the colour the legend gives the stick-slip zone; the markers of the simulated
    points stand at theirs (x steady, o stick-slip)."""
    rpm, wob = np.array([40.0, 80.0, 120.0]), np.array([50e3, 100e3, 150e3])
    unstable = np.array([[False, False, False], [True, False, False], [True, True, False]])
    tested = np.array([[0, 0, 0], [1, -1, 0], [-1, 1, -1]], dtype=np.int8)
    m = sm.StabilityMap("P1", 0.0, rpm, wob, unstable, tested,
                        np.array([100e3, 150e3, np.nan]), 6, 0.1)
    fig = sm.maps_figure([m])
    ax = fig.axes[0]
    (mesh,) = ax.collections
    corners = mesh.get_coordinates()  # (n_wob + 1, n_rpm + 1, 2) cell corners
    centres = 0.25 * (corners[:-1, :-1] + corners[1:, :-1] + corners[:-1, 1:] + corners[1:, 1:])
    np.testing.assert_allclose(centres[..., 0], np.broadcast_to(rpm, (3, 3)))
    np.testing.assert_allclose(centres[..., 1], np.broadcast_to(wob[:, None] / 1e3, (3, 3)))
    np.testing.assert_array_equal(np.asarray(mesh.get_array()).reshape(3, 3), unstable)
    legend = {p.get_label(): p.get_facecolor() for p in fig.legends[0].get_patches()}
    np.testing.assert_allclose(legend["stick-slip zone (inferred)"], mesh.cmap(mesh.norm(1.0)))
    np.testing.assert_allclose(legend["steady zone (inferred)"], mesh.cmap(mesh.norm(0.0)))
    for label, verdict in (("steady", 0), ("stick-slip", 1)):
        (line,) = [line for line in ax.get_lines() if line.get_label() == label]
        drawn = set(zip(line.get_xdata().tolist(), line.get_ydata().tolist(), strict=True))
        j, i = np.nonzero(tested == verdict)
        assert drawn == set(zip(rpm[i].tolist(), (wob[j] / 1e3).tolist(), strict=True))


def test_maps_on_another_wob_grid_do_not_join_the_file(tmp_path) -> None:
    """The same speeds but other WOBs: the old maps are not of the same grid, so the
    file and picture hold the new one alone."""
    import json

    settings = sm.MapSettings(seconds=12.0, measure=10.0)
    sm.write_maps([_toy_map("P1")], tmp_path, settings)
    other = _toy_map("P3")
    other.weight_on_bit = np.array([40e3, 80e3])
    sm.write_maps([other], tmp_path, settings)
    data = json.loads((tmp_path / "stability_map.json").read_text())
    assert [m["position"] for m in data["maps"]] == ["P3"]


def test_an_interrupt_while_the_maps_are_written_leaves_the_old_file_whole(
        tmp_path, monkeypatch) -> None:
    """A Ctrl-C in the middle of writing the JSON leaves the maps already there whole: a
    torn file reads as no maps (:func:`kept_maps`), so the next positions written would
    have dropped the ones it held."""
    import pathlib

    settings = sm.MapSettings(seconds=12.0, measure=10.0)
    sm.write_maps([_toy_map("P1")], tmp_path, settings)
    before = (tmp_path / "stability_map.json").read_text()
    real = pathlib.Path.write_text

    def torn(path, text, *args, **kwargs):
        real(path, text[: len(text) // 2], *args, **kwargs)
        raise KeyboardInterrupt

    monkeypatch.setattr(pathlib.Path, "write_text", torn)
    with pytest.raises(KeyboardInterrupt):
        sm.write_maps([_toy_map("P2")], tmp_path, settings)
    monkeypatch.undo()
    assert (tmp_path / "stability_map.json").read_text() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["stability_map.json",
                                                          "stability_map.png"]


def test_a_position_in_lower_case_is_refused_with_the_one_meant():
    """``positions=["p3"]`` was refused listing the six without saying which (a fuzzing
    walkthrough: the other choices suggest)."""
    with pytest.raises(ValueError, match=r"^position: must be one of \['P1', .* got 'p3' "
                                         r"\(did you mean P3\?\)"):
        sm.stability_maps(positions=["p3"])
