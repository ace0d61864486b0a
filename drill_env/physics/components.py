"""String components of common sizes, and the realistic strings of the scenarios.

Dimensions of the tube bodies (the FE model's mass and stiffness): drill pipe from API
Spec 5DP, heavy-weight pipe and drill collars from API RP 7G / IADC Drilling Manual
tables, MWD, jar and stabilizer bodies typical of 8 1/2 - 8 3/4 in hole tools. Tool
joints and upsets are not modelled: drill pipe and heavy-weight pipe weigh ~10-20 % less
than their nominal "adjusted" weight per foot here, collars (plain bodies) match theirs
(6 1/2 x 2 13/16 in: 136.6 kg/m, nominal 91 lb/ft = 135.4 kg/m).

Every function returns a :class:`~drill_env.physics.config.Component`; lengths and element
lengths in metres. Strings list their components from the bit up.
"""

from __future__ import annotations

import bisect
import functools
import itertools
import warnings

from drill_env.physics.config import Component, StringConfig
from drill_env.physics.hole_fit import warn_under_hole
from drill_env.physics.units import GRAVITY, INCH

#: Stabilizer blades 1/8 in under an 8 3/4 in hole: an undergauge choice (API's blade
#: tolerance is ~1/32 in), and larger than the bit, 10 mm under the hole (docs/model.md,
#: "The compressed BHA leans on its stabilizers").
STABILIZER_8_3_4 = 8.625 * INCH


def drill_pipe_5(length: float, element_length: float = 10.0) -> Component:
    """5 in 19.5 lb/ft drill pipe (API 5DP: OD 5.000, ID 4.276 in)."""
    return Component(length=length, outer_diameter=5.0 * INCH, inner_diameter=4.276 * INCH,
                     element_length=element_length, kind="drill_pipe", name="5 in DP")


def drill_pipe_5_5(length: float, element_length: float = 10.0) -> Component:
    """5 1/2 in 21.9 lb/ft drill pipe (API 5DP: OD 5.500, ID 4.778 in)."""
    return Component(length=length, outer_diameter=5.5 * INCH, inner_diameter=4.778 * INCH,
                     element_length=element_length, kind="drill_pipe", name="5 1/2 in DP")


def heavy_weight_5(length: float, element_length: float = 7.0) -> Component:
    """5 in heavy-weight drill pipe, 49.3 lb/ft (tube OD 5.0, ID 3.0 in)."""
    return Component(length=length, outer_diameter=5.0 * INCH, inner_diameter=3.0 * INCH,
                     element_length=element_length, kind="heavy_weight", name="5 in HWDP")


def collar_6_5(length: float, element_length: float = 1.5) -> Component:
    """6 1/2 x 2 13/16 in drill collars (API RP 7G, 91 lb/ft)."""
    return Component(length=length, outer_diameter=6.5 * INCH, inner_diameter=2.8125 * INCH,
                     element_length=element_length, kind="collar", name="6 1/2 in DC")


def collar_8(length: float, element_length: float = 1.5) -> Component:
    """8 x 2 13/16 in drill collars (API RP 7G, 150 lb/ft), for 12 1/4 in hole and up."""
    return Component(length=length, outer_diameter=8.0 * INCH, inner_diameter=2.8125 * INCH,
                     element_length=element_length, kind="collar", name="8 in DC")


def stabilizer(blade_diameter: float = STABILIZER_8_3_4, length: float = 1.5,
               element_length: float = 1.5, name: str = "stabilizer") -> Component:
    """Integral-blade stabilizer: a 6 1/2 x 2 13/16 in body with blades of
    ``blade_diameter`` (m), the diameter that touches the wall."""
    return Component(length=length, outer_diameter=6.5 * INCH, inner_diameter=2.8125 * INCH,
                     element_length=element_length, kind="stabilizer", name=name,
                     contact_diameter=blade_diameter)


def mwd(length: float = 9.0, element_length: float = 1.5) -> Component:
    """6 3/4 in MWD / LWD collar (ID 3 1/4 in; the electronics add little mass)."""
    return Component(length=length, outer_diameter=6.75 * INCH, inner_diameter=3.25 * INCH,
                     element_length=element_length, kind="mwd", name="MWD")


def jar(length: float = 9.0, element_length: float = 3.0) -> Component:
    """6 1/2 in drilling jar (ID 2 3/4 in)."""
    return Component(length=length, outer_diameter=6.5 * INCH, inner_diameter=2.75 * INCH,
                     element_length=element_length, kind="jar", name="jar")


def bit_sub(length: float = 1.0, element_length: float = 1.0) -> Component:
    """6 1/2 in bit sub (float valve) between the bit and the near-bit stabilizer."""
    return Component(length=length, outer_diameter=6.5 * INCH, inner_diameter=2.8125 * INCH,
                     element_length=element_length, kind="bit_sub", name="bit sub")


