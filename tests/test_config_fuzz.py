"""Every config field, fed bad values: accepted and simulated finitely, or refused by name.

The systematic part tries each field of the physics config, the env config and the
scenario parameters with NaN, infinities, zero, negatives, huge and tiny numbers and
wrong types; the hypothesis part draws further values at random. An input is either
refused with a ``ValueError``/``TypeError`` whose message names the field as the user
typed it, or accepted, and then the simulator (or env) built from it runs a few steps
with finite readings or stops with a reason. Nothing may hang, exhaust memory or raise
anything else.
"""

from __future__ import annotations

import dataclasses
import math
import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from drill_env.env import EnvConfig
from drill_env.physics.config import SimulationConfig, replace
from drill_env.physics.simulator import OperatingPoint, Simulator
from drill_env.physics.units import RPM
from drill_env.scenarios import SCENARIOS, make_scenario, scenario_parameters

#: The bad values every field is tried with.
BAD_VALUES = (math.nan, math.inf, -math.inf, 0.0, 0, -1.0, -1e300, 1e300, 1e30, 1e-300,
              "abc", None, True, [1.0], {"x": 1.0})


def _paths(obj, prefix: str = "") -> list[str]:
    """Dotted paths of every leaf field (tuples of sections: their first item)."""
    out = []
    for f in dataclasses.fields(obj):
        value = getattr(obj, f.name)
        path = f"{prefix}{f.name}"
        out.append(path)
        if dataclasses.is_dataclass(value):
            out += _paths(value, path + ".")
        elif isinstance(value, tuple) and value and dataclasses.is_dataclass(value[0]):
            out += _paths(value[0], f"{path}[0].")
    return out


#: A base with every kind of section filled in (two rocks, two interfaces).
BASE_PHYSICS = make_scenario("paper_case2", lead=0.0).config
PHYSICS_PATHS = _paths(BASE_PHYSICS)
ENV_PATHS = [f.name for f in dataclasses.fields(EnvConfig)]
SCENARIO_PATHS = [(name, p) for name in SCENARIOS for p in scenario_parameters(name)
                  if p != "rng"]


def _check_refusal(err: Exception, field: str) -> None:
    assert isinstance(err, (ValueError, TypeError)), repr(err)
    leaf = field.rsplit(".", 1)[-1]
    message = str(err)
    assert field in message or leaf in message, f"{field!r} not named in: {message}"


