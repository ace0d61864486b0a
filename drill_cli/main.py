"""Command line: ``drill-env <command>`` (or ``python -m drill_cli <command>``).

The top layer: it parses arguments in the units people type (rpm, kN, seconds), checks
them in those units, and calls the libraries below (``drill_env``, ``agents``,
``training``), which work in SI. Every command but ``replay`` prints a table and writes
its outputs under ``--out`` (default ``logs/``; ``benchmark`` ``logs/benchmark``, with
``--task`` ``logs/benchmark/<task>``, with ``--config FILE`` a folder ``config-<stem>``
inside that, ``train`` ``logs/runs``, ``evaluate`` the run's ``evaluation/``).
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import errno
import json
import math
import os
import signal
import sys
import threading
import time
import warnings
from collections.abc import Callable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

from drill_env.physics.units import HOUR, KILO, RPM, few, shown
from drill_env.progress import progress_bar
from drill_env.sweep import (
    Terminated,
    clear_interrupt,
    hear_interrupts,
    note_interrupt,
    save_text,
    save_whole,
)
from drill_env.swing import SWING_BLOCK, swing_per_block, swing_trend

DESCRIPTION = """\
drill-env: drill-string dynamics, classical top-drive controllers and RL agents.
Each command below has its own --help.

SI inside; rpm, kN and m/h only on this command line and in its tables."""


class _Formatter(argparse.ArgumentDefaultsHelpFormatter, argparse.RawDescriptionHelpFormatter):
    """Shows defaults, except where there is none or the help says it already (the help
    then says what happens)."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        if action.default is None or isinstance(action.default, bool) \
                or "default:" in (action.help or ""):
            return action.help
        return super()._get_help_string(action)


def number(unit: str, low: float | None = 0.0, high: float | None = None,
           low_inclusive: bool = True) -> Callable[[str], float]:
    """An argparse type: a finite number in [low, high] of ``unit``; errors in that unit."""
    in_unit = f" {unit}" if unit else ""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"{text!r} is not a number" + (f" ({unit})" if unit else "")) from None
        if not math.isfinite(value):
            raise argparse.ArgumentTypeError(f"must be a finite number{in_unit and ' of'}"
                                             f"{in_unit}, got {text}")
        if low is not None and (value < low or (value == low and not low_inclusive)):
            bound = ">=" if low_inclusive else ">"
            raise argparse.ArgumentTypeError(f"must be {bound} {low:g}{in_unit}, got {text}")
        if high is not None and value > high:
            raise argparse.ArgumentTypeError(f"must be <= {high:g}{in_unit}, got {text}")
        return value
    parse.__name__ = unit or "number"  # argparse names the type in its messages
    return parse


def kilonewtons(text: str) -> float:
    """An argparse type for a WOB in kN: a finite number >= 0, and none between 0 and 1
    kN (no string drills on that; it is what a WOB typed in MN gives)."""
    value = number("kN")(text)
    if 0.0 < value < 1.0:
        raise argparse.ArgumentTypeError(f"{text} kN is only {value * KILO:g} N: the WOB is "
                                         "in kN (100 for 100 kN)")
    return value


kilonewtons.__name__ = "kN"


def replaced_episode_notes(controllers: Sequence[str], env_id: str,
                           scenarios: Sequence[str], settings: Any) -> list[str]:
    """One note per episode setting (scenario, length, start kick) a policy trained
    under and a task benchmark replaces by its own, as ``evaluate`` says them: a run's
    (``learned:RUN``) and a controller of your own's ``env_kwargs()`` (an ``sb3_policy``
    trained on 60 s episodes was run on the benchmark's without a word)."""
    from agents.benchmark import declared_env_kwargs, replaced_episode_settings
    from agents.learned import moved_settings_note, policy_folder, trained_env
    from agents.registry import is_imported, make_controller

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


