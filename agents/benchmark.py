"""The controller benchmark: controllers x scenarios x seeds on equal terms.

Every episode starts from the scenario's settled operating point at the driller's set
points (the scenario's rpm and WOB), with the bit speed kicked by up to
``start_kick`` from the seed, and runs ``duration`` simulated seconds; the metrics
(:func:`drill_env.metrics.window_metrics`, the code of the env's reward) are taken over
the part after ``warmup`` (stick-slip takes ~25 s to grow from a settled start). Each
controller acts in its own env (``Controller.env_id``) built from the same scenario,
seed and targets, so all of them see the same string, rock and start.

Results stream into ``benchmark_results.jsonl`` as episodes finish (an interrupted
benchmark keeps them; rerunning with the same settings and code computes only the rest,
and the episodes whose recording is asked for and missing), then ``benchmark.csv`` (one row
per controller, scenario and seed, the columns of docs/controllers.md), ``benchmark.md`` and
the plots are written from all finished rows.
"""

from __future__ import annotations

import csv
import dataclasses
import io
import json
import math
import sys
import warnings
import zipfile
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import Field

from drill_env.physics.config import Fidelity
from drill_env.physics.units import HOUR, KILO, MEGA, RPM, few, shown
from drill_env.physics.validation import (
    ConfigError,
    NonNegative,
    Positive,
    check_newtons,
    config_dataclass,
    jsonable,
    numbers,
    repeated,
)
from drill_env.sweep import save_text, save_whole, usable_cores

#: benchmark.csv columns, in order (the spec's section 5; meanings in docs/controllers.md);
#: units in the names.
COLUMNS = ("controller", "scenario", "seed", "ssi", "stuck_fraction", "mean_bit_rpm",
           "target_rpm", "rpm_tracking_error", "rop_m_per_h", "radial_ratio",
           "backward_whirl_fraction", "max_lateral_force_kN", "mse_MPa",
           "top_drive_energy_MJ", "episode_return")
#: Channels kept for the time-series plots (every record sample of seed 0).
SERIES_CHANNELS = ("time", "bit_speed", "surface_speed", "torque_on_bit", "surface_torque",
                   "bit_x", "bit_y", "weight_on_bit")
RESULTS_FILE = "benchmark_results.jsonl"
#: The time-series picture of a scenario, beside benchmark.md.
SERIES_PICTURE = "benchmark_{scenario}_series.png"


@config_dataclass
class BenchmarkSettings:
    """What every episode of a benchmark shares."""

    #: Simulated seconds per episode.
    duration: Positive = Field(default=60.0, le=36_000.0)
    #: Seconds at the start left out of the metrics: from a settled start with a 2 % kick
    #: stick-slip under a stiff top drive takes ~25 s to grow to full size on the default
    #: string at 50 rpm (benchmark_stick_slip_series.png).
    warmup: NonNegative = Field(default=30.0, le=36_000.0)
    #: Relative kick of the bit speed at the start, drawn from the seed.
    start_kick: NonNegative = Field(default=0.02, le=0.5)
    #: Physics level ("full" or "fast", docs/performance.md).
    fidelity: Fidelity = "full"
    #: Config overrides (dotted paths, e.g. ``{"string.drill_pipe.length": 2000.0}``)
    #: merged into every episode's scenario, under each controller's own top drive:
    #: what ``drill-env benchmark --config FILE`` reads from YAML.
    physics: dict[str, Any] = Field(default_factory=dict)
    #: A task benchmark's env keywords, the same for every controller: by default those
    #: its learned policies were trained with (:func:`task_settings`: reward weights,
    #: targets, telemetry, physics), so that every return and metric comes from one task.
    env_kwargs: dict[str, Any] = Field(default_factory=dict)
    #: The driller's set points of every episode of a scenario benchmark (rad/s, N; the
    #: ``--rpm`` / ``--wob`` of ``drill-env benchmark``); None: each scenario's own (a
    #: randomised one draws them from the seed).
    surface_speed: Positive | None = Field(default=None, le=1.0e3)
    weight_on_bit: NonNegative | None = Field(default=None, le=1.0e7)

    def __post_init__(self) -> None:
        from drill_env.physics.config import flatten

        if self.weight_on_bit is not None:
            check_newtons("weight_on_bit", (self.weight_on_bit,))
        from drill_env.env_config import EnvConfig

        # the set points are DrillString-v0's, within its ranges
        if out := set_point_outside(self.surface_speed, self.weight_on_bit, EnvConfig()):
            name, value, low, high, unit = out
            si = "rad/s" if unit == "rpm" else "N"
            raise ConfigError(f"{name}: {getattr(self, name):g} {si} is {value:.4g} {unit}, "
                              f"outside DrillString-v0's range {low:g}-{high:g} {unit}")
        if self.warmup >= self.duration:
            raise ConfigError(f"warmup: {self.warmup} s must be shorter than the duration "
                              f"({self.duration} s)")
        for key in flatten(self.physics):
            if key in CONTROLLER_FIELDS:
                raise ConfigError(
                    f"physics.{key}: the benchmark gives each controller its own top drive; "
                    "set for all of them, it would make them one controller (and leave the "
                    "driller and learned policies on another): remove it (tuning knobs such "
                    "as top_drive.impedance_factor or top_drive.filter_frequency may stay)")
        if self.physics:  # a misspelt field fails here, by name, not in a worker process
            from drill_env.physics.config import SimulationConfig, replace

            try:
                replace(SimulationConfig(), **flatten(self.physics))
            except (ValueError, TypeError, IndexError) as err:  # values and list entries
                if "unknown field" in str(err):  # are judged against each scenario's config
                    raise ConfigError(f"physics.{err}") from None

    def set_points(self) -> dict[str, float]:
        """The set points given (reset options of ``DrillString-v0``), {} for none."""
        return {key: value for key, value in (("surface_speed", self.surface_speed),
                                              ("weight_on_bit", self.weight_on_bit))
                if value is not None}


def set_point_outside(surface_speed: float | None, weight_on_bit: float | None,
                      config: Any) -> tuple[str, float, float, float, str] | None:
    """The first set point given (rad/s, N; None: not given) outside the ranges of
    ``config`` (an env's EnvConfig), as (field, value, low, high, unit) in rpm or kN."""
    for name, value, (low, high), unit, scale in (
            ("surface_speed", surface_speed, config.rpm_range, "rpm", RPM),
            ("weight_on_bit", weight_on_bit,
             tuple(v / KILO for v in config.weight_on_bit_range), "kN", KILO)):
        if value is not None and not low <= value / scale <= high:
            return name, value / scale, low, high, unit
    return None


