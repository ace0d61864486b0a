"""The benchmark's outputs: ``benchmark.csv`` (the SPEC's columns), the summary table of
``benchmark.md`` with its marks and footnotes (own speed, growing, not drilling), the
conditions it ran under, and the pictures.
"""

from __future__ import annotations

import csv
import io
import math
from collections import Counter
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from agents.settings import BenchmarkSettings
from drill_env.physics.units import HOUR, KILO, RPM, few, shown
from drill_env.sweep import save_text

#: benchmark.csv columns, in order (the spec's section 5; meanings in docs/controllers.md);
#: units in the names.
COLUMNS = ("controller", "scenario", "seed", "ssi", "stuck_fraction", "mean_bit_rpm",
           "target_rpm", "rpm_tracking_error", "rop_m_per_h", "radial_ratio",
           "backward_whirl_fraction", "max_lateral_force_kN", "mse_MPa",
           "top_drive_energy_MJ", "episode_return")
#: Channels kept for the time-series plots (every record sample of seed 0).
SERIES_CHANNELS = ("time", "bit_speed", "surface_speed", "torque_on_bit", "surface_torque",
                   "bit_x", "bit_y", "weight_on_bit")
#: The time-series picture of a scenario, beside benchmark.md.
SERIES_PICTURE = "benchmark_{scenario}_series.png"
#: The start of a row's ``swing_trend`` where the trend was not judged, and why.
NOT_JUDGED = "not judged: "
SET_POINT_MOVED = NOT_JUDGED + "a set point moved"
ROCK_CHANGED = NOT_JUDGED + "the rock under the bit changed"


# --------------------------------------------------------------------------- outputs


def write_csv(rows: Sequence[dict[str, Any]], path: Path) -> None:
    text = io.StringIO()
    writer = csv.writer(text)
    writer.writerow(COLUMNS)
    for row in rows:
        writer.writerow([csv_value(row[c]) for c in COLUMNS])
    save_text(path, text.getvalue(), newline="")  # an interrupt leaves the old file whole


def csv_value(value: Any) -> Any:
    return f"{value:.6g}" if isinstance(value, float) else value


#: Columns of the summary table: (column, header, format).
SUMMARY = (("ssi", "SSI", "{:.2f}"), ("stuck_fraction", "stuck", "{:.0%}"),
           ("mean_bit_rpm", "bit rpm", "{:.1f}"), ("rpm_tracking_error", "rpm error", "{:.1%}"),
           ("rop_m_per_h", "ROP m/h", "{:.1f}"),
           ("backward_whirl_fraction", "bwd whirl", "{:.0%}"),
           ("max_lateral_force_kN", "max lat. kN", "{:.1f}"), ("mse_MPa", "MSE MPa", "{:.0f}"),
           ("top_drive_energy_MJ", "TD MJ", "{:.2f}"), ("episode_return", "return", "{:.1f}"))
#: The mark on the "rpm error" of a controller that sets its own speed, and its footnote.
OWN_SPEED_MARK = "\N{DAGGER}"
OWN_SPEED_NOTE = (f"{OWN_SPEED_MARK} sets its own speed (the driller, constant set "
                  "points, the drilling task's policy, the trivial policies outside task "
                  "1): its rpm error is how far its mean "
                  "bit rpm departed from the planned rpm (the scenario's or task's target), "
                  "by its choice, not a failure to track it (docs/controllers.md).")


#: What the "return" of a scenario benchmark is, and is not (a controls engineer sorting
#: by it picked the driller, which stick-slipped and ran 93 % off the planned rpm).
RETURN_NOTE = ("return: DrillString-v0's reward summed over the episode: ROP pays, "
               "stick-slip, whirl and set-point changes cost, and an episode that ends early "
               "costs the failure weight and its cut-off steps at its worst step "
               "(docs/controllers.md); a "
               "controller that drills faster off the plan can lead it while it stick-slips: "
               "judge stick-slip control by the SSI and stuck columns.")


#: Beside the seed count of a controller some of whose episodes a failure ended (make-up
#: torque, divergence): their rows hold the metrics until then (benchmark.md lists them).
ENDED_EARLY_MARK = "ended early"


#: Beside the seed count of a controller some of whose episodes' bit-speed swing grows
#: from the warm-up into the metric window (:func:`window_swing_trend`).
GROWING_MARK = "growing"


