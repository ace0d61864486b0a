"""Soft-string friction (physics/string_friction.py): the implicit stick/slip solve
against an independent convex solver, the rotating torque against the soft-string
torque-and-drag model and the FE string, and a string stuck along a lateral that
neither creeps nor chatters."""

from __future__ import annotations

import math

import numpy as np
import pytest
from helpers import build_section, pipe_friction, rotate_off_bottom, straight_hole
from scipy.optimize import minimize

from drill_env.physics.config import replace
from drill_env.physics.layout import (
    N_PARAMS,
    N_STATE,
    Motion,
    Nodes,
    P,
    R,
    S,
    TorsionSystem,
    Work,
)
from drill_env.physics.simulator import OperatingPoint, Simulator
from drill_env.physics.string_friction import (
    MAX_ACTIVE_SET_ITERATIONS,
    _solve_held,
    soft_string_torsion,
    steady_friction,
    thomas_sweep,
)
from drill_env.physics.trajectory import Trajectory, soft_string
from drill_env.physics.units import RPM
from drill_env.scenarios import make_scenario
from drill_env.well import column_for


def chain(rng, n):
    """A random torsional chain: A = J + c K (tridiagonal, SPD), predictor speeds and
    residual torques of both signs, Coulomb limits on every node (the bit's last)."""
    k = rng.uniform(0.5, 3.0, n - 1)
    band = np.zeros((2, n))
    band[0] = rng.uniform(0.2, 1.0, n)
    band[0, :-1] += k
    band[0, 1:] += k
    band[1, :-1] = -k
    return band, rng.normal(0.0, 1.0, n), rng.normal(0.0, 2.0, n), rng.uniform(0.0, 1.5, n)


def kernel_speeds(band, v_pred, residual, limit, h, stick, mu_kinetic=1.0, bit_slip=None):
    """End-of-step speeds and stick state from the kernel. By default equal static and
    slip limits (speed-independent Coulomb friction: mu_s = mu_k = 1, unit radius, the
    bit's slip torque its static one)."""
    n = v_pred.shape[0]
    p = np.zeros(N_PARAMS)
    p[P.DT] = 2.0 * h
    p[P.GAMMA] = 0.5
    p[P.MU_STATIC] = 1.0
    p[P.MU_KINETIC] = mu_kinetic
    p[P.MU_DECAY] = 1.0
    state = np.zeros(N_STATE)
    z = np.zeros(n)
    soft_normal = limit.copy()
    soft_normal[-1] = 0.0  # the bit's limit comes from the bit model
    torsion = TorsionSystem(band, z, band, z, band, thomas_sweep(band))
    nodes = Nodes(z, np.ones(n), z, z, np.zeros((2, n)), soft_normal)
    m = Motion(np.zeros((2, 2)), np.zeros((2, 2)), np.zeros((2, 2)), z.copy(), v_pred.copy(),
               np.zeros(n), stick)
    work = Work(np.zeros((2, 2)), residual.copy(), np.zeros(4), z.copy(), np.zeros((6, n)))
    slip = limit[-1] if bit_slip is None else bit_slip
    t_bit, stuck = soft_string_torsion(p, state, torsion, nodes, m, work, slip, limit[-1])
    return v_pred + h * m.at, m.stick, state[S.FRICTION_ITERATIONS], t_bit, stuck


def convex_minimiser(band, v_pred, residual, limit, h):
    """argmin 1/2 v'Av - (A v_p + h r)'v + h sum T_i |v_i| by L-BFGS-B on v = a - b,
    a, b >= 0: the end-of-step speeds of implicit Coulomb friction, solved without the
    active set."""
    n = v_pred.shape[0]
    a_full = np.diag(band[0]) + np.diag(band[1, :-1], 1) + np.diag(band[1, :-1], -1)
    base = a_full @ v_pred + h * residual

    def f(x):
        v = x[:n] - x[n:]
        g = a_full @ v - base
        value = 0.5 * v @ a_full @ v - base @ v + h * limit @ (x[:n] + x[n:])
        return value, np.concatenate([g + h * limit, -g + h * limit])

    x0 = np.concatenate([np.maximum(v_pred, 0.0), np.maximum(-v_pred, 0.0)])
    res = minimize(f, x0, jac=True, method="L-BFGS-B", bounds=[(0.0, None)] * (2 * n),
                   options={"ftol": 1e-15, "gtol": 1e-12, "maxiter": 10_000})
    return res.x[:n] - res.x[n:]


