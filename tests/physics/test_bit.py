"""Mesoscopic bit (paper section 3): blade splitting, front and gauge loads."""

import dataclasses
import math

import numpy as np
import pytest

from drill_env.physics import bit, bit_reference, formation
from drill_env.physics.bit import BitOut, Blade, Segment
from drill_env.physics.config import BitConfig, FormationConfig, Interface, RockConfig

HARD = RockConfig(name="hard", mu_min=0.5, mu_max=0.9, st1=3.0, st2=0.0,
                  wall_stiffness=2.0e7, wall_damping=2.0e3, depth_of_cut=1.0e-8)
SOFT = RockConfig(name="soft", mu_min=0.3, mu_max=0.45, st1=5.0, st2=0.005,
                  wall_stiffness=5.0e6, wall_damping=1.0e3, depth_of_cut=4.0e-8)
VERY_SOFT = RockConfig(name="very soft", mu_min=0.2, mu_max=0.3, st1=8.0, st2=0.01,
                       wall_stiffness=1.0e6, wall_damping=5.0e2, depth_of_cut=8.0e-8)

DEPTH = 100.0
WOB = 1.0e5


def one_interface(depth: float, dip: float = 45.0, azimuth: float = 0.0,
                  rocks=(HARD, SOFT)) -> formation.FormationArrays:
    cfg = FormationConfig(rocks=rocks, interfaces=(Interface(depth, dip, azimuth),),
                          layers=(0, 1))
    return formation.formation_arrays(cfg)


def pieces(bit_cfg: BitConfig, fa: formation.FormationArrays, bx=0.0, by=0.0, depth=DEPTH,
           phi_z=0.0) -> list[tuple[int, int, int, float, float]]:
    """(blade, segment, rock, length, lever) of every piece, from the kernel."""
    blades = bit.blade_arrays(bit_cfg)
    scratch = bit.make_bit_scratch(len(blades), fa.n_interfaces)
    n = bit.split_blades(blades, fa, bx, by, depth, phi_z, scratch)
    return [(int(scratch.blade[p]), int(scratch.segment[p]), int(scratch.rock[p]),
             float(scratch.length[p]), float(scratch.lever[p])) for p in range(n)]


def loads(bit_cfg: BitConfig, fa: formation.FormationArrays, bx=0.0, by=0.0, vx=0.0, vy=0.0,
          depth=DEPTH, phi_z=0.0, omega=10.0, wob=WOB, compliance=0.0,
          regularisation=1e-3, gauge_friction=math.nan, end_force=None,
          scratch=None) -> np.ndarray:
    """The kernel's loads; ``end_force``: the pads' force at the end of the last step,
    with the contacts implicit (``GaugeContact.shared``); ``scratch``: a
    :class:`bit.BitScratch` to be left holding the pieces and pads."""
    blades = bit.blade_arrays(bit_cfg)
    if scratch is None:
        scratch = bit.make_bit_scratch(len(blades), fa.n_interfaces)
    if end_force is not None:
        scratch.pads[:, bit.PAD.END_FORCE] = end_force
    out = bit.make_loads_out(fa.n_rocks)
    bit.mesoscopic_bit_loads(blades, fa, scratch,
                             bit.BitKinematics(bx, by, vx, vy, depth, phi_z, omega), wob,
                             bit.GaugeContact(bit_cfg.hole_radius, compliance, regularisation,
                                              gauge_friction, end_force is not None),
                             out)
    return out


def reference_loads(bit_cfg, fa, bx=0.0, by=0.0, vx=0.0, vy=0.0, depth=DEPTH, phi_z=0.0,
                    omega=10.0, wob=WOB, compliance=0.0, regularisation=1e-3,
                    gauge_friction=math.nan) -> np.ndarray:
    return bit_reference.bit_loads(bit.blade_arrays(bit_cfg), *fa, bx, by, vx, vy, depth,
                                   phi_z, omega, wob, bit_cfg.hole_radius, compliance,
                                   regularisation, gauge_friction)


# --------------------------------------------------------------------------- geometry


def test_blade_arrays_put_point_c_at_the_gauge_radius():
    cfg = bit.symmetric_bit()
    blades = bit.blade_arrays(cfg)
    np.testing.assert_allclose(blades[:, Blade.R_C], cfg.gauge_radius)
    np.testing.assert_allclose(
        blades[:, Blade.R_C] - blades[:, Blade.R_B],
        blades[:, Blade.L_SH] * np.sin(blades[:, Blade.ALPHA_SH]))  # SPEC 2.2
    np.testing.assert_allclose(np.degrees(blades[:, Blade.PHI]), cfg.blade_angles)


