"""Well paths (minimum curvature, parallel-transport frames) and the soft-string
torque-and-drag model, against closed forms."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from drill_env.physics.trajectory import (
    StringColumn,
    Survey,
    Trajectory,
    soft_string,
)

R_3DEG = 30.0 / math.radians(3.0)  # radius of a 3 deg / 30 m build: 572.958 m


def test_a_quarter_circle_build_has_the_closed_form_tvd_and_departure():
    """0 -> 90 deg at 3 deg/30 m in one course: a quarter circle of radius 572.958 m;
    every point on it, not only the end station, lies on the circle."""
    length = 90.0 / 3.0 * 30.0
    well = Trajectory(Survey.from_stations([0.0, length], [0.0, 90.0], [0.0, 0.0]))
    assert R_3DEG == pytest.approx(572.958, abs=1e-3)
    md = np.linspace(0.0, length, 37)
    pos, tan, curvature = well.at(md)
    angle = md / R_3DEG
    np.testing.assert_allclose(pos[:, 2], R_3DEG * np.sin(angle), rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(pos[:, 0], R_3DEG * (1.0 - np.cos(angle)), rtol=1e-9,
                               atol=1e-9)
    np.testing.assert_allclose(pos[:, 1], 0.0, atol=1e-9)
    assert pos[-1, 2] == pytest.approx(R_3DEG, rel=1e-9)  # TVD
    assert math.hypot(pos[-1, 0], pos[-1, 1]) == pytest.approx(R_3DEG, rel=1e-9)
    np.testing.assert_allclose(np.linalg.norm(tan, axis=1), 1.0, rtol=1e-12)
    np.testing.assert_allclose(curvature, 1.0 / R_3DEG, rtol=1e-12)
    np.testing.assert_allclose(well.inclination(md), angle, atol=1e-9)


def test_stations_along_the_arc_give_the_same_hole():
    """The same arc surveyed every 30 m is the same hole (minimum curvature is exact on
    a circle)."""
    md = np.arange(0.0, 901.0, 30.0)
    fine = Trajectory(Survey.from_stations(md, md / 10.0, np.zeros_like(md)))
    coarse = Trajectory(Survey.from_stations([0.0, 900.0], [0.0, 90.0], [0.0, 0.0]))
    probe = np.linspace(0.0, 900.0, 101)
    np.testing.assert_allclose(fine.at(probe)[0], coarse.at(probe)[0], atol=1e-9)


def test_frames_are_orthonormal_and_do_not_twist_on_a_planar_well():
    survey = Survey.profile(3000.0, kickoff=500.0, build_rate=3.0, hold_inclination=50.0,
                            azimuth=30.0, drop_start=2000.0, drop_rate=2.0,
                            final_inclination=20.0)
    well = Trajectory(survey)
    md = np.linspace(0.0, 3000.0, 601)
    t, e1, e2 = well.frames(md)
    for a, b in ((t, e1), (t, e2), (e1, e2)):
        np.testing.assert_allclose(np.sum(a * b, axis=1), 0.0, atol=1e-12)
    for v in (t, e1, e2):
        np.testing.assert_allclose(np.linalg.norm(v, axis=1), 1.0, rtol=1e-12)
    # planar (azimuth 30 deg): every bend turns the frame about the plane's normal only,
    # so the frame's components along that normal never change (a twist would turn them)
    normal = np.array([-math.sin(math.radians(30.0)), math.cos(math.radians(30.0)), 0.0])
    for v in (e1, e2):
        np.testing.assert_allclose(v @ normal, (v @ normal)[0], atol=1e-12)
    assert abs(e1[0] @ normal) > 0.1  # e1 starts north, out of the plane: not trivial
    # the module's rule: at a vertical top e1 points north
    np.testing.assert_allclose(e1[0], [1.0, 0.0, 0.0], atol=1e-12)


def test_frames_turn_about_no_axis_along_the_hole_on_a_curved_3d_well():
    """Parallel transport: between two close points e1 changes only along t (no
    rotation about the tangent), to second order in the step."""
    md = np.linspace(0.0, 2000.0, 21)
    survey = Survey.from_stations(md, np.linspace(0.0, 70.0, 21), np.linspace(0.0, 120.0, 21))
    well = Trajectory(survey)
    probe = np.linspace(10.0, 1990.0, 4001)
    t, e1, e2 = well.frames(probe)
    step = probe[1] - probe[0]
    twist = np.abs(np.sum((e1[1:] - e1[:-1]) * e2[:-1], axis=1)) / step  # rad/m
    curvature = np.max(well.at(probe)[2])
    assert np.max(twist) < 0.05 * curvature  # a twisting frame would reach ~curvature


def column(length: float, weight: float = 300.0, radius: float = 0.08, dx: float = 10.0):
    n = round(length / dx)
    return StringColumn(np.full(n, length / n), np.full(n, weight), np.full(n, radius))


@pytest.mark.parametrize("seed", range(4))
def test_the_off_bottom_hook_load_of_a_uniform_string_is_its_weight_times_tvd(seed):
    rng = np.random.default_rng(seed)
    md = np.concatenate([[0.0], np.cumsum(rng.uniform(50.0, 300.0, 12))])
    inc = np.clip(np.cumsum(rng.uniform(-5.0, 15.0, md.size)), 0.0, 95.0)
    inc[0] = 0.0
    azi = np.cumsum(rng.uniform(-20.0, 20.0, md.size))
    well = Trajectory(Survey.from_stations(md, inc, azi))
    bit = float(md[-1])
    tvd = well.at(bit)[0][0, 2]
    for friction in (0.0, 0.3):  # rotating: the friction is all tangential
        result = soft_string(well, column(bit, 300.0), bit, friction, "rotating")
        assert result.hook_load == pytest.approx(300.0 * tvd, rel=1e-12)


@pytest.mark.parametrize("mu", [0.25, 2.0])  # 2: the wall friction's top (docs/config.md)
def test_a_straight_60_degree_hole_has_the_soft_string_normal_forces_and_torque(mu):
    length = 2000.0
    well = Trajectory(Survey.from_stations([0.0, length], [60.0, 60.0], [45.0, 45.0]))
    col = column(length, weight=250.0, radius=0.09, dx=20.0)
    result = soft_string(well, col, length, mu, "rotating")
    np.testing.assert_allclose(result.normal_force,
                               250.0 * col.length * math.sin(math.radians(60.0)),
                               rtol=1e-12)
    assert result.surface_torque == pytest.approx(
        mu * 0.09 * 250.0 * length * math.sin(math.radians(60.0)), rel=1e-12)
    # sliding: the drag is mu F_n per element, on top of the weight's axial part
    axial = 250.0 * length * math.cos(math.radians(60.0))
    drag = mu * 250.0 * length * math.sin(math.radians(60.0))
    assert soft_string(well, col, length, mu, "pick_up").hook_load == \
        pytest.approx(axial + drag, rel=1e-12)
    assert soft_string(well, col, length, mu, "slack_off").hook_load == \
        pytest.approx(axial - drag, rel=1e-12)


def test_tension_in_a_build_lifts_the_string_off_the_low_side_and_in_a_drop_pushes_it():
    """Under tension T the contact force per length in a bend of curvature k at
    inclination i is |T k - w sin i| in a build (the tension pulls toward the high side,
    the weight toward the low) and T k + w sin i in a drop."""
    w, tension, inc = 200.0, 300e3, 45.0
    build = Trajectory(Survey.from_stations([0.0, 100.0], [inc - 0.5, inc + 0.5], [0, 0]))
    drop = Trajectory(Survey.from_stations([0.0, 100.0], [inc + 0.5, inc - 0.5], [0, 0]))
    curvature = math.radians(1.0) / 100.0
    col = column(100.0, w, dx=1.0)
    for well, sign in ((build, -1.0), (drop, 1.0)):
        result = soft_string(well, col, 100.0, 0.0, "rotating", weight_on_bit=-tension)
        middle = 0.5 * (result.md[:-1] + result.md[1:])
        sin_i = np.sin(well.inclination(middle))
        expected = np.abs(result.tension[:-1] * curvature + sign * w * sin_i)
        np.testing.assert_allclose(result.normal_force / col.length, expected, rtol=1e-3)
    build_force = soft_string(build, col, 100.0, 0.0, weight_on_bit=-tension).normal_force
    drop_force = soft_string(drop, col, 100.0, 0.0, weight_on_bit=-tension).normal_force
    assert np.all(drop_force > build_force)


def test_pick_up_is_heavier_than_rotating_and_slack_off_lighter_in_a_deviated_well():
    well = Trajectory(Survey.profile(3000.0, kickoff=300.0, build_rate=4.0,
                                     hold_inclination=60.0))
    col = column(3000.0)
    loads = {m: soft_string(well, col, 3000.0, 0.3, m).hook_load
             for m in ("pick_up", "rotating", "slack_off")}
    assert loads["pick_up"] > loads["rotating"] > loads["slack_off"]


def test_bad_surveys_name_the_field():
    with pytest.raises(ValueError, match=r"^survey\.md: station 2: must increase: 90 m "
                                         r"after 100 m$"):
        Survey.from_stations([0.0, 100.0, 90.0], [0, 1, 2], [0, 0, 0])
    with pytest.raises(ValueError, match=r"survey\.md: station 2"):  # a station given twice
        Survey.from_stations([0.0, 100.0, 100.0], [0, 1, 2], [0, 0, 0])
    with pytest.raises(ValueError, match=r"^survey\.md: station 0: must start at 0, got 5 m$"):
        Survey.from_stations([5.0, 100.0], [0, 1], [0, 0])
    with pytest.raises(ValueError, match=r"survey\.inclination"):
        Survey.from_stations([0.0, 100.0], [0.0, float("nan")], [0, 0])
    with pytest.raises(ValueError, match=r"survey\.inclination"):
        Survey.from_stations([0.0, 100.0], [0.0, 190.0], [0, 0])
    with pytest.raises(ValueError, match=r"survey\.total_md"):
        Survey.profile(600.0, kickoff=500.0, hold_inclination=30.0)
    with pytest.raises(ValueError, match="friction"):
        soft_string(Trajectory(Survey.profile(100.0)), column(100.0), 100.0, -0.1)
    with pytest.raises(ValueError, match="bit_md"):
        soft_string(Trajectory(Survey.profile(100.0)), column(50.0), 100.0, 0.2)
    for outside in (-1.0, 101.0):  # no hole above the wellhead or below the last station
        with pytest.raises(ValueError, match=r"^md: within 0-100 m"):
            Trajectory(Survey.profile(100.0)).at(outside)


def test_a_survey_reads_from_csv(tmp_path):
    path = tmp_path / "survey.csv"
    path.write_text("md,inclination,azimuth\n0,0,0\n300,0,0\n900,60,45\n")
    survey = Survey.from_csv(path)
    np.testing.assert_allclose(survey.inclination, np.radians([0, 0, 60]))
    path.write_text("md,incl\n0,0\n")
    with pytest.raises(ValueError, match="missing column"):
        Survey.from_csv(path)
    # what the header held, for units in the names or another separator; an empty file
    path.write_text("MD (m)|Inc (deg)|Azi (deg)\n0|0|0\n")
    with pytest.raises(ValueError, match=re.escape(
            "its header is ['MD (m)|Inc (deg)|Azi (deg)'] (separated by commas, tabs or "
            "semicolons, named md")):
        Survey.from_csv(path)
    path.write_text("")
    with pytest.raises(ValueError, match="missing column.*; the file is empty"):
        Survey.from_csv(path)
    path.write_text("md,inclination,azimuth\n")  # a header alone: no stations
    with pytest.raises(ValueError, match="at least two stations"):
        Survey.from_csv(path)
    # Excel's "CSV UTF-8" (a byte-order mark, CRLF) and names in another case or spaced
    # out: the BOM was an invisible '\ufeffmd' in the refusal (an outside check)
    for header in ("\ufeffmd,inclination,azimuth", "MD, Inclination ,Azimuth"):
        path.write_bytes(f"{header}\r\n0,0,0\r\n300,0,0\r\n900,60,45\r\n".encode())
        np.testing.assert_allclose(Survey.from_csv(path).inclination, np.radians([0, 0, 60]))


@pytest.mark.parametrize(("body", "said"), [
    ("0,0,0\n300,0,0\n900,abc,45\n", "line 4, column inclination: 'abc' is not a number"),
    ("0,0,0\n300,0\n", "line 3, column azimuth: missing"),
    ("0,0,0\n,0,0\n", "line 3, column md: '' is not a number"),
])
def test_a_bad_survey_csv_names_the_line_and_column(tmp_path, body, said):
    """The line as an editor numbers it (the header is line 1) and the column's name,
    for a value that is not a number and for a row too short to have one."""
    path = tmp_path / "survey.csv"
    path.write_text("md,inclination,azimuth\n" + body)
    with pytest.raises(ValueError) as err:
        Survey.from_csv(path)
    assert str(err.value) == f"survey {path}, {said}"


def test_a_weightless_string_pulled_round_a_bend_obeys_the_capstan_equation():
    """Euler-Eytelwein: a rope sliding round an arc of angle theta under friction mu
    changes its tension by exp(+-mu theta); rotating (no axial friction) the tension stays
    and the torque is mu r T theta. A 90 deg arc of 1000 m radius, 1000 elements, 100 kN
    at the bit: the per-element sums converge to the exponential as (theta / n)^2."""
    radius, mu, tension, r = 1000.0, 0.3, 100e3, 0.08
    length = radius * math.pi / 2
    well = Trajectory(Survey.from_stations([0.0, length], [0.0, 90.0], [0.0, 0.0]))
    col = column(length, weight=0.0, radius=r, dx=length / 1000)
    theta = math.pi / 2
    for mode, expected in (("pick_up", math.exp(mu * theta)),
                           ("slack_off", math.exp(-mu * theta))):
        result = soft_string(well, col, length, mu, mode, weight_on_bit=-tension)
        assert result.hook_load / tension == pytest.approx(expected, rel=5e-4), mode
    rotating = soft_string(well, col, length, mu, "rotating", weight_on_bit=-tension)
    assert rotating.hook_load == pytest.approx(tension, rel=1e-12)
    assert rotating.surface_torque == pytest.approx(mu * r * tension * theta, rel=1e-6)


# --------------------------------------------------------------------------- by hand


def _slant(md: float = 1000.0, inclination: float = 60.0) -> Trajectory:
    """A straight hole at ``inclination`` (deg) from the surface."""
    return Trajectory(Survey.from_stations([0.0, md], [inclination] * 2, [0.0, 0.0]))


def test_the_first_frame_points_to_the_high_side_of_an_inclined_hole() -> None:
    """A 30 deg slant from the surface: the high-side vector e1 has the upward component
    -sin 30 deg (z down), whatever the azimuth."""
    _, e1, _ = Trajectory(Survey.from_stations([0, 100], [30, 30], [45, 45])).frames(
        [0.0, 50.0])
    np.testing.assert_allclose(e1[:, 2], -math.sin(math.radians(30.0)), rtol=1e-12)


def test_a_profile_places_its_stations_where_the_rates_put_them() -> None:
    """Build 3 deg/30 m from 300 m to 30 deg: 300 m of build; hold to 750 m; drop at
    2 deg/30 m to vertical: 450 m; then vertical to 2000 m."""
    survey = Survey.profile(2000.0, kickoff=300.0, build_rate=3.0, hold_inclination=30.0,
                            drop_start=750.0, drop_rate=2.0, final_inclination=0.0)
    np.testing.assert_allclose(survey.md, [0, 300, 600, 750, 1200, 2000])


def test_the_curvature_of_a_later_course_is_its_dogleg_over_its_own_length() -> None:
    well = Trajectory(Survey.profile(3000.0, kickoff=300.0, build_rate=3.0,
                                     hold_inclination=60.0))
    assert well.at(500.0)[2][0] == pytest.approx(math.radians(3.0) / 30.0, rel=1e-9)


def test_a_survey_that_turns_back_on_itself_is_refused() -> None:
    with pytest.raises(ValueError, match="back on"):
        Survey.from_stations([0, 100], [0, 180], [0, 0])


def test_a_hole_that_climbs_above_the_wellhead_is_refused() -> None:
    """A fuzzing walkthrough: inclinations of 179 deg charted a TVD of -699 m and hook
    loads below zero. Closed form: a quarter circle from vertical to horizontal over
    100 m descends its radius, 200/pi m; one from horizontal to straight up over 200 m
    climbs 400/pi m; the hole ends 200/pi = 63.66 m above the wellhead."""
    with pytest.raises(ValueError, match=r"^survey\.inclination: station 2: the hole is "
                                         r"63\.66 m above the wellhead"):
        Survey.from_stations([0.0, 100.0, 300.0], [0.0, 90.0, 180.0], [0.0, 0.0, 0.0])
    # a fish-hook well past 90 deg that stays below the surface is a well
    ok = Trajectory(Survey.from_stations([0.0, 100.0, 150.0], [0.0, 90.0, 120.0], [0.0] * 3))
    assert ok.at([150.0])[0][0, 2] == pytest.approx(200.0 / math.pi - 50.0 / (math.pi / 6) *
                                                  (1.0 - math.cos(math.pi / 6)), rel=1e-9)


def test_an_azimuth_beyond_a_turn_is_refused() -> None:
    """1e300 degrees passed (finite), its sine round-off (a fuzzing walkthrough)."""
    with pytest.raises(ValueError, match=r"survey.azimuth: station 1: degrees in \[-360, 360\]"):
        Survey.from_stations([0, 100, 200], [0, 30, 30], [0, 1e300, 1e300])
    Survey.from_stations([0, 100, 200], [0, 30, 30], [-90, 350, 359])  # every bearing


def test_the_bit_weight_pushes_the_last_node_against_the_low_side() -> None:
    """A weightless string with a 1 kN bit in a 60 deg hole: the bit node's lateral load
    is the bit weight's component across the hole, 1 kN sin 60 deg."""
    from drill_env.physics.trajectory import hole_loads

    loads = hole_loads(_slant(), np.array([0.0, 10.0, 20.0]), np.zeros(2), 1000.0)
    assert math.hypot(*loads.load_weight[:, -1]) == pytest.approx(
        1000.0 * math.sin(math.radians(60.0)), rel=1e-12)


