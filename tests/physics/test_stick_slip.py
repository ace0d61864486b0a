"""Stick-slip onset: simulation against linear stability of the assembled system.

The threshold comes from the eigenvalues of the linearised torsional dynamics
(scipy, :mod:`drill_env.physics.stability`), not from the time integrator, so the test
checks the integrator and the bit's stick model against an independent prediction.
"""

from __future__ import annotations

import numpy as np
import pytest

from drill_env.physics.config import (
    INCH,
    FormationConfig,
    RockConfig,
    Section,
    SimulationConfig,
    SolverConfig,
    StringConfig,
)
from drill_env.physics.simulator import OperatingPoint, Simulator
from drill_env.physics.stability import stick_slip_threshold, torsional_growth_rate
from drill_env.physics.units import RPM

WOB = 80e3
ROCK = RockConfig(name="falling", mu_min=0.5, mu_max=0.9, st1=3.0)


def simple_config() -> SimulationConfig:
    string = StringConfig(
        drill_pipe=Section(length=600.0, outer_diameter=5 * INCH, inner_diameter=4.276 * INCH,
                           element_length=20.0),
        bha=Section(length=30.0, outer_diameter=6.5 * INCH, inner_diameter=2.8125 * INCH,
                    element_length=3.0),
        stabilizers=(),
    )
    return SimulationConfig(string=string, bit_model="macroscopic",
                            formation=FormationConfig(rocks=(ROCK,)),
                            solver=SolverConfig(lateral=False))


def run_from_steady(sim: Simulator, omega: float, seconds: float) -> np.ndarray:
    sim.reset(OperatingPoint(omega, WOB))
    sim.vt[-1] *= 0.99  # a 1 % kick of the bit speed
    return sim.run(seconds, omega, sim.hook_load_for(WOB), record_every=10)


@pytest.fixture(scope="module")
def sim_and_threshold():
    sim = Simulator(simple_config())
    return sim, stick_slip_threshold(sim, WOB)


def test_threshold_lies_in_the_operating_range(sim_and_threshold):
    _, threshold = sim_and_threshold
    assert 20 * RPM < threshold < 200 * RPM


def test_resistance_slope_is_the_derivative_of_the_resistance_curve():
    # central differences of eq. (39) as the bit oracle writes it; the curve is smooth
    # for omega > 0, so h = 1e-5 rad/s leaves an error ~ h^2 (third derivative) + eps / h
    from drill_env.physics.bit_reference import mu_curve
    from drill_env.physics.stability import resistance_slope

    h = 1e-5
    for args in ((0.5, 0.9, 3.0, 0.0), (0.3, 0.45, 5.0, 0.005), (0.4, 1.2, 0.7, 0.02)):
        for omega in (0.1, 1.0, 3.0, 10.0, 40.0):
            fd = (mu_curve(omega + h, *args) - mu_curve(omega - h, *args)) / (2.0 * h)
            assert resistance_slope(omega, *args) == pytest.approx(fd, abs=1e-9)


def _two_inertias(j_top: float, j_bit: float, k: float, b: float, c: tuple[float, float],
                  kp: float, ki: float, rock: tuple[float, float, float, float]):
    """The attributes :func:`torsional_growth_rate` reads, for a top-drive inertia and a
    bit inertia joined by one spring ``k`` (stiffness-proportional damping ``b k``)."""
    from types import SimpleNamespace

    from drill_env.physics.formation import N_ROCK_PARAMS, Rock

    params = np.zeros((1, N_ROCK_PARAMS))
    for col, value in zip((Rock.MU_MIN, Rock.MU_MAX, Rock.ST1, Rock.ST2), rock, strict=True):
        params[0, col] = value
    return SimpleNamespace(
        tor_k=np.array([[k, k], [-k, 0.0]]),  # band storage: diagonal, then off-diagonal
        tor_c=np.array(c), tor_m=np.array([j_top, j_bit]), top_drive_gains=(kp, ki),
        config=SimpleNamespace(damping=SimpleNamespace(stiffness_proportional=b)),
        rock_params=params, lever_arm=0.05)


