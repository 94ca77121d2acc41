"""The command line agrees with itself (issue 28, point 5): what one command says, the files and the
other commands say too.

Every test runs the real ``usdcrowd`` command line on a small museum shot
(6 agents, frames 1-12) made by the command line itself.
"""

from __future__ import annotations

import csv
import hashlib
import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from tests.helpers.shots import cli_museum_shot

from usdcrowd.cli import main

GUIDE = "/World/Crowd/Visitors/Family/Guide"            # the museum's invisible leader
TEACHER = "/World/Crowd/Visitors/Students/Teacher"
STUDENT = "/World/Crowd/Visitors/Students/clone_0000"
CROWDCAM = "/World/Cameras/CrowdCam"


@pytest.fixture(scope="module")
def made(tmp_path_factory):
    """A museum scenario and its 12-frame shot made by the command line (read-only: copy it to change it)."""
    scenario, shot = cli_museum_shot(tmp_path_factory.mktemp("agrees"), agents=6, last_frame=12)
    return shot.parent


@pytest.fixture
def shot(made):
    """shot.usda of the module's shot, as made (a test that changes it takes :func:`copy_of`)."""
    return made / "shot" / "shot.usda"


def copy_of(made: Path, where: Path) -> Path:
    """shot.usda of a copy of the whole folder (its times kept: usdcrowd still owns its files)."""
    shutil.copytree(made, where, copy_function=shutil.copy2)
    return where / "shot" / "shot.usda"


def digest(folder: Path) -> dict:
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file() and ".usdcrowd" not in p.parts}


def run(capsys, *argv) -> tuple[int, str, str]:
    """Exit code, stdout and stderr of ``usdcrowd ARGV`` (argparse's own exits included)."""
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exc:
        code = exc.code
    out = capsys.readouterr()
    return code, out.out, out.err


def one_line_error(code: int, err: str, *words) -> None:
    assert code == 2, (code, err)
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    for w in words:
        assert w in err, (w, err)


# ------------------------------------------------------------------ 1. agents listed, missing ones suggested
def test_inspect_agents_lists_every_agent_one_line_each_in_text_and_json(shot, capsys):
    from usdcrowd.scenario.shot_scene import ShotScene

    scene = ShotScene(shot)
    code, out, _ = run(capsys, "inspect", shot, "--agents")
    assert code == 0
    header, *lines = out.strip().splitlines()
    assert header.split() == ["name", "path", "id", "group", "visible", "role"]
    assert len(lines) == len(scene.agent_paths) == 6
    rows = {line.split()[1]: line.split() for line in lines}
    assert set(rows) == set(scene.agent_paths)
    for path, row in rows.items():
        prim = scene.stage.GetPrimAtPath(path)
        assert row[0] == path.rsplit("/", 1)[-1]
        assert int(row[2]) == prim.GetAttribute("crowd:agentId").Get()
        assert row[3] == str(prim.GetRelationship("crowd:group").GetTargets()[0])
    assert rows[GUIDE][4:] == ["no", "invisibleLeader"] and rows[TEACHER][4:] == ["yes", "leader"]

    code, out, _ = run(capsys, "inspect", shot, "--agents", "--json")
    assert code == 0
    agents = json.loads(out)
    assert len(out.strip().splitlines()) == len(agents) == 6            # one agent a line, valid JSON
    by_path = {a["path"]: a for a in agents}
    assert set(by_path) == set(rows)
    for path, row in rows.items():
        a = by_path[path]
        assert [a["name"], a["path"], str(a["id"]), a["group"], "yes" if a["visible"] else "no", a["role"]] == row
    assert by_path[GUIDE]["visible"] is False and by_path[GUIDE]["role"] == "invisibleLeader"


