"""Small banded linear-algebra kernels (numba) for symmetric positive-definite matrices.

Storage: upper band, ``band[d, i] = A[i, i + d]`` for d = 0..p. The Cholesky factor U
(A = U^T U, U upper with bandwidth p) uses the same layout, with its diagonal stored
inverted so that the per-step solves only multiply.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def band_cholesky(band, out):
    """Factor the SPD band matrix ``band`` into ``out``; returns False if not SPD."""
    p = band.shape[0] - 1
    n = band.shape[1]
    for i in range(n):
        s = band[0, i]
        for k in range(max(0, i - p), i):
            u = out[i - k, k]
            s -= u * u
        if not s > 0.0:
            return False
        diag = np.sqrt(s)
        out[0, i] = 1.0 / diag
        for j in range(i + 1, min(n, i + p + 1)):
            s = band[j - i, i]
            for k in range(max(0, j - p), i):
                s -= out[i - k, k] * out[j - k, k]
            out[j - i, i] = s / diag
        for d in range(min(n, i + p + 1) - i, p + 1):
            out[d, i] = 0.0
    return True


@njit(cache=True)
def band_solve(factor, b):
    """Solve A x = b in place for a vector b, given ``band_cholesky``'s factor."""
    p = factor.shape[0] - 1
    n = factor.shape[1]
    for i in range(n):  # U^T y = b
        s = b[i]
        for k in range(max(0, i - p), i):
            s -= factor[i - k, k] * b[k]
        b[i] = s * factor[0, i]
    for i in range(n - 1, -1, -1):  # U x = y
        s = b[i]
        for j in range(i + 1, min(n, i + p + 1)):
            s -= factor[j - i, i] * b[j]
        b[i] = s * factor[0, i]


@njit(cache=True)
def band_solve2(factor, b):
    """Solve A X = B in place for B of shape (n, 2): the two bending planes at once."""
    p = factor.shape[0] - 1
    n = factor.shape[1]
    for i in range(n):
        s0 = b[i, 0]
        s1 = b[i, 1]
        for k in range(max(0, i - p), i):
            f = factor[i - k, k]
            s0 -= f * b[k, 0]
            s1 -= f * b[k, 1]
        b[i, 0] = s0 * factor[0, i]
        b[i, 1] = s1 * factor[0, i]
    for i in range(n - 1, -1, -1):
        s0 = b[i, 0]
        s1 = b[i, 1]
        for j in range(i + 1, min(n, i + p + 1)):
            f = factor[j - i, i]
            s0 -= f * b[j, 0]
            s1 -= f * b[j, 1]
        b[i, 0] = s0 * factor[0, i]
        b[i, 1] = s1 * factor[0, i]


@njit(cache=True)
def band_matvec_sub(band, x, y, scale):
    """y -= scale * A x for a symmetric band matrix and vectors x, y."""
    p = band.shape[0] - 1
    n = band.shape[1]
    for i in range(n):
        s = band[0, i] * x[i]
        for d in range(1, p + 1):
            if i + d < n:
                s += band[d, i] * x[i + d]
            if i - d >= 0:
                s += band[d, i - d] * x[i - d]
        y[i] -= scale * s


@njit(cache=True)
def band_matvec_sub2(band, x, y, scale):
    """y -= scale * A x for x, y of shape (n, 2)."""
    p = band.shape[0] - 1
    n = band.shape[1]
    for i in range(n):
        s0 = band[0, i] * x[i, 0]
        s1 = band[0, i] * x[i, 1]
        for d in range(1, p + 1):
            if i + d < n:
                a = band[d, i]
                s0 += a * x[i + d, 0]
                s1 += a * x[i + d, 1]
            if i - d >= 0:
                a = band[d, i - d]
                s0 += a * x[i - d, 0]
                s1 += a * x[i - d, 1]
        y[i, 0] -= scale * s0
        y[i, 1] -= scale * s1


# --------------------------------------------------------------------------- fast paths
#: Reassociation lets LLVM split the long dependent sums of a band row into parallel
#: chains (the kernels are latency-bound otherwise); NaN/inf semantics are kept, so the
#: integrator's divergence checks still see a non-finite state.
FAST = {"reassoc", "contract"}
# The lateral matrices always have half bandwidth 3 (two DOFs per node, Hermite beams)
# and torsion bandwidth 1. These unrolled versions avoid the generic loops' bounds
# branches; tests check them against the generic kernels and numpy.


@njit(cache=True, fastmath=FAST)
def _lateral_row(k_total, k_damp, ul, vl, i, n):
    s0 = k_total[0, i] * ul[i, 0] + k_damp[0, i] * vl[i, 0]
    s1 = k_total[0, i] * ul[i, 1] + k_damp[0, i] * vl[i, 1]
    for d in range(1, 4):
        j = i + d
        if j < n:
            s0 += k_total[d, i] * ul[j, 0] + k_damp[d, i] * vl[j, 0]
            s1 += k_total[d, i] * ul[j, 1] + k_damp[d, i] * vl[j, 1]
        j = i - d
        if j >= 0:
            s0 += k_total[d, j] * ul[j, 0] + k_damp[d, j] * vl[j, 0]
            s1 += k_total[d, j] * ul[j, 1] + k_damp[d, j] * vl[j, 1]
    return s0, s1