def test_blade_arrays_give_each_blade_its_own_face_shoulder_and_gauge():
    """Row i of blade_arrays is blade i of the config (BitConfig: per blade i, face from
    face_start[i] to face_end[i], gauge pad gauge_length[i]); the oracle reads these
    columns too, so only the config can check them. By hand on unequal blades."""
    gauge_length = (0.05, 0.04, 0.03, 0.06, 0.0, 0.02)
    cfg = dataclasses.replace(bit.asymmetric_bit(), gauge_length=gauge_length)
    blades = bit.blade_arrays(cfg)
    alpha = math.radians(cfg.shoulder_angle)
    l_sh = (cfg.gauge_radius - np.array(bit.ASYMMETRIC_FACE_END)) / math.sin(alpha)
    np.testing.assert_allclose(blades[:, Blade.R_A], bit.ASYMMETRIC_FACE_START, rtol=1e-15)
    np.testing.assert_allclose(blades[:, Blade.R_B], bit.ASYMMETRIC_FACE_END, rtol=1e-15)
    np.testing.assert_allclose(blades[:, Blade.L_SH], l_sh, rtol=1e-12)
    np.testing.assert_allclose(blades[:, Blade.RISE_SH], l_sh * math.cos(alpha), rtol=1e-12)
    np.testing.assert_allclose(blades[:, Blade.L_G], gauge_length, rtol=1e-15)


def test_front_length_and_lever_arm_follow_eqs_30_and_34_with_the_midpoint_rule():
    cfg = bit.symmetric_bit()
    r_a, r_b, alpha = 0.015, 0.070, math.radians(60.0)
    l_sh = (cfg.gauge_radius - r_b) / math.sin(alpha)
    l_f = r_b - r_a
    assert bit.front_length(cfg) == pytest.approx(6 * (l_f + l_sh), rel=1e-14)
    a_f = (r_a + r_b) / 2
    a_sh = r_b + l_sh * math.sin(alpha) / 2
    assert bit.bit_lever_arm(cfg) == pytest.approx((l_f * a_f + l_sh * a_sh) / (l_f + l_sh),
                                                   rel=1e-14)


def test_asymmetric_preset_has_unequal_angles_and_face_lengths_and_a_clear_imbalance():
    cfg = bit.asymmetric_bit()
    assert len(set(np.diff(cfg.blade_angles))) > 1
    assert len(set(np.subtract(cfg.face_end, cfg.face_start))) > 1
    assert np.linalg.norm(bit.front_imbalance(cfg)) > 0.1
    assert np.linalg.norm(bit.front_imbalance(bit.symmetric_bit())) < 1e-15


# --------------------------------------------------------------------------- cases 1-4


class TestPaperCasesOneToFour:
    """One 45 deg interface with azimuth 0; blade 0 points along +x (phi_z = 0).

    A point at radius r on blade 0 at depth z is below the plane (rock 2, index 1) iff
    z > d + tan(45 deg) r. Expected pieces are computed here by hand with the midpoint rule.
    """

    cfg = bit.symmetric_bit()
    r_a, r_b = 0.015, 0.070
    alpha = math.radians(60.0)
    r_c = cfg.gauge_radius
    l_sh = (r_c - r_b) / math.sin(alpha)
    l_g = 0.05
    a_sh = r_b + l_sh * math.sin(alpha) / 2  # the shoulder's midpoint lever arm

    def blade_zero(self, d):
        return [p[1:] for p in pieces(self.cfg, one_interface(d)) if p[0] == 0]

    def assert_pieces(self, actual, expected):
        assert [p[:2] for p in actual] == [p[:2] for p in expected]
        np.testing.assert_allclose([p[2:] for p in actual], [p[2:] for p in expected],
                                   rtol=1e-12, atol=1e-15)

    def test_case_1_blade_fully_in_rock_1(self):
        expected = [(Segment.FACE, 0, self.r_b - self.r_a, (self.r_a + self.r_b) / 2),
                    (Segment.SHOULDER, 0, self.l_sh, self.a_sh),
                    (Segment.GAUGE, 0, self.l_g, self.r_c)]
        self.assert_pieces(self.blade_zero(DEPTH + 1.0), expected)

    def test_case_2_blade_fully_in_rock_2(self):
        expected = [(Segment.FACE, 1, self.r_b - self.r_a, (self.r_a + self.r_b) / 2),
                    (Segment.SHOULDER, 1, self.l_sh, self.a_sh),
                    (Segment.GAUGE, 1, self.l_g, self.r_c)]
        self.assert_pieces(self.blade_zero(DEPTH - 1.0), expected)

    def test_case_3_interface_crosses_the_shoulder(self):
        # Choose |B I| = l_sh / 3: z_I = DEPTH - |BI| cos(a) = d + r_B + |BI| sin(a).
        bi = self.l_sh / 3
        d = DEPTH - self.r_b - bi * (math.cos(self.alpha) + math.sin(self.alpha))
        ic = self.l_sh - bi
        # Paper's case 3 with the midpoint rule: a = r_b - |C M| sin(a_sh), M mid of I, C.
        cm, cn = ic / 2, ic + bi / 2
        expected = [(Segment.FACE, 1, self.r_b - self.r_a, (self.r_a + self.r_b) / 2),
                    (Segment.SHOULDER, 1, bi, self.r_c - cn * math.sin(self.alpha)),
                    (Segment.SHOULDER, 0, ic, self.r_c - cm * math.sin(self.alpha)),
                    (Segment.GAUGE, 0, self.l_g, self.r_c)]
        self.assert_pieces(self.blade_zero(d), expected)

    def test_case_4_interface_crosses_the_face(self):
        r_i = 0.040  # on the face (z = DEPTH): the plane passes r_I = DEPTH - d
        d = DEPTH - r_i
        # Paper's case 4 with the midpoint rule: a = r_B - |B M|, M mid of I, B (or A, I).
        bm, bn = (self.r_b - r_i) / 2, (self.r_b - r_i) + (r_i - self.r_a) / 2
        expected = [(Segment.FACE, 1, r_i - self.r_a, self.r_b - bn),
                    (Segment.FACE, 0, self.r_b - r_i, self.r_b - bm),
                    (Segment.SHOULDER, 0, self.l_sh, self.a_sh),
                    (Segment.GAUGE, 0, self.l_g, self.r_c)]
        self.assert_pieces(self.blade_zero(d), expected)