#: Top-drive fields that say which controller the drive is, or override its rule's gains:
#: a benchmark's physics (``--config``) may not set them for every controller at once.
CONTROLLER_FIELDS = frozenset(f"top_drive.{name}" for name in (
    "controller", "proportional_gain", "integral_gain", "torque_feedback", "feedback_gain"))


@dataclass(frozen=True)
class Episode:
    """One benchmark episode (picklable: runs in a worker process)."""

    controller: str
    scenario: str
    seed: int
    settings: dict[str, Any]
    out: str
    record: bool = False
    series: bool = False
    #: The env every controller acts in (a control task's id); None: each controller's
    #: own (``DrillString-v0`` for the classical ones).
    env_id: str | None = None
    #: The controller's name in the tables (:func:`labels`); default :func:`label`.
    name: str = ""
    #: What else a stored row depends on: a learned policy's model files
    #: (:func:`controller_digest`), so a retrained run is not served its old rows.
    digest: str = ""
    #: The settings and code its row is stored under (:func:`stamp`): written into its
    #: series file and beside its recording, so a row is not reused with the picture or
    #: recording of another run in the same folder.
    stamp: str = ""
    #: The run's settings and code alone (:func:`run_stamp`): the second line beside its
    #: recording, the folder a later run sets the recording aside in.
    run: str = ""

    @property
    def label(self) -> str:
        return self.name or label(self.controller)

    @property
    def key(self) -> str:
        at = f"@{self.digest}" if self.digest else ""
        return f"{self.label}{at}|{self.scenario}|{self.seed}"

    @property
    def stem(self) -> str:
        return f"{self.label}_{self.scenario}_seed{self.seed}"

    @property
    def recording(self) -> Path:
        """Where ``record`` writes the episode's rerun recording."""
        from drill_env.recording import stem_file_name

        return Path(self.out) / "recordings" / stem_file_name(self.stem)

    @property
    def series_file(self) -> Path:
        return Path(self.out) / "series" / f"{self.stem}.npz"

    @property
    def recording_stamp(self) -> Path:
        """Beside :attr:`recording`: the :attr:`stamp` it was made under."""
        return self.recording.with_name(self.recording.name + ".stamp")

    def outputs_current(self) -> bool:
        """Whether the series and recording this episode should leave are there and were
        made under its :attr:`stamp`."""
        if self.series:
            try:
                with np.load(self.series_file) as data:
                    if str(data["stamp"]) != self.stamp:
                        return False
            except (OSError, KeyError, ValueError, EOFError, zipfile.BadZipFile):
                return False  # missing, damaged (a run killed while writing it), old
        return not self.record or self.recording_current()

    def recording_current(self) -> bool:
        """Whether :attr:`recording` is there and was made under this episode's stamp."""
        sidecar = self.recording_stamp
        return (self.recording.exists() and sidecar.exists()
                and sidecar.read_text(encoding="utf-8").partition("\n")[0] == self.stamp)


def label(controller: str) -> str:
    """The name a controller has in the tables and file names: ``learned:PATH`` ->
    ``learned``, ``constant:120/100`` -> ``constant-120rpm-100kN``, ``held:1/-0.5`` ->
    ``held+1-0.5``, one of your own
    (``file.py:Class``) its class's ``name`` (:func:`agents.registry.table_name`)."""
    from agents.registry import is_imported, table_name

    if is_imported(controller):
        return table_name(controller)
    head, _, rest = controller.partition(":")
    if head == "held" and rest:
        from agents.trivial import HeldAction

        return HeldAction.label(rest)
    if head == "constant" and rest:
        rpm, _, kn = rest.partition("/")
        try:  # one name for one pair of set points: 1e2, 100 and 100.0 are 100
            rpm, kn = f"{float(rpm):.15g}", f"{float(kn):.15g}"
        except ValueError:
            pass  # named as typed; ConstantSetPoints.parse says what is wrong with it
        return f"constant-{rpm}rpm-{kn}kN"
    return head


def labels(controllers: Sequence[str]) -> list[str]:
    """The table names of ``controllers``, distinct: :func:`label`, except that a
    ``learned:PATH`` whose label another controller has too is called
    ``learned-<folder name>``. A name given twice, or two run folders of the same name, is
    an error naming the field."""
    if (twice := repeated(controllers)) is not None:
        raise ValueError(f"controllers: {twice!r} is given twice")
    plain = [label(c) for c in controllers]
    out = [f"learned-{Path(c.partition(':')[2]).resolve().name}"
           if c.startswith("learned:") and plain.count(plain[k]) > 1 else plain[k]
           for k, c in enumerate(controllers)]
    folded = [n.casefold() for n in out]  # (case-blind file systems: macOS, Windows)
    for name in out:
        if folded.count(name.casefold()) > 1:
            twins = [c for c, n in zip(controllers, out, strict=True)
                     if n.casefold() == name.casefold()]
            from agents.trivial import HeldAction

            if all(c.startswith(("constant:", "held:")) for c in twins) and (
                    name.startswith("constant-") or HeldAction.from_label(name) is not None):
                what = "set points" if name.startswith("constant-") else "held actions"
                raise ValueError(f"controllers: {', '.join(twins)} are the same {what}; "
                                 "give them once")
            from agents.registry import is_imported

            fix = ("set another name attribute on one of the classes"
                   if any(is_imported(c) for c in twins) else "rename a run folder")
            alike = " (names that differ only in case name the same files on macOS " \
                "and Windows)" if len({out[controllers.index(c)] for c in twins}) > 1 else ""
            raise ValueError(f"controllers: {', '.join(twins)} would share the name "
                             f"{name!r} in the table{alike}; {fix}")
    return out


def controller_digest(controller: str, env_id: str | None = None) -> str:
    """A short hash of a learned controller's model files, or of the source file of a
    controller of your own and what its ``physics()`` and ``env_kwargs()`` return ("" for
    this project's, whose code the fingerprint follows): rows of a benchmark results file
    are reused only for the same model, or the same code and settings."""
    import hashlib

    from agents.registry import (
        CONTROLLERS,
        data_files,
        imported_factory,
        is_imported,
        make_controller,
        source_file,
    )

    digest = hashlib.sha256()
    if controller == "learned" or controller.startswith("learned:"):
        from agents.learned import policy_files

        for file in policy_files(controller.partition(":")[2] or None, env_id):
            digest.update(file.read_bytes())
        return digest.hexdigest()[:12]
    factory = imported_factory(controller) if is_imported(controller) \
        else CONTROLLERS.get(controller)
    own = source_file(factory) if factory is not None else None
    files: list[Path] = []
    if is_imported(controller):  # a factory function's controllers: their class's files
        owner = factory if isinstance(factory, type) else type(make_controller(controller))
        files = data_files(controller, owner)
    if own is None and not files:
        return ""
    if is_imported(controller):  # which of a file's controllers: two of one name in one
        # file shared their rows (the second served the first's numbers)
        digest.update(getattr(factory, "__qualname__", "").encode() + b"\0")
    if own is not None:
        digest.update(own.read_bytes())
    for file in files:
        digest.update(str(file).encode() + b"\0" + file.read_bytes())
    if is_imported(controller):  # what it asks of the physics and the env, resolved: a gain
        # read from a helper module or an environment variable changed these, not its file
        try:
            made = make_controller(controller)
            settings = [getattr(made, name)() for name in ("physics", "env_kwargs")
                        if callable(getattr(made, name, None))]
        except Exception:  # noqa: BLE001 - a controller that cannot be made is said where
            settings = []  # the benchmark makes it; its files still key its rows
        for value in settings:
            digest.update(json.dumps(value, sort_keys=True, default=repr).encode() + b"\0")
    return digest.hexdigest()[:12]


