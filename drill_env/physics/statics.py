"""Static axial loads of a hanging string: neutral point and pipe buckling.

The axial force is the buoyed weight below a point minus the WOB
(:func:`drill_env.physics.fem.axial_force_profile`; in a curved hole the weight below
counts by true vertical depth, as the simulator's, :func:`drill_env.physics.trajectory.
hole_loads`). Below the neutral point the string is in compression; a BHA of collars is
built to carry that, drill pipe is not: in a vertical hole a pipe column under its own
weight buckles once its compression exceeds the heavy-column limit
``1.94 (E I w^2)^(1/3)`` (Lubinski 1950, "first-order buckling"; w the buoyed weight per
length), ~8 kN for 5 in drill pipe. Lying on the low side of an inclined hole, the
weight holds the pipe down, and it buckles (sinusoidally) only at
``2 sqrt(E I w sin(i) / r)`` (Dawson & Paslay 1984; i the inclination, r the radial
clearance between pipe body and hole), ~140 kN for 5 in pipe in an 8 3/4 in hole at 60
degrees: each element is judged by the larger of the two limits, the second from 2
degrees on (:data:`DAWSON_PASLAY_MIN_INCLINATION`). Where the hole's inclination
changes with depth at a rate k (rad/m), a compression F along it pushes the pipe to the
outside of the bend with F k per metre: onto the low side where the hole builds (k > 0),
toward the high side where it drops. Their load is taken with the load across the hole
``w sin(i) + F k`` for ``w sin(i)``, at the element's own compression: F is below
``2 sqrt(E I (w sin(i) + F k) / r)`` exactly when it is below the root of
``F^2 = 4 E I (w sin(i) + F k) / r`` (a convex quadratic, negative at F = 0), which is the
critical load. Where a drop's compression outweighs the weight and lifts the pipe off the
low side, the vertical-hole limit stands alone. The FE string agrees: its pipe in holes
building at 1.5 and 2 deg / 30 m from 3 degrees at the surface (53 and 70 degrees at
the pipe's foot, where this load is 1.4-1.5x the straight hole's) held the low side at
0.9 and 1.0 of this load and wound around the hole at 1.3 and 1.5
(tests/physics/test_curved_hole.py checks 0.9 and 1.5). That check is of the stability
argument under this load (bending, wall contact, gravity and rotation in the FE model),
not of the curvature's share itself: the FE string takes a hole's curvature as the same
side load F k on elements straight in their local frames (:func:`~drill_env.physics.
trajectory.hole_loads`, the soft-string load of Johancsik et al. 1984). The published
curved-hole loads (He & Kyllingstad 1993, SPE 25370; Wu & Juvkam-Wold 1995, J. Energy
Resour. Technol. 117) derive a larger share by energy methods; the screen keeps the
model's own, so that what it lets through the simulator carries. The curvature counts from
:data:`DAWSON_PASLAY_MIN_INCLINATION` on, as the weight does. The hole's turn (azimuth)
is not counted: it presses the pipe sideways, which only raises the load across the hole
(conservative).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np

from drill_env.physics.config import SimulationConfig
from drill_env.physics.fem import axial_force_profile, build_mesh
from drill_env.physics.trajectory import bit_depth, hole_loads, string_in_hole
from drill_env.physics.units import GRAVITY, PSI
from drill_env.physics.validation import require_non_negative

#: Kinds of component that are pipe (not built to carry compression).
PIPE_KINDS = frozenset({"drill_pipe", "heavy_weight"})


def is_pipe(section, top: bool) -> bool:
    """Whether a section of the string is pipe: of a :data:`PIPE_KINDS` kind, or the
    string's top section (``top``) whatever its label."""
    return top or section.kind in PIPE_KINDS
#: Lubinski's heavy-column coefficient: F_c = 1.94 (E I w^2)^(1/3), his 1950 value for
#: pipe pinned at its lower end. The exact load of that idealisation falls slowly with the
#: pipe's length (the pin's reaction decays only as 1/x up the string): 1.88 at 10 units
#: of (EI/w)^(1/3), 1.62 at 36 (600 m of 5 in pipe), 1.55 at 60; a free lower end gives
#: 1.02 at any length (tests/physics/test_modes.py checks the FE string against these).
#: It screens scenario definitions (``Scenario`` refuses a start beyond it); no vertical
#: preset scenario compresses its pipe at all (``lateral_60`` compresses its drill pipe on
#: the low side, far below Dawson-Paslay's load), and the FE string models the buckling
#: itself.
LUBINSKI = 1.94
#: Below this inclination (rad, 2 degrees) the vertical-hole load stands alone: the weight
#: across the hole that holds the pipe on the low side in Dawson & Paslay's load is then
#: under 3.5 % of its weight, which a hole's tortuosity can outweigh, and their load, which
#: grows as sqrt(sin i), passes Lubinski's from a fraction of a degree. A choice of ours,
#: not a published threshold. Above it their load is a lower bound of the pipe's (the
#: Rayleigh quotient of a pipe on the low side: compression that falls up the hole and
#: the vertical load's own stiffening only raise it), and the FE string holds the pipe on
#: the low side at 0.8 of it at 1, 2 and 5 degrees (tests/physics/test_curved_hole.py).
#: Until 2026-12-05 it was 10 degrees, which refused at 9.9 degrees 13 kN where their
#: load is ~62 kN and limited curved-well task draws.
DAWSON_PASLAY_MIN_INCLINATION = math.radians(2.0)


