"""A film clip as the reference of `frame --like` (seed 002, section 4), run as a user runs it.

The pose detector is the ``video`` extra (MediaPipe), which pins protobuf < 5
and so lives in its own venv with usdcrowd: these tests run usdcrowd there.
The clips are usdcrowd's own toric shots drawn by the GL preview, where the
true features are known (the stage the clip was drawn from), and a photo
the project did not make (two people, from the ``ultralytics`` wheel).
"""

from __future__ import annotations

import json
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

from usdcrowd.cameras.moe import CLIP_WEIGHTS, PAIR_MOTION, CameraMoE, camera_angles
from usdcrowd.core.resources import data_dir

from tests.helpers.paths import ROOT
from tests.helpers.tools import load_tool
from tests.helpers.venvs import tool_python

pytestmark = pytest.mark.slow

FRAMES = 240
CLIPS = {"direct": "direct-track", "orbit": "orbit"}
# Print a clip reference's features as usdcrowd reads them (run in the video venv).
FEATURES = """
import json, sys
from usdcrowd.jobs.toric_filming import read_clip_reference
out = {}
for path in sys.argv[1:]:
    r = read_clip_reference(path)
    out[path] = {"character": r.character.tolist(), "camera": r.camera_features.tolist(), "size": r.shot_size}
print(json.dumps(out))
"""


def _usdcrowd(*args, python=sys.executable) -> subprocess.CompletedProcess:
    return subprocess.run([python, "-m", "usdcrowd", *map(str, args)], capture_output=True, text=True)


@pytest.fixture(scope="module")
def video_python():
    return tool_python("video", ["-e", f"{ROOT}[video]"], "USDCROWD_VIDEO_VENV")


@pytest.fixture(scope="module")
def filmed_dialogue(tmp_path_factory):
    """The dialogue example with a medium direct track and a medium orbit on A and B, each drawn to an
    MP4 (960 x 540) by the GL preview: (shot, {name: mp4})."""
    tmp = tmp_path_factory.mktemp("clip_reference")
    (tmp / "dialogue.usda").write_bytes((data_dir("stages") / "dialogue.usda").read_bytes())
    assert _usdcrowd("simulate", tmp / "dialogue.usda", "-o", tmp / "shot", "--frames", f"1:{FRAMES}",
                     "--no-progress").returncode == 0
    shot = tmp / "shot" / "shot.usda"
    clips = {}
    for name, behavior in CLIPS.items():
        r = _usdcrowd("frame", shot, "--behavior", behavior, "--targets", "A", "B", "--shot", "medium", "--name",
                      f"Ref_{name}", "--no-progress")
        assert r.returncode == 0, r.stderr
        r = _usdcrowd("preview", shot, "--camera", f"/World/Cameras/Ref_{name}", "--resolution", "960x540",
                      "-o", tmp / f"{name}.mp4", "--no-progress")
        assert r.returncode == 0, r.stderr
        clips[name] = tmp / f"{name}.mp4"
    return shot, clips


@pytest.fixture(scope="module")
def clip_features(video_python, filmed_dialogue):
    """Each clip's features as `frame --like clip.mp4` reads them."""
    _, clips = filmed_dialogue
    r = subprocess.run([video_python, "-c", FEATURES, *map(str, clips.values())], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-2000:]
    out = json.loads(r.stdout.strip().splitlines()[-1])
    return {name: {k: np.array(v) if k != "size" else v for k, v in out[str(path)].items()}
            for name, path in clips.items()}


def _truth(shot, name, clip_camera):
    """The stage's features of the camera the clip was drawn from, its A the one the clip calls A (the
    benchmark's matching: the character whose head is where the clip's A's is)."""
    return load_tool("bench_clip_reference").truth_of(shot, f"Ref_{name}", clip_camera)


def test_frame_like_a_video_films_the_pair_and_records_the_clip(video_python, filmed_dialogue, clip_features):
    shot, clips = filmed_dialogue
    r = _usdcrowd("frame", shot, "--like", clips["orbit"], "--targets", "C", "D", "--name", "FromClip",
                  "--no-progress", python=video_python)
    assert r.returncode == 0, r.stderr[-2000:]
    assert "experts" in r.stdout and "orbit.mp4" in r.stdout
    assert "W0000" not in r.stderr and "Traceback" not in r.stderr     # MediaPipe's C++ logging is kept quiet
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(str(shot))
    prim = stage.GetPrimAtPath("/World/Cameras/FromClip")
    assert prim.IsValid() and prim.IsA(UsdGeom.Camera)
    assert Path(prim.GetAttribute("crowd:toric:reference").Get().path).name == "orbit.mp4"
    # Read by the model for film clips (one whose experts read no style a picture cannot give).
    clip_model = CameraMoE(CLIP_WEIGHTS)
    est = clip_features["orbit"]
    np.testing.assert_allclose(prim.GetAttribute("crowd:toric:expertWeights").Get(),
                               clip_model.gate(est["character"], est["camera"]), atol=1e-4)
    assert not clip_model.config.expert_style and not prim.GetAttribute("crowd:toric:referenceStyle").HasValue()
    xform = UsdGeom.Xformable(prim)
    eyes = np.array([np.array(xform.ComputeLocalToWorldTransform(t))[3, :3] for t in range(1, FRAMES + 1)])
    assert np.isfinite(eyes).all() and np.linalg.norm(np.diff(eyes, axis=0), axis=1).max() < 0.5