def out_folder(text: str) -> Path:
    """An output folder's name: not empty (``--out ''`` wrote into the current folder,
    from an unset shell variable)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("give a folder's name (an empty one would write "
                                         "into the current folder; '.' says that)")
    return user_path(text)


def user_path(text: str) -> Path:
    """An argparse type: a path, with a leading ``~`` read as the home folder, as the
    shell reads it where it can (``--out=~/runs`` and a quoted ``'~/runs'`` reach us
    unexpanded: the output went into a folder named ``~`` in the current one, an outside
    check)."""
    return Path(os.path.expanduser(text))  # (~name of no user: left as typed)


def shell_word(path: Path) -> str:
    """``path`` as one word on a command line to copy (quoted where it holds a space or,
    on POSIX, a character the shell reads; Windows: ``subprocess.list2cmdline``'s rules):
    the hint after training, ``drill-env evaluate logs/runs/sp ace``, ran two words."""
    import shlex
    import subprocess

    text = str(path)
    return subprocess.list2cmdline([text]) if os.name == "nt" else shlex.quote(text)


def unwritable(folder: Path) -> str:
    """Why ``folder`` could not be written (created if missing), or "" if it can; creates
    nothing, so a command refused later leaves no folder behind."""
    here = folder.absolute()
    if here.exists() and not here.is_dir():
        return "is a file; give a folder (it is created if missing)"
    while not here.exists():
        if here == here.parent:  # a root that is not there (an unmapped drive, Z:\)
            return f"{here} does not exist"
        here = here.parent
    if not here.is_dir():
        return f"{here} is a file, not a folder"
    import tempfile

    try:  # a probe, as root passes os.access everywhere (/proc too)
        os.rmdir(tempfile.mkdtemp(prefix=".drill-env-probe-", dir=here))
    except OSError as err:
        where = "" if here == folder.absolute() else f"{here}: "
        # /proc answers "No such file or directory" for a folder it has: say what it means
        why = "a file system that takes no new files" if err.errno == errno.ENOENT \
            else err.strerror
        return f"{where}cannot write there ({why})"
    return ""


class Once(argparse.Action):
    """An option given at most once: a second ``--config`` replaced the first silently
    (a string of one file and a top-drive setting of another ran on the default string)."""

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace,
                 values: Any, option_string: str | None = None) -> None:
        given = f"_{self.dest}_given"
        if getattr(namespace, given, False):
            parser.error(f"{option_string}: given twice ({getattr(namespace, self.dest)} and "
                         f"{values}); put all the overrides in one file (docs/config.md)")
        setattr(namespace, self.dest, values)
        setattr(namespace, given, True)


def existing_file(text: str) -> Path:
    """An argparse type: the path of a file that exists (else a one-line error)."""
    path = user_path(text)
    if not path.is_file():
        raise argparse.ArgumentTypeError(f"{text} {not_a_file(path)}" if path.exists()
                                         else f"no such file: {text}")
    return path


def not_a_file(path: Path) -> str:
    """Why ``path``, which exists and is not a regular file, cannot be read as one (said
    after its name)."""
    if path.is_dir():
        return "is a folder, not a file"
    # /dev/null, a named pipe: "no such file" was said of one that exists
    return "is not a regular file (a device or a pipe); give a file"


existing_file.__name__ = "file"


#: The most seeds a benchmark takes per (controller, scenario) pair.
MAX_BENCHMARK_SEEDS = 10_000


def integer(low: int = 0, high: int | None = None) -> Callable[[str], int]:
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            try:  # 1e5 or 4.0e5, as the hyperparameter YAMLs write them
                number = float(text)
                if not number.is_integer():
                    raise ValueError(text) from None
                value = int(number)
            except (ValueError, OverflowError):
                raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
        if value < low:
            raise argparse.ArgumentTypeError(f"must be >= {low}, got {value}")
        if high is not None and value > high:
            raise argparse.ArgumentTypeError(f"must be <= {high:,}, got {value:,}")
        return value
    parse.__name__ = "integer"
    return parse


def seed_count(first: str, high: int | None = None) -> Callable[[str], int]:
    """``--seeds`` where it is how many (benchmark, evaluate): a list typed as train's
    ``--seeds 0,1`` takes is told so, ``first`` naming where the seeds start."""
    count = integer(1, high)

    def parse(text: str) -> int:
        if "," in text:
            raise argparse.ArgumentTypeError(
                f"{text!r}: a number of seeds here, counted from {first} (a list of "
                "seeds is train's --seeds)")
        return count(text)
    parse.__name__ = "integer"
    return parse


def fixed(value: float, digits: int = 2) -> str:
    """``value`` with ``digits`` decimals, without the sign of a value that rounds to
    zero ("0.00", not "-0.00")."""
    return shown(f"{{:.{digits}f}}", value)


def counted(n: int, noun: str) -> str:
    """"1 seed", "3 seeds"."""
    return f"{n} {noun}{'' if n == 1 else 's'}"


# --------------------------------------------------------------------------- commands


def cmd_demo(args: argparse.Namespace) -> int:
    from agents.benchmark import BenchmarkSettings, run_benchmark
    from agents.registry import CLASSICAL
    from drill_env.tools.demo import stick_slip_demo

    _, reproduced = stick_slip_demo(args.out)
    print("\nController benchmark (as drill-env benchmark): the classical controllers at "
          "the set points of the default scenario (100 rpm) and of stick_slip (50 rpm)")
    t0 = time.perf_counter()
    out = args.out / "benchmark"
    run_benchmark(list(CLASSICAL), ["default", "stick_slip"], [0, 1, 2], out,
                  BenchmarkSettings(), workers=args.workers)
    print(f"benchmark in {time.perf_counter() - t0:.0f} s: {out / 'benchmark.csv'}, "
          f"{out / 'benchmark.md'}, {out / 'benchmark_bars.png'} and the time series "
          f"{out / 'benchmark_<scenario>_series.png'}")
    return 0 if reproduced else 1


#: The units of run_summary.json's numbers (the window metrics are the info's, in SI
#: units; the rest names its unit in its key or is a count or a ratio).
RUN_SUMMARY_UNITS = {
    "rpm": "rpm", "weight_on_bit_kN": "kN", "mean_setpoint_rpm": "rpm",
    "mean_setpoint_kN": "kN", "mean_surface_torque_kNm": "kN m", "mean_hook_load_kN": "kN",
    "mean_weight_on_bit_kN": "kN",
    "string_length_m": "m", "simulated_s": "s", "wall_s": "s",
    "start_kick": "1 (relative bit-speed kick)", "duration_given_s": "s",
    "mean_ssi": "1",
    "mean_stuck_fraction": "1", "mean_whirl_ratio": "1", "mean_radial_ratio": "1",
    "mean_lateral_force": "N", "mean_rop": "m/s", "return": "reward units",
    "task_return": "reward units", "swing_per_block_rpm": "rpm, per 30 s block",
    "bit_inclination_deg": "deg (0: vertical)"}


def cmd_run(args: argparse.Namespace) -> int:
    import gymnasium as gym

    import drill_env  # noqa: F401  (registers the ids)
    from agents.benchmark import (
        env_ranges,
        guest_env_kwargs,
        scenario_set_points,
        set_point_outside,
        starting_at,
    )
    from agents.classical import ConstantSetPoints, drive_loop_name

    args.controller = canonical_controller(args.controller)
    controller = typed_controller(args.controller)
    overrides = checked_overrides(args.config, [args.scenario])
    if "top_drive.controller" in overrides:  # it would be replaced by --controller's
        raise argparse.ArgumentTypeError(
            f"--config {args.config}: top_drive.controller: drill-env run takes the "
            f"controller from --controller (default stiff); give --controller "
            f"{drive_loop_name(overrides['top_drive.controller'])} instead")
    # the controller's own physics (its top drive) over the file's; a value of the file
    # it would replace is refused (it was dropped without a word)
    own = controller.physics()
    replaced = sorted(k for k in own if k in overrides and overrides[k] != own[k])
    if replaced:
        key = replaced[0]
        raise argparse.ArgumentTypeError(
            f"--config {args.config}: {key}: --controller {args.controller} sets it "
            f"({own[key]!r}), which would replace the file's {overrides[key]!r}: remove it "
            "from the file, or change the controller")
    physics = {**overrides, **own}
    # a task's policy drills this scenario, as in a scenario benchmark
    kwargs: dict[str, Any] = {**guest_env_kwargs(controller), "scenario": args.scenario,
                              "start_kick": args.start_kick, "physics": physics}
    if args.fidelity is not None:  # else the env's own (a task's policy: the task's)
        kwargs["fidelity"] = args.fidelity
    if controller.env_id != "DrillString-v0":
        # a task's policy acts in its task's env (its observation and action), but drills
        # the scenario as DrillString-v0 would: its start and length, not the task's
        kwargs.update(startup="settled", episode_duration=None)
    if args.duration is not None:
        kwargs["episode_duration"] = args.duration
    # --rpm / --wob start the scenario (its buckling check is at the WOB run), where in
    # range (else the check below names the flag)
    given = {"surface_speed": None if args.rpm is None else args.rpm * RPM,
             "weight_on_bit": None if args.wob is None else args.wob * KILO}
    if not set_point_outside(given["surface_speed"], given["weight_on_bit"],
                             env_ranges(controller.env_id, kwargs)):
        kwargs.update(starting_at(args.scenario,
                                  {k: v for k, v in given.items() if v is not None}, physics))
    env: Any = gym.make(controller.env_id, **kwargs)
    base: Any = env.unwrapped
    cfg = base.config
    if isinstance(controller, ConstantSetPoints):
        in_range(controller, cfg, "--controller")
    # set points given on the command line override the episode's; else the scenario's
    # (a randomised scenario draws them from the seed), also for a task's policy, whose
    # env would draw its own targets
    options: dict[str, float] = {}
    if controller.env_id != "DrillString-v0":
        options = scenario_set_points(args.scenario, args.seed)
    for flag, value, (low, high), unit, key, scale in (
            ("--rpm", args.rpm, cfg.rpm_range, "rpm", "surface_speed", RPM),
            ("--wob", args.wob, tuple(v / KILO for v in cfg.weight_on_bit_range), "kN",
             "weight_on_bit", KILO)):
        if value is None:
            continue
        if not low <= value <= high:
            # a WOB typed in newtons, as the Python API takes it (a new user's trial)
            hint = f" (in kN: did you mean {value / KILO:g}?)" if unit == "kN" and \
                low <= value / KILO <= high and value >= KILO else ""
            raise argparse.ArgumentTypeError(f"{flag}: {value:g} {unit} is outside the env's "
                                             f"range {low:g}-{high:g} {unit}{hint}")
        options[key] = value * scale
    if args.record is RECORD_UNDER_OUT:
        args.record = args.out / "recordings"
    if args.record is not None and (reason := unwritable(args.record)):
        raise argparse.ArgumentTypeError(f"--record {args.record}: {reason}")
    if args.record is not None:
        from agents.benchmark import label
        from drill_env.recording import RecordEpisode

        # <controller>_<scenario>_seed<seed>_ep..., the benchmark's order; the --config
        # file's name joined to the scenario's (runs of two wells in one folder told apart)
        scenario = args.scenario if args.config is None \
            else f"{args.scenario}+{args.config.stem}"
        env = RecordEpisode(env, args.record, scenario=scenario,
                            controller=label(args.controller))
    from agents.benchmark import act
    from agents.benchmark import reset as reset_controller
    from drill_env.physics.statics import pipe_buckling

    t0 = time.perf_counter()
    first_step_s, bar = 0.0, None
    keys = ("ssi", "stuck_fraction", "whirl_ratio", "radial_ratio", "lateral_force", "rop")
    totals = dict.fromkeys(keys, 0.0)
    steps, reward, reason = 0, 0.0, ""
    info: dict[str, Any] = {}
    with warnings.catch_warnings():
        if kwargs.get("weight_on_bit") == options.get("weight_on_bit"):  # said at the make
            warnings.filterwarnings("ignore", "reset options: weight_on_bit: .* above this "
                                    "string's weight_on_bit_limit")
        obs, info = env.reset(seed=args.seed, options=options or None)
    if controller.env_id != "DrillString-v0":  # scored as DrillString-v0 scores (benchmark)
        base.plain_return = 0.0
    # judged at the WOB the bit gets: the mesh's limit where the start asks for more (a new
    # user's trial: a buckling note for 170 kN where the bit got 161.8 and did not buckle)
    start_wob_kn = min(base.targets[1], base.weight_on_bit_limit) / KILO
    lateral = base.simulation_config.solver.lateral  # torsion only: nothing to buckle
    for b in pipe_buckling(base.simulation_config, start_wob_kn * KILO) if lateral else ():
        print(buckling_note(f"{start_wob_kn:g} kN", b.component, b), file=sys.stderr)
    for note in tension_notes(base.simulation_config, start_wob_kn * KILO):
        print(note, file=sys.stderr)
    from drill_env.physics.modes import bha_buckles

    if bha_buckles(base.simulation_config, start_wob_kn * KILO):  # as modes says
        print(f"note: {start_wob_kn:g} kN buckles the straight BHA between its stabilizers "
              "(drill-env modes gives the load): the simulation bends it against the wall and "
              "drills on", file=sys.stderr)
    # per step: the driller's targets (a task's may change once) and the set points the
    # controller applied (constant:<rpm>/<kN> and the driller set their own, a stick-slip
    # policy corrects the speed): their episode means are what it ran at
    sums = dict.fromkeys(("target_speed", "target_wob", "speed_setpoint",
                          "weight_on_bit_setpoint", "surface_torque", "hook_load",
                          "weight_on_bit"), 0.0)
    speeds: list[tuple[float, float]] = []  # (episode time s, bit rpm) per step
    held_set_points = controller.rate == "drive" and controller.env_id == "DrillString-v0"
    try:
        reset_controller(controller, args.controller, f"{args.scenario} seed {args.seed}", base)
        # (where stderr is no terminal, a line a minute: a log got the bar's frames, the
        # summary glued after them)
        bar = progress_bar(total=base.max_episode_steps, desc=f"  {args.scenario}",
                           leave=False, file=sys.stderr)
        for _ in range(base.max_episode_steps):
            obs, r, terminated, truncated, info = env.step(act(
                controller, args.controller, f"{args.scenario} seed {args.seed}",
                env.action_space, obs, info))
            steps += 1
            if steps == 1:  # on a first run the compile: the bar's rate starts after it
                first_step_s = time.perf_counter() - t0
                bar.reset()
            bar.update()
            reward += float(r)
            sums["target_speed"] += base.targets[0]
            sums["target_wob"] += base.targets[1]
            sums["speed_setpoint"] += info["speed_setpoint"]
            sums["weight_on_bit_setpoint"] += info["weight_on_bit_setpoint"]
            # what a driller reads first: the torque and the load on the rig
            sums["surface_torque"] += info["surface_torque"]
            sums["hook_load"] += info["hook_load"]
            # what the bit got: below the set point where the string's mesh limits it
            # (the summary said the 100 kN asked where the bit got 96.6: an outside check)
            sums["weight_on_bit"] += info["weight_on_bit"]
            if held_set_points:  # the swing per block: only where it is reported
                speeds.append((info["episode_time"], info["bit_speed"] / RPM))
            for key in keys:
                totals[key] += info[key]
            if terminated or truncated:
                reason = info["termination_reason"]
                break
    except KeyboardInterrupt as stopped:
        reason = "interrupted"
        status = exit_status(stopped)
    else:
        status = 0
    finally:
        if bar is not None:
            bar.close()
        env.close()  # finishes a recording, interrupted or not
    mean = {key: total / steps for key, total in sums.items()} if steps else {
        "target_speed": base.targets[0], "target_wob": base.targets[1],
        "speed_setpoint": base.targets[0], "weight_on_bit_setpoint": base.targets[1],
        "surface_torque": info["surface_torque"], "hook_load": info["hook_load"],
        "weight_on_bit": info["weight_on_bit"]}
    rpm, wob_kn = mean["target_speed"] / RPM, mean["target_wob"] / KILO
    setpoint_rpm = mean["speed_setpoint"] / RPM
    setpoint_kn = mean["weight_on_bit_setpoint"] / KILO
    guest = reward if base.plain_return is not None else None
    # targets and times rounded far below what they mean: 50.0, not 49.99999999999955
    rpm, wob_kn, setpoint_rpm, setpoint_kn = (round(v, 9) for v in (
        rpm, wob_kn, setpoint_rpm, setpoint_kn))
    summary = {
        "scenario": args.scenario, "controller": args.controller,
        "env_id": controller.env_id, "startup": cfg.startup, "rpm": rpm,
        "weight_on_bit_kN": wob_kn, "mean_setpoint_rpm": setpoint_rpm,
        "mean_setpoint_kN": setpoint_kn, "seed": args.seed,
        "mean_surface_torque_kNm": mean["surface_torque"] / KILO,
        "mean_hook_load_kN": mean["hook_load"] / KILO,
        "mean_weight_on_bit_kN": mean["weight_on_bit"] / KILO,
        # what else set the episode: a history's runs of another string or start apart
        "config": None if args.config is None else str(args.config),
        "start_kick": args.start_kick, "duration_given_s": args.duration,
        "fidelity": base.simulation_config.solver.fidelity,
        "string_length_m": base.simulation_config.string.length, "steps": steps,
        # the hole at the bit: a --config's well shows in the record of the run
        "bit_inclination_deg": round(math.degrees(base.sim.bit_inclination), 6),
        "simulated_s": round(float(info.get("episode_time", 0.0)), 6),  # steps of ms
        # a task's policy: DrillString-v0's reward of its episode (as benchmark), and
        # its own task's apart
        "return": reward if guest is None else base.plain_return, "task_return": guest,
        "termination_reason": reason,
        # does stick-slip grow or decay (a tuning run's question: docs/controllers.md);
        # only where the set points hold (a drive-rate loop in DrillString-v0): a policy's
        # speed changes would read as swing
        "swing_per_block_rpm": swing_per_block(speeds) if held_set_points else None,
        **{f"mean_{key}": totals[key] / max(steps, 1) for key in keys},
        "wall_s": time.perf_counter() - t0,
        "units": RUN_SUMMARY_UNITS,
    }
    if args.record is not None:
        summary["recording"] = str(env.last_path) if env.last_path else None
    args.out.mkdir(parents=True, exist_ok=True)
    save_text(args.out / "run_summary.json", json.dumps(summary, indent=2))
    with (args.out / "run_history.jsonl").open("a", encoding="utf-8") as history:
        finished = time.strftime("%Y-%m-%dT%H:%M:%S%z")  # tells the runs of a history apart
        history.write(json.dumps({"finished": finished, **summary}) + "\n")
    ran_at = f"targets {rpm:.0f} rpm, {wob_kn:.0f} kN"
    if abs(setpoint_rpm - rpm) >= 0.5 or abs(setpoint_kn - wob_kn) >= 0.5:
        ran_at += f" (set points applied: mean {setpoint_rpm:.0f} rpm, {setpoint_kn:.0f} kN)"
    returned = f"return {fixed(summary['return'])}" + (
        "" if guest is None else f" (DrillString-v0's reward; its task's {fixed(guest)})")
    named = args.scenario + (f" with {args.config}" if args.config is not None else "")
    compiled = f" ({first_step_s:.1f} s of it the reset and first step, which compiled " \
        "the kernels)" if getattr(args, "compiled", [False])[0] and steps else ""
    if summary["bit_inclination_deg"] > 0.0:
        named += f" (hole at {summary['bit_inclination_deg']:.1f} deg at the bit)"
    print(f"{named}: {steps} step{'' if steps == 1 else 's'} "
          f"({summary['simulated_s']:.1f} s) at {ran_at} in "
          f"{summary['wall_s']:.1f} s{compiled}; {returned}"
          + (f"; ended: {reason}" if reason else ""))
    window = base.config.metric_window
    short = (f" (the episode, {summary['simulated_s']:.1f} s, is shorter than the "
             f"window: they cover what it ran)" if summary["simulated_s"] < window else "")
    print(f"  episode mean of the {window:g} s window metrics{short}: SSI "
          f"{fixed(summary['mean_ssi'])}, stuck "
          f"{fixed(summary['mean_stuck_fraction'])}, whirl ratio "
          f"{fixed(summary['mean_whirl_ratio'])}, radial ratio "
          f"{fixed(summary['mean_radial_ratio'])}, bit lateral force "
          f"{summary['mean_lateral_force'] / KILO:.1f} kN, ROP "
          f"{summary['mean_rop'] * HOUR:.1f} m/h")
    print(f"  episode mean at the rig: surface torque "
          f"{summary['mean_surface_torque_kNm']:.2f} kN m, hook load "
          f"{summary['mean_hook_load_kN']:.1f} kN; at the bit: WOB "
          f"{summary['mean_weight_on_bit_kN']:.1f} kN")
    swings = summary["swing_per_block_rpm"]
    if swings is not None and len(swings) >= 2:
        lowest = min(rpm for t, rpm in speeds if t >= (len(swings) - 1) * SWING_BLOCK)
        print(f"  bit-speed swing (half of max - min) per {SWING_BLOCK:g} s: "
              + few([f"{v:.3g}" for v in swings], "in run_summary.json")
              + f" rpm: {swing_trend(swings, lowest)}")
    elif swings is not None:
        print(f"  (the bit-speed swing per {SWING_BLOCK:g} s, growing or decaying, needs "
              f"{2 * SWING_BLOCK:g} s or more of episode)")
    else:  # said, not left out: a tuning run of a policy looked for it
        print("  (no bit-speed swing reported: the set points move with the policy's "
              "actions, and their changes would read as swing)")
    if args.record is not None:
        print(f"  recording: {summary['recording']} (drill-env replay <file>)")
    print(f"wrote {args.out / 'run_summary.json'} (and a line of "
          f"{args.out / 'run_history.jsonl'}, which keeps every run's)")
    return status


def benchmark_set_points(args: argparse.Namespace, env_id: str | None) -> dict[str, float]:
    """``--rpm`` / ``--wob`` as BenchmarkSettings' set points (rad/s, N), checked against
    DrillString-v0's set-point ranges; refused with ``--task``."""
    from agents.benchmark import set_point_outside
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


def length_range(text: str) -> tuple[float, float]:
    """``"1300,1600"``: a range of string lengths in metres."""
    try:
        low, high = (float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"two lengths in m, LO,HI, got {text!r}") from None
    if not (math.isfinite(low) and math.isfinite(high) and 0.0 < low <= high):
        raise argparse.ArgumentTypeError(f"LO,HI in m with 0 < LO <= HI, got {text!r}")
    return low, high


def checked_string_lengths(lengths: tuple[float, float]) -> tuple[float, float]:
    """``--string-lengths`` judged as the random scenario judges its range, before any
    episode: its refusal named the length a seed drew, not the range typed."""
    from drill_env.scenarios import check_draws, make_scenario

    try:
        make_scenario("random", string_length_range=lengths)
        check_draws("random", {"string_length_range": lengths}, {})
    except ValueError as err:
        raise argparse.ArgumentTypeError(
            f"--string-lengths {lengths[0]:g},{lengths[1]:g}: {err}") from None
    return lengths


def cmd_benchmark(args: argparse.Namespace) -> int:
    from agents.benchmark import BenchmarkSettings, labels, run_benchmark
    from agents.registry import parse_controllers
    from drill_env.scenarios import SCENARIOS

    try:
        controllers = parse_controllers(args.controllers)
        labels(controllers)  # names given twice, or two that would share a table name
    except ValueError as err:
        raise argparse.ArgumentTypeError(f"--{err}") from None
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
        args.out = (Path("logs/benchmark") / (args.task or "")
                    / (f"config-{args.config.stem}" if args.config else ""))
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
        from agents.benchmark import set_point_guests

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
                                policy)
        if text:
            print(f"\n{text}")
    print(f"wrote {args.out / 'benchmark.csv'}, benchmark.md"
          + (", comparison.md" if args.paired is not None else "")
          + f" and the plots in {args.out}")
    return 0


