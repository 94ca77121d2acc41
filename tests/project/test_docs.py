"""The documentation matches the code: the generated reference is what the code gives, the site builds
in strict mode (a broken link or a page missing from the navigation fails), and the README stays a
first screen that sends readers on."""

from __future__ import annotations

import subprocess
import sys

import pytest

from tests.helpers.paths import ROOT


def test_the_generated_reference_is_what_the_code_gives():
    r = subprocess.run([sys.executable, str(ROOT / "tools" / "make_reference.py"), "--check"], capture_output=True,
                       text=True)
    assert r.returncode == 0, r.stderr


def test_the_site_builds_in_strict_mode(tmp_path):
    pytest.importorskip("mkdocs")
    r = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-q", "-f", str(ROOT / "mkdocs.yml"),
                        "-d", str(tmp_path / "site")], capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 0, r.stderr[-3000:]
    for page in ("index.html", "guides/layout-artist/index.html", "reference/cli/index.html"):
        assert (tmp_path / "site" / page).is_file(), page


def test_the_readme_is_a_first_screen_that_links_every_guide():
    text = (ROOT / "README.md").read_text()
    assert len(text.splitlines()) <= 250
    for guide in sorted((ROOT / "docs" / "guides").glob("*.md")):
        assert f"docs/guides/{guide.name}" in text, guide.name

