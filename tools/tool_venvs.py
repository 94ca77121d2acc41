"""Other people's tools in virtual environments of their own, made once per machine.

PyTorch, Blender's ``bpy``, PedPy, motmetrics and MediaPipe each pin their
own numpy (or protobuf), which must not meet ours, so the tools and tests
that need them run them in a venv of their own. :func:`tool_venv` makes one
safely when several processes ask at once (the tests run in parallel): one
makes it under a file lock while the others wait, and a venv counts as made
only once its packages are in (a marker written last), so one cut short by
an interrupt is made again rather than used half-installed.
"""

from __future__ import annotations

import fcntl
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

MARKER = ".usdcrowd-packages"      # written last: the packages the venv was made with

# The venvs more than one tool or test asks for: one list each, since a venv
# whose marker names other packages is topped up (two lists that drift apart
# would reinstall it in turn).
PEDPY = ["pedpy==1.5.1"]           # the JuPedSim team's analysis library (density, speed, flow)
JUPEDSIM = ["jupedsim==1.4.2"]     # the peer simulator, writing its own SQLite trajectories


def tool_venv(name: str, env: str, packages: list[str]) -> str:
    """The Python of a venv holding ``packages``.

    ``$env``, when set, names the venv to use (made there if it has no Python;
    never removed); else it is ``usdcrowd-NAME-venv`` in the temporary folder,
    made again when it was cut short, and topped up when ``packages`` changed.
    Raises ``subprocess.CalledProcessError`` when it cannot be made (no
    package index).
    """
    given = os.environ.get(env)
    venv = Path(given) if given else Path(tempfile.gettempdir()) / f"usdcrowd-{name}-venv"
    python = venv / "bin" / "python"
    want = " ".join(packages)
    if _ready(venv, python, want, given):
        return str(python)
    venv.parent.mkdir(parents=True, exist_ok=True)
    with open(venv.parent / f".{venv.name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)          # whoever holds it is making this venv: wait for it
        if not _ready(venv, python, want, given):
            _make(venv, python, packages, want, name, remake=not given and not (venv / MARKER).exists())
    return str(python)


def _ready(venv: Path, python: Path, want: str, given: str | None) -> bool:
    if given:
        return python.exists()
    marker = venv / MARKER
    return marker.exists() and marker.read_text() == want


def _make(venv: Path, python: Path, packages: list[str], want: str, name: str, remake: bool) -> None:
    if remake and venv.exists():
        shutil.rmtree(venv)                       # made by nobody to the end: an interrupted build
    if not python.exists():
        print(f"making the {name} venv in {venv} ({want})", file=sys.stderr, flush=True)
        subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
    subprocess.run([str(python), "-m", "pip", "install", "-q", *packages], check=True)
    (venv / MARKER).write_text(want)
