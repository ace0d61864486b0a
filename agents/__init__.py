"""Controllers for the drill-string envs: one interface for classical and learned ones
(:mod:`agents.base`), a registry by name (:mod:`agents.registry`), the benchmark that
compares them (:mod:`agents.benchmark`, over :mod:`agents.settings`, :mod:`agents.episode`
and :mod:`agents.tables`), the trivial policies a learned one must beat
(:mod:`agents.trivial`)."""

import drill_env  # noqa: F401, I001  (first: sets OMP_WAIT_POLICY before torch loads OpenMP)
from agents.base import Controller, SetPointController
from agents.classical import ConstantSetPoints, SoftSpeed, SoftTorque, StiffPI, ZTorque
from agents.driller import Driller, DrillerRules
from agents.registry import (
    CLASSICAL,
    CONTROLLERS,
    TRIVIAL,
    make_controller,
    parse_controllers,
)
from agents.trivial import HeldAction, RandomActions

__all__ = ["CLASSICAL", "CONTROLLERS", "TRIVIAL", "ConstantSetPoints", "Controller",
           "Driller", "DrillerRules", "HeldAction", "RandomActions", "SetPointController",
           "SoftSpeed", "SoftTorque", "StiffPI", "ZTorque", "make_controller",
           "parse_controllers"]
