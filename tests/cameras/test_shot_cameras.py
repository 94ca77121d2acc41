"""Events and camera agents in a shot, as a user runs them: simulate, cameras, metrics."""

from __future__ import annotations

import hashlib
import json
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from usdcrowd.core import model
from usdcrowd.cameras.metrics import active_mask, coverage
from usdcrowd.cli import main
from usdcrowd.core.resources import data_dir
from usdcrowd.core.view import CameraView, look_at

HARBOUR = data_dir("stages") / "harbour.usda"


def _run(*argv) -> int:
    return int(main([str(a) for a in argv]) or 0)


def _sha(path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture(scope="module")
def harbour_shot(tmp_path_factory):
    """The harbour simulated over frames 1-240 (the boat moors at 60), with its three camera agents."""
    import shutil

    base = tmp_path_factory.mktemp("harbour")
    shutil.copy(HARBOUR, base / "harbour.usda")
    shutil.copytree(HARBOUR.parent / "maps", base / "maps")
    out = base / "shot"
    assert _run("simulate", base / "harbour.usda", "-o", out, "--frames", "1:240", "--no-progress") == 0
    return out


def _plain_usd(script: str) -> dict:
    """Run ``script`` in a fresh interpreter with usd-core only (no usdcrowd, no schema plugin)."""
    code = textwrap.dedent(script)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout)


def test_cameras_layer_holds_the_authored_camera_agents_with_state_read_by_plain_usd(harbour_shot):
    got = _plain_usd(f"""
        import json
        from pxr import Sdf, Usd
        stage = Usd.Stage.Open({str(harbour_shot / 'shot.usda')!r})
        out = {{}}
        for name in ("ScoutWest", "ScoutEast", "Pier", "CrowdCam"):
            prim = stage.GetPrimAtPath("/World/Cameras/" + name)
            xf = prim.GetAttribute("xformOp:transform")
            st = prim.GetAttribute("crowd:camera:state")
            tr = prim.GetAttribute("crowd:camera:trackedEvent")
            out[name] = {{"type": str(prim.GetTypeName()), "samples": len(xf.GetTimeSamples()),
                         "order": list(prim.GetAttribute("xformOpOrder").Get()),
                         "state": [st.Get(t) for t in (1, 59, 61, 240)] if st else None,
                         "tracked": [tr.Get(t) for t in (1, 59, 61, 240)] if tr else None,
                         "api": [str(s) for s in (prim.GetMetadata("apiSchemas") or
                                                   Sdf.TokenListOp()).GetAddedOrExplicitItems()]}}
        print(json.dumps(out))
    """)
    for name in ("ScoutWest", "ScoutEast", "Pier"):
        cam = got[name]
        assert cam["type"] == "Camera" and cam["samples"] == 240 and cam["order"] == ["xformOp:transform"]
        assert "CameraAgentAPI" in cam["api"]
        assert set(cam["state"]) <= {"scouting", "tracking"}
    # The Pier camera's target is the boat's arrival (frames 60-840): it waits, then tracks it.
    assert got["Pier"]["state"][:2] == ["scouting", "scouting"] and got["Pier"]["state"][2:] == ["tracking"] * 2
    assert got["Pier"]["tracked"][2:] == ["/World/Events/BoatArrival"] * 2 and got["Pier"]["tracked"][0] == ""
    assert got["CrowdCam"]["state"] is None


