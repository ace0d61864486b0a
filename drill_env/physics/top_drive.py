"""The top drive's drive-rate controllers: tuning rules, and the impedance they present.

The speed loop (and any torque feedback) runs inside the compiled step at every time
step (:func:`drill_env.physics.integrator.advance`); :func:`resolve` turns a
``TopDriveConfig`` and its string into gains and filters. Symbols: ``Z = J_p sqrt(G rho)``
the torsional (characteristic) impedance of the drill pipe at the top, ``J_td`` the
top-drive inertia, ``w_s = 2 pi f_s`` the stick-slip (tuning) frequency, ``T_s`` the
string torque at the top.

* **stiff** (the usual factory tuning; Kyllingstad & Nessjoen 2009, SPE-119660):
  ``P = 50 Z``, ``I = 5 J_td`` (1/s^2). P >> Z: the top reflects almost every torsional
  wave (reflection coefficient ~0.96), a fixed end for the string, so stick-slip grows.
* **soft_speed** (SoftSpeed / tuned PI; Kyllingstad & Nessjoen 2009): ``P = k Z`` with
  k ~ 1, so the top drive absorbs the waves arriving from below, and ``I = w_s^2 J_td``,
  so the integral term cancels the top-drive inertia at ``w_s``: the top's impedance is
  the real ``k Z`` there and its reflection coefficient ``(1 - k) / (1 + k)``, 0 at k = 1.
  We use k = 4 (``TopDriveConfig.impedance_factor``, measured choice: r = 0.6 at
  ``w_s``, but a band wide enough to hold the two modes the soft top splits the first
  one into; at k = 1-2.5, and at 3 under 150 kN, stick-slip grows back within 1-4
  minutes on the default string: docs/controllers.md).
* **soft_torque** (Shell's Soft Torque Rotary System as described by Dwars 2015,
  SPE/IADC-173037): the stiff PI speed loop, its command lowered by the string torque
  through a band-pass centred on ``w_s`` and the gain 1/Z:
  ``w_cmd = w_set - BP(T_s) / Z``, ``BP(s) = 2 z w_s s / (s^2 + 2 z w_s s + w_s^2)``,
  z = 0.5. At ``w_s`` the top behaves as a damper of impedance ~Z (absorbing); at DC and
  at high frequency it is the stiff loop.
* **z_torque** (ZTorque, Dwars 2015): the stiff PI speed loop with the string torque fed
  back through a first-order high-pass and 1/Z: ``w_cmd = w_set - HP(T_s) / Z``,
  ``HP(s) = s / (s + w_c)``, corner ``w_c = w_s / 4`` (below the first mode, so this and
  every higher mode see an absorbing top; the mean speed still follows the set point).

With the speed loop ``C(s) = P + I / s`` and torque feedback ``g H(s)`` the top presents
the impedance ``Z_td = (C + J_td s) / (1 + C g H)`` to the string (``T_s = -Z_td w`` for
small oscillations) and reflects speed waves with ``r = (Z - Z_td) / (Z + Z_td)``;
:func:`measured_reflection` checks this against a simulated pulse.
"""

from __future__ import annotations

import functools
import math
import warnings
from dataclasses import dataclass

import numpy as np

from drill_env.physics.config import ConfigError, SimulationConfig
from drill_env.physics.layout import Feedback, P

#: Stiff PI, the drive Kyllingstad & Nessjoen (2009) contrast SoftSpeed with: P = 50 Z,
#: I = 5 J_td, our numbers for a loop much stiffer than the pipe (P >> Z; it reflects at least
#: 49/51 of a torsional wave), not quoted from the paper.
STIFF_IMPEDANCE_FACTOR = 50.0
STIFF_INTEGRAL_FACTOR = 5.0  # 1/s^2
#: ZTorque's high-pass corner as a fraction of the stick-slip frequency.
Z_TORQUE_CORNER_RATIO = 0.25


def stiff_pi_gains(impedance: float, top_drive_inertia: float) -> tuple[float, float]:
    """(P, I) of a stiff speed loop: ``P = 50 Z`` (N m s/rad) and ``I = 5 J_td`` (N m/rad)."""
    return STIFF_IMPEDANCE_FACTOR * impedance, STIFF_INTEGRAL_FACTOR * top_drive_inertia


def soft_speed_gains(impedance: float, top_drive_inertia: float, frequency: float,
                     impedance_factor: float) -> tuple[float, float]:
    """(P, I) of SoftSpeed: ``P = k Z``, ``I = (2 pi f_s)^2 J_td``."""
    if not (frequency > 0.0 and math.isfinite(frequency)):
        raise ValueError(f"tuning_frequency: must be > 0 Hz, got {frequency!r}")
    w = 2.0 * math.pi * frequency
    return impedance_factor * impedance, w * w * top_drive_inertia


