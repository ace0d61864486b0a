"""Drilling-performance metrics: the ONE source of truth (definitions below; docs/controllers.md
lists them as the columns of benchmark.csv).

The env's reward and ``info``, the benchmark tables and the rerun plots all use these
definitions. They are pure NumPy, take signals in SI units (rad/s, N, N m, m, m/s)
sampled on a uniform grid, and return plain floats.

=========================  ============================================================
metric                     definition
=========================  ============================================================
stick-slip severity (SSI)  (max - min) / (2 |mean|) of the bit speed over a window
stuck fraction             share of samples with |bit speed| < 1 rpm
whirl ratio                mean whirl speed / mean bit speed: > 0 forward, < 0 backward
whirl fraction             share of samples that whirl (:func:`whirling`: the one rule)
backward whirl fraction    share of samples that whirl against the rotation
radial ratio               bit lateral displacement over the gauge clearance
excursion ratio            bit lateral displacement from its rest over the clearance
lateral force              magnitude of the bit's lateral force (N)
ROP                        mean rate of penetration (m/s)
MSE                        mechanical specific energy, Teale (1965), in Pa (J/m^3), capped
top-drive energy           work done by the top-drive motor, integral |T w| dt (J)
peak surface torque        max |surface torque| (N m), checked against the make-up torque
=========================  ============================================================

:class:`RollingMetrics` is the fast path the env calls every control step: numba kernels
that give the same floats as :func:`window_metrics` over a rolling record window.
"""

from __future__ import annotations

import math
from enum import IntEnum
from typing import NamedTuple

import numpy as np
from numba import njit

from drill_env.physics.jit import TUPLE_KERNEL
from drill_env.physics.units import RPM
from drill_env.whirl_rule import (  # noqa: F401  (the rule's constants: the surface)
    WHIRL_RADIAL_RATIO,
    WHIRL_REVERSAL,
    WHIRL_SPEED_RATIO,
    WHIRL_SWEEP,
    orbit_angles,
    whirl_legs,
)

#: The bit counts as stuck below this speed (rad/s): 1 rpm.
STUCK_SPEED = 1.0 * RPM
#: Floor of |mean bit speed| in the SSI denominator (rad/s): 1 rpm.
SSI_MIN_MEAN_SPEED = 1.0 * RPM
#: Below this mean ROP (m/s) the bit is not drilling and the MSE rotary term is undefined.
MSE_MIN_ROP = 1e-9
#: Ceiling of the reported MSE (Pa). Hard rock has a compressive strength of ~200 MPa and
#: a drilling bit spends a few times that (Teale 1965; Dupriest & Koederitz 2005 read
#: efficiencies of 30-40 %); 10 GPa means energy spent without drilling. A bit that turns
#: under power without penetrating would have an infinite MSE: it reports this ceiling,
#: so MSE stays finite in info, tables and plots.
MSE_CEILING = 1.0e10


def summed(values) -> float:
    """The floats ``values`` added left to right from 0, as the batched kernels add a
    step's reward terms: Python 3.12's ``sum()`` of floats compensates its rounding, and
    the single env's reward then differed from the batched env's in the last bit."""
    total = 0.0
    for value in values:
        total += value
    return float(total)


def _signal(values, name: str) -> np.ndarray:
    a = np.asarray(values, dtype=float)
    if a.size == 0:
        raise ValueError(f"{name}: empty signal")
    return a


