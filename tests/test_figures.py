"""Pictures are drawn without pyplot (drill_env.figures): a notebook's inline plots went
blank for the rest of its session after a benchmark, since the pictures switched
matplotlib's backend to Agg (an outside check in Jupyter)."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("drill_env", "agents", "training", "drill_cli")


def _pyplot_or_backend_switch(path: Path) -> list[str]:
    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found += [a.name for a in node.names if a.name == "matplotlib.pyplot"]
        elif isinstance(node, ast.ImportFrom) and node.module == "matplotlib":
            found += [f"from matplotlib import {a.name}" for a in node.names
                      if a.name == "pyplot"]
        elif (isinstance(node, ast.Attribute) and node.attr == "use"
              and isinstance(node.value, ast.Name) and node.value.id == "matplotlib"):
            found.append("matplotlib.use")
    return found


def test_the_scan_finds_pyplot_and_a_backend_switch(tmp_path):
    probe = tmp_path / "probe.py"
    probe.write_text("import matplotlib\nmatplotlib.use('Agg')\nimport matplotlib.pyplot "
                     "as plt\nfrom matplotlib import pyplot\n")
    assert sorted(_pyplot_or_backend_switch(probe)) == [
        "from matplotlib import pyplot", "matplotlib.pyplot", "matplotlib.use"]


def test_no_package_module_uses_pyplot_or_switches_the_backend():
    offenders = {str(p.relative_to(ROOT)): found for package in PACKAGES
                 for p in (ROOT / package).rglob("*.py")
                 if (found := _pyplot_or_backend_switch(p))}
    assert not offenders, offenders


def test_drawing_pictures_leaves_the_processs_backend_as_it_was(tmp_path):
    """In a fresh process on another backend: a learning curve, a well's chart and the
    benchmark's bars are written, and the backend is still the one chosen; pyplot was
    never imported."""
    code = """
import sys
from pathlib import Path

import matplotlib
matplotlib.use("svg")

from agents.plots import bar_chart
from drill_env.scenarios import make_scenario
from drill_env.well import WELLS, Trajectory, write_well
from training.learning_curve import plot_learning_curve

out = Path(sys.argv[1])
(out / "evaluations.csv").write_text(
    "timesteps,return,return_std,ssi,stuck_fraction,wall_s\\n"
    "1000,-5.0,1.0,0.5,0.1,3\\n2000,-4.0,1.0,0.4,0.1,6\\n")
assert plot_learning_curve(out).stat().st_size > 0
write_well("j_shaped", Trajectory(WELLS["j_shaped"](1500.0)),
           make_scenario("default").config, out)
row = {"controller": "stiff", "scenario": "stick_slip", "seed": 0, "ssi": 1.2,
       "stuck_fraction": 0.1, "rop_m_per_h": 10.0, "backward_whirl_fraction": 0.0}
bar_chart([row], ["stiff"], ["stick_slip"], out / "bars.png")
print(matplotlib.get_backend(), "matplotlib.pyplot" in sys.modules)
"""
    done = subprocess.run([sys.executable, "-c", code, str(tmp_path)], cwd=ROOT,
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.split() == ["svg", "False"]
    assert {p.name for p in tmp_path.glob("*.png")} == {
        "learning_curve.png", "well_j_shaped.png", "bars.png"}
