"""Frozen, validated configuration of the drill-string model (SI units throughout).

Every default documents where it comes from, every field has a type and a physical range
(:mod:`drill_env.physics.validation`: pydantic dataclasses, errors name the dotted path
the user typed, e.g. ``string.bha.inner_diameter``). Configs are plain frozen dataclasses:
they can be built from a dict or YAML (:func:`from_dict`, :func:`load_yaml`), compared,
hashed and pickled. Ranges are wide physical bounds (nothing a real drilling system
exceeds), and limits that keep a simulation finite in time and memory.
"""

from __future__ import annotations

import math
from dataclasses import field
from typing import Annotated, Literal, get_args

from pydantic import Field

from drill_env.physics import fidelity
from drill_env.physics.fidelity import FIDELITY_LEVELS, Fidelity
from drill_env.physics.hole_fit import check_bit_in_hole
from drill_env.physics.units import GRAVITY, INCH
from drill_env.physics.validation import (
    ConfigError,
    Count,
    DriveTorque,
    Finite,
    FluidDensity,
    NonNegative,
    Positive,
    StrictBool,
    config_dataclass,
    flatten,
    from_dict,
    load_yaml,
    replace,
    require_distinct_angles,
    require_finite,
    require_non_negative,
    require_positive,
)

__all__ = [
    "BIT_MODELS", "FIDELITY_LEVELS", "GRAVITY", "INCH", "BitConfig", "Component", "ConfigError",
    "ContactConfig", "DampingConfig", "FormationConfig", "Interface", "MudConfig", "RockConfig",
    "Section", "SimulationConfig", "SolverConfig", "StringConfig", "TopDriveConfig", "WellConfig",
    "flatten", "from_dict", "load_yaml", "replace", "require_finite", "require_non_negative",
    "require_positive"]

#: Longest string (m): the deepest wells drilled are ~12 km measured depth.
MAX_STRING_LENGTH = 15_000.0
#: Most elements in a string: ~100k DOFs, a few ms per step; far more than any converged
#: mesh needs (docs/performance.md), and a bound on memory and time per step.
MAX_ELEMENTS = 20_000
#: Largest tubular or hole diameter (m): 36 in conductor hole is ~0.91 m.
MAX_DIAMETER = 1.0
#: Shortest time step (s): below it one 0.1 s control interval takes > 10^4 steps.
MIN_TIME_STEP = 1.0e-5
#: Heaviest drilling fluid (kg/m^3): weighted muds stay below ~2.6 g/cc; a margin above.
MAX_MUD_DENSITY = 3000.0


def _require(condition: bool, name: str, message: str) -> None:
    if not condition:
        raise ValueError(f"{name}: {message}")


# --------------------------------------------------------------------------- string


#: What a component is (labels for tables and plots; the physics reads the numbers only).
ComponentKind = Literal["drill_pipe", "heavy_weight", "collar", "stabilizer", "mwd", "jar",
                        "motor", "bit_sub", "other"]


@config_dataclass
class Section:
    """A uniform tubular component of the string: drill pipe, heavy-weight pipe, collars, a
    stabilizer, an MWD tool, a jar, ... (``Component`` is the same class).

    A component touches the wall at ``contact_diameter`` (stabilizer blades, wear pads)
    when given, else at its outer diameter; its mass and stiffness come from the outer
    and inner diameters of its body. Presets: :mod:`drill_env.physics.components`."""

    length: Positive = Field(le=MAX_STRING_LENGTH)
    outer_diameter: Positive = Field(lt=MAX_DIAMETER)
    inner_diameter: NonNegative = Field(lt=MAX_DIAMETER)
    element_length: Positive = Field(ge=0.01, le=MAX_STRING_LENGTH)
    #: Steel, API 5DP / 7-1 (E = 207 GPa, G = 79.5 GPa, rho = 7850 kg/m^3). Bounds: any
    #: engineering metal (aluminium 70 GPa, tungsten 19300 kg/m^3) fits inside them.
    youngs_modulus: Positive = Field(default=2.07e11, ge=1.0e9, le=1.0e12)
    shear_modulus: Positive = Field(default=7.95e10, ge=1.0e9, le=1.0e12)
    density: Positive = Field(default=7850.0, ge=1000.0, le=25_000.0)
    kind: ComponentKind = "other"
    name: str = ""
    #: Diameter that touches the wall (stabilizer blades); None: the outer diameter.
    contact_diameter: Annotated[Positive, Field(lt=MAX_DIAMETER)] | None = None

    def __post_init__(self) -> None:
        _require(self.inner_diameter < self.outer_diameter, "inner_diameter",
                 f"must be smaller than outer_diameter ({self.outer_diameter} m), got "
                 f"{self.inner_diameter} m")
        _require(self.element_length <= self.length, "element_length", "must not exceed "
                 f"the section length ({self.length} m), got {self.element_length} m")
        _require(self.n_elements <= MAX_ELEMENTS, "element_length",
                 f"{self.length} m / {self.element_length} m gives {self.n_elements} "
                 f"elements, more than {MAX_ELEMENTS}")
        if self.contact_diameter is not None:
            _require(self.contact_diameter >= self.outer_diameter, "contact_diameter",
                     f"{self.contact_diameter} m must not be smaller than outer_diameter "
                     f"({self.outer_diameter} m)")

    @property
    def label(self) -> str:
        """Its name, or its kind when it has none."""
        return self.name or self.kind.replace("_", " ")

    @property
    def wall_diameter(self) -> float:
        """The diameter that touches the wall (m)."""
        return self.outer_diameter if self.contact_diameter is None else self.contact_diameter

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
                   element_length=10.0, kind="drill_pipe")