#: Env keywords every benchmark episode sets itself (from :class:`BenchmarkSettings`).
SET_BY_BENCHMARK = frozenset({"scenario", "episode_duration", "start_kick", "fidelity"})


def task_settings(controllers: Sequence[str], env_id: str) -> dict[str, Any]:
    """The env keywords of task ``env_id`` that the learned ``controllers`` were trained
    with (a run's ``config.yaml``; a controller of your own: its ``env_kwargs()``), less
    those the benchmark sets and those at their defaults: what every controller of a task
    benchmark acts under, so that the classical controllers are scored by the policies'
    reward, on their physics. Policies trained under different ones cannot share a table,
    and a policy of another env cannot act in this one: ValueError."""
    from agents.learned import trained_env
    from agents.registry import is_imported, make_controller
    from drill_env.physics.config import flatten

    defaults = _env_defaults(env_id)
    seen: dict[str, dict[str, Any]] = {}
    for name in controllers:
        kwargs: dict[str, Any] | None = None
        if name == "learned" or name.startswith("learned:"):
            trained_on, kwargs = trained_env(name.partition(":")[2] or None, env_id)
            check_acts_in(name, ("policy", trained_on), env_id)  # now, not in an episode
        elif is_imported(name):  # a policy of your own: its env and env_kwargs()
            controller = make_controller(name)
            check_acts_in(name, controller, env_id)
            # (a controller of DrillString-v0 acts in the task through its set points: its
            # env_kwargs() are DrillString-v0's, not the task's: set_point_guests)
            if controller.env_id == env_id and callable(getattr(controller, "env_kwargs",
                                                                None)):
                kwargs = declared_env_kwargs(controller, name)
                _check_env_kwargs(name, env_id, kwargs)
        if kwargs is not None:
            kwargs["physics"] = flatten(kwargs.get("physics") or {})
            seen[name] = {k: v for k, v in kwargs.items() if k not in SET_BY_BENCHMARK
                          and v != {} and _text(v) != _text(defaults.get(k, _NONE))}
    kinds = {_text(v) for v in seen.values()}
    if len(kinds) > 1:
        listed = "; ".join(f"{n}: {v or 'the defaults'}" for n, v in seen.items())
        raise ValueError(f"controllers: the policies were trained on different {env_id} "
                         f"settings ({listed}); benchmark them apart")
    return next(iter(seen.values()), {})


def _check_env_kwargs(name: str, env_id: str, kwargs: Mapping[str, Any]) -> None:
    """ValueError naming the controller if ``env_id`` refuses its ``env_kwargs()``:
    applied to every controller of the task benchmark, they failed in its first episode,
    named as that controller's (the stiff PI's)."""
    import gymnasium as gym

    try:
        gym.make(env_id, **kwargs).close()
    except ValueError as err:
        raise ValueError(f"controllers: {name}.env_kwargs(): {err}") from None


def set_point_guests(controllers: Sequence[str], env_id: str) -> list[str]:
    """The controllers of your own that are policies of ``DrillString-v0`` (``rate``
    "policy"): in a benchmark of task ``env_id`` they act through the task env's
    ``action_for``, and their ``act`` gets the task's observation (its
    ``observation_names``), not DrillString-v0's; their ``env_kwargs()`` do not apply.
    A caller says so (``drill-env benchmark`` prints a note): one that reads the
    observation by position reads other quantities there."""
    from agents.registry import is_imported, make_controller

    if env_id == "DrillString-v0":
        return []
    found = []
    for name in controllers:
        if is_imported(name):
            controller = make_controller(name)
            if controller.rate == "policy" and controller.env_id == "DrillString-v0":
                found.append(name)
    return found


def check_acts_in(name: str, controller: Any, env_id: str) -> None:
    """ValueError unless ``controller`` (or, for a learned run's name, its
    ``(rate, env id)``) can act in a benchmark of ``env_id``: a policy of another env
    reads another observation and sends another action. A set-point controller of
    ``DrillString-v0`` passes (the driller, constants, yours): it acts in any task through
    the env's ``action_for``; a model's policy (``LearnedController``, ``sb3_policy``)
    must be of ``env_id`` itself."""
    from agents.learned import LearnedController

    rate, own_env = controller if isinstance(controller, tuple) else (controller.rate,
                                                                      controller.env_id)
    through_set_points = not isinstance(controller, tuple | LearnedController)
    allowed = (env_id, "DrillString-v0") if through_set_points else (env_id,)
    if rate == "policy" and own_env not in allowed:
        raise ValueError(f"controllers: {name} is a policy of {own_env}; it cannot act in "
                         f"{env_id} (its observation and action differ)")


_NONE = object()  # no default: never equal to a given value


def _text(value: Any) -> str:
    """A value as JSON (tuples and lists, 1 and 1.0 alike) for comparing settings."""
    def plain(v: Any) -> Any:
        if isinstance(v, dict):
            return {k: plain(x) for k, x in v.items()}
        if isinstance(v, list | tuple):
            return [plain(x) for x in v]
        return float(v) if isinstance(v, int) and not isinstance(v, bool) else v

    return json.dumps(plain(jsonable(value)), sort_keys=True) if value is not _NONE else ""


def _env_defaults(env_id: str) -> dict[str, Any]:
    """The keyword values ``gymnasium.make(env_id)`` uses when none is given: the
    registration's, the task's env defaults, its task config's and EnvConfig's fields."""
    from drill_env.env_config import EnvConfig
    from drill_env.vector import registered

    env_class, registration = registered(env_id)
    config = EnvConfig()
    values = {f.name: getattr(config, f.name) for f in dataclasses.fields(config)}
    task_class = getattr(env_class, "task_class", None)
    if task_class is not None:
        task = task_class()
        values.update({f.name: getattr(task, f.name) for f in dataclasses.fields(task)})
    values.update(getattr(env_class, "env_defaults", {}))
    values.update(registration)
    return values