def stick_slip_severity(bit_speed, min_mean_speed: float = SSI_MIN_MEAN_SPEED) -> float:
    """Stick-slip severity SSI = (max - min) / (2 |mean|) of the bit speed over a window.

    0 for steady rotation; a sinusoid ``m + a sin(t)`` over whole periods gives ``a / m``;
    full stick-slip (bit stops, peaks at 2x mean) gives ~1. The mean is floored at
    ``min_mean_speed`` (1 rpm) so a bit rocking about zero gives a large but finite
    value; a bit that never turns has no swing and gives 0 (its stuck share says it).
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


def excursion_ratio(bit_x, bit_y, clearance: float, rest=(0.0, 0.0)) -> np.ndarray:
    """Bit lateral displacement from its rest position ``rest`` (m: x, y) over the radial
    clearance: the lateral vibration the env's whirl reward pays for. The rest is where
    the env's reset placed the bit: the hole axis in a vertical hole (the radial ratio),
    the low side of a deviated one, where gravity holds the bit without any whirl."""
    if not clearance > 0:
        raise ValueError(f"clearance: must be > 0, got {clearance!r}")
    return np.hypot(np.asarray(bit_x, dtype=float) - rest[0],
                    np.asarray(bit_y, dtype=float) - rest[1]) / clearance


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


def whirling(radial, whirl_speed, bit_speed, dt: float, position=None) -> np.ndarray:
    """The whirl rule (:mod:`drill_env.whirl_rule`; :func:`whirl_signs`) per sample of
    signals ``dt`` apart: the bit off the axis AND its centre travelling round the hole,
    fast. A sample with a NaN whirl speed or radius does not whirl and ends a leg."""
    return whirl_signs(radial, whirl_speed, bit_speed, dt, position) != 0.0


def whirl_signs(radial, whirl_speed, bit_speed, dt: float, position=None) -> np.ndarray:
    """Per sample: +1 where the bit whirls with the rotation, -1 against it, 0 where it
    does not whirl (:mod:`drill_env.whirl_rule`; samples ``dt`` apart). ``position``: the
    bit centre's angle about the hole axis (rad, ``atan2(y, x)``): between samples the
    rule takes its difference plus the whole turns the whirl speed implies (recorded
    signals give it; without it the rule integrates the whirl speed alone, which a rattle
    sampled at 50 Hz misreads). A sample's sign is its leg's direction of travel against
    its own bit speed's sign (a stuck bit, or a NaN bit speed, counts as turning the
    positive way)."""
    radial = np.ascontiguousarray(radial, dtype=float)
    ws = np.ascontiguousarray(whirl_speed, dtype=float)
    w = np.ascontiguousarray(bit_speed, dtype=float)
    angle = np.zeros(0) if position is None else np.ascontiguousarray(position, dtype=float)
    if not radial.shape == ws.shape == w.shape or radial.ndim != 1 or (
            position is not None and angle.shape != radial.shape):
        raise ValueError(f"radial, whirl_speed, bit_speed, position: need 1-D signals of one "
                         f"length, got shapes {radial.shape}, {ws.shape}, {w.shape}"
                         + ("" if position is None else f", {angle.shape}"))
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt: must be a finite sample spacing > 0 s, got {dt!r}")
    out = np.zeros(radial.shape[0])
    whirl_legs(radial, angle, ws, w, dt, STUCK_SPEED, out)
    return out


def backward_whirling(radial, whirl_speed, bit_speed, dt: float, position=None) -> np.ndarray:
    """Samples that whirl (:func:`whirling`) against the rotation."""
    return whirl_signs(radial, whirl_speed, bit_speed, dt, position) < 0.0


def whirl_direction(whirl_speed, bit_speed, radial, dt: float, position=None) -> str:
    """"forward", "backward" or "none" (no sample whirls by :func:`whirling`, or as many
    whirl each way).

    The direction most whirling samples take (:func:`whirl_signs`): the share of time,
    as the backward-whirl fraction counts it and the recordings' whirl events name it
    (not the mean whirl speed, which a fast backward whirl would outweigh).
    """
    return direction_of(float(np.sum(whirl_signs(_signal(radial, "radial"), whirl_speed,
                                                 bit_speed, dt, position))))


def direction_of(votes: float) -> str:
    """The whirl direction a sum of :func:`whirl_signs` says: "forward" (more samples
    forward), "backward", or "none" (as many each way); the recordings' whirl events name
    theirs by it too."""
    return "forward" if votes > 0 else "backward" if votes < 0 else "none"


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
                               bit_diameter: float, min_rop: float = MSE_MIN_ROP) -> float:
    """Mechanical specific energy (Teale 1965) over a window, in Pa (= J/m^3).

    ``MSE = WOB / A + 2 pi N T / (A ROP)`` with N in rev/s, i.e. ``omega T / (A ROP)``
    with omega in rad/s; over a window the powers are averaged:
    ``mean(WOB) / A + mean(omega T) / (A mean(ROP))``. ``A = pi d^2 / 4``. The result
    is capped at :data:`MSE_CEILING`; when the mean ROP is below ``min_rop`` (not
    drilling) the rotary term is undefined: the result is the ceiling if rotary power is
    spent, else just ``mean(WOB) / A``. The env's and benchmark's ``torque_on_bit`` is
    the blades' cutting torque (the simulator's record): the gauge pads' friction on
    the wall, which turns the string too when the bit rubs the wall (whirl, a bit
    lying on a deviated hole's low side), is not in it.
    """
    area = bit_area(bit_diameter)
    wob = float(np.mean(_signal(weight_on_bit, "weight_on_bit")))
    power = float(np.mean(_signal(torque_on_bit, "torque_on_bit")
                          * _signal(bit_speed, "bit_speed")))
    r = mean_rop(rop)
    if r < min_rop:
        return MSE_CEILING if power > 0 else min(wob / area, MSE_CEILING)
    return min(wob / area + power / (area * r), MSE_CEILING)


def top_drive_energy(motor_torque, surface_speed, dt: float) -> float:
    """Work done by the top-drive motor, sum |T omega| dt (J), samples ``dt`` apart.

    Braking counts as spent energy too (no regeneration assumed), as in the simulator.
    """
    t = _signal(motor_torque, "motor_torque")
    w = _signal(surface_speed, "surface_speed")
    return float(np.sum(np.abs(t * w)) * dt)


def peak_surface_torque(surface_torque) -> float:
    """Largest |surface torque| over the window (N m): what breaks a pipe connection."""
    return float(np.max(np.abs(_signal(surface_torque, "surface_torque"))))


def window_metrics(records: np.ndarray, channels, dt: float, clearance: float,
                   bit_diameter: float, rest=(0.0, 0.0)) -> dict[str, float]:
    """All metrics of a simulator record window (rows: samples ``dt`` apart).

    ``channels`` names the record columns (the simulator's ``RECORD_CHANNELS``). Returns
    the :data:`WINDOW_METRICS`: ``ssi, stuck_fraction, whirl_ratio, radial_ratio (mean),
    radial_ratio_max, lateral_force (mean), lateral_force_max, rop, mse,
    top_drive_energy, surface_torque_max, whirl_fraction, backward_whirl_fraction,
    mean_bit_speed, excursion_ratio`` (mean, from the bit's ``rest``: :func:`excursion_ratio`).
    """
    col = {name: k for k, name in enumerate(channels)}
    rec = np.asarray(records, dtype=float)
    if rec.ndim != 2 or rec.shape[0] == 0:
        raise ValueError("records: need a non-empty (n_samples, n_channels) array")

    def c(name: str) -> np.ndarray:
        return rec[:, col[name]]

    radial = radial_ratio(c("bit_x"), c("bit_y"), clearance)
    force = lateral_force(c("bit_force_x"), c("bit_force_y"))
    signs = whirl_signs(radial, c("whirl_speed"), c("bit_speed"), dt,
                        orbit_angles(np.ascontiguousarray(c("bit_x")),
                                     np.ascontiguousarray(c("bit_y"))))
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
        "surface_torque_max": peak_surface_torque(c("surface_torque")),
        "whirl_fraction": float(np.mean(signs != 0.0)),
        "backward_whirl_fraction": float(np.mean(signs < 0.0)),
        "mean_bit_speed": float(np.mean(c("bit_speed"))),
        "excursion_ratio": float(np.mean(excursion_ratio(c("bit_x"), c("bit_y"), clearance,
                                                         rest))),
    }


# --------------------------------------------------------------------------- fast path
#
# The env needs the window metrics every control step (10 Hz) over a window of a few
# hundred samples that moves by a few samples. RollingMetrics keeps the per-sample
# quantities of the window (hypot etc., computed once per sample) and reduces them in
# one compiled call. The floats are those of the NumPy definitions above: the same
# element-wise operations and NumPy's pairwise summation order (tests/test_metrics.py).

#: The values of :func:`window_metrics`, in the order the fast path writes them.
Metric = IntEnum("Metric", [
    "SSI", "STUCK_FRACTION", "WHIRL_RATIO", "RADIAL_RATIO", "RADIAL_RATIO_MAX",
    "LATERAL_FORCE", "LATERAL_FORCE_MAX", "ROP", "MSE", "TOP_DRIVE_ENERGY",
    "SURFACE_TORQUE_MAX", "WHIRL_FRACTION", "BACKWARD_WHIRL_FRACTION", "MEAN_BIT_SPEED",
    "EXCURSION_RATIO",
], start=0)
WINDOW_METRICS: tuple[str, ...] = tuple(m.name.lower() for m in Metric)
#: The record channels the metrics read, in the order of :func:`metric_columns`.
Channel = IntEnum("Channel", [
    "BIT_SPEED", "WHIRL_SPEED", "BIT_X", "BIT_Y", "BIT_FORCE_X", "BIT_FORCE_Y", "ROP",
    "WEIGHT_ON_BIT", "TORQUE_ON_BIT", "MOTOR_TORQUE", "SURFACE_SPEED", "SURFACE_TORQUE",
], start=0)
METRIC_CHANNELS: tuple[str, ...] = tuple(c.name.lower() for c in Channel)
#: Per-sample quantities the window metrics reduce (rows of a samples array; ``FINITE``
#: is 1.0 where every channel of the record is finite, else 0.0; ``ORBIT_ANGLE`` is the bit
#: centre's angle about the axis, atan2(y, x), for the whirl rule; ``WHIRL_SIGN`` is the
#: reduction's scratch: :func:`whirl_signs` of the samples reduced last).
Sample = IntEnum("Sample", [
    "BIT_SPEED", "WHIRL_SPEED", "RADIAL_RATIO", "LATERAL_FORCE", "ROP", "WEIGHT_ON_BIT",
    "BIT_POWER", "MOTOR_POWER", "SURFACE_TORQUE", "EXCURSION_RATIO", "FINITE", "ORBIT_ANGLE",
    "WHIRL_SIGN",
], start=0)
#: Scalars of a rolling window (``WindowArrays.params``); REST_X, REST_Y: the bit's rest
#: position (m) that the excursion ratio is measured from (:meth:`RollingMetrics.set_rest`).
WindowParam = IntEnum("WindowParam", ["CLEARANCE", "DT", "AREA", "SIZE", "REST_X", "REST_Y"],
                      start=0)


class WindowArrays(NamedTuple):
    """What a compiled caller passes to :func:`rolling_add` for one rolling window."""

    columns: np.ndarray     # int64: column of each Channel in the records
    params: np.ndarray      # float64: WindowParam
    samples: np.ndarray     # (len(Sample), capacity) per-sample quantities
    bounds: np.ndarray      # int64 [start, end) of the window in ``samples``
    step_out: np.ndarray    # metrics (Metric) of the last records added
    window_out: np.ndarray  # metrics of the whole window
    tasks: np.ndarray       # summation scratch (sum_scratch)
    partial: np.ndarray


def metric_columns(channels) -> np.ndarray:
    """Column of each of :data:`METRIC_CHANNELS` in records whose columns are ``channels``."""
    channels = tuple(channels)
    missing = [name for name in METRIC_CHANNELS if name not in channels]
    if missing:
        raise ValueError(f"channels: missing {missing} (need {METRIC_CHANNELS})")
    return np.array([channels.index(name) for name in METRIC_CHANNELS], dtype=np.int64)


@njit(cache=True, nogil=True)
def _block_sum(a, lo, n):
    """NumPy's sum of a run of at most 128 values (see :func:`_pairwise_sum`)."""
    if n < 8:
        res = 0.0
        for i in range(lo, lo + n):
            res += a[i]
        return res
    r0, r1, r2, r3 = a[lo], a[lo + 1], a[lo + 2], a[lo + 3]
    r4, r5, r6, r7 = a[lo + 4], a[lo + 5], a[lo + 6], a[lo + 7]
    i = lo + 8
    stop = lo + n - n % 8
    while i < stop:
        r0 += a[i]
        r1 += a[i + 1]
        r2 += a[i + 2]
        r3 += a[i + 3]
        r4 += a[i + 4]
        r5 += a[i + 5]
        r6 += a[i + 6]
        r7 += a[i + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < lo + n:
        res += a[i]
        i += 1
    return res


@njit(cache=True, nogil=True)
def _pairwise_sum(a, tasks, partial):
    """``np.sum(a)`` (1-D float64) with NumPy's summation order, so the float is the same.

    NumPy (``pairwise_sum`` in ``loops_utils.h.src``, added to the identity 0.0) adds
    fewer than 8 values in order, up to 128 with 8 interleaved accumulators, and splits
    longer runs in two at a multiple of 8, summing each half the same way. numba cannot
    cache a recursive function, so the recursion runs on the stacks ``tasks`` ((2, 192)
    int64) and ``partial`` ((64,) float64): enough for any length below 2**60.
    """
    n = a.shape[0]
    if n <= 128:
        return 0.0 + _block_sum(a, 0, n)
    # Post-order walk of the split tree. A task is a run (start, length), or start -1:
    # add the two partial sums on top of the stack (left + right).
    tasks[0, 0], tasks[1, 0] = 0, n
    n_tasks, n_partial = 1, 0
    while n_tasks:
        n_tasks -= 1
        lo, m = tasks[0, n_tasks], tasks[1, n_tasks]
        if lo < 0:
            n_partial -= 1
            partial[n_partial - 1] += partial[n_partial]
        elif m <= 128:
            partial[n_partial] = _block_sum(a, lo, m)
            n_partial += 1
        else:
            half = m // 2
            half -= half % 8
            tasks[0, n_tasks], tasks[1, n_tasks] = -1, 0
            tasks[0, n_tasks + 1], tasks[1, n_tasks + 1] = lo + half, m - half
            tasks[0, n_tasks + 2], tasks[1, n_tasks + 2] = lo, half
            n_tasks += 3
    return 0.0 + partial[0]


def sum_scratch() -> tuple[np.ndarray, np.ndarray]:
    """The ``tasks`` and ``partial`` stacks of :func:`_pairwise_sum`, allocated once."""
    return np.empty((2, 192), dtype=np.int64), np.empty(64)


@njit(cache=True, nogil=True)
def _max(a):
    """``np.max``: NaN if any value is NaN."""
    m = a[0]
    for v in a:
        if v > m or v != v:
            m = v
            if v != v:
                break
    return m


@njit(cache=True, nogil=True)
def metric_samples_into(records, columns, params, samples):
    """The :data:`Sample` quantities of each record (row of ``records``) into ``samples``.

    ``columns``: :func:`metric_columns`; ``params``: the window's :data:`WindowParam`
    values; ``samples``: ``(len(Sample), n)``. The element-wise parts of the definitions
    above.
    """
    n_channels = records.shape[1]
    clearance = params[WindowParam.CLEARANCE]
    rest_x, rest_y = params[WindowParam.REST_X], params[WindowParam.REST_Y]
    for k in range(records.shape[0]):
        w = records[k, columns[Channel.BIT_SPEED]]
        x, y = records[k, columns[Channel.BIT_X]], records[k, columns[Channel.BIT_Y]]
        samples[Sample.BIT_SPEED, k] = w
        samples[Sample.WHIRL_SPEED, k] = records[k, columns[Channel.WHIRL_SPEED]]
        samples[Sample.RADIAL_RATIO, k] = math.hypot(x, y) / clearance
        samples[Sample.EXCURSION_RATIO, k] = math.hypot(x - rest_x, y - rest_y) / clearance
        samples[Sample.ORBIT_ANGLE, k] = math.atan2(y, x)
        samples[Sample.LATERAL_FORCE, k] = math.hypot(records[k, columns[Channel.BIT_FORCE_X]],
                                                      records[k, columns[Channel.BIT_FORCE_Y]])
        samples[Sample.ROP, k] = records[k, columns[Channel.ROP]]
        samples[Sample.WEIGHT_ON_BIT, k] = records[k, columns[Channel.WEIGHT_ON_BIT]]
        samples[Sample.BIT_POWER, k] = records[k, columns[Channel.TORQUE_ON_BIT]] * w
        samples[Sample.MOTOR_POWER, k] = abs(records[k, columns[Channel.MOTOR_TORQUE]]
                                             * records[k, columns[Channel.SURFACE_SPEED]])
        samples[Sample.SURFACE_TORQUE, k] = records[k, columns[Channel.SURFACE_TORQUE]]
        finite = 1.0
        for j in range(n_channels):
            if not math.isfinite(records[k, j]):
                finite = 0.0
                break
        samples[Sample.FINITE, k] = finite


@njit(cache=True, nogil=True)
def reduce_metric_samples(samples, dt, area, out, tasks, partial):
    """The :data:`Metric` values of ``samples`` (at least one) into ``out``.

    ``dt``: sample spacing (s); ``area``: :func:`bit_area`; ``tasks``, ``partial``: the
    scratch stacks of :func:`_pairwise_sum`, from :func:`sum_scratch`. Returns whether every
    record behind the samples was finite. The reductions of the definitions above, with
    their NaN behaviour (``np.max`` propagates NaN, Python's ``max(nan, x)`` is NaN).
    """
    n = samples.shape[1]
    w = samples[Sample.BIT_SPEED]

    w_max, w_min = w[0], w[0]  # np.max / np.min: NaN if any is NaN
    stuck = 0
    for v in w:
        if v > w_max or v != v:
            w_max = v
        if v < w_min or v != v:
            w_min = v
        if abs(v) < STUCK_SPEED:
            stuck += 1
    mean_speed = _pairwise_sum(w, tasks, partial) / n
    floor = abs(mean_speed)  # max(|mean|, SSI_MIN_MEAN_SPEED)
    if floor < SSI_MIN_MEAN_SPEED:
        floor = SSI_MIN_MEAN_SPEED
    out[Metric.SSI] = (w_max - w_min) / (2.0 * floor)
    out[Metric.STUCK_FRACTION] = stuck / n
    out[Metric.MEAN_BIT_SPEED] = mean_speed
    whirl = _pairwise_sum(samples[Sample.WHIRL_SPEED], tasks, partial) / n
    out[Metric.WHIRL_RATIO] = whirl / math.copysign(floor, mean_speed if mean_speed != 0 else
                                                    1.0)
    out[Metric.RADIAL_RATIO] = _pairwise_sum(samples[Sample.RADIAL_RATIO], tasks, partial) / n
    out[Metric.RADIAL_RATIO_MAX] = _max(samples[Sample.RADIAL_RATIO])
    out[Metric.EXCURSION_RATIO] = _pairwise_sum(samples[Sample.EXCURSION_RATIO], tasks,
                                                partial) / n
    out[Metric.LATERAL_FORCE] = _pairwise_sum(samples[Sample.LATERAL_FORCE], tasks,
                                              partial) / n
    out[Metric.LATERAL_FORCE_MAX] = _max(samples[Sample.LATERAL_FORCE])
    rop = _pairwise_sum(samples[Sample.ROP], tasks, partial) / n
    out[Metric.ROP] = rop
    wob = _pairwise_sum(samples[Sample.WEIGHT_ON_BIT], tasks, partial) / n
    power = _pairwise_sum(samples[Sample.BIT_POWER], tasks, partial) / n
    if rop < MSE_MIN_ROP:
        out[Metric.MSE] = MSE_CEILING if power > 0 else min(wob / area, MSE_CEILING)
    else:
        out[Metric.MSE] = min(wob / area + power / (area * rop), MSE_CEILING)
    out[Metric.TOP_DRIVE_ENERGY] = _pairwise_sum(samples[Sample.MOTOR_POWER], tasks,
                                                 partial) * dt
    torque = samples[Sample.SURFACE_TORQUE]
    peak = abs(torque[0])  # surface_torque_max, NaN if any is NaN
    for v in torque:
        if abs(v) > peak or v != v:
            peak = abs(v)
    out[Metric.SURFACE_TORQUE_MAX] = peak
    # the whirl rule of whirl_signs(), into the samples' scratch row (NaN: no whirl)
    signs = samples[Sample.WHIRL_SIGN]
    signs[:] = 0.0
    whirl_legs(samples[Sample.RADIAL_RATIO], samples[Sample.ORBIT_ANGLE],
               samples[Sample.WHIRL_SPEED], w, dt, STUCK_SPEED, signs)
    whirls = 0
    backward = 0
    for k in range(n):
        if signs[k] != 0.0:
            whirls += 1
            if signs[k] < 0.0:
                backward += 1
    out[Metric.WHIRL_FRACTION] = whirls / n
    out[Metric.BACKWARD_WHIRL_FRACTION] = backward / n
    for v in samples[Sample.FINITE]:
        if v == 0.0:
            return False
    return True


#: Bits of :func:`rolling_add`'s result: the step's metrics are finite, the window's are.
STEP_FINITE = 1
WINDOW_FINITE = 2


@njit(**TUPLE_KERNEL)
def rolling_add(records, window, with_window):
    """Append the samples of ``records`` (at least one) to a rolling window; metrics.

    ``window``: the :class:`WindowArrays`; its ``samples`` buffer must hold at least
    ``size + len(records)`` samples and ``bounds`` ([start, end) of the window in it) is
    updated. When the records do not fit after ``end`` the kept samples move to the
    front first. Writes the metrics of ``records`` into ``step_out`` and, if
    ``with_window``, those of the last ``size`` samples into ``window_out``. Returns
    :data:`STEP_FINITE` if the step's records were all finite, plus
    :data:`WINDOW_FINITE` if the window's were.
    """
    samples = window.samples
    bounds = window.bounds
    params = window.params
    dt = params[WindowParam.DT]
    area = params[WindowParam.AREA]
    size = np.int64(params[WindowParam.SIZE])
    n = records.shape[0]
    start, end = bounds[0], bounds[1]
    if end + n > samples.shape[1]:
        kept = end - start
        for row in range(samples.shape[0]):
            for k in range(kept):
                samples[row, k] = samples[row, start + k]
        start, end = 0, kept
    new = samples[:, end:end + n]
    metric_samples_into(records, window.columns, params, new)
    end += n
    start = max(start, end - size)
    bounds[0], bounds[1] = start, end
    flags = STEP_FINITE if reduce_metric_samples(new, dt, area, window.step_out,
                                                 window.tasks, window.partial) else 0
    if with_window and reduce_metric_samples(samples[:, start:end], dt, area,
                                             window.window_out, window.tasks,
                                             window.partial):
        flags += WINDOW_FINITE
    return flags


class RollingMetrics:
    """The :func:`window_metrics` of the last ``size`` records, updated as records arrive.

    Args:
        size: window length in records.
        channels: names of the record columns (the simulator's ``RECORD_CHANNELS``).
        dt: record spacing (s); clearance: gauge clearance (m); bit_diameter: (m).

    ``add(records)`` appends the :data:`Sample` quantities of new records to a buffer
    twice the window long (the kept samples move to its front once every ``size``
    records; it grows if one ``add`` brings more) and returns the metrics of those
    records; ``window()`` those of the whole window; ``update(records)`` both, in one
    compiled call (the env's step). Metrics come as a list of floats in the order of
    :data:`WINDOW_METRICS`, with a flag telling whether every value of the records behind
    them is finite. :attr:`arrays` is what a compiled caller hands to :func:`rolling_add`
    (a batch of envs does, :mod:`drill_env.batching`).
    """

    def __init__(self, size: int, channels, dt: float, clearance: float,
                 bit_diameter: float) -> None:
        if not (isinstance(size, (int, np.integer)) and size >= 1):
            raise ValueError(f"size: must be an integer >= 1, got {size!r}")
        if not clearance > 0:
            raise ValueError(f"clearance: must be > 0, got {clearance!r}")
        self.size = int(size)
        self.dt = float(dt)
        self.clearance = float(clearance)
        self.area = bit_area(bit_diameter)
        params = np.zeros(len(WindowParam))
        params[WindowParam.CLEARANCE] = self.clearance
        params[WindowParam.DT] = self.dt
        params[WindowParam.AREA] = self.area
        params[WindowParam.SIZE] = self.size
        tasks, partial = sum_scratch()
        self.arrays = WindowArrays(
            columns=metric_columns(channels), params=params,
            samples=np.empty((len(Sample), 2 * self.size)),
            bounds=np.zeros(2, dtype=np.int64), step_out=np.empty(len(Metric)),
            window_out=np.empty(len(Metric)), tasks=tasks, partial=partial)

    def __len__(self) -> int:
        bounds = self.arrays.bounds
        return int(bounds[1] - bounds[0])

    def clear(self) -> None:
        self.arrays.bounds[:] = 0

    def set_rest(self, x: float, y: float) -> None:
        """The bit's rest position (m) the excursion ratio of the records added from now on
        is measured from (:func:`excursion_ratio`; the env sets it at each reset)."""
        self.arrays.params[WindowParam.REST_X] = x
        self.arrays.params[WindowParam.REST_Y] = y

    @property
    def bit_speed(self) -> np.ndarray:
        """The bit speed of the window's records (a view, valid until the next ``add``)."""
        start, end = self.arrays.bounds.tolist()
        return self.arrays.samples[Sample.BIT_SPEED, start:end]

    def reserve(self, n: int) -> None:
        """Make room for adding ``n`` records at once (grows the buffer if needed; a new
        buffer means a new :attr:`arrays`)."""
        samples = self.arrays.samples
        if self.size + n > samples.shape[1]:
            start, end = self.arrays.bounds.tolist()
            grown = np.empty((len(Sample), self.size + n))
            grown[:, :end - start] = samples[:, start:end]
            self.arrays = self.arrays._replace(samples=grown)
            self.arrays.bounds[:] = (0, end - start)

    def result(self, flags: int) -> tuple[tuple[list[float], bool], tuple[list[float], bool]]:
        """The (step, window) metrics a :func:`rolling_add` call with ``with_window`` left
        in this window's outputs, given the flags it returned."""
        return ((self.arrays.step_out.tolist(), bool(flags & STEP_FINITE)),
                (self.arrays.window_out.tolist(), bool(flags & WINDOW_FINITE)))

    def _add(self, records: np.ndarray, with_window: bool) -> int:
        self.reserve(len(records))
        return rolling_add(records, self.arrays, with_window)

    def add(self, records: np.ndarray) -> tuple[list[float], bool] | None:
        """Append ``records`` (rows); their metrics and whether they are all finite.

        ``None`` (and nothing appended) when ``records`` is empty.
        """
        if len(records) == 0:
            return None
        flags = self._add(records, False)
        return self.arrays.step_out.tolist(), bool(flags & STEP_FINITE)

    def update(self, records: np.ndarray) -> tuple[tuple[list[float], bool] | None,
                                                   tuple[list[float], bool] | None]:
        """``(add(records), window())`` in one compiled call (``add`` is None when
        ``records`` is empty, and ``window()`` is then computed on its own)."""
        if len(records) == 0:
            return None, self.window()
        return self.result(self._add(records, True))

    def window(self) -> tuple[list[float], bool] | None:
        """The metrics of the window and whether they are all finite (``None``: empty)."""
        a = self.arrays
        start, end = a.bounds.tolist()
        if end == start:
            return None
        finite = reduce_metric_samples(a.samples[:, start:end], self.dt, self.area,
                                       a.window_out, a.tasks, a.partial)
        return a.window_out.tolist(), finite
