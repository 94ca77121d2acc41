"""Tracking cameras keep their event in sight: they leave one they cannot see, frame the densest part of
one spread too wide, and stand at a height from which scenery does not hide it."""

from __future__ import annotations

import numpy as np

from tests.cameras.test_cameras import FPS, GROUP, INTERACTION, make_event
from usdcrowd.cameras.film import film
from usdcrowd.cameras.params import CameraParams
from usdcrowd.cameras.placement import generated_agents, take_agents
from usdcrowd.cameras.tracking_quality import tracking_quality
from usdcrowd.core import model
from usdcrowd.core.view import look_at


def _one_camera(eye, target, elevation):
    cams = take_agents(generated_agents(1, np.zeros(3), 1.0), [0])
    cams.cam_to_world[:] = look_at(np.array([eye], float), np.array([target], float))
    cams.elevation[:] = elevation
    return cams


def _pair_walking_into_a_house():
    """A pair walks +X at 1.5 m/s from x = 0 into a closed house (x 15-25) and stays in it; the house is
    30 m tall, so no camera sees them once inside (from frame ~240)."""
    t = 24 * 20
    times = np.arange(1, t + 1, dtype=np.float64)
    pos = np.zeros((t, 2, 3))
    x = np.minimum(np.arange(t) * 1.5 / FPS, 20.0)
    pos[:, 0, 0], pos[:, 1, 0] = x, x
    pos[:, 0, 1], pos[:, 1, 1] = -0.5, 0.5
    ev = make_event("/E/Pair", INTERACTION, pos, [0, 1], 0, t - 1, times)
    house = model.Obstacles(["/House"], [np.array([[15.0, -5.0], [25.0, -5.0], [25.0, 5.0], [15.0, 5.0]])],
                            np.array([30.0]))
    return pos, times, model.EventTable([ev]), house


def test_a_camera_leaves_an_event_it_has_not_seen_for_give_up_seconds():
    pos, times, events, house = _pair_walking_into_a_house()
    cams = _one_camera([0.0, -12.0, 2.0], [0.0, 0.0, 1.1], [1.5, 4.0])
    prm = CameraParams()
    tr = film(pos, times, FPS, cams, events, house, params=prm, seed=1)[0]
    inside = int(np.argmax(pos[:, 0, 0] > 15.6))          # both hidden from here on (half a body in)
    assert tr.tracked[inside - 1] == "/E/Pair"
    gone = inside + int(np.argmax([not e for e in tr.tracked[inside:]]))
    assert tr.tracked[gone] == "" and gone - inside <= (prm.give_up_seconds + 0.5) * FPS, (inside, gone)
    # It does not take the hidden pair again (it would have to see them).
    assert not any(tr.tracked[gone:]), [k for k in range(gone, len(times)) if tr.tracked[k]][:3]
    # A camera that never gives up stays on the hidden pair to the end.
    stubborn = film(pos, times, FPS, cams, events, house, params=CameraParams(give_up_seconds=1e9), seed=1)[0]
    assert all(e == "/E/Pair" for e in stubborn.tracked[inside:])


def _crowd_fleeing_in_every_direction():
    """16 people walk straight out from a 2 m ring at 1.4 m/s for 20 s: the group's centre is empty ground."""
    t = 24 * 20
    times = np.arange(1, t + 1, dtype=np.float64)
    # Eleven flee east and north-east, five west: the densest part is the eastern arc.
    a = np.concatenate([np.linspace(-0.5, 0.8, 11), np.linspace(2.6, 3.6, 5)])
    r = 2.0 + np.arange(t)[:, None] * 1.4 / FPS
    pos = np.zeros((t, len(a), 3))
    pos[..., 0], pos[..., 1] = r * np.cos(a), r * np.sin(a)
    ev = make_event("/E/Flight", GROUP, pos, np.arange(len(a)), 0, t - 1, times)
    return pos, times, model.EventTable([ev])


