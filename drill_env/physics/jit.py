"""Compilation options shared by the numba kernels.

:data:`TUPLE_KERNEL` is for kernels that take named tuples of arrays (the layouts of
:mod:`drill_env.physics.layout`): taking an array out of a tuple costs an atomic
reference-count increment and decrement, and in the step loop those made the torsion-only
step 35 % slower (590 -> 790 ns). These kernels allocate nothing, so numba's runtime
(NRT) and its reference counts are switched off for them (``_nrt=False``, a numba
option not in its type stubs, hence the dict).
"""

from __future__ import annotations

from typing import Any

TUPLE_KERNEL: dict[str, Any] = {"cache": True, "nogil": True, "_nrt": False}
