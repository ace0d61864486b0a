"""The kernel data layout: named once, no literal indices, small compiled functions, layers."""

from __future__ import annotations

import ast
import importlib
import inspect
import pkgutil
import subprocess
import sys
from pathlib import Path

import numba
import pytest

import drill_env
from drill_env.physics import layout

PACKAGE = Path(drill_env.__file__).parent
#: Names the code gives to arrays with a named layout (params, state, records, readings,
#: bit loads, blades, rock parameters, metric samples and outputs, contact results).
LAYOUT_ARRAYS = frozenset({
    "p", "params", "state", "st", "record", "rec", "row", "out", "bit_out", "readings",
    "fresh", "rock_params", "rp", "blades", "blade", "samples", "columns", "step_out",
    "window_out", "contact", "contact_out", "_readings", "r",
})
MAX_KERNEL_ARGUMENTS = 12


def _modules():
    for info in pkgutil.walk_packages([str(PACKAGE)], "drill_env."):
        yield info.name


def _literal_index(node: ast.AST) -> bool:
    if isinstance(node, ast.Constant) and isinstance(node.value, int):
        return True
    if isinstance(node, ast.UnaryOp) and isinstance(node.operand, ast.Constant):
        return True
    if isinstance(node, ast.Tuple):
        return any(_literal_index(e) for e in node.elts)
    if isinstance(node, ast.Slice):
        return any(b is not None and _literal_index(b) for b in (node.lower, node.upper))
    return False


