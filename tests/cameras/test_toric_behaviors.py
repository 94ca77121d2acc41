"""Seed 002's four camera behaviors in three shot sizes, and `usdcrowd frame` as a user runs it."""

from __future__ import annotations

import hashlib
import json
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from usdcrowd.core import model
from usdcrowd.cameras.behaviors import (BEHAVIORS, MIN_BETA, SHOT_SIZES, Behavior, behavior_track,
                                        clear_of_obstacles, fov_y)
from usdcrowd.cameras.toric import toric_to_poses
from usdcrowd.cli import main
from usdcrowd.core.resources import data_dir
from usdcrowd.core.view import CameraView

FPS = 24.0
FOV_X = 2 * np.arctan(18 / 50)          # the default 50 mm lens on 36 mm
ASPECT = 16 / 9
HEAD = 1.62                             # head point of a 1.75 m character (midway neck to top)


def _run(*argv) -> int:
    return int(main([str(a) for a in argv]) or 0)


def _sha(path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _azimuth(v):
    return np.arctan2(v[..., 1], v[..., 0])


def _deg(a):
    return np.degrees((np.asarray(a) + np.pi) % (2 * np.pi) - np.pi)


def _view(m):
    focal = 36.0 / (2 * np.tan(FOV_X / 2))
    return CameraView("/c", 1.0, m, focal, 36.0, 36.0 / ASPECT, 0.01, 1e4)


def _screen(m, point, width=1600, height=900):
    """NDC of a world point through the renderers' camera model (not the behaviors' own projection)."""
    uv, z = _view(m).project(np.asarray(point), width, height)
    return np.array([uv[0] / width * 2 - 1, 1 - uv[1] / height * 2]), float(z)


# --------------------------------------------------------------- the motions the behaviors follow
def _walking_side_by_side(frames=240, speed=1.2):
    """A and B walk along +x, B one metre to A's left; both face the way they go."""
    t = np.arange(1, frames + 1, dtype=np.float64)
    a = np.stack([t / FPS * speed, np.zeros_like(t), np.full_like(t, HEAD)], -1)
    return t, a, a + [0.0, 1.0, 0.03], np.zeros_like(t), np.zeros_like(t)


def _walking_in_line(frames=240, speed=1.2):
    """B walks 1.5 m behind A along +x."""
    t, a, _, ya, yb = _walking_side_by_side(frames, speed)
    return t, a, a - [1.5, 0.0, 0.0], ya, yb


def _facing_each_other(frames=240):
    """A at the origin faces B 1.5 m along +x; B faces A; both sway a little."""
    t = np.arange(1, frames + 1, dtype=np.float64)
    sway = 0.05 * np.sin(t / 10)
    a = np.stack([np.zeros_like(t), sway, np.full_like(t, HEAD)], -1)
    b = np.stack([np.full_like(t, 1.5), -sway, np.full_like(t, HEAD + 0.05)], -1)
    return t, a, b, 0.1 * np.sin(t / 17), np.pi + 0.1 * np.sin(t / 13)


def _turning(frames=240):
    """A stands and turns slowly (45 degrees over the shot); B walks around it."""
    t = np.arange(1, frames + 1, dtype=np.float64)
    yaw_a = np.radians(45) * (t - 1) / (frames - 1)
    ang = np.radians(60) * (t - 1) / (frames - 1)
    a = np.stack([np.zeros_like(t), np.zeros_like(t), np.full_like(t, HEAD)], -1)
    b = np.stack([2 * np.cos(ang), 2 * np.sin(ang), np.full_like(t, HEAD)], -1)
    return t, a, b, yaw_a, ang + np.pi


MOTIONS = {"side-by-side": _walking_side_by_side, "in-line": _walking_in_line,
           "facing": _facing_each_other, "turning": _turning}


@pytest.mark.parametrize("motion", MOTIONS)
@pytest.mark.parametrize("shot", SHOT_SIZES)
@pytest.mark.parametrize("name", BEHAVIORS)
def test_every_behavior_keeps_both_heads_on_screen_and_its_toric_coordinates_rebuild_it(name, shot, motion):
    t, a, b, ya, yb = MOTIONS[motion]()
    tr = behavior_track(Behavior(name, shot), t, FPS, a, b, ya, yb, FOV_X, ASPECT)
    # Projected by the renderers' camera model: both heads in front and inside the frame, where pA, pB say.
    for k in range(0, len(t), 7):
        for head, p in ((a[k], tr.p_a[k]), (b[k], tr.p_b[k])):
            ndc, z = _screen(tr.cam_to_world[k], head)
            assert z > 0 and np.abs(ndc).max() < 0.95, (k, ndc)
            np.testing.assert_allclose(ndc, p, atol=1e-6)
    # (pA, pB, theta, phi) rebuild the same camera through toric space.
    rebuilt = toric_to_poses(a, b, tr.p_a, tr.p_b, tr.theta, tr.phi, FOV_X, ASPECT)
    np.testing.assert_allclose(rebuilt, tr.cam_to_world, atol=1e-6)
    # A level camera (no roll) that moves without jumps.
    assert np.abs(tr.cam_to_world[:, 0, 2]).max() < 1e-9
    step = np.linalg.norm(np.diff(tr.cam_to_world[:, 3, :3], axis=0), axis=1)
    assert step.max() < 0.25, step.max()


def test_direct_track_is_in_front_of_walkers_and_beside_a_pair_that_faces_each_other():
    t, a, b, ya, yb = _walking_side_by_side()
    tr = behavior_track(Behavior("direct-track", "medium"), t, FPS, a, b, ya, yb, FOV_X, ASPECT)
    seen_from = tr.cam_to_world[:, 3, :2] - 0.5 * (a + b)[:, :2]
    assert np.abs(_deg(_azimuth(seen_from) - 0.0)).max() < 2.0          # straight ahead of them (+x)
    t, a, b, ya, yb = _facing_each_other()
    for side, sign in (("left", 1), ("right", -1)):
        tr = behavior_track(Behavior("direct-track", "medium", side=sign), t, FPS, a, b, ya, yb, FOV_X, ASPECT)
        rel = _deg(_azimuth(tr.cam_to_world[:, 3, :2] - 0.5 * (a + b)[:, :2]) - _azimuth((b - a)[:, :2]))
        assert np.abs(rel - sign * 90).max() < 8.0, (side, rel.min(), rel.max())


def test_relative_track_holds_its_angle_to_the_main_characters_shoulders_as_they_turn():
    t, a, b, ya, yb = _turning()
    tr = behavior_track(Behavior("relative-track", "medium", offset=35.0, react=0.25), t, FPS, a, b, ya, yb,
                        FOV_X, ASPECT)
    rel = _deg(_azimuth(tr.cam_to_world[:, 3, :2] - a[:, :2]) - ya)
    inner = slice(12, -12)                  # the direction's smoothing reflects at the ends
    assert np.abs(rel[inner] - 35.0).max() < 1.0
    turned = _deg(_azimuth(tr.cam_to_world[-13, 3, :2] - a[-13, :2]) - _azimuth(tr.cam_to_world[12, 3, :2]))
    assert 35 < turned < 50                 # the camera went round with A (45 degrees over the shot)


def test_side_track_films_from_the_side_of_travel_at_a_steady_framing():
    t, a, b, ya, yb = _walking_in_line()
    for side, sign in (("left", 1), ("right", -1)):
        tr = behavior_track(Behavior("side-track", "long", side=sign), t, FPS, a, b, ya, yb, FOV_X, ASPECT)
        rel = _deg(_azimuth(tr.cam_to_world[:, 3, :2] - 0.5 * (a + b)[:, :2]))
        assert np.abs(rel - sign * 90).max() < 2.0, side
        # Framing static: the heads stay where they are on screen.
        assert np.ptp(tr.p_a, axis=0).max() < 0.01 and np.ptp(tr.p_b, axis=0).max() < 0.01


def test_orbit_turns_around_the_pair_at_its_speed():
    t, a, b, ya, yb = _facing_each_other()
    tr = behavior_track(Behavior("orbit", "medium", orbit_speed=20.0), t, FPS, a, b, ya, yb, FOV_X, ASPECT)
    az = np.unwrap(_azimuth(tr.cam_to_world[:, 3, :2] - 0.5 * (a + b)[:, :2]))
    inner = slice(24, -24)
    rate = np.degrees(np.polyfit(t[inner] / FPS, az[inner], 1)[0])
    assert rate == pytest.approx(20.0, abs=0.5)


@pytest.mark.parametrize("shot", SHOT_SIZES)
def test_shot_size_sets_the_main_characters_height_on_screen(shot):
    """The frame's height covers ``span`` metres at the camera's distance: a 1.75 m person is 1.75 / span frames tall."""
    t, a, b, ya, yb = _walking_in_line()
    size = SHOT_SIZES[shot]
    # In front of A, B behind it: their heads are close on screen, so the camera stands where the size says.
    tr = behavior_track(Behavior("relative-track", shot, offset=25.0), t, FPS, a, b, ya, yb, FOV_X, ASPECT)
    want = size.span / (2 * np.tan(fov_y(FOV_X, ASPECT) / 2))
    np.testing.assert_allclose(tr.distance, want, rtol=1e-6)
    # A vertical 1.75 m segment where A stands, projected: its height in image heights.
    k = 100
    top, _ = _screen(tr.cam_to_world[k], a[k] + [0, 0, 1.75 - HEAD])
    foot, _ = _screen(tr.cam_to_world[k], a[k] - [0, 0, HEAD])
    assert (top[1] - foot[1]) / 2 == pytest.approx(1.75 / size.span, rel=0.12)


def test_a_camera_that_would_stand_behind_a_wall_comes_in_front_of_it():
    wall = model.Obstacles(["/Wall"], [np.array([[-10, 3.0], [30, 3.0], [30, 3.3], [-10, 3.3]])], np.array([3.5]))
    anchor = np.array([[0.0, 0.0, 1.6], [0.0, 0.0, 1.6], [0.0, 0.0, 1.6]])
    eye = np.array([[0.0, 7.0, 1.6], [2.0, -7.0, 1.6], [0.0, 7.0, 9.0]])   # behind, away, over the top
    got = clear_of_obstacles(anchor, eye, wall, margin=0.3)
    np.testing.assert_allclose(got[0], [0.0, 2.7, 1.6], atol=1e-9)
    np.testing.assert_allclose(got[1:], eye[1:])
    # Through a behavior: the long side track of walkers along a wall stays inside the courtyard.
    t, a, b, ya, yb = _walking_in_line()
    a, b = a + [0, 1.5, 0], b + [0, 1.5, 0]
    tr = behavior_track(Behavior("side-track", "long"), t, FPS, a, b, ya, yb, FOV_X, ASPECT, obstacles=wall)
    assert tr.cam_to_world[:, 3, 1].max() == pytest.approx(2.7, abs=0.05)


def test_unknown_behaviors_shot_sizes_and_sides_are_refused():
    for kwargs in ({"name": "dolly"}, {"name": "orbit", "shot": "extreme"}, {"name": "orbit", "side": 0}):
        with pytest.raises(ValueError):
            Behavior(**kwargs)


def test_no_camera_hides_one_character_behind_the_other():
    """A camera wanted on the line AB cranes up over it: MIN_BETA from AB, the two heads apart on screen."""
    t, a, b, ya, yb = _walking_side_by_side()
    tr = behavior_track(Behavior("side-track", "medium"), t, FPS, a, b, ya, yb, FOV_X, ASPECT)
    ab, ac = b - a, tr.cam_to_world[:, 3, :3] - a
    cos = np.einsum("ti,ti->t", ab, ac) / np.linalg.norm(ab, axis=1) / np.linalg.norm(ac, axis=1)
    assert np.degrees(np.arccos(np.abs(cos))).min() >= np.degrees(MIN_BETA) - 0.5
    assert (tr.cam_to_world[:, 3, 2] > HEAD + 0.3).all()                    # above them
    assert np.linalg.norm(tr.p_a - tr.p_b, axis=1).min() > 0.1
    # An orbit passes over the line AB twice a turn, and never jumps.
    t, a, b, ya, yb = _facing_each_other(frames=24 * 30)
    tr = behavior_track(Behavior("orbit", "medium", orbit_speed=24.0), t, FPS, a, b, ya, yb, FOV_X, ASPECT)
    step = np.linalg.norm(np.diff(tr.cam_to_world[:, 3, :3], axis=0), axis=1)
    assert step.max() < 2 * np.median(step)


# ------------------------------------------------------------------------- usdcrowd frame
@pytest.fixture(scope="module")
def dialogue_shot(tmp_path_factory):
    """The dialogue stage simulated over 120 frames: A and B talk, C and D walk across."""
    import shutil

    base = tmp_path_factory.mktemp("dialogue")
    shutil.copy(data_dir("stages") / "dialogue.usda", base / "dialogue.usda")
    out = base / "shot"
    assert _run("simulate", base / "dialogue.usda", "-o", out, "--frames", "1:120", "--no-progress") == 0
    return out


def _plain_usd(script: str) -> dict:
    """Run ``script`` in a fresh interpreter with usd-core only (no usdcrowd, no schema plugin)."""
    out = subprocess.run([sys.executable, "-c", textwrap.dedent(script)], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout)


def _read_camera(shot, path: str) -> dict:
    return _plain_usd(f"""
        import json
        from pxr import Usd, UsdGeom
        stage = Usd.Stage.Open({str(shot / 'shot.usda')!r})
        prim = stage.GetPrimAtPath({path!r})
        cache = [UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(t) for t in range(1, 121)]
        attr = lambda n, t: prim.GetAttribute("crowd:toric:" + n).Get(t)
        print(json.dumps({{
            "type": prim.GetTypeName(), "api": list(prim.GetAppliedSchemas()),
            "m": [[list(r) for r in m] for m in cache],
            "focal": prim.GetAttribute("focalLength").Get(1),
            "behavior": attr("behavior", 1), "shot": attr("shotSize", 1),
            "a": [attr("targetA", t) for t in range(1, 121)], "b": [attr("targetB", t) for t in range(1, 121)],
            "pA": [list(attr("pA", t)) for t in range(1, 121)], "pB": [list(attr("pB", t)) for t in range(1, 121)],
            "theta": [attr("theta", t) for t in range(1, 121)], "phi": [attr("phi", t) for t in range(1, 121)],
            "cameras": sorted(str(p.GetPath()) for p in stage.Traverse() if p.GetTypeName() == "Camera"),
        }}))
    """)


def test_frame_adds_a_toric_camera_that_plain_usd_reads_and_whose_features_hold(dialogue_shot, capsys):
    from usdcrowd.scenario.shot_scene import ShotScene
    from usdcrowd.cameras.features import head_and_facing

    before = ShotScene(dialogue_shot / "shot.usda")
    others = {p: [before.camera(p, t).cam_to_world for t in (1, 60, 120)] for p in before.camera_paths}
    assert _run("frame", dialogue_shot / "shot.usda", "--behavior", "orbit", "--targets", "A", "B",
                "--shot", "medium", "--no-progress") == 0
    assert "Orbit_A_B" in capsys.readouterr().out
    got = _read_camera(dialogue_shot, "/World/Cameras/Orbit_A_B")
    assert got["type"] == "Camera" and got["behavior"] == "orbit" and got["shot"] == "medium"
    assert set(got["a"]) == {"/World/Crowd/Pair/A"} and set(got["b"]) == {"/World/Crowd/Pair/B"}
    assert got["focal"] == pytest.approx(0.5)            # 50 mm in tenths of a scene unit (metres here)
    # Every other camera is still there, unchanged.
    after = ShotScene(dialogue_shot / "shot.usda")
    for p, mats in others.items():
        for t, m in zip((1, 60, 120), mats):
            np.testing.assert_array_equal(after.camera(p, t).cam_to_world, m)
    # The authored features are those of the camera plain USD reads, filming the heads our rig poses.
    rows = [after.agent_row("A"), after.agent_row("B")]
    for t in (1, 40, 80, 120):
        m = np.array(got["m"][t - 1])               # plain USD's world matrix of the camera (metres, Z up)
        heads, _ = head_and_facing(after.agents(t, rows).joints_world)
        for head, p in ((heads[0], got["pA"][t - 1]), (heads[1], got["pB"][t - 1])):
            ndc, z = _screen(m, head, 1920, 1080)
            assert z > 0
            np.testing.assert_allclose(ndc, p, atol=2e-5)         # float2 on the stage
        rebuilt = toric_to_poses(heads[0], heads[1], got["pA"][t - 1], got["pB"][t - 1],
                                 np.radians(got["theta"][t - 1]), np.radians(got["phi"][t - 1]), FOV_X, ASPECT)
        np.testing.assert_allclose(rebuilt[0], m, atol=2e-4)


def test_frame_switches_pairs_smoothly_and_cameras_keeps_it(dialogue_shot):
    assert _run("frame", dialogue_shot / "shot.usda", "--behavior", "direct-track", "--targets", "A", "B",
                "--shot", "long", "--switch", "60", "C", "D", "--name", "Switch", "--no-progress") == 0
    got = _read_camera(dialogue_shot, "/World/Cameras/Switch")
    assert got["a"][58] == "/World/Crowd/Pair/A" and got["a"][59] == "/World/Crowd/Walkers/Left/C"
    eye = np.array(got["m"])[:, 3, :3]
    step = np.linalg.norm(np.diff(eye, axis=0), axis=1)
    assert np.linalg.norm(eye[-1] - eye[0]) > 3.0
    # Blended over a second: a quick move, not the jump of a camera that switches targets at once.
    from usdcrowd.cameras.behaviors import Behavior
    from usdcrowd.jobs.toric_filming import PairSpan, frame_shot

    _, cut, _, _ = frame_shot(dialogue_shot / "shot.usda", Behavior("direct-track", "long"),
                              [PairSpan(1, "A", "B"), PairSpan(60, "C", "D")], name="Cut", transition=1e-3,
                              progress=False)
    jump = np.linalg.norm(np.diff(cut.cam_to_world[:, 3, :3], axis=0), axis=1).max()
    assert step.max() < 1.0 and jump > 2.5 * step.max(), (step.max(), jump)
    # Re-filming the steering cameras keeps the toric cameras.
    assert _run("cameras", dialogue_shot / "shot.usda", "--no-progress") == 0
    again = _read_camera(dialogue_shot, "/World/Cameras/Switch")
    np.testing.assert_allclose(again["m"], got["m"])
    assert again["a"] == got["a"]


@pytest.mark.parametrize("argv, words", [
    (("--targets", "A", "A"), "the same agent"),
    (("--targets", "A", "Nobody"), "no agent named 'Nobody'"),
    (("--targets", "A", "B", "--name", "CrowdCam"), "not a toric camera"),
    (("--targets", "A", "B", "--switch", "500", "C", "D"), "outside the shot's frames"),
    (("--targets", "A", "B", "--switch", "x", "C", "D"), "not a frame number"),
])
def test_bad_targets_are_one_line_errors_and_leave_the_cameras_alone(dialogue_shot, capsys, argv, words):
    cameras = dialogue_shot / "cameras.usda"
    before = _sha(cameras)
    assert _run("frame", dialogue_shot / "shot.usda", "--behavior", "orbit", *argv, "--no-progress") == 2
    err = capsys.readouterr().err.strip()
    assert words in err and "\n" not in err and "Traceback" not in err
    assert _sha(cameras) == before


def test_the_final_renderers_ground_truth_reports_the_toric_intent_it_measures_on_the_frame(dialogue_shot, tmp_path):
    """Per-frame JSON: the camera's authored intent, and the features measured on the rendered frame."""
    assert _run("frame", dialogue_shot / "shot.usda", "--behavior", "relative-track", "--targets", "B", "A",
                "--shot", "close-up", "--name", "Rel", "--no-progress") == 0
    out = tmp_path / "render"
    assert _run("render", dialogue_shot / "shot.usda", "--camera", "/World/Cameras/Rel", "--frames", "30:90x60",
                "--resolution", "128x72", "--spp", "4", "-o", out, "--no-progress") == 0
    got = _read_camera(dialogue_shot, "/World/Cameras/Rel")
    for t in (30, 90):
        rec = json.loads((out / "json" / f"frame.{t:04d}.json").read_text())
        intent = rec["camera_intent"]
        assert intent["behavior"] == "relative-track" and intent["shot_size"] == "close-up"
        assert intent["targets"] == ["/World/Crowd/Pair/B", "/World/Crowd/Pair/A"]
        assert rec["camera"]["toric"]["target_a"] == "/World/Crowd/Pair/B"
        # Measured on the frame (the render's own posing and camera) = authored by `frame` (read by plain USD).
        np.testing.assert_allclose(intent["pA"], got["pA"][t - 1], atol=1e-4)
        np.testing.assert_allclose(intent["pB"], got["pB"][t - 1], atol=1e-4)
        assert intent["theta"] == pytest.approx(got["theta"][t - 1], abs=1e-3)
        assert intent["phi"] == pytest.approx(got["phi"][t - 1], abs=1e-3)
        # Independent: B's head keypoint in the frame's own annotations is where pA says (pixels).
        names = rec["keypoint_names"]
        agent = next(a for a in rec["agents"] if a["path"] == "/World/Crowd/Pair/B")
        neck, top = (np.array(agent["keypoints"][names.index(n)][:2]) for n in ("neck", "headTop"))
        head_px = 0.5 * (neck + top)
        ndc = [head_px[0] / 128 * 2 - 1, 1 - head_px[1] / 72 * 2]
        # (the image midpoint of two keypoints at different depths is not the projected 3D midpoint: 0.1 px)
        np.testing.assert_allclose(ndc, intent["pA"], atol=3e-3)
        # The main character's height on screen, in image heights, is its keypoints' extent in the annotations.
        rows = np.array([k[1] for k in agent["keypoints"]])
        assert intent["main_height"] == pytest.approx(np.ptp(rows) / 72, abs=1e-6)
        assert intent["main_height"] > 1.0          # closer than a long shot, where the body fits the frame
        assert intent["dAB"] == pytest.approx(1.5, abs=0.2)


def test_auto_targets_pick_the_pair_the_scene_brings_together(dialogue_shot, capsys):
    """C and D walk closer together (0.8 m) than A and B stand (1.5 m), but A and B talk: a CrowdEvent of two."""
    from usdcrowd.scenario.shot_scene import ShotScene
    from usdcrowd.jobs.toric_filming import auto_spans

    spans = auto_spans(ShotScene(dialogue_shot / "shot.usda"), span=2.0)
    assert [(s.a, s.b) for s in spans] == [("/World/Crowd/Pair/A", "/World/Crowd/Pair/B")]
    assert _run("frame", dialogue_shot / "shot.usda", "--behavior", "side-track", "--targets", "auto",
                "--no-progress") == 0
    assert "SideTrack_A_B" in capsys.readouterr().out
    assert _run("frame", dialogue_shot / "shot.usda", "--behavior", "orbit", "--targets", "A", "--no-progress") == 2
    assert "two characters or 'auto'" in capsys.readouterr().err


def test_validate_reports_a_toric_camera_whose_target_is_not_an_agent(dialogue_shot, tmp_path):
    import shutil

    from usdcrowd.jobs.validation import validate

    shutil.copytree(dialogue_shot.parent, tmp_path / "copy")      # the shot refers to ../dialogue.usda
    shot = tmp_path / "copy" / "shot"
    assert _run("frame", shot / "shot.usda", "--behavior", "orbit", "--targets", "A", "B", "--name", "V",
                "--no-progress") == 0
    assert not [p for p in validate(shot / "shot.usda") if p.severity == "error"]
    text = (shot / "cameras.usda").read_text()
    (shot / "cameras.usda").write_text(text.replace('1: "/World/Crowd/Pair/B"', '1: "/World/Crowd/Pair/Nobody"'))
    errors = [p for p in validate(shot / "shot.usda") if p.severity == "error"]
    assert any(p.attribute == "crowd:toric:targetB" and "Nobody" in p.message for p in errors), errors


def test_features_follow_a_zooming_camera_frame_by_frame(dialogue_shot, tmp_path):
    """A camera whose focal length changes: each frame's pA, pB are measured with that frame's lens."""
    import shutil

    from pxr import Sdf

    from usdcrowd.jobs.toric_filming import shot_features
    from usdcrowd.scenario.shot_scene import ShotScene

    shutil.copytree(dialogue_shot.parent, tmp_path / "copy")
    shot = tmp_path / "copy" / "shot"
    assert _run("frame", shot / "shot.usda", "--behavior", "orbit", "--targets", "A", "B", "--name", "Zoom",
                "--shot", "long", "--no-progress") == 0
    layer = Sdf.Layer.FindOrOpen(str(shot / "shot.usda"))
    spec = Sdf.CreatePrimInLayer(layer, "/World/Cameras/Zoom")
    spec.specifier = Sdf.SpecifierOver
    focal = Sdf.AttributeSpec(spec, "focalLength", Sdf.ValueTypeNames.Float)
    layer.SetTimeSample(focal.path, 1.0, 0.35)          # 35 mm ...
    layer.SetTimeSample(focal.path, 120.0, 0.70)        # ... to 70 mm
    layer.Save()
    features, about = shot_features(shot / "shot.usda", "/World/Cameras/Zoom", "A", "B", [1, 60, 120], 1920, 1080)
    assert isinstance(about["fov_x_deg"], list) and about["fov_x_deg"][0] > about["fov_x_deg"][2]
    scene = ShotScene(shot / "shot.usda")
    rows = [scene.agent_row("A"), scene.agent_row("B")]
    from usdcrowd.cameras.features import head_and_facing

    for k, t in enumerate((1, 60, 120)):
        view = scene.camera("/World/Cameras/Zoom", t)
        heads, _ = head_and_facing(scene.agents(t, rows).joints_world)
        uv, _ = view.project(heads, 1920, 1080)
        ndc = np.stack([uv[:, 0] / 1920 * 2 - 1, 1 - uv[:, 1] / 1080 * 2], -1)
        np.testing.assert_allclose([features.p_a[k], features.p_b[k]], ndc, atol=1e-6)