@dataclass
class OperatingPoint:
    """A steady state to start from: surface speed (rad/s) and weight on bit (N), both
    finite and >= 0 (the bit drills turning forward, on bottom or just touching)."""

    surface_speed: float = 0.0
    weight_on_bit: float = 0.0

    def __post_init__(self) -> None:
        for name in ("surface_speed", "weight_on_bit"):
            require_non_negative(getattr(self, name), f"OperatingPoint.{name}")


def warn_if_hook_pushes(string_weight: float, weight_on_bit: float) -> None:
    """Warn where ``weight_on_bit`` exceeds the string's hanging weight (N; the buoyed
    weight by true vertical depth in a curved hole): the hook load ``string_weight - WOB``
    is then negative, the top drive pushing the string down, which a conventional rig
    cannot (an outside check found -50 to -480 kN in builds that start near the surface).
    The simulator carries it; one text, so once per place, not per WOB."""
    if weight_on_bit > string_weight:
        warnings.warn("the weight on bit exceeds the string's hanging weight in this hole "
                      "(its buoyed weight by true vertical depth): the hook load is "
                      "negative, the top drive pushing the string down, which a rig "
                      "cannot; a lower WOB or a heavier or longer string "
                      "(docs/model.md)", RuntimeWarning, stacklevel=3)


def bit_buoyed_weight(config: SimulationConfig) -> float:
    """The bit's weight in mud (N); steel like the component it hangs from."""
    return config.bit.mass * GRAVITY * (1.0 - config.mud.density /
                                        config.string.lower[0].density)


def neutral_point_height(config: SimulationConfig, weight_on_bit: float) -> float:
    """Height above the bit (m) where the axial force changes from compression to tension,
    interpolated between element midpoints; the string length if all of it is compressed,
    0 off bottom."""
    if weight_on_bit <= 0.0:
        return 0.0
    mesh = build_mesh(config)
    force, _ = axial_force_and_inclination(config, mesh, weight_on_bit)
    bottom = mesh.node_depth[-1]
    height = bottom - 0.5 * (mesh.node_depth[:-1] + mesh.node_depth[1:])  # midpoints
    compressed = force < 0.0
    if compressed.all():
        return float(config.string.length)
    # force rises going up the string; the last compressed midpoint from the top
    k = int(np.flatnonzero(compressed)[0])  # highest compressed element
    if k == 0:
        return float(height[0])
    f0, f1 = force[k], force[k - 1]  # compressed below, tension above
    h0, h1 = height[k], height[k - 1]
    return float(h0 + (h1 - h0) * (-f0) / (f1 - f0))


@dataclass(frozen=True)
class ComponentLoad:
    """Weights and static axial force of one component (tension > 0)."""

    component: str
    kind: str
    length: float  # m
    bottom_depth: float  # measured depth of its lower end (m)
    weight: float  # in air (N)
    buoyed_weight: float  # in mud (N)
    force_bottom: float  # axial force at its lower end (N)
    force_top: float  # axial force at its upper end (N)


def component_loads(config: SimulationConfig, weight_on_bit: float) -> list[ComponentLoad]:
    """Per component, from the bit up: weight in air and in mud (buoyancy factor
    ``1 - rho_mud / rho_steel``) and the static axial force at both ends,
    ``N = (buoyed weight below) - WOB``, the bit's own weight included."""
    mud = config.mud.density
    force = bit_buoyed_weight(config) - weight_on_bit
    depth = config.string.length
    out = []
    for section in config.string.lower + (config.string.drill_pipe,):
        volume = section.area * section.length
        buoyed = volume * (section.density - mud) * GRAVITY
        out.append(ComponentLoad(section.label, section.kind, section.length, depth,
                                 volume * section.density * GRAVITY, buoyed,
                                 force, force + buoyed))
        force += buoyed
        depth -= section.length
    return out


