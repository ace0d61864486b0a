"""Speed and memory figures of the simulator and the environment (``drill-env speed``).

Five sections, each printed as a table and saved under one key of ``speed.json``:

core      real-time factor, us per step and ns per DOF per step of the default
          simulator (1000 m drill pipe + 35 m BHA, mesoscopic bit, wall contact on) on ONE
          numba thread; the plain NumPy stepper (:mod:`drill_env.physics.reference`) on a
          short run; the speed-up numba / NumPy.
env       env steps/s at the default 10 Hz policy rate: one env, N single envs looped in
          one process, the batched :class:`~drill_env.vector.DrillStringVectorEnv`; the
          Python share of a single env step (env.step minus the time inside
          ``Simulator.advance``).
scaling   us per step against string length and against element count at fixed length,
          with a least-squares line of cost against DOFs (R^2) and the spread of the cost
          per DOF; a PNG of it next to the JSON (drawn when the run finishes).
compile   first import to first env step in a fresh process with numba's cache cold and
          then warm (``NUMBA_CACHE_DIR`` pointing at a new temporary folder).
memory    bytes of one simulator's NumPy arrays and the RSS growth per env over 64 envs,
          measured in a fresh process.

``drill-env speed`` adds a sixth, ``training`` (time to a policy: PPO and SAC end to end,
split into env, update and the rest), from ``training/speed.py`` through ``run_speed``'s
``runners``: ``drill_env`` does not import the training code.

The machines this runs on are shared and noisy, so every figure comes with a ratio
against a reference measured in the same run (the NumPy stepper, a single env, the
default mesh, the warm start, the simulator's own arrays): ratios survive a busy machine
better than absolute times. Timed loops report the best of several repeats.

The core and env sections run once per fidelity level (``FIDELITY_LEVELS``) and report
the fast / full ratio.

Use ``drill-env speed [--quick] [--sections core,env] [--out logs]`` or :func:`run_speed`.
The sections live in :mod:`.core` (core, scaling), :mod:`.env`, :mod:`.system`
(compile, memory); the shared timing helpers in :mod:`.common`.
"""

from __future__ import annotations

import dataclasses
import json
import os
import time
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any

from drill_env.physics.validation import comma_items
from drill_env.sweep import save_text
from drill_env.tools.speed.common import (
    FULL,
    QUICK,
    SECTIONS,
    BenchmarkSettings,
    fidelity_levels,
    machine_info,
    source_stamp,
    threading_layer,
)
from drill_env.tools.speed.core import (
    bench_core,
    bench_scaling,
    format_core,
    format_scaling,
    plot_scaling,
)
from drill_env.tools.speed.env import bench_env, format_env
from drill_env.tools.speed.system import (
    bench_compile,
    bench_memory,
    format_compile,
    format_memory,
)

# --------------------------------------------------------------------------- driver

#: A section: (bench(settings, progress) -> figures, format(figures) -> table).
Runner = tuple[Callable[..., dict[str, Any]], Callable[[dict[str, Any]], str]]

RUNNERS: dict[str, Runner] = {
    "core": (bench_core, format_core),
    "env": (bench_env, format_env),
    "scaling": (bench_scaling, format_scaling),
    "compile": (bench_compile, format_compile),
    "memory": (bench_memory, format_memory),
}


def parse_sections(text: str, extra: Iterable[str] = ()) -> tuple[str, ...]:
    """``"core,env"`` -> ``("core", "env")``; ``ValueError`` naming an unknown section.
    ``extra``: sections a caller adds (``drill-env speed`` adds ``training``)."""
    known = (*SECTIONS, *extra)
    names = tuple(comma_items(text, "sections", "section"))
    unknown = [s for s in names if s not in known]
    if unknown or not names:
        raise ValueError(f"sections: unknown {unknown or text!r}; choose from "
                         f"{','.join(known)}")
    return names


