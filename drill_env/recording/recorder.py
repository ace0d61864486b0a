"""Episode recording to rerun (``.rrd``): one file and one recording id per episode, streamed.

:class:`EpisodeRecorder` opens the file when an episode begins (so an unwritable folder
fails at once, in one line), keeps the per-step values of the current chunk in plain
lists (a few microseconds a step), and writes every ``flush_every`` steps: the series,
orbit, string and blade snapshots of the chunk, and the events the streaming detectors
of :mod:`drill_env.events` found in it. The steps not yet written are one chunk (rerun's
stream keeps ~0.5 MB per chunk written until the file closes: ``flush_every``), and an
interrupted run leaves a readable file with every chunk written so far (the wrapper
finishes the episode on ``close``, as after Ctrl-C; a process killed outright loses the
chunk not yet written, up to ``flush_every`` steps: a 60 s episode at 10 Hz is one).
Each episode has its own :class:`rerun.RecordingStream` (never the global one), so it
works the same in a single process, in subprocess workers and with several envs side by
side.
"""

from __future__ import annotations

import contextlib
import math
import os
import re
import uuid
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from drill_env.env_batch import INFO_WINDOW_METRICS
from drill_env.events import LayerDetector, StickSlipDetector, WhirlDetector
from drill_env.physics.layout import R
from drill_env.physics.validation import jsonable, require_non_negative, require_positive
from drill_env.recording.writer import (
    APPLICATION_ID,
    ROCK_COLORS,
    SERIES,
    SERIES_KEYS,
    Geometry,
    RerunWriter,
    blueprint,
    is_scalar,
)

DEFAULT_DIRECTORY = Path("logs") / "recordings"
#: info keys handled elsewhere (not repeated under timeseries/info).
_SPECIAL_KEYS = frozenset({"time", "bit_lateral", "rock_share", "reward_terms",
                           "termination_reason", *SERIES_KEYS})
_ACTION_NAMES = tuple(f"timeseries/action/{i}" for i in range(16))
#: Columns of a step's records that the whirl events read (``record(records=...)``).
_ORBIT_COLUMNS = [R.TIME, R.BIT_X, R.BIT_Y, R.WHIRL_SPEED, R.BIT_SPEED]


def _num(value: Any) -> float:
    """``float(value)``, NaN for a missing or non-numeric value."""
    if value is None:
        return math.nan
    try:
        return float(value)
    except (TypeError, ValueError):
        return math.nan


def _sanitize(text: str) -> str:
    # (no leading dot: a stem "../x" was written as the hidden file .._x.rrd)
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", str(text)).lstrip("._").rstrip("_") or "x"


def folder_path(directory: Any) -> Path:
    """``directory`` as a Path; ValueError naming it when it is no path (pathlib's bare
    TypeError)."""
    if not isinstance(directory, str | os.PathLike):
        raise ValueError(f"directory: expected a folder's path, got "
                         f"{type(directory).__name__} {directory!r}")
    return Path(directory)


def check_stem(stem: str | None) -> None:
    """ValueError naming ``stem`` unless it is None or a text with a letter or digit (an
    empty one was written as ``x.rrd``)."""
    if stem is not None and not (isinstance(stem, str) and re.search(r"[A-Za-z0-9]", stem)):
        raise ValueError(f"stem: a file name needs a letter or digit, got {stem!r} (None: "
                         "the default name)")


def stem_file_name(stem: str) -> str:
    """The file a recording named by ``stem`` is written to: ``<stem>.rrd``, characters
    other than letters, digits, ``_``, ``.`` and ``-`` replaced by ``_``, without leading
    dots (no hidden file, nothing above the folder)."""
    return f"{_sanitize(stem)}.rrd"


def _path_part(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_]+", "_", str(text)).strip("_") or "x"


def check_directory(directory: Path) -> None:
    """Raise ``OSError`` with one line if recordings cannot be written into ``directory``."""
    try:
        directory.mkdir(parents=True, exist_ok=True)
        probe = directory / f".write-test-{uuid.uuid4().hex[:8]}"
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as err:
        raise OSError(f"directory: cannot write recordings to {directory}: "
                      f"{err.strerror or err}") from None


