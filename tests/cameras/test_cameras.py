"""Steering camera agents (seed 000): geometry, forces, torques, modes, smoothness."""

from __future__ import annotations

import numpy as np
import pytest

from usdcrowd.core import model
from usdcrowd.cameras import forces, framing, torques
from usdcrowd.cameras.film import film
from usdcrowd.cameras.frustum import frustums_intersect_2d
from usdcrowd.cameras.orientation import axes, integrate, level_from_forward, matrix_to_quat
from usdcrowd.cameras.params import CameraParams
from usdcrowd.cameras.placement import generated_agents, take_agents
from usdcrowd.character.rig import quat_to_matrix
from usdcrowd.core.view import look_at

FPS = 24.0
INTERACTION = model.code(model.EVENT_KINDS, "interaction")
GROUP = model.code(model.EVENT_KINDS, "groupMotion")


def make_event(path, kind, positions, members, first, last, times):
    """An event over frames ``first..last`` (indices) with every member active."""
    members = np.asarray(members, np.int32)
    sl = slice(first, last + 1)
    centre = positions[sl][:, members].mean(axis=1)
    radius = np.linalg.norm(positions[sl][:, members] - centre[:, None], axis=2).max(axis=1) + 0.5
    return model.Event(path, kind, float(times[first]), float(times[last]), members, times[sl].copy(),
                       np.ones((last - first + 1, len(members)), bool), centre, radius)


@pytest.fixture
def platoon_scene(rng):
    """100 still bystanders on a 40 m square; 20 of them march in formation along +X at 1.2 m/s for 10 s."""
    t, n = 240, 100
    start = rng.uniform(-20, 20, (n, 2))
    pos = np.zeros((t, n, 3))
    pos[:, :, :2] = start
    grid = np.stack(np.meshgrid(np.arange(5.0), np.arange(4.0), indexing="ij"), -1).reshape(-1, 2)
    pos[:, :20, :2] = grid * 1.2 + [-12.0, -2.0]                       # a 5 x 4 formation
    pos[:, :20, 0] += np.arange(t)[:, None] * 1.2 / FPS
    times = np.arange(1, t + 1, dtype=np.float64)
    ev = make_event("/World/Events/Platoon", GROUP, pos, np.arange(20), 0, t - 1, times)
    return pos, times, model.EventTable([ev])


def in_view(track, k, points):
    """Points inside the camera's frustum at frame k (independent of the package's frustum code)."""
    m = track.cam_to_world[k]
    rel = points - m[3, :3]
    cam = rel @ m[:3, :3].T                      # coordinates along right, up, back
    z = -cam[:, 2]
    tx = 0.5 * track.horizontal_aperture / track.focal_length[k]
    ty = 0.5 * track.vertical_aperture / track.focal_length[k]
    return (z > 0) & (np.abs(cam[:, 0]) <= tx * z) & (np.abs(cam[:, 1]) <= ty * z)


# ----------------------------------------------------------------- geometry
def test_quaternion_of_a_camera_frame_round_trips(rng):
    eye = rng.normal(size=(50, 3)) * 10
    target = rng.normal(size=(50, 3)) * 10
    m = look_at(eye, target)[:, :3, :3]
    q = matrix_to_quat(m)
    np.testing.assert_allclose(quat_to_matrix(q), m, atol=1e-12)


def test_levelled_orientation_looks_along_forward_without_roll(rng):
    f = rng.normal(size=(100, 3))
    f /= np.linalg.norm(f, axis=1, keepdims=True)
    fwd, right, up = axes(level_from_forward(f))
    np.testing.assert_allclose(fwd, f, atol=1e-12)
    np.testing.assert_allclose(right[:, 2], 0.0, atol=1e-12)        # horizon level
    assert (up[:, 2] >= -1e-12).all()                                  # not upside down


def test_integration_turns_by_rate_times_time():
    q = level_from_forward(np.array([[1.0, 0.0, 0.0]]))
    q2 = integrate(q, np.array([[0.0, 0.0, np.radians(30.0)]]), 1.5)    # 45 degrees to the left
    fwd = axes(q2)[0][0]
    np.testing.assert_allclose(fwd, [np.cos(np.pi / 4), np.sin(np.pi / 4), 0.0], atol=1e-12)


