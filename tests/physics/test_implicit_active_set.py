"""The active set of implicit contacts (``implicit_contact.resolve``) and what a step with
them reports, against independent solves.

``resolve`` is called directly on walls and gauge pads placed about the wall with random
loads, and its result compared with scipy's dense solve of the coupled planes whose
right-hand side takes the joined terms' linearised forces and gives back the left ones';
then the complementarity (no final term pulls, no left-out contact ends inside pushing).
After simulator steps: the reported wall and gauge forces against the end-of-step
linearisation recovered from the state, the cached columns of A^-1 after a refactor,
pickling mid-contact, and the option in every solver mode. (From an outside review,
2026-12-03: eight deliberate breaks of the active set survived the first test file.)
"""

from __future__ import annotations

import math
import pickle
import warnings

import numpy as np
import pytest
import scipy.linalg

from drill_env.physics import bit as bitmod
from drill_env.physics.bit import PAD, BitOut, Blade, Segment
from drill_env.physics.config import SimulationConfig, replace
from drill_env.physics.fem import from_band
from drill_env.physics.formation import Rock
from drill_env.physics.implicit_contact import resolve
from drill_env.physics.layout import TERM, Motion, P
from drill_env.physics.simulator import OperatingPoint, Simulator
from drill_env.physics.units import RPM
from drill_env.scenarios import make_scenario

IMPLICIT = {"solver.implicit_contacts": True}


def settled(step: float = 0.006) -> Simulator:
    """The paper string at 60 rpm / 60 kN, one step taken (its lateral matrix factorised)."""
    sim = Simulator(replace(SimulationConfig(), **IMPLICIT, **{"solver.time_step": step}))
    sim.reset(OperatingPoint(60 * RPM, 60e3))
    sim.advance(1)
    return sim


def pad_penalty(a, n_pieces: int, i: int) -> tuple[float, float]:
    """Stiffness and damping of all of pad i's pieces, written out again."""
    pieces = a.bit.pieces
    rp = a.bit.formation.rock_params
    l_g = a.bit.blades[i, Blade.L_G]
    k = c = 0.0
    for q in range(n_pieces):
        if pieces.blade[q] == i and pieces.segment[q] == Segment.GAUGE:
            k += pieces.length[q] / l_g * rp[pieces.rock[q], Rock.WALL_STIFFNESS]
            c += pieces.length[q] / l_g * rp[pieces.rock[q], Rock.WALL_DAMPING]
    return k, c


