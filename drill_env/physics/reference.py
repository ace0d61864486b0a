"""Plain NumPy version of the integrator's time step: the test oracle and the NumPy row
of ``drill-env speed`` (drill_env/tools/speed/core.py).

It integrates exactly the scheme of :func:`drill_env.physics.integrator.advance`
(Newmark average acceleration, implicit linear string, explicit wall contact, top drive
and bit, see that module's docstring) but shares none of its numerics:

* the matrices are re-assembled DENSE from the mesh with :mod:`drill_env.physics.fem`
  (``assemble_lateral`` with the axial force at the actual WOB instead of the kernel's
  ``K_g,weight - WOB K_g,unit`` split; ``assemble_torsion``), the boundary conditions,
  bit and top-drive inertia are applied here, and the systems are solved with dense
  Cholesky factors from :mod:`scipy.linalg` instead of :mod:`drill_env.physics.linalg`;
* the exact stick of the bit uses ``A^-1 e_bit`` from a dense solve;
* the tangential compliances of the friction cap are recomputed from dense inverses;
* wall contact (eqs. 17-26) is written out again, vectorised over the nodes;
* the mesoscopic bit is the pure-Python oracle :func:`drill_env.physics.bit_reference.
  bit_loads` (same output layout as the numba kernel); the macroscopic bit (eq. 38) and
  the rock lookup are written out here.

What it does take from the :class:`~drill_env.physics.simulator.Simulator`: the time
step, the node radii, clearances and contact flags (stabilizer placement), the blade
and formation arrays and the top-drive gains, i.e. inputs, not numerics.

Usage::

    ref = ReferenceStepper(sim)          # copies sim's state
    records = ref.advance(50, speed_setpoint, hook_load, record_every=1)
    ref.ul, ref.vl, ref.al, ref.ut, ref.vt, ref.at, ref.state   # as on the Simulator
"""

from __future__ import annotations

import math

import numpy as np
import scipy.linalg

from drill_env.physics import bit_reference
from drill_env.physics.bit import BitOut, bit_lever_arm
from drill_env.physics.fem import (
    assemble_lateral,
    assemble_torsion,
    axial_force_profile,
    mud_torsional_damping,
)
from drill_env.physics.formation import Rock
from drill_env.physics.integrator import RUNAWAY_DISPLACEMENT_SQ, RUNAWAY_SPEED
from drill_env.physics.layout import N_RECORD, R, S, Status
from drill_env.physics.units import GRAVITY

BETA = 0.25  # Newmark average acceleration
GAMMA = 0.5


def wall_contact_forces(x, y, vx, vy, omega, clearance, radius, compliance, contact):
    """Wall forces of many nodes at once (eqs. 17-26); NumPy twin of ``wall_contact``.

    ``contact`` is a :class:`~drill_env.physics.config.ContactConfig`. Returns
    ``(Fx, Fy, Mz, F_N)`` arrays.
    """
    x, y, vx, vy, omega = (np.asarray(a, dtype=float) for a in (x, y, vx, vy, omega))
    r = np.hypot(x, y)
    outside = r > clearance
    r_safe = np.where(outside, r, 1.0)
    f = r - clearance  # eq. (19)
    f_dot = (x * vx + y * vy) / r_safe  # eq. (20)
    fn = contact.stiffness * f + contact.damping * f_dot  # eq. (18)
    active = outside & (fn > 0.0)
    fn = np.where(active, fn, 0.0)
    cos_psi, sin_psi = x / r_safe, y / r_safe  # eq. (21)
    psi_dot = (x * vy - vx * y) / r_safe**2  # eq. (25)
    v_rel = r * psi_dot + radius * omega  # slip of the material point at the wall
    mu = contact.friction_kinetic + (contact.friction_static - contact.friction_kinetic) * \
        np.exp(-np.abs(v_rel) / contact.friction_decay_speed)
    fr = mu * fn
    fr = np.where(np.abs(v_rel) < contact.regularisation_speed,
                  fr * np.abs(v_rel) / contact.regularisation_speed, fr)
    # capped at the force that stops the slip within one step (compliance 0: no cap)
    compliance = np.asarray(compliance, dtype=float)
    cap = np.abs(v_rel) / np.where(compliance > 0.0, compliance, 1.0)
    fr = np.where(compliance > 0.0, np.minimum(fr, cap), fr)
    fr = np.where(v_rel > 0.0, -fr, fr)  # eq. (23): F_R = -sign(v_r) mu |F_N|
    fx = np.where(active, -fn * cos_psi - fr * sin_psi, 0.0)  # eqs. (22), (26)
    fy = np.where(active, -fn * sin_psi + fr * cos_psi, 0.0)
    mz = np.where(active, radius * fr, 0.0)
    return fx, fy, mz, fn


