"""What a camera really shows: people in frame, hidden by scenery or by others, and their size on screen."""

from __future__ import annotations

import numpy as np
import pytest

from usdcrowd.cameras.metrics import PERSON_HEIGHT
from usdcrowd.cameras.sightlines import Prisms, views
from usdcrowd.core import model
from usdcrowd.core.view import look_at


def _camera(eye, target, focal=35.0):
    m = look_at(eye, target)
    tx = np.array([0.5 * 36.0 / focal])
    ty = np.array([0.5 * 20.25 / focal])
    return m, tx, ty, np.array([0.1]), np.array([500.0])


def _wall(cx, cy, hx, hy, height):
    poly = np.array([[cx - hx, cy - hy], [cx + hx, cy - hy], [cx + hx, cy + hy], [cx - hx, cy + hy]])
    return model.Obstacles(["/Wall"], [poly], np.array([height]))


def test_a_wall_between_hides_a_person_and_a_low_one_does_not():
    m, tx, ty, near, far = _camera([0, 0, 1.6], [10, 0, 1.1])
    people = np.array([[10.0, 0.0, 0.0], [10.0, 3.0, 0.0]])
    clear = views(m, tx, ty, near, far, people)
    assert clear.visible.all() and clear.in_frame.all()
    tall = views(m, tx, ty, near, far, people, prisms=Prisms.of(_wall(5, 0, 0.2, 1.0, 3.0)))
    assert tall.visible.tolist() == [[False, True]] and tall.hidden_by_scenery.tolist() == [[True, False]]
    # A 1.2 m wall hides the chest's line, not the head's (1.6 m, from a camera at 1.6 m).
    low = views(m, tx, ty, near, far, people, prisms=Prisms.of(_wall(5, 0, 0.2, 1.0, 1.2)))
    assert low.visible.all()
    # Seen from above (a crane at 8 m), a 3 m wall near the camera hides nobody behind it.
    m2, *_ = _camera([0, 0, 8.0], [10, 0, 1.1])
    assert views(m2, tx, ty, near, far, people, prisms=Prisms.of(_wall(2, 0, 0.2, 1.0, 3.0))).visible.all()


def test_a_person_in_front_hides_the_one_behind_but_not_one_beside():
    m, tx, ty, near, far = _camera([0, 0, 1.6], [10, 0, 1.1])
    people = np.array([[10.0, 0.0, 0.0], [6.0, 0.1, 0.0], [10.0, 2.0, 0.0]])
    v = views(m, tx, ty, near, far, people)
    assert v.visible.tolist() == [[False, True, True]] and v.hidden_by_people.tolist() == [[True, False, False]]
    # An invisible leader hides nobody.
    v = views(m, tx, ty, near, far, people, occluders=np.array([True, False, True]))
    assert v.visible.all()


def test_the_points_on_a_person_and_the_people_in_the_way_scale_with_their_heights():
    m, tx, ty, near, far = _camera([0, 0, 1.7], [10, 0, 1.1])
    people = np.array([[10.0, 0.0, 0.0], [5.0, 0.05, 0.0]])
    # Two tall people in line: the crown of the one behind is behind the head of the one in front.
    tall = views(m, tx, ty, near, far, people, heights=np.array([1.95, 1.95]))
    assert tall.visible.tolist() == [[False, True]] and tall.hidden_by_people.tolist() == [[True, False]]
    # Two short ones: the eye at 1.7 m sees the crown behind over the head in front.
    assert views(m, tx, ty, near, far, people, heights=np.array([1.5, 1.5])).visible.all()
    # A person's height on screen is their own.
    v = views(m, tx, ty, near, far, people[:1], heights=np.array([1.9]))
    assert v.height[0, 0] == pytest.approx(1.9 / 1.7 * views(m, tx, ty, near, far, people[:1]).height[0, 0], rel=0.02)