@pytest.mark.parametrize("argv, wrong, meant", [
    (["frame", "{shot}", "--behavior", "orbit", "--targets", "Teachr", STUDENT], "Teachr", "'Teacher'"),
    (["frame", "{shot}", "--behavior", "orbit", "--targets", TEACHER, "/World/Crowd/Visitors/Students/clone_000"],
     "/World/Crowd/Visitors/Students/clone_000", f"'{STUDENT}'"),
    (["features", "{shot}", "Teacher", "guide", "-o", "{out}"], "guide", "'Guide'"),
    (["frame", "{shot}", "--like", "{shot}", "--camera", CROWDCAM, "--like-targets", "Gide", "Teacher",
      "--targets", TEACHER, STUDENT], "Gide", "'Guide'"),
])
def test_a_missing_agent_is_refused_with_the_nearest_names(shot, tmp_path, capsys, argv, wrong, meant):
    before = digest(shot.parent)
    extra = ["--no-progress"] if argv[0] == "frame" else []
    code, _, err = run(capsys, *[a.format(shot=shot, out=tmp_path / "out") for a in argv], *extra)
    one_line_error(code, err, f"no agent named '{wrong}'", f"did you mean {meant}", "inspect", "--agents")
    assert digest(shot.parent) == before and not (tmp_path / "out").exists()


def test_no_close_name_still_says_where_the_names_are(shot, tmp_path, capsys):
    code, _, err = run(capsys, "features", shot, "Teacher", "Zebra", "-o", tmp_path / "out")
    one_line_error(code, err, "no agent named 'Zebra'", f"inspect {shot} --agents", "6 agents")
    assert "did you mean" not in err


# ------------------------------------------------------------------ 2. invisible targets
@pytest.mark.parametrize("targets, switch", [([GUIDE, TEACHER], []), (["Teacher", "Guide"], []),
                                             ([TEACHER, STUDENT], ["--switch", "6", "Guide", "Teacher"])])
def test_frame_refuses_an_invisible_target_naming_it(shot, capsys, targets, switch):
    before = digest(shot.parent)
    code, _, err = run(capsys, "frame", shot, "--behavior", "orbit", "--targets", *targets, *switch,
                       "--no-progress")
    one_line_error(code, err, GUIDE, "invisible leader")
    assert digest(shot.parent) == before


def test_frame_films_visible_targets(made, tmp_path, capsys):
    shot = copy_of(made, tmp_path / "copy")
    code, out, err = run(capsys, "frame", shot, "--behavior", "orbit", "--targets", "Teacher", STUDENT,
                         "--no-progress")
    assert code == 0, err
    assert f"{TEACHER} & {STUDENT}" in out


# ------------------------------------------------------------------ 3. --like takes the reference's toric camera
def test_frame_like_takes_the_reference_toric_camera_not_its_first(made, tmp_path, capsys):
    from pxr import Usd

    from usdcrowd.scenario.shot_scene import ShotScene

    reference = copy_of(made, tmp_path / "reference")
    code, _, err = run(capsys, "frame", reference, "--behavior", "side-track", "--targets", "Teacher", STUDENT,
                       "--name", "Toric", "--no-progress")
    assert code == 0, err
    cameras = ShotScene(reference).camera_paths
    assert cameras.index("/World/Cameras/Toric") > 0            # not the reference's first camera
    shot = copy_of(made, tmp_path / "shot")
    code, out, err = run(capsys, "frame", shot, "--like", reference, "--targets", "Teacher", STUDENT,
                         "--name", "Learned", "--no-progress")
    assert code == 0, err
    assert f"like /World/Cameras/Toric of {reference}" in out, out
    stage = Usd.Stage.Open(str(shot))
    prim = stage.GetPrimAtPath("/World/Cameras/Learned")
    assert prim.GetAttribute("crowd:toric:behavior").Get() == "learned"
    assert prim.GetAttribute("crowd:toric:reference").Get().path == "../../reference/shot/shot.usda"


