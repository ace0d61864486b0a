"""The simulator's fidelity levels: "full", and "fast", which coarsens the drill pipe and
lengthens the step (``SimulationConfig.resolved``; docs/performance.md)."""

from __future__ import annotations

from typing import Literal, get_args

Fidelity = Literal["full", "fast"]
FIDELITY_LEVELS: tuple[str, ...] = get_args(Fidelity)
#: Fast level: 20 m drill-pipe elements keep the first torsional frequency of the
#: default string within 0.1 % (tests/physics/test_fidelity.py), the wave to ~10 Hz.
FAST_PIPE_ELEMENT_LENGTH = 20.0
#: Fast level step: at FAST_CRITICAL_STEP_FRACTION of the critical step (5.07 ms for a
#: gauge pad in hard rock on the bit node; docs/model.md section 5) the simulator takes
#: 3.3-4 ms on the random scenario (median 3.8). Not implicit contacts at 10 ms: at task
#: 2's high rpm they add a backward whirl the full model does not show (docs/performance.md).
FAST_TIME_STEP = 4.0e-3
#: 0.75 of the lumped-mass critical step (the full model takes 0.5): two gauge pads on a
#: wall lower the limit to 0.82 of it; at 0.8 10 of 1,000 random-action task-2 episodes
#: ran away, at 0.75 none of 2,000 (docs/tasks.md, "A rare numerical failure").
FAST_CRITICAL_STEP_FRACTION = 0.75