#: Beside the seed count of a controller some of whose episodes did not drill in the
#: metric window (:func:`not_drilling`): their SSI and MSE say nothing (a metrics audit:
#: a bit held at 0 rpm and 200 kN read SSI 0.00 and MSE 5 MPa, the best of its table).
NOT_DRILLING_MARK = "not drilling"


def not_drilling(row: Mapping[str, Any]) -> bool:
    """Whether a row's bit drilled nothing in its metric window (mean ROP under the MSE's
    floor, :data:`~drill_env.metrics.MSE_MIN_ROP`): a bit that never turns has no swing
    (SSI 0) and an MSE of the thrust term alone (WOB / A). A NaN ROP (a row of a broken
    episode) is not judged: its cells read nan."""
    from drill_env.metrics import MSE_MIN_ROP

    return float(row["rop_m_per_h"]) / HOUR < MSE_MIN_ROP


def not_judged(rows: Sequence[Mapping[str, Any]]) -> str:
    """Where :func:`window_swing_trend` judged nothing, in words ("" where it judged every
    row it saw): per reason, the episodes by controller and scenario."""
    words = []
    for reason, why in ((SET_POINT_MOVED, "(a policy's action or a target)"),
                        (ROCK_CHANGED, "(a layer crossed raises the swing by itself)")):
        hit = Counter(f"{r['controller']} on {r['scenario']}" for r in rows
                      if r.get("swing_trend") == reason)
        if hit:
            words.append(f"{reason.removeprefix(NOT_JUDGED)} {why}: " + ", ".join(
                f"{where} ({n} episode{'' if n == 1 else 's'})" for where, n in hit.items()))
    return "; or where ".join(words)


def growing(row: Mapping[str, Any]) -> bool:
    """Whether a row's stick-slip was still growing in its metric window (rows stored
    before the trend was kept have none)."""
    from drill_env.swing import is_growing

    return is_growing(str(row.get("swing_trend", "")))


#: The task whose policy chooses the rpm (task 2); task 1's corrects the top drive around
#: the driller's target, which it tracks.
CHOOSES_RPM = "DrillOptimise-v0"
#: The task whose action corrects the top drive's speed around the driller's target.
CORRECTS_SPEED = "DrillStickSlip-v0"


def sets_own_speed(name: str, env_id: str | None = None) -> bool:
    """Whether the controller of table name ``name`` (:func:`~agents.settings.labels`)
    chooses its own rpm instead of holding the planned one: the driller, constant set
    points, a learned policy in a benchmark of the drilling task (``env_id``), and the
    trivial policies (held actions, random) in any env but task 1's."""
    if name == "driller" or name.startswith("constant-"):
        return True
    from agents.trivial import HeldAction

    if name == "random" or HeldAction.from_label(name) is not None:
        # on the env's own action: the rpm everywhere but in task 1, where it corrects
        # the speed around the driller's target
        return env_id != CORRECTS_SPEED
    return env_id == CHOOSES_RPM and is_learned_label(name)


def is_learned_label(name: str) -> bool:
    """Whether a row label (:func:`~agents.settings.labels`) is a trained policy's: ``learned``, or
    ``learned-<run>`` where several runs are benchmarked."""
    return name == "learned" or name.startswith("learned-")


#: What the tables' "+-" is, said under each of them (benchmark.md, the screen).
SPREAD_NOTE = ("Means over seeds, +- the half-width of their 95 % interval (Student's t "
               "over the seeds; none for one seed).")


def mean_interval(values: np.ndarray) -> float:
    """The half-width of the two-sided 95 % interval of the mean of ``values`` over seeds:
    t(0.975, n - 1) s / sqrt(n); 0 for one value, and where one is not finite (nor is the
    mean beside it: no interval over fewer seeds than the cell counts). An uncertainty of
    the mean, which narrows as seeds are added: half the range, shown until 2026-12-06,
    was a spread that widens with them (a statistician's review). A metric bounded below
    (a stuck share, an SSI) can show an interval reaching past its bound where seeds are
    few and skewed; the rows are in benchmark.csv."""
    values = np.asarray(values, dtype=float)
    if values.size < 2 or not np.isfinite(values).all():
        return 0.0
    from scipy.stats import t

    return float(t.ppf(0.975, values.size - 1) * np.std(values, ddof=1)
                 / math.sqrt(values.size))


