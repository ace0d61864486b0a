"""``--config FILE``: a YAML file of physics overrides, read, merged into a scenario's
config and checked against the scenarios a command runs."""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from drill_cli.arguments import not_a_file


def read_overrides(path: Path | None) -> dict[str, Any]:
    """The config overrides of a YAML file of nested config sections (a string of
    components, a rock, the solver), as dotted paths; {} without a file."""
    if path is None:
        return {}
    from drill_env.physics.config import flatten
    from drill_env.physics.validation import read_yaml

    if not path.is_file():
        raise ValueError(f"--config {path}: "
                         + (not_a_file(path) if path.exists() else "no such file"))
    try:
        data = read_yaml(path)
    except ValueError as err:
        raise ValueError(f"--config {err}") from None
    if data is None:  # an empty file (or only comments): nothing to override, said
        warnings.warn(f"--config {path} holds no settings (empty, or only comments): the "
                      "defaults run", UserWarning, stacklevel=2)
        return {}
    if not isinstance(data, dict):
        raise ValueError(f"--config {path}: expected a mapping of config sections")
    from drill_env.env_config import ENV_FIELDS

    for key in data:  # what a command's options set, written into the file
        if key in NOT_PHYSICS:
            raise ValueError(f"--config {path}: {key}: not a config section; "
                             f"{NOT_PHYSICS[key]}")
        if key in ENV_FIELDS:  # (listed as an unknown field of SimulationConfig)
            raise ValueError(f"--config {path}: {key}: an env setting (EnvConfig), not the "
                             "simulator's config the file changes; the commands build their "
                             "env themselves (its length: --duration)")
    try:
        return flatten(data)
    except ValueError as err:  # a key that is no name (1: 2): said with the file
        raise ValueError(f"--config {path}: {err}") from None


#: Keys a --config file may be given that belong to a command's options instead.
NOT_PHYSICS = {
    "rpm": "the speed is an option of the command (drill-env run --rpm, in rpm)",
    "wob": "the weight on bit is an option of the command (drill-env run --wob, in kN)",
    "weight_on_bit": "the weight on bit is an option of the command (drill-env run --wob, "
                     "in kN)",
    "duration": "the episode's length is an option of the command (--duration, in s)",
    "episode_duration": "the episode's length is an option of the command (--duration, in s)",
    "seed": "the seed is an option of the command (--seed or --seeds)",
    "scenario": "the scenario is an option of the command (--scenario); the file changes "
                "its config",
    "controller": "the controller is an option of the command (--controller or "
                  "--controllers)",
}


def with_overrides(config, path: Path | None):
    """``config`` with the nested overrides of a YAML file merged in (dotted-path errors)."""
    return merged(config, read_overrides(path), path)


def merged(config, overrides: dict[str, Any], path: Path | None):
    """``config`` with the ``overrides`` read from ``path`` (the bit kept at the bottom of
    the string: :func:`~drill_env.scenarios.with_physics`); a bad field names the file."""
    from drill_env.scenarios import with_physics

    try:
        return with_physics(config, overrides)
    except ValueError as err:
        raise ValueError(f"--config {path}: {err}") from None


def checked_overrides(path: Path | None, scenarios: Sequence[str],
                      params: Mapping[str, Any] | None = None, narrow: str = "") -> dict[str, Any]:
    """:func:`read_overrides`, merged once into each scenario's config here, so that a
    bad field fails now, named by its dotted path, not in the first episode. A randomised
    scenario is checked on the longest string its ``params``' range draws (a survey must
    reach that one; it was an unseeded draw from the default range, so that a survey
    shorter than the default range's top failed at random whatever --string-lengths);
    ``narrow``: the option that narrows the range ("": the command has none)."""
    from drill_env.overrides import drawn_with_physics
    from drill_env.scenarios import RANDOMISED, make_scenario

    overrides = read_overrides(path)  # the file read once
    for name in scenarios if overrides else ():
        if name not in RANDOMISED:
            merged(make_scenario(name).config, overrides, path)
            continue
        try:
            drawn_with_physics(name, dict(params or {}), overrides, narrow=narrow)
        except ValueError as err:
            raise ValueError(f"--config {path}: {str(err).removeprefix('physics: ')}"
                             ) from None
    return overrides