def run_speed(sections: Iterable[str] = SECTIONS, settings: BenchmarkSettings = FULL,
              out: Path | None = Path("logs"), progress: bool = True,
              echo: Callable[[str], Any] | None = print,
              runners: Mapping[str, Runner] | None = None) -> dict[str, Any]:
    """Run ``sections`` in order and print each table as it finishes. ``runners`` adds
    sections from outside ``drill_env`` (name -> (bench(settings, progress), format)):
    the ``training`` section lives with the training code, which ``drill_env`` does not
    import.

    Unless ``out`` is None, writes ``out/speed.json`` (every figure) and ``out/speed.md``
    (the tables, for docs/performance.md), both rewritten after each section, so an
    interrupted run keeps the sections it finished (speed.md says it is unfinished), and,
    with the scaling section, ``out/speed_scaling.png``. A run replaces an earlier run's
    files in ``out`` (a run is not resumed: figures from two runs do not compare).
    """
    sections = tuple(sections)
    added = dict(runners or {})
    table = {**RUNNERS, **added}
    parse_sections(",".join(sections), extra=added)
    levels = fidelity_levels()
    result: dict[str, Any] = {
        "machine": machine_info(),
        "settings": dataclasses.asdict(settings),
        "fidelity_levels": list(levels),
    }
    say = echo or (lambda _text: None)
    machine = result["machine"]
    tables: list[str] = []
    say(f"drill-env speed {machine['date']}: {','.join(sections)}; "
        f"{machine['cores']} cores; fidelity levels: {', '.join(levels)}")
    stamp = source_stamp()
    t0 = time.perf_counter()

    def write(finished: bool) -> list[Path]:
        """speed.json and speed.md of this run so far, always the two together (a run
        is not resumed: figures of two runs are not measured in the same rounds)."""
        assert out is not None
        path = out / "speed.json"
        result["finished_sections"] = [s for s in sections if s in result]
        layer = threading_layer()  # chosen at the first parallel call (batched envs)
        if layer is not None:
            machine["numba_threading_layer"] = layer
        save_text(path, json.dumps(result, indent=2) + "\n")
        # The same tables as markdown, to paste into docs/performance.md.
        report = out / "speed.md"
        kind = {FULL: "", QUICK: " --quick"}.get(settings, " (custom settings)")
        if set(sections) != set(table):
            kind += f" --sections {','.join(sections)}"
        changed = machine.get("sources_changed_during_run")
        head = (f"`drill-env speed{kind}`, "
                f"{machine['date'][:10]}, commit {machine.get('git_commit', '?')}: "
                f"{machine['cpu']}, {machine['cores']} cores, {machine['platform']}, "
                f"Python {machine['python']}, NumPy {machine['numpy']}, numba "
                f"{machine['numba']}"
                + (f" ({machine['numba_threading_layer']} layer)"
                   if "numba_threading_layer" in machine else "")
                + f"; load average {machine.get('load_average_1min', 0):.1f} "
                + (f"at the start, {machine.get('load_average_1min_end', 0):.1f} at the end"
                   + ("; SOURCES CHANGED DURING THE RUN." if changed
                      else "; sources unchanged during the run.") if finished else
                   f"at the start; UNFINISHED: sections done so far "
                   f"{', '.join(result['finished_sections'])}."))
        save_text(report, head + "\n\n```text\n" + "\n\n".join(tables) + "\n```\n")
        return [path, report]

    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        # an earlier run's picture would sit beside this run's figures
        (out / "speed_scaling.png").unlink(missing_ok=True)
    for name in sections:
        bench, fmt = table[name]
        tic = time.perf_counter()
        result[name] = bench(settings, progress)
        result[name]["section_wall_s"] = time.perf_counter() - tic
        tables.append(fmt(result[name]))
        say("\n" + tables[-1])
        if out is not None:  # each section as it finishes: an interrupt keeps them
            write(finished=False)
    result["total_wall_s"] = time.perf_counter() - t0
    machine["sources_changed_during_run"] = source_stamp() != stamp
    if machine["sources_changed_during_run"]:
        say("\nWARNING: drill_env sources changed during the run: the figures mix versions, "
            "rerun")
    if hasattr(os, "getloadavg"):
        machine["load_average_1min_end"] = os.getloadavg()[0]
    if out is not None:
        written = write(finished=True)
        if "scaling" in result:
            png = plot_scaling(result["scaling"], out / "speed_scaling.png")
            if png is not None:
                written.append(png)
        say(f"\nwrote {', '.join(str(p) for p in written)} ({result['total_wall_s']:.0f} s)")
    return result
