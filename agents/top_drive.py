"""Classical top-drive speed-loop tunings, as physics overrides of the simulator's PI loop.

The top drive's PI speed loop runs inside the simulator at every time step; a classical
controller is a choice of its gains (a ``TopDriveConfig``), driven by a constant set
point. Formulas:

* stiff PI (the usual factory tuning): ``kp = 50 Z``, ``ki = 5 J_td`` (1/s^2), with
  ``Z = J sqrt(G rho)`` the drill pipe's torsional impedance: the top reflects almost all
  torsional waves, so stick-slip is free to develop.
* SoftSpeed / tuned PI (Kyllingstad & Nessjoen 2009, SPE-119660): ``kp = k Z`` with
  k ~ 1 so the top drive absorbs the waves arriving from below at the stick-slip
  frequency, and ``ki = w_s^2 J_td`` so the integral term cancels the top-drive
  inertia at that frequency (w_s = 2 pi f_s, f_s the first torsional frequency).
"""

from __future__ import annotations

import math

from drill_env.physics.config import SimulationConfig, TopDriveConfig, replace


def stiff_gains(config: SimulationConfig) -> TopDriveConfig:
    """Stiff PI: P = 50 Z, I = 5 J_td."""
    z = config.string.drill_pipe.torsional_impedance
    td = config.top_drive
    return replace(td, proportional_gain=50.0 * z, integral_gain=5.0 * td.inertia)


def soft_speed_gains(config: SimulationConfig, stick_slip_frequency: float,
                     impedance_factor: float = 1.0) -> TopDriveConfig:
    """SoftSpeed (Kyllingstad & Nessjoen 2009): P = k Z, I = (2 pi f_s)^2 J_td."""
    if not (stick_slip_frequency > 0 and math.isfinite(stick_slip_frequency)):
        raise ValueError(f"stick_slip_frequency: must be > 0, got {stick_slip_frequency!r}")
    z = config.string.drill_pipe.torsional_impedance
    td = config.top_drive
    w = 2.0 * math.pi * stick_slip_frequency
    return replace(td, proportional_gain=impedance_factor * z, integral_gain=w * w * td.inertia)
