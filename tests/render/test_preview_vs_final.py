"""The preview can be trusted for framing: its boxes agree with the final renderer's ground truth."""

from __future__ import annotations

import json

import pytest

from usdcrowd.jobs.pipeline import simulate_shot
from usdcrowd.core.resources import data_dir

FRAMES = (1.0, 40.0, 80.0)
SIZE = (320, 180)


def _iou(a, b) -> float:
    """IoU of two (x0, y0, x1, y1) boxes, exclusive ends."""
    w = min(a[2], b[2]) - max(a[0], b[0])
    h = min(a[3], b[3]) - max(a[1], b[1])
    inter = max(w, 0) * max(h, 0)
    area = lambda r: (r[2] - r[0]) * (r[3] - r[1])  # noqa: E731
    return inter / (area(a) + area(b) - inter)


@pytest.fixture(scope="module")
def dialogue_both_ways(tmp_path_factory):
    """The dialogue shot rendered by Mitsuba (ground truth) and by the preview at full detail."""
    pytest.importorskip("mitsuba")
    pytest.importorskip("moderngl")
    from usdcrowd.core.errors import UsdcrowdError
    from usdcrowd.render.demo import final_outputs
    from usdcrowd.render.preview import LodSettings, PreviewRenderer
    from usdcrowd.scenario.shot_scene import ShotScene

    out = tmp_path_factory.mktemp("dialogue")
    shot = simulate_shot(data_dir("stages") / "dialogue.usda", out / "shot", frames=(1, 80), progress=False)
    scene = ShotScene(shot.shot)
    camera = scene.camera_paths[0]
    final = final_outputs(shot.shot, out / "final", camera=camera, frames=FRAMES, resolution=SIZE, spp=4)
    truth = {t: json.loads((out / "final" / "json" / f"frame.{int(t):04d}.json").read_text()) for t in FRAMES}
    try:
        preview = PreviewRenderer(scene, *SIZE, lod_settings=LodSettings(enabled=False))
    except UsdcrowdError as exc:
        pytest.skip(f"no OpenGL context: {exc}")
    try:
        boxes = {t: preview.render(t, camera).boxes() for t in FRAMES}
    finally:
        preview.release()
    assert final["variant"]
    return truth, boxes


def test_unoccluded_agents_have_the_same_box_in_preview_and_ground_truth(dialogue_both_ways):
    truth, boxes = dialogue_both_ways
    compared = 0
    for t, record in truth.items():
        for agent in record["agents"]:
            if agent["visibility"] < 0.999 or agent["visible_pixels"] < 40:
                continue        # occluded or tiny: the claim is about unoccluded agents
            x, y, w, h = agent["bbox_visible"]
            iou = _iou((x, y, x + w, y + h), boxes[t][agent["track_id"]])
            assert iou >= 0.95, (t, agent["track_id"], iou)
            compared += 1
    assert compared >= 6


def test_preview_sees_exactly_the_agents_ground_truth_sees(dialogue_both_ways):
    truth, boxes = dialogue_both_ways
    for t, record in truth.items():
        seen = {a["track_id"] for a in record["agents"] if a["visible_pixels"] > 0}
        assert {k for k in boxes[t] if k < (1 << 24)} == seen
