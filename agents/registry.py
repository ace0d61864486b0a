"""Controllers by name: what ``drill-env run --controller`` and ``benchmark`` accept."""

from __future__ import annotations

import re
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


_CONSTANT_LABEL = re.compile(r"constant-(.+)rpm-(.+)kN")


def canonical(name: str) -> str:
    """``name`` as the registry takes it: a table's name of constant set points
    (``constant-120rpm-100kN``, :func:`agents.benchmark.label`) is ``constant:120/100``,
    so a row of ``benchmark.csv`` can be run again by its name; other names as given.
    A trained run's table name (``learned-<folder>``) cannot say where its folder is: it
    is refused with the form to give."""
    match = _CONSTANT_LABEL.fullmatch(name)
    if match:
        return f"constant:{match[1]}/{match[2]}"
    if name.startswith("learned-"):
        raise ValueError(f"controller: {name!r} is a trained run's name in a benchmark "
                         "table; give it as learned:<run folder>")
    return name


def make_controller(name: str, **kwargs: Any) -> Controller:
    """The controller called ``name`` (``CONTROLLERS``); unknown names are named.

    ``learned:PATH`` loads the policy of a training run folder (``logs/runs/<name>``);
    plain ``learned`` the shipped policy (of ``env_id``'s task if given);
    ``constant:<rpm>/<kN>`` (or its table name, :func:`canonical`) holds those set
    points."""
    name = canonical(name)
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
    """``"stiff,z-torque"`` -> the names, each checked (table names of constant set
    points as :func:`canonical` gives them)."""
    try:
        names = [canonical(n.strip()) for n in text.split(",") if n.strip()]
    except ValueError as err:
        raise ValueError(f"controllers: {str(err).partition(': ')[2]}") from None
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
