"""Mesoscopic PDC bit (paper section 3, eqs. 28-62) as allocation-free numba kernels.

Hole-fixed frame: ``x, y`` lateral (m), ``z`` measured depth positive DOWNWARD. The bit
face (points A, B of every blade) lies at ``z = depth``; the shoulder B->C rises by
``l_sh cos(alpha_sh)`` while it widens by ``l_sh sin(alpha_sh)`` (docs/model.md 4.1 correction of
eq. 29), and the gauge pad C->D is axial at radius ``r_C``, ``D_z = C_z - l_g``. Blade i
points along ``theta_i = phi_i + phi_z`` (eq. 35) from the bit centre ``(bx, by)``.

Every straight blade segment is split EXACTLY at every interface plane it crosses
(:func:`split_blades`), which generalises the paper's cases 1-4 to any number of layers.
Each piece carries its rock, length and lever arm = radius of its midpoint from the bit
axis (the midpoint rule, docs/model.md 4.1).

:func:`mesoscopic_bit_loads` writes, into ``out`` (length ``N_BIT_OUT + n_rock``, the
names of :data:`BitOut`):

=========================  ==========================================================
``TORQUE``                 front torque magnitude at bit speed ``|omega|`` (eqs. 40-53)
``TORQUE_STATIC``          the same at omega -> 0+ (mu = mu_max of each rock)
``FORCE_X``, ``FORCE_Y``   front lateral force for POSITIVE rotation at ``|omega|``
                           (eqs. 46, 49, 52, 62); the caller multiplies by sign(omega)
``FORCE_STATIC_X``, ``_Y`` the same at 0+
``GAUGE_X``, ``GAUGE_Y``   gauge force on the bit, normal + cutting/friction (eqs. 55-60)
``GAUGE_TORQUE``           torque of the gauge forces about the bit axis (signed)
``DEPTH_OF_CUT``           depth of cut per revolution (m/rev): wob sum_j share_j doc_j
``N_BIT_OUT + j``          share of FRONT blade length in rock j (sums to 1)
=========================  ==========================================================
"""

from __future__ import annotations

import math
from enum import IntEnum
from typing import NamedTuple

import numpy as np
from numba import njit

from drill_env.physics.config import BitConfig
from drill_env.physics.formation import Rock, effective_wob, layer_at, resistance
from drill_env.physics.jit import TUPLE_KERNEL

#: Columns of :func:`blade_arrays`, one row per blade.
Blade = IntEnum("Blade", [
    "PHI",       # blade angle phi_i (rad)
    "R_A",       # radius of point A, where the face starts (m)
    "R_B",       # radius of point B, face to shoulder (m)
    "R_C",       # radius of point C, shoulder to gauge (m)
    "ALPHA_SH",  # shoulder angle from the bit axis (rad)
    "L_SH",      # shoulder length (m)
    "L_G",       # gauge length (m)
    "COS_PHI",   # cos and sin of PHI: a step needs one sincos (of phi_z), not one per blade
    "SIN_PHI",
    "RISE_SH",   # l_sh cos(alpha_sh): height of point C above the face (m)
], start=0)
N_BLADE_COLUMNS = len(Blade)

#: Segment codes of the pieces (face A-B, shoulder B-C, gauge C-D).
Segment = IntEnum("Segment", ["FACE", "SHOULDER", "GAUGE"], start=0)
N_SEGMENTS = len(Segment)

#: Layout of the bit's load vector (see the module docstring); rock shares follow.
BitOut = IntEnum("BitOut", [
    "TORQUE", "TORQUE_STATIC", "FORCE_X", "FORCE_Y", "FORCE_STATIC_X", "FORCE_STATIC_Y",
    "GAUGE_X", "GAUGE_Y", "GAUGE_TORQUE", "DEPTH_OF_CUT",
], start=0)
N_BIT_OUT = len(BitOut)
SHARES = N_BIT_OUT


