"""Unit constants: SI inside the code; rpm, kN, inches only at the edges (CLI, tables).

Multiply to convert into SI (``50 * RPM`` is 50 rpm in rad/s), divide to convert out
(``omega / RPM``).
"""

from __future__ import annotations

import math

#: One revolution per minute in rad/s.
RPM = 2.0 * math.pi / 60.0
#: One inch in metres.
INCH = 0.0254
#: One foot in metres.
FOOT = 0.3048
#: One kilonewton in newtons (also kN m in N m).
KILO = 1.0e3
#: One megapascal in pascals (also MJ in J).
MEGA = 1.0e6
#: Seconds per hour (m/s -> m/h: multiply by HOUR).
HOUR = 3600.0
#: Gravity (m/s^2), to three figures (standard gravity, 9.80665, is 0.03 % less).
GRAVITY = 9.81
#: One pound-force per square inch in pascals (pipe grades: 135,000 psi is 931 MPa).
PSI = 6894.757


def shown(fmt: str, value: float) -> str:
    """``fmt.format(value)`` for a table or the console, never a negative zero ("-0.0",
    "-0%"): a finite value that rounds to zero is shown as zero, in the same width if
    ``fmt`` pads; -inf keeps its sign."""
    text = fmt.format(value)
    pad = len(text) - len(text.lstrip())
    if math.isfinite(value) and text[pad:].startswith("-") and not any(
            ch in "123456789" for ch in text):
        text = " " + text[:pad] + text[pad + 1:] if pad else text[1:]
    return text


#: How many items a one-line list on the console or in a report shows (:func:`few`).
FEW = 12


def few(items: list[str], more: str) -> str:
    """``items`` joined by commas, at most :data:`FEW` + 2 of them: else the first and last
    halves, with how many were left out between, and ``more``, where they all are (a 10 h
    run printed 1,200 swings on one line, a 200-seed benchmark 199 episodes in a note: a
    scale trial)."""
    if len(items) <= FEW + 2:  # (hiding one or two saves nothing)
        return ", ".join(items)
    half = FEW // 2
    return ", ".join([*items[:half], f"... {len(items) - FEW} more {more} ...",
                      *items[-half:]])