def say_left_out(args: argparse.Namespace, config: Any) -> None:
    """Note on stderr the settings of the task's shipped hyperparameter entry that the
    ``--config`` file's entry leaves out (a --config file is a whole entry, as rl-zoo3's)."""
    from training.config import HYPERPARAMS, left_out_settings, taken_value

    flags = {"n_timesteps": args.timesteps, "seed": args.seed, "n_envs": args.n_envs}
    left = left_out_settings(config, args.config,
                             [key for key, value in flags.items() if value is not None])

    def here(key: str) -> str:  # the value the run takes (the shipped one alone read as
        known, value = taken_value(config, key)  # it: a new user's trial)
        return json.dumps(value) if known and value is not None else "the default"

    if left:
        shown = ", ".join(f"{key} (shipped {json.dumps(value)}, here {here(key)})"
                          for key, value in left)
        print(f"note: --config {args.config}: its {args.algo} entry leaves out {len(left)} "
              f"setting{'' if len(left) == 1 else 's'} of {HYPERPARAMS / args.task}.yml, "
              f"which the run takes at its defaults (SB3's, the task's, drill-env's) "
              f"instead: {shown}. A --config file is a whole entry, as rl-zoo3's: copy "
              "the task's file to change part of it", file=sys.stderr)


def cmd_train(args: argparse.Namespace) -> int:
    from training.config import ReplacedValueError, load_config
    from training.train import check_run_folder, holds_run, planned_steps, train

    if args.name is not None and (not args.name.strip() or args.name in (".", "..")
                                  or any(c in args.name for c in "/\\")):
        raise argparse.ArgumentTypeError(f"--name: a folder name inside --out, without "
                                         f"'/', got {args.name!r}")
    from training.config import VALIDATION_SEED

    if args.seed is not None and args.seed >= VALIDATION_SEED:
        raise argparse.ArgumentTypeError(
            f"--seed: must be below {VALIDATION_SEED}, got {args.seed} (the seeds from "
            f"{VALIDATION_SEED} on are the validation and held-out episodes)")
    if args.algo is None:  # a named run resumes with its own algorithm; else the default
        named = args.out / args.name if args.resume and args.name else None
        args.algo = (named and saved_algorithm(named)) or "sac"
    try:
        config = load_config(args.task, args.algo, args.config, n_timesteps=args.timesteps,
                             seed=args.seed, n_envs=args.n_envs)
    except ValueError as err:  # a field of the entry: a flag's if given, else the file's
        field, _, rest = str(err).partition(": ")
        flag, value = TRAIN_OVERRIDES.get(field.removeprefix(f"{args.algo}."), ("", ""))
        if flag and getattr(args, value) is not None and not isinstance(err, ReplacedValueError):
            raise argparse.ArgumentTypeError(f"{flag}: {rest}") from None
        if args.config is not None and field.startswith(f"{args.algo}."):
            raise argparse.ArgumentTypeError(f"--config {args.config}: {err}") from None
        raise
    if args.config is not None:  # a file of a few keys lost the task's tuned settings
        say_left_out(args, config)  # without a word (an outside trial's reward variant)
    if args.seeds is not None:
        return train_sweep(args, config)
    if args.ray_address is not None:
        raise argparse.ArgumentTypeError("--ray-address: a single run trains here; give "
                                         "--seeds to fan several runs out")
    if args.workers is not None:  # it started a full run without a word
        raise argparse.ArgumentTypeError("--workers: a single run trains in this process; "
                                         "give --seeds to train several runs side by side")
    from drill_env.sweep import check_folder_free
    from training.sweep import run_name

    run = args.out / (args.name or run_name(config, args.config and args.config.stem))
    saved = run / "config.yaml"
    # a run still training is said so, before any advice on what the folder holds
    check_folder_free(run, "this training run")
    if args.resume and not holds_run(run) and run.is_dir():
        # stopped before it saved anything (a Ctrl-C in its first seconds): a fresh start
        # is what resuming it gives ("--resume starts it", the interrupt said)
        print(f"note: {run} holds nothing of a run yet (stopped before it saved its "
              "config): --resume starts it", file=sys.stderr)
        args.resume = False
    if args.resume and not holds_run(run):
        raise argparse.ArgumentTypeError(f"--resume: no run in {run}; name it by --name, or "
                                         "by --seed (and --algo, --config) as it was "
                                         "started")
    if args.resume and args.config is None and saved.is_file():
        # a resumed run continues with the config it was started with (--config or not)
        config = saved_run_config(saved, args.task, args.algo, n_timesteps=args.timesteps,
                                  n_envs=args.n_envs, seed=args.seed)
    done = check_run_folder(run, args.resume, args.overwrite, config)  # before announcing
    planned = planned_steps(config, done)
    steps = f"{planned} env steps" + (f" ({config.n_timesteps} asked for, rounded up to a "
                                      "whole PPO rollout)" if planned != config.n_timesteps
                                      else "")
    print(f"training {config.algo.upper()} on {config.env_id}: {steps}, "
          f"{config.n_envs} batched envs, seed {config.seed} -> {run}")
    t0 = time.perf_counter()
    model = train(config, run, resume=args.resume, progress=not args.no_progress,
                  overwrite=args.overwrite)
    curve = run / "learning_curve.png"
    made = f", {curve}" if curve.exists() else " (no evaluation yet: no learning curve)"
    print(f"trained in {time.perf_counter() - t0:.0f} s: {model}, {run / 'vecnormalize.pkl'}"
          f"{made}; drill-env evaluate {shell_word(run)}")
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


#: Fields of a training entry that flags of `train` set: (flag, its args attribute).
TRAIN_OVERRIDES = {"n_timesteps": ("--timesteps", "timesteps"), "seed": ("--seed", "seed"),
                   "n_envs": ("--n-envs", "n_envs")}


def saved_algorithm(run: Path) -> str | None:
    """The algorithm the run in folder ``run`` was trained with (None: no config there)."""
    from training.config import read_run_config

    saved = run / "config.yaml"
    if not saved.is_file():
        return None
    algo = read_run_config(saved).get("algo")
    return algo if algo in ("ppo", "sac") else None


def saved_run_config(saved: Path, task: str, algo: str, **overrides: Any) -> Any:
    """The :class:`~training.config.TrainConfig` a run saved (its ``config.yaml``), with
    the ``overrides`` given (None: keep the run's)."""
    from drill_env.physics.validation import from_dict
    from training.config import TrainConfig, read_run_config, without_inert_keys

    data = without_inert_keys(read_run_config(saved))
    for flag, value in (("task", task), ("algo", algo)):
        if data.get(flag, value) != value:
            raise argparse.ArgumentTypeError(f"--{flag}: {saved.parent} was trained with "
                                             f"{data[flag]}, not {value}")
    data.update({k: v for k, v in overrides.items() if v is not None})
    try:
        return from_dict(TrainConfig, data)
    except ValueError as err:  # a field of the saved file (a hand edit; the flags passed
        # load_config's checks already): name the file
        raise ValueError(f"{saved}: {err}") from None


def train_sweep(args: argparse.Namespace, config) -> int:
    from training.sweep import train_seeds

    try:
        seeds = [int(k) for k in args.seeds.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"--seeds: comma-separated integers, got "
                                         f"{args.seeds!r}") from None
    from training.config import VALIDATION_SEED

    if any(not 0 <= k < VALIDATION_SEED for k in seeds) or len(set(seeds)) < len(seeds):
        raise argparse.ArgumentTypeError(f"--seeds: distinct integers in 0-"
                                         f"{VALIDATION_SEED - 1} (the validation seeds "
                                         f"start at {VALIDATION_SEED}), got {args.seeds!r}")
    if args.name is not None or args.resume or args.overwrite or args.seed is not None:
        raise argparse.ArgumentTypeError("--seeds: runs are named <task>_<algo>_seed<k> "
                                         "(<task>_<algo>_<config file>_seed<k>) and "
                                         "always resume; drop --name / --resume / "
                                         "--overwrite / --seed")
    from training.train import check_learns

    check_learns(config, 0)
    t0 = time.perf_counter()
    results = train_seeds(config, seeds, args.out, workers=args.workers,
                          ray_address=args.ray_address, progress=not args.no_progress,
                          label=args.config and args.config.stem)
    for r in results:
        best = "no validation yet (raise --timesteps past eval_freq)" \
            if r["best_return"] is None else \
            f"best validation return {r['best_return']:.1f} at {r['best_at_steps']} steps"
        print(f"seed {r['seed']}: {best} -> {r['run']}")
    print(f"{len(results)} runs in {time.perf_counter() - t0:.0f} s; summary in "
          f"{args.out / 'train_sweep.md'}")
    return 0


def default_evaluation_folder(run: Path, fidelity: str | None = None) -> Path:
    """``RUN/evaluation`` beside a training run; for a policy shipped in the package
    (``agents/trained/<task>``), ``logs/evaluation/<task>``: not into the source tree.
    At a physics level other than the run's own (``--fidelity``), ``_<level>`` is added,
    so that the evaluation at the run's level is kept beside it."""
    from agents.learned import TRAINED

    if run.resolve().is_relative_to(TRAINED):
        folder = Path("logs") / "evaluation" / run.resolve().name
    else:
        folder = run / "evaluation"
    if fidelity is not None and (run / "config.yaml").exists():
        from training.config import read_run_config
        from training.evaluate import trained_fidelity

        own = trained_fidelity(read_run_config(run / "config.yaml").get("env_kwargs") or {})
        if fidelity != own:
            folder = folder.with_name(f"{folder.name}_{fidelity}")
    return folder


def which_model(run: Path, model: Path) -> str:
    """What ``model`` (from :func:`agents.learned.policy_files`) is, said when evaluating
    ``run``: a training run's best or final model, its last checkpoint, or the model a
    shipped policy folder (a README, no run.json) holds."""
    if model.name.startswith("best_"):
        return "the best model on the validation seeds"
    if model.name != "model.zip":
        return "the last checkpoint: the run stopped before its first evaluation"
    if (run / "README.md").exists() and not (run / "run.json").exists():
        from agents.learned import TRAINED

        if run.resolve().is_relative_to(TRAINED):
            return "the shipped policy's chosen model: its README says which"
        return "the folder's model: no run.json, not a training run's record"
    return "the run's final model: it kept no best model"


