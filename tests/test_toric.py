"""Toric space (seed 002, Lino and Christie 2015): exact two-target framing and its inverse."""

from __future__ import annotations

import numpy as np
import pytest

from usdcrowd.cameras.toric import ToricError, framing_angle, pose_to_toric, toric_to_pose
from usdcrowd.view import CameraView

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
