"""The FE string in a curved hole (config ``well``) against the soft-string model and
closed forms: the string climbs the wall to the friction angle when it rotates, lies on
the high side of a build under tension, and a vertical survey changes nothing."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from helpers import build_section, pipe_friction, rotate_off_bottom, straight_hole

from drill_env.physics.config import replace
from drill_env.physics.layout import P
from drill_env.physics.simulator import OperatingPoint, Simulator
from drill_env.physics.trajectory import DOWN, Trajectory, soft_string
from drill_env.physics.units import RPM
from drill_env.scenarios import make_scenario
from drill_env.well import column_for


def test_a_vertical_survey_gives_the_vertical_model_bit_for_bit():
    config = make_scenario("default").config
    length = config.string.length
    vertical = replace(config, **{"well.md": (0.0, 500.0, length + 50.0),
                                  "well.inclination": (0.0, 0.0, 0.0),
                                  "well.azimuth": (0.0, 40.0, 80.0)})
    records = []
    for c in (config, vertical):
        sim = Simulator(c)
        sim.reset(OperatingPoint(100 * RPM, 100e3))
        sim.vt[-1] *= 0.98
        records.append(sim.run(3.0, record_every=10))
    np.testing.assert_array_equal(records[0], records[1])


def test_in_a_straight_60_degree_hole_the_rotating_string_climbs_to_the_friction_angle():
    """Soft string: F_n = w L sin 60 at every node, torque mu r sum F_n. The FE string
    rotating on the low side climbs the wall until friction balances its weight, so the
    wall carries sum F_n / sqrt(1 + mu^2); its torque lies between that and the soft
    string's (the stiff BHA spreads its load onto the stabilizers' larger radius)."""
    config, survey = straight_hole(60.0)
    length = config.string.length
    mu = pipe_friction(config)
    torque, sim = rotate_off_bottom(config)
    column = column_for(config, length)
    soft = soft_string(Trajectory(survey), column, length, mu)
    np.testing.assert_allclose(soft.normal_force,
                               column.buoyed_weight * column.length * math.sin(math.pi / 3),
                               rtol=1e-12)
    climbed = 1.0 / math.sqrt(1.0 + mu * mu)
    assert np.sum(sim.node_force) == pytest.approx(np.sum(soft.normal_force) * climbed,
                                                   rel=0.02)
    ratio = torque / soft.surface_torque
    assert climbed - 0.03 < ratio < 1.03, (ratio, climbed)


def test_in_a_build_the_fe_and_soft_string_torques_agree_and_tension_lifts_the_string():
    """A shallow build (3 deg/30 m from 100 m to 30 deg) with ~1 km of string below it:
    the tension turning with the hole (T k > w sin i) holds the string on the high side
    of the build; below, in the hold, it lies on the low side. The FE rotating torque
    equals the soft string's within 5 % after the friction-angle correction, and the
    hook carries w x TVD."""
    config, survey = build_section()
    length = config.string.length
    mu = pipe_friction(config)
    torque, sim = rotate_off_bottom(config)
    well = Trajectory(survey)
    soft = soft_string(well, column_for(config, length), length, mu)
    assert torque * math.sqrt(1.0 + mu * mu) / soft.surface_torque == pytest.approx(1.0,
                                                                                 abs=0.05)
    # both carry the bit's weight along the hole at the bit (w cos i, in the hold at 30
    # deg; the soft string's column spreads it over its lowest element)
    assert sim.string_weight == pytest.approx(soft.hook_load, rel=1e-9)
    node_md = sim.mesh.node_depth[1:]  # the top node is pinned
    t, e1, e2 = well.frames(node_md)
    across = DOWN[None, :] - t[:, 2:3] * t
    high = -across / np.maximum(np.linalg.norm(across, axis=1), 1e-12)[:, None]
    offset = sim.lat_planes[0][:, 2::2]  # lateral displacement of nodes 1.. (plane, node)
    toward_high = (offset[0] * np.sum(high * e1, axis=1)
                   + offset[1] * np.sum(high * e2, axis=1)) / sim.node_clearance[1:]
    in_build = (node_md > 150.0) & (node_md < 380.0)
    in_hold = (node_md > 600.0) & (node_md < 1100.0)
    assert in_build.sum() > 10 and np.all(toward_high[in_build] > 0.9)
    assert np.all(toward_high[in_hold] < -0.9)


def test_a_compression_pushes_the_string_to_the_outside_of_a_build():
    """The WOB's share of the static side load in a build: a compression C along a hole
    of curvature k pushes each length L of string outward, to the low side of a build,
    with C k L (the tension's turning load of the soft-string model, Johancsik et al.
    1984, reversed). The build of :func:`build_section` is an arc of 3 deg per 30 m in a
    vertical plane: the change of the simulator's lumped static loads between two WOBs
    must be that load, node by node, wherever a node's two elements lie in the arc."""
    config, survey = build_section()
    sim = Simulator(config)
    wob = 80e3
    loads = []
    for w in (0.0, wob):
        sim.reset(OperatingPoint(60 * RPM, w))
        loads.append(sim.static_load[:, 0::2].copy())
    change = loads[1] - loads[0]  # (plane, node from lateral_start)
    node_md = sim.mesh.node_depth[sim.lateral_start:]
    t, e1, e2 = Trajectory(survey).frames(node_md)
    pushed = change[0][:, None] * e1 + change[1][:, None] * e2
    across = DOWN[None, :] - t[:, 2:3] * t
    low = across / np.maximum(np.linalg.norm(across, axis=1), 1e-12)[:, None]
    above, below = np.diff(node_md, prepend=node_md[0]), np.diff(node_md, append=node_md[-1])
    in_arc = (node_md - above >= 100.0) & (node_md + below <= 400.0)  # kick-off to 30 deg
    assert in_arc.sum() > 20
    expected = wob * math.radians(3.0) / 30.0 * 0.5 * (above + below)[in_arc]
    toward_low = np.sum(pushed * low, axis=1)[in_arc]
    np.testing.assert_allclose(toward_low, expected, rtol=1e-9)
    sideways = pushed[in_arc] - toward_low[:, None] * low[in_arc]
    assert np.max(np.linalg.norm(sideways, axis=1)) < 1e-9 * np.max(expected)
    # where the hole is straight (the vertical top, the hold) the WOB adds no side load
    straight = (node_md + below < 100.0) | (node_md - above > 400.0)
    assert np.max(np.abs(change[:, straight])) < 1e-9 * np.max(expected)