def cmd_evaluate(args: argparse.Namespace) -> int:
    from agents.learned import TRAINED, no_such_folder
    from training.config import TASKS
    from training.evaluate import evaluate_run

    # a task's name is its shipped policy, unless a file or folder here has that name
    local = f"; {args.run} here is yours, not the task's shipped policy, which is " \
        f"{TRAINED / str(args.run)}" if str(args.run) in TASKS else ""
    if not args.run.exists() and local:
        args.run, local = TRAINED / str(args.run), ""
    if not args.run.is_dir():
        what = f"{args.run} is a file, not a run folder{local}" if args.run.exists() else \
            no_such_folder(args.run, sorted(TASKS))
        raise argparse.ArgumentTypeError(f"RUN: {what} (a run folder of drill-env train, "
                                         "e.g. logs/runs/<name>, or a task's name for its "
                                         f"shipped policy: {', '.join(sorted(TASKS))})")
    if not (args.run / "config.yaml").exists():
        from agents.learned import ELSEWHERE

        raise argparse.ArgumentTypeError(f"RUN: {args.run} is not a run folder of drill-env "
                                         f"train (no config.yaml){local}; {ELSEWHERE}, then "
                                         "drill-env benchmark --task")
    from agents.learned import policy_files
    from drill_env.sweep import held_by_another

    live = held_by_another(args.run)
    try:
        model, _ = policy_files(args.run)
    except FileNotFoundError as err:  # a run stopped before its first evaluation
        why = " (still training: evaluate it once it has saved one)" if live else \
            " (stopped before its first checkpoint: drill-env train --resume starts it " \
            "again)"
        raise argparse.ArgumentTypeError(f"RUN: {str(err).removeprefix('learned: ')}{why}"
                                         ) from None
    print(f"evaluating {model} ({which_model(args.run, model)})")
    if live:  # (went ahead without a word: a new user's trial)
        print(f"note: {args.run} is held by another drill-env process, a training still "
              "running: this evaluates the model it has saved so far, and goes stale when "
              "training saves a better one", file=sys.stderr)
    if local:  # a folder here took a task's name (a security review: said only on errors)
        print(f"note: {local.removeprefix('; ')}")
    out = args.out or default_evaluation_folder(args.run, args.fidelity)
    evaluate_run(args.run, seeds=args.seeds, workers=args.workers, out=out,
                 ray_address=args.ray_address, fidelity=args.fidelity)
    print(f"wrote {out / 'benchmark.csv'}, benchmark.md, comparison.md and the plots")
    return 0


def cmd_stability_map(args: argparse.Namespace) -> int:
    from drill_env import stability_map as sm
    from drill_env.physics.validation import comma_items

    names = tuple(p.upper() for p in comma_items(args.positions, "--positions",
                                                  "position"))  # p1 too
    unknown = [p for p in names if p not in sm.POSITIONS]
    if unknown or not names:
        raise argparse.ArgumentTypeError(f"--positions: unknown {unknown or args.positions!r};"
                                         f" choose from {','.join(sm.POSITIONS)}")
    from drill_env.physics.modes import torsional_modes

    string = read_overrides(args.config)  # a string (and rock, ...) of your own: {} without
    try:
        first = sm.map_config(names[0], string)
    except ValueError as err:
        raise argparse.ArgumentTypeError(f"--config {args.config}: {err}") from None
    # the stick test reads the last seconds: they must hold a stick-slip cycle, which
    # lasts longer than the string's first torsional period
    period = 1.0 / float(torsional_modes(first).frequency[0])
    if args.seconds < 2.0 * period:
        least = math.ceil(20.0 * period) / 10.0  # two periods, rounded up to what is shown
        raise argparse.ArgumentTypeError(
            f"--seconds: {args.seconds:g} s is too short to tell stick-slip: the string's "
            f"first torsional period is {period:.2f} s; give at least {least:.1f} s "
            f"(stick-slip can take ~25 s to grow from the kick: the default "
            f"{sm.DEFAULT_SETTINGS.seconds:g} s lets it)")
    settings = sm.MapSettings(seconds=args.seconds,
                              measure=min(sm.DEFAULT_SETTINGS.measure, args.seconds))
    configs = {p: sm.map_config(p, string) for p in names} if string else None
    if args.controller is not None:
        from agents.registry import CLASSICAL, CONTROLLERS, is_imported, make_controller
        from drill_env.physics.validation import did_you_mean

        args.controller = canonical_controller(args.controller)
        # the map holds the set points fixed: only the top drive's own loops apply
        drive = [n for n in CLASSICAL if make_controller(n).rate == "drive"]
        own = typed_controller(args.controller) if is_imported(args.controller) else None
        if args.controller not in drive and (own is None or own.rate != "drive"):
            why = ("acts at the policy rate (on the set points, or a task-1 policy on the "
                   "speed command), which the map does not run: it holds the set points "
                   "fixed under the top drive's own loop"
                   if own is not None or args.controller in CONTROLLERS
                   or args.controller.startswith(("learned:", "constant:", "held:"))
                   else "is not a controller" + did_you_mean(args.controller, drive))
            raise argparse.ArgumentTypeError(
                f"--controller: {args.controller} {why}; choose a drive-rate controller: "
                f"{', '.join(drive)} or one of your own (rate = 'drive')")
        controller = own or typed_controller(args.controller)
        from agents.base import SetPointController

        if own is not None and type(own).act is not SetPointController.act:
            raise argparse.ArgumentTypeError(  # it mapped the loop of physics() alone
                f"--controller: {args.controller} has rate 'drive' but an act() of its "
                "own, which the map does not run (it holds the set points fixed under the "
                "top drive's loop of physics()); a controller that acts at the policy "
                "rate sets rate = 'policy' and is judged by drill-env benchmark")
        configs = {p: sm.map_config(p, {**string, **controller.physics()}) for p in names}
    from drill_env.sweep import folder_lock

    # two maps into one --out appended to one points file and each rewrote the
    # JSON and picture with its own positions only
    with folder_lock(args.out, "this stability map"):
        store = args.out / MAP_POINTS_FILE
        t0 = time.perf_counter()
        maps = sm.stability_maps(names, args.rpm_step, args.wob_step * KILO, settings,
                                 args.max_rpm, args.max_wob * KILO, progress=True, store=store,
                                 workers=args.workers, configs=configs,
                                 ray_address=args.ray_address)
        print(sm.format_maps(maps))
        runs = sum(m.runs for m in maps)
        cells = sum(m.unstable.size for m in maps)
        print(f"{runs} simulations of {args.seconds:.0f} s for {cells} grid points (boundary "
              f"tracking; finished points are kept in {store} and reused by a rerun) in "
              f"{time.perf_counter() - t0:.1f} s")
        from agents.benchmark import label  # your own controller by its table name

        name = label(args.controller or "stiff")
        source = None if args.config is None else str(args.config.resolve())  # one per file
        json_path = args.out / f"{sm.map_stem(name, source)}.json"
        before = map_positions(json_path)
        paths = sm.write_maps(maps, args.out, settings, name, string, source)
        print("wrote " + ", ".join(str(p) for p in paths))
        made = {m.position for m in maps}  # the file's other maps were kept from before
        kept = [p for p in map_positions(paths[0]) if p not in made]
        if kept:
            print(f"with the maps of {', '.join(kept)} already in {paths[0]} (same settings "
                  "and grid)")
        replaced = [p for p in before if p not in made and p not in kept]
        if replaced:
            print(f"note: the maps of {', '.join(replaced)} that {paths[0]} held were made with "
                  "other settings, grid, physics or code: left out of the file and picture "
                  "(map them again, or give another --out to keep both)")
    return 0


def map_positions(path: Path) -> list[str]:
    """The positions of the maps in a stability-map JSON file, [] without a readable one."""
    try:
        return [m["position"] for m in json.loads(path.read_text(encoding="utf-8"))["maps"]]
    except (OSError, ValueError, KeyError, TypeError):
        return []


def read_overrides(path: Path | None) -> dict[str, Any]:
    """The config overrides of a YAML file of nested config sections (a string of
    components, a rock, the solver), as dotted paths; {} without a file."""
    if path is None:
        return {}
    from drill_env.physics.config import flatten
    from drill_env.physics.validation import read_yaml

    if not path.is_file():
        raise ValueError(f"--config {path}: "
                         + (not_a_file(path) if path.exists() else "no such file"))
    try:
        data = read_yaml(path)
    except ValueError as err:
        raise ValueError(f"--config {err}") from None
    if data is None:  # an empty file (or only comments): nothing to override, said
        warnings.warn(f"--config {path} holds no settings (empty, or only comments): the "
                      "defaults run", UserWarning, stacklevel=2)
        return {}
    if not isinstance(data, dict):
        raise ValueError(f"--config {path}: expected a mapping of config sections")
    from drill_env.env_config import ENV_FIELDS

    for key in data:  # what a command's options set, written into the file
        if key in NOT_PHYSICS:
            raise ValueError(f"--config {path}: {key}: not a config section; "
                             f"{NOT_PHYSICS[key]}")
        if key in ENV_FIELDS:  # (listed as an unknown field of SimulationConfig)
            raise ValueError(f"--config {path}: {key}: an env setting (EnvConfig), not the "
                             "simulator's config the file changes; the commands build their "
                             "env themselves (its length: --duration)")
    try:
        return flatten(data)
    except ValueError as err:  # a key that is no name (1: 2): said with the file
        raise ValueError(f"--config {path}: {err}") from None


#: Keys a --config file may be given that belong to a command's options instead.
NOT_PHYSICS = {
    "rpm": "the speed is an option of the command (drill-env run --rpm, in rpm)",
    "wob": "the weight on bit is an option of the command (drill-env run --wob, in kN)",
    "weight_on_bit": "the weight on bit is an option of the command (drill-env run --wob, "
                     "in kN)",
    "duration": "the episode's length is an option of the command (--duration, in s)",
    "episode_duration": "the episode's length is an option of the command (--duration, in s)",
    "seed": "the seed is an option of the command (--seed or --seeds)",
    "scenario": "the scenario is an option of the command (--scenario); the file changes "
                "its config",
    "controller": "the controller is an option of the command (--controller or "
                  "--controllers)",
}


def with_overrides(config, path: Path | None):
    """``config`` with the nested overrides of a YAML file merged in (dotted-path errors)."""
    return _merged(config, read_overrides(path), path)


def _merged(config, overrides: dict[str, Any], path: Path | None):
    """``config`` with the ``overrides`` read from ``path`` (the bit kept at the bottom of
    the string: :func:`~drill_env.scenarios.with_physics`); a bad field names the file."""
    from drill_env.scenarios import with_physics

    try:
        return with_physics(config, overrides)
    except ValueError as err:
        raise ValueError(f"--config {path}: {err}") from None


def checked_overrides(path: Path | None, scenarios: Sequence[str],
                      params: Mapping[str, Any] | None = None, narrow: str = "") -> dict[str, Any]:
    """:func:`read_overrides`, merged once into each scenario's config here, so that a
    bad field fails now, named by its dotted path, not in the first episode. A randomised
    scenario is checked on the longest string its ``params``' range draws (a survey must
    reach that one; it was an unseeded draw from the default range, so that a survey
    shorter than the default range's top failed at random whatever --string-lengths);
    ``narrow``: the option that narrows the range ("": the command has none)."""
    from drill_env.overrides import drawn_with_physics
    from drill_env.scenarios import RANDOMISED, make_scenario

    overrides = read_overrides(path)  # the file read once
    for name in scenarios if overrides else ():
        if name not in RANDOMISED:
            _merged(make_scenario(name).config, overrides, path)
            continue
        try:
            drawn_with_physics(name, dict(params or {}), overrides, narrow=narrow)
        except ValueError as err:
            raise ValueError(f"--config {path}: {str(err).removeprefix('physics: ')}"
                             ) from None
    return overrides


