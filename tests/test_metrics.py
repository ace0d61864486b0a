"""Metrics (SPEC section 5) on synthetic signals with known answers."""

import math

import numpy as np
import pytest

from drill_env import metrics
from drill_env.physics.simulator import RECORD_CHANNELS

T = np.linspace(0.0, 10.0, 10001)  # ten whole periods of a 1 Hz sinusoid


def test_stick_slip_severity_of_a_sinusoid_is_amplitude_over_mean():
    speed = 10.0 + 3.0 * np.sin(2 * np.pi * T)
    assert metrics.stick_slip_severity(speed) == pytest.approx(0.3, rel=1e-3)


def test_steady_rotation_has_no_stick_slip_and_is_never_stuck():
    speed = np.full(100, 5.0)
    assert metrics.stick_slip_severity(speed) == 0.0
    assert metrics.stuck_fraction(speed) == 0.0


def test_stalled_bit_has_finite_severity_thanks_to_the_mean_floor():
    speed = np.zeros(50)
    speed[10] = 0.5
    ssi = metrics.stick_slip_severity(speed)
    assert math.isfinite(ssi)
    assert ssi == pytest.approx(0.5 / (2 * metrics.SSI_MIN_MEAN_SPEED))


def test_stuck_fraction_counts_samples_below_one_rpm():
    speed = np.array([0.0, 0.05, -0.05, 0.2, 10.0, 10.0, 10.0, 10.0])
    assert metrics.STUCK_SPEED == pytest.approx(2 * np.pi / 60)
    assert metrics.stuck_fraction(speed) == pytest.approx(3 / 8)


def test_empty_signals_are_rejected_by_name():
    with pytest.raises(ValueError, match="bit_speed"):
        metrics.stick_slip_severity([])


def test_whirl_sign_tells_forward_from_backward():
    omega = np.full(T.size, 10.0)
    forward = np.full(T.size, 10.0)
    assert metrics.whirl_ratio(forward, omega) == pytest.approx(1.0)
    assert metrics.whirl_ratio(-20 * forward, omega) == pytest.approx(-20.0)
    radial = np.full(T.size, 0.8)
    assert metrics.whirl_direction(forward, omega, radial) == "forward"
    assert metrics.whirl_direction(-forward, omega, radial) == "backward"
    assert metrics.whirl_direction(forward, omega, 0.01 * radial) == "none"


def test_radial_ratio_of_an_orbit_on_the_wall_is_one():
    c = 0.005
    x, y = c * np.cos(2 * np.pi * T), c * np.sin(2 * np.pi * T)
    np.testing.assert_allclose(metrics.radial_ratio(x, y, c), 1.0)
    with pytest.raises(ValueError, match="clearance"):
        metrics.radial_ratio(x, y, 0.0)


def test_lateral_force_is_the_magnitude():
    assert metrics.lateral_force(3.0, 4.0) == pytest.approx(5.0)


def test_mse_matches_teale_in_si():
    # WOB 100 kN, 100 rpm, 5 kN m, 10 m/h, 8.75 in bit.
    d = 8.75 * 0.0254
    area = math.pi * d * d / 4
    wob, n_rps, torque, rop = 1e5, 100 / 60, 5e3, 10 / 3600
    expected = wob / area + 2 * math.pi * n_rps * torque / (area * rop)
    got = metrics.mechanical_specific_energy(np.full(5, wob), np.full(5, torque),
                                             np.full(5, 2 * math.pi * n_rps), np.full(5, rop), d)
    assert got == pytest.approx(expected)
    # ~ 0.9 GPa: hard-rock drilling is in the hundreds of MPa to GPa range.
    assert 1e8 < got < 1e10


def test_mse_without_penetration_is_infinite_or_just_the_thrust_term():
    d = 0.2
    zero = np.zeros(3)
    assert metrics.mechanical_specific_energy(np.full(3, 1e5), np.full(3, 1e3), np.full(3, 1.0),
                                              zero, d) == math.inf
    assert metrics.mechanical_specific_energy(np.full(3, 1e5), zero, zero, zero, d) == \
        pytest.approx(1e5 / metrics.bit_area(d))


def test_top_drive_energy_integrates_absolute_power():
    torque = np.full(100, 2e3)
    speed = np.concatenate([np.full(50, 10.0), np.full(50, -10.0)])
    assert metrics.top_drive_energy(torque, speed, 0.01) == pytest.approx(2e3 * 10 * 1.0)


def test_window_metrics_reads_simulator_records():
    n = 1000
    rec = np.zeros((n, len(RECORD_CHANNELS)))
    col = {name: k for k, name in enumerate(RECORD_CHANNELS)}
    t = np.linspace(0, 10, n, endpoint=False)
    rec[:, col["bit_speed"]] = 10 + 5 * np.sin(2 * np.pi * t)
    rec[:, col["bit_x"]] = 0.0025
    rec[:, col["rop"]] = 1e-3
    rec[:, col["weight_on_bit"]] = 1e5
    m = metrics.window_metrics(rec, RECORD_CHANNELS, 0.01, 0.005, 0.2)
    assert m["ssi"] == pytest.approx(0.5, rel=1e-3)
    assert m["radial_ratio"] == pytest.approx(0.5)
    assert m["rop"] == pytest.approx(1e-3)
    assert m["stuck_fraction"] == 0.0
    assert set(m) >= {"whirl_ratio", "lateral_force", "mse", "top_drive_energy"}
