"""Classical top-drive controllers: tuning rules against independent numbers, the
reflection coefficient of a simulated pulse against the closed form, stick-slip cured at
the same mean speed, and the rule-based driller's decisions."""

from __future__ import annotations

import math

import numpy as np
import pytest
from reference_solutions import torsional_impedance, transfer_matrix_frequency

from agents import CLASSICAL, Driller, DrillerRules, make_controller, parse_controllers
from agents.classical import SoftSpeed, SoftTorque, StiffPI, ZTorque
from drill_env.physics.config import (
    INCH,
    BitConfig,
    Section,
    SimulationConfig,
    StringConfig,
    TopDriveConfig,
    replace,
)
from drill_env.physics.top_drive import measured_reflection, resolve
from drill_env.physics.units import RPM
from drill_env.scenarios import make_scenario
from drill_env.tools.studies import simulate, stick_slip_summary


def strings() -> list[tuple[str, SimulationConfig, float, float]]:
    """Two strings whose impedance and stick-slip frequency differ: the realistic default
    (5 in DP) and a 3000 m string of 5 1/2 in DP over 200 m of 8 in collars. Each with
    its drill pipe's Z and its exact fixed-top first frequency, from closed forms."""
    default = make_scenario("default").config
    long = SimulationConfig(string=StringConfig(
        drill_pipe=Section(length=2800.0, outer_diameter=5.5 * INCH,
                           inner_diameter=4.778 * INCH, element_length=20.0),
        bha=Section(length=200.0, outer_diameter=8.0 * INCH, inner_diameter=2.8125 * INCH,
                    element_length=5.0),
        stabilizers=(10.0, 19.0)))  # the paper's near-bit one would sit on the bit's node
    out = []
    for name, cfg in (("default", default), ("long 5 1/2 in", long)):
        pipe = cfg.string.drill_pipe
        z = torsional_impedance(pipe.outer_diameter, pipe.inner_diameter)
        f1 = transfer_matrix_frequency(cfg.string.sections, cfg.bit.inertia, 2.0)
        out.append((name, cfg, z, f1))
    return out


STRINGS = strings()


def test_the_two_strings_differ():
    (_, _, z1, f1), (_, _, z2, f2) = STRINGS
    assert z2 / z1 > 1.3 and f1 / f2 > 1.5


@pytest.mark.parametrize(("name", "config", "z", "f_s"), STRINGS, ids=[s[0] for s in STRINGS])
def test_gains_follow_their_formulas_on_the_string(name, config, z, f_s):
    j = config.top_drive.inertia
    # FE tuning frequency against the exact continuous string (mesh error < 0.5 %)
    tol = {"rel": 5e-3}
    stiff = StiffPI().tuning(config)
    assert stiff.proportional_gain == pytest.approx(50.0 * z, rel=1e-9)
    assert stiff.integral_gain == pytest.approx(5.0 * j, rel=1e-12)
    assert stiff.torque_feedback == "none"

    soft = SoftSpeed().tuning(config)
    k = config.top_drive.impedance_factor
    assert soft.tuning_frequency == pytest.approx(f_s, **tol)
    assert soft.proportional_gain == pytest.approx(k * z, rel=1e-9)
    assert soft.integral_gain == pytest.approx((2 * math.pi * f_s) ** 2 * j, rel=1e-2)

    torque = SoftTorque().tuning(config)
    assert (torque.proportional_gain, torque.integral_gain) == pytest.approx(
        (50.0 * z, 5.0 * j), rel=1e-9)
    assert torque.torque_feedback == "band_pass"
    assert torque.filter_frequency == pytest.approx(f_s, **tol)
    assert torque.feedback_gain == pytest.approx(1.0 / z, rel=1e-9)

    zt = ZTorque().tuning(config)
    assert zt.torque_feedback == "high_pass"
    assert zt.filter_frequency == pytest.approx(f_s / 4.0, **tol)
    assert zt.feedback_gain == pytest.approx(1.0 / z, rel=1e-9)


@pytest.mark.parametrize("name", ["stiff", "soft_speed", "soft_torque", "z_torque"])
def test_explicitly_configured_values_win_over_the_rule(name):
    """``resolve``'s docstring: gains, feedback gain and filter corner given in the config
    are the ones the drive uses, whatever its rule would tune."""
    given = {"top_drive.controller": name, "top_drive.proportional_gain": 1234.0,
             "top_drive.integral_gain": 56.0, "top_drive.feedback_gain": 7.5e-4,
             "top_drive.filter_frequency": 0.33, "top_drive.torque_feedback": "band_pass"}
    law = resolve(replace(make_scenario("default").config, **given))
    assert (law.proportional_gain, law.integral_gain, law.feedback_gain,
            law.filter_frequency, law.torque_feedback) == (1234.0, 56.0, 7.5e-4, 0.33,
                                                            "band_pass")


