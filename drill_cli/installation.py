"""What the installation looks like to a command: the sibling packages a user's module can
shadow, the shipped hyperparameters, and the note said while numba compiles."""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

#: drill-env's packages beside drill_cli: top-level names (the repository's layout, SPEC
#: section 1) that a user's own module of that name can shadow.
SIBLING_PACKAGES = ("agents", "training")


def package_spec(name: str) -> Any:
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
    spec = package_spec("training")
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
        spec = package_spec(name)
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
