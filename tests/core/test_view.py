"""The pure core camera model: look_at, CameraView, and who may import whom."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import numpy as np

from usdcrowd.core.view import CameraView, camera_record, look_at

from tests.helpers.paths import PACKAGE


def test_look_at_points_minus_z_at_the_target_with_a_level_right_axis(rng):
    eye, target = rng.normal(size=(50, 3)) * 10, rng.normal(size=(50, 3)) * 10
    m = look_at(eye, target)
    assert m.shape == (50, 4, 4)
    r = m[:, :3, :3]
    np.testing.assert_allclose(r @ r.transpose(0, 2, 1), np.broadcast_to(np.eye(3), r.shape), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(r), 1.0, atol=1e-12)
    d = (target - eye) / np.linalg.norm(target - eye, axis=1, keepdims=True)
    np.testing.assert_allclose(-m[:, 2, :3], d, atol=1e-12)          # looks down local -Z
    np.testing.assert_allclose(m[:, 0, 2], 0.0, atol=1e-12)          # right axis horizontal: no roll
    assert np.all(m[:, 1, 2] >= 0)                                   # camera +Y on the sky's side
    np.testing.assert_allclose(m[:, 3, :3], eye)
    # The target projects to the image centre, in front of the camera.
    for k in range(3):
        cam = CameraView("/c", 1.0, m[k], 35.0, 36.0, 24.0, 0.1, 100.0)
        uv, z = cam.project(target[k], 64, 48)
        np.testing.assert_allclose(uv, [32, 24], atol=1e-9)
        assert z > 0


def test_look_at_single_points_and_straight_down():
    m = look_at([0.0, 0.0, 5.0], [0.0, 0.0, 0.0])
    assert m.shape == (1, 4, 4)
    np.testing.assert_allclose(m[0, :3, :3], np.eye(3), atol=1e-12)   # +Y stays up when looking down
    m = look_at(np.zeros(3), [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])      # one eye, two targets
    np.testing.assert_allclose(m[:, 2, :3], [[-1, 0, 0], [0, -1, 0]], atol=1e-12)
    y_up = look_at([0.0, 0.0, 0.0], [0.0, 0.0, -1.0], up=(0.0, 1.0, 0.0))
    np.testing.assert_allclose(y_up[0, 1, :3], [0.0, 1.0, 0.0], atol=1e-12)


def test_camera_record_matches_the_projection():
    m = look_at([3.0, -8.0, 2.0], [0.0, 0.0, 1.0])[0]
    cam = CameraView("/c", 4.0, m, 24.0, 36.0, 20.25, 0.1, 100.0)
    rec = camera_record(cam, 160, 90)
    p = np.array([0.5, 1.0, 1.2])
    pc = np.array(rec["world_to_camera_opencv"]) @ np.r_[p, 1.0]
    uvw = np.array(rec["K"]) @ pc[:3]
    uv, z = cam.project(p, 160, 90)
    np.testing.assert_allclose(uvw[:2] / uvw[2], uv, atol=1e-9)
    np.testing.assert_allclose(pc[2], z)
    assert abs(cam.fov_y() - np.degrees(2 * np.arctan(20.25 / 48.0))) < 1e-12


def _imports(path: Path) -> list[str]:
    """Absolute module names imported anywhere in a file (relative ones resolved)."""
    pkg = ".".join(path.relative_to(PACKAGE.parent).with_suffix("").parts[:-1])
    out = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = pkg.rsplit(".", node.level - 1)[0] if node.level else ""
            mod = ".".join(x for x in (base, node.module or "") if x)
            out += [mod] + [f"{mod}.{a.name}" for a in node.names]
    return out


def test_groundtruth_and_the_pure_core_do_not_import_render():
    core = [PACKAGE / "core" / f for f in ("model.py", "view.py", "shading.py")] + [PACKAGE / "character" / "poses.py"]
    files = list((PACKAGE / "groundtruth").glob("*.py")) + core
    for f in files:
        bad = [m for m in _imports(f) if m.startswith("usdcrowd.render")]
        assert not bad, f"{f.name} imports {bad}"
    for f in core:
        assert not [m for m in _imports(f) if m.startswith("pxr")], f


def test_old_import_paths_still_work():
    code = ("import sys; import usdcrowd.groundtruth.annotate, usdcrowd.core.view, usdcrowd.character.poses,"
            " usdcrowd.core.shading;"
            "assert not [m for m in sys.modules if m.startswith('usdcrowd.render')], 'render imported';"
            "from usdcrowd.scenario.shot_scene import CameraView, AgentPoses, Material, Light, SCENERY_ID_BASE;"
            "from usdcrowd.render.final.camera import camera_record;"
            "import usdcrowd.core.view as v; assert CameraView is v.CameraView and camera_record is v.camera_record")
    subprocess.run([sys.executable, "-c", code], check=True)
