"""Drilling-performance metrics: the ONE source of truth (SPEC section 5).

The env's reward and ``info``, the benchmark tables and the rerun plots all call these
functions. They are pure NumPy, take signals in SI units (rad/s, N, N m, m, m/s) sampled
on a uniform grid, and return plain floats.

=========================  ============================================================
metric                     definition
=========================  ============================================================
stick-slip severity (SSI)  (max - min) / (2 |mean|) of the bit speed over a window
stuck fraction             share of samples with |bit speed| < 1 rpm
whirl ratio                mean whirl speed / mean bit speed: > 0 forward, < 0 backward
radial ratio               bit lateral displacement over the gauge clearance
lateral force              magnitude of the bit's lateral force (N)
ROP                        mean rate of penetration (m/s)
MSE                        mechanical specific energy, Teale (1965), in Pa (J/m^3)
top-drive energy           work done by the top-drive motor, integral |T w| dt (J)
=========================  ============================================================
"""

from __future__ import annotations

import math

import numpy as np

RPM = 2.0 * math.pi / 60.0

#: The bit counts as stuck below this speed (rad/s): 1 rpm.
STUCK_SPEED = 1.0 * RPM
#: Floor of |mean bit speed| in the SSI denominator (rad/s): 1 rpm.
SSI_MIN_MEAN_SPEED = 1.0 * RPM
#: Below this radial ratio the bit counts as centred and whirl has no direction.
WHIRL_MIN_RADIAL_RATIO = 0.1


def _signal(values, name: str) -> np.ndarray:
    a = np.asarray(values, dtype=float)
    if a.size == 0:
        raise ValueError(f"{name}: empty signal")
    return a


def stick_slip_severity(bit_speed, min_mean_speed: float = SSI_MIN_MEAN_SPEED) -> float:
    """Stick-slip severity SSI = (max - min) / (2 |mean|) of the bit speed over a window.

    0 for steady rotation; a sinusoid ``m + a sin(t)`` over whole periods gives ``a / m``;
    full stick-slip (bit stops, peaks at 2x mean) gives ~1. The mean is floored at
    ``min_mean_speed`` (1 rpm) so a stalled bit gives a large but finite value.
    """
    w = _signal(bit_speed, "bit_speed")
    mean = max(abs(float(np.mean(w))), min_mean_speed)
    return float(np.max(w) - np.min(w)) / (2.0 * mean)


def stuck_fraction(bit_speed, threshold: float = STUCK_SPEED) -> float:
    """Fraction of the window the bit is stuck: |bit speed| < ``threshold`` (1 rpm)."""
    w = _signal(bit_speed, "bit_speed")
    return float(np.mean(np.abs(w) < threshold))


def radial_ratio(bit_x, bit_y, clearance: float) -> np.ndarray:
    """Bit lateral displacement over the radial clearance (1 = gauge touching the wall)."""
    if not clearance > 0:
        raise ValueError(f"clearance: must be > 0, got {clearance!r}")
    return np.hypot(np.asarray(bit_x, dtype=float), np.asarray(bit_y, dtype=float)) / clearance


def whirl_ratio(whirl_speed, bit_speed, min_mean_speed: float = SSI_MIN_MEAN_SPEED) -> float:
    """Mean whirl speed over mean bit speed: > 0 forward whirl, < 0 backward whirl.

    Whirl speed is the angular speed of the bit centre about the hole axis (rad/s,
    ``(x vy - y vx) / r^2``). Forward synchronous whirl gives ~1; backward whirl, the
    bit rolling on the wall without slip, gives about -(bit radius / clearance), ~ -20
    for an 8 3/4 in bit with 5 mm clearance.
    """
    ws = _signal(whirl_speed, "whirl_speed")
    w = _signal(bit_speed, "bit_speed")
    mean = float(np.mean(w))
    denom = math.copysign(max(abs(mean), min_mean_speed), mean if mean != 0 else 1.0)
    return float(np.mean(ws)) / denom


def whirl_direction(whirl_speed, bit_speed, radial, min_radial: float = WHIRL_MIN_RADIAL_RATIO
                    ) -> str:
    """"forward", "backward" or "none" (bit centred: mean radial ratio < ``min_radial``).

    The sign of the mean whirl speed relative to the mean rotation decides the direction.
    """
    if float(np.mean(_signal(radial, "radial"))) < min_radial:
        return "none"
    r = whirl_ratio(whirl_speed, bit_speed)
    if r > 0:
        return "forward"
    if r < 0:
        return "backward"
    return "none"


