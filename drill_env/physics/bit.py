"""Mesoscopic PDC bit (paper section 3, eqs. 28-62) as allocation-free numba kernels.

Hole-fixed frame: ``x, y`` lateral (m), ``z`` measured depth positive DOWNWARD. The bit
face (points A, B of every blade) lies at ``z = depth``; the shoulder B->C rises by
``l_sh cos(alpha_sh)`` while it widens by ``l_sh sin(alpha_sh)`` (SPEC 2.2 correction of
eq. 29), and the gauge pad C->D is axial at radius ``r_C``, ``D_z = C_z - l_g``. Blade i
points along ``theta_i = phi_i + phi_z`` (eq. 35) from the bit centre ``(bx, by)``.

Every straight blade segment is split EXACTLY at every interface plane it crosses
(:func:`split_blades`), which generalises the paper's cases 1-4 to any number of layers.
Each piece carries its rock, length and lever arm = radius of its midpoint from the bit
axis (the midpoint rule of SPEC 2.2).

:func:`mesoscopic_bit_loads` writes, into ``out`` (length ``N_OUT_FIXED + n_rock``):

====================  ==========================================================
``out[TORQUE]``        front torque magnitude at bit speed ``|omega|`` (eqs. 40-53)
``out[TORQUE_STATIC]`` the same at omega -> 0+ (mu = mu_max of each rock)
``out[FORCE_X:+2]``    front lateral force for POSITIVE rotation at ``|omega|``
                       (eqs. 46, 49, 52, 62); the caller multiplies by sign(omega)
``out[FORCE_STATIC_X:+2]`` the same at 0+
``out[GAUGE_X:+2]``    gauge force on the bit, normal + cutting/friction (eqs. 55-60)
``out[GAUGE_TORQUE]``  torque of the gauge forces about the bit axis (signed)
``out[DEPTH_OF_CUT]``  depth of cut per revolution (m/rev): wob sum_j share_j doc_j
``out[SHARES + j]``    share of FRONT blade length in rock j (sums to 1)
====================  ==========================================================
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from drill_env.physics.config import BitConfig
from drill_env.physics.formation import (
    DEPTH_OF_CUT as ROCK_DEPTH_OF_CUT,
)
from drill_env.physics.formation import (
    MU_MAX,
    MU_MIN,
    ST1,
    ST2,
    WALL_DAMPING,
    WALL_STIFFNESS,
    layer_at,
    resistance,
)

# Columns of blade_arrays().
PHI = 0
R_A = 1
R_B = 2
R_C = 3
ALPHA_SH = 4
L_SH = 5
L_G = 6
COS_PHI = 7  # cos and sin of PHI, so a step needs one sincos (of phi_z), not one per blade
SIN_PHI = 8
RISE_SH = 9  # l_sh cos(alpha_sh): height of point C above the face
N_BLADE_COLUMNS = 10

# Segment codes of the pieces.
FACE = 0
SHOULDER = 1
GAUGE = 2
N_SEGMENTS = 3

# Layout of ``out``.
TORQUE = 0
TORQUE_STATIC = 1
FORCE_X = 2
FORCE_Y = 3
FORCE_STATIC_X = 4
FORCE_STATIC_Y = 5
GAUGE_X = 6
GAUGE_Y = 7
GAUGE_TORQUE = 8
DEPTH_OF_CUT = 9
SHARES = 10
N_OUT_FIXED = 10


# --------------------------------------------------------------------------- geometry


def blade_arrays(cfg: BitConfig) -> np.ndarray:
    """``(n_blades, 10)``: ``[phi (rad), r_A, r_B, r_C, alpha_sh (rad), l_sh, l_g, cos phi,
    sin phi, l_sh cos alpha_sh]`` (eq. 29)."""
    n = cfg.n_blades
    alpha = math.radians(cfg.shoulder_angle)
    blades = np.empty((n, N_BLADE_COLUMNS))
    for i in range(n):
        blades[i, PHI] = math.radians(cfg.blade_angles[i])
        blades[i, R_A] = cfg.face_start[i]
        blades[i, R_B] = cfg.face_end[i]
        # SPEC 2.2: the shoulder's radial extent is l_sh sin(alpha_sh).
        blades[i, R_C] = cfg.face_end[i] + cfg.shoulder_length[i] * math.sin(alpha)
        blades[i, ALPHA_SH] = alpha
        blades[i, L_SH] = cfg.shoulder_length[i]
        blades[i, L_G] = cfg.gauge_length[i]
        blades[i, COS_PHI] = math.cos(blades[i, PHI])
        blades[i, SIN_PHI] = math.sin(blades[i, PHI])
        blades[i, RISE_SH] = cfg.shoulder_length[i] * math.cos(alpha)
    return blades


def front_lengths(cfg: BitConfig) -> np.ndarray:
    """l_front,i = l_f,i + l_sh,i per blade (eq. 30)."""
    blades = blade_arrays(cfg)
    return blades[:, R_B] - blades[:, R_A] + blades[:, L_SH]


def front_length(cfg: BitConfig) -> float:
    """L_front = sum_i l_f,i + l_sh,i (eq. 30); the gauge carries no WOB."""
    return float(front_lengths(cfg).sum())


def bit_lever_arm(cfg: BitConfig) -> float:
    """a_bit of eq. (34) with midpoint lever arms (SPEC 2.2).

    a_f,i = (r_A,i + r_B,i) / 2 (eq. 32) and a_sh,i = r_B,i + l_sh,i sin(alpha_sh) / 2
    (eq. 31), so TOB = a_bit mu WOB (eq. 38) for a bit in one rock.
    """
    b = blade_arrays(cfg)
    l_f = b[:, R_B] - b[:, R_A]
    a_f = 0.5 * (b[:, R_A] + b[:, R_B])
    a_sh = b[:, R_B] + 0.5 * b[:, L_SH] * np.sin(b[:, ALPHA_SH])
    return float(np.sum(l_f * a_f + b[:, L_SH] * a_sh) / front_length(cfg))


def front_imbalance(cfg: BitConfig, phi_z: float = 0.0) -> np.ndarray:
    """sum_i l_front,i (sin theta_i, -cos theta_i) / L_front: the one-rock lateral force
    per unit mu WOB (eqs. 46, 52). Zero for a symmetric bit."""
    b = blade_arrays(cfg)
    lengths = front_lengths(cfg)
    theta = b[:, PHI] + phi_z
    return np.array([np.sum(lengths * np.sin(theta)),
                     -np.sum(lengths * np.cos(theta))]) / lengths.sum()


def symmetric_bit() -> BitConfig:
    """The default 8 3/4 in, six-blade bit: equal blades every 60 deg."""
    return BitConfig()


#: Asymmetric (anti-whirl-like) preset: three long primary blades reaching near the
#: centre, bunched on one side, and three short secondary blades opposite, at unequal
#: angles. See ``asymmetric_bit``.
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


class BitScratch(NamedTuple):
    """Preallocated piece arrays for :func:`split_blades` (blade-major, segment order)."""

    piece_blade: np.ndarray  # int64
    piece_segment: np.ndarray  # int64: FACE, SHOULDER, GAUGE
    piece_rock: np.ndarray  # int64
    piece_length: np.ndarray  # float64 (m)
    piece_lever: np.ndarray  # float64: radius of the piece midpoint from the bit axis (m)


def max_pieces(n_blades: int, n_interfaces: int) -> int:
    """A segment crosses each plane at most once: n_interfaces + 1 pieces per segment."""
    return n_blades * N_SEGMENTS * (n_interfaces + 1)


def make_bit_scratch(n_blades: int, n_interfaces: int) -> BitScratch:
    n = max_pieces(n_blades, n_interfaces)
    return BitScratch(np.zeros(n, np.int64), np.zeros(n, np.int64), np.zeros(n, np.int64),
                      np.zeros(n), np.zeros(n))


def make_loads_out(n_rocks: int) -> np.ndarray:
    return np.zeros(N_OUT_FIXED + n_rocks)


# --------------------------------------------------------------------------- kernels


@njit(cache=True, inline="always")
def _blade_direction(blades, i, cos_z, sin_z):
    """(cos theta_i, sin theta_i) of theta_i = phi_i + phi_z (eq. 35) from the stored
    cos/sin of phi_i and those of phi_z: two rotations' worth of multiplies, no sincos."""
    c = blades[i, COS_PHI] * cos_z - blades[i, SIN_PHI] * sin_z
    s = blades[i, SIN_PHI] * cos_z + blades[i, COS_PHI] * sin_z
    return c, s


