"""Layered formation: planar interfaces, rock lookup and the bit-resistance curve.

Hole-fixed frame: ``x, y`` lateral (m), ``z`` measured depth, positive downward (vertical
well). An :class:`~drill_env.physics.config.Interface` with depth ``d``, dip ``delta`` and
azimuth ``beta`` is the plane

    z = d + tan(delta) (x cos(beta) + y sin(beta)),

i.e. ``n . p = d cos(delta)`` with the unit normal
``n = (-sin(delta) cos(beta), -sin(delta) sin(beta), cos(delta))`` pointing downward. A
point ``p`` lies BELOW interface k iff ``n_k . p > offset_k``; its layer is the number of
interfaces it lies below (interfaces are sorted and do not cross where the bit is) and its
rock is ``layer_rock[layer]``.

The kernels here take plain arrays (:class:`FormationArrays`) so they can be called from
numba code without Python objects.
"""

from __future__ import annotations

import math
from enum import IntEnum
from typing import NamedTuple

import numpy as np
from numba import njit
from scipy.optimize import brentq

from drill_env.physics.config import (
    BitConfig,
    ConfigError,
    FormationConfig,
    Interface,
    RockConfig,
    replace,
)

#: Columns of ``FormationArrays.rock_params``: one row per rock (RockConfig fields).
Rock = IntEnum("Rock", [
    "MU_MIN", "MU_MAX", "ST1", "ST2",     # resistance curve, eq. (39)
    "WALL_STIFFNESS", "WALL_DAMPING",     # gauge contact, eq. (55)
    "DEPTH_OF_CUT",                       # m/(rev N), docs/model.md "Penetration"
    "FOUNDER_WOB",                        # N: founder WOB for the formation's bit (inf: none)
    "POST_FOUNDER_SLOPE",                 # depth of cut lost per unit WOB above it
], start=0)
N_ROCK_PARAMS = len(Rock)


class FormationArrays(NamedTuple):
    """Kernel-ready formation description (see module docstring)."""

    normals: np.ndarray  # (n_if, 3) float64, unit, pointing down
    offsets: np.ndarray  # (n_if,) float64
    layer_rock: np.ndarray  # (n_if + 1,) int64
    rock_params: np.ndarray  # (n_rock, N_ROCK_PARAMS) float64

    @property
    def n_interfaces(self) -> int:
        return self.offsets.shape[0]

    @property
    def n_rocks(self) -> int:
        return self.rock_params.shape[0]


def interface_plane(depth: float, dip: float, azimuth: float) -> tuple[np.ndarray, float]:
    """Unit normal and offset of the interface plane (``dip``, ``azimuth`` in degrees)."""
    delta = math.radians(dip)
    beta = math.radians(azimuth)
    normal = np.array([-math.sin(delta) * math.cos(beta), -math.sin(delta) * math.sin(beta),
                       math.cos(delta)])
    return normal, depth * math.cos(delta)


def rock_parameter_table(rocks, bit_diameter: float = math.inf) -> np.ndarray:
    """``(n_rock, N_ROCK_PARAMS)`` table: row j holds rock j's fields in :data:`Rock` order;
    the founder WOB is the rock's founder WOB per diameter times ``bit_diameter`` (m)."""
    table = np.empty((len(rocks), N_ROCK_PARAMS))
    for j, rock in enumerate(rocks):
        for column in Rock:
            if column == Rock.FOUNDER_WOB:
                per_diameter = rock.founder_wob_per_diameter
                table[j, column] = math.inf if per_diameter is None else \
                    per_diameter * bit_diameter
            else:
                table[j, column] = getattr(rock, column.name.lower())
    return table


#: Smallest cosine of the angle between an interface's normal and the hole axis at the
#: bit (relative dip below ~88.9 deg): a plane nearly parallel to the hole would cross
#: its axis far from ``depth`` and under the bit only sideways.
MIN_RELATIVE_COSINE = 0.02


def across_the_hole(formation: FormationConfig, tangent: np.ndarray) -> FormationConfig:
    """``formation`` with each interface's dip and azimuth read as relative to a hole of
    unit ``tangent`` (north, east, down) at the bit, turned into the true ones: the plane
    crosses that hole as it would cross a vertical one at its given dip (the angle
    between its normal and the hole axis). The azimuth is measured from the hole's low
    side (north in a vertical hole, where nothing changes); ``depth`` stays along the
    hole."""
    t = np.asarray(tangent, dtype=float)
    across = np.array([0.0, 0.0, 1.0]) - t[2] * t  # down, across the hole
    if np.linalg.norm(across) < 1e-12:  # vertical: e1 north
        across = np.array([1.0, 0.0, 0.0])
    e1 = across / np.linalg.norm(across)
    # rows e1 (the low side), e2, t: not the simulator's bit frame (carried down from
    # the surface), but the same tangent, so the dip to the hole is kept
    frame = np.stack([e1, np.cross(t, e1), t])
    interfaces = []
    for interface in formation.interfaces:
        normal, _ = interface_plane(interface.depth, interface.dip, interface.azimuth)
        true = frame.T @ normal
        true = true if true[2] >= 0.0 else -true
        dip = min(math.degrees(math.acos(min(true[2], 1.0))), 89.999)  # Interface: < 90
        azimuth = math.degrees(math.atan2(-true[1], -true[0])) % 360.0 if dip > 0.0 else 0.0
        interfaces.append(Interface(interface.depth, dip, azimuth))
    return replace(formation, interfaces=tuple(interfaces))


