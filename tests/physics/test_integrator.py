"""The numba time step against the plain NumPy oracle, and the band kernels against SciPy."""

import dataclasses
import math

import numpy as np
import pytest
import scipy.linalg

from drill_env.physics import integrator as ig
from drill_env.physics import linalg
from drill_env.physics.config import (
    BitConfig,
    FormationConfig,
    Interface,
    RockConfig,
    SimulationConfig,
    SolverConfig,
    replace,
)
from drill_env.physics.fem import from_band, to_band
from drill_env.physics.layout import CONTACT, N_RECORD, N_STATE, P, R, S
from drill_env.physics.reference import ReferenceStepper, wall_contact_forces
from drill_env.physics.simulator import OperatingPoint, Simulator
from drill_env.physics.units import RPM

HARD = RockConfig(name="hard", mu_min=0.5, mu_max=0.9, st1=3.0, st2=0.0,
                  wall_stiffness=2.0e7, wall_damping=2.0e3, depth_of_cut=1.0e-8)
SOFT = RockConfig(name="soft", mu_min=0.3, mu_max=0.45, st1=5.0, st2=0.005,
                  wall_stiffness=5.0e6, wall_damping=1.0e3, depth_of_cut=4.0e-8)
BIT_DEPTH = 1035.0
#: A dipping hard/soft interface through the bit face, so both rocks cut at once.
SANDWICH = FormationConfig(rocks=(HARD, SOFT), interfaces=(Interface(BIT_DEPTH, 45.0, 30.0),),
                           layers=(0, 1))
N_STEPS = 50
#: Kernel vs NumPy oracle over N_STEPS steps: both solve systems whose condition number is
#: below COND_BOUND (asserted in test_system_matrices_are_well_conditioned), so each step
#: may differ by ~COND_BOUND * eps relative, and the difference grows at most linearly
#: over the steps of a stable integrator; x4 for the explicit forces in between. This
#: sets the tolerance (~1e-10), not the digits one CPU happened to agree to.
COND_BOUND = 2.5e3
RTOL = 4 * N_STEPS * COND_BOUND * np.finfo(float).eps


def random_state(sim: Simulator, rng: np.random.Generator, bit_speed: float,
                 wob: float) -> None:
    """Random lateral offsets (some nodes beyond their clearance), velocities and twist."""
    sim.reset()
    n = sim.n_nodes
    clearance = sim.node_clearance.copy()
    clearance[-1] = sim.config.bit.gauge_clearance
    radius = clearance * rng.uniform(0.0, 1.15, n)
    angle = rng.uniform(0.0, 2.0 * np.pi, n)
    sim.ul[0::2, 0] = radius * np.cos(angle)
    sim.ul[0::2, 1] = radius * np.sin(angle)
    sim.ul[1::2] = rng.normal(0.0, 1e-4, (n, 2))
    sim.vl[0::2] = rng.normal(0.0, 0.05, (n, 2))
    sim.vl[1::2] = rng.normal(0.0, 0.01, (n, 2))
    sim.al[:] = rng.normal(0.0, 1.0, sim.al.shape)
    for arr in (sim.ul, sim.vl, sim.al):
        arr[0] = 0.0  # top node laterally pinned
        if sim.config.bit.axis_aligned:
            arr[-1] = 0.0  # bit tilt held (paper section 3.1.1)
    sim.ut[:] = np.cumsum(rng.normal(0.0, 0.05, n))
    sim.vt[:] = bit_speed + rng.normal(0.0, 0.3, n)
    sim.vt[0] = 60 * RPM
    sim.vt[-1] = bit_speed
    sim.at[:] = rng.normal(0.0, 1.0, n)
    if bit_speed == 0.0:  # a BHA at rest and untwisted, so the bit can stay stuck
        sim.ut[-10:] = sim.ut[-11]
        sim.vt[-10:] = 0.0
        # Not exactly 0, so both sides stay clear of round-off landing on omega == 0.
        sim.at[-10:] = rng.normal(0.0, 1e-3, 10)
    st = sim.state
    st[S.DEPTH] = BIT_DEPTH
    st[S.SETPOINT] = 60 * RPM
    st[S.SETPOINT_TARGET] = 80 * RPM  # the rate limit is active
    st[S.PI_INTEGRAL] = rng.uniform(0.0, 2.0)
    st[S.WOB] = wob
    st[S.HOOK_LOAD] = sim.hook_load_for(wob)
    st[S.WOB_FACTORED] = np.nan


def assert_agree(actual: np.ndarray, expected: np.ndarray, name: str) -> None:
    scale = np.max(np.abs(expected)) if expected.size else 0.0
    np.testing.assert_allclose(actual, expected, rtol=RTOL, atol=RTOL * scale, err_msg=name)


def advance_both(sim: Simulator) -> tuple[np.ndarray, np.ndarray, ReferenceStepper]:
    """``N_STEPS`` of ``sim`` and of a NumPy reference started from its state, recording
    every step: the kernel runs without a failure and every dynamic array agrees. Gives
    (the kernel's records, the reference's, the reference)."""
    ref = ReferenceStepper(sim)
    expected = ref.advance(N_STEPS, record_every=1)
    actual = sim.advance(N_STEPS, record_every=1)
    assert sim.status == 0
    for name in ("ul", "vl", "al", "ut", "vt", "at", "node_force"):
        assert_agree(getattr(sim, name), getattr(ref, name), name)
    return actual, expected, ref


CASES = [
    # (bit model, bit speed rad/s, WOB N): slipping, stuck, backwards, off bottom
    ("mesoscopic", 6.0, 100e3),
    ("mesoscopic", 0.0, 150e3),
    ("mesoscopic", -1.0, 80e3),
    ("mesoscopic", 3.0, 0.0),
    ("macroscopic", 6.0, 100e3),
    ("macroscopic", 0.0, 150e3),
    ("macroscopic", -1.0, 80e3),
]


@pytest.mark.parametrize("seed", [0, 1])
@pytest.mark.parametrize(("bit_model", "bit_speed", "wob"), CASES)
def test_numba_advance_matches_numpy_reference(bit_model, bit_speed, wob, seed):
    sim = Simulator(SimulationConfig(bit_model=bit_model, formation=SANDWICH))
    random_state(sim, np.random.default_rng(seed), bit_speed, wob)
    assert np.any(np.hypot(sim.ul[2::2, 0], sim.ul[2::2, 1])[:-1] > sim.node_clearance[1:-1])
    actual, expected, ref = advance_both(sim)
    keep = np.ones(N_STATE, bool)
    keep[S.WOB_FACTORED] = False
    assert_agree(sim.state[keep], ref.state[keep], "state")
    assert actual.shape == expected.shape == (N_STEPS, N_RECORD)
    for col in range(N_RECORD):
        assert_agree(actual[:, col], expected[:, col], f"record column {col}")
    if bit_speed == 0.0 and wob > 0:
        assert actual[0, R.STUCK] == 1.0  # the stuck branch was exercised
    if bit_speed == 6.0:
        assert actual[0, R.STUCK] == 0.0  # slipping at the start
    if bit_model == "macroscopic":
        assert actual[:, R.MAX_WALL_FORCE].max() > 0.0


