"""The data layout of the compiled step: every array it reads or writes, named once.

Each index set is ONE list of names, turned into an ``IntEnum`` whose members the numba
kernels use as compile-time constants (``params[P.DT]``, ``state[S.WOB]``); the public
channel names derive from the same lists (:data:`RECORD_CHANNELS`, :data:`READINGS`).
Adding a channel is one name here plus the line of the kernel that computes it.

The arrays of one simulator travel as one :class:`KernelArrays` named tuple, grouped by
concern (the string's linear systems, the node contact geometry, the motion, scratch,
the bit and formation). The kernels that take these tuples are compiled without
reference counting (:data:`drill_env.physics.jit.TUPLE_KERNEL`). The bit's own layouts
(blade columns, its output vector) live in :mod:`drill_env.physics.bit`, the rock
parameters in :mod:`drill_env.physics.formation`.
"""

from __future__ import annotations

from enum import IntEnum
from typing import NamedTuple

import numpy as np

from drill_env.physics.bit import BitScratch
from drill_env.physics.formation import FormationArrays

#: Scalar parameters of a simulator (``KernelArrays.params``), set once at build time.
P = IntEnum("P", [
    "DT",             # time step (s)
    "BETA",           # Newmark beta
    "GAMMA",          # Newmark gamma
    "RAYLEIGH_A",     # mass-proportional damping (1/s), lateral only
    "RAYLEIGH_B",     # stiffness-proportional damping (s)
    "WALL_K",         # wall penalty stiffness (N/m), eq. (18)
    "WALL_C",         # wall penalty damping (N s/m)
    "MU_STATIC",      # wall friction at rest
    "MU_KINETIC",     # wall friction sliding
    "MU_DECAY",       # decay speed of the wall friction (m/s)
    "V_REG",          # friction regularisation speed (m/s)
    "CONTACT_ON",     # 1: wall contact enabled
    "KP",             # top-drive PI: proportional gain (N m s/rad)
    "KI",             # top-drive PI: integral gain (N m/rad)
    "TORQUE_MAX",     # top-drive torque limit (N m)
    "ACCEL_MAX",      # set-point rate limit (rad/s^2)
    "HOLE_RADIUS",    # borehole radius at the bit (m)
    "MACRO_BIT",      # 1: macroscopic bit (eq. 38), 0: mesoscopic
    "LEVER_ARM",      # a_bit of eq. (34) (m)
    "G_BIT",          # end-of-step bit speed per unit bit torque (rad/s per N m)
    "LATERAL",        # 1: coupled lateral + torsion, 0: torsion only (lateral frozen)
    "LATERAL_START",  # first node with lateral DOFs (> 0: drill pipe held straight)
    "GAUGE_FRICTION",  # gauge-pad friction coefficient; NaN: the rocks' resistance curves
    "TD_FEEDBACK",    # top-drive torque feedback: 0 none, 1 high-pass, 2 band-pass
    "TD_FEEDBACK_GAIN",  # speed command per string torque (rad/s per N m)
    "TD_FILTER_W",    # filter corner / centre (rad/s)
    "TD_FILTER_ZETA",  # band-pass damping ratio
    "SOFT_STRING",    # 1: soft-string friction at nodes without lateral DOFs
                      # (Nodes.soft_normal; physics/string_friction.py)
    "IMPLICIT_CONTACT",  # 1: wall and gauge normal penalties implicit (with lateral
                         # DOFs only; physics/implicit_contact.py)
], start=0)
N_PARAMS = len(P)

#: Scalar state of a simulator (``KernelArrays.state``): what one step carries to the next.
S = IntEnum("S", [
    "TIME",               # simulated time (s)
    "DEPTH",              # bit face depth (m)
    "PI_INTEGRAL",        # integral of the speed error (rad)
    "SETPOINT",           # rate-limited speed set point (rad/s)
    "SETPOINT_TARGET",    # requested speed set point (rad/s)
    "HOOK_LOAD",          # (N)
    "WOB",                # weight on bit (N)
    "WOB_FACTORED",       # WOB the lateral matrix is factorised for (NaN: refactor)
    "MOTOR_TORQUE",       # (N m)
    "TOB",                # torque on bit (N m)
    "SURFACE_TORQUE",     # torque in the top pipe element (N m)
    "ROP",                # rate of penetration (m/s)
    "BIT_FX",             # lateral force on the bit, x (N)
    "BIT_FY",             # lateral force on the bit, y (N)
    "STUCK",              # 1 while the bit sticks
    "STATUS",             # Status code
    "GAUGE_FORCE",        # gauge normal + friction force magnitude (N)
    "MAX_WALL_FORCE",     # largest wall normal force of the string (N)
    "DEPTH_OF_CUT",       # depth of cut per revolution (m/rev)
    "MECH_ENERGY_BIT",    # work done by the bit torque (J), for MSE
    "TOP_DRIVE_ENERGY",   # work done by the motor (J)
    "STEPS",              # steps taken
    "TD_LOW_PASS",        # high-pass filter: low-passed string torque (N m)
    "TD_BAND_1",          # band-pass filter state 1 (N m s^2)
    "TD_BAND_2",          # band-pass filter state 2 (N m s)
    "TD_CORRECTION",      # speed command correction of the torque feedback (rad/s)
    "SPEED_CORRECTION",   # correction added to the speed command after the set-point rate
                          # limit (rad/s): a policy acting as a stick-slip controller
    "FRICTION_ITERATIONS",  # active-set solves of the last soft-string friction step
                            # (negative: gave up after that many, the last one kept)
], start=0)
N_STATE = len(S)


