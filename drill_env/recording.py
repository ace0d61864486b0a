"""Episode recording to rerun (``.rrd``): one file and one recording id per episode.

:class:`EpisodeRecorder` keeps the per-step values of an episode in memory (plain lists,
a few microseconds a step) and, at the end of the episode, writes ONE ``.rrd`` file with
its own :class:`rerun.RecordingStream` (never the global recording), so it works the same
in a single process, in subprocess workers and with several envs side by side.
:class:`RecordEpisode` is the Gymnasium wrapper that feeds it from ``step``'s ``info``
and action and from ``env.unwrapped.sim``. :func:`replay` opens a file in the viewer.

Everything is sent in batch at the end with ``send_columns`` on the ``sim_time``
timeline (a duration, in seconds of simulated time). Entity paths (see
``docs/recording.md``):

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
import os
import re
import shutil
import subprocess
import sys
import uuid
import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np

from drill_env.metrics import STUCK_SPEED
from drill_env.physics.formation import FormationArrays
from drill_env.physics.units import RPM

APPLICATION_ID = "drill_env"
TIMELINE = "sim_time"
DEFAULT_DIRECTORY = Path("logs") / "recordings"

#: Whirl counts as on when the bit is this far out (radial displacement / clearance) ...
WHIRL_RADIAL_RATIO = 0.5
#: ... and its centre orbits at least this fraction of the bit speed (either direction) ...
WHIRL_SPEED_RATIO = 0.25
#: ... for at least this long (s); it ends after the same time without the condition.
WHIRL_MIN_DURATION = 0.3
#: A stick after this long (s) without one is a stick-slip ONSET (else one more cycle).
STICK_SLIP_QUIET = 5.0

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
_SERIES_KEYS = tuple(s.key for s in SERIES)
#: info keys handled elsewhere (not repeated under timeseries/info).
_SPECIAL_KEYS = frozenset({"time", "bit_lateral", "rock_share", "reward_terms",
                           "termination_reason", *_SERIES_KEYS})


_ACTION_NAMES = tuple(f"timeseries/action/{i}" for i in range(16))


def _num(value: Any) -> float:
    """``float(value)``, NaN for a missing or non-numeric value."""
    if value is None:
        return math.nan
    try:
        return float(value)
    except (TypeError, ValueError):
        return math.nan


def _is_scalar(value: Any) -> bool:
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(
        value, (bool, np.bool_))


def _sanitize(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", str(text)).strip("_") or "x"


def _path_part(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_]+", "_", str(text)).strip("_") or "x"


def _jsonable(obj: Any) -> Any:
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return _jsonable(dataclasses.asdict(obj))
    if isinstance(obj, Mapping):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, (np.integer, np.floating, np.bool_)):
        return obj.item()
    if obj is None or isinstance(obj, (str, int, float, bool)):
        return obj
    return repr(obj)


def _flatten(obj: Any, prefix: str = "") -> dict[str, Any]:
    """Flat ``{dotted.key: scalar or string}`` of a JSON-like tree (lists of numbers kept)."""
    out: dict[str, Any] = {}
    if isinstance(obj, dict):
        for k, v in obj.items():
            out.update(_flatten(v, f"{prefix}.{k}" if prefix else str(k)))
    elif isinstance(obj, list):
        if obj and all(_is_scalar(v) for v in obj):
            out[prefix] = [float(v) for v in obj]
        else:
            for i, v in enumerate(obj):
                out.update(_flatten(v, f"{prefix}.{i}"))
    elif obj is not None:
        out[prefix] = obj if isinstance(obj, str) else (
            float(obj) if _is_scalar(obj) else str(obj))
    return out


def _nice(value: float) -> float:
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


# --------------------------------------------------------------------------- recorder


class EpisodeRecorder:
    """Collect one episode at a time in memory; write one ``.rrd`` per episode.

    Typical use (the :class:`RecordEpisode` wrapper does this for you)::

        rec = EpisodeRecorder("logs/recordings")
        obs, info = env.reset(seed=3)
        rec.begin(sim=env.unwrapped.sim, scenario="paper_case2", seed=3, info=info)
        while True:
            obs, reward, terminated, truncated, info = env.step(action)
            rec.record(info, action=action, reward=reward)
            if terminated or truncated:
                path = rec.finish(info.get("termination_reason"), truncated=truncated)
                break

    Parameters
    ----------
    directory:
        Where the files go (created on demand); default ``logs/recordings``.
    string_period:
        Simulated seconds between two snapshots of the string deflection and of the
        blades (3-D views); 0 snapshots every recorded step.
    exaggeration:
        Factor on the lateral displacement in the 3-D string view; ``None`` picks a round
        number that maps the largest clearance to ~2 % of the string length.
    application_id:
        rerun application id (all episodes share it; each has its own recording id).
    """

    def __init__(self, directory: str | os.PathLike = DEFAULT_DIRECTORY, *,
                 string_period: float = 0.1, exaggeration: float | None = None,
                 application_id: str = APPLICATION_ID) -> None:
        if not (math.isfinite(string_period) and string_period >= 0):
            raise ValueError(f"string_period: must be a finite number >= 0, got "
                             f"{string_period!r}")
        if exaggeration is not None and not (math.isfinite(exaggeration) and exaggeration > 0):
            raise ValueError(f"exaggeration: must be > 0, got {exaggeration!r}")
        self.directory = Path(directory)
        self.string_period = float(string_period)
        self.exaggeration = exaggeration
        self.application_id = application_id
        self.active = False
        self.sim: Any = None
        self.config: Any = None
        self.scenario = "episode"
        self.seed: int | None = None
        self.episode_index = 0
        self.env_settings: dict[str, Any] = {}
        self.recording_id = ""
        self.termination_reason: str | None = None
        self.truncated = False
        self.note: str | None = None
        self._geometry: dict[str, Any] = {"rock_names": []}
        self.last_path: Path | None = None
        self.last_recording_id: str | None = None
        self._reset_buffers()

    # ------------------------------------------------------------------ collection

    def _reset_buffers(self) -> None:
        self._t: list[float] = []
        self._cols: dict[str, list[float]] = {k: [] for k in _SERIES_KEYS}
        self._bx: list[float] = []
        self._by: list[float] = []
        self._phi: list[float] = []
        self._shares: list[Any] = []
        # Sparse series: name -> (step indices, values).
        self._sparse: dict[str, tuple[list[int], list[float]]] = {}
        self._string_t: list[float] = []
        self._string_xy: list[np.ndarray] = []
        self._string_depth: list[float] = []
        self._string_step: list[int] = []
        self._next_string_t = -math.inf
        self._names: dict[Any, str] = {}

    def begin(self, *, sim: Any = None, config: Any = None, scenario: str | None = None,
              seed: int | None = None, episode_index: int = 0,
              env_settings: Mapping[str, Any] | None = None,
              info: Mapping[str, Any] | None = None,
              recording_id: str | None = None) -> str:
        """Start a new episode (an unfinished one is discarded); returns its recording id.

        ``sim`` is the :class:`~drill_env.physics.simulator.Simulator` (geometry, string
        snapshots, blade angle); ``config`` its ``SimulationConfig`` (taken from ``sim``
        when omitted); ``env_settings`` anything JSON-like describing the run (env
        keywords, env config); ``info`` the reset info, recorded as the first sample.
        """
        self._reset_buffers()
        self.active = True
        self.sim = sim
        self.config = config if config is not None else getattr(sim, "config", None)
        self.scenario = str(scenario) if scenario is not None else "episode"
        self.seed = seed
        self.episode_index = int(episode_index)
        self.env_settings = dict(env_settings or {})
        self.recording_id = recording_id or uuid.uuid4().hex
        self.termination_reason = None
        self.truncated = False
        self.note = None
        # Geometry now: a randomised env replaces its simulator at the next reset.
        self._geometry = self._capture_geometry(sim, self.config)
        if info is not None:
            self.record(info)
        return self.recording_id

    def record(self, info: Mapping[str, Any], action: Any = None, reward: float | None = None,
               sim: Any = None) -> None:
        """Append one step: the ``info`` values, optionally the action and the reward.

        Missing keys are skipped (NaN, not plotted); nothing here raises on odd input.
        """
        if not self.active:
            self.begin(sim=sim)
        sim = sim if sim is not None else self.sim
        step = len(self._t)
        t = _num(info.get("time"))
        if math.isnan(t):
            t = _num(getattr(sim, "time", None)) if sim is not None else math.nan
            if math.isnan(t):
                t = (self._t[-1] + 1.0) if self._t else 0.0
        self._t.append(t)
        cols = self._cols
        for key in _SERIES_KEYS:
            cols[key].append(_num(info.get(key)))
        lateral = info.get("bit_lateral")
        if lateral is None and sim is not None:
            lateral = getattr(sim, "bit_lateral", None)
        try:
            self._bx.append(float(lateral[0]))
            self._by.append(float(lateral[1]))
        except (TypeError, ValueError, IndexError, KeyError):
            self._bx.append(math.nan)
            self._by.append(math.nan)
        self._shares.append(info.get("rock_share"))
        self._phi.append(float(sim.ut[-1]) if sim is not None and hasattr(sim, "ut")
                         else math.nan)

        sparse = self._sparse
        names = self._names
        for key, value in info.items():
            if type(value) is not float and not _is_scalar(value):
                if key == "reward_terms" and isinstance(value, Mapping):
                    for term, v in value.items():
                        if type(v) is float or _is_scalar(v):
                            name = names.get(("reward", term))
                            if name is None:
                                name = names[("reward", term)] = (
                                    "timeseries/reward/" + _path_part(term))
                            entry = sparse.get(name)
                            if entry is None:
                                entry = sparse[name] = ([], [])
                            entry[0].append(step)
                            entry[1].append(float(v))
                continue
            name = names.get(key)
            if name is None:
                if key in _SPECIAL_KEYS:
                    name = ""
                elif key.startswith("reward_"):
                    name = "timeseries/reward/" + _path_part(key[7:])
                else:
                    name = "timeseries/info/" + _path_part(key)
                names[key] = name
            if name:
                entry = sparse.get(name)
                if entry is None:
                    entry = sparse[name] = ([], [])
                entry[0].append(step)
                entry[1].append(float(value))
        if reward is not None:
            self._put(sparse, "timeseries/reward/total", step, _num(reward))
        if action is not None:
            try:
                a = np.asarray(action, dtype=np.float64).reshape(-1).tolist()
            except (TypeError, ValueError):
                a = []
            for i, v in enumerate(a):
                self._put(sparse, _ACTION_NAMES[i] if i < len(_ACTION_NAMES)
                          else f"timeseries/action/{i}", step, v)

        if sim is not None and t >= self._next_string_t and hasattr(sim, "lateral_displacement"):
            self._string_t.append(t)
            self._string_xy.append(sim.lateral_displacement)
            self._string_depth.append(_num(getattr(sim, "depth", None)))
            self._string_step.append(step)
            self._next_string_t = t + self.string_period - 1e-9

    @staticmethod
    def _put(sparse: dict, name: str, step: int, value: float) -> None:
        entry = sparse.get(name)
        if entry is None:
            entry = sparse[name] = ([], [])
        entry[0].append(step)
        entry[1].append(value)

    @property
    def n_steps(self) -> int:
        """Samples recorded in the current episode."""
        return len(self._t)

    def discard(self) -> None:
        """Drop the current episode without writing it."""
        self.active = False
        self._reset_buffers()

    # ------------------------------------------------------------------ geometry

    @staticmethod
    def _capture_geometry(sim: Any, config: Any) -> dict[str, Any]:
        g: dict[str, Any] = {}
        bit = getattr(config, "bit", None)
        g["clearance"] = float(getattr(bit, "gauge_clearance", math.nan)) if bit else math.nan
        g["hole_radius"] = float(bit.hole_radius) if bit is not None else math.nan
        rocks = getattr(getattr(config, "formation", None), "rocks", ()) or ()
        names = []
        for j, rock in enumerate(rocks):
            name = _path_part(getattr(rock, "name", f"rock{j}"))
            names.append(name if name not in names else f"{name}_{j}")
        g["rock_names"] = names
        if sim is None:
            return g
        if not math.isfinite(g["clearance"]) and hasattr(sim, "node_clearance"):
            g["clearance"] = float(sim.node_clearance[-1])
        for attr in ("node_depth", "node_clearance", "blades"):
            if hasattr(sim, attr):
                g[attr] = np.array(getattr(sim, attr), copy=True)
        if hasattr(sim, "formation"):
            g["formation"] = FormationArrays(*(a.copy() for a in sim.formation))
        g["depth0"] = _num(getattr(sim, "depth", None))
        return g

    def _exaggeration(self) -> float:
        if self.exaggeration is not None:
            return float(self.exaggeration)
        g = self._geometry
        depth = g.get("node_depth")
        clear = g.get("node_clearance")
        if depth is None or clear is None or len(depth) < 2:
            return 100.0
        length = float(depth[-1] - depth[0])
        return _nice(0.02 * length / max(float(np.max(clear)), 1e-6))

    # ------------------------------------------------------------------ writing

    def file_name(self) -> str:
        seed = "noseed" if self.seed is None else _sanitize(str(self.seed))
        return (f"{_sanitize(self.scenario)}_seed{seed}_ep{self.episode_index:04d}_"
                f"{self.recording_id[:8]}.rrd")

    def finish(self, termination_reason: str | None = None, truncated: bool = False,
               note: str | None = None) -> Path | None:
        """Write the episode to ``directory/<scenario>_seed<seed>_ep<i>_<id>.rrd``.

        ``termination_reason`` (terminated: an ERROR event), ``truncated`` (time limit)
        or ``note`` (why an episode ends otherwise, e.g. a reset) label the last event.

        Returns the path (``None`` if no episode is active or it has no sample, or rerun
        is disabled by ``RERUN=off``). The file appears atomically (written aside, then
        renamed).
        """
        if not self.active:
            return None
        self.active = False
        if not self._t:
            self._reset_buffers()
            return None
        self.termination_reason = termination_reason or None
        self.truncated = bool(truncated)
        self.note = note
        import rerun as rr

        self.directory.mkdir(parents=True, exist_ok=True)
        path = self.directory / self.file_name()
        part = path.with_name(path.name + ".part")
        stream = rr.RecordingStream(self.application_id, recording_id=self.recording_id)
        if not stream.is_enabled():
            self._reset_buffers()
            return None
        try:
            stream.set_log_time_enabled(False)
            stream.save(part, default_blueprint=self.blueprint())
            stream.send_recording_name(
                f"{self.scenario} seed {self.seed} episode {self.episode_index}")
            self._write(stream, rr)
            stream.flush()
            stream.disconnect()
        except BaseException:
            stream.disconnect()
            part.unlink(missing_ok=True)
            self._reset_buffers()
            raise
        finally:
            del stream
        os.replace(part, path)
        self.last_path = path
        self.last_recording_id = self.recording_id
        self._reset_buffers()
        return path

    def _write(self, stream: Any, rr: Any) -> None:
        t = np.asarray(self._t, dtype=np.float64)
        self._write_static(stream, rr, t)
        self._write_series(stream, rr, t)
        self._write_orbit(stream, rr, t)
        self._write_string(stream, rr)
        self._write_bit(stream, rr)
        self._write_events(stream, rr, t)

    def _send(self, stream: Any, rr: Any, entity: str, times: np.ndarray, columns: Any) -> None:
        stream.send_columns(entity, indexes=[rr.TimeColumn(TIMELINE, duration=times)],
                            columns=columns)

    def _scalars(self, stream: Any, rr: Any, entity: str, times: np.ndarray,
                 values: np.ndarray, label: str | None = None,
                 color: tuple[int, int, int] | None = None) -> None:
        mask = np.isfinite(values) & np.isfinite(times)
        if not mask.any():
            return
        stream.log(entity, rr.SeriesLines(names=label or entity.rsplit("/", 1)[-1],
                                          colors=color, widths=1.5), static=True)
        self._send(stream, rr, entity, times[mask], rr.Scalars.columns(scalars=values[mask]))

    def _write_static(self, stream: Any, rr: Any, t: np.ndarray) -> None:
        cfg = self.config
        cfg_tree = _jsonable(cfg) if cfg is not None else {}
        settings = _jsonable(self.env_settings)
        g = self._geometry
        k = self._exaggeration()
        episode = {
            "scenario": self.scenario, "seed": -1 if self.seed is None else self.seed,
            "episode_index": self.episode_index, "recording_id": self.recording_id,
            "steps": len(t), "start_time_s": float(t[0]), "end_time_s": float(t[-1]),
            "termination_reason": self.termination_reason or "",
            "truncated": self.truncated, "end_note": self.note or "", "string_exaggeration": k,
            "string_period_s": self.string_period,
            "gauge_clearance_m": g.get("clearance", math.nan),
            "rock_names": ", ".join(g["rock_names"]),
        }
        stream.log("config/episode", rr.AnyValues(**episode), static=True)
        flat = {key: v for key, v in _flatten(cfg_tree).items() if key}
        if flat:
            stream.log("config/simulation", rr.AnyValues(**flat), static=True)
        flat_env = {key: v for key, v in _flatten(settings).items() if key}
        if flat_env:
            stream.log("config/env", rr.AnyValues(**flat_env), static=True)
        doc = ["# Episode", "", f"- scenario: `{self.scenario}`", f"- seed: {self.seed}",
               f"- episode index: {self.episode_index}",
               f"- recording id: `{self.recording_id}`",
               f"- simulated time: {t[0]:.3f} - {t[-1]:.3f} s ({len(t)} samples)",
               f"- end: {self.termination_reason or ('truncated' if self.truncated else '-')}",
               f"- 3-D string view: lateral displacement exaggerated x{k:g}; "
               "z = minus measured depth (m)",
               "- bit view: true scale (m); z = initial bit depth minus depth",
               "", "## Environment settings", "", "```json",
               json.dumps(settings, indent=1, default=str), "```", "",
               "## Simulation config (SI)", "", "```json",
               json.dumps(cfg_tree, indent=1, default=str), "```"]
        stream.log("config/document", rr.TextDocument("\n".join(doc),
                                                      media_type=rr.MediaType.MARKDOWN),
                   static=True)

    def _write_series(self, stream: Any, rr: Any, t: np.ndarray) -> None:
        for s in SERIES:
            values = np.asarray(self._cols[s.key], dtype=np.float64) * s.scale
            self._scalars(stream, rr, s.entity, t, values, s.label, s.color)
        clearance = self._geometry.get("clearance", math.nan)
        bx = np.asarray(self._bx)
        by = np.asarray(self._by)
        if math.isfinite(clearance) and clearance > 0:
            self._scalars(stream, rr, "timeseries/lateral/radial_ratio", t,
                          np.hypot(bx, by) / clearance, "|bit lateral| / clearance",
                          (170, 110, 220))
        shares = self._share_matrix()
        if shares is not None:
            names = self._geometry["rock_names"]
            for j in range(shares.shape[1]):
                name = names[j] if j < len(names) else f"rock{j}"
                self._scalars(stream, rr, f"timeseries/rock_share/{name}", t, shares[:, j],
                              name, ROCK_COLORS[j % len(ROCK_COLORS)])
        for name, (idx, vals) in sorted(self._sparse.items()):
            self._scalars(stream, rr, name, t[np.asarray(idx, dtype=np.int64)],
                          np.asarray(vals, dtype=np.float64), name.rsplit("/", 1)[-1])

    def _share_matrix(self) -> np.ndarray | None:
        rows = []
        width = 0
        for s in self._shares:
            try:
                a = np.asarray(s, dtype=np.float64).reshape(-1) if s is not None else None
            except (TypeError, ValueError):
                a = None
            rows.append(a)
            if a is not None:
                width = max(width, a.shape[0])
        if width == 0:
            return None
        out = np.full((len(rows), width), np.nan)
        for i, a in enumerate(rows):
            if a is not None:
                out[i, :a.shape[0]] = a
        return out

    def _write_orbit(self, stream: Any, rr: Any, t: np.ndarray) -> None:
        clearance = self._geometry.get("clearance", math.nan)
        if math.isfinite(clearance):
            stream.log("orbit_mm/clearance",
                       rr.LineStrips2D([_circle(clearance * 1e3)], colors=(120, 120, 120),
                                       radii=0.03, labels="gauge clearance"), static=True)
            stream.log("orbit_mm/centre", rr.Points2D([[0.0, 0.0]], radii=0.08,
                                                      colors=(120, 120, 120)), static=True)
        xy = np.stack([self._bx, self._by], axis=1) * 1e3
        mask = np.all(np.isfinite(xy), axis=1)
        if mask.any():
            stream.log("orbit_mm/bit", rr.Points2D.from_fields(radii=0.12, colors=(220, 60, 50)),
                       static=True)
            self._send(stream, rr, "orbit_mm/bit", t[mask],
                       rr.Points2D.columns(positions=xy[mask]))

    def _write_string(self, stream: Any, rr: Any) -> None:
        g = self._geometry
        depth = g.get("node_depth")
        if depth is None or not self._string_t:
            return
        k = self._exaggeration()
        clear = g.get("node_clearance", np.zeros_like(depth))
        z = -np.asarray(depth, dtype=np.float64)
        stream.log("string/info", rr.TextDocument(
            f"Lateral displacement exaggerated x{k:g} (x, y in m x {k:g}); z = minus "
            "measured depth (m). Grey: clearance envelope of every node."), static=True)
        wall = [np.stack([sx * k * clear, sy * k * clear, z], axis=1)
                for sx, sy in ((1, 0), (-1, 0), (0, 1), (0, -1))]
        stream.log("string/wall", rr.LineStrips3D(wall, colors=(150, 150, 150), radii=0.3),
                   static=True)
        times = np.asarray(self._string_t)
        n_nodes = len(depth)
        d = np.asarray(self._string_depth, dtype=np.float64)
        shift = np.where(np.isfinite(d), d - depth[-1], 0.0)
        strips = np.empty((len(times), n_nodes, 3))
        strips[:, :, :2] = np.stack([xy[:n_nodes] for xy in self._string_xy]) * k
        strips[:, :, 2] = z[None, :] - shift[:, None]
        ok = np.all(np.isfinite(strips), axis=(1, 2))
        if not ok.any():
            return
        strips, times = strips[ok], times[ok]
        bits = strips[:, -1, :]
        stream.log("string/deflection", rr.LineStrips3D.from_fields(
            colors=(50, 110, 220), radii=0.6), static=True)
        self._send(stream, rr, "string/deflection", times,
                   rr.LineStrips3D.columns(strips=strips))
        stream.log("string/bit", rr.Points3D.from_fields(colors=(220, 60, 50), radii=2.0),
                   static=True)
        self._send(stream, rr, "string/bit", times,
                   rr.Points3D.columns(positions=np.asarray(bits)))

    def _write_bit(self, stream: Any, rr: Any) -> None:
        g = self._geometry
        if "blades" not in g or "formation" not in g or not self._string_t:
            return
        names = g["rock_names"] or ["rock0"]
        stream.log("bit", rr.AnnotationContext(
            [(j, names[j], ROCK_COLORS[j % len(ROCK_COLORS)]) for j in range(len(names))]),
            static=True)
        depth0 = g.get("depth0", math.nan)
        depths = np.asarray(self._string_depth)
        if not math.isfinite(depth0):
            depth0 = float(depths[0]) if math.isfinite(depths[0]) else 0.0
        hole_r = g.get("hole_radius", math.nan)
        d_end = float(np.nanmax(depths)) if np.isfinite(depths).any() else depth0
        top, bottom = 0.3, -(d_end - depth0) - 0.3
        if math.isfinite(hole_r):
            a = np.linspace(0.0, 2 * math.pi, 8, endpoint=False)
            wall = [np.array([[hole_r * math.cos(ai), hole_r * math.sin(ai), top],
                              [hole_r * math.cos(ai), hole_r * math.sin(ai), bottom]])
                    for ai in a]
            stream.log("bit/wall", rr.LineStrips3D(wall, colors=(150, 150, 150),
                                                   radii=0.0005), static=True)
        self._write_interfaces(stream, rr, depth0, top, bottom, hole_r)
        self._write_blades(stream, rr, depth0)

    def _write_interfaces(self, stream: Any, rr: Any, depth0: float, top: float,
                          bottom: float, hole_r: float) -> None:
        cfg = self.config
        formation = getattr(cfg, "formation", None)
        interfaces = getattr(formation, "interfaces", ()) or ()
        layers = getattr(formation, "layers", ()) or ()
        names = self._geometry["rock_names"]
        if not interfaces:
            return
        r_wall = hole_r if math.isfinite(hole_r) else 0.11
        a = np.linspace(0.0, 2.0 * math.pi, 73)
        strips, labels, colors = [], [], []
        for k, itf in enumerate(interfaces):
            tan = math.tan(math.radians(itf.dip))
            beta = math.radians(itf.azimuth)
            for radius in (r_wall, 2.5 * r_wall):
                x, y = radius * np.cos(a), radius * np.sin(a)
                zdown = itf.depth + tan * (x * math.cos(beta) + y * math.sin(beta))
                zup = depth0 - zdown
                if np.max(zup) < bottom - 1.0 or np.min(zup) > top + 1.0:
                    continue
                strips.append(np.stack([x, y, zup], axis=1))
                above = names[layers[k]] if k < len(layers) and layers[k] < len(names) else "?"
                below = (names[layers[k + 1]]
                         if k + 1 < len(layers) and layers[k + 1] < len(names) else "?")
                labels.append(f"interface {k}: {above} above / {below} below "
                              f"({itf.depth:.2f} m, dip {itf.dip:g}, az {itf.azimuth:g})"
                              if radius == r_wall else "")
                colors.append((90, 90, 90) if radius == r_wall else (170, 170, 170))
        if strips:
            stream.log("bit/interfaces", rr.LineStrips3D(strips, colors=colors,
                                                         labels=labels, radii=0.001),
                       static=True)

    def _write_blades(self, stream: Any, rr: Any, depth0: float) -> None:
        from drill_env.physics.bit import make_bit_scratch, split_blades

        g = self._geometry
        blades = g["blades"]
        formation = g["formation"]
        layer_rock = formation.layer_rock
        scratch = make_bit_scratch(blades.shape[0], formation.n_interfaces)
        names = g["rock_names"]
        n_blades = blades.shape[0]
        n_rocks = max(len(names), int(np.max(layer_rock)) + 1 if layer_rock.size else 1)
        # Split the blades at every snapshot (numba), then place all pieces at once.
        cols: list[list[np.ndarray]] = [[], [], [], [], []]  # sample, blade, segment, rock, len
        samples, times, lengths = [], [], []
        for j, step in enumerate(self._string_step):
            bx, by = self._bx[step], self._by[step]
            depth = self._string_depth[j]
            phi = self._phi[step]
            if not (math.isfinite(bx) and math.isfinite(by) and math.isfinite(depth)):
                continue
            phi = phi if math.isfinite(phi) else 0.0
            n = int(split_blades(blades, formation, bx, by, depth, phi, scratch))
            cols[0].append(np.full(n, len(samples)))
            for c, arr in zip(cols[1:], scratch[:4], strict=True):
                c.append(arr[:n].copy())
            samples.append((bx, by, depth, phi))
            times.append(self._string_t[j])
            lengths.append(n)
        if not times:
            return
        si, pb, ps, pr, pl = (np.concatenate(c) for c in cols)
        state = np.asarray(samples)
        p0, p1 = _piece_points(blades, si, pb, ps, pl, state[si, 0], state[si, 1],
                               state[si, 2], state[si, 3])
        seg = np.stack([p0, p1], axis=1)
        seg[:, :, 2] = depth0 - seg[:, :, 2]
        stream.log("bit/blades", rr.LineStrips3D.from_fields(radii=0.002), static=True)
        self._send(stream, rr, "bit/blades", np.asarray(times),
                   rr.LineStrips3D.columns(strips=seg, class_ids=pr).partition(lengths))
        # Share of FRONT length (face + shoulder) of each blade in each rock, to 10 %.
        front = ps < 2
        per = np.bincount((si[front] * n_blades + pb[front]) * n_rocks + pr[front],
                          weights=pl[front], minlength=len(times) * n_blades * n_rocks
                          ).reshape(len(times), n_blades, n_rocks)
        total = per.sum(axis=2, keepdims=True)
        pct = np.round(10.0 * per / np.where(total > 0, total, 1.0)).astype(int) * 10
        change = np.ones(len(times), dtype=bool)
        change[1:] = np.any(pct[1:] != pct[:-1], axis=(1, 2))
        texts = []
        for j in np.flatnonzero(change):
            lines = [f"- blade {b}: " + ", ".join(
                f"{names[r] if r < len(names) else f'rock{r}'} {pct[j, b, r]}%"
                for r in range(n_rocks) if pct[j, b, r] > 0) for b in range(n_blades)]
            texts.append("Rock under each blade (front = face + shoulder, share of length, "
                         "to 10 %):\n\n" + "\n".join(lines))
        self._send(stream, rr, "bit/blade_rocks", np.asarray(times)[change],
                   rr.TextDocument.columns(text=texts))

    def _write_events(self, stream: Any, rr: Any, t: np.ndarray) -> None:
        events: list[tuple[float, str, str]] = []
        info_level, err = "INFO", "ERROR"
        events.append((t[0], info_level,
                       f"episode start: scenario {self.scenario}, seed {self.seed}, "
                       f"episode {self.episode_index}"))
        w = np.asarray(self._cols["bit_speed"], dtype=np.float64)
        events.extend(stick_slip_events(t, w))
        clearance = self._geometry.get("clearance", math.nan)
        if math.isfinite(clearance) and clearance > 0:
            events.extend(whirl_events(t, np.asarray(self._bx), np.asarray(self._by),
                                       np.asarray(self._cols["whirl_speed"]), w, clearance))
        shares = self._share_matrix()
        if shares is not None:
            events.extend(layer_events(t, shares, self._geometry["rock_names"]))
        if self.termination_reason:
            events.append((t[-1], err, f"terminated: {self.termination_reason}"))
        elif self.truncated:
            events.append((t[-1], info_level, "episode truncated (time limit)"))
        else:
            events.append((t[-1], info_level,
                           f"episode end: {self.note}" if self.note else "episode end"))
        events.sort(key=lambda e: e[0])
        self._send(stream, rr, "events", np.array([e[0] for e in events]),
                   rr.TextLog.columns(text=[e[2] for e in events],
                                      level=[e[1] for e in events]))

    # ------------------------------------------------------------------ blueprint

    def blueprint(self) -> Any:
        """Default layout: time series left; string, bit, orbit, events, config right."""
        import rerun as rr
        import rerun.blueprint as rrb

        def ts(group: str, name: str) -> Any:
            return rrb.TimeSeriesView(origin=f"/timeseries/{group}", name=name)

        clearance = self._geometry.get("clearance", math.nan)
        bounds = None
        if math.isfinite(clearance) and clearance > 0:
            c = clearance * 1e3 * 1.15
            bounds = rrb.VisualBounds2D(x_range=[-c, c], y_range=[-c, c])
        trail = rr.VisibleTimeRange(TIMELINE,
                                    start=rr.TimeRangeBoundary.cursor_relative(seconds=-2.0),
                                    end=rr.TimeRangeBoundary.cursor_relative())
        left = rrb.Vertical(
            ts("speed_rpm", "Speed (rpm)"),
            ts("torque_kNm", "Torque (kN m)"),
            rrb.Tabs(ts("wob_kN", "WOB (kN)"), ts("hook_load_kN", "Hook load (kN)"),
                     ts("rop_m_per_h", "ROP (m/h)"), ts("depth_m", "Depth (m)")),
            rrb.Tabs(ts("stick_slip", "Stick-slip (SSI)"), ts("whirl_rpm", "Whirl (rpm)"),
                     ts("lateral", "Radial ratio"), ts("rock_share", "Rock share")),
            rrb.Tabs(ts("reward", "Reward"), ts("action", "Action"),
                     ts("info", "Other info (SI)")),
        )
        right = rrb.Vertical(
            rrb.Horizontal(
                rrb.Spatial3DView(origin="/string", name="String deflection (exaggerated)"),
                rrb.Spatial3DView(origin="/bit", name="Bit, blades and layers"),
            ),
            rrb.Horizontal(
                rrb.Spatial2DView(origin="/orbit_mm", name="Bit orbit (mm)",
                                  visual_bounds=bounds, time_ranges=trail),
                rrb.TextLogView(origin="/events", name="Events"),
            ),
            rrb.Tabs(rrb.TextDocumentView(origin="/bit/blade_rocks", name="Blade rocks"),
                     rrb.TextDocumentView(origin="/config/document", name="Config")),
            row_shares=[3, 3, 2],
        )
        return rrb.Blueprint(rrb.Horizontal(left, right, column_shares=[1, 1]),
                             rrb.BlueprintPanel(state="collapsed"),
                             rrb.SelectionPanel(state="collapsed"))


# --------------------------------------------------------------------------- events


def stick_slip_events(t: np.ndarray, bit_speed: np.ndarray, quiet: float = STICK_SLIP_QUIET
                      ) -> list[tuple[float, str, str]]:
    """Stick-slip events from sampled bit speed (rad/s).

    A stick is a sample with ``|bit speed| < 1 rpm`` (:data:`drill_env.metrics.STUCK_SPEED`)
    after one at or above it (the bit was moving). The first stick, or the first after
    ``quiet`` seconds without one, is a WARN "stick-slip onset"; the others are DEBUG
    "bit stuck" lines with their cycle count.
    """
    events: list[tuple[float, str, str]] = []
    w = np.abs(np.asarray(bit_speed, dtype=np.float64))
    finite = np.isfinite(w)
    stuck = finite & (w < STUCK_SPEED)
    moving = finite & ~stuck
    was_moving = np.zeros_like(stuck)
    if len(w) > 1:
        was_moving[1:] = moving[:-1]
    starts = np.flatnonzero(stuck & was_moving)
    last = -math.inf
    cycle = 0
    for i in starts:
        ti = float(t[i])
        if ti - last >= quiet:
            cycle = 1
            events.append((ti, "WARN", "stick-slip onset: bit speed below 1 rpm after "
                                       "moving"))
        else:
            cycle += 1
            events.append((ti, "DEBUG", f"bit stuck (cycle {cycle})"))
        last = ti
    return events


def whirl_events(t: np.ndarray, bit_x: np.ndarray, bit_y: np.ndarray, whirl_speed: np.ndarray,
                 bit_speed: np.ndarray, clearance: float,
                 min_duration: float = WHIRL_MIN_DURATION) -> list[tuple[float, str, str]]:
    """Whirl onset / end from the sampled bit lateral state.

    Whirl is on while the radial ratio exceeds :data:`WHIRL_RADIAL_RATIO` and the bit
    centre orbits faster than :data:`WHIRL_SPEED_RATIO` x the bit speed (at least 1 rpm),
    for ``min_duration`` seconds; forward when the orbit turns with the rotation.
    """
    events: list[tuple[float, str, str]] = []
    radial = np.hypot(bit_x, bit_y) / clearance
    ws = np.asarray(whirl_speed, dtype=np.float64)
    w = np.asarray(bit_speed, dtype=np.float64)
    floor = np.maximum(np.abs(np.nan_to_num(w)), STUCK_SPEED)
    cond = (np.nan_to_num(radial) > WHIRL_RADIAL_RATIO) & (
        np.abs(np.nan_to_num(ws)) > WHIRL_SPEED_RATIO * floor)
    on = False
    since: int | None = None
    for i in range(len(t)):
        if bool(cond[i]) == on:
            since = None
            continue
        if since is None:
            since = i
        if float(t[i] - t[since]) < min_duration:
            continue
        on = not on
        k = since
        if on:
            rel = np.nanmean(np.sign(ws[k:i + 1] * np.where(np.isfinite(w[k:i + 1]),
                                                               w[k:i + 1], 1.0)))
            direction = "forward" if rel > 0 else "backward"
            events.append((float(t[k]), "WARN",
                           f"whirl onset ({direction}): radial ratio {radial[k]:.2f}, "
                           f"whirl {ws[k] / RPM:.0f} rpm, bit {w[k] / RPM:.0f} rpm"))
        else:
            events.append((float(t[k]), "INFO", "whirl ended"))
        since = None
    return events


def layer_events(t: np.ndarray, shares: np.ndarray, names: list[str]
                 ) -> list[tuple[float, str, str]]:
    """"layer change" when the dominant rock under the front blades changes."""
    events: list[tuple[float, str, str]] = []
    valid = np.isfinite(shares).any(axis=1)
    if not valid.any():
        return events
    rows = np.flatnonzero(valid)
    dom = np.argmax(np.where(np.isfinite(shares[rows]), shares[rows], -np.inf), axis=1)
    change = np.ones(len(rows), dtype=bool)
    change[1:] = dom[1:] != dom[:-1]

    def name(j: int) -> str:
        return names[j] if j < len(names) else f"rock{j}"

    prev = None
    for k in np.flatnonzero(change):
        i, d = int(rows[k]), int(dom[k])
        row = shares[i]
        mix = ", ".join(f"{name(j)} {row[j] * 100:.0f}%" for j in range(len(row))
                        if np.isfinite(row[j]) and row[j] > 0)
        if prev is None:
            events.append((float(t[i]), "INFO", f"bit in {name(d)} ({mix})"))
        else:
            events.append((float(t[i]), "WARN", f"layer change: {name(prev)} -> {name(d)} "
                                                f"({mix})"))
        prev = d
    return events


# --------------------------------------------------------------------------- blade geometry


def _blade_segments(blades: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per blade and segment (face, shoulder, gauge): (radius, z offset) of both ends and
    the segment length (the geometry of ``drill_env.physics.bit.split_blades``)."""
    from drill_env.physics.bit import blade_points, segment_lengths

    points = blade_points(blades)  # A, B, C, D: (radius, height above the face)
    ends = np.stack([points[:, :3], points[:, 1:]], axis=2)  # blade, segment, end, (r, h)
    return ends, segment_lengths(blades)


