"""What a benchmark episode is and the settings it runs under: :class:`BenchmarkSettings`,
:class:`Episode` and the controllers' table names; the env settings the learned policies of
a task benchmark trained with, which every controller beside them acts under; a guest
controller's env keywords; the scenario's starting point and set points.
"""

from __future__ import annotations

import dataclasses
import json
import zipfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import Field

from drill_env.physics.config import Fidelity
from drill_env.physics.units import KILO, RPM
from drill_env.physics.validation import (
    ConfigError,
    NonNegative,
    Positive,
    check_newtons,
    config_dataclass,
    jsonable,
    repeated,
)


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


#: The first line of a recording's stamp while it is being made (its second: the run's
#: stamp): one an interrupt cut short, told from a finished one of another run.
UNFINISHED = "unfinished"


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
    #: A ``learned:RUN`` controller's (model, statistics) files as pinned when the
    #: benchmark started (:func:`agents.benchmark.pin_policy`); None: its own.
    policy: tuple[str, str] | None = None

    @property
    def label(self) -> str:
        return self.name or label(self.controller)

    def policy_kwargs(self) -> dict[str, Any]:
        """What :func:`agents.registry.make_controller` takes to load :attr:`policy`."""
        return {} if self.policy is None else {"files": tuple(map(Path, self.policy))}

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
            if all(c.startswith("learned:") for c in twins) and len(
                    runs := {Path(c.partition(":")[2]).resolve() for c in twins}) == 1:
                raise ValueError(f"controllers: {', '.join(twins)} are the same run "
                                 f"({runs.pop()}), given twice; give it once")
            from agents.registry import is_imported

            fix = ("set another name attribute on one of the classes"
                   if any(is_imported(c) for c in twins) else "rename a run folder")
            alike = " (names that differ only in case name the same files on macOS " \
                "and Windows)" if len({out[controllers.index(c)] for c in twins}) > 1 else ""
            raise ValueError(f"controllers: {', '.join(twins)} would share the name "
                             f"{name!r} in the table{alike}; {fix}")
    return out


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

    defaults = env_defaults(env_id)
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
                check_env_kwargs(name, env_id, kwargs)
        if kwargs is not None:
            kwargs["physics"] = flatten(kwargs.get("physics") or {})
            seen[name] = {k: v for k, v in kwargs.items() if k not in SET_BY_BENCHMARK
                          and v != {} and as_text(v) != as_text(defaults.get(k, NONE))}
    kinds = {as_text(v) for v in seen.values()}
    if len(kinds) > 1:
        listed = "; ".join(f"{n}: {v or 'the defaults'}" for n, v in seen.items())
        raise ValueError(f"controllers: the policies were trained on different {env_id} "
                         f"settings ({listed}); benchmark them apart")
    return next(iter(seen.values()), {})


def check_env_kwargs(name: str, env_id: str, kwargs: Mapping[str, Any]) -> None:
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


NONE = object()  # no default: never equal to a given value


def as_text(value: Any) -> str:
    """A value as JSON (tuples and lists, 1 and 1.0 alike) for comparing settings."""
    def plain(v: Any) -> Any:
        if isinstance(v, dict):
            return {k: plain(x) for k, x in v.items()}
        if isinstance(v, list | tuple):
            return [plain(x) for x in v]
        return float(v) if isinstance(v, int) and not isinstance(v, bool) else v

    return json.dumps(plain(jsonable(value)), sort_keys=True) if value is not NONE else ""


def env_defaults(env_id: str) -> dict[str, Any]:
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

    values = {**env_defaults(env_id), **dict(kwargs.get("config") or {}), **kwargs}
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


def stamp(fingerprint: str, key: str) -> str:
    """A short digest of a row's fingerprint and key, for the files it leaves."""
    import hashlib

    return hashlib.sha256(f"{fingerprint}|{key}".encode()).hexdigest()[:16]
