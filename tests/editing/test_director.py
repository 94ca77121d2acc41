"""The director's parts on arrays: importance, the continuity rules, and the planned cut."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from usdcrowd.core import model
from usdcrowd.editing import EditParams, plan_cut
from usdcrowd.editing.coverage import Coverage
from usdcrowd.editing.director import _best_partition
from usdcrowd.editing.importance import importance
from usdcrowd.editing.rules import JUMP_CUT, LINE_CROSSED, OK, angle_about, broken_rule, side_of_line

FPS = 24.0


def _event(path, kind, start, end, n_members, first_row=0):
    times = np.arange(start, end + 1, dtype=np.float64)
    return model.Event(path, model.code(model.EVENT_KINDS, kind), float(start), float(end),
                       np.arange(first_row, first_row + n_members, dtype=np.int32), times,
                       np.ones((len(times), n_members), bool), np.zeros((len(times), 3)), np.ones(len(times)))


# ------------------------------------------------------------------------------------------- importance
def test_unique_new_and_large_events_matter_more_and_the_users_weights_count():
    times = np.arange(1, 481, dtype=np.float64)
    arrival = _event("/E/Arrival", "arrival", 1, 480, 2)
    walks = [_event(f"/E/Walk{k}", "groupMotion", 1, 480, 2, 10 + 2 * k) for k in range(4)]
    big = _event("/E/Crowd", "interaction", 1, 480, 16, 30)
    small = _event("/E/Pair", "interaction", 1, 480, 2, 50)
    late = _event("/E/Late", "dialogue", 241, 480, 2, 60)
    events = model.EventTable([arrival, *walks, big, small, late])
    imp = importance(events, times, FPS, EditParams())
    # Unique before repetitive: one arrival against one of four group walks, same size and age.
    assert imp[0, 100] == pytest.approx(2.0 * imp[1, 100])
    # Larger before smaller: 16 people against 2 (1 + 0.25 log2 n).
    assert imp[5, 100] / imp[6, 100] == pytest.approx(2.0 / 1.25)
    # New before long-running: at its start the late dialogue outranks the arrival, ten seconds old.
    assert imp[7, 240] > imp[0, 240]
    assert imp[0, 0] / imp[0, 240] == pytest.approx(1.0 / (0.5 + 0.5 * np.exp(-1.0)), rel=1e-3)
    assert (imp[7, :240] == 0).all() and imp[7, 240] > 0
    # The user's weights: by kind and, over it, by event name.
    w = importance(events, times, FPS, EditParams(kind_weights={"groupMotion": 3.0}, event_weights={"Walk2": 0.0}))
    assert w[1, 100] == pytest.approx(3.0 * imp[1, 100]) and w[3, 100] == 0.0
    # Nobody visible taking part: nothing to film.
    hidden = np.ones(70, bool)
    hidden[[0, 1]] = False
    assert (importance(events, times, FPS, EditParams(), hidden)[0] == 0).all()


# ------------------------------------------------------------------------------------------- rules
def test_the_angle_about_an_event_and_the_side_of_its_line():
    c = np.zeros(3)
    assert angle_about([10, 0, 2], [0, 10, 2], c) == pytest.approx(90.0)
    assert angle_about([10, 0, 2], [-5, 0, 1], c) == pytest.approx(180.0)
    assert angle_about([10, 0], [10 * np.cos(0.3), 10 * np.sin(0.3)], c) == pytest.approx(np.degrees(0.3))
    line = np.array([1.0, 0.0])
    assert side_of_line([0, 5, 1], c, line, 10) == 1 and side_of_line([3, -5, 1], c, line, 10) == -1
    assert side_of_line([10, 1, 1], c, line, 10) == 0          # 5.7 degrees off the line: on it
    assert side_of_line([0, 5, 1], c, np.zeros(2), 10) == 0    # no line, no side


def test_cuts_that_break_the_30_and_180_degree_rules_are_named():
    p = EditParams()
    c = np.zeros(3)
    line = np.array([1.0, 0.0])
    at = lambda deg: [10 * np.cos(np.radians(deg)), 10 * np.sin(np.radians(deg)), 1.6]  # noqa: E731
    assert broken_rule(at(60), at(80), c, line, 0.2, 0.2, p) == JUMP_CUT           # 20 degrees, same size
    assert broken_rule(at(60), at(95), c, line, 0.2, 0.2, p) == OK                 # 35 degrees
    assert broken_rule(at(60), at(70), c, line, 0.2, 0.5, p) == OK                 # a cut in (2.5x)
    assert broken_rule(at(60), at(-60), c, line, 0.2, 0.2, p) == LINE_CROSSED      # over the line
    assert broken_rule(at(60), at(-60), c, np.zeros(2), 0.2, 0.2, p) == OK         # no line to cross
    assert broken_rule(at(60), at(175), c, line, 0.2, 0.2, p) == OK                # onto the line: allowed


# ------------------------------------------------------------------------------------------- the cut
def _coverage(share, eye=None, centre=None, line=None, size=0.3):
    """A Coverage from a (c, e, t) share (sizes all ``size``), cameras around the origin by default."""
    share = np.asarray(share, np.float32)
    c, e, t = share.shape
    if eye is None:
        ang = np.radians(np.arange(c) * 360.0 / c)
        eye = np.repeat(np.stack([10 * np.cos(ang), 10 * np.sin(ang), np.full(c, 1.6)], 1)[:, None], t, 1)
    return Coverage(np.arange(1, t + 1, dtype=np.float64), share, np.full_like(share, size),
                    np.zeros((c, t), np.float32), np.asarray(eye, np.float64),
                    np.zeros((e, t, 3)) if centre is None else centre,
                    np.zeros((e, t, 2)) if line is None else line)


def _check_holds(cut, t, params, fps=FPS):
    assert cut.shots[0].start == 0 and cut.shots[-1].end == t
    for a, b in zip(cut.shots, cut.shots[1:]):
        assert a.end == b.start and a.camera != b.camera
    for s in cut.shots:
        assert params.min_hold * fps <= s.frames <= params.max_hold * fps, s
        assert (cut.camera[s.start:s.end] == s.camera).all()


def test_the_cut_follows_the_camera_that_shows_the_event_and_holds_every_shot_2_to_8_seconds():
    t = 330
    share = np.zeros((3, 1, t))
    share[0, 0, :150] = 1.0
    share[1, 0, 150:] = 1.0
    share[2, 0, :] = 0.3
    events = model.EventTable([_event("/E/A", "arrival", 1, t, 2)])
    params = EditParams()
    cut = plan_cut(_coverage(share), events, FPS, params)
    _check_holds(cut, t, params)
    # Camera 0 while it shows the event, camera 1 after: the cut where the view changes.
    assert [(s.camera, s.start, s.end) for s in cut.shots] == [(0, 0, 150), (1, 150, 330)]
    assert all(s.event == 0 for s in cut.shots)


def test_a_cut_the_rules_forbid_is_not_made():
    """Cameras 0 and 1 frame the pair from opposite sides of its line: the best cut (0 -> 1) crosses it;
    camera 2, on camera 0's side and 90 degrees round, is taken instead."""
    t = 240
    share = np.zeros((3, 1, t))
    share[0, 0, :120] = 1.0
    share[1, 0, 120:] = 1.0
    share[2, 0, 120:] = 0.6
    eye = np.zeros((3, t, 3))
    eye[0, :] = [10, 10, 1.6]
    eye[1, :] = [10, -10, 1.6]
    eye[2, :] = [-10, 10, 1.6]
    line = np.zeros((1, t, 2))
    line[0, :] = [1.0, 0.0]
    events = model.EventTable([_event("/E/Pair", "interaction", 1, t, 2)])
    params = EditParams()
    free = plan_cut(_coverage(share, eye=eye), events, FPS, params)                 # no line: 0 then 1
    assert 1 in free.camera[130:].tolist()
    cut = plan_cut(_coverage(share, eye=eye, line=line), events, FPS, params)
    _check_holds(cut, t, params)
    assert 1 not in cut.camera.tolist() and 2 in cut.camera.tolist()
    assert cut.refused.get(LINE_CROSSED, 0) > 0


