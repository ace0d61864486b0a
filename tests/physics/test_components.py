"""Component strings: torsional frequency against the transfer-matrix solution, neutral
point against statics, the legacy two-section config unchanged, realistic defaults."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from reference_solutions import transfer_matrix_frequency

from drill_env.physics import components as cp
from drill_env.physics.config import INCH, Section, SimulationConfig, StringConfig, replace
from drill_env.physics.modes import torsional_modes
from drill_env.physics.simulator import OperatingPoint, Simulator
from drill_env.physics.statics import component_loads, neutral_point_height, pipe_buckling
from drill_env.physics.units import GRAVITY, RPM


def field_well_string() -> StringConfig:
    """Every kind of component once or more: bit sub, stabilizers, MWD, collars, jar,
    heavy-weight pipe, drill pipe (2500 m, a field-like well)."""
    lower = (cp.bit_sub(), cp.stabilizer(name="near-bit"), cp.mwd(), cp.stabilizer(),
             cp.collar_6_5(27.0), cp.stabilizer(), cp.collar_6_5(27.0, 3.0), cp.jar(),
             cp.collar_8(18.0, 3.0), cp.heavy_weight_5(190.0))
    pipe = 2500.0 - sum(c.length for c in lower)
    return StringConfig(drill_pipe=cp.drill_pipe_5_5(pipe), components=lower)


@pytest.mark.parametrize("string", [field_well_string(), cp.realistic_string(),
                                    StringConfig()], ids=["field well", "default", "paper"])
def test_first_torsional_frequency_matches_the_transfer_matrix_solution(string):
    config = SimulationConfig(string=string)
    fe = torsional_modes(replace(config, **{"mud.torsional_damping": 0.0,
                                            "damping.stiffness_proportional": 0.0}),
                         "fixed", 2).frequency[0]
    exact = transfer_matrix_frequency(string.sections, config.bit.inertia, 2.0)
    assert fe == pytest.approx(exact, rel=0.01)
    assert fe == pytest.approx(exact, rel=2e-3)  # in fact much closer


def statics_neutral_point(config: SimulationConfig, wob: float) -> float:
    """Height above the bit where the buoyed weight below balances the WOB."""
    rest = wob - config.bit.mass * GRAVITY * (1 - config.mud.density /
                                              config.string.lower[0].density)
    height = 0.0
    for s in (*config.string.lower, config.string.drill_pipe):
        w = (s.density - config.mud.density) * s.area * GRAVITY
        if rest <= w * s.length:
            return height + rest / w
        rest -= w * s.length
        height += s.length
    return height


@pytest.mark.parametrize("wob", [20e3, 60e3, 100e3, 140e3, 180e3])
def test_neutral_point_matches_statics(wob):
    config = SimulationConfig(string=field_well_string())
    assert neutral_point_height(config, wob) == pytest.approx(
        statics_neutral_point(config, wob), rel=0.01)


def test_component_loads_follow_archimedes_and_the_hook_load():
    """Each component's weight in mud is its weight in air times the buoyancy factor
    1 - rho_mud / rho_steel; the axial force at the top of the string is the hook load
    (buoyed weight of string and bit minus the WOB), and the neutral point lies in the
    component where the axial force changes sign."""
    config = SimulationConfig(string=field_well_string())
    wob = 100e3
    loads = component_loads(config, wob)
    factor = 1.0 - config.mud.density / 7850.0
    for c in loads:
        assert c.buoyed_weight == pytest.approx(c.weight * factor, rel=1e-9)
    total = sum(c.buoyed_weight for c in loads)
    bit = config.bit.mass * GRAVITY * factor
    assert loads[-1].force_top == pytest.approx(total + bit - wob, rel=1e-9)
    # the simulator's hook load for that WOB (fem.buoyed_string_weight: "hook load with
    # the bit off bottom", the bit's weight in mud included)
    assert Simulator(config).hook_load_for(wob) == pytest.approx(total + bit - wob, rel=1e-9)
    assert sum(c.length for c in loads) == pytest.approx(config.string.length)
    height = neutral_point_height(config, wob)
    bottom_height = np.cumsum([0.0] + [c.length for c in loads])
    k = int(np.searchsorted(bottom_height, height)) - 1
    assert loads[k].force_bottom < 0.0 <= loads[k].force_top


def test_the_two_section_config_is_the_same_string_as_its_components():
    """The legacy drill_pipe + bha config and the same BHA given as one component drill
    the same trajectory, bit for bit (same code, same machine)."""
    legacy = SimulationConfig()
    as_components = SimulationConfig(string=StringConfig(
        drill_pipe=legacy.string.drill_pipe, components=(legacy.string.bha,),
        stabilizers=(1.0, 10.0, 19.0)))
    runs = []
    for cfg in (legacy, as_components):
        sim = Simulator(cfg)
        sim.reset(OperatingPoint(60 * RPM, 30e3))
        sim.ul[-2, 0] = 0.004  # exercise the lateral model and the contacts
        runs.append(sim.advance(3000, 60 * RPM, sim.hook_load_for(30e3), 10))
    np.testing.assert_array_equal(runs[0], runs[1])


def test_giving_both_a_bha_and_components_is_refused():
    other_bha = Section(length=50.0, outer_diameter=6.5 * INCH, inner_diameter=2.8 * INCH,
                        element_length=1.0)
    with pytest.raises(ValueError, match="components"):
        StringConfig(bha=other_bha, components=(cp.collar_6_5(30.0),))


def test_an_empty_component_list_is_refused_not_replaced_by_the_default_bha():
    # it fell back to the paper's 35 m collar BHA, which the user never wrote
    from drill_env.physics.config import from_dict

    with pytest.raises(ValueError, match="^string.components: an empty list"):
        from_dict(SimulationConfig, {"string": {"components": []}})
    assert StringConfig().components is None and StringConfig().lower[0].length == 35.0


def test_stabilizer_components_touch_the_wall_at_their_blades():
    sim = Simulator(SimulationConfig(string=cp.realistic_string()))
    blade = cp.STABILIZER_8_3_4 / 2
    hole = sim.config.string.hole_diameter / 2
    # components.py: blades 1/8 in under the 8 3/4 in hole, 1/16 in each side
    assert hole == pytest.approx(8.75 * INCH / 2, rel=1e-12)
    assert hole - blade == pytest.approx(INCH / 16, rel=1e-9)
    assert np.sum(np.isclose(sim.node_clearance, hole - blade)) == 5  # one node each
    assert sim.node_clearance.min() == pytest.approx(hole - blade)


def test_the_paper_bhas_stabilizers_leave_a_sixteenth_of_an_inch_to_the_wall():
    """The single-section BHA's stabilizers (1, 10 and 19 m above the bit, on its 1 m
    elements): 8 5/8 in blades in an 8 3/4 in hole leave 1/16 in on each side, one node
    each; everywhere else the collars' 6 1/2 in body."""
    sim = Simulator(SimulationConfig())
    height = sim.mesh.node_depth[-1] - sim.mesh.node_depth  # above the bit
    for pos in (1.0, 10.0, 19.0):
        k = int(np.argmin(np.abs(height - pos)))
        assert sim.node_clearance[k] == pytest.approx(INCH / 16, rel=1e-9)
    stabilized = np.isclose(sim.node_clearance, INCH / 16, rtol=1e-9)
    assert stabilized.sum() == 3