@njit(cache=True, inline="always")
def _split_segment(x0, y0, z0, x1, y1, z1, r0, r1, length, blade, segment, normals,
                   offsets, layer_rock, piece_blade, piece_segment, piece_rock,
                   piece_length, piece_lever, n):
    """Split the segment p0 -> p1 (radii r0 -> r1 from the bit axis) at every plane it
    crosses; append the pieces from index n on and return the new count."""
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
        piece_blade[n] = blade
        piece_segment[n] = segment
        piece_rock[n] = layer_rock[layer]
        piece_length[n] = (t_next - t_prev) * length
        # The blade is radial in the bit frame, so the radius is linear along it.
        piece_lever[n] = r0 + tm * (r1 - r0)
        n += 1
        if t_next >= 1.0:
            return n
        t_prev = t_next


@njit(cache=True)
def split_blades(blades, normals, offsets, layer_rock, bx, by, depth, phi_z, piece_blade,
                 piece_segment, piece_rock, piece_length, piece_lever):
    """Split face A->B, shoulder B->C and gauge C->D of every blade at every interface.

    Points in the hole frame (eq. 35, SPEC 2.2 geometry): A, B at z = depth, C at
    z = depth - l_sh cos(alpha_sh), D at C_z - l_g. Returns the number of pieces written
    (blade-major, then segment, then along the segment). Zero-length segments give no
    piece. The rock of a piece is that of its midpoint, so the split is exact.
    """
    return _split_blades(blades, normals, offsets, layer_rock, bx, by, depth,
                         math.cos(phi_z), math.sin(phi_z), piece_blade, piece_segment,
                         piece_rock, piece_length, piece_lever)


