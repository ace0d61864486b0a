"""Well paths: surveys, the minimum-curvature method, local frames along the hole.

A survey is a list of stations (measured depth MD, inclination from the vertical,
azimuth from north). Between two stations the minimum-curvature method (Sawaryn &
Thorogood, SPE 84246, 2005) takes the hole as the circular arc that joins the two
tangents: with the dogleg angle beta between the unit tangents t1 and t2 and the course
length dMD, the arc has radius dMD / beta, and

    r(tau) = r1 + (dMD / beta) (sin(tau beta) t1 + (1 - cos(tau beta)) n),  tau in [0, 1]
    n = (t2 - cos(beta) t1) / sin(beta)        (unit normal toward the centre of the arc)

(a straight line where beta = 0). Coordinates are (north, east, down) in metres from the
wellhead; TVD is the down coordinate, the departure the horizontal distance.

The local frame along the hole (t, e1, e2) is carried by parallel transport: from one
point to the next, e1 and e2 are turned by the smallest rotation that takes one tangent
into the next, so the frame does not twist about the hole axis: on a planar well it
turns about the plane's normal only. At a vertical top e1 points north.

:func:`soft_string` is the soft-string torque-and-drag model in its vector form
(Johancsik, Friesen & Dawson, SPE 11380, 1984; Aadnoy et al. 2010): the string lies on
the wall, each element's contact force balances the tension turning with the hole and
the buoyed weight across it, and Coulomb friction on that force adds drag or torque.
"""

from __future__ import annotations

import contextlib
import contextvars
import csv
import math
import re
import warnings
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numba import njit

from drill_env.physics.units import FOOT

DOWN = np.array([0.0, 0.0, 1.0])


def tangent(inclination: np.ndarray | float, azimuth: np.ndarray | float) -> np.ndarray:
    """Unit tangent(s) (north, east, down) of inclination and azimuth (rad)."""
    inc = np.asarray(inclination, dtype=float)
    azi = np.asarray(azimuth, dtype=float)
    return np.stack([np.sin(inc) * np.cos(azi), np.sin(inc) * np.sin(azi), np.cos(inc)],
                    axis=-1)


#: Dogleg severity (deg per 30 m) beyond which a survey warns: rotating drill pipe is
#: kept to a few deg/30 m for fatigue (API RP 7G's dogleg limits) and medium-radius
#: wells build at 8-20 deg/30 m; past it the bending of the hole's curvature, which the
#: model does not load (docs/model.md section 6), dominates the string's stresses
#: (E r kappa: 150 MPa in 5 in pipe at 20 deg/30 m).
MAX_DOGLEG_SEVERITY = 20.0


def _warn_of_radians_or_sharp_bends(md: np.ndarray, inc: np.ndarray, azi: np.ndarray,
                                    dogleg: np.ndarray, guess_radians: bool) -> None:
    """UserWarning for angles that look typed in radians (``guess_radians``: every
    inclination within pi and every azimuth within 2 pi, some of each not zero: a build
    to 75 deg typed as 1.309 ran as a near-vertical well; a well due north has no azimuth
    to tell) and for a course bent beyond :data:`MAX_DOGLEG_SEVERITY` (``dogleg``: each
    course's, rad)."""
    if guess_radians and 0.0 < inc.max() <= math.pi and 0.0 < np.abs(azi).max() <= 2.0 * math.pi:
        warnings.warn(f"survey: every inclination is at most {inc.max():g} deg and every "
                      f"azimuth at most {np.abs(azi).max():g} deg: typed in radians? They "
                      f"are degrees ({inc.max():g} rad = {math.degrees(inc.max()):.0f} deg)",
                      UserWarning, stacklevel=1)  # once per process, wherever from
    severity = np.degrees(dogleg) / np.diff(md) * 30.0
    k = int(np.argmax(severity))
    if severity[k] > MAX_DOGLEG_SEVERITY:
        stress = 2.07e11 * 0.0635 * math.radians(severity[k]) / 30.0 / 1e6  # 5 in steel pipe
        warnings.warn(f"survey: stations {k} and {k + 1} bend the hole {severity[k]:.0f} "
                      f"deg/30 m, beyond {MAX_DOGLEG_SEVERITY:g} deg/30 m (a bending stress "
                      f"of {stress:,.0f} MPa in 5 in pipe): the model does not load that "
                      "bending (docs/model.md section 6)", UserWarning, stacklevel=1)


