"""Where numba keeps drill_env's compiled kernels (``drill_env/__init__.py``): this
version's folder, for drill_env's functions only, and a writable one (outside checks: in
a notebook another library's kernels went into drill_env's folders, which the pruning
of old versions removes; with no writable home numba fell back to the sources'
``__pycache__``, keyed file by file, and a kernel compiled before an edit of another file
ran the old physics)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

#: A small cached kernel of drill_env's and one of another library's, compiled in a
#: fresh process; where each was cached, what drill_env warned, and the environment.
PROBE = """
import json, os, sys, warnings
from pathlib import Path
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    import drill_env
import numpy as np
from drill_env.physics.linalg import band_cholesky
sys.path.insert(0, sys.argv[1])
import other_lib
band_cholesky(np.array([[0.0, 0.0], [4.0, 4.0]]), np.zeros((2, 2)))
other_lib.twice(1.0)
cache = drill_env.numba_cache_dir()
print(json.dumps({"cache": str(cache), "ours": sorted(p.name for p in cache.rglob("*.nbi")),
                  "environ": os.environ.get("NUMBA_CACHE_DIR"),
                  "theirs": sorted(p.name for p in Path(sys.argv[1]).rglob("*.nbi")),
                  "warnings": [str(w.message) for w in caught]}))
"""


def _probe(tmp_path: Path, **env: str) -> dict:
    lib = tmp_path / "lib"
    lib.mkdir()
    (lib / "other_lib.py").write_text("from numba import njit\n\n\n@njit(cache=True)\n"
                                      "def twice(x):\n    return 2.0 * x\n")
    environ = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    done = subprocess.run([sys.executable, "-c", PROBE, str(lib)], cwd=tmp_path,
                          env={**environ, **env}, capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]
    return json.loads(done.stdout.splitlines()[-1])


def _source_tree_kernels() -> set[Path]:
    return set((ROOT / "drill_env").rglob("*.nbi"))


def test_drill_envs_kernels_go_to_its_folder_and_no_other_librarys(tmp_path):
    before = _source_tree_kernels()
    found = _probe(tmp_path, XDG_CACHE_HOME=str(tmp_path / "xdg"))
    cache = Path(found["cache"])
    assert cache.parent == tmp_path / "xdg" / "drill_env" / "numba"
    from drill_env.physics.linalg import band_cholesky

    line = band_cholesky.py_func.__code__.co_firstlineno
    assert found["ours"] == [f"linalg.band_cholesky-{line}.py{sys.version_info.major}"
                             f"{sys.version_info.minor}.nbi"]
    # the other library's kernel where numba puts it by itself, beside its source
    assert found["theirs"] == [f"other_lib.twice-4.py{sys.version_info.major}"
                               f"{sys.version_info.minor}.nbi"]
    assert found["environ"] is None  # nothing set for the whole process (or its children)
    assert found["warnings"] == []
    assert _source_tree_kernels() == before


def test_the_cache_key_hashes_every_source_file_and_an_inherited_key_is_kept(tmp_path,
                                                                          monkeypatch):
    """``_numba_cache_dir``'s docstring: the cache is keyed by a hash of every source file
    of the package, so an edit of a subpackage's file (the bit model) starts a fresh
    folder under the base (``NUMBA_CACHE_DIR``), named by 16 hex digits; a base that is
    already this version's folder (inherited from a parent process) is used as it is."""
    import re

    import drill_env

    package = tmp_path / "package"
    (package / "physics").mkdir(parents=True)
    (package / "__init__.py").write_text("")
    bit = package / "physics" / "bit.py"
    bit.write_text("K = 1\n")
    monkeypatch.setattr(drill_env, "__file__", str(package / "__init__.py"))
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "base"))
    before = Path(drill_env._numba_cache_dir())
    bit.write_text("K = 2\n")
    after = Path(drill_env._numba_cache_dir())
    assert before.parent == after.parent == tmp_path / "base"
    assert re.fullmatch("[0-9a-f]{16}", after.name) and after.name != before.name
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(after))
    assert Path(drill_env._numba_cache_dir()) == after


def test_an_unwritable_cache_folder_falls_back_to_the_temporary_folder(tmp_path):
    """No writable home (XDG_CACHE_HOME under a file): the kernels go to this version's
    folder in the temporary folder, said once; none into the sources' __pycache__."""
    blocked = tmp_path / "a-file"
    blocked.write_text("")
    (tmp_path / "tmp").mkdir()
    before = _source_tree_kernels()
    found = _probe(tmp_path, XDG_CACHE_HOME=str(blocked), TMPDIR=str(tmp_path / "tmp"))
    cache = Path(found["cache"])
    assert cache.parent.parent == tmp_path / "tmp"
    assert cache.parent.name.startswith("drill_env-numba-")
    assert len(found["ours"]) == 1
    (warning,) = found["warnings"]
    assert f"numba cannot keep its compiled kernels in {blocked}/drill_env/numba/" in warning
    assert f"they are kept in {cache} instead (set NUMBA_CACHE_DIR" in warning
    assert _source_tree_kernels() == before