#: EnvConfig fields that shape only DrillString-v0's reward: a scenario benchmark scores
#: every row with their defaults, whatever a controller's ``env_kwargs()`` say (one that
#: zeroed its stick-slip weight led the return column with the stiff PI's stick-slip).
REWARD_ONLY = frozenset({"rop_weight", "stick_slip_weight", "whirl_weight", "effort_weight",
                         "failure_weight", "ssi_cap"})
#: EnvConfig fields of the episode itself, the same for every controller of a scenario
#: benchmark: a controller's ``env_kwargs()`` may not set them (a make-up torque of its
#: own ended its episodes early; ``rop_scale`` scales the reward as well as the
#: observation).
EPISODE_FIELDS = frozenset({"makeup_torque", "startup", "drawworks_rate", "record_every",
                            "metric_window", "limit_weight_on_bit_to_mesh", "rop_scale"})


def guest_env_kwargs(controller: Any) -> dict[str, Any]:
    """The env keywords a controller brings to a scenario: a task's policy (a guest)
    keeps those of its observation, not its run's physics (it drills the scenario, on the
    scenario's physics); a controller acting in DrillString-v0 keeps those of its
    observation and action, not its own reward weights (:data:`REWARD_ONLY`: every row's
    return is scored alike) and never its own episode (:data:`EPISODE_FIELDS`: refused,
    naming the controller); a classical controller brings none."""
    name = getattr(controller, "name", type(controller).__name__)
    own = declared_env_kwargs(controller, name)
    own.pop("physics", None)
    if getattr(controller, "env_id", "DrillString-v0") != "DrillString-v0":
        return own
    config = own.pop("config", None) or {}
    from drill_env.env_config import EnvConfig

    if isinstance(config, EnvConfig):  # the fields it sets otherwise than the default
        default = EnvConfig()
        config = {f.name: getattr(config, f.name) for f in dataclasses.fields(config)
                  if getattr(config, f.name) != getattr(default, f.name)}
    own = {**dict(config), **own}
    episode = sorted(EPISODE_FIELDS & set(own))
    if episode:
        raise ValueError(f"controller: {name}.env_kwargs() sets {', '.join(episode)}: in a "
                         "scenario benchmark every controller drills the same episode (its "
                         "start, make-up torque, records and reward scale); a controller "
                         "brings only its observation and action settings")
    return {key: value for key, value in own.items() if key not in REWARD_ONLY}


def declared_env_kwargs(controller: Any, name: str) -> dict[str, Any]:
    """A copy of ``controller.env_kwargs()`` (the task settings its policy was trained
    with; none without the method); ValueError naming the controller when a controller
    of your own raises in it or returns no mapping (it was a traceback)."""
    method = getattr(controller, "env_kwargs", None)
    if method is None:
        return {}
    from agents.registry import in_user_code

    try:
        kwargs = method()
    except Exception as err:  # noqa: BLE001 - the user's code: said in one line
        raise ValueError(f"controller: {name}.env_kwargs() raised {in_user_code(err)}"
                         ) from None
    if not isinstance(kwargs, Mapping):
        raise ValueError(f"controller: {name}.env_kwargs() returned {kwargs!r:.60}, not a "
                         "dict of env keywords")
    return dict(kwargs)


def starting_at(scenario: str, set_points: Mapping[str, float],
                physics: Mapping[str, Any]) -> dict[str, float]:
    """The ``set_points`` given (``surface_speed`` rad/s, ``weight_on_bit`` N) that
    ``scenario`` takes as parameters of its starting point, as env keywords: the scenario
    checks its pipe against buckling at the WOB it starts at, which must be the one run
    (on a horizontal well its own 100 kN buckled the pipe and refused ``--wob 60``). A WOB
    that buckles the pipe itself (under the ``physics`` overrides) stays out where the
    scenario's own start does not: the run and the benchmark note it and drill it from
    there; where both buckle, the scenario refuses the WOB given, by its value."""
    from drill_env.physics.statics import pipe_buckling
    from drill_env.scenarios import make_scenario, scenario_parameters, with_physics

    params = scenario_parameters(scenario)
    start = {key: value for key, value in set_points.items() if key in params}
    if "weight_on_bit" in start:
        own = make_scenario(scenario)
        config = with_physics(own.config, physics)
        if config.solver.lateral and pipe_buckling(config, start["weight_on_bit"]) \
                and not pipe_buckling(config, own.weight_on_bit):
            del start["weight_on_bit"]
    return start


def env_ranges(env_id: str, kwargs: Mapping[str, Any]) -> Any:
    """The set-point ranges ``gymnasium.make(env_id, **kwargs)`` will have (``rpm_range``
    rpm, ``weight_on_bit_range`` N; a task's own), for :func:`set_point_outside`."""
    from types import SimpleNamespace

    values = {**_env_defaults(env_id), **dict(kwargs.get("config") or {}), **kwargs}
    return SimpleNamespace(rpm_range=tuple(values["rpm_range"]),
                           weight_on_bit_range=tuple(values["weight_on_bit_range"]))


def scenario_set_points(scenario: str, seed: int) -> dict[str, float]:
    """The set points (``surface_speed`` rad/s, ``weight_on_bit`` N) at which
    ``DrillString-v0`` starts episode ``seed`` of ``scenario``: the driller's, at which the
    classical controllers act. A control task draws its own targets instead; given these
    as reset options, a task's policy is compared at the same ones."""
    import gymnasium as gym

    import drill_env  # noqa: F401  (registers the env ids)

    env: Any = gym.make("DrillString-v0", scenario=scenario)
    try:
        env.reset(seed=seed)  # a randomised scenario draws them from the seed
        speed, wob = env.unwrapped.targets
    finally:
        env.close()
    return {"surface_speed": float(speed), "weight_on_bit": float(wob)}


