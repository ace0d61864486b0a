"""drill-env: a Gymnasium environment over a finite-element drill string with a PDC bit.

``import drill_env`` registers the environments (idempotently) and imports nothing heavy:
not torch, Stable-Baselines3 or rerun, and not even gymnasium until the program imports
it. The physics layer (``drill_env.physics``) never needs gymnasium at all, so the
registration runs when gymnasium is (or already was) imported (see
:func:`register_envs`).

=========================  =====================================================
id                         what it is
=========================  =====================================================
``DrillString-v0``         mesoscopic bit, downhole + surface sensors
``DrillStringMacro-v0``    macroscopic bit (eq. 38: torque only, no lateral bit)
``DrillStringSurface-v0``  surface measurements only (``sensors="surface"``)
``DrillStringRandom-v0``   randomised training scenario (``scenario="random"``)
``DrillStickSlip-v0``      task 1: the agent corrects the top drive's speed command
``DrillOptimise-v0``       task 2: the agent is the driller (rpm and WOB)
=========================  =====================================================

All take the keywords of :class:`drill_env.env.DrillStringEnv`;
``gymnasium.make_vec(id, num_envs=N)`` builds :class:`drill_env.vector.DrillStringVectorEnv`.
"""

from __future__ import annotations

import hashlib
import importlib.abc
import importlib.util
import os
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

__version__ = "0.1.0"


def _own_cache_base() -> Path:
    """drill_env's own base of numba caches, ``~/.cache/drill_env/numba``."""
    return Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "drill_env" / "numba"


def _numba_cache_dir() -> str:
    """numba's cache folder for this version of the sources.

    numba invalidates a cached function when ITS file changes, but not when a function it
    calls (from another file) does: a kernel cached before an edit of the bit model would
    run the old bit model. Keying the whole cache by a hash of every source file of the
    package makes an edit start a fresh cache. The base is ``NUMBA_CACHE_DIR`` if set,
    else ``~/.cache/drill_env/numba``.
    """
    root = Path(__file__).resolve().parent
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        digest.update(path.relative_to(root).as_posix().encode())
        digest.update(path.read_bytes())
    key = digest.hexdigest()[:16]
    base = os.environ.get("NUMBA_CACHE_DIR") or str(_own_cache_base())
    if Path(base).name == key:  # inherited from a parent process that set it already
        return base
    return str(Path(base) / key)


#: Old source versions' caches kept besides this one (the most recently used), and how
#: long (s) unused before a cache beyond those is removed: every edit of the sources
#: starts a new ~8.5 MB folder, which would otherwise pile up (hundreds in a week).
CACHES_KEPT, CACHE_UNUSED_FOR = 5, 86400.0
#: The file that marks a folder as one of drill_env's version caches.
CACHE_MARKER = ".drill_env_numba_cache"


def _prune_numba_caches(current: Path, keep: int = CACHES_KEPT,
                        unused_for: float = CACHE_UNUSED_FOR) -> list[Path]:
    """Mark ``current`` (a version's cache folder) as drill_env's and as used now, and
    remove the sibling version caches beyond the ``keep`` most recently used that have
    not been used for ``unused_for`` seconds. A sibling is a version cache if it holds
    :data:`CACHE_MARKER` (anywhere: a ``NUMBA_CACHE_DIR`` may hold other programs'
    folders), or, under drill_env's own base ``~/.cache/drill_env/numba``, if its name is
    16 hex digits (the caches made before the marker). Returns what it removed; never
    raises."""
    import re
    import shutil
    import time

    removed: list[Path] = []
    try:
        current.mkdir(parents=True, exist_ok=True)
        (current / CACHE_MARKER).touch()
        os.utime(current)
        own_base = current.parent == _own_cache_base()
        others = sorted((p for p in current.parent.iterdir()
                         if p != current and p.is_dir() and (
                             (p / CACHE_MARKER).exists()
                             or (own_base and re.fullmatch(r"[0-9a-f]{16}", p.name)))),
                        key=lambda p: p.stat().st_mtime, reverse=True)
        now = time.time()
        for old in others[keep:]:
            if now - old.stat().st_mtime > unused_for:
                shutil.rmtree(old, ignore_errors=True)
                if not old.exists():
                    removed.append(old)
    except OSError:  # a read-only cache: leave it as it is
        pass
    return removed