# --------------------------------------------------------------------------- one rock


@pytest.mark.parametrize("phi_z", [0.0, 0.4, 2.5])
def test_symmetric_bit_in_one_rock_has_no_net_lateral_force_and_tob_is_a_bit_mu_wob(phi_z):
    cfg = bit.symmetric_bit()
    fa = formation.formation_arrays(FormationConfig(rocks=(HARD,)))
    omega = 7.0
    out = loads(cfg, fa, phi_z=phi_z, omega=omega)
    mu = formation.resistance(omega, HARD.mu_min, HARD.mu_max, HARD.st1, HARD.st2)
    # eq. (38)
    assert out[BitOut.TORQUE] == pytest.approx(bit.bit_lever_arm(cfg) * mu * WOB, rel=1e-12)
    assert out[BitOut.TORQUE_STATIC] == pytest.approx(bit.bit_lever_arm(cfg) * HARD.mu_max * WOB,
                                                   rel=1e-12)
    total_cutting_force = mu * WOB
    assert np.hypot(*out[BitOut.FORCE_X:BitOut.FORCE_Y + 1]) < 1e-9 * total_cutting_force
    static = out[BitOut.FORCE_STATIC_X:BitOut.FORCE_STATIC_Y + 1]
    assert np.hypot(*static) < 1e-9 * total_cutting_force
    assert out[bit.SHARES] == pytest.approx(1.0)


def test_asymmetric_bit_in_one_rock_pushes_sideways_and_the_force_turns_with_the_bit():
    cfg = bit.asymmetric_bit()
    fa = formation.formation_arrays(FormationConfig(rocks=(HARD,)))
    omega = 7.0
    mu = formation.resistance(omega, HARD.mu_min, HARD.mu_max, HARD.st1, HARD.st2)
    force0 = loads(cfg, fa, phi_z=0.3, omega=omega)[BitOut.FORCE_X:BitOut.FORCE_Y + 1]
    np.testing.assert_allclose(force0, mu * WOB * bit.front_imbalance(cfg, 0.3), rtol=1e-12)
    assert np.linalg.norm(force0) > 0.1 * mu * WOB
    for delta in (0.5, 2.0, -1.2):
        turned = loads(cfg, fa, phi_z=0.3 + delta, omega=omega)[BitOut.FORCE_X:BitOut.FORCE_Y + 1]
        rotation = np.array([[math.cos(delta), -math.sin(delta)],
                             [math.sin(delta), math.cos(delta)]])
        np.testing.assert_allclose(turned, rotation @ force0, rtol=1e-10, atol=1e-9)
    assert loads(cfg, fa, omega=omega)[BitOut.TORQUE] == pytest.approx(
        bit.bit_lever_arm(cfg) * mu * WOB, rel=1e-12)


# --------------------------------------------------------------------------- conservation


def random_formation(rng, n_interfaces, n_rocks=3, spread=0.12):
    """Random interfaces; half the time the rocks have founder points (at 8.75 in,
    30-180 kN) so that WOBs up to 200 kN cross them. The planes may cross under the bit:
    the kernels must split the blades at any planes (a config of crossing ones is refused
    before they see it, so the arrays are built without a bit and given its rock table)."""
    rocks = (HARD, SOFT, VERY_SOFT)[:n_rocks]
    if rng.random() < 0.5:
        rocks = tuple(dataclasses.replace(r, founder_wob_per_diameter=float(rng.uniform(
            1.4e5, 8e5)), post_founder_slope=float(rng.uniform(0.0, 2.0))) for r in rocks)
    depths = np.sort(DEPTH + rng.uniform(-spread, spread / 2, n_interfaces))
    interfaces = tuple(Interface(float(d), float(rng.uniform(0, 80)), float(rng.uniform(0, 360)))
                       for d in depths)
    layers = tuple(int(j) for j in rng.integers(0, n_rocks, n_interfaces + 1))
    planes = formation.formation_arrays(FormationConfig(rocks=rocks, interfaces=interfaces,
                                                        layers=layers))
    return planes._replace(rock_params=formation.rock_parameter_table(rocks, 8.75 * 0.0254))


def random_bit(rng) -> BitConfig:
    n = int(rng.integers(3, 9))
    return BitConfig(blade_angles=tuple(np.sort(rng.uniform(0, 360, n))),
                     face_start=tuple(rng.uniform(0.0, 0.03, n)),
                     face_end=tuple(rng.uniform(0.04, 0.09, n)),
                     shoulder_angle=float(rng.uniform(20, 90)),
                     gauge_length=tuple(rng.uniform(0.0, 0.08, n) * (rng.random(n) > 0.1)))


