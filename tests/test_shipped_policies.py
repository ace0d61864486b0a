"""The shipped policies (``agents/trained``) against the trivial policies, on held-out
seeds: each action held at -1, 0 and +1, random actions, and for the drilling task the
best constant set point of a grid search on training seeds.

"Measurably below": on the 20 held-out seeds the policy's episode returns exceed the
other's in a one-sided paired t-test (the seeds pair the episodes: the same string, rock
and targets) at p < 0.01 for the trivial policies. The best constant set point, the best
of a 5 x 5 grid chosen on 8 training seeds (as ``drill-env evaluate`` chooses it), is the
strongest of these baselines: the policy must beat it at p < 0.05. docs/tasks.md
("Where it loses") gives the measured p and why the margin is smaller there.

With one model and fixed seeds these tests are deterministic: a regression check that
the shipped models keep their margins as the simulator changes, not a new significance
claim. The held-out seeds chose task 2's recipe (its 600k steps), so they are a
development set; docs/tasks.md "Fresh seeds" gives the margins on 100 seeds no choice
has seen (smaller against the best constant), and its power note: at the fresh seeds'
effect size against the constant, 20 seeds would pass a retrained model as good as this
one about half the time, so a retrain is judged on those 100 seeds, not by this test.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import drill_env  # noqa: F401
from agents.learned import TRAINED, LearnedController
from agents.registry import TRIVIAL, make_controller
from drill_env.scenarios import EVALUATION_SEEDS
from training.evaluate import acting, returns_on

SEEDS = EVALUATION_SEEDS


def returns_of(env_id: str, make_act, **env_kwargs) -> np.ndarray:
    return returns_on(gym.make(env_id, **env_kwargs), SEEDS, make_act)


def assert_clearly_better(policy: np.ndarray, other: np.ndarray, name: str,
                          alpha: float = 0.01) -> None:
    from scipy.stats import ttest_rel

    diff = policy - other
    p = ttest_rel(policy, other, alternative="greater").pvalue
    assert p < alpha, (f"{name}: policy {policy.mean():.1f} vs {other.mean():.1f} (paired "
                       f"difference {diff.mean():.1f}, p = {p:.4f}, needs < {alpha})")


@pytest.mark.parametrize("task", ["stick_slip", "drilling"])
def test_shipped_policy_beats_the_trivial_policies(task):
    if not (TRAINED / task / "model.zip").exists():
        pytest.fail(f"no shipped policy in {TRAINED / task}")
    controller = LearnedController.load(TRAINED / task)
    kwargs = controller.env_kwargs()
    policy = returns_of(controller.env_id, acting(controller), **kwargs)
    for name in TRIVIAL:  # held:-1, held:0, held:1, random, as drill-env evaluate runs them
        other = returns_of(controller.env_id, acting(make_controller(name)), **kwargs)
        assert_clearly_better(policy, other, name)


def test_shipped_drilling_policy_beats_the_best_constant_set_point(tmp_path):
    """The grid search of ``drill-env evaluate`` (``training.evaluate.best_constant``: 5 x 5
    over the action range, mean return on ``GRID_SEEDS``, training seeds) picks the
    constant; on held-out seeds the policy does better at p < 0.05."""
    from agents.classical import ConstantSetPoints
    from training.evaluate import best_constant

    controller = LearnedController.load(TRAINED / "drilling")
    name, _ = best_constant(tmp_path, workers=2, progress=False)
    constant = ConstantSetPoints.parse(name.partition(":")[2])
    policy = returns_of(controller.env_id, acting(controller), **controller.env_kwargs())
    held_out = returns_of(controller.env_id, acting(constant), **controller.env_kwargs())
    assert_clearly_better(policy, held_out, name, alpha=0.05)


@pytest.mark.parametrize("task", ["stick_slip", "drilling"])
def test_the_shipped_policies_run_under_the_settings_they_are_tested_under(task):
    """Each shipped policy's ``trained_with.json`` holds the task settings its tests above
    pass it under; a task default moved since (its history, telemetry, a reward weight,
    the fidelity level) fails here by name: retrain the policy, or measure it under the
    new default and write the record again. A user's run is checked the same way when
    it is evaluated (a note) or resumed (refused)."""
    from agents.learned import moved_settings_note
    from training.config import TASKS, read_trained_with, settings_changes, trained_settings

    record = read_trained_with(TRAINED / task)
    assert record is not None and record["env_id"] == TASKS[task]
    assert not settings_changes(record, trained_settings(TASKS[task], {}))
    assert moved_settings_note("learned", TRAINED / task, TASKS[task], {}) is None