def _default_bha() -> Section:
    # 6 1/2 in x 2 13/16 in drill collars (API 7-1), meshed 10x finer than the pipe
    # because the BHA carries the lateral dynamics and the wall contacts near the bit.
    return Section(length=35.0, outer_diameter=6.5 * INCH, inner_diameter=2.8125 * INCH,
                   element_length=1.0, kind="collar")


#: Component is the name to use when building a string from parts.
Component = Section

#: Stabilizers of the paper's 35 m BHA (m above the bit): see StringConfig.stabilizers.
LEGACY_STABILIZERS = (1.0, 10.0, 19.0)


@config_dataclass
class StringConfig:
    """The drill string: ``drill_pipe`` at the top, over a BHA.

    The BHA is either one section (``bha``: the paper's Table 1, 35 m of collars under
    1000 m of pipe, the default) or an ordered list of ``components`` from the bit up
    (bit sub, stabilizers, MWD, collars, jar, heavy-weight pipe, lower drill pipe, ...);
    giving ``components`` replaces ``bha``. Presets of common sizes and the scenarios'
    realistic strings: :mod:`drill_env.physics.components`."""

    drill_pipe: Section = field(default_factory=_default_pipe)
    bha: Section = field(default_factory=_default_bha)
    #: The BHA (and any pipe below the top drill pipe) from the bit up; replaces ``bha``.
    #: None: the single ``bha`` section (an empty list is refused: it would mean that).
    components: tuple[Section, ...] | None = None
    #: Borehole diameter; an 8 3/4 in PDC bit drills an 8 3/4 in hole.
    hole_diameter: Positive = Field(default=8.75 * INCH, le=MAX_DIAMETER)
    #: Extra stabilizer positions, metres above the bit, each on the nearest node with
    #: ``stabilizer_diameter``. None: the paper BHA's (1, 10, 19) with the single-section
    #: ``bha`` (a slick 35 m BHA of 6 1/2 in collars buckles at ~60 kN, pi^2 EI / L^2,
    #: below the paper's 75-100 kN WOB, so it is packed: near-bit stabilizer plus two
    #: string stabilizers), none with ``components`` (stabilizers are components there).
    stabilizers: tuple[Positive, ...] | None = None
    #: Blade diameter of the ``stabilizers`` positions (a component of kind stabilizer has
    #: its own contact_diameter): 1/8 in under the hole (docs/model.md); >1 in under warns.
    stabilizer_diameter: Positive = Field(default=8.625 * INCH, le=MAX_DIAMETER)

    def __post_init__(self) -> None:
        _require(self.components != (), "components", "an empty list; give at least one "
                 "component from the bit up, or leave it out for the single bha section")
        if self.components:
            _require(self.bha == _default_bha(), "components",
                     "give the BHA either as one section (bha) or as components, not both")
        _require(not self.stabilizer_positions or self.stabilizer_diameter
                 < self.hole_diameter, "stabilizer_diameter",  # only where it places any
                 f"{self.stabilizer_diameter} m (default: 1/8 in under an 8 3/4 in gauge) is not "
                 f"below hole_diameter {self.hole_diameter} m (clearance <= 0); set it for this "
                 "hole")
        from drill_env.physics.components import check_stabilizers  # it imports this module

        check_stabilizers(self)
        named = [("drill_pipe", self.drill_pipe)] + (
            [(f"components[{k}]", c) for k, c in enumerate(self.components)]
            if self.components else [("bha", self.bha)])
        for name, section in named:
            diameter = section.wall_diameter
            field_name = "contact_diameter" if section.contact_diameter is not None else \
                "outer_diameter"
            _require(diameter < self.hole_diameter, f"{name}.{field_name}",
                     f"{diameter} m must be smaller than hole_diameter {self.hole_diameter} m "
                     "(clearance <= 0)")
        longest = max(named, key=lambda item: item[1].length)[0]  # what the user lengthened
        _require(self.length <= MAX_STRING_LENGTH, f"{longest}.length", f"the string is "
                 f"{self.length} m long, more than {MAX_STRING_LENGTH} m")
        n = sum(s.n_elements for s in self.sections)
        _require(n <= MAX_ELEMENTS, "drill_pipe.element_length",
                 f"the string has {n} elements, more than {MAX_ELEMENTS}")

    @property
    def lower(self) -> tuple[Section, ...]:
        """Everything below the top drill pipe, from the bit up."""
        return self.components if self.components else (self.bha,)

    @property
    def sections(self) -> tuple[Section, ...]:
        """Every component from the surface down (the order of the mesh)."""
        return (self.drill_pipe, *reversed(self.lower))

    @property
    def bha_length(self) -> float:
        """Length of everything below the top drill pipe (m)."""
        return sum(s.length for s in self.lower)

    @property
    def length(self) -> float:
        return self.drill_pipe.length + self.bha_length

    @property
    def stabilizer_positions(self) -> tuple[float, ...]:
        """The extra stabilizers placed on nodes (see ``stabilizers``)."""
        if self.stabilizers is not None:
            return self.stabilizers
        return () if self.components else LEGACY_STABILIZERS


