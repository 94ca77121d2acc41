"""Learned camera behaviors (seed 002, section 5): numpy inference, PyTorch's equal, retargeting as a user runs it."""

from __future__ import annotations

import subprocess

import numpy as np
import pytest

from usdcrowd.cameras.behaviors import BEHAVIORS
from usdcrowd.cameras.moe import N_CAMERA, N_CHARACTER, WEIGHTS, CameraMoE, camera_features, toric_of_features
from usdcrowd.cameras.moe_data import ASPECT, FOV_X, make_clip
from usdcrowd.cameras.toric import toric_to_poses
from usdcrowd.cli import main
from usdcrowd.jobs.toric_filming import SETTLE_FRAMES

from tests.helpers.paths import TOOLS


def _run(*argv) -> int:
    return int(main([str(a) for a in argv]) or 0)


@pytest.fixture(scope="module")
def moe():
    return CameraMoE()


def test_the_shipped_weights_are_small_and_say_what_they_are(moe):
    c = moe.config
    assert WEIGHTS.stat().st_size < 3e6 and moe.size_bytes < 3e6
    assert moe.w["experts.w1"].shape == (c.experts, c.n_in, c.hidden)
    assert moe.w["experts.w3"].shape == (c.experts, c.hidden, c.out * N_CAMERA)
    assert moe.w["gate.lstm.weight_ih"].shape == (4 * c.gate_hidden, N_CHARACTER + N_CAMERA)
    assert moe.about["train_clips"] > 0 and moe.about["torch"].startswith("2.13.0")


def test_blending_the_weights_equals_blending_each_layers_outputs(moe, rng):
    """The prediction network with blended weights (inference) is the training's per-layer mix of experts."""
    c = moe.config
    w = rng.dirichlet(np.ones(c.experts))
    x = rng.normal(size=(5, c.n_in))
    np.testing.assert_allclose(moe.predict(moe.blend(w), x), moe.predict_experts(np.tile(w, (5, 1)), x), atol=1e-9)


@pytest.mark.slow
def test_numpy_inference_equals_pytorchs(moe, rng, tmp_path):
    """The gating LSTM and the blended prediction network, in numpy and in PyTorch (its own venv), to 1e-5."""
    from tests.helpers.venvs import tool_python

    python = tool_python("torch", ["torch==2.13.0", "numpy", "scikit-learn"], "USDCROWD_TORCH_VENV")
    c = moe.config
    gate_x = rng.normal(size=(3, c.gate_len, N_CHARACTER + N_CAMERA))
    x = rng.normal(size=(4, c.n_in))
    w = rng.dirichlet(np.ones(c.experts), size=4)
    np.savez(tmp_path / "inputs.npz", gate_x=gate_x, x=x, w=w)
    subprocess.run([python, str(TOOLS / "camera_moe_torch.py"), "forward", str(WEIGHTS), str(tmp_path / "inputs.npz"),
                    str(tmp_path / "out.npz")], check=True)
    torch_out = np.load(tmp_path / "out.npz")
    np.testing.assert_allclose(moe.gate_sequence(gate_x), torch_out["gate"], atol=1e-5)
    np.testing.assert_allclose(moe.predict_experts(w, x), torch_out["pred"], atol=1e-5)
    np.testing.assert_allclose(moe.predict(moe.blend(w[0]), x[:1]), torch_out["pred"][:1], atol=1e-5)


def test_toric_features_of_a_prediction_always_make_a_camera(rng):
    """Whatever the network says, the features become a valid toric pose with both heads on screen."""
    t = 200
    cam = np.column_stack([rng.uniform(-2, 2, t), rng.uniform(-2, 2, t), rng.uniform(-2, 2, t),
                           rng.uniform(-0.5, 2.5, t), rng.normal(size=t), rng.normal(size=t)])
    cam[::7, 1] = cam[::7, 0]                      # heads on top of each other
    p_a, p_b, theta, phi = toric_of_features(cam, FOV_X, ASPECT)
    a = np.column_stack([np.zeros(t), np.zeros(t), np.full(t, 1.6)])
    b = a + [1.5, 0.3, 0.05]
    m = toric_to_poses(a, b, p_a, p_b, theta, phi, FOV_X, ASPECT)
    assert np.isfinite(m).all()
    assert (np.abs(p_a) <= 0.95).all() and (np.abs(p_b) <= 0.95).all()


