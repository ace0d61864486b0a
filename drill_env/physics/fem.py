"""Finite-element assembly of the drill string (paper section 2.2, eqs. 15-16).

Each node carries 5 DOFs ``x, phi_x, y, phi_y, phi_z`` (eq. 15). In a straight vertical
hole the linear part of eq. (16) decouples into three independent systems, which the
simulator stores separately and in banded form:

* bending in the x-z plane, DOFs ``(x_k, theta_k)`` with theta = dx/ds (= phi_y),
* bending in the y-z plane, the same matrices (theta = dy/ds = -phi_x),
* torsion, DOFs ``phi_z,k``.

Bending uses cubic Hermite (Euler-Bernoulli) elements plus the geometric stiffness of
the static axial force; torsion uses linear elements. Mass is lumped: half of each
element's translational mass (steel + mud inside + added mass of displaced mud) and
half of its cross-section rotary inertia go to each end node (HRZ-free row sum, which
is exact for the translational mass and keeps the explicit force terms cheap).

Node 0 is at the surface (laterally pinned, driven in rotation by the top drive); the
last node carries the bit.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from drill_env.physics.config import GRAVITY, SimulationConfig

#: Half bandwidth of the lateral matrices (2 DOFs per node, 4x4 element matrices).
LATERAL_BANDWIDTH = 3


@dataclass
class Mesh:
    """Node positions and per-element section properties (SI)."""

    node_depth: np.ndarray  # (n_nodes,) measured depth of each node (m)
    element_length: np.ndarray  # (n_el,)
    bending_stiffness: np.ndarray  # EI (N m^2)
    torsional_stiffness: np.ndarray  # GJ (N m^2)
    steel_mass: np.ndarray  # rho A (kg/m)
    lateral_mass: np.ndarray  # rho A + mud inside + Ca * displaced mud (kg/m)
    rotary_inertia: np.ndarray  # rho I per length, tilt DOFs (kg m)
    polar_inertia: np.ndarray  # rho J per length, torsion (kg m)
    buoyed_weight: np.ndarray  # (rho_s - rho_m) A g (N/m)
    outer_radius: np.ndarray  # (n_el,)
    is_bha: np.ndarray  # (n_el,) bool: below the top drill pipe
    #: (n_el,) radius that touches the wall (stabilizer blades); default: outer_radius
    contact_radius: np.ndarray = None  # type: ignore[assignment]
    #: (n_el,) int: index into StringConfig.sections (surface down); default: all 0
    component: np.ndarray = None  # type: ignore[assignment]

    def __post_init__(self) -> None:
        if self.contact_radius is None:
            self.contact_radius = self.outer_radius.copy()
        if self.component is None:
            self.component = np.zeros(self.element_length.size, dtype=np.int64)

    @property
    def n_nodes(self) -> int:
        return self.node_depth.size

    @property
    def n_elements(self) -> int:
        return self.element_length.size


def build_mesh(config: SimulationConfig) -> Mesh:
    """The elements of every component, surface down (``StringConfig.sections``)."""
    mud = config.mud
    lengths, props = [], []
    for index, section in enumerate(config.string.sections):
        is_bha = index > 0
        n = section.n_elements
        le = section.length / n
        ro, ri = section.outer_diameter / 2, section.inner_diameter / 2
        a_out, a_in = np.pi * ro**2, np.pi * ri**2
        rho_a = section.density * section.area
        row = (
            section.youngs_modulus * section.second_moment,
            section.shear_modulus * section.polar_moment,
            rho_a,
            rho_a + mud.density * a_in + mud.added_mass_coefficient * mud.density * a_out,
            section.density * section.second_moment,
            section.density * section.polar_moment,
            (section.density - mud.density) * section.area * GRAVITY,
            ro,
            is_bha,
            section.wall_diameter / 2,
            index,
        )
        lengths += [le] * n
        props += [row] * n
    cols = list(zip(*props, strict=True))
    element_length = np.asarray(lengths)
    return Mesh(
        node_depth=np.concatenate(([0.0], np.cumsum(element_length))),
        element_length=element_length,
        bending_stiffness=np.asarray(cols[0]),
        torsional_stiffness=np.asarray(cols[1]),
        steel_mass=np.asarray(cols[2]),
        lateral_mass=np.asarray(cols[3]),
        rotary_inertia=np.asarray(cols[4]),
        polar_inertia=np.asarray(cols[5]),
        buoyed_weight=np.asarray(cols[6]),
        outer_radius=np.asarray(cols[7]),
        is_bha=np.asarray(cols[8], dtype=bool),
        contact_radius=np.asarray(cols[9]),
        component=np.asarray(cols[10], dtype=np.int64),
    )


def node_contact_radius(mesh: Mesh, config: SimulationConfig) -> np.ndarray:
    """The radius with which each node touches the wall (m).

    A node between components touches with the larger of the two (a collar's top end
    below the pipe); a stabilizer sub with the blades of its lower end only (a point
    contact), or, where that end is the bit's node (whose wall contact is the bit's
    gauge), with those of its own node nearest its middle: its top end when it is one
    element. The extra ``stabilizers`` go on the nodes nearest their heights (the
    bit's node excepted: one nearest it is not modelled, and ``check_stabilizers``
    warns of it).
    """
    string = config.string
    n = mesh.n_nodes
    above, below = mesh.contact_radius[:-1], mesh.contact_radius[1:]
    sub = np.array([s.kind == "stabilizer" for s in string.sections])[mesh.component]
    radius = np.concatenate(
        [above[:1], np.where(sub[1:], above, np.maximum(above, below)), below[-1:]])
    if sub[-1]:  # a stabilizer on the bit: its blades on its own node nearest its middle
        nodes = np.flatnonzero(mesh.component == mesh.component[-1])  # its top down
        middle = mesh.node_depth[-1] - 0.5 * string.sections[-1].length
        k = nodes[np.argmin(np.abs(mesh.node_depth[nodes] - middle))]
        radius[k] = max(radius[k], mesh.contact_radius[-1])
    for height in string.stabilizer_positions:
        k = int(np.argmin(np.abs(mesh.node_depth[-1] - mesh.node_depth - height)))
        if 0 < k < n - 1:
            radius[k] = string.stabilizer_diameter / 2
    return radius


# --------------------------------------------------------------------------- elements


def _bending_entries(le: Any) -> list[list[Any]]:
    """The 4 x 4 entries of the Hermite bending stiffness over EI / L^3 (``le``: one
    length or an array of them)."""
    l2 = le * le
    return [[12.0, 6 * le, -12.0, 6 * le],
            [6 * le, 4 * l2, -6 * le, 2 * l2],
            [-12.0, -6 * le, 12.0, -6 * le],
            [6 * le, 2 * l2, -6 * le, 4 * l2]]


def _geometric_entries(le: Any) -> list[list[Any]]:
    """The 4 x 4 entries of the consistent geometric stiffness over N / (30 L)."""
    l2 = le * le
    return [[36.0, 3 * le, -36.0, 3 * le],
            [3 * le, 4 * l2, -3 * le, -l2],
            [-36.0, -3 * le, 36.0, -3 * le],
            [3 * le, -l2, -3 * le, 4 * l2]]


def beam_stiffness(ei: float, le: float) -> np.ndarray:
    """Hermite Euler-Bernoulli bending stiffness, DOFs (w1, theta1, w2, theta2)."""
    return ei / le**3 * np.array(_bending_entries(le))


def beam_geometric_stiffness(axial_force: float, le: float) -> np.ndarray:
    """Consistent geometric stiffness of a Hermite beam under axial force N (tension > 0).

    Standard result (e.g. Cook et al., Concepts and Applications of FEA, eq. 18.3-6):
    ``N/(30 L) [[36, 3L, -36, 3L], [3L, 4L^2, -3L, -L^2], ...]``; compression softens.
    """
    return axial_force / (30.0 * le) * np.array(_geometric_entries(le))


# --------------------------------------------------------------------------- axial force


def buoyed_string_weight(mesh: Mesh, bit_buoyed_weight: float = 0.0) -> float:
    """Hook load with the bit off bottom (N)."""
    return float(np.sum(mesh.buoyed_weight * mesh.element_length) + bit_buoyed_weight)


def axial_force_profile(mesh: Mesh, weight_on_bit: float,
                        bit_buoyed_weight: float = 0.0) -> np.ndarray:
    """Static axial force at each element's midpoint (N, tension > 0).

    N(s) = -WOB + (buoyed weight of everything below s). The paper neglects axial
    motion but keeps this static force (section 2.2); its geometric stiffness softens
    the compressed BHA laterally.
    """
    w = mesh.buoyed_weight * mesh.element_length
    below = np.cumsum(w[::-1])[::-1] - 0.5 * w  # weight of the element half + all below
    return below + bit_buoyed_weight - weight_on_bit


# --------------------------------------------------------------------------- dense assembly


def _element_matrices(le: np.ndarray, scale: np.ndarray, entries) -> np.ndarray:
    """(n_elements, 4, 4): ``scale[e] * entries(le[e])`` for every element, entry by entry
    with the arithmetic of :func:`beam_stiffness` / :func:`beam_geometric_stiffness`."""
    out = np.empty((le.shape[0], 4, 4))
    for i, row in enumerate(entries(le)):
        for j, entry in enumerate(row):
            out[:, i, j] = scale * entry
    return out


def assemble_lateral_band(mesh: Mesh, axial_force: np.ndarray | None = None,
                          ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Lateral stiffness and geometric stiffness of one plane in upper band storage
    (``band[d, i] = A[i, i + d]``, d = 0..:data:`LATERAL_BANDWIDTH`), and the lumped mass.

    Element by element as :func:`beam_stiffness` and :func:`beam_geometric_stiffness`
    give them, added in two passes, even elements then odd ones: the elements of a pass
    do not overlap, and an entry shared by two neighbours gets ``0 + a + b``, which
    IEEE addition gives the same in either order. So the result is the element loop's to
    the last bit, in O(n) memory and time (a randomised scenario builds a new string
    every episode; dense 2n x 2n matrices cost page faults by the megabyte)."""
    n = mesh.n_nodes
    le = np.asarray(mesh.element_length, dtype=float)
    ne = le.shape[0]
    # ei / le**3 and N / (30 le) per element with scalar arithmetic, as the element
    # functions compute them
    bend = np.array([ei / length**3 for ei, length in zip(mesh.bending_stiffness, le,
                                                           strict=True)])
    # the upper entries (a <= b) of each 4 x 4 element matrix, and where they go:
    # global (2e + a, 2e + b) is band[b - a, 2e + a]
    upper = [(a, b) for a in range(4) for b in range(a, 4)]
    local = np.array([4 * a + b for a, b in upper])
    where = np.array([(b - a) * 2 * n + a for a, b in upper])
    flat = 2 * np.arange(ne)[:, None] + where[None, :]  # (ne, 10) band.flat index
    k = np.zeros((LATERAL_BANDWIDTH + 1, 2 * n))
    kg = np.zeros((LATERAL_BANDWIDTH + 1, 2 * n))
    passes = (slice(0, ne, 2), slice(1, ne, 2))
    for target, elements in ((k, _element_matrices(le, bend, _bending_entries)),
                             (kg, None if axial_force is None else _element_matrices(
                                 le, np.asarray(axial_force, dtype=float)[:ne] / (30.0 * le),
                                 _geometric_entries))):
        if elements is not None:
            values = elements.reshape(ne, 16)[:, local]
            view = target.reshape(-1)  # contiguous: a view
            for part in passes:
                view[flat[part]] += values[part]
    half_m = 0.5 * np.asarray(mesh.lateral_mass) * le
    half_j = 0.5 * np.asarray(mesh.rotary_inertia) * le
    m = np.zeros(2 * n)
    dofs = 2 * np.arange(ne)[:, None] + np.arange(4)[None, :]  # (ne, 4)
    lumped = np.stack([half_m, half_j, half_m, half_j], axis=1)
    for part in passes:
        m[dofs[part]] += lumped[part]
    return k, kg, m


