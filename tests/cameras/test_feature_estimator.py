"""The cinematic feature estimator (seed 002, section 4): a filmed pair's features from 2D poses."""

from __future__ import annotations

import subprocess

import numpy as np
import pytest

from usdcrowd.cameras import clip_poses
from usdcrowd.cameras.estimator import BODY, HEAD, WEIGHTS, FeatureEstimator, body_points, frame_inputs, project, windows
from usdcrowd.cameras.moe import CameraMoE, camera_angles
from usdcrowd.cameras import moe_data
from usdcrowd.cameras.moe_data import ASPECT, FOV_X, refilm_track

from tests.helpers.paths import TOOLS
from tests.helpers.tools import load_tool

_TRAINING = load_tool("train_feature_estimator")
clip_joints, component_errors = _TRAINING.clip_joints, _TRAINING.component_errors


@pytest.fixture(scope="module")
def estimator():
    return FeatureEstimator()


@pytest.fixture(scope="module")
def held_out_clips():
    """Two clips of each behavior from the camera model's held-out seed (never trained on)."""
    return moe_data.held_out_clips(2)


def test_the_projected_head_joint_is_where_the_controller_framed_the_head(held_out_clips):
    """body_points and project against the controller's own toric framing (pA, pB), computed apart."""
    clip = held_out_clips[3]
    track = refilm_track(clip, clip.params)
    body = BODY.copy()
    body[0, 2] = HEAD                                   # the rig's head point, which the controller frames
    for heads, yaw, p in ((clip.heads_a, clip.yaw_a, track.p_a), (clip.heads_b, clip.yaw_b, track.p_b)):
        joints = project(track.cam_to_world, body_points(heads, yaw, body=body), FOV_X, ASPECT)
        np.testing.assert_allclose(joints[:, 0], p, atol=1e-6)
        # Facing the camera, a character's left shoulder is on the screen's right.
        eye = track.cam_to_world[:, 3, :2]
        facing = np.stack([np.cos(yaw), np.sin(yaw)], -1)
        toward = np.einsum("ti,ti->t", facing, eye - heads[:, :2]) > 0.3 * np.linalg.norm(eye - heads[:, :2], axis=1)
        if toward.any():
            assert (joints[toward, 2, 0] > joints[toward, 3, 0]).all()


def test_the_estimated_features_match_held_out_truth(estimator, held_out_clips, rng):
    """Per component, on clips never trained on, with a detector's noise on the joints: the paper's Fig. 7
    reports theta within 8 degrees at worst and phi within 2.3."""
    char_mean = CameraMoE().w["char_mean"]
    errs = {}
    for clip in held_out_clips:
        char, cam = estimator.features(clip_joints(clip, rng), char_mean)
        for k, v in component_errors(char, cam, clip.character, clip.camera).items():
            errs.setdefault(k, []).append(v)
    med = {k: float(np.median(np.concatenate(v))) for k, v in errs.items()}
    assert med["theta_deg"] < 5.0 and med["phi_deg"] < 2.0, med
    assert abs(np.log(med["span_ratio"])) < 0.06 and abs(np.log(med["d_ab_ratio"])) < 0.08, med
    assert med["s_a_deg"] < 6.0 and med["s_b_deg"] < 6.0 and med["s_ab_deg"] < 6.0, med


def test_the_screen_positions_are_read_off_the_joints_and_the_unknown_motion_is_the_mean(estimator, held_out_clips,
                                                                                          rng):
    clip = held_out_clips[0]
    joints = clip_joints(clip, rng, screen_noise=0.0)
    char_mean = CameraMoE().w["char_mean"]
    char, cam = estimator.features(joints, char_mean)
    np.testing.assert_allclose(cam[:, 0:4], joints[:, :, 0].reshape(len(joints), 4))
    np.testing.assert_allclose(cam[:, 0:4], clip.camera[:, 0:4], atol=0.03)     # the ears' midpoint, not the rig's
    np.testing.assert_allclose(char[:, 7:10], np.tile(char_mean[7:10], (len(char), 1)))
    np.testing.assert_allclose(np.linalg.norm(cam[:, 4:7], axis=1), 1.0)


def test_a_shift_on_screen_leaves_the_estimate_as_it_is(estimator, held_out_clips, rng):
    """Centred inputs: moving both characters across the frame (a pan) does not move theta or phi."""
    clip = held_out_clips[5]
    joints = clip_joints(clip, rng, screen_noise=0.0)
    a = estimator.estimate(joints)
    b = estimator.estimate(joints + np.array([0.2, -0.1]))
    np.testing.assert_allclose(a, b, atol=1e-9)


