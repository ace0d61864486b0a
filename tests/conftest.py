"""Test-session settings.

Hypothesis draws the same examples on every run by default ("ci" profile), so CI on a
fresh clone is reproducible; ``HYPOTHESIS_PROFILE=explore`` draws new ones (run it
now and then to look for new failures, and keep any it finds as a plain test)."""

import os

from hypothesis import settings

settings.register_profile("ci", derandomize=True)
settings.register_profile("explore", derandomize=False)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))
