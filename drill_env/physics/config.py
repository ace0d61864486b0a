"""Frozen, validated configuration of the drill-string model (SI units throughout).

Every default documents where it comes from. Configs are plain dataclasses so that
they can be built from a dict or YAML (:func:`from_dict`) and compared, hashed and
pickled. Validation happens in ``__post_init__`` and raises ``ValueError`` naming the
offending field.
"""

from __future__ import annotations

import dataclasses
import math
import types
import typing
from dataclasses import dataclass, field
from typing import Any

INCH = 0.0254
GRAVITY = 9.81


def _require(condition: bool, name: str, message: str) -> None:
    if not condition:
        raise ValueError(f"{name}: {message}")


def require_finite(value: float, name: str) -> None:
    """Raise ``ValueError`` naming ``name`` unless ``value`` is a finite number."""
    _require(isinstance(value, (int, float)) and math.isfinite(value), name,
             f"must be a finite number, got {value!r}")


def require_positive(value: float, name: str) -> None:
    require_finite(value, name)
    _require(value > 0, name, f"must be > 0, got {value!r}")


def require_non_negative(value: float, name: str) -> None:
    require_finite(value, name)
    _require(value >= 0, name, f"must be >= 0, got {value!r}")


# --------------------------------------------------------------------------- string


@dataclass(frozen=True)
class Section:
    """A uniform tubular section of the string (drill pipe or drill collars)."""

    length: float
    outer_diameter: float
    inner_diameter: float
    element_length: float
    #: Steel, API 5DP / 7-1 (E = 207 GPa, G = 79.5 GPa, rho = 7850 kg/m^3).
    youngs_modulus: float = 2.07e11
    shear_modulus: float = 7.95e10
    density: float = 7850.0

    def __post_init__(self) -> None:
        for name in ("length", "outer_diameter", "element_length", "youngs_modulus",
                     "shear_modulus", "density"):
            require_positive(getattr(self, name), name)
        require_non_negative(self.inner_diameter, "inner_diameter")
        _require(self.inner_diameter < self.outer_diameter, "inner_diameter",
                 "must be smaller than outer_diameter")
        _require(self.element_length <= self.length, "element_length",
                 "must not exceed the section length")

    @property
    def area(self) -> float:
        return math.pi / 4 * (self.outer_diameter**2 - self.inner_diameter**2)

    @property
    def second_moment(self) -> float:
        """Area moment of inertia I about a diameter (m^4)."""
        return math.pi / 64 * (self.outer_diameter**4 - self.inner_diameter**4)

    @property
    def polar_moment(self) -> float:
        """Polar moment J = 2 I (m^4)."""
        return 2.0 * self.second_moment

    @property
    def torsional_impedance(self) -> float:
        """Characteristic torsional impedance Z = J sqrt(G rho) (N m s/rad)."""
        return self.polar_moment * math.sqrt(self.shear_modulus * self.density)

    @property
    def torsional_wave_speed(self) -> float:
        return math.sqrt(self.shear_modulus / self.density)

    @property
    def n_elements(self) -> int:
        return max(1, round(self.length / self.element_length))


def _default_pipe() -> Section:
    # 5 in, 19.5 lb/ft drill pipe: OD 127.0 mm, ID 108.6 mm (API 5DP). 10 m elements
    # resolve the first torsional modes and the helical-buckling pitch (~40 m).
    return Section(length=1000.0, outer_diameter=5.0 * INCH, inner_diameter=4.276 * INCH,
                   element_length=10.0)


def _default_bha() -> Section:
    # 6 1/2 in x 2 13/16 in drill collars (API 7-1), meshed 10x finer than the pipe
    # because the BHA carries the lateral dynamics and the wall contacts near the bit.
    return Section(length=35.0, outer_diameter=6.5 * INCH, inner_diameter=2.8125 * INCH,
                   element_length=1.0)