def lateral_force(force_x, force_y) -> np.ndarray:
    """Magnitude of the bit's lateral force (N)."""
    return np.hypot(np.asarray(force_x, dtype=float), np.asarray(force_y, dtype=float))


def mean_rop(rop) -> float:
    """Mean rate of penetration over the window (m/s)."""
    return float(np.mean(_signal(rop, "rop")))


def bit_area(bit_diameter: float) -> float:
    """Hole cross-section drilled by the bit, pi d^2 / 4 (m^2)."""
    if not bit_diameter > 0:
        raise ValueError(f"bit_diameter: must be > 0, got {bit_diameter!r}")
    return math.pi * bit_diameter**2 / 4.0


def mechanical_specific_energy(weight_on_bit, torque_on_bit, bit_speed, rop,
                               bit_diameter: float, min_rop: float = 1e-9) -> float:
    """Mechanical specific energy (Teale 1965) over a window, in Pa (= J/m^3).

    ``MSE = WOB / A + 2 pi N T / (A ROP)`` with N in rev/s, i.e. ``omega T / (A ROP)``
    with omega in rad/s; over a window the powers are averaged:
    ``mean(WOB) / A + mean(omega T) / (A mean(ROP))``. ``A = pi d^2 / 4``. When the
    mean ROP is below ``min_rop`` (not drilling) the rotary term is undefined: the
    result is ``inf`` if rotary power is spent, else just ``mean(WOB) / A``.
    """
    area = bit_area(bit_diameter)
    wob = float(np.mean(_signal(weight_on_bit, "weight_on_bit")))
    power = float(np.mean(_signal(torque_on_bit, "torque_on_bit")
                          * _signal(bit_speed, "bit_speed")))
    r = mean_rop(rop)
    if r < min_rop:
        return math.inf if power > 0 else wob / area
    return wob / area + power / (area * r)


def top_drive_energy(motor_torque, surface_speed, dt: float) -> float:
    """Work done by the top-drive motor, sum |T omega| dt (J), samples ``dt`` apart.

    Braking counts as spent energy too (no regeneration assumed), as in the simulator.
    """
    t = _signal(motor_torque, "motor_torque")
    w = _signal(surface_speed, "surface_speed")
    return float(np.sum(np.abs(t * w)) * dt)


def window_metrics(records: np.ndarray, channels, dt: float, clearance: float,
                   bit_diameter: float) -> dict[str, float]:
    """All metrics of a simulator record window (rows: samples ``dt`` apart).

    ``channels`` names the record columns (the simulator's ``RECORD_CHANNELS``). Returns
    ``ssi, stuck_fraction, whirl_ratio, radial_ratio (mean), radial_ratio_max,
    lateral_force (mean), lateral_force_max, rop, mse, top_drive_energy``.
    """
    col = {name: k for k, name in enumerate(channels)}
    rec = np.asarray(records, dtype=float)
    if rec.ndim != 2 or rec.shape[0] == 0:
        raise ValueError("records: need a non-empty (n_samples, n_channels) array")

    def c(name: str) -> np.ndarray:
        return rec[:, col[name]]

    radial = radial_ratio(c("bit_x"), c("bit_y"), clearance)
    force = lateral_force(c("bit_force_x"), c("bit_force_y"))
    return {
        "ssi": stick_slip_severity(c("bit_speed")),
        "stuck_fraction": stuck_fraction(c("bit_speed")),
        "whirl_ratio": whirl_ratio(c("whirl_speed"), c("bit_speed")),
        "radial_ratio": float(np.mean(radial)),
        "radial_ratio_max": float(np.max(radial)),
        "lateral_force": float(np.mean(force)),
        "lateral_force_max": float(np.max(force)),
        "rop": mean_rop(c("rop")),
        "mse": mechanical_specific_energy(c("weight_on_bit"), c("torque_on_bit"),
                                          c("bit_speed"), c("rop"), bit_diameter),
        "top_drive_energy": top_drive_energy(c("motor_torque"), c("surface_speed"), dt),
    }
