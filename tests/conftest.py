"""Shared fixtures, named after what they set up."""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np
import pytest

import usdcrowd  # noqa: F401  (registers the schemas before any stage opens)
from usdcrowd.core.resources import data_dir

from tests.helpers.shots import HEADER


@pytest.fixture(autouse=True)
def one_ray_at_a_time(request):
    """Tests marked ``ray`` take turns machine-wide: the tests run in parallel workers (pytest-xdist), and a
    Ray test looks for render actors among all of the machine's processes and stops every Ray process it
    started a cluster for (`ray stop --force`), another worker's too."""
    if request.node.get_closest_marker("ray") is None:
        yield
        return
    import fcntl
    import tempfile

    with open(Path(tempfile.gettempdir()) / "usdcrowd-tests-ray.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        yield


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


@pytest.fixture(scope="session")
def simulated_harbour(tmp_path_factory):
    """The harbour example simulated over frames 1-360 by the command line (the boat moors at 60), with its
    camera agents: a shot usdcrowd owns (copy it before writing into it)."""
    import shutil

    from usdcrowd.cli import main

    stages = data_dir("stages")
    base = tmp_path_factory.mktemp("simulated_harbour")
    shutil.copy(stages / "harbour.usda", base / "harbour.usda")
    shutil.copytree(stages / "maps", base / "maps")
    assert main(["simulate", str(base / "harbour.usda"), "-o", str(base / "shot"), "--frames", "1:360",
                 "--no-progress"]) == 0
    return base / "shot"


@pytest.fixture(scope="session")
def harbour_frames(simulated_harbour):
    """The simulated harbour read back (crowd, events, scenery) with its cameras' tracks at six frames:
    (ShotCrowd, tracks, frame indices)."""
    from usdcrowd.jobs.editing import camera_tracks, candidate_cameras
    from usdcrowd.jobs.filming import load_shot
    from usdcrowd.scenario.shot_scene import ShotScene

    sc = load_shot(simulated_harbour / "shot.usda", progress=False)
    scene = ShotScene(sc.shot)
    times = np.asarray(sc.scenario.time.codes)
    idx = np.linspace(0, len(times) - 1, 6).round().astype(int)
    return sc, camera_tracks(scene, candidate_cameras(scene, None), times[idx]), idx