def cmd_modes(args: argparse.Namespace) -> int:
    import numpy as np

    from drill_env.physics import modes as md
    from drill_env.scenarios import RANDOMISED, make_scenario

    if args.seed is not None and args.scenario not in RANDOMISED:
        raise argparse.ArgumentTypeError(f"--seed: draws a randomised scenario "
                                         f"({', '.join(sorted(RANDOMISED))}); "
                                         f"{args.scenario} is fixed")
    # a randomised scenario's string is drawn as an env's reset with this seed draws it
    scenario = make_scenario(args.scenario, rng=np.random.default_rng(args.seed or 0)) \
        if args.scenario in RANDOMISED else make_scenario(args.scenario)
    config = with_overrides(scenario.config, args.config)
    wob = args.wob * KILO if args.wob is not None else scenario.weight_on_bit
    try:
        md.require_vertical(config)
    except ValueError as err:  # the scenarios offered are vertical: the file set the well
        raise argparse.ArgumentTypeError(f"--config {args.config}: {err}") from None
    torsional = md.torsional_modes(config, args.top, args.n)
    try:
        lateral = md.lateral_modes(config, wob, n_modes=args.n)
    except ValueError as err:
        raise argparse.ArgumentTypeError(f"--wob: {str(err).partition(': ')[2]}") from None
    source = args.scenario  # what the title names: the string analysed
    described = scenario.description
    if args.config is not None:
        source = (f"{args.config.name} (scenario {args.scenario})"
                  if config.string != scenario.config.string
                  else f"{args.scenario} with {args.config.name}")
        # the scenario's description (its rock, bit, string) holds no more for what the
        # file changed: name those sections instead
        changed = [f.name for f in dataclasses.fields(config)
                   if getattr(config, f.name) != getattr(scenario.config, f.name)]
        if changed:
            described = f"the file changes its {', '.join(changed)}"
    print(f"{source}: {described}; string {config.string.length:.0f} m, "
          f"WOB {wob / KILO:.0f} kN, neutral point "
          f"{md.neutral_point_height(config, wob):.0f} m above the bit")
    from drill_env.physics.statics import bit_buoyed_weight, pipe_buckling

    # what a scenario refuses to start at; a torsion-only one drills it straight
    then = ("a scenario refuses to start there" if config.solver.lateral else "this "
            "scenario is torsion only (solver.lateral false): drill-env run drills it with "
            "the string straight")
    for b in pipe_buckling(config, wob):
        print(f"note: at {wob / KILO:.0f} kN the {b.component} is compressed by "
              f"{b.compression / KILO:.1f} kN {b.place}, beyond its buckling load "
              f"{b.buckling_load / KILO:.1f} kN: it would buckle, and {then}; the modes "
              "below are of the straight string")
    for note in tension_notes(config, wob):
        print(note)
    print(f"\n{'component (bit up)':<22} {'length':>7} {'air':>8} {'in mud':>8} "
          f"{'N bottom':>9} {'N top':>9}   (m, kN; tension > 0)")
    for load in md.component_loads(config, wob):
        print(f"{load.component:<22} {load.length:7.1f} {load.weight / KILO:8.1f} "
              f"{load.buoyed_weight / KILO:8.1f} {load.force_bottom / KILO:9.1f} "
              f"{load.force_top / KILO:9.1f}")
    print(f"(the lowest N bottom is the bit's own weight in mud, "
          f"{bit_buoyed_weight(config) / KILO:.1f} kN, less the WOB)")
    print()
    header = f"{'mode':<12} {'f (Hz)':>8} {'damping':>8}   boundary"
    print(header + "\n" + "-" * 78)
    for m in (torsional, lateral):
        for i, (f, z) in enumerate(zip(m.frequency, m.damping_ratio, strict=True)):
            print(f"{m.kind + ' ' + str(i + 1):<12} {f:8.3f} {z:8.1%}   "
                  + (m.boundary if i == 0 else ""))
        for f, z in zip(m.overdamped, m.overdamped_ratio, strict=True):
            print(f"({m.kind} mode at {f:.3f} Hz undamped is overdamped, damping {z:.0%}: "
                  "it creeps back without oscillating, not listed nor counted above)")
        if len(m.frequency) < args.n:  # the mesh has no more oscillating modes
            print(f"({m.kind}: -n {args.n} asked, the model has {len(m.frequency)} "
                  "oscillating modes; overdamped ones are not listed)")
    laws = top_drive_laws(config)
    given_f = config.top_drive.tuning_frequency is not None
    print("\ntop-drive controllers tuned for this string (docs/controllers.md; Z = "
          f"{laws[0].impedance:.1f} N m s/rad, f_s = {laws[1].tuning_frequency:.4f} Hz ("
          + ("the config's top_drive.tuning_frequency" if given_f else
             "fixed top, undamped") + f"), J_td = {laws[0].inertia:g} kg m^2; a value the "
          "config sets wins under every controller that uses it):")
    print(f"  {'controller':<12} {'P (N m s/rad)':>14} {'I (N m/rad)':>12}   torque feedback")
    for law in laws:
        feedback = "none" if law.torque_feedback == "none" else (
            f"{law.torque_feedback.replace('_', '-')} at {law.filter_frequency:.4g} Hz, "
            f"gain {law.feedback_gain:.3g} rad/s per N m")
        chosen = "   <- the config's" if config.top_drive != scenario.config.top_drive \
            and law.controller == config.top_drive.controller else ""
        print(f"  {law.controller.replace('_', '-'):<12} {law.proportional_gain:14,.0f} "
              f"{law.integral_gain:12,.0f}   {feedback}{chosen}")
    thresholds = stick_slip_thresholds(config, wob)
    rock = config.formation.rocks[0].name
    print(f"\nlinear stick-slip threshold at {wob / KILO:.0f} kN on the {rock} rock (steady "
          "rotation below it is unstable: the bit's falling friction against the string's "
          "damping and the drive's loop; drill_env.physics.stability):")
    for name, rpm in thresholds.items():
        print(f"  {name:<12} " + ("none: stable at every speed" if rpm is None else
                                  f"{rpm:6.1f} rpm"))
    crit = md.critical_speeds(config, (torsional, lateral), args.max_rpm)
    print(f"\ncritical speeds up to {args.max_rpm:.0f} rpm:")
    for c in crit:
        print(f"  {c.rpm:6.1f} rpm   {c.mode:<12} x {c.excitation}")
    args.out.mkdir(parents=True, exist_ok=True)
    png = args.out / "modes_critical_speeds.png"
    title = f"{source}: natural frequencies and excitations (WOB {wob / KILO:.0f} kN)"
    save_whole(png, lambda file: md.critical_speed_chart(config, (torsional, lateral), file,
                                                         args.max_rpm, title))
    data = {"scenario": args.scenario, "weight_on_bit_N": wob,
            # keys without a unit in their name (a drilling engineer's review)
            "units": {"components_N": {"length": "m", "bottom_depth": "m", "weight": "N",
                                       "buoyed_weight": "N", "force_bottom": "N",
                                       "force_top": "N"},
                      "critical_speeds": {"rpm": "rpm", "frequency": "Hz"},
                      "top_drive_controllers": {
                          "proportional_gain": "N m s/rad", "integral_gain": "N m/rad",
                          "feedback_gain": "rad/s per N m", "filter_frequency": "Hz",
                          "filter_damping": "1", "tuning_frequency": "Hz",
                          "impedance": "N m s/rad", "inertia": "kg m^2"}},
            "components_N": [vars(load) for load in md.component_loads(config, wob)],
            "modes": [{"kind": m.kind, "boundary": m.boundary,
                       "frequency_Hz": m.frequency.tolist(),
                       "damping_ratio": m.damping_ratio.tolist(),
                       "overdamped_frequency_Hz": m.overdamped.tolist(),
                       "overdamped_damping_ratio": m.overdamped_ratio.tolist()}
                      for m in (torsional, lateral)],
            "critical_speeds": [c.__dict__ for c in crit],
            "stick_slip_threshold_rpm": thresholds, "stick_slip_rock": rock,
            "top_drive_controllers": [
                {k: None if isinstance(v, float) and not math.isfinite(v) else v
                 for k, v in dataclasses.asdict(law).items()} for law in laws]}
    save_text(args.out / "modes.json", json.dumps(data, indent=2))
    print(f"wrote {png} and {args.out / 'modes.json'}")
    return 0


def stick_slip_thresholds(config: Any, wob: float) -> dict[str, float | None]:
    """The linear stick-slip threshold (rpm) at ``wob`` on ``config``'s first rock under
    each drive-rate controller (None: stable at every speed): a SoftSpeed tuning that
    cannot hold a heavy drive shows there (docs/controllers.md)."""
    from drill_env.physics.simulator import Simulator
    from drill_env.physics.stability import stick_slip_threshold

    out = {}
    for each in controller_configs(config):
        with warnings.catch_warnings():  # (its notes said above, once)
            warnings.simplefilter("ignore")
            sim = Simulator(each)
        low, high = 0.05, 60.0  # rad/s: the range searched (0.5-573 rpm)
        found = stick_slip_threshold(sim, wob, omega_range=(low, high))
        # None: stable at every speed searched (a rising or flat rock curve)
        name = each.top_drive.controller.replace("_", "-")
        out[name] = None if found <= low else found / RPM
    return out


def controller_configs(config: Any) -> list[Any]:
    """``config`` under each of the four drive-rate controllers, stiff first: what it sets
    of the drive wins, but a feedback gain only where the drive runs a feedback (the
    others refuse one: a soft_torque gain is not the stiff PI's)."""
    from drill_env.physics.config import replace

    out = []
    for name in ("stiff", "soft_speed", "soft_torque", "z_torque"):
        drive = replace(config.top_drive, controller=name, feedback_gain=None)
        if drive.feedback() != "none":
            drive = replace(drive, feedback_gain=config.top_drive.feedback_gain)
        out.append(replace(config, top_drive=drive))
    return out


def top_drive_laws(config: Any) -> list[Any]:
    """The four drive-rate controllers as ``config``'s string tunes them
    (``top_drive.resolve``), stiff first."""
    from drill_env.physics.top_drive import resolve

    return [resolve(each) for each in controller_configs(config)]


def cmd_well(args: argparse.Namespace) -> int:
    from drill_env.overrides import sets_section
    from drill_env.physics.config import MAX_STRING_LENGTH
    from drill_env.physics.trajectory import Survey, Trajectory
    from drill_env.scenarios import make_scenario
    from drill_env.well import CHART_STEP, WELLS, write_well

    overrides = read_overrides(args.config)  # the file read once
    config = _merged(make_scenario(args.scenario).config, overrides, args.config)
    if args.survey is not None and args.well is not None:
        raise argparse.ArgumentTypeError("--well: give a preset well or --survey, not both")
    if args.total_md is not None and args.well is None and (args.survey or config.well.md):
        raise argparse.ArgumentTypeError("--total-md: sets the length of a preset --well (or "
                                         "of j_shaped, drawn when nothing gives a well); a "
                                         "--survey's, the scenario's or --config's well has "
                                         "its own")
    if args.survey is not None:
        try:
            survey = Survey.from_csv(args.survey)
        except ValueError as err:
            where = "--survey" if str(args.survey) in str(err) else f"--survey {args.survey}"
            raise argparse.ArgumentTypeError(f"{where}: {err}") from None
        name, source = args.survey.stem, "--survey"
    elif args.well is not None or not config.well.md:  # no survey of its own
        name = args.well or "j_shaped"
        total_md = args.total_md if args.total_md is not None else DEFAULT_WELL_MD
        if total_md > MAX_STRING_LENGTH:  # the longest string a config takes
            raise argparse.ArgumentTypeError(f"--total-md: must be <= {MAX_STRING_LENGTH:g} m, "
                                             f"got {total_md:g}")
        try:
            survey = WELLS[name](total_md)
        except ValueError as err:  # the profile's curves do not fit in it
            raise argparse.ArgumentTypeError(
                f"--total-md: {str(err).removeprefix('survey.total_md: ')}") from None
        source = "--total-md"
    else:  # the scenario's hole, or the one --config gives (its well section)
        well = config.well
        survey = Survey.from_stations(well.md, well.inclination, well.azimuth, warn=False)
        given = sets_section(overrides, "well")
        # (a scenario's hole is named apart from the preset well of the same name, which
        # --well draws at another length: neither overwrites the other's chart)
        name, source = ((args.config.stem, f"--config {args.config}") if given
                        else (f"scenario_{args.scenario}", f"--scenario {args.scenario}"))
    trajectory = Trajectory(survey)
    bha = sum(section.length for section in config.string.lower)
    shortest = max(bha, CHART_STEP)
    if trajectory.total_md <= shortest:
        raise argparse.ArgumentTypeError(
            f"{source}: the well is {trajectory.total_md:g} m long; the chart needs more than "
            f"{shortest:g} m (the string's BHA is {bha:g} m, the chart's depth step "
            f"{CHART_STEP:g} m)")
    from drill_env.physics.validation import comma_items

    items = comma_items(args.friction, "--friction", "factor")
    if not items:
        raise argparse.ArgumentTypeError("--friction: give at least one factor")
    try:
        frictions = [float(v) for v in items]
    except ValueError:
        raise argparse.ArgumentTypeError(f"--friction: comma-separated numbers, got "
                                         f"{args.friction!r}") from None
    bad = [f for f in frictions if not (math.isfinite(f) and 0.0 <= f <= 2.0)]
    if bad:  # (none given is said above)
        raise argparse.ArgumentTypeError(f"--friction: factors in [0, 2], got {args.friction!r}")
    # the string the chart's loads are of (a file of only a well was named as the
    # string's: "string of curved.yaml"; one of the mud said nothing of it)
    beyond_well = any(not sets_section((key,), "well") for key in overrides)  # (--config's)
    whose = (args.config.name if sets_section(overrides, "string") else
             f"the {args.scenario} scenario" + (f" with {args.config.name}" if beyond_well
                                                else ""))
    # the file names the string too where it is not the default scenario's: charts of one
    # well for two strings overwrote each other (a new user's trial)
    strung = [args.scenario] if args.scenario != "default" \
        and name != f"scenario_{args.scenario}" else []
    if beyond_well and name != args.config.stem:
        strung.append(args.config.stem)
    name = "_".join((name, *strung))
    paths = write_well(name, trajectory, config, args.out, frictions, whose)
    end, _, _ = trajectory.at(trajectory.total_md)
    print(f"well {name}: {trajectory.total_md:.0f} m MD, TVD {end[0, 2]:.0f} m, departure "
          f"{math.hypot(end[0, 0], end[0, 1]):.0f} m, inclination at TD "
          f"{math.degrees(trajectory.inclination(trajectory.total_md)[0]):.1f} deg")
    table = json.loads(paths[1].read_text(encoding="utf-8"))["torque_drag"]
    print(f"at TD (the survey's end), off bottom (soft string, string of {whose}): hook load "
          "pick-up / rotating / slack-off (kN), rotating wall torque (kN m)")
    for mu in frictions:
        row = table[f"mu={mu:g}"]
        print(f"  mu {mu:<4g} {row['pick_up'][-1] / KILO:8.1f} {row['rotating'][-1] / KILO:8.1f} "
              f"{row['slack_off'][-1] / KILO:8.1f}   {row['torque'][-1] / KILO:6.2f}")
    if any(table[f"mu={mu:g}"]["slack_off"][-1] < 0.0 for mu in frictions):
        print("  (a negative slack-off: at that friction the string does not slide down under "
              "its own weight; it must be pushed)")
    print("wrote " + ", ".join(str(p) for p in paths))
    return 0