def test_a_controller_of_your_own_has_the_tuning_of_its_physics():
    """A walkthrough needed private plumbing for the closed-form reflection of its own
    loop (tuning() was the built-in controllers' only); every SetPointController has it,
    the law of its physics() on the config's string."""
    from agents import SetPointController

    class Mine(SetPointController):
        def physics(self):
            return {"top_drive.torque_feedback": "high_pass", "top_drive.feedback_gain": 2.5e-3,
                    "top_drive.filter_frequency": 0.2}

    config = make_scenario("default").config
    law = Mine().tuning(config)
    assert (law.torque_feedback, law.feedback_gain, law.filter_frequency) == (
        "high_pass", 2.5e-3, 0.2)
    assert (law.proportional_gain, law.integral_gain) == (
        StiffPI().tuning(config).proportional_gain, StiffPI().tuning(config).integral_gain)
    assert abs(law.reflection_coefficient(1.0)) < abs(
        StiffPI().tuning(config).reflection_coefficient(1.0))

    class Nested(Mine):  # physics() nested, as the env and benchmark take it too
        def physics(self):
            return {"top_drive": {"torque_feedback": "high_pass", "feedback_gain": 2.5e-3,
                                  "filter_frequency": 0.2}}

    # (whole, the section would have replaced the config's: its inertia back to default)
    heavy = replace(config, **{"top_drive.inertia": 1500.0})
    assert Nested().tuning(heavy) == Mine().tuning(heavy)
    assert Nested().tuning(heavy).inertia == 1500.0


@pytest.mark.parametrize("given", [{}, {"top_drive.controller": "soft_speed"},
                                   {"top_drive.controller": "z_torque",
                                    "top_drive.torque_feedback": "none"}])
def test_a_feedback_gain_for_a_drive_without_torque_feedback_is_refused(given):
    """A gain given to a drive that runs no torque feedback was dropped (resolve's law had
    gain 0): a controller of one's own with ``physics()`` = {feedback_gain: ...} alone
    drilled exactly as stiff PI. It is refused, naming the field and what to set."""
    from drill_env.physics.config import ConfigError

    with pytest.raises(ConfigError, match="^top_drive.feedback_gain: .*would change nothing: "
                                          "set torque_feedback"):
        replace(make_scenario("default").config, **given,
                **{"top_drive.feedback_gain": 3e-3})
    # with a feedback it is the drive's
    law = resolve(replace(make_scenario("default").config,
                          **{**given, "top_drive.feedback_gain": 3e-3,
                             "top_drive.torque_feedback": "high_pass"}))
    assert (law.torque_feedback, law.feedback_gain) == ("high_pass", 3e-3)


def test_modes_shows_a_configs_feedback_gain_under_the_drives_that_run_a_feedback():
    """A review of the refusal above: drill-env modes tunes all four drives on the config,
    and a soft_torque config's feedback_gain made the stiff PI's law an error. The gain is
    each feedback drive's; the others have none."""
    from drill_cli.studies import top_drive_laws

    config = replace(make_scenario("default").config,
                     **{"top_drive.controller": "soft_torque", "top_drive.feedback_gain": 2e-3})
    laws = top_drive_laws(config)
    assert [(law.torque_feedback, law.feedback_gain) for law in laws] == [
        ("none", 0.0), ("none", 0.0), ("band_pass", 2e-3), ("high_pass", 2e-3)]


def test_a_stiff_drive_with_torque_feedback_tunes_its_filter_to_the_string():
    """A stiff PI given a high-pass torque feedback and no corner: the corner follows the
    ZTorque rule on the string's stick-slip frequency, as for ZTorque itself (it was
    left at NaN when only non-stiff controllers looked the frequency up)."""
    config = make_scenario("default").config
    stiff = resolve(replace(config, **{"top_drive.torque_feedback": "high_pass"}))
    z_torque = resolve(replace(config, **{"top_drive.controller": "z_torque"}))
    assert math.isfinite(stiff.filter_frequency) and stiff.filter_frequency > 0.0
    assert stiff.filter_frequency == pytest.approx(z_torque.filter_frequency, rel=1e-12)


def test_a_torque_filter_too_fast_for_the_step_is_refused_by_name():
    """The filter's semi-implicit update keeps its phase error under ~10 % while
    2 pi f dt <= 0.5 (top_drive.MAX_FILTER_W_DT's reason): 0.4 runs, 0.6 is refused
    naming the field."""
    from drill_env.physics.simulator import Simulator
    from drill_env.physics.validation import ConfigError

    config = make_scenario("default").config
    dt = config.solver.time_step
    for w_dt, refused in ((0.4, False), (0.6, True)):
        cfg = replace(config, **{"top_drive.controller": "z_torque",
                                 "top_drive.filter_frequency": w_dt / (2 * math.pi * dt)})
        if refused:
            with pytest.raises(ConfigError, match="^top_drive.filter_frequency: .*too fast"):
                Simulator(cfg)
        else:
            assert Simulator(cfg).dt == dt


