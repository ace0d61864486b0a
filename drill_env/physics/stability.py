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

from collections.abc import Callable

import numpy as np
import scipy.linalg
from scipy.optimize import brentq

from drill_env.physics.fem import from_band
from drill_env.physics.formation import Rock
from drill_env.physics.linalg import one_blas_thread


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
    return _largest_real(_first_order(sim, omega, weight_on_bit, rock, bit_damping),
                         sim.tor_m.shape[0])


def _first_order(sim, omega: float, weight_on_bit: float, rock: int = 0,
                 bit_damping: float | None = None) -> np.ndarray:
    """The first-order system over (th, w) of the string and the feedback's states."""
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
    c[-1, -1] += _bit_damping(sim, omega, weight_on_bit, rock) if bit_damping is None \
        else bit_damping
    m_inv = 1.0 / sim.tor_m
    n = k.shape[0]
    a = np.zeros((2 * n, 2 * n))
    a[:n, n:] = np.eye(n)
    a[n:, :n] = -m_inv[:, None] * k
    a[n:, n:] = -m_inv[:, None] * c
    return _with_torque_feedback(a, getattr(sim, "top_drive_law", None), kp, ki, m_inv[0],
                                 np.concatenate([torque_row, b * torque_row]))


def _bit_damping(sim, omega: float, weight_on_bit: float, rock: int) -> float:
    """``c_bit = a WOB mu'(omega)`` (N m s/rad) of ``rock``'s macroscopic curve."""
    rp = sim.rock_params[rock]
    return sim.lever_arm * weight_on_bit * resistance_slope(
        omega, rp[Rock.MU_MIN], rp[Rock.MU_MAX], rp[Rock.ST1], rp[Rock.ST2])


def _largest_real(a: np.ndarray, n: int) -> float:
    """The largest real part of the eigenvalues of ``a``, the system over the ``n``
    angles, ``n`` speeds and the feedback's states."""
    with one_blas_thread():
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


def string_modes(sim, n_modes: int) -> np.ndarray:
    """(n, m) the string's ``m = min(n_modes, n)`` lowest undamped torsional modes with its
    top free (``K phi = w^2 J phi``, ``J``-orthonormal; the first is the rigid turn), a
    basis in which the low motions of the drilling string are few coordinates."""
    band = np.asarray(sim.tor_k, dtype=float)
    scale = 1.0 / np.sqrt(sim.tor_m)
    n = band.shape[1]
    scaled = np.zeros_like(band)
    for d in range(band.shape[0]):  # J^-1/2 K J^-1/2, still banded (lower: [d, i] = K[i+d, i])
        scaled[d, : n - d] = band[d, : n - d] * scale[: n - d] * scale[d:]
    m = min(n_modes, n)
    with one_blas_thread():
        _, vectors = scipy.linalg.eig_banded(scaled, lower=True, select="i",
                                             select_range=(0, m - 1))
    return scale[:, None] * vectors


def _projected(sim, weight_on_bit: float, rock: int, basis: np.ndarray
               ) -> Callable[[float], float]:
    """:func:`torsional_growth_rate` of the system projected on ``basis`` (Galerkin, the
    feedback's states kept), as a function of the speed: close to the full one near the
    threshold, but with the bit's negative damping no bound on it (a projected system
    can turn unstable where the full one is not), so :func:`stick_slip_threshold` only
    searches with it. The speed moves one entry of the full system, the bit's damping:
    a rank-one term of the projected one."""
    a = _first_order(sim, 0.0, weight_on_bit, rock, bit_damping=0.0)
    n, m = basis.shape
    extra = a.shape[0] - 2 * n
    right = np.zeros((a.shape[0], 2 * m + extra))
    right[:n, :m] = right[n:2 * n, m:2 * m] = basis
    right[2 * n:, 2 * m:] = np.eye(extra)
    left = right.T.copy()  # J-orthonormal: (phi' J) phi = I, so phi' J is its left inverse
    left[:m, :n] *= sim.tor_m
    left[m:2 * m, n:2 * n] *= sim.tor_m
    fixed = left @ a @ right
    bit = np.outer(left[:, 2 * n - 1], right[2 * n - 1]) / -sim.tor_m[-1]  # per unit c_bit

    def growth(omega: float) -> float:
        return _largest_real(fixed + _bit_damping(sim, omega, weight_on_bit, rock) * bit, m)
    return growth


