"""Typed, validated configuration dataclasses, with errors that name the dotted path.

Configs are frozen dataclasses checked by pydantic v2 (``pydantic.dataclasses``): every
field has a type (a bool only takes ``True``/``False``, a number no string, a nested
section its own dataclass or a dict that is converted) and a range, and no number may be
NaN or infinite. Checks between fields live in ``__post_init__`` and raise
``ValueError("field: message")``. Whatever fails, the user sees one :class:`ConfigError`
(a ``ValueError``) naming the path they typed: ``mud.density: Input should be less than
3000, got 9000.0``.

Why pydantic and not hand-written checks: it walks nested dicts and tuples, reports the
location of every error, and converts YAML/JSON-like data, which is what a config loader
needs; numba kernels never see these objects (the simulator copies them into arrays).
"""

from __future__ import annotations

import dataclasses
import difflib
import functools
import math
import re
import sys
import typing
import warnings
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Annotated, Any, TypeVar, dataclass_transform

import numpy as np
from pydantic import (
    AfterValidator,
    BeforeValidator,
    ConfigDict,
    Field,
    Strict,
    StrictBool,
    ValidationError,
    validate_call,
)
from pydantic.dataclasses import dataclass as pydantic_dataclass

__all__ = [
    "ConfigError", "Count", "Finite", "NonNegative", "Positive", "StrictBool", "config_dataclass",
    "flatten", "from_dict", "jsonable", "load_yaml", "replace", "require_finite",
    "require_non_negative", "require_positive", "validated",
]

T = TypeVar("T")


class ConfigError(ValueError):
    """A configuration value was rejected; the message names the dotted path of the field."""


# --------------------------------------------------------------------------- field types


def _real(value: Any) -> Any:
    """Numbers only: NumPy scalars become Python floats; bools and strings are refused."""
    if isinstance(value, (bool, np.bool_)):
        raise ValueError(f"must be a number, not a bool ({value!r})")
    if isinstance(value, (np.floating, np.integer)):
        return float(value)
    return value


def _integer(value: Any) -> Any:
    if isinstance(value, (bool, np.bool_)):
        raise ValueError(f"must be an integer, not a bool ({value!r})")
    if isinstance(value, np.integer):
        return int(value)
    return value


#: A finite real number (NaN and inf are refused by the config, see ``_CONFIG``).
Finite = Annotated[float, BeforeValidator(_real), Strict()]
Positive = Annotated[Finite, Field(gt=0.0)]
NonNegative = Annotated[Finite, Field(ge=0.0)]
#: An integer (NumPy integers accepted, bools and floats refused).
Count = Annotated[int, BeforeValidator(_integer), Strict()]

#: Densities (kg/m^3) that are a drilling mud typed in pounds per gallon: 5-25 ppg spans
#: light oil-based to the heaviest weighted muds. Air and mist at depth are this light too,
#: so it is a warning, not an error.
PPG_LIKE = (5.0, 25.0)


#: Densities (kg/m^3) that are a mud's specific gravity (g/cm^3) typed as kg/m^3: 0.5-3
#: spans foam to the heaviest muds (a new user's 1.5 ran the string in near vacuum); air
#: at the surface is as light, so a warning too.
SG_LIKE = (0.5, 3.0)


def _mud_density(value: float) -> float:
    if PPG_LIKE[0] <= value <= PPG_LIKE[1]:  # (said at the user's line, not pydantic's)
        warnings.warn(f"mud.density: {value:g} kg/m^3 is as light as air or mist; a mud "
                      f"of {value:g} ppg is {value * 119.826:,.0f} kg/m^3 (the density is "
                      "in kg/m^3)", UserWarning, stacklevel=caller_outside())
    elif SG_LIKE[0] <= value <= SG_LIKE[1]:
        warnings.warn(f"mud.density: {value:g} kg/m^3 is air's; a mud of specific gravity "
                      f"{value:g} is {value * 1e3:,.0f} kg/m^3 (the density is in kg/m^3; "
                      "drilling with air, leave it)", UserWarning, stacklevel=caller_outside())
    return value


#: Least continuous torque (N m) of a top drive: the smallest give ~10 kN m, so a rating
#: below this is one typed in kN m (a new user's 50 stalled the drive, which read as
#: stick-slip); a warning, as a model drive may be that small.
DRIVE_TORQUE_LIKE = 1.0e3