def test_the_tuning_frequency_carries_the_bits_inertia():
    """The soft controllers tune to the string's first torsional mode with the bit on it:
    a heavy end inertia (50 kg m^2, a mud motor's rotor and bit, say) lowers the mode
    0.66 -> 0.48 Hz on the paper string (``SimulationConfig()``; exact continuous
    shafts, transfer matrices); the tuning frequency follows to the mesh error (~1e-5)."""
    for inertia in (0.3, 50.0):
        config = SimulationConfig(bit=BitConfig(inertia=inertia))
        exact = transfer_matrix_frequency(config.string.sections, inertia, 2.0)
        assert SoftSpeed().tuning(config).tuning_frequency == pytest.approx(exact, rel=1e-4)
    light = transfer_matrix_frequency(config.string.sections, 0.3, 2.0)
    assert exact < 0.8 * light


def test_soft_speed_cancels_the_top_drive_inertia_at_its_tuning_frequency():
    """At f_s the I-term's impedance I / (j w) cancels the inertia's j w J_td: the top is
    the real k Z, and reflects (1 - k) / (1 + k)."""
    _, config, z, _ = STRINGS[0]
    law = SoftSpeed().tuning(config)
    z_td = law.impedance_at(law.tuning_frequency)
    assert z_td.imag == pytest.approx(0.0, abs=1e-9 * abs(z_td))
    k = config.top_drive.impedance_factor
    assert z_td.real == pytest.approx(k * z, rel=1e-9)
    assert abs(law.reflection_coefficient(law.tuning_frequency)) == pytest.approx(
        (k - 1) / (k + 1), rel=1e-9)


def test_z_torque_filter_corner_is_where_the_high_pass_is_3_db_down():
    _, config, _, _ = STRINGS[0]
    law = ZTorque().tuning(config)
    h = law.filter_response(law.filter_frequency)
    assert abs(h) == pytest.approx(1 / math.sqrt(2), rel=1e-12)
    assert math.degrees(math.atan2(h.imag, h.real)) == pytest.approx(45.0, rel=1e-12)
    assert abs(law.filter_response(100 * law.filter_frequency)) > 0.9999
    assert abs(law.filter_response(1e-4 * law.filter_frequency)) < 1e-3


@pytest.fixture(scope="module")
def reflections():
    """Measured (pulse) and closed-form reflection at the top, per controller, at the
    filter corner, half, once and twice the stick-slip frequency."""
    config = make_scenario("default").config
    out = {}
    for name in ("stiff", "soft-speed", "soft-torque", "z-torque"):
        controller = make_controller(name)
        cfg = replace(config, **controller.physics())
        law = resolve(cfg)
        f_s = resolve(replace(config, **{"top_drive.controller": "soft_speed"})
                      ).tuning_frequency
        freqs = np.array([0.25 * f_s, 0.5 * f_s, f_s, 2.0 * f_s])
        measured = measured_reflection(cfg, freqs)
        theory = np.array([law.reflection_coefficient(f) for f in freqs])
        out[name] = (measured, theory)
    return out


@pytest.mark.parametrize("name", ["stiff", "soft-speed", "soft-torque", "z-torque"])
def test_the_pulse_reflection_matches_the_top_drive_impedance(reflections, name):
    """The compiled controller (filters, one-step torque delay, FE string) against
    (Z - Z_td) / (Z + Z_td) from its transfer function: this checks the filter corners
    and centres numerically, in the time domain."""
    measured, theory = reflections[name]
    assert np.abs(measured - theory).max() < 0.03


def test_tuned_controllers_absorb_at_their_frequency_and_stiff_reflects(reflections):
    """Stiff PI reflects nearly everything; the torque-feedback loops absorb at f_s;
    SoftSpeed's top is the damper k Z there, reflecting (k - 1)/(k + 1) (Kyllingstad &
    Nessjoen 2009: its integral term cancels the top-drive inertia at f_s), and more away
    from f_s, where the inertia shows again."""
    f_s_index = 2
    assert abs(reflections["stiff"][0][f_s_index]) > 0.9
    # the stiff drive's top by hand: Z_td = P + I / (j w) + j w J_td, P = 50 Z, I = 5 J_td
    # (Kyllingstad & Nessjoen's factory tuning), Z of the pipe's tube: |r| = 0.96 at f_s
    (_, config, z, f_s), _ = STRINGS
    j, w = config.top_drive.inertia, 2.0 * math.pi * f_s
    z_td = 50.0 * z + 5.0 * j / (1j * w) + 1j * w * j
    by_hand = abs((z - z_td) / (z + z_td))
    assert by_hand == pytest.approx(0.96, abs=0.005)  # docs/controllers.md's table
    assert abs(reflections["stiff"][0][f_s_index]) == pytest.approx(by_hand, abs=0.03)
    for name in ("soft-torque", "z-torque"):
        assert abs(reflections[name][0][f_s_index]) < 0.3, name
    k = TopDriveConfig().impedance_factor
    soft = np.abs(reflections["soft-speed"][0])
    assert soft[f_s_index] == pytest.approx((k - 1.0) / (k + 1.0), abs=0.03)
    assert soft[f_s_index] < min(soft[1], soft[3]) - 0.1
    assert soft[f_s_index] < abs(reflections["stiff"][0][f_s_index]) - 0.3