def test_pieces_add_up_to_the_blade_lengths_for_any_interfaces_and_bit_motion():
    rng = np.random.default_rng(4)
    for trial in range(300):
        cfg = random_bit(rng) if trial % 2 else bit.symmetric_bit()
        fa = random_formation(rng, int(rng.integers(0, 6)))
        blades = bit.blade_arrays(cfg)
        got = pieces(cfg, fa, bx=rng.uniform(-0.01, 0.01), by=rng.uniform(-0.01, 0.01),
                     phi_z=rng.uniform(-10, 10))
        for i, blade in enumerate(blades):
            expected = (blade[Blade.R_B] - blade[Blade.R_A], blade[Blade.L_SH], blade[Blade.L_G])
            for segment in (Segment.FACE, Segment.SHOULDER, Segment.GAUGE):
                total = sum(p[3] for p in got if p[0] == i and p[1] == segment)
                assert total == pytest.approx(expected[segment], rel=1e-12, abs=1e-15)
        out = loads(cfg, fa, bx=0.0, by=0.0, phi_z=rng.uniform(0, 7))
        assert out[bit.SHARES:].sum() == pytest.approx(1.0, rel=1e-12)


def test_three_rocks_can_cut_one_bit_at_once():
    cfg = FormationConfig(rocks=(HARD, SOFT, VERY_SOFT),
                          interfaces=tuple(Interface(DEPTH + dz, 45.0, 30.0)
                                           for dz in (-0.06, 0.0, 0.06)),
                          layers=(0, 1, 2, 0))
    fa = formation.formation_arrays(cfg)
    out = loads(bit.symmetric_bit(), fa, phi_z=0.2)
    assert np.count_nonzero(out[bit.SHARES:] > 0.05) == 3
    assert out[bit.SHARES:].sum() == pytest.approx(1.0)
    # eq. (53) per piece equals the kernel torque
    got = pieces(bit.symmetric_bit(), fa, phi_z=0.2)
    mu = [formation.resistance(10.0, r.mu_min, r.mu_max, r.st1, r.st2) for r in cfg.rocks]
    torque = WOB / bit.front_length(bit.symmetric_bit()) * sum(
        mu[p[2]] * p[3] * p[4] for p in got if p[1] != Segment.GAUGE)
    assert out[BitOut.TORQUE] == pytest.approx(torque, rel=1e-12)


@pytest.mark.parametrize("omega", [10.0, 0.5])
def test_a_bit_across_two_rocks_is_pushed_by_each_rocks_resistance_on_its_pieces(omega):
    """Eqs. (46)-(53) by hand on a symmetric bit across a dipping interface: each front
    piece of length l in rock j cuts with mu_j(omega) l W / L against the motion of its
    blade, along (sin theta, -cos theta), theta = phi_i + phi_z (eq. 35); the static
    force and torque take mu_j's value at rest, mu_max (eq. 39). One rock would cancel
    the force of a symmetric bit; two leave the difference of their resistances on the
    pieces in each. The pieces (where the interface cuts the blades) come from the
    split, tested against the geometry above."""
    cfg = bit.symmetric_bit()
    fa = one_interface(DEPTH - 0.04)
    phi_z = 0.3
    out = loads(cfg, fa, omega=omega, phi_z=phi_z)
    rocks = (HARD, SOFT)
    mu = [r.mu_min + (r.mu_max - r.mu_min) * math.exp(-omega / r.st1) + r.st2 * omega
          for r in rocks]  # eq. (39), omega > 0
    load = WOB / bit.front_length(cfg)  # eq. (40)
    force, static, torque_static = np.zeros(2), np.zeros(2), 0.0
    front = [p for p in pieces(cfg, fa, phi_z=phi_z) if p[1] != Segment.GAUGE]
    assert {p[2] for p in front} == {0, 1}  # the bit is in both rocks
    for blade_index, _, rock, length, lever in front:
        theta = math.radians(cfg.blade_angles[blade_index]) + phi_z
        against = np.array([math.sin(theta), -math.cos(theta)])
        force += mu[rock] * length * load * against
        static += rocks[rock].mu_max * length * load * against
        torque_static += rocks[rock].mu_max * length * load * lever
    scale = WOB * HARD.mu_max
    assert np.hypot(*force) > 0.01 * WOB  # not the one-rock zero
    np.testing.assert_allclose(out[[BitOut.FORCE_X, BitOut.FORCE_Y]], force, rtol=0,
                               atol=1e-12 * scale)
    np.testing.assert_allclose(out[[BitOut.FORCE_STATIC_X, BitOut.FORCE_STATIC_Y]], static,
                               rtol=0, atol=1e-12 * scale)
    assert out[BitOut.TORQUE_STATIC] == pytest.approx(torque_static, rel=1e-12)


def test_loads_are_continuous_as_an_interface_sweeps_across_the_bit():
    # No blade face is near the strike of the plane (|cos(theta - azimuth)| >= 0.34): a
    # face lying along the strike line would be crossed all at once, a genuine jump.
    cfg = bit.asymmetric_bit()
    step = 2e-5
    sweep = np.arange(DEPTH - 0.2, DEPTH + 0.2, step)
    # Bit pushed into the wall so that the gauge split is swept too.
    history = np.array([loads(cfg, one_interface(d, dip=40.0, azimuth=0.0), bx=0.0065,
                              by=0.001, vx=0.01, phi_z=0.0, omega=8.0) for d in sweep])
    assert history[0, bit.SHARES + 1] == pytest.approx(1.0)
    assert history[-1, bit.SHARES] == pytest.approx(1.0)
    for k in range(history.shape[1]):
        column = history[:, k]
        span = column.max() - column.min()
        jumps = np.abs(np.diff(column))
        # A misplaced whole segment would jump by ~1/12 of the span or more.
        assert jumps.max() <= 0.01 * span + 1e-12 * np.abs(column).max(), k


