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

Every array is preallocated by the caller; nothing is allocated per step. The arrays
come as one :class:`~drill_env.physics.layout.KernelArrays` (named in
:mod:`drill_env.physics.layout`); :func:`advance` is a loop over small inlined kernels,
one per stage of the step, in the order of docs/model.md section 5.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from drill_env.physics.bit import PAD, BitKinematics, BitOut, GaugeContact, mesoscopic_bit_loads
from drill_env.physics.formation import Rock, effective_wob, resistance, rock_at
from drill_env.physics.implicit_contact import (
    add_term,
    implicit_contacts_on,
    kappa_of,
    pad_terms,
    resolve,
)
from drill_env.physics.jit import TUPLE_KERNEL
from drill_env.physics.layout import CONTACT, TERM, Feedback, P, R, S, Status
from drill_env.physics.linalg import (
    band_cholesky,
    cholesky_to_ldl,
    lateral_residual,
    solve3_planes,
    solve_twisted,
    torsion_residual,
)
from drill_env.physics.string_friction import (
    settle_held,
    soft_string_torsion,
    wall_friction_coefficient,
)

#: Above this bit speed (rad/s, ~9500 rpm) or lateral displacement (m) the state is a
#: numerical runaway, not drilling: the kernel stops with Status.RUNAWAY.
RUNAWAY_SPEED = 1.0e3
RUNAWAY_DISPLACEMENT = 1.0
RUNAWAY_DISPLACEMENT_SQ = RUNAWAY_DISPLACEMENT * RUNAWAY_DISPLACEMENT
#: Radius^2 (m^2) below which the bit counts as centred and its whirl speed is 0.
WHIRL_MIN_RADIUS_SQ = 1e-12
#: The bit speed (rad/s) at which a resting bit's resistance is evaluated: mu(0) = 0 by
#: eq. (39)'s sign, so a bit breaking away from exact rest is evaluated just off zero,
#: where it meets its static resistance.
BREAKAWAY_SPEED = 1e-9
#: Status codes as the floats the state vector holds.
_SINGULAR = float(Status.SINGULAR)
_NONFINITE = float(Status.NONFINITE)
_RUNAWAY = float(Status.RUNAWAY)
_NO_FEEDBACK = float(Feedback.NONE)
_HIGH_PASS = float(Feedback.HIGH_PASS)


@njit(cache=True)
def wall_contact(x, y, vx, vy, omega, clearance, radius, p, compliance, out):
    """Penalty normal force and friction of one node against the wall (eqs. 17-26).

    Writes ``out`` (layout :data:`~drill_env.physics.layout.CONTACT`: Fx, Fy, Mz, F_N).
    The contact point slips at ``v_r = r psi_dot + R phi_dot_z``, the exact speed of the
    material point touching the wall (eq. 24 writes (r + R) psi_dot, the speed of the
    geometric contact point). Friction is regularised linearly below ``P.V_REG`` and
    capped at the force that would stop the slip within one step
    (``|v_r| / compliance``), see docs/model.md.
    """
    out[CONTACT.FX] = 0.0
    out[CONTACT.FY] = 0.0
    out[CONTACT.MZ] = 0.0
    out[CONTACT.NORMAL] = 0.0
    r2 = x * x + y * y
    if r2 <= clearance * clearance:
        return
    r = np.sqrt(r2)
    f = r - clearance  # eq. (19)
    f_dot = (x * vx + y * vy) / r  # eq. (20)
    fn = p[P.WALL_K] * f + p[P.WALL_C] * f_dot  # eq. (18)
    if fn <= 0.0:
        return  # the wall pulls nothing back
    cos_psi = x / r  # eq. (21)
    sin_psi = y / r
    psi_dot = (x * vy - vx * y) / r2  # eq. (25)
    v_rel = r * psi_dot + radius * omega
    mu = wall_friction_coefficient(v_rel, p[P.MU_STATIC], p[P.MU_KINETIC], p[P.MU_DECAY])
    fr = mu * fn
    v_reg = p[P.V_REG]
    if abs(v_rel) < v_reg:
        fr *= abs(v_rel) / v_reg
    if compliance > 0.0:
        cap = abs(v_rel) / compliance
        if fr > cap:
            fr = cap
    if v_rel > 0.0:  # eq. (23): F_R = -sign(v_r) mu |F_N|
        fr = -fr
    out[CONTACT.FX] = -fn * cos_psi - fr * sin_psi  # eqs. (22), (26)
    out[CONTACT.FY] = -fn * sin_psi + fr * cos_psi
    out[CONTACT.MZ] = radius * fr
    out[CONTACT.NORMAL] = fn


