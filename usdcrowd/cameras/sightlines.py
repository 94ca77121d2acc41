"""What a camera really shows of the people it films: in frame, not hidden, and how large.

Seed 000's metrics call a character seen when its chest is inside the
frustum (:mod:`.metrics`). A director choosing the camera on air, and a
measure of how well a tracking camera frames its event, need more: a wall
or another person between the camera and someone hides them. Here each
(camera, person) pair is tested with sight lines to points on the person
(chest and head, then shoulders, crown and the sides: :data:`SIGHT_POINTS`,
scaled to the person's height): against the scenery's footprints (convex prisms up to their height,
as the simulation and the cameras know the scenery) and against the other
people (upright cylinders). A person is visible when any line is clear.

The test is geometric and conservative where it must choose: a person is a
body :data:`PERSON_RADIUS` in radius up to the shoulders and a head
:data:`HEAD_RADIUS` in radius up to :data:`PERSON_HEIGHT`, so an
arm or a gap between legs does not count. The id pass of a
render (:mod:`usdcrowd.groundtruth`) is the exact answer for one frame; this
is the one a whole shot's cameras can afford at every frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core import model
from .frustum import half_tangents

# Where sight lines end on a person, and how tall a person stands, metres.
CHEST_HEIGHT = 1.1
PERSON_HEIGHT = 1.7
HEAD_HEIGHT = 1.6
SHOULDER_HEIGHT = 1.45
PERSON_RADIUS = 0.25
HEAD_RADIUS = 0.12
SHOULDER_HALF_WIDTH = 0.2
CROWN_HEIGHT = 1.66
# The points sight lines end at (metres across the view, metres up, for a person PERSON_HEIGHT tall): the
# chest and the head first; then the shoulders' middle, the crown and the chest's sides, which a person
# under the frame's top, behind a wall seen from above or at a wall's edge may show alone. (Not the
# shoulders' sides: they would call a person seen whose shoulder shows beside the head of one in front.)
SIGHT_POINTS = ((0.0, CHEST_HEIGHT), (0.0, HEAD_HEIGHT), (0.0, SHOULDER_HEIGHT), (0.0, CROWN_HEIGHT),
                (-SHOULDER_HALF_WIDTH, CHEST_HEIGHT), (SHOULDER_HALF_WIDTH, CHEST_HEIGHT))
# Pair-by-occluder tests are done in chunks of about this many (memory, not speed).
_CHUNK = 500_000


@dataclass
class Prisms:
    """Scenery footprints padded to one array (degenerate closing edges repeat the first vertex).

    Attributes
    ----------
    a, b : (o, k, 2) float64
        Edge starts and ends, counter-clockwise.
    height : (o,) float64
        Tops, metres.
    bottom : (o,) float64
        Undersides (0 for scenery standing on the ground).
    """

    a: np.ndarray
    b: np.ndarray
    height: np.ndarray
    bottom: np.ndarray | None = None

    def __post_init__(self):
        if self.bottom is None:
            self.bottom = np.zeros(len(self.height))

    @classmethod
    def of(cls, obstacles: model.Obstacles, min_height: float = 0.3,
           overhead: model.Obstacles | None = None) -> "Prisms":
        """Footprints at least ``min_height`` tall (a kerb hides nobody), and raised scenery (``overhead``,
        with its undersides: an awning hides people from a camera above it)."""
        parts = [(obstacles.polygons[i], obstacles.height[i], 0.0) for i in range(len(obstacles))
                 if obstacles.height[i] >= min_height]
        if overhead is not None and len(overhead):
            under = overhead.bottom if overhead.bottom is not None else np.zeros(len(overhead))
            parts += [(overhead.polygons[i], overhead.height[i], under[i]) for i in range(len(overhead))]
        if not parts:
            return cls(np.zeros((0, 1, 2)), np.zeros((0, 1, 2)), np.zeros(0))
        k = max(len(p) for p, _, _ in parts)
        a = np.zeros((len(parts), k, 2))
        b = np.zeros((len(parts), k, 2))
        for row, (poly, _, _) in enumerate(parts):
            p = np.asarray(poly, dtype=np.float64)
            closed = np.concatenate([p, np.repeat(p[:1], k - len(p) + 1, axis=0)])
            a[row], b[row] = closed[:-1], closed[1:]
        return cls(a, b, np.array([h for _, h, _ in parts], dtype=np.float64),
                   np.array([u for _, _, u in parts], dtype=np.float64))

    def __len__(self) -> int:
        return len(self.height)

    def blocks(self, start: np.ndarray, end: np.ndarray) -> np.ndarray:
        """(m,) bool: the segment from ``start`` to ``end`` ((m, 3) each) passes through a prism.

        Cyrus-Beck clipping of each segment's ground projection against each
        convex footprint, then the segment's heights over the clipped part
        against the prism's underside and top.
        """
        m = len(start)
        out = np.zeros(m, bool)
        if m == 0 or len(self) == 0:
            return out
        start, end = np.asarray(start, dtype=np.float64), np.asarray(end, dtype=np.float64)
        # Only the (segment, prism) pairs whose boxes meet, below the prism's top, are clipped.
        lo_xy, hi_xy = np.minimum(start[:, :2], end[:, :2]), np.maximum(start[:, :2], end[:, :2])
        low_z, high_z = np.minimum(start[:, 2], end[:, 2]), np.maximum(start[:, 2], end[:, 2])
        near = ((lo_xy[:, None] <= self.box_hi[None]) & (hi_xy[:, None] >= self.box_lo[None])).all(axis=2)
        near &= (low_z[:, None] < self.height[None]) & (high_z[:, None] > self.bottom[None])
        seg, obs = np.nonzero(near)
        step = max(1, _CHUNK // self.a.shape[1])
        for lo in range(0, len(seg), step):
            sm, so = seg[lo:lo + step], obs[lo:lo + step]
            s, e = start[sm], end[sm]
            a, b = self.a[so], self.b[so]                                 # (p, k, 2)
            edge = b - a
            normal = np.stack([edge[..., 1], -edge[..., 0]], -1)        # outward for ccw
            d = (e - s)[:, None, :2]
            num = np.einsum("pki,pki->pk", s[:, None, :2] - a, normal)  # > 0: outside this edge's half-plane
            den = np.einsum("pki,pki->pk", np.broadcast_to(d, a.shape), normal)
            with np.errstate(divide="ignore", invalid="ignore"):
                t = -num / den
            entering = den < -1e-12
            leaving = den > 1e-12
            parallel_out = (~entering & ~leaving) & (num > 1e-12)
            t_in = np.maximum(np.where(entering, t, 0.0).max(axis=1), 0.0)
            t_out = np.minimum(np.where(leaving, t, 1.0).min(axis=1), 1.0)
            crosses = (t_in < t_out) & ~parallel_out.any(axis=1)
            z0, dz = s[:, 2], (e - s)[:, 2]
            low = np.minimum(z0 + t_in * dz, z0 + t_out * dz)
            high = np.maximum(z0 + t_in * dz, z0 + t_out * dz)
            hit = crosses & (low < self.height[so]) & (high > self.bottom[so])
            out[sm[hit]] = True
        return out

    @property
    def box_lo(self) -> np.ndarray:
        return np.minimum(self.a.min(axis=1), self.b.min(axis=1))

    @property
    def box_hi(self) -> np.ndarray:
        return np.maximum(self.a.max(axis=1), self.b.max(axis=1))


@dataclass
class Views:
    """How each camera shows each person at one frame.

    Attributes
    ----------
    in_frame : (c, n) bool
        A point of the person (:data:`SIGHT_POINTS`) is inside the frustum.
    visible : (c, n) bool
        With a clear sight line to one of those in frame.
    hidden_by_scenery, hidden_by_people : (c, n) bool
        In frame, every sight line blocked by the scenery (or, failing that, by people).
    height : (c, n) float64
        A person's height on screen, as a share of the frame's height (0 behind the camera).
    depth : (c, n) float64
        Metres along each camera's view axis.
    """

    in_frame: np.ndarray
    visible: np.ndarray
    hidden_by_scenery: np.ndarray
    hidden_by_people: np.ndarray
    height: np.ndarray
    depth: np.ndarray


def lens_tangents(tracks: list[model.CameraTrack], frame: int) -> tuple[np.ndarray, np.ndarray]:
    """(c,) half-angle tangents of each track's lens at sample ``frame``."""
    tx = np.array([half_tangents(t.focal_length[frame], t.horizontal_aperture, t.vertical_aperture)[0]
                   for t in tracks])
    ty = np.array([half_tangents(t.focal_length[frame], t.horizontal_aperture, t.vertical_aperture)[1]
                   for t in tracks])
    return tx, ty


