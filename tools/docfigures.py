"""Figures in README.md and docs/: written by the scripts that measure them, never typed.

A script in tools/ that measures something calls :func:`record`, which writes
``docs/data/<name>.json``::

    {"source": "tools/bench_sim.py", "command": "python tools/bench_sim.py",
     "date": "2026-11-27T16:40:00+00:00", "commit": "16046c6", "machine": "2-core x86_64 ...",
     "figures": {"steps_per_s": {"1000": 820.4}}, "tables": {...}, "images": ["docs/images/x.png"]}

and fills the pages again. A page holds each figure between markers that
neither GitHub nor MkDocs shows::

    <!--fig bench_sim:steps_per_s.1000 ,.0f-->820<!--/fig-->     a number, with a format spec
    <!--table camera_metrics:harbour-->                            a table, the lines up to
    | ... |                                                        <!--/table> rewritten
    <!--/table-->
    <!--from bench_sim-->Measured ...<!--/from-->                  where, when, on what

``python tools/docfigures.py`` fills every page from the data; ``--check``
(run by the tests) changes nothing and fails when a marker names data or a
source script that is missing, when a page no longer shows what its data
says, when an image a page shows has no script that writes it, or when a
measurement-like number (seconds, rates, memory) stands outside a marker.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DATA = ROOT / "docs" / "data"
# Pages written by hand (docs/reference/cli.md and schemas.md are generated from the code).
PAGES = ["README.md", *sorted(str(p.relative_to(ROOT)) for p in (ROOT / "docs").rglob("*.md")
                              if p.parent.name != "reference" or p.name == "commands.md")]
FIG = re.compile(r"<!--fig (?P<name>[\w-]+):(?P<key>[\w.-]+)(?: (?P<fmt>[^>]*?))?-->(?P<text>.*?)<!--/fig-->")
TABLE = re.compile(r"<!--table (?P<name>[\w-]+):(?P<key>[\w.-]+)-->\n(?P<text>.*?)<!--/table-->", re.S)
FROM = re.compile(r"<!--from (?P<name>[\w-]+)-->(?P<text>.*?)<!--/from-->", re.S)
IMAGE = re.compile(r"!\[[^\]]*\]\((?P<path>[^)\s]+\.(?:png|jpg|gif|svg))\)")
# A number with a unit of time, rate or memory, or a speed-up: what a measurement looks like ("at 24 fps" is
# a stage's frame rate, not one).
_NUMBER = r"(?<![\w.])\d[\d,]*(?:\.\d+)?\s?"
MEASURED = re.compile(rf"{_NUMBER}(?:ms|s|min|minutes|seconds|hours|steps/s|frames/h|MiB|GiB|MB|GB|MB/s|x faster|×)"
                      rf"(?![\w/])|(?<!at ){_NUMBER}fps\b")

# Sentences whose numbers are not this project's measurements: targets, papers' figures, inputs.
EXEMPT = re.compile(r"[Tt]arget|\breport|\bpaper|<!--not-measured-->")


# ------------------------------------------------------------------ recording
def machine() -> str:
    """This machine in words: cores, processor, memory, GPU."""
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    try:
        pages = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
        memory = f", {pages / 2**30:.0f} GiB"
    except (ValueError, OSError, AttributeError):
        memory = ""
    try:
        gpu = subprocess.run(["nvidia-smi", "--query-gpu=name", "--format=csv,noheader"], capture_output=True,
                             text=True, timeout=10).stdout.strip().splitlines()
    except (OSError, subprocess.SubprocessError):
        gpu = []
    return f"{os.cpu_count()}-core {cpu}{memory}, {'GPU ' + gpu[0] if gpu else 'no GPU'}"


def commit() -> str:
    """The commit the figures were measured at (``+`` when the work tree had changes)."""
    try:
        sha = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True,
                             check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=ROOT,
                               capture_output=True, text=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return sha + ("+" if dirty else "")


def record(name: str, source: str, figures: dict | None = None, tables: dict | None = None,
           images: list | None = None, command: str | None = None, fill_pages: bool = True) -> Path:
    """Write ``docs/data/<name>.json`` with the date, commit and machine, then fill the pages.

    Parameters
    ----------
    name : str
        The data's name, as pages' markers give it.
    source : str
        The script that measured it, relative to the repository (``tools/bench_sim.py``).
    figures : dict
        Nested ``{key: number or text}``; a marker names one by dotted path.
    tables : dict
        ``{key: {"columns": [...], "rows": [[...], ...]}}``, cells already formatted.
    images : list of str
        Files under docs/ the script wrote (repository-relative).
    """
    DATA.mkdir(parents=True, exist_ok=True)
    data = {"source": source, "command": command or "python " + " ".join([source, *sys.argv[1:]]),
            "date": datetime.datetime.now(datetime.timezone.utc).replace(microsecond=0).isoformat(),
            "commit": commit(), "machine": machine(), "figures": figures or {}, "tables": tables or {},
            "images": list(images or [])}
    path = DATA / f"{name}.json"
    tmp = path.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(data, indent=1, sort_keys=True) + "\n")
    os.replace(tmp, path)
    if fill_pages and not os.environ.get("DOCFIGURES_NO_FILL"):     # a batch of scripts fills once, at its end
        fill(check=False)
    print(f"recorded {path.relative_to(ROOT)}")
    return path


# -------------------------------------------------------------------- pages
def _load(name: str, cache: dict) -> dict | None:
    if name not in cache:
        path = DATA / f"{name}.json"
        cache[name] = json.loads(path.read_text()) if path.is_file() else None
    return cache[name]


def _lookup(tree, key: str):
    """``key``'s value in ``tree``: dotted names, and indices into lists (``rates.0``, ``rates.-1``)."""
    for part in key.split("."):
        if isinstance(tree, list) and part.lstrip("-").isdigit() and -len(tree) <= int(part) < len(tree):
            tree = tree[int(part)]
        elif isinstance(tree, dict) and part in tree:
            tree = tree[part]
        else:
            raise KeyError(key)
    return tree


