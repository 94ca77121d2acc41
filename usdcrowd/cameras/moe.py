"""Learned camera behaviors (seed 002, section 5): a mixture of experts, run in plain numpy.

A *gating* network reads a reference clip's cinematic features (an LSTM over
them, then a softmax over ``m`` experts): the mix of behaviors the clip
shows. The *prediction* network's weights are that mix of the experts'
weights; from the camera's recent toric features and the two characters'
features around the present it predicts the camera's next ones. Rolled out
over a new scene, it films a new pair the way the reference was filmed.

Training is PyTorch's (``tools/train_camera_moe.py``, in its own venv); the
weights ship in the package (float32) and everything here is numpy: using a
trained model needs no PyTorch. Two models ship: ``camera_moe.npz`` for
references read from a stage, whose pair's motion is known, and
``camera_moe_clip.npz`` for film clips (:data:`CLIP_WEIGHTS`), where the
pair's motion is not: a model whose experts read the reference's style
films stage references best and clips worst (the camera researcher's
guide has the numbers), so a clip is read by one trained without it.

Features per frame
------------------
character, 10 (they do not depend on any camera):
    dAB (m), sin and cos of sA, sB and sAB (the paper's shoulder angles,
    :func:`usdcrowd.cameras.features.pair_orientation`), the pair's
    velocity along AB and across it (m/s, the heads' midpoint, smoothed
    over half a second), and how fast the line AB turns in the world
    (rad/s, smoothed alike: without it a camera cannot tell an orbit from
    a pair that turns, and cannot keep an orbit's speed in the world).
camera, 8 (the paper's toric features, and the main character's size):
    pA.x, pA.y, pB.x, pB.y (NDC; both heights, as the paper has them),
    u = (cos(theta / 2), sin(theta / 2) cos phi, sin(theta / 2) sin phi),
    the unit direction from A to the camera in the pair's frame (along AB,
    across it level, up; :mod:`usdcrowd.cameras.toric`): an orbit crosses
    the line AB by craning over it, where theta turns back and phi sweeps
    through pi / 2; as angles that is a fold a regression cannot time, as
    a direction it is a smooth arc), and log of the span: the metres the
    frame's height covers at A's distance (the shot size, independent of
    the lens).

A camera is built from predicted features (:func:`poses_of_features`) the
way the controllers build theirs: the eye at A plus the span's distance
along u, turned without roll to put the heads' midpoint at their predicted
height. The paper places the camera in toric space from pA, pB, theta
and phi alone; there the distance grows as 1 / sin(alpha) when the two
heads come close on screen (a side track's pair one behind the other),
and a roll-out's small errors became cameras 10-30 times too far. The span
bounds the distance, and a level camera cannot roll.

The paper's sizes are 60 past and 60 future frames, 30 predicted, hidden
512 and 9 experts at 60 fps; here the windows are sampled every ``step``
frames and the sizes are read from the weights file (see
:class:`CameraMoE`; the tool states what it trained).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np

N_CHARACTER = 10
N_CAMERA = 8
N_STYLE = 5         # the gate's style features (style_features), after its character and camera features
U = slice(4, 7)     # the camera features' direction from A
SPAN = 7            # and their log span
WEIGHTS = Path(__file__).with_name("camera_moe.npz")             # references read from a stage
CLIP_WEIGHTS = Path(__file__).with_name("camera_moe_clip.npz")   # film clips (no pair motion known)
PAIR_MOTION = slice(7, 10)  # the character features a picture cannot show: the pair's velocity and turn
CLIP = 4.0          # standard deviations a fed-back camera feature may reach (and the training's range, if stored)


# ------------------------------------------------------------------------------------ features
def character_features(heads_a, heads_b, yaw_a, yaw_b, fps: float) -> np.ndarray:
    """(t, 10) float64 character features of A and B (see the module).

    Parameters
    ----------
    heads_a, heads_b : (t, 3) float
        Head points, metres, Z up.
    yaw_a, yaw_b : (t,) float
        Shoulder facings, radians.
    fps : float
        Frames per second (for the velocities).
    """
    from .features import pair_orientation
    from .smoothing import moving_average

    heads_a, heads_b = (np.asarray(v, dtype=np.float64) for v in (heads_a, heads_b))
    d, s_a, s_b, s_ab = pair_orientation(heads_a, heads_b, yaw_a, yaw_b)
    mid = 0.5 * (heads_a + heads_b)[:, :2]
    vel = np.gradient(mid, axis=0) * fps if len(mid) > 1 else np.zeros_like(mid)
    vel = moving_average(vel, max(1, int(round(0.5 * fps))))
    ab = (heads_b - heads_a)[:, :2]
    along = ab / np.maximum(np.linalg.norm(ab, axis=1, keepdims=True), 1e-9)
    across = np.stack([-along[:, 1], along[:, 0]], -1)
    turn = moving_average(_angle_rate(np.arctan2(ab[:, 1], ab[:, 0]), fps), max(1, int(round(0.5 * fps))))
    return np.column_stack([d, np.sin(s_a), np.cos(s_a), np.sin(s_b), np.cos(s_b), np.sin(s_ab), np.cos(s_ab),
                            np.einsum("ti,ti->t", vel, along), np.einsum("ti,ti->t", vel, across), turn])


def _angle_rate(angle: np.ndarray, fps: float) -> np.ndarray:
    """(t,) rad/s of an angle (t,) radians taken unwrapped (0 for a single frame)."""
    angle = np.unwrap(angle)
    return np.gradient(angle) * fps if len(angle) > 1 else np.zeros_like(angle)


def style_features(char: np.ndarray, cam: np.ndarray, fps: float = 24.0) -> np.ndarray:
    """(t, N_STYLE) what a camera does with its characters, for the gate: derived from (t, 10) character and (t, 8)
    camera features alone, so any reference (a stage, a clip) has them.

    Columns: sin and cos of the camera's bearing from A less A's shoulder angle (constant for a camera
    that keeps an angle to A's facing: the relative track's offset), the camera's turn about the pair in
    the world (rad/s: the bearing's rate plus the line AB's, smoothed over half a second: an orbit's
    speed), and the pair's velocity toward the camera and across its bearing (m/s: a side track's is all
    across). Each is one easy sum of the gate's inputs, but one an LSTM of the gate's size does not learn
    to form: trained on the 18 features alone, its expert mix carries the signs of an offset and an orbit
    speed, hardly their sizes. A model trained with config ``gate_style`` reads them (the shipped one does
    not: see the camera researcher's guide).
    """
    from .smoothing import moving_average

    char, cam = np.asarray(char, dtype=np.float64), np.asarray(cam, dtype=np.float64)
    bearing = np.arctan2(cam[:, U.start + 1], cam[:, U.start])      # in the pair's frame, from AB
    s_a = np.arctan2(char[:, 1], char[:, 2])
    turn = moving_average(_angle_rate(bearing, fps) + char[:, 9], max(1, int(round(0.5 * fps))))
    c, s = np.cos(bearing), np.sin(bearing)
    return np.column_stack([np.sin(bearing - s_a), np.cos(bearing - s_a), turn,
                            char[:, 7] * c + char[:, 8] * s, -char[:, 7] * s + char[:, 8] * c])


def camera_features(p_a, p_b, theta, phi, span) -> np.ndarray:
    """(t, 8) float64 camera features (see the module).

    Parameters
    ----------
    p_a, p_b : (t, 2) float
        Screen positions of the heads, NDC.
    theta, phi : (t,) float
        Toric angles, radians.
    span : (t,) float
        Metres the frame's height covers at A's distance (:func:`frame_span`).
    """
    p_a, p_b = np.asarray(p_a, dtype=np.float64), np.asarray(p_b, dtype=np.float64)
    half, phi = 0.5 * np.asarray(theta, dtype=np.float64), np.asarray(phi, dtype=np.float64)
    return np.column_stack([p_a, p_b, np.cos(half), np.sin(half) * np.cos(phi), np.sin(half) * np.sin(phi),
                            np.log(np.asarray(span, dtype=np.float64))])


def frame_span(eye, head, fov_x, aspect: float) -> np.ndarray:
    """(t,) metres the frame's height covers at the distance from ``eye`` to ``head`` ((t, 3) each)."""
    from .behaviors import fov_y

    dist = np.linalg.norm(np.asarray(eye, dtype=np.float64) - np.asarray(head, dtype=np.float64), axis=-1)
    return 2.0 * dist * np.tan(0.5 * fov_y(np.asarray(fov_x, dtype=np.float64), aspect))


def camera_angles(cam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(theta, phi), each (t,), of camera features' direction (normalised first; no range clipping)."""
    u = np.asarray(cam, dtype=np.float64)[:, U]
    u = u / np.maximum(np.linalg.norm(u, axis=1, keepdims=True), 1e-12)
    return 2.0 * np.arctan2(np.hypot(u[:, 1], u[:, 2]), u[:, 0]), np.arctan2(u[:, 2], u[:, 1])


def turned(cam: np.ndarray) -> float:
    """Degrees the direction from A to the camera travels over (t, 8) camera features (an orbit's turn)."""
    u = np.asarray(cam, dtype=np.float64)[:, U]
    u = u / np.linalg.norm(u, axis=1, keepdims=True)
    return float(np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", u[1:], u[:-1]), -1.0, 1.0))).sum())


def poses_of_features(cam: np.ndarray, heads_a, heads_b, fov_x: float, aspect: float) -> np.ndarray:
    """(t, 4, 4) level cameras built from (t, 8) camera features filming heads ``heads_a``, ``heads_b`` ((t, 3)).

    The eye is where :func:`eyes_of_features` puts it; the camera turns
    without roll to put the two heads either side of the centre, their
    midpoint at the predicted heads' mean height (:func:`level_camera`).
    Distance and roll are so bounded by construction (see the module); the
    screen positions are what this pose gives, which the predicted pA.x,
    pB.x only approximate.
    """
    eye = eyes_of_features(cam, heads_a, heads_b, fov_x, aspect)
    return level_camera(eye, heads_a, heads_b, screen_height(cam), fov_x, aspect)


def eyes_of_features(cam: np.ndarray, heads_a, heads_b, fov_x: float, aspect: float) -> np.ndarray:
    """(t, 3) camera positions of (t, 8) camera features: A plus the span's distance along the direction u
    (in the pair's toric frame)."""
    from .behaviors import fov_y
    from .toric import axes

    cam = np.asarray(cam, dtype=np.float64)
    heads_a, heads_b = np.asarray(heads_a, dtype=np.float64), np.asarray(heads_b, dtype=np.float64)
    x, y, z, _ = axes(heads_a, heads_b, np.array([0.0, 0.0, 1.0]))
    u = cam[:, U] / np.maximum(np.linalg.norm(cam[:, U], axis=1, keepdims=True), 1e-12)
    direction = u[:, :1] * x + u[:, 1:2] * y + u[:, 2:3] * z
    dist = np.exp(cam[:, SPAN]) / (2.0 * np.tan(0.5 * fov_y(fov_x, aspect)))
    return heads_a + dist[:, None] * direction


def screen_height(cam: np.ndarray) -> np.ndarray:
    """(t,) the heads' mean screen height (NDC) of (t, 8) camera features."""
    cam = np.asarray(cam, dtype=np.float64)
    return 0.5 * (cam[:, 1] + cam[:, 3])


def level_camera(eye, heads_a, heads_b, height, fov_x: float, aspect: float, rounds: int = 4) -> np.ndarray:
    """(t, 4, 4) cameras at ``eye`` turned without roll, the heads either side of the centre and the mean of
    their screen heights at ``height`` ((t,) NDC, clipped to +-0.95): the pitch is corrected a few rounds,
    since heads at different depths do not project their mean height onto their midpoint's."""
    from .behaviors import _project, fov_y, look_without_roll

    half_y = np.tan(0.5 * fov_y(fov_x, aspect))
    want = np.arctan(np.clip(height, -0.95, 0.95) * half_y)
    above = want.copy()
    for _ in range(rounds):
        m = look_without_roll(eye, heads_a, heads_b, above)
        got = 0.5 * (_project(m, heads_a, fov_x, aspect)[:, 1] + _project(m, heads_b, fov_x, aspect)[:, 1])
        above = above + want - np.arctan(np.where(np.isfinite(got), got, 0.0) * half_y)
    return look_without_roll(eye, heads_a, heads_b, above)


# ---------------------------------------------------------------------------------- the network
def load_weights(path: str | Path, what: str):
    """A weights file (npz, no pickles), or a one-line error naming it and ``what`` it holds."""
    from ..core.errors import UsdcrowdError

    try:
        return np.load(path, allow_pickle=False)
    except (OSError, ValueError) as exc:
        raise UsdcrowdError(f"cannot read {what}'s weights: {exc}", file=str(path)) from None


def _sigmoid(x):
    return 0.5 * (1.0 + np.tanh(0.5 * x))


def _elu(x):
    return np.where(x > 0, x, np.expm1(np.minimum(x, 0.0)))


@dataclass
class Config:
    """Sizes of a trained model (stored in its weights file)."""

    step: int             # frames between the samples of the prediction windows
    past: int             # camera samples fed back
    char_past: int        # character samples up to the present (included)
    char_future: int      # character samples after it
    out: int              # camera samples predicted
    gate_step: int        # frames between the samples of the reference clip
    gate_len: int         # reference samples the gating network reads
    experts: int
    hidden: int
    gate_hidden: int
    noise: float = 0.0    # training: noise added to the past camera input (robust roll-outs)
    blind: float = 0.0    # training: share of samples shown no past camera (the gate must carry the behavior)
    reset: float = 0.0    # training: share of samples whose past camera is another clip's (a cold start)
    pair: float = 0.0     # training: share of samples gated from the same behavior filming other characters
    gate_lr: float = 1.0  # training: the gate's learning rate, a multiple of the experts'
    unroll: int = 1       # training: predictions in a row, each fed the one before (as a roll-out)
    residual: bool = False  # the network predicts the camera's change from its last sample
    u: tuple = (4, 7)     # training: the camera features' direction columns (its error in degrees)
    eta: float = 1.0      # training: weight of the predicted samples after the first (the paper's Eq. 6: 0.1)
    style: float = 0.0    # training: weight of the gate's auxiliary loss on the controllers' parameters
    gate_style: bool = False  # the gate also reads style_features (the weights hold their normalisation)
    expert_style: bool = False  # ... and so do the experts: their means over the gate's window, after n_in
    n_style: int = 0      # training: how many such labels
    unseen_motion: float = 0.0  # training: share of gate windows whose pair motion is unknown, as a clip's
    long_orbit_weight: float = 1.0  # training: loss weight of long-shot orbit windows against the others'

    @property
    def n_in(self) -> int:
        return self.past * N_CAMERA + (self.char_past + self.char_future) * N_CHARACTER


class CameraMoE:
    """The gating and prediction networks, from a weights file (numpy arrays, float32).

    Arrays (PyTorch's layouts, so a state dict saves straight into it):
    ``gate.lstm.weight_ih`` (4H, 18), ``weight_hh`` (4H, H), ``bias_ih``,
    ``bias_hh`` (4H,) with gates in the order i, f, g, o; ``gate.fc.weight``
    (m, H), ``bias`` (m,); ``experts.w1`` (m, n_in, h), ``b1`` (m, h),
    ``w2`` (m, h, h), ``b2``, ``w3`` (m, h, out * 8), ``b3``; and the
    normalisation ``char_mean``, ``char_std`` (10,), ``cam_mean``, ``cam_std``,
    ``cam_lo``, ``cam_hi`` (8,).
    """

    def __init__(self, path: str | Path = WEIGHTS):
        data = load_weights(path, "the camera model")
        self.path = str(path)
        self.config = Config(**json.loads(str(data["config"])))
        self.w = {k: data[k].astype(np.float64) for k in data.files if k not in ("config", "about")}
        self.about = json.loads(str(data["about"])) if "about" in data.files else {}

    @cached_property
    def size_bytes(self) -> int:
        return int(sum(v.size * 4 for v in self.w.values()))

    # ------------------------------------------------------------------ gating
    def gate_input(self, char: np.ndarray, cam: np.ndarray) -> np.ndarray:
        """(gate_len, 18 or 23) normalised reference features (with :func:`style_features` where the model was
        trained on them): the middle of the clip, sampled every gate_step frames."""
        c = self.config
        parts = [(char - self.w["char_mean"]) / self.w["char_std"], (cam - self.w["cam_mean"]) / self.w["cam_std"]]
        if "style_mean" in self.w:
            parts.append((style_features(char, cam) - self.w["style_mean"]) / self.w["style_std"])
        feats = np.column_stack(parts)
        idx = np.arange(c.gate_len) * c.gate_step
        start = max(0, (len(feats) - 1 - idx[-1]) // 2)
        return feats[np.clip(start + idx, 0, len(feats) - 1)]

    def gate(self, char: np.ndarray, cam: np.ndarray) -> np.ndarray:
        """(m,) expert weights (sum 1) for a reference clip's (t, 10) character and (t, 8) camera features; a
        model trained with ``expert_style`` follows them with the (N_STYLE,) normalised style its experts read
        (a mix and a style, interpolated alike between references)."""
        x = self.gate_input(char, cam)
        w = self.gate_sequence(x[None])[0]
        return np.concatenate([w, x[:, -N_STYLE:].mean(axis=0)]) if self.config.expert_style else w

    @property
    def n_experts(self) -> int:
        return int(self.w["gate.fc.bias"].shape[0])

    def mix_and_style(self, gated: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """:meth:`gate`'s output split into the (m,) expert weights and the (N_STYLE,) style the experts
        read (None for a model whose experts read no style)."""
        m = self.n_experts
        return gated[:m], (gated[m:] if self.config.expert_style else None)

    def gate_sequence(self, x: np.ndarray) -> np.ndarray:
        """(b, m) expert weights of (b, gate_len, 18) normalised sequences: the LSTM's last state, FC, softmax."""
        w = self.w
        h_size = w["gate.lstm.weight_hh"].shape[1]
        h = np.zeros((len(x), h_size))
        cell = np.zeros_like(h)
        for k in range(x.shape[1]):
            z = x[:, k] @ w["gate.lstm.weight_ih"].T + w["gate.lstm.bias_ih"] + h @ w["gate.lstm.weight_hh"].T \
                + w["gate.lstm.bias_hh"]
            i, f, g, o = np.split(z, 4, axis=1)
            cell = _sigmoid(f) * cell + _sigmoid(i) * np.tanh(g)
            h = _sigmoid(o) * np.tanh(cell)
        logits = h @ w["gate.fc.weight"].T + w["gate.fc.bias"]
        e = np.exp(logits - logits.max(axis=1, keepdims=True))
        return e / e.sum(axis=1, keepdims=True)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(8,) lowest and highest normalised camera features a roll-out may feed back: the range the
        training data spans (``cam_lo``, ``cam_hi`` in the weights), within CLIP standard deviations."""
        lo, hi = np.full(N_CAMERA, -CLIP), np.full(N_CAMERA, CLIP)
        if "cam_lo" in self.w:
            lo = np.maximum(lo, (self.w["cam_lo"] - self.w["cam_mean"]) / self.w["cam_std"])
            hi = np.minimum(hi, (self.w["cam_hi"] - self.w["cam_mean"]) / self.w["cam_std"])
        return lo, hi

    # -------------------------------------------------------------- prediction
    def blend(self, weights: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
        """The prediction network's three layers for one expert mix (:meth:`gate`): [(W (in, out), b (out,)),
        ...]; the style an ``expert_style`` model's experts read is constant over a roll-out, so it is folded
        into the first layer's bias."""
        wt = np.asarray(weights, dtype=np.float64)
        mix, style = wt[:self.n_experts], wt[self.n_experts:]
        layers = [(np.tensordot(mix, self.w[f"experts.w{k}"], 1), mix @ self.w[f"experts.b{k}"]) for k in (1, 2, 3)]
        if len(style):
            w1, b1 = layers[0]
            layers[0] = (w1[:-len(style)], b1 + style @ w1[-len(style):])
        return layers

    def predict(self, layers, x: np.ndarray) -> np.ndarray:
        """(b, out * 8) normalised camera features of the next ``out`` samples from (b, n_in) normalised inputs."""
        (w1, b1), (w2, b2), (w3, b3) = layers
        return _elu(_elu(x @ w1 + b1) @ w2 + b2) @ w3 + b3

    def predict_experts(self, weights: np.ndarray, x: np.ndarray) -> np.ndarray:
        """As :meth:`predict` with a mix per row ((b, m) weights, or (b, m + N_STYLE) as :meth:`gate` gives an
        ``expert_style`` model's): the training's form, for the tests."""
        m = self.n_experts
        out = np.concatenate([x, weights[:, m:]], axis=1)
        for k in (1, 2, 3):
            per = np.einsum("bi,mio->bmo", out, self.w[f"experts.w{k}"]) + self.w[f"experts.b{k}"][None]
            out = np.einsum("bm,bmo->bo", weights[:, :m], per)
            if k < 3:
                out = _elu(out)
        return out

    def inputs(self, char_n: np.ndarray, past_n: np.ndarray, frame: int) -> np.ndarray:
        """(n_in,) prediction input at ``frame``: normalised character features around it, camera before it.

        ``char_n`` is (t, 10) normalised, ``past_n`` (past, 8) normalised camera samples ending at ``frame``.
        """
        c = self.config
        idx = frame + np.arange(-(c.char_past - 1), c.char_future + 1) * c.step
        window = char_n[np.clip(idx, 0, len(char_n) - 1)]
        return np.concatenate([past_n.ravel(), window.ravel()])

    def rollout(self, weights: np.ndarray, char: np.ndarray, start_cam: np.ndarray | None,
                settle: int = 0) -> np.ndarray:
        """(t, 8) camera features filming characters ``char`` (t, 10) in the style of ``weights``.

        Parameters
        ----------
        weights : (m,) float
            Expert mix (:meth:`gate`).
        char : (t, 10) float
            The new scene's character features.
        start_cam : (8,) float or None
            Camera features to start from (held over the first past window);
            None starts blind, the first prediction made from the gate and
            the characters alone (a model trained with ``blind`` samples
            frames a new pair so; another pair's framing, the reference's,
            is not one for these characters).
        settle : int
            Frames rolled out before the first, on the first frame's character
            features repeated, so that the shot begins on a framing the network
            has made and mended (a blind start's first sample is no camera).

        The network predicts ``out`` samples (``out * step`` frames) at a
        time, which become the past of the next prediction; frames between
        samples are interpolated linearly. A residual model predicts them
        as changes from the last sample: the camera keeps where it is and
        the network says how it moves (an orbit's turn).
        """
        c = self.config
        layers = self.blend(weights)
        char = np.asarray(char, dtype=np.float64)
        char = np.concatenate([np.repeat(char[:1], settle, axis=0), char]) if settle > 0 else char
        char_n = (char - self.w["char_mean"]) / self.w["char_std"]
        if start_cam is None:       # blind: the past all zeros, as the training's "blind" samples
            cam_n = np.zeros(N_CAMERA)
        else:
            cam_n = np.clip((np.asarray(start_cam, dtype=np.float64) - self.w["cam_mean"]) / self.w["cam_std"],
                            -CLIP, CLIP)
        lo, hi = self.bounds()
        samples = [cam_n] * c.past
        frame, t = 0, len(char_n)
        while frame < t - 1:
            x = self.inputs(char_n, np.array(samples[-c.past:]), frame)
            # Fed back, a prediction must stay within what the network has seen, or a roll-out can diverge.
            pred = self.predict(layers, x[None])[0].reshape(c.out, N_CAMERA)
            samples.extend(np.clip(pred + samples[-1] if c.residual else pred, lo, hi))
            frame += c.out * c.step
        known = np.array(samples[c.past - 1:]) * self.w["cam_std"] + self.w["cam_mean"]
        at = np.arange(len(known)) * c.step
        out = np.column_stack([np.interp(np.arange(t), at, known[:, k]) for k in range(N_CAMERA)])
        out[:, U] /= np.maximum(np.linalg.norm(out[:, U], axis=1), 1e-9)[:, None]
        return out[max(settle, 0):]