def test_a_node_between_two_components_touches_with_the_larger():
    """The top node of the collars (below the heavy-weight pipe) had the pipe's radius:
    the collar's end could sink 19 mm into the wall before touching (a review against
    the paper). Each node between two body components takes the larger body; a
    stabilizer sub (one element) stays a point contact at its lower node."""
    config = SimulationConfig(string=cp.realistic_string())
    sim = Simulator(config)
    hwdp, collar = (next(s for s in config.string.sections if s.kind == kind)
                    for kind in ("heavy_weight", "collar"))
    below_pipe = config.string.length - (config.string.drill_pipe.length + hwdp.length)
    depth = sim.mesh.node_depth  # from the top
    top_collar = int(np.argmin(np.abs(depth - (config.string.length - below_pipe))))
    assert sim.node_radius[top_collar] == pytest.approx(collar.outer_diameter / 2)
    assert sim.node_radius[top_collar - 1] == pytest.approx(0.127 / 2)  # 5 in HWDP body
    # every stabilizer a point contact: one node at the blades' radius each (five)
    blades = np.isclose(sim.node_radius, cp.STABILIZER_8_3_4 / 2)
    assert blades.sum() == 5 and not np.any(blades[1:] & blades[:-1])



@pytest.mark.parametrize("elements", [1, 3])
def test_a_stabilizer_on_the_bit_holds_the_bit_with_its_blades(elements):
    """A near-bit stabilizer made up directly on the bit (components[0], no bit sub):
    its lower end is the bit's node, whose wall contact is the bit's gauge model, and
    a stabilizer of one element lost its blades (an outside check: docs/config.md's
    J-well example did this). They now sit on its own node nearest its middle: its top
    end when it is one element (the inner nodes of a longer one had them already). In a
    45 degree hole, settled at 100 kN: that node rests on the low side at the blades'
    clearance (plus the wall's penalty penetration, under a millimetre here) carrying
    the BHA, and the bit stays inside its own gauge clearance, as with the stabilizer on
    a 0.5 m bit sub (checked here too)."""
    from drill_env.physics.config import BitConfig, WellConfig

    collar = Section(kind="collar", length=90.0, element_length=3.0,
                     outer_diameter=0.1651, inner_diameter=0.07144)
    stabilizer = Section(kind="stabilizer", length=1.5, element_length=1.5 / elements,
                         outer_diameter=0.1651, inner_diameter=0.07144,
                         contact_diameter=0.2127)
    bit_sub = Section(kind="bit_sub", length=0.5, element_length=0.5,
                      outer_diameter=0.1651, inner_diameter=0.07144)
    well = WellConfig(md=(0.0, 500.0, 1000.0, 1200.0), inclination=(0.0, 0.0, 45.0, 45.0),
                      azimuth=(0.0, 0.0, 0.0, 0.0))
    results = []
    for lower in ((stabilizer, collar), (bit_sub, stabilizer, collar)):
        string = StringConfig(hole_diameter=0.2159, components=lower)
        config = SimulationConfig(string=string, well=well, bit=BitConfig(diameter=0.2159))
        sim = Simulator(config)
        sim.reset(OperatingPoint(0.0, 100e3))
        blades = np.flatnonzero(np.isclose(sim.node_radius, 0.2127 / 2)
                                & (sim.node_contact > 0.0))
        assert blades.size >= 1
        k = blades[np.argmax(sim.contact_forces[blades])]  # the one that carries the BHA
        height = sim.mesh.node_depth[-1] - sim.mesh.node_depth[k]
        offset = np.hypot(*sim.lateral_displacement[k])
        clearance = (0.2159 - 0.2127) / 2
        assert clearance <= offset < clearance + 1e-3
        assert sim.contact_forces[k] > 1e3
        radial = np.hypot(*sim.lateral_displacement[-1]) / config.bit.gauge_clearance
        results.append((height, radial, sim.contact_forces[k]))
    (height, radial, force), (_, radial_sub, force_sub) = results
    # one element: its top end; three: an inner node (they had the blades before)
    assert height == pytest.approx(1.5 if elements == 1 else 1.0)
    assert radial < 0.6 and radial_sub < 0.6
    assert force == pytest.approx(force_sub, rel=0.15)