def test_depth_of_cut_per_revolution_mixes_the_rocks_by_front_share():
    out = loads(bit.symmetric_bit(), one_interface(DEPTH - 0.02), phi_z=0.7)
    shares = out[bit.SHARES:]
    assert 0.0 < shares[1] < 1.0
    expected = WOB * (shares[0] * HARD.depth_of_cut + shares[1] * SOFT.depth_of_cut)
    assert out[BitOut.DEPTH_OF_CUT] == pytest.approx(expected, rel=1e-14)


# --------------------------------------------------------------------------- oracle


#: Absolute tolerance of a piece length or lever arm (m). The blade points are computed
#: at depths near DEPTH, where one ulp is eps * DEPTH (2.2e-14 m at 100 m); the crossing
#: parameter t = g0 / (g0 - g1) divides that round-off by the blade's rise across the
#: plane, so a piece next to a crossing carries an absolute error of tens of ulps in
#: either implementation (3e-13 m was seen: a relative error of 1e-8 on a 40 um piece,
#: depending on how the CPU contracts the dot products). 1e3 ulps of the depth: above the
#: round-off of any CPU, far below any physical length.
PIECE_ATOL = 1e3 * np.finfo(float).eps * DEPTH


def test_kernels_agree_with_the_reference_on_random_states():
    rng = np.random.default_rng(7)
    n_contacts = 0
    for trial in range(300):
        cfg = random_bit(rng) if trial % 3 else (bit.symmetric_bit(), bit.asymmetric_bit())[
            trial % 2]
        fa = random_formation(rng, int(rng.integers(0, 5)), n_rocks=int(rng.integers(1, 4)))
        offset = rng.uniform(0.0, 0.012)
        angle = rng.uniform(0, 2 * math.pi)
        state = dict(bx=offset * math.cos(angle), by=offset * math.sin(angle),
                     vx=rng.normal(scale=0.05), vy=rng.normal(scale=0.05),
                     phi_z=rng.uniform(-20, 20), omega=rng.normal(scale=10.0) * (trial % 7 != 0),
                     wob=rng.uniform(0, 2e5), compliance=rng.choice([0.0, 1e-6, 1e-4]),
                     regularisation=rng.choice([0.0, 1e-3, 0.1]),
                     gauge_friction=math.nan if trial % 2 else rng.uniform(0.0, 0.5))
        got = loads(cfg, fa, **state)
        expected = reference_loads(cfg, fa, **state)
        scale = max(1.0, np.abs(expected).max())
        np.testing.assert_allclose(got, expected, rtol=1e-10, atol=1e-10 * scale)
        n_contacts += expected[BitOut.GAUGE_X] != 0.0
        kernel_pieces = pieces(cfg, fa, state["bx"], state["by"], phi_z=state["phi_z"])
        reference_pieces = bit_reference.split(bit.blade_arrays(cfg), *fa[:3], state["bx"],
                                               state["by"], DEPTH, state["phi_z"])
        assert [p[:3] for p in kernel_pieces] == [(p.blade, p.segment, p.rock)
                                                 for p in reference_pieces]
        np.testing.assert_allclose([p[3:] for p in kernel_pieces],
                                   [(p.length, p.lever) for p in reference_pieces],
                                   rtol=1e-10, atol=PIECE_ATOL)
    assert n_contacts > 50  # the gauge branch was exercised


# --------------------------------------------------------------------------- gauge