@njit(**TUPLE_KERNEL)
def factor_lateral(lateral, wob, p):
    """Assemble A = M + gamma dt C + beta dt^2 (K + K_g(WOB)) and factorise it.

    ``lateral`` is a :class:`~drill_env.physics.layout.LateralSystem`;
    ``K_g(WOB) = K_g,weight - WOB K_g,unit`` because the axial force is linear in WOB.
    Also stores the total stiffness K + K_g(WOB) used by the residual. ``factor``
    receives the LDL^T form of :func:`~drill_env.physics.linalg.cholesky_to_ldl`.
    Returns False if A is not positive definite.
    """
    dt = p[P.DT]
    c_m = 1.0 + p[P.GAMMA] * dt * p[P.RAYLEIGH_A]
    c_d = p[P.GAMMA] * dt * p[P.RAYLEIGH_B]
    c_g = p[P.BETA] * dt * dt
    k, work = lateral.k, lateral.work
    for d in range(k.shape[0]):
        for i in range(k.shape[1]):
            k_tot = k[d, i] + lateral.kg_weight[d, i] - wob * lateral.kg_unit[d, i]
            lateral.k_total[d, i] = k_tot
            work[d, i] = c_g * k_tot + c_d * k[d, i]
    for i in range(k.shape[1]):
        work[0, i] += c_m * lateral.mass[i]
    if not band_cholesky(work, lateral.factor):
        return False
    cholesky_to_ldl(lateral.factor)
    return True


# ----------------------------------------------------------------- stages of one step


@njit(cache=True, inline="always")
def _predict(p, m, work, nodes, moving):
    """Newmark predictors. The lateral residuals start from the static lateral loads (a
    curved hole's weight across it and turning tension; zero in a vertical hole), the
    torsional ones from zero."""
    dt = p[P.DT]
    h1 = dt * dt * (0.5 - p[P.BETA])
    h2 = dt * (1.0 - p[P.GAMMA])
    if moving:
        for c in range(2):
            for i in range(m.ul.shape[1]):
                m.ul[c, i] += dt * m.vl[c, i] + h1 * m.al[c, i]
                m.vl[c, i] += h2 * m.al[c, i]
                work.rl[c, i] = nodes.static_load[c, i]
    for i in range(m.ut.shape[0]):
        m.ut[i] += dt * m.vt[i] + h1 * m.at[i]
        m.vt[i] += h2 * m.at[i]
        work.rt[i] = 0.0


@njit(cache=True, inline="always")
def _torque_feedback(p, state, mode):
    """Speed command correction ``g H(T_s)`` of a torque-feedback top drive (SoftTorque,
    ZTorque), from the string torque at the top at the end of the last step.

    High-pass ``H = s / (s + w_c)``: ``T_s`` minus its low-pass, backward Euler.
    Band-pass ``H = 2 z w0 s / (s^2 + 2 z w0 s + w0^2)`` (unit gain at w0) as a state-variable
    filter ``x1' = x2``, ``x2' = T_s - w0^2 x1 - 2 z w0 x2``, ``H T_s = 2 z w0 x2``,
    semi-implicit Euler (damping implicit): stable for ``w0 dt < 2``, checked at set-up.
    """
    dt = p[P.DT]
    w = p[P.TD_FILTER_W]
    torque = state[S.SURFACE_TORQUE]
    if mode == _HIGH_PASS:
        low = state[S.TD_LOW_PASS]
        low += w * dt / (1.0 + w * dt) * (torque - low)
        state[S.TD_LOW_PASS] = low
        filtered = torque - low
    else:
        two_zw = 2.0 * p[P.TD_FILTER_ZETA] * w
        x1 = state[S.TD_BAND_1]
        x2 = (state[S.TD_BAND_2] + dt * (torque - w * w * x1)) / (1.0 + two_zw * dt)
        state[S.TD_BAND_1] = x1 + dt * x2
        state[S.TD_BAND_2] = x2
        filtered = two_zw * x2
    correction = p[P.TD_FEEDBACK_GAIN] * filtered
    state[S.TD_CORRECTION] = correction
    return correction