class BitKinematics(NamedTuple):
    """Position and motion of the bit in the hole frame."""

    x: float      # bit centre (m)
    y: float
    vx: float     # bit centre velocity (m/s)
    vy: float
    depth: float  # bit face depth (m)
    phi_z: float  # rotation angle (rad)
    omega: float  # rotation speed (rad/s)


class GaugeContact(NamedTuple):
    """What the gauge model needs besides the bit's motion."""

    hole_radius: float             # m
    tangential_compliance: float   # m/(N s); > 0 caps friction at |v_r| / compliance
    regularisation_speed: float    # m/s: friction linear below it
    friction: float                # gauge-pad friction; NaN: each rock's resistance curve
    shared: bool = False           # the cap split among the pads on the wall (implicit
                                   # contacts: several pads press deep into the rock at once)


# --------------------------------------------------------------------------- geometry


def shoulder_lengths(cfg: BitConfig) -> tuple[float, ...]:
    """Each blade's shoulder length: ``cfg.shoulder_length``, or where that is empty the
    lengths that reach the gauge radius, ``r_C = r_B + l_sh sin(alpha_sh)``, so that a
    bit given another diameter gets its own (they were stored at the first size)."""
    if cfg.shoulder_length:
        return tuple(cfg.shoulder_length)
    sin_a = math.sin(math.radians(cfg.shoulder_angle))
    return tuple((cfg.gauge_radius - rb) / sin_a for rb in cfg.face_end)


def blade_arrays(cfg: BitConfig) -> np.ndarray:
    """``(n_blades, N_BLADE_COLUMNS)``: the columns of :data:`Blade` (eq. 29)."""
    n = cfg.n_blades
    alpha = math.radians(cfg.shoulder_angle)
    blades = np.empty((n, N_BLADE_COLUMNS))
    shoulder = shoulder_lengths(cfg)
    for i in range(n):
        blades[i, Blade.PHI] = math.radians(cfg.blade_angles[i])
        blades[i, Blade.R_A] = cfg.face_start[i]
        blades[i, Blade.R_B] = cfg.face_end[i]
        # docs/model.md 4.1: the shoulder's radial extent is l_sh sin(alpha_sh).
        blades[i, Blade.R_C] = cfg.face_end[i] + shoulder[i] * math.sin(alpha)
        blades[i, Blade.ALPHA_SH] = alpha
        blades[i, Blade.L_SH] = shoulder[i]
        blades[i, Blade.L_G] = cfg.gauge_length[i]
        blades[i, Blade.COS_PHI] = math.cos(blades[i, Blade.PHI])
        blades[i, Blade.SIN_PHI] = math.sin(blades[i, Blade.PHI])
        blades[i, Blade.RISE_SH] = shoulder[i] * math.cos(alpha)
    return blades


def blade_points(blades: np.ndarray) -> np.ndarray:
    """Points A, B, C, D of every blade as (radius from the bit axis, height above the
    face): shape ``(n_blades, 4, 2)``. Segment k runs from point k to point k + 1.

    The one place the blade's shape is derived from :func:`blade_arrays` outside the
    kernels (the formation's share bracket, the recorder's 3-D blades, the test oracle).
    """
    n = blades.shape[0]
    points = np.zeros((n, 4, 2))
    points[:, 0, 0] = blades[:, Blade.R_A]
    points[:, 1, 0] = blades[:, Blade.R_B]
    points[:, 2, 0] = blades[:, Blade.R_C]
    points[:, 2, 1] = blades[:, Blade.RISE_SH]
    points[:, 3, 0] = blades[:, Blade.R_C]
    points[:, 3, 1] = blades[:, Blade.RISE_SH] + blades[:, Blade.L_G]
    return points