def test_the_axial_force_at_an_element_midpoint_is_the_weight_below_it_along_the_hole(
        ) -> None:
    """A straight 60 deg hole, elements of unequal length and weight and a 2 kN bit: the
    tension at each element's middle is cos 60 deg times the weight of everything below
    that middle (half the element, the elements below, the bit). Taken at the element's
    lower end instead, the curved-hole force lost half an element's weight everywhere
    and no test saw it (a mutation test: vertical holes take another path)."""
    from drill_env.physics.trajectory import hole_loads

    node_md = np.array([0.0, 12.0, 30.0, 37.0, 52.0])
    weight = np.array([300.0, 150.0, 900.0, 450.0])  # N/m
    bit = 2000.0
    loads = hole_loads(_slant(), node_md, weight, bit)
    middle = 0.5 * (node_md[:-1] + node_md[1:])
    below = [bit + sum(w * max(0.0, min(b, node_md[-1]) - max(a, m))
                       for a, b, w in zip(node_md[:-1], node_md[1:], weight, strict=True))
             for m in middle]
    np.testing.assert_allclose(loads.axial_weight, 0.5 * np.array(below), rtol=1e-12)


def test_string_above_the_wellhead_hangs_from_the_hook_too() -> None:
    """Nodes at -100, 0, 100, 200 m in a vertical hole, 50 N/m: the hook carries all
    300 m (the 100 m above the surface continue the hole straight up)."""
    from drill_env.physics.trajectory import hole_loads

    well = Trajectory(Survey.from_stations([0, 1000], [0, 0], [0, 0]))
    loads = hole_loads(well, np.array([-100.0, 0.0, 100.0, 200.0]), np.full(3, 50.0), 0.0)
    assert loads.hanging_weight == pytest.approx(50.0 * 300.0, rel=1e-12)


