"""Regenerate schemas/generatedSchema.usda and schemas/plugInfo.json.

Runs usdGenSchema on schemas/schema.usda (codeless: no C++), then fills the
plugInfo placeholders so the plugin loads from the folder it sits in.

    python tools/regen_schemas.py            # rewrite the generated files
    python tools/regen_schemas.py --check    # exit 1 if they are stale
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

SCHEMAS = Path(__file__).resolve().parents[1] / "schemas"
GENERATED = ("generatedSchema.usda", "plugInfo.json")


def _fill_placeholders(plug_info: str) -> str:
    # usdGenSchema leaves CMake placeholders; a codeless resource plugin
    # needs no library and finds its generatedSchema.usda next to itself.
    header, _, body = plug_info.partition("{")
    info = json.loads("{" + body)
    for plugin in info["Plugins"]:
        plugin["LibraryPath"] = ""
        plugin["ResourcePath"] = "."
        plugin["Root"] = "."
    return header + json.dumps(info, indent=4, sort_keys=True) + "\n"


def generate(out_dir: Path) -> None:
    """Run usdGenSchema on schemas/schema.usda and write the two files to out_dir."""
    with tempfile.TemporaryDirectory() as tmp:
        shutil.copy(SCHEMAS / "schema.usda", Path(tmp) / "schema.usda")
        subprocess.run(
            [sys.executable, "-m", "pxr.Usd.usdGenSchema", "-q", "schema.usda", "."],
            cwd=tmp, check=True, capture_output=True, text=True,
        )
        plug = (Path(tmp) / "plugInfo.json").read_text()
        (out_dir / "plugInfo.json").write_text(_fill_placeholders(plug))
        shutil.copy(Path(tmp) / "generatedSchema.usda", out_dir / "generatedSchema.usda")


def stale_files() -> list[str]:
    """Names of generated files that differ from a fresh generation."""
    with tempfile.TemporaryDirectory() as tmp:
        generate(Path(tmp))
        return [n for n in GENERATED
                if (Path(tmp) / n).read_text() != (SCHEMAS / n).read_text()]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="only report stale files")
    args = parser.parse_args(argv)
    if args.check:
        stale = stale_files()
        for name in stale:
            print(f"schemas/{name} is stale: run python tools/regen_schemas.py")
        return 1 if stale else 0
    generate(SCHEMAS)
    print(f"regenerated {', '.join(GENERATED)} in {SCHEMAS}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