@config_dataclass
class MudConfig:
    """Drilling fluid: buoyancy, added lateral mass and viscous torsional drag."""

    #: 10 ppg water-based mud (kg/m^3: 0.5-3 and 5-25 warn, typed as SG, in ppg). Lighter
    #: than the string (SimulationConfig checks it): a string lighter than its mud floats.
    density: FluidDensity = Field(default=1200.0, le=MAX_MUD_DENSITY)
    #: Added-mass coefficient of the displaced fluid for lateral motion; 1.0 is the
    #: potential-flow value for a cylinder in unbounded fluid (confinement raises it).
    added_mass_coefficient: NonNegative = Field(default=1.0, le=10.0)
    #: Viscous drag torque per unit length and angular speed (N m s/rad per m). Chosen so
    #: the 1035 m string needs ~1 kN m off-bottom torque at 100 rpm, a typical field
    #: figure for a shallow vertical well; it also sets the damping of the first
    #: torsional mode, and so the stick-slip threshold.
    torsional_damping: NonNegative = Field(default=0.1, le=100.0)


@config_dataclass
class DampingConfig:
    """Structural damping C = a M_lat + b K (Rayleigh).

    The mass-proportional term acts on the lateral DOFs only: applied to torsion it
    would brake rigid-body rotation and create a spurious surface torque.
    """

    #: a (1/s): 8 % damping of a 1 Hz lateral mode, a rough stand-in for mud drag.
    mass_proportional: NonNegative = Field(default=1.0, le=1.0e3)
    #: b (s): damps the mesh-scale modes (zeta ~ 0.3 at the highest torsional frequency)
    #: while leaving the first torsional mode almost untouched (zeta ~ 2e-4).
    stiffness_proportional: NonNegative = Field(default=1.0e-4, le=1.0)


@config_dataclass
class ContactConfig:
    """String-to-borehole wall contact (paper eqs. 17-26)."""

    enabled: StrictBool = True
    #: Penalty stiffness k of eq. (18). Formation + tool-joint compliance of the order of
    #: 1e7 N/m is common in FE drill-string codes; the explicit contact step needs
    #: dt < 2 sqrt(m/k), which holds at dt = 1 ms for every node of the default mesh.
    stiffness: Positive = Field(default=1.0e7, le=1.0e10)
    #: Penalty damping c of eq. (18). 3e4 N s/m is ~35 % of critical for the lightest
    #: contact node (1 m of collar with mud and added mass, 167 kg on the paper string,
    #: k = 1e7 N/m: 37 %, restitution 0.39 with the no-pull clamp; docs/model.md): steel
    #: striking rock through a mud film loses most of its normal speed (squeeze-film
    #: damping). With the earlier 5e3 (6 %, restitution 0.83) a symmetric bit thrown to the
    #: wall by a layer kept whirling backward in homogeneous rock forever; with this value
    #: it settles after the layer, as in the paper (docs/paper-reproduction.md, P6).
    damping: NonNegative = Field(default=3.0e4, le=1.0e8)
    #: Velocity-dependent wall friction mu(v) = mu_kin + (mu_static - mu_kin) exp(-|v|/v_s):
    #: 0.25-0.30, the open-hole friction factors of torque-and-drag practice (docs/model.md).
    #: Kinetic above static is taken: friction that rises with the slip speed, a choice.
    friction_static: NonNegative = Field(default=0.30, le=2.0)
    friction_kinetic: NonNegative = Field(default=0.25, le=2.0)
    friction_decay_speed: Positive = Field(default=0.1, le=100.0)
    #: Friction is regularised linearly below this slip speed (m/s), see docs/model.md.
    regularisation_speed: Positive = Field(default=1.0e-3, le=1.0)


