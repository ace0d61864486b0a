"""The settled start in a curved hole: the string at rest on the wall, the wall's
friction in the static twist (drill_env/physics/settle.py).

Started on the hole's axis, the string fell onto the wall and met friction the twist did
not hold: the bit stalled within half a second at any speed (a drilling engineer's
walkthrough), and the stall left stick-slip cycles a settled string does not start."""

from __future__ import annotations

from contextlib import nullcontext
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import minimize

from drill_env.physics.layout import READINGS, RECORD_CHANNELS, P
from drill_env.physics.simulator import OperatingPoint, Simulator
from drill_env.physics.string_friction import wall_friction_coefficient
from drill_env.physics.units import RPM
from drill_env.scenarios import make_scenario, with_physics

TORQUE = READINGS.index("surface_torque")


@pytest.mark.parametrize("name", ["j_shaped", "lateral_60", "s_shaped"])
def test_a_settled_start_in_a_curved_hole_is_at_rest(name):
    """The settled state is an equilibrium of the kernel's own dynamics: over 2 s neither
    the bit's speed nor any lateral displacement moves, at a low speed and high WOB
    (where the stall stuck the bit) and at the scenario's operating point."""
    sim = Simulator(make_scenario(name).config)
    for rpm, wob in [(30.0, 100e3), (100.0, 100e3), (250.0, 20e3)]:
        sim.reset(OperatingPoint(rpm * RPM, wob))
        assert sim.settle_share == 1.0  # with all of the friction
        start = sim.ul.copy()
        assert np.max(np.hypot(start[0::2, 0], start[0::2, 1])) > 0.01  # on the wall
        record = sim.run(2.0, record_every=10)
        bit = record[:, RECORD_CHANNELS.index("bit_speed")] / RPM
        assert np.max(np.abs(bit - rpm)) < 1e-6 * rpm, (rpm, wob)
        assert np.max(np.abs(sim.ul - start)) < 1e-6, (rpm, wob)  # m


def _slant(inclination: float) -> Simulator:
    """The default string in a straight hole inclined ``inclination`` degrees from the
    surface down."""
    config = make_scenario("default").config
    depth = config.string.length + 100.0
    return Simulator(with_physics(config, {"well.md": (0.0, depth),
                                           "well.inclination": (inclination, inclination),
                                           "well.azimuth": (0.0, 0.0)}))


@pytest.mark.parametrize("inclination", [10.0, 30.0, 60.0])
def test_the_wall_torque_of_a_slant_hole_is_the_soft_string_torque(inclination):
    """Johancsik et al. (1984) in a straight inclined hole: each length of string lies
    on the low side with its weight across the hole, ``w L sin i``, and rubs
    ``mu(R omega) R w L sin i`` off the rotation. The settled FE string carries that
    torque to within 5 %. Two things move it, each checked: turning, the string climbs
    the wall until friction balances its weight, so the wall carries
    ``w L sin i / sqrt(1 + mu^2)`` (3 % less); and between the stabilizers the stiff
    collars lift off the wall, so the stabilizers' larger radius carries their weight
    (6-8 % more torque per newton)."""
    omega, wob = 100.0 * RPM, 50e3
    vertical = Simulator(make_scenario("default").config)
    vertical.reset(OperatingPoint(omega, wob))
    sim = _slant(inclination)
    sim.reset(OperatingPoint(omega, wob))
    p = sim.params
    # by hand: each node carries half of each element beside it (buoyed weight per
    # length times length; the bit hangs on the last), sin i of it across the hole
    length = np.diff(sim.mesh.node_depth)
    element = sim.mesh.buoyed_weight * length
    lumped = 0.5 * (np.concatenate([[0.0], element]) + np.concatenate([element, [0.0]]))
    across = lumped * np.sin(np.radians(inclination))
    mu = np.array([wall_friction_coefficient(omega * r, p[P.MU_STATIC], p[P.MU_KINETIC],
                                             p[P.MU_DECAY]) for r in sim.node_radius])
    # over the contact nodes: the top node is held on the axis, the bit's torque is the
    # bit model's
    closed = float(np.sum((mu * sim.node_radius * across)[1:-1]))
    wall = sim.readings[TORQUE] - vertical.readings[TORQUE]
    assert 1.0 < wall / closed < 1.05, wall / closed
    climbed = float(np.sum((across / np.sqrt(1.0 + mu * mu))[1:-1]))
    assert sim.node_force[1:-1].sum() == pytest.approx(climbed, rel=0.015)
    force, radius, soft = sim.node_force[1:-1], sim.node_radius[1:-1], across[1:-1]
    arm = float(np.sum(force * radius) / np.sum(force))
    assert 1.05 < arm / float(np.sum(soft * radius) / np.sum(soft)) < 1.09


