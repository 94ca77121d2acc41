"""Toric space (seed 002, Lino and Christie 2015): exact two-target framing and its inverse."""

from __future__ import annotations

import numpy as np
import pytest

from usdcrowd.cameras.toric import ToricError, framing_angle, pose_to_toric, toric_to_pose
from usdcrowd.core.view import CameraView

FOV_X = np.radians(50.0)
ASPECT = 16 / 9


def _random_config(rng):
    """Two targets at head height, screen positions and toric angles a camera can meet."""
    a = rng.uniform(-20, 20, 3) * [1, 1, 0] + [0, 0, rng.uniform(1.4, 1.9)]
    b = a + np.r_[rng.normal(size=2) * rng.uniform(0.5, 8.0), rng.uniform(-0.4, 0.4)]
    top = np.tan(FOV_X / 2) / ASPECT / np.tan(FOV_X / 2)
    p_a = np.array([rng.uniform(-0.9, -0.05), rng.uniform(-0.8, 0.8) * top])
    p_b = np.array([rng.uniform(0.05, 0.9), rng.uniform(-0.8, 0.8) * top])
    alpha = framing_angle(p_a, p_b, FOV_X, ASPECT)
    theta = rng.uniform(0.05, 0.95) * 2 * (np.pi - alpha)
    phi = rng.uniform(-1.3, 1.3)
    return a, b, p_a, p_b, theta, phi


def _ndc(view: CameraView, points, width=1600, height=900):
    uv, z = view.project(np.asarray(points), width, height)
    return np.stack([uv[..., 0] / width * 2 - 1, 1 - uv[..., 1] / height * 2], -1), z


def test_targets_land_exactly_where_asked_and_the_pose_comes_back(rng):
    """Property over 500 random configurations: reprojection and round trip exact to 1e-6."""
    for _ in range(500):
        a, b, p_a, p_b, theta, phi = _random_config(rng)
        m = toric_to_pose(a, b, p_a, p_b, theta, phi, FOV_X, ASPECT)
        np.testing.assert_allclose(m[:3, :3] @ m[:3, :3].T, np.eye(3), atol=1e-9)      # a rotation, no scale
        assert np.linalg.det(m[:3, :3]) == pytest.approx(1.0)
        # Projected by the renderers' own camera model (another code path): at p_a and p_b.
        focal = 36.0 / (2 * np.tan(FOV_X / 2))
        view = CameraView("/c", 1.0, m, focal, 36.0, 36.0 / ASPECT, 0.01, 1e4)
        ndc, z = _ndc(view, [a, b])
        assert (z > 0).all()
        np.testing.assert_allclose(ndc, [p_a, p_b], atol=1e-6)
        back = pose_to_toric(m, a, b, FOV_X, ASPECT)
        np.testing.assert_allclose(np.r_[back[0], back[1], back[2], back[3]], np.r_[p_a, p_b, theta, phi], atol=1e-6)


def test_the_angles_mean_what_the_docstring_says():
    a, b = np.array([0.0, 0.0, 1.7]), np.array([2.0, 0.0, 1.7])
    p_a, p_b = (-0.3, 0.0), (0.3, 0.0)
    alpha = framing_angle(p_a, p_b, FOV_X, ASPECT)
    # theta = pi - alpha: C on the perpendicular bisector (isosceles); phi = 0: level, on the up x AB (+y) side.
    m = toric_to_pose(a, b, p_a, p_b, np.pi - alpha, 0.0, FOV_X, ASPECT)
    eye = m[3, :3]
    assert eye[0] == pytest.approx(1.0) and eye[2] == pytest.approx(1.7) and eye[1] > 0
    assert np.hypot(*(eye - a)[:2]) == pytest.approx(np.hypot(*(eye - b)[:2]))
    # Positive phi raises the camera; pi / 2 puts it above the line AB.
    assert toric_to_pose(a, b, p_a, p_b, np.pi - alpha, 0.4, FOV_X, ASPECT)[3, 2] > 1.7
    above = toric_to_pose(a, b, p_a, p_b, np.pi - alpha, np.pi / 2, FOV_X, ASPECT)[3, :3]
    assert above[1] == pytest.approx(0.0, abs=1e-9) and above[2] > 1.7
    # A small theta: near the line AB, beyond B (over B's shoulder).
    near_b = toric_to_pose(a, b, p_a, p_b, 0.1, 0.0, FOV_X, ASPECT)[3, :3]
    assert near_b[0] > 2.0