def save_with_layout(stream: Any, path: Any, layout: Any, application_id: str) -> None:
    """``stream.save(path, default_blueprint=layout)``, its layout's stream closed after.
    rerun 0.41's ``save`` builds the layout in a stream of its own that stays open, with
    its two threads and buffers, for the life of the process: one per episode recorded.
    Falls back to ``save`` where rerun's internals differ."""
    import rerun_bindings as bindings
    from rerun.recording_stream import RecordingStream

    try:
        layout_stream = RecordingStream._from_native(bindings.new_blueprint(
            application_id=application_id, make_default=False, make_thread_default=False,
            default_enabled=True))
        log = layout.to_blueprint()._log_to_stream
    except (AttributeError, TypeError):  # another rerun than the 0.41 the project pins
        stream.save(path, default_blueprint=layout)
        return
    try:
        layout_stream.set_time("blueprint", sequence=0)  # as rerun's own save does
        log(layout_stream)
        memory = layout_stream.memory_recording()
        bindings.save(path=str(path), default_blueprint=memory.storage,
                      recording=stream.to_native(), write_footer=True)
    finally:
        layout_stream.disconnect()


def release_streams() -> None:
    """Free the native side of the rerun streams no longer referenced. rerun 0.41 keeps a
    dropped stream's threads (two per stream: the episode's and its saved layout's) and
    buffers until this runs; a dataset recorded in one process grew by 4 threads and
    ~4.8 MB an episode (1,206 threads after 300 episodes)."""
    try:
        from rerun_bindings import flush_and_cleanup_orphaned_recordings
    except ImportError:  # another rerun: it frees them itself or not at all
        return
    flush_and_cleanup_orphaned_recordings()


class _Detectors(NamedTuple):
    """The streaming event detectors of one episode (state carried across chunks)."""

    stick: StickSlipDetector
    whirl: WhirlDetector | None  # None where the hole has no clearance to whirl in
    layer: LayerDetector


class _Chunk:
    """The per-step values of the steps not yet written."""

    def __init__(self) -> None:
        self.t: list[float] = []
        self.cols: dict[str, list[float]] = {k: [] for k in SERIES_KEYS}
        self.bx: list[float] = []
        self.by: list[float] = []
        self.phi: list[float] = []
        self.shares: list[Any] = []
        self.sparse: dict[str, tuple[list[float], list[float]]] = {}  # name -> (t, values)
        self.string_t: list[float] = []
        self.string_xy: list[np.ndarray] = []
        self.string_force: list[np.ndarray | None] = []
        self.string_depth: list[float] = []
        self.string_state: list[tuple[float, float, float, float]] = []
        # the steps' own records for the whirl events: (m, 5) time, bit x, bit y, whirl
        # speed, bit speed each (record() with ``records``)
        self.orbit: list[np.ndarray] = []

    def drop_partial(self) -> None:
        """Drop what an interrupted :meth:`EpisodeRecorder.record` left half-appended
        (Ctrl-C raises KeyboardInterrupt between any two appends): each group of per-step
        lists back to the length all of its lists have, so the chunk still writes and the
        episode still gets its end event."""
        groups: list[Sequence[list[Any]]] = [
            [self.t, self.bx, self.by, self.phi, self.shares, *self.cols.values()],
            [self.string_t, self.string_xy, self.string_force, self.string_depth,
             self.string_state],
            *self.sparse.values()]
        for group in groups:
            n = min(map(len, group))
            for values in group:
                del values[n:]

    def put(self, name: str, t: float, value: float) -> None:
        entry = self.sparse.get(name)
        if entry is None:
            entry = self.sparse[name] = ([], [])
        entry[0].append(t)
        entry[1].append(value)

    def share_matrix(self) -> np.ndarray | None:
        rows = []
        width = 0
        for s in self.shares:
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