def formation_arrays(cfg: FormationConfig, bit_diameter: float = math.inf,
                     bit_frame: np.ndarray | None = None) -> FormationArrays:
    """Convert a :class:`FormationConfig` into the arrays the kernels read (the founder
    WOB of each rock for a bit of ``bit_diameter``, m).

    ``bit_frame``: rows e1, e2, t of a curved hole at the bit (north, east, down). The
    interfaces' dip and azimuth are then true ones (from the horizontal, from north),
    turned into the bit's frame; ``depth`` stays where the plane crosses the hole axis
    (measured depth), the hole taken straight along t near the bit. None: the vertical
    hole, e1 north, e2 east (the identity).
    """
    n_if = len(cfg.interfaces)
    normals = np.zeros((n_if, 3))
    offsets = np.zeros(n_if)
    for k, interface in enumerate(cfg.interfaces):
        normals[k], offsets[k] = interface_plane(interface.depth, interface.dip,
                                                 interface.azimuth)
        if bit_frame is None:
            continue
        local = bit_frame @ normals[k]
        if abs(local[2]) < MIN_RELATIVE_COSINE:
            hole = bit_frame[2]  # the tangent: north, east, down
            heading = math.degrees(math.atan2(hole[1], hole[0])) % 360.0
            raise ConfigError(
                f"formation.interfaces[{k}]: the plane (dip {interface.dip:g} deg, azimuth "
                f"{interface.azimuth:g} deg) is nearly parallel to the hole at the bit "
                f"({math.degrees(math.acos(abs(local[2]))):.1f} deg from its normal; the "
                f"hole there: inclination {math.degrees(math.acos(hole[2])):.1f} deg, "
                f"azimuth {heading:.1f} deg): give the plane another dip or azimuth")
        # "below" an interface is further along the hole
        normals[k] = local if local[2] > 0.0 else -local
        offsets[k] = interface.depth * abs(local[2])
    if math.isfinite(bit_diameter):
        _check_order_under_the_bit(normals, offsets, 0.5 * bit_diameter)
    layer_rock = np.asarray(cfg.layers, dtype=np.int64)
    return FormationArrays(normals, offsets, layer_rock,
                           rock_parameter_table(cfg.rocks, bit_diameter))


def _check_order_under_the_bit(normals: np.ndarray, offsets: np.ndarray, radius: float
                               ) -> None:
    """ConfigError unless each interface lies below the one before it everywhere within
    ``radius`` of the hole axis (the bit face; a layer's rock is found by counting the
    planes above a point, which two crossing planes make wrong). Half the bit diameter is
    the face's whole reach: its cutters lie within the gauge radius (diameter / 2 -
    gauge_clearance) of the bit's centre, which stays within the clearance of the axis
    (beyond it only by the gauge contact's penetration). Along the axis at a
    lateral offset r, plane k lies at offsets[k] / n_z - r . n_xy / n_z: the gap of two
    planes shrinks by at most radius x |n_xy / n_z difference| over the face."""
    for k in range(len(offsets) - 1):
        (a, da), (b, db) = (normals[k], offsets[k]), (normals[k + 1], offsets[k + 1])
        gap = db / b[2] - da / a[2]
        slope = b[:2] / b[2] - a[:2] / a[2]
        tilt = math.hypot(*slope)
        if gap < radius * tilt * (1.0 - 1e-12):
            # where the line the planes share passes closest to the axis
            near = gap * slope / (tilt * tilt) if tilt > 0.0 else np.zeros(2)
            depth = da / a[2] - float(near @ (a[:2] / a[2]))
            raise ConfigError(
                f"formation.interfaces[{k + 1}]: crosses interfaces[{k}] within the bit's "
                f"radius of the hole axis ({math.hypot(*near):.3g} m from it, at "
                f"{depth:.2f} m measured depth): {gap:.4g} m apart on the axis, their dips "
                f"open or close that gap by {tilt:.3g} m per m across, so it needs at least "
                f"{radius * tilt:.4g} m at the bit's radius {radius:.4g} m. Layers are listed "
                "top to bottom and may not pinch out where the hole runs, at any depth: "
                "leave out an interface the bit never reaches")


# --------------------------------------------------------------------------- kernels


@njit(cache=True, inline="always")
def resistance(omega, mu_min, mu_max, st1, st2):
    """Bit resistance coefficient mu(omega), omega in rad/s.

    eq. (39), as corrected in docs/model.md section 4.1:
    mu = sign(w) (mu_min + (mu_max - mu_min) exp(-|w / st1|) + st2 |w|); 0 at w == 0.
    """
    if omega == 0.0:
        return 0.0
    w = abs(omega)
    magnitude = mu_min + (mu_max - mu_min) * math.exp(-w / st1) + st2 * w
    return magnitude if omega > 0.0 else -magnitude