@pytest.mark.parametrize("a, b, p_a, p_b, theta, words", [
    ((0, 0, 1.7), (0, 0, 1.7), (-0.3, 0), (0.3, 0), 1.0, "distinct targets"),
    ((0, 0, 1.0), (0, 0, 3.0), (-0.3, 0), (0.3, 0), 1.0, "one above the other"),
    ((0, 0, 1.7), (2, 0, 1.7), (0.2, 0.1), (0.2, 0.1), 1.0, "coincide"),
    ((0, 0, 1.7), (2, 0, 1.7), (-0.3, 0), (0.3, 0), 6.0, "outside"),
    ((0, 0, 1.7), (2, 0, 1.7), (-0.3, 0), (0.3, 0), 0.0, "outside"),
])
def test_degenerate_configurations_are_clear_errors(a, b, p_a, p_b, theta, words):
    with pytest.raises(ToricError, match=words):
        toric_to_pose(a, b, p_a, p_b, theta, 0.0, FOV_X, ASPECT)


def test_a_target_behind_the_camera_has_no_toric_coordinates():
    m = np.eye(4)
    m[3, :3] = (0, 0, 1.7)                       # identity rotation: the camera looks down world -Z
    with pytest.raises(ToricError, match="behind"):
        pose_to_toric(m, (0, 0, 5.0), (1, 0, 5.0), FOV_X, ASPECT)


def test_cinematic_features_give_back_the_framing_and_the_characters_orientations(tmp_path):
    import csv
    import json

    from usdcrowd.cameras.features import cinematic_features, write_features
    from usdcrowd.core.view import look_at

    times = np.arange(1.0, 5.0)
    a, b = np.array([0.0, 0.0, 1.6]), np.array([2.0, 0.0, 1.6])
    heads_a, heads_b = np.tile(a, (4, 1)), np.tile(b, (4, 1))
    # Frames 1-3: toric cameras with known angles; frame 4: a plain camera south of the pair looking north.
    asked = [((-0.4, 0.1), (0.35, 0.0), 1.9, 0.2), ((-0.2, -0.1), (0.5, 0.1), 2.2, 0.35), ((-0.6, 0.0), (0.1, 0.2), 1.5, 0.0)]
    cams = [toric_to_pose(a, b, pa, pb, th, ph, FOV_X, ASPECT) for pa, pb, th, ph in asked]
    cams.append(look_at((1.0, -6.0, 1.6), (1.0, 0.0, 1.6))[0])
    # A faces south (-y), B north (+y): each a quarter turn clockwise from facing the other.
    yaw_a, yaw_b = np.full(4, -np.pi / 2), np.full(4, np.pi / 2)
    f = cinematic_features(times, heads_a, heads_b, yaw_a, yaw_b, heads_a * [1, 1, 0], heads_b * [1, 1, 0],
                           np.array([1.0, 2.0, 1.0, 1.0]), np.array([2.0, 2.0, 2.0, 2.0]), np.array(cams),
                           FOV_X, ASPECT)
    for k, (pa, pb, th, ph) in enumerate(asked):
        np.testing.assert_allclose(np.r_[f.p_a[k], f.p_b[k], f.theta[k], f.phi[k]], np.r_[pa, pb, th, ph], atol=1e-6)
    np.testing.assert_allclose(f.d_ab, 2.0)
    # Relative to the line AB, whatever the camera (the same for all four cameras).
    np.testing.assert_allclose(f.s_a, -np.pi / 2)
    np.testing.assert_allclose(f.s_b, -np.pi / 2)
    np.testing.assert_allclose(np.abs(f.s_ab), np.pi)
    # A faces B (east); B faces north, a quarter turn clockwise from facing A: sB = -pi / 2, sAB = pi / 2.
    from usdcrowd.cameras.features import pair_orientation

    d, sa, sb, sab = pair_orientation(heads_a[:1], heads_b[:1], [0.0], [np.pi / 2])
    assert sa[0] == pytest.approx(0.0) and sb[0] == pytest.approx(-np.pi / 2) and sab[0] == pytest.approx(np.pi / 2)
    d, sa, sb, sab = pair_orientation(heads_a[:1], heads_b[:1], [0.0], [np.pi])      # face to face
    assert sa[0] == pytest.approx(0.0) and sb[0] == pytest.approx(0.0, abs=1e-12)
    assert f.main == 1                                   # B is the larger on screen on average
    written = write_features(f, tmp_path / "f.csv", tmp_path / "f.json", camera="/World/Cameras/Toric")
    rows = list(csv.DictReader(open(written[0])))
    assert len(rows) == 4 and float(rows[1]["theta_deg"]) == pytest.approx(np.degrees(2.2)) and rows[0]["M"] == "B"
    doc = json.loads((tmp_path / "f.json").read_text())
    assert doc["camera"] == "/World/Cameras/Toric" and doc["frames"][2]["pA_x_ndc"] == pytest.approx(-0.6)