def test_a_survey_that_ends_above_the_string_is_refused_by_name():
    from drill_env.physics.config import ConfigError

    config = make_scenario("default").config
    with pytest.raises(ConfigError, match=r"well\.md"):
        replace(config, **{"well.md": (0.0, 300.0), "well.inclination": (0.0, 30.0),
                           "well.azimuth": (0.0, 0.0)})


def test_soft_string_friction_acts_exactly_where_the_string_has_no_lateral_dofs():
    """Full level: every node below the top has lateral DOFs and the FE contacts carry
    the friction. Fast level: the straight pipe and the pinned BHA top node. Torsion
    only: every node between the top drive and the bit. Vertical: none."""
    config = make_scenario("lateral_60").config
    full = Simulator(config)
    fast = Simulator(replace(config, **{"solver.fidelity": "fast"}))
    torsion = Simulator(replace(config, **{"solver.lateral": False}))
    vertical = Simulator(replace(make_scenario("default").config, **{"solver.lateral": False}))
    assert not full.soft_nodes.any() and full.params[P.SOFT_STRING] == 0.0
    assert np.flatnonzero(fast.soft_nodes).tolist() == list(range(1, fast.lateral_start + 1))
    assert np.flatnonzero(torsion.soft_nodes).tolist() == list(range(1, torsion.n_nodes - 1))
    assert not vertical.soft_nodes.any() and vertical.params[P.SOFT_STRING] == 0.0


def test_the_mesh_check_uses_the_axial_force_along_the_curved_hole():
    """Less of the string's weight acts along a 60-degree hole, so a smaller WOB brings
    an element to its limit than in the vertical hole, and the check says so."""
    vertical = Simulator(make_scenario("default").config)
    deviated = Simulator(make_scenario("lateral_60").config)
    assert deviated.resolved_weight_on_bit < 0.9 * vertical.resolved_weight_on_bit
    with pytest.raises(ValueError, match="buckling load"):
        deviated.check_mesh_resolves(1.01 * deviated.resolved_weight_on_bit)
    vertical.check_mesh_resolves(1.01 * deviated.resolved_weight_on_bit)