def format_figure(value, fmt: str | None) -> str:
    """A figure as a page shows it: ``fmt`` is a Python format spec; by default integers get thousands
    separators and other numbers three significant digits."""
    if fmt:
        return format(value, fmt)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return str(value)
    if isinstance(value, int) or float(value).is_integer() and abs(value) >= 100:
        return f"{int(value):,}"
    return f"{value:,.3g}" if abs(value) < 1000 else f"{value:,.0f}"


def render_table(table: dict) -> str:
    """A markdown table from ``{"columns": [...], "rows": [[...]]}``."""
    cols = table["columns"]
    lines = ["| " + " | ".join(cols) + " |", "|" + "|".join("---" for _ in cols) + "|"]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in table["rows"]]
    return "\n".join(lines) + "\n"


def provenance(data: dict) -> str:
    """Where, when and on what a page's figures were measured."""
    return (f"Measured by `{data['command']}` on {data['date'][:10]}, commit {data['commit']}, "
            f"on a {data['machine']}.")


def _fill_page(text: str, page: str, cache: dict, problems: list) -> str:
    missing = set()

    def resolve(name, what):
        data = _load(name, cache)
        if data is None:
            if name not in missing:                        # said once a page
                missing.add(name)
                problems.append(f"{page}: {what} names docs/data/{name}.json, which no script has written")
        elif not (ROOT / data["source"]).is_file():
            problems.append(f"{page}: docs/data/{name}.json comes from {data['source']}, which is gone")
            data = None
        return data

    def fig(m):
        data = resolve(m["name"], f"figure {m['name']}:{m['key']}")
        if data is None:
            return m[0]
        try:
            value = _lookup(data["figures"], m["key"])
        except KeyError:
            problems.append(f"{page}: docs/data/{m['name']}.json gives no figure {m['key']!r}")
            return m[0]
        fmt = f" {m['fmt']}" if m["fmt"] else ""
        return f"<!--fig {m['name']}:{m['key']}{fmt}-->{format_figure(value, m['fmt'])}<!--/fig-->"

    def table(m):
        data = resolve(m["name"], f"table {m['name']}:{m['key']}")
        if data is None or m["key"] not in data["tables"]:
            if data is not None:
                problems.append(f"{page}: docs/data/{m['name']}.json gives no table {m['key']!r}")
            return m[0]
        return f"<!--table {m['name']}:{m['key']}-->\n{render_table(data['tables'][m['key']])}<!--/table-->"

    def origin(m):
        data = resolve(m["name"], f"provenance of {m['name']}")
        return m[0] if data is None else f"<!--from {m['name']}-->{provenance(data)}<!--/from-->"

    return FROM.sub(origin, TABLE.sub(table, FIG.sub(fig, text)))


def _unmarked_measurements(text: str) -> list[str]:
    """Measurement-like numbers outside any marker, code blocks included (a transcript's timing is a
    figure too). A sentence that states a target, a paper's figure or an input (marked
    ``<!--not-measured-->``) is not a measurement."""
    stripped = FROM.sub("", TABLE.sub("", FIG.sub("", text)))
    found = []
    lineno = 1
    for paragraph in re.split(r"(\n\s*\n)", stripped):
        for sentence in re.split(r"(?<=[.;!?])\s+", paragraph):
            if not EXEMPT.search(sentence):
                found += [f"line {lineno}: {m[0]!r}" for m in MEASURED.finditer(sentence)]
        lineno += paragraph.count("\n")
    return found


def _claimed_images(cache: dict) -> set[str]:
    claimed = set()
    for path in DATA.glob("*.json"):
        claimed.update(_load(path.stem, cache).get("images", []))
    return claimed


def fill(check: bool) -> list[str]:
    """Fill every page's markers from docs/data (``check``: only report what differs). Returns problems."""
    cache: dict = {}
    problems: list[str] = []
    claimed = _claimed_images(cache)
    for page in PAGES:
        path = ROOT / page
        text = path.read_text()
        new = _fill_page(text, page, cache, problems)
        if new != text:
            if check:
                problems.append(f"{page}: shows figures its data no longer gives (run python tools/docfigures.py)")
            else:
                path.write_text(new)
        problems += [f"{page}: {where}, a measurement with no script behind it (put it in a marker)"
                     for where in _unmarked_measurements(new)]
        for m in IMAGE.finditer(new):
            image = os.path.normpath(os.path.join(os.path.dirname(page), m["path"]))
            if image not in claimed:
                problems.append(f"{page}: image {m['path']} is written by no script that records it")
    for path in sorted(DATA.glob("*.json")):
        data = _load(path.stem, cache)
        if not (ROOT / data["source"]).is_file():
            problems.append(f"docs/data/{path.name}: its source {data['source']} is gone")
        problems += [f"docs/data/{path.name}: lists {image}, which is not there"
                     for image in data.get("images", []) if not (ROOT / image).is_file()]
    return problems


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="change nothing; exit 1 on any problem")
    args = parser.parse_args(argv)
    problems = fill(check=args.check)
    for p in problems:
        print(p, file=sys.stderr)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
