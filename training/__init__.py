"""Training scripts for DrillString-v0 (Stable-Baselines3)."""
