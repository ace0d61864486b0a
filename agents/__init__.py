"""Controllers for DrillString-v0: one interface for classical and learned policies."""

from agents.policies import ConstantSetpoint, Policy, SB3Policy
from agents.top_drive import soft_speed_gains, stiff_gains

__all__ = ["ConstantSetpoint", "Policy", "SB3Policy", "soft_speed_gains", "stiff_gains"]