@dataclass(frozen=True)
class StringConfig:
    """Drill pipe over a BHA of drill collars (paper Table 1: 1000 m string, 35 m BHA)."""

    drill_pipe: Section = field(default_factory=_default_pipe)
    bha: Section = field(default_factory=_default_bha)
    #: Borehole diameter; an 8 3/4 in PDC bit drills an 8 3/4 in hole.
    hole_diameter: float = 8.75 * INCH
    #: Stabilizer positions, metres above the bit. A slick 35 m BHA of 6 1/2 in collars
    #: buckles at ~60 kN (pi^2 EI / L^2), below the paper's 75-100 kN WOB, so the default
    #: is a packed BHA: near-bit stabilizer plus two string stabilizers (a common
    #: vertical-hole assembly). Each sits on the nearest node.
    stabilizers: tuple[float, ...] = (1.0, 10.0, 19.0)
    #: Stabilizer blade diameter: 1/8 in under gauge, the usual API undergauge.
    stabilizer_diameter: float = 8.625 * INCH

    def __post_init__(self) -> None:
        require_positive(self.hole_diameter, "hole_diameter")
        require_positive(self.stabilizer_diameter, "stabilizer_diameter")
        _require(self.stabilizer_diameter < self.hole_diameter, "stabilizer_diameter",
                 "must be smaller than hole_diameter (clearance <= 0)")
        for k, pos in enumerate(self.stabilizers):
            _require(0.0 < pos < self.bha.length + self.drill_pipe.length, f"stabilizers[{k}]",
                     f"{pos} m above the bit is outside the string")

        for name in ("drill_pipe", "bha"):
            od = getattr(self, name).outer_diameter
            _require(od < self.hole_diameter, f"{name}.outer_diameter",
                     f"{od} m must be smaller than hole_diameter {self.hole_diameter} m "
                     "(clearance <= 0)")

    @property
    def length(self) -> float:
        return self.drill_pipe.length + self.bha.length


@dataclass(frozen=True)
class MudConfig:
    """Drilling fluid: buoyancy, added lateral mass and viscous torsional drag."""

    #: 10 ppg water-based mud.
    density: float = 1200.0
    #: Added-mass coefficient of the displaced fluid for lateral motion; 1.0 is the
    #: potential-flow value for a cylinder in unbounded fluid (confinement raises it).
    added_mass_coefficient: float = 1.0
    #: Viscous drag torque per unit length and angular speed (N m s/rad per m). Chosen so
    #: the 1035 m string needs ~1 kN m off-bottom torque at 100 rpm, a typical field
    #: figure for a shallow vertical well; it also sets the damping of the first
    #: torsional mode, and so the stick-slip threshold.
    torsional_damping: float = 0.1

    def __post_init__(self) -> None:
        require_non_negative(self.density, "density")
        require_non_negative(self.added_mass_coefficient, "added_mass_coefficient")
        require_non_negative(self.torsional_damping, "torsional_damping")


@dataclass(frozen=True)
class DampingConfig:
    """Structural damping C = a M_lat + b K (Rayleigh).

    The mass-proportional term acts on the lateral DOFs only: applied to torsion it
    would brake rigid-body rotation and create a spurious surface torque.
    """

    #: a (1/s): 8 % damping of a 1 Hz lateral mode, a rough stand-in for mud drag.
    mass_proportional: float = 1.0
    #: b (s): damps the mesh-scale modes (zeta ~ 0.3 at the highest torsional frequency)
    #: while leaving the first torsional mode almost untouched (zeta ~ 2e-4).
    stiffness_proportional: float = 1.0e-4

    def __post_init__(self) -> None:
        require_non_negative(self.mass_proportional, "mass_proportional")
        require_non_negative(self.stiffness_proportional, "stiffness_proportional")