def test_the_wall_of_the_rest_state_is_the_kernels_wall_contact_at_rest():
    """settle.Wall is the kernel's contact law (integrator.wall_contact) at zero lateral
    speed: the penalty normal force, friction at the slip R omega regularised linearly
    below P.V_REG and capped at |v_r| / compliance. Node by node on the string's contact
    nodes (the bit node is the bit model's), turning slower and faster than V_REG."""
    from drill_env.physics.integrator import wall_contact
    from drill_env.physics.layout import CONTACT
    from drill_env.physics.settle import Wall

    sim = _slant(30.0)
    p = sim.params
    n = sim.ut.shape[0]
    nodes = np.array([k for k in range(sim.lateral_start + 1, n - 1)
                      if sim.node_contact[k] != 0.0])
    clearance, radius = sim.node_clearance[nodes], sim.node_radius[nodes]
    angle = 0.7
    x = (clearance + 1e-5) * np.cos(angle)  # 0.1 mm into the wall: small normal forces,
    y = (clearance + 1e-5) * np.sin(angle)  # whose friction stays below the cap
    slow = 0.2 * p[P.V_REG] / radius.max()
    for omega in (slow, 100.0 * RPM):
        wall = Wall(sim, nodes, omega)
        force, _ = wall.forces(x, y)
        out = np.zeros(len(CONTACT))
        for m, k in enumerate(nodes):
            wall_contact(x[m], y[m], 0.0, 0.0, omega, clearance[m], radius[m], p,
                         sim.compliance[k], out)
            np.testing.assert_allclose(force[m], out[[CONTACT.FX, CONTACT.FY]], rtol=1e-12)
            assert wall.normal[m] == pytest.approx(out[CONTACT.NORMAL], rel=1e-12)
            assert wall.torque[m] == pytest.approx(out[CONTACT.MZ], rel=1e-12)
        assert np.all(wall.torque < 0.0)  # friction against the rotation


def test_the_rest_state_is_the_energy_minimum_an_independent_optimiser_finds():
    """Without rotation the rest state minimises the potential energy of the string, the
    static loads and the wall's penalty. scipy's L-BFGS-B from the axis, on the energy
    written here from the assembled stiffness, finds the same state (to a micrometre) on a
    400 m string in a 40 degree build."""
    config = make_scenario("default", string_length=400.0).config
    # a build from vertical to 40 degrees over 500 m: weight and turning tension
    sim = Simulator(with_physics(config, {"well.md": (0.0, 500.0),
                                          "well.inclination": (0.0, 40.0),
                                          "well.azimuth": (0.0, 0.0)}))
    sim.reset(OperatingPoint(0.0, 20e3))
    band = sim.lat_k + sim.lat_kg_weight - 20e3 * sim.lat_kg_unit
    nl = band.shape[1]
    k = np.zeros((nl, nl))
    for d in range(band.shape[0]):
        for i in range(nl - d):
            k[i, i + d] = k[i + d, i] = band[d, i]
    free = np.diag(k) != 0.0  # the pinned DOFs stay at zero
    load = sim.static_load  # (2, nl)
    l0, n = sim.lateral_start, sim.ut.shape[0]
    nodes = [j for j in range(l0 + 1, n) if sim.node_contact[j] != 0.0 or j == n - 1]
    dof = np.array([2 * (j - l0) for j in nodes])
    clearance = sim.node_clearance[nodes].copy()
    clearance[-1] = sim.config.string.hole_diameter / 2 - sim.config.bit.gauge_radius
    stiffness = sim.params[P.WALL_K]
    scale = 1e-3  # mm as the optimiser's unknowns: better conditioned

    def energy(v: np.ndarray) -> tuple[float, np.ndarray]:
        u = np.zeros((2, nl))
        u[:, free] = v.reshape(2, -1) * scale
        r = np.hypot(u[0, dof], u[1, dof])
        into = np.maximum(r - clearance, 0.0)
        e = 0.5 * np.sum(u * (k @ u.T).T) - np.sum(load * u) + 0.5 * stiffness * into @ into
        grad = (k @ u.T).T - load
        push = np.where(r > 0.0, stiffness * into / np.where(r > 0.0, r, 1.0), 0.0)
        grad[0, dof] += push * u[0, dof]
        grad[1, dof] += push * u[1, dof]
        return e, grad[:, free].reshape(-1) * scale

    found = minimize(energy, np.zeros(2 * int(free.sum())), jac=True, method="L-BFGS-B",
                     options={"maxiter": 20000, "maxcor": 50, "gtol": 1e-9, "ftol": 1e-15})
    theirs = np.zeros((2, nl))
    theirs[:, free] = found.x.reshape(2, -1) * scale
    ours = sim.ul.T
    assert np.max(np.abs(ours)) > 0.02  # the string on the wall, centimetres off the axis
    # (L-BFGS-B may end on "ABNORMAL" line search precision, at the same state)
    assert np.max(np.abs(ours[:, 0::2] - theirs[:, 0::2])) < 1e-6