def test_frame_like_without_a_toric_camera_names_the_reference_cameras(made, tmp_path, capsys):
    from usdcrowd.scenario.shot_scene import ShotScene

    shot = copy_of(made, tmp_path / "shot")
    reference = made / "shot" / "shot.usda"             # no toric camera: the overview and CrowdCam
    before = digest(shot.parent)
    for extra in ([], ["--like-targets", "Teacher", STUDENT]):
        code, _, err = run(capsys, "frame", shot, "--like", reference, "--targets", "Teacher", STUDENT, *extra,
                           "--no-progress")
        one_line_error(code, err, "no toric camera", "--camera", *ShotScene(reference).camera_paths)
    assert digest(shot.parent) == before


# ------------------------------------------------------------------ 4. cameras counts what cameras.usda holds
def _cameras_in_file(shot: Path) -> list[str]:
    """Camera prims that cameras.usda authors, seen on the composed shot (plain usd-core)."""
    from pxr import Usd, UsdGeom

    layer = (shot.parent / "cameras.usda").resolve()
    stage = Usd.Stage.Open(str(shot))
    return [str(p.GetPath()) for p in stage.Traverse() if p.IsA(UsdGeom.Camera)
            and any(Path(s.layer.realPath or "/").resolve() == layer for s in p.GetPrimStack())]


def test_cameras_counts_match_what_cameras_usda_holds(made, tmp_path, capsys):
    from pxr import Sdf

    shot = copy_of(made, tmp_path / "shot")
    assert run(capsys, "frame", shot, "--behavior", "orbit", "--targets", "Teacher", STUDENT, "--name", "Kept",
               "--no-progress")[0] == 0
    code, out, err = run(capsys, "cameras", shot, "--count", "2", "--static", "1", "--no-progress")
    assert code == 0, err
    held = _cameras_in_file(shot)
    said = re.search(r": (\d+) cameras \(([^)]*)\)", out.splitlines()[0])
    assert said and int(said.group(1)) == len(held) == 5, (out, held)      # 2 agents, 1 static, CrowdCam, Kept
    parts = said.group(2).split(", ")
    assert {"2 agents", "1 static", "CrowdCam", "1 toric kept"} == set(parts), parts
    data = Sdf.Layer.FindOrOpen(str(shot.parent / "cameras.usda")).customLayerData["usdcrowd"]
    assert data["cameras"] == len(held)
    # Once more without the static one: the count follows the file again.
    code, out, err = run(capsys, "cameras", shot, "--count", "1", "--no-progress")
    assert code == 0, err
    assert f": {len(_cameras_in_file(shot))} cameras (1 agents, CrowdCam, 1 toric kept)" in out, out


# ------------------------------------------------------------------ 5. static cameras: one pose
def test_static_cameras_hold_one_pose_and_are_not_called_animated(made, tmp_path, capsys):
    from pxr import Sdf, Usd, UsdGeom

    from usdcrowd.scenario.shot_scene import ShotScene

    shot = copy_of(made, tmp_path / "shot")
    code, _, err = run(capsys, "cameras", shot, "--count", "1", "--static", "2", "--no-progress")
    assert code == 0, err
    layer = Sdf.Layer.FindOrOpen(str(shot.parent / "cameras.usda"))
    stage = Usd.Stage.Open(str(shot))
    static = [p for p in _cameras_in_file(shot) if "/Static" in p]
    assert len(static) == 2
    for path in static:
        for name in ("xformOp:transform", "focalLength"):
            spec = layer.GetAttributeAtPath(f"{path}.{name}")
            assert spec.HasDefaultValue() and layer.GetNumTimeSamplesForPath(spec.path) == 0, (path, name)
        assert not UsdGeom.Xformable(stage.GetPrimAtPath(path)).TransformMightBeTimeVarying()
    # A moving camera keeps a sample a frame.
    assert layer.GetNumTimeSamplesForPath(Sdf.Path("/World/Cameras/Agent01.xformOp:transform")) == 12
    code, out, _ = run(capsys, "inspect", shot, "--json")
    animated = {c["path"]: c["animated"] for c in json.loads(out)["cameras"]}
    assert [animated[p] for p in static] == [False, False] and animated["/World/Cameras/Agent01"] is True
    code, out, _ = run(capsys, "inspect", shot)
    assert all("animated" not in line for line in out.splitlines() if "/Static" in line)
    # The renderers read the one pose at every frame.
    scene = ShotScene(shot)
    for path in static:
        views = [scene.camera(path, t) for t in (1, 6, 12)]
        assert all(np.array_equal(v.cam_to_world, views[0].cam_to_world) for v in views)
        assert views[0].focal_length > 0 and np.isfinite(views[0].cam_to_world).all()