def segment_lengths(blades: np.ndarray) -> np.ndarray:
    """``(n_blades, N_SEGMENTS)`` lengths of face, shoulder and gauge (m)."""
    return np.stack([blades[:, Blade.R_B] - blades[:, Blade.R_A], blades[:, Blade.L_SH],
                     blades[:, Blade.L_G]], axis=1)


def front_lengths(cfg: BitConfig) -> np.ndarray:
    """l_front,i = l_f,i + l_sh,i per blade (eq. 30)."""
    lengths = segment_lengths(blade_arrays(cfg))
    return lengths[:, Segment.FACE] + lengths[:, Segment.SHOULDER]


def front_length(cfg: BitConfig) -> float:
    """L_front = sum_i l_f,i + l_sh,i (eq. 30); the gauge carries no WOB."""
    return float(front_lengths(cfg).sum())


def bit_lever_arm(cfg: BitConfig) -> float:
    """a_bit of eq. (34) with midpoint lever arms (docs/model.md 4.1).

    a_f,i = (r_A,i + r_B,i) / 2 (eq. 32) and a_sh,i = r_B,i + l_sh,i sin(alpha_sh) / 2
    (eq. 31), so TOB = a_bit mu WOB (eq. 38) for a bit in one rock.
    """
    b = blade_arrays(cfg)
    l_f = b[:, Blade.R_B] - b[:, Blade.R_A]
    a_f = 0.5 * (b[:, Blade.R_A] + b[:, Blade.R_B])
    a_sh = b[:, Blade.R_B] + 0.5 * b[:, Blade.L_SH] * np.sin(b[:, Blade.ALPHA_SH])
    return float(np.sum(l_f * a_f + b[:, Blade.L_SH] * a_sh) / front_length(cfg))


def front_imbalance(cfg: BitConfig, phi_z: float = 0.0) -> np.ndarray:
    """sum_i l_front,i (sin theta_i, -cos theta_i) / L_front: the one-rock lateral force
    per unit mu WOB (eqs. 46, 52). Zero for a symmetric bit."""
    b = blade_arrays(cfg)
    lengths = front_lengths(cfg)
    theta = b[:, Blade.PHI] + phi_z
    return np.array([np.sum(lengths * np.sin(theta)),
                     -np.sum(lengths * np.cos(theta))]) / lengths.sum()


def symmetric_bit() -> BitConfig:
    """The default 8 3/4 in, six-blade bit: equal blades every 60 deg."""
    return BitConfig()


#: Asymmetric (anti-whirl-like) preset: three long primary blades reaching near the
#: centre, bunched on one side, and three short secondary blades opposite, at unequal
#: angles. See ``asymmetric_bit``. MODELLING CHOICE (the paper shows its asymmetric bit
#: only as a sketch): an anti-whirl bit is built to carry a net imbalance force that
#: holds one side on the wall (Warren et al. 1990, SPE 19572); these numbers give an
#: imbalance of 16.5 % of mu WOB, which reproduces the paper's case 4 (a lateral force
#: all the time and forward whirl, Figs. 17-18; tests/test_paper_results.py).
ASYMMETRIC_BLADE_ANGLES = (0.0, 55.0, 110.0, 180.0, 240.0, 300.0)
ASYMMETRIC_FACE_START = (0.010, 0.010, 0.010, 0.045, 0.045, 0.045)
ASYMMETRIC_FACE_END = (0.080, 0.075, 0.080, 0.065, 0.070, 0.065)


def asymmetric_bit() -> BitConfig:
    """Anti-whirl-like six-blade bit: unequal blade angles AND unequal face lengths.

    Blade angles 0, 55, 110, 180, 240, 300 deg; faces from r_A = 10/10/10/45/45/45 mm to
    r_B = 80/75/80/65/70/65 mm; shoulders reach the gauge radius as in the default bit
    (front lengths ~100 mm on the primary and ~67 mm on the secondary blades). Its front
    imbalance |sum_i l_front,i (sin theta_i, -cos theta_i)| / L_front is 0.165 (see
    :func:`front_imbalance`): a net lateral cutting force of 16.5 % of mu WOB, pointing
    at -43 deg from the bit's x axis, that rotates with the bit.
    """
    return BitConfig(blade_angles=ASYMMETRIC_BLADE_ANGLES, face_start=ASYMMETRIC_FACE_START,
                     face_end=ASYMMETRIC_FACE_END)


