"""A bit or a stabilizer against the hole it runs in: refused when larger, said when
much smaller (a size typed for another hole)."""

from __future__ import annotations

import warnings

from drill_env.physics.units import INCH
from drill_env.physics.validation import caller_outside

#: How far (m) a bit may be under its hole before it is said: a bit drills a hole of its
#: own size, which a washout widens by a fraction of an inch; an inch is no washout.
BIT_UNDER_HOLE = INCH


def check_bit_in_hole(bit: float, hole: float) -> None:
    """ValueError naming ``bit.diameter`` where the bit (m) is larger than the hole; a
    warning where it is more than :data:`BIT_UNDER_HOLE` smaller (a new user's 12 1/4 in
    hole drilled on by the default 8 3/4 in bit without a word)."""
    if bit > hole + 1e-12:
        raise ValueError(f"bit.diameter: {bit} m must not exceed string.hole_diameter "
                         f"({hole} m); set it for this hole (the default bit is 8 3/4 in)")
    warn_under_hole("bit.diameter", bit, hole, BIT_UNDER_HOLE, "a bit drills a hole of its "
                    "own size; set bit.diameter for this hole (the default bit is 8 3/4 in)")


def warn_under_hole(name: str, size: float, hole: float, limit: float, why: str) -> None:
    """UserWarning ``name``: ``size`` (m) more than ``limit`` under ``hole``, then ``why``."""
    if size < hole - limit:
        warnings.warn(f"{name}: {size:.4g} m ({size / INCH:.4g} in) is {(hole - size) / INCH:.3g}"
                      f" in under string.hole_diameter ({hole:.4g} m): {why}", UserWarning,
                      stacklevel=caller_outside())
