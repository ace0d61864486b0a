"""Named drilling scenarios: a physics configuration plus episode defaults.

A scenario is a function returning a :class:`Scenario`: the frozen
:class:`~drill_env.physics.config.SimulationConfig` of the run, the operating point the
episode starts from and its default duration. :func:`make_scenario` looks one up by name
(unknown names raise ``ValueError`` listing the known ones).

========================  ==============================================================
name                      what it is (parameters)
========================  ==============================================================
``default``               homogeneous hard rock, symmetric bit, realistic 1250 m string
                          (packed 108 m BHA + 140 m HWDP + 5 in DP)
``stick_slip``            the default string and rock at 50 rpm, 100 kN: a stiff top drive
                          stick-slips there (SSI ~1.3), the benchmark's second scenario
``paper_case1``           hard-soft-hard sandwich dipping 45 deg, symmetric bit placed at
                          one of the paper's torsional-map positions ``position`` = P1..P6
                          (share of the bit in rock 2: 0, 25, 75, 100, 50, 0 %)
``paper_case2``           the same sandwich, symmetric bit approaching it (``position``
                          P1 by default): stick-slip fades in the soft layer and returns
``paper_case3``           hard - very soft - hard sandwich, symmetric bit
``paper_case4``           hard-soft-hard sandwich, asymmetric bit (continuous whirl)
``random``                randomised training distribution drawn from an RNG (rock
                          curves, layer depth/thickness/dip/azimuth, bit symmetric or
                          asymmetric, string length, start operating point); takes
                          ``string_length_range``, ``rpm_range``,
                          ``weight_on_bit_range`` and ``episode_duration`` instead of
                          the parameters below (an env takes the two start ranges as
                          ``start_rpm_range``, ``start_weight_on_bit_range``)
``j_shaped``              the default string and hard rock in a J-shaped well (kick-off
                          500 m, 3 deg/30 m to 45 deg; :data:`drill_env.well.WELLS`)
``s_shaped``              the same in an S-shaped well (to 30 deg, vertical again below
                          1200 m)
``lateral_60``            the same in a 60-degree well (kick-off 300 m, 4 deg/30 m)
========================  ==============================================================

Every named scenario but ``random`` takes ``surface_speed`` (rad/s) and ``weight_on_bit``
(N), the operating point the episode starts from, ``episode_duration`` (s) and
``string_length`` (m, total measured length of pipe + BHA; the element COUNT is kept, so
changing it changes the element length only and all envs keep equal array shapes); the
paper cases take their own as well (``position``, ...): :func:`scenario_parameters`
lists a scenario's.

The rock presets :data:`HARD`, :data:`SOFT` and :data:`VERY_SOFT` live here and only here.
"""

from __future__ import annotations

import dataclasses
import inspect
import math
from collections.abc import Callable, Collection, Mapping
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import Field

from drill_env.overrides import drawn_with_physics, with_physics
from drill_env.physics.bit import asymmetric_bit, symmetric_bit
from drill_env.physics.components import realistic_string
from drill_env.physics.config import (
    INCH,
    MAX_STRING_LENGTH,
    BitConfig,
    FormationConfig,
    Interface,
    RockConfig,
    Section,
    SimulationConfig,
    SolverConfig,
    StringConfig,
    replace,
)
from drill_env.physics.formation import interface_depth_for_share
from drill_env.physics.statics import neutral_point_height, pipe_buckling
from drill_env.physics.trajectory import bit_depth
from drill_env.physics.units import RPM
from drill_env.physics.validation import (
    Finite,
    NonNegative,
    Positive,
    StrictBool,
    check_newtons,
    config_dataclass,
    did_you_mean,
    validated,
)

# --------------------------------------------------------------------------- rock presets
# MODELLING CHOICES: the paper gives no rock-curve numbers (docs/model.md, "Rocks and
# scenarios"). They are chosen so that hard rock has a strongly falling curve
# (stick-slip tendency at low rpm and high WOB), soft rock a flat one, very soft rock a
# low, rising one. Tune them HERE; every scenario reads these three constants.
#
# Gauge contact (eq. 55; no values in the paper): the stiffness follows the rocks'
# Young's moduli in the paper's order (Table 2: rock 1 stiffer than rock 2), 2e7, 5e6
# and 1e6 N/m, i.e. 0.5, 2 and 10 mm of gauge penetration under a 10 kN side force (the
# very soft rock yields like a washed-out wall). The damping keeps every rock's gauge
# contact at ~2 % of critical on the bit node of the default string (134 kg: c = 2 zeta
# sqrt(k m) gives 2e3, 1e3 and 5e2 N s/m): lightly damped, so gauge impacts rebound, as in
# the paper's transitions. The stiffest contact rings at 62 Hz, resolved by 8 steps of
# 2 ms, and `Simulator.stable_time_step` covers it.