def literal_layout_indices(source: str) -> list[tuple[int, str]]:
    """(line, text) of every subscript of a layout array by an integer literal."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if not isinstance(node, ast.Subscript):
            continue
        target = node.value
        name = target.id if isinstance(target, ast.Name) else (
            target.attr if isinstance(target, ast.Attribute) else None)
        if name in LAYOUT_ARRAYS and _literal_index(node.slice):
            found.append((node.lineno, ast.unparse(node)))
    return sorted(found)


def test_the_scan_finds_a_literal_index():
    assert literal_layout_indices("x = p[3] + state[S.TIME]\nout[0:2] = 1") == [
        (1, "p[3]"), (2, "out[0:2]")]
    assert literal_layout_indices("x = p[P.DT] + rec[:, k] + ul[0, j]") == []


def test_no_literal_index_into_a_layout_array_remains():
    offenders = []
    for path in sorted(PACKAGE.rglob("*.py")):
        for line, text in literal_layout_indices(path.read_text()):
            offenders.append(f"{path.relative_to(PACKAGE.parent)}:{line}: {text}")
    assert not offenders, "\n".join(offenders)


def compiled_functions():
    for name in _modules():
        module = importlib.import_module(name)
        for attr, obj in vars(module).items():
            if isinstance(obj, numba.core.registry.CPUDispatcher) and \
                    obj.py_func.__module__ == name:
                yield f"{name}.{attr}", obj


def test_no_compiled_function_takes_more_than_twelve_arguments():
    functions = dict(compiled_functions())
    assert len(functions) > 20  # the scan sees the kernels
    wide = {name: len(inspect.signature(f.py_func).parameters)
            for name, f in functions.items()
            if len(inspect.signature(f.py_func).parameters) > MAX_KERNEL_ARGUMENTS}
    assert not wide, wide


def test_channel_names_derive_from_the_layout_lists():
    from drill_env.env import DrillStringEnv
    from drill_env.physics.simulator import RECORD_CHANNELS

    assert RECORD_CHANNELS == tuple(m.name.lower() for m in layout.R)
    assert layout.READINGS == tuple(m.name.lower() for m in layout.READ)
    env = DrillStringEnv(episode_duration=0.2)
    _, info = env.reset(seed=0)
    shown = set(layout.READINGS) - {"bit_x", "bit_y", "bit_vx", "bit_vy", "status"}
    assert shown <= set(info)  # a new reading is an info key without touching the env
    assert set(env.observation_names) <= set(layout.READINGS) | {
        "speed_setpoint", "weight_on_bit_setpoint"}


def _imports(path: Path) -> set[str]:
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module.split(".")[0])
    return names


def test_drill_env_never_imports_agents_or_training():
    offenders = [str(p.relative_to(PACKAGE.parent)) for p in PACKAGE.rglob("*.py")
                 if _imports(p) & {"agents", "training"}]
    assert not offenders, offenders


@pytest.mark.parametrize("module", ["drill_env.physics.simulator", "drill_env.physics"])
def test_importing_the_physics_leaves_gymnasium_unimported(module):
    code = (f"import sys, {module}; "
            "print(sorted(m for m in ('gymnasium', 'torch', 'stable_baselines3', 'rerun') "
            "if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == "[]"


def test_no_package_file_is_much_longer_than_one_concern():
    """The command line, the controllers and the training too: the command line was one
    file of 2,300 lines (a module per command now), the benchmark one of 1,440 (four now),
    training one of 1,015 (four now)."""
    sizes = {str(p.relative_to(PACKAGE.parent)): len(p.read_text().splitlines())
             for folder in (PACKAGE, *(PACKAGE.parent / p for p in ("drill_cli", "agents",
                                                                   "training")))
             for p in folder.rglob("*.py")}
    assert not {k: v for k, v in sizes.items() if v > 700}, sizes


#: The only places that write a file in place: save_text itself (into its hidden partial
#: file), the recorder's writability probe (an empty file it removes) and the modes
#: chart of the physics layer, which imports nothing above it (the CLI hands it the
#: partial file of save_whole).
WRITES_IN_PLACE = {("drill_env/sweep.py", "save_text"),
                   ("drill_env/recording/recorder.py", "check_directory"),
                   ("drill_env/physics/modes.py", "critical_speed_chart"),
                   ("agents/benchmark.py", "write_bytes")}  # (what pin_policy's save_whole
# calls, as save_text's)


def _writes_in_place(path: Path) -> list[tuple[str, int]]:
    """(enclosing function, line) of each ``.write_text(`` / ``.write_bytes(`` call and
    each ``.savefig(`` outside a lambda (the form save_whole takes)."""
    found = []

    def visit(node: ast.AST, function: str, in_lambda: bool) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
                visit(child, child.name, False)
                continue
            if isinstance(child, ast.Call) and isinstance(child.func, ast.Attribute) and (
                    child.func.attr in ("write_text", "write_bytes")
                    or child.func.attr == "savefig" and not in_lambda):
                found.append((function, child.lineno))
            visit(child, function, in_lambda or isinstance(child, ast.Lambda))

    visit(ast.parse(path.read_text(encoding="utf-8")), "<module>", False)
    return found


def test_every_output_is_saved_whole():
    """A summary, a table, a JSON file or a picture written in place is left cut short by
    a kill mid-write, where a reader (a resume, a docs table, a person) takes it whole:
    each goes through save_text or save_whole (a hidden partial file renamed over the
    name). Until 2026-12-06 eight text outputs (run_summary.json, modes.json, speed.json
    and .md, a stability map's JSON, a well's JSON, demo_summary.json, the training seeds'
    table) and six pictures (the stability maps, the modes chart, the demo's, the speed
    scaling, the well chart, the learning curve) were written in place."""
    root = PACKAGE.parent
    offenders = []
    for package in ("drill_env", "agents", "training", "drill_cli"):
        for path in sorted((root / package).rglob("*.py")):
            name = path.relative_to(root).as_posix()
            offenders += [f"{name}:{line} in {function}"
                          for function, line in _writes_in_place(path)
                          if (name, function) not in WRITES_IN_PLACE]
    assert not offenders, offenders
    assert _writes_in_place(root / "drill_env" / "sweep.py")  # the scan sees a call
    assert _writes_in_place(root / "drill_env" / "physics" / "modes.py")