def test_an_element_on_a_bend_is_pressed_by_its_weight_across_the_mean_tangent() -> None:
    """One 100 m element on a 0 -> 90 deg arc, no WOB, no friction: its normal force is
    w L sin 45 deg, the weight across the tangent at the element's middle."""
    length, w = 100.0, 10.0
    well = Trajectory(Survey.from_stations([0, length], [0, 90], [0, 0]))
    result = soft_string(well, StringColumn(np.array([length]), np.array([w]),
                                            np.array([0.1])), length, 0.0)
    assert result.normal_force[0] == pytest.approx(w * length * math.sin(math.radians(45.0)),
                                                   rel=1e-9)


def test_only_the_string_below_the_surface_lies_on_the_wall() -> None:
    """A 200 m column with the bit at 95 m in a straight 60 deg hole: 95 m of string is in
    the hole, and its summed normal force is w 95 m sin 60 deg."""
    n, w = 20, 200.0
    column = StringColumn(np.full(n, 10.0), np.full(n, w), np.full(n, 0.06))
    result = soft_string(_slant(), column, 95.0, 0.0)
    assert result.normal_force.sum() == pytest.approx(w * 95.0 * math.sin(math.radians(60.0)),
                                                      rel=1e-9)


def test_a_string_that_slides_without_turning_has_no_surface_torque() -> None:
    column = StringColumn(np.full(20, 10.0), np.full(20, 200.0), np.full(20, 0.06))
    for mode in ("pick_up", "slack_off"):
        assert soft_string(_slant(), column, 150.0, 0.3, mode).surface_torque == 0.0
    assert soft_string(_slant(), column, 150.0, 0.3, "rotating").surface_torque > 0.0