def test_a_curved_holes_loads_follow_the_wob_down_as_well_as_up():
    """Simulator.prepare: a change of hook load moves a curved hole's static loads with
    the WOB ("the curved hole's loads follow the WOB"), a lower WOB as a higher one: the
    soft string's normal forces are then those a reset at the new WOB gives (the same
    formula on the same WOB, to round-off)."""
    scenario = make_scenario("j_shaped")
    config = replace(scenario.config, **{"solver.fidelity": "fast"})
    sim, fresh = Simulator(config), Simulator(config)
    soft = sim.soft_nodes
    sim.reset(OperatingPoint(60 * RPM, 0.5 * scenario.weight_on_bit))
    forces = []
    for wob in (scenario.weight_on_bit, 0.25 * scenario.weight_on_bit):
        assert sim.prepare(1, hook_load=sim.hook_load_for(wob))
        fresh.reset(OperatingPoint(60 * RPM, wob))
        forces.append(fresh.contact_forces[soft])
        np.testing.assert_allclose(sim.contact_forces[soft], forces[-1], rtol=1e-12)
    assert np.max(np.abs(forces[0] - forces[1])) > 100.0  # the WOB moves them (N)


def test_the_neutral_point_of_a_deviated_well_is_where_the_simulators_force_turns():
    """The statics summed the weight along the measured depth, as in a vertical hole:
    in the 60-degree well it put the neutral point 87 m above the bit, where the
    simulator's own axial force (w x TVD) is compressive up to ~250 m."""
    scenario = make_scenario("lateral_60")
    sim = Simulator(scenario.config)
    force = sim.axial_weight - scenario.weight_on_bit
    height = sim.mesh.node_depth[-1] - 0.5 * (sim.mesh.node_depth[:-1]
                                              + sim.mesh.node_depth[1:])
    top = int(np.flatnonzero(force < 0.0)[0])  # the highest compressed midpoint
    assert height[top] <= scenario.neutral_point <= height[top - 1]
    vertical = make_scenario("default")
    assert scenario.neutral_point > 2.5 * vertical.neutral_point


def test_pipe_on_the_low_side_of_an_inclined_hole_buckles_at_the_dawson_paslay_load():
    """In a straight 60-degree hole the weight holds the pipe on the low side: it
    buckles at 2 sqrt(E I w sin i / r) (Dawson & Paslay 1984), ~18x the vertical-hole
    load the check used, so a WOB a vertical hole refuses is a safe start here."""
    from drill_env.physics.statics import pipe_buckling

    config, _ = straight_hole(60.0)
    wob = 600e3  # enough to compress the drill pipe in the inclined hole
    found = pipe_buckling(config, wob)
    pipe = config.string.drill_pipe
    w = (pipe.density - config.mud.density) * pipe.area * 9.81
    clearance = 0.5 * (config.string.hole_diameter - pipe.outer_diameter)
    expected = 2.0 * math.sqrt(pipe.youngs_modulus * pipe.second_moment * w
                               * math.sin(math.radians(60.0)) / clearance)
    buckled = {b.component: b for b in found}
    assert buckled[pipe.label].buckling_load == pytest.approx(expected, rel=1e-9)
    assert 120e3 < expected < 160e3  # 5 in pipe, 8 3/4 in hole
    assert pipe_buckling(make_scenario("lateral_60", weight_on_bit=0.0).config, 150e3) == []

    def vertical_load(section) -> float:  # Lubinski (1950): 1.94 (E I w^2)^(1/3)
        w = (section.density - config.mud.density) * section.area * 9.81
        return 1.94 * (section.youngs_modulus * section.second_moment * w * w) ** (1 / 3)

    default = make_scenario("default").config.string
    (hwdp,) = [c for c in default.components if c.label == "5 in HWDP"]
    with pytest.raises(ValueError, match=f"HWDP by .* buckling load "
                                         f"{vertical_load(hwdp) / 1e3:.1f} kN"):
        make_scenario("default", weight_on_bit=150e3)
    make_scenario("lateral_60", weight_on_bit=150e3)  # refused before, as if vertical
    # below 2 degrees the vertical load stands: Dawson-Paslay's passed it at 0.5 degree
    limit = {}
    for inclination in (0.5, 1.5, 2.5, 5.0, 15.0):
        tilted, _ = straight_hole(inclination)
        limit[inclination] = {b.component: b.buckling_load
                              for b in pipe_buckling(tilted, 600e3)}[pipe.label]
    assert limit[0.5] == limit[1.5] == pytest.approx(vertical_load(pipe), rel=1e-9)
    for inclination in (2.5, 5.0, 15.0):  # (was the vertical load up to 10 degrees)
        assert limit[inclination] == pytest.approx(2.0 * math.sqrt(
            pipe.youngs_modulus * pipe.second_moment * w
            * math.sin(math.radians(inclination)) / clearance), rel=1e-9)
    # at 250 kN the pipe buckles where the hole is still near vertical: the compression
    # named is that element's (~40-56 kN against 7.6 kN), not the 151 kN at 60 degrees,
    # which the pipe carries there
    (top,) = pipe_buckling(make_scenario("lateral_60", weight_on_bit=0.0).config, 250e3)
    assert top.buckling_load == pytest.approx(vertical_load(pipe), rel=1e-9)
    assert 30e3 < top.compression < 60e3


