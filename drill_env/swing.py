"""Does a stick-slip grow or decay? The bit-speed swing per block of time and its trend:
what a tuning run reads (docs/controllers.md's SoftSpeed k table) and what marks a
benchmark row whose metric window is too short to show a slowly growing stick-slip."""

from __future__ import annotations

from collections.abc import Sequence

#: Seconds per block of :func:`swing_per_block` (docs/controllers.md's k table: the swing
#: per 30 s from a small kick tells a growing stick-slip from a decaying one).
SWING_BLOCK = 30.0
#: A swing below this (rpm) is no oscillation to speak of (a steady bit reads ~1e-3).
NO_SWING = 0.01
#: A bit slower than this (rpm) at some sample of a block has stopped: stick-slip.
STOPPED = 0.5


def swing_per_block(speeds: Sequence[tuple[float, float]]) -> list[float]:
    """Half of (max - min) of the bit speed in each whole ``SWING_BLOCK`` of an episode,
    from its (time s, rpm) samples."""
    blocks: dict[int, list[float]] = {}
    for t, rpm in speeds:
        blocks.setdefault(int(t // SWING_BLOCK), []).append(rpm)
    end = speeds[-1][0] if speeds else 0.0
    whole = int((end + 1e-6) // SWING_BLOCK)  # the last block only if the episode filled it
    return [round(0.5 * (max(blocks[k]) - min(blocks[k])), 6) for k in range(whole)
            if blocks.get(k)]


def is_growing(trend: str) -> bool:
    """Whether a :func:`swing_trend` text (a benchmark row's ``swing_trend``) says growing."""
    return trend.startswith("growing")


def swing_trend(swings: Sequence[float], lowest_rpm: float,
                block: float = SWING_BLOCK) -> str:
    """What the last two blocks' swings say: full stick-slip (the bit stops: its lowest
    speed in the last block, ``lowest_rpm``, under :data:`STOPPED`), none to speak of
    (about :data:`NO_SWING` or less), growing or decaying (by more than 10 % per block of
    ``block`` s, with the factor) or steady."""
    last, before = swings[-1], swings[-2]
    if lowest_rpm < STOPPED:
        return "full stick-slip (the bit stops)"
    if last < NO_SWING:  # rounding, not an oscillation: no ratio of two such to quote
        return f"none to speak of (below {NO_SWING:g} rpm)"
    if before < NO_SWING:  # no ratio of rounding to quote; 10 % above the floor to grow
        # (0.0099 -> 0.0101 rpm read as growing)
        return (f"growing (from below {NO_SWING:g} rpm)" if last > 1.1 * NO_SWING
                else f"none to speak of (about {NO_SWING:g} rpm)")
    ratio = last / before
    # not 2.7e+02, nor x1,224 (read as x1.224 where the comma is the decimal mark)
    factor = f"{ratio:.2g}" if ratio < 100.0 else f"{ratio:.0f}"
    if last > 1.1 * before:
        return f"growing (x{factor} per {block:g} s)"
    if last < 0.9 * before:
        return f"decaying (x{factor} per {block:g} s)"
    return "steady"