def test_one_camera_is_held_for_the_whole_shot_and_says_so():
    t = 300
    cut = plan_cut(_coverage(np.ones((1, 1, t))), model.EventTable([_event("/E/A", "arrival", 1, t, 2)]), FPS)
    assert len(cut.shots) == 1 and cut.shots[0].frames == t and cut.shots[0].held_long


def test_the_planned_cut_is_the_best_of_every_allowed_cut():
    """The dynamic programme against brute force over every partition and camera sequence (small case)."""
    rng = np.random.default_rng(5)
    c, k = 3, 9
    starts = np.arange(k + 1) * 6
    block = rng.random((c, k))
    cum = np.concatenate([np.zeros((c, 1)), np.cumsum(block, axis=1)], axis=1)
    allowed = rng.random((k, c, c)) > 0.3
    allowed[:, np.arange(c), np.arange(c)] = False
    lo, hi, cost = 12, 24, 0.4

    best_value, best_plan = -np.inf, None
    for n_cuts in range(0, k):
        for bounds in itertools.combinations(range(1, k), n_cuts):
            edges = (0, *bounds, k)
            lengths = [starts[b] - starts[a] for a, b in zip(edges, edges[1:])]
            if not all(lo <= n <= hi for n in lengths):
                continue
            for cams in itertools.product(range(c), repeat=len(edges) - 1):
                if any(not allowed[edges[j + 1], cams[j], cams[j + 1]] for j in range(len(cams) - 1)):
                    continue
                value = sum(cum[cm, b] - cum[cm, a] for cm, a, b in zip(cams, edges, edges[1:])) - cost * n_cuts
                if value > best_value + 1e-12:
                    best_value, best_plan = value, list(zip(cams, edges, edges[1:]))
    plan = _best_partition(cum, starts, allowed, cost, lo, hi)
    value = sum(cum[cm, b] - cum[cm, a] for cm, a, b in plan) - cost * (len(plan) - 1)
    assert value == pytest.approx(best_value) and plan == best_plan


