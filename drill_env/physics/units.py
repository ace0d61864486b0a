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
#: One kilonewton in newtons (also kN m in N m).
KILO = 1.0e3
#: Seconds per hour (m/s -> m/h: multiply by HOUR).
HOUR = 3600.0
#: Standard gravity (m/s^2).
GRAVITY = 9.81
