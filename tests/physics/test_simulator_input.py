"""The simulator's entry points refuse bad input, naming it, instead of a silent
diverged (or empty) run."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from drill_env.physics.simulator import OperatingPoint, Simulator
from drill_env.physics.units import RPM

NOT_FINITE, NEGATIVE = "must be a finite number", "must be >= 0"


@pytest.mark.parametrize(("speed", "wob", "field", "message"), [
    (math.nan, 100e3, "surface_speed", NOT_FINITE),
    (math.inf, 100e3, "surface_speed", NOT_FINITE),
    (-5.0, 100e3, "surface_speed", NEGATIVE), (5.0, math.nan, "weight_on_bit", NOT_FINITE),
    (5.0, -100e3, "weight_on_bit", NEGATIVE), (5.0, "100", "weight_on_bit", NOT_FINITE)])
def test_an_operating_point_must_be_finite_and_not_negative(speed, wob, field, message):
    with pytest.raises(ValueError, match=f"^OperatingPoint.{field}: {message}, got"):
        OperatingPoint(surface_speed=speed, weight_on_bit=wob)


def test_numpy_scalars_make_an_operating_point():
    point = OperatingPoint(np.float32(50 * RPM), np.int64(100_000))
    assert point.weight_on_bit == 100_000


@pytest.mark.parametrize(("duration", "message"), [
    (-1.0, "must be > 0"), (0.0, "must be > 0"), (math.nan, NOT_FINITE),
    (math.inf, NOT_FINITE)])
def test_run_needs_a_positive_finite_duration(duration, message):
    sim = Simulator()
    sim.reset(OperatingPoint(50 * RPM, 100e3))
    with pytest.raises(ValueError, match=f"^duration: {message}, got"):
        sim.run(duration)


@pytest.mark.parametrize("depth", [math.nan, math.inf, "1000"])
def test_a_bit_depth_must_be_a_finite_number(depth):
    # a NaN depth would fail every layer test and drill layer 0 with a NaN depth reading
    sim = Simulator()
    with pytest.raises(ValueError, match=f"^depth: {NOT_FINITE}, got"):
        sim.reset(OperatingPoint(50 * RPM, 100e3), depth=depth)
    sim.reset(OperatingPoint(50 * RPM, 100e3), depth=1000.0)
    with pytest.raises(ValueError, match=f"^depth: {NOT_FINITE}, got"):
        sim.set_depth(depth)
    assert sim.depth == 1000.0


def test_run_records_every_so_many_steps_or_none():
    sim = Simulator()
    sim.reset(OperatingPoint(50 * RPM, 100e3))
    assert sim.run(0.1).shape[0] == 0
    steps = round(0.1 / sim.dt)
    first = sim.run(0.1, record_every=5)
    assert first.shape[0] == steps // 5
    kept = first.copy()
    sim.run(0.1, record_every=5)  # records(): a copy, not a view of the kernel's buffer
    np.testing.assert_array_equal(first, kept)
    with pytest.raises(ValueError, match="record_every: must be a whole number of steps "
                                         "from 0 to 1000000000, got -1"):
        sim.run(0.1, record_every=-1)  # it returned no records, as 0 asks, without a word


@pytest.mark.parametrize(("call", "message"), [
    # each reached the compiled kernel (a numba TypingError or OverflowError) or ran
    (lambda sim: sim.advance("5"), r"^n_steps: must be a whole number of steps .* got '5'"),
    (lambda sim: sim.advance(1.5), r"^n_steps: .* got 1\.5"),
    (lambda sim: sim.advance(-5), r"^n_steps: .* got -5"),
    (lambda sim: sim.advance(True), r"^n_steps: .* got True"),
    (lambda sim: sim.run(0.1, record_every=2.5), r"^record_every: .* got 2\.5"),
    (lambda sim: sim.run(1e300), r"^duration: 1e\+300 s is 5e\+302 steps, more than one"),
    (lambda sim: sim.hook_load_for(math.nan), r"^weight_on_bit: must be a finite number"),
    # a NaN hook load left a WOB of max(0, nan) = 0: a silent run off bottom
    (lambda sim: sim.advance(1, hook_load=math.nan), r"^hook_load must be finite, got nan"),
    (lambda sim: sim.advance(1, speed_setpoint=math.inf), r"^speed_setpoint must be finite"),
    (lambda sim: setattr(sim, "speed_correction", math.nan),
     r"^speed_correction: must be finite, got nan")])
def test_the_simulators_inputs_are_refused_by_name(call, message):
    sim = Simulator()
    sim.reset(OperatingPoint(50 * RPM, 100e3))
    with pytest.raises(ValueError, match=message):
        call(sim)
    assert sim.advance(np.int64(5), record_every=np.int32(1)).shape[0] == 5  # NumPy counts
    assert sim.advance(np.int64(0)).shape[0] == 0  # from 0 (require_steps' docstring)


def test_a_run_shorter_than_a_step_takes_one_step():
    """``run(duration)`` takes the steps that make ``duration``, at least one: a request
    below half a step advanced nothing and returned an empty record."""
    from drill_env.physics.config import SimulationConfig, replace
    from drill_env.physics.validation import duration_steps

    assert duration_steps(1e-4, 2e-3) == 1
    assert duration_steps(5.2e-3, 2e-3) == 3  # rounded to the nearest step
    sim = Simulator(replace(SimulationConfig(), **{"solver.lateral": False}))
    sim.reset(OperatingPoint(60 * RPM, 50e3))
    rec = sim.run(1e-4, record_every=1)
    assert sim.time == pytest.approx(sim.dt, rel=1e-12) and len(rec) == 1


def test_run_takes_its_duration_at_the_step_the_simulator_uses():
    """``run(duration)`` advances ``duration`` simulated seconds at the simulator's own
    step ``sim.dt``, which stability shortens below ``solver.time_step`` (here 10 ms asked,
    ~2.5 ms used): the time reached is the duration to within half a step."""
    from drill_env.physics.config import SimulationConfig, replace

    sim = Simulator(replace(SimulationConfig(), **{"solver.time_step": 0.01,
                                                   "solver.lateral": False}))
    assert sim.dt < 0.5 * sim.config.solver.time_step
    sim.reset(OperatingPoint(60 * RPM, 50e3))
    sim.run(0.1)
    assert sim.time == pytest.approx(0.1, abs=0.5 * sim.dt)


def test_a_hook_load_above_the_string_weight_lifts_the_bit_off_bottom():
    """``weight_on_bit_for``: the bit is off bottom (WOB 0, not negative) when the hook
    carries everything; a step at such a hook load runs at WOB 0."""
    sim = Simulator()
    sim.reset(OperatingPoint(50 * RPM, 100e3))
    assert sim.weight_on_bit_for(sim.string_weight + 5e3) == 0.0
    assert sim.weight_on_bit_for(sim.string_weight - 5e3) == pytest.approx(5e3)
    sim.advance(1, hook_load=sim.string_weight + 5e3)
    assert sim.weight_on_bit == 0.0


@pytest.mark.parametrize("value", [True, np.True_, np.False_])
def test_a_bool_is_not_a_number_in_a_config(value):
    """pydantic's float takes NumPy bools as 1.0 / 0.0; a config field refuses them by
    name (a mask or flag typed where a density belongs)."""
    from drill_env.physics.config import ConfigError, SimulationConfig, replace

    with pytest.raises(ConfigError, match=r"^mud\.density: .*bool"):
        replace(SimulationConfig(), **{"mud.density": value})


def test_a_yaml_word_read_as_a_boolean_is_named_as_one(tmp_path):
    """An upgrade review: ``telemetry: no`` or ``bit_model: off`` in a YAML file was
    refused as "got False", with no word that YAML 1.1 (PyYAML) reads yes, no, on and off
    as booleans; a field that takes words now says so. A number's field does not (quoting
    the word would not help), nor a switch, which takes it."""
    import gymnasium as gym

    from drill_env.physics.config import ConfigError, SimulationConfig
    from drill_env.physics.validation import load_yaml

    hint = "(an unquoted yes, no, on or off in YAML is a boolean: quote it)"
    path = tmp_path / "physics.yml"
    path.write_text("bit_model: off\n", encoding="utf-8")
    with pytest.raises(ConfigError, match=r"^bit_model: Input should be 'mesoscopic' or "
                                          r"'macroscopic', got False \(an unquoted"):
        load_yaml(SimulationConfig, path)
    with pytest.raises(ValueError, match=r"^telemetry: must be one of .*got False " +
                                         re.escape(hint)):
        gym.make("DrillStickSlip-v0", telemetry=False)
    path.write_text("mud: {density: on}\n", encoding="utf-8")
    with pytest.raises(ConfigError, match=r"^mud\.density: ") as refused:
        load_yaml(SimulationConfig, path)
    assert hint not in str(refused.value)
    path.write_text("solver: {implicit_contacts: no}\n", encoding="utf-8")  # a switch
    assert load_yaml(SimulationConfig, path).solver.implicit_contacts is False


def test_a_list_given_whole_and_by_index_in_one_file_is_refused_by_what_to_do(tmp_path):
    """``rocks:`` as a list of dicts and ``rocks[0].mu_max`` beside it (one YAML file) was
    refused as "no section at index 0 of rocks (1 items)", which contradicts itself; it
    now says that the list is given twice and how to give it once. The list of sections
    and an index into it (Python's way) still apply both."""
    from drill_env.physics.config import ConfigError, SimulationConfig, replace
    from drill_env.physics.validation import flatten, jsonable

    config = SimulationConfig()
    rocks = jsonable(config)["formation"]["rocks"]
    with pytest.raises(ConfigError, match=r"^formation\.rocks\[0\]: rocks is given as a whole "
                                          r"list as well; set mu_max in that list's entry 0"):
        replace(config, **flatten({"formation": {"rocks": rocks, "rocks[0].mu_max": 0.5}}))
    both = replace(config, **{"formation.rocks": config.formation.rocks,
                              "formation.rocks[0].mu_max": 0.5})
    assert both.formation.rocks[0].mu_max == 0.5


@pytest.mark.parametrize("config", [{"mud.density": 1300.0}, {}])
def test_a_dict_for_the_config_is_refused_naming_what_takes_one(config):
    """``Simulator({"mud.density": 1300.0})`` ended in an AttributeError deep inside and
    ``Simulator({})`` built the defaults unsaid (a fuzzing walkthrough)."""
    with pytest.raises(TypeError, match=r"^config: a SimulationConfig, got dict; dotted "
                                        r"overrides: with_physics\(SimulationConfig\(\)"):
        Simulator(config)