#: The strongest common drill-pipe grade, API 5DP's S-135: minimum yield 135,000 psi
#: (931 MPa); API RP 7G's maximum allowable design tension is 90 % of the tension at
#: minimum yield of new pipe. The model has no grade: a string past this load is past
#: every common grade's (E-75 yields at 517 MPa, G-105 at 724 MPa), and the load is the
#: lenient bound: new pipe's body, static, no tool joints (the model's 5 in pipe weighs
#: 17.95 lb/ft, real 19.5 lb/ft pipe with its joints ~22-23), no slip crushing, margin of
#: overpull or torque (docs/model.md).
S135_YIELD, RP7G_DESIGN_FACTOR = 135_000 * PSI, 0.9


@dataclass(frozen=True)
class OverTension:
    """A pipe component whose static tension passes the allowable design load of new
    S-135 pipe."""

    component: str
    tension: float  # at its top, hanging straight (N)
    allowable: float  # 0.9 x 931 MPa x its body's area (N)


def over_allowable_tension(config: SimulationConfig, weight_on_bit: float
                           ) -> list[OverTension]:
    """The pipe components (drill pipe, heavy-weight pipe and the string's top section),
    from the bit up, whose static tension at their top (hanging straight:
    :func:`component_loads`; a curved hole's true vertical depth lowers it, drag while
    pulling out raises it) is above the allowable design tension of new S-135 pipe of
    their body (:data:`S135_YIELD`, :data:`RP7G_DESIGN_FACTOR`): within 10 % of its
    minimum yield, past the design limit of any common grade; the model has no yield.
    The BHA below the pipe carries less tension than the pipe above it."""
    sections = config.string.lower + (config.string.drill_pipe,)  # component_loads' order
    out = []
    for k, (load, section) in enumerate(zip(component_loads(config, weight_on_bit),
                                            sections, strict=True)):
        allowable = RP7G_DESIGN_FACTOR * S135_YIELD * section.area
        if is_pipe(section, top=k == len(sections) - 1) and load.force_top > allowable:
            out.append(OverTension(load.component, load.force_top, allowable))
    return out


@dataclass(frozen=True)
class PipeBuckling:
    """A pipe component compressed beyond its buckling load."""

    component: str
    compression: float  # compression where it comes nearest to buckling (N)
    buckling_load: float  # the buckling load there (N)
    measured_depth: float = math.nan  # of that place (m; the bit at initial_depth)
    inclination: float = 0.0  # of the hole there (rad)
    #: the hole drops there and the compression lifts the pipe off the low side (its
    #: weight no longer holds it down: the vertical-hole limit applies)
    lifted: bool = False

    @property
    def place(self) -> str:
        """"at 367 m measured depth" (and ", 10.0 deg inclination" in a curved hole): a
        horizontal well's pipe may buckle first where the vertical-hole limit still holds,
        not where it is most compressed."""
        where = f"at {self.measured_depth:.0f} m measured depth"
        if self.inclination > 0.0:
            where += f", {math.degrees(self.inclination):.1f} deg inclination"
        if self.lifted:
            where += (", where the hole drops and the compression lifts the pipe off the "
                      "low side")
        return where


def axial_force_and_inclination(config: SimulationConfig, mesh, weight_on_bit: float
                                ) -> tuple[np.ndarray, np.ndarray]:
    """Static axial force at the element midpoints (N, tension > 0) at this WOB, the
    buoyed weight below by true vertical depth in a curved hole (as the simulator's),
    and the hole's inclination there (rad; 0 in a vertical hole)."""
    return _axial_force_and_inclination(config, mesh, weight_on_bit,
                                        string_in_hole(config, mesh))


def _axial_force_and_inclination(config: SimulationConfig, mesh, weight_on_bit: float,
                                 placed) -> tuple[np.ndarray, np.ndarray]:
    """:func:`axial_force_and_inclination` of a string already placed in its hole
    (``string_in_hole``'s result)."""
    bit_weight = bit_buoyed_weight(config)
    if placed is None:
        return (axial_force_profile(mesh, weight_on_bit, bit_weight),
                np.zeros(mesh.node_depth.shape[0] - 1))
    trajectory, node_md = placed
    hole = hole_loads(trajectory, node_md, mesh.buoyed_weight, bit_weight)
    middle = np.maximum(0.5 * (node_md[:-1] + node_md[1:]), 0.0)
    return hole.axial_weight - weight_on_bit, trajectory.inclination(middle)