def views(cam_to_world: np.ndarray, tan_x: np.ndarray, tan_y: np.ndarray, near: np.ndarray, far: np.ndarray,
          ground: np.ndarray, people: np.ndarray | None = None, prisms: Prisms | None = None,
          occluders: np.ndarray | None = None, heights: np.ndarray | None = None) -> Views:
    """Every camera's view of the ``people`` rows at one frame.

    Parameters
    ----------
    cam_to_world : (c, 4, 4) float
        Canonical metres, row vectors (the camera looks down -Z).
    tan_x, tan_y, near, far : (c,) float
        Half-angle tangents of the lens and the clipping range (metres).
    ground : (n, 3) float
        Everyone's ground position, metres, Z up.
    people : (p,) int, optional
        The rows to test (default: all).
    prisms : Prisms, optional
        The scenery (default: none).
    occluders : (n,) bool, optional
        Rows that can hide others (default: all; pass the rendered ones:
        an invisible leader hides nobody).
    heights : (n,) float, optional
        Everyone's body height, metres (default :data:`PERSON_HEIGHT`): the
        points on a person scale with it.

    Returns
    -------
    Views
        Over (c, p).
    """
    ground = np.asarray(ground, dtype=np.float64)
    rows = np.arange(len(ground)) if people is None else np.asarray(people, dtype=np.int64)
    occ_rows = np.arange(len(ground)) if occluders is None else np.flatnonzero(occluders)
    everyone = None if heights is None else np.asarray(heights, dtype=np.float64)
    tall = np.full(len(rows), PERSON_HEIGHT) if everyone is None else everyone[rows]
    c, p = len(cam_to_world), len(rows)
    eye = cam_to_world[:, 3, :3]
    right, up, back = cam_to_world[:, 0, :3], cam_to_world[:, 1, :3], cam_to_world[:, 2, :3]
    shape = (c, p)
    if c == 0 or p == 0:
        z = np.zeros(shape, bool)
        return Views(z, z.copy(), z.copy(), z.copy(), np.zeros(shape), np.zeros(shape))
    # Sideways on a person is the camera's right, levelled (a camera rolled a quarter turn has none: the
    # side points fall on the chest then).
    side = right * [1.0, 1.0, 0.0]
    side /= np.maximum(np.linalg.norm(side, axis=1, keepdims=True), 1e-9)
    lift = np.zeros((p, 3))
    lift[:, 2] = tall / PERSON_HEIGHT                             # metres up per metre of a standard person
    in_frame, visible, scenery_clear = (np.zeros(shape, bool) for _ in range(3))
    for across, h in SIGHT_POINTS:
        pts = (ground[rows] + h * lift)[None] + across * side[:, None]                 # (c, p, 3)
        d = pts - eye[:, None]
        x, y = np.einsum("cpi,ci->cp", d, right), np.einsum("cpi,ci->cp", d, up)
        z = -np.einsum("cpi,ci->cp", d, back)
        inside = (z > near[:, None]) & (z < far[:, None]) & (np.abs(x) <= tan_x[:, None] * z) & (
            np.abs(y) <= tan_y[:, None] * z)
        in_frame |= inside
        # Each point is tried only where no point before it showed the person (chest and head first).
        cam_i, who = np.nonzero(inside & ~visible)
        if not len(cam_i):
            continue
        clear = np.ones(len(cam_i), bool)
        if prisms is not None and len(prisms):
            clear = ~prisms.blocks(eye[cam_i], pts[cam_i, who])
        scenery_clear[cam_i[clear], who[clear]] = True
        seen = clear.copy()
        if clear.any():
            seen[clear] = ~_people_block(eye, right, up, back, cam_i[clear], pts[cam_i[clear], who[clear]],
                                         rows[who[clear]], ground, occ_rows, everyone)
        visible[cam_i[seen], who[seen]] = True
    by_scenery = in_frame & ~visible & ~scenery_clear
    by_people = in_frame & ~visible & ~by_scenery
    chest = ground[rows] + CHEST_HEIGHT * lift
    depth = -np.einsum("cpi,ci->cp", chest[None] - eye[:, None], back)
    with np.errstate(divide="ignore", invalid="ignore"):
        height = np.where(depth > 1e-6, tall[None] / (2.0 * tan_y[:, None] * depth), 0.0)
    return Views(in_frame, visible, by_scenery, by_people, height, depth)