def summary_table(rows: Sequence[dict[str, Any]], controllers: Sequence[str],
                  scenarios: Sequence[str], env_id: str | None = None) -> list[list[str]]:
    """Per scenario and controller: the mean over seeds (+- its 95 % interval,
    :func:`mean_interval`, when seeds differ);
    the rpm error of a controller that sets its own speed is marked (the rows' ``own_speed``,
    judged in the env each acted in; rows without it: in ``env_id``)."""
    table = []
    for s in scenarios:
        for c in controllers:
            sel = [r for r in rows if r["controller"] == c and r["scenario"] == s]
            if not sel:
                continue
            marks = [f"{n} {mark}" for n, mark in (
                (sum(1 for r in sel if r.get("termination")), ENDED_EARLY_MARK),
                (sum(1 for r in sel if growing(r)), GROWING_MARK),
                (sum(1 for r in sel if not_drilling(r)), NOT_DRILLING_MARK)) if n]
            cells = [s, c, str(len(sel)) + (f" ({', '.join(marks)})" if marks else "")]
            for key, _, fmt in SUMMARY:
                values = np.array([r[key] for r in sel], dtype=float)
                if np.isnan(values).all():  # not defined (a zero target's rpm error)
                    cells.append("-")
                    continue
                text = shown(fmt, float(np.mean(values)))
                half = shown(fmt, mean_interval(values))
                if half != shown(fmt, 0.0):  # seeds differ at the shown precision
                    text += " +-" + half
                if key == "rpm_tracking_error" and any(
                        r.get("own_speed", sets_own_speed(c, env_id)) for r in sel):
                    text += " " + OWN_SPEED_MARK
                cells.append(text)
            table.append(cells)
    return table


def given_set_points(settings: BenchmarkSettings) -> str:
    """The set points a benchmark was given, in words ("" for none)."""
    words = []
    if settings.surface_speed is not None:
        words.append(f"{settings.surface_speed / RPM:g} rpm")
    if settings.weight_on_bit is not None:
        words.append(f"{settings.weight_on_bit / KILO:g} kN")
    if not words:
        return ""
    rest = "" if len(words) == 2 else " (the other set point each scenario's)"
    return f"the set points {' and '.join(words)} in every scenario{rest}"


#: Up to this many ``--config`` overrides are listed with their values in benchmark.md's
#: first line; more (a string file) by section, with a count.
LISTED_OVERRIDES = 8


def overrides_in_words(physics: Mapping[str, Any]) -> str:
    """``--config``'s overrides in words: each key with its value (a list by its length),
    or, past :data:`LISTED_OVERRIDES` keys, each section with its count. A controls
    engineer's check: "config overrides of top_drive" hid a SoftSpeed row run at k = 1 on
    a 2,000 kg m^2 top drive."""
    from drill_env.physics.config import flatten

    flat = flatten(dict(physics))
    if len(flat) > LISTED_OVERRIDES:
        sections = Counter(key.split(".")[0] for key in flat)
        return "of " + ", ".join(f"{name} ({count} keys)" if count > 1 else name
                                 for name, count in sorted(sections.items()))

    def value(v: Any) -> str:
        if isinstance(v, (list, tuple)):
            return f"a list of {len(v)}"
        return f"{v:g}" if isinstance(v, float) else str(v)

    return ", ".join(f"{key} = {value(v)}" for key, v in sorted(flat.items()))