def _drive_torque(value: float) -> float:
    if value < DRIVE_TORQUE_LIKE:
        warnings.warn(f"top_drive.max_torque: {value:g} N m is no top drive's (they give "
                      f"10-100 kN m); typed in kN m? {value:g} kN m = {value * 1e3:,.0f} N m "
                      "(the torque is in N m)", UserWarning, stacklevel=caller_outside())
    return value


def caller_outside(packages: tuple[str, ...] = ("drill_env", "gymnasium", "pydantic")
                   ) -> int:
    """The ``stacklevel`` of the first frame, from the caller of the function that calls
    this, whose module is in none of ``packages``: the user's line (a warning given in an
    env's reset or ``gym.make`` pointed into gymnasium's registration.py, one given by a
    config's validation into pydantic's dataclass module)."""
    frame: Any = sys._getframe(2)
    level = 2
    while frame is not None and str(frame.f_globals.get("__name__", "")).split(".")[0] \
            in packages:
        frame, level = frame.f_back, level + 1
    return level


#: A fluid density (kg/m^3) that warns when it looks typed in ppg or as SG.
FluidDensity = Annotated[NonNegative, AfterValidator(_mud_density)]
#: A top drive's torque rating (N m) that warns when it looks typed in kN m.
DriveTorque = Annotated[Positive, AfterValidator(_drive_torque)]

_CONFIG = ConfigDict(extra="forbid", allow_inf_nan=False, revalidate_instances="never",
                     arbitrary_types_allowed=True)


# --------------------------------------------------------------------------- errors

_PATH_MESSAGE = re.compile(r"^([A-Za-z_][\w.\[\]]*): (.*)$", re.DOTALL)

#: The unit of a field by the end of its name, said with a bound it breaks: a diameter
#: typed in inches or millimetres breaks "less than 1" (m), which alone does not say why.
_UNITS = {"diameter": "metres; 5 in = 0.127 m", "length": "metres; 30 ft = 9.144 m",
          "depth": "metres; 1,000 ft = 304.8 m",
          "density": "kg/m^3; steel 7,850 kg/m^3, a 10 ppg mud 1,198 kg/m^3",
          "md": "metres; 1,000 ft = 304.8 m", "duration": "s; a year is 3.15e7 s"}


def _unit_hint(loc: list[Any], error_type: str) -> str:
    """`` (<unit>; an example)`` for a bound broken by a field whose unit :data:`_UNITS`
    knows."""
    if not error_type.startswith(("less_than", "greater_than")) or not loc:
        return ""
    name = next((str(p) for p in reversed(loc) if isinstance(p, str)), "")
    unit = next((u for end, u in _UNITS.items() if name == end or name.endswith("_" + end)),
                None)
    return f" ({unit})" if unit else ""


def short_repr(value: Any) -> str:
    """``repr(value)`` with long lists and texts cut (``[0.0, 0.0, ...]``): a list pasted
    into a number's field printed whole, and a YAML file of nested aliases made a line of
    megabytes (a fuzzing walkthrough)."""
    import reprlib

    cut = reprlib.Repr()
    cut.maxlist = cut.maxtuple = cut.maxdict = 8
    cut.maxstring = cut.maxother = 100
    return cut.repr(value)


def _format_location(parts: list[Any]) -> str:
    out = ""
    for part in parts:
        if isinstance(part, str) and part.startswith("[") and part.endswith("]"):
            out += part
        elif isinstance(part, int):
            out += f"[{part}]"
        else:
            out += ("." if out else "") + str(part)
    return out


def _section_at(root: Any, loc: list[Any]) -> Any:
    """The config dataclass at ``loc`` (field names and list indices) under ``root``, or
    None."""
    cls = root
    for part in loc:
        if isinstance(part, int):
            continue  # an element of a tuple of sections: its type was found already
        try:
            hint = typing.get_type_hints(cls).get(part)
        except (NameError, TypeError):
            return None
        cls = _dataclass_in(hint)
        if cls is None:
            return None
    return cls


def _dataclass_in(hint: Any) -> Any:
    if dataclasses.is_dataclass(hint):
        return hint
    return next((found for arg in typing.get_args(hint)
                 if (found := _dataclass_in(arg)) is not None), None)