def test_detected_events_are_crowd_event_prims_with_time_sampled_member_ids(harbour_shot):
    from usdcrowd.scenario.events import read_events
    from usdcrowd.scenario.stageio import time_range
    from pxr import Usd

    got = _plain_usd(f"""
        import json
        from pxr import Usd
        stage = Usd.Stage.Open({str(harbour_shot / 'shot.usda')!r})
        out = {{}}
        for prim in stage.Traverse():
            if prim.GetTypeName() != "CrowdEvent" or prim.GetName() == "BoatArrival":
                continue
            ids = prim.GetAttribute("crowd:memberIds")
            members = prim.GetRelationship("crowd:members").GetTargets()
            start, end = prim.GetAttribute("crowd:startTime").Get(), prim.GetAttribute("crowd:endTime").Get()
            out[str(prim.GetPath())] = {{
                "kind": prim.GetAttribute("crowd:kind").Get(), "start": start, "end": end,
                "members": [str(m) for m in members],
                "ids": {{str(t): list(ids.Get(t)) for t in range(int(start), int(end) + 1)}},
                "centre": list(prim.GetAttribute("crowd:center").Get(start))}}
        print(json.dumps(out))
    """)
    assert got, "the workers' rush to the pier is a group motion"
    stage = Usd.Stage.Open(str(harbour_shot / "shot.usda"))
    id_of = {p.GetPath().pathString: p.GetAttribute("crowd:agentId").Get() for p in stage.Traverse()
             if p.HasAPI("CrowdAgentAPI")}
    pos_of = {}
    for path, ev in got.items():
        assert ev["kind"] in ("groupMotion", "interaction")
        member_ids = {id_of[m] for m in ev["members"]}
        seen = set()
        for ids in ev["ids"].values():
            assert set(ids) <= member_ids
            seen |= set(ids)
        assert seen == member_ids              # everyone listed took part at some frame
        pos_of[path] = ev["centre"]
    # Our reader gives the same events back.
    rows = {p: i for i, p in enumerate(id_of)}
    table = read_events(stage, rows, time_range(stage))
    detected = {e.path: e for e in table if not e.authored}
    assert set(detected) == set(got)
    for path, e in detected.items():
        np.testing.assert_allclose(e.center[0], pos_of[path], atol=1e-5)


def test_refilming_replaces_only_the_cameras_layer(harbour_shot, tmp_path, capsys):
    import shutil

    # The whole folder, so the shot's relative reference to its scenario still resolves.
    shutil.copytree(harbour_shot.parent, tmp_path / "copy")
    shot = tmp_path / "copy" / "shot"
    before = {name: _sha(shot / name) for name in ("shot.usda", "crowd.usdc")}
    assert _run("cameras", shot / "shot.usda", "--count", "5", "--static", "2", "--no-progress") == 0
    assert "5 agents" in capsys.readouterr().out
    assert {name: _sha(shot / name) for name in before} == before
    from pxr import Usd

    stage = Usd.Stage.Open(str(shot / "shot.usda"))
    cams = {str(p.GetPath()) for p in stage.Traverse() if p.GetTypeName() == "Camera"}
    assert {"/World/Cameras/Agent04", "/World/Cameras/Agent05", "/World/Cameras/Static01",
            "/World/Cameras/Static02"} <= cams
    gen = stage.GetPrimAtPath("/World/Cameras/Agent04")
    assert "CameraAgentAPI" in gen.GetAppliedSchemas()
    assert abs(gen.GetAttribute("crowd:camera:maxAngularSpeed").Get() - 60.0) < 1e-4     # degrees, as authored
    assert not list(shot.glob(".*partial*"))


def test_coverage_matches_projection_into_the_image(rng):
    """Algorithm 7 against an independent count: project every character with CameraView."""
    t, n = 5, 300
    pos = np.zeros((t, n, 3))
    pos[..., :2] = rng.uniform(-30, 30, (t, n, 2))
    active = rng.random((t, n)) < 0.3
    eye = np.array([[0.0, -40.0, 6.0], [35.0, 0.0, 4.0]])
    mats = look_at(eye, np.zeros((2, 3)))
    tracks = [model.CameraTrack(f"/C{k}", np.arange(t, dtype=float), np.repeat(mats[k:k + 1], t, 0),
                                np.full(t, 35.0), 36.0, 20.25, 0.1, 1000.0) for k in range(2)]
    series = coverage(tracks, pos, active, max_distance=100.0, min_pixels=30.0, image_width=640)
    w, h = 3600, 2025                   # the apertures' aspect: the image is the frustum
    for k in range(t):
        chest = pos[k] + [0, 0, 1.1]
        act = idle = 0.0
        seen = set()
        for c in range(2):
            view = CameraView(f"/C{c}", k, mats[c], 35.0, 36.0, 20.25, 0.1, 1000.0)
            uv, z = view.project(chest, w, h)
            d = np.linalg.norm(chest - eye[c], axis=1)
            inside = (z > 0.1) & (uv[:, 0] >= 0) & (uv[:, 0] <= w) & (uv[:, 1] >= 0) & (uv[:, 1] <= h) & (d < 100)
            # At least 30 px tall in a 640-wide frame: 1.7 m at its depth through the pinhole K.
            inside &= view.intrinsics(640, 360)[0, 0] * 1.7 / z >= 30.0
            act += (1 / d[inside & active[k]]).sum()
            idle += (1 / d[inside & ~active[k]]).sum()
            seen |= set(np.flatnonzero(inside & active[k]))
        assert series.score_active[k] == pytest.approx(act, rel=1e-9)
        assert series.score_idle[k] == pytest.approx(idle, rel=1e-9)
        assert series.n_active_viewed[k] == len(seen)
        assert series.n_active[k] == active[k].sum()