def _swing(run, start: float, end: float) -> float:
    """Half the bit speed's peak-to-peak (rpm) in ``[start, end)`` s."""
    w = run.channel("bit_speed")[(run.time >= start) & (run.time < end)] / RPM
    return float(w.max() - w.min()) / 2.0


@pytest.mark.slow
@pytest.mark.parametrize(("rpm", "wob"), [(50.0, 100e3), (60.0, 150e3)])
def test_tuned_controllers_cure_stick_slip_at_the_same_mean_speed(rpm, wob):
    """In hard rock on the default string (coupled), where stiff PI stick-slips, SoftSpeed,
    SoftTorque and ZTorque hold the bit steady at the same mean speed, and keep it so:
    the oscillation left from the 1 % kick decays over four minutes. (SoftSpeed at k =
    1.5 passed a 40-80 s window with SSI 0.03, yet its oscillation grew x3 every 15 s to
    full stick-slip by ~90 s: a cure is judged on whether the oscillation shrinks.)"""
    config = make_scenario("default").config
    results = {}
    for name in ("stiff", "soft-speed", "soft-torque", "z-torque"):
        cfg = replace(config, **make_controller(name).physics())
        run = simulate(cfg, rpm, wob, 240.0)
        tail = run.time > 200.0
        results[name] = (stick_slip_summary(run, 200.0)["ssi"],
                         float(np.mean(run.channel("bit_speed")[tail])) / RPM,
                         _swing(run, 120.0, 160.0), _swing(run, 200.0, 240.0))
    ssi_stiff, rpm_stiff, _, _ = results["stiff"]
    assert ssi_stiff > 1.0
    for name in ("soft-speed", "soft-torque", "z-torque"):
        ssi, mean, earlier, late = results[name]
        assert ssi <= 0.02, name
        assert late <= max(earlier, 0.01), (name, earlier, late)  # not growing back
        assert mean == pytest.approx(rpm, abs=0.5), name


def test_registry_names_every_controller_and_refuses_unknown_ones():
    assert parse_controllers("stiff, z-torque") == ["stiff", "z-torque"]
    for name in CLASSICAL:
        assert make_controller(name).name == name
    with pytest.raises(ValueError, match="unknown name 'pid'.*stiff"):
        make_controller("pid")
    with pytest.raises(ValueError, match=r"unknown name 'z_torque' \(did you mean z-torque\?\)"):
        make_controller("z_torque")
    with pytest.raises(ValueError, match="controllers"):
        parse_controllers("stiff,pid")
    with pytest.raises(ValueError, match=r"^controllers: unknown name 'z-torq' \(did you "
                                         r"mean z-torque\?\); known: "):
        parse_controllers("stiff,z-torq")
    for typed in ("stiff,,z-torque", "stiff,"):  # a name left out: dropped, unsaid
        with pytest.raises(ValueError, match=r"^controllers: an empty name in "):
            parse_controllers(typed)


class FakeEnv:
    """What a controller reads from an env: targets, action mapping, control interval."""

    class config:  # noqa: N801 - mimics EnvConfig's attribute
        control_interval = 0.1
        rpm_range = (0.0, 200.0)

    def __init__(self, rpm: float, wob: float) -> None:
        self.targets = (rpm * RPM, wob)

    def action_for(self, speed: float, wob: float) -> np.ndarray:
        return np.array([speed, wob])


def run_driller(driller: Driller, torque: np.ndarray) -> np.ndarray:
    out = []
    for value in torque:
        out.append(driller.act(np.zeros(1), {"surface_torque": value}))
    return np.array(out)