@pytest.mark.parametrize("n", [1, 2, 9, 128])
def test_the_free_string_solve_with_the_precomputed_sweep_matches_numpy(n):
    """With no node held, _solve_held takes the Thomas sweep precomputed once
    (thomas_sweep) instead of dividing in every row; it still solves A v = rhs. A stuck
    flag on a node without a static limit (a bare pipe node) holds nothing. It returns the
    last row's 1 / pivot: the last diagonal entry of A's inverse (its docstring)."""
    rng = np.random.default_rng(40 + n)
    band, _, rhs, _ = chain(rng, n)
    stick = rng.choice([-1.0, 0.0, 1.0], n)
    v = np.zeros(n)
    g = _solve_held(band, thomas_sweep(band), rhs, stick, np.zeros(n), np.zeros(n), v)
    dense = np.diag(band[0]) + np.diag(band[1, :-1], 1) + np.diag(band[1, :-1], -1)
    np.testing.assert_allclose(v, np.linalg.solve(dense, rhs), rtol=1e-12, atol=1e-12)
    # (diagonally dominant, condition number below ~40: both sides to rounding)
    assert g == pytest.approx(np.linalg.inv(dense)[-1, -1], rel=1e-12)


@pytest.mark.parametrize("seed", range(12))
def test_the_active_set_solve_is_the_minimiser_of_implicit_coulomb_friction(seed):
    rng = np.random.default_rng(seed)
    n = 9
    band, v_pred, residual, limit = chain(rng, n)
    h = 0.3
    cold = rng.choice([-1.0, 0.0, 1.0], n)  # any start: the set is found, not assumed
    v, stick, iterations, t_bit, stuck = kernel_speeds(band, v_pred, residual, limit, h,
                                                       cold.copy())
    reference = convex_minimiser(band, v_pred, residual, limit, h)
    scale = np.max(np.abs(reference)) + 1e-3
    np.testing.assert_allclose(v, reference, atol=1e-6 * scale)
    assert 0 < iterations <= MAX_ACTIVE_SET_ITERATIONS  # converged
    # stuck: at rest to rounding (v = v_p + h a with a = -v_p / h)
    assert np.all(np.abs(v[stick == 0.0]) <= 1e-12 * np.max(np.abs(v_pred)))
    assert np.all(np.sign(v[stick != 0.0]) == stick[stick != 0.0])
    # the bit torque: the holding torque within its limit while stuck, the limit against
    # the slip otherwise
    assert abs(t_bit) <= limit[-1] * (1 + 1e-12)
    if not stuck:
        assert t_bit == pytest.approx(-np.sign(v[-1]) * limit[-1])


def test_the_soft_string_mode_turns_with_the_soft_string_torque_of_a_60_degree_hole():
    """Torsion only in a straight 60-degree hole: every node lies on the low side with
    F_n = w L sin 60 and the rotating wall torque is mu r sum F_n, the soft-string
    torque-and-drag model's (an independent implementation along the survey)."""
    config, survey = straight_hole(60.0)
    length = config.string.length
    config = replace(config, **{"solver.lateral": False})
    torque, sim = rotate_off_bottom(config, wound=False)
    soft = soft_string(Trajectory(survey), column_for(config, length), length,
                       pipe_friction(config))
    assert sim.params[P.SOFT_STRING] == 1.0
    assert torque == pytest.approx(soft.surface_torque, rel=0.01)
    assert np.sum(sim.node_force) == pytest.approx(np.sum(soft.normal_force), rel=0.01)


@pytest.mark.parametrize("omega", [3.0, -2.0, 0.0])
def test_the_steady_friction_is_eq_23_against_the_rotation(omega):
    """The settled start's soft-string torques, against eq. (23) written out: mu(|v|) =
    mu_k + (mu_s - mu_k) exp(-|v| / v_s) at each node's wall speed omega r, times its
    normal force, opposing the rotation; nothing at rest."""
    rng = np.random.default_rng(3)
    params = np.zeros(N_PARAMS)
    params[P.MU_STATIC], params[P.MU_KINETIC], params[P.MU_DECAY] = 0.3, 0.2, 0.05
    normal = rng.uniform(0.0, 2e3, 12)
    radius = rng.uniform(0.05, 0.1, 12)
    v = np.abs(omega * radius)
    mu = 0.2 + (0.3 - 0.2) * np.exp(-v / 0.05)
    expected = -np.sign(omega) * mu * normal
    assert steady_friction(params, normal, radius, omega) == pytest.approx(
        expected, rel=1e-13, abs=0.0)


def test_a_settled_start_in_an_inclined_hole_is_steady():
    """Torsion only in a straight 60-degree hole, every node on the wall: the settled
    start balances the steady wall friction, so the string keeps turning at the set
    point from the first step instead of winding up."""
    config, _ = straight_hole(60.0)
    config = replace(config, **{"solver.lateral": False})
    sim = Simulator(config)
    sim.reset(OperatingPoint(60 * RPM, 0.0))
    records = sim.run(2.0, record_every=10)
    speeds = records[:, [R.BIT_SPEED, R.SURFACE_SPEED]]
    assert np.max(np.abs(speeds / (60 * RPM) - 1.0)) < 1e-3