@dataclass(frozen=True)
class ContactConfig:
    """String-to-borehole wall contact (paper eqs. 17-26)."""

    enabled: bool = True
    #: Penalty stiffness k of eq. (18). Formation + tool-joint compliance of the order of
    #: 1e7 N/m is common in FE drill-string codes; the explicit contact step needs
    #: dt < 2 sqrt(m/k), which holds at dt = 1 ms for every node of the default mesh.
    stiffness: float = 1.0e7
    #: Penalty damping c of eq. (18): ~10 % of critical for a 1 m collar node.
    damping: float = 5.0e3
    #: Velocity-dependent wall friction mu(v) = mu_kin + (mu_static - mu_kin) exp(-|v|/v_s).
    friction_static: float = 0.30
    friction_kinetic: float = 0.25
    friction_decay_speed: float = 0.1
    #: Friction is regularised linearly below this slip speed (m/s), see docs/model.md.
    regularisation_speed: float = 1.0e-3

    def __post_init__(self) -> None:
        for name in ("stiffness", "friction_decay_speed", "regularisation_speed"):
            require_positive(getattr(self, name), name)
        for name in ("damping", "friction_static", "friction_kinetic"):
            require_non_negative(getattr(self, name), name)


@dataclass(frozen=True)
class TopDriveConfig:
    """Top drive: motor inertia, PI speed loop, torque limit."""

    #: Top-drive rotor inertia referred to the output shaft (kg m^2); Kyllingstad &
    #: Nessjoen (2009) quote 500-3000 kg m^2 for electric top drives.
    inertia: float = 1000.0
    #: PI gains of the speed loop. None selects the stiff controller of the literature:
    #: P = 50 Z (Z: drill-pipe torsional impedance), I = 5 J_td (1/s^2).
    proportional_gain: float | None = None
    integral_gain: float | None = None
    #: Continuous torque rating of a mid-size top drive (N m).
    max_torque: float = 50.0e3
    #: Rate limit of the speed set point (rad/s^2): 0 -> 150 rpm in ~5 s.
    max_acceleration: float = 3.0

    def __post_init__(self) -> None:
        require_positive(self.inertia, "inertia")
        require_positive(self.max_torque, "max_torque")
        require_positive(self.max_acceleration, "max_acceleration")
        for name in ("proportional_gain", "integral_gain"):
            value = getattr(self, name)
            if value is not None:
                require_non_negative(value, name)


# --------------------------------------------------------------------------- bit & rock


@dataclass(frozen=True)
class RockConfig:
    """A rock's bit-resistance curve (eq. 39) and its wall behaviour at the gauge (eq. 55).

    mu(w) = sign(w) (mu_min + (mu_max - mu_min) exp(-|w / st1|) + st2 |w|)
    """

    name: str = "rock"
    mu_min: float = 0.5
    mu_max: float = 0.9
    #: Decay speed of the falling curve (rad/s).
    st1: float = 3.0
    #: Slope of the rising branch (s/rad).
    st2: float = 0.0
    #: Gauge contact stiffness and damping of eq. (55).
    wall_stiffness: float = 2.0e7
    wall_damping: float = 2.0e3
    #: Depth of cut per bit revolution and per newton of WOB (m/(rev N)).
    depth_of_cut: float = 2.0e-8

    def __post_init__(self) -> None:
        for name in ("mu_min", "mu_max", "st2", "wall_damping", "depth_of_cut"):
            require_non_negative(getattr(self, name), name)
        for name in ("st1", "wall_stiffness"):
            require_positive(getattr(self, name), name)
        _require(self.mu_max >= self.mu_min, "mu_max", "must be >= mu_min")


@dataclass(frozen=True)
class Interface:
    """A planar formation boundary.

    ``depth`` is where the plane crosses the borehole axis (m, measured depth of a
    vertical well), ``dip`` the angle between the plane and the horizontal (deg), and
    ``azimuth`` the direction of steepest descent in the hole's x-y plane (deg from x).
    """

    depth: float
    dip: float = 45.0
    azimuth: float = 0.0

    def __post_init__(self) -> None:
        require_finite(self.depth, "depth")
        require_finite(self.dip, "dip")
        require_finite(self.azimuth, "azimuth")
        _require(0.0 <= self.dip < 90.0, "dip", f"must be in [0, 90) deg, got {self.dip}")