def test_an_event_spread_wider_than_a_frame_is_framed_by_its_densest_part():
    pos, times, events = _crowd_fleeing_in_every_direction()
    cams = _one_camera([-20.0, -20.0, 4.0], [0.0, 0.0, 1.1], [1.5, 8.0])
    tr = film(pos, times, FPS, cams, events, model.Obstacles.empty(), seed=2)[0]
    q = tracking_quality([tr], pos, events, np.ones(pos.shape[1], bool), model.Obstacles.empty(), FPS)[0]
    late = q.settled & (np.arange(len(times)) > 12 * FPS)        # the ring is then ~36 m across
    assert late.sum() > 100
    # Someone of the event is in the picture in every late frame, and the eastern arc mostly.
    assert (q.share[late] > 0).all(), np.flatnonzero(late & (q.share == 0))[:5]
    east = np.array([np.mean(pos[k, :11, 0]) for k in range(len(times))])
    ahead = -tr.cam_to_world[late, 2, :2]
    to_east = np.column_stack([east[late], np.mean(pos[late][:, :11, 1], axis=1)]) - tr.cam_to_world[late, 3, :2]
    cos = np.einsum("ij,ij->i", ahead, to_east) / (np.linalg.norm(ahead, axis=1) * np.linalg.norm(to_east, axis=1))
    assert np.median(cos) > np.cos(np.radians(20.0))


def test_a_camera_looks_under_tree_crowns_between_it_and_its_event():
    """Three tree crowns (2.4 m to 6 m up) stand in a row between a camera and a pair; the camera, free to
    rise to 8 m, would look into them from above: it comes down to see under them (in at least 90 % of
    the frames from 2 s on; while it flies under them and out, its height is still changing)."""
    t = 24 * 12
    times = np.arange(1, t + 1, dtype=np.float64)
    pos = np.zeros((t, 2, 3))
    pos[:, 0, :2], pos[:, 1, :2] = [-0.5, 0.0], [0.5, 0.0]
    events = model.EventTable([make_event("/E/Talk", INTERACTION, pos, [0, 1], 0, t - 1, times)])
    crowns = [np.array([[x - 2.0, -11.0], [x + 2.0, -11.0], [x + 2.0, -7.0], [x - 2.0, -7.0]]) for x in (-4, 0, 4)]
    trees = model.Obstacles(["/T0", "/T1", "/T2"], crowns, np.full(3, 6.0), bottom=np.full(3, 2.4))
    cams = _one_camera([0.0, -24.0, 7.0], [0.0, 0.0, 1.1], [1.5, 8.0])
    cams.target[:] = ["/E/Talk"]
    prm = CameraParams(crane_members=1, crane_gain=10.0)      # it would crane high above the pair
    tr = film(pos, times, FPS, cams, events, model.Obstacles.empty(), params=prm, seed=3, overhead=trees)[0]
    q = tracking_quality([tr], pos, events, np.ones(2, bool), model.Obstacles.empty(), FPS, overhead=trees)[0]
    late = q.settled & (np.arange(t) > 2 * FPS)
    assert np.mean(q.share[late] == 1.0) >= 0.9, np.flatnonzero(late & (q.share < 1))


def test_a_camera_told_to_film_an_event_faces_it_when_it_begins():
    """A camera pinned to an event that begins at 5 s, 20 m behind it, has turned to where it begins by
    then (without ``ready_seconds`` they are not yet in its picture: it scouts the crowd in front of it)."""
    t = 24 * 8
    times = np.arange(1, t + 1, dtype=np.float64)
    pos = np.zeros((t, 6, 3))
    pos[:, 0, :2], pos[:, 1, :2] = [20.0, -0.5], [20.0, 0.5]
    pos[:, 2:, :2] = [[-12.0, -3.0], [-12.0, -1.0], [-12.0, 1.0], [-12.0, 3.0]]     # the rest of the crowd
    start = 5 * 24
    events = model.EventTable([make_event("/E/Later", INTERACTION, pos, [0, 1], start, t - 1, times)])
    cams = _one_camera([0.0, 0.0, 2.0], [-10.0, 0.0, 1.5], [1.5, 4.0])
    cams.target[:] = ["/E/Later"]

    def in_picture(track, k):
        m = track.cam_to_world[k]
        rel = (pos[k, :2, :] + [0.0, 0.0, 1.1] - m[3, :3]) @ m[:3, :3].T     # along right, up, back
        z = -rel[:, 2]
        tx = 0.5 * track.horizontal_aperture / track.focal_length[k]
        ty = 0.5 * track.vertical_aperture / track.focal_length[k]
        return bool(((z > 0) & (np.abs(rel[:, 0]) <= tx * z) & (np.abs(rel[:, 1]) <= ty * z)).all())

    ready = film(pos, times, FPS, cams, events, model.Obstacles.empty(), seed=4)[0]
    assert ready.tracked[start - 1] == "" and ready.tracked[start] == "/E/Later"
    assert in_picture(ready, start)
    late = film(pos, times, FPS, cams, events, model.Obstacles.empty(), seed=4,
                params=CameraParams(ready_seconds=0.0))[0]
    assert not in_picture(late, start)


