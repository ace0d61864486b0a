"""Implicit wall and gauge contacts (``solver.implicit_contacts``).

The Woodbury correction against a dense solve of the coupled planes (scipy), the gauge
pads' forces and stiffness against the Python oracle of the bit, what the longer
step keeps (the stick-slip metrics of the default scenario, a curved hole's wall forces)
and that the wall still holds a string thrown at it at steps the explicit contacts could
not take.
"""

from __future__ import annotations

import math
import warnings
from contextlib import nullcontext

import gymnasium
import numpy as np
import pytest
import scipy.linalg

import drill_env  # noqa: F401  (registers the envs)
from drill_env.physics import bit, bit_reference, formation, integrator
from drill_env.physics.batch import SimulatorBatch
from drill_env.physics.bit import PAD, BitOut
from drill_env.physics.config import FormationConfig, Interface, SimulationConfig, replace
from drill_env.physics.fem import from_band
from drill_env.physics.implicit_contact import couple, make_implicit
from drill_env.physics.layout import TERM
from drill_env.physics.simulator import OperatingPoint, Simulator
from drill_env.physics.units import RPM
from drill_env.scenarios import HARD, SOFT, make_scenario
from drill_env.tools.studies import simulate, stick_slip_summary

IMPLICIT = {"solver.implicit_contacts": True}


def implicit(config: SimulationConfig, step: float | None = None) -> SimulationConfig:
    extra = {} if step is None else {"solver.time_step": step}
    return replace(config, **IMPLICIT, **extra)


def test_the_coupled_solve_matches_a_dense_solve_of_both_planes():
    sim = Simulator(implicit(SimulationConfig()))
    sim.reset(OperatingPoint(60 * RPM, 60e3))
    sim.advance(1)  # factorises the lateral matrix at this WOB
    a = from_band(sim.lat_work_band)  # one plane's A (both planes share it)
    n = a.shape[0]
    rng = np.random.default_rng(7)
    store = make_implicit(n, 6)
    dofs = [2 * 20, 2 * 21, 2 * 60, n - 2, n - 2]  # neighbours, a far node, the bit twice
    kappas = 10.0 ** rng.uniform(1.0, 3.0, len(dofs))  # N s^2/m: 0.1-10x a node mass
    angles = rng.uniform(0.0, 2.0 * math.pi, len(dofs))
    for t, (dof, kappa, angle) in enumerate(zip(dofs, kappas, angles, strict=True)):
        store.terms[t, TERM.DOF] = dof
        store.terms[t, TERM.NX], store.terms[t, TERM.NY] = math.cos(angle), math.sin(angle)
        store.terms[t, TERM.KAPPA] = kappa
    acc0 = rng.normal(size=(2, n))
    acc0[:, 0] = 0.0  # the pinned top DOF
    acc = acc0.copy()
    couple(store, sim.lat_factor, len(dofs), acc)

    coupled = scipy.linalg.block_diag(a, a)
    for dof, kappa, angle in zip(dofs, kappas, angles, strict=True):
        w = np.zeros(2 * n)
        w[dof], w[n + dof] = math.cos(angle), math.sin(angle)
        coupled += kappa * np.outer(w, w)
    rhs = np.concatenate([a @ acc0[0], a @ acc0[1]])  # acc0 = A^-1 r in each plane
    expected = scipy.linalg.solve(coupled, rhs, assume_a="pos")
    scale = np.max(np.abs(expected))
    np.testing.assert_allclose(acc.ravel(), expected, rtol=0, atol=1e-9 * scale)
    # y: each term's implicit force, kappa (n . a) at its DOF
    for t, (dof, kappa, angle) in enumerate(zip(dofs, kappas, angles, strict=True)):
        along = math.cos(angle) * acc[0, dof] + math.sin(angle) * acc[1, dof]
        assert store.gram[t, len(dofs)] == pytest.approx(kappa * along, rel=1e-9,
                                                         abs=1e-9 * kappa * scale)


