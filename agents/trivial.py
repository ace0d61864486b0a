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

#: One signed value of a held action's table name (``+1``, ``-0.5``, ``+1e-05``).
_SIGNED = r"[+-](?:\d+(?:\.\d*)?|\.\d+)(?:e[+-]?\d+)?"
#: A held action's table name: ``held`` and each action's value with its sign.
HELD_LABEL = re.compile(rf"held((?:{_SIGNED})+)")


class _ActionSpacePolicy:
    """What both share: a policy of any env (``env_id`` is the plain env, so the
    benchmark lets it act in a task's env too, as the set-point controllers do). Whether
    it chooses its own rpm is the benchmark's to say (``agents.tables.sets_own_speed``:
    not in task 1, whose action corrects the speed around the driller's target)."""

    name: ClassVar[str]
    rate: ClassVar[Rate] = "policy"
    env_id: ClassVar[str] = "DrillString-v0"
    data_files: ClassVar[tuple[str, ...]] = ()

    def physics(self) -> dict[str, Any]:
        return {}


def _plain(value: float) -> str:
    """A held value as its table name writes it: signed, 15 digits, -0 as +0."""
    return f"{value + 0.0:+.15g}"


class HeldAction(_ActionSpacePolicy):
    """Every action held at a value for the whole episode. Registry name
    ``held:<a>`` (every action at ``a``) or ``held:<a1>/<a2>`` (one value per action),
    each in [-1, 1]: ``held:1``, ``held:-1``, ``held:0``, ``held:1/-1``."""

    name = "held"

    def __init__(self, values: tuple[float, ...]) -> None:
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
            return "held" + "".join(_plain(float(v)) for v in text.split("/"))
        except ValueError:
            return f"held-{text}"

    @staticmethod
    def from_label(name: str) -> str | None:
        """``held+1-0.5`` -> ``held:1/-0.5`` (the registry's form); None for other names."""
        match = HELD_LABEL.fullmatch(name)
        if match is None:
            return None
        return "held:" + "/".join(_plain(float(v)).lstrip("+")
                                  for v in re.findall(_SIGNED, match[1]))

    def check_size(self, size: int) -> None:
        """ValueError unless the values fit an action of ``size`` entries (one value for
        all, or one each)."""
        if len(self.values) not in (1, size):
            typed = "/".join(f"{v:g}" for v in self.values)
            give = "one value" if size == 1 else f"one value or {size}"
            raise ValueError(f"controller: held:{typed}: {len(self.values)} values for an "
                             f"action of {size}; give {give}")

    def reset(self, env: Any) -> None:
        """Start an episode; one value per action, or one for all of them."""
        shape = env.action_space.shape
        self.check_size(int(np.prod(shape)))
        self._action = np.broadcast_to(np.asarray(self.values, dtype=np.float32),
                                       shape).copy()

    def act(self, observation: Any, info: dict[str, Any]) -> np.ndarray:
        return self._action


class RandomActions(_ActionSpacePolicy):
    """Uniform random actions in [-1, 1], a new draw every control step. An episode reset
    with a seed draws from a stream of that seed, so it repeats, and the same for every
    use (the benchmark, ``scripts/fresh_seeds.py``); the stream is a child of the seed's
    (``SeedSequence(seed).spawn``), not the env's own (``default_rng(seed)``), whose draws
    set the episode's targets and rocks. Episodes reset without a seed draw on from the
    last stream. Registry name ``random``."""

    name = "random"

    def __init__(self) -> None:
        self._rng = np.random.default_rng()
        self._env_rng: Any = None  # the env's generator the stream was seeded for
        self._shape: tuple[int, ...] = ()

    def reset(self, env: Any) -> None:
        generator = env.np_random  # a reset with a seed makes a new one
        if generator is not self._env_rng:
            self._env_rng = generator
            seed = env.np_random_seed
            entropy = np.random.SeedSequence(seed) if seed >= 0 else np.random.SeedSequence()
            self._rng = np.random.default_rng(entropy.spawn(1)[0])
        self._shape = env.action_space.shape

    def act(self, observation: Any, info: dict[str, Any]) -> np.ndarray:
        return self._rng.uniform(-1, 1, self._shape).astype(np.float32)
