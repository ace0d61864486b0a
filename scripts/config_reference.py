"""Write docs/config.md: every section and field of the physics config, from the code.

    .venv/bin/python scripts/config_reference.py          # rewrite docs/config.md
    .venv/bin/python scripts/config_reference.py --check  # exit 1 if it is out of date

Each field with its type, default and the ``#:`` comment above it in
``drill_env/physics/config.py`` (where each default's source is given). A YAML file for
``--config`` (or ``physics=`` in Python) nests these sections; tests/test_config_reference.py fails
when a field changes and this page was not rewritten.
"""

from __future__ import annotations

import argparse
import dataclasses
import inspect
import re
import sys
import typing
from pathlib import Path

from drill_env.physics import config as cfg

OUT = Path(__file__).resolve().parents[1] / "docs" / "config.md"

HEADER = """# Config reference

Generated from `drill_env/physics/config.py` by `scripts/config_reference.py` (do not
edit by hand). SI units throughout (metres, kilograms, seconds, newtons, rad/s), angles
in degrees (blade angles, dips, azimuths, inclinations). A `--config` YAML file (or
`physics=` in Python, as dotted keys: `{"string.hole_diameter": 0.2159}`) nests these
sections; a field left out keeps the scenario's value. A list (`formation.rocks`,
`string.components`) replaces the scenario's whole, its entries built from the defaults
below, not from the scenario's entries (a warning names the fields that then differ):
to change one field of the scenario's rock, set it by index,
`"formation.rocks[0].mu_min": 0.5` (quoted in YAML). Types: `Positive` > 0,
`NonNegative` >= 0, `Finite` any finite number, `Count` a whole number; `bounds` are the
physical range a value must lie in (a diameter of 5 is refused: metres). Bad values are
refused with the dotted path of the field, e.g. `string.components[1].outer_diameter`.
A whole string: `examples/field_well_string.yaml`; the model behind each field:
`docs/model.md`. An 8 1/2 in J-well (tested to load):

```yaml
string:                # StringConfig
  hole_diameter: 0.2159
  drill_pipe: {kind: drill_pipe, length: 1900.0, element_length: 10.0,
               outer_diameter: 0.127, inner_diameter: 0.10861}
  components:          # from the bit up; each a Section
    - {kind: stabilizer, length: 1.5, element_length: 1.5, outer_diameter: 0.1651,
       inner_diameter: 0.07144, contact_diameter: 0.2127}
    - {kind: collar, length: 90.0, element_length: 3.0, outer_diameter: 0.1651,
       inner_diameter: 0.07144}
bit: {diameter: 0.2159}
mud: {density: 1200.0}   # kg/m^3 (10 ppg)
well: {md: [0, 1000, 2100], inclination: [0, 0, 45], azimuth: [0, 0, 90]}
```
"""


def field_comments(klass: type) -> dict[str, str]:
    """The ``#:`` comment lines right above each field of ``klass``, joined."""
    comments: dict[str, str] = {}
    pending: list[str] = []
    for line in inspect.getsource(klass).splitlines():
        text = line.strip()
        if text.startswith("#:"):
            pending.append(text[2:].strip())
            continue
        match = re.match(r"^(\w+)\s*:", text)
        if match and pending:
            comments[match.group(1)] = " ".join(pending)
        pending = []
    return comments


def type_text(annotation: typing.Any) -> str:
    """A short readable type: the pydantic bounds' names, Optional as ``| None``."""
    text = annotation if isinstance(annotation, str) else getattr(annotation, "__name__",
                                                                   str(annotation))
    text = re.sub(r"Annotated\[([^,\[\]]+(?:\[[^\]]*\])?),\s*Field\(([^)]*)\)\]", r"\1 (\2)",
                  text)
    return text.replace("typing.", "")


def default_text(field: dataclasses.Field) -> tuple[str, str]:
    """(default, bounds) of a field; a pydantic ``Field(default=..., le=...)`` unpacked."""
    from pydantic.fields import FieldInfo
    from pydantic_core import PydanticUndefined

    value: typing.Any = field.default
    if value is dataclasses.MISSING and field.default_factory is not dataclasses.MISSING:
        value = field.default_factory()
    bounds = ""
    if isinstance(value, FieldInfo):
        bounds = ", ".join(f"{symbol} {_number(getattr(m, name))}" for m in value.metadata
                           for name, symbol in _SYMBOL.items() if hasattr(m, name))
        value = (value.default_factory() if value.default_factory is not None  # type: ignore[call-arg]
                 else value.default)
    if value is dataclasses.MISSING or value is PydanticUndefined:
        return "required", bounds
    if dataclasses.is_dataclass(value):
        return f"a {type(value).__name__} (below)", bounds
    text = _number(value) if isinstance(value, float) else repr(value)
    return (text if len(text) <= 60 else text[:57] + "..."), bounds