def _low_side_spread(inclination: float, share: float) -> float:
    """The FE string (the paper's: 1000 m of 5 in drill pipe on a 35 m BHA) in a straight
    hole at ``inclination`` (deg), its drill pipe compressed to ``share`` of Dawson &
    Paslay's load: :func:`_spread_compressed`."""
    from drill_env.physics.config import SimulationConfig
    from drill_env.physics.trajectory import Survey
    from drill_env.well import with_survey

    base = SimulationConfig()
    config = with_survey(base, Survey.from_stations(
        [0.0, base.string.length + 100.0], [inclination] * 2, [0.0, 0.0]))
    pipe = config.string.drill_pipe
    w = (pipe.density - config.mud.density) * pipe.area * 9.81
    clearance = 0.5 * (config.string.hole_diameter - pipe.outer_diameter)
    load = 2.0 * math.sqrt(pipe.youngs_modulus * pipe.second_moment * w
                           * math.sin(math.radians(inclination)) / clearance)
    return _spread_compressed(config, share * load)


def _spread_compressed(config, compression: float) -> float:
    """The FE string of ``config`` turning at 60 rpm with its drill pipe's lowest element
    compressed by ``compression`` (N) and kicked sideways (2 cm/s per node, seeded): the
    spread (deg) of its lowest 40 pipe nodes around the hole after 20 s. On the low side
    it stays a few degrees; buckled, the pipe winds around the hole."""
    from drill_env.physics.fem import build_mesh
    from drill_env.physics.statics import axial_force_and_inclination

    mesh = build_mesh(config)
    force, _ = axial_force_and_inclination(config, mesh, 0.0)
    in_pipe = np.nonzero(mesh.component == 0)[0]
    sim = Simulator(config)
    sim.reset(OperatingPoint(60 * RPM, compression + float(force[in_pipe[-1]])))
    sim.vl[0::2] += np.random.default_rng(0).normal(0.0, 0.02, sim.vl[0::2].shape)
    sim.run(20.0)
    assert sim.status == 0
    z = sim.ul[0::2, 0] + 1j * sim.ul[0::2, 1]
    lowest = z[in_pipe[-40:]]
    return float(np.ptp(np.degrees(np.angle(lowest * np.conj(np.mean(lowest))))))


def test_the_fe_pipe_holds_the_low_side_below_the_dawson_paslay_load_from_1_degree():
    """Dawson & Paslay's load is what the buckling check takes from 2 degrees on (it took
    the vertical-hole load, 6x lower at 5 degrees, up to 10): the FE string, an
    independent model of the same pipe (beam elements, wall contact, gravity across the
    hole), holds its pipe on the low side at 0.8 of that load at 1, 2 and 5 degrees, and
    at 5 degrees buckles at 1.6 of it. (At low inclination the load is a lower bound: the
    compression falls up the hole over a few buckle wavelengths; 1.25 of it buckles at 5
    degrees but not yet at 1-2.)"""
    for inclination in (1.0, 2.0, 5.0):
        assert _low_side_spread(inclination, 0.8) < 10.0, inclination
    assert _low_side_spread(5.0, 1.6) > 60.0


