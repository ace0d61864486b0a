"""Backward whirl by step and contact treatment: whether implicit contacts at long steps
whirl as the full model does (docs/performance.md, "Implicit contacts", "Backward whirl").

Runs the drilling task's held-out seeds (1000000-1000019, 300 s, metrics over the last
290 s, as ``drill-env evaluate`` does) under the stiff and SoftSpeed drives and the best
constant set point (160 rpm / 65 kN) for each variant: the full model and the fast
level's mesh (pipe laterally straight, 20 m pipe elements, 0.8 of the explicit critical
step), with explicit or implicit contacts at several steps. Whirl is bistable: on a
few seeds the BHA rolls into backward whirl for most of the window, so the table counts
those episodes ("sustained": backward whirl over 30 % of the window) beside the mean
share and the mean peak lateral force. The results of each variant stay in
``--out/<variant>`` (a rerun reuses them). ~2 min on 2 cores.

``--seed-start 2000000 --seeds 300`` plays seeds no one tuned on (neither training,
validation nor held-out), ``--variants`` a comma-separated list of the folders below;
the comparison behind the fast level's choice (docs/performance.md, "300 fresh
seeds"):

    python scripts/whirl_study.py --seed-start 2000000 --seeds 300 \
        --variants full_explicit,fast_explicit,fast_implicit_5ms,fast_implicit_10ms
    # ~10 min on 2 cores

    python scripts/whirl_study.py [--seeds 20] [--seed-start N] [--variants A,B]
        [--out logs/whirl_study]
"""

from __future__ import annotations

import argparse
import contextlib
import io
import statistics
from pathlib import Path
from typing import Any

from agents.benchmark import run_benchmark
from agents.settings import BenchmarkSettings
from drill_env.physics.fidelity import FAST_CRITICAL_STEP_FRACTION, FAST_PIPE_ELEMENT_LENGTH
from drill_env.scenarios import EVALUATION_SEEDS

CONTROLLERS = ["stiff", "soft-speed", "constant:160/65"]
#: What the fast level sets besides its step and contacts (SimulationConfig.resolved),
#: given to the full level so that the step and the contacts can be chosen freely.
FAST_MESH = {"solver.pipe_lateral": False,
             "solver.critical_step_fraction": FAST_CRITICAL_STEP_FRACTION,
             "string.drill_pipe.element_length": FAST_PIPE_ELEMENT_LENGTH}
#: (label, folder, overrides of the full level)
VARIANTS: list[tuple[str, str, dict[str, Any]]] = [
    ("full, explicit 2 ms (the reference)", "full_explicit", {}),
    ("full, implicit 2 ms", "full_implicit_2ms", {"solver.implicit_contacts": True}),
    ("full, implicit 4 ms", "full_implicit_4ms", {"solver.implicit_contacts": True,
                                                  "solver.time_step": 0.004}),
    ("fast mesh, explicit 4 ms (the fast level)", "fast_explicit",
     {**FAST_MESH, "solver.time_step": 0.004}),
    ("fast mesh, implicit 2 ms", "fast_implicit_2ms",
     {**FAST_MESH, "solver.implicit_contacts": True, "solver.time_step": 0.002}),
    ("fast mesh, implicit 4 ms", "fast_implicit_4ms",
     {**FAST_MESH, "solver.implicit_contacts": True, "solver.time_step": 0.004}),
    ("fast mesh, implicit 5 ms", "fast_implicit_5ms",
     {**FAST_MESH, "solver.implicit_contacts": True, "solver.time_step": 0.005}),
    ("fast mesh, implicit 6 ms", "fast_implicit_6ms",
     {**FAST_MESH, "solver.implicit_contacts": True, "solver.time_step": 0.006}),
    ("fast mesh, implicit 10 ms", "fast_implicit_10ms",
     {**FAST_MESH, "solver.implicit_contacts": True, "solver.time_step": 0.010}),
]
SUSTAINED = 0.3


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--seed-start", type=int, default=EVALUATION_SEEDS[0],
                        help="first seed (default: the held-out seeds)")
    parser.add_argument("--variants", default="",
                        help="comma-separated folders of the variants to run (default: all)")
    parser.add_argument("--out", type=Path, default=Path("logs/whirl_study"))
    args = parser.parse_args()
    seeds = list(range(args.seed_start, args.seed_start + args.seeds))
    asked = [name for name in args.variants.split(",") if name]
    chosen = [v for v in VARIANTS if not asked or v[1] in asked]
    unknown = set(asked) - {v[1] for v in VARIANTS}
    if unknown:
        parser.error(f"--variants: unknown {sorted(unknown)}; known: "
                     f"{', '.join(v[1] for v in VARIANTS)}")
    names = ["stiff", "soft-speed", "constant"]
    lines = ["| variant | " + " | ".join(
        f"{n}: sustained / mean share / mean peak kN" for n in names) + " |",
        "| --- |" + " --- |" * len(names)]
    whirled: dict[str, dict[tuple[str, int], bool]] = {}
    for label, folder, physics in chosen:
        settings = BenchmarkSettings(duration=300.0, warmup=10.0, fidelity="full",
                                     physics=physics)
        with contextlib.redirect_stdout(io.StringIO()):  # each variant's own table
            rows = run_benchmark(CONTROLLERS, ["random"], seeds, args.out / folder,
                                 settings, progress=False, env_id="DrillOptimise-v0")
        whirled[label] = {(r["controller"], r["seed"]): r["backward_whirl_fraction"]
                          > SUSTAINED for r in rows}
        cells = []
        for controller in CONTROLLERS:
            mine = [r for r in rows if r["controller"].startswith(controller.split(":")[0])]
            shares = [r["backward_whirl_fraction"] for r in mine]
            peaks = [r["max_lateral_force_kN"] for r in mine]
            cells.append(f"{sum(s > SUSTAINED for s in shares)} of {len(shares)} / "
                         f"{100 * statistics.fmean(shares):.1f} % / "
                         f"{statistics.fmean(peaks):.1f}")
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
        print(lines[-1], flush=True)
    print("\n" + "\n".join(lines))
    print_pairs(whirled, names)


def print_pairs(whirled: dict[str, dict[tuple[str, int], bool]], names: list[str]) -> None:
    """Seed by seed against the first variant run: the episodes where both whirl, where
    only the first does and where only the other does (sustained whirl), with the exact
    two-sided sign test's p of the two discordant counts."""
    from scipy.stats import binomtest

    (first, ref), *others = whirled.items()
    if not others:
        return
    print(f"\nsustained whirl, seed by seed against {first}: both / only the first / "
          "only this one (sign test p)")
    print("| variant | " + " | ".join(names) + " |\n| --- |" + " --- |" * len(names))
    for label, mine in others:
        cells = []
        for name in names:  # the rows' labels start with them, as in main's table
            keys = [k for k in ref if k[0].startswith(name)]
            both = sum(ref[k] and mine[k] for k in keys)
            a = sum(ref[k] and not mine[k] for k in keys)
            b = sum(mine[k] and not ref[k] for k in keys)
            p = binomtest(a, a + b).pvalue if a + b else 1.0
            cells.append(f"{both} / {a} / {b} (p = {p:.2f})")
        print(f"| {label} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
