"""Controllers by name: what ``drill-env run --controller`` and ``benchmark`` accept.

Besides the registry's names, a controller of your own is named by where it is:
``path/to/file.py:ClassName`` or ``package.module:ClassName`` (docs/controllers.md, "Your
own controller"). The benchmark's workers import it again by that name."""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
import os
import re
import sys
from collections.abc import Callable, Mapping
from pathlib import Path
from types import ModuleType
from typing import Any

from agents.base import Controller
from agents.classical import ConstantSetPoints, SoftSpeed, SoftTorque, StiffPI, ZTorque
from agents.driller import Driller
from agents.trivial import HeldAction, RandomActions
from drill_env.physics.validation import comma_items, did_you_mean


def _learned(**kwargs: Any) -> Controller:
    from agents.learned import LearnedController

    return LearnedController.load(**kwargs)


#: name -> factory. ``learned`` loads a trained policy (the shipped one by default).
CONTROLLERS: dict[str, Callable[..., Controller]] = {
    StiffPI.name: StiffPI,
    SoftSpeed.name: SoftSpeed,
    SoftTorque.name: SoftTorque,
    ZTorque.name: ZTorque,
    Driller.name: Driller,
    RandomActions.name: RandomActions,
    "learned": _learned,
}
#: The trivial policies a learned one must beat (agents.trivial): every action held at
#: -1, 0 and +1, and random actions.
TRIVIAL = ("held:-1", "held:0", "held:1", RandomActions.name)
#: The controllers that need no trained policy (the classical ones and the driller).
CLASSICAL = tuple(name for name in CONTROLLERS if name != "learned" and name not in TRIVIAL)


#: The fields of ``TopDriveConfig`` that make a controller's loop, which its ``physics()``
#: may set; every other field is the drive's hardware (rotor inertia, torque rating,
#: acceleration limit, and any added later), the same for every controller, which
#: ``--config`` changes for all of them.
TOP_DRIVE_LOOP = frozenset({"controller", "proportional_gain", "integral_gain",
                            "tuning_frequency", "impedance_factor", "torque_feedback",
                            "feedback_gain", "filter_frequency", "filter_damping"})

#: What an unknown name's error lists: the registry's names and the parametrised forms.
KNOWN = (f"{', '.join(CONTROLLERS)}, learned:<run folder>, constant:<rpm>/<kN>, "
         "held:<action>[/<action>], <file.py or module>:<class> (your own)")

#: The prefixes of the registry's parametrised names (not a module to import).
_PARAMETRISED = ("learned", "constant", "held")


def is_imported(name: str) -> bool:
    """Whether ``name`` is the import form ``<file.py or module>:<attribute>`` of a
    controller of your own."""
    source, colon, attribute = name.rpartition(":")
    return bool(colon and source and source not in _PARAMETRISED
                and not source.startswith(tuple(p + ":" for p in _PARAMETRISED))
                and attribute.isidentifier())


