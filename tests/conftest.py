"""Shared fixtures, named after what they set up."""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np
import pytest

import usdcrowd  # noqa: F401  (registers the schemas before any stage opens)
from usdcrowd.core.resources import data_dir

from tests.helpers.shots import HEADER


@pytest.fixture
def rng():
    """A seeded generator: tests are reproducible."""
    return np.random.default_rng(1234)


@pytest.fixture
def museum_path() -> Path:
    return data_dir("stages") / "museum.usda"


@pytest.fixture
def write_stage(tmp_path):
    """Write a small .usda from a body of prims; returns its path."""
    counter = {"n": 0}

    def _write(body: str, name: str | None = None, up: str = "Z", mpu: float = 1, end: int = 12) -> Path:
        counter["n"] += 1
        path = tmp_path / (name or f"stage{counter['n']}.usda")
        path.write_text(HEADER.format(up=up, mpu=mpu, end=end) + textwrap.dedent(body))
        return path

    return _write


@pytest.fixture(scope="session")
def walking_museum(tmp_path_factory):
    """The museum stage's agents walking straight for 12 frames, as a shot (read-only: share it)."""
    import usdcrowd.core.resources as res
    from usdcrowd.jobs.pipeline import author_shot

    from tests.helpers.frames import straight_walk

    out = tmp_path_factory.mktemp("walking_museum")
    return author_shot(res.data_dir("stages") / "museum.usda", out, lambda sc: [straight_walk(sc.agents, sc.time)],
                       frames=(1, 12), progress=False).shot


@pytest.fixture(scope="module")
def gl():
    """A headless OpenGL context; the module is skipped where none can be made (no EGL, no moderngl)."""
    pytest.importorskip("moderngl")
    from usdcrowd.core.errors import UsdcrowdError
    from usdcrowd.render.preview.context import headless_context

    try:
        ctx = headless_context()
    except UsdcrowdError as exc:
        pytest.skip(str(exc))
    yield ctx
    ctx.release()