@njit(cache=True)
def _split_blades(blades, normals, offsets, layer_rock, bx, by, depth, cos_z, sin_z,
                  piece_blade, piece_segment, piece_rock, piece_length, piece_lever):
    """:func:`split_blades` with the bit angle given as its cosine and sine."""
    # np.int64(): plain ints, not literals, so _split_segment compiles only once.
    n = np.int64(0)
    face, shoulder, gauge = np.int64(FACE), np.int64(SHOULDER), np.int64(GAUGE)
    for i in range(blades.shape[0]):
        c, s = _blade_direction(blades, i, cos_z, sin_z)  # eq. (35)
        r_a = blades[i, R_A]
        r_b = blades[i, R_B]
        r_c = blades[i, R_C]
        l_sh = blades[i, L_SH]
        l_g = blades[i, L_G]
        z_c = depth - blades[i, RISE_SH]
        z_d = z_c - l_g
        if r_b - r_a > 0.0:
            n = _split_segment(bx + r_a * c, by + r_a * s, depth, bx + r_b * c, by + r_b * s,
                               depth, r_a, r_b, r_b - r_a, i, face, normals, offsets,
                               layer_rock, piece_blade, piece_segment, piece_rock,
                               piece_length, piece_lever, n)
        if l_sh > 0.0:
            n = _split_segment(bx + r_b * c, by + r_b * s, depth, bx + r_c * c, by + r_c * s,
                               z_c, r_b, r_c, l_sh, i, shoulder, normals, offsets,
                               layer_rock, piece_blade, piece_segment, piece_rock,
                               piece_length, piece_lever, n)
        if l_g > 0.0:
            n = _split_segment(bx + r_c * c, by + r_c * s, z_c, bx + r_c * c, by + r_c * s,
                               z_d, r_c, r_c, l_g, i, gauge, normals, offsets, layer_rock,
                               piece_blade, piece_segment, piece_rock, piece_length,
                               piece_lever, n)
    return n


@njit(cache=True)
def _front_loads(blades, rock_params, cos_z, sin_z, omega, wob, n, piece_blade, piece_segment,
                 piece_rock, piece_length, piece_lever, out):
    """Front (face + shoulder) torque, lateral force, shares and depth of cut."""
    l_front = 0.0
    for i in range(blades.shape[0]):
        l_front += blades[i, R_B] - blades[i, R_A] + blades[i, L_SH]  # eq. (30)
    load = wob / l_front  # eq. (40): line load on the front blades
    w = abs(omega)
    last_rock = -1
    mu = 0.0
    for p in range(n):
        if piece_segment[p] == GAUGE:
            continue
        j = piece_rock[p]
        length = piece_length[p]
        if j != last_rock:  # pieces come in runs of one rock: one exp per run
            mu = resistance(w, rock_params[j, MU_MIN], rock_params[j, MU_MAX],
                            rock_params[j, ST1], rock_params[j, ST2])
            last_rock = j
        mu0 = rock_params[j, MU_MAX]  # eq. (39) at 0+
        c, s = _blade_direction(blades, piece_blade[p], cos_z, sin_z)
        sx = s
        cy = -c
        # eqs. (47), (50): cutting force mu l F/L and its torque with the piece lever arm
        out[TORQUE] += mu * piece_lever[p] * length
        out[TORQUE_STATIC] += mu0 * piece_lever[p] * length
        # eqs. (46), (49), (52): the force opposes the blade's motion for omega > 0
        out[FORCE_X] += mu * length * sx
        out[FORCE_Y] += mu * length * cy
        out[FORCE_STATIC_X] += mu0 * length * sx
        out[FORCE_STATIC_Y] += mu0 * length * cy
        out[SHARES + j] += length / l_front
    for k in range(FORCE_STATIC_Y + 1):
        out[k] *= load
    for j in range(rock_params.shape[0]):
        out[DEPTH_OF_CUT] += wob * out[SHARES + j] * rock_params[j, ROCK_DEPTH_OF_CUT]