def test_driller_raises_rpm_then_lowers_wob_on_stick_slip_and_steps_back_when_calm():
    rules = DrillerRules()
    driller = Driller(rules)
    driller.reset(FakeEnv(50.0, 100e3))
    t = np.arange(0, 100.0, 0.1)
    swinging = 10e3 * (1.0 + 0.5 * np.sin(2 * np.pi * 0.5 * t))  # swing 0.5 > 0.15
    actions = run_driller(driller, swinging)
    decisions = len(t) // 50
    raises = round(rules.max_rpm_raise / rules.rpm_step)
    assert actions[-1, 0] == pytest.approx((50.0 + rules.max_rpm_raise) * RPM)
    lowered = decisions - raises
    assert actions[-1, 1] == pytest.approx(
        max(100e3 - lowered * rules.weight_on_bit_step, rules.min_weight_fraction * 100e3))
    # calm: one step back toward the plan every ``calm_decisions`` decisions, WOB first
    calm = np.full(50 * rules.calm_decisions, 10e3)
    actions = run_driller(driller, calm)
    assert actions[-1, 1] == pytest.approx(
        max(100e3 - lowered * rules.weight_on_bit_step, 50e3) + rules.weight_on_bit_step)
    assert actions[-1, 0] == pytest.approx((50.0 + rules.max_rpm_raise) * RPM)
    # and the next step back waits as many calm decisions again, not one
    before = actions[-1].copy()
    assert before[1] + rules.weight_on_bit_step < 100e3  # still below the plan
    actions = run_driller(driller, np.full(50 * (rules.calm_decisions - 1), 10e3))
    np.testing.assert_array_equal(actions[-1], before)
    actions = run_driller(driller, np.full(50, 10e3))
    assert actions[-1, 1] == pytest.approx(before[1] + rules.weight_on_bit_step)
    # once the WOB is back at the plan, the speed steps back one rpm_step at a time (a
    # mutation test: a jump straight back to the planned rpm passed every test)
    stints = np.array([run_driller(driller, calm)[-1] for _ in range(14)])
    back = int(np.argmax(stints[:, 1] >= 100e3 - 1e-6))  # the stint the WOB got back in
    assert stints[back, 1] == pytest.approx(100e3) and back < 8
    raised = (50.0 + rules.max_rpm_raise) * RPM
    np.testing.assert_allclose(stints[: back + 1, 0], raised, rtol=1e-12)  # (WOB first)
    steps = round(rules.max_rpm_raise / rules.rpm_step)
    expected = [raised - k * rules.rpm_step * RPM for k in range(1, steps + 1)]
    np.testing.assert_allclose(stints[back + 1: back + 1 + steps, 0], expected, rtol=1e-12)
    np.testing.assert_allclose(stints[back + 1 + steps:, 0], 50.0 * RPM, rtol=1e-12)


def test_driller_acts_at_its_torque_swing_threshold():
    """The swing is (max - min) / (2 mean) of the surface torque over a decision: for
    T = m (1 + a sin) it is a. Just above the threshold (0.15) the first decision raises
    the speed one step; just below it nothing moves."""
    rules = DrillerRules()
    t = np.arange(0, 5.0, 0.1)  # one decision of 50 control steps
    for amplitude, raised in ((rules.torque_swing + 0.03, True),
                              (rules.torque_swing - 0.03, False)):
        driller = Driller(rules)
        driller.reset(FakeEnv(50.0, 100e3))
        # the peaks fall on samples: a quarter period is 5 steps of 0.1 s at 0.5 Hz
        actions = run_driller(driller, 10e3 * (1.0 + amplitude * np.sin(np.pi * t)))
        want = 50.0 + (rules.rpm_step if raised else 0.0)
        assert actions[-1, 0] == pytest.approx(want * RPM)
        assert actions[-1, 1] == pytest.approx(100e3)


