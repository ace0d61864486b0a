"""The trivial policies a learned one must beat: actions held at a value, and random
actions.

They act on the env's own action space (the ``[-1, 1]`` box of every env here), not
through set points: in ``DrillString-v0`` they command rpm and WOB, in task 1 the speed
correction, in task 2 the driller's rpm and WOB. They are the baselines of
``scripts/fresh_seeds.py`` and docs/tasks.md ("held at -1 / 0 / +1", "random"), here as
controllers, so that ``drill-env evaluate`` and ``benchmark --task`` measure them beside
a trained policy on the same held-out episodes.
"""

from __future__ import annotations

import math
import re
from typing import Any, ClassVar

import numpy as np

from agents.base import Rate

#: A held action's table name: ``held`` and each action's value with its sign.
HELD_LABEL = re.compile(r"held((?:[+-](?:\d+(?:\.\d*)?|\.\d+)(?:e[+-]?\d+)?)+)")
_SIGNED = re.compile(r"[+-](?:\d+(?:\.\d*)?|\.\d+)(?:e[+-]?\d+)?")


class _ActionSpacePolicy:
    """What both share: a policy of any env (``env_id`` is the plain env, so the
    benchmark lets it act in a task's env too, as the set-point controllers do)."""

    name: ClassVar[str]
    rate: ClassVar[Rate] = "policy"
    env_id: ClassVar[str] = "DrillString-v0"
    data_files: ClassVar[tuple[str, ...]] = ()

    def __init__(self) -> None:
        self._env: Any = None
        #: Whether it chooses the rpm (marked in the benchmark's table): everywhere but
        #: task 1, whose action corrects the top drive around the driller's target.
        self.sets_own_speed = True

    def physics(self) -> dict[str, Any]:
        return {}

    def reset(self, env: Any) -> None:
        from drill_env.tasks.stick_slip import StickSlipEnv

        self._env = env
        self.sets_own_speed = not isinstance(env, StickSlipEnv)


class HeldAction(_ActionSpacePolicy):
    """Every action held at a value for the whole episode. Registry name
    ``held:<a>`` (every action at ``a``) or ``held:<a1>/<a2>`` (one value per action),
    each in [-1, 1]: ``held:1``, ``held:-1``, ``held:0``, ``held:1/-1``."""

    name = "held"

    def __init__(self, values: tuple[float, ...]) -> None:
        super().__init__()
        if not values or not all(math.isfinite(v) and -1.0 <= v <= 1.0 for v in values):
            raise ValueError(f"controller: held:{'/'.join(f'{v:g}' for v in values)}: "
                             "each value must be in [-1, 1] (the env's action box)")
        self.values = values
        self._action = np.zeros(0, dtype=np.float32)

    @classmethod
    def parse(cls, text: str) -> HeldAction:
        """``"1"`` -> every action at 1; ``"1/-0.5"`` -> one value per action."""
        try:
            values = tuple(float(v) for v in text.split("/"))
        except ValueError:
            raise ValueError(f"controller: held:<a>[/<a2>] expected (values in [-1, 1]), "
                             f"got 'held:{text}'") from None
        return cls(values)

    @staticmethod
    def label(text: str) -> str:
        """The table name of ``held:<text>``: ``held:1/-0.5`` -> ``held+1-0.5``; as typed
        (``held-<text>``) where the values do not parse."""
        try:
            return "held" + "".join(f"{float(v):+.15g}" for v in text.split("/"))
        except ValueError:
            return f"held-{text}"

    @staticmethod
    def from_label(name: str) -> str | None:
        """``held+1-0.5`` -> ``held:1/-0.5`` (the registry's form); None for other names."""
        match = HELD_LABEL.fullmatch(name)
        if match is None:
            return None
        return "held:" + "/".join(f"{float(v):.15g}" for v in _SIGNED.findall(match[1]))

    def reset(self, env: Any) -> None:
        """Start an episode; one value per action, or one for all of them."""
        super().reset(env)
        shape = env.action_space.shape
        size = int(np.prod(shape))
        if len(self.values) not in (1, size):
            raise ValueError(f"controller: held:{'/'.join(f'{v:g}' for v in self.values)}: "
                             f"{len(self.values)} values for an action of {size}; give one "
                             f"or {size}")
        self._action = np.broadcast_to(np.asarray(self.values, dtype=np.float32),
                                       shape).copy()

    def act(self, observation: Any, info: dict[str, Any]) -> np.ndarray:
        return self._action


class RandomActions(_ActionSpacePolicy):
    """Uniform random actions in [-1, 1], a new draw every control step, from a generator
    seeded by the episode's seed (``reset(seed=...)``): an episode repeats, and the draws
    are those of ``scripts/fresh_seeds.py``'s random baseline. Registry name
    ``random``."""

    name = "random"

    def __init__(self) -> None:
        super().__init__()
        self._rng = np.random.default_rng()
        self._shape: tuple[int, ...] = ()

    def reset(self, env: Any) -> None:
        super().reset(env)
        seed = getattr(env, "np_random_seed", None)
        # an episode reset without a seed has none to repeat: fresh entropy
        self._rng = np.random.default_rng(seed if isinstance(seed, int) and seed >= 0
                                          else None)
        self._shape = env.action_space.shape

    def act(self, observation: Any, info: dict[str, Any]) -> np.ndarray:
        return self._rng.uniform(-1, 1, self._shape).astype(np.float32)
