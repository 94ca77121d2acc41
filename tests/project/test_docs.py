"""The documentation matches the code: the generated reference is what the code gives, the site builds
in strict mode (a broken link or a page missing from the navigation fails), and the README stays a
first screen that sends readers on."""

from __future__ import annotations

import subprocess
import sys

import pytest

from tests.helpers.paths import ROOT
from tests.helpers.tools import load_tool


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


# ---------------------------------------------------------------- figures
docfigures = load_tool("docfigures")


def test_every_documented_figure_comes_from_a_script_and_shows_what_it_measured():
    """Each number in a marker is its data's, each data file's script exists, each picture has a script,
    and no timing, rate or size stands outside a marker."""
    r = subprocess.run([sys.executable, str(ROOT / "tools" / "docfigures.py"), "--check"], capture_output=True,
                       text=True)
    assert r.returncode == 0, r.stderr[-3000:]


@pytest.fixture
def recorded_bench():
    """The data of one measurement, as tools/docfigures.record writes it."""
    return {"bench": {"source": "tools/bench_sim.py", "command": "python tools/bench.py sim", "date": "2026-01-02T03:04:05",
                      "commit": "abc1234", "machine": "2-core test machine, no GPU",
                      "figures": {"rate": {"1000": 820.4}}, "tables": {"t": {"columns": ["a", "b"], "rows": [[1, 2]]}},
                      "images": []}}


def _fill(text, cache):
    problems = []
    return docfigures._fill_page(text, "page.md", dict(cache), problems), problems


def test_a_figure_is_filled_from_its_data_with_its_format(recorded_bench):
    text, problems = _fill("runs <!--fig bench:rate.1000 ,.0f-->?<!--/fig--> steps/s", recorded_bench)
    assert text == "runs <!--fig bench:rate.1000 ,.0f-->820<!--/fig--> steps/s" and not problems
    table, _ = _fill("<!--table bench:t-->\nold\n<!--/table-->", recorded_bench)
    assert table == "<!--table bench:t-->\n| a | b |\n|---|---|\n| 1 | 2 |\n<!--/table-->"
    origin, _ = _fill("<!--from bench-->?<!--/from-->", recorded_bench)
    assert "on 2026-01-02, commit abc1234, on a 2-core test machine" in origin


def test_a_typed_figure_its_missing_data_or_its_missing_script_is_found(recorded_bench):
    assert docfigures._unmarked_measurements("It runs at 820 steps/s on two cores.")
    assert not docfigures._unmarked_measurements("The target is 60 steps/s. Frames at 24 fps.")
    _, problems = _fill("<!--fig bench:rate.5000-->1<!--/fig-->", recorded_bench)
    assert problems and "no figure 'rate.5000'" in problems[0]
    _, problems = _fill("<!--fig other:rate-->1<!--/fig-->", {**recorded_bench, "other": None})
    assert problems and "which no script has written" in problems[0]
    gone = {"bench": {**recorded_bench["bench"], "source": "tools/no_such_bench.py"}}
    _, problems = _fill("<!--fig bench:rate.1000-->820<!--/fig-->", gone)
    assert problems and "tools/no_such_bench.py, which is gone" in problems[0]