@pytest.mark.parametrize(("seed", "scale"), [(0, 1.0), (1, 1.0), (2, 1.0), (3, 1e-3)])
def test_3d_stations_lie_where_the_ratio_factor_formulas_put_them(seed: int,
                                                                 scale: float) -> None:
    """Minimum curvature as the industry computes it (Bourgoyne et al., Applied Drilling
    Engineering, ch. 8; API Bulletin D20), written out independently of the arcs: each
    course's dogleg cos(beta) = cos(I2 - I1) - sin I1 sin I2 (1 - cos(A2 - A1)) and its
    offsets dN, dE, dTVD = dMD / 2 (sum of the two stations' direction cosines) times the
    ratio factor 2 / beta tan(beta / 2). Random 3-D surveys where inclination and azimuth
    both change from station to station (a planar arc would not test the azimuth);
    ``scale`` 1e-3 makes doglegs of ~1e-4 rad: still arcs, not straight lines."""
    rng = np.random.default_rng(seed)
    n = 25
    md = np.concatenate([[0.0], np.cumsum(rng.uniform(10.0, 100.0, n - 1))])
    inc = np.clip(np.cumsum(rng.uniform(-8.0, 12.0, n) * scale), 0.0, 110.0)
    inc[0] = 0.0
    azi = np.mod(rng.uniform(0.0, 360.0) + np.cumsum(rng.uniform(-25.0, 25.0, n) * scale), 360.0)
    well = Trajectory(Survey.from_stations(md, inc, azi))
    i, a = np.radians(inc), np.radians(azi)
    cos_beta = np.cos(i[1:] - i[:-1]) - np.sin(i[:-1]) * np.sin(i[1:]) * (
        1.0 - np.cos(a[1:] - a[:-1]))
    beta = np.arccos(np.clip(cos_beta, -1.0, 1.0))
    ratio = np.where(beta > 1e-9, 2.0 / np.maximum(beta, 1e-9) * np.tan(beta / 2.0), 1.0)
    half = np.diff(md) / 2.0 * ratio
    north = half * (np.sin(i[:-1]) * np.cos(a[:-1]) + np.sin(i[1:]) * np.cos(a[1:]))
    east = half * (np.sin(i[:-1]) * np.sin(a[:-1]) + np.sin(i[1:]) * np.sin(a[1:]))
    down = half * (np.cos(i[:-1]) + np.cos(i[1:]))
    expected = np.vstack([np.zeros(3), np.cumsum(np.column_stack([north, east, down]),
                                                 axis=0)])
    pos, tangent, curvature = well.at(md)
    # sums of ~25 offsets of <= 100 m: rounding is ~1e-12 m; the dogleg's arccos near
    # beta = 0 loses digits (sqrt of eps), which the ratio factor (1 + beta^2 / 12)
    # turns into ~1e-9 relative at most
    np.testing.assert_allclose(pos, expected, rtol=0.0, atol=1e-7)
    np.testing.assert_allclose(well.survey.doglegs(), beta, atol=1e-7)
    np.testing.assert_allclose(tangent[:, 2], np.cos(i), atol=1e-12)
    leaning = inc > 1.0  # the azimuth of a vertical tangent is not defined
    heading = np.arctan2(tangent[leaning, 1], tangent[leaning, 0])
    np.testing.assert_allclose(np.angle(np.exp(1j * (heading - a[leaning]))), 0.0, atol=1e-9)