def cmd_speed(args: argparse.Namespace) -> int:
    from drill_env.tools.speed import FULL, QUICK, SECTIONS, parse_sections, run_speed
    from training.speed import RUNNER

    runners = {"training": RUNNER}
    try:
        sections = (parse_sections(args.sections, extra=runners)
                    if args.sections is not None else (*SECTIONS, *runners))
    except ValueError as err:
        raise argparse.ArgumentTypeError(f"--{err}") from None
    run_speed(sections, QUICK if args.quick else FULL, args.out, runners=runners)
    return 0


def cmd_replay(args: argparse.Namespace) -> int:
    from drill_env.recording import check_recording, replay

    for path in args.paths:  # what the viewer would show as an empty page, refused here
        if path.is_dir():
            inside = sorted(p.name for p in path.glob("*.rrd"))
            raise argparse.ArgumentTypeError(
                f"FILE: {path} is a folder; give its recordings" + (
                    f": {', '.join(inside[:3])}{' ...' if len(inside) > 3 else ''}"
                    if inside else " (it holds no .rrd file)"))
        if not path.is_file():
            raise argparse.ArgumentTypeError(f"FILE: no recording at {path}")
        if path.suffix != ".rrd":
            raise argparse.ArgumentTypeError(f"FILE: {path} is not a rerun recording (.rrd)")
        with path.open("rb") as f:  # rerun's files start "RRF" and a format version
            if f.read(3) != b"RRF":
                raise argparse.ArgumentTypeError(f"FILE: {path} is not a rerun recording "
                                                 "(no RRF header)")
        try:
            warning = check_recording(path)
        except ValueError as err:  # the library names its argument; the usage says FILE
            text = str(err)
            raise argparse.ArgumentTypeError(
                "FILE: " + text.removeprefix("path: ") if text.startswith("path: ") else text
            ) from None
        if warning:
            print(f"warning: {warning}", file=sys.stderr)
    if args.port is not None and not args.web:
        raise argparse.ArgumentTypeError("--port: the web viewer's port; add --web")
    from drill_env.recording.replay import no_display

    if not args.web and no_display():
        raise argparse.ArgumentTypeError("no display here (DISPLAY is not set) for "
                                         "the native viewer; add --web to serve the web "
                                         "viewer instead")
    if args.web:
        print("serving the web viewer: open the URL on rerun's line below (its server keeps "
              "one core busy while it runs: Ctrl-C when done)", file=sys.stderr)
    try:  # the port is checked there, once, just before the viewer takes it
        code = replay(args.paths, web=args.web, web_viewer_port=args.port,
                      **({"bind": args.bind} if args.bind is not None else {}))
    except ValueError as err:
        for name, flag in (("web_viewer_port", "--port"), ("bind", "--bind")):
            if str(err).startswith(name):
                raise argparse.ArgumentTypeError(
                    f"{flag}{str(err).removeprefix(name)}") from None
        raise
    return int(code) if isinstance(code, int) else 0


# --------------------------------------------------------------------------- parser


