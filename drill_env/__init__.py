"""drill-env: a Gymnasium environment over a finite-element drill string with a PDC bit.

``import drill_env`` registers the environments (idempotently) and imports nothing
heavier than gymnasium and numpy; torch, Stable-Baselines3 and rerun load only where used.

======================  =====================================================
id                      what it is
======================  =====================================================
``DrillString-v0``      mesoscopic bit, downhole + surface sensors
``DrillStringMacro-v0`` macroscopic bit (eq. 38: torque only, no lateral bit)
``DrillStringSurface-v0`` surface measurements only (``sensors="surface"``)
``DrillStringRandom-v0`` randomised training scenario (``scenario="random"``)
======================  =====================================================

All take the keywords of :class:`drill_env.env.DrillStringEnv`;
``gymnasium.make_vec(id, num_envs=N)`` builds :class:`drill_env.vector.DrillStringVectorEnv`.
"""

from __future__ import annotations

import gymnasium

__version__ = "0.1.0"

ENTRY_POINT = "drill_env.env:DrillStringEnv"
VECTOR_ENTRY_POINT = "drill_env.vector:DrillStringVectorEnv"

#: Registered ids and their default keyword arguments.
ENV_IDS: dict[str, dict] = {
    "DrillString-v0": {},
    "DrillStringMacro-v0": {"bit_model": "macroscopic"},
    "DrillStringSurface-v0": {"sensors": "surface"},
    "DrillStringRandom-v0": {"scenario": "random"},
}


def register_envs() -> None:
    """Register every id of :data:`ENV_IDS` unless already registered (idempotent)."""
    for env_id, kwargs in ENV_IDS.items():
        if env_id not in gymnasium.registry:
            gymnasium.register(id=env_id, entry_point=ENTRY_POINT,
                               vector_entry_point=VECTOR_ENTRY_POINT, kwargs=dict(kwargs))


register_envs()