def test_a_camera_told_to_film_an_event_faces_its_people_not_where_it_was_authored():
    """The harbour's boat arrival is authored round the boat, but its people are ashore: a camera told to
    film it turns, before it begins, to the people it will frame (the authored centre is 90 degrees off)."""
    t = 24 * 8
    times = np.arange(1, t + 1, dtype=np.float64)
    pos = np.zeros((t, 2, 3))
    pos[:, 0, :2], pos[:, 1, :2] = [20.0, -0.5], [20.0, 0.5]
    start = 5 * 24
    ev = make_event("/E/Arrival", INTERACTION, pos, [0, 1], start, t - 1, times)
    ev.center[:] = [0.0, 20.0, 0.0]                     # the boat, north of the camera
    cams = _one_camera([0.0, 0.0, 2.0], [-10.0, 0.0, 1.5], [1.5, 4.0])
    cams.target[:] = ["/E/Arrival"]
    tr = film(pos, times, FPS, cams, model.EventTable([ev]), model.Obstacles.empty(), seed=4)[0]
    q = tracking_quality([tr], pos, model.EventTable([ev]), np.ones(2, bool), model.Obstacles.empty(), FPS)[0]
    assert tr.tracked[start] == "/E/Arrival"
    assert q.share[start] == 1.0, q.share[start:start + 24]


def _walker_passing_under(camera_height):
    """One person walks +X at 1.4 m/s along y = 0 from x = -25 for 36 s, under where a camera told to film
    them stands at the start (x = 6, ``camera_height`` up, looking at them)."""
    t = 24 * 36
    times = np.arange(1, t + 1, dtype=np.float64)
    pos = np.zeros((t, 1, 3))
    pos[:, 0, 0] = -25.0 + np.arange(t) * 1.4 / FPS
    events = model.EventTable([make_event("/E/Walker", INTERACTION, pos, [0], 0, t - 1, times)])
    cams = _one_camera([6.0, 0.0, camera_height], [-25.0, 0.0, 1.1], [1.5, 8.0])
    cams.target[:] = ["/E/Walker"]
    return pos, times, events, cams


def test_a_person_walking_at_a_tracking_camera_stays_in_its_picture_as_they_pass():
    """Seen from the front, a walker comes at the camera: it backs away and, where they pass it, pans and
    tilts round to keep them (a turn through the ground below it would be stopped by the pitch limit;
    a crane move taking all of the camera's force would leave it coasting over them)."""
    for height in (3.0, 7.5):
        pos, times, events, cams = _walker_passing_under(height)
        tr = film(pos, times, FPS, cams, events, model.Obstacles.empty(), seed=5)[0]
        q = tracking_quality([tr], pos, events, np.ones(1, bool), model.Obstacles.empty(), FPS)[0]
        late = q.settled & (np.arange(len(times)) > 2 * FPS)
        assert (q.share[late] == 1.0).all(), (height, np.flatnonzero(late & (q.share < 1.0))[:5])
        flat = np.linalg.norm(tr.cam_to_world[late, 3, :2] - pos[late, 0, :2], axis=1)
        assert flat.min() > 1.0, (height, flat.min())