def pads_at(bit_cfg, fa, bx, by, vx=0.0, vy=0.0):
    """The kernel's gauge pads (``BitScratch.pads``) and loads at a bit position, no
    rotation and no gauge friction."""
    blades = bit.blade_arrays(bit_cfg)
    scratch = bit.make_bit_scratch(len(blades), fa.n_interfaces)
    out = bit.make_loads_out(fa.n_rocks)
    bit.mesoscopic_bit_loads(blades, fa, scratch, bit.BitKinematics(bx, by, vx, vy, 100.0, 0.3,
                                                                    0.0),
                             60e3, bit.GaugeContact(bit_cfg.hole_radius, 0.0, 1e-3, 0.0), out)
    return scratch.pads.copy(), out


@pytest.mark.parametrize("angle", [0.1, 0.9, 2.0, 4.0])
def test_the_pads_carry_the_gauge_force_and_its_stiffness(angle):
    """The pads' normal forces sum to the Python oracle's gauge force (no friction), and
    each pushing pad's stiffness is the derivative of its force along its normal (a
    centred difference, 1 um either side). The interface is flat and crosses the pads:
    two rocks per pad, split the same wherever the bit moves across the hole."""
    bit_cfg = bit.asymmetric_bit()
    fa = formation.formation_arrays(FormationConfig(rocks=(HARD, SOFT), interfaces=(
        Interface(100.0 - 0.06, 0.0, 0.0),), layers=(0, 1)))
    offset = 6.0e-3  # 1 mm past the 5 mm gauge clearance
    bx, by = offset * math.cos(angle), offset * math.sin(angle)
    pads, _ = pads_at(bit_cfg, fa, bx, by, vx=0.01, vy=-0.02)
    pushing = pads[:, PAD.FORCE] > 0.0
    assert pushing.any()

    def oracle(x, y, vx=0.01, vy=-0.02):
        return bit_reference.bit_loads(bit.blade_arrays(bit_cfg), *fa, x, y, vx, vy, 100.0,
                                       0.3, 0.0, 60e3, bit_cfg.hole_radius, 0.0, 1e-3, 0.0)

    expected = oracle(bx, by)
    normal = -np.sum(pads[:, PAD.FORCE, None] * pads[:, [PAD.EX, PAD.EY]], axis=0)
    np.testing.assert_allclose(normal, expected[[BitOut.GAUGE_X, BitOut.GAUGE_Y]],
                               rtol=1e-9, atol=1e-6)
    h = 1e-6  # at rest: the damping's part moves with the normal's turn otherwise
    for i in np.flatnonzero(pushing):
        e = pads[i, [PAD.EX, PAD.EY]]
        pads_plus, _ = pads_at(bit_cfg, fa, bx + h * e[0], by + h * e[1])
        pads_minus, _ = pads_at(bit_cfg, fa, bx - h * e[0], by - h * e[1])
        slope = (pads_plus[i, PAD.FORCE] - pads_minus[i, PAD.FORCE]) / (2 * h)
        assert slope == pytest.approx(pads[i, PAD.STIFFNESS], rel=1e-3)
    off = ~pushing & (pads[:, PAD.ON] > 0)
    assert (pads[off, PAD.PENETRATION] <= 0.0).all() or (pads[off, PAD.FORCE] == 0.0).all()


def test_implicit_contacts_lift_the_step_limit_of_the_penalties():
    explicit = Simulator(replace(SimulationConfig(), **{"solver.time_step": 0.008}))
    assert explicit.dt < 0.004  # 0.5 of the ~5 ms penalty limit
    assert Simulator(implicit(SimulationConfig(), 0.008)).dt == 0.008


