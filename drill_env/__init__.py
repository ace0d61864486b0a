"""drill-env: a Gymnasium environment over a finite-element drill string with a PDC bit.

``import drill_env`` registers the environments (idempotently) and imports nothing heavy:
not torch, Stable-Baselines3 or rerun, and not even gymnasium until the program imports
it. The physics layer (``drill_env.physics``) never needs gymnasium at all, so the
registration runs when gymnasium is (or already was) imported (see
:func:`register_envs`).

=========================  =====================================================
id                         what it is
=========================  =====================================================
``DrillString-v0``         mesoscopic bit, downhole + surface sensors
``DrillStringMacro-v0``    macroscopic bit (eq. 38: torque only, no lateral bit)
``DrillStringSurface-v0``  surface measurements only (``sensors="surface"``)
``DrillStringRandom-v0``   randomised training scenario (``scenario="random"``)
=========================  =====================================================

All take the keywords of :class:`drill_env.env.DrillStringEnv`;
``gymnasium.make_vec(id, num_envs=N)`` builds :class:`drill_env.vector.DrillStringVectorEnv`.
"""

from __future__ import annotations

import importlib.abc
import importlib.util
import sys
from typing import Any

__version__ = "0.1.0"

ENTRY_POINT = "drill_env.env:DrillStringEnv"
VECTOR_ENTRY_POINT = "drill_env.vector:DrillStringVectorEnv"

#: Registered ids and their default keyword arguments.
ENV_IDS: dict[str, dict[str, Any]] = {
    "DrillString-v0": {},
    "DrillStringMacro-v0": {"bit_model": "macroscopic"},
    "DrillStringSurface-v0": {"sensors": "surface"},
    "DrillStringRandom-v0": {"scenario": "random"},
}


def register_envs() -> None:
    """Register every id of :data:`ENV_IDS` unless already registered (idempotent).

    Imports gymnasium. ``import drill_env`` calls it at once if gymnasium is already
    imported, or else right after the program first imports gymnasium.
    """
    import gymnasium

    for env_id, kwargs in ENV_IDS.items():
        if env_id not in gymnasium.registry:
            gymnasium.register(id=env_id, entry_point=ENTRY_POINT,
                               vector_entry_point=VECTOR_ENTRY_POINT, kwargs=dict(kwargs))


class _RegisterWhenGymnasiumLoads(importlib.abc.MetaPathFinder):
    """Import hook: lets gymnasium load as usual, then registers the envs, then leaves."""

    def find_spec(self, fullname: str, path: Any, target: Any = None) -> Any:
        if fullname != "gymnasium":
            return None
        if self in sys.meta_path:
            sys.meta_path.remove(self)
        spec = importlib.util.find_spec("gymnasium")
        if spec is None or spec.loader is None:
            return spec
        loader = spec.loader
        load = loader.exec_module

        def exec_module(module: Any) -> None:
            load(module)
            register_envs()

        loader.exec_module = exec_module  # type: ignore[method-assign]
        return spec


if "gymnasium" in sys.modules:
    register_envs()
elif not any(isinstance(f, _RegisterWhenGymnasiumLoads) for f in sys.meta_path):
    sys.meta_path.insert(0, _RegisterWhenGymnasiumLoads())