def test_in_a_build_the_fe_string_and_the_soft_string_mode_agree_on_the_torque():
    """Acceptance 3: the FE string climbs the wall to the friction angle, so its wall
    torque times sqrt(1 + mu^2) equals the soft-string mode's within 5 %."""
    config, _ = build_section()
    mu = pipe_friction(config)
    fe, _ = rotate_off_bottom(config)
    soft, _ = rotate_off_bottom(replace(config, **{"solver.lateral": False}))
    assert fe * math.sqrt(1.0 + mu * mu) / soft == pytest.approx(1.0, abs=0.05)
    fast, _ = rotate_off_bottom(replace(config, **{"solver.fidelity": "fast"}))
    assert fast == pytest.approx(soft, rel=0.1)  # FE BHA, soft-string pipe


def test_a_string_stuck_along_a_lateral_neither_creeps_nor_chatters_and_breaks_away():
    """Stop the top drive of the 60-degree lateral (torsion only): the string comes to
    rest held by wall friction with its torque trapped, then stays at rest to rounding;
    a set point again breaks it free and it turns at the set point."""
    config = replace(make_scenario("lateral_60").config, **{"solver.lateral": False})
    sim = Simulator(config)
    sim.reset(OperatingPoint(60 * RPM, 0.0))
    sim.run(40.0, speed_setpoint=0.0)
    soft = sim.soft_nodes
    angles = sim.ut.copy()
    sim.run(10.0, speed_setpoint=0.0)
    assert np.mean(sim.stick[soft] == 0.0) > 0.7
    assert np.max(np.abs(sim.ut - angles)) < 1e-8  # rad in 10 s
    assert np.max(np.abs(sim.vt)) < 1e-9
    trapped = sim.state[S.SURFACE_TORQUE]
    assert trapped > 1e3  # the friction holds the wound-up string
    # and no more than static friction can: the string at rest off bottom, the top's
    # torque is the wall's, at most mu_static r N summed over the nodes (5.7 of 7.2 kN m)
    capacity = np.sum(sim.node_radius[soft] * sim.node_force[soft])
    assert trapped <= config.contact.friction_static * capacity * (1.0 + 1e-9)
    held = sim.soft_work[2] > 0.0  # the nodes the last solve held: at rest, no acceleration
    assert held.sum() > 0.7 * soft.sum()
    assert np.all(sim.at[held] == 0.0) and np.all(sim.vt[held] == 0.0)
    torques = []
    for _ in range(4):  # steady, not alternating step to step
        sim.advance(1, speed_setpoint=0.0)
        torques.append(sim.state[S.SURFACE_TORQUE])
    np.testing.assert_allclose(torques, trapped, rtol=1e-9)
    np.testing.assert_array_equal(sim.contact_forces[soft], sim.node_force[soft])
    assert np.all(sim.contact_forces[soft][held[soft]] > 0.0)
    rec = sim.run(20.0, speed_setpoint=60 * RPM, record_every=50)
    late = rec[rec[:, R.TIME] > rec[-1, R.TIME] - 5.0]
    assert np.mean(late[:, R.BIT_SPEED]) == pytest.approx(60 * RPM, rel=0.05)
    assert np.max(rec[:, R.SURFACE_TORQUE]) > trapped


def test_a_set_that_never_settles_reports_its_solves_as_negative():
    """A step that gives up reports its solves negative (MAX_ACTIVE_SET_ITERATIONS' note)."""
    # one node with a negative pivot (no physical string) has no consistent set: held, it
    # needs 10 against its static limit of 1; released forward (rhs 3 - 0.3 = 2.7), it
    # runs backward (v = -2.7): every solve flips the guess
    band = np.array([[-1.0], [0.0]])
    _, _, iterations, _, _ = kernel_speeds(band, np.zeros(1), np.array([10.0]), np.ones(1),
                                           0.3, np.zeros(1))
    assert iterations == -MAX_ACTIVE_SET_ITERATIONS