def test_a_camera_right_over_the_person_it_films_steps_back_to_frame_them():
    """A camera told to film a still person, authored as an 8 m wide event, starts almost over them (0.3 m
    off, 3 m up): the framing range's nearest viewpoints lie ~10 m out on both sides, and chasing whichever
    was nearer this step held the camera over them; it steps straight back."""
    t = 24 * 10
    times = np.arange(1, t + 1, dtype=np.float64)
    pos = np.zeros((t, 1, 3))
    ev = make_event("/E/Still", INTERACTION, pos, [0], 0, t - 1, times)
    ev.radius[:] = 8.0
    events = model.EventTable([ev])
    cams = _one_camera([0.3, 0.05, 3.0], [0.0, 0.0, 1.1], [1.5, 6.0])
    cams.target[:] = ["/E/Still"]
    tr = film(pos, times, FPS, cams, events, model.Obstacles.empty(), seed=6)[0]
    q = tracking_quality([tr], pos, events, np.ones(1, bool), model.Obstacles.empty(), FPS)[0]
    late = np.arange(t) > 2 * FPS
    assert (q.share[late] == 1.0).all(), np.flatnonzero(late & (q.share < 1.0))[:5]
    assert np.linalg.norm(tr.cam_to_world[4 * int(FPS):, 3, :2], axis=1).min() > 5.0


def _pair_passing_a_gap_in_a_wall():
    """A pair walks +X at 1.5 m/s along y = 0 from x = -6, behind a 30 m tall wall at y = -3 with a 0.8 m gap
    at x = 0: a camera 12 m south of the gap sees them through it for about half a second."""
    t = 24 * 10
    times = np.arange(1, t + 1, dtype=np.float64)
    pos = np.zeros((t, 2, 3))
    pos[:, :, 0] = (-6.0 + np.arange(t) * 1.5 / FPS)[:, None] + [0.0, 0.6]
    ev = make_event("/E/Pair", INTERACTION, pos, [0, 1], 0, t - 1, times)
    walls = [np.array([[x0, -3.2], [x1, -3.2], [x1, -2.8], [x0, -2.8]]) for x0, x1 in ((-60.0, -0.4), (0.4, 60.0))]
    return pos, times, model.EventTable([ev]), model.Obstacles(["/West", "/East"], walls, np.full(2, 30.0))


def test_a_scout_does_not_take_people_it_sees_walking_behind_a_wall():
    """A scout glimpses a pair through a gap in a wall they are walking behind: where they will be in
    ``occlusion_lookahead`` seconds it would not see them, so it does not take them (with no look ahead
    it takes them and films the wall until it gives up)."""
    pos, times, events, walls = _pair_passing_a_gap_in_a_wall()
    cams = _one_camera([0.0, -15.0, 1.6], [0.0, 0.0, 1.4], [1.5, 1.7])
    still = dict(wander_jitter=0.0, wander_speed=0.0)
    tr = film(pos, times, FPS, cams, events, walls, params=CameraParams(**still), seed=7)[0]
    assert not any(tr.tracked), [k for k, e in enumerate(tr.tracked) if e][:3]
    blind = film(pos, times, FPS, cams, events, walls, params=CameraParams(occlusion_lookahead=0.0, **still),
                 seed=7)[0]
    assert any(blind.tracked)


def test_a_camera_closing_in_on_people_under_an_awning_comes_down_in_time():
    """A pair talks under a 10 m awning (2.6 to 3.2 m up); a camera told to film them flies in from 30 m
    away at 7 m. The height it may look from without the awning's edge in the way falls as it closes in:
    choosing it from where it will be, not only where it is, it comes down in time and never loses them."""
    t = 24 * 12
    times = np.arange(1, t + 1, dtype=np.float64)
    pos = np.zeros((t, 2, 3))
    pos[:, 0, :2], pos[:, 1, :2] = [-0.5, 0.0], [0.5, 0.0]
    events = model.EventTable([make_event("/E/Talk", INTERACTION, pos, [0, 1], 0, t - 1, times)])
    awning = model.Obstacles(["/Awning"], [np.array([[-5.0, -5.0], [5.0, -5.0], [5.0, 5.0], [-5.0, 5.0]])],
                             np.array([3.2]), bottom=np.array([2.6]))
    cams = _one_camera([0.0, -30.0, 7.0], [0.0, 0.0, 1.1], [1.5, 8.0])
    cams.target[:] = ["/E/Talk"]
    prm = CameraParams(crane_members=1, crane_gain=10.0)      # it would stay high above the pair
    tr = film(pos, times, FPS, cams, events, model.Obstacles.empty(), params=prm, seed=8, overhead=awning)[0]
    q = tracking_quality([tr], pos, events, np.ones(2, bool), model.Obstacles.empty(), FPS, overhead=awning)[0]
    assert q.walled.sum() == 0 and (q.share > 0).all(), np.flatnonzero(q.share == 0)[:5]


