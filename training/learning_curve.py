"""The learning curve picture of a run (``learning_curve.png``): validation return and
SSI over env steps, each resumed session's start marked.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from drill_env.sweep import save_whole
from training.config import read_run_config
from training.run_folder import read_evaluations, session_starts


def plot_learning_curve(run: Path, sessions: Sequence[int] | None = None) -> Path | None:
    """``learning_curve.png``: validation return, SSI and stuck share against env steps;
    a dotted line where a resumed session started (``sessions``: the env steps each
    started from; None: ``run.json``'s), after which the training is not the
    uninterrupted run's (a new user's trial read the bumps there as learning)."""
    rows = read_evaluations(run / "evaluations.csv")
    if not rows:
        return None
    if sessions is None:
        try:
            sessions = session_starts(json.loads((run / "run.json").read_text(encoding="utf-8")))
        except (OSError, ValueError):
            sessions = ()
    resumed = sorted({s for s in sessions if s > 0})
    from drill_env.figures import agg_figure

    steps = np.array([float(r["timesteps"]) for r in rows]) / 1e3
    fig = agg_figure(figsize=(10, 3.6))
    axes = fig.subplots(1, 2)
    ret = np.array([float(r["return"]) for r in rows])
    std = np.array([float(r["return_std"]) for r in rows])
    # whiskers as well as the band: a band of one evaluation is not drawn
    axes[0].errorbar(steps, ret, yerr=std, fmt="o-", ms=3, capsize=3, elinewidth=0.8)
    axes[0].fill_between(steps, ret - std, ret + std, alpha=0.2)
    axes[0].set_ylabel("validation return (mean +- std)")
    ssi_values = np.array([float(r["ssi"]) for r in rows])
    stuck_values = np.array([100.0 * float(r["stuck_fraction"]) for r in rows])
    ssi = axes[1].plot(steps, ssi_values, "o-", ms=3, color="tab:blue", label="SSI")
    stuck_axis = axes[1].twinx()  # in % like every other picture's stuck share
    stuck = stuck_axis.plot(steps, stuck_values, "s--", ms=3, color="tab:orange",
                            label="time stuck (%)")
    axes[1].legend(handles=ssi + stuck, fontsize=8)
    # each axis in its line's colour: two scales share the panel
    axes[1].set_ylabel("SSI (of the env's 3 s metric\nwindow, mean over the episode)",
                       color="tab:blue")
    axes[1].tick_params(axis="y", colors="tab:blue")
    stuck_axis.set_ylabel("time stuck (% of the 3 s metric\nwindow, mean over the episode)",
                          color="tab:orange")
    stuck_axis.tick_params(axis="y", colors="tab:orange")
    # from 0, with room above the highest point (a flat curve sat on the frame's top);
    # the stuck share's highest point lower than the SSI's, so two flat lines part
    def highest(values: np.ndarray) -> float:
        finite = values[np.isfinite(values)]
        return float(finite.max()) if finite.size else 0.0

    stuck_axis.set_ylim(0.0, max(1.6 * highest(stuck_values), 1.0))
    axes[1].set_ylim(0.0, max(1.15 * highest(ssi_values), 0.05))
    # a line of zeros lies on the frame's bottom, where it cannot be seen: said (a check of
    # the pictures: task 2's stuck share, zero at every evaluation)
    nothing = [words for values, words in ((ssi_values, "no stick-slip (SSI 0)"),
                                           (stuck_values, "never stuck"))
               if np.isfinite(values).any() and highest(values) == 0.0]  # (not undefined)
    if nothing:
        axes[1].text(0.5, 0.5, " and ".join(nothing) + "\nat any evaluation",
                     transform=axes[1].transAxes, ha="center", va="center", fontsize=9,
                     color="0.3")
    axes[0].set_title("return", fontsize=10)
    axes[1].set_title("stick-slip", fontsize=10)
    for ax in axes:
        ax.set_xlabel("env steps (thousands)")
        ax.grid(alpha=0.3)
        for start in resumed:
            ax.axvline(start / 1e3, color="0.4", linestyle=":", linewidth=1.2)
    saved = run / "config.yaml"
    try:
        config = read_run_config(saved) if saved.exists() else {}
    except ValueError:
        config = {}  # the plot says less
    what = (f"{str(config['algo']).upper()} on task {config['task']}, deterministic policy "
            f"on {config['eval_episodes']} fixed validation seed"
            f"{'' if config['eval_episodes'] == 1 else 's'}"
            if {"algo", "task", "eval_episodes"} <= set(config)
            else "deterministic policy on the fixed validation seeds")
    if resumed:
        what += (f"; dotted: resumed at {', '.join(f'{start:,}' for start in resumed)} "
                 "env steps")
    from agents.plots import balanced_fill

    fig.suptitle(balanced_fill(f"{run.name}: {what}", 120))  # (a long run name and the
    fig.tight_layout()  # resumes ran off both sides)
    out = run / "learning_curve.png"
    save_whole(out, lambda file: fig.savefig(file, dpi=110))
    return out
