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
    default drill pipe, and 14 km of it is past S-135's allowable tension as the named
    pipe is (``over_allowable_tension``'s docstring): the top of a string is pipe."""
    from drill_env.physics.statics import over_allowable_tension

    pipe = SimulationConfig().string.drill_pipe
    unnamed = Section(length=pipe.length, outer_diameter=pipe.outer_diameter,
                      inner_diameter=pipe.inner_diameter, element_length=pipe.element_length)
    assert unnamed.kind != pipe.kind
    assert pipe_buckling(SimulationConfig(), 100e3)
    assert pipe_buckling(SimulationConfig(string=StringConfig(drill_pipe=unnamed)), 100e3)
    for top in (replace(pipe, length=14e3), replace(unnamed, length=14e3)):
        over = over_allowable_tension(SimulationConfig(string=StringConfig(drill_pipe=top)),
                                      0.0)
        assert [o.component for o in over] == [top.label]


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


def test_a_string_past_the_allowable_tension_of_s135_pipe_is_named_at_its_length() -> None:
    """The default scenario's string lengthened: the drill pipe's static tension at the
    top, the buoyed weight of everything below it less the WOB (Archimedes, summed here
    from the sections' diameters and densities), reaches API RP 7G's allowable load of
    S-135 pipe (0.9 x 135,000 psi x the body's area) at a length solved by hand; 20 m
    shorter the string passes, 20 m longer the drill pipe is named, and only it."""
    import math

    from drill_env.physics.statics import over_allowable_tension
    from drill_env.physics.units import GRAVITY
    from drill_env.scenarios import make_scenario

    base = make_scenario("default").config
    lower = cp.realistic_string(1250.0).lower
    mud, wob = base.mud.density, 100e3

    def buoyed(section) -> float:  # per metre (N/m)
        area = math.pi / 4 * (section.outer_diameter ** 2 - section.inner_diameter ** 2)
        return area * (section.density - mud) * GRAVITY

    below = sum(buoyed(s) * s.length for s in lower) \
        + base.bit.mass * GRAVITY * (1.0 - mud / lower[0].density)
    pipe = cp.realistic_string(1250.0).drill_pipe
    pipe_area = math.pi / 4 * (pipe.outer_diameter ** 2 - pipe.inner_diameter ** 2)
    allowable = 0.9 * 135_000 * 6894.757 * pipe_area  # psi to Pa
    length = sum(s.length for s in lower) + (allowable + wob - below) / buoyed(pipe)
    assert length == pytest.approx(12_650.0, abs=50.0)  # docs/model.md: 12.65 km
    for extra, named in ((-20.0, []), (20.0, [pipe.label])):
        config = replace(base, string=cp.realistic_string(length + extra))
        over = over_allowable_tension(config, wob)
        assert [o.component for o in over] == named
        for o in over:
            assert o.allowable == pytest.approx(allowable, rel=1e-12)
            assert o.tension == pytest.approx(allowable + 20.0 * buoyed(pipe), rel=1e-9)