@njit(cache=True, inline="always")
def _top_drive(p, state, m, work):
    """Rate-limited set point, optional torque feedback, PI speed loop with torque limit;
    returns the motor torque."""
    dt = p[P.DT]
    sp = state[S.SETPOINT]
    dsp = state[S.SETPOINT_TARGET] - sp
    lim = p[P.ACCEL_MAX] * dt
    if dsp > lim:
        dsp = lim
    elif dsp < -lim:
        dsp = -lim
    sp += dsp
    state[S.SETPOINT] = sp
    mode = p[P.TD_FEEDBACK]
    if mode != _NO_FEEDBACK:
        sp -= _torque_feedback(p, state, mode)
    sp += state[S.SPEED_CORRECTION]
    err = sp - m.vt[0]
    t_unsat = p[P.KP] * err + p[P.KI] * state[S.PI_INTEGRAL]
    t_max = p[P.TORQUE_MAX]
    t_motor = min(max(t_unsat, -t_max), t_max)
    if t_motor == t_unsat or (err > 0.0) != (t_unsat > 0.0):
        state[S.PI_INTEGRAL] += err * dt  # conditional integration (anti-windup)
    work.rt[0] += t_motor
    state[S.MOTOR_TORQUE] = t_motor
    return t_motor


@njit(cache=True, inline="always")
def _wall_contacts(p, nodes, m, work, l0, implicit_on, terms):
    """Wall contact at every node below ``l0`` (the bit node uses the gauge model
    instead); returns the largest normal force and the number of implicit terms written
    to ``terms`` (with ``implicit_on``)."""
    max_wall = 0.0
    count = 0
    kappa = kappa_of(p, p[P.WALL_K], p[P.WALL_C])
    out = work.contact
    for k in range(l0 + 1, m.ut.shape[0]):
        last = work.node_force[k]  # at the end of the last step
        work.node_force[k] = 0.0
        if nodes.contact[k] == 0.0:
            continue
        j = 2 * (k - l0)
        xk = m.ul[0, j]
        yk = m.ul[1, j]
        if xk * xk + yk * yk <= nodes.clearance[k] * nodes.clearance[k]:
            continue
        wall_contact(xk, yk, m.vl[0, j], m.vl[1, j], m.vt[k], nodes.clearance[k],
                     nodes.radius[k], p, nodes.compliance[k], out)
        # implicit contacts: a continuing contact rubs with the smaller of its predicted
        # and last normal forces, a starting one (last == 0) with the mean of its force at
        # the start of the step (0) and the predicted one (physics/implicit_contact.py:
        # the impact's friction starts backward whirl)
        if implicit_on and out[CONTACT.NORMAL] > last:
            scale = last / out[CONTACT.NORMAL] if last > 0.0 else 0.5
            _friction_on(out, scale, xk, yk, nodes.radius[k])
        if out[CONTACT.NORMAL] > 0.0:
            work.rl[0, j] += out[CONTACT.FX]
            work.rl[1, j] += out[CONTACT.FY]
            work.rt[k] += out[CONTACT.MZ]
            work.node_force[k] = out[CONTACT.NORMAL]
            if out[CONTACT.NORMAL] > max_wall:
                max_wall = out[CONTACT.NORMAL]
            if implicit_on:
                r = np.sqrt(xk * xk + yk * yk)
                count = add_term(terms, count, k, j, xk / r, yk / r, kappa,
                                 out[CONTACT.NORMAL])
    return max_wall, count