@njit(cache=True)
def _gauge_loads(blades, rock_params, bx, by, vx, vy, cos_z, sin_z, omega, hole_radius,
                 tangential_compliance, regularisation_speed, n, piece_blade, piece_segment,
                 piece_rock, piece_length, out):
    """Gauge contact of every blade's point D with the wall (eqs. 36, 37, 55-60)."""
    for i in range(blades.shape[0]):
        l_g = blades[i, L_G]
        if l_g <= 0.0:
            continue
        r_c = blades[i, R_C]
        c, s = _blade_direction(blades, i, cos_z, sin_z)
        px = bx + r_c * c
        py = by + r_c * s
        radius = math.sqrt(px * px + py * py)
        penetration = radius - hole_radius  # eq. (36), SPEC: max(0, r - r_limit)
        if penetration <= 0.0:
            continue
        # Velocity of the contact point: bit translation + rotation about the bit axis.
        wx = vx - omega * r_c * s
        wy = vy + omega * r_c * c
        ex = px / radius
        ey = py / radius
        penetration_rate = ex * wx + ey * wy
        tx = -ey
        ty = ex
        slip = tx * wx + ty * wy  # exact form of eq. (37)
        # The resistance curves are in rad/s: the slip speed enters as |v_r| / r_C.
        w = abs(slip) / r_c
        normal = 0.0
        friction = 0.0
        for p in range(n):
            if piece_blade[p] != i or piece_segment[p] != GAUGE:
                continue
            j = piece_rock[p]
            # eq. (55): normal force split by the gauge length in each rock; no adhesion,
            # so each rock's part is clamped at >= 0 (hence also the total).
            f_n = piece_length[p] / l_g * (rock_params[j, WALL_STIFFNESS] * penetration
                                           + rock_params[j, WALL_DAMPING] * penetration_rate)
            if f_n <= 0.0:
                continue
            normal += f_n
            friction += resistance(w, rock_params[j, MU_MIN], rock_params[j, MU_MAX],
                                   rock_params[j, ST1], rock_params[j, ST2]) * f_n  # eq. (57)
        if normal <= 0.0:
            continue
        speed = abs(slip)
        if speed < regularisation_speed:
            friction *= speed / regularisation_speed
        if tangential_compliance > 0.0 and friction > speed / tangential_compliance:
            friction = speed / tangential_compliance
        if slip < 0.0:
            friction = -friction
        elif slip == 0.0:
            friction = 0.0
        # Normal force along -P/|P|, the gradient of the penetration; for a small bit
        # offset this is eq. (56)'s -(cos theta, sin theta). Friction along -sign(v_r) t.
        fx = -normal * ex - friction * tx
        fy = -normal * ey - friction * ty
        out[GAUGE_X] += fx
        out[GAUGE_Y] += fy
        out[GAUGE_TORQUE] += r_c * c * fy - r_c * s * fx  # exact lever from the bit axis


@njit(cache=True)
def mesoscopic_bit_loads(blades, normals, offsets, layer_rock, rock_params, bx, by, vx, vy,
                         depth, phi_z, omega, wob, hole_radius, tangential_compliance,
                         regularisation_speed, piece_blade, piece_segment, piece_rock,
                         piece_length, piece_lever, out):
    """Front and gauge loads of the mesoscopic bit; see the module docstring for ``out``.

    ``(bx, by)``, ``(vx, vy)``: bit centre position and velocity (m, m/s); ``depth``: bit
    face depth (m); ``phi_z``, ``omega``: bit rotation angle and speed (rad, rad/s);
    ``wob``: weight on bit (N, >= 0); ``hole_radius``: borehole radius (m). Gauge friction
    is regularised linearly below ``regularisation_speed`` (m/s) and, when
    ``tangential_compliance`` > 0 (m/(N s)), capped at ``|v_r| / tangential_compliance``.
    Returns the number of pieces (the pieces stay in the scratch arrays).
    """
    for k in range(out.shape[0]):
        out[k] = 0.0
    cos_z = math.cos(phi_z)
    sin_z = math.sin(phi_z)
    n = _split_blades(blades, normals, offsets, layer_rock, bx, by, depth, cos_z, sin_z,
                      piece_blade, piece_segment, piece_rock, piece_length, piece_lever)
    _front_loads(blades, rock_params, cos_z, sin_z, omega, wob, n, piece_blade, piece_segment,
                 piece_rock, piece_length, piece_lever, out)
    _gauge_loads(blades, rock_params, bx, by, vx, vy, cos_z, sin_z, omega, hole_radius,
                 tangential_compliance, regularisation_speed, n, piece_blade, piece_segment,
                 piece_rock, piece_length, out)
    return n