@dataclass(frozen=True)
class FormationConfig:
    """Layers separated by planar interfaces, top to bottom.

    ``layers[k]`` names the rock of layer k (index into ``rocks``); layer 0 lies above
    ``interfaces[0]``, layer k between interfaces k-1 and k. Interfaces must not cross
    inside the region the bit visits.
    """

    rocks: tuple[RockConfig, ...] = (RockConfig(),)
    interfaces: tuple[Interface, ...] = ()
    layers: tuple[int, ...] = (0,)

    def __post_init__(self) -> None:
        _require(len(self.rocks) >= 1, "rocks", "needs at least one rock")
        _require(len(self.layers) == len(self.interfaces) + 1, "layers",
                 f"needs len(interfaces) + 1 = {len(self.interfaces) + 1} entries, "
                 f"got {len(self.layers)}")
        for k, rock in enumerate(self.layers):
            _require(0 <= rock < len(self.rocks), f"layers[{k}]",
                     f"rock index {rock} out of range 0..{len(self.rocks) - 1}")
        depths = [i.depth for i in self.interfaces]
        _require(depths == sorted(depths), "interfaces", "must be sorted by depth")


@dataclass(frozen=True)
class BitConfig:
    """Mesoscopic PDC bit (paper section 3.1, eqs. 28-35).

    Per blade i: angle ``blade_angles[i]`` (deg), face from radius ``face_start[i]``
    (point A) to ``face_end[i]`` (point B), a shoulder of length ``shoulder_length[i]``
    at ``shoulder_angle`` from the bit axis reaching the gauge radius (point C:
    r_C = r_B + l_sh sin(alpha_sh)), and a gauge pad of length ``gauge_length[i]`` (C-D).
    """

    #: 8 3/4 in PDC bit, six blades.
    diameter: float = 8.75 * INCH
    #: Radial clearance between gauge pads and borehole wall (paper section 4: 0.005 m).
    gauge_clearance: float = 0.005
    blade_angles: tuple[float, ...] = (0.0, 60.0, 120.0, 180.0, 240.0, 300.0)
    face_start: tuple[float, ...] = (0.015,) * 6
    face_end: tuple[float, ...] = (0.070,) * 6
    shoulder_angle: float = 60.0
    shoulder_length: tuple[float, ...] = ()
    gauge_length: tuple[float, ...] = (0.05,) * 6
    #: Bit mass (kg) and polar inertia (kg m^2): ~ a 50 kg steel body, m r^2 / 2.
    mass: float = 50.0
    inertia: float = 0.3
    #: Hold the bit axis parallel to the hole axis (paper section 3.1.1: with a 1/16 in
    #: gauge clearance the tilt of the bit is negligible). The bit node's tilt DOFs are
    #: then fixed; lateral translation stays free. Without it the free bit end under the
    #: dead WOB load is a tilting mechanism (a column with a free end buckles at P = 0).
    axis_aligned: bool = True

    def __post_init__(self) -> None:
        n = len(self.blade_angles)
        _require(n >= 1, "blade_angles", "needs at least one blade")
        require_positive(self.diameter, "diameter")
        require_positive(self.gauge_clearance, "gauge_clearance")
        _require(self.gauge_clearance < self.diameter / 2, "gauge_clearance",
                 "must be smaller than the bit radius")
        _require(0.0 < self.shoulder_angle <= 90.0, "shoulder_angle",
                 f"must be in (0, 90] deg, got {self.shoulder_angle}")
        if not self.shoulder_length:
            # Shoulders reach the gauge radius: r_C = r_B + l_sh sin(alpha_sh).
            sin_a = math.sin(math.radians(self.shoulder_angle))
            lengths = tuple((self.gauge_radius - rb) / sin_a for rb in self.face_end)
            object.__setattr__(self, "shoulder_length", lengths)
        for name in ("face_start", "face_end", "shoulder_length", "gauge_length"):
            values = getattr(self, name)
            _require(len(values) == n, name, f"needs one value per blade ({n}), got {len(values)}")
            for v in values:
                require_non_negative(v, name)
        for i in range(n):
            _require(self.face_start[i] < self.face_end[i], f"face_end[{i}]",
                     "must be larger than face_start")
            r_c = self.face_end[i] + self.shoulder_length[i] * math.sin(
                math.radians(self.shoulder_angle))
            _require(r_c <= self.gauge_radius + 1e-9, f"shoulder_length[{i}]",
                     f"blade reaches radius {r_c:.4f} m beyond the gauge radius "
                     f"{self.gauge_radius:.4f} m")
        require_positive(self.mass, "mass")
        require_positive(self.inertia, "inertia")

    @property
    def hole_radius(self) -> float:
        return self.diameter / 2

    @property
    def gauge_radius(self) -> float:
        return self.diameter / 2 - self.gauge_clearance

    @property
    def n_blades(self) -> int:
        return len(self.blade_angles)


