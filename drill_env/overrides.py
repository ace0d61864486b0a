"""A scenario's physics config with a user's overrides (``physics=`` of an env, ``--config``
of a command): the bit kept at the bottom of its string, the layers and the survey moved
with the string's length, a randomised scenario's layers turned to cross a curved hole as
drawn."""

from __future__ import annotations

import dataclasses
import re
import warnings
from collections.abc import Mapping
from typing import Any

import numpy as np

from drill_env.physics.config import ConfigError, SimulationConfig, StringConfig, replace
from drill_env.physics.formation import across_the_hole
from drill_env.physics.trajectory import (
    Survey,
    Trajectory,
    bit_depth,
    check_survey_holds,
    draws_hang_freely,
)

__all__ = ["MAX_LEAD", "drawn_with_physics", "kept_value_said", "sets_section",
           "warn_lists_rebuilt", "with_physics"]


def with_physics(config: SimulationConfig, overrides: Mapping[str, Any],
                 drawn: bool = False) -> SimulationConfig:
    """A scenario's ``config`` with dotted physics ``overrides`` (a user's ``physics=`` or
    ``--config``), its bit kept at the bottom of its string. ``drawn``: its layers were
    drawn as they cross the hole (a randomised scenario's, 0-60 deg): in a curved well
    the overrides set, they cross it so at the bit
    (:func:`~drill_env.physics.formation.across_the_hole`; as true dips some ran
    parallel to a 75 deg hole and were refused).

    A scenario puts the bit face at the bottom of its string (``initial_depth``, a lead
    above it in the crossing cases), its rock layers where they are relative to the bit
    and its well's survey to below the bit. When the overrides change the string's length,
    the bit depth and the layer interfaces move by the same amount, as ``string_length=``
    would have placed them, and a longer string's survey is extended by it (its last
    station: the preset wells end in a hold), unless the overrides set ``initial_depth``,
    the interfaces or the well. Components (``string.components``) replace the scenario's
    one-section BHA and its stabilizers unless the overrides set those as well. A list of
    sections given whole is built from the class's defaults; a warning names what that
    changed against the scenario's entries (:func:`warn_lists_rebuilt`). An error of a
    field the overrides do not set says it is the scenario's (:func:`kept_value_said`).
    """
    try:
        return _with_physics(config, overrides, drawn)
    except ConfigError as err:
        said = kept_value_said(str(err), overrides)
        if said is None:
            raise
        raise ConfigError(said) from None


def _with_physics(config: SimulationConfig, overrides: Mapping[str, Any],
                  drawn: bool) -> SimulationConfig:
    """:func:`with_physics` but its errors' words."""
    if not drawn:
        return warn_lists_rebuilt(config, _overridden(config, overrides), overrides)
    with draws_hang_freely():  # said for the range's longest string (drawn_with_physics)
        changed = warn_lists_rebuilt(config, _overridden(config, overrides), overrides)
        if changed.well.vertical or _sets_layers(overrides):  # the user's: true dips
            return changed
        well = changed.well
        survey = Survey.from_stations(well.md, well.inclination, well.azimuth, warn=False)
        _, tangent, _ = Trajectory(survey).at(np.array([bit_depth(changed)]))
        return replace(changed, formation=across_the_hole(changed.formation, tangent[0]))


def drawn_with_physics(name: str, params: Mapping[str, Any], overrides: Mapping[str, Any],
                       length: float | None = None, narrow: str = "string_length_range"
                       ) -> SimulationConfig:
    """The randomised ``name`` drawn (rng 0) with ``params`` at string ``length`` (None:
    the longest its range draws), with the ``overrides``; a survey ending above the
    string is said with the range, and ``narrow`` (what narrows it; "": nothing)."""
    from drill_env.scenarios import make_scenario, string_length_range  # (it imports
    # this module)

    low, high = string_length_range(name, params)
    draw = make_scenario(name, np.random.default_rng(0), **{
        **params, "string_length_range": (high, high) if length is None else (length, length)})
    try:
        config = with_physics(draw.config, overrides, drawn=True)
    except ValueError as err:
        if "the survey ends at" not in str(err):
            raise
        raise ValueError(f"physics: {err}: the {name} scenario draws strings of {low:g}-"
                         f"{high:g} m" + (f" ({narrow}); extend the survey or narrow the range"
                                          if narrow else "; extend the survey")) from None
    if (length is None or length >= high) and not config.well.vertical:
        check_survey_holds(config)  # the longest string above the bend: said
    return config