def _unwritable(folder: Path) -> str | None:
    """Why numba could not keep a cache in ``folder`` (made if missing), or None."""
    import tempfile

    try:
        folder.mkdir(parents=True, exist_ok=True)
        tempfile.TemporaryFile(dir=folder).close()
    except OSError as err:
        return f"{folder} ({err.strerror or err})"
    return None


def _not_private(folder: Path) -> str | None:
    """Why ``folder`` (made if missing, this user's only) is not a folder of this user's
    that no one else may write, or None. Where the platform has no user ids: None."""
    import stat

    if not hasattr(os, "getuid"):
        return None
    try:
        folder.mkdir(mode=0o700, exist_ok=True)
        found = folder.lstat()
    except OSError as err:
        return f"{folder} ({err.strerror or err})"
    if not stat.S_ISDIR(found.st_mode):
        return f"{folder} (not a folder: a link or a file)"
    if found.st_uid != os.getuid() or found.st_mode & 0o022:
        return f"{folder} (another user's, or writable by others)"
    return None


def _usable_cache_dir(wanted: str) -> tuple[str, list[str]]:
    """``wanted`` where numba can write it, else the same version's folder in the
    temporary folder (``drill_env-numba-<uid>/<key>``); and why those it passed over
    could not be used.

    Where the chosen folder could not be written (no home, a read-only one), numba's own
    fallback put the kernels beside the sources, in ``__pycache__``, keyed file by file:
    an edit of the bit model then left a kernel cached before it running the old model
    (an outside check: a run gave the old surface torque), or, with a read-only package
    too, every command failed. If no folder is writable, ``wanted`` is returned and the
    locator says so when numba asks it for a kernel's cache."""
    import tempfile

    refused: list[str] = []
    candidates = [Path(wanted)]
    user = str(os.getuid()) if hasattr(os, "getuid") else "user"
    no_temporary = ""
    try:
        temporary = tempfile.gettempdir()
    except OSError as err:  # no usable temporary folder at all
        no_temporary = f"no temporary folder ({err})"
    else:
        candidates.append(Path(temporary) / f"drill_env-numba-{user}" / Path(wanted).name)
    for k, folder in enumerate(candidates):
        # in the shared temporary folder, only a folder of this user's that no one else
        # may write: numba unpickles its index files, so one planted there would run
        # another user's code in this process (a review)
        reason = _unwritable(folder) if k == 0 else (_not_private(folder.parent)
                                                     or _unwritable(folder))
        if reason is None:
            return str(folder), refused
        refused.append(reason)
    if no_temporary:
        refused.append(no_temporary)
    return wanted, refused


def _install_cache_locator() -> None:
    """Have numba cache drill_env's kernels, and only drill_env's, in :data:`_CACHE_DIR`.

    A cache locator of numba's kind, ahead of numba's own: for a function defined in this
    package's files it names a folder in this version's cache (laid out as numba lays out
    a ``NUMBA_CACHE_DIR``); for any other it declines, so other numba code in the process
    keeps numba's own cache. (``NUMBA_CACHE_DIR`` was set for the whole process before:
    another library's kernels went into drill_env's version folders, and the pruning of
    old versions removed them; an outside check in a notebook.)"""
    from numba.core import caching

    package = os.path.realpath(Path(__file__).resolve().parent) + os.sep

    class DrillEnvCacheLocator(caching.UserProvidedCacheLocator):
        def __init__(self, py_func: Any, py_file: str) -> None:
            super().__init__(py_func, py_file)
            self._cache_path = os.path.join(_CACHE_DIR,
                                            self.get_suitable_cache_subpath(py_file))

        @classmethod
        def from_function(cls, py_func: Any, py_file: str) -> Any:
            if not os.path.exists(py_file) or \
                    not os.path.realpath(py_file).startswith(package):
                return None  # (no source file: a zip or frozen install, numba's own)
            # the source-file locators' own check: the folder can be made and written
            found = super(caching.UserProvidedCacheLocator, cls).from_function(
                py_func, py_file)
            if found is None:  # not numba's next locator: the sources' __pycache__
                raise RuntimeError(
                    "drill_env: no writable folder for numba's compiled kernels: "
                    + "; ".join(_REFUSED or [_CACHE_DIR])
                    + ". Set NUMBA_CACHE_DIR to a folder you can write.")
            return found

    classes = caching.CacheImpl._locator_classes
    classes[:] = [c for c in classes if c.__name__ != "DrillEnvCacheLocator"]
    classes.insert(0, DrillEnvCacheLocator)


