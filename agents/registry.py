"""Controllers by name: what ``drill-env run --controller`` and ``benchmark`` accept."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from agents.base import Controller
from agents.classical import ConstantSetPoints, SoftSpeed, SoftTorque, StiffPI, ZTorque
from agents.driller import Driller


def _learned(**kwargs: Any) -> Controller:
    from agents.learned import LearnedController

    return LearnedController.load(**kwargs)


#: name -> factory. ``learned`` loads a trained policy (the shipped one by default).
CONTROLLERS: dict[str, Callable[..., Controller]] = {
    StiffPI.name: StiffPI,
    SoftSpeed.name: SoftSpeed,
    SoftTorque.name: SoftTorque,
    ZTorque.name: ZTorque,
    Driller.name: Driller,
    "learned": _learned,
}
#: The controllers that need no trained policy.
CLASSICAL = tuple(name for name in CONTROLLERS if name != "learned")


#: What an unknown name's error lists: the registry's names and the parametrised forms.
KNOWN = f"{', '.join(CONTROLLERS)}, learned:<run folder>, constant:<rpm>/<kN>"


def make_controller(name: str, **kwargs: Any) -> Controller:
    """The controller called ``name`` (``CONTROLLERS``); unknown names are named.

    ``learned:PATH`` loads the policy of a training run folder (``logs/runs/<name>``);
    plain ``learned`` the shipped policy (of ``env_id``'s task if given);
    ``constant:<rpm>/<kN>`` holds those set points."""
    if name.startswith("learned:"):
        return _learned(path=name.partition(":")[2], **kwargs)
    if name.startswith("constant:"):
        return ConstantSetPoints.parse(name.partition(":")[2])
    if name != "learned":
        kwargs.pop("env_id", None)  # only the learned controller depends on the task
    try:
        factory = CONTROLLERS[name]
    except KeyError:
        raise ValueError(f"controller: unknown name {name!r}; known: "
                         f"{KNOWN}") from None
    return factory(**kwargs)


def parse_controllers(text: str) -> list[str]:
    """``"stiff,z-torque"`` -> the names, each checked."""
    names = [n.strip() for n in text.split(",") if n.strip()]
    if not names:
        raise ValueError("controllers: give at least one name")
    for n in names:
        if n.startswith("constant:"):
            try:
                ConstantSetPoints.parse(n.partition(":")[2])  # checks the numbers
            except ValueError as err:
                raise ValueError(f"controllers: {str(err).partition(': ')[2]}") from None
        elif n.startswith("learned:"):
            from agents.learned import policy_files

            try:  # a missing folder or model, said before any episode runs
                policy_files(n.partition(":")[2])
            except (FileNotFoundError, ValueError) as err:
                raise ValueError(f"controllers: {err}") from None
        elif n not in CONTROLLERS:
            raise ValueError(f"controllers: unknown name {n!r}; known: "
                             f"{KNOWN}")
    return names