@njit(cache=True, inline="always")
def _friction_on(out, scale, x, y, radius):
    """Scale the friction part of one wall contact's result (implicit contacts: the
    normal force it rubs with, physics/implicit_contact.py)."""
    fr = out[CONTACT.MZ] / radius
    r = np.sqrt(x * x + y * y)
    change = (scale - 1.0) * fr
    out[CONTACT.FX] -= change * y / r
    out[CONTACT.FY] += change * x / r
    out[CONTACT.MZ] *= scale


@njit(cache=True, inline="always")
def _implicit_contacts(p, implicit, factor, count, work, state, gauge, m, nodes, l0, bit):
    """The implicit normal forces (:func:`~drill_env.physics.implicit_contact.resolve`)
    into the accelerations; the reported wall and gauge forces become the end-of-step
    ones. ``gauge``: the bit's gauge force at the predictors (x, y), its piece count and
    lateral DOF. Returns the largest wall normal force."""
    gauge_x, gauge_y, n_pieces, lb = gauge
    terms = implicit.terms
    for t in range(count):  # a term may leave: its predictor force goes
        if terms[t, TERM.NODE] >= 0.0:
            work.node_force[int(terms[t, TERM.NODE])] = 0.0
    count = resolve(p, implicit, factor, count, work.rl, m, nodes, l0, bit, n_pieces, lb)
    gram = implicit.gram
    max_wall = 0.0
    dx = 0.0  # the gauge pads' normal force: at the end of the step less at the predictors
    dy = 0.0
    pads = bit.pieces.pads
    for i in range(pads.shape[0]):
        if p[P.MACRO_BIT] == 0.0 and pads[i, PAD.ON] > 0.0 and pads[i, PAD.FORCE] > 0.0:
            dx += pads[i, PAD.FORCE] * pads[i, PAD.EX]
            dy += pads[i, PAD.FORCE] * pads[i, PAD.EY]
        pads[i, PAD.END_FORCE] = 0.0
    for t in range(count):
        force = max(terms[t, TERM.FORCE] + gram[t, count], 0.0)
        node = int(terms[t, TERM.NODE])
        if node < 0:  # a gauge pad, pushing along -n
            dx -= force * terms[t, TERM.NX]
            dy -= force * terms[t, TERM.NY]
            pads[-1 - node, PAD.END_FORCE] = force
            continue
        work.node_force[node] = force
        max_wall = max(max_wall, force)
    if dx != 0.0 or dy != 0.0:
        state[S.BIT_FX] += dx
        state[S.BIT_FY] += dy
        state[S.GAUGE_FORCE] = np.sqrt((gauge_x + dx) ** 2 + (gauge_y + dy) ** 2)
    return max_wall