def test_system_matrices_are_well_conditioned():
    """The premise of RTOL: the implicit systems of the oracle tests are well conditioned."""
    sim = Simulator(SimulationConfig(formation=SANDWICH))
    lateral = sim.kernel_arrays().lateral
    for wob in (0.0, 150e3):
        assert ig.factor_lateral(lateral, wob, sim.params)
        assert np.linalg.cond(from_band(lateral.work)) < COND_BOUND
    assert np.linalg.cond(from_band(sim._torsion_system())) < COND_BOUND


def test_torsion_only_mode_matches_numpy_reference():
    """``SolverConfig(lateral=False)`` freezes the lateral DOFs in both implementations."""
    cfg = SimulationConfig(formation=SANDWICH, solver=SolverConfig(lateral=False))
    sim = Simulator(cfg)
    random_state(sim, np.random.default_rng(5), 0.0, 120e3)
    ref = ReferenceStepper(sim)
    expected = ref.advance(N_STEPS, record_every=1)
    actual = sim.advance(N_STEPS, record_every=1)
    for name in ("ul", "vl", "ut", "vt", "at"):
        assert_agree(getattr(sim, name), getattr(ref, name), name)
    assert_agree(actual, expected, "records")
    assert np.all(sim.al == 0.0)


def test_bit_breaking_away_from_exact_rest_gets_its_static_torque():
    """Regression: mu(0) = 0, so the kernel must evaluate the breakaway at 0+, not 0.

    At 1 ms the bit's own DOF takes most of the one-step kick from the twisted element.
    """
    sim = Simulator(SimulationConfig(solver=SolverConfig(time_step=1e-3)))
    wob = 100e3
    sim.reset(OperatingPoint(0.0, wob))
    t_static = sim.lever_arm * sim.rock_params[0, 1] * wob
    # Twist the string so the bit torque exceeds the static resistance; the bit is at
    # exact rest (speed and acceleration 0.0).
    sim.ut[:-1] = 3.0 * t_static * sim.mesh.element_length[-1] / sim.mesh.torsional_stiffness[-1]
    sim.advance(1)
    assert sim.status == 0
    assert sim.state[S.STUCK] == 0.0  # it breaks away ...
    assert sim.torque_on_bit == pytest.approx(t_static, rel=1e-3)  # ... against mu_max


def test_wall_contact_kernel_matches_numpy_version():
    """The compiled contact against its NumPy version (eqs. 17-26), to their rounding:
    the penetration r - clearance cancels, so the forces carry k eps r and c eps |v| of
    absolute error (64 of each, with friction's share of them), the moment radius times
    that; beyond it products of a few roundings (16 eps relative)."""
    sim = Simulator()
    eps = np.finfo(float).eps
    rng = np.random.default_rng(3)
    out = np.zeros(4)
    p = sim.params
    for _ in range(200):
        clearance = rng.uniform(0.001, 0.03)
        r = clearance * rng.uniform(0.9, 1.3)
        psi = rng.uniform(0, 2 * np.pi)
        x, y = r * np.cos(psi), r * np.sin(psi)
        vx, vy = rng.normal(0, 0.3, 2)
        omega = rng.normal(0, 5)
        radius = rng.uniform(0.05, 0.1)
        compliance = rng.choice([0.0, rng.uniform(1e-7, 1e-5)])
        ig.wall_contact(x, y, vx, vy, omega, clearance, radius, p, compliance, out)
        expected = wall_contact_forces(x, y, vx, vy, omega, clearance, radius,
                                       np.float64(compliance), sim.config.contact)
        force = 64 * eps * (1.0 + p[P.MU_STATIC]) * (p[P.WALL_K] * r
                                                     + p[P.WALL_C] * math.hypot(vx, vy))
        atol = np.full(len(CONTACT), force)
        atol[CONTACT.MZ] = radius * force
        assert np.all(np.abs(out - np.ravel(expected)) <= atol + 16 * eps * np.abs(out))


# --------------------------------------------------------------------------- band kernels


def random_spd_band(rng: np.random.Generator, n: int, p: int) -> np.ndarray:
    """Dense SPD matrix with half bandwidth p (diagonally dominant)."""
    a = np.zeros((n, n))
    for d in range(1, p + 1):
        off = rng.normal(0.0, 1.0, n - d)
        a += np.diag(off, d) + np.diag(off, -d)
    a += np.diag(np.abs(a).sum(axis=1) + rng.uniform(0.1, 2.0, n))
    return a


@pytest.mark.parametrize("dense", [
    [[1.0, 1.0], [1.0, 1.0]],  # singular: the second pivot is exactly 0
    [[1.0, 2.0], [2.0, 1.0]],  # indefinite
    [[1.0, 0.5], [0.5, np.nan]],  # a NaN stiffness (a NaN load reached the matrix)
])
def test_band_cholesky_refuses_what_scipy_refuses(dense):
    """Not positive definite (scipy raises LinAlgError), or NaN: False, so that the
    simulator stops with Status.SINGULAR instead of stepping on a factor of NaNs or
    dividing by a zero pivot."""
    dense = np.array(dense)
    if np.isfinite(dense).all():
        with pytest.raises(np.linalg.LinAlgError):
            scipy.linalg.cholesky(dense)
    band = to_band(dense, 1)
    assert not linalg.band_cholesky(band, np.zeros_like(band))


@pytest.mark.parametrize(("n", "p"), [(1, 0), (5, 1), (40, 1), (50, 3), (7, 6), (30, 5)])
def test_band_cholesky_matches_scipy(n, p):
    rng = np.random.default_rng(n * 10 + p)
    dense = random_spd_band(rng, n, p)
    band = to_band(dense, p)
    np.testing.assert_array_equal(from_band(band), dense)
    factor = np.zeros_like(band)
    assert linalg.band_cholesky(band, factor)
    u = scipy.linalg.cholesky(dense, lower=False)
    np.testing.assert_allclose(1.0 / factor[0], np.diag(u), rtol=1e-12)
    for d in range(1, p + 1):
        np.testing.assert_allclose(factor[d, : n - d], np.diagonal(u, d), rtol=1e-10,
                                   atol=1e-12 * np.abs(u).max())