def _group_behind_a_wall(gap):
    """Seven people stand 1 m apart along y = 0 (x = -3 to 3) behind a 30 m tall wall at y = -3 with a gap
    ``gap`` = (x0, x1); a camera 15 m south of x = 0.5 sees those whose sight line passes the gap."""
    t = 24 * 3
    times = np.arange(1, t + 1, dtype=np.float64)
    pos = np.zeros((t, 7, 3))
    pos[:, :, 0] = np.arange(-3.0, 4.0)
    ev = make_event("/E/Group", GROUP, pos, np.arange(7), 0, t - 1, times)
    walls = [np.array([[x0, -3.2], [x1, -3.2], [x1, -2.8], [x0, -2.8]]) for x0, x1 in ((-60.0, gap[0]), (gap[1], 60.0))]
    cams = _one_camera([0.5, -15.0, 1.6], [0.5, 0.0, 1.4], [1.5, 1.7])
    return pos, times, model.EventTable([ev]), model.Obstacles(["/West", "/East"], walls, np.full(2, 30.0)), cams


def test_a_scout_takes_a_group_only_when_it_sees_a_good_part_of_it():
    """Through a gap showing two of a group of seven a scout does not take it (under ``take_share``, a
    third); through one showing three it does, and with ``take_share`` 0 a glimpse of two is enough."""
    still = dict(wander_jitter=0.0, wander_speed=0.0)
    pos, times, events, walls, cams = _group_behind_a_wall((-0.3, 1.3))         # people at x = 0 and 1
    assert not any(film(pos, times, FPS, cams, events, walls, params=CameraParams(**still), seed=9)[0].tracked)
    glimpse = film(pos, times, FPS, cams, events, walls, params=CameraParams(take_share=0.0, **still), seed=9)[0]
    assert all(glimpse.tracked)
    pos, times, events, walls, cams = _group_behind_a_wall((-1.1, 1.3))         # x = -1, 0 and 1
    assert all(film(pos, times, FPS, cams, events, walls, params=CameraParams(**still), seed=9)[0].tracked)


def test_cameras_take_no_one_before_they_come_into_the_scene():
    """A replay's people come and go (NaN positions where absent): a scout looking at where a pair will
    walk in does not take their event before they are there, takes it within a second once they are, and
    the overview's crowd centre is that of the people present."""
    from usdcrowd.cameras.overview import crowd_summary

    t, come = 24 * 8, 24 * 3
    times = np.arange(1, t + 1, dtype=np.float64)
    pos = np.zeros((t, 3, 3))
    pos[:, 0, :2] = [-6.0, 4.0]                                   # a bystander, there all along
    pos[:, 1, 0] = pos[:, 2, 0] = np.arange(t) * 1.2 / FPS
    pos[:, 1, 1], pos[:, 2, 1] = -0.4, 0.4
    pos[:come, 1:] = np.nan
    held = np.where(np.isfinite(pos), pos, pos[come])             # where they stand for the event's centre
    ev = make_event("/E/Pair", INTERACTION, held, [1, 2], 0, t - 1, times)
    cams = _one_camera([0.0, -10.0, 2.0], [0.0, 0.0, 1.0], [1.5, 4.0])
    tr = film(pos, times, FPS, cams, model.EventTable([ev]), seed=1)[0]
    assert not any(tr.tracked[:come]), [k for k in range(come) if tr.tracked[k]][:3]
    assert all(e == "/E/Pair" for e in tr.tracked[come + int(FPS):]), tr.tracked[come:come + 5]
    centre, _ = crowd_summary(pos, np.ones(3, bool))
    np.testing.assert_allclose(centre[:come], pos[:come, 0])
    np.testing.assert_allclose(centre[come:], pos[come:].mean(axis=1))


