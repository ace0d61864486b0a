"""The Python examples of the README and the docs run as printed (a reader copies them)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = ("README.md", "docs/env.md", "docs/tasks.md", "docs/recording.md",
         "docs/controllers.md")


def _snippets() -> list[tuple[str, int, str]]:
    out = []
    for page in PAGES:
        text = (ROOT / page).read_text()
        for k, match in enumerate(re.finditer(r"^```python\n(.*?)^```", text, re.M | re.S)):
            out.append((page, k, match.group(1)))
    return out


@pytest.mark.parametrize(("page", "index", "code"), _snippets(),
                         ids=[f"{p}[{k}]" for p, k, _ in _snippets()])
def test_a_python_example_of_the_docs_runs(page, index, code, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # what an example writes (logs/recordings) stays here
    (tmp_path / "agents").mkdir()  # the shipped policies' files they read, as from ROOT
    (tmp_path / "agents" / "trained").symlink_to(ROOT / "agents" / "trained")
    (tmp_path / "examples").symlink_to(ROOT / "examples")  # (the example configs)
    # an rl-zoo3 run's layout (docs/tasks.md), the shipped task-1 SAC policy standing in
    zoo = tmp_path / "logs" / "sac" / "DrillStickSlip-v0_1"
    (zoo / "DrillStickSlip-v0").mkdir(parents=True)
    shipped = ROOT / "agents" / "trained" / "stick_slip"
    (zoo / "DrillStickSlip-v0.zip").symlink_to(shipped / "model.zip")
    (zoo / "DrillStickSlip-v0" / "vecnormalize.pkl").symlink_to(shipped / "vecnormalize.pkl")
    # each example as a reader copies it: nothing defined for it
    exec(compile(code, f"{page} example {index}", "exec"), {})  # noqa: S102


def test_every_page_with_python_examples_is_checked():
    """A page that gains a Python example is run by the test above."""
    pages = {str(p.relative_to(ROOT)) for p in [ROOT / "README.md", *ROOT.glob("docs/*.md")]
             if "```python" in p.read_text()}
    assert pages <= set(PAGES)
    assert len(_snippets()) >= 4


def test_the_rock_table_of_the_model_page_is_the_scenarios_rocks():
    """docs/model.md section 7 quotes the rock presets; a tuned preset must not leave the
    page behind."""
    from drill_env import scenarios

    text = (ROOT / "docs/model.md").read_text().split("## 7. Rocks and scenarios")[1]
    rows = {}
    for line in text.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if cells[0] in ("hard", "soft", "very_soft"):
            rows[cells[0]] = [float(c) for c in cells[1:]]
    fields = ("mu_min", "mu_max", "st1", "st2", "wall_stiffness", "wall_damping",
              "depth_of_cut", "founder_wob_per_diameter")
    for rock in (scenarios.HARD, scenarios.SOFT, scenarios.VERY_SOFT):
        assert rows[rock.name] == pytest.approx([getattr(rock, f) for f in fields],
                                                rel=1e-12), rock.name


def _line(page: str, start: str) -> str:
    """The line of ``page`` that starts with ``start`` (a table row)."""
    lines = [line for line in (ROOT / page).read_text().splitlines() if line.startswith(start)]
    assert len(lines) == 1, (page, start, len(lines))
    return lines[0]


def test_the_controllers_page_states_the_defaults_the_code_has():
    """docs/controllers.md's numbers for the driller's rules, SoftTorque's band-pass and
    the stability map's points are the defaults of ``DrillerRules``, ``TopDriveConfig``
    and ``MapSettings``: a default changed in the code (or the page) without the other
    fails here."""
    from agents.driller import DrillerRules
    from drill_env.physics.units import KILO
    from drill_env.stability_map import MapSettings

    r = DrillerRules()
    row = _line("docs/controllers.md", "| `driller` |")
    assert (f"raises rpm (+{r.rpm_step:g} per {r.decision_period:g} s, up to "
            f"+{r.max_rpm_raise:g}), then lowers WOB (-{r.weight_on_bit_step / KILO:g} kN, "
            f"down to half) while the surface torque swings > {100 * r.torque_swing:g} % of "
            f"its mean; steps back after {r.calm_decisions * r.decision_period:g} s calm"
            ) in row
    assert r.min_weight_fraction == 0.5  # "down to half"
    from drill_env.physics.config import TopDriveConfig

    row = _line("docs/controllers.md", "| `soft-torque` |")
    assert f"damping {TopDriveConfig().filter_damping:g} (our choice)" in row
    m = MapSettings()
    text = " ".join((ROOT / "docs/controllers.md").read_text().split())
    assert f"A map point is {m.seconds:g} s from a {100 * m.kick:g} % kick (`MapSettings`)" \
        in text


def test_the_citation_and_licence_files_say_what_the_package_declares():
    """CITATION.cff's version and licence are pyproject's; LICENSE is the licence named."""
    import tomllib

    import yaml

    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    citation = yaml.safe_load((ROOT / "CITATION.cff").read_text())
    assert str(citation["version"]) == project["version"]
    assert citation["license"] == project["license"]
    assert (ROOT / "LICENSE").read_text().startswith(f"{project['license']} License")
