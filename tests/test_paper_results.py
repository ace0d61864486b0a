"""The paper's qualitative results (section 4), reproduced by full simulations.

Each test runs the simulator for minutes of simulated time (seconds of wall time).
Windows are chosen from the rock share actually under the bit, not from hand-typed
times, so the tests follow the physics if the penetration law changes.
"""

from __future__ import annotations

import numpy as np
import pytest

from drill_env import metrics
from drill_env.physics.config import FormationConfig, SimulationConfig, SolverConfig, replace
from drill_env.physics.simulator import RECORD_CHANNELS
from drill_env.physics.units import RPM
from drill_env.scenarios import HARD, SOFT, make_scenario
from drill_env.tools.studies import (
    COL,
    Run,
    lateral_force,
    radial_displacement,
    simulate,
    stick_slip_summary,
)

pytestmark = pytest.mark.slow
#: Each paper case's gauge clearance, read from the config it runs (a copy of the number
#: would keep the thresholds below where the config moved)
GAUGE_CLEARANCE = {name: make_scenario(name).config.bit.gauge_clearance
                   for name in ("paper_case2", "paper_case4")}


def torsional(rock) -> SimulationConfig:
    return SimulationConfig(formation=FormationConfig(rocks=(rock,)),
                            solver=SolverConfig(lateral=False))


@pytest.mark.parametrize(("rock", "rpm", "stick_slip"), [
    (HARD, 50.0, True), (HARD, 100.0, False), (SOFT, 50.0, False)])
def test_stiff_top_drive_stick_slip_in_hard_rock_only_at_low_speed(rock, rpm, stick_slip):
    """Paper Fig. 13/14: 100 kN, stiff speed control; stick-slip at 50 rpm, not at 100."""
    run = simulate(torsional(rock), rpm, 100e3, 60.0)
    summary = stick_slip_summary(run, 30.0)
    if stick_slip:
        assert summary["ssi"] >= 0.8
        assert summary["stuck_fraction"] > 0.1
    else:
        assert summary["ssi"] < 0.2
        assert summary["stuck_fraction"] == 0.0


def _windows(run, rock: int = 1):
    """Masks of records before the layer, fully inside it, and after leaving it."""
    t = run.time
    share = run.share_at(t, rock)
    entered = t[share > 0.01]
    assert entered.size, "the bit never reached the middle layer"
    before = t < entered[0]
    inside = share > 0.99
    after = t > entered[-1]
    return before, inside, after


def test_stick_slip_fades_in_the_soft_layer_and_returns_after_it():
    """Paper Fig. 13/16: crossing hard-soft-hard at 50 rpm, 100 kN (torsional model)."""
    scenario = make_scenario("paper_case2", weight_on_bit=100e3, thickness=0.8, lead=0.2)
    config = replace(scenario.config, **{"solver.lateral": False})
    run = simulate(config, 50.0, 100e3, 360.0)
    before, inside, after = _windows(run)
    speed = run.channel("bit_speed")
    t = run.time

    def ssi(mask, skip=10.0):
        t0 = t[mask][0] + skip  # let the transient of the previous rock die out
        sel = mask & (t >= t0)
        return (speed[sel].max() - speed[sel].min()) / (2 * speed[sel].mean())

    assert inside.sum() > 0 and after.sum() > 0
    last_hard = before & (t > t[before][-1] - 15.0)
    assert ssi(last_hard, skip=0.0) >= 0.8
    assert ssi(inside, skip=15.0) < 0.3
    assert ssi(after) >= 0.8


@pytest.fixture(scope="module")
def case2():
    sc = make_scenario("paper_case2")
    return simulate(sc.config, 50.0, sc.weight_on_bit, 150.0)


@pytest.fixture(scope="module")
def case3():
    sc = make_scenario("paper_case3")
    return simulate(sc.config, 50.0, sc.weight_on_bit, 150.0)


def test_symmetric_bit_is_laterally_quiet_in_homogeneous_rock(case2):
    before, _, _ = _windows(case2)
    force = lateral_force(case2)[before]
    radial = radial_displacement(case2)[before]
    # The compressed BHA leans on its stabilizers (~1.6 mm clearance), no gauge contact.
    assert radial.max() < 0.5 * GAUGE_CLEARANCE["paper_case2"]
    cutting_force = HARD.mu_min * 75e3  # the smallest total cutting force, ~37 kN
    assert force.max() < 0.01 * cutting_force