@pytest.mark.parametrize("rate", [1.5, 2.0])  # deg / 30 m
def test_a_builds_curvature_holds_the_pipe_down_to_the_load_the_fe_string_buckles_at(rate):
    """Compression F in a hole that builds at k rad/m presses the pipe onto the low side
    with F k per metre on top of its weight's w sin(i): the check's load is the root of
    F^2 = 4 E I (w sin(i) + F k) / r (Dawson & Paslay's with that load), 1.4-1.5x the
    straight hole's here (a hole building from 3 degrees at the surface: 53 and 70 at the
    pipe's foot). The screen refuses just past it, and the FE string (5 m pipe elements,
    so that they resolve these loads) holds its pipe on the low side at 0.9 of it and
    winds it around the hole at 1.5. (The FE string takes the curvature as the same side
    load F k, hole_loads: this checks the stability argument under it, and that leaving
    the build out, or doubling its share, would misjudge what the simulator carries.)"""
    from drill_env.physics.config import SimulationConfig, replace
    from drill_env.physics.fem import build_mesh
    from drill_env.physics.statics import axial_force_and_inclination, pipe_buckling
    from drill_env.physics.trajectory import Survey
    from drill_env.well import with_survey

    base = replace(SimulationConfig(), **{"string.drill_pipe.element_length": 5.0})
    k = math.radians(rate / 30.0)
    end = base.string.length + 100.0
    config = with_survey(base, Survey.from_stations(
        [0.0, end], [3.0, 3.0 + math.degrees(k * end)], [0.0, 0.0]))
    pipe = config.string.drill_pipe
    w = (pipe.density - config.mud.density) * pipe.area * 9.81
    ei = pipe.youngs_modulus * pipe.second_moment
    r = 0.5 * (config.string.hole_diameter - pipe.outer_diameter)
    mesh = build_mesh(config)
    force, inclination = axial_force_and_inclination(config, mesh, 0.0)
    foot = np.nonzero(mesh.component == 0)[0][-1]  # the pipe's most compressed element
    held = w * math.sin(inclination[foot])
    critical = 2 * ei * k / r + math.sqrt((2 * ei * k / r) ** 2 + 4 * ei * held / r)
    straight = 2.0 * math.sqrt(ei * held / r)
    assert critical > 1.3 * straight

    def refused(share: float) -> list:
        return pipe_buckling(config, share * critical + float(force[foot]))

    assert refused(0.999) == []
    (past,) = refused(1.001)
    assert past.compression == pytest.approx(1.001 * critical, rel=1e-9)
    assert past.buckling_load == pytest.approx(2.0 * math.sqrt(
        ei * (held + past.compression * k) / r), rel=1e-6)
    assert _spread_compressed(config, 0.9 * critical) < 20.0
    assert _spread_compressed(config, 1.5 * critical) > 60.0


def test_where_the_hole_drops_its_compression_lifts_the_pipe_off_the_low_side():
    """Compression F along a hole that drops at k rad/m pushes the pipe toward the high
    side with F k per metre, against the weight across the hole that holds it down in
    Dawson & Paslay's load: the load is taken with w sin(i) - F k, and where F k outweighs
    the weight the vertical-hole load stands alone. A sharp drop (60 to 20 degrees over
    100 m) at a high compression lifts the HWDP; in the same hole building (20 to 60),
    where the build presses it down, it comes nearest to buckling below the build, at
    their load for the straight 60 degrees."""
    from drill_env.physics.statics import pipe_buckling
    from drill_env.physics.trajectory import Survey
    from drill_env.well import with_survey

    config = make_scenario("default").config
    end = config.string.length + 100.0
    (hwdp,) = [c for c in config.string.components if c.label == "5 in HWDP"]
    w = (hwdp.density - config.mud.density) * hwdp.area * 9.81
    ei = hwdp.youngs_modulus * hwdp.second_moment
    clearance = 0.5 * (config.string.hole_diameter - hwdp.outer_diameter)
    vertical = 1.94 * (ei * w * w) ** (1 / 3)
    length = config.string.length
    limits = {}
    for name, (top, bottom) in (("drop", (60.0, 20.0)), ("build", (20.0, 60.0))):
        holed = with_survey(config, Survey.from_stations(
            [0.0, length - 150.0, length - 50.0, end], [top, top, bottom, bottom], [0.0] * 4))
        limits[name] = {b.component: b for b in pipe_buckling(holed, 900e3)}["5 in HWDP"]
    assert limits["drop"].buckling_load == pytest.approx(vertical, rel=1e-9)
    build = limits["build"]
    assert build.buckling_load == pytest.approx(2.0 * math.sqrt(
        ei * w * math.sin(build.inclination) / clearance), rel=1e-9)
    assert build.buckling_load > 3.0 * vertical
    # the refusal says why the drop's limit is the vertical one (an outside check read
    # "in a near-vertical hole" at 13.5 degrees)
    assert limits["drop"].lifted and not build.lifted
    assert limits["drop"].place.endswith("where the hole drops and the compression lifts "
                                         "the pipe off the low side")


