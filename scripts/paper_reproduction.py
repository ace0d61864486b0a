"""Regenerate the figures of docs/paper-reproduction.md (paper Figs. 13-18).

    .venv/bin/python scripts/paper_reproduction.py                 # -> logs/paper_figures/
    .venv/bin/python scripts/paper_reproduction.py --out docs/img  # refresh the docs' figures
    .venv/bin/python scripts/paper_reproduction.py --kicks         # + the initial-kick table

``--kicks`` also prints the lateral figures of the docs' table at initial kicks of 0.5-3 %
(about 10 s): the coupled cases are chaotic, so a figure quoted from one kick is noise.

Every run comes from drill_env.tools.studies.simulate, the same code the paper-result tests use;
the stability maps (Fig. 15) from drill_env.stability_map, as ``drill-env stability-map``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from drill_env.physics.config import replace  # noqa: E402
from drill_env.scenarios import make_scenario  # noqa: E402
from drill_env.stability_map import plot_maps, stability_maps  # noqa: E402
from drill_env.tools.studies import (  # noqa: E402
    RPM,
    lateral_force,
    radial_displacement,
    simulate,
    stick_slip_summary,
)

#: Initial kicks (relative drop of the bit speed) of the kick table.
KICKS = (0.005, 0.01, 0.02, 0.03)
#: The bit's gauge clearance in the paper cases (m).
GAUGE_CLEARANCE = 0.005


def torsional_crossing(rpm: float):
    sc = make_scenario("paper_case2", weight_on_bit=100e3, thickness=0.8, lead=0.2)
    return simulate(replace(sc.config, **{"solver.lateral": False}), rpm, 100e3, 360.0)


def figure_13_14(out: Path) -> None:
    fig, axes = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
    for ax, rpm in zip(axes, (50.0, 100.0), strict=True):
        run = torsional_crossing(rpm)
        ax.plot(run.time, run.channel("bit_speed") / RPM, lw=0.6, label="bit speed")
        ax.set_ylabel("bit speed (rpm)")
        ax2 = ax.twinx()
        ax2.fill_between(run.share_time, run.shares[:, 1], color="tab:orange", alpha=0.25,
                         label="share of rock 2")
        ax2.set_ylim(0, 1.05)
        ax2.set_ylabel("share of soft rock")
        ax.set_title(f"Fig. 13/14: {rpm:.0f} rpm, 100 kN, hard-soft-hard 45 deg (torsional)")
    axes[-1].set_xlabel("time (s)")
    fig.tight_layout()
    fig.savefig(out / "fig13_14_torsional_crossing.png", dpi=110)
    plt.close(fig)


def figure_15(out: Path) -> None:
    plot_maps(stability_maps(progress=True), out / "fig15_stability_map.png")


def lateral_cases():
    runs = {}
    for name in ("paper_case2", "paper_case3", "paper_case4"):
        sc = make_scenario(name)
        runs[name] = simulate(sc.config, sc.surface_speed / RPM, sc.weight_on_bit, 240.0)
    return runs


def figure_16_17_18(runs, out: Path) -> None:
    titles = {"paper_case2": "case 2: symmetric, soft layer",
              "paper_case3": "case 3: symmetric, very soft layer",
              "paper_case4": "case 4: asymmetric, soft layer"}
    def time_series(values, ylabel: str, figure: str, filename: str) -> None:
        # one scale for the three cases, which the docs compare (case 3's larger lateral
        # forces read against case 2's own 0-12 kN axis; a check of the pictures)
        fig, axes = plt.subplots(3, 1, figsize=(10, 8), sharex=True, sharey=True)
        for ax, (name, run) in zip(axes, runs.items(), strict=True):
            ax.plot(run.time, values(run), lw=0.5)
            ax.set_ylabel(ylabel)
            ax.set_title(f"{figure} {titles[name]} (50 rpm, 75 kN)")
            ax.yaxis.set_tick_params(labelleft=True)
            ax2 = ax.twinx()  # shaded: share of the middle rock under the blades
            ax2.fill_between(run.share_time, run.shares[:, 1], color="tab:orange", alpha=0.25)
            ax2.set_ylim(0, 1.05)
            ax2.set_ylabel("share of the layer's rock\nunder the blades (shaded)", fontsize=8)
        axes[-1].set_xlabel("time (s)")
        fig.tight_layout()
        fig.savefig(out / filename, dpi=110)
        plt.close(fig)

    time_series(lambda run: run.channel("bit_speed") / RPM, "bit rpm", "Fig. 16",
                "fig16_torsional_cases.png")
    time_series(lambda run: lateral_force(run) / 1e3, "lateral force (kN)", "Fig. 17",
                "fig17_lateral_force.png")

    fig, axes = plt.subplots(3, 3, figsize=(10, 10))
    phases = (("homogeneous (before)", 0.0, 0.01), ("transition", 0.01, 0.99),
              ("inside the layer", 0.99, 1.01))
    theta = np.linspace(0, 2 * np.pi, 200)
    for row, (name, run) in zip(axes, runs.items(), strict=True):
        share = run.share_at(run.time, 1)
        x, y = run.channel("bit_x") * 1e3, run.channel("bit_y") * 1e3
        for ax, (label, lo, hi) in zip(row, phases, strict=True):
            sel = (share >= lo) & (share < hi)
            if label.startswith("homogeneous"):
                sel &= run.time < run.time[share > 0.01][0] if (share > 0.01).any() else sel
            ax.plot(5 * np.cos(theta), 5 * np.sin(theta), color="tab:blue", lw=1)
            ax.plot(x[sel], y[sel], lw=0.4, color="k")
            ax.set_aspect("equal")
            ax.set_xlim(-12, 12)
            ax.set_ylim(-12, 12)
            ax.set_title(f"{name[-5:]}: {label}", fontsize=9)
        row[0].set_ylabel("bit y (mm)")
    for ax in axes[-1]:
        ax.set_xlabel("bit x (mm)")
    fig.suptitle("Fig. 18: bit orbit (mm) in the 5 mm gauge clearance")
    fig.tight_layout()
    fig.savefig(out / "fig18_orbits.png", dpi=110)
    plt.close(fig)


def kick_table() -> list[str]:
    """The lateral figures of docs/paper-reproduction.md's table at every kick of KICKS.

    Symmetric bit (cases 2 and 3, 200 s): 95th percentile and maximum of the lateral force
    over the transition (share of the layer rock between 1 and 99 %), and how long after
    the last of the layer left the blades the lateral force last exceeded 100 N (the
    paper-result test's "no contact"), and the stick-slip from 10 s after that to the end.
    Asymmetric bit (case 4, 120 s, after 5 s): the share of the moving time (bit turning,
    off centre by more than 10 % of the clearance) it whirls forward, and the 5th-95th
    percentiles of its lateral force.
    """
    lines = ["| case | kick | transition p95 / max kN | settled after the layer (s) | "
             "SSI / stuck after it | forward whirl | lateral force p5-p95 kN |",
             "| --- | --- | --- | --- | --- | --- | --- |"]
    for name in ("paper_case2", "paper_case3", "paper_case4"):
        sc = make_scenario(name)
        seconds = 120.0 if name == "paper_case4" else 200.0
        for kick in KICKS:
            run = simulate(sc.config, sc.surface_speed / RPM, sc.weight_on_bit, seconds,
                           kick=kick)
            force, t = lateral_force(run), run.time
            if name == "paper_case4":
                late = t > 5.0
                rotation = run.channel("bit_speed")[late]
                moving = (np.abs(rotation) > 0.1) & (
                    radial_displacement(run)[late] > 0.1 * GAUGE_CLEARANCE)
                forward = np.mean(np.sign(run.channel("whirl_speed")[late][moving])
                                  == np.sign(rotation[moving]))
                p5, p95 = np.percentile(force[late], (5, 95)) / 1e3
                lines.append(f"| {name} | {kick:.1%} | | | | {forward:.0%} | {p5:.1f}-{p95:.1f} |")
                continue
            share = run.share_at(t, 1)
            transition = (share > 0.01) & (share < 0.99)
            left = t[share > 0.01][-1]
            loud = t[(t > left) & (force > 100.0)]
            settled = f"{loud[-1] - left:.1f}" if loud.size else "0"
            if loud.size and loud[-1] > t[-1] - 1.0:
                settled = "not by the end"
            p95 = np.percentile(force[transition], 95) / 1e3
            after = stick_slip_summary(run, left + 10.0)
            lines.append(f"| {name} | {kick:.1%} | {p95:.1f} / {force[transition].max() / 1e3:.0f}"
                         f" | {settled} | {after['ssi']:.2f} / {after['stuck_fraction']:.0%} | | |")
    return lines


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--out", type=Path, default=Path("logs/paper_figures"),
                        help="output folder (docs/img to refresh the figures of the docs)")
    parser.add_argument("--kicks", action="store_true",
                        help="also print the lateral figures at initial kicks of 0.5-3 %%")
    parser.add_argument("--only-kicks", action="store_true", help="only the kick table")
    args = parser.parse_args()
    if args.kicks or args.only_kicks:
        print("\n".join(kick_table()), flush=True)
    if args.only_kicks:
        return
    args.out.mkdir(parents=True, exist_ok=True)
    figure_13_14(args.out)
    figure_15(args.out)
    figure_16_17_18(lateral_cases(), args.out)
    print(f"figures written to {args.out}")


if __name__ == "__main__":
    main()
