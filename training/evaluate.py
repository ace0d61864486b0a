"""``drill-env evaluate RUN``: a trained policy through the controller benchmark.

The policy (the controller ``learned``, from the run folder), the classical controllers
and the trivial policies (:mod:`agents.trivial`) act in the run's task env on the
held-out seeds (``drill_env.scenarios.EVALUATION_SEEDS``, never used in training or in
choosing a run's model; task 2's recipe was chosen on them, docs/tasks.md "Fresh seeds"
scores the shipped policies on seeds no choice has seen), each from the same targets
and start; the benchmark writes its table, csv and plots to ``RUN/evaluation/``, and
the policy paired by seed against each of the others to ``comparison.md``.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from agents.benchmark import replaced_episode_settings, run_benchmark
from agents.registry import CLASSICAL, TRIVIAL
from agents.settings import BenchmarkSettings, label, task_settings
from drill_env.physics.config import Fidelity
from drill_env.physics.units import shown
from drill_env.scenarios import EVALUATION_SEEDS
from training.config import TASKS, read_run_config

#: Per task: (episode seconds, warm-up seconds the metrics leave out). Task 1 starts with
#: the bit stuck; 5 s lets every controller take hold before the metrics start. Task 2
#: is judged over its whole episode after the first 10 s.
EVALUATION_WINDOWS = {"stick_slip": (30.0, 5.0), "drilling": (300.0, 10.0)}


#: Points per axis of the drilling task's grid search of constant set points: its whole
#: action range (the run's own rpm and WOB ranges) in 5 x 5 steps; the task's default
#: ranges give 40, 80, ..., 200 rpm and 40, 65, ..., 140 kN.
GRID_STEPS = 5
#: Seeds of the training distribution the grid search picks its point on (not held out;
#: the training envs themselves draw from ``training.run_folder.env_seed``).
GRID_SEEDS = tuple(range(8))


#: A policy for one episode: (observation, info) -> action.
Act = Callable[[np.ndarray, dict[str, Any]], np.ndarray]
#: Builds the policy of one episode from (env, seed), after the env's reset.
MakeAct = Callable[[Any, int], Act]


def episode_return(env: Any, make: MakeAct, seed: int) -> float:
    """The return of one episode of ``env`` from ``reset(seed=seed)`` under the policy
    ``make`` builds after that reset (a controller reads the episode's targets and seed)."""
    obs, info = env.reset(seed=seed)
    act = make(env, seed)
    total = 0.0
    while True:
        obs, reward, terminated, truncated, info = env.step(act(obs, info))
        total += float(reward)
        if terminated or truncated:
            return total


def returns_on(env: Any, seeds: list[int] | tuple[int, ...], make: MakeAct) -> np.ndarray:
    """Episode returns on ``seeds`` (paired across policies: the same string, rock and
    targets per seed); ``make`` builds each episode's policy."""
    return np.array([episode_return(env, make, seed) for seed in seeds])


def acting(controller: Any) -> MakeAct:
    """A controller (``reset(env)``, ``act``) as the policy of each episode: the
    registry's, e.g. ``acting(make_controller("held:1"))``, ``acting(RandomActions())``."""
    def make(env: Any, seed: int) -> Act:
        controller.reset(env.unwrapped)
        return controller.act
    return make


def settings_of(task: str, fidelity: Fidelity = "fast") -> BenchmarkSettings:
    duration, warmup = EVALUATION_WINDOWS[task]
    return BenchmarkSettings(duration=duration, warmup=warmup, start_kick=0.02,
                             fidelity=fidelity)


def grid_points(env_kwargs: dict[str, Any]) -> list[tuple[float, float]]:
    """The (rpm, kN) set points of the drilling task's grid search: :data:`GRID_STEPS`
    per axis over the action ranges of the task's env under ``env_kwargs`` (a run trained
    on 60-180 rpm had its evaluation refused at the fixed grid's 40 rpm: an outside
    check), rounded to 0.1 inside the ranges, each point once."""
    import gymnasium as gym

    import drill_env  # noqa: F401  (registers the tasks)

    env: Any = gym.make(TASKS["drilling"], **env_kwargs)
    try:
        cfg = env.unwrapped.config
        (rpm_low, rpm_high), (wob_low, wob_high) = cfg.rpm_range, cfg.weight_on_bit_range
    finally:
        env.close()

    def axis(low: float, high: float, name: str, unit: str) -> list[float]:
        # the ends on the 0.1 grid inside the range (1e-9: 16.1 x 1,000 N is 16.1 kN), each
        # point rounded inside it: an end of 40.04 rpm gave 40, refused as outside
        inner = (math.ceil(low * 10.0 - 1e-9) / 10.0, math.floor(high * 10.0 + 1e-9) / 10.0)
        if inner[0] > inner[1]:
            raise ValueError(f"{name}: the run's range holds no 0.1 {unit} step, which the "
                             "grid search of constant set points needs")
        return [min(max(round(float(v), 1), inner[0]), inner[1])
                for v in np.linspace(low, high, GRID_STEPS)]

    points = [(r, w) for r in axis(rpm_low, rpm_high, "rpm_range", "rpm")
              for w in axis(wob_low / 1e3, wob_high / 1e3, "weight_on_bit_range", "kN")]
    return list(dict.fromkeys(points))  # a range narrower than the steps: each point once


def best_constant(out: Path, workers: int | None = None, progress: bool = True,
                  ray_address: str | None = None, settings: BenchmarkSettings | None = None
                  ) -> tuple[str, list[dict[str, Any]]]:
    """The drilling task's best constant set point: the grid point of highest mean return
    on ``GRID_SEEDS`` (of the training distribution, not held out). Returns its controller
    name and the grid rows.
    ``ray_address``: run the grid on that Ray cluster (the ``distributed`` extra);
    ``settings``: those of the evaluation it is for (default :func:`settings_of`)."""
    settings = settings or settings_of("drilling")
    names = [f"constant:{r:g}/{w:g}" for r, w in grid_points(settings.env_kwargs)]
    rows = run_benchmark(names, ["random"], list(GRID_SEEDS), out, settings,
                         workers=workers, progress=progress, env_id=TASKS["drilling"],
                         ray_address=ray_address,
                         heading=f"Grid search of {len(names)} constant set points on "
                                 f"{len(GRID_SEEDS)} training seeds (the best joins the "
                                 "evaluation)")
    means: dict[str, list[float]] = {}
    for row in rows:
        means.setdefault(row["controller"], []).append(row["episode_return"])
    best = max(means, key=lambda c: sum(means[c]) / len(means[c]))
    if progress:
        print(f"grid search: the best constant set point is {best} (mean return "
              f"{sum(means[best]) / len(means[best]):.1f} over {len(GRID_SEEDS)} seeds)")
    return names[[label(n) for n in names].index(best)], rows


def standard_episode_notes(trained: dict[str, Any], settings: BenchmarkSettings
                           ) -> list[str]:
    """What of the run's ``env_kwargs`` an evaluation replaces by the task's standard
    episode (scenario, length, start kick: the held-out episodes every run of the task is
    scored on), one note each, so that it is said, not done silently."""
    return [f"note: the run trained with {key}={was!r}; evaluate scores it on the "
            f"task's standard held-out episodes ({key}={value!r}), as every run of the task"
            for key, was, value in replaced_episode_settings(trained, settings, "random")]


def paired_comparison(rows: list[dict[str, Any]], policy: str = "learned",
                      column: str = "episode_return") -> list[dict[str, Any]]:
    """The policy's return against every other controller's on the same episodes (paired:
    the same scenario and seed, so the same string, rocks and targets): per controller
    its mean return, the policy's mean lead with its 95 % confidence interval (Student's
    t on the differences), the median lead, on how many episodes it led, the one-sided
    paired t-test p of a positive lead (``scipy.stats.ttest_rel``; NaN with fewer than
    two episodes or no spread in the differences) and that p adjusted by Holm's step-down
    method over the controllers compared (:func:`holm`: the chance that any one of them
    shows a lead by luck, where "the policy beats one of them" is read from the table).
    The returns are often skewed (a few seeds with a large lead): the mean is the
    estimate, the median and the count of wins say what a typical episode does.
    ``column``: the rows' return compared (``window_return``: the steps after the warm-up,
    which the metrics measure); rows without it are left out."""
    from scipy.stats import ttest_rel

    returns: dict[str, dict[tuple[str, int], float]] = {}
    ended: dict[str, set[tuple[str, int]]] = {}  # the episodes a failure ended early
    for row in rows:
        if row.get(column) is None:  # (rows of a version without the window's return)
            continue
        episode = (str(row.get("scenario", "")), int(row["seed"]))
        returns.setdefault(row["controller"], {})[episode] = float(row[column])
        if row.get("termination"):
            ended.setdefault(row["controller"], set()).add(episode)
    mine = returns.get(policy, {})
    out: list[dict[str, Any]] = []
    keys: list[tuple[Any, ...]] = []  # each one's returns on the paired episodes
    for name, theirs in returns.items():
        seeds = sorted(set(mine) & set(theirs))
        if name == policy or not seeds:
            continue
        a = np.array([mine[s] for s in seeds])
        b = np.array([theirs[s] for s in seeds])
        keys.append((*seeds, *b.tolist()))  # (episodes and returns: one key per pairing)
        diff = a - b
        p, low, high = math.nan, math.nan, math.nan
        if len(seeds) > 1 and np.ptp(diff) > 0:
            p = float(ttest_rel(a, b, alternative="greater").pvalue)
            low, high = (float(v) for v in ttest_rel(a, b).confidence_interval(0.95))
        out.append({"controller": name, "seeds": len(seeds), "return": float(b.mean()),
                    "lead": float(diff.mean()), "lead_ci": (low, high),
                    "median_lead": float(np.median(diff)), "wins": int(np.sum(diff > 0)),
                    "p": p, "ended_early": len(ended.get(name, set()) & set(seeds)),
                    "policy_ended_early": len(ended.get(policy, set()) & set(seeds))})
    # controllers that returned the same on every episode (task 1's stiff PI and the
    # action held at 0) are one comparison, not two, in Holm's count
    distinct: dict[tuple[Any, ...], float] = {}
    for key, c in zip(keys, out, strict=True):
        distinct.setdefault(key, c["p"])
    adjusted = dict(zip(distinct, holm(list(distinct.values())), strict=True))
    tested = sum(not math.isnan(p) for p in distinct.values())  # Holm's m
    for key, c in zip(keys, out, strict=True):
        c["p_holm"] = adjusted[key]
        c["comparisons"] = tested
    return out


def holm(p: Sequence[float]) -> list[float]:
    """Holm's step-down adjustment of the p values of several tests (Holm 1979): the
    k-th smallest of m is multiplied by m - k + 1, and each adjusted value is at least
    the one before it in that order (at most 1). A NaN (no test) stays NaN and does not
    count among the m."""
    order = sorted((v, k) for k, v in enumerate(p) if not math.isnan(v))
    out = [math.nan] * len(p)
    running = 0.0
    for rank, (value, k) in enumerate(order):
        running = max(running, min(1.0, (len(order) - rank) * value))
        out[k] = running
    return out


def comparison_text(comparison: list[dict[str, Any]], policy_return: float,
                    policy: str = "the policy", scope: str = "", legend: bool = True) -> str:
    """:func:`paired_comparison` as the markdown table ``evaluate`` (and ``benchmark
    --paired``, with ``policy`` its controller's name) prints and writes, each column
    defined above it (``legend=False``: not again, below a table that did); ``scope``:
    what of the episodes the returns sum, where not all."""
    n = max((c.get("comparisons", len(comparison)) for c in comparison), default=0)
    what = "comparison" if n == 1 else "comparisons"
    lines = [f"Paired by episode (scenario and seed): {policy} (mean return "
             f"{shown('{:.1f}', policy_return)}{scope}) against each other controller on "
             "the same episodes.", ""]
    legend_lines = [
        f"- mean lead: the mean over episodes of {policy}'s return minus theirs; 95 % "
        "CI: its two-sided confidence interval (Student's t on the differences), per "
        "row, not adjusted for the other rows;",
        "- median lead: the median of those differences (the mean can be pulled by a "
        f"few episodes); better on: the episodes where {policy}'s return is higher "
        "(a tie is not counted);",
        f"- p: the one-sided paired t-test that {policy}'s mean return is higher; "
        + (f"p, Holm: p adjusted by Holm's method over the {n} {what} "
           "(controllers with identical returns on every episode counted once): read "
           f"it to say which of them {policy} beats; a claim that it beats every one of "
           "them at once needs each raw p below the level, no adjustment;" if n else
           "none here, nor p, Holm: a paired test needs two episodes or more with a "
           "spread in the differences;"),
        "- ended early: episodes a failure stopped (their return is the steps until "
        "then and the failure term, which charges each step cut off at the episode's "
        "worst step so far: never more than running on at that worst).", ""]
    lines += legend_lines if legend else []
    lines += [
        "| controller | return | mean lead | 95 % CI of the lead | median lead | "
        f"better on | p | p, Holm | ended early (theirs / {policy}'s) |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for c in comparison:
        p, adjusted = ("n/a" if math.isnan(v) else f"{v:#.2g}" for v in (c["p"], c["p_holm"]))
        low, high = c["lead_ci"]
        ci = "n/a" if math.isnan(low) else f"{low:+.1f} to {high:+.1f}"
        lines.append(f"| {c['controller']} | {shown('{:.1f}', c['return'])} | "
                     f"{shown('{:+.1f}', c['lead'])} | {ci} | "
                     f"{shown('{:+.1f}', c['median_lead'])} | {c['wins']} of {c['seeds']} "
                     f"| {p} | {adjusted} | {c['ended_early']} / {c['policy_ended_early']} |")
    few = min((c["seeds"] for c in comparison), default=0)
    if few == 1:
        lines += ["", "n/a: one episode a pair has no spread to test or to bound (give "
                      "more seeds)."]
    elif 1 < few < 10:
        lines += ["", f"With {few} episodes a pair the t-test's p and interval lean on the "
                      "differences being near normal, which so few cannot show; "
                      "`evaluate` scores on 20 seeds by default."]
    if any(math.isnan(c["p"]) for c in comparison if c["seeds"] > 1):
        lines += ["", "n/a where there are two or more episodes: the differences do not "
                      "vary (the same returns, or a constant lead), so there is nothing to "
                      "test."]
    return "\n".join(lines) + "\n"


def trained_fidelity(trained: Mapping[str, Any]) -> Fidelity:
    """The physics level a run trained at, from its ``env_kwargs`` (the tasks' default:
    fast)."""
    return trained.get("fidelity", "fast")


def evaluation_heading(run: str, model: str, algo: str, task: str, seeds: Sequence[int],
                       trained: Mapping[str, Any], fidelity: Fidelity | None = None) -> str:
    """The title of an evaluation's benchmark.md, comparison.md and pictures: the run and
    what its episodes ran on (physics level, the physics sections the run trained with:
    a run trained on a curved well read as if on the random scenario's vertical ones).
    ``fidelity``: the level the episodes ran at, where not the one the run trained at."""
    from drill_env.physics.config import flatten

    own = trained_fidelity(trained)
    level = fidelity or own
    changed = sorted({key.split(".")[0] for key in flatten(trained.get("physics") or {})})
    shown = f"seeds {seeds[0]}-{seeds[-1]}" if len(seeds) > 1 else f"seed {seeds[0]}"
    return (f"Evaluation of {run} ({model}, {algo} on task {task}), held-out {shown}, "
            f"physics level {level}"
            + (f" (trained at {own})" if level != own else "")
            + (f", the run's own {', '.join(changed)}" if changed else ""))


def evaluate_run(run: Path, seeds: int = len(EVALUATION_SEEDS), workers: int | None = None,
                 out: Path | None = None, controllers: tuple[str, ...] = CLASSICAL + TRIVIAL,
                 progress: bool = True, ray_address: str | None = None,
                 fidelity: Fidelity | None = None) -> list[dict[str, Any]]:
    """Benchmark ``learned:<run>`` against ``controllers`` on ``seeds`` held-out seeds:
    the classical ones and the trivial policies (actions held at -1, 0, +1, random); for
    the drilling task also against the best constant set point of a grid search. Writes
    the paired comparison (:func:`paired_comparison`) to ``out/comparison.md``.
    ``ray_address``: run the episodes on that Ray cluster (the ``distributed`` extra);
    ``fidelity``: the physics level of every episode (default: the one the run trained
    at; ``"full"`` judges a policy trained at the fast level in the full model, the
    classical controllers and the best constant with it)."""
    config = read_run_config(Path(run) / "config.yaml")
    task = config["task"]
    if seeds > len(EVALUATION_SEEDS):
        raise ValueError(f"seeds: at most {len(EVALUATION_SEEDS)} held-out seeds")
    out = out or Path(run) / "evaluation"
    names = [f"learned:{run}", *controllers]
    trained = config.get("env_kwargs") or {}
    own = trained_fidelity(trained)
    level = fidelity or own
    # every controller, and the grid search, under the task settings the run trained with
    settings = dataclasses.replace(settings_of(task, level), env_kwargs=task_settings(
        names[:1], TASKS[task]))
    if level != own:
        print(f"note: the run trained at the {own} level; evaluate scores it, and every "
              f"controller beside it, at the {level} level (--fidelity)")
    for note in standard_episode_notes(trained, settings):
        print(note)
    from agents.learned import moved_settings_note
    from agents.registry import make_controller

    make_controller(names[0], env_id=TASKS[task])  # a policy it cannot load: said first
    if moved := moved_settings_note("the run", Path(run), TASKS[task], trained):
        print(moved)
    if task == "drilling":
        constant, _ = best_constant(out / "grid_search", workers, progress, ray_address,
                                    settings)
        names.append(constant)
    from agents.learned import policy_files

    held_out = list(EVALUATION_SEEDS[:seeds])
    heading = evaluation_heading(Path(run).name, policy_files(run)[0].name, config["algo"],
                                 task, held_out, trained, level)
    rows = run_benchmark(names, ["random"], held_out, out, settings, workers=workers,
                         progress=progress, env_id=TASKS[task], ray_address=ray_address,
                         heading=heading)
    text = write_comparison(rows, label(names[0]), out, heading, warmup=settings.warmup)
    if text:
        print(text)  # beside the benchmark's table, which is printed too
    return rows


def write_comparison(rows: list[dict[str, Any]], policy: str, out: Path, heading: str,
                     name: str = "the policy", warmup: float | None = None) -> str | None:
    """``out/comparison.md``: the row label ``policy`` paired against every other
    controller of ``rows`` (:func:`paired_comparison`, :func:`comparison_text`, called
    ``name`` in the text) under ``heading``, for ``evaluate`` and ``benchmark --paired``;
    returns the text, None where ``policy`` has no rows. A second table pairs the returns
    of the metric window alone (``window_return``: from the end of the ``warmup`` on),
    where the warm-up changed them: task 1's return counts its stalled start, where a
    policy may gain what it does not keep after (an outside review)."""
    from drill_env.sweep import save_text

    mine = [r for r in rows if r["controller"] == policy]
    if not mine:
        return None
    text = comparison_text(paired_comparison(rows, policy),
                           float(np.mean([r["episode_return"] for r in mine])), name)
    windows = [r.get("window_return") for r in mine]
    if all(w is not None for w in windows) and any(
            w != r["episode_return"] for w, r in zip(windows, mine, strict=True)):
        after = f" {warmup:g} s" if warmup is not None else ""
        text = ("## The whole episode\n\nThe return of every step, what a policy is "
                "trained on: the warm-up counts (in task 1 the stalled start: getting a "
                "stuck bit going). "
                "The second table leaves it out: read it for what a controller does once "
                "the episode is under way (docs/tasks.md, \"Its lead is in the "
                "start-up\").\n\n" + text)
        text += ("\n## The metric window alone\n\nThe same pairing on the return of the "
                 f"steps after the{after} warm-up (the window the metrics measure): a lead "
                 "won in the start-up alone shows here as none.\n\n"
                 + comparison_text(paired_comparison(rows, policy, "window_return"),
                                   float(np.mean([w for w in windows if w is not None])), name,
                                   " after the warm-up", legend=False))
    save_text(out / "comparison.md", f"# {heading}\n\n{text}")
    return text
