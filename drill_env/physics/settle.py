"""The string at rest on the wall of a curved hole: the lateral part of a settled start.

A settled start (:meth:`~drill_env.physics.simulator.Simulator.reset`) begins in steady
rotation. In a vertical hole the string hangs straight on the axis, which is at rest. In
a curved hole the weight across the hole and the tension turning with it press the
string on the wall: started on the axis, it fell onto the wall within ~0.1 s, and the
wall friction it then met was not in the static twist, so the bit stalled in the first
half second whatever the speed, and the stall could leave a stick-slip cycle that a
settled string does not start (stick-slip is hysteretic). Here the string is put where
it rests instead, and the wall's friction torques join the twist.

The rest state solves the static balance of the FE string with its wall contacts,
``(K + K_g(WOB)) u = f_static + f_wall(u)`` in both bending planes at once. ``f_wall`` is
the kernel's contact force law at zero lateral speed
(:func:`~drill_env.physics.integrator.wall_contact`): the penalty normal force, and in
steady rotation the friction of the contact point slipping at ``R omega``, which sets
the string up the wall by the friction angle. The two planes are interleaved into one
banded system (the contacts couple a node's two directions); each contact's 2 x 2
Jacobian is in closed form. First without friction: the minimum of the potential
energy, by Newton's method with an Armijo line search, the Hessian shifted (Marquardt:
each DOF by its own diagonal) where the compressed BHA alone is not stable and only the
wall holds it; past the iteration limit the best state found. Then with the
friction, which has no potential, by Newton's method on the imbalance from there, all
of it at once or, where that fails, in smaller steps. The bit node rests on its gauge:
the macroscopic bit as the kernel's wall contact at the gauge radius; the mesoscopic
bit's gauge pads (eqs. 55-57: the rock's wall stiffness, the pads' or the rock's
friction at r_C omega) as one pad facing the wall, which the six rotating pads are on
average. Where the bit rests on the wall (a build under WOB: docs/config.md's example)
its speed then ripples with the passing pads from the first step as it does later
(96-104 rpm at 100 rpm / 100 kN over 0-0.5 s and over 8-12 s); with the pads left out
it dropped to 88 rpm in the first 0.6 s (a walkthrough).
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np
from numba import njit
from scipy.linalg import solve_banded, solveh_banded

from drill_env.physics.bit import Blade
from drill_env.physics.formation import Rock, resistance
from drill_env.physics.layout import P
from drill_env.physics.string_friction import wall_friction_coefficient

#: Newton iterations of one solve before giving up (the curved scenarios at 10-250 rpm,
#: 0-200 kN took a median 7 without friction and 14 with it, up to 85 with it: the
#: contact set changes a few nodes a step; a BHA buckled far against the wall, s_shaped
#: from 200 kN, uses all of them and starts from the best state found).
MAX_ITERATIONS = 150
#: The friction's first step from the frictionless rest (all of it at once), halved
#: while a step's rest state is not found, down to the smallest; past that the string
#: starts with the friction reached (the curved scenarios' points at 10-250 rpm, 0-150
#: kN needed at most three halvings).
FRICTION_STEP = 1.0
MIN_FRICTION_STEP = 1.0 / 8.0
#: Converged when no force or moment is out of balance by more than this share of the
#: largest static load (:meth:`_Problem.tolerance`); a start left more than the loose
#: share out of balance warns (its first steps move the string).
TOLERANCE = 1e-6
LOOSE_TOLERANCE = 0.05
#: Half-bandwidth of the two planes interleaved: the lateral band (the DOFs of the next
#: node, 3 per plane) times the two planes.
_BAND = 6


def rest_on_wall(sim: Any, omega: float, weight_on_bit: float) -> np.ndarray:
    """Put ``sim``'s lateral nodes where they rest on the wall of its curved hole at the
    static loads of ``weight_on_bit`` (``sim.static_load``, set for it), turning at
    ``omega``; returns the wall's torque on each node (N m, against the rotation), which
    the settled twist must carry. Sets ``ul`` (velocities and accelerations stay zero)
    and ``node_force`` (the normal forces); ``sim.settle_iterations``, ``settle_imbalance``
    (N) and ``settle_share`` (of the friction reached) say how it went."""
    n, l0 = sim.ut.shape[0], sim.lateral_start
    nl = sim.static_load.shape[1]
    nodes = np.array([k for k in range(l0 + 1, n) if sim.node_contact[k] != 0.0 or k == n - 1])
    problem = _Problem(sim, nodes, weight_on_bit)
    # each node first at the wall where its static load pushes it: Newton's first steps
    # then need not find the contacts from the axis
    z = np.zeros(2 * nl)
    push = problem.load.reshape(-1, 2)[problem.at // 2]
    size = np.hypot(push[:, 0], push[:, 1])
    wall = Wall(sim, nodes, 0.0)
    z[problem.at], z[problem.at + 1] = (wall.clearance * push.T
                                        / np.where(size > 0.0, size, 1.0))
    # without friction (a minimum of the potential energy), then with it from there;
    # where the friction's rest state is not found the string starts at the last share
    # of it reached (the first steps then climb the rest of the way up the wall)
    z, sim.settle_iterations, imbalance = problem.minimize(z, wall)
    sim.settle_imbalance = imbalance  # N (or N m): what is left out of balance
    if imbalance > LOOSE_TOLERANCE * problem.scale:
        warnings.warn(f"settled start: the string's rest on the wall left {imbalance:.0f} N "
                      f"out of balance after {MAX_ITERATIONS} Newton iterations; it starts "
                      "there and settles in the first steps", RuntimeWarning, stacklevel=3)
    share = 1.0
    if omega != 0.0:  # the friction brought in by steps (continuation), smaller where
        wall = Wall(sim, nodes, omega)  # a step's rest state is not found
        mu, share, increment = wall.mu.copy(), 0.0, FRICTION_STEP
        while share < 1.0 and increment >= MIN_FRICTION_STEP:
            wall.mu = min(1.0, share + increment) * mu
            rubbing = problem.solve(z, wall)
            if rubbing is None:
                increment /= 2.0
                continue
            z, more = rubbing
            sim.settle_iterations += more
            share = min(1.0, share + increment)
        wall.mu = mu  # the twist holds the kernel's torque at t = 0: all of the friction
    sim.settle_share = share
    sim.ul[...] = z.reshape(nl, 2)
    at = problem.at
    wall.forces(z[at], z[at + 1])
    torque = np.zeros(n)
    sim.node_force[nodes] = wall.normal
    torque[nodes] = wall.torque
    return torque


class _Problem:
    """The static balance ``K z = f_static + f_wall(z)`` of the two planes interleaved."""

    def __init__(self, sim: Any, nodes: np.ndarray, weight_on_bit: float) -> None:
        band = sim.lat_k + sim.lat_kg_weight - weight_on_bit * sim.lat_kg_unit
        self.matrix = _stiffness(band)
        pinned = 2 * np.flatnonzero(band[0] == 0.0)  # rows the assembly zeroed
        self.pinned = np.concatenate([pinned, pinned + 1])
        self.at = 4 * (nodes - sim.lateral_start)  # each node's x displacement in z
        self.load = sim.static_load.T.reshape(-1)  # interleaved: z[2 i + c] = u[c, i]
        self.free = np.ones(self.load.shape[0], dtype=bool)
        self.free[self.pinned] = False

    def residual(self, z: np.ndarray, wall: Wall) -> tuple[np.ndarray, np.ndarray]:
        at = self.at
        force, jacobian = wall.forces(z[at], z[at + 1])
        residual = self.load - _apply(self.matrix, z)
        residual[at] += force[:, 0]
        residual[at + 1] += force[:, 1]
        return np.where(self.free, residual, 0.0), jacobian

    @property
    def scale(self) -> float:
        """The largest static load (N), at least 1."""
        return max(1.0, float(np.max(np.abs(self.load))))

    def tolerance(self) -> float:
        """Converged when no force (N) or moment (N m) is out of balance by more than a
        millionth of the largest static load (~4 mN in the curved scenarios)."""
        return TOLERANCE * self.scale

    def _tangent(self, jacobian: np.ndarray) -> np.ndarray:
        """K - dF/du in banded storage, with the pinned DOFs held."""
        system = self.matrix.copy()
        for r in range(2):
            for c in range(2):  # the node's 2 x 2 block
                system[_BAND + r - c, self.at + c] -= jacobian[:, r, c]
        for j in self.pinned:
            _pin(system, np.zeros(1), j, rhs_too=False)
        return system

    def energy(self, z: np.ndarray, wall: Wall) -> float:
        """The potential energy without friction: the string's, the loads', the wall's."""
        at = self.at
        r = np.hypot(z[at], z[at + 1])
        into = np.maximum(r - wall.clearance, 0.0)
        return float(0.5 * z @ _apply(self.matrix, z) - self.load @ z
                     + 0.5 * into @ (wall.stiffness * into))

    def minimize(self, z: np.ndarray, wall: Wall) -> tuple[np.ndarray, int, float]:
        """The rest state without friction: the energy's minimum by Newton's method, its
        Hessian made positive definite where the compressed string alone is not (a
        buckled BHA the wall holds: Marquardt's shift), with an Armijo line search;
        (z, iterations, largest imbalance left). Where the wall holds a string buckled
        far past its own limit the Hessian stays indefinite and the steps shrink to
        gradient steps: after ``MAX_ITERATIONS`` the best state found is returned (a few
        newtons out of balance on the s_shaped string at 215-290 kN)."""
        residual, jacobian = self.residual(z, wall)
        best = (z, float(np.max(np.abs(residual))))
        shift = 0.0  # Marquardt's: each DOF's diagonal times this, the last one that held
        for iteration in range(MAX_ITERATIONS):
            imbalance = float(np.max(np.abs(residual)))
            if imbalance < best[1]:
                best = (z, imbalance)
            if imbalance < self.tolerance():
                return z, iteration, imbalance
            system = self._tangent(jacobian)
            upper = system[:_BAND + 1]  # scipy's upper form of the symmetric band
            # scaled by each DOF's own stiffness: one shift for all would be set by the
            # stiff tilt DOFs and swamp the pipe's lateral ones (a crawl at high WOB)
            diagonal = np.abs(upper[_BAND])
            shift /= 10.0
            while True:
                try:
                    shifted = upper.copy()
                    shifted[_BAND] += shift * diagonal
                    step = solveh_banded(shifted, residual)
                    break
                except np.linalg.LinAlgError:
                    shift = max(4.0 * shift, 1e-8)
            energy, slope = self.energy(z, wall), -residual @ step
            alpha = 1.0
            while alpha > 1e-12 and self.energy(z + alpha * step, wall) > \
                    energy + 1e-4 * alpha * slope:
                alpha *= 0.5
            z = z + alpha * step
            residual, jacobian = self.residual(z, wall)
        return best[0], MAX_ITERATIONS, best[1]

    def solve(self, z: np.ndarray, wall: Wall) -> tuple[np.ndarray, int] | None:
        """The rest state with friction (not a minimum: friction does no potential) from
        a nearby one ``z``: Newton's method with backtracking on the imbalance;
        (z, iterations), or None."""
        residual, jacobian = self.residual(z, wall)
        for iteration in range(MAX_ITERATIONS):
            if np.max(np.abs(residual)) < self.tolerance():
                return z, iteration
            system = self._tangent(jacobian)
            residual[self.pinned] = 0.0
            step = solve_banded((_BAND, _BAND), system, residual)
            size = np.linalg.norm(residual)
            for _ in range(40):
                new, new_jacobian = self.residual(z + step, wall)
                if np.linalg.norm(new) < size:
                    break
                step *= 0.5
            else:
                return None  # no step reduces the imbalance
            z, residual, jacobian = z + step, new, new_jacobian
        return None