# --------------------------------------------------------------------------- simulation


FIDELITY_LEVELS = ("full", "fast")
#: Fast level: 25 m drill-pipe elements keep the first torsional frequency of the
#: default string within 0.1 % (40 linear elements over 1000 m; tests/physics/
#: test_fidelity.py) and the torsional wave resolved to ~10 Hz.
FAST_PIPE_ELEMENT_LENGTH = 20.0
#: Fast level step: the explicit contact and gauge terms are stable up to half their
#: critical step (~3.7 ms for 1 m collar elements at the default wall stiffness;
#: Simulator.stable_time_step shortens a longer request).
FAST_TIME_STEP = 4.0e-3
#: Fast level: 0.8 of the lumped-mass critical step (the full model takes 0.5). Stable
#: with the stick-slip metrics unchanged in tests/physics/test_fidelity.py.
FAST_CRITICAL_STEP_FRACTION = 0.8


@dataclass(frozen=True)
class SolverConfig:
    """Time integration (see docs/model.md, "Integrator")."""

    #: Requested step (s); the simulator may shorten it to the stable step of the
    #: explicit force terms and to divide the control interval evenly.
    time_step: float = 2.0e-3
    #: False freezes the lateral DOFs (torsion only): the paper's case 1 studies torsion
    #: alone, and torsion-only runs are ~3x cheaper for stability maps.
    lateral: bool = True
    #: False holds the drill pipe laterally straight (no lateral DOFs above the BHA; the
    #: BHA top node is pinned) while the BHA keeps its full lateral FE model and wall
    #: contacts. Valid while the pipe is in tension (neutral point in the BHA), where the
    #: whirl and bit-wall contacts live in the BHA.
    pipe_lateral: bool = True
    #: "full": the model as configured. "fast": the training level of docs/performance.md,
    #: resolved by :meth:`SimulationConfig.resolved`: pipe laterally straight
    #: (``pipe_lateral=False``), drill-pipe elements of at least
    #: ``FAST_PIPE_ELEMENT_LENGTH``, a time step of ``FAST_TIME_STEP`` and
    #: ``FAST_CRITICAL_STEP_FRACTION`` of the critical step.
    fidelity: str = "full"
    #: The step is shortened to this fraction of the critical step 2 sqrt(m/k) of the
    #: explicit wall and gauge penalties, computed from the lumped node mass alone. The
    #: implicit neighbours add effective mass, so even 1.0 keeps a margin; 0.5 is the
    #: full model's conservative choice, the fast level uses FAST_CRITICAL_STEP_FRACTION.
    critical_step_fraction: float = 0.5

    def __post_init__(self) -> None:
        require_positive(self.time_step, "time_step")
        require_positive(self.critical_step_fraction, "critical_step_fraction")
        _require(self.critical_step_fraction <= 1.0, "critical_step_fraction",
                 f"must be <= 1 (explicit stability), got {self.critical_step_fraction}")
        _require(self.fidelity in FIDELITY_LEVELS, "fidelity",
                 f"must be one of {FIDELITY_LEVELS}, got {self.fidelity!r}")


BIT_MODELS = ("mesoscopic", "macroscopic")


