"""What the control tasks share: their config split from the env's keywords, the env
defaults they change, and an observation of history frames (oldest first) plus extras,
with downhole data only through telemetry."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

import numpy as np
from gymnasium import spaces

from drill_env.env import OBS_BOUND, DrillStringEnv
from drill_env.physics.config import replace
from drill_env.physics.layout import READ
from drill_env.physics.validation import flatten, jsonable
from drill_env.tasks.telemetry import Telemetry


class TaskEnv(DrillStringEnv):
    """A control task over ``DrillString-v0``. The subclass names its task config
    (``task_class``, which has ``history`` and ``telemetry`` fields), the env defaults it
    changes, its frame and extra entries and how many values its telemetry carries; it
    builds each frame and the downhole values in ``_observation`` and hands them to
    :meth:`_push_frame`, :meth:`_received` and :meth:`_finish`."""

    task_class: type
    task: Any
    env_defaults: dict[str, Any]
    frame: tuple[str, ...]
    extras: tuple[str, ...]
    telemetry_values: int

    #: ``DrillString-v0`` settings a task does not read: it builds its own observation
    #: (no ``sensors``, delay or noise of the plain env) and reward (the plain env's reward
    #: fields that its task config does not also have); a subclass adds its action's.
    unused_env_fields: frozenset[str] = frozenset({
        "sensors", "telemetry_delay", "observation_noise", "force_scale", "rop_scale",
        "rop_weight", "stick_slip_weight", "whirl_weight", "effort_weight",
        "failure_weight", "ssi_cap"})

    def __init__(self, scenario: str, task: Any, **kwargs: Any) -> None:
        fields = {f.name for f in dataclasses.fields(self.task_class)}
        self.own_settings = tuple(sorted(fields))  # a typo of one is suggested one
        config = kwargs.get("config")
        if config is not None and not isinstance(config, Mapping):
            raise ValueError(
                f"config: {type(self).__name__} takes its DrillString-v0 settings as "
                f"keywords or a dict, not a {type(config).__name__}: an EnvConfig holds a "
                f"value for every field, and the task's own defaults "
                f"({', '.join(k for k in self.env_defaults if k != 'scenario')}) could not "
                f"tell the ones you set from EnvConfig's defaults")
        if config:  # a task setting in the dict is the task's (the reward weights both
            # have: in EnvConfig, which the task's reward does not read, it changed nothing)
            given = {k: v for k, v in config.items() if k in fields}
            kwargs["config"] = {k: v for k, v in config.items() if k not in fields}
            config = kwargs["config"]
        else:
            given = {}
        keywords = {k: kwargs.pop(k) for k in list(kwargs) if k in fields}
        # a setting in the task dict and beside it: the dict's was dropped without a word
        # (a keyword wins over ``config``, as in DrillString-v0)
        for where, place in (("in config", given), ("as a keyword", keywords)):
            if twice := sorted(set(task if isinstance(task, dict) else {}) & set(place)):
                raise ValueError(f"{twice[0]}: given twice (in the task dict and {where}); "
                                 "give one")
        given.update(keywords)  # keywords win
        typed = set(kwargs) | set(config or {})
        unused = sorted(typed & (self.unused_env_fields - fields))
        if unused:
            raise ValueError(
                f"{unused[0]}: {type(self).__name__} does not use "
                f"{', '.join(unused)} (a setting of DrillString-v0 that the task replaces "
                f"by its own observation, reward, action or targets); its own settings: "
                f"{', '.join(sorted(fields))}")
        if isinstance(task, self.task_class):
            base = task
        elif task is None or isinstance(task, dict):
            base = self.task_class(**(task or {}))
        else:
            raise ValueError(f"task: expected a {self.task_class.__name__} or a dict of its "
                             f"fields, got {type(task).__name__}")
        self.task = replace(base, **given) if given else base
        # a task default gives way to the caller's value, as a keyword, in ``config`` or,
        # for the fidelity, in ``physics``
        physics = kwargs.get("physics")
        chosen = typed | ({"fidelity"} if isinstance(physics, dict)
                          and "solver.fidelity" in flatten(physics) else set())
        for key, value in self.env_defaults.items():
            if key != "scenario" and key not in chosen:
                kwargs[key] = value
        try:
            super().__init__(scenario, **kwargs)
        except ValueError as err:  # a typo: name the task and its own settings too
            if not str(err).startswith("DrillStringEnv: unknown argument"):
                raise
            raise ValueError(f"{type(self).__name__}: {str(err).partition(': ')[2]}; task "
                             f"settings: {sorted(fields)}") from None
        self.observation_names = tuple(f"{name}[{k}]" for k in range(self.task.history)
                                       for name in self.frame) + self.extras
        self.observation_space = spaces.Box(-OBS_BOUND, OBS_BOUND,
                                            shape=(len(self.observation_names),),
                                            dtype=np.float32)

    def settings(self) -> dict[str, Any]:
        """What this env resolved from its defaults and the caller's keywords, as JSON
        values: the task config (``task``) and the ``DrillString-v0`` settings the task
        reads (``env``), defaults included; the scenario its episodes are drawn from and
        the parameters given to it (its start ranges resolved); the physics overrides
        (the fidelity level among them; the scenario's own physics is its code's). A
        run saves them, so that a later version whose defaults moved can say so instead
        of feeding the policy other observations without a word."""
        env = {k: v for k, v in jsonable(self.config).items()
               if k not in self.unused_env_fields}
        return {"task": jsonable(self.task), "env": env, "scenario": self.scenario_name,
                "scenario_params": jsonable(self.scenario_params),
                "physics": jsonable(self.physics_overrides)}

    def _observation_plan(self) -> list[tuple[int, float]]:
        return []  # the task builds its own observation (_observation)

    def _init_task_state(self) -> None:
        # the observation, built in place: the history frames (oldest first), then the
        # extras; each value NaN -> 0 and clipped to +-OBS_BOUND as it comes in
        size = len(self.frame) * self.task.history + len(self.extras)
        self._obs = np.zeros(size, dtype=np.float32)
        self._frames_seen = 0
        self._telemetry = Telemetry(self.task.telemetry, self.telemetry_values)
        self._telemetry_started = False

    def _init_episode_state(self) -> None:
        super()._init_episode_state()  # (the task is set before the env's own set-up)
        self._init_task_state()

    def _push_frame(self, frame: list[float]) -> None:
        """Append this step's frame; the first one fills the whole history."""
        obs, width = self._obs, len(frame)
        end = width * self.task.history
        if not self._frames_seen:
            obs[:end] = _bounded(frame) * self.task.history
        else:
            obs[:end - width] = obs[width:end]  # numpy copies overlapping slices safely
            obs[end - width:end] = _bounded(frame)
        self._frames_seen += 1

    def _received(self, downhole: list[float]) -> list[float]:
        """The downhole values as last received through the telemetry, and the age of
        that message / 10 s (capped at 100 s)."""
        now = self._readings[READ.TIME]
        if not self._telemetry_started:
            self._telemetry.reset(now, self.control_interval)
            self._telemetry_started = True
        held = self._telemetry.update(now, downhole)
        return [*held, min(self._telemetry.age(now), 100.0) / 10.0]

    def _finish(self, extras: list[float]) -> np.ndarray:
        """The history then ``extras``, NaN as 0, clipped to the observation bound."""
        obs = self._obs
        obs[obs.shape[0] - len(extras):] = _bounded(extras)
        return obs.copy()


def _bounded(values: list[float]) -> list[float]:
    """NaN -> 0, +-inf and beyond -> +-OBS_BOUND, in float64 (rounded to float32 when
    stored): what np.clip(np.nan_to_num(...)) gives, at a fraction of its per-call cost."""
    bound = OBS_BOUND
    return [0.0 if v != v else bound if v > bound else -bound if v < -bound else v
            for v in values]