@njit(cache=True, inline="always")
def _bit_loads(p, state, m, work, compliance, bit, wob, lb, lateral):
    """The bit at the predicted state: the rock under it, its slip and static torques and
    front forces; the gauge forces go into the residuals. Returns
    ``(t_slip, t_static, fx_slip, fy_slip, fx_static, fy_static, gauge_x, gauge_y,
    n_pieces)``."""
    n = m.ut.shape[0]
    bx = m.ul[0, lb]
    by = m.ul[1, lb]
    omega_p = m.vt[n - 1]
    depth = state[S.DEPTH]
    formation = bit.formation
    rock_params = formation.rock_params
    if p[P.MACRO_BIT] > 0.0:
        w_eval = max(abs(omega_p), BREAKAWAY_SPEED)
        rock = rock_at(bx, by, depth, formation.normals, formation.offsets,
                       formation.layer_rock)
        mu_slip = abs(resistance(w_eval, rock_params[rock, Rock.MU_MIN],
                                 rock_params[rock, Rock.MU_MAX], rock_params[rock, Rock.ST1],
                                 rock_params[rock, Rock.ST2]))
        t_slip = p[P.LEVER_ARM] * mu_slip * wob  # eq. (38)
        t_static = p[P.LEVER_ARM] * rock_params[rock, Rock.MU_MAX] * wob
        state[S.DEPTH_OF_CUT] = rock_params[rock, Rock.DEPTH_OF_CUT] * effective_wob(
            wob, rock_params[rock, Rock.FOUNDER_WOB], rock_params[rock, Rock.POST_FOUNDER_SLOPE])
        state[S.GAUGE_FORCE] = 0.0
        return t_slip, t_static, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0
    omega_eval = omega_p if omega_p != 0.0 else BREAKAWAY_SPEED
    out = bit.out
    n_pieces = mesoscopic_bit_loads(
        bit.blades, formation, bit.pieces,
        BitKinematics(bx, by, m.vl[0, lb], m.vl[1, lb], depth, m.ut[n - 1], omega_eval), wob,
        GaugeContact(p[P.HOLE_RADIUS], compliance, p[P.V_REG], p[P.GAUGE_FRICTION],
                     implicit_contacts_on(p)), out)
    gauge_x = out[BitOut.GAUGE_X]
    gauge_y = out[BitOut.GAUGE_Y]
    if lateral:
        work.rl[0, lb] += gauge_x
        work.rl[1, lb] += gauge_y
    work.rt[n - 1] += out[BitOut.GAUGE_TORQUE]
    state[S.GAUGE_FORCE] = np.sqrt(gauge_x ** 2 + gauge_y ** 2)
    state[S.DEPTH_OF_CUT] = out[BitOut.DEPTH_OF_CUT]
    return (out[BitOut.TORQUE], out[BitOut.TORQUE_STATIC], out[BitOut.FORCE_X],
            out[BitOut.FORCE_Y], out[BitOut.FORCE_STATIC_X], out[BitOut.FORCE_STATIC_Y],
            gauge_x, gauge_y, n_pieces)


@njit(cache=True, inline="always")
def _torsion(p, torsion, m, work, t_slip, t_static):
    """Implicit torsion solve without the front bit torque (``work.rt`` holds the
    residual), then the exact stick or slip of the bit (module docstring); returns the
    bit torque (on the string) and stuck."""
    n = m.ut.shape[0]
    bit = n - 1
    solve_twisted(torsion.factor, work.rt)
    g_bit = p[P.G_BIT]
    v_free = m.vt[bit] + p[P.GAMMA] * p[P.DT] * work.rt[bit]
    if abs(v_free) <= g_bit * t_static:
        t_bit = -v_free / g_bit  # the torque that holds the bit: it sticks
        stuck = 1.0
    else:
        t_bit = -t_slip if v_free > 0.0 else t_slip
        stuck = 0.0
    for i in range(n):
        m.at[i] = work.rt[i] + t_bit * torsion.col_bit[i]
    return t_bit, stuck


@njit(cache=True, inline="always")
def _front_force(t_bit, stuck, t_static, fx_slip, fy_slip, fx_static, fy_static):
    """The front cutting force follows the bit torque: scaled static force while stuck,
    the slip force against the rotation otherwise."""
    if stuck > 0.0:
        scale = -t_bit / t_static if t_static > 0.0 else 0.0
        return scale * fx_static, scale * fy_static
    if t_bit < 0.0:
        return fx_slip, fy_slip
    return -fx_slip, -fy_slip


@njit(cache=True, inline="always")
def _lateral(p, lateral, m, work):
    """Implicit lateral solve of both bending planes (the top node laterally pinned)."""
    lateral_residual(lateral.k_total, lateral.k_damp, m.ul, m.vl, lateral.mass,
                     p[P.RAYLEIGH_A], work.rl)
    work.rl[0, 0] = 0.0
    work.rl[1, 0] = 0.0
    solve3_planes(lateral.factor, work.rl)


@njit(cache=True, inline="always")
def _correct(p, m, work, lateral, moving):
    """Newmark correctors; torsion only: the lateral accelerations stay zero."""
    dt = p[P.DT]
    h3 = p[P.BETA] * dt * dt
    h4 = p[P.GAMMA] * dt
    if lateral:
        for c in range(2):
            for i in range(m.ul.shape[1]):
                m.al[c, i] = work.rl[c, i]
                m.ul[c, i] += h3 * m.al[c, i]
                m.vl[c, i] += h4 * m.al[c, i]
    elif moving:
        for c in range(2):
            for i in range(m.ul.shape[1]):
                m.al[c, i] = 0.0
    for i in range(m.ut.shape[0]):
        m.ut[i] += h3 * m.at[i]
        m.vt[i] += h4 * m.at[i]