@pytest.mark.parametrize("seed", range(50))
def test_with_static_above_slip_and_a_bit_that_slips_harder_the_set_is_consistent(seed):
    """Velocity-weakening friction (mu_k < mu_s, speed-dependent; seeds 40-49: a config's
    mu_k above mu_s, whose slip torque is capped at the static one) has no convex
    potential, so no minimiser to compare with; the solution must satisfy the Coulomb
    conditions instead, checked from the speeds with NumPy: a node at rest needs no more
    than its static torque to stay there, a moving node feels its slip torque (capped at
    the static one) against its motion. The bit here may slip with more torque than holds
    it (a rock whose resistance grows with speed): it keeps that torque, unless no set is
    consistent with it (it would reverse at once), and slips with its static torque
    then; the reported bit torque is the one applied."""
    rng = np.random.default_rng(100 + seed)
    n = 9
    band, v_pred, residual, limit = chain(rng, n)
    h = 0.3
    # seeds 40-49: a slip coefficient above the static one (the config allows it): the
    # slip torque is capped at the static torque
    mu_k = rng.uniform(0.3, 0.95) if seed < 40 else rng.uniform(1.05, 1.5)
    bit_slip = limit[-1] * rng.uniform(0.5, 1.5)
    v, stick, iterations, t_bit, stuck = kernel_speeds(
        band, v_pred, residual, limit, h, rng.choice([-1.0, 0.0, 1.0], n),
        mu_kinetic=mu_k, bit_slip=bit_slip)
    assert 0 < iterations <= MAX_ACTIVE_SET_ITERATIONS
    a_full = np.diag(band[0]) + np.diag(band[1, :-1], 1) + np.diag(band[1, :-1], -1)
    torque = (a_full @ (v - v_pred)) / h - residual  # what held or slipped each node
    mu = mu_k + (1.0 - mu_k) * np.exp(-np.abs(v_pred))  # eq. (23) at the predictor, r = 1
    static = limit.copy()
    slip = np.append(np.minimum(mu[:-1] * limit[:-1], static[:-1]), bit_slip)
    scale = np.max(np.abs(torque)) + 1.0
    if stick[-1] != 0.0 and torque[-1] == pytest.approx(-stick[-1] * static[-1],
                                                        abs=1e-9 * scale):
        # the bit capped at its static torque: right only if the rock's torque would
        # reverse it in this set (no consistent set with it), checked by a NumPy solve
        assert bit_slip > static[-1]
        rows = a_full.copy()
        rhs = a_full @ v_pred + h * (residual + np.append(torque[:-1], -stick[-1] * bit_slip))
        for i in np.flatnonzero(stick == 0.0):
            rows[i] = 0.0
            rows[i, i], rhs[i] = 1.0, 0.0
        assert np.linalg.solve(rows, rhs)[-1] * stick[-1] <= 1e-12
        slip[-1] = static[-1]
    for i in range(n):
        if stick[i] == 0.0:
            assert abs(v[i]) <= 1e-12 * (np.max(np.abs(v_pred)) + 1.0)
            assert abs(torque[i]) <= static[i] + 1e-9 * scale
        else:
            assert np.sign(v[i]) == stick[i] or abs(v[i]) <= 1e-12
            assert torque[i] == pytest.approx(-stick[i] * slip[i], abs=1e-9 * scale)
    assert t_bit == pytest.approx(torque[-1], abs=1e-9 * scale)
    assert stuck == float(stick[-1] == 0.0)


@pytest.mark.parametrize("scenario", ["default", "lateral_60"])
def test_a_rock_rising_past_mu_max_keeps_its_torque_in_a_curved_hole(scenario):
    """Eq. (39)'s rising branch: very soft rock at 150 rpm resists with mu(w) > mu_max.
    The bit torque is a mu(w) WOB (the macroscopic law the mesoscopic bit sums to, a
    symmetric bit in one rock) in a vertical hole and in the 60-degree one, where the
    soft-string solve decides stick and slip (it once capped the slip torque at the
    static a mu_max WOB at every speed: 19 % low here)."""
    from drill_env.physics.bit_reference import mu_curve
    from drill_env.physics.config import FormationConfig
    from drill_env.scenarios import VERY_SOFT

    config = make_scenario(scenario, weight_on_bit=0.0).config
    config = replace(config, formation=FormationConfig(rocks=(VERY_SOFT,), interfaces=(),
                                                       layers=(0,)),
                     **{"solver.lateral": False})
    sim = Simulator(config)
    assert sim.params[P.SOFT_STRING] == float(scenario == "lateral_60")
    sim.reset(OperatingPoint(150 * RPM, 100e3))
    records = sim.run(5.0, 150 * RPM, sim.hook_load_for(100e3), record_every=10)
    late = records[records[:, R.TIME] > 3.0]
    speed = float(np.mean(late[:, R.BIT_SPEED]))
    wob = float(np.mean(late[:, R.WEIGHT_ON_BIT]))
    rock = (VERY_SOFT.mu_min, VERY_SOFT.mu_max, VERY_SOFT.st1, VERY_SOFT.st2)
    expected = sim.lever_arm * wob * mu_curve(speed, *rock)
    assert expected > 1.2 * sim.lever_arm * wob * VERY_SOFT.mu_max  # past mu_max
    assert float(np.mean(late[:, R.TORQUE_ON_BIT])) == pytest.approx(expected, rel=1e-6)
