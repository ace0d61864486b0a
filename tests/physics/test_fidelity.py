"""The fast fidelity level (SolverConfig.fidelity="fast") against the full model.

The fast level holds the drill pipe laterally straight, coarsens its elements and takes a
longer step (config.SimulationConfig.resolved). Its errors are measured here against
the full model: the first torsional frequency (eigenvalues, scipy) and the paper-case
stick-slip metrics (full simulations, slow-marked).
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
import scipy.linalg

from drill_env.physics.config import (
    FormationConfig,
    SimulationConfig,
    SolverConfig,
    replace,
)
from drill_env.physics.fem import from_band
from drill_env.physics.fidelity import FAST_PIPE_ELEMENT_LENGTH, FAST_TIME_STEP
from drill_env.physics.simulator import OperatingPoint, Simulator
from drill_env.physics.units import RPM
from drill_env.scenarios import HARD, make_scenario
from drill_env.tools.studies import simulate, stick_slip_summary


def fast(config: SimulationConfig) -> SimulationConfig:
    return replace(config, **{"solver.fidelity": "fast"})


def first_torsional_frequency(sim: Simulator) -> float:
    """First mode (Hz) of the simulator's own torsional matrices, top node fixed."""
    k = from_band(sim.tor_k)[1:, 1:]
    j = np.diag(sim.tor_m[1:])
    eig = scipy.linalg.eigh(k, j, eigvals_only=True, subset_by_index=[0, 0])
    return math.sqrt(eig[0]) / (2.0 * math.pi)


def test_fidelity_names_are_checked():
    with pytest.raises(ValueError, match="fidelity"):
        SolverConfig(fidelity="turbo")


def test_fast_level_resolves_into_a_straight_coarse_pipe_and_a_longer_step():
    cfg = fast(SimulationConfig()).resolved()
    assert cfg.solver.pipe_lateral is False
    assert cfg.string.drill_pipe.element_length == FAST_PIPE_ELEMENT_LENGTH
    assert cfg.string.bha == SimulationConfig().string.bha  # the BHA keeps its mesh
    assert SimulationConfig().resolved() == SimulationConfig()  # full: unchanged
    full, quick = Simulator(), Simulator(fast(SimulationConfig()))
    assert quick.dt > full.dt
    assert quick.n_nodes < full.n_nodes
    bha_nodes = SimulationConfig().string.bha.n_elements + 1
    assert quick.ul.shape == (2 * bha_nodes, 2)  # lateral DOFs in the BHA only
    assert quick.lateral_displacement.shape == (quick.n_nodes, 2)


def test_the_fast_level_keeps_explicit_contacts_unless_the_config_asks_for_implicit():
    """Explicit contacts at FAST_TIME_STEP, which the simulator shortens to
    FAST_CRITICAL_STEP_FRACTION of their critical step; a user's implicit contacts and
    longer step stay (docs/performance.md, "300 fresh seeds": at 10 ms the implicit ones
    add backward whirl at task 2's high rpm)."""
    level = fast(SimulationConfig()).resolved()
    assert level.solver.implicit_contacts is False
    assert level.solver.time_step == FAST_TIME_STEP
    assert Simulator(fast(SimulationConfig())).dt <= FAST_TIME_STEP
    asked = replace(SimulationConfig(), **{"solver.implicit_contacts": True,
                                           "solver.time_step": 0.01})
    assert fast(asked).resolved().solver.implicit_contacts is True
    assert Simulator(fast(asked)).dt == 0.01