def assemble_lateral(mesh: Mesh, axial_force: np.ndarray | None = None,
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Dense (2n x 2n) lateral stiffness, geometric stiffness and lumped mass of one
    plane: :func:`assemble_lateral_band` unfolded (for modal analysis and tests)."""
    k, kg, m = assemble_lateral_band(mesh, axial_force)
    return from_band(k), from_band(kg), m


def assemble_torsion_band(mesh: Mesh) -> tuple[np.ndarray, np.ndarray]:
    """Torsional stiffness in band storage (2, n) and lumped polar inertia (n,): the
    element loop of :func:`assemble_torsion` to the last bit (each entry is the sum of
    at most two element terms, ``0 + a + b`` in either order)."""
    n = mesh.n_nodes
    ke = np.asarray(mesh.torsional_stiffness, dtype=float) / np.asarray(
        mesh.element_length, dtype=float)
    half = 0.5 * np.asarray(mesh.polar_inertia, dtype=float) * np.asarray(
        mesh.element_length, dtype=float)
    k = np.zeros((2, n))
    k[0, :-1] += ke
    k[0, 1:] += ke
    k[1, :-1] = -ke
    j = np.zeros(n)
    j[:-1] += half
    j[1:] += half
    return k, j


def assemble_torsion(mesh: Mesh) -> tuple[np.ndarray, np.ndarray]:
    """Dense torsional stiffness (n x n) and lumped polar inertia (n,):
    :func:`assemble_torsion_band` unfolded."""
    k, j = assemble_torsion_band(mesh)
    return from_band(k), j


def mud_torsional_damping(mesh: Mesh, per_length: float) -> np.ndarray:
    """Lumped viscous drag coefficient of each node (N m s/rad)."""
    c = np.zeros(mesh.n_nodes)
    half = 0.5 * per_length * mesh.element_length
    c[:-1] += half
    c[1:] += half
    return c


# --------------------------------------------------------------------------- banded storage


def to_band(dense: np.ndarray, bandwidth: int) -> np.ndarray:
    """Upper band of a symmetric matrix: ``band[d, i] = A[i, i + d]`` (zero past the end)."""
    n = dense.shape[0]
    band = np.zeros((bandwidth + 1, n))
    for d in range(bandwidth + 1):
        band[d, : n - d] = np.diagonal(dense, d)
    return band


def from_band(band: np.ndarray) -> np.ndarray:
    n = band.shape[1]
    dense = np.zeros((n, n))
    for d in range(band.shape[0]):
        idx = np.arange(n - d)
        dense[idx, idx + d] = band[d, : n - d]
        dense[idx + d, idx] = band[d, : n - d]
    return dense
