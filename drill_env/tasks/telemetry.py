"""Downhole data as a surface controller gets it: sampled, delayed, held.

A mud-pulse MWD tool sends a few words every couple of seconds (1-10 bit/s) and the
pressure pulses need about a second per 1.2 km to reach the surface, plus decoding; wired
drill pipe delivers ~10 samples a second within tens of milliseconds. :class:`Telemetry`
samples a vector of downhole values every ``period`` seconds and delivers it ``delay``
seconds later, both counted in control steps; between deliveries the last delivered
message is held (zeros before the first one arrives, with ``age`` telling how old the
held message is).
"""

from __future__ import annotations

import math
from collections import deque
from typing import Annotated, Literal

from pydantic import PlainValidator

#: (period, delay) in seconds of each telemetry kind ("none": nothing is delivered).
TELEMETRY: dict[str, tuple[float, float]] = {
    # mud pulse: one message every 2 s (~10 words at a few bit/s), 3 s of pulse travel
    # and decoding on a 1-2 km well
    "mud_pulse": (2.0, 3.0),
    # wired drill pipe: 10 samples/s, 50 ms latency
    "wired_pipe": (0.1, 0.05),
}
#: The kinds by name ("none": nothing is delivered).
TelemetryKind = Literal["mud_pulse", "wired_pipe", "none"]


def telemetry_setting(value: object) -> TelemetryKind | tuple[float, float]:
    """A task's ``telemetry`` checked: a kind of :data:`TELEMETRY`, "none", or a channel
    of your own as (period, delay) in seconds (a YAML list), e.g. ``(1.0, 2.0)`` for a
    faster mud pulse: the period above 0, the delay at least 0, both at most an hour
    (counted in control steps like the kinds'). ValueError saying what it takes."""
    if value in ("mud_pulse", "wired_pipe", "none"):  # (TelemetryKind's, TELEMETRY's)
        return value
    if isinstance(value, (tuple, list)) and len(value) == 2 and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
        period, delay = float(value[0]), float(value[1])
        if 0.0 < period <= 3600.0 and 0.0 <= delay <= 3600.0:  # (NaN fails both)
            return period, delay
    raise ValueError(f"must be one of {', '.join(map(repr, sorted(TELEMETRY)))}, 'none' or "
                     "(period, delay) in seconds (period above 0, delay at least 0, both "
                     f"at most 3600), got {value!r}")


#: A task's ``telemetry`` field (:func:`telemetry_setting`).
TelemetrySetting = Annotated[TelemetryKind | tuple[float, float],
                             PlainValidator(telemetry_setting)]


class Telemetry:
    """Sample-and-delay channel for a fixed-length vector of downhole values, read once
    per control step.

    The period and the delay are counted in control steps (the nearest whole number; a
    delay of at least one step): a task's control interval is a whole number of the
    drawn simulator step, a few milliseconds off 1 s or 0.1 s, and sampled by the clock
    a 2 s period became 3 steps on ~40 % of task 2's seeds, the 3 s delay 4.
    """

    def __init__(self, kind: TelemetrySetting, size: int) -> None:
        kind = telemetry_setting(kind)
        if isinstance(kind, tuple):  # a channel of one's own
            self.kind = "custom"
            self.period, self.delay = kind
        else:
            self.kind = kind
            self.period, self.delay = TELEMETRY.get(kind, (math.inf, 0.0))
        self.size = size
        self.reset(0.0, 0.1)

    def reset(self, time: float, interval: float) -> None:
        """A new episode at ``time`` (s), read every ``interval`` seconds (its control
        step); the first message is sampled at the first :meth:`update`."""
        if not interval > 0.0:
            raise ValueError(f"interval: must be > 0, got {interval!r}")
        self._step = 0
        if self.kind != "none":
            self._every = max(1, round(self.period / interval))  # steps between samples
            self._late = max(1, round(self.delay / interval)) if self.delay > 0.0 else 0
        self._in_flight: deque[tuple[int, float, list[float]]] = deque()
        self.held = [0.0] * self.size
        self.sent_at = time - 1.0e9

    def update(self, time: float, values: list[float]) -> list[float]:
        """Once per control step: sample ``values`` if a period has passed, deliver what
        has arrived; returns the held message."""
        if self.kind == "none":
            return self.held
        if self._step % self._every == 0:
            self._in_flight.append((self._step + self._late, time, list(values)))
        while self._in_flight and self._in_flight[0][0] <= self._step:
            _, sampled, message = self._in_flight.popleft()
            self.held = message
            self.sent_at = sampled
        self._step += 1
        return self.held

    def age(self, time: float) -> float:
        """Seconds since the held message was sampled downhole."""
        return time - self.sent_at