def run_case(seed: int, with_pads: bool, step: float = 0.006, scale: float = 3e5) -> None:
    """Eight wall nodes (and the bit's pads) within 2 mm of the wall, random forces on
    them; ``resolve`` against the dense solve and the complementarity."""
    sim = settled(step)
    a = sim.kernel_arrays()
    p = a.params
    A = from_band(sim.lat_work_band)
    n = A.shape[0]
    l0 = int(p[P.LATERAL_START])
    nn = a.motion.ut.shape[0]
    lb = 2 * (nn - 1 - l0)
    rng = np.random.default_rng(seed)
    ul = np.zeros((2, n))
    vl = np.zeros((2, n))
    nodes = a.nodes
    cand = [k for k in range(l0 + 1, nn) if nodes.contact[k] > 0]
    chosen = rng.choice(cand, size=min(8, len(cand)), replace=False)
    h3 = p[P.BETA] * p[P.DT] ** 2
    h4 = p[P.GAMMA] * p[P.DT]
    K, C = p[P.WALL_K], p[P.WALL_C]
    kap = h3 * K + h4 * C
    terms = a.implicit.terms
    count = 0
    for k in chosen:
        j = 2 * (k - l0)
        ang = rng.uniform(0, 2 * math.pi)
        r = nodes.clearance[k] + rng.uniform(-2e-3, 2e-3)
        ul[0, j], ul[1, j] = r * math.cos(ang), r * math.sin(ang)
        vr = rng.normal(0, 0.05)
        vl[0, j], vl[1, j] = vr * math.cos(ang), vr * math.sin(ang)
    # initial terms as _wall_contacts
    for k in range(l0 + 1, nn):
        j = 2 * (k - l0)
        if nodes.contact[k] == 0:
            continue
        x, y = ul[0, j], ul[1, j]
        r = math.hypot(x, y)
        if r <= nodes.clearance[k]:
            continue
        f = K * (r - nodes.clearance[k]) + C * (x * vl[0, j] + y * vl[1, j]) / r
        if f <= 0:
            continue
        row = terms[count]
        row[:] = 0
        row[TERM.NODE], row[TERM.DOF], row[TERM.NX], row[TERM.NY] = k, j, x / r, y / r
        row[TERM.KAPPA], row[TERM.FORCE] = kap, f
        count += 1
    n_pieces = 0
    pads = a.bit.pieces.pads
    if with_pads:
        ang = rng.uniform(0, 2 * math.pi)
        off = sim.config.bit.hole_radius - sim.config.bit.gauge_radius + 0.8e-3
        bx, by = off * math.cos(ang), off * math.sin(ang)
        bvx, bvy = rng.normal(0, 0.05, 2)
        ul[0, lb], ul[1, lb] = bx, by
        vl[0, lb], vl[1, lb] = bvx, bvy
        out = bitmod.make_loads_out(a.bit.formation.rock_params.shape[0])
        n_pieces = bitmod.mesoscopic_bit_loads(
            a.bit.blades,
            a.bit.formation,
            a.bit.pieces,
            bitmod.BitKinematics(bx, by, bvx, bvy, sim.depth, 0.0, 5.0),
            60e3,
            bitmod.GaugeContact(p[P.HOLE_RADIUS], 0.0, p[P.V_REG], p[P.GAUGE_FRICTION], True),
            out,
        )
        for i in range(pads.shape[0]):
            pad = pads[i]
            if pad[PAD.ON] > 0 and pad[PAD.FORCE] > 0:
                row = terms[count]
                row[:] = 0
                row[TERM.NODE], row[TERM.DOF] = -1.0 - i, lb
                row[TERM.NX], row[TERM.NY] = pad[PAD.EX], pad[PAD.EY]
                row[TERM.KAPPA] = h3 * pad[PAD.STIFFNESS] + h4 * pad[PAD.DAMPING]
                row[TERM.FORCE] = pad[PAD.FORCE]
                count += 1
    else:
        pads[:, PAD.ON] = 0.0
    initial = {terms[t, TERM.NODE]: terms[t].copy() for t in range(count)}
    # uncoupled accelerations: random forces at the chosen nodes
    r = np.zeros((2, n))
    for k in list(chosen) + ([nn - 1] if with_pads else []):
        j = 2 * (k - l0)
        r[:, j] = rng.normal(0, scale, 2)
    r[:, 0] = 0
    acc_in = np.linalg.solve(A, r.T).T
    acc = acc_in.copy()
    m = Motion(
        ul,
        vl,
        np.zeros((2, n)),
        a.motion.ut.copy(),
        a.motion.vt.copy(),
        a.motion.at.copy(),
        a.motion.stick.copy(),
    )
    cnt = resolve(p, a.implicit, a.lateral.factor, count, acc, m, nodes, l0, a.bit, n_pieces, lb)
    fin = terms[:cnt].copy()
    y = a.implicit.gram[:cnt, cnt].copy()
    assert np.all(a.implicit.member == 0.0), "member invariant"
    # dense check
    Mbig = scipy.linalg.block_diag(A, A)
    rhs = np.concatenate([A @ acc_in[0], A @ acc_in[1]])
    final_ids = set(fin[:, TERM.NODE])

    def w(dof, nx, ny):
        v = np.zeros(2 * n)
        v[dof] = nx
        v[n + dof] = ny
        return v

    for row in fin:
        wv = w(int(row[TERM.DOF]), row[TERM.NX], row[TERM.NY])
        Mbig += row[TERM.KAPPA] * np.outer(wv, wv)
        if row[TERM.NODE] not in initial:
            # independent linearised force
            node = row[TERM.NODE]
            if node >= 0:
                k = int(node)
                j = 2 * (k - l0)
                rr = math.hypot(ul[0, j], ul[1, j])
                nx, ny = ul[0, j] / rr, ul[1, j] / rr
                f = K * (rr - nodes.clearance[k]) + C * (nx * vl[0, j] + ny * vl[1, j])
                assert row[TERM.KAPPA] == pytest.approx(kap)
            else:
                i = int(-1 - node)
                kp, cp = pad_penalty(a, n_pieces, i)
                f = kp * pads[i, PAD.PENETRATION] + cp * pads[i, PAD.RATE]
                assert row[TERM.KAPPA] == pytest.approx(h3 * kp + h4 * cp)
            assert row[TERM.FORCE] == pytest.approx(f, rel=1e-9, abs=1e-6)
            rhs -= row[TERM.FORCE] * wv
    for node, row in initial.items():
        if node not in final_ids:
            rhs += row[TERM.FORCE] * w(int(row[TERM.DOF]), row[TERM.NX], row[TERM.NY])
    expected = scipy.linalg.solve(Mbig, rhs).reshape(2, n)
    sc = np.max(np.abs(expected))
    np.testing.assert_allclose(acc, expected, rtol=0, atol=1e-8 * sc)
    for t, row in enumerate(fin):
        d = int(row[TERM.DOF])
        along = row[TERM.NX] * acc[0, d] + row[TERM.NY] * acc[1, d]
        assert y[t] == pytest.approx(row[TERM.KAPPA] * along, rel=1e-7, abs=1e-6)
    # complementarity: no final term pulls, no left-out contact ends inside pushing
    assert np.all(fin[:, TERM.FORCE] + y >= -1e-6 * (1 + np.abs(y)))
    members = set(int(v) for v in fin[:, TERM.NODE])
    for k in range(l0 + 1, nn):
        if nodes.contact[k] == 0 or k in members:
            continue
        j = 2 * (k - l0)
        rr = math.hypot(ul[0, j], ul[1, j])
        if rr == 0:
            continue
        nx, ny = ul[0, j] / rr, ul[1, j] / rr
        along = nx * acc[0, j] + ny * acc[1, j]
        f = K * (rr - nodes.clearance[k]) + C * (nx * vl[0, j] + ny * vl[1, j])
        assert rr - nodes.clearance[k] + h3 * along <= 1e-12 or f + kap * along <= 1e-6, k
    for i in range(pads.shape[0] if with_pads else 0):
        if pads[i, PAD.ON] == 0 or (-1 - i) in members:
            continue
        nx, ny = pads[i, PAD.EX], pads[i, PAD.EY]
        along = nx * acc[0, lb] + ny * acc[1, lb]
        kp, cp = pad_penalty(a, n_pieces, i)
        f = kp * pads[i, PAD.PENETRATION] + cp * pads[i, PAD.RATE]
        assert (
            pads[i, PAD.PENETRATION] + h3 * along <= 1e-12
            or f + (h3 * kp + h4 * cp) * along <= 1e-6
        ), i


