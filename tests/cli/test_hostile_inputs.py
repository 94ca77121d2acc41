"""Hostile and careless inputs: layers that would hang or silently empty a command, bad values, bad outputs."""

from __future__ import annotations

import os
import shutil
import signal

import pytest

from tests.helpers.hung import fails_if_hung

from usdcrowd.cli import main
from usdcrowd.core.resources import data_dir

COMMANDS = {
    "inspect": [], "validate": [], "simulate": ["-o", "{out}"], "preview": ["-o", "{out}/p.mp4"],
    "render": ["-o", "{out}"], "cameras": [], "metrics": ["-o", "{out}"],
}


def _run(capsys, command, stage, out):
    """Run one command in-process; a hang fails the test after 30 s instead of blocking the suite."""
    argv = [command, str(stage)] + [a.format(out=out) for a in COMMANDS[command]] + (
        ["--no-progress"] if command not in ("inspect", "validate") else [])

    with fails_if_hung(30, f"usdcrowd {command} on {stage}"):
        code = main(argv)
    err = capsys.readouterr().err
    return code, err


def _small_shot(tmp_path, agents: int, last_frame: int):
    """A museum shot of ``agents`` agents over frames 1..``last_frame`` in tmp_path/shot."""
    scenario = tmp_path / "museum.usda"
    assert main(["new", "museum", "-o", str(scenario), "--agents", str(agents)]) == 0
    shot = tmp_path / "shot"
    assert main(["simulate", str(scenario), "-o", str(shot), "--frames", f"1:{last_frame}", "--no-progress"]) == 0
    return shot


def _crowd_stage(path, prims: str):
    """A 6-frame stage with a 2-agent group and ``prims`` beside it under /World."""
    path.write_text('#usda 1.0\n(\n    defaultPrim = "World"\n    startTimeCode = 1\n    endTimeCode = 6\n)\n'
                    'def Xform "World"\n{\n    def CrowdGroup "Crowd"\n    {\n        uniform int crowd:clones = 2\n'
                    f'    }}\n{prims}\n}}\n')
    return path


@pytest.fixture
def layers(tmp_path):
    """A FIFO stage, a stage whose sublayer is a FIFO, and one whose sublayer is missing."""
    os.mkfifo(tmp_path / "pipe.usda")
    (tmp_path / "on_pipe.usda").write_text('#usda 1.0\n(\n    subLayers = [@./pipe.usda@]\n)\n')
    (tmp_path / "on_missing.usda").write_text('#usda 1.0\n(\n    subLayers = [@./gone.usda@]\n)\n')
    return tmp_path


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_a_fifo_stage_or_sublayer_is_refused_at_once_by_every_command(layers, capsys, command):
    out = layers / f"out_{command}"
    for stage, words in (("pipe.usda", "not a regular file"), ("on_pipe.usda", "not a regular file"),
                         ("on_missing.usda", "does not exist")):
        code, err = _run(capsys, command, layers / stage, out)
        assert code == 2 and err.count("\n") == 1, (stage, err)
        assert words in err and stage in err, err
        assert not out.exists() or not any(out.iterdir())


def test_a_shot_without_its_crowd_layer_is_an_error_not_an_empty_render(tmp_path, capsys):
    shot = _small_shot(tmp_path, agents=6, last_frame=12)
    capsys.readouterr()
    (shot / "crowd.usdc").unlink()
    for command in ("render", "preview", "cameras", "inspect"):
        code, err = _run(capsys, command, shot / "shot.usda", tmp_path / f"out_{command}")
        assert code == 2 and "crowd.usdc" in err and "does not exist" in err, (command, err)
    shutil.rmtree(shot)


@pytest.fixture
def museum(tmp_path):
    """A small museum scenario's text and a writer for broken copies of it."""
    path = tmp_path / "museum.usda"
    assert main(["new", "museum", "-o", str(path), "--agents", "6"]) == 0
    text = path.read_text()

    def broken(old_pattern: str, new: str, name: str):
        import re

        m = re.search(old_pattern, text)
        assert m, old_pattern
        bad = tmp_path / name
        bad.write_text(text[:m.start()] + new + text[m.end():])
        return bad

    return broken


