"""Event detection (seed 000, section 4.1) on hand-built trajectories with known answers.

Every scene is a set of (t, n, 2) planar tracks built with numpy at 24 fps;
velocities are their time derivative and headings follow the velocity unless
given. The truth is known by construction.
"""

from __future__ import annotations

import numpy as np
import pytest

from usdcrowd.core import model
from usdcrowd.events import EventDetector, EventParams, detect_events, find_groups, find_interaction_pairs
from usdcrowd.events.groups import fill_gaps

FPS = 24.0
DT = 1.0 / FPS
INTERACTION = model.code(model.EVENT_KINDS, "interaction")
GROUP_MOTION = model.code(model.EVENT_KINDS, "groupMotion")


# --- building scenes --------------------------------------------------------

def frames_from(xy: np.ndarray, heading: np.ndarray | None = None, velocity: np.ndarray | None = None,
                t0: float = 1.0) -> model.CrowdFrames:
    """CrowdFrames from (t, n, 2) tracks.

    Velocity is the backward difference (zero on the first frame), so an
    agent that stops has zero velocity from the first frame it stands still;
    where ``velocity`` (t, n, 2) is given and finite it is used instead.
    Where ``heading`` is NaN (or not given) the heading follows the velocity,
    and keeps its last value while the agent stands.
    """
    t, n, _ = xy.shape
    vel = np.zeros_like(xy)
    vel[1:] = (xy[1:] - xy[:-1]) / DT
    if velocity is not None:
        vel = np.where(np.isfinite(velocity), velocity, vel)
    speed = np.linalg.norm(vel, axis=2)
    head = np.full((t, n), np.nan) if heading is None else np.array(heading, np.float64)
    auto = np.where(speed > 0.05, np.arctan2(vel[..., 1], vel[..., 0]), np.nan)
    head = np.where(np.isnan(head), auto, head)
    # Hold the last heading while standing (forward fill), 0 before any.
    idx = np.where(np.isnan(head), 0, np.arange(t)[:, None])
    np.maximum.accumulate(idx, axis=0, out=idx)
    head = np.nan_to_num(head[idx, np.arange(n)[None]])
    pos = np.concatenate([xy, np.zeros((t, n, 1))], axis=2)
    return model.CrowdFrames(
        times=t0 + np.arange(t, dtype=np.float64), position=pos.astype(np.float32),
        heading=head.astype(np.float32), velocity=vel.astype(np.float32),
        behavior=np.zeros((t, n), np.int8), anim_class=np.zeros((t, n), np.int8),
        anim_phase=np.zeros((t, n), np.float32), health=np.zeros((t, n), np.int8),
        look_at=np.full((t, n, 3), np.nan, np.float32), path_method=np.zeros(n, np.int8))


def concat(*scenes: np.ndarray) -> np.ndarray:
    """Stack (t, n_i, 2) tracks side by side into (t, sum n_i, 2)."""
    return np.concatenate(scenes, axis=1)


def walk(start, velocity_per_frame) -> np.ndarray:
    """(t, 2) track from a start point and a (t, 2) velocity (m/s) per frame (first row unused)."""
    v = np.asarray(velocity_per_frame, np.float64)
    steps = np.concatenate([np.zeros((1, 2)), v[1:] * DT])
    return np.asarray(start, np.float64) + np.cumsum(steps, axis=0)


