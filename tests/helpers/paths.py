"""Where things are, from this file's own place: tests may move between folders without breaking them."""

from __future__ import annotations

from pathlib import Path

TESTS = Path(__file__).resolve().parents[1]
ROOT = TESTS.parent
BASELINES = TESTS / "baselines"
FAILURES = TESTS / "_failures"          # the pictures a failed image comparison leaves (git ignores it)
PACKAGE = ROOT / "usdcrowd"
TOOLS = ROOT / "tools"