def test_implicit_contacts_warn_in_a_curved_hole_only():
    """A curved hole's BHA rests on the wall, where the implicit terms cost more than a
    longer step saves (docs/performance.md); a vertical hole's long step whirls
    (test_fidelity.py) and says nothing."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        Simulator(implicit(SimulationConfig(), 0.010))
        Simulator(replace(SimulationConfig(), **{"solver.fidelity": "fast"}))
    curved = make_scenario("j_shaped").config
    with pytest.warns(RuntimeWarning, match="curved hole"):
        Simulator(implicit(curved, 0.004))


def thrown_span(config: SimulationConfig, seconds: float = 0.2) -> tuple[float, float]:
    """The throw of test_fidelity.py (2 m/s over a 9 m span of the BHA, 30 kN): the
    deepest a contact node ends a step inside the wall (m) and the largest normal force."""
    sim = Simulator(config)
    sim.reset(OperatingPoint(60 * RPM, 30e3))
    height = sim.node_depth[-1] - sim.node_depth
    span = (height > 10.0 + 1e-9) & (height < 19.0 - 1e-9)
    sim.vl[0::2, 0][span] = 2.0 * np.sin(math.pi * (height[span] - 10.0) / 9.0)
    deepest = 0.0
    peak = 0.0
    for _ in range(int(round(seconds / sim.dt))):
        sim.advance(1)
        assert sim.status == 0
        radius = np.hypot(sim.ul[0::2, 0], sim.ul[0::2, 1])
        inside = (radius - sim.node_clearance)[sim.node_contact > 0]
        deepest = max(deepest, float(inside.max()))
        peak = max(peak, float(np.max(sim.contact_forces[:-1])))
    return deepest, peak


@pytest.mark.parametrize(("step", "peak_tolerance"), [(0.004, 0.15), (0.006, 0.15),
                                                      (0.008, 0.25)])
def test_the_wall_holds_a_span_thrown_at_it_as_stiffly_at_long_steps(step, peak_tolerance):
    """The deepest penetration and the largest force are the wall's stiffness and damping
    meeting the span's momentum: the converged explicit run (0.5 ms) sets them (~5 mm and
    ~57 kN at 10 MN/m), which an explicit penalty could not step past 4 ms for. The peak
    is a largest end-of-step sample: at 8 ms one step is about the impact's duration (half
    a period of the 10 MN/m wall on the lightest collar node, ~9 ms: its explicit critical
    step 2 / w is 5.7 ms), so it may fall well off the crest."""
    converged, converged_peak = thrown_span(
        replace(SimulationConfig(), **{"solver.time_step": 5e-4}))
    deepest, peak = thrown_span(implicit(SimulationConfig(), step))
    assert converged_peak > 10e3  # it did hit the wall
    assert deepest == pytest.approx(converged, rel=0.15)
    assert peak == pytest.approx(converged_peak, rel=peak_tolerance)


def test_the_default_scenario_keeps_its_stick_slip_at_a_5_ms_implicit_step():
    """docs/performance.md: SSI and stuck share at 50 rpm against the 2 ms explicit run."""
    sc = make_scenario("default")
    full = stick_slip_summary(simulate(sc.config, 50.0, sc.weight_on_bit, 60.0), 20.0)
    long = stick_slip_summary(simulate(implicit(sc.config, 0.005), 50.0, sc.weight_on_bit,
                                       60.0), 20.0)
    assert full["ssi"] > 0.8
    assert long["ssi"] == pytest.approx(full["ssi"], rel=0.05)
    assert long["stuck_fraction"] == pytest.approx(full["stuck_fraction"], rel=0.10, abs=0.02)


def test_a_curved_hole_rests_on_the_wall_with_the_same_forces_at_a_long_step():
    """Equilibrium does not depend on the step: the total wall force of the J-shaped
    well's string, averaged over 2 s while it turns, explicit at 2 ms against implicit at
    2 and 8 ms."""
    sc = make_scenario("j_shaped")
    totals = []
    for config in (sc.config, implicit(sc.config), implicit(sc.config, 0.008)):
        expect = config.solver.implicit_contacts
        with pytest.warns(RuntimeWarning, match="curved hole") if expect else nullcontext():
            sim = Simulator(config)
        sim.reset(OperatingPoint(60 * RPM, sc.weight_on_bit))
        sim.advance(int(round(6.0 / sim.dt)))
        samples = []
        for _ in range(20):
            sim.advance(int(round(0.1 / sim.dt)))
            samples.append(float(np.sum(sim.contact_forces[:-1])))
        totals.append(np.mean(samples))
    assert totals[0] > 50e3
    assert totals[1] == pytest.approx(totals[0], rel=0.01)
    assert totals[2] == pytest.approx(totals[0], rel=0.05)


def test_a_batch_of_implicit_simulators_gives_the_floats_of_each_alone():
    def make() -> list[Simulator]:
        sims = []
        for rpm, step in ((60.0, 0.004), (90.0, 0.008)):
            sim = Simulator(implicit(SimulationConfig(), step))
            sim.reset(OperatingPoint(rpm * RPM, 60e3))
            sim.vl[0::2, 0][-20:] = 0.5  # a push towards the wall
            sims.append(sim)
        return sims

    alone, together = make(), make()
    batch = SimulatorBatch(2)
    for k in range(3):
        hooks = [sim.hook_load_for(60e3 + 5e3 * k) for sim in alone]  # refactors
        expected = [sim.advance(50, 60 * RPM, h, 10) for sim, h in zip(alone, hooks,
                                                                       strict=True)]
        actual = batch.advance(together, [50, 50], [60 * RPM] * 2, hooks, [10, 10])
        for a, e in zip(actual, expected, strict=True):
            np.testing.assert_array_equal(a, e)
    for a, e in zip(together, alone, strict=True):
        np.testing.assert_array_equal(a.ul, e.ul)
        np.testing.assert_array_equal(a.contact_forces, e.contact_forces)
        assert np.max(e.contact_forces[:-1]) > 0.0  # the push reached the wall


@pytest.mark.parametrize(("gauge_length", "pads"), [((0.05,) * 6, 2),
                                                    ((0.05, 0.0, 0.05, 0.05, 0.05, 0.05), 1)])
def test_the_bits_friction_cap_is_split_among_the_pads_on_the_wall(gauge_length, pads):
    """GaugeContact.shared: with every pad's friction at its cap (fast spin, a cap far
    below the normal forces' friction), the pads' friction torque is the unshared one
    over the number of pads pushing (the normal forces' own torque, with no friction,
    taken off both). Blades 0 and 1 reach past the wall; with blade 1's gauge pad left
    out (gauge length 0) it is no pad on the wall, and blade 0's pad keeps its whole cap."""
    bit_cfg = replace(bit.asymmetric_bit(), gauge_length=gauge_length)
    fa = formation.formation_arrays(FormationConfig(rocks=(HARD,)))
    blades = bit.blade_arrays(bit_cfg)

    def gauge_torque(friction: float, shared: bool) -> tuple[float, int]:
        scratch = bit.make_bit_scratch(len(blades), fa.n_interfaces)
        scratch.pads[:, PAD.END_FORCE] = 1e12  # rubbing as hard at the last step's end
        out = bit.make_loads_out(fa.n_rocks)
        bit.mesoscopic_bit_loads(blades, fa, scratch,
                                 bit.BitKinematics(0.009, 0.0, 0.0, 0.0, 100.0, 0.0, 20.0),
                                 60e3, bit.GaugeContact(bit_cfg.hole_radius, 1e-3, 1e-3,
                                                        friction, shared), out)
        return out[BitOut.GAUGE_TORQUE], int(np.sum(scratch.pads[:, PAD.FORCE] > 0.0))

    normal_only, touching = gauge_torque(0.0, False)
    alone = gauge_torque(0.5, False)[0] - normal_only
    shared = gauge_torque(0.5, True)[0] - normal_only
    assert touching == pads and abs(alone) > 0.0
    assert shared == pytest.approx(alone / pads, rel=1e-9)