@pytest.mark.parametrize("n", [1, 2, 3, 4, 5, 8, 41])
def test_plane_major_bandwidth3_kernels_match_numpy(n):
    """The integrator's unrolled kernels (bandwidth 3, planes in rows) against dense numpy."""
    rng = np.random.default_rng(n)
    p = min(3, n - 1)
    dense = random_spd_band(rng, n, p)
    band = np.zeros((4, n))
    band[: p + 1] = to_band(dense, p)
    factor = np.zeros_like(band)
    assert linalg.band_cholesky(band, factor)
    linalg.cholesky_to_ldl(factor)
    b = rng.normal(size=(2, n))
    x = b.copy()
    linalg.solve3_planes(factor, x)
    np.testing.assert_allclose(x, np.linalg.solve(dense, b.T).T, rtol=1e-10, atol=1e-12)

    damp = random_spd_band(rng, n, p)
    damp_band = np.zeros((4, n))
    damp_band[: p + 1] = to_band(damp, p)
    m = rng.uniform(1.0, 2.0, n)
    u, v, r = rng.normal(size=(3, 2, n))
    r0 = r.copy()
    linalg.lateral_residual(band, damp_band, u, v, m, 0.3, r)
    expected = r0 - (dense @ u.T + damp @ v.T + 0.3 * m[:, None] * v.T).T
    np.testing.assert_allclose(r, expected, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("n", [2, 3, 17])
def test_torsion_kernels_match_numpy(n):
    rng = np.random.default_rng(100 + n)
    dense = random_spd_band(rng, n, 1)
    band = to_band(dense, 1)
    factor = np.zeros_like(band)
    assert linalg.band_cholesky(band, factor)
    linalg.cholesky_to_ldl(factor)
    b = rng.normal(size=n)
    x = b.copy()
    linalg.solve_tridiagonal(factor, x)
    np.testing.assert_allclose(x, np.linalg.solve(dense, b), rtol=1e-10, atol=1e-12)
    c = rng.uniform(0.0, 1.0, n)
    u, v, r = rng.normal(size=(3, n))
    r0 = r.copy()
    linalg.torsion_residual(band, 0.2, c, u, v, r)
    np.testing.assert_allclose(r, r0 - dense @ (u + 0.2 * v) - c * v, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("n", [1, 2, 3, 4, 5, 17, 86, 137])
def test_twisted_solve_matches_numpy(n):
    """The kernel's torsional solve (two half chains meeting in the middle row) against
    numpy's dense solve, for odd and even n and the degenerate sizes."""
    rng = np.random.default_rng(300 + n)
    dense = random_spd_band(rng, n, 1)
    factor = linalg.twisted_tridiagonal(to_band(dense, 1), "A")
    b = rng.normal(size=n)
    x = b.copy()
    linalg.solve_twisted(factor, x)
    np.testing.assert_allclose(x, np.linalg.solve(dense, b), rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("dense", [
    # indefinite: its leading 2 x 2 block has the eigenvalue -1
    [[1.0, 2.0, 0.0], [2.0, 1.0, 0.5], [0.0, 0.5, 3.0]],
    [[1.0, 1.0], [1.0, 1.0]],  # singular: the middle pivot is exactly 0
    [[1.0, 0.5], [0.5, np.nan]],  # a NaN stiffness
])
def test_twisted_factor_names_a_matrix_that_is_not_positive_definite(dense):
    """linalg.twisted_tridiagonal's docstring: a ValueError naming the matrix if it is not
    positive definite, for what band_cholesky refuses too (indefinite, singular, NaN),
    not a factor of infinities or NaNs."""
    with pytest.raises(ValueError, match="torsional system matrix is not positive definite"):
        linalg.twisted_tridiagonal(to_band(np.array(dense), 1), "torsional system matrix")


@pytest.mark.parametrize(("n", "p"), [(1, 0), (2, 1), (17, 1), (3, 3), (4, 3), (41, 3),
                                    (30, 5)])
def test_band_of_the_inverse_matches_numpy_inverse(n, p):
    """Takahashi's recurrence on the LDL^T factor gives the band of A^-1 that
    numpy.linalg.inv (LAPACK LU, another algorithm) gives: both backward stable, so they
    agree to ~cond(A) eps of the largest entry (x10 for the length of the sums)."""
    rng = np.random.default_rng(7 * n + p)
    dense = random_spd_band(rng, n, p)
    factor = np.zeros((p + 1, n))
    assert linalg.band_cholesky(to_band(dense, p), factor)
    linalg.cholesky_to_ldl(factor)
    band = linalg.ldl_inverse_band(factor)
    inverse = np.linalg.inv(dense)
    tol = 10 * np.linalg.cond(dense) * np.finfo(float).eps * np.abs(inverse).max()
    rows = np.arange(n)
    near = np.abs(np.subtract.outer(rows, rows)) <= p  # the band
    np.testing.assert_allclose(from_band(band)[near], inverse[near], rtol=0, atol=tol)


def test_simulator_compliance_and_bit_column_match_the_dense_inverse():
    """The friction caps (compliance), the bit's column of the torsional A^-1 and
    G_BIT, now from the band factors in O(n), against numpy's dense inverse of the same
    system matrices: both are backward stable, so the entries agree to cond(A) eps
    relative to the largest one (x10 on the lateral sums, whose terms mix two inverses)."""
    from drill_env.physics.layout import LateralSystem
    from drill_env.scenarios import make_scenario

    for config in (SimulationConfig(), make_scenario("random", rng=np.random.default_rng(2)
                                                     ).config.resolved()):
        sim = Simulator(config)
        tor = from_band(sim._torsion_system())
        tor_inv = np.linalg.inv(tor)
        tol = np.linalg.cond(tor) * np.finfo(float).eps * np.abs(tor_inv).max()
        np.testing.assert_allclose(sim.col_bit, tor_inv[:, -1], rtol=0, atol=tol)
        gamma_dt = sim.params[P.GAMMA] * sim.dt
        assert sim.params[P.G_BIT] == pytest.approx(gamma_dt * tor_inv[-1, -1],
                                                    abs=gamma_dt * tol)
        lateral = LateralSystem(sim.lat_k, sim.lat_kg_weight, sim.lat_kg_unit, sim.lat_m,
                                sim.lat_k_damp, np.zeros_like(sim.lat_k),
                                np.zeros_like(sim.lat_k), np.zeros_like(sim.lat_k))
        assert ig.factor_lateral(lateral, 0.0, sim.params)
        lat = from_band(lateral.work)
        lat_inv = np.diag(np.linalg.inv(lat))[0::2]
        radius = sim.node_radius.copy()
        radius[-1] = config.bit.gauge_radius
        start = sim.lateral_start
        want = gamma_dt * (lat_inv + radius[start:] ** 2 * np.diag(tor_inv)[start:])
        want[0] = 0.0  # the pinned top node
        scale = np.linalg.cond(lat) * np.finfo(float).eps * np.abs(want).max()
        np.testing.assert_allclose(sim.compliance[start:], want, rtol=0, atol=10 * scale)


def test_band_cholesky_rejects_indefinite_matrix():
    dense = np.diag([1.0, -1.0, 2.0])
    factor = np.zeros((2, 3))
    assert not linalg.band_cholesky(to_band(dense, 1), factor)


def test_lateral_system_matches_dense_assembly():
    """A = M + gamma dt C + beta dt^2 (K + K_g(WOB)) as factorised by the kernel."""
    sim = Simulator()
    ref = ReferenceStepper(sim)
    wob = 80e3
    sim.reset(OperatingPoint(60 * RPM, wob))
    sim.advance(1)
    dense = from_band(sim.lat_work_band)[1:-1, 1:-1]  # pinned top, held bit tilt
    expected = ref._lateral_system(wob)
    np.testing.assert_allclose(dense, expected, rtol=1e-12, atol=1e-12 * np.abs(expected).max())


@pytest.mark.parametrize("bit_model", ["mesoscopic", "macroscopic"])
def test_founder_point_and_gauge_friction_match_the_numpy_reference(bit_model):
    """The depth-of-cut law above the founder point and a gauge-pad friction of its own,
    in both implementations (WOB 150 kN above founder points of 90 and 110 kN)."""
    rocks = tuple(dataclasses.replace(r, founder_wob_per_diameter=f, post_founder_slope=0.7)
                  for r, f in ((HARD, 5e5), (SOFT, 4e5)))
    formation = dataclasses.replace(SANDWICH, rocks=rocks)
    cfg = SimulationConfig(bit_model=bit_model, formation=formation,
                           bit=BitConfig(gauge_friction=0.25))
    sim = Simulator(cfg)
    random_state(sim, np.random.default_rng(9), 6.0, 150e3)
    ref = ReferenceStepper(sim)
    expected = ref.advance(N_STEPS, record_every=1)
    actual = sim.advance(N_STEPS, record_every=1)
    assert sim.status == 0
    for name in ("ul", "vl", "ut", "vt"):
        assert_agree(getattr(sim, name), getattr(ref, name), name)
    assert_agree(actual, expected, "records")
    linear = max(r.depth_of_cut for r in rocks) * 150e3
    assert sim.state[S.DEPTH_OF_CUT] < 0.5 * linear  # past the founder points



def test_numpy_reference_takes_the_set_point_hook_load_and_record_spacing_as_the_kernel():
    """The inputs of ``advance`` in both implementations, over three calls: a set point
    below the current one (the rate limit on the way down), a hook load per call (each a
    new WOB, so the oracle refactors its lateral system; the last above the string's
    weight: off bottom, WOB 0, not negative) and a record every few steps."""
    sim = Simulator(SimulationConfig(formation=SANDWICH))
    random_state(sim, np.random.default_rng(11), 6.0, 100e3)
    ref = ReferenceStepper(sim)
    assert ref.string_weight == pytest.approx(sim.string_weight, rel=1e-12)
    calls = [(40 * RPM, sim.hook_load_for(120e3), 3), (90 * RPM, sim.hook_load_for(60e3), 2),
             (90 * RPM, sim.string_weight + 5e3, 4)]
    steps = N_STEPS // len(calls)  # N_STEPS in all: the tolerance's premise
    for speed, hook, every in calls:
        expected = ref.advance(steps, speed, hook, record_every=every)
        actual = sim.advance(steps, speed, hook, record_every=every)
        assert sim.status == 0
        assert actual.shape == expected.shape == (steps // every, N_RECORD)
        for col in range(N_RECORD):
            assert_agree(actual[:, col], expected[:, col], f"record column {col}")
        for name in ("ul", "vl", "ut", "vt"):
            assert_agree(getattr(sim, name), getattr(ref, name), name)
    assert expected[:, R.WEIGHT_ON_BIT].tolist() == [0.0] * len(expected)


@pytest.mark.parametrize("override", [{"bit.axis_aligned": False},
                                      {"contact.enabled": False}])
def test_numpy_reference_matches_with_a_tilting_bit_and_without_wall_contact(override):
    """The two switches the default config leaves on one side: a bit free to tilt (its
    rotation DOF solved, not held, paper section 3.1.1) and the string's wall contact
    off (no wall forces on any node, though some lie beyond their clearance)."""
    sim = Simulator(replace(SimulationConfig(formation=SANDWICH), **override))
    random_state(sim, np.random.default_rng(12), 6.0, 100e3)
    actual, expected, _ = advance_both(sim)
    assert_agree(actual, expected, "records")
    if override == {"bit.axis_aligned": False}:
        assert np.any(sim.al[-1] != 0.0)  # the bit's tilt moved
    else:
        assert np.all(actual[:, R.MAX_WALL_FORCE] == 0.0)


def test_numpy_reference_unwinds_a_saturated_top_drive_as_the_kernel():
    """The anti-windup's other half in both implementations: the drive at its torque
    limit keeps integrating while the error pulls the other way (the set point ramps
    down below the top's speed, a large integral holds the torque at the limit), so the
    integral unwinds instead of freezing."""
    limit = 20e3
    sim = Simulator(replace(SimulationConfig(formation=SANDWICH),
                            **{"top_drive.max_torque": limit}))
    random_state(sim, np.random.default_rng(13), 6.0, 100e3)
    ki = sim.top_drive_gains[1]
    sim.state[S.SETPOINT_TARGET] = 40 * RPM
    sim.state[S.PI_INTEGRAL] = integral = 2.0 * limit / ki
    ref = ReferenceStepper(sim)
    expected = ref.advance(N_STEPS, record_every=1)
    actual = sim.advance(N_STEPS, record_every=1)
    assert_agree(sim.state, ref.state, "state")
    assert_agree(actual, expected, "records")
    assert np.all(actual[:5, R.MOTOR_TORQUE] == limit)  # saturated at first ...
    assert sim.state[S.PI_INTEGRAL] < integral  # ... and unwinding


@pytest.mark.parametrize("bit_model", ["mesoscopic", "macroscopic"])
def test_far_past_the_founder_point_both_implementations_cut_nothing(bit_model):
    """WOB 150 kN far above founder points of ~20-40 kN at a slope of 0.7: the depth of
    cut's decline ends at zero (no negative cut, no drilling backwards)."""
    rocks = tuple(dataclasses.replace(r, founder_wob_per_diameter=f, post_founder_slope=0.7)
                  for r, f in ((HARD, 2e5), (SOFT, 1e5)))
    formation = dataclasses.replace(SANDWICH, rocks=rocks)
    sim = Simulator(SimulationConfig(bit_model=bit_model, formation=formation))
    random_state(sim, np.random.default_rng(14), 6.0, 150e3)
    ref = ReferenceStepper(sim)
    expected = ref.advance(N_STEPS, record_every=1)
    actual = sim.advance(N_STEPS, record_every=1)
    assert_agree(sim.state, ref.state, "state")
    assert_agree(actual, expected, "records")
    assert sim.state[S.DEPTH_OF_CUT] == ref.state[S.DEPTH_OF_CUT] == 0.0
    assert np.all(expected[:, R.ROP] == 0.0)


@pytest.mark.parametrize("disturb, runaway", [
    (lambda sim: sim.ul.__setitem__((-2, 0), 1.2), True),  # the bit 1.2 m off centre
    (lambda sim: sim.vt.__setitem__(slice(None), 1.5e3), True),  # ~14,000 rpm
    (lambda sim: sim.vt.__setitem__(slice(None), 900.0), False),  # ~8,600 rpm: not yet
])
def test_the_numpy_reference_stops_a_runaway_as_the_kernel_does(disturb, runaway):
    """The oracle's runaway guard (1e3 rad/s, 1 m off centre): it stops at the step with
    Status.RUNAWAY and no record, where the kernel does."""
    from drill_env.physics.layout import Status

    sim = Simulator(SimulationConfig())
    sim.reset(OperatingPoint(60 * RPM, 100e3))
    disturb(sim)
    ref = ReferenceStepper(sim)
    records = ref.advance(1, record_every=1)
    sim.advance(1)
    assert ref.state[S.STATUS] == sim.status == (Status.RUNAWAY if runaway else 0)
    assert records.shape == ((0 if runaway else 1), N_RECORD)


def test_the_numpy_reference_refuses_a_pipe_held_straight():
    """The oracle covers lateral DOFs on every node only; a simulator whose pipe is held
    straight (solver.pipe_lateral=False) is refused by name, not integrated wrongly."""
    sim = Simulator(replace(SimulationConfig(), **{"solver.pipe_lateral": False}))
    assert sim.lateral_start > 0
    with pytest.raises(NotImplementedError, match="pipe_lateral"):
        ReferenceStepper(sim)


# --------------------------------------------------------------------------- top drive


def test_top_drive_set_point_ramps_at_the_acceleration_limit():
    """docs/model.md, top drive: the speed set point moves towards the target at
    ``max_acceleration`` (3 rad/s^2): from 60 rpm (2 pi rad/s) towards 120 rpm it is at
    2 pi + 3 rad/s after 1 s, and on target after 2 pi / 3 s."""
    sim = Simulator(SimulationConfig(solver=SolverConfig(lateral=False)))
    sim.reset(OperatingPoint(60 * RPM, 50e3))
    hook = sim.hook_load_for(50e3)
    sim.advance(round(1.0 / sim.dt), 120 * RPM, hook)
    assert sim.state[S.SETPOINT] == pytest.approx(2 * np.pi + 3.0, rel=1e-12)
    sim.advance(round(1.2 / sim.dt), 120 * RPM, hook)
    assert sim.state[S.SETPOINT] == 120 * RPM


def test_top_drive_set_point_ramps_down_at_the_acceleration_limit():
    """The same limit on the way down (drillers and policies lower the rpm as often as
    they raise it): from 120 rpm (4 pi rad/s) towards 60 rpm the set point is at
    4 pi - 3 rad/s after 1 s, and on target after 2 pi / 3 s."""
    sim = Simulator(SimulationConfig(solver=SolverConfig(lateral=False)))
    sim.reset(OperatingPoint(120 * RPM, 50e3))
    hook = sim.hook_load_for(50e3)
    sim.advance(round(1.0 / sim.dt), 60 * RPM, hook)
    assert sim.state[S.SETPOINT] == pytest.approx(4 * np.pi - 3.0, rel=1e-12)
    sim.advance(round(1.2 / sim.dt), 60 * RPM, hook)
    assert sim.state[S.SETPOINT] == 60 * RPM


def test_top_drive_torque_clamps_without_winding_up_its_integral():
    """A bit that cannot break free (static torque above the drive's 50 kN m): the motor
    sits at exactly the limit and the PI integral stops growing while it does
    (conditional integration): without it, 10 s of the ~5.6 rad/s error (set point 2 pi,
    top winding the string up at ~0.6 rad/s) would store ~56 rad, ~280 kN m at the
    default ki, to unwind before the drive could let go."""
    rock = {"formation.rocks[0].mu_max": 5.0, "formation.rocks[0].mu_min": 5.0}
    from drill_env.physics.config import replace

    config = replace(SimulationConfig(bit_model="macroscopic",
                                      solver=SolverConfig(lateral=False)), **rock)
    sim = Simulator(config)
    assert sim.steady_torque_on_bit(60 * RPM, 200e3) > 50e3 * 1.2
    sim.reset(OperatingPoint(60 * RPM, 200e3))
    hook = sim.hook_load_for(200e3)
    sim.vt[:] = 0.0  # stalled
    sim.advance(round(10.0 / sim.dt), 60 * RPM, hook)
    assert sim.state[S.MOTOR_TORQUE] == 50e3
    integral = sim.state[S.PI_INTEGRAL]
    sim.advance(round(10.0 / sim.dt), 60 * RPM, hook)
    assert sim.state[S.MOTOR_TORQUE] == 50e3
    assert sim.state[S.PI_INTEGRAL] == integral  # not one step integrated at the limit


def test_top_drive_brakes_with_at_most_its_torque_limit():
    """The torque limit holds both ways: the set point dropped from 120 rpm to 0 (the
    acceleration limit out of the way) and the PI loop asks for far more braking torque
    than the drive has; the motor sits at -max_torque while the string's inertia runs
    down, never below."""
    from drill_env.physics.config import replace

    config = replace(SimulationConfig(bit_model="macroscopic",
                                      solver=SolverConfig(lateral=False)),
                     **{"top_drive.max_acceleration": 1e6})
    sim = Simulator(config)
    sim.reset(OperatingPoint(120 * RPM, 0.0))
    limit = config.top_drive.max_torque
    rec = sim.advance(round(3.0 / sim.dt), 0.0, sim.hook_load_for(0.0), record_every=1)
    torque = rec[:, R.MOTOR_TORQUE]
    assert torque.min() == -limit and torque.max() <= limit


def _explicit_penalty_amplification(omega_dt: float, zeta: float) -> np.ndarray:
    """One step of the scheme on one DOF of unit mass whose spring and damper are
    explicit (docs/model.md section 5): forces at the Newmark predictors, the mass
    implicit; state (u, v, a) with omega = 1, so dt = omega_dt."""
    dt, beta, gamma = omega_dt, 0.25, 0.5
    columns = []
    for state in np.eye(3):
        u, v, a = state
        u_pred = u + dt * v + dt * dt * (0.5 - beta) * a
        v_pred = v + dt * (1.0 - gamma) * a
        a_new = -u_pred - 2.0 * zeta * v_pred
        columns.append([u_pred + beta * dt * dt * a_new, v_pred + gamma * dt * a_new, a_new])
    return np.array(columns).T


@pytest.mark.parametrize("zeta", [0.0, 0.1, 0.4])
def test_the_critical_step_of_the_explicit_contacts_is_the_damped_oscillators(zeta):
    """``Simulator.stable_time_step``'s limit (2 / w)(sqrt(1 + z^2) - z) against the
    spectral radius of the scheme's own amplification matrix, found by bisection."""
    def stable(x: float) -> bool:
        return max(abs(np.linalg.eigvals(_explicit_penalty_amplification(x, zeta)))) \
            <= 1.0 + 1e-9

    low, high = 0.1, 4.0
    assert stable(low) and not stable(high)
    for _ in range(60):
        mid = 0.5 * (low + high)
        low, high = (mid, high) if stable(mid) else (low, mid)
    assert low == pytest.approx(2.0 * (np.sqrt(1.0 + zeta * zeta) - zeta), rel=1e-6)


def test_a_soft_wall_with_strong_damping_limits_the_step_to_2m_over_c_and_names_its_rock():
    """Heavily damped (z >> 1), the critical step tends to 2 m / c; the form sqrt(1 + z^2)
    - z cancelled to 0 there and refused a 1e-12 N/m wall as needing a zero step. The
    refusal names the rock the user typed, not ``rocks[]``."""
    from drill_env.physics.config import replace
    from drill_env.physics.validation import ConfigError
    from drill_env.scenarios import make_scenario

    sim = Simulator(replace(SimulationConfig(), **{"contact.stiffness": 1e-12}))
    assert sim.dt == 2e-3
    config = make_scenario("paper_case2").config  # two rocks
    with pytest.raises(ConfigError, match=r"^formation\.rocks\[1\]\.wall_stiffness, "
                                          r"wall_damping: needs a step of 2\.1"):
        Simulator(replace(config, **{"formation.rocks[1].wall_stiffness": 1e10,
                                     "formation.rocks[1].wall_damping": 1e8}))


def _speed_loop_amplification(m: float, kp: float, ki: float, dt: float) -> np.ndarray:
    """One step of a rotor of inertia m under the kernel's PI loop, written from the
    scheme (not from the bound): Newmark average acceleration, the torque kp (0 - v_p)
    + ki I at the predictor speed with the integral of the step before, which forward
    Euler then advances. State (v, a, I)."""
    columns = []
    for v, a, integral in np.eye(3):
        v_pred = v + 0.5 * dt * a
        err = -v_pred
        a_new = (kp * err + ki * integral) / m
        columns.append([v_pred + 0.5 * dt * a_new, a_new, integral + err * dt])
    return np.array(columns).T


@pytest.mark.parametrize(("m", "kp", "ki"), [
    (1000.0, 14837.0, 5000.0), (5.0, 14837.0, 5000.0), (1000.0, 1187.0, 7762.0),
    (1.0, 1.0, 100.0), (1000.0, 100.0, 1e5), (1.0, 1.0, 0.0)])
def test_the_speed_loops_critical_step_is_the_schemes(m, kp, ki):
    """``top_drive.speed_loop_critical_step`` against the spectral radius of the scheme's
    own amplification matrix, the first unstable step found by a scan and bisection:
    damper-dominated (the stiff loop's gains), integral-dominated (the bound kp / ki)
    and without an integral (2 m / kp)."""
    from drill_env.physics.top_drive import speed_loop_critical_step

    def stable(dt: float) -> bool:
        return max(abs(np.linalg.eigvals(_speed_loop_amplification(m, kp, ki, dt)))) \
            <= 1.0 + 1e-12

    steps = np.geomspace(1e-7, 100.0, 2000)
    first = [stable(s) for s in steps].index(False)  # every case has a finite limit
    low, high = steps[first - 1], steps[first]
    for _ in range(80):
        mid = 0.5 * (low + high)
        low, high = (mid, high) if stable(mid) else (low, mid)
    assert speed_loop_critical_step(kp, ki, m) == pytest.approx(low, rel=1e-6)


@pytest.mark.parametrize("inertia", [20.0, 5.0, 0.5])
def test_the_top_drives_speed_loop_limits_the_step_on_a_light_rotor(inertia):
    """The PI loop acts on the top node explicitly (the test above): a rotor of
    5 kg m^2 at the default 2 ms step chattered between the motor's torque limits every
    step, the surface at 0.5 rad/s instead of 60 rpm; now the step shortens to half its
    critical step and it turns steadily."""
    from drill_env.physics.config import replace
    from drill_env.physics.top_drive import speed_loop_critical_step

    config = replace(SimulationConfig(bit_model="macroscopic"),
                     **{"top_drive.inertia": inertia, "solver.lateral": False})
    sim = Simulator(config)
    limit = speed_loop_critical_step(*sim.top_drive_gains, sim.tor_m[0])
    assert sim.dt == pytest.approx(min(2e-3, 0.5 * limit), rel=1e-12)
    assert sim.dt < 2e-3  # the default rotor (1000 kg m^2) leaves the step at 2 ms
    sim.reset(OperatingPoint(60 * RPM, 0.0))
    records = sim.run(3.0, 60 * RPM, sim.string_weight, record_every=10)
    np.testing.assert_allclose(records[-50:, R.SURFACE_SPEED], 60 * RPM, rtol=1e-6)


def _exact_from_rest(k: np.ndarray, c: np.ndarray, m: np.ndarray, v0: np.ndarray,
                     seconds: float) -> tuple[np.ndarray, np.ndarray]:
    """(displacement, velocity) at ``seconds`` of M x'' + C x' + K x = 0 (M = diag(m)) from
    zero displacement and velocity ``v0``: scipy's expm of [[0, I], [-M^-1 K, -M^-1 C]]."""
    n = len(m)
    a = np.zeros((2 * n, 2 * n))
    a[:n, n:] = np.eye(n)
    a[n:, :n] = -k / m[:, None]
    a[n:, n:] = -c / m[:, None]
    state = scipy.linalg.expm(a * seconds) @ np.concatenate([np.zeros(n), v0])
    return state[:n], state[n:]


def test_damped_torsional_transient_matches_the_matrix_exponential():
    """The integrator against scipy's exact solution of the same linear ODE: torsion
    only, the bit off bottom (no bit torque), the top drive's rotor free (PI gains 0:
    ``modes.torsional_system`` with ``top="top_drive"`` adds only its inertia; the PI
    integral is a rectangle rule, which a linear ODE would not reproduce to 1e-3), mud
    drag and Rayleigh damping, started at zero twist with the first mode's velocity.
    After 5 s (3 periods) the Newmark solution agrees with
    expm([[0, I], [-J^-1 K, -J^-1 C]]) to its O((w dt)^2) phase error (~1.4e-4 of the
    amplitude for the first mode, 3e-4 measured)."""
    from drill_env.physics.config import replace
    from drill_env.physics.modes import torsional_system

    config = replace(SimulationConfig(bit_model="macroscopic",
                                      solver=SolverConfig(lateral=False)),
                     **{"top_drive.proportional_gain": 0.0, "top_drive.integral_gain": 0.0})
    sim = Simulator(config)
    sim.reset(OperatingPoint(0.0, 0.0))
    k, c, j, _ = torsional_system(config, top="top_drive")
    values, vectors = scipy.linalg.eigh(k, np.diag(j))
    first = vectors[:, np.argmax(values > 1e-9 * values.max())]  # skip the drive's slow mode
    v0 = 0.5 * first / np.abs(first).max()  # rad/s
    sim.ut[:] = 0.0
    sim.vt[:] = v0
    sim.at[:] = -(c @ v0) / j  # the ODE's acceleration at t = 0
    seconds = 5.0
    sim.advance(round(seconds / sim.dt), 0.0, sim.hook_load_for(0.0))
    angle, speed = _exact_from_rest(k, c, j, v0, seconds)
    print(f"angle error {np.abs(sim.ut - angle).max() / np.abs(angle).max():.1e}, speed error "
          f"{np.abs(sim.vt - speed).max() / np.abs(speed).max():.1e}")
    assert np.abs(sim.ut - angle).max() < 1e-3 * np.abs(angle).max()
    assert np.abs(sim.vt - speed).max() < 5e-3 * np.abs(speed).max()
    assert np.abs(speed).max() < 0.9 * 0.5  # the damping did act


@pytest.mark.parametrize("where", ["centre", "lower half-power", "upper half-power"])
def test_soft_torque_band_pass_has_unit_gain_at_its_centre_and_half_power_at_its_edges(where):
    """The SoftTorque filter H = 2 z w0 s / (s^2 + 2 z w0 s + w0^2) (docs/model.md, top
    drive), driven in the kernel by a sinusoidal string torque: gain 1 and phase 0 at w0;
    at w0 (sqrt(1 + z^2) -+ z) (its -3 dB band, 2 z w0 wide) gain 1/sqrt(2) and phase
    +-45 deg. Amplitude and phase fitted over the last 5 periods of 40."""

    sim = Simulator(SimulationConfig(top_drive=dataclasses.replace(
        SimulationConfig().top_drive, controller="soft_torque")))
    p, state = sim.params.copy(), np.zeros(N_STATE)
    w0, zeta, gain = p[P.TD_FILTER_W], p[P.TD_FILTER_ZETA], p[P.TD_FEEDBACK_GAIN]
    edge = {"lower half-power": -zeta, "upper half-power": zeta}.get(where)
    w = w0 if edge is None else w0 * (np.sqrt(1.0 + zeta * zeta) + edge)
    dt = p[P.DT]
    t = np.arange(round(40 * 2 * np.pi / w / dt)) * dt
    out = np.empty(t.size)
    for k, time in enumerate(t):
        state[S.SURFACE_TORQUE] = np.sin(w * time)
        out[k] = ig._torque_feedback(p, state, p[P.TD_FEEDBACK]) / gain
    last = t > t[-1] - 5 * 2 * np.pi / w
    basis = np.column_stack([np.sin(w * t[last]), np.cos(w * t[last])])
    (a, b), *_ = np.linalg.lstsq(basis, out[last], rcond=None)
    expected_gain = 1.0 if where == "centre" else 1.0 / np.sqrt(2.0)
    expected_phase = {"centre": 0.0, "lower half-power": np.pi / 4,
                      "upper half-power": -np.pi / 4}[where]
    # semi-implicit Euler: O(w dt) off the continuous filter, 3e-3 at the upper edge
    assert np.hypot(a, b) == pytest.approx(expected_gain, rel=0.01)
    assert np.arctan2(b, a) == pytest.approx(expected_phase, abs=0.01)


def test_the_macroscopic_bit_turns_against_a_bit_mu_wob_and_drills_nothing_backward():
    """Eq. (38) in the step: the macroscopic bit's torque is a_bit mu(omega) WOB (a_bit
    the midpoint lever arm, tested by hand in test_bit.py; mu of eq. 39 at the bit's
    speed), here in steady rotation at 120 rpm in hard rock (above the stick-slip
    threshold); and a bit turning backward drills nothing (ROP = delta max(omega, 0) /
    2 pi: the depth does not move while it slips backward)."""
    from drill_env.physics.bit import bit_lever_arm

    config = SimulationConfig(bit_model="macroscopic", solver=SolverConfig(lateral=False),
                              formation=FormationConfig(rocks=(HARD,)))
    sim = Simulator(config)
    sim.reset(OperatingPoint(120 * RPM, 100e3))
    sim.run(10.0)
    speeds, torques, wobs = [], [], []
    for _ in range(500):
        sim.advance(1)
        speeds.append(sim.bit_speed)
        torques.append(sim.torque_on_bit)
        wobs.append(sim.weight_on_bit)
    omega = np.array(speeds)
    assert np.ptp(omega) < 1e-3 * omega.mean()  # steady
    mu = HARD.mu_min + (HARD.mu_max - HARD.mu_min) * np.exp(-omega / HARD.st1)
    expected = bit_lever_arm(config.bit) * mu * np.array(wobs)
    np.testing.assert_allclose(torques, expected, rtol=1e-4)
    assert np.mean(wobs) == pytest.approx(100e3, rel=1e-6)
    # backward: the whole string turning at -20 rad/s, the bit slipping back
    sim.vt[:] = -20.0
    depth = sim.state[S.DEPTH]
    for _ in range(20):
        sim.advance(1)
        assert sim.bit_speed < 0.0 and sim.state[S.STUCK] == 0.0
        assert sim.torque_on_bit < 0.0  # the rock resists the backward turn
    assert sim.state[S.DEPTH] == depth


def test_the_cutting_force_follows_the_bit_torque_stuck_slipping_and_backward():
    """Eqs. (46)-(53) through the step: blades at 0, 90 and 180 deg in one rock cut with
    the torque mu W lever and the 90 deg blade's force mu W / 3 (the 0 and 180 deg
    blades cancel), so the force is TOB / (3 lever) along (cos phi, sin phi), phi the
    bit angle, whatever the bit does: slipping forward (mu(omega)), stuck (the static
    force scaled by the torque that holds the bit) and slipping backward (the force
    turns with the torque). Torsion only (the bit stays centred: no gauge contact);
    stick-slip at 40 rpm, and a start with the bit turning backward."""
    from drill_env.physics.bit import Blade, blade_arrays

    bit_cfg = BitConfig(blade_angles=(0.0, 90.0, 180.0), face_start=(0.02,) * 3,
                        face_end=(0.07,) * 3, gauge_length=(0.05,) * 3,
                        shoulder_length=(0.0,) * 3)
    blade = blade_arrays(bit_cfg)[0]
    face, shoulder = blade[Blade.R_B] - blade[Blade.R_A], blade[Blade.L_SH]
    lever = (face * 0.5 * (blade[Blade.R_A] + blade[Blade.R_B])  # eq. (34), midpoint rule
             + shoulder * 0.5 * (blade[Blade.R_B] + blade[Blade.R_C])) / (face + shoulder)
    sim = Simulator(SimulationConfig(bit=bit_cfg, solver=SolverConfig(lateral=False),
                                     formation=FormationConfig(rocks=(HARD,))))
    sim.reset(OperatingPoint(40 * RPM, 100e3))
    sim.vt[:] = -20.0  # the string turning backward (rad/s): the bit slips backward
    seen = {"forward": 0, "stuck": 0, "backward": 0}
    for _ in range(6000):
        speed = sim.bit_speed
        sim.advance(1)
        # the loads act at the Newmark predictor: the angle less beta dt^2 a_(n+1) (to
        # ~2e-5 rad: a bit that sticks is held at rest without that acceleration)
        phi = sim.bit_angle - 0.25 * sim.dt**2 * sim.at[-1]
        tob, force = sim.torque_on_bit, sim.bit_lateral_force
        along = force @ np.array([np.cos(phi), np.sin(phi)])
        scale = 1e5 * HARD.mu_max / 3  # the largest force, static
        assert along == pytest.approx(tob / (3 * lever), abs=1e-4 * scale)
        assert abs(force @ np.array([-np.sin(phi), np.cos(phi)])) < 1e-4 * scale
        kind = "stuck" if sim.state[S.STUCK] > 0 else ("backward" if speed < 0 else "forward")
        seen[kind] += 1
    assert seen["backward"] > 10 and seen["stuck"] > 100 and seen["forward"] > 100, seen


def test_z_torque_high_pass_is_the_backward_euler_filter_of_scipy():
    """The ZTorque filter H = s / (s + w_c) (docs/model.md, top drive) in the kernel,
    driven by a random string torque, against scipy's backward-Euler discretisation of the
    same transfer function (``cont2discrete(..., method="backward_diff")``, run by
    ``dlsim``): the same difference equation, reached from the other side (an input-output
    recurrence rather than the kernel's low-pass state), so equal to rounding. Its DC gain
    is 0: a held torque is not fed back."""
    import scipy.signal

    from drill_env.physics.layout import P

    sim = Simulator(SimulationConfig(top_drive=dataclasses.replace(
        SimulationConfig().top_drive, controller="z_torque")))
    p, state = sim.params.copy(), np.zeros(N_STATE)
    w, gain, dt = p[P.TD_FILTER_W], p[P.TD_FEEDBACK_GAIN], p[P.DT]
    assert w * dt > 1e-4  # a corner the step resolves, so the discretisation shows
    torque = np.random.default_rng(7).normal(0.0, 1e4, 4000)  # N m
    out = np.empty(torque.size)
    for k, value in enumerate(torque):
        state[S.SURFACE_TORQUE] = value
        out[k] = ig._torque_feedback(p, state, p[P.TD_FEEDBACK]) / gain
    num, den, _ = scipy.signal.cont2discrete(([1.0, 0.0], [1.0, w]), dt, method="backward_diff")
    _, expected = scipy.signal.dlsim((num.ravel(), den, dt), torque)
    np.testing.assert_allclose(out, expected.ravel(), rtol=0.0, atol=1e-9 * np.abs(torque).max())
    state[:] = 0.0
    for _ in range(round(10.0 / (w * dt))):  # ten time constants of a held torque
        state[S.SURFACE_TORQUE] = 5e3
        held = ig._torque_feedback(p, state, p[P.TD_FEEDBACK]) / gain
    assert abs(held) < 1e-3 * 5e3


def _lateral_transient_error(time_step: float) -> tuple[float, float, float]:
    """Max error of the lateral displacements after 1 s against scipy's expm of the same
    damped ODE (M u'' + (a M + b K) u' + (K + K_g) u = 0, top node pinned, bit tilt held),
    started in a mode near 8 Hz with a 1 mm/s velocity, relative to the mode's
    displacement amplitude (1 mm/s over w); also the mode's w and damping ratio."""
    from drill_env.physics.fem import from_band

    config = SimulationConfig(bit_model="macroscopic", solver=SolverConfig(time_step=time_step))
    sim = Simulator(config)
    assert sim.dt == time_step
    sim.reset(OperatingPoint(0.0, 0.0))
    k = from_band(sim.lat_k + sim.lat_kg_weight)  # K + K_g at zero WOB
    m = sim.lat_m
    c = config.damping.mass_proportional * np.diag(m) + from_band(sim.lat_k_damp)
    n = len(m)
    free = np.arange(1, n - 1)  # row/column 0 and the bit tilt carry no force
    ix = np.ix_(free, free)
    values, vectors = scipy.linalg.eigh(k[ix], np.diag(m[free]))
    mode = np.argmin(np.abs(np.sqrt(np.maximum(values, 0.0)) / (2 * np.pi) - 8.0))
    shape = np.zeros(n)
    shape[free] = vectors[:, mode] / np.abs(vectors[:, mode]).max()
    v0 = 1e-3 * shape
    sim.ul[:] = 0.0
    sim.vl[:] = 0.0
    sim.al[:] = 0.0
    sim.vl[:, 0] = v0
    sim.al[free, 0] = -(c[ix] @ v0[free]) / m[free]
    sim.advance(round(1.0 / sim.dt), 0.0, sim.hook_load_for(0.0))
    exact, _ = _exact_from_rest(k[ix], c[ix], m[free], v0[free], 1.0)
    assert np.abs(sim.ul[free, 1]).max() == 0.0  # the other plane stays at rest
    w = float(np.sqrt(values[mode]))
    zeta = config.damping.mass_proportional / (2 * w) + \
        config.damping.stiffness_proportional * w / 2  # Rayleigh
    return float(np.abs(sim.ul[free, 0] - exact).max() / (1e-3 / w)), w, zeta


def test_damped_lateral_transient_converges_to_the_matrix_exponential_at_second_order():
    """The lateral Newmark solution against scipy's exact solution of the same linear ODE:
    halving the step divides the error by ~4 (the average-acceleration scheme is second
    order), and its size is the scheme's period error: a phase lag of (w dt)^2 / 12 per
    radian, so after t the displacement is off by that lag x w t x |cos w t| x the decay
    exp(-zeta w t) of the amplitude (8.5 Hz mode, 1 s: 0.65 % at 1 ms)."""
    (coarse, _, _), (fine, w, zeta) = (_lateral_transient_error(dt) for dt in (0.002, 0.001))
    print(f"lateral transient error: {coarse:.2e} at 2 ms, {fine:.2e} at 1 ms")
    lag = (w * 0.001) ** 2 / 12 * w * 1.0
    assert fine == pytest.approx(lag * abs(np.cos(w)) * np.exp(-zeta * w), rel=0.1)
    assert 3.5 < coarse / fine < 4.5


def _bit_thrown_at_the_wall(fraction: float, time_step: float, degrees: float) -> float:
    """Largest bit offset / clearance over 0.3 s after the bit, at rest and 1 % short of
    the wall, is thrown at it at 1 m/s, ``degrees`` from a blade (off bottom, at rest);
    inf if the kernel stopped on a runaway."""
    import math

    cfg = replace(SimulationConfig(), **{"solver.time_step": time_step,
                                         "solver.critical_step_fraction": fraction})
    sim = Simulator(cfg)
    sim.reset(OperatingPoint(0.0, 0.0))
    c, angle = cfg.bit.gauge_clearance, math.radians(degrees)
    sim.ul[-2] = 0.99 * c * math.cos(angle), 0.99 * c * math.sin(angle)
    sim.vl[-2] = math.cos(angle), math.sin(angle)
    largest = 0.0
    for _ in range(round(0.3 / sim.dt)):
        sim.advance(1, 0.0, sim.string_weight)
        if sim.status:
            return math.inf
        largest = max(largest, math.hypot(*sim.ul[-2]) / c)
    return largest


def test_two_gauge_pads_on_the_wall_fit_under_the_largest_allowed_step_fraction():
    """Thrown between two of its six blades, the bit presses both gauge pads on the wall:
    2 k cos^2 30 = 1.5 k, so the explicit limit is 1/sqrt(1.5) = 0.82 of the one-pad
    critical step the simulator computes (at 0.9 of it the bit ran away in 7 steps, when
    the config still allowed it). At 0.8, the most the config now allows, it bounces off
    the wall between two blades and at a blade alike."""
    from drill_env.physics.validation import ConfigError

    with pytest.raises(ConfigError, match="critical_step_fraction"):
        replace(SimulationConfig(), **{"solver.critical_step_fraction": 0.9})
    for degrees in (30.0, 0.0):
        assert _bit_thrown_at_the_wall(0.8, 4.0e-3, degrees) < 1.5


@pytest.mark.parametrize("disturb, runaway", [
    (lambda sim: sim.ul.__setitem__((-2, 0), 1.2), True),  # the bit 1.2 m off centre
    (lambda sim: sim.vt.__setitem__(slice(None), 1.5e3), True),  # ~14,000 rpm
    (lambda sim: sim.vt.__setitem__(slice(None), 900.0), False),  # ~8,600 rpm: not yet
])
def test_a_runaway_state_stops_the_kernel_with_its_status(disturb, runaway):
    """The kernel's runaway guard (docs: above 1e3 rad/s, ~9,500 rpm, or 1 m off the
    hole's centre the state is a numerical runaway, not drilling): it stops at the step
    with Status.RUNAWAY and its message, where an episode ends with a reason."""
    from drill_env.physics.layout import Status

    sim = Simulator(SimulationConfig())
    sim.reset(OperatingPoint(60 * RPM, 100e3))
    disturb(sim)
    sim.advance(1)
    assert sim.status == (Status.RUNAWAY if runaway else 0), sim.status_message
    if runaway:
        assert sim.status_message.startswith("simulation diverged")
        assert "out of range" in sim.status_message  # the runaway's reason (Status.RUNAWAY)
        time = sim.time
        sim.advance(5)  # a stopped simulator does not run on
        assert sim.time == time


def test_a_speed_correction_shifts_the_pi_set_point():
    """A policy's speed correction (task 1) adds to the top drive's set point inside the
    kernel: at the first step the motor torque moves by exactly kp x the correction (the
    PI's proportional part; its integral starts from the same state), and the loop, whose
    integral leaves no steady error, then holds the surface speed that much higher."""
    config = replace(SimulationConfig(), **{"solver.lateral": False,
                                            "bit_model": "macroscopic"})
    torques, speeds = [], []
    for correction in (0.0, 1.0):
        sim = Simulator(config)
        sim.reset(OperatingPoint(120 * RPM, 60e3))
        sim.speed_correction = correction
        sim.advance(1)
        torques.append(sim.state[S.MOTOR_TORQUE])
        rec = sim.run(40.0, record_every=10)
        speeds.append(rec[rec[:, R.TIME] > 30.0, R.SURFACE_SPEED].mean())
    kp, _ = Simulator(config).top_drive_gains
    assert torques[1] - torques[0] == pytest.approx(kp * 1.0, rel=1e-9)
    assert speeds[1] - speeds[0] == pytest.approx(1.0, rel=0.01)