def test_transition_pushes_the_symmetric_bit_toward_the_wall(case2):
    before, _, _ = _windows(case2)
    t = case2.time
    share = case2.share_at(t, 1)
    transition = (share > 0.01) & (share < 0.99)
    force = lateral_force(case2)
    radial = radial_displacement(case2)
    assert force[transition].max() >= 10 * max(force[before].max(), 1.0)
    # the orbit reaches the wall
    assert radial[transition].max() > 0.8 * GAUGE_CLEARANCE["paper_case2"]


def test_very_soft_layer_gives_a_larger_lateral_force_peak(case2, case3):
    """Peak level = 95th percentile of the lateral force over the transition.

    The single largest sample is one wall impact of a chaotic orbit: it changed order
    between the cases under round-off-level changes of the kernel (with the wall
    contact's first damping case 2's spanned 37-65 kN across initial kicks of 0.5-3 %;
    with today's, 9-13 kN against case 3's 11 kN), while the 95th percentile keeps case
    3 above case 2 at every kick (docs/paper-reproduction.md). The paper has case 3's
    peaks larger too: that part is not reproduced. Held at each kick of 0.5-3 % (0.5 %
    apart) with a margin, 5 % (measured 10-29 %), not merely above (a review of the
    tests: one kick, and 0.1 % would have passed).
    """
    def peak(run):
        share = run.share_at(run.time, 1)
        transition = (share > 0.01) & (share < 0.99)
        return np.percentile(lateral_force(run)[transition], 95)

    assert peak(case3) > 1.05 * peak(case2)  # the fixtures' kick, 1 %
    for kick in (0.005, 0.015, 0.02, 0.025, 0.03):
        soft, very_soft = (make_scenario(name) for name in ("paper_case2", "paper_case3"))
        runs = [simulate(sc.config, 50.0, sc.weight_on_bit, 150.0, kick=kick)
                for sc in (soft, very_soft)]
        assert peak(runs[1]) > 1.05 * peak(runs[0]), kick


def test_asymmetric_bit_whirls_forward_for_most_of_the_run():
    sc = make_scenario("paper_case4")
    run = simulate(sc.config, 50.0, sc.weight_on_bit, 120.0)
    late = run.time > 5.0
    whirl = run.channel("whirl_speed")[late]
    rotation = run.channel("bit_speed")[late]
    radial = radial_displacement(run)[late]
    moving = (np.abs(rotation) > 0.1) & (radial > 0.1 * GAUGE_CLEARANCE["paper_case4"])
    forward = np.sign(whirl[moving]) == np.sign(rotation[moving])
    assert moving.mean() > 0.5
    assert forward.mean() > 0.6
    assert lateral_force(run)[late].min() > 100.0  # a lateral force all the time
    # as the metrics, the benchmark and task 2 count it: most of the time whirling
    # forward, never backward (the per-sample rule to 2026-12-05 read the bit's rattle on
    # the wall while stuck as 17 % backward whirl at 60 rpm)
    from drill_env.metrics import whirl_signs

    time = run.time[late]
    signs = whirl_signs(radial / GAUGE_CLEARANCE["paper_case4"], whirl, rotation,
                        time[1] - time[0])
    assert np.mean(signs > 0) > 0.6 and not (signs < 0).any()


def test_symmetric_bit_settles_after_the_layer_and_stick_slip_returns():
    """Paper Fig. 17/18, P6: after the transition threw it against the wall, the symmetric
    bit is laterally quiet again in homogeneous rock, and the stick-slip of the hard rock
    returns (Fig. 16). Needs the stabilizers' wall impacts damped as through a mud film
    (ContactConfig.damping, docs/paper-reproduction.md); with a restitution of 0.8 a
    backward whirl of the stabilizers kept the bit on the wall."""
    for case, kick in (("paper_case2", 0.01), ("paper_case2", 0.03), ("paper_case3", 0.01)):
        sc = make_scenario(case)
        run = simulate(sc.config, 50.0, sc.weight_on_bit, 200.0, kick=kick)
        _, _, after = _windows(run)
        t = run.time
        late = after & (t > t[after][0] + 40.0)
        assert late.sum() > 100, case
        assert lateral_force(run)[late].mean() < 100.0, case  # N: no contact, no whirl
        summary = stick_slip_summary(run, t[after][0] + 10.0)
        assert summary["ssi"] > 0.8 and summary["stuck_fraction"] > 0.1, case