@config_dataclass
class TopDriveConfig:
    """Top drive: motor inertia, speed controller, torque limit.

    ``controller`` names the drive-rate controller; its gains and filters follow from the
    configured string by the rules of :mod:`drill_env.physics.top_drive` (docs/model.md,
    "Top drive"), so a string change retunes it. A field given explicitly overrides the
    rule's value.
    """

    #: Top-drive rotor inertia referred to the output shaft (kg m^2); Kyllingstad &
    #: Nessjoen (2009) quote 500-3000 kg m^2 for electric top drives.
    inertia: Positive = Field(default=1000.0, le=1.0e6)
    #: "stiff": PI with P = 50 Z, I = 5 J_td; "soft_speed": tuned PI (Kyllingstad &
    #: Nessjoen 2009); "soft_torque": stiff PI + band-pass torque feedback at the
    #: stick-slip frequency; "z_torque": stiff PI + high-pass torque feedback through
    #: 1/Z (Dwars 2015). Formulas and sources: drill_env.physics.top_drive.
    controller: Literal["stiff", "soft_speed", "soft_torque", "z_torque"] = "stiff"
    #: PI gains of the speed loop (N m s/rad, N m/rad); None: the controller's rule.
    proportional_gain: Annotated[NonNegative, Field(le=1.0e9)] | None = None
    integral_gain: Annotated[NonNegative, Field(le=1.0e9)] | None = None
    #: Frequency the soft controllers tune to (Hz); None: the first torsional natural
    #: frequency of the string with a fixed top and a free bit, which stick-slip
    #: oscillates close to (Kyllingstad & Nessjoen 2009).
    tuning_frequency: Annotated[Positive, Field(le=100.0)] | None = None
    #: SoftSpeed's P = impedance_factor x Z. k = 1 matches the pipe exactly (no
    #: reflection at the tuning frequency), but the top absorbs only within ~kZ / (4 pi
    #: J_td) Hz of it (0.02 Hz at k = 1 on the default string), and with the soft top in
    #: the loop the first mode splits into two on either side of that band (0.37 and
    #: 0.53 Hz at k = 1.5), which the bit's falling friction drives: stick-slip grows
    #: back, slowly (at k = 1.5 from a 2 % kick to full size in ~90 s, at k = 2 in
    #: ~180 s). Over 240 s on the default string at 50 rpm / 100 kN and 60 rpm / 150 kN
    #: only k = 4 decays at both (k = 3 still grows at 150 kN, k = 5 and 6 grow back);
    #: the reflection at the tuning frequency is then (k - 1)/(k + 1) = 0.6.
    #: Measured in docs/controllers.md ("SoftSpeed's k").
    impedance_factor: Positive = Field(default=4.0, le=100.0)
    #: Feedback of the string torque at the top T_s (the torque in the top pipe element,
    #: as a torque sub measures it) into the speed command at every time step:
    #: ``w_cmd = w_set - feedback_gain H(T_s)``; "high_pass": H first-order with corner
    #: ``filter_frequency``; "band_pass": H second-order of unit gain at
    #: ``filter_frequency`` with damping ``filter_damping``. Neither passes DC: the mean
    #: speed still follows the set point. None: the controller's choice.
    torque_feedback: Literal["none", "high_pass", "band_pass"] | None = None
    #: (rad/s per N m); None: 1/Z of the drill pipe, so the top absorbs the torsional waves
    #: the filter passes. Refused where the drive runs no torque feedback.
    feedback_gain: Annotated[NonNegative, Field(le=1.0)] | None = None
    #: Corner (high-pass) or centre (band-pass) of the torque filter (Hz); None: the rule.
    filter_frequency: Annotated[Positive, Field(le=100.0)] | None = None
    #: Damping ratio of the band-pass: its -3 dB band is 2 zeta f wide.
    filter_damping: Positive = Field(default=0.5, le=10.0)
    #: Continuous torque rating of a mid-size top drive (N m; below 1,000 warns: in kN m?).
    max_torque: DriveTorque = Field(default=50.0e3, le=1.0e6)
    #: Rate limit of the speed set point (rad/s^2): 0 -> 150 rpm in ~5 s (tests: 1e4).
    max_acceleration: Positive = Field(default=3.0, le=1.0e6)

    def __post_init__(self) -> None:  # a gain for no feedback was dropped without a word
        _require(self.feedback_gain is None or self.feedback() != "none", "feedback_gain",
                 f"the {self.controller} drive runs no torque feedback (torque_feedback "
                 f"{self.torque_feedback or 'not set'}), so it would change nothing: set "
                 "torque_feedback to 'high_pass' or 'band_pass'")

    def feedback(self) -> str:
        """``torque_feedback``, else its controller's (SoftTorque's, ZTorque's) or "none"."""
        return self.torque_feedback or {"soft_torque": "band_pass",
                                        "z_torque": "high_pass"}.get(self.controller, "none")


