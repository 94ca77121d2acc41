"""Other people's tools in their own virtual environments, made once per machine.

The checks that a file we write is read right by a tool that does not know
our code run that tool in its own venv: it pins its own numpy (motmetrics
needs numpy < 2, Blender's ``bpy`` wheel its own), which must not meet ours.
The venvs are the tools' (``tools/tool_venvs.py``): made under a lock, so
the tests' parallel workers wait for one another rather than build one
venv twice at once.
"""

from __future__ import annotations

import subprocess

import pytest

from tests.helpers.tools import load_tool

# The Blender of the checks that Blender reads our shots: the ``bpy`` wheel, in its own venv.
BPY = ["bpy==5.0.1"]


def tool_python(name: str, packages: list[str], env: str) -> str:
    """The Python of a venv holding ``packages`` (at ``$env`` if set, else in the temporary folder).

    Skips the test with a clear line when the venv cannot be built (no package index).
    """
    try:
        return load_tool("tool_venvs").tool_venv(name, env, packages)
    except subprocess.CalledProcessError:
        pytest.skip(f"could not build the {name} venv ({' '.join(packages)}): no package index? "
                    f"Point {env} at a venv that has them.")


def pedpy_python() -> str:
    """The PedPy venv (tools/tool_venvs.py's PEDPY, the list tools/bench_realism.py uses too)."""
    return tool_python("pedpy", load_tool("tool_venvs").PEDPY, "USDCROWD_PEDPY_VENV")


def jupedsim_python() -> str:
    """The JuPedSim venv (tools/tool_venvs.py's JUPEDSIM)."""
    return tool_python("jupedsim", load_tool("tool_venvs").JUPEDSIM, "USDCROWD_JUPEDSIM_VENV")


def torch_python() -> str:
    """The PyTorch venv the training tools use (their TORCH_PACKAGES: one list, so the venv's marker agrees
    whoever asks first)."""
    return tool_python("torch", load_tool("train_camera_moe").TORCH_PACKAGES, "USDCROWD_TORCH_VENV")
