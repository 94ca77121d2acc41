"""Retargeting (seed 002, section 5): a new pair filmed the way a reference filmed its own, and how close it comes.

:func:`retarget_features` is what ``usdcrowd frame --like`` runs once the
reference is read: the gate's mix of experts rolled out over the new pair's
character features from a blind start; :func:`retarget_poses` builds each
frame's features into a level camera
(:func:`usdcrowd.cameras.moe.poses_of_features`), as the command does
(which first blends references switched over time and keeps the camera
clear of walls).
:func:`compare` measures a camera against the controller it imitates, frame
by frame, in the quantities a cinematographer checks: where the camera is
round the pair (theta, phi), how far (distance ratio), where the heads are
on screen, the roll, and an orbit's turn.
"""

from __future__ import annotations

import numpy as np

SETTLE_FRAMES = 48         # a blind start, rolled out before the shot begins (2 s at 24 fps)
_UP = np.array([0.0, 0.0, 1.0])


def retarget_features(model, weights: np.ndarray, char: np.ndarray, start_cam: np.ndarray | None = None) -> np.ndarray:
    """(t, 8) camera features filming a pair (character features ``char``, (t, 10)) in the style of ``weights``
    ((m,), :meth:`CameraMoE.gate` of the reference); ``start_cam`` ((8,) or None): features to start from, None
    (what the command does) starting blind, settled over :data:`SETTLE_FRAMES` frames (a model trained without
    blind samples needs a start)."""
    return model.rollout(weights, char, start_cam, settle=SETTLE_FRAMES if start_cam is None else 0)