#: Hard rock: falling curve mu 0.9 -> 0.5 over ~3 rad/s (stick-slip tendency).
#: Linear stability of the paper string (``SimulationConfig()``: 1000 m of pipe, 35 m BHA)
#: puts its stick-slip threshold at 71 rpm for 75 kN and 79 rpm for 100 kN (stiff top
#: drive; the ``default`` scenario's 1250 m string: 64 and 72 rpm): stick-slip at 50 rpm,
#: none at 100 rpm (paper Fig. 13, 14). Depth of cut 3 mm/rev at 75 kN (~9 m/h at 50 rpm).
HARD = RockConfig(name="hard", mu_min=0.5, mu_max=0.9, st1=3.0, st2=0.0,
                  wall_stiffness=2.0e7, wall_damping=2.0e3, depth_of_cut=4.0e-8,
                  founder_wob_per_diameter=6.8e5, post_founder_slope=0.5)
#: Soft rock: nearly flat curve, softer wall, twice the depth of cut of hard rock.
#: Threshold 29 rpm at 75 kN, 38 rpm at 100 kN on the paper string (21 and 31 rpm on the
#: ``default`` scenario's): steady at 50 rpm.
SOFT = RockConfig(name="soft", mu_min=0.3, mu_max=0.45, st1=5.0, st2=0.005,
                  wall_stiffness=5.0e6, wall_damping=1.0e3, depth_of_cut=8.0e-8,
                  founder_wob_per_diameter=5.0e5, post_founder_slope=0.5)
#: Very soft rock: low, rising curve, very soft wall, fast drilling.
#: It falls by 0.002 up to 17 rpm (1.8 rad/s: slope st2 - (mu_max - mu_min) / st1 e^(-w /
#: st1)), then rises; the falling part's negative damping is below the string's, so
#: steady rotation is stable at every speed (linear stability of the default string at
#: 100 and 200 kN).
#:
#: Founder points (Dupriest & Koederitz 2005: the WOB beyond which the depth of cut stops
#: responding, from bit balling or vibrations; field founder points of PDC bits lie at
#: roughly 2-5 klbf per inch of bit diameter, 0.35-0.9 MN/m): 680 kN/m for hard rock
#: (151 kN on an 8 3/4 in bit), 500 kN/m for soft (111 kN) and 360 kN/m for very soft
#: rock (80 kN; soft rocks ball the bit at lower loads); past them the depth of cut falls
#: by half the excess WOB (post_founder_slope 0.5), so the ROP peaks at the founder WOB.
#: The paper's cases (75-100 kN) stay below them.
VERY_SOFT = RockConfig(name="very_soft", mu_min=0.2, mu_max=0.3, st1=8.0, st2=0.01,
                       wall_stiffness=1.0e6, wall_damping=5.0e2, depth_of_cut=1.6e-7,
                       founder_wob_per_diameter=3.6e5, post_founder_slope=0.5)

#: Paper section 4: share of rock 2 (the middle layer) under the front blades at the
#: torsional-map positions, and which interface sets it ("top": entering the layer,
#: "bottom": leaving it).
POSITIONS: dict[str, tuple[float, str]] = {
    "P1": (0.00, "top"), "P2": (0.25, "top"), "P3": (0.75, "top"),
    "P4": (1.00, "top"), "P5": (0.50, "bottom"), "P6": (0.00, "bottom"),
}

#: Seeds of the held-out evaluation set of the ``random`` scenario. Training code must
#: not reset with these (``drill-env train`` draws its envs' seeds from 2**31 up,
#: ``training.config.TRAINING_SEEDS``, and validates from 900,000).
EVALUATION_SEEDS: tuple[int, ...] = tuple(range(1_000_000, 1_000_020))

#: The paper's operating points (SPEC 2.4: 100 kN in hard rock, no stick-slip at 100 rpm,
#: stick-slip at 50 rpm): the default drills smoothly, ``stick_slip`` moves to 50 rpm.
DEFAULT_SURFACE_SPEED = 100.0 * RPM
DEFAULT_WEIGHT_ON_BIT = 100.0e3
#: 60 s: tens of periods of the strings' first torsional mode (below 1 Hz), so stick-slip
#: grows to its full cycle and the benchmark's 30 s warm-up leaves 30 s to measure.
DEFAULT_EPISODE_DURATION = 60.0


