"""Implicit wall and gauge contacts (numba): the normal penalties in the system matrix.

With ``solver.implicit_contacts`` the normal force of a contact is linearised at the
Newmark predictors: a node at ``u_p`` with unit normal ``n`` (outward) ends the step
pushed inward by ``F_p + kappa (n . a)``, ``kappa = beta dt^2 k + gamma dt c`` (its
penalty stiffness k and damping c, eqs. 18 and 55; ``F_p`` the force at the predictors).
That adds ``kappa n n^T`` to the lateral system at the node's DOF, a rank-one term that
couples the two bending planes. With ``A`` the one-plane band matrix (both planes share
it) and ``W`` the terms' directions, the coupled solve is Sherman-Morrison-Woodbury on the
uncoupled one::

    a = a0 - Z y,   (K^-1 + W^T Z) y = W^T a0,   Z = (A^-1 (+) A^-1) W,

``a0`` the band solve of both planes, ``K = diag(kappa)``. A column ``A^-1 e_j`` is solved
the first time node j touches after a refactor and kept until the next one. ``y = K W^T
a`` are the implicit parts of the normal forces: a term ends the step with ``F_p + y``.
Who touches is settled per step by an active set (:func:`resolve`); the friction and the
contact torque stay explicit at the predictors, as in Hughes & Liu's partition. The
gauge pads enter as the bit node's 2 x 2 stiffness, split into its principal directions.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from drill_env.physics.jit import TUPLE_KERNEL
from drill_env.physics.layout import TERM, Implicit, P
from drill_env.physics.linalg import solve3_planes


def make_implicit(n_lat: int) -> Implicit:
    """The arrays of a string with ``n_lat`` lateral DOFs (two per lateral node): a wall
    term per lateral node and two for the gauge pads at most."""
    nodes = n_lat // 2
    terms = nodes + 2
    return Implicit(np.zeros((nodes, n_lat)), np.zeros(nodes), np.zeros((terms, len(TERM))),
                    np.zeros((terms, terms + 1)), np.zeros((2, n_lat)), np.zeros((2, n_lat)),
                    np.zeros(nodes))


@njit(cache=True, inline="always")
def add_term(terms, count, node, dof, nx, ny, kappa, force):
    """Append one term (layout :data:`~drill_env.physics.layout.TERM`); returns the count."""
    row = terms[count]
    row[TERM.NODE] = node
    row[TERM.DOF] = dof
    row[TERM.NX] = nx
    row[TERM.NY] = ny
    row[TERM.KAPPA] = kappa
    row[TERM.FORCE] = force
    return count + 1


@njit(cache=True, inline="always")
def gauge_terms(p, kxx, kxy, kyy, cxx, cxy, cyy, terms, count, dof):
    """The gauge pads' ``beta dt^2 K + gamma dt C`` (2 x 2, symmetric, >= 0) as up to two
    terms along its eigenvectors; returns the count."""
    h_k = p[P.BETA] * p[P.DT] * p[P.DT]
    h_c = p[P.GAMMA] * p[P.DT]
    a = h_k * kxx + h_c * cxx
    b = h_k * kxy + h_c * cxy
    d = h_k * kyy + h_c * cyy
    if a + d <= 0.0:
        return count
    mean = 0.5 * (a + d)
    half = math.sqrt(0.25 * (a - d) * (a - d) + b * b)
    angle = 0.5 * math.atan2(2.0 * b, a - d)  # of the larger eigenvalue's vector
    c = math.cos(angle)
    s = math.sin(angle)
    count = add_term(terms, count, -1.0, dof, c, s, mean + half, 0.0)
    if mean - half > 1e-12 * (mean + half):
        count = add_term(terms, count, -1.0, dof, -s, c, mean - half, 0.0)
    return count


@njit(cache=True, inline="always")
def _column(implicit, factor, dof):
    """``A^-1 e_dof`` (cached per lateral node until the next refactor)."""
    node = dof // 2
    column = implicit.columns[node]
    if implicit.ready[node] == 0.0:
        rhs = implicit.scratch
        for c in range(2):
            for i in range(rhs.shape[1]):
                rhs[c, i] = 0.0
        rhs[0, dof] = 1.0
        solve3_planes(factor, rhs)
        for i in range(column.shape[0]):
            column[i] = rhs[0, i]
        implicit.ready[node] = 1.0
    return column


@njit(**TUPLE_KERNEL)
def couple(implicit, factor, count, acc):
    """Correct the uncoupled accelerations ``acc`` (2, n_lat) for the ``count`` terms:
    the Woodbury solve of the module docstring. Leaves ``y``, the implicit part of each
    term's normal force, in ``gram[:count, count]``."""
    terms = implicit.terms
    gram = implicit.gram
    m = count
    for s in range(m):  # K^-1 + W^T Z (lower triangle) and W^T a0 in column m
        js = int(terms[s, TERM.DOF])
        nxs = terms[s, TERM.NX]
        nys = terms[s, TERM.NY]
        for t in range(s + 1):
            jt = int(terms[t, TERM.DOF])
            z = _column(implicit, factor, jt)
            gram[s, t] = (nxs * terms[t, TERM.NX] + nys * terms[t, TERM.NY]) * z[js]
        gram[s, s] += 1.0 / terms[s, TERM.KAPPA]
        gram[s, m] = nxs * acc[0, js] + nys * acc[1, js]
    # Cholesky of the small SPD matrix in place, then the two triangular solves
    for j in range(m):
        d = gram[j, j]
        for k in range(j):
            d -= gram[j, k] * gram[j, k]
        d = math.sqrt(d)
        gram[j, j] = d
        for i in range(j + 1, m):
            v = gram[i, j]
            for k in range(j):
                v -= gram[i, k] * gram[j, k]
            gram[i, j] = v / d
    for i in range(m):
        v = gram[i, m]
        for k in range(i):
            v -= gram[i, k] * gram[k, m]
        gram[i, m] = v / gram[i, i]
    for i in range(m - 1, -1, -1):
        v = gram[i, m]
        for k in range(i + 1, m):
            v -= gram[k, i] * gram[k, m]
        gram[i, m] = v / gram[i, i]
    for t in range(m):
        y = gram[t, m]
        z = implicit.columns[int(terms[t, TERM.DOF]) // 2]
        fx = y * terms[t, TERM.NX]
        fy = y * terms[t, TERM.NY]
        for i in range(z.shape[0]):
            acc[0, i] -= fx * z[i]
            acc[1, i] -= fy * z[i]


#: Active-set passes per step: a node the coupled solve moves into the wall with a
#: pushing end-of-step force joins, a term whose end-of-step force would pull leaves, and
#: the solve is repeated; the last pass is kept as it is.
MAX_PASSES = 8


@njit(**TUPLE_KERNEL)
def resolve(p, implicit, factor, count, acc, m, nodes, l0):
    """The coupled solve with its active set (:data:`MAX_PASSES`): ``acc`` (2, n_lat)
    holds the uncoupled accelerations on entry and the coupled ones on return; ``m`` the
    predictors (:class:`~drill_env.physics.layout.Motion`). Returns the final number of
    terms; ``y`` of each is in ``implicit.gram[:count, count]``."""
    terms = implicit.terms
    member = implicit.member
    a0 = implicit.uncoupled
    saved = False  # a0 holds acc's entry values
    for t in range(count):  # member is all 0 between steps
        if terms[t, TERM.NODE] >= 0.0:
            member[int(terms[t, TERM.DOF]) // 2] = t + 1.0
    h3 = p[P.BETA] * p[P.DT] * p[P.DT]
    kappa = h3 * p[P.WALL_K] + p[P.GAMMA] * p[P.DT] * p[P.WALL_C]
    contact_on = p[P.CONTACT_ON] > 0.0
    for sweep in range(MAX_PASSES):
        if saved or count > 0:
            for c in range(2):
                for i in range(acc.shape[1]):
                    if saved:
                        acc[c, i] = a0[c, i]
                    else:
                        a0[c, i] = acc[c, i]
            saved = True
        if count > 0:
            couple(implicit, factor, count, acc)
        if sweep == MAX_PASSES - 1:
            break
        changed = False
        kept = 0
        for t in range(count):  # leave: a wall term that would pull at the end
            node = terms[t, TERM.NODE]
            if node >= 0.0 and terms[t, TERM.FORCE] + implicit.gram[t, count] < 0.0:
                member[int(terms[t, TERM.DOF]) // 2] = 0.0
                changed = True
                continue
            if kept != t:
                for q in range(terms.shape[1]):
                    terms[kept, q] = terms[t, q]
            if node >= 0.0:
                member[int(terms[kept, TERM.DOF]) // 2] = kept + 1.0
            kept += 1
        count = kept
        for k in range(l0 + 1, m.ut.shape[0]):  # join: a node the step moves into it
            j = 2 * (k - l0)
            if not contact_on or nodes.contact[k] == 0.0 or member[j // 2] != 0.0:
                continue
            clearance = nodes.clearance[k]
            xe = m.ul[0, j] + h3 * acc[0, j]
            ye = m.ul[1, j] + h3 * acc[1, j]
            if xe * xe + ye * ye <= clearance * clearance:
                continue  # ends the step off the wall
            xp = m.ul[0, j]
            yp = m.ul[1, j]
            r = math.sqrt(xp * xp + yp * yp)
            if r == 0.0:
                continue
            nx = xp / r
            ny = yp / r
            force = p[P.WALL_K] * (r - clearance) + p[P.WALL_C] * (
                nx * m.vl[0, j] + ny * m.vl[1, j])  # eq. (18) linearised at the predictor
            if force + kappa * (nx * acc[0, j] + ny * acc[1, j]) <= 0.0:
                continue  # inside, but leaving faster than the damper lets it push
            count = add_term(terms, count, k, j, nx, ny, kappa, force)
            member[j // 2] = count
            changed = True
        if not changed:
            break
    for t in range(count):
        member[int(terms[t, TERM.DOF]) // 2] = 0.0
    return count