def test_active_mask_follows_time_varying_membership():
    times = np.arange(1.0, 11.0)
    act = np.zeros((4, 2), bool)
    act[:2, 0] = True
    act[1:, 1] = True
    ev = model.Event("/E", 1, 3.0, 6.0, np.array([5, 7], np.int32), np.arange(3.0, 7.0), act, np.zeros((4, 3)),
                     np.ones(4))
    mask = active_mask(model.EventTable([ev]), times, 9)
    assert mask[2, 5] and mask[3, 5] and not mask[4, 5]          # agent 5 at t = 3, 4, not 5
    assert not mask[2, 7] and mask[3, 7] and mask[5, 7] and not mask[6, 7]
    assert mask.sum() == 2 + 3


def test_metrics_command_writes_figures_and_csvs(harbour_shot, tmp_path, capsys):
    out = tmp_path / "metrics"
    assert _run("metrics", harbour_shot / "shot.usda", "-o", out, "--counts", "2", "--no-progress") == 0
    text = capsys.readouterr().out
    assert "autonomous" in text and "static" in text
    for name in ("summary.csv", "activity_2.csv", "viewed_2.csv", "activity_2.png", "viewed_2.png"):
        assert (out / name).stat().st_size > 0, name
    rows = (out / "activity_2.csv").read_text().splitlines()
    assert len(rows) == 1 + 240 and rows[0].startswith("time_code,")      # time codes, like every CSV we write
    # Static cameras both ways: placed knowing the whole shot, and on its first frame (where the workers
    # start: they see fewer of the people who take part later).
    import csv

    kinds = {r["kind"]: r for r in csv.DictReader(open(out / "summary.csv", newline=""))}
    assert set(kinds) == {"autonomous", "static", "static_start"}
    assert kinds["static_start"]["mean_active_share"] != kinds["static"]["mean_active_share"]
    assert (out / "tracking_2.csv").stat().st_size > 0


def test_refilming_a_shot_without_detected_events_detects_them_beside_the_cameras(harbour_shot, tmp_path, capsys):
    import shutil

    from pxr import Sdf, Usd

    shutil.copytree(harbour_shot.parent, tmp_path / "copy")
    shot = tmp_path / "copy" / "shot"
    crowd = Sdf.Layer.FindOrOpen(str(shot / "crowd.usdc"))
    events = crowd.GetPrimAtPath("/World/Events")
    names = [c.name for c in events.nameChildren]
    assert names, "the crowd layer holds the detected events"
    for name in names:
        del events.nameChildren[name]
    crowd.Save()
    assert _run("cameras", shot / "shot.usda", "--no-progress") == 0
    assert "(detected now)" in capsys.readouterr().out
    stage = Usd.Stage.Open(str(shot / "shot.usda"))
    again = sorted(p.GetName() for p in stage.GetPrimAtPath("/World/Events").GetChildren()
                   if p.GetName() != "BoatArrival")
    assert again == sorted(names)
    assert stage.GetPrimAtPath(f"/World/Events/{names[0]}").GetPrimStack()[0].layer.identifier.endswith(
        "cameras.usda")