def test_the_default_string_carries_its_wob_in_the_bha_with_margin():
    config = SimulationConfig(string=cp.realistic_string())
    bha = cp.packed_bha()
    assert not pipe_buckling(config, 100e3)
    assert 80.0 < neutral_point_height(config, 100e3) < sum(c.length for c in bha)
    assert cp.buoyed_weight(bha, config.mud.density) > 1.15 * 100e3  # API RP 7G margin
    assert pipe_buckling(SimulationConfig(), 100e3)  # the paper's 35 m BHA cannot


def test_each_collar_span_of_the_packed_bha_carries_under_half_its_euler_load():
    """At 100 kN every span between stabilizer centres carries less than half its pinned
    Euler load pi^2 EI / L^2 (a drilling engineer's review: the docs said a third, and
    the 19.5 m span above the lowest string stabilizer carries 0.45), from the sections'
    own weights in mud (Archimedes), not from our statics."""
    config = SimulationConfig(string=cp.realistic_string())
    wob, rho_mud = 100e3, config.mud.density
    top, weights, centres, ratios = 0.0, [], [], []
    for c in reversed(config.string.sections):  # from the bit up
        weights.append((top, top + c.length, (c.density - rho_mud) * c.area * GRAVITY))
        if c.kind == "stabilizer":
            centres.append(top + c.length / 2)
        top += c.length
    collar = next(c for c in config.string.sections if c.kind == "collar")
    ei = collar.youngs_modulus * collar.second_moment
    for low, high in zip(centres[:-1], centres[1:], strict=True):
        below = sum(w * (min(b, low) - a) for a, b, w in weights if a < low)
        ratios.append((wob - below) / (np.pi ** 2 * ei / (high - low) ** 2))
    assert len(ratios) == 4
    assert max(ratios) < 0.5
    assert max(ratios) == pytest.approx(0.45, abs=0.01)  # docs/model.md's figure


