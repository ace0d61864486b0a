"""Modal analysis: the eigenvalues of the assembled matrices, the closed forms of the FE
validation, the damping ratio against its perturbation estimate, the critical speeds."""

from __future__ import annotations

import dataclasses
import math

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
    SimulationConfig,
    StringConfig,
    replace,
)
from drill_env.physics.fem import assemble_lateral, assemble_torsion, build_mesh
from drill_env.physics.modes import (
    critical_speeds,
    excitations,
    lateral_buckling_weight,
    lateral_modes,
    torsional_modes,
    torsional_system,
    undamped_frequencies,
)

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
    cot(w L / c) = (J_BHA w) / (Z) ... solved here in the form tan(kL) kL = J_pipe / J_end."""
    config = replace(SimulationConfig(), **UNDAMPED)
    pipe, bha = config.string.drill_pipe, config.string.bha
    j_pipe = pipe.density * pipe.polar_moment * pipe.length
    j_end = bha.density * bha.polar_moment * bha.length + config.bit.inertia
    x = brentq(lambda x: x * math.tan(x) - j_pipe / j_end, 1e-6, math.pi / 2 - 1e-9)
    f = x / pipe.length * pipe.torsional_wave_speed / (2 * math.pi)
    assert torsional_modes(config, "fixed", 1).frequency[0] == pytest.approx(f, rel=0.01)
    assert f == pytest.approx(0.66, abs=0.01)


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
    buckling load) moves the frequencies by < 0.2 %."""
    collar, config = _pinned_collar()
    config = dataclasses.replace(config, damping=DampingConfig(mass_proportional=0.0,
                                                               stiffness_proportional=0.0))
    modes = lateral_modes(config, 0.0, supports="stabilizers", n_modes=3, region="bha")
    ei = collar.youngs_modulus * collar.second_moment
    rho_a = collar.density * collar.area
    expected = [(n * math.pi / collar.length) ** 2 * math.sqrt(ei / rho_a) / (2 * math.pi)
                for n in (1, 2, 3)]
    np.testing.assert_allclose(modes.frequency, expected, rtol=0.01)


def test_lateral_buckling_weight_of_a_pinned_collar_is_eulers_load():
    """Euler: P_cr = pi^2 EI / L^2 for a pinned-pinned column; the collar's own 7 kN of
    weight relieves its top by up to 7 kN against ~2 MN (< 0.4 %)."""
    collar, config = _pinned_collar()
    euler = math.pi ** 2 * collar.youngs_modulus * collar.second_moment / collar.length ** 2
    assert lateral_buckling_weight(config, region="bha") == pytest.approx(euler, rel=5e-3)


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


def test_critical_speeds_are_where_the_excitations_meet_the_modes():
    config = SimulationConfig(string=cp.realistic_string())
    lateral = lateral_modes(config, 100e3, n_modes=3)
    torsional = torsional_modes(config, "fixed", 3)
    crit = critical_speeds(config, (lateral, torsional), 300.0)
    assert crit == sorted(crit, key=lambda c: c.rpm)
    for c in crit:
        per_rev = dict(excitations(config, c.mode.split()[0]))[c.excitation]
        assert per_rev * c.rpm / 60.0 == pytest.approx(c.frequency)
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


@pytest.mark.parametrize("max_rpm", [250.0, 120.0])
def test_critical_speed_chart_labels_stay_inside_and_apart(max_rpm):
    """The mode and excitation labels of the chart `drill-env modes` draws: none runs off
    the plot (the steep backward-whirl line leaves near the left edge) and none prints
    over another (close lateral and torsional frequencies)."""
    from drill_env.physics.modes import critical_speed_figure

    config = SimulationConfig()
    modes = (torsional_modes(config, "fixed", 5), lateral_modes(config, 100e3, n_modes=5))
    fig = critical_speed_figure(config, modes, max_rpm)
    renderer = fig.canvas.get_renderer()
    ax = fig.axes[0]
    boxes = [(t.get_text(), t.get_window_extent(renderer)) for t in ax.texts]
    assert len(boxes) == 10 + len({name for m in modes for name, _ in
                                    excitations(config, m.kind)})
    for text, box in boxes:
        assert ax.bbox.x0 <= box.x0 and box.x1 <= ax.bbox.x1, text
        assert ax.bbox.y0 <= box.y0 and box.y1 <= ax.bbox.y1, text
    for k, (text, box) in enumerate(boxes):
        for other, box2 in boxes[k + 1:]:
            assert not box.overlaps(box2), (text, other)