class Feedback(IntEnum):
    """``params[P.TD_FEEDBACK]``: the top drive's torque feedback filter."""

    NONE = 0
    HIGH_PASS = 1
    BAND_PASS = 2


class Status(IntEnum):
    """``state[S.STATUS]``: why a simulator stopped (0: running)."""

    OK = 0
    NONFINITE = 1        # a non-finite state
    RUNAWAY = 2          # bit speed or lateral displacement out of range
    SINGULAR = 3         # the lateral system matrix lost positive definiteness
    MESH_BUCKLING = 4    # a hook load compressed the string beyond what the mesh resolves


#: What each :class:`Status` tells a user (``Simulator.status_message``).
STATUS_MESSAGES = {
    Status.OK: "",
    Status.NONFINITE: "simulation diverged: non-finite state",
    Status.RUNAWAY: "simulation diverged: bit speed or lateral displacement out of range",
    Status.SINGULAR: "lateral stiffness not positive definite: string buckled beyond what "
                     "the time step can hold (reduce weight on bit)",
    Status.MESH_BUCKLING: "string buckled beyond the mesh resolution",
}


#: Record channels (columns of ``KernelArrays.record``), one row every ``record_every``
#: steps. Names are the public channel names (``RECORD_CHANNELS``).
R = IntEnum("R", [
    "TIME", "BIT_SPEED", "SURFACE_SPEED", "TORQUE_ON_BIT", "SURFACE_TORQUE",
    "WEIGHT_ON_BIT", "BIT_X", "BIT_Y", "WHIRL_SPEED", "DEPTH", "ROP", "MOTOR_TORQUE",
    "BIT_FORCE_X", "BIT_FORCE_Y", "MAX_WALL_FORCE", "STUCK",
], start=0)
N_RECORD = len(R)
RECORD_CHANNELS: tuple[str, ...] = tuple(m.name.lower() for m in R)

#: Readings after a kernel call (:mod:`drill_env.physics.readings`); the share of each
#: rock of the formation follows them.
READ = IntEnum("READ", [
    "TIME", "DEPTH", "BIT_SPEED", "SURFACE_SPEED", "TORQUE_ON_BIT", "SURFACE_TORQUE",
    "WEIGHT_ON_BIT", "HOOK_LOAD", "ROP", "BIT_X", "BIT_Y", "BIT_VX", "BIT_VY", "WHIRL_SPEED",
    "BIT_FORCE_X", "BIT_FORCE_Y", "MAX_CONTACT_FORCE", "STATUS",
], start=0)
N_READINGS = len(READ)
READINGS: tuple[str, ...] = tuple(m.name.lower() for m in READ)

#: One wall contact's result (``Work.contact``): forces on the node and its torque.
CONTACT = IntEnum("CONTACT", ["FX", "FY", "MZ", "NORMAL"], start=0)


class LateralSystem(NamedTuple):
    """Banded matrices of ONE bending plane (both planes are equal), upper band layout.

    ``k_total``, ``work`` and ``factor`` are refreshed by :func:`~drill_env.physics.
    integrator.factor_lateral` whenever the WOB changes.
    """

    k: np.ndarray          # elastic stiffness K
    kg_weight: np.ndarray  # geometric stiffness of the string's own weight
    kg_unit: np.ndarray    # geometric stiffness per newton of WOB: K_g = K_g,w - WOB K_g,u
    mass: np.ndarray       # lumped mass (diagonal)
    k_damp: np.ndarray     # b K (stiffness-proportional damping)
    k_total: np.ndarray    # K + K_g(WOB)
    work: np.ndarray       # the system matrix A before factorisation
    factor: np.ndarray     # LDL^T factor of A (linalg.cholesky_to_ldl)