def test_growth_rate_is_the_largest_root_of_the_two_inertia_characteristic_polynomial():
    """det(M s^2 + C s + K) of two inertias on a spring, the PI top drive on the first
    (kp damping, ki stiffness) and the bit's c_bit = a W mu'(omega) on the second, expanded
    by hand: its roots, by numpy.roots, against the eigenvalues of the assembled system."""
    from drill_env.physics.bit_reference import mu_curve

    j_top, j_bit, k, b, c = 2500.0, 30.0, 700.0, 0.002, (1.0, 4.0)
    kp, ki, rock = 900.0, 100.0, (0.5, 0.9, 3.0, 0.0)
    sim = _two_inertias(j_top, j_bit, k, b, c, kp, ki, rock)
    signs = set()
    for omega, wob in ((0.5, 80e3), (2.0, 80e3), (6.0, 40e3), (20.0, 150e3)):
        h = 1e-6
        c_bit = sim.lever_arm * wob * (mu_curve(omega + h, *rock)
                                       - mu_curve(omega - h, *rock)) / (2.0 * h)
        p_top = np.array([j_top, b * k + c[0] + kp, k + ki])  # s^2, s, 1
        p_bit = np.array([j_bit, b * k + c[1] + c_bit, k])
        coupling = np.array([b * k, k])  # -(b k s + k) off the diagonal
        det = np.polysub(np.polymul(p_top, p_bit), np.polymul(coupling, coupling))
        expected = max(np.roots(det).real)
        # simple roots: both eigen-solvers are accurate to ~eps |s| (the finite-difference
        # c_bit to ~1e-9 relative)
        got = torsional_growth_rate(sim, omega, wob)
        assert got == pytest.approx(expected, rel=1e-6, abs=1e-9)
        signs.add(got > 0.0)
    assert signs == {True, False}  # both sides of the threshold are exercised


@pytest.mark.parametrize("rock, expected", [
    ((0.6, 0.6, 3.0, 0.0), "stable"),  # a flat curve: the bit adds no negative damping
    ((0.6, 0.6, 3.0, 0.01), "stable"),  # rising: positive damping
    ((0.1, 2.0, 100.0, 0.0), "unstable"),  # falling over the whole range
])
def test_the_threshold_at_the_ends_of_its_range(rock, expected):
    """Two inertias on a damped spring with a PI drive and a bit whose curve does not fall
    (mu' >= 0) form a passive, positively damped chain: asymptotically stable at every
    speed, so the threshold is the range's low end ("stable everywhere"); a curve that
    falls steeply everywhere: its high end."""
    sim = _two_inertias(2500.0, 30.0, 700.0, 0.002, (1.0, 4.0), 900.0, 100.0, rock)
    low, high = 0.05, 60.0
    growth = [torsional_growth_rate(sim, w, 80e3) for w in (low, 1.0, 10.0, high)]
    if expected == "stable":
        assert max(growth) < 0.0
        assert stick_slip_threshold(sim, 80e3, omega_range=(low, high)) == low
    else:
        assert min(growth) > 0.0
        assert stick_slip_threshold(sim, 80e3, omega_range=(low, high)) == high


def test_growth_rate_changes_sign_at_the_threshold(sim_and_threshold):
    sim, threshold = sim_and_threshold
    assert torsional_growth_rate(sim, 0.8 * threshold, WOB) > 0
    assert torsional_growth_rate(sim, 1.2 * threshold, WOB) < 0