def conditions(settings: BenchmarkSettings, env_id: str | None = None,
               guests: bool = False) -> str:
    """What every episode of a benchmark shares, in words (benchmark.md's first line);
    ``guests``: a task's policy ran in a scenario benchmark."""
    window = (f"metrics over the last {settings.duration - settings.warmup:g} s; physics "
              f"level {settings.fidelity}"
              + ("; config overrides (--config) " + overrides_in_words(settings.physics)
                 + " merged into every scenario"
                 + (", over the task settings' own" if env_id else "")
                 if settings.physics else "")
              + ". " + SPREAD_NOTE + " Rows: benchmark.csv.")
    if env_id is None:
        at = given_set_points(settings) or "each scenario's set points"
        return (f"{settings.duration:g} s episodes of DrillString-v0 from the settled state "
                f"(torsionally with the wall's friction; laterally at rest on the wall in a "
                f"curved hole, straight on the axis in a vertical one, from where a "
                f"compressed BHA drifts sideways until its stabilizers rest on the wall, the "
                f"bit held within the near-bit stabilizer's clearance (0.32 of its own on the "
                f"default BHA), no whirl: the slow drift of the bit's radial position in the "
                f"series; docs/model.md) "
                f"at {at} (bit speed kicked by up to {settings.start_kick:.0%} by the seed"
                + ("; a task's policy acts in its task's env from the same start and set "
                   "points, its return DrillString-v0's reward of its episode" if guests
                   else "") + f"); {window}")
    from drill_env.vector import registered

    env_class, kwargs = registered(env_id)
    config = settings.env_kwargs.get("config") or {}
    startup = settings.env_kwargs.get("startup") or config.get("startup") or kwargs.get(
        "startup") or getattr(env_class, "env_defaults", {}).get("startup", "settled")
    trained = ", ".join(f"{k} {v}" for k, v in sorted(settings.env_kwargs.items()))
    return (f"{settings.duration:g} s episodes of {env_id}: its own start ({startup}) and "
            f"targets, drawn from each seed (and changed during the episode where the task "
            f"does), the same for every controller of a seed"
            + (f"; every controller under these task settings (the learned policies' "
               f"training settings, --string-lengths): {trained}" if trained else "")
            + f"; {window}")


def write_outputs(rows: Sequence[dict[str, Any]], out: Path, controllers: Sequence[str],
                  scenarios: Sequence[str], settings: BenchmarkSettings,
                  env_id: str | None = None, heading: str = "Controller benchmark",
                  first_seed: int = 0, runs: Mapping[str, str] | None = None,
                  stamps: Mapping[tuple[str, str], str] | None = None) -> None:
    """benchmark.csv, benchmark.md and the plots (the series of ``first_seed``); prints
    the table; ``runs``: the run folder of each ``learned:PATH`` row, by its label;
    ``stamps``: the stamp each (label, scenario) series must carry to be drawn. The
    series pictures of an earlier benchmark into ``out``
    (``benchmark_<scenario>_series.png``) are removed: beside benchmark.md are only this
    benchmark's pictures."""
    write_csv(rows, out / "benchmark.csv")
    header = ["scenario", "controller", "seeds"] + [h for _, h, _ in SUMMARY]
    table = summary_table(rows, controllers, scenarios, env_id)
    notes = [OWN_SPEED_NOTE] if any(OWN_SPEED_MARK in r[header.index("rpm error")]
                                    for r in table) else []
    # a variant's weights said beside its returns (read as the task's own reward: an
    # outside trial)
    changed = ", ".join(f"{k} {v}" for k, v in sorted(settings.env_kwargs.items()))
    notes.append(RETURN_NOTE if env_id is None else
                 f"return: {env_id}'s reward summed over the episode (docs/tasks.md)"
                 + (f", under the task settings {changed}." if changed else "."))
    if any(is_learned_label(c) for c in controllers):  # the row labels (labels())
        notes.append("Sensors: a learned policy reads its env's observation (in the tasks "
                     "surface history and delayed mud-pulse telemetry) once per control "
                     "step; the classical drives read the surface speed and torque at every "
                     "solver step (docs/controllers.md).")
    if runs:  # which model a row is (a plain label does not say it)
        notes.append("Trained runs: " + "; ".join(f"{name}: the policy of {path}"
                                                  for name, path in runs.items()) + ".")
    failed = [r for r in rows if r.get("termination")]
    if failed:  # on screen too: only benchmark.md's last line said it
        notes.append("Episodes that ended early (metrics until then): " + few(
            [f"{r['controller']}/{r['scenario']}/{r['seed']} ({r['termination']})"
             for r in failed], "in benchmark_results.jsonl's termination field") + ".")
    building = [r for r in rows if growing(r)]
    if building:  # SSI 0.00 in the window of a loop that stick-slips a minute later
        notes.append("Growing: the bit-speed swing of the metric window exceeds the one "
                     "before it by more than 10 %, a stick-slip still building that the "
                     "window's SSI and stuck share may not show yet; follow it in a longer "
                     "run (drill-env run --duration 240 prints the swing per 30 s): "
                     + few([f"{r['controller']}/{r['scenario']}/{r['seed']} "
                            f"({r['swing_trend'].removeprefix('growing (').removesuffix(')')})"
                            for r in building], "in benchmark_results.jsonl's swing_trend")
                     + ".")
    idle = [r for r in rows if not_drilling(r)]
    if idle:
        notes.append("Not drilling: the bit drilled nothing in the metric window, so its SSI "
                     "(0 for a bit that never turns) and MSE (the thrust term WOB / A alone) "
                     "say nothing of vibration or efficiency; the stuck share and ROP do: "
                     + few([f"{r['controller']}/{r['scenario']}/{r['seed']}" for r in idle],
                           "with ROP 0 in benchmark.csv") + ".")
    if unjudged := not_judged(rows):  # no mark is not "not growing" (an outside review)
        notes.append("Whether a stick-slip still grows is not judged where, over the "
                     "warm-up's end and the window, " + unjudged + ".")
    print_table(header, table, [*notes, SPREAD_NOTE], title=heading)
    from agents.plots import bar_chart, series_chart

    # the pictures say what benchmark.md's heading says (a --config run read "default")
    given = given_set_points(settings) if env_id is None else ""
    title = heading + (f"; {given}" if given else "")
    bar_chart(rows, controllers, scenarios, out / "benchmark_bars.png", title,
              with_return=env_id is not None)  # a task is judged by its return
    drawn = [s for s in scenarios
             if series_chart(out / "series", controllers, s,
                             out / SERIES_PICTURE.format(scenario=s), settings.warmup,
                             env_id, seed=first_seed,
                             stamps=None if stamps is None else {
                                 c: stamps.get((c, s), "") for c in controllers},
                             title=title)]
    # an earlier benchmark's series pictures go once this one's are drawn (an interrupt
    # before left benchmark.md linking pictures already removed)
    for old in out.glob(SERIES_PICTURE.format(scenario="*")):
        if old.name not in {SERIES_PICTURE.format(scenario=s) for s in drawn}:
            old.unlink()
    guests = any(r.get("guest") for r in rows)
    lines = [f"# {heading}", "", conditions(settings, env_id, guests), "",
             "| " + " | ".join(header) + " |", "|" + " --- |" * len(header)]
    lines += ["| " + " | ".join(r) + " |" for r in table]
    lines += [line for note in notes for line in ("", note)]
    lines += ["", "## Metrics", "", "![metrics](benchmark_bars.png)"]
    # one section per scenario: each picture in its own paragraph, none hidden beside another
    for s in drawn:
        lines += ["", f"## {s}: time series (first seed)", "",
                  f"![{s}]({SERIES_PICTURE.format(scenario=s)})"]
    save_text(out / "benchmark.md", "\n".join(lines) + "\n")