def parser() -> argparse.ArgumentParser:
    from drill_env import __version__
    from drill_env.scenarios import DEVIATED, SCENARIOS

    top = argparse.ArgumentParser(prog="drill-env", description=DESCRIPTION,
                                  formatter_class=_Formatter)
    top.add_argument("--version", action="version", version=f"drill-env {__version__}")
    sub = top.add_subparsers(dest="command", required=True, metavar="command")

    def add(name: str, help_text: str, func: Callable[[argparse.Namespace], int]
            ) -> argparse.ArgumentParser:
        # no abbreviations: `evaluate RUN --seed 3` quietly meant --seeds 3
        p = sub.add_parser(name, help=help_text, description=help_text,
                           formatter_class=_Formatter, allow_abbrev=False)
        p.set_defaults(func=func, command_parser=p)
        return p

    p = add("demo", "the main job: stick-slip at 50 vs 100 rpm, then the controller "
                    "benchmark on the default scenarios; outputs in --out", cmd_demo)
    p.add_argument("--out", type=out_folder, default=Path("logs"), help="output folder")
    p.add_argument("--workers", type=integer(1), default=None,
                   help="local processes for the benchmark (default: the cores this "
                        "process may use)")

    p = add("run", "one episode with a controller at the scenario's (or the given) set "
                   "points; optional rerun recording", cmd_run)
    p.add_argument("--scenario", default="default", choices=sorted(SCENARIOS),
                   help="the scenario")
    p.add_argument("--controller", default="stiff",
                   help="controller name (stiff, soft-speed, soft-torque, z-torque, driller, "
                        "learned, learned:<run folder>, constant:<rpm>/<kN>, the trivial "
                        "policies random and held:<action>[/<action>], or your own "
                        "as <file.py or module>:<class>: docs/controllers.md)")
    p.add_argument("--rpm", type=number("rpm"), default=None,
                   help="surface speed set point in rpm, in the env's rpm_range (0-200 by "
                        "default; 0: the string held still) (default: the scenario's)")
    p.add_argument("--wob", type=kilonewtons, default=None,
                   help="weight on bit in kN (default: the scenario's)")
    p.add_argument("--seed", type=integer(0), default=0, help="episode seed")
    p.add_argument("--duration", type=number("s", low=0.0, low_inclusive=False), default=None,
                   help="episode length in simulated s (default: the scenario's)")
    p.add_argument("--fidelity", choices=("full", "fast"), default=None,
                   help="physics level (docs/performance.md; default: the env's own, full "
                        "for DrillString-v0, fast for a task's learned policy)")
    p.add_argument("--start-kick", type=number("", high=0.5), default=0.02,
                   help="relative bit-speed kick at the start, drawn from the seed (as the "
                        "benchmark's; 0: start exactly settled, stick-slip then takes "
                        "over a minute to grow)")
    p.add_argument("--record", type=user_path, default=None, nargs="?",
                   const=RECORD_UNDER_OUT,
                   help="write a rerun .rrd of the episode into this folder (given without "
                        "a folder: --out/recordings)")
    p.add_argument("--config", type=existing_file, default=None, action=Once,
                   help="YAML of config overrides merged into the scenario's (e.g. a "
                        "string of components: the repository's "
                        "examples/field_well_string.yaml)")
    p.add_argument("--out", type=out_folder, default=Path("logs"),
                   help="folder for run_summary.json (this run's) and run_history.jsonl "
                        "(every run's summary, one line each)")

    p = add("benchmark", "controllers x scenarios x seeds at each scenario's set points "
                         "(or --rpm / --wob): table, benchmark.csv, benchmark.md and plots "
                         "in --out; resumable",
            cmd_benchmark)
    p.add_argument("--controllers", default="stiff,soft-speed,soft-torque,z-torque,driller",
                   help="comma-separated controller names (as run's --controller, your "
                        "own as <file.py or module>:<class>)")
    p.add_argument("--scenarios", default=None,
                   help="comma-separated scenario names (default: default,stick_slip; with "
                        "--task: random)")
    p.add_argument("--task", choices=("stick_slip", "drilling"), default=None,
                   help="run every controller in this control task's env (its targets, "
                        "observation, reward); default: DrillString-v0")
    p.add_argument("--rpm", type=number("rpm", low_inclusive=False), default=None,
                   help="surface speed set point of every episode in rpm, above 0 (a "
                        "benchmark measures a turning string) up to DrillString-v0's 200 "
                        "(default: each scenario's; not with --task, whose targets are "
                        "drawn)")
    p.add_argument("--wob", type=kilonewtons, default=None,
                   help="weight on bit of every episode in kN (default: each scenario's; "
                        "not with --task)")
    p.add_argument("--string-lengths", type=length_range, default=None, metavar="LO,HI",
                   help="with --task: the string lengths the task's random scenario draws, "
                        "in m (default 900,1600; a curved well of --config may need a "
                        "narrower range, docs/tasks.md)")
    # (1e12 was a MemoryError building the seed list; 10,000 seeds x one pair take days)
    p.add_argument("--seeds", type=seed_count("--seed-start", MAX_BENCHMARK_SEEDS), default=3,
                   help="seeds per pair")
    p.add_argument("--seed-start", type=integer(0), default=0,
                   help="first seed (the held-out evaluation seeds start at 1000000)")
    p.add_argument("--paired", default=None, metavar="CONTROLLER",
                   help="one of --controllers (as typed there): its return against each "
                        "other's on the same episodes (mean and median lead, the lead's "
                        "95%% interval, one-sided paired t-tests, Holm's adjustment), as "
                        "drill-env evaluate gives a run's; in comparison.md")
    p.add_argument("--duration", type=number("s", low_inclusive=False), default=None,
                   help="simulated seconds per episode (default: 60; with --task the "
                        "task's evaluation episode, as drill-env evaluate runs it)")
    p.add_argument("--warmup", type=number("s"), default=None,
                   help="seconds at the start left out of the metrics (default: 30; with "
                        "--task the task's evaluation warm-up)")
    p.add_argument("--start-kick", type=number("", high=0.5), default=0.02,
                   help="relative bit-speed kick at the start, drawn from the seed")
    p.add_argument("--fidelity", choices=("full", "fast"), default=None,
                   help="physics level (docs/performance.md; default: full, with --task "
                        "fast, as the task trains and drill-env evaluate runs)")
    p.add_argument("--workers", type=integer(1), default=None,
                   help="local processes (default: the cores this process may use)")
    add_ray_address(p, "the simulations")
    p.add_argument("--record", action="store_true",
                   help="write one rerun recording per episode to --out/recordings, named "
                        "<controller>_<scenario>_seed<N>")
    p.add_argument("--config", type=existing_file, default=None, action=Once,
                   help="YAML of config overrides merged into every episode's scenario, under "
                        "each controller's top drive (e.g. a string of components: the "
                        "repository's examples/field_well_string.yaml)")
    p.add_argument("--out", type=out_folder, default=None,
                   help="output folder (default: logs/benchmark; with --task "
                        "logs/benchmark/<task>, beside the scenario benchmark's outputs; "
                        "with --config FILE a folder config-<FILE's stem> inside that, "
                        "e.g. logs/benchmark/stick_slip/config-field_well_string)")

    p = add("train", "train PPO or SAC on a control task; the run (model, VecNormalize, "
                     "checkpoints, learning curve, TensorBoard) in --out/<name>", cmd_train)
    p.add_argument("--task", required=True, choices=("stick_slip", "drilling"),
                   help="stick_slip: DrillStickSlip-v0, drilling: DrillOptimise-v0")
    p.add_argument("--algo", choices=("ppo", "sac"), default=None,
                   help="algorithm (default: sac, what the shipped policies of both tasks "
                        "were trained with, docs/tasks.md; --resume --name: the run's own)")
    p.add_argument("--config", type=existing_file, default=None, action=Once,
                   help="hyperparameter YAML (default: the task's file shipped with "
                        f"drill-env, {shipped_hyperparameters()}/<task>.yml; copy it to "
                        "change it)")
    p.add_argument("--timesteps", type=integer(1), default=None,
                   help="env steps (default: the YAML's n_timesteps)")
    p.add_argument("--n-envs", type=integer(1), default=None,
                   help="batched envs (default: the YAML's n_envs)")
    p.add_argument("--seed", type=integer(0), default=None,
                   help="training seed (default: the YAML's, 0)")
    p.add_argument("--seeds", default=None,
                   help="comma-separated seeds: a seed sweep, one run per seed in parallel "
                        "(resumable; summary in --out/train_sweep.md)")
    p.add_argument("--workers", type=integer(1), default=None,
                   help="with --seeds: local processes (default: one per seed)")
    add_ray_address(p, "the training runs of --seeds")
    p.add_argument("--name", default=None,
                   help="run name (default: <task>_<algo>_seed<seed>, from a --config "
                        "file <task>_<algo>_<file's name>_seed<seed>)")
    again = p.add_mutually_exclusive_group()
    again.add_argument("--resume", action="store_true",
                       help="continue the run from its last checkpoint (or its final model; "
                            "a Ctrl-C or SIGTERM saves one), with the config it was started with")
    again.add_argument("--overwrite", action="store_true",
                       help="delete an existing run of that name (the files training "
                            "and evaluate wrote; a folder holding others is refused) and "
                            "start again (without it, an existing run is refused)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--out", type=out_folder, default=Path("logs/runs"), help="folder of runs")

    p = add("evaluate", "a trained run against the classical controllers and the trivial "
                        "policies on the held-out seeds, through the benchmark; paired "
                        "comparison in comparison.md", cmd_evaluate)
    p.add_argument("run", type=user_path, help="run folder of drill-env train, or a task's name "
                                           "(stick_slip, drilling) for its shipped policy")
    p.add_argument("--seeds", type=seed_count("1000000, the held-out seeds"), default=20,
                   help="how many held-out seeds (1000000 on)")
    p.add_argument("--fidelity", choices=("full", "fast"), default=None,
                   help="physics level of every episode, the policy's and the others' "
                        "(default: the level the run trained at, fast for the tasks; full "
                        "judges a fast-trained policy in the full model)")
    p.add_argument("--workers", type=integer(1), default=None,
                   help="local processes (default: the cores this process may use)")
    add_ray_address(p, "the episodes")
    p.add_argument("--out", type=out_folder, default=None,
                   help="output folder (default: RUN/evaluation; logs/evaluation/<task> "
                        "for a shipped policy; _full or _fast added at a --fidelity other "
                        "than the run's)")

    p = add("stability-map", "torsional stability maps P1-P6 (paper Fig. 15) by boundary "
                             "tracking; finished points are kept in --out and reused",
            cmd_stability_map)
    p.add_argument("--positions", default="P1,P2,P3,P4,P5,P6",
                   help="comma-separated bit positions")
    p.add_argument("--controller", default=None,
                   help="drive-rate top-drive controller (stiff, soft-speed, soft-torque, "
                        "z-torque, or one of your own with rate 'drive': file.py:Class; "
                        "default: the scenario's stiff PI)")
    p.add_argument("--rpm-step", type=number("rpm", low_inclusive=False), default=5.0,
                   help="speed step (rpm)")
    p.add_argument("--wob-step", type=number("kN", low_inclusive=False), default=5.0,
                   help="WOB step (kN)")
    p.add_argument("--max-rpm", type=number("rpm", low_inclusive=False), default=250.0,
                   help="highest speed (rpm)")
    p.add_argument("--max-wob", type=number("kN", low_inclusive=False), default=200.0,
                   help="highest WOB (kN)")
    p.add_argument("--seconds", type=number("s", low_inclusive=False), default=30.0,
                   help="simulated seconds per grid point")
    p.add_argument("--config", type=existing_file, default=None, action=Once,
                   help="YAML of config overrides merged into the map's scenario (paper case "
                        "1 at each position): a string of your own, e.g. the repository's "
                        "examples/field_well_string.yaml; its maps are named and titled by "
                        "the file: stability_map[_<controller>]_<file>.*")
    p.add_argument("--workers", type=integer(1), default=None,
                   help="local processes (default: the cores this process may use)")
    add_ray_address(p, "the simulations")
    p.add_argument("--out", type=out_folder, default=Path("logs"),
                   help="folder for stability_map.png/.json (stability_map_<controller>.* "
                        "under another controller than stiff; maps of other positions "
                        "already there with the same settings and grid are kept) and the "
                        "points file")

    p = add("modes", "natural frequencies, damping and the critical-speed chart of a "
                     "scenario's string", cmd_modes)
    p.add_argument("--scenario", default="default",
                   choices=sorted(set(SCENARIOS) - set(DEVIATED)),
                   help="the scenario whose string to analyse (vertical holes: a deviated "
                        "well's static loads are drill-env well's)")
    p.add_argument("--seed", type=integer(0), default=None,
                   help="the random scenario's draw (default 0; the string an env's "
                        "reset(seed=SEED) drills)")
    p.add_argument("--wob", type=kilonewtons, default=None,
                   help="weight on bit in kN (default: the scenario's)")
    p.add_argument("--config", type=existing_file, default=None, action=Once,
                   help="YAML of config overrides merged into the scenario's (e.g. a "
                        "string of components: the repository's "
                        "examples/field_well_string.yaml)")
    p.add_argument("--top", choices=("fixed", "top_drive"), default="fixed",
                   help="torsional boundary at the top")
    p.add_argument("-n", type=integer(1), default=5, help="modes of each kind")
    # (1e20 ran, dividing by zero; no drill string turns near 10,000 rpm, a turbine ~1,500)
    p.add_argument("--max-rpm", type=number("rpm", low=0.0, high=10_000.0,
                                            low_inclusive=False), default=250.0,
                   help="highest speed of the chart")
    p.add_argument("--out", type=out_folder, default=Path("logs"),
                   help="folder for modes_critical_speeds.png and modes.json")

    p = add("well", "a well path (preset or survey CSV) and the soft-string torque-and-drag "
                    "chart of a scenario's string: hook load and torque against bit depth",
            cmd_well)
    p.add_argument("--well", default=None,
                   choices=("vertical", "j_shaped", "s_shaped", "lateral_60"),
                   help="preset well shape (drill_env/well.py); default: the scenario's or "
                        "--config's well, else j_shaped")
    p.add_argument("--survey", type=existing_file, default=None,
                   help="survey CSV with columns md (m), inclination, azimuth (deg); "
                        "instead of --well")
    p.add_argument("--total-md", type=number("m", low_inclusive=False), default=None,
                   help=f"measured depth of the preset well (default {DEFAULT_WELL_MD:g} m)")
    p.add_argument("--scenario", default="default", choices=sorted(SCENARIOS),
                   help="whose string (its BHA and pipe; drill pipe added to reach TD)")
    p.add_argument("--config", type=existing_file, default=None, action=Once,
                   help="YAML of config overrides (e.g. the repository's "
                        "examples/field_well_string.yaml)")
    p.add_argument("--friction", default="0.1,0.2,0.3,0.4",
                   help="comma-separated friction factors")
    p.add_argument("--out", type=out_folder, default=Path("logs"),
                   help="folder for well_<name>.png and .json (<name>: the well's, then "
                        "the scenario's and the --config file's where they give the string)")

    p = add("speed", "speed and memory benchmark; speed.json and speed.md in --out", cmd_speed)
    p.add_argument("--out", type=out_folder, default=Path("logs"), help="output folder")
    p.add_argument("--quick", action="store_true", help="short runs (smoke test, ~1 min)")
    p.add_argument("--sections", default=None,
                   help="comma-separated subset of core,env,scaling,compile,memory,"
                        "training (default: all; training is the time to a policy)")

    p = add("replay", "open .rrd recordings in the rerun viewer", cmd_replay)
    p.add_argument("paths", type=user_path, nargs="+", metavar="FILE",
                   help="a .rrd file; several open in one viewer, whose recordings panel "
                        "(left, folded) switches between them")
    p.add_argument("--web", action="store_true", help="serve the web viewer instead")
    p.add_argument("--port", type=integer(1), default=None,
                   help="the web viewer's HTTP port (default 9090, or a free one where "
                        "9090 is taken; the URL is printed)")
    p.add_argument("--bind", default=None, metavar="ADDRESS",
                   help="the address the viewer's servers listen on (the web viewer's, "
                        "and the data server of either; default 127.0.0.1: this machine "
                        "only; 0.0.0.0 serves every interface, i.e. the network)")
    return top


def add_ray_address(p: argparse.ArgumentParser, what: str) -> None:
    p.add_argument("--ray-address", default=None,
                   help=f"run {what} on Ray: 'local' (a one-machine Ray here), 'auto' (the "
                        "cluster of `ray start` on this machine) or an address; needs the "
                        "distributed extra (README: Scaling out on Ray)")


#: ``run --record`` without a folder: the run's ``--out``/recordings, as ``benchmark``.
RECORD_UNDER_OUT = Path("<out>/recordings")

#: ``well --well <preset>`` without ``--total-md`` (m).
DEFAULT_WELL_MD = 3000.0

#: Library fields whose errors reach the command line under another option's name (the
#: rest: ``max_wob`` -> ``--max-wob``, :func:`option_of`).
OPTION_OF_FIELD = {"ray_address": "--ray-address", "episode_duration": "--duration"}


def option_of(field: str, command_parser: argparse.ArgumentParser) -> str | None:
    """The option of this command that set a library field named in an error
    (``max_wob`` -> ``--max-wob``, ``rpm_step/wob_step`` -> ``--rpm-step/--wob-step``), or
    None: a dotted path (``sac.n_envs``, ``string.components[2].length``) is a config
    file's, and is said as it is."""
    options = {s for action in command_parser._actions for s in action.option_strings}
    flags = [OPTION_OF_FIELD.get(name, "--" + name.replace("_", "-"))
             for name in field.split("/")]
    if not all(name.isidentifier() for name in field.split("/")):
        return None
    # a field of one item set by an option of a list (controller -> --controllers)
    flags = [f + "s" if f not in options and f + "s" in options else f for f in flags]
    return "/".join(flags) if all(flag in options for flag in flags) else None


def canonical_controller(name: str) -> str:
    """``--controller``'s name as the registry takes it (``agents.registry.canonical``:
    a table's name of set points is theirs); a trained run's table name is an error of
    the option."""
    from agents.registry import canonical

    try:
        return canonical(name)
    except ValueError as err:
        raise argparse.ArgumentTypeError(
            f"--controller: {str(err).removeprefix('controller: ')}") from None


def typed_controller(name: str) -> Any:
    """The controller ``--controller`` names; a bad name is an error of that option."""
    from agents.registry import make_controller

    try:
        return make_controller(name)
    except (ValueError, FileNotFoundError) as err:  # a learned:<folder> that is not there
        detail = str(err).removeprefix("controller: ").removeprefix("constant: ") \
            .removeprefix("learned: ")
        raise argparse.ArgumentTypeError(f"--controller: {detail}") from None


def option_hint(word: str, command: argparse.ArgumentParser) -> str:
    """`` (did you mean --rpm?)`` for a misspelt option of ``command``, else ""."""
    from drill_env.physics.validation import did_you_mean

    if not word.startswith("--"):
        return ""
    return did_you_mean(word.partition("=")[0], [o for action in command._actions
                                                 for o in action.option_strings
                                                 if o.startswith("--")])