def test_without_wall_contact_the_string_starts_straight():
    """``contact.enabled: false`` has no wall to rest on: nothing is settled on one, and
    no wall friction joins the twist (it did: the bit overshot by 110 rpm, a review)."""
    config = with_physics(make_scenario("lateral_60").config, {"contact.enabled": False})
    sim = Simulator(config)
    sim.reset(OperatingPoint(100.0 * RPM, 50e3))
    assert not np.any(sim.ul) and not np.any(sim.node_force)
    vertical = Simulator(with_physics(make_scenario("default").config,
                                      {"contact.enabled": False}))
    vertical.reset(OperatingPoint(100.0 * RPM, 50e3))
    # the same torque as the vertical string: mud drag and the bit (same string, rock)
    assert sim.readings[TORQUE] == pytest.approx(vertical.readings[TORQUE], rel=1e-9)


def test_a_macroscopic_bit_on_the_wall_starts_at_rest_with_its_friction():
    """Without a near-bit stabilizer the bit itself rests on the wall of a 60 deg hole;
    the macroscopic bit is the kernel's wall contact at its gauge radius, friction too,
    so the start is at rest (the mesoscopic bit's gauge pads are approximated: see
    drill_env/physics/settle.py)."""
    config = with_physics(make_scenario("paper_case2").config, {
        "string.stabilizers": (10.0, 19.0), "bit_model": "macroscopic",
        "well.md": (0.0, 2000.0), "well.inclination": (60.0, 60.0),
        "well.azimuth": (0.0, 0.0)})
    sim = Simulator(config)
    sim.reset(OperatingPoint(100.0 * RPM, 30e3))
    assert sim.node_force[-1] > 1e3  # the bit on the wall (N)
    start = sim.ul.copy()
    record = sim.run(1.0, record_every=10)
    bit = record[:, RECORD_CHANNELS.index("bit_speed")] / RPM
    assert np.max(np.abs(bit - 100.0)) < 1e-4
    assert np.max(np.abs(sim.ul - start)) < 1e-6


def test_a_string_buckled_far_against_the_wall_still_starts():
    """At 215-290 kN the s_shaped BHA is buckled far past its own limit and held by the
    wall: Newton's steps shrink to gradient steps. The reset must not fail (it raised):
    it starts from the best state found, a little out of balance, and runs on, with no
    warning (settle.LOOSE_TOLERANCE: only more than 5 % of the largest static load
    out of balance warns)."""
    import warnings

    sim = Simulator(make_scenario("s_shaped").config)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sim.reset(OperatingPoint(60.0 * RPM, 215e3))
    assert sim.settle_imbalance < 100.0  # N, against loads of kN
    assert sim.settle_imbalance > 1e-3  # (out of balance: the case of the warning)
    assert not [w for w in caught if "settled start" in str(w.message)]
    record = sim.run(1.0, record_every=10)
    bit = record[:, RECORD_CHANNELS.index("bit_speed")] / RPM
    assert np.all(np.isfinite(bit)) and np.max(np.abs(bit - 60.0)) < 0.05 * 60.0


def test_where_the_frictions_rest_is_not_found_the_twist_still_holds_all_of_it(
        monkeypatch):
    """settle.rest_on_wall: where no step of the friction's continuation finds its rest
    state, the string starts at the last share reached (here none: the frictionless
    rest), but the wall torques it returns are those of all the friction, mu(R omega) R
    f_n against the rotation at each string node (the twist holds the kernel's torque at
    t = 0). In a 30 degree slant hole, the slip R omega far above V_REG and the cap."""
    from drill_env.physics import settle

    monkeypatch.setattr(settle._Problem, "solve", lambda self, z, wall: None)
    omega, wob = 100.0 * RPM, 50e3
    sim = _slant(30.0)
    sim.reset(OperatingPoint(omega, wob))
    assert sim.settle_share == 0.0
    torque = settle.rest_on_wall(sim, omega, wob)
    p = sim.params
    touching = np.flatnonzero(sim.node_force[:-1] > 0.0)  # the string's nodes on the wall
    assert touching.size > 10
    radius = sim.node_radius[touching]
    mu = np.array([wall_friction_coefficient(omega * r, p[P.MU_STATIC], p[P.MU_KINETIC],
                                             p[P.MU_DECAY]) for r in radius])
    np.testing.assert_allclose(torque[touching], -mu * radius * sim.node_force[touching],
                               rtol=1e-12)