#: Types of the scenario parameters (checked on every call; errors name the parameter).
SurfaceSpeed = Annotated[NonNegative, Field(le=1000.0 * RPM)]  # rad/s
WeightOnBit = Annotated[NonNegative, Field(le=1.0e7)]  # N
Duration = Annotated[Positive, Field(le=3.2e7)]  # s
StringLengthValue = Annotated[Positive, Field(le=MAX_STRING_LENGTH)]  # m
StringLength = StringLengthValue | None
Rpm = Annotated[NonNegative, Field(le=1000.0)]
Position = Literal["P1", "P2", "P3", "P4", "P5", "P6"]
Thickness = Annotated[Positive, Field(le=1000.0)]  # m along the hole axis
Dip = Annotated[Finite, Field(ge=0.0, le=85.0)]  # deg; 85: see sandwich()
Lead = Annotated[NonNegative, Field(le=100.0)]  # m


@config_dataclass
class Scenario:
    """A physics configuration and the defaults of an episode in it.

    A scenario whose starting WOB compresses drill pipe or heavy-weight pipe beyond its
    buckling load (:func:`~drill_env.physics.statics.pipe_buckling`) in the coupled
    lateral model is refused unless ``allow_pipe_buckling``: such a string buckles into
    the wall and whirls (docs/model.md, "Axial load and buckling"). The torsion-only
    model has no lateral motion and is exempt.
    """

    name: str
    config: SimulationConfig
    #: Operating point the episode starts from: surface speed (rad/s), WOB (N).
    surface_speed: SurfaceSpeed = DEFAULT_SURFACE_SPEED
    weight_on_bit: WeightOnBit = DEFAULT_WEIGHT_ON_BIT
    #: Default episode length (s of simulated time).
    episode_duration: Duration = DEFAULT_EPISODE_DURATION
    description: str = ""
    allow_pipe_buckling: StrictBool = False

    def __post_init__(self) -> None:
        check_newtons("weight_on_bit", (self.weight_on_bit,))
        if self.allow_pipe_buckling or not self.config.solver.lateral:
            return
        buckled = pipe_buckling(self.config, self.weight_on_bit)
        if buckled:
            b = buckled[0]
            raise ValueError(
                f"weight_on_bit: {self.weight_on_bit / 1e3:.0f} kN compresses the "
                f"{b.component} by {b.compression / 1e3:.1f} kN {b.place}, beyond its "
                f"buckling load {b.buckling_load / 1e3:.1f} kN there (neutral point "
                f"{self.neutral_point:.0f} m above the bit): "
                + ("lower the WOB (--wob, or weight_on_bit= in Python)" if self.name not in
                   RANDOMISED else "draw other string lengths (string_length_range=)")
                + " or, in a near-vertical hole, use a heavier BHA (string.components); to "
                "study the buckled string on purpose, build the Scenario in Python with "
                "allow_pipe_buckling=True")

    @property
    def neutral_point(self) -> float:
        """Height above the bit (m) of the neutral point at the starting WOB."""
        return neutral_point_height(self.config, self.weight_on_bit)


# --------------------------------------------------------------------------- helpers


def with_string_length(config: SimulationConfig, string_length: float | None) -> SimulationConfig:
    """Set the total string length (pipe + BHA) keeping the pipe's element COUNT.

    Only the drill-pipe element length changes, so simulators of different lengths keep
    equal array shapes (a batched kernel can stack them).
    """
    if string_length is None:
        return config
    bha = config.string.bha_length
    if not (math.isfinite(string_length) and string_length <= MAX_STRING_LENGTH):
        raise ValueError(f"string_length: must be a finite length up to "
                         f"{MAX_STRING_LENGTH} m, got {string_length!r}")
    if string_length <= bha:
        raise ValueError(f"string_length: {string_length} m must exceed the BHA length "
                         f"{bha} m (BHA longer than the string)")
    pipe = config.string.drill_pipe
    n = pipe.n_elements
    pipe_length = string_length - bha
    return replace(config, **{"string.drill_pipe.length": pipe_length,
                              "string.drill_pipe.element_length": pipe_length / n})


def sandwich(bit: BitConfig, middle: RockConfig, bit_depth: float, position: str,
             thickness: float = 1.0, dip: float = 45.0, azimuth: float = 0.0,
             hard: RockConfig = HARD) -> FormationConfig:
    """Hard / ``middle`` / hard layers, the bit face at ``bit_depth`` at ``position``.

    ``thickness`` is the middle layer's thickness along the hole axis (m). The interfaces
    are parallel planes (``dip``, ``azimuth`` in deg). ``position``: one of :data:`POSITIONS`,
    the interface depth from :func:`~drill_env.physics.formation.interface_depth_for_share`.
    """
    if position not in POSITIONS:
        raise ValueError(f"position: must be one of {sorted(POSITIONS)}, got {position!r}"
                         + did_you_mean(str(position), list(POSITIONS)))
    if not (thickness > 0 and math.isfinite(thickness)):
        raise ValueError(f"thickness: must be > 0, got {thickness!r}")
    share, which = POSITIONS[position]
    if which == "top":
        top = bit_depth + interface_depth_for_share(bit, dip, azimuth, share, "below")
    else:
        top = bit_depth + interface_depth_for_share(bit, dip, azimuth, share, "above") \
            - thickness
    return FormationConfig(rocks=(hard, middle),
                           interfaces=(Interface(top, dip, azimuth),
                                       Interface(top + thickness, dip, azimuth)),
                           layers=(0, 1, 0))


