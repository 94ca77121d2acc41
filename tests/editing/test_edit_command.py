"""``usdcrowd edit`` as a user runs it on the harbour: the cut, read back by tools that do not know usdcrowd."""

from __future__ import annotations

import csv
import json
import shutil
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from usdcrowd.cli import main

HOLD = (2.0, 8.0)
FPS = 24.0


def _run(*argv) -> int:
    return int(main([str(a) for a in argv]) or 0)


@pytest.fixture(scope="module")
def edited_harbour(simulated_harbour, tmp_path_factory):
    """A copy of the simulated harbour, edited by ``usdcrowd edit`` (no video): (shot folder, cut folder)."""
    base = tmp_path_factory.mktemp("edited_harbour")
    shutil.copytree(simulated_harbour.parent, base / "harbour")
    shot = base / "harbour" / "shot"
    assert _run("edit", shot / "shot.usda", "-o", base / "cut", "--no-video", "--no-progress") == 0
    return shot, base / "cut"


def _onair(cut) -> list[dict]:
    with open(cut / "onair.csv", newline="") as fh:
        return list(csv.DictReader(fh))


def _plain_usd(script: str) -> dict:
    """Run ``script`` in a fresh interpreter with usd-core only (no usdcrowd, no schema plugin)."""
    out = subprocess.run([sys.executable, "-c", textwrap.dedent(script)], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout)


def _cut_as_plain_usd_sees_it(shot) -> dict:
    return _plain_usd(f"""
        import json
        from pxr import Usd, UsdGeom
        stage = Usd.Stage.Open({str(shot / "shot.usda")!r})
        cut = stage.GetPrimAtPath("/World/Cameras/CutCam")
        frames = range(int(stage.GetStartTimeCode()), int(stage.GetEndTimeCode()) + 1)
        out = {{"frames": list(frames), "on_air": [], "event": [], "shot": [], "reason": [], "cut_pose": [],
               "on_air_pose": [], "before_pose": [], "focal": [], "on_air_focal": [], "eye": {{}}}}
        for f in frames:
            cache = UsdGeom.XformCache(f)
            who = cut.GetAttribute("crowd:cut:camera").Get(f)
            out["on_air"].append(who)
            out["event"].append(cut.GetAttribute("crowd:cut:event").Get(f))
            out["shot"].append(cut.GetAttribute("crowd:cut:shot").Get(f))
            out["reason"].append(cut.GetAttribute("crowd:cut:reason").Get(f))
            out["cut_pose"].append([list(r) for r in cache.GetLocalToWorldTransform(cut)])
            cam = stage.GetPrimAtPath(who)
            out["on_air_pose"].append([list(r) for r in cache.GetLocalToWorldTransform(cam)])
            out["focal"].append(UsdGeom.Camera(cut).GetFocalLengthAttr().Get(f))
            out["on_air_focal"].append(UsdGeom.Camera(cam).GetFocalLengthAttr().Get(f))
            # Just before the frame: the camera on air at the frame before (a cut is a cut, even blurred).
            prev = out["on_air"][-2] if len(out["on_air"]) > 1 else who
            t = f - 0.01
            out["before_pose"].append([[list(r) for r in UsdGeom.XformCache(t).GetLocalToWorldTransform(cut)],
                                       [list(r) for r in UsdGeom.XformCache(f).GetLocalToWorldTransform(
                                           stage.GetPrimAtPath(prev))]])
        for prim in stage.Traverse():
            if prim.GetTypeName() == "Camera":
                out["eye"][str(prim.GetPath())] = [list(UsdGeom.XformCache(f).GetLocalToWorldTransform(prim)[3])[:3]
                                                  for f in frames]
        out["events"] = {{}}
        for prim in stage.Traverse():
            if prim.GetTypeName() == "CrowdEvent":
                c = prim.GetAttribute("crowd:center")
                out["events"][str(prim.GetPath())] = {{str(f): list(c.Get(f)) for f in frames}}
        print(json.dumps(out))
    """)


def test_cutcam_plays_the_camera_on_air_at_every_frame_for_a_plain_usd_reader(edited_harbour):
    shot, cut = edited_harbour
    seen = _cut_as_plain_usd_sees_it(shot)
    rows = _onair(cut)
    assert [r["camera"] for r in rows] == seen["on_air"]
    assert [r["event"] for r in rows] == seen["event"]
    assert [int(r["shot"]) for r in rows] == seen["shot"]
    np.testing.assert_allclose(seen["cut_pose"], seen["on_air_pose"], atol=1e-6)
    # The lens too (the harbour's cameras share an aperture: the focal length is the one on air).
    np.testing.assert_allclose(seen["focal"], seen["on_air_focal"], rtol=1e-6)
    # A hundredth of a frame before each frame, the pose is still the outgoing camera's.
    before = np.array([b[0] for b in seen["before_pose"]])[1:]
    outgoing = np.array([b[1] for b in seen["before_pose"]])[1:]
    np.testing.assert_allclose(before[:, 3], outgoing[:, 3], atol=0.05)     # within a hundredth of a frame of motion
    assert len(set(seen["on_air"])) >= 2 and all(r for r in seen["reason"])