def test_people_out_of_frame_or_behind_are_not_shown_and_sizes_follow_the_lens():
    m, tx, ty, near, far = _camera([0, 0, 1.6], [10, 0, 1.1], focal=50.0)
    people = np.array([[10.0, 0.0, 0.0], [10.0, 9.0, 0.0], [-5.0, 0.0, 0.0], [20.0, 0.0, 0.0]])
    v = views(m, tx, ty, near, far, people)
    assert v.in_frame.tolist() == [[True, False, False, True]]
    # Height on screen: the person's height over the frame's height at their depth.
    forward = np.array([10.0, 0.0, -0.5]) / np.hypot(10.0, 0.5)
    depth = (people[[0, 3]] + [0.0, 0.0, 1.1] - [0.0, 0.0, 1.6]) @ forward
    assert v.height[0, [0, 3]] == pytest.approx(PERSON_HEIGHT / (2 * ty[0] * depth), rel=1e-3)
    assert v.height[0, 2] == 0.0


def test_sight_lines_agree_with_the_id_pass_of_the_preview(harbour_frames):
    """Independent: the OpenGL preview's id buffer of the harbour, every camera, six frames. People called
    visible have pixels; those hidden by scenery have none; those hidden by others show little."""
    from usdcrowd.cameras.sightlines import lens_tangents
    from usdcrowd.render.preview.renderer import PreviewRenderer

    sc, tracks, idx = harbour_frames
    vis = np.asarray(sc.scenario.agents.visible, bool)
    rows = np.flatnonzero(vis)
    ids = np.asarray(sc.scenario.agents.agent_id)
    w, h = 640, 360
    seen = {"visible": [], "scenery": [], "people": []}
    r = PreviewRenderer(sc.shot, w, h)
    try:
        for j, i in enumerate(idx):
            mats = np.stack([t.cam_to_world[j] for t in tracks])
            tx, ty = lens_tangents(tracks, j)
            v = views(mats, tx, ty, np.array([t.near for t in tracks]), np.array([t.far for t in tracks]),
                      np.asarray(sc.positions[i], dtype=np.float64), people=rows,
                      prisms=Prisms.of(sc.scenario.obstacles), occluders=vis, heights=sc.scenario.agents.height)
            for c, track in enumerate(tracks):
                counts = np.bincount(r.render(float(track.times[j]), track.path).ids.ravel().astype(np.int64),
                                     minlength=int(ids.max()) + 1)
                big = v.height[c] > 0.05
                area = 0.25 * (v.height[c] * h) ** 2               # a person about a quarter as wide as tall
                share = counts[ids[rows]] / np.maximum(area, 1.0)
                seen["visible"] += share[big & v.visible[c]].tolist()
                seen["scenery"] += share[big & v.hidden_by_scenery[c]].tolist()
                seen["people"] += share[big & v.hidden_by_people[c]].tolist()
    finally:
        r.release()
    visible, scenery, people = (np.array(seen[k]) for k in ("visible", "scenery", "people"))
    # Partly hidden people whose chest, head, shoulders, crown or a side shows are visible: those left hidden by
    # others are few (measured: 8 against 623 visible) and show little of themselves.
    assert len(visible) > 100 and len(scenery) > 10 and len(people) > 4, {k: len(a) for k, a in seen.items()}
    assert np.mean(visible > 0.01) > 0.97
    # Measured: 55 of the 56 people called hidden by scenery show under 1 % of their area, one 5 %.
    assert np.mean(scenery < 0.01) > 0.97
    # Measured: a median 0.06 of a person's area against 0.43 for those in plain view.
    assert np.median(people) < 0.15 and np.median(people) < 0.3 * np.median(visible)


def test_an_awning_hides_people_from_above_but_not_from_under_it():
    awning = model.Obstacles(["/Awning"], [np.array([[8.0, -2.0], [12.0, -2.0], [12.0, 2.0], [8.0, 2.0]])],
                             np.array([2.4]), np.array([2.3]))
    person = np.array([[10.0, 0.0, 0.0]])
    prisms = Prisms.of(model.Obstacles.empty(), overhead=awning)
    above = _camera([2.0, 0.0, 8.0], [10.0, 0.0, 1.1])
    assert views(*above, person).visible.all()
    assert views(*above, person, prisms=prisms).hidden_by_scenery.all()
    level = _camera([2.0, 0.0, 1.6], [10.0, 0.0, 1.1])
    assert views(*level, person, prisms=prisms).visible.all()