def test_viewpoint_range_arcs_see_the_pair_under_alpha():
    a, b = np.array([[0.0, 0.0]]), np.array([[4.0, 1.0]])
    cam = np.array([[2.0, -12.0]])
    alpha, beta = np.radians([25.0]), np.radians([80.0])
    poly = framing.viewpoint_range(a, b, cam, alpha, beta)[0]
    arcs = np.concatenate([poly[:framing.ARC_SAMPLES],
                           poly[framing.ARC_SAMPLES + framing.BEZIER_SAMPLES:
                                2 * framing.ARC_SAMPLES + framing.BEZIER_SAMPLES]])
    u, v = arcs - a, arcs - b
    angle = np.arccos(np.einsum("ij,ij->i", u, v) / np.linalg.norm(u, axis=1) / np.linalg.norm(v, axis=1))
    np.testing.assert_allclose(angle, alpha[0], atol=1e-9)
    # The Bezier pieces near A and B stay further from the pair than the arcs' ends would allow:
    # no viewpoint of the range is within 1 m of A or B.
    assert np.linalg.norm(poly - a, axis=1).min() > 1.0
    assert np.linalg.norm(poly - b, axis=1).min() > 1.0


def test_framing_target_from_far_away_is_the_frontal_viewpoint():
    a, b = np.array([[-2.0, 0.0]]), np.array([[2.0, 0.0]])
    cam = np.array([[0.0, -30.0]])
    alpha = np.radians([30.0])
    goal = forces.framing_target(cam, a, b, alpha, np.radians([80.0]), 0.6)
    expected = 2.0 / np.tan(alpha[0]) + 2.0 / np.sin(alpha[0])     # centre's offset + radius
    np.testing.assert_allclose(goal[0], [0.0, -expected], atol=0.05)


def test_frustum_intersection_of_facing_and_opposite_cameras():
    half = np.radians([30.0])
    pc, pi = np.array([[0.0, 0.0]]), np.array([[10.0, 0.0]])
    facing = frustums_intersect_2d(pc, np.array([[1.0, 0.0]]), half, pi, np.array([[-1.0, 0.0]]), half, 0.1, 30)
    apart = frustums_intersect_2d(pc, np.array([[-1.0, 0.0]]), half, pi, np.array([[1.0, 0.0]]), half, 0.1, 30)
    # Looking the same way, 10 m apart: their inner sides cross about 8.7 m ahead.
    parallel = frustums_intersect_2d(pc, np.array([[0.0, 1.0]]), half, pi, np.array([[0.0, 1.0]]), half, 0.1, 30)
    too_far = frustums_intersect_2d(pc, np.array([[0.0, 1.0]]), half, pi, np.array([[0.0, 1.0]]), half, 0.1, 5)
    assert facing[0] and parallel[0]
    assert not apart[0] and not too_far[0]


# ------------------------------------------------------------------ torques
def test_aiming_torque_turns_at_full_rate_then_slows_inside_the_threshold():
    q = level_from_forward(np.array([[1.0, 0.0, 0.0]]))
    goal = level_from_forward(np.array([[0.0, 1.0, 0.0]]))                 # 90 degrees to the left
    rate, thr = np.radians([40.0]), np.radians([10.0])
    w = np.zeros((1, 3))
    tau = torques.aiming(q, goal, w, rate, thr)
    np.testing.assert_allclose(tau[0], [0.0, 0.0, rate[0]], atol=1e-9)       # full rate, about +Z
    near = level_from_forward(np.array([[np.cos(np.radians(85)), np.sin(np.radians(85)), 0.0]]))
    tau = torques.aiming(near, goal, w, rate, thr)
    np.testing.assert_allclose(tau[0, 2], rate[0] * 0.5, atol=1e-9)          # 5 of 10 degrees left