def warn_lists_rebuilt(config: SimulationConfig, changed: SimulationConfig,
                       overrides: Mapping[str, Any]) -> SimulationConfig:
    """``changed``, after a warning for each list of sections the ``overrides`` give whole
    (a YAML's ``formation: {rocks: [{mu_min: 0.5}]}``) whose entry left out fields that
    then differ from the scenario's entry at the same index: pydantic builds the entry
    from the class's defaults, so the paper rock's depth of cut halved and its founder
    point went, and the ROP with them, without a word (a new user's trial). Entries of
    another kind (a stabilizer where the scenario has a collar) are a new string's and are
    not compared, nor a label (``name``). The dotted key ``formation.rocks[0].mu_min``
    changes one field."""
    for key, value in overrides.items():
        if not (isinstance(value, (list, tuple)) and any(isinstance(v, Mapping) for v in value)):
            continue
        old, new = _field_at(config, key), _field_at(changed, key)
        if not (isinstance(old, tuple) and isinstance(new, tuple)):
            continue
        for i, (given, before, after) in enumerate(zip(value, old, new, strict=False)):
            if not (isinstance(given, Mapping) and dataclasses.is_dataclass(before)
                    and type(before) is type(after)
                    and getattr(before, "kind", None) == getattr(after, "kind", None)):
                continue
            lost = [f"{f.name} {_shown(getattr(after, f.name))} (the scenario's "
                    f"{_shown(getattr(before, f.name))})" for f in dataclasses.fields(before)
                    if f.name not in given and f.name != "name"  # (a label)
                    and _differs(getattr(before, f.name), getattr(after, f.name))]
            if lost:
                warnings.warn(f"{key}[{i}]: a list given whole builds its entries from "
                              f"{type(after).__name__}'s defaults, not from the scenario's: "
                              f"{', '.join(lost)}; to change a field of the scenario's entry "
                              "alone, set it by index: "
                              f"{', '.join(f'{key}[{i}].{name}' for name in given) or key}",
                              stacklevel=3)
    return changed


def kept_value_said(error: str, overrides: Mapping[str, Any]) -> str | None:
    """``error`` (a ConfigError's words, led by a dotted field) with a note that the
    field is the scenario's, kept by the ``overrides`` that clash with it; None where the
    overrides set that field (or a section or list holding it) themselves. A smaller
    hole named the default string's stabilizer, ``string.components[1].contact_diameter``,
    which the user had not typed (a new user's trial)."""
    field, colon, _ = error.partition(": ")
    if not (colon and re.fullmatch(r"[A-Za-z_][\w.\[\]]*", field) and overrides):
        return None
    for key in overrides:
        if key == field or field.startswith((f"{key}.", f"{key}[")) \
                or key.startswith((f"{field}.", f"{field}[")):
            return None
    return (f"{error} (the scenario's {field}, which the overrides keep: give it as well, "
            "or change what clashes with it)")


def _field_at(config: Any, key: str) -> Any:
    """The value of ``config`` at the dotted ``key`` (None where it names no field or
    goes through an index)."""
    value = config
    for name in key.split("."):
        value = getattr(value, name, None)
    return value


def _differs(a: Any, b: Any) -> bool:
    try:
        return bool(a != b)
    except ValueError:  # arrays
        return not np.array_equal(a, b)


def _shown(value: Any) -> str:
    return f"{value:g}" if isinstance(value, float) else repr(value)


def sets_section(keys: Any, section: str) -> bool:
    """Whether the dotted override ``keys`` set the config ``section`` ("well"), whole
    or a field of it."""
    return any(key == section or key.startswith(f"{section}.") for key in keys)


def _sets_layers(keys: Any) -> bool:
    """Whether the override ``keys`` set the formation's interfaces (the whole formation
    or its ``interfaces``)."""
    return any(key == "formation" or key.startswith("formation.interfaces") for key in keys)