def test_reading_a_shot_back_in_windows_gives_the_same_crowd_and_events(harbour_shot, tmp_path, monkeypatch):
    """The cameras read a shot a window at a time (bounded memory): the same positions and detected events."""
    import shutil

    from pxr import Sdf

    from usdcrowd.jobs import filming

    shutil.copytree(harbour_shot.parent, tmp_path / "copy")
    shot = tmp_path / "copy" / "shot"
    crowd = Sdf.Layer.FindOrOpen(str(shot / "crowd.usdc"))
    events = crowd.GetPrimAtPath("/World/Events")
    for name in [c.name for c in events.nameChildren]:
        del events.nameChildren[name]
    crowd.Save()
    loaded = {}
    for window in (512, 37):
        monkeypatch.setattr(filming, "READ_WINDOW", window)
        loaded[window] = filming.load_shot(shot / "shot.usda", progress=False)
    a, b = loaded[512], loaded[37]
    assert a.detected_now and b.detected_now and a.positions.shape == b.positions.shape == (240, 110, 3)
    np.testing.assert_allclose(np.asarray(b.positions), np.asarray(a.positions), atol=1e-6)
    assert [(e.path, e.start, e.end) for e in b.events] == [(e.path, e.start, e.end) for e in a.events]
    assert sum(not e.authored for e in a.events) > 0
    for x, y in zip(a.events, b.events):
        assert np.array_equal(x.members, y.members) and np.array_equal(x.active, y.active), x.path


def test_frame_json_records_the_camera_state_and_each_agents_events(harbour_shot, tmp_path):
    from pxr import Usd

    out = tmp_path / "render"
    stage = Usd.Stage.Open(str(harbour_shot / "shot.usda"))
    # A camera agent that tracks something at frame 200, and an event with members on screen.
    cam = next(p for p in stage.Traverse() if p.GetTypeName() == "Camera"
               and p.GetAttribute("crowd:camera:state") and p.GetAttribute("crowd:camera:state").Get(200) == "tracking")
    assert _run("render", harbour_shot / "shot.usda", "-o", out, "--camera", cam.GetPath(), "--frames", "200",
                "--resolution", "160x90", "--spp", "1", "--executor", "inline", "--no-progress") == 0
    record = json.loads((out / "json" / "frame.0200.json").read_text())
    assert record["camera"]["agent_state"] == "tracking"
    assert record["camera"]["tracked_event"] == cam.GetAttribute("crowd:camera:trackedEvent").Get(200)
    # Independent: each agent's events from the CrowdEvent prims' memberIds (or members) at frame 200.
    expected = {}
    for prim in stage.Traverse():
        if prim.GetTypeName() != "CrowdEvent":
            continue
        start, end = prim.GetAttribute("crowd:startTime").Get(), prim.GetAttribute("crowd:endTime").Get()
        if not start <= 200 <= end:
            continue
        ids = prim.GetAttribute("crowd:memberIds")
        if ids.HasAuthoredValue():
            who = set(ids.Get(200))
        else:
            who = {stage.GetPrimAtPath(t).GetAttribute("crowd:agentId").Get()
                   for t in prim.GetRelationship("crowd:members").GetTargets()}
        for i in who:
            expected.setdefault(int(i), set()).add(str(prim.GetPath()))
    assert record["agents"], "the tracked event is on screen"
    for agent in record["agents"]:
        assert {e["path"] for e in agent["events"]} == expected.get(agent["track_id"], set())
    assert any(agent["events"] for agent in record["agents"])