# --------------------------------------------------------------------------- scratch


#: One gauge pad at the last call (``BitScratch.pads`` row), for implicit contacts.
PAD = IntEnum("PAD", [
    "ON",           # 1.0 where the blade has a gauge pad
    "EX", "EY",     # unit vector from the hole axis to the pad's point D
    "PENETRATION",  # |D| - hole radius (m; < 0 off the wall)
    "RATE",         # its rate (m/s)
    "STIFFNESS",    # sum of k over the pad's pieces that push (N/m; 0 off the wall)
    "DAMPING",      # and of c (N s/m)
    "FORCE",        # the pad's normal force (N)
    "END_FORCE",    # its normal force at the end of the last step (implicit contacts)
], start=0)


class BitScratch(NamedTuple):
    """Preallocated piece arrays for :func:`split_blades` (blade-major, segment order)
    and the gauge pads of the last call."""

    blade: np.ndarray    # int64
    segment: np.ndarray  # int64: Segment
    rock: np.ndarray     # int64
    length: np.ndarray   # float64 (m)
    lever: np.ndarray    # float64: radius of the piece midpoint from the bit axis (m)
    pads: np.ndarray     # (n_blades, PAD)


def max_pieces(n_blades: int, n_interfaces: int) -> int:
    """A segment crosses each plane at most once: n_interfaces + 1 pieces per segment."""
    return n_blades * N_SEGMENTS * (n_interfaces + 1)


def make_bit_scratch(n_blades: int, n_interfaces: int) -> BitScratch:
    n = max_pieces(n_blades, n_interfaces)
    return BitScratch(np.zeros(n, np.int64), np.zeros(n, np.int64), np.zeros(n, np.int64),
                      np.zeros(n), np.zeros(n), np.zeros((n_blades, len(PAD))))


def make_loads_out(n_rocks: int) -> np.ndarray:
    return np.zeros(N_BIT_OUT + n_rocks)


# --------------------------------------------------------------------------- kernels


@njit(cache=True, inline="always")
def _blade_direction(blades, i, cos_z, sin_z):
    """(cos theta_i, sin theta_i) of theta_i = phi_i + phi_z (eq. 35) from the stored
    cos/sin of phi_i and those of phi_z: two rotations' worth of multiplies, no sincos."""
    c = blades[i, Blade.COS_PHI] * cos_z - blades[i, Blade.SIN_PHI] * sin_z
    s = blades[i, Blade.SIN_PHI] * cos_z + blades[i, Blade.COS_PHI] * sin_z
    return c, s


@njit(cache=True, inline="always")
def _split_segment(p0, p1, r0, r1, length, blade, segment, formation, pieces, n):
    """Split the segment p0 -> p1 (points (x, y, z); radii r0 -> r1 from the bit axis) at
    every plane it crosses; append the pieces from index n on and return the new count."""
    x0, y0, z0 = p0
    x1, y1, z1 = p1
    normals = formation.normals
    offsets = formation.offsets
    n_if = offsets.shape[0]
    t_prev = 0.0
    while True:
        # Next crossing after t_prev: selection instead of a sort keeps this allocation-free.
        t_next = 1.0
        for k in range(n_if):
            g0 = normals[k, 0] * x0 + normals[k, 1] * y0 + normals[k, 2] * z0 - offsets[k]
            g1 = normals[k, 0] * x1 + normals[k, 1] * y1 + normals[k, 2] * z1 - offsets[k]
            if (g0 > 0.0) != (g1 > 0.0):
                t = g0 / (g0 - g1)
                if t_prev < t < t_next:
                    t_next = t
        tm = 0.5 * (t_prev + t_next)
        layer = layer_at(x0 + tm * (x1 - x0), y0 + tm * (y1 - y0), z0 + tm * (z1 - z0),
                         normals, offsets)
        pieces.blade[n] = blade
        pieces.segment[n] = segment
        pieces.rock[n] = formation.layer_rock[layer]
        pieces.length[n] = (t_next - t_prev) * length
        # The blade is radial in the bit frame, so the radius is linear along it.
        pieces.lever[n] = r0 + tm * (r1 - r0)
        n += 1
        if t_next >= 1.0:
            return n
        t_prev = t_next


