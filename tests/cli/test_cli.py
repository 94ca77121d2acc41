"""The command line as a user runs it: outputs, and one-line errors for mistakes."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from tests.helpers.paths import BASELINES
from usdcrowd.cli import main

GROUP = '''
def Xform "World"
{{
    def CrowdGroup "Crowd"
    {{
        uniform int crowd:clones = 3
        {extra}
    }}
    {more}
}}
'''


def _run(capsys, *argv):
    with pytest.raises(SystemExit) as ex:
        raise SystemExit(main(list(argv)))
    out = capsys.readouterr()
    return ex.value.code, out.out, out.err


def test_new_inspect_validate(tmp_path, capsys):
    out = tmp_path / "s.usda"
    code, stdout, _ = _run(capsys, "new", "museum", "-o", str(out), "--agents", "30", "--seed", "9")
    assert code == 0 and out.exists() and "30 agents" in stdout
    code, stdout, _ = _run(capsys, "inspect", str(out))
    assert code == 0 and "Family" in stdout and "seed 9" in stdout and "DistantLight" in stdout
    code, stdout, _ = _run(capsys, "inspect", str(out), "--json")
    data = json.loads(stdout)
    assert data["agents"]["count"] == 30 and data["seed"] == 9
    assert sum(g["agents"] for g in data["groups"]) == 30
    code, stdout, _ = _run(capsys, "validate", str(out))
    assert code == 0 and "0 error(s)" in stdout


def test_validate_reports_problems_and_exits_1(write_stage, capsys):
    bad = write_stage(GROUP.format(extra='uniform token crowd:behavior = "dance"\n        uniform float crowd:maxSlope = -1',
                                   more='def SkelRoot "A" (prepend apiSchemas = ["CrowdAgentAPI"])\n    {\n'
                                        '        rel crowd:leader = </World>\n    }'))
    code, stdout, _ = _run(capsys, "validate", str(bad))
    assert code == 1
    assert "/World/Crowd.crowd:behavior" in stdout and "'dance' is not one of" in stdout
    assert "/World/Crowd.crowd:maxSlope" in stdout and "/World/A.crowd:leader" in stdout


def _assert_one_line_error(code, stderr, *must_contain):
    assert code == 2
    lines = stderr.strip().splitlines()
    assert len(lines) == 1, stderr
    assert "Traceback" not in stderr
    for text in must_contain:
        assert text in lines[0], (text, lines[0])


@pytest.mark.parametrize("case", ["missing", "not_usd", "garbage_usda"])
def test_unreadable_inputs(tmp_path, capsys, case):
    path = tmp_path / {"missing": "nope.usda", "not_usd": "notes.txt", "garbage_usda": "broken.usda"}[case]
    if case == "not_usd":
        path.write_text("shopping list")
    elif case == "garbage_usda":
        path.write_text("#usda 1.0\ndef Xform \"A\" {\n  float x = \n}\n")
    for command in ("inspect", "validate", "simulate"):
        argv = [command, str(path)] + (["-o", str(tmp_path / "out")] if command == "simulate" else [])
        code, _, err = _run(capsys, *argv)
        _assert_one_line_error(code, err, str(path))
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())


@pytest.mark.parametrize("extra, more, prim, attribute", [
    ("uniform float2 crowd:speedRange = (-1, 2)", "", "/World/Crowd", "crowd:speedRange"),
    ("", 'def SkelRoot "A" (prepend apiSchemas = ["CrowdAgentAPI"])\n    {\n        rel crowd:group = </World>\n    }',
     "/World/A", "crowd:group"),
    ("", 'def BehaviorLayer "Food"\n    {\n        uniform asset crowd:image = @maps/missing.png@\n    }',
     "/World/Food", "crowd:image"),
    ("", 'def BehaviorLayer "Map"\n    {\n        uniform float2 crowd:extentMax = (-60, 10)\n'
         '        uniform token crowd:generator = "explosion"\n    }', "/World/Map", "crowd:extentMax"),
])
def test_bad_scenarios_fail_simulate_with_one_line_and_no_output(write_stage, tmp_path, capsys, extra, more, prim,
                                                                 attribute):
    path = write_stage(GROUP.format(extra=extra, more=more))
    out = tmp_path / "shot"
    code, _, err = _run(capsys, "simulate", str(path), "-o", str(out))
    _assert_one_line_error(code, err, str(path), prim, attribute)
    assert not out.exists() or not any(out.iterdir())


@pytest.mark.parametrize("argv, text", [
    (["new", "nowhere", "-o", "x.usda"], "unknown template 'nowhere'"),
    (["new", "museum", "-o", "x.usda", "--agents", "0"], "argument --agents: expected a positive integer"),
    (["new", "museum", "-o", "x.usda", "--agents", "3"], "needs at least 4 agents"),
    (["new", "dialogue", "-o", "x.usda", "--agents", "9"], "fixed cast of 4 agents"),
    (["simulate", "s.usda", "-o", "o", "--frames", "10:1"], "bad frame spec"),
    (["frobnicate"], "invalid choice"),
    (["preview", "shot.usda", "-o", "p.mp4", "--max-meshes", "-1"], "expected a whole number >= 0, got '-1'"),
    (["simulate", "s.usda", "-o", "o", "--fps", "0"], "usdcrowd simulate: error: unrecognized arguments: --fps 0"),
    (["new", "museum", "x.usda", "-o", "x.usda"], "usdcrowd new: error: unrecognized arguments: x.usda"),
])
def test_usage_mistakes(tmp_path, capsys, monkeypatch, argv, text):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as ex:
        raise SystemExit(main(argv))
    err = capsys.readouterr().err
    _assert_one_line_error(ex.value.code, err, text)
    assert not (tmp_path / "x.usda").exists()


def test_console_script_runs_as_installed(tmp_path):
    exe = Path(sys.executable).with_name("usdcrowd")
    out = subprocess.run([str(exe), "inspect", str(tmp_path / "missing.usda")], capture_output=True, text=True)
    _assert_one_line_error(out.returncode, out.stderr, "missing.usda", "no such file")


def test_the_command_line_reads_its_arguments_before_loading_the_heavy_libraries():
    """Building the parser (every command, --help included) loads none of numba, scipy, trimesh, the
    renderers or the learning libraries: a command answers at once, and a Ctrl-C in the first second
    lands in usdcrowd's own handlers rather than in a half-imported library."""
    heavy = ("numba", "scipy", "trimesh", "mitsuba", "drjit", "torch", "ray", "OpenGL", "mediapipe")
    probe = ("import sys, usdcrowd.cli as c; c.build_parser(); "
             f"print(' '.join(m for m in {heavy!r} if m in sys.modules))")
    loaded = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True).stdout
    assert loaded.split() == []