def test_the_gate_carries_the_behavior_a_clip_shows(moe):
    """Rolled out on a clip's own characters, the clip's gate reproduces its camera; an orbit's gate does not."""
    rng = np.random.default_rng(11)
    for b in range(3):                              # the three tracks
        clip = make_clip(rng, b, frames=480, kind="talking" if b else "in-line")
        orbit = make_clip(rng, BEHAVIORS.index("orbit"), frames=480, kind=clip.motion)
        own = moe.rollout(moe.gate(clip.character, clip.camera), clip.character, clip.camera[0])
        other = moe.rollout(moe.gate(orbit.character, orbit.camera), clip.character, clip.camera[0])
        err_own, err_other = np.abs(own - clip.camera).mean(), np.abs(other - clip.camera).mean()
        assert err_own < 0.08 and err_own < 0.5 * err_other, (BEHAVIORS[b], err_own, err_other)


def test_a_learned_orbit_keeps_turning_round_the_pair(moe):
    """An orbit's gate, rolled out on its clip's characters from a blind start (as `frame --like` does), turns
    the camera round them about as far as the orbit does: the median of five clips within 0.67 and 1.5 times,
    each within 0.25 and 4 (the shipped model's single orbits turn 0.3 to 2.4 times as far; an earlier model,
    fed its own absolute predictions, stalled after a second: a tenth)."""
    from usdcrowd.cameras.moe import turned as turn

    rng = np.random.default_rng(11)
    ratios = []
    for kind in ("talking", "side-by-side", "in-line", "circling", "walk-then-talk"):
        clip = make_clip(rng, BEHAVIORS.index("orbit"), frames=480, kind=kind)
        out = moe.rollout(moe.gate(clip.character, clip.camera), clip.character, None, settle=SETTLE_FRAMES)
        assert turn(clip.camera) > 200
        ratios.append(turn(out) / turn(clip.camera))
    assert 0.67 < np.median(ratios) < 1.5 and all(0.25 < r < 4 for r in ratios), ratios


def test_a_tracks_style_carries_onto_a_pair_doing_something_else(moe):
    """Retargeting (section 5) as `usdcrowd frame --like` runs it: a track's gate, read from a reference clip,
    rolled out from a blind start on another pair doing another kind of motion, films them about as the same
    controller with the same parameters would, and far closer than an orbit's gate does. Theta, degrees on
    average over the clips: direct and side tracks within 15, the relative track (anchored on A's shoulders,
    the hardest) within 30. (The model trained without references of other characters and without blind
    samples, started from the reference's framing as the command then did, was 66, 44 and 207 off here.)"""
    from usdcrowd.cameras.moe import camera_angles
    from usdcrowd.cameras.moe_data import MOTIONS, refilm

    rng = np.random.default_rng(5)
    for name, limit in (("direct-track", 15), ("relative-track", 30), ("side-track", 15)):
        b = BEHAVIORS.index(name)
        errs, errs_orbit = [], []
        for k, kind in enumerate(MOTIONS):
            ref = make_clip(rng, b, frames=480, kind=kind)
            target = make_clip(rng, b, frames=480, kind=MOTIONS[(k + 2) % len(MOTIONS)])
            orbit = make_clip(rng, BEHAVIORS.index("orbit"), frames=480, kind=kind)
            truth = refilm(target, ref.params)
            for clip, out in ((ref, errs), (orbit, errs_orbit)):
                cam = moe.rollout(moe.gate(clip.character, clip.camera), target.character, None, settle=SETTLE_FRAMES)
                out.append(np.degrees(np.abs(camera_angles(cam)[0] - camera_angles(truth)[0])).mean())
        assert np.mean(errs) < limit and np.mean(errs) < 0.4 * np.mean(errs_orbit), (name, errs, errs_orbit)


def test_a_roll_out_stays_a_camera_however_it_is_retargeted(moe):
    """Fed its own predictions on characters unlike the reference's, from the reference's framing or blind,
    the camera features stay bounded and valid, one frame per frame of the characters.

    (Test clips 24, 74 and 84 of the evaluation's seed, retargeted onto another kind of motion; unbounded,
    an earlier model's reached 6,000 standard deviations there.)
    """
    from usdcrowd.cameras.moe_data import make_clips

    test = make_clips(1000, 25)
    for k in (84, 74, 24):
        ref = test[k]
        other = next(c for c in test[k + 1:] + test[:k] if c.motion != ref.motion)
        for start, settle in ((ref.camera[0], 0), (None, SETTLE_FRAMES)):
            out = moe.rollout(moe.gate(ref.character, ref.camera), other.character, start, settle=settle)
            assert out.shape == (len(other.character), N_CAMERA) and np.isfinite(out).all()
            lo = moe.w["cam_mean"] - 4.0 * moe.w["cam_std"] - 1e-6
            hi = moe.w["cam_mean"] + 4.0 * moe.w["cam_std"] + 1e-6
            assert ((out[:, :3] >= lo[:3]) & (out[:, :3] <= hi[:3])).all()
            np.testing.assert_allclose(np.linalg.norm(out[:, 3:6], axis=1), 1.0, atol=1e-9)