def speed_loop_critical_step(kp: float, ki: float, inertia: float) -> float:
    """The longest step (s) at which the PI loop alone keeps the top node's inertia
    stable (inf: no limit). The kernel's loop is explicit: its torque ``kp (w_set - v_p)
    + ki I`` takes the Newmark predictor speed v_p and the integral I of the step before,
    which it then advances by forward Euler. One rotor under it moves by
    ``m z^2 + (dt kp - 2 m) z + (m - dt kp + dt^2 ki)``, whose roots (Jury's test) lie in
    the unit circle for ``dt < kp / ki`` and, where ``kp^2 >= 4 ki m``, ``dt < 4 m / (kp +
    sqrt(kp^2 - 4 ki m))`` (``2 m / kp`` without an integral term). Without a
    proportional gain the isolated rotor has no stable step, but the string's damping
    holds it: no limit is set then."""
    if kp <= 0.0:
        return math.inf
    bound = kp / ki if ki > 0.0 else math.inf
    if kp * kp >= 4.0 * ki * inertia:
        bound = min(bound, 4.0 * inertia / (kp + math.sqrt(kp * kp - 4.0 * ki * inertia)))
    return bound


@functools.lru_cache(maxsize=64)
def stick_slip_frequency(config: SimulationConfig) -> float:
    """First torsional natural frequency (Hz) of the string with a fixed top and a free
    bit (undamped): the frequency stick-slip oscillates close to, and the soft
    controllers' tuning frequency."""
    import scipy.linalg

    from drill_env.physics.fem import assemble_torsion, build_mesh
    from drill_env.physics.linalg import one_blas_thread

    cfg = config.resolved()
    k, j = assemble_torsion(build_mesh(cfg))
    j[-1] += cfg.bit.inertia
    with one_blas_thread():  # (0.4 s on OpenBLAS's threads beside another job, not 0.02)
        lam = scipy.linalg.eigh(k[1:, 1:], np.diag(j[1:]), eigvals_only=True,
                                subset_by_index=[0, 0])
    return float(math.sqrt(lam[0]) / (2.0 * math.pi))


@dataclass(frozen=True)
class TopDriveLaw:
    """A top drive's resolved controller: what the compiled step runs."""

    controller: str
    proportional_gain: float  # N m s/rad
    integral_gain: float  # N m/rad
    torque_feedback: str  # "none", "high_pass", "band_pass"
    feedback_gain: float  # rad/s per N m
    filter_frequency: float  # Hz (0 without feedback)
    filter_damping: float
    #: Hz; None when the controller tunes to none (not NaN: from Python 3.13 a dataclass
    #: compares field by field, and two laws with a NaN here were unequal)
    tuning_frequency: float | None
    impedance: float  # drill pipe Z (N m s/rad)
    inertia: float  # J_td (kg m^2)

    def filter_response(self, frequency: float) -> complex:
        """H(j w) of the torque filter."""
        if self.torque_feedback == "none":
            return 0j
        s = 2j * math.pi * frequency
        w = 2.0 * math.pi * self.filter_frequency
        if self.torque_feedback == "high_pass":
            return s / (s + w)
        two_zw = 2.0 * self.filter_damping * w
        return two_zw * s / (s * s + two_zw * s + w * w)

    def impedance_at(self, frequency: float) -> complex:
        """``Z_td(j w) = (C + J_td s) / (1 + C g H)``: the torque the top drive takes per
        unit speed of the string's top (module docstring)."""
        s = 2j * math.pi * frequency
        c = self.proportional_gain + self.integral_gain / s
        return (c + self.inertia * s) / (1.0 + c * self.feedback_gain
                                         * self.filter_response(frequency))

    def reflection_coefficient(self, frequency: float) -> complex:
        """``(Z - Z_td) / (Z + Z_td)`` for speed waves arriving from below."""
        z_td = self.impedance_at(frequency)
        return (self.impedance - z_td) / (self.impedance + z_td)