#: Paper Table 2: cases 2-4 drill at 50 rpm and 75 kN.
PAPER_LATERAL_RPM = 50.0
PAPER_LATERAL_WOB = 75.0e3


def collar_weighted_string(string: StringConfig | None = None,
                           bha_length: float = 120.0) -> StringConfig:
    """The paper's pipe over a BHA heavy enough to carry the paper's WOB.

    The paper's 35 m of 6 1/2 in collars weigh ~40 kN in mud: at 75-100 kN the drill
    pipe above would be in compression and buckle (docs/model.md, "Axial load and
    buckling"). 120 m of the same collars (~136 kN buoyed) keep the neutral point in
    the collars; stabilizers every 9 m hold the compressed collars off the wall.
    """
    string = string or StringConfig()
    bha = Section(length=bha_length, outer_diameter=6.5 * INCH, inner_diameter=2.8125 * INCH,
                  element_length=2.0)
    stabilizers = tuple(float(h) for h in range(1, int(bha_length) - 9, 9))
    return replace(string, bha=bha, stabilizers=stabilizers)


def _base(string_length: float | None, bit: BitConfig | None = None,
          string: StringConfig | None = None) -> SimulationConfig:
    """A config on ``string`` (default: the paper's 1000 m + 35 m string) with the bit face
    at the bottom of the string."""
    cfg = SimulationConfig() if string is None else SimulationConfig(string=string)
    cfg = with_string_length(cfg, string_length)
    if bit is not None:
        cfg = replace(cfg, bit=bit)
    return replace(cfg, initial_depth=cfg.string.length)


# --------------------------------------------------------------------------- scenarios


@validated
def default(surface_speed: SurfaceSpeed = DEFAULT_SURFACE_SPEED,
            weight_on_bit: WeightOnBit = DEFAULT_WEIGHT_ON_BIT,
            episode_duration: Duration = DEFAULT_EPISODE_DURATION,
            string_length: StringLength = None) -> Scenario:
    """Homogeneous hard rock, symmetric bit, on the realistic string of
    :func:`~drill_env.physics.components.realistic_string` (1250 m: 5 in pipe, 140 m of
    heavy-weight pipe, a 108 m packed BHA that carries the WOB: neutral point 88 m above
    the bit at 100 kN)."""
    cfg = _base(string_length, string=realistic_string())
    cfg = replace(cfg, formation=FormationConfig(rocks=(HARD,)))
    return Scenario("default", cfg, surface_speed, weight_on_bit, episode_duration,
                    "homogeneous hard rock")


@validated
def stick_slip(surface_speed: SurfaceSpeed = 50.0 * RPM,
               weight_on_bit: WeightOnBit = DEFAULT_WEIGHT_ON_BIT,
               episode_duration: Duration = 60.0,
               string_length: StringLength = None) -> Scenario:
    """The default string and rock at 50 rpm: below the stick-slip threshold of a stiff
    top drive (~72 rpm at 100 kN), where the anti-stick-slip controllers earn their keep
    (the paper's Fig. 13 operating point on a realistic string)."""
    sc = default(surface_speed, weight_on_bit, episode_duration, string_length)
    return Scenario("stick_slip", sc.config, surface_speed, weight_on_bit, episode_duration,
                    "homogeneous hard rock at 50 rpm")


def _deviated_scenario(name: str, description: str) -> Callable[..., Scenario]:
    """The default string and rock in a deviated hole of :data:`drill_env.well.WELLS`
    (reaching 100 m below the bit)."""

    def scenario(surface_speed: SurfaceSpeed = DEFAULT_SURFACE_SPEED,
                 weight_on_bit: WeightOnBit = DEFAULT_WEIGHT_ON_BIT,
                 episode_duration: Duration = DEFAULT_EPISODE_DURATION,
                 string_length: StringLength = None) -> Scenario:
        from drill_env.well import WELLS, with_survey

        # off bottom here: the pipe's buckling is judged in the deviated hole, below
        sc = default(surface_speed, 0.0, episode_duration, string_length)
        depth = bit_depth(sc.config)
        try:
            survey = WELLS[name](depth + 100.0)
        except ValueError as err:  # the profile's curves do not fit above the bit
            raise ValueError(f"string_length: the {name} survey is drilled to 100 m below "
                             f"the bit, here at {depth:g} m, and "
                             f"{str(err).partition(': ')[2]}: give a longer string") from None
        cfg = with_survey(sc.config, survey)
        return Scenario(name, cfg, surface_speed, weight_on_bit, episode_duration,
                        description)

    scenario.__name__ = scenario.__qualname__ = name
    scenario.__doc__ = (f"The default string and hard rock in a {description} "
                        "(drill_env.well.WELLS; docs/model.md section 6).")
    return validated(scenario)