class TestGauge:
    """Bit pushed along +x into the wall: only blade 0 (theta = 0) touches.

    A horizontal interface cuts the gauge pad of every blade: 30 % of its length in the
    hard rock above, 70 % in the soft rock below (the front lies in the soft rock).
    """

    cfg = bit.symmetric_bit()
    penetration = 1.0e-3
    bx = cfg.gauge_clearance + penetration
    r_c = cfg.gauge_radius
    l_g = 0.05
    z_c = DEPTH - (cfg.gauge_radius - 0.070) / math.tan(math.radians(60.0))
    fa = one_interface(z_c - 0.7 * l_g, dip=0.0)

    def test_only_the_blade_facing_the_wall_touches_it(self):
        for i in range(1, 6):
            theta = math.radians(60.0 * i)
            assert math.hypot(self.bx + self.r_c * math.cos(theta),
                              self.r_c * math.sin(theta)) < self.cfg.hole_radius

    def test_centred_bit_has_no_gauge_contact(self):
        out = loads(self.cfg, self.fa, vx=0.1, omega=10.0)
        assert np.all(out[BitOut.GAUGE_X:BitOut.GAUGE_TORQUE + 1] == 0.0)

    @pytest.mark.parametrize("gauge_friction", [math.nan, 0.25])
    def test_normal_force_is_k_f_plus_c_fdot_split_by_gauge_length_in_each_rock(
            self, gauge_friction):
        """Eq. (55); the pad does not slip (v_r = 0), so no friction (along -sign(v_r) t,
        bit.py's gauge comment), even unregularised and with the pads' own coefficient."""
        vx = 0.01
        out = loads(self.cfg, self.fa, bx=self.bx, vx=vx, omega=0.0, regularisation=0.0,
                    gauge_friction=gauge_friction)
        k = 0.3 * HARD.wall_stiffness + 0.7 * SOFT.wall_stiffness
        c = 0.3 * HARD.wall_damping + 0.7 * SOFT.wall_damping
        assert out[BitOut.GAUGE_X] == pytest.approx(-(k * self.penetration + c * vx), rel=1e-9)
        assert out[BitOut.GAUGE_Y] == 0.0  # no slip, no friction
        assert out[BitOut.GAUGE_TORQUE] == 0.0

    def test_the_wall_does_not_pull_on_a_receding_bit(self):
        out = loads(self.cfg, self.fa, bx=self.bx, vx=-100.0, omega=10.0)
        assert np.all(out[BitOut.GAUGE_X:BitOut.GAUGE_TORQUE + 1] == 0.0)

    def test_a_receding_pad_is_pushed_only_by_the_rock_that_still_presses_on_it(self):
        """Eq. (55) has no adhesion rock by rock, not only in total. Receding at 7 m/s,
        between the two rocks' k / c (1e4 and 5e3 1/s), the hard rock's 30 % still
        pushes with 0.3 (2e4 - 1.4e4) = 1800 N and the soft rock's 70 % would pull with
        0.7 (5e3 - 7e3) = -1400 N: the pad feels 1800 N, not their sum of 400 N."""
        vx = -7.0
        f_hard = 0.3 * (HARD.wall_stiffness * self.penetration + HARD.wall_damping * vx)
        f_soft = 0.7 * (SOFT.wall_stiffness * self.penetration + SOFT.wall_damping * vx)
        assert f_hard > 0.0 > f_soft  # the case this test is about
        out = loads(self.cfg, self.fa, bx=self.bx, vx=vx, omega=0.0)
        assert out[BitOut.GAUGE_X] == pytest.approx(-f_hard, rel=1e-9)
        expected = reference_loads(self.cfg, self.fa, bx=self.bx, vx=vx, omega=0.0)
        np.testing.assert_allclose(out, expected, rtol=1e-10, atol=1e-10)

    @pytest.mark.parametrize("vx", [0.01, -7.0])
    def test_a_pads_stiffness_and_damping_are_those_of_its_pushing_pieces(self, vx):
        """bit.PAD, kept for the implicit contacts: STIFFNESS and DAMPING are the sums of
        l / l_g k and l / l_g c (eq. 55) over the pad's pieces that push, FORCE its normal
        force. Here 30 % hard and 70 % soft rock; receding at 7 m/s only the hard rock's
        part pushes (the test above). The pads off the wall carry none."""
        scratch = bit.make_bit_scratch(6, self.fa.n_interfaces)
        out = loads(self.cfg, self.fa, bx=self.bx, vx=vx, omega=0.0, scratch=scratch)
        soft = 0.7 if vx > 0.0 else 0.0  # the soft rock's share that pushes
        pad = scratch.pads[0]
        assert pad[bit.PAD.PENETRATION] == pytest.approx(self.penetration, rel=1e-9)
        assert pad[bit.PAD.RATE] == pytest.approx(vx, rel=1e-12)
        assert pad[bit.PAD.STIFFNESS] == pytest.approx(
            0.3 * HARD.wall_stiffness + soft * SOFT.wall_stiffness, rel=1e-12)
        assert pad[bit.PAD.DAMPING] == pytest.approx(
            0.3 * HARD.wall_damping + soft * SOFT.wall_damping, rel=1e-12)
        assert pad[bit.PAD.FORCE] == pytest.approx(-out[BitOut.GAUGE_X], rel=1e-12)
        assert np.all(scratch.pads[1:, bit.PAD.STIFFNESS:bit.PAD.FORCE + 1] == 0.0)

    @pytest.mark.parametrize("end_force", [2.0e3, 5.0e4])
    def test_shared_pads_rub_with_the_smaller_of_their_predicted_and_last_forces(
            self, end_force):
        """Implicit contacts (physics/implicit_contact.py): a pad rubs with the smaller of
        its normal force at the predictor and at the end of the last step. Here the
        predictor's is (0.3 k_hard + 0.7 k_soft) x 1 mm = 9.5 kN; with mu = 0.25, no
        regularisation and no cap, the friction is 0.25 min(9.5 kN, end force)."""
        out = loads(self.cfg, self.fa, bx=self.bx, omega=5.0, regularisation=0.0,
                    gauge_friction=0.25, end_force=end_force)
        predicted = (0.3 * HARD.wall_stiffness + 0.7 * SOFT.wall_stiffness) * self.penetration
        assert out[BitOut.GAUGE_X] == pytest.approx(-predicted, rel=1e-12)
        assert out[BitOut.GAUGE_Y] == pytest.approx(-0.25 * min(predicted, end_force),
                                                    rel=1e-12)

    @pytest.mark.parametrize("omega", [5.0, -5.0])
    def test_gauge_friction_opposes_the_slip_and_its_torque_opposes_rotation(self, omega):
        out = loads(self.cfg, self.fa, bx=self.bx, omega=omega, regularisation=1e-3)
        f_hard = 0.3 * HARD.wall_stiffness * self.penetration
        f_soft = 0.7 * SOFT.wall_stiffness * self.penetration
        w = abs(omega)  # slip speed omega r_C converted back to rad/s by r_C (eq. 57)
        mu_hard = formation.resistance(w, HARD.mu_min, HARD.mu_max, HARD.st1, HARD.st2)
        mu_soft = formation.resistance(w, SOFT.mu_min, SOFT.mu_max, SOFT.st1, SOFT.st2)
        friction = -math.copysign(mu_hard * f_hard + mu_soft * f_soft, omega)
        assert out[BitOut.GAUGE_X] == pytest.approx(-(f_hard + f_soft), rel=1e-9)
        assert out[BitOut.GAUGE_Y] == pytest.approx(friction, rel=1e-9)
        assert out[BitOut.GAUGE_TORQUE] == pytest.approx(self.r_c * friction, rel=1e-9)
        assert out[BitOut.GAUGE_TORQUE] * omega < 0.0

    def test_a_gauge_friction_of_its_own_replaces_the_rock_curve(self):
        out = loads(self.cfg, self.fa, bx=self.bx, omega=5.0, regularisation=1e-3,
                    gauge_friction=0.25)
        normal = (0.3 * HARD.wall_stiffness + 0.7 * SOFT.wall_stiffness) * self.penetration
        assert out[BitOut.GAUGE_Y] == pytest.approx(-0.25 * normal, rel=1e-9)

    def test_friction_opposes_a_lateral_slide_of_the_contact_point(self):
        out = loads(self.cfg, self.fa, bx=self.bx, vy=0.05, omega=0.0)
        assert out[BitOut.GAUGE_Y] < 0.0

    @pytest.mark.parametrize("omega", [5.0, -8.0])
    def test_a_pad_rolling_on_the_wall_without_slip_feels_no_friction(self, omega):
        """The pad's material point slips along the wall at the centre's tangential speed
        plus omega r_C (docs/model.md section 4, in place of the printed eq. 37): a bit
        whose centre moves at -omega r_C along the wall rolls on it, with neither
        friction nor gauge torque; a slip v_t added gets mu(|v_t| / r_C) of the normal
        force against it. By hand, where the oracle of the same authors had been the
        only check of rotation and lateral motion together (a review of the tests)."""
        rolling = -omega * self.r_c
        f_hard = 0.3 * HARD.wall_stiffness * self.penetration
        f_soft = 0.7 * SOFT.wall_stiffness * self.penetration
        out = loads(self.cfg, self.fa, bx=self.bx, vy=rolling, omega=omega)
        assert out[BitOut.GAUGE_X] == pytest.approx(-(f_hard + f_soft), rel=1e-9)
        assert abs(out[BitOut.GAUGE_Y]) < 1e-9 * (f_hard + f_soft)
        assert abs(out[BitOut.GAUGE_TORQUE]) < 1e-9 * self.r_c * (f_hard + f_soft)
        for slip in (0.02, -0.03):
            out = loads(self.cfg, self.fa, bx=self.bx, vy=rolling + slip, omega=omega)
            w = abs(slip) / self.r_c
            mu_hard = formation.resistance(w, HARD.mu_min, HARD.mu_max, HARD.st1, HARD.st2)
            mu_soft = formation.resistance(w, SOFT.mu_min, SOFT.mu_max, SOFT.st1, SOFT.st2)
            friction = -math.copysign(mu_hard * f_hard + mu_soft * f_soft, slip)
            assert out[BitOut.GAUGE_Y] == pytest.approx(friction, rel=1e-9)
            assert out[BitOut.GAUGE_TORQUE] == pytest.approx(self.r_c * friction, rel=1e-9)

    def test_friction_is_regularised_and_capped_at_low_slip(self):
        vy = 1e-4
        full = loads(self.cfg, self.fa, bx=self.bx, vy=vy, omega=0.0, regularisation=0.0)
        regular = loads(self.cfg, self.fa, bx=self.bx, vy=vy, omega=0.0, regularisation=1e-3)
        assert regular[BitOut.GAUGE_Y] == pytest.approx(0.1 * full[BitOut.GAUGE_Y], rel=1e-12)
        capped = loads(self.cfg, self.fa, bx=self.bx, vy=vy, omega=0.0, compliance=1e-3)
        assert capped[BitOut.GAUGE_Y] == pytest.approx(-vy / 1e-3, rel=1e-12)