def main(argv: Sequence[str] | None = None) -> int:
    """The ``drill-env`` command; returns its exit status."""
    for stream in (sys.stdout, sys.stderr):
        tolerant_output(stream)
    try:
        return _main(argv)
    except RuntimeError as err:  # no folder numba may keep the kernels in: one line, not
        # a traceback from the first import of a kernel (`--help` too)
        if not str(err).startswith("drill_env: no writable folder"):
            raise
        print(f"drill-env: error: {str(err).removeprefix('drill_env: ')}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as caught:  # before the command ran (building the parser:
        # imports), a Ctrl-C printed a traceback of dozens of lines (an outside check)
        said = "terminated" if isinstance(caught, Terminated) else "interrupted"
        print(f"drill-env: {said}", file=sys.stderr)
        return exit_status(caught)


def tolerant_output(stream: Any) -> None:
    """A stream whose encoding cannot write every character (any but UTF's: ASCII under
    ``LC_ALL=C`` without Python's UTF-8 mode or ``PYTHONIOENCODING=ascii``, Latin-1,
    cp1252) writes the ones it cannot as ``\\u2020``. A table's dagger or a path with an
    umlaut ended demo, benchmark, evaluate and run with an encoding error after their
    work, reported as a bad value (exit 2), before benchmark.md was written (an outside
    check)."""
    import codecs

    encoding = getattr(stream, "encoding", None)
    if not encoding or not hasattr(stream, "reconfigure"):
        return
    try:  # any encoding but Unicode's lacks some character (cp1252 has the dagger and
        # the umlaut, not a Polish or Chinese letter a path may hold: a review)
        unicode = codecs.lookup(encoding).name.startswith("utf")
    except LookupError:
        unicode = False
    if not unicode:
        stream.reconfigure(errors="backslashreplace")


def _joined_values(argv: Sequence[str]) -> list[str]:
    """``--seeds -1,2`` as ``--seeds=-1,2``: argparse reads a value that starts with '-'
    and is not a plain number as an option, and said "expected one argument" (a
    negative list or 1e3 refused without naming what was wrong); no option of ours
    starts with '-' and a digit, so the value is the option's, judged by its checks."""
    out: list[str] = []
    for token in argv:
        if out and token[:1] == "-" and token[1:2].isdigit() and \
                out[-1].startswith("--") and "=" not in out[-1]:
            out[-1] = f"{out[-1]}={token}"
        else:
            out.append(token)
    return out


#: drill-env's packages beside drill_cli: top-level names (the repository's layout, SPEC
#: section 1) that a user's own module of that name can shadow.
SIBLING_PACKAGES = ("agents", "training")


def _package_spec(name: str) -> Any:
    """Where Python would import the top-level ``name`` from (its ``ModuleSpec``, None if
    nowhere), found without importing it."""
    import importlib.util

    try:
        return importlib.util.find_spec(name)
    except (ImportError, ValueError):  # (a module in sys.modules without a spec)
        return None


def shipped_hyperparameters() -> str:
    """The folder of the hyperparameter files shipped in the ``training`` package (found
    without importing it: the help is built for every command)."""
    spec = _package_spec("training")
    where = next(iter(spec.submodule_search_locations or []), None) if spec else None
    return str(Path(where) / "hyperparams") if where else "training/hyperparams"


def shadowed_packages() -> list[str]:
    """Each of :data:`SIBLING_PACKAGES` that Python would import from somewhere other than
    beside drill_cli, in words ("training is ./training.py"): ``python -m drill_cli`` from
    a folder holding ``training.py`` or ``agents/`` imported the user's and failed far
    inside a command with "No module named 'training.config'" (an outside check). Asked
    where an import failed: a folder of that name blocks nothing that does not need it."""
    home = Path(__file__).resolve().parent.parent
    said = []
    for name in SIBLING_PACKAGES:
        spec = _package_spec(name)
        where = None if spec is None else \
            (spec.origin or next(iter(spec.submodule_search_locations or []), None))
        if where is None:
            said.append(f"{name} is not installed")
        elif Path(where).resolve().parent.parent != home and \
                Path(where).resolve().parent != home:
            said.append(f"{name} is {where}")
    return said


#: The commands that run numba kernels (a first run after an install compiles them).
COMPILING_COMMANDS = frozenset(("demo", "run", "benchmark", "train", "evaluate",
                                "stability-map", "modes", "speed"))


def no_kernels_cached() -> bool:
    """Whether this version's numba cache holds no compiled kernel of this checkout's
    (numba's index files): a new install, the first run after an edit of the sources, or
    a second checkout of the same version. numba keeps a source folder's kernels in a
    subfolder named by that folder's path (``physics_<sha1 of the path>``, numba's own
    ``_CacheLocator.get_suitable_cache_subpath``): another checkout's kernels are not this
    one's, and a new user's first benchmark in a second clone sat ~2 min unexplained (an
    outside check)."""
    from numba.core.caching import _CacheLocator

    import drill_env
    from drill_env import numba_cache_dir

    cache = numba_cache_dir()
    subfolders = {_CacheLocator.get_suitable_cache_subpath(str(source))
                  for source in Path(drill_env.__file__).parent.rglob("*.py")}
    return not any(next((cache / sub).glob("*.nbi"), None) for sub in subfolders)


@contextlib.contextmanager
def compile_notice(command: str) -> Iterator[list[bool]]:
    """While a command runs, say on stderr when numba starts compiling a kernel (once:
    a first run after an install or an edit of the sources); yields a flag list whose
    first item tells whether it did. A new user's first `run` sat ~20 s on its first step
    unexplained, its progress bar projecting three hours. numba's "numba:compile" event
    comes only where its cache had nothing to load, so a warm run says nothing; a cache
    without a kernel (a new install) is said at once, since a benchmark's worker
    processes compile where this process's listener does not hear them."""
    said = [False]
    if command not in COMPILING_COMMANDS:
        yield said
        return
    from numba.core import event

    from drill_env import numba_cache_dir

    def say() -> None:
        if not said[0]:
            said[0] = True
            from tqdm import tqdm

            # tqdm's write: above a progress bar already drawn, not inside its line
            tqdm.write(f"drill-env {command}: numba compiles the kernels its cache lacks, "
                       f"once for this version of drill-env (all of them 20-60 s on 2 "
                       f"cores, one left out by an earlier command far less; cached in "
                       f"{numba_cache_dir()})", file=sys.stderr)

    class Notice(event.Listener):
        def on_start(self, event: event.Event) -> None:
            say()

        def on_end(self, event: event.Event) -> None:
            pass

    if no_kernels_cached():
        say()
    listener = Notice()
    event.register("numba:compile", listener)
    try:
        yield said
    finally:
        event.unregister("numba:compile", listener)


def _main(argv: Sequence[str] | None) -> int:
    top = parser()
    argv = _joined_values(sys.argv[1:] if argv is None else argv)
    if not argv:  # no command: what the commands are
        top.print_help()
        return 2
    args, extra = top.parse_known_args(argv)
    if extra:  # said by the command's parser (argparse's own said the top usage)
        args.command_parser.error(f"unrecognized arguments: {' '.join(extra)}"
                                  + option_hint(extra[0], args.command_parser))
    out = getattr(args, "out", None)
    if out is not None and (reason := unwritable(out)):  # before the work: found after an
        args.command_parser.error(f"--out {out}: {reason}")  # hour's work, it lost the hour
    if getattr(args, "ray_address", None) is not None and getattr(args, "workers", None):
        args.command_parser.error("--workers: the local processes; with --ray-address the "
                                  "cluster's CPUs run the work: give one of the two")
    import tempfile

    try:  # where the commands' processes mark the warnings said
        marks = tempfile.TemporaryDirectory(prefix="drill-env-warnings-")
    except OSError as err:  # (a traceback of tempfile's; an outside check)
        print(f"drill-env {args.command}: error: no writable temporary folder ({err}); "
              "set TMPDIR to a folder you can write", file=sys.stderr)
        return 2
    started = time.time()  # (what its results file holds from before is not its work)
    stop, terminated = _stop_as_interrupt()
    heard = False
    clear_interrupt()  # one noted before this command is not this command's
    from drill_env.sweep import COMMAND_VARIABLE, SAID_VARIABLE, command_warning

    shown, named = warnings.formatwarning, os.environ.get(COMMAND_VARIABLE)
    outer = os.environ.get(SAID_VARIABLE)  # a command run inside another (tests)
    warnings.formatwarning = command_warning(args.command, marks.name)
    # a sweep's pool workers (spawned) say their warnings the same way, and once in all
    os.environ[COMMAND_VARIABLE] = args.command
    os.environ[SAID_VARIABLE] = marks.name
    try:
        heard = hear_interrupts()  # (a script's background job: kill -INT stops it)
        with compile_notice(args.command) as args.compiled:
            return int(args.func(args))
    except ImportError as err:  # our agents or training package hidden by the user's
        if not (shadowed := shadowed_packages()):
            raise
        print(f"drill-env {args.command}: error: {err}: {'; '.join(shadowed)} (drill-env's "
              f"own lie in {Path(__file__).resolve().parent.parent}): a module or folder of "
              "that name in the working folder or on PYTHONPATH hides it; run from another "
              "folder or rename yours", file=sys.stderr)
        return 2
    except BrokenPipeError:  # the reader went away (`drill-env modes | head`): stop quietly
        sys.stderr.close()  # nothing more can be said on a closed pipe
        return 0
    except argparse.ArgumentTypeError as err:  # a bad argument found after parsing:
        # said as argparse says its own (the command's usage, then the error)
        args.command_parser.error(str(err))
    except (ValueError, OSError) as err:  # a bad value named by the library below
        field, colon, rest = str(err).partition(": ")  # by the option the user typed
        # an error led by a path the user typed is that file's or folder's (a folder in
        # use given as --out seeds was said as --seeds)
        typed = {str(v) for v in vars(args).values() if isinstance(v, Path)}
        option = option_of(field, args.command_parser) \
            if colon and field not in typed else None
        said = f"{option}: {rest}" if option else str(err)
        print(f"drill-env {args.command}: error: {said}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as caught:
        # a SIGTERM's Terminated may come back as a plain KeyboardInterrupt (Ray's wait
        # turns a signal's exception into its own)
        stopped = Terminated() if terminated.is_set() else caught
        said = "terminated" if isinstance(stopped, Terminated) else "interrupted"
        kept = finished_work_folder(args, out)
        if args.command in KEEPS_FINISHED and kept is not None and finished_since(
                results_file(args.command, kept), started):  # (none finished: it said so
            # all the same)
            said += (f"; its finished {KEEPS_FINISHED[args.command]} are kept in {kept}: the "
                     "same command again goes on from them")
        print(f"drill-env {args.command}: {said}", file=sys.stderr)
        return exit_status(stopped)
    finally:
        warnings.formatwarning = shown
        if named is None:
            os.environ.pop(COMMAND_VARIABLE, None)
        else:
            os.environ[COMMAND_VARIABLE] = named
        if outer is None:
            os.environ.pop(SAID_VARIABLE, None)
        else:
            os.environ[SAID_VARIABLE] = outer
        marks.cleanup()
        clear_interrupt()  # handled here: not a later command's (or caller's) to act on
        if stop is not _NOT_INSTALLED:
            signal.signal(signal.SIGTERM, stop if stop is not None else signal.SIG_DFL)
        if heard:
            signal.signal(signal.SIGINT, signal.SIG_IGN)
    return 2


_NOT_INSTALLED = object()
#: The stability map's store of finished points (one JSON line each).
MAP_POINTS_FILE = "stability_map.points.jsonl"
#: Commands that keep what they finished in their --out as it arrives, and what that is
#: (a rerun with the same settings and code reuses it; `train` says its own checkpoint).
KEEPS_FINISHED = {"benchmark": "episodes", "stability-map": "points", "evaluate": "episodes",
                  "demo": "episodes"}


def finished_work_folder(args: argparse.Namespace, out: Path | None) -> Path | None:
    """Where a stopped command of :data:`KEEPS_FINISHED` keeps its finished work: its
    ``--out``; evaluate's default beside the run; the demo's benchmark folder."""
    if args.command == "evaluate":
        return out or default_evaluation_folder(args.run, args.fidelity)
    if args.command == "demo":
        return None if out is None else out / "benchmark"
    return out


def results_file(command: str, folder: Path) -> Path:
    """The file in ``folder`` where a command of :data:`KEEPS_FINISHED` appends its
    finished episodes or points."""
    if command == "stability-map":
        return folder / MAP_POINTS_FILE
    from agents.benchmark import RESULTS_FILE

    return folder / RESULTS_FILE


def finished_since(path: Path, started: float) -> bool:
    """Whether ``path`` was written since ``started`` (``time.time()``): a result finished
    then."""
    try:
        return path.stat().st_mtime >= started
    except OSError:
        return False


def exit_status(stopped: KeyboardInterrupt) -> int:
    """The shell's status of a command stopped by a signal, 128 + its number: 143 after
    SIGTERM, 130 after Ctrl-C (SIGINT)."""
    return 128 + (signal.SIGTERM if isinstance(stopped, Terminated) else signal.SIGINT)


def _stop_as_interrupt() -> tuple[Any, threading.Event]:
    """SIGTERM (``kill``, a scheduler's stop) handled as Ctrl-C for the command's duration:
    what is done is kept and a sweep's workers are stopped (it ended this process at once,
    its workers left running). Returns the previous handler (``_NOT_INSTALLED`` off the
    main thread, where none can be set) and an event the handler sets: what stopped the
    command also where its :class:`Terminated` was replaced on the way up (Ray's wait
    raises a KeyboardInterrupt of its own)."""
    terminated = threading.Event()
    if threading.current_thread() is not threading.main_thread():
        return _NOT_INSTALLED, terminated

    def interrupt(signum: int, frame: Any) -> None:
        note_interrupt(Terminated)  # kept also where the raise is lost (training checks it)
        terminated.set()
        raise Terminated

    return signal.signal(signal.SIGTERM, interrupt), terminated


if __name__ == "__main__":  # python -m drill_cli.main, as python -m drill_cli
    sys.exit(main())