class EpisodeRecorder:
    """Record one episode at a time into its own ``.rrd`` file, chunk by chunk.

    Typical use (the :class:`~drill_env.recording.RecordEpisode` wrapper does this)::

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
        Where the files go (created on demand, checked for writing at ``begin``).
    string_period:
        Simulated seconds between two snapshots of the string deflection and of the
        blades (3-D views); 0 snapshots every recorded step.
    exaggeration:
        Factor on the lateral displacement in the 3-D string view; ``None`` picks a round
        number that maps the largest clearance to ~2 % of the string length.
    flush_every:
        Steps per written chunk (at the default 10 Hz, 100 s of simulated time). Rerun's
        stream keeps ~0.5 MB per chunk written until the file closes: at 100 a recorded
        2 h episode held 280 MB more at its end, at 1,000 65 MB (docs/recording.md).
    application_id:
        rerun application id (all episodes share it; each has its own recording id).
    """

    def __init__(self, directory: str | os.PathLike = DEFAULT_DIRECTORY, *,
                 string_period: float = 0.1, exaggeration: float | None = None,
                 flush_every: int = 1000, application_id: str = APPLICATION_ID) -> None:
        require_non_negative(string_period, "string_period")
        if exaggeration is not None:
            require_positive(exaggeration, "exaggeration")
        if not (isinstance(flush_every, int) and flush_every >= 1):
            raise ValueError(f"flush_every: must be an integer >= 1, got {flush_every!r}")
        self.directory = folder_path(directory)
        self.string_period = float(string_period)
        self.exaggeration = exaggeration
        self.flush_every = flush_every
        self.application_id = application_id
        self.active = False
        self.sim: Any = None
        self.scenario = "episode"
        self.controller: str | None = None
        self.seed: int | None = None
        self.episode_index = 0
        self.recording_id = ""
        self.stem: str | None = None
        self.path: Path | None = None
        self.last_path: Path | None = None
        self.last_recording_id: str | None = None
        self._chunk = _Chunk()
        self._flushed = 0  # steps of this episode written to the file
        self._stream: Any = None
        self._writer: RerunWriter | None = None
        self._saved = False

    def __getstate__(self) -> dict[str, Any]:
        """Picklable (a copy, a worker process) between episodes, not while one is being
        recorded: rerun's stream cannot travel (a raw TypeError of rerun's bindings)."""
        if self._stream is not None:
            raise TypeError("EpisodeRecorder: an episode is being recorded (its rerun stream "
                            "is open): pickle or copy the env it wraps (.env), or this one "
                            "between episodes")
        return self.__dict__.copy()

    # ------------------------------------------------------------------ begin

    def begin(self, *, sim: Any = None, config: Any = None, scenario: str | None = None,
              seed: int | None = None, episode_index: int = 0,
              env_settings: Mapping[str, Any] | None = None,
              info: Mapping[str, Any] | None = None,
              recording_id: str | None = None, stem: str | None = None,
              controller: str | None = None) -> str:
        """Start a new episode (an unfinished one is finished first); returns its id.

        ``sim`` is the :class:`~drill_env.physics.simulator.Simulator` (geometry, string
        snapshots, blade angle); ``config`` its ``SimulationConfig`` (taken from ``sim``
        when omitted); ``env_settings`` anything JSON-like describing the run (env
        keywords, env config); ``info`` the reset info, recorded as the first sample;
        ``stem`` the file's name without ``.rrd`` (:meth:`file_name`); ``controller`` the
        name of what drove the episode (kept with the scenario and leading the file's
        name). The file is opened now: ``OSError`` (one line) if its folder is not
        writable or the file cannot be created; then no episode is active.
        """
        if self.active:
            self.finish(note="a new episode began")
        check_directory(self.directory)
        import rerun as rr

        self.sim = sim
        config = config if config is not None else getattr(sim, "config", None)
        self.scenario = str(scenario) if scenario is not None else "episode"
        self.controller = controller
        self.seed = seed
        self.episode_index = int(episode_index)
        self.recording_id = recording_id or uuid.uuid4().hex
        self.stem = stem
        geometry = capture_geometry(sim, config)
        self._detectors = _Detectors(
            StickSlipDetector(),
            WhirlDetector(geometry.clearance) if math.isfinite(geometry.clearance)
            and geometry.clearance > 0 else None,
            LayerDetector(geometry.rock_names))
        self._chunk = _Chunk()
        self._flushed = 0
        self._next_string_t = -math.inf
        self._names: dict[Any, str] = {}
        self._styled: set[str] = set()
        self._start_time = math.nan
        self._last_time = math.nan
        self._orbit_history = np.zeros((0, 2))
        self.path = self.directory / self.file_name()
        stream = rr.RecordingStream(self.application_id, recording_id=self.recording_id)
        self._stream = stream
        self._writer = None
        self._saved = False  # whether the file was started (to remove if it fails)
        self.active = True
        if not rr.is_enabled(stream):  # RERUN=off: record nothing, said once per process
            warnings.warn("rerun is disabled in this process (RERUN=off): nothing is "
                          "recorded", RuntimeWarning, stacklevel=3)
            return self.recording_id
        try:
            self._open(stream, geometry, config, env_settings, info)
        except BaseException:
            self.discard()  # the stream closed, a started file removed, nothing active
            raise
        return self.recording_id

    def _open(self, stream: Any, geometry: Any, config: Any,
              env_settings: Mapping[str, Any] | None,
              info: Mapping[str, Any] | None) -> None:
        """:meth:`begin`'s writing: the file, the episode's header and first sample."""
        stream.set_log_time_enabled(False)
        try:
            save_with_layout(stream, self.path, blueprint(
                geometry, geometry.exaggeration(self.exaggeration)), self.application_id)
        except RuntimeError as err:  # rerun's "Failed to create file: ..."
            raise OSError(f"{self.path}: cannot write the recording: {err}") from None
        self._saved = True
        stream.send_recording_name(
            f"{self._driven}{self.scenario} seed {self.seed} episode {self.episode_index}")
        k = geometry.exaggeration(self.exaggeration)
        writer = RerunWriter(stream, geometry, k)
        self._writer = writer
        self._config_tree = jsonable(config) if config is not None else {}
        self._settings = jsonable(dict(env_settings or {}))
        self._geometry = geometry
        writer.configuration(self._config_tree, self._settings, self._summary("running"))
        writer.episode(self._episode_fields("running"))
        writer.scene()
        if info is not None:
            self.record(info)
        stream.flush()

    def file_name(self) -> str:
        """``<stem>.rrd`` when :meth:`begin` was given a stem (a name the caller keeps
        unique, such as the benchmark's controller, scenario and seed), else
        ``[<controller>_]<scenario>_seed<seed>_ep<index>_<recording id>.rrd``, with
        ``noseed`` for ``seed<seed>`` when the episode's reset got no seed."""
        if self.stem is not None:
            return stem_file_name(self.stem)
        seed = "noseed" if self.seed is None else f"seed{_sanitize(str(self.seed))}"
        lead = f"{_sanitize(self.controller)}_" if self.controller else ""
        return (f"{lead}{_sanitize(self.scenario)}_{seed}_ep{self.episode_index:04d}_"
                f"{self.recording_id[:8]}.rrd")

    # ------------------------------------------------------------------ steps

    def record(self, info: Mapping[str, Any], action: Any = None, reward: float | None = None,
               sim: Any = None, records: np.ndarray | None = None) -> None:
        """Append one step: the ``info`` values, optionally the action and the reward.

        ``records``: the step's simulator records (columns ``RECORD_CHANNELS``, the env's
        ``last_records``); given, the whirl events judge them, at the rate the metrics
        read, instead of one reading per step (which aliases a rattle at the blade-pass
        rate into an orbit). Missing keys are skipped (NaN, not plotted); nothing here
        raises on odd input.
        """
        if not self.active:
            self.begin(sim=sim)
        sim = sim if sim is not None else self.sim
        c = self._chunk
        t = _num(info.get("time"))
        if math.isnan(t):
            t = _num(getattr(sim, "time", None)) if sim is not None else math.nan
            if math.isnan(t):
                t = (self._last_time + 1.0) if math.isfinite(self._last_time) else 0.0
        if math.isnan(self._start_time):
            self._start_time = t
        self._last_time = t
        if records is not None and getattr(records, "ndim", 0) == 2 and len(records):
            c.orbit.append(np.asarray(records, dtype=np.float64)[:, _ORBIT_COLUMNS])
        c.t.append(t)
        for key in SERIES_KEYS:
            c.cols[key].append(_num(info.get(key)))
        lateral = info.get("bit_lateral")
        if lateral is None and sim is not None:
            lateral = getattr(sim, "bit_lateral", None)
        try:
            bx, by = float(lateral[0]), float(lateral[1])  # type: ignore[index]
        except (TypeError, ValueError, IndexError, KeyError):
            bx = by = math.nan
        c.bx.append(bx)
        c.by.append(by)
        c.shares.append(info.get("rock_share"))
        phi = _num(getattr(sim, "bit_angle", None)) if sim is not None else math.nan
        c.phi.append(phi)

        names = self._names
        for key, value in info.items():
            if type(value) is not float and not is_scalar(value):
                if key == "reward_terms" and isinstance(value, Mapping):
                    for term, v in value.items():
                        if type(v) is float or is_scalar(v):
                            name = names.get(("reward", term))
                            if name is None:
                                name = names[("reward", term)] = (
                                    "timeseries/reward/" + _path_part(term))
                            c.put(name, t, float(v))
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
                c.put(name, t, float(value))
        if reward is not None:
            c.put("timeseries/reward/total", t, _num(reward))
        if action is not None:
            try:
                a = np.asarray(action, dtype=np.float64).reshape(-1).tolist()
            except (TypeError, ValueError):
                a = []
            for i, v in enumerate(a):
                c.put(_ACTION_NAMES[i] if i < len(_ACTION_NAMES) else f"timeseries/action/{i}",
                      t, v)
        if sim is not None and t >= self._next_string_t and hasattr(sim, "lateral_displacement"):
            depth = _num(getattr(sim, "depth", None))
            c.string_t.append(t)
            c.string_xy.append(sim.lateral_displacement)
            forces = getattr(sim, "contact_forces", None)
            c.string_force.append(None if forces is None else np.array(forces, copy=True))
            c.string_depth.append(depth)
            c.string_state.append((bx, by, depth, phi))
            self._next_string_t = t + self.string_period - 1e-9
        if len(c.t) >= self.flush_every:
            self.flush()

    @property
    def n_steps(self) -> int:
        """Samples recorded in the current episode."""
        return self._flushed + len(self._chunk.t)

    def flush(self) -> None:
        """Write the steps collected since the last flush and wait for them to reach the
        file."""
        c = self._chunk
        self._chunk = _Chunk()
        c.drop_partial()
        first = self._flushed == 0
        self._flushed += len(c.t)
        writer = self._writer
        if writer is None or not c.t:
            return
        t = np.asarray(c.t, dtype=np.float64)
        for s in SERIES:
            values = np.asarray(c.cols[s.key], dtype=np.float64) * s.scale
            self._scalars(s.entity, t, values, s.label, s.color)
        bx, by = np.asarray(c.bx), np.asarray(c.by)
        g = self._geometry
        if math.isfinite(g.clearance) and g.clearance > 0:
            self._scalars("timeseries/lateral/radial_ratio", t, np.hypot(bx, by) / g.clearance,
                          "|bit lateral| / clearance", (170, 110, 220))
        shares = c.share_matrix()
        if shares is not None:
            for j in range(shares.shape[1]):
                name = g.rock_names[j] if j < len(g.rock_names) else f"rock{j}"
                self._scalars(f"timeseries/rock_share/{name}", t, shares[:, j], name,
                              ROCK_COLORS[j % len(ROCK_COLORS)])
        for name, (times, vals) in sorted(c.sparse.items()):
            key = name.rsplit("/", 1)[-1]
            # the window metrics are means over the env's last metric_window s: said, so
            # the info's radial_ratio is not read as the instantaneous one of "lateral"
            label = f"{key} (window mean)" if name.startswith(
                "timeseries/info/") and key in INFO_WINDOW_METRICS else key
            self._scalars(name, np.asarray(times), np.asarray(vals, dtype=np.float64), label)
        self._orbit_history = writer.orbit(t, bx, by, self._orbit_history)
        writer.string(np.asarray(c.string_t), c.string_xy, np.asarray(c.string_depth),
                      c.string_force)
        writer.blades(np.asarray(c.string_t), np.asarray(c.string_state).reshape(-1, 4))
        # events: the streaming detectors carry their state from chunk to chunk
        stick, whirl, layer = self._detectors
        w = np.asarray(c.cols["bit_speed"], dtype=np.float64)
        events = stick.update(t, w)
        if whirl is not None and c.orbit:  # the steps' records
            o = np.concatenate(c.orbit)
            events += whirl.update(o[:, 0], o[:, 1], o[:, 2], o[:, 3], o[:, 4])
        elif whirl is not None:  # one reading a step
            events += whirl.update(t, bx, by, np.asarray(c.cols["whirl_speed"]), w)
        if shares is not None:
            events += layer.update(t, shares)
        if first:  # the first chunk of the episode
            events.insert(0, (float(t[0]), "INFO",
                              f"episode start: {self._driven}scenario {self.scenario}, "
                              f"seed {self.seed}, "
                              f"episode {self.episode_index}"))
        writer.events(events)
        self._stream.flush()

    def _scalars(self, entity: str, times: np.ndarray, values: np.ndarray, label: str,
                 color: tuple[int, int, int] | None = None) -> None:
        writer = self._writer
        if writer is None:
            return
        if writer.scalars(entity, times, values) and entity not in self._styled:
            writer.styled(entity, label, color)
            self._styled.add(entity)

    # ------------------------------------------------------------------ end

    def finish(self, termination_reason: str | None = None, truncated: bool = False,
               note: str | None = None) -> Path | None:
        """Write what is left of the episode and close its file.

        ``termination_reason`` (terminated: an ERROR event), ``truncated`` (time limit)
        or ``note`` (why an episode ends otherwise, e.g. a reset or an interrupt) label
        the last event. Returns the path (``None`` if no episode is active or it has no
        sample, in which case no file is left, or rerun is disabled by ``RERUN=off``).
        """
        if not self.active:
            return None
        self.active = False
        stream, writer, path = self._stream, self._writer, self.path
        try:
            if writer is None:
                return None
            if self.n_steps == 0:
                stream.disconnect()
                if path is not None:
                    path.unlink(missing_ok=True)
                return None
            self.flush()
            whirl = self._detectors.whirl
            if whirl is not None:  # the last seconds' samples, which no later one follows
                writer.events(whirl.finish())
            last = self._last_time
            if termination_reason:
                end = (last, "ERROR", f"terminated: {termination_reason}")
                state = f"terminated: {termination_reason}"
            elif truncated:
                end = (last, "INFO", "episode truncated (time limit)")
                state = "truncated (time limit)"
            else:
                end = (last, "INFO", f"episode end: {note}" if note else "episode end")
                state = note or "ended"
            writer.events([end])
            writer.episode(self._episode_fields(state))
            writer.configuration(self._config_tree, self._settings, self._summary(state))
            stream.flush()
            stream.disconnect()
        except BaseException:
            with contextlib.suppress(Exception):  # the stream closed even so
                stream.disconnect()
            if path is not None:  # an episode without its end: not left as if recorded
                path.unlink(missing_ok=True)
            raise
        finally:
            self._stream = self._writer = None
            self._chunk = _Chunk()
            del stream, writer
            release_streams()
        self.last_path = path
        self.last_recording_id = self.recording_id
        return path

    def discard(self) -> None:
        """Drop the current episode and its file."""
        if not self.active:
            return
        self.active = False
        if self._stream is not None:
            with contextlib.suppress(Exception):  # a failed stream: its file goes below
                self._stream.disconnect()
        if self.path is not None and self._saved:
            self.path.unlink(missing_ok=True)
        self._stream = self._writer = None
        self._chunk = _Chunk()
        release_streams()

    # ------------------------------------------------------------------ text

    @property
    def _driven(self) -> str:
        """``"<controller>, "`` where the episode names its controller, else ""."""
        return f"{self.controller}, " if self.controller else ""

    def _episode_fields(self, state: str) -> dict[str, Any]:
        g = self._geometry
        return {
            "scenario": self.scenario, "controller": self.controller or "",
            # the env's registered id ("" for an env not made by id): a task's episodes
            # were told from the plain env's by /config/env alone, which is not returned
            "env_id": str(self._settings.get("env_id") or ""),
            "seed": -1 if self.seed is None else self.seed,
            "episode_index": self.episode_index, "recording_id": self.recording_id,
            "samples": self._flushed, "start_time_s": self._start_time,
            "end_time_s": self._last_time, "state": state,
            "string_exaggeration": self._writer.exaggeration if self._writer else math.nan,
            "string_period_s": self.string_period,
            "gauge_clearance_m": g.clearance, "rock_names": ", ".join(g.rock_names),
            **_provenance(),
        }

    def _summary(self, state: str) -> list[str]:
        k = self._writer.exaggeration if self._writer else math.nan
        return [f"- scenario: `{self.scenario}`",
                *([f"- controller: `{self.controller}`"] if self.controller else []),
                f"- seed: {self.seed}",
                f"- episode index: {self.episode_index}",
                f"- recording id: `{self.recording_id}`",
                "- written by drill-env {drill_env_version} (sources {drill_env_sources})"
                .format(**_provenance()),
                f"- simulated time: {self._start_time:.3f} - {self._last_time:.3f} s "
                f"({self._flushed} samples)", f"- state: {state}",
                f"- 3-D string view: lateral displacement exaggerated x{k:g}; "
                "z = minus measured depth (m)",
                "- bit view: true scale (m); z = initial bit depth minus depth"]


