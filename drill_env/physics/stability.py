"""Linear torsional stability of steady drilling (independent of the time integrator).

Around steady rotation at speed Omega the bit torque ``a mu(w) WOB`` acts on small speed
perturbations like a damper of coefficient ``c_bit = a WOB mu'(Omega)``; a falling curve
(mu' < 0) gives negative damping. The PI top drive adds ``kp`` to the damping and ``ki``
to the stiffness of the top node. Steady rotation is linearly stable when every
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
    eig = scipy.linalg.eigvals(a)
    return float(np.max(eig.real))


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