def test_every_shot_lasts_2_to_8_seconds_and_no_cut_breaks_the_30_or_180_degree_rule(edited_harbour):
    """Independent of the director: shots from the stage's CutCam, angles from the cameras' and the events'
    positions as plain usd-core composes them."""
    shot, cut = edited_harbour
    seen = _cut_as_plain_usd_sees_it(shot)
    shots = np.array(seen["shot"])
    starts = np.flatnonzero(np.diff(shots)) + 1
    bounds = np.concatenate([[0], starts, [len(shots)]])
    lengths = np.diff(bounds) / FPS
    assert len(lengths) >= 2 and (lengths >= HOLD[0] - 1e-9).all() and (lengths <= HOLD[1] + 1e-9).all(), lengths
    assert (np.diff(shots[bounds[:-1]]) == 1).all()
    for f in starts:
        a, b = seen["on_air"][f - 1], seen["on_air"][f]
        assert a != b
        if seen["event"][f - 1] != seen["event"][f] or not seen["event"][f]:
            continue
        centre = np.array(seen["events"][seen["event"][f]][str(seen["frames"][f])])
        ea, eb = np.array(seen["eye"][a][f - 1]) - centre, np.array(seen["eye"][b][f]) - centre
        angle = np.degrees(np.arccos(np.clip(ea[:2] @ eb[:2] / np.linalg.norm(ea[:2]) / np.linalg.norm(eb[:2]),
                                             -1, 1)))
        row_a, row_b = _onair(cut)[f - 1], _onair(cut)[f]
        sizes = sorted([float(row_a["screen_height"]), float(row_b["screen_height"])])
        assert angle >= 30.0 or (sizes[0] > 0 and sizes[1] / sizes[0] >= 2.0), (f, a, b, angle, sizes)


def test_the_timeline_opens_in_opentimelineio_with_one_clip_per_shot(edited_harbour):
    otio = pytest.importorskip("opentimelineio")
    shot, cut = edited_harbour
    timeline = otio.adapters.read_from_file(str(cut / "cut.otio"))
    clips = list(timeline.find_clips())
    rows = _onair(cut)
    assert len(clips) == len({r["shot"] for r in rows}) >= 2
    assert timeline.duration().rescaled_to(FPS).value == len(rows)
    frame = 0
    for clip in clips:
        rng = clip.source_range
        assert rng.start_time.rate == FPS
        first, n = int(rng.start_time.value), int(rng.duration.value)
        assert first == int(rows[frame]["time_code"])
        on = {r["camera"] for r in rows[frame:frame + n]}
        assert on == {clip.metadata["usdcrowd"]["camera"]}
        assert clip.metadata["usdcrowd"]["event"] == rows[frame]["event"]
        assert (cut / clip.media_reference.target_url).resolve() == (shot / "shot.usda").resolve()
        frame += n
    assert frame == len(rows)


def test_the_rendered_ground_truth_says_which_camera_is_on_air_and_why(edited_harbour, tmp_path):
    shot, cut = edited_harbour
    rows = _onair(cut)
    change = next(i for i in range(1, len(rows)) if rows[i]["camera"] != rows[i - 1]["camera"])
    frames = [int(rows[change - 1]["time_code"]), int(rows[change]["time_code"])]
    out = tmp_path / "render"
    assert _run("render", shot / "shot.usda", "-o", out, "--camera", "/World/Cameras/CutCam", "--frames",
                f"{frames[0]}:{frames[1]}", "--resolution", "160x90", "--spp", "1", "--executor", "inline",
                "--no-progress") == 0
    for f, row in zip(frames, (rows[change - 1], rows[change])):
        record = json.loads((out / "json" / f"frame.{f:04d}.json").read_text())["camera"]
        assert record["cut"]["on_air"] == row["camera"] and record["cut"]["reason"] == row["reason"]
        assert record["cut"]["event"] == row["event"] and record["cut"]["shot"] == int(row["shot"])