def test_aiming_pans_round_to_a_target_behind_a_camera_looking_down():
    """Looking east 70 degrees down, with its target west-north-west 50 degrees down: the camera pans round
    (about +Z, to its left) as a camera head does. The shortest rotation would swing the view through the
    ground under the camera, where the pitch limit holds it."""
    def look(yaw, pitch):
        y, p = np.radians(yaw), np.radians(pitch)
        return level_from_forward(np.array([[np.cos(p) * np.cos(y), np.cos(p) * np.sin(y), np.sin(p)]]))

    rate, thr = np.radians([40.0]), np.radians([10.0])
    tau = torques.aiming(look(0.0, -70.0), look(150.0, -50.0), np.zeros((1, 3)), rate, thr)
    np.testing.assert_allclose(np.linalg.norm(tau[0]), rate[0], rtol=1e-9)
    pan, tilt = np.radians(150.0), np.radians(20.0)
    assert tau[0, 2] == pytest.approx(rate[0] * pan / np.hypot(pan, tilt), rel=1e-6)


def test_avoidance_torque_pans_away_from_the_overlapping_camera():
    pos = np.array([[0.0, 0.0, 2.0], [10.0, 0.0, 2.0]])
    fwd = np.array([[0.0, 1.0, 0.0], [0.0, 1.0, 0.0]])
    right = np.array([[1.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    tau = torques.avoidance(pos, fwd, right, np.radians([30.0, 30.0]), np.zeros((2, 3)),
                            np.radians([60.0, 60.0]), np.array([[0, 1]]), 0.1, 30.0)
    assert tau[0, 2] > 0 and tau[1, 2] < 0          # the left camera turns left, the right one right


def test_separation_pushes_close_cameras_looking_the_same_way_apart():
    pos = np.array([[0.0, 0.0, 2.0], [1.0, 0.0, 2.0]])
    fwd = np.array([[0.0, 1.0, 0.0]] * 2)
    right = np.array([[1.0, 0.0, 0.0]] * 2)
    f = forces.separation(pos, np.zeros((2, 3)), fwd, right, np.array([3.0, 3.0]), np.array([5.0, 5.0]),
                          np.array([[0, 1]]))
    assert f[0, 0] < 0 and f[1, 0] > 0
    opposite = forces.separation(pos, np.zeros((2, 3)), np.array([[0, 1.0, 0], [0, -1.0, 0]]), right,
                                 np.array([3.0, 3.0]), np.array([5.0, 5.0]), np.array([[0, 1]]))
    np.testing.assert_allclose(opposite, 0.0)       # max(0, l_c . l_i) = 0: no push


# ------------------------------------------------------------ whole agents
def test_tracking_cameras_keep_the_event_in_frame_and_move_smoothly(platoon_scene):
    pos, times, events = platoon_scene
    cams = generated_agents(4, np.zeros(3), 25.0)
    tracks = film(pos, times, FPS, cams, events, seed=3)
    dt = 1.0 / FPS
    for tr in tracks:
        tracking = tr.state == model.code(model.CAMERA_MODES, "tracking")
        assert tracking.mean() > 0.9
        framed = [in_view(tr, k, pos[k, :20] + [0, 0, 1.0]).mean() for k in np.flatnonzero(tracking)]
        # Every member inside the frustum in at least 85 % of tracking frames.
        assert np.mean(np.array(framed) == 1.0) >= 0.85, tr.path
        p = tr.cam_to_world[:, 3, :3]
        v = np.diff(p, axis=0) / dt
        assert np.linalg.norm(v, axis=1).max() <= cams.max_speed[0] * 1.001
        # No jump in velocity: per frame at most the force limit (2 substeps of max force).
        dv = np.linalg.norm(np.diff(v, axis=0), axis=1)
        assert dv.max() <= cams.max_force[0] * dt * 1.01
        fwd = -tr.cam_to_world[:, 2, :3]
        turn = np.arccos(np.clip(np.einsum("ij,ij->i", fwd[1:], fwd[:-1]), -1, 1)) / dt
        assert turn.max() <= cams.max_angular_speed[0] * 1.01
        assert (p[:, 2] >= cams.elevation[0, 0] - 1e-9).all() and (p[:, 2] <= cams.elevation[0, 1] + 1e-9).all()


def test_scouting_prefers_events_no_other_camera_follows():
    t = 48
    times = np.arange(1, t + 1, dtype=np.float64)
    pos = np.zeros((t, 4, 3))
    pos[:, 0, :2], pos[:, 1, :2] = [-3.0, 20.0], [-2.0, 20.0]
    pos[:, 2, :2], pos[:, 3, :2] = [2.0, 20.0], [3.0, 20.0]
    e1 = make_event("/E/Left", INTERACTION, pos, [0, 1], 0, t - 1, times)
    e2 = make_event("/E/Right", INTERACTION, pos, [2, 3], 0, t - 1, times)
    cams = generated_agents(2, np.zeros(3), 1.0)
    cams.cam_to_world[:] = look_at(np.array([[-1.0, 0.0, 2.0], [1.0, 0.0, 2.0]]), np.array([[0.0, 20.0, 1.0]] * 2))
    tracks = film(pos, times, FPS, cams, model.EventTable([e1, e2]))
    assert {tracks[0].tracked[0], tracks[1].tracked[0]} == {"/E/Left", "/E/Right"}


def test_a_camera_scouts_again_when_its_event_ends_and_stays_out_of_scenery(platoon_scene):
    pos, times, events = platoon_scene
    short = make_event("/World/Events/Short", GROUP, pos, np.arange(20), 0, 60, times)
    # A 4 m tall building beside the camera's first view of the crowd, in its way once it moves.
    box = np.array([[20.0, 2.0], [26.0, 2.0], [26.0, 12.0], [20.0, 12.0]])
    obstacles = model.Obstacles(["/World/Scenery/House"], [box], np.array([4.0]))
    cams = take_agents(generated_agents(4, np.zeros(3), 25.0), [0])      # starts at (30, 0)
    tracks = film(pos, times, FPS, cams, model.EventTable([short]), obstacles, seed=5)
    tr = tracks[0]
    assert tr.tracked[10] == "/World/Events/Short" and tr.tracked[70] == ""
    assert tr.state[70] == model.code(model.CAMERA_MODES, "scouting")
    p = tr.cam_to_world[:, 3, :3]
    inside = (p[:, 0] > 20) & (p[:, 0] < 26) & (p[:, 1] > 2) & (p[:, 1] < 12) & (p[:, 2] < 4.0)
    assert not inside.any()


def _behind_box(eye, target, lo, hi, height, samples=400):
    """Whether the straight line from ``eye`` to ``target`` (3,) passes through an axis-aligned box
    footprint [lo, hi] (2,) below ``height``: sampled along the line, independent of the sight-line code."""
    s = np.linspace(0.0, 1.0, samples)[:, None]
    pts = eye + s * (target - eye)
    return bool(((pts[:, :2] > lo).all(axis=1) & (pts[:, :2] < hi).all(axis=1) & (pts[:, 2] < height)).any())


def test_a_scout_does_not_see_an_event_through_a_house(platoon_scene):
    """A camera behind a house (and kept below its roof) does not take the crowd it would see if the
    house were glass; whenever it takes the event, one of its people is in clear sight."""
    pos, times, _ = platoon_scene
    short = make_event("/World/Events/Short", GROUP, pos, np.arange(20), 0, 200, times)
    lo, hi = np.array([20.0, -5.0]), np.array([26.0, 5.0])
    box = np.array([[20.0, -5.0], [26.0, -5.0], [26.0, 5.0], [20.0, 5.0]])
    obstacles = model.Obstacles(["/World/Scenery/House"], [box], np.array([4.0]))
    cams = take_agents(generated_agents(4, np.zeros(3), 25.0), [0])      # starts at (30, 0), behind the house
    cams.elevation[:] = [1.5, 3.0]
    glass = film(pos, times, FPS, cams, model.EventTable([short]), model.Obstacles.empty(), seed=5)[0]
    tr = film(pos, times, FPS, cams, model.EventTable([short]), obstacles, seed=5)[0]
    assert glass.tracked[1] == "/World/Events/Short"          # seen at once through glass
    assert tr.tracked[1] == ""
    takes = [k for k in range(len(times)) if tr.tracked[k] and (k == 0 or not tr.tracked[k - 1])]
    for k in takes:
        eye = tr.cam_to_world[k, 3, :3]
        assert any(not _behind_box(eye, pos[k, i] + [0.0, 0.0, 1.1], lo, hi, 4.0) for i in range(20)), k


def test_obstacle_avoidance_clears_the_line_of_sight():
    t = 24 * 12
    times = np.arange(1, t + 1, dtype=np.float64)
    pos = np.zeros((t, 2, 3))
    pos[:, 0, :2], pos[:, 1, :2] = [-1.0, 0.0], [1.0, 0.0]
    ev = make_event("/E/Talk", INTERACTION, pos, [0, 1], 0, t - 1, times)
    # A wall 6 m wide, 5 m tall, between the camera (south) and the pair.
    wall = np.array([[-3.0, -8.0], [3.0, -8.0], [3.0, -7.0], [-3.0, -7.0]])
    obstacles = model.Obstacles(["/W"], [wall], np.array([5.0]))
    cams = take_agents(generated_agents(1, np.zeros(3), 1.0), [0])
    cams.cam_to_world[:] = look_at(np.array([[0.0, -14.0, 1.6]]), np.array([[0.0, 0.0, 1.1]]))
    cams.elevation[:] = [1.5, 2.0]                # cannot crane over the wall
    cams.target[:] = ["/E/Talk"]                  # tracks the pair it cannot see (a scout would not take it)
    with_avoid = film(pos, times, FPS, cams, model.EventTable([ev]), obstacles)[0]
    without = film(pos, times, FPS, cams, model.EventTable([ev]), obstacles, params=CameraParams(w_obstacle=0.0))[0]

    def blocked(track):
        eye = track.cam_to_world[-24:, 3, :2]
        # The sight line to the pair's midpoint crosses y = -7.5 at this x.
        s = (-7.5 - eye[:, 1]) / (0.0 - eye[:, 1])
        x = eye[:, 0] + s * (0.0 - eye[:, 0])
        return np.mean((s > 0) & (s < 1) & (np.abs(x) < 3.0))

    assert blocked(with_avoid) == 0.0
    assert blocked(without) > 0.5


def test_framing_force_brings_the_camera_onto_the_constant_angle_arc():
    t = 24 * 15
    times = np.arange(1, t + 1, dtype=np.float64)
    pos = np.zeros((t, 2, 3))
    pos[:, 0, :2], pos[:, 1, :2] = [-1.5, 0.0], [1.5, 0.0]
    ev = make_event("/E/Talk", INTERACTION, pos, [0, 1], 0, t - 1, times)
    cams = take_agents(generated_agents(1, np.zeros(3), 1.0), [0])
    cams.cam_to_world[:] = look_at(np.array([[5.0, -40.0, 2.0]]), np.array([[0.0, 0.0, 1.1]]))
    tr = film(pos, times, FPS, cams, model.EventTable([ev]))[0]
    eye = tr.cam_to_world[-1, 3, :2]
    alpha = cams.view_angle[0] * 2 * np.arctan(0.5 * cams.horizontal_aperture[0] / cams.focal_length[0])
    seen = framing.subtended_angle(eye[None], pos[-1, :1, :2], pos[-1, 1:, :2])[0]
    assert abs(seen - alpha) < 0.05 * alpha
    start = framing.subtended_angle(np.array([[5.0, -40.0]]), pos[0, :1, :2], pos[0, 1:, :2])[0]
    assert start < 0.5 * alpha                     # it had to come much closer


def test_a_camera_sharing_its_event_leaves_it_for_one_nobody_follows():
    t = 24 * 8
    times = np.arange(1, t + 1, dtype=np.float64)
    pos = np.zeros((t, 4, 3))
    pos[:, 0, :2], pos[:, 1, :2] = [-1.0, 20.0], [0.0, 20.0]
    pos[:, 2, :2], pos[:, 3, :2] = [1.5, 21.0], [2.5, 21.0]
    e1 = make_event("/E/First", INTERACTION, pos, [0, 1], 0, t - 1, times)
    e2 = make_event("/E/Later", INTERACTION, pos, [2, 3], 100, t - 1, times)       # from 4.2 s on
    cams = generated_agents(2, np.zeros(3), 1.0)
    cams.cam_to_world[:] = look_at(np.array([[-1.0, 0.0, 2.0], [1.0, 0.0, 2.0]]), np.array([[0.0, 20.0, 1.0]] * 2))
    tracks = film(pos, times, FPS, cams, model.EventTable([e1]), seed=2)
    assert tracks[0].tracked[-1] == tracks[1].tracked[-1] == "/E/First"            # nothing else to film
    tracks = film(pos, times, FPS, cams, model.EventTable([e1, e2]), seed=2)
    assert tracks[0].tracked[90] == tracks[1].tracked[90] == "/E/First"
    assert sorted([tracks[0].tracked[-1], tracks[1].tracked[-1]]) == ["/E/First", "/E/Later"]


def test_cameras_run_with_no_event_and_with_no_character(platoon_scene):
    pos, times, _ = platoon_scene
    cams = generated_agents(3, np.zeros(3), 25.0)
    quiet = film(pos[:48], times[:48], FPS, cams, model.EventTable(), seed=1)
    assert all((tr.state == model.code(model.CAMERA_MODES, "scouting")).all() for tr in quiet)
    assert all(np.isfinite(tr.cam_to_world).all() for tr in quiet)
    empty = film(np.zeros((12, 0, 3)), times[:12], FPS, cams, model.EventTable(), seed=1)
    assert all(np.isfinite(tr.cam_to_world).all() for tr in empty)


def test_a_scouts_decisions_read_nobody_outside_its_view(platoon_scene, rng):
    """Seed 000's cameras know only what they see: moving every character outside a scout's frustum
    changes neither what it decides (the event it takes) nor how it turns and moves (the crowd's centre
    for containment, the paper's one piece of shared knowledge, is given unchanged)."""
    import copy

    from usdcrowd.cameras.steering import CameraAgents
    from usdcrowd.cameras.placement import crowd_extent

    pos, times, _ = platoon_scene
    # Three cameras round the crowd, looking past it (75 degrees off its centre): part of it in view.
    ev = make_event("/World/Events/Platoon", GROUP, pos, np.arange(20), 0, len(times) - 1, times)
    cams = generated_agents(3, np.zeros(3), 25.0)
    eye = cams.cam_to_world[:, 3, :3].copy()
    a = np.radians(75.0)
    inward = -eye[:, :2] / np.linalg.norm(eye[:, :2], axis=1, keepdims=True)
    past = inward @ np.array([[np.cos(a), np.sin(a)], [-np.sin(a), np.cos(a)]])
    cams.cam_to_world[:] = look_at(eye, eye + np.column_stack([past * 10.0, np.zeros(3)]))
    agents = CameraAgents(cams, model.EventTable([ev]), model.Obstacles.empty(), seed=4, fps=FPS)
    dt = 1.0 / (FPS * agents.params.substeps)
    checked, took = 0, False
    for k in range(1, len(times)):
        p = pos[k].copy()
        centre, radius = crowd_extent(p)
        scouts = np.flatnonzero(agents.tracked < 0)
        fwd, right, up = axes(agents.q)

        def seen_by_a_scout(q):
            seen = np.zeros(len(q), bool)
            for c in scouts:
                rel = q + [0.0, 0.0, agents.params.look_height] - agents.p[c]
                z = rel @ fwd[c]
                seen |= (z > 0) & (np.abs(rel @ right[c]) <= agents.tan_x[c] * z) & (
                    np.abs(rel @ up[c]) <= agents.tan_y[c] * z)
            return seen

        # A camera tracking an event (taken before or at this frame) knows the event's people.
        decided = copy.deepcopy(agents)
        decided.update_modes(float(times[k]), p)
        followed = np.zeros(len(p), bool)
        if (decided.tracked >= 0).any():
            followed[ev.members] = True
        moved = p.copy()
        moved[:, :2] += rng.uniform(-15.0, 15.0, (len(p), 2))
        unseen = ~seen_by_a_scout(p) & ~seen_by_a_scout(moved) & ~followed     # out of view before and after
        moved[~unseen] = p[~unseen]
        a, b = copy.deepcopy(agents), copy.deepcopy(agents)
        for one, where in ((a, p), (b, moved)):
            one.update_modes(float(times[k]), where)
            for _ in range(one.params.substeps):
                one.step(float(times[k]), where, centre, radius, dt)
        for c in scouts:
            assert a.tracked[c] == b.tracked[c] and a.mode[c] == b.mode[c], (k, c)
            np.testing.assert_array_equal(a.q[c], b.q[c])
            np.testing.assert_array_equal(a.p[c], b.p[c])
        checked += len(scouts) * unseen.any()
        agents.update_modes(float(times[k]), p)
        took |= bool((agents.tracked >= 0).any())
        for _ in range(agents.params.substeps):
            agents.step(float(times[k]), p, centre, radius, dt)
    assert checked > 50
    assert took                                 # and what they saw, they took


def test_people_hidden_by_a_wall_or_by_others_are_not_seen_by_the_metrics():
    """Seed 000's viewed share with occlusion counted: one camera, three people in a row behind it, a wall
    before the third; without the scenery all three are seen, with it the wall and the front person hide."""
    from usdcrowd.cameras.metrics import coverage

    t = 4
    times = np.arange(1, t + 1, dtype=np.float64)
    pos = np.zeros((t, 3, 3))
    pos[:, 0, :2], pos[:, 1, :2], pos[:, 2, :2] = [8.0, 0.0], [12.0, 0.05], [8.0, 4.0]
    mats = np.repeat(look_at([0.0, 0.0, 1.6], [10.0, 1.5, 1.1]), t, axis=0)
    track = model.CameraTrack("/Cam", times, mats, np.full(t, 24.0), 36.0, 20.25, 0.1, 500.0)
    active = np.ones((t, 3), bool)
    wall = model.Obstacles(["/Wall"], [np.array([[5.0, 2.0], [5.4, 2.0], [5.4, 4.0], [5.0, 4.0]])], np.array([3.0]))
    open_view = coverage([track], pos, active)
    hidden = coverage([track], pos, active, obstacles=wall)
    assert (open_view.n_active_viewed == 3).all()
    assert (hidden.n_active_viewed == 1).all()                    # the one in front: the others are hidden
    no_wall = coverage([track], pos, active, obstacles=model.Obstacles.empty())
    assert (no_wall.n_active_viewed == 2).all()                   # the wall's person again, not the one behind


def test_static_cameras_placed_on_the_first_frame_know_only_where_the_crowd_starts(platoon_scene):
    from usdcrowd.cameras.placement import static_cameras

    pos, times, _ = platoon_scene
    moving = pos.copy()
    moving[:, :, 0] += np.linspace(0, 60.0, len(times))[:, None]      # everyone walks 60 m along +X
    start = static_cameras(moving[:1], 2, times)
    whole = static_cameras(moving[::10], 2, times)
    def aim(tr):                                   # where the view's centre meets the ground
        eye, fwd = tr.cam_to_world[0, 3], -tr.cam_to_world[0, 2, :3]
        return (eye[:3] + fwd * (-eye[2] / fwd[2]))[:2]

    lo, hi = moving[0, :, :2].min(axis=0), moving[0, :, :2].max(axis=0)
    inside = lambda p: bool(((p >= lo - 5.0) & (p <= hi + 5.0)).all())  # noqa: E731
    assert all(inside(aim(tr)) for tr in start), [aim(tr) for tr in start]
    assert not all(inside(aim(tr)) for tr in whole), [aim(tr) for tr in whole]
