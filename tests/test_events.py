"""Event rules of drill_env.events against hand-made signals: what starts a stick-slip
episode, what a NaN sample is, how long whirl must hold and which way it turns, which
rock a layer event names."""

from __future__ import annotations

import numpy as np
import pytest

from drill_env.events import (
    STICK_SLIP_QUIET,
    WHIRL_CONTEXT,
    WHIRL_MIN_DURATION,
    WhirlDetector,
    layer_events,
    stick_slip_events,
    whirl_events,
)
from drill_env.metrics import direction_of, whirl_direction

CLEARANCE = 0.005  # m


def test_sticking_every_two_seconds_is_one_stick_slip_episode() -> None:
    """Sticks closer together than the quiet time continue one episode: one onset
    (WARN), the other sticks are its cycles (DEBUG)."""
    assert STICK_SLIP_QUIET > 2.0
    t = np.arange(0.0, 20.0, 0.1)
    w = np.where((t % 2.0) < 0.3, 0.0, 5.0)
    w[0] = 5.0
    levels = [e[1] for e in stick_slip_events(t, w)]
    assert levels.count("WARN") == 1 and levels.count("DEBUG") == 9


def test_a_nan_sample_is_neither_stuck_nor_moving() -> None:
    """Moving, stuck, NaN, stuck, moving, stuck: sticks at t = 1 and 5 only (the stuck
    sample after the NaN did not follow a moving one)."""
    t = np.arange(6.0)
    events = stick_slip_events(t, np.array([5.0, 0.0, np.nan, 0.0, 5.0, 0.0]))
    assert [e[0] for e in events] == [1.0, 5.0]


def test_a_stick_is_a_sample_below_the_stuck_speed_right_after_one_at_or_above_it() -> None:
    """StickSlipDetector: a stick is ``|bit speed| < STUCK_SPEED`` after a sample at or
    above it: a signal that starts stuck has no stick there, one at exactly STUCK_SPEED
    is moving; the first stick after ``quiet`` s (5 s here, exactly) is an onset."""
    from drill_env.metrics import STUCK_SPEED

    t = np.arange(12.0)
    w = np.array([0.0, 5.0, STUCK_SPEED, 0.0, 5.0, 5.0, 5.0, 5.0, 0.0, 5.0, 5.0, 0.0])
    events = stick_slip_events(t, w)  # sticks at 3 s, 8 s (5 s after: an onset), 11 s
    assert [(e[0], e[1]) for e in events] == [(3.0, "WARN"), (8.0, "WARN"), (11.0, "DEBUG")]


def test_a_layer_event_ignores_a_nan_share() -> None:
    events = layer_events(np.array([0.0]), np.array([[np.nan, 1.0]]), ["hard", "soft"])
    assert events[0][2].startswith("bit in soft")


def test_a_layer_event_names_an_unnamed_rock_by_its_index() -> None:
    """LayerDetector: a rock past the names given is called ``rock<j>``."""
    events = layer_events(np.array([0.0]), np.array([[0.0, 0.0, 1.0]]), ["hard"])
    assert events[0][2].startswith("bit in rock2")


def test_the_whirl_detector_refuses_a_clearance_that_is_not_positive() -> None:
    """WhirlDetector: the radial ratio divides by the clearance, which must be > 0."""
    for clearance in (0.0, -CLEARANCE):
        with pytest.raises(ValueError, match=r"^clearance: must be > 0"):
            WhirlDetector(clearance)