def pipe_buckling(config: SimulationConfig, weight_on_bit: float) -> list[PipeBuckling]:
    """The pipe components (drill pipe, heavy-weight pipe) whose compression at this WOB
    exceeds their buckling load somewhere: the larger of Lubinski's vertical-hole limit
    and Dawson-Paslay's at the hole's inclination (module docstring), element by element;
    empty when the pipe is safe. Each names the compression and the limit of the element
    that comes nearest to buckling (in a vertical hole: the most compressed)."""
    mesh = build_mesh(config)
    placed = string_in_hole(config, mesh)  # (once: it builds the survey's trajectory)
    force, inclination = _axial_force_and_inclination(config, mesh, weight_on_bit, placed)
    node_md = mesh.node_depth + (bit_depth(config) - mesh.node_depth[-1])
    middle_md = 0.5 * (node_md[:-1] + node_md[1:])
    sin_i = np.where(inclination >= DAWSON_PASLAY_MIN_INCLINATION, np.sin(inclination), 0.0)
    build = np.zeros_like(inclination)  # rad/m the inclination grows along the element
    if placed is not None:
        trajectory, md = placed
        ends = trajectory.inclination(np.maximum(md, 0.0))
        build = (ends[1:] - ends[:-1]) / np.maximum(np.diff(md), 1e-9)
    out = []
    for index, section in enumerate(config.string.sections):
        if not is_pipe(section, top=index == 0):
            continue
        mine = mesh.component == index
        w = (section.density - config.mud.density) * section.area * GRAVITY
        ei = section.youngs_modulus * section.second_moment
        clearance = 0.5 * (config.string.hole_diameter - section.outer_diameter)
        # the load across the hole that holds the pipe down: its weight's, and what its
        # compression (-force) presses out of a build or lifts along a drop (module
        # docstring); below DAWSON_PASLAY_MIN_INCLINATION the vertical limit alone
        held = np.where(sin_i[mine] > 0.0,
                        np.maximum(w * sin_i[mine] - force[mine] * build[mine], 0.0), 0.0)
        limit = np.maximum(LUBINSKI * (ei * w * w) ** (1 / 3),
                           2.0 * np.sqrt(ei * held / clearance))
        ratio = -force[mine] / limit
        worst = int(np.argmax(ratio))
        if ratio[worst] > 1.0:
            out.append(PipeBuckling(section.label, -float(force[mine][worst]),
                                    float(limit[worst]), float(middle_md[mine][worst]),
                                    float(inclination[mine][worst]),
                                    bool(sin_i[mine][worst] > 0.0 and held[worst] == 0.0)))
    return out


#: An element may carry this share of its own (pinned-pinned, element-length) buckling
#: load: past ~pi^2 EI / L_e^2 the lumped tilt DOFs of one Hermite element go spuriously
#: unstable within milliseconds (coupled lateral model only).
ELEMENT_BUCKLING_SHARE = 0.8


def element_buckling_error(config: SimulationConfig, mesh, weight_on_bit: float,
                           axial_weight: np.ndarray, lateral_start: int) -> str:
    """Why ``weight_on_bit`` (N) compresses an element with lateral DOFs (from
    ``lateral_start`` on) beyond what it resolves, naming the field to refine; "" if
    none does. ``axial_weight``: the axial force at element midpoints at zero WOB (N;
    ``Simulator.axial_weight``, along the hole in a curved one)."""
    n = axial_weight - weight_on_bit
    limit = np.pi**2 * mesh.bending_stiffness / mesh.element_length**2
    ratio = -n / limit
    ratio[:lateral_start] = 0.0  # pipe held straight: no lateral DOFs to buckle
    worst = int(np.argmax(ratio))
    if ratio[worst] <= ELEMENT_BUCKLING_SHARE:
        return ""
    string = config.string
    index = int(mesh.component[worst])
    if index == 0:
        field_name = "drill_pipe"
    elif string.components:
        field_name = f"components[{len(string.components) - index}]"
    else:
        field_name = "bha"
    return (f"weight_on_bit={weight_on_bit:.0f} N compresses element {worst} "
            f"({string.sections[index].label}, {mesh.element_length[worst]:.1f} m) to "
            f"{ratio[worst]:.0%} of its own buckling load: refine "
            f"string.{field_name}.element_length or reduce WOB")


def resolved_weight_on_bit(config: SimulationConfig, mesh, axial_weight: np.ndarray,
                           lateral_start: int) -> float:
    """A WOB (N) below which :func:`element_buckling_error` finds nothing, so control
    steps skip the axial profile. The force is affine in WOB (N_e = c_e - WOB), so the
    ratio passes the share iff WOB > c_e + share x limit_e; the margin of 1e-9 relative
    keeps rounding on the safe side: at and above it the full check decides."""
    if not config.solver.lateral:
        return math.inf
    limit = np.pi**2 * mesh.bending_stiffness / mesh.element_length**2
    allowed = (axial_weight + ELEMENT_BUCKLING_SHARE * limit)[lateral_start:]
    if allowed.size == 0:
        return math.inf
    lowest = float(np.min(allowed))
    return lowest - 1.0e-9 * abs(lowest)
