"""Simulator readings (one compiled readout) against the properties and closed forms."""

from __future__ import annotations

import math

import numpy as np
import pytest

from drill_env.physics.config import SimulationConfig, replace
from drill_env.physics.layout import N_READINGS, READ, READINGS, S, Status
from drill_env.physics.readings import whirl_speed
from drill_env.physics.simulator import OperatingPoint, Simulator
from drill_env.physics.units import RPM


def whirling(bit_model: str) -> Simulator:
    """A default string one step after its bit was pushed into the wall."""
    sim = Simulator(replace(SimulationConfig(), bit_model=bit_model))
    sim.reset(OperatingPoint(60 * RPM, 80e3))
    sim.ul[-2] = [1.2 * sim.config.bit.gauge_clearance, 0.0]  # kick the bit into the wall
    sim.advance(1, 60 * RPM, sim.hook_load_for(80e3))
    return sim


@pytest.mark.parametrize("bit_model", ["mesoscopic", "macroscopic"])
def test_readings_are_the_simulator_properties(bit_model):
    sim = whirling(bit_model)
    r = dict(zip(READINGS, sim.read().tolist(), strict=False))
    assert np.hypot(r["bit_x"], r["bit_y"]) > 0.0 and r["max_contact_force"] > 0.0
    for name in ("time", "depth", "bit_speed", "surface_speed", "torque_on_bit",
                 "surface_torque", "weight_on_bit", "hook_load", "rop"):
        assert r[name] == getattr(sim, name), name  # copies of the same state values
    # computed twice (compiled readout, Python property): equal to round-off
    assert r["whirl_speed"] == pytest.approx(sim.whirl_speed, rel=1e-14)
    assert [r["bit_x"], r["bit_y"]] == sim.bit_lateral.tolist()
    assert [r["bit_vx"], r["bit_vy"]] == sim.bit_lateral_velocity.tolist()
    assert [r["bit_force_x"], r["bit_force_y"]] == sim.bit_lateral_force.tolist()
    assert r["max_contact_force"] == sim.contact_forces.max()
    assert r["status"] == sim.status == 0
    shares = sim.readings[N_READINGS:]
    np.testing.assert_array_equal(shares, sim.rock_share)
    assert shares.sum() == pytest.approx(1.0)


def test_the_largest_wall_force_reading_is_the_propertys_at_every_node_and_nan():
    """The readings are the properties' values (module docstring): whichever node bears
    the largest wall force, the reading is ``contact_forces.max()``, and a NaN among the
    forces (a diverging step) reads NaN as numpy's max does."""
    sim = whirling("mesoscopic")
    forces = sim.node_force.copy()
    for k in range(forces.shape[0] - 1):  # the bit's node shows its gauge force instead
        sim.node_force[k] = 1e9
        assert sim.read()[READ.MAX_CONTACT_FORCE] == sim.contact_forces.max() == 1e9, k
        sim.node_force[k] = forces[k]
    sim.node_force[3] = math.nan
    assert math.isnan(sim.contact_forces.max())
    assert math.isnan(sim.read()[READ.MAX_CONTACT_FORCE])


def test_the_rock_share_reading_follows_the_bit_not_the_top_drive():
    """Two rocks, an interface dipping 30 degrees that crosses the axis 2 cm below the bit
    face (off the bit's centre: a symmetric bit's share through the centre is 1/2 at
    every angle), the top turned 1.7 rad further than the settled twist (top and bit
    ~5 rad apart): the readout's shares are the
    blades' at the bit's angle (the property), not at the top drive's."""
    from drill_env.physics.config import FormationConfig, Interface, RockConfig

    base = SimulationConfig()
    depth = base.initial_depth if base.initial_depth is not None else base.string.length
    formation = FormationConfig(rocks=(RockConfig(), RockConfig(mu_max=1.0)),
                                interfaces=(Interface(depth + 0.02, 30.0, 0.0),),
                                layers=(0, 1))
    sim = Simulator(replace(base, formation=formation, bit_model="mesoscopic"))
    sim.reset(OperatingPoint(60 * RPM, 80e3))
    hook = sim.hook_load_for(80e3)
    sim.advance(10, 60 * RPM, hook)
    sim.ut[0] += 1.7  # the top turned ahead of the bit
    sim.advance(1, 60 * RPM, hook)
    shares = sim.read()[N_READINGS:].copy()
    np.testing.assert_array_equal(shares, sim.rock_share)
    assert 0.05 < shares[1] < 0.95  # both rocks under the blades
    sim.ut[-1] = sim.ut[0]  # the blades where the top drive points: other shares
    assert abs(sim.rock_share[1] - shares[1]) > 0.02


def test_advance_with_read_is_advance_then_read():
    a, b = whirling("mesoscopic"), whirling("mesoscopic")
    ra = a.advance(100, 70 * RPM, a.hook_load_for(90e3), 10, read=True)
    rb = b.advance(100, 70 * RPM, b.hook_load_for(90e3), 10)
    np.testing.assert_array_equal(ra, rb)
    np.testing.assert_array_equal(a.state, b.state)
    np.testing.assert_array_equal(a.readings, b.read())


def test_reset_leaves_fresh_readings():
    sim = Simulator(SimulationConfig())
    sim.reset(OperatingPoint(90 * RPM, 50e3))
    assert sim.readings[READ.BIT_SPEED] == pytest.approx(90 * RPM)
    assert sim.readings[READ.WEIGHT_ON_BIT] == 50e3
    assert sim.readings[READ.TIME] == 0.0


def test_a_stopped_simulator_reads_nan_rock_shares():
    sim = whirling("mesoscopic")
    sim.state[S.STATUS] = Status.NONFINITE
    readings = sim.read()
    assert readings[READ.STATUS] == Status.NONFINITE
    assert np.isnan(readings[N_READINGS:]).all()


def test_whirl_speed_of_a_circular_orbit_is_its_angular_speed():
    """x = r cos(Wt), y = r sin(Wt): (x vy - vx y) / r^2 = W, either direction."""
    r = 2e-3
    for omega in (5.0, -3.0):
        for t in np.linspace(0.0, 1.0, 7):
            x, y = r * math.cos(omega * t), r * math.sin(omega * t)
            vx, vy = -r * omega * math.sin(omega * t), r * omega * math.cos(omega * t)
            assert whirl_speed(x, y, vx, vy) == pytest.approx(omega, rel=1e-12)
    assert whirl_speed(0.0, 0.0, 1.0, 1.0) == 0.0  # centred: no direction