def _simulates_finitely(config: SimulationConfig) -> None:
    """A few steps at a modest operating point: finite readings, or a stop with a reason."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # e.g. the compressed-pipe warning
        sim = Simulator(config)
        wob = 20e3
        sim.reset(OperatingPoint(60 * RPM, wob))
        records = sim.advance(20, 60 * RPM, sim.hook_load_for(wob), record_every=5, read=True)
    if sim.status:
        assert sim.status_message
    else:
        assert np.all(np.isfinite(records)), "accepted input simulated to a non-finite value"
        assert np.all(np.isfinite(sim.readings))


def physics_case(path: str, value) -> str:
    try:
        config = replace(BASE_PHYSICS, **{path: value})
    except Exception as err:  # noqa: BLE001  (the type is asserted)
        _check_refusal(err, path)
        return "refused"
    try:
        _simulates_finitely(config)
    except (ValueError, TypeError) as err:  # a check at simulator build time is fine
        _check_refusal(err, path)
        return "refused"
    return "accepted"


def env_case(path: str, value) -> str:
    from drill_env.env import DrillStringEnv

    try:
        env = DrillStringEnv("paper_case1", episode_duration=0.3, **{path: value})
    except Exception as err:  # noqa: BLE001
        if path == "episode_duration":  # given twice above: the test's own override wins
            raise
        _check_refusal(err, path)
        return "refused"
    obs, info = env.reset(seed=0)
    for _ in range(2):
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        assert np.all(np.isfinite(obs)) and math.isfinite(reward)
        if terminated or truncated:
            break
    return "accepted"


def scenario_case(name: str, param: str, value) -> str:
    try:
        scenario = make_scenario(name, rng=np.random.default_rng(0), **{param: value}) \
            if name == "random" else make_scenario(name, **{param: value})
    except Exception as err:  # noqa: BLE001
        _check_refusal(err, param)
        return "refused"
    _simulates_finitely(scenario.config)
    return "accepted"


def test_every_field_is_covered():
    assert len(PHYSICS_PATHS) > 70 and len(ENV_PATHS) >= 25 and len(SCENARIO_PATHS) > 30
    assert "mud.density" in PHYSICS_PATHS and "formation.rocks[0].mu_max" in PHYSICS_PATHS


@pytest.mark.parametrize("path", PHYSICS_PATHS)
def test_physics_fields_refuse_bad_values_by_name(path):
    outcomes = [physics_case(path, v) for v in BAD_VALUES]
    assert outcomes[0] == outcomes[1] == outcomes[2] == "refused"  # NaN, +inf, -inf
    if not path.endswith("name"):
        assert outcomes[10] == "refused"  # a string is never a number or a section


@pytest.mark.parametrize("path", [p for p in ENV_PATHS if p != "episode_duration"])
def test_env_fields_refuse_bad_values_by_name(path):
    outcomes = [env_case(path, v) for v in BAD_VALUES if v is not None or path in (
        "episode_duration",)]
    assert outcomes[0] == outcomes[1] == outcomes[2] == "refused"


@pytest.mark.parametrize(("name", "param"), SCENARIO_PATHS)
def test_scenario_parameters_refuse_bad_values_by_name(name, param):
    outcomes = [scenario_case(name, param, v) for v in BAD_VALUES]
    assert outcomes[0] == outcomes[1] == outcomes[2] == "refused"


def test_a_misspelt_scenario_name_is_told_the_name_it_was_probably_meant_to_be():
    with pytest.raises(ValueError, match=r"^scenario: unknown name 'stick_slp' \(did you mean "
                                         r"stick_slip\?\); known scenarios: default"):
        make_scenario("stick_slp")
    with pytest.raises(ValueError, match=r"^scenario: unknown name 'zzz'; known scenarios"):
        make_scenario("zzz")  # nothing close: no guess


def test_the_systematic_part_tries_more_than_2000_inputs():
    n = len(BAD_VALUES) * (len(PHYSICS_PATHS) + len(ENV_PATHS) - 1 + len(SCENARIO_PATHS))
    assert n >= 2000, n


NUMBERS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(min_value=-10**30, max_value=10**30),
    st.sampled_from([0.0, -0.0, 1e-320, 5e-324, 1e308, -1e308]),
)
ANYTHING = st.one_of(NUMBERS, st.text(max_size=5), st.booleans(), st.none(),
                     st.lists(st.floats(), max_size=3))


@settings(max_examples=1000, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(path=st.sampled_from(PHYSICS_PATHS), value=ANYTHING)
def test_random_values_on_random_physics_fields(path, value):
    physics_case(path, value)


@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(case=st.sampled_from(SCENARIO_PATHS), value=ANYTHING)
def test_random_values_on_random_scenario_parameters(case, value):
    scenario_case(*case, value)


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(path=st.sampled_from([p for p in ENV_PATHS if p != "episode_duration"]),
       value=ANYTHING)
def test_random_values_on_random_env_fields(path, value):
    env_case(path, value)


def test_nested_dicts_are_converted_and_unknown_keys_named():
    from drill_env.env import DrillStringEnv

    env = DrillStringEnv(physics={"mud": {"density": 1300}}, episode_duration=0.2)
    assert env.simulation_config.mud.density == 1300.0
    with pytest.raises(ValueError, match=r"mud\.densty"):
        DrillStringEnv(physics={"mud": {"densty": 1300}})
    with pytest.raises(ValueError, match=r"mud\.density"):
        DrillStringEnv(physics={"mud.density": 8000.0})
    with pytest.raises(ValueError, match=r"^dip: "):
        make_scenario("paper_case1", dip=math.nan)
    with pytest.raises(ValueError, match=r"solver\.lateral"):
        SimulationConfig(solver={"lateral": 1})


def test_a_typo_in_a_section_of_a_list_lists_that_sections_fields():
    # it said "Unexpected keyword argument" without the fields (a dotted path did); the
    # field it was meant to be is named, and its "Field required" left out
    from drill_env.physics.config import from_dict

    collar = {"lenght": 9.0, "outer_diameter": 0.2, "inner_diameter": 0.07,
              "element_length": 1.0}
    with pytest.raises(ValueError, match=r"^string\.components\[0\]\.lenght: unknown field "
                                         r"of Section \(did you mean length\?\); known: "
                                         r"length, outer_diameter") as err:
        from_dict(SimulationConfig, {"string": {"components": [collar]}})
    assert "required" not in str(err.value)
    with pytest.raises(ValueError, match=r"^solver\.time_stepp: unknown field of SolverConfig "
                                         r"\(did you mean time_step\?\); known: "):
        replace(SimulationConfig(), **{"solver.time_stepp": 0.001})
    collar = {"outer_diameter": 0.2, "inner_diameter": 0.07, "element_length": 1.0}
    with pytest.raises(ValueError, match=r"length: Field required"):  # a field left out
        from_dict(SimulationConfig, {"string": {"components": [collar]}})
    with pytest.raises(ValueError, match=r"^bogus: unknown field of SimulationConfig; known: "
                                         r"string, mud"):
        from_dict(SimulationConfig, {"bogus": 1})


@pytest.mark.parametrize(("scenario", "physics", "message"), [
    # a TypeError ('NoneType' object is not iterable) from deep inside
    ("paper_case2", {"string.components[2].length": 9.0}, r"^string\.components: is None "
     r"here, not a list, so it takes no index"),
    ("default", {"mud[0].density": 1000.0}, r"^mud: is a MudConfig here, not a list"),
    # the last of the two silently won
    ("default", {"mud": {"density": 1200.0}, "mud.density": 1300.0},
     r"^mud\.density: given twice"),
    # it named string.drill_pipe.length, which the user had not touched
    ("default", {"string.components[12].length": 14000.0},
     r"^string\.components\[12\]\.length: the string is 15110\.0 m long"),
    # it read as an unknown field "components[-1]" ("did you mean components?")
    ("default", {"string.components[-1].length": 9.0},
     r"^string\.components\[-1\]: an index is a whole number from 0 \(components\[0\] "
     r"is the first\), got \[-1\]"),
    # cut at the dot inside the index, it named a field "components[1" (an outside check)
    ("default", {"string.components[1.5].length": 9.0},
     r"^string\.components\[1\.5\]: an index is a whole number from 0 .* got \[1\.5\]"),
    # a Section's bore too wide is its inner diameter's fault (Section.__post_init__)
    ("paper_case1", {"string.bha.inner_diameter": 0.2},
     r"^string\.bha\.inner_diameter: must be smaller than outer_diameter \(0\.1651 m\)"),
    # a stabilizer's blades wider than the 8 3/4 in hole: its contact diameter, not its body
    ("default", {"string.components[0].contact_diameter": 0.23},
     r"^string\.components\[0\]\.contact_diameter: 0\.23 m must be smaller than "
     r"hole_diameter 0\.22225 m"),
    # a gauge clearance of more than the bit's radius (8 3/4 in / 2 = 0.111125 m)
    ("default", {"bit.gauge_clearance": 0.12},
     r"^bit\.gauge_clearance: 0\.12 m must be smaller than the bit radius \(diameter / 2 = "
     r"0\.111125 m\)"),
    # only the diameter set, the default blades' face_end (0.07 m) lay outside a 0.1 m bit,
    # refused by a field the file never set (a new user's walkthrough): it says why
    ("default", {"bit.diameter": 0.1}, r"^bit\.face_end\[0\]: 0\.07 m lies beyond the "
     r"gauge radius .*needs its own face_end \(the default is the 8\.75 in bit's\)"),
    # a misspelt word of a field that takes words got the list but no suggestion, where a
    # misspelt field name gets one (a new user's trial: kind colar, stabiliser)
    ("default", {"string.components[1].kind": "colar"}, r"^string\.components\[1\]\.kind: "
     r"Input should be .*, got 'colar' \(did you mean collar\?\)"),
    ("default", {"solver.fidelity": "fastt"}, r"^solver\.fidelity: .*, got 'fastt' \(did you "
     r"mean fast\?\)"),
])
def test_a_dotted_path_error_names_what_the_user_typed(scenario, physics, message):
    from drill_env.env import DrillStringEnv

    with pytest.raises(ValueError, match=message):
        DrillStringEnv(scenario, physics=physics)


def test_an_index_one_past_the_last_section_is_out_of_range():
    """Index n of n sections names the path and count (validation._changed_fields)."""
    config = make_scenario("default").config
    n = len(config.string.components)
    with pytest.raises(ValueError, match=rf"^string\.components\[{n}\]: index out of range "
                                         rf"\({n} items\)"):
        replace(config, **{f"string.components[{n}]": config.string.components[0]})


def test_an_overdamped_wall_contact_is_refused_by_its_damping():
    """Found by the random fuzz: a contact damper so hard that the explicit step falls
    below the minimum was blamed on contact.stiffness alone."""
    assert physics_case("contact.damping", 33418268) == "refused"


def test_a_section_dict_replaces_the_section_and_dotted_keys_merge_as_documented():
    """replace's docstring and docs/model.md, after a walkthrough lost the paper_case2
    sandwich's interfaces to ``replace(c, formation={"rocks": ...})``: the section dict
    starts from the section's defaults, ``**flatten(...)`` keeps the rest of it, and both
    read the same values into the fields they name."""
    from drill_env.physics.config import flatten

    config = make_scenario("paper_case2").config
    rocks = [{"name": f"r{k}", "mu_max": 0.7} for k in range(len(config.formation.rocks))]
    whole = replace(config, formation={"rocks": rocks})
    merged = replace(config, **flatten({"formation": {"rocks": rocks}}))
    assert len(config.formation.interfaces) == 2
    assert whole.formation.interfaces == () and whole.formation.layers == (0,)
    assert merged.formation.interfaces == config.formation.interfaces
    assert merged.formation.layers == config.formation.layers
    assert whole.formation.rocks == merged.formation.rocks
    assert [r.mu_max for r in merged.formation.rocks] == [0.7] * len(rocks)


@pytest.mark.parametrize("rocks", [{"shale": {"mu_max": 0.6}}, {"name": "shale", "mu_max": 0.6}])
def test_a_list_section_given_as_a_dict_is_told_to_be_a_list(rocks):
    """From a walkthrough: a rock list typed as a dict (by name, or one rock) read
    "rocks is not a section", which did not say what it is."""
    from drill_env.physics.config import flatten

    with pytest.raises(ValueError, match=r"^formation\.rocks: a list of RockConfig, not a "
                                         r"section: give a list of dicts .* set one entry "
                                         r"\(formation\.rocks\[0\]\.<field>\)"):
        gym_physics = flatten({"formation": {"rocks": rocks}})  # as the env reads physics=
        replace(SimulationConfig(), **gym_physics)


@pytest.mark.parametrize("path, value, unit", [
    ("string.drill_pipe.outer_diameter", 5.0, "metres; 5 in = 0.127 m"),  # inches
    ("string.hole_diameter", 215.9, "metres; 5 in = 0.127 m"),  # millimetres
    ("mud.density", 1e5, "kg/m^3; steel 7,850 kg/m^3, a 10 ppg mud 1,198 kg/m^3"),
    ("string.hole_diameter", 0.0, "metres; 5 in = 0.127 m"),  # a lower bound ("greater than")
])
def test_a_bound_broken_by_a_field_with_a_unit_says_the_unit(path, value, unit):
    """A diameter typed in inches broke "less than 1" and said no more: which unit the
    field is in is what the user needs (a drilling engineer's walkthrough)."""
    with pytest.raises(ValueError) as caught:
        replace(SimulationConfig(), **{path: value})
    said = str(caught.value)
    assert f"{path}: " in said and f"got {value!r} ({unit})" in said
    with pytest.raises(ValueError) as caught:  # a bound on a field without a unit: as was
        replace(SimulationConfig(), **{"damping.mass_proportional": -1.0})
    assert "(" not in str(caught.value).partition("got")[2]


@pytest.mark.parametrize("density, warned, unit", [  # 1 US gal = 3.785412 L, 1 lb = 0.4535924 kg
    (10.0, "1,198 kg/m^3", "ppg"), (19.5, "2,337 kg/m^3", "ppg"),
    (1.5, "1,500 kg/m^3", "specific gravity"), (1.2, "1,200 kg/m^3", "specific gravity"),
    (0.1, "", ""), (1200.0, "", ""), (2100.0, "", "")])
def test_a_mud_density_typed_in_ppg_or_as_sg_is_warned_of(density, warned, unit):
    """10 (ppg, typed for 1,198 kg/m^3) was accepted silently: the string then drills
    without buoyancy; so was 1.5 (a specific gravity, a new user's trial). Each warns with
    its conversion (air at the surface, 1.2, with them: it says so); real muds do not."""
    import warnings

    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        config = replace(SimulationConfig(), **{"mud.density": density})
    said = [str(w.message) for w in seen if "mud.density" in str(w.message)]
    assert config.mud.density == density  # a warning, not a refusal: air at depth is light
    assert bool(said) == bool(warned)
    if warned:
        assert warned in said[0] and unit in said[0]


@pytest.mark.parametrize("torque, warned", [(50.0, "50 kN m = 50,000 N m"), (999.0, "999 kN m"),
                                            (1000.0, ""), (50e3, "")])
def test_a_top_drive_torque_typed_in_knm_is_warned_of(torque, warned):
    """top_drive.max_torque 50 (kN m, typed for 50,000 N m) stalled the drive without a
    word, which read as stick-slip (a new user's trial): below 1 kN m it warns with the
    conversion; a drive's real ratings do not."""
    import warnings

    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        config = replace(SimulationConfig(), **{"top_drive.max_torque": torque})
    said = [str(w.message) for w in seen if "max_torque" in str(w.message)]
    assert config.top_drive.max_torque == torque  # a warning: a model drive may be small
    assert bool(said) == bool(warned)
    if warned:
        assert said[0].startswith("top_drive.max_torque: ") and warned in said[0]


def test_a_mud_heavier_than_the_lightest_section_is_refused():
    """MudConfig: the mud "must be lighter than the string" (SimulationConfig): an
    aluminium drill pipe (2,700 kg/m^3) under steel collars floats in a 2,800 kg/m^3 mud
    and is refused, naming mud.density and the lightest section's density."""
    with pytest.raises(ValueError, match=r"^mud\.density: 2800\.0 kg/m\^3 must be below the "
                                         r"density of the string \(2700\.0 kg/m\^3\)"):
        replace(SimulationConfig(), **{"string.drill_pipe.density": 2700.0,
                                       "mud.density": 2800.0})


def test_a_smaller_hole_names_the_default_it_meets_and_what_to_do():
    """Setting only the hole diameter met the default stabilizer diameter, a field the
    user never wrote: the error says it is a default and to set it."""
    with pytest.raises(ValueError) as caught:
        replace(SimulationConfig(), **{"string.hole_diameter": 8.5 * 0.0254})
    said = str(caught.value)
    assert said.startswith("string.stabilizer_diameter: ") and "default" in said
    assert "set it for this hole" in said


def test_a_components_contact_diameter_may_equal_its_outer_diameter():
    """Section: ``contact_diameter`` "must not be smaller than outer_diameter": equal is
    the body touching the wall, as with none given; smaller is refused by name."""
    from drill_env.physics.config import Section

    body = {"length": 9.0, "element_length": 1.0, "outer_diameter": 0.1651,
            "inner_diameter": 0.07}
    assert Section(**body, contact_diameter=0.1651).wall_diameter == 0.1651
    with pytest.raises(ValueError, match=r"^contact_diameter: 0\.16 m must not be smaller "
                                         r"than outer_diameter \(0\.1651 m\)"):
        Section(**body, contact_diameter=0.16)


def test_a_string_of_components_needs_no_stabilizer_diameter():
    """With components a stabilizer is a component with its own contact_diameter:
    string.stabilizer_diameter places only the legacy ``stabilizers`` and was refused,
    though unused, in a smaller hole (a new user's walkthrough)."""
    from drill_env.physics.config import Section

    stabilizer = Section(kind="stabilizer", length=1.5, element_length=1.5,
                         outer_diameter=0.1651, inner_diameter=0.07144,
                         contact_diameter=0.2127)
    collars = Section(kind="collar", length=60.0, element_length=3.0,
                      outer_diameter=0.1651, inner_diameter=0.07144)
    config = replace(SimulationConfig(), **{
        "string.hole_diameter": 0.2159, "string.components": (stabilizer, collars),
        "string.bha": SimulationConfig().string.bha, "string.stabilizers": None,
        "bit.diameter": 0.2159})
    assert config.string.stabilizer_diameter > config.string.hole_diameter  # unused


def test_a_smaller_hole_names_the_default_bit_it_meets():
    """Only the hole set, the 8 3/4 in default bit was refused without saying it is a
    default (a new user's walkthrough)."""
    with pytest.raises(ValueError) as caught:
        replace(SimulationConfig(), **{"string.hole_diameter": 8.5 * 0.0254,
                                       "string.stabilizer_diameter": 0.21})
    said = str(caught.value)
    assert said.startswith("bit.diameter: ") and "the default bit is 8 3/4 in" in said
    assert "set it for this hole" in said


@pytest.mark.parametrize("hole_in, bit_in, warned", [(12.25, 8.75, True), (8.75, 8.75, False),
                                                     (9.7, 8.75, False), (9.8, 8.75, True)])
def test_a_bit_well_under_its_hole_is_warned_of(hole_in, bit_in, warned):
    """A new user's 12 1/4 in hole was drilled on by the default 8 3/4 in bit without a
    word: a bit drills a hole of its own size, so more than an inch under it
    (hole_fit.BIT_UNDER_HOLE) is said, naming bit.diameter; a washout's fraction of an
    inch is not."""
    import warnings

    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        replace(SimulationConfig(), **{"string.hole_diameter": hole_in * 0.0254,
                                       "bit.diameter": bit_in * 0.0254})
    said = [str(w.message) for w in seen if str(w.message).startswith("bit.diameter: ")]
    assert bool(said) == warned
    if warned:
        assert f"{hole_in - bit_in:.3g} in under string.hole_diameter" in said[0]


def test_a_survey_missing_a_field_names_the_field_missing():
    """A well without azimuth said "well: md, inclination: one value per survey station":
    it named the two fields given, not the one left out."""
    from drill_env.physics.validation import from_dict

    for well, named in (({"md": [0, 300, 800], "inclination": [0, 0, 30]}, "well.azimuth: "),
                        ({"md": [0, 300, 800]}, "well: inclination, azimuth: "),
                        ({"md": [0, 300, 800], "inclination": [0, 30], "azimuth": [0] * 3},
                         "well.inclination: ")):
        with pytest.raises(ValueError) as caught:
            from_dict(SimulationConfig, {"well": well})
        assert str(caught.value).startswith(named), str(caught.value)


@pytest.mark.parametrize("kick_off, initial_depth, warned", [
    (1500.0, None, True), (1035.0, None, True), (1034.0, None, False),
    (1038.0, 1040.0, False), (1040.0, 1040.0, True), (300.0, None, False)])
def test_a_hole_that_bends_only_below_the_string_is_warned_of(kick_off, initial_depth,
                                                               warned):
    """A survey typed in feet put its kick-off below the default 1,035 m string, which
    then hung in a vertical hole without a word: a hole vertical down to the deepest node
    (the string's length or ``initial_depth``) is said, naming well.md and the depth in
    feet converted (kick_off ft x 0.3048 m)."""
    import warnings

    survey = {"well.md": (0.0, kick_off, 3000.0), "well.inclination": (0.0, 0.0, 45.0),
              "well.azimuth": (0.0, 0.0, 0.0)}
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        replace(SimulationConfig(), **survey, initial_depth=initial_depth)
    said = [str(w.message) for w in seen if str(w.message).startswith("well.md: ")]
    assert bool(said) == warned
    if warned:
        assert f"vertical down to {kick_off:,.6g} m" in said[0]
        assert f"= {kick_off * 0.3048:,.6g} m" in said[0]


def test_the_survey_must_reach_a_bit_set_below_the_string():
    """WellConfig: "The survey must reach the deepest node (the string's length or
    ``initial_depth``)": a 1,050 m survey holds the default 1,035 m string at a bit depth
    of 1,040 m, not of 1,100 m."""
    survey = {"well.md": (0.0, 1050.0), "well.inclination": (0.0, 10.0),
              "well.azimuth": (0.0, 0.0)}
    assert replace(SimulationConfig(), **survey, initial_depth=1040.0).initial_depth == 1040.0
    with pytest.raises(ValueError, match=r"^well\.md: the survey ends at 1050\.0 m, above the "
                                         r"string's deepest node \(1100\.0 m\)"):
        replace(SimulationConfig(), **survey, initial_depth=1100.0)