_WANTED_CACHE_DIR = _numba_cache_dir()
_CACHE_DIR, _REFUSED = _usable_cache_dir(_WANTED_CACHE_DIR)
if _REFUSED and _CACHE_DIR != _WANTED_CACHE_DIR:
    import warnings

    warnings.warn(f"drill_env: numba cannot keep its compiled kernels in {_REFUSED[0]}; "
                  f"they are kept in {_CACHE_DIR} instead (set NUMBA_CACHE_DIR to choose "
                  "the folder)", RuntimeWarning, stacklevel=2)
_prune_numba_caches(Path(_CACHE_DIR))
# the locator is installed when numba loads its caching module (below, with the import
# hooks): imported here, numba read NUMBA_NUM_THREADS before a pool worker's set-up
# could set it to one, and `import drill_env` took ten times as long


def numba_cache_dir() -> Path:
    """The folder of this version's compiled kernels (``NUMBA_CACHE_DIR`` or
    ``~/.cache/drill_env/numba``, then a key of the sources)."""
    return Path(_CACHE_DIR)


def _load_tbb() -> str | None:
    """Make numba's TBB threading layer loadable; the library's path, or None.

    numba's TBB layer links ``libtbb.so.12``, which the ``tbb`` wheel installs into the
    environment's ``lib/``, where the dynamic loader does not look (conda's layout puts
    it on the path). Loaded here by its path, the layer's own import then finds it, and
    numba's default order (tbb, omp, workqueue) takes it for the batched envs' parallel
    calls: its workers join a call without the ~80 us a sleeping libgomp worker takes
    and, unlike libgomp's spinning ones, give the core back to a competing process (docs/
    performance.md, "TBB"); and numba counts TBB fork-safe, GNU OpenMP not. Nothing
    is done where the user chose a layer without TBB (``NUMBA_THREADING_LAYER``), numba
    started its threads already, or there is no such library (other platforms, no
    ``tbb`` package): numba then picks as it would.
    """
    import ctypes

    choices_with_tbb = ("default", "tbb", "safe", "threadsafe", "forksafe")  # numba's names
    if os.environ.get("NUMBA_THREADING_LAYER", "default") not in choices_with_tbb \
            or sys.platform != "linux":
        return None
    parallel = sys.modules.get("numba.np.ufunc.parallel")
    if parallel is not None and getattr(parallel, "_is_initialized", False):
        return None
    library = Path(sys.prefix) / "lib" / "libtbb.so.12"
    if not library.exists():
        return None
    try:
        ctypes.CDLL(str(library), mode=ctypes.RTLD_GLOBAL)
    except OSError:
        return None
    return str(library)


TBB_LIBRARY = _load_tbb()

# On macOS numba's OpenMP layer can bind the libomp torch loaded before it, and a parallel
# kernel after `import torch` then aborts or crashes (numba#10492; scanpy#4026 shows it on
# Apple silicon), which is what a training run does. There, the batched envs take numba's
# own workqueue layer unless the user chose one.
if sys.platform == "darwin" and "NUMBA_THREADING_LAYER" not in os.environ:
    os.environ["NUMBA_THREADING_LAYER"] = "workqueue"
    if "numba" in sys.modules:  # numba read its settings at its import: read them again
        from numba.core import config as _numba_config

        _numba_config.reload_config()

# OpenMP workers (torch's, and numba's for the batched env) wait for the next parallel
# region while serial Python runs. libgomp's default wait spins, which costs nothing on
# an idle machine and takes the core from everyone else on a shared one: PPO training
# fell from 3,322 to 1,011 env steps/s beside one CPU-bound process, against 2,761 and
# 2,835 with passive waiting (scripts/threading_study.py, docs/performance.md). OpenMP
# reads the variable when it loads (torch: at import), so it is set here, before; a
# user's own choice stands.
if "OMP_WAIT_POLICY" not in os.environ:
    os.environ["OMP_WAIT_POLICY"] = "PASSIVE"
    if "torch" in sys.modules:
        import warnings

        warnings.warn("drill_env was imported after torch, whose OpenMP threads then spin "
                      "while they wait: beside another job training runs 2-3x slower. "
                      "Import drill_env first or export OMP_WAIT_POLICY=PASSIVE before "
                      "Python starts (in a notebook: restart the kernel and import "
                      "drill_env before torch); the variable set now reaches only the "
                      "processes this one starts (docs/performance.md).", RuntimeWarning,
                      stacklevel=2)

