"""Shared fixtures, named after what they set up."""

from __future__ import annotations

import contextlib
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

import usdcrowd  # noqa: F401  (registers the schemas before any stage opens)
from usdcrowd.core.resources import data_dir

sys.path.insert(0, str(Path(__file__).parent))


@pytest.fixture
def rng():
    """A seeded generator: tests are reproducible."""
    return np.random.default_rng(1234)


@pytest.fixture
def museum_path() -> Path:
    return data_dir("stages") / "museum.usda"


HEADER = '''#usda 1.0
(
    defaultPrim = "World"
    metersPerUnit = {mpu}
    upAxis = "{up}"
    startTimeCode = 1
    endTimeCode = {end}
    timeCodesPerSecond = 24
)
'''


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
    from frames_factory import straight_walk

    import usdcrowd.core.resources as res
    from usdcrowd.jobs.pipeline import author_shot

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


def cli_museum_shot(folder: Path, agents: int, last_frame: int) -> tuple[Path, Path]:
    """A museum scenario and its shot made by the command line, so usdcrowd owns their files.

    Returns (scenario path, shot folder).
    """
    from usdcrowd.cli import main

    scenario = folder / "museum.usda"
    assert main(["new", "museum", "-o", str(scenario), "--agents", str(agents)]) == 0
    assert main(["simulate", str(scenario), "-o", str(folder / "shot"), "--frames", f"1:{last_frame}",
                 "--no-progress"]) == 0
    return scenario, folder / "shot"


@contextlib.contextmanager
def ray_head(port: int):
    """A local two-CPU Ray cluster started as on a head node (`ray start --head`), stopped on leaving.

    Yields the environment a process joining it through ``--address 127.0.0.1:PORT`` runs with (no usage
    statistics, no token authentication: a real cluster shares its token).
    """
    import os
    import subprocess

    ray = Path(sys.executable).with_name("ray")
    env = dict(os.environ, RAY_USAGE_STATS_ENABLED="0", RAY_AUTH_MODE="disabled")
    started = subprocess.run([str(ray), "start", "--head", "--port", str(port), "--num-cpus", "2",
                              "--include-dashboard", "false", "--disable-usage-stats"],
                             capture_output=True, text=True, env=env, timeout=120)
    assert started.returncode == 0, started.stderr[-2000:]
    try:
        yield env
    finally:
        subprocess.run([str(ray), "stop", "--force"], capture_output=True, env=env, timeout=120)


@contextlib.contextmanager
def fails_if_hung(seconds: int, what: str):
    """Within, a hang raises TimeoutError after ``seconds`` instead of blocking the suite (SIGALRM)."""
    import signal

    def hung(*_):
        raise TimeoutError(f"{what} hung")

    old = signal.signal(signal.SIGALRM, hung)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)
