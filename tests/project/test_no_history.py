"""The repository speaks of the project as it is: no development-history narrative in the documentation or
the code (history lives in git). Words that only a story of how it was made uses are refused."""

from __future__ import annotations

import re

from tests.helpers.paths import ROOT

STORY = re.compile(r"\b((this|next|previous|earlier|last) session|session \d+|work period|until now|as before|"
                   r"previously|used to be|earlier (versions?|builds?)|older (versions?|builds?)|"
                   r"before the (tracer work|fix))\b", re.IGNORECASE)


def _files():
    yield ROOT / "README.md"
    yield from (ROOT / "docs").rglob("*.md")
    for folder in ("usdcrowd", "tools"):
        yield from (ROOT / folder).rglob("*.py")


def test_no_file_tells_how_the_project_was_made():
    found = [f"{path.relative_to(ROOT)}:{n}: {line.strip()[:100]}"
             for path in _files() for n, line in enumerate(path.read_text().splitlines(), 1) if STORY.search(line)]
    assert not found, "\n".join(found)