def test_the_straight_pipe_warning_uses_the_axial_force_along_the_curved_hole():
    """The fast level holds the pipe straight, valid while it is in tension. In the
    60-degree hole less weight acts along the string, so 150 kN on the bit compresses
    pipe the vertical hole would still hold in tension; the warning must say so."""
    config = replace(make_scenario("lateral_60").config, solver={"fidelity": "fast"})
    sim = Simulator(config)
    assert np.min(sim.axial_weight[: sim.lateral_start]) < 150e3  # compressed along the hole
    vertical = Simulator(replace(make_scenario("default").config, solver={"fidelity": "fast"}))
    assert np.min(vertical.axial_weight[: vertical.lateral_start]) > 150e3  # not vertically
    with pytest.warns(RuntimeWarning, match="compression"):
        sim.reset(OperatingPoint(60 * RPM, 150e3))
    with warnings.catch_warnings(record=True) as again:  # "once per simulator"
        warnings.simplefilter("always")
        sim.reset(OperatingPoint(60 * RPM, 150e3))
    assert not [w for w in again if "compression" in str(w.message)]


def test_formation_dip_is_true_and_turned_into_the_bits_frame():
    """A bed dipping 60 deg toward south is perpendicular to a hole inclined 60 deg
    toward north, so the bit meets it flat; a horizontal bed meets that bit at 60 deg.
    The plane still crosses the hole axis at its measured depth. Interfaces along the
    hole are refused by name. The bit's inclination is reported."""
    from drill_env.physics.config import ConfigError, FormationConfig, Interface, RockConfig

    config, _ = straight_hole(60.0)
    depth = config.string.length + 0.5

    def planes(*interfaces):
        formation = FormationConfig(rocks=(RockConfig(), RockConfig(name="soft")),
                                    interfaces=interfaces, layers=(0, 1, 0)[:len(interfaces) + 1])
        sim = Simulator(replace(config, formation=formation))
        return sim, sim.formation.normals, sim.formation.offsets

    sim, normals, offsets = planes(Interface(depth, 60.0, 180.0), Interface(depth + 1.0, 0.0))
    np.testing.assert_allclose(normals[0], [0.0, 0.0, 1.0], atol=1e-12)
    assert normals[1][2] == pytest.approx(0.5, rel=1e-12)  # cos 60
    np.testing.assert_allclose(offsets, normals[:, 2] * [depth, depth + 1.0], rtol=1e-12)
    assert sim.bit_inclination == pytest.approx(math.radians(60.0), rel=1e-12)
    with pytest.raises(ConfigError, match=r"formation\.interfaces\[0\]"):
        planes(Interface(depth, 30.0, 0.0))  # dips 30 deg north: along a 60-deg hole
    vertical = Simulator(replace(make_scenario("default").config, formation=FormationConfig(
        rocks=(RockConfig(), RockConfig(name="soft")), interfaces=(Interface(depth, 60.0, 180.0),),
        layers=(0, 1))))
    assert vertical.formation.normals[0][2] == pytest.approx(0.5, rel=1e-12)
    assert vertical.bit_inclination == 0.0