def _orbit(t: np.ndarray, radial: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    r = radial * CLEARANCE
    return r * np.cos(3.0 * t), r * np.sin(3.0 * t)


def test_whirl_shorter_than_the_hold_time_is_no_whirl() -> None:
    t = np.arange(0.0, 4.0, 0.1)
    radial = np.full_like(t, 0.1)
    radial[10:13] = 0.9  # 0.2 s on the wall, under WHIRL_MIN_DURATION
    assert WHIRL_MIN_DURATION > 0.25
    x, y = _orbit(t, radial)
    assert whirl_events(t, x, y, np.full_like(t, -40.0), np.full_like(t, 5.0),
                        CLEARANCE) == []


def test_whirl_held_longer_than_the_hold_time_is_an_event_dated_at_its_start() -> None:
    """docs/recording.md: the rule held for 0.3 s is an onset, off for 0.3 s an end. A
    backward whirl on the wall for 0.4 s (1.0-1.4 s) is one onset at 1.0 s and its end."""
    t = np.arange(0.0, 3.0, 0.01)
    radial = np.where((t >= 1.0) & (t < 1.4), 0.9, 0.1)
    whirl = np.full_like(t, -40.0)  # rad/s, the orbit turning backward
    angle = np.cumsum(whirl) * 0.01
    x, y = radial * CLEARANCE * np.cos(angle), radial * CLEARANCE * np.sin(angle)
    events = whirl_events(t, x, y, whirl, np.full_like(t, 5.0), CLEARANCE)
    assert [e[2].split(":")[0] for e in events] == ["whirl onset (backward)", "whirl ended"]
    assert events[0][0] == pytest.approx(1.0)


def test_a_stick_after_five_quiet_seconds_is_a_new_stick_slip_onset() -> None:
    """docs/recording.md: a stick after 5 s without one starts a new episode (WARN); one
    4 s after the last continues it (DEBUG)."""
    assert STICK_SLIP_QUIET == 5.0
    t = np.arange(0.0, 20.0, 0.1)
    w = np.full_like(t, 5.0)
    for start in (1.0, 5.0, 11.0):  # 4 s, then 6 s after the one before
        w[(t >= start) & (t < start + 0.3)] = 0.0
    assert [(e[0], e[1]) for e in stick_slip_events(t, w)] == [
        (pytest.approx(1.0), "WARN"), (pytest.approx(5.0), "DEBUG"),
        (pytest.approx(11.0), "WARN")]


def test_the_whirl_direction_is_that_of_most_samples_since_the_onset() -> None:
    """Backward whirl with one sample's whirl speed reversed: the angle it travels turns
    back by none of the rule's 90 degrees, so the sample belongs to the backward leg and
    the onset says backward, as :func:`drill_env.metrics.whirl_direction`."""
    t = np.arange(0.0, 2.0, 0.1)
    radial = np.full_like(t, 0.9)
    x, y = _orbit(t, radial)
    whirl_speed = np.full_like(t, -40.0)
    whirl_speed[3] = 40.0
    bit_speed = np.full_like(t, 5.0)
    events = whirl_events(t, x, y, whirl_speed, bit_speed, CLEARANCE)
    assert events[0][2].startswith("whirl onset (backward)")
    assert whirl_direction(whirl_speed[:4], bit_speed[:4], radial[:4], 0.1) == "backward"


def test_a_whirl_onset_with_as_many_samples_each_way_names_neither(monkeypatch) -> None:
    """Signs that tie over the held samples (four of 0.125 s: +, -, +, -) are "none" by
    the metrics' rule (:func:`drill_env.metrics.direction_of`); the onset, which named
    them backward, says as many forward as backward."""
    import drill_env.events as events

    t = np.arange(0.0, 2.0, 0.125)
    assert 2 * 0.125 < WHIRL_MIN_DURATION <= 3 * 0.125  # held at the fourth sample
    signs = np.where(np.arange(t.size) % 2 == 0, 1.0, -1.0)
    monkeypatch.setattr(events, "whirl_signs", lambda *signal: signs)
    x, y = _orbit(t, np.full_like(t, 0.9))
    said = whirl_events(t, x, y, np.full_like(t, 3.0), np.full_like(t, 5.0), CLEARANCE)
    assert said[0][2].startswith("whirl onset (as many forward as backward)")
    assert direction_of(float(signs[:4].sum())) == "none"


def test_whirl_fed_step_by_step_is_judged_with_the_seconds_before_and_after() -> None:
    """A forward whirl at 0.6 of the bit speed takes ~1 s to travel the rule's half turn;
    fed in 0.1 s chunks (an env step) the detector dates it, as the whole array does, from
    the start of the orbit (it had dated it from the chunk that completed the half turn,
    ~1 s late), and says so once WHIRL_CONTEXT seconds have come after that start."""
    t = np.arange(0.0, 6.0, 0.01)
    radial = np.full_like(t, 0.9)
    x, y = _orbit(t, radial)
    ws, w = np.full_like(t, 3.0), np.full_like(t, 5.0)
    whole = whirl_events(t, x, y, ws, w, CLEARANCE)
    assert [e[2].split(":")[0] for e in whole] == ["whirl onset (forward)"]
    assert whole[0][0] == 0.0
    detector = WhirlDetector(CLEARANCE)
    said_at = []
    chunked = []
    for k in range(0, t.size, 10):
        found = detector.update(t[k:k + 10], x[k:k + 10], y[k:k + 10], ws[k:k + 10],
                                w[k:k + 10])
        said_at += [t[min(k + 9, t.size - 1)]] * len(found)
        chunked += found
    assert detector.finish() == []
    assert chunked == whole
    # the onset held WHIRL_MIN_DURATION, then WHIRL_CONTEXT more came (one chunk late)
    assert WHIRL_CONTEXT + WHIRL_MIN_DURATION <= said_at[0] <= \
        WHIRL_CONTEXT + WHIRL_MIN_DURATION + 0.1


def test_a_slow_whirl_fed_in_chunks_is_dated_as_the_whole_signal_dates_it() -> None:
    """A review: a 10 rpm whirl on a 29 rpm bit (the rule takes down to a quarter of the
    bit speed) takes 3 s to go half a turn: with 2 s of context, fed in 0.1 s chunks, it
    was dated 6.1 s to 12.9 s where the whole signal says 5.0 s to 14.0 s. With
    WHIRL_CONTEXT 4 s every whirl of 7.5 rpm or more is dated as the whole signal."""
    from drill_env.physics.units import RPM

    assert 0.5 * 2.0 * np.pi / (7.5 * RPM) <= WHIRL_CONTEXT  # half a turn at 7.5 rpm
    t = np.arange(0.0, 20.0, 0.01)
    on = (t >= 5.0) & (t < 14.0)
    radial = np.where(on, 0.9, 0.1)
    ws = np.full_like(t, 7.6 * RPM)
    w = np.full_like(t, 29.0 * RPM)
    angle = np.cumsum(ws) * 0.01
    x, y = radial * CLEARANCE * np.cos(angle), radial * CLEARANCE * np.sin(angle)
    whole = whirl_events(t, x, y, ws, w, CLEARANCE)
    assert [(e[0], e[2].split(":")[0]) for e in whole] == [
        (5.0, "whirl onset (forward)"), (pytest.approx(14.0), "whirl ended")]
    detector = WhirlDetector(CLEARANCE)
    chunked = [e for k in range(0, t.size, 10) for e in detector.update(
        t[k:k + 10], x[k:k + 10], y[k:k + 10], ws[k:k + 10], w[k:k + 10])]
    assert chunked + detector.finish() == whole


def test_whirl_events_left_at_the_end_come_with_finish() -> None:
    """A whirl in the last WHIRL_CONTEXT seconds of a signal is judged at ``finish``."""
    t = np.arange(0.0, 3.0, 0.01)
    radial = np.where(t > 1.5, 0.9, 0.1)
    x, y = _orbit(t, radial)
    ws, w = np.full_like(t, 3.0), np.full_like(t, 5.0)
    detector = WhirlDetector(CLEARANCE)
    assert detector.update(t, x, y, ws, w) == []
    events = detector.finish()
    assert [e[2].split(":")[0] for e in events] == ["whirl onset (forward)"]
    assert events == whirl_events(t, x, y, ws, w, CLEARANCE)
    assert detector.finish() == []  # each sample judged once
