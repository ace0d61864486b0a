"""What a recording holds and how it is laid out in the viewer: rerun entities + blueprint.

:class:`RerunWriter` turns the pieces an :class:`~drill_env.recording.recorder.
EpisodeRecorder` collects (chunks of per-step series, string snapshots, events) into
rerun entities on the ``sim_time`` timeline (a duration in seconds of simulated time),
with ``send_columns``. Entity paths (see ``docs/recording.md``):

==================================  =====================================================
``timeseries/<group>_<unit>/<name>`` scalar series; the unit is in the group name and
                                    :data:`SERIES` gives the info key and the factor from
                                    SI (plotted = SI value x ``scale``)
``timeseries/rock_share/<rock>``    share of front blade length in each rock (0-1)
``timeseries/reward/<term>``        reward terms and ``total`` (the step's reward)
``timeseries/action/<i>``           the raw action vector, one series per component
``timeseries/info/<key>``           every other scalar of ``info``, in SI, unscaled
``orbit_mm/clearance``, ``/bit``    2-D bit orbit (mm) inside the gauge-clearance circle
``string/deflection``               3-D lateral deflection of the string, exaggerated
``string/wall``                     clearance envelope of the string (exaggerated)
``string/contact``                  nodes on the wall, coloured and sized by wall force
``bit/blades``                      blade pieces in the hole frame, coloured by rock
``bit/interfaces``, ``bit/wall``    formation interfaces and borehole wall near the bit
``bit/blade_rocks``                 text: which rock(s) each blade cuts (on change)
``events``                          text log: start, stick-slip, whirl, layer change, end
``config/...``                      static: simulation config, env settings, episode
==================================  =====================================================

Units: SI in ``timeseries/info`` and in the config; elsewhere the unit is in the path
(``speed_rpm``, ``torque_kNm``, ``wob_kN``, ``orbit_mm``, ...). The 3-D views use metres.
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from drill_env.physics.bit import (
    Blade,
    blade_points,
    make_bit_scratch,
    segment_lengths,
    split_blades,
)
from drill_env.physics.units import RPM

APPLICATION_ID = "drill_env"
TIMELINE = "sim_time"

#: Samples in the orbit's trail (2 s at the default 10 Hz).
ORBIT_TRAIL = 20

#: Rock colours by rock index (RGB), cycled.
ROCK_COLORS = ((200, 90, 60), (70, 150, 230), (110, 200, 110), (230, 190, 60),
               (170, 110, 220), (120, 120, 120))


@dataclass(frozen=True)
class Series:
    """A scalar series plotted from an ``info`` key: plotted value = SI value x ``scale``."""

    entity: str
    key: str
    scale: float
    label: str
    color: tuple[int, int, int]


#: The fixed time series; the group (second path part) carries the plotted unit.
SERIES: tuple[Series, ...] = (
    Series("timeseries/speed_rpm/bit", "bit_speed", 1.0 / RPM, "bit", (220, 60, 50)),
    Series("timeseries/speed_rpm/surface", "surface_speed", 1.0 / RPM, "surface",
           (50, 110, 220)),
    Series("timeseries/speed_rpm/setpoint", "speed_setpoint", 1.0 / RPM, "set point",
           (150, 150, 150)),
    Series("timeseries/torque_kNm/on_bit", "torque_on_bit", 1e-3, "on bit", (220, 60, 50)),
    Series("timeseries/torque_kNm/surface", "surface_torque", 1e-3, "surface",
           (50, 110, 220)),
    Series("timeseries/wob_kN/weight_on_bit", "weight_on_bit", 1e-3, "WOB", (220, 60, 50)),
    Series("timeseries/wob_kN/setpoint", "weight_on_bit_setpoint", 1e-3, "set point",
           (150, 150, 150)),
    Series("timeseries/hook_load_kN/hook_load", "hook_load", 1e-3, "hook load",
           (50, 110, 220)),
    Series("timeseries/rop_m_per_h/rop", "rop", 3600.0, "ROP", (60, 170, 90)),
    Series("timeseries/depth_m/depth", "depth", 1.0, "bit depth", (120, 90, 60)),
    Series("timeseries/stick_slip/ssi", "ssi", 1.0, "SSI", (220, 60, 50)),
    Series("timeseries/stick_slip/stuck_fraction", "stuck_fraction", 1.0, "stuck fraction",
           (120, 120, 120)),
    Series("timeseries/whirl_rpm/whirl_speed", "whirl_speed", 1.0 / RPM, "whirl speed",
           (170, 110, 220)),
)
SERIES_KEYS = tuple(s.key for s in SERIES)


# --------------------------------------------------------------------------- helpers


def is_scalar(value: Any) -> bool:
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(
        value, (bool, np.bool_))


def flatten_tree(obj: Any, prefix: str = "") -> dict[str, Any]:
    """Flat ``{dotted.key: scalar or string}`` of a JSON-like tree (lists of numbers kept)."""
    out: dict[str, Any] = {}
    if isinstance(obj, dict):
        for k, v in obj.items():
            out.update(flatten_tree(v, f"{prefix}.{k}" if prefix else str(k)))
    elif isinstance(obj, list):
        if obj and all(is_scalar(v) for v in obj):
            out[prefix] = [float(v) for v in obj]
        else:
            for i, v in enumerate(obj):
                out.update(flatten_tree(v, f"{prefix}.{i}"))
    elif obj is not None:
        out[prefix] = obj if isinstance(obj, str) else (
            float(obj) if is_scalar(obj) else str(obj))
    return out


def nice(value: float) -> float:
    """1, 2 or 5 times a power of ten, at most ``value``."""
    if not value > 0 or not math.isfinite(value):
        return 1.0
    exp = math.floor(math.log10(value))
    for m in (5.0, 2.0, 1.0):
        if m * 10**exp <= value:
            return m * 10**exp
    return 10.0**exp


def _circle(radius: float, n: int = 96) -> np.ndarray:
    a = np.linspace(0.0, 2.0 * math.pi, n + 1)
    return np.stack([radius * np.cos(a), radius * np.sin(a)], axis=1)


@dataclass
class Geometry:
    """What the views need of the string and bit, captured when an episode begins (a
    randomised env replaces its simulator at the next reset)."""

    clearance: float = math.nan
    hole_radius: float = math.nan
    rock_names: list[str] = dataclasses.field(default_factory=list)
    node_depth: np.ndarray | None = None
    node_clearance: np.ndarray | None = None
    blades: np.ndarray | None = None
    formation: Any = None  # FormationArrays
    interfaces: tuple = ()  # the config's Interface objects
    layers: tuple = ()
    depth0: float = math.nan

    def exaggeration(self, override: float | None = None) -> float:
        """Factor on the lateral displacement in the 3-D string view: a round number that
        maps the largest clearance to ~2 % of the string length."""
        if override is not None:
            return float(override)
        if self.node_depth is None or self.node_clearance is None or len(self.node_depth) < 2:
            return 100.0
        length = float(self.node_depth[-1] - self.node_depth[0])
        return nice(0.02 * length / max(float(np.max(self.node_clearance)), 1e-6))


# --------------------------------------------------------------------------- writer


class RerunWriter:
    """Writes one episode's entities into a rerun ``RecordingStream`` (not the global one)."""

    def __init__(self, stream: Any, geometry: Geometry, exaggeration: float) -> None:
        import rerun as rr

        self.rr = rr
        self.stream = stream
        self.geometry = geometry
        self.exaggeration = exaggeration
        self._blade_rocks: np.ndarray | None = None  # the last text's shares (its chunk)

    def _send(self, entity: str, times: np.ndarray, columns: Any) -> None:
        self.stream.send_columns(entity, indexes=[self.rr.TimeColumn(TIMELINE, duration=times)],
                                 columns=columns)

    def styled(self, entity: str, label: str, color: tuple[int, int, int] | None) -> None:
        """The static style of a scalar series (once per entity)."""
        self.stream.log(entity, self.rr.SeriesLines(names=label, colors=color, widths=1.5),
                        static=True)

    def scalars(self, entity: str, times: np.ndarray, values: np.ndarray) -> bool:
        """Finite samples of one series; False if there were none."""
        mask = np.isfinite(values) & np.isfinite(times)
        if not mask.any():
            return False
        self._send(entity, times[mask], self.rr.Scalars.columns(scalars=values[mask]))
        return True

    # ------------------------------------------------------------------ static parts

    def episode(self, fields: Mapping[str, Any]) -> None:
        """``config/episode``: scenario, seed, steps, end; logged at the start and again at
        the end (the last one wins)."""
        self.stream.log("config/episode", self.rr.AnyValues(**fields), static=True)

    def configuration(self, config_tree: Any, settings: Any, summary: Sequence[str]) -> None:
        rr = self.rr
        flat = {key: v for key, v in flatten_tree(config_tree).items() if key}
        if flat:
            self.stream.log("config/simulation", rr.AnyValues(**flat), static=True)
        flat_env = {key: v for key, v in flatten_tree(settings).items() if key}
        if flat_env:
            self.stream.log("config/env", rr.AnyValues(**flat_env), static=True)
        doc = ["# Episode", "", *summary, "", "## Environment settings", "", "```json",
               json.dumps(settings, indent=1, default=str), "```", "",
               "## Simulation config (SI)", "", "```json",
               json.dumps(config_tree, indent=1, default=str), "```"]
        self.stream.log("config/document", rr.TextDocument(
            "\n".join(doc), media_type=rr.MediaType.MARKDOWN), static=True)

    def scene(self) -> None:
        """The static parts of the 2-D and 3-D views: clearance circle, string envelope,
        borehole wall and formation interfaces near the bit, rock colours."""
        rr, g, stream = self.rr, self.geometry, self.stream
        if math.isfinite(g.clearance):
            stream.log("orbit_mm/clearance",
                       rr.LineStrips2D([_circle(g.clearance * 1e3)], colors=(120, 120, 120),
                                       radii=0.03, labels="gauge clearance"), static=True)
            stream.log("orbit_mm/centre", rr.Points2D([[0.0, 0.0]], radii=0.08,
                                                      colors=(120, 120, 120)), static=True)
        stream.log("orbit_mm/bit", rr.Points2D.from_fields(radii=0.15, colors=(220, 60, 50)),
                   static=True)
        stream.log("orbit_mm/trail", rr.LineStrips2D.from_fields(radii=0.04,
                                                                 colors=(230, 140, 120)),
                   static=True)
        if g.node_depth is not None:
            k = self.exaggeration
            clear = g.node_clearance if g.node_clearance is not None else \
                np.zeros_like(g.node_depth)
            z = -np.asarray(g.node_depth, dtype=np.float64)
            stream.log("string/info", rr.TextDocument(
                f"Lateral displacement exaggerated x{k:g} (x, y in m x {k:g}); z = minus "
                "measured depth (m). Grey: clearance envelope of every node. Dots: nodes "
                "on the wall, yellow (100 N) to dark red (50 kN, log scale), sized by force."),
                static=True)
            wall = [np.stack([sx * k * clear, sy * k * clear, z], axis=1)
                    for sx, sy in ((1, 0), (-1, 0), (0, 1), (0, -1))]
            stream.log("string/wall", rr.LineStrips3D(wall, colors=(150, 150, 150),
                                                      radii=0.3), static=True)
            stream.log("string/deflection", rr.LineStrips3D.from_fields(
                colors=(50, 110, 220), radii=0.6), static=True)
            stream.log("string/bit", rr.Points3D.from_fields(colors=(220, 60, 50), radii=2.0),
                       static=True)
        if g.blades is not None:
            names = g.rock_names or ["rock0"]
            stream.log("bit", rr.AnnotationContext(
                [(j, names[j], ROCK_COLORS[j % len(ROCK_COLORS)]) for j in range(len(names))]),
                static=True)
            stream.log("bit/blades", rr.LineStrips3D.from_fields(radii=0.002, show_labels=False),
                       static=True)
            self._bit_surroundings()

    def _bit_surroundings(self) -> None:
        """Borehole wall and interfaces within ~2 m of the starting bit depth."""
        rr, g = self.rr, self.geometry
        top, bottom = 0.15, -0.5
        hole_r = g.hole_radius
        if math.isfinite(hole_r):
            a = np.linspace(0.0, 2 * math.pi, 8, endpoint=False)
            wall = [np.array([[hole_r * math.cos(ai), hole_r * math.sin(ai), top],
                              [hole_r * math.cos(ai), hole_r * math.sin(ai), bottom]])
                    for ai in a]
            self.stream.log("bit/wall", rr.LineStrips3D(wall, colors=(150, 150, 150),
                                                        radii=0.0005), static=True)
        if not g.interfaces:
            return
        names = g.rock_names
        r_wall = hole_r if math.isfinite(hole_r) else 0.11
        depth0 = g.depth0 if math.isfinite(g.depth0) else 0.0
        a = np.linspace(0.0, 2.0 * math.pi, 73)
        strips, labels, colors = [], [], []
        for k, itf in enumerate(g.interfaces):
            tan = math.tan(math.radians(itf.dip))
            beta = math.radians(itf.azimuth)
            for radius in (r_wall, 2.5 * r_wall):
                x, y = radius * np.cos(a), radius * np.sin(a)
                z_up = depth0 - (itf.depth + tan * (x * math.cos(beta) + y * math.sin(beta)))
                if np.max(z_up) < bottom - 1.0 or np.min(z_up) > top + 1.0:
                    continue
                strips.append(np.stack([x, y, z_up], axis=1))

                def rock(layer: int) -> str:
                    return names[g.layers[layer]] if layer < len(g.layers) and \
                        g.layers[layer] < len(names) else "?"

                labels.append(f"interface {k}: {rock(k)} above / {rock(k + 1)} below "
                              f"({itf.depth:.2f} m, dip {itf.dip:g}, az {itf.azimuth:g})"
                              if radius == r_wall else "")
                colors.append((90, 90, 90) if radius == r_wall else (170, 170, 170))
        if strips:
            self.stream.log("bit/interfaces", rr.LineStrips3D(strips, colors=colors,
                                                              labels=labels, radii=0.001),
                            static=True)

    # ------------------------------------------------------------------ chunks

    def orbit(self, times: np.ndarray, bit_x: np.ndarray, bit_y: np.ndarray,
              history: np.ndarray) -> np.ndarray:
        """At every sample, the bit centre (mm) and its trail over the last
        ``ORBIT_TRAIL`` samples as a line. ``history``: the trail points
        of the samples before this chunk; returns the history for the next chunk."""
        xy = np.stack([bit_x, bit_y], axis=1) * 1e3
        finite = np.all(np.isfinite(xy), axis=1) & np.isfinite(times)
        points = np.concatenate([history, xy[finite]])
        t = times[finite]
        if len(t):
            self._send("orbit_mm/bit", t, self.rr.Points2D.columns(positions=xy[finite]))
            n_old = len(history)
            strips = [points[max(0, n_old + i + 1 - ORBIT_TRAIL):n_old + i + 1]
                      for i in range(len(t))]
            self._send("orbit_mm/trail", t, self.rr.LineStrips2D.columns(strips=strips))
        return points[-ORBIT_TRAIL:]

    def string(self, times: np.ndarray, lateral: Sequence[np.ndarray],
               depths: np.ndarray, forces: Sequence[np.ndarray | None] = ()) -> None:
        """Snapshots of the string's lateral displacement ``(n_nodes, 2)`` (m) and, where
        given, its wall normal force per node (N): ``string/contact`` marks the nodes
        that touch the wall (or lie on it, soft-string nodes of a curved hole), coloured
        and sized by force."""
        g = self.geometry
        if g.node_depth is None or len(times) == 0:
            return
        k = self.exaggeration
        n_nodes = len(g.node_depth)
        z = -np.asarray(g.node_depth, dtype=np.float64)
        shift = np.where(np.isfinite(depths), depths - g.node_depth[-1], 0.0)
        strips = np.empty((len(times), n_nodes, 3))
        strips[:, :, :2] = np.stack([xy[:n_nodes] for xy in lateral]) * k
        strips[:, :, 2] = z[None, :] - shift[:, None]
        ok = np.all(np.isfinite(strips), axis=(1, 2))
        if not ok.any():
            return
        if len(forces) == len(ok):
            self._contact(times[ok], strips[ok], [f for f, good in zip(forces, ok, strict=True)
                                                  if good])
        strips, times = strips[ok], times[ok]
        self._send("string/deflection", times,
                   self.rr.LineStrips3D.columns(strips=list(strips)))
        self._send("string/bit", times, self.rr.Points3D.columns(positions=strips[:, -1, :]))

    def _contact(self, times: np.ndarray, strips: np.ndarray,
                 forces: Sequence[np.ndarray | None]) -> None:
        """``string/contact``: the nodes with a wall force at each snapshot, coloured and
        sized by force on the fixed scale of :func:`force_share`."""
        if not forces or any(f is None or len(f) != strips.shape[1] for f in forces):
            return
        force = np.nan_to_num(np.stack([np.asarray(f) for f in forces]), nan=0.0,
                              posinf=0.0, neginf=0.0)
        touching = force > 0.0
        share = force_share(force[touching])
        self._send("string/contact", times, self.rr.Points3D.columns(
            positions=strips[touching], colors=force_colors(share),
            radii=0.3 + 1.7 * share**2).partition(lengths=touching.sum(axis=1).tolist()))

    def blades(self, times: np.ndarray, states: np.ndarray) -> None:
        """The blades at snapshots ``states`` = rows (bit x, bit y, depth, angle): pieces
        coloured by rock, and a text of the rock under each blade when it changes."""
        g = self.geometry
        if g.blades is None or g.formation is None or len(times) == 0:
            return
        blades, formation = g.blades, g.formation
        pieces = make_bit_scratch(blades.shape[0], formation.n_interfaces)
        names = g.rock_names
        n_blades = blades.shape[0]
        layer_rock = formation.layer_rock
        n_rocks = max(len(names), int(np.max(layer_rock)) + 1 if layer_rock.size else 1)
        cols: list[list[np.ndarray]] = [[], [], [], [], []]  # sample, blade, segment, rock, len
        kept: list[int] = []
        lengths: list[int] = []
        for j, (bx, by, depth, phi) in enumerate(states):
            if not (math.isfinite(bx) and math.isfinite(by) and math.isfinite(depth)):
                continue
            phi = phi if math.isfinite(phi) else 0.0
            n = int(split_blades(blades, formation, bx, by, depth, phi, pieces))
            cols[0].append(np.full(n, len(kept)))
            for c, arr in zip(cols[1:], (pieces.blade, pieces.segment, pieces.rock,
                                         pieces.length), strict=True):
                c.append(arr[:n].copy())
            kept.append(j)
            lengths.append(n)
        if not kept:
            return
        si, pb, ps, pr, pl = (np.concatenate(c) for c in cols)
        bit_x, bit_y, depth, angle = np.asarray(states)[kept].T
        t = np.asarray(times)[kept]
        p0, p1 = piece_points(blades, si, pb, ps, pl, bit_x[si], bit_y[si], depth[si],
                              angle[si])
        seg = np.stack([p0, p1], axis=1)
        depth0 = g.depth0 if math.isfinite(g.depth0) else float(depth[0])
        seg[:, :, 2] = depth0 - seg[:, :, 2]
        self._send("bit/blades", t, self.rr.LineStrips3D.columns(
            strips=seg, class_ids=pr).partition(lengths))
        # Share of FRONT length (face + shoulder) of each blade in each rock, to 10 %.
        front = ps < 2
        per = np.bincount((si[front] * n_blades + pb[front]) * n_rocks + pr[front],
                          weights=pl[front], minlength=len(t) * n_blades * n_rocks
                          ).reshape(len(t), n_blades, n_rocks)
        total = per.sum(axis=2, keepdims=True)
        pct = np.round(10.0 * per / np.where(total > 0, total, 1.0)).astype(int) * 10
        change = np.ones(len(t), dtype=bool)
        change[1:] = np.any(pct[1:] != pct[:-1], axis=(1, 2))
        if self._blade_rocks is not None:  # the last chunk's text still holds
            change[0] = bool(np.any(pct[0] != self._blade_rocks))
        self._blade_rocks = pct[-1].copy()
        if not change.any():
            return
        texts = []
        for j in np.flatnonzero(change).tolist():
            lines = [f"- blade {b}: " + ", ".join(
                f"{names[r] if r < len(names) else f'rock{r}'} {pct[j, b, r]}%"
                for r in range(n_rocks) if pct[j, b, r] > 0) for b in range(n_blades)]
            texts.append("Rock under each blade (front = face + shoulder, share of length, "
                         "to 10 %):\n\n" + "\n".join(lines))
        self._send("bit/blade_rocks", t[change], self.rr.TextDocument.columns(text=texts))

    def events(self, events: Sequence[tuple[float, str, str]]) -> None:
        if not events:
            return
        ordered = sorted(events, key=lambda e: e[0])
        self._send("events", np.array([e[0] for e in ordered]),
                   self.rr.TextLog.columns(text=[e[2] for e in ordered],
                                           level=[e[1] for e in ordered]))