@pytest.mark.parametrize("rpm", [50.0, 100.0, 150.0])
def test_the_default_scenario_keeps_its_pipe_in_tension_and_off_the_wall(rpm):
    """Coupled model at the default WOB: the drill pipe and HWDP stay in tension, nothing
    above the BHA touches the wall after a lateral kick of the BHA, and at 100 rpm the
    coupled SSI equals the torsion-only one within 0.05."""
    from drill_env import metrics
    from drill_env.physics.fem import axial_force_profile, build_mesh
    from drill_env.physics.layout import R
    from drill_env.physics.statics import bit_buoyed_weight
    from drill_env.scenarios import make_scenario

    sc = make_scenario("default")
    config = sc.config
    mesh = build_mesh(config)
    force = axial_force_profile(mesh, sc.weight_on_bit, bit_buoyed_weight(config))
    pipe = np.isin(mesh.component, [0, 1])  # drill pipe and heavy-weight pipe, surface down
    assert config.string.sections[1].kind == "heavy_weight"
    assert force[pipe].min() > 0.0
    bha_top = mesh.node_depth[-1] - sum(c.length for c in cp.packed_bha())
    above_bha = mesh.node_depth < bha_top - 1e-6

    def run(lateral: bool) -> tuple[float, float]:
        cfg = config if lateral else replace(config, **{"solver.lateral": False})
        sim = Simulator(cfg)
        sim.reset(OperatingPoint(rpm * RPM, sc.weight_on_bit))
        sim.vt[-1] *= 0.99
        if lateral:
            sim.ul[-2, 0] = 0.5 * cfg.bit.gauge_clearance  # kick the bit ...
            sim.ul[-40::2, 1] = 0.002  # ... and the lower BHA
        wall_above, records = 0.0, []
        for _ in range(60):
            records.append(sim.advance(500, rpm * RPM, sim.hook_load_for(sc.weight_on_bit),
                                       5))
            wall_above = max(wall_above, float(sim.contact_forces[above_bha].max()))
        assert sim.status == 0
        rec = np.concatenate(records)
        late = rec[rec[:, R.TIME] > 30.0, R.BIT_SPEED]
        return metrics.stick_slip_severity(late), wall_above

    ssi_coupled, wall_above = run(True)
    assert wall_above == 0.0
    if rpm == 100.0:
        ssi_torsion, _ = run(False)
        assert abs(ssi_coupled - ssi_torsion) < 0.05


def test_a_scenario_refuses_a_wob_that_buckles_its_pipe_unless_allowed():
    from drill_env.scenarios import Scenario, make_scenario

    coupled_paper = make_scenario("paper_case2").config  # 120 m of collars
    legacy = replace(coupled_paper, string=StringConfig())  # the paper's 35 m BHA
    with pytest.raises(ValueError, match=r"weight_on_bit: 100 kN compresses the 5 in|"
                                         r"weight_on_bit: 100 kN compresses the drill pipe"):
        Scenario("x", legacy, 50 * RPM, 100e3)
    # built without an error (a Scenario is always truthy: check what it holds)
    assert Scenario("x", legacy, 50 * RPM, 100e3, allow_pipe_buckling=True
                    ).weight_on_bit == 100e3
    assert Scenario("x", legacy, 50 * RPM, 40e3).weight_on_bit == 40e3  # in the collars