#: False while a randomised scenario's draws are built (:func:`draws_hang_freely`): a draw
#: above the hole's bend is one of the range's, said for the range's longest string.
_SAY_HANGING = contextvars.ContextVar("say_hanging", default=True)


@contextlib.contextmanager
def draws_hang_freely() -> Iterator[None]:
    """Configs built inside do not warn of a string hanging above its hole's bend
    (:func:`check_survey_holds`); other warnings stand. (``warnings.catch_warnings``
    would reset the once-per-place registry: every reset repeated a survey's warnings.)"""
    token = _SAY_HANGING.set(False)
    try:
        yield
    finally:
        _SAY_HANGING.reset(token)


def check_survey_holds(config) -> None:
    """ValueError naming ``well.md`` where ``config``'s survey ends above the string's
    deepest node (its length or ``initial_depth``); a UserWarning where the hole is
    vertical down to that node and bends only below it, so the string hangs in a vertical
    hole. A survey typed in feet put a 1,000 ft kick-off 1,000 m down, below a 900 m
    string, which then ran as a vertical well without a word; a string still above a
    planned kick-off is as vertical, so a warning."""
    md, deepest = config.well.md, max(config.string.length, config.initial_depth or 0.0)
    if md[-1] < deepest:
        raise ValueError(f"well.md: the survey ends at {md[-1]} m, above the string's "
                         f"deepest node ({deepest} m)")
    inclined = np.flatnonzero(np.abs(np.asarray(config.well.inclination, dtype=float)) > 0.0)
    if not inclined.size or inclined[0] == 0:
        return
    vertical_to = float(md[inclined[0] - 1])  # the first bent course starts there
    if vertical_to >= deepest and _SAY_HANGING.get():
        from drill_env.physics.validation import caller_outside

        warnings.warn(f"well.md: the hole is vertical down to {vertical_to:,.6g} m, at or "
                      f"below the string's deepest node ({deepest:,.6g} m): the string "
                      f"hangs in a vertical hole; md typed in feet? {vertical_to:,.6g} ft "
                      f"= {vertical_to * FOOT:,.6g} m (md is in metres)", UserWarning,
                      stacklevel=caller_outside())


#: The names a survey CSV's column goes by (lower case, spaces and underscores as one
#: space): ours and those survey files and exports commonly use. "depth" alone is not
#: among them: it may be true vertical depth.
SURVEY_COLUMNS = {"md": ("md", "measured depth"),
                  "inclination": ("inclination", "inc", "incl"),
                  "azimuth": ("azimuth", "azi", "azim", "az")}
#: An angle's units, as factors to degrees (inclination and azimuth alike).
_ANGLE_UNITS = {"deg": 1.0, "degree": 1.0, "degrees": 1.0, "\u00b0": 1.0,
                "\u00ba": 1.0,  # the ordinal sign Spanish and Portuguese keyboards type for it
                "rad": 180.0 / math.pi}
#: The units a survey column may name in brackets after its name, as factors to ours
#: (m, degrees): a file in feet or radians says so in its header, and is read as it says.
SURVEY_UNITS = {"md": {"m": 1.0, "meter": 1.0, "meters": 1.0, "metre": 1.0, "metres": 1.0,
                       "ft": FOOT, "feet": FOOT, "usft": 1200.0 / 3937.0,
                       "ftus": 1200.0 / 3937.0},
                "inclination": _ANGLE_UNITS, "azimuth": _ANGLE_UNITS}

#: Words of an azimuth's header that say which north it is from, not a unit: one north
#: throughout a file turns the hole alike (the formations' dip azimuths are the user's).
NORTH_REFERENCES = frozenset({"true", "grid", "mag", "magnetic", "north", "tn", "gn", "mn"})
#: Words of a depth's header that say where it is measured from (rotary or kelly
#: bushing, drill floor, ground, sea level), not a unit: ``MD (m RKB)``. The survey's
#: first station is its zero, whatever the datum.
DEPTH_DATUMS = frozenset({"rkb", "kb", "rt", "df", "gl", "msl", "bdf", "ddf"})