@dataclass(frozen=True)
class SimulationConfig:
    string: StringConfig = field(default_factory=StringConfig)
    mud: MudConfig = field(default_factory=MudConfig)
    damping: DampingConfig = field(default_factory=DampingConfig)
    contact: ContactConfig = field(default_factory=ContactConfig)
    top_drive: TopDriveConfig = field(default_factory=TopDriveConfig)
    bit: BitConfig = field(default_factory=BitConfig)
    formation: FormationConfig = field(default_factory=FormationConfig)
    solver: SolverConfig = field(default_factory=SolverConfig)
    #: "mesoscopic" (paper section 3) or "macroscopic" (eq. 38, torque only).
    bit_model: str = "mesoscopic"
    #: Measured depth of the bit face at t = 0 (m).
    initial_depth: float | None = None

    def __post_init__(self) -> None:
        _require(self.bit_model in BIT_MODELS, "bit_model",
                 f"must be one of {BIT_MODELS}, got {self.bit_model!r}")
        _require(self.bit.diameter <= self.string.hole_diameter + 1e-12, "bit.diameter",
                 "must not exceed string.hole_diameter")
        if self.initial_depth is not None:
            require_finite(self.initial_depth, "initial_depth")

    def resolved(self) -> SimulationConfig:
        """This config with ``solver.fidelity`` expanded into the fields it sets.

        "full" returns the config unchanged. "fast" holds the drill pipe laterally
        straight, coarsens its elements to at least ``FAST_PIPE_ELEMENT_LENGTH`` and
        requests ``FAST_TIME_STEP`` at ``FAST_CRITICAL_STEP_FRACTION`` of the critical
        step; the BHA mesh, the bit and the contacts stay.
        """
        if self.solver.fidelity == "full":
            return self
        pipe = self.string.drill_pipe
        element = min(max(pipe.element_length, FAST_PIPE_ELEMENT_LENGTH), pipe.length)
        return replace(self, **{
            "solver.pipe_lateral": False,
            "solver.time_step": max(self.solver.time_step, FAST_TIME_STEP),
            "solver.critical_step_fraction": max(self.solver.critical_step_fraction,
                                                 FAST_CRITICAL_STEP_FRACTION),
            "string.drill_pipe.element_length": element,
        })


# --------------------------------------------------------------------------- dict / YAML


def from_dict(cls: type, data: dict[str, Any] | None) -> Any:
    """Build a (nested) config dataclass from plain dicts, lists and numbers.

    Unknown keys raise ``ValueError`` naming the key, so typos do not pass silently.
    """
    if data is None:
        return cls()
    if dataclasses.is_dataclass(data):
        return data
    if not isinstance(data, dict):
        raise ValueError(f"{cls.__name__}: expected a mapping, got {type(data).__name__}")
    hints = typing.get_type_hints(cls)
    names = {f.name for f in dataclasses.fields(cls)}
    unknown = set(data) - names
    if unknown:
        raise ValueError(f"{cls.__name__}: unknown field(s) {sorted(unknown)}")
    kwargs = {}
    for key, value in data.items():
        kwargs[key] = _convert(hints[key], value, f"{cls.__name__}.{key}")
    return cls(**kwargs)


def _convert(hint: Any, value: Any, name: str) -> Any:
    origin = typing.get_origin(hint)
    if dataclasses.is_dataclass(hint):
        return from_dict(hint, value)
    if origin in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(hint) if a is not type(None)]
        if value is None:
            return None
        return _convert(args[0], value, name)
    if origin is tuple:
        args = typing.get_args(hint)
        item = args[0]
        if not isinstance(value, (list, tuple)):
            raise ValueError(f"{name}: expected a list, got {value!r}")
        return tuple(_convert(item, v, name) for v in value)
    return value


def replace(config: Any, **changes: Any) -> Any:
    """``dataclasses.replace`` with dotted paths: ``replace(c, **{"mud.density": 1.1e3})``."""
    nested: dict[str, dict[str, Any]] = {}
    flat: dict[str, Any] = {}
    for key, value in changes.items():
        head, _, rest = key.partition(".")
        if rest:
            nested.setdefault(head, {})[rest] = value
        else:
            flat[key] = value
    for head, sub in nested.items():
        if not hasattr(config, head):
            raise ValueError(f"{type(config).__name__}: unknown field {head!r}")
        flat[head] = replace(getattr(config, head), **sub)
    names = {f.name for f in dataclasses.fields(config)}
    unknown = set(flat) - names
    if unknown:
        raise ValueError(f"{type(config).__name__}: unknown field(s) {sorted(unknown)}")
    return dataclasses.replace(config, **flat)