@pytest.mark.parametrize(("seed", "step"), [(117, 0.006), (119, 0.006), (101, 0.008),
                                            (102, 0.008)])
def test_task_episodes_that_diverged_at_long_steps_hold(seed, step):
    """DrillOptimise-v0 at the fast level, implicit contacts, uniformly random actions:
    these episodes diverged (several gauge pads pressed into the rock, the bit's speed
    alternating in sign) while the friction followed the predictors' normal forces at the
    full cap; 22 of 300 did at 6 ms and 82 of 300 at 8 ms, none now
    (docs/performance.md)."""
    env = gymnasium.make("DrillOptimise-v0", physics={"solver.fidelity": "fast", **IMPLICIT,
                                                      "solver.time_step": step})
    env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    for _ in range(300):
        action = rng.uniform(env.action_space.low, env.action_space.high).astype(np.float32)
        _, _, terminated, truncated, info = env.step(action)
        assert not terminated, info["termination_reason"]
        if truncated:
            break


def test_a_hard_whirl_that_diverged_at_8_ms_holds():
    """The random scenario's seed 4 at 80 rpm and 140 kN, fast level at 8 ms: with the
    friction on the predictors' normal forces the bit's speed alternated in sign, tripling
    every step, and the run diverged after 10.7 s (docs/performance.md)."""
    sc = make_scenario("random", np.random.default_rng(4))
    config = replace(replace(sc.config, **{"solver.fidelity": "fast"}).resolved(),
                     **IMPLICIT, **{"solver.time_step": 0.008})
    sim = Simulator(config)
    sim.reset(OperatingPoint(80 * RPM, 140e3))
    sim.advance(int(round(20.0 / sim.dt)), 80 * RPM, sim.hook_load_for(140e3))
    assert sim.status == 0
    assert np.max(sim.contact_forces) > 0.0  # it whirls against the wall


