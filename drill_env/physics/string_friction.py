"""Soft-string wall friction with implicit stick and slip (docs/model.md section 6).

Where a node has no lateral DOFs (torsion-only runs, the drill pipe held straight at the
fast level) a curved hole still presses it on the wall with the static normal force
``F_n`` of :func:`~drill_env.physics.trajectory.hole_loads` (weight across the hole,
tension turning with it). Such a node feels a Coulomb torque ``mu r F_n`` against its
rotation: ``mu(v)`` of eq. (23) at the predicted contact speed while it slips, and up to
``mu_s r F_n`` holding it while it sticks, like the bit's static and slip torques (a
slip torque is capped at the static one, :func:`_limits`).

Stick or slip is decided implicitly for all nodes and the bit together. Torsion is linear
and tridiagonal: with ``A = J + gamma dt C + beta dt^2 K`` and the Newmark predictor
``v_p``, the end-of-step speeds solve ``A v = A v_p + gamma dt (r + tau)``, where ``r`` is
the residual without friction and ``tau`` the friction torques. Each node is stuck
(``v = 0``, ``|tau| <= T_static``) or slips (``tau = -sign(v) T_slip``). A primal-dual
active-set iteration guesses the set, solves the tridiagonal system with the stuck rows
held at zero (Thomas algorithm, O(n)), then releases the stuck nodes whose holding torque
exceeds their static limit and sticks the slipping nodes whose speed came out reversed.
It starts from the previous step's set and converges in one or two solves when nothing
changes. A node the last solve held ends the step at rest with no acceleration
(:func:`settle_held`): a whole string stuck along a lateral stays exactly at rest, with
steady holding torques (no regularisation, so no creep; no alternating acceleration).

Without a friction node (the vertical hole) the step keeps the exact bit rule of
:mod:`~drill_env.physics.integrator` and its arithmetic.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from drill_env.physics.layout import P, S

#: Active-set solves before the step gives up improving the set and keeps the last one;
#: ``state[S.FRICTION_ITERATIONS]`` reports the count (negative: gave up). With the slip
#: torque below the static one, 3,000 random 9-node chains from random starts needed at
#: most 7 (a review's measurement; tests/physics/test_string_friction.py checks 52).
MAX_ACTIVE_SET_ITERATIONS = 60

#: How often a step's solve may take back the cap of the bit's slip torque (see
#: :func:`soft_string_torsion`); then it ends however the set turns out. A bound that
#: keeps a release-cap-uncap sequence from using up the active set's iterations.
MAX_BIT_CAP_CHECKS = 4

#: ``Motion.stick`` entries: the slip direction of a node, or stuck.
STUCK = 0.0

#: The row of ``Work.soft`` that is the Thomas solve's scratch during a solve and, after
#: each one, 1 where that solve held the node at rest (read by :func:`settle_held`).
HELD_ROW = 2


@njit(cache=True)
def wall_friction_coefficient(v, mu_static, mu_kinetic, decay):
    """mu(|v|) = mu_k + (mu_s - mu_k) exp(-|v|/v_s): velocity-dependent wall friction
    (eq. 23), the one definition for the wall contacts, the soft-string nodes and the
    steady torque of a curved hole."""
    return mu_kinetic + (mu_static - mu_kinetic) * np.exp(-abs(v) / decay)


@njit(cache=True, inline="always")
def _limits(p, nodes, m, k, bit, t_slip, t_static):
    """(static, slip) torque limits of node ``k``; the bit's come from the bit model.
    A wall node's slip torque is capped at its static one (``friction_kinetic >
    friction_static`` would exceed it): a node that slips with more torque than would hold
    it reverses at once and sticks, and held it needs more than its limit, so the set
    would cycle. The bit keeps the rock's slip torque, as in the straight hole's solve
    (eq. 39's rising branch past ``mu_max`` at speed); :func:`soft_string_torsion` caps
    it only where that cycle begins. No static limit: no friction."""
    if k == bit:
        return max(t_static, 0.0), t_slip
    lever = nodes.soft_normal[k]  # r F_n (N m per unit friction coefficient)
    if lever <= 0.0:
        return 0.0, 0.0
    mu = wall_friction_coefficient(m.vt[k] * nodes.radius[k], p[P.MU_STATIC],
                                   p[P.MU_KINETIC], p[P.MU_DECAY])
    static = max(p[P.MU_STATIC], 0.0) * lever
    return static, min(mu * lever, static)


@njit(cache=True)
def thomas_sweep(band):
    """(2, n): the Thomas algorithm's ``cp`` and ``1 / diag`` for ``band`` with no row
    held, in :func:`_solve_held`'s arithmetic, so its free-string path can skip the
    divisions and return the same floats."""
    n = band.shape[1]
    sweep = np.zeros((2, n))
    for i in range(n):
        diag = band[0, i]
        if i > 0:
            diag -= band[1, i - 1] * sweep[0, i - 1]
        inv = 1.0 / diag
        sweep[0, i] = band[1, i] * inv if i < n - 1 else 0.0
        sweep[1, i] = inv
    return sweep


@njit(cache=True, inline="always")
def _solve_held(band, sweep, rhs, stick, static_limit, cp, v):
    """Solve the tridiagonal ``band`` system for ``v`` with the stuck friction nodes
    (``stick`` 0 and a static limit) held at zero: their rows become ``v_k = 0``. Thomas;
    a held row leaves ``cp`` and ``v`` zero, so its neighbours need no special case.
    With no row held the sweep's ``cp`` and ``1 / diag`` are ``sweep``
    (:func:`thomas_sweep`): the same floats without a division in the chain. Returns the
    last row's ``1 / pivot``, the last diagonal entry of the held system's inverse (0 if
    that row is held): how the last node's speed answers a torque on it."""
    n = v.shape[0]
    held = False
    for i in range(n):
        if stick[i] == STUCK and static_limit[i] > 0.0:
            held = True
            break
    if not held:
        prev = 0.0
        for i in range(n):
            r = rhs[i]
            if i > 0:
                r -= band[1, i - 1] * prev
            prev = r * sweep[1, i]
            v[i] = prev
        for i in range(n - 2, -1, -1):
            prev = v[i] - sweep[0, i] * prev
            v[i] = prev
        return sweep[1, n - 1]
    last = 0.0
    for i in range(n):
        if stick[i] == STUCK and static_limit[i] > 0.0:
            cp[i] = 0.0
            v[i] = 0.0
            continue
        diag = band[0, i]
        r = rhs[i]
        if i > 0:
            off = band[1, i - 1]
            diag -= off * cp[i - 1]
            r -= off * v[i - 1]
        inv = 1.0 / diag
        last = inv
        cp[i] = band[1, i] * inv if i < n - 1 else 0.0
        v[i] = r * inv
    for i in range(n - 2, -1, -1):
        v[i] -= cp[i] * v[i + 1]
    return 0.0 if stick[n - 1] == STUCK and static_limit[n - 1] > 0.0 else last


@njit(cache=True, inline="always")
def _band_times(band, x, i):
    """Row ``i`` of the tridiagonal ``band`` times ``x``."""
    out = band[0, i] * x[i]
    if i > 0:
        out += band[1, i - 1] * x[i - 1]
    if i < x.shape[0] - 1:
        out += band[1, i] * x[i + 1]
    return out


@njit(cache=True, inline="always")
def soft_string_torsion(p, state, torsion, nodes, m, work, t_slip, t_static):
    """The torsion solve with implicit Coulomb friction at the soft-string nodes and the
    bit (module docstring). ``work.rt`` holds the residual; on return ``m.at`` holds the
    accelerations. Returns the bit torque on the string and whether the bit is stuck."""
    n = m.vt.shape[0]
    bit = n - 1
    h = p[P.GAMMA] * p[P.DT]
    band = torsion.band
    stick = m.stick
    base = work.soft[0]  # A v_p + h r
    rhs = work.soft[1]
    cp = work.soft[HELD_ROW]
    v = work.soft[3]
    static_limit = work.soft[4]
    slip_limit = work.soft[5]
    for i in range(n):
        base[i] = _band_times(band, m.vt, i) + h * work.rt[i]
        static_limit[i], slip_limit[i] = _limits(p, nodes, m, i, bit, t_slip, t_static)
    held = cp  # after each solve: 1 where that solve held the node at rest
    bit_released = False
    bit_checks = 0
    iterations = 0
    converged = False
    for _ in range(MAX_ACTIVE_SET_ITERATIONS):
        iterations += 1
        for i in range(n):
            rhs[i] = base[i]
            if stick[i] != STUCK:
                rhs[i] -= h * stick[i] * slip_limit[i]
        g_bit = _solve_held(band, torsion.sweep, rhs, stick, static_limit, cp, v)
        changed = False
        for i in range(n):
            static = static_limit[i]
            held[i] = 0.0
            if static <= 0.0:
                stick[i] = 1.0 if v[i] >= 0.0 else -1.0  # free: follows its speed
                continue
            if stick[i] == STUCK:
                held[i] = 1.0
                holding = (_band_times(band, v, i) - base[i]) / h
                if abs(holding) > static:
                    stick[i] = -1.0 if holding > 0.0 else 1.0
                    if i == bit:
                        # released with the rock's slip torque, the bit may reverse at once
                        # and be held again: that torque is more than held it (a rock whose
                        # resistance rises past mu_max) and no set is consistent. Released
                        # again, it slips with at most the torque that held it: no cycle.
                        if bit_released and slip_limit[i] > static:
                            slip_limit[i] = static
                        bit_released = True
                    changed = True
            elif v[i] * stick[i] < 0.0:
                stick[i] = STUCK
                changed = True
        capped = slip_limit[bit] < t_slip  # only the release above lowers it
        if not changed and capped and bit_checks < MAX_BIT_CAP_CHECKS \
                and stick[bit] != STUCK:
            # the cap is right only where the rock's torque would reverse the bit in the
            # final set; if the set has moved on since, it slips with the rock's torque
            bit_checks += 1
            extra = h * stick[bit] * (t_slip - slip_limit[bit]) * g_bit
            if (v[bit] - extra) * stick[bit] > 0.0:
                slip_limit[bit] = t_slip
                changed = True
        if not changed:
            converged = True
            break
    # negative: the set kept changing and the last solve is kept (physically valid
    # torques, possibly not the consistent set)
    state[S.FRICTION_ITERATIONS] = iterations if converged else -iterations
    t_bit = (_band_times(band, v, bit) - base[bit]) / h  # the torque the solve applied
    stuck = held[bit]
    for i in range(n):
        m.at[i] = (v[i] - m.vt[i]) / h
    return t_bit, stuck


@njit(cache=True, inline="always")
def settle_held(m, work):
    """After the Newmark corrector: the nodes the last solve held are at rest with no
    acceleration. Without this, the acceleration ``-v_p / h`` that stopped a node feeds
    the next predictor, and a stuck node's acceleration and holding torque alternate in
    sign every step (the displacement stays exact either way)."""
    held = work.soft[HELD_ROW]
    for i in range(m.vt.shape[0]):
        if held[i] > 0.0:
            m.vt[i] = 0.0
            m.at[i] = 0.0


def soft_string_nodes(lateral: bool, n_nodes: int, lateral_start: int) -> np.ndarray:
    """Mask of the nodes that feel soft-string friction: every node between the top
    drive and the bit in a torsion-only run; the laterally straight drill pipe and the
    pinned BHA top node (``lateral_start``) when the pipe is held straight; none when
    every node below the top has lateral DOFs (the FE contacts carry the friction)."""
    mask = np.zeros(n_nodes, dtype=bool)
    if not lateral:
        mask[1:-1] = True
    elif lateral_start > 0:
        mask[1:lateral_start + 1] = True
    return mask


@njit(cache=True)
def steady_friction(params, soft_normal, radius, omega):
    """Soft-string torque on each node of a string turning steadily at ``omega`` (N m,
    against the rotation; zero at rest)."""
    out = np.empty_like(soft_normal)
    sign = float(np.sign(omega))
    for k in range(out.shape[0]):
        out[k] = -sign * wall_friction_coefficient(
            omega * radius[k], params[P.MU_STATIC], params[P.MU_KINETIC],
            params[P.MU_DECAY]) * soft_normal[k]
    return out