def _in_the_way(eye, forward, right, target, feet, scale=1.0) -> np.ndarray:
    """Whether a person standing at ``feet`` is in the sight line from ``eye`` to ``target``.

    A person is a body up to the shoulders (:data:`PERSON_RADIUS` wide) and a
    narrower head above them: a sight line over a shoulder, between two
    heads, is clear (a packed group seen from a little above shows its
    heads). Tested where the line passes the person's axis: the line's offset
    across the view (the camera's ``right``, level for these cameras) and its
    height above their feet. Arguments are (..., 3) arrays broadcast against
    each other (``scale``, the person's height over :data:`PERSON_HEIGHT`, against
    their leading axes); the result has their broadcast shape.
    """
    def dot(a, b):
        return (a * b).sum(axis=-1)

    to_target, to_feet = target - eye, feet - eye
    tz, tx = dot(to_target, forward), dot(to_target, right)
    oz, ox = dot(to_feet, forward), dot(to_feet, right)
    along = oz / np.maximum(tz, 1e-9)
    across = np.abs(tx * along - ox)
    above = eye[..., 2] + (target[..., 2] - eye[..., 2]) * along - feet[..., 2]
    body = (above >= 0.0) & (above <= SHOULDER_HEIGHT * scale) & (across < PERSON_RADIUS)
    head = (above > SHOULDER_HEIGHT * scale) & (above <= PERSON_HEIGHT * scale) & (across < HEAD_RADIUS)
    return (oz > 0.2) & (oz < tz - PERSON_RADIUS) & (body | head)