def test_the_cut_video_shows_what_the_camera_on_air_shows(simulated_harbour, tmp_path):
    """cut.mp4, decoded by imageio's ffmpeg, against the preview of each frame's camera on air."""
    imageio = pytest.importorskip("imageio.v3")
    pytest.importorskip("moderngl")
    from usdcrowd.render.preview.renderer import PreviewRenderer

    shutil.copytree(simulated_harbour.parent, tmp_path / "harbour")
    shot = tmp_path / "harbour" / "shot" / "shot.usda"
    assert _run("edit", shot, "-o", tmp_path / "cut", "--resolution", "160x96", "--no-progress") == 0
    video = imageio.imread(tmp_path / "cut" / "cut.mp4")
    rows = _onair(tmp_path / "cut")
    assert len(video) == len(rows)
    r = PreviewRenderer(shot, 160, 96)
    try:
        for i in (0, len(rows) // 2, len(rows) - 1):
            own = r.render(float(rows[i]["time_code"]), rows[i]["camera"]).color.astype(float)
            other = next(p for p in {x["camera"] for x in rows} if p != rows[i]["camera"])
            theirs = r.render(float(rows[i]["time_code"]), other).color.astype(float)
            err_own = np.abs(video[i].astype(float) - own).mean()
            assert err_own < 6.0 and err_own < 0.5 * np.abs(video[i].astype(float) - theirs).mean()
    finally:
        r.release()
    assert (tmp_path / "cut" / "cut_sheet.png").stat().st_size > 0


def test_edit_again_replaces_the_cut_and_never_cuts_to_the_cut_camera(edited_harbour, tmp_path):
    shot, _ = edited_harbour
    assert _run("edit", shot / "shot.usda", "-o", tmp_path / "again", "--cameras", "Pier", "ScoutEast",
                "--no-video", "--no-progress") == 0
    rows = _onair(tmp_path / "again")
    assert {r["camera"] for r in rows} <= {"/World/Cameras/Pier", "/World/Cameras/ScoutEast"}
    seen = _cut_as_plain_usd_sees_it(shot)
    assert seen["on_air"] == [r["camera"] for r in rows]


@pytest.mark.parametrize("argv, words", [
    (["--cameras", "Nowhere"], ["--cameras", "Nowhere", "is not a camera of the shot", "shot.usda"]),
    (["--hold", "3", "4"], ["--hold 3 4", "twice the shortest"]),
    (["--hold", "0", "8"], ["--hold", "expected seconds"]),
    (["--weight", "arrival"], ["--weight", "KIND=W"]),
    (["--weight", "arrival=-1"], ["--weight", "a weight"]),
    (["--cut-cost", "nan"], ["--cut-cost"]),
])
def test_careless_edit_options_get_one_line_and_nothing_written(edited_harbour, tmp_path, capsys, argv, words):
    shot, _ = edited_harbour
    before = (shot / "cameras.usda").read_bytes()
    code = _run("edit", shot / "shot.usda", "-o", tmp_path / "cut", "--no-video", "--no-progress", *argv)
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    for w in words:
        assert w in err, (w, err)
    assert (shot / "cameras.usda").read_bytes() == before
    assert not (tmp_path / "cut" / "cut.otio").exists()


def test_edit_through_a_stage_placing_the_shot_in_a_set(simulated_harbour, tmp_path):
    """A layout artist's stage (Y up, centimetres, the shot moved and turned): the cut is the shot's own,
    its timeline names the shot and its cameras, and the set's stage plays CutCam where it places it."""
    from pxr import Usd, UsdGeom

    shutil.copytree(simulated_harbour.parent, tmp_path / "harbour")
    shot = tmp_path / "harbour" / "shot" / "shot.usda"
    (tmp_path / "set.usda").write_text('#usda 1.0\n(\n    defaultPrim = "Set"\n    upAxis = "Y"\n'
                                       '    metersPerUnit = 0.01\n)\ndef Xform "Set"\n{\n}\n')
    placed = tmp_path / "placed.usda"
    assert _run("place", shot, "--into", tmp_path / "set.usda", "-o", placed, "--at", "100", "0", "200",
                "--rotate", "30") == 0
    assert _run("edit", placed, "-o", tmp_path / "cut", "--no-video", "--no-progress") == 0
    rows = _onair(tmp_path / "cut")
    otio = pytest.importorskip("opentimelineio")
    clip = next(iter(otio.adapters.read_from_file(str(tmp_path / "cut" / "cut.otio")).find_clips()))
    assert (tmp_path / "cut" / clip.media_reference.target_url).resolve() == shot.resolve()
    stage = Usd.Stage.Open(str(placed))
    cut = next(p for p in stage.Traverse() if p.GetName() == "CutCam")
    on_air = stage.GetPrimAtPath(str(cut.GetPath()).replace("CutCam", rows[10]["camera"].rsplit("/", 1)[-1]))
    t = float(rows[10]["time_code"])
    np.testing.assert_allclose(np.array(UsdGeom.XformCache(t).GetLocalToWorldTransform(cut)),
                               np.array(UsdGeom.XformCache(t).GetLocalToWorldTransform(on_air)), atol=1e-4)


def test_one_camera_makes_one_shot_held_the_whole_shot_and_says_how_long(edited_harbour, tmp_path, capsys):
    shot, _ = edited_harbour
    assert _run("edit", shot / "shot.usda", "-o", tmp_path / "one", "--cameras", "Pier", "--no-video",
                "--no-progress") == 0
    out = capsys.readouterr().out
    rows = _onair(tmp_path / "one")
    assert out.startswith("wrote ") and "1 shot from 1 of 1 camera over 360 frames" in out
    assert {r["shot"] for r in rows} == {"1"} and f"held {len(rows) / FPS:.1f} s" in rows[0]["reason"]