@njit(cache=True, inline="always")
def effective_wob(wob, founder_wob, slope):
    """The WOB that acts on the depth of cut: ``wob`` up to the founder point, then
    ``founder - slope (wob - founder)``, never below 0 (docs/model.md, "Penetration")."""
    if wob <= founder_wob:
        return wob
    acting = founder_wob - slope * (wob - founder_wob)
    return acting if acting > 0.0 else 0.0


@njit(cache=True, inline="always")
def layer_at(x, y, z, normals, offsets):
    """Number of interfaces the point (x, y, z) lies below (its layer index)."""
    layer = 0
    for k in range(offsets.shape[0]):
        if normals[k, 0] * x + normals[k, 1] * y + normals[k, 2] * z > offsets[k]:
            layer += 1
    return layer


@njit(cache=True, inline="always")
def rock_at(x, y, z, normals, offsets, layer_rock):
    """Rock index at the point (x, y, z)."""
    return layer_rock[layer_at(x, y, z, normals, offsets)]


# --------------------------------------------------------------------------- bit placement


def front_shares(bit_cfg: BitConfig, formation: FormationArrays, depth: float,
                 bx: float = 0.0, by: float = 0.0, n_phi: int = 72) -> np.ndarray:
    """Share of FRONT blade length (face + shoulder) in each rock, averaged over one revolution.

    ``n_phi`` equally spaced rotation angles phi_z in [0, 2 pi) are averaged; the bit face
    lies at measured depth ``depth`` with its centre at ``(bx, by)``.
    """
    from drill_env.physics import bit  # late import: bit imports this module

    blades = bit.blade_arrays(bit_cfg)
    pieces = bit.make_bit_scratch(blades.shape[0], formation.n_interfaces)
    shares = np.zeros(formation.n_rocks)
    for phi_z in np.arange(n_phi) * (2.0 * math.pi / n_phi):
        n = bit.split_blades(blades, formation, bx, by, depth, phi_z, pieces)
        front = pieces.segment[:n] != bit.Segment.GAUGE
        np.add.at(shares, pieces.rock[:n][front], pieces.length[:n][front])
    return shares / shares.sum()


def _front_points(bit_cfg: BitConfig) -> tuple[np.ndarray, np.ndarray]:
    """Radii and axial offsets (z - face depth) of points A, B, C of every blade."""
    from drill_env.physics import bit

    points = bit.blade_points(bit.blade_arrays(bit_cfg))[:, :3]  # A, B, C
    radii = points[:, :, 0].T.reshape(-1)
    dz = -points[:, :, 1].T.reshape(-1)  # z grows downward; heights are above the face
    return radii, dz


def interface_depth_for_share(bit_cfg: BitConfig, dip: float, azimuth: float,
                              target_share: float, side: str = "below",
                              n_phi: int = 72) -> float:
    """Interface depth, relative to the bit face depth, giving a front-blade share.

    Returns ``d_rel`` such that an interface (``dip``, ``azimuth`` in degrees) crossing the
    hole axis at ``face_depth + d_rel`` leaves the fraction ``target_share`` of the FRONT
    blade length (face + shoulder, eq. 30) BELOW it (``side="below"``: entering a layer
    from above) or ABOVE it (``side="above"``: leaving a layer). The bit is centred and
    the share is AVERAGED OVER ONE REVOLUTION (``n_phi`` equally spaced phi_z), so the
    answer does not depend on where the blades happen to point, only on the bit geometry.

    The share is monotone in ``d_rel``; it is found with ``brentq`` inside the exact
    bracket where some blade point can touch the plane during a revolution. Targets 0
    and 1 return the bracket ends, i.e. the positions where the plane just touches the
    front of the bit. Place the bit at ``interface_depth - d_rel``.
    """
    if side not in ("below", "above"):
        raise ValueError(f"side: must be 'below' or 'above', got {side!r}")
    if not 0.0 <= target_share <= 1.0:
        raise ValueError(f"target_share: must be in [0, 1], got {target_share!r}")
    share_below = target_share if side == "below" else 1.0 - target_share

    # A point at radius r, axial offset dz (relative to the face) is below the plane
    # through the axis at d_rel iff d_rel < dz - tan(dip) r cos(theta - azimuth).
    radii, dz = _front_points(bit_cfg)
    tan_d = math.tan(math.radians(dip))
    d_low = float(np.min(dz - tan_d * radii))  # plane above every point: share 1
    d_high = float(np.max(dz + tan_d * radii))  # plane below every point: share 0
    if share_below >= 1.0:
        return d_low
    if share_below <= 0.0:
        return d_high

    # Two (identical) rocks: only the geometry matters here.
    rocks = (RockConfig(), RockConfig())

    def residual(d_rel: float) -> float:
        cfg = FormationConfig(rocks=rocks, interfaces=(Interface(d_rel, dip, azimuth),),
                              layers=(0, 1))
        return front_shares(bit_cfg, formation_arrays(cfg), 0.0, n_phi=n_phi)[1] - share_below

    return float(brentq(residual, d_low, d_high, xtol=1e-10))