@pytest.mark.parametrize(("dip", "azimuth"), [(60.0, 180.0), (0.0, 0.0), (75.0, 0.0),
                                              (40.0, 90.0), (20.0, 250.0)])
def test_the_layer_a_point_near_the_bit_lies_in_follows_the_true_plane(dip, azimuth):
    """World geometry against the bit's frame: a point at local (x, y, z) near the bit
    lies at Q + x e1 + y e2 + (z - depth) t in north-east-down coordinates, with Q where
    the plane crosses the hole axis. The kernel's layer (``layer_at`` on the transformed
    plane) must say the hole has crossed the interface exactly where the point lies on
    the far side of the true plane from the part of the hole before the crossing. For a
    bed dipping 75 deg north the 60-degree hole drills up-section (the plane's normal
    points back up the hole): its second layer lies geologically above the plane, as
    ``layers`` are listed in the order the hole meets them."""
    from drill_env.physics.config import FormationConfig, Interface, RockConfig
    from drill_env.physics.formation import interface_plane, layer_at

    config, _ = straight_hole(60.0)
    depth = config.string.length + 0.3
    sim = Simulator(replace(config, formation=FormationConfig(
        rocks=(RockConfig(), RockConfig(name="soft")), interfaces=(Interface(depth, dip,
                                                                             azimuth),),
        layers=(0, 1))))
    frame = sim.hole.bit_frame  # rows e1, e2, t
    normal, _ = interface_plane(0.0, dip, azimuth)  # true normal, north-east-down
    before = np.sign(normal @ (-frame[2]))  # side of the hole before the crossing
    rng = np.random.default_rng(7)
    for x, y, dz in rng.uniform([-0.2, -0.2, -0.6], [0.2, 0.2, 0.6], (200, 3)):
        world = x * frame[0] + y * frame[1] + dz * frame[2]  # relative to Q
        side = np.sign(normal @ world)
        expected = 0 if side == before else 1
        assert layer_at(x, y, depth + dz, sim.formation.normals, sim.formation.offsets) \
            == expected, (x, y, dz)
    if dip == 75.0:
        assert before > 0  # drilling up-section: the layer met second is above the bed


def test_a_wob_past_the_strings_hanging_weight_is_warned_of():
    """In a curved hole the string's hanging weight is its buoyed weight by true vertical
    depth: a WOB above it leaves a negative hook load, the top drive pushing the string
    down, which the simulator carries and a rig cannot (an outside check of the buckling
    screen found -50 to -480 kN in builds from the surface). Warned of at the start; the
    hanging weight checked against its closed form, w x TVD summed over the elements, the
    arc's TVD (sin i2 - sin i1) / k, and the bit's weight along the hole at the bit."""
    import warnings

    from drill_env.physics.config import SimulationConfig, replace
    from drill_env.physics.fem import build_mesh
    from drill_env.physics.statics import bit_buoyed_weight
    from drill_env.physics.trajectory import Survey
    from drill_env.well import with_survey

    base = replace(SimulationConfig(), **{"string.drill_pipe.element_length": 5.0})
    k = math.radians(2.0 / 30.0)
    end = base.string.length + 100.0
    config = with_survey(base, Survey.from_stations(
        [0.0, end], [3.0, 3.0 + math.degrees(k * end)], [0.0, 0.0]))
    sim = Simulator(config)
    mesh = build_mesh(config)
    md = mesh.node_depth  # the bit at the string's length: measured depth from the top
    i = np.radians(3.0) + k * md  # a constant build: inclination linear in md
    tvd = np.sin(np.radians(3.0) + k * md) / k - math.sin(math.radians(3.0)) / k
    weight = float(np.sum(mesh.buoyed_weight * mesh.element_length * np.diff(tvd)
                          / np.diff(md))) + bit_buoyed_weight(config) * math.cos(i[-1])
    assert sim.string_weight == pytest.approx(weight, rel=1e-9)
    assert np.degrees(i[-1]) > 60.0  # most of the weight lies along the hole, not down it
    for wob, warned in ((0.95 * sim.string_weight, False), (1.05 * sim.string_weight, True)):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            sim.reset(OperatingPoint(60 * RPM, wob))
        pushes = [w for w in caught if "hook load is negative" in str(w.message)]
        assert bool(pushes) == warned, wob