j_shaped = _deviated_scenario("j_shaped", "J-shaped well (kick-off 500 m, 3 deg/30 m to 45 deg)")
s_shaped = _deviated_scenario("s_shaped", "S-shaped well (to 30 deg, vertical again below 1200 m)")
lateral_60 = _deviated_scenario("lateral_60", "60-degree well (kick-off 300 m, 4 deg/30 m)")
#: The scenarios drilled in a deviated hole (the rest are vertical).
DEVIATED = ("j_shaped", "s_shaped", "lateral_60")


def _torsional_sandwich_case(name: str, bit: BitConfig, middle: RockConfig, position: str,
                             thickness: float, dip: float, surface_speed: float,
                             weight_on_bit: float, episode_duration: float,
                             string_length: float | None, description: str) -> Scenario:
    """The paper's string in a sandwich, bit at ``position``, torsion only (case 1)."""
    cfg = _base(string_length, bit)
    formation = sandwich(bit, middle, bit_depth(cfg), position, thickness, dip)
    cfg = replace(cfg, formation=formation, solver=SolverConfig(lateral=False))
    return Scenario(name, cfg, surface_speed, weight_on_bit, episode_duration, description)


@validated
def paper_case1(position: Position = "P1", thickness: Thickness = 1.0, dip: Dip = 45.0,
                surface_speed: SurfaceSpeed = 50.0 * RPM,
                weight_on_bit: WeightOnBit = DEFAULT_WEIGHT_ON_BIT,
                episode_duration: Duration = 30.0,
                string_length: StringLength = None) -> Scenario:
    """Torsional stability map (paper Fig. 15): symmetric bit held at ``position`` P1..P6.

    Torsion only (``SolverConfig(lateral=False)``), as the paper's case 1.
    """
    return _torsional_sandwich_case("paper_case1", symmetric_bit(), SOFT, position, thickness,
                                    dip, surface_speed, weight_on_bit, episode_duration,
                                    string_length,
                                    f"hard-soft-hard 45 deg sandwich, bit at {position}")


def _lateral_case(name: str, bit: BitConfig, middle: RockConfig, position: str,
                  thickness: float, dip: float, lead: float, surface_speed: float,
                  weight_on_bit: float, episode_duration: float, string_length: float | None,
                  description: str) -> Scenario:
    """A crossing of the sandwich with the coupled lateral-torsional model (cases 2-4).

    The bit starts ``lead`` metres above ``position`` (P1 by default: the front just
    touching the soft layer), so it drills rock 1 first and then crosses the layer.
    """
    cfg = _base(None, bit)
    cfg = replace(cfg, string=collar_weighted_string(cfg.string))
    cfg = replace(with_string_length(cfg, string_length), initial_depth=None)
    depth = cfg.string.length
    formation = sandwich(bit, middle, depth, position, thickness, dip)
    cfg = replace(cfg, formation=formation, initial_depth=depth - lead)
    return Scenario(name, cfg, surface_speed, weight_on_bit, episode_duration, description)


#: Paper cases 2-4 (Table 2, Figs. 16-18): the crossing of a 45 deg sandwich at 50 rpm and
#: 75 kN with the coupled lateral-torsional model: name -> (bit, middle rock, description).
CROSSING_CASES: dict[str, tuple[Callable[[], BitConfig], RockConfig, str]] = {
    "paper_case2": (symmetric_bit, SOFT,
                    "symmetric bit through a hard-soft-hard 45 deg sandwich"),
    "paper_case3": (symmetric_bit, VERY_SOFT,
                    "symmetric bit through a hard-very soft-hard 45 deg sandwich"),
    "paper_case4": (asymmetric_bit, SOFT,
                    "asymmetric bit through a hard-soft-hard 45 deg sandwich"),
}


def _crossing_scenario(name: str) -> Callable[..., Scenario]:
    bit, middle, description = CROSSING_CASES[name]

    def scenario(position: Position = "P1", thickness: Thickness = 0.3, dip: Dip = 45.0,
                 lead: Lead = 0.05, surface_speed: SurfaceSpeed = PAPER_LATERAL_RPM * RPM,
                 weight_on_bit: WeightOnBit = PAPER_LATERAL_WOB,
                 episode_duration: Duration = 240.0,
                 string_length: StringLength = None) -> Scenario:
        return _lateral_case(name, bit(), middle, position, thickness, dip, lead,
                             surface_speed, weight_on_bit, episode_duration, string_length,
                             description)

    scenario.__name__ = scenario.__qualname__ = name
    scenario.__doc__ = (f"{description[0].upper()}{description[1:]} (paper Table 2): the bit "
                        "starts ``lead`` m above ``position`` and drills through the layer.")
    return validated(scenario)


