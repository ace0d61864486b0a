"""The ``drill-env`` parser: every command's options, their help and defaults, and the
option a library's error names (``max_wob`` -> ``--max-wob``)."""

from __future__ import annotations

import argparse
import re
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any, NoReturn

from drill_cli.arguments import (
    DEFAULT_WELL_MD,
    MAX_BENCHMARK_SEEDS,
    RECORD_UNDER_OUT,
    Once,
    existing_file,
    integer,
    kilonewtons,
    length_range,
    number,
    out_folder,
    seed_count,
    user_path,
)
from drill_cli.benchmark import cmd_benchmark
from drill_cli.installation import shipped_hyperparameters
from drill_cli.run import cmd_demo, cmd_run
from drill_cli.studies import cmd_modes, cmd_stability_map, cmd_well
from drill_cli.tools import cmd_replay, cmd_speed
from drill_cli.train import cmd_evaluate, cmd_train

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


class _Parser(argparse.ArgumentParser):
    """argparse's parser, whose "invalid choice" names the choice a misspelt one was
    probably meant to be (``benchmak``: did you mean benchmark?), as a misspelt option's
    error does; the choices' list stays as argparse says it."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        if sys.version_info >= (3, 14):  # argparse's own suggestion, on by default from
            kwargs.setdefault("suggest_on_error", False)  # 3.15: ours alone, one form
        super().__init__(*args, **kwargs)

    def error(self, message: str) -> NoReturn:
        from drill_env.physics.validation import did_you_mean

        found = re.match(r"argument (\S+): invalid choice: '([^']*)'", message)
        if found:
            name, value = found.groups()
            for action in self._actions:
                if action.choices and (name in action.option_strings
                                       or name == action.metavar):
                    message += did_you_mean(value, [str(c) for c in action.choices])
                    break
        super().error(message)


# --------------------------------------------------------------------------- parser


def parser() -> argparse.ArgumentParser:
    from drill_env import __version__
    from drill_env.scenarios import DEVIATED, SCENARIOS

    top = _Parser(prog="drill-env", description=DESCRIPTION, formatter_class=_Formatter)
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
    add_config(p, "YAML of config overrides merged into the scenario's (e.g. a "
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
                   help="one of --controllers (as typed there, or its table name): its "
                        "return against each "
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
    add_config(p, "YAML of config overrides merged into every episode's scenario, under "
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
                        "were trained with, docs/tasks.md; --resume --name: the run's own; "
                        "a --config of one entry: its algorithm)")
    add_config(p, "hyperparameter YAML (default: the task's file shipped with "
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
    add_config(p, "YAML of config overrides merged into the map's scenario (paper case "
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
    add_config(p, "YAML of config overrides merged into the scenario's (e.g. a "
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
                   help="survey CSV with columns md (m), inclination, azimuth (deg), or "
                        "as survey files name them, with a unit if not these: MD (ft), "
                        "Inc, Azi; instead of --well")
    p.add_argument("--total-md", type=number("m", low_inclusive=False), default=None,
                   help=f"measured depth of the preset well (default {DEFAULT_WELL_MD:g} m)")
    p.add_argument("--scenario", default="default", choices=sorted(SCENARIOS),
                   help="whose string (its BHA and pipe; drill pipe added to reach TD)")
    p.add_argument("--seed", type=integer(0), default=None,
                   help="the random scenario's draw (default 0; the string an env's "
                        "reset(seed=SEED) drills)")
    add_config(p, "YAML of config overrides (e.g. the repository's "
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


def add_config(p: argparse.ArgumentParser, help_text: str) -> None:
    """``--config FILE``: a YAML file that must exist, given at most once."""
    p.add_argument("--config", type=existing_file, default=None, action=Once, help=help_text)


def add_ray_address(p: argparse.ArgumentParser, what: str) -> None:
    p.add_argument("--ray-address", default=None,
                   help=f"run {what} on Ray: 'local' (a one-machine Ray here), 'auto' (the "
                        "cluster of `ray start` on this machine) or an address; needs the "
                        "distributed extra (README: Scaling out on Ray)")

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


def option_hint(word: str, command: argparse.ArgumentParser) -> str:
    """`` (did you mean --rpm?)`` for a misspelt option of ``command``, else ""."""
    from drill_env.physics.validation import did_you_mean

    if not word.startswith("--"):
        return ""
    return did_you_mean(word.partition("=")[0], [o for action in command._actions
                                                 for o in action.option_strings
                                                 if o.startswith("--")])