def test_a_survey_typed_in_radians_or_bent_past_pipe_limits_warns() -> None:
    """Radians (a build to 75 deg typed 1.309, azimuth 45 deg typed 0.785) ran as a
    near-vertical well without a word; a course of 225 deg/30 m (a typo'd station depth)
    ran with plausible numbers although its bending stress, which the model does not
    load, is past steel's yield. Both warn; the preset profiles (2-4 deg/30 m) do not."""
    import warnings

    from drill_env.well import WELLS

    def said(md, inc, azi) -> list[str]:
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("always")
            Survey.from_stations(md, inc, azi)
        return [str(w.message) for w in seen]

    [radians] = said([0, 300, 800, 1400], [0, 0, 1.309, 1.309], [0.785] * 4)
    assert "typed in radians?" in radians and "1.309 rad = 75 deg" in radians
    [sharp] = said([0, 300, 310, 1400], [0, 0, 75, 75], [45] * 4)
    # 75 deg over 10 m: 225 deg/30 m; E r kappa = 207 GPa x 63.5 mm x 0.131 /m
    assert "stations 1 and 2 bend the hole 225 deg/30 m" in sharp and "1,721 MPa" in sharp
    assert said([0, 300, 800, 1400], [0, 0, 75, 75], [45] * 4) == []
    assert said([0, 500, 1000], [0, 1.0, 2.5], [0, 120, 130]) == []  # degrees, near vertical
    # a near-vertical well drilled a few degrees east of north fits the rule; a survey
    # whose header names its angles' unit is not guessed at (a fuzzing walkthrough)
    assert "typed in radians?" in said([0, 500, 1000], [0, 0.5, 2.0], [0, 3, 6])[0]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        Survey.from_stations([0, 500, 1000], [0, 0.5, 2.0], [0, 3, 6], degrees_said=True)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for profile in WELLS.values():
            profile(3000.0)


def test_an_env_in_a_sharply_bent_well_says_so_once() -> None:
    """The survey's warnings belong to the config that holds it: an env built, reset and
    stepped in a well bent 90 deg/30 m says so once even where every warning is shown
    (simplefilter "always"), not again each time the string is put in the hole (three
    times before)."""
    import warnings

    import gymnasium as gym

    import drill_env  # noqa: F401  (registers the env)

    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        env = gym.make("DrillString-v0", physics={
            "well.md": (0.0, 300.0, 310.0, 2500.0), "well.inclination": (0.0, 0.0, 30.0, 30.0),
            "well.azimuth": (45.0,) * 4})
        env.reset(seed=0)
        env.step(env.action_space.sample())
        env.close()
    bends = [str(w.message) for w in seen if "bend the hole" in str(w.message)]
    assert len(bends) == 1 and "90 deg/30 m" in bends[0]
