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


def test_stuck_bit_really_stops_while_torque_builds(sim_and_threshold):
    sim, threshold = sim_and_threshold
    rec = run_from_steady(sim, 0.6 * threshold, 40.0)
    late = rec[rec[:, 0] > 20.0]
    stuck = late[:, 15] > 0
    assert stuck.any()
    assert np.all(np.abs(late[stuck, 1]) < 1e-6)  # exactly at rest, not creeping
    tob = late[stuck, 3]
    assert np.ptp(tob) > 0.2 * np.abs(tob).max()  # torque on bit builds during a stick