@pytest.mark.slow
def test_numpy_inference_equals_pytorchs(estimator, rng, tmp_path):
    """Batch norm folded into the convolutions, in numpy, against PyTorch's modules (its own venv)."""
    from tests.helpers.venvs import torch_python

    python = torch_python()
    x = rng.normal(size=(6, 32, 8))
    np.savez(tmp_path / "inputs.npz", x=x)
    subprocess.run([python, str(TOOLS / "feature_estimator_torch.py"), "forward", str(WEIGHTS),
                    str(tmp_path / "inputs.npz"), str(tmp_path / "out.npz")], check=True)
    mine = estimator.forward(x / estimator.w["in_std"][None, :, None]) * estimator.w["out_std"] + estimator.w["out_mean"]
    np.testing.assert_allclose(mine, np.load(tmp_path / "out.npz")["y"], atol=1e-4)


def test_windows_hold_the_ends_and_inputs_are_centred_on_the_heads():
    joints = np.arange(10 * 32, dtype=float).reshape(10, 2, 8, 2)
    x = frame_inputs(joints)
    centre = 0.5 * (joints[:, 0, 0] + joints[:, 1, 0])
    np.testing.assert_allclose(x[:, :2], joints[:, 0, 0] - centre)
    w = windows(x)
    assert w.shape == (10, 32, 8)
    np.testing.assert_allclose(w[0, :, 0], x[0])        # frame 0 - 4, held
    np.testing.assert_allclose(w[0, :, 4], x[0])
    np.testing.assert_allclose(w[9, :, 7], x[9])        # frame 9 + 3, held
    np.testing.assert_allclose(w[5, :, 7], x[8])


def _person(x: float, y: float = 300.0) -> np.ndarray:
    return np.array([[x, y - 100], [x, y], [x + 20, y], [x - 20, y], [x, y + 150], [x + 10, y + 150], [x - 10, y + 150],
                     [x + 5, y - 100]])


def test_association_keeps_each_character_when_the_detector_swaps_or_misses_them():
    """A is the left one in the first frame with two people; the detector's order does not matter; a frame
    where one is missing is filled between its neighbours."""
    frames = []
    for k in range(6):
        a, b = _person(100 + 10 * k), _person(600 - 10 * k)
        frames.append([b, a] if k % 2 else [a, b])
    frames[3] = [frames[3][1]]                                # only A found
    frames.insert(0, [])                                      # nobody in the first frame
    joints, found = clip_poses.associate(frames)
    assert not found[0].any() and found[4].tolist() == [True, False]
    filled = clip_poses.fill(joints, found)
    np.testing.assert_allclose(filled[1:, 0, 0, 0], 100 + 10 * np.arange(6))
    np.testing.assert_allclose(filled[1:, 1, 0, 0], 600 - 10 * np.arange(6))
    np.testing.assert_allclose(filled[0], filled[1])          # the start, held


def test_what_each_wears_keeps_them_apart_where_one_comes_to_where_the_other_was():
    """A camera craning over a pair: B is lost while A walks across the screen to where B was last seen; B
    comes back on the other side, alone first, then both are found. The joints alone give the returning B
    to A and swap them; the torso colours (read off the frames) keep each its own."""
    frames = [[_person(300), _person(600)]]
    frames += [[_person(300 + 15 * k)] for k in range(1, 21)]       # A alone, from 300 to 600
    frames += [[_person(440)], [_person(430), _person(605)], [_person(420), _person(610)]]
    red, blue = np.array([200, 30, 30], np.uint8), np.array([30, 30, 200], np.uint8)
    wear = [[red, blue]] + [[red]] * 20 + [[blue], [blue, red], [blue, red]]      # A in red, B in blue
    images = []
    for people, worn in zip(frames, wear):
        image = np.full((500, 800, 3), 128, np.uint8)
        for p, c in zip(people, worn):
            x = int(p[1, 0])
            image[300:450, x - 25:x + 26] = c                        # the torso, from the neck to the hips
        images.append(image)
    colours = clip_poses.torso_colours(images, frames)
    assert np.allclose(colours[0][0], red / 255) and np.allclose(colours[0][1], blue / 255)
    joints, found = clip_poses.associate(frames, colours)
    assert found[21].tolist() == [False, True]                     # the returning one is B
    np.testing.assert_allclose(joints[22:, 0, 0, 0], [605, 610])
    np.testing.assert_allclose(joints[21:, 1, 0, 0], [440, 430, 420])
    joints, found = clip_poses.associate(frames)                   # by the joints alone: B taken for A
    assert found[21].tolist() == [True, False]