def _module(source: str) -> ModuleType:
    """The module ``source`` names: a ``.py`` file or an importable module, looked for in
    the working folder too (as ``python -m`` does; the ``drill-env`` script alone would
    not). Loaded again when its file changed since (the benchmark's stored rows follow
    the file, :func:`source_file`, so the code that runs must too)."""
    if source == "__main__" and not getattr(sys.modules.get("__main__"), "__file__", None):
        raise ValueError("controller: __main__ is a notebook or the interactive prompt here: "
                         "a class defined there has no file for the benchmark's worker "
                         "processes to import and its stored rows to follow; save it in a "
                         ".py file and give file.py:ClassName")
    if source.endswith(".py"):
        path = Path(source).expanduser().resolve()
        if not path.is_file():
            raise ValueError(f"controller: no file {source!r} (from {os.getcwd()})")
        key = "_drill_env_controller_" + hashlib.sha256(str(path).encode()).hexdigest()[:12]
        module = sys.modules.get(key)
        if module is None or _LOADED.get(key) != path.read_bytes():
            spec = importlib.util.spec_from_file_location(key, path)
            assert spec is not None and spec.loader is not None  # a .py file
            module = importlib.util.module_from_spec(spec)
            sys.modules[key] = module
            # the modules it imports from its own folder, found first as `python file.py`
            # finds them; for its import only (a later import elsewhere is not redirected)
            sys.path.insert(0, str(path.parent))
            try:
                _load(module, spec.loader.exec_module)
            except BaseException as err:
                del sys.modules[key]
                if isinstance(err, USER_ERRORS):
                    raise ValueError(f"controller: cannot load {source}: "
                                     f"{in_user_code(err)}") from None
                raise
            finally:
                sys.path.remove(str(path.parent))
        return module
    try:
        module = _import(source)
    except ModuleNotFoundError as err:
        here = os.getcwd()
        if err.name != source.partition(".")[0] or here in sys.path:
            raise ValueError(f"controller: cannot import {source!r}: {err}") from None
        sys.path.append(here)
        try:
            module = _import(source)
        except ModuleNotFoundError as err:
            raise ValueError(f"controller: cannot import {source!r} (looked in the Python "
                             f"path and {here}): {err}") from None
        except USER_ERRORS as err:  # the user's module: said in one line
            raise ValueError(f"controller: cannot load {source}: {in_user_code(err)}"
                             ) from None
        finally:
            sys.path.remove(here)
    except USER_ERRORS as err:  # the user's module: said in one line
        raise ValueError(f"controller: cannot load {source}: {in_user_code(err)}") from None
    return module


#: What a controller of your own may raise, said in one line naming it: its errors, and a
#: ``sys.exit`` (a file whose last line is ``sys.exit(main())``, no ``__main__`` guard,
#: ended the command at its import with exit 0 and nothing said). Not KeyboardInterrupt:
#: a Ctrl-C stops the command.
USER_ERRORS = (Exception, SystemExit)


def in_user_code(err: BaseException) -> str:
    """``err`` in one line, with the file and line of the deepest frame outside this
    project's packages and Python's own import machinery (the user's code)."""
    import traceback

    if isinstance(err, SyntaxError):
        return f"SyntaxError: {err.msg} ({Path(err.filename or '?').name}, line {err.lineno})"
    ours = Path(__file__).resolve().parent.parent
    skip = [ours / "agents", ours / "drill_env",  # ours, Python's and installed packages
            *{Path(p).resolve() for p in (sys.prefix, sys.base_prefix, sys.exec_prefix)}]
    where = ""
    for frame in traceback.extract_tb(err.__traceback__):
        path = Path(frame.filename).resolve()
        if not frame.filename.startswith("<") and not any(path.is_relative_to(s)
                                                          for s in skip):
            where = f" ({path.name}, line {frame.lineno})"
    return f"{type(err).__name__}: {err}{where}"


#: module name -> the bytes of its file when it was loaded (controllers of your own).
_LOADED: dict[str, bytes] = {}


def _load(module: ModuleType, run: Callable[[ModuleType], Any]) -> None:
    """Run (or rerun) ``module``'s code, noting its file's bytes first."""
    file = getattr(module, "__file__", None)
    code = Path(file).read_bytes() if file else b""
    run(module)
    _LOADED[module.__name__] = code


def _import(source: str) -> ModuleType:
    """``importlib.import_module``, reloaded when its file changed since it was loaded."""
    module = importlib.import_module(source)
    file = getattr(module, "__file__", None)
    if module.__name__ not in _LOADED:
        _LOADED[module.__name__] = Path(file).read_bytes() if file else b""
    elif file and _LOADED[module.__name__] != Path(file).read_bytes():
        _load(module, importlib.reload)
    return module