def _overridden(config: SimulationConfig, overrides: Mapping[str, Any]) -> SimulationConfig:
    """:func:`with_physics` but the layers' turn."""
    if not overrides:
        return config
    components = overrides.get("string.components")  # (a NumPy array: no truth value)
    if components is not None and (not hasattr(components, "__len__") or len(components)):
        # components replace the scenario's one-section BHA and the stabilizers placed on
        # it (the crossing cases' 120 m of collars): they would clash with the components
        blank = StringConfig()
        overrides = {"string.bha": blank.bha, "string.stabilizers": blank.stabilizers,
                     **overrides}
    given = tuple(overrides)
    sets_well = sets_section(given, "well")
    # the new string's length, before a survey (the scenario's, which may now be short,
    # or the overrides', which may end above the scenario's bit) is checked
    probe = config if config.well.vertical else replace(config, well={})
    changed = replace(probe, **{key: value for key, value in overrides.items()
                                if not sets_section((key,), "well")})
    shift = changed.string.length - config.string.length
    if probe is config and not sets_well and (shift == 0.0 or "initial_depth" in given):
        # nothing to move (the usual case, as at every random reset)
        return _bit_at_string_end(changed, given)
    moved: dict[str, Any] = {}
    if shift != 0.0 and "initial_depth" not in given:
        if config.initial_depth is not None:
            moved["initial_depth"] = config.initial_depth + shift
        if not _sets_layers(given):
            moved["formation.interfaces"] = tuple(
                replace(i, depth=i.depth + shift) for i in config.formation.interfaces)
        if not (config.well.vertical or sets_well):
            moved["well.md"] = (*config.well.md[:-1], config.well.md[-1] + max(shift, 0.0))
    return _bit_at_string_end(replace(config, **{**moved, **overrides}), given)


#: How far above its string's end a bit depth given by hand may lie (m): a crossing
#: case's lead (``Lead``) at most.
MAX_LEAD = 100.0


def _bit_at_string_end(config: SimulationConfig, given: tuple[str, ...]) -> SimulationConfig:
    """``config``; a ValueError naming ``initial_depth`` where the overrides set one that
    leaves more than :data:`MAX_LEAD` m of the string above the wellhead (a 2,000 m string
    at ``initial_depth: 1500`` ran, its rocks taken at 1,500 m and its wall loads at
    2,000 m: a new user's walkthrough)."""
    if "initial_depth" in given and config.initial_depth is not None:
        above = config.string.length - config.initial_depth
        if above > MAX_LEAD:
            raise ValueError(f"initial_depth: {config.initial_depth:g} m leaves {above:g} m of "
                             f"the {config.string.length:g} m string above the wellhead: the "
                             "bit hangs at its bottom (leave initial_depth out, or give a depth "
                             f"within {MAX_LEAD:g} m of the string's length)")
        if above < -DEPTH_TOLERANCE:  # (1e5 m on a 1,250 m string ran: depth 100 km)
            raise ValueError(f"initial_depth: {config.initial_depth:g} m is below the end of "
                             f"the {config.string.length:g} m string that hangs from the top "
                             "drive (leave initial_depth out, or lengthen the string: "
                             "string.drill_pipe.length)")
    return config


#: How far below its string's end a bit depth given by hand may lie (m): round-off.
DEPTH_TOLERANCE = 1e-3


def physics_overrides(physics: Any) -> dict[str, Any]:
    """The dotted overrides of an env's ``physics=``, a dict of nested config sections or
    dotted paths (``{"mud": {"density": 1300}}`` or ``{"mud.density": 1300}``; None: {});
    a ValueError for anything else, one naming the reader of a YAML file for a path (a
    new user's trial passed one as ``--config`` takes it)."""
    import os

    from drill_env.physics.config import flatten

    if isinstance(physics, str | os.PathLike):
        raise ValueError(f"physics: expected a dict of overrides, got the path {physics!r}; "
                         "a YAML file of config sections: physics=read_yaml(path) "
                         "(drill_env.physics.validation.read_yaml, the --config reader)")
    if physics is not None and not isinstance(physics, dict):
        raise ValueError(f"physics: expected a dict of overrides, got {type(physics).__name__}")
    return flatten(physics or {})