def _piece_points(blades: np.ndarray, si: np.ndarray, pb: np.ndarray, ps: np.ndarray,
                  pl: np.ndarray, bx: np.ndarray, by: np.ndarray, depth: np.ndarray,
                  phi_z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Start and end points (x, y, z down) in the hole frame of blade pieces.

    The pieces come from :func:`~drill_env.physics.bit.split_blades` (in order along each
    segment), ``si`` numbering the snapshot each belongs to; ``bx .. phi_z`` are per piece.
    """
    from drill_env.physics.bit import Blade

    n = pb.shape[0]
    if n == 0:
        return np.zeros((0, 3)), np.zeros((0, 3))
    ends, seg_len = _blade_segments(blades)
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
    r0 = e0[:, 0] + t0 * (e1[:, 0] - e0[:, 0])
    r1 = e0[:, 0] + t1 * (e1[:, 0] - e0[:, 0])
    h0 = e0[:, 1] + t0 * (e1[:, 1] - e0[:, 1])
    h1 = e0[:, 1] + t1 * (e1[:, 1] - e0[:, 1])
    theta = blades[pb, Blade.PHI] + phi_z
    c, s = np.cos(theta), np.sin(theta)
    p0 = np.stack([bx + r0 * c, by + r0 * s, depth - h0], axis=1)
    p1 = np.stack([bx + r1 * c, by + r1 * s, depth - h1], axis=1)
    return p0, p1


# --------------------------------------------------------------------------- wrapper


class RecordEpisode(gymnasium.Wrapper):
    """Record every episode of ``env`` to its own ``.rrd`` file (one recording id each).

    Feeds an :class:`EpisodeRecorder` from ``step``'s ``info``, action and reward and from
    ``env.unwrapped.sim``; writes the file when the episode terminates or is truncated,
    when ``reset`` is called mid-episode, or on ``close()``. No global state: safe in
    subprocess workers (``gymnasium.vector.AsyncVectorEnv``, multiprocessing).
    ``last_path`` / ``paths`` list the files written.

    ``scenario`` names the files (default: the env's ``scenario_name`` or its ``spec``
    keyword ``scenario``); ``record`` = False passes everything through untouched.
    ``every`` records one episode in ``every`` (the first, then every ``every``-th).
    An episode cut short by ``reset`` or ``close`` is written if it has at least one
    step (a vector env's final auto-reset leaves none).
    """

    def __init__(self, env: gymnasium.Env, directory: str | os.PathLike = DEFAULT_DIRECTORY,
                 *, scenario: str | None = None, string_period: float = 0.1,
                 exaggeration: float | None = None, every: int = 1, record: bool = True,
                 application_id: str = APPLICATION_ID) -> None:
        super().__init__(env)
        if every < 1:
            raise ValueError(f"every: must be >= 1, got {every!r}")
        self.recorder = EpisodeRecorder(directory, string_period=string_period,
                                        exaggeration=exaggeration,
                                        application_id=application_id)
        self._scenario = scenario
        self.every = int(every)
        self.record = bool(record)
        self.episode_index = -1
        self._steps = 0
        self.paths: list[Path] = []

    @property
    def last_path(self) -> Path | None:
        return self.paths[-1] if self.paths else None

    def _scenario_name(self) -> str:
        if self._scenario is not None:
            return self._scenario
        base = self.env.unwrapped
        name = getattr(base, "scenario_name", None)
        if name is None:
            kwargs = getattr(getattr(self.env, "spec", None), "kwargs", None) or {}
            name = kwargs.get("scenario")
        if name is None:
            sc = getattr(base, "scenario", None)
            name = getattr(sc, "name", sc)
        return str(name) if name is not None else type(base).__name__

    def _env_settings(self) -> dict[str, Any]:
        base = self.env.unwrapped
        spec = getattr(self.env, "spec", None)
        out: dict[str, Any] = {}
        if spec is not None:
            out["env_id"] = getattr(spec, "id", None)
            out["make_kwargs"] = _jsonable(dict(getattr(spec, "kwargs", None) or {}))
        for attr in ("scenario_name", "scenario_params", "physics_overrides", "config"):
            value = getattr(base, attr, None)
            if value is not None and not (attr == "config" and not dataclasses.is_dataclass(
                    value)):
                out[attr] = _jsonable(value)
        for attr in ("control_interval", "episode_duration"):
            try:
                out[attr] = _jsonable(getattr(base, attr))
            except Exception:  # noqa: BLE001 - a description, never fatal
                pass
        return out

    def _flush(self, reason: str | None, truncated: bool, note: str | None = None) -> None:
        if self.recorder.active and note is not None and self._steps == 0:
            self.recorder.discard()  # reset, then reset/close again: nothing to keep
        if self.recorder.active:
            try:
                path = self.recorder.finish(reason, truncated=truncated, note=note)
            except Exception as exc:  # noqa: BLE001 - recording must not stop a run
                warnings.warn(f"RecordEpisode: episode {self.episode_index} not recorded: "
                              f"{exc!r}", RuntimeWarning, stacklevel=3)
                return
            if path is not None:
                self.paths.append(path)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        self._flush(None, truncated=False, note="reset before the episode ended")
        obs, info = self.env.reset(seed=seed, options=options)
        self.episode_index += 1
        self._steps = 0
        if self.record and self.episode_index % self.every == 0:
            base = self.env.unwrapped
            sim = getattr(base, "sim", None)
            config = getattr(base, "simulation_config", None) or getattr(sim, "config", None)
            self.recorder.begin(sim=sim, config=config, scenario=self._scenario_name(),
                                seed=seed, episode_index=self.episode_index,
                                env_settings=self._env_settings(), info=info)
        return obs, info

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        self._steps += 1
        if self.recorder.active:
            self.recorder.record(info, action=action, reward=reward)
            if terminated or truncated:
                reason = info.get("termination_reason") if terminated else None
                self._flush(str(reason) if reason else ("terminated" if terminated else None),
                            truncated=bool(truncated and not terminated))
        return obs, reward, terminated, truncated, info

    def close(self) -> None:
        try:
            self._flush(None, truncated=False, note="env closed before the episode ended")
        finally:
            super().close()


# --------------------------------------------------------------------------- replay


def replay_command(path: str | os.PathLike, web: bool = False,
                   web_viewer_port: int | None = None) -> list[str]:
    """The command line that opens ``path`` in the rerun viewer (see :func:`replay`)."""
    exe = shutil.which("rerun", path=str(Path(sys.executable).parent)) or shutil.which("rerun")
    cmd = [exe] if exe else [sys.executable, "-m", "rerun"]
    if web:
        cmd.append("--web-viewer")
        if web_viewer_port is not None:
            cmd += ["--web-viewer-port", str(int(web_viewer_port))]
    cmd.append(str(path))
    return cmd


def replay(path: str | os.PathLike, web: bool = False, *, web_viewer_port: int | None = None,
           wait: bool = True) -> int | subprocess.Popen:
    """Open a recording in the rerun viewer (the ``rerun`` binary shipped with rerun-sdk).

    ``web=True`` serves the web viewer over HTTP instead (``rerun --web-viewer``; port
    9090 unless ``web_viewer_port``) and opens a browser if there is one. Blocks until
    the viewer exits and returns its exit code; ``wait=False`` returns the process.
    Needs a display (native) or a browser (web): never called by the tests.
    """
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"path: no recording at {p}")
    proc = subprocess.Popen(replay_command(p, web, web_viewer_port))
    if not wait:
        return proc
    try:
        return proc.wait()
    except KeyboardInterrupt:
        proc.terminate()
        return proc.wait()


# --------------------------------------------------------------------------- reading back


@dataclass
class RecordingContents:
    """What :func:`read_recording` found in a ``.rrd`` file."""

    application_id: str
    recording_id: str
    #: Every entity path (leading ``/``) with at least one chunk.
    entities: set[str]
    #: Scalar series: entity -> (sim_time in s, values), sorted by time.
    scalars: dict[str, tuple[np.ndarray, np.ndarray]]
    #: Text log lines: entity -> list of (sim_time s, level, text), sorted by time.
    text_logs: dict[str, list[tuple[float, str, str]]]
    #: Number of blueprint stores in the file.
    n_blueprints: int


def read_recording(path: str | os.PathLike) -> RecordingContents:
    """Read a recording back with rerun's own reader (``rerun.chunk.RrdReader``)."""
    import pyarrow as pa
    from rerun.chunk import RrdReader

    reader = RrdReader(str(path))
    stores = reader.recordings()
    if not stores:
        raise ValueError(f"path: {path} holds no recording")
    entry = stores[0]
    entities: set[str] = set()
    raw: dict[str, list[tuple[np.ndarray, np.ndarray]]] = {}
    logs: dict[str, list[tuple[float, str, str]]] = {}
    for chunk in reader.stream(store=entry):
        entity = chunk.entity_path
        entities.add(entity)
        batch = chunk.to_record_batch()
        names = batch.schema.names
        if TIMELINE not in names:
            continue
        times = batch.column(TIMELINE).cast(pa.int64()).to_numpy(
            zero_copy_only=False).astype(np.float64) * 1e-9
        if "Scalars:scalars" in names:
            col = batch.column("Scalars:scalars")
            values = np.array([row[0] if row else np.nan for row in col.to_pylist()],
                              dtype=np.float64)
            raw.setdefault(entity, []).append((times, values))
        if "TextLog:text" in names:
            texts = [r[0] if r else "" for r in batch.column("TextLog:text").to_pylist()]
            levels = (["" for _ in texts] if "TextLog:level" not in names else
                      [r[0] if r else "" for r in batch.column("TextLog:level").to_pylist()])
            logs.setdefault(entity, []).extend(zip(times.tolist(), levels, texts, strict=True))
    scalars = {}
    for entity, parts in raw.items():
        tt = np.concatenate([p[0] for p in parts])
        vv = np.concatenate([p[1] for p in parts])
        order = np.argsort(tt, kind="stable")
        scalars[entity] = (tt[order], vv[order])
    for lines in logs.values():
        lines.sort(key=lambda e: e[0])
    return RecordingContents(entry.application_id, entry.recording_id, entities, scalars,
                             logs, len(reader.blueprints()))