@pytest.mark.parametrize("last", [0.0, 0.5, 2.0])
def test_wall_friction_follows_the_smaller_normal_force(last):
    """Implicit contacts: a continuing wall contact's friction is the explicit one scaled
    by the smaller of its normal forces at the predictors and at the end of the last step
    (as a fraction ``last`` of the predictors'); a starting one (``last`` 0) with half the
    predictors' (the mean of the step's start, 0, and its predicted end); the normal part
    stays as it is."""
    sim = Simulator(implicit(SimulationConfig()))
    sim.reset(OperatingPoint(60 * RPM, 60e3))
    a = sim.arrays
    k = sim.n_nodes - 20
    j = 2 * (k - sim.lateral_start)
    clearance = sim.node_clearance[k]
    a.motion.ul[:, j] = (0.6 * (clearance + 2e-3), 0.8 * (clearance + 2e-3))  # 2 mm in
    a.motion.vl[:, j] = (0.0, 0.0)

    def contact(implicit_on: bool, last_force: float) -> tuple[np.ndarray, np.ndarray]:
        a.work.rl[:] = 0.0
        a.work.rt[:] = 0.0
        a.work.node_force[:] = 0.0
        a.work.node_force[k] = last_force
        integrator._wall_contacts(a.params, a.nodes, a.motion, a.work, sim.lateral_start,
                                  implicit_on, a.implicit.terms)
        return a.work.rl[:, j].copy(), np.array([a.work.rt[k]])

    explicit_f, explicit_t = contact(False, 0.0)
    normal = a.work.node_force[k]
    assert normal > 0.0 and abs(explicit_t[0]) > 0.0  # it pushes and rubs
    got_f, got_t = contact(True, last * normal)
    scale = min(last, 1.0) if last > 0.0 else 0.5
    n = np.array((0.6, 0.8))
    np.testing.assert_allclose(got_t, scale * explicit_t, rtol=1e-12)
    assert got_f @ n == pytest.approx(explicit_f @ n, rel=1e-12)  # the normal part
    t = np.array((-0.8, 0.6))
    assert got_f @ t == pytest.approx(scale * (explicit_f @ t), rel=1e-9, abs=1e-9)