def run_episode(episode: Episode) -> dict[str, Any]:
    """Run one episode; returns its benchmark row (plus ``termination``)."""
    import gymnasium as gym

    import drill_env  # noqa: F401  (registers the env ids)
    from agents.registry import make_controller
    from drill_env.metrics import window_metrics
    from drill_env.physics.config import flatten
    from drill_env.physics.layout import RECORD_CHANNELS, R

    settings = BenchmarkSettings(**episode.settings)
    controller = make_controller(episode.controller, env_id=episode.env_id)
    if episode.env_id is not None:  # a task benchmark: one task for every controller
        env_kwargs = dict(settings.env_kwargs)
    else:
        env_kwargs = guest_env_kwargs(controller)
    physics = {**flatten(env_kwargs.pop("physics", None) or {}), **settings.physics,
               **controller.physics()}
    env_id = episode.env_id or controller.env_id
    check_acts_in(episode.controller, controller, env_id)
    # under the benchmark's episode settings, which are the same for every controller
    env_kwargs.update(scenario=episode.scenario, episode_duration=settings.duration,
                      start_kick=settings.start_kick, fidelity=settings.fidelity)
    # a task's policy within a benchmark of DrillString-v0 scenarios acts in its task's
    # env (its observation and action), from the same start as every other controller
    guest = episode.env_id is None and env_id != "DrillString-v0"
    if guest:
        env_kwargs["startup"] = "settled"
    if episode.env_id is None:  # --rpm / --wob, the scenario's start (also reset options)
        env_kwargs.update(starting_at(episode.scenario, settings.set_points(), physics))
    try:
        env: Any = gym.make(env_id, physics=physics, **env_kwargs)
    except ValueError as err:  # said with whose episode it is (a gain of yours too high
        # for the step read as the scenario's)
        raise ValueError(f"{err} (the episode of {episode.label} on {episode.scenario})"
                         ) from None
    if episode.record:
        from drill_env.recording import RecordEpisode

        env = RecordEpisode(env, Path(episode.out) / "recordings", scenario=episode.scenario,
                            controller=episode.label, stem=episode.stem)
    base = env.unwrapped
    kept: list[np.ndarray] = []
    targets: list[tuple[float, float]] = []  # (time, target speed) per step
    # (time, (speed and WOB set points, rock shares)) per step: what must hold for a
    # growing swing to be the loop's (window_swing_trend)
    held: list[tuple[float, tuple[float, ...]]] = []
    total = 0.0
    reason = ""
    # a task's policy in its task's env, within a benchmark of the scenario's set points:
    # at those (else the task would draw its own targets)
    options = scenario_set_points(episode.scenario, episode.seed) if guest else None
    if episode.env_id is None and settings.set_points():  # the user's, over the scenario's
        options = {**(options or {}), **settings.set_points()}
    try:
        obs, info = env.reset(seed=episode.seed, options=options)
        if guest:  # scored as DrillString-v0 scores the other controllers
            base.plain_return = 0.0
        reset(controller, episode.controller, f"{episode.scenario} seed {episode.seed}", base)
        start = float(info["time"])
        while True:
            obs, reward, terminated, truncated, info = env.step(
                act(controller, episode.controller, f"{episode.scenario} seed {episode.seed}",
                    env.action_space, obs, info))
            total += float(reward)
            kept.append(base.last_records)
            targets.append((float(info["time"]), base.targets[0]))
            held.append((float(info["time"]), (float(info["speed_setpoint"]),
                                               float(info["weight_on_bit_setpoint"]),
                                               *np.asarray(info["rock_share"], float))))
            if terminated or truncated:
                reason = str(info.get("termination_reason", "")) if terminated else ""
                break
    finally:
        env.close()
    if episode.record and getattr(env, "last_path", None) == episode.recording:
        # (only a file this run wrote: RERUN=off writes none, and an older one stays old)
        save_text(episode.recording_stamp, f"{episode.stamp}\n{episode.run}\n")
    everything = np.concatenate(kept) if kept else np.zeros((0, len(RECORD_CHANNELS)))
    records = everything[everything[:, R.TIME] >= start + settings.warmup]
    if len(records) < 2 <= len(everything) and reason:  # a failure in the warm-up is a
        # result too: its metrics are the whole episode's (it stopped the whole benchmark)
        records = everything
        reason += "; in the warm-up: metrics over the whole episode"
    if len(records) < 2:  # (a ValueError: said in one line, not a worker's traceback)
        # not a failure: whole control steps end the episode before --duration (20 s are
        # 202 steps of 0.0988 s, 19.97 s, at the fast level: a metrics audit's 19.98 s
        # warm-up left no sample)
        ended = float(info["time"]) - start
        why = reason or (f"the warm-up, {settings.warmup:g} s, leaves no two samples in it: "
                         f"it ends at {ended:.4g} s, {base.max_episode_steps} control steps of "
                         f"{base.control_interval:.4g} s")
        raise ValueError(f"the episode of {episode.label} on {episode.scenario}, seed "
                         f"{episode.seed}, ended before a second sample, with nothing to "
                         f"measure ({why})")
    dt = float(records[1, R.TIME] - records[0, R.TIME])
    m = window_metrics(records, RECORD_CHANNELS, dt, base.clearance,
                       base.sim.config.bit.diameter)
    mean_speed = float(np.mean(records[:, R.BIT_SPEED]))
    # the target may change during an episode (the tasks' driller): its mean over the
    # measured part, step by step
    in_window = [speed for t, speed in targets if t >= start + settings.warmup]
    target_rpm = float(np.mean(in_window or [targets[-1][1]])) / RPM
    own = getattr(controller, "sets_own_speed", None)  # a controller of your own may say
    row = {
        "controller": episode.label, "scenario": episode.scenario, "seed": episode.seed,
        "ssi": m["ssi"], "stuck_fraction": m["stuck_fraction"],
        "mean_bit_rpm": mean_speed / RPM, "target_rpm": target_rpm,
        "rpm_tracking_error": abs(mean_speed / RPM - target_rpm) / target_rpm
        if target_rpm > 0 else math.nan,
        "rop_m_per_h": m["rop"] * HOUR, "radial_ratio": m["radial_ratio"],
        "backward_whirl_fraction": m["backward_whirl_fraction"],
        "max_lateral_force_kN": m["lateral_force_max"] / KILO,
        "mse_MPa": m["mse"] / MEGA, "top_drive_energy_MJ": m["top_drive_energy"] / MEGA,
        # a guest's own return is its task's reward: DrillString-v0's is comparable
        "episode_return": base.plain_return if guest else total, "termination": reason,
        # judged in the env it acted in: a drilling-task policy chooses the rpm in a
        # scenario benchmark too, as a guest (not a benchmark.csv column)
        "own_speed": own if isinstance(own, bool) else sets_own_speed(episode.label, env_id),
        "guest": guest,  # a task's policy in a scenario benchmark (not a column either)
        # a stick-slip still building, which the window's SSI may not show yet (not a
        # column): judged in DrillString-v0 (a guest's corrections, like a task's
        # target changes, would read as swing) where set points and rock held
        "swing_trend": window_swing_trend(everything, held, start, settings)
        if episode.env_id is None and not guest and not reason else "",
    }
    if episode.series:
        series_dir = Path(episode.out) / "series"
        series_dir.mkdir(parents=True, exist_ok=True)
        arrays: dict[str, Any] = {name: everything[:, RECORD_CHANNELS.index(name)]
                                  for name in SERIES_CHANNELS}
        arrays["time"] = arrays["time"] - start
        arrays["clearance"] = base.clearance
        arrays["target_time"] = np.array([0.0] + [t - start for t, _ in targets[:-1]])
        arrays["target_rpm"] = np.array([speed / RPM for _, speed in targets])
        arrays["stamp"] = np.array(episode.stamp)
        save_whole(episode.series_file, lambda file: np.savez_compressed(file, **arrays))
    return row


