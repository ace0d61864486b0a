"""The whirl rule: when the bit whirls, sample by sample (compiled; one rule for the
metrics, the env's rewards, the benchmark and the recordings' events, through
:func:`drill_env.metrics.whirl_signs` and the metrics' fast path)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: The whirl rule, used by the metrics, the env, the benchmark and the recorder's events
#: (:func:`whirl_legs`): the bit centre travels round the hole, off its axis, fast. The
#: centre's angle about the axis (followed as :func:`whirl_legs` says) is cut into *legs*,
#: runs over which it moves one way and turns back by less than WHIRL_REVERSAL; a sample
#: at most WHIRL_RADIAL_RATIO of the gauge clearance off the axis (or with a NaN whirl
#: speed) ends a leg and never whirls. In a leg that travels at least WHIRL_SWEEP, a
#: sample whirls where the centre orbits faster than WHIRL_SPEED_RATIO of the bit speed
#: (floored at 1 rpm; a NaN bit speed reads as stuck), in the leg's direction.
#: Half the clearance keeps the small static offset of a bit pushed by a dipping
#: interface out; a quarter of the bit speed keeps a slow drift or a pause out and
#: catches forward (~1x) and backward (~ -R/clearance, ~ -20x) whirl. Half a turn of
#: travel keeps out a bit that rattles on the wall without going round, up to half a turn
#: from end to end: the chatter of the paper's sandwich cases (~70 degrees to and fro,
#: case 2 at 60 rpm) and of a slick BHA that gravity holds on the low side of a deviated
#: hole (~80 degrees at the blade-pass rate), which the per-sample radius and speed test
#: alone (the rule to 2026-12-05) read as 17-94 % whirl, half of it backward. A reversal
#: of 90 degrees ends a leg: a forward whirl's wobble at the blade pass turns back less
#: (paper case 4 at 60-120 rpm reads 78-92 % forward whirl and none backward). Limits:
#: a forward orbit whose wobble turns it back by more than 90 degrees is not read (at
#: fast records); records cannot resolve a motion faster than half their rate. The
#: clearance is the bit's (``bit.gauge_clearance``): on the realistic strings the
#: near-bit stabilizer 1 m above it has 0.32 of that (docs/model.md, "The compressed BHA
#: leans on its stabilizers"), so a bit there reaches half only by pressing it into the wall.
WHIRL_RADIAL_RATIO = 0.5
WHIRL_SPEED_RATIO = 0.25
WHIRL_SWEEP = math.pi
WHIRL_REVERSAL = 0.5 * math.pi


@njit(cache=True, nogil=True)
def _close_leg(ws, w, start, end, direction, travel, stuck, out):
    """Mark the samples ``start..end`` (inclusive) of a leg that travelled ``travel`` (rad):
    if it went at least WHIRL_SWEEP, those of its samples that orbit fast (the rule
    above; ``stuck``: the bit-speed floor, rad/s; a NaN bit speed reads as stuck)."""
    if direction == 0 or abs(travel) < WHIRL_SWEEP:
        return
    for k in range(start, end + 1):
        spin = abs(w[k]) if w[k] == w[k] else 0.0
        if abs(ws[k]) > WHIRL_SPEED_RATIO * max(spin, stuck):
            turning = w[k] if (w[k] != 0.0 and w[k] == w[k]) else 1.0
            out[k] = 1.0 if direction * turning > 0.0 else -1.0


@njit(cache=True, nogil=True)
def whirl_legs(radial, position, ws, w, dt, stuck, out):
    """The whirl rule over signals ``dt`` apart (radial ratio, the centre's angle about
    the axis ``position`` (rad, ``atan2(y, x)``; an empty array: none), whirl speed, bit
    speed; ``stuck``: the bit-speed floor of the speed test, rad/s): ``out[k]`` +1 / -1 /
    0 (with the rotation, against it, no whirl; ``out`` zeroed by the caller). A leg ends
    at its extreme sample; the next begins after it.

    The angle travelled between two samples is the difference of their positions plus
    the whole turns that the trapezoid of the whirl speed over the interval implies: the
    positions fix the angle to within whole turns at any record rate (a rattle's records
    are points on its arc), the whirl speed, which the simulator computes from the bit's
    state, counts the turns (a backward whirl that turns by more than half an orbit
    between records, 25 Hz in some task episodes, keeps its direction). Without positions
    (or where one is NaN), the trapezoid: at 50 Hz records it misreads a blade-pass
    rattle's turning back and forth by up to ~2x."""
    n = radial.shape[0]
    positions = position.shape[0] == n
    k = 0
    while k < n:
        if not (radial[k] > WHIRL_RADIAL_RATIO and ws[k] == ws[k]):
            k += 1
            continue
        # a stretch of samples off the axis from k: its angle from 0, cut into legs
        angle, high, low = 0.0, 0.0, 0.0
        i_high, i_low, start, start_angle, direction = k, k, k, 0.0, 0
        j = k + 1
        while j < n and radial[j] > WHIRL_RADIAL_RATIO and ws[j] == ws[j]:
            spun = 0.5 * (ws[j] + ws[j - 1]) * dt  # the trapezoid of the whirl speed
            turn = position[j] - position[j - 1] if positions else math.nan
            if turn == turn:  # the positions' difference, with the whole turns it implies
                angle += turn + 2.0 * math.pi * math.floor((spun - turn) / (2.0 * math.pi)
                                                           + 0.5)
            else:  # no positions (or a NaN one)
                angle += spun
            if angle > high:
                high, i_high = angle, j
            if angle < low:
                low, i_low = angle, j
            if direction == 0:
                if angle - low >= WHIRL_REVERSAL:
                    direction, start, start_angle, high, i_high = 1, i_low, low, angle, j
                elif high - angle >= WHIRL_REVERSAL:
                    direction, start, start_angle, low, i_low = -1, i_high, high, angle, j
            elif direction > 0 and high - angle >= WHIRL_REVERSAL:
                _close_leg(ws, w, start, i_high, 1, high - start_angle, stuck, out)
                direction, start, start_angle, low, i_low = -1, i_high + 1, high, angle, j
            elif direction < 0 and angle - low >= WHIRL_REVERSAL:
                _close_leg(ws, w, start, i_low, -1, low - start_angle, stuck, out)
                direction, start, start_angle, high, i_high = 1, i_low + 1, low, angle, j
            j += 1
        if direction > 0:
            _close_leg(ws, w, start, i_high, 1, high - start_angle, stuck, out)
        elif direction < 0:
            _close_leg(ws, w, start, i_low, -1, low - start_angle, stuck, out)
        k = j


@njit(cache=True, nogil=True)
def orbit_angles(x, y):
    """The bit centre's angle about the hole axis (rad), ``atan2(y, x)`` per sample: as
    the metrics' fast path computes it, so both paths follow the same positions."""
    out = np.empty(x.shape[0])
    for k in range(x.shape[0]):
        out[k] = math.atan2(y[k], x[k])
    return out