def imported_factory(name: str) -> Callable[..., Controller]:
    """The class (or factory) ``<file.py or module>:<attribute>`` names."""
    source, _, attribute = name.rpartition(":")
    module = _module(source)
    try:
        factory = getattr(module, attribute)
    except AttributeError:  # (which it has: a class named in the docs' example and
        # another in the file was a guess to make)
        found = sorted(n for n, v in vars(module).items() if isinstance(v, type)
                       and v.__module__ == module.__name__ and callable(getattr(v, "act", None)))
        where = (f"; its controller classes: {', '.join(found)}" if found
                 else "; it defines no controller class (a subclass of "
                      "agents.SetPointController)")
        raise ValueError(f"controller: {source} has no {attribute!r}{where}") from None
    if not callable(factory):
        raise ValueError(f"controller: {name} is {type(factory).__name__} "
                         f"{factory!r:.40}, not a controller class (subclass "
                         "agents.SetPointController)")
    return factory


def source_file(factory: Any) -> Path | None:
    """The file ``factory`` is defined in, when that is outside this project's packages
    (a controller of your own, whose code the benchmark's stored rows must follow)."""
    import inspect

    try:
        file = inspect.getsourcefile(factory)
    except (TypeError, OSError):  # built in, or no source (defined at a prompt)
        return None
    if file is None:
        return None
    path = Path(file).resolve()
    ours = Path(__file__).resolve().parent.parent
    inside = any(path.is_relative_to(ours / package) for package in ("agents", "drill_env"))
    return None if inside else path


def table_name(name: str) -> str:
    """The name a controller of your own has in tables and file names: its class's own
    ``name`` attribute if it sets one, else the attribute after the colon."""
    factory = imported_factory(name)
    own = vars(factory).get("name") if isinstance(factory, type) else None
    return own if isinstance(own, str) and own else name.rpartition(":")[2]


_CONSTANT_LABEL = re.compile(r"constant-(.+)rpm-(.+)kN")


def canonical(name: str) -> str:
    """``name`` as the registry takes it: a table's name of constant set points
    (``constant-120rpm-100kN``, :func:`agents.settings.label`) is ``constant:120/100``,
    so a row of ``benchmark.csv`` can be run again by its name; other names as given.
    A trained run's table name (``learned-<folder>``) cannot say where its folder is: it
    is refused with the form to give."""
    match = _CONSTANT_LABEL.fullmatch(name)
    if match:
        return f"constant:{match[1]}/{match[2]}"
    held = HeldAction.from_label(name)
    if held is not None:
        return held
    if name.startswith("learned-"):
        raise ValueError(f"controller: {name!r} is a trained run's name in a benchmark "
                         "table; give it as learned:<run folder>")
    return name


def make_controller(name: str, **kwargs: Any) -> Controller:
    """The controller called ``name`` (``CONTROLLERS``); unknown names are named.

    ``learned:PATH`` loads the policy of a training run folder (``logs/runs/<name>``);
    plain ``learned`` the shipped policy (of ``env_id``'s task if given);
    ``constant:<rpm>/<kN>`` (or its table name, :func:`canonical`) holds those set
    points, ``held:<a>[/<a2>]`` those actions (:class:`agents.trivial.HeldAction`)."""
    name = canonical(name)
    if name.startswith("learned:"):
        return _learned(path=name.partition(":")[2], **kwargs)
    if name.startswith("constant:"):
        return ConstantSetPoints.parse(name.partition(":")[2])
    if name.startswith("held:"):
        return HeldAction.parse(name.partition(":")[2])
    if name != "learned":
        kwargs.pop("env_id", None)  # only the learned controller depends on the task
    if is_imported(name):
        factory = imported_factory(name)
        import inspect

        try:  # (an error raised inside it was said as "cannot be made with no arguments")
            inspect.signature(factory).bind(**kwargs)
        except TypeError as err:
            raise ValueError(f"controller: {name} cannot be made with no arguments: "
                             f"TypeError: {err}") from None
        except ValueError:  # no signature to read (a builtin): the call says
            pass
        try:
            controller = factory(**kwargs)
        except USER_ERRORS as err:  # the user's code: said in one line
            raise ValueError(f"controller: {name} failed as it was made: "
                             f"{in_user_code(err)}") from None
        check_interface(name, controller)
        return controller
    try:
        factory = CONTROLLERS[name]
    except KeyError:
        raise ValueError(f"controller: unknown name {name!r}"
                         f"{did_you_mean(name, list(CONTROLLERS))}; known: {KNOWN}") from None
    return factory(**kwargs)