def _survey_column(header: str, path: str) -> tuple[str, float, str]:
    """Our name of a survey CSV's column, the factor of its unit (1 where it names none)
    and the unit as named ('' for none); a column not ours keeps its name. A unit not
    known for the column is a ValueError naming it."""
    text = header.strip().lower()
    found = re.fullmatch(r"(.*?)\s*[(\[]\s*([^)\]]*?)\s*[)\]]", text)
    base, unit = found.groups() if found else (text, "")
    base = " ".join(base.replace("_", " ").split()).rstrip(".")  # "Inc." as "Inc"
    # "US ft", "ft.", "deg true", "m RKB": the unit's words without a north or a datum
    unit = "".join(w for w in unit.replace(".", " ").replace(",", " ").split()
                   if w not in NORTH_REFERENCES | DEPTH_DATUMS)
    for name, aliases in SURVEY_COLUMNS.items():
        words = base.rsplit(" ", 1)  # a unit without brackets: "MD ft"
        if not unit and len(words) == 2 and words[0] in aliases \
                and words[1] in SURVEY_UNITS[name]:
            base, unit = words
        if base in aliases:
            if not unit:
                return name, 1.0, ""
            if unit not in SURVEY_UNITS[name]:
                raise ValueError(f"survey {path}: column {header.strip()!r}: unit {unit!r} "
                                 f"unknown for {name} (one of "
                                 f"{', '.join(SURVEY_UNITS[name])})")
            return name, SURVEY_UNITS[name][unit], unit
    return text, 1.0, ""


class StationError(ValueError):
    """A survey station's value refused: ``station`` (from 0) and ``column`` say which,
    so a CSV's refusal names its line and column (a whole column of 10,000 values was
    printed, and no line: a fuzzing walkthrough)."""

    def __init__(self, column: str, station: int, detail: str) -> None:
        super().__init__(f"survey.{column}: station {station}: {detail}")
        self.column, self.station, self.detail = column, station, detail


def _check_stations(md: np.ndarray, inc: np.ndarray, azi: np.ndarray) -> None:
    """StationError at the first station whose value is refused: not finite, a depth not
    from 0 and increasing or deeper than the longest string, an angle out of its range."""
    from drill_env.physics.config import MAX_STRING_LENGTH

    for name, values in (("md", md), ("inclination", inc), ("azimuth", azi)):
        if not np.all(np.isfinite(values)):
            k = int(np.argmin(np.isfinite(values)))
            raise StationError(name, k, f"must be finite, got {float(values[k])!r}")
    if md[0] != 0.0:
        raise StationError("md", 0, f"must start at 0, got {md[0]:g} m")
    if np.any(np.diff(md) <= 0.0):
        k = int(np.argmax(np.diff(md) <= 0.0)) + 1
        raise StationError("md", k, f"must increase: {md[k]:g} m after {md[k - 1]:g} m")
    if md[-1] > MAX_STRING_LENGTH:  # the longest string: a 1e12 m survey ran out of memory
        k = int(np.argmax(md > MAX_STRING_LENGTH))
        raise StationError("md", k, f"{md[k]:,.10g} m is deeper than {MAX_STRING_LENGTH:,g}"
                                    " m, the longest string a config takes (feet without "
                                    "their unit?)")
    for name, values, low, high in (("inclination", inc, 0.0, 180.0),
                                    ("azimuth", azi, -360.0, 360.0)):
        if np.any(values < low) or np.any(values > high):  # (1e300 deg: a sine of round-off)
            k = int(np.argmax((values < low) | (values > high)))
            raise StationError(name, k, f"degrees in [{low:g}, {high:g}], got {values[k]:g}")


