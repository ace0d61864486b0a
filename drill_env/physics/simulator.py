"""The drill-string simulator: FE string + top drive + bit + formation, SI units.

:class:`Simulator` builds the matrices once, then advances the state with the numba
kernel :func:`drill_env.physics.integrator.advance`. It knows nothing about
Gymnasium; the environment layer wraps it.
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from drill_env.physics import integrator, string_friction, top_drive
from drill_env.physics.bit import (
    SHARES,
    BitKinematics,
    BitOut,
    GaugeContact,
    bit_lever_arm,
    blade_arrays,
    make_bit_scratch,
    make_loads_out,
    mesoscopic_bit_loads,
)
from drill_env.physics.config import MIN_TIME_STEP, ConfigError, SimulationConfig
from drill_env.physics.fem import (
    LATERAL_BANDWIDTH,
    Mesh,
    assemble_lateral_band,
    assemble_torsion_band,
    axial_force_profile,
    build_mesh,
    buoyed_string_weight,
    mud_torsional_damping,
    node_contact_radius,
)
from drill_env.physics.formation import Rock, effective_wob, formation_arrays, resistance, rock_at
from drill_env.physics.implicit_contact import make_implicit, warn_of_curved_hole
from drill_env.physics.layout import (
    N_PARAMS,
    N_READINGS,
    N_RECORD,
    N_STATE,
    RECORD_CHANNELS,
    STATUS_MESSAGES,
    BitArrays,
    KernelArrays,
    LateralSystem,
    Motion,
    Nodes,
    P,
    S,
    Status,
    TorsionSystem,
    Work,
)
from drill_env.physics.linalg import (
    ldl_factor,
    ldl_inverse_band,
    solve_tridiagonal,
    twisted_tridiagonal,
)
from drill_env.physics.readings import SHARE_MIN_SPEED, SHARE_MIN_WOB, advance_and_read, readout
from drill_env.physics.settle import rest_on_wall
from drill_env.physics.statics import (
    OperatingPoint,
    bit_buoyed_weight,
    element_buckling_error,
    resolved_weight_on_bit,
    warn_if_hook_pushes,
)
from drill_env.physics.top_drive import MAX_FILTER_W_DT
from drill_env.physics.trajectory import bit_depth, curved_hole_loads
from drill_env.physics.validation import duration_steps, require_finite, require_steps

__all__ = ["MAX_FILTER_W_DT", "RECORD_CHANNELS", "STATUS_MESSAGES", "OperatingPoint",
           "Simulator", "Status"]


class Simulator:
    """Finite-element drill string with a mesoscopic (or macroscopic) PDC bit.

    Typical use::

        sim = Simulator(SimulationConfig())
        sim.reset(OperatingPoint(surface_speed=50 * RPM, weight_on_bit=100e3))
        records = sim.advance(1000, speed_setpoint=50 * RPM,
                              hook_load=sim.hook_load_for(100e3), record_every=10)
    """

    def __init__(self, config: SimulationConfig | None = None) -> None:
        if config is not None and not isinstance(config, SimulationConfig):  # (a dict: an
            # AttributeError deep inside, or {} the defaults unsaid: a fuzzing walkthrough)
            raise TypeError(f"config: a SimulationConfig, got {type(config).__name__}; dotted "
                            "overrides: with_physics(SimulationConfig(), {...}) (drill_env."
                            "overrides)")
        # solver.fidelity expanded: sim.config shows the mesh and step actually used.
        self.config = (config or SimulationConfig()).resolved()
        cfg = self.config
        self.mesh: Mesh = build_mesh(cfg)
        mesh = self.mesh
        n = mesh.n_nodes
        self.n_nodes = n
        self.bit_buoyed_weight = bit_buoyed_weight(cfg)

        # ---- lateral (one plane; the other is identical); in a curved hole the axial
        # force follows the TVD and static loads act across the hole (docs/model.md, 6)
        self.hole = curved_hole_loads(cfg, mesh, self.bit_buoyed_weight)
        if self.hole is None:
            self.string_weight = buoyed_string_weight(mesh, self.bit_buoyed_weight)
            self.axial_weight = axial_force_profile(mesh, 0.0, self.bit_buoyed_weight)
        else:
            self.string_weight = self.hole.hanging_weight
            self.axial_weight = self.hole.axial_weight
        # axial_weight: axial force at element midpoints at zero WOB (N); a WOB takes
        # off the same force everywhere along the string
        (k_lat, kg_weight, m_lat), (_, kg_with_unit_wob, _) = (
            assemble_lateral_band(mesh, a) for a in (self.axial_weight, self.axial_weight - 1.0))
        kg_unit = kg_weight - kg_with_unit_wob  # K_g(WOB) = K_g,weight - WOB K_g,unit
        m_lat[-2] += cfg.bit.mass
        # Lateral DOFs start at node ``lateral_start``: 0, or the BHA's top node when the
        # pipe is held straight (solver.pipe_lateral=False). Dropping the pipe's rows
        # keeps the pipe element above as a rotational spring on that node's tilt.
        self.lateral_start = 0 if cfg.solver.pipe_lateral else cfg.string.drill_pipe.n_elements
        first = 2 * self.lateral_start
        # in band storage (band[d, i] = A[i, i + d]): A[first:, first:] is band[:, first:]
        k_lat, kg_weight, kg_unit = (m[:, first:].copy() for m in (k_lat, kg_weight, kg_unit))
        m_lat = m_lat[first:].copy()
        d, last = np.arange(LATERAL_BANDWIDTH + 1), k_lat.shape[1] - 1
        for mat in (k_lat, kg_weight, kg_unit):
            mat[:, 0] = 0.0  # top (lateral) node pinned: row and column 0 are band[:, 0]
            if cfg.bit.axis_aligned:  # bit tilt held at zero: row and column ``last``,
                mat[d, last - d] = 0.0  # which are band[d, last - d], carry no force
        m_lat[0] = 1.0
        if cfg.bit.axis_aligned:
            m_lat[-1] = 1.0
        self.lat_k, self.lat_kg_weight, self.lat_kg_unit = k_lat, kg_weight, kg_unit
        self.lat_m = m_lat
        self.lat_factor = np.zeros_like(self.lat_k)
        self.lat_work_band = np.zeros_like(self.lat_k)
        self.lat_k_total = np.zeros_like(self.lat_k)
        self.lat_k_damp = cfg.damping.stiffness_proportional * self.lat_k

        # ---- torsion
        self.tor_k, j_tor = assemble_torsion_band(mesh)
        j_tor[0] += cfg.top_drive.inertia
        j_tor[-1] += cfg.bit.inertia
        self.tor_m = j_tor
        self.tor_c = mud_torsional_damping(mesh, cfg.mud.torsional_damping)

        # ---- node geometry for wall contact
        self.node_radius = radius = node_contact_radius(mesh, cfg)
        self.node_contact = np.ones(n)
        self.node_contact[: self.lateral_start + 1] = 0.0  # pinned or held straight
        self.node_clearance = cfg.string.hole_diameter / 2 - radius
        # nodes without lateral DOFs in a curved hole: soft-string friction (_hole_wob)
        self.soft_nodes = string_friction.soft_string_nodes(
            cfg.solver.lateral, n, self.lateral_start) & (self.hole is not None)
        self.soft_normal = np.zeros(n)
        if cfg.bit_model == "mesoscopic":
            self.node_contact[-1] = 0.0  # the gauge model handles the bit
        else:  # the macroscopic bit touches the wall with its gauge
            radius[-1] = cfg.bit.gauge_radius
            self.node_clearance[-1] = cfg.string.hole_diameter / 2 - radius[-1]

        # ---- bit and formation
        self.blades = blade_arrays(cfg.bit)
        self.lever_arm = bit_lever_arm(cfg.bit)
        fa = formation_arrays(cfg.formation, cfg.bit.diameter,
                              None if self.hole is None else self.hole.bit_frame)
        #: inclination of the hole at the bit (rad, 0: vertical)
        self.bit_inclination = 0.0 if self.hole is None else float(
            np.arccos(np.clip(self.hole.bit_frame[2, 2], -1.0, 1.0)))
        self.normals, self.offsets = fa.normals, fa.offsets
        self.layer_rock, self.rock_params = fa.layer_rock, fa.rock_params
        self.formation = fa
        self.bit_scratch = make_bit_scratch(cfg.bit.n_blades, fa.offsets.shape[0])
        self.bit_out = make_loads_out(self.rock_params.shape[0])

        # ---- time step and the implicit matrices
        self.top_drive_law = top_drive.resolve(cfg)  # its speed loop limits the step too
        self.dt = self.stable_time_step()
        if cfg.solver.implicit_contacts and self.hole is not None:
            warn_of_curved_hole()
        self._build_parameters()
        self._factor_torsion()
        self._compute_compliance()

        # ---- state
        # Lateral state plane-major, (2, 2n): each bending plane one contiguous vector for
        # the kernel; ``ul``/``vl``/``al``: (2n, 2) views (row DOF, column plane x/y).
        nl = 2 * (n - self.lateral_start)
        self.lat_planes = np.zeros((3, 2, nl))  # displacement, velocity, acceleration
        self._bind_lateral_views()
        self.ut, self.vt, self.at = np.zeros(n), np.zeros(n), np.zeros(n)  # torsional motion
        self.rl = np.zeros((2, nl))  # plane-major residual / acceleration scratch
        self.static_load = np.zeros((2, nl))  # curved hole, set with the WOB (_hole_wob)
        self.rt, self.node_force, self.state = np.zeros(n), np.zeros(n), np.zeros(N_STATE)
        self.stick = np.zeros(n)  # soft-string slip directions (0: stuck)
        self.soft_work, self.contact_out = np.zeros((6, n)), np.zeros(4)
        self.implicit = make_implicit(nl, cfg.bit.n_blades)
        #: :data:`~drill_env.physics.layout.READINGS` + rock shares, refreshed by
        #: :meth:`read` (and by ``advance(..., read=True)`` and batched advances).
        self.readings = np.zeros(N_READINGS + self.rock_params.shape[0])
        self._warned_compression = False
        #: WOB (N) below which no element is near its own buckling load
        self.resolved_weight_on_bit = resolved_weight_on_bit(
            self.config, self.mesh, self.axial_weight, self.lateral_start)
        #: From this WOB on, a change of WOB makes :meth:`prepare` run Python (the mesh
        #: check; a curved hole's loads at any WOB), which a batch leaves to it.
        self.checked_weight_on_bit = -math.inf if self.hole is not None else (
            self.resolved_weight_on_bit if cfg.solver.lateral else math.inf)
        self._bind_arrays(np.zeros((1, N_RECORD)))
        self.reset()

    # ------------------------------------------------------------------ set-up

    def _bind_lateral_views(self) -> None:
        self.ul, self.vl, self.al = (plane.T for plane in self.lat_planes)

    def _bind_arrays(self, record: np.ndarray) -> None:
        """(Re)build :attr:`arrays`, the kernel's view of this simulator's storage."""
        self.arrays = KernelArrays(
            params=self.params, state=self.state,
            lateral=LateralSystem(self.lat_k, self.lat_kg_weight, self.lat_kg_unit, self.lat_m,
                                  self.lat_k_damp, self.lat_k_total, self.lat_work_band,
                                  self.lat_factor),
            torsion=TorsionSystem(self.tor_k, self.tor_c, self.tor_twisted, self.col_bit,
                                  self.tor_band, self.tor_sweep),
            nodes=Nodes(self.node_clearance, self.node_radius, self.node_contact,
                        self.compliance, self.static_load, self.soft_normal),
            motion=Motion(self.lat_planes[0], self.lat_planes[1], self.lat_planes[2],
                          self.ut, self.vt, self.at, self.stick),
            work=Work(self.rl, self.rt, self.contact_out, self.node_force, self.soft_work),
            bit=BitArrays(self.blades, self.formation, self.bit_scratch, self.bit_out),
            record=record, implicit=self.implicit)

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        for name in ("ul", "vl", "al", "arrays"):  # views: pickling would detach them
            del state[name]
        state["_record"] = self.arrays.record
        return state

    def __setstate__(self, state: dict) -> None:
        record = state.pop("_record")
        self.__dict__.update(state)
        self._bind_lateral_views()
        self._bind_arrays(record)

    @property
    def top_drive_gains(self) -> tuple[float, float]:
        """(P, I) of the speed loop (:attr:`top_drive_law`)."""
        return self.top_drive_law.proportional_gain, self.top_drive_law.integral_gain

    def stable_time_step(self) -> float:
        """Requested step, shortened to ``solver.critical_step_fraction`` (default 0.5) of
        the critical step of the explicit terms: the wall and gauge penalties (stiffness k,
        damping c on a node mass m; none with ``solver.implicit_contacts``) that of an
        explicit damped oscillator, (2 / w) (sqrt(1 + z^2) - z), w = sqrt(k/m), z = c / (2
        sqrt(k m)), two gauge pads on the wall at once stiffening the bit 1.5x (a fraction
        of at most 0.8 leaves room); the top drive's speed loop on the top node's inertia,
        :func:`~drill_env.physics.top_drive.speed_loop_critical_step`."""
        cfg = self.config
        node_mass = self.lat_m[0::2]  # lumped masses of the lateral nodes, the bit's included

        def critical(m: float, k: float, c: float) -> float:
            zeta = c / (2.0 * math.sqrt(k * m))
            if zeta <= 1.0:  # no cancellation to speak of (and the floats of every run)
                return 2.0 * math.sqrt(m / k) * (math.sqrt(1.0 + zeta * zeta) - zeta)
            # beyond, the same as 1 / (sqrt(1 + z^2) + z): sqrt(1 + z^2) - z cancelled to 0
            return 2.0 * math.sqrt(m / k) / (math.sqrt(1.0 + zeta * zeta) + zeta)

        limits = {}
        touching = self.node_contact[self.lateral_start:] > 0.0  # wall-contact nodes
        if cfg.contact.enabled and touching.any() and not cfg.solver.implicit_contacts:
            limits["contact.stiffness, contact.damping"] = critical(
                float(np.min(node_mass[touching])), cfg.contact.stiffness, cfg.contact.damping)
        for i, r in enumerate(() if cfg.solver.implicit_contacts else cfg.formation.rocks):
            limits[f"formation.rocks[{i}].wall_stiffness, wall_damping"] = critical(
                float(node_mass[-1]), r.wall_stiffness, r.wall_damping)
        limits["top_drive.inertia, proportional_gain, integral_gain"] = \
            top_drive.speed_loop_critical_step(*self.top_drive_gains, float(self.tor_m[0]))
        binding = min(limits, key=limits.__getitem__)
        dt = min(cfg.solver.time_step, cfg.solver.critical_step_fraction * limits[binding])
        if dt < MIN_TIME_STEP:
            what = ("the speed loop on a lighter rotor or with stronger gains than a top drive"
                    " has" if binding.startswith("top_drive") else "a stiffer wall, a harder "
                    "damper or lighter elements than a drilling simulation needs")
            raise ConfigError(f"{binding}: needs a step of {dt:.2e} s (at solver.critical_"
                              f"step_fraction = {cfg.solver.critical_step_fraction}), below "
                              f"{MIN_TIME_STEP} s: {what}")
        return dt

    def _build_parameters(self) -> None:
        cfg = self.config
        p = np.zeros(N_PARAMS)
        p[P.DT] = self.dt
        p[P.BETA] = 0.25
        p[P.GAMMA] = 0.5
        p[P.RAYLEIGH_A] = cfg.damping.mass_proportional
        p[P.RAYLEIGH_B] = cfg.damping.stiffness_proportional
        c = cfg.contact
        p[P.WALL_K] = c.stiffness
        p[P.WALL_C] = c.damping
        p[P.MU_STATIC] = c.friction_static
        p[P.MU_KINETIC] = c.friction_kinetic
        p[P.MU_DECAY] = c.friction_decay_speed
        p[P.V_REG] = c.regularisation_speed
        p[P.CONTACT_ON] = 1.0 if c.enabled else 0.0
        kp, ki = self.top_drive_gains
        p[P.KP] = kp
        p[P.KI] = ki
        p[P.TORQUE_MAX] = cfg.top_drive.max_torque
        p[P.ACCEL_MAX] = cfg.top_drive.max_acceleration
        p[P.HOLE_RADIUS] = cfg.string.hole_diameter / 2
        p[P.MACRO_BIT] = 1.0 if cfg.bit_model == "macroscopic" else 0.0
        p[P.LEVER_ARM] = self.lever_arm
        p[P.LATERAL] = 1.0 if cfg.solver.lateral else 0.0
        p[P.LATERAL_START] = self.lateral_start
        friction = cfg.bit.gauge_friction
        p[P.GAUGE_FRICTION] = math.nan if friction is None else friction
        p[P.SOFT_STRING] = 1.0 if self.soft_nodes.any() else 0.0
        p[P.IMPLICIT_CONTACT] = 1.0 if cfg.solver.implicit_contacts and cfg.solver.lateral \
            else 0.0
        top_drive.feedback_parameters(self.top_drive_law, self.dt, p)
        self.params = p

    def _torsion_system(self) -> np.ndarray:
        dt, p = self.dt, self.params
        band = p[P.BETA] * dt * dt * self.tor_k + p[P.GAMMA] * dt * (
            p[P.RAYLEIGH_B] * self.tor_k)
        band[0] += self.tor_m + p[P.GAMMA] * dt * self.tor_c
        return band

    def _factor_torsion(self) -> None:
        band = self.tor_band = self._torsion_system()
        self.tor_factor = ldl_factor(band, "torsional system matrix")
        # the per-step solve: two half-length chains (linalg.solve_twisted)
        self.tor_twisted = twisted_tridiagonal(band, "torsional system matrix")
        self.tor_sweep = string_friction.thomas_sweep(band)  # the free soft string's
        # K with the top node as reference, for the settled twist of reset
        self._twist_factor = ldl_factor(self.tor_k[:, 1:].copy(), "torsional stiffness")
        # the bit's column and the diagonal of A^-1, from the factor in O(n)
        self.col_bit = np.eye(1, band.shape[1], band.shape[1] - 1)[0]  # e_bit, then
        solve_tridiagonal(self.tor_factor, self.col_bit)               # A^-1 e_bit
        self.params[P.G_BIT] = self.params[P.GAMMA] * self.dt * self.col_bit[-1]
        self._tor_inv_diag = ldl_inverse_band(self.tor_factor)[0].copy()

    def _compute_compliance(self) -> None:
        """Tangential compliance of each contact point within one step (friction cap)."""
        work, factor = np.zeros_like(self.lat_k), np.zeros_like(self.lat_k)
        system = LateralSystem(self.lat_k, self.lat_kg_weight, self.lat_kg_unit, self.lat_m,
                               self.lat_k_damp, np.zeros_like(self.lat_k), work, factor)
        if not integrator.factor_lateral(system, 0.0, self.params):
            raise ValueError("lateral system matrix is not positive definite")
        lat_inv = np.zeros(self.n_nodes)
        lat_inv[self.lateral_start:] = ldl_inverse_band(factor)[0, 0::2]  # O(n)
        radius = np.append(self.node_radius[:-1], self.config.bit.gauge_radius)
        self.compliance = self.params[P.GAMMA] * self.dt * (
            lat_inv + radius**2 * self._tor_inv_diag)
        self.compliance[: self.lateral_start + 1] = 0.0
        if self.params[P.IMPLICIT_CONTACT] > 0.0:  # half the cap: physics/implicit_contact.py
            self.compliance *= 2.0

    # ------------------------------------------------------------------ operation

    def hook_load_for(self, weight_on_bit: float) -> float:
        """Hook load (N) that puts ``weight_on_bit`` on the bit (static axial balance)."""
        require_finite(weight_on_bit, "weight_on_bit")
        return self.string_weight - weight_on_bit

    def _hole_wob(self, wob: float) -> None:
        """The curved hole's static lateral loads at this WOB (displacement DOFs), and
        the normal forces of the soft-string nodes (``node_force``) with their r F_n."""
        if self.hole is not None:
            load = self.hole.load_weight - wob * self.hole.load_unit
            self.static_load[:, 0::2] = load[:, self.lateral_start:]
            soft = self.soft_nodes
            self.node_force[soft] = np.hypot(load[0], load[1])[soft]
            self.soft_normal[soft] = self.node_radius[soft] * self.node_force[soft]

    def check_mesh_resolves(self, weight_on_bit: float) -> None:
        """Raise if an element is compressed beyond what one Hermite element can bend
        (:func:`~drill_env.physics.statics.element_buckling_error`); below
        ``resolved_weight_on_bit`` at once, without the axial profile."""
        if not self.config.solver.lateral or weight_on_bit < self.resolved_weight_on_bit:
            return
        message = element_buckling_error(self.config, self.mesh, weight_on_bit,
                                         self.axial_weight, self.lateral_start)
        if message:
            raise ValueError(message)

    def _warn_if_straight_pipe_compressed(self, weight_on_bit: float) -> None:
        """Warn (once per simulator) if a laterally straight pipe would be in compression.

        ``pipe_lateral=False`` (the fast fidelity level) assumes the neutral point lies in
        the BHA; a compressed pipe would buckle and touch the wall in the full model.
        """
        if (self.lateral_start == 0 or not self.config.solver.lateral
                or self._warned_compression):
            return
        force = self.axial_weight - weight_on_bit  # along the hole, curved or not
        if np.min(force[: self.lateral_start]) < 0.0:
            self._warned_compression = True
            warnings.warn(  # one text: once per place, not per WOB a curved-well task draws
                "the weight on bit puts the drill pipe in compression, but the fast level "
                "(solver.pipe_lateral=False) holds it straight: pipe buckling and its wall "
                "contacts are not modelled. Use fidelity='full' (--fidelity full in evaluate "
                "and benchmark) or a heavier BHA (docs/performance.md).", RuntimeWarning,
                stacklevel=3)

    def weight_on_bit_for(self, hook_load: float) -> float:
        """WOB from hook load; the bit is off bottom when the hook carries everything."""
        return max(0.0, self.string_weight - hook_load)

    def steady_torque_on_bit(self, surface_speed: float, weight_on_bit: float) -> float:
        """Bit torque of steady drilling at this speed (the falling-curve value)."""
        if weight_on_bit <= 0.0 or surface_speed == 0.0:
            return 0.0
        if self.config.bit_model == "macroscopic":
            rp = self._rock_at_bit()
            return self.lever_arm * abs(resistance(surface_speed, rp[Rock.MU_MIN],
                                                   rp[Rock.MU_MAX], rp[Rock.ST1],
                                                   rp[Rock.ST2])) * weight_on_bit
        self._bit_loads(surface_speed, weight_on_bit)
        return float(self.bit_out[BitOut.TORQUE]) * math.copysign(1.0, surface_speed)

    def _rock_at_bit(self) -> np.ndarray:
        """Parameters (:class:`Rock` columns) of the rock at the centred bit's face."""
        return self.rock_params[rock_at(0.0, 0.0, self.depth, self.normals, self.offsets,
                                        self.layer_rock)]

    def _bit_loads(self, omega: float, wob: float) -> np.ndarray:
        """The mesoscopic bit's loads at the current position, centred velocity 0."""
        kin = BitKinematics(self.ul[-2, 0], self.ul[-2, 1], 0.0, 0.0, self.depth, self.ut[-1],
                            omega)
        gauge = GaugeContact(self.params[P.HOLE_RADIUS], 0.0, self.params[P.V_REG],
                             self.params[P.GAUGE_FRICTION], False)
        mesoscopic_bit_loads(self.blades, self.formation, self.bit_scratch, kin, wob, gauge,
                             self.bit_out)
        return self.bit_out

    def reset(self, operating_point: OperatingPoint | None = None,
              depth: float | None = None) -> None:
        """Start from a settled state: steady rotation with its static twist, which
        balances mud drag, the steady bit torque and wall friction at this speed and WOB
        (K phi = f, top node the reference), the PI integrator holding the matching motor
        torque: no start-up transient. Laterally at rest: straight in a vertical hole, on
        the wall in a curved one (:func:`~drill_env.physics.settle.rest_on_wall`)."""
        if depth is not None:
            require_finite(depth, "depth")
        op = operating_point or OperatingPoint()
        cfg = self.config
        for arr in (self.ul, self.vl, self.al, self.ut, self.vt, self.at, self.node_force,
                    self.state, self.bit_scratch.pads):  # pads: the gauge's last forces
            arr[...] = 0.0
        self._mesh_message = ""
        if depth is None:
            depth = bit_depth(cfg)
        self.state[S.DEPTH] = depth
        omega, wob = op.surface_speed, op.weight_on_bit
        self.check_mesh_resolves(wob)
        self._warn_if_straight_pipe_compressed(wob)
        warn_if_hook_pushes(self.string_weight, wob)
        self._hole_wob(wob)
        self.stick[:] = np.sign(omega)
        tob = self.steady_torque_on_bit(omega, wob)
        load = -self.tor_c * omega
        if self.hole is not None and cfg.solver.lateral and cfg.contact.enabled:  # on the wall
            load += rest_on_wall(self, omega, wob)
        if self.soft_nodes.any():
            load += string_friction.steady_friction(self.params, self.soft_normal,
                                                    self.node_radius, omega)
        load[-1] -= tob
        total = -load.sum()  # motor torque that balances everything
        self.ut[1:] = load[1:]
        solve_tridiagonal(self._twist_factor, self.ut[1:])  # K[1:, 1:] ut[1:] = load[1:]
        self.vt[:] = omega
        kp, ki = self.top_drive_gains
        self.state[S.PI_INTEGRAL] = total / ki if ki > 0 else 0.0
        self.state[S.SETPOINT] = omega
        self.state[S.SETPOINT_TARGET] = omega
        self.state[S.WOB] = wob
        self.state[S.HOOK_LOAD] = self.hook_load_for(wob)
        self.state[S.WOB_FACTORED] = np.nan
        self.state[S.MOTOR_TORQUE] = total
        self.state[S.TOB] = tob
        # Readings of the settled state, as the kernel would report them.
        k0 = -self.tor_k[1, 0]
        self.state[S.SURFACE_TORQUE] = k0 * (self.ut[0] - self.ut[1])
        # Torque-feedback filters in their steady state: no correction.
        self.state[S.TD_LOW_PASS] = self.state[S.SURFACE_TORQUE]
        w = self.params[P.TD_FILTER_W]
        self.state[S.TD_BAND_1] = self.state[S.SURFACE_TORQUE] / (w * w) if w > 0 else 0.0
        if wob > 0.0 and omega != 0.0:
            if cfg.bit_model == "macroscopic":
                rp = self._rock_at_bit()
                doc = rp[Rock.DEPTH_OF_CUT] * effective_wob(wob, rp[Rock.FOUNDER_WOB],
                                                            rp[Rock.POST_FOUNDER_SLOPE])
            else:
                doc = float(self._bit_loads(omega, wob)[BitOut.DEPTH_OF_CUT])
            self.state[S.DEPTH_OF_CUT] = doc
            self.state[S.ROP] = doc * max(omega, 0.0) / (2 * np.pi)
        self.read()

    @property
    def speed_correction(self) -> float:
        """Added to the speed command after the set-point rate limit (rad/s), held until
        changed: the command of a stick-slip controller acting at the policy rate (the
        set-point ramp protects the driller's set points, not a controller's fast
        corrections). ``reset`` sets it to 0."""
        return float(self.state[S.SPEED_CORRECTION])

    @speed_correction.setter
    def speed_correction(self, value: float) -> None:
        if not math.isfinite(value):
            raise ValueError(f"speed_correction: must be finite, got {value}")
        self.state[S.SPEED_CORRECTION] = value

    def advance(self, n_steps: int, speed_setpoint: float | None = None,
                hook_load: float | None = None, record_every: int = 0,
                read: bool = False) -> np.ndarray:
        """Advance ``n_steps`` steps under a surface speed set point (rad/s) and hook load (N).

        Returns the recorded samples (one row every ``record_every`` steps, columns
        :data:`RECORD_CHANNELS`); empty when ``record_every`` is 0. ``read``: refresh
        :attr:`readings` in the same compiled call (as :meth:`read` would after it).
        """
        if not self.prepare(n_steps, speed_setpoint, hook_load, record_every):
            if read:
                self.read()
            return np.zeros((0, N_RECORD))
        if read:
            n_rec = advance_and_read(n_steps, record_every, self.arrays, self.readings)
        else:
            n_rec = integrator.advance(n_steps, record_every, self.arrays)
        return self.records(n_rec)

    def read(self) -> np.ndarray:
        """Refresh and return :attr:`readings` (the current state's observables)."""
        readout(self.arrays, self.readings)
        return self.readings

    def prepare(self, n_steps: int, speed_setpoint: float | None = None,
                hook_load: float | None = None, record_every: int = 0) -> bool:
        """Apply the inputs of the next ``n_steps`` steps; False if the simulator is stopped.

        :meth:`advance` is ``prepare`` + one kernel call; a batch of simulators
        (:mod:`drill_env.physics.batch`) prepares each, then runs all kernels in one call.
        """
        require_steps(n_steps, "n_steps")
        require_steps(record_every, "record_every")
        if self.status:
            return False  # stopped: reset() first
        if speed_setpoint is not None:
            if not math.isfinite(speed_setpoint):
                raise ValueError(f"speed_setpoint must be finite, got {speed_setpoint}")
            self.state[S.SETPOINT_TARGET] = speed_setpoint
        if hook_load is not None:
            if not math.isfinite(hook_load):
                raise ValueError(f"hook_load must be finite, got {hook_load}")
            wob = self.weight_on_bit_for(hook_load)
            if wob != self.state[S.WOB]:
                try:
                    self.check_mesh_resolves(wob)
                except ValueError as err:  # a control input, not a config error: stop
                    self.state[S.STATUS] = Status.MESH_BUCKLING
                    self._mesh_message = str(err)
                    return False
                self._hole_wob(wob)  # the curved hole's loads follow the WOB only
            self.state[S.HOOK_LOAD] = hook_load
            self.state[S.WOB] = wob
        n_rec_max = n_steps // record_every if record_every > 0 else 0
        if self.arrays.record.shape[0] < max(n_rec_max, 1):
            self._bind_arrays(np.zeros((max(n_rec_max, 1), N_RECORD)))
        return True

    def kernel_arrays(self) -> KernelArrays:
        """The simulator's storage as the kernel takes it (updated in place by a kernel
        call); :meth:`prepare` may replace the record buffer, and with it this tuple."""
        return self.arrays

    def records(self, n_rec: int) -> np.ndarray:
        """A copy of the first ``n_rec`` rows the last kernel call recorded."""
        return self.arrays.record[:n_rec].copy()

    def set_depth(self, depth: float) -> None:
        """Move the bit face to ``depth`` (m) without moving the string: a study that holds
        the bit at a position in the formation (the stability map) sets it back."""
        require_finite(depth, "depth")
        self.state[S.DEPTH] = depth

    def run(self, duration: float, speed_setpoint: float | None = None,
            hook_load: float | None = None, record_every: int = 0) -> np.ndarray:
        """:meth:`advance` for ``duration`` simulated seconds (> 0; at least one step);
        ``record_every`` > 0 returns every so many steps' records, 0 none."""
        return self.advance(duration_steps(duration, self.dt), speed_setpoint, hook_load,
                            record_every)

    # ------------------------------------------------------------------ observables

    @property
    def status(self) -> int:
        return int(self.state[S.STATUS])

    @property
    def status_message(self) -> str:
        if self.status == Status.MESH_BUCKLING:
            return f"{STATUS_MESSAGES[Status.MESH_BUCKLING]}: {self._mesh_message}"
        return STATUS_MESSAGES[Status(self.status)]

    @property
    def time(self) -> float:
        return float(self.state[S.TIME])

    @property
    def depth(self) -> float:
        return float(self.state[S.DEPTH])

    @property
    def bit_speed(self) -> float:
        return float(self.vt[-1])

    @property
    def surface_speed(self) -> float:
        return float(self.vt[0])

    @property
    def torque_on_bit(self) -> float:
        return float(self.state[S.TOB])

    @property
    def surface_torque(self) -> float:
        return float(self.state[S.SURFACE_TORQUE])

    @property
    def motor_torque(self) -> float:
        return float(self.state[S.MOTOR_TORQUE])

    @property
    def weight_on_bit(self) -> float:
        return float(self.state[S.WOB])

    @property
    def hook_load(self) -> float:
        return float(self.state[S.HOOK_LOAD])

    @property
    def rop(self) -> float:
        return float(self.state[S.ROP])

    @property
    def bit_lateral(self) -> np.ndarray:
        return self.ul[-2].copy()

    @property
    def bit_lateral_velocity(self) -> np.ndarray:
        return self.vl[-2].copy()

    @property
    def whirl_speed(self) -> float:
        return float(integrator.whirl_speed(*self.ul[-2], *self.vl[-2]))

    @property
    def bit_lateral_force(self) -> np.ndarray:
        return np.array([self.state[S.BIT_FX], self.state[S.BIT_FY]])

    @property
    def lateral_displacement(self) -> np.ndarray:
        """(n_nodes, 2) lateral x, y of every node (m); 0 where the pipe is held straight."""
        xy = np.zeros((self.n_nodes, 2))
        xy[self.lateral_start:] = self.ul[0::2]
        return xy

    @property
    def contact_forces(self) -> np.ndarray:
        """(n_nodes,) wall normal force at each node (N); the bit node shows the gauge force."""
        f = self.node_force.copy()
        if self.config.bit_model == "mesoscopic":
            f[-1] = self.state[S.GAUGE_FORCE]
        return f

    @property
    def rock_share(self) -> np.ndarray:
        """Share of front blade length in each rock (sums to 1)."""
        self._bit_loads(max(abs(self.bit_speed), SHARE_MIN_SPEED),
                        max(self.weight_on_bit, SHARE_MIN_WOB))
        return self.bit_out[SHARES:].copy()

    @property
    def bit_angle(self) -> float:
        """Rotation angle of the bit phi_z (rad): where its blades point."""
        return float(self.ut[-1])

    @property
    def node_depth(self) -> np.ndarray:
        return self.mesh.node_depth