@njit(cache=True, inline="always")
def _bookkeeping(p, state, torsion, m, t_bit, t_motor):
    """Penetration (the bit advances with its own forward rotation only), time, energies
    and the surface torque; returns the ROP."""
    dt = p[P.DT]
    omega_bit = m.vt[m.vt.shape[0] - 1]
    rop = state[S.DEPTH_OF_CUT] * max(omega_bit, 0.0) / (2.0 * np.pi)
    state[S.ROP] = rop
    state[S.DEPTH] += rop * dt
    state[S.TIME] += dt
    state[S.STEPS] += 1.0
    state[S.MECH_ENERGY_BIT] += abs(t_bit * omega_bit) * dt
    state[S.TOP_DRIVE_ENERGY] += abs(t_motor * m.vt[0]) * dt
    k0 = torsion.k[1, 0]  # element 0 stiffness (-off-diagonal)
    state[S.SURFACE_TORQUE] = -k0 * ((m.ut[0] - m.ut[1]) + p[P.RAYLEIGH_B] * (m.vt[0] - m.vt[1]))
    return rop


@njit(cache=True, nogil=True)
def whirl_speed(x, y, vx, vy):
    """Angular speed of the bit centre about the hole axis, (x vy - vx y) / r^2 (rad/s)."""
    r2 = x * x + y * y
    return (x * vy - vx * y) / r2 if r2 > WHIRL_MIN_RADIUS_SQ else 0.0


@njit(cache=True, inline="always")
def _record(row, state, m, lb, wob, rop, t_motor, max_wall, stuck):
    """One row of the record (:data:`~drill_env.physics.layout.R`)."""
    x = m.ul[0, lb]
    y = m.ul[1, lb]
    whirl = whirl_speed(x, y, m.vl[0, lb], m.vl[1, lb])
    row[R.TIME] = state[S.TIME]
    row[R.BIT_SPEED] = m.vt[m.vt.shape[0] - 1]
    row[R.SURFACE_SPEED] = m.vt[0]
    row[R.TORQUE_ON_BIT] = state[S.TOB]
    row[R.SURFACE_TORQUE] = state[S.SURFACE_TORQUE]
    row[R.WEIGHT_ON_BIT] = wob
    row[R.BIT_X] = x
    row[R.BIT_Y] = y
    row[R.WHIRL_SPEED] = whirl
    row[R.DEPTH] = state[S.DEPTH]
    row[R.ROP] = rop
    row[R.MOTOR_TORQUE] = t_motor
    row[R.BIT_FORCE_X] = state[S.BIT_FX]
    row[R.BIT_FORCE_Y] = state[S.BIT_FY]
    row[R.MAX_WALL_FORCE] = max_wall
    row[R.STUCK] = stuck


# ----------------------------------------------------------------- the step loop


