"""The physics part of ``drill-env demo``: stick-slip at 50 rpm, none at 100 rpm.

Paper section 4, case 1 at 100 kN (Figs. 13, 14): the paper's string
(``SimulationConfig()``'s default; the envs' default scenario drills the realistic one),
torsional model in hard rock under the stiff top drive. Prints a table, writes
``demo_stick_slip.png`` (both set points on one speed scale) and ``demo_summary.json``.
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

from drill_env.physics.config import FormationConfig, SimulationConfig, SolverConfig
from drill_env.physics.units import HOUR, KILO, RPM, shown
from drill_env.scenarios import HARD
from drill_env.sweep import save_text, save_whole
from drill_env.tools.studies import COL, simulate, stick_slip_summary

#: The demo's set points (rpm), WOB (N) and simulated seconds per run.
DEMO_RPM = (50.0, 100.0)
DEMO_WOB = 100e3
DEMO_SECONDS = 60.0


def stick_slip_demo(out: Path, echo: Any = print) -> tuple[list[dict[str, Any]], bool]:
    """Run the two set points; returns the table rows and whether paper result 1 holds."""
    from drill_env.figures import agg_figure

    out.mkdir(parents=True, exist_ok=True)
    # Paper case 1 is a torsional study: lateral DOFs frozen (docs/model.md, "Axial load
    # and buckling": the paper's 35 m BHA cannot carry 100 kN laterally).
    config = SimulationConfig(formation=FormationConfig(rocks=(HARD,)),
                              solver=SolverConfig(lateral=False))
    rows: list[dict[str, Any]] = []
    runs = {}
    t0 = time.perf_counter()
    simulate(config, DEMO_RPM[0], DEMO_WOB, 0.1)  # compile (or load the cache) untimed
    for rpm in DEMO_RPM:
        tic = time.perf_counter()
        run = simulate(config, rpm, DEMO_WOB, DEMO_SECONDS, progress=f"{rpm:.0f} rpm")
        wall = time.perf_counter() - tic
        runs[rpm] = run
        window = run.window(DEMO_SECONDS / 2)
        bit = window[:, COL["bit_speed"]]
        rows.append({
            "rpm": rpm, "wob_kN": DEMO_WOB / KILO, **stick_slip_summary(run, DEMO_SECONDS / 2),
            "bit_rpm_min": float(bit.min() / RPM),  # a stuck bit may creep back a little
            "bit_rpm_max": float(bit.max() / RPM),
            "mean_tob_kNm": float(window[:, COL["torque_on_bit"]].mean() / KILO),
            "rop_m_per_h": float(window[:, COL["rop"]].mean() * HOUR),
            "real_time_factor": DEMO_SECONDS / wall, "status": run.status or "ok",
        })
    header = (f"{'rpm':>5} {'SSI':>6} {'stuck':>6} {'bit rpm min-max':>16} "
              f"{'TOB kN m':>9} {'ROP m/h':>8} {'x real time':>11}")
    echo("Paper string (1000 m DP + 35 m BHA, SimulationConfig()), mesoscopic bit, hard rock, "
         f"WOB 100 kN, stiff top drive, torsional dynamics (paper case 1); metrics over the "
         f"last {DEMO_SECONDS / 2:g} s of {DEMO_SECONDS:g}")
    echo(header)
    echo("-" * len(header))
    for r in rows:
        echo(f"{r['rpm']:5.0f} {r['ssi']:6.2f} {r['stuck_fraction']:6.0%} "
             f"{shown('{:7.1f}', r['bit_rpm_min'])} - {r['bit_rpm_max']:6.1f} "
             f"{r['mean_tob_kNm']:9.2f} "
             f"{r['rop_m_per_h']:8.2f} {r['real_time_factor']:11.0f}")
    verdict = rows[0]["ssi"] > 0.8 and rows[1]["ssi"] < 0.2
    echo(f"paper result 1 (stick-slip at 50 rpm, none at 100 rpm): "
         f"{'reproduced' if verdict else 'NOT reproduced'}")

    # One speed scale for both panels: a steady run must look steady.
    fig = agg_figure(figsize=(9, 6))
    axes = fig.subplots(2, 1, sharex=True, sharey=True)
    for ax, rpm in zip(axes, DEMO_RPM, strict=True):
        run = runs[rpm]
        # the bit over a wider surface line: where both turn steadily (100 rpm) the bit
        # still shows
        ax.plot(run.time, run.channel("bit_speed") / RPM, lw=0.8, label="bit", zorder=3)
        ax.plot(run.time, run.channel("surface_speed") / RPM, lw=2.4, label="surface",
                alpha=0.6, zorder=2)
        ax.set_ylabel("speed (rpm)")
        ax.set_title(f"{rpm:.0f} rpm set point, WOB 100 kN, hard rock, stiff top drive "
                     f"(grey: not in the table)", fontsize=10)
        ax.axvspan(0.0, DEMO_SECONDS / 2, color="0.9", zorder=0)
        ax.legend(loc="upper left", bbox_to_anchor=(1.0, 1.0))  # beside, not on, the peaks
    axes[0].set_ylim(bottom=min(0.0, axes[0].get_ylim()[0]))
    axes[-1].set_xlabel("time (s)")
    fig.tight_layout()
    save_whole(out / "demo_stick_slip.png", lambda file: fig.savefig(file, dpi=120))
    save_text(out / "demo_summary.json", json.dumps(rows, indent=2))
    echo(f"wrote {out / 'demo_stick_slip.png'} and {out / 'demo_summary.json'} "
         f"({time.perf_counter() - t0:.1f} s)")
    return rows, verdict