def test_every_named_scenario_states_its_neutral_point():
    from drill_env.scenarios import SCENARIOS, make_scenario

    for name in SCENARIOS:
        sc = make_scenario(name, rng=np.random.default_rng(3)) if name == "random" else \
            make_scenario(name)
        height = sc.neutral_point
        assert 0.0 < height < sc.config.string.length
        if sc.config.solver.lateral and sc.config.well.vertical:  # coupled scenarios
            assert height < sc.config.string.bha_length, name    # carry the WOB in the BHA
        if sc.config.solver.lateral:
            # in a deviated hole less weight acts along it: at 100 kN the neutral point of
            # lateral_60 lies 262 m up, in the drill pipe, which lies on the low side and
            # carries that compression far below its (Dawson-Paslay) buckling load
            assert pipe_buckling(sc.config, sc.weight_on_bit) == [], name


def test_a_stabilizer_narrower_than_its_body_is_refused_by_name():
    """A stabilizer's blades narrower than the collar under them would widen the node's
    clearance (a recess): refused, naming the field and where; one beyond the string
    too."""
    with pytest.raises(ValueError, match=r"stabilizer_diameter: 0.1 m is narrower than the "
                                         r"collar it sits on at stabilizers\[0\]"):
        StringConfig(stabilizer_diameter=0.1)
    with pytest.raises(ValueError, match=r"stabilizers\[0\]: 5000.0 m above the bit is "
                                         "outside the 1035.0 m string"):
        StringConfig(stabilizers=(5000.0,))
    # at the string's top end too: the pinned surface node, where none is placed
    with pytest.raises(ValueError, match=r"stabilizers\[0\]: 1035.0 m above the bit is "
                                         "outside the 1035.0 m string"):
        StringConfig(stabilizers=(1035.0,))
    # nearest the bit's node (1 m elements at the bit): the bit's gauge touches there, and
    # the stabilizer was dropped without a word; said (not refused: the paper BHA's 1 m
    # default meets it on a coarser mesh)
    with pytest.warns(UserWarning, match=r"stabilizers\[0\]: 0.3 m above the bit is nearest "
                                         r"the bit's node .* it is not modelled"):
        StringConfig(stabilizers=(0.3,))
    with warnings.catch_warnings():  # at half an element the node above takes it: no word
        warnings.simplefilter("error")
        assert StringConfig(stabilizers=(0.5,)).stabilizers == (0.5,)
    # blades as wide as the 6 1/2 in collars they sit on are no narrower: accepted
    assert StringConfig(stabilizer_diameter=6.5 * INCH).stabilizer_diameter == 6.5 * INCH
    # on the pipe above a 35 m BHA a 6 in stabilizer is wider than the 5 in body: accepted,
    # also at 34.6 m, whose nearest node (35 m) carries the pipe
    assert StringConfig(stabilizers=(100.0,), stabilizer_diameter=6 * INCH).stabilizers
    assert StringConfig(stabilizers=(34.6,), stabilizer_diameter=6 * INCH).stabilizers


@pytest.mark.parametrize("hole_in, blades_in, warned", [
    (8.75, 8.625, False), (12.25, 8.625, True), (12.25, 12.125, False), (8.75, 7.75, False),
    (8.75, 7.7, True)])
def test_stabilizer_blades_well_under_the_hole_are_warned_of(hole_in, blades_in, warned):
    """A 12 1/4 in hole kept the default 8 5/8 in blades of the ``stabilizers`` positions
    without a word, 1.8 in off the wall each side: more than an inch under the hole
    (components.STABILIZER_UNDER_HOLE; field stabilizers run at most ~1/2 in under gauge)
    is said, naming the field and the gap in inches."""
    config = {"hole_diameter": hole_in * INCH, "stabilizer_diameter": blades_in * INCH}
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        StringConfig(**config)
    said = [str(w.message) for w in seen
            if str(w.message).startswith("string.stabilizer_diameter: ")]
    assert bool(said) == warned
    if warned:
        assert f"is {hole_in - blades_in:.3g} in under string.hole_diameter" in said[0]
    # a string of components places no stabilizers by these fields: no word
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        StringConfig(**config, components=(cp.collar_6_5(60.0),))
    assert not [w for w in seen if "stabilizer_diameter" in str(w.message)]


@pytest.mark.parametrize("make, lb_per_ft", [(cp.collar_6_5, 91.0), (cp.collar_8, 150.0),
                                             (cp.drill_pipe_5, 17.93)])
