"""usdcrowd inspect STAGE --image PNG: a quick look at any stage through the OpenGL preview."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from usdcrowd.cli import main

OVERVIEW = "/World/Cameras/Overview"
SIZE = (640, 360)


def _read_png(path) -> np.ndarray:
    """(h, w, 3) uint8 through imageio (the writer is Pillow)."""
    import imageio.v3 as iio

    return np.asarray(iio.imread(path))[..., :3]


def _inspect(stage, png, *extra) -> np.ndarray:
    assert main(["inspect", str(stage), "--image", str(png), "--resolution", f"{SIZE[0]}x{SIZE[1]}", *extra]) == 0
    return _read_png(png)


def test_a_shot_is_drawn_with_its_agents_where_the_camera_projects_them(walking_museum, gl, tmp_path, capsys):
    from usdcrowd.render.preview import PreviewRenderer

    image = _inspect(walking_museum, tmp_path / "look.png", "--camera", OVERVIEW, "--frame", "6")
    assert image.shape == (SIZE[1], SIZE[0], 3)
    assert "frame 6" in capsys.readouterr().out
    # The same frame as the preview command writes it.
    frames = tmp_path / "preview"
    assert main(["preview", str(walking_museum), "--camera", OVERVIEW, "--frames", "6", "--resolution",
                 f"{SIZE[0]}x{SIZE[1]}", "-o", str(frames), "--no-progress"]) == 0
    np.testing.assert_array_equal(image, _read_png(frames / "frame.0006.png"))
    # Where the camera projects the agents' heads, the picture differs from the same view without agents.
    r = PreviewRenderer(walking_museum, *SIZE)
    try:
        poses = r.poses(6.0)
        camera = r.camera(OVERVIEW, 6.0)
        empty = r.render_poses(dataclasses.replace(poses, visible=np.zeros(len(poses), bool)), camera).color
    finally:
        r.release()
    keypoints = poses.keypoints()
    heads, depth = camera.project((keypoints[:, 2] + keypoints[:, 3]) / 2.0, *SIZE)
    shown = poses.visible & (depth > 0) & (heads >= 2).all(1) & (heads < np.array(SIZE) - 2).all(1)
    assert shown.sum() >= 10
    changed = np.abs(image.astype(int) - empty.astype(int)).max(-1)
    near_head = [changed[y - 1:y + 2, x - 1:x + 2].max() for x, y in np.floor(heads[shown]).astype(int)]
    assert np.mean(np.array(near_head) > 20) >= 0.8, near_head
    # Away from every agent (a corner of the room), nothing changed.
    assert changed[:20, :20].max() <= 2


def test_the_frame_defaults_to_the_stages_start(walking_museum, gl, tmp_path):
    start = _inspect(walking_museum, tmp_path / "start.png", "--camera", OVERVIEW, "--frame", "1")
    later = _inspect(walking_museum, tmp_path / "later.png", "--camera", OVERVIEW, "--frame", "12")
    default = _inspect(walking_museum, tmp_path / "default.png", "--camera", OVERVIEW)
    np.testing.assert_array_equal(default, start)
    assert (default != later).any()             # the agents walked


BOXES = {"Small": ((-6, -6), 1.0), "Middle": ((0, 0), 2.0), "Large": ((6, 6), 3.0)}    # centre, side (m)


def test_scenery_without_camera_or_crowd_is_framed_from_three_quarters(write_stage, gl, tmp_path, capsys):
    """Three boxes on a diagonal across the view: each one whole in the picture, smallest on the left."""
    from scipy import ndimage

    cubes = "".join(f'''
    def Cube "{name}"
    {{
        double size = {side}
        double3 xformOp:translate = ({x}, {y}, {side / 2})
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }}''' for name, ((x, y), side) in BOXES.items())
    stage = write_stage(f'def Xform "World"\n{{{cubes}\n}}\n')
    image = _inspect(stage, tmp_path / "boxes.png")
    assert "three-quarter view" in capsys.readouterr().out
    background = image[0, 0].astype(int)
    boxes = np.abs(image.astype(int) - background).max(-1) > 8
    assert 0.02 < boxes.mean() < 0.5                                   # not uniform, not all box
    labels, count = ndimage.label(boxes)
    areas = ndimage.sum(boxes, labels, np.arange(1, count + 1))
    blobs = np.flatnonzero(areas > 50) + 1
    assert len(blobs) == 3, areas
    for blob in blobs:                                                 # in view: none cut by the border
        ys, xs = np.nonzero(labels == blob)
        assert xs.min() > 0 and ys.min() > 0 and xs.max() < SIZE[0] - 1 and ys.max() < SIZE[1] - 1
    left_to_right = sorted(blobs, key=lambda b: np.nonzero(labels == b)[1].mean())
    assert np.all(np.diff([areas[b - 1] for b in left_to_right]) > 0)  # Small, Middle, Large


def test_the_three_quarter_view_frames_the_box_tightly():
    """Every corner inside the picture, one on the border the view leaves (QUICK_LOOK_FILL)."""
    from usdcrowd.cli.inspect_cmd import QUICK_LOOK_FILL, three_quarter_view

    lo, hi = np.array([-20.0, -3.0, 0.0]), np.array([40.0, 9.0, 12.0])
    for width, height in ((640, 360), (300, 600)):
        view = three_quarter_view(lo, hi, width, height)
        corners = np.array(np.meshgrid(*np.stack([lo, hi], 1), indexing="ij")).reshape(3, -1).T
        uv, depth = view.project(corners, width, height)
        assert (depth > view.near).all() and (depth < view.far).all()
        reach = np.abs(uv - [width / 2, height / 2]) / [width / 2, height / 2]
        assert reach.max() == pytest.approx(QUICK_LOOK_FILL, abs=1e-9)
        eye = view.position
        assert eye[0] > hi[0] and eye[1] < lo[1] and eye[2] > hi[2]     # front right, above


def test_a_wrong_camera_is_one_line_and_writes_nothing(write_stage, gl, tmp_path, capsys):
    stage = write_stage('def Xform "World"\n{\n    def Cube "Box"\n    {\n    }\n}\n')
    out = tmp_path / "out" / "look.png"
    assert main(["inspect", str(stage), "--image", str(out), "--camera", "/World/Nope"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "/World/Nope" in err and "not a camera" in err
    assert not out.exists() and not list(tmp_path.glob("out/*"))
