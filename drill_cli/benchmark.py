"""``drill-env benchmark``: controllers against scenarios or a task over seeds, and the notes
said before it (set points that coincide, a start that buckles or overloads the pipe)."""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from drill_cli.arguments import checked_string_lengths, counted, recording_note, unwritable
from drill_cli.configs import checked_overrides
from drill_env.physics.units import KILO, RPM


def replaced_episode_notes(controllers: Sequence[str], env_id: str,
                           scenarios: Sequence[str], settings: Any) -> list[str]:
    """One note per episode setting (scenario, length, start kick) a policy trained
    under and a task benchmark replaces by its own, as ``evaluate`` says them: a run's
    (``learned:RUN``) and a controller of your own's ``env_kwargs()`` (an ``sb3_policy``
    trained on 60 s episodes was run on the benchmark's without a word)."""
    from agents.benchmark import replaced_episode_settings
    from agents.learned import moved_settings_note, policy_folder, trained_env
    from agents.registry import is_imported, make_controller
    from agents.settings import declared_env_kwargs

    notes = []
    for name in controllers:
        if name == "learned" or name.startswith("learned:"):
            path = name.partition(":")[2] or None
            trained_on, trained = trained_env(path, env_id)
            if moved := moved_settings_note(name, policy_folder(path, env_id), trained_on,
                                            trained):
                notes.append(moved)
        elif is_imported(name) and (made := make_controller(name)).env_id == env_id:
            trained = declared_env_kwargs(made, name)
        else:
            continue
        notes += [f"note: {name} trained with {key}={was!r}; the benchmark runs every "
                  f"controller on its own episodes ({key}={value!r})"
                  for key, was, value in replaced_episode_settings(
                      trained, settings, ",".join(scenarios))]
    return notes


def variant_folder(controllers: Sequence[str], env_id: str) -> str:
    """The folder of its own, inside a task benchmark's default --out, for a benchmark
    of policies trained under other ``env_id`` settings than the task's (a task variant,
    whose settings every controller then acts under): ``variant-<run>-<settings>`` after
    the first run (``learned:RUN``) or controller file of one's own that carries them
    and six hex digits of the settings (two runs of one name in two folders, of other
    settings, shared a folder, the second table over the first: a fuzzing walkthrough);
    "" for the task's own settings. The variant's table replaced the task's own in
    logs/benchmark/<task> (its rows kept apart in benchmark_results.jsonl, the table not;
    a closing note)."""
    import hashlib

    from agents.registry import is_imported
    from agents.settings import as_text, task_settings

    try:
        if not (settings := task_settings(controllers, env_id)):
            return ""
        # (the first of one's own named it: a set-point file beside two variants' runs
        # put both in one folder, the second table over the first; a review)
        carrier = next(name for name in controllers if (
            name.startswith("learned:") or is_imported(name)) and task_settings([name], env_id))
    except (ValueError, StopIteration):  # said by the benchmark, in its words
        return ""
    if carrier.startswith("learned:"):
        name = Path(carrier.partition(":")[2]).resolve().name
    else:
        where = carrier.rpartition(":")[0]  # file.py:Class, or package.module:Class
        name = Path(where).stem if where.endswith(".py") else where.rpartition(".")[2]
    # (as the benchmark compares settings: 15 and 15.0 alike, a review)
    return f"variant-{name}-{hashlib.sha256(as_text(settings).encode()).hexdigest()[:6]}"


def scenario_twins(scenarios: Sequence[str], key: Callable[[Any], Any]) -> dict[str, str]:
    """The fixed scenarios among ``scenarios`` whose ``key`` (of the scenario as built,
    its own start) equals an earlier one's, each mapped to that earlier one."""
    from drill_env.scenarios import RANDOMISED, make_scenario

    first: dict[Any, str] = {}
    twins = {}
    for name in dict.fromkeys(n for n in scenarios if n not in RANDOMISED):  # once each
        k = key(make_scenario(name))
        if k in first:
            twins[name] = first[k]
        else:
            first[k] = name
    return twins


def same_physics(scenarios: Sequence[str]) -> list[str]:
    """The fixed scenarios among ``scenarios`` whose physics equals another's (they differ
    only in their set points, e.g. default and stick_slip)."""
    twins = scenario_twins(scenarios, lambda s: s.config)
    return [s for s in dict.fromkeys(scenarios) if s in twins or s in twins.values()]