@njit(**TUPLE_KERNEL)
def split_blades(blades, formation, bx, by, depth, phi_z, pieces):
    """Split face A->B, shoulder B->C and gauge C->D of every blade at every interface.

    Points in the hole frame (eq. 35, docs/model.md 4.1 geometry): A, B at z = depth, C at
    z = depth - l_sh cos(alpha_sh), D at C_z - l_g. Returns the number of pieces written
    (blade-major, then segment, then along the segment). Zero-length segments give no
    piece. The rock of a piece is that of its midpoint, so the split is exact.
    """
    return _split_blades(blades, formation, bx, by, depth, math.cos(phi_z), math.sin(phi_z),
                         pieces)


@njit(**TUPLE_KERNEL)
def _split_blades(blades, formation, bx, by, depth, cos_z, sin_z, pieces):
    """:func:`split_blades` with the bit angle given as its cosine and sine."""
    # np.int64(): plain ints, not literals, so _split_segment compiles only once.
    n = np.int64(0)
    face = np.int64(Segment.FACE)
    shoulder = np.int64(Segment.SHOULDER)
    gauge = np.int64(Segment.GAUGE)
    for i in range(blades.shape[0]):
        c, s = _blade_direction(blades, i, cos_z, sin_z)  # eq. (35)
        r_a = blades[i, Blade.R_A]
        r_b = blades[i, Blade.R_B]
        r_c = blades[i, Blade.R_C]
        l_sh = blades[i, Blade.L_SH]
        l_g = blades[i, Blade.L_G]
        z_c = depth - blades[i, Blade.RISE_SH]
        z_d = z_c - l_g
        if r_b - r_a > 0.0:
            n = _split_segment((bx + r_a * c, by + r_a * s, depth),
                               (bx + r_b * c, by + r_b * s, depth), r_a, r_b, r_b - r_a, i,
                               face, formation, pieces, n)
        if l_sh > 0.0:
            n = _split_segment((bx + r_b * c, by + r_b * s, depth),
                               (bx + r_c * c, by + r_c * s, z_c), r_b, r_c, l_sh, i,
                               shoulder, formation, pieces, n)
        if l_g > 0.0:
            n = _split_segment((bx + r_c * c, by + r_c * s, z_c),
                               (bx + r_c * c, by + r_c * s, z_d), r_c, r_c, l_g, i, gauge,
                               formation, pieces, n)
    return n