@njit(cache=True, fastmath=FAST)
def lateral_residual(k_total, k_damp, ul, vl, lat_m, mass_damping, rl):
    """rl -= K_total ul + K_damp vl + mass_damping * M vl, for (n, 2) arrays, bandwidth 3.

    ``k_damp`` is b K (stiffness-proportional damping) in the same band layout. The
    interior rows are unrolled without bounds branches; the three rows at each end take
    the generic path.
    """
    n = ul.shape[0]
    for i in range(n):
        m = mass_damping * lat_m[i]
        rl[i, 0] -= m * vl[i, 0]
        rl[i, 1] -= m * vl[i, 1]
    edge = min(3, n)
    for i in range(edge):
        s0, s1 = _lateral_row(k_total, k_damp, ul, vl, i, n)
        rl[i, 0] -= s0
        rl[i, 1] -= s1
    for i in range(max(edge, n - 3), n):
        s0, s1 = _lateral_row(k_total, k_damp, ul, vl, i, n)
        rl[i, 0] -= s0
        rl[i, 1] -= s1
    for i in range(3, n - 3):
        a0 = k_total[0, i]
        a1 = k_total[1, i]
        a2 = k_total[2, i]
        a3 = k_total[3, i]
        b1 = k_total[1, i - 1]
        b2 = k_total[2, i - 2]
        b3 = k_total[3, i - 3]
        c0 = k_damp[0, i]
        c1 = k_damp[1, i]
        c2 = k_damp[2, i]
        c3 = k_damp[3, i]
        e1 = k_damp[1, i - 1]
        e2 = k_damp[2, i - 2]
        e3 = k_damp[3, i - 3]
        for c in range(2):
            rl[i, c] -= (a0 * ul[i, c] + a1 * ul[i + 1, c] + a2 * ul[i + 2, c]
                         + a3 * ul[i + 3, c] + b1 * ul[i - 1, c] + b2 * ul[i - 2, c]
                         + b3 * ul[i - 3, c]
                         + c0 * vl[i, c] + c1 * vl[i + 1, c] + c2 * vl[i + 2, c]
                         + c3 * vl[i + 3, c] + e1 * vl[i - 1, c] + e2 * vl[i - 2, c]
                         + e3 * vl[i - 3, c])


@njit(cache=True, fastmath=FAST)
def solve3_pair(factor, b):
    """band_solve2 specialised to half bandwidth 3."""
    n = b.shape[0]
    for i in range(min(n, 3)):
        s0 = b[i, 0]
        s1 = b[i, 1]
        for k in range(0, i):
            f = factor[i - k, k]
            s0 -= f * b[k, 0]
            s1 -= f * b[k, 1]
        b[i, 0] = s0 * factor[0, i]
        b[i, 1] = s1 * factor[0, i]
    for i in range(3, n):
        f1 = factor[1, i - 1]
        f2 = factor[2, i - 2]
        f3 = factor[3, i - 3]
        s0 = b[i, 0] - f1 * b[i - 1, 0] - f2 * b[i - 2, 0] - f3 * b[i - 3, 0]
        s1 = b[i, 1] - f1 * b[i - 1, 1] - f2 * b[i - 2, 1] - f3 * b[i - 3, 1]
        b[i, 0] = s0 * factor[0, i]
        b[i, 1] = s1 * factor[0, i]
    for i in range(n - 1, max(n - 4, -1), -1):
        s0 = b[i, 0]
        s1 = b[i, 1]
        for j in range(i + 1, n):
            f = factor[j - i, i]
            s0 -= f * b[j, 0]
            s1 -= f * b[j, 1]
        b[i, 0] = s0 * factor[0, i]
        b[i, 1] = s1 * factor[0, i]
    for i in range(n - 4, -1, -1):
        f1 = factor[1, i]
        f2 = factor[2, i]
        f3 = factor[3, i]
        s0 = b[i, 0] - f1 * b[i + 1, 0] - f2 * b[i + 2, 0] - f3 * b[i + 3, 0]
        s1 = b[i, 1] - f1 * b[i + 1, 1] - f2 * b[i + 2, 1] - f3 * b[i + 3, 1]
        b[i, 0] = s0 * factor[0, i]
        b[i, 1] = s1 * factor[0, i]


@njit(cache=True, fastmath=FAST)
def torsion_residual(k_band, k_damp_scale, c_diag, ut, vt, rt):
    """rt -= K ut + b K vt + diag(c) vt for a tridiagonal K (band layout, bandwidth 1)."""
    n = ut.shape[0]
    for i in range(n):
        x = ut[i] + k_damp_scale * vt[i]
        s = k_band[0, i] * x + c_diag[i] * vt[i]
        if i + 1 < n:
            s += k_band[1, i] * (ut[i + 1] + k_damp_scale * vt[i + 1])
        if i >= 1:
            s += k_band[1, i - 1] * (ut[i - 1] + k_damp_scale * vt[i - 1])
        rt[i] -= s


@njit(cache=True, fastmath=FAST)
def solve_tridiagonal(factor, b):
    """band_solve specialised to bandwidth 1."""
    n = b.shape[0]
    b[0] = b[0] * factor[0, 0]
    for i in range(1, n):
        b[i] = (b[i] - factor[1, i - 1] * b[i - 1]) * factor[0, i]
    b[n - 1] = b[n - 1] * factor[0, n - 1]
    for i in range(n - 2, -1, -1):
        b[i] = (b[i] - factor[1, i] * b[i + 1]) * factor[0, i]
