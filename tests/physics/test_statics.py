"""Static loads of the string (drill_env.physics.statics): component loads and depths, the
neutral point, pipe buckling and the mesh-refinement check, against hand sums and the
docstrings' rules."""

from __future__ import annotations

import re

import pytest

from drill_env.physics import components as cp
from drill_env.physics.config import INCH, Section, SimulationConfig, StringConfig, replace
from drill_env.physics.simulator import Simulator
from drill_env.physics.statics import component_loads, neutral_point_height, pipe_buckling


def test_each_component_bottom_is_the_string_length_less_what_hangs_below_it() -> None:
    config = SimulationConfig(string=cp.realistic_string())
    loads = component_loads(config, 100e3)  # bit first, drill pipe last
    assert len(loads) > 3
    below = 0.0
    for load in loads:
        assert load.bottom_depth == pytest.approx(config.string.length - below, abs=1e-9)
        below += load.length


def test_a_string_compressed_all_the_way_up_has_its_neutral_point_at_the_top() -> None:
    """The docstring's rule: the string length when every element is compressed."""
    config = SimulationConfig()
    assert neutral_point_height(config, 1e7) == pytest.approx(config.string.length)
    assert 0.0 < neutral_point_height(config, 100e3) < config.string.length
    assert neutral_point_height(config, 0.0) == 0.0


def test_the_top_section_is_checked_as_pipe_whatever_its_kind() -> None:
    """A drill pipe built without ``kind`` ("other") buckles at the same WOB as the
    default drill pipe: the top of a string is pipe."""
    pipe = SimulationConfig().string.drill_pipe
    unnamed = Section(length=pipe.length, outer_diameter=pipe.outer_diameter,
                      inner_diameter=pipe.inner_diameter, element_length=pipe.element_length)
    assert unnamed.kind != pipe.kind
    assert pipe_buckling(SimulationConfig(), 100e3)
    assert pipe_buckling(SimulationConfig(string=StringConfig(drill_pipe=unnamed)), 100e3)


def test_the_mesh_refinement_error_names_the_component_it_found_too_coarse() -> None:
    """Two collars, a coarse one (30 m elements) below a fine one: the coarse one trips the
    check first, and the message's ``components[k]`` is that component."""
    coarse = Section(length=60.0, outer_diameter=6.5 * INCH, inner_diameter=2.8 * INCH,
                     element_length=30.0, kind="collar", name="coarse DC")
    fine = Section(length=60.0, outer_diameter=6.5 * INCH, inner_diameter=2.8 * INCH,
                   element_length=1.0, kind="collar", name="fine DC")
    config = replace(SimulationConfig(string=StringConfig(components=(coarse, fine))),
                     **{"solver.lateral": True})
    sim = Simulator(config)
    with pytest.raises(ValueError) as err:
        sim.check_mesh_resolves(1.01 * sim.resolved_weight_on_bit)
    k = int(re.search(r"components\[(\d+)\]", str(err.value)).group(1))
    assert config.string.components[k].name == "coarse DC"
    assert f"({config.string.components[k].label}," in str(err.value)
