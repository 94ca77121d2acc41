"""Synthetic clips for the learned camera behaviors (seed 002, section 5.3): two characters, one behavior.

Two-character motions (walking side by side or one behind the other,
standing and talking, one walking round the other, walking then stopping
to talk) are drawn at random, and each is filmed by one of the four
controllers of :mod:`usdcrowd.cameras.behaviors` with drawn parameters
(shot size, side, offset, orbit speed, reaction time), as the paper builds
its training set from parametric behaviors. Everything comes from one seed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .behaviors import BEHAVIORS, SHOT_SIZES, Behavior, behavior_track
from .moe import camera_features, character_features, frame_span

FPS = 24.0
FOV_X = 2.0 * np.arctan(18.0 / 50.0)       # the 50 mm lens of `usdcrowd frame`
ASPECT = 16.0 / 9.0
MOTIONS = ("side-by-side", "in-line", "talking", "circling", "walk-then-talk")
HELD_OUT = 1000         # a training seed plus this draws the held-out clips (never trained on)


@dataclass
class Clip:
    """One synthetic clip: features per frame and what made it."""

    character: np.ndarray      # (t, 10)
    camera: np.ndarray         # (t, 8)
    behavior: int              # index into BEHAVIORS
    shot: str
    motion: str
    heads_a: np.ndarray        # (t, 3)
    heads_b: np.ndarray
    yaw_a: np.ndarray          # (t,)
    yaw_b: np.ndarray
    params: Behavior           # the behavior with its drawn parameters


def _wrap(a):
    return (a + np.pi) % (2 * np.pi) - np.pi


def _path(rng, frames: int, speed: float, turn: float):
    """(t, 2) positions and (t,) headings of a walk at ``speed`` m/s that turns by up to ``turn`` rad/s."""
    wobble = np.cumsum(rng.normal(0.0, 1.0, frames)) / np.sqrt(frames)
    rate = turn * np.sin(np.linspace(0, rng.uniform(1, 3) * np.pi, frames) + rng.uniform(0, 6.3)) + 0.2 * turn * wobble
    heading = rng.uniform(-np.pi, np.pi) + np.cumsum(rate) / FPS
    step = speed / FPS * np.stack([np.cos(heading), np.sin(heading)], -1)
    return np.cumsum(step, axis=0) + rng.uniform(-5, 5, 2), heading


def motion(rng, kind: str, frames: int):
    """Heads (t, 3) and shoulder yaws (t,) of A and B doing ``kind`` (one of MOTIONS)."""
    t = np.arange(frames) / FPS
    h_a, h_b = rng.uniform(1.5, 1.7), rng.uniform(1.5, 1.7)
    gap = rng.uniform(0.6, 2.5)
    sway = lambda: 0.08 * np.sin(2 * np.pi * rng.uniform(0.1, 0.4) * t + rng.uniform(0, 6.3))  # noqa: E731
    if kind in ("side-by-side", "in-line"):
        pos, heading = _path(rng, frames, rng.uniform(0.6, 1.6), rng.uniform(0.0, 0.25))
        fwd = np.stack([np.cos(heading), np.sin(heading)], -1)
        offset = np.stack([-fwd[:, 1], fwd[:, 0]], -1) if kind == "side-by-side" else -fwd
        a, b = pos, pos + gap * offset * rng.choice([-1.0, 1.0])
        ya, yb = heading + sway(), heading + sway()
    elif kind == "talking":
        centre, angle = rng.uniform(-5, 5, 2), rng.uniform(-np.pi, np.pi)
        drift = 0.2 * np.sin(2 * np.pi * 0.05 * t)
        d = np.stack([np.cos(angle + drift), np.sin(angle + drift)], -1)
        a, b = centre - 0.5 * gap * d, centre + 0.5 * gap * d
        toward = np.arctan2(d[:, 1], d[:, 0])
        ya, yb = toward + 2 * sway(), toward + np.pi + 2 * sway()
    elif kind == "circling":
        a = np.tile(rng.uniform(-5, 5, 2), (frames, 1))
        w = rng.choice([-1.0, 1.0]) * rng.uniform(0.15, 0.5)
        ang = rng.uniform(-np.pi, np.pi) + w * t
        b = a + gap * np.stack([np.cos(ang), np.sin(ang)], -1)
        toward = np.arctan2(*(b - a).T[::-1])
        ya, yb = toward + sway(), ang + np.sign(w) * np.pi / 2 + sway()
    else:                                            # walk side by side, then stop and face each other
        ha, hb, ya, yb = motion(rng, "side-by-side", frames)
        stop = int(frames * rng.uniform(0.3, 0.6))
        ha[stop:], hb[stop:] = ha[stop], hb[stop]
        toward = np.arctan2(hb[stop, 1] - ha[stop, 1], hb[stop, 0] - ha[stop, 0])
        k = np.clip((np.arange(frames) - stop) / FPS, 0.0, 1.0)        # a second to turn
        after = np.arange(frames) >= stop
        ya = np.where(after, ya[stop] + k * _wrap(toward - ya[stop]), ya)
        yb = np.where(after, yb[stop] + k * _wrap(toward + np.pi - yb[stop]), yb)
        return ha, hb, ya, yb
    return (np.column_stack([a, np.full(frames, h_a)]), np.column_stack([b, np.full(frames, h_b)]), ya, yb)


def draw_behavior(rng, name: str, shot: str | None = None) -> Behavior:
    """A behavior with drawn parameters (the paper's "regular sampling of the behaviors parameters")."""
    return Behavior(name, shot or str(rng.choice(list(SHOT_SIZES))), side=int(rng.choice([-1, 1])),
                    offset=float(rng.uniform(20, 60) * rng.choice([-1, 1])),
                    orbit_speed=float(rng.uniform(8, 25) * rng.choice([-1, 1])),
                    react=float(rng.uniform(0.5, 1.5)))


def make_clip(rng, behavior_index: int, frames: int = 480, kind: str | None = None,
              shot: str | None = None) -> Clip:
    """One clip: a drawn motion filmed by a drawn behavior of the given kind."""
    kind = kind or str(rng.choice(MOTIONS))
    ha, hb, ya, yb = motion(rng, kind, frames)
    behavior = draw_behavior(rng, BEHAVIORS[behavior_index], shot)
    times = np.arange(1, frames + 1, dtype=np.float64)
    cam = track_features(behavior_track(behavior, times, FPS, ha, hb, ya, yb, FOV_X, ASPECT), ha)
    return Clip(character_features(ha, hb, ya, yb, FPS), cam, behavior_index, behavior.shot, kind, ha, hb, ya, yb,
                behavior)


def track_features(track, heads_a) -> np.ndarray:
    """(t, 8) camera features of a controller's BehaviorTrack filming A's heads ``heads_a`` (t, 3)."""
    return camera_features(track.p_a, track.p_b, track.theta, track.phi,
                           frame_span(track.cam_to_world[:, 3, :3], heads_a, FOV_X, ASPECT))


def refilm_track(clip: Clip, behavior: Behavior):
    """The BehaviorTrack of ``behavior`` filming the clip's characters (the truth a retargeting aims at)."""
    times = np.arange(1, len(clip.yaw_a) + 1, dtype=np.float64)
    return behavior_track(behavior, times, FPS, clip.heads_a, clip.heads_b, clip.yaw_a, clip.yaw_b, FOV_X, ASPECT)


def refilm(clip: Clip, behavior: Behavior) -> np.ndarray:
    """(t, 8) camera features of ``behavior`` filming the clip's characters."""
    return track_features(refilm_track(clip, behavior), clip.heads_a)


def make_clips(seed: int, per_behavior: int, frames: int = 480) -> list[Clip]:
    """``per_behavior`` clips of each behavior, every shot size and motion in turn."""
    rng = np.random.default_rng(seed)
    clips = []
    for k in range(per_behavior):
        for b in range(len(BEHAVIORS)):
            clips.append(make_clip(rng, b, frames, kind=MOTIONS[(k + b) % len(MOTIONS)],
                                   shot=list(SHOT_SIZES)[k % len(SHOT_SIZES)]))
    return clips


def held_out_clips(per_behavior: int, seed: int = 0, frames: int = 480) -> list[Clip]:
    """The clips held out from a model trained with ``seed``: its evaluation's, the tests' and the figures'."""
    return make_clips(seed + HELD_OUT, per_behavior, frames)
