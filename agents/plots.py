"""Pictures of the controller benchmark."""

from __future__ import annotations

import math
import textwrap
import zlib
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import matplotlib
import numpy as np

from drill_env.figures import agg_figure
from drill_env.physics.units import RPM

#: An SSI below this is no stick-slip: a smooth run's is ~1e-7 (the swing of the bit
#: speed's round-off and blade passes), which left the all-zero note off an SSI panel of
#: no stick-slip (a new user's check); 0.001 is a swing of 0.1 % of the mean speed.
NO_SWING_SSI = 1e-3
#: (column, axis label, scale, what a panel whose values are all zero says) of the bar
#: chart: an empty panel says so instead of looking like a broken plot.
BARS = (("ssi", "stick-slip severity (SSI)", 1.0,
         f"no stick-slip in any episode (SSI under {NO_SWING_SSI:g})"),
        ("stuck_fraction", "time stuck (% of the measured window)", 100.0,
         "the bit never stuck in any episode"),
        ("rop_m_per_h", "ROP (m/h)", 1.0, "no penetration in any episode"),
        ("backward_whirl_fraction", "time in backward whirl (% of the window)", 100.0,
         "no backward whirl in any episode"))

#: The values each metric of :data:`BARS` can take (its column's unit), at whose ends a
#: whisker is cut: over few seeds the interval of the mean reaches past them (t = 12.7
#: for two), and an evaluation of two seeds drew time stuck to 175 % (a new user's
#: check). The table's +- and benchmark.csv keep the interval whole. (ROP: a depth of cut
#: per forward turn.)
LIMITS = {"ssi": (0.0, math.inf), "stuck_fraction": (0.0, 1.0),
          "rop_m_per_h": (0.0, math.inf), "backward_whirl_fraction": (0.0, 1.0),
          "episode_return": (-math.inf, math.inf)}
#: The return's panel, which a task benchmark's chart adds to :data:`BARS`: an
#: evaluation is judged by it, and without it the chart could not show who won (a new
#: user's trial: a tiny policy's loss to the best constant, -33 against 82, was not in it).
RETURN_BAR = ("episode_return", "episode return (higher is better)", 1.0,
              "every episode's return is zero")
#: Room above (and, for the return, below) the tallest bar or seed's dot in a panel: a
#: whisker reaching past it is cut at the panel's edge and marked (two seeds' interval,
#: t = 12.7, drew an SSI to 8.3 and flattened every bar under 1.4: a new user's trial).
HEADROOM = 0.15

#: The colour (tab10's) of each built-in name in every picture: the classical drives, the
#: driller, the shipped policy and the trivial policies of an evaluation (a new user's
#: trial: held-1 was pink in an evaluation and grey in a benchmark). Other names take one
#: from their name (:func:`_colours`).
COLOURS = {"stiff": 0, "soft-speed": 1, "soft-torque": 2, "z-torque": 3, "driller": 4,
           "learned": 5, "held-1": 6, "held+0": 7, "held+1": 8, "random": 9}
#: Dash patterns by a controller's place in the list, so that lines which coincide (the
#: tuned controllers at a speed where none is needed) still all show; six, so that a
#: policy and its five baselines all differ (with four, the first and fifth, a policy
#: and ZTorque, were both solid, in brown and red).
DASHES = ("-", (0, (6, 3)), (0, (2, 2)), (0, (8, 2, 2, 2)), (0, (12, 3)),
          (0, (4, 2, 1, 2, 1, 2)))


#: Last radial position / clearance above which the series chart says that a drift alike
#: under every controller (ends within a factor 1.5, each still rising: up 20 % in the
#: last 5 s) is not theirs.
SAME_DRIFT = 0.05
#: Radial position / clearance below which the series chart says the bit stayed on the
#: hole axis: a line that close to zero is hidden by the axis line (the panel spans >= 0.2).
ON_AXIS = 1e-3


def save(fig: Any, path: Path) -> None:
    """``fig`` as a PNG at ``path`` (:func:`drill_env.sweep.save_whole`): an interrupt
    leaves the old picture whole (benchmark.md links it), never a torn one. The figures
    here are matplotlib ``Figure`` objects, not pyplot's: drawing them neither switches
    the process's backend (a notebook's inline plots went blank after a benchmark) nor
    leaves figures open."""
    from drill_env.sweep import save_whole

    save_whole(path, lambda file: fig.savefig(file, dpi=110, format="png"))


def _say_empty(ax: Any, text: str) -> None:
    """Write ``text`` across the middle of a panel that has nothing to show."""
    ax.text(0.5, 0.5, text, transform=ax.transAxes, ha="center", va="center", fontsize=10,
            color="0.3", wrap=True, bbox={"boxstyle": "round", "fc": "white", "ec": "0.7"})