# --------------------------------------------------------------------------- bit & rock


@config_dataclass
class RockConfig:
    """A rock's bit-resistance curve (eq. 39) and its wall behaviour at the gauge (eq. 55).

    mu(w) = sign(w) (mu_min + (mu_max - mu_min) exp(-|w / st1|) + st2 |w|)
    """

    name: str = "rock"
    mu_min: NonNegative = Field(default=0.5, le=5.0)
    mu_max: NonNegative = Field(default=0.9, le=5.0)
    #: Decay speed of the falling curve (rad/s).
    st1: Positive = Field(default=3.0, le=1.0e3)
    #: Slope of the rising branch (s/rad). The presets take 0-0.01; 0.1 adds 2 to mu at
    #: 200 rpm, past any bit; from 0.2 on the default string diverged within 2 s at the
    #: env's top WOB (an outside check, 2026-12-05: 0.5 diverged in the first step).
    st2: NonNegative = Field(default=0.0, le=0.1)
    #: Gauge contact stiffness and damping of eq. (55) (the paper gives no values). The
    #: default is the hard-rock preset's (drill_env/scenarios.py, where the choice of all
    #: three rocks is explained): 0.5 mm of gauge penetration under 10 kN, ~2 % of
    #: critical damping on the default bit node (134 kg), a 62 Hz contact resolved by 8
    #: steps of 2 ms.
    wall_stiffness: Positive = Field(default=2.0e7, le=1.0e10)
    wall_damping: NonNegative = Field(default=2.0e3, le=1.0e8)
    #: Depth of cut per bit revolution and per newton of WOB (m/(rev N)), whatever the bit's
    #: size (the cutting load per unit radius sets it: for a bit k times the 8 3/4 in one,
    #: divide by k); 1e-6 is 100 mm/rev at 100 kN, beyond any PDC bit. The default, 2 mm/rev
    #: at 100 kN, is the first hard-rock preset's; the scenarios' HARD preset doubled it for
    #: a field-like ROP (~9 m/h at 50 rpm, 75 kN); the bare ``Simulator()`` keeps this one.
    depth_of_cut: NonNegative = Field(default=2.0e-8, le=1.0e-6)
    #: Founder point (Dupriest & Koederitz 2005, SPE 92194): the WOB per unit bit diameter
    #: (N/m) above which the depth of cut stops growing with WOB (bit balling, bottom-hole
    #: balling, vibrations); None: the linear law at any WOB. See ``post_founder_slope``.
    founder_wob_per_diameter: Annotated[Positive, Field(le=1.0e8)] | None = None
    #: Above the founder WOB W_f the depth of cut is that of W_f minus this fraction of the
    #: excess: doc (W_f - s (W - W_f)), never below 0, so the ROP peaks at W_f.
    post_founder_slope: NonNegative = Field(default=0.5, le=10.0)

    def __post_init__(self) -> None:
        _require(self.mu_max >= self.mu_min, "mu_max",
                 f"must be >= mu_min ({self.mu_min}), got {self.mu_max}")


@config_dataclass
class Interface:
    """A planar formation boundary.

    ``depth`` is where the plane crosses the borehole axis (m, measured depth), ``dip``
    the angle between the plane and the horizontal (deg), and ``azimuth`` the direction
    of steepest descent (deg from x, which is north). Both are true, relative to the
    vertical: in a curved hole (``well``) the plane is turned into the bit's frame at the
    bit (docs/model.md section 6), so a bed dipping 60 deg south is flat to a bit
    drilling 60 deg north.
    """

    depth: Finite = Field(ge=-1.0e5, le=1.0e5)
    dip: Finite = Field(default=45.0, ge=0.0, lt=90.0)
    azimuth: Finite = Field(default=0.0, ge=-3600.0, le=3600.0)


#: Most rocks and interfaces of one formation: the bit kernel splits every blade segment
#: at every interface, so the work per step grows with their number.
MAX_ROCKS = 16
MAX_INTERFACES = 64