def closest(name: str, names: list[str]) -> str | None:
    """The one of ``names`` a misspelt ``name`` was probably meant to be, if any: itself in
    another case, the closest by difflib, else the one it begins (``bench``: benchmark)."""
    begun = [n for n in names if n.lower().startswith(name.lower()) and len(name.strip("-")) > 2]
    close = [n for n in names if n.lower() == name.lower()] or difflib.get_close_matches(
        name, names, n=1, cutoff=0.75)
    return close[0] if close else begun[0] if len(begun) == 1 else None


def repeated(names: Sequence[str]) -> str | None:
    """The first name given a second time in ``names`` (None: each once)."""
    seen = list(names)  # (any iterable: a dict's keys; a review)
    return next((name for k, name in enumerate(seen) if name in seen[:k]), None)


def comma_items(text: str, field: str, what: str = "name") -> list[str]:
    """``"a, b"`` -> ``["a", "b"]``; ``ValueError`` naming ``field`` for an empty item
    between items (``"a,,b"``, ``"a,"``: one left out, not nothing). An empty or blank
    ``text`` gives ``[]``: the caller says what it needs."""
    items = [item.strip() for item in text.split(",")]
    if any(items) and not all(items):
        raise ValueError(f"{field}: an empty {what} in {text!r} (two commas, or one at an "
                         "end)")
    return [item for item in items if item]


def did_you_mean(name: str, names: list[str]) -> str:
    """`` (did you mean x?)`` with :func:`closest`, or "" when no name is close."""
    best = closest(name, names)
    return f" (did you mean {best}?)" if best else ""


def _error_text(err: ValidationError, prefix: str = "", root: Any = None) -> str:
    """One line per error: ``path: message, got value``; an unknown field of a section
    (``root``: the config class) comes first and lists the section's fields, with the
    one it was probably meant to be, whose own "Field required" is then left out."""
    unknown, lines = [], []
    meant: set[tuple[Any, ...]] = set()  # the fields misspelt ones probably were
    errors = err.errors(include_url=False)
    for e in errors:
        loc = [p for p in e["loc"] if p not in ("__post_init__",)]
        section = _section_at(root, loc[:-1]) if (
            root is not None and e["type"] == "unexpected_keyword_argument") else None
        if section is not None:
            known = [f.name for f in dataclasses.fields(section)]
            best = closest(str(loc[-1]), known)
            if best:
                meant.add((*loc[:-1], best))
            hint = f" (did you mean {best}?)" if best else ""
            path = ".".join(p for p in (prefix, _format_location(loc)) if p)
            unknown.append(f"{path}: unknown field of {section.__name__}{hint}; known: "
                           f"{', '.join(known)}")
            e["type"] = "handled"
    for e in errors:
        loc = [p for p in e["loc"] if p not in ("__post_init__",)]
        msg = str(e["msg"])
        if e["type"] == "handled" or (e["type"] == "missing" and tuple(loc) in meant):
            continue
        value_error = e["type"] in ("value_error", "assertion_error")
        if value_error:
            msg = msg.removeprefix("Value error, ").removeprefix("Assertion failed, ")
            match = _PATH_MESSAGE.match(msg)
            if match:  # "field: message" from a __post_init__ check
                loc += [p for p in re.split(r"\.|(?=\[)", match.group(1)) if p]
                msg = match.group(2)
        parts = [prefix] if prefix else []
        path = ".".join(p for p in (*parts, _format_location(loc)) if p) or "config"
        text = f"{path}: {msg}"
        if not value_error and "input" in e and not isinstance(e["input"], Mapping) and \
                type(e["input"]).__name__ != "ArgsKwargs":
            text += f", got {short_repr(e['input'])}" + _unit_hint(loc, e["type"])
            if e["type"] == "literal_error" and isinstance(e["input"], str):  # kind: colar
                text += did_you_mean(e["input"], [str(v) for v in re.findall(
                    r"'([^']*)'", str(e.get("ctx", {}).get("expected", "")))])
        if isinstance(e.get("input"), bool) and (
                e["type"] in ("literal_error", "string_type", "enum")
                or value_error and "must be one of" in msg):
            # a field that takes words (telemetry: no, bit_model: off): YAML 1.1's
            # booleans, as PyYAML reads them (a number's field: quoting would not help)
            text += " (an unquoted yes, no, on or off in YAML is a boolean: quote it)"
        lines.append(text)
    return "; ".join(unknown + lines)


def config_error(err: ValidationError, prefix: str = "", root: Any = None) -> ConfigError:
    return ConfigError(_error_text(err, prefix, root))