SMALL = """
import json, sys
import numpy as np
from usdcrowd.cameras import clip_poses
frames, _ = clip_poses.read_frames(sys.argv[1])
det = clip_poses._Detector()
out = []
for image in frames[::12]:
    h, w = image.shape[:2]
    native = det.people(image)
    # The same picture in the middle of a frame three times as wide and high: a long shot's small people.
    wide = np.full((3 * h, 3 * w, 3), image.reshape(-1, 3).mean(axis=0), np.uint8)
    wide[h:2 * h, w:2 * w] = image
    alone = det.people(wide)
    helped = det.people(wide, last=[p + [w, h] for p in native])
    out.append({"native": [(p + [w, h]).tolist() for p in native], "alone": len(alone),
                "helped": [p.tolist() for p in helped]})
print(json.dumps(out))
"""


def test_people_too_small_for_the_whole_frame_are_found_again_where_they_were(video_python, filmed_dialogue):
    """A long shot's people are small for the detector's view of the whole frame: it is shown the medium
    orbit's frames in the middle of a frame three times as large, and looks again in a crop around where
    each person was (as ``detect`` does with the people of the frame before). Measured: of 13 sampled frames
    showing both, both found in none of the large frames, in 10 with the crops (profile views are harder:
    the direct track's far character is not found in a crop at any size tried)."""
    _, clips = filmed_dialogue
    r = subprocess.run([video_python, "-c", SMALL, str(clips["orbit"])], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-2000:]
    frames = json.loads(r.stdout.strip().splitlines()[-1])
    both = [f for f in frames if len(f["native"]) == 2]
    assert len(both) >= 10
    alone, helped = sum(f["alone"] == 2 for f in both), sum(len(f["helped"]) == 2 for f in both)
    assert alone <= 0.2 * len(both) and helped >= 0.5 * len(both), (alone, helped, len(both))
    for f in both:
        for person in f["helped"]:                 # each found where one was: the head within a tenth of its size
            assert min(np.linalg.norm(np.subtract(person[0], p[0])) / np.ptp(np.array(p), axis=0).max()
                       for p in f["native"]) < 0.1


def test_the_clips_features_match_the_stage_it_was_drawn_from(filmed_dialogue, clip_features):
    """Per component, the medians over the clip's frames against the stage's truth."""
    shot, _ = filmed_dialogue
    for name in CLIPS:
        est = clip_features[name]
        truth = _truth(shot, name, est["camera"])
        n = min(len(est["camera"]), len(truth.camera_features))
        cam, t_cam = est["camera"][:n], truth.camera_features[:n]
        char, t_char = est["character"][:n], truth.character[:n]
        screen = np.median(np.linalg.norm(cam[:, :4] - t_cam[:, :4], axis=1))
        (theta, phi), (t_theta, t_phi) = camera_angles(cam), camera_angles(t_cam)
        span = np.exp(np.median(np.abs(cam[:, 7] - t_cam[:, 7])))
        d_ab = np.exp(np.median(np.abs(np.log(char[:, 0] / t_char[:, 0]))))
        wrap = lambda a: np.degrees(np.abs((a + np.pi) % (2 * np.pi) - np.pi))  # noqa: E731
        # Measured (tools/bench_clip_reference.py): heads 0.03-0.05 NDC, span and dAB within 1.15x, phi within
        # 4 degrees; theta 12-19 degrees off (25 before the characters had eyes and a mouth: BlazePose took
        # those facing the camera for seen from behind, and swapped their left and right).
        assert screen < 0.08, (name, screen)
        assert span < 1.15 and d_ab < 1.35, (name, span, d_ab)
        assert np.median(wrap(phi - t_phi)) < 5.0, name
        assert np.median(wrap(theta - t_theta)) < 23.0, name
        assert est["size"] == "medium", name


