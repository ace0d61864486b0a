"""Time integration of the drill string (numba).

Scheme (docs/model.md, "Integrator"): Newmark average acceleration (beta = 1/4,
gamma = 1/2) in acceleration form. The linear string (mass, Rayleigh + mud damping,
elastic + geometric stiffness) is implicit, factorised once per axial-load change as
a banded Cholesky; wall contact, the bit and the top drive are explicit forces
evaluated at the Newmark predictors (Hughes & Liu's implicit-explicit partition).
The implicit part is unconditionally stable, so the step is limited only by the
explicit contact and bit terms, not by the stiff short elements.

Stick of the bit is exact: torsion is linear, so the bit's end-of-step speed is
``v_free + g T`` with ``g = gamma dt (A^-1)_bb`` and the column ``A^-1 e_b``
precomputed. If the static resistance can hold the bit (``|v_free| <= g T_static``)
the bit torque is the one that stops it; otherwise it slips on the falling curve.

Every array is preallocated by the caller; nothing is allocated per step.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from drill_env.physics.bit import mesoscopic_bit_loads
from drill_env.physics.formation import DEPTH_OF_CUT, MU_MAX, resistance, rock_at
from drill_env.physics.linalg import (
    band_cholesky,
    cholesky_to_ldl,
    lateral_residual,
    solve3_planes,
    solve_tridiagonal,
    torsion_residual,
)

# ----------------------------------------------------------------- parameter indices
P_DT = 0
P_BETA = 1
P_GAMMA = 2
P_RAYLEIGH_A = 3
P_RAYLEIGH_B = 4
P_WALL_K = 5
P_WALL_C = 6
P_MU_STATIC = 7
P_MU_KINETIC = 8
P_MU_DECAY = 9
P_V_REG = 10
P_CONTACT_ON = 11
P_KP = 12
P_KI = 13
P_TORQUE_MAX = 14
P_ACCEL_MAX = 15
P_HOLE_RADIUS = 16
P_MACRO_BIT = 17
P_LEVER_ARM = 18
P_G_BIT = 19
P_LATERAL = 20  # 1: coupled lateral + torsion, 0: torsion only (lateral frozen)
P_LATERAL_START = 21  # first node with lateral DOFs (> 0: drill pipe held straight)
N_PARAMS = 22

# ----------------------------------------------------------------- scalar state indices
S_TIME = 0
S_DEPTH = 1
S_PI_INTEGRAL = 2
S_SETPOINT = 3  # rate-limited speed set point (rad/s)
S_SETPOINT_TARGET = 4
S_HOOK_LOAD = 5
S_WOB = 6
S_WOB_FACTORED = 7  # WOB the lateral matrix is factorised for (NaN: refactor)
S_MOTOR_TORQUE = 8
S_TOB = 9
S_SURFACE_TORQUE = 10
S_ROP = 11
S_BIT_FX = 12
S_BIT_FY = 13
S_STUCK = 14
S_STATUS = 15  # 0 ok, 1 non-finite state, 2 runaway, 3 lateral factorisation failed
S_GAUGE_FORCE = 16
S_MAX_WALL_FORCE = 17
S_DEPTH_OF_CUT = 18
S_MECH_ENERGY_BIT = 19  # work done by the bit torque (J), for MSE
S_TOP_DRIVE_ENERGY = 20  # work done by the motor (J)
S_STEPS = 21
N_STATE = 22

STATUS_OK = 0
STATUS_NONFINITE = 1
STATUS_RUNAWAY = 2
STATUS_SINGULAR = 3

# ----------------------------------------------------------------- record channels
R_TIME = 0
R_BIT_SPEED = 1
R_SURFACE_SPEED = 2
R_TOB = 3
R_SURFACE_TORQUE = 4
R_WOB = 5
R_BIT_X = 6
R_BIT_Y = 7
R_WHIRL = 8
R_DEPTH = 9
R_ROP = 10
R_MOTOR_TORQUE = 11
R_BIT_FX = 12
R_BIT_FY = 13
R_MAX_WALL_FORCE = 14
R_STUCK = 15
N_RECORD = 16


@njit(cache=True)
def wall_friction_coefficient(v, mu_static, mu_kinetic, decay):
    """mu(|v|) = mu_k + (mu_s - mu_k) exp(-|v|/v_s): velocity-dependent wall friction (eq. 23)."""
    return mu_kinetic + (mu_static - mu_kinetic) * np.exp(-abs(v) / decay)


@njit(cache=True)
def wall_contact(x, y, vx, vy, omega, clearance, radius, p, compliance, out):
    """Penalty normal force and friction of one node against the wall (eqs. 17-26).

    Writes ``out = (Fx, Fy, Mz, F_N)``. The contact point slips at
    ``v_r = r psi_dot + R phi_dot_z``, the exact speed of the material point touching
    the wall (eq. 24 writes (r + R) psi_dot, the speed of the geometric contact point).
    Friction is regularised linearly below ``P_V_REG`` and capped at the force that
    would stop the slip within one step (``|v_r| / compliance``), see docs/model.md.
    """
    out[0] = 0.0
    out[1] = 0.0
    out[2] = 0.0
    out[3] = 0.0
    r2 = x * x + y * y
    if r2 <= clearance * clearance:
        return
    r = np.sqrt(r2)
    f = r - clearance  # eq. (19)
    f_dot = (x * vx + y * vy) / r  # eq. (20)
    fn = p[P_WALL_K] * f + p[P_WALL_C] * f_dot  # eq. (18)
    if fn <= 0.0:
        return  # the wall pulls nothing back
    cos_psi = x / r  # eq. (21)
    sin_psi = y / r
    psi_dot = (x * vy - vx * y) / r2  # eq. (25)
    v_rel = r * psi_dot + radius * omega
    mu = wall_friction_coefficient(v_rel, p[P_MU_STATIC], p[P_MU_KINETIC], p[P_MU_DECAY])
    fr = mu * fn
    v_reg = p[P_V_REG]
    if abs(v_rel) < v_reg:
        fr *= abs(v_rel) / v_reg
    if compliance > 0.0:
        cap = abs(v_rel) / compliance
        if fr > cap:
            fr = cap
    if v_rel > 0.0:  # eq. (23): F_R = -sign(v_r) mu |F_N|
        fr = -fr
    out[0] = -fn * cos_psi - fr * sin_psi  # eqs. (22), (26)
    out[1] = -fn * sin_psi + fr * cos_psi
    out[2] = radius * fr
    out[3] = fn


@njit(cache=True)
def factor_lateral(lat_k, lat_kg_weight, lat_kg_unit, lat_m, wob, p, work_band, lat_factor,
                   lat_k_total):
    """Assemble A = M + gamma dt C + beta dt^2 (K + K_g(WOB)) and factorise it.

    ``K_g(WOB) = K_g,weight - WOB K_g,unit`` because the axial force is linear in WOB.
    Also stores the total stiffness K + K_g(WOB) used by the residual. ``lat_factor``
    receives the LDL^T form of :func:`~drill_env.physics.linalg.cholesky_to_ldl`.
    """
    dt = p[P_DT]
    c_m = 1.0 + p[P_GAMMA] * dt * p[P_RAYLEIGH_A]
    c_d = p[P_GAMMA] * dt * p[P_RAYLEIGH_B]
    c_g = p[P_BETA] * dt * dt
    for d in range(lat_k.shape[0]):
        for i in range(lat_k.shape[1]):
            k_tot = lat_k[d, i] + lat_kg_weight[d, i] - wob * lat_kg_unit[d, i]
            lat_k_total[d, i] = k_tot
            work_band[d, i] = c_g * k_tot + c_d * lat_k[d, i]
    for i in range(lat_k.shape[1]):
        work_band[0, i] += c_m * lat_m[i]
    if not band_cholesky(work_band, lat_factor):
        return False
    cholesky_to_ldl(lat_factor)
    return True


@njit(cache=True, nogil=True)
def advance(n_steps, record_every, p, state,
            lat_k, lat_kg_weight, lat_kg_unit, lat_m, lat_factor, lat_work_band,
            lat_k_total, lat_k_damp, tor_k, tor_c, tor_factor, col_bit,
            node_clearance, node_radius, node_contact, compliance,
            ul, vl, al, ut, vt, at,
            rl, rt, contact_out, node_force,
            blades, normals, offsets, layer_rock, rock_params,
            piece_blade, piece_segment, piece_rock, piece_length, piece_lever, bit_out,
            record):
    """Advance one simulator by ``n_steps`` steps; returns the number of records written.

    Stops early (and sets ``state[S_STATUS]``) if the state stops being finite.
    """
    n = ut.shape[0]
    bit = n - 1
    l0 = int(p[P_LATERAL_START])  # node k has lateral DOFs 2 (k - l0), 2 (k - l0) + 1
    lb = 2 * (bit - l0)  # the bit's lateral displacement DOF
    dt = p[P_DT]
    beta = p[P_BETA]
    gamma = p[P_GAMMA]
    a_ray = p[P_RAYLEIGH_A]
    b_ray = p[P_RAYLEIGH_B]
    n_rec = 0
    wob = state[S_WOB]
    if state[S_WOB_FACTORED] != wob:
        if not factor_lateral(lat_k, lat_kg_weight, lat_kg_unit, lat_m, wob, p,
                              lat_work_band, lat_factor, lat_k_total):
            state[S_STATUS] = STATUS_SINGULAR
            return 0
        state[S_WOB_FACTORED] = wob
    n_lat = ul.shape[1]
    lateral = p[P_LATERAL] > 0.0
    # Torsion only: the lateral forces are dropped (a = 0), but a lateral velocity set by
    # the caller still carries the displacement along. A string at rest skips the loops.
    moving = lateral
    for c in range(2):
        for i in range(n_lat):
            if vl[c, i] != 0.0 or al[c, i] != 0.0:
                moving = True
    for step in range(n_steps):
        # --- Newmark predictors
        h1 = dt * dt * (0.5 - beta)
        h2 = dt * (1.0 - gamma)
        if moving:
            for c in range(2):
                for i in range(n_lat):
                    ul[c, i] += dt * vl[c, i] + h1 * al[c, i]
                    vl[c, i] += h2 * al[c, i]
                    rl[c, i] = 0.0
        for i in range(n):
            ut[i] += dt * vt[i] + h1 * at[i]
            vt[i] += h2 * at[i]
            rt[i] = 0.0

        # --- top drive: rate-limited set point, PI speed loop with torque limit
        sp = state[S_SETPOINT]
        dsp = state[S_SETPOINT_TARGET] - sp
        lim = p[P_ACCEL_MAX] * dt
        if dsp > lim:
            dsp = lim
        elif dsp < -lim:
            dsp = -lim
        sp += dsp
        state[S_SETPOINT] = sp
        err = sp - vt[0]
        t_unsat = p[P_KP] * err + p[P_KI] * state[S_PI_INTEGRAL]
        t_max = p[P_TORQUE_MAX]
        t_motor = min(max(t_unsat, -t_max), t_max)
        if t_motor == t_unsat or (err > 0.0) != (t_unsat > 0.0):
            state[S_PI_INTEGRAL] += err * dt  # conditional integration (anti-windup)
        rt[0] += t_motor
        state[S_MOTOR_TORQUE] = t_motor

        # --- wall contact at every node (the bit node uses the gauge model instead)
        max_wall = 0.0
        if lateral and p[P_CONTACT_ON] > 0.0:
            for k in range(l0 + 1, n):
                node_force[k] = 0.0
                if node_contact[k] == 0.0:
                    continue
                j = 2 * (k - l0)
                xk = ul[0, j]
                yk = ul[1, j]
                if xk * xk + yk * yk <= node_clearance[k] * node_clearance[k]:
                    continue
                wall_contact(xk, yk, vl[0, j], vl[1, j], vt[k],
                             node_clearance[k], node_radius[k], p, compliance[k], contact_out)
                if contact_out[3] > 0.0:
                    rl[0, j] += contact_out[0]
                    rl[1, j] += contact_out[1]
                    rt[k] += contact_out[2]
                    node_force[k] = contact_out[3]
                    if contact_out[3] > max_wall:
                        max_wall = contact_out[3]
        state[S_MAX_WALL_FORCE] = max_wall

        # --- bit: rock under the bit, slip resistance at the predicted speed
        bx = ul[0, lb]
        by = ul[1, lb]
        omega_p = vt[bit]
        w_eval = max(abs(omega_p), 1e-9)
        # mu(0) = 0 by eq. (39)'s sign: a bit breaking away from exact rest is evaluated
        # just off zero so it meets its static resistance.
        omega_bit_eval = omega_p if omega_p != 0.0 else 1e-9
        depth = state[S_DEPTH]
        if p[P_MACRO_BIT] > 0.0:
            rock = rock_at(bx, by, depth, normals, offsets, layer_rock)
            mu_slip = abs(resistance(w_eval, rock_params[rock, 0], rock_params[rock, 1],
                                     rock_params[rock, 2], rock_params[rock, 3]))
            t_slip = p[P_LEVER_ARM] * mu_slip * wob  # eq. (38)
            t_static = p[P_LEVER_ARM] * rock_params[rock, MU_MAX] * wob
            fx_slip = 0.0
            fy_slip = 0.0
            fx_static = 0.0
            fy_static = 0.0
            state[S_DEPTH_OF_CUT] = rock_params[rock, DEPTH_OF_CUT] * wob
            state[S_GAUGE_FORCE] = 0.0
            gauge_x = 0.0
            gauge_y = 0.0
        else:
            mesoscopic_bit_loads(blades, normals, offsets, layer_rock, rock_params,
                                 bx, by, vl[0, lb], vl[1, lb], depth, ut[bit],
                                 omega_bit_eval, wob, p[P_HOLE_RADIUS], compliance[bit], p[P_V_REG],
                                 piece_blade, piece_segment, piece_rock, piece_length,
                                 piece_lever, bit_out)
            t_slip = bit_out[0]
            t_static = bit_out[1]
            fx_slip = bit_out[2]
            fy_slip = bit_out[3]
            fx_static = bit_out[4]
            fy_static = bit_out[5]
            gauge_x = bit_out[6]
            gauge_y = bit_out[7]
            if lateral:
                rl[0, lb] += gauge_x
                rl[1, lb] += gauge_y
            rt[bit] += bit_out[8]
            state[S_GAUGE_FORCE] = np.sqrt(bit_out[6] ** 2 + bit_out[7] ** 2)
            state[S_DEPTH_OF_CUT] = bit_out[9]

        # --- torsion: implicit solve without the front bit torque, then stick / slip
        torsion_residual(tor_k, b_ray, tor_c, ut, vt, rt)
        solve_tridiagonal(tor_factor, rt)
        g_bit = p[P_G_BIT]
        v_free = vt[bit] + gamma * dt * rt[bit]
        if abs(v_free) <= g_bit * t_static:
            t_bit = -v_free / g_bit  # the torque that holds the bit: it sticks
            stuck = 1.0
        else:
            t_bit = -t_slip if v_free > 0.0 else t_slip
            stuck = 0.0
        for i in range(n):
            at[i] = rt[i] + t_bit * col_bit[i]
        state[S_STUCK] = stuck
        state[S_TOB] = -t_bit

        # --- lateral: front cutting force follows the bit torque
        if stuck > 0.0:
            scale = -t_bit / t_static if t_static > 0.0 else 0.0
            fbx = scale * fx_static
            fby = scale * fy_static
        elif t_bit < 0.0:
            fbx = fx_slip
            fby = fy_slip
        else:
            fbx = -fx_slip
            fby = -fy_slip
        state[S_BIT_FX] = fbx + gauge_x
        state[S_BIT_FY] = fby + gauge_y
        if lateral:
            rl[0, lb] += fbx
            rl[1, lb] += fby
            lateral_residual(lat_k_total, lat_k_damp, ul, vl, lat_m, a_ray, rl)
            rl[0, 0] = 0.0  # top node laterally pinned
            rl[1, 0] = 0.0
            solve3_planes(lat_factor, rl)

        # --- Newmark correctors
        h3 = beta * dt * dt
        h4 = gamma * dt
        if lateral:
            for c in range(2):
                for i in range(n_lat):
                    al[c, i] = rl[c, i]
                    ul[c, i] += h3 * al[c, i]
                    vl[c, i] += h4 * al[c, i]
        elif moving:
            for c in range(2):
                for i in range(n_lat):
                    al[c, i] = 0.0
        for i in range(n):
            ut[i] += h3 * at[i]
            vt[i] += h4 * at[i]

        # --- penetration: the bit advances with its own forward rotation only
        omega_bit = vt[bit]
        rop = state[S_DEPTH_OF_CUT] * max(omega_bit, 0.0) / (2.0 * np.pi)
        state[S_ROP] = rop
        state[S_DEPTH] += rop * dt
        state[S_TIME] += dt
        state[S_STEPS] += 1.0
        state[S_MECH_ENERGY_BIT] += abs(t_bit * omega_bit) * dt
        state[S_TOP_DRIVE_ENERGY] += abs(t_motor * vt[0]) * dt
        k0 = tor_k[1, 0]  # element 0 stiffness (-off-diagonal)
        state[S_SURFACE_TORQUE] = -k0 * ((ut[0] - ut[1]) + b_ray * (vt[0] - vt[1]))

        if not (np.isfinite(omega_bit) and np.isfinite(ul[0, lb])
                and np.isfinite(ul[1, lb]) and np.isfinite(vt[0])):
            state[S_STATUS] = STATUS_NONFINITE
            return n_rec
        if abs(omega_bit) > 1.0e3 or bx * bx + by * by > 1.0:
            state[S_STATUS] = STATUS_RUNAWAY
            return n_rec

        if record_every > 0 and (step + 1) % record_every == 0 and n_rec < record.shape[0]:
            x = ul[0, lb]
            y = ul[1, lb]
            r2 = x * x + y * y
            whirl = 0.0
            if r2 > 1e-12:
                whirl = (x * vl[1, lb] - vl[0, lb] * y) / r2
            rec = record[n_rec]
            rec[R_TIME] = state[S_TIME]
            rec[R_BIT_SPEED] = omega_bit
            rec[R_SURFACE_SPEED] = vt[0]
            rec[R_TOB] = state[S_TOB]
            rec[R_SURFACE_TORQUE] = state[S_SURFACE_TORQUE]
            rec[R_WOB] = wob
            rec[R_BIT_X] = x
            rec[R_BIT_Y] = y
            rec[R_WHIRL] = whirl
            rec[R_DEPTH] = state[S_DEPTH]
            rec[R_ROP] = rop
            rec[R_MOTOR_TORQUE] = t_motor
            rec[R_BIT_FX] = state[S_BIT_FX]
            rec[R_BIT_FY] = state[S_BIT_FY]
            rec[R_MAX_WALL_FORCE] = max_wall
            rec[R_STUCK] = stuck
            n_rec += 1
    return n_rec
