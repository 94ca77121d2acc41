"""A local Ray cluster, started as a head node is, for the tests of distributed runs."""

from __future__ import annotations

import contextlib
import sys
from pathlib import Path


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