@pytest.mark.slow
def test_the_fast_level_whirls_backward_as_the_full_model_does(tmp_path):
    """The drilling task's 20 held-out seeds under the stiff and SoftSpeed drives
    (scripts/whirl_study.py): on a few of them the BHA rolls into backward whirl for most
    of the 290 s window, a bistable outcome, so the test asks for the group's share, not
    a seed's. Full model 5.8 and 12.4 % (4 sustained whirls of 40), the fast level 9.9
    and 11.6 % (5; at 0.8 of the critical step, to 2026-12-04, 9.9 and 7.4 %, 4). Also
    the fast level with implicit contacts at 10 ms: 9.0 and 4.2 % (3; it passes here but
    adds whirl at task 2's high rpm, docs/performance.md, "300 fresh seeds"); with a
    starting wall contact rubbing with the smaller of its predicted and last normal
    forces (zero) instead of half the predicted one, 2.1 and 0.3 % (none), which fails
    here (physics/implicit_contact.py). Those shares are the per-sample whirl rule's; under
    the legs rule of 2026-12-05 (metrics.whirl_signs) the group means read 8.4 % (full),
    10.1 % (fast) and 6.3 % (fast, implicit 10 ms), with 4, 5 and 3 sustained whirls."""
    from agents.benchmark import run_benchmark
    from agents.settings import BenchmarkSettings

    implicit = {"solver.implicit_contacts": True, "solver.time_step": 0.010}
    for level, physics in (("full", None), ("fast", None), ("fast", implicit)):
        settings = BenchmarkSettings(duration=300.0, warmup=10.0, fidelity=level,
                                     physics=physics or {})
        name = level + ("_implicit" if physics else "")
        rows = run_benchmark(["stiff", "soft-speed"], ["random"],
                             list(range(1_000_000, 1_000_020)), tmp_path / name, settings,
                             workers=2, progress=False, env_id="DrillOptimise-v0")
        shares = [row["backward_whirl_fraction"] for row in rows]
        sustained = sum(share > 0.3 for share in shares)
        print(f"{name}: mean backward whirl share {np.mean(shares):.3f}, {sustained} of "
              f"{len(shares)} episodes whirling over 30 % of the window")
        assert len(shares) == 40
        assert np.mean(shares) > 0.04, name


@pytest.mark.parametrize("scenario", ["default", "paper_case1", "paper_case2"])
def test_fast_level_keeps_the_first_torsional_frequency_within_0_1_percent(scenario):
    """The first speed issue asked for 2 %; the 20 m elements' h^2 error is ~3e-5
    (fidelity.FAST_PIPE_ELEMENT_LENGTH claims 0.1 %, held here)."""
    config = make_scenario(scenario).config
    f_full = first_torsional_frequency(Simulator(config))
    f_fast = first_torsional_frequency(Simulator(fast(config)))
    print(f"{scenario}: full {f_full:.4f} Hz, fast {f_fast:.4f} Hz")
    assert f_fast == pytest.approx(f_full, rel=1e-3)


def test_fast_level_bha_whirls_against_the_wall_like_the_full_model():
    """The BHA keeps its lateral FE model: a throw at a span reaches the wall in both."""
    peaks = []
    for config in (SimulationConfig(), fast(SimulationConfig())):
        sim = Simulator(config)
        sim.reset(OperatingPoint(60 * RPM, 30e3))
        height = sim.node_depth[-1] - sim.node_depth[sim.lateral_start:]
        span = (height > 10.0 + 1e-9) & (height < 19.0 - 1e-9)
        sim.vl[0::2, 0][span] = 2.0 * np.sin(math.pi * (height[span] - 10.0) / 9.0)
        peak = 0.0
        for _ in range(100):
            sim.advance(1)
            peak = max(peak, float(np.max(sim.contact_forces[:-1])))
        assert sim.status == 0
        peaks.append(peak)
    assert peaks[0] > 0.0 and peaks[1] > 0.0
    assert peaks[1] == pytest.approx(peaks[0], rel=0.25)


def test_fast_level_warns_when_the_straight_pipe_would_be_compressed():
    sim = Simulator(fast(SimulationConfig()))  # 35 m BHA: ~40 kN buoyed
    with pytest.warns(RuntimeWarning, match="compression"):
        sim.reset(OperatingPoint(60 * RPM, 100e3))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        Simulator(fast(SimulationConfig())).reset(OperatingPoint(60 * RPM, 20e3))
        case2 = make_scenario("paper_case2")  # 120 m of collars carry the 75 kN
        Simulator(fast(case2.config)).reset(OperatingPoint(50 * RPM, case2.weight_on_bit))
    # one text whatever the WOB: Python's default filter shows it once per place, not once
    # per drawn WOB (a task on a curved well printed one per episode)
    texts = set()
    for wob in (90e3, 100e3, 110e3):
        with pytest.warns(RuntimeWarning, match="compression") as caught:
            Simulator(fast(SimulationConfig())).reset(OperatingPoint(60 * RPM, wob))
        texts |= {str(w.message) for w in caught if "compression" in str(w.message)}
    assert len(texts) == 1


# --------------------------------------------------------------------------- stick-slip