def same_episodes(scenarios: Sequence[str], set_points: dict[str, float]
                  ) -> dict[str, str]:
    """The fixed scenarios among ``scenarios`` that the benchmark's ``set_points`` (its
    ``--rpm``, ``--wob``) make equal to an earlier one (config and set points: e.g.
    default and stick_slip at one --rpm), each mapped to that earlier one. Compared as
    built at their own start: the benchmark runs a --wob that buckles it too."""
    return scenario_twins(scenarios, lambda s: (
        s.config, set_points.get("surface_speed", s.surface_speed),
        set_points.get("weight_on_bit", s.weight_on_bit), s.episode_duration,
        s.allow_pipe_buckling))


def benchmark_set_points(args: argparse.Namespace, env_id: str | None) -> dict[str, float]:
    """``--rpm`` / ``--wob`` as BenchmarkSettings' set points (rad/s, N), checked against
    DrillString-v0's set-point ranges; refused with ``--task``."""
    from agents.settings import set_point_outside
    from drill_env.env import EnvConfig

    given = {flag: value for flag, value in (("--rpm", args.rpm), ("--wob", args.wob))
             if value is not None}
    if given and env_id is not None:
        raise argparse.ArgumentTypeError(
            f"{next(iter(given))}: a task benchmark drills at the targets its task draws "
            "from each seed, the same for every controller; --rpm and --wob set a scenario "
            "benchmark's")
    out = {key: given[flag] * scale for flag, key, scale in (
        ("--rpm", "surface_speed", RPM), ("--wob", "weight_on_bit", KILO)) if flag in given}
    if outside := set_point_outside(out.get("surface_speed"), out.get("weight_on_bit"),
                                    EnvConfig()):
        key, value, low, high, unit = outside
        flag = "--rpm" if key == "surface_speed" else "--wob"
        raise argparse.ArgumentTypeError(f"{flag}: {value:g} {unit} is outside "
                                         f"DrillString-v0's range {low:g}-{high:g} {unit}")
    return out


def buckling_notes(scenarios: Sequence[str], wob: float, physics: dict[str, Any]
                   ) -> list[str]:
    """A note per fixed scenario whose pipe buckles at the start under ``--wob`` (N), as
    ``run`` notes it: the scenarios refuse such a start of their own, the benchmark runs
    it (a randomised scenario draws another string per seed: not judged here)."""
    from drill_env.physics.statics import pipe_buckling
    from drill_env.scenarios import RANDOMISED, make_scenario, with_physics

    notes = []
    for name in (n for n in scenarios if n not in RANDOMISED):
        config = with_physics(make_scenario(name).config, physics)
        notes += [buckling_note(f"--wob {wob / KILO:g} kN", f"{b.component} of {name}", b)
                  for b in (pipe_buckling(config, wob) if config.solver.lateral else ())]
    return notes


def buckling_note(load: str, component: str, buckled: Any) -> str:
    """The note on a start whose WOB (``load``, as typed) buckles ``component`` (a
    :func:`drill_env.physics.statics.pipe_buckling` entry)."""
    return (f"note: {load} compresses the {component} by {buckled.compression / KILO:.1f} "
            f"kN {buckled.place}, beyond its buckling load "
            f"{buckled.buckling_load / KILO:.1f} kN there: it buckles "
            "into the wall (the scenarios refuse such a starting point; docs/model.md, "
            "'Axial load and buckling')")


def tension_notes(config: Any, wob: float) -> list[str]:
    """A note per component whose static tension at ``wob`` (N) passes the allowable
    design load of the strongest common pipe grade (``over_allowable_tension``)."""
    from drill_env.physics.statics import over_allowable_tension

    return [f"note: the {o.component} carries {o.tension / KILO:,.0f} kN at its top hanging "
            f"straight, above {o.allowable / KILO:,.0f} kN, API RP 7G's allowable tension "
            "for its body even in new S-135 pipe (90 % of 931 MPa): within 10 % of yield, "
            "past any common grade's design limit; the model has no yield, and its pipe no "
            "tool joints, so a real string's load is higher (docs/model.md, 'Statics and "
            "the realistic string')" for o in over_allowable_tension(config, wob)]