@pytest.mark.parametrize("pattern, new, words, where", [
    (r'uniform token crowd:behavior = "\w+"', 'uniform token crowd:behavior = "fly"', "'fly' is not one of",
     "crowd:behavior"),
    (r"uniform int crowd:clones = \d+", 'uniform string crowd:clones = "3"', "authored as string",
     "crowd:clones"),
    (r"endTimeCode = \d+", "endTimeCode = -5", "before startTimeCode", "endTimeCode"),
    (r"uniform float crowd:height = [\d.]+", "uniform float crowd:height = nan", "not a finite number",
     "crowd:height"),
])
def test_bad_values_are_one_line_errors_in_simulate_and_validate(museum, tmp_path, capsys, pattern, new, words,
                                                                 where):
    bad = museum(pattern, new, "bad.usda")
    capsys.readouterr()
    out = tmp_path / "shot"
    assert main(["simulate", str(bad), "-o", str(out), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and words in err and where in err and "bad.usda" in err, err
    assert not (out / "shot.usda").exists()
    assert main(["validate", str(bad)]) == 1
    report = capsys.readouterr().out
    assert words in report and where in report


def test_output_paths_that_are_not_folders_and_huge_images_are_refused(museum, tmp_path, capsys):
    scenario = museum(r"endTimeCode = \d+", "endTimeCode = 12", "short.usda")
    (tmp_path / "a_file").write_text("")
    for out in (tmp_path / "a_file", "/dev/null"):
        assert main(["simulate", str(scenario), "-o", str(out), "--no-progress"]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "is not a folder" in err
    assert main(["simulate", str(scenario), "-o", str(tmp_path / "shot"), "--no-progress"]) == 0
    assert main(["preview", str(tmp_path / "shot" / "shot.usda"), "--resolution", "100000x100000", "-o",
                 str(tmp_path / "p.mp4")]) == 2
    assert "too large" in capsys.readouterr().err


def test_resource_bounds_refuse_early_and_options_raise_them(museum, tmp_path, capsys):
    big = museum(r"uniform int crowd:clones = \d+", "uniform int crowd:clones = 1000000000", "big.usda")
    long = museum(r"endTimeCode = \d+", "endTimeCode = 100000000", "long.usda")
    capsys.readouterr()
    for argv, words in (
            (["simulate", str(big), "-o", str(tmp_path / "o1")], "--max-agents"),
            (["inspect", str(big)], "--max-agents"),
            (["simulate", str(long), "-o", str(tmp_path / "o2")], "--max-frames"),
    ):
        assert main(argv + (["--no-progress"] if argv[0] == "simulate" else [])) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and words in err, err
    assert main(["validate", str(big)]) == 1 and "--max-agents" in capsys.readouterr().out
    assert main(["simulate", str(long), "-o", str(tmp_path / "o3"), "--frames", "1:100000000"]) == 2
    assert "at most" in capsys.readouterr().err
    # The harbour's 256 x 256 px water map, refused under a 1,000-pixel bound, accepted by default.
    harbour = data_dir("stages") / "harbour.usda"
    assert main(["inspect", str(harbour), "--max-image-pixels", "1000"]) == 2
    err = capsys.readouterr().err
    assert "harbour_water.png" in err and "--max-image-pixels" in err and "crowd:image" in err
    assert main(["inspect", str(harbour)]) == 0


def test_a_rerun_removes_what_an_interrupted_run_left_half_written(museum, tmp_path, capsys):
    scenario = museum(r"endTimeCode = \d+", "endTimeCode = 6", "short.usda")
    shot = tmp_path / "shot"
    (shot / "json").mkdir(parents=True)
    left = [shot / ".trajectories.partial-0a1b2c3d.png", shot / ".cameras.partial-deadbeef.usda",
            shot / "json" / ".frame.0002.partial-12345678.json"]
    for path in left:
        path.write_bytes(b"")
    mine = shot / "notes.partial.txt"            # not a name usdcrowd makes: left alone
    mine.write_text("keep")
    # The user's own json/ and notes: the folder is usdcrowd's to write in only when forced.
    assert main(["simulate", str(scenario), "-o", str(shot), "--no-progress"]) == 2
    assert "notes.partial.txt" in capsys.readouterr().err
    assert main(["simulate", str(scenario), "-o", str(shot), "--no-progress", "--force"]) == 0
    assert not any(p.exists() for p in left) and mine.read_text() == "keep"
    assert not list(shot.rglob(".*partial*"))


@pytest.mark.parametrize("counts, indices, words, attribute", [
    ("[4, 4]", "[0, 1, 2, 3]", "the faces use 8 indices", "faceVertexCounts"),
    ("[4]", "[0, 1, 2, 7]", "index 7 is outside the 4 points", "faceVertexIndices"),
    ("[2, 2]", "[0, 1, 2, 3]", "a face has 2 vertices", "faceVertexCounts"),
])
def test_broken_meshes_are_one_line_errors(tmp_path, capsys, counts, indices, words, attribute):
    stage = _crowd_stage(tmp_path / "mesh.usda", f"""
    def Mesh "Wall"
    {{
        int[] faceVertexCounts = {counts}
        int[] faceVertexIndices = {indices}
        point3f[] points = [(0, 0, 0), (1, 0, 0), (1, 0, 3), (0, 0, 3)]
    }}""")
    assert main(["simulate", str(stage), "-o", str(tmp_path / "shot"), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and words in err and f"/World/Wall.{attribute}" in err and "mesh.usda" in err
    assert main(["validate", str(stage)]) == 1
    assert words in capsys.readouterr().out


def test_a_reference_to_a_missing_prim_is_a_one_line_error_not_a_usd_warning(tmp_path, capfd):
    (tmp_path / "part.usda").write_text('#usda 1.0\ndef Xform "Here"\n{\n}\n')
    stage = tmp_path / "ref.usda"
    stage.write_text('#usda 1.0\ndef Xform "A" (\n    references = @./part.usda@</Nowhere>\n)\n{\n}\n')
    assert main(["inspect", str(stage)]) == 2
    err = capfd.readouterr().err
    assert err.count("\n") == 1 and "cannot be composed" in err and "</Nowhere>" in err, err


@pytest.fixture
def full_disk(tmp_path):
    """A 600 KiB tmpfs (needs root, as on CI); skipped where it cannot be mounted."""
    import subprocess

    mount = tmp_path / "full"
    mount.mkdir()
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=600k", "tmpfs", str(mount)], capture_output=True)
    if done.returncode != 0:
        pytest.skip("cannot mount a small tmpfs here")
    yield mount
    subprocess.run(["umount", str(mount)], capture_output=True)


def test_a_full_disk_is_one_line_and_leaves_nothing(full_disk, tmp_path, capsys):
    scenario = tmp_path / "museum.usda"
    assert main(["new", "museum", "-o", str(scenario), "--agents", "40"]) == 0
    capsys.readouterr()
    out = full_disk / "shot"
    assert main(["simulate", str(scenario), "-o", str(out), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no space left on device" in err and str(out) in err, err
    assert not out.exists() or not any(out.iterdir())


@pytest.mark.parametrize("make, words", [
    (lambda p: p.write_bytes(b"\x89PNG\r\n\x1a\n" + b"\x00" * 40), "cannot be read"),      # a truncated PNG
    (lambda p: p.write_text("not an image at all"), "cannot be read"),
    (lambda p: os.mkfifo(p), "not found"),                                                  # a pipe as image
    (lambda p: p.mkdir(), "not found"),                                                     # a folder
    (lambda p: None, "not found"),                                                          # nothing there
])
def test_hostile_behavior_map_images_are_one_line_errors(tmp_path, capsys, make, words):
    image = tmp_path / "map.png"
    make(image)
    stage = _crowd_stage(tmp_path / "maps.usda", """
    def BehaviorLayer "Map"
    {
        uniform token crowd:meaning = "forbidden"
        uniform asset crowd:image = @./map.png@
        uniform float2 crowd:extentMin = (-10, -10)
        uniform float2 crowd:extentMax = (10, 10)
    }""")
    code, err = _run(capsys, "simulate", stage, tmp_path / "shot")
    assert code == 2 and err.count("\n") == 1, err
    assert words in err and "/World/Map.crowd:image" in err and "map.png" in err, err
    assert not (tmp_path / "shot" / "shot.usda").exists()


def test_an_interrupted_simulate_leaves_nothing_and_says_so(tmp_path):
    """SIGINT half-way through a simulation: exit 130, one line, no shot and no part layers left."""
    import subprocess
    import sys
    import time
    from pathlib import Path

    scenario = tmp_path / "museum.usda"
    assert main(["new", "museum", "-o", str(scenario), "--agents", "2000"]) == 0
    exe = Path(sys.executable).with_name("usdcrowd")
    # 1,200 frames: long enough (tens of seconds) that the signal lands mid-run even on a fast or idle machine.
    # Ctrl-C's default restored in the child: a run started in the background (nohup, `&`) ignores SIGINT.
    proc = subprocess.Popen([str(exe), "simulate", str(scenario), "-o", str(tmp_path / "shot"), "--no-progress",
                             "--frames", "1:1200"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.time() + 60
    while not (tmp_path / "shot").exists() and time.time() < deadline:
        time.sleep(0.05)
    time.sleep(1.0)                                   # well into the simulation
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 130 and err.startswith("usdcrowd simulate: interrupted") and err.strip().count("\n") == 0, err
    left = [p.name for p in (tmp_path / "shot").iterdir()] if (tmp_path / "shot").exists() else []
    assert left == [], left


@pytest.mark.parametrize("attribute, value, words", [
    ("focalLength", 0.0, "must be > 0"),
    ("horizontalAperture", float("nan"), "must be > 0"),
    ("clippingRange", (10.0, 1.0), "0 < near < far"),
])
def test_a_camera_no_renderer_can_use_is_refused_by_preview_render_and_validate(tmp_path, capsys, attribute,
                                                                               value, words):
    from pxr import Gf, Sdf

    shot = _small_shot(tmp_path, agents=4, last_frame=6)
    layer = Sdf.Layer.FindOrOpen(str(shot / "cameras.usda"))
    spec = layer.GetAttributeAtPath(f"/World/Cameras/CrowdCam.{attribute}")
    if spec is None:
        type_name = Sdf.ValueTypeNames.Float2 if attribute == "clippingRange" else Sdf.ValueTypeNames.Float
        spec = Sdf.AttributeSpec(layer.GetPrimAtPath("/World/Cameras/CrowdCam"), attribute, type_name)
    bad = Gf.Vec2f(*value) if attribute == "clippingRange" else value
    layer.SetTimeSample(spec.path, 3.0, bad)
    if attribute != "focalLength":
        spec.default = bad
    layer.Save()
    capsys.readouterr()
    for command, extra in (("preview", ["-o", str(tmp_path / "p.mp4"), "--frames", "3"]),
                           ("render", ["-o", str(tmp_path / "r"), "--frames", "3", "--resolution", "32x18",
                                       "--spp", "1", "--no-progress"])):
        assert main([command, str(shot / "shot.usda"), "--camera", "/World/Cameras/CrowdCam"] + extra) == 2
        err = capsys.readouterr().err
        assert err.strip().count("\n") == 0 and words in err and f"CrowdCam.{attribute}" in err, (command, err)
    assert main(["validate", str(shot / "shot.usda")]) == 1
    assert words in capsys.readouterr().out


@pytest.mark.parametrize("argv, words", [
    (["new", "museum", "-o", "/dev/null/x.usda"], "is not a folder"),
    (["new", "museum", "-o", "{tmp}/s.usda", "--agents", "1000000000"], "--max-agents"),
    (["demo", "-o", "/dev/null", "--no-progress"], "is not a folder"),
])
def test_careless_new_and_demo_arguments_are_one_line_errors(tmp_path, capsys, argv, words):
    assert main([a.format(tmp=tmp_path) for a in argv]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and words in err, err
    assert not (tmp_path / "s.usda").exists()


def test_non_finite_transforms_and_lights_are_one_line_errors(museum, tmp_path, capsys):
    harbour = (data_dir("stages") / "harbour.usda").read_text()
    (tmp_path / "maps").symlink_to(data_dir("stages") / "maps")
    cam = tmp_path / "cam.usda"
    cam.write_text(harbour.replace("double3 xformOp:translate = (-40, -38, 5)",
                                   "double3 xformOp:translate = (nan, -38, 5)"))
    code, err = _run(capsys, "simulate", cam, tmp_path / "o1")
    assert code == 2 and "ScoutWest.xformOp:translate" in err and "not a finite value" in err, err
    assert main(["validate", str(cam)]) == 1 and "ScoutWest.xformOp:translate" in capsys.readouterr().out

    shot = tmp_path / "shot"
    assert main(["simulate", str(tmp_path / "museum.usda"), "-o", str(shot), "--frames", "1:3", "--no-progress"]) == 0
    # The lamp broken afterwards in the scenario the shot is made of: simulate would refuse it, the readers too.
    lit = museum(r"float inputs:intensity = [\d.]+", "float inputs:intensity = nan", "museum.usda")
    capsys.readouterr()
    assert main(["simulate", str(lit), "-o", str(tmp_path / "again"), "--frames", "1:3", "--no-progress"]) == 2
    assert "inputs:intensity" in capsys.readouterr().err
    for command, out in (("render", tmp_path / "r"), ("preview", tmp_path / "p.mp4")):
        argv = [command, str(shot / "shot.usda"), "-o", str(out), "--frames", "1"]
        argv += ["--resolution", "32x18", "--spp", "1", "--no-progress"] if command == "render" else []
        assert main(argv) == 2
        err = capsys.readouterr().err
        # The shot's scenario changed since simulate: a warning line says so, then the error.
        warning, error = err.strip().splitlines()
        assert "changed since the shot was simulated" in warning, warning
        assert "inputs:intensity" in error and "not a finite" in error, (command, err)
    assert main(["validate", str(lit)]) == 1 and "inputs:intensity" in capsys.readouterr().out


def test_a_damaged_animation_in_the_crowd_layer_is_found_by_preview_render_and_validate(tmp_path, capsys):
    from tests.helpers.damage import spoil_root_translation

    shot = _small_shot(tmp_path, agents=4, last_frame=4)
    target = spoil_root_translation(shot / "crowd.usdc", 2.0, float("inf"))
    capsys.readouterr()
    where = f"{target.GetPrimPath()}.translations"
    for command, extra in (("preview", ["-o", str(tmp_path / "p.mp4")]),
                           ("render", ["-o", str(tmp_path / "r"), "--resolution", "32x18", "--spp", "1",
                                       "--no-progress"])):
        assert main([command, str(shot / "shot.usda"), "--frames", "2"] + extra) == 2
        err = capsys.readouterr().err
        assert where in err and "not a finite value at time 2" in err, (command, err)
    assert main(["validate", str(shot / "shot.usda")]) == 1
    assert where in capsys.readouterr().out


def test_frames_outside_the_shot_are_refused_by_preview_and_render(tmp_path, capsys):
    shot = _small_shot(tmp_path, agents=4, last_frame=4)
    capsys.readouterr()
    for command, out in (("preview", tmp_path / "p.mp4"), ("render", tmp_path / "r")):
        argv = [command, str(shot / "shot.usda"), "--frames", "2:5000", "-o", str(out)]
        assert main(argv + (["--no-progress"] if command == "render" else [])) == 2
        err = capsys.readouterr().err
        assert "frame 5 is outside the shot's frames 1-4" in err and err.count("\n") == 1, err
        assert not out.exists()


@pytest.fixture(scope="module")
def clipped_shot(tmp_path_factory):
    """A 4-agent museum shot over 20 frames with its crowd split in 6-frame value clips."""
    from usdcrowd.jobs.pipeline import simulate_shot

    tmp = tmp_path_factory.mktemp("clipped")
    scenario = tmp / "museum.usda"
    assert main(["new", "museum", "-o", str(scenario), "--agents", "4"]) == 0
    simulate_shot(scenario, tmp / "shot", frames=(1, 20), progress=False, clip_frames=6)
    assert len(list((tmp / "shot" / "crowd.clips").iterdir())) == 5
    return tmp / "shot"


def _truncate(path):
    data = path.read_bytes()
    path.write_bytes(data[:len(data) // 2])


def _garbage(path):
    path.write_bytes(b"\x00\xffnot usd at all\n" * 40)


SHOT_COMMANDS = {"inspect": [], "validate": [], "cameras": [], "metrics": ["-o", "{out}"],
                 "preview": ["-o", "{out}/p.mp4", "--frames", "14"],
                 "render": ["-o", "{out}", "--frames", "14", "--resolution", "32x18", "--spp", "1"]}


@pytest.mark.parametrize("damage, file, words", [
    (os.unlink, "crowd.clips/crowd.0002.usdc", "crowd.0002.usdc, which does not exist"),
    (_truncate, "crowd.clips/crowd.0002.usdc", "crowd.0002.usdc, which is truncated or damaged"),
    (_truncate, "crowd.clips/crowd.manifest.usdc", "crowd.manifest.usdc, which is truncated or damaged"),
    (_truncate, "crowd.usdc", "crowd.usdc"),
    (_garbage, "cameras.usda", "cameras.usda"),
])
@pytest.mark.parametrize("command", sorted(SHOT_COMMANDS))
def test_a_damaged_shot_layer_is_one_line_in_every_command(clipped_shot, tmp_path, capsys, command, damage, file,
                                                          words):
    shutil.copytree(clipped_shot.parent, tmp_path / "w")      # the shot and the scenario it names
    shot = tmp_path / "w" / "shot"
    damage(shot / file)
    out = tmp_path / "out"
    argv = [command, str(shot / "shot.usda")] + [a.format(out=out) for a in SHOT_COMMANDS[command]]
    capsys.readouterr()
    code = main(argv + (["--no-progress"] if command not in ("inspect", "validate") else []))
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err, (command, err)
    assert words in err, err
    assert not out.exists() or not any(out.rglob("*.*"))
    # cameras replaces cameras.usda in place: a refused run leaves the shot as it was.
    assert sorted(p.name for p in shot.iterdir()) == sorted(p.name for p in clipped_shot.iterdir())


def test_a_hierarchy_nested_thousands_deep_is_refused_at_once(tmp_path, capsys):
    """10,000 nested prims made simulate run for ever (layer writing grows with the square of the depth)."""
    depth = 5000
    nested = "".join(f'def Xform "N{i}"\n{{\n' for i in range(depth)) + "}\n" * depth
    stage = _crowd_stage(tmp_path / "deep.usda", nested)
    code, err = _run(capsys, "simulate", stage, tmp_path / "out")
    assert code == 2 and err.count("\n") == 1 and "nested more than 256 deep" in err and "deep.usda" in err, err
    assert main(["validate", str(stage)]) == 1
    assert "nested more than 256 deep" in capsys.readouterr().out


def test_an_agent_inside_an_instanceable_prim_is_refused(tmp_path, capsys):
    """USD instances are read-only: the agent's animation would be lost without a word."""
    stage = tmp_path / "instanced.usda"
    stage.write_text('#usda 1.0\n(\n    defaultPrim = "World"\n    upAxis = "Z"\n    metersPerUnit = 1\n)\n'
                     'class Xform "Proto"\n{\n    def SkelRoot "Bob" (\n'
                     '        prepend apiSchemas = ["CrowdAgentAPI"]\n    )\n    {\n    }\n}\n'
                     'def Xform "World"\n{\n    def CrowdGroup "Crowd"\n    {\n        uniform int crowd:clones = 2\n'
                     '        def Xform "Crowds" (\n            instanceable = true\n'
                     '            references = </Proto>\n        )\n        {\n        }\n    }\n}\n')
    code, err = _run(capsys, "simulate", stage, tmp_path / "out")
    assert code == 2 and err.count("\n") == 1, err
    assert "/World/Crowd/Crowds/Bob" in err and "instanceable prim /World/Crowd/Crowds" in err, err
    assert main(["validate", str(stage)]) == 1
    assert "instanceable" in capsys.readouterr().out