#: Wall forces (N) at the two ends of the contact colour scale (logarithmic between):
#: ~100 N is a light pipe joint grazing the wall, 50 kN a stabilizer in hard whirl.
FORCE_SCALE = (100.0, 50.0e3)


def force_share(force: np.ndarray) -> np.ndarray:
    """Wall force (N) as a share of the logarithmic scale :data:`FORCE_SCALE`, in [0, 1]."""
    low, high = FORCE_SCALE
    return np.clip(np.log(np.maximum(force, low) / low) / math.log(high / low), 0.0, 1.0)


def force_colors(share: np.ndarray) -> np.ndarray:
    """RGB (uint8) of wall-force shares in [0, 1]: light yellow through orange to dark
    red (a sequential scale that reads on the grey wall and the blue string)."""
    stops = np.array([[255, 230, 120], [245, 140, 40], [200, 30, 30], [110, 0, 20]], float)
    x = np.clip(share, 0.0, 1.0) * (len(stops) - 1)
    k = np.minimum(x.astype(int), len(stops) - 2)
    w = (x - k)[:, None]
    return ((1.0 - w) * stops[k] + w * stops[k + 1]).round().astype(np.uint8)


def piece_points(blades: np.ndarray, si: np.ndarray, pb: np.ndarray, ps: np.ndarray,
                 pl: np.ndarray, bx: np.ndarray, by: np.ndarray, depth: np.ndarray,
                 phi_z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Start and end points (x, y, z down) in the hole frame of blade pieces.

    The pieces come from :func:`~drill_env.physics.bit.split_blades` (in order along each
    segment), ``si`` numbering the snapshot each belongs to; ``bx .. phi_z`` are per piece.
    The blade shape is :func:`~drill_env.physics.bit.blade_points`.
    """
    n = pb.shape[0]
    if n == 0:
        return np.zeros((0, 3)), np.zeros((0, 3))
    points = blade_points(blades)  # A, B, C, D: (radius, height above the face)
    ends = np.stack([points[:, :3], points[:, 1:]], axis=2)  # blade, segment, end, (r, h)
    seg_len = segment_lengths(blades)
    key = (si * blades.shape[0] + pb) * 3 + ps
    new = np.ones(n, dtype=bool)
    new[1:] = key[1:] != key[:-1]
    before = np.cumsum(pl) - pl
    first = np.maximum.accumulate(np.where(new, np.arange(n), 0))
    offset = before - before[first]
    length = seg_len[pb, ps]
    safe = np.where(length > 0, length, 1.0)
    t0 = offset / safe
    t1 = (offset + pl) / safe
    e0 = ends[pb, ps, 0]
    e1 = ends[pb, ps, 1]
    radius_0 = e0[:, 0] + t0 * (e1[:, 0] - e0[:, 0])
    radius_1 = e0[:, 0] + t1 * (e1[:, 0] - e0[:, 0])
    h0 = e0[:, 1] + t0 * (e1[:, 1] - e0[:, 1])
    h1 = e0[:, 1] + t1 * (e1[:, 1] - e0[:, 1])
    theta = blades[pb, Blade.PHI] + phi_z
    c, s = np.cos(theta), np.sin(theta)
    p0 = np.stack([bx + radius_0 * c, by + radius_0 * s, depth - h0], axis=1)
    p1 = np.stack([bx + radius_1 * c, by + radius_1 * s, depth - h1], axis=1)
    return p0, p1


def blueprint(geometry: Geometry, exaggeration: float) -> Any:
    """Default layout: time series (whole episode) left; string, bit, orbit, events, texts
    right. The 3-D cameras look at the bottom of the string and at the bit (a whole 1 km
    string is a line), the time panel starts folded."""
    import rerun.blueprint as rrb

    # every plot spans the whole episode, legends at the top left (its quiet start):
    # by default they followed the cursor with a one-minute window, out of which half a
    # 90 s episode's history fell while the window's end stood empty
    whole = rrb.archetypes.TimeAxis(view_range=rrb.components.TimeRange(
        start=rrb.TimeRangeBoundary.infinite(), end=rrb.TimeRangeBoundary.infinite()))

    def ts(group: str, name: str) -> Any:
        return rrb.TimeSeriesView(origin=f"/timeseries/{group}", name=name,
                                  plot_legend=rrb.PlotLegend(corner=rrb.Corner2D.LeftTop),
                                  axis_x=whole)

    clearance = geometry.clearance
    bounds = None
    if math.isfinite(clearance) and clearance > 0:
        c = clearance * 1e3 * 1.15
        bounds = rrb.VisualBounds2D(x_range=[-c, c], y_range=[-c, c])
    string_camera = None
    if geometry.node_depth is not None:
        bottom = -float(geometry.node_depth[-1])
        width = 2.0 * exaggeration * float(np.max(geometry.node_clearance)) \
            if geometry.node_clearance is not None else 10.0
        string_camera = rrb.EyeControls3D(position=[3.0 * width, -3.0 * width, bottom + 60.0],
                                          look_target=[0.0, 0.0, bottom + 20.0])
    bit_camera = rrb.EyeControls3D(position=[0.45, -0.45, 0.25], look_target=[0.0, 0.0, -0.05])
    left = rrb.Vertical(
        ts("speed_rpm", "Speed (rpm)"),
        ts("torque_kNm", "Torque (kN m)"),
        rrb.Tabs(ts("wob_kN", "WOB (kN)"), ts("hook_load_kN", "Hook load (kN)"),
                 ts("rop_m_per_h", "ROP (m/h)"), ts("depth_m", "Depth (m)"),
                 active_tab="ROP (m/h)"),
        rrb.Tabs(ts("stick_slip", "Stick-slip (SSI)"), ts("whirl_rpm", "Whirl (rpm)"),
                 ts("lateral", "Radial ratio"), ts("rock_share", "Rock share")),
        rrb.Tabs(ts("reward", "Reward"), ts("action", "Action"),
                 ts("info", "Other info (SI)")),
    )
    right = rrb.Vertical(
        rrb.Horizontal(
            rrb.Spatial3DView(origin="/string", name="String, bottom (lateral exaggerated)",
                              eye_controls=string_camera),
            rrb.Spatial3DView(origin="/bit", name="Bit, blades and layers",
                              eye_controls=bit_camera),
        ),
        rrb.Horizontal(
            rrb.Spatial2DView(origin="/orbit_mm", name="Bit orbit (mm), last 2 s",
                              visual_bounds=bounds),
            rrb.TextLogView(origin="/events", name="Events"),
            column_shares=[3, 2],
        ),
        rrb.Tabs(rrb.TextDocumentView(origin="/bit/blade_rocks", name="Blade rocks"),
                 rrb.TextDocumentView(origin="/config/document", name="Config")),
        row_shares=[4, 4, 2],
    )
    return rrb.Blueprint(rrb.Horizontal(left, right, column_shares=[1, 1]),
                         rrb.BlueprintPanel(state="collapsed"),
                         rrb.SelectionPanel(state="collapsed"),
                         rrb.TimePanel(state="collapsed"))