paper_case2 = _crossing_scenario("paper_case2")
paper_case3 = _crossing_scenario("paper_case3")
paper_case4 = _crossing_scenario("paper_case4")


# --------------------------------------------------------------------------- random
# MODELLING CHOICES of the training distribution (and of the held-out seeds drawn from
# it: changing one changes every episode behind EVALUATION_SEEDS). Around the paper's
# sandwich (45 deg, a soft layer near the bit) so that the bit crosses a layer in most
# episodes, widened so a policy cannot learn one geometry: the rocks' parameters scaled
# by a factor in ROCK_JITTER, the layer's top LAYER_TOP m from the bit face (negative:
# above it), its thickness along the axis LAYER_THICKNESS m, its dip LAYER_DIP degrees
# (any azimuth); the bit symmetric or asymmetric at even odds.
ROCK_JITTER = (0.7, 1.3)
LAYER_TOP = (-0.3, 0.5)
LAYER_THICKNESS = (0.1, 1.0)
LAYER_DIP = (0.0, 60.0)


def _jitter(rng: np.random.Generator, rock: RockConfig, name: str) -> RockConfig:
    """A rock whose curve parameters are drawn within ROCK_JITTER of the preset (mu_max
    raised to the drawn mu_min where the draws cross: the curve then flat)."""
    def f(value: float) -> float:
        return float(value * rng.uniform(*ROCK_JITTER))

    mu_min = f(rock.mu_min)
    mu_max = max(mu_min, f(rock.mu_max))
    founder = rock.founder_wob_per_diameter
    return RockConfig(name=name, mu_min=mu_min, mu_max=mu_max, st1=f(rock.st1),
                      st2=f(rock.st2), wall_stiffness=f(rock.wall_stiffness),
                      wall_damping=f(rock.wall_damping), depth_of_cut=f(rock.depth_of_cut),
                      founder_wob_per_diameter=None if founder is None else f(founder),
                      post_founder_slope=rock.post_founder_slope)


#: The random scenario's starting WOB is drawn in this range (N) by default.
RANDOM_WEIGHT_ON_BIT_RANGE = (50.0e3, 130.0e3)


@validated
def random(rng: np.random.Generator | None = None,
           string_length_range: tuple[StringLengthValue, StringLengthValue] = (900.0, 1600.0),
           rpm_range: tuple[Rpm, Rpm] = (40.0, 160.0),
           weight_on_bit_range: tuple[WeightOnBit, WeightOnBit] = RANDOM_WEIGHT_ON_BIT_RANGE,
           episode_duration: Duration = DEFAULT_EPISODE_DURATION) -> Scenario:
    """Randomised training distribution, drawn from ``rng`` (the env passes ``np_random``).

    Drawn: three rocks (hard, soft, very soft presets, each curve parameter within
    +-30 %); a middle layer of soft or very soft rock between two parallel interfaces
    whose top lies 0.3 m above to 0.5 m below the bit, 0.1-1 m thick along the axis,
    dipping 0-60 deg to the hole at any azimuth (in a curved well set by physics overrides
    the true dip follows: ``with_physics``); a symmetric or asymmetric bit (even odds); the length
    of the realistic string (:func:`~drill_env.physics.components.realistic_string`) in
    ``string_length_range`` (the drill pipe's element LENGTH changes, the element count
    does not); the start operating point (rpm, WOB) uniformly in the given ranges (up to
    130 kN the neutral point stays in the BHA or the heavy-weight pipe, which does not
    buckle). The shapes of every draw are equal: 3 rocks, 2 interfaces, 6 blades, same
    node count.
    """
    for name, (low, high) in (("string_length_range", string_length_range),
                              ("rpm_range", rpm_range),
                              ("weight_on_bit_range", weight_on_bit_range)):
        if not low <= high:
            raise ValueError(f"{name}: the low end must not exceed the high end, got "
                             f"{(low, high)}")
    check_newtons("weight_on_bit_range", weight_on_bit_range)
    lower = realistic_string().bha_length
    if not string_length_range[0] > lower + 10.0:
        raise ValueError(f"string_length_range: the strings need more than {lower + 10.0:.0f} m "
                         f"(BHA and heavy-weight pipe, plus a pipe joint), got "
                         f"{string_length_range}")
    rng = rng if rng is not None else np.random.default_rng()
    lo, hi = string_length_range
    cfg = _base(float(rng.uniform(lo, hi)),
                symmetric_bit() if rng.random() < 0.5 else asymmetric_bit(),
                string=realistic_string())
    rocks = (_jitter(rng, HARD, "hard"), _jitter(rng, SOFT, "soft"),
             _jitter(rng, VERY_SOFT, "very_soft"))
    middle = int(rng.integers(1, 3))
    top = bit_depth(cfg) + float(rng.uniform(*LAYER_TOP))
    thickness = float(rng.uniform(*LAYER_THICKNESS))
    dip = float(rng.uniform(*LAYER_DIP))
    azimuth = float(rng.uniform(0.0, 360.0))
    formation = FormationConfig(rocks=rocks,
                                interfaces=(Interface(top, dip, azimuth),
                                            Interface(top + thickness, dip, azimuth)),
                                layers=(0, middle, 0))
    cfg = replace(cfg, formation=formation)
    rpm = float(rng.uniform(*rpm_range))
    wob = float(rng.uniform(*weight_on_bit_range))
    return Scenario("random", cfg, rpm * RPM, wob, episode_duration,
                    f"random draw: middle rock {rocks[middle].name}, dip {dip:.0f} deg")