def assert_within_10_percent(full: dict, quick: dict, label: str) -> None:
    """SSI within 10 %; the stuck fraction (a share of time) within 10 % or 3 points.

    The absolute floor matters where the bit barely sticks (2-4 % of the time in case 2):
    there the stuck fraction of the full model itself moves by a few points between two
    kick amplitudes (docs/performance.md).
    """
    print(f"{label}: full {full}, fast {quick}")
    assert quick["ssi"] == pytest.approx(full["ssi"], rel=0.10)
    assert quick["stuck_fraction"] == pytest.approx(full["stuck_fraction"], rel=0.10,
                                                    abs=0.03)


@pytest.mark.slow
def test_fast_level_stick_slip_of_the_torsional_case_within_10_percent():
    """Paper Fig. 13: hard rock, 50 rpm, 100 kN, stiff top drive, torsion only."""
    config = SimulationConfig(formation=FormationConfig(rocks=(HARD,)),
                              solver=SolverConfig(lateral=False))
    full = stick_slip_summary(simulate(config, 50.0, 100e3, 60.0), 30.0)
    quick = stick_slip_summary(simulate(fast(config), 50.0, 100e3, 60.0), 30.0)
    assert full["ssi"] > 0.8  # there is stick-slip to compare
    assert_within_10_percent(full, quick, "torsional hard 50 rpm")


@pytest.mark.slow
@pytest.mark.parametrize("position", ["P1", "P2", "P5"])
def test_fast_level_stick_slip_of_paper_case1_within_10_percent(position):
    """Positions where the full model oscillates (P3/P4 damp out: nothing to compare)."""
    sc = make_scenario("paper_case1", position=position)
    full = stick_slip_summary(simulate(sc.config, 50.0, sc.weight_on_bit, 60.0), 30.0)
    quick = stick_slip_summary(simulate(fast(sc.config), 50.0, sc.weight_on_bit, 60.0), 30.0)
    assert_within_10_percent(full, quick, f"paper case 1 at {position}")


@pytest.mark.slow
@pytest.mark.parametrize("case", ["paper_case2", "paper_case4"])
def test_fast_level_stick_slip_of_the_lateral_paper_cases_within_10_percent(case):
    """Coupled cases on the 120 m collar BHA, stick-slip window 30-90 s of the crossing.

    Case 3 (very soft layer) is left out: there the full model's own SSI moves by ~30 %
    when only the initial kick changes from 1 % to 2 % (docs/performance.md), so a 10 %
    comparison would measure chaos, not the fidelity level.
    """
    sc = make_scenario(case)
    full = stick_slip_summary(simulate(sc.config, 50.0, sc.weight_on_bit, 90.0), 30.0)
    quick = stick_slip_summary(simulate(fast(sc.config), 50.0, sc.weight_on_bit, 90.0), 30.0)
    assert full["ssi"] > 0.8
    assert_within_10_percent(full, quick, case)


def test_the_fast_level_keeps_the_pipe_element_above_the_bha_as_a_rotational_spring():
    """Held straight, the drill pipe leaves its lowest element on the BHA's top node as a
    rotational spring: the node pinned laterally, its tilt held by the Hermite element's
    tilt-tilt terms with the far end clamped, 4 EI / L elastic and 2 N L / 15 geometric
    (Przemieniecki), added to those of the BHA element below it."""
    config = SimulationConfig(solver=SolverConfig(fidelity="fast"))
    sim = Simulator(config)
    top = sim.lateral_start  # the BHA's top node: element top - 1 above it, top below
    assert top == config.resolved().string.drill_pipe.n_elements > 0
    mesh = sim.mesh
    tilt_elastic = sum(4.0 * mesh.bending_stiffness[e] / mesh.element_length[e]
                       for e in (top - 1, top))
    tilt_geometric = sum(2.0 * sim.axial_weight[e] * mesh.element_length[e] / 15.0
                         for e in (top - 1, top))
    assert mesh.element_length[top - 1] >= FAST_PIPE_ELEMENT_LENGTH - 1e-9  # coarse pipe
    assert sim.lat_k[0, 1] == pytest.approx(tilt_elastic, rel=1e-12)  # band[0, i] = A[i, i]
    assert sim.lat_kg_weight[0, 1] == pytest.approx(tilt_geometric, rel=1e-12)
    assert sim.lat_k[0, 0] == 0.0 and sim.lat_m[0] == 1.0  # the node pinned laterally
