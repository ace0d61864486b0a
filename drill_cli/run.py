"""``drill-env demo`` and ``drill-env run``: the main job, and one episode of one controller
with its summary, history and optional recording."""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
import warnings
from typing import Any

from drill_cli.arguments import (
    RECORD_UNDER_OUT,
    canonical_controller,
    fixed,
    recording_note,
    typed_controller,
    unwritable,
)
from drill_cli.benchmark import buckling_note, in_range, tension_notes
from drill_cli.configs import checked_overrides
from drill_cli.interrupts import exit_status
from drill_env.physics.units import HOUR, KILO, RPM, few
from drill_env.progress import progress_bar
from drill_env.sweep import (
    save_text,
)
from drill_env.swing import SWING_BLOCK, swing_per_block, swing_trend

# --------------------------------------------------------------------------- commands


def cmd_demo(args: argparse.Namespace) -> int:
    from agents.benchmark import run_benchmark
    from agents.registry import CLASSICAL
    from agents.settings import BenchmarkSettings
    from drill_env.sweep import folder_lock
    from drill_env.tools.demo import stick_slip_demo

    # (a second demo into one folder redid part 1 over the first's files, then was told
    # to give "this benchmark" another folder, which demo has no option for: a fuzz)
    with folder_lock(args.out, "this demo (by --out)"):
        _, reproduced = stick_slip_demo(args.out)
        print("\nController benchmark (as drill-env benchmark): the classical controllers "
              "at the set points of the default scenario (100 rpm) and of stick_slip (50 rpm)")
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
    from agents.classical import ConstantSetPoints, drive_loop_name
    from agents.settings import (
        env_ranges,
        guest_env_kwargs,
        scenario_set_points,
        set_point_outside,
        starting_at,
    )

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
    if args.record is not None and args.record.suffix == ".rrd" and not args.record.is_dir():
        # (it made a folder x.rrd holding the episode's file: a fuzzing walkthrough)
        raise argparse.ArgumentTypeError(f"--record {args.record}: a folder, in which each "
                                         "episode's file is named by its controller, "
                                         f"scenario and seed; give {args.record.parent}")
    if args.record is not None and (reason := unwritable(args.record)):
        raise argparse.ArgumentTypeError(f"--record {args.record}: {reason}")
    if args.record is not None and (note := recording_note(args.record, args.duration)):
        print(note, file=sys.stderr)
    if args.record is not None:
        from agents.settings import label
        from drill_env.recording import RecordEpisode

        # <controller>_<scenario>_seed<seed>_ep..., the benchmark's order; the --config
        # file's name joined to the scenario's (runs of two wells in one folder told apart)
        scenario = args.scenario if args.config is None \
            else f"{args.scenario}+{args.config.stem}"
        env = RecordEpisode(env, args.record, scenario=scenario,
                            controller=label(args.controller))
    from agents.episode import act
    from agents.episode import reset as reset_controller
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
        where = f"scenario {args.scenario}, seed {args.seed}"  # (as a benchmark episode's)
        reset_controller(controller, args.controller, where, base)
        # (where stderr is no terminal, a line a minute: a log got the bar's frames, the
        # summary glued after them)
        bar = progress_bar(total=base.max_episode_steps, desc=f"  {args.scenario}",
                           leave=False, file=sys.stderr)
        for _ in range(base.max_episode_steps):
            obs, r, terminated, truncated, info = env.step(act(
                controller, args.controller, where, env.action_space, obs, info))
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
    if args.record is not None and summary["recording"]:
        print(f"  recording: {summary['recording']} (drill-env replay <file>)")
    elif args.record is not None:  # (exit 0 with 'recording: None' on a full disk: a fuzz)
        print("drill-env run: error: --record: the recording was not written (the warning "
              "above says why)", file=sys.stderr)
        status = status or 2
    # the results said first: a failed write lost them behind a bare errno (a fuzz)
    args.out.mkdir(parents=True, exist_ok=True)
    save_text(args.out / "run_summary.json", json.dumps(summary, indent=2))
    with (args.out / "run_history.jsonl").open("a", encoding="utf-8") as history:
        finished = time.strftime("%Y-%m-%dT%H:%M:%S%z")  # tells the runs of a history apart
        history.write(json.dumps({"finished": finished, **summary}) + "\n")
    print(f"wrote {args.out / 'run_summary.json'} (and a line of "
          f"{args.out / 'run_history.jsonl'}, which keeps every run's)")
    return status
