"""Test-session settings.

Hypothesis draws the same examples on every run by default ("ci" profile), so CI on a
fresh clone is reproducible; ``HYPOTHESIS_PROFILE=explore`` draws new ones (run it
now and then to look for new failures, and keep any it finds as a plain test)."""

import os

import pytest
from hypothesis import settings

settings.register_profile("ci", derandomize=True)
settings.register_profile("explore", derandomize=False)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))


@pytest.fixture(autouse=True, scope="session")
def sb3_log_folder(tmp_path_factory):
    """Stable-Baselines3 gives every ``learn`` without a logger of its own a new folder
    in the system's temporary directory (``SB3-<date>``), which nothing removes; the
    tests' models log into one folder under pytest's own temporary directory."""
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("SB3_LOGDIR", str(tmp_path_factory.mktemp("sb3")))
        yield
