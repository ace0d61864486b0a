"""The controller interface shared by classical and learned controllers.

A controller has two parts, either of which may be trivial:

* a **drive-rate** part, ``physics``: dotted overrides of the simulator config that
  select what the top drive runs at every time step inside the compiled step (the
  stiff, SoftSpeed, SoftTorque and ZTorque loops of :mod:`drill_env.physics.top_drive`,
  whose gains follow from the configured string);
* a **policy-rate** part, ``act``: the action it sends the env every control interval
  (10 Hz by default), from the observation and ``info``.

``env_id`` is the env the controller acts in (its observation and action spaces); the
benchmark builds that env for every controller from the same scenario, seed and targets.
"""

from __future__ import annotations

from typing import Any, ClassVar, Literal, Protocol, runtime_checkable

import numpy as np

Rate = Literal["drive", "policy"]


@runtime_checkable
class Controller(Protocol):
    """What the benchmark, ``drill-env run`` and the tasks drive."""

    @property
    def name(self) -> str:
        """Registry name (``stiff``, ``soft-speed``, ...)."""
        ...

    @property
    def rate(self) -> Rate:
        """"drive": acts inside the compiled step at every time step; "policy": acts at
        the env's control interval."""
        ...

    @property
    def env_id(self) -> str:
        """The gymnasium id of the env it acts in."""
        ...

    def physics(self) -> dict[str, Any]:
        """Dotted ``SimulationConfig`` overrides of its drive-rate part (may be empty)."""
        ...

    def reset(self, env: Any) -> None:
        """Start an episode; ``env`` is the unwrapped env (targets, action mapping)."""
        ...

    def act(self, observation: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        """The action for this control interval."""
        ...


class SetPointController:
    """Asks for the driller's set points of the episode (``env.targets``: the scenario's,
    the reset options', or a task's drawn targets) through ``env.action_for``; subclasses
    pick the top drive's drive-rate loop."""

    name: ClassVar[str] = "set-point"
    rate: ClassVar[Rate] = "drive"
    env_id: ClassVar[str] = "DrillString-v0"
    #: Files a controller of your own reads (a model, its statistics): the benchmark reuses
    #: its stored rows only while these bytes, and the controller's source file, are the
    #: same (paths as given, from where the benchmark runs).
    data_files: ClassVar[tuple[str, ...]] = ()

    def __init__(self) -> None:
        self._env: Any = None

    def physics(self) -> dict[str, Any]:
        return {}

    def tuning(self, config: Any) -> Any:
        """The top drive's loop this controller runs on ``config``'s string (a
        ``SimulationConfig``): its gains and filters after :meth:`physics`, as a
        :class:`~drill_env.physics.top_drive.TopDriveLaw` (``reflection_coefficient(f)``,
        ``impedance_at(f)``), yours as the built-in ones."""
        from drill_env.physics.config import flatten, replace
        from drill_env.physics.top_drive import resolve

        return resolve(replace(config, **flatten(self.physics())))  # (nested as dotted)

    def reset(self, env: Any) -> None:
        """Start an episode in ``env``, unwrapped here if ``gym.make`` wrapped it (the
        wrapper has no ``action_for`` nor ``targets``: an AttributeError at the first act)."""
        self._env = getattr(env, "unwrapped", env)

    def act(self, observation: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        # the targets may change during an episode (the control tasks' driller does)
        return self._env.action_for(*self._env.targets)