@config_dataclass
class FormationConfig:
    """Layers separated by planar interfaces, top to bottom.

    ``layers[k]`` names the rock of layer k (index into ``rocks``); layer 0 lies above
    ``interfaces[0]``, layer k between interfaces k-1 and k. Interfaces must not cross
    within the bit's radius of the hole axis (the simulator refuses them). In a curved
    hole (``well``) "above" means before the crossing along the hole: the layers are in
    the order the hole meets them, which for a hole drilling up-section (a bed dipping
    more steeply than the hole's inclination, toward the hole's direction) is from the
    geologically lower rock up.
    """

    rocks: tuple[RockConfig, ...] = (RockConfig(),)
    interfaces: tuple[Interface, ...] = ()
    layers: tuple[Count, ...] = (0,)

    def __post_init__(self) -> None:
        _require(1 <= len(self.rocks) <= MAX_ROCKS, "rocks",
                 f"needs 1 to {MAX_ROCKS} rocks, got {len(self.rocks)}")
        _require(len(self.interfaces) <= MAX_INTERFACES, "interfaces",
                 f"at most {MAX_INTERFACES}, got {len(self.interfaces)}")
        _require(len(self.layers) == len(self.interfaces) + 1, "layers",
                 f"needs len(interfaces) + 1 = {len(self.interfaces) + 1} entries, "
                 f"got {len(self.layers)}")
        for k, rock in enumerate(self.layers):
            _require(0 <= rock < len(self.rocks), f"layers[{k}]",
                     f"rock index {rock} out of range 0..{len(self.rocks) - 1}")
        depths = [i.depth for i in self.interfaces]
        _require(depths == sorted(depths), "interfaces", "must be sorted by depth")


#: Most blades of a bit (PDC bits have 3 to ~12).
MAX_BLADES = 32


@config_dataclass
class BitConfig:
    """Mesoscopic PDC bit (paper section 3.1, eqs. 28-35).

    Per blade i: angle ``blade_angles[i]`` (deg), face from radius ``face_start[i]``
    (point A) to ``face_end[i]`` (point B), a shoulder of length ``shoulder_length[i]``
    at ``shoulder_angle`` from the bit axis reaching the gauge radius (point C:
    r_C = r_B + l_sh sin(alpha_sh)), and a gauge pad of length ``gauge_length[i]`` (C-D).
    """

    #: 8 3/4 in PDC bit, six blades.
    diameter: Positive = Field(default=8.75 * INCH, le=MAX_DIAMETER)
    #: Gauge-pad to wall clearance (paper section 4: 0.005 m, its results; section 3.1.1
    #: says 1/16 in; backward whirl turns at -R/clearance, ~21x the bit speed here);
    #: at least 0.1 mm (a bit's is millimetres; radial ratios divide by it).
    gauge_clearance: Positive = Field(default=0.005, ge=1.0e-4)
    #: Blade geometry (the paper gives the parametrisation of its Fig. 6, not numbers;
    #: these are read off a generic six-bladed 8 3/4 in PDC bit like its Fig. 4): six
    #: blades at equal angles (a symmetric bit: no net lateral force in homogeneous rock,
    #: the paper's cases 2-3); the face from 15 mm (the cone at the centre has no cutters)
    #: to 70 mm, about 2/3 of the 111 mm radius; the shoulder at 60 deg from the bit axis
    #: up to the gauge (empty: the lengths that reach it, bit.shoulder_lengths); 2 in pads.
    blade_angles: tuple[Annotated[Finite, Field(ge=-360.0, le=360.0)], ...] = (
        0.0, 60.0, 120.0, 180.0, 240.0, 300.0)
    face_start: tuple[NonNegative, ...] = (0.015,) * 6
    face_end: tuple[NonNegative, ...] = (0.070,) * 6
    shoulder_angle: Positive = Field(default=60.0, le=90.0)
    shoulder_length: tuple[NonNegative, ...] = ()
    gauge_length: tuple[Annotated[NonNegative, Field(le=1.0)], ...] = (0.05,) * 6
    #: Bit mass (kg) and polar inertia (kg m^2): ~ a 50 kg steel body, m r^2 / 2.
    mass: Positive = Field(default=50.0, le=1.0e4)
    inertia: Positive = Field(default=0.3, le=1.0e3)
    #: Friction coefficient of the gauge pads against the wall. None: the rock's resistance
    #: curve (eq. 57 as written, mu 0.5-0.9 for hard rock); gauge pads are smooth,
    #: hard-faced surfaces, closer to 0.2-0.3 against rock (docs/model.md, "Gauge").
    gauge_friction: Annotated[NonNegative, Field(le=2.0)] | None = None
    #: Hold the bit axis parallel to the hole axis (paper section 3.1.1: with a 1/16 in
    #: gauge clearance the tilt of the bit is negligible). The bit node's tilt DOFs are
    #: then fixed; lateral translation stays free. Without it the free bit end under the
    #: dead WOB load is a tilting mechanism (a column with a free end buckles at P = 0).
    axis_aligned: StrictBool = True

    def __post_init__(self) -> None:
        n = len(self.blade_angles)
        _require(1 <= n <= MAX_BLADES, "blade_angles",
                 f"needs 1 to {MAX_BLADES} blades, got {n}")
        require_distinct_angles(self.blade_angles, "blade_angles")  # two blades in one place
        _require(self.gauge_clearance < self.diameter / 2, "gauge_clearance",
                 f"{self.gauge_clearance} m must be smaller than the bit radius "
                 f"(diameter / 2 = {self.diameter / 2} m)")
        for name in ("face_start", "face_end", "gauge_length"):
            _require(len(values := getattr(self, name)) == n, name, f"needs one value per "
                     f"blade (len(blade_angles) = {n}), got {len(values)}")
        for i in range(n):
            _require(self.face_start[i] < self.face_end[i], f"face_end[{i}]",
                     f"must be larger than face_start[{i}] ({self.face_start[i]} m), got "
                     f"{self.face_end[i]} m")
            _require(self.face_end[i] <= self.gauge_radius, f"face_end[{i}]",
                     f"{self.face_end[i]} m lies beyond the gauge radius (diameter / 2 - "
                     f"gauge_clearance = {self.gauge_radius:.4f} m); a bit of another "
                     "diameter needs its own face_end (the default is the 8.75 in bit's)")
        from drill_env.physics.bit import shoulder_lengths  # it imports this module

        lengths = shoulder_lengths(self)  # empty: to the gauge, of this bit's size
        _require(all(map(math.isfinite, lengths)), "shoulder_angle", f"{self.shoulder_angle} "
                 "deg: shoulders this close to the bit axis never reach the gauge radius")
        _require(len(lengths) == n, "shoulder_length", f"needs one value per blade "
                 f"(len(blade_angles) = {n}), got {len(lengths)}")
        for i in range(n):
            r_c = self.face_end[i] + lengths[i] * math.sin(math.radians(self.shoulder_angle))
            _require(r_c <= self.gauge_radius + 1e-9, f"shoulder_length[{i}]",
                     f"blade reaches radius {r_c:.4f} m beyond the gauge radius (diameter / "
                     f"2 - gauge_clearance = {self.gauge_radius:.4f} m)")

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


