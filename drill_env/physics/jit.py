"""Compilation options shared by the numba kernels, and :func:`claim`, the one atomic
operation they use (numba has none on the CPU).

:data:`TUPLE_KERNEL` is for kernels that take named tuples of arrays (the layouts of
:mod:`drill_env.physics.layout`): taking an array out of a tuple costs an atomic
reference-count increment and decrement, and in the step loop those made the torsion-only
step 35 % slower (590 -> 790 ns). These kernels allocate nothing, so numba's runtime
(NRT) and its reference counts are switched off for them (``_nrt=False``, a numba
option not in its type stubs, hence the dict).
"""

from __future__ import annotations

from typing import Any

from numba import config, types
from numba.core import cgutils
from numba.extending import intrinsic

TUPLE_KERNEL: dict[str, Any] = {"cache": True, "nogil": True, "_nrt": False}


@intrinsic
def claim(typingctx: Any, counter: Any) -> Any:
    """``counter[0] += 1`` as one atomic operation; returns the value before. For a
    ``prange`` over worker lanes that take the next item from a shared counter (dynamic
    scheduling, :func:`drill_env.batching.step_many`); numba exposes no CPU atomics.
    ``counter``: a writable one-dimensional int64 array; element 0 is the counter."""
    if not (isinstance(counter, types.Array) and counter.dtype == types.int64
            and counter.ndim == 1 and counter.mutable):
        return None

    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        array_type = signature.args[0]
        array = context.make_array(array_type)(context, builder, args[0])
        first = cgutils.get_item_pointer(context, builder, array_type, array,
                                         [context.get_constant(types.intp, 0)])
        return builder.atomic_rmw("add", first, context.get_constant(types.int64, 1),
                                  "monotonic")

    return types.int64(counter), codegen


def _claim_uncompiled(counter: Any) -> Any:
    """:func:`claim` in plain Python: ``counter[0] += 1``, the value before (no other
    thread runs uncompiled code's lanes)."""
    before = counter[0]
    counter[0] += 1
    return before


if getattr(config, "DISABLE_JIT", False):  # NUMBA_DISABLE_JIT=1 (debugging in plain
    # Python): an intrinsic cannot run uncompiled, and every batched env step failed with
    # numba's "not usable in pure-python"
    claim = _claim_uncompiled  # type: ignore[assignment]