#: The characters a controller's table name may hold: it names files (series,
#: recordings) and CSV rows.
_TABLE_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.+-]*")


def data_files(name: str, controller: Any) -> list[Path]:
    """A controller's ``data_files`` (:class:`agents.SetPointController`), each an existing
    file; ValueError naming the controller otherwise."""
    files = getattr(controller, "data_files", ())
    if isinstance(files, (str, bytes)) or not isinstance(files, (tuple, list)) or not all(
            isinstance(f, (str, os.PathLike)) for f in files):
        raise ValueError(f"controller: {name}: data_files is {files!r}, not a tuple of "
                         "file paths")
    for file in files:
        if not Path(file).is_file():
            raise ValueError(f"controller: {name}: data_files: {os.fspath(file)!r} is not a "
                             f"file (from {Path.cwd()})")
    return [Path(f) for f in files]


def is_drill_env(env_id: Any) -> bool:
    """Whether ``env_id`` is registered for :class:`drill_env.env.DrillStringEnv` or a
    subclass (the tasks', one of your own), or for a factory function (which only making
    an env would tell)."""
    import gymnasium
    from gymnasium.envs.registration import load_env_creator

    from drill_env.env import DrillStringEnv

    if not isinstance(env_id, str) or env_id not in gymnasium.registry:
        return False
    entry = gymnasium.registry[env_id].entry_point
    try:
        made = entry if callable(entry) or entry is None else load_env_creator(entry)
    except (ImportError, AttributeError, ValueError, gymnasium.error.Error):  # (gone, or
        # its dependency not installed: Box2D's)
        return False
    # (a factory function of one's own cannot be told without making an env: taken, as
    # the env's own checks judge what it makes; a review)
    return not isinstance(made, type) or issubclass(made, DrillStringEnv)