#: annotated_types' bounds (``Ge(ge=0)``, ...) by attribute
_SYMBOL = {"ge": ">=", "gt": ">", "le": "<=", "lt": "<"}


def _number(value: typing.Any) -> str:
    return f"{value:.6g}" if isinstance(value, float) else str(value)


def sections() -> list[tuple[list[str], type]]:
    """(YAML paths, config class) of every section under SimulationConfig, depth first;
    a class used in several places (a Section) once, with all of them."""
    found: dict[type, list[str]] = {cfg.SimulationConfig: ["(top level)"]}

    def walk(path: str, klass: type) -> None:
        hints = typing.get_type_hints(klass, include_extras=False)
        for f in dataclasses.fields(klass):
            hint = hints.get(f.name)
            for inner in _classes(hint):
                sub = (f"{path}.{f.name}" if path else f.name) + (
                    "[i]" if typing.get_origin(hint) is tuple or tuple in map(
                        typing.get_origin, typing.get_args(hint)) else "")
                if inner in found:
                    found[inner].append(sub)
                    continue
                found[inner] = [sub]
                walk(sub, inner)

    walk("", cfg.SimulationConfig)
    return [(paths, klass) for klass, paths in found.items()]


def _classes(hint: typing.Any) -> list[type]:
    """The config dataclasses a field's type holds (itself, in a tuple, or optional)."""
    if dataclasses.is_dataclass(hint) and isinstance(hint, type):
        return [hint]
    return [c for arg in typing.get_args(hint) for c in _classes(arg)]


#: Meanings of fields without a ``#:`` comment in config.py whose meaning is not plain
#: from the class docstring shown above them (config.py is at its length limit).
EXTRA = {
    ("Section", "length"): "Length of the component (m).",
    ("Section", "outer_diameter"): "Outer diameter of its body (m): mass and stiffness.",
    ("Section", "inner_diameter"): "Bore (m); 0 for a solid bar.",
    ("Section", "element_length"): "Finite-element length (m): the component is split into "
    "max(1, round(length / element_length)) equal elements (9 m at 2 m: 4 of 2.25 m).",
    ("Section", "shear_modulus"): "G (Pa), see youngs_modulus.",
    ("Section", "density"): "Steel density (kg/m^3), see youngs_modulus.",
    ("Section", "kind"): "One of: " + ", ".join(typing.get_args(cfg.ComponentKind))
    + " (in `drill-env modes` a stabilizer is a support, and the BHA analysed is what "
    "lies below the lowest drill_pipe or heavy_weight).",
    ("Section", "name"): "A label for tables and error messages.",
    ("RockConfig", "name"): "A label (recordings, rock shares).",
    ("RockConfig", "mu_min"): "The falling part's high-speed limit (the curve above).",
    ("RockConfig", "mu_max"): "The curve's value as the speed goes to zero (above).",
    ("FormationConfig", "layers"): "The rock of each layer, as an index into rocks (above).",
    ("WellConfig", "md"): "Measured depth of each station (m), increasing from 0.",
    ("WellConfig", "inclination"): "Inclination of each station from vertical (deg, 0-180).",
    ("WellConfig", "azimuth"): "Azimuth of each station (deg clockwise from north).",
}


def render() -> str:
    out = [HEADER]
    for paths, klass in sections():
        doc = inspect.getdoc(klass) or ""
        text = "\n\n".join(part.replace("\n", " ") for part in doc.split("\n\n"))
        where = ", ".join(f"`{p}`" for p in paths)
        out.append(f"## {klass.__name__}: {where}\n\n{text}\n")
        out.append("| field | type | default | bounds | meaning |\n"
                   "| --- | --- | --- | --- | --- |")
        comments = field_comments(klass)
        for f in dataclasses.fields(klass):
            if f.name.startswith("_"):
                continue
            meaning = (comments.get(f.name) or EXTRA.get((klass.__name__, f.name), "")
                       ).replace("|", "\\|")
            kind = type_text(f.type).replace("|", "\\|")
            default, bounds = (t.replace("|", "\\|") for t in default_text(f))
            out.append(f"| `{f.name}` | {kind} | `{default}` | {bounds} | {meaning} |")
        out.append("")
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--check", action="store_true",
                        help="exit 1 if docs/config.md is not what this writes")
    args = parser.parse_args(argv)
    text = render()
    if args.check:
        current = OUT.read_text() if OUT.exists() else ""
        if current != text:
            print(f"{OUT} is out of date: run scripts/config_reference.py", file=sys.stderr)
            return 1
        return 0
    OUT.write_text(text)
    print(f"wrote {OUT}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
