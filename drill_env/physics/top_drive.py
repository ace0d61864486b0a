"""The top drive's speed controller: the gain rules the simulator's PI loop uses.

The PI speed loop runs inside the compiled step (:func:`drill_env.physics.integrator.
advance`); the controllers of :mod:`agents` choose its gains. The stiff rule below is
the simulator's default when ``TopDriveConfig`` gives no gains.
"""

from __future__ import annotations

#: Stiff PI (the usual factory tuning, Kyllingstad & Nessjoen 2009): P = 50 Z, I = 5 J_td.
STIFF_IMPEDANCE_FACTOR = 50.0
STIFF_INTEGRAL_FACTOR = 5.0  # 1/s^2


def stiff_pi_gains(impedance: float, top_drive_inertia: float) -> tuple[float, float]:
    """(P, I) of a stiff speed loop: ``P = 50 Z`` (N m s/rad) and ``I = 5 J_td`` (N m/rad).

    ``impedance`` is the drill pipe's torsional impedance Z = J sqrt(G rho); with P >> Z
    the top reflects almost every torsional wave (reflection coefficient ~0.96), so the
    top drive behaves like a fixed end and stick-slip can develop.
    """
    return STIFF_IMPEDANCE_FACTOR * impedance, STIFF_INTEGRAL_FACTOR * top_drive_inertia