# --------------------------------------------------------------------------- penetration


def test_depth_of_cut_peaks_at_the_founder_point():
    """Linear in WOB up to W_f = founder per diameter x bit diameter, then falling by
    ``post_founder_slope`` per unit of excess WOB (docs/model.md, "Penetration")."""
    cfg = bit.symmetric_bit()
    rock = dataclasses.replace(HARD, founder_wob_per_diameter=5e5, post_founder_slope=0.5)
    fa = formation.formation_arrays(FormationConfig(rocks=(rock,)), cfg.diameter)
    w_f = 5e5 * cfg.diameter
    wobs = np.linspace(10e3, 2.5 * w_f, 40)
    doc = np.array([loads(cfg, fa, wob=w)[BitOut.DEPTH_OF_CUT] for w in wobs])
    expected = rock.depth_of_cut * np.where(wobs <= w_f, wobs,
                                            np.maximum(0.0, w_f - 0.5 * (wobs - w_f)))
    np.testing.assert_allclose(doc, expected, rtol=1e-12)
    assert wobs[np.argmax(doc)] == pytest.approx(w_f, rel=0.06)
    no_founder = formation.formation_arrays(FormationConfig(rocks=(HARD,)), cfg.diameter)
    assert loads(cfg, no_founder, wob=3 * w_f)[BitOut.DEPTH_OF_CUT] == pytest.approx(
        HARD.depth_of_cut * 3 * w_f, rel=1e-12)  # no founder point: linear at any WOB