def check_interface(name: str, controller: Any) -> None:
    """ValueError naming what a controller of your own lacks or gets wrong: the methods
    and attributes of :class:`agents.base.Controller`, a ``rate``, an ``env_id`` that is
    registered, ``physics()`` a dict of overrides that the default config takes, a table
    name (:func:`table_name`) that can name files and is not a built-in controller's."""
    missing = [a for a in ("name", "rate", "env_id", "physics", "reset", "act")
               if not hasattr(controller, a)]
    if missing:
        raise ValueError(f"controller: {name} is not a controller: it has no "
                         f"{', '.join(missing)} (agents.base.Controller; subclass "
                         "agents.SetPointController)")
    if controller.rate not in ("drive", "policy"):
        raise ValueError(f"controller: {name}: rate is {controller.rate!r}, not "
                         "'drive' or 'policy'")
    import gymnasium

    if not is_drill_env(controller.env_id):  # (another registered env, CartPole-v1: a
        # pool's traceback from its constructor, or "env_class:", typed by nobody)
        drill = ", ".join(k for k in gymnasium.registry if k.startswith("Drill"))
        known = "is not a drill-env env" if controller.env_id in gymnasium.registry else \
            "is not a registered env"
        raise ValueError(f"controller: {name}: env_id {controller.env_id!r} {known}; the "
                         f"drill-env ones: {drill}")
    try:
        physics = controller.physics()
    except USER_ERRORS as err:  # the user's code: said in one line
        raise ValueError(f"controller: {name}: physics() raised {in_user_code(err)}"
                         ) from None
    if not isinstance(physics, Mapping):
        raise ValueError(f"controller: {name}: physics() returned "
                         f"{type(physics).__name__}, not a dict of config overrides "
                         "({} for none)")
    from drill_env.physics.config import SimulationConfig
    from drill_env.physics.validation import replace

    try:  # a misspelt key reads as the controller's, not as the user's --config
        replace(SimulationConfig(), **physics)
    except (ValueError, TypeError) as err:
        raise ValueError(f"controller: {name}: physics() returned {err}") from None
    from drill_env.physics.config import flatten

    # its top drive only: the string, rock, well and bit are the scenario's, the same for
    # every controller (one that softened the rock was listed as curing stick-slip at
    # twice the ROP, "every controller from the same start and targets")
    keys = flatten(dict(physics))
    other = sorted(key for key in keys if not key.startswith("top_drive."))
    if other:
        raise ValueError(f"controller: {name}: physics() sets {', '.join(other)}: a "
                         "controller sets its top drive only (top_drive.*); the string, "
                         "rock (formation.*), well, mud and bit are the scenario's, the same "
                         "for every controller")
    # nor the drive itself: a controller that gave itself a 50 kg m^2 rotor and a 500 kN m
    # rating was listed beside the others without a word (a controls engineer's check)
    hardware = sorted(key for key in keys
                      if key.removeprefix("top_drive.") not in TOP_DRIVE_LOOP)
    if hardware:
        raise ValueError(f"controller: {name}: physics() sets {', '.join(hardware)}: the "
                         "top drive's hardware (rotor inertia, torque rating, acceleration "
                         "limit) is the same for every controller; a controller sets its "
                         "loop (controller, gains, tuning, torque feedback); to drill with "
                         "another drive, give it to all with --config")
    data_files(name, controller)
    if getattr(type(controller), "data_files", ()) != getattr(controller, "data_files", ()):
        raise ValueError(f"controller: {name}: data_files is set on the instance; set it on "
                         "the class (the benchmark reads it before it makes the controller, "
                         "to tell whether its stored rows are current)")
    own = table_name(name)  # the class's own name, else the attribute after the colon
    if not _TABLE_NAME.fullmatch(own):
        raise ValueError(f"controller: {name}: name {own!r} cannot name its rows and "
                         "files: letters, digits and _ . + - (set the class's name "
                         "attribute)")
    if own.casefold() in {c.casefold() for c in CONTROLLERS} or \
            own.casefold().startswith(("constant-", "learned-")) or \
            HeldAction.from_label(own.casefold()) is not None:
        raise ValueError(f"controller: {name}: name {own!r} is a built-in controller's "
                         "(set the class's name attribute to your own)")


def parse_controllers(text: str) -> list[str]:
    """``"stiff,z-torque"`` -> the names, each checked (table names of constant set
    points as :func:`canonical` gives them)."""
    try:
        names = [canonical(n) for n in comma_items(text, "controllers")]
    except ValueError as err:
        raise ValueError(f"controllers: {str(err).partition(': ')[2]}") from None
    if not names:
        raise ValueError("controllers: give at least one name")
    for n in names:
        if n.startswith(("constant:", "held:")):
            try:  # checks the numbers
                (ConstantSetPoints if n.startswith("constant:") else HeldAction).parse(
                    n.partition(":")[2])
            except ValueError as err:
                raise ValueError(f"controllers: {str(err).partition(': ')[2]}") from None
        elif n.startswith("learned:"):
            from agents.learned import policy_files

            try:  # a missing folder or model, said before any episode runs
                policy_files(n.partition(":")[2])
            except (FileNotFoundError, ValueError) as err:
                raise ValueError(f"controllers: {err}") from None
        elif is_imported(n):
            try:  # importable and a controller, said before any episode runs
                make_controller(n)
            except ValueError as err:
                raise ValueError(f"controllers: {str(err).partition(': ')[2]}") from None
        elif n not in CONTROLLERS:
            raise ValueError(f"controllers: unknown name {n!r}"
                             f"{did_you_mean(n, list(CONTROLLERS))}; known: {KNOWN}")
    return names
