"""Reference solutions that do not come from the project's code (closed forms, exact
continuous models), shared by several test files (pytest puts tests/ on the path)."""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import brentq


def torsional_impedance(outer_diameter: float, inner_diameter: float,
                        shear_modulus: float = 7.95e10, density: float = 7850.0) -> float:
    """Z = J sqrt(G rho) of a tube, J = pi (D^4 - d^4) / 32 (N m s/rad)."""
    polar = math.pi * (outer_diameter ** 4 - inner_diameter ** 4) / 32.0
    return polar * math.sqrt(shear_modulus * density)


def transfer_matrix_frequency(sections_top_down, bit_inertia: float, f_max: float) -> float:
    """First natural frequency (Hz) of a fixed-top string of uniform shafts with a bit
    inertia at the free bottom (:func:`transfer_matrix_frequencies`)."""
    return transfer_matrix_frequencies(sections_top_down, bit_inertia, f_max)[0]


def transfer_matrix_frequencies(sections_top_down, bit_inertia: float, f_max: float,
                                top_inertia: float | None = None, f_min: float = 1e-3
                                ) -> list[float]:
    """Natural frequencies (Hz) in (f_min, f_max) of a string of uniform shafts with a bit
    inertia at the free bottom: distributed (exact) torsion, no FE.

    Each shaft carries (twist, torque); across a length L at circular frequency w,
    k = w sqrt(rho / G) and the state moves by [[cos kL, sin kL / (GJ k)],
    [-GJ k sin kL, cos kL]]. The top is fixed (theta = 0), or with ``top_inertia`` a free
    rotor (T = -J_top w^2 theta); the bottom condition is T = J_bit w^2 theta.
    """
    def residual(f: float) -> float:
        w = 2 * math.pi * f
        if top_inertia is None:
            theta, torque = 0.0, 1.0  # fixed top, unit torque
        else:
            theta, torque = 1.0, -top_inertia * w * w  # free rotor, unit twist
        for s in sections_top_down:
            k = w * math.sqrt(s.density / s.shear_modulus)
            gjk = s.shear_modulus * s.polar_moment * k
            c, sn = math.cos(k * s.length), math.sin(k * s.length)
            theta, torque = theta * c + torque * sn / gjk, -theta * gjk * sn + torque * c
        return torque - bit_inertia * w * w * theta

    grid = np.linspace(f_min, f_max, 2000)
    values = [residual(f) for f in grid]
    roots = [brentq(residual, grid[k], grid[k + 1], xtol=1e-12)
             for k in range(len(values) - 1) if values[k] * values[k + 1] < 0]
    if not roots:
        raise AssertionError(f"no natural frequency below {f_max} Hz")
    return roots