# --------------------------------------------------------------------------- the study helpers
# (short runs and hand-made records: seconds, not minutes; found unchecked by a mutation
# round of drill_env/tools/studies.py, 2026-12-07)


def test_a_study_run_records_evenly_up_to_its_duration():
    """``simulate`` advances in chunks of whole record intervals (a chunk of 0.1 s is not
    a multiple of 7 steps) and stops at the duration asked for: records every 7 steps,
    the last at or before 0.5 s; the rock shares once per chunk (49 steps), at its end."""
    config = torsional(HARD)
    run = simulate(config, 50.0, 100e3, 0.5, record_every=7, chunk_seconds=0.1)
    dt = run.time[0] / 7
    steps = round(0.5 / dt)
    assert run.records.shape == (steps // 7, len(RECORD_CHANNELS))
    np.testing.assert_allclose(np.diff(run.time), 7 * dt, rtol=1e-9)
    assert run.share_time[-1] == pytest.approx(steps * dt, rel=1e-12)
    np.testing.assert_allclose(np.diff(run.share_time[:-1]), 49 * dt, rtol=1e-9)
    assert run.shares.shape == (run.share_time.size, 1)
    assert run.status == ""


def test_a_study_run_starts_with_its_kick_and_stops_with_the_simulators_reason():
    """Steady drilling is an equilibrium the kick (here 20 % of the bit's speed) tests:
    without it the bit keeps its speed, with it the bit swings. A kick of -1e3 (the bit
    at ~5,000 rad/s, past the runaway limit of 1e3 rad/s) stops the run at once: the
    reason in ``status``, no record, no chunk run after it."""
    config = torsional(HARD)
    steady = simulate(config, 50.0, 100e3, 0.2, record_every=1, kick=0.0)
    kicked = simulate(config, 50.0, 100e3, 0.2, record_every=1, kick=0.2)
    np.testing.assert_allclose(steady.channel("bit_speed"), 50 * RPM, rtol=1e-3)
    assert np.abs(kicked.channel("bit_speed") - 50 * RPM).max() > 0.05 * 50 * RPM
    stopped = simulate(config, 50.0, 100e3, 2.0, kick=-1e3, chunk_seconds=0.1)
    assert stopped.status.startswith("simulation diverged")
    assert stopped.share_time.size == 1 and stopped.records.shape[0] == 0


def test_the_study_helpers_read_their_channels_and_windows():
    """Windows are half-open [t0, t1); rock shares are interpolated per rock; the lateral
    force and displacement are the x-y magnitudes; the stick-slip summary reads the bit
    speed, not the surface's."""
    t = np.arange(1, 9) * 0.5
    records = np.zeros((t.size, len(RECORD_CHANNELS)))
    records[:, COL["time"]] = t
    bit_speed = np.array([5.0, 0.0, 0.0, 9.0, 5.0, 0.0, 0.0, 9.0])
    records[:, COL["bit_speed"]] = bit_speed
    records[:, COL["surface_speed"]] = 5.0
    records[:, COL["bit_force_x"]], records[:, COL["bit_force_y"]] = 3.0, -4.0
    records[:, COL["bit_x"]], records[:, COL["bit_y"]] = -6e-3, 8e-3
    shares = np.array([[1.0, 0.0], [0.0, 1.0]])
    run = Run(torsional(HARD), records, np.array([0.0, 4.0]), shares, "")
    np.testing.assert_array_equal(run.window(1.0, 2.5)[:, COL["time"]], [1.0, 1.5, 2.0])
    np.testing.assert_array_equal(run.window(3.5)[:, COL["time"]], [3.5, 4.0])
    np.testing.assert_allclose(run.share_at(np.array([1.0, 3.0]), 1), [0.25, 0.75])
    np.testing.assert_allclose(lateral_force(run), 5.0)
    np.testing.assert_allclose(radial_displacement(run), 1e-2)
    summary = stick_slip_summary(run, 1.0, 3.0)
    window = bit_speed[1:5]
    assert summary == {"ssi": metrics.stick_slip_severity(window),
                       "stuck_fraction": metrics.stuck_fraction(window)}
    assert summary["ssi"] > 0.5 and summary["stuck_fraction"] == 0.5
