"""Modal analysis: the eigenvalues of the assembled matrices, the closed forms of the FE
validation, the damping ratio against its perturbation estimate, the critical speeds."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg
from reference_solutions import transfer_matrix_frequencies
from scipy.optimize import brentq

from drill_env.physics import components as cp
from drill_env.physics.config import (
    BitConfig,
    DampingConfig,
    MudConfig,
    Section,
    SimulationConfig,
    StringConfig,
    replace,
)
from drill_env.physics.fem import assemble_lateral, assemble_torsion, build_mesh
from drill_env.physics.modes import (
    _lateral_system,
    critical_speeds,
    excitation_label,
    excitations,
    lateral_buckling_weight,
    lateral_modes,
    torsional_modes,
    torsional_system,
    undamped_frequencies,
)
from drill_env.scenarios import make_scenario, with_physics

UNDAMPED = {"mud.torsional_damping": 0.0, "damping.stiffness_proportional": 0.0,
            "damping.mass_proportional": 0.0}


def test_torsional_modes_are_the_eigenvalues_of_the_assembled_matrices():
    config = replace(SimulationConfig(string=cp.realistic_string()), **UNDAMPED)
    modes = torsional_modes(config, "fixed", 5)
    mesh = build_mesh(config)
    k, j = assemble_torsion(mesh)
    j[-1] += config.bit.inertia
    w2 = scipy.linalg.eigh(k[1:, 1:], np.diag(j[1:]), eigvals_only=True)[:5]
    np.testing.assert_allclose(modes.frequency, np.sqrt(w2) / (2 * math.pi), rtol=1e-9)
    np.testing.assert_allclose(modes.damping_ratio, 0.0, atol=1e-9)


def test_first_torsional_mode_of_the_paper_string_is_the_shaft_with_end_inertia():
    """SPEC section 3: 1000 m of 5 in pipe over 35 m of 6 1/2 in collars, fixed top: the
    BHA (short and stiff) acts as an end inertia on the pipe shaft:
    cot(w L / c) = (J_BHA w) / (Z) ... solved here in the form tan(kL) kL = J_pipe / J_end.
    Its shape over the pipe is sin(k s) / sin(k L) of the bit's angle (s down from the
    top), scaled to max |.| = 1 (``Modes.shapes``)."""
    config = replace(SimulationConfig(), **UNDAMPED)
    pipe, bha = config.string.drill_pipe, config.string.bha
    j_pipe = pipe.density * pipe.polar_moment * pipe.length
    j_end = bha.density * bha.polar_moment * bha.length + config.bit.inertia
    x = brentq(lambda x: x * math.tan(x) - j_pipe / j_end, 1e-6, math.pi / 2 - 1e-9)
    f = x / pipe.length * pipe.torsional_wave_speed / (2 * math.pi)
    modes = torsional_modes(config, "fixed", 1)
    assert modes.frequency[0] == pytest.approx(f, rel=0.01)
    assert f == pytest.approx(0.66, abs=0.01)
    depth = modes.node_depth
    on_pipe = depth <= pipe.length + 1e-9
    # the BHA's own twist (the end inertia taken as rigid) is ~0.1 % of the bit's angle
    np.testing.assert_allclose(modes.shapes[0, on_pipe],
                               np.sin(x * depth[on_pipe] / pipe.length) / math.sin(x),
                               atol=3e-3)
    assert np.max(np.abs(modes.shapes[0])) == pytest.approx(1.0, rel=1e-12)


def test_lateral_modes_are_the_eigenvalues_of_the_assembled_matrices():
    config = replace(SimulationConfig(string=cp.realistic_string()), **UNDAMPED)
    wob = 40e3  # the string pinned only at the top buckles at ~51 kN
    modes = lateral_modes(config, wob, supports="top_only", n_modes=4, region="string")
    mesh = build_mesh(config)
    from drill_env.physics.fem import axial_force_profile
    from drill_env.physics.statics import bit_buoyed_weight

    k, kg, m = assemble_lateral(mesh, axial_force_profile(mesh, wob,
                                                          bit_buoyed_weight(config)))
    m[-2] += config.bit.mass
    free = np.arange(1, 2 * mesh.n_nodes - 1)  # top w pinned, bit tilt held
    expected = undamped_frequencies((k + kg)[np.ix_(free, free)], m[free], 5)
    expected = expected[expected > 1e-4][:4]  # a hanging string's near-neutral pendulum mode
    # The first-order eigenproblem spans stiffness ratios of ~1e12 (tilt DOFs of 1 m collar
    # elements vs a 1 km pendulum): the slowest modes keep ~7 digits, hence 1e-5.
    np.testing.assert_allclose(modes.frequency, expected, rtol=1e-5)


def _pinned_collar() -> tuple[cp.Section, SimulationConfig]:
    """A 6 m collar of 0.3 m elements below 1 m of collar, no mud, a massless bit free to
    tilt: pinned at its top and at the bit by ``supports="stabilizers"``."""
    collar = cp.collar_6_5(6.0, 0.3)
    string = StringConfig(drill_pipe=cp.collar_6_5(1.0, 0.5), components=(collar,))
    return collar, SimulationConfig(string=string, mud=MudConfig(density=0.0),
                                    bit=BitConfig(axis_aligned=False, mass=1e-6,
                                                  inertia=1e-6))


def test_lateral_modes_of_a_short_collar_are_the_pinned_pinned_beam():
    """A 6 m collar, pinned at the top and at the (tilt-free) bit, no mud: Euler-Bernoulli
    w_n = (n pi / L)^2 sqrt(EI / rho A); its own weight (7 kN of tension against a 2 MN
    buckling load) moves the frequencies by < 0.2 %. The shapes are the sines
    sin(n pi x / L) over the nodes, scaled to max |.| = 1 (``Modes.shapes``)."""
    collar, config = _pinned_collar()
    config = dataclasses.replace(config, damping=DampingConfig(mass_proportional=0.0,
                                                               stiffness_proportional=0.0))
    modes = lateral_modes(config, 0.0, supports="stabilizers", n_modes=3, region="bha")
    ei = collar.youngs_modulus * collar.second_moment
    rho_a = collar.density * collar.area
    expected = [(n * math.pi / collar.length) ** 2 * math.sqrt(ei / rho_a) / (2 * math.pi)
                for n in (1, 2, 3)]
    np.testing.assert_allclose(modes.frequency, expected, rtol=0.01)
    x = modes.node_depth - modes.node_depth[0]  # from the top pin
    for n, shape in enumerate(modes.shapes, start=1):
        sine = np.sin(n * math.pi * x / collar.length)
        sine /= np.max(np.abs(sine))  # (each sine's peaks fall on nodes of 0.3 m)
        np.testing.assert_allclose(shape * np.sign(shape @ sine), sine, atol=2e-3)


def test_a_string_of_pipe_alone_is_analysed_below_its_lowest_joint():
    """``bha_top_node`` with no BHA kind below the pipe (a 6 m heavy-weight section under
    the top section): ``region="bha"`` keeps the lowest section, pinned at its top and at
    the bit, the pinned-pinned beam of Euler-Bernoulli as above (not the bit's node
    alone)."""
    heavy = cp.heavy_weight_5(6.0, 0.3)
    config = SimulationConfig(string=StringConfig(drill_pipe=cp.collar_6_5(1.0, 0.5),
                                                  components=(heavy,)),
                              mud=MudConfig(density=0.0),
                              bit=BitConfig(axis_aligned=False, mass=1e-6, inertia=1e-6),
                              damping=DampingConfig(mass_proportional=0.0,
                                                    stiffness_proportional=0.0))
    modes = lateral_modes(config, 0.0, supports="stabilizers", n_modes=1, region="bha")
    ei = heavy.youngs_modulus * heavy.second_moment
    expected = (math.pi / heavy.length) ** 2 * math.sqrt(ei / (heavy.density * heavy.area))
    assert modes.frequency[0] == pytest.approx(expected / (2 * math.pi), rel=0.01)
    assert modes.node_depth[-1] - modes.node_depth[0] == pytest.approx(heavy.length)


def test_a_stabilizer_halfway_makes_two_spans_of_the_continuous_beam():
    """A 12 m collar pinned at its top, at a stabilizer 6 m above the bit and at the bit:
    the continuous beam over three pins. Its modes (Euler-Bernoulli, w = (beta L)^2
    sqrt(EI / rho A) / L^2 per span) alternate: antisymmetric about the middle pin, each
    span pinned-pinned (beta L = pi, 2 pi), and symmetric, the middle pin acting as a
    clamp on each span (pinned-clamped: tan(beta L) = tanh(beta L), beta L = 3.9266)."""
    collar = cp.collar_6_5(12.0, 0.3)
    string = StringConfig(drill_pipe=cp.collar_6_5(1.0, 0.5), bha=collar, stabilizers=(6.0,))
    config = SimulationConfig(string=string, mud=MudConfig(density=0.0),
                              bit=BitConfig(axis_aligned=False, mass=1e-6, inertia=1e-6),
                              damping=DampingConfig(mass_proportional=0.0,
                                                    stiffness_proportional=0.0))
    modes = lateral_modes(config, 0.0, supports="stabilizers", n_modes=3, region="bha")
    root = float(brentq(lambda x: math.tan(x) - math.tanh(x), 3.5, 4.5))
    ei = collar.youngs_modulus * collar.second_moment
    rho_a = collar.density * collar.area
    expected = [(bl / 6.0) ** 2 * math.sqrt(ei / rho_a) / (2 * math.pi)
                for bl in (math.pi, root, 2 * math.pi)]
    np.testing.assert_allclose(modes.frequency, expected, rtol=0.005)


def test_lateral_rayleigh_damping_acts_on_the_elastic_stiffness_under_load():
    """The pinned collar at half its Euler load, Rayleigh damping a M + b K_e: the sine
    modes diagonalise M, K_e and K_g alike, so w_n^2 = w_e,n^2 (1 - P / P_n) with
    P_n = n^2 P_Euler and zeta_n = (a + b w_e,n^2) / (2 w_n): the compression softens
    the mode, not the material damping (Rayleigh on K + K_g would under-damp it)."""
    collar, config = _pinned_collar()
    a, b = 0.5, 2.0e-4
    config = dataclasses.replace(config, damping=DampingConfig(mass_proportional=a,
                                                               stiffness_proportional=b))
    euler = math.pi ** 2 * collar.youngs_modulus * collar.second_moment / collar.length ** 2
    load = 0.5 * euler
    modes = lateral_modes(config, load, supports="stabilizers", n_modes=2, region="bha")
    ei = collar.youngs_modulus * collar.second_moment
    rho_a = collar.density * collar.area
    for n in (1, 2):
        w_e = (n * math.pi / collar.length) ** 2 * math.sqrt(ei / rho_a)
        w_d_squared = w_e ** 2 * (1.0 - load / (n * n * euler))  # undamped, loaded
        zeta = (a + b * w_e ** 2) / (2.0 * math.sqrt(w_d_squared))
        # |lambda| of the damped pair is the undamped w_n; the collar's own weight and
        # the mesh move it by < 1 %
        assert modes.frequency[n - 1] == pytest.approx(math.sqrt(w_d_squared) / (2 * math.pi),
                                                       rel=0.01)
        assert modes.damping_ratio[n - 1] == pytest.approx(zeta, rel=0.01)


def test_the_modal_analysis_takes_vertical_holes_only():
    """Survey noise (0.4 deg, and up to ``VERTICAL_NOISE``, 0.5 deg) passes; 1 deg is a
    deviated hole, refused naming ``well``."""
    config = SimulationConfig()
    for steepest, refused in ((0.4, False), (0.5, False), (1.0, True)):
        well = {"md": (0.0, 500.0, 1200.0), "inclination": (0.0, steepest, steepest),
                "azimuth": (0.0, 0.0, 0.0)}
        deviated = replace(config, well=well)
        if refused:
            with pytest.raises(ValueError, match="^well: the modal analysis is for vertical"):
                lateral_modes(deviated, 0.0, n_modes=1)
        else:
            assert len(lateral_modes(deviated, 0.0, n_modes=1).frequency) == 1
    # a well that bends only below the string (1,035 m) is vertical along it: the string
    # hangs in a vertical hole, as the config's warning says (refused before: a fuzz)
    below = replace(config, well={"md": (0.0, 1100.0, 1101.0), "inclination": (0.0, 0.0, 60.0),
                                  "azimuth": (0.0, 0.0, 0.0)})
    vertical = lateral_modes(config, 0.0, n_modes=1).frequency
    assert lateral_modes(below, 0.0, n_modes=1).frequency == pytest.approx(vertical, rel=1e-9)


def test_overdamped_motions_are_not_modes():
    """``_damped`` keeps the oscillating roots only: a 1-DOF system at zeta = 1.5 has none;
    two uncoupled DOFs, one at zeta = 0.05 (w = 10 rad/s) and one at zeta = 2.5, give the
    first alone, at |lambda| = w and -Re(lambda) / |lambda| = zeta (closed form)."""
    from drill_env.physics.modes import _damped

    freq, zeta, _ = _damped(np.array([[1.0]]), np.array([[3.0]]), np.array([1.0]), 3)
    assert len(freq) == 0
    k = np.array([[100.0, 0.0], [0.0, 1.0]])
    c = np.array([[1.0, 0.0], [0.0, 5.0]])  # zeta 0.05 and 2.5
    freq, zeta, _ = _damped(k, c, np.array([1.0, 1.0]), 3)
    np.testing.assert_allclose(freq, [10.0 / (2 * math.pi)], rtol=1e-12)
    np.testing.assert_allclose(zeta, [0.05], rtol=1e-12)


def test_the_overdamped_modes_dropped_are_reported_with_their_damping():
    """The two uncoupled DOFs above: the one at zeta = 2.5 (w = 1 rad/s) is reported
    as overdamped, at its undamped frequency and damping (closed form, zeta = c / 2 w),
    being below the one listed, and so is one at zeta = 1 (``overdamped_modes``: "at
    least 1"); under mass-proportional damping alone a string's lowest
    lateral modes are overdamped where a / (2 w) >= 1, and exactly those (and no
    oscillating one) are reported, each at its undamped frequency."""
    from drill_env.physics.modes import overdamped_modes, undamped_frequencies

    k = np.array([[100.0, 0.0], [0.0, 1.0]])
    c = np.array([[1.0, 0.0], [0.0, 5.0]])
    slow, ratio = overdamped_modes(k, c, np.array([1.0, 1.0]), 10.0 / (2 * math.pi))
    np.testing.assert_allclose(slow, [1.0 / (2 * math.pi)], rtol=1e-12)
    np.testing.assert_allclose(ratio, [2.5], rtol=1e-12)
    # critically damped (zeta = c / 2 w = 1: a double real root, which _damped drops too)
    slow, ratio = overdamped_modes(k, np.array([[1.0, 0.0], [0.0, 2.0]]),
                                   np.array([1.0, 1.0]), 10.0 / (2 * math.pi))
    np.testing.assert_allclose(slow, [1.0 / (2 * math.pi)], rtol=1e-12)
    np.testing.assert_allclose(ratio, [1.0], rtol=1e-12)
    a = 3.0  # 1/s: overdamps the modes below a / 2 rad/s = 0.24 Hz
    config = replace(make_scenario("default").config,
                     **{"damping.mass_proportional": a, "damping.stiffness_proportional": 0.0})
    modes = lateral_modes(config, 0.0, n_modes=3, region="string", supports="top_only")
    assert len(modes.overdamped) > 0
    np.testing.assert_allclose(modes.overdamped_ratio,
                               a / (2 * 2 * math.pi * modes.overdamped), rtol=1e-6)
    assert np.all(modes.overdamped < a / 2 / (2 * math.pi))
    assert np.all(modes.frequency > modes.overdamped.max())  # none listed is overdamped
    k, kg, m, free, _, _ = _lateral_system(config.resolved(), 0.0, "top_only", "string")
    lowest = undamped_frequencies((k + kg)[np.ix_(free, free)], m[free],
                                  len(modes.overdamped))
    np.testing.assert_allclose(modes.overdamped, lowest, rtol=1e-6)


def test_a_stabilizer_component_is_a_support_whatever_its_blade_diameter():
    """BHA analysis pins the stabilizers. A component of kind stabilizer with blades
    1/8 in smaller than ``string.stabilizer_diameter`` (which places the legacy extra
    stabilizers) was not found, so its span went unpinned: the lowest lateral mode fell
    by a fifth and the BHA's buckling WOB by 13 % (a drilling engineer's walkthrough).
    The blade diameter does not move a pin: the modes are the same."""
    from drill_cli.configs import read_overrides

    field = read_overrides(Path(__file__).parents[2] / "examples" / "field_well_string.yaml")
    base = with_physics(make_scenario("default").config, field)
    gauge = base.string.stabilizer_diameter
    found = []
    for blades in (gauge, gauge - 0.125 * 0.0254):
        components = tuple(dataclasses.replace(c, contact_diameter=blades)
                           if c.kind == "stabilizer" else c for c in base.string.components)
        config = replace(base, **{"string.components": components})
        found.append(lateral_modes(config, 40e3, n_modes=3, region="bha").frequency)
    np.testing.assert_allclose(found[0], found[1], rtol=1e-9)


def test_lateral_buckling_weight_of_a_pinned_collar_is_eulers_load():
    """Euler: P_cr = pi^2 EI / L^2 for a pinned-pinned column; the collar's own 7 kN of
    weight relieves its top by up to 7 kN against ~2 MN (< 0.4 %)."""
    collar, config = _pinned_collar()
    euler = math.pi ** 2 * collar.youngs_modulus * collar.second_moment / collar.length ** 2
    assert lateral_buckling_weight(config, region="bha") == pytest.approx(euler, rel=5e-3)


def test_the_bha_buckles_only_with_lateral_motion_and_a_wall():
    """``bha_buckles``: past Euler's load the pinned collar buckles, but not in a model
    without lateral motion or without a wall (its docstring): the note ``run`` prints."""
    from drill_env.physics.modes import bha_buckles

    collar, config = _pinned_collar()
    euler = math.pi ** 2 * collar.youngs_modulus * collar.second_moment / collar.length ** 2
    # the collar's own weight moves the load by < 0.4 % (the test above)
    assert not bha_buckles(config, 0.98 * euler)
    assert bha_buckles(config, 1.02 * euler)
    for off in ({"contact.enabled": False}, {"solver.lateral": False}):
        assert not bha_buckles(replace(config, **off), 1.02 * euler), off


def test_mud_loads_the_lateral_mass_with_its_inner_column_and_added_mass():
    """The pinned collar in 1200 kg/m^3 mud: Euler-Bernoulli with the mass per metre
    rho A + rho_mud A_in + C_a rho_mud A_out (steel, mud carried inside, displaced mud
    dragged along; Blevins, Formulas for Natural Frequency, added mass of a cylinder:
    C_a = 1)."""
    collar, dry = _pinned_collar()
    config = replace(dry, **{"mud.density": 1200.0, "mud.added_mass_coefficient": 1.0})
    a_in = math.pi / 4 * collar.inner_diameter ** 2
    a_out = math.pi / 4 * collar.outer_diameter ** 2
    m_eff = collar.density * collar.area + 1200.0 * a_in + 1.0 * 1200.0 * a_out
    ei = collar.youngs_modulus * collar.second_moment
    expected = (math.pi / collar.length) ** 2 * math.sqrt(ei / m_eff) / (2 * math.pi)
    modes = lateral_modes(config, 0.0, n_modes=1, region="bha")
    # the mud's buoyancy takes ~85 % of the 7 kN tension away: < 0.1 % on f
    assert modes.frequency[0] == pytest.approx(expected, rel=2e-3)
    assert modes.frequency[0] < 0.95 * lateral_modes(dry, 0.0, n_modes=1,
                                                     region="bha").frequency[0]


def _hanging_pipe(element_length: float, tilt_held: bool
                  ) -> tuple[SimulationConfig, float, float]:
    """600 m of 5 in drill pipe (2 m of it as the "BHA", no stabilizers) hanging in air
    over a massless bit: the config, and the heavy column's units of length
    (EI / w)^(1/3) and force (EI w^2)^(1/3), w the steel weight per metre."""
    from drill_env.physics.config import Section

    pipe = Section(length=600.0, outer_diameter=0.127, inner_diameter=0.1086,
                   element_length=element_length)
    string = StringConfig(drill_pipe=pipe, bha=dataclasses.replace(pipe, length=2.0),
                          stabilizers=())
    config = SimulationConfig(string=string, mud=MudConfig(density=0.0),
                              bit=BitConfig(axis_aligned=tilt_held, mass=1e-6, inertia=1e-6))
    ei = pipe.youngs_modulus * pipe.second_moment
    w = pipe.density * pipe.area * 9.80665
    return config, (ei / w) ** (1 / 3), (ei * w * w) ** (1 / 3)


def test_a_heavy_hanging_pipe_buckles_at_the_airy_load():
    """A long vertical pipe hanging from the top, WOB at its lower end: the compressed
    bottom buckles where EI y'''' + (N y')' = 0 with N = w s - W (s up from the bit), the
    Airy equation, has its first solution: W_cr = a (EI w^2)^(1/3), a the first zero of
    Ai' (1.01879) for a free bottom and of Ai (2.33811) for a bottom held vertical (the
    bit's tilt fixed). No mud: w is the steel weight per metre."""
    from scipy.special import ai_zeros

    zeros, zeros_prime, _, _ = ai_zeros(1)
    for tilt_held, a in ((False, -zeros_prime[0]), (True, -zeros[0])):
        config, _, unit_force = _hanging_pipe(2.0, tilt_held)
        found = lateral_buckling_weight(config, supports="top_only", region="string")
        assert found == pytest.approx(a * unit_force, rel=5e-3), tilt_held


def _heavy_column_load(bottom: str, length: float) -> float:
    """The first buckling load of a hanging column of ``length`` (in units of (EI/w)^(1/3))
    under a WOB at its lower end, in units of (EI w^2)^(1/3): y'''' = ((x - W) y')' in
    x = s (w / EI)^(1/3) (tension stiffens it), y = y' = 0 at the top; solved by scipy's
    collocation BVP solver with W as the unknown."""
    from scipy.integrate import solve_bvp

    x = np.linspace(0.0, length, 2000)
    bottoms = {"hinged": lambda ya, p: [ya[0], ya[2], ya[1] - 1.0],  # y = y'' = 0, y' = 1
               "free": lambda ya, p: [ya[2], ya[3] + p[0] * ya[1], ya[0] - 1.0]}

    def fun(s, y, p):
        return np.vstack([y[1], y[2], y[3], (s - p[0]) * y[2] + y[1]])

    def bc(ya, yb, p):
        bottom_conditions = bottoms[bottom](ya, p)
        return np.array([*bottom_conditions[:2], yb[0], yb[1], bottom_conditions[2]])

    guess = np.vstack([np.exp(-x), -np.exp(-x), np.exp(-x), -np.exp(-x)])
    solution = solve_bvp(fun, bc, x, guess, p=[1.5], tol=1e-8, max_nodes=200_000)
    assert solution.success
    return float(solution.p[0])


def test_a_heavy_pipe_pinned_at_the_bit_buckles_at_the_heavy_column_load():
    """The hinged bottom (bit pinned, free to tilt), the case of Lubinski's 1950
    coefficient that ``statics.pipe_buckling`` uses (1.94). Unlike a free bottom (Ai':
    1.0188 whatever the length), the pin's reaction decays only as 1/x up the string, so
    the load falls slowly with the length: 1.88 (EI w^2)^(1/3) at 10 units of (EI/w)^(1/3)
    (close to Lubinski's), 1.62 at the 36 units of 600 m of 5 in pipe. The FE string,
    pinned at the bit with no stabilizers, finds the collocation solution's load."""
    from drill_env.physics.statics import LUBINSKI

    assert _heavy_column_load("free", 10.0) == pytest.approx(1.01879, rel=1e-4)
    assert _heavy_column_load("hinged", 10.0) == pytest.approx(LUBINSKI, rel=0.04)
    config, unit_length, unit_force = _hanging_pipe(1.0, tilt_held=False)
    hinged = _heavy_column_load("hinged", config.string.length / unit_length)
    found = lateral_buckling_weight(config, supports="stabilizers", region="string")
    assert found == pytest.approx(hinged * unit_force, rel=5e-3)


def test_lateral_modes_refuse_a_buckled_string_and_a_deviated_hole():
    """Near the buckling load the first mode softens towards zero (f^2 ~ 1 - P / P_cr);
    past it the modes of the straight string do not exist, and the analysis says so."""
    _, config = _pinned_collar()
    limit = lateral_buckling_weight(config, region="bha")
    f0 = lateral_modes(config, 0.0, n_modes=1, region="bha").frequency[0]
    near = lateral_modes(config, 0.99 * limit, n_modes=1, region="bha").frequency[0]
    assert near < 0.15 * f0
    with pytest.raises(ValueError, match="weight_on_bit: .* buckles the BHA"):
        lateral_modes(config, 1.01 * limit, region="bha")
    deviated = replace(SimulationConfig(), **{"well.md": (0.0, 500.0, 1500.0),
                                              "well.inclination": (0.0, 0.0, 60.0),
                                              "well.azimuth": (0.0, 0.0, 0.0)})
    with pytest.raises(ValueError, match="well: the modal analysis is for vertical holes"):
        lateral_modes(deviated, 50e3)


def test_the_first_torsional_damping_ratio_matches_its_perturbation_estimate():
    """Light, non-proportional damping: zeta ~ phi^T C phi / (2 w phi^T J phi) with the
    undamped mode phi. The mud drag of MudConfig.torsional_damping (0.1 N m s/rad per m)
    gives the paper string's first mode ~9 % (docs/model.md, "Torsional damping")."""
    config = SimulationConfig()
    modes = torsional_modes(config, "fixed", 1)
    k, c, j, free = torsional_system(config, "fixed")
    ix = np.ix_(free, free)
    w2, phi = scipy.linalg.eigh(k[ix], np.diag(j[free]), subset_by_index=[0, 0])
    phi = phi[:, 0]
    estimate = phi @ c[ix] @ phi / (2 * math.sqrt(w2[0]) * phi @ (j[free] * phi))
    assert modes.damping_ratio[0] == pytest.approx(estimate, rel=0.05)
    assert 0.05 < modes.damping_ratio[0] < 0.15


def _numpy_torsion_poles(config: SimulationConfig, top_drive: tuple[float, float, float]
                         | None = None, n: int = 2) -> np.ndarray:
    """The ``n`` lowest oscillating poles of a torsional chain built here with numpy from
    the sections' data alone (2 m pipe and 1 m collar elements, lumped inertias, mud drag
    per metre lumped to the nodes, Rayleigh b K, bit inertia at the free end), solved as a
    first-order system by numpy: no matrix of the project's. Top fixed, or with
    ``top_drive`` = (rotor inertia, kp, ki): the rotor on the top node, the PI speed loop
    a damper kp and a spring ki to the ground."""
    string = config.string
    lengths, stiff, inertia = [], [], []
    for section, step in ((string.drill_pipe, 2.0), (string.bha, 1.0)):
        polar = math.pi / 32.0 * (section.outer_diameter**4 - section.inner_diameter**4)
        count = round(section.length / step)
        lengths += [section.length / count] * count
        stiff += [section.shear_modulus * polar / (section.length / count)] * count
        inertia += [section.density * polar * section.length / count] * count
    nodes = len(lengths) + 1
    k = np.zeros((nodes, nodes))
    j = np.zeros(nodes)
    c = np.zeros(nodes)
    for e, (length, ke, je) in enumerate(zip(lengths, stiff, inertia, strict=True)):
        k[e:e + 2, e:e + 2] += ke * np.array([[1.0, -1.0], [-1.0, 1.0]])
        j[e:e + 2] += je / 2.0
        c[e:e + 2] += config.mud.torsional_damping * length / 2.0
    j[-1] += config.bit.inertia
    damping = np.diag(c) + config.damping.stiffness_proportional * k
    if top_drive is None:  # fixed top
        k, j, damping = k[1:, 1:], j[1:], damping[1:, 1:]
    else:
        rotor, kp, ki = top_drive
        j[0] += rotor
        damping[0, 0] += kp
        k[0, 0] += ki
    size = len(j)
    system = np.block([[np.zeros((size, size)), np.eye(size)],
                       [-k / j[:, None], -damping / j[:, None]]])
    poles = np.linalg.eigvals(system)
    poles = poles[poles.imag > 1e-9]
    return poles[np.argsort(np.abs(poles))][:n]


def test_torsional_damping_ratios_match_an_independent_damped_eigenproblem():
    """The paper string's first torsional modes against the chain of
    :func:`_numpy_torsion_poles`. The meshes differ (10 m pipe elements there), so they
    agree to the discretisation error; the chain's first ratio is the one docs/model.md
    states, to the 0.1 % it is given in."""
    import re

    config = SimulationConfig()
    poles = _numpy_torsion_poles(config)
    zeta = -poles.real / np.abs(poles)
    modes = torsional_modes(config, "fixed", 2)
    model = (Path(__file__).parents[2] / "docs" / "model.md").read_text()
    stated = re.search(r"paper string\s+has ([\d.]+) % of critical damping", model)
    assert stated, "docs/model.md no longer states the paper string's modal damping"
    assert zeta[0] == pytest.approx(float(stated[1]) / 100.0, abs=0.0005)
    np.testing.assert_allclose(modes.damping_ratio, zeta, rtol=2e-3)
    np.testing.assert_allclose(modes.frequency, np.abs(poles) / (2.0 * math.pi), rtol=1e-3)


@pytest.mark.parametrize("kp, ki", [(2.0e4, 4.0e3), (3.0e3, 2.0e4)])
def test_torsional_modes_with_the_pi_top_drive_match_an_independent_chain(kp, ki):
    """``top="top_drive"``: the rotor inertia on the top, the speed loop's kp as a damper
    and ki as a spring to the ground (the PI's integral of the speed error is the
    angle's), against the numpy chain with the same three numbers: frequencies and
    damping ratios of the three lowest oscillating modes, the PI's own among them."""
    config = replace(SimulationConfig(), **{"top_drive.proportional_gain": kp,
                                            "top_drive.integral_gain": ki})
    poles = _numpy_torsion_poles(config, (config.top_drive.inertia, kp, ki), n=3)
    modes = torsional_modes(config, "top_drive", 3)
    np.testing.assert_allclose(modes.frequency, np.abs(poles) / (2.0 * math.pi), rtol=2e-3)
    np.testing.assert_allclose(modes.damping_ratio, -poles.real / np.abs(poles), rtol=5e-3,
                               atol=1e-4)


def test_backward_whirl_excitations_are_rolling_without_slip():
    """A body of radius r rolling without slip on the wall of a hole of radius R whirls
    backward at r / (R - r) times its rotation (Jansen 1993): the realistic string's
    largest BHA body is its 6 3/4 in MWD in the 8 3/4 in hole (3.375 / 1), the bit
    rolls on its gauge clearance (0.106125 m / 0.005 m)."""
    config = SimulationConfig(string=cp.realistic_string())
    per_rev = dict(excitations(config))
    assert per_rev["1x"] == 1.0
    assert per_rev["6x (blades)"] == 6.0
    assert per_rev["backward whirl (bit)"] == pytest.approx(0.106125 / 0.005, rel=1e-12)
    body = [name for name in per_rev if name.startswith("backward whirl (")
            and name != "backward whirl (bit)"]
    assert body == ["backward whirl (MWD)"]
    assert per_rev["backward whirl (MWD)"] == pytest.approx(3.375 / 1.0, rel=1e-12)
    assert dict(excitations(config, "torsional")) == {"6x (blades)": 6.0}
    # a near-bit stabilizer whose 8 in body ties with the 8 in collars' named the line (a
    # new user's trial): its blades touch the wall, not its body; the collars roll
    inch = 0.0254
    stab = Section(kind="stabilizer", name="near-bit stab", length=1.8, element_length=1.8,
                   outer_diameter=8 * inch, inner_diameter=2.8125 * inch,
                   contact_diameter=12.125 * inch)
    collars = Section(kind="collar", name="8 in DC", length=54.0, element_length=3.0,
                      outer_diameter=8 * inch, inner_diameter=2.8125 * inch)
    big = SimulationConfig(string=StringConfig(hole_diameter=12.25 * inch, components=(
        stab, collars), drill_pipe=replace(SimulationConfig().string.drill_pipe,
                                           length=1000.0)), bit=BitConfig(diameter=12.25 * inch))
    per_rev = dict(excitations(big))
    assert per_rev["backward whirl (8 in DC)"] == pytest.approx(4.0 / (6.125 - 4.0), rel=1e-12)
    assert "backward whirl (near-bit stab)" not in per_rev


def test_critical_speeds_are_where_the_excitations_meet_the_modes():
    config = SimulationConfig(string=cp.realistic_string())
    lateral = lateral_modes(config, 100e3, n_modes=3)
    torsional = torsional_modes(config, "fixed", 3)
    crit = critical_speeds(config, (lateral, torsional), 300.0)
    assert crit == sorted(crit, key=lambda c: c.rpm)
    for c in crit:
        per_rev = dict(excitations(config, c.mode.split()[0]))[c.excitation]
        assert per_rev * c.rpm / 60.0 == pytest.approx(c.frequency)
        kind, number = c.mode.split()  # "lateral 1": the lowest lateral mode (the chart's L1)
        assert c.frequency == {"lateral": lateral, "torsional": torsional}[kind].frequency[
            int(number) - 1]
    first_lateral = lateral.frequency[0]
    assert any(c.excitation == "1x" and c.rpm == pytest.approx(60 * first_lateral)
               for c in crit)


def test_torsional_modes_with_a_free_top_drive_rotor_are_the_transfer_matrix_roots():
    """``top="top_drive"`` with the PI gains at 0: the rotor is a free inertia J_td on the
    top (T(0) = -J_td w^2 phi(0)), the bit one at the bottom (T(L) = J_bit w^2 phi(L)).
    The exact frequencies solve the transfer-matrix equation of the uniform sections
    (``reference_solutions.transfer_matrix_frequencies``)."""
    config = replace(SimulationConfig(), **UNDAMPED, **{"top_drive.proportional_gain": 0.0,
                                                        "top_drive.integral_gain": 0.0})
    roots = transfer_matrix_frequencies(config.string.sections, config.bit.inertia, 2.5,
                                        top_inertia=config.top_drive.inertia, f_min=0.008)
    modes = torsional_modes(config, top="top_drive", n_modes=3)
    flexible = modes.frequency[modes.frequency > 1e-3]  # not the free string's rotation
    np.testing.assert_allclose(flexible[:2], roots[:2], rtol=1e-3)
    assert flexible[0] > torsional_modes(config, top="fixed", n_modes=1).frequency[0]


ROOT = Path(__file__).parents[2]


def _field_config() -> SimulationConfig:
    """The default scenario with the string of ``examples/field_well_string.yaml``, as
    ``drill-env modes --config`` reads it."""
    from drill_env.physics.config import flatten
    from drill_env.physics.validation import read_yaml
    from drill_env.scenarios import make_scenario

    overrides = flatten(read_yaml(ROOT / "examples/field_well_string.yaml"))
    return replace(make_scenario("default").config, **overrides)


def _chart(config: SimulationConfig, n_modes: int, max_rpm: float):
    """(figure, axes, modes) of the critical-speed chart `drill-env modes` draws."""
    from drill_env.physics.modes import critical_speed_figure

    modes = (torsional_modes(config, "fixed", n_modes),
             lateral_modes(config, 100e3, n_modes=n_modes))
    fig = critical_speed_figure(config, modes, max_rpm)
    return fig, fig.axes[0], modes


def _mode_labels(ax):
    """{(kind letter, mode number): text} of the mode labels ("L5 1.73 Hz")."""
    import re

    found = (re.match(r"([LT])(\d+) ", t.get_text()) for t in ax.texts)
    return {(m[1], int(m[2])): t for m, t in zip(found, ax.texts, strict=True) if m}


CHARTS = [("default", 5, 250.0), ("default", 5, 120.0), ("field", 5, 250.0),
          ("field", 10, 250.0), ("field", 60, 250.0)]


@pytest.mark.parametrize(("string", "n_modes", "max_rpm"), CHARTS)
def test_critical_speed_chart_labels_stay_inside_and_apart(string, n_modes, max_rpm):
    """The mode and excitation labels of the chart `drill-env modes` draws: none runs off
    the plot (the steep backward-whirl line leaves near the left edge; 120 modes reach
    2000 Hz), none prints over another (close lateral and torsional frequencies; the
    field string's three steep lines of bit whirl, collar whirl and blades leave the
    plot close together) or over the title, and none covers a critical speed."""
    config = SimulationConfig() if string == "default" else _field_config()
    fig, ax, modes = _chart(config, n_modes, max_rpm)
    renderer = fig.canvas.get_renderer()
    boxes = [(t.get_text(), t.get_window_extent(renderer)) for t in ax.texts]
    names = {excitation_label(name, per_rev)
             for m in modes for name, per_rev in excitations(config, m.kind)}
    assert len(boxes) == len(_mode_labels(ax)) + len(names)
    assert names <= {text for text, _ in boxes}
    title = ax.title.get_window_extent(renderer)
    for text, box in boxes:
        assert ax.bbox.x0 <= box.x0 and box.x1 <= ax.bbox.x1, text
        assert ax.bbox.y0 <= box.y0 and box.y1 <= ax.bbox.y1, text
        assert not box.overlaps(title), text
    for k, (text, box) in enumerate(boxes):
        for other, box2 in boxes[k + 1:]:
            assert not box.overlaps(box2), (text, other)
    circles = [xy for line in ax.lines if line.get_marker() == "o"
               for xy in ax.transData.transform(line.get_xydata())]
    assert circles
    for text, box in boxes:
        assert not any(box.contains(x, y) for x, y in circles), text


@pytest.mark.parametrize(("string", "n_modes", "max_rpm"), CHARTS)
def test_each_mode_label_sits_on_its_own_line(string, n_modes, max_rpm):
    """A label pushed off its line to make room (the field string's "L5 1.73 Hz" once
    sat at 2.0 Hz, by the line of L6) reads as the next line's: each label spans the
    height of its own mode, and every mode drawn has one."""
    config = SimulationConfig() if string == "default" else _field_config()
    fig, ax, modes = _chart(config, n_modes, max_rpm)
    renderer = fig.canvas.get_renderer()
    from drill_env.physics.modes import chart_cutoff

    labels = _mode_labels(ax)
    top = chart_cutoff(config, modes, max_rpm)
    drawn = {(m.kind[0].upper(), i + 1): f for m in modes
             for i, f in enumerate(m.frequency) if f <= top}
    assert set(labels) == set(drawn)
    for key, text in labels.items():
        box = text.get_window_extent(renderer)
        y = ax.transData.transform((0.0, drawn[key]))[1]
        assert box.y0 <= y <= box.y1, text.get_text()


@pytest.mark.parametrize(("string", "n_modes", "max_rpm"), CHARTS)
def test_each_excitation_line_runs_into_its_label_and_through_no_other(string, n_modes,
                                                                       max_rpm):
    """Three steep lines leave the field string's chart close together: each runs into
    (or passes just under) its own label, and no other line passes through it."""
    config = SimulationConfig() if string == "default" else _field_config()
    fig, ax, modes = _chart(config, n_modes, max_rpm)
    renderer = fig.canvas.get_renderer()
    labels = {t.get_text(): t.get_window_extent(renderer) for t in ax.texts
              if t.get_gid() == "excitation label"}
    per_rev = {name: x for m in modes for name, x in excitations(config, m.kind)}
    assert set(labels) == {excitation_label(name, x) for name, x in per_rev.items()}
    lines = {excitation_label(gid[len("excitation: "):], per_rev[gid[len("excitation: "):]]):
             line for line in ax.lines
             if (gid := str(line.get_gid())).startswith("excitation: ")}
    assert set(lines) == set(labels)
    for name, box in labels.items():
        inner = box.padded(-1.0)  # the outline may touch its own line
        for other, line in lines.items():
            (x0, y0), (x1, y1) = ax.transData.transform(line.get_xydata()[[0, -1]])
            t = np.linspace(0.0, 1.0, 4001)
            xs, ys = x0 + t * (x1 - x0), y0 + t * (y1 - y0)
            seen = (xs <= ax.bbox.x1) & (ys <= ax.bbox.y1)  # the part inside the plot
            xs, ys = xs[seen], ys[seen]
            assert not np.any((inner.x0 < xs) & (xs < inner.x1) & (inner.y0 < ys)
                              & (ys < inner.y1)), (name, "crossed by", other)
            if other == name:
                gap = np.hypot(np.clip(xs, box.x0, box.x1) - xs,
                               np.clip(ys, box.y0, box.y1) - ys)
                assert np.min(gap) < 6.0, (name, "away from its line")


@pytest.mark.parametrize(("string", "n_modes", "max_rpm"), CHARTS)
def test_mode_labels_stand_apart_and_each_line_ends_at_its_label(string, n_modes,
                                                                  max_rpm):
    """Close frequencies (the default string's L5 1.69 Hz and T2 1.65 Hz) put two mode
    labels side by side: they keep a gap, and the left one's line ends under its own
    label rather than running on beneath its neighbour's (it read "Hz-T2")."""

    from drill_env.physics.modes import MODE_LABEL_GAP

    config = SimulationConfig() if string == "default" else _field_config()
    fig, ax, _ = _chart(config, n_modes, max_rpm)
    renderer = fig.canvas.get_renderer()
    labels = [t for t in ax.texts if t.get_gid() == "mode label"]
    boxes = [t.get_window_extent(renderer) for t in labels]
    moved = 0
    for k, box in enumerate(boxes):
        for other in boxes[k + 1:]:
            if box.y0 < other.y1 and other.y0 < box.y1:  # side by side
                assert max(box.x0, other.x0) - min(box.x1, other.x1) >= MODE_LABEL_GAP - 4
    mode_lines = [line for line in ax.lines if line.get_gid() == "mode line"]
    for text, box, line in zip(labels, boxes, mode_lines, strict=True):  # drawn in turn
        assert text.get_text().endswith(f"{line.get_ydata()[0]:.2f} Hz")
        end = ax.bbox.x0 + line.get_xdata()[1] * ax.bbox.width
        assert box.x0 < end <= box.x1, text.get_text()
        moved += box.x1 < ax.bbox.x1 - 10.0
    if string == "default" and max_rpm == 250.0:
        assert moved >= 1  # L5 beside T2: the case this test is about


def test_excitation_labels_and_lines_keep_off_the_modes():
    """The random scenario's seed-3 string (`drill-env modes --scenario random --seed 3`):
    the 1x line leaves through the right edge just under T3 (4.07 Hz); its label sat on
    T3's dashed line and the line ran on into T3's label. No excitation label may sit on
    a mode line, and no excitation line may pass through a mode label."""

    from drill_env.physics.modes import _crosses
    from drill_env.scenarios import make_scenario

    config = make_scenario("random", rng=np.random.default_rng(3)).config
    fig, ax, _ = _chart(config, 5, 250.0)
    renderer = fig.canvas.get_renderer()
    to_px = ax.transData.transform
    rows = [(to_px((0.0, line.get_ydata()[0]))[1],
             ax.bbox.x0 + line.get_xdata()[1] * ax.bbox.width)
            for line in ax.lines if line.get_gid() == "mode line"]
    mode_boxes = [t.get_window_extent(renderer) for t in ax.texts
                  if t.get_gid() == "mode label"]
    for text in (t for t in ax.texts if t.get_gid() == "excitation label"):
        box = text.get_window_extent(renderer)
        assert not any(box.y0 < y < box.y1 and box.x0 < end for y, end in rows), \
            text.get_text()
    for line in (x for x in ax.lines if str(x.get_gid()).startswith("excitation:")):
        start, end = to_px(line.get_xydata())
        assert not any(_crosses(start, end, b) for b in mode_boxes), line.get_gid()


def test_backward_whirl_labels_say_their_multiplier():
    """A backward whirl line's slope is not in its name: rolling without slip on the
    wall, a body of radius r in a hole of radius R whirls backward at r / (R - r) times
    the rotary speed (Jansen 1993; Vandiver et al. 1990): 21.2x for the default 8.36 in
    bit in a hole 5 mm wider in radius."""
    config = SimulationConfig()
    cfg = config.resolved()
    r = cfg.bit.gauge_radius
    hole = r + cfg.bit.gauge_clearance
    label = excitation_label("backward whirl (bit)", dict(excitations(config))[
        "backward whirl (bit)"])
    assert label == f"backward whirl (bit): {r / (hole - r):.3g}x"
    assert excitation_label("1x", 1.0) == "1x"


def test_a_chart_of_many_modes_draws_the_lowest_and_says_so():
    """`drill-env modes -n 500` asks for modes up to 2000 Hz; their labels cannot all be
    read on one page, nor are modes above the fastest excitation critical in its range.
    The chart draws the ``CHART_MODES`` lowest, its y axis just above them (room for the
    labels, shaded: the higher modes there are not drawn), and its title says how many
    more the table lists."""

    from drill_env.physics.modes import CHART_MODES, chart_cutoff

    config = _field_config()
    fig, ax, modes = _chart(config, 60, 250.0)
    every = np.sort(np.concatenate([m.frequency for m in modes]))
    assert len(_mode_labels(ax)) == CHART_MODES
    cutoff = every[CHART_MODES - 1]
    assert cutoff < ax.get_ylim()[1] < 1.3 * cutoff
    assert f"the {CHART_MODES} lowest of {len(every)} modes; those above {cutoff:.2f} Hz, " \
        "shaded" in ax.get_title()
    (shade,) = [p for p in ax.patches if p.get_gid() == "modes not drawn"]
    low, high = shade.get_window_extent().y0, shade.get_window_extent().y1
    assert low == pytest.approx(ax.transData.transform((0.0, cutoff))[1])
    assert high == pytest.approx(ax.bbox.y1)
    fastest = max(per_rev for _, per_rev in excitations(config)) * 10.0 / 60.0
    assert chart_cutoff(config, modes, 10.0) <= fastest
    assert chart_cutoff(config, modes, 10.0) >= every[0]  # always the lowest mode
    # even where every excitation stays below it (the fastest at half its frequency)
    slow = 0.5 * every[0] / fastest * 10.0
    assert chart_cutoff(config, modes, slow) == every[0]


def test_the_modes_command_titles_the_chart_with_the_string_of_its_config(tmp_path,
                                                                           monkeypatch):
    """With ``--config`` replacing the string, the chart is of that string, not of the
    scenario's ("default: ...")."""
    from drill_cli.main import main
    from drill_env.physics import modes as md

    titles = []
    def chart(config, modes, path, max_rpm, title):  # (into save_whole's partial file)
        titles.append(title)
        Path(path).write_bytes(b"")

    monkeypatch.setattr(md, "critical_speed_chart", chart)
    assert main(["modes", "--out", str(tmp_path)]) == 0
    assert main(["modes", "--config", str(ROOT / "examples/field_well_string.yaml"),
                 "--out", str(tmp_path)]) == 0
    assert titles[0].startswith("default: ")
    assert titles[1].startswith("field_well_string.yaml (scenario default): ")


def test_string_stabilizer_diameter_pins_nothing_in_a_string_of_components():
    """With components, string.stabilizer_diameter places no stabilizer; it still decided
    which nodes modes pinned, so in a 12 1/4 in hole every 8 in collar node (no tighter
    than an 8 in stabilizer) became a support (a review). The modes do not depend on it:
    at 0.15 m its clearance (8 cm) is wider than every collar's in this hole (7.0-7.3 cm at
    their contact diameters), which would all be pinned."""
    from drill_cli.configs import read_overrides

    field = read_overrides(Path(__file__).parents[2] / "examples" / "field_well_string.yaml")
    base = with_physics(make_scenario("default").config,
                        {**field, "string.hole_diameter": 12.25 * 0.0254,
                         "bit.diameter": 12.25 * 0.0254})
    found = [lateral_modes(replace(base, **{"string.stabilizer_diameter": d}), 20e3,
                           n_modes=3, region="bha").frequency for d in (0.15, 0.3)]
    np.testing.assert_allclose(found[0], found[1], rtol=1e-12)


def test_modes_with_a_torque_feedback_drive_say_the_feedback_is_left_out():
    """The modal model holds the top drive's inertia and PI speed loop, not a torque
    feedback's filter: for z_torque and soft_torque it says so in a warning and in the
    boundary's label, instead of passing its PI's modes off as the controller's."""
    import warnings

    from drill_env.physics.config import SimulationConfig, replace
    from drill_env.physics.modes import torsional_modes

    for name, feedback in (("z_torque", "high-pass"), ("soft_torque", "band-pass")):
        config = replace(SimulationConfig(), **{"top_drive.controller": name})
        with pytest.warns(UserWarning, match=f"top_drive.controller: {name}.*{feedback}"):
            modes = torsional_modes(config, "top_drive")
        assert f"its {feedback} torque feedback not modelled" in modes.boundary
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        modes = torsional_modes(replace(SimulationConfig(), **{
            "top_drive.controller": "soft_speed"}), "top_drive")
    assert "not modelled" not in modes.boundary


def test_the_dense_eigenproblems_run_on_one_blas_thread(monkeypatch):
    """physics.linalg.one_blas_thread: the modal analysis, the stability threshold and the
    soft controllers' tuning frequency solve dense eigenproblems of a few hundred rows on
    one BLAS thread; on OpenBLAS's threads ``drill-env modes`` took 15-128 s where one
    thread takes ~4.5 s, on a 2-core machine another job shared (a new user's trial)."""
    from threadpoolctl import threadpool_info

    from drill_env.physics import top_drive
    from drill_env.physics.simulator import Simulator
    from drill_env.physics.stability import stick_slip_threshold

    if not any(i["user_api"] == "blas" for i in threadpool_info()):
        pytest.skip("no BLAS library that threadpoolctl can see")
    seen: list[tuple[str, list[int]]] = []

    def count(module, name):
        real = getattr(module, name)

        def call(*args, **kwargs):
            seen.append((name, [i["num_threads"] for i in threadpool_info()
                                if i["user_api"] == "blas"]))
            return real(*args, **kwargs)
        monkeypatch.setattr(module, name, call)

    for name in ("eig", "eigh", "eigvals", "eig_banded"):
        count(scipy.linalg, name)
    count(np.linalg, "eigvalsh")
    config = SimulationConfig()
    torsional_modes(config)
    lateral_modes(config, 50e3)
    top_drive.stick_slip_frequency.cache_clear()
    top_drive.stick_slip_frequency(config)
    stick_slip_threshold(Simulator(config), 100e3)
    assert {name for name, _ in seen} >= {"eig", "eigh", "eigvals", "eigvalsh"}
    assert all(threads and set(threads) == {1} for _, threads in seen), seen
