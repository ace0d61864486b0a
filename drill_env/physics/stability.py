"""Linear torsional stability of steady drilling (independent of the time integrator).

Around steady rotation at speed Omega the bit torque ``a mu(w) WOB`` acts on small speed
perturbations like a damper of coefficient ``c_bit = a WOB mu'(Omega)``; a falling curve
(mu' < 0) gives negative damping. The PI top drive adds ``kp`` to the damping and ``ki``
to the stiffness of the top node; a torque feedback (SoftTorque, ZTorque) adds its
filter's states. Steady rotation is linearly stable when every
eigenvalue of the first-order system has a negative real part. The rotary speed where
the largest real part crosses zero is the stick-slip threshold (Kyllingstad & Halsey
1988; Brett 1992): below it, stick-slip grows out of steady rotation.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg
from scipy.optimize import brentq

from drill_env.physics.fem import from_band
from drill_env.physics.formation import Rock


def resistance_slope(omega: float, mu_min: float, mu_max: float, st1: float,
                     st2: float) -> float:
    """d mu / d omega of eq. (39) for omega > 0."""
    return -(mu_max - mu_min) / st1 * np.exp(-abs(omega) / st1) + st2


def torsional_growth_rate(sim, omega: float, weight_on_bit: float,
                          rock: int = 0, bit_damping: float | None = None) -> float:
    """Largest real part (1/s) of the linearised torsional dynamics at steady ``omega``.

    ``sim`` is a :class:`~drill_env.physics.simulator.Simulator` (its assembled
    matrices are used, not its integrator). The bit's damping is the slope of the
    macroscopic curve of ``rock`` unless ``bit_damping`` (N m s/rad) is given.
    """
    k = from_band(sim.tor_k)
    b = sim.config.damping.stiffness_proportional
    c = b * k + np.diag(sim.tor_c)
    kp, ki = sim.top_drive_gains
    # the string torque at the top, as the drive measures it: T_s = k_e ((th0 - th1)
    # + b (w0 - w1)) (integrator: S.SURFACE_TORQUE), a row over (th, w)
    torque_row = -k[0, 1] * np.concatenate([[1.0, -1.0], np.zeros(k.shape[0] - 2)])
    k = k.copy()
    c[0, 0] += kp
    k[0, 0] += ki
    if bit_damping is None:
        rp = sim.rock_params[rock]
        bit_damping = sim.lever_arm * weight_on_bit * resistance_slope(
            omega, rp[Rock.MU_MIN], rp[Rock.MU_MAX], rp[Rock.ST1], rp[Rock.ST2])
    c[-1, -1] += bit_damping
    m_inv = 1.0 / sim.tor_m
    n = k.shape[0]
    a = np.zeros((2 * n, 2 * n))
    a[:n, n:] = np.eye(n)
    a[n:, :n] = -m_inv[:, None] * k
    a[n:, n:] = -m_inv[:, None] * c
    a = _with_torque_feedback(a, getattr(sim, "top_drive_law", None), kp, ki, m_inv[0],
                              np.concatenate([torque_row, b * torque_row]))
    eig = scipy.linalg.eigvals(a)
    if a.shape[0] > 2 * n:  # the feedback's integral q and the angles share one motion:
        # the string turned by c and q by -c / g leave every force as it was, a zero
        # eigenvalue of the model, not of the drive (its speed loop holds th0 + g q)
        eig = np.delete(eig, np.argmin(np.abs(eig)))
    return float(np.max(eig.real))


def _with_torque_feedback(a: np.ndarray, law, kp: float, ki: float, m0_inv: float,
                          torque: np.ndarray) -> np.ndarray:
    """The first-order system ``a`` over (th, w) of the string, with the top drive's
    torque feedback (SoftTorque, ZTorque; ``law`` a ``TopDriveLaw``) as extra states: the
    speed command drops by ``g y``, ``y = H(T_s)`` (``torque``: the row giving T_s), so
    the PI adds ``-kp g y - ki g q`` to the top node, ``q' = y``. High-pass
    ``H = s / (s + w_c)``: ``x' = w_c (T_s - x)``, ``y = T_s - x``; band-pass
    ``x1' = x2``, ``x2' = T_s - w0^2 x1 - 2 z w0 x2``, ``y = 2 z w0 x2`` (the kernel's
    filters, integrator._torque_feedback, in continuous time)."""
    if law is None or law.torque_feedback == "none":  # (None: a stand-in without one)
        return a
    size, w, g = a.shape[0], 2.0 * np.pi * law.filter_frequency, law.feedback_gain
    top = size // 2  # the row of the top node's acceleration
    band = law.torque_feedback == "band_pass"
    extra = 3 if band else 2  # (x1, x2, q) or (x, q)
    out = np.zeros((size + extra, size + extra))
    out[:size, :size] = a
    q = size + extra - 1
    y = np.zeros(size + extra)  # y as a row over the augmented state
    if band:
        two_zw = 2.0 * law.filter_damping * w
        x1, x2 = size, size + 1
        out[x1, x2] = 1.0
        out[x2, :size] = torque
        out[x2, x1], out[x2, x2] = -w * w, -two_zw
        y[x2] = two_zw
    else:
        x = size
        out[x, :size] = w * torque
        out[x, x] = -w
        y[:size], y[x] = torque, -1.0
    out[q] = y
    out[top] -= m0_inv * g * (kp * y)
    out[top, q] -= m0_inv * g * ki
    return out


def stick_slip_threshold(sim, weight_on_bit: float, rock: int = 0,
                         omega_range: tuple[float, float] = (0.05, 60.0)) -> float:
    """Rotary speed (rad/s) below which steady rotation is linearly unstable.

    Returns ``omega_range[0]`` if stable everywhere in the range, ``omega_range[1]`` if
    unstable everywhere.
    """
    lo, hi = omega_range

    def growth(w: float) -> float:
        return torsional_growth_rate(sim, w, weight_on_bit, rock)

    g_lo, g_hi = growth(lo), growth(hi)
    if g_lo <= 0.0:
        return lo
    if g_hi > 0.0:
        return hi
    return float(brentq(growth, lo, hi, xtol=1e-4))
