"""Ground truth read back with the field's own tools: pycocotools and motmetrics."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("mitsuba")
pytest.importorskip("OpenEXR")
pytest.importorskip("pycocotools")

from usdcrowd.groundtruth import frame_json, rle  # noqa: E402
from usdcrowd.groundtruth.annotate import AgentMetadata, annotate_frame  # noqa: E402
from usdcrowd.groundtruth.mot import read_mot  # noqa: E402
from usdcrowd.render.final.exr import read_frame_exr  # noqa: E402
from usdcrowd.scenario.shot_scene import SCENERY_ID_BASE
from usdcrowd.render.sequence import frame_files, render_sequence  # noqa: E402
from usdcrowd.render.settings import settings_from_preset  # noqa: E402

FRAMES = np.array([1.0, 3.0, 5.0])


@pytest.fixture(scope="module")
def sequence(walking_museum, tmp_path_factory):
    """Three frames through the crowd-following camera, ground truth on."""
    out = tmp_path_factory.mktemp("gt")
    settings = settings_from_preset("groundtruth", resolution=(160, 90), spp=4)
    return render_sequence(walking_museum, out, camera="/World/Cameras/CrowdCam", frames=FRAMES, settings=settings,
                           executor="inline", progress=False)


def _frame(sequence, t):
    out = Path(sequence.out_dir)
    _, ch = read_frame_exr(out / frame_files(t, True)["exr"])
    return ch, frame_json.read(out / frame_files(t, True)["json"])


def test_counts_agree_between_exr_json_mot_and_coco(sequence):
    from pycocotools.coco import COCO

    out = Path(sequence.out_dir)
    coco = COCO(str(out / "coco.json"))
    mot = read_mot(out / "mot" / "gt" / "gt.txt")
    for index, t in enumerate(FRAMES, start=1):
        ch, rec = _frame(sequence, t)
        ids = ch["id"]
        in_exr = {int(i) for i in np.unique(ids) if 0 < i < SCENERY_ID_BASE}
        visible = {a["track_id"] for a in rec["agents"] if a["visible_pixels"] > 0}
        assert visible == in_exr and in_exr
        for a in rec["agents"]:
            assert a["visible_pixels"] == int((ids == a["track_id"]).sum())
        anns = coco.loadAnns(coco.getAnnIds(imgIds=[index]))
        assert {a["track_id"] for a in anns} == in_exr
        assert {r[1] for r in mot if r[0] == index} == {a["track_id"] for a in rec["agents"]}
    ini = (out / "mot" / "seqinfo.ini").read_text()
    assert f"seqLength={len(FRAMES)}" in ini and "imWidth=160" in ini and "frameRate=12" in ini
    assert len(list((out / "mot" / "img1").glob("*.png"))) == len(FRAMES)


def test_sequence_files_read_the_frames_one_at_a_time(sequence, tmp_path):
    """COCO and MOT are written a frame at a time from the JSON files, and say what the frames say."""
    from usdcrowd.groundtruth.coco import coco_dict, write_coco
    from usdcrowd.groundtruth.mot import write_mot

    out = Path(sequence.out_dir)
    records = frame_json.Records(sorted((out / "json").glob("frame.*.json")))
    assert len(records) >= 2 and isinstance(records[1], dict) and len(records[:1]) == 1
    files = [f"img{i}.png" for i in range(len(records))]
    write_coco(records, tmp_path / "c.json", files)
    whole = coco_dict(list(records), files)
    assert json.loads((tmp_path / "c.json").read_text()) == whole
    assert len(whole["annotations"]) == sum(a["visible_pixels"] > 0 for r in records for a in r["agents"]) > 0
    gt = read_mot(write_mot(records, tmp_path / "mot"))
    assert len(gt) == sum(a.get("bbox_amodal") is not None for r in records for a in r["agents"])
    assert (tmp_path / "mot" / "frames.csv").read_text().splitlines()[1:] == [
        f"{i},{r['time']:g}" for i, r in enumerate(records, 1)]


def test_coco_masks_decode_to_the_exr_pixels(sequence):
    from pycocotools.coco import COCO

    coco = COCO(str(Path(sequence.out_dir) / "coco.json"))
    cat = coco.loadCats(1)[0]
    assert cat["name"] == "person" and cat["keypoints"] == ["pelvis", "waist", "neck", "headTop", "ground"]
    assert cat["skeleton"] == [[5, 1], [1, 2], [2, 3], [3, 4]]
    for index, t in enumerate(FRAMES, start=1):
        ch, _ = _frame(sequence, t)
        for ann in coco.loadAnns(coco.getAnnIds(imgIds=[index])):
            mask = coco.annToMask(ann).astype(bool)
            assert np.array_equal(mask, ch["id"] == ann["track_id"])
            ys, xs = np.nonzero(mask)
            assert ann["bbox"] == [xs.min(), ys.min(), xs.max() + 1 - xs.min(), ys.max() + 1 - ys.min()]
            assert ann["area"] == mask.sum() and len(ann["keypoints"]) == 15


def test_coco_scores_itself_perfectly(sequence):
    """COCOeval of the ground truth as detections: segm and bbox AP are 1."""
    from pycocotools.coco import COCO
    from pycocotools.cocoeval import COCOeval

    gt = COCO(str(Path(sequence.out_dir) / "coco.json"))
    dets = [dict(a, score=1.0) for a in gt.dataset["annotations"]]
    for iou_type in ("segm", "bbox"):
        ev = COCOeval(gt, gt.loadRes([dict(d) for d in dets]), iou_type)
        ev.params.areaRng = [[0, 1e10]]
        ev.params.areaRngLbl = ["all"]
        ev.evaluate()
        ev.accumulate()
        precision = ev.eval["precision"][:, :, 0, 0, -1]               # IoU x recall, person, all, maxDets
        assert np.all(precision[precision > -1] == 1.0)


def test_visibility_boxes_and_keypoints_are_consistent(sequence):
    for t in FRAMES:
        ch, rec = _frame(sequence, t)
        assert rec["camera"]["camera"] == "/World/Cameras/CrowdCam" and len(rec["camera"]["K"]) == 3
        for a in rec["agents"]:
            assert 0 <= a["visibility"] <= 1
            assert a["visibility"] == pytest.approx(a["visible_pixels"] / a["alone_pixels"])
            if a["bbox_visible"]:
                # Visible pixel centres lie inside the projected mesh's box.
                vx, vy, vw, vh = a["bbox_visible"]
                ax, ay, aw, ah = a["bbox_amodal"]
                assert ax <= vx + 0.5 and ay <= vy + 0.5
                assert vx + vw - 0.5 <= ax + aw and vy + vh - 0.5 <= ay + ah
            for (u, v, flag) in a["keypoints"]:
                inside = 0 <= u < ch["id"].shape[1] and 0 <= v < ch["id"].shape[0]
                assert (flag > 0) == inside
            assert a["group"].startswith("/World/Crowd") and a["state"]["health"] == "ok"
            assert np.isfinite(a["heading"]) and len(a["position_3d"]) == 3
        json.dumps(rec)                                                  # plain JSON all the way down


def test_fully_hidden_agent_has_zero_visibility_and_occluded_keypoints(walking_museum):
    """An agent behind a wall: in view (alone pixels) but not visible; keypoints flagged occluded."""
    from pxr import Gf, Usd, UsdGeom

    from usdcrowd.render.final.frame import FrameRenderer
    from usdcrowd.scenario.shot_scene import ShotScene

    shot = ShotScene(walking_museum)
    poses = shot.agents(1)
    i = poses.paths.index("/World/Crowd/Visitors/Students/Teacher")
    head = poses.keypoints()[i, 3]
    # A camera 6 m in front of the teacher's head and a wall in between, in the session layer.
    with Usd.EditContext(shot.stage, shot.stage.GetSessionLayer()):
        cam = shot.stage.DefinePrim("/World/TestCam", "Camera")
        eye = head + np.array([0.0, -6.0, 0.0])
        xf = UsdGeom.Xformable(cam)
        xf.AddTranslateOp().Set(Gf.Vec3d(*eye.tolist()))
        xf.AddRotateXYZOp().Set(Gf.Vec3f(90, 0, 0))                       # look along +Y
        wall = UsdGeom.Cube.Define(shot.stage, "/World/Scenery/TestWall")
        wall.GetSizeAttr().Set(1.0)
        UsdGeom.Xformable(wall).AddTranslateOp().Set(Gf.Vec3d(*(head + [0, -3.0, -0.8]).tolist()))
        UsdGeom.Xformable(wall).AddScaleOp().Set(Gf.Vec3f(4, 0.1, 4))
    shot = ShotScene(walking_museum, stage=shot.stage)
    r = FrameRenderer(shot, "/World/TestCam", (64, 48), spp=1, max_depth=2).render(1)
    rec = annotate_frame(r, AgentMetadata.from_shot(shot))
    teacher = next(a for a in rec["agents"] if a["track_id"] == 100)
    assert teacher["alone_pixels"] > 100 and teacher["visible_pixels"] == 0 and teacher["visibility"] == 0
    assert teacher["bbox_visible"] is None
    assert all(k[2] == 1 for k in teacher["keypoints"] if 0 <= k[0] < 64 and 0 <= k[1] < 48)
    assert not (r.gt.ids == 100).any()


def test_metadata_reads_leaders_and_events(walking_museum):
    from pxr import Sdf, Usd

    from usdcrowd.scenario.shot_scene import ShotScene

    shot = ShotScene(walking_museum)
    student = next(p for p in shot.agent_paths if "/Students/" in p and not p.endswith("Teacher"))
    with Usd.EditContext(shot.stage, shot.stage.GetSessionLayer()):
        ev = shot.stage.DefinePrim("/World/Events/Chat", "CrowdEvent")
        ev.CreateAttribute("crowd:kind", Sdf.ValueTypeNames.Token).Set("interaction")
        ev.CreateAttribute("crowd:startTime", Sdf.ValueTypeNames.Double).Set(2.0)
        ev.CreateAttribute("crowd:endTime", Sdf.ValueTypeNames.Double).Set(4.0)
        ev.CreateRelationship("crowd:members").SetTargets([student])
    meta = AgentMetadata.from_shot(shot)
    assert meta.at(student, 3.0)["events"] == [{"path": "/World/Events/Chat", "kind": "interaction"}]
    assert meta.at(student, 5.0)["events"] == []
    # Time-sampled crowd:memberIds: the student leaves the chat at frame 4, the teacher (id 100) joins.
    with Usd.EditContext(shot.stage, shot.stage.GetSessionLayer()):
        ids = ev.CreateAttribute("crowd:memberIds", Sdf.ValueTypeNames.IntArray)
        sid = int(shot.stage.GetPrimAtPath(student).GetAttribute("crowd:agentId").Get())
        ids.Set([sid], 2.0)
        ids.Set([100], 4.0)
    meta = AgentMetadata.from_shot(shot)
    teacher = next(p for p, a in zip(shot.agent_paths, shot._agent_static[1]) if a == 100)
    assert [bool(meta.at(student, t)["events"]) for t in (2.0, 3.0, 4.0)] == [True, True, False]
    assert [bool(meta.at(teacher, t)["events"]) for t in (2.0, 3.0, 4.0)] == [False, False, True]
    info = meta.at(student, 3.0)
    assert info["group"] == "/World/Crowd/Visitors/Students" and info["role"] == "member"
    leaders = {meta.at(p, 1.0)["leader"] for p in shot.agent_paths if "/Students/" in p}
    assert 100 in leaders                                                # the teacher leads students


def test_rle_round_trips_and_matches_pycocotools(rng):
    from pycocotools import mask as mask_utils

    for shape in ((1, 1), (7, 5), (30, 41)):
        for density in (0.0, 0.3, 1.0):
            m = rng.random(shape) < density
            r = rle.encode(m)
            assert np.array_equal(rle.decode(r), m)
            compressed = mask_utils.frPyObjects(r, *shape)
            assert np.array_equal(mask_utils.decode(compressed).astype(bool), m)
            assert compressed == mask_utils.encode(np.asfortranarray(m.astype(np.uint8)))


MOTMETRICS_SCRIPT = '''
import sys, motmetrics as mm
gt = mm.io.loadtxt(sys.argv[1], fmt="mot15-2D", min_confidence=1)
acc = mm.utils.compare_to_groundtruth(gt, gt.copy(), "iou", distth=0.5)
summary = mm.metrics.create().compute(acc, metrics=["mota", "idf1", "num_switches", "num_objects"], name="self")
print(summary.to_csv())
'''


def _motmetrics_python() -> str:
    """A small venv with motmetrics 1.4.0 on numpy < 2 (it calls np.asfarray, gone in numpy 2), made once."""
    from tests.helpers.venvs import tool_python

    return tool_python("motmetrics", ["numpy<2", "pandas<2.3", "scipy<1.14", "motmetrics==1.4.0"],
                       "USDCROWD_MOTMETRICS_VENV")


@pytest.mark.slow
def test_motmetrics_scores_the_ground_truth_against_itself(sequence, tmp_path):
    gt = Path(sequence.out_dir) / "mot" / "gt" / "gt.txt"
    script = tmp_path / "score.py"
    script.write_text(MOTMETRICS_SCRIPT)
    python = _motmetrics_python()
    out = subprocess.run([python, str(script), str(gt)], check=True, capture_output=True, text=True).stdout
    header, row = out.strip().splitlines()[:2]
    values = dict(zip(header.split(",")[1:], row.split(",")[1:]))
    assert float(values["mota"]) == 1.0 and float(values["idf1"]) == 1.0
    assert int(float(values["num_switches"])) == 0
    assert int(float(values["num_objects"])) == len(read_mot(gt))
