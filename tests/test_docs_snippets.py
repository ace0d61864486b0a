"""The Python examples of the README and the docs run as printed (a reader copies them)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = ("README.md", "docs/tasks.md", "docs/recording.md")


def _snippets() -> list[tuple[str, int, str]]:
    out = []
    for page in PAGES:
        text = (ROOT / page).read_text()
        for k, match in enumerate(re.finditer(r"^```python\n(.*?)^```", text, re.M | re.S)):
            out.append((page, k, match.group(1)))
    return out


@pytest.mark.parametrize(("page", "index", "code"), _snippets(),
                         ids=[f"{p}[{k}]" for p, k, _ in _snippets()])
def test_a_python_example_of_the_docs_runs(page, index, code, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # what an example writes (logs/recordings) stays here
    # each example as a reader copies it: nothing defined for it
    exec(compile(code, f"{page} example {index}", "exec"), {})  # noqa: S102


def test_every_page_with_python_examples_is_checked():
    """A page that gains a Python example is run by the test above."""
    pages = {str(p.relative_to(ROOT)) for p in [ROOT / "README.md", *ROOT.glob("docs/*.md")]
             if "```python" in p.read_text()}
    assert pages <= set(PAGES)
    assert len(_snippets()) >= 4
