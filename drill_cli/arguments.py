"""The command line's argument types and checks: numbers in the units people type (rpm, kN,
seconds), folders and files, seed counts and controller names, each refusal said as an
error of the option typed."""

from __future__ import annotations

import argparse
import errno
import math
import os
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

from drill_env.physics.units import KILO, shown


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
    check). An empty one is refused: it read as the current folder ('evaluate ""' scored
    it, '--survey ""' called it a folder; a fuzzing walkthrough)."""
    if not text.strip():
        raise argparse.ArgumentTypeError(f"give a path, got {text!r}")
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


#: A recording's size on the default scenario, per simulated minute and per file (the
#: layout and static data): docs/recording.md, "file size", measured 2026-12-07 with the
#: recorder's defaults (a longer string records more nodes, a shorter one fewer).
RECORDING_MB_PER_MINUTE, RECORDING_MB_PER_FILE = 1.9, 0.6

#: The size from which --record says what it will write before it starts (a 10 h run
#: wrote 1.1 GB unannounced).
LARGE_RECORDING_MB = 1000.0


def recording_note(folder: Path, seconds: float, files: int = 1) -> str:
    """A note of the recordings' size when :data:`LARGE_RECORDING_MB` or more, else "";
    ArgumentTypeError when the disk under ``folder`` has less free than that (the run
    would find it out when the disk filled, hours in)."""
    size = files * (RECORDING_MB_PER_FILE + RECORDING_MB_PER_MINUTE * seconds / 60.0)
    here = folder.absolute()
    while not here.exists() and here != here.parent:
        here = here.parent
    free = shutil.disk_usage(here).free / 1e6

    def said(mb: float) -> str:
        return f"{mb / 1000:.1f} GB" if mb >= 1000 else f"{mb:.0f} MB"

    how = (f"about {said(size)} ({counted(files, 'file')}, ~{RECORDING_MB_PER_MINUTE:g} MB "
           "per simulated minute on the default scenario, docs/recording.md)")
    if size > free:
        raise argparse.ArgumentTypeError(
            f"--record {folder}: the recordings would take {how}, and {here} has "
            f"{said(free)} free; record a shorter --duration or fewer episodes, or give a "
            "folder on a disk with room")
    return f"note: --record: {how}" if size >= LARGE_RECORDING_MB else ""


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


#: ``run --record`` without a folder: the run's ``--out``/recordings, as ``benchmark``.
RECORD_UNDER_OUT = Path("<out>/recordings")

#: ``well --well <preset>`` without ``--total-md`` (m).
DEFAULT_WELL_MD = 3000.0


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