#: Least bit-speed swing (rpm, half of max - min) of a window that the benchmark marks as
#: growing: above the ~0.02 rpm a held SoftSpeed loop (k = 4) settles to on a 1,500 kg m^2
#: top drive and the 0.027-0.028 rpm hump at 60-90 s of k = 5 there, which then decays
#: (seeds 0-4; both rise from ~0.003 rpm, neither is stick-slip), below the 0.045 rpm at
#: 60 s of the 2,000 kg m^2 drive's stick-slip, full by ~200 s (docs/controllers.md); about
#: midway. :data:`drill_env.swing.NO_SWING`, 0.01 rpm, marked loops that hold.
GROWING_FLOOR = 0.035
#: The start of a row's ``swing_trend`` where the trend was not judged, and why.
NOT_JUDGED = "not judged: "
SET_POINT_MOVED = NOT_JUDGED + "a set point moved"
ROCK_CHANGED = NOT_JUDGED + "the rock under the bit changed"
#: Rock shares under the bit that differ by more than this are another rock: a layer
#: crossed raises the swing without any loop's doing (paper_case2's ZTorque, x2.5).
SAME_ROCK = 1e-3


def window_swing_trend(records: np.ndarray, held: Sequence[tuple[float, tuple[float, ...]]],
                       start: float, settings: BenchmarkSettings) -> str:
    """Whether the bit-speed swing grows from the warm-up into the metric window
    (:func:`drill_env.swing.swing_trend`): the last ``block`` s of the window against the
    ``block`` s before it, ``block`` the shorter of the warm-up and the window. "" where
    the window's swing is under :data:`GROWING_FLOOR`; :data:`NOT_JUDGED` and why where
    ``held`` (per step: time, then set points and rock shares) changed over the two
    blocks: a set point moved by a policy or a target, or a layer crossed, would read as
    growth. A controls engineer's check: SoftSpeed on a 2,000 kg m^2 top drive read SSI
    0.00 over 30-60 s while its swing grew x4 per 30 s, to full stick-slip by ~200 s."""
    from drill_env.physics.layout import R
    from drill_env.swing import swing_trend

    split, end = start + settings.warmup, start + settings.duration
    block = min(settings.warmup, settings.duration - settings.warmup)
    spanned = np.array([values for t, values in held if t > split - block])
    if len(spanned) and np.ptp(spanned[:, :2], axis=0).any():
        return SET_POINT_MOVED
    if len(spanned) and float(np.max(np.ptp(spanned[:, 2:], axis=0))) > SAME_ROCK:
        return ROCK_CHANGED
    time, rpm = records[:, R.TIME], records[:, R.BIT_SPEED] / RPM
    before = rpm[(time >= split - block) & (time < split)]
    last = rpm[time >= min(end, float(time[-1])) - block]
    if len(before) < 2 or len(last) < 2 or 0.5 * float(np.ptp(last)) < GROWING_FLOOR:
        return ""
    swings = [0.5 * float(np.ptp(before)), 0.5 * float(np.ptp(last))]
    return swing_trend(swings, float(np.min(last)), block=end - split)


def reset(controller: Any, typed: str, where: str, env: Any) -> None:
    """``controller.reset(env)``; for a controller of your own (``typed``), an error in its
    code said in one line as :func:`act` says one (a raising ``reset`` gave a traceback
    through the benchmark and exit 1 where every other hook gave a line and exit 2: a new
    user's trial)."""
    from agents.registry import in_user_code, is_imported

    if not is_imported(typed):
        controller.reset(env)
        return
    try:
        controller.reset(env)
    except Exception as err:  # noqa: BLE001 - the user's code: said in one line
        raise ValueError(f"controller: {typed}: reset() raised {in_user_code(err)} "
                         f"({where})") from None


def act(controller: Any, typed: str, where: str, space: Any, obs: Any,
        info: dict[str, Any]) -> Any:
    """``controller.act``; for a controller of your own (``typed``: its name as given), an
    error in its code or an action the env cannot take is said in one line naming it,
    the line of its file and ``where`` (the episode), not a worker's traceback of dozens
    of lines of the pool's."""
    from agents.registry import in_user_code, is_imported

    if not is_imported(typed):
        return controller.act(obs, info)
    try:
        action = controller.act(obs, info)
    except Exception as err:  # noqa: BLE001 - the user's code: said in one line
        raise ValueError(f"controller: {typed}: act() raised {in_user_code(err)} "
                         f"({where})") from None
    if action is None:  # (said as "an action of shape ()")
        raise ValueError(f"controller: {typed}: act() returned None; the env takes an "
                         f"action of shape {space.shape} ({where})")
    if np.shape(action) != space.shape:
        raise ValueError(f"controller: {typed}: act() returned an action of shape "
                         f"{np.shape(action)}; the env takes {space.shape} ({where})")
    try:
        values = numbers(action, "action")
    except ValueError as err:  # strings, None, ragged lists: said with the controller
        raise ValueError(f"controller: {typed}: act() returned an {err} ({where})") from None
    if not np.isfinite(values).all():
        raise ValueError(f"controller: {typed}: act() returned {values.tolist()}, not "
                         f"finite numbers ({where})")
    if typed not in _CLIPPED and not (np.all(values >= space.low)
                                      and np.all(values <= space.high)):
        # the env clips it, as documented; a controller of your own hears it once (one
        # returning 5.0 ran at the top speed, its table saying only "rpm error 193 %")
        _CLIPPED.add(typed)
        low, high = space.low.tolist(), space.high.tolist()
        bounds = f"[{low[0]:g}, {high[0]:g}]" if len(set(low)) == len(set(high)) == 1 \
            else f"[{low}, {high}]"
        warnings.warn(f"controller: {typed}: act() returned {values.tolist()}, outside the "
                      f"action space {bounds}: the env clips it ({where}; said at the first)",
                      stacklevel=2)
    return action


#: Controllers of your own already told that the env clips their actions.
_CLIPPED: set[str] = set()