#: Least RGB distance (0-1 per channel) of a colour taken for a name without its own from
#: every colour taken before it: tab20b's gold-brown beside the policy's brown (0.14 apart)
#: could not be told from it in a legend of thirteen (a check of the pictures).
DISTINCT = 0.2
#: The colours a name without its own draws from first (Dark2's teal, magenta and green,
#: tab20b's two darkest blues): dark enough for the line of a policy or controller under
#: study, each at least DISTINCT from tab10's and from one another (Dark2's gold-brown,
#: 0.24 from the policy's brown, read as it in a series picture).
OWN_COLOURS = ("#1b9e77", "#e7298a", "#393b79", "#66a61e", "#525aa3")


def _colours(controllers: Sequence[str]) -> dict[str, Any]:
    """Each controller's colour: its own (:data:`COLOURS`), else one its name draws
    (CRC-32) from :data:`OWN_COLOURS`, so that a set point, a run or a controller of your
    own has the same colour in every picture; where two such names of one picture draw
    the same, the later takes the next one free (once all five are taken, tab20b's colours
    at least :data:`DISTINCT` from all before them, then its others, in turn)."""
    from matplotlib.colors import to_rgba

    cmap = matplotlib.colormaps["tab10"]
    extra = matplotlib.colormaps["tab20b"]
    own = [to_rgba(c) for c in OWN_COLOURS]
    candidates = [extra(4 * (k % 5) + k // 5) for k in range(20)]  # a hue apart, then shades
    candidates = [c for c in candidates  # (less the two of them among the five)
                  if min(np.linalg.norm(np.subtract(c, o)) for o in own) > 1e-3]
    taken = [np.array(c[:3]) for c in [*map(cmap, COLOURS.values()), *own]]
    after = []
    for colour in candidates:
        if min(float(np.linalg.norm(np.array(colour[:3]) - t)) for t in taken) >= DISTINCT:
            after.append(colour)
            taken.append(np.array(colour[:3]))
    after += [c for c in candidates if c not in after]
    out, used, n = {}, set(), 0
    for c in controllers:
        if c in COLOURS:
            out[c] = cmap(COLOURS[c])
            continue
        first = zlib.crc32(c.encode()) % len(own)
        free = [own[(first + k) % len(own)] for k in range(len(own))]
        out[c] = next((colour for colour in free if colour not in used), None) or \
            after[n % len(after)]
        n += out[c] in after
        used.add(out[c])
    return out


#: Most entries in a row of a picture's legend.
LEGEND_ROW = 6


def bar_chart(rows: Sequence[dict[str, Any]], controllers: Sequence[str],
              scenarios: Sequence[str], path: Path, title: str = "Controller benchmark",
              with_return: bool = False) -> None:
    """One panel per metric (``with_return``: the episode return's too, a task
    benchmark's); bars per controller, grouped by scenario, with the whisker of the
    table's 95 % interval of the mean and a dot per seed (in seed order across the bar);
    an SSI bar of a stick-slip still growing in the window, or of a bit that drilled
    nothing, is marked. A panel's scale is its bars' and dots' (:data:`HEADROOM`): a
    whisker past it is cut at the edge, with an arrowhead there.
    ``title``: what the benchmark was (benchmark.md's heading: its --config file, the set
    points given on the command line, a task and its seeds)."""
    from agents.tables import growing, mean_interval, not_drilling

    colours = _colours(controllers)
    panels = (*BARS, RETURN_BAR) if with_return else BARS
    # two by two, not four in a row: shrunk to a page's width (~800 px) the row's text was
    # ~6 px high (a check of the pictures); the return's fifth panel makes it three wide
    fig = agg_figure(figsize=(15.0, 8.4) if with_return else (11.0, 8.4))
    axes = fig.subplots(2, 3 if with_return else 2).ravel()
    for spare in axes[len(panels):]:
        spare.set_axis_off()
    width = 0.8 / max(len(controllers), 1)
    for ax, (key, label, scale, empty) in zip(axes, panels, strict=False):
        shown: list[float] = []
        bars: list[tuple[float, float, str]] = []  # (x, mean, colour)
        whiskers: list[tuple[float, float, float, float]] = []  # (x, mean, low, high)
        marked = False  # a bar's word above it ("growing"): more room over the bars
        for i, c in enumerate(controllers):
            for j, s in enumerate(scenarios):
                sel = [r for r in rows if r["controller"] == c and r["scenario"] == s]
                values = np.array([r[key] for r in sel], float)
                if values.size == 0:
                    continue
                mean = float(values.mean()) * scale
                shown += list(values)
                x = j + (i - (len(controllers) - 1) / 2) * width
                ax.bar(x, mean, width * 0.9, color=colours[c],
                       label=c if j == 0 else None)
                bars.append((x, mean, colours[c]))
                # the table's marks: a stick-slip still building that the window's SSI
                # does not show yet (agents.episode.window_swing_trend), a bit that
                # drilled nothing (its SSI 0: no swing of a bit that never turns)
                said = [word for word, hit in (("growing", growing),
                                               ("not drilling", not_drilling))
                        if key == "ssi" and any(hit(r) for r in sel)]
                if said:
                    marked = True
                    ax.annotate(", ".join(said), (x, mean), xytext=(0, 4),
                                textcoords="offset points", rotation=90, ha="center",
                                va="bottom", fontsize=8, color=colours[c])
                if half := mean_interval(values) * scale:  # the table's +- (its 95 %
                    # interval of the mean: the dots are the seeds, this what they say),
                    # cut at the metric's range (two seeds' drew 175 % stuck)
                    low, high = (scale * end for end in LIMITS[key])
                    whiskers.append((x, mean, max(low, mean - half), min(high, mean + half)))
                if values.size > 1:  # each seed a dot: a min-max whisker of 20 seeds
                    # drew one outlier as the spread of all (a check of the pictures)
                    spread = np.linspace(-0.25, 0.25, values.size) * width
                    ax.scatter(x + spread, values * scale, s=7, color="k", alpha=0.6,
                               linewidths=0, zorder=4)
        # slanted where many: ten scenarios' names ran into each other in a panel; "the
        # random scenario", not "random" alone under every group of bars, which read as
        # the random policy (a new user's trial)
        ax.set_xticks(range(len(scenarios)), [f"{s} scenario" for s in scenarios],
                      **({"rotation": 30, "ha": "right"} if len(scenarios) > 4 else {}))
        ax.set_title(label, fontsize=10)
        ax.grid(axis="y", alpha=0.3)
        drawn = np.array([m for _, m, _ in bars] + [scale * v for v in shown], float)
        drawn = drawn[np.isfinite(drawn)]
        top = max(float(drawn.max()) if drawn.size else 0.0, 0.0)
        bottom = min(float(drawn.min()) if drawn.size else 0.0, 0.0)
        span = top - bottom
        room = (3.0 if marked else 1.0) * HEADROOM
        top, bottom = top + room * span, bottom - (HEADROOM * span if bottom < 0 else 0.0)
        ax.set_ylim(bottom, max(top, bottom + 0.05))  # an all-zero metric shows as zero
        _whiskers(ax, whiskers)
        negligible = NO_SWING_SSI if key == "ssi" else 0.0
        if np.all(np.abs(np.nan_to_num(shown)) <= negligible):  # all zero (or not defined)
            _say_empty(ax, empty if key != "ssi" or not any(map(not_drilling, rows))
                       else "no swing in any episode (some did not drill)")
            ax.set_yticks([])  # no scale: 0-0.05 ticks read as small measured values
        else:  # a bar too low to see is drawn as a coloured base line: zero, not missing
            lowest, highest = ax.get_ylim()
            for x, mean, colour in bars:
                if abs(mean) < 0.01 * (highest - lowest):
                    ax.hlines(0.0, x - 0.45 * width, x + 0.45 * width, colors=colour, lw=4,
                              clip_on=False, zorder=3)
            if lowest < 0.0:
                ax.axhline(0.0, color="k", lw=0.8, zorder=2)
    handles, labels = axes[0].get_legend_handles_labels()
    # in rows of at most six (as the series chart's): thirteen controllers in one row ran
    # off both sides of the picture
    lines = max(1, math.ceil(len(labels) / LEGEND_ROW))
    fig.legend(handles, labels, loc="lower center", ncol=math.ceil(len(labels) / lines),
               fontsize=9, frameon=False)
    # the key wrapped as the title is: one line of it ran off both sides of the
    # two-panel-wide picture (a review)
    reading = ("bars: seed means; whiskers: the table's 95 % interval, cut at the metric's "
               "range and at the panel's edge (an arrowhead: it goes on); dots: each seed; "
               "a coloured base line alone: about zero")
    wide = 140 if with_return else 100
    fig.suptitle(f"{balanced_fill(title, wide)}\n{balanced_fill(reading, wide)}")
    fig.tight_layout(rect=(0.0, 0.035 * lines + 0.01, 1.0, 1.0))
    save(fig, path)


def _whiskers(ax: Any, whiskers: Sequence[tuple[float, float, float, float]]) -> None:
    """Each (x, mean, low, high) as a whisker cut at the panel's edges, with an
    arrowhead at an edge it reaches past (the interval goes on: benchmark.md has it)."""
    lowest, highest = ax.get_ylim()
    for x, mean, low, high in whiskers:
        down, up = max(low, lowest), min(high, highest)
        # (none past a mean that lies outside the range itself: matplotlib refuses a
        # negative length)
        ax.errorbar(x, mean, yerr=[[max(0.0, mean - down)], [max(0.0, up - mean)]],
                    color="k", capsize=3, linewidth=1.0, zorder=5)
        for end, edge, marker in ((high, highest, "^"), (low, lowest, "v")):
            if (end > edge) if marker == "^" else (end < edge):
                ax.plot([x], [edge], marker=marker, color="k", markersize=6,
                        clip_on=False, zorder=6)


#: Bit-speed swing (:func:`_swing`, rad/s) above which a series line is drawn
#: translucent: 50 rpm, above a controller's transient after a change of target (up to
#: ~30 rpm in task 1's picture), below a stick-slip band (the bit stopping, then running
#: at up to twice its speed).
SWINGING = 50 * RPM


def _swing(t: np.ndarray, speed: np.ndarray, warmup: float) -> float:
    """How widely ``speed`` swings most of the time after ``warmup``: the median over 5 s
    blocks of each block's range (a stick-slip cycle of up to 5 s fills a block; a change
    of target moves one block only)."""
    measured = speed[t >= warmup]
    if measured.size < 2:
        return 0.0
    dt = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    n = max(1, round(5.0 / dt)) if dt > 0 else measured.size
    blocks = measured[:measured.size // n * n].reshape(-1, n) if measured.size >= n \
        else measured[None, :]
    finite = np.isfinite(blocks).any(axis=1)  # a diverged episode's last samples are NaN
    if not finite.any():
        return 0.0
    blocks = blocks[finite]
    return float(np.median(np.nanmax(blocks, axis=1) - np.nanmin(blocks, axis=1)))


def balanced_fill(text: str, width: int) -> str:
    """``text`` in as few lines of at most ``width`` characters as ``textwrap`` needs, of
    even length: a title one word longer than a line no longer leaves the word alone on
    its second line ("... physics level" / "fast")."""
    lines = textwrap.wrap(text, width)
    for narrower in range(math.ceil(len(text) / max(len(lines), 1)), width):
        even = textwrap.wrap(text, narrower)
        if len(even) <= len(lines):
            return "\n".join(even)
    return "\n".join(lines)


def series_chart(series_dir: Path, controllers: Sequence[str], scenario: str, path: Path,
                 warmup: float, env_id: str | None = None, seed: int = 0,
                 stamps: Mapping[str, str] | None = None, title: str = "") -> bool:
    """Bit speed, surface torque, torque on bit and the bit's radial position over the gauge
    clearance, one line per controller (``seed``: the benchmark's first), on one time
    axis; the grey band is the warm-up the metrics leave out. Returns whether it drew:
    False (no file written) when ``series_dir`` holds no series of ``scenario``.
    ``env_id``: the task env every controller acted in (its title names it; None: the
    scenario's ``DrillString-v0``); ``stamps``: the stamp each controller's file must
    carry (another run's is left out); ``title``: a first title line (the benchmark's
    heading), if any."""
    colours = _colours(controllers)
    # the surface torque is what a drive-rate loop does (a controls engineer's check: the
    # picture showed the bit alone, not the drive's torque that cures or feeds it)
    fig = agg_figure(figsize=(11, 10))
    axes = fig.subplots(4, 1, sharex=True)
    found = False
    drawn: list[tuple[int, float, list[Any]]] = []  # (order given, bit-speed swing, lines)
    off_axis = 0.0  # the largest radial position drawn
    ends: list[tuple[float, float]] = []  # each one's radial position 5 s before the end, last
    target: list[Any] = []  # the planned rpm's line
    for k, c in enumerate(controllers):
        file = Path(series_dir) / f"{c}_{scenario}_seed{seed}.npz"
        if not file.exists():
            continue
        d = np.load(file)
        if stamps is not None and ("stamp" not in d.files
                                   or str(d["stamp"]) != stamps.get(c)):
            continue
        found = True
        t = d["time"]
        radial = np.hypot(d["bit_x"], d["bit_y"]) / float(d["clearance"])
        off_axis = max(off_axis, float(np.nanmax(radial, initial=0.0)))
        before = radial[t <= t[-1] - 5.0]  # 5 s before the end: still drifting?
        ends.append((float(before[-1]) if before.size else math.nan, float(radial[-1])))
        kw = {"color": colours[c], "lw": 0.8, "label": c, "ls": DASHES[k % len(DASHES)]}
        if "target_time" in d and k == 0:  # the planned rpm (a task's drawn targets)
            target += axes[0].step(d["target_time"], d["target_rpm"], where="post",
                                   color="k", lw=1.0, ls=(0, (1, 1)), label="target")
        swing = _swing(t, d["bit_speed"], warmup)
        drawn.append((k, swing, [axes[0].plot(t, d["bit_speed"] / RPM, **kw)[0],
                                 axes[1].plot(t, d["surface_torque"] / 1e3, **kw)[0],
                                 axes[2].plot(t, d["torque_on_bit"] / 1e3, **kw)[0],
                                 axes[3].plot(t, radial, **kw)[0]]))
    if not found:
        return False
    # the first controller on top (a policy before its baselines), the others the steadier
    # above the wider swinging: a stick-slip band drawn over a steady line hid it (the
    # driller's 140 rpm inside stiff PI's 0-190 rpm swing)
    bottom_up = sorted(drawn, key=lambda item: (item[0] == 0, -item[1]))
    # bands of stick-slip let the lines behind them show through, the more of them the
    # more (an evaluation's eleven controllers, four in stick-slip, made one solid band
    # that hid the policy and its target: a new user's check)
    bands = sum(swing > SWINGING for _, swing, _ in drawn)
    for z, (k, swing, lines) in enumerate(bottom_up):
        for line in lines:
            line.set_zorder(2 + z)
            if swing > SWINGING:
                line.set_alpha(0.55 if bands <= 2 else 0.3)
            if k == 0 and len(drawn) > 4:  # the first (a policy) stands out among many
                line.set_linewidth(1.4)
    for line in target:  # above the bands, under the first controller
        line.set_zorder(1.5 + len(drawn) - 1)
    # the smallest span each axis shows (rpm, kN m, -): a steady run is a flat line,
    # not its last digits magnified into what looks like an oscillation
    spans = (20.0, 1.0, 1.0, 0.2)
    for ax, label, span in zip(axes, ("bit speed (rpm)", "surface torque (kN m)",
                                      "torque on bit (kN m)",
                                      "bit radial position / clearance"), spans,
                               strict=True):
        ax.set_ylabel(label)
        low, high = ax.get_ylim()
        if high - low < span:
            middle = 0.5 * (low + high)
            ax.set_ylim(middle - 0.5 * span, middle + 0.5 * span)
        ax.ticklabel_format(axis="y", useOffset=False)
        ax.axvspan(0.0, warmup, color="0.85", zorder=0)
        ax.grid(alpha=0.3)
    axes[3].set_ylim(bottom=0.0)  # a distance
    last = [end for _, end in ends]
    if len(ends) > 1 and min(last) > SAME_DRIFT and max(last) < 1.5 * min(last) and all(
            end > 1.2 * earlier for earlier, end in ends):  # (NaN: too short to tell)
        # a rise at the end that reads as a lateral instability of the controllers (a
        # controls engineer's check): one alike under all of them is not of their making
        axes[3].text(0.01, 0.95, "alike under every controller: not of their making (the "
                     "demo's: a compressed BHA leaning onto its stabilizers; "
                     "docs/model.md)", transform=axes[3].transAxes,
                     ha="left", va="top", fontsize=8, color="0.3")
    if off_axis < ON_AXIS:  # the lines lie on the axis line: say so
        _say_empty(axes[3], f"the bit stays on the hole axis (less than {ON_AXIS:.1%} of "
                            "the clearance off it) under every controller")
    # above the plots, in rows of at most six: a sweep of constant set points has dozens
    entries = len(axes[0].get_legend_handles_labels()[1])
    rows = math.ceil(entries / LEGEND_ROW)  # rows as even as they come: 7 -> 4 + 3
    axes[0].legend(fontsize=8, ncol=math.ceil(entries / rows), loc="lower center",
                   bbox_to_anchor=(0.5, 1.0), frameon=False)
    axes[-1].set_xlabel("time (s)")
    where = f"{env_id} on the {scenario} scenario" if env_id else scenario
    fig.suptitle((f"{balanced_fill(title, 110)}\n" if title else "") + f"{where}: every "
                 "controller from the "
                 "same start and targets (first seed; grey: warm-up, not in the metrics)",
                 fontsize=11)
    fig.tight_layout()
    save(fig, path)
    return True