def test_tube_presets_weigh_what_the_api_tables_list(make, lb_per_ft):
    """Plain collars are steel tubes: their weight per foot in API RP 7G's table (6 1/2 x
    2 13/16 in: 91 lb/ft; 8 x 2 13/16 in: 150 lb/ft), which rounds to the pound; the 5 in
    19.5 lb/ft drill pipe's body is 17.93 lb/ft plain-end (API 5DP; tool joints make the
    nominal weight). From the preset's diameters and steel density."""
    tube = make(30.0)
    kg_per_m = tube.density * tube.area
    assert kg_per_m / 1.48816 == pytest.approx(lb_per_ft, abs=1.0)  # 1 lb/ft = 1.48816 kg/m


@pytest.mark.parametrize("make, size", [
    (cp.heavy_weight_5, (5.0, 3.0)),
    (lambda length: cp.stabilizer(length=length), (6.5, 2.8125)),
    (cp.mwd, (6.75, 3.25)),
    (cp.jar, (6.5, 2.75)),
    (cp.bit_sub, (6.5, 2.8125)),
], ids=["HWDP", "stabilizer", "MWD", "jar", "bit sub"])
def test_tool_and_hwdp_bodies_weigh_the_steel_tube_their_docstrings_name(make, size):
    """Each preset's body is the tube its docstring names (OD x ID, in), so it weighs
    2.67 (OD^2 - ID^2) lb/ft, the plain steel-tube formula behind API RP 7G's collar
    table (490 lb/ft^3 steel): to 0.2 %, its 7850 kg/m^3 being 0.1 % off that."""
    tube = make(30.0)
    od, bore = size
    assert tube.density * tube.area / 1.48816 == pytest.approx(2.67 * (od**2 - bore**2),
                                                              rel=2e-3)


@pytest.mark.parametrize("make, size, listed", [(cp.drill_pipe_5, (5.0, 0.362), 17.93),
                                                (cp.drill_pipe_5_5, (5.5, 0.361), 19.81)])
def test_drill_pipe_bodies_are_the_api_sizes_and_weigh_their_plain_end_weight(make, size,
                                                                                 listed):
    """API Spec 5DP: the 5 in and 5 1/2 in pipe's diameter and wall, and the plain-end
    weight its table lists (17.93 and 19.81 lb/ft, which its formula 10.68 (D - t) t
    lb/ft gives to the table's rounding); the preset's mass per length to 0.2 % of it
    (its steel, 7850 kg/m^3, is 0.1 % above the 7842 the 10.68 implies). The test above
    checks the table weight to the pound."""
    tube = make(30.0)
    d, wall = tube.outer_diameter / INCH, (tube.outer_diameter - tube.inner_diameter) / 2 / INCH
    assert (d, wall) == pytest.approx(size, abs=5e-4)  # the API size, to its 0.001 in
    assert 10.68 * (d - wall) * wall == pytest.approx(listed, rel=1e-3)
    assert tube.density * tube.area / 1.48816 == pytest.approx(listed, rel=2e-3)


def test_buoyed_weight_takes_the_mud_s_buoyancy_factor():
    """Weight in mud = weight in air x (1 - mud weight / 65.5 ppg), the driller's
    buoyancy factor (65.5 ppg: steel; Bourgoyne et al., Applied Drilling Engineering):
    10 ppg mud (1198 kg/m^3) on the default BHA."""
    components = cp.packed_bha()
    air = sum(c.density * c.area * c.length for c in components) * GRAVITY
    mud = 10.0 * 119.826  # 10 ppg in kg/m^3
    assert cp.buoyed_weight(components, mud) == pytest.approx(air * (1 - 10.0 / 65.5),
                                                              rel=1e-3)


@pytest.mark.parametrize("total_length", [247.5, 200.0])
def test_a_realistic_string_with_no_room_for_drill_pipe_is_refused_by_total_length(
        total_length):
    """components.py: the 107.5 m packed BHA and 140 m of HWDP leave no drill pipe in a
    string of 247.5 m or less: refused naming ``total_length``, not the pipe's length."""
    with pytest.raises(ValueError, match=rf"^total_length: {total_length} m leaves no room "
                                         r"for the drill pipe above 248 m of BHA and HWDP"):
        cp.realistic_string(total_length)