def _provenance() -> dict[str, str]:
    """Which code wrote a recording: the package version and the digest of its sources
    (the one stored sweep results are keyed by), so two recordings can be told apart
    after the code changed in between."""
    from drill_env import __version__
    from drill_env.sweep import source_digest

    return {"drill_env_version": __version__, "drill_env_sources": source_digest("drill_env")}


def capture_geometry(sim: Any, config: Any) -> Geometry:
    """The :class:`~drill_env.recording.writer.Geometry` of a simulator (and its config);
    what is missing stays NaN / None."""
    g = Geometry()
    bit = getattr(config, "bit", None)
    if bit is not None:
        g.clearance = float(bit.gauge_clearance)
        g.hole_radius = float(bit.hole_radius)
    formation = getattr(config, "formation", None)
    rocks = getattr(formation, "rocks", ()) or ()
    names: list[str] = []
    for j, rock in enumerate(rocks):
        name = _path_part(getattr(rock, "name", f"rock{j}"))
        names.append(name if name not in names else f"{name}_{j}")
    g.rock_names = names
    g.interfaces = tuple(getattr(formation, "interfaces", ()) or ())
    g.layers = tuple(getattr(formation, "layers", ()) or ())
    if sim is None:
        return g
    if not math.isfinite(g.clearance) and hasattr(sim, "node_clearance"):
        g.clearance = float(sim.node_clearance[-1])
    if hasattr(sim, "node_depth"):
        g.node_depth = np.array(sim.node_depth, copy=True)
    if hasattr(sim, "node_clearance"):
        g.node_clearance = np.array(sim.node_clearance, copy=True)
    if hasattr(sim, "blades") and hasattr(sim, "formation"):
        g.blades = np.array(sim.blades, copy=True)
        g.formation = type(sim.formation)(*(np.array(a, copy=True) for a in sim.formation))
    g.depth0 = _num(getattr(sim, "depth", None))
    return g