@dataclass(frozen=True)
class Survey:
    """Survey stations: measured depth (m, from 0, increasing), inclination and azimuth
    (rad). Build with :meth:`from_stations` (degrees), :meth:`from_csv` or
    :meth:`profile`, which check their input and name the bad field."""

    md: np.ndarray
    inclination: np.ndarray
    azimuth: np.ndarray

    @classmethod
    def from_stations(cls, md, inclination_deg, azimuth_deg, *, warn: bool = True,
                      degrees_said: bool = False) -> Survey:
        """The survey of the stations (degrees), checked (a refused station is a
        :class:`StationError`); ``warn``: say when the angles look typed in radians or a
        course bends past pipe limits (False where a config's well, which said so when it
        was built, is read again); ``degrees_said``: the angles' unit was stated (a CSV
        header's), so no guess at radians (a near-vertical well was suspected)."""
        md = np.asarray(md, dtype=float)
        inc = np.asarray(inclination_deg, dtype=float)
        azi = np.asarray(azimuth_deg, dtype=float)
        for name, values in (("md", md), ("inclination", inc), ("azimuth", azi)):
            if values.ndim != 1 or values.size < 2:
                raise ValueError(f"survey.{name}: at least two stations, one value each")
        if not md.size == inc.size == azi.size:
            raise ValueError("survey: md, inclination and azimuth need one value per "
                             f"station, got {md.size}, {inc.size}, {azi.size}")
        _check_stations(md, inc, azi)
        survey = cls(md, np.radians(inc), np.radians(azi))
        dogleg = survey.doglegs()
        if np.any(dogleg >= math.pi - 1e-6):
            k = int(np.argmax(dogleg))
            raise ValueError(f"survey: stations {k} and {k + 1} turn the hole back on "
                             "itself (dogleg 180 degrees)")
        # minimum curvature's depths at the stations: a hole above the wellhead is no well
        # (inclinations of 179 deg charted a TVD of -699 m and hook loads below zero)
        half = np.maximum(dogleg / 2.0, 1e-300)
        ratio = np.where(dogleg > 1e-9, np.tan(half) / half, 1.0)
        cos = np.cos(survey.inclination)
        tvd = np.concatenate([[0.0], np.cumsum(np.diff(md) / 2.0 * ratio * (cos[:-1] + cos[1:]))])
        if np.any(tvd < -1e-9 * md[-1]):
            k = int(np.argmax(tvd < -1e-9 * md[-1]))
            raise StationError("inclination", k, f"the hole is {-tvd[k]:,.4g} m above the "
                               "wellhead there (minimum curvature): inclinations past 90 "
                               "deg climb")
        if warn:
            _warn_of_radians_or_sharp_bends(md, inc, azi, dogleg, not degrees_said)
        return survey

    @classmethod
    def from_csv(cls, path: str | Path) -> Survey:
        """A CSV with columns ``md`` (m), ``inclination`` and ``azimuth`` (degrees), named
        in any case with spaces around them, or as survey files name them (``MD``,
        ``Inc``, ``Azi``: :data:`SURVEY_COLUMNS`); a unit in brackets after a name is
        read (``MD (ft)``, ``Inc [deg]``: :data:`SURVEY_UNITS`) and one not known there is
        refused; a name without a unit is in ours. A UTF-8 byte-order mark (Excel's "CSV
        UTF-8") is skipped, a UTF-16 one (Excel's tab-separated "Unicode text") read,
        the header's first separator of comma, tab and semicolon taken, and a file that
        is not UTF-8 is read as Windows' code page 1252 (Excel's plain CSV on Windows: a
        header's degree sign). Blank lines above the header are skipped; a refused value
        names its line and column."""
        import io

        names = tuple(SURVEY_COLUMNS)
        raw = Path(path).read_bytes()
        try:
            text = raw.decode("utf-16" if raw[:2] in (b"\xff\xfe", b"\xfe\xff")
                              else "utf-8-sig")
        except UnicodeDecodeError:
            text = raw.decode("cp1252", errors="replace")
        body = text.lstrip("\r\n\t ")  # (a blank first line was read as the header)
        above = len(text[:len(text) - len(body)].splitlines())
        header = body.partition("\n")[0]
        # tab-separated (Excel's "Unicode text") or semicolons (a decimal comma's Excel)
        separator = next((c for c in ",\t;" if c in header), ",")
        lines: list[int] = []
        with io.StringIO(body, newline="") as f:
            reader = csv.DictReader(f, delimiter=separator)
            found = reader.fieldnames or []
            read = [_survey_column(name, str(path)) for name in found]
            reader.fieldnames = [name for name, _, _ in read]
            scale = {name: factor for name, factor, _ in read if name in names}
            said = {name for name, _, unit in read if unit}
            missing = set(names) - set(reader.fieldnames)
            if missing:  # say what the header held: units in the names, another separator
                held = f"its header is {found}" if found else "the file is empty"
                raise ValueError(f"survey {path}: missing column(s) {sorted(missing)}; "
                                 f"{held} (separated by commas, tabs or semicolons, named "
                                 "md, inclination, azimuth: m and degrees, or with their "
                                 "unit: MD (ft))")
            if twice := [n for n in names if reader.fieldnames.count(n) > 1]:
                raise ValueError(f"survey {path}: two columns are {twice[0]} (its header is "
                                 f"{found}); keep one")
            columns: list[list[float]] = [[], [], []]
            for row in reader:
                lines.append(reader.line_num + above)
                for column, name in zip(columns, names, strict=True):
                    text = row[name]
                    try:  # a minus sign copied from a PDF or a word processor is one
                        column.append(float(text.replace("\u2212", "-")) * scale[name])
                    except (AttributeError, ValueError):  # a short row reads None
                        raise ValueError(
                            f"survey {path}, line {lines[-1]}, column {name}: "
                            + ("missing" if text is None else f"{text!r} is not a number")
                        ) from None
        try:
            return cls.from_stations(*columns,
                                     degrees_said=bool(said & {"inclination", "azimuth"}))
        except StationError as err:  # (its detail in m and deg: a header's unit converted)
            raise ValueError(f"survey {path}, line {lines[err.station]}, column "
                             f"{err.column}: {err.detail}") from None

    @classmethod
    def profile(cls, total_md: float, kickoff: float | None = None,
                build_rate: float = 3.0, hold_inclination: float = 0.0,
                azimuth: float = 0.0, drop_start: float | None = None,
                drop_rate: float = 2.0, final_inclination: float = 0.0) -> Survey:
        """A vertical, J-shaped or S-shaped well: vertical to ``kickoff`` (m), build at
        ``build_rate`` (deg/30 m) to ``hold_inclination`` (deg), hold; with
        ``drop_start`` (m) drop at ``drop_rate`` (deg/30 m) to ``final_inclination``
        and hold to ``total_md``. Stations at every change of curvature."""
        for name, value in (("total_md", total_md), ("build_rate", build_rate),
                            ("drop_rate", drop_rate)):
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"survey.{name}: must be positive, got {value}")
        if kickoff is None or hold_inclination == 0.0:
            return cls.from_stations([0.0, total_md], [0.0, 0.0], [azimuth, azimuth])
        md, inc = [0.0, kickoff], [0.0, 0.0]
        end_build = kickoff + hold_inclination / build_rate * 30.0
        md.append(end_build)
        inc.append(hold_inclination)
        if drop_start is not None:
            if drop_start < end_build:
                raise ValueError(f"survey.drop_start: {drop_start} m lies inside the "
                                 f"build, which ends at {end_build:.1f} m")
            end_drop = drop_start + abs(hold_inclination - final_inclination) / drop_rate * 30
            md += [drop_start, end_drop]
            inc += [hold_inclination, final_inclination]
        if md[-1] >= total_md:
            raise ValueError(f"survey.total_md: {total_md} m ends before the profile's "
                             f"last curve ({md[-1]:.1f} m)")
        md.append(total_md)
        inc.append(inc[-1])
        keep = np.concatenate([[True], np.diff(md) > 0.0])
        return cls.from_stations(np.array(md)[keep], np.array(inc)[keep],
                                 np.full(int(keep.sum()), azimuth))

    def tangents(self) -> np.ndarray:
        return tangent(self.inclination, self.azimuth)

    def doglegs(self) -> np.ndarray:
        """Dogleg angle (rad) of each course between two stations."""
        t = self.tangents()
        cos = np.clip(np.sum(t[1:] * t[:-1], axis=1), -1.0, 1.0)
        # the angle from the cross product is exact for the small angles surveys have
        sin = np.linalg.norm(np.cross(t[:-1], t[1:]), axis=1)
        return np.arctan2(sin, cos)