def test_someone_who_leaves_is_held_where_they_were_last_seen():
    """The cameras' velocities need a position for people not in the scene: someone who leaves after a
    stretch with everyone there is held where they left, not where they started."""
    from usdcrowd.cameras.film import _Held

    t = 6
    pos = np.zeros((t, 2, 3))
    pos[:, 0, 0] = np.arange(t)                   # there all along
    pos[:, 1, 1] = 10.0 + np.arange(t)            # walks off and is gone from frame 3
    pos[3:, 1] = np.nan
    held = _Held(pos)
    for k in range(3):
        got, here = held(k)
        assert here is None and np.array_equal(got, pos[k])
    for k in range(3, t):
        got, here = held(k)
        assert here.tolist() == [True, False]
        np.testing.assert_array_equal(got[1], pos[2, 1])        # where they left, not (0, 10, 0)
        np.testing.assert_array_equal(got[0], pos[k, 0])


def test_a_scout_looking_at_a_wall_turns_to_the_crowd_it_has_behind_it():
    """A scout 4 m from a 3 m wall, looking at it, the crowd behind its back (well inside the containing
    radius, so only the wall can turn it): whatever its wandering draws, it has people in the picture
    within 2.5 s, and most of the time after (it wanders on; the paper's wander left it filming the wall
    for up to 7 s, or never turned)."""
    t = 24 * 8
    times = np.arange(1, t + 1, dtype=np.float64)
    crowd = np.array([[x, y, 0.0] for x in (-6.0, -8.0, -10.0) for y in (-6.0, -2.0, 2.0, 6.0)])
    pos = np.broadcast_to(crowd, (t, len(crowd), 3)).copy()
    wall = model.Obstacles(["/Wall"], [np.array([[4.0, -20.0], [4.3, -20.0], [4.3, 20.0], [4.0, 20.0]])],
                           np.array([3.0]))
    first, share = [], []
    for seed in range(6):
        cams = _one_camera([0.0, 0.0, 2.5], [4.0, 0.0, 1.1], [2.0, 3.0])
        track = film(pos, times, FPS, cams, model.EventTable([]), wall, seed=seed)[0]
        m = track.cam_to_world
        rel = np.einsum("tpj,tij->tpi", pos + [0.0, 0.0, 1.1] - m[:, None, 3, :3], m[:, :3, :3])
        z = -rel[..., 2]
        tx = 0.5 * track.horizontal_aperture / track.focal_length[:, None]
        seen = ((z > 0) & (np.abs(rel[..., 0]) <= tx * z)).any(axis=1)        # someone in the picture
        first.append(int(np.argmax(seen)) if seen.any() else t)
        share.append(float(seen[3 * 24:].mean()))
    assert max(first) <= 2.5 * FPS, first
    assert np.mean(share) >= 0.75, share


def test_a_scout_does_not_stare_at_scenery_that_hides_the_crowds_centre():
    """People in a ring round a 3 m kiosk, a scout inside the ring looking at the kiosk: the crowd's centre
    is behind the kiosk from everywhere, so turning toward it cannot clear its view; the scout wanders on
    (always facing the kiosk, had the kiosk alone turned it)."""
    from usdcrowd.cameras.sightlines import Prisms

    t = 24 * 8
    times = np.arange(1, t + 1, dtype=np.float64)
    ring = np.linspace(0.0, 2.0 * np.pi, 16, endpoint=False)
    pos = np.broadcast_to(np.column_stack([9.0 * np.cos(ring), 9.0 * np.sin(ring), np.zeros(16)]), (t, 16, 3))
    kiosk = model.Obstacles(["/Kiosk"], [np.array([[-3.0, -3.0], [3.0, -3.0], [3.0, 3.0], [-3.0, 3.0]])],
                            np.array([3.0]))
    facing = []
    for seed in range(6):
        cams = _one_camera([-6.0, 0.0, 2.5], [0.0, 0.0, 1.1], [2.0, 3.0])
        m = film(pos.copy(), times, FPS, cams, model.EventTable([]), kiosk, seed=seed)[0].cam_to_world
        eye = m[:, 3, :3]
        facing.append(Prisms.of(kiosk).blocks(eye, eye - 15.0 * m[:, 2, :3])[2 * 24:].mean())
    assert np.mean(facing) <= 0.5, facing
