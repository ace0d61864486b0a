"""The ROP law against kinematics: the bit advances its depth of cut per revolution.

Independent of the integrator's bookkeeping: the depth drilled over a run must equal
``d(W) x (bit angle turned) / 2 pi``, where ``d(W)`` is the rock's depth of cut per
newton times the WOB acting on it (the WOB itself up to the founder point W_f, then
``W_f - s (W - W_f)``, Dupriest & Koederitz 2005; docs/model.md, "Penetration"). A bit
that sticks does not advance. The bit angle comes from the Newmark displacement (the
trapezoid of the speed), the depth from the per-step ROP: the two differ by O(omega dt)
at the ends of the run, ~1e-5 of the angle here.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from drill_env.physics.config import SimulationConfig, replace
from drill_env.physics.layout import R
from drill_env.physics.simulator import OperatingPoint, Simulator

RPM = 2.0 * math.pi / 60.0


def drill(rpm: float, wob: float, seconds: float, **overrides) -> tuple[Simulator, float, float,
                                                                        np.ndarray]:
    """Torsion only, homogeneous rock, from the settled state with a 2 % kick: the
    simulator, the depth drilled, the bit angle turned and the records."""
    config = replace(SimulationConfig(), **{"solver.lateral": False, **overrides})
    sim = Simulator(config)
    sim.reset(OperatingPoint(rpm * RPM, wob))
    sim.vt[-1] *= 0.98
    depth0, angle0 = sim.depth, sim.bit_angle
    records = sim.advance(round(seconds / sim.dt), rpm * RPM, sim.hook_load_for(wob), 1)
    return sim, sim.depth - depth0, sim.bit_angle - angle0, records


@pytest.mark.parametrize("rpm", [50.0, 120.0])  # stick-slip, steady rotation
def test_depth_drilled_is_depth_of_cut_per_revolution(rpm):
    wob = 100e3
    sim, drilled, turned, records = drill(rpm, wob, 20.0)
    rock = SimulationConfig().formation.rocks[0]
    assert turned > 2.0 * math.pi * 5  # several revolutions
    expected = rock.depth_of_cut * wob * turned / (2.0 * math.pi)
    assert drilled == pytest.approx(expected, rel=1e-3)
    assert records[:, R.ROP].min() >= 0.0  # never drills upward


def test_the_settled_start_reads_the_rop_of_its_depth_of_cut():
    """The ROP an env observes at reset, before any step: depth of cut per revolution
    times revolutions per second, d W omega / (2 pi) (one rock, below its founder
    point); one step later the kernel's own ROP is the same to 1e-3."""
    rpm, wob = 120.0, 100e3
    sim = Simulator(replace(SimulationConfig(), **{"solver.lateral": False}))
    sim.reset(OperatingPoint(rpm * RPM, wob))
    rock = SimulationConfig().formation.rocks[0]
    expected = rock.depth_of_cut * wob * rpm * RPM / (2.0 * math.pi)
    assert sim.rop == pytest.approx(expected, rel=1e-9)
    sim.advance(1, rpm * RPM, sim.hook_load_for(wob))
    assert sim.rop == pytest.approx(expected, rel=1e-3)


def test_a_stuck_bit_does_not_advance():
    sim, _, _, records = drill(50.0, 100e3, 20.0)
    stuck = np.abs(records[:, R.BIT_SPEED]) < 1e-6  # rad/s; a stuck bit creeps at ~1e-12
    assert stuck.mean() > 0.1  # the hard rock at 50 rpm stick-slips
    assert records[stuck, R.ROP].max() < 1e-12  # m/s: 0.1 um per day


def test_above_the_founder_point_the_depth_of_cut_falls_with_wob():
    """W = 100 kN past W_f = 80 kN with slope 0.5: the rock sees 80 - 0.5 x 20 = 70 kN."""
    diameter = SimulationConfig().bit.diameter
    founder = {"formation.rocks[0].founder_wob_per_diameter": 80e3 / diameter,
               "formation.rocks[0].post_founder_slope": 0.5}
    rock = SimulationConfig().formation.rocks[0]
    _, drilled, turned, _ = drill(120.0, 100e3, 10.0, **founder)
    assert drilled == pytest.approx(rock.depth_of_cut * 70e3 * turned / (2.0 * math.pi),
                                    rel=1e-3)