def test_harbour_camera_agents_move_smoothly_frame_their_event_and_stay_out_of_scenery(harbour_shot):
    """Section 6 of the steering-camera issue, measured on the shot with the renderer's own reader."""
    from usdcrowd.scenario.shot_scene import ShotScene
    from usdcrowd.scenario import load_scenario

    scene = ShotScene(harbour_shot / "shot.usda")
    stage, times, dt = scene.stage, scene.time_codes, 1.0 / scene.fps
    poses = [scene.agents(t) for t in times]
    row = {int(i): k for k, i in enumerate(poses[0].agent_ids)}
    obstacles = load_scenario(harbour_shot.parent / "harbour.usda").obstacles
    cams = [p for p in stage.Traverse() if p.GetAttribute("crowd:camera:state").HasValue()]
    assert len(cams) == 3
    counted = 0
    for cam in cams:
        state, tracked = cam.GetAttribute("crowd:camera:state"), cam.GetAttribute("crowd:camera:trackedEvent")
        views = [scene.camera(str(cam.GetPath()), t) for t in times]
        eye = np.array([v.position for v in views])
        fwd = np.array([-v.cam_to_world[2, :3] for v in views])
        max_force = cam.GetAttribute("crowd:camera:maxForce").Get()
        max_rate = np.radians(cam.GetAttribute("crowd:camera:maxAngularSpeed").Get())
        velocity = np.diff(eye, axis=0) / dt
        # Stated bounds: acceleration within maxForce; angular speed within maxAngularSpeed and, from
        # frame to frame, changing by at most half of it (gain 4/s over two substeps of 1/48 s).
        assert np.linalg.norm(np.diff(velocity, axis=0), axis=1).max() / dt <= max_force * 1.01
        rate = np.arccos(np.clip(np.einsum("ij,ij->i", fwd[1:], fwd[:-1]), -1, 1)) / dt
        assert rate.max() <= max_rate * 1.01
        assert np.abs(np.diff(rate)).max() <= 0.5 * max_rate
        # Above the ground, never inside scenery lower than the camera.
        assert eye[:, 2].min() >= 0.3
        for poly, height in zip(obstacles.polygons, obstacles.height):
            edges = np.roll(poly, -1, axis=0) - poly
            rel = eye[:, None, :2] - poly[None]
            inside = ((edges[None, :, 0] * rel[..., 1] - edges[None, :, 1] * rel[..., 0]) > 0).all(axis=1)
            assert not (inside & (eye[:, 2] < height)).any(), cam.GetPath()
        # The tracked event's visible members are all in the picture in >= 90 % of each agent's tracking
        # frames, counted from 2 s after it took the event (it has to turn and move to it first).
        framed = []
        since = None
        for k, t in enumerate(times):
            if state.Get(t) != "tracking":
                since = None
                continue
            since = t if since is None or tracked.Get(t) != tracked.Get(t - 1) else since
            if t - since < 2.0 * scene.fps:
                continue
            event = stage.GetPrimAtPath(tracked.Get(t))
            ids = event.GetAttribute("crowd:memberIds")
            who = ([row[i] for i in ids.Get(t)] if ids.HasAuthoredValue() else
                   [row[stage.GetPrimAtPath(m).GetAttribute("crowd:agentId").Get()]
                    for m in event.GetRelationship("crowd:members").GetTargets()])
            who = [w for w in who if poses[k].visible[w]]
            if who:
                uv, z = views[k].project(poses[k].joints_world[who, 0, 3, :3], 640, 360)
                framed.append(((z > 0) & (uv[:, 0] >= 0) & (uv[:, 0] < 640) & (uv[:, 1] >= 0)
                               & (uv[:, 1] < 360)).all())
        assert not framed or np.mean(framed) >= 0.9, (cam.GetPath(), np.mean(framed))
        counted += len(framed)
    # Enough tracking for the share to mean something: each new event costs an agent its 2 s, so how
    # the frames fall between the three depends on which events the crowd makes.
    assert counted > 120, counted


def test_cameras_on_a_scenario_is_a_one_line_error(capsys):
    code = _run("cameras", HARBOUR, "--no-progress")
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1
    assert "harbour.usda" in err and "not a usdcrowd shot" in err