def print_table(header: Sequence[str], table: Sequence[Sequence[str]],
                 notes: Sequence[str] = (), title: str = "Controller benchmark") -> None:
    """The table on screen under ``title`` (benchmark.md's heading: evaluate's grid search
    and its evaluation printed two tables both called "controller benchmark"), every cell
    on one line: on a terminal narrower than the table
    its columns are split over as many tables as it takes, each with the scenario and
    controller (a terminal wrapping the lines of one wide table garbled every row, a
    review; rich folding the cells split figures); in a log or a pipe, one table."""
    from rich.console import Console
    from rich.table import Table

    widths = [max(len(str(cell)) for cell in column) + 3 for column in zip(header, *table,
                                                                            strict=True)]
    console = Console()
    keys = 2  # scenario and controller: in every part
    if not console.is_terminal:
        console.width = max(console.width, sum(widths) + 1)
    parts: list[list[int]] = [[]]
    for k in range(keys, len(header)):
        if parts[-1] and sum(widths[j] for j in [*range(keys), *parts[-1], k]) + 1 \
                > console.width:
            parts.append([])
        parts[-1].append(k)
    for n, part in enumerate(parts):
        t = Table(title=f"{title} (means over seeds)" if n == 0 else None)
        for k in [*range(keys), *part]:
            t.add_column(header[k], no_wrap=True)
        for r in table:
            t.add_row(*(r[k] for k in [*range(keys), *part]))
        console.print(t)
    for note in notes:  # under the tables, as wide as the terminal
        console.print(note, style="dim italic", highlight=False)