class Trajectory:
    """The hole of a survey by minimum curvature: positions, tangents, curvature and the
    twist-free frame at any measured depth."""

    def __init__(self, survey: Survey) -> None:
        self.survey = survey
        self._t = survey.tangents()
        self._beta = survey.doglegs()
        course = np.diff(survey.md)
        steps = np.array([self._arc(k, 1.0)[0] for k in range(course.size)])
        self._r = np.vstack([np.zeros(3), np.cumsum(steps, axis=0)])

    @property
    def total_md(self) -> float:
        return float(self.survey.md[-1])

    def _arc(self, k: int, tau: np.ndarray | float
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Offset from station k, unit tangent t and dt/ds (1/m: curvature times the unit
        normal toward the centre) at fraction ``tau`` of course k."""
        tau = np.asarray(tau, dtype=float)[..., None]
        t1, t2 = self._t[k], self._t[k + 1]
        length = self.survey.md[k + 1] - self.survey.md[k]
        beta = self._beta[k]
        if beta < 1e-12:
            along = np.broadcast_to(t1, tau.shape[:-1] + (3,))
            return tau * length * t1, along.copy(), np.zeros_like(along)
        n = (t2 - math.cos(beta) * t1) / math.sin(beta)
        offset = length / beta * (np.sin(tau * beta) * t1 + (1.0 - np.cos(tau * beta)) * n)
        direction = np.cos(tau * beta) * t1 + np.sin(tau * beta) * n
        bend = beta / length * (-np.sin(tau * beta) * t1 + np.cos(tau * beta) * n)
        return offset, direction, bend

    def _locate(self, md: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        md = np.asarray(md, dtype=float)
        if np.any(md < 0.0) or np.any(md > self.total_md * (1.0 + 1e-12)):
            raise ValueError(f"md: within 0-{self.total_md:g} m of the survey")
        k = np.clip(np.searchsorted(self.survey.md, md, side="right") - 1, 0,
                    self._beta.size - 1)
        tau = (md - self.survey.md[k]) / np.diff(self.survey.md)[k]
        return k, tau

    def _evaluate(self, md) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Course index (n,), positions (n, 3), unit tangents (n, 3) and dt/ds (n, 3)."""
        md = np.atleast_1d(np.asarray(md, dtype=float))
        k, tau = self._locate(md)
        pos = np.empty((md.size, 3))
        tan = np.empty((md.size, 3))
        bend = np.empty((md.size, 3))
        for j in np.unique(k):
            sel = k == j
            offset, tan[sel], bend[sel] = self._arc(int(j), tau[sel])
            pos[sel] = self._r[j] + offset
        return k, pos, tan, bend

    def at(self, md) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Positions (n, 3), unit tangents (n, 3) and curvature (1/m, n) at ``md``."""
        k, pos, tan, _ = self._evaluate(md)
        return pos, tan, self._beta[k] / np.diff(self.survey.md)[k]

    def bend(self, md) -> np.ndarray:
        """dt/ds (n, 3) at ``md``: curvature times the unit normal toward the centre."""
        return self._evaluate(md)[3]

    def inclination(self, md) -> np.ndarray:
        _, t, _ = self.at(md)
        return np.arccos(np.clip(t[:, 2], -1.0, 1.0))

    def frames(self, md) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(t, e1, e2) at increasing ``md``, carried by parallel transport from the
        first point (e1 north there if the hole is vertical, else the high side)."""
        md = np.atleast_1d(np.asarray(md, dtype=float))
        if np.any(np.diff(md) <= 0.0):
            raise ValueError("md: must increase")
        _, t, _ = self.at(md)
        first = np.array([1.0, 0.0, 0.0]) if abs(t[0, 2]) > 1.0 - 1e-12 else \
            -(DOWN - t[0, 2] * t[0]) / np.linalg.norm(DOWN - t[0, 2] * t[0])
        e1 = _parallel_transport(t, first)
        e2 = np.cross(t, e1)
        return t, e1, e2


@njit(cache=True)
def _parallel_transport(t, first):
    """Unit normals ``e1[i]`` to the unit tangents ``t[i]``: ``first`` made normal to
    ``t[0]``, then each carried to the next tangent by the smallest rotation that takes
    ``t[i - 1]`` into ``t[i]`` (Rodrigues, about their cross product) and made exactly
    normal again. Sequential, so compiled: a string's frames in microseconds."""
    e1 = np.empty_like(t)
    d = first[0] * t[0, 0] + first[1] * t[0, 1] + first[2] * t[0, 2]
    vx, vy, vz = first[0] - d * t[0, 0], first[1] - d * t[0, 1], first[2] - d * t[0, 2]
    for i in range(t.shape[0]):
        bx, by, bz = t[i, 0], t[i, 1], t[i, 2]
        if i > 0:
            ax, ay, az = t[i - 1, 0], t[i - 1, 1], t[i - 1, 2]
            kx, ky, kz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx  # a x b
            s = math.sqrt(kx * kx + ky * ky + kz * kz)
            if s >= 1e-15:
                c = ax * bx + ay * by + az * bz
                kx, ky, kz = kx / s, ky / s, kz / s
                kv = (kx * vx + ky * vy + kz * vz) * (1.0 - c)
                cx, cy, cz = ky * vz - kz * vy, kz * vx - kx * vz, kx * vy - ky * vx  # k x v
                vx, vy, vz = (vx * c + cx * s + kx * kv, vy * c + cy * s + ky * kv,
                              vz * c + cz * s + kz * kv)
            d = vx * bx + vy * by + vz * bz  # keep it exactly normal to the tangent
            vx, vy, vz = vx - d * bx, vy - d * by, vz - d * bz
        norm = math.sqrt(vx * vx + vy * vy + vz * vz)
        vx, vy, vz = vx / norm, vy / norm, vz / norm
        e1[i, 0], e1[i, 1], e1[i, 2] = vx, vy, vz
    return e1


@dataclass(frozen=True)
class StringColumn:
    """A string for the soft-string model, element by element from the bit up: length
    (m), buoyed weight per length (N/m) and contact radius (m, the tool joint's or the
    stabilizer's)."""

    length: np.ndarray
    buoyed_weight: np.ndarray
    radius: np.ndarray


@dataclass(frozen=True)
class TorqueDrag:
    """Soft-string result along the string, from the bit (index 0) to the surface."""

    md: np.ndarray  # measured depth of each element boundary (m), bit first
    tension: np.ndarray  # axial force (N, tension > 0) at each boundary
    torque: np.ndarray  # torque (N m) at each boundary
    normal_force: np.ndarray  # contact force of each element (N)

    @property
    def hook_load(self) -> float:
        return float(self.tension[-1])

    @property
    def surface_torque(self) -> float:
        return float(self.torque[-1])


#: Axial motion of the string: friction along the string opposes it.
MODES = ("rotating", "pick_up", "slack_off")


def soft_string(trajectory: Trajectory, column: StringColumn, bit_md: float,
                friction: float, mode: str = "rotating", weight_on_bit: float = 0.0,
                torque_on_bit: float = 0.0) -> TorqueDrag:
    """Tension and torque along a string whose bit is at ``bit_md``, walking up from the
    bit. Per element (length L, buoyed weight w, mean tangent t, end tangents t_low and
    t_up, tension T at its lower end):

        F_n = | T (t_low - t_up) + w L (d - (d . t) t) |      (d: down)
        T_up = T + w dz + {0, +mu F_n, -mu F_n}   (rotating, pick-up, slack-off)
        M_up = M + mu F_n r                        (rotating only)

    where dz is the element's exact vertical extent on the minimum-curvature hole, so an
    off-bottom frictionless string hangs w x TVD. In a build the tension pulls the
    string toward the high side against its weight: the sign of build or drop matters.
    Rotating, the friction is all tangential (the soft-string limit). The column is cut
    at the surface when the bit is shallower than the column is long. Buckling is not
    modelled."""
    if mode not in MODES:
        raise ValueError(f"mode: one of {MODES}, got {mode!r}")
    if not (math.isfinite(friction) and 0.0 <= friction <= 2.0):
        raise ValueError(f"friction: a factor in [0, 2], got {friction}")
    if not (0.0 < bit_md <= trajectory.total_md * (1.0 + 1e-12)):
        raise ValueError(f"bit_md: within (0, {trajectory.total_md:g}] m, got {bit_md}")
    lengths = np.cumsum(column.length)
    if lengths[-1] < bit_md * (1.0 - 1e-12):
        raise ValueError(f"bit_md: {bit_md:g} m is deeper than the string is long "
                         f"({lengths[-1]:g} m)")
    n = min(int(np.searchsorted(lengths, bit_md - 1e-9)) + 1, column.length.size)
    length = column.length[:n].copy()
    length[-1] += bit_md - float(np.sum(length))  # the top element cut at the surface
    bounds = bit_md - np.concatenate([[0.0], np.cumsum(length)])
    bounds[-1] = 0.0
    pos, tan, _ = trajectory.at(bounds)
    tension = np.empty(n + 1)
    torque = np.empty(n + 1)
    normal = np.empty(n)
    tension[0] = -weight_on_bit
    torque[0] = torque_on_bit
    sign = {"rotating": 0.0, "pick_up": 1.0, "slack_off": -1.0}[mode]
    for e in range(n):
        low, up = tan[e], tan[e + 1]
        mean = low + up
        mean /= np.linalg.norm(mean)
        w = column.buoyed_weight[e] * length[e]
        across = tension[e] * (low - up) + w * (DOWN - mean[2] * mean)
        normal[e] = float(np.linalg.norm(across))
        dz = pos[e, 2] - pos[e + 1, 2]
        tension[e + 1] = tension[e] + column.buoyed_weight[e] * dz + \
            sign * friction * normal[e]
        torque[e + 1] = torque[e] + (friction * normal[e] * column.radius[e]
                                     if mode == "rotating" else 0.0)
    return TorqueDrag(bounds, tension, torque, normal)


@dataclass(frozen=True)
class HoleLoads:
    """What a curved hole does to a straight-beam FE string (``Simulator``), per node
    in the hole's twist-free frames (plane 0 along e1, plane 1 along e2)."""

    axial_weight: np.ndarray  # axial force at element midpoints without WOB (N, tension)
    hanging_weight: float     # buoyed weight the hook carries off bottom (N): w x TVD
    load_weight: np.ndarray   # (2, n_nodes) static lateral load at zero WOB (N)
    load_unit: np.ndarray     # (2, n_nodes) its change per newton of WOB (subtracted)
    bit_frame: np.ndarray     # (3, 3) rows e1, e2, t at the bit (north, east, down)


def hole_loads(trajectory: Trajectory, node_md: np.ndarray, element_weight: np.ndarray,
               bit_weight: float) -> HoleLoads:
    """Static loads of a string hanging in a curved hole, lumped at its nodes (node
    measured depths ``node_md``, surface down, increasing; negative above the wellhead,
    where the string continues the hole's first tangent; buoyed weight per length of
    each element). The axial force N follows the true vertical depth; each node of
    lumped length L carries the buoyed weight across the hole, ``w L (d - (d.t) t)``,
    and the tension turning with the hole, ``N L dt/ds`` (toward the inside of the bend;
    a compression pushes outward). In the local frames the beam is straight: in effect
    pre-curved to the hole, so the bending moment ``EI k`` of the hole's curvature, and
    the side-load couples where the curvature changes (kick-off, end of a build), are
    not loaded (docs/model.md section 6)."""
    inside = np.maximum(node_md, 0.0)
    _, pos, tan, bend = trajectory._evaluate(inside)  # bend = dt/ds
    above = np.minimum(node_md, 0.0)
    pos = pos + above[:, None] * tan[0]  # straight on above the wellhead
    unique, index = np.unique(inside, return_inverse=True)
    _, e1, e2 = (f[index] for f in trajectory.frames(unique))
    length = np.diff(node_md)
    dz = np.diff(pos[:, 2])
    w_dz = element_weight * dz
    # at the nodes; of the bit's weight only its part along the hole at the bit (w cos i)
    below = np.concatenate([np.cumsum(w_dz[::-1])[::-1], [0.0]]) + bit_weight * tan[-1, 2]
    axial_weight = below[1:] + 0.5 * w_dz
    lumped_length = 0.5 * (np.concatenate([[0.0], length]) + np.concatenate([length, [0.0]]))
    lumped_weight = 0.5 * (np.concatenate([[0.0], element_weight * length])
                           + np.concatenate([element_weight * length, [0.0]]))
    lumped_weight[-1] += bit_weight  # the bit hangs on the last node
    across = DOWN[None, :] - tan[:, 2:3] * tan  # the weight's part across the hole
    bend = np.where((node_md > 0.0)[:, None], bend, 0.0)  # straight above the wellhead
    gravity = lumped_weight[:, None] * across
    turning = (below * lumped_length)[:, None] * bend
    unit = lumped_length[:, None] * bend
    frame = np.stack([e1, e2])  # (2, n, 3)
    return HoleLoads(axial_weight, float(below[0]),
                     np.einsum("cnk,nk->cn", frame, gravity + turning),
                     np.einsum("cnk,nk->cn", frame, unit),
                     np.stack([e1[-1], e2[-1], tan[-1]]))



def bit_depth(config) -> float:
    """Measured depth of the bit face at t = 0 (m): ``initial_depth``, default the
    string's length."""
    return config.initial_depth if config.initial_depth is not None else config.string.length


def string_in_hole(config, mesh) -> tuple[Trajectory, np.ndarray] | None:
    """``config.well``'s hole and the measured depths of ``mesh``'s nodes in it (the bit
    at ``initial_depth``, default the string's length; < 0 above the wellhead); None for
    a vertical hole."""
    well = config.well
    if well.vertical:
        return None
    depth = bit_depth(config)
    survey = Survey.from_stations(well.md, well.inclination, well.azimuth, warn=False)
    return Trajectory(survey), mesh.node_depth + (depth - mesh.node_depth[-1])


def curved_hole_loads(config, mesh, bit_weight: float) -> HoleLoads | None:
    """:func:`hole_loads` of a simulator's string in ``config.well``'s hole
    (:func:`string_in_hole`); None for a vertical hole, which keeps the vertical model's
    arithmetic exactly."""
    placed = string_in_hole(config, mesh)
    if placed is None:
        return None
    trajectory, node_md = placed
    return hole_loads(trajectory, node_md, mesh.buoyed_weight, bit_weight)