def test_the_gate_reads_each_clip_nearer_its_own_stage_than_the_other(filmed_dialogue, clip_features):
    """The expert weights from the clip against those from the stage the clip was drawn from (the
    pair's motion, which a picture cannot show, set as unknown in both)."""
    shot, _ = filmed_dialogue
    model = CameraMoE(CLIP_WEIGHTS)
    gates = {}
    for name in CLIPS:
        truth = _truth(shot, name, clip_features[name]["camera"])
        char = truth.character.copy()
        char[:, PAIR_MOTION] = model.w["char_mean"][PAIR_MOTION]
        gates[name] = (model.gate(clip_features[name]["character"], clip_features[name]["camera"]),
                       model.gate(char, truth.camera_features))
    for name, other in (("direct", "orbit"), ("orbit", "direct")):
        own = np.abs(gates[name][0] - gates[name][1]).sum()
        assert own < np.abs(gates[name][0] - gates[other][1]).sum(), (name, gates)


def _third_party_photo(tmp: Path) -> Path:
    """A photo of two people the project did not make: ultralytics' zidane.jpg (1280 x 720), from its wheel."""
    r = subprocess.run([sys.executable, "-m", "pip", "download", "ultralytics==8.4.190", "--no-deps", "-q", "-d",
                        str(tmp)], capture_output=True, text=True)
    wheels = list(tmp.glob("ultralytics-*.whl"))
    if r.returncode != 0 or not wheels:
        pytest.skip("could not download the ultralytics wheel (no package index?) for its photo")
    with zipfile.ZipFile(wheels[0]) as z:
        data = z.read("ultralytics/assets/zidane.jpg")
    folder = tmp / "frames"
    folder.mkdir()
    for k in range(12):                       # a still: the same picture as a folder of frames
        (folder / f"frame.{k:04d}.jpg").write_bytes(data)
    return folder


def test_a_photo_the_project_did_not_make_reads_as_the_two_shot_it_is(video_python, tmp_path):
    """Zidane (left) and Ancelotti: found in every frame, heads where a person marks them, and the frame's
    span at Zidane about what his body shows (head top to waist, 0.7 m, over 520 of the 720 rows: 0.97 m)."""
    folder = _third_party_photo(tmp_path)
    r = subprocess.run([video_python, "-c", FEATURES, str(folder)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-2000:]
    out = json.loads(r.stdout.strip().splitlines()[-1])[str(folder)]
    cam = np.array(out["camera"])
    # The heads' ears' midpoints (the estimator's head joint), marked by hand on the photo: pixels (572, 325) and
    # (975, 165) of 1280 x 720, in NDC.
    marked = np.array([[572 / 640 - 1, 1 - 325 / 360], [975 / 640 - 1, 1 - 165 / 360]])
    np.testing.assert_allclose(cam[0, 0:2], marked[0], atol=0.08)
    np.testing.assert_allclose(cam[0, 2:4], marked[1], atol=0.08)
    span = float(np.exp(np.median(cam[:, 7])))
    assert 0.97 / 1.25 < span < 0.97 * 1.25, span


def test_an_orbit_read_from_its_clip_turns_a_new_pair_as_the_stage_does(filmed_dialogue, clip_features):
    """What a user gets: the orbit's style read from the clip and read from the stage, each rolled out on C
    and D as `frame --like` does; the two cameras turn round the pair the same way and as far (within 30 %)."""
    from usdcrowd.cameras.features import head_and_facing
    from usdcrowd.cameras.moe import character_features
    from usdcrowd.cameras.moe_data import ASPECT, FOV_X
    from usdcrowd.cameras.retarget import compare, retarget_poses
    from usdcrowd.scenario.shot_scene import ShotScene

    shot, _ = filmed_dialogue
    model = CameraMoE(CLIP_WEIGHTS)
    scene = ShotScene(shot)
    rows = [scene.agent_row("C"), scene.agent_row("D")]
    heads, yaws = map(np.array, zip(*(head_and_facing(scene.agents(t, rows).joints_world)
                                      for t in range(1, FRAMES + 1))))
    char = character_features(heads[:, 0], heads[:, 1], yaws[:, 0], yaws[:, 1], scene.fps)
    est = clip_features["orbit"]
    truth = _truth(shot, "orbit", est["camera"])
    stage_char = truth.character.copy()
    stage_char[:, PAIR_MOTION] = model.w["char_mean"][PAIR_MOTION]
    poses = [retarget_poses(model, model.gate(c, m), char, heads[:, 0], heads[:, 1], FOV_X, ASPECT)[0]
             for c, m in ((est["character"], est["camera"]), (stage_char, truth.camera_features))]
    d = compare(poses[0], poses[1], heads[:, 0], heads[:, 1], FOV_X, ASPECT)
    assert np.sign(d["turn_deg"]) == np.sign(d["truth_turn_deg"]) and abs(d["truth_turn_deg"]) > 45, d["turn_deg"]
    assert 0.7 < d["turn_deg"] / d["truth_turn_deg"] < 1.3, (d["turn_deg"], d["truth_turn_deg"])