@pytest.mark.parametrize("scale", [3e4, 3e5, 3e6])
@pytest.mark.parametrize("seed", range(12))
@pytest.mark.parametrize("with_pads", [False, True])
def test_the_active_set_matches_a_dense_solve_and_is_complementary(seed, with_pads, scale):
    run_case(seed, with_pads, scale=scale)


def pushed(cfg: SimulationConfig, rpm: float = 60.0, wob: float = 60e3) -> Simulator:
    """A settled simulator with its lowest 20 lateral nodes pushed towards the wall."""
    with warnings.catch_warnings():  # a curved hole, a straight pipe under compression
        warnings.simplefilter("ignore", RuntimeWarning)
        sim = Simulator(cfg)
        sim.reset(OperatingPoint(rpm * RPM, wob))
    if sim.vl.shape[0] > 20:
        sim.vl[0::2, 0][-20:] = 0.5
    return sim


#: Solver modes the option must run in (torsion only: it does nothing).
CASES = {
    "default": {},
    "no_contact": {"contact.enabled": False},
    "macro": {"bit_model": "macroscopic"},
    "torsion_only": {"solver.lateral": False},
    "no_pipe_lateral": {"solver.pipe_lateral": False},
    "long_step": {"solver.time_step": 0.008},
}


@pytest.mark.parametrize("case", list(CASES))
def test_every_solver_mode_runs_and_leaves_no_member_behind(case):
    sim = pushed(replace(SimulationConfig(), **IMPLICIT, **CASES[case]))
    for _ in range(40):
        sim.advance(10)
        assert sim.status == 0
        assert np.all(sim.implicit.member == 0.0)
    assert np.all(np.isfinite(sim.ul))


def test_a_curved_hole_runs_and_leaves_no_member_behind():
    sc = make_scenario("j_shaped")
    sim = pushed(replace(sc.config, **IMPLICIT), wob=sc.weight_on_bit)
    for _ in range(20):
        sim.advance(20)
        assert sim.status == 0
        assert np.all(sim.implicit.member == 0.0)


@pytest.mark.parametrize("case", ["default", "macro", "long_step"])
def test_a_simulator_pickled_mid_contact_continues_bit_identically(case):
    cfg = replace(SimulationConfig(), **IMPLICIT, **CASES[case])
    a = pushed(cfg)
    a.advance(60)
    assert np.max(a.contact_forces) > 0
    b = pickle.loads(pickle.dumps(a))
    ra = a.advance(200, 60 * RPM, a.hook_load_for(65e3), 5)
    rb = b.advance(200, 60 * RPM, b.hook_load_for(65e3), 5)
    np.testing.assert_array_equal(ra, rb)
    np.testing.assert_array_equal(a.ul, b.ul)
    np.testing.assert_array_equal(a.contact_forces, b.contact_forces)