class TorsionSystem(NamedTuple):
    """The torsional system: tridiagonal band matrices, factorised once."""

    k: np.ndarray        # stiffness (band, bandwidth 1)
    c: np.ndarray        # mud drag per node (diagonal, N m s/rad)
    factor: np.ndarray   # twisted factor of A = J + gamma dt C + beta dt^2 K
                         # (linalg.twisted_tridiagonal)
    col_bit: np.ndarray  # A^-1 e_bit: the response of every node to a unit bit torque
    band: np.ndarray     # A itself (band layout), for the soft-string friction solve
    sweep: np.ndarray    # its Thomas cp and 1 / diag with no node held
                         # (string_friction.thomas_sweep)


class Nodes(NamedTuple):
    """Per node: wall-contact geometry and the friction cap's compliance."""

    clearance: np.ndarray   # hole radius minus node radius (m)
    radius: np.ndarray      # outer radius (stabilizer blades where present) (m)
    contact: np.ndarray     # 1.0 where the node may touch the wall
    compliance: np.ndarray  # tangential compliance of the contact point in one step
    static_load: np.ndarray  # (2, n_lat) curved hole: weight across it, tension turning
    soft_normal: np.ndarray  # (n,) r F_n of the soft-string nodes (N m), 0 elsewhere


class Motion(NamedTuple):
    """The dynamic state: lateral plane-major (2, n_lat), torsion (n,)."""

    ul: np.ndarray
    vl: np.ndarray
    al: np.ndarray
    ut: np.ndarray
    vt: np.ndarray
    at: np.ndarray
    stick: np.ndarray  # (n,) soft-string friction: slip direction +-1, or 0 while stuck


class Work(NamedTuple):
    """Scratch of one step (overwritten every step) and the per-node wall forces."""

    rl: np.ndarray          # lateral residual, then acceleration (2, n_lat)
    rt: np.ndarray          # torsional residual, then acceleration
    contact: np.ndarray     # one contact's result (:data:`CONTACT`)
    node_force: np.ndarray  # wall normal force of every node (N)
    soft: np.ndarray        # (6, n) scratch of the soft-string friction solve


#: One implicit contact term (``Implicit.terms`` row): the normal stiffness
#: ``kappa n n^T`` of one contact on one lateral node (docs/model.md section 5).
TERM = IntEnum("TERM", [
    "NODE",    # the string node; gauge pad i of the bit: -1 - i
    "DOF",     # its lateral displacement DOF
    "NX",      # unit normal of the contact, x
    "NY",      # and y
    "KAPPA",   # beta dt^2 k + gamma dt c: acceleration-to-force factor (N s^2/m)
    "FORCE",   # normal force it applies at the predictors (N); at the end of the
               # step it is FORCE + y, y in Implicit.gram[t, count]
], start=0)


class Implicit(NamedTuple):
    """Implicit contacts: the rank-one terms of a step and the columns of A^-1 they use
    (:mod:`drill_env.physics.implicit_contact`)."""

    columns: np.ndarray   # (n_lat_nodes, n_lat) A^-1 e_j of each lateral node's w DOF
    ready: np.ndarray     # (n_lat_nodes,) 1.0 where that column is current
    terms: np.ndarray     # (n_lat_nodes + n_blades, TERM) this step's terms
    gram: np.ndarray      # (terms, terms + 1) the small system and its right-hand side
    scratch: np.ndarray   # (2, n_lat) a right-hand side of the band solve
    uncoupled: np.ndarray  # (2, n_lat) the accelerations before the terms
    member: np.ndarray    # (n_lat_nodes,) 1 + the term of each node this step, 0: none


class BitArrays(NamedTuple):
    """The bit's blades, the formation it cuts, the piece scratch and its loads."""

    blades: np.ndarray           # (n_blades, bit.Blade) geometry
    formation: FormationArrays   # interfaces and rock parameters
    pieces: BitScratch           # blade pieces of the last split
    out: np.ndarray              # loads (bit.BitOut), then the rock shares


class KernelArrays(NamedTuple):
    """Everything the compiled step of one simulator reads and writes."""

    params: np.ndarray       # (N_PARAMS,) :data:`P`
    state: np.ndarray        # (N_STATE,) :data:`S`
    lateral: LateralSystem
    torsion: TorsionSystem
    nodes: Nodes
    motion: Motion
    work: Work
    bit: BitArrays
    record: np.ndarray       # (capacity, N_RECORD) :data:`R`
    implicit: Implicit