@njit(**TUPLE_KERNEL)
def advance(n_steps, record_every, a):
    """Advance one simulator (its :class:`~drill_env.physics.layout.KernelArrays`) by
    ``n_steps`` steps; returns the number of records written.

    Stops early (and sets ``state[S.STATUS]``) if the state stops being finite.
    """
    p = a.params
    state = a.state
    m = a.motion
    work = a.work
    nodes = a.nodes
    bit_arrays = a.bit
    torsion = a.torsion
    lateral_system = a.lateral
    record = a.record
    n = m.ut.shape[0]
    bit = n - 1
    l0 = int(p[P.LATERAL_START])  # node k has lateral DOFs 2 (k - l0), 2 (k - l0) + 1
    lb = 2 * (bit - l0)  # the bit's lateral displacement DOF
    n_rec = 0
    wob = state[S.WOB]
    if state[S.WOB_FACTORED] != wob:
        if not factor_lateral(lateral_system, wob, p):
            state[S.STATUS] = _SINGULAR
            return 0
        state[S.WOB_FACTORED] = wob
        a.implicit.ready[:] = 0.0  # the columns of A^-1 are the old matrix's
    lateral = p[P.LATERAL] > 0.0
    contact_on = lateral and p[P.CONTACT_ON] > 0.0
    soft_string = p[P.SOFT_STRING] > 0.0
    # Torsion only: the lateral forces are dropped (a = 0), but a lateral velocity set by
    # the caller still carries the displacement along. A string at rest skips the loops.
    moving = lateral
    for c in range(2):
        for i in range(m.ul.shape[1]):
            if m.vl[c, i] != 0.0 or m.al[c, i] != 0.0:
                moving = True
    implicit = a.implicit
    terms = implicit.terms
    implicit_on = implicit_contacts_on(p)
    gauge_implicit = implicit_on and p[P.MACRO_BIT] == 0.0
    for step in range(n_steps):
        _predict(p, m, work, nodes, moving)
        t_motor = _top_drive(p, state, m, work)
        max_wall = 0.0
        count = 0
        if contact_on:
            max_wall, count = _wall_contacts(p, nodes, m, work, l0, implicit_on,
                                             terms)
        state[S.MAX_WALL_FORCE] = max_wall
        bx = m.ul[0, lb]
        by = m.ul[1, lb]
        (t_slip, t_static, fx_slip, fy_slip, fx_static, fy_static, gauge_x, gauge_y,
         n_pieces) = _bit_loads(p, state, m, work, nodes.compliance[bit], bit_arrays, wob, lb,
                                lateral)
        if gauge_implicit:
            count = pad_terms(p, bit_arrays.pieces.pads, terms, count, lb)
        torsion_residual(torsion.k, p[P.RAYLEIGH_B], torsion.c, m.ut, m.vt, work.rt)
        if soft_string:
            t_bit, stuck = soft_string_torsion(p, state, torsion, nodes, m, work, t_slip,
                                               t_static)
        else:
            t_bit, stuck = _torsion(p, torsion, m, work, t_slip, t_static)
        state[S.STUCK] = stuck
        state[S.TOB] = -t_bit
        fbx, fby = _front_force(t_bit, stuck, t_static, fx_slip, fy_slip, fx_static,
                                fy_static)
        state[S.BIT_FX] = fbx + gauge_x
        state[S.BIT_FY] = fby + gauge_y
        if lateral:
            work.rl[0, lb] += fbx
            work.rl[1, lb] += fby
            _lateral(p, lateral_system, m, work)
            if implicit_on:
                max_wall = _implicit_contacts(p, implicit, lateral_system.factor, count, work,
                                              state, (gauge_x, gauge_y, n_pieces, lb), m,
                                              nodes, l0, bit_arrays)
                state[S.MAX_WALL_FORCE] = max_wall
        _correct(p, m, work, lateral, moving)
        if soft_string:
            settle_held(m, work)
        elif stuck > 0.0:  # the held bit at rest with no acceleration, as settle_held
            # leaves a held node: else the acceleration that stopped it feeds the next
            # predictor and the holding torque alternates in sign every step
            m.vt[bit] = 0.0
            m.at[bit] = 0.0
        rop = _bookkeeping(p, state, torsion, m, t_bit, t_motor)

        omega_bit = m.vt[bit]
        if not (np.isfinite(omega_bit) and np.isfinite(m.ul[0, lb])
                and np.isfinite(m.ul[1, lb]) and np.isfinite(m.vt[0])):
            state[S.STATUS] = _NONFINITE
            return n_rec
        if abs(omega_bit) > RUNAWAY_SPEED or bx * bx + by * by > RUNAWAY_DISPLACEMENT_SQ:
            state[S.STATUS] = _RUNAWAY
            return n_rec

        if record_every > 0 and (step + 1) % record_every == 0 and n_rec < record.shape[0]:
            _record(record[n_rec], state, m, lb, wob, rop, t_motor, max_wall, stuck)
            n_rec += 1
    return n_rec