def test_with_no_writable_folder_the_locator_says_what_to_set(monkeypatch, tmp_path):
    """Where neither the chosen folder nor a temporary one can be written, numba's next
    locator would use the sources' __pycache__ (stale kernels after an edit): drill_env's
    refuses with what it tried and what to set instead."""
    from numba.core import caching

    import drill_env
    from drill_env.physics import linalg

    blocked = tmp_path / "a-file"
    blocked.write_text("")
    monkeypatch.setattr(drill_env, "_CACHE_DIR", str(blocked / "key"))
    monkeypatch.setattr(drill_env, "_REFUSED", [f"{blocked / 'key'} (Not a directory)"])
    locator = caching.CacheImpl._locator_classes[0]
    assert locator.__name__ == "DrillEnvCacheLocator"
    with pytest.raises(RuntimeError, match=r"no writable folder for numba's compiled "
                                           r"kernels: .*a-file/key \(Not a directory\)\. "
                                           r"Set NUMBA_CACHE_DIR"):
        locator.from_function(linalg.band_cholesky.py_func, linalg.__file__)
    # another library's function: not drill_env's to place
    assert locator.from_function(test_with_no_writable_folder_the_locator_says_what_to_set,
                                 __file__) is None


def test_importing_drill_env_leaves_numba_unloaded_until_its_caching_loads():
    """The locator waits for numba's caching module: installed at `import drill_env`, it
    loaded numba there (ten times the import time) and numba read NUMBA_NUM_THREADS
    before a pool worker's set-up could set it (a review). Installed all the same before
    any kernel of drill_env's asks for a cache."""
    code = ("import sys, drill_env; print('numba' in sys.modules); "
            "from drill_env.physics import linalg; "
            "from numba.core import caching; "
            "print(caching.CacheImpl._locator_classes[0].__name__)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120, check=True)
    assert done.stdout.split() == ["False", "DrillEnvCacheLocator"]


def test_the_temporary_fallback_takes_only_a_private_folder_of_this_users(tmp_path):
    """numba unpickles its index files: a `drill_env-numba-<uid>` folder another user made
    in the shared temporary folder (writable by others, or a link to theirs) would let
    them run code in this process (a review). Such a folder is refused; a new one is
    made for this user only."""
    import stat

    import drill_env

    fresh = tmp_path / "fresh"
    assert drill_env._not_private(fresh) is None
    assert stat.S_IMODE(fresh.stat().st_mode) & 0o077 == 0
    shared = tmp_path / "shared"
    shared.mkdir()
    shared.chmod(0o777)
    assert "writable by others" in drill_env._not_private(shared)
    group = tmp_path / "group"  # writable by the group's other members: others too
    group.mkdir()
    group.chmod(0o775)
    assert "writable by others" in drill_env._not_private(group)
    (tmp_path / "link").symlink_to(fresh)
    assert "not a folder" in drill_env._not_private(tmp_path / "link")
    # in a fresh process: home unwritable and the fallback planted, nothing is used
    blocked = tmp_path / "a-file"
    blocked.write_text("")
    (tmp_path / "tmp" / f"drill_env-numba-{os.getuid()}").mkdir(parents=True)
    (tmp_path / "tmp" / f"drill_env-numba-{os.getuid()}").chmod(0o777)
    code = ("import numpy as np, drill_env\n"
            "from drill_env.physics.linalg import band_cholesky\n"
            "band_cholesky(np.array([[0.0, 0.0], [4.0, 4.0]]), np.zeros((2, 2)))\n")
    environ = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env={**environ, "XDG_CACHE_HOME": str(blocked),
                               "TMPDIR": str(tmp_path / "tmp")}, timeout=120)
    assert done.returncode != 0
    assert "no writable folder for numba's compiled kernels" in done.stderr
    assert "writable by others" in done.stderr


def test_with_no_writable_folder_the_command_line_says_so_in_one_line(tmp_path):
    """Every command, `--help` too, imports kernels: with nowhere to cache them it ended
    in a traceback from that import (a review); it says what to set, and exits 2."""
    blocked = tmp_path / "a-file"
    blocked.write_text("")
    planted = tmp_path / "tmp" / f"drill_env-numba-{os.getuid()}"
    planted.mkdir(parents=True)
    planted.chmod(0o777)
    environ = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    done = subprocess.run([sys.executable, "-m", "drill_cli", "--help"], cwd=ROOT,
                          capture_output=True, text=True, timeout=120,
                          env={**environ, "XDG_CACHE_HOME": str(blocked),
                               "TMPDIR": str(tmp_path / "tmp")})
    assert done.returncode == 2
    assert "Traceback" not in done.stderr
    assert done.stderr.startswith("drill-env: error: no writable folder for numba's")
    assert "Set NUMBA_CACHE_DIR to a folder you can write." in done.stderr