def _people_block(eye, right, up, back, cam_i, target, owner, ground, occ_rows, tall=None) -> np.ndarray:
    """(m,) bool: another person (:func:`_in_the_way`) stands between camera ``cam_i`` and ``target`` ((m, 3));
    ``tall`` (n,) is everyone's height (default :data:`PERSON_HEIGHT`)."""
    m = len(cam_i)
    out = np.zeros(m, bool)
    if len(occ_rows) == 0:
        return out
    occ = ground[occ_rows]
    scale = 1.0 if tall is None else (np.asarray(tall, dtype=np.float64)[occ_rows] / PERSON_HEIGHT)[None]
    step = max(1, _CHUNK // len(occ_rows))
    for lo in range(0, m, step):
        ci = cam_i[lo:lo + step]
        hit = _in_the_way(eye[ci, None], -back[ci, None], right[ci, None], target[lo:lo + step, None], occ[None],
                          scale)
        hit &= occ_rows[None] != owner[lo:lo + step, None]
        out[lo:lo + step] = hit.any(axis=1)
    return out


def seen_points(eye: np.ndarray, axes3: tuple, tan_x: np.ndarray, tan_y: np.ndarray, near: np.ndarray,
                far: np.ndarray, ground: np.ndarray, owner: np.ndarray, candidates: tuple,
                prisms: Prisms | None = None) -> np.ndarray:
    """(m,) bool: each person ``owner[k]`` is in frame of camera ``k`` with a clear line to chest or head.

    A cheaper, stricter check than :func:`views` for many (camera, person)
    pairs at once (the camera agents' own check, every few frames, and seed
    000's metrics): two points only, the chest and the head of a person
    :data:`PERSON_HEIGHT` tall, so a person showing only a side or the crown
    counts as unseen here and as visible in :func:`views`. Each pair has its
    camera's eye ``(m, 3)`` and axes (right, up, forward: three (m, 3)
    arrays), lens tangents and clipping range ``(m,)``; ``ground`` (n, 3) is
    everyone's position; ``candidates`` = (pair index (q,), row (q,)) says
    who may hide whom (the caller bounds the work by choosing them).
    """
    right, up, fwd = axes3
    m = len(eye)
    out = np.zeros(m, bool)
    if m == 0:
        return out
    cand_pair, cand_row = (np.asarray(a, dtype=np.int64) for a in candidates)
    for h in (CHEST_HEIGHT, HEAD_HEIGHT):
        pts = ground[owner] + [0.0, 0.0, h]
        d = pts - eye
        z = np.einsum("mi,mi->m", d, fwd)
        inside = (z > near) & (z < far) & (np.abs(np.einsum("mi,mi->m", d, right)) <= tan_x * z) & (
            np.abs(np.einsum("mi,mi->m", d, up)) <= tan_y * z)
        test = inside & ~out
        if not test.any():
            continue
        clear = test.copy()
        k = np.flatnonzero(test)
        if prisms is not None and len(prisms):
            clear[k] &= ~prisms.blocks(eye[k], pts[k])
        use = test[cand_pair] & (cand_row != owner[cand_pair])
        pair, who = cand_pair[use], cand_row[use]
        if len(pair):
            hit = _in_the_way(eye[pair], fwd[pair], right[pair], pts[pair], ground[who])
            clear[pair[hit]] = False
        out |= clear
    return out
