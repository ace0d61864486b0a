"""The Gymnasium wrapper that records every episode of an env to its own ``.rrd`` file."""

from __future__ import annotations

import dataclasses
import os
import warnings
from pathlib import Path
from typing import Any

import gymnasium

from drill_env.physics.validation import jsonable
from drill_env.recording.recorder import (
    DEFAULT_DIRECTORY,
    EpisodeRecorder,
    check_directory,
    check_stem,
    folder_path,
    stem_file_name,
)
from drill_env.recording.writer import APPLICATION_ID


class RecordEpisode(gymnasium.Wrapper):
    """Record every episode of ``env`` to its own ``.rrd`` file (one recording id each).

    Feeds an :class:`EpisodeRecorder` from ``step``'s ``info``, action and reward and from
    ``env.unwrapped.sim``. The file is opened at ``reset`` and written in chunks as the
    episode runs; it is finished when the episode terminates or is truncated, when
    ``reset`` is called mid-episode, or on ``close()`` (also after an interrupt: close the
    env in a ``finally``). No global state: safe in subprocess workers
    (``gymnasium.vector.AsyncVectorEnv``, multiprocessing). ``last_path`` / ``paths`` list
    the files written. An unwritable ``directory`` raises ``OSError`` at construction.

    ``scenario`` names the files (default: the env's ``scenario_name`` or its ``spec``
    keyword ``scenario``), after ``controller`` where given (what drove the episode, also
    kept in its metadata and events), or ``stem`` does: ``<stem>.rrd``, later episodes
    ``<stem>_ep<index>.rrd``; ``record`` = False passes everything through untouched.
    ``every`` records one episode in ``every`` (the first, then every ``every``-th).
    An episode cut short by ``reset`` or ``close`` is written if it has at least one
    step (a vector env's final auto-reset leaves none).
    """

    def __init__(self, env: gymnasium.Env, directory: str | os.PathLike = DEFAULT_DIRECTORY,
                 *, scenario: str | None = None, stem: str | None = None,
                 controller: str | None = None,
                 string_period: float = 0.1,
                 exaggeration: float | None = None, every: int = 1, record: bool = True,
                 flush_every: int = 1000, application_id: str = APPLICATION_ID) -> None:
        super().__init__(env)
        if not (isinstance(every, int) and every >= 1):
            raise ValueError(f"every: must be an integer >= 1, got {every!r}")
        check_stem(stem)
        if record:
            check_directory(folder_path(directory))  # now, in one line, not after an episode
        self.recorder = EpisodeRecorder(directory, string_period=string_period,
                                        exaggeration=exaggeration, flush_every=flush_every,
                                        application_id=application_id)
        self._scenario = scenario
        self._stem = stem
        self._controller = controller
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
            out["make_kwargs"] = jsonable(dict(getattr(spec, "kwargs", None) or {}))
        for attr in ("scenario_name", "scenario_params", "physics_overrides", "config"):
            value = getattr(base, attr, None)
            if value is not None and not (attr == "config" and not dataclasses.is_dataclass(
                    value)):
                out[attr] = jsonable(value)
        for attr in ("control_interval", "episode_duration"):
            try:
                out[attr] = jsonable(getattr(base, attr))
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
                self._not_recorded(exc, stacklevel=4)  # _flush, then reset/step/close
                return
            if path is not None and not Path(path).is_file():  # its folder removed meanwhile
                self._not_recorded(FileNotFoundError(f"{path}: gone after it was written"),
                                   stacklevel=4)
            elif path is not None:
                self.paths.append(path)

    def _not_recorded(self, exc: Exception, stacklevel: int = 3) -> None:
        """A write failed (opening the file, a chunk, the end): warn (at the caller of
        ``reset`` or ``step``), drop this episode's recording, let the run go on."""
        warnings.warn(f"RecordEpisode: episode {self.episode_index} not recorded: {exc!r}",
                      RuntimeWarning, stacklevel=stacklevel)
        self.recorder.discard()

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        self._flush(None, truncated=False, note="reset before the episode ended")
        obs, info = self.env.reset(seed=seed, options=options)
        self.episode_index += 1
        self._steps = 0
        if self.record and self.episode_index % self.every == 0:
            base = self.env.unwrapped
            sim = getattr(base, "sim", None)
            config = getattr(base, "simulation_config", None) or getattr(sim, "config", None)
            stem = self._stem if self._stem is None or self.episode_index == 0 else \
                f"{self._stem}_ep{self.episode_index:04d}"
            named = None if stem is None else self.recorder.directory / stem_file_name(stem)
            if named is not None and named.is_file():
                warnings.warn(f"RecordEpisode: {named} exists: this episode's recording "
                              "replaces it (stem= names one file; without it every name is "
                              "unique)", RuntimeWarning, stacklevel=2)
            try:
                self.recorder.begin(sim=sim, config=config, scenario=self._scenario_name(),
                                    seed=seed, episode_index=self.episode_index,
                                    env_settings=self._env_settings(), info=info,
                                    stem=stem, controller=self._controller)
            except Exception as exc:  # noqa: BLE001 - recording must not stop a run
                self._not_recorded(exc)
        return obs, info

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        self._steps += 1
        if self.recorder.active:
            try:
                self.recorder.record(info, action=action, reward=reward,
                                     records=getattr(self.env.unwrapped, "last_records", None))
            except Exception as exc:  # noqa: BLE001 - recording must not stop a run
                self._not_recorded(exc)
                return obs, reward, terminated, truncated, info
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
