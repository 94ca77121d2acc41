"""Every console example in the README and the documentation's pages, run in order as a new user would type
it: the README's tour first, then the pages in the site's order (mkdocs.yml), each command once.

Each ``$ usdcrowd ...`` line must exit 0, and the first line it prints must
have the shape the README shows (numbers may differ: they are masked). The
commands that make pictures run small (``--frames 1:2`` and a small
``--resolution`` are appended, ``--preset preview`` for render, a small
``--resolution`` for edit's video), so the suite stays within its time.
"""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest

from usdcrowd.cli import main

from tests.helpers.paths import ROOT

README = ROOT / "README.md"


def pages() -> list[Path]:
    """The README, then every page of the site in its navigation's order."""
    import yaml

    def walk(nav):
        for item in nav:
            value = next(iter(item.values())) if isinstance(item, dict) else item
            yield from walk(value) if isinstance(value, list) else [value]

    nav = yaml.safe_load((ROOT / "mkdocs.yml").read_text())["nav"]
    return [README] + [ROOT / "docs" / page for page in walk(nav)]
# Appended to the commands that render (the last option given wins in argparse).
QUICK = {"preview": ["--frames", "1:2", "--resolution", "64x36"], "edit": ["--resolution", "64x36"],
         "render": ["--frames", "1:2", "--resolution", "64x36", "--preset", "preview", "--spp", "1"]}


def console_examples(text: str) -> list[tuple[str, list[str]]]:
    """(command line, the lines the README shows it print) for every ``$`` line of every console block."""
    examples = []
    for block in re.findall(r"```console\n(.*?)```", text, flags=re.S):
        for line in block.splitlines():
            if line.startswith("$ "):
                examples.append((line[2:], []))
            elif examples:
                examples[-1][1].append(line)
    return examples


def shape(line: str) -> str:
    """A printed line with its numbers masked, and runs of spaces made one."""
    return " ".join(re.sub(r"-?\d+(?:\.\d+)?", "#", line).split())


def test_the_readme_has_the_tour():
    commands = [c.split()[1] for c, _ in console_examples(README.read_text())]
    for command in ("new", "inspect", "validate", "simulate", "cameras", "metrics", "frame", "preview", "render"):
        assert command in commands, command


@pytest.mark.slow
def test_every_console_example_in_the_readme_runs_as_shown(tmp_path, monkeypatch, capsys):
    pytest.importorskip("mitsuba")
    monkeypatch.chdir(tmp_path)
    done = set()
    examples = [e for page in pages() for e in console_examples(page.read_text())]
    for line, shown in examples:
        if line in done:                    # a guide repeating the tour's command
            continue
        done.add(line)
        command, _, pipe = line.partition("|")
        argv = shlex.split(command)
        assert argv[0] == "usdcrowd", line
        argv = argv[1:] + QUICK.get(argv[1], []) + (["--no-progress"] if argv[1] not in ("new", "inspect",
                                                                                            "validate") else [])
        capsys.readouterr()
        code = main(argv)
        out, err = capsys.readouterr()
        assert code == 0, (line, err)
        printed = out.splitlines()
        if pipe.strip().startswith("head"):
            printed = printed[:int(pipe.split("-")[-1])]
        if shown:
            assert printed, (line, "printed nothing")
            assert shape(printed[0]) == shape(shown[0]), (line, printed[0], shown[0])
