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
contact torque stay explicit at the predictors, as in Hughes & Liu's partition; each
gauge pad is a term of its own.

The friction. It stays explicit, and the predictors it is evaluated at are poor once the
contacts are implicit and the step long: the predictor ``u + dt v + dt^2 a / 4`` carries
the step's acceleration, which for a stiff contact (``w dt`` ~ 1.5-3) throws the
predicted position across the hole, so gauge pads on the far side "touch" with hundreds
of kN at the predictors while the end of the step has them off the rock. Friction on
those forces turned the bit back and forth (an 8 ms fast-level run diverged within 11 s).
So a contact rubs with the smaller of its normal forces at the predictors and at the end
of the last step (``PAD.END_FORCE`` for the pads, ``node_force`` for the walls): what
the implicit solve settled, not what the predictor guessed. Except a wall contact that
starts in this step (no force at the end of the last): it rubs with the mean of its
force at the start of the step, zero, and at the predictors, the step's average for a
penetration that grows through it. Backward whirl starts at an impact: the friction of
the first step on the wall turns a BHA thrown there into rolling. Rubbing with the
smaller force, zero on that step, the BHA slid off instead, and from 4 ms on it no
longer rolled into sustained backward whirl where the full model does; rubbing with the
whole predicted force, which grows with the predictor's overshoot, from about 7.7 ms on
it whirled at task 2's high rpm where the full model does not (docs/performance.md,
"Backward whirl"). With the mean, on 300 fresh task-2 seeds the BHA whirls under the
classical drives about as often as in the full model, but at 8-10 ms it still adds
whirl at the shipped policy's high rpm (4 of 100 fresh seeds at 10 ms, "300 fresh
seeds"): the fast level keeps explicit contacts. The gauge pads keep the smaller force
when they start too: with both starting walls and pads rubbing with their predicted
forces, 43 of 300 random-action task-2 episodes diverged at 10 ms, with the walls alone
none. And its cap, the force that
would stop its slip within the step (``|v_r| / compliance``, docs/model.md), is too
large for two reasons. The predictor carries the step's acceleration into the next one
(``v_p' = v_p + dt F / m`` at gamma = 1/2), so a friction force at the cap stops the
slip at the end of the step but reverses it at the next predictor: a neutral period-two
oscillation that the falling friction curves grow; at half the cap the next predictor's
slip is zero. And a long step presses several gauge
pads into the rock at once, each capped as if it alone turned the bit, and their sum
reversed the bit's rotation. So with implicit contacts the compliances are doubled
(``Simulator``) and the bit's cap is split among its pads on the wall
(``GaugeContact.shared``).
"""

from __future__ import annotations

import math
import warnings

import numpy as np
from numba import njit

from drill_env.physics.bit import PAD, Blade, Segment
from drill_env.physics.formation import Rock
from drill_env.physics.jit import TUPLE_KERNEL
from drill_env.physics.layout import TERM, Implicit, P
from drill_env.physics.linalg import solve3_planes


def warn_of_curved_hole() -> None:
    """The RuntimeWarning of ``solver.implicit_contacts`` in a curved hole."""
    warnings.warn("solver.implicit_contacts in a curved hole: slower than explicit "
                  "(docs/performance.md)", RuntimeWarning, stacklevel=3)


def make_implicit(n_lat: int, n_pads: int) -> Implicit:
    """The arrays of a string with ``n_lat`` lateral DOFs (two per lateral node): a wall
    term per lateral node and one per gauge pad at most."""
    nodes = n_lat // 2
    terms = nodes + n_pads
    return Implicit(np.zeros((nodes, n_lat)), np.zeros(nodes), np.zeros((terms, len(TERM))),
                    np.zeros((terms, terms + 1)), np.zeros((2, n_lat)), np.zeros((2, n_lat)),
                    np.zeros(nodes))


@njit(cache=True, inline="always")
def implicit_contacts_on(p):
    """Implicit contacts in force: asked for, with the lateral DOFs moving (torsion only
    has no contacts)."""
    return p[P.IMPLICIT_CONTACT] > 0.0 and p[P.LATERAL] > 0.0


@njit(cache=True, inline="always")
def kappa_of(p, stiffness, damping):
    """``beta dt^2 k + gamma dt c``: a penalty's end-of-step force per unit acceleration
    along its normal (N s^2/m)."""
    return p[P.BETA] * p[P.DT] * p[P.DT] * stiffness + p[P.GAMMA] * p[P.DT] * damping


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
def pad_terms(p, pads, terms, count, dof):
    """A term for every gauge pad that pushes at the predictors (``pads``: the bit's
    :data:`~drill_env.physics.bit.PAD` rows); returns the count."""
    for i in range(pads.shape[0]):
        pad = pads[i]
        if pad[PAD.ON] > 0.0 and pad[PAD.FORCE] > 0.0:
            count = add_term(terms, count, -1.0 - i, dof, pad[PAD.EX], pad[PAD.EY],
                             kappa_of(p, pad[PAD.STIFFNESS], pad[PAD.DAMPING]),
                             pad[PAD.FORCE])
    return count


@njit(cache=True, inline="always")
def _pad_penalty(bit, n_pieces, blade):
    """Stiffness and damping of a whole gauge pad (all its pieces, eq. 55)."""
    pieces = bit.pieces
    rock_params = bit.formation.rock_params
    l_g = bit.blades[blade, Blade.L_G]
    k = 0.0
    c = 0.0
    for q in range(n_pieces):
        if pieces.blade[q] == blade and pieces.segment[q] == Segment.GAUGE:
            j = pieces.rock[q]
            k += pieces.length[q] / l_g * rock_params[j, Rock.WALL_STIFFNESS]
            c += pieces.length[q] / l_g * rock_params[j, Rock.WALL_DAMPING]
    return k, c


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


#: Active-set passes per step: a node or gauge pad the coupled solve moves into the wall
#: with a pushing end-of-step force joins, a term whose end-of-step force would pull
#: leaves, and the solve is repeated; the last pass is kept as it is.
MAX_PASSES = 8


@njit(cache=True, inline="always")
def _copy(source, target):
    for c in range(2):
        for i in range(source.shape[1]):
            target[c, i] = source[c, i]


@njit(cache=True, inline="always")
def _shift(implicit, factor, a0, dof, nx, ny, force):
    """Add to ``a0`` the accelerations of an outward force ``force n`` at ``dof``: a term
    that leaves takes back the force it applied (``-F n``), one that joins applies its
    linearised force at the predictors."""
    z = _column(implicit, factor, dof)
    fx = force * nx
    fy = force * ny
    for i in range(z.shape[0]):
        a0[0, i] += fx * z[i]
        a0[1, i] += fy * z[i]


@njit(**TUPLE_KERNEL)
def resolve(p, implicit, factor, count, acc, m, nodes, l0, bit, n_pieces, lb):
    """The coupled solve with its active set (:data:`MAX_PASSES`): ``acc`` (2, n_lat)
    holds the uncoupled accelerations on entry and the coupled ones on return; ``m`` the
    predictors (:class:`~drill_env.physics.layout.Motion`); ``bit`` the
    :class:`~drill_env.physics.layout.BitArrays` (its pads and the ``n_pieces`` pieces of
    the last call; no pads with the macroscopic bit), ``lb`` the bit's DOF. Each term's
    ``TERM.FORCE`` is the force it applies at the predictors, so it ends the step with
    ``FORCE + y``; returns the final count, ``y`` in ``implicit.gram[:count, count]``."""
    terms = implicit.terms
    member = implicit.member
    a0 = implicit.uncoupled
    saved = False  # a0 holds the uncoupled accelerations (and the shifts since)
    for t in range(count):  # member is all 0 between steps
        if terms[t, TERM.NODE] >= 0.0:
            member[int(terms[t, TERM.DOF]) // 2] = t + 1.0
    h3 = p[P.BETA] * p[P.DT] * p[P.DT]
    kappa = kappa_of(p, p[P.WALL_K], p[P.WALL_C])
    contact_on = p[P.CONTACT_ON] > 0.0
    pads = bit.pieces.pads
    pads_on = p[P.MACRO_BIT] == 0.0
    for sweep in range(MAX_PASSES):
        if saved:
            _copy(a0, acc)
        elif count > 0:
            _copy(acc, a0)
            saved = True
        if count > 0:
            couple(implicit, factor, count, acc)
        if sweep == MAX_PASSES - 1:
            break
        changed = False
        kept = 0
        for t in range(count):  # leave: a term that would pull at the end
            node = terms[t, TERM.NODE]
            if terms[t, TERM.FORCE] + implicit.gram[t, count] < 0.0:
                _shift(implicit, factor, a0, int(terms[t, TERM.DOF]), terms[t, TERM.NX],
                       terms[t, TERM.NY], terms[t, TERM.FORCE])
                if node >= 0.0:
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
            xp = m.ul[0, j]
            yp = m.ul[1, j]
            r = math.sqrt(xp * xp + yp * yp)
            if r == 0.0:
                continue
            nx = xp / r
            ny = yp / r
            along = nx * acc[0, j] + ny * acc[1, j]
            if r - clearance + h3 * along <= 0.0:
                continue  # ends the step off the wall
            force = p[P.WALL_K] * (r - clearance) + p[P.WALL_C] * (
                nx * m.vl[0, j] + ny * m.vl[1, j])  # eq. (18) linearised at the predictor
            if force + kappa * along <= 0.0:
                continue  # inside, but leaving faster than the damper lets it push
            if not saved:
                _copy(acc, a0)
                saved = True
            _shift(implicit, factor, a0, j, nx, ny, -force)
            count = add_term(terms, count, k, j, nx, ny, kappa, force)
            member[j // 2] = count
            changed = True
        for i in range(pads.shape[0] if pads_on else 0):  # join: a gauge pad
            pad = pads[i]
            if pad[PAD.ON] == 0.0:
                continue
            present = False
            for t in range(count):
                if terms[t, TERM.NODE] == -1.0 - i:
                    present = True
            if present:
                continue
            nx = pad[PAD.EX]
            ny = pad[PAD.EY]
            along = nx * acc[0, lb] + ny * acc[1, lb]
            if pad[PAD.PENETRATION] + h3 * along <= 0.0:
                continue
            k_pad, c_pad = _pad_penalty(bit, n_pieces, i)
            force = k_pad * pad[PAD.PENETRATION] + c_pad * pad[PAD.RATE]
            kappa_pad = kappa_of(p, k_pad, c_pad)
            if force + kappa_pad * along <= 0.0:
                continue
            if not saved:
                _copy(acc, a0)
                saved = True
            _shift(implicit, factor, a0, lb, nx, ny, -force)
            count = add_term(terms, count, -1.0 - i, lb, nx, ny, kappa_pad, force)
            changed = True
        if not changed:
            break
    for t in range(count):
        member[int(terms[t, TERM.DOF]) // 2] = 0.0
    return count