@config_dataclass
class WellConfig:
    """The hole's path by survey stations (docs/model.md section 6): measured depth (m,
    from 0), inclination (0-180) and azimuth (+-360) in degrees, by minimum curvature. No
    stations: the vertical hole. The string's nodes feel, in the hole's local
    twist-free frames, the buoyed weight across the hole and the tension turning with
    it; the axial force follows the true vertical depth. The survey must reach the
    deepest node (the string's length or ``initial_depth``); a hole still vertical at
    that node warns (md typed in feet?)."""

    md: tuple[NonNegative, ...] = ()
    inclination: tuple[Finite, ...] = ()
    azimuth: tuple[Finite, ...] = ()

    def __post_init__(self) -> None:
        sizes = {"md": len(self.md), "inclination": len(self.inclination),
                 "azimuth": len(self.azimuth)}
        if not any(sizes.values()):
            return
        if len(set(sizes.values())) > 1:
            short = [k for k, v in sizes.items() if v < max(sizes.values())]  # or missing
            raise ValueError(f"{', '.join(short)}: one value per survey station in each of "
                             f"md, inclination and azimuth, got {sizes}")
        from drill_env.physics.trajectory import Survey

        try:
            Survey.from_stations(self.md, self.inclination, self.azimuth)
        except ValueError as err:
            # the section's name is added by the config loader: "well.md: ..."
            raise ValueError(str(err).replace("survey.", "").replace(
                "survey:", "md:")) from None

    @property
    def vertical(self) -> bool:
        """No stations, or every station vertical: the straight vertical hole."""
        return not any(abs(i) > 0.0 for i in self.inclination)


