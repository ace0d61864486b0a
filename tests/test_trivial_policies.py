"""The trivial policies as controllers (agents.trivial): what they send, their names in
the tables, and that they are the baselines docs/tasks.md quotes; the paired comparison
``drill-env evaluate`` prints against them."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.stats import t as student_t

import drill_env  # noqa: F401  (registers the ids)
from agents.registry import TRIVIAL, canonical, make_controller, parse_controllers
from agents.settings import label, labels
from agents.tables import sets_own_speed
from drill_env.physics.units import RPM
from training.evaluate import paired_comparison


def _play(env, controller, seed: int) -> tuple[float, list[np.ndarray]]:
    """Return and actions of one episode of ``controller`` (reset after the env's)."""
    obs, info = env.reset(seed=seed)
    controller.reset(env.unwrapped)
    total, sent = 0.0, []
    while True:
        action = controller.act(obs, info)
        sent.append(np.array(action))
        obs, reward, terminated, truncated, info = env.step(action)
        total += float(reward)
        if terminated or truncated:
            return total, sent


def test_random_actions_repeat_per_seed_on_a_stream_of_their_own() -> None:
    """An episode of a seed repeats its draws (the benchmark's and scripts/fresh_seeds.py's
    "random" rows are one baseline), another seed draws others; the draws are not the
    env's own stream (``default_rng(seed)``, which sets the targets and rocks: an action
    repeated the draw that set the target rpm); resets without a seed draw on."""
    env = gym.make("DrillStickSlip-v0", episode_duration=3.0)
    controller = make_controller("random")
    total, sent = _play(env, controller, 7)
    again, sent_again = _play(env, controller, 7)
    actions = np.concatenate(sent)
    assert again == total and np.array_equal(actions, np.concatenate(sent_again))
    assert _play(env, controller, 8)[0] != total
    assert np.ptp(actions) > 1.0 and np.all(np.abs(actions) <= 1.0)  # drawn every step
    own = np.random.default_rng(7).uniform(-1, 1, actions.size).astype(np.float32)
    assert not np.any(actions == own)
    firsts = []
    for _ in range(2):
        obs, info = env.reset()
        controller.reset(env.unwrapped)
        firsts.append(float(controller.act(obs, info)[0]))
    assert len({*firsts, float(actions[0])}) == 3
    # seed 0, the benchmark's first, is a seed like any other: its draws repeat
    zero = []
    for _ in range(2):
        obs, info = env.reset(seed=0)
        controller.reset(env.unwrapped)
        zero.append(controller.act(obs, info).copy())
    np.testing.assert_array_equal(*zero)
    env.close()


def test_held_actions_command_the_ends_of_the_ranges() -> None:
    """In DrillString-v0 held at +1 / -1 asks for the top / bottom of the rpm and WOB
    ranges (the env's action mapping), one value per action when given so."""
    env = gym.make("DrillString-v0", scenario="default", episode_duration=0.5)
    config = env.unwrapped.config
    for name, rpm, wob in (("held:1", config.rpm_range[1], config.weight_on_bit_range[1]),
                           ("held:-1", config.rpm_range[0], config.weight_on_bit_range[0]),
                           ("held:1/-1", config.rpm_range[1], config.weight_on_bit_range[0])):
        controller = make_controller(name)
        obs, info = env.reset(seed=0)
        controller.reset(env.unwrapped)
        _, _, _, _, info = env.step(controller.act(obs, info))
        assert info["speed_setpoint"] == pytest.approx(rpm * RPM, rel=1e-6), name
        assert info["weight_on_bit_setpoint"] == pytest.approx(wob, rel=1e-6), name
    with pytest.raises(ValueError, match=r"held:1/0/1: 3 values for an action of 2; give "
                                         "one value or 2"):
        make_controller("held:1/0/1").reset(env.unwrapped)
    env.close()
    task = gym.make("DrillStickSlip-v0", episode_duration=0.5)
    controller = make_controller("held:0.5")
    controller.reset(task.unwrapped)
    np.testing.assert_array_equal(controller.act(None, {}), np.array([0.5], np.float32))
    task.close()
    # their rpm is their own choice (marked in the tables) but in task 1, where the
    # action corrects the speed around the driller's target
    assert sets_own_speed("held+1") and sets_own_speed("random", "DrillOptimise-v0")
    assert not sets_own_speed("held+1", "DrillStickSlip-v0")
    assert not sets_own_speed("random", "DrillStickSlip-v0")


@given(st.lists(st.floats(-1.0, 1.0), min_size=1, max_size=2))
def test_a_held_action_is_run_again_by_its_table_name(values: list[float]) -> None:
    """``held:...`` -> its table name -> ``held:...`` with the same values (to the
    table's 15 digits), a name
    ``benchmark.csv`` can hand back to --controllers (and file names can hold)."""
    name = "held:" + "/".join(repr(v) for v in values)
    table = label(name)
    assert all(c.isalnum() or c in "+-." for c in table)
    back = canonical(table)
    assert "+" not in back  # the registry's form: held+1-0.5 -> held:1/-0.5 (from_label)
    assert label(back) == table  # one name for one held action
    # the table names a value to 15 significant digits, as it does constant set points
    np.testing.assert_allclose(make_controller(back).values, values, rtol=1e-14, atol=1e-300)


def test_bad_held_names_are_refused_by_name() -> None:
    for typed, said in (("held:2", "each value must be in [-1, 1]"),
                        ("held:nan", "each value must be in [-1, 1]"),
                        ("held:x", "held:<a>[/<a2>] expected")):
        with pytest.raises(ValueError) as err:
            parse_controllers(typed)
        text = str(err.value)
        assert text.startswith("controllers: ") and typed in text and said in text, text
    with pytest.raises(ValueError, match="held:1, held:1.0 are the same held actions"):
        labels(["held:1", "held:1.0"])
    with pytest.raises(ValueError, match="held:0, held:-0 are the same held actions"):
        labels(["held:0", "held:-0"])
    from agents.trivial import HeldAction

    assert HeldAction.from_label("heldout") is None  # a class of yours may be so named
    # the count of values against the env's action, before any episode runs
    from agents.benchmark import check_held_actions

    check_held_actions(["held:1/-1", "stiff"], None)  # DrillString-v0: rpm and WOB
    with pytest.raises(ValueError, match=r"^controllers: held:1/-1: 2 values for an action "
                                         r"of 1; give one value \(DrillStickSlip-v0\)"):
        check_held_actions(["held:1/-1"], "DrillStickSlip-v0")
    assert parse_controllers(",".join(TRIVIAL)) == list(TRIVIAL)


def test_paired_comparison_pairs_by_seed() -> None:
    """Rows in any order: the lead, wins and p of each controller from the returns of the
    same seeds; p against the one-sided t distribution of the differences by hand."""
    learned = {1: 10.0, 2: 20.0, 3: 30.0, 4: 40.0}
    other = {4: 36.0, 2: 19.0, 1: 8.0, 3: 27.0, 9: 1e6}  # seed 9: the policy has none
    rows = [{"controller": "other", "seed": s, "episode_return": r} for s, r in other.items()]
    rows += [{"controller": "learned", "seed": s, "episode_return": r}
             for s, r in reversed(learned.items())]
    rows += [{"controller": "same", "seed": s, "episode_return": r,
              "termination": "surface torque above make-up torque" if s == 2 else ""}
             for s, r in learned.items()]
    (c, same) = paired_comparison(rows)
    assert (c["ended_early"], same["ended_early"], same["policy_ended_early"]) == (0, 1, 0)
    diff = np.array([2.0, 1.0, 3.0, 4.0])
    t = diff.mean() / (diff.std(ddof=1) / math.sqrt(4))
    assert c["controller"] == "other" and c["seeds"] == 4 and c["wins"] == 4
    assert c["lead"] == pytest.approx(2.5) and c["return"] == pytest.approx(22.5)
    assert c["p"] == pytest.approx(student_t.sf(t, 3), rel=1e-9)
    # the lead's 95 % interval: mean +- t(0.975, 3) s / sqrt(4), by hand; the median lead
    half = student_t.ppf(0.975, 3) * diff.std(ddof=1) / math.sqrt(4)
    assert c["lead_ci"] == pytest.approx((2.5 - half, 2.5 + half), rel=1e-9)
    assert c["median_lead"] == pytest.approx(2.5)
    assert c["p_holm"] == c["p"]  # the only test made: nothing to adjust
    assert same["wins"] == 0 and math.isnan(same["p"])  # no spread: no test
    assert math.isnan(same["p_holm"]) and all(map(math.isnan, same["lead_ci"]))
    assert c["comparisons"] == 1  # the untested one (no spread) is not one of Holm's m
    # two scenarios with the same seeds are two episodes each, not one overwritten
    rows = [{"controller": c, "scenario": sc, "seed": 0, "episode_return": r}
            for c, sc, r in (("learned", "a", 5.0), ("learned", "b", 7.0),
                             ("other", "a", 1.0), ("other", "b", 6.0))]
    (c,) = paired_comparison(rows)
    assert (c["seeds"], c["wins"], c["lead"]) == (2, 2, pytest.approx(2.5))


def test_holms_adjustment_by_hand() -> None:
    """Holm (1979): the k-th smallest of m p values times m - k + 1, never below the one
    before it in that order, at most 1; a NaN (no test made) is not one of the m."""
    from training.evaluate import holm

    # sorted 0.005, 0.01, 0.03, 0.04 -> 0.02, 0.03, 0.06, max(0.06, 0.04)
    assert holm([0.01, 0.04, 0.03, 0.005]) == pytest.approx([0.03, 0.06, 0.06, 0.02])
    adjusted = holm([0.2, math.nan, 0.6])
    assert adjusted[0] == pytest.approx(0.4) and adjusted[2] == pytest.approx(0.6)
    assert math.isnan(adjusted[1])
    assert holm([0.5, 0.6, 0.7]) == [1.0, 1.0, 1.0]
    assert holm([]) == []


def test_holm_counts_controllers_with_the_same_returns_once() -> None:
    """Task 1's stiff PI and the action held at 0 are one controller under two names:
    counted twice, they made every other adjusted p larger (an outside check)."""
    from training.evaluate import holm

    learned = [10.0, 20.0, 30.0, 40.0]
    others = {"a": [8.0, 19.0, 27.0, 36.0], "b": [8.0, 19.0, 27.0, 36.0],
              "c": [9.0, 18.0, 29.0, 30.0]}
    rows = [{"controller": "learned", "seed": s, "episode_return": r}
            for s, r in enumerate(learned)]
    rows += [{"controller": name, "seed": s, "episode_return": r}
             for name, values in others.items() for s, r in enumerate(values)]
    a, b, c = paired_comparison(rows)
    assert a["comparisons"] == b["comparisons"] == c["comparisons"] == 2
    expected = holm([a["p"], c["p"]])
    assert a["p_holm"] == b["p_holm"] == expected[0] and c["p_holm"] == expected[1]
    # the text's m is Holm's, not the rows': three rows, two comparisons
    from training.evaluate import comparison_text

    assert "over the 2 comparisons" in comparison_text([a, b, c], 25.0)


def test_skewed_returns_give_the_median_lead_and_the_policys_mean_return(tmp_path) -> None:
    """paired_comparison's docstring: the median lead is the median of the differences, the
    mean the estimate; comparison.md heads with the policy's mean return. Leads 1, 1, 10:
    median 1, mean 4; the policy's returns 11, 11, 20: mean 14, median 11."""
    from training.evaluate import write_comparison

    rows = [{"controller": "learned", "seed": s, "episode_return": r}
            for s, r in enumerate([11.0, 11.0, 20.0])]
    rows += [{"controller": "other", "seed": s, "episode_return": 10.0} for s in range(3)]
    (c,) = paired_comparison(rows)
    assert c["median_lead"] == pytest.approx(1.0) and c["lead"] == pytest.approx(4.0)
    text = write_comparison(rows, "learned", tmp_path, "heading")
    assert "the policy (mean return 14.0)" in text
    assert "| other | 10.0 | +4.0 | " in text and " | +1.0 | 3 of 3 | " in text


def test_the_comparison_pairs_the_metric_window_apart(tmp_path) -> None:
    """comparison.md's second table pairs the returns after the warm-up: a policy that
    leads by 10 on the whole episode by winning its start (window returns 1 below the
    other's on each seed) shows there as trailing, by -1.0 on 3 of 3 seeds against it;
    without window returns (a row of an older version) or where they are the whole
    episode's (no warm-up), no second table."""
    from training.evaluate import write_comparison

    rows = [{"controller": c, "seed": s, "episode_return": r + s, "window_return": w + s}
            for c, r, w in (("learned", 20.0, 4.0), ("other", 10.0, 5.0)) for s in range(3)]
    text = write_comparison(rows, "learned", tmp_path, "heading", warmup=5.0)
    assert "| other | 11.0 | +10.0 | " in text
    whole, _, window = text.partition("## The metric window alone")
    assert whole.startswith("## The whole episode")  # (a new user: the first had no name)
    assert "after the 5 s warm-up" in window and "(mean return 5.0 after the warm-up)" in window
    assert "| other | 6.0 | -1.0 | " in window and " | -1.0 | 0 of 3 | " in window
    assert (tmp_path / "comparison.md").read_text(encoding="utf-8").endswith(window)
    for row in rows:
        row["window_return"] = row["episode_return"]
    assert "metric window" not in write_comparison(rows, "learned", tmp_path, "heading")
    for row in rows:
        del row["window_return"]
    assert "metric window" not in write_comparison(rows, "learned", tmp_path, "heading")


def test_the_comparison_says_why_a_p_is_missing() -> None:
    """comparison_text's notes: one episode a pair has no spread to test ("n/a: one
    episode"); the note that the differences do not vary is for pairs of two or more
    episodes only (a constant lead), not for a single episode's missing p."""
    from training.evaluate import comparison_text

    one = [{"controller": c, "seed": 0, "episode_return": r}
           for c, r in (("learned", 5.0), ("other", 3.0))]
    text = comparison_text(paired_comparison(one), 5.0)
    assert "n/a: one episode a pair" in text and "do not vary" not in text
    # no test at all: no "Holm's method over the 0 comparisons" (a trial's --seeds 1)
    assert "over the 0" not in text and "none here, nor p, Holm" in text
    constant = [{"controller": c, "seed": s, "episode_return": r + s}
                for c, r in (("learned", 5.0), ("other", 3.0)) for s in range(2)]
    text = comparison_text(paired_comparison(constant), 5.5)
    assert "do not vary" in text and "n/a: one episode" not in text