def test_reported_wall_forces_are_end_of_step_linearised():
    """After a step: a reported node force equals K(r_p-c)+C n.v_p + kappa n.a with the
    predictors recovered from the end state; a non-reported node in reach doesn't push."""
    sim = pushed(replace(SimulationConfig(), **IMPLICIT, **{"solver.time_step": 0.006}))
    p = sim.params
    h3 = p[P.BETA] * p[P.DT] ** 2
    h4 = p[P.GAMMA] * p[P.DT]
    K, C = p[P.WALL_K], p[P.WALL_C]
    kap = h3 * K + h4 * C
    checked = 0
    for _ in range(100):
        sim.advance(1)
        ul, vl, al = sim.ul, sim.vl, sim.al  # (n, 2) views for lateral nodes
        l0 = sim.lateral_start
        for k in range(l0 + 1, sim.n_nodes):
            if sim.node_contact[k] == 0:
                continue
            j = k - l0
            u = ul[2 * j]
            v = vl[2 * j]
            a = al[2 * j]
            up = u - h3 * a
            vp = v - h4 * a
            r = math.hypot(*up)
            if r == 0:
                continue
            nrm = up / r
            f_end = K * (r - sim.node_clearance[k]) + C * nrm @ vp + kap * (nrm @ a)
            rep = sim.node_force[k]
            if rep > 0:
                assert rep == pytest.approx(f_end, rel=1e-6, abs=1e-3)
                checked += 1
            elif r - sim.node_clearance[k] + h3 * (nrm @ a) > 0:
                assert f_end <= 1e-6 * max(1.0, abs(kap * (nrm @ a)))
    assert checked > 10


def test_cached_columns_follow_a_refactor():
    sim = pushed(replace(SimulationConfig(), **IMPLICIT))
    sim.advance(60, 60 * RPM, sim.hook_load_for(60e3))
    assert sim.implicit.ready.any()
    sim.advance(1, 60 * RPM, sim.hook_load_for(90e3))  # refactor at the new WOB
    A = from_band(sim.lat_work_band)
    for node in np.flatnonzero(sim.implicit.ready):
        e = np.zeros(A.shape[0])
        e[2 * node] = 1.0
        np.testing.assert_allclose(
            sim.implicit.columns[node], np.linalg.solve(A, e), rtol=1e-8, atol=1e-12
        )


@pytest.mark.parametrize("step", [0.004, 0.006])
def test_the_reported_gauge_force_is_the_end_of_step_one(step):
    """The bit's gauge force after a step: the bit's own at the predictors with each
    pushing pad's normal force replaced by its end-of-step linearisation (steps where a
    pad may have joined are skipped)."""
    sim = Simulator(replace(SimulationConfig(), **IMPLICIT, **{"solver.time_step": step}))
    sim.reset(OperatingPoint(60 * RPM, 60e3))
    sim.vl[0::2, 0][-20:] = 0.5
    p = sim.params
    h3 = p[P.BETA] * p[P.DT] ** 2
    h4 = p[P.GAMMA] * p[P.DT]
    checked = 0
    for _ in range(300):
        sim.advance(1)
        pads = sim.bit_scratch.pads
        a = sim.al[-2]  # the bit's lateral acceleration (x, y)
        if not (pads[:, PAD.FORCE] > 0).any():
            continue
        gx, gy = sim.bit_out[BitOut.GAUGE_X], sim.bit_out[BitOut.GAUGE_Y]
        skip = False
        for i in range(pads.shape[0]):
            if pads[i, PAD.ON] == 0:
                continue
            e = pads[i, [PAD.EX, PAD.EY]]
            along = e @ a
            if pads[i, PAD.FORCE] > 0:
                f = pads[i, PAD.FORCE]
                end = max(
                    f + (h3 * pads[i, PAD.STIFFNESS] + h4 * pads[i, PAD.DAMPING]) * along, 0.0
                )
                gx += (f - end) * e[0]
                gy += (f - end) * e[1]
            elif pads[i, PAD.PENETRATION] + h3 * along > 0:
                skip = True  # may have joined: not checked here
        if skip:
            continue
        assert sim.contact_forces[-1] == pytest.approx(math.hypot(gx, gy), rel=1e-6, abs=1e-3)
        checked += 1
    assert checked > 5


def test_a_reset_after_contact_runs_as_a_fresh_simulator():
    """Implicit contacts keep the last step's normal forces for the friction (the walls'
    and the gauge pads'): a reset clears them, and an episode after a whirl is the
    episode of a fresh simulator, float for float."""
    config = replace(SimulationConfig(), **IMPLICIT, **{"solver.time_step": 0.008})
    used = pushed(config)
    pads = used.bit_scratch.pads
    for _ in range(2000):  # until the gauge pads press at the end of a step
        used.advance(1)
        if pads[:, PAD.END_FORCE].max() > 0.0:
            break
    assert pads[:, PAD.END_FORCE].max() > 0.0
    fresh = Simulator(config)
    for sim in (used, fresh):
        sim.reset(OperatingPoint(60 * RPM, 60e3))
        sim.vl[0::2, 0][-20:] = 0.5
    assert not pads[:, PAD.END_FORCE].any()
    np.testing.assert_array_equal(used.advance(100, record_every=1),
                                  fresh.advance(100, record_every=1))
