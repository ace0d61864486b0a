"""Figures and numbers of docs/controllers.md.

    .venv/bin/python scripts/controller_figures.py                 # -> logs/controller_figures/
    .venv/bin/python scripts/controller_figures.py --out docs/img  # refresh the docs' figures

Reflection coefficient of the top per controller (pulse measurement and closed form), and
the stick-slip share of the paper's stability maps under each drive-rate controller.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from agents.registry import make_controller  # noqa: E402
from drill_env import stability_map as sm  # noqa: E402
from drill_env.physics.config import replace  # noqa: E402
from drill_env.physics.top_drive import measured_reflection, resolve  # noqa: E402
from drill_env.scenarios import make_scenario  # noqa: E402

DRIVE = ("stiff", "soft-speed", "soft-torque", "z-torque")


def reflection_figure(out: Path) -> None:
    config = make_scenario("default").config
    f_s = resolve(replace(config, **{"top_drive.controller": "soft_speed"})).tuning_frequency
    curve = np.linspace(0.02, 3.0, 600)
    points = np.array([0.25, 0.5, 0.75, 1.0, 1.25, 1.5, 2.0, 3.0, 4.0]) * f_s
    fig, ax = plt.subplots(figsize=(9, 4.5))
    print(f"default string: f_s = {f_s:.3f} Hz")
    print(f"{'controller':<12} " + " ".join(f"{p / f_s:>6.2f}fs" for p in points))
    for k, name in enumerate(DRIVE):
        cfg = replace(config, **make_controller(name).physics())
        law = resolve(cfg)
        colour = plt.get_cmap("tab10")(k)
        ax.plot(curve, [abs(law.reflection_coefficient(f)) for f in curve], color=colour,
                label=f"{name} (closed form)")
        measured = np.abs(measured_reflection(cfg, points))
        ax.plot(points, measured, "o", color=colour, mfc="none")
        print(f"{name:<12} " + " ".join(f"{m:8.3f}" for m in measured))
    ax.plot([], [], "o", color="0.3", mfc="none",
            label="simulated pulse (circles, in each line's colour)")
    ax.axvline(f_s, color="0.5", ls="--", lw=0.8)
    ax.text(f_s, 1.17, " f_s", color="0.4", va="top")
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel("|reflection coefficient| at the top")
    ax.set_ylim(0, 1.2)
    ax.set_title("Torsional waves reflected by the top drive, default string "
                 "(lines: (Z - Z_td)/(Z + Z_td); circles: simulated pulse)", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="lower right")
    fig.tight_layout()
    fig.savefig(out / "controllers_reflection.png", dpi=110)
    plt.close(fig)


def map_shares(out: Path) -> None:
    shares = {}
    for name in DRIVE:
        physics = make_controller(name).physics()
        configs = {p: sm.map_config(p, physics) for p in sm.POSITIONS}
        maps = sm.stability_maps(tuple(sm.POSITIONS), configs=configs, workers=None,
                                 progress=True)
        shares[name] = [m.unstable_fraction for m in maps]
        print(f"{name:<12} " + " ".join(f"{m.position} {m.unstable_fraction:4.0%}"
                                         for m in maps))
    fig, ax = plt.subplots(figsize=(9, 4))
    width = 0.2
    for k, name in enumerate(DRIVE):
        x = np.arange(len(sm.POSITIONS)) + (k - 1.5) * width
        values = np.array(shares[name]) * 100
        bars = ax.bar(x, values, width * 0.9, label=name)
        for bar, value in zip(bars, values, strict=True):
            if value == 0.0:  # no bar: said to be zero, not missing
                ax.text(bar.get_x() + bar.get_width() / 2, 0.3, "0", ha="center",
                        va="bottom", fontsize=8, color=bar.get_facecolor())
    ax.set_xticks(range(len(sm.POSITIONS)), list(sm.POSITIONS))
    ax.set_xlabel("the bit's position in the layer (paper Fig. 15: P1-P4 entering it, "
                  "P5-P6 leaving it)")
    ax.set_ylabel("stick-slip share of the map (%)")
    ax.set_title("Paper Fig. 15 maps (0-250 rpm x 0-200 kN, 5 rpm / 5 kN) under each "
                 "top-drive controller", fontsize=10)
    ax.legend(fontsize=8)
    ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    fig.savefig(out / "controllers_stability_maps.png", dpi=110)
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, default=Path("logs/controller_figures"))
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    reflection_figure(args.out)
    map_shares(args.out)
    print(f"figures written to {args.out}")


if __name__ == "__main__":
    main()