def episodes(controllers: Sequence[str], scenarios: Sequence[str], seeds: Sequence[int],
             settings: BenchmarkSettings, out: Path, record: bool = False,
             env_id: str | None = None) -> list[Episode]:
    """Every (controller, scenario, seed); the first seed keeps its time series."""
    plain = dataclasses.asdict(settings)
    names = dict(zip(controllers, labels(controllers), strict=True))
    digests = {c: controller_digest(c, env_id) for c in controllers}
    return [Episode(c, s, seed, plain, str(out), record, seed == seeds[0], env_id,
                    names[c], digests[c])
            for s in scenarios for seed in seeds for c in controllers]


def replaced_episode_settings(trained: dict[str, Any], settings: BenchmarkSettings,
                              scenario: str) -> list[tuple[str, Any, Any]]:
    """(key, trained value, benchmark value) of each episode setting (scenario, length,
    start kick) a policy trained under and the benchmark's own episodes replace: what
    ``evaluate`` and a task benchmark say, so that it is not done silently."""
    ours = {"scenario": scenario, "episode_duration": settings.duration,
            "start_kick": settings.start_kick}
    return [(key, trained[key], value) for key, value in ours.items()
            if key in trained and trained[key] != value]


def stamp(fingerprint: str, key: str) -> str:
    """A short digest of a row's fingerprint and key, for the files it leaves."""
    import hashlib

    return hashlib.sha256(f"{fingerprint}|{key}".encode()).hexdigest()[:16]


def run_stamp(fingerprint: str) -> str:
    """A short digest of a run's fingerprint: the same for all its rows."""
    import hashlib

    return hashlib.sha256(fingerprint.encode()).hexdigest()[:16]


def fingerprint(settings: BenchmarkSettings, env_id: str | None = None) -> str:
    """What a stored row depends on besides its key: rows of other settings, or computed
    by other code (the simulator, scenarios, metrics, controllers), are not reused."""
    from drill_env.sweep import source_digest

    return json.dumps({"settings": jsonable(settings), "env_id": env_id,
                       "code": source_digest("drill_env", "agents")}, sort_keys=True)


def check_guest_set_points(controllers: Sequence[str], settings: BenchmarkSettings) -> None:
    """ConfigError naming a controller that acts in a task's env (a guest) whose set-point
    ranges do not hold the set points given: found before any episode runs, not in it."""
    import gymnasium as gym

    import drill_env  # noqa: F401  (registers the env ids)
    from agents.registry import make_controller

    for name in controllers:
        controller = make_controller(name)
        if controller.env_id == "DrillString-v0":
            continue
        env: Any = gym.make(controller.env_id, **guest_env_kwargs(controller))
        config = env.unwrapped.config
        env.close()
        if out := set_point_outside(settings.surface_speed, settings.weight_on_bit, config):
            key, value, low, high, unit = out
            raise ConfigError(
                f"{key}: {value:g} {unit} lies outside {controller.env_id}'s range "
                f"{low:g}-{high:g} {unit}, where {name} acts (a task's policy drills a "
                "scenario benchmark in its own env)")


def check_held_actions(controllers: Sequence[str], env_id: str | None) -> None:
    """ValueError unless each ``held:...`` gives one value, or one per action, of the env
    it acts in (``env_id``, else ``DrillString-v0``): said before any episode runs, not in
    a worker after other controllers' episodes."""
    held = [n for n in controllers if n.startswith("held:")]
    if not held:
        return
    import gymnasium as gym

    import drill_env  # noqa: F401  (registers the env ids)
    from agents.trivial import HeldAction

    env = gym.make(env_id or "DrillString-v0")
    try:
        size = int(np.prod(env.action_space.shape or ()))
    finally:
        env.close()
    for name in held:
        try:
            HeldAction.parse(name.partition(":")[2]).check_size(size)
        except ValueError as err:
            raise ValueError(f"controllers: {str(err).partition(': ')[2]} "
                             f"({env_id or 'DrillString-v0'})") from None


