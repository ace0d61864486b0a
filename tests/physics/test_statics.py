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


def test_the_buckling_names_where_the_pipe_comes_nearest_to_buckling() -> None:
    """Vertical: the drill pipe's bottom element (the most compressed), its compression
    the WOB less the buoyed weight hanging below its midpoint, summed by hand. Horizontal
    well (a build of 90 deg over 600 m from 300 m, in one plane: the inclination grows
    linearly with measured depth): the pipe buckles first above 10 deg, where the
    vertical-hole limit holds, not in the lateral; the place says so (a directional
    driller read "29.8 kN" against the 100 kN of the lateral)."""
    import math

    config = SimulationConfig()
    string, g = config.string, 9.81
    pipe = string.drill_pipe
    [found] = pipe_buckling(config, 100e3)
    assert found.measured_depth == pytest.approx(pipe.length - 0.5 * pipe.element_length)
    assert found.inclination == 0.0 and found.place == f"at {found.measured_depth:.0f} m " \
        "measured depth"
    below = sum((s.density - config.mud.density) * s.area * g * s.length
                for s in string.sections[1:])
    below += (pipe.density - config.mud.density) * pipe.area * g * 0.5 * pipe.element_length
    steel = string.sections[-1].density  # the bit's, as the collar it hangs from
    below += config.bit.mass * g * (1.0 - config.mud.density / steel)
    assert found.compression == pytest.approx(100e3 - below, rel=1e-6)

    well = replace(config, well={"md": (0.0, 300.0, 900.0, 1400.0),
                                 "inclination": (0.0, 0.0, 90.0, 90.0),
                                 "azimuth": (45.0, 45.0, 45.0, 45.0)})
    [curved] = pipe_buckling(well, 100e3)
    assert 300.0 < curved.measured_depth < 900.0
    assert curved.inclination == pytest.approx(
        math.radians(90.0 * (curved.measured_depth - 300.0) / 600.0), rel=1e-6)
    assert curved.inclination < math.radians(10.0)  # the vertical-hole limit's last element
    assert curved.buckling_load == pytest.approx(found.buckling_load)  # Lubinski's, as there
    assert f"{math.degrees(curved.inclination):.1f} deg inclination" in curved.place
