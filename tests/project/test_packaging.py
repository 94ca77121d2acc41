"""The wheel carries the schemas, stages and render data, and registers from there."""

from __future__ import annotations

import os
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from tests.helpers.paths import ROOT


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    pytest.importorskip("hatchling")
    out = tmp_path_factory.mktemp("dist")
    subprocess.run([sys.executable, "-m", "build", "--wheel", "--no-isolation", "--outdir", str(out), str(ROOT)],
                   check=True, capture_output=True, text=True)
    (whl,) = out.glob("usdcrowd-*.whl")
    return whl


def test_wheel_contains_the_data_folders(wheel):
    names = set(zipfile.ZipFile(wheel).namelist())
    for needed in ("usdcrowd/_data/schemas/plugInfo.json", "usdcrowd/_data/schemas/generatedSchema.usda",
                   "usdcrowd/_data/schemas/schema.usda", "usdcrowd/_data/stages/museum.usda",
                   "usdcrowd/_data/render/README.md", "usdcrowd/cli/__init__.py",
                   "usdcrowd/cameras/camera_moe.npz"):       # the learned camera behaviors' weights
        assert needed in names, needed


def test_installed_wheel_registers_its_own_schemas(wheel, tmp_path):
    zipfile.ZipFile(wheel).extractall(tmp_path)
    code = ("import usdcrowd; from usdcrowd.core.resources import data_dir; from pxr import Usd; "
            "s = Usd.Stage.CreateInMemory(); p = s.DefinePrim('/G', 'CrowdGroup'); "
            "print(data_dir('schemas')); print(p.IsA(Usd.Typed))")
    env = dict(os.environ, PYTHONPATH=str(tmp_path))
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True, cwd=tmp_path)
    where, typed = out.stdout.split()
    assert Path(where) == tmp_path / "usdcrowd" / "_data" / "schemas" and typed == "True"