def test_below_threshold_steady_rotation_turns_into_stick_slip(sim_and_threshold):
    sim, threshold = sim_and_threshold
    rec = run_from_steady(sim, 0.8 * threshold, 60.0)
    late = rec[rec[:, 0] > 30.0]
    bit_speed = late[:, 1]
    ssi = (bit_speed.max() - bit_speed.min()) / (2 * bit_speed.mean())
    stuck = np.abs(bit_speed) < 1 * RPM
    assert ssi > 0.8
    # Stick phases last: the bit rests below 1 rpm for a measurable share of the time,
    # in phases of more than 0.1 s each.
    assert stuck.mean() > 0.05
    dt_rec = late[1, 0] - late[0, 0]
    runs = np.diff(np.flatnonzero(np.diff(np.concatenate(([0], stuck.astype(int), [0])))))[::2]
    assert runs.max() * dt_rec > 0.1


def test_above_threshold_a_perturbation_decays(sim_and_threshold):
    sim, threshold = sim_and_threshold
    rec = run_from_steady(sim, 1.2 * threshold, 60.0)
    early = rec[rec[:, 0] < 5.0, 1]
    late = rec[rec[:, 0] > 50.0, 1]
    assert np.ptp(late) < 0.2 * np.ptp(early)
    assert np.all(np.abs(rec[:, 1]) > 1 * RPM)


def _stick_runs(stuck: np.ndarray) -> list[tuple[int, int]]:
    """(first, end) sample of each run of consecutive stuck samples."""
    edges = np.flatnonzero(np.diff(np.concatenate(([0], stuck.astype(int), [0]))))
    return list(zip(edges[0::2].tolist(), edges[1::2].tolist(), strict=True))


def test_a_held_bit_holds_one_torque_not_one_that_alternates_each_step(sim_and_threshold):
    """With the average-acceleration rule a node stopped at the end of a step (v = 0)
    keeps an acceleration -a that flips sign every step, and so did the torque holding
    the stuck bit: on this string +-272 N m (6 % of the static torque) at the step
    frequency, the stuck flag flickering (32 stick runs in 20 cycles). Held at rest with
    no acceleration, as the soft-string path holds its stuck nodes, the bit sticks once
    per cycle and its torque winds up smoothly. Every step is recorded (an even
    record_every samples one phase of a period-2 signal and hides it)."""
    sim, threshold = sim_and_threshold
    omega = 0.6 * threshold
    sim.reset(OperatingPoint(omega, WOB))
    sim.vt[-1] *= 0.99
    rec = sim.run(40.0, omega, sim.hook_load_for(WOB), record_every=1)
    late = rec[rec[:, 0] > 20.0]
    runs = [(a, b) for a, b in _stick_runs(late[:, 15] > 0) if b - a > 10]
    speed = late[:, 1]
    cycles = np.count_nonzero(np.diff((speed > 0.5 * speed.max()).astype(int)) == 1)
    assert cycles >= 5
    assert abs(len(_stick_runs(late[:, 15] > 0)) - cycles) <= 1
    tob = late[:, 3]
    static = np.abs(tob).max()
    for a, b in runs:
        # the amplitude of the step-frequency zigzag c (-1)^k: the second difference
        # turns it into 4 c (-1)^k and the smooth wind-up into a slowly varying curve,
        # which averages out against (-1)^k (0.3 N m here; 204 N m with the zigzag)
        d2 = np.diff(tob[a:b], 2)
        zigzag = abs(np.mean(d2 * (-1.0) ** np.arange(len(d2)))) / 4.0
        assert zigzag < 0.005 * static, (a, zigzag)


def test_stuck_bit_really_stops_while_torque_builds(sim_and_threshold):
    sim, threshold = sim_and_threshold
    rec = run_from_steady(sim, 0.6 * threshold, 40.0)
    late = rec[rec[:, 0] > 20.0]
    stuck = late[:, 15] > 0
    assert stuck.any()
    assert np.all(np.abs(late[stuck, 1]) < 1e-6)  # exactly at rest, not creeping
    tob = late[stuck, 3]
    assert np.ptp(tob) > 0.2 * np.abs(tob).max()  # torque on bit builds during a stick