def run_benchmark(controllers: Sequence[str], scenarios: Sequence[str], seeds: Sequence[int],
                  out: Path, settings: BenchmarkSettings | None = None,
                  workers: int | None = None, ray_address: str | None = None,
                  record: bool = False, progress: bool = True, env_id: str | None = None,
                  heading: str = "Controller benchmark") -> list[dict[str, Any]]:
    """Run what is not in ``out/benchmark_results.jsonl`` yet, then write the table,
    summary and plots of every finished row (``heading``: benchmark.md's title) and print
    the table (``progress``: the progress bar and the note of reused rows). Returns the
    rows."""
    from drill_env.progress import progress_bar
    from drill_env.sweep import ResultStore, folder_lock, make_executor

    settings = settings or BenchmarkSettings()
    if objects := [c for c in controllers if not isinstance(c, str)]:  # (an AttributeError
        # deep inside: 'type' object has no attribute 'startswith')
        raise TypeError(f"controllers: names, not {type(objects[0]).__name__} objects "
                        f"({objects[0]!r:.60}): a built-in name, or a class of your own as "
                        "'file.py:ClassName' (worker processes import it by name, and "
                        "stored rows follow its file; one defined in a notebook or at the "
                        "prompt: save it in a .py file first; docs/controllers.md)")
    if (twice := repeated(scenarios)) is not None:
        raise ValueError(f"scenarios: {twice!r} is given twice")
    if env_id is not None and settings.set_points():
        raise ConfigError(
            f"{next(iter(settings.set_points()))}: a task benchmark drills at the targets its "
            "task draws from each seed (the same for every controller); set points are a "
            "scenario benchmark's")
    if env_id is None and settings.set_points():
        check_guest_set_points(controllers, settings)
    if env_id is None and settings.env_kwargs:
        raise ConfigError(
            f"env_kwargs: {sorted(settings.env_kwargs)} would change nothing in a scenario "
            "benchmark, where each controller runs in its own env at the scenario's set "
            "points: they are a task benchmark's (env_id, --task); config overrides go in "
            "physics")
    check_held_actions(controllers, env_id)
    if env_id is not None:  # the policies' task settings, unless the caller gave its own
        settings = dataclasses.replace(settings, env_kwargs={
            **task_settings(controllers, env_id), **settings.env_kwargs})
    labels(controllers)  # a name that does not load is refused before --out is made
    out = Path(out)
    # one process writes the folder: a second benchmark into it is refused
    with folder_lock(out, "this benchmark", tidy=("series",)):
        store = ResultStore(out / RESULTS_FILE, fingerprint(settings, env_id))
        todo_all = [dataclasses.replace(e, stamp=stamp(store.fingerprint, e.key),
                                        run=run_stamp(store.fingerprint))
                    for e in episodes(controllers, scenarios, seeds, settings, out, record,
                                      env_id)]
        # a stored row is rerun only to write its series or a recording asked for, missing
        # or made by another run, or where it is not a row this episode writes (an edit)
        unsound = [e.key for e in todo_all
                   if e.key in store and not sound_row(store.get(e.key), e)]
        todo = [e for e in todo_all
                if e.key not in store or e.key in unsound or not e.outputs_current()]
        reused = len(todo_all) - len(todo)
        if store.ignored and progress:  # (it started afresh without a word)
            print(f"benchmark: {store.ignored} stored row(s) of other settings or code in "
                  f"{out / RESULTS_FILE}: not used (kept in the file)", file=sys.stderr)
        if store.cut and progress:
            print(f"benchmark: the last line of {out / RESULTS_FILE} was cut (a run stopped "
                  "while writing it): skipped, its episode runs again", file=sys.stderr)
        if (store.damaged or unsound) and progress:
            print(f"benchmark: {store.damaged + len(unsound)} line(s) of {out / RESULTS_FILE} "
                  "are not rows this run can use (damaged or edited by hand"
                  + (f": {unsound[0]}" if unsound else "") + "): skipped, their episodes "
                  "run again", file=sys.stderr)
        if reused and progress:
            print(f"benchmark: {reused} of {len(todo_all)} episodes already in "
                  f"{out / RESULTS_FILE} (same settings and code; a controller of your own: its "
                  f"file and data_files): not rerun", file=sys.stderr)
        # before any episode: one recorded now would replace theirs under the same name
        set_aside_stale_recordings(todo_all, out, progress)
        if todo:
            from agents.registry import make_controller

            # each policy loaded once here first: a damaged file is the command's error before
            # any episode runs, not after the classical controllers' episodes
            for name, episode_env in {(e.controller, e.env_id) for e in todo
                                      if e.controller.startswith("learned")}:
                make_controller(name, env_id=episode_env)
            local = min(workers or usable_cores(), len(todo))
            executor = make_executor(local if ray_address is None else None, ray_address)
            bar = progress_bar(total=len(todo_all), initial=len(todo_all) - len(todo),
                               unit="episode", desc="benchmark", disable=not progress,
                               file=sys.stderr)
            try:
                def keep(k: int, row: dict[str, Any]) -> None:
                    store.put(todo[k].key, row)
                    bar.update(1)

                for k, row in executor.map_unordered(run_episode, todo, late=keep):
                    keep(k, row)
            finally:
                bar.close()
                executor.close()
        rows = [store.get(e.key) for e in todo_all]
        from agents.learned import policy_files

        names = labels(controllers)
        runs = {name: f"{c.partition(':')[2]} ({policy_files(c.partition(':')[2])[0].name})"
                for c, name in zip(controllers, names, strict=True) if c.startswith("learned:")}
        first_seed = seeds[0] if len(seeds) else 0
        # the series this run's episodes wrote (another benchmark into the same folder at the
        # same time overwrote them: a picture of its episodes beside this run's table)
        stamps = {(e.label, e.scenario): e.stamp for e in todo_all if e.seed == first_seed}
        write_outputs(rows, out, names, scenarios, settings, env_id, heading,
                      first_seed=first_seed, runs=runs, stamps=stamps)
        return rows


def sound_row(row: Any, episode: Episode) -> bool:
    """Whether ``row``, stored under ``episode``'s key, is one :func:`run_episode` writes
    for it: its columns there, the episode's controller, scenario and seed, numbers where
    the metrics are. A row edited by hand ("abc" for a ROP) ended the command with "could
    not convert string to float: 'abc'", naming neither file nor row; a seed changed by
    hand went into benchmark.csv (an outside check)."""
    if not (isinstance(row, dict) and set(COLUMNS) <= row.keys()):
        return False
    if (row["controller"], row["scenario"], row["seed"]) != (
            episode.label, episode.scenario, episode.seed):
        return False
    return all(isinstance(row[c], int | float) and not isinstance(row[c], bool)
               for c in COLUMNS[3:])


def set_aside_stale_recordings(episodes: Sequence[Episode], out: Path, say: bool) -> None:
    """Move the recordings under these rows' names that another run made (other
    settings or code: the stamp beside them differs, or is missing) to
    ``recordings/other_runs/<their stamp>/``, before the run records its own: a rerun
    into the folder, with ``--record``, replaced them, without it, left them beside a table
    they do not replay. Says how many it moved."""
    moved = 0
    for e in episodes:
        if not e.recording.exists() or e.recording_current():
            continue
        sidecar = e.recording_stamp
        lines = sidecar.read_text(encoding="utf-8").split() if sidecar.exists() else []
        # one folder per run (its run stamp; a recording of before it had only its row's),
        # so a second set-aside keeps the first; a damaged stamp is not a path
        stamp = lines[-1] if lines else ""
        folder = stamp if stamp.isalnum() and stamp.isascii() else "unstamped"
        aside = out / "recordings" / "other_runs" / folder
        aside.mkdir(parents=True, exist_ok=True)
        for file in (e.recording, sidecar):
            if file.exists():
                file.replace(aside / file.name)
        moved += 1
    if moved and say:
        print(f"benchmark: {moved} recording(s) of another run (other settings or code) "
              f"under this table's names moved to {out / 'recordings' / 'other_runs'}",
              file=sys.stderr)


# --------------------------------------------------------------------------- outputs


def write_csv(rows: Sequence[dict[str, Any]], path: Path) -> None:
    text = io.StringIO()
    writer = csv.writer(text)
    writer.writerow(COLUMNS)
    for row in rows:
        writer.writerow([_csv_value(row[c]) for c in COLUMNS])
    save_text(path, text.getvalue(), newline="")  # an interrupt leaves the old file whole


def _csv_value(value: Any) -> Any:
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
               "costs the failure weight (docs/controllers.md); a "
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
    """Whether the controller of table name ``name`` (:func:`labels`) chooses its own rpm
    instead of holding the planned one: the driller, constant set points, a learned
    policy in a benchmark of the drilling task (``env_id``), and the trivial policies
    (held actions, random) in any env but task 1's."""
    if name == "driller" or name.startswith("constant-"):
        return True
    from agents.trivial import HeldAction

    if name == "random" or HeldAction.from_label(name) is not None:
        # on the env's own action: the rpm everywhere but in task 1, where it corrects
        # the speed around the driller's target
        return env_id != CORRECTS_SPEED
    return env_id == CHOOSES_RPM and is_learned_label(name)


def is_learned_label(name: str) -> bool:
    """Whether a row label (:func:`labels`) is a trained policy's: ``learned``, or
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
    _print_table(header, table, [*notes, SPREAD_NOTE], title=heading)
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


def _print_table(header: Sequence[str], table: Sequence[Sequence[str]],
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
