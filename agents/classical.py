"""Classical top-drive controllers: the drive-rate loops of the literature.

Each one holds the driller's set points and selects a top-drive controller that runs at
every simulator time step (``rate = "drive"``) inside the compiled step; its gains and
filters come from the configured string (drill-pipe impedance ``Z = J_p sqrt(G rho)``,
top-drive inertia ``J_td``, stick-slip frequency ``f_s`` = first torsional natural
frequency with a fixed top and a free bit) by :func:`drill_env.physics.top_drive.resolve`
when the simulator is built, so a scenario with another string retunes them.
:meth:`~agents.base.SetPointController.tuning` shows the numbers for a config.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

from agents.base import SetPointController
from drill_env.physics.units import RPM


class _DriveLoop(SetPointController):
    #: ``TopDriveConfig.controller`` value.
    top_drive: ClassVar[str]

    def physics(self) -> dict[str, Any]:
        return {"top_drive.controller": self.top_drive}


def drive_loop_name(top_drive: str) -> str:
    """The registry name (``soft-speed``) of the drive-rate controller whose
    ``TopDriveConfig.controller`` is ``top_drive`` (``soft_speed``)."""
    return next((c.name for c in _DriveLoop.__subclasses__() if c.top_drive == top_drive),
                top_drive)


class StiffPI(_DriveLoop):
    """Stiff PI speed loop, the usual factory tuning (Kyllingstad & Nessjoen 2009,
    SPE-119660): ``P = 50 Z``, ``I = 5 J_td`` (1/s^2). The top reflects ~96 % of the
    torsional waves: a fixed end, so stick-slip develops freely. Drive rate."""

    name = "stiff"
    top_drive = "stiff"


class SoftSpeed(_DriveLoop):
    """SoftSpeed / tuned PI (Kyllingstad & Nessjoen 2009, SPE-119660): ``P = k Z`` so the
    top absorbs the waves coming up the string, ``I = (2 pi f_s)^2 J_td`` so the integral
    term cancels the top-drive inertia at the stick-slip frequency; k = 4
    (``TopDriveConfig.impedance_factor``: reflection (k-1)/(k+1) = 0.6 at f_s, but an
    absorbing band wide enough for the modes the soft top creates; at k = 1.5-2.5 stick-slip
    grew back within 1-3 minutes, at k = 3 at 150 kN, at k = 5-6 as the loop stiffens;
    docs/controllers.md, "SoftSpeed's k"). Drive rate."""

    name = "soft-speed"
    top_drive = "soft_speed"


class SoftTorque(_DriveLoop):
    """SoftTorque (Shell's Soft Torque Rotary System, as Dwars 2015, SPE/IADC-173037,
    describes it): the stiff speed loop with its command lowered by the string torque
    through a band-pass at the stick-slip frequency and the gain 1/Z,
    ``w_cmd = w_set - BP(T_s) / Z``, ``BP(s) = 2 z w_s s / (s^2 + 2 z w_s s + w_s^2)``,
    z = 0.5: the top absorbs near f_s and stays stiff at DC. Drive rate."""

    name = "soft-torque"
    top_drive = "soft_torque"


class ZTorque(_DriveLoop):
    """ZTorque (Dwars 2015, SPE/IADC-173037): the stiff speed loop with the string torque
    high-pass filtered and fed back through 1/Z, ``w_cmd = w_set - HP(T_s) / Z``,
    ``HP(s) = s / (s + w_c)``, corner ``w_c = 2 pi f_s / 4``: above the corner the top
    is an impedance-matched absorber for the first and every higher mode. Drive rate."""

    name = "z-torque"
    top_drive = "z_torque"


class ConstantSetPoints(SetPointController):
    """Fixed rpm and WOB, whatever the episode's targets: a driller who never adjusts;
    with the best point of a grid search, the drilling task's constant baseline. The
    stiff top drive. Registry name ``constant:<rpm>/<kN>``, e.g. ``constant:120/100``."""

    name = "constant"
    rate = "policy"

    def __init__(self, rpm: float, weight_on_bit: float) -> None:
        super().__init__()
        if not (math.isfinite(rpm) and math.isfinite(weight_on_bit) and rpm >= 0.0
                and weight_on_bit >= 0.0):
            raise ValueError(f"constant: rpm and WOB must be finite and >= 0, got "
                             f"{rpm:g} rpm, {weight_on_bit / 1e3:g} kN")
        self.rpm = rpm  # as typed, for the range check
        self.speed = rpm * RPM
        self.weight_on_bit = weight_on_bit

    @classmethod
    def parse(cls, text: str) -> ConstantSetPoints:
        """``"120/100"`` -> 120 rpm, 100 kN."""
        try:
            rpm, kn = (float(v) for v in text.split("/"))
        except ValueError:
            raise ValueError(f"controller: constant:<rpm>/<kN> expected, got "
                             f"'constant:{text}'") from None
        return cls(rpm, kn * 1e3)

    def physics(self) -> dict[str, Any]:
        return {"top_drive.controller": "stiff"}

    def reset(self, env: Any) -> None:
        """Start an episode; a set point outside the env's action range is refused (the
        env would clip it, and the row would be named after a point it never drilled)."""
        super().reset(env)
        self.check_range(self._env.config)  # (unwrapped)

    def check_range(self, config: Any) -> None:
        """ValueError unless the set points lie in the action ranges of an env's
        ``config`` (an :class:`~drill_env.env_config.EnvConfig`)."""
        rpm, kn = self.rpm, self.weight_on_bit / 1e3
        w_low, w_high = (v / 1e3 for v in config.weight_on_bit_range)
        for value, (low, high), unit in ((rpm, config.rpm_range, "rpm"),
                                         (kn, (w_low, w_high), "kN")):
            if not low <= value <= high:
                raise ValueError(f"controller: constant:{rpm:g}/{kn:g}: {value:g} {unit} is "
                                 f"outside the env's range {low:g}-{high:g} {unit}")

    def act(self, observation: Any, info: dict[str, Any]) -> Any:
        return self._env.action_for(self.speed, self.weight_on_bit)