class ReferenceStepper:
    """Dense NumPy integrator of one :class:`Simulator`'s model, on copies of its state."""

    def __init__(self, sim) -> None:
        if sim.lateral_start:
            raise NotImplementedError("the reference stepper covers solver.pipe_lateral=True "
                                      "(lateral DOFs on every node) only")
        cfg = sim.config
        self.config = cfg
        mesh = sim.mesh
        self.mesh = mesh
        n = mesh.n_nodes
        self.n = n
        self.dt = sim.dt
        self.a_ray = cfg.damping.mass_proportional
        self.b_ray = cfg.damping.stiffness_proportional
        self.bit_buoyed_weight = cfg.bit.mass * GRAVITY * (
            1.0 - cfg.mud.density / cfg.string.lower[0].density)
        self.string_weight = float(np.sum(mesh.buoyed_weight * mesh.element_length)
                                   + self.bit_buoyed_weight)

        # ---- lateral, one plane: bit mass on the last w DOF; the top w DOF is pinned
        k_lat, _, m_lat = assemble_lateral(mesh)
        m_lat[-2] += cfg.bit.mass
        self.k_lat = k_lat
        self.m_lat = m_lat
        # every lateral DOF except the top w (pinned) and, with an axis-aligned bit
        # (paper section 3.1.1), the bit's tilt
        last = 2 * n - 1 if cfg.bit.axis_aligned else 2 * n
        self.free = np.arange(1, last)
        self._lat_wob: float | None = None

        # ---- torsion: top-drive rotor on node 0, bit on the last node, mud drag
        k_tor, j_tor = assemble_torsion(mesh)
        j_tor[0] += cfg.top_drive.inertia
        j_tor[-1] += cfg.bit.inertia
        self.k_tor = k_tor
        self.j_tor = j_tor
        self.c_tor = np.diag(mud_torsional_damping(mesh, cfg.mud.torsional_damping)) \
            + self.b_ray * k_tor
        a_tor = np.diag(j_tor) + GAMMA * self.dt * self.c_tor + BETA * self.dt**2 * k_tor
        self.tor_cho = scipy.linalg.cho_factor(a_tor)
        e_bit = np.zeros(n)
        e_bit[-1] = 1.0
        self.col_bit = scipy.linalg.cho_solve(self.tor_cho, e_bit)
        self.g_bit = GAMMA * self.dt * self.col_bit[-1]

        # ---- contact geometry (stabilizers) and the friction cap's compliance
        self.node_radius = sim.node_radius.copy()
        self.node_clearance = sim.node_clearance.copy()
        self.node_contact = sim.node_contact.astype(bool)
        a_lat0 = self._lateral_system(0.0)
        lat_inv = np.zeros(2 * n)
        lat_inv[self.free] = np.diag(np.linalg.inv(a_lat0))
        radius = self.node_radius.copy()
        radius[-1] = cfg.bit.gauge_radius
        self.compliance = GAMMA * self.dt * (lat_inv[0::2]
                                             + radius**2 * np.diag(np.linalg.inv(a_tor)))
        self.compliance[0] = 0.0

        # ---- top drive, bit, formation
        self.kp, self.ki = sim.top_drive_gains
        self.macroscopic = cfg.bit_model == "macroscopic"
        self.lever_arm = bit_lever_arm(cfg.bit)
        self.blades = sim.blades.copy()
        self.normals = sim.normals.copy()
        self.offsets = sim.offsets.copy()
        self.layer_rock = sim.layer_rock.copy()
        self.rock_params = sim.rock_params.copy()
        self.hole_radius = cfg.string.hole_diameter / 2

        # ---- state (copies)
        self.ul, self.vl, self.al = sim.ul.copy(), sim.vl.copy(), sim.al.copy()
        self.ut, self.vt, self.at = sim.ut.copy(), sim.vt.copy(), sim.at.copy()
        self.state = sim.state.copy()
        self.node_force = sim.node_force.copy()

    # ------------------------------------------------------------------ matrices

    def geometric_stiffness(self, wob: float) -> np.ndarray:
        """Dense lateral K_g of one plane for this WOB (top w DOF not yet removed)."""
        _, kg, _ = assemble_lateral(self.mesh, axial_force_profile(self.mesh, wob,
                                                                   self.bit_buoyed_weight))
        return kg

    def _lateral_system(self, wob: float) -> np.ndarray:
        """A = M + gamma dt C + beta dt^2 (K + K_g) on the free DOFs, C = a M + b K."""
        dt = self.dt
        idx = np.ix_(self.free, self.free)
        k = self.k_lat[idx]
        kg = self.geometric_stiffness(wob)[idx]
        m = np.diag(self.m_lat[self.free])
        return (1.0 + GAMMA * dt * self.a_ray) * m + (BETA * dt**2 + GAMMA * dt * self.b_ray) \
            * k + BETA * dt**2 * kg

    def _factor_lateral(self, wob: float) -> None:
        if self._lat_wob == wob:
            return
        self.kg_lat = self.geometric_stiffness(wob)
        self.lat_cho = scipy.linalg.cho_factor(self._lateral_system(wob))
        self._lat_wob = wob

    # ------------------------------------------------------------------ stepping

    def advance(self, n_steps: int, speed_setpoint: float | None = None,
                hook_load: float | None = None, record_every: int = 0) -> np.ndarray:
        """Same contract as :meth:`Simulator.advance`."""
        st = self.state
        if speed_setpoint is not None:
            st[S.SETPOINT_TARGET] = speed_setpoint
        if hook_load is not None:
            st[S.HOOK_LOAD] = hook_load
            st[S.WOB] = max(0.0, self.string_weight - hook_load)
        wob = st[S.WOB]
        self._factor_lateral(wob)
        st[S.WOB_FACTORED] = wob
        records = []
        for step in range(n_steps):
            rec = self.step(wob)
            if rec is None:
                break
            if record_every > 0 and (step + 1) % record_every == 0:
                records.append(rec)
        return np.array(records).reshape(-1, N_RECORD)

    def step(self, wob: float) -> np.ndarray | None:
        """One Newmark step; returns the record row, or None if the state diverged."""
        st = self.state
        dt, bit = self.dt, self.n - 1
        cfg = self.config
        ul, vl, al, ut, vt, at = self.ul, self.vl, self.al, self.ut, self.vt, self.at

        # --- Newmark predictors
        ul += dt * vl + dt * dt * (0.5 - BETA) * al
        vl += dt * (1.0 - GAMMA) * al
        ut += dt * vt + dt * dt * (0.5 - BETA) * at
        vt += dt * (1.0 - GAMMA) * at
        rl = np.zeros_like(ul)
        rt = np.zeros_like(ut)

        # --- top drive: rate-limited set point, PI with torque limit and anti-windup
        lim = cfg.top_drive.max_acceleration * dt
        sp = st[S.SETPOINT] + float(np.clip(st[S.SETPOINT_TARGET] - st[S.SETPOINT],
                                               -lim, lim))
        st[S.SETPOINT] = sp
        err = sp - vt[0]
        t_unsat = self.kp * err + self.ki * st[S.PI_INTEGRAL]
        t_max = cfg.top_drive.max_torque
        t_motor = min(max(t_unsat, -t_max), t_max)
        if t_motor == t_unsat or (err > 0.0) != (t_unsat > 0.0):
            st[S.PI_INTEGRAL] += err * dt
        rt[0] += t_motor
        st[S.MOTOR_TORQUE] = t_motor

        # --- wall contact
        max_wall = 0.0
        lateral = getattr(cfg.solver, "lateral", True)
        if lateral and cfg.contact.enabled:
            k = np.flatnonzero(self.node_contact)
            fx, fy, mz, fn = wall_contact_forces(
                ul[2 * k, 0], ul[2 * k, 1], vl[2 * k, 0], vl[2 * k, 1], vt[k],
                self.node_clearance[k], self.node_radius[k], self.compliance[k], cfg.contact)
            rl[2 * k, 0] += fx
            rl[2 * k, 1] += fy
            rt[k] += mz
            self.node_force[1:] = 0.0
            self.node_force[k] = fn
            max_wall = float(fn.max(initial=0.0))
        st[S.MAX_WALL_FORCE] = max_wall

        # --- bit at the predicted state
        bx, by = ul[2 * bit, 0], ul[2 * bit, 1]
        omega_p = vt[bit]
        depth = st[S.DEPTH]
        gauge_x = gauge_y = 0.0
        if self.macroscopic:
            point = np.array([bx, by, depth])
            rock = int(self.layer_rock[int(np.count_nonzero(
                self.normals.reshape(-1, 3) @ point > self.offsets))])
            rp = self.rock_params[rock]
            mu_slip = abs(bit_reference.mu_curve(max(abs(omega_p), 1e-9), rp[Rock.MU_MIN],
                                                 rp[Rock.MU_MAX], rp[Rock.ST1], rp[Rock.ST2]))
            t_slip = self.lever_arm * mu_slip * wob  # eq. (38)
            t_static = self.lever_arm * rp[Rock.MU_MAX] * wob
            fx_slip = fy_slip = fx_static = fy_static = 0.0
            founder, slope = rp[Rock.FOUNDER_WOB], rp[Rock.POST_FOUNDER_SLOPE]
            acting = wob if wob <= founder else max(0.0, founder - slope * (wob - founder))
            st[S.DEPTH_OF_CUT] = rp[Rock.DEPTH_OF_CUT] * acting
            st[S.GAUGE_FORCE] = 0.0
        else:
            out = bit_reference.bit_loads(
                self.blades, self.normals, self.offsets, self.layer_rock, self.rock_params,
                bx, by, vl[2 * bit, 0], vl[2 * bit, 1], depth, ut[bit],
                omega_p if omega_p != 0.0 else 1e-9, wob,  # mu(0) = 0: break away at 0+
                self.hole_radius, self.compliance[bit], cfg.contact.regularisation_speed,
                math.nan if cfg.bit.gauge_friction is None else cfg.bit.gauge_friction)
            t_slip, t_static = out[BitOut.TORQUE], out[BitOut.TORQUE_STATIC]
            fx_slip, fy_slip = out[BitOut.FORCE_X], out[BitOut.FORCE_Y]
            fx_static, fy_static = out[BitOut.FORCE_STATIC_X], out[BitOut.FORCE_STATIC_Y]
            gauge_x, gauge_y = out[BitOut.GAUGE_X], out[BitOut.GAUGE_Y]
            rl[2 * bit, 0] += gauge_x
            rl[2 * bit, 1] += gauge_y
            rt[bit] += out[BitOut.GAUGE_TORQUE]
            st[S.GAUGE_FORCE] = math.hypot(gauge_x, gauge_y)
            st[S.DEPTH_OF_CUT] = out[BitOut.DEPTH_OF_CUT]

        # --- torsion: free solution, then exact stick or slip of the bit
        rt -= self.c_tor @ vt + self.k_tor @ ut
        a_free = scipy.linalg.cho_solve(self.tor_cho, rt)
        v_free = vt[bit] + GAMMA * dt * a_free[bit]
        if abs(v_free) <= self.g_bit * t_static:
            t_bit = -v_free / self.g_bit
            stuck = 1.0
        else:
            t_bit = -t_slip if v_free > 0.0 else t_slip
            stuck = 0.0
        at[:] = a_free + t_bit * self.col_bit
        st[S.STUCK] = stuck
        st[S.TOB] = -t_bit

        # --- lateral: the front cutting force follows the bit torque
        if stuck > 0.0:
            scale = -t_bit / t_static if t_static > 0.0 else 0.0
            fbx, fby = scale * fx_static, scale * fy_static
        elif t_bit < 0.0:
            fbx, fby = fx_slip, fy_slip
        else:
            fbx, fby = -fx_slip, -fy_slip
        rl[2 * bit, 0] += fbx
        rl[2 * bit, 1] += fby
        st[S.BIT_FX] = fbx + gauge_x
        st[S.BIT_FY] = fby + gauge_y
        f = self.free
        if lateral:
            rl[f] -= (self.a_ray * self.m_lat[f])[:, None] * vl[f] \
                + (self.k_lat + self.kg_lat)[np.ix_(f, f)] @ ul[f] \
                + self.b_ray * self.k_lat[np.ix_(f, f)] @ vl[f]
            al[0] = 0.0
            al[f] = scipy.linalg.cho_solve(self.lat_cho, rl[f])
        else:  # torsion only: the lateral DOFs are frozen
            al[:] = 0.0

        # --- Newmark correctors
        ul += BETA * dt * dt * al
        vl += GAMMA * dt * al
        ut += BETA * dt * dt * at
        vt += GAMMA * dt * at
        if stuck > 0.0:  # the held bit at rest with no acceleration (the kernel's reason)
            vt[bit] = 0.0
            at[bit] = 0.0

        # --- penetration, bookkeeping
        omega_bit = vt[bit]
        rop = st[S.DEPTH_OF_CUT] * max(omega_bit, 0.0) / (2.0 * np.pi)
        st[S.ROP] = rop
        st[S.DEPTH] += rop * dt
        st[S.TIME] += dt
        st[S.STEPS] += 1.0
        st[S.MECH_ENERGY_BIT] += abs(t_bit * omega_bit) * dt
        st[S.TOP_DRIVE_ENERGY] += abs(t_motor * vt[0]) * dt
        k0 = self.mesh.torsional_stiffness[0] / self.mesh.element_length[0]
        st[S.SURFACE_TORQUE] = k0 * ((ut[0] - ut[1]) + self.b_ray * (vt[0] - vt[1]))
        if not np.all(np.isfinite([omega_bit, ul[2 * bit, 0], ul[2 * bit, 1], vt[0]])):
            st[S.STATUS] = Status.NONFINITE
            return None
        if abs(omega_bit) > RUNAWAY_SPEED or bx * bx + by * by > RUNAWAY_DISPLACEMENT_SQ:
            st[S.STATUS] = Status.RUNAWAY
            return None

        x, y = ul[2 * bit]
        r2 = x * x + y * y
        rec = np.zeros(N_RECORD)
        rec[R.TIME] = st[S.TIME]
        rec[R.BIT_SPEED] = omega_bit
        rec[R.SURFACE_SPEED] = vt[0]
        rec[R.TORQUE_ON_BIT] = st[S.TOB]
        rec[R.SURFACE_TORQUE] = st[S.SURFACE_TORQUE]
        rec[R.WEIGHT_ON_BIT] = wob
        rec[R.BIT_X] = x
        rec[R.BIT_Y] = y
        rec[R.WHIRL_SPEED] = (x * vl[2 * bit, 1] - vl[2 * bit, 0] * y) / r2 if r2 > 1e-12 else 0.0
        rec[R.DEPTH] = st[S.DEPTH]
        rec[R.ROP] = rop
        rec[R.MOTOR_TORQUE] = t_motor
        rec[R.BIT_FORCE_X] = st[S.BIT_FX]
        rec[R.BIT_FORCE_Y] = st[S.BIT_FY]
        rec[R.MAX_WALL_FORCE] = max_wall
        rec[R.STUCK] = stuck
        return rec