@config_dataclass
class SolverConfig:
    """Time integration (see docs/model.md, "Integrator")."""

    #: Requested step (s); the simulator may shorten it to the stable step of the
    #: explicit force terms (an env then takes round(control_interval / step) steps per
    #: control interval: its period is within half a step of it). Bounded below by
    #: MIN_TIME_STEP (time per simulated second) and above by 50 ms (the top drive's PI
    #: loop and the bit's stick test are explicit in the step).
    time_step: Positive = Field(default=2.0e-3, ge=MIN_TIME_STEP, le=0.05)
    #: False freezes the lateral DOFs (torsion only): the paper's case 1 studies torsion
    #: alone, and torsion-only runs are ~3x cheaper for stability maps.
    lateral: StrictBool = True
    #: False holds the drill pipe laterally straight (no lateral DOFs above the BHA; the
    #: BHA top node is pinned) while the BHA keeps its full lateral FE model and wall
    #: contacts. Valid while the pipe is in tension (neutral point in the BHA), where the
    #: whirl and bit-wall contacts live in the BHA.
    pipe_lateral: StrictBool = True
    #: "full": the model as configured. "fast": the training level of docs/performance.md,
    #: resolved by :meth:`SimulationConfig.resolved`: pipe laterally straight
    #: (``pipe_lateral=False``), drill-pipe elements of at least
    #: ``FAST_PIPE_ELEMENT_LENGTH``, a time step of ``FAST_TIME_STEP`` and
    #: ``FAST_CRITICAL_STEP_FRACTION`` of the critical step.
    fidelity: Fidelity = "full"
    #: The step is shortened to this fraction of the critical step 2 sqrt(m/k) of the
    #: explicit wall and gauge penalties on the lumped node mass. Two gauge pads on the
    #: wall at once (2 k cos^2 30 = 1.5 k) lower it to 0.82 of the computed one: above 0.8
    #: a bit thrown at the wall that way runs away (docs/model.md section 5). 0.5 is the
    #: full model's choice, the fast level uses FAST_CRITICAL_STEP_FRACTION (0.75).
    critical_step_fraction: Positive = Field(default=0.5, ge=0.01, le=0.8)
    #: True: the normal wall and gauge penalties are implicit (physics/implicit_contact.py)
    #: and no longer limit the step; an opt-in (docs/performance.md, "Backward whirl").
    implicit_contacts: StrictBool = False


BitModel = Literal["mesoscopic", "macroscopic"]
BIT_MODELS: tuple[str, ...] = get_args(BitModel)


@config_dataclass
class SimulationConfig:
    string: StringConfig = field(default_factory=StringConfig)
    mud: MudConfig = field(default_factory=MudConfig)
    damping: DampingConfig = field(default_factory=DampingConfig)
    contact: ContactConfig = field(default_factory=ContactConfig)
    top_drive: TopDriveConfig = field(default_factory=TopDriveConfig)
    bit: BitConfig = field(default_factory=BitConfig)
    formation: FormationConfig = field(default_factory=FormationConfig)
    solver: SolverConfig = field(default_factory=SolverConfig)
    well: WellConfig = field(default_factory=WellConfig)
    #: "mesoscopic" (paper section 3) or "macroscopic" (eq. 38, torque only).
    bit_model: BitModel = "mesoscopic"
    #: Measured depth of the bit face at t = 0 (m); None: the string length. Given in
    #: physics= or --config: at most that, within 100 m of it (drill_env.overrides).
    initial_depth: Annotated[Finite, Field(ge=0.0, le=1.0e5)] | None = None

    def __post_init__(self) -> None:
        check_bit_in_hole(self.bit.diameter, self.string.hole_diameter)
        lightest = min(s.density for s in self.string.sections)
        _require(self.mud.density < lightest, "mud.density",
                 f"{self.mud.density} kg/m^3 must be below the density of the string "
                 f"({lightest} kg/m^3): the string would float")
        if not self.well.vertical:
            from drill_env.physics.trajectory import check_survey_holds

            check_survey_holds(self)

    def resolved(self) -> SimulationConfig:
        """This config with ``solver.fidelity`` expanded into the fields it sets.

        "full" returns the config unchanged. "fast" holds the drill pipe laterally
        straight, coarsens its elements to at least ``FAST_PIPE_ELEMENT_LENGTH`` and
        requests ``FAST_TIME_STEP`` at ``FAST_CRITICAL_STEP_FRACTION`` of the critical
        step; the BHA mesh, the bit and the contacts stay (implicit contacts only where
        the config asks for them)."""
        if self.solver.fidelity == "full":
            return self
        pipe = self.string.drill_pipe
        element = min(max(pipe.element_length, fidelity.FAST_PIPE_ELEMENT_LENGTH), pipe.length)
        return replace(self, **{
            "solver.pipe_lateral": False,
            "solver.time_step": max(self.solver.time_step, fidelity.FAST_TIME_STEP),
            "solver.critical_step_fraction": max(self.solver.critical_step_fraction,
                                                 fidelity.FAST_CRITICAL_STEP_FRACTION),
            "string.drill_pipe.element_length": element,
        })