#: Scenario functions by name.
SCENARIOS: dict[str, Callable[..., Scenario]] = {
    "default": default,
    "stick_slip": stick_slip,
    "paper_case1": paper_case1,
    "paper_case2": paper_case2,
    "paper_case3": paper_case3,
    "paper_case4": paper_case4,
    "random": random,
    "j_shaped": j_shaped,
    "s_shaped": s_shaped,
    "lateral_60": lateral_60,
}

#: Scenarios drawn anew from the env's RNG at every reset.
RANDOMISED = frozenset({"random"})


#: Spacing (m) of the string lengths at which a curved well's draws are checked: the
#: lengths at which a build's pipe buckles can form a window ~15 m wide.
DRAW_CHECK_STEP = 5.0
_CHECKED: set[str] = set()  # the (scenario, params, overrides) found sound in this process
CHECKED_KEPT = 1024  # at most (then forgotten together): a sweep's new settings each added


def check_draws(name: str, params: Mapping[str, Any], overrides: Mapping[str, Any],
                top_wob: float | None = None,
                lower_wob: str = "start_weight_on_bit_range in gym.make or env_kwargs"
                ) -> None:
    """Refuse the physics ``overrides`` (dotted) under which a randomised scenario drawn
    with ``params`` would fail at some later reset, not only at the first: its starting
    WOB is drawn up to the top of its range and must not buckle the pipe, and in a curved
    well the survey must reach the longest string drawn and the pipe's place in the hole
    moves with the drawn length (checked every :data:`DRAW_CHECK_STEP` along the range;
    in a vertical hole the pipe's compression is set by what every draw shares: BHA,
    heavy-weight pipe, bit, mud). ``top_wob``: the most WOB an episode starts at (N; None:
    the top of the scenario's ``weight_on_bit_range``), and ``lower_wob`` the setting that
    lowers it (a task draws its own targets). Each set is checked once per process."""
    key = repr((name, sorted(params.items()), sorted(overrides.items()), top_wob))
    if name not in RANDOMISED or not (overrides or top_wob is not None) or key in _CHECKED:
        return
    defaults = inspect.signature(SCENARIOS[name]).parameters
    low, high = string_length_range(name, params)
    if overrides.get("initial_depth") is not None:  # (it fit some draws, was refused at others,
        # with advice to lengthen a string the scenario draws)
        raise ValueError(f"physics: initial_depth: the {name} scenario draws each episode's "
                         f"string ({low:g}-{high:g} m, string_length_range) and hangs the "
                         "bit at its bottom: leave initial_depth out")
    make_scenario(name, np.random.default_rng(0), **params)  # (as typed: not (l, l) below)
    top = params.get("weight_on_bit_range", defaults["weight_on_bit_range"].default)[1] \
        if top_wob is None else top_wob
    buckling: list[tuple[float, Any]] = []  # (length, the first component) that buckle
    for length in (*np.arange(high, low, -DRAW_CHECK_STEP), low):
        config = drawn_with_physics(name, params, overrides, length)
        buckled = pipe_buckling(config, top) if config.solver.lateral else []
        if buckled:
            buckling.append((float(length), buckled[0]))
        if config.well.vertical:
            break
    if buckling:
        length, b = buckling[0]
        spans = _spans(sorted(at for at, _ in buckling), DRAW_CHECK_STEP)
        given = ", ".join(k for k in sorted(overrides) if not k.startswith("top_drive."))
        raise ValueError(
            # (named by what lowers it when no physics was given: a task's WOB targets)
            (f"physics: with {given} " if given else f"{lower_wob.split()[0]}: ")
            + f"the {name} scenario's starting "
            f"WOB, drawn up to {top / 1e3:.0f} kN at each reset, would compress the "
            f"{b.component} of a {length:.0f} m string by {b.compression / 1e3:.1f} kN "
            f"{b.place}, beyond its buckling load {b.buckling_load / 1e3:.1f} kN: "
            + ("" if config.well.vertical else
               f"strings of {spans} m buckle (checked every {DRAW_CHECK_STEP:g} m): draw "
               "others (string_length_range=(lo, hi) in gym.make or env_kwargs, "
               "--string-lengths in "
               "drill-env benchmark --task), ")
            + f"draw a lower WOB ({lower_wob}), lighten the mud or make the BHA heavier "
            "(string.components)")
    if len(_CHECKED) >= CHECKED_KEPT:
        _CHECKED.clear()
    _CHECKED.add(key)