@pytest.mark.parametrize("up, mpu", [("Z", 1.0), ("Y", 0.01)])
def test_camera_tracks_are_world_poses_in_the_stages_units_under_a_moved_parent(tmp_path, up, mpu):
    """A camera agent under a transformed rig, on a Y-up centimetre stage too: plain USD puts it where we said
    (its pose authored in the rig's space)."""
    from pxr import Gf, Sdf, Usd, UsdGeom

    from usdcrowd.scenario.parent_space import ParentSpace
    from usdcrowd.scenario.stageio import StageFrame
    from usdcrowd.usd.cameras import write_camera_tracks

    frame = StageFrame(up, mpu)
    scenario = tmp_path / "scenario.usda"
    stage = Usd.Stage.CreateNew(str(scenario))
    UsdGeom.SetStageUpAxis(stage, up)
    UsdGeom.SetStageMetersPerUnit(stage, mpu)
    world = UsdGeom.Xform.Define(stage, "/World")
    stage.SetDefaultPrim(world.GetPrim())
    rig = UsdGeom.Xform.Define(stage, "/World/Rig")
    rig.AddTranslateOp().Set(Gf.Vec3d(100.0, 20.0, 5.0))
    rig.AddRotateZOp().Set(30.0)
    cam = UsdGeom.Camera.Define(stage, "/World/Rig/Cam")
    cam.CreateFocalLengthAttr(50.0)
    stage.GetRootLayer().Save()
    times = np.array([1.0, 2.0])
    pose = look_at(np.array([[3.0, -10.0, 2.5], [4.0, -9.0, 3.0]]), np.zeros((2, 3)))
    track = model.CameraTrack("/World/Rig/Cam", times, pose, np.full(2, 35.0), 36.0, 20.25, 0.1, 500.0)
    write_camera_tracks(tmp_path, [track], frame, "World", model.TimeRange(1, 2, 24), defined={"/World/Rig/Cam"},
                        parents=ParentSpace(stage, times))
    shot = Sdf.Layer.CreateNew(str(tmp_path / "shot.usda"))
    shot.subLayerPaths = ["./cameras.usda", "./scenario.usda"]
    shot.Save()
    composed = Usd.Stage.Open(str(tmp_path / "shot.usda"))
    prim = composed.GetPrimAtPath("/World/Rig/Cam")
    for k, t in enumerate(times):
        m = np.array(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(t))
        np.testing.assert_allclose(m[:3, :3] @ frame.to_canonical[:3, :3] / mpu, pose[k, :3, :3], atol=1e-9)
        np.testing.assert_allclose(frame.points_to_canonical(m[3, :3]), pose[k, 3, :3], atol=1e-9)
        np.testing.assert_allclose(np.linalg.norm(m[:3, :3], axis=1), 1.0, atol=1e-12)   # not scaled
    assert UsdGeom.Camera(prim).GetFocalLengthAttr().Get(1.0) == 50.0                      # the user's lens


def test_simulate_without_event_detection_keeps_only_the_authored_events(tmp_path):
    from pxr import Usd

    out = tmp_path / "shot"
    assert _run("simulate", HARBOUR, "-o", out, "--frames", "1:72", "--no-events", "--no-progress") == 0
    stage = Usd.Stage.Open(str(out / "shot.usda"))
    events = [p.GetName() for p in stage.Traverse() if p.GetTypeName() == "CrowdEvent"]
    assert events == ["BoatArrival"]


@pytest.mark.parametrize("attribute, value", [("crowd:camera:viewAngle", "1.5"), ("crowd:camera:maxSpeed", "0"),
                                              ("crowd:camera:elevationRange", "(8, 2)"),
                                              ("crowd:camera:maxAngularSpeed", "nan")])
def test_a_bad_camera_agent_value_is_a_one_line_error_naming_it(tmp_path, capsys, attribute, value):
    text = HARBOUR.read_text()
    kind = "float2" if "Range" in attribute else "float"
    old = f"uniform {kind} {attribute} = "
    start = text.index(old)                          # the first camera agent's value (ScoutWest)
    end = text.index("\n", start)
    (tmp_path / "maps").symlink_to(HARBOUR.parent / "maps")
    bad = tmp_path / "harbour.usda"
    bad.write_text(text[:start] + old + value + text[end:])
    code = _run("simulate", bad, "-o", tmp_path / "shot", "--frames", "1:24", "--no-progress")
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1
    assert "/World/Cameras/ScoutWest" in err and attribute in err and "harbour.usda" in err
    assert not (tmp_path / "shot" / "shot.usda").exists()