def resolve(config: SimulationConfig) -> TopDriveLaw:
    """The controller of ``config.top_drive`` with its gains and filters from its rule
    (module docstring); explicitly configured values win."""
    td = config.top_drive
    z = config.string.drill_pipe.torsional_impedance
    name = td.controller
    needs_frequency = name != "stiff" or (td.torque_feedback not in (None, "none")
                                          and td.filter_frequency is None)
    f_s = math.nan
    if needs_frequency:
        f_s = td.tuning_frequency if td.tuning_frequency is not None \
            else stick_slip_frequency(config)
    if name == "soft_speed":
        kp, ki = soft_speed_gains(z, td.inertia, f_s, td.impedance_factor)
    else:
        kp, ki = stiff_pi_gains(z, td.inertia)
    kp = kp if td.proportional_gain is None else td.proportional_gain
    ki = ki if td.integral_gain is None else td.integral_gain
    if kp == 0.0 and ki == 0.0:  # a study's free top, or a typo that reads as mild stick-slip
        warnings.warn("top_drive.proportional_gain, top_drive.integral_gain: both 0, so the "
                      "drive's speed loop applies no torque: a free top (the string runs "
                      "down on its own)", UserWarning, stacklevel=2)
    feedback = td.feedback()
    filter_frequency = 0.0
    if feedback != "none":
        if td.filter_frequency is not None:
            filter_frequency = td.filter_frequency
        elif feedback == "high_pass":
            filter_frequency = Z_TORQUE_CORNER_RATIO * f_s
        else:
            filter_frequency = f_s
    gain = (1.0 / z if td.feedback_gain is None else td.feedback_gain) \
        if feedback != "none" else 0.0
    return TopDriveLaw(name, kp, ki, feedback, gain, filter_frequency, td.filter_damping,
                       f_s if needs_frequency else None, z, td.inertia)


def measured_reflection(config: SimulationConfig, frequencies: np.ndarray,
                        seconds: float = 40.0, surface_rpm: float = 60.0
                        ) -> np.ndarray:
    """Reflection coefficient of the top, measured as the literature does it: a torque
    pulse travels up the string and the top sends back a part of it.

    The string turns steadily off bottom (torsion only) at ``surface_rpm``; a short
    torque pulse at the bit starts a wave up the pipe. At the top the speed w and the
    string torque T split into the wave going up, ``(w - T/Z) / 2``, and the wave coming
    back down, ``(w + T/Z) / 2`` (d'Alembert for a uniform shaft of impedance Z); their
    Fourier transforms over the run give ``r(f) = down / up``. This holds whatever
    reflects at the bit later, so one run gives every frequency the pulse excites.
    """
    from drill_env.physics.config import replace
    from drill_env.physics.layout import R
    from drill_env.physics.simulator import OperatingPoint, Simulator
    from drill_env.physics.units import RPM

    cfg = replace(config, **{"solver.lateral": False})
    sim = Simulator(cfg)
    omega = surface_rpm * RPM
    sim.reset(OperatingPoint(omega, 0.0))
    # The pulse: the bit's speed kicked by 1 %, a broadband velocity impulse.
    sim.vt[-1] += 0.01 * omega
    steps = round(seconds / sim.dt)
    record = sim.advance(steps, omega, sim.hook_load_for(0.0), record_every=1)
    w = record[:, R.SURFACE_SPEED] - omega
    torque = record[:, R.SURFACE_TORQUE]
    torque = torque - torque[0]
    z = cfg.string.drill_pipe.torsional_impedance
    up = 0.5 * (w - torque / z)
    down = 0.5 * (w + torque / z)
    t = record[:, R.TIME]
    out = np.empty(len(frequencies), dtype=complex)
    for i, f in enumerate(np.atleast_1d(frequencies)):
        phase = np.exp(-2j * math.pi * f * t)
        out[i] = complex(np.sum(down * phase) / np.sum(up * phase))
    return out



#: Largest 2 pi f dt of the top drive's torque filter: its semi-implicit update is stable
#: below 2; 0.5 keeps its phase error at the filter frequency under ~10 %.
MAX_FILTER_W_DT = 0.5


def feedback_parameters(law: TopDriveLaw, dt: float, p: np.ndarray) -> None:
    """Write the torque feedback of ``law`` (``TopDriveConfig.torque_feedback``) into the
    kernel parameters ``p``; refuse a filter too fast for the step ``dt``."""
    mode = {"none": Feedback.NONE, "high_pass": Feedback.HIGH_PASS,
            "band_pass": Feedback.BAND_PASS}[law.torque_feedback]
    p[P.TD_FEEDBACK] = mode
    if mode == Feedback.NONE:
        return
    w = 2.0 * math.pi * law.filter_frequency
    if w * dt > MAX_FILTER_W_DT:
        raise ConfigError(
            f"top_drive.filter_frequency: {law.filter_frequency:g} Hz is too fast for "
            f"the time step {dt:.2e} s (2 pi f dt must stay below {MAX_FILTER_W_DT})")
    p[P.TD_FEEDBACK_GAIN] = law.feedback_gain
    p[P.TD_FILTER_W] = w
    p[P.TD_FILTER_ZETA] = law.filter_damping
