"""Training scripts for DrillString-v0 (Stable-Baselines3)."""

import drill_env  # noqa: F401  (first: sets OMP_WAIT_POLICY before torch loads OpenMP)