def test_frame_like_films_a_new_pair_like_a_reference_camera(tmp_path, capsys):
    """`usdcrowd frame --like`: the reference is a stage with a toric camera; the learned camera is added."""
    import shutil

    from usdcrowd.scenario.shot_scene import ShotScene
    from usdcrowd.core.resources import data_dir

    shutil.copy(data_dir("stages") / "dialogue.usda", tmp_path / "dialogue.usda")
    shot = tmp_path / "shot"
    assert _run("simulate", tmp_path / "dialogue.usda", "-o", shot, "--frames", "1:240", "--no-progress") == 0
    assert _run("frame", shot / "shot.usda", "--behavior", "side-track", "--targets", "C", "D", "--shot", "medium",
                "--name", "Reference", "--no-progress") == 0
    assert _run("frame", shot / "shot.usda", "--like", shot / "shot.usda", "--camera", "/World/Cameras/Reference",
                "--targets", "A", "B", "--name", "Learned", "--no-progress") == 0
    out = capsys.readouterr().out
    assert "Learned" in out and "experts" in out
    # It films A and B as the reference's side track would: theta near the controller's, read with plain
    # usd-core (started from the reference's own framing, as the command did before blind starts: 174 off).
    assert _run("frame", shot / "shot.usda", "--behavior", "side-track", "--targets", "A", "B", "--shot", "medium",
                "--name", "Controller", "--no-progress") == 0
    from pxr import Usd

    stage = Usd.Stage.Open(str(shot / "shot.usda"))
    theta = [stage.GetPrimAtPath(f"/World/Cameras/{name}").GetAttribute("crowd:toric:theta") for name in
             ("Learned", "Controller")]
    diff = [abs(theta[0].Get(t) - theta[1].Get(t)) for t in range(1, 241, 4)]
    assert np.mean(diff) < 30, np.mean(diff)
    # Level, as the controllers are (seed 002's cameras do not roll): the camera's right axis stays
    # horizontal in every frame, read from the composed transform.
    from pxr import UsdGeom

    up = np.eye(3)[{"Y": 1, "Z": 2}[UsdGeom.GetStageUpAxis(stage)]]
    xform = UsdGeom.Xformable(stage.GetPrimAtPath("/World/Cameras/Learned"))
    right = np.array([np.array(xform.ComputeLocalToWorldTransform(t))[0, :3] for t in range(1, 241)])
    roll = np.degrees(np.arcsin(np.abs(right @ up) / np.linalg.norm(right, axis=1)))
    assert roll.max() < 2.0, roll.max()
    del stage
    scene = ShotScene(shot / "shot.usda")
    rows = [scene.agent_row("A"), scene.agent_row("B")]
    seen = 0
    for t in range(1, 241, 8):
        view = scene.camera("/World/Cameras/Learned", t)
        assert view.toric["behavior"] == "learned" and view.toric["shot_size"] == "medium"
        uv, z = view.project(scene.agents(t, rows).keypoints()[:, 3], 1920, 1080)
        seen += bool((z > 0).all() and ((uv >= 0) & (uv < [1920, 1080])).all())
    assert seen >= 27, seen                         # both heads in frame in at least 90 % of the frames checked
    prim = scene.stage.GetPrimAtPath("/World/Cameras/Learned")
    weights = np.array(prim.GetAttribute("crowd:toric:expertWeights").Get())
    assert weights.sum() == pytest.approx(1.0, abs=1e-5) and len(weights) == CameraMoE().config.experts
    # Not a toric reference and no characters named: one line.
    assert _run("frame", shot / "shot.usda", "--like", shot / "shot.usda", "--camera", "/World/Cameras/CrowdCam",
                "--targets", "A", "B", "--no-progress") == 2
    assert "--like-targets" in capsys.readouterr().err


def test_camera_features_round_trip_through_toric_space(rng):
    a, b = np.array([[0.0, 0.0, 1.6]]), np.array([[2.0, 0.5, 1.65]])
    p_a, p_b = np.array([[-0.3, 0.4]]), np.array([[0.35, 0.4]])
    cam = camera_features(p_a, p_b, [2.0], [2.9])
    back = toric_of_features(cam, FOV_X, ASPECT)
    np.testing.assert_allclose(back[0], p_a)
    np.testing.assert_allclose(back[1], p_b)
    assert back[2][0] == pytest.approx(2.0) and back[3][0] == pytest.approx(2.9)
    assert np.isfinite(toric_to_poses(a, b, *back, FOV_X, ASPECT)).all()