#: The packed vertical-hole BHA of the realistic strings, from the bit up: stabilizers at
#: 1-2.5, 11.5-13, 31-32.5, 50.5-52 and 70-71.5 m keep every span below half of its pinned
#: Euler load at 100 kN (the 19.5 m span above stabilizer 1: 0.45, the compressed collars
#: stay straight), 107.5 m in all (~122 kN in 1.2 g/cc mud): 100 kN of WOB puts the neutral point
#: in the collars ~88 m above the bit, with ~18 % of the BHA weight to spare (API RP 7G
#: asks for 15-25 %).
def packed_bha() -> tuple[Component, ...]:
    return (
        bit_sub(),
        stabilizer(length=1.5, name="near-bit stabilizer"),
        mwd(),
        stabilizer(name="string stabilizer 1"),
        collar_6_5(18.0),
        stabilizer(name="string stabilizer 2"),
        collar_6_5(18.0),
        stabilizer(name="string stabilizer 3"),
        collar_6_5(18.0, element_length=2.0),
        stabilizer(name="string stabilizer 4"),
        jar(),
        collar_6_5(27.0, element_length=3.0),
    )


#: Heavy-weight pipe above the BHA: 15 joints (140 m), a stiff transition to the pipe.
HEAVY_WEIGHT_LENGTH = 140.0


@functools.lru_cache(maxsize=32)
def realistic_string(total_length: float = 1250.0, pipe_element_length: float = 10.0
                     ) -> StringConfig:
    """5 in drill pipe over 140 m of 5 in HWDP over the :func:`packed_bha` in an
    8 3/4 in hole, ``total_length`` m in all (default 1250 m: a shallow vertical well).

    Cached: the config is frozen, and the randomised scenario asks for it at every
    episode reset (validating its sixteen sections took a sixth of a reset)."""
    lower = (*packed_bha(), heavy_weight_5(HEAVY_WEIGHT_LENGTH))
    pipe_length = total_length - sum(c.length for c in lower)
    if pipe_length <= 0:
        raise ValueError(f"total_length: {total_length} m leaves no room for the drill pipe "
                         f"above {sum(c.length for c in lower):.0f} m of BHA and HWDP")
    return StringConfig(drill_pipe=drill_pipe_5(pipe_length, pipe_element_length),
                        components=lower)


def buoyed_weight(components: tuple[Component, ...], mud_density: float) -> float:
    """Weight in mud of some components (N), tube bodies only."""
    return sum(c.area * c.length * (c.density - mud_density) * GRAVITY for c in components)


#: How far (m) the ``stabilizers`` blades may be under the hole before it is said: field
#: stabilizers run 0-1/4 in under gauge, under-gauge ones up to ~1/2 in; an inch under,
#: the blades hold the BHA nowhere near the wall (a 12 1/4 in hole kept the default
#: 8 5/8 in blades without a word).
STABILIZER_UNDER_HOLE = INCH


def check_stabilizers(string: StringConfig) -> None:
    """ValueError naming the field unless every extra stabilizer of ``string`` lies on it
    and its blades are no narrower than the body they sit on (narrower, the node's
    clearance would grow: a recess, not a stabilizer). The simulator puts a stabilizer on
    the nearest node, which may belong to the next component: it is refused only if it is
    narrower than every body within an element of its position. One nearest the bit's
    node is not modelled (the bit's gauge holds that node): a UserWarning says so, as it
    does blades more than :data:`STABILIZER_UNDER_HOLE` under the hole."""
    bodies = (*string.lower, string.drill_pipe)
    tops = list(itertools.accumulate(s.length for s in bodies))
    for k, pos in enumerate(string.stabilizer_positions):
        if pos >= string.length:
            raise ValueError(f"stabilizers[{k}]: {pos} m above the bit is outside the "
                             f"{string.length} m string")
        bottom = bodies[0].length / bodies[0].n_elements  # the element on the bit
        if pos < bottom / 2:  # (at half an element the node above takes it)
            # said, not refused: the paper BHA's near-bit stabilizer (1 m, a default the
            # user may never have typed) meets it on any mesh coarser than 2 m
            warnings.warn(f"stabilizers[{k}]: {pos} m above the bit is nearest the bit's "
                          f"node ({bottom} m elements there), where the bit's gauge touches "
                          f"the wall: it is not modelled; place it at least {bottom / 2} m "
                          "up, or give the lowest component shorter elements", UserWarning,
                          stacklevel=2)
        reach = bodies[bisect.bisect_right(tops, pos)].element_length
        near = bodies[bisect.bisect_right(tops, max(pos - reach, 0.0)):
                      bisect.bisect_right(tops, pos + reach) + 1]
        body = min(near, key=lambda s: s.outer_diameter)
        if string.stabilizer_diameter < body.outer_diameter:
            raise ValueError(f"stabilizer_diameter: {string.stabilizer_diameter} m is narrower "
                             f"than the {body.label} it sits on at stabilizers[{k}] ({pos} m "
                             f"above the bit, outer diameter {body.outer_diameter} m)")
    if string.stabilizer_positions:
        warn_under_hole("string.stabilizer_diameter", string.stabilizer_diameter,
                        string.hole_diameter, STABILIZER_UNDER_HOLE, "the stabilizers' "
                        "blades stand off the wall; set it for this hole (the default is "
                        "8 5/8 in, 1/8 in under the default hole)")