class Wall:
    """The kernel's wall contact law (:func:`~drill_env.physics.integrator.wall_contact`)
    at zero lateral speed for the nodes ``nodes`` (the mesoscopic bit's gauge pads as
    one), with its Jacobian."""

    def __init__(self, sim: Any, nodes: np.ndarray, omega: float) -> None:
        p = sim.params
        self.stiffness = np.full(nodes.shape[0], p[P.WALL_K])
        self.clearance = sim.node_clearance[nodes].copy()
        self.radius = sim.node_radius[nodes].copy()
        speed = omega * self.radius  # the contact point slips at R omega
        self.sign = np.sign(speed)
        mu = np.array([wall_friction_coefficient(v, p[P.MU_STATIC], p[P.MU_KINETIC],
                                                 p[P.MU_DECAY]) for v in speed])
        self.mu = mu * np.minimum(np.abs(speed) / p[P.V_REG], 1.0)  # regularised slow slip
        compliance = sim.compliance[nodes]
        self.cap = np.where(compliance > 0.0, np.abs(speed) / np.where(
            compliance > 0.0, compliance, 1.0), np.inf)  # the kernel's one-step cap
        # The mesoscopic bit rests on its gauge pads (eqs. 55-57): the rock's wall
        # stiffness, pads at their radius r_C slipping at r_C omega, the pads' friction
        # or the rock's resistance curve at omega. Here as one pad facing the wall, which
        # the rotating pads are on average; none without pads (all gauge lengths 0: the
        # kernel gives that bit no wall); no friction with implicit contacts, whose pads
        # rub only once their force is known (PAD.END_FORCE, 0 at the start). The
        # macroscopic bit is the kernel's wall contact at its gauge radius, as above.
        bit = sim.config.bit
        if sim.config.bit_model == "mesoscopic" and nodes[-1] == sim.ut.shape[0] - 1:
            rock = sim._rock_at_bit()
            pads = sim.blades[:, Blade.L_G] > 0.0
            reach = float(np.max(sim.blades[pads, Blade.R_C])) if pads.any() else 0.0
            self.stiffness[-1] = rock[Rock.WALL_STIFFNESS] if pads.any() else 0.0
            self.clearance[-1] = sim.config.string.hole_diameter / 2 - reach
            self.radius[-1] = reach
            self.sign[-1] = np.sign(omega)
            rubs = pads.any() and not sim.config.solver.implicit_contacts
            self.mu[-1] = abs(bit.gauge_friction if bit.gauge_friction is not None else
                              resistance(omega, rock[Rock.MU_MIN], rock[Rock.MU_MAX],
                                         rock[Rock.ST1], rock[Rock.ST2])) if rubs else 0.0
            # regularised below V_REG as the kernel's pads are (bit._gauge_loads)
            self.mu[-1] *= min(abs(reach * omega) / p[P.V_REG], 1.0)
            self.cap[-1] = np.inf
        self.normal = np.zeros(nodes.shape[0])
        self.torque = np.zeros(nodes.shape[0])

    def forces(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Forces (m, 2) on the nodes at (x, y) and their Jacobian (m, 2, 2) d F / d u;
        sets :attr:`normal` and :attr:`torque`."""
        force = np.empty((x.shape[0], 2))
        jacobian = np.empty((x.shape[0], 2, 2))
        _wall_forces(x, y, self.clearance, self.radius, self.sign, self.mu, self.cap,
                     self.stiffness, force, jacobian, self.normal, self.torque)
        return force, jacobian


@njit(cache=True)
def _wall_forces(x, y, clearance, radius, sign, mu, cap, stiffness, force, jacobian,
                 normal, torque):
    """:meth:`Wall.forces` node by node: ``F = -f_n n + f_r t`` with ``f_n = k (r - c)``,
    ``f_r = -sign min(mu f_n, cap)`` and its derivatives
    ``dF/du = -k n n^T - f_n P / r + t (d f_r / du) + f_r R P / r`` (``P = I - n n^T``,
    ``R`` the quarter turn taking n to t)."""
    for k in range(x.shape[0]):
        r = np.hypot(x[k], y[k])
        force[k, :] = 0.0
        jacobian[k, :, :] = 0.0
        normal[k] = 0.0
        torque[k] = 0.0
        if r <= clearance[k]:
            continue
        nx, ny = x[k] / r, y[k] / r
        tx, ty = -ny, nx
        fn = stiffness[k] * (r - clearance[k])
        slip = mu[k] * fn
        capped = slip > cap[k]
        fr = -sign[k] * (cap[k] if capped else slip)
        dfr = 0.0 if capped else -sign[k] * mu[k] * stiffness[k]
        force[k, 0] = -fn * nx + fr * tx
        force[k, 1] = -fn * ny + fr * ty
        n = (nx, ny)
        t = (tx, ty)
        for a in range(2):
            for b in range(2):
                proj = ((1.0 if a == b else 0.0) - n[a] * n[b]) / r
                # (R P)[a, b] = sum_c R[a, c] P[c, b], R = [[0, -1], [1, 0]]
                turned = (-(((1.0 if b == 1 else 0.0) - n[1] * n[b]) / r) if a == 0
                          else ((1.0 if b == 0 else 0.0) - n[0] * n[b]) / r)
                jacobian[k, a, b] = (-stiffness[k] * n[a] * n[b] - fn * proj
                                     + t[a] * dfr * n[b] + fr * turned)
        normal[k] = fn
        torque[k] = radius[k] * fr


def _stiffness(band: np.ndarray) -> np.ndarray:
    """One plane's ``band`` (upper band storage, ``band[d, i] = A[i, i + d]``: K +
    K_g(WOB)) for the two planes interleaved, in scipy's banded storage
    (``ab[_BAND + i - j, j] = A[i, j]``)."""
    nl = band.shape[1]
    ab = np.zeros((2 * _BAND + 1, 2 * nl))
    for d in range(band.shape[0]):
        for i in range(nl - d):
            for c in range(2):
                row, col = 2 * i + c, 2 * (i + d) + c
                ab[_BAND + row - col, col] = band[d, i]
                ab[_BAND + col - row, row] = band[d, i]
    return ab


@njit(cache=True)
def _apply(ab, z):
    """A z for A in banded storage (``ab[_BAND + i - j, j] = A[i, j]``)."""
    m = z.shape[0]
    out = np.zeros(m)
    for j in range(m):
        for i in range(max(0, j - _BAND), min(m, j + _BAND + 1)):
            out[i] += ab[_BAND + i - j, j] * z[j]
    return out


def _pin(ab: np.ndarray, rhs: np.ndarray, j: int, *, rhs_too: bool = True) -> None:
    """Hold DOF ``j`` at zero (the pinned top node, a bit held axis-aligned): its row
    and column cleared, 1 on the diagonal."""
    for other in range(max(0, j - _BAND), min(ab.shape[1], j + _BAND + 1)):
        ab[_BAND + j - other, other] = 0.0  # A[j, other]
        ab[_BAND + other - j, j] = 0.0  # A[other, j]
    ab[_BAND, j] = 1.0
    if rhs_too:
        rhs[j] = 0.0