@njit(**TUPLE_KERNEL)
def _front_loads(blades, rock_params, cos_z, sin_z, omega, wob, n, pieces, out):
    """Front (face + shoulder) torque, lateral force, shares and depth of cut."""
    l_front = 0.0
    for i in range(blades.shape[0]):
        l_front += blades[i, Blade.R_B] - blades[i, Blade.R_A] + blades[i, Blade.L_SH]  # (30)
    load = wob / l_front  # eq. (40): line load on the front blades
    w = abs(omega)
    last_rock = -1
    mu = 0.0
    for p in range(n):
        if pieces.segment[p] == Segment.GAUGE:
            continue
        j = pieces.rock[p]
        length = pieces.length[p]
        if j != last_rock:  # pieces come in runs of one rock: one exp per run
            mu = resistance(w, rock_params[j, Rock.MU_MIN], rock_params[j, Rock.MU_MAX],
                            rock_params[j, Rock.ST1], rock_params[j, Rock.ST2])
            last_rock = j
        mu0 = rock_params[j, Rock.MU_MAX]  # eq. (39) at 0+
        c, s = _blade_direction(blades, pieces.blade[p], cos_z, sin_z)
        sx = s
        cy = -c
        lever = pieces.lever[p]
        # eqs. (47), (50): cutting force mu l F/L and its torque with the piece lever arm
        out[BitOut.TORQUE] += mu * lever * length
        out[BitOut.TORQUE_STATIC] += mu0 * lever * length
        # eqs. (46), (49), (52): the force opposes the blade's motion for omega > 0
        out[BitOut.FORCE_X] += mu * length * sx
        out[BitOut.FORCE_Y] += mu * length * cy
        out[BitOut.FORCE_STATIC_X] += mu0 * length * sx
        out[BitOut.FORCE_STATIC_Y] += mu0 * length * cy
        out[SHARES + j] += length / l_front
    for k in range(BitOut.FORCE_STATIC_Y + 1):
        out[k] *= load
    for j in range(rock_params.shape[0]):
        acting = effective_wob(wob, rock_params[j, Rock.FOUNDER_WOB],
                               rock_params[j, Rock.POST_FOUNDER_SLOPE])
        out[BitOut.DEPTH_OF_CUT] += acting * out[SHARES + j] * rock_params[j, Rock.DEPTH_OF_CUT]