def test_a_bit_resting_on_the_wall_starts_as_it_goes_on():
    """docs/config.md's J-well with a slick BHA (its near-bit stabilizer left out),
    drilling its build at 100 kN, presses its bit on the wall: the gauge pads' friction
    (the rock's curve) belongs in the settled twist. Left out, the bit fell to 88 rpm in
    0.6 s (a walkthrough); with it the bit speed ripples with the passing pads from the
    start within the range it keeps later."""
    import yaml

    from drill_env.physics.config import flatten

    text = (Path(__file__).parents[2] / "docs" / "config.md").read_text()
    example = yaml.safe_load(text.split("```yaml\n", 1)[1].split("```", 1)[0])
    lower = example["string"]["components"]
    assert lower[0]["kind"] == "stabilizer"
    example["string"]["components"] = lower[1:]
    sim = Simulator(with_physics(make_scenario("default").config, flatten(example)))
    sim.reset(OperatingPoint(100.0 * RPM, 100e3))
    assert sim.node_force[-1] > 1e3  # on the wall (N)
    record = sim.run(12.0, record_every=10)
    time, bit = record[:, 0], record[:, RECORD_CHANNELS.index("bit_speed")] / RPM
    start, later = bit[time < 1.0], bit[time > 8.0]
    assert later.max() - later.min() > 2.0  # the pads' ripple (rpm), there to compare
    assert start.min() > later.min() - 0.5 and start.max() < later.max() + 0.5


@pytest.mark.parametrize("implicit, slow", [(False, False), (True, False), (False, True)])
def test_a_mesoscopic_bit_rests_on_one_pad_with_the_rocks_stiffness_and_curve(implicit,
                                                                              slow):
    """settle.py's Wall: the mesoscopic bit rests on its gauge pads as one pad at r_C
    facing the wall, with the rock's wall stiffness (eq. 55) and the rock's resistance
    curve at omega (eq. 57: the slip r_C omega over r_C; no gauge_friction here), its
    torque r_C mu f_n against the rotation, the friction scaled by r_C omega / V_REG
    where the pads slip slower than V_REG (as the kernel's pads are: settle's rest had
    the full coefficient there, 0.90 against the kernel's 0.19 at 0.002 rad/s); no
    friction with implicit contacts. By hand from the settled bit offset and the hard
    rock the bit sits in."""
    from drill_env.physics.settle import rest_on_wall
    from drill_env.scenarios import HARD

    config = with_physics(make_scenario("paper_case2").config, {
        "string.stabilizers": (10.0, 19.0), "well.md": (0.0, 2000.0),
        "well.inclination": (60.0, 60.0), "well.azimuth": (0.0, 0.0),
        "solver.implicit_contacts": implicit})
    assert config.formation.rocks[config.formation.layers[0]] == HARD
    assert config.bit.gauge_friction is None
    with pytest.warns(RuntimeWarning, match="curved hole") if implicit else nullcontext():
        sim = Simulator(config)
    r_c = config.bit.gauge_radius
    v_reg = sim.params[P.V_REG]
    omega, wob = (0.25 * v_reg / r_c if slow else 100.0 * RPM), 30e3
    sim.reset(OperatingPoint(omega, wob))
    assert sim.depth < config.formation.interfaces[0].depth  # the bit in the top layer
    torque = rest_on_wall(sim, omega, wob)  # the wall's torques of the settled state
    normal = sim.node_force[-1]
    assert normal > 1e3  # the bit on the wall (N)
    penetration = np.hypot(*sim.ul[-2]) - (config.string.hole_diameter / 2 - r_c)
    assert normal == pytest.approx(HARD.wall_stiffness * penetration, rel=1e-9)
    mu = 0.0 if implicit else (HARD.mu_min + (HARD.mu_max - HARD.mu_min)
                               * np.exp(-omega / HARD.st1) + HARD.st2 * omega)  # eq. (39)
    mu *= min(r_c * omega / v_reg, 1.0)
    assert torque[-1] == pytest.approx(-r_c * mu * normal, rel=1e-9, abs=1e-9)


def test_a_bit_without_gauge_pads_does_not_rest_on_a_wall_it_has_none_of():
    """All gauge lengths 0: the kernel gives the mesoscopic bit no wall, so its settled
    rest carries no wall force or torque there (it rested on a pad that did not exist)."""
    config = with_physics(make_scenario("paper_case2").config, {
        "string.stabilizers": (10.0, 19.0), "bit.gauge_length": (0.0,) * 6,
        "well.md": (0.0, 2000.0), "well.inclination": (60.0, 60.0),
        "well.azimuth": (0.0, 0.0)})
    sim = Simulator(config)
    sim.reset(OperatingPoint(100.0 * RPM, 30e3))
    assert sim.node_force[-1] == 0.0
    with_pads = Simulator(with_physics(config, {"bit.gauge_length": (0.05,) * 6}))
    with_pads.reset(OperatingPoint(100.0 * RPM, 30e3))
    assert with_pads.node_force[-1] > 1e3  # the same bit with pads: on the wall