def string_length_range(name: str, params: Mapping[str, Any]) -> tuple[float, float]:
    """(shortest, longest) string (m) the randomised ``name`` draws with ``params``."""
    low, high = params.get("string_length_range", inspect.signature(
        SCENARIOS[name]).parameters["string_length_range"].default)
    return low, high


def _spans(lengths: list[float], step: float) -> str:
    """"900-1110, 1135-1150": the runs of ``lengths`` (sorted) no more than ``step``
    apart."""
    runs = [[lengths[0], lengths[0]]]
    for at in lengths[1:]:
        if at - runs[-1][1] <= step + 1e-9:
            runs[-1][1] = at
        else:
            runs.append([at, at])
    return ", ".join(f"{a:.0f}" if a == b else f"{a:.0f}-{b:.0f}" for a, b in runs)


def check_one_string_length(params: Mapping[str, Any], overrides: Collection[str]) -> None:
    """Refuse ``string_length=`` beside physics overrides that set the string's length
    themselves (the pipe's length, the BHA, the components): the overrides would win
    without a word."""
    if params.get("string_length") is None:
        return
    sections = ("string.drill_pipe", "string.bha", "string.components")
    setting = sorted(k for k in overrides if k in ("string", *sections)
                     or (k.startswith(sections) and k.endswith(".length")))
    if setting:
        raise ValueError(f"string_length: the physics overrides set the string's length too "
                         f"({', '.join(setting)}); give one of them")


def scenario_parameters(name: str) -> tuple[str, ...]:
    """Names of the keyword parameters a scenario takes (``rng`` excluded)."""
    _check_name(name)
    params = inspect.signature(SCENARIOS[name]).parameters
    return tuple(p for p in params if p != "rng")


def _check_name(name: str) -> None:
    if isinstance(name, Scenario):  # (its repr runs to kilobytes)
        raise ValueError(
            f"scenario: takes a scenario's name, not a Scenario (this one: {name.name!r}); "
            "give its parameters as keywords (scenario_parameters(name): string_length, ...) "
            "and config overrides as physics={dotted path: value}; known scenarios: "
            f"{', '.join(sorted(SCENARIOS))}")
    if not isinstance(name, str) or name not in SCENARIOS:
        hint = did_you_mean(name, list(SCENARIOS)) if isinstance(name, str) else ""
        raise ValueError(f"scenario: unknown name {name!r}{hint}; known scenarios: "
                         f"{', '.join(sorted(SCENARIOS))}")


def make_scenario(name: str, rng: np.random.Generator | None = None, **params) -> Scenario:
    """Build the scenario ``name`` with ``params``; ``rng`` feeds randomised scenarios."""
    _check_name(name)
    unknown = set(params) - set(scenario_parameters(name))
    if unknown:
        raise ValueError(f"scenario {name!r}: unknown parameter(s) {sorted(unknown)}; "
                         f"known: {list(scenario_parameters(name))}")
    if name in RANDOMISED:
        return SCENARIOS[name](rng=rng, **params)
    return SCENARIOS[name](**params)


def scenario_with_physics(name: str, rng: np.random.Generator | None,
                          params: Mapping[str, Any], physics: Mapping[str, Any],
                          drawn: bool = False) -> Scenario:
    """:func:`make_scenario` with ``physics`` overrides applied (``drawn``: a randomised
    scenario's draw, :func:`with_physics`). The starting WOB's buckling check is made on
    the string drilled: where the scenario's own string buckles at the WOB asked and the
    overrides' string does not, the WOB stands (a --config J-well at 170 kN was refused
    for the default string's heavy-weight pipe)."""
    start: dict[str, Any] = {}
    try:
        scenario = make_scenario(name, rng=rng, **params)
    except ValueError:
        if not physics or drawn or "weight_on_bit" not in params:
            raise
        start = {"weight_on_bit": params["weight_on_bit"]}  # checked below, on the string
        scenario = make_scenario(name, rng=rng, **{key: value for key, value in params.items()
                                                   if key not in start})
    if physics:
        scenario = dataclasses.replace(scenario, **start,
                                       config=with_physics(scenario.config, physics, drawn))
    return scenario
