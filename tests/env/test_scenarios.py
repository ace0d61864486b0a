"""Named scenarios: lookup, paper positions, randomised draws."""

import numpy as np
import pytest

from drill_env import scenarios
from drill_env.physics.formation import formation_arrays, front_shares
from drill_env.physics.simulator import Simulator


def test_unknown_scenario_raises_listing_known_names():
    with pytest.raises(ValueError) as err:
        scenarios.make_scenario("granite")
    for name in scenarios.SCENARIOS:
        assert name in str(err.value)


def test_unknown_scenario_parameter_is_named():
    with pytest.raises(ValueError, match="positoin"):
        scenarios.make_scenario("paper_case1", positoin="P2")


def test_every_named_scenario_builds_a_simulator():
    for name in scenarios.SCENARIOS:
        s = scenarios.make_scenario(name, rng=np.random.default_rng(0))
        sim = Simulator(s.config)
        assert sim.depth == pytest.approx(s.config.initial_depth)
        assert s.episode_duration > 0


@pytest.mark.parametrize("position", list(scenarios.POSITIONS))
def test_paper_case1_places_the_bit_at_its_rock_2_share(position):
    s = scenarios.paper_case1(position=position)
    share, _ = scenarios.POSITIONS[position]
    shares = front_shares(s.config.bit, formation_arrays(s.config.formation),
                          s.config.initial_depth)
    assert shares[1] == pytest.approx(share, abs=0.02)


def test_paper_cases_use_the_documented_bits_and_rocks():
    assert scenarios.paper_case2().config.formation.rocks[1] == scenarios.SOFT
    assert scenarios.paper_case3().config.formation.rocks[1] == scenarios.VERY_SOFT
    sym = scenarios.paper_case2().config.bit
    asym = scenarios.paper_case4().config.bit
    assert len(set(np.diff(sym.blade_angles))) == 1
    assert len(set(np.diff(asym.blade_angles))) > 1
    assert scenarios.default().config.formation.rocks == (scenarios.HARD,)


def test_string_length_changes_element_length_not_count():
    a = Simulator(scenarios.default(string_length=600.0).config)
    b = Simulator(scenarios.default().config)
    assert a.n_nodes == b.n_nodes
    assert a.config.string.length == pytest.approx(600.0)
    with pytest.raises(ValueError, match="string_length"):
        scenarios.default(string_length=20.0)


def test_random_scenario_is_reproducible_and_keeps_array_shapes():
    draws = [scenarios.random(np.random.default_rng(s)) for s in range(6)]
    again = [scenarios.random(np.random.default_rng(s)) for s in range(6)]
    assert draws == again
    sims = [Simulator(d.config) for d in draws]
    assert len({s.n_nodes for s in sims}) == 1
    assert len({s.rock_params.shape for s in sims}) == 1
    assert len({s.offsets.shape for s in sims}) == 1
    assert len({d.config for d in draws}) == len(draws)  # draws differ
    bits = {d.config.bit.blade_angles for d in [scenarios.random(np.random.default_rng(s))
                                                for s in range(20)]}
    assert len(bits) == 2  # symmetric and asymmetric both drawn


def test_evaluation_seeds_are_held_out_and_fixed():
    assert len(scenarios.EVALUATION_SEEDS) == len(set(scenarios.EVALUATION_SEEDS)) >= 10
    assert min(scenarios.EVALUATION_SEEDS) >= 1_000_000


def test_rock_presets_have_falling_to_flat_curves():
    h, s, v = scenarios.HARD, scenarios.SOFT, scenarios.VERY_SOFT
    assert h.mu_max - h.mu_min > s.mu_max - s.mu_min
    assert h.depth_of_cut < s.depth_of_cut < v.depth_of_cut