def formation(rows: int, cols: int, spacing: float, rng, jitter: float = 0.1) -> np.ndarray:
    """(rows * cols, 2) offsets of a rectangular formation centred on 0: rows along x, columns along y."""
    ij = np.stack(np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij"), axis=-1).reshape(-1, 2)
    off = (ij - (np.array([rows, cols]) - 1) / 2) * spacing
    return off + rng.uniform(-jitter, jitter, off.shape)


def platoon(t: int, center0, offsets: np.ndarray, velocity: np.ndarray, rng, sway: float = 0.05) -> np.ndarray:
    """(t, k, 2) tracks of a formation whose centre moves with ``velocity`` (t, 2), m/s.

    Each member sways a little about its place (a smooth random offset).
    """
    c = walk(center0, velocity)
    k = len(offsets)
    phase = rng.uniform(0, 2 * np.pi, (k, 2))
    tt = np.arange(t)[:, None, None] * DT
    wobble = sway * np.sin(2 * np.pi * 0.5 * tt + phase[None])
    return c[:, None, :] + offsets[None] + wobble


def wanderers(t: int, k: int, half: float, rng, speed=(0.8, 1.6), turn: float = 0.6):
    """Agents walking at random headings that drift (random walk of ``turn``
    rad/sqrt(s)) on a square of half-side ``half`` that wraps round (a torus:
    no wall herds them into a common direction).

    Returns (t, k, 2) positions and (t, k, 2) velocities, m/s.
    """
    xy = np.empty((t, k, 2))
    vel = np.empty((t, k, 2))
    xy[0] = rng.uniform(-half, half, (k, 2))
    head = rng.uniform(-np.pi, np.pi, k)
    s = rng.uniform(*speed, k)
    vel[0] = s[:, None] * np.stack([np.cos(head), np.sin(head)], axis=1)
    for i in range(1, t):
        head = head + rng.normal(0, turn * np.sqrt(DT), k)
        vel[i] = s[:, None] * np.stack([np.cos(head), np.sin(head)], axis=1)
        xy[i] = (xy[i - 1] + DT * vel[i] + half) % (2 * half) - half
    return xy, vel


def const_velocity(t: int, v, t_from: int = 0, t_to: int | None = None) -> np.ndarray:
    """(t, 2) velocity: ``v`` on frames [t_from, t_to), zero elsewhere."""
    out = np.zeros((t, 2))
    out[t_from:t_to] = v
    return out


def run(xy, heading=None, ctype=None, visible=None, params=None, chunk: int | None = None,
        velocity=None) -> model.EventTable:
    """Detect the events of a scene, whole or in chunks of ``chunk`` frames."""
    fr = frames_from(xy, heading, velocity)
    n = xy.shape[1]
    ctype = np.zeros(n, np.int8) if ctype is None else ctype
    visible = np.ones(n, bool) if visible is None else visible
    if chunk is None:
        return detect_events(fr, ctype, visible, FPS, params)
    det = EventDetector(ctype, visible, FPS, params)
    for a in range(0, len(fr.times), chunk):
        det.feed(slice_frames(fr, a, a + chunk))
    return det.finish()


def slice_frames(fr: model.CrowdFrames, a: int, b: int) -> model.CrowdFrames:
    return model.CrowdFrames(
        times=fr.times[a:b], position=fr.position[a:b], heading=fr.heading[a:b], velocity=fr.velocity[a:b],
        behavior=fr.behavior[a:b], anim_class=fr.anim_class[a:b], anim_phase=fr.anim_phase[a:b],
        health=fr.health[a:b], look_at=fr.look_at[a:b], path_method=fr.path_method)


def of_kind(table: model.EventTable, kind: int) -> list[model.Event]:
    return [e for e in table if e.kind == kind]


def frame_of(time: float) -> int:
    """Frame index of a time code (scenes start at time code 1)."""
    return int(round(time - 1.0))


def member_scores(event: model.Event, truth: np.ndarray, frames: slice | None = None):
    """Per sample of ``event``: precision and recall of its active members against ``truth`` rows."""
    truth = set(int(a) for a in truth)
    prec, rec = [], []
    for i in range(len(event.times))[frames or slice(None)]:
        got = set(int(a) for a in event.members[event.active[i]])
        hit = len(got & truth)
        prec.append(hit / max(len(got), 1))
        rec.append(hit / len(truth))
    return np.array(prec), np.array(rec)


# --- (a) one-to-one interactions -------------------------------------------

def interaction_scene(rng):
    """Two walk toward each other, stand face to face 4 s, walk away; plus
    decoys: a back-to-back pair, a pair passing by, a side-by-side pair.

    Returns the tracks, the headings and the truth (first, last standing frame).
    """
    t = int(12 * FPS)
    arrive, leave = int(3 * FPS), int(7 * FPS)
    # A and B walk 3 s toward each other, meet 1.2 m apart at frame `arrive`.
    a = walk((-0.6 - 1.2 * arrive * DT, 0.0),
             const_velocity(t, (1.2, 0), 1, arrive + 1) + const_velocity(t, (-1.2, 0), leave))
    b = walk((0.6 + 1.2 * arrive * DT, 0.0),
             const_velocity(t, (-1.2, 0), 1, arrive + 1) + const_velocity(t, (1.2, 0), leave))
    # C and D: standing back to back 1 m apart for the whole shot.
    c = np.broadcast_to((20.0, -0.5), (t, 2))
    d = np.broadcast_to((20.0, 0.5), (t, 2))
    # E and F: walk past each other head-on with a 0.8 m lateral offset.
    e = walk((30.0, 10.0), const_velocity(t, (1.2, 0), 1))
    f = walk((30.0 + 1.2 * 12, 10.8), const_velocity(t, (-1.2, 0), 1))
    # G and H: standing side by side, both facing +Y.
    g = np.broadcast_to((-20.0, 0.0), (t, 2))
    h = np.broadcast_to((-19.0, 0.0), (t, 2))
    xy = np.stack([a, b, c, d, e, f, g, h], axis=1)
    heading = np.full((t, 8), np.nan)
    heading[:, 2] = -np.pi / 2  # C faces away from D (D is at +Y)
    heading[:, 3] = np.pi / 2
    heading[:, 6:8] = np.pi / 2
    # A and B face each other while standing (the heading holds from the walk),
    # then turn round to walk away. They stand still (zero velocity) on
    # frames arrive + 1 .. leave - 1.
    return xy, heading, (arrive + 1, leave - 1)


def test_interaction_face_to_face(rng):
    xy, heading, (first, last) = interaction_scene(rng)
    table = run(xy, heading)
    inter = of_kind(table, INTERACTION)
    assert len(inter) == 1, [e.path for e in table]
    ev = inter[0]
    assert ev.members.tolist() == [0, 1]
    assert abs(frame_of(ev.start) - first) <= 2
    assert abs(frame_of(ev.end) - last) <= 2
    assert ev.path == "/World/Events/Interaction_0001"
    # Centre between the two, radius half their distance (1.2 m) + 0.5 m.
    i = ev.sample(ev.start + 24)
    np.testing.assert_allclose(ev.center[i, :2], [0.0, 0.0], atol=1e-5)
    assert ev.radius[i] == pytest.approx(1.1, abs=1e-5)
    assert ev.active.all() and ev.times.tolist() == list(np.arange(ev.start, ev.end + 1))
    assert of_kind(table, GROUP_MOTION) == []


def test_interaction_needs_facing_each_other(rng):
    """Per frame: the facing pair is found, back to back or side by side is not."""
    xy, heading, (first, _) = interaction_scene(rng)
    fr = frames_from(xy, heading)
    i = first + 10
    speed = np.linalg.norm(fr.velocity[i], axis=1)
    pairs = find_interaction_pairs(fr.position[i, :, :2], fr.heading[i], speed, np.ones(8, bool))
    assert pairs.tolist() == [[0, 1]]
    # Turned round (each facing away): no longer an interaction.
    turned = fr.heading[i].copy()
    turned[:2] += np.pi
    assert len(find_interaction_pairs(fr.position[i, :, :2], turned, speed, np.ones(8, bool))) == 0


def test_interaction_short_or_invisible_is_dropped(rng):
    xy, heading, _ = interaction_scene(rng)
    # Invisible: A takes part in nothing.
    visible = np.ones(8, bool)
    visible[0] = False
    assert of_kind(run(xy, heading, visible=visible), INTERACTION) == []
    # Standing face to face for less than the minimum duration: nothing kept.
    p = EventParams(interaction_min_duration=5.0)
    assert of_kind(run(xy, heading, params=p), INTERACTION) == []


def test_interaction_blip_does_not_split(rng):
    """A two-frame glance away does not end the interaction (hysteresis)."""
    xy, heading, (first, last) = interaction_scene(rng)
    heading[first:last + 1, 0] = 0.0  # A faces B (+X) ...
    heading[first + 40:first + 42, 0] = np.pi / 2  # ... but for a glance to the side
    inter = of_kind(run(xy, heading), INTERACTION)
    assert len(inter) == 1
    assert abs(frame_of(inter[0].start) - first) <= 2 and abs(frame_of(inter[0].end) - last) <= 2


# --- (b) a platoon among wanderers -----------------------------------------

def platoon_scene(rng):
    """20 in formation cross a 60 m square among 100 wanderers.

    The platoon (rows 0..19) stands 1 s, walks +X at 1.3 m/s for 26 s, stands
    1 s. Returns the tracks and the truth (first, last walking frame).
    """
    t = int(28 * FPS)
    go, stop = int(1 * FPS), int(27 * FPS)
    pl = platoon(t, (-17.0, 3.0), formation(5, 4, 1.0, rng), const_velocity(t, (1.3, 0.0), go, stop), rng)
    wa, wv = wanderers(t, 100, 30.0, rng)
    vel = concat(np.full_like(pl, np.nan), wv)
    return concat(pl, wa), vel, (go, stop - 1)


def test_platoon_among_wanderers(rng):
    xy, vel, (first, last) = platoon_scene(rng)
    table = run(xy, velocity=vel)
    groups = of_kind(table, GROUP_MOTION)
    assert len(groups) == 1, [(e.start, e.end, e.members.tolist()) for e in groups]
    ev = groups[0]
    assert abs(frame_of(ev.start) - first) <= 6
    assert abs(frame_of(ev.end) - last) <= 6
    # Per frame over the event: precision and recall of its members against
    # the platoon. A wanderer walking the platoon's way right beside it is,
    # for a moment, part of the group motion: hence the 95 % of frames.
    prec, rec = member_scores(ev, np.arange(20))
    assert prec.mean() >= 0.9 and rec.mean() >= 0.9, (prec.mean(), rec.mean())
    assert (prec >= 0.9).mean() >= 0.95 and (rec >= 0.9).mean() >= 0.95
    # The event follows the platoon: centre within a metre of the formation's.
    for i in range(0, len(ev.times), 24):
        f = frame_of(ev.times[i])
        np.testing.assert_allclose(ev.center[i, :2], xy[f, :20].mean(axis=0), atol=1.0)
        assert ev.radius[i] >= np.linalg.norm(xy[f, :20] - ev.center[i, :2], axis=1).max() - 1e-6


def test_wanderers_alone_make_no_group(rng):
    """100 people at random drifting headings: no group motion, no interaction.

    (In much denser random crowds five people do now and then walk the same
    way side by side for seconds: that is a group motion by the criteria.)
    """
    xy, vel = wanderers(int(28 * FPS), 100, 30.0, rng)
    assert len(run(xy, velocity=vel)) == 0


# --- (c) a group splits in two -----------------------------------------------

def split_scene(rng):
    """20 in formation walk +X for 5 s, then 12 of them (y > 0) turn to +40
    degrees and the other 8 to -40 degrees and walk on 7 s.

    Returns tracks, the two halves' rows, and the split frame.
    """
    t = int(12 * FPS)
    split = int(5 * FPS)
    off = formation(4, 5, 1.0, rng)  # 4 deep along x, 5 across y
    up = np.argsort(off[:, 1])[8:]  # the 12 on the +Y side
    down = np.argsort(off[:, 1])[:8]
    v = np.zeros((t, 20, 2))
    v[1:split] = (1.3, 0.0)
    for rows, ang in ((up, 40.0), (down, -40.0)):
        a = np.radians(ang)
        v[split:, rows] = 1.3 * np.array([np.cos(a), np.sin(a)])
    xy = np.stack([walk(off[j], v[:, j]) for j in range(20)], axis=1)
    return xy, np.sort(up), np.sort(down), split


def test_split_keeps_event_for_larger_part(rng):
    xy, up, down, split = split_scene(rng)
    groups = of_kind(run(xy), GROUP_MOTION)
    assert len(groups) == 2, [(e.start, e.end, e.members.tolist()) for e in groups]
    first, second = groups  # ordered by start time
    # The first event runs from the start to the end, with everybody before
    # the split and the larger part (12) after it.
    assert frame_of(first.start) <= 2 and frame_of(first.end) >= len(xy) - 3
    assert first.members.tolist() == list(range(20))
    before = first.sample(split - 12 + 1.0)
    after = first.sample(split + 48 + 1.0)
    assert first.active[before].all()
    np.testing.assert_array_equal(first.members[first.active[after]], up)
    # The smaller part starts a new event shortly after the split.
    assert split <= frame_of(second.start) <= split + 36
    np.testing.assert_array_equal(second.members, down)
    assert frame_of(second.end) >= len(xy) - 3
    assert first.path.endswith("GroupMotion_0001") and second.path.endswith("GroupMotion_0002")


# --- (d) a group thins out -----------------------------------------------------

def thinning_scene(rng):
    """8 walk +X at 1.4 m/s in two files; from 3 s on, every 2 s the last
    walker in the files turns round and walks back, until 2 are left.

    Returns tracks and the frame at which the walkers fell from 3 to 2.
    """
    t = int(18 * FPS)
    off = formation(4, 2, 1.0, rng, jitter=0.05)  # rows 0..3 along x, back row first
    v = np.zeros((t, 8, 2))
    v[1:] = (1.4, 0.0)
    leave = {}
    for k in range(6):  # the back-most walkers leave first
        j = k
        leave[j] = int((3 + 2 * k) * FPS)
        v[leave[j]:, j] = (-1.4, 0.0)
    # Off the world-aligned cell borders (x = 0, y = 0 border cells at every level).
    xy = np.stack([walk(off[j] + (-9.3, 2.1), v[:, j]) for j in range(8)], axis=1)
    return xy, leave[5]


def test_thinning_ends_event(rng):
    xy, below = thinning_scene(rng)
    groups = of_kind(run(xy), GROUP_MOTION)
    walkers = [e for e in groups if 6 in e.members]
    assert len(walkers) == 1, [(e.start, e.end, e.members.tolist()) for e in groups]
    ev = walkers[0]
    assert frame_of(ev.start) <= 2
    # It ends when fewer than min_members_keep (3) walk on together.
    assert below - 24 <= frame_of(ev.end) <= below + 2, (frame_of(ev.end), below)
    # Members leave one by one: the active count falls.
    counts = ev.active.sum(axis=1)
    assert counts[0] == 8 and counts[-1] <= 4
    assert np.all(np.diff(counts) <= 0)


# --- (e) a mixed scene: precision and recall of whole events --------------------

def face_to_face(t: int, mid, angle: float, arrive: int, leave: int, gap: float = 1.2):
    """(t, 2, 2) two people who walk 2 s toward ``mid`` along ``angle``, stand
    face to face ``gap`` metres apart on frames ``arrive + 1 .. leave - 1``,
    then walk back the way they came. Returns the tracks and the headings."""
    d = np.array([np.cos(angle), np.sin(angle)])
    v = np.zeros((t, 2, 2))
    steps = int(2 * FPS)
    a0 = max(arrive - steps + 1, 1)
    v[a0:arrive + 1, 0] = 1.2 * d
    v[a0:arrive + 1, 1] = -1.2 * d
    v[leave:leave + steps, 0] = -1.2 * d
    v[leave:leave + steps, 1] = 1.2 * d
    walked = 1.2 * (arrive + 1 - a0) * DT
    xy = np.stack([walk(np.asarray(mid) - d * (gap / 2 + walked), v[:, 0]),
                   walk(np.asarray(mid) + d * (gap / 2 + walked), v[:, 1])], axis=1)
    heading = np.full((t, 2), np.nan)
    heading[arrive + 1:leave, 0] = angle  # facing each other while they stand
    heading[arrive + 1:leave, 1] = angle + np.pi
    return xy, heading


def mixed_scene(rng):
    """Four interactions, three platoons (20, 12 and 8) and 80 wanderers over 28 s.

    Returns tracks, headings, velocities (NaN: from the tracks), and the truth
    as a list of (kind, member rows, first frame, last frame).
    """
    t = int(28 * FPS)
    parts, heads, vels, truth = [], [], [], []
    row = 0

    def add(xy, heading=None, vel=None):
        nonlocal row
        parts.append(xy)
        heads.append(np.full(xy.shape[:2], np.nan) if heading is None else heading)
        vels.append(np.full(xy.shape, np.nan) if vel is None else vel)
        rows = np.arange(row, row + xy.shape[1])
        row += xy.shape[1]
        return rows

    for mid, ang, a, b in (((-20, 20), 0.3, 3, 8), ((0, 0), 1.2, 10, 14), ((20, -20), -0.7, 15, 20),
                           ((-5, -25), 2.5, 2, 6)):
        arrive, leave = int(a * FPS), int(b * FPS)
        xy, hd = face_to_face(t, mid, ang, arrive, leave)
        truth.append((INTERACTION, add(xy, hd), arrive + 1, leave - 1))
    for size, (rows_, cols_), start, ang, speed, (a, b) in (
            (20, (5, 4), (-30, -10), 0.0, 1.3, (2, 22)),
            (12, (4, 3), (10, -30), np.pi / 2, 1.1, (5, 25)),
            (8, (4, 2), (25.3, 25.7), -3 * np.pi / 4, 1.2, (8, 20))):
        go, stop = int(a * FPS), int(b * FPS)
        d = np.array([np.cos(ang), np.sin(ang)])
        off = formation(rows_, cols_, 1.0, rng) @ np.array([[d[0], d[1]], [-d[1], d[0]]])
        xy = platoon(t, start, off, const_velocity(t, speed * d, go, stop), rng)
        truth.append((GROUP_MOTION, add(xy), go, stop - 1))
    wa, wv = wanderers(t, 80, 40.0, rng)
    add(wa, vel=wv)
    return concat(*parts), np.concatenate(heads, axis=1), np.concatenate(vels, axis=1), truth


def match_events(table: model.EventTable, truth) -> tuple[float, float]:
    """Precision and recall of detected events against the truth.

    A detected event matches a true one of its kind when the Jaccard index of
    their member sets is >= 0.5 and their frame spans overlap by >= 50 %
    (intersection over union); each is matched at most once.
    """
    used = set()
    hits = 0
    for kind, rows, a, b in truth:
        for i, e in enumerate(table):
            if i in used or e.kind != kind:
                continue
            m = set(e.members.tolist())
            jac = len(m & set(rows.tolist())) / len(m | set(rows.tolist()))
            s, f = frame_of(e.start), frame_of(e.end)
            iou = max(0, min(b, f) - max(a, s) + 1) / (max(b, f) - min(a, s) + 1)
            if jac >= 0.5 and iou >= 0.5:
                used.add(i)
                hits += 1
                break
    return hits / max(len(table), 1), hits / len(truth)


def test_mixed_scene_precision_recall(rng):
    xy, heading, vel, truth = mixed_scene(rng)
    table = run(xy, heading, velocity=vel)
    precision, recall = match_events(table, truth)
    summary = [(e.path, frame_of(e.start), frame_of(e.end), e.members.tolist()[:6]) for e in table]
    assert precision >= 0.9 and recall >= 0.9, (precision, recall, summary)
    # Ids follow start time, then first member.
    keys = [(e.start, int(e.members[0])) for e in table]
    assert keys == sorted(keys)
    assert [int(e.path[-4:]) for e in table] == list(range(1, len(table) + 1))


# --- (f) chunked feeding -----------------------------------------------------

def assert_same_events(a: model.EventTable, b: model.EventTable) -> None:
    assert a.paths == b.paths
    for x, y in zip(a, b):
        assert (x.kind, x.start, x.end) == (y.kind, y.start, y.end)
        np.testing.assert_array_equal(x.members, y.members)
        np.testing.assert_array_equal(x.times, y.times)
        np.testing.assert_array_equal(x.active, y.active)
        np.testing.assert_array_equal(x.center, y.center)
        np.testing.assert_array_equal(x.radius, y.radius)


def test_chunked_feeding_gives_same_events(rng):
    xy, heading, vel, _ = mixed_scene(rng)
    whole = run(xy, heading, velocity=vel)
    assert len(whole) >= 7
    assert_same_events(whole, run(xy, heading, velocity=vel, chunk=48))
    assert_same_events(whole, run(xy, heading, velocity=vel, chunk=7))
    assert_same_events(whole, run(xy, heading, velocity=vel, chunk=1))      # a one-frame first chunk too
    # Deterministic: the same input again gives the same events.
    assert_same_events(whole, run(xy, heading, velocity=vel, chunk=1000))


# --- the per-frame quad-tree -------------------------------------------------

def test_find_groups_separates_directions(rng):
    """Two dense clusters walking opposite ways side by side: two groups;
    random headings: none."""
    a = rng.uniform(0, 6, (30, 2)) + (3.3, 1.7)
    b = rng.uniform(0, 6, (30, 2)) + (3.3, 7.9)
    xy = np.concatenate([a, b])
    vel = np.concatenate([np.tile([1.2, 0.0], (30, 1)), np.tile([-1.2, 0.0], (30, 1))])
    vel += rng.normal(0, 0.05, vel.shape)
    lab = find_groups(xy, vel, np.zeros(60, np.int8))
    assert lab[0] == 0 and np.all(lab[:30] == 0) and np.all(lab[30:] == 1)
    ang = rng.uniform(-np.pi, np.pi, 60)
    rand = 1.2 * np.stack([np.cos(ang), np.sin(ang)], axis=1)
    assert np.all(find_groups(xy, rand, np.zeros(60, np.int8)) < 0)


def test_find_groups_across_cell_borders(rng):
    """A formation centred on the world origin (a cell border at every
    level) and one across a 32 m border are each found whole."""
    for centre in ((0.0, 0.0), (64.0, 31.8)):
        off = formation(5, 4, 1.0, rng) + centre
        vel = np.tile([0.0, 1.3], (20, 1)) + rng.normal(0, 0.05, (20, 2))
        lab = find_groups(off, vel, np.zeros(20, np.int8))
        assert np.all(lab == 0), (centre, lab)


def test_find_groups_needs_speed_density_and_one_type(rng):
    off = formation(5, 4, 1.0, rng) + (5.0, 5.0)
    vel = np.tile([1.3, 0.0], (20, 1))
    ctype = np.zeros(20, np.int8)
    assert np.all(find_groups(off, vel, ctype) == 0)
    # Too slow.
    assert np.all(find_groups(off, 0.3 * vel, ctype) < 0)
    # Too sparse: the same formation at 4 m spacing.
    assert np.all(find_groups(4 * off, vel, ctype) < 0)
    # Humans and herbivores in a checkerboard: no cell is homogeneous.
    mixed = ((np.arange(20) // 4 + np.arange(20) % 4) % 2).astype(np.int8)
    assert np.all(find_groups(off, vel, mixed) < 0)
    # Speeds too unequal (coefficient of variation over 0.35).
    uneven = vel * np.where(mixed == 1, 0.4, 1.6)[:, None]
    assert np.all(find_groups(off, uneven, ctype) < 0)


def test_fill_gaps():
    act = np.array([[1, 1], [0, 0], [0, 1], [1, 0], [0, 0], [0, 0], [0, 1]], bool)
    out = fill_gaps(act, 2)
    np.testing.assert_array_equal(out[:, 0], [1, 1, 1, 1, 0, 0, 0])  # the gap of 2 filled, the tail not
    np.testing.assert_array_equal(out[:, 1], [1, 1, 1, 0, 0, 0, 1])  # the gap of 3 left


# --- the streaming detector ----------------------------------------------------

def test_dead_and_invisible_take_no_part(rng):
    xy, vel, _ = platoon_scene(rng)
    fr = frames_from(xy, velocity=vel)
    visible = np.ones(xy.shape[1], bool)
    visible[:3] = False
    fr.health[:, 3] = model.code(model.HEALTH_STATES, "dead")
    det = EventDetector(np.zeros(xy.shape[1], np.int8), visible, FPS)
    det.feed(fr)
    ev = of_kind(det.finish(), GROUP_MOTION)
    assert len(ev) == 1 and not np.isin([0, 1, 2, 3], ev[0].members).any()


def test_detector_rejects_misuse():
    fr = frames_from(np.zeros((4, 3, 2)))
    det = EventDetector(np.zeros(3, np.int8), np.ones(3, bool), FPS, scope="/Shot/Events/")
    det.feed(slice_frames(fr, 0, 2))
    with pytest.raises(ValueError, match="time order"):
        det.feed(slice_frames(fr, 0, 2))
    with pytest.raises(ValueError, match="expected"):
        det.feed(frames_from(np.zeros((2, 5, 2)), t0=10.0))
    assert len(det.finish()) == 0
    with pytest.raises(RuntimeError):
        det.feed(slice_frames(fr, 2, 4))
    with pytest.raises(ValueError):
        EventDetector(np.zeros(3, np.int8), np.ones(2, bool), FPS)
    with pytest.raises(ValueError):
        EventParams(interaction_distance=-1.0)
    with pytest.raises(ValueError):
        EventParams(min_members_keep=6, min_members_create=5)


def test_scope_and_event_fields(rng):
    xy, heading, _ = interaction_scene(rng)
    fr = frames_from(xy, heading)
    table = detect_events(fr, np.zeros(8, np.int8), np.ones(8, bool), FPS, scope="/Shot/Events/")
    ev = table[0]
    assert ev.path == "/Shot/Events/Interaction_0001" and not ev.authored
    assert ev.members.dtype == np.int32 and ev.active.shape == (len(ev.times), 2)
    assert ev.center.shape == (len(ev.times), 3) and ev.radius.shape == (len(ev.times),)
    assert table.agent_events(ev.start + 10, 8)[0] == [0]


def test_memory_does_not_grow_with_frames(rng):
    """A long shot of people milling about: the running state stays small."""
    n, t = 200, int(60 * FPS)
    xy = np.broadcast_to(rng.uniform(-10, 10, (n, 2)), (t, n, 2)).copy()
    heading = rng.uniform(-np.pi, np.pi, (t, n))  # fidgeting: every frame a new heading
    det = EventDetector(np.zeros(n, np.int8), np.ones(n, bool), FPS)
    fr = frames_from(xy, heading)
    peak = 0
    for a in range(0, t, 48):
        det.feed(slice_frames(fr, a, a + 48))
        it = det._interactions
        peak = max(peak, it.stored, len(it.blocks))
    # Facing pairs come and go each frame; none lasts, nothing piles up.
    assert peak < 5000
    assert len(det.finish()) == 0


def test_find_groups_far_flung_crowd(rng):
    """Two groups 14 km apart (sparse cell index) get the labels they get apart."""
    a = formation(5, 4, 1.0, rng) + (3.3, 1.7)
    va = np.tile([1.3, 0.0], (20, 1))
    b = formation(4, 3, 1.0, rng) + (-9000.0, 11000.0)
    vb = np.tile([0.0, -1.1], (12, 1))
    ct = np.zeros(32, np.int8)
    both = find_groups(np.concatenate([a, b]), np.concatenate([va, vb]), ct)
    np.testing.assert_array_equal(both[:20], find_groups(a, va, ct[:20]))
    np.testing.assert_array_equal(both[20:], find_groups(b, vb, ct[:12]) + 1)
    # One level, or members through every level: still one group each.
    for p in (EventParams(levels=1, member_levels=1), EventParams(member_levels=4)):
        lab = find_groups(np.concatenate([a, b]), np.concatenate([va, vb]), ct, p)
        assert np.all(lab[:20] == 0) and np.all(lab[20:] == 1)


def test_an_explosion_layer_is_an_event_of_everyone_within_reach():
    from usdcrowd.events.scenario import REACH, layer_events

    t, n = 60, 10
    times = np.arange(1.0, t + 1.0)
    pos = np.zeros((t, n, 3))
    pos[:, :5, 0] = np.arange(5.0)                  # near the origin
    pos[:, 5:9, 0] = 100.0                          # far away
    pos[:, 9, 0] = np.linspace(40.0, 0.0, t)        # walks in: within 2 x 8 m from x <= 16
    visible = np.ones(n, bool)
    visible[4] = False                              # an invisible leader takes part in nothing
    blast = model.BehaviorField("/World/BehaviorLayers/Blast", model.code(model.LAYER_MEANINGS, "damage"),
                                model.code(model.LAYER_GENERATORS, "explosion"), None, np.zeros(2), np.ones(2),
                                origin=np.zeros(3), radius=8.0, start_time=11.0)
    (ev,) = layer_events([blast], pos, times, visible, "/World/Events")
    assert ev.path == "/World/Events/Explosion_Blast" and model.EVENT_KINDS[ev.kind] == "explosion"
    assert ev.start == 11.0 and ev.end == 60.0
    assert ev.members.tolist() == [0, 1, 2, 3, 9]
    walker = ev.active[:, -1]
    inside = np.linalg.norm(pos[10:, 9, :2], axis=1) <= REACH * 8.0
    np.testing.assert_array_equal(walker, inside)
    np.testing.assert_allclose(ev.radius, REACH * 8.0)
    far = model.BehaviorField("/L/Far", blast.meaning, blast.generator, None, np.zeros(2), np.ones(2),
                              origin=np.array([500.0, 0, 0]), radius=8.0, start_time=1.0)
    assert layer_events([far], pos, times, visible) == []


def test_layer_events_of_two_layers_with_one_name_get_distinct_paths():
    from usdcrowd.events.scenario import layer_events

    pos = np.zeros((5, 2, 3))
    times = np.arange(1.0, 6.0)
    make = lambda parent: model.BehaviorField(f"/World/{parent}/Blast", model.code(model.LAYER_MEANINGS, "damage"),
                                              model.code(model.LAYER_GENERATORS, "explosion"), None, np.zeros(2),
                                              np.ones(2), origin=np.zeros(3), radius=3.0, start_time=1.0)
    paths = [e.path for e in layer_events([make("A"), make("B"), make("C")], pos, times, np.ones(2, bool))]
    assert paths == ["/World/Events/Explosion_Blast", "/World/Events/Explosion_Blast_2",
                     "/World/Events/Explosion_Blast_3"]
