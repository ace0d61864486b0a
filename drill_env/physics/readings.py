"""The simulator's readings after a kernel call, gathered by one compiled function.

An environment step reads about twenty scalars from the simulator (bit speed, torques,
bit position, whirl speed, largest wall force, the share of each rock under the bit).
As Python properties they cost more than a third of the env's own Python per step;
:func:`readout` writes them into one float array instead, and :func:`advance_and_read`
runs it straight after the integrator in the same compiled call. The batched kernel
(:mod:`drill_env.physics.batch`) calls it inside its parallel loop, so the readings of
a batch cost no serial Python at all.

The values are exactly those of the :class:`~drill_env.physics.simulator.Simulator`
properties of the same names (``tests/physics/test_readings.py``).
"""

from __future__ import annotations

import math

from numba import njit

from drill_env.physics import integrator
from drill_env.physics.bit import SHARES, BitKinematics, GaugeContact, mesoscopic_bit_loads
from drill_env.physics.integrator import whirl_speed
from drill_env.physics.jit import TUPLE_KERNEL
from drill_env.physics.layout import N_READINGS, READ, READINGS, P, S

__all__ = ["N_READINGS", "READ", "READINGS", "advance_and_read", "readout", "whirl_speed"]

#: Floors of the bit speed (rad/s) and WOB (N) at which the rock share is evaluated:
#: the share is geometric, but the bit model needs a turning, loaded bit.
SHARE_MIN_SPEED = 1e-9
SHARE_MIN_WOB = 1.0


@njit(**TUPLE_KERNEL)
def readout(a, out):
    """Write the :data:`READINGS` and the rock shares of one simulator (its
    :class:`~drill_env.physics.layout.KernelArrays`) into ``out``.

    The bit's lateral DOFs are the next-to-last column of the plane-major ``motion.ul``.
    The rock share runs the bit model once more (its piece scratch and ``bit.out`` are
    overwritten; the integrator writes them before reading them every step). A stopped
    simulator gets NaN rock shares.
    """
    p = a.params
    state = a.state
    m = a.motion
    n_lat = m.ul.shape[1]
    x = m.ul[0, n_lat - 2]
    y = m.ul[1, n_lat - 2]
    vx = m.vl[0, n_lat - 2]
    vy = m.vl[1, n_lat - 2]
    omega = m.vt[m.vt.shape[0] - 1]
    wob = state[S.WOB]
    status = state[S.STATUS]
    out[READ.TIME] = state[S.TIME]
    out[READ.DEPTH] = state[S.DEPTH]
    out[READ.BIT_SPEED] = omega
    out[READ.SURFACE_SPEED] = m.vt[0]
    out[READ.TORQUE_ON_BIT] = state[S.TOB]
    out[READ.SURFACE_TORQUE] = state[S.SURFACE_TORQUE]
    out[READ.WEIGHT_ON_BIT] = wob
    out[READ.HOOK_LOAD] = state[S.HOOK_LOAD]
    out[READ.ROP] = state[S.ROP]
    out[READ.BIT_X] = x
    out[READ.BIT_Y] = y
    out[READ.BIT_VX] = vx
    out[READ.BIT_VY] = vy
    out[READ.WHIRL_SPEED] = whirl_speed(x, y, vx, vy)
    out[READ.BIT_FORCE_X] = state[S.BIT_FX]
    out[READ.BIT_FORCE_Y] = state[S.BIT_FY]
    # Largest wall force; the mesoscopic bit node shows its gauge force (contact_forces).
    node_force = a.work.node_force
    n = node_force.shape[0]
    peak = state[S.GAUGE_FORCE] if p[P.MACRO_BIT] == 0.0 else node_force[n - 1]
    for k in range(n - 1):  # np.max: NaN wins
        if node_force[k] > peak or node_force[k] != node_force[k]:
            peak = node_force[k]
            if peak != peak:
                break
    out[READ.MAX_CONTACT_FORCE] = peak
    out[READ.STATUS] = status
    n_rocks = out.shape[0] - N_READINGS
    if status != 0.0:
        for k in range(n_rocks):
            out[N_READINGS + k] = math.nan
        return
    bit = a.bit
    mesoscopic_bit_loads(bit.blades, bit.formation, bit.pieces,
                         BitKinematics(x, y, 0.0, 0.0, state[S.DEPTH], m.ut[m.ut.shape[0] - 1],
                                       max(abs(omega), SHARE_MIN_SPEED)),
                         max(wob, SHARE_MIN_WOB),
                         GaugeContact(p[P.HOLE_RADIUS], 0.0, p[P.V_REG], p[P.GAUGE_FRICTION],
                                      False),
                         bit.out)
    for k in range(n_rocks):
        out[N_READINGS + k] = bit.out[SHARES + k]


@njit(**TUPLE_KERNEL)
def advance_and_read(n_steps, record_every, a, readings):
    """:func:`~drill_env.physics.integrator.advance`, then :func:`readout` into
    ``readings``; returns the number of records."""
    n_rec = integrator.advance(n_steps, record_every, a)
    readout(a, readings)
    return n_rec
