"""``drill-env stability-map``, ``modes`` and ``well``: the paper's stability maps, the
string's frequencies and critical speeds, a well path with its torque and drag."""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
import time
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

from drill_cli.arguments import DEFAULT_WELL_MD, canonical_controller, typed_controller
from drill_cli.benchmark import tension_notes
from drill_cli.configs import merged, read_overrides, with_overrides
from drill_env.physics.units import KILO, RPM
from drill_env.progress import progress_bar
from drill_env.sweep import (
    save_text,
    save_whole,
)

#: Seconds before `modes` shows its bar (the default string's analyses take ~1 s).
MODES_BAR_DELAY = 2.0


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

    rpm, wob = sm.grid(args.rpm_step, args.wob_step * KILO, args.max_rpm, args.max_wob * KILO)
    for option, step, top, last, unit in (
            ("--max-rpm", "--rpm-step", args.max_rpm, rpm[-1], "rpm"),
            ("--max-wob", "--wob-step", args.max_wob, wob[-1] / KILO, "kN")):
        if last < top * (1 - 1e-9):  # (a new user's --wob-step 3 map ended at 198 kN unsaid)
            print(f"note: {option} {top:g} {unit} is not a whole number of {step}s: the "
                  f"map's last line is at {last:g} {unit}", file=sys.stderr)
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
        from agents.settings import label

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


def seeded_scenario(args: argparse.Namespace) -> Any:
    """``--scenario``, a randomised one drawn with ``--seed`` (default 0) as an env's reset
    with that seed draws it; ArgumentTypeError for a --seed beside a fixed scenario."""
    import numpy as np

    from drill_env.scenarios import RANDOMISED, make_scenario

    if args.seed is not None and args.scenario not in RANDOMISED:
        raise argparse.ArgumentTypeError(f"--seed: draws a randomised scenario "
                                         f"({', '.join(sorted(RANDOMISED))}); "
                                         f"{args.scenario} is fixed")
    if (seed := drawn_seed(args)) is not None:
        return make_scenario(args.scenario, rng=np.random.default_rng(seed))
    return make_scenario(args.scenario)


def drawn_seed(args: argparse.Namespace) -> int | None:
    """The seed ``--scenario`` is drawn with (``--seed``, default 0) where it is randomised;
    None for a fixed one."""
    from drill_env.scenarios import RANDOMISED

    return (args.seed or 0) if args.scenario in RANDOMISED else None


def cmd_modes(args: argparse.Namespace) -> int:
    from drill_env.physics import modes as md

    scenario = seeded_scenario(args)
    config = with_overrides(scenario.config, args.config)
    wob = args.wob * KILO if args.wob is not None else scenario.weight_on_bit
    try:
        md.require_vertical(config)
    except ValueError as err:  # the scenarios offered are vertical: the file set the well
        raise argparse.ArgumentTypeError(f"--config {args.config}: {err}") from None
    # a bar from 2 s on: a 14 km string's eigenproblems took 2 min 20 s, said by nothing
    # until the report (the four thresholds 112 s, the torsional modes 22 s)
    with progress_bar(total=6, desc="modes", unit="analysis", delay=MODES_BAR_DELAY,
                      leave=False) as bar:
        torsional = md.torsional_modes(config, args.top, args.n)
        bar.update()
        try:
            lateral = md.lateral_modes(config, wob, n_modes=args.n)
        except ValueError as err:
            raise argparse.ArgumentTypeError(f"--wob: {str(err).partition(': ')[2]}"
                                             ) from None
        bar.update()
        thresholds = stick_slip_thresholds(config, wob, done=bar.update)
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
    # what it analysed, so that the file tells itself from another's (a --config's string
    # was "scenario": "default" alone: a fuzzing walkthrough)
    data = {"scenario": args.scenario, "weight_on_bit_N": wob,
            "seed": drawn_seed(args),
            "config": None if args.config is None else str(args.config), "top": args.top,
            "modes_of_each_kind": args.n, "max_rpm": args.max_rpm,
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


def stick_slip_thresholds(config: Any, wob: float, done: Callable[[], Any] = lambda: None
                          ) -> dict[str, float | None]:
    """The linear stick-slip threshold (rpm) at ``wob`` on ``config``'s first rock under
    each drive-rate controller (None: stable at every speed), calling ``done`` after each:
    a SoftSpeed tuning that cannot hold a heavy drive shows there (docs/controllers.md)."""
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
        done()
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
    from drill_env.well import CHART_STEP, WELLS, write_well

    overrides = read_overrides(args.config)  # the file read once
    config = merged(seeded_scenario(args).config, overrides, args.config)
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
    # a randomised scenario's string is its seed's draw: named with it (two seeds' charts
    # shared one file)
    seed = drawn_seed(args)
    whose = (args.config.name if sets_section(overrides, "string") else
             f"the {args.scenario} scenario" + (f" (seed {seed})" if seed is not None else "")
             + (f" with {args.config.name}" if beyond_well else ""))
    # the file names the string too where it is not the default scenario's: charts of one
    # well for two strings overwrote each other (a new user's trial)
    strung = [args.scenario + (f"_seed{seed}" if seed is not None else "")] \
        if args.scenario != "default" and name != f"scenario_{args.scenario}" else []
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
#: The stability map's store of finished points (one JSON line each).
MAP_POINTS_FILE = "stability_map.points.jsonl"