def cmd_benchmark(args: argparse.Namespace) -> int:
    from agents.benchmark import run_benchmark
    from agents.registry import parse_controllers
    from agents.settings import BenchmarkSettings, labels
    from drill_env.scenarios import SCENARIOS

    try:
        controllers = parse_controllers(args.controllers)
        labels(controllers)  # names given twice, or two that would share a table name
    except ValueError as err:
        raise argparse.ArgumentTypeError(f"--{err}") from None
    if args.paired is not None and args.paired not in controllers \
            and args.paired in labels(controllers):  # its table name (a new user's try)
        args.paired = controllers[labels(controllers).index(args.paired)]
    if args.paired is not None and args.paired not in controllers:
        raise argparse.ArgumentTypeError(f"--paired: {args.paired!r} is not one of "
                                         f"--controllers ({', '.join(controllers)})")
    env_id = None
    if args.task is not None:
        from training.config import TASKS

        env_id = TASKS[args.task]
    if args.out is None:  # a task's benchmark replaced the scenario benchmark's outputs, and
        # a --config variant the benchmark without it: each in a folder of its own
        # (config-<stem>: a file named stick_slip.yaml would have written into the task
        # benchmark's own folder; a review)
        variant = variant_folder(controllers, env_id) if env_id else ""
        args.out = (Path("logs/benchmark") / (args.task or "")
                    / (f"config-{args.config.stem}" if args.config else "") / variant)
        if variant:
            print(f"note: the policies were trained under other {env_id} settings than "
                  f"the task's, which every controller acts under here: the benchmark goes "
                  f"to {args.out}, apart from the task's own", file=sys.stderr)
        if reason := unwritable(args.out):
            raise argparse.ArgumentTypeError(f"--out {args.out}: {reason}")
    if args.scenarios is not None and not args.scenarios.strip(", "):  # (an unset variable)
        raise argparse.ArgumentTypeError("--scenarios: give at least one name, or leave the "
                                         "option out for the default set")
    from drill_env.physics.validation import comma_items

    text = args.scenarios or ("random" if env_id else "default,stick_slip")
    scenarios = comma_items(text, "--scenarios")
    unknown = [n for n in scenarios if n not in SCENARIOS]
    if unknown or not scenarios:
        from drill_env.physics.validation import did_you_mean

        hint = did_you_mean(unknown[0], list(SCENARIOS)) if unknown else ""
        raise argparse.ArgumentTypeError(f"--scenarios: unknown {unknown or text!r}{hint};"
                                         f" known: {', '.join(sorted(SCENARIOS))}")
    from drill_env.physics.validation import repeated

    if (twice := repeated(scenarios)) is not None:  # (it ran the same episodes twice, and
        # benchmark.csv held their rows twice)
        raise argparse.ArgumentTypeError(f"--scenarios: {twice!r} is given twice")
    # a task's episodes and window default to the ones evaluate measures the task on
    if args.task is not None:
        from training.evaluate import EVALUATION_WINDOWS

        duration, warmup = EVALUATION_WINDOWS[args.task]
    else:
        duration, warmup = 60.0, 30.0
    whose = ("" if args.warmup is not None else
             f" (the default{' of --task ' + args.task if args.task else ''})")
    args.duration = duration if args.duration is None else args.duration
    args.warmup = warmup if args.warmup is None else args.warmup
    if args.warmup >= args.duration:
        raise argparse.ArgumentTypeError(
            f"--warmup: {args.warmup:g} s{whose} must be shorter than --duration "
            f"({args.duration:g} s)" + ("; give a shorter --warmup" if whose else ""))
    check_constant_set_points(controllers, env_id)
    set_points = benchmark_set_points(args, env_id)
    if set_points:  # one episode is not run twice under two names
        twins = same_episodes(scenarios, set_points)
        if twins:
            scenarios = [n for n in scenarios if n not in twins]
            flags = " ".join(f"{f} {v:g}" for f, v in (("--rpm", args.rpm), ("--wob", args.wob))
                             if v is not None)
            print("note: at " + flags + ", " + "; ".join(
                f"{n} is the same episode as {first}" for n, first in twins.items())
                + " (they differ only in set points): run once, as "
                + ", ".join(dict.fromkeys(twins.values())), file=sys.stderr)
    if args.string_lengths is not None and env_id is None:
        raise argparse.ArgumentTypeError("--string-lengths: the range a task's random "
                                         "scenario draws; give --task with it")
    lengths = {} if args.string_lengths is None else {
        "string_length_range": checked_string_lengths(args.string_lengths)}
    # a task benchmark runs at the level the task trains and evaluates on
    fidelity: Any = args.fidelity or ("fast" if env_id else "full")  # argparse checked it
    try:
        settings = BenchmarkSettings(duration=args.duration, warmup=args.warmup,
                                     start_kick=args.start_kick, fidelity=fidelity,
                                     physics=checked_overrides(
                                         args.config, scenarios, lengths,
                                         "--string-lengths with --task"),
                                     env_kwargs=lengths,
                                     surface_speed=set_points.get("surface_speed"),
                                     weight_on_bit=set_points.get("weight_on_bit"))
    except ValueError as err:  # a field of the --config file the benchmark cannot take
        if not str(err).startswith("physics."):
            raise
        raise argparse.ArgumentTypeError(
            f"--config {args.config}: {str(err).removeprefix('physics.')}") from None
    if settings.weight_on_bit is not None:
        for note in buckling_notes(scenarios, settings.weight_on_bit, settings.physics):
            print(note, file=sys.stderr)
    if env_id is not None:
        for note in replaced_episode_notes(controllers, env_id, scenarios, settings):
            print(note, file=sys.stderr)
        from agents.settings import set_point_guests

        for name in set_point_guests(controllers, env_id):
            print(f"note: {name} is a policy of DrillString-v0: in {env_id} its act gets the "
                  "task's observation (env.unwrapped.observation_names: read what it needs "
                  "from info, by name), acts through the task's action_for, and its "
                  "env_kwargs() do not apply", file=sys.stderr)
        same = same_physics(scenarios)
        if same:
            print(f"note: a task benchmark drills each scenario at the task's targets drawn "
                  f"from the seed, not at the scenario's set points: {', '.join(same)} are "
                  "then the same episodes", file=sys.stderr)
    episodes = len(controllers) * len(scenarios) * args.seeds  # (a rerun's reused ones too)
    if args.record and (note := recording_note(args.out / "recordings", args.duration,
                                               episodes)):
        print(note, file=sys.stderr)
    t0 = time.perf_counter()
    seeds = list(range(args.seed_start, args.seed_start + args.seeds))
    heading = "Controller benchmark" + (f", config {args.config}" if args.config else "")
    if env_id is not None:  # its pictures said "Controller benchmark" and "random" alone
        heading += (f", task {args.task} ({env_id}), seeds {seeds[0]}-{seeds[-1]}"
                    if len(seeds) > 1 else f", task {args.task} ({env_id}), seed {seeds[0]}")
    rows = run_benchmark(controllers, scenarios, seeds, args.out, settings,
                         workers=args.workers, record=args.record, env_id=env_id,
                         ray_address=args.ray_address, heading=heading)
    print(f"{counted(len(rows), 'episode')} ({counted(len(controllers), 'controller')} x "
          f"{counted(len(scenarios), 'scenario')} x {counted(args.seeds, 'seed')}) in the "
          f"table after {time.perf_counter() - t0:.0f} s (reused ones included); finished "
          f"episodes are kept in {args.out / 'benchmark_results.jsonl'} (a rerun reuses "
          "them)")
    if args.paired is not None:  # an outside policy's t-tests, as evaluate gives a run's
        from training.evaluate import write_comparison

        policy = labels(controllers)[controllers.index(args.paired)]
        text = write_comparison(rows, policy, args.out, f"{heading}, paired against {policy}",
                                policy, warmup=args.warmup)
        if text:
            print(f"\n{text}")
    print(f"wrote {args.out / 'benchmark.csv'}, benchmark.md"
          + (", comparison.md" if args.paired is not None else "")
          + f" and the plots in {args.out}")
    return 0


def check_constant_set_points(controllers: Sequence[str], env_id: str | None) -> None:
    """Refuse a ``constant:`` controller outside the action ranges of the benchmark's env
    before the first episode (its own check would fail in a worker, mid-run)."""
    constants = [c for c in controllers if c.startswith("constant:")]
    if not constants:
        return
    from agents.classical import ConstantSetPoints
    from drill_env.env import DrillStringEnv
    from drill_env.vector import registered

    env_class, kwargs = registered(env_id) if env_id else (DrillStringEnv, {})
    config = env_class(**kwargs).config
    for name in constants:
        in_range(ConstantSetPoints.parse(name.partition(":")[2]), config, "--controllers")


def in_range(constant: Any, config: Any, option: str) -> None:
    """A :class:`~agents.classical.ConstantSetPoints` outside the action ranges of an
    env's ``config`` is an error of ``option``, the one it was typed in."""
    try:
        constant.check_range(config)
    except ValueError as err:
        raise argparse.ArgumentTypeError(f"{option}: {str(err).partition(': ')[2]}") from None