def test_gauge_normal_forces_derive_from_the_penetration_energy():
    """Without motion the gauge pads are springs against the wall: the force and torque
    on the bit are minus the gradient of U = sum_i k pen_i^2 / 2 over the bit offset and
    rotation, pen_i = |P_i| - r_hole for the pads' outer points P_i = b + r_C e(theta_i +
    phi) (eq. 36; eq. 56's normal is this gradient's direction). Central differences of U,
    written here from the geometry alone, for the asymmetric bit pushed off centre."""
    cfg = bit.asymmetric_bit()
    fa = one_interface(DEPTH + 1.0)  # the whole bit in the hard rock above the interface
    r_c = cfg.gauge_radius
    theta = np.radians(np.array(cfg.blade_angles))
    gauge_share = np.array(cfg.gauge_length) > 0.0

    def energy(bx: float, by: float, phi: float) -> float:
        px = bx + r_c * np.cos(theta + phi)
        py = by + r_c * np.sin(theta + phi)
        pen = np.maximum(np.hypot(px, py) - cfg.hole_radius, 0.0) * gauge_share
        return 0.5 * HARD.wall_stiffness * float(np.sum(pen ** 2))

    bx, by, phi, h = 4.5e-3, 4.2e-3, 0.3, 1e-8
    out = loads(cfg, fa, bx=bx, by=by, phi_z=phi, omega=0.0)
    force = [-(energy(bx + h, by, phi) - energy(bx - h, by, phi)) / (2 * h),
             -(energy(bx, by + h, phi) - energy(bx, by - h, phi)) / (2 * h)]
    torque = -(energy(bx, by, phi + h) - energy(bx, by, phi - h)) / (2 * h)
    assert abs(force[0]) > 1e3  # in the wall
    np.testing.assert_allclose([out[BitOut.GAUGE_X], out[BitOut.GAUGE_Y]], force, rtol=1e-5)
    assert out[BitOut.GAUGE_TORQUE] == pytest.approx(torque, rel=1e-4)


def test_three_blades_on_one_side_push_the_bit_by_a_third_of_the_cutting_force():
    """Eqs. (46)-(52) by hand: three equal blades at 0, 90 and 180 deg share the line load
    W / L equally; each cuts with mu W / 3 against its motion (omega > 0: along
    (sin theta, -cos theta)), so the 0 and 180 deg blades cancel and the 90 deg blade's
    (mu W / 3, 0) is left. The torque is mu W times the blades' mean lever arm."""
    cfg = BitConfig(blade_angles=(0.0, 90.0, 180.0), face_start=(0.02,) * 3,
                    face_end=(0.07,) * 3, gauge_length=(0.05,) * 3)
    fa = one_interface(DEPTH + 1.0)
    omega = 10.0
    mu = HARD.mu_min + (HARD.mu_max - HARD.mu_min) * math.exp(-omega / HARD.st1)  # eq. 39
    out = loads(cfg, fa, omega=omega)
    assert out[BitOut.FORCE_X] == pytest.approx(mu * WOB / 3, rel=1e-12)
    assert abs(out[BitOut.FORCE_Y]) < 1e-12 * mu * WOB
    # lever of one blade: length-weighted mean radius of its face and shoulder (eq. 34)
    blade = bit.blade_arrays(cfg)[0]
    face = blade[Blade.R_B] - blade[Blade.R_A]
    shoulder = blade[Blade.L_SH]
    lever = (face * 0.5 * (blade[Blade.R_A] + blade[Blade.R_B])
             + shoulder * 0.5 * (blade[Blade.R_B] + blade[Blade.R_C])) / (face + shoulder)
    assert out[BitOut.TORQUE] == pytest.approx(mu * WOB * lever, rel=1e-12)


def test_a_bit_given_another_diameter_gets_shoulders_to_its_own_gauge():
    """Shoulders left empty reach the gauge: r_B + l_sh sin(alpha_sh) = gauge radius. They
    were stored at the default 8 3/4 in bit's size, so a config that then set an
    8 1/2 in bit was refused ("blade reaches radius 0.1061 m beyond the gauge") for a
    field the user never wrote (a drilling engineer's walkthrough)."""
    import math

    from drill_env.physics.bit import shoulder_lengths
    from drill_env.physics.config import BitConfig, replace

    small = replace(BitConfig(), diameter=8.5 * 0.0254)
    gauge = small.diameter / 2 - small.gauge_clearance
    for r_b, l_sh in zip(small.face_end, shoulder_lengths(small), strict=True):
        assert r_b + l_sh * math.sin(math.radians(small.shoulder_angle)) == \
            pytest.approx(gauge, rel=1e-12)
    given = replace(small, shoulder_length=(0.02,) * 6)  # given lengths are kept
    assert shoulder_lengths(given) == (0.02,) * 6