# --------------------------------------------------------------------------- decorators


@dataclass_transform(frozen_default=True, field_specifiers=(dataclasses.field, Field))
def config_dataclass(cls: type[T]) -> type[T]:
    """A frozen pydantic dataclass whose constructor raises :class:`ConfigError`."""
    built: Any = pydantic_dataclass(frozen=True, config=_CONFIG)(cls)
    init = built.__init__

    @functools.wraps(init)
    def __init__(self: Any, *args: Any, **kwargs: Any) -> None:
        try:
            init(self, *args, **kwargs)
        except ValidationError as err:
            raise config_error(err, root=built) from None

    built.__init__ = __init__
    return built


F = TypeVar("F", bound=Callable[..., Any])


def validated(func: F) -> F:
    """Check a function's arguments against its annotations (``pydantic.validate_call``);
    a bad argument raises :class:`ConfigError` naming it (``dip: ...``)."""
    checked = validate_call(config=ConfigDict(arbitrary_types_allowed=True,
                                              allow_inf_nan=False))(func)

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return checked(*args, **kwargs)
        except ValidationError as err:
            raise config_error(err) from None

    return wrapper  # type: ignore[return-value]


def check_newtons(name: str, values: tuple[float, ...]) -> None:
    """ValueError if a WOB (or a WOB range) in newtons is positive but below 1 kN: no
    string drills on that, and it is what a value typed in kN gives (``(70, 130)``)."""
    if 0.0 < max(values) < 1.0e3:
        shown = ", ".join(f"{v:g}" for v in values)
        meant = ", ".join(f"{v:g}e3" if v else "0" for v in values)
        if len(values) > 1:
            shown, meant = f"({shown})", f"({meant})"
            what = f"reaches only {max(values):g} N"
        else:
            what = "is below 1 kN"
        raise ValueError(f"{name}: {shown} N {what}; WOB is in newtons: did you mean "
                         f"{meant}?")


# --------------------------------------------------------------------------- loading


def from_dict(cls: type[T], data: Mapping[str, Any] | T | None) -> T:
    """Build the (nested) config ``cls`` from plain dicts, lists and numbers (or pass an
    instance through). Unknown keys and bad values raise :class:`ConfigError`."""
    if data is None:
        return cls()
    if isinstance(data, cls):
        return data
    if not isinstance(data, Mapping):
        raise ConfigError(f"{cls.__name__}: expected a mapping or a {cls.__name__}, got "
                          f"{type(data).__name__}")
    return cls(**dict(data))


def _config_loader() -> type:
    """PyYAML's safe loader with three changes for hand-written configs: numbers such as
    ``3e-4`` and ``2.1e11`` are floats (YAML 1.1 wants ``3.0e-4``, and PyYAML read them as
    strings: "not a number" errors and SB3 tracebacks), a key written twice in one
    mapping is refused (the last one silently won), and so is a base-60 number (``20:00``
    read as 1200)."""
    import yaml

    class ConfigLoader(yaml.SafeLoader):
        def construct_mapping(self, node: Any, deep: bool = False) -> Any:
            first: dict[Any, int] = {}
            for key_node, _ in node.value:
                if key_node.tag == "tag:yaml.org,2002:merge":
                    continue
                key = self.construct_object(key_node, deep=True)
                if isinstance(key, (str, int, float, bool)) and key in first:
                    raise yaml.constructor.ConstructorError(
                        None, None, f"duplicate key {key!r} (first at line {first[key]})",
                        key_node.start_mark)
                first[key] = key_node.start_mark.line + 1
            return super().construct_mapping(node, deep=deep)

        def construct_yaml_int(self, node: Any) -> Any:
            return _not_base_60(node, super().construct_yaml_int(node))

        def construct_yaml_float(self, node: Any) -> Any:
            return _not_base_60(node, super().construct_yaml_float(node))

    def _not_base_60(node: Any, value: Any) -> Any:
        if ":" in str(node.value):  # YAML 1.1 reads 20:00 as 1200 (meant as a time? a ratio?)
            raise yaml.constructor.ConstructorError(
                None, None, f"{node.value} is the base-60 number {value} to YAML 1.1; write "
                "the number itself, or quote it for a text", node.start_mark)
        return value

    ConfigLoader.add_constructor("tag:yaml.org,2002:int", ConfigLoader.construct_yaml_int)
    ConfigLoader.add_constructor("tag:yaml.org,2002:float", ConfigLoader.construct_yaml_float)
    ConfigLoader.add_implicit_resolver(
        "tag:yaml.org,2002:float",
        re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$"),
        list("-+.0123456789"))
    return ConfigLoader