def test_the_main_character_is_the_larger_on_screen_where_both_are_found():
    """Appendix B's M: the larger box around the joints, on average over the frames showing both."""
    small, large = _person(100.0), _person(600.0)
    large = 600 + 1.5 * (large - 600)
    joints = np.stack([np.stack([small, large])] * 4)
    found = np.ones((4, 2), bool)
    assert clip_poses.main_character(joints, found) == 1
    assert clip_poses.main_character(joints[:, ::-1], found) == 0
    joints[0, 0] *= 10                                          # a frame where B was not found does not count
    found[0, 1] = False
    assert clip_poses.main_character(joints, found) == 1


def test_a_person_found_off_the_frame_is_neither_kept_nor_painted_out():
    """A close-up's detector may place a whole person outside the picture: no box (and no crash); a person
    partly in it is painted out within the frame."""
    assert clip_poses.paint_box(np.array([[-500.0, 100.0], [-300.0, 50.0]]), 640, 360) is None
    assert clip_poses.paint_box(np.array([[100.0, 900.0], [200.0, 1200.0]]), 640, 360) is None
    x0, y0, x1, y1 = clip_poses.paint_box(np.array([[100.0, 100.0], [200.0, 300.0], [-400.0, 100.0]]), 640, 360)
    assert (x0, y0, x1, y1) == (85, 70, 215, 330)


def test_a_crop_round_a_person_last_found_holds_them_whole_and_stays_in_the_frame():
    """The second look for a small person (a long shot): a square twice the larger side of their joints' box,
    centred on it, shifted into the frame at its edges, never under the smallest crop."""
    person = np.array([[100, 50], [100, 70], [90, 70], [110, 70], [100, 120], [95, 120], [105, 120], [102, 50.0]])
    x0, y0, x1, y1 = clip_poses.crop_box(person, 960, 540)
    assert x1 - x0 == y1 - y0 == 2 * 70                       # the box is 20 x 70 pixels
    assert x0 <= person[:, 0].min() and x1 >= person[:, 0].max() and y0 <= person[:, 1].min() and y1 >= 120
    assert (x0 + x1) / 2 == pytest.approx(100, abs=1) and (y0 + y1) / 2 == pytest.approx(85, abs=1)
    x0, y0, x1, y1 = clip_poses.crop_box(person + [900, 0], 960, 540)      # at the right edge: shifted in
    assert x1 == 960 and x1 - x0 == 140 and y1 - y0 == 140
    tiny = person * 0.1 + 300                                   # 2 x 7 pixels, far off
    x0, y0, x1, y1 = clip_poses.crop_box(tiny, 960, 540)
    assert x1 - x0 == y1 - y0 == clip_poses._CROP_MIN


def test_pixels_become_the_ndc_of_usdcrowds_camera(held_out_clips):
    """A frame filmed with usdcrowd's 50 mm lens at 1920 x 1080: pixels back to the projection's NDC; a
    35 mm lens sees the same pixel further out."""
    clip = held_out_clips[1]
    track = refilm_track(clip, clip.params)
    ndc = project(track.cam_to_world, body_points(clip.heads_a, clip.yaw_a), FOV_X, ASPECT)
    pixels = np.stack([(ndc[..., 0] + 1) * 960, (1 - ndc[..., 1]) * 540], -1)
    np.testing.assert_allclose(clip_poses.to_ndc(pixels, 1920, 1080, 50.0, FOV_X, ASPECT), ndc, atol=1e-9)
    wide = clip_poses.to_ndc(pixels, 1920, 1080, 35.0, FOV_X, ASPECT)
    np.testing.assert_allclose(wide, ndc * 50.0 / 35.0, atol=1e-9)


def test_the_camera_direction_of_estimates_is_a_toric_angle_pair(estimator, held_out_clips, rng):
    clip = held_out_clips[2]
    _, cam = estimator.features(clip_joints(clip, rng), CameraMoE().w["char_mean"])
    theta, phi = camera_angles(cam)
    assert np.all((theta > 0) & (theta < 2 * np.pi)) and np.all(np.abs(phi) < np.pi)


@pytest.mark.slow
def test_the_recorded_estimator_figures_are_what_the_shipped_weights_give():
    """docs/data/feature_estimator.json (tools/train_feature_estimator.py --record) recomputed from the shipped
    weights on the same held-out clips."""
    import json

    from tests.helpers.paths import ROOT

    recorded = json.loads((ROOT / "docs" / "data" / "feature_estimator.json").read_text())["figures"]
    fresh = _TRAINING.evaluate(WEIGHTS, moe_data.held_out_clips(50), 0)
    for k, v in recorded["components"].items():
        assert fresh["components"][k]["median"] == pytest.approx(v["median"], rel=1e-6), k