@njit(**TUPLE_KERNEL)
def _gauge_loads(blades, rock_params, kin, cos_z, sin_z, gauge, n, pieces, out):
    """Gauge contact of every blade's point D with the wall (eqs. 36, 37, 55-60)."""
    bx = kin.x
    by = kin.y
    omega = kin.omega
    pads = pieces.pads
    cap_compliance = gauge.tangential_compliance
    if gauge.shared:  # each pad's cap, summed over the pads, stops the bit's slip
        touching = 0
        for i in range(blades.shape[0]):
            c, s = _blade_direction(blades, i, cos_z, sin_z)
            px = bx + blades[i, Blade.R_C] * c
            py = by + blades[i, Blade.R_C] * s
            if blades[i, Blade.L_G] > 0.0 and px * px + py * py > gauge.hole_radius ** 2:
                touching += 1
        cap_compliance *= max(touching, 1)
    for i in range(blades.shape[0]):
        pad = pads[i]
        l_g = blades[i, Blade.L_G]
        r_c = blades[i, Blade.R_C]
        c, s = _blade_direction(blades, i, cos_z, sin_z)
        px = bx + r_c * c
        py = by + r_c * s
        radius = math.sqrt(px * px + py * py)
        if l_g <= 0.0 or radius == 0.0:
            pad[PAD.ON] = 0.0
            continue
        penetration = radius - gauge.hole_radius  # eq. (36) as max(0, r - r_limit)
        # Velocity of the contact point: bit translation + rotation about the bit axis.
        wx = kin.vx - omega * r_c * s
        wy = kin.vy + omega * r_c * c
        ex = px / radius
        ey = py / radius
        penetration_rate = ex * wx + ey * wy
        pad[PAD.ON] = 1.0
        pad[PAD.EX] = ex
        pad[PAD.EY] = ey
        pad[PAD.PENETRATION] = penetration
        pad[PAD.RATE] = penetration_rate
        pad[PAD.STIFFNESS] = 0.0
        pad[PAD.DAMPING] = 0.0
        pad[PAD.FORCE] = 0.0
        if penetration <= 0.0:
            continue
        tx = -ey
        ty = ex
        slip = tx * wx + ty * wy  # exact form of eq. (37)
        # The resistance curves are in rad/s: the slip speed enters as |v_r| / r_C.
        w = abs(slip) / r_c
        normal = 0.0
        friction = 0.0
        stiffness = 0.0  # of the pieces that push: d normal / d penetration
        damping = 0.0
        for p in range(n):
            if pieces.blade[p] != i or pieces.segment[p] != Segment.GAUGE:
                continue
            j = pieces.rock[p]
            # eq. (55): normal force split by the gauge length in each rock; no adhesion,
            # so each rock's part is clamped at >= 0 (hence also the total).
            f_n = pieces.length[p] / l_g * (rock_params[j, Rock.WALL_STIFFNESS] * penetration
                                            + rock_params[j, Rock.WALL_DAMPING]
                                            * penetration_rate)
            if f_n <= 0.0:
                continue
            normal += f_n
            stiffness += pieces.length[p] / l_g * rock_params[j, Rock.WALL_STIFFNESS]
            damping += pieces.length[p] / l_g * rock_params[j, Rock.WALL_DAMPING]
            if gauge.friction >= 0.0:  # the pads' own coefficient (BitConfig.gauge_friction)
                friction += gauge.friction * f_n
            else:  # eq. (57): the rock's resistance curve
                friction += resistance(w, rock_params[j, Rock.MU_MIN],
                                       rock_params[j, Rock.MU_MAX], rock_params[j, Rock.ST1],
                                       rock_params[j, Rock.ST2]) * f_n
        if normal <= 0.0:
            continue
        pad[PAD.STIFFNESS] = stiffness
        pad[PAD.DAMPING] = damping
        pad[PAD.FORCE] = normal
        if gauge.shared and pad[PAD.END_FORCE] < normal:  # physics/implicit_contact.py
            friction *= pad[PAD.END_FORCE] / normal
        speed = abs(slip)
        if speed < gauge.regularisation_speed:
            friction *= speed / gauge.regularisation_speed
        compliance = cap_compliance
        if compliance > 0.0 and friction > speed / compliance:
            friction = speed / compliance
        if slip < 0.0:
            friction = -friction
        elif slip == 0.0:
            friction = 0.0
        # Normal force along -P/|P|, the gradient of the penetration; for a small bit
        # offset this is eq. (56)'s -(cos theta, sin theta). Friction along -sign(v_r) t.
        fx = -normal * ex - friction * tx
        fy = -normal * ey - friction * ty
        out[BitOut.GAUGE_X] += fx
        out[BitOut.GAUGE_Y] += fy
        out[BitOut.GAUGE_TORQUE] += r_c * c * fy - r_c * s * fx  # exact lever from the axis


@njit(**TUPLE_KERNEL)
def mesoscopic_bit_loads(blades, formation, pieces, kin, wob, gauge, out):
    """Front and gauge loads of the mesoscopic bit; see the module docstring for ``out``.

    ``blades``: :func:`blade_arrays`; ``formation``: a
    :class:`~drill_env.physics.formation.FormationArrays`; ``pieces``: a
    :class:`BitScratch` (left holding the pieces); ``kin``: the :class:`BitKinematics`;
    ``wob``: weight on bit (N, >= 0); ``gauge``: the :class:`GaugeContact` (gauge
    friction is regularised linearly below its ``regularisation_speed`` and, when its
    ``tangential_compliance`` > 0, capped at ``|v_r| / tangential_compliance``).
    Returns the number of pieces.
    """
    for k in range(out.shape[0]):
        out[k] = 0.0
    cos_z = math.cos(kin.phi_z)
    sin_z = math.sin(kin.phi_z)
    n = _split_blades(blades, formation, kin.x, kin.y, kin.depth, cos_z, sin_z, pieces)
    rock_params = formation.rock_params
    _front_loads(blades, rock_params, cos_z, sin_z, kin.omega, wob, n, pieces, out)
    _gauge_loads(blades, rock_params, kin, cos_z, sin_z, gauge, n, pieces, out)
    return n