#: Most values a config file may hold: a survey of a few thousand stations is far below.
MAX_YAML_VALUES = 1_000_000


def read_yaml(path: str | Path) -> Any:
    """The content of a YAML file (:func:`_config_loader`'s rules); ConfigError naming the
    file, line and column of a syntax error or a repeated key in one line (not PyYAML's
    multi-line excerpt)."""
    import yaml

    try:
        text = Path(path).read_text(encoding="utf-8")
    except UnicodeDecodeError as err:  # (UTF-16 from Notepad, a binary file)
        raise ConfigError(f"{path}: not UTF-8 text (byte {err.start}: {err.reason}); save "
                          "it as UTF-8") from None
    try:
        data = yaml.load(text, Loader=_config_loader())  # noqa: S506
        values, stack = 0, [data]  # aliases nest: a 448-byte file held 387 million
        while stack and values <= MAX_YAML_VALUES:  # values and ran out of memory (a fuzz)
            item = stack.pop()
            values += 1
            stack += [*item.keys(), *item.values()] if isinstance(item, dict) else \
                list(item) if isinstance(item, list) else []
        if values > MAX_YAML_VALUES:
            raise ConfigError(f"{path}: holds more than {MAX_YAML_VALUES:,} values once its "
                              "aliases (*name) are expanded; write them out")
        return data
    except yaml.YAMLError as err:
        mark = getattr(err, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        raise ConfigError(f"{path}: not valid YAML{where} "
                          f"({getattr(err, 'problem', None) or err})") from None


def load_yaml(cls: type[T], path: str | Path) -> T:
    """A config from a YAML file (the same structure as :func:`from_dict`)."""
    return from_dict(cls, read_yaml(path) or {})


_INDEXED = re.compile(r"^(\w+)\[(\d+)\]$")
_ANY_INDEX = re.compile(r"^(\w+)\[(.*)\]$")


def _sections(value: Any, where: str) -> list[Any]:
    """The list an indexed key (``components[2]``) indexes; ConfigError naming ``where``
    when the field holds none (``string.components`` is None where the string is built
    from its named sections)."""
    if not isinstance(value, (list, tuple)):
        what = "None" if value is None else f"a {type(value).__name__}"
        raise ConfigError(f"{where}: is {what} here, not a list, so it takes no index; "
                          "set it as a whole list")
    return list(value)


def _split_dotted(key: str) -> tuple[str, str]:
    """``"rocks[1].mu_max"`` -> ``("rocks[1]", "mu_max")``: split at the first dot outside
    brackets (``components[1.5].length`` was cut inside the index and named a field
    ``components[1``)."""
    depth = 0
    for i, char in enumerate(key):
        depth += (char == "[") - (char == "]")
        if char == "." and depth == 0:
            return key[:i], key[i + 1:]
    return key, ""


def _changed_fields(config: Any, changes: Mapping[str, Any], path: str) -> dict[str, Any]:
    """The fields of ``config`` as keyword arguments with dotted ``changes`` applied;
    changed sub-sections come back as dicts, so one construction validates them all and
    its errors carry the whole path. A key may index a tuple of sections
    (``rocks[1].mu_max``)."""
    names = [f.name for f in dataclasses.fields(config)]
    nested: dict[str, dict[str, Any]] = {}
    flat: dict[str, Any] = {}
    for key, value in changes.items():
        head, rest = _split_dotted(key)
        if (odd := _ANY_INDEX.match(head)) and not _INDEXED.match(head):
            # (components[-1] read as an unknown field named "components[-1]")
            raise ConfigError(f"{path + '.' if path else ''}{head}: an index is a whole number "
                              f"from 0 ({odd.group(1)}[0] is the first), got "
                              f"[{odd.group(2)}]")
        name = _INDEXED.sub(r"\1", head)
        if name not in names:
            where = f"{path}.{head}" if path else head
            raise ConfigError(f"{where}: unknown field of {type(config).__name__}"
                              f"{did_you_mean(name, names)}; known: {', '.join(names)}")
        if rest:
            nested.setdefault(head, {})[rest] = value
        else:
            flat[head] = value
    kwargs = {name: getattr(config, name) for name in names}
    for head, sub in nested.items():
        where = f"{path}.{head}" if path else head
        indexed = _INDEXED.match(head)
        if indexed:
            name, index = indexed.group(1), int(indexed.group(2))
            items = _sections(flat.pop(name, kwargs[name]), f"{path}.{name}" if path else name)
            if 0 <= index < len(items) and isinstance(items[index], Mapping):
                # the whole list given too, as dicts (a YAML's): "no section at index 0 of
                # rocks (1 items)" contradicted itself (an outside review)
                raise ConfigError(f"{where}: {name} is given as a whole list as well; set "
                                  f"{', '.join(sorted(sub))} in that list's entry {index}, or "
                                  "leave the list out and set entries by index")
            if not 0 <= index < len(items) or not dataclasses.is_dataclass(items[index]):
                raise ConfigError(f"{where}: no section at index {index} of {name} "
                                  f"({len(items)} items)")
            items[index] = _changed_fields(items[index], sub, where)
            kwargs[name] = items
            continue
        current = flat.pop(head, kwargs[head])
        if isinstance(current, Mapping):
            current = from_dict(type(kwargs[head]), current)
        if isinstance(current, (tuple, list)) and current \
                and dataclasses.is_dataclass(current[0]):
            raise ConfigError(
                f"{where}: a list of {type(current[0]).__name__}, not a section: give a list "
                f"of dicts ([{{...}}, ...]) or set one entry ({where}[0].<field>); cannot set "
                f"{', '.join(sorted(sub))} in it")
        if not dataclasses.is_dataclass(current):
            raise ConfigError(f"{where}: {head} is not a section; cannot set "
                              f"{', '.join(sorted(sub))} in it")
        kwargs[head] = _changed_fields(current, sub, where)
    for head, value in flat.items():
        indexed = _INDEXED.match(head)
        if indexed:
            name, index = indexed.group(1), int(indexed.group(2))
            items = _sections(kwargs[name], f"{path}.{name}" if path else name)
            if not 0 <= index < len(items):
                raise ConfigError(f"{path + '.' if path else ''}{head}: index out of range "
                                  f"({len(items)} items)")
            items[index] = value
            kwargs[name] = items
        else:
            kwargs[head] = value
    return kwargs


def numbers(value: Any, name: str) -> np.ndarray:
    """``value`` (an action, say) as a float64 array; ValueError naming ``name`` when it
    is not numbers (strings, even of digits, None, ragged lists, booleans)."""
    try:
        array = np.asarray(value)
    except ValueError as err:  # ragged
        raise ValueError(f"{name}: expected numbers, got {value!r} ({err})") from None
    if array.dtype.kind not in "iuf":
        raise ValueError(f"{name}: expected numbers, got {value!r}")
    return array.astype(np.float64, copy=False)


def action_values(action: Any, size: int) -> list[float]:
    """An env's ``action`` of ``size`` entries as floats; ValueError naming ``action`` when
    it is not ``size`` finite numbers. The usual policy output (a float32 or float64 array
    of that shape, a batch's row) takes a fast path, exactly as float64."""
    if type(action) is np.ndarray and action.shape == (size,) and action.dtype.char in "fd":
        values = action.tolist()
    else:
        a = numbers(action, "action")
        if a.shape != (size,):
            raise ValueError(f"action: expected shape ({size},), got {np.shape(action)}")
        values = a.tolist()
    if not all(map(math.isfinite, values)):
        raise ValueError(f"action: must be finite, got {values if size > 1 else values[0]} "
                         "(NaN/inf)")
    return values


def replace(config: T, **changes: Any) -> T:
    """``dataclasses.replace`` with dotted paths: ``replace(c, **{"mud.density": 1.1e3})``.

    A value may also be a dict for a whole section (``replace(c, mud={"density": 1e3})``):
    it REPLACES the section, whose fields it does not name take their defaults, not
    ``config``'s (``formation={"rocks": ...}`` drops the interfaces). To merge, as an env's
    ``physics=`` and ``--config`` do, pass dotted keys: ``replace(c, **flatten(nested))``.
    Errors name the dotted path.
    """
    if not changes:
        return config
    return type(config)(**_changed_fields(config, changes, ""))


def flatten(changes: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """``{"mud": {"density": 1}}`` -> ``{"mud.density": 1}`` (dotted keys kept as they are).

    Nested dicts are taken as paths into sections; use this to merge user overrides."""
    out: dict[str, Any] = {}
    for key, value in changes.items():
        if not isinstance(key, str):
            raise ConfigError(f"{prefix + ': ' if prefix else ''}the key {key!r} is not a "
                              "field's name (keys are names, e.g. mud or density)")
        path = f"{prefix}.{key}" if prefix else key
        nested = isinstance(value, Mapping) and value
        for leaf, leaf_value in (flatten(value, path).items() if nested else ((path, value),)):
            if leaf in out:  # {"mud": {"density": ..}, "mud.density": ..}: the last one won
                raise ConfigError(f"{leaf}: given twice (in a section and as a dotted key, "
                                  "or twice in one); keep one")
            out[leaf] = leaf_value
    return out


def jsonable(obj: Any) -> Any:
    """A JSON-ready copy of configs (dataclasses), dicts, arrays and NumPy scalars: what
    result files and recordings store to say which configuration they belong to."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return jsonable(dataclasses.asdict(obj))
    if isinstance(obj, Mapping):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, (np.integer, np.floating, np.bool_)):
        return obj.item()
    if obj is None or isinstance(obj, (str, int, float, bool)):
        return obj
    return repr(obj)


# --------------------------------------------------------------------------- plain checks


def _require(condition: bool, name: str, message: str) -> None:
    if not condition:
        raise ConfigError(f"{name}: {message}")


def require_finite(value: Any, name: str) -> None:
    """Raise :class:`ConfigError` naming ``name`` unless ``value`` is a finite number."""
    if type(value) is float and math.isfinite(value):  # the usual case, per env step
        return
    _require(isinstance(value, (int, float, np.integer, np.floating))
             and not isinstance(value, (bool, np.bool_)) and math.isfinite(value), name,
             f"must be a finite number, got {value!r}")


#: The most simulator steps one call may take (the kernels count in int64; 10^9 steps
#: are 23 days of simulated time at 2 ms).
MAX_STEPS_PER_CALL = 10**9


def require_steps(value: Any, name: str) -> None:
    """Raise ValueError naming ``name`` unless ``value`` is a whole number of steps, 0 to
    :data:`MAX_STEPS_PER_CALL` (Python or NumPy integers; no floats, bools or strings,
    which reached the compiled kernel as a typing error)."""
    if type(value) is int and 0 <= value <= MAX_STEPS_PER_CALL:  # the usual case, at once
        return  # (it runs at every env step)
    if not (isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))
            and 0 <= value <= MAX_STEPS_PER_CALL):
        raise ValueError(f"{name}: must be a whole number of steps from 0 to "
                         f"{MAX_STEPS_PER_CALL}, got {value!r}")


def duration_steps(duration: Any, dt: float) -> int:
    """The steps of ``dt`` that make ``duration`` (s; > 0, at least one step); ValueError
    naming ``duration`` beyond :data:`MAX_STEPS_PER_CALL`."""
    require_positive(duration, "duration")
    n_steps = max(1, round(duration / dt))
    if n_steps > MAX_STEPS_PER_CALL:
        raise ValueError(f"duration: {duration:g} s is {float(n_steps):.3g} steps, more "
                         f"than one call takes ({MAX_STEPS_PER_CALL}); run it in parts")
    return n_steps


def require_positive(value: Any, name: str) -> None:
    require_finite(value, name)
    _require(value > 0, name, f"must be > 0, got {value!r}")


def require_non_negative(value: Any, name: str) -> None:
    require_finite(value, name)
    _require(value >= 0, name, f"must be >= 0, got {value!r}")


#: Angles closer than this (deg, modulo 360) are one angle given twice.
ANGLE_TOLERANCE = 1.0e-6


def require_distinct_angles(angles: tuple[float, ...], name: str) -> None:
    """Raise :class:`ConfigError` naming ``name[i]`` where an angle (deg) repeats an
    earlier one modulo 360 (a bit's blades: two in one place). Only a repeat: how close
    blades may sit, and how unbalanced a bit may be, is the user's design."""
    for i, b in enumerate(angles):
        for j, a in enumerate(angles[:i]):
            _require(abs((b - a + 180.0) % 360.0 - 180.0) > ANGLE_TOLERANCE, f"{name}[{i}]",
                     f"{b:g} deg repeats entry [{j}] ({a:g} deg, modulo 360)")
