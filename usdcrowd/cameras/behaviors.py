"""Seed 002's four camera behaviors (appendix D) in three shot sizes, as controllers in toric space.

A behavior says where the camera stands relative to two characters A and B
(A is the main character) from what they do; the shot size says how far,
from the size a character should have on screen. Per frame:

1. the behavior gives a direction ``u`` (azimuth and elevation) from an
   anchor point: the midpoint of the two heads, or A's head for the
   relative track;
2. the shot size gives the distance ``D`` along it, so the frame's height
   covers ``span`` metres at that distance (:data:`SHOT_SIZES`);
3. the camera position is written in A's toric coordinates: theta is twice
   the angle at A between AB and A-to-camera, and phi is the turn about AB.
   Where the direction comes within MIN_BETA of the line AB the camera
   cranes up over it (:func:`_above_the_line`), so that neither character
   hides the other. Where the two heads would lie
   further apart on screen than ``MAX_SPREAD``, the camera moves back along
   its ray from A until they fit (the framing angle alpha shrinks, theta and
   phi stay): both characters are always on screen;
4. where scenery stands between the anchor and that position, the camera
   comes in front of it (:func:`clear_of_obstacles`);
5. the camera turns, without roll, to put the two heads as far left as right
   of the centre, their midpoint on the shot size's head line (``head_y``,
   in normalised device coordinates).

The screen positions pA, pB of the result are exact projections, so
(pA, pB, theta, phi) rebuild the pose through
:func:`usdcrowd.cameras.toric.toric_to_poses` exactly.

Behaviors (appendix D):

direct-track
    In front of the pair: the direction both characters face on average, so
    their gaze toward the camera stays steady. Where they face each other
    (the average is short) the camera moves to the side ``side`` of AB.
relative-track
    At a fixed angle ``offset`` from A's shoulders, anchored on A: A is seen
    from the same side whatever B does (puts the emphasis on A).
side-track
    Perpendicular to the pair's direction of travel, on side ``side`` (+1
    left of travel, -1 right), the framing constant. While they stand still
    the last direction is kept.
orbit
    Around the heads' midpoint at ``orbit_speed`` degrees per second,
    starting on side ``side`` of AB.

Directions are smoothed over ``react`` seconds (three passes of a moving
average on the unwrapped azimuth), the time a camera operator takes to
follow; section 7.2's smoothing of the final track is a separate option
(:func:`usdcrowd.cameras.smoothing.smooth_track`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .smoothing import moving_average, rotation_from_ypr
from .toric import angles_at_a, axes

BEHAVIORS = ("direct-track", "relative-track", "side-track", "orbit")
MIN_BETA = np.radians(15.0)        # nearer the line AB one character hides the other
MAX_SPREAD = 0.7                   # the heads stay within +-0.7 of the frame's half-width
MIN_SPREAD = 0.02                  # in NDC: two heads in line still get distinct screen positions
OBSTACLE_MARGIN = 0.3             # metres a camera keeps in front of a wall it would stand behind
STILL_SPEED = 0.2                  # m/s: slower and the pair has no direction of travel
FACING_EACH_OTHER = 0.5            # |mean facing| below this: the pair faces each other (or apart)


@dataclass(frozen=True)
class ShotSize:
    """How large the main character is on screen.

    Attributes
    ----------
    span : float
        Metres of the character the frame's height covers at the camera's
        distance: close-up 0.7 (head and shoulders; a 1.75 m person is 2.5
        frame heights tall), medium 1.3 (from the waist up; 1.35 frame
        heights), long 3.0 (the whole body in 58 % of the frame's height).
    head_y : float
        Height of the heads' midpoint on screen, NDC (-1 bottom, 1 top).
    elevation : float
        Degrees the camera looks down from above the anchor's height.
    """

    name: str
    span: float
    head_y: float
    elevation: float


SHOT_SIZES = {s.name: s for s in (ShotSize("close-up", 0.7, 0.45, 0.0), ShotSize("medium", 1.3, 0.5, 5.0),
                                  ShotSize("long", 3.0, 0.6, 12.0))}


@dataclass(frozen=True)
class Behavior:
    """A behavior and its parameters (see the module).

    Attributes
    ----------
    name : str
        One of :data:`BEHAVIORS`.
    shot : str
        A key of :data:`SHOT_SIZES`.
    side : int
        +1 or -1: which side of the pair (direct track facing each other,
        side track, orbit's start).
    offset : float
        Relative track: degrees from A's facing to the camera (positive: to
        A's left).
    orbit_speed : float
        Degrees per second, positive counter-clockwise seen from above.
    react : float
        Seconds over which the direction is smoothed.
    """

    name: str
    shot: str = "medium"
    side: int = 1
    offset: float = 35.0
    orbit_speed: float = 15.0
    react: float = 1.0

    def __post_init__(self):
        if self.name not in BEHAVIORS:
            raise ValueError(f"unknown behavior {self.name!r} (one of {', '.join(BEHAVIORS)})")
        if self.shot not in SHOT_SIZES:
            raise ValueError(f"unknown shot size {self.shot!r} (one of {', '.join(SHOT_SIZES)})")
        if self.side not in (1, -1):
            raise ValueError(f"side must be +1 or -1, not {self.side!r}")


@dataclass
class BehaviorTrack:
    """A behavior's camera over ``t`` frames, with its toric coordinates.

    Attributes
    ----------
    cam_to_world : (t, 4, 4) float64
        Row-vector camera-to-world matrices, metres.
    p_a, p_b : (t, 2) float64
        Screen positions of A's and B's heads (NDC).
    theta, phi : (t,) float64
        Toric angles about A and B, radians.
    distance : (t,) float64
        Camera to anchor, metres (larger than the shot size asks where the
        two heads had to be brought closer on screen).
    """

    cam_to_world: np.ndarray
    p_a: np.ndarray
    p_b: np.ndarray
    theta: np.ndarray
    phi: np.ndarray
    distance: np.ndarray


def fov_y(fov_x: float, aspect: float) -> float:
    """Vertical field of view (radians) of a horizontal one and an aspect (width / height)."""
    return 2.0 * np.arctan(np.tan(0.5 * fov_x) / aspect)


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.divide(v, n, out=np.zeros_like(v), where=n > 0)


def _smooth_angle(angle: np.ndarray, frames: int) -> np.ndarray:
    """Three passes of a moving average on the unwrapped angle (a turn through +-pi stays a turn)."""
    a = np.unwrap(angle)
    for _ in range(3):
        a = moving_average(a, frames)
    return a


def _azimuth(behavior: Behavior, times: np.ndarray, fps: float, heads_a, heads_b, yaw_a, yaw_b) -> np.ndarray:
    """(t,) world azimuth of the direction from the anchor to the camera, radians, before smoothing."""
    ab = (heads_b - heads_a)[:, :2]
    left = _unit(np.stack([-ab[:, 1], ab[:, 0]], -1))        # up x AB: the toric phi = 0 side
    side = behavior.side * left
    if behavior.name == "direct-track":
        facing = np.stack([np.cos(yaw_a) + np.cos(yaw_b), np.sin(yaw_a) + np.sin(yaw_b)], -1) / 2
        strength = np.linalg.norm(facing, axis=-1, keepdims=True)
        # Facing each other: fade to the side of AB, continuously.
        w = np.clip(1.0 - strength / FACING_EACH_OTHER, 0.0, 1.0)
        v = (1.0 - w) * _unit(facing) + w * side
        return np.arctan2(v[:, 1], v[:, 0])
    if behavior.name == "relative-track":
        return np.asarray(yaw_a) + np.radians(behavior.offset)
    if behavior.name == "side-track":
        mid = 0.5 * (heads_a + heads_b)[:, :2]
        vel = np.gradient(mid, axis=0) * fps if len(mid) > 1 else np.zeros_like(mid)
        k = max(1, int(round(behavior.react * fps)))
        for _ in range(3):
            vel = moving_average(vel, k)
        speed = np.linalg.norm(vel, axis=-1)
        moving = speed > STILL_SPEED
        # Hold the last direction of travel while still; before any, AB's side stands in for it.
        travel = np.where(moving[:, None], _unit(vel), np.nan)
        idx = np.where(moving, np.arange(len(moving)), -1)
        idx = np.maximum.accumulate(idx)
        held = np.where((idx >= 0)[:, None], travel[np.maximum(idx, 0)], np.stack([left[:, 1], -left[:, 0]], -1))
        perp = behavior.side * np.stack([-held[:, 1], held[:, 0]], -1)
        return np.arctan2(perp[:, 1], perp[:, 0])
    # orbit
    start = np.arctan2(side[0, 1], side[0, 0])
    return start + np.radians(behavior.orbit_speed) * (times - times[0]) / fps


def behavior_track(behavior: Behavior, times, fps: float, heads_a, heads_b, yaw_a, yaw_b,
                   fov_x: float, aspect: float, obstacles=None) -> BehaviorTrack:
    """The camera of ``behavior`` filming A and B.

    Parameters
    ----------
    behavior : Behavior
    times : (t,) float
        Time codes.
    fps : float
        Time codes per second.
    heads_a, heads_b : (t, 3) float
        Head points of A (the main character) and B, metres, Z up.
    yaw_a, yaw_b : (t,) float
        Their shoulders' facing in the world, radians.
    fov_x, aspect : float
        Horizontal field of view (radians) and width / height of the image.
    obstacles : Obstacles, optional
        Scenery footprints: a camera that would stand behind one (seen from
        the anchor) comes in front of it, OBSTACLE_MARGIN metres clear.

    Returns
    -------
    BehaviorTrack
    """
    times = np.asarray(times, dtype=np.float64)
    heads_a, heads_b = (np.asarray(v, dtype=np.float64).reshape(-1, 3) for v in (heads_a, heads_b))
    yaw_a, yaw_b = (np.asarray(v, dtype=np.float64).reshape(-1) for v in (yaw_a, yaw_b))
    size = SHOT_SIZES[behavior.shot]
    half_y = np.tan(0.5 * fov_y(fov_x, aspect))
    distance = size.span / (2.0 * half_y)

    psi = _azimuth(behavior, times, fps, heads_a, heads_b, yaw_a, yaw_b)
    psi = _smooth_angle(psi, max(1, int(round(behavior.react * fps))))
    elev = np.radians(size.elevation)
    u = np.stack([np.cos(elev) * np.cos(psi), np.cos(elev) * np.sin(psi), np.full_like(psi, np.sin(elev))], -1)
    anchor = heads_a if behavior.name == "relative-track" else 0.5 * (heads_a + heads_b)
    wanted = anchor + distance * u

    # A's toric coordinates of the wanted position: beta (theta / 2), phi and the distance AC.
    x, y, z, d = axes(heads_a, heads_b, np.array([0.0, 0.0, 1.0]))
    ac_vec = _above_the_line(wanted - heads_a, x, y, z)
    beta, phi = angles_at_a(ac_vec, x, y, z)
    ac = np.linalg.norm(ac_vec, axis=-1)
    # The angle at C of triangle ABC, then its largest value with both heads within MAX_SPREAD.
    alpha = np.arctan2(d * np.sin(beta), ac - d * np.cos(beta))
    t_x = np.tan(0.5 * fov_x)
    k = np.sqrt(1.0 + (size.head_y * half_y) ** 2)
    spread = np.clip(k * np.tan(0.5 * alpha) / t_x, MIN_SPREAD, MAX_SPREAD)
    alpha = 2.0 * np.arctan(spread * t_x / k)
    ac = d * np.sin(alpha + beta) / np.sin(alpha)                  # law of sines: the camera moves along its ray
    direction = (np.cos(beta)[:, None] * x
                 + np.sin(beta)[:, None] * (np.cos(phi)[:, None] * y + np.sin(phi)[:, None] * z))
    eye = heads_a + ac[:, None] * direction
    if obstacles is not None and len(obstacles):
        eye = clear_of_obstacles(anchor, eye, obstacles)

    cam = look_without_roll(eye, heads_a, heads_b, np.arctan(size.head_y * half_y))
    p_a, p_b = (_project(cam, h, fov_x, aspect) for h in (heads_a, heads_b))
    # The toric angles of the camera as placed (exact: (pA, pB, theta, phi) rebuild the pose).
    beta, phi = angles_at_a(eye - heads_a, x, y, z)
    return BehaviorTrack(cam, p_a, p_b, 2.0 * beta, phi, np.linalg.norm(eye - anchor, axis=-1))


def clear_of_obstacles(anchor: np.ndarray, eye: np.ndarray, obstacles, margin: float = None,
                       chunk: int = 2048) -> np.ndarray:
    """Cameras brought in along their line from ``anchor`` to stand in front of any obstacle on it.

    Parameters
    ----------
    anchor, eye : (t, 3) float
        What the camera looks at, and where it would stand, metres.
    obstacles : Obstacles
        Convex footprints with heights; a footprint edge crossed below its
        obstacle's height blocks the line.

    Returns
    -------
    (t, 3) float64
        ``eye``, or the point ``margin`` metres before the first blocking edge.
    """
    margin = OBSTACLE_MARGIN if margin is None else margin
    seg = obstacles.segments
    heights = np.concatenate([np.full(len(p), h) for p, h in zip(obstacles.polygons, obstacles.height)])
    e0, f = seg[:, 0], seg[:, 1] - seg[:, 0]                          # (s, 2)
    out = np.array(eye, dtype=np.float64)
    for lo in range(0, len(eye), chunk):
        p, q = anchor[lo:lo + chunk], eye[lo:lo + chunk]
        d = (q - p)[:, :2]
        w = e0[None] - p[:, None, :2]                                  # (t, s, 2)
        denom = d[:, None, 0] * f[None, :, 1] - d[:, None, 1] * f[None, :, 0]
        with np.errstate(divide="ignore", invalid="ignore"):
            u = (w[..., 0] * f[None, :, 1] - w[..., 1] * f[None, :, 0]) / denom
            v = (w[..., 0] * d[:, None, 1] - w[..., 1] * d[:, None, 0]) / denom
            z = p[:, None, 2] + u * (q - p)[:, None, 2]
        hit = (u > 0) & (u < 1) & (v >= 0) & (v <= 1) & (z < heights[None])
        first = np.where(hit, u, np.inf).min(axis=1)
        blocked = np.isfinite(first)
        length = np.linalg.norm(q - p, axis=1)
        keep = np.clip(first * length - margin, 0.0, None) / np.where(length > 0, length, 1.0)
        out[lo:lo + chunk][blocked] = p[blocked] + keep[blocked, None] * (q - p)[blocked]
    return out


def _above_the_line(ac: np.ndarray, x: np.ndarray, y: np.ndarray, z: np.ndarray) -> np.ndarray:
    """A-to-camera vectors ``ac`` raised where they come within MIN_BETA of the line AB, so that one
    character does not hide the other: the camera cranes up over the line (continuously, so an
    orbit passes over it without a jump), its distance to A unchanged.

    ``x`` runs along AB, ``y`` and ``z`` across it (``z`` up), per frame (toric axes).
    """
    ax, ay, az = (np.einsum("ti,ti->t", ac, e) for e in (x, y, z))
    # Height across AB that keeps MIN_BETA: tan(MIN_BETA) |ax| on the line, easing (C1) to none at twice
    # that distance to the side; (1 - u^2)^2 keeps sqrt(ay^2 + needed^2) >= tan(MIN_BETA) |ax| throughout.
    reach = np.tan(MIN_BETA) * np.abs(ax)
    u = np.clip(np.abs(ay) / np.maximum(2.0 * reach, 1e-12), 0.0, 1.0)
    az = np.maximum(az, reach * (1.0 - u * u) ** 2)
    out = ax[:, None] * x + ay[:, None] * y + az[:, None] * z
    return out * (np.linalg.norm(ac, axis=-1) / np.linalg.norm(out, axis=-1))[:, None]


def look_without_roll(eye: np.ndarray, a: np.ndarray, b: np.ndarray, above) -> np.ndarray:
    """(t, 4, 4) level cameras at ``eye`` ((t, 3) float) that see A and B ((t, 3) float) either side of
    the screen's centre, their midpoint ``above`` radians (float, or (t,) float) above it."""
    to_a, to_b = a - eye, b - eye
    # The horizontal bisector of the two directions: the heads are as far left as right of the centre.
    bis = _unit(to_a[:, :2]) + _unit(to_b[:, :2])
    yaw = np.arctan2(bis[:, 1], bis[:, 0])
    to = 0.5 * (to_a + to_b)
    pitch = np.arctan2(to[:, 2], np.hypot(to[:, 0], to[:, 1])) - above
    m = np.zeros((len(eye), 4, 4))
    m[:, :3, :3] = rotation_from_ypr(np.stack([yaw, pitch, np.zeros_like(yaw)], -1))
    m[:, 3, :3] = eye
    m[:, 3, 3] = 1.0
    return m


def _project(cam_to_world: np.ndarray, points: np.ndarray, fov_x: float, aspect: float) -> np.ndarray:
    """(t, 2) NDC of one point per frame (module conventions of :mod:`usdcrowd.cameras.toric`)."""
    rel = points - cam_to_world[:, 3, :3]
    c = np.einsum("tj,tij->ti", rel, cam_to_world[:, :3, :3])      # camera-space coordinates
    t = np.tan(0.5 * fov_x)
    return np.stack([c[:, 0] / (-c[:, 2] * t), c[:, 1] * aspect / (-c[:, 2] * t)], -1)