def retarget_poses(model, weights: np.ndarray, char: np.ndarray, heads_a, heads_b, fov_x: float, aspect: float,
                   start_cam: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Cameras filming A and B in the style of ``weights``: :func:`retarget_features` built into cameras.

    Parameters
    ----------
    model : CameraMoE
    weights : (m,) float
    char : (t, 10) float
        The new pair's character features.
    heads_a, heads_b : (t, 3) float
        Their heads, metres, Z up.
    fov_x, aspect : float
        The new camera's lens (radians) and frame (width / height).
    start_cam : (8,) float or None

    Returns
    -------
    poses : (t, 4, 4) float
        Row-vector camera-to-world matrices.
    features : (t, 8) float
        The rolled-out camera features they were built from.
    """
    from .moe import poses_of_features

    cam = retarget_features(model, weights, char, start_cam)
    return poses_of_features(cam, heads_a, heads_b, fov_x, aspect), cam


def switch_weights(starts, times, fps: float, transition: float = 1.0) -> np.ndarray:
    """(t, n) share of each of ``n`` references in each frame, for references switched over time.

    Parameters
    ----------
    starts : sequence of float
        The time code each reference takes over from (the first's is
        ignored: it holds from the start), increasing.
    times : (t,) float
        The shot's time codes.
    fps : float
        Time codes per second.
    transition : float
        Seconds over which one reference's share passes to the next, easing
        in and out (smoothstep: the camera's speed changes without a jolt).
    """
    times = np.asarray(times, dtype=np.float64)
    out = np.zeros((len(times), len(starts)))
    out[:, 0] = 1.0
    for k, start in enumerate(starts[1:], 1):
        ramp = np.clip((times - start) / max(transition * fps, 1e-9), 0.0, 1.0)[:, None]
        ramp = ramp * ramp * (3.0 - 2.0 * ramp)
        out = (1.0 - ramp) * out
        out[:, k] += ramp[:, 0]
    return out


def _slerp(a: np.ndarray, b: np.ndarray, t: np.ndarray, over_the_top: bool = False) -> np.ndarray:
    """(t, 3) unit vectors ``t`` ((t,) in [0, 1]) of the way along the great circle from ``a`` to ``b``.

    With ``over_the_top`` the way goes through the up direction made
    orthogonal to ``a`` (half the way there, then on to ``b``): nearly
    opposite directions have no one great circle between them, and a camera
    passing to the other side of a pair cranes over it.
    """
    a = a / np.linalg.norm(a, axis=1, keepdims=True)
    b = b / np.linalg.norm(b, axis=1, keepdims=True)
    if over_the_top:
        up = np.array([0.0, 0.0, 1.0]) - a[:, 2:3] * a
        flat = np.linalg.norm(up, axis=1) < 1e-6
        up[flat] = np.cross(a[flat], [1.0, 0.0, 0.0])
        top = up / np.linalg.norm(up, axis=1, keepdims=True)
        return _slerp(_slerp(a, top, np.minimum(2 * t, 1.0)), b, np.maximum(2 * t - 1.0, 0.0))
    omega = np.arccos(np.clip(np.einsum("ti,ti->t", a, b), -1.0, 1.0))
    sin = np.sin(omega)
    near = sin < 1e-6
    wa = np.where(near, 1.0 - t, np.sin((1.0 - t) * omega) / np.where(near, 1.0, sin))
    wb = np.where(near, t, np.sin(t * omega) / np.where(near, 1.0, sin))
    out = wa[:, None] * a + wb[:, None] * b
    return out / np.linalg.norm(out, axis=1, keepdims=True)


def blend_features(features, shares: np.ndarray) -> np.ndarray:
    """(t, 8) camera features passing from one roll-out ((t, 8) each) to the next by per-frame ``shares`` ((t, n)
    from :func:`switch_weights`: each frame mixes at most two neighbours).

    Screen positions and the log span mix linearly; the direction from A
    turns along the great circle between the two (:func:`_slerp`, over
    the top where they come nearly opposite), so
    that a camera passing from one style's place to the next goes round the
    pair, not through it.
    """
    from .moe import U

    out = np.array(features[0], dtype=np.float64)
    for k in range(1, len(features)):
        nxt = np.asarray(features[k], dtype=np.float64)
        t = shares[:, k] / np.maximum(shares[:, k - 1] + shares[:, k], 1e-12)
        t = np.where(shares[:, k:].sum(axis=1) > 0, np.where(shares[:, :k].sum(axis=1) > 0, t, 1.0), 0.0)
        # One way for the whole transition (switching ways midway would jump): over the top wherever the
        # two directions come nearly opposite during it.
        moving = (t > 0) & (t < 1)
        cos = np.einsum("ti,ti->t", out[moving][:, U], nxt[moving][:, U]) / np.maximum(
            np.linalg.norm(out[moving][:, U], axis=1) * np.linalg.norm(nxt[moving][:, U], axis=1), 1e-12)
        u = _slerp(out[:, U], nxt[:, U], t, over_the_top=bool(moving.any() and cos.min() < -0.95))
        out = (1.0 - t)[:, None] * out + t[:, None] * nxt
        out[:, U] = u
    return out


def _angles(eye, heads_a, heads_b):
    """(theta, phi), each (t,): toric angles of eyes about A and B (the convention of camera_features)."""
    from .toric import angles_at_a, axes

    x, y, z, _ = axes(heads_a, heads_b, _UP)
    beta, phi = angles_at_a(eye - heads_a, x, y, z)
    return 2.0 * beta, phi


def turn_about(eye: np.ndarray, centre: np.ndarray) -> float:
    """Signed degrees ``eye`` ((t, 3)) goes round ``centre`` ((t, 3)) about the vertical over the frames."""
    rel = (eye - centre)[:, :2]
    return float(np.degrees(np.unwrap(np.arctan2(rel[:, 1], rel[:, 0]))[[0, -1]] @ [-1.0, 1.0]))


def compare(poses: np.ndarray, truth: np.ndarray, heads_a, heads_b, fov_x: float, aspect: float) -> dict:
    """Per-frame differences of cameras ``poses`` from the controller's ``truth`` ((t, 4, 4) each).

    Returns
    -------
    dict of (t,) float arrays
        ``distance_ratio`` (to the heads' midpoint, learned over controller),
        ``theta_deg``, ``phi_deg`` (absolute differences, phi wrapped),
        ``screen`` (mean distance of the two heads' screen positions, NDC),
        ``roll_deg`` (the learned camera's right axis out of the horizontal);
        and floats ``turn_deg``, ``truth_turn_deg``: how far each goes round
        the midpoint over the frames (signed, counter-clockwise seen from above).
    """
    from .behaviors import _project

    heads_a, heads_b = np.asarray(heads_a, dtype=np.float64), np.asarray(heads_b, dtype=np.float64)
    mid = 0.5 * (heads_a + heads_b)
    eye, true_eye = poses[:, 3, :3], truth[:, 3, :3]
    ratio = np.linalg.norm(eye - mid, axis=1) / np.maximum(np.linalg.norm(true_eye - mid, axis=1), 1e-9)
    (th, ph), (th_t, ph_t) = _angles(eye, heads_a, heads_b), _angles(true_eye, heads_a, heads_b)
    screen = 0.5 * sum(np.linalg.norm(_project(poses, h, fov_x, aspect) - _project(truth, h, fov_x, aspect), axis=1)
                       for h in (heads_a, heads_b))
    right = poses[:, 0, :3]
    roll = np.degrees(np.arcsin(np.clip(np.abs(right @ _UP) / np.linalg.norm(right, axis=1), 0.0, 1.0)))
    return {"distance_ratio": ratio, "theta_deg": np.degrees(np.abs(th - th_t)),
            "phi_deg": np.degrees(np.abs(np.angle(np.exp(1j * (ph - ph_t))))), "screen": screen, "roll_deg": roll,
            "turn_deg": turn_about(eye, mid), "truth_turn_deg": turn_about(true_eye, mid)}
