"""Slow, independent NumPy/Python version of the mesoscopic bit, the test oracle.

Written from the paper's equations (section 3, eqs. 28-62, with the corrections of
docs/model.md 4.1) without calling the numba kernels of :mod:`drill_env.physics.bit`:
blade points are built as 3-vectors, every segment is cut at the sorted plane crossings,
rocks are looked up by counting the planes above a point, lever arms are measured as
distances from the bit axis, and the loads are assembled per blade and per rock as in
eqs. (47)-(60).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from drill_env.physics.bit import N_BIT_OUT, SHARES, BitOut, Blade, Segment
from drill_env.physics.formation import Rock


@dataclass(frozen=True)
class Piece:
    blade: int
    segment: int  # Segment: face, shoulder, gauge
    rock: int
    length: float
    lever: float


def mu_curve(omega: float, mu_min: float, mu_max: float, st1: float, st2: float) -> float:
    """eq. (39), corrected (docs/model.md 4.1)."""
    if omega == 0.0:
        return 0.0
    return math.copysign(mu_min + (mu_max - mu_min) * math.exp(-abs(omega / st1))
                         + st2 * abs(omega), omega)


def rock_of_point(point: np.ndarray, normals: np.ndarray, offsets: np.ndarray,
                  layer_rock: np.ndarray) -> int:
    below = np.asarray(normals).reshape(-1, 3) @ point > np.asarray(offsets)
    return int(layer_rock[int(np.count_nonzero(below))])


def blade_points(blade: np.ndarray, bx: float, by: float, depth: float,
                 phi_z: float) -> tuple[np.ndarray, ...]:
    """A, B, C, D of one blade in the hole frame (eq. 35, z down; geometry of docs/model.md 4.1)."""
    # The geometry from the config's numbers, not the kernel's cached R_C, trig and rise.
    phi, r_a, r_b = blade[Blade.PHI], blade[Blade.R_A], blade[Blade.R_B]
    alpha, l_sh, l_g = blade[Blade.ALPHA_SH], blade[Blade.L_SH], blade[Blade.L_G]
    r_c = r_b + l_sh * math.sin(alpha)
    direction = np.array([math.cos(phi + phi_z), math.sin(phi + phi_z), 0.0])
    centre = np.array([bx, by, depth])
    a = centre + r_a * direction
    b = centre + r_b * direction
    c = centre + r_c * direction - np.array([0.0, 0.0, l_sh * math.cos(alpha)])
    d = c - np.array([0.0, 0.0, l_g])
    return a, b, c, d


def split(blades: np.ndarray, normals: np.ndarray, offsets: np.ndarray,
          layer_rock: np.ndarray, bx: float, by: float, depth: float,
          phi_z: float) -> list[Piece]:
    """Cut every blade segment at every plane crossing (generalised cases 1-4)."""
    normals = np.asarray(normals, dtype=float).reshape(-1, 3)
    offsets = np.asarray(offsets, dtype=float)
    axis = np.array([bx, by])
    pieces = []
    for i, blade in enumerate(blades):
        a, b, c, d = blade_points(blade, bx, by, depth, phi_z)
        for segment, (p0, p1) in enumerate(((a, b), (b, c), (c, d))):
            length = float(np.linalg.norm(p1 - p0))
            if length == 0.0:
                continue
            g0 = normals @ p0 - offsets
            g1 = normals @ p1 - offsets
            crossing = (g0 > 0) != (g1 > 0)
            ts = np.sort(g0[crossing] / (g0[crossing] - g1[crossing]))
            cuts = np.concatenate([[0.0], ts[(ts > 0.0) & (ts < 1.0)], [1.0]])
            for t0, t1 in zip(cuts[:-1], cuts[1:], strict=True):
                if t1 <= t0:
                    continue
                mid = p0 + 0.5 * (t0 + t1) * (p1 - p0)
                pieces.append(Piece(i, segment, rock_of_point(mid, normals, offsets, layer_rock),
                                    (t1 - t0) * length, float(np.linalg.norm(mid[:2] - axis))))
    return pieces


def bit_loads(blades, normals, offsets, layer_rock, rock_params, bx, by, vx, vy, depth, phi_z,
              omega, wob, hole_radius, tangential_compliance,
              regularisation_speed, gauge_friction=math.nan) -> np.ndarray:
    """Same output layout as :func:`drill_env.physics.bit.mesoscopic_bit_loads`."""
    blades = np.asarray(blades, dtype=float)
    rock_params = np.asarray(rock_params, dtype=float)
    n_rock = rock_params.shape[0]
    pieces = split(blades, normals, offsets, layer_rock, bx, by, depth, phi_z)
    out = np.zeros(N_BIT_OUT + n_rock)

    def mu(j: int, w: float) -> float:
        rp = rock_params[j]
        return mu_curve(w, rp[Rock.MU_MIN], rp[Rock.MU_MAX], rp[Rock.ST1], rp[Rock.ST2])

    l_front = sum((bl[Blade.R_B] - bl[Blade.R_A]) + bl[Blade.L_SH] for bl in blades)  # (30)
    per_len = wob / l_front  # eq. (40)
    for i, blade in enumerate(blades):
        theta = blade[Blade.PHI] + phi_z
        front = [p for p in pieces if p.blade == i and p.segment != Segment.GAUGE]
        # eqs. (48), (51): blade force and torque summed over rocks and pieces
        f_blade = sum(mu(p.rock, abs(omega)) * p.length for p in front) * per_len
        mu_max = rock_params[:, Rock.MU_MAX]
        f_blade0 = sum(mu_max[p.rock] * p.length for p in front) * per_len
        out[BitOut.TORQUE] += sum(mu(p.rock, abs(omega)) * p.lever * p.length
                                  for p in front) * per_len
        out[BitOut.TORQUE_STATIC] += sum(mu_max[p.rock] * p.lever * p.length
                                         for p in front) * per_len
        direction = np.array([math.sin(theta), -math.cos(theta)])  # eq. (49)
        out[BitOut.FORCE_X:BitOut.FORCE_Y + 1] += f_blade * direction
        out[BitOut.FORCE_STATIC_X:BitOut.FORCE_STATIC_Y + 1] += f_blade0 * direction
        for p in front:
            out[SHARES + p.rock] += p.length / l_front
    # the founder point: the depth of cut stops following WOB above each rock's W_f
    founder = rock_params[:, Rock.FOUNDER_WOB]
    slope = rock_params[:, Rock.POST_FOUNDER_SLOPE]
    acting = np.where(wob <= founder, wob,
                      np.maximum(0.0, founder - slope * (wob - np.minimum(founder, wob))))
    out[BitOut.DEPTH_OF_CUT] = float(np.dot(acting * out[SHARES:],
                                            rock_params[:, Rock.DEPTH_OF_CUT]))

    for i, blade in enumerate(blades):
        _, _, _, d = blade_points(blade, bx, by, depth, phi_z)
        gauge = [p for p in pieces if p.blade == i and p.segment == Segment.GAUGE]
        l_g = sum(p.length for p in gauge)
        position = d[:2]
        distance = float(np.linalg.norm(position))
        f = max(0.0, distance - hole_radius)  # eq. (36)
        if f == 0.0 or l_g == 0.0:
            continue
        arm = np.array([d[0] - bx, d[1] - by, 0.0])
        velocity = np.array([vx, vy, 0.0]) + np.cross([0.0, 0.0, omega], arm)
        e_n = position / distance
        e_t = np.array([-e_n[1], e_n[0]])
        f_dot = float(velocity[:2] @ e_n)
        v_r = float(velocity[:2] @ e_t)  # eq. (37)
        # eq. (55) per rock, then no adhesion per rock
        l_by_rock = np.zeros(n_rock)
        for p in gauge:
            l_by_rock[p.rock] += p.length
        f_n = l_by_rock / l_g * (rock_params[:, Rock.WALL_STIFFNESS] * f
                                 + rock_params[:, Rock.WALL_DAMPING] * f_dot)
        f_n = np.maximum(f_n, 0.0)
        if f_n.sum() == 0.0:
            continue
        # eq. (57), the curves in rad/s: slip speed / r_C
        w = abs(v_r) / float(np.linalg.norm(arm))
        if gauge_friction >= 0.0:  # the pads' own coefficient
            f_r = gauge_friction * float(np.sum(np.abs(f_n)))
        else:
            f_r = sum(mu(j, w) * abs(f_n[j]) for j in range(n_rock))
        if abs(v_r) < regularisation_speed:
            f_r *= abs(v_r) / regularisation_speed
        if tangential_compliance > 0.0:
            f_r = min(f_r, abs(v_r) / tangential_compliance)
        f_r *= -np.sign(v_r)
        force = -f_n.sum() * e_n + f_r * e_t
        out[BitOut.GAUGE_X:BitOut.GAUGE_Y + 1] += force
        out[BitOut.GAUGE_TORQUE] += float(arm[0] * force[1] - arm[1] * force[0])
    return out
