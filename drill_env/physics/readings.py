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

from drill_env.physics import integrator as ig
from drill_env.physics.bit import mesoscopic_bit_loads

#: The readings, in the order of the array :func:`readout` fills; the share of each rock
#: of the formation (``Simulator.rock_share``) follows them.
READINGS = (
    "time", "depth", "bit_speed", "surface_speed", "torque_on_bit", "surface_torque",
    "weight_on_bit", "hook_load", "rop", "bit_x", "bit_y", "bit_vx", "bit_vy", "whirl_speed",
    "bit_force_x", "bit_force_y", "max_contact_force", "status",
)
N_READINGS = len(READINGS)
R = {name: k for k, name in enumerate(READINGS)}

#: Radius^2 (m^2) below which the bit counts as centred and its whirl speed is 0.
WHIRL_MIN_RADIUS_SQ = 1e-12
#: Floors of the bit speed (rad/s) and WOB (N) at which the rock share is evaluated:
#: the share is geometric, but the bit model needs a turning, loaded bit.
SHARE_MIN_SPEED = 1e-9
SHARE_MIN_WOB = 1.0


@njit(cache=True, nogil=True)
def whirl_speed(x, y, vx, vy):
    """Angular speed of the bit centre about the hole axis, (x vy - vx y) / r^2 (rad/s)."""
    r2 = x * x + y * y
    return (x * vy - vx * y) / r2 if r2 > WHIRL_MIN_RADIUS_SQ else 0.0


@njit(cache=True, nogil=True)
def readout(p, state, ul, vl, ut, vt, node_force, blades, normals, offsets, layer_rock,
            rock_params, piece_blade, piece_segment, piece_rock, piece_length, piece_lever,
            bit_out, out):
    """Write the :data:`READINGS` and the rock shares of one simulator into ``out``.

    ``ul``, ``vl``: the plane-major lateral displacement and velocity ``(2, n_lat)``; the
    bit's lateral DOFs are column ``n_lat - 2``. The rock share runs the bit model once
    more (its scratch arrays and ``bit_out`` are overwritten; the integrator writes them
    before reading them every step). A stopped simulator gets NaN rock shares.
    """
    n_lat = ul.shape[1]
    x = ul[0, n_lat - 2]
    y = ul[1, n_lat - 2]
    vx = vl[0, n_lat - 2]
    vy = vl[1, n_lat - 2]
    omega = vt[vt.shape[0] - 1]
    wob = state[ig.S_WOB]
    status = state[ig.S_STATUS]
    out[0] = state[ig.S_TIME]
    out[1] = state[ig.S_DEPTH]
    out[2] = omega
    out[3] = vt[0]
    out[4] = state[ig.S_TOB]
    out[5] = state[ig.S_SURFACE_TORQUE]
    out[6] = wob
    out[7] = state[ig.S_HOOK_LOAD]
    out[8] = state[ig.S_ROP]
    out[9] = x
    out[10] = y
    out[11] = vx
    out[12] = vy
    out[13] = whirl_speed(x, y, vx, vy)
    out[14] = state[ig.S_BIT_FX]
    out[15] = state[ig.S_BIT_FY]
    # Largest wall force; the mesoscopic bit node shows its gauge force (contact_forces).
    n = node_force.shape[0]
    peak = state[ig.S_GAUGE_FORCE] if p[ig.P_MACRO_BIT] == 0.0 else node_force[n - 1]
    for k in range(n - 1):  # np.max: NaN wins
        if node_force[k] > peak or node_force[k] != node_force[k]:
            peak = node_force[k]
            if peak != peak:
                break
    out[16] = peak
    out[17] = status
    n_rocks = out.shape[0] - N_READINGS
    if status != 0.0:
        for k in range(n_rocks):
            out[N_READINGS + k] = math.nan
        return
    mesoscopic_bit_loads(blades, normals, offsets, layer_rock, rock_params, x, y, 0.0, 0.0,
                         state[ig.S_DEPTH], ut[ut.shape[0] - 1],
                         max(abs(omega), SHARE_MIN_SPEED), max(wob, SHARE_MIN_WOB),
                         p[ig.P_HOLE_RADIUS], 0.0, p[ig.P_V_REG], piece_blade, piece_segment,
                         piece_rock, piece_length, piece_lever, bit_out)
    for k in range(n_rocks):
        out[N_READINGS + k] = bit_out[10 + k]


@njit(cache=True, nogil=True)
def advance_and_read(n_steps, record_every, p, state,
                     lat_k, lat_kg_weight, lat_kg_unit, lat_m, lat_factor, lat_work_band,
                     lat_k_total, lat_k_damp, tor_k, tor_c, tor_factor, col_bit,
                     node_clearance, node_radius, node_contact, compliance,
                     ul, vl, al, ut, vt, at, rl, rt, contact_out, node_force,
                     blades, normals, offsets, layer_rock, rock_params,
                     piece_blade, piece_segment, piece_rock, piece_length, piece_lever,
                     bit_out, record, readings):
    """:func:`~drill_env.physics.integrator.advance`, then :func:`readout` into
    ``readings``; returns the number of records."""
    n_rec = ig.advance(n_steps, record_every, p, state, lat_k, lat_kg_weight, lat_kg_unit,
                       lat_m, lat_factor, lat_work_band, lat_k_total, lat_k_damp, tor_k,
                       tor_c, tor_factor, col_bit, node_clearance, node_radius, node_contact,
                       compliance, ul, vl, al, ut, vt, at, rl, rt, contact_out, node_force,
                       blades, normals, offsets, layer_rock, rock_params, piece_blade,
                       piece_segment, piece_rock, piece_length, piece_lever, bit_out, record)
    readout(p, state, ul, vl, ut, vt, node_force, blades, normals, offsets, layer_rock,
            rock_params, piece_blade, piece_segment, piece_rock, piece_length, piece_lever,
            bit_out, readings)
    return n_rec