def test_heads_and_shoulders_come_from_the_rig():
    from usdcrowd.cameras.features import head_and_facing
    from usdcrowd.character import rig

    rest = rig.BIND_SKEL[None].copy()                   # the canonical 1.75 m character, facing +X
    turn = np.eye(4)
    turn[:2, :2] = [[0.0, 1.0], [-1.0, 0.0]]            # row vectors: +X -> +Y, a quarter turn left
    turned = rest @ turn
    head, yaw = head_and_facing(np.concatenate([rest, turned]))
    assert yaw[0] == pytest.approx(0.0, abs=1e-9) and yaw[1] == pytest.approx(np.pi / 2)
    assert 1.45 < head[0, 2] < 1.75 and np.allclose(head[0, :2], head[1, [1, 0]] * [1, -1], atol=1e-9)


def test_features_of_a_shot_match_the_renderers_projection_and_the_cli_writes_them(museum_path, tmp_path, capsys):
    import csv

    from tests.helpers.frames import straight_walk

    from usdcrowd.cameras.features import head_and_facing
    from usdcrowd.jobs.toric_filming import shot_features
    from usdcrowd.cli import main
    from usdcrowd.jobs.pipeline import author_shot
    from usdcrowd.scenario.shot_scene import ShotScene

    shot = author_shot(museum_path, tmp_path / "shot", lambda sc: [straight_walk(sc.agents, sc.time)],
                       frames=(1, 6), progress=False, events=False).shot
    cam = "/World/Cameras/CrowdCam"
    f, about = shot_features(shot, cam, "Guide", "Teacher", width=1600, height=900)
    assert about["A"].endswith("/Guide") and about["B"].endswith("/Teacher") and len(f.times) == 6
    scene = ShotScene(shot)
    rows = [scene.agent_paths.index(about["A"]), scene.agent_paths.index(about["B"])]
    for k, t in enumerate(f.times):
        head, _ = head_and_facing(scene.agents(t).joints_world[rows])
        uv, _ = scene.camera(cam, t).project(head, 1600, 900)
        ndc = np.stack([uv[:, 0] / 1600 * 2 - 1, 1 - uv[:, 1] / 900 * 2], -1)
        np.testing.assert_allclose([f.p_a[k], f.p_b[k]], ndc, atol=1e-6)
    assert main(["features", shot, "Guide", "Teacher", "-o", str(tmp_path / "f"), "--camera", cam,
                 "--frames", "2:4"]) == 0
    assert [r["time_code"] for r in csv.DictReader(open(tmp_path / "f" / "features.csv"))] == ["2.0", "3.0", "4.0"]
    capsys.readouterr()
    assert main(["features", shot, "clone_0000", "Guide", "-o", str(tmp_path / "g")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "more than one agent named 'clone_0000'" in err


def test_smoothing_keeps_steady_tracks_removes_jitter_and_turns_through_180_degrees(rng):
    from usdcrowd.cameras.smoothing import smooth_track
    from usdcrowd.core.view import look_at

    t = np.arange(400)
    # A camera circling a point at constant speed, turning through +-180 degrees: the average of a steady
    # motion is itself (away from the ends) but for the pull of averaging points on a circle.
    angle = t * (2 * np.pi / len(t)) + np.pi        # its yaw passes +-180 degrees at frame 200
    eye = np.stack([10 * np.cos(angle), 10 * np.sin(angle), np.full(len(t), 3.0)], -1)
    track = look_at(eye, (0.0, 0.0, 1.5))
    smooth = smooth_track(track)
    np.testing.assert_allclose(np.einsum("tij,tkj->tik", smooth[:, :3, :3], smooth[:, :3, :3]),
                               np.broadcast_to(np.eye(3), (len(t), 3, 3)), atol=1e-9)
    mid = slice(40, 360)
    # Averaging points of a circle pulls them in: 3 x 20-frame boxes (sigma 10 frames, 9 degrees) by 1.2 %.
    np.testing.assert_allclose(np.linalg.norm(smooth[mid, 3, :2], axis=1), 10.0, rtol=0.015)
    forward = -smooth[mid, 2, :3]
    want = -track[mid, 2, :3]
    assert np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", forward, want), -1, 1))).max() < 2.0
    # Jitter on a still camera is averaged away: 60 frames of noise shrink by about sqrt(60).
    still = np.repeat(look_at((0.0, -8.0, 2.0), (0.0, 0.0, 1.5)), len(t), axis=0)
    noisy = still.copy()
    noisy[:, 3, :3] += rng.normal(scale=0.05, size=(len(t), 3))
    out = smooth_track(noisy)
    assert np.std(out[mid, 3, :3] - still[mid, 3, :3]) < 0.25 * np.std(noisy[mid, 3, :3] - still[mid, 3, :3])