def test_demo_runs_the_whole_chain(tmp_path, capsys):
    code, stdout, _ = _run(capsys, "demo", "-o", str(tmp_path / "demo"), "--no-progress")
    assert code == 0, stdout
    shot = tmp_path / "demo" / "shot"
    for name in ("shot.usda", "crowd.usdc", "cameras.usda", "trajectories.png"):
        assert (shot / name).stat().st_size > 0, name
    assert "validate  shot: 0 errors" in stdout
    # The same command gives the same ground truth: the tracks byte for byte, the COCO file value for value
    # (floats to a thousandth of a pixel); tools/make_baselines.py --demo records both.
    from tests.helpers.tools import load_tool

    baselines = load_tool("make_baselines")
    expected = json.loads((BASELINES / "demo_ground_truth.json").read_text())
    assert baselines.demo_digests(tmp_path / "demo") == expected
    coco = json.loads((tmp_path / "demo" / baselines.DEMO_COCO).read_text())
    differences = baselines.coco_differences(coco, json.loads((BASELINES / "demo_coco.json").read_text()))
    assert not differences, differences[:5]
    # One toric camera (seed 002) on the shot, filmed by the preview: two heads in each of its frames.
    from usdcrowd.scenario.shot_scene import ShotScene

    scene = ShotScene(shot / "shot.usda")
    toric = [p for p in scene.camera_paths if scene.camera(p, 1).toric]
    assert len(toric) == 1 and "/Cameras/Orbit_" in toric[0]
    assert (tmp_path / "demo" / "preview" / "toric" / "preview.mp4").stat().st_size > 0
    for t in (1, 120, 240):
        view = scene.camera(toric[0], t)
        rows = [scene.agent_row(view.toric["target_a"]), scene.agent_row(view.toric["target_b"])]
        uv, z = view.project(scene.agents(t, rows).keypoints()[:, 3], 640, 360)      # head tops
        assert (z > 0).all() and ((uv >= 0) & (uv < [640, 360])).all(), (t, uv)