# ------------------------------------------------------------------ 6. features in degrees, units in the header
def test_features_writes_degrees_with_units_in_the_header_like_the_usd(made, tmp_path, capsys):
    from pxr import Usd

    from usdcrowd.jobs.toric_filming import shot_features

    shot = copy_of(made, tmp_path / "shot")
    assert run(capsys, "frame", shot, "--behavior", "relative-track", "--targets", "Teacher", STUDENT,
               "--name", "Toric", "--no-progress")[0] == 0
    camera = "/World/Cameras/Toric"
    code, _, err = run(capsys, "features", shot, "Teacher", STUDENT, "-o", tmp_path / "f", "--camera", camera)
    assert code == 0, err
    with open(tmp_path / "f" / "features.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    header = list(rows[0])
    assert header == ["time_code", "pA_x_ndc", "pA_y_ndc", "pB_x_ndc", "pB_y_ndc", "theta_deg", "phi_deg", "dAB_m",
                      "sA_deg", "sB_deg", "sAB_deg", "M"]
    doc = json.loads((tmp_path / "f" / "features.json").read_text())
    assert list(doc["frames"][0]) == header
    # The same degrees the toric camera authored in USD (crowd:toric:theta, phi).
    stage = Usd.Stage.Open(str(shot))
    prim = stage.GetPrimAtPath(camera)
    for row, frame in zip(rows, doc["frames"]):
        t = float(row["time_code"])
        for key, attr in (("theta_deg", "crowd:toric:theta"), ("phi_deg", "crowd:toric:phi")):
            assert float(row[key]) == pytest.approx(prim.GetAttribute(attr).Get(t), abs=0.05), (t, key)
            assert frame[key] == pytest.approx(float(row[key]), abs=1e-9)
    # Every angle in degrees: the library's radians, converted.
    f, _ = shot_features(shot, camera, "Teacher", STUDENT)
    for key, values in (("sA_deg", f.s_a), ("sB_deg", f.s_b), ("sAB_deg", f.s_ab), ("theta_deg", f.theta)):
        np.testing.assert_allclose([float(r[key]) for r in rows], np.degrees(values), atol=1e-6)
    np.testing.assert_allclose([float(r["dAB_m"]) for r in rows], f.d_ab, atol=1e-6)


# ------------------------------------------------------------------ 7. labelled progress
def test_metrics_labels_each_step_and_hides_bars_on_no_progress(shot, tmp_path, capsys):
    code, out, err = run(capsys, "metrics", shot, "-o", tmp_path / "m", "--counts", "2,3")
    assert code == 0, err
    for step in ("read crowd", "metrics 2 autonomous", "metrics 2 static", "metrics 3 autonomous",
                 "metrics 3 static"):
        assert step in err, (step, err[-2000:])
    code, out, err = run(capsys, "metrics", shot, "-o", tmp_path / "q", "--counts", "2", "--no-progress")
    assert code == 0 and err == "", err
    assert (tmp_path / "q" / "summary.csv").is_file()


def test_demo_prints_each_step_as_it_starts_with_labelled_progress(tmp_path, capsys, monkeypatch):
    """The slow renderers are stood in for (each finds its step's line already printed, and is asked for
    progress exactly when the demo is)."""
    import usdcrowd.render.demo as demo
    import usdcrowd.render.sequence as sequence
    from usdcrowd.core.errors import UsdcrowdError

    seen = {}

    def stand_in(step):
        def call(*args, progress=None, **kwargs):
            seen[step] = (capsys.readouterr(), progress)
            raise UsdcrowdError("stood in for by the test")
        return call

    monkeypatch.setattr(demo, "preview_outputs", stand_in("preview"))
    monkeypatch.setattr(sequence, "render_sequence", stand_in("render"))
    for progress in (True, False):
        seen.clear()
        code, out, err = run(capsys, "demo", "-o", tmp_path / f"demo{progress}", "--agents", "6", "--cameras", "1",
                             *([] if progress else ["--no-progress"]))
        assert code == 0, err
        (before_preview, asked_preview), (before_render, asked_render) = seen["preview"], seen["render"]
        assert before_preview.out.rstrip().splitlines()[-1].startswith("[7] preview ")
        assert before_render.out.rstrip().splitlines()[-1].startswith("[8] render ")
        assert asked_preview is progress and asked_render is progress
        started = before_preview.out + before_render.out + out
        for k, name in enumerate(("scenario", "validate", "simulate", "validate", "frame", "edit", "preview", "render"), 1):
            assert re.search(rf"^\[{k}\] {name} +.* \.\.\.$", started, re.M), (k, started)
        bars = before_preview.err + before_render.err + err
        if progress:
            for label in ("simulate", "find pairs", "read characters"):
                assert f"{label}:" in bars, (label, bars[-2000:])
        else:
            assert bars == ""


# ------------------------------------------------------------------ 8. careless numbers, one line, before work
CARELESS = [
    (["frame", "{shot}", "--behavior", "orbit", "--targets", "auto", "--orbit-speed", "inf"], "--orbit-speed"),
    (["frame", "{shot}", "--behavior", "orbit", "--targets", "auto", "--orbit-speed", "nan"], "--orbit-speed"),
    (["frame", "{shot}", "--behavior", "orbit", "--targets", "auto", "--orbit-speed", "1e300"], "--orbit-speed"),
    (["frame", "{shot}", "--behavior", "relative-track", "--targets", "auto", "--offset", "nan"], "--offset"),
    (["frame", "{shot}", "--behavior", "relative-track", "--targets", "auto", "--offset", "-inf"], "--offset"),
    (["frame", "{shot}", "--behavior", "orbit", "--targets", "auto", "--span", "inf"], "--span"),
    (["frame", "{shot}", "--behavior", "orbit", "--targets", "auto", "--span", "nan"], "--span"),
    (["frame", "{shot}", "--behavior", "orbit", "--targets", "auto", "--span", "1e-300"], "--span"),
    (["frame", "{shot}", "--behavior", "orbit", "--targets", "auto", "--name", "a/b c"], "--name"),
    (["frame", "{shot}", "--behavior", "orbit", "--targets", "auto", "--name", "1st"], "--name"),
    (["frame", "{shot}", "--behavior", "orbit", "--targets", "auto", "--name", ""], "--name"),
    (["cameras", "{shot}", "--count", "1000000"], "--count"),
    (["cameras", "{shot}", "--static", "1000000"], "--static"),
    (["cameras", "{shot}", "--count", "600", "--static", "600"], "--count and --static"),
    (["metrics", "{shot}", "-o", "{out}", "--counts", "100000"], "--counts"),
    (["metrics", "{shot}", "-o", "{out}", "--counts", "4,1001"], "--counts"),
    (["demo", "-o", "{out}", "--cameras", "1000000"], "--cameras"),
]


@pytest.mark.parametrize("argv, option", CARELESS, ids=[" ".join(a[:1] + a[-2:]) for a, _ in CARELESS])
def test_a_careless_number_is_refused_in_one_line_before_any_work(made, tmp_path, capsys, argv, option):
    shot = made / "shot" / "shot.usda"
    before = digest(made)
    code, out, err = run(capsys, *[a.format(shot=shot, out=tmp_path / "out") for a in argv], "--no-progress")
    one_line_error(code, err, option)
    if argv[0] in ("cameras", "metrics", "demo"):
        assert "1,000 cameras" in err or "1000 cameras" in err, err
    assert out == "" and digest(made) == before and not (tmp_path / "out").exists()