#: Modes of the projected system :func:`stick_slip_threshold` searches on.
SEARCH_MODES = 80
#: Strings of at most this many nodes are searched on the full system alone (an outside
#: check measured the projection no faster there).
FULL_SEARCH_NODES = 200
#: Relative half-width of the bracket in which the full system confirms a root, and how
#: many times the root is shifted again before the full system is searched instead: the
#: search's root shifted by the full system's growth rate lands within 1e-5 of the full
#: system's under the stiff PI and SoftSpeed, 1e-4 under SoftTorque and up to 7.5e-4
#: under ZTorque on 2,000-5,000 m strings; shifted again at the bracket, within 2e-4.
CONFIRM_WIDTH = 2e-4
CORRECTIONS = 3


def stick_slip_threshold(sim, weight_on_bit: float, rock: int = 0,
                         omega_range: tuple[float, float] = (0.05, 60.0),
                         search_modes: int = SEARCH_MODES) -> float:
    """Rotary speed (rad/s) below which steady rotation is linearly unstable.

    Returns ``omega_range[0]`` if stable everywhere in the range, ``omega_range[1]`` if
    unstable everywhere; between them, where the growth rate turns negative (one
    crossing assumed, as a search on the full system assumes). On a string of more than
    :data:`FULL_SEARCH_NODES` nodes the root is searched on its ``search_modes`` lowest
    modes (:func:`string_modes`, :func:`_projected`), that search shifted by the full
    system's growth rate at the root found, and the root confirmed by the full system:
    its growth rate changes sign within :data:`CONFIRM_WIDTH` of it (the root then
    interpolated between the two), or the shift is taken there again, up to
    :data:`CORRECTIONS` times, before the full system is searched instead, between the
    speeds it was already found unstable and stable at. A long string costs three
    solves of the full eigenproblem (2n and the feedback's states), not the ~14 of a
    search on it (timings: docs/controllers.md).
    """
    if search_modes < 1:
        raise ValueError(f"search_modes: at least one mode, got {search_modes}")
    lo, hi = omega_range
    seen: dict[float, float] = {}  # the full system's growth rate at the speeds solved

    def full(w: float) -> float:
        if w not in seen:
            seen[w] = torsional_growth_rate(sim, w, weight_on_bit, rock)
        return seen[w]

    if sim.tor_m.shape[0] <= FULL_SEARCH_NODES:
        return _root(full, lo, hi)
    reduced = _projected(sim, weight_on_bit, rock, string_modes(sim, search_modes))
    fine = CONFIRM_WIDTH / 20.0  # the projected roots well inside the bracket
    guess = _root(reduced, lo, hi, rtol=fine)
    if guess in (lo, hi):  # (stable or unstable throughout: one or two full solves)
        return _root(full, lo, hi)
    shift = full(guess) - reduced(guess)
    for _ in range(CORRECTIONS):
        guess = _root(lambda w, shift=shift: reduced(w) + shift, lo, hi, rtol=fine)
        a, b = guess * (1.0 - CONFIRM_WIDTH), guess * (1.0 + CONFIRM_WIDTH)
        if not lo < a < b < hi:
            break
        g_a, g_b = full(a), full(b)
        if g_a > 0.0 >= g_b:
            # the secant's root: ~1e-8 relative where the growth rate is smooth in the
            # bracket (a kink, two modes' real parts crossing, leaves it within the bracket)
            return a + (b - a) * g_a / (g_a - g_b)
        near, g_near = (a, g_a) if g_a <= 0.0 else (b, g_b)  # the end nearer the root
        shift = g_near - reduced(near)
    return _root(full, lo, hi, seen=seen)


def _root(growth, lo: float, hi: float, rtol: float | None = None,
          seen: dict[float, float] | None = None) -> float:
    """Where ``growth`` turns from positive to negative in ``[lo, hi]``: ``lo`` if it is
    not positive there, ``hi`` if it is positive at ``hi``; to 1e-4 rad/s, or to ``rtol``
    of the root where given. ``seen``: its values already known at some speeds, which
    narrow the search (unless they show more than one crossing)."""
    if growth(lo) <= 0.0:
        return lo
    if growth(hi) > 0.0:
        return hi
    known = {w: g for w, g in (seen or {}).items() if lo < w < hi}
    a = max((w for w, g in known.items() if g > 0.0), default=lo)
    b = min((w for w, g in known.items() if g <= 0.0), default=hi)
    if a >= b:
        a, b = lo, hi
    if rtol is None:
        return float(brentq(growth, a, b, xtol=1e-4))
    return float(brentq(growth, a, b, xtol=1e-12, rtol=rtol))
