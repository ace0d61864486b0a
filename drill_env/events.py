"""Drilling events from sampled signals: stick-slip onsets, whirl on/off, layer changes.

The rules sit next to :mod:`drill_env.metrics` and use its definitions (a stuck bit is
``|bit speed| < STUCK_SPEED``; whirl is :func:`drill_env.metrics.whirl_signs`, the one rule
the metrics, the benchmark and the recordings share). Each detector is streaming: feed
it the samples chunk by chunk (``update``) and it returns the events that the chunk
completes, carrying its state across chunks, so a recording writes events as the
episode runs (the whirl detector's come up to ``WHIRL_CONTEXT`` late, the last at its
``finish``). An event is ``(time s, level, text)`` with the levels of rerun's text log.
The functions :func:`stick_slip_events`, :func:`whirl_events` and :func:`layer_events`
run one detector over whole arrays.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from drill_env.metrics import STUCK_SPEED, direction_of, whirl_signs
from drill_env.physics.units import RPM
from drill_env.whirl_rule import orbit_angles

Event = tuple[float, str, str]

#: A stick after this long (s) without one is a stick-slip ONSET (else one more cycle).
STICK_SLIP_QUIET = 5.0
#: Whirl (the rule of :func:`drill_env.metrics.whirl_signs`) counts as on after it has
#: held this long (s), and as off after the same time without it: the orbit passes
#: through the rule's thresholds twice a cycle in a transition.
WHIRL_MIN_DURATION = 0.3
#: Seconds of samples the whirl detector judges a sample with, before it and after it: a
#: leg of the rule (half a turn round the hole) can start before the chunk that holds its
#: end (a recording flushes its chunks every 100 env steps). A sample is judged once this
#: much has come after it (or at :meth:`WhirlDetector.finish`), so its events come up to
#: this late, dated as the whole signal dates them wherever the chunks end for a whirl
#: that goes half a turn within it: 7.5 rpm or faster (the rule takes whirl down to a
#: quarter of the bit speed: 10 rpm at 40 rpm). A slower one is dated from where it had
#: gone half a turn within this window.
WHIRL_CONTEXT = 4.0


class StickSlipDetector:
    """A stick is a sample with ``|bit speed| < STUCK_SPEED`` after one at or above it (the
    bit was moving). The first stick, or the first after ``quiet`` seconds without one,
    is a WARN "stick-slip onset"; the others are DEBUG "bit stuck" lines with their
    cycle count."""

    def __init__(self, quiet: float = STICK_SLIP_QUIET) -> None:
        self.quiet = quiet
        self._was_moving = False
        self._last = -math.inf
        self._cycle = 0

    def update(self, t: np.ndarray, bit_speed: np.ndarray) -> list[Event]:
        events: list[Event] = []
        w = np.abs(np.asarray(bit_speed, dtype=np.float64))
        if w.size == 0:
            return events
        finite = np.isfinite(w)
        stuck = finite & (w < STUCK_SPEED)
        moving = finite & ~stuck
        was_moving = np.empty_like(stuck)
        was_moving[0] = self._was_moving
        was_moving[1:] = moving[:-1]
        self._was_moving = bool(moving[-1])
        for i in np.flatnonzero(stuck & was_moving):
            ti = float(t[i])
            if ti - self._last >= self.quiet:
                self._cycle = 1
                events.append((ti, "WARN", "stick-slip onset: bit speed below 1 rpm after "
                                           "moving"))
            else:
                self._cycle += 1
                events.append((ti, "DEBUG", f"bit stuck (cycle {self._cycle})"))
            self._last = ti
        return events


class WhirlDetector:
    """Whirl on and off by :func:`drill_env.metrics.whirl_signs`, held ``min_duration``;
    the onset says forward or backward (the direction most samples took while it held),
    the radial ratio where it began and the mean whirl and bit speeds while it held.
    Each sample is judged with the ``WHIRL_CONTEXT`` seconds before and after it:
    :meth:`update` returns the events of the samples that have that much after them,
    :meth:`finish` those of the rest (the end of the signal)."""

    def __init__(self, clearance: float, min_duration: float = WHIRL_MIN_DURATION) -> None:
        if not clearance > 0:
            raise ValueError(f"clearance: must be > 0, got {clearance!r}")
        self.clearance = clearance
        self.min_duration = min_duration
        self._on = False
        # The candidate change: its first sample's time and radial ratio, and each sample's
        # (whirl sign, whirl speed, bit speed) since then.
        self._since: tuple[float, float] | None = None
        self._held: list[tuple[float, float, float]] = []
        # the samples kept, one row each of time, radial ratio, whirl speed, bit speed and
        # the centre's angle about the axis: the last WHIRL_CONTEXT seconds of those judged
        # (columns up to _judged), then those not judged yet
        self._seen = np.empty((5, 0))
        self._judged = 0

    def update(self, t: np.ndarray, bit_x: np.ndarray, bit_y: np.ndarray,
               whirl_speed: np.ndarray, bit_speed: np.ndarray) -> list[Event]:
        self.add(t, bit_x, bit_y, whirl_speed, bit_speed)
        if not self._seen.shape[1]:
            return []
        ready = int(np.searchsorted(self._seen[0], self._seen[0, -1] - WHIRL_CONTEXT,
                                    side="right"))
        return self._judge(max(ready, self._judged))

    def add(self, t: np.ndarray, bit_x: np.ndarray, bit_y: np.ndarray,
            whirl_speed: np.ndarray, bit_speed: np.ndarray) -> None:
        """Take samples without judging any (:meth:`update` judges those that are ready):
        :func:`whirl_events` judges a whole signal at once, with all of it as context."""
        radial = np.hypot(bit_x, bit_y) / self.clearance
        angle = orbit_angles(np.ascontiguousarray(bit_x, dtype=np.float64),
                             np.ascontiguousarray(bit_y, dtype=np.float64))
        new = np.stack([np.asarray(t, dtype=np.float64), radial,
                        np.asarray(whirl_speed, dtype=np.float64),
                        np.asarray(bit_speed, dtype=np.float64), angle])
        self._seen = np.concatenate([self._seen, new], axis=1)

    def finish(self) -> list[Event]:
        """The events of the samples not judged yet: the signal has ended."""
        return self._judge(self._seen.shape[1])

    def _judge(self, until: int) -> list[Event]:
        """Judge the samples from ``_judged`` to ``until`` (their events), and keep the
        last WHIRL_CONTEXT seconds of them as the context of the next ones."""
        seen, first = self._seen, self._judged
        if until <= first:
            return []
        spacing = np.diff(seen[0])
        if spacing.size and np.all(spacing > 0):
            sign = whirl_signs(seen[1], seen[2], seen[3], float(np.median(spacing)), seen[4])
        else:  # one sample so far, or times that do not advance: no orbit to follow
            sign = np.zeros(seen.shape[1])
        events = self._events(seen[:, first:until], sign[first:until])
        keep = int(np.searchsorted(seen[0, :until], seen[0, until - 1] - WHIRL_CONTEXT,
                                   side="right"))
        self._seen = seen[:, keep:]
        self._judged = until - keep
        return events

    def _events(self, samples: np.ndarray, sign: np.ndarray) -> list[Event]:
        events: list[Event] = []
        t, radial, ws, w, _ = samples  # (the rows of _seen)
        for i in range(samples.shape[1]):
            if (sign[i] != 0.0) == self._on:
                self._since = None
                self._held = []
                continue
            if self._since is None:
                self._since = (float(t[i]), float(radial[i]))
            self._held.append((float(sign[i]), float(ws[i]), float(w[i])))
            start, r0 = self._since
            if float(t[i]) - start < self.min_duration:
                continue
            self._on = not self._on
            if self._on:
                # the rule of metrics.whirl_direction over the samples since the onset;
                # the speeds are their means (one sample's whirl speed swings both ways
                # in a wobbling orbit: "forward ... whirl -10 rpm" read as a contradiction)
                held = np.array(self._held)
                direction = direction_of(float(held[:, 0].sum()))
                if direction == "none":  # as many samples each way (it said backward,
                    # where the metrics' rule says none)
                    direction = "as many forward as backward"
                ws_mean, w_mean = held[:, 1:].mean(axis=0)
                events.append((start, "WARN",
                               f"whirl onset ({direction}): radial ratio {r0:.2f}, whirl "
                               f"{ws_mean / RPM:.0f} rpm, bit {w_mean / RPM:.0f} rpm "
                               f"(means over the {self.min_duration:g} s held)"))
            else:
                events.append((start, "INFO", "whirl ended"))
            self._since = None
            self._held = []
        return events


class LayerDetector:
    """"layer change" when the dominant rock under the front blades changes (the first
    sample with a known rock says which rock the bit is in)."""

    def __init__(self, names: Sequence[str]) -> None:
        self.names = list(names)
        self._previous: int | None = None

    def _name(self, j: int) -> str:
        return self.names[j] if j < len(self.names) else f"rock{j}"

    def update(self, t: np.ndarray, shares: np.ndarray) -> list[Event]:
        events: list[Event] = []
        shares = np.asarray(shares, dtype=np.float64)
        if shares.ndim != 2 or shares.shape[1] == 0:
            return events
        for i in np.flatnonzero(np.isfinite(shares).any(axis=1)):
            row = shares[i]
            dominant = int(np.argmax(np.where(np.isfinite(row), row, -np.inf)))
            if dominant == self._previous:
                continue
            mix = ", ".join(f"{self._name(j)} {row[j] * 100:.0f}%" for j in range(len(row))
                            if np.isfinite(row[j]) and row[j] > 0)
            if self._previous is None:
                events.append((float(t[i]), "INFO", f"bit in {self._name(dominant)} ({mix})"))
            else:
                events.append((float(t[i]), "WARN", f"layer change: "
                               f"{self._name(self._previous)} -> {self._name(dominant)} "
                               f"({mix})"))
            self._previous = dominant
        return events


def stick_slip_events(t: np.ndarray, bit_speed: np.ndarray, quiet: float = STICK_SLIP_QUIET
                      ) -> list[Event]:
    """:class:`StickSlipDetector` over whole arrays."""
    return StickSlipDetector(quiet).update(np.asarray(t), bit_speed)


def whirl_events(t: np.ndarray, bit_x: np.ndarray, bit_y: np.ndarray, whirl_speed: np.ndarray,
                 bit_speed: np.ndarray, clearance: float,
                 min_duration: float = WHIRL_MIN_DURATION) -> list[Event]:
    """:class:`WhirlDetector` over whole arrays."""
    detector = WhirlDetector(clearance, min_duration)
    detector.add(np.asarray(t), np.asarray(bit_x, dtype=np.float64),
                 np.asarray(bit_y, dtype=np.float64), whirl_speed, bit_speed)
    return detector.finish()  # every sample judged with the whole signal


def layer_events(t: np.ndarray, shares: np.ndarray, names: Sequence[str]) -> list[Event]:
    """:class:`LayerDetector` over whole arrays."""
    return LayerDetector(names).update(np.asarray(t), shares)