ENTRY_POINT = "drill_env.env:DrillStringEnv"
VECTOR_ENTRY_POINT = "drill_env.vector:DrillStringVectorEnv"

#: Registered ids and their default keyword arguments.
ENV_IDS: dict[str, dict[str, Any]] = {
    "DrillString-v0": {},
    "DrillStringMacro-v0": {"bit_model": "macroscopic"},
    "DrillStringSurface-v0": {"sensors": "surface"},
    "DrillStringRandom-v0": {"scenario": "random"},
}
#: The control tasks (SPEC section 7, :mod:`drill_env.tasks`): id -> (env class, batched
#: vector env), as import strings so that registering imports nothing.
TASK_IDS: dict[str, tuple[str, str]] = {
    "DrillStickSlip-v0": ("drill_env.tasks.stick_slip:StickSlipEnv",
                          "drill_env.vector:stick_slip_vector_env"),
    "DrillOptimise-v0": ("drill_env.tasks.drilling:DrillingEnv",
                         "drill_env.vector:drilling_vector_env"),
}


def register_envs() -> None:
    """Register every id of :data:`ENV_IDS` unless already registered (idempotent).

    Imports gymnasium. ``import drill_env`` calls it at once if gymnasium is already
    imported, or else right after the program first imports gymnasium.
    """
    import gymnasium

    # without gymnasium's passive env checker: the envs check their own actions and
    # observations (tests/env/test_env.py runs gymnasium's and SB3's full checkers), and
    # gymnasium 1.4's broke every step of an env whose first reset was refused (a WOB
    # typed in kN: "cannot unpack non-iterable NoneType object" for the env's lifetime)
    for env_id, kwargs in ENV_IDS.items():
        if env_id not in gymnasium.registry:
            gymnasium.register(id=env_id, entry_point=ENTRY_POINT,
                               vector_entry_point=VECTOR_ENTRY_POINT, kwargs=dict(kwargs),
                               disable_env_checker=True)
    for env_id, (entry_point, vector_entry_point) in TASK_IDS.items():
        if env_id not in gymnasium.registry:
            gymnasium.register(id=env_id, entry_point=entry_point,
                               vector_entry_point=vector_entry_point,
                               disable_env_checker=True)


class _RunAfterImport(importlib.abc.MetaPathFinder):
    """Import hook: lets ``module`` load as usual, then runs ``action``, then leaves."""

    def __init__(self, module: str, action: Any) -> None:
        self.module, self.action = module, action

    def find_spec(self, fullname: str, path: Any, target: Any = None) -> Any:
        if fullname != self.module:
            return None
        if self in sys.meta_path:
            sys.meta_path.remove(self)
        spec = importlib.util.find_spec(fullname)
        if spec is None or spec.loader is None:
            return spec
        loader = spec.loader
        load = loader.exec_module

        def exec_module(module: Any) -> None:
            load(module)
            self.action()

        loader.exec_module = exec_module  # type: ignore[method-assign]
        return spec


def _after_import(module: str, action: Any) -> None:
    """``action()`` now if ``module`` is loaded, else right after it loads."""
    if module in sys.modules:
        action()
    elif not any(type(f).__name__ == "_RunAfterImport" and getattr(f, "module", None) == module
                 for f in sys.meta_path):
        sys.meta_path.insert(0, _RunAfterImport(module, action))


_after_import("gymnasium", register_envs)
_after_import("numba.core.caching", _install_cache_locator)


if not TYPE_CHECKING:  # (to mypy, a module-level __getattr__ would make every name of the
    # package exist, a misspelt one too)
    def __getattr__(name: str) -> Any:
        """``drill_env.vector.make_sb3_vec_env(...)`` after a plain ``import drill_env``, as
        the README writes it (a new user's AttributeError): a submodule is imported when a
        program first names it (PEP 562), so ``import drill_env`` stays as light as above."""
        if (name.isidentifier() and not name.startswith("_")
                and importlib.util.find_spec(f"{__name__}.{name}") is not None):
            return importlib.import_module(f"{__name__}.{name}")
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