def test_driller_raises_the_speed_no_higher_than_the_env_drills():
    """A plan of 170 rpm in a 0-200 rpm env: three raises reach the top of the range,
    and the next decisions take weight off instead of asking for clipped speeds."""
    rules = DrillerRules()
    driller = Driller(rules)
    driller.reset(FakeEnv(170.0, 100e3))
    t = np.arange(0, 30.0, 0.1)  # six decisions
    swinging = 10e3 * (1.0 + 0.5 * np.sin(2 * np.pi * 0.5 * t))
    actions = run_driller(driller, swinging)
    raises = math.ceil((200.0 - 170.0) / rules.rpm_step)
    assert raises < round(rules.max_rpm_raise / rules.rpm_step)  # the range binds first
    assert actions[:, 0].max() == pytest.approx(200.0 * RPM)
    assert actions[-1, 1] == pytest.approx(
        100e3 - (len(t) // 50 - raises) * rules.weight_on_bit_step)


def test_driller_keeps_the_plan_while_drilling_is_smooth():
    driller = Driller()
    driller.reset(FakeEnv(80.0, 120e3))
    actions = run_driller(driller, np.full(3000, 12e3) + 100.0 * np.sin(np.arange(3000)))
    assert np.all(actions[:, 0] == pytest.approx(80.0 * RPM))
    assert np.all(actions[:, 1] == 120e3)


def test_a_constant_set_point_at_the_ends_of_the_env_ranges_is_accepted() -> None:
    """The action ranges are closed: their ends are set points the env drills at."""
    import gymnasium as gym

    from agents import ConstantSetPoints

    env = gym.make("DrillString-v0")
    config = env.unwrapped.config
    (rpm_low, rpm_high), (wob_low, wob_high) = config.rpm_range, config.weight_on_bit_range
    for rpm, wob in ((rpm_low, wob_low), (rpm_high, wob_high)):
        ConstantSetPoints(rpm, wob).check_range(config)
    with pytest.raises(ValueError, match="outside the env's range"):
        ConstantSetPoints(rpm_high + 1.0, wob_high).check_range(config)
    env.close()


def test_a_constant_set_point_drives_the_stiff_top_drive() -> None:
    """"a driller who never adjusts": the factory speed loop, not a tuned one."""
    from agents import ConstantSetPoints

    assert ConstantSetPoints(100.0, 50e3).physics() == {"top_drive.controller": "stiff"}


def test_a_constant_controller_name_reads_rpm_and_kilonewtons() -> None:
    """``constant:<rpm>/<kN>`` (ConstantSetPoints' docstring: "120/100" -> 120 rpm,
    100 kN): the env gets the speed in rad/s (120 x 2 pi / 60) and the WOB in newtons."""
    controller = make_controller("constant:120/100")
    assert controller.rpm == 120.0
    assert controller.speed == pytest.approx(120.0 * 2.0 * math.pi / 60.0, rel=1e-12)
    assert controller.weight_on_bit == pytest.approx(100.0e3, rel=1e-12)


def test_drive_loop_name_maps_each_top_drive_setting_to_its_registry_name() -> None:
    """``drive_loop_name`` (the CLI's "give --controller ... instead"): the
    ``TopDriveConfig.controller`` value of each drive-rate controller gives its registry
    name, e.g. ``soft_speed`` -> ``soft-speed``; an unknown value comes back as typed."""
    from agents.classical import drive_loop_name

    expected = {"stiff": "stiff", "soft_speed": "soft-speed", "soft_torque": "soft-torque",
                "z_torque": "z-torque"}
    for cls in (StiffPI, SoftSpeed, SoftTorque, ZTorque):
        assert drive_loop_name(cls.top_drive) == expected[cls.top_drive] == cls.name
    assert drive_loop_name("no_such_drive") == "no_such_drive"


class _DrillerEnv:
    class config:  # noqa: N801
        control_interval = 0.1
        rpm_range = (0.0, 200.0)

    def __init__(self, rpm, wob, top_rpm=200.0):
        self.targets = (rpm * RPM, wob)
        self.config = type("cfg", (), {"control_interval": 0.1, "rpm_range": (0.0, top_rpm)})

    def action_for(self, speed, wob):
        return np.array([speed, wob])


def _drive(driller, torque):
    return np.array([driller.act(np.zeros(1), {"surface_torque": v}) for v in torque])


def test_driller_does_not_act_at_exactly_its_swing_threshold():
    # DrillerRules: stick-slip when the swing is MORE than torque_swing (0.15)
    from agents.driller import Driller

    d = Driller()
    d.reset(_DrillerEnv(50.0, 100e3))
    torque = np.tile([8.5e3, 11.5e3], 25)  # (11.5-8.5)/(2*10) = 0.15 exactly
    out = _drive(d, torque)
    assert out[-1, 0] == pytest.approx(50.0 * RPM)


def test_driller_steps_the_speed_back_once_the_weight_is_back():
    # module docstring: once calm for a while, step back toward the plan (WOB first,
    # then the rpm)
    from agents.driller import Driller, DrillerRules

    r = DrillerRules()
    d = Driller(r)
    d.reset(_DrillerEnv(50.0, 100e3))
    t = np.arange(0, 5.0, 0.1)
    out = _drive(d, 10e3 * (1.0 + 0.5 * np.sin(np.pi * t)))  # one decision: +10 rpm
    assert out[-1, 0] == pytest.approx(60.0 * RPM)
    out = _drive(d, np.full(50 * r.calm_decisions, 10e3))
    assert out[-1, 0] == pytest.approx(50.0 * RPM)
    assert out[-1, 1] == pytest.approx(100e3)


def test_driller_steps_back_after_calm_decisions_in_a_row_only():
    # DrillerRules.calm_decisions: calm decisions in a row before a step back; stick-slip
    # in between starts the count again (a mutation test: a count kept through a swing
    # stepped back after one calm decision, and passed every test)
    from agents.driller import Driller, DrillerRules

    r = DrillerRules()
    d = Driller(r)
    d.reset(_DrillerEnv(50.0, 100e3))
    swing = 10e3 * (1.0 + 0.5 * np.sin(np.pi * np.arange(0, 5.0, 0.1)))  # one decision
    calm = np.full(50, 10e3)  # one calm decision
    _drive(d, swing)  # +10 rpm
    _drive(d, np.tile(calm, r.calm_decisions - 1))
    _drive(d, swing)  # +10 rpm again
    out = _drive(d, np.tile(calm, r.calm_decisions - 1))
    assert out[-1, 0] == pytest.approx(70.0 * RPM)  # one calm decision short
    out = _drive(d, calm)
    assert out[-1, 0] == pytest.approx(60.0 * RPM)


def test_driller_keeps_at_least_its_minimum_weight_fraction():
    # DrillerRules.min_weight_fraction: the least WOB it keeps (0.5 of the plan)
    from agents.driller import Driller

    d = Driller()
    d.reset(_DrillerEnv(50.0, 95e3, top_rpm=50.0))  # no room to raise: WOB goes first
    t = np.arange(0, 60.0, 0.1)
    out = _drive(d, 10e3 * (1.0 + 0.5 * np.sin(np.pi * t)))
    assert out[:, 1].min() == pytest.approx(0.5 * 95e3)


def test_driller_steps_the_weight_back_no_further_than_the_plan():
    # module docstring: calm, it steps back *toward* the planned set points; from the
    # floor of a 95 kN plan (47.5 kN) four 10 kN steps reach 87.5 kN and the fifth stops
    # at 95, not 97.5 (a mutation test: a step back past the plan passed every test)
    from agents.driller import Driller, DrillerRules

    r = DrillerRules()
    d = Driller(r)
    d.reset(_DrillerEnv(50.0, 95e3, top_rpm=50.0))  # no room to raise: WOB goes first
    t = np.arange(0, 30.0, 0.1)  # six decisions: 85, 75, 65, 55 kN, then the floor
    out = _drive(d, 10e3 * (1.0 + 0.5 * np.sin(np.pi * t)))
    assert out[-1, 1] == pytest.approx(0.5 * 95e3)
    out = _drive(d, np.full(50 * r.calm_decisions * 6, 10e3))  # room for six steps back
    assert out[:, 1].max() == pytest.approx(95e3)
    assert out[-1] == pytest.approx([50.0 * RPM, 95e3])


def test_driller_raises_to_the_top_of_the_range_and_steps_back_to_the_plan_off_its_grid():
    # a plan of 175 rpm in a 0-200 rpm env is not a whole number of rpm_steps from
    # either end: the third raise stops at 200 (not 205), and the third step back at 175
    # (not 170) (a mutation test: both limits dropped passed every test, whose plans
    # reached the range's top and came back in whole steps)
    from agents.driller import Driller, DrillerRules

    r = DrillerRules()
    d = Driller(r)
    d.reset(_DrillerEnv(175.0, 100e3))
    swing = 10e3 * (1.0 + 0.5 * np.sin(np.pi * np.arange(0, 15.0, 0.1)))  # 3 decisions
    out = _drive(d, swing)
    assert out[49::50, 0] / RPM == pytest.approx([185.0, 195.0, 200.0])
    assert out[-1, 1] == pytest.approx(100e3)  # (the WOB untouched: the rpm went first)
    out = _drive(d, np.full(50 * r.calm_decisions * 4, 10e3))  # room for four steps back
    steps = out[50 * r.calm_decisions - 1::50 * r.calm_decisions, 0] / RPM
    assert steps == pytest.approx([190.0, 180.0, 175.0, 175.0])


def test_driller_takes_a_new_plan_at_once():
    # the targets may change during an episode (a control task's driller moves them):
    # the driller asks for the new set points from that step on, not the old plan's or
    # its own steps away from it (a mutation test: a driller that kept the first plan
    # passed every test)
    from agents.driller import Driller, DrillerRules

    r = DrillerRules()
    d = Driller(r)
    env = _DrillerEnv(50.0, 100e3)
    d.reset(env)
    swing = 10e3 * (1.0 + 0.5 * np.sin(np.pi * np.arange(0, 5.0, 0.1)))  # one decision
    assert _drive(d, swing)[-1] == pytest.approx([60.0 * RPM, 100e3])
    env.targets = (80.0 * RPM, 120e3)
    out = _drive(d, np.full(50, 10e3))
    np.testing.assert_allclose(out, np.tile([80.0 * RPM, 120e3], (50, 1)), rtol=1e-12)
    out = _drive(d, swing)  # and its steps are taken from the new plan
    assert out[-1] == pytest.approx([90.0 * RPM, 120e3])


def test_driller_decides_every_decision_period_of_each_episode():
    # DrillerRules.decision_period over the env's control interval, rounded: 0.3 s is
    # 3 steps of 0.1 s (0.3 / 0.1 is 2.9999999999999996: cut to 2 it decided every
    # 0.2 s), one shorter than half an interval is every step (rounded to 0 steps it
    # raised ZeroDivisionError at the first step), and the count starts again at each
    # reset (kept, a second episode's first decision came after 20 steps of it, on 20
    # torque samples: mutation tests)
    from agents.driller import Driller, DrillerRules

    swing = np.tile([10e3, 5e3, 15e3], 4)  # any three in a row: swing 0.5
    d = Driller(DrillerRules(decision_period=0.3))
    d.reset(_DrillerEnv(50.0, 100e3))
    out = _drive(d, swing)
    assert out[:, 0] / RPM == pytest.approx([50.0] * 2 + [60.0] * 3 + [70.0] * 3 + [80.0] * 3
                                            + [90.0])
    d = Driller(DrillerRules(decision_period=0.01))
    d.reset(_DrillerEnv(50.0, 100e3))  # one torque sample a decision: never a swing
    assert _drive(d, swing) == pytest.approx(np.tile([50.0 * RPM, 100e3], (12, 1)))
    d = Driller()
    env = _DrillerEnv(50.0, 100e3)
    d.reset(env)
    _drive(d, np.full(30, 10e3))  # an episode cut short mid-decision
    d.reset(env)
    out = _drive(d, 10e3 * (1.0 + 0.5 * np.sin(np.pi * np.arange(0, 5.0, 0.1))))
    assert out[:-1, 0] == pytest.approx(50.0 * RPM)  # its first decision after 50 steps
    assert out[-1, 0] == pytest.approx(60.0 * RPM)


def test_driller_reads_the_size_of_the_surface_torque_swing_whatever_its_sign():
    # (max - min) / (2 |mean|): a torque reported with the other sign swings as much (a
    # mutation test: the mean's sign kept, a negative torque never read as stick-slip)
    from agents.driller import Driller

    t = np.arange(0, 5.0, 0.1)
    for sign in (1.0, -1.0):
        d = Driller()
        d.reset(_DrillerEnv(50.0, 100e3))
        out = _drive(d, sign * 10e3 * (1.0 + 0.5 * np.sin(np.pi * t)))
        assert out[-1, 0] == pytest.approx(60.0 * RPM), sign


def test_driller_reads_a_string_at_rest_as_calm_without_a_warning():
    # no surface torque at all (mean 0): the swing is 0, not 0/0 (numpy's "invalid
    # value encountered" warning at every decision of a string at rest)
    import warnings

    from agents.driller import Driller

    d = Driller()
    d.reset(_DrillerEnv(50.0, 100e3))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        out = _drive(d, np.zeros(100))
    assert out[-1] == pytest.approx([50.0 * RPM, 100e3])


def test_driller_runs_on_the_stiff_pi_whatever_the_config_names():
    # module docstring: the top drive keeps its stiff PI loop, also under a config that
    # names another loop; a set-point controller of your own names none (docs/
    # controllers.md: the config's loop) (mutation tests: both passed every test, the
    # default config's loop being the stiff PI)
    from agents.base import SetPointController

    soft = replace(make_scenario("default").config, **{"top_drive.controller": "soft_speed"})
    assert Driller().tuning(soft).controller == "stiff"
    assert SetPointController().physics() == {}
    assert SetPointController().tuning(soft).controller == "soft_speed"


def test_set_point_controller_asks_for_speed_then_wob():
    from agents.base import SetPointController

    class Env:
        targets = (5.0, 1.0e5)

        def action_for(self, surface_speed, weight_on_bit):
            return (surface_speed, weight_on_bit)

    c = SetPointController()
    c.reset(Env())
    assert c.act(np.zeros(3), {}) == (5.0, 1.0e5)


def test_soft_speed_refuses_a_zero_tuning_frequency():
    from drill_env.physics.top_drive import soft_speed_gains

    # docstring/error text: "must be > 0 Hz"
    with pytest.raises(ValueError):
        soft_speed_gains(1.0, 1.0, 0.0, 4.0)
    kp, ki = soft_speed_gains(2.0, 3.0, 1.0, 4.0)  # P = kZ = 8, I = (2 pi)^2 * 3
    assert kp == pytest.approx(8.0) and ki == pytest.approx(4 * np.pi**2 * 3.0)


def test_a_top_drive_with_both_gains_zero_is_said_to_be_a_free_top():
    """Both PI gains 0 (a study's free top, or a typo) ran without a word and read as mild
    stick-slip (an outside review); it warns now, naming both fields."""
    import warnings

    from drill_env.physics.config import SimulationConfig, replace
    from drill_env.physics.top_drive import resolve

    free = replace(SimulationConfig(), **{"top_drive.proportional_gain": 0.0,
                                          "top_drive.integral_gain": 0.0})
    with pytest.warns(UserWarning, match="proportional_gain, top_drive.integral_gain: both 0"):
        law = resolve(free)
    assert law.proportional_gain == law.integral_gain == 0.0
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        resolve(replace(SimulationConfig(), **{"top_drive.integral_gain": 0.0}))


def test_a_controller_class_of_a_notebook_is_refused_with_what_to_do(monkeypatch, tmp_path):
    """In Jupyter, a class defined in a cell given as ``__main__:GentlePI`` failed deep in
    inspect ("source code not available"), and the class itself as a controller with
    "'type' object has no attribute 'startswith'" (an outside check): worker processes
    import a controller by name and stored rows follow its file, so both are refused up
    front, saying to save it in a .py file."""
    import sys
    import types

    from agents import SetPointController
    from agents.benchmark import run_benchmark
    from agents.registry import make_controller

    class GentlePI(SetPointController):
        pass

    prompt = types.ModuleType("__main__")  # a notebook's: no __file__
    prompt.GentlePI = GentlePI
    monkeypatch.setitem(sys.modules, "__main__", prompt)
    with pytest.raises(ValueError, match=r"__main__ is a notebook or the interactive prompt "
                                         r"here: .* give file.py:ClassName"):
        make_controller("__main__:GentlePI")
    with pytest.raises(TypeError, match=r"controllers: names, not type objects .* "
                                        r"'file.py:ClassName'.* save it in a .py file"):
        run_benchmark([GentlePI, "stiff"], ["stick_slip"], [0], tmp_path)
    with pytest.raises(ValueError, match="__main__ is a notebook"):
        run_benchmark(["__main__:GentlePI"], ["stick_slip"], [0], tmp_path / "out")
    assert not (tmp_path / "out").exists()  # refused before its folder is made
