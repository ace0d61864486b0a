"""Small banded linear-algebra kernels (numba) for symmetric positive-definite matrices.

Storage: upper band, ``band[d, i] = A[i, i + d]`` for d = 0..p. The Cholesky factor U
(A = U^T U, U upper with bandwidth p) uses the same layout, with its diagonal stored
inverted so that the per-step solves only multiply.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np
from numba import njit


@functools.cache
def _blas_controller() -> Any:
    from threadpoolctl import ThreadpoolController

    return ThreadpoolController()  # (once: it looks the loaded libraries up, ~1 ms)


def one_blas_thread() -> Any:
    """A context in which NumPy's and SciPy's BLAS and LAPACK run on one thread
    (``threadpoolctl``): the dense eigenproblems of the modal analysis and the stability
    thresholds are a few hundred rows, where OpenBLAS's threads only wait on one another,
    and on a machine another job shares they spin: ``drill-env modes`` of the default
    string took 15-23 s against 4.5 s on one thread (a new user's trial, 2026-12-07: 128 s
    against 4.3 s for a 2,160 m string beside a test suite)."""
    return _blas_controller().limit(limits=1, user_api="blas")


@njit(cache=True)
def band_cholesky(band, factor):
    """Factor the SPD band matrix ``band`` into ``factor``; returns False if not SPD."""
    p = band.shape[0] - 1
    n = band.shape[1]
    for i in range(n):
        s = band[0, i]
        for k in range(max(0, i - p), i):
            u = factor[i - k, k]
            s -= u * u
        if not s > 0.0:
            return False
        diag = np.sqrt(s)
        factor[0, i] = 1.0 / diag
        for j in range(i + 1, min(n, i + p + 1)):
            s = band[j - i, i]
            for k in range(max(0, j - p), i):
                s -= factor[i - k, k] * factor[j - k, k]
            factor[j - i, i] = s / diag
        for d in range(min(n, i + p + 1) - i, p + 1):
            factor[d, i] = 0.0
    return True


def ldl_factor(band: np.ndarray, what: str) -> np.ndarray:
    """The LDL^T factor (:func:`cholesky_to_ldl`) of the SPD band matrix ``band``;
    ValueError naming ``what`` if it is not positive definite."""
    factor = np.zeros_like(band)
    if not band_cholesky(band, factor):
        raise ValueError(f"{what} is not positive definite")
    cholesky_to_ldl(factor)
    return factor


# --------------------------------------------------------------------------- fast paths
#: No fastmath: reassociation and FMA contraction let LLVM compile the same kernel into
#: different operation orders depending on where it was inlined and on whether the code
#: came from the JIT or numba's cache, so the batched and single-env paths, or a fresh and
#: a cached process, drilled slightly different trajectories (tests/physics/
#: test_determinism.py, test_batch.py). Measured without it: the same speed (the solves
#: are latency-bound chains either way).
# The lateral matrices always have half bandwidth 3 (two DOFs per node, Hermite beams)
# and torsion bandwidth 1. The lateral kernels below work on PLANE-MAJOR arrays of shape
# (2, n): each bending plane is one contiguous vector, so the band products run as
# unit-stride loops along each diagonal that LLVM vectorises. Tests check them against
# the generic kernels and numpy.


@njit(cache=True)
def lateral_residual(k_total, k_damp, ul, vl, lat_m, mass_damping, rl):
    """rl -= K_total ul + K_damp vl + mass_damping * M vl, plane-major (2, n), bandwidth 3.

    ``k_damp`` is b K (stiffness-proportional damping) in the same band layout. The
    symmetric product is taken diagonal by diagonal: each stored diagonal d acts on
    rows i (with column i + d) and on rows i + d (with column i).
    """
    n = ul.shape[1]
    for c in range(2):
        u = ul[c]
        v = vl[c]
        r = rl[c]
        for i in range(n):
            r[i] -= k_total[0, i] * u[i] + (k_damp[0, i] + mass_damping * lat_m[i]) * v[i]
        for d in range(1, 4):
            kt = k_total[d]
            kd = k_damp[d]
            for i in range(n - d):
                r[i] -= kt[i] * u[i + d] + kd[i] * v[i + d]
            for i in range(n - d):
                r[i + d] -= kt[i] * u[i] + kd[i] * v[i]


@njit(cache=True)
def cholesky_to_ldl(factor):
    """Rewrite ``band_cholesky``'s factor U (A = U^T U) in place as A = W^T D W.

    W is unit upper triangular, ``factor[d, i] = W[i, i + d]`` for d >= 1, and
    ``factor[0, i] = 1 / D_i = 1 / U_ii^2``. With a unit diagonal each row of the
    triangular solves depends on the previous row through one multiply-add only, which
    halves the latency chain of :func:`solve3_planes`.
    """
    p = factor.shape[0] - 1
    n = factor.shape[1]
    for i in range(n):
        inv_u = factor[0, i]  # band_cholesky stores 1 / U_ii
        for d in range(1, p + 1):
            factor[d, i] *= inv_u
        factor[0, i] = inv_u * inv_u


@njit(cache=True)
def solve3_planes(factor, b):
    """Solve A X = B in place for plane-major B (2, n), half bandwidth 3, LDL^T factor.

    ``factor`` comes from :func:`cholesky_to_ldl`. Both planes are solved in the same
    sweep so their independent chains overlap.
    """
    n = b.shape[1]
    x = b[0]
    y = b[1]
    for i in range(1, min(n, 3)):  # W^T z = b, first rows
        for k in range(0, i):
            f = factor[i - k, k]
            x[i] -= f * x[k]
            y[i] -= f * y[k]
    # The last three solved values ride in registers (x1..x3, y1..y3): reading them back
    # from memory would add a store-to-load delay to every row's dependency chain.
    if n > 3:
        x1, x2, x3 = x[2], x[1], x[0]
        y1, y2, y3 = y[2], y[1], y[0]
        for i in range(3, n):
            tx = x[i] - factor[3, i - 3] * x3 - factor[2, i - 2] * x2
            ty = y[i] - factor[3, i - 3] * y3 - factor[2, i - 2] * y2
            f1 = factor[1, i - 1]
            x3, x2 = x2, x1
            y3, y2 = y2, y1
            x1 = tx - f1 * x1
            y1 = ty - f1 * y1
            x[i] = x1
            y[i] = y1
    for i in range(n):  # z <- D^-1 z
        x[i] *= factor[0, i]
        y[i] *= factor[0, i]
    for i in range(n - 2, max(n - 4, -1), -1):  # W x = z, last rows
        for j in range(i + 1, n):
            f = factor[j - i, i]
            x[i] -= f * x[j]
            y[i] -= f * y[j]
    if n > 3:
        x1, x2, x3 = x[n - 3], x[n - 2], x[n - 1]
        y1, y2, y3 = y[n - 3], y[n - 2], y[n - 1]
        for i in range(n - 4, -1, -1):
            tx = x[i] - factor[3, i] * x3 - factor[2, i] * x2
            ty = y[i] - factor[3, i] * y3 - factor[2, i] * y2
            f1 = factor[1, i]
            x3, x2 = x2, x1
            y3, y2 = y2, y1
            x1 = tx - f1 * x1
            y1 = ty - f1 * y1
            x[i] = x1
            y[i] = y1


@njit(cache=True)
def torsion_residual(k_band, k_damp_scale, c_diag, ut, vt, rt):
    """rt -= K ut + b K vt + diag(c) vt for a tridiagonal K (band layout, bandwidth 1)."""
    n = ut.shape[0]
    for i in range(n):
        rt[i] -= k_band[0, i] * (ut[i] + k_damp_scale * vt[i]) + c_diag[i] * vt[i]
    for i in range(n - 1):
        k = k_band[1, i]
        rt[i] -= k * (ut[i + 1] + k_damp_scale * vt[i + 1])
        rt[i + 1] -= k * (ut[i] + k_damp_scale * vt[i])


@njit(cache=True)
def solve_tridiagonal(factor, b):
    """Solve A x = b in place for a tridiagonal SPD A, given its LDL^T factor.

    ``factor`` comes from :func:`band_cholesky` followed by :func:`cholesky_to_ldl`. The
    running value stays in a register, so each row costs one multiply-add of latency.
    """
    n = b.shape[0]
    prev = b[0]
    for i in range(1, n):
        prev = b[i] - factor[1, i - 1] * prev
        b[i] = prev
    for i in range(n):
        b[i] *= factor[0, i]
    prev = b[n - 1]
    for i in range(n - 2, -1, -1):
        prev = b[i] - factor[1, i] * prev
        b[i] = prev


def twisted_tridiagonal(band: np.ndarray, what: str) -> np.ndarray:
    """The twisted factor of the SPD tridiagonal ``band`` for :func:`solve_twisted`;
    ValueError naming ``what`` if it is not positive definite.

    Rows above the middle row m = n // 2 are eliminated downwards, rows below it
    upwards, and the two halves meet at m (a "BABE" or twisted factorisation; Parlett &
    Dhillon, Lin. Alg. Appl. 309, 2000). The solve then runs two independent chains of
    n / 2 rows instead of one of n. Layout (2, n): row 0 the inverse pivots, row 1 the
    multipliers, ``[1, j] = e_j / d_j`` for j < m (downwards) and ``e_j / d_{j + 1}``
    for j >= m (upwards), with e_j = A[j, j + 1].
    """
    n = band.shape[1]
    a, e = band[0].tolist(), band[1].tolist()
    mid = n // 2
    factor = np.zeros((2, n))

    def checked(pivot: float) -> float:
        # the factor is congruent to A: all pivots positive iff A is (Sylvester)
        if not pivot > 0.0:
            raise ValueError(f"{what} is not positive definite")
        return pivot

    for i in range(mid):
        pivot = checked(a[i] - (e[i - 1] * factor[1, i - 1] if i > 0 else 0.0))
        factor[0, i] = 1.0 / pivot
        factor[1, i] = e[i] / pivot
    for i in range(n - 1, mid, -1):
        pivot = checked(a[i] - (e[i] * factor[1, i] if i < n - 1 else 0.0))
        factor[0, i] = 1.0 / pivot
        factor[1, i - 1] = e[i - 1] / pivot
    pivot = a[mid]
    if mid > 0:
        pivot -= e[mid - 1] * factor[1, mid - 1]
    if mid < n - 1:
        pivot -= e[mid] * factor[1, mid]
    factor[0, mid] = 1.0 / checked(pivot)
    return factor


@njit(cache=True)
def solve_twisted(factor, b):
    """Solve A x = b in place with the twisted factor of :func:`twisted_tridiagonal`.

    The two halves' sweeps are independent chains run in one loop, so each costs half
    the latency of :func:`solve_tridiagonal`'s single chain; the arithmetic differs from
    it only by rounding.
    """
    n = b.shape[0]
    mid = n // 2
    f = factor[1]
    # eliminate: rows 1..mid-1 downwards, rows n-2..mid+1 upwards, in lockstep
    down = b[0]
    up = b[n - 1]
    for k in range(1, max(mid, n - 1 - mid)):
        i = k
        j = n - 1 - k
        if i < mid:
            down = b[i] - f[i - 1] * down
            b[i] = down
        if j > mid:
            up = b[j] - f[j] * up
            b[j] = up
    x = b[mid]
    if mid > 0:
        x -= f[mid - 1] * b[mid - 1]
    if mid < n - 1:
        x -= f[mid] * b[mid + 1]
    x *= factor[0, mid]
    b[mid] = x
    # back-substitute outwards from the middle
    down = x
    up = x
    for k in range(1, max(mid + 1, n - mid)):
        i = mid - k
        j = mid + k
        if i >= 0:
            down = b[i] * factor[0, i] - f[i] * down
            b[i] = down
        if j < n:
            up = b[j] * factor[0, j] - f[j - 1] * up
            b[j] = up


@njit(cache=True)
def ldl_inverse_band(factor):
    """The band of A^-1 (``out[d, i] = Z[i, i + d]``, Z = A^-1) from A's LDL^T factor
    (:func:`cholesky_to_ldl`), in O(n p^2) without forming Z (Takahashi's recurrence).

    From A = W^T D W: W Z = D^-1 W^-T, whose upper triangle is diag(1 / D). So, for
    j >= i, ``Z[i, j] = [i == j] / D_i - sum_{e=1..p} W[i, i + e] Z[i + e, j]``, and the
    rows below i give every Z[i + e, j] the band needs (|i + e - j| < p).
    """
    p = factor.shape[0] - 1
    n = factor.shape[1]
    out = np.empty_like(factor)
    for i in range(n - 1, -1, -1):
        for d in range(p, -1, -1):
            j = i + d
            if j >= n:
                out[d, i] = 0.0
                continue
            s = factor[0, i] if d == 0 else 0.0
            for e in range(1, min(p, n - 1 - i) + 1):
                k = i + e
                z = out[j - k, k] if k <= j else out[k - j, j]
                s -= factor[e, i] * z
            out[d, i] = s
    return out
