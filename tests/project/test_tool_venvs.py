"""The venvs of other people's tools (tools/tool_venvs.py): made once however many processes ask at once, made
again when a build was cut short, and a venv the user names left as it is."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

from tests.helpers.paths import TOOLS
from tests.helpers.tools import load_tool

ASK = textwrap.dedent("""
    import importlib.util, sys
    spec = importlib.util.spec_from_file_location("tool_venvs", sys.argv[1])
    tool_venvs = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tool_venvs)
    # pip is in every new venv: installing it again needs no package index.
    print(tool_venvs.tool_venv("probe", "USDCROWD_PROBE_VENV", ["pip"]))
""")


def _ask(tmp: Path, **env) -> subprocess.Popen:
    import os

    run_env = {k: v for k, v in os.environ.items() if k != "USDCROWD_PROBE_VENV"}
    run_env.update(TMPDIR=str(tmp), **env)
    return subprocess.Popen([sys.executable, "-c", ASK, str(TOOLS / "tool_venvs.py")], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=run_env)


def test_two_processes_asking_at_once_get_one_venv_made_once(tmp_path):
    procs = [_ask(tmp_path) for _ in range(2)]
    outs = [p.communicate(timeout=300) for p in procs]
    assert all(p.returncode == 0 for p in procs), outs
    pythons = {out.strip() for out, _ in outs}
    venv = tmp_path / "usdcrowd-probe-venv"
    assert pythons == {str(venv / "bin" / "python")}
    made = sum(err.count("making the probe venv") for _, err in outs)
    assert made == 1, outs                       # the second waited for the first, then used its venv
    assert (venv / load_tool("tool_venvs").MARKER).read_text() == "pip"
    ran = subprocess.run([str(venv / "bin" / "python"), "-c", "import sys; print(sys.prefix)"],
                         capture_output=True, text=True, check=True)
    assert Path(ran.stdout.strip()) == venv


def test_a_venv_whose_build_was_cut_short_is_made_again(tmp_path):
    venv = tmp_path / "usdcrowd-probe-venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True)
    (venv / "half-installed").write_text("")        # as a build stopped before its packages were in
    out, err = _ask(tmp_path).communicate(timeout=300)
    assert "making the probe venv" in err, err
    assert not (venv / "half-installed").exists()
    assert (venv / load_tool("tool_venvs").MARKER).exists()
    # Made to the end: the next ask uses it as it is.
    _, err = _ask(tmp_path).communicate(timeout=300)
    assert "making" not in err, err


def test_a_venv_the_user_names_is_used_as_it_is(tmp_path):
    theirs = tmp_path / "their-venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(theirs)], check=True)
    (theirs / "their-file").write_text("")
    proc = _ask(tmp_path, USDCROWD_PROBE_VENV=str(theirs))
    out, err = proc.communicate(timeout=300)
    assert proc.returncode == 0, err
    assert out.strip() == str(theirs / "bin" / "python")
    assert (theirs / "their-file").exists() and not (theirs / load_tool("tool_venvs").MARKER).exists()
    assert not (tmp_path / "usdcrowd-probe-venv").exists()