def test_screen_time_wears_an_event_out_and_the_cut_turns_to_another():
    """Cameras 0 and 2 show a unique arrival, camera 1 a group walking past (one of three, so it matters
    less) for 40 s: without fatigue the cut never leaves the arrival (0 and 2 take turns); with it, the
    group gets on air once the arrival has had its time, and the arrival keeps most of it."""
    t = int(40 * FPS)
    share = np.zeros((3, 4, t))
    share[0, 0], share[2, 0], share[1, 1] = 1.0, 1.0, 1.0
    events = model.EventTable([_event("/E/Arrival", "arrival", 1, t, 4), _event("/E/Walk", "groupMotion", 1, t, 4, 4),
                               _event("/E/Walk2", "groupMotion", 1, 2, 2, 8),
                               _event("/E/Walk3", "groupMotion", 1, 2, 2, 10)])
    fresh = EditParams(fatigue_seconds=0.0)
    never = plan_cut(_coverage(share), events, FPS, fresh)
    _check_holds(never, t, fresh)
    assert set(never.camera.tolist()) == {0, 2}
    worn = EditParams()
    cut = plan_cut(_coverage(share), events, FPS, worn)
    _check_holds(cut, t, worn)
    on_walk = np.mean(cut.event == 1)
    assert 0.1 <= on_walk < 0.5, on_walk
    assert all(s.event == (1 if s.camera == 1 else 0) for s in cut.shots), cut.shots
    # The importance it reports is the worn one: the arrival's falls as it is shown.
    assert cut.importance[0, -1] < 0.5 * never.importance[0, -1]
